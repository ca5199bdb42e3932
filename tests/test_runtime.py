"""Python runtime: streaming equals batch, save/restore, missing readings, wrap-around."""

import subprocess
import sys
from decimal import Decimal

import numpy as np
import pytest

import cfdesign
from cfdesign.errors import CfdesignError
from cfdesign.runtime import Runtime, wrap


@pytest.fixture(scope="module")
def heading():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))


@pytest.fixture(scope="module")
def position():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))


def readings(table, N, seed=0, amplitude=0.3):
    rng = np.random.default_rng(seed)
    t = np.arange(N)
    return {s.name: amplitude * rng.normal(size=N) + np.sin(0.002 * t) for s in table.sensors}


def stream(table, data, x0=None):
    rt = Runtime(table, x0=x0)
    names = list(data)
    N = len(data[names[0]])
    return np.array([rt.step(**{n: data[n][k] for n in names}) for k in range(N)]), rt


def test_runtime_does_not_import_sympy_or_scipy(heading, tmp_path):
    """Loading a saved table and stepping it (the runtime path) imports numpy only: no scipy, sympy,
    python-control or matplotlib."""
    heading.save(tmp_path / "gains.json")
    code = ("import sys, math, cfdesign\n"
            "from cfdesign.runtime import Runtime\n"
            f"rt = Runtime(cfdesign.load_gains({str(tmp_path / 'gains.json')!r}))\n"
            "x = [rt.step(gyro=0.01, compass=0.3, odometry=0.3) for _ in range(5)]\n"
            "assert all(math.isfinite(e) for e in x), x\n"
            "heavy = [m for m in ('scipy', 'sympy', 'control', 'matplotlib') if m in sys.modules]\n"
            "assert not heavy, heavy\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
@pytest.mark.parametrize("name", ["heading", "position"])
def test_batch_equals_streaming(name, request):
    table = request.getfixturevalue(name)
    data = readings(table, 3000)
    x0 = np.full(table.F.shape[0], 0.1)
    est_stream, rt_stream = stream(table, data, x0)
    rt = Runtime(table, x0=x0)
    est = rt.run(data)
    assert np.max(np.abs(est - est_stream)) < 1e-9
    assert np.max(np.abs(rt.x - rt_stream.x)) < 1e-9 and rt.phase == rt_stream.phase
    est2, xs = Runtime(table, x0=x0).run(data, states=True)  # the blocked path
    assert np.max(np.abs(est2 - est_stream)) < 1e-9 and xs.shape == (3000, table.F.shape[0])


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_both_gain_forms_run_their_recursion_and_output_both_estimates(form):
    spec = cfdesign.load_spec(cfdesign.example_path("dckf3"))
    import dataclasses

    table = cfdesign.design(dataclasses.replace(spec, gain_form=form, wrap_angle=False))
    assert table.output == "posterior"  # the default of designed tables, whatever the gain form
    data = readings(table, 500)
    est_stream, _ = stream(table, data)
    assert np.max(np.abs(Runtime(table).run(data) - est_stream)) < 1e-10
    # one step by hand, in the gain form as the paper writes it
    x = np.array([0.3, -0.01])
    innov = np.array([0.5, 0.45]) - table.H @ x
    K = table.K[0]
    if form == "filter":  # x+ = x + K e; x[k+1] = F x+ + B u
        post = x + K @ innov
        nxt = table.F @ post + table.B[:, 0] * 0.1
    else:  # x[k+1] = F x + B u + K e; the estimate after the readings: x + F^-1 K e
        post = x + np.linalg.solve(table.F, K) @ innov
        nxt = table.F @ x + table.B[:, 0] * 0.1 + K @ innov
    for output, expected in (("posterior", post[0]), ("prior", x[0])):
        rt = Runtime(table, output=output)
        rt.x = x.copy()
        assert rt.step(gyro=0.1, compass=0.5, odometry=0.45) == pytest.approx(expected, abs=1e-15)
        assert np.allclose(rt.x, nxt, atol=1e-15)
    assert Runtime(table).output == "posterior"


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
def test_split_run_with_restore_equals_one_run(position):
    data = readings(position, 2000)
    whole = Runtime(position).run(data)
    first = Runtime(position)
    a = first.run({k: v[:777] for k, v in data.items()})
    saved = first.state()
    second = Runtime(position)
    second.restore(saved)
    b = second.run({k: v[777:] for k, v in data.items()})
    assert np.max(np.abs(np.concatenate([a, b]) - whole)) < 1e-9


def test_restore_refuses_a_state_of_another_filter_of_the_same_shape(heading):
    """dckf3 and robot-heading both have 2 states, 1 input, period 1: the sizes cannot tell their
    states apart; the snapshot names its filter and restore refuses it, naming both tables."""
    import json

    other = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    rt = Runtime(heading)
    rt.step(gyro=0.1, compass=0.2, odometry=0.3)
    saved = json.loads(json.dumps(rt.state()))                     # across JSON
    target = Runtime(other)
    with pytest.raises(CfdesignError, match=r"state does not fit robot heading .*taken from another filter, "
                                            r"'robot heading \(Carreira et al. DCKF3"):
        target.restore(saved)
    assert target.state()["x"] == [0.0, 0.0]                       # unchanged
    renamed = cfdesign.GainTable.from_dict({**heading.to_dict(), "name": "renamed"})
    same = Runtime(renamed, output="prior")                         # the same filter: name and output do not matter
    same.restore(saved)
    assert same.state()["x"] == saved["x"] and same.step(gyro=0.1) == rt.step(gyro=0.1)
    legacy = {k: saved[k] for k in ("x", "phase", "u_last")}        # a snapshot of an earlier cfdesign: sizes only
    Runtime(other).restore(legacy)


def test_missing_readings_skip_the_update_and_hold_the_input(heading):
    data = readings(heading, 400)
    data["compass"][::3] = np.nan
    data["gyro"][5] = np.nan
    est, _rt = stream(heading, data)
    assert np.all(np.isfinite(est))
    batch = Runtime(heading).run(data)  # NaN -> the general loop
    assert np.max(np.abs(batch - est)) < 1e-12
    # a step with no compass and no odometry is pure prediction
    rt2 = Runtime(heading)
    rt2.x = np.array([0.2, 0.01])
    rt2.step(gyro=0.5)
    assert np.allclose(rt2.x, heading.F @ [0.2, 0.01] + heading.B[:, 0] * 0.5)


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
def test_multirate_readings_between_fixes_have_no_effect(position):
    data = readings(position, 200)
    a = Runtime(position).run(data)
    data["gps"][np.arange(200) % 50 != 0] = 1e6  # garbage at phases with zero gain
    b = Runtime(position).run(data)
    assert np.array_equal(a, b) or np.max(np.abs(a - b)) < 1e-9


def test_heading_crossing_pi_does_not_jolt(heading):
    N = 3000
    truth = wrap(np.linspace(2.5, 4.0, N))  # crosses +pi -> -pi
    T = heading.sample_time_s
    rate = np.gradient(np.unwrap(truth), T)
    data = {"gyro": rate, "compass": truth, "odometry": truth}
    x0 = [truth[0], 0.0]
    for est in (stream(heading, data, x0)[0], Runtime(heading, x0=x0).run(data)):
        err = wrap(est - truth)
        assert np.max(np.abs(err)) < 1e-3
        assert np.all((est > -np.pi) & (est <= np.pi))


def test_ten_million_samples_stay_bounded(heading):
    rng = np.random.default_rng(1)
    N = 10_000_000
    rt = Runtime(heading)
    worst = 0.0
    for _ in range(10):  # streamed in blocks of one million, state carried
        n = N // 10
        data = {"gyro": 0.05 * rng.standard_normal(n), "compass": 0.05 * rng.standard_normal(n),
                "odometry": 0.002 * rng.standard_normal(n)}
        est = rt.run(data)
        assert np.all(np.isfinite(est))
        worst = max(worst, np.abs(est).max())
    assert worst < 1.0 and np.all(np.isfinite(rt.x))


@pytest.mark.parametrize("bad", ["0.1", None, 1j, np.array([1.0, 2.0]), Decimal("0.1")])
@pytest.mark.parametrize("sensor", ["gyro", "odometry"])
def test_a_reading_that_is_no_number_is_named_and_changes_nothing(heading, sensor, bad):
    """The step compares every reading before it stores anything: an input held from the step
    that failed, or a count, would otherwise change what the next step computes."""
    rt = Runtime(heading)
    rt.step(gyro=0.3, compass=0.2, odometry=0.1)
    before = rt.state()
    with pytest.raises(CfdesignError, match=f"^{sensor}: reading .* is not a number"):
        rt.step(**{"gyro": 0.9, "compass": 0.4, "odometry": 0.5, sensor: bad})
    with pytest.raises(CfdesignError, match="is not a number"):
        rt.step_values(*[bad if name == sensor else 0.5 for name in ("gyro", "compass", "odometry")])
    assert rt.state() == before and rt.counts == {}


@pytest.mark.parametrize("kind", [np.float64, np.float32, np.int64, np.array, int])
def test_numpy_scalar_readings_keep_the_state_in_python_floats(heading, kind):
    """Readings taken from numpy arrays (np.float64, np.float32, a 0-d array) are used by their value:
    the state, held inputs and estimates stay Python floats.  A numpy scalar used to enter the state,
    so every later step computed in numpy scalars (2.5x slower) and, for float32, in single precision."""
    values = [(0.31, 0.2, 0.21), (-0.5, 1.0, 2.0), (3.0, -2.0, 1.0)]
    if kind in (np.int64, int):
        values = [tuple(round(v) for v in row) for row in values]
    rt, ref = Runtime(heading), Runtime(heading)
    for row in values * 3:
        got = rt.step(**dict(zip(("gyro", "compass", "odometry"), map(kind, row), strict=True)))
        want = ref.step(**dict(zip(("gyro", "compass", "odometry"), (float(kind(v)) for v in row), strict=True)))
        assert type(got) is float and got == want
    assert all(type(v) is float for v in rt._S[:2]) and rt.state() == ref.state()


def test_arrays_and_huge_integers_as_readings(heading):
    rt = Runtime(heading)
    with pytest.raises(CfdesignError, match=r"^compass: reading array"):
        rt.step(gyro=0.1, compass=np.array([0.2]), odometry=0.2)  # one value in an array: not a reading
    assert rt.state()["x"] == [0.0, 0.0]
    rt.step(gyro=10**400, compass=-(10**400), odometry=0.2)  # beyond the limit: rejected, counted
    assert rt.counts == {"rejected": {"gyro": 1, "compass": 1}} and all(type(v) is float for v in rt._S[:2])


def test_bad_inputs(heading):
    rt = Runtime(heading)
    with pytest.raises(CfdesignError, match="unknown sensor"):
        rt.step(gyro=1.0, baro=2.0)
    with pytest.raises(CfdesignError, match="no readings for odometry"):
        rt.run({"gyro": [1.0], "compass": [1.0]})
    with pytest.raises(CfdesignError, match="differ in length"):
        rt.run({"gyro": [1.0, 2.0], "compass": [1.0], "odometry": [1.0]})
    with pytest.raises(CfdesignError, match="state does not fit"):
        rt.restore({"x": [1.0], "phase": 0, "u_last": [0.0]})
    continuous = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("ckf3")))
    with pytest.raises(CfdesignError, match="continuous-time"):
        Runtime(continuous)


