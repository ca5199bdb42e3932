"""Running a gain table on the logs people have: timestamped, gapped, big, many.

A log is a table with one column per sensor (named as in the gain table, or mapped to it),
usually a time column (seconds), and any other columns, which are passed through.  A slow
sensor's column is empty (NaN) between its readings - the natural way to log - and its
readings arrive when they arrive: :mod:`cfdesign.timing` places every row on the table's base
tick by its time and locks the table's schedule to the actual arrivals (recomputing the gains
for the actual pattern where each sensor has its own offset).  The filter then runs at batch
speed (:class:`cfdesign.runtime.Runtime`), in blocks of rows so that a 10-million-row log runs
in bounded memory, and the estimates are written with the time column and a column per state
(``heading``, ``gyro_correction``, ...), optionally with their predicted standard deviations.

Reading and writing use pandas (CSV; Parquet through pyarrow), an optional dependency:
``pip install "cfdesign[logs]"``.  Many logs run in parallel on Dask: :func:`run_logs`.
"""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import logging
import math
import numbers
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import CfdesignError, DataError, OutputError
from .files import check_distinct, is_dir, not_a_device, open_atomic, write_bytes, write_text
from .gains import require_table
from .linear import wrap

__all__ = ["LogResult", "run_log", "run_logs", "read_log", "read_columns", "plot_log", "TIME_COLUMNS", "TIME_UNITS",
           "BLOCK_ROWS", "INTERNAL"]

#: column names taken as the time (seconds) when none is given
TIME_COLUMNS = ("time", "t", "timestamp")
#: units a numeric time column may be in (``time_unit``, ``cfdesign run --time-unit``): seconds each
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: cells that are no reading (in lower case, spaces stripped): those pandas reads as missing
MISSING = ("", "nan", "-nan", "na", "n/a", "#n/a", "#na", "null", "none", "<na>", "nat")
#: how the summary of :func:`run_logs` begins the error of a log that met a fault of cfdesign, not of the log
INTERNAL = "internal error"
#: rows read, run and written at a time (and ticks run at a time across a gap without rows)
BLOCK_ROWS = 1_000_000
#: a file smaller than this is read once; a larger one twice (arrivals first, then in blocks)
ONE_PASS_BYTES = 200_000_000
#: rows where the inputs read over which the log's base rate is measured (the first ones)
RATE_SAMPLE = 1_000_000


def _pandas(parquet=False):
    """pandas, and with ``parquet`` pyarrow (pandas reads and writes Parquet through it); a
    missing one is a one-line error naming the extra that installs it."""
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - depends on the installation
        raise CfdesignError('reading logs needs pandas: pip install "cfdesign[logs]"') from None
    if parquet:
        try:
            import pyarrow.parquet  # noqa: F401
        except ImportError:
            raise CfdesignError('Parquet logs and estimates need pyarrow: pip install "cfdesign[logs]"') from None
    return pd


# ---------------------------------------------------------------------------- results
@dataclass
class LogResult:
    """What running a table on a log gave.

    Attributes
    ----------
    estimates : pandas.DataFrame or None
        One row per log row: the time column (if any), a column per state (the table's
        ``states``), ``<state>_std`` columns when asked for,
        and the log's other columns.  None when the estimates were written to a file only.
    samples : int
        Rows run.
    rms : dict
        ``{state: RMS error against the reference column}`` over every row (angles wrapped to
        (-pi, pi]); NaN when no row has a finite reference to compare with.  It includes the
        start-up, where the error of the initial state is still dying away.
    unused : dict
        Readings not used, by reason and sensor: ``rejected`` (inf, or beyond the runtime's
        :data:`~cfdesign.runtime.filter.READING_LIMIT`), ``unscheduled`` (no gain at its
        tick), ``same_tick`` (a second reading of a sensor on one base tick), ``before_start``
        (logged more than half a tick before the first row where the inputs read).
    notes : list of str
        What a user should know: offsets found, gains recomputed, rate mismatches.
    output : Path or None
        The file written.
    source : str
        The log's name (its path, or the name given).
    rms_settled : dict
        ``{state: RMS error}`` over the rows after the start-up (``startup_s``); NaN when no
        row after it has a finite reference (the log ends within it).
    predicted_std : dict
        ``{state: predicted standard deviation}`` of the estimate that ran, over the rows of
        ``rms_settled`` (over every compared row when none is after the start-up): the root
        mean square of the ``<state>_std`` column there (the table's figure; a multirate
        table's averaged over its phases; widened through missed readings; of the gains
        recomputed for the log where they were).  What ``rms_settled`` should come to.
    startup_s : float
        The start-up's length in seconds: :func:`~cfdesign.linear.startup_steps` of the table
        (its slowest error mode shrunk :data:`~cfdesign.linear.STARTUP_DECAY` times), rounded up
        to whole base ticks; ``inf`` when the error does not die away (a state no sensor
        corrects).  NaN when the log was run without a reference.
    settled_samples : int
        Rows after the start-up (and after the start-up that follows each pause).
    pauses : int
        Pauses of the logger: more than :data:`~cfdesign.timing.PAUSE_TICKS` ticks without a
        reading of an input sensor, after each of which the first state starts again from the
        first direct reading (its start-up left out of ``rms_settled``).
    """

    estimates: object
    samples: int
    rms: dict = field(default_factory=dict)
    unused: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    output: Path | None = None
    source: str = ""
    rms_settled: dict = field(default_factory=dict)
    predicted_std: dict = field(default_factory=dict)
    startup_s: float = math.nan
    settled_samples: int = 0
    pauses: int = 0

    @property
    def without_gain(self) -> int:
        """Readings not used for any reason (the number ``cfdesign run`` reports)."""
        return sum(sum(v.values()) for v in self.unused.values())

    def summary(self) -> dict:
        """One row of a fleet's summary table (``summary.csv`` of :func:`run_logs`).

        Returns
        -------
        dict
            ``log``, ``samples``, ``readings_not_used``, and for each reference ``rms_<state>``
            (over every row), ``rms_settled_<state>`` (after the start-up, ``startup_s``) and
            ``predicted_std_<state>``, what the settled figure should come to for this log
            (``predicted_std``: missed readings and recomputed gains make it differ from log to log).
        """
        row = {"log": self.source, "samples": self.samples, "readings_not_used": self.without_gain}
        for k, v in self.rms.items():
            row.update({f"rms_{k}": v, f"rms_settled_{k}": self.rms_settled.get(k, math.nan),
                        f"predicted_std_{k}": self.predicted_std.get(k, math.nan)})
        if self.rms:
            row["startup_s"] = self.startup_s
        return row


# ---------------------------------------------------------------------------- columns
@dataclass(frozen=True)
class _Columns:
    """Which log column feeds what."""

    sensors: dict          # sensor -> column
    time: str | None
    references: dict       # state -> column
    extra: list            # passed through
    time_unit: str = "s"     # of a numeric time column (TIME_UNITS)
    lines: object = None     # _Lines: the file line of each row (after the header, the comments before it, blank lines)

    @property
    def time_scale(self) -> float:
        """Seconds per unit of a numeric time column."""
        return TIME_UNITS[self.time_unit]

    @property
    def numeric(self) -> list:
        """The columns that must hold numbers (time, sensors, references), each once."""
        cols = ([self.time] if self.time else []) + [*self.sensors.values(), *self.references.values()]
        return list(dict.fromkeys(cols))

    @property
    def read(self) -> list:
        """Every column read, each once (a reference may be a sensor's or the time column)."""
        return list(dict.fromkeys(self.numeric + self.extra))


#: how a time column's name may write its unit (``time [sec]``, ``t (µs)``)
_UNIT_NAMES = {**{w: "s" for w in ("s", "sec", "secs", "second", "seconds")},
               **{w: "ms" for w in ("ms", "msec", "millisecond", "milliseconds")},
               **{w: "us" for w in ("us", "\u00b5s", "\u03bcs", "usec", "microsecond", "microseconds")},
               **{w: "ns" for w in ("ns", "nsec", "nanosecond", "nanoseconds")}}


def _unit(name) -> tuple:
    """``(name, unit)`` of a column named with its unit (``gyro [rad/s]``, ``time (ms)``, or a unit of
    time after an underscore: ``time_ms``), else ``(name, None)``; a unit of time as
    :data:`TIME_UNITS` names it (``sec`` is ``s``)."""
    m = re.fullmatch(r"(.*?)\s*(?:\[([^\]]*)\]|\(([^)]*)\))", str(name).strip())
    if not (m and m.group(1)):
        m = re.fullmatch(r"(.+?)_([^_]+)", str(name).strip())
        unit = _UNIT_NAMES.get(m.group(2).lower()) if m else None
        return (m.group(1), unit) if unit else (name, None)
    unit = (m.group(2) if m.group(2) is not None else m.group(3)).strip()
    return m.group(1), _UNIT_NAMES.get(unit.lower(), unit)


def _time_with_unit(name):
    """The time column name (one of :data:`TIME_COLUMNS`, in lower case) that ``name`` is with a unit
    of time (``time [ms]``, ``t_us``), else None."""
    base, unit = _unit(name)
    return str(base).lower() if str(base).lower() in TIME_COLUMNS and unit in TIME_UNITS else None


def _time_name(name) -> bool:
    """Whether ``name`` is taken as the time when no time column is given: one of
    :data:`TIME_COLUMNS` in any case, or with a unit of time (:func:`_time_with_unit`)."""
    name = str(name).strip()
    return name.lower() in TIME_COLUMNS or _time_with_unit(name) is not None


def _time_unit(source, time, time_unit, units=None) -> str:
    """The unit of a numeric time column: ``time_unit`` if given, else the one its name gives
    (``time [ms]``) or the row of ``units`` under a CSV's header (``{column: unit}``), else
    seconds; a given unit that contradicts the name or the row is refused."""
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise CfdesignError(f"time unit {time_unit!r} is none of {', '.join(TIME_UNITS)}")
    written = (units or {}).get(time, "").strip(" []()").lower()
    named = (_unit(time)[1] or _UNIT_NAMES.get(written)) if time is not None else None  # in its name or units row
    if named in TIME_UNITS and time_unit not in (None, named):
        raise DataError(f"{source}: the time column {time!r} is in {named}, but the time unit given is {time_unit}")
    return time_unit or (named if named in TIME_UNITS else "s")


def _columns(table, header, source, time=None, mapping=None, reference=None, time_unit=None,
             lines=None, units=None) -> _Columns:
    header = [str(h).strip() for h in header]
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{source}: duplicate column(s) {', '.join(dup)}")
    if mapping is not None and not isinstance(mapping, dict):  # a list of pairs gave dict()'s raw ValueError
        raise CfdesignError(f"mapping must be a dict {{sensor: column}}, got {type(mapping).__name__} {mapping!r:.80}")
    mapping = dict(mapping or {})
    unknown = sorted(set(mapping) - set(table.sensor_names()))
    if unknown:
        raise DataError(f"--map {unknown[0]}: {table.name} has no sensor {unknown[0]!r} "
                        f"(sensors: {', '.join(table.sensor_names())})")
    sensors = {s: mapping.get(s, s) for s in table.sensor_names()}
    for s, c in sensors.items():  # a sensor's name in another case ('Gyro', 'GYRO'), as the time column's
        like = [h for h in header if h.lower() == s.lower()]
        if s not in mapping and c not in header and len(like) == 1:
            sensors[s] = like[0]
    missing = [f"{c} (sensor {s})" if c != s else c for s, c in sensors.items() if c not in header]
    if missing:
        # a column named with its unit ('gyro [rad/s]') is not taken in silence: its unit may not be the table's
        like = [(s, h) for s, c in sensors.items() if c not in header and s not in mapping
                for h in header if _unit(h)[1] is not None and _unit(h)[0].lower() == s.lower()]
        hint = " ".join(f'--map "{s}={h}"' for s, h in like)
        raise DataError(f"{source}: missing column(s) {', '.join(missing)} (columns: {_listed(header)}); "
                        + (f"columns named with a unit are mapped where it is the table's: {hint}" if like else
                           "the header is one column: cells are separated by commas, by the semicolons or tabs "
                           "of a header without a comma, or by spaces where the first row has as many cells"
                           if len(header) == 1 else
                           "name them as the table's sensors or map them with --map SENSOR=COLUMN"))
    if time is None:  # 'time', 't', 'timestamp', else in another case ('Time'), else with a unit ('time [ms]', 't_us')
        time = next((c for c in TIME_COLUMNS if c in header), None) or next(
            (h for c in TIME_COLUMNS for h in header if h.lower() == c), None) or next(
            (h for c in TIME_COLUMNS for h in header if _time_with_unit(h) == c), None)
    elif time not in header:
        raise DataError(f"{source}: no time column {time!r} (columns: {_listed(header)})")
    time_unit = _time_unit(source, time, time_unit, units)
    shared = {c: [s for s, col in sensors.items() if col == c] for c in sensors.values()}
    shared = {c: names for c, names in shared.items() if len(names) > 1}
    if shared:  # one column read as two sensors (a --map typo) ran a filter on the wrong readings in silence
        c, names = next(iter(shared.items()))
        raise DataError(f"{source}: column {c!r} is given to sensors {' and '.join(names)} "
                        "(each sensor needs a column of its own: --map SENSOR=COLUMN)")
    if time is not None and time in sensors.values():
        s = next(s for s, c in sensors.items() if c == time)
        raise DataError(f"{source}: column {time!r} is both the time and sensor {s} "
                        "(--time COLUMN, --map SENSOR=COLUMN)")
    refs = _references(table, reference, header, source)
    used = {time, *sensors.values()}  # a reference column is passed through as well
    return _Columns(sensors, time, refs, [h for h in header if h not in used], time_unit, lines or _Lines())


