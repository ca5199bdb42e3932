"""Rotations in the ENU frame: quaternions, Euler angles, Euler-rate kinematics, gravity.

numpy only, vectorised over leading axes.  The one place for the frame conventions of
:mod:`cfdesign.sim` (truth and sensor models) and :mod:`cfdesign.nav` (the filters), so
that neither needs the other:

* quaternions are ``[w, x, y, z]`` (scalar first), Hamilton product;
* an attitude quaternion ``q`` maps body (sensor) coordinates to the local level frame
  **ENU** (x east, y north, z up): ``v_enu = q ⊗ v_body ⊗ conj(q)``;
* Euler angles are ZYX ``[yaw, pitch, roll]`` of the body relative to ENU:
  ``R = R_Z(yaw) R_Y(pitch) R_X(roll)`` (body -> ENU), yaw counter-clockwise from east;
* gravity in ENU is :data:`GRAVITY_ENU`; an accelerometer reads the specific force
  ``f_b = R^T (a_n - g_n)``, so ``a_n = R f_b + g_n``.

Angles are wrapped with :func:`cfdesign.linear.wrap`, the one wrap of cfdesign.
"""

from __future__ import annotations

import numpy as np

from .linear import wrap

__all__ = ["GRAVITY_ENU", "multiply", "conjugate", "normalize", "rotate", "from_rotation_vector", "from_euler",
           "to_euler", "to_matrix", "from_matrix", "euler_rate_matrix", "euler_rate_matrix_inverse"]

#: gravity in ENU (m/s^2): standard gravity 9.80665 m/s^2 pointing down
GRAVITY_ENU = np.array([0.0, 0.0, -9.80665])


def multiply(p, q):
    """Hamilton product ``p ⊗ q`` of ``[w, x, y, z]`` quaternions, broadcast over leading axes.

    Parameters
    ----------
    p, q : array_like, shape (..., 4)
        Unit quaternions ``[w, x, y, z]`` (scalar first); they broadcast.

    Returns
    -------
    ndarray, shape (..., 4)
        The product ``p ⊗ q``, ``[w, x, y, z]``.

    Examples
    --------
    >>> from cfdesign.rotations import multiply
    >>> multiply([0, 1, 0, 0], [0, 1, 0, 0]).tolist()     # i * i = -1
    [-1.0, 0.0, 0.0, 0.0]
    """
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def conjugate(q):
    """Conjugate ``[w, -x, -y, -z]``: the inverse of a unit quaternion.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion(s) ``[w, x, y, z]``.

    Returns
    -------
    ndarray, shape (..., 4)
        The conjugate ``[w, -x, -y, -z]``.
    """
    out = np.array(q, dtype=float, copy=True)
    out[..., 1:] *= -1
    return out


