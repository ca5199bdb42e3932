"""The position filter of Vasconcelos et al. (cfdesign.nav.position) on simulated 3-D flights with the true attitude."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.errors import InputError, TableMismatchError
from cfdesign.nav.position import PositionFilter, design_position, earth_acceleration, position_spec
from cfdesign.sim import helicopter as heli

RATE = 50
#: a 3-D path with a constant attitude after a smooth start: speeds up East and climbs
CLIMB = heli.Manoeuvre(straight_s=10.0, start_speed_m_s=0.0, speed_m_s=4.0, accel_s=8.0, helix_s=150.0,
                       turn_rate_rad_s=0.0, climb_m_s=1.0)
ERRORS = replace(heli.TABLE1, accel_bias_axes=(1.0, -1.0, 1.0), gps_noise_std_m=1.0)


@pytest.fixture(scope="module")
def flight():
    truth = heli.helicopter_manoeuvre(CLIMB)
    return truth, heli.simulate_readings(truth, 7, ERRORS)


@pytest.fixture(scope="module")
def pf():
    return PositionFilter(RATE, 1, accel_noise_std=ERRORS.accel_noise_std_m_s2, accel_bias_density=2e-3,
                          gps_noise_std=ERRORS.gps_noise_std_m)


def _run(pf, truth, readings, gps=None):
    n = truth.steps
    gps = readings.gps_enu_m[:n] if gps is None else gps
    est = pf.run(readings.accel_m_s2, truth.quaternion[:n], gps, initial_velocity=truth.velocity_m_s[0])
    return est, np.linalg.norm(est.position - truth.position_m[:n], axis=1)


def test_gains_zero_between_fixes(pf):
    K = np.array(pf.table.K, dtype=float)
    assert K.shape[0] == RATE and pf.fix_phases == [0]
    assert np.all(K[1:] == 0) and np.all(np.abs(K[0]) > 0)


def test_earth_acceleration_removes_gravity():
    truth = heli.helicopter_manoeuvre(CLIMB)
    u = earth_acceleration(truth.mean_specific_force_m_s2, truth.quaternion[:-1])
    mean_acc = 0.5 * (truth.acceleration_m_s2[1:] + truth.acceleration_m_s2[:-1])
    assert np.max(np.abs(u - mean_acc)) < 1e-3


def test_error_bounded_and_bias_converges(pf, flight):
    truth, readings = flight
    est, err = _run(pf, truth, readings)
    gps_err = np.linalg.norm(readings.gps_enu_m - truth.position_m, axis=1)
    assert err.max() < 6.0  # the start: zero bias estimate against 10 mg per axis
    assert err[len(err) // 2:].mean() < 0.5 * np.nanmean(gps_err)  # better than the GPS alone
    bias_enu = rot.rotate(truth.quaternion[-1], ERRORS.accel_bias)  # constant attitude at the end
    assert np.max(np.abs(est.accel_bias[-1000:].mean(axis=0) - bias_enu)) < 2.5 * heli.MG_M_S2
    assert np.all(np.isfinite(est.velocity))


def test_outage_coasts_and_recovers(pf, flight):
    """No fix from 60 s to 120 s: the error grows at most like the residual bias, then recovers in 20 s."""
    truth, readings = flight
    _, normal = _run(pf, truth, readings)
    gps = readings.gps_enu_m[:truth.steps].copy()
    gps[60 * RATE:120 * RATE] = np.nan
    _, err = _run(pf, truth, readings, gps)
    assert np.allclose(err[:60 * RATE], normal[:60 * RATE])
    coast = err[60 * RATE:120 * RATE]
    t = np.arange(len(coast)) / RATE
    assert np.all(coast < err[60 * RATE] + 0.5 * 2 * heli.MG_M_S2 * t**2 + 1.0)  # b t^2/2, residual bias < 2 mg
    assert coast.max() > 1.0  # the outage did cost something ...
    assert err[140 * RATE:].max() < 2 * normal[120 * RATE:].max() + 0.5  # ... and is gone 20 s later


def test_stray_fix_and_shapes_rejected(pf):
    acc, q, gps = np.zeros((100, 3)), np.tile([1.0, 0, 0, 0], (100, 1)), np.full((100, 3), np.nan)
    gps[3] = 0.0
    with pytest.raises(InputError, match="off the GPS schedule"):
        pf.run(acc, q, gps)
    with pytest.raises(InputError, match="quat_nb"):
        pf.run(acc, q[:, :3], gps)


def test_default_gains_are_the_designers(pf):
    """The stored-structure design (no sympy) gives the periodic gains of cfdesign.design bit for bit."""
    from cfdesign.designer import design

    spec = position_spec(RATE, 1, accel_noise_std=ERRORS.accel_noise_std_m_s2, accel_bias_density=2e-3,
                         gps_noise_std=ERRORS.gps_noise_std_m)
    assert all(np.array_equal(a, b) for a, b in zip(pf.table.K, design(spec).K, strict=True))


def test_a_users_table_drives_the_filter(pf, flight):
    truth, readings = flight
    table = design_position(RATE, 1, accel_noise_std=ERRORS.accel_noise_std_m_s2, accel_bias_density=2e-3,
                            gps_noise_std=ERRORS.gps_noise_std_m)
    given = PositionFilter(table=table)                     # rates from the table
    assert given.fix_phases == pf.fix_phases
    n = 20 * RATE
    args = (readings.accel_m_s2[:n], truth.quaternion[:n], readings.gps_enu_m[:n])
    assert np.array_equal(given.run(*args).position, pf.run(*args).position)
    spec = position_spec(RATE, 1, accel_noise_std=ERRORS.accel_noise_std_m_s2, accel_bias_density=2e-3,
                         gps_noise_std=ERRORS.gps_noise_std_m)
    assert np.array_equal(PositionFilter(RATE, 1, table=spec).run(*args).position, pf.run(*args).position)


def test_the_schedule_says_when_fixes_come_and_the_runtime_gives_the_posterior(pf, flight):
    """fix_phases asks the table's schedule (a scheduled fix whose gain happens to be zero is
    still a fix), and the velocity and bias are the runtime's posterior states: those the
    streaming recursion gives, ``x+[k] = F^-1 (x[k+1] - B u[k])``."""
    from cfdesign.runtime import Runtime

    zero = replace(pf.table, K=[np.zeros_like(K) for K in pf.table.K])
    assert PositionFilter(table=zero).fix_phases == pf.fix_phases == list(pf.table.schedule.phases("gps"))
    truth, readings = flight
    n = 5 * RATE
    acc, q, gps = readings.accel_m_s2[:n], truth.quaternion[:n], readings.gps_enu_m[:n]
    est = pf.run(acc, q, gps)
    u = earth_acceleration(acc, q)[:, 0]
    rt = Runtime(pf.table, x0=[gps[0, 0], 0.0, 0.0], output="posterior")
    after = np.array([(rt.step(accelerometer=a, gps=g), rt.x)[1] for a, g in zip(u, gps[:, 0], strict=True)])
    F, B = pf.table.F, pf.table.B[:, 0]
    post = np.linalg.solve(F, (after - u[:, None] * B).T).T
    assert np.allclose(post, np.column_stack([est.position[:, 0], est.velocity[:, 0], est.accel_bias[:, 0]]),
                       rtol=0, atol=1e-9)


def test_tables_that_do_not_fit_are_rejected():
    table = design_position(RATE, 1, accel_noise_std=0.01, accel_bias_density=1e-3, gps_noise_std=1.0)
    with pytest.raises(TableMismatchError, match="period of 50 step"):
        PositionFilter(RATE, 5, table=table)
    with pytest.raises(TableMismatchError, match=r"sample time 0\.02 s"):
        PositionFilter(100, 2, table=table)
    from cfdesign.nav import design_channel

    with pytest.raises(TableMismatchError, match="2 states"):
        PositionFilter(table=design_channel(RATE, 0.01, 1e-4, 0.01))
    with pytest.raises(InputError, match="not both"):
        PositionFilter(table=table, gps_noise_std=1.0)
    with pytest.raises(InputError, match="accel_bias_density is missing"):
        PositionFilter(RATE, 1, accel_noise_std=0.01, gps_noise_std=1.0)
    with pytest.raises(InputError, match="3 Hz must divide imu_rate_hz 50 Hz"):
        PositionFilter(RATE, 3, accel_noise_std=0.01, accel_bias_density=1e-3, gps_noise_std=1.0)
