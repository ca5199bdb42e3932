"""Design by crossover (cfdesign.crossover): adjacent bands of equal magnitude at the frequencies
a design file asks for, continuous and discrete (docs/derivations.md, "Design by crossover")."""

import math

import numpy as np
import pytest

from cfdesign import linear
from cfdesign.designer import design, numeric_structure
from cfdesign.errors import SpecError
from cfdesign.spec import parse_spec
from cfdesign.verify import band_polynomials, verify_table

GYRO = {"measures": "rate", "rate_hz": 100.0, "noise": {"density": 1.7e-4},
        "bias": {"model": "random_walk", "density": 2e-5}}
ANGLE = {"measures": "angle", "rate_hz": 100.0, "noise": {"std": 0.01}}
CHAIN = {"acceleration": {"rate_hz": 100.0, "noise": {"density": 0.01}},
         "velocity": {"rate_hz": 100.0, "noise": {"std": 0.05}},
         "position": {"rate_hz": 100.0, "noise": {"std": 0.5}}}


def cf2_spec(hz=0.5, **top):
    return parse_spec({"structure": "cf2", "order": 2, "crossover": {"hz": hz}, **top,
                       "sensors": {"rate": GYRO, "angle": ANGLE}})


def magnitudes(table, hz):
    """``{sensor: |T(j w)|}`` at ``hz`` from the table's own band polynomials (cfdesign.verify)."""
    bands, _ = band_polynomials(table)
    w = 2 * np.pi * np.asarray(hz, dtype=float)
    return {name: np.abs(linear.response(num, den, w, table.sample_time_s)) for name, (num, den) in bands.items()}


@pytest.mark.parametrize("top", [{}, {"discrete": True}, {"discrete": True, "gain_form": "filter"},
                                 {"discrete": True, "output": "prior"}],
                         ids=["continuous", "discrete-predictor", "discrete-filter", "discrete-prior"])
def test_cf2_order2_crossover_at_half_a_hertz(top):
    table = design(cf2_spec(**top))
    mag = magnitudes(table, [0.5])
    assert mag["angle"][0] == pytest.approx(mag["rate"][0], rel=0.01)
    assert mag["angle"][0] == pytest.approx(mag["rate"][0], rel=1e-9)  # solved, not approximated
    below, above = magnitudes(table, [0.05]), magnitudes(table, [5.0])
    assert below["angle"][0] > below["rate"][0] and above["rate"][0] > above["angle"][0]
    solver = table.provenance["solver"]
    assert solver["crossover_hz"] == [0.5]
    assert solver["kalman_predicted_variance"] <= solver["predicted_variance"]
    assert table.checks["complementary"] and table.checks["stable"]


@pytest.mark.parametrize("discrete", [False, True])
def test_three_band_crossovers_at_both_frequencies(discrete):
    table = design(parse_spec({"structure": "cf3", "discrete": discrete, "crossover": {"hz": [0.05, 2.0]},
                               "sensors": CHAIN}))
    mag = magnitudes(table, [0.05, 2.0])
    assert mag["position"][0] == pytest.approx(mag["velocity"][0], rel=1e-6)
    assert mag["velocity"][1] == pytest.approx(mag["acceleration"][1], rel=1e-6)
    # the Bode plot marks those crossovers (discrete: the rate and acceleration bands both grow towards
    # Nyquist, where ordering the bands by their peaks had drawn 'position/acceleration' at 0.32 Hz)
    from cfdesign.analysis import frequency_response
    from cfdesign.designer import designed_observer

    spec = parse_spec({"structure": "cf3", "discrete": discrete, "crossover": {"hz": [0.05, 2.0]}, "sensors": CHAIN})
    drawn = [(a, b, w / (2 * np.pi)) for a, b, w in frequency_response(designed_observer(spec, table)).crossovers()]
    assert [(a, b) for a, b, _ in drawn] == [("position", "velocity"), ("velocity", "acceleration")]
    assert [w for _, _, w in drawn] == pytest.approx([0.05, 2.0], rel=1e-6)


