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
