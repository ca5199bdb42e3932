"""The first pass over a log: rows placed on the table's base ticks, the base rate checked, the
schedule locked to the arrivals, the gaps of the inputs counted."""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import DataError, require_extra
from .columns import NEEDS_PYARROW, _numeric

#: rows where the inputs read over which the log's base rate is measured (the first ones)
RATE_SAMPLE = 1_000_000
#: a slow sensor's column is forward-filled (its last reading repeated on the rows between readings)
#: when it has more than this many times the readings its rate gives and at least half of them repeat
#: the one before exactly
FILLED_RATIO = 1.5


class _Pass:
    """Placement of rows on ticks, carried from block to block (times checked across blocks)."""

    def __init__(self, table, cols, source, blocks=None, grid=None, rephased=None):
        self.table, self.cols, self.source = table, cols, source
        self.blocks = blocks  # the log's blocks, looked through for the grid when the first block has no input row
        self.t0 = None
        self.spacing = table.sample_time_s  # of the log's clock: the table's tick unless it drifts (timing.grid_fit)
        self.grid = grid  # (t0, spacing) of tick 0, when known (the first pass's, for the second)
        self.rephased = dict(rephased or {})  # the log's row after each pause -> the grid's origin from there on
        self.tail = None  # the previous block's rows at its last time: (times, {sensor: read}), checked with the next
        self.rows = 0
        self.early = {}  # sensor -> readings logged before tick 0 (not used)
        self.base_times = []  # of the first RATE_SAMPLE rows where the inputs read: the base rate
        self._sampled = 0
        self.last_base = None  # the time of the last row so far where the inputs read
        self.filled = {}  # slow sensor -> its last value, where its column is forward-filled (_unfill)
        self.judged = set()  # sensors whose column was looked at for that

    def _unfill(self, values):
        """Forward-filled columns of slow sensors (a logger or a spreadsheet that repeats the last
        reading on every row) read as the readings they hold: a value equal to the one before it is
        no reading (NaN).  Each repeated as a reading of its own made a 1 Hz compass a 100 Hz one
        whose noise averaged away: a predicted std far too small and the estimate pulled to it.
        Judged on a sensor's first block with 20 readings: more than :data:`FILLED_RATIO` times the
        readings its rate gives over the block's span, half of them repeats."""
        n = len(next(iter(values.values()))) if values else 0
        dt = self.table.sample_time_s
        for s in self.table.measurements:
            col = values[self.cols.sensors[s.name]]
            if s.name not in self.judged:  # an inf is a rejected reading, not a repeat ('inf' in every
                read = col[np.isfinite(col)]  # empty cell made a column look forward-filled)
                if read.size < 20:
                    continue
                self.judged.add(s.name)
                expected = n * dt * (s.rate_hz or 1 / dt)
                if read.size > FILLED_RATIO * expected and np.mean(read[1:] == read[:-1]) >= 0.5:
                    self.filled[s.name] = np.nan
            if s.name in self.filled:
                keep = ~np.isnan(col)
                v = col[keep]
                prev = np.concatenate([[self.filled[s.name]], v[:-1]])
                if v.size:
                    self.filled[s.name] = v[-1]
                out = np.full(n, np.nan)
                out[np.flatnonzero(keep)[v != prev]] = v[v != prev]
                values[self.cols.sensors[s.name]] = out

    def ticks(self, values):
        """Ticks of a block's rows (``row index`` when the log has no time column)."""
        n = len(next(iter(values.values()))) if values else 0
        self._unfill(values)
        if self.cols.time is None:
            ticks = self.rows + np.arange(n, dtype=np.int64)
        else:
            from ..timing import place

            t = values[self.cols.time]
            read = {s: ~np.isnan(values[c]) for s, c in self.cols.sensors.items()}
            base = np.ones(n, dtype=bool)
            for s in self.table.inputs:
                base &= read[s.name]
            tail_t, tail_read = self.tail or (t[:0], {s: r[:0] for s, r in read.items()})
            start = self.rows - len(tail_t)
            place(np.concatenate([tail_t, t]), self.table.sample_time_s, source=self.source, rate=False,
                  where=lambda i: self.cols.lines.at(start + i), time_scale=self.cols.time_scale,
                  readings={s: np.concatenate([tail_read[s], r]) for s, r in read.items()})
            rows, pauses = self._pauses(t[base], np.flatnonzero(base))
            if self.t0 is None and n:  # tick 0: the first row where the inputs read (the base clock), on
                # the grid of the first such rows up to a pause (not its own jittered time; timing.grid_fit)
                self.grid = self.grid or self._first_grid(t[base][:pauses[0] if pauses else None], t[0])
                self.t0, self.spacing = self.grid
            self._sample(t[base])
            ticks = self._placed(t, t[base], rows, pauses)
            early = ticks < 0  # logged more than half a tick before the first row where the inputs read:
            if early.any():  # no tick of the run is within S/2 of it, so it is counted, not used late
                for name, col in self.cols.sensors.items():
                    gone = early & ~np.isnan(values[col])
                    if gone.any():
                        self.early[name] = self.early.get(name, 0) + int(gone.sum())
                        values[col] = np.where(gone, np.nan, values[col])
                ticks = np.maximum(ticks, 0)  # the row itself gets the first tick's estimate
            if n:
                last = t == t[-1]
                if last.all() and len(tail_t) and tail_t[-1] == t[-1]:  # a block all at the tail's time
                    self.tail = (np.concatenate([tail_t, t]), {s: np.concatenate([tail_read[s], r])
                                                               for s, r in read.items()})
                else:
                    self.tail = (t[last], {s: r[last] for s, r in read.items()})
        self.rows += n
        return ticks

    def _first_grid(self, first, t_first):
        """``(t0, spacing)`` fitted to ``first``, the first rows where the inputs read up to a pause
        (:func:`cfdesign.timing.grid_fit`); when the block has none, to those of the first block
        that has (the log's blocks read again up to it: a log of more than a block of rows before
        its first input row was placed on the grid of its first row, half a tick off the inputs'
        at worst, and its readings before the inputs were used instead of counted), else the first row's time."""
        from ..timing import FIT_ROWS, grid_fit

        if not first.size:
            first = self._ahead(0, count=FIT_ROWS)
        return grid_fit(first, self.table.sample_time_s) if first.size else (t_first, self.spacing)

    def _ahead(self, row, before=None, count=None):
        """The times of the rows where the inputs read from the log's row ``row`` on (its blocks
        read again), up to ``count`` of them (:data:`~cfdesign.timing.ARC_ROWS`) and the first
        pause (also one right after ``before``, the time of such a row before them); none without
        the blocks."""
        from ..timing import ARC_ROWS, PAUSE_TICKS

        count = count or ARC_ROWS
        out, n = [np.zeros(0)], 0
        if self.blocks is None:
            return out[0]
        sensors = [self.cols.sensors[s.name] for s in self.table.inputs]
        start = 0
        for block in self.blocks():
            start, first = start + len(block), start
            if start <= row:
                continue
            block, at = block.iloc[max(row - first, 0):], max(row, first)
            values = _numeric(block, [self.cols.time, *sensors], self.source,
                              lambda i, at=at: self.cols.lines.at(at + i), self.cols.time, self.cols.time_scale)
            base = np.ones(len(block), dtype=bool)
            for c in sensors:
                base &= ~np.isnan(values[c])
            t = values[self.cols.time][base]
            pause = np.flatnonzero(np.diff(np.concatenate([[before] if before is not None else [], t]))
                                   > PAUSE_TICKS * self.spacing)
            t = t[:pause[0] - (before is not None) + 1 if pause.size else None][:count - n]
            out.append(t)
            n += len(t)
            before = t[-1] if t.size else before
            if pause.size or n >= count:
                break
        return np.concatenate(out)

    def _pauses(self, base_t, rows) -> tuple:
        """``(rows, pauses)``: the rows of the block where the inputs read and the indices among them
        of those that follow a pause (:data:`~cfdesign.timing.PAUSE_TICKS`; a block's first such row
        after the previous block's, or the log's first one when its first rows had none)."""
        from ..timing import PAUSE_TICKS

        if not base_t.size:
            return rows, []
        before = [] if self.last_base is None else [self.last_base]
        steps = np.diff(np.concatenate([before, base_t]))
        pauses = (np.flatnonzero(steps > PAUSE_TICKS * self.spacing) + (0 if before else 1)).tolist()
        self.last_base = float(base_t[-1])
        return rows, pauses

    def _placed(self, t, base_t, rows, pauses):
        """Ticks of a block's rows: on the grid, whose phase is fitted again at each pause
        (:func:`cfdesign.timing.rephase`) for the rows from there on."""
        from ..timing import ARC_ROWS, nearest_tick, rephase

        cuts = [0, *(int(rows[p]) for p in pauses), len(t)]
        starts = [0, *pauses, len(base_t)]
        out = np.empty(len(t), dtype=np.int64)
        for k, (a, b) in enumerate(itertools.pairwise(cuts)):
            if k and self.rows + a not in self.rephased:  # the base rows from this pause to the next, also
                # those of the blocks after this one (a pause at a block's end: a phase fitted to its few
                # rows there had left one row in ten on a shared tick for the rest of the log)
                after = base_t[starts[k]:starts[k + 1]]
                if starts[k + 1] == len(base_t) and len(after) < ARC_ROWS:
                    after = np.concatenate([after, self._ahead(self.rows + len(t), after[-1])])
                self.rephased[self.rows + a] = rephase(after, self.t0, self.spacing)
            if k:
                self.t0 = self.rephased[self.rows + a]
            out[a:b] = nearest_tick((t[a:b] - self.t0) / self.spacing)
        return out

    def _sample(self, times):
        if self._sampled < RATE_SAMPLE:
            self.base_times.append(times[:RATE_SAMPLE - self._sampled])
            self._sampled += len(self.base_times[-1])

    def check_rate(self):
        """The log's base rate against the table's, once over the log (not per block: a block of a
        few jittered rows cannot tell the rate), from the rows where the inputs read."""
        if self.cols.time is not None and self.base_times:
            from ..timing import check_rate

            check_rate(np.concatenate(self.base_times), self.table.sample_time_s, self.source,
                       self.cols.time_scale)


