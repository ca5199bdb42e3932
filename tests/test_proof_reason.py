"""A complementarity proof that fails says why, in terms of the model and the sensors.

Each failing observer below has a model that does not follow a sensor's relation
(docs/derivations.md, "Bands, and why they sum to one"); its reason must name the cause, and
the fix it names must make the proof hold.
"""

import json

import pytest
import sympy as sp

import cfdesign
from cfdesign import Observer, Sensor
from cfdesign.symbolic import zoh, zoh_chain

k1, k2 = sp.symbols("k1 k2")
GYRO, COMPASS = Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)
ACC, GPS = Sensor.input("acc", "acceleration"), Sensor.measurement("gps", "position", 0)


def _fails_because(obs, *phrases):
    """The proof fails, keeps its residual and gives a reason holding every phrase (and prints it)."""
    proof = obs.proof()
    assert proof.holds is False and proof.residual != 0
    for phrase in phrases:
        assert phrase in proof.reason
    assert f"why: {proof.reason}" in proof.text()
    assert json.loads(json.dumps(proof.to_dict()))["reason"] == proof.reason
    return proof.reason


def test_numeric_model_with_the_sample_time_left_symbolic():
    """F, B sampled at 0.01 s without sample_time=: T stays symbolic in the gyro's relation."""
    obs = Observer([[1]], [[0.01]], [[1]], [[k1]], [GYRO, COMPASS], domain="z")
    _fails_because(obs, "left symbolic", "relation of gyro", "pass sample_time=0.01")
    assert Observer(obs.F, obs.B, obs.H, obs.K, obs.sensors, domain="z", sample_time=0.01).proof().holds


def test_numeric_model_of_no_sample_time_still_asks_for_one():
    """B lacks T^2/2 and T is symbolic: no T fits, the reason says so and still asks for sample_time=."""
    obs = Observer([[1, 0.01], [0, 1]], [[0], [0.01]], [[1, 0]], [[k1], [k2]], [ACC, GPS], domain="z")
    _fails_because(obs, "left symbolic", "sample_time=<the model's sample time, s>", "no sample time makes")


@pytest.mark.parametrize("chain", [1, 2])
def test_continuous_model_given_as_discrete(chain):
    """The integrator chain (x' = F x + B u) given with domain='z'; sampled by ZOH it proves."""
    F, B = cfdesign.symbolic.integrator_chain(chain)
    sensors = [GYRO, COMPASS] if chain == 1 else [ACC, GPS]
    H, K = [[1] + [0] * (chain - 1)], [[k1], [k2]][:chain]
    _fails_because(Observer(F, B, H, K, sensors, domain="z"), "continuous model", "domain='z'", "zoh(F, B, T)")
    assert Observer(*zoh(F, B), H, K, sensors, domain="z").proof().holds
    assert Observer(F, B, H, K, sensors).proof().holds


def test_model_sampled_at_another_sample_time():
    """B = 0.02 integrates the rate over 0.02 s, but sample_time=0.01 is given."""
    obs = Observer([[1]], [[0.02]], [[1]], [[k1]], [GYRO, COMPASS], domain="z", sample_time=0.01)
    _fails_because(obs, "sample time of 0.02 s", "sample_time=0.01 given")
    assert Observer(obs.F, obs.B, obs.H, obs.K, obs.sensors, domain="z", sample_time=0.02).proof().holds


def test_acceleration_input_without_its_half_T_squared():
    """B = [0, T] misses T^2/2: the reason names the input and shows the ZOH chain it assumes."""
    T = sp.Rational(1, 100)
    obs = Observer([[1, T], [0, 1]], [[0], [T]], [[1, 0]], [[k1], [k2]], [ACC, GPS], domain="z", sample_time=T)
    reason = _fails_because(obs, "input acc", "'acceleration' (order 2)", "zoh_chain(2, T)")
    F, B = zoh_chain(2, T)
    assert f"B = {B.T.tolist()[0]}" in reason and B[0] == T**2 / 2
    assert Observer(F, B, obs.H, obs.K, obs.sensors, domain="z", sample_time=T).proof().holds