def test_closed_forms_are_the_sympy_solutions():
    import sympy as sp

    from cfdesign.crossover import continuous_crossover_gains
    from cfdesign.symbolic import cf2, cf3, cfn
    from cfdesign.symbolic.crossover import crossover_solution

    hz = [0.05, 0.4, 3.0]
    for obs, spec, n, damping in [(cf2(1), {"structure": "cf2", "order": 1}, 1, None),
                                  (cf2(2), {"structure": "cf2", "order": 2}, 1, 0.4),
                                  (cf3(), {"structure": "cf3"}, 2, None),
                                  (cfn(4), {"structure": "cfn", "bands": 4}, 3, None)]:
        w = [2 * math.pi * f for f in hz[-n:]]
        exact = crossover_solution(obs, [sp.nsimplify(x) for x in w],
                                   None if damping is None else sp.nsimplify(damping))
        names = [x.name for x in obs.sensors]
        sensors = {x: {"rate_hz": 10.0, "noise": {"std": 0.1}} for x in names}
        structure = numeric_structure(parse_spec({**spec, "sensors": sensors}))
        numeric = continuous_crossover_gains(structure, hz[-n:], damping)
        assert {k.name: float(v) for k, v in exact.items()} == pytest.approx(numeric, rel=1e-12)


@pytest.mark.parametrize("output", ["posterior", "prior"])
def test_discrete_cf2_order1_high_crossover_takes_the_stable_root(output):
    # the posterior bands k z/(z-1+k) and (1-k)(z-1)/(z-1+k) meet at k = |z-1|/(1+|z-1|) (stable)
    # and at |z-1|/(|z-1|-1), unstable once |z-1| > 1 (above 100/6 Hz here): the solver started
    # from the continuous k T found the unstable root and refused 20 Hz at 100 Hz
    gyro = {k: v for k, v in GYRO.items() if k != "bias"}
    table = design(parse_spec({"structure": "cf2", "order": 1, "discrete": True, "output": output,
                               "crossover": {"hz": 20.0}, "sensors": {"rate": gyro, "angle": ANGLE}}))
    d = 2 * math.sin(math.pi * 20.0 / 100.0)
    assert table.gains["k"] == pytest.approx(d / (1 + d) if output == "posterior" else d, rel=1e-9)
    mag = magnitudes(table, [20.0])
    assert mag["angle"][0] == pytest.approx(mag["rate"][0], rel=1e-6)
    assert table.checks["stable"]


def test_damping_shapes_the_poles():
    table = design(parse_spec(
        {"structure": "cf2", "order": 2, "crossover": {"hz": 0.5, "damping": 1.0},
         "sensors": {"rate": GYRO, "angle": ANGLE}}))
    poles = [complex(*p) for p in table.checks["poles"]]
    assert all(abs(p.imag) < 1e-6 * abs(p) for p in poles)  # critically damped: a double real pole


def test_constant_bias_designs_without_a_kalman_optimum():
    gyro = {**GYRO, "bias": {"model": "constant", "value": 0.01}}
    table = design(parse_spec({"structure": "cf2", "order": 2, "discrete": True, "crossover": {"hz": 1.0},
                               "sensors": {"rate": gyro, "angle": ANGLE}}))
    assert table.provenance["solver"]["kalman_predicted_variance"] is None
    assert magnitudes(table, [1.0])["rate"][0] == pytest.approx(magnitudes(table, [1.0])["angle"][0], rel=1e-9)


@pytest.mark.parametrize("data, message", [
    ({"structure": "cf2", "order": 2, "crossover": {"hz": [0.1, 1.0]}}, "1 crossover frequency; got 2"),
    ({"structure": "cf2", "order": 2, "crossover": {"hz": [1.0, 0.1]}}, "must increase"),
    ({"structure": "cf2", "order": 2, "crossover": {"hz": 0.5}, "gains": {"k1": 1.0}}, "not both"),
    ({"structure": "cf2", "order": 2, "crossover": {"hz": -1}}, "positive"),
    ({"structure": "cf2", "order": 2, "crossover": {"hz": 0.5, "shape": 1}}, "unknown field"),
    ({"structure": "cf2", "order": 2, "discrete": True, "crossover": {"hz": 60.0}}, "Nyquist"),
    ({"structure": "cf2", "order": 1, "crossover": {"hz": 0.5, "damping": 0.5}}, "cf2 order 2 only"),
])
def test_crossover_errors_name_the_field(data, message):
    with pytest.raises(SpecError, match=message):
        design(parse_spec({**data, "sensors": {"rate": {k: v for k, v in GYRO.items() if k != "bias"}
                                               if data.get("order") == 1 else GYRO, "angle": ANGLE}}))


