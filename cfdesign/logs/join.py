"""A log kept as one file per sensor (PX4's ``ulog2csv``, ROS's ``rostopic echo -p``): the rows of
the joined files merged into the blocks of the main log by time (:func:`~cfdesign.logs.run_log`'s
``join``, ``cfdesign run --join``).

The main file streams in blocks as a log alone does; a joined file is read whole (the slow
sensors: a 1 Hz topic beside a 100 Hz IMU), only the columns the run uses, each with its own time
column and unit, checked as a log is (its cells, its times, naming that file).  Its rows go
between the main file's by time, after the main file's rows at the same time and in the order the
files are given: the log is then the one ``pandas.concat`` of the files sorted stably by time gives.
"""

from __future__ import annotations

import numpy as np

from ..errors import DataError
from .columns import TIME_UNITS, _listed, _named_unit, _numeric, _pandas, _time_unit
from .read import _header, _lines, _row_units, _unique, read_log, sensor_column, time_column


def joined_header(table, header, source, paths, *, time=None, mapping=None, reference=None) -> tuple:
    """``(header, used, listing)``: the main file's header with the columns each joined file gives
    the run after it, ``{path: [column]}`` of those, and every file's columns for a message.

    A column the run uses is a sensor's (its name, or the ``mapping`` one; the sensor's name in
    another case when the file holds one such column) or a reference's; a joined file's other
    columns are not read.  A joined file's time column is its own, never a used one.

    Parameters
    ----------
    table : GainTable
        The table run: its sensors' names.
    header : list of str
        The main file's column names.
    source : str
        The main file's name, for messages.
    paths : list of str or Path
        The joined files.
    time : str, optional
        The time column of every file (``--time``); default each file's own (:func:`time_column`).
    mapping : dict, optional
        ``{sensor: column}``, as :func:`~cfdesign.logs.run_log` takes it.
    reference : str or list of str, optional
        ``COLUMN`` or ``STATE=COLUMN`` items, as :func:`~cfdesign.logs.run_log` takes them.

    Returns
    -------
    tuple
        ``(header, used, listing)``: list of str, dict of path to list of str, str.

    Raises
    ------
    DataError
        A used column is in two files (naming it and both files), a joined file cannot be read or
        has no time column.
    """
    headers = {p: _unique(_header(p), p) for p in paths}
    times = {p: _time_of(p, h, time) for p, h in headers.items()}
    files = [(source, [str(h).strip() for h in header], None), *((p, h, times[p]) for p, h in headers.items())]
    mapping = mapping if isinstance(mapping, dict) else {}
    items = [reference] if isinstance(reference, str) else reference if isinstance(reference, (list, tuple)) else []
    reads = table.sensor_units()
    wanted = [(mapping.get(s, s), reads[s] if s not in mapping else None) for s in table.sensor_names()]
    wanted += [(str(r).partition("=")[2] or str(r), None) for r in items if isinstance(r, str)]
    used, missing = {p: [] for p in paths}, []
    for name, reads in dict.fromkeys(wanted):
        found = [(f, c) for f, h, t in files for c in [_found(name, h, reads, t)] if c is not None]
        missing += [] if found else [name]
        if len(found) > 1:
            raise DataError(f"column {name!r} is in both {found[0][0]} and {found[1][0]}: each column a run uses "
                            "must be in one file (rename one, or --map the sensor to a column of its own)")
        if found and found[0][0] != source and found[0][1] not in used[found[0][0]]:
            used[found[0][0]].append(found[0][1])
    listing = "; ".join(f"{f}: {_listed(h, 200)}" for f, h, _ in files)
    idle = next((p for p, cols in used.items() if not cols), None)
    if idle is not None and not missing:  # else the message on the missing column, which lists every file's
        raise DataError(f"{idle}: none of its columns ({_listed(headers[idle])}) is one the run uses (a sensor's, by "
                        "the table's name or --map, or a --reference): a file joined by mistake?")
    return [*header, *(c for cols in used.values() for c in cols)], used, listing


def _found(name, header, reads, time):
    """The column of ``header`` that is ``name``, not the file's ``time``; or, for a sensor's own name
    (``reads``: the unit it reads, :func:`~cfdesign.logs.read.sensor_column`), the one its name
    takes in another case or with a unit; else None."""
    if reads is None:
        return name if name in header and name != time else None
    return sensor_column(name, header, reads, time)


