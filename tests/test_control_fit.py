"""python-control fit: named transfer functions, Observer.from_statespace, GainTable.transfer_functions,
.bode and .observer."""

import numpy as np
import pytest
import sympy as sp

import cfdesign
from cfdesign.errors import GainTableError, StructureError
from cfdesign.symbolic import Observer, Sensor


@pytest.fixture(scope="module")
def dckf3():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))


def test_observer_transfer_functions_carry_the_sensor_names():
    tfs = cfdesign.transfer_functions(cfdesign.cf2(2).with_gains(k1=2, k2=1))
    assert tfs["angle"].input_labels == ["angle"] and tfs["angle"].output_labels == ["estimate"]
    assert tfs["rate"].name == "T_rate" and tfs["sum"].input_labels == ["quantity"]


def test_from_statespace_builds_the_same_observer():
    import control

    sensors = [Sensor.input("gyro", "rate", bias_state=1), Sensor.measurement("compass", "angle", 0)]
    K = sp.Matrix(sp.symbols("k1 k2"))
    obs = Observer.from_statespace(control.ss([[0, 1], [0, 0]], [[1], [0]], [[1, 0]], [[0]], name="heading"),
                                   K, sensors)
    assert obs.proof().holds and obs.name == "heading"
    assert sp.simplify(obs.bands["compass"] - cfdesign.cf2(2).bands["angle"]) == 0
    disc = Observer.from_statespace(control.ss([[1, 0.1], [0, 1]], [[0.1], [0]], [[1, 0]], [[0]], 0.1), K, sensors)
    assert disc.discrete and disc.sample_time == sp.Rational(1, 10) and disc.proof().holds
    with pytest.raises(StructureError, match="from_statespace"):
        Observer(control.ss([[0]], [[1]], [[1]], [[0]]), [[1]], [[1]], [[1]], sensors)
    with pytest.raises(StructureError, match=r"needs a control\.StateSpace"):
        Observer.from_statespace(control.tf([1], [1, 1]), K, sensors)
    with pytest.raises(StructureError, match="D must be zero"):
        Observer.from_statespace(control.ss([[0]], [[1]], [[1]], [[1]]), [[sp.Symbol("k")]], sensors[:1])


def test_gain_table_transfer_functions_observer_and_bode(dckf3):
    tfs = dckf3.transfer_functions()
    assert set(tfs) == {"gyro", "compass", "odometry", "sum"} and tfs["sum"].dcgain() == 1
    assert tfs["compass"].dt == dckf3.sample_time_s and tfs["compass"].input_labels == ["compass"]
    obs = dckf3.observer()
    assert obs.proof().holds
    w = np.logspace(-2, 0.5, 7)
    for name, tf in tfs.items():
        if name != "sum":
            num, den = obs.band_coefficients()[name]
            from cfdesign.linear import response

            assert np.allclose(tf(np.exp(1j * w * dckf3.sample_time_s)), response(num, den, w, dckf3.sample_time_s),
                               rtol=1e-8)
    fig = dckf3.bode(hz=True)
    assert "Hz" in fig.axes[-1].get_xlabel()


def test_multirate_table_bode_and_lifted_system():
    from cfdesign.plot import lifted_system

    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    sys = lifted_system(table)
    assert sys.dt == pytest.approx(table.period * table.sample_time_s)
    assert sys.input_labels == ["accelerometer", "gps"]
    assert np.allclose(np.abs(np.linalg.eigvals(sys.A)),
                       np.abs([complex(*p) for p in table.checks["monodromy_multipliers"]]))
    assert abs(sys[0, 1].dcgain()) == pytest.approx(1.0, rel=1e-9)  # a held GPS fix is the position
    fig = table.bode()
    assert len(fig.axes) == 2
    with pytest.raises(GainTableError, match="multirate"):
        table.transfer_functions()


def test_cli_bode_in_hz(cli, tmp_path):
    code, _, err = cli("bode", "cf2", "--order", "2", "--gains", "k1=2,k2=1", "--hz", "-o", tmp_path / "b.png")
    assert code == 0, err


