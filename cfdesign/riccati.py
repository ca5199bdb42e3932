"""Algebraic Riccati equations: checked, refined, named results.

Continuous (CARE), discrete (DARE) and periodic discrete (filter form) Riccati equations,
plus the two steady-state Kalman estimator helpers built on them.  Every solver

1. validates its data (shapes, finiteness, symmetry) with messages that name the matrix;
2. runs the PBH (Hautus) test on the modes that matter and names the offending mode;
3. takes scipy's Schur / QZ solution as a first estimate (a matrix-sign or doubling
   fallback where scipy fails), then refines it by Newton's method (Kleinman for the CARE,
   Hewer for the DARE) with the residual evaluated in double-double arithmetic, so the
   result is accurate far beyond what a backward-stable solver gives on ill-conditioned
   problems (fast sampling, badly scaled data, nearly marginal closed loops);
4. checks the closed loop and returns a frozen, named result, or raises an error of the
   :class:`~cfdesign.errors.RiccatiError` family.  A closed loop whose margin cannot be
   resolved from the boundary is flagged ``marginal=True`` with a warning, never passed
   off as stabilising.

Conventions follow :func:`scipy.linalg.solve_continuous_are` and
:func:`scipy.linalg.solve_discrete_are` (control form, ``'`` is the conjugate transpose).
The estimator helpers name their gain forms (``K_filter`` for the measurement update
``x+ = x- + K (z - H x-)``, ``K_predictor`` for ``x[k+1] = F x + B u + K (z - H x)``), see
DESIGN.md: the two are never mixed silently.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .errors import (
    AccuracyError,
    NoStabilisingSolutionError,
    NotDetectableError,
    NotStabilisableError,
    RiccatiError,
)

__all__ = [
    "RiccatiSolution",
    "ContinuousKalmanGains",
    "DiscreteKalmanGains",
    "PeriodicSolution",
    "care",
    "dare",
    "kalman_continuous",
    "kalman_discrete",
    "periodic_dare",
]

_EPS = np.finfo(float).eps
_SPLITTER = 134217729.0  # 2**27 + 1, Dekker's splitting constant
_MAX_NEWTON = 12


# --------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------
def _frozen(*arrays):
    """Read-only copies, so a frozen result cannot be changed through its arrays."""
    out = []
    for a in arrays:
        a = np.array(a)
        a.setflags(write=False)
        out.append(a)
    return out


@dataclass(frozen=True, eq=False)
class RiccatiSolution:
    """Stabilising solution of a CARE or DARE with its accuracy and stability record.

    Attributes
    ----------
    X : ndarray, shape (n, n)
        Hermitian solution.
    K : ndarray, shape (m, n)
        Gain, ``u = -K x``: ``R^-1 (B'XE + S')`` (CARE) or ``(R + B'XB)^-1 (B'XA + S')`` (DARE).
    closed_loop_eigenvalues : ndarray, shape (n,)
        Eigenvalues of the pencil ``(A - B K, E)``.
    stability_margin : float
        Distance of the closed loop to the stability boundary: ``-max Re(lambda)`` (CARE) or
        ``1 - max |lambda|`` (DARE).  Positive means stable.
    residual : float
        Frobenius norm of the Riccati residual at ``X``, evaluated in double-double arithmetic.
    relative_residual : float
        ``residual`` divided by the sum of the Frobenius norms of the terms of the equation.
    condition : float
        Estimated relative condition number ``||Omega^-1|| * theta / ||X||`` where ``Omega`` is
        the Frechet derivative of the Riccati operator at ``X`` (the Lyapunov operator
        ``D -> Ac' D E + E' D Ac`` or the Stein operator ``D -> Ac' D Ac - E' D E``),
        ``||Omega^-1||`` is computed exactly in the spectral norm as ``||Omega^-1(I)||_2``
        (valid because ``Omega^-1`` is a positive map when the closed loop is stable), and
        ``theta`` is the size of the terms of the equation.  ``condition * relative_residual``
        bounds the relative forward error to first order.
    forward_error : float
        Estimated relative forward error ``||X - X_exact||_F / ||X||_F``: the size of the Newton
        correction computed from the accurate residual at the returned ``X``.
    refinement_steps : int
        Newton steps accepted.
    kind : {'care', 'dare'}
    marginal : bool
        True when a closed-loop eigenvalue lies on the stability boundary within its
        uncertainty; ``X`` is then the maximal (almost stabilising) solution, not a
        stabilising one.
    method : str
        How the first estimate was obtained ('schur' for scipy, 'sign', 'doubling').
    warnings : tuple of str
        Everything a user should know about this solution (also issued as RuntimeWarning).
    """

    X: np.ndarray
    K: np.ndarray
    closed_loop_eigenvalues: np.ndarray
    stability_margin: float
    residual: float
    relative_residual: float
    condition: float
    forward_error: float
    refinement_steps: int
    kind: str
    marginal: bool
    method: str
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class ContinuousKalmanGains:
    """Steady-state continuous Kalman-Bucy estimator (seed 001 eqs. (23)-(24)).

    Attributes
    ----------
    P : ndarray
        Steady-state error covariance, ``F P + P F' - P H' R^-1 H P + Q = 0``.
    K : ndarray
        Gain ``P H' R^-1`` of ``xhat' = F xhat + B u + K (z - H xhat)``.
    closed_loop_eigenvalues : ndarray
        Eigenvalues of ``F - K H``.
    solution : RiccatiSolution
        The dual CARE ``care(F', H', Q, R)`` with its accuracy record.
    """

    P: np.ndarray
    K: np.ndarray
    closed_loop_eigenvalues: np.ndarray
    solution: RiccatiSolution


@dataclass(frozen=True, eq=False)
class DiscreteKalmanGains:
    """Steady-state discrete Kalman estimator in both gain forms (seed 001 eq. (28)).

    Attributes
    ----------
    P : ndarray
        A-priori (predicted) steady-state covariance,
        ``P = F P F' + Q - F P H' (H P H' + R)^-1 H P F'``.
    K_filter : ndarray
        ``P H' (H P H' + R)^-1`` for the measurement update ``x+ = x- + K_filter (z - H x-)``.
    K_predictor : ndarray
        ``F K_filter`` for the one-step predictor ``x[k+1] = F x + B u + K_predictor (z - H x)``.
    P_filtered : ndarray
        A-posteriori covariance ``(I - K_filter H) P``.
    closed_loop_eigenvalues : ndarray
        Eigenvalues of ``F - K_predictor H = F (I - K_filter H)``.
    solution : RiccatiSolution
        The dual DARE ``dare(F', H', Q, R)``.
    """

    P: np.ndarray
    K_filter: np.ndarray
    K_predictor: np.ndarray
    P_filtered: np.ndarray
    closed_loop_eigenvalues: np.ndarray
    solution: RiccatiSolution


@dataclass(frozen=True, eq=False)
class PeriodicSolution:
    """Stabilising periodic solution of the filter-form periodic DARE (seed 004 sec. 3).

    Attributes
    ----------
    P : tuple of ndarray
        ``P[k]``: a-priori covariance at phase ``k`` (before the measurement of phase ``k``).
    K_filter : tuple of ndarray
        ``P[k] C[k]' (C[k] P[k] C[k]' + R[k])^-1``, shape ``(n, m_k)``; exactly zero-width
        ``(n, 0)`` at phases without a measurement.
    K_predictor : tuple of ndarray
        ``A[k] K_filter[k]``.
    P_filtered : tuple of ndarray
        ``(I - K_filter[k] C[k]) P[k]``.
    monodromy_multipliers : ndarray
        Eigenvalues of ``Phi = prod_{k=N-1..0} A[k] (I - K_filter[k] C[k])`` (phase N-1 leftmost).
    period : int
    residual : float
        ``max_k ||P[k+1] - RHS_k(P[k])||_F / ||P[k+1]||_F`` with ``P[N] = P[0]``; as each stored
        ``P[k+1]`` is the right-hand side evaluated at ``P[k]``, only the wrap-around term
        ``||RHS_{N-1}(P[N-1]) - P[0]|| / ||P[0]||`` is nonzero.
    refinement_steps : int
        Newton steps on ``P[0]`` after the doubling.
    """

    P: tuple[np.ndarray, ...]
    K_filter: tuple[np.ndarray, ...]
    K_predictor: tuple[np.ndarray, ...]
    P_filtered: tuple[np.ndarray, ...]
    monodromy_multipliers: np.ndarray
    period: int
    residual: float
    refinement_steps: int


# --------------------------------------------------------------------------------------
# public solvers
# --------------------------------------------------------------------------------------
def care(A, B, Q, R, S=None, E=None, *, refine=True, rtol=1e-10):
    r"""Solve the continuous-time algebraic Riccati equation for its stabilising solution.

    .. math::

        A'XE + E'XA - (E'XB + S) R^{-1} (B'XE + S') + Q = 0,
        \qquad K = R^{-1} (B'XE + S'),

    stabilising iff all eigenvalues of the pencil ``(A - BK, E)`` have negative real part.

    Parameters
    ----------
    A, Q : array_like, shape (n, n)
        ``Q`` Hermitian (it may be indefinite).
    B : array_like, shape (n, m)
    R : array_like, shape (m, m)
        Hermitian and nonsingular.
    S : array_like, shape (n, m), optional
        Cross weight, zero by default.
    E : array_like, shape (n, n), optional
        Nonsingular descriptor matrix, identity by default.
    refine : bool
        Refine scipy's estimate by Newton (Kleinman) steps with a double-double residual.
    rtol : float
        Largest relative residual accepted; above it :class:`AccuracyError` is raised.

    Returns
    -------
    RiccatiSolution

    Raises
    ------
    RiccatiError
        Invalid data (the message names the matrix).
    NotStabilisableError, NotDetectableError
        A mode fails the PBH test where that rules out a stabilising solution.
    NoStabilisingSolutionError
        The Hamiltonian pencil has eigenvalues on the imaginary axis.
    AccuracyError
        The solution fails the residual or stability check after refinement.

    Notes
    -----
    Checks before solving: (A, B) must be stabilisable (PBH test on every eigenvalue of
    ``(A, E)`` on or right of the axis).  When the weight ``[[Q, S], [S', R]]`` is positive
    semidefinite and ``R`` positive definite, a mode on the axis that the reduced weight
    ``Q - S R^-1 S'`` cannot see (pair ``A - B R^-1 S'``) rules out a stabilising solution and
    raises :class:`NotDetectableError`; an unobservable *unstable* mode does not (the
    stabilising solution then exists and is returned).  Indefinite weights (H-infinity type
    data) are accepted; the solver decides.

    After solving: the closed loop is certified stable by a Lyapunov radius or by its
    eigenvalue margin, each compared with the uncertainty left in ``X``; an eigenvalue on the
    axis within that uncertainty gives ``marginal=True`` and a RuntimeWarning.
    """
    return _solve("care", A, B, Q, R, S, E, refine, rtol)


def dare(A, B, Q, R, S=None, E=None, *, refine=True, rtol=1e-10):
    r"""Solve the discrete-time algebraic Riccati equation for its stabilising solution.

    .. math::

        A'XA - E'XE - (A'XB + S)(R + B'XB)^{-1}(B'XA + S') + Q = 0,
        \qquad K = (R + B'XB)^{-1} (B'XA + S'),

    stabilising iff all eigenvalues of ``(A - BK, E)`` lie inside the unit circle.  ``R`` may
    be singular (``R + B'XB`` must be invertible at the solution) and ``Q`` indefinite.
    Newton refinement uses Hewer's iteration with the Stein equations solved through a
    Cayley transform of ``A - BK - E``, which keeps fast-sampling problems (``A`` close to
    ``E``) accurate.  Parameters, returns and errors as for :func:`care`.
    """
    return _solve("dare", A, B, Q, R, S, E, refine, rtol)


def kalman_continuous(F, H, Q, R):
    r"""Steady-state Kalman-Bucy gain (seed 001 eqs. (23)-(24)).

    Solves :math:`F P + P F' - P H' R^{-1} H P + Q = 0` (the dual CARE ``care(F', H', Q, R)``)
    and returns ``K = P H' R^{-1}`` for ``xhat' = F xhat + B u + K (z - H xhat)``.

    ``Q`` (process noise) must be positive semidefinite and ``R`` (measurement noise)
    positive definite.  An unstable mode that ``H`` cannot see raises
    :class:`NotDetectableError`; a mode on the imaginary axis that ``Q`` does not excite
    raises :class:`NotStabilisableError`.

    Returns
    -------
    ContinuousKalmanGains
    """
    F, H, Q, R = _covariance_data(F, H, Q, R)
    sol = _solve("care", F.conj().T, H.conj().T, Q, R, None, None, True, 1e-10, dual=True)
    P, K = sol.X, sol.K.conj().T
    return ContinuousKalmanGains(*_frozen(P, K, np.linalg.eigvals(F - K @ H)), sol)


def kalman_discrete(F, H, Q, R):
    r"""Steady-state discrete Kalman gains in filter and predictor form (seed 001 eq. (28)).

    Solves :math:`P = F P F' + Q - F P H' (H P H' + R)^{-1} H P F'` (the dual DARE
    ``dare(F', H', Q, R)``; ``P`` is the a-priori covariance) and returns

    * ``K_filter = P H' (H P H' + R)^-1`` (measurement update ``x+ = x- + K_filter (z - H x-)``),
    * ``K_predictor = F K_filter`` (``x[k+1] = F x + B u + K_predictor (z - H x)``; this is
      what python-control's ``dlqe`` returns),
    * ``P_filtered = (I - K_filter H) P``.

    Data requirements and errors as for :func:`kalman_continuous`.

    Returns
    -------
    DiscreteKalmanGains
    """
    F, H, Q, R = _covariance_data(F, H, Q, R)
    sol = _solve("dare", F.conj().T, H.conj().T, Q, R, None, None, True, 1e-10, dual=True)
    P = sol.X
    Kf = np.linalg.solve(H @ P @ H.conj().T + R, H @ P).conj().T
    Pf = _herm(P - Kf @ H @ P)
    Kp = F @ Kf
    eig = np.linalg.eigvals(F - Kp @ H)
    return DiscreteKalmanGains(*_frozen(P, Kf, Kp, Pf, eig), sol)


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------
def _matrix(name, value, shape=(None, None), *, hermitian=False):
    """Validate one matrix and return it as a 2-D float or complex array.

    ``shape`` entries of None are free; 'square' requires a square matrix.  Messages name
    the matrix: ``"Q must be 3x3 (got 2x3)"``.
    """
    try:
        M = np.array(value, dtype=complex if np.iscomplexobj(value) else float)
    except (TypeError, ValueError) as exc:
        raise RiccatiError(f"{name} must be a numeric matrix ({exc})") from None
    want_r, want_c = (None, None) if shape == "square" else shape
    if M.ndim < 2:  # a scalar is 1x1; a vector is a row where a row fits, else a column
        M = M.reshape((1, -1) if want_c == M.size and want_r in (None, 1) else (-1, 1))
    if M.ndim != 2:
        raise RiccatiError(f"{name} must be a 2-D matrix (got {M.ndim} dimensions)")
    rows, cols = M.shape
    if shape == "square":
        want_r, want_c = rows, rows
    if (want_r is not None and rows != want_r) or (want_c is not None and cols != want_c):
        want = f"{want_r if want_r is not None else rows}x{want_c if want_c is not None else cols}"
        raise RiccatiError(f"{name} must be {want} (got {rows}x{cols})")
    if not np.all(np.isfinite(M)):
        raise RiccatiError(f"{name} contains NaN or Inf")
    if hermitian:
        gap = np.max(np.abs(M - M.conj().T), initial=0.0)
        if gap > 1e-10 * max(np.max(np.abs(M), initial=0.0), np.finfo(float).tiny):
            raise RiccatiError(f"{name} must be symmetric (Hermitian): max |{name} - {name}'| = {gap:.3g}")
        M = _herm(M)
    return M


def _herm(M):
    return 0.5 * (M + M.conj().T)


def _min_eig(M):
    return np.linalg.eigvalsh(M)[0] if M.size else np.inf


def _is_psd(M):
    return _min_eig(M) >= -100 * M.shape[0] * _EPS * max(np.linalg.norm(M, 2), np.finfo(float).tiny)


def _covariance_data(F, H, Q, R):
    """Estimator data: F square, H (p, n), Q PSD and R PD covariances."""
    F = _matrix("F", F, "square")
    n = F.shape[0]
    H = _matrix("H", H, (None, n))
    Q = _matrix("Q", Q, (n, n), hermitian=True)
    R = _matrix("R", R, (H.shape[0], H.shape[0]), hermitian=True)
    if not _is_psd(Q):
        raise RiccatiError(f"Q (process noise covariance) must be positive semidefinite (min eig {_min_eig(Q):.3g})")
    if _min_eig(R) <= 0:
        raise RiccatiError(f"R (measurement noise covariance) must be positive definite (min eig {_min_eig(R):.3g})")
    return F, H, Q, R


# --------------------------------------------------------------------------------------
# the problem
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Problem:
    """Validated real data of one CARE/DARE (complex data is realified first)."""

    kind: str
    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray
    E: np.ndarray | None  # None means identity

    @property
    def n(self):
        return self.A.shape[0]

    def e_solve(self, M, transpose=False):
        """E^-1 M (or E^-T M); identity when E is None."""
        if self.E is None:
            return M
        return np.linalg.solve(self.E.T if transpose else self.E, M)

    def closed_loop(self, K):
        """Closed-loop matrix in standard form: E^-1 (A - BK), minus I for the DARE."""
        Eref = np.eye(self.n) if self.E is None else self.E
        M = (self.A - Eref) - self.B @ K if self.kind == "dare" else self.A - self.B @ K
        return self.e_solve(M)


def _problem(kind, A, B, Q, R, S, E):
    A = _matrix("A", A, "square")
    n = A.shape[0]
    B = _matrix("B", B, (n, None))
    m = B.shape[1]
    Q = _matrix("Q", Q, (n, n), hermitian=True)
    R = _matrix("R", R, (m, m), hermitian=True)
    S = np.zeros((n, m)) if S is None else _matrix("S", S, (n, m))
    E = None if E is None else _matrix("E", E, (n, n))
    if E is not None and np.linalg.cond(E) > 1 / (n * _EPS):
        raise RiccatiError(f"E must be nonsingular (condition number {np.linalg.cond(E):.3g})")
    if kind == "care" and np.linalg.cond(R) > 1 / (m * _EPS):
        raise RiccatiError(f"R must be nonsingular for the CARE (condition number {np.linalg.cond(R):.3g})")
    return A, B, Q, R, S, E


def _realify(M):
    """Real representation [[Re M, -Im M], [Im M, Re M]] (an algebra homomorphism)."""
    if M is None:
        return None
    return np.block([[M.real, -M.imag], [M.imag, M.real]])


def _complexify(M, rows, cols):
    """Inverse of _realify, averaging the two copies of each block."""
    return 0.5 * (M[:rows, :cols] + M[rows:, cols:]) + 0.5j * (M[rows:, :cols] - M[:rows, cols:])


# --------------------------------------------------------------------------------------
# double-double arithmetic (error-free transformations, Dekker / Knuth / Ogita-Rump-Oishi)
# --------------------------------------------------------------------------------------
def _two_sum(a, b):
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


def _split(a):
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def _dd_matmul(a, b):
    """a @ b for double matrices as an unevaluated pair hi + lo, accurate to ~u^2."""
    ah, al = _split(a)
    bh, bl = _split(b)
    s = np.zeros((a.shape[0], b.shape[1]))
    c = np.zeros_like(s)
    for j in range(a.shape[1]):
        x, xh, xl = a[:, j, None], ah[:, j, None], al[:, j, None]
        y, yh, yl = b[None, j, :], bh[None, j, :], bl[None, j, :]
        p = x * y
        err = ((xh * yh - p) + xh * yl + xl * yh) + xl * yl
        s, t = _two_sum(s, p)
        c += t + err
    return _two_sum(s, c)


def _dd(a):
    return a if isinstance(a, tuple) else (a, np.zeros_like(a))


def _dd_add(x, y, sign=1.0):
    x, y = _dd(x), _dd(y)
    s, e = _two_sum(x[0], sign * y[0])
    return _two_sum(s, e + x[1] + sign * y[1])


def _dd_mul(x, y):
    x, y = _dd(x), _dd(y)
    hi, lo = _dd_matmul(x[0], y[0])
    return _two_sum(hi, lo + x[0] @ y[1] + x[1] @ y[0])


def _dd_t(x):
    x = _dd(x)
    return x[0].T, x[1].T


def _dd_val(x):
    x = _dd(x)
    return x[0] + x[1]


def _dd_solve(W, Y):
    """W^-1 Y with two steps of iterative refinement on a double-double residual."""
    Wd = _dd_val(W)
    if np.linalg.cond(Wd) > 1 / (Wd.shape[0] * _EPS):
        raise AccuracyError(f"the matrix to invert in the gain is singular (condition {np.linalg.cond(Wd):.3g})")
    lu = sla.lu_factor(Wd)
    G = _dd(sla.lu_solve(lu, _dd_val(Y)))
    for _ in range(2):
        r = _dd_add(Y, _dd_mul(W, G), -1.0)
        G = _dd_add(G, sla.lu_solve(lu, _dd_val(r)))
    return G


# --------------------------------------------------------------------------------------
# residual, gain, Newton correction
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Eval:
    res: np.ndarray  # Riccati residual (double, from double-double)
    K: np.ndarray
    theta: float  # size of the terms of the equation


def _evaluate(p: _Problem, X) -> _Eval:
    """Residual and gain at X; every product in double-double arithmetic."""
    XE = X if p.E is None else _dd_mul(X, p.E)
    EX = _dd_t(XE)  # E'X (X symmetric)
    if p.kind == "care":
        T = _dd_mul(p.A.T, XE)
        lin = _dd_add(T, _dd_t(T))
        L = _dd_add(_dd_mul(EX, p.B), p.S)
        W = p.R
        terms = 2 * np.linalg.norm(_dd_val(T))
    else:
        AX = _dd_mul(p.A.T, X)
        T1 = _dd_mul(AX, p.A)
        T2 = _dd(X) if p.E is None else _dd_mul(EX, p.E)
        lin = _dd_add(T1, T2, -1.0)
        L = _dd_add(_dd_mul(AX, p.B), p.S)
        W = _dd_add(p.R, _dd_mul(_dd_mul(p.B.T, X), p.B))
        terms = np.linalg.norm(_dd_val(T1)) + np.linalg.norm(_dd_val(T2))
    G = _dd_solve(W, _dd_t(L))
    N = _dd_mul(L, G)
    res = _dd_val(_dd_add(_dd_add(lin, p.Q), N, -1.0))
    theta = terms + np.linalg.norm(p.Q) + np.linalg.norm(_dd_val(N))
    return _Eval(_herm(res), _dd_val(G), theta)


def _gain(p: _Problem, X):
    """Gain in plain double precision (for trial points)."""
    Eref = np.eye(p.n) if p.E is None else p.E
    if p.kind == "care":
        return np.linalg.solve(p.R, p.B.T @ X @ Eref + p.S.T)
    return np.linalg.solve(p.R + p.B.T @ X @ p.B, p.B.T @ X @ p.A + p.S.T)


def _stein(D, W):
    """Solve (I + D)' Y (I + D) - Y + W = 0 through the Cayley transform.

    With M = D (2I + D)^-1 the equation becomes M'Y + YM = -2 (2I + D)^-T W (2I + D)^-1;
    D (not I + D) is the input, so a closed loop close to the identity loses no digits.
    """
    F = 2 * np.eye(D.shape[0]) + D
    Fi = np.linalg.inv(F)
    M = D @ Fi
    return _herm(sla.solve_continuous_lyapunov(M.conj().T, -2 * Fi.conj().T @ W @ Fi))


def _omega_std(kind, M, W):
    """Solve M'Y + YM = -W (CARE, M = Ac) or (I + M)'Y(I + M) - Y = -W (DARE, M = Ac - I)."""
    if kind == "care":
        return _herm(sla.solve_continuous_lyapunov(M.conj().T, -W))
    return _stein(M, W)


def _omega_inv(p: _Problem, K, W):
    """Solve the linearised Riccati equation in standard coordinates Y = E'DE at the gain K.

    CARE: Ac' D E + E' D Ac = -W; DARE: Ac' D Ac - E' D E = -W, with Ac = A - BK.
    """
    return _omega_std(p.kind, p.closed_loop(K), W)


def _correction(p: _Problem, K, W):
    """The Newton correction D with Omega(D) = -W (original coordinates)."""
    return _from_standard(p, _omega_inv(p, K, W))


def _rel(a, b):
    return np.linalg.norm(a) / max(np.linalg.norm(b), np.finfo(float).tiny)


def _refine(p: _Problem, X, max_steps):
    """Newton (Kleinman / Hewer) refinement in defect-correction form.

    A step is kept if it does not increase the residual beyond rounding level.  Returns
    the refined X, its evaluation, the number of accepted steps and the relative size of
    the last correction (the forward error estimate).
    """
    ev = _evaluate(p, X)
    steps, last = 0, np.inf
    floor = 16 * p.n * _EPS
    while True:
        D = _correction(p, ev.K, ev.res)
        size = _rel(D, X)
        if not np.isfinite(size):
            return X, ev, steps, np.inf, D
        if steps >= max_steps or size <= 4 * _EPS or size > 0.9 * last:
            return X, ev, steps, size, D
        Xn = _herm(X + D)
        try:
            evn = _evaluate(p, Xn)
        except AccuracyError:
            return X, ev, steps, size, D
        if np.linalg.norm(evn.res) > max(np.linalg.norm(ev.res), floor * ev.theta):
            return X, ev, steps, size, D
        X, ev, last, steps = Xn, evn, size, steps + 1


# --------------------------------------------------------------------------------------
# first estimate and fallbacks
# --------------------------------------------------------------------------------------
def _distance(kind, lam):
    """Distance to the stability boundary, positive inside the stable region."""
    lam = np.asarray(lam)
    return -lam.real if kind == "care" else 1.0 - np.abs(lam)


def _eigs(p: _Problem, K):
    M = p.A - p.B @ K
    return sla.eigvals(M) if p.E is None else sla.eigvals(M, p.E)


def _standard_form(p: _Problem):
    """(A_r, G, Q_r) of the equivalent standard problem in Y = E'XE (needs R invertible)."""
    Rinv_St = np.linalg.solve(p.R, p.S.T)
    Ar = p.e_solve(p.A - p.B @ Rinv_St)
    Bt = p.e_solve(p.B)
    G = _herm(Bt @ np.linalg.solve(p.R, Bt.T))
    return Ar, G, _herm(p.Q - p.S @ Rinv_St)


def _from_standard(p: _Problem, Y):
    if p.E is None:
        return Y
    return _herm(p.e_solve(p.e_solve(Y, transpose=True).T, transpose=True).T)


def _sign_solution(p: _Problem):
    """CARE fallback: matrix sign function of the Hamiltonian (determinant scaling)."""
    Ar, G, Qr = _standard_form(p)
    n = p.n
    Z = np.block([[Ar, -G], [-Qr, -Ar.T]])
    for _ in range(100):
        Zi = np.linalg.inv(Z)
        c = np.exp(-np.linalg.slogdet(Z)[1] / (2 * n))
        Zn = 0.5 * (c * Z + Zi / c)
        done = np.linalg.norm(Zn - Z, 1) <= 100 * n * _EPS * np.linalg.norm(Zn, 1)
        Z = Zn
        if done:
            break
    else:
        raise AccuracyError("the matrix sign iteration did not converge")
    lhs = np.vstack([Z[:n, n:], Z[n:, n:] + np.eye(n)])
    rhs = -np.vstack([Z[:n, :n] + np.eye(n), Z[n:, :n]])
    return _from_standard(p, _herm(np.linalg.lstsq(lhs, rhs, rcond=None)[0]))


def _dare_doubling(p: _Problem):
    """DARE fallback: structure-preserving doubling on (A_r', G, Q_r) (needs R invertible)."""
    Ar, G, Qr = _standard_form(p)
    Y, _ = _sda(Ar.T, G, Qr, 1e-15)
    return _from_standard(p, Y)


def _estimates(p: _Problem):
    """Yield (X, method) first estimates: scipy's Schur/QZ solver, then the fallback."""
    solver = sla.solve_continuous_are if p.kind == "care" else sla.solve_discrete_are
    attempts = (("schur", lambda: solver(p.A, p.B, p.Q, p.R, e=p.E, s=p.S)),
                ("sign", lambda: _sign_solution(p)) if p.kind == "care" else ("doubling", lambda: _dare_doubling(p)))
    for method, attempt in attempts:
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                X = np.real(attempt())
        except (np.linalg.LinAlgError, ValueError, RiccatiError):
            continue
        if np.all(np.isfinite(X)):
            yield _herm(X), method


def _pencil_boundary(p: _Problem):
    """An eigenvalue of the Hamiltonian / symplectic pencil on the stability boundary, or None."""
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
    scale = 1.0 if p.kind == "dare" else max(1.0, np.linalg.norm(M, 1))
    close = np.abs(_distance(p.kind, lam)) <= np.sqrt(_EPS) * scale
    return lam[close][0] if np.any(close) else None


# --------------------------------------------------------------------------------------
# PBH checks
# --------------------------------------------------------------------------------------
def _fmt_mode(kind, lam):
    var = "s" if kind == "care" else "z"
    lam = complex(lam)
    if abs(lam.imag) <= 1e-12 * max(1.0, abs(lam)):
        return f"{var} = {float(f'{lam.real:.6g}')!r}"
    return f"{var} = {float(f'{lam.real:.6g}')!r}{'+' if lam.imag >= 0 else '-'}{float(f'{abs(lam.imag):.6g}')!r}j"


def _unreachable_mode(kind, A, E, B, boundary_only=False):
    """PBH test: an eigenvalue of (A, E) on/beyond the boundary with rank [A - lam E, B] < n.

    B is rescaled to the norm of A first, so only exact rank loss counts (a small but
    nonzero B is not rejected: the solution then simply is ill-conditioned).
    """
    n = A.shape[0]
    Eref = np.eye(n) if E is None else E
    lam = sla.eigvals(A) if E is None else sla.eigvals(A, E)
    d = _distance(kind, lam)
    scale = max(1.0, np.max(np.abs(lam), initial=0.0)) if kind == "care" else 1.0
    tol_b = 100 * n * _EPS * scale
    bnorm = np.linalg.norm(B)
    Bs = B * (max(np.linalg.norm(A), np.linalg.norm(Eref)) / bnorm) if bnorm > 0 else B
    tested = []
    for lam_i, d_i in zip(lam, d, strict=True):
        if (abs(d_i) if boundary_only else d_i) > tol_b or any(abs(lam_i - t) <= tol_b for t in tested):
            continue
        tested.append(lam_i)
        M = np.hstack([A - lam_i * Eref, Bs])
        smin = np.linalg.svd(M, compute_uv=False)[-1] if n else 1.0
        if smin <= 100 * n * _EPS * np.linalg.norm(M):
            return lam_i, d_i
    return None


def _raise_mode(cls, kind, lam, d, what):
    where = "unstable" if d < 0 and abs(d) > 1e-9 else (
        "on the imaginary axis" if kind == "care" else "on the unit circle")
    raise cls(f"mode at {_fmt_mode(kind, lam)} is {where} and {what} (PBH test)")


def _check_modes(kind, A, B, Q, R, S, E, dual):
    """Stabilisability of (A, B); for a PSD weight, no unobservable boundary mode of (A_r, Q_r).

    ``dual`` phrases the messages for the estimator problem (A = F', B = H').
    """
    hit = _unreachable_mode(kind, A, E, B)
    if hit is not None:
        cls, what = (NotDetectableError, "not observable from H") if dual else (
            NotStabilisableError, "not reachable from B")
        _raise_mode(cls, kind, *hit, what)
    W = np.block([[Q, S], [S.conj().T, R]])
    if _min_eig(R) <= 0 or not _is_psd(W):
        return  # indefinite weights: no PBH criterion; the solver decides
    RiS = np.linalg.solve(R, S.conj().T)
    Ar, Qr = A - B @ RiS, _herm(Q - S @ RiS)
    Eh = None if E is None else E.conj().T
    hit = _unreachable_mode(kind, Ar.conj().T, Eh, Qr, boundary_only=True)
    if hit is not None:
        lam, d = hit
        if dual:
            _raise_mode(NotStabilisableError, kind, np.conj(lam), d,
                        "not excited by the process noise Q, so no stabilising solution exists")
        _raise_mode(NotDetectableError, kind, np.conj(lam), d,
                    "not observable from the weight Q, so no stabilising solution exists")


# --------------------------------------------------------------------------------------
# the solve pipeline
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Stability:
    eigenvalues: np.ndarray
    margin: float  # eigenvalue distance to the boundary
    status: str  # 'stable' | 'marginal' | 'unstable'
    omega_inv_norm: float  # ||Omega^-1(I)||_2
    robust: float  # certified distance to instability of the closed loop
    uncertainty: float  # uncertainty of the closed-loop matrix


def _eigen_margin(p: _Problem, K, K2):
    """Eigenvalues of (A - BK, E), their margin and its first-order uncertainty.

    The uncertainty is the larger of the rounding bound ``10 eps kappa ||A - BK||`` (kappa:
    condition number of the eigenvalue nearest the boundary) and four times the change of
    the margin when the gain moves to ``K2`` (the gain after one more Newton step).
    """
    Eref = np.eye(p.n) if p.E is None else p.E
    lam, vl, vr = sla.eig(p.A - p.B @ K, Eref, left=True, right=True)
    d = _distance(p.kind, lam)
    i = int(np.argmin(d))
    kappa = np.linalg.norm(vl[:, i]) * np.linalg.norm(vr[:, i]) / max(abs(vl[:, i].conj() @ Eref @ vr[:, i]), 1e-300)
    with np.errstate(all="ignore"):
        d2 = _distance(p.kind, _eigs(p, K2)) if np.all(np.isfinite(K2)) else np.array([np.inf])
    unc = max(10 * _EPS * kappa * np.linalg.norm(p.A - p.B @ K), 4 * abs(np.min(d2) - d[i]))
    return lam, float(d[i]), float(unc)


def _lyapunov_radius(p: _Problem, K, K2):
    """Certified stability radius of the closed loop and the uncertainty of the closed loop.

    ``Y = Omega^-1(I)`` positive definite proves the closed loop stable (Lyapunov), and every
    perturbation smaller than ``1/(2||Y||)`` (CARE) or ``sqrt(||Ac||^2 + 1/||Y||) - ||Ac||``
    (DARE) keeps it so.  Both are evaluated after a diagonal balancing similarity.  The
    uncertainty is rounding plus four times the change of ``B K`` when the gain moves to
    ``K2`` (at a double root Newton only halves the error, so what remains is about a step).
    Returns (radius, uncertainty); radius 0 when no certificate exists.
    """
    M = p.closed_loop(K)
    scale = sla.matrix_balance(M, permute=False, separate=True)[1][0]
    Ms = M / scale[:, None] * scale[None, :]
    Bs, Ks = p.e_solve(p.B) / scale[:, None], K * scale[None, :]
    As = p.e_solve(p.A) / scale[:, None] * scale[None, :]
    unc = 10 * _EPS * (np.linalg.norm(As) + np.linalg.norm(Bs) * np.linalg.norm(Ks))
    unc += 4 * np.linalg.norm(Bs @ ((K2 - K) * scale[None, :]))
    try:
        Y = _omega_std(p.kind, Ms, np.eye(p.n))
        if not np.linalg.eigvalsh(Y)[0] > 0:
            return 0.0, float(unc)
    except (np.linalg.LinAlgError, ValueError):
        return 0.0, float(unc)
    ynorm = np.linalg.norm(Y, 2)
    if p.kind == "care":
        return 0.5 / ynorm, float(unc)
    ac = np.linalg.norm(Ms + np.eye(p.n), 2)
    return (1 / ynorm) / (np.sqrt(ac**2 + 1 / ynorm) + ac), float(unc)  # no cancellation


def _stability(p: _Problem, X, K, D):
    """Classify the closed loop at X, allowing for the uncertainty of X.

    'stable' when the Lyapunov radius exceeds the closed-loop uncertainty, or when the
    eigenvalue margin exceeds its own uncertainty (this resolves badly scaled, highly
    non-normal closed loops for which the norm-wise radius is pessimistic); 'unstable'
    when an eigenvalue is outside by more than its uncertainty; 'marginal' otherwise.
    """
    with np.errstate(all="ignore"):
        K2 = _gain(p, _herm(X + D)) if np.all(np.isfinite(D)) else np.full_like(K, np.inf)
    lam, margin, unc_eig = _eigen_margin(p, K, K2)
    robust, unc = _lyapunov_radius(p, K, K2)
    status = "stable" if robust > unc or margin > unc_eig else ("unstable" if margin < -unc_eig else "marginal")
    try:
        onorm = np.linalg.norm(_correction(p, K, np.eye(p.n)), 2)
    except (np.linalg.LinAlgError, ValueError):
        onorm = np.inf
    return _Stability(lam, margin, status, float(onorm), float(robust), float(unc))


@dataclass(frozen=True)
class _Candidate:
    X: np.ndarray
    ev: _Eval
    steps: int
    fwd: float
    method: str


def _best_candidate(p: _Problem, refine, rtol):
    """First estimate that refines to an accurate, (marginally) stabilising solution."""
    seen = []
    for X0, method in _estimates(p):
        try:
            with warnings.catch_warnings():  # scipy's Lyapunov solver warns near singularity
                warnings.simplefilter("ignore", RuntimeWarning)
                X, ev, steps, fwd, D = _refine(p, X0, _MAX_NEWTON if refine else 0)
                st = _stability(p, X, ev.K, D)
        except (AccuracyError, np.linalg.LinAlgError, ValueError):
            continue
        rel_res = np.linalg.norm(ev.res) / max(ev.theta, np.finfo(float).tiny)
        if st.status != "unstable" and rel_res <= rtol:
            return _Candidate(X, ev, steps, fwd, method), st, rel_res
        seen.append(f"{method}: " + (f"relative residual {rel_res:.3g}" if rel_res > rtol else "not stabilising"))
    lam = _pencil_boundary(p)
    if lam is not None:
        pencil = "Hamiltonian" if p.kind == "care" else "symplectic"
        raise NoStabilisingSolutionError(
            f"no stabilising solution: the {pencil} pencil has an eigenvalue on the stability boundary "
            f"({_fmt_mode(p.kind, lam)}); the closed loop would be marginal at best")
    tried = "; ".join(seen) if seen else "every solver failed"
    raise AccuracyError(f"could not compute an accurate stabilising {p.kind.upper()} solution ({tried})")


def _solve(kind, A, B, Q, R, S, E, refine, rtol, dual=False):
    A, B, Q, R, S, E = _problem(kind, A, B, Q, R, S, E)
    _check_modes(kind, A, B, Q, R, S, E, dual)
    cplx = any(np.iscomplexobj(M) for M in (A, B, Q, R, S, E) if M is not None)
    n, m = B.shape
    p = _Problem(kind, *(_realify(M) if cplx else M for M in (A, B, Q, R, S, E)))
    cand, st, rel_res = _best_candidate(p, refine, rtol)
    X, K, lam = cand.X, cand.ev.K, st.eigenvalues
    cond = st.omega_inv_norm * cand.ev.theta / max(np.linalg.norm(X), np.finfo(float).tiny)
    notes = _notes(kind, st, cand.fwd, R, dual)
    for note in notes:
        warnings.warn(note, RuntimeWarning, stacklevel=3)
    residual = np.linalg.norm(cand.ev.res) / (np.sqrt(2) if cplx else 1.0)
    if cplx:
        X, K = _herm(_complexify(X, n, n)), _complexify(K, m, n)
        lam = sla.eigvals(A - B @ K) if E is None else sla.eigvals(A - B @ K, E)
    return RiccatiSolution(*_frozen(X, K, lam), st.margin, float(residual), float(rel_res), float(cond),
                           float(cand.fwd), cand.steps, kind, st.status == "marginal", cand.method, tuple(notes))


def _notes(kind, st: _Stability, fwd, R, dual):
    notes = []
    if st.status == "marginal":
        where = "imaginary axis" if kind == "care" else "unit circle"
        notes.append(f"marginal solution: the closed loop cannot be certified stable, an eigenvalue lies on the "
                     f"{where} within the uncertainty of X (eigenvalue margin {st.margin:.3g}, closed-loop "
                     f"uncertainty {st.uncertainty:.3g}); X is the maximal, not a stabilising, solution")
    if fwd > 1e-6:
        notes.append(f"estimated relative forward error {fwd:.3g}: the solution is ill-conditioned")
    if kind == "care" and not dual and _min_eig(R) <= 0:
        notes.append("R is not positive definite: X solves an indefinite (game-type) problem")
    return notes


# --------------------------------------------------------------------------------------
# periodic DARE (filter form)
# --------------------------------------------------------------------------------------
def _hb(M):
    return np.conj(np.swapaxes(M, -1, -2))


def _compose(first, second):
    """(A, G, H) triple of T2 o T1 for the Riccati maps T(P) = A P (I + G P)^-1 A' + H.

    A3 = A2 (I + H1 G2)^-1 A1, G3 = G1 + A1' G2 (I + H1 G2)^-1 A1,
    H3 = H2 + A2 (I + H1 G2)^-1 H1 A2'.  Works on stacks of matrices.
    """
    A1, G1, H1 = first
    A2, G2, H2 = second
    n = A1.shape[-1]
    M = np.eye(n) + H1 @ G2
    Y = np.linalg.solve(M, np.concatenate([A1, H1 @ _hb(A2)], axis=-1))
    G3 = G1 + _hb(A1) @ (G2 @ Y[..., :n])
    H3 = H2 + A2 @ Y[..., n:]
    return A2 @ Y[..., :n], 0.5 * (G3 + _hb(G3)), 0.5 * (H3 + _hb(H3))


def _fold(A, G, H):
    """Compose the maps of all phases, T[N-1] o ... o T[0], by pairwise (tree) reduction."""
    while A.shape[0] > 1:
        k = A.shape[0] // 2 * 2
        nxt = _compose((A[0:k:2], G[0:k:2], H[0:k:2]), (A[1:k:2], G[1:k:2], H[1:k:2]))
        if A.shape[0] % 2:
            nxt = tuple(np.concatenate([x, y[-1:]]) for x, y in zip(nxt, (A, G, H), strict=True))
        A, G, H = nxt
    return A[0], G[0], H[0]


def _sda(A, G, H, tol, max_iter=64):
    """Structure-preserving doubling for P = A P (I + G P)^-1 A' + H; returns (P, iterations).

    Converges quadratically (like rho(closed loop)^(2^k)) when a stabilising solution
    exists; stops at the tolerance or when rounding stalls the change.
    """
    last = np.inf
    for it in range(1, max_iter + 1):
        A, G, Hn = _compose((A, G, H), (A, G, H))
        if not np.all(np.isfinite(Hn)):
            break
        change = _rel(Hn - H, Hn)
        if change <= tol or (change >= last and change <= 1e3 * tol):
            return Hn, it
        H, last = Hn, change
    raise NoStabilisingSolutionError("the doubling iteration did not converge: the closed loop cannot be "
                                     "made stable (a multiplier is on or outside the unit circle)")


def _phase_list(name, value, N, shape, *, hermitian=False):
    """Validated matrices of one argument for every phase; a repeated object is checked once.

    ``shape(k)`` gives the required shape at phase k; a None ``shape(k)`` means "no
    measurement" and yields an empty ``(0, 0)`` matrix (the value must then be None or empty).
    """
    seq = list(value) if isinstance(value, (list, tuple)) else [value]
    per_phase = len(seq) == N > 1
    seq = seq * N if len(seq) == 1 else seq
    out, seen = [], {}
    for k, v in enumerate(seq):
        want = shape(k)
        if want is None:
            if per_phase and v is not None and np.size(v):
                raise RiccatiError(f"{name}[{k}] must be empty (0x0) or None: phase {k} has no measurement")
            out.append(np.zeros((0, 0)))
            continue
        key = (id(v), want)
        if key not in seen:
            seen[key] = _matrix(f"{name}[{k}]", v, want, hermitian=hermitian)
        out.append(seen[key])
    return out


def _periodic_data(A, C, Q, R):
    """Validate the per-phase data; a single matrix (or a length-1 list) is constant."""
    lengths = {name: len(v) if isinstance(v, (list, tuple)) else 1 for name, v in
               (("A", A), ("C", C), ("Q", Q), ("R", R))}
    N = max(lengths.values())
    if min(lengths.values()) < 1 or any(length not in (1, N) for length in lengths.values()):
        raise RiccatiError(f"periodic data must be lists of one common length (the period) or single "
                           f"matrices; got lengths {lengths}")
    A0 = _matrix("A[0]", A[0] if isinstance(A, (list, tuple)) else A, "square")
    n = A0.shape[0]
    As = _phase_list("A", A, N, lambda k: (n, n))
    no_rows = np.zeros((0, n))
    Cin = [c if c is not None and np.size(c) else no_rows for c in (C if isinstance(C, (list, tuple)) else [C])]
    Cs = _phase_list("C", Cin if isinstance(C, (list, tuple)) else Cin[0], N, lambda k: (None, n))
    Qs = _phase_list("Q", Q, N, lambda k: (n, n), hermitian=True)
    Rs = _phase_list("R", R, N, lambda k: (Cs[k].shape[0],) * 2 if Cs[k].shape[0] else None, hermitian=True)
    for name, mats, test, what in (("Q", Qs, _is_psd, "positive semidefinite"),
                                   ("R", Rs, lambda M: _min_eig(M) > 0, "positive definite")):
        for k, M in {id(M): (k, M) for k, M in enumerate(mats)}.values():
            if M.size and not test(M):
                raise RiccatiError(f"{name}[{k}] must be {what} (min eig {_min_eig(M):.3g})")
    return As, Cs, Qs, Rs


def _chain(M):
    """M[N-1] @ ... @ M[0] by pairwise (tree) reduction of a stack."""
    while M.shape[0] > 1:
        k = M.shape[0] // 2 * 2
        prod = M[1:k:2] @ M[0:k:2]
        M = np.concatenate([prod, M[k:]]) if M.shape[0] % 2 else prod
    return M[0]


def _periodic_checks(Phi, Wo, Wc):
    """Lifted PBH tests at phase 0 on the monodromy matrix Phi = A[N-1] ... A[0].

    ``Wo`` (the folded G) has the null space of the period's observability matrix and ``Wc``
    (the folded Q) the range of its reachability Gramian.  Every multiplier with
    ``|mu| >= 1`` must be observable; none on the unit circle may be missed by the noise.
    """
    hit = _unreachable_mode("dare", Phi.conj().T, None, Wo)
    if hit is not None:
        mu, d = hit
        where = "unstable" if d < 0 else "on the unit circle"
        raise NotDetectableError(f"monodromy multiplier at {_fmt_mode('dare', np.conj(mu))} is {where} and not "
                                 f"observable from C over the period (lifted PBH test)")
    hit = _unreachable_mode("dare", Phi, None, Wc, boundary_only=True)
    if hit is not None:
        raise NotStabilisableError(f"monodromy multiplier at {_fmt_mode('dare', hit[0])} is on the unit circle and "
                                   f"not excited by the process noise Q (lifted PBH test): no stabilising solution")


def _propagate(As, Cs, Qs, Rs, P0):
    """One period of the recursion from P[0]: P[0..N], K_filter, P_filtered and Phi."""
    n = P0.shape[0]
    P, Kf, Pf, Phi = [P0], [], [], np.eye(n)
    empty = np.zeros((n, 0))
    for A, C, Q, R in zip(As, Cs, Qs, Rs, strict=True):
        Pk = P[-1]
        if C.shape[0]:
            Sk = C @ Pk @ C.conj().T + R
            K = np.linalg.solve(Sk, C @ Pk).conj().T
            Pk = Pk - K @ Sk @ K.conj().T
            Pk = 0.5 * (Pk + Pk.conj().T)
            Phi = (A - (A @ K) @ C) @ Phi
        else:
            K = empty
            Phi = A @ Phi
        Kf.append(K)
        Pf.append(Pk)
        Pn = A @ Pk @ A.conj().T + Q
        P.append(0.5 * (Pn + Pn.conj().T))
    return P, Kf, Pf, Phi


def periodic_dare(A, C, Q, R, *, tol=1e-13):
    r"""Stabilising periodic solution of the filter-form periodic DARE (seed 004 sec. 3).

    .. math::

        P_{k+1} = A_k P_k A_k' + Q_k - A_k P_k C_k' (C_k P_k C_k' + R_k)^{-1} C_k P_k A_k',
        \qquad P_N = P_0 .

    Method: each phase is the Riccati map ``T_k(P) = A_k P (I + G_k P)^-1 A_k' + Q_k`` with
    ``G_k = C_k' R_k^-1 C_k``; the N maps are composed pairwise (a tree of batched
    compositions) into one map over the period, i.e. the lifted problem at phase 0, whose
    fixed point ``P[0]`` is found by structure-preserving doubling (quadratic convergence).
    One sweep of the recursion gives ``P[1..N-1]``; if ``P[N]`` misses ``P[0]`` by more than
    ``tol``, Newton steps on ``P[0]`` (one Stein equation with the closed-loop monodromy
    matrix each) polish it against the recursion itself.

    Parameters
    ----------
    A, C, Q, R : array_like or list of array_like
        One matrix (constant) or a list over the period; every list has the same length N
        (or length 1).  ``C[k]`` may have zero rows (shape ``(0, n)``, or None) for a phase
        without a measurement; ``R[k]`` is then ``(0, 0)`` or None (a single constant ``R``
        applies to the phases that measure).  ``Q[k]`` must be positive semidefinite and
        ``R[k]`` positive definite.
    tol : float
        Relative convergence tolerance of the doubling and of the Newton polish.

    Returns
    -------
    PeriodicSolution
        ``residual`` is the relative mismatch ``||P[N] - P[0]||_F / ||P[0]||_F`` of one sweep
        of the recursion from ``P[0]``; at every other phase ``P[k+1]`` is the right-hand side
        evaluated at ``P[k]``.

    Raises
    ------
    RiccatiError
        Invalid data, named by matrix and phase (``"R[3] must be 1x1 (got 2x2)"``).
    NotDetectableError
        An unstable monodromy multiplier of A is not observable over the period.
    NotStabilisableError
        A multiplier on the unit circle is not excited by Q.
    NoStabilisingSolutionError
        The doubling failed or the periodic closed loop is not stable.
    AccuracyError
        After the Newton polish one period still misses ``P[0]`` by more than
        ``max(1e4 tol, 1e-9)`` (relative).
    """
    As, Cs, Qs, Rs = _periodic_data(A, C, Q, R)
    n, N = As[0].shape[0], len(As)
    gcache = {}
    for C_, R_ in zip(Cs, Rs, strict=True):
        if (id(C_), id(R_)) not in gcache:
            gcache[id(C_), id(R_)] = C_.conj().T @ np.linalg.solve(R_, C_) if C_.shape[0] else np.zeros((n, n))
    Gs = [gcache[id(C_), id(R_)] for C_, R_ in zip(Cs, Rs, strict=True)]
    folded = _fold(np.array(As), np.array(Gs), np.array(Qs))
    _periodic_checks(_chain(np.array(As)), folded[1], folded[2])
    P, Kf, Pf, Phi = _propagate(As, Cs, Qs, Rs, _sda(*folded, tol)[0])
    steps = 0
    while _rel(P[-1] - P[0], P[0]) > tol and steps < 4:
        P0 = _herm(P[0] + _stein(Phi.conj().T - np.eye(n), P[-1] - P[0]))
        P, Kf, Pf, Phi = _propagate(As, Cs, Qs, Rs, P0)
        steps += 1
    mult = np.linalg.eigvals(Phi)
    if np.max(np.abs(mult)) >= 1 - 100 * n * _EPS:
        raise NoStabilisingSolutionError(f"the periodic closed loop is not stable (largest multiplier "
                                         f"|mu| = {np.max(np.abs(mult)):.6g})")
    residual = _rel(P[-1] - P[0], P[0])
    if not residual <= max(1e4 * tol, 1e-9):
        raise AccuracyError(f"periodic DARE: one period of the recursion misses P[0] by {residual:.3g} "
                            f"(relative) after {steps} Newton steps")
    Kp = [A_ @ K for A_, K in zip(As, Kf, strict=True)]
    for M in (*P, *Kf, *Pf, *Kp, mult):
        M.setflags(write=False)
    return PeriodicSolution(tuple(P[:N]), tuple(Kf), tuple(Kp), tuple(Pf), mult, N, float(residual), steps)
