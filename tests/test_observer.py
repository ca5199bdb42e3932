"""The engine itself: failing proofs, gain forms, substitution, errors, time-domain check."""

import numpy as np
import pytest
import sympy as sp
from scipy import signal

import cfdesign
from cfdesign import Observer, Sensor
from cfdesign.symbolic.observer import T, discrete_relation, z

DCKF3_GAINS = dict(k11=0.3, k12=0.2, k21=0.01, k22=0.02, T=0.2)


def test_inconsistent_observer_fails_the_proof():
    """B = [T/2, 0] does not match a rate sensor integrated over T: the proof must fail."""
    good = cfdesign.dckf3()
    bad = Observer(good.F, sp.Matrix([T / 2, 0]), good.H, good.K, good.sensors,
                   domain="z", name="dckf3 with wrong B")
    proof = bad.proof()
    assert proof.holds is False
    assert proof.residual != 0
    assert "FAILS" in proof.text()
    assert proof.to_dict()["holds"] is False


def test_wrong_declared_relation_fails_the_proof():
    """Declaring the gyro an angle sensor (order 0) breaks complementarity of CF3's model."""
    good = cfdesign.cf3()
    sensors = [Sensor.input("acceleration", "velocity"), *good.sensors[1:]]
    assert not Observer(good.F, good.B, good.H, good.K, sensors).proof().holds


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_discrete_gain_forms_both_complementary(form):
    d = cfdesign.dckf3()
    obs = Observer(d.F, d.B, d.H, d.K, d.sensors, domain="z", gain_form=form)
    assert obs.proof().holds


def test_filter_form_is_predictor_form_with_gain_F_K_up_to_the_update():
    """x-[k+1] = F x+ + B u with x+ = x- + K(y - H x-) has the predictor gain F K.

    docs/derivations.md, section "Gain forms"."""
    d = cfdesign.dckf3()
    filt = Observer(d.F, d.B, d.H, d.K, d.sensors, domain="z", gain_form="filter")
    pred = Observer(d.F, d.B, d.H, d.F * d.K, d.sensors, domain="z")
    assert sp.expand(filt.characteristic_polynomial - pred.characteristic_polynomial) == 0


def test_discrete_relation_zoh_chain():
    assert sp.simplify(discrete_relation(1, 1) - (z - 1) / T) == 0
    assert sp.simplify(discrete_relation(1, 2) - 2 * (z - 1) / (T * (z + 1))) == 0
    assert sp.simplify(discrete_relation(2, 2) - 2 * (z - 1) ** 2 / (T**2 * (z + 1))) == 0


def test_position_chain_is_complementary():
    """Vasconcelos et al.'s position filter: state [p, v, b_a], accelerometer input, GPS position."""
    F = sp.Matrix([[1, T, -T**2 / 2], [0, 1, -T], [0, 0, 1]])
    B = sp.Matrix([T**2 / 2, T, 0])
    K = sp.Matrix(sp.symbols("kp kv kb"))
    obs = Observer(F, B, sp.Matrix([[1, 0, 0]]), K,
                   [Sensor.input("accelerometer", "acceleration"), Sensor.measurement("gps", "position", 0)],
                   domain="z")
    assert obs.proof().holds


def test_subs_is_exact_and_checked():
    num = cfdesign.dckf3().with_gains(DCKF3_GAINS)
    assert num.is_numeric and num.sample_time == sp.Rational(1, 5)
    assert num.proof().holds
    with pytest.raises(cfdesign.GainError, match="k33"):
        cfdesign.dckf3().subs(k33=1)
    with pytest.raises(cfdesign.GainError, match="needs a value for k22"):
        cfdesign.dckf3().with_gains(k11=1, k12=1, k21=1, T=1)
    with pytest.raises(cfdesign.GainError, match="positive"):
        cfdesign.dckf3().subs(T=0)
    with pytest.raises(cfdesign.GainError, match="finite"):
        cfdesign.cf3().subs(k1=float("nan"))
    with pytest.raises(cfdesign.GainError, match="real number"):
        cfdesign.cf3().subs(k1="2")


