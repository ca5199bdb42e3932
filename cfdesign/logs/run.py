"""Running a gain table on one log: :func:`~cfdesign.logs.run_log`, its checks, and the filter
run block by block (``_Runner``: segments, pauses, restarts)."""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import numbers
import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import CfdesignError, DataError, OutputError
from ..files import check_distinct, is_dir, not_a_device
from ..gains import require_table
from ..linear import wrap
from .columns import (
    _UNIT_NAMES,
    TIME_UNITS,
    _first_line,
    _named_unit,
    _numeric,
    _pandas,
    _time_name,
    _time_unit,
    _unit,
)
from .consistency import Innovations
from .join import _Join, joined_header
from .plot import plot_log
from .read import (
    COMPRESSIONS,
    _columns,
    _header,
    _kind,
    _Lines,
    _lines,
    _pipe,
    _row_units,
    _spooled,
    _tail_note,
    _units_note,
    read_log,
    time_column,
)
from .result import LogResult
from .ticks import _arrow_types, _first_direct, _lock, _Pass, _startup_ticks, _unique
from .write import _estimates, _rms, _Writer

#: rows read, run and written at a time (and ticks run at a time across a gap without rows)
BLOCK_ROWS = 1_000_000
#: a file smaller than this is read once; a larger one twice (arrivals first, then in blocks)
ONE_PASS_BYTES = 200_000_000


