"""The filter's start-up: its length from the table (the slowest error mode's decay), and the
figures of a log run that tell the start-up from the settled filter (RMS over every row, after the
start-up, the predicted std; the start-up shaded on the plot; the fleet's summary)."""

import math
import re

import numpy as np
import pandas as pd
import pytest

import cfdesign
from cfdesign.linear import closed_loop, gain_pair, startup_steps, wrap
from cfdesign.logs import LogResult, plot_log, run_log
from cfdesign.runtime import Runtime
from cfdesign.sim.gaussian import model_log
from cfdesign.spec import parse_spec

#: a gyro + compass filter with slow gains (0.1 Hz crossover, 100 Hz): a start-up of 16 s
SLOW = {"name": "slow cf2", "structure": "cf2", "order": 2, "discrete": True, "wrap_angle": True,
        "crossover": {"hz": 0.1}, "sensors": {
            "gyro": {"port": "rate", "measures": "rate", "rate_hz": 100.0, "noise": {"density": 0.002},
                     "bias": {"model": "random_walk", "density": 5e-5}},
            "compass": {"port": "angle", "measures": "angle", "rate_hz": 100.0, "noise": {"std": 0.02}}}}
#: the hand-typed DCKF3 of tests/test_output.py (5 Hz): closed-loop poles 0.512 and 0.988, both real
HAND = {"name": "hand-typed dckf3", "structure": "dckf3", "wrap_angle": True, "gains": {
    "k11": 0.3, "k12": 0.2, "k21": 0.01, "k22": 0.02}, "sensors": {
    "gyro": {"rate_hz": 5.0, "noise": {"std": 0.0447}, "bias": {"model": "random_walk", "density": 1e-4}},
    "compass": {"rate_hz": 5.0, "noise": {"std": 0.0447}},
    "odometry": {"rate_hz": 5.0, "noise": {"std": 0.002}}}}
#: the multirate heading table of tests/test_logs.py (period 100): monodromy multipliers 0.536 and 0.904
HEADING = {"name": "heading 100/10/1 Hz", "structure": "dckf3", "wrap_angle": True, "sensors": {
    "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
    "odometry": {"rate_hz": 10.0, "noise": {"std": 0.005}},
    "compass": {"rate_hz": 1.0, "noise": {"std": 0.05}}}}
N = 20_000


@pytest.fixture(scope="module")
def slow():
    return cfdesign.design(parse_spec(SLOW))


@pytest.fixture(scope="module")
def biased_log(slow):
    """``N`` steps of the slow table's own model whose gyro starts 0.1 rad/s off (the filter
    starts its correction at zero): the truth, plus the noise-free motion of that initial state."""
    x, readings = model_log(slow, N, seed=5)
    e, offset = np.array([0.0, 0.1]), np.empty((N, 2))
    for k in range(N):
        offset[k], e = e, slow.F @ e
    x = x + offset
    readings["compass"] = readings["compass"] + offset @ slow.H[slow.sensor("compass").index]
    return pd.DataFrame({"time": np.arange(N) * slow.sample_time_s, **readings, "truth": x[:, 0]})


def _first_below(errors, decay=100.0) -> int:
    """The first index where the norm of ``errors`` has shrunk ``decay`` times from the first."""
    norms = np.linalg.norm(errors, axis=1)
    return int(np.flatnonzero(norms <= norms[0] / decay)[0])


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
@pytest.mark.parametrize("spec", [HAND, HEADING], ids=["single-rate", "multirate"])
def test_startup_steps_is_when_a_noise_free_transient_has_shrunk_a_hundred_times(spec):
    """The filter run on noise-free readings of a zero truth from an initial error along its
    slowest mode (the closed loop's eigenvector; a multirate table's monodromy eigenvector at
    phase 0): the error at the table's output has shrunk 100 times after startup_steps steps
    (the multirate table's error is looked at once a period, where the mode is exactly
    multiplied by the monodromy multiplier)."""
    table = cfdesign.design(parse_spec(spec))
    n, p = len(table.F), table.period
    monodromy = np.eye(n)
    for K in table.K:
        monodromy = closed_loop(table.F, table.H, K, table.gain_form) @ monodromy
    values, vectors = np.linalg.eig(monodromy)
    slowest = vectors[:, np.argmax(np.abs(values))]
    assert np.isreal(slowest).all()
    rt = Runtime(table)
    rt.x = np.real(slowest) * 0.1
    steps = startup_steps(table.F, table.H, table.K, table.gain_form)
    length = int(2 * steps) + p
    _, errors = rt.run({s.name: np.zeros(length) for s in table.sensors}, states=True)
    found = _first_below(errors[::p]) * p
    assert found == math.ceil(steps / p) * p, (found, steps)
    if p == 1:
        assert steps == pytest.approx(math.log(100) / -math.log(0.98769729), rel=1e-6)  # the slow pole's
    else:
        assert steps == pytest.approx(p * math.log(100) / -math.log(0.90365536), rel=1e-6)  # per period


