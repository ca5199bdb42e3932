"""Singularity-free attitude estimation: a quaternion complementary filter with gyro-bias estimation.

The quaternion form of the attitude filter of Vasconcelos et al. (Sec. 2): a quaternion
propagated by the gyro and corrected by the small-angle error between it and the
Magneto-Pendular Sensor (:mod:`cfdesign.nav.mps`), resolved in ENU (x, y: inclination,
gains of the tilt table; z: heading, gains of the heading table).  For small errors the
three ENU error components obey the channel recursion of
:mod:`cfdesign.nav.attitude_channel`, so the bands are the designed ones.  Use it for any
attitude, including pitch near ±90° (hand-held IMUs, the BROAD benchmark).

Frames: attitude of the body (sensor) frame relative to **ENU** (x east, y north, z up);
quaternions ``[w, x, y, z]`` map body to ENU.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .. import rotations as rot
from ..linear import wrap_scalar
from .attitude_channel import channel_gains, channel_tables, design_channel, gain_schedule
from .attitude_inputs import imu_inputs, initial_quaternion, positive, usable_rows

__all__ = ["estimate_attitude", "DEFAULT_NOISE"]

#: defaults of :func:`estimate_attitude` as rate-independent densities (see its docstring)
DEFAULT_NOISE = {
    "gyro_noise_density": 2.0e-4,      # rad/s/sqrt(Hz): ~0.011 deg/s/sqrt(Hz), typical MEMS gyro
    "gyro_bias_density": 1.0e-5,       # rad/s/sqrt(s): slow bias drift (temperature)
    "tilt_noise_density": 0.002,       # rad/sqrt(Hz): MPS tilt after the 1 s strapdown-frame average
    "heading_noise_density": 0.04,     # rad/sqrt(Hz): MPS heading incl. indoor field distortion
}


def estimate_attitude(gyr, acc, mag, rate_hz, *, gyro_noise_density=None, gyro_bias_density=None,
                      tilt_noise_density=None, heading_noise_density=None, declination_rad=0.0,
                      gyro_bias_std0=0.0175, initial=None, correction_rate_hz=1.0, return_bias=False, tables=None):
    """Attitude quaternions of the sensor frame relative to **ENU** from a gyro, accelerometer and magnetometer.

    The singularity-free form of the attitude filter of Vasconcelos et al. (module docstring).  The
    gyro propagates ``q[k] = q[k-1] ⊗ exp((ω[k] - b) T)`` (half-angle quaternion exponential)
    at the full rate; every ``M`` samples (``M = round(rate_hz / correction_rate_hz)``, one
    second by default) the MPS corrects it.  The error between the propagated attitude and
    the MPS is resolved in ENU: inclination
    ``δ_xy = angle(R a, e_z)`` about ``R a × e_z`` and heading
    ``δ_z = wrap(angle of magnetic north - angle of (R m)_horizontal)``, then::

        q ← exp(K1 δ / 2) ⊗ q,   b ← b - R^T (K2 δ),   K_i = diag(k_i^tilt, k_i^tilt, k_i^heading)

    with ``k1, k2`` the update gains of two channel tables at the correction rate ``rate_hz / M``
    (the lifted single-rate problem, ``docs/derivations.md``): by default designed by
    :func:`~cfdesign.nav.design_channel` (``cf2``, DARE; no sympy) from the noise densities,
    or a user's own design given as ``tables``.
    The accelerometer and field samples of each block are rotated into the block-end frame
    with the gyro and averaged.  Averaging the specific force in this gyro-propagated
    (almost inertial) frame cancels most linear acceleration, whose integral is a bounded
    velocity change (the idea of filtering the accelerometer in an inertial frame is from
    VQF: D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation estimation with bias
    estimation and magnetic disturbance rejection", Information Fusion 91, 2023); it is a
    boxcar prefilter, so the MPS noise densities above describe the averaged MPS.  The heavy
    part is vectorised and the sequential loop runs at the correction rate: a
    100,000-sample trial takes well under 0.1 s.  The gyro products of a block use the bias
    of a first pass (two passes in all); the second pass applies only the small residual
    bias change after the block increment, a commutator error below ``|ω| |Δb| (M T)² / 2``.

    Parameters
    ----------
    gyr : array_like (N, 3)
        Body rate, rad/s.
    acc : array_like (N, 3)
        Specific force, m/s² (any unit works: only its direction is used).
    mag : array_like (N, 3) or None
        Magnetic field, any consistent unit.  ``None``: 6-axis use; heading is the gyro's
        integral from the initial heading (zero), unobserved, and the bias about the vertical
        is not estimated.
    rate_hz : float
        Sample rate (Hz), > 0.
    gyro_noise_density : float, optional
        Gyro white noise (rad/s/sqrt(Hz)); default ``DEFAULT_NOISE`` 2e-4 (0.011 °/s/√Hz,
        the order of consumer MEMS gyros such as BROAD's).
    gyro_bias_density : float, optional
        Gyro bias random walk (rad/s/sqrt(s)), default 1e-5.
    tilt_noise_density, heading_noise_density : float, optional
        MPS inclination / heading noise (rad/sqrt(Hz)), defaults 0.002 and 0.04: the effective
        noise of the averaged gravity and field directions including residual motion
        accelerations and indoor field distortion, not the white sensor noise alone (which is
        far smaller and would give a filter that trusts every acceleration).  Per-correction
        stds follow as density·sqrt(correction rate).  Chosen on BROAD's ten development
        trials (one set for all; see ``benchmarks/bench_broad.py``).
    declination_rad : float
        Magnetic declination, positive east.
    initial : array_like (4,), optional
        Initial quaternion ``[w, x, y, z]`` (body -> ENU); default the MPS of the first
        usable accelerometer (and field) sample.
    gyro_bias_std0 : float
        Prior std of the initial gyro bias (rad/s), default 0.0175 (1 °/s, an uncalibrated
        MEMS gyro).  The gains start from the Kalman recursion of the same ``cf2`` model from
        ``P0 = diag(R, gyro_bias_std0²)`` and converge to the designed (DARE) gains, so a
        large initial bias is learnt in seconds instead of minutes; 0 uses the DARE gains
        from the first sample (as do tables whose gains are not their Kalman gains).
    correction_rate_hz : float
        Rate of the MPS corrections (Hz), default 1 (a one-second strapdown-frame average);
        ``>= rate_hz`` corrects every sample with that sample alone.
    return_bias : bool
        Also return the gyro bias estimate (N, 3), rad/s, body frame.
    tables : pair, optional
        ``(tilt, heading)``: a user's own design instead of the noise densities, each a
        :class:`~cfdesign.gains.GainTable` of the ``cf2`` order-2 channel at the correction
        rate ``rate_hz / M`` (e.g. :func:`cfdesign.nav.design_channel` or
        :func:`cfdesign.design` of a spec at that rate) or a :class:`~cfdesign.spec.FilterSpec`
        of it.  Give either ``tables`` or noise densities.

    Returns
    -------
    ndarray (N, 4)
        Unit quaternions ``[w, x, y, z]`` (w >= 0), sensor frame relative to ENU; with
        ``return_bias`` the tuple ``(quaternions, bias)``.

    Raises
    ------
    AttitudeInputError
        (a :class:`~cfdesign.errors.CfdesignError`) for wrong shapes, ``rate_hz <= 0``,
        invalid noise figures, or both tables and noise figures.
    TableMismatchError
        A table that is not the channel's model or not at the correction rate (the message
        names the mismatch).

    Notes
    -----
    Missing data never yields a NaN quaternion: a gyro row with a NaN is a zero rate (the
    attitude is held); accelerometer rows that are not finite or zero are left out of the
    correction (a block without any skips the correction); field rows that are not finite or
    zero (or parallel to gravity) skip only the heading correction.
    """
    gyr, acc, mag, _ = imu_inputs(gyr, acc, mag)
    rate_hz = positive("rate_hz", rate_hz)
    given = {name: value for name, value in zip(DEFAULT_NOISE, (gyro_noise_density, gyro_bias_density,
                                                                 tilt_noise_density, heading_noise_density),
                                                 strict=True) if value is not None}
    M = max(1, round(rate_hz / positive("correction_rate_hz", correction_rate_hz)))
    f_c = rate_hz / M

    def design_pair():
        noise = {**DEFAULT_NOISE, **{name: positive(name, value) for name, value in given.items()}}
        std = {name: noise[name] * math.sqrt(f_c) for name in ("gyro_noise_density", "tilt_noise_density",
                                                                "heading_noise_density")}
        return (design_channel(f_c, std["gyro_noise_density"], noise["gyro_bias_density"], std["tilt_noise_density"]),
                design_channel(f_c, std["gyro_noise_density"], noise["gyro_bias_density"],
                               std["heading_noise_density"]))

    tilt, heading = channel_tables(tables, list(given), design_pair)
    timing = (f"the correction interval: {M} sample(s) at rate_hz {rate_hz:g} Hz, correction_rate_hz "
              f"{float(correction_rate_hz):g} Hz")
    k_tilt = channel_gains(tilt, "tables[0] (tilt)", M / rate_hz, timing)
    k_heading = channel_gains(heading, "tables[1] (heading)", M / rate_hz, timing)
    nb = -(-len(gyr) // M)
    std0 = positive("gyro_bias_std0", gyro_bias_std0, allow_zero=True)
    gains = _merge_schedules(gain_schedule(tilt, k_tilt, std0, nb), gain_schedule(heading, k_heading, std0, nb))
    acc, mag = usable_rows(acc), usable_rows(mag)
    q0 = initial_quaternion(acc, mag, float(declination_rad), initial)
    q, bias = _run_blocks(gyr, acc, mag, 1.0 / rate_hz, M, q0, gains, float(declination_rad))
    return (q, bias) if return_bias else q


def _merge_schedules(tilt, heading):
    """Per-step tuples ``(k1_tilt, k2_tilt, k1_heading, k2_heading)``; the shorter schedule holds its last gain."""
    n = max(len(tilt[0]), len(heading[0]))
    cols = [c + [c[-1]] * (n - len(c)) for c in (*tilt, *heading)]
    return list(zip(*cols, strict=True))


def _blocks(x, M, fill):
    """Pad (N, d) to a multiple of M rows with ``fill`` and reshape to (blocks, M, d)."""
    n = -(-len(x) // M) * M
    pad = np.full((n - len(x), x.shape[1]), fill)
    return np.concatenate([x, pad]).reshape(-1, M, x.shape[1])


def _block_rotations(gyr, T, M, bias_ref):
    """Gyro increments inside each block: ``P[b, j] = ⊗_{i<=j} exp((ω_i - b_ref[b]) T / 2)``.

    The rate of sample 0 is not used, so that the first output is the initial attitude itself.
    """
    w = np.where(np.isfinite(gyr).all(axis=1)[:, None], gyr, 0.0)
    w[0] = 0.0
    w = (_blocks(w, M, 0.0) - bias_ref[:, None, :]).reshape(-1, 3)
    w[len(gyr):] = 0.0                                               # padding rows: no rotation
    w = w.reshape(-1, M, 3)
    dq = rot.from_rotation_vector(w * T)
    P = np.empty_like(dq)
    P[:, 0] = dq[:, 0]
    for j in range(1, M):
        P[:, j] = rot.multiply(P[:, j - 1], dq[:, j])
    return P / np.linalg.norm(P, axis=-1, keepdims=True)


def _block_mean(vectors, P):
    """Mean of body vectors over each block, expressed in the block-end body frame (NaN rows skipped)."""
    if vectors is None:
        return None
    v = rot.rotate(P, _blocks(vectors, P.shape[1], np.nan))           # into the block-start frame
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN blocks -> NaN (skipped)
        mean = np.nanmean(v, axis=1)
    return rot.rotate(rot.conjugate(P[:, -1]), mean)                 # into the block-end frame


def _run_blocks(gyr, acc, mag, T, M, q0, gains, declination):
    """Two passes of :func:`_pass`: the second removes the first pass's bias inside the gyro products."""
    nb = -(-len(gyr) // M)
    starts, biases, P, ref = _pass(gyr, acc, mag, T, M, q0, gains, declination, np.zeros((nb, 3)))
    starts, biases, P, ref = _pass(gyr, acc, mag, T, M, q0, gains, declination, biases)
    return _outputs(P, starts, biases - ref, biases, T, len(gyr))


def _pass(gyr, acc, mag, T, M, q0, gains, declination, bias_ref):
    """Sequential correction loop at the block rate (Python floats); returns block-start states."""
    P = _block_rotations(gyr, T, M, bias_ref)
    a_blk, m_blk = _block_mean(acc, P), _block_mean(mag, P)
    nb = len(P)
    starts, biases = np.empty((nb, 4)), np.empty((nb, 3))
    state = [float(v) for v in q0] + [0.0, 0.0, 0.0]
    north = math.atan2(math.cos(declination), math.sin(declination))   # ENU angle of magnetic north
    a_list, p_list, ref = a_blk.tolist(), P[:, -1].tolist(), bias_ref.tolist()
    m_list = m_blk.tolist() if m_blk is not None else [None] * nb
    for k in range(nb):
        starts[k], biases[k] = state[:4], state[4:]
        state = _block_step(state, p_list[k], a_list[k], m_list[k], M * T, gains[min(k, len(gains) - 1)], north,
                            ref[k])
    return starts, biases, P, bias_ref


def _block_step(state, p, a, m, dt, gains, north, ref):
    """One block: propagate with the block's gyro increment and bias, then correct (Python floats)."""
    w, x, y, z, bx, by, bz = state
    # q ⊗ P_end ⊗ exp(-(b - b_ref) dt / 2) (first order in the small residual bias)
    pw, px, py, pz = p
    hx, hy, hz = -0.5 * (bx - ref[0]) * dt, -0.5 * (by - ref[1]) * dt, -0.5 * (bz - ref[2]) * dt
    pw, px, py, pz = (pw - px * hx - py * hy - pz * hz, pw * hx + px + py * hz - pz * hy,
                      pw * hy - px * hz + py + pz * hx, pw * hz + px * hy - py * hx + pz)
    w, x, y, z = (w * pw - x * px - y * py - z * pz, w * px + x * pw + y * pz - z * py,
                  w * py - x * pz + y * pw + z * px, w * pz + x * py - y * px + z * pw)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    r = _matrix(w, x, y, z)
    ex = ey = ez = 0.0
    if a[0] == a[0] and a[1] == a[1] and a[2] == a[2]:               # finite block mean
        ex, ey = _tilt_error(r, a)
        if m is not None and m[0] == m[0]:
            ez = _heading_error(r, m, north)
    k1t, k2t, k1h, k2h = gains
    cx, cy, cz = k1t * ex, k1t * ey, k1h * ez
    # q ← exp(c / 2) ⊗ q  (correction in ENU)
    ang = math.sqrt(cx * cx + cy * cy + cz * cz)
    s = math.sin(0.5 * ang) / ang if ang > 1e-12 else 0.5
    cw, cx, cy, cz = math.cos(0.5 * ang), s * cx, s * cy, s * cz
    w, x, y, z = (cw * w - cx * x - cy * y - cz * z, cw * x + cx * w + cy * z - cz * y,
                  cw * y - cx * z + cy * w + cz * x, cw * z + cx * y - cy * x + cz * w)
    # b ← b - R^T K2 δ
    dx, dy, dz = k2t * ex, k2t * ey, k2h * ez
    bx -= r[0] * dx + r[3] * dy + r[6] * dz
    by -= r[1] * dx + r[4] * dy + r[7] * dz
    bz -= r[2] * dx + r[5] * dy + r[8] * dz
    return [w, x, y, z, bx, by, bz]


def _matrix(w, x, y, z):
    """Row-major rotation matrix (body -> ENU) of a unit quaternion, as a flat tuple."""
    return (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


def _tilt_error(r, a):
    """ENU x, y of the rotation vector taking the measured up ``R a`` onto ``e_z``."""
    ux = r[0] * a[0] + r[1] * a[1] + r[2] * a[2]
    uy = r[3] * a[0] + r[4] * a[1] + r[5] * a[2]
    uz = r[6] * a[0] + r[7] * a[1] + r[8] * a[2]
    h = math.hypot(ux, uy)
    if h < 1e-12:
        return 0.0, 0.0
    angle = math.atan2(h, uz)
    return angle * uy / h, -angle * ux / h                 # axis (R a) × e_z = (u_y, -u_x, 0)


def _heading_error(r, m, north):
    """ENU z rotation (rad) taking the horizontal part of ``R m`` onto magnetic north."""
    mx = r[0] * m[0] + r[1] * m[1] + r[2] * m[2]
    my = r[3] * m[0] + r[4] * m[1] + r[5] * m[2]
    if math.hypot(mx, my) < 1e-9 * math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]):
        return 0.0
    return wrap_scalar(north - math.atan2(my, mx))


def _outputs(P, starts, residual, biases, T, n):
    """Quaternions ``q_start ⊗ P[b, j] ⊗ exp(-r (j + 1) T / 2)`` (``r``: residual bias) and the bias."""
    M = P.shape[1]
    steps = (np.arange(1, M + 1) * T)[None, :, None]
    bias_rot = rot.from_rotation_vector(-residual[:, None, :] * steps)
    q = rot.multiply(rot.multiply(starts[:, None, :], P), bias_rot).reshape(-1, 4)[:n]
    bias = np.repeat(biases, M, axis=0)[:n]
    return rot.normalize(q), bias
