"""Input checks shared by the two attitude filters, and their initial attitude.

Every check raises :class:`~cfdesign.errors.AttitudeInputError` naming the argument.
Frames as :mod:`cfdesign.rotations` (ENU, quaternions ``[w, x, y, z]`` body -> ENU).
"""

from __future__ import annotations

import math

import numpy as np

from .. import rotations as rot
from ..errors import AttitudeInputError
from .mps import mps_quaternion

__all__ = ["positive", "vectors", "imu_inputs", "usable_rows", "initial_quaternion"]


def positive(name, value, allow_zero=False) -> float:
    """``value`` as a finite positive (or non-negative) float; AttitudeInputError naming ``name`` otherwise."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise AttitudeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise AttitudeInputError(f"{name} must be a finite {'non-negative' if allow_zero else 'positive'} "
                                 f"number, got {value!r}")
    return value


def vectors(name, value, n=None, allow_none=False):
    """``value`` as an (N, 3) float array (``n`` rows when given), or None when allowed."""
    if value is None and allow_none:
        return None
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise AttitudeInputError(f"{name} must be a numeric array of shape (N, 3)") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise AttitudeInputError(f"{name} must have shape (N, 3), got {arr.shape}")
    if n is not None and len(arr) != n:
        raise AttitudeInputError(f"{name} has {len(arr)} rows but gyr has {n}")
    return arr


def imu_inputs(gyr, acc, mag, velocity_body=None):
    """``(gyr, acc, mag, velocity_body)`` checked: (N, 3) each, N >= 1; ``mag`` and the velocity may be None."""
    gyr = vectors("gyr", gyr)
    if len(gyr) == 0:
        raise AttitudeInputError("gyr is empty: need at least one sample")
    acc = vectors("acc", acc, len(gyr))
    mag = vectors("mag", mag, len(gyr), allow_none=True)
    vel = vectors("velocity_body", velocity_body, len(gyr), allow_none=True)
    return gyr, acc, mag, vel


def usable_rows(vectors_):
    """Rows that can correct the attitude: finite and non-zero (others -> NaN, skipped); None stays None."""
    if vectors_ is None:
        return None
    bad = ~np.isfinite(vectors_).all(axis=1) | ~(np.abs(vectors_).sum(axis=1) > 0)
    return np.where(bad[:, None], np.nan, vectors_)


def initial_quaternion(acc, mag, declination_rad, initial):
    """Initial attitude: ``initial`` (a quaternion) or the MPS of the first usable sample."""
    if initial is not None:
        q0 = np.asarray(initial, dtype=float)
        if q0.shape != (4,) or not np.isfinite(q0).all() or np.linalg.norm(q0) == 0:
            raise AttitudeInputError(f"initial must be a finite non-zero quaternion [w, x, y, z], got {initial!r}")
        return rot.normalize(q0)
    rows = np.flatnonzero(np.isfinite(acc).all(axis=1))
    if len(rows) == 0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    k = rows[0]
    if mag is not None:
        good = rows[np.isfinite(mag[rows]).all(axis=1)]
        k = good[0] if len(good) else k
    return mps_quaternion(acc[k], None if mag is None else mag[k], declination_rad=declination_rad)
