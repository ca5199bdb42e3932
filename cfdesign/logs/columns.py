"""Which log column is what: time column names and units, the optional pandas, cells to numbers."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import CfdesignError, DataError, require_extra

#: column names taken as the time (seconds) when none is given
TIME_COLUMNS = ("time", "t", "timestamp")
#: the time column of a ROS ``rostopic echo -p`` export: integer nanoseconds since 1970
ROS_TIME = "%time"
#: units a numeric time column may be in (``time_unit``, ``cfdesign run --time-unit``): seconds each
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: cells that are no reading (in lower case, spaces stripped): those pandas reads as missing
MISSING = ("", "nan", "-nan", "na", "n/a", "#n/a", "#na", "null", "none", "<na>", "nat")
#: a spreadsheet's error values: a formula that failed in that cell (``#N/A`` is missing, above)
_SHEET_ERRORS = re.compile(r"#(?:DIV/0!|VALUE!|REF!|NAME\?|NUM!|NULL!|SPILL!|CALC!|FIELD!|GETTING_DATA)",
                           re.IGNORECASE)


#: what reading or writing Parquet needs, the start of the one-line error without pyarrow
NEEDS_PYARROW = "Parquet logs and estimates need pyarrow"


def _pandas(parquet=False):
    """pandas, and with ``parquet`` pyarrow (pandas reads and writes Parquet through it); a
    missing one is a one-line error naming the extra that installs it
    (:func:`cfdesign.errors.require_extra`)."""
    pd = require_extra("pandas", "reading logs needs pandas")
    if parquet:
        require_extra("pyarrow.parquet", NEEDS_PYARROW)
    return pd


@dataclass(frozen=True)
class _Columns:
    """Which log column feeds what."""

    sensors: dict          # sensor -> column
    time: str | None
    references: dict       # state -> column
    extra: list            # passed through
    time_unit: str = "s"     # of a numeric time column (TIME_UNITS)
    lines: object = None     # _Lines: the file line of each row (after the header, the comments before it, blank lines)
    scales: dict = field(default_factory=dict)  # column -> factor into the table's unit (its own unit given)
    notes: list = field(default_factory=list)   # on those units

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
               **{w: "ms" for w in ("ms", "msec", "millis", "millisecond", "milliseconds")},
               **{w: "us" for w in ("us", "\u00b5s", "\u03bcs", "usec", "micros", "microsecond", "microseconds")},
               **{w: "ns" for w in ("ns", "nsec", "nanos", "nanosecond", "nanoseconds")}}


def _unit(name) -> tuple:
    """``(name, unit)`` of a column named with its unit (``gyro [rad/s]``, ``time (ms)``, or a unit of
    time after an underscore: ``time_ms``), else ``(name, None)``; a unit of time as
    :data:`TIME_UNITS` names it (``sec`` is ``s``)."""
    m = re.fullmatch(r"(.*?)\s*(?:\[([^\]]*)\]|\(((?:[^()]|\([^()]*\))*)\))", str(name).strip())
    if not (m and m.group(1)):
        m = re.fullmatch(r"(.+?)_([^_]+)", str(name).strip())
        unit = _UNIT_NAMES.get(m.group(2).lower()) if m else None
        return (m.group(1), unit) if unit else (name, None)
    unit = (m.group(2) if m.group(2) is not None else m.group(3)).strip()
    return m.group(1), _UNIT_NAMES.get(unit.lower(), unit)


def _bare_unit(cell) -> str:
    """A cell of a row of units without the spaces and the one pair of brackets around it (``[deg/s]``,
    ``(m/(s^2))``; the brackets stripped one by one left ``m/(s^2`` of the last, a unit no longer)."""
    text = str(cell).strip()
    if len(text) < 2 or (text[0], text[-1]) not in (("[", "]"), ("(", ")")):
        return text
    depth = 0
    for c in text[1:-1]:  # '(m/s)/(s)' is no pair around it
        depth += {"(": 1, ")": -1}.get(c, 0)
        if depth < 0:
            return text
    return text[1:-1].strip() if depth == 0 else text


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
    """The unit of a numeric time column: ``time_unit`` if given (it overrides the name: a logger
    that writes ``time (s)`` over milliseconds is corrected by the option, not by renaming the
    column of a large file), else the one its name gives (``time [ms]``) or the row of ``units``
    under a CSV's header (``{column: unit}``), else seconds."""
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise CfdesignError(f"time unit {time_unit!r} is none of {', '.join(TIME_UNITS)}")
    return time_unit or _named_unit(time, units) or "s"


def _named_unit(time, units=None):
    """The unit of time (of :data:`TIME_UNITS`) that the name of the column ``time`` gives
    (``time [ms]``; ``%time``, a ROS export's: ns), else the row of ``units`` under a CSV's header
    (``{column: unit}``), else None."""
    if time is None:
        return None
    if time == ROS_TIME:
        return "ns"
    named = _unit(time)[1] or _UNIT_NAMES.get(_bare_unit((units or {}).get(time, "")).lower())
    return named if named in TIME_UNITS else None


def _listed(header, limit=300) -> str:
    """The column names for a message, cut to about ``limit`` characters (a file read as one
    column - JSON, a spreadsheet - or a log of thousands of columns gave a line of megabytes)."""
    text = ", ".join(str(h) for h in header)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(header)} columns)"


