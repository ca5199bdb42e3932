"""Problem classes and an independent reference for the Riccati sweep (tests and benchmark).

* Parametric examples of the CAREX and DAREX benchmark collections (J. Abels and P. Benner,
  "CAREX - A collection of benchmark examples for continuous-time algebraic Riccati equations
  (Version 2.0)" and "DAREX - ... discrete-time ... (Version 2.0)", SLICOT Working Notes
  1999-14 and 1999-16), written here from the problem definitions in those notes: only the
  examples a test needs, each with its closed-form solution where the notes give one.
* Seeded random problem classes: generic, singular ``Q``, nearly unstabilisable, modes on or
  near the stability boundary, badly scaled.
* :func:`pencil_reference`: the stabilising solution from the stable deflating subspace of the
  extended Hamiltonian / symplectic pencil, computed in mpmath at 50 digits on the exact
  float data, together with the pencil's distance to the stability boundary, which decides
  whether a stabilising solution exists at all.  Independent of cfdesign and of LAPACK.
"""

from __future__ import annotations

import warnings

import numpy as np

# --------------------------------------------------------------------------------------
# CAREX / DAREX parametric examples (Abels and Benner), as (A, B, Q, R, X closed form or None)
# --------------------------------------------------------------------------------------


def carex_2_1(eps):
    """CAREX 2.1: a mode reached only through ``eps`` (eps > 0); closed-form X."""
    A, B = np.diag([1.0, -2.0]), np.array([[eps], [0.0]])
    Q, R = np.ones((2, 2)), np.eye(1)
    t = np.hypot(1.0, eps)
    x12 = 1.0 / (2.0 + t)
    lo = (2.0 + 1.0 / (t + eps)) * x12  # 1 - eps x12 without cancellation (t - eps = 1 / (t + eps))
    X = np.array([[(1.0 + t) / eps**2, x12], [x12, lo * (1.0 + eps * x12) / 4.0]])
    return A, B, Q, R, X


def carex_2_3(eps):
    """CAREX 2.3: ``A = [[0, eps], [0, 0]]``, a growing coupling (eps > 0); closed-form X."""
    A, B = np.array([[0.0, eps], [0.0, 0.0]]), np.array([[0.0], [1.0]])
    t = np.sqrt(1.0 + 2.0 * eps)
    return A, B, np.eye(2), np.eye(1), np.array([[t / eps, 1.0], [1.0, t]])


def carex_2_6(eps):
    """CAREX 2.6: three decoupled modes mixed by ``V = I - 2/3 ones`` (eps > 0); closed-form X.

    Formed in floating point, ``Q = V diag(1/eps, 1, eps) V`` loses its small eigenvalues below
    ``1/eps`` times rounding: for eps <= 1e-9 it is indefinite and the float data have no
    stabilising solution (their Hamiltonian has eigenvalues on the imaginary axis).
    """
    V = np.eye(3) - 2.0 / 3.0 * np.ones((3, 3))
    A = V @ np.diag([eps, 2.0 * eps, 3.0 * eps]) @ V
    Q = V @ np.diag([1.0 / eps, 1.0, eps]) @ V
    x = [eps**2 + np.sqrt(eps**4 + 1.0), 2.0 * eps**2 + np.sqrt(4.0 * eps**4 + eps),
         3.0 * eps**2 + eps * np.sqrt(9.0 * eps**2 + 1.0)]
    return A, np.eye(3), 0.5 * (Q + Q.T), eps * np.eye(3), V @ np.diag(x) @ V


def carex_2_5(eps):
    """CAREX 2.5: H-infinity type data (indefinite Q), Hamiltonian eigenvalues ``+-eps +- i`` (eps >= 0)."""
    A = np.array([[3.0 - eps, 1.0], [4.0, 2.0 - eps]])
    Q = np.array([[4.0 * eps - 11.0, 2.0 * eps - 5.0], [2.0 * eps - 5.0, 2.0 * eps - 2.0]])
    return A, np.ones((2, 1)), Q, np.eye(1), np.array([[2.0, 1.0], [1.0, 1.0]])


