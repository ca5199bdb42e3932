"""A continuous gain table discretised for a rate (cfdesign.discretize), against re-designing at it."""

from dataclasses import replace

import numpy as np
import pytest

from cfdesign.designer import design
from cfdesign.discretize import discretize_table
from cfdesign.errors import GainTableError
from cfdesign.gains import load_gains
from cfdesign.runtime import Runtime
from cfdesign.spec import parse_spec
from cfdesign.verify import verify_table


def spec(discrete=False, rate=100.0):
    return parse_spec({"structure": "cf2", "order": 2, "discrete": discrete, "sensors": {
        "rate": {"rate_hz": rate, "noise": {"density": 1.7e-3}, "bias": {"model": "random_walk", "density": 2e-4}},
        "angle": {"rate_hz": rate, "noise": {"density": 0.01}}}})


@pytest.fixture(scope="module")
def continuous():
    return design(spec())


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_discretised_table_verifies_and_runs(continuous, form):
    table = discretize_table(continuous, 200.0, form)
    assert table.domain == "z" and table.sample_time_s == 1 / 200 and table.gain_form == form
    assert all(c.ok for c in verify_table(table))
    poles = np.linalg.eigvals(continuous.F - continuous.K[0] @ continuous.H)
    got = sorted(np.log([complex(*p) for p in table.checks["poles"]]) * 200, key=lambda c: c.imag)
    assert np.allclose(got, sorted(poles, key=lambda c: c.imag), rtol=0.02)  # e^{lambda T} + O(T^2)
    est = Runtime(table).run({"rate": np.full(400, 0.1), "angle": 0.1 * np.arange(400) / 200})
    assert est[-1] == pytest.approx(0.1 * 399 / 200, abs=1e-3)


def test_discretising_approaches_redesigning_as_the_rate_grows(continuous):
    gaps = []
    for rate in (20.0, 200.0, 2000.0):
        mine = discretize_table(continuous, rate, "predictor")
        fresh = design(replace(spec(True, rate)))
        gaps.append(np.abs(mine.K[0] - fresh.K[0]).max() / np.abs(fresh.K[0]).max())
        assert fresh.predicted_std <= mine.predicted_std * (1 + 1e-9)  # the DARE gain is optimal at that rate
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 0.01


def test_cli_discretize(cli, continuous, tmp_path):
    continuous.save(tmp_path / "c.json")
    code, out, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 200, "-o", tmp_path / "d.json")
    assert code == 0, err
    # no exact proof is run on a discretised table: the summary says how it is known
    assert "complementary (structural, checked numerically): True" in out and "exact proof" not in out
    assert "gains: \n" not in out and "K = [[" in out
    assert load_gains(tmp_path / "d.json").sample_time_s == pytest.approx(0.005)
    code, _, err = cli("discretize", tmp_path / "d.json", "--rate-hz", 200, "-o", tmp_path / "e.json")
    assert code == 2 and "already discrete" in err
    with pytest.raises(GainTableError, match="do not stabilise"):
        discretize_table(continuous, 0.01)


def test_cli_discretize_at_another_rate_than_the_sensors_says_what_its_prediction_assumes(cli, continuous, tmp_path):
    """At a rate other than the sensors' own, ``R = PSD x rate`` is the noise of a reading averaged
    over each step, not of the sensor's readings: a 100 Hz compass (std 0.02) read every second
    sample by a table discretised at 50 Hz has 1.86 times the predicted error variance (the test
    below), silently.
    The note says so, naming both rates; at the sensors' own rate there is none."""
    continuous.save(tmp_path / "c.json")
    code, _, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 100, "-o", tmp_path / "d.json")
    assert code == 0 and err == ""
    code, _, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 50, "-o", tmp_path / "d.json")
    assert code == 0 and len(err.strip().splitlines()) == 1
    assert "described at 100 Hz" in err and "at 50 Hz" in err and "PSD x 50" in err and "rate_hz = 50" in err


