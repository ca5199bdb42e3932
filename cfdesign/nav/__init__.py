"""Navigation filters: attitude, position, and the baselines they are compared with.

Attitude APIs return the body (sensor) frame relative to **ENU** (x east, y north, z up):
quaternions ``[w, x, y, z]`` map body to ENU, Euler angles are ZYX ``[yaw, pitch, roll]``
(:mod:`cfdesign.rotations`).  The complementary filters run designed gain tables: by
default designed from noise figures without sympy (:mod:`cfdesign.nav.stored_design`), or a
user's own design given as ``tables=`` / ``table=``.

* :class:`AttitudeFilter` - the streaming attitude filter for real IMUs (gyro, accelerometer,
  optional magnetometer: rest, gyro bias, magnetic and acceleration disturbances; 6D and 9D;
  exported as C by :mod:`cfdesign.codegen.attitude`), :func:`estimate_attitude` its
  whole-array call (:mod:`~cfdesign.nav.attitude_filter`, :mod:`~cfdesign.nav.quaternion_attitude`);
  :func:`align_imu` puts streams at their own rates and time stamps (a phone's logger) on the gyro's
  clock for them (:mod:`~cfdesign.nav.attitude_streams`);
* :class:`EulerAttitudeFilter` - the Euler-angle filter of Vasconcelos et al. (low-pitch
  vehicles; :mod:`~cfdesign.nav.euler_attitude`);
* :func:`design_channel` - the gains of one attitude channel (:mod:`~cfdesign.nav.attitude_channel`);
* :class:`PositionFilter` - the per-axis position filter of Vasconcelos et al.
  (accelerometer + GPS, multirate gains; :mod:`~cfdesign.nav.position`);
* :mod:`~cfdesign.nav.mps` - the Magneto-Pendular Sensor; :mod:`~cfdesign.nav.triad` - TRIAD;
* :mod:`~cfdesign.nav.adaptive` - the adaptive complementary filter of Alves Neto et al.;
* :mod:`~cfdesign.nav.strapdown_ekf` - the 22-state strapdown EKF of the low-cost 3D
  localization paper; :mod:`~cfdesign.nav.planar_ekf` - the planar EKF of the outdoor
  localization paper (optical navigation sensor, IMU, GPS).

The names below are loaded on first use, so that importing one filter (an EKF, the MPS)
does not load the design stage the complementary filters use for their defaults.
"""

from importlib import import_module

_LAZY = {
    ".quaternion_attitude": ["estimate_attitude"],
    ".attitude_filter": ["AttitudeFilter", "AttitudeParams", "AttitudeRun", "design_attitude"],
    ".attitude_streams": ["align_imu", "AlignedImu", "hard_iron_offset"],
    ".euler_attitude": ["EulerAttitudeFilter", "EulerEstimate"],
    ".attitude_channel": ["design_channel"],
    "..errors": ["AttitudeInputError"],
    "..rotations": ["euler_rate_matrix", "euler_rate_matrix_inverse"],
    ".mps": ["mps_euler", "mps_quaternion"],
    ".position": ["PositionFilter", "PositionEstimate"],
}
_WHERE = {name: module for module, names in _LAZY.items() for name in names}

__all__ = ["estimate_attitude", "AttitudeFilter", "AttitudeParams", "AttitudeRun", "design_attitude",
           "align_imu", "AlignedImu", "hard_iron_offset", "EulerAttitudeFilter", "EulerEstimate", "AttitudeInputError",
           "design_channel",
           "euler_rate_matrix", "euler_rate_matrix_inverse", "mps_euler", "mps_quaternion", "PositionFilter",
           "PositionEstimate"]


def __getattr__(name):
    if name not in _WHERE:
        raise AttributeError(f"module 'cfdesign.nav' has no attribute {name!r}")
    value = getattr(import_module(_WHERE[name], __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *__all__})