def _listed(header, limit=300) -> str:
    """The column names for a message, cut to about ``limit`` characters (a file read as one
    column - JSON, a spreadsheet - or a log of thousands of columns gave a line of megabytes)."""
    text = ", ".join(str(h) for h in header)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(header)} columns)"


def _references(table, reference, header, source) -> dict:
    """``{state: column}`` from ``COLUMN`` (the first state) or ``STATE=COLUMN`` items."""
    out = {}
    items = [reference] if isinstance(reference, str) else reference or []
    if not isinstance(items, (list, tuple)) or not all(isinstance(item, str) for item in items):
        raise CfdesignError(f"reference must be a column name or a list of COLUMN / STATE=COLUMN texts, "
                            f"got {reference!r:.80}")
    for item in items:
        state, sep, col = item.partition("=")
        state, col = (state, col) if sep else (table.states[0], state)
        if state not in table.states:
            raise DataError(f"--reference {item}: {table.name} has no state {state!r} "
                            f"(states: {', '.join(table.states)})")
        if col not in header:
            raise DataError(f"{source}: no reference column {col!r} (columns: {_listed(header)})")
        if state in out:
            raise DataError(f"--reference {item}: state {state} already has the reference {out[state]!r}")
        out[state] = col
    return out


def _numeric(df, columns, source, line, time=None, time_scale=1.0):
    """The columns as float arrays; a cell that is not a number is an error naming its line
    (``line(i)``: the file line of row ``i`` of ``df``).

    The ``time`` column may also hold dates (a datetime column of a Parquet file, ISO 8601 text
    in a CSV: ``2024-05-01T12:00:00.010``): they become seconds since 1970-01-01 UTC (a date
    without a time zone is taken as UTC; only differences matter); durations (a timedelta
    column) become seconds.  Numbers in the ``time`` column are multiplied by ``time_scale``
    (seconds per unit: milliseconds, nanoseconds ...)."""
    pd = _pandas()
    out = {}
    for c in columns:
        s = df[c]
        if s.dtype.kind in "fiub":
            out[c] = s.to_numpy(dtype=float) * (time_scale if c == time else 1.0)
            continue
        if c == time and (s.dtype.kind == "M" or isinstance(s.dtype, pd.DatetimeTZDtype)):
            out[c] = _epoch_seconds(s)
            continue
        if c == time and s.dtype.kind == "m":  # durations (a Parquet duration column): seconds; NaT is NaN
            out[c] = s.dt.total_seconds().to_numpy(dtype=float)
            continue
        text = s.astype("string").str.strip()
        text = text.where(~text.str.lower().isin(MISSING))  # 'NaN ' padded by a fixed-width export: missing too
        values = pd.to_numeric(text, errors="coerce")
        bad = np.flatnonzero(values.isna().to_numpy() & text.notna().to_numpy())
        if bad.size and c == time and len(bad) == int(text.notna().sum()):  # no number: dates?
            dates, not_date = _dates(text)
            if not_date is None:
                out[c] = dates
                continue
            bad = [not_date]  # the first cell that is no date either
        if len(bad):
            what = ("neither a number (seconds, or the --time-unit ms|us|ns) nor an ISO 8601 date and time "
                    "(2024-05-01T12:00:00.010)" if c == time else "not a number")
            cell = str(text.iloc[bad[0]])
            hint = (" (a decimal comma: read in a log separated by semicolons, tabs or spaces whose first 64 kB "
                    "show one, not in one separated by commas; write decimal points)"
                    if re.fullmatch(r"[-+]?[0-9]+,[0-9]+(?:[eE][-+]?[0-9]+)?", cell) else
                    " (a comment line: only those before the header are skipped)" if cell.startswith("#") else "")
            raise DataError(f"{source} line {line(bad[0])}: column {c!r} is {what}: {_cell_text(s.iloc[bad[0]])}"
                            + hint)
        out[c] = values.to_numpy(dtype=float) * (time_scale if c == time else 1.0)
    return out


def _cell_text(cell, limit=40) -> str:
    """A cell for a message: its repr, cut to about ``limit`` characters (a row of the NUL bytes a
    log cut off by a power loss ends in printed thousands of ``\\x00``)."""
    text = repr(cell)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(str(cell))} characters)"


def _dates(text):
    """``(epoch seconds, None)`` for a column of ISO 8601 dates (:func:`cfdesign.timing.date_seconds`),
    or ``(None, i)`` with ``i`` the first cell that is not one."""
    from .timing import date_seconds

    def seconds(cell):
        try:
            return date_seconds(cell)
        except (TypeError, ValueError):  # NA (an empty cell) is a TypeError: NaN, the others are named
            return math.nan

    values = text.map(seconds, na_action="ignore").to_numpy(dtype=float)
    wrong = np.flatnonzero(np.isnan(values) & text.notna().to_numpy())
    return (None, int(wrong[0])) if wrong.size else (values, None)


def _epoch_seconds(s):
    """A datetime series as float seconds since 1970-01-01 UTC (naive dates taken as UTC); NaT is NaN."""
    pd = _pandas()
    s = pd.Series(s)
    if s.dt.tz is None:
        s = s.dt.tz_localize("UTC")
    return ((s - pd.Timestamp(0, tz="UTC")) / pd.Timedelta(seconds=1)).to_numpy(dtype=float)


# ---------------------------------------------------------------------------- reading
#: the first bytes of the compressions a CSV log may come in (pandas and Python's modules read them)
COMPRESSIONS = {b"\x1f\x8b": "gzip", b"BZh": "bz2", b"\xfd7zXZ\x00": "xz", b"PK\x03\x04": "zip"}
#: what cfdesign reads, for the messages about a file it cannot
_READS = "CSV (plain, or compressed with gzip, bz2, xz or zip) and Parquet"


#: the endings of a compressed file's name, left off the names of the estimate files of a fleet
_PACKED_SUFFIXES = (".gz", ".bz2", ".xz", ".zip")


def _log_stem(path) -> str:
    """A log's name without its extensions: ``flight`` of ``flight.csv``, ``flight.csv.gz``.

    Parameters
    ----------
    path : str or Path
        The log.

    Returns
    -------
    str
        The name an estimate file of a fleet takes (:func:`run_logs`) before its own suffix.
    """
    path = Path(path)
    if path.suffix.lower() in _PACKED_SUFFIXES:
        path = Path(path.stem)
    return path.stem


def _kind(path) -> str:
    """``'parquet'``, ``'csv'`` or the compression of a CSV (:data:`COMPRESSIONS`), from the
    file's first bytes, whatever its name (``log.csv.gz``, a Parquet file named ``.bin``); a
    ``.parquet`` name without Parquet's bytes is read as Parquet, for pyarrow to name the fault."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as exc:
        raise _read_error(Path(path), exc) from None
    if head.startswith(b"PAR1"):
        return "parquet"
    kind = next((k for magic, k in COMPRESSIONS.items() if head.startswith(magic)), None)
    if kind:
        return kind
    return "parquet" if Path(path).suffix.lower() in (".parquet", ".pq") else "csv"


def _open_csv(path, kind):
    """The bytes of a CSV log, decompressed (a zip must hold one file)."""
    if kind == "csv":
        return open(path, "rb")
    if kind == "zip":
        import zipfile

        try:
            archive = zipfile.ZipFile(path)
        except zipfile.BadZipFile as exc:
            raise DataError(f"cannot read {path}: {exc} (a damaged zip archive)") from None
        names = [n for n in archive.namelist() if not n.endswith("/")]
        if len(names) != 1:
            archive.close()
            raise DataError(f"cannot read {path}: a zip archive of {len(names)} files (a spreadsheet's own format "
                            "is one: export it as CSV); cfdesign reads a zip that holds one CSV")
        return archive.open(names[0])
    import bz2
    import gzip
    import lzma

    return {"gzip": gzip.open, "bz2": bz2.open, "xz": lzma.open}[kind](path, "rb")


def read_log(path, columns=None, *, chunksize=None):
    """Read a CSV (UTF-8, a BOM and CRLF line ends are fine) or Parquet log with pandas.

    What a file is comes from its first bytes, not its name: Parquet, or a CSV, plain or
    compressed with gzip, bz2, xz or zip (one file in the archive; ``log.csv.gz``).  A CSV's
    separator is a comma, or the semicolon or tab of its header line when that has no
    comma, or spaces when the header and the first row split into as many cells at spaces
    (``numpy.savetxt``; a semicolon-, tab- or space-separated file may write decimal commas:
    ``0,01``); column names are stripped of spaces, and a row with more cells than the header is
    an error naming its line (it was read without its extra cells), but empty cells after the first
    row's last (a separator ending every row) are columns without a name.  The first cells of a
    row are never an index.  The end of a plain CSV cut off while it was written
    (a power loss) is not read: the NUL bytes it may end in, and its last line when that has no
    line end and has fewer cells than the header or NUL bytes after it (its last cell may have
    lost digits); :func:`run_log` notes it.

    Parameters
    ----------
    path : str or Path
        A Parquet file (by its content, or named ``.parquet`` / ``.pq``), else a CSV.
    columns : list of str, optional
        Keep only these.
    chunksize : int, optional
        Yield blocks of this many rows instead of one DataFrame.

    Returns
    -------
    pandas.DataFrame or iterator of DataFrame
        The log, or an iterator of blocks of ``chunksize`` rows.

    Raises
    ------
    DataError
        The file cannot be read, is empty, is not text (UTF-8) or not a table (also while blocks
        are read).
    """
    path = Path(path)
    kind = _kind(path)
    pd = _pandas(kind == "parquet")
    try:
        if kind == "parquet":
            return _parquet_blocks(path, columns, chunksize) if chunksize else next(_parquet_blocks(path, columns))
        fmt = _csv_format(path, kind)
        hashed = fmt.pop("_hashed", False)
        if fmt.pop("_units", None) is not None:  # the line under the header: units
            fmt["skiprows"] = [*range(fmt.get("skiprows", 0)), fmt.get("skiprows", 0) + 1]
        end = _tail(path)[0] if kind == "csv" else None
        source = path if end is None else io.BufferedReader(_Upto(path, end))  # a cut end left out
        reader = pd.read_csv(source, chunksize=chunksize, encoding="utf-8-sig", skipinitialspace=True,
                             low_memory=False, index_col=False, compression=None if kind == "csv" else kind, **fmt)
        if chunksize:
            return _csv_blocks(path, reader, columns, hashed, closing=None if end is None else source)
        with contextlib.closing(source) if end is not None else contextlib.nullcontext():
            return _stripped(reader, columns, hashed)
    except (pd.errors.EmptyDataError, pd.errors.ParserError, OSError, UnicodeDecodeError, ValueError,
            *_unpack_errors()) as exc:
        raise _read_error(path, exc) from None


class _Upto(io.RawIOBase):
    """The bytes of a file up to ``end`` (pandas reads a log without its cut end)."""

    def __init__(self, path, end):
        self._fh, self._left = open(path, "rb"), end

    def readable(self):
        return True

    def readinto(self, b):
        n = self._fh.readinto(memoryview(b)[:min(len(b), self._left)])
        self._left -= n
        return n

    def close(self):
        self._fh.close()
        super().close()


def _tail(path) -> tuple:
    """``(end, nul, cells)`` of a plain CSV cut off while it was written: ``end`` the byte its
    rows end at (None: the file is whole), ``nul`` the NUL bytes it ends in (a file system
    that had given the file its space before a power loss), ``cells`` the ``(cells, header
    cells)`` of a last line with no line end and fewer cells than the header or NUL bytes after
    it (else None: a last line without its end is common in files written by hand)."""
    size = os.path.getsize(path)
    text_end = size
    with open(path, "rb") as fh:
        while text_end:  # the NUL bytes at the end, read backwards
            step = min(text_end, 1 << 16)
            fh.seek(text_end - step)
            kept = fh.read(step).rstrip(b"\x00")
            text_end -= step - len(kept)
            if kept:
                break
        start = max(0, text_end - (1 << 16))
        fh.seek(start)
        last = fh.read(text_end - start)
    end, cells = text_end, None
    newline = last.rfind(b"\n")
    if last and not last.endswith(b"\n") and newline >= 0:  # a last line without its end (not the header)
        row = _cells(last[newline + 1:], _csv_format(path).get("sep", ","))
        header = len(_header(path))
        if len(row) < header or text_end < size:  # fewer cells, or NUL bytes where the rest was not written
            cells, end = (len(row), header), start + newline + 1
    return (None if end == size else end), size - text_end, cells


def _row_units(path) -> dict:
    """``{column: unit}`` of the row of units under a CSV's header (:func:`_csv_format`), or ``{}``."""
    kind = _kind(path)
    units = None if kind == "parquet" else _csv_format(path, kind).get("_units")
    return dict(zip(_header(path), units, strict=False)) if units else {}