@pytest.mark.parametrize("crossings", [1, 3, 50])
def test_sparse_unwrap_equals_numpy(crossings):
    from cfdesign.runtime.filter import _unwrap

    rng = np.random.default_rng(crossings)
    angle = np.cumsum(rng.normal(0, 0.05, 20000)) + np.linspace(0, 2 * np.pi * crossings, 20000)
    wrapped = wrap(angle)
    assert np.allclose(_unwrap(wrapped, wrapped[0]), np.unwrap(wrapped), rtol=0, atol=1e-12)
    # the first reading brought within pi of the estimate: every reading moves by the same turns
    assert np.allclose(_unwrap(wrapped, wrapped[0] + 4 * np.pi), np.unwrap(wrapped) + 4 * np.pi, rtol=0, atol=1e-12)


def test_step_adds_no_correction_to_a_state_no_gain_reaches(heading):
    """A state no gain corrects at any phase is advanced by ``F x + B u`` alone: its line of the
    compiled step has no correction term (it added 0.0, about 5 % of a 6-state chain's step), and
    the step is still the recursion the batch path runs."""
    import dataclasses

    K = np.array(heading.K[0], dtype=float)
    K[1] = 0.0  # the gyro correction: dead reckoning
    table = dataclasses.replace(heading, K=[K])
    rt = Runtime(table)
    line = next(ln.strip() for ln in rt.step_source.splitlines() if ln.strip().startswith("n1 = "))
    assert "e0" not in line and "e1" not in line and "0.0" not in line, line
    data = readings(table, 500)
    est, rt = stream(table, data, x0=[0.1, 0.01])
    batch = Runtime(table, x0=[0.1, 0.01])
    assert np.max(np.abs(wrap(batch.run(data) - est))) < 1e-9 and np.max(np.abs(batch.x - rt.x)) < 1e-9


