"""Frozen, named results of the Riccati solvers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RiccatiSolution", "ContinuousKalmanGains", "DiscreteKalmanGains", "PeriodicSolution", "frozen"]


def frozen(*arrays):
    """Read-only copies, so that a frozen result cannot be changed through its arrays.

    Parameters
    ----------
    *arrays : array_like
        Arrays to copy.

    Returns
    -------
    list of ndarray
        Copies with the write flag cleared.
    """
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
        Eigenvalues of the pencil ``(A - B K, E)``.  When the last Newton step only polished
        ``X`` (a step below ``1e-6 / condition``), they are computed at the gain before that
        step, which moved the closed loop by less than ``||B dK||`` (a few units of the
        forward error of the starting estimate); the stability check allows for it.
    stability_margin : float
        Distance of the closed loop to the stability boundary: ``-max Re(lambda)`` (CARE) or
        ``1 - max |lambda|`` (DARE), from ``closed_loop_eigenvalues``.  Positive means stable.
    residual : float
        Frobenius norm of the Riccati residual at ``X``, evaluated in double-double arithmetic.
    relative_residual : float
        ``residual`` divided by ``theta``: the sum of the Frobenius norms of the terms of the
        equation plus ``||Omega|| ||X||``, the first-order change of the residual under a unit
        relative change of ``X`` (:func:`cfdesign.riccati.refinement.evaluate`); so the
        correctly rounded solution scores about ``eps`` even when the gain term is small
        through cancellation (near-singular ``R``).
    condition : float
        Estimated relative condition number ``||Omega^-1|| * theta / ||X||`` where ``Omega`` is
        the Frechet derivative of the Riccati operator at ``X`` (the Lyapunov operator
        ``D -> Ac' D E + E' D Ac`` or the Stein operator ``D -> Ac' D Ac - E' D E``),
        ``||Omega^-1||`` is computed exactly in the spectral norm as ``||Omega^-1(I)||_2``
        (valid because ``Omega^-1`` is a positive map when the closed loop is stable), and
        ``theta`` is the scale of ``relative_residual``.  ``condition * relative_residual``
        bounds the relative forward error to first order.
    forward_error : float
        Estimated relative forward error ``||X - X_exact||_F / ||X||_F``: the size of the Newton
        correction computed from the accurate residual at the returned ``X`` or, when that
        correction was below four units in the last place and has been applied, its size (a
        bound of the error left).
    refinement_steps : int
        Newton steps accepted.
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    marginal : bool
        True when a closed-loop eigenvalue lies on the stability boundary within its
        uncertainty; ``X`` is then the maximal (almost stabilising) solution, not a
        stabilising one.
    method : str
        How the first estimate was obtained ('schur' for scipy, 'sign', 'doubling', 'schur-unbalanced').
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
    """Steady-state continuous Kalman-Bucy estimator (Carreira et al. eqs. (23)-(24)).

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
    """Steady-state discrete Kalman estimator in both gain forms (Carreira et al. eq. (28)).

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
    """Stabilising periodic solution of the filter-form periodic DARE (Vasconcelos et al., sec. 3).

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
        Number of phases.
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
