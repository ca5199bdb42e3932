"""IMU streams at their own rates put on the gyro's clock: the one-sample-per-step arrays the attitude filter takes.

A phone or hobby-IMU logger (Android's sensor API, a "Sensor Logger" export) records the gyro, the
accelerometer and the magnetometer as separate streams, each at its own rate (200, 100 and 50 Hz, say), with
its own time stamps, jitter and dropped samples; a merged export has one row per time stamp of any sensor and
empty cells for the others.  :class:`~cfdesign.nav.AttitudeFilter` steps at one rate, with a sample of every
sensor per step: a row of such a merged table taken as a step integrates the held rate over ``1 / rate_hz``
however far apart the rows are (a 200/100/50 Hz table run at 200 Hz: 133 deg RMS off).
:func:`align_imu` puts each reading on the nearest tick of the gyro's clock (the grid fitted to the gyro's
stamps, :func:`cfdesign.timing.grid_fit`, so jitter within half a tick leaves every gyro reading on its own
tick), the same placement as ``cfdesign run`` (``docs/logs.md``): a reading is used at most half a gyro
interval from when it was taken.  A tick without a reading of a sensor is NaN, which the filter counts as
missing (a missing rate holds the last one; a missing specific force or field skips its correction), and a
pause in the gyro is as many NaN ticks as it lasted, so the filter's gap handling sees it (a gap longer than
the tilt's start-up, 2 s, runs the start-up again), up to ``MAX_TICKS_PER_READING`` ticks per gyro reading
beyond a million: a longer pause (an hour in a 20 s log at 500 Hz) is refused naming its row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import AttitudeInputError
from ..timing import grid_fit, nearest_tick
from .attitude_inputs import rows

__all__ = ["AlignedImu", "align_imu", "hard_iron_offset", "TIME_UNITS"]

#: units the time stamps may be in: seconds each
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


@dataclass
class AlignedImu:
    """The streams of :func:`align_imu` on the gyro's clock: one row per tick.

    Attributes
    ----------
    time : ndarray (N,)
        Tick times, s since ``t0`` (tick 0 is the first gyro reading's, within half an interval of it).
    t0 : int or float
        The earliest time stamp of any stream, in the stamps' unit (an integer stamp kept exact): ``time`` counts
        from it.
    rate_hz : float
        The gyro's rate fitted to its stamps: the ``rate_hz`` of the filter.
    gyr, acc : ndarray (N, 3)
        Readings on their nearest tick (the mean where several fall on one), NaN on a tick without one.
    mag : ndarray (N, 3) or None
        The same for the field; None when no magnetometer was given.
    counts : dict
        Per sensor (``'gyr'``, ``'acc'``, ``'mag'``): ``readings`` given, ``ticks`` holding one, ``shared``
        readings averaged onto a tick that already had one, ``outside`` readings before the first gyro tick or
        after the last (not used).
    """

    time: np.ndarray
    t0: float
    rate_hz: float
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray | None
    counts: dict

    def describe(self) -> str:
        """What the alignment found, to check a log by.

        Returns
        -------
        str
            One line per sensor: its readings, the ticks that hold one and those that do not.
        """
        n = len(self.time)
        return "\n".join(f"{name}: {c['readings']} readings on {c['ticks']} of {n} ticks at {self.rate_hz:.6g} Hz "
                         f"({n - c['ticks']} without one, {c['shared']} shared, {c['outside']} outside the gyro's span)"
                         for name, c in self.counts.items())


#: the most ticks :func:`align_imu` lays out per gyro reading (beyond a million): a log whose gyro stamps span more
#: is mostly a gap - one stamp of another clock or unit (2**63 ns at the end of an Android log) would otherwise
#: allocate arrays for years of ticks
MAX_TICKS_PER_READING = 10


def align_imu(t_gyr, gyr, t_acc, acc, t_mag=None, mag=None, *, time_unit="s") -> AlignedImu:
    """Put gyro, accelerometer (and magnetometer) streams, each with its own time stamps, on the gyro's clock.

    Each stream is a time column and its readings; a merged table (one row per time stamp of any sensor, NaN
    where a sensor has no sample) is the same time column given for each sensor: rows whose three entries are
    all NaN are not readings.  Convert the readings to the filter's units first (rad/s, m/s²; the field in any
    one unit).

    Parameters
    ----------
    t_gyr : array_like (N,)
        The gyro's time stamps, non-decreasing, in ``time_unit`` (integers such as Android's nanoseconds are kept
        exact: the first stamp is subtracted before the conversion to float).
    gyr : array_like (N, 3)
        Body rate, rad/s, one row per time stamp.
    t_acc : array_like (M,)
        The accelerometer's time stamps, as ``t_gyr``.
    acc : array_like (M, 3)
        Specific force, m/s², one row per time stamp.
    t_mag : array_like (L,), optional
        The magnetometer's time stamps, as ``t_gyr``.
    mag : array_like (L, 3), optional
        Field, any one unit, one row per time stamp; without it (and ``t_mag``): 6D.
    time_unit : {'s', 'ms', 'us', 'ns'}
        The unit of every time stamp.

    Returns
    -------
    AlignedImu
        ``rate_hz``, ``gyr``, ``acc``, ``mag`` for :func:`~cfdesign.nav.estimate_attitude` or
        :meth:`~cfdesign.nav.AttitudeFilter.run`, and the tick times.

    Raises
    ------
    AttitudeInputError
        A time column that is not one-dimensional, not finite or goes back (the message names the column and
        the row as given), readings that are not (N, 3) or whose length differs from their time column's, an
        unknown ``time_unit``, ``mag`` without ``t_mag`` (or the reverse), a stream without a reading or none
        within the gyro's span (other clocks or time units), a gyro with fewer than two readings, or gyro
        stamps spanning more than ``MAX_TICKS_PER_READING`` ticks per reading (beyond a million): a stamp
        that jumps (the message names it).

    Examples
    --------
    A 200 Hz gyro and a 100 Hz accelerometer, stamped in nanoseconds:

    >>> import numpy as np
    >>> from cfdesign.nav import align_imu
    >>> t_g = np.arange(0, 1_000_000_000, 5_000_000)
    >>> t_a = np.arange(2_000_000, 1_000_000_000, 10_000_000)
    >>> imu = align_imu(t_g, np.zeros((200, 3)), t_a, np.tile([0.0, 0.0, 9.81], (100, 1)), time_unit="ns")
    >>> round(imu.rate_hz, 6), imu.gyr.shape, int(np.isnan(imu.acc[:, 0]).sum())
    (200.0, (200, 3), 100)
    """
    if time_unit not in TIME_UNITS:
        raise AttitudeInputError(f"time_unit must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}")
    if (t_mag is None) != (mag is None):
        raise AttitudeInputError("give t_mag and mag together (or neither: 6D)")
    given = {"gyr": (t_gyr, gyr), "acc": (t_acc, acc)} | ({} if mag is None else {"mag": (t_mag, mag)})
    streams = {name: _stream(name, t, v) for name, (t, v) in given.items()}
    if len(streams["gyr"][0]) < 2:
        raise AttitudeInputError("gyr has fewer than two readings: its rate cannot be told from the time stamps")
    start = min(t[0] for t, _, _ in streams.values())
    seconds = {name: _seconds(t, start, TIME_UNITS[time_unit]) for name, (t, _, _) in streams.items()}
    tg = seconds["gyr"]
    steps = np.diff(tg)
    if not (steps > 0).any():
        raise AttitudeInputError("t_gyr: every gyro reading has the same time stamp: its rate cannot be told")
    origin, spacing = grid_fit(tg, _interval(tg, steps))
    n = int(nearest_tick((tg[-1] - origin) / spacing)) + 1
    if n > MAX_TICKS_PER_READING * len(tg) + 1_000_000:  # mostly empty ticks: a stamp of another clock or unit
        i = int(np.argmax(steps)) + 1
        raise AttitudeInputError(f"t_gyr jumps by {steps[i - 1]:.6g} s at row {streams['gyr'][2][i]}: the gyro's "
                                 f"{len(tg)} readings would span {n} ticks of {spacing:.6g} s, nearly all empty; "
                                 "fix that time stamp, or split the log there")
    out, counts = {}, {}
    for name, (_, v, _) in streams.items():
        out[name], counts[name] = _on_ticks(seconds[name], v, origin, spacing, n)
        if not counts[name]["ticks"]:
            raise AttitudeInputError(f"t_{name}: none of the {len(v)} readings falls within the gyro's span "
                                     f"({_span(seconds[name])} s against {_span(tg)} s from the earliest stamp): "
                                     "streams on other clocks or in other time units?")
    return AlignedImu(time=(origin + spacing * np.arange(n)), t0=start.item(), rate_hz=1.0 / spacing,
                      gyr=out["gyr"], acc=out["acc"], mag=out.get("mag"), counts=counts)


def _stream(name, t, values) -> tuple:
    """A stream's time column, readings and their rows as given, checked (named ``t_<name>`` and ``name``),
    without the rows that hold no reading (all three entries NaN: a merged table's other sensors)."""
    v = rows(name, values, 3)
    t = np.asarray(t)
    if t.ndim != 1:
        raise AttitudeInputError(f"t_{name} must be one time stamp per reading (N,), got shape {t.shape}")
    if len(t) != len(v):
        raise AttitudeInputError(f"t_{name} has {len(t)} time stamps but {name} has {len(v)} readings")
    if t.dtype.kind not in "iuf":
        raise AttitudeInputError(f"t_{name} must be numbers (time stamps in the time_unit), got {t.dtype}")
    row = np.flatnonzero(~np.isnan(v).all(axis=1))   # the rows given (a merged table's numbering) that hold one
    t, v = t[row], v[row]
    if not len(t):
        raise AttitudeInputError(f"{name} has no reading (every row empty or NaN): align_imu needs each stream it is "
                                 "given")
    if t.dtype.kind == "f" and not np.isfinite(t).all():
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise AttitudeInputError(f"t_{name}: the time stamp of row {row[i]} is {float(t[i])}, not a finite number")
    back = np.flatnonzero(np.diff(t) < 0)
    if len(back):
        i = back[0] + 1
        raise AttitudeInputError(f"t_{name} goes back at row {row[i]} ({t[i].item()!r} after {t[i - 1].item()!r}, "
                                 f"row {row[i - 1]}): sort each stream by time")
    return t, v, row


def _interval(t, steps) -> float:
    """The gyro's interval (s) from its stamps ``t`` (s) and their steps: the least-squares slope of the stamps
    over their ticks, each step counted as the whole number of intervals nearest to it (a dropped reading's step
    as two), from the median step and then from that slope (the median of jittered steps with a few dropped
    readings is a fraction of a percent off: on 60 s at 200 Hz, a tick slipped every 40 s)."""
    interval = float(np.median(steps[steps > 0]))
    for _ in range(2):
        k = np.concatenate(([0.0], np.cumsum(nearest_tick(steps / interval))))
        k -= k.mean()
        if k @ k > 0:
            interval = float(k @ (t - t.mean()) / (k @ k))
    return interval


def _span(t) -> str:
    """The first and last of the times ``t`` (s), as text."""
    return f"{t[0]:.6g} to {t[-1]:.6g}"


def _seconds(t, start, scale) -> np.ndarray:
    """Stamps ``t`` minus ``start`` (exact for integers), in seconds."""
    if t.dtype.kind in "iu" and float(start).is_integer():
        return (t.astype(np.int64) - np.int64(start)).astype(float) * scale
    return (t.astype(float) - float(start)) * scale


def _on_ticks(t, values, origin, spacing, n) -> tuple:
    """Readings at times ``t`` (s) on ticks ``0 .. n-1`` of the grid ``origin + k spacing``: the mean of those on
    a tick, NaN on a tick without one; and the counts of :class:`AlignedImu`."""
    k = nearest_tick((t - origin) / spacing).astype(np.int64)
    inside = (k >= 0) & (k < n)
    k, v = k[inside], values[inside]
    total, number = np.zeros((n, 3)), np.zeros(n)
    np.add.at(total, k, v)
    np.add.at(number, k, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(number[:, None] > 0, total / number[:, None], np.nan)
    ticks = int((number > 0).sum())
    return out, {"readings": len(t), "ticks": ticks, "shared": int(len(k) - ticks), "outside": int((~inside).sum())}


#: the hard-iron check (:func:`hard_iron_offset`): the least turn of the readings' directions about the fitted centre
#: that lets a sphere be told from their mean (the smallest principal spread of the unit directions: a turn about one
#: axis only leaves the centre's component along it undetermined and spreads them about it by 0), the offset beyond
#: which it matters (relative to the field's norm: 0.1, a heading error up to about 6 deg), how much better than the
#: raw norms the sphere must fit them (the norms' spread about it at most a third of theirs about their mean), and how
#: round the readings must be (the RMS of their distances from the sphere at most 3 % of its radius: a sensor's noise
#: is about 1 %, a field disturbed from outside for part of a log 4 % and more; a calibrated BROAD trial 2-3 %)
HARD_IRON_SPREAD, HARD_IRON_SHARE, HARD_IRON_FIT, HARD_IRON_ROUND = 0.1, 0.1, 1.0 / 3.0, 0.03


def hard_iron_offset(mag):
    """The centre of the sphere the field readings lie on: a hard-iron offset, if they turned enough to show one.

    A field fixed to the sensor (an uncalibrated magnetometer, a magnet or steel carried with it) adds the same
    vector to every reading, so the readings of a turning sensor lie on a sphere about it instead of about zero; the
    filter, which reads the field's direction, then errs in heading by up to the offset over the horizontal field
    (a 30 µT offset beside 50 µT: 23 deg RMS).  The centre is the linear least-squares sphere
    (``|m|² = 2 c . m + k``).

    Parameters
    ----------
    mag : array_like (N, 3)
        Field readings, any one unit; non-finite rows are left out.

    Returns
    -------
    ndarray (3,) or None
        The offset (the field's unit), or None when it cannot be told or does not matter: the readings did not turn
        enough about the fitted centre (the smallest spread of their directions from it below ``HARD_IRON_SPREAD``:
        turned about one axis only, which leaves the centre's component along it unknown), they do not lie on the
        sphere (their distances from it over ``HARD_IRON_ROUND`` of its radius, RMS: at rest, where the fit is to the
        noise, or a field disturbed from outside), the sphere fits their norms no better than their mean does
        (``HARD_IRON_FIT``), or the offset is below ``HARD_IRON_SHARE`` of the field.  An offset of several times
        the field (an uncalibrated phone: 100-200 µT beside 50) is found too: the turn is judged from the centre,
        not from zero, from which such readings' directions hardly turn.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.nav import hard_iron_offset
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((500, 3))
    >>> field = 50.0 * u / np.linalg.norm(u, axis=1, keepdims=True)
    >>> np.round(hard_iron_offset(field + [15.0, -10.0, 30.0]), 6).tolist()
    [15.0, -10.0, 30.0]
    >>> hard_iron_offset(field) is None
    True
    """
    m = rows("mag", mag, 3)
    with np.errstate(invalid="ignore", over="ignore"):
        m = m[np.isfinite(m).all(axis=1) & (np.abs(m).sum(axis=1) > 0)]
    if len(m) < 10:
        return None
    scale = float(np.median(np.linalg.norm(m, axis=1)))
    m = m / scale
    norms = np.linalg.norm(m, axis=1)
    a = np.column_stack((2.0 * m, np.ones(len(m))))
    sol = np.linalg.lstsq(a, norms * norms, rcond=None)[0]
    centre, radius2 = sol[:3], sol[3] + sol[:3] @ sol[:3]
    if not (radius2 > 0.0 and _spread(m - centre) >= HARD_IRON_SPREAD):
        return None
    radius = np.sqrt(radius2)
    misfit = np.sqrt(np.mean((np.linalg.norm(m - centre, axis=1) - radius) ** 2))
    if (np.linalg.norm(centre) < HARD_IRON_SHARE * radius or misfit > HARD_IRON_ROUND * radius
            or misfit > HARD_IRON_FIT * np.std(norms)):
        return None
    return centre * scale


def _spread(d) -> float:
    """The smallest principal standard deviation of the directions of the vectors ``d`` (rad, about): how far they
    turned about their least-turned axis (0 for a turn about one axis only, whose directions lie on a cone)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / np.linalg.norm(d, axis=1, keepdims=True)
    u = u[np.isfinite(u).all(axis=1)]
    return float(np.sqrt(max(np.linalg.eigvalsh(np.cov(u.T))[0], 0.0))) if len(u) > 3 else 0.0
