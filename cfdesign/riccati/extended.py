"""Double-double arithmetic on matrices (error-free transformations).

A double-double number is an unevaluated pair ``hi + lo`` of doubles; the operations below
keep about twice the precision of double arithmetic.  They rest on the error-free
transformations of Dekker ("A floating-point technique for extending the available
precision") and Knuth (TwoSum), as used by Ogita, Rump and Oishi ("Accurate sum and dot
product").
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import AccuracyError
from .problem import EPS

__all__ = ["two_sum", "dd", "dd_matmul", "dd_add", "dd_mul", "dd_t", "dd_val", "dd_solve"]

_SPLITTER = 134217729.0  # 2**27 + 1, Dekker's splitting constant


def two_sum(a, b):
    """``s + e = a + b`` exactly, ``s = fl(a + b)`` (Knuth)."""
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


def _split(a):
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def dd_matmul(a, b):
    """``a @ b`` for double matrices as an unevaluated pair ``hi + lo``, accurate to ~u^2."""
    ah, al = _split(a)
    bh, bl = _split(b)
    s = np.zeros((a.shape[0], b.shape[1]))
    c = np.zeros_like(s)
    for j in range(a.shape[1]):
        x, xh, xl = a[:, j, None], ah[:, j, None], al[:, j, None]
        y, yh, yl = b[None, j, :], bh[None, j, :], bl[None, j, :]
        p = x * y
        err = ((xh * yh - p) + xh * yl + xl * yh) + xl * yl
        s, t = two_sum(s, p)
        c += t + err
    return two_sum(s, c)


def dd(a):
    """``a`` as a double-double pair (a double gets a zero low part)."""
    return a if isinstance(a, tuple) else (a, np.zeros_like(a))


def dd_add(x, y, sign=1.0):
    """``x + sign * y``."""
    x, y = dd(x), dd(y)
    s, e = two_sum(x[0], sign * y[0])
    return two_sum(s, e + x[1] + sign * y[1])


def dd_mul(x, y):
    """``x @ y`` (the product of the low parts is below the working precision)."""
    x, y = dd(x), dd(y)
    hi, lo = dd_matmul(x[0], y[0])
    return two_sum(hi, lo + x[0] @ y[1] + x[1] @ y[0])


def dd_t(x):
    """Transpose."""
    x = dd(x)
    return x[0].T, x[1].T


def dd_val(x):
    """Rounded to double."""
    x = dd(x)
    return x[0] + x[1]


def dd_solve(W, Y):
    """``W^-1 Y`` with two steps of iterative refinement on a double-double residual."""
    Wd = dd_val(W)
    if np.linalg.cond(Wd) > 1 / (Wd.shape[0] * EPS):
        raise AccuracyError(f"the matrix to invert in the gain is singular (condition {np.linalg.cond(Wd):.3g})")
    lu = sla.lu_factor(Wd)
    G = dd(sla.lu_solve(lu, dd_val(Y)))
    for _ in range(2):
        r = dd_add(Y, dd_mul(W, G), -1.0)
        G = dd_add(G, sla.lu_solve(lu, dd_val(r)))
    return G
