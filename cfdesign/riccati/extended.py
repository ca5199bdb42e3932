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

import math

import numpy as np

__all__ = ["two_sum", "dd", "dd_dot", "dd_add", "dd_mul", "dd_t", "dd_val"]


def two_sum(a, b):
    """Knuth's error-free sum: ``s + e = a + b`` exactly, ``s = fl(a + b)``.

    Parameters
    ----------
    a, b : float or ndarray
        Summands.

    Returns
    -------
    s, e : float or ndarray
        The rounded sum and its rounding error.

    Examples
    --------
    >>> from cfdesign.riccati.extended import two_sum
    >>> two_sum(1.0, 1e-17)
    (1.0, 1e-17)
    """
    s = a + b
    z = s - a
    return s, (a - (s - z)) + (b - z)


def _beta(k):
    """Exponent gap of the splitting for inner dimension ``k``.

    A slice carries at most ``53 - beta`` bits (plus one for rounding up) on the grid of its
    row or column; products of slices at one level (``a1 b2 + a2 b1``, ...) share a grid, so
    a sum of up to ``3k`` of them needs at most ``108 - 2 beta + log2(3k) <= 53`` bits: it is
    exact in double, in any summation order.
    """
    return math.ceil((56 + math.log2(3 * max(k, 1))) / 2)


def _slices(M, mu, axis, beta):
    """``M = M1 + M2 + M3 + M4`` exactly; ``M1..M3`` on grids ``2^(53 - beta)`` apart.

    The grid of each row (``axis=1``) or column (``axis=0``) starts from the power of two
    above its largest entry ``mu`` (Rump, Ogita and Oishi's ExtractVector with a fixed
    sequence of shifts).  Returns the slices ``[M1, M2, M3]`` and the remainders
    ``[M - M1, M - M1 - M2, M4]``.
    """
    sigma = np.ldexp(1.0, np.frexp(mu)[1] + beta)
    step = 2.0 ** (beta - 53)
    hi, rest, r = [], [], M
    for _ in range(3):
        q = (r + sigma) - sigma
        r = r - q
        hi.append(q)
        rest.append(r)
        sigma = sigma * step
    return hi, rest


def dd_dot(a, b):
    """``a @ b`` of two double matrices in double-double precision.

    With ``a = a1 + a2 + a3 + a4`` and ``b = b1 + b2 + b3 + b4`` (the splitting of the module
    docstring), the three levels ``a1 b1``, ``a1 b2 + a2 b1`` and ``a1 b3 + a2 b2 + a3 b1`` are
    each one exact BLAS product of stacked slices and are summed error-free; what is left is
    about ``2^-60`` of the row and column maxima and needs only double precision.  Factors
    near over- or underflow are scaled by exact powers of two first.

    Parameters
    ----------
    a : ndarray, shape (n, k)
        Left factor.
    b : ndarray, shape (k, m)
        Right factor.

    Returns
    -------
    hi, lo : ndarray, shape (n, m)
        ``hi + lo`` is the product to about twice double precision.
    """
    k = a.shape[1]
    if not (k and a.size and b.size):
        return a @ b, np.zeros((a.shape[0], b.shape[1]))
    mu_a = np.abs(a).max(axis=1, keepdims=True)
    mu_b = np.abs(b).max(axis=0, keepdims=True)
    big_a, big_b = mu_a.max(), mu_b.max()
    scale = 0
    if not (2.0**-900 < big_a < 2.0**900 and 2.0**-900 < big_b < 2.0**900):  # keep the grids clear of
        if not (big_a > 0 and big_b > 0 and np.isfinite(big_a) and np.isfinite(big_b)):  # over/underflow
            return a @ b, np.zeros((a.shape[0], b.shape[1]))
        sa, sb = -int(np.frexp(big_a)[1]), -int(np.frexp(big_b)[1])  # exact power-of-two scalings
        a, mu_a, b, mu_b = np.ldexp(a, sa), np.ldexp(mu_a, sa), np.ldexp(b, sb), np.ldexp(mu_b, sb)
        scale = sa + sb
    beta = _beta(k)
    (a1, a2, a3), (_, _, a4) = _slices(a, mu_a, 1, beta)
    (b1, b2, b3), (br2, br3, b4) = _slices(b, mu_b, 0, beta)
    As = np.hstack([a1, a2, a3])
    Bs = np.vstack([b3, b2, b1])
    s, e1 = two_sum(As[:, :k] @ b1, As[:, :2 * k] @ Bs[k:])
    s, e2 = two_sum(s, As @ Bs)
    hi, lo = two_sum(s, e1 + e2 + (As @ np.vstack([b4, br3, br2]) + a4 @ b))
    if scale:
        hi, lo = np.ldexp(hi, -scale), np.ldexp(lo, -scale)
    return hi, lo


