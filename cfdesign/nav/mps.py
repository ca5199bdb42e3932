"""Magneto-Pendular Sensor (MPS): attitude from gravity and the magnetic field.

The attitude aiding device of Vasconcelos et al. (Sec. 2.2).

Frame: ENU (x east, y north, z up); angles are ZYX ``[yaw, pitch, roll]`` of the body
relative to ENU (see :mod:`cfdesign.rotations`).  The accelerometer reads specific
force, ``+g`` along up at rest, so the paper's eq. (2) holds as printed:
``a = (-g sin θ, g cos θ sin φ, g cos θ cos φ)``.

Roll and pitch (eq. (3))::

    φ = atan2(a_y, a_z),   θ = atan2(-a_x, a_z / cos φ) = atan2(-a_x, sqrt(a_y² + a_z²))

(both branches of eq. (3) equal ``sqrt(a_y² + a_z²)`` in the second argument; the hypot form
needs no division).  Yaw from the tilt-compensated field ``m' = R_Y(θ) R_X(φ) m``: the paper
writes ``ψ = atan2(-m'_y, m'_x) - α_dec`` for a north-east-down frame; in ENU the same
construction reads ``ψ = atan2(m'_x, m'_y) - α_dec`` (yaw counter-clockwise from east,
declination ``α_dec`` positive when magnetic north lies east of true north).

Centripetal compensation (Sec. 2.2): ``a_MPS = a - ω̂ × v_B`` with the unbiased
rate ``ω̂`` and the body-frame velocity ``v_B``.
"""

from __future__ import annotations

import numpy as np

from .. import rotations as rot
from ..linear import wrap

__all__ = ["centripetal_compensation", "mps_euler", "mps_quaternion", "tilt_compensated_field", "real_vectors"]


def real_vectors(name, value) -> np.ndarray:
    """Check that a value is one 3-vector or an array of them and return it as floats.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it (``acc``, ``mag``).
    value : array_like (..., 3)
        The vectors.

    Returns
    -------
    ndarray (..., 3)
        ``value`` as a float array.  Non-finite entries are kept.

    Raises
    ------
    AttitudeInputError
        ``value`` is not an array of real numbers (text, None, complex values) or its last axis
        is not of length 3; the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.mps import real_vectors
    >>> real_vectors("acc", [0, 0, 9.81]).tolist()
    [0.0, 0.0, 9.81]
    >>> real_vectors("acc", [0.0, 9.81])
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: acc must be 3-vectors (shape (..., 3)), got shape (2,)
    """
    from ..errors import AttitudeInputError, CfdesignError
    from ..runtime.filter import real_array

    try:
        a = real_array(value, name)
    except CfdesignError as exc:
        raise AttitudeInputError(f"{exc}: 3-vectors are needed") from None
    if a.ndim == 0 or a.shape[-1] != 3:
        raise AttitudeInputError(f"{name} must be 3-vectors (shape (..., 3)), got shape {a.shape}")
    return a


def centripetal_compensation(acc, rate, velocity_body):
    """Centripetal compensation of the accelerometer: ``a_MPS = a - ω̂ × v_B`` (Vasconcelos et al. Sec. 2.2).

    Parameters
    ----------
    acc : array_like, shape (..., 3)
        Specific force in the body frame (m/s²).
    rate : array_like, shape (..., 3)
        Unbiased body rate (rad/s).
    velocity_body : array_like, shape (..., 3)
        Velocity in the body frame (m/s).

    Returns
    -------
    ndarray, shape (..., 3)
        The compensated specific force (m/s², body frame).
    """
    return np.asarray(acc, dtype=float) - np.cross(rate, velocity_body)


def tilt_compensated_field(mag, pitch, roll):
    """The magnetic field in the level frame that shares the body's heading: ``m' = R_Y(θ) R_X(φ) m``.

    Parameters
    ----------
    mag : array_like, shape (..., 3)
        Field in the body frame (any unit).
    pitch, roll : array_like
        Pitch ``θ`` and roll ``φ`` (rad), ZYX relative to ENU.

    Returns
    -------
    ndarray, shape (..., 3)
        The field rotated to the level frame (same unit).
    """
    m = np.asarray(mag, dtype=float)
    cp, sp, cr, sr = np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    y = cr * m[..., 1] - sr * m[..., 2]                     # R_X(φ) m, its z is z1
    z1 = sr * m[..., 1] + cr * m[..., 2]
    x = cp * m[..., 0] + sp * z1                           # then R_Y(θ)
    z = -sp * m[..., 0] + cp * z1
    return np.stack([x, y, z], axis=-1)


