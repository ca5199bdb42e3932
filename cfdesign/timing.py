"""Time is data: timestamps to base ticks, and the schedule locked to when sensors really arrive.

A gain table runs on a base tick ``T`` (its ``sample_time_s``) with a periodic schedule: the
phases at which each measurement sensor is read.  A log says when each reading happened.  Two
steps join them (docs/derivations.md, "Multirate gains"; the choice is argued in
``docs/logs.md``):

1. **Placement.**  A reading at time ``t`` goes to the base tick ``k = round((t - t0) / S)``
   (:func:`nearest_tick`: halves up), ``S`` the table's tick ``T`` or, when the log's clock
   drifts against it, the log's own (:func:`grid_fit`), ``t0`` the time of the log's first row
   where the input sensors read (the base clock; a reading logged before it is used at tick 0)
   moved to the phase of the grid: the nearest tick, so a reading is used at most ``S/2`` before
   or after it was taken (the worst-case placement latency; jitter of a few percent of a tick
   does not move it).  Times must be finite and increasing (rows at one time read different
   sensors), and the rate of the input sensors' rows must be the table's base rate within 1 %.
2. **Locking.**  Each slow sensor's arrivals are matched to its phases in the table's
   schedule, allowing it an offset of its own (the compass arriving at tick 37 of every 100,
   the odometry at ticks 3, 13, 23, ...).  Where the offsets amount to one rotation of the
   schedule, the table runs as designed from the matching phase.  Where they do not (each
   sensor at its own offset), the gains are recomputed for the actual arrival pattern: the
   periodic DARE of the table's own model over the shifted schedule
   (``cfdesign.designer.gains_for_schedule``), which is what the design would have given
   had it known the offsets.  A sensor whose offset wanders (a rate that drifts, arrivals that
   slip by a tick) gets a new segment with the gains of its new offset, so no reading is left
   without a gain; only a table without a model to recompute from (fixed gains) leaves the
   readings off its schedule unused, and those are counted and reported.  When the pattern
   keeps changing (the stretches average fewer than :data:`STEADY_PERIODS` periods: a rate
   that drifts, arrivals that straddle half a tick), or a sensor arrives faster than the table
   reads it (a 3.3 Hz GPS into a 3 Hz table: no periodic gain is there for the extra readings),
   no periodic gain is the right one for long: the log then runs the Kalman filter of the
   table's model with each tick's gain from the covariance recursion over the readings as they arrive
   (:class:`cfdesign.runtime.arrivals.ArrivalKalman`), which converges to the periodic gains
   wherever the pattern holds still.
"""

from __future__ import annotations

import bisect
import itertools
import re
from dataclasses import dataclass, field

import numpy as np

from .errors import DataError

__all__ = ["RATE_RTOL", "JITTER_TICKS", "STEADY_PERIODS", "PHASE_ROWS", "ARC_ROWS", "DRIFT_LAG", "FIT_ROWS",
           "FIT_START", "MAX_GAP_TICKS", "PAUSE_TICKS", "SWAP_ROWS", "BLURRED_TICKS", "rephase", "date_seconds",
           "nearest_tick", "grid_origin", "grid_fit", "place", "check_rate", "Segment", "Lock", "lock_schedule",
           "rotation"]

#: largest relative difference between a log's base rate and the table's
RATE_RTOL = 0.01
#: arrival patterns that last fewer periods than this on average are not steady: the log runs
#: the Kalman filter over the actual arrivals instead of periodic gains per stretch
STEADY_PERIODS = 20
#: time-stamp jitter (in ticks) allowed at each end of the span the base rate is measured over
JITTER_TICKS = 0.05
#: most base ticks between two rows of a log: the filter runs every tick of a gap, one value
#: per tick in memory (a time jump of 2e8 s at 5 Hz ran for minutes and asked for gigabytes; 9e6
#: ticks took 16 s of CPU)
MAX_GAP_TICKS = 1_000_000


def date_seconds(text: str) -> float:
    """An ISO 8601 date and time as seconds since 1970-01-01 UTC.

    The one reading of dates in time columns (:func:`cfdesign.logs.run_log`,
    ``cfdesign noise --time``): Python's :meth:`datetime.datetime.fromisoformat`
    (``2024-05-01T12:00:00.010``, ``2024-05-01 12:00:00,5+01:00``, a trailing ``Z``); a date
    without a time zone is taken as UTC (only differences between rows matter).  Python 3.10, whose
    ``fromisoformat`` reads fewer layouts, reads the same dates but for week
    dates (``2024-W18-3``).

    Parameters
    ----------
    text : str
        The cell.

    Returns
    -------
    float
        Seconds (microsecond resolution).

    Raises
    ------
    ValueError
        The text is not an ISO 8601 date.

    Examples
    --------
    >>> date_seconds("1970-01-01T00:01:00.5Z")
    60.5
    """
    from datetime import datetime, timezone

    text = text.strip()
    text = text[:-1] + "+00:00" if text.endswith(("Z", "z")) else text
    try:
        when = datetime.fromisoformat(text)
    except ValueError:  # Python 3.10 reads only the layout isoformat() writes
        when = datetime.fromisoformat(_iso_as_written(text))
    return (when if when.tzinfo else when.replace(tzinfo=timezone.utc)).timestamp()


#: a date and time as Python 3.11's ``fromisoformat`` reads it and 3.10's may not: the date with or
#: without hyphens, any one character before the time, the time with or without colons (hours,
#: minutes, seconds), a fraction of the seconds of any length after a dot or a comma, and an offset
#: of hours (``+01``), hours and minutes (``+0100``, ``+01:00``) or more (``+01:00:30.5``)
_ISO_311 = re.compile(r"(\d{4})(-?)(\d{2})\2(\d{2})"
                      r"(?:(.)(\d{2})(?:(:?)(\d{2})(?:\7(\d{2})(?:[.,](\d+))?)?)?"
                      r"(?:([+-])(\d{2})(?:(:?)(\d{2})(?:\13(\d{2})(?:[.,](\d+))?)?)?)?)?")