@pytest.mark.parametrize("names", [("unknown", "PI", "u0"), ("U", "S", "LIM"), ("x0", "e0", "est"),
                                   ("OverflowError", "float", "type")])
def test_step_takes_sensors_named_like_its_own_variables(heading, names):
    """Sensor names are any identifiers: the compiled step's own names (S, U, PI, LIM, u0,
    unknown, ...) and the builtins it uses (OverflowError: a sensor of that name made an int
    reading too large for a float raise TypeError) move out of their way instead of being
    shadowed or clashing."""
    import dataclasses

    old = [s.name for s in heading.sensors]
    ports = tuple(dataclasses.replace(s, name=new) for s, new in zip(heading.sensors, names, strict=True))
    measured = tuple(names[old.index(m)] for m in heading.schedule.measurements)
    renamed = dataclasses.replace(heading, sensors=ports,
                                  schedule=dataclasses.replace(heading.schedule, measurements=measured))
    data = readings(heading, 300)
    data["compass"] = wrap(data["compass"] + 3.0)  # innovations across +-pi: the wrap is exercised
    expected, _ = stream(heading, data)
    got, rt = stream(renamed, {new: data[o] for o, new in zip(old, names, strict=True)})
    assert np.array_equal(got, expected)
    rt.step(**dict.fromkeys(names, 10**400))                      # too large for a float: rejected, counted
    assert rt.counts == {"rejected": dict.fromkeys(names, 1)}