#: a number written with thousands separators: groups of 3 digits after commas, points, spaces or
#: apostrophes, with a decimal separator of the other kind (``1,234.5``, ``1.234,5``, ``1 234``)
_THOUSANDS = re.compile(r"[-+]?[0-9]{1,3}(?:(?:,[0-9]{3})+\.[0-9]*|(?:\.[0-9]{3})+,[0-9]*|(?:\.[0-9]{3}){2,}"
                        r"|(?:[' \u00a0\u202f][0-9]{3})+(?:[.,][0-9]*)?)")


def _numeric(df, columns, source, where, time=None, time_scale=1.0, scales=None):
    """The columns as float arrays; a cell that is not a number is an error naming where it is
    (``where(i)``: row ``i`` of ``df`` for a message, ``cfdesign.logs.read._Lines.at``:
    ``line N`` of a text log, ``row N`` of a Parquet log).

    The ``time`` column may also hold dates (a datetime column of a Parquet file, ISO 8601 text
    in a CSV: ``2024-05-01T12:00:00.010``): they become seconds since 1970-01-01 UTC (a date
    without a time zone is taken as UTC; only differences matter); durations (a timedelta
    column) become seconds.  Numbers in the ``time`` column are multiplied by ``time_scale``
    (seconds per unit: milliseconds, nanoseconds ...), and those of a column of ``scales``
    (``{column: factor}``, :attr:`_Columns.scales`) by its factor."""
    out = _numbers_of(df, columns, source, where, time, time_scale)
    for c, factor in (scales or {}).items():
        if c in out:
            out[c] = out[c] * factor
    return out


def _numbers_of(df, columns, source, where, time, time_scale):
    """:func:`_numeric` before ``scales``."""
    pd = _pandas()
    out = {}
    for c in columns:
        s = df[c]
        if s.dtype.kind == "b":  # text True/False in an object column is named as not a number, below
            _refuse_booleans(s, c, source, where)
        if s.dtype.kind in "fiu":
            out[c] = _floats(s, pd) * (time_scale if c == time else 1.0)
            continue
        if c == time and (s.dtype.kind == "M" or isinstance(s.dtype, pd.DatetimeTZDtype)):
            out[c] = _epoch_seconds(s)
            continue
        if c == time and s.dtype.kind == "m":  # durations (a Parquet duration column): seconds; NaT is NaN
            out[c] = s.dt.total_seconds().to_numpy(dtype=float)
            continue
        text = s.astype("string").str.strip()
        text = text.where(~text.str.lower().isin(MISSING))  # 'NaN ' padded by a fixed-width export: missing too
        values = _numbers(text, pd)
        bad = np.flatnonzero(np.isnan(values) & text.notna().to_numpy())
        if bad.size and c == time and len(bad) == int(text.notna().sum()):  # no number: dates?
            dates, not_date = _dates(text)
            if not_date is None:
                out[c] = dates
                continue
            bad = [not_date]  # the first cell that is no date either
        if len(bad):  # a number with thousands separators first: it left the others unread (0,5 by 1.234,5)
            bad = np.flatnonzero(text.str.fullmatch(_THOUSANDS.pattern).fillna(False).to_numpy())[:1].tolist() or bad
            what = ("neither a number (seconds, or the --time-unit ms|us|ns) nor an ISO 8601 date and time "
                    "(2024-05-01T12:00:00.010)" if c == time else "not a number")
            cell = str(text.iloc[bad[0]])
            raise DataError(f"{source} {where(bad[0])}: column {c!r} is {what}: {_cell_text(s.iloc[bad[0]])}"
                            + _cell_hint(cell, c))
        out[c] = values * (time_scale if c == time else 1.0)
    return out