def _time_of(path, header, time):
    """The time column of a joined file: ``time`` (given for every file) or the one its header names."""
    if time is not None and time not in header:
        raise DataError(f"{path}: no time column {time!r} (columns: {_listed(header)})")
    found = time or time_column(header)
    if found is None:
        raise DataError(f"{path}: no time column ('time', 't', 'timestamp' in any case or with a unit, or a ROS "
                        f"export's '%time'; columns: {_listed(header)}): a joined file's rows are placed by their "
                        "times (--time COLUMN names the time column of every file)")
    return found


class _File:
    """A joined file read whole: its used columns as numbers, its times raw and in seconds (let go
    once merged: :meth:`_Join._prepare`), the span of its times (s)."""

    def __init__(self, path, columns, table, time, time_unit):
        from ..timing import place

        header = _header(path)
        self.path, self.columns = path, list(columns)
        self.time = _time_of(path, header, time)
        units = _row_units(path)  # the unit its name gives, else time_unit (a ROS %time beside PX4's us)
        self.scale = TIME_UNITS[_named_unit(self.time, units) or _time_unit(path, self.time, time_unit, units)]
        self.lines = _lines(path)
        frame = read_log(path, [self.time, *self.columns])
        if not len(frame):
            raise DataError(f"{path}: the joined file has a header but no rows")
        self.values = _numeric(frame, self.columns, path, self.lines.at)
        self.raw = _numeric(frame, [self.time], path, self.lines.at, time=self.time)[self.time]
        # integer times kept whole (a ROS %time: nanoseconds since 1970 lose up to 128 ns as floats)
        self.whole = frame[self.time].to_numpy(dtype=np.int64) if frame[self.time].dtype.kind in "iu" else None
        self.number = _is_number(frame[self.time])
        self.seconds = self.raw * self.scale if self.number else self.raw
        place(self.seconds, table.sample_time_s, source=str(path), rate=False, where=self.lines.at,
              time_scale=self.scale if self.number else 1.0,
              readings={c: ~np.isnan(v) for c, v in self.values.items()})
        self.size, self.span = len(self.raw), (float(self.seconds.min()), float(self.seconds.max()))

    def keys(self, number, scale):
        """The file's times in the main file's: its unit (``scale`` seconds; integer ratios of
        units as a division or a product, as pandas would convert them) when ``number``, else seconds."""
        if not number:
            return self.seconds
        if not self.number:
            return self.seconds / scale
        ratio = self.scale / scale
        if ratio >= 1:  # integers stay integers, as pandas multiplies them
            return (self.whole if self.whole is not None else self.raw) * round(ratio)
        return self.raw / round(1 / ratio)


def _is_number(series) -> bool:
    """Whether a time column holds numbers (not dates, durations or ISO 8601 text)."""
    pd = _pandas()
    if series.dtype.kind in "fiu":
        return True
    if series.dtype.kind in "Mmb" or isinstance(series.dtype, pd.DatetimeTZDtype):
        return False
    return bool(pd.to_numeric(series.astype("string").str.strip(), errors="coerce").notna().any())


