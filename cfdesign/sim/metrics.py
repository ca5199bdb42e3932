"""Errors and Monte-Carlo statistics for heading estimates."""

from __future__ import annotations

import math

import numpy as np

from ..linear import wrap

__all__ = ["heading_error", "mse", "mean_ci"]


def heading_error(estimate, truth) -> np.ndarray:
    """Accumulated heading error: the wrapped difference, unwrapped along the run.

    Whole turns count: a filter that drifts by 21 rad has an error of 21 rad, not of its
    remainder modulo 2 pi.  The error must change by less than pi per sample.

    Parameters
    ----------
    estimate, truth : array_like, shape (N,)
        Headings (rad), wrapped or not.

    Returns
    -------
    ndarray, shape (N,)
        Error (rad).
    """
    return np.unwrap(wrap(np.asarray(estimate) - np.asarray(truth)))


def mse(estimate, truth) -> float:
    """Mean square of :func:`heading_error` over the run.

    Parameters
    ----------
    estimate, truth : array_like, shape (N,)
        Headings (rad).

    Returns
    -------
    float
        MSE (rad^2).

    Examples
    --------
    >>> import math
    >>> from cfdesign.sim import mse
    >>> round(mse([math.pi - 0.1], [-math.pi + 0.1]), 6)     # 0.2 rad apart across +-pi
    0.04
    """
    return float(np.mean(heading_error(estimate, truth) ** 2))


def mean_ci(values, confidence: float = 0.95) -> tuple:
    """Mean and two-sided Student-t confidence interval of independent values.

    ``mean +- t_{(1+c)/2, n-1} s / sqrt(n)`` with ``s`` the sample standard deviation.

    Parameters
    ----------
    values : array_like
        Independent values (one per Monte-Carlo run).
    confidence : float
        Confidence level ``c``.

    Returns
    -------
    mean, low, high : float
        The interval is ``(nan, nan)`` for a single value.

    Examples
    --------
    >>> from cfdesign.sim import mean_ci
    >>> [round(float(v), 4) for v in mean_ci([1.0, 2.0, 3.0])]
    [2.0, -0.4841, 4.4841]
    """
    from scipy import stats

    values = np.asarray(values, dtype=float)
    mean = float(values.mean())
    if len(values) < 2:
        return mean, math.nan, math.nan
    half = stats.t.ppf(0.5 + confidence / 2, len(values) - 1) * values.std(ddof=1) / math.sqrt(len(values))
    return mean, mean - half, mean + half
