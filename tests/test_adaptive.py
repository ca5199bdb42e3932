"""cfdesign.nav.adaptive: the adaptive complementary filter of Alves Neto et al. on the ground-robot scenario."""

import math

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.errors import InputError
from cfdesign.linear import wrap
from cfdesign.nav.adaptive import AdaptiveCF, attitude_cutoffs, cutoff_plot, position_cutoff
from cfdesign.sim.ground import ground_robot_scenario

OUTAGE = (120.0, 180.0)


@pytest.fixture(scope="session")  # once per worker: xdist deals other modules between its tests
def run():
    s = ground_robot_scenario(0, duration_s=300.0, outages=(OUTAGE,))
    cf = AdaptiveCF(50.0)
    est = cf.run(s.gyro_rad_s, s.accel_m_s2, s.mag, s.odometry_speed_m_s, s.gps_enu_m, s.n_satellites)
    return s, est


def _inputs(s):
    return s.gyro_rad_s, s.accel_m_s2, s.mag, s.odometry_speed_m_s, s.gps_enu_m, s.n_satellites


def test_shapes(run):
    s, est = run
    n = s.steps
    assert est.quaternion.shape == (n, 4) and est.euler.shape == (n, 3) and est.position.shape == (n, 3)
    assert est.cutoff_attitude.shape == (n, 3) and est.cutoff_position.shape == (n,)
    np.testing.assert_allclose(rot.to_euler(est.quaternion), est.euler, atol=1e-9)


def test_attitude_error_bounded(run):
    """Bound: every angle within 1.5° at all times, RMS within 0.8° (gyro bias 0.1 °/s, accel bias 5 mg)."""
    s, est = run
    err = np.degrees(wrap(est.euler - s.euler_rad[1:]))
    assert np.abs(err).max() < 1.5
    assert (np.sqrt((err**2).mean(axis=0)) < 0.8).all()


def test_paper_rate_10_hz(run):
    """The paper samples at 10 Hz: every 5th row (gyro averaged over the 0.1-s interval), same bounds."""
    s, _ = run
    gyr = s.gyro_rad_s.reshape(-1, 5, 3).mean(axis=1)
    rows = slice(4, None, 5)
    est = AdaptiveCF(10.0).run(gyr, s.accel_m_s2[rows], s.mag[rows], s.odometry_speed_m_s[rows],
                               s.gps_enu_m[rows], s.n_satellites[rows])
    err = np.degrees(wrap(est.euler - s.euler_rad[1:][rows]))
    assert np.abs(err).max() < 1.5
    t = s.reading_t_s[rows]
    pos = np.linalg.norm(est.position - s.position_m[1:][rows], axis=1)
    assert np.sqrt(np.mean(pos[t > 40.0] ** 2)) < 2.0


def test_position_error_with_gps_and_through_the_outage(run):
    s, est = run
    t = s.reading_t_s
    err = np.linalg.norm(est.position - s.position_m[1:], axis=1)
    assert np.isnan(est.position[t < 1.0 - 1e-9]).all()                 # starts at the first fix
    settled = (t > 40.0) & (t < OUTAGE[0])
    assert np.sqrt(np.mean(err[settled] ** 2)) < 2.0                     # GPS alone: 4.3 m RMS (3-D)
    gps = np.linalg.norm(s.gps_enu_m - s.position_m[1:], axis=1)
    assert np.sqrt(np.mean(err[settled] ** 2)) < 0.6 * np.sqrt(np.nanmean(gps[settled] ** 2))
    outage = (t >= OUTAGE[0]) & (t < OUTAGE[1])
    start = err[np.argmax(outage)]
    assert (err[outage] - start).max() < 2.0                             # dead-reckoning growth in 60 s
    after = t > OUTAGE[1] + 40.0
    assert np.sqrt(np.mean(err[after] ** 2)) < 1.5                       # recovered


def test_position_cutoff_follows_eqs_22_to_24(run):
    s, est = run
    low = s.n_satellites <= 3
    assert low.any() and (est.cutoff_position[low] == 0.0).all()
    assert (est.cutoff_position[~low] > 0).all()
    k_p, v_max, n_max = 0.05, 2.0, 12.0
    v, n = 1.0, 8
    expected = min(k_p * (1 - math.exp(-v / (v_max - v))), k_p * (1 - math.exp(-n / (n_max - n))))
    assert position_cutoff([v], [n], k_p, v_max, n_max)[0] == pytest.approx(expected)
    np.testing.assert_allclose(position_cutoff([0.0, 3.0, 1.0, 1.0], [10, 10, 3, 20], k_p, v_max, n_max),
                               [0.0, min(k_p, k_p * (1 - math.exp(-10 / 2))), 0.0, k_p * (1 - math.exp(-1.0))])


def test_attitude_cutoff_drops_when_acceleration_departs_from_g(run):
    s, est = run
    acc = np.array([[0.0, 0.0, 9.80665], [0.0, 0.0, 11.80665], [1.5, 0.0, 9.0]])
    cut = attitude_cutoffs(acc, 0.5, 0.4)
    np.testing.assert_allclose(cut[0], [0.5, 0.4])
    np.testing.assert_allclose(cut[1], [0.5 * math.exp(-2.0), 0.4 * math.exp(-2.0)])
    assert (cut[2] < cut[0]).all()
    # in the run: eqs. (15)-(17) hold row by row
    dev = np.abs(9.80665 - np.linalg.norm(s.accel_m_s2, axis=1))
    np.testing.assert_allclose(est.cutoff_attitude[:, 0], 0.5 * np.exp(-dev))
    tilt = np.maximum(np.abs(est.euler[:-1, 1]), np.abs(est.euler[:-1, 2]))
    np.testing.assert_allclose(est.cutoff_attitude[1:, 2], 0.3 * np.exp(-tilt))