def _startup_ticks(table) -> float:
    """The start-up of ``table`` in whole base ticks (:func:`~cfdesign.linear.startup_steps`
    rounded up; ``inf`` when its error does not die away): rows on a tick before it are the
    start-up's."""
    from ..linear import startup_steps

    steps = startup_steps(table.F, table.H, table.K, table.gain_form)
    return float(math.ceil(steps)) if math.isfinite(steps) else math.inf


def _arrow_types(frame):
    """The Parquet types of the log's passed-through columns over all its blocks (a column of
    integers with a gap in a later block is a column of floats; one empty in the first block
    takes the type of its first value)."""
    pa = require_extra("pyarrow", NEEDS_PYARROW)

    schema = pa.Schema.from_pandas(frame, preserve_index=False).remove_metadata()
    empty = frame.isna().all(axis=0) if len(frame) else None  # no value: any type (CSV chunks read floats)
    return pa.schema([f.with_type(pa.null()) if empty is not None and empty[f.name] else f for f in schema])


def _lock(table, blocks, cols, source, types=False):
    """First pass: check times and collect the ticks at which each measurement arrives (and,
    with ``types``, the Parquet types of the passed-through columns over every block)."""
    from ..timing import lock_schedule

    place = _Pass(table, cols, source, blocks=blocks)
    arrivals = {s.name: [] for s in table.measurements}
    inputs = {s.name: _Held() for s in table.inputs}  # the ticks without a reading of each input sensor
    last, first = -1, None  # the last tick; the first direct reading (_first_direct)
    schemas = []
    for block in blocks():
        if types:
            schemas.append(_arrow_types(block[cols.extra]))
        values = _numeric(block, [c for c in cols.read if c == cols.time or c in cols.sensors.values()], source,
                          lambda i, start=place.rows: cols.lines.at(start + i), cols.time, cols.time_scale,
                          cols.scales)
        if cols.time is not None and block[cols.time].dtype == np.float32:
            _check_float32_time(values[cols.time], cols.time, table.sample_time_s, source, cols.time_scale)
        first_row = place.rows
        ticks = place.ticks(values)
        for s in table.measurements:
            arrivals[s.name].append(ticks[np.isfinite(values[cols.sensors[s.name]])])
        for name, held in inputs.items():
            held.add(ticks, np.isfinite(values[cols.sensors[name]]), first_row)
        here = _first_direct(table, ticks, {s.name: values[cols.sensors[s.name]] for s in table.measurements})
        if here is not None and (first is None or here[:3] < first[:3]):
            first = here
        last = int(ticks[-1]) if len(ticks) else last
    place.check_rate()
    arrivals = {k: _unique(np.concatenate(v)) if v else np.zeros(0, np.int64) for k, v in arrivals.items()}
    if schemas:
        pa = require_extra("pyarrow", NEEDS_PYARROW)

        schemas = pa.unify_schemas(schemas, promote_options="permissive")
    lock = lock_schedule(table, arrivals, last + 1, recompute=table.has_kalman_gains)
    lock.notes[:0] = [f"{name} (an input) has no reading in the log: the estimates run on an input of zero"
                      if held.last is None else held.note(name, last, table.sample_time_s, cols.lines)
                      for name, held in inputs.items() if held.last is None or held.missing(last)]
    lock.notes[:0] = [f"{name} repeats its last reading on the rows between its readings (a forward-filled "
                      f"column): a value that differs from the one before is read as a reading "
                      f"({len(arrivals[name])} of them), a repeat is not (nor a reading equal to the one before)"
                      for name in place.filled]
    return lock, place.rows, schemas or None, (place.grid, place.rephased, first)


