"""Properties of the streaming multirate runtime over random arrival patterns, and the bugs they
found: Runtime.run equals a loop of Runtime.step (split, snapshot and restored alike), the phase
lock costs nothing on a common offset and lock=False is the fixed schedule, every usable reading
is used or counted once (against a tally made here), and ArrivalKalman.step is the textbook
Kalman filter written here.  Cases are drawn by hypothesis (derandomized, few examples) and
seeded numpy: readings from the table's own model, then the slow sensors' arrivals."""

import json
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import cfdesign
from cfdesign.linear import wrap
from cfdesign.runtime import Runtime
from cfdesign.runtime import filter as runtime_filter
from cfdesign.runtime.arrivals import ArrivalKalman
from cfdesign.spec import parse_spec
from cfdesign.timing import _pattern, rotation

KINDS = ("aligned", "common", "own", "jitter", "dropout", "silent", "held")
FEW = settings(max_examples=8, derandomize=True, deadline=None, database=None)


def position_spec(imu_hz, gps_hz):
    return {"name": f"position {imu_hz:g}/{gps_hz:g} Hz", "structure": "position", "gain_form": "filter",
            "sensors": {"accelerometer": {"measures": "acceleration", "rate_hz": imu_hz, "noise": {"std": 0.05},
                                          "bias": {"model": "random_walk", "density": 1e-3}},
                        "gps": {"measures": "position", "rate_hz": gps_hz, "noise": {"std": 0.5}}}}


@pytest.fixture(scope="module")
def tables(heading):
    """100/10/1 Hz heading (dckf3), the position example (50/1 Hz), 50/5 Hz and 100/3 Hz (phases
    0, 33, 67) positions."""
    return [heading, cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position"))),
            cfdesign.design(parse_spec(position_spec(50.0, 5.0))),
            cfdesign.design(parse_spec(position_spec(100.0, 3.0)))]


def simulate(table, N, rng):
    """Inputs, true states and every measurement at every tick from the table's own model
    (``x <- F x + B u + w``, ``y = H x + v``; ``w, v`` of covariances ``Q, R``)."""
    F, B, H, Q, R = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H, table.Q, table.R))

    def root(M):
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        return V * np.sqrt(np.maximum(w, 0.0))

    cq, cr = root(Q), root(R)
    u = 0.3 * np.sin(0.01 * (1.0 + rng.random()) * np.arange(N))[:, None] + 0.05 * rng.standard_normal((N, B.shape[1]))
    X, x = np.empty((N, F.shape[0])), np.zeros(F.shape[0])
    for k in range(N):
        X[k] = x
        x = F @ x + B @ u[k] + cq @ rng.standard_normal(len(x))
    return u, X, X @ H.T + rng.standard_normal((N, H.shape[0])) @ cr.T