def run_log(table, data, *, output=None, time=None, mapping=None, reference=None, std=False,
            prediction=False, plot=None, start="reading", block_rows=None, progress=False,
            source=None, time_unit=None, join=None) -> LogResult:
    """Run a discrete gain table on a timestamped log (module docstring).

    Parameters
    ----------
    table : GainTable
        The gain table the log is run through.
    data : str, Path, pandas.DataFrame or dict
        A CSV or Parquet file, a DataFrame, or a dict of columns (``{name: array}``, as
        :meth:`Runtime.run <cfdesign.runtime.Runtime.run>` takes).
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
        A progress bar on stderr for logs longer than a block, when stderr is a terminal.
    source : str, optional
        The log's name in messages.
    time_unit : {'s', 'ms', 'us', 'ns'}, optional
        The unit of a numeric time column (:data:`TIME_UNITS`): ``'ns'`` for the integer
        nanoseconds of a ROS ``rostopic echo -p`` export (``%time``).  Default: the unit the
        column's name gives (``time [ms]``, ``t (us)``), else seconds.  Dates and durations are
        read as they are.  It applies to every file of ``join`` (each file's unit is else its own).
    join : str, Path or list of them, optional
        Files of the same log's other sensors (one file per sensor or topic: PX4's ``ulog2csv``,
        ROS's ``rostopic echo -p``): the log is the union of the rows of ``data`` and of these by
        time, as ``pandas.concat`` sorted stably by time gives it (on equal times the rows of
        ``data`` first, then the files in this order).  Each has its own time column (found as
        ``data``'s, with ``time``) and unit; only the columns the run uses (the sensors', also by
        ``mapping``, and the references') are taken from them.  They are read whole (the slow
        sensors); ``data`` streams in blocks as alone.

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
        positive whole number, a ``mapping`` that is not a dict, a ``reference`` that is not
        text or a list of it, or ``data`` of another type.
    DataError
        A dict's columns of different lengths, a missing or non-numeric column or bad times
        (naming the line; a Parquet log's row), a base rate more than 1 % off the table's, an
        empty log; of a joined file as well (naming it), a column the run uses in two files, times
        that do not overlap the log's.
    OutputError
        The output cannot be written; nothing is left half-written.
    """
    require_table(table, "run_log")
    if table.domain != "z":
        from ..runtime.filter import DISCRETE_HINT

        raise CfdesignError(f"{table.name} is a continuous-time table; logs run discrete tables ({DISCRETE_HINT})")
    if block_rows is not None and (isinstance(block_rows, bool) or not isinstance(block_rows, numbers.Integral)
                                   or block_rows < 1):  # -5 read no row ('a header but no rows'), True one a block
        raise CfdesignError(f"block_rows must be a positive whole number of rows, got {block_rows!r}")
    block_rows = int(block_rows or BLOCK_ROWS)
    frame, source = _source(data, source, time)
    join = _join_paths(join)
    spooled = [p for p in join if _pipe(p)]
    if spooled:  # a pipe is read more than once (its header, then its rows): into a file first
        with contextlib.ExitStack() as stack:
            join = [stack.enter_context(_spooled(p, str(p))) if p in spooled else p for p in join]
            return run_log(table, data, output=output, time=time, mapping=mapping, reference=reference, std=std,
                           prediction=prediction, plot=plot, start=start, block_rows=block_rows, progress=progress,
                           source=source, time_unit=time_unit, join=join)
    if frame is None and not_a_device(data):  # /dev/zero: an endless line
        raise DataError(f"cannot read {source}: {not_a_device(data)}")
    if frame is None and _pipe(data):  # read once into a file: a log is read more than once
        with _spooled(data, source) as path:
            return run_log(table, path, output=output, time=time, mapping=mapping, reference=reference, std=std,
                           prediction=prediction, plot=plot, start=start, block_rows=block_rows, progress=progress,
                           source=source, time_unit=time_unit, join=join)
    if frame is None and output is not None and _same_file(data, output):
        raise DataError(f"{source}: the output {output} is the log itself; it would be replaced by the estimates")
    joins = {f"joined file {i + 1}": p for i, p in enumerate(join)}
    check_distinct({"the log": data if frame is None else None, **joins, "the output": output, "the plot": plot},
                   inputs=("the log", *joins))
    _pandas(output is not None and Path(output).suffix.lower() in (".parquet", ".pq"))  # before the log is read
    if output is not None and Path(output).suffix.lower() == ".zip":
        raise OutputError(f"cannot write {output}: estimates are written as CSV (.csv, or compressed: .csv.gz, "
                          ".csv.bz2, .csv.xz) or Parquet, not a zip archive")
    header = list(frame.columns) if frame is not None else _header(data)
    header, used, listing = joined_header(table, header, source, join, time=time, mapping=mapping,
                                          reference=reference) if join else (header, {}, None)
    lines = _Lines() if frame is not None else _lines(data)
    units = None if frame is not None else _row_units(data)
    # of several files, the option is the unit of those whose time's name gives none (a ROS %time in ns
    # beside PX4's timestamp in us)
    named = join and _time_unit(source, None, time_unit) and _named_unit(time or time_column(header), units)
    cols = _columns(table, header, source, time, mapping, reference, None if named else time_unit, lines, units,
                    listing, {c: u for p in join for c, u in _row_units(p).items()} if join else None)
    _check_output_names(table, cols, std, source)
    joined = None
    if join:
        if cols.time is None:
            raise DataError(f"{source}: no time column ('time', 't' or 'timestamp', --time COLUMN): the rows of "
                            "--join files are placed among the log's by their times")
        joined = _Join(table, cols, source, lines, join, used, time, time_unit)
        cols = dataclasses.replace(cols, lines=joined)
    blocks, whole = _blocks(data, frame, cols, block_rows, joined)
    parquet = output is not None and Path(output).suffix.lower() in (".parquet", ".pq")
    lock, n_rows, types, (grid, rephased, first) = _lock(table, blocks, cols, source, types=parquet and whole is None)
    if n_rows == 0:
        raise DataError(f"{source}: the log has a header but no rows")
    if start not in ("reading", "zero"):
        raise CfdesignError(f"start must be 'reading' or 'zero', got {start!r}")
    if plot is not None:  # before any work: a plot that cannot be written stops nothing half-way
        _check_plot_target(plot)
    startup = _startup_ticks(table)
    runner = _Runner(table, lock, "prior" if prediction else None, start == "reading",
                     covariances=bool(std or cols.references), first_reading=first, startup=startup)
    if parquet and whole is not None:
        types = _arrow_types(whole[cols.extra])
    writer = _Writer(output, keep=output is None or plot is not None, types=types)
    place = _Pass(table, cols, source, grid=grid, rephased=rephased)  # ticks where the first pass put them
    far = {}  # sensor -> [readings far from the estimate, readings] (_far)

    def run_rows(block, values, ticks):
        if len(ticks):
            readings = {s: values[c] for s, c in cols.sensors.items()}
            states, _, stds = runner.run(ticks, readings)
            _check_bounded(table, states, ticks, source)
            _far(table, readings, states, stds, far)
            writer.write(_estimates(table, block, cols, values, states, stds, std), runner.settled(ticks, startup),
                         runner.steady(ticks, startup))
            bar.update(len(ticks))

    with _progress(n_rows, progress) as bar, writer:
        pending = None  # the rows of a block's last tick: the next block may hold more rows of that tick
        for block in blocks():
            values = _numeric(block, cols.numeric, source, lambda i, start=place.rows: cols.lines.at(start + i),
                              cols.time, cols.time_scale, cols.scales)
            ticks = place.ticks(values)
            if pending is not None:
                pd = _pandas()
                block = pd.concat([pending[0], block])
                values = {k: np.concatenate([pending[1][k], v]) for k, v in values.items()}
                ticks = np.concatenate([pending[2], ticks])
            cut = int(np.searchsorted(ticks, ticks[-1])) if len(ticks) else 0
            held = runner.held_from(ticks[:cut], {s: values[c][:cut] for s, c in cols.sensors.items()})
            # rows after a pause wait for the reading that moves them (those before the log's first, a million)
            if len(ticks) - held <= (max(block_rows, BLOCK_ROWS) if runner.late_start else block_rows):
                cut = held
            pending = (block.iloc[cut:], {k: v[cut:] for k, v in values.items()}, ticks[cut:])
            run_rows(block.iloc[:cut], {k: v[:cut] for k, v in values.items()}, ticks[:cut])
        if pending is not None:
            run_rows(*pending)
        est = writer.frame()
        if plot is not None:  # inside the writer: written with the estimates, all or nothing
            from ..plot import figure_bytes

            writer.attach(plot, figure_bytes(plot_log(table, est, cols.references, cols.time, cols.time_unit,
                                                      restarts=runner.restarts), plot))
    if place.early:
        _merge(runner.counts, {"before_start": place.early})
    notes = (_units_note(data, source) + _tail_note(data, source) if frame is None else []) + _time_note(
        cols, table, lock.rate_hz)
    notes += joined.notes() if joined is not None else []
    notes += cols.notes
    notes += lock.notes + _far_note(far, table)
    if runner.innovations is not None:
        notes += runner.innovations.notes(table, _unit_slips, named=_far_names(far))
    notes += [n for n in [runner.start_note(table.sample_time_s), runner.pause_note(table.sample_time_s)] if n]
    settled, predicted = writer.settled()
    notes += _model_note(*writer.steady(), writer.steady_rows, startup)
    return LogResult(est if output is None else None, n_rows, _rms(writer.errors), runner.counts, notes,
                     Path(output) if output else None, source, settled, predicted,
                     startup * table.sample_time_s if cols.references else math.nan, writer.settled_rows,
                     len(runner.pauses), len(runner.restarts) - (runner.start_tick is not None),
                     *_consistency(runner.innovations))


