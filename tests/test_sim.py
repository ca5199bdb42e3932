"""cfdesign.sim: trajectories, sensor models, role conversions, metrics, seed 001's scenario."""

import math

import numpy as np
import pytest
from scipy import stats

from cfdesign.errors import InputError, SpecError
from cfdesign.linear import wrap
from cfdesign.noise import Bias, WhiteNoise, van_loan
from cfdesign.sim import (
    HeadingSensor,
    MagneticPerturbation,
    RateSensor,
    Segment,
    difference_heading,
    differenced_noise,
    from_segments,
    heading_error,
    integrate_rate,
    integrated_noise,
    mean_ci,
    mse,
    rounded_square,
    simulate,
    smooth_turn,
)
from cfdesign.sim import robot_heading as s001

DT = 0.2


def straight(seconds=2000.0):
    """A robot standing on one heading: every reading is its error alone."""
    return from_segments([Segment(seconds - 1.0, 0.0, 1.0)], dt_s=DT, start_heading_rad=0.3)


# ---------------------------------------------------------------------- trajectories
def test_rounded_square_matches_seed001_and_closes():
    traj = rounded_square(start_heading_rad=0.0)
    assert traj.steps == 12200 and traj.duration_s == pytest.approx(2440.0) and traj.dt_s == pytest.approx(DT)
    assert traj.heading_rad[-1] == pytest.approx(2 * np.pi)
    assert traj.heading_rad[3000] == pytest.approx(0.0) and traj.heading_rad[3050] == pytest.approx(np.pi / 2)
    assert np.allclose(traj.position_m()[-1], 0.0, atol=1e-9)  # four equal legs, 90 deg apart
    assert traj.position_m()[3000, 0] == pytest.approx(60.0)  # 600 s at 0.1 m/s
    assert np.sum(traj.rate_rad_s) * DT == pytest.approx(2 * np.pi)


def test_turns_are_smooth_and_can_go_right():
    s = np.linspace(0, 1, 1001)
    rate = np.gradient(smooth_turn(s), s)
    assert smooth_turn(0.0) == 0 and smooth_turn(1.0) == 1 and smooth_turn(-1) == 0 and smooth_turn(2) == 1
    assert rate[0] == pytest.approx(0, abs=1e-5) and rate[-1] == pytest.approx(0, abs=1e-5)
    assert rate.max() == pytest.approx(2.0, rel=1e-4)  # peak rate twice the mean
    right = rounded_square(legs=1, straight_s=10.0, left=False)
    assert right.heading_rad[-1] == pytest.approx(-np.pi / 2)


def test_trajectory_duration_must_be_whole_samples():
    with pytest.raises(InputError, match="whole number"):
        from_segments([Segment(1.05, 0.1, 1.0)], dt_s=DT)
    with pytest.raises(InputError, match="segment"):
        from_segments([], dt_s=DT)


# ---------------------------------------------------------------------- sensors
def test_noise_free_sensors_read_the_truth():
    traj = rounded_square(start_heading_rad=np.radians(135), straight_s=20.0)
    out = simulate(traj, {"gyro": RateSensor(), "compass": HeadingSensor()}, seed=0)
    assert out["gyro"].shape == (traj.steps,) and out["compass"].shape == (traj.steps + 1,)
    assert np.allclose(out["gyro"], traj.rate_rad_s)
    assert np.allclose(out["compass"], traj.wrapped_heading_rad)
    assert out["compass"].max() <= np.pi and out["compass"].min() > -np.pi


def test_white_noise_has_the_stated_std_for_std_and_density():
    traj = straight()
    for noise, std in ((WhiteNoise(std=0.01), 0.01), (WhiteNoise(density=0.01), 0.01 * math.sqrt(5.0))):
        r = simulate(traj, {"g": RateSensor(noise=noise), "c": HeadingSensor(noise=noise)}, seed=1)
        assert np.std(r["g"]) == pytest.approx(std, rel=0.03)
        assert np.std(r["c"] - 0.3) == pytest.approx(std, rel=0.03)