def test_full_gain_structures_are_refused():
    with pytest.raises(SpecError, match="crossover: dckf3 has two sensors of the same derivative order"):
        design(parse_spec({"structure": "dckf3", "crossover": {"hz": [0.1, 1.0]}, "sensors": {
            "gyro": GYRO, "compass": ANGLE, "odometry": ANGLE}}))
    with pytest.raises(SpecError, match="not available for ckf3"):
        design(parse_spec({"structure": "ckf3", "crossover": {"hz": [0.1, 1.0]}, "sensors": CHAIN}))


def test_cli_design_and_verify_a_crossover_table(cli, tmp_path):
    spec = tmp_path / "x.toml"
    spec.write_text('structure = "cf2"\norder = 2\ndiscrete = true\n[crossover]\nhz = 0.5\n'
                    '[sensors.rate]\nrate_hz = 100.0\nnoise = { density = 1.7e-4 }\n'
                    'bias = { model = "random_walk", density = 2e-5 }\n'
                    '[sensors.angle]\nrate_hz = 100.0\nnoise = { std = 0.01 }\n')
    code, out, err = cli("design", spec, "-o", tmp_path / "g.json")
    assert code == 0, err
    assert "angle/rate at 0.5 Hz" in out and "Kalman optimum" in out
    code, out, err = cli("verify", tmp_path / "g.json", "--spec", spec)
    assert code == 0, out + err
    from cfdesign.gains import load_gains

    assert all(c.ok for c in verify_table(load_gains(tmp_path / "g.json")))


@pytest.mark.parametrize(("rate", "damping"), [(1000.0, None), (1000.0, 2.0), (20000.0, 0.3), (20000.0, 2.0)])
def test_discrete_damped_crossover_far_below_the_sample_rate(rate, damping):
    """A crossover at 1e-7 to 5e-9 of the sample rate: Ackermann's formula from the expanded
    characteristic polynomial cancelled to rounding (p(F) of size 1e-15 from terms of size 1), so
    the damping was not imposed and no root was found; the poles must have the asked damping."""
    crossover = {"hz": 1e-4, **({} if damping is None else {"damping": damping})}
    table = design(parse_spec({"structure": "cf2", "order": 2, "discrete": True, "crossover": crossover,
                               "sensors": {"rate": {**GYRO, "rate_hz": rate}, "angle": {**ANGLE, "rate_hz": rate}}}))
    zeta = damping or 1 / math.sqrt(2)
    Kp = linear.gain_pair(table.F, table.K[0], table.gain_form)[0]
    D = (table.F - np.eye(2)) - Kp @ table.H  # A - I without cancellation (F - I is exact)
    # its eigenvalues are expm1(s_i w_n T), s_i the roots of s^2 + 2 zeta s + 1: det gives w_n T
    # (to first order), the trace then the damping
    wnT = math.sqrt(np.linalg.det(D))
    assert np.real(np.sum(np.expm1(np.roots([1.0, 2 * zeta, 1.0]) * wnT))) == pytest.approx(np.trace(D), rel=1e-6)
    assert -np.trace(D) / (2 * wnT) == pytest.approx(zeta, rel=1e-5)