def _check_float32_time(t, name, dt, source, scale=1.0):
    """A float32 time column (``t`` in seconds, ``scale`` seconds a unit of the column) must resolve
    a tenth of a tick (at 1.7e9 s, Unix time, its steps are 128 s)."""
    finite = np.abs(t[np.isfinite(t)])
    if finite.size:
        step = float(np.spacing(np.float32(finite.max() / scale))) * scale
        if step > dt / 10:
            raise DataError(f"{source}: the time column {name!r} is float32, whose steps at {finite.max():.6g} s are "
                            f"{step:.3g} s, too coarse for the table's {dt:.6g} s tick; write times as float64")


def _first_direct(table, ticks, readings):
    """``(tick, variance, sensor, value)`` of the first usable reading
    (:func:`~cfdesign.runtime.filter.usable`; the first of its tick, as ``_Runner._dense`` keeps it)
    of a sensor whose row of H picks the quantity (state 0); on a shared tick the most precise one
    (the least variance in the table's ``R``; a table without ``R``: the first by name; a compass of
    0.05 rad beside odometry of 0.01 rad had started the heading from the compass, by its name),
    None when there is none.  ``readings``: ``{sensor: values}`` of the rows at ``ticks``
    (ascending; NaN where none).  Tuples compare as the order of preference."""
    from ..runtime.filter import usable  # a rejected reading (inf, beyond the limit) is no start

    e0 = np.eye(table.F.shape[0])[0]
    firsts = []
    for s in table.measurements:
        if not np.array_equal(table.H[s.index], e0):
            continue
        col = readings[s.name]
        ok = np.flatnonzero(~np.isnan(col))
        at, row = _unique(ticks[ok], return_index=True)
        good = np.flatnonzero(usable(col[ok[row]]))
        if good.size:
            var = float(table.R[s.index, s.index]) if table.R is not None else 0.0
            firsts.append((int(at[good[0]]), var, s.name, float(col[ok[row[good[0]]]])))
    return min(firsts) if firsts else None