@pytest.mark.parametrize("entry, error, message", [
    (float("nan"), cfdesign.GainError, r"K\[0\]\[0\] must be finite"),
    (float("inf"), cfdesign.GainError, "must be finite"),
    ("k1", cfdesign.StructureError, "text is never evaluated"),
    ("__import__('os')", cfdesign.StructureError, "text is never evaluated"),
])
def test_observer_matrices_refuse_text_and_non_finite_entries(entry, error, message):
    """A NaN gain gave an observer whose proof said 'not complementary'; text was sympified
    (evaluated: ``"__import__('os')"`` became the os module), where subs refuses both."""
    import control

    c = cfdesign.cf3()
    with pytest.raises(error, match=message):
        Observer(c.F, c.B, c.H, [[entry, 0], [0, 1]], c.sensors)
    sys = control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0], [0, 1]], [[0], [0]])
    sensors = [Sensor.input("acc", "acceleration"), Sensor.measurement("gps", "position", 0),
               Sensor.measurement("wheel", "velocity", 1)]
    with pytest.raises(error, match=message):
        Observer.from_statespace(sys, np.array([[entry, 0], [0, 1]], dtype=object), sensors)


def test_partial_substitution_keeps_proof_symbolic():
    obs = cfdesign.dckf3().subs(T=0.1)
    assert [p.name for p in obs.parameters] == ["k11", "k12", "k21", "k22"]
    assert obs.proof().holds


def test_structure_errors_name_the_problem():
    c = cfdesign.cf3()
    with pytest.raises(cfdesign.StructureError, match="K must be 2x2"):
        Observer(c.F, c.B, c.H, sp.ones(2, 3), c.sensors)
    with pytest.raises(cfdesign.StructureError, match="row of H"):
        Observer(c.F, c.B, c.H, c.K, c.sensors[:2])
    with pytest.raises(cfdesign.StructureError, match="duplicate"):
        Observer(c.F, c.B, c.H, c.K, [c.sensors[0], Sensor.measurement("acceleration", 1, 1),
                                     c.sensors[2]])
    with pytest.raises(cfdesign.StructureError, match="identifier"):
        Sensor.input("gyro rate", "rate")
    with pytest.raises(cfdesign.StructureError, match="unknown sensor quantity"):
        Sensor.input("gyro", "spin")
    with pytest.raises(cfdesign.StructureError, match="never evaluated"):
        _ = Observer(c.F, c.B, c.H, c.K, [Sensor.input("acceleration", 2, relation="s**2"), *c.sensors[1:]]).bands
    with pytest.raises(cfdesign.StructureError, match="unknown structure"):
        cfdesign.structure("cf4")


def test_numeric_poles_and_band_coefficients():
    num = cfdesign.dckf3().with_gains(DCKF3_GAINS)
    den = [1, 0.3 + 0.2 - 2, 1 - 0.3 - 0.2 + 0.2 * 0.01 + 0.2 * 0.02]
    assert np.allclose(sorted(complex(p).real for p in num.poles()), sorted(np.roots(den).real))
    coeffs = num.band_coefficients()
    assert np.allclose(coeffs["compass"][0], [0.3, -0.3 + 0.2 * 0.01])
    assert np.allclose(coeffs["compass"][1], den)
    with pytest.raises(cfdesign.GainError, match="symbolic parameters"):
        cfdesign.dckf3().band_coefficients()


def test_poles_of_quintic_need_numbers():
    with pytest.raises(cfdesign.ProofError, match="substitute numbers"):
        cfdesign.cfn(6).poles()
    num = cfdesign.cfn(6).with_gains(k1=5, k2=10, k3=10, k4=5, k5=1)  # (s + 1)^5
    assert np.allclose([complex(p) for p in num.poles()], -1, atol=1e-2)


def test_time_domain_run_equals_band_filters():
    """Run the predictor recursion of DCKF3 on exact sensor signals: estimate == truth,
    and each sensor alone through lfilter(band) sums to the same estimate."""
    g = DCKF3_GAINS
    Tn = g["T"]
    F = np.array([[1, Tn], [0, 1]])
    B = np.array([Tn, 0])
    H = np.array([[1, 0], [1, 0]])
    K = np.array([[g["k11"], g["k12"]], [g["k21"], g["k22"]]])
    t = np.arange(2000) * Tn
    psi = np.sin(0.3 * t) + 0.5 * np.sin(1.7 * t + 1)
    omega = np.diff(psi) / Tn  # the rate that integrates exactly to psi over one step
    x = np.array([psi[0], 0.0])
    est = np.empty(len(omega))
    for k in range(len(omega)):
        est[k] = x[0]
        x = F @ x + B * omega[k] + K @ (np.array([psi[k], psi[k]]) - H @ x)
    assert np.max(np.abs(est[-500:] - psi[:-1][-500:])) < 1e-9
    coeffs = cfdesign.dckf3().with_gains(g).band_coefficients()
    parts = 0
    for num, den in coeffs.values():  # powers of z -> powers of z^-1: pad the numerator
        parts = parts + signal.lfilter(np.r_[np.zeros(len(den) - len(num)), num], den, psi)
    assert np.max(np.abs(parts[-500:] - psi[-500:])) < 1e-9