def test_from_statespace_checks_named_signals_and_sensor_types():
    """A system whose signals carry names of their own must agree with the sensors; sensors that
    are not Sensor objects are a StructureError, not a raw TypeError or AttributeError."""
    import control

    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    k = [[sp.Symbol("k")]]
    named = control.ss([[0]], [[1]], [[1]], [[0]], inputs=["gyro"], outputs=["compass"], name="heading")
    assert Observer.from_statespace(named, k, sensors).proof().holds
    for inputs, outputs, wrong in ((["odometry"], ["compass"], "input 0 is named 'odometry'"),
                                   (["gyro"], ["magnetometer"], "output 0 is named 'magnetometer'")):
        sys = control.ss([[0]], [[1]], [[1]], [[0]], inputs=inputs, outputs=outputs)
        with pytest.raises(StructureError, match=wrong):
            Observer.from_statespace(sys, k, sensors)
    anonymous = control.ss([[0]], [[1]], [[1]], [[0]])  # python-control's u[0] / y[0]: any sensor names
    assert Observer.from_statespace(anonymous, k, sensors).proof().holds
    for bad in (None, "gyro", sensors[0], [("gyro", "rate")]):
        with pytest.raises(StructureError, match="sensors must be"):
            Observer.from_statespace(anonymous, k, bad)
        with pytest.raises(StructureError, match="sensors must be"):
            Observer([[0]], [[1]], [[1]], k, bad)


def test_cli_design_bode_of_a_multirate_table(cli, tmp_path):
    """design --bode draws what GainTable.bode draws for a multirate table (it was refused)."""
    code, _, err = cli("design", "--example", "position", "--bode", tmp_path / "p.png", "--hz")
    assert code == 0, err
    assert (tmp_path / "p.png").read_bytes().startswith(b"\x89PNG")


def test_bode_omega_is_rad_per_s_also_in_hz_and_titles_fit(dckf3):
    """omega is in rad/s whatever the axis unit (as control.bode_plot); a long table name is
    wrapped instead of clipped; multirate gains are labelled with the state names."""
    import dataclasses

    fig = dckf3.bode(omega=[0.1, 1.0, 2.0], hz=True)
    assert np.allclose(fig.axes[0].lines[0].get_xdata(), np.array([0.1, 1.0, 2.0]) / (2 * np.pi))
    long = dataclasses.replace(dckf3, name="a rather long table name " * 6)
    fig = long.bode()
    fig.canvas.draw()
    box = fig.axes[0].title.get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    labels = table.bode().axes[0].get_legend_handles_labels()[1]
    assert labels and {label.split(",")[0].removeprefix("K[") for label in labels} <= set(table.states)


def test_transfer_functions_warn_where_polynomials_lose_the_filter_and_bode_does_not():
    """A cf2 crossing over at 1e-4 Hz at 20 kHz: its poles lie within 2e-16 of z = 1, so the
    polynomial transfer functions lost the closed loop (|T_angle| / |T_rate| = 1.21 at the
    crossover where the filter has 1, by a 50-digit evaluation) and said nothing; the Bode plot
    drew those polynomials."""
    gyro = {"measures": "rate", "rate_hz": 2e4, "noise": {"density": 1.7e-4},
            "bias": {"model": "random_walk", "density": 2e-5}}
    angle = {"measures": "angle", "rate_hz": 2e4, "noise": {"std": 0.01}}
    table = cfdesign.design(cfdesign.spec.parse_spec({"structure": "cf2", "order": 2, "discrete": True,
                                                      "crossover": {"hz": 1e-4},
                                                      "sensors": {"rate": gyro, "angle": angle}}))
    with pytest.warns(RuntimeWarning, match="too close to z = 1"):
        table.transfer_functions()
    w = 2 * np.pi * 1e-4
    fig = table.bode(omega=[w / 10, w, w * 10])
    mags = {line.get_label(): line.get_ydata() for line in fig.axes[0].get_lines()}
    assert mags["T_angle"][1] == pytest.approx(mags["T_rate"][1], abs=1e-6)  # dB: equal at the crossover
    # the crossover the plot marks is refined on the state-space responses its grid holds: on the
    # polynomials, which have no sign change there, Brent's method raised 'f(a) and f(b) must
    # have different signs'
    fig = table.bode()
    marked = [line.get_xdata()[0] for line in fig.axes[0].get_lines() if line.get_marker() == "o"
              and len(line.get_xdata())]
    assert marked == [pytest.approx(w, rel=1e-6)]


