"""The helicopter manoeuvre of Vasconcelos et al.: a straight path, then an ascending helix, and its IMU/GPS readings.

Frames and conventions
----------------------
* Earth frame **ENU** (x East, y North, z Up); gravity ``g_n = [0, 0, -9.80665]`` m/s^2.
* Body frame **FLU** (x forward, y left, z up); attitude as Z-Y-X Euler angles
  ``lambda = (psi, theta, phi)`` (yaw, pitch, roll), ``R_nb = R_z(psi) R_y(theta) R_x(phi)``
  (body -> ENU), quaternions ``[w, x, y, z]`` of the same rotation, as in
  :mod:`cfdesign.rotations`.  Yaw is counted counter-clockwise from East.
* The accelerometer measures the **specific force** in the body frame,
  ``f_b = R_nb^T (a_n - g_n)``, so a vehicle at rest reads ``+9.80665`` m/s^2 on its z axis
  and the Earth-frame acceleration is ``a_n = R_nb f_b + g_n``.  With this convention the
  pendular part of the Magneto-Pendular Sensor is the paper's eq. (2)-(3) unchanged:
  ``f_b = (-g sin(theta), g cos(theta) sin(phi), g cos(theta) cos(phi))`` at rest.
* Body rates from the attitude derivative: ``lambda' = Q(lambda) omega`` (Sec. 2.1),
  solved for ``omega``.

The trajectory (Sec. 4, Fig. 5 - dimensions not printed; our choices)
---------------------------------------------------------------------
* 0-20 s, straight level path East at ``speed_m_s = 5`` m/s (cruise from the start; a
  ``start_speed_m_s`` below it accelerates along the smooth profile of
  :func:`cfdesign.sim.trajectory.smooth_turn` in ``accel_s``); the loop starts at 20 s as in
  the paper (Sec. 4);
* from 20 s, an ascending helix: turn rate (left) and climb rate rise smoothly in
  ``entry_s = 5`` s to ``turn_rate_rad_s = 1/3`` rad/s (radius 15 m, a turn every 18.8 s)
  and ``climb_m_s = 0.5`` m/s, for ``helix_s = 80`` s (100 s in all, 4.1 turns, 38 m climbed);
* the attitude of a helicopter in coordinated flight: yaw along the course, and the rotor
  thrust (body z) along the specific force, so ``f_b = (0, 0, |a_n - g_n|)``; pitch and roll
  follow from the acceleration (nose down to speed up, bank into the turn).

Kinematics are analytic (velocity, acceleration, jerk, attitude and its derivative) except
the horizontal position, integrated on a grid ``oversample`` times finer than the IMU.

Sensors (Table 1; per-axis readings of our choice where the paper is silent)
----------------------------------------------------------------------------
IMU at 50 Hz, GPS at 1 Hz (first fix at t = 0).  Gyro: constant bias 0.05 deg/s and white
noise of variance (0.02 deg/s)^2 per sample on each axis, bias signs ``BIAS_SIGNS``;
accelerometer: noise (0.6 mg)^2 per axis, 1 mg = 9.80665e-3 m/s^2, and a 10-mg bias on the
body z axis (``ACCEL_BIAS_READINGS["z"]``).  Why z: a horizontal accelerometer bias ``b``
tilts the pendular attitude by ``b/g`` (0.57 deg per 10 mg) and no filter fed by the same
accelerometer can see it (the position filter's gravity removal cancels it, the paper's
"multiple equilibrium points"); the paper's pitch and roll errors (0.168 and 0.101 deg)
leave room for at most 2.9 and 1.8 mg on body x and y.  ``"xyz"`` puts 10 mg on every axis.
Magnetometer: noise (1 uG)^2 per axis on a horizontal 0.5-G field pointing North (ours: the
paper gives no field; its yaw error, ten times below the tilt errors, rules out a steep dip,
through which tilt errors would leak into the heading), sampled at the IMU sample times.  GPS: white noise of variance
10 m^2 on each ENU axis.  Gyro and accelerometer read the *mean* over each 20-ms interval
(integrating sensors) through :class:`cfdesign.sim.sensors.RateSensor`; magnetometer and GPS
sample the truth at the sample times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import rotations as rot
from ..errors import InputError
from ..rotations import GRAVITY_ENU, euler_rate_matrix_inverse
from .sensors import RateSensor, cumulative_trapezoid, interval_mean_readings, noisy_samples
from .trajectory import SampledTimes, smooth_turn

__all__ = ["GRAVITY_M_S2", "GRAVITY_ENU", "MG_M_S2", "BIAS_SIGNS", "MAGNETIC_FIELD_ENU_G", "ACCEL_BIAS_READINGS",
           "Manoeuvre", "HelicopterTrajectory", "helicopter_manoeuvre", "SensorErrors", "TABLE1", "ImuGpsReadings",
           "simulate_readings", "declination_rad"]

#: standard gravity (m/s^2); ``GRAVITY_ENU = [0, 0, -GRAVITY_M_S2]``: ``a_n = R_nb f_b + GRAVITY_ENU``
GRAVITY_M_S2 = -float(GRAVITY_ENU[2])
#: one milli-g (m/s^2)
MG_M_S2 = 1e-3 * GRAVITY_M_S2
#: signs of the constant gyro biases on the body x, y, z axes (ours)
BIAS_SIGNS = (1.0, -1.0, 1.0)
#: Earth magnetic field in ENU (gauss): 0.27 G North, 0.35 G down (ours; mid northern latitude)
MAGNETIC_FIELD_ENU_G = np.array([0.0, 0.5, 0.0])


# ---------------------------------------------------------------------------- trajectory
@dataclass(frozen=True)
class Manoeuvre:
    """Dimensions of the manoeuvre (module docstring); SI units, angles in rad.

    Attributes
    ----------
    straight_s : float
        Duration of the straight level path (s).
    start_speed_m_s : float
        Speed at ``t = 0`` (m/s); below ``speed_m_s`` the helicopter accelerates in ``accel_s``.
    speed_m_s : float
        Cruise speed (m/s).
    accel_s : float
        Duration of the acceleration (s).
    helix_s : float
        Duration of the ascending helix (s).
    entry_s : float
        Time in which turn rate and climb rate rise smoothly into the helix (s).
    turn_rate_rad_s : float
        Turn rate of the helix (rad/s, left).
    climb_m_s : float
        Climb rate of the helix (m/s).
    rate_hz : float
        IMU rate (Hz).
    oversample : int
        Integration grid points per IMU sample for the horizontal position.
    """

    straight_s: float = 20.0
    start_speed_m_s: float = 5.0
    speed_m_s: float = 5.0
    accel_s: float = 10.0
    helix_s: float = 80.0
    entry_s: float = 5.0
    turn_rate_rad_s: float = 1.0 / 3.0
    climb_m_s: float = 0.5
    rate_hz: float = 50.0
    oversample: int = 10

    @property
    def duration_s(self) -> float:
        """Total duration (s): the straight path and the helix."""
        return self.straight_s + self.helix_s


@dataclass(frozen=True)
class HelicopterTrajectory(SampledTimes):
    """Sampled truth at the ``N + 1`` IMU sample times (ENU, FLU body; module docstring).

    Attributes
    ----------
    t_s : ndarray, shape (N + 1,)
        Sample times (s).
    position_m, velocity_m_s, acceleration_m_s2 : ndarray, shape (N + 1, 3)
        Position (m), velocity (m/s) and acceleration (m/s^2) in ENU.
    euler_rad : ndarray, shape (N + 1, 3)
        ``[yaw, pitch, roll]`` (rad), yaw continuous (not wrapped).
    quaternion : ndarray, shape (N + 1, 4)
        Attitude ``[w, x, y, z]``, body -> ENU.
    body_rate_rad_s : ndarray, shape (N + 1, 3)
        Angular rate ``omega`` (rad/s) in the body frame.
    specific_force_m_s2 : ndarray, shape (N + 1, 3)
        Specific force ``f_b = R_nb^T (a_n - g_n)`` (m/s^2) in the body frame.
    mean_body_rate_rad_s, mean_specific_force_m_s2 : ndarray, shape (N, 3)
        Means over each sample interval (rad/s, m/s^2; body frame): what integrating sensors read.
    """

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    euler_rad: np.ndarray
    quaternion: np.ndarray
    body_rate_rad_s: np.ndarray
    specific_force_m_s2: np.ndarray
    mean_body_rate_rad_s: np.ndarray
    mean_specific_force_m_s2: np.ndarray


def _ramp(t, start, length):
    """Smooth 0 -> 1 ramp ``P(s) = s - sin(2 pi s)/(2 pi)``, ``s = (t - start)/length``: P, P', P'' (per s), int P."""
    s = (t - start) / length
    inside = (s > 0) & (s < 1)
    p = smooth_turn(s)
    dp = np.where(inside, (1 - np.cos(2 * np.pi * s)) / length, 0.0)
    ddp = np.where(inside, 2 * np.pi * np.sin(2 * np.pi * s) / length**2, 0.0)
    sc = np.clip(s, 0.0, 1.0)
    integral = length * (sc**2 / 2 + (np.cos(2 * np.pi * sc) - 1) / (4 * np.pi**2) + np.maximum(s - 1, 0.0))
    return p, dp, ddp, integral


