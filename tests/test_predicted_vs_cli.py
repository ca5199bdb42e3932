"""What ``cfdesign design`` prints and ``cfdesign run --std`` writes, against the error of what
``cfdesign run`` writes for a log drawn from the design file's own noise model.

Each test designs a table through the command line, draws a log of 50,000 base ticks (100,000
for the 3 Hz GPS) whose sensors follow the design file exactly (white noise of the stated std,
a bias random walk of the stated density sampled exactly over each tick, a time column jittered
by 3 % of a tick, slow sensors at offsets of their own), runs it with ``cfdesign run ... --std``
(the default output; ``--prediction`` too for the default example, a filter-form multirate table
and the missed readings: the two outputs' ratios agree to 0.001 in the benchmark; with
``--reference`` for every state), and checks the RMS
error against the printed figure, the written std column, and the predicted figure that
``cfdesign run --reference`` prints beside its own RMS error.  The simulation is
``benchmarks/bench_predicted.py``'s (which runs the long logs); it is checked here against the
table's ``F``, ``B``, ``H``, ``Q``, ``R`` first.

Monte-Carlo error: the batch-means standard error ``se`` of each measured variance is asserted
below 4.5 % (0.6 to 4.3 % in these cases; 2.25 % on the std), and measured / predicted std must
lie within 3 % + ``se`` of 1 (3 % and two standard errors of the std): a 5 % bias in a predicted
variance is not hidden by a lucky draw, as the seeds are fixed.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location(
    "bench_predicted", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_predicted.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

TOL = 0.03  # on the std: measured / predicted within 1 +- (TOL + the variance's standard error)
MC_MAX = 0.045  # the measured variance's standard error must be below this for the check to mean anything

#: multirate heading whose errors decorrelate within a second (a precise 10 Hz odometry, a noisy
#: gyro): 100 Hz gyro, 10 Hz odometry, 1 Hz compass
HEADING = bench.HEADING_MULTIRATE.replace("{form}", "{form}", 1)
HEADING_NOISE = {"gyro": 0.1, "gyro_bias": 0.05, "odometry": 0.001, "compass": 0.05}

#: a precise 3 Hz GPS beside a noisy 100 Hz accelerometer (a rate ratio of 100/3)
GPS_NOISE = {"accelerometer": 1.0, "accelerometer_bias": 0.1, "gps": 0.01}


def heading_spec(form):
    """The benchmark's multirate heading design file (case b) with :data:`HEADING_NOISE`."""
    return bench.HEADING_MULTIRATE.format(form=form, **HEADING_NOISE)


def gps_spec(form):
    """The benchmark's 3 Hz GPS design file (case c) with :data:`GPS_NOISE`."""
    return bench.GPS_3HZ.format(form=form, **GPS_NOISE)

OFFSETS = {"odometry": 3, "compass": 37}


def _run(tmp_path, rows, offsets, seed, missing=0.0, settle_s=30.0, example=None, spec_text=None, prior=False):
    """Design, simulate, run through the CLI (and with ``prior``, again with ``--prediction``): the rows
    of :func:`bench.compare` for each output, keyed by (output, state)."""
    path, table, printed, figures = bench.design(tmp_path, "case", spec_text=spec_text, example=example)
    log, truth = bench.simulate(table, figures, rows, offsets, np.random.default_rng(seed), missing)
    out = {}
    for prediction in (False, True)[: 1 + prior]:
        for r in bench.compare(path, table, log, truth, printed, tmp_path, prediction, settle_s=settle_s):
            out[r["output"], r["state"]] = r
    return table, out


def _check(row, against=("ratio", "ratio_column")):
    assert row["mc_se_var"] < MC_MAX, row
    for key in against:
        assert abs(row[key] - 1) < TOL + row["mc_se_var"], (key, row)
    # the two figures `cfdesign run --reference` prints: the RMS error after its start-up, and the
    # predicted std beside it
    assert abs(row["run_rms"] / row["run_predicted"] - 1) < TOL + row["mc_se_var"], row


