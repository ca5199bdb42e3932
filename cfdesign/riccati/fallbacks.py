"""First estimates: scipy's Schur / QZ solvers, and the fallbacks when they fail.

* CARE: the matrix sign function of the Hamiltonian with determinant scaling (Roberts,
  "Linear model reduction and solution of the algebraic Riccati equation by use of the
  sign function"; Byers, "Solving the algebraic Riccati equation with the matrix sign
  function").
* DARE: the structure-preserving doubling algorithm (Chu, Fan, Lin and Wang,
  "Structure-preserving algorithms for periodic discrete-time algebraic Riccati
  equations"), which the periodic solver also uses on the map of a whole period.

Also the test that decides "no stabilising solution" when every estimate fails: an
eigenvalue of the Hamiltonian / symplectic pencil on the stability boundary.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from ..errors import AccuracyError, NoStabilisingSolutionError, RiccatiError
from .problem import EPS, Problem, distance, from_standard, herm, rel, standard_form

__all__ = ["compose", "sda", "sign_solution", "dare_doubling", "estimates", "pencil_boundary"]


def _hb(M):
    return np.conj(np.swapaxes(M, -1, -2))


def compose(first, second):
    """The ``(A, G, H)`` triple of ``T2 o T1`` for the Riccati maps ``T(P) = A P (I + G P)^-1 A' + H``.

    ``A3 = A2 (I + H1 G2)^-1 A1``, ``G3 = G1 + A1' G2 (I + H1 G2)^-1 A1``,
    ``H3 = H2 + A2 (I + H1 G2)^-1 H1 A2'``.  Works on stacks of matrices.

    Parameters
    ----------
    first, second : (ndarray, ndarray, ndarray)
        The triples of ``T1`` and ``T2``, each matrix of shape (..., n, n).

    Returns
    -------
    (ndarray, ndarray, ndarray)
        The triple of the composition; ``G3`` and ``H3`` symmetrised.
    """
    A1, G1, H1 = first
    A2, G2, H2 = second
    n = A1.shape[-1]
    M = np.eye(n) + H1 @ G2
    Y = np.linalg.solve(M, np.concatenate([A1, H1 @ _hb(A2)], axis=-1))
    G3 = G1 + _hb(A1) @ (G2 @ Y[..., :n])
    H3 = H2 + A2 @ Y[..., n:]
    return A2 @ Y[..., :n], 0.5 * (G3 + _hb(G3)), 0.5 * (H3 + _hb(H3))


def sda(A, G, H, tol, max_iter=64):
    """Structure-preserving doubling for ``P = A P (I + G P)^-1 A' + H``.

    Converges quadratically (like ``rho(closed loop)^(2^k)``) when a stabilising solution
    exists; stops at the tolerance or when rounding stalls the change.

    Parameters
    ----------
    A, G, H : ndarray, shape (n, n)
        The map (``G``, ``H`` symmetric positive semidefinite).
    tol : float
        Relative change at which the iteration stops.
    max_iter : int
        Doublings at most.

    Returns
    -------
    P : ndarray, shape (n, n)
        The fixed point.
    iterations : int
        Doublings made.

    Raises
    ------
    NoStabilisingSolutionError
        The iteration does not converge: the closed loop cannot be made stable.
    """
    last = np.inf
    for it in range(1, max_iter + 1):
        A, G, Hn = compose((A, G, H), (A, G, H))
        if not np.all(np.isfinite(Hn)):
            break
        change = rel(Hn - H, Hn)
        if change <= tol or (change >= last and change <= 1e3 * tol):
            return Hn, it
        H, last = Hn, change
    raise NoStabilisingSolutionError("the doubling iteration did not converge: the closed loop cannot be "
                                     "made stable (a multiplier is on or outside the unit circle)")


def sign_solution(p: Problem):
    """CARE fallback: the matrix sign function of the Hamiltonian, with determinant scaling.

    Parameters
    ----------
    p : Problem
        The validated equation.

    Returns
    -------
    ndarray, shape (n, n)
        The solution estimate ``X``.

    Raises
    ------
    AccuracyError
        The sign iteration does not converge.
    """
    Ar, G, Qr = standard_form(p)
    n = p.n
    Z = np.block([[Ar, -G], [-Qr, -Ar.T]])
    for _ in range(100):
        Zi = np.linalg.inv(Z)
        c = np.exp(-np.linalg.slogdet(Z)[1] / (2 * n))
        Zn = 0.5 * (c * Z + Zi / c)
        done = np.linalg.norm(Zn - Z, 1) <= 100 * n * EPS * np.linalg.norm(Zn, 1)
        Z = Zn
        if done:
            break
    else:
        raise AccuracyError("the matrix sign iteration did not converge")
    lhs = np.vstack([Z[:n, n:], Z[n:, n:] + np.eye(n)])
    rhs = -np.vstack([Z[:n, :n] + np.eye(n), Z[n:, :n]])
    return from_standard(p, herm(np.linalg.lstsq(lhs, rhs, rcond=None)[0]))


def dare_doubling(p: Problem):
    """DARE fallback: structure-preserving doubling on ``(A_r', G, Q_r)`` (needs ``R`` invertible).

    Parameters
    ----------
    p : Problem
        The validated equation.

    Returns
    -------
    ndarray, shape (n, n)
        The solution estimate ``X``.

    Raises
    ------
    NoStabilisingSolutionError
        The doubling does not converge.
    """
    Ar, G, Qr = standard_form(p)
    Y, _ = sda(Ar.T, G, Qr, 1e-15)
    return from_standard(p, Y)


def estimates(p: Problem):
    """First estimates of the solution: scipy's Schur/QZ solver, the fallback, then scipy unbalanced.

    Lazy: an estimate is computed only when the caller asks for the next one (the previous
    ones failed), so a problem the first estimate solves pays for nothing else.

    scipy balances the Hamiltonian / symplectic pencil by a symplectic diagonal similarity
    (a state scaling found from ``|H| + |J|``; ``G`` is not scaled against ``Q``) and then
    refuses when its stable basis fails a symmetry test.  On graded data the balancing can
    cost the digits that test needs: CAREX 2.6 at eps = 1e-11 (``R = 1e-11 I``, closed-loop
    eigenvalues from -1e11 to -582) is refused with it ("eigenvalues too close to the
    imaginary axis") and solved without it (first estimate 2e-9 from the solution, which
    Newton's method then reaches).  Hence the last attempt, ``balanced=False``.

    Parameters
    ----------
    p : Problem
        The validated equation.

    Yields
    ------
    X : ndarray, shape (n, n)
        A finite Hermitian estimate.
    method : str
        ``schur``, ``sign`` (CARE) or ``doubling`` (DARE), ``schur-unbalanced``.
    """
    solver = sla.solve_continuous_are if p.kind == "care" else sla.solve_discrete_are
    attempts = (("schur", lambda: solver(p.A, p.B, p.Q, p.R, e=p.E, s=p.S)),
                ("sign", lambda: sign_solution(p)) if p.kind == "care" else ("doubling", lambda: dare_doubling(p)),
                ("schur-unbalanced", lambda: solver(p.A, p.B, p.Q, p.R, e=p.E, s=p.S, balanced=False)))
    for method, attempt in attempts:
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                X = np.real(attempt())
        except (np.linalg.LinAlgError, ValueError, RiccatiError):
            continue
        if np.all(np.isfinite(X)):
            yield herm(X), method


def pencil_boundary(p: Problem):
    """An eigenvalue of the Hamiltonian / symplectic pencil on the stability boundary.

    Such an eigenvalue rules a stabilising solution out.

    Parameters
    ----------
    p : Problem
        The validated equation.

    Returns
    -------
    complex or None
        An eigenvalue within ``sqrt(eps)`` times the smaller of the pencil's norm (continuous time;
        1 in discrete time) and the eigenvalue's size (at least 1) of the boundary, or None.
    """
    n, m = p.B.shape
    E = np.eye(n) if p.E is None else p.E
    Z, Zb, Zm = np.zeros((n, n)), np.zeros((m, n)), np.zeros((m, m))
    if p.kind == "care":  # E x' = A x + B u, E' l' = -(Q x + S u + A' l), 0 = S' x + R u + B' l
        M = np.block([[p.A, Z, p.B], [-p.Q, -p.A.T, -p.S], [p.S.T, p.B.T, p.R]])
        N = np.block([[E, Z, Zb.T], [Z, E.T, Zb.T], [Zb, Zb, Zm]])
    else:  # the same optimality conditions in discrete time, with l[k+1] = z l[k]
        M = np.block([[p.A, Z, p.B], [p.Q, -E.T, p.S], [p.S.T, Zb, p.R]])
        N = np.block([[E, Z, Zb.T], [Z, -p.A.T, Zb.T], [Zb, -p.B.T, Zm]])
    with np.errstate(all="ignore"):
        lam = sla.eigvals(M, N)
    lam = lam[np.isfinite(lam)]
    # within sqrt(eps) of the pencil's norm (a double eigenvalue moves that far under rounding of the data),
    # and of the eigenvalue's own size: a real s = 612 of a pencil of norm 1e12 (CAREX 2.6, eps = 1e-11, whose
    # stabilising solution exists) was named on the boundary; such a case now ends as an accuracy error
    scale = 1.0 if p.kind == "dare" else max(1.0, np.linalg.norm(M, 1))
    close = np.abs(distance(p.kind, lam)) <= np.sqrt(EPS) * np.minimum(scale, np.maximum(1.0, np.abs(lam)))
    return lam[close][0] if np.any(close) else None
