"""Newton refinement (Kleinman for the CARE, Hewer for the DARE) on an accurate residual.

The residual and the gain are evaluated in double-double arithmetic, so the refined
solution is accurate far beyond what a backward-stable solver gives on ill-conditioned
problems (fast sampling, badly scaled data, nearly marginal closed loops): each Newton step
is a defect correction ``X <- X + Omega^-1(-Res(X))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import AccuracyError
from .extended import dd, dd_add, dd_mul, dd_solve, dd_t, dd_val
from .lyapunov import correction
from .problem import EPS, Problem, herm, rel

__all__ = ["Evaluation", "evaluate", "newton_refine", "MAX_NEWTON"]

MAX_NEWTON = 12


@dataclass(frozen=True)
class Evaluation:
    """Residual, gain and scale of the equation at one ``X``."""

    res: np.ndarray  # Riccati residual (double, from double-double)
    K: np.ndarray
    theta: float  # size of the terms of the equation


def evaluate(p: Problem, X) -> Evaluation:
    """Residual and gain at ``X``; every product in double-double arithmetic."""
    XE = X if p.E is None else dd_mul(X, p.E)
    EX = dd_t(XE)  # E'X (X symmetric)
    if p.kind == "care":
        T = dd_mul(p.A.T, XE)
        lin = dd_add(T, dd_t(T))
        L = dd_add(dd_mul(EX, p.B), p.S)
        W = p.R
        terms = 2 * np.linalg.norm(dd_val(T))
    else:
        AX = dd_mul(p.A.T, X)
        T1 = dd_mul(AX, p.A)
        T2 = dd(X) if p.E is None else dd_mul(EX, p.E)
        lin = dd_add(T1, T2, -1.0)
        L = dd_add(dd_mul(AX, p.B), p.S)
        W = dd_add(p.R, dd_mul(dd_mul(p.B.T, X), p.B))
        terms = np.linalg.norm(dd_val(T1)) + np.linalg.norm(dd_val(T2))
    G = dd_solve(W, dd_t(L))
    N = dd_mul(L, G)
    res = dd_val(dd_add(dd_add(lin, p.Q), N, -1.0))
    theta = terms + np.linalg.norm(p.Q) + np.linalg.norm(dd_val(N))
    return Evaluation(herm(res), dd_val(G), theta)


def newton_refine(p: Problem, X, max_steps):
    """Newton (Kleinman / Hewer) refinement in defect-correction form.

    A step is kept if it does not increase the residual beyond rounding level.  Returns
    the refined ``X``, its evaluation, the number of accepted steps, the relative size of
    the last correction (the forward error estimate) and that correction.
    """
    ev = evaluate(p, X)
    steps, last = 0, np.inf
    floor = 16 * p.n * EPS
    while True:
        D = correction(p, ev.K, ev.res)
        size = rel(D, X)
        if not np.isfinite(size):
            return X, ev, steps, np.inf, D
        if steps >= max_steps or size <= 4 * EPS or size > 0.9 * last:
            return X, ev, steps, size, D
        Xn = herm(X + D)
        try:
            evn = evaluate(p, Xn)
        except AccuracyError:
            return X, ev, steps, size, D
        if np.linalg.norm(evn.res) > max(np.linalg.norm(ev.res), floor * ev.theta):
            return X, ev, steps, size, D
        X, ev, last, steps = Xn, evn, size, steps + 1