def _heading_frame_motion(t, m: Manoeuvre):
    """Speed, course and climb profiles and their derivatives (module docstring)."""
    P, dP, ddP, _ = (r * (m.speed_m_s - m.start_speed_m_s) for r in _ramp(t, 0.0, m.accel_s))
    V, dV, ddV = m.start_speed_m_s + P, dP, ddP
    P, dP, ddP, intP = _ramp(t, m.straight_s, m.entry_s)
    psi, dpsi, ddpsi = m.turn_rate_rad_s * intP, m.turn_rate_rad_s * P, m.turn_rate_rad_s * dP
    z, w, dw, ddw = m.climb_m_s * intP, m.climb_m_s * P, m.climb_m_s * dP, m.climb_m_s * ddP
    return V, dV, ddV, psi, dpsi, ddpsi, z, w, dw, ddw


def _thrust_attitude(fh, dfh):
    """Pitch and roll putting body z along the heading-frame specific force ``fh``, and their rates.

    ``R_y(theta) R_x(phi) e_z = (cos(phi) sin(theta), -sin(phi), cos(phi) cos(theta)) = fh/|fh|``.
    """
    fx, fy, fz = fh
    dfx, dfy, dfz = dfh
    r2 = fx**2 + fz**2
    r = np.sqrt(r2)
    theta = np.arctan2(fx, fz)
    dtheta = (fz * dfx - fx * dfz) / r2
    phi = np.arctan2(-fy, r)
    dr = (fx * dfx + fz * dfz) / r
    dphi = (fy * dr - r * dfy) / (fy**2 + r2)
    return theta, phi, dtheta, dphi