def test_transfer_functions_of_ordinary_tables_do_not_warn(dckf3, recwarn):
    dckf3.transfer_functions()
    cfdesign.design(cfdesign.load_spec(cfdesign.example_path("tilt"))).transfer_functions()
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_complex_matrices_and_unreadable_gains_are_named():
    """A complex system matrix raised float()'s raw TypeError in from_statespace, and a complex F given to
    Observer was taken: its proof failed ('the bands do not sum to one') for no fault of the
    filter; sympy's multi-line reason for a gain that is no matrix is one line."""
    import control

    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    k = [[sp.Symbol("k")]]
    sys = control.ss([[0]], [[1]], [[1]], [[0]])
    sys.A = np.array([[1j]])  # control.ss refuses complex matrices; its attributes take them
    with pytest.raises(StructureError, match=r"A\[0\]\[0\] is complex"):
        Observer.from_statespace(sys, k, sensors)
    for F in ([[1j]], np.array([[2j]]), [[sp.I]]):
        with pytest.raises(StructureError, match=r"F\[0\]\[0\] is complex"):
            Observer(F, [[1]], [[1]], k, sensors)
    sys.A = np.array([[0j]])  # complex dtype, real values
    assert Observer.from_statespace(sys, k, sensors).proof().holds
    with pytest.raises(StructureError, match="K is not a matrix") as err:
        Observer([[0]], [[1]], [[1]], 1.0, sensors)
    assert "\n" not in str(err.value)


def test_filter_gain_form_of_a_continuous_observer_is_refused():
    """gain_form='filter' for a continuous system was dropped without a word (its K taken as the
    continuous gain), as a design file's is refused ('applies to discrete filters only')."""
    import control

    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)]
    sys = control.ss([[0]], [[1]], [[1]], [[0]])
    with pytest.raises(StructureError, match="'filter' applies to discrete observers only"):
        Observer.from_statespace(sys, [[0.5]], sensors, gain_form="filter")
    obs = Observer([[0]], [[1]], [[1]], [[sp.Symbol("k")]], sensors)
    with pytest.raises(StructureError, match="'filter' applies to discrete observers only"):
        obs.with_gain_matrix([[0.5]], gain_form="filter")
    assert Observer.from_statespace(control.c2d(sys, 0.1), [[0.5]], sensors, gain_form="filter").proof().holds


def test_band_functions_name_what_is_not_an_observer():
    """cfdesign.transfer_functions, bode_plot and frequency_response read their argument's
    attributes first: a python-control system, a gain table or None raised a raw AttributeError,
    and an observer with a symbolic sample time float()'s TypeError."""
    import control

    from cfdesign.analysis import frequency_response
    from cfdesign.errors import GainError

    table = cfdesign.design(cfdesign.load_spec(cfdesign.spec.example_path("tilt")))
    for fn in (cfdesign.transfer_functions, cfdesign.bode_plot, frequency_response):
        for arg, hint in ((control.tf([1], [1, 1]), "from_statespace"), (table, "table.transfer_functions"),
                          (None, "got NoneType")):
            with pytest.raises(StructureError, match=hint):
                fn(arg)
        with pytest.raises(GainError, match="substitute numbers first"):
            fn(cfdesign.dckf3())