def test_continuous_observer_may_use_a_symbol_named_T():
    tau = sp.Symbol("T", positive=True)  # the same symbol the discrete filters use
    obs = Observer([[-1 / tau]], [[1]], [[1]], [[sp.Symbol("k")]],
                   [Sensor.input("rate", "rate"), Sensor.measurement("angle", "angle", 0)])
    assert {p.name for p in obs.parameters} == {"k", "T"}
    assert not obs.with_gains(k=1, T=2).parameters


def test_design_with_bad_bode_path_writes_nothing(tmp_path, cli):
    out = tmp_path / "g.json"
    code, _, _ = cli("design", "-o", out, "--bode", tmp_path / "missing" / "b.png")
    assert code == 2 and not out.exists()


@pytest.mark.parametrize("form", ["predictor", "filter"])
@pytest.mark.parametrize("assumptions", [{}, {"real": True}, {"positive": True}])
def test_a_users_own_symbol_T_is_the_sample_time(form, assumptions):
    """The docstring calls the default sample time "the symbol T": a discrete observer written with
    ``sp.Symbol("T")`` (not the engine's ``T``, which is positive) proved FAILS with a ``sum - 1``
    that printed as ``(T*z - T - T*z + T)/...``, two different symbols of one name."""
    k, t = sp.Symbol("k"), sp.Symbol("T", **assumptions)
    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    obs = Observer([[1]], [[t]], [[1]], [[k]], sensors, domain="z", gain_form=form)
    assert obs.proof().holds and obs.proof().residual == 0
    assert obs.sample_time == t and obs.with_gains(k=sp.Rational(1, 2), T=sp.Rational(1, 10)).proof().holds


def test_two_symbols_of_the_sample_times_name_are_refused():
    k, mine = sp.Symbol("k"), sp.Symbol("T", real=True)
    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    with pytest.raises(cfdesign.errors.StructureError, match="symbol T"):
        Observer([[1]], [[mine]], [[1]], [[k]], sensors, domain="z", sample_time=sp.Symbol("T"))
    with pytest.raises(cfdesign.errors.StructureError, match="symbol T"):
        Observer([[1]], [[mine]], [[1]], [[k * T]], sensors, domain="z")


def _canonical_residual(obs):
    """sum_i T_i - 1 brought to lowest terms band by band: the proof as it was first written."""
    return sp.cancel(sp.together(sum(obs.bands.values()) - 1))


def _observers():
    from cfdesign.symbolic.filters import chain

    d, c3 = cfdesign.dckf3(), cfdesign.cf3()
    yield from (cfdesign.cf2(), cfdesign.cf2(order=2), c3, cfdesign.ckf3(), d, cfdesign.cfn(4),
                cfdesign.cfn(3, full=True, discrete=True), cfdesign.dckf3().subs(**DCKF3_GAINS),
                Observer(d.F, d.B, d.H, d.K, d.sensors, domain="z", gain_form="filter"),
                chain(2, ["acc_a", "acc_b"], [("pos", 0), ("vel", 1)], bias=True, discrete=True))
    # two that fail: an input matrix the relations do not follow, a measurement read as the wrong order
    yield Observer(d.F, sp.Matrix([T / 2, 0]), d.H, d.K, d.sensors, domain="z", name="wrong B")
    yield Observer(c3.F, c3.B, c3.H, c3.K, [Sensor.input("acceleration", "velocity"), *c3.sensors[1:]])


@pytest.mark.parametrize("obs", list(_observers()), ids=lambda o: o.name)
def test_the_gain_free_proof_and_the_numerator_agree_with_the_bands_in_lowest_terms(obs):
    """The proof decides with a check free of the gains (the relations are a trajectory of the
    model) and the numerator of sum - 1 over the common denominator; both must agree with the
    canonical sum of the bands, holding and failing alike."""
    holds = _canonical_residual(obs) == 0
    assert obs.proof().holds is holds
    assert (obs.residual_numerator == 0) is holds
    assert obs.relations_follow_the_model is holds  # (for these; in general it only suffices)
    if holds:
        assert obs.proof().total == 1 and dict(obs.proof().bands) == obs.bands