def _units_note(path, source) -> list:
    """The note on a row of units under a CSV's header, which :func:`read_log` skips, if any."""
    if _kind(path) == "parquet":
        return []
    fmt = _csv_format(path, _kind(path))
    if "_units" not in fmt:
        return []
    return [f"{source} line {2 + fmt.get('skiprows', 0)} ({_listed(fmt['_units'], 80)}) is taken as the columns' "
            "units and not read; the readings are used as they are, in the units the table was designed in"]


def _tail_note(path, source) -> list:
    """The note on the cut end of a CSV that :func:`read_log` leaves out (:func:`_tail`), if any."""
    if _kind(path) != "csv":
        return []
    end, nul, cells = _tail(path)
    if end is None:
        return []
    what = []
    if cells:
        with open(path, "rb") as fh:  # the line's number: one after the line ends before it
            line, left = 1, end
            while left > 0:
                chunk = fh.read(min(left, 1 << 22))
                line, left = line + chunk.count(b"\n"), left - len(chunk)
        what.append(f"its last line ({line}) is cut short ({cells[0]} of {cells[1]} cells, no line end)"
                    if cells[0] < cells[1] else f"its last line ({line}) has no line end")
    if nul:
        what.append(f"it ends in {nul} NUL bytes")
    return [f"{source} was cut off while it was written: {' and '.join(what)}; "
            + ("that line is" if cells else "they are") + " not read"]


def _unpack_errors() -> tuple:
    """What a truncated or damaged compressed CSV raises while it is read (gzip's is an OSError)."""
    import lzma
    import zlib

    return EOFError, zlib.error, lzma.LZMAError


def _read_error(path, exc) -> DataError:
    """The one-line DataError of a log pandas cannot read."""
    pd = _pandas()
    if isinstance(exc, FileNotFoundError):
        return DataError(f"cannot read {path}: no such file")
    if isinstance(exc, UnicodeDecodeError):  # Latin-1 or UTF-16 text, or a file that is not text
        return DataError(f"cannot read {path}: not UTF-8 text (byte {exc.object[exc.start:exc.start + 1].hex()} "
                         f"at byte {exc.start}); cfdesign reads {_READS}: save the log as UTF-8")
    if isinstance(exc, OSError):
        return DataError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}")
    if isinstance(exc, pd.errors.EmptyDataError):
        return DataError(f"{path}: empty file (expected a header row naming the columns)")
    return DataError(f"{path}: not a readable log: {_first_line(exc)}")


#: most comment lines before a CSV's header (``# logged by ...``) that are skipped
COMMENT_LINES = 1000


def _csv_format(path, kind="csv") -> dict:
    """``read_csv`` options of a CSV: its separator, from its header line: a comma unless the line
    has none and has semicolons or tabs, else spaces where the header and the first row split into
    as many cells (:func:`_separator`); a semicolon, tab or space file writes decimal commas when a
    cell of its first 64 kB of rows is a number with one (``0,01``: the first row may be all integers).
    A first row with more cells than the header is :func:`_wider_rows`'.
    A first line ``sep=;`` (written for spreadsheets) names the separator and is skipped.
    Blank lines and lines starting with ``#`` before the header are skipped (``skiprows``); when
    the first line after them is numbers, the last ``#`` line is the header (``numpy.savetxt``'s
    ``# time,gyro``) and ``_hashed`` says so.  A first row under the header with text and no
    number or date (``s,rad/s,rad``) over a row with numbers is a row of units: ``_units`` holds
    it (:func:`read_log` skips it).  A file whose first 64 kB hold a NUL byte is not
    text (UTF-16, a spreadsheet, a binary log): a DataError says so."""
    try:
        with _open_csv(path, kind) as fh:
            skipped, comment = 0, None
            line = fh.readline(1 << 16)
            forced = re.fullmatch(rb"(?:\xef\xbb\xbf)?sep=(.)\r?\n", line)  # a spreadsheet's 'sep=;' line
            if forced:
                skipped, forced, line = 1, forced.group(1).decode("latin-1"), fh.readline(1 << 16)
            while skipped < COMMENT_LINES and (line.strip() in (b"", b"\xef\xbb\xbf")
                                               or line.lstrip(b"\xef\xbb\xbf \t").startswith(b"#")) and b"\n" in line:
                comment = line if line.strip(b"\xef\xbb\xbf \t\r\n") else comment
                skipped += 1
                line = fh.readline(1 << 16)
            rows = fh.read(1 << 16)
    except DataError:
        raise
    except (OSError, EOFError, ValueError) as exc:  # a truncated or corrupt archive
        raise DataError(f"cannot read {path}: {_first_line(exc)}") from None
    if b"\x00" in (line + rows).rstrip(b"\x00"):  # NUL bytes after the text: a log cut off (_tail)
        what = "UTF-16 text" if line.startswith((b"\xff\xfe", b"\xfe\xff")) else "not a text file"
        raise DataError(f"cannot read {path}: {what}; cfdesign reads {_READS}"
                        + (": save the log as UTF-8" if what == "UTF-16 text" else ""))
    out = {"skiprows": skipped} if skipped else {}
    if comment is not None and _numbers(line, comment):  # '# time,gyro' over rows of numbers: the header
        out = {"skiprows": skipped - 1, "_hashed": True} if skipped > 1 else {"_hashed": True}
        rows, line = line + rows, comment
    sep = forced or _separator(line, rows)
    if sep == WHITESPACE and out.get("_hashed"):  # '# time gyro': the '#' is no column of its own
        out = {**out, "header": 0, "names": _cells(line.lstrip(b"\xef\xbb\xbf \t").lstrip(b"#"), sep)}
    if sep in (";", "\t", WHITESPACE):
        cut = rb"\s+" if sep == WHITESPACE else re.escape(sep.encode())
        cell = rb'(?:^|%s)[ "]*[-+]?[0-9]+,[0-9]+(?:[eE][-+]?[0-9]+)?[ "]*(?=%s|\r?$)' % (cut, cut)
        out = {**out, "sep": sep, "decimal": ","} if re.search(cell, rows, re.MULTILINE) else {**out, "sep": sep}
    if not out.get("_hashed"):
        units = _units_row(rows, line, sep or ",")
        if units is not None:
            out["_units"] = units
    if sep == WHITESPACE:
        _short_rows(path, out, line, rows)
    return _wider_rows(path, out, line, rows, sep or ",")


#: the separator of a log whose columns are separated by spaces (``numpy.savetxt``'s default)
WHITESPACE = r"\s+"


def _separator(header, rows):
    """The separator of a CSV from its header line: a comma, else a semicolon or a tab; else
    spaces (:data:`WHITESPACE`) when the header and the first row of ``rows`` split into as many
    cells, at least two; else None (one column)."""
    for sep in (",", ";", "\t"):
        if sep.encode() in header:
            return sep
    first = next((r for r in rows.split(b"\n")[:-1] if r.strip()), b"")
    names = _cells(header.lstrip(b"\xef\xbb\xbf \t").lstrip(b"#"), WHITESPACE)
    return WHITESPACE if len(names) > 1 and len(_cells(first, WHITESPACE)) == len(names) else None


def _cells(line, sep) -> list:
    """The cells of a CSV line (bytes or text) split at ``sep`` (quotes as the csv module reads
    them; :data:`WHITESPACE`: runs of spaces and tabs)."""
    text = line.decode("utf-8-sig", "replace") if isinstance(line, bytes) else line
    text = text.strip("\r\n")
    if sep == WHITESPACE:
        return text.split()
    try:
        return next(csv.reader([text], delimiter=sep), [])
    except csv.Error:
        return []


def _short_rows(path, fmt, header, rows):
    """A DataError naming the first row of the first 64 kB (``rows``, whole lines) of a log
    separated by spaces that has fewer cells than its header: an empty cell of a column-aligned
    table (a slow sensor between its readings) is no cell at all there, so pandas read the cells
    after it into the columns before them and left the last column empty (the reference read as
    the GPS, exit 0).  Blank lines, ``#`` lines and the row of units are not rows of cells."""
    names = fmt.get("names") or _cells(header, WHITESPACE)
    units = "_units" in fmt
    for i, row in enumerate(rows.split(b"\n")[:-1]):
        cells = _cells(row, WHITESPACE)
        if not cells or cells[0].startswith("#"):
            continue
        if units:  # the first row of cells is the units row
            units = False
            continue
        if len(cells) < len(names):
            raise DataError(f"{path} line {2 + fmt.get('skiprows', 0) + i}: {len(cells)} cells under a header of "
                            f"{len(names)} columns separated by spaces: an empty cell cannot be told from the "
                            "spaces around it (write nan in it, or separate the cells by commas or tabs)")


def _wider_rows(path, fmt, header, rows, sep) -> dict:
    """``fmt`` for a CSV whose first row has more cells than its header: pandas took the first
    cells as an index and every column from the wrong cell (the gyro's cells read as times).
    Empty cells at the end (a separator after each row's last cell) are columns without a name
    (``names``); cells with values are a DataError naming the line (a decimal comma in a
    comma-separated file: ``0,01`` is two cells)."""
    lines = rows.split(b"\n")[:-1]
    at = next((i for i, r in enumerate(lines) if r.strip()), None)
    if at is None:
        return fmt
    if "_units" in fmt:
        at = next((i for i in range(at + 1, len(lines)) if lines[i].strip()), None)
        if at is None:
            return fmt
    names = fmt.get("names") or _cells(header, sep)
    cells = _cells(lines[at], sep)
    if len(cells) <= len(names):
        return fmt
    if any(c.strip() for c in cells[len(names):]):
        line = 2 + fmt.get("skiprows", 0) + at
        raise DataError(f"{path} line {line}: {len(cells)} cells under a header of {len(names)} columns"
                        + (" (decimal commas in a log separated by commas? 0,01 is two cells: separate the cells "
                           "by semicolons or write decimal points)" if sep == "," else ""))
    return {**fmt, "header": 0, "names": [*names, *(f"Unnamed: {i}" for i in range(len(names), len(cells)))]}


def _units_row(rows, header, sep):
    """The cells of a row of units under a CSV's header (``s,rad/s,rad``: text in as many cells
    as the header, no number, no date, and a row with a number after it), or None."""
    from .timing import date_seconds

    lines = rows.split(b"\n", 2)
    if len(lines) < 3:
        return None

    first, second, names = _cells(lines[0], sep), _cells(lines[1], sep), _cells(header, sep)
    text = [c.strip() for c in first if c.strip().lower() not in MISSING]
    if len(first) != len(names) or not text:
        return None
    for c in text:
        for read in (lambda c: float(c.replace(",", ".")), date_seconds):
            try:
                read(c)
                return None  # a number or a date: a row of data
            except ValueError:
                pass
    for c in second:
        try:
            float(c.strip().replace(",", "."))
            return [c.strip() for c in first]
        except ValueError:
            pass
    return None


def _numbers(line, header) -> bool:
    """Whether a CSV line is a row of numbers (or empty cells), split as its ``header`` line is."""
    try:
        for cell in _cells(line.strip(), _separator(header, line + b"\n") or ","):
            cell = cell.strip(' "')
            if cell:
                float(cell.replace(",", "."))
    except ValueError:
        return False
    return bool(line.strip())


def _column_name(i: int, name, hashed=False) -> str:
    """A CSV column's name as cfdesign uses it: stripped of white space, and ``Unnamed: i`` (pandas'
    name) when nothing is left.  The one rule for the header read as written and for pandas'
    frames: a trailing comma or a tab as a name was '' in one and 'Unnamed: 0' or a tab in the
    other, and its lookup raised KeyError (an internal error).  A ``hashed`` header (``# time,gyro``)
    loses the ``#`` of its first name."""
    name = str(name).strip()
    return (name.lstrip("#").strip() if hashed and i == 0 else name) or f"Unnamed: {i}"


def _stripped(frame, columns=None, hashed=False):
    """A block read from a CSV with its column names stripped (and only ``columns``, if given)."""
    frame.columns = [_column_name(i, c, hashed) for i, c in enumerate(frame.columns)]
    return frame if columns is None else frame[list(columns)]


