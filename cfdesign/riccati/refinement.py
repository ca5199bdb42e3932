"""Newton refinement (Kleinman for the CARE, Hewer for the DARE) on an accurate residual.

The residual and the gain are evaluated in double-double arithmetic, so the refined
solution is accurate far beyond what a backward-stable solver gives on ill-conditioned
problems (fast sampling, badly scaled data, nearly marginal closed loops): each Newton step
is a defect correction ``X <- X + Omega^-1(-Res(X))``.

The cost follows the problem.  The closed loop is factorised once per step that changes
the gain noticeably (:class:`~cfdesign.riccati.lyapunov.ClosedLoop`), and the last
factorisation also serves the stability certificate and the condition estimate.  After a
small step the residual is updated instead of re-evaluated: the exact identities

* CARE: ``Res(X + D) = Res(X) + Ac'DE + E'DAc - E'DB R^-1 B'DE``,
  ``K(X + D) = K(X) + R^-1 B'DE``;
* DARE: ``Res(X + D) = Res(X) + Ac'DAc - E'DE - Ac'DB (R + B'(X + D)B)^-1 B'DAc``,
  ``K(X + D) = K(X) + (R + B'(X + D)B)^-1 B'DAc``

(``Ac = A - BK(X)``) need only double precision when ``D`` is small, as rounding then
errs by ``u ||D||`` relative to terms of size ``||X||``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from ..errors import AccuracyError
from .extended import dd_add, dd_dot, dd_mul, dd_t, dd_val, two_sum
from .lyapunov import ClosedLoop
from .problem import EPS, TINY, Problem, herm, norm2_bound, rel

__all__ = ["Evaluation", "evaluate", "update", "newton_refine", "MAX_NEWTON"]

#: Most Newton (Kleinman) refinement steps taken on one solution
MAX_NEWTON = 12
# Below this bound on (step size) * (condition number) the residual is updated rather than
# re-evaluated (its error then moves X by less than 1e-6 u ||X||) and the factorisation of the
# closed loop is kept (the chord correction then agrees with Newton's to six digits).
_UPDATE_BELOW = 1e-6


@dataclass(frozen=True)
class Evaluation:
    """Residual, gain and scale of the equation at one ``X``.

    Attributes
    ----------
    res : ndarray, shape (n, n)
        Riccati residual (rounded to double from double-double).
    K : ndarray, shape (m, n)
        The gain at ``X``.
    theta : float
        Scale of a relative residual: the sizes of the terms of the equation plus the size
        of the change a unit relative change of ``X`` makes in them (see :func:`evaluate`).
    """

    res: np.ndarray  # Riccati residual (double, from double-double)
    K: np.ndarray
    theta: float  # size of the terms of the equation


def _block(x, rows, cols):
    return x[0][rows, cols], x[1][rows, cols]


def _gain_term(W, Lt):
    """``G = W^-1 L'`` and ``N = L W^-1 L'`` (double-double) from ``W`` (double or pair) and ``L'`` (pair).

    With ``G0`` from an LU solve and the residual ``r = L' - W G0`` in double-double, the
    identity ``N = L G0 + G0' r + r' W^-1 r`` is exact, and its last two terms are small
    enough for double precision; ``G = G0 + W^-1 r`` is one step of iterative refinement
    (two when ``W`` is ill-conditioned).  ``W G0`` and ``L G0`` are one stacked product.
    """
    Wh, Wl = W if isinstance(W, tuple) else (W, None)
    Lh, Ll = Lt
    Wd = Wh if Wl is None else Wh + Wl
    m = Wd.shape[0]
    if not (np.all(np.isfinite(Wd)) and np.all(np.isfinite(Lh))):
        raise AccuracyError("the gain overflows")
    lu, piv, info = lapack.dgetrf(Wd)
    rcond = lapack.dgecon(lu, np.abs(Wd).sum(axis=0).max(initial=0.0))[0] if info == 0 else 0.0
    if not rcond >= m * EPS:  # 1-norm condition estimate above 1 / (m eps)
        raise AccuracyError(f"the matrix to invert in the gain is singular (condition {1 / max(rcond, TINY):.3g})")
    G0, delta = lapack.dgetrs(lu, piv, Lh + Ll)[0], None
    stacked = np.vstack([Wh, Lh.T])
    for _ in range(2 if rcond < 1e-8 else 1):
        if delta is not None:
            G0 = G0 + delta
        hi, lo = dd_dot(stacked, G0)
        WG_lo = lo[:m] if Wl is None else lo[:m] + Wl @ G0
        r = (Lh - hi[:m]) + (Ll - WG_lo)  # L' - W G0: the high parts agree to rounding, r is small
        delta = lapack.dgetrs(lu, piv, r)[0]
    s, e = two_sum(hi[m:], Ll.T @ G0 + G0.T @ r + r.T @ delta)  # L G0 = hi + lo + Ll' G0
    return G0 + delta, (s, e + lo[m:])


def evaluate(p: Problem, X) -> Evaluation:
    r"""Residual and gain at ``X``; every product in double-double arithmetic.

    The quadratic forms are stacked so that two products give all of them: ``[A B]'(XE)`` for
    the CARE, ``V'XV`` with ``V = [A B]`` (``[A B E]``) for the DARE.

    The scale of the relative residual is

    .. math::

        \theta = \sum_i \|T_i\|_F + \|Q\|_F + \|N\|_F + \|\Omega\|\,\|X\|_F,

    with ``T_i`` the linear terms (``A'XE``, ``E'XA``; ``A'XA``, ``E'XE``), ``N`` the gain term
    (``X B R^-1 B' X`` and its generalisations) and ``||Omega|| <= 2 ||Ac||_2 ||E||_2`` (CARE) or
    ``||Ac||_2^2 + ||E||_2^2`` (DARE) the linearised operator at ``Ac = A - BK``.  The last term
    is what a relative change ``delta`` of ``X`` changes the residual by, to first order
    (``Res(X + D) = Res(X) + Omega(D) + O(||D||^2)``), so the correctly rounded solution has a
    relative residual of order ``eps``, and a relative residual ``eta`` means a backward
    error ``eta`` in ``(Q, X)`` jointly, hence a relative forward error of at most about
    ``cond * eta`` with ``cond = ||Omega^-1|| theta / ||X||``.  Without it a gain term
    ``X B R^-1 B' X`` that is small only through cancellation (``R`` near-singular: ``||BK||
    ||X||`` far above ``||X B K||``) made the rounded exact solution fail a residual test; the
    normwise backward-error scales of Ghavimi and Laub ("Backward error, sensitivity, and
    refinement of computed solutions of algebraic Riccati equations", Numer. Linear Algebra
    Appl. 2, 1995) and Sun ("Residual bounds of approximate solutions of the algebraic
    Riccati equation", Numer. Math. 76, 1997) bound the same terms by ``||A|| ||X||`` and
    ``||B R^-1 B'|| ||X||^2`` instead, which here would be 1e8 times larger and accept
    inaccurate solutions.

    Parameters
    ----------
    p : Problem
        The validated equation.
    X : ndarray, shape (n, n)
        The trial solution.

    Returns
    -------
    Evaluation
        Residual, gain and scale at ``X``.

    Raises
    ------
    AccuracyError
        The gain overflows, or the matrix inverted in the gain is singular.
    """
    n, m = p.B.shape
    top, mid = slice(0, n), slice(n, n + m)
    if p.kind == "care":
        P = dd_mul(p.AB.T, X if p.E is None else dd_dot(X, p.E))  # [[A'XE], [B'XE]]
        T = _block(P, top, slice(None))
        lin = dd_add(T, dd_t(T))
        Lt = _block(P, mid, slice(None))  # L' = B'XE + S'
        W = p.R
        terms = 2 * np.linalg.norm(dd_val(T))
    else:
        V = p.AB if p.E is None else p.ABE
        P = dd_mul(V.T, dd_dot(X, V))  # V'XV
        T1 = _block(P, top, top)
        T2 = X if p.E is None else _block(P, slice(n + m, None), slice(n + m, None))
        lin = dd_add(T1, T2, -1.0)
        Lt = _block(P, mid, top)  # L' = B'XA + S'
        W = dd_add(_block(P, mid, mid), p.R)  # R + B'XB
        terms = np.linalg.norm(dd_val(T1)) + np.linalg.norm(dd_val(T2))
    if p.has_S:
        Lt = dd_add(Lt, p.S.T)
    G, N = _gain_term(W, Lt)
    res = dd_val(dd_add(dd_add(lin, p.Q), N, -1.0))
    theta = terms + np.linalg.norm(p.Q) + np.linalg.norm(dd_val(N)) + _omega_bound(p, G) * np.linalg.norm(X)
    return Evaluation(herm(res), G, theta)


def _omega_bound(p: Problem, K):
    """An upper bound of ``||Omega||`` (Frobenius to Frobenius), the linearised Riccati operator at ``K``.

    ``Omega(D) = Ac'DE + E'DAc`` (CARE) or ``Ac'DAc - E'DE`` (DARE), ``Ac = A - BK``, so
    ``||Omega|| <= 2 ||Ac||_2 ||E||_2`` or ``||Ac||_2^2 + ||E||_2^2``.
    """
    Ac = p.A - p.B @ K
    a = norm2_bound(Ac)
    e = 1.0 if p.E is None else norm2_bound(p.E)
    return 2 * a * e if p.kind == "care" else a * a + e * e


def update(p: Problem, X, ev: Evaluation, Xn) -> Evaluation:
    """Residual and gain at ``Xn`` from those at a nearby ``X`` (see the module notes).

    Accurate to ``u ||Xn - X|| / ||X||`` relative to the terms of the equation; ``theta`` is
    kept (it changes by as little).

    Parameters
    ----------
    p : Problem
        The validated equation.
    X : ndarray, shape (n, n)
        The previous point.
    ev : Evaluation
        Its evaluation.
    Xn : ndarray, shape (n, n)
        The new point.

    Returns
    -------
    Evaluation
        Residual, gain and scale at ``Xn``.
    """
    D = Xn - X
    K = ev.K
    Ac = p.A - p.B @ K
    DE = D if p.E is None else D @ p.E
    if p.kind == "care":
        BDE = p.B.T @ DE
        dK = np.linalg.solve(p.R, BDE)
        T = Ac.T @ DE
        dres = T + T.T - BDE.T @ dK
    else:
        BDA = (p.B.T @ D) @ Ac
        dK = np.linalg.solve(p.R + p.B.T @ Xn @ p.B, BDA)
        EDE = D if p.E is None else p.E.T @ DE
        dres = Ac.T @ D @ Ac - EDE - BDA.T @ dK
    return Evaluation(herm(ev.res + dres), K + dK, ev.theta)


def newton_refine(p: Problem, X, max_steps):
    """Newton (Kleinman / Hewer) refinement in defect-correction form.

    A step is kept if it does not increase the residual beyond rounding level.  The iteration
    stops when the correction is below half a unit in the last place of ``X`` (relative), or
    right after applying one below four: left unapplied, those last few units made the
    returned ``X`` no more accurate than scipy's starting estimate (a complex DARE with ``E``
    and ``S``: 2.7 eps from the exact solution against scipy's 1.6 eps; a badly scaled CARE:
    its small entries wrong from the 13th digit).  After a step
    small enough for the residual update (``size * cond <= 1e-6``) the closed loop is not
    factorised again: the gain moved by so little that the correction computed with the
    previous factorisation (a chord step) agrees with Newton's to six digits.

    Parameters
    ----------
    p : Problem
        The validated equation.
    X : ndarray, shape (n, n)
        First estimate.
    max_steps : int
        Newton steps at most.

    Returns
    -------
    X : ndarray
        The refined solution.
    ev : Evaluation
        Its evaluation.
    steps : int
        Accepted steps.
    size : float
        Relative size of the last correction (the forward error estimate).  A last correction
        of half a unit of X's last place to four (relative) is applied before returning, so the
        returned ``X`` is the exact solution rounded, and its size then bounds the error left.
    D : ndarray
        That correction.
    cl : ClosedLoop
        The factorisation it was computed with (``cl.K`` is ``ev.K`` or, after a small last
        step, the gain before it).

    Raises
    ------
    AccuracyError
        The first evaluation fails (the gain overflows or is singular).
    """
    ev = evaluate(p, X)
    cl = ClosedLoop(p, ev.K)
    steps, last = 0, np.inf
    floor = 16 * p.n * EPS
    while True:
        D = cl.correction(ev.res)
        size = rel(D, X)
        if not np.isfinite(size):
            return X, ev, steps, np.inf, D, cl
        if steps >= max_steps or size <= EPS / 2 or size > 0.9 * last:
            return X, ev, steps, size, D, cl
        Xn = herm(X + D)
        # the update errs by about u * size relative to the terms, i.e. by cond * u * size in X,
        # and the chord correction differs from Newton's by about cond * size (relative)
        small = size * cl.condition(ev.theta, X) <= _UPDATE_BELOW
        try:
            evn = update(p, X, ev, Xn) if small else evaluate(p, Xn)
        except (AccuracyError, np.linalg.LinAlgError):
            return X, ev, steps, size, D, cl
        if np.linalg.norm(evn.res) > max(np.linalg.norm(ev.res), floor * ev.theta):
            return X, ev, steps, size, D, cl
        X, ev, last, steps = Xn, evn, size, steps + 1
        if size <= 4 * EPS:  # converged: the correction just applied bounds the error left
            return X, ev, steps, size, D, cl
        if not small:
            cl = ClosedLoop(p, ev.K)