def test_simulation_is_the_tables_model(tmp_path):
    """The simulated truth and readings have the table's process and measurement noise: the
    one-step residuals' variances over 50,000 ticks are ``diag Q`` and ``R`` within 3 %
    (standard error of a variance over 50,000 samples: 0.6 %)."""
    _, table, _, figures = bench.design(tmp_path, "h", spec_text=heading_spec("predictor"))
    log, truth = bench.simulate(table, figures, 50_000, {}, np.random.default_rng(0))
    q_ratio, r_ratio = bench.model_check(table, log, truth)
    np.testing.assert_allclose(q_ratio, 1, atol=0.03)
    np.testing.assert_allclose(r_ratio[:1], 1, atol=0.03)  # odometry: 5,000 readings
    np.testing.assert_allclose(r_ratio[1:], 1, atol=0.15)  # compass: 500 readings (se 6 %)


def test_example_robot_heading(tmp_path):
    """The default example: both states, the estimate and the one-step prediction, against the
    printed figure (first state), the table's covariance (second) and the std column."""
    table, out = _run(tmp_path, 50_000, {}, seed=1, settle_s=300.0, example="robot-heading", prior=True)
    for state in table.states:
        for output in ("posterior", "prior"):
            _check(out[output, state])


def test_example_dckf3(tmp_path):
    """The paper's DCKF3 example: the heading (its slow gyro-correction state needs millions of
    ticks: benchmarks/bench_predicted.py)."""
    _, out = _run(tmp_path, 50_000, {}, seed=2, settle_s=300.0, example="dckf3")
    _check(out["posterior", "heading"])


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_multirate_heading_at_own_offsets(tmp_path, form):
    """100 Hz gyro, 10 Hz odometry at rows 3, 13, ..., 1 Hz compass at rows 37, 137, ...: the
    runtime recomputes the gains for the arrivals, and the error is what the design predicted."""
    _, out = _run(tmp_path, 50_000, OFFSETS, seed=3, spec_text=heading_spec(form), prior=form == "filter")
    for output in ("posterior", "prior")[: 1 + (form == "filter")]:
        _check(out[output, "heading"])


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_gps_at_3_hz(tmp_path, form):
    """A rate ratio of 100/3 (the GPS on ticks 0, 33, 67 of every 100, shifted by 5)."""
    _, out = _run(tmp_path, 100_000, {"gps": 5}, seed=4, spec_text=gps_spec(form))
    _check(out["posterior", "position"])


def test_missing_slow_readings_std_column(tmp_path):
    """20 % of the odometry and compass readings missing at random: the written std column (the
    bridged path's covariance) is the error's; the printed figure, for every reading present, is
    well below it."""
    _, out = _run(tmp_path, 50_000, OFFSETS, seed=5, missing=0.2, spec_text=heading_spec("predictor"),
                  prior=True)
    for output in ("posterior", "prior"):
        _check(out[output, "heading"], against=("ratio_column",))
        assert out[output, "heading"]["ratio"] > 1.2


def test_multirate_example_redesign_hint_designs(tmp_path, capsys):
    """The CKF3 example's 10 Hz position cannot be discretised with its 100 Hz sensors; the lines
    ``cfdesign discretize`` names instead design a multirate table through the command line whose
    predicted std is the continuous CKF3's within 1 % (0.0039748 against 0.0039759 m)."""
    from cfdesign.cli import main

    continuous = tmp_path / "ckf3.json"
    assert main(["design", "--example", "ckf3", "-o", str(continuous)]) == 0
    assert main(["discretize", str(continuous), "--rate-hz", "100", "-o", str(tmp_path / "d.json")]) == 2
    hint = re.search(r"so write (.*) in the design file", capsys.readouterr().err).group(1)
    lines = "\n".join(part.strip() for part in hint.split(", "))
    text = Path(bench.example_path("ckf3")).read_text()
    text = re.sub(r'^structure = .*$', lines, text, count=1, flags=re.M)
    _, table, printed, _ = bench.design(tmp_path, "redesigned", spec_text=text)
    assert table.period == 10 and table.schedule.rows(1) != table.schedule.rows(0)
    assert printed["posterior"] == pytest.approx(bench.load_gains(continuous).predicted_std, rel=0.01)