def carex_2_8(eps):
    """CAREX 2.8: a stable and an unstable oscillator at distance ``eps`` from the axis (eps > 0)."""
    A = np.zeros((4, 4))
    A[:2, :2] = [[-eps, 1.0], [-1.0, -eps]]
    A[2:, 2:] = [[eps, 1.0], [-1.0, eps]]
    return A, np.ones((4, 1)), np.ones((4, 4)), np.eye(1), None


def darex_2_1(r):
    """DAREX 2.1: input weight ``r`` (r > 0); closed-form X."""
    A, B = np.array([[4.0, 3.0], [-4.5, -3.5]]), np.array([[1.0], [-1.0]])
    Q = np.array([[9.0, 6.0], [6.0, 4.0]])
    return A, B, Q, np.array([[r]]), (1.0 + np.sqrt(1.0 + 4.0 * r)) / 2.0 * Q


def darex_2_3(eps):
    """DAREX 2.3: ``A = [[0, eps], [0, 0]]`` (eps >= 0); closed-form ``X = diag(1, 1 + eps^2)``."""
    A, B = np.array([[0.0, eps], [0.0, 0.0]]), np.array([[0.0], [1.0]])
    return A, B, np.eye(2), np.eye(1), np.diag([1.0, 1.0 + eps**2])


def darex_2_5(tau):
    """DAREX 2.5: paper machine sampled at ratio ``tau`` (tau > 1); closed-form X."""
    t = 1.0 / tau
    alpha, beta, r = 1.0 - t, t, 0.25
    A = np.zeros((4, 4))
    A[0, 0] = alpha
    A[1:, :3] = np.eye(3)
    B = np.zeros((4, 1))
    B[0, 0] = beta
    Q = np.zeros((4, 4))
    Q[3, 3] = 1.0
    X = np.eye(4)
    c = r * (alpha + 1.0) * (alpha - 1.0) + beta**2
    X[0, 0] = (c + np.sqrt(c * c + 4.0 * beta**2 * r)) / (2.0 * beta**2)
    return A, B, Q, np.array([[r]]), X


def darex_4_1(n, r=1.0):
    """DAREX 4.1: the n-state shift with ``Q = I`` (n >= 2, r > 0); closed-form ``X = diag(1..n)``."""
    A, B = np.eye(n, k=1), np.zeros((n, 1))
    B[-1, 0] = 1.0
    return A, B, np.eye(n), np.array([[r]]), np.diag(np.arange(1.0, n + 1.0))


# --------------------------------------------------------------------------------------
# random problem classes
# --------------------------------------------------------------------------------------
RANDOM_CLASSES = ("generic", "singular_q", "near_unstabilisable", "boundary_observed", "boundary_unobserved",
                  "badly_scaled")


def _boundary_block(kind, rng, k):
    """k x k real block whose eigenvalues lie on the stability boundary (axis or unit circle)."""
    M = np.zeros((k, k))
    i, w = 0, 0.0
    while i < k:  # distinct eigenvalues: a repeated one would need as many inputs as its multiplicity
        if k - i >= 2:
            w += rng.uniform(0.2, 1.0)
            M[i:i + 2, i:i + 2] = ([[0.0, w], [-w, 0.0]] if kind == "care"
                                   else [[np.cos(w), np.sin(w)], [-np.sin(w), np.cos(w)]])
            i += 2
        else:
            M[i, i] = 0.0 if kind == "care" else 1.0
            i += 1
    return M