def _fine_truth(t, m: Manoeuvre) -> dict:
    """Every analytic quantity on the time grid ``t`` (horizontal position excepted)."""
    V, dV, ddV, psi, dpsi, ddpsi, z, w, dw, ddw = _heading_frame_motion(t, m)
    fh = (dV, V * dpsi, dw + GRAVITY_M_S2)  # specific force in the heading frame R_z(psi)^T (a_n - g_n)
    dfh = (ddV, dV * dpsi + V * ddpsi, ddw)
    theta, phi, dtheta, dphi = _thrust_attitude(fh, dfh)
    c, s = np.cos(psi), np.sin(psi)
    euler = np.column_stack([psi, theta, phi])
    R = rot.to_matrix(rot.from_euler(euler))
    acc = np.column_stack([dV * c - V * dpsi * s, dV * s + V * dpsi * c, dw])
    omega = np.einsum("kij,kj->ki", euler_rate_matrix_inverse(euler), np.column_stack([dpsi, dtheta, dphi]))
    return {"euler": euler, "omega": omega,
            "velocity": np.column_stack([V * c, V * s, w]), "acceleration": acc, "z": z,
            "force": np.einsum("kji,kj->ki", R, acc - GRAVITY_ENU)}


def helicopter_manoeuvre(manoeuvre: Manoeuvre | None = None) -> HelicopterTrajectory:
    """The straight-then-helix manoeuvre of Vasconcelos et al. Sec. 4 (Fig. 5), sampled at the IMU rate.

    Parameters
    ----------
    manoeuvre : Manoeuvre, optional
        Dimensions; default the module docstring's.

    Returns
    -------
    HelicopterTrajectory
        The sampled trajectory (ENU, body -> ENU attitude).

    Raises
    ------
    InputError
        The duration is not a whole number of IMU samples, or ``oversample < 1``.
    """
    m = manoeuvre or Manoeuvre()
    steps = round(m.duration_s * m.rate_hz)
    if steps < 1 or not math.isclose(steps / m.rate_hz, m.duration_s, rel_tol=1e-9) or m.oversample < 1:
        raise InputError(f"manoeuvre: duration {m.duration_s:g} s is not a whole number of {1 / m.rate_hz:g}-s samples")
    M = int(m.oversample)
    h = 1.0 / (m.rate_hz * M)
    fine = _fine_truth(np.arange(steps * M + 1) * h, m)
    horizontal = cumulative_trapezoid(fine["velocity"][:, :2], h)
    position = np.column_stack([horizontal, fine["z"]])
    every = slice(None, None, M)
    mean = {k: np.diff(cumulative_trapezoid(fine[k], h)[every], axis=0) * m.rate_hz for k in ("omega", "force")}
    return HelicopterTrajectory(
        t_s=np.arange(steps + 1) / m.rate_hz, position_m=position[every], velocity_m_s=fine["velocity"][every],
        acceleration_m_s2=fine["acceleration"][every], euler_rad=fine["euler"][every],
        quaternion=rot.from_euler(fine["euler"][every]), body_rate_rad_s=fine["omega"][every],
        specific_force_m_s2=fine["force"][every], mean_body_rate_rad_s=mean["omega"],
        mean_specific_force_m_s2=mean["force"])