def test_constant_bias_offset_drift_and_perturbation():
    traj = rounded_square(straight_s=20.0)
    pert = MagneticPerturbation(np.radians(20))
    r = simulate(traj, {"g": RateSensor(bias=Bias("constant", value=0.01)),
                        "c": HeadingSensor(bias=Bias("constant", value=0.05), perturbation=pert),
                        "o": HeadingSensor(drift_rad_s=0.002)}, seed=0)
    assert np.allclose(r["g"] - traj.rate_rad_s, 0.01)
    assert np.allclose(wrap(r["c"] - traj.heading_rad), 0.05 + np.radians(20) * np.sin(traj.heading_rad))
    assert np.allclose(wrap(r["o"] - traj.heading_rad), 0.002 * traj.t_s)
    assert MagneticPerturbation(1.0, harmonic=2, phase_rad=np.pi / 2)(0.0) == pytest.approx(1.0)


def test_random_walk_bias_is_sampled_exactly_as_van_loan():
    """The bias and its integral over each interval have the covariance the designer's Q assumes."""
    from cfdesign.sim.sensors import _bias_path

    q = 1e-3**2
    at, mean = _bias_path(Bias("random_walk", density=1e-3, value=0.2), 200_000, DT, np.random.default_rng(0))
    assert at[0] == 0.2
    w = np.column_stack([DT * (mean - at[:-1]), np.diff(at)])  # angle and bias increments over each interval
    Q = van_loan([[0.0, 1.0], [0.0, 0.0]], np.diag([0.0, q]), DT)[1]  # x = [angle, bias], angle' = bias
    assert np.allclose(np.cov(w.T), Q, rtol=0.02)


def test_slow_sensors_dropouts_and_bad_rates():
    traj = straight(100.0)
    r = simulate(traj, {"g": RateSensor(rate_hz=1.0), "c": HeadingSensor(rate_hz=2.5),
                        "d": HeadingSensor(dropout=0.3)}, seed=0)
    assert np.all(~np.isnan(r["g"][::5])) and np.all(np.isnan(r["g"][1::5]))
    assert np.allclose(r["g"][::5], 0.0) and np.all(np.isnan(r["c"][1::2])) and np.allclose(r["c"][::2], 0.3)
    assert np.mean(np.isnan(r["d"])) == pytest.approx(0.3, abs=0.05)
    with pytest.raises(InputError, match="sensor c: rate_hz: 3 Hz"):
        simulate(traj, {"c": HeadingSensor(rate_hz=3.0)}, seed=0)
    with pytest.raises(InputError, match="dropout"):
        simulate(traj, {"c": HeadingSensor(dropout=1.0)}, seed=0)


def test_simulation_is_seeded_per_sensor():
    traj = straight(50.0)
    noisy = HeadingSensor(noise=WhiteNoise(std=0.1))
    a = simulate(traj, {"c": noisy, "o": noisy}, seed=7)
    b = simulate(traj, {"c": noisy}, seed=7)
    c = simulate(traj, {"c": noisy}, seed=8)
    assert np.array_equal(a["c"], b["c"]) and not np.array_equal(a["c"], a["o"])
    assert not np.array_equal(a["c"], c["c"])


# ---------------------------------------------------------------------- a sensor in the other role
def test_difference_and_integrate_are_inverse_across_the_wrap():
    traj = rounded_square(start_heading_rad=np.radians(135), straight_s=20.0)
    rate = difference_heading(traj.wrapped_heading_rad, DT)
    assert np.allclose(rate, traj.rate_rad_s)  # no 2 pi jump where the heading crosses +-180 deg
    assert np.allclose(integrate_rate(rate, DT, traj.heading_rad[0]), traj.wrapped_heading_rad)
    held = integrate_rate([0.1, np.nan, np.nan, 0.2], 1.0, 0.0)  # a missing rate holds the last one
    assert np.allclose(held, [0, 0.1, 0.2, 0.3, 0.5])
    assert np.allclose(integrate_rate([np.nan, 0.1], 1.0, 3.1), wrap([3.1, 3.1, 3.2]))


def test_role_noise_stand_ins():
    n = WhiteNoise(std=0.01)
    assert differenced_noise(n, 5.0).std == pytest.approx(math.sqrt(2) * 0.01 * 5.0)
    assert integrated_noise(n, 5.0).std == pytest.approx(0.01 / 5.0)


