"""Certification of the closed loop at a computed solution, allowing for its uncertainty.

A closed loop is 'stable' when a Lyapunov certificate (a stability radius) or the
eigenvalue margin exceeds the uncertainty left in ``X``; 'unstable' when an eigenvalue is
outside the stable region by more than its uncertainty; 'marginal' otherwise.  A marginal
solution is never passed off as stabilising.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..linear import balancing
from .lyapunov import ClosedLoop
from .problem import EPS, Problem, distance, gain, herm, norm2_bound

__all__ = ["Stability", "stability", "closed_loop_eigenvalues"]


@dataclass(frozen=True)
class Stability:
    """How stable the closed loop of a solution is, allowing for its uncertainty.

    Attributes
    ----------
    eigenvalues : ndarray of complex
        Eigenvalues of the pencil ``(A - BK, E)``.
    margin : float
        Their smallest distance to the stability boundary (positive inside).
    status : {'stable', 'marginal', 'unstable'}
        ``stable`` (certified), ``marginal`` (too close to the boundary to certify) or ``unstable``.
    omega_inv_norm : float
        ``||Omega^-1(I)||_2`` of the linearised Riccati operator.
    robust : float
        Certified distance to instability of the closed loop (0 without a certificate).
    uncertainty : float
        Uncertainty of the closed-loop matrix (what ``robust`` is compared with).
    margin_uncertainty : float
        Uncertainty of ``margin`` from the eigenvalue test (what ``margin`` is compared with:
        it decides 'marginal' and 'unstable'); NaN when the Lyapunov certificate settled the
        status and the eigenvalue test did not run.
    """
    eigenvalues: np.ndarray
    margin: float  # eigenvalue distance to the boundary
    status: str  # 'stable' | 'marginal' | 'unstable'
    omega_inv_norm: float  # ||Omega^-1(I)||_2
    robust: float  # certified distance to instability of the closed loop
    uncertainty: float  # uncertainty of the closed-loop matrix
    margin_uncertainty: float = float("nan")  # uncertainty of the eigenvalue margin (eigenvalue test only)


def closed_loop_eigenvalues(p: Problem, K):
    """Eigenvalues of the pencil ``(A - BK, E)``.

    Parameters
    ----------
    p : Problem
        The validated equation.
    K : ndarray, shape (m, n)
        Gain.

    Returns
    -------
    ndarray of complex, shape (n,)
        The closed-loop eigenvalues (``s`` for the CARE, ``z`` for the DARE).
    """
    M = p.A - p.B @ K
    return sla.eigvals(M) if p.E is None else sla.eigvals(M, p.E)


def _eigen_margin(p: Problem, K, K2):
    """Eigenvalues of (A - BK, E), their margin and its first-order uncertainty.

    The uncertainty is the larger of the rounding bound and four times the change of the margin
    when the gain moves to ``K2`` (the gain after one more Newton step).  The rounding bound is
    the smaller of the normwise ``10 eps kappa ||A - BK||`` and an a posteriori one: with the
    eigenpair's residual ``r = M x - lam E x``, the exact eigenvalue is ``lam + y'r / y'Ex`` to
    first order, and forming ``M = A - BK`` and ``r`` in double changes that by at most a few
    ``eps |y|' (|A| + |B||K| + |lam||E|) |x| / |y'Ex|``.  For a stiff loop the normwise bound
    is the scale of the fast modes: ``diag(-1e7, -2e-8)`` read 2.2e-8 beside a margin of 2e-8,
    exact in its entries (a posteriori: 3e-22).  Kappa, the condition number of the eigenvalue
    nearest the boundary, and the norm are those of the balanced closed loop ``D^-1 (A - BK) D``
    when ``E`` is the identity, which is what the eigensolver factorises: unbalanced, the
    companion-form loop of a 30-state integrator chain read an uncertainty of 0.225 beside a
    margin of 0.0523 that its eigenvalues computed in 80 digits confirm.
    """
    M = p.A - p.B @ K
    W = np.abs(p.A) + np.abs(p.B) @ np.abs(K)  # entrywise size of what M is formed from
    if p.E is None:  # balanced first, as LAPACK's eigensolver does: kappa and ||M|| of what it factorises
        scale = balancing(M)
        M = M / scale[:, None] * scale[None, :]
        W = W / scale[:, None] * scale[None, :]
    Eref = np.eye(p.n) if p.E is None else p.E
    lam, vl, vr = sla.eig(M, Eref, left=True, right=True)
    d = distance(p.kind, lam)
    i = int(np.argmin(d))
    x, y = vr[:, i], vl[:, i]
    yEx = max(abs(y.conj() @ Eref @ x), 1e-300)
    normwise = 10 * EPS * np.linalg.norm(y) * np.linalg.norm(x) / yEx * np.linalg.norm(M)
    # a posteriori: lam_exact - lam = y_exact' r / y_exact' E x with r = M x - lam E x, plus what forming M
    # and r in double can change, entrywise
    ax = np.abs(x)
    r = M @ x - lam[i] * (Eref @ x)
    entrywise = 10 * (p.n + p.B.shape[1]) * EPS * (np.abs(y) @ (W @ ax + abs(lam[i]) * (np.abs(Eref) @ ax)))
    posterior = (abs(y.conj() @ r) + entrywise) / yEx
    with np.errstate(all="ignore"):
        d2 = distance(p.kind, closed_loop_eigenvalues(p, K2)) if np.all(np.isfinite(K2)) else np.array([np.inf])
    unc = max(min(normwise, posterior), 4 * abs(np.min(d2) - d[i]))
    return lam, float(d[i]), float(unc)


def _lyapunov_radius(p: Problem, cl: ClosedLoop, K, K2):
    """Certified stability radius of the closed loop and the uncertainty of the closed loop.

    ``Y = Omega^-1(I)`` positive definite proves the closed loop stable (Lyapunov), and every
    perturbation smaller than ``1/(2||Y||)`` (CARE) or ``sqrt(||Ac||^2 + 1/||Y||) - ||Ac||``
    (DARE) keeps it so.  Both are evaluated after the diagonal balancing similarity of
    ``cl``.  The uncertainty is rounding, plus the distance from the factorised closed loop
    (gain ``cl.K``) to the one at ``K``, plus four times the change of ``B K`` when the gain
    moves to ``K2`` (at a double root Newton only halves the error, so what remains is about
    a step).  Returns (radius, uncertainty); radius 0 when no certificate exists.
    """
    scale, Ms = cl.scale, cl.Ms
    if cl.unscaled:
        As, Bs, Ks = p.EinvA, p.EinvB, K
    else:
        Bs, Ks = p.EinvB / scale[:, None], K * scale[None, :]
        As = p.EinvA / scale[:, None] * scale[None, :]
    unc = 10 * EPS * (np.linalg.norm(As) + np.linalg.norm(Bs) * np.linalg.norm(Ks))
    unc += 4 * np.linalg.norm(Bs @ ((K2 - K) * scale[None, :]))
    if cl.K is not K:
        unc += np.linalg.norm(Bs @ ((K - cl.K) * scale[None, :]))
    ev = cl.certificate
    if ev is None or not ev[0] > 0:
        return 0.0, float(unc)
    ynorm = ev[-1]
    if p.kind == "care":
        return 0.5 / ynorm, float(unc)
    Ac = Ms + np.eye(p.n)
    for ac in (norm2_bound(Ac), None):  # first with an upper bound of ||Ac||_2 (a smaller, still valid radius)
        if ac is None:
            ac = np.sqrt(np.linalg.eigvalsh(Ac.T @ Ac)[-1])  # ||Ac||_2
        radius = (1 / ynorm) / (np.sqrt(ac**2 + 1 / ynorm) + ac)  # no cancellation
        if radius > unc:
            break
    return radius, float(unc)


def stability(p: Problem, X, K, D, cl: ClosedLoop):
    """Classify the closed loop at ``X`` (gain ``K``), allowing for the uncertainty of ``X``.

    'stable' when the Lyapunov radius exceeds the closed-loop uncertainty, or when the
    eigenvalue margin exceeds its own uncertainty (this resolves badly scaled, highly
    non-normal closed loops for which the norm-wise radius is pessimistic); 'unstable' when
    an eigenvalue is outside by more than its uncertainty; 'marginal' otherwise.  The
    eigenvalue test (left and right eigenvectors, and the eigenvalues at the next Newton gain)
    is only run when the Lyapunov certificate does not settle the question.

    Parameters
    ----------
    p : Problem
        The validated equation.
    X : ndarray, shape (n, n)
        The solution.
    K : ndarray, shape (m, n)
        Its gain.
    D : ndarray, shape (n, n)
        The last Newton correction (the size of the uncertainty of ``X``).
    cl : ClosedLoop
        The closed loop factorised at ``K`` or, after a last Newton step too small to
        refactorise for, at the gain before it; the certificate then allows for the
        difference.

    Returns
    -------
    Stability
        Eigenvalues, margin, status and the certified distance to instability.
    """
    with np.errstate(all="ignore"):
        K2 = gain(p, herm(X + D)) if np.all(np.isfinite(D)) else np.full_like(K, np.inf)
    robust, unc = _lyapunov_radius(p, cl, K, K2)
    unc_eig = float("nan")
    if robust > unc:
        status = "stable"
        if p.E is None:
            lam, margin = cl.eigenvalues, cl.margin
        else:  # the pencil's own eigenvalues (QZ), rather than those of E^-1 (A - BK)
            lam = closed_loop_eigenvalues(p, K)
            margin = float(np.min(distance(p.kind, lam)))
    else:
        lam, margin, unc_eig = _eigen_margin(p, K, K2)
        status = "stable" if margin > unc_eig else ("unstable" if margin < -unc_eig else "marginal")
    return Stability(lam, margin, status, cl.omega_inv_norm, float(robust), float(unc), unc_eig)