def _csv_blocks(path, reader, columns, hashed=False, closing=None):
    """The blocks of a CSV reader; a row pandas cannot parse is a DataError here too.  ``closing``:
    the file the reader reads, closed with it."""
    pd = _pandas()
    with reader, contextlib.closing(closing) if closing is not None else contextlib.nullcontext():
        while True:
            try:
                block = next(reader)
            except StopIteration:
                return
            except (pd.errors.ParserError, UnicodeDecodeError, ValueError, OSError, *_unpack_errors()) as exc:
                raise _read_error(path, exc) from None
            yield _stripped(block, columns, hashed)


def _first_line(exc) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _parquet_names(schema) -> dict:
    """``{field: column}``: the columns of a Parquet file as cfdesign reads them.

    A frame saved by pandas keeps its index as a field: one with a name (``time``) is a column
    like the others; an unnamed one (``__index_level_0__``) is the time column ``time`` when it
    holds dates or durations and no column is named ``time`` or ``t`` (a frame indexed by a
    DatetimeIndex, as :func:`run_log` takes the index of a DataFrame), and is left out otherwise
    (row labels).  It was asked for by its field name and not found: an internal error."""
    import pyarrow as pa

    index = {c for c in (schema.pandas_metadata or {}).get("index_columns", []) if isinstance(c, str)}
    unnamed = {f.name for f in schema if f.name in index and re.fullmatch(r"__index_level_\d+__", f.name)}
    timed = any(f.name.strip().lower() in TIME_COLUMNS for f in schema if f.name not in unnamed)
    names = {}
    for f in schema:
        if f.name not in unnamed:
            names[f.name] = f.name
        elif not timed and (pa.types.is_timestamp(f.type) or pa.types.is_duration(f.type)):
            names[f.name], timed = "time", True
    return names


def _parquet_blocks(path, columns, rows=None):
    """A Parquet log's blocks of ``rows`` rows (all of it in one when None), columns named as
    :func:`_parquet_names` names them."""
    import pyarrow.parquet as pq

    with pq.ParquetFile(path) as f:
        names = _parquet_names(f.schema_arrow)
        fields = {c: k for k, c in names.items()}
        wanted = [fields.get(c, c) for c in columns] if columns is not None else list(names)
        if rows is None:
            yield f.read(columns=wanted).to_pandas(ignore_metadata=True).rename(columns=names)
            return
        for batch in f.iter_batches(batch_size=rows, columns=wanted):
            yield batch.to_pandas(ignore_metadata=True).rename(columns=names)


def _pipe(path) -> bool:
    """Whether ``path`` is a pipe or a socket (``/dev/stdin`` of ``cat log.csv |``, ``<(zcat log.gz)``)."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError, TypeError):
        return False
    return stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode)


def _spooled(path, source):
    """A context giving a temporary copy of a pipe's log (its header is read before its rows, and
    a pipe gives its bytes once: the first data row became the header, 'duplicate column(s) 0.5')."""
    import contextlib
    import shutil
    import tempfile

    @contextlib.contextmanager
    def copy():
        with tempfile.TemporaryDirectory(prefix="cfdesign-log-") as folder:
            target = Path(folder) / "log"
            try:
                with open(path, "rb") as src, open(target, "wb") as dst:
                    shutil.copyfileobj(src, dst, 1 << 20)
            except OSError as exc:
                raise DataError(f"cannot read {source}: {exc.strerror or exc}") from None
            try:
                yield target
            except DataError as exc:  # messages name the pipe, not the copy
                raise DataError(str(exc).replace(str(target), str(source))) from None

    return copy()


class _Lines:
    """The file line of each row of a log (rows numbered from 0 as read): ``first`` for the
    first, one more for each row after it, and, in a CSV file, one more for each blank line
    between them, which pandas skips (a bad row after a blank line was named a line early).
    The blank lines are looked for when a message first names a line (:meth:`__call__`)."""

    def __init__(self, first=2, path=None, kind="csv", sep=","):
        self.first, self.path, self.kind, self.sep = first, path, kind, sep
        self._after = None  # the rows before each blank line

    def __call__(self, row) -> int:
        """The file line of row ``row``."""
        if self.path is None:
            return self.first + int(row)
        if self._after is None:
            self._after = self._blank_lines()
        return self.first + int(row) + int(np.searchsorted(self._after, row, side="right"))

    def _blank_lines(self):
        """The rows before each blank line after the header: lines of nothing but spaces other
        than the separator (a tab-separated line of tabs is a row of empty cells)."""
        space = b"".join(re.escape(bytes([c])) for c in b" \t\r\f\v" if bytes([c]) != self.sep.encode())
        blank = re.compile(rb"\n[" + space + rb"]*(?=\n)")
        after, lines, carry = [], 0, b"\n"  # a newline before the first row's line: each match starts a line
        with _open_csv(self.path, self.kind) as fh:
            for _ in range(self.first - 1):
                fh.readline()
            while True:
                chunk = fh.read(1 << 22)
                text = carry + chunk
                end = text.rfind(b"\n") if chunk else len(text)
                pos = 0
                for m in blank.finditer(text, 0, end + 1 if chunk else end):
                    lines += text.count(b"\n", pos, m.start())
                    pos = m.start()
                    after.append(lines - len(after))
                if not chunk:
                    return np.array(after, dtype=np.int64)
                lines += text.count(b"\n", pos, end)
                carry = text[end:]


def _lines(path) -> _Lines:
    """The :class:`_Lines` of a log file: its first row on line 2, after the comment lines of a CSV."""
    kind = _kind(path)
    if kind == "parquet":
        return _Lines()
    fmt = _csv_format(path, kind)
    return _Lines(2 + fmt.get("skiprows", 0) + ("_units" in fmt), path, kind, fmt.get("sep", ","))


def _header(path) -> list:
    import io

    path = Path(path)
    kind = _kind(path)
    pd = _pandas(kind == "parquet")
    if kind == "parquet":
        import pyarrow.parquet as pq

        try:
            return list(_parquet_names(pq.read_schema(path)).values())
        except (OSError, ValueError) as exc:
            raise DataError(f"cannot read {path}: {_first_line(exc)}") from None
    fmt = _csv_format(path, kind)
    try:  # the header line as written (pandas renames a second 'gyro' to 'gyro.1')
        with io.TextIOWrapper(_open_csv(path, kind), encoding="utf-8-sig", newline="") as fh:
            for _ in range(fmt.get("skiprows", 0)):
                fh.readline()
            sep = fmt.get("sep", ",")
            header = fmt.get("names") or (fh.readline().split() if sep == WHITESPACE else
                                           next(csv.reader(fh, delimiter=sep), None))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise _read_error(path, exc) from None
    if not header:
        raise _read_error(path, pd.errors.EmptyDataError())
    return [_column_name(i, h, fmt.get("_hashed", False)) for i, h in enumerate(header)]


def read_columns(path, columns, time=None, time_unit=None) -> dict:
    """Whole numeric columns of a log, read as :func:`run_log` reads them (``cfdesign noise``).

    Parameters
    ----------
    path : str or Path
        A CSV or Parquet log (:func:`read_log`).
    columns : sequence of str
        Columns to read.
    time : str, optional
        A column of times: numbers in ``time_unit``, or dates (ISO 8601 text, a datetime
        column) as seconds since 1970-01-01 UTC.
    time_unit : {'s', 'ms', 'us', 'ns'}, optional
        The unit of a numeric ``time`` column (:data:`TIME_UNITS`), returned in seconds; by
        default the one its name gives (``time [ms]``), else seconds.

    Returns
    -------
    dict
        ``{column: float ndarray}``; an empty cell is NaN.

    Raises
    ------
    DataError
        The file cannot be read, a column is missing or named twice, a cell is not a number
        (naming its line).
    """
    wanted = list(dict.fromkeys([*columns, *([time] if time else [])]))
    if _pipe(path):
        with _spooled(path, str(path)) as spooled:
            return read_columns(spooled, columns, time, time_unit)
    header = _header(path)
    missing = [c for c in wanted if c not in header]
    if missing:
        raise DataError(f"{path}: no column {missing[0]!r} (columns: {_listed(header)})")
    dup = sorted({c for c in wanted if header.count(c) > 1})
    if dup:
        raise DataError(f"{path}: column {dup[0]!r} appears twice in the header")
    scale = TIME_UNITS[_time_unit(path, time, time_unit, _row_units(path))]
    return _numeric(read_log(path, wanted), wanted, path, _lines(path), time=time, time_scale=scale)


# ---------------------------------------------------------------------------- the run
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

    def ticks(self, values):
        """Ticks of a block's rows (``row index`` when the log has no time column)."""
        n = len(next(iter(values.values()))) if values else 0
        if self.cols.time is None:
            ticks = self.rows + np.arange(n, dtype=np.int64)
        else:
            from .timing import place

            t = values[self.cols.time]
            read = {s: ~np.isnan(values[c]) for s, c in self.cols.sensors.items()}
            base = np.ones(n, dtype=bool)
            for s in self.table.inputs:
                base &= read[s.name]
            tail_t, tail_read = self.tail or (t[:0], {s: r[:0] for s, r in read.items()})
            start = self.rows - len(tail_t)
            place(np.concatenate([tail_t, t]), self.table.sample_time_s, source=self.source, rate=False,
                  line=lambda i: self.cols.lines(start + i),
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
        from .timing import FIT_ROWS, grid_fit

        if not first.size:
            first = self._ahead(0, count=FIT_ROWS)
        return grid_fit(first, self.table.sample_time_s) if first.size else (t_first, self.spacing)

    def _ahead(self, row, before=None, count=None):
        """The times of the rows where the inputs read from the log's row ``row`` on (its blocks
        read again), up to ``count`` of them (:data:`~cfdesign.timing.ARC_ROWS`) and the first
        pause (also one right after ``before``, the time of such a row before them); none without
        the blocks."""
        from .timing import ARC_ROWS, PAUSE_TICKS

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
                              lambda i, at=at: self.cols.lines(at + i), self.cols.time, self.cols.time_scale)
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
        from .timing import PAUSE_TICKS

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
        from .timing import ARC_ROWS, nearest_tick, rephase

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
            from .timing import check_rate

            check_rate(np.concatenate(self.base_times), self.table.sample_time_s, self.source)