def test_iir_path_on_runs_shorter_than_the_filter_equals_streaming():
    """The IIR path runs one recursion on the sum of the bands' numerator outputs and forms the
    final state from the last readings; a run of fewer readings than the filter has states
    (readings before it count as zero) must still hand the next run the recursion's state."""
    from cfdesign.runtime.filter import _LtiBands

    spec = cfdesign.spec.parse_spec({"name": "p", "structure": "position", "gain_form": "filter", "sensors": {
        "accelerometer": {"rate_hz": 1.0, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-4}},
        "gps": {"rate_hz": 1.0, "noise": {"std": 2.0}}}})
    table = cfdesign.design(spec)
    assert _LtiBands.of(Runtime(table)) is not None and table.F.shape == (3, 3)  # the path under test
    rng = np.random.default_rng(4)
    N = 40
    data = {s.name: np.sin(0.1 * np.arange(N)) + 0.1 * rng.standard_normal(N) for s in table.sensors}
    x0 = [0.5, -0.2, 0.01]
    expected, rt = stream(table, data, x0)
    batch, est, start = Runtime(table, x0=x0), [], 0
    for length in [1, 2, 3, 4, 1, 1, 5, 2, 21]:  # pieces shorter than, equal to and longer than n = 3
        est.append(batch.run({k: v[start:start + length] for k, v in data.items()}))
        start += length
    assert start == N
    assert np.max(np.abs(np.concatenate(est) - expected)) < 1e-9
    assert np.max(np.abs(batch.x - rt.x)) < 1e-9


