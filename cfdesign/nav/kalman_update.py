"""The Kalman measurement update both extended Kalman filters of :mod:`cfdesign.nav` use.

Joseph form, symmetrised, for any gain (:func:`cfdesign.linear.posterior_covariance`)::

    K = P H^T (H P H^T + R)^-1,   x+ = x + K ν,   P+ = (I - K H) P (I - K H)^T + K R K^T
"""

from __future__ import annotations

import numpy as np

from ..linear import posterior_covariance

__all__ = ["joseph_update", "first_finite", "noise_figure"]


def joseph_update(x, P, innovation, H, R):
    """Kalman measurement update in Joseph form, symmetrised.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Prior state.
    P : ndarray, shape (n, n)
        Prior covariance.
    innovation : ndarray, shape (m,)
        ``ν = z - h(x)``.
    H : ndarray, shape (m, n)
        Measurement Jacobian.
    R : ndarray, shape (m, m)
        Measurement-noise covariance.

    Returns
    -------
    x : ndarray, shape (n,)
        ``x + K ν`` with ``K = P H^T (H P H^T + R)^-1``.
    P : ndarray, shape (n, n)
        ``(I - K H) P (I - K H)^T + K R K^T``, symmetrised.

    Raises
    ------
    InputError
        The innovation covariance ``H P H^T + R`` is singular or the update is not finite: the
        filter's noise figures and initial standard deviations are too small, or too far apart,
        for double precision (a GPS std of 1e-300 on a position known to 1e-12 m, an odometer
        noise of 1e15 m beside a scale noise of 1e-170).
    """
    from ..errors import InputError

    PHt = P @ H.T
    S = H @ PHt + R
    try:
        K = np.linalg.solve(S, PHt.T).T
        P = posterior_covariance(P, H, K, R)
        x = x + K @ innovation
    except np.linalg.LinAlgError:
        K = None
    if K is None or not (np.isfinite(P).all() and np.isfinite(x).all()):
        scale = np.abs(np.diag(S))
        raise InputError(f"the innovation covariance H P H^T + R (diagonal from {scale.min():.3g} to "
                         f"{scale.max():.3g}) is singular or its update not finite: the noise figures and initial "
                         "standard deviations are too small, or too far apart, for double precision")
    return x, 0.5 * (P + P.T)


def first_finite(rows):
    """The first all-finite row of an array.

    Parameters
    ----------
    rows : ndarray, shape (N, k)
        Rows to search, in order.

    Returns
    -------
    ndarray, shape (k,), or None
        None when no row is finite.
    """
    ok = np.flatnonzero(np.isfinite(rows).all(axis=1))
    return None if len(ok) == 0 else rows[ok[0]]


def noise_figure(name, value, allow_zero=False) -> float:
    """Check a noise figure of an EKF: a finite positive number up to 1e15 (its square is finite).

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it.
    value : float
        A standard deviation or a density.
    allow_zero : bool
        Accept zero as well (a random walk that is not there).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    InputError
        ``value`` is not a number, not finite, negative, zero without ``allow_zero``, or beyond
        1e15; the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.kalman_update import noise_figure
    >>> noise_figure("gps_pos_std", 2)
    2.0
    >>> noise_figure("gps_pos_std", -1.0)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: gps_pos_std must be a finite positive number, got -1.0
    """
    from ..errors import InputError
    from .attitude_inputs import positive

    value = positive(name, value, allow_zero)
    if value > 1e15:
        raise InputError(f"{name} must be at most 1e15, got {value!r}")
    return value
