"""The Kalman measurement update both extended Kalman filters of :mod:`cfdesign.nav` use.

Joseph form, symmetrised, for any gain (:func:`cfdesign.linear.posterior_covariance`)::

    K = P H^T (H P H^T + R)^-1,   x+ = x + K ν,   P+ = (I - K H) P (I - K H)^T + K R K^T
"""

from __future__ import annotations

import numpy as np

from ..linear import posterior_covariance

__all__ = ["joseph_update", "first_finite"]


def joseph_update(x, P, innovation, H, R):
    """Kalman update in Joseph form, symmetrised: returns ``x + K ν`` and ``P``."""
    PHt = P @ H.T
    K = np.linalg.solve(H @ PHt + R, PHt.T).T
    P = posterior_covariance(P, H, K, R)
    return x + K @ innovation, 0.5 * (P + P.T)


def first_finite(rows):
    """First all-finite row of ``rows`` or ``None``."""
    ok = np.flatnonzero(np.isfinite(rows).all(axis=1))
    return None if len(ok) == 0 else rows[ok[0]]
