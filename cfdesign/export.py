"""Gain tables as CSV (one row per phase and state); logs are read and written by
:mod:`cfdesign.logs`.  Written atomically (:mod:`cfdesign.files`)."""

from __future__ import annotations

import csv
from pathlib import Path

from .files import open_atomic
from .gains import require_table

__all__ = ["write_gain_csv"]


def _atomic_write(path, rows):
    with open_atomic(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return Path(path)


def write_gain_csv(table, path) -> Path:
    """Write a table's gains as CSV, atomically.

    One row per (phase, state): ``phase, state, <one column per measurement sensor>``.  Values
    use ``repr`` precision; the gain form and sample time are in the JSON table.

    Parameters
    ----------
    table : GainTable
        The gain table to write.
    path : str or Path
        CSV file to write.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    OutputError
        The file cannot be written; an existing file is left as it was.
    """
    require_table(table, "write_gain_csv")
    rows = [["phase", "state", *table.sensor_names("measurement")]]
    for k, K in enumerate(table.K):
        rows += [[k, i, *(repr(float(v)) for v in K[i])] for i in range(K.shape[0])]
    return _atomic_write(path, rows)