def _consistency(innovations) -> tuple:
    """``(consistency, consistency_rms, noise_estimate)`` of :class:`LogResult` from the run's
    :class:`~cfdesign.logs.consistency.Innovations` (empty without a noise model)."""
    if innovations is None:
        return {}, {}, {}
    return innovations.ratios(), innovations.rms_ratios(), innovations.noise()


def _check_bounded(table, states, ticks, source):
    """An estimate that leaves :data:`~cfdesign.runtime.filter.STATE_LIMIT` (or overflows to
    inf or NaN) is a filter that diverges, not an estimate: an unstable table (an edited gain
    or model) wrote empty estimate columns with exit status 0."""
    from ..runtime.filter import STATE_LIMIT

    bad = ~np.all(np.abs(states) <= STATE_LIMIT, axis=1)
    if bad.any():
        tick = int(ticks[np.argmax(bad)])
        raise DataError(f"{source}: the estimates of {table.name!r} diverge (beyond {STATE_LIMIT:g} at tick {tick}): "
                        "the table's filter is not stable (cfdesign verify names the check)")


#: a reading this many predicted standard deviations from the estimate disagrees with it; a note
#: names a sensor when most of its readings (FAR_SHARE) do
FAR_SIGMA, FAR_SHARE = 5.0, 0.5
#: a settled RMS error against a reference this many times the predicted std is no spread of the
#: design's noise model (over a fifth of a start-up's length of settled rows at least): a note says so
MODEL_RATIO = 3.0


def _far(table, readings, states, stds, counts):
    """Count, per measurement sensor, its readings and those more than :data:`FAR_SIGMA`
    predicted standard deviations (its noise and the estimate's, ``H`` of ``stds``) from the
    estimate ``H x`` of their row, and sum their squared distances and predicted variances, into
    ``counts`` (``{sensor: [far, readings, squares, variances]}``): a column in degrees for
    radians, in mrad/s, of another sign or sensor ran with exit status 0 (a compass in degrees
    moved the 100/10/1 Hz heading 0.004 rad, all in degrees 3.1 rad)."""
    if table.R is None:
        return
    e0 = np.eye(table.F.shape[0])[0]
    for s in table.measurements:
        z, h = readings[s.name], table.H[s.index]
        ok = np.isfinite(z)
        if not ok.any():
            continue
        r = z[ok] - states[ok] @ h
        if table.wrap_angle and np.array_equal(h, e0):
            r = wrap(r)
        var = table.R[s.index, s.index] + (stds[ok] ** 2) @ (h ** 2)
        c = counts.setdefault(s.name, [0, 0, 0.0, 0.0])
        c[0] += int(np.sum(r ** 2 > FAR_SIGMA ** 2 * var))
        c[1] += int(ok.sum())
        c[2] += float(np.sum(r ** 2))
        c[3] += float(np.sum(var))


def _far_names(counts) -> set:
    """The sensors :func:`_far_note` names."""
    return {name for name, (far, n, _, _) in counts.items() if n and far > FAR_SHARE * n}


def _far_note(counts, table) -> list:
    """The notes of :func:`_far`'s counts: the sensors most of whose readings disagree, with
    their RMS distance from the estimate against the one predicted, and the unit mix-ups likely
    for what each reads (:func:`_unit_slips`)."""
    return [f"{name}: {far} of its {n} readings lie more than {FAR_SIGMA:g} predicted standard deviations from "
            f"the estimate (RMS {math.sqrt(sq / n):.3g}, {math.sqrt(sq / var):.3g} times the {math.sqrt(var / n):.3g} "
            f"predicted): its column, or an input's, may be in other units than the table's "
            f"({_unit_slips(table, name)}), of another sign or of another sensor, or noisier than the design file says "
            f"(an error that is not white counts: an accelerometer's angle while the vehicle accelerates; see the "
            f"noise guide)" for name, (far, n, sq, var) in counts.items() if n and far > FAR_SHARE * n]


def _unit_slips(table, name) -> str:
    """The unit mix-ups a note of :func:`_far_note` names for the measurement sensor ``name``, by the
    unit of what it reads (:meth:`~cfdesign.gains.GainTable.sensor_units`): a GPS in degrees of
    latitude and longitude fed as metres ran 1,100 times its predicted error with a note that spoke
    of radians."""
    unit = table.sensor_units()[name]
    slips = {"m": "degrees of latitude or longitude for metres, feet, mm", "m/s": "km/h, knots, ft/s for m/s",
             "m/s²": "g for m/s²"}
    if unit in slips:
        return slips[unit]
    return "degrees for radians, mrad/s" if unit.startswith("rad") or not unit else f"another unit for {unit}"