def run_log(table, data, *, output=None, time=None, mapping=None, reference=None, std=False,
            prediction=False, plot=None, start="reading", block_rows=None, progress=False,
            source=None, time_unit=None) -> LogResult:
    """Run a discrete gain table on a timestamped log (module docstring).

    Parameters
    ----------
    table : GainTable
        The gain table the log is run through.
    data : str, Path or pandas.DataFrame
        A CSV or Parquet file, or a DataFrame.
    output : str or Path, optional
        Write the estimates here (``.csv``, or ``.parquet``), atomically; the result then holds
        no DataFrame (bounded memory for big logs).
    time : str, optional
        The time column (seconds, or dates: ISO 8601 text, a datetime column); default ``time``,
        ``t`` or ``timestamp`` (in any case, or named with a unit: ``time [ms]``, ``time_ms``) when
        present, or a DataFrame's index when it is a DatetimeIndex or is named so; else every row
        is one base tick (said in a note).
    mapping : dict, optional
        ``{sensor: column}`` where the log names a sensor differently.
    reference : str or list of str, optional
        ``COLUMN`` (a reference for the first state, e.g. the true heading) or
        ``STATE=COLUMN`` items: the RMS error of each is in the result, over every row and after
        the start-up, beside the predicted standard deviation.
    std : bool
        Add ``<state>_std`` columns: the predicted standard deviation at each row's phase.
    prediction : bool
        Output the one-step prediction instead of the table's output.
    plot : str or Path, optional
        Also draw :func:`plot_log` to this image file.
    start : {'reading', 'zero'}
        The initial state: the quantity from the first reading of a sensor that measures it
        directly (the others zero), or all zero (as :class:`~cfdesign.runtime.Runtime`).
    block_rows : int, optional
        Rows per block (default :data:`BLOCK_ROWS`).
    progress : bool
        A progress bar on stderr for long logs.
    source : str, optional
        The log's name in messages.
    time_unit : {'s', 'ms', 'us', 'ns'}, optional
        The unit of a numeric time column (:data:`TIME_UNITS`): ``'ns'`` for the integer
        nanoseconds of a ROS ``rostopic echo -p`` export (``%time``).  Default: the unit the
        column's name gives (``time [ms]``, ``t (us)``), else seconds.  Dates and durations are
        read as they are.

    Returns
    -------
    LogResult
        The estimates (None when written to ``output``), the RMS error of each reference (over every
        row, and after the start-up beside the predicted standard deviation), the unused readings
        and notes.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        A continuous-time table (logs run discrete tables), a ``block_rows`` that is not a
        positive whole number, a ``mapping`` that is not a dict or a ``reference`` that is not
        text or a list of it.
    DataError
        A missing or non-numeric column (naming the line), bad times (naming the line), a base
        rate more than 1 % off the table's, an empty log.
    OutputError
        The output cannot be written; nothing is left half-written.
    """
    require_table(table, "run_log")
    if table.domain != "z":
        from .runtime.filter import DISCRETE_HINT

        raise CfdesignError(f"{table.name} is a continuous-time table; logs run discrete tables ({DISCRETE_HINT})")
    if block_rows is not None and (isinstance(block_rows, bool) or not isinstance(block_rows, numbers.Integral)
                                   or block_rows < 1):  # -5 read no row ('a header but no rows'), True one a block
        raise CfdesignError(f"block_rows must be a positive whole number of rows, got {block_rows!r}")
    block_rows = int(block_rows or BLOCK_ROWS)
    frame, source = _source(data, source, time)
    if frame is None and not_a_device(data):  # /dev/zero: an endless line
        raise DataError(f"cannot read {source}: {not_a_device(data)}")
    if frame is None and _pipe(data):  # read once into a file: a log is read more than once
        with _spooled(data, source) as path:
            return run_log(table, path, output=output, time=time, mapping=mapping, reference=reference, std=std,
                           prediction=prediction, plot=plot, start=start, block_rows=block_rows, progress=progress,
                           source=source, time_unit=time_unit)
    if frame is None and output is not None and _same_file(data, output):
        raise DataError(f"{source}: the output {output} is the log itself; it would be replaced by the estimates")
    check_distinct({"the log": data if frame is None else None, "the output": output, "the plot": plot})
    _pandas(output is not None and Path(output).suffix.lower() in (".parquet", ".pq"))  # before the log is read
    if output is not None and Path(output).suffix.lower() == ".zip":
        raise OutputError(f"cannot write {output}: estimates are written as CSV (.csv, or compressed: .csv.gz, "
                          ".csv.bz2, .csv.xz) or Parquet, not a zip archive")
    header = list(frame.columns) if frame is not None else _header(data)
    cols = _columns(table, header, source, time, mapping, reference, time_unit,
                    _Lines() if frame is not None else _lines(data), None if frame is not None else _row_units(data))
    _check_output_names(table, cols, std, source)
    blocks, whole = _blocks(data, frame, cols, block_rows)
    parquet = output is not None and Path(output).suffix.lower() in (".parquet", ".pq")
    lock, n_rows, types, (grid, rephased, first) = _lock(table, blocks, cols, source, types=parquet and whole is None)
    if n_rows == 0:
        raise DataError(f"{source}: the log has a header but no rows")
    if start not in ("reading", "zero"):
        raise CfdesignError(f"start must be 'reading' or 'zero', got {start!r}")
    if plot is not None:  # before any work: a plot that cannot be written stops nothing half-way
        _check_plot_target(plot)
    runner = _Runner(table, lock, "prior" if prediction else None, start == "reading",
                     covariances=bool(std or cols.references), first_reading=first)
    if parquet and whole is not None:
        types = _arrow_types(whole[cols.extra])
    writer = _Writer(output, keep=output is None or plot is not None, types=types)
    place = _Pass(table, cols, source, grid=grid, rephased=rephased)  # ticks where the first pass put them
    startup = _startup_ticks(table)

    def run_rows(block, values, ticks):
        if len(ticks):
            states, _, stds = runner.run(ticks, {s: values[c] for s, c in cols.sensors.items()})
            _check_bounded(table, states, ticks, source)
            writer.write(_estimates(table, block, cols, values, states, stds, std), runner.settled(ticks, startup))
            bar.update(len(ticks))

    with _progress(n_rows, progress) as bar, writer:
        pending = None  # the rows of a block's last tick: the next block may hold more rows of that tick
        for block in blocks():
            values = _numeric(block, cols.numeric, source, lambda i, start=place.rows: cols.lines(start + i),
                              cols.time, cols.time_scale)
            ticks = place.ticks(values)
            if pending is not None:
                pd = _pandas()
                block = pd.concat([pending[0], block])
                values = {k: np.concatenate([pending[1][k], v]) for k, v in values.items()}
                ticks = np.concatenate([pending[2], ticks])
            cut = int(np.searchsorted(ticks, ticks[-1])) if len(ticks) else 0
            held = runner.held_from(ticks[:cut], {s: values[c][:cut] for s, c in cols.sensors.items()})
            if len(ticks) - held <= block_rows:  # rows after a pause wait for the reading that moves them
                cut = held
            pending = (block.iloc[cut:], {k: v[cut:] for k, v in values.items()}, ticks[cut:])
            run_rows(block.iloc[:cut], {k: v[:cut] for k, v in values.items()}, ticks[:cut])
        if pending is not None:
            run_rows(*pending)
        est = writer.frame()
        if plot is not None:  # inside the writer: a plot that cannot be written leaves the previous estimates
            from .plot import figure_bytes

            write_bytes(plot, figure_bytes(plot_log(table, est, cols.references, cols.time, cols.time_unit,
                                                          restarts=runner.restarts), plot))
    if place.early:
        _merge(runner.counts, {"before_start": place.early})
    notes = (_units_note(data, source) + _tail_note(data, source) if frame is None else []) + _time_note(cols)
    notes += lock.notes + [n for n in [runner.pause_note(table.sample_time_s)] if n]
    settled, predicted = writer.settled()
    return LogResult(est if output is None else None, n_rows, _rms(writer.errors), runner.counts, notes,
                     Path(output) if output else None, source, settled, predicted,
                     startup * table.sample_time_s if cols.references else math.nan, writer.settled_rows,
                     len(runner.pauses))


def _startup_ticks(table) -> float:
    """The start-up of ``table`` in whole base ticks (:func:`~cfdesign.linear.startup_steps`
    rounded up; ``inf`` when its error does not die away): rows on a tick before it are the
    start-up's."""
    from .linear import startup_steps

    steps = startup_steps(table.F, table.H, table.K, table.gain_form)
    return float(math.ceil(steps)) if math.isfinite(steps) else math.inf


def _check_bounded(table, states, ticks, source):
    """An estimate that leaves :data:`~cfdesign.runtime.filter.STATE_LIMIT` (or overflows to
    inf or NaN) is a filter that diverges, not an estimate: an unstable table (an edited gain
    or model) wrote empty estimate columns with exit status 0."""
    from .runtime.filter import STATE_LIMIT

    bad = ~np.all(np.abs(states) <= STATE_LIMIT, axis=1)
    if bad.any():
        tick = int(ticks[np.argmax(bad)])
        raise DataError(f"{source}: the estimates of {table.name!r} diverge (beyond {STATE_LIMIT:g} at tick {tick}): "
                        "the table's filter is not stable (cfdesign verify names the check)")


def _same_file(a, b) -> bool:
    """``a`` and ``b`` name one existing file (through links or relative paths as well)."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one does not exist (yet): not the same file
        return False


def _check_plot_target(plot):
    from .plot import FIGURE_FORMATS

    path = Path(plot)
    fmt = path.suffix.lstrip(".").lower() or "png"
    if fmt not in FIGURE_FORMATS:
        raise OutputError(f"cannot write {plot}: unknown image format {fmt!r} "
                          f"(use {', '.join('.' + f for f in FIGURE_FORMATS)})")
    if is_dir(path) or not is_dir(path.parent if str(path.parent) else Path(".")):
        raise OutputError(f"cannot write {plot}: " + ("it is a directory" if is_dir(path) else
                                                      f"no folder {path.parent}"))


def _source(data, source, time=None):
    """``(frame or None, name)``; a DataFrame whose time is its index (a DatetimeIndex, or an
    index named as a time column is, :func:`_time_name`: ``time``, ``t``, ``timestamp``, ``time_ms``)
    and not a column has it made its first column."""
    pd = _pandas()
    if isinstance(data, pd.DataFrame):
        index = data.index
        named = index.name is not None and _time_name(index.name)
        if time is None and not any(_time_name(c) for c in data.columns) and (
                named or isinstance(index, pd.DatetimeIndex)):
            data = data.reset_index(names=str(index.name) if index.name is not None else "time")
        return data, source or "log"
    return None, source or str(data)


def _time_note(cols) -> list:
    """A note when the log has no time column: its rows are taken one a tick."""
    if cols.time is not None:
        return []
    like = [c for c in cols.extra if any(w in c.lower() for w in ("time", "stamp", "sec"))]
    return ["the log has no time column ('time', 't' or 'timestamp'): every row is taken as one base tick"
            + (f" (column {like[0]!r} looks like a time: --time {like[0]})" if like else " (--time COLUMN)")]


def _blocks(data, frame, cols, rows):
    """``(blocks, whole)``: a function giving the log's blocks each time it is called (two passes
    need two), and the whole log when it is in memory (a DataFrame, or a file read once), else None."""
    if frame is not None:
        whole = frame
    else:
        path = Path(data)
        packed = 10 if _kind(path) in COMPRESSIONS.values() else 1  # a compressed CSV unpacks to several times its size
        if packed * os.path.getsize(path) >= ONE_PASS_BYTES:
            return (lambda: read_log(path, cols.read, chunksize=rows)), None
        whole = read_log(path, cols.read)
    return (lambda: (whole.iloc[i:i + rows] for i in range(0, max(len(whole), 1), rows))), whole


def _check_output_names(table, cols, std, source):
    """A column of the log passed through must not take the name of a column the estimates add."""
    made = [*table.states, *(f"{s}_std" for s in table.states if std or cols.references),
            *(f"{s}_reference" for s in cols.references)]
    clash = [c for c in [*([cols.time] if cols.time else []), *cols.extra] if c in made]
    if clash:
        raise DataError(f"{source}: column {clash[0]!r} has the name of a column of the estimates "
                        f"({', '.join(made)}); rename it in the log")


def _arrow_types(frame):
    """The Parquet types of the log's passed-through columns over all its blocks (a column of
    integers with a gap in a later block is a column of floats; one empty in the first block
    takes the type of its first value)."""
    import pyarrow as pa

    schema = pa.Schema.from_pandas(frame, preserve_index=False).remove_metadata()
    empty = frame.isna().all(axis=0) if len(frame) else None  # no value: any type (CSV chunks read floats)
    return pa.schema([f.with_type(pa.null()) if empty is not None and empty[f.name] else f for f in schema])


def _lock(table, blocks, cols, source, types=False):
    """First pass: check times and collect the ticks at which each measurement arrives (and,
    with ``types``, the Parquet types of the passed-through columns over every block)."""
    from .timing import lock_schedule

    place = _Pass(table, cols, source, blocks=blocks)
    arrivals = {s.name: [] for s in table.measurements}
    inputs = {s.name: _Held() for s in table.inputs}  # the ticks without a reading of each input sensor
    last, first = -1, None  # the last tick; the first direct reading (_first_direct)
    schemas = []
    for block in blocks():
        if types:
            schemas.append(_arrow_types(block[cols.extra]))
        values = _numeric(block, [c for c in cols.read if c == cols.time or c in cols.sensors.values()], source,
                          lambda i, start=place.rows: cols.lines(start + i), cols.time, cols.time_scale)
        if cols.time is not None and block[cols.time].dtype == np.float32:
            _check_float32_time(values[cols.time], cols.time, table.sample_time_s, source, cols.time_scale)
        first_row = place.rows
        ticks = place.ticks(values)
        for s in table.measurements:
            arrivals[s.name].append(ticks[np.isfinite(values[cols.sensors[s.name]])])
        for name, held in inputs.items():
            held.add(ticks, np.isfinite(values[cols.sensors[name]]), first_row)
        here = _first_direct(table, ticks, {s.name: values[cols.sensors[s.name]] for s in table.measurements})
        if here is not None and (first is None or here[:2] < first[:2]):
            first = here
        last = int(ticks[-1]) if len(ticks) else last
    place.check_rate()
    arrivals = {k: _unique(np.concatenate(v)) if v else np.zeros(0, np.int64) for k, v in arrivals.items()}
    if schemas:
        import pyarrow as pa

        schemas = pa.unify_schemas(schemas, promote_options="permissive")
    from .designer import has_kalman_gains  # fixed gains have no model to recompute them from

    lock = lock_schedule(table, arrivals, last + 1, recompute=has_kalman_gains(table))
    lock.notes[:0] = [f"{name} (an input) has no reading in the log: the estimates run on an input of zero"
                      if held.last is None else held.note(name, last, table.sample_time_s, cols.lines)
                      for name, held in inputs.items() if held.last is None or held.missing(last)]
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
    """``(tick, sensor, value)`` of the first usable reading (:func:`~cfdesign.runtime.filter.usable`;
    the first of its tick, as ``_Runner._dense`` keeps it) of a sensor whose row of H picks the
    quantity (state 0), the sensor first by name on a shared tick; None when there is none.
    ``readings``: ``{sensor: values}`` of the rows at ``ticks`` (ascending; NaN where none)."""
    from .runtime.filter import usable  # a rejected reading (inf, beyond the limit) is no start

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
            firsts.append((int(at[good[0]]), s.name, float(col[ok[row[good[0]]]])))
    return min(firsts, key=lambda f: f[:2]) if firsts else None


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
        """The note on the held ticks; ``lines(row)`` gives a row's file line."""
        ticks, row = self.longest
        line = lines(row)
        longest = f", the longest {ticks} ticks ({ticks * dt:.3g} s) after line {line}" if ticks > 1 else ""
        return (f"{name} (an input) has no reading at {self.missing(last_tick)} of {last_tick + 1} ticks{longest}: "
                "its last reading is held there")