# ---------------------------------------------------------------------- metrics
def test_heading_error_counts_whole_turns():
    truth = np.linspace(0, 30, 3001)
    est = wrap(truth * 1.5)  # drifts by 15 rad: wrapped, but the error keeps growing
    e = heading_error(est, truth)
    assert e[-1] == pytest.approx(15.0) and mse(est, truth) == pytest.approx(np.mean((0.5 * truth) ** 2))


def test_mean_ci_is_the_student_t_interval():
    values = [1.0, 2.0, 4.0, 7.0]
    m, lo, hi = mean_ci(values)
    half = stats.t.ppf(0.975, 3) * np.std(values, ddof=1) / 2
    assert (m, lo, hi) == pytest.approx((3.5, 3.5 - half, 3.5 + half))
    m, lo, hi = mean_ci([2.0])
    assert m == 2.0 and math.isnan(lo) and math.isnan(hi)


# ---------------------------------------------------------------------- seed 001
def test_seed001_reading_is_stated_once():
    assert s001.READING.name == "std" and s001.READING.std("gyro") == 2e-3 and s001.READING.std("odometry") == 4e-6
    assert s001.READINGS["variance"].std("compass") == pytest.approx(math.sqrt(2e-3))
    assert "standard deviation" in s001.READING.describe()
    with pytest.raises(SpecError, match="reading"):
        s001.Reading("sigma")


def test_seed001_scenario_crosses_the_wrap_and_has_the_papers_errors():
    sc = s001.scenario()
    traj = sc.trajectory
    assert traj.duration_s == pytest.approx(2440.0) and np.any(np.abs(np.diff(traj.wrapped_heading_rad)) > np.pi)
    assert sc.gyro_compensation_rad_s == pytest.approx(np.radians(0.8))
    assert sc.sensors["odometry"].drift_rad_s == pytest.approx(np.radians(0.5))
    assert sc.sensors["compass"].perturbation.amplitude_rad == pytest.approx(np.radians(20))
    sig = sc.signals(0)
    assert np.std(sig["gyro"]["rate"] - traj.rate_rad_s) == pytest.approx(2e-3, rel=0.05)  # bias compensated
    assert sig["odometry"]["rate"].mean() - traj.rate_rad_s.mean() == pytest.approx(np.radians(0.5), rel=1e-3)
    assert sc.noise("odometry", "rate").std == pytest.approx(math.sqrt(2) * 4e-6 * 5)
    assert sc.noise("gyro", "heading").std == pytest.approx(2e-3 * DT) and sc.noise("gyro", "rate").std == 2e-3


def test_seed001_linear_gaussian_version_keeps_only_white_noise_and_the_bias_walk():
    sc = s001.scenario(linear_gaussian=True, straight_s=20.0)
    assert sc.gyro_compensation_rad_s == 0 and sc.sensors["gyro"].bias.model == "random_walk"
    assert sc.sensors["gyro"].bias.density == s001.READING.rate_bias_density
    assert sc.sensors["compass"].perturbation is None and sc.sensors["odometry"].drift_rad_s == 0


def test_sinusoid_readings_give_every_sensor_the_derivative_of_its_order():
    """cfn with 4 bands has a jerk input (order 3): the readings raised IndexError for it."""
    from types import SimpleNamespace

    from cfdesign.sim.signals import sinusoid_readings

    # what the function reads of a table (a 4-band cfn's ports): designing one takes seconds
    table = SimpleNamespace(wrap_angle=False, sample_time_s=0.5,
                            sensors=[SimpleNamespace(name=name, order=order) for name, order in
                                     (("jerk", 3), ("acceleration", 2), ("velocity", 1), ("position", 0))])
    data = sinusoid_readings(table, 4000)
    w = 2 * np.pi / 100.0
    t = np.arange(4000) * 0.5
    for name, truth in (("jerk", -50.0 * w**3 * np.cos(w * t)), ("position", 50.0 * np.sin(w * t))):
        assert np.std(data[name] - truth) == pytest.approx(0.05, rel=0.1)
