"""Double-double arithmetic on matrices, vectorised on top of BLAS.

A double-double number is an unevaluated pair ``hi + lo`` of doubles carrying about twice
the precision of double arithmetic.  Sums use Knuth's error-free TwoSum.  Products use the
error-free splitting of Ozaki, Ogita, Oishi and Rump ("Error-free transformations of
matrix multiplication by using fast routines of matrix multiplication and its
applications"): each factor is cut into slices of at most ``53 - beta`` significant bits
on a grid common to its row (left factor) or column (right factor), chosen so that the
product of two slices is computed *exactly* by an ordinary floating-point matrix
multiplication, whatever order BLAS sums in.  So every product below is a handful of BLAS
calls rather than a loop in Python.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import AccuracyError
from .problem import EPS

__all__ = ["two_sum", "dd", "dd_dot", "dd_add", "dd_mul", "dd_t", "dd_val", "dd_solve"]


def two_sum(a, b):
    """``s + e = a + b`` exactly, ``s = fl(a + b)`` (Knuth)."""
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


def _beta(k):
    """Exponent gap of the splitting for inner dimension ``k``.

    Slices carry at most ``54 - beta`` bits on a common grid, so a sum of ``k`` products of
    two slices needs at most ``108 - 2 beta + log2 k <= 53`` bits: it is exact in double.
    """
    return int(np.ceil((55 + np.log2(max(k, 1))) / 2))


def _extract(M, axis, beta):
    """``M = hi + rest`` exactly, ``hi`` on the grid ``2^(e + beta - 53)`` of its row (axis=1)
    or column (axis=0), where ``2^e`` bounds that row or column (Rump's ExtractVector)."""
    mu = np.max(np.abs(M), axis=axis, keepdims=True)
    sigma = np.ldexp(1.0, np.frexp(mu)[1] + beta)
    hi = (M + sigma) - sigma
    return hi, M - hi


def dd_dot(a, b):
    """``a @ b`` of two double matrices as a pair ``(hi, lo)``.

    Each factor is cut into three slices and a remainder below ``2^-(3 (53 - beta))`` of its
    row (column) maximum: ``a = a1 + a2 + a3 + a4``.  The six slice products ``a_i b_j`` with
    ``i + j <= 4`` are exact and summed error-free; the rest is a remainder product about
    ``2^-60`` times smaller, which double precision evaluates well below ``u^2`` of the row
    and column maxima.
    """
    beta = _beta(a.shape[1])
    a1, ar2 = _extract(a, 1, beta)
    a2, ar3 = _extract(ar2, 1, beta)
    a3, a4 = _extract(ar3, 1, beta)
    b1, br2 = _extract(b, 0, beta)
    b2, br3 = _extract(br2, 0, beta)
    b3, b4 = _extract(br3, 0, beta)
    s, err = a1 @ b1, 0.0
    for p in (a1 @ b2, a2 @ b1, a1 @ b3, a2 @ b2, a3 @ b1):
        s, e = two_sum(s, p)
        err = err + e
    return two_sum(s, err + (a1 @ b4 + a2 @ br3 + a3 @ br2 + a4 @ b))


def dd(a):
    """``a`` as a double-double pair (a double gets a zero low part)."""
    return a if isinstance(a, tuple) else (a, np.zeros_like(a))


def dd_add(x, y, sign=1.0):
    """``x + sign * y``."""
    if not isinstance(y, tuple):
        if not isinstance(x, tuple):
            return two_sum(x, sign * y)
        s, e = two_sum(x[0], sign * y)
        return two_sum(s, e + x[1])
    x = dd(x)
    s, e = two_sum(x[0], sign * y[0])
    return two_sum(s, e + x[1] + sign * y[1])


def dd_mul(x, y):
    """``x @ y`` for doubles or pairs (the product of the low parts is below the precision kept)."""
    if not isinstance(x, tuple) and not isinstance(y, tuple):
        return dd_dot(x, y)
    x, y = dd(x), dd(y)
    hi, lo = dd_dot(x[0], y[0])
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
    lu = sla.lu_factor(Wd, check_finite=False)
    G = sla.lu_solve(lu, dd_val(Y), check_finite=False)
    for _ in range(2):
        r = dd_add(Y, dd_mul(W, G), -1.0)
        G = dd_add(G, sla.lu_solve(lu, dd_val(r), check_finite=False))
    return G