#: a pause of the logger restarts state 0 when the first direct reading after it is more than
#: this many standard deviations of the innovation from the state carried over the pause
RESTART_GATE = 3.0


class _Runner:
    """Runs the blocks of ticks through the table (or its re-locked variants), state carried."""

    def __init__(self, table, lock, output, from_reading=True, covariances=False, first_reading=None):
        from .runtime import Runtime

        self.table, self.lock, self.output, self.from_reading = table, lock, output, from_reading
        # (tick, sensor, value) of the log's first direct reading (:func:`_first_direct`): the start
        # when it lies in a later block than the first
        self.first_reading = first_reading
        self.covariances = covariances  # standard deviations that follow missed readings
        self.P_missed = None
        from .designer import has_kalman_gains

        # a table with a model: missed readings are bridged by the Kalman filter over the arrivals
        self.kalman = has_kalman_gains(table) and table.Q is not None and table.R is not None
        self.bridge = None  # that filter while it runs (:meth:`_run_bridged`)
        self._Runtime = Runtime
        self.runtimes = {}
        self.counts = {}
        self.x, self.u_last = None, None
        self.next_tick = 0
        self.quiet = 0  # ticks since an input sensor last read (carried from call to call)
        self.pauses = []  # (first tick without an input reading, ticks) of each pause
        self.restarts = []  # ticks where a pause ended (state 0 started again from a direct reading)
        self.pending = False  # a pause ended, no direct reading since: start again at the first one

    def _runtime(self, seg):
        key = (seg.rotation, seg.offsets) if seg.offsets else ("rotation",)
        if key not in self.runtimes:
            table = self.table
            if seg.offsets:
                from .designer import gains_for_schedule

                table = gains_for_schedule(self.table, self.table.schedule.shifted(dict(seg.offsets)))
            self.runtimes[key] = self._Runtime(table, output=self.output)
        return self.runtimes[key]

    def _phase(self, seg, tick):
        return (tick - seg.rotation) % self.table.period if not seg.offsets else tick % self.table.period

    def run(self, ticks, readings):
        """Output states, phases and predicted standard deviations (of the table that ran each
        tick) at ``ticks`` (ascending, may repeat or skip) from the rows' readings; rows on a tick
        already run get that tick's estimate and their readings are counted as ``same_tick``
        (:func:`run_log` keeps the rows of one tick in one call, so this does not happen there)."""
        n = self.table.F.shape[0]
        if not len(ticks):
            return np.zeros((0, n)), np.zeros(0, np.int64), np.zeros((0, n))
        late = ticks < self.next_tick
        if late.any():
            _merge(self.counts, {"same_tick": {k: int(np.sum(~np.isnan(v[late]))) for k, v in readings.items()
                                               if np.any(~np.isnan(v[late]))}})
            states, phases, stds = self.run(ticks[~late], {k: v[~late] for k, v in readings.items()})
            out, ph, sd = np.empty((len(ticks), n)), np.empty(len(ticks), dtype=np.int64), np.empty((len(ticks), n))
            out[late], ph[late], sd[late] = self.last_out, self.last_phase, self.last_std
            out[~late], ph[~late], sd[~late] = states, phases, stds
            return out, ph, sd
        if ticks[-1] - self.next_tick >= BLOCK_ROWS:  # a gap of many ticks without rows: run it in bounded pieces
            ends = np.arange(self.next_tick + BLOCK_ROWS - 1, ticks[-1], BLOCK_ROWS)
            cuts = np.searchsorted(ticks, ends, side="right")
            parts = [self._ticks(ticks[a:b], {k: v[a:b] for k, v in readings.items()}, int(end))
                     for a, b, end in zip([0, *cuts], [*cuts, len(ticks)], [*ends, ticks[-1]], strict=True)]
            return tuple(np.concatenate(arrays) for arrays in zip(*parts, strict=True))
        return self._ticks(ticks, readings, int(ticks[-1]))

    def _ticks(self, ticks, readings, last):
        """Ticks ``next_tick .. last`` (those of the rows at ``ticks`` and the ones between, without
        a row): the estimates at ``ticks``.  After a pause (:meth:`_restart_ticks`) the ticks from
        the first direct reading on run from state 0 started again from it."""
        first = self.next_tick
        dense = self._dense(ticks, readings, first, last)
        if self.x is None and self.from_reading:
            self.x, self.u_last = self._start(dense), np.zeros(len(self.table.inputs))
        parts, shifts = [], []
        restarts = self._restart_ticks(dense, first)
        cuts = [first, *(r for _, r in restarts), last + 1]
        for k, (a, b) in enumerate(itertools.pairwise(cuts)):
            moved = self._restart(dense, a - first) if k else None
            if moved is not None:
                shifts.append((max(restarts[k - 1][0], first), a, *moved))
                self.restarts.append(restarts[k - 1][0])
            if a < b:
                part = {name: v[a - first:b - first] for name, v in dense.items()}
                parts.append(self._run_arrivals(part, a, b - 1) if self.lock.varying
                             else self._run_segments(part, a, b - 1))
        out, phases, stds = (np.concatenate(arrays) for arrays in zip(*parts, strict=True))
        F = self.table.F
        if np.array_equal(F[:, 0], np.eye(len(F))[0]):  # state 0 feeds no other state: a shift of it stays
            for e, r, delta, std in shifts:  # the ticks from the pause's end to the reading, moved onto it
                out[e - first:r - first, 0] += delta
                stds[e - first:r - first, 0] = np.maximum(stds[e - first:r - first, 0], std)
            if self.table.wrap_angle and shifts:
                out[:, 0] = wrap(out[:, 0])
        self.next_tick = last + 1
        self.last_out, self.last_phase, self.last_std = out[-1].copy(), phases[-1], stds[-1].copy()
        return out[ticks - first], phases[ticks - first], stds[ticks - first]

    def settled(self, ticks, startup):
        """Whether each of ``ticks`` is after the start-up (``startup`` ticks) of the log and of the
        restart after every pause so far."""
        out = np.asarray(ticks) >= startup
        for e in self.restarts:
            out &= ~((ticks >= e) & (ticks < e + startup))
        return out

    def pause_note(self, dt):
        """One line on the pauses, or None."""
        from .timing import PAUSE_TICKS

        if not self.pauses:
            return None
        start, longest = max(self.pauses, key=lambda p: p[1])
        return (f"the inputs have no reading for more than {PAUSE_TICKS} ticks {len(self.pauses)} time"
                f"{'s' * (len(self.pauses) > 1)} (a logger paused), the longest {longest * dt:.3g} s from "
                f"{start * dt:.6g} s: {self.table.states[0]} started again from the first direct reading after "
                f"{len(self.restarts)} of them (where it disagreed with the state carried over the pause by more "
                f"than {RESTART_GATE:g} sigma), each start-up shaded and left out of the settled RMS")

    def held_from(self, ticks, readings) -> int:
        """The first of rows at ``ticks`` (ascending, the next to run) whose estimates are not known
        until a later block: those from the end of a pause (:meth:`_restart_ticks`) on when no direct
        reading follows it among them, as that reading may move them (:meth:`_restart`); else
        ``len(ticks)``.  (Rows written before the reading came in the next block stayed where the
        held inputs took them: 0.69 rad off, where one block moved them.)"""
        from .runtime.filter import usable
        from .timing import PAUSE_TICKS

        inputs, direct, n = self.table.inputs, self._direct(), len(ticks)
        if not (inputs and direct and n):
            return n
        have = np.zeros(n, dtype=bool)
        for s in inputs:
            have |= usable(readings[s.name])
        at = np.flatnonzero(have)
        quiet = np.diff(np.concatenate([[self.next_tick - 1 - self.quiet], ticks[at]])) - 1
        ends = at[quiet >= PAUSE_TICKS]
        if not ends.size:
            return n
        read = np.zeros(n, dtype=bool)
        for i in direct:
            read |= usable(readings[self.table.measurements[i].name])
        return n if read[ends[-1]:].any() else int(ends[-1])

    def _direct(self):
        """Indices (in the table's measurements) of the sensors that read state 0 directly."""
        e0 = np.eye(self.table.F.shape[0])[0]
        return [i for i, s in enumerate(self.table.measurements) if np.array_equal(self.table.H[s.index], e0)]

    def _restart_ticks(self, dense, first) -> list:
        """Ticks (ascending) of the direct readings that start state 0 again: the first one at or
        after the end of each pause (more than :data:`~cfdesign.timing.PAUSE_TICKS` ticks without
        a reading of any input sensor: the logger stopped, the vehicle moved on, and what it did
        meanwhile is unknown), pauses counted in :attr:`pauses`."""
        from .runtime.filter import usable
        from .timing import PAUSE_TICKS

        inputs, direct = self.table.inputs, self._direct()
        if not inputs or not direct:
            return []
        n = len(dense[inputs[0].name])
        have = np.zeros(n, dtype=bool)
        for s in inputs:
            have |= usable(dense[s.name])
        at = np.flatnonzero(have)
        before = np.concatenate([[at[0] + self.quiet] if at.size else [], np.diff(at) - 1]).astype(np.int64)
        ends = at[before >= PAUSE_TICKS]
        self.pauses += [(first + int(e - q), int(q)) for e, q in zip(ends, before[before >= PAUSE_TICKS], strict=True)]
        self.quiet = int(n - 1 - at[-1]) if at.size else self.quiet + n
        read = np.zeros(n, dtype=bool)
        for i in direct:
            read |= usable(dense[self.table.measurements[i].name])
        due, out, self.pending = ([0] if self.pending else []) + ends.tolist(), [], False
        for e in due:
            if out and out[-1][1] >= e:  # the reading that ends an earlier pause ends this one too
                continue
            r = np.flatnonzero(read[e:])
            if not r.size:  # no direct reading yet: at the first one of a later call
                self.pending = True
                break
            out.append((e, e + int(r[0])))
        return [(first + e, first + r) for e, r in out]

    def _restart(self, dense, k):
        """State 0 started again from the direct reading at index ``k`` of ``dense`` (the most
        precise one there), as at the log's start; its error is that reading's noise, independent
        of the other states' errors, so the covariance carried (grown over the pause) gets row and
        column 0 of that: variance ``R`` of the sensor, no correlation.  The other states carry on.
        Only where the reading disagrees with the state carried over the pause by more than
        :data:`RESTART_GATE` standard deviations of the innovation (``P00 + R``, the prior grown
        over the pause): a short gap of a fast IMU, bridged well by the held inputs, would
        otherwise swap a precise heading for one noisy compass reading.
        Returns ``(delta, std)``: the move of state 0 and the reading's noise std, or None
        (no restart)."""
        from .runtime.filter import usable

        ms, R = self.table.measurements, self.table.R
        here = [i for i in self._direct() if usable(dense[ms[i].name][k:k + 1])[0]]
        best = min(here, key=lambda i: R[i, i] if R is not None else 0.0)
        kf = getattr(self, "_arrivals", None)  # the Kalman filter over the arrivals carries its own state
        x = np.zeros(self.table.F.shape[0]) if (kf.x if kf is not None else self.x) is None else \
            (kf.x if kf is not None else self.x).copy()
        delta = dense[ms[best].name][k] - x[0]
        if self.table.wrap_angle:
            delta = float(wrap(delta))
        # the prior grown over the pause
        P = kf.P if kf is not None else self.bridge.P if self.bridge is not None else self.P_missed
        var0 = float(P[0, 0]) if P is not None else max(float(c[0, 0]) for c in self.table.P)
        if R is not None and delta ** 2 <= RESTART_GATE ** 2 * (var0 + R[best, best]):
            return None  # the inputs held over the pause still agree with the reading: carry on
        x[0] += delta
        if kf is not None:
            kf.x = x
        else:
            self.x = x
        for P in (self.P_missed, None if kf is None else kf.P, None if self.bridge is None else self.bridge.P):
            if P is not None and R is not None:
                P[0, :] = P[:, 0] = 0.0
                P[0, 0] = R[best, best]
        return delta, math.sqrt(R[best, best]) if R is not None else 0.0

    def _run_arrivals(self, dense, first, last):
        """Ticks ``first..last`` through the Kalman filter over the actual arrivals
        (:class:`~cfdesign.runtime.arrivals.ArrivalKalman`), its state carried between blocks."""
        if not hasattr(self, "_arrivals"):
            from .runtime.arrivals import ArrivalKalman

            self._arrivals = ArrivalKalman(self.table, self.output, self.x)
        kf = self._arrivals
        N = last - first + 1
        u = np.column_stack([dense[s.name] for s in self.table.inputs]) if self.table.inputs else np.zeros((N, 0))
        y = np.column_stack([dense[s.name] for s in self.table.measurements])
        kf.counts = {}
        out, stds = kf.run(u, y)
        _merge(self.counts, kf.counts)
        return out, np.arange(first, last + 1) % self.table.period, stds

    def _run_segments(self, dense, first, last):
        """Ticks ``first..last`` through the table's segments (:class:`~cfdesign.timing.Lock`)."""
        n = self.table.F.shape[0]
        out = np.empty((last - first + 1, n))
        phases = np.empty(last - first + 1, dtype=np.int64)
        stds = np.empty((last - first + 1, n))
        for seg in self.lock.segments:
            a, b = max(seg.start, first), min(seg.stop, last + 1)
            if a >= b:
                continue
            rt = self._runtime(seg)
            if self.x is not None:
                rt.x, rt.u_last = self.x.copy(), self.u_last.copy()
            rt.phase = self._phase(seg, a)
            rt.counts = {}
            part = {k: v[a - first:b - first] for k, v in dense.items()}
            phases[a - first:b - first] = (rt.phase + np.arange(b - a)) % rt.period
            if self.kalman:
                out[a - first:b - first], stds[a - first:b - first] = self._run_bridged(rt, part)
            else:
                _, xs = rt.run(part, states=True)
                out[a - first:b - first] = xs
                stds[a - first:b - first] = self._std(rt)[phases[a - first:b - first]]
                if self.covariances:
                    stds[a - first:b - first] = self._missed(rt, part, phases[a - first:b - first],
                                                             stds[a - first:b - first])
            self.x, self.u_last = rt.x.copy(), rt.u_last.copy()
            _merge(self.counts, rt.counts)
        return out, phases, stds

    def _run_bridged(self, rt, part):
        """A segment of a table with Kalman gains: its own (vectorised) gains wherever every
        scheduled reading is present, and from a missed one (a dropout, an outage, a sensor that
        starts late or stops early) the Kalman filter of the table's model over the readings that
        did arrive (:class:`~cfdesign.runtime.arrivals.ArrivalKalman`), until its covariance is
        back on the table's (to :attr:`~cfdesign.runtime.arrivals.MissedReadings.RTOL`): the
        table's fixed gains are those of every reading present, and after an outage they kept a
        small gain on the readings that came back (or, with a sensor gone, on the one left) -
        3.9 times the RMS error of the Kalman filter over the same readings on a simulated log
        whose odometry stopped early beside a compass.  Returns the output states and their predicted standard
        deviations; the bridging filter is carried from segment to segment and block to block."""
        from .runtime.arrivals import ArrivalKalman, MissedReadings
        from .runtime.filter import usable

        table, N, n = rt.table, len(next(iter(part.values()))), rt.table.F.shape[0]
        phases = (rt.phase + np.arange(N)) % rt.period
        ms = table.measurements
        present = np.column_stack([usable(part[s.name]) for s in ms])
        missed = (table.schedule.mask()[phases] & ~present).any(axis=1)
        std = self._std(rt)
        out, stds = np.empty((N, n)), np.empty((N, n))
        every = rt.period * -(-16 // rt.period)  # the covariance compared with the table's every whole period
        if self.bridge is not None:  # carried on from the last call, with the state as it was left (or restarted)
            self.bridge.x, self.bridge.u_last = rt.x.copy(), rt.u_last.copy()
        i = 0
        while i < N:
            kf = self.bridge
            if kf is None:  # the table's gains up to the next missed reading
                m = i + int(np.argmax(missed[i:])) if missed[i:].any() else N
                if m > i:
                    _, out[i:m] = rt.run({k: v[i:m] for k, v in part.items()}, states=True)
                    stds[i:m] = std[phases[i:m]]
                if m == N:
                    break
                kf = self.bridge = ArrivalKalman(table, rt.output, rt.x)
                kf.P, kf.u_last = np.array(table.P[phases[m]], dtype=float), rt.u_last.copy()
                i = m
            j = min(N, i + every)
            u = np.column_stack([part[s.name][i:j] for s in table.inputs]) if table.inputs else np.zeros((j - i, 0))
            kf.counts = {}
            out[i:j], stds[i:j] = kf.run(u, np.column_stack([part[s.name][i:j] for s in ms]))
            _merge(self.counts, kf.counts)
            rt.x, rt.u_last, rt.phase = kf.x.copy(), kf.u_last.copy(), int((phases[j - 1] + 1) % rt.period)
            ref = np.asarray(table.P[rt.phase], dtype=float)
            if not missed[i:j].any() and np.max(np.abs(kf.P - ref)) <= MissedReadings.RTOL * np.max(np.diag(ref)):
                self.bridge = None  # back on the table's gains
            i = j
        return out, stds

    def _missed(self, rt, part, phases, base):
        """``base`` (the table's standard deviations) where every scheduled reading was present;
        from a missed one until the error is back on the table's, the error of the gains that ran
        over the readings present (:class:`~cfdesign.runtime.arrivals.MissedReadings`; its
        covariance carried from segment to segment and block to block)."""
        if rt.table.Q is None or rt.table.R is None:
            return base
        if not hasattr(rt, "_missed"):
            from .runtime.arrivals import MissedReadings

            rt._missed = MissedReadings(rt.table, rt.output)
        from .runtime.filter import usable

        present = np.column_stack([usable(part[s.name]) for s in rt.table.measurements])
        missed = rt._missed
        missed.P = self.P_missed
        out = missed.stds(phases, present, base)
        self.P_missed = missed.P
        return out

    def _std(self, rt):
        """``(period, n)``: predicted standard deviation of every state at each phase of ``rt``'s
        table, for the estimate it outputs."""
        if not hasattr(rt, "_log_std"):
            covs = rt.table.P_filtered if rt.output == "posterior" else rt.table.P
            rt._log_std = np.sqrt(np.maximum(np.array([np.diag(P) for P in covs]), 0.0))
        return rt._log_std

    def _start(self, dense):
        """The quantity from the first reading of a sensor whose row of H picks it (state 0): the
        log's (``first_reading``, found by the first pass over every block) or, without it, the
        first in ``dense``."""
        x = np.zeros(self.table.F.shape[0])
        first = self.first_reading or _first_direct(self.table, np.arange(len(next(iter(dense.values())))), dense)
        if first is not None:
            x[0] = first[2]
        return x

    def _dense(self, ticks, readings, first, last):
        """One value per tick: rows on the same tick merged (a second reading counted)."""
        n = last - first + 1
        dense = {}
        for name, col in readings.items():
            arr = np.full(n, np.nan)
            ok = np.flatnonzero(~np.isnan(col))
            idx, first_row = _unique(ticks[ok] - first, return_index=True)  # the first reading of a tick
            arr[idx] = col[ok[first_row]]
            twice = len(ok) - len(idx)
            if twice:
                _merge(self.counts, {"same_tick": {name: twice}})
            dense[name] = arr
        return dense



def _merge(into, counts):
    for kind, per in counts.items():
        bucket = into.setdefault(kind, {})
        for name, c in per.items():
            bucket[name] = bucket.get(name, 0) + c


def _estimates(table, block, cols, values, states, stds, std):
    pd = _pandas()
    out = {}
    if cols.time:
        out[cols.time] = block[cols.time].array
    for i, name in enumerate(table.states):
        out[name] = states[:, i]
    if std or cols.references:
        for i, name in enumerate(table.states):
            out[f"{name}_std"] = stds[:, i]
    for state, col in cols.references.items():
        out[f"{state}_reference"] = values[col]
    for c in cols.extra:
        out[c] = block[c].array  # with its dtype (a column of text stays text in every block)
    frame = pd.DataFrame(out)
    # the columns only kept in memory (for the plot and the RMS), by name: not by suffix, so that
    # a column of the log that ends in _std or _reference is passed through like any other
    frame.attrs["hidden"] = [f"{s}_reference" for s in cols.references] + (
        [] if std else [f"{s}_std" for s in table.states if f"{s}_std" in out])
    frame.attrs["references"] = list(cols.references)
    frame.attrs["wrap"] = table.states[0] if table.wrap_angle else None
    return frame


def _gzip(fh):
    import gzip

    return gzip.GzipFile(fileobj=fh, mode="wb")


def _bz2(fh):
    import bz2

    return bz2.BZ2File(fh, "wb")


def _xz(fh):
    import lzma

    return lzma.LZMAFile(fh, "wb")


#: an estimates file named so is a CSV compressed so (the compressors leave the file under them open)
_PACK = {".gz": _gzip, ".bz2": _bz2, ".xz": _xz}


class _Writer:
    """Blocks of estimates to a file (atomically) and/or kept in memory."""

    def __init__(self, path, keep, types=None):
        self.path, self.keep = (Path(path) if path else None), keep
        self.frames, self.errors = [], {}
        self._settled = {}  # state -> (squared errors, their count, variances predicted) after the start-up
        self._predicted = {}  # state -> (variances predicted, their count) over every compared row
        self.settled_rows = 0
        self._ctx = self._fh = self._parquet = self._packed = None
        self._types = types  # Parquet types of the log's passed-through columns over the whole log
        self._blocks = 0  # CSV blocks written

    def __enter__(self):
        if self.path is not None:
            parquet = self.path.suffix.lower() in (".parquet", ".pq")
            packed = _PACK.get(self.path.suffix.lower())  # estimates.csv.gz: a gzip-compressed CSV
            binary = parquet or packed
            self._ctx = open_atomic(self.path, "wb" if binary else "w", **({} if binary else {"newline": ""}))
            self._fh = self._ctx.__enter__()
            if packed:
                import io

                self._fh = self._packed = io.TextIOWrapper(packed(self._fh), encoding="utf-8", newline="")
            self._is_parquet = parquet
        return self

    def __exit__(self, *exc):
        if self._parquet is not None:
            self._parquet.close()
        if self._packed is not None:
            self._packed.close()  # the compressed stream's end; the file under it stays open until moved into place
        if self._ctx is not None:
            self._ctx.__exit__(*exc)
        return False

    def write(self, frame, settled):
        """Write a block of estimates (``settled``: a boolean per row, the rows after the start-up)."""
        self._errors(frame, settled)
        shown = frame.drop(columns=frame.attrs["hidden"])
        if self.keep:
            self.frames.append(frame)
        if self._fh is None:
            return
        if self._is_parquet:
            import pyarrow as pa
            import pyarrow.parquet as pq

            tab = pa.Table.from_pandas(shown, preserve_index=False)
            if self._parquet is None:
                schema, whole = tab.schema, self._types  # the whole log's types, not its first block's
                if whole is not None:
                    schema = pa.schema([whole.field(f.name) if f.name in whole.names
                                        and whole.field(f.name).type != pa.null() else f for f in schema],
                                       metadata=schema.metadata)
                self._parquet = pq.ParquetWriter(self._fh, schema)
            if not tab.schema.equals(self._parquet.schema, check_metadata=False):
                tab = self._cast(tab, self._parquet.schema)
            self._parquet.write_table(tab)
        else:
            # the header before the first block: counted, not asked of the file (a pipe, /dev/stdout, has no tell)
            shown.to_csv(self._fh, index=False, header=not self._blocks, lineterminator="\n")
            self._blocks += 1

    @staticmethod
    def _cast(tab, schema):
        """A block of the estimates in the file's column types (a log read in chunks may change a
        column's type between them: integers in one, with gaps as floats in the next)."""
        try:
            return tab.select(schema.names).cast(schema)
        except (ValueError, TypeError, NotImplementedError) as exc:  # pyarrow's ArrowInvalid is a ValueError
            raise OutputError(f"cannot write Parquet: a column changes type between blocks of the log "
                              f"({_first_line(exc)}); write CSV, or give the column one type") from None

    def _errors(self, frame, settled):
        from .runtime.filter import usable

        self.settled_rows += int(np.count_nonzero(settled))
        for state in frame.attrs.get("references", ()):
            ref = frame[f"{state}_reference"].to_numpy(dtype=float)
            err = frame[state].to_numpy() - ref
            if frame.attrs.get("wrap") == state:
                err = wrap(err)
            ok = np.isfinite(err) & usable(ref)  # a reference of 1e308 squared to an RMS error of inf
            var = frame[f"{state}_std"].to_numpy() ** 2
            s, n = self.errors.get(state, (0.0, 0))
            self.errors[state] = (s + float(np.sum(err[ok] ** 2)), n + int(ok.sum()))
            v, n = self._predicted.get(state, (0.0, 0))
            self._predicted[state] = (v + float(np.sum(var[ok])), n + int(ok.sum()))
            ok &= settled
            s, n, v = self._settled.get(state, (0.0, 0, 0.0))
            self._settled[state] = (s + float(np.sum(err[ok] ** 2)), n + int(ok.sum()), v + float(np.sum(var[ok])))

    def settled(self) -> tuple:
        """``({state: RMS error after the start-up}, {state: RMS of the predicted std over those
        rows, or over every compared row when none is after the start-up})``."""
        rms = _rms({k: (s, n) for k, (s, n, _) in self._settled.items()})
        predicted = {k: math.sqrt(v / n) if n else math.sqrt(self._predicted[k][0] / self._predicted[k][1])
                     if self._predicted[k][1] else math.nan for k, (_, n, v) in self._settled.items()}
        return rms, predicted

    def frame(self):
        if not self.frames:
            return None
        pd = _pandas()
        return pd.concat(self.frames, ignore_index=True)


def _rms(errors):
    return {state: math.sqrt(s / n) if n else math.nan for state, (s, n) in errors.items()}


class _NoBar:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        pass


def _progress(total, show):
    if not show or total < BLOCK_ROWS:
        return _NoBar()
    import sys

    from tqdm import tqdm

    return tqdm(total=total, unit="row", file=sys.stderr)


# ---------------------------------------------------------------------------- plots
def plot_log(table, estimates, references=None, time=None, time_unit="s", restarts=()):
    """Every state over time with its predicted +-2 sigma band; against its reference where given.

    The error panels shade the start-up (:func:`~cfdesign.linear.startup_steps`): the error of
    the initial state, dying away at the closed loop's pace, is not in the band, which is the
    filter's steady state.  Their titles give the RMS error over every row and after the start-up.

    Parameters
    ----------
    table : GainTable
        The gain table the estimates came from (it names the states and sensors).
    estimates : pandas.DataFrame
        ``LogResult.estimates`` (with the ``<state>_std`` and ``<state>_reference``
        columns that :func:`run_log` adds when references are given).
    references : dict, optional
        ``{state: column}``: these states get a panel of the error inside the +-2 sigma band.
    time : str, optional
        The time column (else the row number is the x axis).
    time_unit : {'s', 'ms', 'us', 'ns'}
        The unit of a numeric time column (:data:`TIME_UNITS`); the axis is in seconds.
    restarts : sequence of int
        Base ticks (from the log's first) where a pause of the logger ended and state 0 started
        again (:func:`run_log`): the start-up after each is shaded too.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per state (and per reference error).
    """
    import matplotlib.pyplot as plt

    refs = references or {}
    rows = sum(2 if s in refs else 1 for s in table.states)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.2 * rows), sharex=True, squeeze=False)
    x, xlabel = _time_axis(estimates, time, TIME_UNITS[time_unit])
    startup = _startup_ticks(table) if table.domain == "z" and len(x) else None  # (logs run discrete tables)
    if startup is not None:  # where it ends on the x axis: without a time column, a row is a base tick
        startup_s = startup * table.sample_time_s
        end = x[0] + (startup_s if time else startup)
    ax_iter = iter(axes[:, 0])
    wrapped = table.states[0] if table.wrap_angle else None
    units = dict(zip(table.states, (f" ({u})" if u else "" for u in table.state_units()), strict=True))
    gaps = _gaps(x)

    def cut(values):  # lines and bands break at a gap of the log (a pause) instead of bridging it
        out = np.array(values, dtype=float)
        out[gaps] = np.nan
        return out

    for name in table.states:
        ax = next(ax_iter)
        est = estimates[name].to_numpy()
        ax.plot(x, cut(_broken(est) if name == wrapped else est), lw=0.8, label=f"{name} (estimate)")
        if name in refs:
            ref = estimates[f"{name}_reference"].to_numpy()
            ax.plot(x, cut(_broken(ref) if name == wrapped else ref), lw=0.8, ls="--", label="reference")
            ax2 = next(ax_iter)
            err = est - estimates[f"{name}_reference"].to_numpy()
            err = wrap(err) if table.wrap_angle and name == table.states[0] else err
            band = cut(2 * estimates[f"{name}_std"].to_numpy()) if f"{name}_std" in estimates else None
            if startup is not None:  # the start-up: the error of the initial state dying away, outside the band
                ax2.axvspan(x[0], min(end, x[-1]), color="#fde9b5", lw=0, zorder=0,
                            label=f"start-up (first {startup_s:.3g} s)" if math.isfinite(startup_s)
                            else "start-up (the error does not die away)")
                for e in restarts:  # and the start-up after each pause
                    at = x[0] + e * (table.sample_time_s if time else 1)
                    ax2.axvspan(at, min(at + end - x[0], x[-1]), color="#fde9b5", lw=0, zorder=0)
            ax2.plot(x, cut(err), lw=0.6, color="C3", label="error")
            if band is not None:
                ax2.fill_between(x, -band, band, color="0.85", label="predicted ±2σ")
            ok = np.isfinite(err)
            after = ok & (x >= end) if startup is not None else None
            for e in restarts if startup is not None else ():
                at = x[0] + e * (table.sample_time_s if time else 1)
                after &= ~((x >= at) & (x < at + end - x[0]))
            title = f"RMS {np.sqrt(np.mean(err[ok] ** 2)):.3g}"
            if after is not None and after.any():
                title += f"; after the start-up {np.sqrt(np.mean(err[after] ** 2)):.3g}"
            ax2.set_ylabel(f"{name} error{units[name]}")
            ax2.set_title(title, fontsize=9, loc="right")
            ax2.legend(loc="upper right", fontsize=8)
        elif f"{name}_std" in estimates:
            band = 2 * estimates[f"{name}_std"].to_numpy()
            ax.fill_between(x, cut(est - band), cut(est + band), color="0.85", label="predicted ±2σ")
        ax.set_ylabel(f"{name}{units[name]}")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel(xlabel)
    fig.suptitle(table.name, fontsize=10)
    fig.tight_layout()
    return fig


