"""Public CARE / DARE solvers and the steady-state Kalman estimators built on them.

Every solver

1. validates its data (shapes, finiteness, symmetry) with messages that name the matrix;
2. takes scipy's Schur / QZ solution as a first estimate (a matrix-sign or doubling
   fallback where scipy fails, then scipy without balancing), then refines it by Newton's method (Kleinman for the CARE,
   Hewer for the DARE) with the residual evaluated in double-double arithmetic;
3. certifies the closed loop and returns a frozen, named result;
4. when no certified stabilising solution comes out (or only a marginal one), runs the PBH
   (Hautus) tests and names the offending mode, or raises another error of the
   :class:`~cfdesign.errors.RiccatiError` family.  A certified stabilising gain is itself
   the proof that those tests pass, so a solvable problem does not pay for them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..blas import small_problem
from ..errors import AccuracyError, NoStabilisingSolutionError, RiccatiError
from .fallbacks import estimates, pencil_boundary
from .problem import EPS, TINY, Problem, complexify, herm, realify
from .refinement import MAX_NEWTON, Evaluation, newton_refine
from .results import ContinuousKalmanGains, DiscreteKalmanGains, RiccatiSolution, frozen
from .stability import Stability, stability
from .validation import check_modes, covariance_data, fmt_mode, min_eig, problem_data

__all__ = ["care", "dare", "kalman_continuous", "kalman_discrete"]


@small_problem
def care(A, B, Q, R, S=None, E=None, *, refine=True, rtol=1e-10):
    r"""Solve the continuous-time algebraic Riccati equation for its stabilising solution.

    .. math::

        A'XE + E'XA - (E'XB + S) R^{-1} (B'XE + S') + Q = 0,
        \qquad K = R^{-1} (B'XE + S'),

    stabilising iff all eigenvalues of the pencil ``(A - BK, E)`` have negative real part.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    Q : array_like, shape (n, n)
        State weight, Hermitian (it may be indefinite).
    R : array_like, shape (m, m)
        Input weight, hermitian and nonsingular.
    S : array_like, shape (n, m), optional
        Cross weight, zero by default.
    E : array_like, shape (n, n), optional
        Nonsingular descriptor matrix, identity by default.
    refine : bool
        Refine scipy's estimate by Newton (Kleinman) steps with a double-double residual.
    rtol : float
        Largest relative residual accepted, between 0 and 1; above it
        :class:`~cfdesign.errors.AccuracyError` is raised.

    Returns
    -------
    RiccatiSolution
        The solution ``X``, its gain, residual and stability record.

    Raises
    ------
    RiccatiError
        Invalid data (the message names the matrix), or ``rtol`` not between 0 and 1.
    NotStabilisableError, NotDetectableError
        A mode fails the PBH test where that rules out a stabilising solution.
    NoStabilisingSolutionError
        The Hamiltonian pencil has eigenvalues on the imaginary axis.
    AccuracyError
        The solution fails the residual or stability check after refinement.

    Notes
    -----
    The closed loop is certified stable by a Lyapunov radius or by its eigenvalue margin,
    each compared with the uncertainty left in ``X``; an eigenvalue on the axis within that
    uncertainty gives ``marginal=True`` and a RuntimeWarning.

    Mode checks (run when no certified stabilising solution is found, or it is marginal):
    (A, B) must be stabilisable (PBH test on every eigenvalue of ``(A, E)`` on or right of
    the axis).  When the weight ``[[Q, S], [S', R]]`` is positive semidefinite and ``R``
    positive definite, a mode on the axis that the reduced weight ``Q - S R^-1 S'`` cannot
    see (pair ``A - B R^-1 S'``) rules out a stabilising solution and raises
    :class:`~cfdesign.errors.NotDetectableError`; an unobservable *unstable* mode does not (the stabilising
    solution then exists and is returned).  Indefinite weights (H-infinity type data) are
    accepted; the solver decides.

    Cost: scipy's solver, one double-double residual, one real Schur factorisation of the
    closed loop per Newton step that moves the gain noticeably, and a few triangular
    Sylvester solves with it (see :mod:`cfdesign.riccati.refinement`).
    """
    return _solve("care", A, B, Q, R, S, E, refine, rtol)


@small_problem
def dare(A, B, Q, R, S=None, E=None, *, refine=True, rtol=1e-10):
    r"""Solve the discrete-time algebraic Riccati equation for its stabilising solution.

    .. math::

        A'XA - E'XE - (A'XB + S)(R + B'XB)^{-1}(B'XA + S') + Q = 0,
        \qquad K = (R + B'XB)^{-1} (B'XA + S'),

    stabilising iff all eigenvalues of ``(A - BK, E)`` lie inside the unit circle.  ``R`` may
    be singular (``R + B'XB`` must be invertible at the solution) and ``Q`` indefinite.
    Newton refinement uses Hewer's iteration with the Stein equations solved through a
    Cayley transform of ``A - BK - E``, which keeps fast-sampling problems (``A`` close to
    ``E``) accurate.  Argument order as :func:`scipy.linalg.solve_discrete_are`.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    Q : array_like, shape (n, n)
        State weight, Hermitian (it may be indefinite).
    R : array_like, shape (m, m)
        Input weight, hermitian.
    S : array_like, shape (n, m), optional
        Cross weight, zero by default.
    E : array_like, shape (n, n), optional
        Nonsingular descriptor matrix, identity by default.
    refine : bool
        Refine scipy's estimate by Newton (Hewer) steps with a double-double residual.
    rtol : float
        Largest relative residual accepted, between 0 and 1; above it
        :class:`~cfdesign.errors.AccuracyError` is raised.

    Returns
    -------
    RiccatiSolution
        ``X``, ``K``, closed-loop eigenvalues, residual, condition estimate, ``marginal``,
        warnings.

    Raises
    ------
    RiccatiError
        Invalid data (the message names the matrix), or ``rtol`` not between 0 and 1.
    NotStabilisableError, NotDetectableError
        A mode fails the PBH test where that rules out a stabilising solution.
    NoStabilisingSolutionError
        The symplectic pencil has eigenvalues on the unit circle.
    AccuracyError
        The solution fails the residual or stability check after refinement.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.riccati import dare
    >>> sol = dare(np.eye(1), np.eye(1), np.eye(1), np.eye(1))   # X = golden ratio
    >>> round(float(sol.X[0, 0]), 12), round(float(sol.K[0, 0]), 12)
    (1.61803398875, 0.61803398875)
    """
    return _solve("dare", A, B, Q, R, S, E, refine, rtol)


@small_problem
def kalman_continuous(F, H, Q, R):
    """Steady-state Kalman-Bucy gain (Carreira et al. eqs. (23)-(24)).

    Solves :math:`F P + P F' - P H' R^{-1} H P + Q = 0` (the dual CARE ``care(F', H', Q, R)``)
    and returns ``K = P H' R^{-1}`` for ``xhat' = F xhat + B u + K (z - H xhat)``.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State matrix (1/s).
    H : array_like, shape (m, n)
        Measurement matrix.
    Q : array_like, shape (n, n)
        Process-noise PSD, positive semidefinite.
    R : array_like, shape (m, m)
        Measurement-noise PSD, positive definite.

    Returns
    -------
    ContinuousKalmanGains
        ``P`` (error covariance), ``K`` and the closed-loop eigenvalues of ``F - K H``.

    Raises
    ------
    RiccatiError
        Invalid data (shapes, symmetry, definiteness; the message names the matrix).
    NotDetectableError
        An unstable mode that ``H`` cannot see.
    NotStabilisableError
        A mode on the imaginary axis that ``Q`` does not excite.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.riccati import kalman_continuous
    >>> est = kalman_continuous([[0.0, 1.0], [0.0, 0.0]], [[1.0, 0.0]], np.diag([0.0, 1.0]), [[1.0]])
    >>> est.K.ravel().round(6).tolist()          # the second-order CF with crossover 1 rad/s
    [1.414214, 1.0]
    """
    F, H, Q, R = covariance_data(F, H, Q, R)
    sol = _solve("care", F.conj().T, H.conj().T, Q, R, None, None, True, 1e-10, dual=True)
    P, K = sol.X, sol.K.conj().T
    return ContinuousKalmanGains(*frozen(P, K, np.linalg.eigvals(F - K @ H)), sol)


@small_problem
def kalman_discrete(F, H, Q, R):
    """Steady-state discrete Kalman gains in filter and predictor form (Carreira et al. eq. (28)).

    Solves :math:`P = F P F' + Q - F P H' (H P H' + R)^{-1} H P F'` (the dual DARE
    ``dare(F', H', Q, R)``; ``P`` is the a-priori covariance) and returns

    * ``K_filter = P H' (H P H' + R)^-1`` (measurement update ``x+ = x- + K_filter (z - H x-)``),
    * ``K_predictor = F K_filter`` (``x[k+1] = F x + B u + K_predictor (z - H x)``; this is
      what python-control's ``dlqe`` returns),
    * ``P_filtered = (I - K_filter H) P``.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Discrete state matrix.
    H : array_like, shape (m, n)
        Measurement matrix.
    Q : array_like, shape (n, n)
        Per-sample process-noise covariance, positive semidefinite.
    R : array_like, shape (m, m)
        Per-sample measurement-noise covariance, positive definite.

    Returns
    -------
    DiscreteKalmanGains
        ``P``, ``K_filter``, ``K_predictor``, ``P_filtered`` and the closed-loop eigenvalues.

    Raises
    ------
    RiccatiError
        Invalid data (the message names the matrix).
    NotDetectableError
        An unstable mode that ``H`` cannot see.
    NotStabilisableError
        A mode on the unit circle that ``Q`` does not excite.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.riccati import kalman_discrete
    >>> F = np.array([[1.0, 0.1], [0.0, 1.0]]); H = np.array([[1.0, 0.0]])
    >>> est = kalman_discrete(F, H, np.diag([1e-4, 1e-6]), np.array([[1e-2]]))
    >>> np.allclose(est.K_predictor, F @ est.K_filter)
    True
    """
    F, H, Q, R = covariance_data(F, H, Q, R)
    sol = _solve("dare", F.conj().T, H.conj().T, Q, R, None, None, True, 1e-10, dual=True)
    P = sol.X
    Kf = np.linalg.solve(H @ P @ H.conj().T + R, H @ P).conj().T
    Pf = herm(P - Kf @ H @ P)
    Kp = F @ Kf
    eig = np.linalg.eigvals(F - Kp @ H)
    return DiscreteKalmanGains(*frozen(P, Kf, Kp, Pf, eig), sol)


# --------------------------------------------------------------------------------------
# the solve pipeline
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Candidate:
    X: np.ndarray
    ev: Evaluation
    steps: int
    fwd: float
    method: str


def _best_candidate(p: Problem, refine, rtol):
    """First estimate that refines to an accurate, (marginally) stabilising solution.

    Returns ``(candidate, stability, relative residual)``, or ``(None, what was tried)``: one
    ``(description, condition estimate)`` per estimate, the condition None unless Newton stalled.
    """
    seen = []
    for X0, method in estimates(p):
        try:
            with warnings.catch_warnings():  # LAPACK-based solvers may warn near singularity
                warnings.simplefilter("ignore", RuntimeWarning)
                X, ev, steps, fwd, D, cl = newton_refine(p, X0, MAX_NEWTON if refine else 0)
                st = stability(p, X, ev.K, D, cl)
        except (AccuracyError, np.linalg.LinAlgError, ValueError):
            continue
        rel_res = np.linalg.norm(ev.res) / max(ev.theta, TINY)
        if st.status != "unstable" and rel_res <= rtol:
            return _Candidate(X, ev, steps, fwd, method), st, rel_res
        what = f"relative residual {rel_res:.3g}" if rel_res > rtol else (
            "not stabilising" if st.status == "unstable" else "marginal")
        cond = None
        if not fwd <= _UNCONVERGED:  # Newton stalls: its correction is a sizeable part of X
            cond = st.omega_inv_norm * ev.theta / max(np.linalg.norm(X), TINY)
            what += f", Newton's correction {fwd:.2g} of X, condition estimate {cond:.2g}"
        seen.append((f"{method}: {what}", cond))
    return None, seen


# a Newton correction above this fraction of X at the end of the refinement: not converged
_UNCONVERGED = 1e-2


def _no_solution(p: Problem, seen):
    lam = pencil_boundary(p)
    if lam is not None:
        pencil = "Hamiltonian" if p.kind == "care" else "symplectic"
        raise NoStabilisingSolutionError(
            f"no stabilising solution: the {pencil} pencil has an eigenvalue on the stability boundary "
            f"({fmt_mode(p.kind, lam)}); the closed loop would be marginal at best")
    tried = "; ".join(what for what, _ in seen) if seen else "every solver failed"
    # "not determined" only when every estimate says so: Newton stalls and the condition estimate there is
    # at least 1 / eps.  A stall at a smaller estimate (CAREX 2.8 at eps = 1e6: 9e4 at the sign-function
    # estimate, 2.5e16 at the solution) only shows that the estimate was too far from the solution.
    why = ": every first estimate failed to refine to one"
    if seen and all(cond is not None and cond * EPS >= 1 for _, cond in seen):
        why = (": the equation is too ill-conditioned for double precision (Newton's method on the double-double "
               "residual does not converge from any estimate, where the condition estimate is at least 1/eps: "
               "X is not determined to any digit)")
    raise AccuracyError(f"could not compute an accurate stabilising {p.kind.upper()} solution{why} ({tried})")


def _solve(kind, A, B, Q, R, S, E, refine, rtol, dual=False):
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float, np.floating)) or not 0 < rtol < 1:  # NaN too
        raise RiccatiError(f"rtol must be a relative residual tolerance between 0 and 1, got {rtol!r}")
    A, B, Q, R, S, E = problem_data(kind, A, B, Q, R, S, E)
    cplx = any(np.iscomplexobj(M) for M in (A, B, Q, R, S, E) if M is not None)
    n, m = B.shape
    p = Problem(kind, *(realify(M) if cplx else M for M in (A, B, Q, R, S, E)))
    found = _best_candidate(p, refine, rtol)
    if found[0] is None or found[1].status == "marginal":
        # A certified stabilising solution proves (A, B) stabilisable and rules out an unobservable mode on
        # the boundary, so the PBH tests only run when they can tell the user something: they name the mode.
        check_modes(kind, A, B, Q, R, S, E, dual)
    if found[0] is None:
        _no_solution(p, found[1])
    cand, st, rel_res = found
    X, K, lam = cand.X, cand.ev.K, st.eigenvalues
    cond = st.omega_inv_norm * cand.ev.theta / max(np.linalg.norm(X), TINY)
    notes = _notes(kind, st, cand.fwd, R, dual)
    for note in notes:
        warnings.warn(note, RuntimeWarning, stacklevel=3)
    residual = np.linalg.norm(cand.ev.res) / (np.sqrt(2) if cplx else 1.0)
    if cplx:
        X, K = herm(complexify(X, n, n)), complexify(K, m, n)
        lam = sla.eigvals(A - B @ K) if E is None else sla.eigvals(A - B @ K, E)
    return RiccatiSolution(*frozen(X, K, lam), st.margin, float(residual), float(rel_res), float(cond),
                           float(cand.fwd), cand.steps, kind, st.status == "marginal", cand.method, tuple(notes))


def _notes(kind, st: Stability, fwd, R, dual):
    notes = []
    if st.status == "marginal":
        where = "imaginary axis" if kind == "care" else "unit circle"
        notes.append(f"marginal solution: the closed loop cannot be certified stable, an eigenvalue lies on the "
                     f"{where} within the uncertainty of X (eigenvalue margin {st.margin:.3g}, its uncertainty "
                     f"{st.margin_uncertainty:.3g}); X is the maximal, not a stabilising, solution")
    if fwd > 1e-6:
        notes.append(f"estimated relative forward error {fwd:.3g}: the solution is ill-conditioned")
    if kind == "care" and not dual and min_eig(R) <= 0:
        notes.append("R is not positive definite: X solves an indefinite (game-type) problem")
    return notes
