"""The estimate users get: the posterior (after this step's readings) by default, and its error
variance is what the table predicts, on logs drawn from the table's own model."""

import dataclasses

import numpy as np
import pytest

import cfdesign
from cfdesign.runtime import Runtime
from cfdesign.sim.gaussian import model_log

N = 400_000


def _table(example, form, rates=None, output="posterior"):
    spec = cfdesign.load_spec(cfdesign.example_path(example))
    sensors = tuple(dataclasses.replace(s, rate_hz=(rates or {}).get(s.name, s.rate_hz)) for s in spec.sensors)
    return cfdesign.design(dataclasses.replace(spec, gain_form=form, wrap_angle=False, sensors=sensors, output=output))


@pytest.mark.parametrize("rates", [None, {"compass": 1.0}], ids=["single-rate", "multirate"])
@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_default_output_variance_is_the_posterior_prediction(rates, form):
    """The dckf3 example (the paper's Fig. 5 arrangement) at 5 Hz, and with the compass at 1 Hz
    (period 5): the default output's error variance within 3 % of the table's a-posteriori
    prediction, the prediction's within 3 % of P (measured: within 0.5 % over four seeds)."""
    table = _table("dckf3", form, rates)
    assert table.period == (1 if rates is None else 5)
    assert table.output == "posterior"
    x, readings = model_log(table, N, seed=7)
    skip = 5000  # the start-up transient
    phases = np.arange(skip, N) % table.period
    for output, covs in (("posterior", table.P_filtered), ("prior", table.P)):
        est = Runtime(table, output=output).run(readings)
        measured = np.mean((est[skip:] - x[skip:, 0]) ** 2)
        predicted = np.mean([covs[k][0, 0] for k in phases])
        assert measured == pytest.approx(predicted, rel=0.03), (output, measured, predicted)
    # the posterior is the better estimate, as predicted
    assert table.predicted_std_of("posterior") < table.predicted_std_of("prior")


def test_multirate_phases_without_a_reading_give_the_prediction():
    table = _table("position", "filter")
    _, readings = model_log(table, 500, seed=1)
    post, xs_post = Runtime(table).run(readings, states=True)
    prior, xs_prior = Runtime(table, output="prior").run(readings, states=True)
    read = table.schedule.mask()[np.arange(500) % table.period].any(axis=1)
    assert np.array_equal(post[~read], prior[~read]) and not np.allclose(post[read], prior[read])
    assert np.array_equal(xs_post[~read], xs_prior[~read])


def test_gaps_and_bad_numbers_run_in_batch_like_the_stream():
    """NaN gaps at scheduled phases, inf readings and NaN inputs: batch equals streaming, nothing
    becomes NaN, bad numbers are counted."""
    table = _table("dckf3", "predictor")
    _, readings = model_log(table, 3000, seed=2)
    readings["compass"][[10, 11, 500, 1700]] = np.nan
    readings["odometry"][[42, 2999]] = np.inf
    readings["compass"][100] = -np.inf
    readings["gyro"][[5, 6, 900]] = [np.nan, np.inf, -np.inf]
    rt = Runtime(table)
    batch = rt.run(readings)
    stream_rt = Runtime(table)
    names = list(readings)
    stream = np.array([stream_rt.step(**{n: readings[n][k] for n in names}) for k in range(3000)])
    assert np.all(np.isfinite(batch)) and np.max(np.abs(batch - stream)) < 1e-9
    assert rt.counts == stream_rt.counts == {"rejected": {"odometry": 2, "compass": 1, "gyro": 2}}
    assert np.all(np.isfinite(rt.x))


def test_model_log_truth_follows_the_model_recursion():
    """The simulated truth steps as ``x[k+1] = F x[k] + B u[k] + w[k]``, ``w ~ N(0, Q)``, on a long
    log of the position example (a triple integrator): an IIR filter of ``(zI - F)^-1`` drifted
    (the position increments had 4.5x the variance of Q over 200,000 steps; its truth 1 m off)."""
    table = _table("position", "filter")
    x, readings = model_log(table, 200_000, seed=0)
    u = np.column_stack([readings[s.name] for s in table.inputs])
    w = x[1:] - x[:-1] @ table.F.T - u[:-1] @ table.B.T
    assert np.diag(np.cov(w.T)) / np.diag(table.Q) == pytest.approx(np.ones(3), rel=0.03)


@pytest.mark.parametrize("output, form", [("posterior", "filter"), ("prior", None)])
def test_multirate_proof_is_of_the_output_the_table_declares(monkeypatch, output, form):
    """A multirate table's exact proof (gains symbolic, so every phase) is of the bands of the
    estimate it outputs: the posterior's are the filter-form observer's (the readings fed
    through).  A posterior table recorded the structure's proof of the prediction's bands."""
    from cfdesign import designer
    from cfdesign.symbolic.observer import Observer

    proved = []
    real = Observer.proof
    monkeypatch.setattr(Observer, "proof", lambda self: proved.append((self.gain_form, self.is_numeric)) or real(self))
    monkeypatch.setattr(designer, "_SYMBOLIC_PROOFS", {})
    table = _table("dckf3", "predictor", {"compass": 1.0}, output=output)
    assert table.period == 5 and table.output == output
    # the posterior's bands: the filter-form observer, gains symbolic; the prior's: the structure's
    # own (predictor-form) proof, already run
    assert ((form, False) in proved) if form else not any(f == "filter" for f, _ in proved)
    assert table.checks["complementary"] and f"{output} output" in table.checks["complementary_method"]