def _time_axis(estimates, time, scale=1.0):
    """``(x, label)``: the time column in seconds (``scale`` seconds a unit; dates as seconds after
    the first row), or the row number."""
    if not time:
        return np.arange(len(estimates)), "row"
    col = estimates[time]
    if col.dtype.kind in "fiu" and scale != 1.0:  # nanoseconds since 1970: seconds from the first row
        raw = col.to_numpy()  # whole numbers subtracted before they become floats: exact
        return (raw - raw[0]).astype(float) * scale, f"{time} (s after the first row)"
    if col.dtype.kind in "fiu":
        return col.to_numpy(dtype=float), f"{time} (s)"
    x = _numeric(estimates, [time], "estimates", _Lines(), time)[time]
    return x - x[0], f"{time} (s after {col.iloc[0]})"


def _gaps(x):
    """Rows that follow a gap of the x axis of more than ten median steps (a logger's pause):
    the plot's lines and bands break there rather than draw a straight line across it."""
    out = np.zeros(len(x), dtype=bool)
    if len(x) > 2:
        step = np.diff(np.asarray(x, dtype=float))
        out[1:] = step > 10 * np.median(step)
    return out


def _broken(angle):
    """An angle with NaN at its +-pi wraps, so the plot has no vertical lines there."""
    out = np.array(angle, dtype=float)
    out[1:][np.abs(np.diff(out)) > np.pi] = np.nan
    return out