# ---------------------------------------------------------------------------- sensors
@dataclass(frozen=True)
class SensorErrors:
    """Sensor errors per axis (SI): constant biases, white-noise per-sample standard deviations.

    Defaults: Table 1 of Vasconcelos et al. (module docstring).

    Attributes
    ----------
    gyro_bias_rad_s : float
        Gyro bias magnitude (rad/s), signs :data:`BIAS_SIGNS`.
    gyro_noise_std_rad_s : float
        Gyro noise per sample (rad/s).
    accel_bias_m_s2 : float
        Accelerometer bias magnitude (m/s^2).
    accel_noise_std_m_s2 : float
        Accelerometer noise per sample (m/s^2).
    mag_noise_std_g : float
        Magnetometer noise per sample (gauss).
    gps_noise_std_m : float
        GPS noise per fix and axis (m).
    gps_rate_hz : float
        GPS rate (Hz); it must divide the IMU rate.
    accel_bias_axes : tuple of 3 floats
        Body axes the accelerometer bias is on (``(0, 0, 1)``: body z).
    """

    gyro_bias_rad_s: float = math.radians(0.05)
    gyro_noise_std_rad_s: float = math.radians(0.02)
    accel_bias_m_s2: float = 10 * MG_M_S2
    accel_noise_std_m_s2: float = 0.6 * MG_M_S2
    mag_noise_std_g: float = 1e-6
    gps_noise_std_m: float = math.sqrt(10.0)
    gps_rate_hz: float = 1.0
    accel_bias_axes: tuple = (0.0, 0.0, 1.0)

    @property
    def gyro_bias(self) -> np.ndarray:
        """Body-frame gyro bias (rad/s), signs :data:`BIAS_SIGNS`."""
        return self.gyro_bias_rad_s * np.array(BIAS_SIGNS)

    @property
    def accel_bias(self) -> np.ndarray:
        """Body-frame accelerometer bias (m/s^2): ``accel_bias_m_s2`` times ``accel_bias_axes``."""
        return self.accel_bias_m_s2 * np.array(self.accel_bias_axes, dtype=float)