def dd(a):
    """A double matrix as a double-double pair (zero low part); a pair is returned as it is.

    Parameters
    ----------
    a : ndarray or (ndarray, ndarray)
        A double matrix or a ``(high, low)`` pair.

    Returns
    -------
    (ndarray, ndarray)
        ``(high, low)``: ``a`` and zeros, or ``a`` itself when it is a pair.
    """
    return a if isinstance(a, tuple) else (a, np.zeros_like(a))


def dd_add(x, y, sign=1.0):
    """``x + sign * y`` for doubles or pairs.

    The result is not renormalised: its low part may be as large as the rounding error of the
    high part plus the low parts of the inputs, which keeps every later operation here exact
    to the same order (``hi + lo`` is what counts).

    Parameters
    ----------
    x : ndarray or (ndarray, ndarray)
        A double matrix or a double-double pair ``(hi, lo)``.
    y : ndarray or (ndarray, ndarray)
        Second term: a double matrix or a ``(high, low)`` pair.
    sign : float
        1 or -1.

    Returns
    -------
    (ndarray, ndarray)
        The sum as a ``(high, low)`` pair.
    """
    if not isinstance(y, tuple):
        if not isinstance(x, tuple):
            return two_sum(x, y if sign == 1.0 else sign * y)
        s, e = two_sum(x[0], y if sign == 1.0 else sign * y)
        return s, e + x[1]
    if not isinstance(x, tuple):
        s, e = two_sum(x, sign * y[0])
        return s, e + sign * y[1]
    s, e = two_sum(x[0], sign * y[0])
    return s, (e + x[1]) + sign * y[1]


def dd_mul(x, y):
    """``x @ y`` for doubles or pairs (the product of the low parts is below the precision kept).

    Parameters
    ----------
    x : ndarray or (ndarray, ndarray)
        A double matrix or a double-double pair ``(hi, lo)``.
    y : ndarray or (ndarray, ndarray)
        Right factor: a double matrix or a ``(high, low)`` pair.

    Returns
    -------
    (ndarray, ndarray)
        The product as a ``(high, low)`` pair.
    """
    if not isinstance(x, tuple):
        if not isinstance(y, tuple):
            return dd_dot(x, y)
        hi, lo = dd_dot(x, y[0])
        return hi, lo + x @ y[1]
    if not isinstance(y, tuple):
        hi, lo = dd_dot(x[0], y)
        return hi, lo + x[1] @ y
    hi, lo = dd_dot(x[0], y[0])
    return hi, lo + (x[0] @ y[1] + x[1] @ y[0])


def dd_t(x):
    """Transpose of a double matrix or a pair.

    Parameters
    ----------
    x : ndarray or (ndarray, ndarray)
        A double matrix or a double-double pair ``(hi, lo)``.

    Returns
    -------
    ndarray or (ndarray, ndarray)
        The transpose, a pair if ``x`` is one.
    """
    return (x[0].T, x[1].T) if isinstance(x, tuple) else x.T


def dd_val(x):
    """A double or a pair rounded to double.

    Parameters
    ----------
    x : ndarray or (ndarray, ndarray)
        A double matrix or a double-double pair ``(hi, lo)``.

    Returns
    -------
    ndarray
        ``high + low`` rounded to double.
    """
    return x[0] + x[1] if isinstance(x, tuple) else x
