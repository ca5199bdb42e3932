"""Predicted std against measured error for design files drawn at random (``benchmarks/bench_predicted.py
--random``), and the regression found by it: the held input readings' noise in a discrete ``Q``.

Tolerance of the property test: a state passes when measured / predicted std and measured / std
column lie within ``4 se + 3 %`` of 1 and the std column's RMS is the prediction within 1 %
(:func:`bench.flagged`), ``se`` the batch-means standard error of the measured std, which is
asserted below 2.5 % here (1.2 to 1.9 % for these seeds), so the band is at most 13 %: a variance
predicted 28 % off fails it, and the std column's 1 % is a check without Monte-Carlo error.  The
seeds are fixed, so the draw is the same on every run.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from cfdesign.designer import Structure, design_from_structure
from cfdesign.spec import parse_spec

_spec = importlib.util.spec_from_file_location(
    "bench_predicted", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_predicted.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

SE_MAX = 0.025  # the measured std's standard error must be below this for the band to mean anything


#: a cfn of 2 bands; a multirate cf2 heading (wrapped, period 25); a cf2 tracking its gyro bias; a cfn
#: whose slow sensor is read at its own offset (period 3)
@pytest.mark.parametrize("seed", [8, 11, 13, 14])
def test_random_design_files_predict_their_error(tmp_path, seed):
    """A random design file (structure, noise, rates, offsets, form, output drawn by the benchmark),
    designed, simulated and run through the command line on a short log: every state's error
    is the predicted one within its Monte-Carlo band."""
    text, table, _, _, _, found = bench.random_run(np.random.default_rng(seed), 0, tmp_path, 0.1)
    assert found and len(found) == len(table.states)
    for row in found:
        assert row["mc_se_var"] / 2 < SE_MAX, (text, row)
        assert not bench.flagged(row), (text, row)


def test_held_input_noise_is_the_discrete_q():
    """A discrete design's ``Q`` is that of a log whose accelerometer reading is held over each
    10 Hz step (``B n[k]``, its position entry ``T^4 sigma^2 / 4``), not the Van Loan integral of
    white noise (``T^4 sigma^2 / 3``, 4/3 of it): the one-step residuals of the benchmark's exact
    simulation over 50,000 ticks have ``diag Q`` within 3 % (standard error 0.6 %; the Van Loan
    input gave 0.75 on the position)."""
    spec = parse_spec({"structure": "position", "sensors": {
        "accelerometer": {"rate_hz": 10.0, "noise": {"std": 0.05},
                          "bias": {"model": "random_walk", "density": 1e-3}},
        "gps": {"rate_hz": 10.0, "noise": {"std": 0.01}}}})
    table = design_from_structure(Structure.load("position"), spec)
    figures = {"accelerometer": (0.05, 1e-3), "gps": (0.01, 0.0)}
    log, truth = bench.simulate(table, figures, 50_000, {}, np.random.default_rng(0))
    q_ratio, r_ratio = bench.model_check(table, log, truth)
    np.testing.assert_allclose(q_ratio, 1, atol=0.03)
    np.testing.assert_allclose(r_ratio, 1, atol=0.03)