#: Table 1 of Vasconcelos et al. (accelerometer bias on body z: see the module docstring)
TABLE1 = SensorErrors()
#: readings of Table 1's "10 mg": on body z only (default), or on every axis with signs +, -, +
ACCEL_BIAS_READINGS = {"z": (0.0, 0.0, 1.0), "xyz": BIAS_SIGNS}


@dataclass(frozen=True)
class ImuGpsReadings:
    """One run's readings.

    Attributes
    ----------
    gyro_rad_s, accel_m_s2 : ndarray, shape (N, 3)
        Gyro (rad/s) and accelerometer (m/s^2) readings in the body frame: means over each IMU
        interval ``[t_k, t_k+1]``.
    mag_g : ndarray, shape (N + 1, 3)
        Magnetic field in the body frame (gauss) at the sample times.
    gps_enu_m : ndarray, shape (N + 1, 3)
        ENU position fixes (m); NaN rows between fixes.
    """

    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    mag_g: np.ndarray
    gps_enu_m: np.ndarray


def simulate_readings(trajectory: HelicopterTrajectory, seed: int, errors: SensorErrors = TABLE1,
                      field_enu_g=MAGNETIC_FIELD_ENU_G) -> ImuGpsReadings:
    """IMU, magnetometer and GPS readings of one run (module docstring), reproducible by ``seed``.

    Each sensor axis draws from its own stream seeded by ``(seed, crc32(name))`` (as
    :func:`cfdesign.sim.sensors.simulate`).

    Parameters
    ----------
    trajectory : HelicopterTrajectory
        The truth (:func:`helicopter_manoeuvre`).
    seed : int
        Seed of the run.
    errors : SensorErrors
        Sensor errors; default Table 1.
    field_enu_g : array_like, shape (3,)
        Earth magnetic field in ENU (gauss).

    Returns
    -------
    ImuGpsReadings
        Gyro (rad/s) and accelerometer (m/s^2) means over each interval, magnetometer (gauss)
        at the samples, GPS ENU fixes (m) at their rate (NaN between).

    Raises
    ------
    InputError
        The GPS rate does not divide the IMU rate.
    """
    t = trajectory.t_s
    every = RateSensor(rate_hz=errors.gps_rate_hz).every(trajectory.dt_s)
    R = rot.to_matrix(trajectory.quaternion)
    mag = np.einsum("kji,j->ki", R, np.asarray(field_enu_g, dtype=float))
    return ImuGpsReadings(
        gyro_rad_s=interval_mean_readings(t, trajectory.mean_body_rate_rad_s, errors.gyro_bias,
                                   errors.gyro_noise_std_rad_s, "gyro", seed),
        accel_m_s2=interval_mean_readings(t, trajectory.mean_specific_force_m_s2, errors.accel_bias,
                                   errors.accel_noise_std_m_s2, "accelerometer", seed),
        mag_g=noisy_samples(mag, errors.mag_noise_std_g, 1, "magnetometer", seed),
        gps_enu_m=noisy_samples(trajectory.position_m, errors.gps_noise_std_m, every, "gps", seed))


def declination_rad(field_enu_g=MAGNETIC_FIELD_ENU_G) -> float:
    """Magnetic declination of a field given in ENU: ``atan2(m_E, m_N)``.

    The :mod:`cfdesign.nav.mps` yaw ``psi = atan2(m'_x, m'_y) - alpha_dec`` then returns the yaw
    counted from East; 0 for a field pointing North.

    Parameters
    ----------
    field_enu_g : array_like, shape (3,)
        Earth magnetic field in ENU (any unit).

    Returns
    -------
    float
        Declination (rad, positive East).

    Examples
    --------
    >>> from cfdesign.sim.helicopter import declination_rad
    >>> declination_rad([0.0, 0.5, -0.3])
    0.0
    """
    m = np.asarray(field_enu_g, dtype=float)
    return math.atan2(m[0], m[1])