@pytest.mark.parametrize("rate, N", [(1000.0, 30_000), (10_000.0, 200_000)])
def test_batch_equals_streaming_for_a_slow_filter_sampled_fast(rate, N):
    """A single-rate position filter at 1 and 10 kHz: closed-loop poles clustered near z = 1,
    where the IIR (direct form) path drifted 1e-4 relative from the recursion (1 kHz), and the
    direct form of the lifted block recursion 1e-7 (10 kHz); the batch run must still be the
    streaming recursion to rounding."""
    spec = cfdesign.spec.parse_spec({"name": "p", "structure": "position", "gain_form": "filter", "sensors": {
        "accelerometer": {"rate_hz": rate, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-4}},
        "gps": {"rate_hz": rate, "noise": {"std": 2.0}}}})
    table = cfdesign.design(spec)
    rng = np.random.default_rng(0)
    data = {s.name: np.sin(1e-5 * np.arange(N)) + 0.1 * rng.standard_normal(N) for s in table.sensors}
    rt = Runtime(table)
    expected = np.array([rt.step_values(a, g) for a, g in zip(data["accelerometer"], data["gps"], strict=True)])
    batch = Runtime(table)
    est = batch.run(data)
    assert np.max(np.abs(est - expected)) <= 1e-9 * np.max(np.abs(expected))
    assert np.max(np.abs(batch.x - rt.x)) <= 1e-9 * np.max(np.abs(rt.x))


