"""Periodic discrete Riccati equation in filter form (multirate Kalman gains).

A fast sensor (the IMU) drives the prediction every step; slower sensors measure every
N-th step, so the measurement matrix ``C[k]`` and noise ``R[k]`` are periodic (Vasconcelos
et al., sec. 3).  The periodic stabilising solution is found by composing the Riccati maps
of all phases into the map of one period and running structure-preserving doubling on it
(Chu, Fan, Lin and Wang, "Structure-preserving algorithms for periodic discrete-time
algebraic Riccati equations"), then polishing ``P[0]`` by Newton steps against the
recursion itself.
"""

from __future__ import annotations

import numpy as np

from ..blas import small_problem
from ..errors import AccuracyError, NoStabilisingSolutionError, NotDetectableError, NotStabilisableError, RiccatiError
from .api import dare
from .fallbacks import compose, sda
from .lyapunov import stein
from .problem import EPS, herm, rel
from .results import PeriodicSolution
from .validation import fmt_mode, is_psd, matrix, min_eig, mode_position, unreachable_mode

__all__ = ["periodic_dare"]


def _fold(A, G, H):
    """Compose the maps of all phases, T[N-1] o ... o T[0], by pairwise (tree) reduction."""
    while A.shape[0] > 1:
        k = A.shape[0] // 2 * 2
        nxt = compose((A[0:k:2], G[0:k:2], H[0:k:2]), (A[1:k:2], G[1:k:2], H[1:k:2]))
        if A.shape[0] % 2:
            nxt = tuple(np.concatenate([x, y[-1:]]) for x, y in zip(nxt, (A, G, H), strict=True))
        A, G, H = nxt
    return A[0], G[0], H[0]


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
            seen[key] = matrix(f"{name}[{k}]", v, want, hermitian=hermitian)
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
    A0 = matrix("A[0]", A[0] if isinstance(A, (list, tuple)) else A, "square")
    n = A0.shape[0]
    As = _phase_list("A", A, N, lambda k: (n, n))
    no_rows = np.zeros((0, n))
    Cin = [c if c is not None and np.size(c) else no_rows for c in (C if isinstance(C, (list, tuple)) else [C])]
    Cs = _phase_list("C", Cin if isinstance(C, (list, tuple)) else Cin[0], N, lambda k: (None, n))
    Qs = _phase_list("Q", Q, N, lambda k: (n, n), hermitian=True)
    Rs = _phase_list("R", R, N, lambda k: (Cs[k].shape[0],) * 2 if Cs[k].shape[0] else None, hermitian=True)
    for name, mats, test, what in (("Q", Qs, is_psd, "positive semidefinite"),
                                   ("R", Rs, lambda M: min_eig(M) > 0, "positive definite")):
        for k, M in {id(M): (k, M) for k, M in enumerate(mats)}.values():
            if M.size and not test(M):
                raise RiccatiError(f"{name}[{k}] must be {what} (min eig {min_eig(M):.3g})")
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
    hit = unreachable_mode("dare", Phi.conj().T, None, Wo)
    if hit is not None:
        mu = np.conj(hit[0])
        where = mode_position("dare", mu, *hit[1:])
        raise NotDetectableError(f"monodromy multiplier at {fmt_mode('dare', mu)} is {where} and not observable from C "
                                 f"over the period (lifted PBH test)")
    hit = unreachable_mode("dare", Phi, None, Wc, boundary_only=True)
    if hit is not None:
        where = mode_position("dare", *hit)
        raise NotStabilisableError(f"monodromy multiplier at {fmt_mode('dare', hit[0])} is {where} and not excited by "
                                   f"the process noise Q (lifted PBH test): no stabilising solution")


def _lifted_dare(A, G, H):
    """Stabilising fixed point of the period's map ``P = A P (I + G P)^-1 A' + H`` by :func:`dare`.

    Doubling computes the map's iterates from ``P = 0``; on an unstable mode that the noise
    ``H`` does not excite they stay at 0, the fixed point of an unstable closed loop, although
    the stabilising one exists when the mode is observable.  With ``G = L L'`` (the lifted
    measurement term, positive semidefinite) the map is the standard filter DARE
    ``dare(A', L, H, I)``, whose Schur estimate and Newton refinement find the stabilising
    solution.
    """
    w, V = np.linalg.eigh(G)
    keep = w > G.shape[0] * EPS * max(w[-1], 0.0)
    if not np.any(keep):
        raise NoStabilisingSolutionError("the periodic closed loop is not stable and nothing is measured over the "
                                         "period")
    L = V[:, keep] * np.sqrt(w[keep])
    return dare(A.conj().T, L, H, np.eye(L.shape[1])).X


