"""Structures from the design file: a general kinematic chain (two rate sensors), and cfn's
``full`` and ``discrete`` options as top-level keys (docs/derivations.md, "A general kinematic
chain")."""

import numpy as np
import pytest

from cfdesign.designer import design
from cfdesign.errors import SpecError
from cfdesign.gains import load_gains
from cfdesign.runtime import Runtime
from cfdesign.spec import load_spec, parse_spec

TWO_GYROS = """
name = "heading from two gyros and a compass"
structure = "chain"
order = 1
discrete = true

[sensors.gyro_a]
measures = "rate"
rate_hz = 50.0
noise = { density = 1.7e-4 }
bias = { model = "random_walk", density = 2e-5 }

[sensors.gyro_b]
measures = "rate"
rate_hz = 50.0
noise = { density = 5e-4 }
bias = { model = "random_walk", density = 4e-5 }

[sensors.compass]
measures = "angle"
rate_hz = 50.0
noise = { std = 0.02 }
"""


@pytest.fixture
def spec_file(tmp_path):
    path = tmp_path / "two_gyros.toml"
    path.write_text(TWO_GYROS)
    return path


def test_two_rate_sensors_design_prove_verify(cli, spec_file, tmp_path):
    code, out, err = cli("design", spec_file, "-o", tmp_path / "g.json")
    assert code == 0, err
    assert "complementary (exact proof): True; stable: True" in out
    table = load_gains(tmp_path / "g.json")
    assert table.structure == "chain" and [s.name for s in table.inputs] == ["gyro_a", "gyro_b"]
    # the inputs are averaged with minimum-variance weights w ~ 1/q
    qa, qb = 1.7e-4**2, 5e-4**2
    wa = (1 / qa) / (1 / qa + 1 / qb)
    assert table.B[0] == pytest.approx([0.02 * wa, 0.02 * (1 - wa)], rel=1e-12)
    code, out, err = cli("verify", tmp_path / "g.json", "--spec", spec_file)
    assert code == 0, out + err


def test_the_symbolic_proof_holds_for_any_gain_and_weights():
    from cfdesign.symbolic.filters import chain

    obs = chain(1, ["gyro_a", "gyro_b"], [("compass", 0)], weights=[0.25, 0.75], bias=True, discrete=True)
    assert obs.proof().holds and set(obs.gains) == {"k11", "k21"}
    obs = chain(2, ["acc"], [("gps", 0), ("wheel", 1), ("radar", 1)], weights=None)
    assert obs.proof().holds
    with pytest.raises(Exception, match="sum to 1"):
        chain(1, ["a", "b"], [("c", 0)], weights=[0.5, 0.6])


def test_two_gyros_run_and_track(spec_file):
    table = design(load_spec(spec_file))
    n = 3000
    truth = 0.3 * np.sin(np.arange(n) * 0.01)
    rate = np.gradient(truth) * 50.0
    data = {"gyro_a": rate + 0.002, "gyro_b": rate - 0.001, "compass": truth}  # biased gyros, exact compass
    est = Runtime(table).run(data)
    assert abs(est[-1] - truth[-1]) < 0.01
    streamed = Runtime(table)
    assert streamed.step(**{k: v[0] for k, v in data.items()}) == pytest.approx(est[0])


def test_two_gyros_export_to_c(spec_file, tmp_path):
    import shutil

    from cfdesign.codegen import write_c
    from cfdesign.sim.signals import sinusoid_readings

    table = design(load_spec(spec_file))
    header = write_c(table, tmp_path / "gen")[0].read_text()
    assert "GYRO_A" in header and "GYRO_B" in header
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    from test_codegen import run_c  # the codegen tests' driver

    data = sinusoid_readings(table, 5000, seed=3, missing=0.02)
    rt = Runtime(table)
    py = np.array([rt.step(**{k: v[i] for k, v in data.items()}) for i in range(5000)])
    c = run_c(table, data, tmp_path, "double")
    assert np.max(np.abs(c - py)) <= 1e-12 * np.max(np.abs(py))


