"""A ground robot on uneven terrain with GPS outages: truth and low-cost sensor readings.

The setting of Alves Neto et al. (adaptive complementary filtering for mobile robot localization).

Frames and conventions (as :mod:`cfdesign.sim.helicopter`)
-----------------------------------------------------------
* Earth frame **ENU**, body frame **FLU** (x forward, y left, z up); quaternions ``[w, x, y, z]``
  body -> ENU; Euler angles ZYX ``[yaw, pitch, roll]`` (:mod:`cfdesign.rotations`), so a
  positive pitch is nose *down* and the forward axis is ``[cosψ cosθ, sinψ cosθ, -sinθ]``.
* The accelerometer reads the specific force ``f_b = R^T (a_n - g_n)``, ``g_n = [0, 0, -9.80665]``.

Path and terrain (ours; the paper gives no dimensions)
------------------------------------------------------
* Horizontal path: a figure-eight (lemniscate of Gerono) ``x = A sin u``, ``y = (A/2) sin 2u``,
  ``u = Ω t``, ``A = 30`` m, ``AΩ = 1.2`` m/s: horizontal speed ``AΩ sqrt(cos²u + cos²2u)``
  between 0.8 and 1.7 m/s (slowest in the lobes' tight ends), heading sweeping through ±π on
  each lobe, one lap in 157 s.
* Terrain: ``h(x, y) = 0.3 sin(2πx/12) + 0.2 sin(2πy/9 + 0.5)`` m, slopes up to ~9°; the robot
  rides on it (``z = h``), body x along the velocity, body z along the terrain normal
  ``n ∝ [-h_x, -h_y, 1]``, so pitch and roll undulate with the height profile.
* Position, velocity and acceleration are analytic; the body rate is ``ω = Q(λ)^-1 λ'`` with
  the Euler rates ``λ'`` by a central difference of the analytic attitude (step 1e-4 s, error
  ~1e-9 rad/s) - the approach of :mod:`cfdesign.sim.helicopter`.  Integrating sensors read the
  means over each interval, computed on a grid ``oversample`` times finer.

Sensors (a typical low-cost MEMS IMU, consumer GPS; per axis, our figures)
--------------------------------------------------------------------------
* gyro: white noise 0.015 °/s/√Hz (0.1 °/s per sample at 50 Hz), constant residual bias
  0.1 °/s after a standstill calibration, signs :data:`~cfdesign.sim.helicopter.BIAS_SIGNS`;
* accelerometer: white noise 200 µg/√Hz (1.4 mg per sample at 50 Hz), bias 5 mg on each axis;
* magnetometer: field :data:`MAGNETIC_FIELD_ENU_G` (0.5 G, horizontal, north; heading errors
  through a dip are left out, as in the paper's levelled two-axis compass), noise 2 mG per axis;
* odometry: forward speed with a 2 % scale error and white noise 0.05 m/s;
* GPS at ``gps_rate_hz``: position noise 2.5 m, velocity noise 0.1 m/s per ENU axis; the
  receiver sees 6-10 satellites, and 0-3 during an outage, when it gives no fix.

Readings are at the IMU rate, ``N`` rows: row ``k`` belongs to the time ``t_s[k + 1]`` - gyro and
accelerometer are the means over ``[t_s[k], t_s[k + 1]]`` (read by
:class:`cfdesign.sim.sensors.RateSensor`), the others sample ``t_s[k + 1]``.  NaN marks a missing
GPS reading.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from .. import rotations as rot
from ..errors import InputError
from ..linear import wrap
from ..rotations import GRAVITY_ENU, euler_rate_matrix_inverse
from .helicopter import BIAS_SIGNS, MG_M_S2
from .sensors import cumulative_trapezoid, interval_mean_readings, noisy_samples
from .trajectory import SampledTimes

__all__ = ["MAGNETIC_FIELD_ENU_G", "GroundErrors", "GROUND_ERRORS", "GroundScenario", "ground_robot_scenario",
           "MAX_STEPS"]

#: Earth magnetic field in ENU (gauss) of the scenario: 0.5 G pointing north, horizontal
MAGNETIC_FIELD_ENU_G = np.array([0.0, 0.5, 0.0])

_AMPLITUDE_M = 30.0
_SPEED_SCALE_M_S = 1.2
_TERRAIN = ((0.3, 2 * math.pi / 12.0, 0.0), (0.2, 2 * math.pi / 9.0, 0.5))   # (amplitude m, k rad/m, phase)
_EULER_STEP_S = 1e-4


@dataclass(frozen=True)
class GroundErrors:
    """Sensor errors of the ground-robot scenario (module docstring); SI units, per axis.

    Attributes
    ----------
    gyro_noise_density : float
        Gyro white noise (rad/s/sqrt(Hz)).
    gyro_bias_rad_s : float
        Constant gyro bias (rad/s).
    accel_noise_density : float
        Accelerometer white noise (m/s^2/sqrt(Hz)).
    accel_bias_m_s2 : float
        Constant accelerometer bias (m/s^2).
    mag_noise_std_g : float
        Magnetometer noise per sample (gauss).
    odometry_scale_error : float
        Relative scale error of the odometer.
    odometry_noise_std_m_s : float
        Odometer speed noise per sample (m/s).
    gps_noise_std_m : float
        GPS position noise per fix and axis (m).
    gps_velocity_noise_std_m_s : float
        GPS velocity noise per fix and axis (m/s).
    """

    gyro_noise_density: float = math.radians(0.015)     # rad/s/sqrt(Hz)
    gyro_bias_rad_s: float = math.radians(0.1)
    accel_noise_density: float = 200e-6 * 9.80665        # m/s^2/sqrt(Hz)
    accel_bias_m_s2: float = 5 * MG_M_S2
    mag_noise_std_g: float = 2e-3
    odometry_scale_error: float = 0.02
    odometry_noise_std_m_s: float = 0.05
    gps_noise_std_m: float = 2.5
    gps_velocity_noise_std_m_s: float = 0.1


#: the default errors (module docstring)
GROUND_ERRORS = GroundErrors()


@dataclass(frozen=True)
class GroundScenario(SampledTimes):
    """Truth at the ``N + 1`` times ``t_s`` and readings at the IMU rate (``N`` rows, row k at ``t_s[k+1]``).

    Attributes
    ----------
    t_s : ndarray, shape (N + 1,)
        Sample times (s).
    position_m, velocity_m_s, acceleration_m_s2 : ndarray, shape (N + 1, 3)
        True position (m), velocity (m/s) and acceleration (m/s^2) in ENU.
    quaternion : ndarray, shape (N + 1, 4)
        True attitude ``[w, x, y, z]``, body -> ENU.
    euler_rad : ndarray, shape (N + 1, 3)
        ``[yaw, pitch, roll]`` (rad), yaw wrapped.
    speed_m_s : ndarray, shape (N + 1,)
        Forward (3-D) speed (m/s).
    body_rate_rad_s, specific_force_m_s2 : ndarray, shape (N + 1, 3)
        True angular rate (rad/s) and specific force (m/s^2) in the body frame, at the sample times.
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        Gyro (rad/s) and accelerometer (m/s^2) readings in the body frame, means over each interval.
    mag : ndarray, shape (N, 3)
        Magnetometer readings: the magnetic field in the body frame (gauss).
    odometry_speed_m_s : ndarray, shape (N,)
        Odometry reading of the forward speed (m/s).
    gps_enu_m, gps_velocity_enu_m_s : ndarray, shape (N, 3)
        GPS position (m) and velocity (m/s) fixes in ENU; NaN rows between fixes and in outages.
    n_satellites : ndarray of int, shape (N,)
        Satellites seen (fewer than 4 in outages).
    outages : tuple of (start, end)
        The GPS outages, ``[start, end)`` in seconds.
    """

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    quaternion: np.ndarray
    euler_rad: np.ndarray
    speed_m_s: np.ndarray
    body_rate_rad_s: np.ndarray
    specific_force_m_s2: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    mag: np.ndarray
    odometry_speed_m_s: np.ndarray
    gps_enu_m: np.ndarray
    gps_velocity_enu_m_s: np.ndarray
    n_satellites: np.ndarray
    outages: tuple

    @property
    def reading_t_s(self) -> np.ndarray:
        """Times (N,) of the reading rows, ``t_s[1:]``."""
        return self.t_s[1:]


# ---------------------------------------------------------------------------- truth
def _terrain(x, y):
    """Height ``h`` and its derivatives ``h_x, h_y, h_xx, h_yy`` (``h_xy = 0``)."""
    (a1, k1, p1), (a2, k2, p2) = _TERRAIN
    s1, c1, s2, c2 = np.sin(k1 * x + p1), np.cos(k1 * x + p1), np.sin(k2 * y + p2), np.cos(k2 * y + p2)
    return a1 * s1 + a2 * s2, a1 * k1 * c1, a2 * k2 * c2, -a1 * k1**2 * s1, -a2 * k2**2 * s2


def _motion(t):
    """Analytic ENU position, velocity and acceleration (..., 3), and the terrain gradient."""
    w = _SPEED_SCALE_M_S / _AMPLITUDE_M
    u = w * t
    x, y = _AMPLITUDE_M * np.sin(u), 0.5 * _AMPLITUDE_M * np.sin(2 * u)
    vx, vy = _SPEED_SCALE_M_S * np.cos(u), _SPEED_SCALE_M_S * np.cos(2 * u)
    ax, ay = -_SPEED_SCALE_M_S * w * np.sin(u), -2 * _SPEED_SCALE_M_S * w * np.sin(2 * u)
    h, hx, hy, hxx, hyy = _terrain(x, y)
    vz = hx * vx + hy * vy
    az = hxx * vx**2 + hyy * vy**2 + hx * ax + hy * ay
    return (np.stack([x, y, h], -1), np.stack([vx, vy, vz], -1), np.stack([ax, ay, az], -1),
            np.stack([-hx, -hy, np.ones_like(hx)], -1))


def _euler(t):
    """Attitude ``[yaw, pitch, roll]``: body x along the velocity, body z along the terrain normal."""
    _, v, _, normal = _motion(t)
    forward = v / np.linalg.norm(v, axis=-1, keepdims=True)
    up = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
    R = np.stack([forward, np.cross(up, forward), up], axis=-1)       # columns: body axes in ENU
    return rot.to_euler(rot.from_matrix(R))


def _body_rate(t):
    """``ω = Q(λ)^-1 λ'`` with ``λ'`` by a central difference of the analytic attitude."""
    h = _EULER_STEP_S
    euler = _euler(t)
    rates = wrap(_euler(t + h) - _euler(t - h)) / (2 * h)
    return np.einsum("kij,kj->ki", euler_rate_matrix_inverse(euler), rates), euler


def _fine_truth(t):
    """Every truth quantity on the grid ``t``."""
    position, velocity, acceleration, _ = _motion(t)
    omega, euler = _body_rate(t)
    R = rot.to_matrix(rot.from_euler(euler))
    force = np.einsum("kji,kj->ki", R, acceleration - GRAVITY_ENU)
    return {"position": position, "velocity": velocity, "acceleration": acceleration, "euler": euler,
            "omega": omega, "force": force}


# ---------------------------------------------------------------------------- readings
def _satellites(t, in_outage, every, rng):
    """Satellites seen: a slow walk in 6..10 (one step per GPS period), 0..3 in outages."""
    steps = rng.integers(-1, 2, size=len(t) // every + 1)
    walk = np.clip(8 + np.cumsum(steps), 6, 10)
    walk = np.repeat(walk, every)[: len(t)]
    low = rng.integers(0, 4, size=len(t) // every + 1)
    return np.where(in_outage, np.repeat(low, every)[: len(t)], walk).astype(int)


def _gps_rows(t, every, outages):
    """Rows with a fix (every ``every``-th sample time, not in an outage) and the outage mask."""
    in_outage = np.zeros(len(t), dtype=bool)
    for start, end in outages:
        in_outage |= (t >= start) & (t < end)
    fix = (np.arange(1, len(t) + 1) % every == 0) & ~in_outage
    return fix, in_outage


#: most IMU steps of a scenario (its truth is built at ``oversample`` times the rate, in memory)
MAX_STEPS = 1_000_000


def _validate(duration_s, imu_rate_hz, gps_rate_hz, outages):
    for name, value in (("duration_s", duration_s), ("imu_rate_hz", imu_rate_hz), ("gps_rate_hz", gps_rate_hz)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"{name}: a positive finite number is needed, got {value!r}")
    ratio = imu_rate_hz / gps_rate_hz
    if round(ratio) < 1 or not math.isclose(ratio, round(ratio), rel_tol=1e-9):
        raise InputError(f"gps_rate_hz: {gps_rate_hz:g} Hz must divide imu_rate_hz {imu_rate_hz:g} Hz")
    try:
        outages = tuple((float(a), float(b)) for a, b in outages)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"outages: (start_s, end_s) pairs are needed, got {outages!r}") from None
    if any(not a < b for a, b in outages):
        raise InputError(f"outages: each (start_s, end_s) needs start < end, got {outages!r}")
    steps = round(duration_s * imu_rate_hz)
    if steps < round(ratio) or steps > MAX_STEPS:  # none: an IndexError; 1e20: numpy's "maximum size exceeded"
        raise InputError(f"duration_s: {duration_s:g} s at {imu_rate_hz:g} Hz is {steps} IMU steps; a scenario has "
                         f"from one GPS period ({round(ratio)}) to {MAX_STEPS} steps")
    return round(ratio), outages


def ground_robot_scenario(seed=0, *, duration_s=300.0, imu_rate_hz=50.0, gps_rate_hz=1.0, outages=((120.0, 180.0),),
                          errors: GroundErrors = GROUND_ERRORS, oversample=10) -> GroundScenario:
    """A ground robot on a figure-eight over uneven terrain, with GPS outages (module docstring).

    Parameters
    ----------
    seed : int
        Seeds every random draw (each sensor its own stream, as :func:`cfdesign.sim.sensors.simulate`).
    duration_s : float
        Length (s); ``N = round(duration_s * imu_rate_hz)`` IMU intervals.
    imu_rate_hz, gps_rate_hz : float
        IMU and GPS rates (Hz); the GPS rate divides the IMU rate.
    outages : sequence of (start_s, end_s)
        Intervals ``[start, end)`` without fixes and with fewer than four satellites.
    errors : GroundErrors
        Sensor errors; default :data:`GROUND_ERRORS`.
    oversample : int
        Fine-grid factor for the interval means of the integrating sensors.

    Returns
    -------
    GroundScenario
        Truth, sensor readings and GPS fixes at the IMU rate.

    Raises
    ------
    InputError
        A non-positive duration or rate, a duration shorter than one GPS period or longer than
        :data:`MAX_STEPS` IMU steps, a GPS rate not dividing the IMU rate, bad outages.
    """
    every, outages = _validate(duration_s, imu_rate_hz, gps_rate_hz, outages)
    steps, M = round(duration_s * imu_rate_hz), int(oversample)
    t = np.arange(steps + 1) / imu_rate_hz
    fine = _fine_truth(np.arange(steps * M + 1) / (imu_rate_hz * M))
    truth = {k: v[::M] for k, v in fine.items()}
    mean = {k: np.diff(cumulative_trapezoid(fine[k], 1.0 / (imu_rate_hz * M))[::M], axis=0) * imu_rate_hz
            for k in ("omega", "force")}
    quaternion = rot.from_euler(truth["euler"])
    speed = np.linalg.norm(truth["velocity"], axis=-1)
    e = errors
    gyro = interval_mean_readings(t, mean["omega"], e.gyro_bias_rad_s * np.array(BIAS_SIGNS),
                           e.gyro_noise_density * math.sqrt(imu_rate_hz), "gyro", seed)
    accel = interval_mean_readings(t, mean["force"], e.accel_bias_m_s2 * np.array(BIAS_SIGNS),
                            e.accel_noise_density * math.sqrt(imu_rate_hz), "accelerometer", seed)
    field = np.einsum("kji,j->ki", rot.to_matrix(quaternion[1:]), MAGNETIC_FIELD_ENU_G)
    odometry = (1 + e.odometry_scale_error) * noisy_samples(speed[1:, None], e.odometry_noise_std_m_s / (
        1 + e.odometry_scale_error), 1, "odometry", seed)[:, 0]
    fix, in_outage = _gps_rows(t[1:], every, outages)
    gps = np.where(fix[:, None], noisy_samples(truth["position"][1:], e.gps_noise_std_m, 1, "gps", seed), np.nan)
    gps_v = np.where(fix[:, None], noisy_samples(truth["velocity"][1:], e.gps_velocity_noise_std_m_s, 1, "gps_velocity",
                                            seed), np.nan)
    rng = np.random.default_rng([int(seed), zlib.crc32(b"satellites")])
    return GroundScenario(
        t_s=t, position_m=truth["position"], velocity_m_s=truth["velocity"], acceleration_m_s2=truth["acceleration"],
        quaternion=quaternion, euler_rad=rot.to_euler(quaternion), speed_m_s=speed,
        body_rate_rad_s=truth["omega"], specific_force_m_s2=truth["force"], gyro_rad_s=gyro, accel_m_s2=accel,
        mag=noisy_samples(field, e.mag_noise_std_g, 1, "magnetometer", seed), odometry_speed_m_s=odometry,
        gps_enu_m=gps, gps_velocity_enu_m_s=gps_v, n_satellites=_satellites(t[1:], in_outage, every, rng),
        outages=outages)
