"""cfdesign.sim.ground: kinematic consistency, GPS outages, satellites, reproducibility."""

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.errors import InputError
from cfdesign.rotations import GRAVITY_ENU
from cfdesign.sim.ground import ground_robot_scenario


@pytest.fixture(scope="module")
def scenario():
    return ground_robot_scenario(0, duration_s=240.0, outages=((100.0, 150.0),))


def test_shapes_and_ranges(scenario):
    s = scenario
    n = s.steps
    assert s.position_m.shape == s.velocity_m_s.shape == s.euler_rad.shape == (n + 1, 3)
    assert s.quaternion.shape == (n + 1, 4)
    for name in ("gyro_rad_s", "accel_m_s2", "mag", "gps_enu_m", "gps_velocity_enu_m_s"):
        assert getattr(s, name).shape == (n, 3), name
    assert s.odometry_speed_m_s.shape == s.n_satellites.shape == (n,)
    assert s.n_satellites.dtype.kind == "i"
    assert 0.7 < s.speed_m_s.min() and s.speed_m_s.max() < 2.0            # a ground robot at 1-2 m/s
    tilt = np.degrees(np.abs(s.euler_rad[:, 1:]))
    assert 3.0 < tilt.max() < 15.0                                       # undulating terrain, small angles
    assert np.ptp(s.position_m[:, 2]) > 0.3


def test_velocity_is_the_position_derivative(scenario):
    s = scenario
    dt = s.dt_s
    central = (s.position_m[2:] - s.position_m[:-2]) / (2 * dt)
    assert np.abs(central - s.velocity_m_s[1:-1]).max() < 1e-3
    accel = (s.velocity_m_s[2:] - s.velocity_m_s[:-2]) / (2 * dt)
    assert np.abs(accel - s.acceleration_m_s2[1:-1]).max() < 1e-3


def test_body_rate_is_the_attitude_derivative(scenario):
    s = scenario
    dq = rot.multiply(rot.conjugate(s.quaternion[:-1]), s.quaternion[1:])   # body-frame increments
    dq = rot.normalize(dq)
    angle = 2 * np.arctan2(np.linalg.norm(dq[:, 1:], axis=1), dq[:, 0])
    axis = dq[:, 1:] / np.maximum(np.linalg.norm(dq[:, 1:], axis=1, keepdims=True), 1e-300)
    rate_fd = axis * (angle / s.dt_s)[:, None]
    mid = 0.5 * (s.body_rate_rad_s[1:] + s.body_rate_rad_s[:-1])
    assert np.abs(rate_fd - mid).max() < 1e-4


def test_specific_force_and_readings(scenario):
    s = scenario
    R = rot.to_matrix(s.quaternion)
    force = np.einsum("kji,kj->ki", R, s.acceleration_m_s2 - GRAVITY_ENU)
    np.testing.assert_allclose(force, s.specific_force_m_s2, atol=1e-9)
    # the IMU reads the interval means plus small errors
    mid_force = 0.5 * (s.specific_force_m_s2[1:] + s.specific_force_m_s2[:-1])
    assert np.abs(s.accel_m_s2 - mid_force).mean() < 0.1
    mid_rate = 0.5 * (s.body_rate_rad_s[1:] + s.body_rate_rad_s[:-1])
    assert np.abs(s.gyro_rad_s - mid_rate).mean() < np.radians(0.3)
    assert np.abs(s.odometry_speed_m_s - s.speed_m_s[1:]).mean() < 0.1


def test_gps_outage_rows_and_satellites(scenario):
    s = scenario
    t = s.reading_t_s
    fix = np.isfinite(s.gps_enu_m).all(axis=1)
    assert np.array_equal(fix, np.isfinite(s.gps_velocity_enu_m_s).all(axis=1))
    assert np.isnan(s.gps_enu_m[~fix]).all()
    outage = (t >= 100.0) & (t < 150.0)
    assert not fix[outage].any()
    assert (s.n_satellites[outage] < 4).all() and (s.n_satellites[~outage] >= 4).all()
    # 1 Hz fixes outside the outage
    np.testing.assert_allclose(t[fix], np.round(t[fix]), atol=1e-9)
    assert fix.sum() == 240 - 50
    err = s.gps_enu_m[fix] - s.position_m[1:][fix]
    assert 1.5 < err.std() < 3.5


def test_seeded_and_validated():
    a = ground_robot_scenario(3, duration_s=20.0)
    b = ground_robot_scenario(3, duration_s=20.0)
    c = ground_robot_scenario(4, duration_s=20.0)
    assert np.array_equal(a.gyro_rad_s, b.gyro_rad_s) and np.array_equal(a.gps_enu_m, b.gps_enu_m, equal_nan=True)
    assert not np.array_equal(a.gyro_rad_s, c.gyro_rad_s)
    with pytest.raises(InputError, match="imu_rate_hz"):
        ground_robot_scenario(imu_rate_hz=0.0)
    with pytest.raises(InputError, match="gps_rate_hz"):
        ground_robot_scenario(duration_s=10.0, gps_rate_hz=3.0)
    with pytest.raises(InputError, match="outages"):
        ground_robot_scenario(duration_s=10.0, outages=((5.0, 2.0),))
