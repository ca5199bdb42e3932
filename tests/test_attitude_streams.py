"""align_imu: gyro, accelerometer and magnetometer streams at their own rates and time stamps (a phone's logger) on
the gyro's clock, for AttitudeFilter.  Synthetic tracks of a known attitude (tests/test_attitude_filter.py's
``motion`` and ``imu`` at the gyro's rate): each stream reads every few ticks, stamped with jitter, so the
aligned arrays have a known answer, the full-rate readings where the stream read and NaN elsewhere."""

import warnings

import numpy as np
import pytest
from test_attitude_filter import imu, motion

from cfdesign import rotations as rot
from cfdesign.errors import AttitudeInputError
from cfdesign.nav import AttitudeFilter, align_imu, estimate_attitude, hard_iron_offset

RATE = 200.0
#: an Android-like epoch in nanoseconds (1.7e18): beyond float64's integers, so exactness needs int64 stamps
EPOCH_NS = 1_700_000_000_123_456_789


def phone_streams(n=6000, every=(1, 2, 4), jitter=0.2, drop=0.01, gap=None, seed=0):
    """A track at RATE for ``n`` ticks (6 s at rest, then turning), and its gyro, accelerometer and magnetometer
    read every ``every`` ticks (each from its own phase), stamped in int64 ns with uniform jitter of ``jitter``
    ticks, ``drop`` of the readings lost, and no reading at all in the ticks ``gap`` (a slice).

    Returns
    -------
    q : ndarray (n, 4)
        The true attitude per tick.
    full : dict
        The readings at every tick (``gyr``, ``acc``, ``mag``).
    streams : dict
        ``name: (stamps_ns, readings)`` per sensor.
    read : dict
        ``name: ticks`` where each sensor read.
    """
    rng = np.random.default_rng(seed)
    q = motion(n, rate=RATE, still_s=6.0)
    full = dict(zip(("gyr", "acc", "mag"), imu(q, rate=RATE), strict=True))
    streams, read = {}, {}
    for j, (name, m) in enumerate(zip(full, every, strict=True)):
        ticks = np.arange(j % m, n, m)
        if name != "gyr":
            ticks = ticks[ticks > 0]              # the gyro's first tick is the clock's tick 0
        keep = rng.random(len(ticks)) >= drop
        keep[-1] |= name == "gyr"                 # the gyro's last tick ends the clock
        ticks = ticks[keep]
        if gap is not None:
            ticks = ticks[(ticks < gap.start) | (ticks >= gap.stop)]
        jit = np.round(rng.uniform(-jitter, jitter, len(ticks)) * 1e9 / RATE).astype(np.int64)
        stamps = EPOCH_NS + ticks.astype(np.int64) * 5_000_000 + jit
        streams[name], read[name] = (stamps, full[name][ticks]), ticks
    return q, full, streams, read


def expected(full, read, n):
    """The readings on the ticks where each sensor read, NaN elsewhere."""
    out = {}
    for name, ticks in read.items():
        a = np.full((n, 3), np.nan)
        a[ticks] = full[name][ticks]
        out[name] = a
    return out


def merged_table(streams):
    """One table: a row per time stamp of any sensor, NaN where a sensor has no reading."""
    t = np.unique(np.concatenate([s[0] for s in streams.values()]))
    cols = {}
    for name, (stamps, values) in streams.items():
        a = np.full((len(t), 3), np.nan)
        a[np.searchsorted(t, stamps)] = values
        cols[name] = a
    return t, cols


def rms_angle(est, q):
    """RMS angle (deg) between two quaternion tracks."""
    dot = np.clip(np.abs(np.sum(est * q, axis=1)), 0.0, 1.0)
    return float(np.sqrt(np.mean(np.degrees(2 * np.arccos(dot)) ** 2)))