def test_continuous_three_bands_with_crossovers_far_apart_design_and_verify():
    """0.05 and 9000 Hz: the closed-loop poles are 5 decades apart; the bands from the
    eigenvalue-based characteristic polynomial failed the identity check ('cannot be decided in
    double precision') and the design was refused."""
    table = design(parse_spec({"structure": "cf3", "crossover": {"hz": [0.05, 9000.0]}, "sensors": CHAIN}))
    assert all(check.ok for check in verify_table(table))
    mag = magnitudes(table, [0.05, 9000.0])
    assert mag["position"][0] == pytest.approx(mag["velocity"][0], rel=1e-6)
    assert mag["velocity"][1] == pytest.approx(mag["acceleration"][1], rel=1e-6)


@pytest.mark.parametrize("damping", [1e3, 1e6])
@pytest.mark.parametrize("discrete", [False, True])
def test_large_damping_crossover_designs(damping, discrete):
    """The damping range (up to 1e6) designs: w_n = w_c sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2)
    cancelled (a damping of 1000: 'no gains put the crossover', 1e6: 'do not stabilise'), and the
    discrete search for w_n started three decades below w_c, above w_n ~ w_c / (2 zeta)."""
    table = design(cf2_spec(crossover={"hz": 0.5, "damping": damping}, **({"discrete": True} if discrete else {})))
    mag = magnitudes(table, [0.5])
    assert mag["angle"][0] == pytest.approx(mag["rate"][0], rel=1e-6)
    assert table.checks["stable"]
    if not discrete:
        k1, k2 = table.gains["k1"], table.gains["k2"]
        assert k1 / (2 * math.sqrt(k2)) == pytest.approx(damping, rel=1e-9)
    elif damping == 1e3:
        Kp = linear.gain_pair(table.F, table.K[0], table.gain_form)[0]
        # the closed-loop eigenvalues 1 + expm1(s_i T): s_i real, of damping -(s1 + s2) / (2 sqrt(s1 s2))
        s = np.log1p(np.linalg.eigvals((table.F - np.eye(2)) - Kp @ table.H)) / table.sample_time_s
        assert np.all(np.abs(s.imag) == 0)
        assert -s.real.sum() / (2 * math.sqrt(np.prod(s.real))) == pytest.approx(damping, rel=1e-6)


@pytest.mark.parametrize(("output", "hz", "damping"), [("posterior", 45.0, 300.0), ("prior", 20.0, 30.0)])
def test_discrete_damped_search_spans_both_the_continuous_w_n_and_w_c(output, hz, damping):
    """The search for w_n spans three decades around w_c and around the continuous w_n (~ w_c / (2
    zeta)): around w_c alone it missed the root of damping 300 at 45 Hz (of 100 Hz), around the
    continuous w_n alone that of damping 30 at 20 Hz for the prior output (w_n ~ 20 w_c)."""
    table = design(cf2_spec(crossover={"hz": hz, "damping": damping}, discrete=True, output=output))
    mag = magnitudes(table, [hz])
    assert mag["angle"][0] == pytest.approx(mag["rate"][0], rel=1e-6)
    assert table.checks["stable"]


@pytest.mark.parametrize("gain_form", ["predictor", "filter"])
def test_a_pole_within_rounding_of_z_1_is_named_not_called_unstable(gain_form):
    """A damping of 1e6 crossing over at 0.01 Hz at 1 kHz has its slow pole at 1.6e-14 rad/s,
    1.6e-17 of a step: e^(-s T) rounds to 1 and the design was refused as 'the gains ... do not
    stabilise cf2', which they do (the continuous design holds them). The refusal names the pole,
    the rounding and what to change."""
    spec = parse_spec({"structure": "cf2", "order": 2, "discrete": True, "gain_form": gain_form,
                       "crossover": {"hz": 0.01, "damping": 1e6},
                       "sensors": {"rate": {**GYRO, "rate_hz": 1000.0}, "angle": {**ANGLE, "rate_hz": 1000.0}}})
    with pytest.raises(SpecError, match=r"slowest closed-loop pole of cf2 \(order 2\) is 1.57e-14 rad/s .* "
                                        r"within double rounding of z = 1.*lower sample rate"):
        design(spec)
    assert design(cf2_spec(crossover={"hz": 0.01, "damping": 1e6})).checks["stable"]  # continuous: held