def _iso_as_written(text: str) -> str:
    """``text`` in the layout of :meth:`datetime.datetime.isoformat` (which Python 3.10 reads), the
    fractions cut to microseconds as Python 3.11 cuts them; ``text`` itself when it is not such a date.

    Parameters
    ----------
    text : str
        A date and time (``2024-05-01 12:00:00,5+0100``, ``20240501T1200+01``).

    Returns
    -------
    str
        ``2024-05-01 12:00:00.500000+01:00``, ``2024-05-01T12:00+01:00``.
    """
    m = _ISO_311.fullmatch(text)
    if m is None:
        return text
    (year, _, month, day, sep, hour, _, minute, second, fraction,
     sign, off_h, _, off_m, off_s, off_f) = m.groups()
    out = f"{year}-{month}-{day}"
    if sep is not None:
        out += sep + ":".join(v for v in (hour, minute, second) if v) + _micro(fraction)
    if sign is not None:  # 3.10 needs the offset's minutes
        out += sign + ":".join(v for v in (off_h, off_m or "00", off_s) if v) + _micro(off_f)
    return out


def _micro(fraction) -> str:
    """A fraction of a second's digits as ``.ffffff`` (cut, not rounded, to microseconds), or ''."""
    return f".{fraction[:6]:0<6}" if fraction else ""


def nearest_tick(x):
    """The tick nearest to ``x`` (in ticks), halves rounded up: ``floor(x + 1/2)``.

    The one rounding of placement (:func:`place`, :func:`cfdesign.logs.run_log`) and of the
    designer's schedules (``offset_s``, fractional rates:
    :func:`cfdesign.designer.multirate_schedule`), so that a reading exactly half a tick late
    lands on the tick the design put it on.

    Parameters
    ----------
    x : float or array_like
        Positions in ticks.

    Returns
    -------
    float or ndarray
        The nearest whole ticks (as floats).

    Examples
    --------
    >>> nearest_tick([2.5, 3.5, -0.5, 1.49]).tolist()
    [3.0, 4.0, 0.0, 1.0]
    """
    return np.floor(np.asarray(x, dtype=float) + 0.5)


#: rows over which the phase of a log's tick grid is measured (:func:`grid_origin`)
PHASE_ROWS = 200


def grid_origin(time, dt: float) -> float:
    """The time of tick 0 of a log: its first time moved to the phase of its first rows' grid.

    Rows are placed on ``nearest_tick((t - origin) / dt)``.  With the first row's own time as
    the origin, its time-stamp jitter shifts every other row: rows jittered by +-0.3 tick
    differ from it by up to 0.6 tick, and one row in ten of such a log landed on the tick
    of its neighbour (one of the two readings not used, the tick between them empty).  The
    origin here is the first time plus the circular mean of the fractional tick positions of
    the first :data:`PHASE_ROWS` rows, so a jitter within half a tick of a steady grid puts
    every row on its own tick; the first row stays on tick 0.

    Parameters
    ----------
    time : array_like
        Row times (s), ascending, at least one.
    dt : float
        The table's base tick (s).

    Returns
    -------
    float
        The time of tick 0 (s), within half a tick of ``time[0]``.

    Examples
    --------
    >>> abs(grid_origin([0.2, 0.9, 2.1, 2.8, 4.0], 1.0)) < 1e-12   # first row 0.2 s late on a 1 s grid
    True
    """
    t = np.asarray(time, dtype=float)
    p = (t[:PHASE_ROWS] - t[0]) / dt
    phase = float(np.angle(np.mean(np.exp(2j * np.pi * (p - np.rint(p)))))) / (2 * np.pi)  # (-1/2, 1/2]
    return float(t[0] + phase * dt)


#: rows whose phases give the shortest arc that holds them (:func:`grid_fit`): enough that the
#: empty arc of bounded jitter (0.02 tick for +-0.49 tick) is longer than the gaps between phases
ARC_ROWS = 10_000
#: rows over which a step is measured for a log's own spacing (:func:`grid_fit`)
DRIFT_LAG = 100
#: the first rows of a log its grid is fitted to (:func:`grid_fit`: 200 ppm of drift shows as 40 ticks)
FIT_ROWS = 200_000
#: the rows the least-squares slope is first fitted over (:func:`grid_fit`), doubled up to :data:`FIT_ROWS`
FIT_START = 1000