def test_each_reading_lands_on_the_tick_it_was_read_at():
    """200 / 100 / 50 Hz streams stamped in ns from an epoch float64 cannot hold exactly, jitter of +-0.2 tick,
    1 % of the readings lost: the rate is the gyro's, and the aligned arrays are exactly the full-rate readings
    where each sensor read and NaN elsewhere (lost gyro readings too: the filter holds the rate over them)."""
    q, full, streams, read = phone_streams()
    out = align_imu(*streams["gyr"], *streams["acc"], *streams["mag"], time_unit="ns")
    assert out.rate_hz == pytest.approx(RATE, rel=1e-6) and len(out.time) == len(q)
    assert out.t0 == min(stamps[0] for stamps, _ in streams.values())     # exact: an int64 stamp
    ticks = np.arange(len(q))
    assert np.abs(out.t0 + out.time * 1e9 - (EPOCH_NS + 5_000_000 * ticks)).max() < 0.2 * 5_000_000
    for name, want in expected(full, read, len(q)).items():
        np.testing.assert_array_equal(getattr(out, name), want)
        assert out.counts[name]["ticks"] == len(read[name]) and out.counts[name]["shared"] == 0
    assert out.time[1] - out.time[0] == pytest.approx(1.0 / RATE, rel=1e-6)