def test_heading_is_wrap_safe():
    """A robot standing still facing west (yaw ±π): the noisy compass flips sign, the estimate must not jump."""
    n, rate = 2000, 50.0
    rng = np.random.default_rng(1)
    truth = np.array([math.pi, 0.0, 0.0])
    q = rot.from_euler(truth)
    acc = rot.rotate(rot.conjugate(q), [0.0, 0.0, 9.80665]) + 0.02 * rng.normal(size=(n, 3))
    mag = rot.rotate(rot.conjugate(q), [0.0, 0.5, 0.0]) + 0.01 * rng.normal(size=(n, 3))
    gyr = np.radians(0.05) + np.radians(0.1) * rng.normal(size=(n, 3))
    est = AdaptiveCF(rate).run(gyr, acc, mag, np.zeros(n), np.full((n, 3), np.nan), np.zeros(n, dtype=int))
    err = wrap(est.euler[:, 0] - math.pi)
    assert np.abs(err).max() < np.radians(3.0)
    assert np.abs(est.euler[:, 0]).min() > 3.0                           # near ±π throughout, never near 0
    # turning in place through ±π: tracks the gyro and the compass
    yaw = np.linspace(2.5, 4.0, n)
    q = rot.from_euler(np.column_stack([yaw, np.zeros(n), np.zeros(n)]))
    acc = rot.rotate(rot.conjugate(q), [0.0, 0.0, 9.80665])
    mag = rot.rotate(rot.conjugate(q), np.array([0.0, 0.5, 0.0]))
    gyr = np.zeros((n, 3))
    gyr[:, 2] = (yaw[1] - yaw[0]) * rate
    est = AdaptiveCF(rate).run(gyr, acc, mag, np.zeros(n), np.full((n, 3), np.nan), np.zeros(n, dtype=int))
    assert np.abs(wrap(est.euler[:, 0] - yaw)).max() < 1e-6


def test_position_dead_reckoning_and_fix_handling():
    """Level, east at 1 m/s with no satellites: pure dead reckoning from the initial position."""
    n, rate = 500, 10.0
    acc = np.tile([0.0, 0.0, 9.80665], (n, 1))
    mag = np.tile([0.0, 0.5, 0.0], (n, 1))          # north on the body's left: facing east
    gps = np.full((n, 3), 100.0)                    # wrong fixes, ignored with 3 satellites
    est = AdaptiveCF(rate).run(np.zeros((n, 3)), acc, mag, np.ones(n), gps, np.full(n, 3),
                               initial_position=[1.0, 2.0, 3.0])
    np.testing.assert_allclose(est.euler[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(est.position[:, 0], 1.0 + np.arange(n) / rate, atol=1e-9)
    np.testing.assert_allclose(est.position[:, 1:], [[2.0, 3.0]] * n, atol=1e-9)
    # with satellites the fixes pull the estimate with the accumulated factor exp(-Σ ω_c T)
    est = AdaptiveCF(rate).run(np.zeros((n, 3)), acc, mag, np.zeros(n) + 1.0, gps, np.full(n, 12),
                               initial_position=[0.0, 0.0, 0.0])
    w = position_cutoff([1.0], [12], 0.05, 2.0, 12.0)[0]
    assert est.position[0, 1] == pytest.approx((1 - math.exp(-w / rate)) * 100.0)


@pytest.mark.parametrize(("kwargs", "name"), [({"rate_hz": 0.0}, "rate_hz"), ({"rate_hz": -1.0}, "rate_hz"),
                                               ({"rate_hz": 10.0, "k_p": -1.0}, "k_p"),
                                               ({"rate_hz": 10.0, "n_max": 3.0}, "n_max")])
def test_bad_parameters(kwargs, name):
    with pytest.raises(InputError, match=name):
        AdaptiveCF(**kwargs)


def test_bad_shapes():
    n = 10
    good = [np.zeros((n, 3)), np.tile([0, 0, 9.8], (n, 1)), np.tile([0, 0.5, 0], (n, 1)), np.zeros(n),
            np.full((n, 3), np.nan), np.zeros(n)]
    names = ["gyr", "acc", "mag", "odometry_speed", "gps_enu", "n_satellites"]
    cf = AdaptiveCF(10.0)
    for i, name in enumerate(names):
        args = list(good)
        args[i] = np.zeros((n, 2)) if good[i].ndim == 2 else np.zeros((n, 3))
        with pytest.raises(InputError, match=name):
            cf.run(*args)
    args = list(good)
    args[3] = np.zeros(n + 1)
    with pytest.raises(InputError, match="odometry_speed"):
        cf.run(*args)


def test_cutoff_plot(run):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    s, est = run
    ax = cutoff_plot(est, s.reading_t_s)
    assert len(ax.lines) == 4
    np.testing.assert_allclose(ax.lines[3].get_ydata(), est.cutoff_position)
    with pytest.raises(InputError, match="t_s"):
        cutoff_plot(est, s.reading_t_s[:-1])
    import matplotlib.pyplot as plt

    plt.close(ax.figure)