def _propagate(As, Cs, Qs, Rs, P0):
    r"""One period of the recursion from P[0]: P[0..N], K_filter, P_filtered and Phi.

    Every measurement update is in Joseph form,

    .. math::

        P^+_k = (I - K_k C_k) P_k (I - K_k C_k)' + K_k R_k K_k'

    (Bucy and Joseph, *Filtering for Stochastic Processes with Applications to Guidance*,
    1968; Simon, *Optimal State Estimation*, 2006, eq. 5.19).  It equals ``P_k - K_k S_k K_k'``
    in exact arithmetic, but that difference cancels to the rounding of ``P_k`` when ``R_k`` is
    far below ``C_k P_k C_k'`` (a precise sensor after a long prediction), and the lost digits
    do not stay in the posterior: the next prediction multiplies them by ``A`` over the rest of
    the period.  With an unstable ``A`` (a 1.05 multiplier per step, one measurement every 400
    steps) the prior came out 9 % too small with a zero residual, since the fixed-point check
    ran the same recursion; a 1e-12 m GPS beside a 100 Hz IMU gave a posterior of 1.3e-23 m^2
    for 1e-24.  The Joseph form is stationary in ``K``, so the rounding of the gain enters only
    to second order and a small posterior keeps its relative accuracy.
    """
    n = P0.shape[0]
    eye = np.eye(n)
    P, Kf, Pf, Phi = [P0], [], [], np.eye(n)
    empty = np.zeros((n, 0))
    for A, C, Q, R in zip(As, Cs, Qs, Rs, strict=True):
        Pk = P[-1]
        if C.shape[0]:
            Sk = C @ Pk @ C.conj().T + R
            try:
                K = np.linalg.solve(Sk, C @ Pk).conj().T
            except np.linalg.LinAlgError:  # (numpy's 'Singular matrix' reached users as an internal error)
                raise AccuracyError(_singular_innovation(len(Kf), Pk, C, R)) from None
            IKC = eye - K @ C
            Pk = IKC @ Pk @ IKC.conj().T + K @ R @ K.conj().T
            Pk = 0.5 * (Pk + Pk.conj().T)
            Phi = (A @ IKC) @ Phi
        else:
            K = empty
            Phi = A @ Phi
        Kf.append(K)
        Pf.append(Pk)
        Pn = A @ Pk @ A.conj().T + Q
        P.append(0.5 * (Pn + Pn.conj().T))
    return P, Kf, Pf, Phi


def _singular_innovation(k, P, C, R) -> str:
    """Why ``C P C' + R`` of phase ``k`` is singular in doubles: two readings of one state whose
    noise variances lie below the rounding of that state's predicted variance."""
    prior = float(np.max(np.abs(np.diag(C @ P @ C.conj().T))))
    noise = float(np.min(np.abs(np.diag(R))))
    return (f"the innovation covariance C P C' + R at phase {k} is singular in double precision: a measurement "
            f"noise variance of {noise:.3g} is below the rounding of a predicted variance of {prior:.3g} "
            "(the noise figures and the sample time span more than a double resolves: a slower sensor's noise "
            "in density units at a very low rate?)")