def test_startup_steps_at_its_limits():
    """Radius 0 (the error gone in one step), radius 1 (a state no sensor corrects: no end); a
    factor that is no decay, and a continuous gain (no steps), refused."""
    assert startup_steps([[1.0]], [[1.0]], [[[1.0]]], "filter") == 0.0
    assert startup_steps([[1.0]], [[1.0]], [[[0.0]]], "filter") == math.inf
    assert startup_steps([[1.0]], [[1.0]], [[[0.5]]], "filter", decay=2.0) == pytest.approx(1.0)
    for bad in (1.0, 0.5, float("nan"), True, "100"):
        with pytest.raises(ValueError, match="decay must be a number greater than 1"):
            startup_steps([[1.0]], [[1.0]], [[[0.5]]], "filter", decay=bad)
    with pytest.raises(ValueError, match=r"discrete gain form .* not 'continuous'"):
        startup_steps([[0.0]], [[1.0]], [[[0.5]]], "continuous")


def _correlation_sum(table) -> float:
    """``1 + 2 sum_{j>=1} rho_j^2`` of the steady-state error of state 0 at the table's posterior
    output (single rate): ``rho_j`` from the closed loop ``A = F - Kp H``, the prior covariance
    ``P`` and the update ``C = I - L H``: ``cov_j = C A^(j-1) (A P C' + Kp R L')``."""
    F, H, R, P = table.F, table.H, table.R, table.P[0]
    Kp, L = gain_pair(F, table.K[0], table.gain_form)
    A, C = closed_loop(F, H, table.K[0], table.gain_form), np.eye(len(F)) - L @ H
    var = (C @ P @ C.T + L @ R @ L.T)[0, 0]
    assert var == pytest.approx(table.P_filtered[0][0, 0], rel=1e-9)
    total, M = 1.0, A @ P @ C.T + Kp @ R @ L.T
    for _ in range(20 * math.ceil(startup_steps(F, H, table.K, table.gain_form))):
        total += 2 * ((C @ M)[0, 0] / var) ** 2
        M = A @ M
    return total


def test_after_the_startup_the_rms_error_is_the_predicted_std(slow, biased_log):
    """A gyro 0.1 rad/s off at the start: over every row the RMS heading error is 7 times the
    predicted std (the start-up's error, 0.1 rad at 2 s, is far outside the band); after the
    start-up (16.1 s) it is the predicted std within 3 standard errors of an RMS over the settled
    rows (21 %: the error's correlation, derived from the table's closed loop, leaves about 50
    independent samples in 18,400 rows; measured 0.96 times the prediction)."""
    result = run_log(slow, biased_log, reference="truth")
    steps = startup_steps(slow.F, slow.H, slow.K, slow.gain_form)
    assert result.startup_s == pytest.approx(math.ceil(steps) * slow.sample_time_s)
    assert result.settled_samples == N - math.ceil(steps)
    predicted = result.predicted_std["heading"]
    assert predicted == pytest.approx(slow.predicted_std, rel=1e-12)  # single rate, nothing missed: the table's
    tolerance = 3 * math.sqrt(_correlation_sum(slow) / (2 * result.settled_samples))
    assert 0.15 < tolerance < 0.25  # the error's correlation time is long beside 18,400 rows (0.1 Hz crossover)
    assert result.rms_settled["heading"] == pytest.approx(predicted, rel=tolerance)
    assert result.rms["heading"] > 5 * predicted  # over every row: the start-up's error
    # the figures by hand: the settled RMS is over the rows from the start-up's tick on
    err = wrap(biased_log["truth"].to_numpy() - result.estimates["heading"].to_numpy())
    settled = np.arange(N) >= math.ceil(steps)
    assert result.rms_settled["heading"] == pytest.approx(np.sqrt(np.mean(err[settled] ** 2)), rel=1e-12)


