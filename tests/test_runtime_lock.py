"""The streaming runtime locked to the readings as they arrive: slow sensors at a phase the
schedule has no gain for are used when one shift places them, warned of otherwise, and
ArrivalKalman.step streams the filter that uses every reading."""

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import HEADING

import cfdesign
from cfdesign.linear import wrap
from cfdesign.runtime import Runtime
from cfdesign.runtime.arrivals import ArrivalKalman
from cfdesign.spec import parse_spec

N = 8000


@pytest.fixture(scope="module")
def heading():
    return cfdesign.design(parse_spec(HEADING))


def heading_rows(odometry_row, compass_row, n=N, seed=0):
    """A turning robot at 100 Hz (as tests/test_logs.py): gyro every row, odometry every 10th row
    from ``odometry_row``, compass every 100th from ``compass_row`` (NaN between), true heading."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    psi = 2.0 + 6.0 * np.sin(0.05 * t) + 0.3 * t
    gyro = np.gradient(psi, 0.01) + 0.01 * rng.standard_normal(n) + 0.002
    odo, com = np.full(n, np.nan), np.full(n, np.nan)
    odo[odometry_row::10] = wrap(psi[odometry_row::10] + 0.005 * rng.standard_normal(len(odo[odometry_row::10])))
    com[compass_row::100] = wrap(psi[compass_row::100] + 0.05 * rng.standard_normal(len(com[compass_row::100])))
    return {"gyro": gyro, "odometry": odo, "compass": com}, psi


def rms(est, psi, start=2000):
    return float(np.sqrt(np.mean(wrap(np.asarray(est)[start:] - psi[start:]) ** 2)))


def stepped(rt, data):
    rows = [dict(zip(data, r, strict=True)) for r in zip(*data.values(), strict=True)]
    return [rt.step(**{k: v for k, v in r.items() if not np.isnan(v)}) for r in rows]


def test_one_common_offset_is_locked_to(heading):
    """Odometry at rows 7, 17, ... and compass at 37, 137, ... (the whole schedule 37 ticks late)
    stepped with the defaults: every reading used, no warning, RMS within 1.25x of the aligned run;
    with lock=False the readings are lost and counted (the failure of the issue)."""
    aligned, psi = heading_rows(0, 0)
    late, _ = heading_rows(7, 37)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ref = rms(stepped(Runtime(heading), aligned), psi)
        rt = Runtime(heading)
        got = rms(stepped(rt, late), psi)
    assert rt.counts == {} and got <= 1.25 * ref, (got, ref)
    fixed = Runtime(heading, lock=False)
    with pytest.warns(UserWarning, match="lock=False"):
        stepped(fixed, late)
    assert fixed.counts["unscheduled"] == {"odometry": 800, "compass": 80}


def test_own_offsets_are_warned_of_and_arrival_kalman_uses_them(heading):
    """Odometry at rows 3, 13, ..., compass at 37, 137, ...: no one shift places both, so the
    compass is counted and warned of (naming ArrivalKalman), the odometry kept on schedule;
    ArrivalKalman.step uses both, within 1.25x of the aligned run."""
    aligned, psi = heading_rows(0, 0)
    own, _ = heading_rows(3, 37)
    rt = Runtime(heading)
    with pytest.warns(UserWarning, match=r"compass: a reading at phase 34 .*ArrivalKalman") as caught:
        stepped(rt, own)
    assert len(caught) == 1 and rt.counts == {"unscheduled": {"compass": 80}}
    ref = rms(stepped(Runtime(heading), aligned), psi)
    kf = ArrivalKalman(heading)
    got = rms(stepped(kf, own), psi)
    assert got <= 1.25 * ref, (got, ref)


def test_arrival_kalman_step_is_its_run(heading):
    """ArrivalKalman.step over whole arrays equals ArrivalKalman.run to 1e-12 (either output),
    with an inf counted and a missing input held alike."""
    data, _ = heading_rows(3, 37, n=600, seed=2)
    data["gyro"][[40, 41]] = [np.nan, np.inf]
    data["odometry"][53] = np.inf
    for output in ("posterior", "prior"):
        a, b = ArrivalKalman(heading, output), ArrivalKalman(heading, output)
        est = stepped(a, data)
        states, _ = b.run(data["gyro"][:, None], np.column_stack([data[s.name] for s in heading.measurements]))
        assert np.max(np.abs(wrap(np.array(est) - states[:, 0]))) <= 1e-12
        assert np.allclose(a.x, b.x, rtol=0, atol=1e-12) and a.counts == b.counts == {
            "rejected": {"odometry": 1, "gyro": 1}}
    with pytest.raises(cfdesign.CfdesignError, match=r"unknown sensor.*gps.*gyro"):
        a.step(gps=1.0)
    with pytest.raises(cfdesign.CfdesignError, match=r"compass: reading 'x'"):
        a.step(compass="x")


def test_the_issue_gps_is_used():
    """The issue's loop: a 1 Hz GPS at phase 17 of a table that reads it at phase 0 moves the
    estimate to the fix with the defaults (it stayed 0.0, every fix unscheduled)."""
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    rt = Runtime(table)
    for k in range(200):
        x = rt.step(accelerometer=0.0, **({"gps": 1.0} if k % 50 == 17 else {}))
    assert rt.counts == {} and 0.2 < x <= 1.0
    snap = rt.state()  # the lock's view is carried: a restored runtime goes on alike
    other = Runtime(table)
    other.restore(snap)
    for k in range(200, 400):
        kw = {"gps": 1.0} if k % 50 == 18 else {}  # the fixes slip a tick: relocked
        assert rt.step(accelerometer=0.0, **kw) == other.step(accelerometer=0.0, **kw)
    assert rt.counts == other.counts == {} and rt.state() == other.state()


def test_a_faster_sensor_is_warned_of_not_locked_to(heading):
    """A 10 Hz compass into the 1 Hz compass table: its readings off phase come faster than the
    table reads it, so none moves the phase (the odometry keeps its gains); counted and warned."""
    data, _ = heading_rows(0, 0, n=1000)
    data["compass"][::10] = data["odometry"][::10]
    rt = Runtime(heading)
    with pytest.warns(UserWarning, match="compass.*faster than designed"):
        stepped(rt, data)
    assert rt.counts == {"unscheduled": {"compass": 90}} and rt.phase == 0


def test_warn_false_counts_without_warning_and_cfdesign_run_speaks_once(heading):
    """A caller that reports the counts itself (run_log: its notes, LogResult.unused) builds its
    runtimes with warn=False: the readings are counted as before, and the runtime's warning (which
    names Runtime.counts and ArrivalKalman, not what a log's user can do) is not given as well."""
    from cfdesign.logs import run_log

    own, _ = heading_rows(3, 37, n=2000)
    rt = Runtime(heading, warn=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stepped(rt, own)
    assert rt.counts == {"unscheduled": {"compass": 20}}
    with pytest.raises(cfdesign.errors.CfdesignError, match="warn must be True or False"):
        Runtime(heading, warn="no")
    fixed = dataclasses.replace(heading, provenance={})    # hand-typed gains: no recomputed pattern
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = run_log(fixed, {**own, "time": np.arange(2000) * 0.01})
    assert result.unused                                     # the log path's own report


def test_run_log_takes_a_dict_of_columns_as_runtime_run_does(heading):
    """run_log(table, {name: array}) ran into os.stat's TypeError; it is the frame of those columns,
    and a dict of ragged columns or a list is refused naming the problem."""
    from cfdesign.errors import CfdesignError, DataError
    from cfdesign.logs import run_log

    pd = pytest.importorskip("pandas")
    data, _ = heading_rows(0, 0, n=600)
    data["time"] = np.arange(600) * 0.01
    a, b = run_log(heading, data), run_log(heading, pd.DataFrame(data))
    np.testing.assert_array_equal(a.estimates["heading"], b.estimates["heading"])
    with pytest.raises(DataError, match="a log given as a dict needs columns of one length"):
        run_log(heading, {**data, "gyro": data["gyro"][:10]})
    with pytest.raises(CfdesignError, match="a log is a path, a pandas DataFrame or a dict of columns, got list"):
        run_log(heading, [1, 2, 3])


def test_a_sensor_gone_for_good_no_longer_holds_the_schedule(heading, monkeypatch):
    """The compass stops at row 1000 and the odometry comes back 3 ticks late at row 1500: the
    compass, not read for 5 s (more than LOCK_STALE_READINGS of its spacings), no longer pins the
    phase, so the odometry relocks (every one of its readings was lost, 0.18 rad RMS against
    0.0014 with them); the same rows through ArrivalKalman are the reference."""
    n = 4000
    data, psi = heading_rows(0, 0, n=n)
    data["compass"][1000:] = np.nan
    data["odometry"][1500:] = np.nan
    data["odometry"][1503::10] = wrap(psi[1503::10])
    rt = Runtime(heading)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = rms(stepped(rt, data), psi, start=2500)
    ref = rms(stepped(ArrivalKalman(heading), data), psi, start=2500)
    assert rt.counts == {} and got <= 1.25 * ref, (got, ref)
    monkeypatch.setattr("cfdesign.runtime.lock.LOCK_STALE_READINGS", 10**9)  # a compass that holds for ever
    held = Runtime(heading, warn=False)
    stepped(held, data)
    assert held.counts == {"unscheduled": {"odometry": 250}}


def test_a_reading_a_tick_early_moves_the_phase_one_tick():
    """A 3 Hz GPS read at phases 0, 33, 67 of a 100 Hz table, its second fix a tick early (row 32):
    the phase moves back one tick (it took that fix for the phase-0 one 32 ticks late and moved 3
    more times before it settled), and one tick forward at the next fix, on time."""
    spec = {"name": "pos 100/3", "structure": "position", "gain_form": "filter", "sensors": {
        "accelerometer": {"measures": "acceleration", "rate_hz": 100.0, "noise": {"std": 0.05},
                          "bias": {"model": "random_walk", "density": 1e-3}},
        "gps": {"measures": "position", "rate_hz": 3.0, "noise": {"std": 0.2}}}}
    table = cfdesign.design(parse_spec(spec))
    fixes = {0, 32, 67, 100, 133, 167, 200}
    rt, phases = Runtime(table), []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for k in range(220):
            phases.append(rt.phase)
            rt.step(accelerometer=0.0, **({"gps": 1.0} if k in fixes else {}))
    moves = [k for k in range(1, 220) if phases[k] != (phases[k - 1] + 1) % 100]
    assert moves == [33, 68] and phases[33] == 34 and phases[68] == 68 and rt.phase == 220 % 100 and rt.counts == {}


# ---------------------------------------------------------------- Runtime.run locks as step does
def position_rows(n=1000, seed=4):
    """The issue's rows through the position example: a 50 Hz accelerometer, a 1 Hz GPS at tick 17
    of each 50 (the table reads it at phase 0), NaN between its fixes."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    pos = 2.0 * (1.0 - np.cos(0.4 * t))  # from rest at 0, as the filter starts
    acc = 0.32 * np.cos(0.4 * t) + 0.05 + 0.006 * rng.standard_normal(n)  # a 0.05 m/s^2 bias
    gps = np.full(n, np.nan)
    gps[17::50] = pos[17::50] + 0.5 * rng.standard_normal(len(gps[17::50]))
    return {"accelerometer": acc, "gps": gps}


def same_state(a, b, tol=1e-12):
    """``a.state() == b.state()``, the state floats to ``tol``."""
    sa, sb = a.state(), b.state()
    xa, xb = np.array(sa.pop("x")), np.array(sb.pop("x"))
    return sa == sb and np.max(np.abs(xa - xb)) <= tol


@pytest.fixture(scope="module")
def position():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))


def lock_cases(heading, position):
    return [(heading, heading_rows(7, 37, n=2000)[0]), (heading, heading_rows(3, 37, n=2000)[0]),
            (position, position_rows())]


def posterior_states(rt, rows):
    """Each step's posterior states from the priors a step loop went through, another way than
    run forms them: ``x[k + 1] = F x+[k] + B u[k]`` (filter form, ``Kp = F L``), so ``x+[k]`` is
    ``F^-1 (x[k + 1] - B u[k])``; with the estimates ``step`` returned."""
    p, est, priors = len(rt.inputs), [], []
    for r in rows:
        est.append(rt.step(**{k: v for k, v in r.items() if not np.isnan(v)}))
        priors.append(rt.x)
    u = np.array([[r[name] for name in rt.inputs] for r in rows]).reshape(len(rows), p)
    xs = np.linalg.solve(rt.F, (np.array(priors) - u @ rt.B.T).T).T
    return np.array(est), xs


def recorded(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = call()
    return out, [(str(w.message), w.filename) for w in caught]


def assert_same(a, b, tol=1e-12, angle=False):
    d = np.asarray(a) - np.asarray(b)
    if angle:
        d[..., 0] = wrap(d[..., 0])
    assert np.max(np.abs(d)) <= tol, np.max(np.abs(d))


def test_run_gives_what_a_step_loop_gives(heading, position):
    """The common offset, the own offsets (compass counted and warned of) and the issue's GPS at
    tick 17 of each 50: run, with or without states, equals stepping the rows on fresh runtimes
    (estimates, posterior states, counts, state() afterwards) and warns as the steps do, at this
    file's line; a GPS used at every fix moves the estimate where run used none before."""
    for table, data in lock_cases(heading, position):
        rows = [dict(zip(data, r, strict=True)) for r in zip(*data.values(), strict=True)]
        angle = bool(table.wrap_angle)
        ref = Runtime(table)
        (est, xs), warned = recorded(lambda ref=ref, rows=rows: posterior_states(ref, rows))
        for states in (False, True):
            rt = Runtime(table)
            out, got = recorded(lambda rt=rt, states=states, data=data: rt.run(data, states=states))
            assert [m for m, _ in got] == [m for m, _ in warned] and all(f == __file__ for _, f in got)
            assert_same(out[0] if states else out, est, angle=angle)
            if states:
                assert_same(out[1], xs, tol=1e-9, angle=angle)  # (the reference's solve rounds)
                assert_same(out[1][:, 0], out[0], tol=0)
            assert rt.counts == ref.counts and same_state(rt, ref)
    issue = {"accelerometer": np.zeros(200), "gps": np.where(np.arange(200) % 50 == 17, 1.0, np.nan)}
    rt, fixed = Runtime(position), Runtime(position, lock=False)
    with pytest.warns(UserWarning, match="lock=False"):
        lost = fixed.run(issue)
    assert 0.2 < rt.run(issue)[-1] <= 1.0 and lost[-1] == 0.0 and rt.counts == {}  # every fix used, none before
    assert fixed.counts == {"unscheduled": {"gps": 4}}


def test_split_runs_equal_one_run_and_the_steps(heading, position):
    """run(a) then run(b) equals one run(a + b) and the step loop, split before the first slow
    reading, after the lock has moved (b then runs on the vectorised paths) and mid-stretch."""
    for table, data in lock_cases(heading, position):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ref = Runtime(table)
            est = np.array(stepped(ref, data))
            whole = Runtime(table)
            one = whole.run(data)
            for cut in (5, 140, 1234):
                rt = Runtime(table)
                parts = [rt.run({k: v[:cut] for k, v in data.items()}), rt.run({k: v[cut:] for k, v in data.items()})]
                assert_same(np.concatenate(parts), est, angle=bool(table.wrap_angle))
                assert rt.counts == ref.counts == whole.counts and same_state(rt, ref) and same_state(whole, ref)
        assert_same(one, est, angle=bool(table.wrap_angle))


def test_aligned_run_keeps_the_vectorised_path(heading, position, monkeypatch):
    """Readings on the schedule never reach the steps: run gives bit for bit what the fixed
    schedule (lock=False) gives, and the stepped path is not taken."""
    taken = []
    monkeypatch.setattr(Runtime, "_run_stepped", lambda self, *a: taken.append(len(a[0])))
    aligned = heading_rows(0, 0, n=3000)[0]
    gps = position_rows()
    gps["gps"] = np.roll(gps["gps"], -17)
    for table, data in ((heading, aligned), (position, gps)):
        for states in (False, True):
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                a, b = Runtime(table).run(data, states=states), Runtime(table, lock=False).run(data, states=states)
            for x, y in zip(*((a, b) if states else ([a], [b])), strict=True):
                np.testing.assert_array_equal(x, y)
    assert taken == []


def test_a_slow_value_repeated_every_tick_runs_the_fixed_schedule_in_run(monkeypatch):
    """A 1 Hz GPS's value given at every tick (held and repeated) is refused by the lock one repeat
    at a time; run keeps the vectorised fixed schedule for it (0.75 us a row by steps), counts the
    repeats and says why once, with the numbers of lock=False.  Given only at its arrivals
    (sinusoid_readings(arrivals=True)) nothing is off the schedule."""
    from cfdesign.sim.signals import sinusoid_readings

    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    every = sinusoid_readings(table, 1000)
    rt = Runtime(table)
    monkeypatch.setattr(rt, "_run_stepped", lambda *a: pytest.fail("stepped a sensor given every tick"))
    with pytest.warns(UserWarning, match=r"gps: .*faster than designed \(a value held and repeated\?\)") as caught:
        est = rt.run(every)
    assert len(caught) == 1 and rt.counts == {"unscheduled": {"gps": 980}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        np.testing.assert_array_equal(est, Runtime(table, lock=False).run(every))
    arrivals = sinusoid_readings(table, 1000, arrivals=True)
    assert np.flatnonzero(~np.isnan(arrivals["gps"])).tolist() == list(range(0, 1000, 50))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet = Runtime(table)
        quiet.run(arrivals)
    assert quiet.counts == {}


def held_rows(table, n, seed):
    """Rows of a robot loop: the inputs every tick; each slow sensor's new values at gaps about half
    its designed spacing, and about its spacing, apart (the rule's edge), each value repeated at every
    tick until the next in some stretches (the loop caches the latest value) and given once in others."""
    rng = np.random.default_rng(seed)
    lock = Runtime(table)._lock
    inputs = table.sensor_names("input")
    rows = [dict(zip(inputs, rng.standard_normal(len(inputs)).tolist(), strict=True)) for _ in range(n)]
    for name, spacing, half in zip(lock.names, lock.spacing, lock.half, strict=True):
        k, gaps = int(rng.integers(0, 20)), [1, half - 1, half, half + 1, int(spacing) - 1, int(spacing)]
        while k < n:
            gap, repeat, value = max(int(rng.choice(gaps)), 1), rng.random() < 0.5, float(rng.standard_normal())
            for row in rows[k:k + gap] if repeat else rows[k:k + 1]:
                row[name] = value
            k += gap
    return rows


def held_steps(rt, rows, forced):
    """Step ``rows`` with snapshots, phase moves both ways, a reset and a run call between;
    ``forced``: ``soon`` cleared before each step (every reading off the schedule through the rule).
    The estimates and the lock's state after each step."""
    out = []
    for k, r in enumerate(rows):
        if k in (25, 600):
            rt.restore(rt.state())
        if k in (300, 900):
            rt.phase = rt.phase + (13 if k == 300 else -29)
        if k == 700:
            rt.reset()
        if k == 1300:
            out.extend(rt.run({s: np.array([r.get(s, np.nan)] * 40) for s in rt.inputs + rt.measurements}))
        if forced:
            rt._lock.soon[:] = [-np.inf] * len(rt._lock.soon)
        out.append((rt.step(**r), rt._lock.state()))
    return out


@pytest.mark.parametrize(("name", "lock"), [("heading", True), ("position", True), ("heading", False)])
def test_held_repeats_are_refused_by_the_step_as_by_the_rule(name, lock, request, monkeypatch):
    """A slow sensor's value repeated every tick: after the warning the step refuses each repeat
    itself (PhaseLock.soon, one comparison of ticks) instead of the rule; the estimates, the counts,
    the warnings and the lock's state after every step are those of steps that take every such
    reading through the rule, with readings at the rule's edge (held_steps); lock=False never
    refuses so."""
    table = request.getfixturevalue(name)
    rows = held_rows(table, 1500, seed=len(table.measurements))
    fast, ruled = Runtime(table, lock=lock), Runtime(table, lock=lock)
    soon = {id(fast): 0, id(ruled): 0}  # readings the rule refused as faster than designed

    def counted(rt, rule, *args):
        why, new = rule(*args)
        soon[id(rt)] += new is None and "faster than designed" in why()
        return why, new

    for rt in (fast, ruled):
        monkeypatch.setattr(rt._lock, "_placed", lambda *a, rt=rt, rule=rt._lock._placed: counted(rt, rule, *a))
    got, said = recorded(lambda: held_steps(fast, rows, False))
    want, said_ruled = recorded(lambda: held_steps(ruled, rows, True))
    assert got == want and said == said_ruled and fast.counts == ruled.counts and fast.state() == ruled.state()
    assert sorted(m.split(":")[0] for m, _ in said) == sorted(fast.counts["unscheduled"]) != []
    # the rule still sees those that come too soon after a reading with a gain (the step keeps
    # the aligned path free of that bookkeeping): some 60 of 1500 (heading), 15 of 750 (position)
    assert 10 * soon[id(fast)] < soon[id(ruled)] if lock else soon[id(fast)] == soon[id(ruled)] == 0, soon


def test_a_restored_lock_refuses_a_held_value_as_before(position):
    """Restored after a GPS fix read at phase 0 (no warning yet), a repeat a tick later is refused
    by the rule and warned of; restored again, a fix 25 ticks (half its spacing) after that repeat
    is not faster than designed: the lock places it (the phase moves), nothing more is counted."""
    rt = Runtime(position)
    rt.step(accelerometer=0.0, gps=1.0)
    rt.restore(rt.state())
    with pytest.warns(UserWarning, match=r"gps: a reading at phase 1 .*it came 1 ticks after"):
        rt.step(accelerometer=0.0, gps=1.0)
    rt.restore(rt.state())
    for _ in range(24):
        rt.step(accelerometer=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rt.step(accelerometer=0.0, gps=1.0)
    assert rt.counts == {"unscheduled": {"gps": 1}} and rt.phase == 1 and rt.state()["lock"]["on"] == {"gps": 1}
