"""CSV in and out: gain tables as CSV, sensor logs in, estimates out.

Nothing partial is ever written: files are written to a temporary name beside the target
and renamed into place once complete.  CSV text is parsed as numbers only.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .errors import DataError
from .files import open_atomic

__all__ = ["write_gain_csv", "read_readings", "write_estimates", "DataError"]


def _atomic_write(path, rows):
    with open_atomic(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return Path(path)


def write_gain_csv(table, path) -> Path:
    """Gains as CSV, one row per (phase, state): ``phase, state, <one column per measurement sensor>``.

    Values use ``repr`` precision; the gain form and sample time are in the JSON table.
    """
    rows = [["phase", "state", *table.sensor_names("measurement")]]
    for k, K in enumerate(table.K):
        rows += [[k, i, *(repr(float(v)) for v in K[i])] for i in range(K.shape[0])]
    return _atomic_write(path, rows)


def read_readings(path, sensors) -> tuple:
    """``(time or None, {sensor: array})`` from a CSV whose header names the sensors.

    An empty cell is a missing reading (NaN).  Errors name the line and the column.
    """
    path = Path(path)
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise DataError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"{path}: not a readable CSV file: {exc}") from None
    if not rows:
        raise DataError(f"{path}: empty file (expected a header with the columns {', '.join(sensors)})")
    header = [h.strip() for h in rows[0]]
    _check_header(path, header, sensors)
    values = np.empty((len(rows) - 1, len(header)))
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise DataError(f"{path} line {line}: {len(row)} fields, the header has {len(header)}")
        for j, cell in enumerate(row):
            values[line - 2, j] = _number(cell, path, line, header[j])
    columns = {h: values[:, j] for j, h in enumerate(header)}
    return columns.get("time"), {s: columns[s] for s in sensors}


def _check_header(path, header, sensors):
    missing = [s for s in sensors if s not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {', '.join(header)})")
    extra = [h for h in header if h not in sensors and h != "time"]
    if extra:
        raise DataError(f"{path}: unknown column(s) {', '.join(extra)}; the table reads {', '.join(sensors)} "
                        "(plus an optional time)")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}: duplicate column(s) {', '.join(dup)}")


def _number(cell, path, line, column):
    cell = cell.strip()
    if not cell:
        return math.nan
    try:
        return float(cell)
    except ValueError:
        raise DataError(f"{path} line {line}: column {column!r} is not a number: {cell!r}") from None


def write_estimates(path, time, estimate, states) -> Path:
    """``[time,] estimate, state_0, ..., state_{n-1}`` per sample, full precision."""
    head = (["time"] if time is not None else []) + ["estimate"] + [f"state_{i}" for i in range(states.shape[1])]
    cols = ([time] if time is not None else []) + [estimate] + list(states.T)
    rows = [head] + [[repr(float(v)) for v in row] for row in zip(*cols, strict=True)]
    return _atomic_write(path, rows)
