"""Navigation systems of the seeds: attitude (seed 004 Sec. 2) and position filters.

Attitude APIs return the body (sensor) frame relative to **ENU** (x east, y north, z up):
quaternions ``[w, x, y, z]`` map body to ENU, Euler angles are ZYX ``[yaw, pitch, roll]``.

* :func:`estimate_attitude` - general purpose, singularity-free (quaternion) filter;
* :class:`EulerAttitudeFilter` - seed 004's Euler-angle filter (low-pitch vehicles);
* :class:`PositionFilter` - seed 004's per-axis position filter (accelerometer + GPS, multirate gains);
* :mod:`cfdesign.nav.mps` - the Magneto-Pendular Sensor; rotations: :mod:`cfdesign.rotations`.
"""

from .attitude import (
                       AttitudeInputError,
                       EulerAttitudeFilter,
                       EulerEstimate,
                       design_channel,
                       estimate_attitude,
                       euler_rate_matrix,
                       euler_rate_matrix_inverse,
)
from .mps import mps_euler, mps_quaternion
from .position import PositionEstimate, PositionFilter

__all__ = ["estimate_attitude", "EulerAttitudeFilter", "EulerEstimate", "AttitudeInputError", "design_channel",
           "euler_rate_matrix", "euler_rate_matrix_inverse", "mps_euler", "mps_quaternion", "PositionFilter",
           "PositionEstimate"]