def grid_fit(time, dt: float) -> tuple:
    """The tick grid of a log's base-rate rows: ``(origin, spacing)``, rows placed on
    ``nearest_tick((t - origin) / spacing)``.

    Two things move rows of a steady clock onto their neighbours' ticks when the grid is the
    table's ``dt`` from :func:`grid_origin`.  A log clock that drifts against the table (a rate
    0.5 % off, within the :data:`RATE_RTOL` that :func:`check_rate` allows) gains a tick every
    200: two rows on one tick (the second reading of the input not used) or a tick without one.
    And time-stamp jitter that spans most of a tick (uniform within +-0.49 tick, or a delay of
    0 to 0.9 tick when the stamp is the time of receipt) leaves the circular mean of the phases
    almost undetermined: one input row in four of such a log shared a tick.  So:

    * the spacing is, of ``dt`` and the log's own, the one that puts fewer rows on a shared
      tick or skips fewer ticks between rows (``dt`` on a tie: a log on the table's clock is
      placed on the table's ticks).  The log's own is the median step over
      :data:`DRIFT_LAG` rows (a dropped row moves few of them), refined by the least-squares
      slope of the times over the ticks it puts them on, over the first :data:`FIT_START` rows
      and then a span doubled each time (a spacing a few parts in a million off slips the ticks
      of a long span, and a slope fitted to slipped ticks is that spacing again);
    * the origin is, of the circular mean of the phases (:func:`grid_origin`) and the middle of
      the shortest arc that holds the phases of the first :data:`ARC_ROWS` rows (the centre of
      bounded jitter), the one that puts fewer of the rows on a shared tick (the circular mean
      on a tie).

    A rate beyond :func:`check_rate`'s tolerance keeps ``dt`` (the log is refused there).

    Parameters
    ----------
    time : array_like
        Times (s) of the rows where the input sensors read, ascending, at least one (the first
        :data:`FIT_ROWS` are used).
    dt : float
        The table's base tick (s).

    Returns
    -------
    tuple of float
        ``(origin, spacing)`` in seconds.

    Examples
    --------
    >>> t = 0.2 + 1.005 * np.arange(1000)              # a clock 0.5 % slow against a 1 s tick
    >>> origin, spacing = grid_fit(t, 1.0)
    >>> round(origin, 9), round(spacing, 9)
    (0.2, 1.005)
    """
    t = np.asarray(time, dtype=float)[:FIT_ROWS]
    fits = [(dt, _phase_origin(t, dt))]
    lag = min(DRIFT_LAG, len(t) // 4)
    if lag >= 2:
        # the median step over `lag` rows (a dropped row moves few of them), then the least-squares
        # slope of the times over the ticks it puts them on, over a span of rows doubled each time
        # (FIT_START first): the ticks of the rows are only right where the spacing so far keeps
        # them within half a tick, and a slope fitted to wrong ticks is that spacing again
        spacing = float(np.median(t[lag:] - t[:-lag])) / lag
        m, last = min(FIT_START, len(t)), 0
        while abs(spacing / dt - 1) <= 2 * RATE_RTOL and last < 3:  # the whole span up to three times
            part = t[:m]
            k = nearest_tick((part - _phase_origin(part, spacing)) / spacing)
            k -= k.mean()
            before, spacing = spacing, (float(k @ (part - part[0]) / (k @ k)) if k[-1] > k[0] else dt)
            if m == len(t):
                last = 3 if spacing == before else last + 1  # the same ticks again: the same slope
            m = min(2 * m, len(t))
        if abs(spacing / dt - 1) <= RATE_RTOL:
            fits.append((spacing, _phase_origin(t, spacing)))
    # the grid that puts the rows one a tick: fewest rows sharing a tick or ticks skipped (dt on a tie)
    spacing, origin = min(fits, key=lambda f: _irregular(t, f[1], f[0]))[:2]
    return origin, spacing


#: a pause (in ticks) between rows where the inputs read after which the phase of a log's grid is
#: fitted again (:func:`rephase`): a logger stopped and started again keeps its rate, not its phase
PAUSE_TICKS = 50


def rephase(time, origin: float, spacing: float) -> float:
    """The origin of a log's grid for the rows after a pause: the phase of their times, fitted
    as :func:`grid_fit` fits it, on the tick numbers of the grid before the pause.

    A logger that stops for a while and starts again keeps its rate but not the phase of its
    ticks: rows half a tick off the old grid, jittered, landed two on a tick and left the next
    without one (one input reading in six not used after a 10 s pause of a log jittered by
    +-0.3 tick).

    Parameters
    ----------
    time : array_like
        Times (s) of the rows where the input sensors read after the pause, ascending, at least one.
    origin : float
        The origin (s) of the grid before the pause.
    spacing : float
        The grid's spacing (s).

    Returns
    -------
    float
        The new origin: the fitted phase, moved by whole ticks to within half a tick of the old
        grid, so that tick numbers carry on (rows placed on ``nearest_tick((t - origin) / spacing)``).

    Examples
    --------
    >>> round(rephase([10.4, 11.4, 12.4], 0.0, 1.0), 9)   # restarted 0.4 tick off a 1 s grid
    0.4
    """
    t = np.asarray(time, dtype=float)
    new = _phase_origin(t, spacing)
    return float(new - nearest_tick((new - origin) / spacing) * spacing)


def _irregular(t, origin, spacing) -> int:
    """Rows that share a tick, and ticks skipped between rows, on a grid."""
    return int(np.sum(np.abs(np.diff(nearest_tick((t - origin) / spacing)) - 1)))


def _phase_origin(t, spacing):
    """Of the circular mean of the first rows' phases and the middle of the shortest arc that
    holds them, the origin that leaves fewer rows on a shared tick (:func:`grid_fit`)."""
    mean = grid_origin(t, spacing)
    p = np.sort(((t[:ARC_ROWS] - t[0]) / spacing) % 1.0)
    if len(p) < 2:
        return mean
    gaps = np.diff(np.concatenate([p, [p[0] + 1.0]]))
    i = int(np.argmax(gaps))  # the arc from p[i+1] round to p[i] holds every phase
    middle = (p[(i + 1) % len(p)] + (1.0 - gaps[i]) / 2) % 1.0
    arc = float(t[0] + (middle - np.rint(middle)) * spacing)

    def shared(origin):
        k = nearest_tick((t - origin) / spacing)
        return int(np.sum(np.diff(k) == 0))

    return arc if shared(arc) < shared(mean) else mean


def _written_to(t):
    """The coarsest power of ten (s) that every finite time of ``t`` is a whole multiple of, or None:
    epoch seconds written with ten digits (``1700000000``) are written to 1 s."""
    t = np.asarray(t, dtype=float)
    t = t[np.isfinite(t)]
    if not np.any(t):
        return None
    for e in range(12, -10, -1):
        q = t / 10.0 ** e
        if t.size and np.all(np.abs(q - np.rint(q)) <= 8 * np.finfo(float).eps * np.max(np.abs(q))):
            return 10.0 ** e
    return None


def place(time, dt: float, *, base_rows=None, source: str = "log", first_line: int = 2, rate: bool = True,
          readings=None, where=None, time_scale: float = 1.0):
    """Base ticks of the rows of a log: ``round((t - t0) / dt)``.

    Parameters
    ----------
    time : array_like
        Row times (s).
    dt : float
        The table's base tick (s).
    base_rows : array_like of bool, optional
        Rows where every input sensor has a reading: their spacing is the log's base rate,
        checked against ``1/dt``.  Default: every row.
    source : str
        Name of the log, for messages.
    first_line : int
        File line of the first row (messages name lines as a spreadsheet does).
    rate : bool
        Check the base rate (False: the caller checks it once over the whole log, with
        :func:`check_rate`; a block of a few rows cannot tell a jittered rate from a wrong one).
    readings : dict, optional
        ``{sensor: bool array}``: which rows hold a reading of each sensor.  Rows at one time
        are then allowed when no sensor reads in two of them (a log with one row per reading,
        the compass stamped at the time of a gyro sample); without it every repeated time is
        refused.
    where : callable, optional
        ``where(i)``: where row ``i`` is, for a message: ``'line N'`` where the rows are not one a
        line (a CSV with blank lines between them), ``'row N'`` in a Parquet log, which has no
        lines (``cfdesign.logs.read._Lines.at``); default ``line first_line + i``.
    time_scale : float
        Seconds per unit of the times as the log wrote them (``1e-6`` for ``--time-unit us``): the
        message of a gap or a rate that another unit explains names that unit's ``--time-unit``.

    Returns
    -------
    ndarray of int64
        The tick of every row, ``0`` for the first.

    Raises
    ------
    DataError
        A time that is not finite, goes back, or repeats with a second reading of one sensor
        (naming its line, or a Parquet log's row), a gap of more than :data:`MAX_GAP_TICKS` ticks
        after a row (naming it so), or a base rate more than :data:`RATE_RTOL` off the table's (naming both).
    """
    t = np.asarray(time, dtype=float)
    if not t.size:
        return np.zeros(0, dtype=np.int64)
    where = where or (lambda i: f"line {first_line + int(i)}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:  # an empty cell is NaN: say so (a spreadsheet's rows of empty cells below the data)
        raise DataError(f"{source} {where(bad[0])}: " + (
            "no time (an empty cell; every row needs one)" if np.isnan(t[bad[0]])
            else f"time {float(t[bad[0]])!r} is not a finite number of seconds"))
    d = np.diff(t)
    back = np.flatnonzero(d < 0) if readings is not None else np.flatnonzero(d <= 0)
    if readings is not None:  # a repeated time is a duplicate when a sensor reads twice at it
        first = np.concatenate([[True], d != 0])  # the first row at each time
        start = np.maximum.accumulate(np.where(first, np.arange(len(t)), 0))
        for read in readings.values():
            read = np.asarray(read, dtype=np.int64)
            count = np.cumsum(read)  # count - count[start] + read[start]: readings at this time so far
            twice = np.flatnonzero((read > 0) & (count - count[start] + read[start] > 1))
            if twice.size and (not back.size or twice[0] - 1 < back[0]):
                back = np.array([twice[0] - 1])
    if back.size:
        i = back[0] + 1
        what = "repeats" if d[back[0]] == 0 else "goes back from"
        coarse = _written_to(t) if what == "repeats" else None
        raise DataError(f"{source} {where(i)}: time {float(t[i])!r} {what} {float(t[i - 1])!r} on the "
                        f"{_noun(where, i)} before (times must increase"
                        + (", and rows at one time must read different sensors)" if readings is not None else ")")
                        + (f": the times are written to {coarse:g} s, coarser than the table's tick of {dt:g} s "
                           "(write them with more digits)" if coarse is not None and coarse > dt else
                           _back_hint(t[max(0, i - 101):i], float(t[i]), dt) if what != "repeats" else ""))
    gap = np.flatnonzero(d > MAX_GAP_TICKS * dt)
    if gap.size:
        i = gap[0] + 1
        step = float(d[gap[0]])
        # the log's usual step half a tick to 10,000 ticks in a finer unit (PX4's microseconds, ROS's
        # %time), not a gap: the median step, as a jittered step (1.14 ticks of a 200 Hz PX4 log) and a
        # slow sensor's file (a 1 Hz compass: 100 ticks) had missed the hint asking for one to ten
        usual = float(np.median(d[d > 0]))
        unit = _unit_hint(usual, dt, time_scale, lambda ticks: 0.5 <= ticks <= 10_000) or (
            "are the times in seconds? Split the log at the gap")
        raise DataError(f"{source} {where(i)}: time {float(t[i])!r} is {step:.6g} s after the "
                        f"{_noun(where, i)} before, a gap of more than {MAX_GAP_TICKS} ticks of {dt:g} s (the filter "
                        f"runs every tick): {unit}")
    if rate:
        check_rate(t if base_rows is None else t[np.asarray(base_rows, dtype=bool)], dt, source, time_scale)
    return nearest_tick((t - t[0]) / dt).astype(np.int64)


#: the widths (bits) of the counters a logger's clock may be, which wrap back to 0
_COUNTER_BITS = (16, 31, 32)


def _back_hint(before, after: float, dt: float) -> str:
    """Why a time goes back, for the message that names it: a counter that wraps (a 32-bit count of
    microseconds wraps every 71.6 min), a clock that restarts (two recordings in one file), or
    rows out of order.  ``before``: the times of the rows before (s, the last one's time last);
    ``after``: the time that goes back from it."""
    steps = np.diff(before)
    step = float(np.median(steps[steps > 0])) if np.any(steps > 0) else dt
    for bits in _COUNTER_BITS:  # the time unwrapped is a step or a few after the row before
        for _, short, scale in (("", "", 1.0), *_TIME_UNITS):
            wrap = 2.0 ** bits / scale  # a counter's times lie in [0, wrap)
            if 0 <= after and before[-1] < wrap and 0 < after + wrap - before[-1] <= PAUSE_TICKS * step:
                span = next((f", {wrap / n:.4g} {w}" for n, w in ((86400, "days"), (3600, "h"), (60, "min"))
                             if wrap >= 2 * n), "")
                unit = f"{short} ({wrap:.7g} s{span})" if short else "of the column's unit"
                return (f": a counter that wraps at 2^{bits} {unit}? Add 2^{bits}{' ' + short if short else ''} "
                        "to the times from there on, or split the log there")
    if before[-1] - after > PAUSE_TICKS * step:
        return ": the clock restarted (a logger restart, or two recordings in one file)? Split the log there"
    return ": rows out of order? Sort them by time"


def _noun(where, i) -> str:
    """What ``where(i)`` counts the log in (``line`` of a text log, ``row`` of a Parquet log): the
    row before ``i`` is named as ``where`` names ``i``."""
    return where(i).split(" ", 1)[0]


def _row_spacing(t, dt):
    """``(spacing, times)`` of a log whose rows between two pauses (the longest such stretch) are on
    consecutive ticks of a grid (one row a tick, none skipped or shared): the least-squares slope
    of their times over the rows, and those times; None when no grid puts them so (rows
    dropped, a wrong rate)."""
    cuts = [0, *(np.flatnonzero(np.diff(t) > PAUSE_TICKS * dt) + 1), len(t)]
    a, b = max(itertools.pairwise(cuts), key=lambda c: c[1] - c[0])  # the longest stretch between pauses
    fitted = t[a:min(b, a + FIT_ROWS)]
    if len(fitted) < 3:
        return None
    rows = np.arange(len(fitted)) - (len(fitted) - 1) / 2
    slope = float(rows @ (fitted - fitted.mean()) / (rows @ rows))
    if slope > 0 and any(_one_a_tick(nearest_tick((fitted - o) / s))
                         for o, s in ((_phase_origin(fitted, slope), slope), grid_fit(fitted, dt))):
        return slope, fitted
    return None


#: rows in a row that jitter may put a tick off their own before they are taken for rows missing
SWAP_ROWS = 3
#: RMS distance (ticks) of times from the grid fitted to them beyond which the grid does not
#: tell the rate (:func:`check_rate`): times spread evenly over a tick are 1/sqrt(12) = 0.289
#: from any grid, jitter of +-0.4 tick is 0.23 from its own
BLURRED_TICKS = 0.25


def _misfit(t, spacing) -> float:
    """The mean square of the times ``t`` about the straight line fitted to them over the ticks a
    grid of ``spacing`` puts them on."""
    k = nearest_tick((t - _phase_origin(t, spacing)) / spacing)
    k -= k.mean()
    slope = float(k @ (t - t.mean()) / (k @ k)) if k @ k > 0 else 0.0
    return float(np.mean((t - t.mean() - slope * k) ** 2))


def _one_a_tick(k) -> bool:
    """Whether ticks ``k`` (of consecutive rows) are one a row: each on the tick after the one
    before, or a tick off it for at most :data:`SWAP_ROWS` rows (a row jittered onto its
    neighbour's tick, the next back on its own: a Gaussian jitter of 0.2 tick puts one row in a
    hundred there).  A row missing moves every row after it a tick on (a grid fitted to rows
    with some missing moves them back only after many rows)."""
    off = np.cumsum(np.diff(k) - 1)  # ticks the rows are off the consecutive ticks
    if not np.all(np.abs(off) <= 1):
        return False
    moved = np.flatnonzero(np.diff(np.concatenate([[0], off != 0, [0]]).astype(np.int8)))
    return bool(np.all(moved[1::2] - moved[::2] <= SWAP_ROWS))


def _tick_spacing(t):
    """The spacing of times some of whose rows are missing: the least-squares slope of the times
    over the ticks they fall on, from the median step, over a span of rows doubled each time."""
    steps = np.diff(t[:FIT_ROWS])
    spacing = float(np.median(steps))
    for _ in range(3):  # the median of the one-tick steps: those of dropped rows (two ticks or more) left out
        near = steps[(steps > 0.5 * spacing) & (steps < 1.5 * spacing)]
        if not near.size:
            break
        spacing = float(np.median(near))
    if not spacing > 0:
        return spacing
    m, end = min(32, len(t)), min(len(t), FIT_ROWS)
    while True:  # the slope of the times over their ticks, over a span doubled each time
        part = t[:m]
        k = nearest_tick((part - grid_origin(part, spacing)) / spacing)
        k -= k.mean()
        if np.dot(k, k) > 0:
            spacing = float(np.dot(k, part - part.mean()) / np.dot(k, k))
        if m == end:
            break
        m = min(2 * m, end)
    return spacing


def check_rate(t, dt, source, time_scale=1.0):
    """The base spacing of the times ``t`` is ``dt`` within :data:`RATE_RTOL` (DataError naming both rates).

    Where the rows of the longest stretch between pauses (:data:`PAUSE_TICKS`) lie one a tick on a grid (that of
    :func:`grid_fit`, or of their own slope: none dropped; a row jittered onto its neighbour's tick
    for at most :data:`SWAP_ROWS` rows), the spacing is the
    least-squares slope of their times over the rows; jitter of +-0.45 tick had put the ticks below
    a few percent off (one such log of 300 rows in three refused at 5 Hz, and one 4 % off taken).
    Otherwise the spacing is the least-squares slope of the times over the ticks they fall on, fitted
    first over the first 32 rows and then over a span doubled each time (the ticks of a span are
    right while the spacing so far keeps its rows within half a tick), from the median of the
    steps near it (those within half a step of the median, found again three times); the span
    stops at :data:`FIT_ROWS` rows, as :func:`grid_fit`'s.  The ticks come from the times, not
    from counting rows, so a row the IMU dropped counts as the ticks it skips: a log missing one
    row in twenty with +-0.2 tick of jitter had been refused as 98.8 Hz for 100 Hz (the steps
    over dropped rows pulled the median of all steps up, and the span was counted in that
    median).  The fit is not the median step: time-stamp jitter of a few percent of a tick moves
    a single step by as much, and with rows jittered by more than a quarter of a tick a single
    step can round to two ticks (1.6 -> 2) and its neighbour to none (counting every step as at
    least one tick made a log jittered by +-0.3 tick 1.4 % too fast).  The jitter of the two
    ends (:data:`JITTER_TICKS` each) is allowed on top of :data:`RATE_RTOL`, so a short log is
    not refused for its jitter.  Jitter of +-0.45 tick with a few percent of the rows missing
    still blurs one tick into two.

    Parameters
    ----------
    t : array_like
        Times (s) of the rows where the input sensors read, ascending; fewer than three are
        not checked.
    dt : float
        The table's base tick (s).
    source : str
        Name of the log, for the message.
    time_scale : float
        Seconds per unit of the times as the log wrote them: a rate that another unit explains
        names that unit's ``--time-unit`` (microseconds read as milliseconds name ``us``).

    Raises
    ------
    DataError
        The log's base rate differs from ``1/dt`` by more than the tolerance; the message gives
        both rates.  Where the times fit the table's rate with rows missing as well as another
        with every row present, or lie about as far from the grid fitted to them as from any
        (more than :data:`BLURRED_TICKS` RMS: jitter of +-0.4 tick with a row in seven missing),
        the message says the rate cannot be told from them instead of naming a wrong one.
    """
    t = np.asarray(t, dtype=float)
    if len(t) < 3:
        return
    rows, spacing, span = _row_spacing(t, dt), _tick_spacing(t), t[-1] - t[0]
    skipped = spacing  # the spacing of ticks with some skipped
    if rows is not None and not (spacing > 0 and _misfit(rows[1], spacing) < 0.5 * _misfit(rows[1], rows[0])):
        spacing, span = rows[0], rows[1][-1] - rows[1][0]  # the rows one a tick, unless ticks with some
        # skipped fit their times far closer (every 7th row missing from exact times: 6 rows in 7 ticks)
    if not spacing > 0:
        return

    def off(s):
        return abs(s - dt) > (RATE_RTOL + 2 * JITTER_TICKS / max(float(span) / s, 1.0)) * dt

    if off(spacing):
        rms = np.sqrt(_misfit(t[:FIT_ROWS], spacing)) / spacing  # ticks from the grid fitted
        # the times fit the table's rate with rows missing as well, or lie off any grid
        if (not off(skipped)) if spacing != skipped else rms > BLURRED_TICKS:
            raise DataError(f"{source}: the log's base rate is "
                            + (f"{1.0 / spacing:.6g} Hz with every row present or {1.0 / skipped:.6g} Hz with rows "
                               "missing" if spacing != skipped else
                               f"{1.0 / spacing:.6g} Hz at best, its times as far from that grid as from none "
                               f"({rms:.2f} tick RMS)")
                            + f", and the table runs at {1.0 / dt:.6g} Hz: the rate cannot be told from the times "
                            "(time-stamp jitter of a third of a tick or more with rows missing blurs one tick into "
                            "two); stamp the rows with the sensor's sample time, or log every row")
        unit = _unit_hint(spacing, dt, time_scale, lambda ticks: abs(ticks - 1) <= RATE_RTOL)
        unit = f" ({unit.replace('? They', '? they')})" if unit else ""
        raise DataError(f"{source}: the log's base rate is {1.0 / spacing:.6g} Hz (mean spacing {spacing:.6g} s) "
                        f"but the table runs at {1.0 / dt:.6g} Hz; a gain table is designed for one rate{unit}")


#: time units a log may have written instead of seconds, named in the message of a rate that is off by their scale
_TIME_UNITS = (("milliseconds", "ms", 1e3), ("microseconds", "us", 1e6), ("nanoseconds", "ns", 1e9))


def _unit_hint(step: float, dt: float, time_scale: float, fits) -> str | None:
    """The sentence naming the time unit a log's times are likely in, or None.

    Parameters
    ----------
    step : float
        The log's step as read (s).
    dt : float
        The table's base tick (s).
    time_scale : float
        Seconds per unit of the times as they were read (1e-6 for ``--time-unit us``).
    fits : callable
        ``fits(ticks)``: whether the step, were the times in another unit, is the log's step in
        ticks of ``dt``.

    Returns
    -------
    str or None
        ``'times in microseconds? ...'`` with the ``--time-unit`` that reads them, for the finest
        unit other than the one read whose step fits; None when none does.
    """
    units = (*((name, short, 1.0 / per) for name, short, per in reversed(_TIME_UNITS)), ("seconds", "s", 1.0))
    read = next((u for u in units if abs(u[2] / time_scale - 1) < 1e-9), None)
    for name, short, seconds in units:
        if (read is not None and short == read[1]) or not fits(step * seconds / time_scale / dt):
            continue
        if time_scale == 1.0:
            return f"times in {name}? They are read as seconds unless --time-unit {short} is given"
        return f"times in {name}? They are read as {read[0] if read else 'another unit'}: give --time-unit {short}"
    return None


@dataclass(frozen=True)
class Segment:
    """Ticks ``[start, stop)`` run with one schedule.

    Attributes
    ----------
    start, stop : int
        First tick and one past the last.
    rotation : int
        The table's own schedule with its phase 0 at this tick (when ``offsets`` is None).
    offsets : tuple, optional
        The table's schedule with each sensor shifted by these phases (gains recomputed).
    """

    start: int
    stop: int
    rotation: int = 0
    offsets: tuple | None = None


@dataclass(frozen=True)
class Lock:
    """How a log's arrivals meet a table's schedule.

    Attributes
    ----------
    segments : list of Segment
        Covering every tick of the log, in order.
    offsets : dict
        ``{sensor: ticks late}`` for the longest-lived configuration (for the report).
    rate_hz : dict
        ``{sensor: arrivals per second}`` measured in the log.
    notes : list of str
        One line each for what a user should know (offsets, recomputed gains, rate mismatches).
    varying : bool
        The pattern is not steady (module docstring): run the Kalman filter over the actual
        arrivals, not the segments.
    """

    segments: list
    offsets: dict = field(default_factory=dict)
    rate_hz: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    varying: bool = False

    @property
    def recomputed(self) -> bool:
        """True when some segment runs gains recomputed for shifted sensors."""
        return any(s.offsets is not None for s in self.segments)


def _pattern(schedule, name):
    """``(phases, step)``: the sensor's phases and the smallest shift that maps them onto
    themselves (its own period: 10 for a 10-tick sensor in a 100-tick schedule)."""
    P = schedule.period
    phases = np.array(schedule.phases(name), dtype=np.int64)
    members = set(phases.tolist())
    step = next(g for g in range(1, P + 1) if all((p + g) % P in members for p in members))
    return phases, step


def _offset_runs(ticks, phases, step, period):
    """``[(first tick, offset mod step)]``: runs of arrivals consistent with one offset."""
    if len(phases) * step == period:  # read every `step` ticks: the offset is the tick mod step
        off = (ticks - phases[0]) % step
        change = np.flatnonzero(np.diff(off)) + 1
        starts = np.concatenate([[0], change])
        return [(int(ticks[i]), int(off[i])) for i in starts]
    # a general pattern (e.g. 0, 33, 67 of 100): the offsets o in [0, step) consistent with every
    # arrival t of a run, those with (t - o) mod step among the phases; kept by testing only the
    # run's surviving candidates against a membership table (O(candidates) a tick, not
    # O(phases): 1 kHz beside 333.3 Hz, 3333 phases of 10000, took 0.18 ms a row)
    member = np.zeros(step, dtype=bool)
    member[phases % step] = True
    offsets = np.flatnonzero(member)  # the phases within the sensor's own period
    runs, current = [], None
    for t in ticks.tolist():
        if current is not None:
            kept = current[member[(t - current) % step]]
            if kept.size:
                current = kept
                continue
            runs[-1][1] = current
        current = np.sort((t - offsets) % step)
        runs.append([t, current])
    if runs:
        runs[-1][1] = current
    return [(t, int(c[0])) for t, c in runs]


def lock_schedule(table, arrivals: dict, n_ticks: int, *, recompute: bool = True) -> Lock:
    """Match each measurement sensor's arrival ticks to the table's schedule (module docstring).

    Parameters
    ----------
    table : GainTable
        The gain table whose schedule the arrivals are matched to.
    arrivals : dict
        ``{sensor: ascending int array of ticks}`` where the log has a reading.
    n_ticks : int
        Ticks in the log.
    recompute : bool
        Allow recomputed gains (False: rotations of the table's schedule only).

    Returns
    -------
    Lock
        The segments, offsets, measured rates and notes.
    """
    sched, P, dt = table.schedule, table.period, table.sample_time_s
    notes, rates, patterns, faster, drifting = [], {}, {}, False, set()
    for name in sched.measurements:
        ticks = np.asarray(arrivals.get(name, ()), dtype=np.int64)
        if not len(ticks):
            notes.append(f"{name} has no reading in the log: " + (
                "the log runs the Kalman filter of the table's model over the readings that arrive" if recompute
                else "the gains are still those designed with it (re-design without it for the best estimate)"))
        phases, step = _pattern(sched, name)
        expected = len(phases) / (P * dt)
        if len(ticks) >= 10:
            rates[name] = _arrival_rate(ticks, len(phases), dt)
        if name in rates and rates[name] > 1.05 * expected:  # more readings than the schedule has gains for
            notes.append(f"{name} arrives at {rates[name]:.4g} Hz but the table reads it at {expected:.4g} Hz: "
                         + ("every reading is used: the log runs the Kalman filter of the table's model with "
                            "gains from the readings as they arrive" if recompute
                            else "readings off its schedule have no gain"))
            faster |= recompute
            ticks = ticks[:0]
        elif name in rates and rates[name] < 0.95 * expected:  # fewer readings: each still has a gain
            notes.append(f"{name} has {rates[name]:.4g} readings a second where the table reads it at "
                         f"{expected:.4g} Hz (missed readings or a slower sensor): every reading is used, the "
                         "estimate is less accurate than designed")
        elif name in rates and abs(rates[name] / expected - 1) > RATE_RTOL:  # a rate_hz a few percent off
            notes.append(f"{name} arrives at {rates[name]:.4g} Hz but the table reads it at {expected:.4g} Hz "
                         f"({100 * (rates[name] / expected - 1):+.1f} %: is its rate in the design file right?): "
                         "its arrivals slip through the schedule" + (", every reading is used" if recompute else ""))
            drifting.add(name)
        patterns[name] = (ticks, phases, step)
    runs = {name: _offset_runs(t, ph, st, P) for name, (t, ph, st) in patterns.items() if len(t) and st < P + 1}
    breaks = sorted({t for r in runs.values() for t, _ in r} | {0})
    starts = {name: [t for t, _ in r] for name, r in runs.items()}  # listed once, not per break: time
    # quadratic in the breaks (a compass 0.5 % fast, 5000 breaks in 1M rows: 0.87 s, now 0.19 s)
    segments, life = [], {}
    for a, b in zip(breaks, [*breaks[1:], n_ticks], strict=True):
        if a >= n_ticks:
            break
        offs = {name: _current(r, starts[name], a) for name, r in runs.items()}
        seg = _segment(a, b, offs, patterns, P, recompute)
        segments.append(seg)
        life[tuple(sorted(offs.items()))] = life.get(tuple(sorted(offs.items())), 0) + (b - a)
    segments = _merged(segments)
    main = dict(max(life, key=life.get)) if life else {}
    late = {k: v for k, v in main.items() if v and k not in drifting}  # a sensor off its rate has no one offset
    varying = faster or (recompute and len(segments) > 1 and n_ticks < STEADY_PERIODS * P * len(segments))
    if late:  # (what runs: a drifting sensor's log runs the Kalman filter, not the locked schedule)
        notes.insert(0, "readings arrive " + ", ".join(f"{k} {v} ticks" for k, v in late.items())
                     + " after the table's schedule: " + (
                         "they are used as they arrive, by the Kalman filter of the table's model" if varying
                         else "gains recomputed for the arrival pattern (periodic DARE of the table's model)"
                         if any(s.offsets for s in segments) else "the schedule is locked to the arrivals"))
    if varying and not faster:
        notes.append(f"the arrival pattern changes {len(segments) - 1} times in the log ({_WHY_CHANGES}): "
                     "the log runs the Kalman filter of the table's model with gains from the readings "
                     "as they arrive")
    elif len(segments) > 1 and not faster:
        notes.append(f"the arrival pattern changes {len(segments) - 1} times in the log ({_WHY_CHANGES}): "
                     "each stretch runs with the gains of its own pattern")
    return Lock(segments or [Segment(0, n_ticks)], main, rates, notes, varying)


#: why a slow sensor's arrival pattern changes along a log, for the note that says it does
_WHY_CHANGES = ("a drifting or slipping sensor, or time stamps jittered near the middle between two ticks, "
                "where a rate that is not a whole fraction of the base rate puts some of its readings")


def _arrival_rate(ticks, per_period: int, dt: float) -> float:
    """Arrivals per second of a sensor, from the typical span of ``per_period`` readings.

    A sensor at a fraction of the base rate (8 Hz on a 20 Hz tick) arrives 3, 2, 3, 2 ...
    ticks apart, so the median of single spacings is 2 or 3 by the count's parity; the
    median span of ``per_period`` consecutive readings (``q`` readings every ``p`` ticks)
    is exact, and gaps (a dropped reading) do not change it.

    Parameters
    ----------
    ticks : ndarray of int
        Ascending arrival ticks (at least two).
    per_period : int
        Readings of the sensor in one period of the table's schedule.
    dt : float
        Base sample time (s).

    Returns
    -------
    float
    """
    q = max(1, min(per_period, len(ticks) // 2))
    span = float(np.median(ticks[q:] - ticks[:-q]))
    return q / (max(span, float(q)) * dt)


def _current(runs, starts, tick):
    """The offset of the run in force at ``tick`` (the first run's before it starts); ``starts``
    the runs' first ticks."""
    i = bisect.bisect_right(starts, tick) - 1
    return runs[max(i, 0)][1]


def rotation(offsets: dict, steps: dict, period: int):
    """The one shift of the whole schedule that puts every sensor on its offset, if there is one.

    The lock rule of :func:`lock_schedule` (per stretch of a log) and of
    :meth:`cfdesign.runtime.Runtime.step` (per reading, as they arrive).

    Parameters
    ----------
    offsets : dict
        ``{sensor: ticks late}``, each in ``range(steps[sensor])``; not empty.
    steps : dict
        ``{sensor: its own period in ticks}`` (``_pattern``: 10 for a 10-tick sensor in a
        100-tick schedule, the period for a sensor read once a period).
    period : int
        The schedule's period (ticks).

    Returns
    -------
    int or None
        ``c`` in ``range(period)`` with ``(offsets[s] - c) % steps[s] == 0`` for every sensor
        (the table's schedule runs exactly with its phase 0 at tick ``c``), the smallest such;
        None when the sensors are at offsets no one shift gives (their own offsets).
    """
    slowest = max(offsets, key=steps.get)
    step = steps[slowest]  # a divisor of the period; every rotation is offsets[slowest] mod step
    for c in range(offsets[slowest], period, step):  # (a 2 Hz sensor 10 ticks late, a 5 Hz one on time: 60)
        if all((o - c) % steps[n] == 0 for n, o in offsets.items()):
            return c
    return None


def _segment(a, b, offs, patterns, P, recompute):
    """A rotation of the table when every sensor's offset is one shift of the whole schedule."""
    if not offs:
        return Segment(a, b)
    c = rotation(offs, {n: patterns[n][2] for n in offs}, P)
    if c is not None:
        return Segment(a, b, rotation=c)
    if not recompute:
        return Segment(a, b, rotation=offs[max(offs, key=lambda n: patterns[n][2])])
    return Segment(a, b, offsets=tuple(sorted(offs.items())))


def _merged(segments):
    out = []
    for s in segments:
        if out and (out[-1].rotation, out[-1].offsets) == (s.rotation, s.offsets) and out[-1].stop == s.start:
            out[-1] = Segment(out[-1].start, s.stop, s.rotation, s.offsets)
        else:
            out.append(s)
    return out