def normalize(q):
    """Unit quaternion(s) with a non-negative scalar part (``q`` and ``-q`` are one rotation).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion(s) ``[w, x, y, z]``.

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternion(s) ``[w, x, y, z]`` with ``w >= 0``.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rotate(q, v):
    """Rotate vectors by a quaternion: ``q ⊗ [0, v] ⊗ conj(q)``.

    For an attitude quaternion this maps body coordinates to ENU.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion(s) ``[w, x, y, z]``.
        Unit quaternion(s).
    v : array_like, shape (..., 3)
        Vectors (any unit).

    Returns
    -------
    ndarray, shape (..., 3)
        The rotated vectors, in the unit of ``v``.

    Examples
    --------
    >>> import math
    >>> from cfdesign.rotations import from_euler, rotate
    >>> rotate(from_euler([math.pi / 2, 0.0, 0.0]), [1.0, 0.0, 0.0]).round(6).tolist()  # yaw 90 deg: x -> north
    [0.0, 1.0, 0.0]
    """
    v = np.asarray(v, dtype=float)
    return np.einsum("...ij,...j->...i", to_matrix(q), v)


def from_rotation_vector(r):
    """Quaternion ``exp(r / 2)`` of a rotation vector (axis times angle).

    Parameters
    ----------
    r : array_like, shape (..., 3)
        Rotation vector (rad); exact for tiny rotations (series of ``sin(x)/x``).

    Returns
    -------
    ndarray, shape (..., 4)
        Unit quaternion(s) ``[w, x, y, z]``.
    """
    r = np.asarray(r, dtype=float)
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(x)/x with its series near 0, so that tiny rotations stay exact
    scale = np.where(angle > 1e-8, np.sin(half) / np.where(angle > 1e-8, angle, 1.0), 0.5 - angle**2 / 48)
    return np.concatenate([np.cos(half), scale * r], axis=-1)


def from_euler(euler):
    """Quaternion of ZYX Euler angles: ``q = q_Z(yaw) ⊗ q_Y(pitch) ⊗ q_X(roll)``.

    I.e. ``R = R_Z R_Y R_X`` (Vasconcelos et al. Sec. 2.2).

    Parameters
    ----------
    euler : array_like, shape (..., 3)
        ``[yaw, pitch, roll]`` (rad) of the body relative to ENU; yaw counter-clockwise from
        east.

    Returns
    -------
    ndarray, shape (..., 4)
        ``[w, x, y, z]``, body -> ENU.
    """
    e = np.asarray(euler, dtype=float)
    cy, sy = np.cos(e[..., 0] / 2), np.sin(e[..., 0] / 2)
    cp, sp = np.cos(e[..., 1] / 2), np.sin(e[..., 1] / 2)
    cr, sr = np.cos(e[..., 2] / 2), np.sin(e[..., 2] / 2)
    return np.stack([cy * cp * cr + sy * sp * sr,
                     cy * cp * sr - sy * sp * cr,
                     cy * sp * cr + sy * cp * sr,
                     sy * cp * cr - cy * sp * sr], axis=-1)


def to_euler(q):
    """ZYX Euler angles of an attitude quaternion.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion(s) ``[w, x, y, z]``.
        Unit quaternion(s), body -> ENU.

    Returns
    -------
    ndarray, shape (..., 3)
        ``[yaw, pitch, roll]`` (rad), yaw in ``(-pi, pi]``, pitch in ``[-pi/2, pi/2]``.
    """
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    pitch = np.arcsin(np.clip(2 * (w * y - x * z), -1.0, 1.0))
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    return np.stack([wrap(yaw), pitch, roll], axis=-1)


def to_matrix(q):
    """Rotation matrix of unit quaternion(s): ``v_enu = R v_body`` for an attitude.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Quaternion(s) ``[w, x, y, z]``.
        Unit quaternion(s).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rotation matrices ``R``.
    """
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def from_matrix(R):
    """Unit quaternion(s) of rotation matrices, robust for any angle (Shepperd's method).

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrices (body -> ENU for an attitude).

    Returns
    -------
    ndarray, shape (..., 4)
        ``[w, x, y, z]`` with ``w >= 0``.
    """
    R = np.asarray(R, dtype=float)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    # squared components, each from the diagonal; signs from the skew part (Shepperd's method)
    sq = np.stack([1 + tr, 1 + 2 * R[..., 0, 0] - tr, 1 + 2 * R[..., 1, 1] - tr, 1 + 2 * R[..., 2, 2] - tr], axis=-1)
    best = np.argmax(sq, axis=-1)
    a = np.sqrt(np.maximum(np.take_along_axis(sq, best[..., None], -1)[..., 0], 1e-300))
    skew = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    sym = np.stack([R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0], R[..., 1, 2] + R[..., 2, 1]], -1)
    rows = {0: (a, skew[..., 0] / a, skew[..., 1] / a, skew[..., 2] / a),
            1: (skew[..., 0] / a, a, sym[..., 0] / a, sym[..., 1] / a),
            2: (skew[..., 1] / a, sym[..., 0] / a, a, sym[..., 2] / a),
            3: (skew[..., 2] / a, sym[..., 1] / a, sym[..., 2] / a, a)}
    out = np.zeros((*R.shape[:-2], 4))
    for k, comps in rows.items():
        out = np.where((best == k)[..., None], np.stack(comps, axis=-1), out)
    return normalize(0.5 * out)


def euler_rate_matrix(euler):
    """``Q(λ)``: Euler-angle rates ``λ' = Q(λ) ω`` for ``λ = (ψ, θ, φ)`` (Vasconcelos et al. Sec. 2.1).

    ``Q = [[0, sinφ secθ, cosφ secθ], [0, cosφ, -sinφ], [1, sinφ tanθ, cosφ tanθ]]``.

    Parameters
    ----------
    euler : array_like, shape (..., 3)
        ZYX Euler angles ``[yaw, pitch, roll]`` (rad) of the body frame relative to ENU.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Maps the body rate ``ω`` (rad/s, body frame) to ``[ψ', θ', φ']`` (rad/s).  Singular at
        ``θ = ±90°`` (entries become infinite).

    Examples
    --------
    >>> from cfdesign.rotations import euler_rate_matrix
    >>> euler_rate_matrix([0.0, 0.0, 0.0]).tolist()     # level: yaw rate = body z rate
    [[0.0, 0.0, 1.0], [0.0, 1.0, -0.0], [1.0, 0.0, 0.0]]
    """
    e = np.asarray(euler, dtype=float)
    sf, cf = np.sin(e[..., 2]), np.cos(e[..., 2])
    sec, tan = 1.0 / np.cos(e[..., 1]), np.tan(e[..., 1])
    zero, one = np.zeros_like(sf), np.ones_like(sf)
    return np.stack([np.stack([zero, sf * sec, cf * sec], -1),
                     np.stack([zero, cf, -sf], -1),
                     np.stack([one, sf * tan, cf * tan], -1)], -2)


def euler_rate_matrix_inverse(euler):
    """``Q(λ)^-1``: body rate from Euler-angle rates, ``ω = Q^-1 λ'`` (defined at every attitude).

    ``Q^-1 = [[-sinθ, 0, 1], [cosθ sinφ, cosφ, 0], [cosθ cosφ, -sinφ, 0]]`` (columns ψ', θ', φ').

    Parameters
    ----------
    euler : array_like, shape (..., 3)
        ZYX Euler angles ``[yaw, pitch, roll]`` (rad) of the body frame relative to ENU.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Maps ``[ψ', θ', φ']`` (rad/s) to the body rate ``ω`` (rad/s, body frame).
    """
    e = np.asarray(euler, dtype=float)
    st, ct, sf, cf = np.sin(e[..., 1]), np.cos(e[..., 1]), np.sin(e[..., 2]), np.cos(e[..., 2])
    zero, one = np.zeros_like(st), np.ones_like(st)
    return np.stack([np.stack([-st, zero, one], -1),
                     np.stack([ct * sf, cf, zero], -1),
                     np.stack([ct * cf, -sf, zero], -1)], -2)
