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

The parts, each looking only at those below it: :mod:`~cfdesign.logs.fleet` (many logs on Dask)
uses :mod:`~cfdesign.logs.run` (one log: the run block by block, restarts), which uses
:mod:`~cfdesign.logs.join` (a log in one file per sensor, merged by time), :mod:`~cfdesign.logs.plot`,
:mod:`~cfdesign.logs.ticks` (the first pass: rows on ticks, the
schedule locked to the arrivals), :mod:`~cfdesign.logs.read` (CSV, compressed or not, Parquet,
a pipe), :mod:`~cfdesign.logs.write` (the estimate files) and :mod:`~cfdesign.logs.result`; all
use :mod:`~cfdesign.logs.columns` (column names, time units, cells to numbers).
"""

from __future__ import annotations

from . import columns, fleet, run
from .columns import MISSING as MISSING
from .fleet import run_logs
from .plot import plot_log
from .read import COMMENT_LINES as COMMENT_LINES
from .read import COMPRESSIONS as COMPRESSIONS
from .read import WHITESPACE as WHITESPACE
from .read import read_columns, read_log
from .result import LogResult
from .run import ONE_PASS_BYTES as ONE_PASS_BYTES
from .run import RESTART_GATE as RESTART_GATE
from .run import run_log
from .ticks import RATE_SAMPLE as RATE_SAMPLE

__all__ = ["LogResult", "run_log", "run_logs", "read_log", "read_columns", "plot_log", "TIME_COLUMNS", "TIME_UNITS",
           "BLOCK_ROWS", "INTERNAL"]

# The constants are defined in the part that reads them (set BLOCK_ROWS, ONE_PASS_BYTES ... there,
# cfdesign.logs.run.BLOCK_ROWS, for a change to take effect); these names give their values.
#: column names taken as the time (seconds) when none is given
TIME_COLUMNS = columns.TIME_COLUMNS
#: units a numeric time column may be in (``time_unit``, ``cfdesign run --time-unit``): seconds each
TIME_UNITS = columns.TIME_UNITS
#: rows read, run and written at a time (and ticks run at a time across a gap without rows); the
#: value of ``cfdesign.logs.run.BLOCK_ROWS``, which the run reads
BLOCK_ROWS = run.BLOCK_ROWS
#: how the summary of :func:`run_logs` begins the error of a log that met a fault of cfdesign, not of the log
INTERNAL = fleet.INTERNAL