def _model_note(settled, predicted, rows, startup) -> list:
    """A note per reference whose RMS error after the start-up is more than :data:`MODEL_RATIO`
    times the predicted std, over the rows ``settled`` after the start-up of the log and of every
    pause (one the filter carried over as well: the error the held inputs left fades over a start-up,
    and the predicted std leaves it out), at least a fifth of ``startup`` of them (about the
    error's correlation time: a log that follows the model is that far off in 0.3 % of such
    stretches): the log does not follow the design's noise model (BROAD's slow translation, a
    pitch designed with the accelerometer's noise at rest: 0.0276 rad against a predicted
    0.000175 rad, noted only as readings in other units)."""
    if rows < max(startup / 5, 1):
        return []
    return [f"the RMS error of {state} after the start-up is {rms / predicted[state]:.3g} times the predicted "
            f"std: the log does not follow the design file's noise model, which the predicted figures take as "
            f"given (a sensor noisier than its figure or whose error is not white, in other units, of another "
            f"sign)" for state, rms in settled.items()
            if math.isfinite(rms) and predicted.get(state, 0) > 0 and rms > MODEL_RATIO * predicted[state]]


def _same_file(a, b) -> bool:
    """``a`` and ``b`` name one existing file (through links or relative paths as well)."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one does not exist (yet): not the same file
        return False


def _check_plot_target(plot):
    from ..plot import FIGURE_FORMATS

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
    and not a column has it made its first column; a dict of columns (what ``Runtime.run`` takes)
    is made a DataFrame; anything else but a path is refused naming its type."""
    pd = _pandas()
    if isinstance(data, Mapping):
        try:
            data = pd.DataFrame({str(k): v for k, v in data.items()})
        except (ValueError, TypeError) as exc:  # columns of different lengths, a scalar column
            raise DataError(f"{source or 'log'}: a log given as a dict needs columns of one length "
                            f"({_first_line(exc)})") from None
    elif not isinstance(data, (str, bytes, os.PathLike, pd.DataFrame)):
        raise CfdesignError(f"a log is a path, a pandas DataFrame or a dict of columns, got {type(data).__name__}")
    if isinstance(data, pd.DataFrame):
        index = data.index
        named = index.name is not None and _time_name(index.name)
        if time is None and not any(_time_name(c) for c in data.columns) and (
                named or isinstance(index, pd.DatetimeIndex)):
            data = data.reset_index(names=str(index.name) if index.name is not None else "time")
        if any(not isinstance(c, str) or c != c.strip() for c in data.columns):  # read as a file's header is
            data = data.rename(columns=lambda c: str(c).strip())  # (' gyro [deg/s]' was a raw KeyError)
        return data, source or "log"
    return None, source or str(data)


#: without a time column, every measured sensor (two at least) arriving this share or more off its rate by one
#: factor (within ``RATE_SHARE_TOL`` of it) says the rows are not one tick apart (a 50 Hz log through a 100 Hz table:
#: 0.17 rad RMS off in heading, its notes naming each sensor's rate alone)
RATE_SHARE_OFF, RATE_SHARE_TOL = 0.2, 0.05


def _row_rate_note(table, rates) -> str:
    """What the measured sensors' arrival ``rates`` (``{sensor: Hz}``, :class:`~cfdesign.timing.Lock`'s) say of a
    log without a time column: '' unless every one (two at least) arrives one factor off its rate in ``table``."""
    ratios = [rates[s.name] / s.rate_hz for s in table.measurements if s.name in rates]
    if len(ratios) < 2 or len(ratios) < len(table.measurements):
        return ""
    r = float(np.median(ratios))
    if abs(r - 1.0) < RATE_SHARE_OFF or any(abs(x / r - 1.0) > RATE_SHARE_TOL for x in ratios):
        return ""
    f = 1.0 / table.sample_time_s
    return (f"; every sensor measured arrives {r:.3g} times as often as the table reads it: the rows are probably "
            f"{r:.3g} ticks apart (a log at {f / r:.4g} Hz through a {f:.4g} Hz table), so the run needs its "
            "time column or rows at the table's rate")


def _time_note(cols, table, rates) -> list:
    """A note when the log has no time column: its rows are taken one a tick (and, where every measured sensor
    arrives one factor off its rate, :func:`_row_rate_note` says the rows are another rate's)."""
    if cols.time is not None:
        return []
    like = [c for c in cols.extra if any(w in c.lower() for w in ("time", "stamp", "sec")) or c.lower() == "ts"
            or _unit(c)[1] in TIME_UNITS or c.lower() in _UNIT_NAMES]  # 'elapsed_ms', an Arduino's 'millis'
    import shlex

    # a name that is only a unit, or ends in one written in CamelCase (ArduPilot's 'TimeUS'): not read from it
    unit = (_UNIT_NAMES.get(like[0].lower()) or _camel_unit(like[0])) if like else None
    return ["the log has no time column ('time', 't' or 'timestamp'): every row is taken as one base tick"
            + (f" (column {like[0]!r} looks like a time: --time {shlex.quote(like[0])}"
               + (f" --time-unit {unit})" if unit not in (None, "s") else ")") if like else " (--time COLUMN)")
            + _row_rate_note(table, rates)]


def _camel_unit(name):
    """The unit of time a CamelCase name ends in (``TimeUS``, ``timeMs``: ``'us'``, ``'ms'``), else None;
    ``timeS`` is not taken (a plural)."""
    m = re.search(r"[a-z0-9]([A-Z][A-Za-z]*)$", str(name))
    unit = _UNIT_NAMES.get(m.group(1).lower()) if m else None
    return unit if unit != "s" else None