class _Join:
    """The rows of the joined files merged into the main log's blocks by time; also the
    ``cols.lines`` of the merged log (:meth:`at` names a row's file and line)."""

    def __init__(self, table, cols, source, main_lines, paths, used, time=None, time_unit=None):
        self.cols, self.source, self.main_lines = cols, source, main_lines
        self.files = [_File(p, used[p], table, time, time_unit) for p in paths]
        self.columns = [c for f in self.files for c in f.columns]
        self.starts = np.cumsum([0, *(f.size for f in self.files)])  # joined row j: of the file before j's start
        # the merged row of each joined row by time (-1: not merged yet), set once for the whole log: an array
        # of them kept per block lay between the blocks' memory (60 MB more peak memory on 10 million rows)
        self.position = None
        self._ready = None
        self.order = None  # the joined rows (in the files' order) sorted by time

    def _prepare(self, block):
        """The joined rows as the main file would hold them, sorted stably by time (the files in
        the order given), once the main file's time column is seen (numbers or dates)."""
        pd = _pandas()
        if self._ready is not None:
            return self._ready
        col = block[self.cols.time]
        number = _is_number(col)
        keys = np.concatenate([f.keys(number, self.cols.time_scale) for f in self.files])
        order = np.argsort(keys, kind="stable")
        times = keys[order] if number else _as_dates(np.concatenate([f.seconds for f in self.files])[order], col)
        frame = pd.DataFrame({self.cols.time: times})
        for f in self.files:
            for c in f.columns:
                mine = [g.values[c] if g is f else np.full(g.size, np.nan) for g in self.files]
                frame[c] = np.concatenate(mine)[order]
        for f in self.files:  # merged into frame: not held twice (40 bytes a joined row of one column)
            f.values = f.raw = f.whole = f.seconds = None
        self.order = order
        self.position = np.full(len(keys), -1, dtype=np.int64)
        self._ready = (keys[order], frame, number)
        return self._ready

    def blocks(self, chunks, rows):
        """The merged blocks of the main file read in ``chunks`` (a fraction of a block each): the
        joined rows merged into each chunk, gathered into blocks of ``rows`` rows of the main file
        (:class:`_Gather`: the main file's chunk and the block it goes into, not a whole block read
        beside its merged copy), and after the last the joined rows after the main file's last time.

        Raises
        ------
        DataError
            The main file has no rows, or a joined file's times do not overlap the main file's.
        """
        merged, main, done, first, last, gather = 0, 0, 0, None, None, None
        for chunk in chunks:
            if not len(chunk):
                continue
            keys, frame, number = self._prepare(chunk)
            main_keys = self._keys(chunk, main)
            finite = np.isfinite(main_keys)
            scale = self.cols.time_scale if number else 1.0
            if first is None and finite.any():
                first = main_keys[np.argmax(finite)] * scale
                self._overlap(first, None)
            last = main_keys[len(finite) - 1 - np.argmax(finite[::-1])] * scale if finite.any() else last
            upto = int(np.searchsorted(keys, main_keys[-1], side="left")) if np.isfinite(main_keys[-1]) else done
            upto = max(upto, done)
            joined, at = frame.iloc[done:upto], np.searchsorted(main_keys, keys[done:upto], side="right")
            if gather is not None and not gather.fits(chunk, joined):  # a column of text in this chunk only
                box, gather = [gather.frame()], None
                yield box.pop()
            if gather is None:
                more = min(len(keys) - done, int(rows * (upto - done) / len(chunk) * 1.5) + 1024)
                gather = _Gather(self.cols.read, chunk, joined, rows + more, merged)
            gather.add(chunk, joined, at)
            self.position[done:upto] = merged + at + np.arange(upto - done)
            merged, main, done = merged + len(chunk) + upto - done, main + len(chunk), upto
            empty = chunk.iloc[:0].copy()
            chunk = main_keys = finite = joined = None
            if gather.main >= rows:
                # no reference to the block is kept while it runs: run_log's copy of it with the rows of the
                # block before (a tick split between blocks) had been a second copy (36 MB more at the peak)
                box, gather = [gather.frame()], None
                yield box.pop()
        if main == 0:
            raise DataError(f"{self.source}: the log has a header but no rows")
        self._overlap(first, last)
        if done < len(keys):
            joined = frame.iloc[done:]
            gather = gather if gather is not None and gather.fits(empty, joined) else _Gather(
                self.cols.read, empty, joined, len(joined), merged)
            gather.add(empty, joined, np.zeros(len(joined), np.int64))
            self.position[done:] = merged + np.arange(len(joined))
        if gather is not None:
            yield gather.frame()

    def _keys(self, block, main):
        """The times of the main file's ``block`` (its rows from ``main`` on) as numbers: in its unit,
        or dates as seconds; a float column as it is (no copy of a million rows)."""
        col = block[self.cols.time]
        if col.dtype.kind == "f":
            return col.to_numpy(dtype=float)
        if col.dtype.kind in "iu":  # whole, as the joined files' integer times are compared with them
            return col.to_numpy(dtype=np.int64)
        return _numeric(block, [self.cols.time], self.source, lambda i: self.main_lines.at(main + i),
                        time=self.cols.time)[self.cols.time]

    def _overlap(self, first, last):
        """A joined file whose times lie all before the main file's ``first`` (s) or, once its
        ``last`` is known, all after it: the files' clocks differ."""
        if first is None:  # no time in the main file: its first row is named so (timing.place)
            return
        for f in self.files:
            a, b = f.span
            if b < first or (last is not None and a > last):
                span = f"from {first:.10g} s" if last is None else f"{first:.10g} s to {last:.10g} s"
                raise DataError(f"{f.path}: its times ({a:.10g} s to {b:.10g} s) do not overlap those of {self.source} "
                                f"({span}): the files' clocks differ (a ROS %time is nanoseconds since 1970, a PX4 "
                                "timestamp microseconds since boot); join files stamped by one clock")

    def at(self, row) -> str:
        """Where row ``row`` of the merged log is, for a message: the main file's line (or Parquet
        row), or ``line N of FILE`` of a joined file."""
        row = int(row)
        placed = self.position[:int(np.sum(self.position >= 0))] if self.position is not None else np.zeros(0)
        k = int(np.searchsorted(placed, row))  # the joined rows before it
        if k < len(placed) and placed[k] == row:
            j = int(self.order[k])
            i = int(np.searchsorted(self.starts, j, side="right")) - 1
            return f"{self.files[i].lines.at(j - self.starts[i])} of {self.files[i].path}"
        return self.main_lines.at(row - k)

    def notes(self) -> list:
        """The notes of the joined files (a row of units, a cut end), as a log's."""
        from .read import _tail_note, _units_note

        return [n for f in self.files for n in _units_note(f.path, str(f.path)) + _tail_note(f.path, str(f.path))]