#: a decimal number (``1e999`` as well: pandas before 3.0 read no number that overflows a double)
_DECIMAL = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")


def before_pandas_3(pd) -> bool:
    """Whether ``pd`` is pandas 2.x, whose parsers read numbers inexactly by default (the logs extra
    allows pandas>=2.0; pandas 3 needs Python 3.11)."""
    return int(pd.__version__.split(".")[0]) < 3


def _numbers(text, pd):
    """The cells of a column of stripped text (missing ones NA) as float64, NaN where a cell is no
    number: the nearest double to each, and +-inf for one beyond the doubles (``1e999``), as
    pandas 3 reads them.  ``pandas.to_numeric`` before 3.0 read a third of the shortest reprs of doubles
    of any exponent an ulp off, and ``1e999`` as no number (a log writing it for no reading stopped):
    its numbers, and the decimal numbers it refused, are read again with numpy's exact parser."""
    values = _floats(pd.to_numeric(text, errors="coerce"), pd)
    if not before_pandas_3(pd):
        return values
    numbers = text.notna().to_numpy() & (~np.isnan(values) | text.str.fullmatch(_DECIMAL.pattern).fillna(False)
                                         .to_numpy(dtype=bool))
    values = values.copy()  # not a view of the column's own buffer
    values[numbers] = text[numbers].to_numpy(dtype=str).astype(float)
    return values


def _floats(s, pd):
    """A column of numbers as float64, a missing value NaN: pandas 2.0 refused ``to_numpy(dtype=float)``
    of a nullable column (``to_numeric`` of text gives one) holding ``<NA>``, which later pandas turn into NaN."""
    if isinstance(s.dtype, pd.api.extensions.ExtensionDtype):
        return s.to_numpy(dtype=float, na_value=np.nan)
    return s.to_numpy(dtype=float)


def _cell_hint(cell, column) -> str:
    """What a cell that is not a number likely is, for the message naming it (or '')."""
    if _THOUSANDS.fullmatch(cell):
        return " (a thousands separator: write numbers without one)"
    if re.fullmatch(r"[-+]?[0-9]+,[0-9]+(?:[eE][-+]?[0-9]+)?", cell):
        return (" (a decimal comma: read in a log separated by semicolons, tabs or spaces whose first 64 kB "
                "show one, not in one separated by commas; write decimal points)")
    if _SHEET_ERRORS.fullmatch(cell):  # '#DIV/0!' was named a comment line
        return " (a spreadsheet's error value: the formula of that cell failed; write a number or leave it empty)"
    if cell.startswith("#"):
        return " (a comment line: only those before the header are skipped)"
    if re.fullmatch(r"[-–—]+", cell):  # a dash may be no reading or a number cut to its sign
        return " (a dash: leave a cell without a reading empty, or write nan)"
    if cell == str(column).strip():
        return " (the header again: two logs written into one file? split it there)"
    if "\n" in cell:  # a quote opened in a cell and closed lines later took the lines between as its text
        return " (a quote opened in this cell is closed lines later: a line cut off inside quotes?)"
    return ""


def _refuse_booleans(s, column, source, where):
    """A DataError naming the first true/false cell of a column that must hold numbers: pandas reads
    ``True``/``False`` as booleans, which numpy takes as 1 and 0 (a gyro column of them ran, exit 0)."""
    first = int(np.argmax(s.notna().to_numpy()))
    raise DataError(f"{source} {where(first)}: column {column!r} holds true/false values, not numbers: "
                    f"{bool(s.iloc[first])}")


def _cell_text(cell, limit=40) -> str:
    """A cell for a message: its repr, cut to about ``limit`` characters (a row of the NUL bytes a
    log cut off by a power loss ends in printed thousands of ``\\x00``)."""
    text = repr(cell)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(str(cell))} characters)"


def _dates(text):
    """``(epoch seconds, None)`` for a column of ISO 8601 dates (:func:`cfdesign.timing.date_seconds`),
    or ``(None, i)`` with ``i`` the first cell that is not one."""
    from ..timing import date_seconds

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


def _first_line(exc) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
