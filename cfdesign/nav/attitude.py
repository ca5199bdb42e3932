"""Attitude complementary filters with gyro-bias estimation (seed 004 Sec. 2).

Two forms share one design: each attitude channel is the discrete ``cf2`` (order 2) of
:func:`cfdesign.symbolic.filters.cf2`, state ``[angle, rate correction]``, gyro rate input
with a random-walk bias, angle measurement from the Magneto-Pendular Sensor
(:mod:`cfdesign.nav.mps`).  Its filter-form gains ``k1`` (angle) and ``k2`` (bias, 1/s)
come from :func:`cfdesign.design` (DARE on the sensors' noise figures), one table for the
tilt channels (pitch, roll) and one for heading (yaw).

* :class:`EulerAttitudeFilter` is the paper's filter: Euler channels ``λ = (ψ, θ, φ)`` with
  ``u_λ = Q(λ) ω`` and the bias kept in body rates.  Use it for vehicles that stay far from
  ``θ = ±90°`` (helicopters, cars, fixed wings in normal flight) and to reproduce seed 004.
* :func:`estimate_attitude` is the singularity-free form: a quaternion propagated by the gyro
  and corrected by the small-angle error between it and the MPS, resolved in ENU (x, y:
  inclination, gains of the tilt table; z: heading, gains of the heading table).  For small
  errors the three ENU error components obey the same ``cf2`` recursion, so the bands are
  the designed ones.  Use it for any attitude, including pitch near ±90° (hand-held IMUs,
  BROAD).

Frames: attitude of the body (sensor) frame relative to **ENU** (x east, y north, z up);
quaternions ``[w, x, y, z]`` map body to ENU; Euler angles are ZYX ``[yaw, pitch, roll]``.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np

from .. import rotations as quat
from ..errors import AttitudeInputError
from ..linear import wrap_scalar
from ..rotations import euler_rate_matrix, euler_rate_matrix_inverse
from .mps import mps_euler, mps_quaternion

__all__ = ["EulerAttitudeFilter", "EulerEstimate", "euler_rate_matrix", "euler_rate_matrix_inverse",
           "design_channel", "estimate_attitude", "AttitudeInputError", "DEFAULT_NOISE"]

#: defaults of :func:`estimate_attitude` as rate-independent densities (see its docstring)
DEFAULT_NOISE = {
    "gyro_noise_density": 2.0e-4,      # rad/s/sqrt(Hz): ~0.011 deg/s/sqrt(Hz), typical MEMS gyro
    "gyro_bias_density": 1.0e-5,       # rad/s/sqrt(s): slow bias drift (temperature)
    "tilt_noise_density": 0.002,       # rad/sqrt(Hz): MPS tilt after the 1 s strapdown-frame average
    "heading_noise_density": 0.04,     # rad/sqrt(Hz): MPS heading incl. indoor field distortion
}


# --------------------------------------------------------------------------------------------
# gain design (seed 004 Sec. 3: stationary Kalman gains from the DARE)


def _positive(name, value, allow_zero=False):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise AttitudeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise AttitudeInputError(f"{name} must be a finite {'non-negative' if allow_zero else 'positive'} "
                                 f"number, got {value!r}")
    return value


@functools.lru_cache(maxsize=64)
def _design_cached(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std):
    from ..designer import design
    from ..spec import parse_spec
    spec = parse_spec({
        "name": "attitude channel (seed 004)", "structure": "cf2", "order": 2, "discrete": True,
        "gain_form": "filter",
        "sensors": {
            "rate": {"measures": "rate", "rate_hz": rate_hz, "noise": {"std": gyro_noise_std},
                     "bias": {"model": "random_walk", "density": gyro_bias_density}},
            "angle": {"measures": "angle", "rate_hz": rate_hz, "noise": {"std": angle_noise_std}},
        }})
    return design(spec)


def design_channel(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std):
    """Gains of one attitude channel: ``cfdesign.design`` of a discrete ``cf2`` order 2, filter form.

    Model (MATH.md §2, seed 004 Sec. 2.1): ``λ[k+1] = λ[k] + T (u[k] + c[k])``,
    ``c[k+1] = c[k]`` (``c = -b``, rate correction) with gyro noise ``gyro_noise_std`` (rad/s
    per sample), a random-walk bias ``gyro_bias_density`` (rad/s/sqrt(s)) and an angle
    reading with ``angle_noise_std`` (rad per sample), all at ``rate_hz``.  The DARE gives the
    filter-form gain ``[k1, k2]``: ``λ+ = λ- + k1 e``, ``c+ = c- + k2 e`` (``k2`` in 1/s).
    Cached: equal arguments return the same :class:`~cfdesign.gains.GainTable`.
    """
    return _design_cached(_positive("rate_hz", rate_hz), _positive("gyro_noise_std", gyro_noise_std),
                          _positive("gyro_bias_density", gyro_bias_density),
                          _positive("angle_noise_std", angle_noise_std))


def gain_schedule(table, bias_std0, steps, rtol=1e-3):
    """Start-up gains ``(k1[k], k2[k])`` of a designed ``cf2`` table: its Kalman recursion from a prior.

    The filter-form Riccati recursion of the table's own ``F, Q, R`` (``H = [1, 0]``)::

        K = P⁻ Hᵀ (H P⁻ Hᵀ + R)⁻¹,  P⁺ = (I - K H) P⁻,  P⁻ ← F P⁺ Fᵀ + Q

    from ``P⁻ = diag(R, bias_std0²)``, run until the gain is within ``rtol`` of the table's DARE
    gain (its limit) or for ``steps`` steps; the last entry is the DARE gain itself.  Returns
    two lists.  ``bias_std0 = 0`` returns the DARE gain only.
    """
    k1_inf, k2_inf = table.gains["k1"], table.gains["k2"]
    if bias_std0 == 0:
        return [k1_inf], [k2_inf]
    (f00, f01), (f10, f11) = table.F.tolist()
    (q00, q01), (_, q11) = table.Q.tolist()
    r = float(table.R[0][0])
    p00, p01, p11 = r, 0.0, bias_std0 ** 2
    k1s, k2s = [], []
    for _ in range(max(int(steps), 1)):
        s = p00 + r
        k1, k2 = p00 / s, p01 / s
        k1s.append(k1)
        k2s.append(k2)
        if abs(k1 - k1_inf) <= rtol * k1_inf and abs(k2 - k2_inf) <= rtol * k2_inf:
            break
        a00, a01, a11 = (1 - k1) * p00, (1 - k1) * p01, p11 - k2 * p01
        p00 = f00 * f00 * a00 + 2 * f00 * f01 * a01 + f01 * f01 * a11 + q00
        p01 = f00 * f10 * a00 + (f00 * f11 + f01 * f10) * a01 + f01 * f11 * a11 + q01
        p11 = f10 * f10 * a00 + 2 * f10 * f11 * a01 + f11 * f11 * a11 + q11
    k1s.append(k1_inf)
    k2s.append(k2_inf)
    return k1s, k2s


# --------------------------------------------------------------------------------------------
# input checks


def _vectors(name, value, n=None, allow_none=False):
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


def _inputs(gyr, acc, mag, velocity_body=None):
    gyr = _vectors("gyr", gyr)
    if len(gyr) == 0:
        raise AttitudeInputError("gyr is empty: need at least one sample")
    acc = _vectors("acc", acc, len(gyr))
    mag = _vectors("mag", mag, len(gyr), allow_none=True)
    vel = _vectors("velocity_body", velocity_body, len(gyr), allow_none=True)
    return gyr, acc, mag, vel


def _usable_mag(mag):
    """Field rows that can correct heading: finite and non-zero (others -> NaN, skipped)."""
    if mag is None:
        return None
    bad = ~np.isfinite(mag).all(axis=1) | ~(np.abs(mag).sum(axis=1) > 0)
    return np.where(bad[:, None], np.nan, mag)


def _usable_acc(acc):
    bad = ~np.isfinite(acc).all(axis=1) | ~(np.abs(acc).sum(axis=1) > 0)
    return np.where(bad[:, None], np.nan, acc)


def _initial_quaternion(acc, mag, declination_rad, initial):
    """Initial attitude: ``initial`` (a quaternion) or the MPS of the first usable sample."""
    if initial is not None:
        q0 = np.asarray(initial, dtype=float)
        if q0.shape != (4,) or not np.isfinite(q0).all() or np.linalg.norm(q0) == 0:
            raise AttitudeInputError(f"initial must be a finite non-zero quaternion [w, x, y, z], got {initial!r}")
        return quat.normalize(q0)
    rows = np.flatnonzero(np.isfinite(acc).all(axis=1))
    if len(rows) == 0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    k = rows[0]
    if mag is not None:
        good = rows[np.isfinite(mag[rows]).all(axis=1)]
        k = good[0] if len(good) else k
    return mps_quaternion(acc[k], None if mag is None else mag[k], declination_rad=declination_rad)


# --------------------------------------------------------------------------------------------
# Euler form (seed 004 Sec. 2.1, Fig. 2)


@dataclass(frozen=True)
class EulerEstimate:
    """Output of :meth:`EulerAttitudeFilter.run`; attitude of the body relative to **ENU**.

    Attributes
    ----------
    euler : ndarray (N, 3)
        ZYX ``[yaw, pitch, roll]`` (rad), yaw wrapped to ``(-pi, pi]``.
    bias : ndarray (N, 3)
        Body-rate gyro bias estimate ``b_ω`` (rad/s).
    quaternion : ndarray (N, 4)
        The same attitude as ``[w, x, y, z]``, body -> ENU.
    gains : dict
        The designed :class:`~cfdesign.gains.GainTable` per channel group: ``"tilt"`` (pitch,
        roll) and ``"heading"`` (yaw).
    """

    euler: np.ndarray
    bias: np.ndarray
    quaternion: np.ndarray
    gains: dict


class EulerAttitudeFilter:
    """Seed 004's Euler-angle attitude complementary filter with body-rate gyro bias.

    Per channel ``λ ∈ (ψ, θ, φ)``, in filter form at every sample ``k`` (seed 004 Sec. 2.1,
    MATH.md §7)::

        e      = y_λ[k] - λ⁻[k]                  (yaw innovation wrapped to (-pi, pi])
        λ[k]   = λ⁻[k] + k1 e
        b_ω    = b_ω - Q(λ)^-1 (k2 e)            (bias kept in body rates, Fig. 2's dotted box)
        λ⁻[k+1] = λ[k] + T Q(λ[k]) (ω[k] - b_ω)  (u_λ = Q(λ) ω)

    with ``y_λ`` the MPS (:func:`cfdesign.nav.mps.mps_euler`, centripetal compensation when a
    body velocity is given) and ``k1, k2`` designed by :func:`design_channel` from the noise
    figures: tilt channels with ``tilt_noise_std``, yaw with ``heading_noise_std``.

    Parameters
    ----------
    rate_hz : float
        IMU (and MPS) sample rate (Hz).
    gyro_noise_std : float
        Gyro white noise, rad/s per sample.
    gyro_bias_density : float
        Gyro bias random walk, rad/s/sqrt(s).
    tilt_noise_std, heading_noise_std : float
        MPS roll/pitch resp. yaw noise, rad per sample.
    declination_rad : float
        Magnetic declination (positive east).

    Notes
    -----
    Frame ENU, Euler ZYX of the body relative to ENU.  ``Q(λ)`` is singular at pitch ±90°:
    use :func:`estimate_attitude` for attitudes that get there.  Missing data: a gyro row
    with NaN holds the attitude (zero rate); a non-finite or zero accelerometer row skips
    the whole correction; a non-finite or zero field row skips the yaw correction.
    """

    def __init__(self, rate_hz, *, gyro_noise_std, gyro_bias_density, tilt_noise_std, heading_noise_std,
                 declination_rad=0.0):
        self.rate_hz = _positive("rate_hz", rate_hz)
        self.declination_rad = float(declination_rad)
        for name, value in (("gyro_noise_std", gyro_noise_std), ("gyro_bias_density", gyro_bias_density),
                            ("tilt_noise_std", tilt_noise_std), ("heading_noise_std", heading_noise_std)):
            _positive(name, value)
        tilt = design_channel(rate_hz, gyro_noise_std, gyro_bias_density, tilt_noise_std)
        heading = design_channel(rate_hz, gyro_noise_std, gyro_bias_density, heading_noise_std)
        self.gains = {"tilt": tilt, "heading": heading}
        # per channel (ψ, θ, φ)
        self.k1 = np.array([heading.gains["k1"], tilt.gains["k1"], tilt.gains["k1"]])
        self.k2 = np.array([heading.gains["k2"], tilt.gains["k2"], tilt.gains["k2"]])

    def run(self, gyr, acc, mag, velocity_body=None, initial=None) -> EulerEstimate:
        """Filter a log: ``gyr`` (N, 3) rad/s, ``acc`` (N, 3) m/s², ``mag`` (N, 3) or None.

        ``velocity_body`` (N, 3) m/s enables the centripetal compensation; ``initial`` is the
        initial ``[yaw, pitch, roll]`` (rad, ENU) and defaults to the MPS of the first usable
        sample.  Returns an :class:`EulerEstimate` (ENU).
        """
        gyr, acc, mag, vel = _inputs(gyr, acc, mag, velocity_body)
        acc, mag = _usable_acc(acc), _usable_mag(mag)
        gyr = np.where(np.isfinite(gyr).all(axis=1)[:, None], gyr, 0.0)
        y = None if vel is not None else mps_euler(acc, mag, declination_rad=self.declination_rad).tolist()
        lam = [float(v) for v in self._initial(acc, mag, initial)]
        b = [0.0, 0.0, 0.0]
        T = 1.0 / self.rate_hz
        gains = (self.k1.tolist(), self.k2.tolist())
        out_e, out_b = np.empty((len(gyr), 3)), np.empty((len(gyr), 3))
        for k, w in enumerate(gyr.tolist()):
            rate = [w[0] - b[0], w[1] - b[1], w[2] - b[2]]
            yk = y[k] if y is not None else self._mps_one(acc[k], None if mag is None else mag[k], rate, vel[k])
            lam, b = _euler_correct(lam, b, yk, gains)
            out_e[k], out_b[k] = lam, b
            lam = _euler_propagate(lam, [w[0] - b[0], w[1] - b[1], w[2] - b[2]], T)
        return EulerEstimate(out_e, out_b, quat.normalize(quat.from_euler(out_e)), self.gains)

    def _initial(self, acc, mag, initial):
        if initial is not None:
            lam = np.asarray(initial, dtype=float)
            if lam.shape != (3,) or not np.isfinite(lam).all():
                raise AttitudeInputError(f"initial must be finite [yaw, pitch, roll] in rad, got {initial!r}")
            return lam.copy()
        q0 = _initial_quaternion(acc, mag, self.declination_rad, None)
        return quat.to_euler(q0)

    def _mps_one(self, a, m, rate, v):
        return mps_euler(a, m, declination_rad=self.declination_rad, rate=np.asarray(rate),
                         velocity_body=v).tolist()


def _euler_propagate(lam, rate, T):
    """``λ + T Q(λ) ω`` (seed 004 Sec. 2.1) in Python floats; yaw wrapped."""
    psi, theta, phi = lam
    sf, cf = math.sin(phi), math.cos(phi)
    ct, tt = math.cos(theta), math.tan(theta)
    wy, wz = rate[1], rate[2]
    return [wrap_scalar(psi + T * (sf * wy + cf * wz) / ct), theta + T * (cf * wy - sf * wz),
            phi + T * (rate[0] + tt * (sf * wy + cf * wz))]


def _euler_correct(lam, b, y, gains):
    """Measurement update ``λ += k1 e``, ``b_ω -= Q(λ)^-1 (k2 e)``; channels with a NaN MPS are skipped."""
    (k1p, k1t, k1r), (k2p, k2t, k2r) = gains
    e = [y[0] - lam[0], y[1] - lam[1], y[2] - lam[2]]
    e = [v if v == v else 0.0 for v in e]                   # NaN: channel not measured
    e[0] = wrap_scalar(e[0])
    psi, theta, phi = wrap_scalar(lam[0] + k1p * e[0]), lam[1] + k1t * e[1], lam[2] + k1r * e[2]
    dpsi, dtheta, dphi = k2p * e[0], k2t * e[1], k2r * e[2]
    st, ct, sf, cf = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
    b = [b[0] - (-st * dpsi + dphi), b[1] - (ct * sf * dpsi + cf * dtheta), b[2] - (ct * cf * dpsi - sf * dtheta)]
    return [psi, theta, phi], b


# --------------------------------------------------------------------------------------------
# quaternion form (singularity-free) and the general entry point


def estimate_attitude(gyr, acc, mag, rate_hz, *, gyro_noise_density=None, gyro_bias_density=None,
                      tilt_noise_density=None, heading_noise_density=None, declination_rad=0.0,
                      gyro_bias_std0=0.0175, initial=None, correction_rate_hz=1.0, return_bias=False):
    """Attitude quaternions of the sensor frame relative to **ENU** from a gyro, accelerometer and magnetometer.

    The singularity-free form of seed 004's attitude filter (see the module docstring).  The
    gyro propagates ``q[k] = q[k-1] ⊗ exp((ω[k] - b) T)`` (half-angle quaternion exponential)
    at the full rate; every ``M`` samples (``M = round(rate_hz / correction_rate_hz)``, one
    second by default) the MPS corrects it.  The error between the propagated attitude and
    the MPS is resolved in ENU: inclination
    ``δ_xy = angle(R a, e_z)`` about ``R a × e_z`` and heading
    ``δ_z = wrap(angle of magnetic north - angle of (R m)_horizontal)``, then::

        q ← exp(K1 δ / 2) ⊗ q,   b ← b - R^T (K2 δ),   K_i = diag(k_i^tilt, k_i^tilt, k_i^heading)

    with ``k1, k2`` designed by :func:`design_channel` (``cf2``, DARE) at the correction rate
    ``rate_hz / M`` from the noise densities (the lifted single-rate problem of MATH.md §6).
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
        from the first sample.
    correction_rate_hz : float
        Rate of the MPS corrections (Hz), default 1 (a one-second strapdown-frame average);
        ``>= rate_hz`` corrects every sample with that sample alone.
    return_bias : bool
        Also return the gyro bias estimate (N, 3), rad/s, body frame.

    Returns
    -------
    ndarray (N, 4)
        Unit quaternions ``[w, x, y, z]`` (w >= 0), sensor frame relative to ENU; with
        ``return_bias`` the tuple ``(quaternions, bias)``.

    Raises
    ------
    AttitudeInputError
        (a :class:`~cfdesign.errors.CfdesignError`) for wrong shapes, ``rate_hz <= 0`` or
        invalid noise figures.

    Notes
    -----
    Missing data never yields a NaN quaternion: a gyro row with a NaN is a zero rate (the
    attitude is held); accelerometer rows that are not finite or zero are left out of the
    correction (a block without any skips the correction); field rows that are not finite or
    zero (or parallel to gravity) skip only the heading correction.
    """
    gyr, acc, mag, _ = _inputs(gyr, acc, mag)
    rate_hz = _positive("rate_hz", rate_hz)
    noise = {name: _positive(name, given) if given is not None else value
             for (name, value), given in zip(DEFAULT_NOISE.items(), (gyro_noise_density, gyro_bias_density,
                                                                     tilt_noise_density, heading_noise_density),
                                                    strict=True)}
    M = max(1, round(rate_hz / _positive("correction_rate_hz", correction_rate_hz)))
    f_c = rate_hz / M
    tilt = design_channel(f_c, noise["gyro_noise_density"] * math.sqrt(f_c), noise["gyro_bias_density"],
                          noise["tilt_noise_density"] * math.sqrt(f_c))
    heading = design_channel(f_c, noise["gyro_noise_density"] * math.sqrt(f_c), noise["gyro_bias_density"],
                             noise["heading_noise_density"] * math.sqrt(f_c))
    nb = -(-len(gyr) // M)
    std0 = _positive("gyro_bias_std0", gyro_bias_std0, allow_zero=True)
    gains = _merge_schedules(gain_schedule(tilt, std0, nb), gain_schedule(heading, std0, nb))
    acc, mag = _usable_acc(acc), _usable_mag(mag)
    q0 = _initial_quaternion(acc, mag, float(declination_rad), initial)
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
    dq = quat.from_rotation_vector(w * T)
    P = np.empty_like(dq)
    P[:, 0] = dq[:, 0]
    for j in range(1, M):
        P[:, j] = quat.multiply(P[:, j - 1], dq[:, j])
    return P / np.linalg.norm(P, axis=-1, keepdims=True)


def _block_mean(vectors, P):
    """Mean of body vectors over each block, expressed in the block-end body frame (NaN rows skipped)."""
    if vectors is None:
        return None
    v = quat.rotate(P, _blocks(vectors, P.shape[1], np.nan))           # into the block-start frame
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN blocks -> NaN (skipped)
        mean = np.nanmean(v, axis=1)
    return quat.rotate(quat.conjugate(P[:, -1]), mean)                 # into the block-end frame


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
    bias_rot = quat.from_rotation_vector(-residual[:, None, :] * steps)
    q = quat.multiply(quat.multiply(starts[:, None, :], P), bias_rot).reshape(-1, 4)[:n]
    bias = np.repeat(biases, M, axis=0)[:n]
    return quat.normalize(q), bias