def _unique(a, return_index=False):
    """``np.unique`` of ticks, in one pass where they ascend (a log's ticks do: times increase);
    ``np.unique`` sorted a million ticks by hashing, a tenth of a million-row run."""
    a = np.asarray(a)
    if a.size and not np.all(a[1:] >= a[:-1]):
        return np.unique(a, return_index=return_index)
    first = np.flatnonzero(np.concatenate([[True], a[1:] != a[:-1]])) if a.size else np.zeros(0, np.int64)
    return (a[first], first) if return_index else a[first]


class _Held:
    """The ticks at which an input sensor has no reading (its last reading is held there), counted
    block by block: how many, and the longest gap with the row it follows (rows numbered from 0)."""

    def __init__(self):
        self.last = self.line = None  # tick and row of the last reading so far
        self.gaps = 0  # ticks without a reading between readings
        self.longest = (0, 0)  # (ticks, row of the reading before the gap)

    def add(self, ticks, read, first_row):
        rows = np.flatnonzero(read)
        if not rows.size:
            return
        at = _unique(ticks[rows]) if self.last is None else _unique(np.concatenate([[self.last], ticks[rows]]))
        skip = np.diff(at) - 1
        self.gaps += int(skip.sum())
        if skip.size and skip.max() > self.longest[0]:
            k = int(np.argmax(skip))
            before = rows[ticks[rows] <= at[k]]  # the row of the reading before the gap (or the last block's)
            self.longest = (int(skip[k]), first_row + int(before[-1]) if before.size else self.line)
        if self.last is None:
            self.gaps += int(at[0])  # ticks before the first reading
        self.last, self.line = int(at[-1]), first_row + int(rows[-1])

    def missing(self, last_tick) -> int:
        """Ticks of the log (``0 .. last_tick``) without a reading."""
        return self.gaps + (last_tick - self.last)

    def note(self, name, last_tick, dt, lines) -> str:
        """The note on the held ticks; ``lines.at(row)`` names where a row is (a line, a Parquet row)."""
        ticks, row = self.longest
        longest = f", the longest {ticks} ticks ({ticks * dt:.3g} s) after {lines.at(row)}" if ticks > 1 else ""
        # the table knows nothing of how the input moves, so no std can carry the hold's error: a
        # position filter's accelerometer held 22 s had 11.9 m RMS error against 1.07 m predicted
        std = ("; the predicted std leaves out the error of the held value, which grows with the gap"
               if ticks > 1 else "")
        return (f"{name} (an input) has no reading at {self.missing(last_tick)} of {last_tick + 1} ticks{longest}: "
                f"its last reading is held there{std}")