def mps_euler(acc, mag=None, *, declination_rad=0.0, rate=None, velocity_body=None):
    """MPS attitude ``[yaw, pitch, roll]`` (rad, ZYX, body relative to ENU), Vasconcelos et al. eqs. (2)-(3).

    Parameters
    ----------
    acc : array_like (..., 3)
        Specific force in the body frame (m/s²).
    mag : array_like (..., 3), optional
        Magnetic field in the body frame (any unit).  ``None``: yaw is NaN (unobserved).
    declination_rad : float
        Magnetic declination, positive east; subtracted from the magnetic heading.
    rate, velocity_body : array_like (..., 3), optional
        Unbiased body rate (rad/s) and body-frame velocity (m/s) for the centripetal
        compensation ``a - ω̂ × v_B``; both or neither.

    Returns
    -------
    ndarray (..., 3)
        ``[yaw, pitch, roll]``; yaw wrapped to ``(-pi, pi]``.  Rows whose field is zero or not
        finite get a NaN yaw; rows with a non-finite acceleration (after the compensation) are
        all NaN.

    Raises
    ------
    AttitudeInputError
        ``acc``, ``mag``, ``rate`` or ``velocity_body`` is not an array of real 3-vectors.
    """
    a = real_vectors("acc", acc)
    mag = None if mag is None else real_vectors("mag", mag)
    with np.errstate(invalid="ignore", over="ignore"):  # an unusable row: NaN, as documented
        if velocity_body is not None and rate is not None:
            a = centripetal_compensation(a, real_vectors("rate", rate), real_vectors("velocity_body", velocity_body))
        roll = np.arctan2(a[..., 1], a[..., 2])
        pitch = np.arctan2(-a[..., 0], np.hypot(a[..., 1], a[..., 2]))
        if mag is None:
            yaw = np.full(roll.shape, np.nan)
        else:
            mp = tilt_compensated_field(mag, pitch, roll)
            horizontal = np.hypot(mp[..., 0], mp[..., 1])
            yaw = np.where(horizontal > 0, wrap(np.arctan2(mp[..., 0], mp[..., 1]) - declination_rad), np.nan)
    return np.stack([yaw, pitch, roll], axis=-1)


def mps_quaternion(acc, mag=None, *, declination_rad=0.0):
    """Singularity-free Magneto-Pendular Sensor attitude as a quaternion (TRIAD-like).

    Up is ``a/|a|``; east is ``m × up`` normalised; north is ``up × east``; the rotation matrix
    has the ENU axes (in body coordinates) as its rows.  The magnetic frame is then turned by
    ``-α_dec`` about up.  Gravity fixes roll and pitch; the field only the heading, at any pitch
    (unlike :func:`mps_euler`, which is singular at ``θ = ±90°``).

    Parameters
    ----------
    acc : array_like, shape (..., 3)
        Specific force in the body frame (m/s²); points up when at rest.
    mag : array_like, shape (..., 3), optional
        Magnetic field in the body frame (any unit).  Without a usable field (``None``, zero,
        or parallel to gravity) the heading is set to zero (yaw-free tilt, the shortest
        rotation from up to ``a``).
    declination_rad : float
        Magnetic declination (rad), positive east.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternion ``[w, x, y, z]`` rotating body to ENU; NaN where ``acc`` is zero or not
        finite (no up).

    Raises
    ------
    AttitudeInputError
        ``acc`` or ``mag`` is not an array of real 3-vectors.

    Examples
    --------
    >>> from cfdesign.nav import mps_quaternion
    >>> mps_quaternion([0.0, 0.0, 9.81], [0.0, 1.0, -1.0]).round(6).tolist()  # level, axes along ENU
    [1.0, 0.0, 0.0, 0.0]
    """
    a = real_vectors("acc", acc)
    mag = None if mag is None else real_vectors("mag", mag)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # an unusable row: NaN, as documented
        up = a / np.linalg.norm(a, axis=-1, keepdims=True)
        east = None
        if mag is not None:
            east = np.cross(mag, up)
            norm = np.linalg.norm(east, axis=-1, keepdims=True)
            ok = norm > 1e-9 * np.maximum(np.linalg.norm(mag, axis=-1, keepdims=True), 1e-300)
            east = np.where(ok, east / np.where(ok, norm, 1.0), np.nan)
        tilt = _tilt_only(up)
        if east is None:
            return tilt
        north = np.cross(up, east)
        q = rot.from_matrix(np.where(np.isfinite(east).all(axis=-1)[..., None, None],
                                     np.stack([east, north, up], axis=-2), np.eye(3)))
        q = rot.multiply(rot.from_rotation_vector(np.array([0.0, 0.0, -declination_rad])), q)
        q = rot.normalize(q)
        return np.where(np.isfinite(east).all(axis=-1, keepdims=True), q, tilt)


def _tilt_only(up):
    """Yaw-free quaternion turning the body's measured up ``up`` onto ENU up (shortest rotation)."""
    # rotation body -> ENU maps up_body to e_z: axis up × e_z, angle acos(up_z)
    w = 1.0 + up[..., 2]
    q = np.stack([w, up[..., 1], -up[..., 0], np.zeros_like(w)], axis=-1)
    flipped = w < 1e-9                      # upside down: any horizontal axis, take x
    q = np.where(flipped[..., None], np.array([0.0, 1.0, 0.0, 0.0]), q)
    return rot.normalize(q)