class _Gather:
    """The merged rows of the main file's chunks gathered into one block: the columns of numbers
    written into one array of floats (as ``read_csv`` gives a block, and as ``pandas.concat`` gives
    them with the joined rows' gaps), grown if the joined rows outnumber its room; other columns
    (text, dates, booleans) concatenated by pandas.  A block merged as a whole beside the chunk
    read for it held both (and a frame concatenated and reordered four copies): 60 MB more peak
    memory on 10 million rows."""

    def __init__(self, columns, chunk, joined, room, start):
        self.columns, self.start = list(columns), start
        self.numbers = self._numbers(chunk, joined)
        self.values = np.empty((len(self.numbers), room))
        self.others = {c: [] for c in self.columns if c not in self.numbers}
        self.size = self.main = 0  # rows, and rows of the main file, so far

    def _numbers(self, chunk, joined) -> list:
        """The columns written as floats: numbers, but not integers in both frames (a time column of
        integers, as pandas.concat keeps it: a ROS %time written as a float had lost its last digits)."""
        def number(c):
            kinds = [f[c].dtype.kind for f in (chunk, joined) if c in f.columns]
            return all(k in "fiu" for k in kinds) and not (len(kinds) == 2 and all(k in "iu" for k in kinds))

        return [c for c in self.columns if number(c)]

    def fits(self, chunk, joined) -> bool:
        """Whether the columns of numbers of ``chunk`` and ``joined`` are this block's."""
        return self._numbers(chunk, joined) == self.numbers

    def add(self, chunk, joined, at):
        """``chunk`` of the main file with the ``joined`` rows before its rows ``at``."""
        pd = _pandas()
        n, m = len(chunk), len(joined)
        if self.size + n + m > self.values.shape[1]:
            grown = np.empty((len(self.numbers), max(2 * self.values.shape[1], self.size + n + m)))
            grown[:, :self.size] = self.values[:, :self.size]
            self.values = grown
        mine = np.ones(n + m, dtype=bool)
        mine[at + np.arange(m)] = False
        part = self.values[:, self.size:self.size + n + m]
        for i, c in enumerate(self.numbers):
            part[i, mine] = chunk[c].to_numpy() if c in chunk.columns else np.nan
            part[i, ~mine] = joined[c].to_numpy() if c in joined.columns else np.nan
        if self.others and n + m:
            take = np.empty(n + m, dtype=np.int64)
            take[mine], take[~mine] = np.arange(n), n + np.arange(m)
            for c, parts in self.others.items():  # an empty side left out: its dtype was the column's on
                # pandas 3 (int64 cells became objects) and not on pandas 2, which warned that it would be
                both = pd.concat([(f[c] if c in f.columns else pd.Series(np.full(len(f), np.nan)))
                                  .reset_index(drop=True) for f in (chunk, joined) if len(f)], ignore_index=True)
                parts.append(both.iloc[take].reset_index(drop=True))
        self.size, self.main = self.size + n + m, self.main + n

    def frame(self):
        """The block: its rows numbered on from the rows of the blocks before it."""
        pd = _pandas()
        out = pd.DataFrame(self.values[:, :self.size].T, columns=self.numbers, copy=False,
                           index=pd.RangeIndex(self.start, self.start + self.size))
        for i, c in enumerate(self.columns):
            if c in self.others:
                out.insert(i, c, pd.concat(self.others[c], ignore_index=True).array)
        return out


def _as_dates(seconds, like):
    """``seconds`` since 1970 as the main file's time column holds dates: datetimes (in its zone),
    durations, or ISO 8601 text."""
    pd = _pandas()
    ns = np.round(seconds * 1e9).astype(np.int64)
    if like.dtype.kind == "m":
        return pd.to_timedelta(ns, unit="ns")
    when = pd.to_datetime(ns, unit="ns", utc=True)
    if isinstance(like.dtype, pd.DatetimeTZDtype):
        return when.tz_convert(like.dtype.tz)
    if like.dtype.kind == "M":
        return when.tz_localize(None)
    return np.array([w.isoformat() for w in when], dtype=object)