def test_a_merged_table_aligns_as_its_streams():
    """A merged export (one row per time stamp of any sensor, NaN for the others) given as the same time column
    for each sensor gives the arrays of the separate streams."""
    _, _, streams, _ = phone_streams(n=2000)
    t, cols = merged_table(streams)
    a = align_imu(t, cols["gyr"], t, cols["acc"], t, cols["mag"], time_unit="ns")
    b = align_imu(*streams["gyr"], *streams["acc"], *streams["mag"], time_unit="ns")
    for name in ("gyr", "acc", "mag"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.rate_hz == b.rate_hz


def test_the_filter_on_aligned_streams_is_as_accurate_as_on_one_clock():
    """The filter on the aligned 200 / 100 / 50 Hz streams is about as accurate as on every sensor at 200 Hz;
    the merged table taken row by row (what a user without align_imu runs) is warned of, and is far off."""
    q, full, streams, _ = phone_streams()
    ref = rms_angle(estimate_attitude(full["gyr"], full["acc"], full["mag"], RATE), q)
    out = align_imu(*streams["gyr"], *streams["acc"], *streams["mag"], time_unit="ns")
    aligned = rms_angle(estimate_attitude(out.gyr, out.acc, out.mag, out.rate_hz), q)
    assert aligned < 1.5 * ref + 0.1
    t, cols = merged_table(streams)
    with pytest.warns(UserWarning, match=r"have no rate but another sensor's reading.*align_imu"):
        est = estimate_attitude(cols["gyr"], cols["acc"], cols["mag"], RATE)
    assert rms_angle(est[np.searchsorted(t, streams["gyr"][0])], q[len(q) - len(streams["gyr"][0]):]) > 10 * aligned


def test_a_log_on_one_clock_with_a_few_readings_lost_is_not_warned_of():
    """A gyro that loses 3 % of its readings in a log on its own clock (a phone's, about 1 %) is no merged table: no
    warning; nor is a gap of seconds in the gyro alone."""
    _, full, _, _ = phone_streams(n=2000)
    gyr = full["gyr"].copy()
    gyr[np.random.default_rng(3).random(len(gyr)) < 0.03] = np.nan
    gyr[1000:1600] = np.nan
    with warnings.catch_warnings():         # any warning fails the test
        warnings.simplefilter("error")
        AttitudeFilter(RATE).run(gyr, full["acc"], full["mag"])


def test_a_pause_is_as_many_ticks_without_readings():
    """2 s without any reading: the clock runs on through it (400 ticks without a reading of any sensor), so the
    filter sees the gap for what it is and the readings after it are on their own ticks."""
    q, full, streams, read = phone_streams(n=4000, gap=slice(2000, 2400))
    out = align_imu(*streams["gyr"], *streams["acc"], *streams["mag"], time_unit="ns")
    assert len(out.time) == len(q)
    assert np.isnan(out.gyr[2000:2400]).all() and np.isnan(out.acc[2000:2400]).all()
    for name, want in expected(full, read, len(q)).items():
        np.testing.assert_array_equal(getattr(out, name), want)


def test_six_axis_streams_and_seconds():
    """Without a magnetometer (6D) and with stamps in float seconds."""
    _, full, streams, read = phone_streams(n=1000)
    t_g, t_a = ((streams[k][0] - EPOCH_NS) / 1e9 for k in ("gyr", "acc"))
    out = align_imu(t_g, streams["gyr"][1], t_a, streams["acc"][1])
    assert out.mag is None and out.rate_hz == pytest.approx(RATE, rel=1e-4)    # 5 s of +-0.2 tick jitter
    np.testing.assert_array_equal(out.acc, expected(full, read, 1000)["acc"])


@pytest.mark.parametrize(("change", "match"), [
    (lambda s: s.update(t_acc=s["t_acc"][::-1].copy()), r"t_acc goes back at row 1 .*sort each stream"),
    (lambda s: s.update(t_gyr=s["t_gyr"][:-1]), r"t_gyr has \d+ time stamps but gyr has \d+ readings"),
    (lambda s: s.update(t_mag=None), r"give t_mag and mag together"),
    (lambda s: s.update(time_unit="min"), r"time_unit must be one of s, ms, us, ns"),
    (lambda s: s.update(t_gyr=np.where(np.arange(len(s["t_gyr"])) == 5, np.nan, 1.0 * s["t_gyr"])),
     r"t_gyr: the time stamp of row 5 is nan"),
    (lambda s: s.update(t_acc=s["t_acc"].astype(str)), r"t_acc must be numbers"),
    (lambda s: s.update(acc=np.full_like(s["acc"], np.nan)), r"acc has no reading"),            # IndexError before
    (lambda s: s.update(t_mag=s["t_mag"][:0], mag=s["mag"][:0]), r"mag has no reading"),
    (lambda s: s.update(t_acc=s["t_acc"] // 1000), r"t_acc: none of the \d+ readings falls within the gyro's span"),
    # a last stamp of another clock: arrays for 2**62 ns of ticks were allocated (MemoryError) before
    (lambda s: s["t_gyr"].__setitem__(-1, 2**62), r"t_gyr jumps by 2.9\d+e\+09 s at row \d+: .*split the log"),
])
def test_bad_stamps_are_refused_naming_the_column(change, match):
    _, _, streams, _ = phone_streams(n=1000)
    args = {"t_gyr": streams["gyr"][0], "gyr": streams["gyr"][1], "t_acc": streams["acc"][0],
            "acc": streams["acc"][1], "t_mag": streams["mag"][0], "mag": streams["mag"][1], "time_unit": "ns"}
    change(args)
    with pytest.raises(AttitudeInputError, match=match):
        align_imu(**args)


def test_streams_of_other_lengths_given_to_the_filter_name_align_imu():
    """Three streams given as they are (one length each) are refused with the way to put them on one clock."""
    _, _, streams, _ = phone_streams(n=1000)
    with pytest.raises(AttitudeInputError, match=r"acc has \d+ rows but gyr has \d+: .*align_imu"):
        estimate_attitude(streams["gyr"][1], streams["acc"][1], streams["mag"][1], RATE)


def test_a_merged_tables_bad_stamp_is_named_by_its_row_in_the_table():
    """A merged table (one time column, NaN where a sensor has no sample): the row named is the table's, not the
    sensor's reading count (reading 10 of the accelerometer was row 31 of the table)."""
    t = np.arange(60) * 0.0025
    gyr, acc = np.full((60, 3), np.nan), np.full((60, 3), np.nan)
    gyr[::2], acc[1::2] = 0.0, [0.0, 0.0, 9.81]
    t[31] = np.nan
    with pytest.raises(AttitudeInputError, match=r"t_acc: the time stamp of row 31 is nan"):
        align_imu(t, gyr, t, acc)


# ---------------------------------------------------------------------- hard iron
def test_a_hard_iron_offset_is_warned_of_and_its_subtraction_gives_the_heading():
    """A field fixed to the sensor (an uncalibrated phone magnetometer: 15, -10, 30 µT beside a 45 µT field) turned
    the heading far off without a word.  Now run warns, naming the offset, and hard_iron_offset finds it (within
    0.5 µT), so the field less it gives the heading of the clean one."""
    q, full, _, _ = phone_streams(n=6000)
    offset = np.array([15.0, -10.0, 30.0])
    with pytest.warns(UserWarning, match=r"mag: the readings lie on a sphere centred at \(15, -10, 30\).*hard-iron"):
        bad = estimate_attitude(full["gyr"], full["acc"], full["mag"] + offset, RATE)
    found = hard_iron_offset(full["mag"] + offset)
    assert np.abs(found - offset).max() < 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fixed = estimate_attitude(full["gyr"], full["acc"], full["mag"] + offset - found, RATE)
    clean = rms_angle(estimate_attitude(full["gyr"], full["acc"], full["mag"], RATE), q)
    assert rms_angle(bad, q) > 5.0 and rms_angle(fixed, q) < clean + 0.2


def test_no_hard_iron_is_told_from_a_field_that_did_not_turn_or_was_disturbed_from_outside():
    """Readings that hardly turned (a sensor at rest) tell no sphere; a field disturbed from outside (the norm
    changing with the place, not the orientation) fits no sphere better than its mean; a calibrated one has none."""
    _, full, _, _ = phone_streams(n=6000)
    assert hard_iron_offset(full["mag"][:1000] + np.array([15.0, -10.0, 30.0])) is None     # the first 5 s: at rest
    assert hard_iron_offset(full["mag"]) is None
    place = 1.0 + 0.3 * np.sin(np.arange(6000) / 700.0)[:, None]                           # the norm 0.7-1.3 times
    assert hard_iron_offset(full["mag"] * place) is None


def test_an_offset_of_three_times_the_field_is_found_after_full_turns():
    """An uncalibrated phone's offset (150 µT beside a 50 µT field) puts the readings on a sphere so far from zero
    that their directions from it hardly turn (a spread of 0.02): the check of that turn returned None after full
    turns, and run said nothing.  The turn is now judged about the fitted centre: found within 2 µT, and warned of."""
    t = np.arange(6000) / RATE
    q = rot.normalize(rot.from_euler(np.column_stack((0.37 * t, 1.2 * np.sin(0.23 * t), 1.4 * np.sin(0.31 * t + 1)))))
    gyr, acc, mag = imu(q, rate=RATE, field=np.tile([0.0, 22.4, -44.7], (len(q), 1)), noise=(0.003, 0.03, 0.5))
    offset = 150.0 * np.array([0.6, -0.64, 0.48])
    assert np.abs(hard_iron_offset(mag + offset) - offset).max() < 2.0
    with pytest.warns(UserWarning, match=r"mag: the readings lie on a sphere centred at \(90, -96, 72\).*hard-iron"):
        estimate_attitude(gyr, acc, mag + offset, RATE)


def test_a_turn_about_one_axis_tells_no_offset():
    """Readings turned about one axis only lie on a circle: every sphere through it fits, the offset along the axis
    is unknown (the fit gave x = -1.3 for 35.9 µT, and run's warning advised subtracting it); now none is told."""
    rng = np.random.default_rng(1)
    th = np.linspace(0.0, 2.0 * np.pi, 1000)
    field, offset = np.array([-38.0, -30.9, -10.0]), np.array([35.9, 9.9, -32.8])
    c, s = np.cos(th), np.sin(th)                                      # the field turned about the body's x axis
    about_x = np.column_stack((np.full_like(th, field[0]), c * field[1] - s * field[2], s * field[1] + c * field[2]))
    about_x += offset + rng.normal(0, 0.3, (1000, 3))
    assert hard_iron_offset(about_x) is None


@pytest.mark.parametrize(("rate", "aligns"), [(100.0, True), (500.0, False)])
def test_an_hours_pause_aligns_within_the_tick_bound_and_is_refused_beyond_it(rate, aligns):
    """A gyro pause stays as NaN ticks up to MAX_TICKS_PER_READING a reading beyond a million ticks (the
    guide's bound): an hour's pause between two 10 s stretches is 362,000 ticks at 100 Hz and aligns,
    whole; at 500 Hz it is 1,810,000 ticks for 10,000 readings, refused naming the row after the jump."""
    t = np.arange(int(10 * rate)) / rate
    stamps = np.concatenate([t, t + 3610.0])
    gyr = np.random.default_rng(0).standard_normal((len(stamps), 3))
    n = round(3620 * rate)
    if aligns:
        out = align_imu(stamps, gyr, stamps, gyr)
        assert len(out.gyr) == n and np.isnan(out.gyr[len(t):-len(t)]).all()
        np.testing.assert_array_equal(out.gyr[-len(t):], gyr[len(t):])
    else:
        with pytest.raises(AttitudeInputError, match=rf"t_gyr jumps by 3600 s at row {len(t)}: .* {n} ticks"):
            align_imu(stamps, gyr, stamps, gyr)