def _blocks(data, frame, cols, rows, joined=None):
    """``(blocks, whole)``: a function giving the log's blocks each time it is called (two passes
    need two), and the whole log when it is in memory (a DataFrame, or a file read once), else None.
    With ``joined`` (a :class:`~cfdesign.logs.join._Join`), its files' rows merged in by time."""
    read = [c for c in cols.read if joined is None or c not in joined.columns]
    if frame is not None:
        whole = frame if joined is None else frame[read]
    else:
        path = Path(data)
        packed = 10 if _kind(path) in COMPRESSIONS.values() else 1  # a compressed CSV unpacks to several times its size
        if packed * os.path.getsize(path) >= ONE_PASS_BYTES:
            if joined is not None:  # read in eighths of a block, gathered into blocks with the joined rows
                return (lambda: joined.blocks(read_log(path, read, chunksize=max(rows // 8, 1)), rows)), None
            return (lambda: read_log(path, cols.read, chunksize=rows)), None
        whole = read_log(path, read)
    if joined is not None:
        whole = _pandas().concat(list(joined.blocks([whole], len(whole))))
    return (lambda: (whole.iloc[i:i + rows] for i in range(0, max(len(whole), 1), rows))), whole


def _join_paths(join) -> list:
    """The files of ``run_log``'s ``join`` as a list."""
    if join is None:
        return []
    items = [join] if isinstance(join, (str, os.PathLike)) else join
    if not isinstance(items, (list, tuple)) or not all(isinstance(p, (str, os.PathLike)) for p in items):
        raise CfdesignError(f"join must be a file or a list of files (str or Path), got {join!r:.80}")
    for p in items:
        if not_a_device(p):
            raise DataError(f"cannot read {p}: {not_a_device(p)}")
    return list(items)


def _check_output_names(table, cols, std, source):
    """A column of the log passed through must not take the name of a column the estimates add."""
    made = [*table.states, *(f"{s}_std" for s in table.states if std or cols.references),
            *(f"{s}_reference" for s in cols.references)]
    clash = [c for c in [*([cols.time] if cols.time else []), *cols.extra] if c in made]
    if clash:
        raise DataError(f"{source}: column {clash[0]!r} has the name of a column of the estimates "
                        f"({', '.join(made)}); rename it in the log")


#: a pause of the logger restarts state 0 when the first direct reading after it is more than
#: this many standard deviations of the innovation from the state carried over the pause
RESTART_GATE = 3.0


class _Runner:
    """Runs the blocks of ticks through the table (or its re-locked variants), state carried."""

    def __init__(self, table, lock, output, from_reading=True, covariances=False, first_reading=None, startup=0):
        from ..runtime import Runtime
        from ..timing import PAUSE_TICKS

        self.table, self.lock, self.output, self.from_reading = table, lock, output, from_reading
        # (tick, variance, sensor, value) of the log's first direct reading (:func:`_first_direct`): the start
        # when it lies in a later block than the first
        self.first_reading = first_reading
        self.covariances = covariances  # standard deviations that follow missed readings
        self.P_missed = None
        # a table with a model: missed readings are bridged by the Kalman filter over the arrivals
        self.kalman = table.has_kalman_gains and table.Q is not None and table.R is not None
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
        # the log's first direct reading comes after a pause's worth of ticks (PAUSE_TICKS): the ticks
        # before it move onto it, as after a pause (nearer, it is the start, a few ticks' turn off)
        self.late_start = bool(from_reading and first_reading and first_reading[0] > PAUSE_TICKS)
        self.start_tick = None  # and the tick of that reading, once run
        self.startup = startup  # ticks of a start-up: the innovations of those after one are checked
        self.innovations = Innovations(table) if table.R is not None else None
        self.before = None  # (output state, held inputs) of the tick before next_tick (:meth:`_innovate`)

    def _runtime(self, seg):
        key = (seg.rotation, seg.offsets) if seg.offsets else ("rotation",)
        if key not in self.runtimes:
            table = self.table
            if seg.offsets:
                from ..designer import gains_for_schedule

                table = gains_for_schedule(self.table, self.table.schedule.shifted(dict(seg.offsets)))
            # the log path places the phase itself (its lock, per stretch): the runtime neither relocks nor warns
            self.runtimes[key] = self._Runtime(table, output=self.output, lock=False, warn=False)
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
            self.pending = self.late_start
        parts, shifts = [], []
        restarts, ends = self._restart_ticks(dense, first)
        at = {r: (i, e) for i, (e, r) in enumerate(restarts)}
        cuts = [first, *sorted({*ends, *at}), last + 1]
        for k, (a, b) in enumerate(itertools.pairwise(cuts)):
            if k and a in ends:
                self._forget()
            moved = None
            if k and a in at:
                i, e = at[a]
                start = i == 0 and self.late_start  # the log's first direct reading: no gate
                moved = self._restart(dense, a - first, gate=not start)
            if moved is not None:
                shifts.append((max(e, first), a, *moved))
                # the start-up after a pause runs from its end; the log's, from that first reading
                self.restarts.append(a if start else e)
                if start:
                    self.late_start, self.start_tick = False, a
            if a < b:
                part = {name: v[a - first:b - first] for name, v in dense.items()}
                parts.append(self._run_arrivals(part, a, b - 1) if self.lock.varying
                             else self._run_segments(part, a, b - 1))
        out, phases, stds, hph = (np.concatenate(arrays) for arrays in zip(*parts, strict=True))
        self._innovate(dense, out, hph, first)
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

    def _innovate(self, dense, out, hph, first):
        """Add the innovations of ticks ``first..`` (``dense``'s readings, ``out`` the output states,
        ``hph`` the prior ``H P H'`` of the gains that ran, NaN where they use no reading) after the
        start-up of the log and of every pause (:meth:`steady`) to :attr:`innovations`.  The
        prediction of a tick is the output state of the one before moved on by the model with its
        held inputs, ``F x+ + B u`` (what every gain form runs), or the output itself when that is
        the prediction; the log's first tick has none."""
        from ..runtime.filter import usable

        table, N = self.table, len(out)
        before = self.before
        prior = before[1] if before is not None else np.zeros(len(table.inputs))  # the inputs held before
        if self.innovations is None:
            self.before = (out[-1].copy(), self._held(dense, np.array([N - 1]), prior)[0])
            return
        ms = table.measurements
        read = np.zeros(N, dtype=bool)
        for s in ms:
            read |= ~np.isnan(dense[s.name])
        at = np.flatnonzero(read)
        y = np.column_stack([dense[s.name][at] for s in ms])
        used = usable(y) & np.isfinite(hph[at])
        keep = used.any(axis=1) & self.steady(first + at, self.startup)
        if self.output != "prior" and before is None:
            keep &= at > 0
        at, y, used = at[keep], y[keep], used[keep]
        u_in = self._held(dense, np.append(at - 1, N - 1), prior)
        self.before = (out[-1].copy(), u_in[-1])
        if self.output == "prior":
            x = out[at]
        else:
            x_out, u_in = out[at - 1], u_in[:-1]
            if at.size and at[0] == 0:
                x_out[0], u_in[0] = before
            x = x_out @ np.asarray(table.F, dtype=float).T + u_in @ np.asarray(table.B, dtype=float).T
        nu = y - x @ np.asarray(table.H, dtype=float).T
        for i, s in enumerate(ms):
            if table.wrap_angle and s.order == 0:
                nu[:, i] = wrap(nu[:, i])
        nu[~used] = 0.0
        v = np.where(used, hph[at], 0.0)
        self.innovations.add(nu, v + np.diag(np.asarray(table.R, dtype=float)), v, used)

    def _held(self, dense, at, prior):
        """``(len(at), p)``: the inputs of ``dense`` held as the runtime holds them (a missing or
        rejected one is its last usable value; ``prior`` those held at the tick before ``dense``) at
        the indices ``at`` (-1: that tick before)."""
        from ..runtime.filter import usable

        ins, out = self.table.inputs, np.empty((len(at), len(self.table.inputs)))
        for j, s in enumerate(ins):
            col = dense[s.name]
            out[:, j] = col[np.maximum(at, 0)]
            out[at < 0, j] = prior[j]
            if usable(out[at >= 0, j]).all():  # each its own last usable value
                continue
            good = usable(col)
            last = np.maximum.accumulate(np.where(good, np.arange(len(col)), -1))[np.maximum(at, 0)]
            last[at < 0] = -1
            out[:, j] = np.where(last >= 0, col[np.maximum(last, 0)], prior[j])
        return out

    def settled(self, ticks, startup):
        """Whether each of ``ticks`` is after the start-up (``startup`` ticks) of the log and of the
        restart after every pause so far."""
        return _after(ticks, startup, self.restarts)

    def steady(self, ticks, startup):
        """:meth:`settled`, and also after the start-up that follows every pause so far, restarted or
        carried over (the rows whose error the predicted std describes)."""
        return _after(ticks, startup, [*self.restarts, *(s + n for s, n in self.pauses)])

    def pause_note(self, dt):
        """One line on the pauses, or None."""
        from ..timing import PAUSE_TICKS

        if not self.pauses:
            return None
        start, longest = max(self.pauses, key=lambda p: p[1])
        return (f"the inputs have no reading for more than {PAUSE_TICKS} ticks {len(self.pauses)} time"
                f"{'s' * (len(self.pauses) > 1)} (a logger paused), the longest {longest * dt:.3g} s from "
                f"{start * dt:.6g} s: {self.table.states[0]} started again from the first direct reading after "
                f"{len(self.restarts) - (self.start_tick is not None)} of them (where it disagreed with the state "
                f"carried over the pause by more than {RESTART_GATE:g} sigma), each start-up shaded and left out of "
                f"the settled RMS")

    def start_note(self, dt):
        """One line on a first direct reading more than a pause after the log's start, or None."""
        if self.start_tick is None:
            return None
        name = self.table.states[0]
        return (f"no sensor reads {name} before {self.start_tick * dt:.6g} s: {name} there is that first "
                f"reading moved back by the inputs (a drift of theirs is not in its predicted std), and the "
                f"start-up runs from it")

    def held_from(self, ticks, readings) -> int:
        """The first of rows at ``ticks`` (ascending, the next to run) whose estimates are not known
        until a later block: those from the end of a pause (:meth:`_restart_ticks`) on when no direct
        reading follows it among them, as that reading may move them (:meth:`_restart`); else
        ``len(ticks)``.  (Rows written before the reading came in the next block stayed where the
        held inputs took them: 0.69 rad off, where one block moved them.)"""
        from ..runtime.filter import usable
        from ..timing import PAUSE_TICKS

        inputs, direct, n = self.table.inputs, self._direct(), len(ticks)
        if not (inputs and direct and n):
            return n
        if self.late_start and ticks[-1] < self.first_reading[0]:  # the log's first direct reading moves them
            return 0
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

    def _restart_ticks(self, dense, first) -> tuple:
        """Ticks (ascending) of the direct readings that start state 0 again: the first one at or
        after the end of each pause (more than :data:`~cfdesign.timing.PAUSE_TICKS` ticks without
        a reading of any input sensor: the logger stopped, the vehicle moved on, and what it did
        meanwhile is unknown), pauses counted in :attr:`pauses`, as ``(pause's end, reading)``; and
        the ticks where a pause ends (:meth:`_forget`)."""
        from ..runtime.filter import usable
        from ..timing import PAUSE_TICKS

        inputs, direct = self.table.inputs, self._direct()
        if not inputs or not direct:
            return [], set()
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
        return [(first + e, first + r) for e, r in out], {first + int(e) for e in ends}

    def _restart(self, dense, k, gate=True):
        """State 0 started again from the direct reading at index ``k`` of ``dense`` (the most
        precise one there), as at the log's start; its error is that reading's noise, independent
        of the other states' errors, so the covariance carried (grown over the pause) gets row and
        column 0 of that: variance ``R`` of the sensor, no correlation.  The other states carry on.
        The state and covariance carried are the prior of that reading's tick, so the restart is
        its update (from a prior of state 0 that knows nothing): the reading is consumed (made NaN
        in ``dense``, not counted as unused) and that tick reads only the others.  Read again
        there, it counted twice: the variance of state 0 halved (a predicted std 0.71 times the
        error's over 200 simulated restarts of a position filter).
        Only where the reading disagrees with the state carried over the pause by more than
        :data:`RESTART_GATE` standard deviations of the innovation (``P00 + R``, the prior grown
        over the pause): a short gap of a fast IMU, bridged well by the held inputs, would
        otherwise swap a precise heading for one noisy compass reading.
        Without ``gate`` (the log's first direct reading after tick 0, whose value the state
        started from: the state carried to it holds nothing else of state 0) always.
        Returns ``(delta, std)``: the move of state 0 and the reading's noise std, or None
        (no restart)."""
        from ..runtime.filter import usable

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
        if gate and R is not None and delta ** 2 <= RESTART_GATE ** 2 * (var0 + R[best, best]):
            return None  # the inputs held over the pause still agree with the reading: carry on
        x[0] += delta
        dense[ms[best].name][k] = np.nan  # consumed here: the tick's update does not read it again
        if kf is not None:
            kf.x = x
        else:
            self.x = x
        if R is not None:
            for P in self._covariances():
                P[0, :] = P[:, 0] = 0.0
                P[0, 0] = R[best, best]
        return delta, math.sqrt(R[best, best]) if R is not None else 0.0

    def _covariances(self) -> list:
        """The covariances carried from tick to tick (of the Kalman filter over the arrivals, the
        bridging filter, the missed readings' standard deviations) that exist so far."""
        kf = getattr(self, "_arrivals", None)
        return [P for P in (self.P_missed, None if kf is None else kf.P, None if self.bridge is None else self.bridge.P)
                if P is not None]

    def _forget(self):
        """At a pause's end, state 0 (what the vehicle did over the pause is unknown) is made
        uncorrelated with the other states in the covariances carried, its variance kept: the
        held inputs had correlated its error over the pause with the other states', so a reading of
        another state (a velocity) before the first direct reading stepped it (39.7 m on a 30 s
        pause of a position filter, its 10 Hz velocity read 5 ticks after the end), and the rows
        before that reading were left off by the step (37 m from the truth) when the ticks from
        the pause's end moved onto the direct reading (:meth:`_restart`) by one amount."""
        for P in self._covariances():
            p00 = P[0, 0]
            P[0, :] = P[:, 0] = 0.0
            P[0, 0] = p00

    def _run_arrivals(self, dense, first, last):
        """Ticks ``first..last`` through the Kalman filter over the actual arrivals
        (:class:`~cfdesign.runtime.arrivals.ArrivalKalman`), its state carried between blocks."""
        if not hasattr(self, "_arrivals"):
            self._arrivals = _kalman()(self.table, self.output, self.x)
        kf = self._arrivals
        N = last - first + 1
        u = np.column_stack([dense[s.name] for s in self.table.inputs]) if self.table.inputs else np.zeros((N, 0))
        y = np.column_stack([dense[s.name] for s in self.table.measurements])
        kf.counts = {}
        out, stds, hph = kf.run(u, y, priors=True)
        _merge(self.counts, kf.counts)
        return out, np.arange(first, last + 1) % self.table.period, stds, hph

    def _run_segments(self, dense, first, last):
        """Ticks ``first..last`` through the table's segments (:class:`~cfdesign.timing.Lock`)."""
        n = self.table.F.shape[0]
        out = np.empty((last - first + 1, n))
        phases = np.empty(last - first + 1, dtype=np.int64)
        stds = np.empty((last - first + 1, n))
        hph = np.empty((last - first + 1, len(self.table.measurements)))
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
                out[a - first:b - first], stds[a - first:b - first], hph[a - first:b - first] = \
                    self._run_bridged(rt, part)
            else:
                _, xs = rt.run(part, states=True)
                out[a - first:b - first] = xs
                stds[a - first:b - first] = self._std(rt)[phases[a - first:b - first]]
                hph[a - first:b - first] = self._hph(rt)[phases[a - first:b - first]]
                if self.covariances:
                    stds[a - first:b - first] = self._missed(rt, part, phases[a - first:b - first],
                                                             stds[a - first:b - first])
            self.x, self.u_last = rt.x.copy(), rt.u_last.copy()
            _merge(self.counts, rt.counts)
        return out, phases, stds, hph

    def _run_bridged(self, rt, part):
        """A segment of a table with Kalman gains: its own (vectorised) gains wherever every
        scheduled reading is present, and from a missed one (a dropout, an outage, a sensor that
        starts late or stops early) the Kalman filter of the table's model over the readings that
        did arrive (:class:`~cfdesign.runtime.arrivals.ArrivalKalman`), until its covariance is
        back on the table's (to :attr:`~cfdesign.runtime.arrivals.MissedReadings.RTOL`): the
        table's fixed gains are those of every reading present, and after an outage they kept a
        small gain on the readings that came back (or, with a sensor gone, on the one left) -
        1.27 times the RMS error of the Kalman filter over the same readings on the log of
        ``tests/test_logs.py`` whose odometry drops out and stops (docs/logs.md).  Returns the
        output states, their predicted standard deviations and the prior ``H P H'`` of each
        reading (:meth:`_hph`); the bridging filter is carried from segment to segment and block to
        block."""
        from ..runtime.arrivals import MissedReadings
        from ..runtime.filter import usable

        table, N, n = rt.table, len(next(iter(part.values()))), rt.table.F.shape[0]
        phases = (rt.phase + np.arange(N)) % rt.period
        ms = table.measurements
        present = np.column_stack([usable(part[s.name]) for s in ms])
        missed = (table.schedule.mask()[phases] & ~present).any(axis=1)
        std, var = self._std(rt), self._hph(rt)
        out, stds, hph = np.empty((N, n)), np.empty((N, n)), np.empty((N, len(ms)))
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
                    stds[i:m], hph[i:m] = std[phases[i:m]], var[phases[i:m]]
                if m == N:
                    break
                kf = self.bridge = _kalman()(table, rt.output, rt.x)
                kf.P, kf.u_last = np.array(table.P[phases[m]], dtype=float), rt.u_last.copy()
                i = m
            j = min(N, i + every)
            u = np.column_stack([part[s.name][i:j] for s in table.inputs]) if table.inputs else np.zeros((j - i, 0))
            kf.counts = {}
            out[i:j], stds[i:j], hph[i:j] = kf.run(u, np.column_stack([part[s.name][i:j] for s in ms]), priors=True)
            _merge(self.counts, kf.counts)
            rt.x, rt.u_last, rt.phase = kf.x.copy(), kf.u_last.copy(), int((phases[j - 1] + 1) % rt.period)
            ref = np.asarray(table.P[rt.phase], dtype=float)
            if not missed[i:j].any() and np.max(np.abs(kf.P - ref)) <= MissedReadings.RTOL * np.max(np.diag(ref)):
                self.bridge = None  # back on the table's gains
            i = j
        return out, stds, hph

    def _missed(self, rt, part, phases, base):
        """``base`` (the table's standard deviations) where every scheduled reading was present;
        from a missed one until the error is back on the table's, the error of the gains that ran
        over the readings present (:class:`~cfdesign.runtime.arrivals.MissedReadings`; its
        covariance carried from segment to segment and block to block)."""
        if rt.table.Q is None or rt.table.R is None:
            return base
        if not hasattr(rt, "_missed"):
            from ..runtime.arrivals import MissedReadings

            rt._missed = MissedReadings(rt.table, rt.output)
        from ..runtime.filter import usable

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

    def _hph(self, rt):
        """``(period, m)``: ``H P H'`` of every measurement row at each phase of ``rt``'s table (its
        prior covariance ``P``), NaN where the table has no gain for it.  Where readings were missed,
        a table without Kalman gains keeps this figure (its grown covariance is not followed here:
        the few readings after an outage weigh little in a median)."""
        if not hasattr(rt, "_log_hph"):
            t = rt.table
            H = np.asarray(t.H, dtype=float)
            var = np.einsum("ij,pjk,ik->pi", H, np.asarray(t.P, dtype=float), H)
            rt._log_hph = np.where(t.schedule.mask(), var, np.nan)
        return rt._log_hph

    def _start(self, dense):
        """The quantity from the first reading of a sensor whose row of H picks it (state 0): the
        log's (``first_reading``, found by the first pass over every block) or, without it, the
        first in ``dense``."""
        x = np.zeros(self.table.F.shape[0])
        first = self.first_reading or _first_direct(self.table, np.arange(len(next(iter(dense.values())))), dense)
        if first is not None:
            x[0] = first[3]
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


def _kalman():
    """:class:`~cfdesign.runtime.arrivals.ArrivalKalman` (imported when a log needs it)."""
    from ..runtime.arrivals import ArrivalKalman

    return ArrivalKalman


def _after(ticks, startup, starts):
    """Whether each of ``ticks`` (base ticks) is at or after ``startup`` and outside the ``startup`` ticks from
    each of ``starts``: one search over the sorted starts (a pass over the rows for each one cost 4 s a block
    of a million rows with 10,000 pauses)."""
    ticks = np.asarray(ticks)
    out = ticks >= startup
    if len(starts):
        starts = np.sort(np.asarray(starts, dtype=float))
        i = np.searchsorted(starts, ticks, side="right") - 1  # the latest start-up begun at or before each tick
        out &= ~((i >= 0) & (ticks - starts[np.maximum(i, 0)] < startup))
    return out


def _merge(into, counts):
    for kind, per in counts.items():
        bucket = into.setdefault(kind, {})
        for name, c in per.items():
            bucket[name] = bucket.get(name, 0) + c


class _NoBar:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        pass


def _progress(total, show):
    """A tqdm bar of ``total`` rows on stderr when ``show`` and the log spans more than a block;
    silent when stderr is not a terminal (a redirected log or CI gets no carriage-return lines)."""
    if not show or total < BLOCK_ROWS:
        return _NoBar()
    import sys

    from tqdm import tqdm

    return tqdm(total=total, unit="row", file=sys.stderr, disable=None)