def test_rate_sensor_integrated_over_another_T_in_a_symbolic_model():
    """dckf3 with B = T/2: the model needs twice the gyro's relation."""
    d = cfdesign.dckf3()
    T = d.sample_time
    reason = _fails_because(Observer(d.F, d.B / 2, d.H, d.K, d.sensors, domain="z"), "input gyro")
    assert f"needs the relation {sp.factor(2 * (sp.Symbol('z') - 1) / T)}" in reason


@pytest.mark.parametrize("declared, enters", [("velocity", 2), ("angle", 1)])
def test_input_declared_one_order_entering_as_another(declared, enters):
    """An accelerometer declared a velocity sensor (cf3), a gyro declared an angle sensor (dckf3):
    the reason names the order the model implies."""
    good = cfdesign.cf3() if enters == 2 else cfdesign.dckf3()
    x = good.sensors[0]
    sensors = [Sensor.input(x.name, declared, bias_state=x.bias_state), *good.sensors[1:]]
    obs = Observer(good.F, good.B, good.H, good.K, sensors, domain=good.domain)
    _fails_because(obs, f"input {x.name}", f"the relation of an order-{enters} ")


def test_measurement_declared_rate_entering_as_angle():
    obs = Observer([[0]], [[1]], [[1]], [[k1]], [GYRO, Sensor.measurement("compass", "rate", 0)])
    _fails_because(obs, "measurement compass is declared 'rate/velocity'", "row 0 of H",
                   "the relation of an order-0 'angle/position' sensor")


@pytest.mark.parametrize("obs", [
    cfdesign.cf2(), cfdesign.dckf3(),
    Observer([[1]], [[0.01]], [[1]], [[k1]], [GYRO, COMPASS], domain="z", sample_time=0.01),
], ids=["cf2", "dckf3", "numeric"])
def test_a_proof_that_holds_has_no_reason(obs):
    proof = obs.proof()
    assert proof.holds and proof.reason == "" and "why:" not in proof.text()
    assert cfdesign.symbolic.proof.explain(obs) == ""


_POSITION_SPEC = {"name": "one axis", "structure": "position", "gain_form": "filter",
                  "sensors": {"acc": {"measures": "acceleration", "noise": {"std": 0.01}, "rate_hz": 100},
                              "gps": {"measures": "position", "noise": {"std": 1.0}, "rate_hz": 100}}}


def _designed(obs):
    with pytest.raises(cfdesign.SpecError) as err:
        cfdesign.design(cfdesign.parse_spec(_POSITION_SPEC), observer=obs)
    assert "\n" not in str(err.value) and "a bug" not in str(err.value)
    return str(err.value)


def test_design_of_an_observer_that_cannot_be_complementary_names_the_relation():
    """A continuous model whose input also drives the position: its ZOH is consistent with it, but no gain
    makes the bands sum to one; design named the gains' scaling (the numeric check), now the relation."""
    T = sp.Rational(1, 100)
    Fc, Bc = sp.Matrix([[0, 1], [0, 0]]), sp.Matrix([[1], [1]])
    obs = Observer(*zoh(Fc, Bc, T), [[1, 0]], [[k1], [k2]], [ACC, GPS], domain="z", sample_time=T,
                   gain_form="filter", continuous=(Fc, Bc))
    message = _designed(obs)
    assert "do not sum to one for any gains" in message and "input acc" in message and "zoh_chain(2, T)" in message


def test_design_of_a_discrete_model_that_is_not_the_hold_of_its_continuous_one():
    """B = [0, T] beside continuous=(chain): the user's model, not a fault of cfdesign; the entry is shown."""
    T = sp.Rational(1, 100)
    obs = Observer([[1, T], [0, 1]], [[0], [T]], [[1, 0]], [[k1], [k2]], [ACC, GPS], domain="z", sample_time=T,
                   gain_form="filter", continuous=([[0, 1], [0, 0]], [[0], [1]]))
    message = _designed(obs)
    assert "B is not the zero-order hold" in message and "[[5e-05], [0.01]]" in message
    good = Observer(*zoh(sp.Matrix([[0, 1], [0, 0]]), sp.Matrix([[0], [1]]), T), obs.H, obs.K, obs.sensors,
                    domain="z", sample_time=T, gain_form="filter", continuous=([[0, 1], [0, 0]], [[0], [1]]))
    assert cfdesign.design(cfdesign.parse_spec(_POSITION_SPEC), observer=good).checks["complementary"]