def test_batch_equals_streaming_when_the_heading_turns_more_than_pi_between_readings(heading):
    """The batch paths unwrap the angle readings over the readings present; a heading that turns
    more than pi between two readings of a slow sensor (4 rad/s beside a 1 Hz compass; 20 rad/s at
    5 Hz) cannot be unwrapped from the readings alone.  The batch run must still be the
    recursion, whose innovations are wrapped against the estimate."""
    slow = cfdesign.design(cfdesign.spec.parse_spec({"name": "h", "structure": "dckf3", "wrap_angle": True, "sensors": {
        "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
        "odometry": {"rate_hz": 100.0, "noise": {"std": 0.5}},
        "compass": {"rate_hz": 1.0, "noise": {"std": 0.05}}}}))
    rng = np.random.default_rng(2)
    for table, rate in ((slow, 4.0), (heading, 20.0)):
        N, T = 1500, table.sample_time_s
        turn = np.where(np.arange(N) > N // 3, rate, 0.1)
        psi = np.cumsum(turn * T)
        data = {"gyro": turn + 0.01 * rng.standard_normal(N), "odometry": wrap(psi + 0.5 * rng.standard_normal(N)),
                "compass": np.where(np.arange(N) % table.period == 0, wrap(psi), np.nan)}
        for states in (False, True):
            expected, rt = stream(table, data, x0=[psi[0], 0.0])
            batch = Runtime(table, x0=[psi[0], 0.0])
            est = batch.run(data, states=states)
            est = est[0] if states else est
            assert np.max(np.abs(wrap(est - expected))) < 1e-9
            assert abs(wrap(batch.x[0] - rt.x[0])) < 1e-9 and abs(batch.x[1] - rt.x[1]) < 1e-9


def test_angle_check_does_not_send_ordinary_runs_step_by_step(heading, monkeypatch):
    """The check of the angle innovations costs one more IIR pass, not the batch speed: a heading
    that crosses +-pi at an ordinary rate runs without a single step of the loop."""
    stepped = []
    loop = Runtime._run_loop
    monkeypatch.setattr(Runtime, "_run_loop", lambda self, u, y, states: stepped.append(len(u)) or loop(self, u, y,
                                                                                                         states))
    N = 5000
    psi = np.linspace(0.0, 40.0, N)
    rng = np.random.default_rng(3)
    data = {"gyro": np.gradient(psi, heading.sample_time_s), "compass": wrap(psi + 0.05 * rng.standard_normal(N)),
            "odometry": wrap(psi + 0.05 * rng.standard_normal(N))}
    for states in (False, True):
        Runtime(heading, x0=[0.0, 0.0]).run(data, states=states)
    assert stepped == []


@pytest.fixture(scope="module")
def crossover4():
    """A 4-band discrete chain (jerk input; position, velocity, acceleration measured) designed by
    its crossovers: slow poles, where the IIR path's direct form amplifies rounding most."""
    from cfdesign.designer import design
    from cfdesign.spec import parse_spec

    sensors = {x: {"rate_hz": 100.0, "noise": {"std": 0.01}} for x in ["jerk", "acceleration", "velocity", "position"]}
    return design(parse_spec({"structure": "cfn", "bands": 4, "discrete": True,
                              "crossover": {"hz": [0.01, 0.3, 3.0]}, "sensors": sensors}))


def _grid_log(table, N, seed=3):
    """Readings on a grid of 2**-20 (so a shift by 6.4e6 or 1e9 is exact); the slow sensors'
    columns NaN between their readings."""
    rng, k = np.random.default_rng(seed), np.arange(N)
    data = {}
    for s in table.sensors:
        col = (3.0 if s.order == 0 else 0.1) * np.sin(0.001 * k) + 0.01 * rng.normal(size=N)
        col = np.round(col * 2**20) / 2**20
        if s.role == "measurement":
            col[~table.schedule.mask()[k % table.period, s.index]] = np.nan
        data[s.name] = col
    return data


@pytest.mark.parametrize("shift", [6.4e6, 1e9])
@pytest.mark.parametrize("name", ["crossover4", "position"])
def test_batch_on_a_shifted_log_is_the_run_plus_the_shift(name, shift, request):
    """ECEF/UTM-sized positions: the batch paths (the summed-band IIR path; the blocked path,
    single-rate with states=True and multirate) ran the recursion on absolute values and their
    rounding grew with |x| (run - step 1.4e-3 m at 6.4e6 m on the 4-band table, 0.22 m at 1e9,
    against a 3.2 mm predicted std). Relative to a reference (the offset moves the position
    only, not the velocity or the bias), a shifted log gives the shifted estimates to the
    rounding of the shifted numbers themselves, and agrees with the streaming step."""
    table = request.getfixturevalue(name)
    data = _grid_log(table, 40000)
    moved = {s.name: data[s.name] + shift if s.order == 0 else data[s.name] for s in table.sensors}
    x0 = np.zeros(table.F.shape[0])
    x0[0] = shift
    base, base_states = Runtime(table).run(data, states=True)
    est, est_states = Runtime(table, x0=x0).run(moved, states=True)
    fast = Runtime(table, x0=x0).run(moved)  # the IIR path where the table has one
    ulp = np.spacing(shift)
    assert np.max(np.abs(fast - shift - base)) <= 2 * ulp
    assert np.max(np.abs(est - shift - base)) <= 2 * ulp
    assert np.max(np.abs(est_states[:, 1:] - base_states[:, 1:])) <= ulp  # velocity, bias: not moved
    rt = Runtime(table, x0=x0)
    names = rt.inputs + rt.measurements
    stepped = np.array([rt.step_values(*row) for row in zip(*[moved[n] for n in names], strict=True)])
    std = float(np.sqrt(table.P_filtered[0][0, 0] if table.output == "posterior" else table.P[0][0, 0]))
    assert np.max(np.abs(fast - stepped)) <= 1e-2 * std


def test_offset_moves_the_quantity_only(crossover4, position):
    """The offset direction from the typed ports: order-0 sensors' readings and state 0 only."""
    from cfdesign.runtime.filter import _offset_direction

    for table, s in [(crossover4, [0, 1, 0, 0]), (position, [0, 1])]:
        v, flags = _offset_direction(np.array(table.F), np.array(table.B), np.array(table.H), table)
        assert flags.tolist() == s and v.tolist() == [1.0] + [0.0] * (len(v) - 1)


def test_batch_follows_a_position_that_drifts_far_within_the_log(crossover4):
    """A log whose position drifts from 6.4e6 m by 4e5 m (1 km/s, 400 s): one reference for the
    whole log would leave the batch's rounding at the scale of the drift; re-taken every piece,
    the run agrees with the streaming step far inside the predicted std (before: 1.4e-3 m off,
    against 3.2 mm)."""
    N = 40000
    data = _grid_log(crossover4, N)
    k = np.arange(N)
    data["position"] = data["position"] + 6.4e6 + 10.0 * k
    data["velocity"] = data["velocity"] + 1000.0
    rt = Runtime(crossover4, x0=[6.4e6, 1000.0, 0.0])
    est = Runtime(crossover4, x0=[6.4e6, 1000.0, 0.0]).run(data)
    names = rt.inputs + rt.measurements
    stepped = np.array([rt.step_values(*row) for row in zip(*[data[n] for n in names], strict=True)])
    std = float(np.sqrt(crossover4.P_filtered[0][0, 0]))
    assert np.max(np.abs(est - stepped)) <= 1e-2 * std


def test_reprs_name_the_table_and_stay_short_whatever_the_period(position):
    """A notebook shows a table or a runtime by its repr: one line naming what runs, not the 50 phases'
    matrices (the dataclass repr of the position table was 22 kB)."""
    text = repr(position)
    assert len(text) < 400 and "\n" not in text
    assert "period 50" in text and "gps (measurement, order 0, 1 Hz)" in text and position.name in text
    rt = Runtime(position)
    rt.step(accelerometer=0.0)
    assert repr(rt).startswith(f"<Runtime of {position.name!r}: output posterior, phase 1 of 50")
    continuous = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("cf3")))
    assert ", continuous, period 1, output prior;" in repr(continuous)   # no gain form: it has none


@pytest.mark.parametrize("Phi", [np.array([[0.9, 0.01], [-0.01, 0.95]]), np.array([[0.99999, 1e-3], [0.0, 0.99999]]),
                                 np.array([[1.0, 0.01], [0.0, 1.0]]), np.diag([0.999999, 0.999998, 0.5])])
@pytest.mark.parametrize("P", [1, 5, 9, 4097])
def test_block_boundary_states_equal_the_recursion(Phi, P):
    """The lifted batch path's states at the start of every block (a doubling scan over the blocks)
    equal the plain recursion ``X[p+1] = Phi X[p] + C[p]``, also for a double pole at 0.99999 and an
    uncorrected double integrator (a Jordan block at 1), where the direct form of lfilter drifted."""
    from cfdesign.runtime.filter import _boundary_states

    rng = np.random.default_rng(P)
    C, x0 = rng.standard_normal((P, len(Phi))), rng.standard_normal(len(Phi))
    want, x = np.empty((P, len(Phi))), x0
    for p in range(P):
        want[p], x = x, Phi @ x + C[p]
    assert np.max(np.abs(_boundary_states(Phi, C, x0) - want)) <= 1e-12 * max(1.0, np.max(np.abs(want)))
