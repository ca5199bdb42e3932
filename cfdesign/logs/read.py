"""Reading logs: file kinds (CSV plain or compressed, Parquet, a pipe), CSV format sniffing,
:func:`~cfdesign.logs.read_log`, :func:`~cfdesign.logs.read_columns`, and which columns of a
header feed a table's sensors (``_columns``)."""

from __future__ import annotations

import codecs
import contextlib
import csv
import io
import os
import re
from pathlib import Path

import numpy as np

from ..errors import CfdesignError, DataError, require_extra
from .columns import (
    MISSING,
    NEEDS_PYARROW,
    ROS_TIME,
    TIME_COLUMNS,
    TIME_UNITS,
    _bare_unit,
    _Columns,
    _first_line,
    _listed,
    _numeric,
    _pandas,
    _time_name,
    _time_unit,
    _time_with_unit,
    _unit,
    before_pandas_3,
)


def _numbers_only(header) -> bool:
    """Whether every name of ``header`` is a number or a column pandas named for an empty cell."""
    named = [h for h in header if not re.fullmatch(r"Unnamed: [0-9]+", h)]
    return bool(named) and all(re.fullmatch(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?(?:\.[0-9]+)?", h)
                               for h in named)


def time_column(header):
    """The time column of a log whose options name none: ``time``, ``t`` or ``timestamp``, else
    one of them in another case (``Time``), else with a unit (``time [ms]``, ``t_us``), else a ROS
    ``rostopic echo -p`` export's ``%time`` (nanoseconds); None when the header has none of them.

    Parameters
    ----------
    header : list of str
        The log's column names.

    Returns
    -------
    str or None
        The name as the header writes it.

    Examples
    --------
    >>> from cfdesign.logs.read import time_column
    >>> time_column(["gyro", "Time (ms)"]), time_column(["gyro"])
    ('Time (ms)', None)
    """
    return next((c for c in TIME_COLUMNS if c in header), None) or next(
        (h for c in TIME_COLUMNS for h in header if h.lower() == c), None) or next(
        (h for c in TIME_COLUMNS for h in header if _time_with_unit(h) == c), None) or (
        ROS_TIME if ROS_TIME in header else None)


def _unique(header, source) -> list:
    """``header``'s names stripped of spaces; DataError naming a name written twice (of the log
    ``source``, or of a joined file: one would be read in silence)."""
    header = [str(h).strip() for h in header]
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{source}: duplicate column(s) {', '.join(dup)}")
    return header


def _columns(table, header, source, time=None, mapping=None, reference=None, time_unit=None,
             lines=None, units=None, listing=None, joined_units=None) -> _Columns:
    """Which of ``header``'s columns feeds what; ``listing``: the columns a message on a missing one
    lists (every file's, of a log joined from several: ``cfdesign.logs.join.joined_header``);
    ``units`` the row of units under the main file's header, ``joined_units`` those of the joined
    files (``{column: unit}``: of the sensors' columns only, :func:`_scales`)."""
    header = _unique(header, source)
    if mapping is not None and not isinstance(mapping, dict):  # a list of pairs gave dict()'s raw ValueError
        raise CfdesignError(f"mapping must be a dict {{sensor: column}}, got {type(mapping).__name__} {mapping!r:.80}")
    mapping = dict(mapping or {})
    unknown = sorted(set(mapping) - set(table.sensor_names()))
    if unknown:
        raise DataError(f"--map {unknown[0]}: {table.name} has no sensor {unknown[0]!r} "
                        f"(sensors: {', '.join(table.sensor_names())})")
    sensors = {s: mapping.get(s, s) for s in table.sensor_names()}
    reads = table.sensor_units()
    for s, c in sensors.items():
        if s not in mapping and c not in header:
            sensors[s] = sensor_column(s, header, reads[s]) or c
    missing = [f"{c} (sensor {s})" if c != s else c for s, c in sensors.items() if c not in header]
    if missing:
        # a column named with a unit cfdesign cannot convert ('gyro [LSB]') is not taken in silence
        like = {s: _named(s, header) for s, c in sensors.items() if c not in header and s not in mapping}
        like = {s: names for s, names in like.items() if names}
        twice = next(((s, names) for s, names in like.items() if len(names) > 1), None)
        if twice is not None:  # 'gyro [deg/s]' and 'gyro [rad/s]': the hint gave two --map for one sensor
            raise DataError(f"{source}: sensor {twice[0]} has {len(twice[1])} columns named with a unit "
                            f"({', '.join(twice[1])}): --map \"{twice[0]}=COLUMN\" takes one")
        hint = " ".join(f'--map "{s}={names[0]}"' for s, names in like.items())
        if not like and _numbers_only(header):  # the first row of a file without a header read as one
            raise DataError(f"{source}: the header holds numbers ({_listed(header)}), not column names: the log "
                            f"has no header; add a first line naming its columns ("
                            f"{', '.join(['time', *sensors.values()])})")
        raise DataError(f"{source}: missing column(s) {', '.join(missing)} (columns: {listing or _listed(header)}); "
                        + ("a column named with a unit cfdesign cannot convert (one it does not know, or a table "
                           "whose state names do not tell what its sensor reads) is not taken in silence: "
                           f"{hint} reads it as it is, in the table's units" if like else
                           "the header is one column: cells are separated by commas, semicolons or tabs, or by "
                           "spaces where the first row has as many cells"
                           if len(header) == 1 else
                           "name them as the table's sensors or map them with --map SENSOR=COLUMN"))
    if time is None:
        time = time_column(header)
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
    scales, notes = _scales(table, sensors, refs, {**(joined_units or {}), **(units or {})}, source)
    used = {time, *sensors.values()}  # a reference column is passed through as well
    return _Columns(sensors, time, refs, [h for h in header if h not in used], time_unit, lines or _Lines(),
                    scales, notes)


def _named(sensor, header) -> list:
    """The columns of ``header`` named ``sensor`` (in any case) with a unit: ``gyro [deg/s]``, ``Gyro (dps)``."""
    return [h for h in header if _bracket_unit(h) is not None and str(_unit(h)[0]).lower() == sensor.lower()]


def _bracket_unit(name):
    """The unit a column's name gives in brackets (``gyro [deg/s]``, ``gyro (dps)``), or None: a unit of time
    after an underscore (:func:`~cfdesign.logs.columns._unit`'s ``time_ms``) names a time column's only (a GPS's
    own clock ``gps_us`` had been taken for the GPS's readings in microseconds, and refused as not metres)."""
    return _unit(name)[1] if str(name).strip().endswith(("]", ")")) else None


def sensor_column(sensor, header, reads, time=None):
    """The column of ``header`` a sensor takes by its name (no ``--map`` for it): its name, else its
    one column named so in another case (``Gyro``), else its one column named so with a unit
    cfdesign converts to what the sensor reads (``gyro [deg/s]``, :func:`_scales`); the one rule
    of a log and of its joined files (a joined ``compass [deg]`` was missing where the main file's
    was taken).  A table whose state names do not tell what the sensor reads (``reads`` ``''``)
    takes no column by its unit: it would be read as it is (deg/s as rad/s).

    Parameters
    ----------
    sensor : str
        The sensor's name.
    header : list of str
        The file's column names.
    reads : str
        The unit the table's sensor reads (:meth:`~cfdesign.gains.GainTable.sensor_units`), or ``''``.
    time : str, optional
        The file's time column, never a sensor's.

    Returns
    -------
    str or None
        The column, or None (none, or more than one).
    """
    header = [h for h in header if h != time]
    if sensor in header:
        return sensor
    like = [h for h in header if h.lower() == sensor.lower()]
    if len(like) == 1:
        return like[0]
    named = [h for h in _named(sensor, header) if reads and _known_unit(_unit(h)[1])]
    return named[0] if len(named) == 1 else None


def _known_unit(text) -> bool:
    """Whether :func:`~cfdesign.units.parse_unit` reads ``text``."""
    from ..errors import SpecError
    from ..units import parse_unit

    try:
        parse_unit(text)
    except SpecError:
        return False
    return True


#: what a row of units (or a name) may write for a column without one
_NO_UNIT = {"", "none", "n/a", "na", "unitless", "dimensionless"}


def _scales(table, sensors, refs, units, source) -> tuple:
    """``({column: factor}, notes)``: the factor that takes each sensor or reference column whose
    unit is given (by its name, ``gyro [deg/s]``, or by the row of ``units`` under a CSV's header)
    into the unit the table reads there (:meth:`~cfdesign.gains.GainTable.sensor_units`,
    :meth:`~cfdesign.gains.GainTable.state_units`), where the two differ, with a note on each;
    a note on a column read as it is: its unit one :func:`~cfdesign.units.parse_unit` does not
    know, or the table's state names do not tell what it reads there.  A gyro logged in deg/s and
    read as rad/s had run 57 times too fast.  A column that feeds two things (a sensor and a
    reference) is checked against both and scaled once.

    Raises
    ------
    DataError
        A column whose unit is of another quantity than the table reads there (``m/s`` for rad/s),
        or whose name and row of units give two units.
    """
    reads = table.sensor_units()
    state_units = dict(zip(table.states, table.state_units(), strict=True))
    targets = [(c, f"sensor {s}", reads[s]) for s, c in sensors.items()]
    targets += [(c, f"reference for {st}", state_units[st]) for st, c in refs.items()]
    scales, notes, seen = {}, [], set()
    for column, what, unit in targets:
        text = _given_unit(column, units, source)
        if text is None:
            continue
        first, _ = column not in seen, seen.add(column)
        if not unit or not _known_unit(text):
            cause = ("is no unit cfdesign knows" if unit else
                     f"is not converted: the table's state names do not tell what its {what} reads")
            notes += [f"column {column!r}: {text!r} {cause}; read as it is, in the table's {unit or 'units'}"
                      ] if first else []
            continue
        factor = _factor(column, text, unit, what, source)
        if first and abs(factor - 1.0) > 1e-12:
            scales[column] = factor
            notes.append(f"column {column!r} is in {text}: read as {unit} (times {factor:.6g})")
    return scales, notes


def _given_unit(column, units, source):
    """The unit a column's name (``gyro [deg/s]``) or the row of ``units`` under its CSV's header
    gives it, or None (none, or one of :data:`_NO_UNIT`).

    Raises
    ------
    DataError
        The name and the row give two units (``gyro [deg/s]`` over ``rad/s``): which one the numbers
        are in is not known.
    """
    from ..units import parse_unit

    named, row = _bracket_unit(column), _bare_unit((units or {}).get(column, ""))
    named, row = [u if u is not None and u.strip("-\u2013\u2014 ").lower() not in _NO_UNIT else None
                  for u in (named, row)]
    if named and row and _known_unit(named) and _known_unit(row):
        (a, dim_a), (b, dim_b) = parse_unit(named), parse_unit(row)
        if dim_a != dim_b or abs(a / b - 1.0) > 1e-12:
            raise DataError(f"{source}: column {column!r} is named in {named} but the row of units gives it {row}: "
                            "correct the one that is wrong")
    return named or row


def _factor(column, text, unit, what, source) -> float:
    """The factor from the column's unit ``text`` to the table's ``unit`` of ``what`` (``sensor gyro``,
    ``reference for heading``).

    Raises
    ------
    DataError
        The two are units of other quantities.
    """
    from ..units import parse_unit

    (scale, dim), (base, want) = parse_unit(text), parse_unit(unit)
    if dim != want:
        option = "--map SENSOR=COLUMN" if what.startswith("sensor") else "--reference STATE=COLUMN"
        raise DataError(f"{source}: column {column!r} is in {text}, but the table's {what} reads {unit} "
                        f"(another quantity): give the right column with {option}, or check its unit")
    return scale / base


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


#: the first bytes of the compressions a CSV log may come in (pandas and Python's modules read them)
COMPRESSIONS = {b"\x1f\x8b": "gzip", b"BZh": "bz2", b"\xfd7zXZ\x00": "xz", b"PK\x03\x04": "zip"}
#: what cfdesign reads, for the messages about a file it cannot
_READS = "CSV (plain, or compressed with gzip, bz2, xz or zip) and Parquet"


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
    """Read a CSV (UTF-8, a BOM and CRLF line ends are fine; Windows-1252 where its first 64 kB
    are not UTF-8: ``_encoding``) or Parquet log with pandas.

    What a file is comes from its first bytes, not its name: Parquet, or a CSV, plain or
    compressed with gzip, bz2, xz or zip (one file in the archive; ``log.csv.gz``).  A CSV's
    separator is the comma, semicolon or tab of its header line that splits it and the
    first row alike (``_separator``), or spaces when the header and the first row split into as many cells at spaces
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
        The file cannot be read, is empty, is not text (UTF-16, binary) or not a table (also while blocks
        are read).
    """
    path = Path(path)
    kind = _kind(path)
    pd = _pandas(kind == "parquet")
    try:
        if kind == "parquet":
            return _parquet_blocks(path, columns, chunksize) if chunksize else next(_parquet_blocks(path, columns))
        fmt = _csv_format(path, kind)
        first = _first_row(fmt)
        hashed = fmt.pop("_hashed", False)
        if fmt.pop("_units", None) is not None:  # the line under the header: units
            fmt["skiprows"] = [*range(fmt.get("skiprows", 0)), fmt.get("skiprows", 0) + 1]
        end = _tail(path)[0] if kind == "csv" else None
        source = path if end is None else io.BufferedReader(_Upto(path, end))  # a cut end left out
        if fmt.get("sep") == WHITESPACE:  # every row's cells counted (the decompressed bytes, then)
            raw = _Upto(path, end) if end is not None else _open_csv(path, kind)
            source, kind = io.BufferedReader(_RowCells(raw, path, len(_header(path)), first), 1 << 20), "csv"
        encoding = fmt.pop("encoding", "utf-8-sig")  # Windows-1252: its 5 unused bytes read as U+FFFD
        reader = pd.read_csv(source, chunksize=chunksize, encoding=encoding, skipinitialspace=True, low_memory=False,
                             encoding_errors="strict" if encoding == "utf-8-sig" else "replace",
                             index_col=False, compression=None if kind == "csv" else kind, **_exact(pd), **fmt)
        opened = None if source is path else source
        if chunksize:
            return _csv_blocks(path, reader, columns, hashed, closing=opened)
        with contextlib.closing(opened) if opened is not None else contextlib.nullcontext():
            return _stripped(reader, columns, hashed)
    except DataError:
        raise
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
    """``{column: unit}`` of the row of units under a CSV's header (:func:`_csv_format`), or ``{}``
    (also for the header written twice: each sensor's name was noted as a unit cfdesign does not know)."""
    kind = _kind(path)
    units = None if kind == "parquet" else _csv_format(path, kind).get("_units")
    header = _header(path)
    if not units or [u.strip() for u in units] == header:
        return {}
    return dict(zip(header, units, strict=False))


def _units_note(path, source) -> list:
    """The note on a row of units under a CSV's header, which :func:`read_log` skips, if any."""
    if _kind(path) == "parquet":
        return []
    fmt = _csv_format(path, _kind(path))
    if "_units" not in fmt:
        return []
    line = 2 + fmt.get("skiprows", 0)
    if [u.strip() for u in fmt["_units"]] == _header(path):  # the header written twice: no units
        return [f"{source} line {line} repeats the header and is not read"]
    return [f"{source} line {line} ({_listed(fmt['_units'], 80)}) is taken as the columns' units and not read: "
            "a sensor's or reference's column in a known unit other than the table's is converted (a note says so)"]


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
    text = _first_line(exc)
    wide = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", text)
    if wide:  # pandas counts the file's lines (comments, blank lines and all), as the messages do
        columns, line, cells = (int(g) for g in wide.groups())
        return DataError(f"{path} line {line}: {cells} cells under a header of {columns} columns (a line "
                         "written into another, or an unquoted separator in a cell)")
    if "EOF inside string" in text:  # its 'row N' counts neither the comment lines nor the blank ones
        line = _unclosed_quote(path)
        return DataError(f"{path}{f' line {line}' if line else ''}: a quote (\") opened in a cell is never closed "
                         "(a line cut off inside quotes?)")
    return DataError(f"{path}: not a readable log: {text}")


def _unclosed_quote(path):
    """The file line from which a CSV's quotes stay open (an odd count of ``"`` up to it), or None."""
    start = None
    try:
        with _open_csv(path, _kind(path)) as fh:
            for line, text in enumerate(fh, 1):
                if text.count(b'"') % 2:
                    start = line if start is None else None
    except (OSError, DataError, *_unpack_errors()):
        return None
    return start


#: most comment lines before a CSV's header (``# logged by ...``) that are skipped
COMMENT_LINES = 1000


def _csv_format(path, kind="csv") -> dict:
    """``read_csv`` options of a CSV: its separator, from its header line and first row
    (:func:`_separator`); a semicolon, tab or space file writes decimal commas when a
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
            skipped, comment, before = 0, None, []
            line = fh.readline(1 << 16)
            forced = re.fullmatch(rb"(?:\xef\xbb\xbf)?sep=(.)\r?\n", line)  # a spreadsheet's 'sep=;' line
            if forced:
                skipped, forced, line = 1, forced.group(1).decode("latin-1"), fh.readline(1 << 16)
            while skipped < COMMENT_LINES and (line.strip() in (b"", b"\xef\xbb\xbf")
                                               or line.lstrip(b"\xef\xbb\xbf \t").startswith(b"#")) and b"\n" in line:
                comment = line if line.strip(b"\xef\xbb\xbf \t\r\n") else comment
                before.append(line)
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
    encoding = _encoding(b"".join(before[-64:]) + line + rows)  # a comment's '25 \xb0C' too
    out = {"skiprows": skipped} if skipped else {}
    if encoding is not None:  # analysed as UTF-8 from here on: the names and units read as written
        line, rows, comment = (b.decode(encoding, "replace").encode() if b is not None else None
                               for b in (line, rows, comment))
        out["encoding"] = encoding
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


def _encoding(head):
    """None where the first bytes of a CSV, ``head``, are UTF-8 (a character cut at their end
    included), else the 8-bit encoding they are read in: Windows-1252, what a spreadsheet saves as
    "CSV (comma delimited)" on Windows (``Temp [\u00b0C]``, ``t [\u00b5s]``), else Latin-1, which
    reads any byte.  Only names and text cells can hold such bytes: the numbers are ASCII alike."""
    try:
        codecs.getincrementaldecoder("utf-8")().decode(head, final=False)
        return None
    except UnicodeDecodeError:
        pass
    try:
        head.decode("cp1252")
        return "cp1252"
    except UnicodeDecodeError:
        return "latin-1"


#: the first rows :func:`_separator` splits alike with the header (a row of whole numbers, ``0;0,01``, splits
#: as the header ``time;gyro, rad/s`` at commas too; the next, ``0,01;0,02``, does not)
_SEPARATOR_ROWS = 20


def _separator(header, rows):
    """The separator of a CSV from its header line: of the comma, semicolon and tab it holds, the
    one that splits it and the first row of ``rows`` into as many cells, and none of the next rows
    (:data:`_SEPARATOR_ROWS`) into more, the most (at least two; the first on a tie), else the first
    it holds (a name with a comma in a file separated by semicolons or tabs, ``temp, C``, had split
    the header at that comma: 'missing column(s)' beside the very names); else spaces
    (:data:`WHITESPACE`) when the header and the first row split into as many cells, at least two;
    else None (one column)."""
    sample = [r for r in rows.split(b"\n")[:-1] if r.strip()][:_SEPARATOR_ROWS]
    first = sample[0] if sample else b""
    held = [sep for sep in (",", ";", "\t") if sep.encode() in header]
    if held:
        split = {sep: len(_cells(header, sep)) for sep in held if len(_cells(first, sep)) == len(_cells(header, sep))
                 and all(len(_cells(r, sep)) <= len(_cells(header, sep)) for r in sample)}
        return max(split, key=split.get) if max(split.values(), default=0) > 1 else held[0]
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
    separated by spaces that has fewer cells than its header (:func:`_short_line`), found before
    the log is read; :func:`read_log` checks every row (:class:`_RowCells`).  The row of units
    is not a row of cells."""
    names = fmt.get("names") or _cells(header, WHITESPACE)
    short = _short_line(rows[:rows.rfind(b"\n") + 1], len(names), skip=int("_units" in fmt))
    if short is not None:
        raise _short_error(path, 2 + fmt.get("skiprows", 0) + short[0], short[1], len(names))


def _short_error(path, line, cells, columns) -> DataError:
    """The DataError of a row with fewer cells than its header in a log separated by spaces: an
    empty cell of a column-aligned table (a slow sensor between its readings, a sensor that
    stops) is no cell at all there, so pandas read the cells after it into the columns before
    them and left the last column empty (the reference read as the GPS, exit 0)."""
    return DataError(f"{path} line {line}: {cells} cells under a header of {columns} columns separated by "
                     "spaces: an empty cell cannot be told from the spaces around it (write nan in it, or "
                     "separate the cells by commas or tabs)")


def _short_line(data, columns, skip=0):
    """``(i, cells)`` of the first line of ``data`` (bytes, whole lines, counted from 0; those
    before ``skip`` left out) with cells split at spaces (tabs, control bytes) but fewer than
    ``columns``, else None.  Blank lines and lines whose first cell starts with ``#`` are not rows
    of cells.  Counted with numpy, about 2 ms a megabyte (pandas reads one in about 6)."""
    a = np.frombuffer(data, dtype=np.uint8)
    if not a.size:
        return None
    cell = a > 32
    start = np.empty(a.size, dtype=np.uint8)  # 1 at the first byte of each cell
    start[0] = cell[0]
    np.greater(cell[1:], cell[:-1], out=start[1:].view(bool))
    heads = np.flatnonzero(a == 10) + 1  # the first byte of each line
    heads = np.concatenate([[0], heads[heads < a.size]])
    count = np.add.reduceat(start, heads, dtype=np.int64)  # cells in each line
    short = np.flatnonzero((count > 0) & (count < columns))
    for i in short[short >= skip]:
        if not data[heads[i]:heads[i + 1] if i + 1 < heads.size else None].lstrip().startswith(b"#"):
            return int(i), int(count[i])
    return None


class _RowCells(io.RawIOBase):
    """The bytes of a log separated by spaces (``raw``, a binary stream) as pandas reads them,
    each row's cells counted on the way (:func:`_short_line`): a row with fewer cells than the
    header's ``columns`` is a DataError naming its line, wherever it is in the file (a sensor
    that stops partway; those of the first 64 kB only were refused).  ``first``: the line of the
    first row (those before it are the header, comments and the row of units)."""

    def __init__(self, raw, path, columns, first):
        self._raw, self._path, self._columns, self._first = raw, path, columns, first
        self._carry, self._line = b"", 1  # the bytes of a line not yet whole, and its line number

    def readable(self):
        return True

    def readinto(self, b):
        n = self._raw.readinto(b)
        data = self._carry + bytes(memoryview(b)[:n])
        whole = data.rfind(b"\n") + 1 if n else len(data)  # at the end, a last line without its line end
        short = _short_line(data[:whole], self._columns, skip=self._first - self._line)
        if short is not None:
            raise _short_error(self._path, self._line + short[0], short[1], self._columns)
        self._line += data.count(b"\n", 0, whole)
        self._carry = data[whole:]
        return n

    def close(self):
        self._raw.close()
        super().close()


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
    from ..timing import date_seconds

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
    """A CSV column's name as cfdesign uses it: stripped of white space (and of :data:`_INVISIBLE`),
    and ``Unnamed: i`` (pandas' name) when nothing is left.  The one rule for the header read as written and for pandas'
    frames: a trailing comma or a tab as a name was '' in one and 'Unnamed: 0' or a tab in the
    other, and its lookup raised KeyError (an internal error).  A ``hashed`` header (``# time,gyro``)
    loses the ``#`` of its first name."""
    name = str(name).strip().strip(_INVISIBLE).strip()
    return (name.lstrip("#").strip() if hashed and i == 0 else name) or f"Unnamed: {i}"


#: characters that an editor or a spreadsheet leaves around a name and that print as nothing (a
#: zero-width space after 'gyro' made it a column 'gyro\u200b' that printed as 'gyro ': missing)
_INVISIBLE = "\u200b\u200c\u200d\u2060\ufeff"


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
            except DataError:  # a row of a log separated by spaces short of cells (_RowCells)
                raise
            except (pd.errors.ParserError, UnicodeDecodeError, ValueError, OSError, *_unpack_errors()) as exc:
                raise _read_error(path, exc) from None
            yield _stripped(block, columns, hashed)


def _exact(pd) -> dict:
    """The option of ``read_csv`` that reads every number as the nearest double: pandas before 3.0
    read about a third of the shortest round-trip texts of random doubles an ulp off by default (32 to
    43 % of a million-row log's cells with pandas 2.3.3, by distribution; its ``round_trip`` parser is
    exact, at about twice the parse time; pandas 3 reads them exactly and deprecates the option)."""
    return {"float_precision": "round_trip"} if before_pandas_3(pd) else {}


def _parquet_names(schema) -> dict:
    """``{field: column}``: the columns of a Parquet file as cfdesign reads them.

    A frame saved by pandas keeps its index as a field: one with a name (``time``) is a column
    like the others; an unnamed one (``__index_level_0__``) is the time column ``time`` when it
    holds dates or durations and no column is named as a time column (the one rule of CSV logs and
    DataFrames, :func:`~cfdesign.logs.columns._time_name`: ``time``, ``t [ms]``, ``time_ms``; a frame
    indexed by a DatetimeIndex, as :func:`run_log` takes the index of a DataFrame), and is left out
    otherwise (row labels).  It was asked for by its field name and not found: an internal error."""
    pa = require_extra("pyarrow", NEEDS_PYARROW)

    index = {c for c in (schema.pandas_metadata or {}).get("index_columns", []) if isinstance(c, str)}
    unnamed = {f.name for f in schema if f.name in index and re.fullmatch(r"__index_level_\d+__", f.name)}
    timed = any(_time_name(f.name) for f in schema if f.name not in unnamed)
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
    pq = require_extra("pyarrow.parquet", NEEDS_PYARROW)

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
    The blank lines are looked for when a message first names a line (:meth:`__call__`).
    A Parquet file has no lines: :meth:`at` names its rows, counted from 1."""

    def __init__(self, first=2, path=None, kind="csv", sep=","):
        self.first, self.path, self.kind, self.sep = first, path, kind, sep
        self._after = None  # the rows before each blank line

    def at(self, row) -> str:
        """Where row ``row`` is, for a message: ``line N`` of a text log, ``row N`` of a Parquet log
        (rows counted from 1)."""
        return f"row {int(row) + 1}" if self.kind == "parquet" else f"line {self(row)}"

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
        return _Lines(kind=kind)
    fmt = _csv_format(path, kind)
    return _Lines(_first_row(fmt), path, kind, fmt.get("sep", ","))


def _first_row(fmt) -> int:
    """The file line of a CSV's first row, from its :func:`_csv_format`: after the comment lines,
    the header and a row of units."""
    return 2 + fmt.get("skiprows", 0) + ("_units" in fmt)


def _header(path) -> list:
    import io

    path = Path(path)
    kind = _kind(path)
    pd = _pandas(kind == "parquet")
    if kind == "parquet":
        pq = require_extra("pyarrow.parquet", NEEDS_PYARROW)

        try:
            return list(_parquet_names(pq.read_schema(path)).values())
        except (OSError, ValueError) as exc:
            raise DataError(f"cannot read {path}: {_first_line(exc)}") from None
    fmt = _csv_format(path, kind)
    try:  # the header line as written (pandas renames a second 'gyro' to 'gyro.1')
        with io.TextIOWrapper(_open_csv(path, kind), encoding=fmt.get("encoding", "utf-8-sig"), newline="",
                              errors="replace" if "encoding" in fmt else "strict") as fh:
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
        (naming its line; a Parquet log's row).
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
    return _numeric(read_log(path, wanted), wanted, path, _lines(path).at, time=time, time_scale=scale)