def test_readings_as_they_come_at_half_their_rate_have_about_1_8_times_the_predicted_variance(continuous):
    """The figure docs/guide/noise-and-crossover.md gives: a 100 Hz gyro and compass read every
    second sample by the table discretised at 50 Hz: the covariance of the same gains under the
    readings' own noise (each white noise's density doubled: a reading's variance is PSD x 100,
    the prediction's PSD x 50) is 1.86 times the predicted variance of the angle, and the runtime
    on 200,000 simulated steps agrees within 10 %."""
    from cfdesign.designer import _covariances
    from cfdesign.discretize import van_loan

    table = discretize_table(continuous, 50.0)
    Q = np.array(continuous.Q)
    Q[0, 0] *= 2                                                    # the gyro's white noise; not its bias walk
    P_filtered = _covariances(table.F, table.H, table.K[0], van_loan(continuous.F, Q, 0.02)[1],
                              2 * np.array(table.R), table.gain_form)[1]
    predicted = table.P_filtered[0][0, 0]
    rng, n, dt = np.random.default_rng(0), 400_000, 0.01          # 100 Hz truth and readings
    t = np.arange(n) * dt
    rate = 0.2 * np.sin(0.3 * t)
    angle = np.concatenate([[0.0], np.cumsum(rate[:-1]) * dt])
    gyro = rate + np.cumsum(2e-4 * np.sqrt(dt) * rng.standard_normal(n)) + 1.7e-3 * 10 * rng.standard_normal(n)
    compass = angle + 0.01 * 10 * rng.standard_normal(n)
    err = Runtime(table).run({"rate": gyro[::2], "angle": compass[::2]})[5000:] - angle[::2][5000:]
    assert round(P_filtered[0, 0] / predicted, 2) == 1.86
    assert np.mean(err**2) / predicted == pytest.approx(P_filtered[0, 0] / predicted, rel=0.1)


def test_discretised_table_keeps_the_state_names(continuous):
    """The estimates of a discretised table are named as the design named them (not x0, x1)."""
    assert continuous.states == ("angle", "rate_correction")
    assert discretize_table(continuous, 100.0).states == continuous.states


def test_a_multirate_continuous_table_is_refused_with_its_slow_sensor_named():
    """A 10 Hz position beside 100 Hz sensors: the discretised table would read it at every step."""
    table = design(parse_spec({"structure": "cf3", "sensors": {
        "acceleration": {"rate_hz": 100.0, "noise": {"density": 0.003}},
        "velocity": {"rate_hz": 100.0, "noise": {"std": 0.01}},
        "position": {"rate_hz": 10.0, "noise": {"std": 0.05}}}, "gains": {"k1": 12.566, "k2": 15.791}}))
    with pytest.raises(GainTableError, match=r"position runs at 10 Hz.*discrete = true"):
        discretize_table(table, 100.0)


def test_the_built_in_tilt_example_discretises_and_verifies(tmp_path, cli):
    """The example the docs point ``cfdesign discretize`` at: continuous, every sensor at 200 Hz."""
    code, _, err = cli("design", "--example", "tilt", "-o", tmp_path / "c.json")
    assert code == 0, err
    code, out, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 200, "-o", tmp_path / "d.json")
    assert code == 0 and "K = [[" in out, err
    assert all(c.ok for c in verify_table(load_gains(tmp_path / "d.json")))


def test_numpy_scalar_rates_are_rates(continuous):
    """np.int64(200) or np.float32(200) (a rate read from an array) was refused as 'not a positive
    number of hertz'; a numpy bool still is."""
    expected = discretize_table(continuous, 200.0)
    for rate in (np.int64(200), np.float32(200.0)):
        table = discretize_table(continuous, rate)
        assert table.sample_time_s == expected.sample_time_s and type(table.sample_time_s) is float
        np.testing.assert_array_equal(table.K[0], expected.K[0])
    with pytest.raises(GainTableError, match="positive number of hertz"):
        discretize_table(continuous, np.bool_(True))