def random_problem(kind, cls, n, seed):
    """A seeded random (A, B, Q, R) of one class; every one has a stabilising solution except
    ``boundary_unobserved`` (a boundary mode that Q does not see: none exists).

    Parameters
    ----------
    kind : {'care', 'dare'}
        Equation.
    cls : str
        One of :data:`RANDOM_CLASSES`.
    n : int
        States, 1 to 12.
    seed : int
        Seed of the generator.

    Returns
    -------
    A, B, Q, R : ndarray
    """
    rng = np.random.default_rng([seed, n, RANDOM_CLASSES.index(cls), kind == "dare"])
    m = int(rng.integers(1, min(n, 3) + 1))
    A = rng.standard_normal((n, n)) / np.sqrt(n) * (1.0 if kind == "care" else 1.2)
    B = rng.standard_normal((n, m))
    C = rng.standard_normal((n, n))
    Q = C.T @ C
    L = rng.standard_normal((m, m))
    R = L @ L.T + 0.1 * np.eye(m)
    if cls == "singular_q":  # rank 1: detectability rests on A's stable modes and the one output
        c = rng.standard_normal((1, n))
        Q = c.T @ c
    elif cls == "near_unstabilisable":  # an unstable mode reached only through a tiny input
        T = rng.standard_normal((n, n))
        D = np.diag(rng.uniform(-1.5, -0.2, n) if kind == "care" else rng.uniform(-0.8, 0.8, n))
        D[0, 0] = 0.5 if kind == "care" else 1.5
        Bm = rng.standard_normal((n, m))
        Bm[0] *= 10.0 ** -rng.uniform(2, 6)
        A, B = T @ D @ np.linalg.inv(T), T @ Bm
    elif cls in ("boundary_observed", "boundary_unobserved"):  # modes on the axis / unit circle
        k = max(1, n // 2)
        T = rng.standard_normal((n, n))
        D = np.zeros((n, n))
        D[:k, :k] = _boundary_block(kind, rng, k)
        D[k:, k:] = (np.diag(rng.uniform(-2.0, -0.3, n - k)) if kind == "care"
                     else np.diag(rng.uniform(-0.9, 0.9, n - k)))
        Ti = np.linalg.inv(T)
        A = T @ D @ Ti
        if cls == "boundary_unobserved":  # the weight sees only the other modes
            c = np.zeros((max(1, n - k), n))
            c[:, k:] = rng.standard_normal((max(1, n - k), n - k)) if n > k else 0.0
            c = c @ Ti
            Q = c.T @ c
    elif cls == "badly_scaled":  # a diagonal similarity spreading entries over 1e-8 .. 1e8
        d = 10.0 ** rng.uniform(-4, 4, n)
        A = A * (1 / d)[:, None] * d[None, :]
        B = B / d[:, None]
        Q = Q * d[:, None] * d[None, :]
        R = R * 10.0 ** rng.uniform(-4, 4)
    return A, B, 0.5 * (Q + Q.T), 0.5 * (R + R.T)


# --------------------------------------------------------------------------------------
# mpmath reference
# --------------------------------------------------------------------------------------
def pencil_reference(kind, A, B, Q, R, dps=50):
    """Stabilising solution from the extended pencil, in mpmath; ``(X or None, boundary distance)``.

    The pencil ``M - lam N`` (size 2n + m) of the optimality conditions, as in scipy's solvers,
    is turned into a standard eigenproblem by the shift-invert map ``W = (M - sigma N)^-1 N``
    (eigenvalue ``1 / (lam - sigma)``; the m infinite eigenvalues go to 0), solved by mpmath's
    QR algorithm at ``dps`` digits on the exact float data.  ``X = U2 U1^-1`` from the
    eigenvectors of the n finite eigenvalues inside the stability region.  The boundary
    distance is the smallest ``|Re lam|`` (CARE) or ``||lam| - 1|`` (DARE) over the finite
    eigenvalues: below ``10^(-dps/2)`` the pencil has an eigenvalue on the boundary and no
    stabilising solution exists (X is None).
    """
    import mpmath as mp

    n, m = B.shape
    with mp.workdps(dps):
        Am, Bm, Qm, Rm = (mp.matrix(np.asarray(M, dtype=float).tolist()) for M in (A, B, Q, R))
        size = 2 * n + m
        M, N = mp.zeros(size, size), mp.zeros(size, size)
        for i in range(n):
            N[i, i] = 1
            for j in range(n):
                M[i, j] = Am[i, j]
                M[n + i, j] = -Qm[i, j] if kind == "care" else Qm[i, j]
                if kind == "care":
                    M[n + i, n + j] = -Am[j, i]
                else:
                    N[n + i, n + j] = -Am[j, i]
            if kind == "care":
                N[n + i, n + i] = 1
            else:
                M[n + i, n + i] = -1
            for k in range(m):
                M[i, 2 * n + k] = Bm[i, k]
                if kind == "care":
                    M[2 * n + k, n + i] = Bm[i, k]
                else:
                    N[2 * n + k, n + i] = -Bm[i, k]
        for k in range(m):
            for j in range(m):
                M[2 * n + k, 2 * n + j] = Rm[k, j]
        sigma = mp.mpc("0.3183098861837907", "0.2718281828459045")  # away from any special point
        W = mp.inverse(M - sigma * N) * N
        mu, V = mp.eig(W)
        big = max(abs(x) for x in mu)
        lam = [sigma + 1 / x if abs(x) > big * mp.mpf(10) ** (-dps // 2) else None for x in mu]
        dist = [(-mp.re(x) if kind == "care" else 1 - abs(x)) for x in lam if x is not None]
        boundary = float(min(abs(d) for d in dist))
        stable = [i for i, x in enumerate(lam) if x is not None and (-mp.re(x) if kind == "care" else 1 - abs(x)) > 0]
        if boundary < 10.0 ** (-dps / 2) or len(stable) != n:
            return None, boundary
        U1, U2 = mp.zeros(n, n), mp.zeros(n, n)
        for c, i in enumerate(stable):
            for r in range(n):
                U1[r, c], U2[r, c] = V[r, i], V[n + r, i]
        X = U2 * mp.inverse(U1)
        X = (X + X.H) / 2
        X = mp.matrix([[mp.re(X[i, j]) for j in range(n)] for i in range(n)])
        try:
            D, res = _newton_correction(kind, Am, Bm, Qm, Rm, X)
        except (np.linalg.LinAlgError, ValueError):
            D, res = None, None
        for _ in range(4 if D is not None else 0):  # a defective eigenvalue leaves the subspace short of digits
            Xn = X + mp.matrix(D.tolist())
            try:
                Dn, res_n = _newton_correction(kind, Am, Bm, Qm, Rm, Xn)
            except (np.linalg.LinAlgError, ValueError):  # the Lyapunov / Stein operator singular in double
                break
            if not res_n < res:  # an ill-conditioned step (double-precision solve) stops the polish
                break
            X, D, res = Xn, Dn, res_n
        X = np.array([[float(mp.re(X[i, j])) for j in range(n)] for i in range(n)])
    return 0.5 * (X + X.T), boundary


def _newton_correction(kind, A, B, Q, R, X):
    """Newton's correction at the mpmath X (Lyapunov / Stein solve in double) and the residual norm (mpmath)."""
    import mpmath as mp
    import scipy.linalg as sla

    if kind == "care":
        L = B.T * X
        K = mp.inverse(R) * L
        res = A.T * X + X * A - L.T * K + Q
    else:
        L = B.T * X * A
        K = mp.inverse(R + B.T * X * B) * L
        res = A.T * X * A - X - L.T * K + Q
    to_np = lambda M: np.array([[float(mp.re(M[i, j])) for j in range(M.cols)] for i in range(M.rows)])  # noqa: E731
    Ac = to_np(A) - to_np(B) @ to_np(K)
    Rd = to_np(res)
    Rd = 0.5 * (Rd + Rd.T)
    with warnings.catch_warnings():  # an ill-conditioned step is judged by the residual it leaves
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        D = sla.solve_continuous_lyapunov(Ac.T, -Rd) if kind == "care" else sla.solve_discrete_lyapunov(Ac.T, Rd)
    return D, mp.mnorm(res, "f")