# ---------------------------------------------------------------------------- many logs
def run_logs(table, paths, outdir, *, workers=None, scheduler=None, suffix=".csv", **options) -> list:
    """Run a table on many logs in parallel on Dask; write one estimate file per log and a
    summary table (``summary.csv``: one row per log) in ``outdir`` (created if missing).

    Parameters
    ----------
    table : GainTable
        The gain table every log is run through.
    paths : list of str or Path
        The logs (CSV or Parquet).
    outdir : str or Path
        Folder the estimates are written to, one file per log.
    workers : int, optional
        Processes of a local Dask cluster (default: the number of CPUs).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``) instead of a local cluster.
    suffix : str
        Extension of the estimate files (``.csv`` or ``.parquet``).
    **options
        As :func:`run_log` (time, mapping, reference, std, prediction).

    Returns
    -------
    list of dict
        The summary rows, in the order of ``paths``; a log that could not be run has ``error``:
        its one-line message, beginning with :data:`INTERNAL` for a fault of cfdesign.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        Dask is not installed, ``workers`` and ``scheduler`` are both given, the scheduler
        cannot be reached, ``outdir`` cannot be created, or the table cannot run any log (a
        continuous or unstable table, as :func:`run_log` and
        :class:`~cfdesign.runtime.Runtime` refuse it), named before the workers start.
    DataError
        Two logs of the same name (their estimates would overwrite each other), or a log
        that cannot be run (as :func:`run_log`).
    """
    require_table(table, "run_logs")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise CfdesignError(f"workers must be a positive number of processes, got {workers!r}")  # (-1 hangs Dask)
    if workers is not None and scheduler:
        raise CfdesignError("workers and scheduler exclude each other: an existing scheduler has its own workers")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise CfdesignError('running many logs needs Dask: pip install "cfdesign[fleet]"') from None
    outdir = Path(outdir)
    targets = [outdir / (_log_stem(p) + suffix) for p in paths]
    first = {}
    for i, t in enumerate(targets):
        j = first.setdefault(t, i)
        if j != i:
            raise DataError(f"{paths[j]} and {paths[i]} have the same name; their estimates would both be {t}")
    same = [str(p) for p, t in zip(paths, targets, strict=True) if _same_file(p, t)]
    if same:
        raise DataError(f"{same[0]}: its estimates would replace the log itself (write them to another folder, "
                        "or with another --format)")
    from .runtime.filter import Runtime

    # a table no log can run (continuous, unstable, no posterior) is named once, before the workers start
    Runtime(table, output="prior" if options.get("prediction") else None)
    text = table.to_json()
    if scheduler:
        try:
            client, cluster = Client(scheduler), None
        except (OSError, ValueError, TypeError) as exc:  # unreachable or not an address: the user's to fix
            raise CfdesignError(f"cannot connect to the Dask scheduler {scheduler}: {_first_line(exc)}") from None
    else:
        # no dashboard; the scheduler's HTTP server on a free port of this machine: on 8787, its default, it
        # warned on stderr when another cluster (another fleet run at the same time) had that port
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                               dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                               silence_logs=logging.ERROR)  # no shutdown warnings
        client = Client(cluster)
    try:
        try:  # once connected: an unreachable scheduler leaves no empty folder
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CfdesignError(f"cannot create {outdir}: {exc.strerror or exc}") from None
        futures = [client.submit(_run_one, text, str(p), str(t), options, pure=False)
                   for p, t in zip(paths, targets, strict=True)]
        rows = client.gather(futures, errors="skip")  # what still fails is an internal error of that log
        done = {r["log"]: r for r in rows}
        rows = [done.get(str(p)) or {"log": str(p), "samples": 0, "error": _failure(f)}
                for p, f in zip(paths, futures, strict=True)]
    finally:
        dask_log = logging.getLogger("distributed")  # closing: a slow worker is killed after 4 s, which it
        level = dask_log.level                          # logged as a WARNING on stderr (a busy machine, not a fault)
        dask_log.setLevel(logging.ERROR)
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        finally:
            dask_log.setLevel(level)
    write_text(outdir / "summary.csv", _summary_csv(rows))
    return rows


def _failure(future) -> str:
    try:
        exc = future.exception()
    except Exception as e:  # noqa: BLE001 - a cancelled future reports why
        exc = e
    return str(exc).splitlines()[0] if exc else "failed"


def _run_one(table_json, path, target, options):
    import json

    from .gains import GainTable

    table = GainTable.from_dict(json.loads(table_json))
    try:
        return run_log(table, path, output=target, source=path, **options).summary()
    except CfdesignError as exc:  # a bad log is a row of the summary, not a failed task (no worker traceback)
        return {"log": path, "samples": 0, "error": _first_line(exc)}
    except Exception as exc:  # noqa: BLE001 - a fault of cfdesign on one log: the others still run
        # a failed task printed Dask's traceback of it and summarised it as the bare exception ("'__index_level_0__'")
        return {"log": path, "samples": 0, "error": f"{INTERNAL} ({type(exc).__name__}: {_first_line(exc)}); "
                                                    "please report it with the log"}


def _summary_csv(rows) -> str:
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    lines = [",".join(keys)]
    for r in rows:
        lines.append(",".join(_cell(r.get(k, "")) for k in keys))
    return "\n".join(lines) + "\n"


def _cell(v) -> str:
    if isinstance(v, float):
        return repr(v)
    text = str(v)
    return '"' + text.replace('"', '""') + '"' if ("," in text or '"' in text or "\n" in text) else text