def test_a_long_chain_with_many_gains_proves_and_designs():
    """An order-3 chain with a biased jerk input and position, velocity and acceleration
    sensors (12 symbolic gains): the proof reduced every band to lowest terms and ran for
    minutes (cfdesign design never finished); the gain-free check proves it at once."""
    from cfdesign.designer import design
    from cfdesign.spec import parse_spec
    from cfdesign.symbolic.filters import chain

    obs = chain(3, ["jerk"], [("p", 0), ("v", 1), ("a", 2)], bias=True, discrete=True)
    assert len(obs.gains) == 12 and obs.proof().holds
    sensors = {"jerk": {"measures": "jerk", "rate_hz": 50.0, "noise": {"std": 0.03},
                        "bias": {"model": "random_walk", "density": 1e-3}},
               **{n: {"measures": q, "rate_hz": 50.0, "noise": {"std": 0.01}}
                  for n, q in (("p", "position"), ("v", "velocity"), ("a", "acceleration"))}}
    table = design(parse_spec({"structure": "chain", "order": 3, "discrete": True, "sensors": sensors}))
    assert table.checks["complementary"] is True and table.checks["stable"] is True


@pytest.mark.parametrize("seed", range(8))
def test_the_gain_free_check_is_sound_on_random_observers(seed):
    """Random two-state observers with symbolic gains, their relations derived from the model
    (X = (vI - F)^-1 B D_u normalised so that C X = 1, D_j = H_j X) and then, in odd seeds, one
    relation spoilt: the gain-free check says True only where the canonical sum of the bands is
    exactly one, and the numerator route agrees with the canonical sum either way."""
    rng = np.random.default_rng(seed)
    discrete = seed % 4 >= 2
    v = z if discrete else sp.Symbol("s")
    F = sp.Matrix(rng.integers(-2, 3, (2, 2)).tolist())
    B = sp.Matrix([int(rng.integers(-2, 3)), int(rng.integers(1, 3))])
    C = sp.Matrix([[1, int(rng.integers(0, 2))]])
    H = sp.eye(2) if seed % 3 else sp.Matrix([[1, 1]])
    drive = v - 1 if discrete else v  # the input reads a rate (a difference when discrete)
    X = (v * sp.eye(2) - F).LUsolve(B * drive)
    scale = sp.cancel((C * X)[0, 0])  # the common quantity C X, made one below
    assert scale != 0
    X = (X / scale).applyfunc(sp.cancel)
    relations = [sp.cancel((H[j, :] * X)[0, 0]) for j in range(H.rows)]
    if seed % 2:
        relations[0] = sp.cancel(relations[0] * (v + 2) / (v + 3))
    K = sp.Matrix(2, H.rows, lambda i, j: sp.Symbol(f"k{i + 1}{j + 1}"))
    sensors = [Sensor.input("u", "rate", relation=sp.cancel(drive / scale)),
               *(Sensor.measurement(f"y{j}", "angle", j, relation=r) for j, r in enumerate(relations))]
    obs = Observer(F, B, H, K, sensors, domain="z" if discrete else "s", output=C,
                   **({"sample_time": sp.Rational(1, 10)} if discrete else {}))
    holds = _canonical_residual(obs) == 0
    assert obs.relations_follow_the_model is (seed % 2 == 0)
    assert holds is (seed % 2 == 0) and obs.proof().holds is holds
    assert (obs.residual_numerator == 0) is holds


def test_values_by_symbol_and_exact_decimal():
    """A dict keyed by the observer's own sympy symbols (``{k11: 0.3}``) was told 'needs a value
    for k11'; a Decimal was 'not a real number'.  Both give the poles of the same numbers by name."""
    from decimal import Decimal

    f = cfdesign.dckf3()
    by_name = f.with_gains(**DCKF3_GAINS)
    by_symbol = f.with_gains({f.symbol(k): v for k, v in DCKF3_GAINS.items() if k != "T"}, T=0.2)
    assert by_symbol.K == by_name.K and by_symbol.sample_time == by_name.sample_time
    exact = f.with_gains({**DCKF3_GAINS, "k11": Decimal("0.3"), "T": Decimal("0.2")})
    assert exact.K == by_name.K and exact.sample_time == sp.Rational(1, 5)
    for bad, said in ((2, "give the values by name"), ({1: 2}, "named by its name"),
                      ({**DCKF3_GAINS, "k11": Decimal("NaN")}, "k11 must be finite")):
        with pytest.raises(cfdesign.GainError, match=said):
            f.with_gains(bad)
    with pytest.raises(cfdesign.GainError, match="k11 is given twice"):
        f.with_gains({f.symbol("k11"): 0.3}, **DCKF3_GAINS)