def test_the_cli_prints_every_rows_and_the_settled_rms_beside_the_prediction(slow, biased_log, tmp_path, cli):
    """One line per reference: over all rows, after the start-up (its length named), predicted;
    a log that ends within the start-up says so instead of a settled figure."""
    biased_log.to_csv(tmp_path / "log.csv", index=False)
    table = slow.save(tmp_path / "g.json")
    code, out, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv", "--reference",
                         "heading=truth", "--plot", tmp_path / "p.png")
    assert code == 0, err
    line = next(s for s in out.splitlines() if s.startswith("RMS error of heading"))
    number = r"([0-9.e+-]+)"
    m = re.fullmatch(rf"RMS error of heading: {number} rad over all rows; {number} rad after the start-up "
                     rf"\(first {number} s\); predicted {number} rad", line)
    assert m, line
    result = run_log(slow, biased_log, reference="truth")
    assert [float(v) for v in m.groups()] == pytest.approx(
        [result.rms["heading"], result.rms_settled["heading"], 16.1, result.predicted_std["heading"]], rel=1e-5)
    assert result.startup_s == pytest.approx(16.13)
    biased_log.iloc[:1000].to_csv(tmp_path / "short.csv", index=False)  # 10 s of a 16.1 s start-up
    code, out, err = cli("run", table, tmp_path / "short.csv", "-o", tmp_path / "e.csv", "--reference",
                         "heading=truth")
    assert code == 0, err
    assert re.search(r"RMS error of heading: [0-9.e+-]+ rad over all rows; none after the start-up \(the log ends "
                     r"within it: its first 16.1 s\); predicted [0-9.e+-]+ rad", out), out


def test_the_plot_shades_the_startup(slow, biased_log):
    """The error panel has a span from the first row to the start-up's end, in its legend; the
    title gives the settled RMS beside the RMS over every row."""
    result = run_log(slow, biased_log, reference="truth")
    fig = plot_log(slow, result.estimates, {"heading": "truth"}, "time")
    panel = fig.axes[1]
    spans = [p for p in panel.patches if p.get_label().startswith("start-up")]
    assert len(spans) == 1 and spans[0].get_label() == f"start-up (first {result.startup_s:.3g} s)"
    extent = spans[0].get_window_extent().transformed(panel.transData.inverted())
    assert (extent.x0, extent.x1) == pytest.approx((0.0, result.startup_s))
    assert "start-up (first 16.1 s)" in [t.get_text() for t in panel.get_legend().get_texts()]
    assert f"after the start-up {result.rms_settled['heading']:.3g}" in panel.get_title(loc="right")
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_the_plot_breaks_its_lines_at_a_pause_of_the_log(slow, biased_log):
    """Rows missing for 10 s (a logger's pause): the estimate, error and band stop at the pause
    and start again after it, instead of a straight line across it."""
    paused = biased_log[(biased_log["time"] < 20.0) | (biased_log["time"] >= 30.0)].reset_index(drop=True)
    result = run_log(slow, paused, reference="truth", std=True)
    fig = plot_log(slow, result.estimates, {"heading": "truth"}, "time")
    first = np.flatnonzero(result.estimates["time"].to_numpy() >= 30.0)[0]
    for line in (fig.axes[0].lines[0], fig.axes[1].lines[0]):
        y = np.asarray(line.get_ydata(), dtype=float)
        assert np.isnan(y[first]) and np.isfinite(y[first - 1]) and np.isfinite(y[first + 1])
    assert np.isfinite(np.asarray(fig.axes[1].lines[0].get_ydata(), dtype=float)[100:first]).all()
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_the_fleet_summary_has_the_settled_rms_beside_the_rms():
    """``summary.csv``'s row: ``rms_<state>``, ``rms_settled_<state>`` and the prediction it should
    come to, and the start-up's length; a result without references has none of them."""
    r = LogResult(None, 10, {"heading": 0.5}, rms_settled={"heading": 0.1}, predicted_std={"heading": 0.09},
                  startup_s=16.1)
    assert list(r.summary().items())[3:] == [("rms_heading", 0.5), ("rms_settled_heading", 0.1),
                                             ("predicted_std_heading", 0.09), ("startup_s", 16.1), ("notes", "")]
    assert list(LogResult(None, 10).summary()) == ["log", "samples", "readings_not_used", "notes"]