def arrivals(table, N, rng, kind):
    """``(N, m)`` bool, where each measurement arrives: on the schedule (``aligned``), the whole
    schedule at a random offset (``common``), each sensor at its own (``own``), or at a common
    offset then some readings a tick early or late (``jitter``), runs of missed readings
    (``dropout``), one sensor silent then back at another phase (``silent``), one sensor's value
    repeated every tick from some row on (``held``)."""
    P, mask = table.period, table.schedule.mask()
    rows, m = np.arange(N), mask.shape[1]
    if kind == "aligned":
        return mask[rows % P]
    if kind == "own":
        return np.column_stack([mask[(rows - int(rng.integers(P))) % P, i] for i in range(m)])
    at = mask[(rows - int(rng.integers(P))) % P]
    i = int(rng.integers(m))
    if kind == "jitter":
        for i in range(m):
            for k in np.flatnonzero(at[:, i] & (rng.random(N) < 0.15)):
                d = int(rng.choice([-1, 1]))
                if 0 <= k + d < N and not at[k + d, i]:
                    at[[k, k + d], i] = [False, True]
    elif kind == "dropout":
        for i in range(m):
            for a in rng.integers(N, size=3):
                at[a:a + int(rng.integers(1, 4 * P)), i] = False
    elif kind == "silent":
        a = int(rng.integers(N // 2 + 1))
        b = a + int(rng.integers(P, 4 * P))
        at[a:, i] = False
        at[b:, i] = mask[(rows[b:] - int(rng.integers(P))) % P, i]
    elif kind == "held":
        at[int(rng.integers(N)):, i] = True
    return at


def case(table, N, seed, kind, bad=False):
    """``(readings, true states)``: the model's readings where they arrive (NaN elsewhere), with
    ``bad`` 1 % of every column (inputs too) inf, -inf, 2e12 or NaN."""
    rng = np.random.default_rng(seed)
    u, X, Y = simulate(table, N, rng)
    y = np.where(arrivals(table, N, rng, kind), Y, np.nan)
    if table.wrap_angle:
        y = wrap(y)
    if bad:
        for a in (u, y):
            hit = rng.random(a.shape) < 0.01
            a[hit] = rng.choice([np.inf, -np.inf, 2e12, np.nan], size=int(hit.sum()))
    data = {s.name: u[:, j].copy() for j, s in enumerate(table.inputs)}
    data.update({s.name: y[:, i].copy() for i, s in enumerate(table.measurements)})
    return data, X


def step_rows(rt, data):
    """Step ``data`` row by row (NaN left out); the estimates and the phase each step ran at."""
    names = list(data)
    est, ran = [], []
    for row in zip(*(data[k] for k in names), strict=True):
        est.append(rt.step(**{k: v for k, v in zip(names, row, strict=True) if not np.isnan(v)}))
        ran.append((rt.phase - 1) % rt.period)
    return np.array(est), np.array(ran, dtype=int)


def recorded(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = call()
    return out, [str(w.message) for w in caught]


def close(a, b, table, tol=1e-12):
    """The estimates agree to ``tol`` (relative to their size, at least 1; angles wrapped)."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    d = wrap(d) if table.wrap_angle else d
    return not d.size or np.max(np.abs(d)) <= tol * max(1.0, float(np.max(np.abs(b))))


def tally(table, data, ran):
    """Counts made here: a usable reading at a phase its step ran at without a gain is unscheduled;
    an inf or one beyond 1e12 is rejected."""
    mask, out = table.schedule.mask(), {}
    for what, sensors in (("rejected", (*table.inputs, *table.measurements)), ("unscheduled", table.measurements)):
        per = {}
        for s in sensors:
            y = data[s.name]
            ok = np.isfinite(y) & (np.abs(y) <= 1e12)
            i = table.measurements.index(s) if what == "unscheduled" else None
            c = int((ok & ~mask[ran, i]).sum()) if what == "unscheduled" else int((~ok & ~np.isnan(y)).sum())
            if c:
                per[s.name] = c
        if per:
            out[what] = per
    return out


cases = st.tuples(st.integers(0, 3), st.sampled_from(KINDS), st.sampled_from([5, 37, 260, 700]),
                  st.integers(0, 2**16), st.booleans())


# ---------------------------------------------------------------- (a) run, steps, pieces, snapshots
@FEW
@given(cases, st.lists(st.tuples(st.floats(0, 1), st.integers(0, 3)), min_size=1, max_size=4))
@example((1, "held", 37, 0, False), [(0.5, 0)])  # run kept the unlocked schedule (test_a_held_value_...)
def test_run_is_the_step_loop_whole_in_pieces_and_restored(tables, c, cuts):
    """run on whole arrays gives what stepping the rows gives (estimates to 1e-12, counts, the
    lock's state, the warnings); so does the stream cut anywhere into runs (with or without
    states) and steps, a JSON snapshot restored into a new runtime at some cuts."""
    table = tables[c[0]]
    data, _ = case(table, c[2], c[3], c[1], c[4])
    ref = Runtime(table)
    (est, _), warned = recorded(lambda: step_rows(ref, data))
    rt = Runtime(table)
    out, got = recorded(lambda: rt.run(data))
    assert close(out, est, table) and got == warned
    assert rt.counts == ref.counts and rt.state()["lock"] == ref.state()["lock"] and rt.phase == ref.phase
    N, rt, outs, start = len(est), Runtime(table, warn=False), [], 0
    runtimes = [rt]
    for frac, how in [*sorted(cuts), (1.0, 0)]:  # how: run, run with states, steps, steps then a snapshot
        stop = max(start, int(frac * N))
        rows = {k: v[start:stop] for k, v in data.items()}
        part = rt.run(rows, states=how == 1) if how < 2 else step_rows(rt, rows)[0]
        outs, start = [*outs, part[0] if how == 1 else part], stop
        if how == 3:  # a snapshot, through JSON, restored into a new runtime
            rt = Runtime(table, warn=False)
            rt.restore(json.loads(json.dumps(runtimes[-1].state())))
            runtimes.append(rt)
    assert close(np.concatenate(outs), est, table)
    assert summed(r.counts for r in runtimes) == ref.counts
    assert rt.state()["lock"] == ref.state()["lock"] and rt.phase == ref.phase


@FEW
@given(cases, st.lists(st.floats(0, 1), max_size=2))
def test_run_moving_between_steps_and_the_fixed_schedule_is_the_step_loop(tables, c, cuts):
    """The stretches between readings the lock may place run on the fixed schedule from one
    period on (``_FIXED_PERIODS`` 1, not 40), the placeable readings stepped two at most at a time
    (``_CHAIN``) and found one window reading at a time: so every arrival pattern moves between the
    steps and the vectorised paths many times in a few hundred rows, and still gives what the step
    loop gives (estimates to 1e-12, counts, warnings, lock state, phase), whole or cut into runs."""
    table = tables[c[0]]
    data, _ = case(table, c[2], c[3], c[1], c[4])
    ref = Runtime(table)
    (est, _), warned = recorded(lambda: step_rows(ref, data))
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(runtime_filter, "_FIXED_PERIODS", 1)
        patch.setattr(runtime_filter, "_CHAIN", 2)
        patch.setattr(runtime_filter._Placeable, "WINDOW", 1)
        rt = Runtime(table)
        out, got = recorded(lambda: rt.run(data, states=c[3] % 2 == 1))
        out = out[0] if c[3] % 2 == 1 else out
        assert close(out, est, table) and got == warned
        assert rt.counts == ref.counts and rt.state()["lock"] == ref.state()["lock"] and rt.phase == ref.phase
        pieces, outs, start = Runtime(table, warn=False), [], 0
        for stop in [*sorted(int(f * c[2]) for f in cuts), c[2]]:
            outs.append(pieces.run({k: v[start:stop] for k, v in data.items()}))
            start = stop
        assert close(np.concatenate(outs), est, table)
        assert pieces.counts == ref.counts and pieces.state()["lock"] == ref.state()["lock"]


def settling_cases(tables):
    """Long arrays whose slow readings are off the schedule from phase 0 and settle, then move:
    the heading's odometry and compass 37 ticks late, 63 from row 5000 (the whole schedule moved),
    the compass silent from 9400 and back from 10000 at 93 (odometry still at 3 of 10: placed);
    the position's GPS 17 ticks late, 29 from row 3000, its value held and repeated every tick
    from 5500 (each repeat refused as faster).  Each settled stretch is longer than the steps' share
    (``_FIXED_PERIODS`` periods)."""
    heading, position = tables[0], tables[1]
    rng = np.random.default_rng(5)
    u, _, Y = simulate(heading, 14000, rng)
    rows = np.arange(14000)
    at = {"odometry": np.where(rows < 5000, rows % 10 == 7, rows % 10 == 3),
          "compass": np.where(rows < 5000, rows % 100 == 37,
                              np.where(rows < 9400, rows % 100 == 63, (rows >= 10000) & (rows % 100 == 93)))}
    data = {"gyro": u[:, 0]}
    data.update({s.name: wrap(np.where(at[s.name], Y[:, i], np.nan)) for i, s in enumerate(heading.measurements)})
    yield heading, data
    u, _, Y = simulate(position, 7500, rng)
    rows = np.arange(7500)
    y = np.where(np.where(rows < 3000, rows % 50 == 17, rows % 50 == 29), Y[:, 0], np.nan)
    y[5500:] = y[5479]  # (row 5479: a fix)
    yield position, {"accelerometer": u[:, 0], "gps": y}


def test_run_goes_back_to_the_vectorised_path_once_the_lock_has_settled(tables, monkeypatch):
    """Slow readings off the schedule from phase 0, the offset changing mid-array, a sensor silent
    then back at another phase, a value held after settling (:func:`settling_cases`): run steps
    only the rows up to each reading that moves the phase and runs the rest on the vectorised
    fixed schedule (fewer than 3 % of the rows stepped; before, every row up to the last reading
    the lock may place), giving what the step loop gives, whole and in pieces."""
    stepped, step = [], Runtime._run_stepped
    monkeypatch.setattr(Runtime, "_run_stepped", lambda self, u, *a: stepped.append(len(u)) or step(self, u, *a))
    for table, data in settling_cases(tables):
        ref = Runtime(table)
        (est, ran), warned = recorded(lambda ref=ref, data=data: step_rows(ref, data))
        assert len(set(((ran - np.arange(len(ran))) % table.period).tolist())) >= 3  # phase 0, moved twice or more
        stepped.clear()
        rt = Runtime(table)
        out, got = recorded(lambda rt=rt, data=data: rt.run(data))
        assert 0 < sum(stepped) < 0.03 * len(est)
        assert close(out, est, table) and got == warned
        assert rt.counts == ref.counts and rt.state()["lock"] == ref.state()["lock"] and rt.phase == ref.phase
        pieces = Runtime(table, warn=False)
        cut = np.concatenate([pieces.run({k: v[a:a + 2500] for k, v in data.items()})
                              for a in range(0, len(est), 2500)])
        assert close(cut, est, table)
        assert pieces.counts == ref.counts and pieces.state()["lock"] == ref.state()["lock"]


def summed(counts):
    """The counts of runtimes that ran one after another, as one runtime's."""
    out = {}
    for c in counts:
        for what, per in c.items():
            for name, n in per.items():
                out.setdefault(what, {}).setdefault(name, 0)
                out[what][name] += n
    return out


# ---------------------------------------------------------------- (b) the lock on a common offset, lock=False
def rms(est, X, table, start):
    d = np.asarray(est) - X[:, 0]
    return float(np.sqrt(np.mean((wrap(d) if table.wrap_angle else d)[start:] ** 2)))


@pytest.mark.parametrize("which", range(4))
def test_the_lock_costs_nothing_on_a_common_offset(tables, which):
    """Every slow sensor at one random offset: lock=True from phase 0 has, after a start-up, the
    RMS error of the runtime started at the phase that aligns the schedule with the same rows
    (within 1.1x; measured 0.9999 to 1.00000006)."""
    table = tables[which]
    for seed in (which, 10 + which):
        data, X = case(table, 3000, seed, "common")
        read = np.column_stack([~np.isnan(data[s.name]) for s in table.measurements])
        mask, rows = table.schedule.mask(), np.arange(3000)
        late = next(c for c in range(table.period) if np.array_equal(read, mask[(rows - c) % table.period]))
        aligned = Runtime(table, lock=False)  # the fixed schedule, its phase 0 at row `late`
        aligned.phase = -late
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ref = aligned.run(data)
            rt = Runtime(table)
            got = rt.run(data)
        assert rt.counts == aligned.counts == {}
        assert rms(got, X, table, 1000) <= 1.1 * rms(ref, X, table, 1000)


@FEW
@given(cases)
def test_lock_false_is_the_fixed_schedule(tables, c):
    """lock=False: stepping or running any arrival pattern gives bit for bit what the same rows
    give with every reading off the fixed schedule removed, those readings counted (as tallied here)."""
    table = tables[c[0]]
    data, _ = case(table, c[2], c[3], c[1], c[4])
    fixed = {k: v.copy() for k, v in data.items()}
    phases = np.arange(c[2]) % table.period
    for i, s in enumerate(table.measurements):
        fixed[s.name][~table.schedule.mask()[phases, i]] = np.nan
    rt = Runtime(table, lock=False, warn=False)
    est, _ = step_rows(rt, data)
    np.testing.assert_array_equal(est, step_rows(Runtime(table, lock=False), fixed)[0])
    np.testing.assert_array_equal(Runtime(table, lock=False, warn=False).run(data),
                                  Runtime(table, lock=False).run(fixed))
    assert rt.counts == tally(table, data, phases)


# ---------------------------------------------------------------- (c) every reading used or counted once
@FEW
@given(cases)
@example((0, "jitter", 700, 3, False))  # a reading counted twice, or used and counted (test_a_reading_refused_...)
def test_every_reading_is_used_or_counted_once(tables, c):
    """Over any arrival pattern, the steps' counts are the tally made here from the phase each
    step ran at (a usable reading without a gain there is unscheduled, an inf or beyond 1e12
    rejected), a sensor with unscheduled readings is warned of once, and changing the value of
    every reading counted as unscheduled changes no estimate (they were not used)."""
    table = tables[c[0]]
    data, _ = case(table, c[2], c[3], c[1], c[4])
    rt = Runtime(table)
    (est, ran), warned = recorded(lambda: step_rows(rt, data))
    counts = tally(table, data, ran)
    assert rt.counts == counts
    assert sorted(w.split(":")[0] for w in warned) == sorted(counts.get("unscheduled", {}))
    moved = {k: v.copy() for k, v in data.items()}
    for i, s in enumerate(table.measurements):
        y = moved[s.name]
        y[np.isfinite(y) & (np.abs(y) <= 1e12) & ~table.schedule.mask()[ran, i]] += 0.3
    np.testing.assert_array_equal(step_rows(Runtime(table, warn=False), moved)[0], est)


# ---------------------------------------------------------------- (d) ArrivalKalman.step, the textbook filter
def textbook_kalman(table, data):
    """The Kalman filter of the table's ``F, B, H, Q, R`` written out tick by tick (``P0`` the
    table's ``P[0]``; the estimate after the tick's readings; a missing input holds the last; angle
    innovations wrapped)."""
    F, B, H, Q, R = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H, table.Q, table.R))
    x, P, held = np.zeros(len(F)), np.asarray(table.P[0], dtype=float), np.zeros(B.shape[1])
    angle = np.array([bool(table.wrap_angle) and s.order == 0 for s in table.measurements])
    us = np.column_stack([data[s.name] for s in table.inputs])
    ys = np.column_stack([data[s.name] for s in table.measurements])
    out = []
    for u, y in zip(us, ys, strict=True):
        held = np.where(np.isfinite(u) & (np.abs(u) <= 1e12), u, held)
        seen = np.isfinite(y) & (np.abs(y) <= 1e12)
        if seen.any():
            Hs, e = H[seen], y[seen] - H[seen] @ x
            e = np.where(angle[seen], wrap(e), e)
            K = P @ Hs.T @ np.linalg.inv(Hs @ P @ Hs.T + R[np.ix_(seen, seen)])
            x, P = x + K @ e, (np.eye(len(x)) - K @ Hs) @ P
        out.append(x[0])
        x, P = F @ x + B @ held, F @ P @ F.T + Q
    return np.array(out)


@pytest.mark.parametrize("kind", KINDS)
def test_arrival_kalman_step_is_the_textbook_filter(tables, kind):
    """ArrivalKalman.step over any arrival pattern (readings inf or beyond 1e12 now and then) has
    the RMS error of the textbook filter within 1.05x (measured equal to 1e-13, the estimates to 1e-9)."""
    for which in range(4):
        table = tables[which]
        data, X = case(table, 800, 7 * which + KINDS.index(kind), kind, bad=which % 2 == 1)
        kf = ArrivalKalman(table)
        est = np.array([kf.step(**{k: v[r] for k, v in data.items() if not np.isnan(v[r])})
                        for r in range(800)])
        ref = textbook_kalman(table, data)
        assert rms(est, X, table, 300) <= 1.05 * rms(ref, X, table, 300)
        assert close(est, ref, table, tol=1e-9)


# ---------------------------------------------------------------- timing.rotation
@FEW
@given(st.integers(0, 3), st.lists(st.integers(0, 10**6), min_size=2, max_size=2))
def test_rotation_is_the_smallest_shift_that_places_every_sensor(tables, which, draws):
    """rotation gives the smallest c in range(period) with every sensor's offset minus c a
    multiple of its own period, or None when no c in range(period) has that (searched here)."""
    table = tables[which]
    steps = {s.name: _pattern(table.schedule, s.name)[1] for s in table.measurements}
    offsets = {name: d % step for (name, step), d in zip(steps.items(), draws * len(steps), strict=False)}
    found = [c for c in range(table.period) if all((o - c) % steps[n] == 0 for n, o in offsets.items())]
    assert rotation(offsets, steps, table.period) == (found[0] if found else None)


# ---------------------------------------------------------------- regressions
def test_a_reading_refused_before_a_relock_in_its_step_is_counted_once_and_not_used(heading):
    """Compass and odometry both 5 ticks off at row 155: the compass (row 0 of H) is refused (the
    odometry holds the phase), then the odometry relocks and the step ran again with the compass
    reading, which the lock refused a second time (counted 2 for one reading); and in a clock glitch
    (both a tick late at one tick) it was used at the new phase though counted and warned of as not
    used, its use then holding the odometry off its phases for the next 9 readings."""
    n = 160
    data = {"gyro": np.zeros(n), "odometry": np.full(n, np.nan), "compass": np.full(n, np.nan)}
    data["odometry"][0:151:10] = 0.0
    data["compass"][[0, 100, 155]] = 0.0
    data["odometry"][155] = 0.0
    rt = Runtime(heading, warn=False)
    step_rows(rt, data)
    assert rt.counts == {"unscheduled": {"compass": 1}}

    glitch = {"gyro": np.zeros(400), "odometry": np.full(400, np.nan), "compass": np.full(400, np.nan)}
    glitch["odometry"][0::10] = 0.0
    glitch["compass"][0::100] = 0.0
    for name in ("odometry", "compass"):
        glitch[name][[200, 201]] = [np.nan, 0.0]
    rt = Runtime(heading, warn=False)
    est, _ = step_rows(rt, glitch)
    assert rt.counts == {"unscheduled": {"compass": 1}}
    moved = {k: v.copy() for k, v in glitch.items()}
    moved["compass"][201] = 1.0  # the reading counted as not used changes nothing
    np.testing.assert_array_equal(step_rows(Runtime(heading, warn=False), moved)[0], est)


def test_a_held_value_from_an_off_phase_tick_runs_as_the_steps_do():
    """A 1 Hz GPS value held and repeated every tick from tick 17 (phase 0 reads it): the steps lock
    to its first reading and refuse every repeat; run judged the sensor "given too often" by its
    count over the whole call and kept the unlocked schedule (1.30 m from the steps, one count
    more, phase 0 against 33), and a run cut in pieces judged each piece alike.  Now the readings
    the lock would refuse as faster (each less than half the spacing after the last) are found
    reading by reading: the first steps and locks, the repeats stay vectorised."""
    from cfdesign.sim.signals import sinusoid_readings

    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    data = sinusoid_readings(table, 2000)
    data["gps"][:17] = np.nan
    ref = Runtime(table)
    with pytest.warns(UserWarning, match="faster than designed") as stepped_warnings:
        est, _ = step_rows(ref, data)
    rt = Runtime(table)
    with pytest.warns(UserWarning) as run_warnings:
        out = rt.run(data)
    assert [str(w.message) for w in run_warnings] == [str(w.message) for w in stepped_warnings]
    np.testing.assert_allclose(out, est, rtol=0, atol=1e-12 * np.abs(est).max())
    assert rt.counts == ref.counts == {"unscheduled": {"gps": 1943}} and rt.state()["lock"] == ref.state()["lock"]
    assert rt.phase == ref.phase == 33
    pieces = Runtime(table, warn=False)
    cut = np.concatenate([pieces.run({k: v[i:i + 20] for k, v in data.items()}) for i in range(0, 2000, 20)])
    np.testing.assert_allclose(cut, out, rtol=0, atol=1e-12 * np.abs(est).max())
    assert pieces.counts == rt.counts and pieces.phase == 33