def test_gain_matrix_and_model_shapes_are_told():
    """A ragged, 1-D or scalar gain matrix raised raw ValueError/TypeError; H's wrong width read
    'H must be Nonex1'; numeric_model(0) gave B = 0 without a word."""
    f = cfdesign.ckf3()
    for K in ([[1, 2], [3]], np.array([1.0, 2.0]), 2.0):
        with pytest.raises(cfdesign.StructureError, match=r"^K "):
            f.with_gain_matrix(K)
    with pytest.raises(cfdesign.GainError, match="must be a real number"):
        f.with_gain_matrix([[sp.Symbol("a"), 0], [0, 1]])
    assert f.with_gain_matrix(np.array([[1, 2], [3, 4.0]])).K == sp.Matrix([[1, 2], [3, 4]])
    with pytest.raises(cfdesign.StructureError, match=r"H must be \(measurements\)x1: one column per state, got 1x2"):
        Observer([[0]], [[1]], [[1, 0]], [[1]], [Sensor.input("g", "rate"), Sensor.measurement("c", "angle", 0)])
    for bad in (0, -0.1):
        with pytest.raises(cfdesign.GainError, match="sample time must be positive"):
            cfdesign.dckf3().numeric_model(bad)


@pytest.mark.parametrize("build, message", [
    (lambda S: Observer(np.zeros((1, 1, 1)), [[1]], [[1]], [[1]], S), r"F must be a matrix \(2-D\), got an array"),
    (lambda S: Observer(np.array([[True]]), [[1]], [[1]], [[1]], S), "F holds a bool"),
    (lambda S: Observer([[0]], [[1]], [[1]], [[True]], S), "K holds a bool"),
    (lambda S: Observer([[0]], [[1]], [[1]], np.array([[True]], dtype=object), S), "K holds a bool"),
    (lambda S: Observer([[0]], [[1]], [[sp.true]], [[1]], S), "H holds a bool"),
    (lambda S: Observer({"a": 1}, [[1]], [[1]], [[1]], S), "F is a dict, not a matrix"),
    (lambda S: Observer([[0]], [[1], [2]], [[1]], [[1]], S), r"B must be 1x\(inputs\): one row per state, got 2x1"),
    (lambda S: Observer([[0]], [[1]], [[1]], [[1]], S, name=3), "name must be text"),
    (lambda S: Sensor.input("gyro", "rate", bias_state="x"), "bias_state must be a state index"),
    (lambda S: Sensor.input("gyro", "rate", bias_state=-1), "bias_state must be a state index"),
])
def test_bad_matrices_and_sensors_are_named(build, message):
    """A 3-D array raised sympy's NotImplementedError, a bool entry sympy's 'BooleanAtom not allowed'
    at the bands (after a deprecation warning), bias_state='x' a raw TypeError and bias_state=-1
    put the bias on the last state; B's wrong height read 'B must be 1xNone'."""
    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    with pytest.raises(cfdesign.StructureError, match=message):
        build(sensors)


def test_repr_gives_the_sample_time_in_seconds():
    """The repr read 'T=1/5' (no unit) for a numeric sample time and 'T=T' for a symbolic one."""
    assert "T = 0.2 s," in repr(cfdesign.dckf3().subs(T=0.2))
    assert "T = T (symbolic)" in repr(cfdesign.dckf3())
    assert "continuous;" in repr(cfdesign.cf3())


def test_a_list_of_sympy_rows_is_a_matrix():
    """sympy stacks a list of row matrices into one matrix; the check for arrays of more than 2
    dimensions took numpy's view of it (shape 2x1x2) and refused it."""
    k1, k2 = sp.symbols("k1 k2")
    rows = [sp.Matrix([[k1, 0]]), sp.Matrix([[k2, 1]])]
    obs = cfdesign.dckf3()
    built = Observer(obs.F, obs.B, obs.H, rows, obs.sensors, domain="z", sample_time=obs.sample_time)
    assert built.K == sp.Matrix([[k1, 0], [k2, 1]])