@pytest.mark.parametrize("T", [0.013, 1 / 3, 0.07])
def test_from_statespace_proves_a_c2d_model_with_a_dlqe_gain(T):
    """A MIMO model sampled by control.c2d (B = 0.012999999999999999 at 0.013 s) with a numpy
    gain from control.dlqe: the bands sum to one exactly (they summed to X/X - 5.6e-17)."""
    import control

    sysd = control.c2d(control.ss([[0, -1], [0, 0]], [[1], [0]], [[1, 0], [1, 0]], [[0], [0]],
                                  inputs=["gyro"], outputs=["compass", "odometry"]), T)
    K = control.dlqe(sysd.A, np.eye(2), sysd.C, np.diag([1e-4, 1e-6]), np.diag([0.1, 0.2]))[0]
    sensors = [Sensor.input("gyro", "rate", bias_state=1), Sensor.measurement("compass", "angle", 0),
               Sensor.measurement("odometry", "angle", 1)]
    for form in ("predictor", "filter"):
        obs = Observer.from_statespace(sysd, K, sensors, gain_form=form)
        proof = obs.proof()
        assert proof.holds and proof.residual == 0
        assert float(obs.sample_time) == T
        tfs = cfdesign.transfer_functions(obs)
        assert tfs["odometry"].input_labels == ["odometry"] and tfs["sum"].dt == T


def test_float_gains_of_a_discrete_observer_are_exact():
    """numpy floats in any matrix are the decimals they print as, not sympy Floats whose rounding
    failed the exact proof of a discrete observer."""
    T = sp.Rational(1, 100)
    sensors = [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0),
               Sensor.measurement("odometry", "angle", 1)]
    K = np.array([[0.1, 0.2], [0.3, 0.05]])
    obs = Observer([[1, -T], [0, 1]], [[T], [0]], [[1, 0], [1, 0]], K, sensors, domain="z", sample_time=T)
    assert obs.K[0, 0] == sp.Rational(1, 10) and obs.proof().holds
    cont = Observer(np.array([[0.0]]), [[1]], [[1]], np.array([[2.0]]), sensors[:2])
    assert cont.bands["compass"] == 2 / (sp.Symbol("s") + 2)


def test_with_gains_takes_numpy_scalars():
    """np.float32 (a raw TypeError from Fraction) and 0-d arrays (refused) are real numbers."""
    for k in (np.float32(0.5), np.array(0.5), np.float64(0.5)):
        assert sp.simplify(cfdesign.cf2().with_gains(k=k).bands["angle"] - 1 / (2 * sp.Symbol("s") + 1)) == 0
    with pytest.raises(cfdesign.GainError, match="real number"):
        cfdesign.cf2().with_gains(k=np.array([0.5]))


@pytest.mark.parametrize("omega", ["abc", [[1.0, 2.0]], [], [1.0, np.nan], 5.0])
def test_a_frequency_grid_that_is_not_one_is_named(omega, dckf3):
    """Text gave numpy's raw ValueError, a matrix a broadcast error inside the plot."""
    from cfdesign.errors import InputError

    for call in (lambda: cfdesign.bode_plot(cfdesign.cf2().with_gains(k=2), omega=omega),
                 lambda: cfdesign.frequency_response(cfdesign.cf2().with_gains(k=2), omega=omega),
                 lambda: dckf3.bode(omega=omega)):
        with pytest.raises(InputError, match=r"omega must be a non-empty 1-D array of finite angular frequencies"):
            call()
    assert len(cfdesign.frequency_response(cfdesign.cf2().with_gains(k=2), omega=[0.1, 1.0]).omega) == 2


@pytest.mark.parametrize("omega", [[0.0], [0.0, 1.0, 10.0], [-1.0, 1.0], [1e300]])
def test_a_bode_diagram_refuses_frequencies_its_log_axis_cannot_hold(omega, dckf3):
    """0 gave matplotlib's raw 'Axis limits cannot be NaN or Inf' (a rate band is infinite there), a
    negative frequency was dropped from the plot without a word, 1e300 overflowed the continuous responses;
    frequency_response keeps 0 (the DC value of a band)."""
    from cfdesign.errors import InputError

    for call in (lambda: cfdesign.bode_plot(cfdesign.cf2().with_gains(k=2), omega=omega),
                 lambda: dckf3.bode(omega=omega)):
        with pytest.raises(InputError, match=r"frequencies must lie in \(0, 1e100\] rad/s"):
            call()
    resp = cfdesign.frequency_response(cfdesign.cf2().with_gains(k=2), omega=[0.0, 1.0])
    assert np.allclose(resp.bands["angle"][0], 1.0)