@small_problem
def periodic_dare(A, C, Q, R, *, tol=1e-13):
    r"""Stabilising periodic solution of the filter-form periodic DARE (Vasconcelos et al., sec. 3).

    .. math::

        P_{k+1} = A_k P_k A_k' + Q_k - A_k P_k C_k' (C_k P_k C_k' + R_k)^{-1} C_k P_k A_k',
        \qquad P_N = P_0 .

    Method: each phase is the Riccati map ``T_k(P) = A_k P (I + G_k P)^-1 A_k' + Q_k`` with
    ``G_k = C_k' R_k^-1 C_k``; the N maps are composed pairwise (a tree of batched
    compositions) into one map over the period, i.e. the lifted problem at phase 0, whose
    fixed point ``P[0]`` is found by structure-preserving doubling (quadratic convergence).
    Where the doubling's fixed point does not stabilise the period (an unstable mode that ``Q``
    does not excite: the iterates from ``P = 0`` stay at 0 on it), ``P[0]`` is instead the
    stabilising solution of the lifted map as a standard DARE (:func:`~cfdesign.riccati.dare`).
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
        Relative convergence tolerance of the doubling and of the Newton polish, between 0 and 1.

    Returns
    -------
    PeriodicSolution
        ``residual`` is the relative mismatch ``||P[N] - P[0]||_F / ||P[0]||_F`` of one sweep
        of the recursion from ``P[0]``; at every other phase ``P[k+1]`` is the right-hand side
        evaluated at ``P[k]``.

    Raises
    ------
    RiccatiError
        Invalid data, named by matrix and phase (``"R[3] must be 1x1 (got 2x2)"``), or a product of
        A over the period that overflows, or ``tol`` not between 0 and 1.
    NotDetectableError
        An unstable monodromy multiplier of A is not observable over the period.
    NotStabilisableError
        A multiplier on the unit circle is not excited by Q.
    NoStabilisingSolutionError
        The doubling failed or the periodic closed loop is not stable.
    AccuracyError
        After the Newton polish one period still misses ``P[0]`` by more than
        ``max(1e4 tol, 1e-9)`` (relative), or a phase's innovation covariance ``C P C' + R`` is
        singular in double precision (noise variances below the rounding of the prediction's).
    """
    if isinstance(tol, bool) or not isinstance(tol, (int, float, np.floating)) or not 0 < tol < 1:  # NaN too
        raise RiccatiError(f"tol must be a relative tolerance between 0 and 1, got {tol!r}")
    As, Cs, Qs, Rs = _periodic_data(A, C, Q, R)
    n, N = As[0].shape[0], len(As)
    gcache = {}
    for C_, R_ in zip(Cs, Rs, strict=True):
        if (id(C_), id(R_)) not in gcache:
            gcache[id(C_), id(R_)] = C_.conj().T @ np.linalg.solve(R_, C_) if C_.shape[0] else np.zeros((n, n))
    Gs = [gcache[id(C_), id(R_)] for C_, R_ in zip(Cs, Rs, strict=True)]
    with np.errstate(over="ignore", invalid="ignore"):  # checked below, named
        folded = _fold(np.array(As), np.array(Gs), np.array(Qs))
        Phi = _chain(np.array(As))
    if not (np.all(np.isfinite(Phi)) and all(np.all(np.isfinite(M)) for M in folded)):
        raise RiccatiError(f"the product of A over the {N} phases (the monodromy matrix) overflows a double "
                           f"(entries of A up to {max(np.abs(M).max() for M in As):.3g})")
    _periodic_checks(Phi, folded[1], folded[2])
    try:
        P, Kf, Pf, Phi = _propagate(As, Cs, Qs, Rs, sda(*folded, tol)[0])
        stable = np.max(np.abs(np.linalg.eigvals(Phi))) < 1
    except NoStabilisingSolutionError:
        stable = False
    if not stable:  # doubling from P = 0 stays at 0 on an unstable mode that Q does not excite
        P, Kf, Pf, Phi = _propagate(As, Cs, Qs, Rs, _lifted_dare(*folded))
    steps = 0
    while rel(P[-1] - P[0], P[0]) > tol and steps < 4:
        P0 = herm(P[0] + stein(Phi.conj().T - np.eye(n), P[-1] - P[0]))
        P, Kf, Pf, Phi = _propagate(As, Cs, Qs, Rs, P0)
        steps += 1
    mult = np.linalg.eigvals(Phi)
    if np.max(np.abs(mult)) >= 1 - 100 * n * EPS:
        raise NoStabilisingSolutionError(f"the periodic closed loop is not stable (largest multiplier "
                                         f"|mu| = {np.max(np.abs(mult)):.6g})")
    residual = rel(P[-1] - P[0], P[0])
    if not residual <= max(1e4 * tol, 1e-9):
        raise AccuracyError(f"periodic DARE: one period of the recursion misses P[0] by {residual:.3g} "
                            f"(relative) after {steps} Newton steps")
    Kp = [A_ @ K for A_, K in zip(As, Kf, strict=True)]
    for M in (*P, *Kf, *Pf, *Kp, mult):
        M.setflags(write=False)
    return PeriodicSolution(tuple(P[:N]), tuple(Kf), tuple(Kp), tuple(Pf), mult, N, float(residual), steps)