@pytest.mark.parametrize("edit, message", [
    (("order = 1", "order = 2"), "needs an input sensor"),
    (('measures = "angle"', 'measures = "rate"\nrole = "measurement"'), "has a lower derivative order"),
    (('order = 1\n', ''), "order: missing field"),
    (('measures = "angle"', 'measures = "angle"\nport = "x"'), "port: does not apply"),
    (('measures = "angle"', 'measures = "speed"'), "unknown sensor kind"),
])
def test_chain_errors_name_the_field(tmp_path, edit, message):
    path = tmp_path / "bad.toml"
    path.write_text(TWO_GYROS.replace(*edit))
    with pytest.raises(SpecError, match=message):
        design(load_spec(path))


def test_role_only_for_chains():
    with pytest.raises(SpecError, match="role: applies to structure chain only"):
        design(parse_spec({"structure": "cf2", "sensors": {
            "rate": {"rate_hz": 10.0, "noise": {"std": 0.1}, "role": "input"},
            "angle": {"rate_hz": 10.0, "noise": {"std": 0.1}}}}))


@pytest.mark.parametrize("discrete", [False, True])
def test_cfn_full_and_discrete_from_the_design_file(discrete):
    sensors = {"acceleration": {"rate_hz": 20.0, "noise": {"density": 0.05}},
               "velocity": {"rate_hz": 20.0, "noise": {"std": 0.05}},
               "position": {"rate_hz": 20.0, "noise": {"std": 0.5}}}
    table = design(parse_spec({"structure": "cfn", "bands": 3, "full": True, "discrete": discrete,
                               "sensors": sensors}))
    assert set(table.gains) == {"k11", "k12", "k21", "k22"} and table.options["full"] is True
    assert table.domain == ("z" if discrete else "s")
    assert table.checks["complementary"]
    with pytest.raises(SpecError, match="full: does not apply to structure cf2"):
        design(parse_spec({"structure": "cf2", "full": True, "sensors": {
            "rate": {"rate_hz": 10.0, "noise": {"std": 0.1}}, "angle": {"rate_hz": 10.0, "noise": {"std": 0.1}}}}))


def test_cli_prove_takes_full_and_discrete(cli):
    code, out, _ = cli("prove", "cfn", "--bands", "3", "--full", "--discrete")
    assert code == 0 and "k22" in out and "z" in out and "HOLDS" in out


def test_the_bias_state_two_gyros_share_is_named_after_their_quantity(spec_file):
    """It corrects the weighted mean of both gyros; naming it after the last one (gyro_b_correction)
    read as gyro_b's own bias."""
    from cfdesign.designer import design

    assert design(load_spec(spec_file)).states == ("angle", "rate_correction")


def test_state_units_follow_the_state_names(spec_file):
    """Units of every state from the designer's names: the shared bias of two gyros is a rate."""
    import dataclasses

    import cfdesign

    assert design(load_spec(spec_file)).state_units() == ("rad", "rad/s")
    position = design(load_spec(cfdesign.example_path("position")))
    assert position.state_units() == ("m", "m/s", "m/s²")
    renamed = dataclasses.replace(position, states=("p", "v", "b"))
    assert renamed.state_units() == ("", "", "")


@pytest.mark.parametrize("discrete", [False, True])
def test_a_designed_chain_table_proves_through_its_observer(discrete):
    """table.observer().proof() of a one-input chain (accelerometer, wheel, GPS) said 'not
    complementary' although cfdesign verify proved the table: the continuous model was taken as
    sympy Floats, and the sampled B = [T^3/6, T^2/2, T] by the decimal values of its doubles
    (1.6666666666666668e-07 is not T^3/6)."""
    table = design(parse_spec({"structure": "chain", "order": 2, "discrete": discrete, "sensors": {
        "acc": {"measures": "acceleration", "rate_hz": 100.0, "noise": {"density": 0.01},
                "bias": {"model": "random_walk", "density": 1e-3}},
        "wheel": {"measures": "velocity", "rate_hz": 100.0, "noise": {"std": 0.05}},
        "gps": {"measures": "position", "rate_hz": 100.0, "noise": {"std": 0.5}}}}))
    assert table.checks["complementary"]
    assert table.observer().proof().holds
