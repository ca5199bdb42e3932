"""Properties of the streaming multirate runtime over random arrival patterns, and the bugs they
found: Runtime.run equals a loop of Runtime.step (split, snapshot and restored alike), the phase
lock costs nothing on a common offset and lock=False is the fixed schedule, every usable reading
is used or counted once (against a tally made here), and ArrivalKalman.step is the textbook
Kalman filter written here."""

import numpy as np
import pytest
from conftest import HEADING

import cfdesign
from cfdesign.runtime import Runtime
from cfdesign.spec import parse_spec


@pytest.fixture(scope="module")
def heading():
    return cfdesign.design(parse_spec(HEADING))


def step_rows(rt, data):
    """Step ``data`` row by row (NaN left out); the estimates and the phase each step ran at."""
    names = list(data)
    est, ran = [], []
    for row in zip(*(data[k] for k in names), strict=True):
        est.append(rt.step(**{k: v for k, v in zip(names, row, strict=True) if not np.isnan(v)}))
        ran.append((rt.phase - 1) % rt.period)
    return np.array(est), np.array(ran, dtype=int)


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
