"""Writing estimates: the estimate columns of a block, and the CSV/Parquet writer (compressed by its name)."""

from __future__ import annotations

import functools
import math
import sys
from pathlib import Path

import numpy as np

from ..errors import CfdesignError, OutputError, require_extra
from ..files import open_atomic, write_bytes
from ..linear import wrap
from .columns import NEEDS_PYARROW, _first_line, _pandas


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
        self._steady = {}  # the same after the start-up of the log and of every pause (:meth:`steady`)
        self.steady_rows = 0
        self._predicted = {}  # state -> (variances predicted, their count) over every compared row
        self.settled_rows = 0
        self._ctx = self._fh = self._parquet = self._packed = None
        self.also = {}  # {path: bytes} written with the estimates, all or nothing (a plot of them)
        self._types = types  # Parquet types of the log's passed-through columns over the whole log
        self._blocks = 0  # CSV blocks written

    def __enter__(self):
        if self.path is not None:
            parquet = self.path.suffix.lower() in (".parquet", ".pq")
            packed = _PACK.get(self.path.suffix.lower())  # estimates.csv.gz: a gzip-compressed CSV
            binary = parquet or packed
            self._ctx = open_atomic(self.path, "wb" if binary else "w", also=self.also,
                                    **({} if binary else {"newline": ""}))
            self._fh = self._ctx.__enter__()
            if packed:
                import io

                self._fh = self._packed = io.TextIOWrapper(packed(self._fh), encoding="utf-8", newline="")
            self._is_parquet = parquet
        return self

    def __exit__(self, *exc):
        try:
            if self._parquet is not None:
                self._parquet.close()
            if self._packed is not None:
                self._packed.close()  # the compressed stream's end; the file under it stays open until moved
        except BaseException:  # (Ctrl-C, a full disk): the temporary file is removed, not left or moved into place
            if self._ctx is not None:
                self._ctx.__exit__(*sys.exc_info())
            raise
        if self._ctx is not None:
            self._ctx.__exit__(*exc)
        return False

    def write(self, frame, settled, steady=None):
        """Write a block of estimates (``settled``: a boolean per row, the rows after the start-up;
        ``steady``: those also after the start-up of every pause, default ``settled``)."""
        self._errors(frame, settled, settled if steady is None else steady)
        shown = frame.drop(columns=frame.attrs["hidden"])
        if self.keep:
            self.frames.append(frame)
        if self._fh is None:
            return
        if self._is_parquet:
            pa = require_extra("pyarrow", NEEDS_PYARROW)
            pq = require_extra("pyarrow.parquet", NEEDS_PYARROW)

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
            self._csv(shown, header=not self._blocks)
            self._blocks += 1

    def _csv(self, shown, header):
        """A block as pandas' ``to_csv`` writes it; its numbers formatted by Arrow when it can."""
        pieces = _fast_pieces(shown)
        if pieces is None:
            shown.to_csv(self._fh, index=False, header=header, lineterminator="\n")
            return
        if header:
            shown.iloc[:0].to_csv(self._fh, index=False, lineterminator="\n")
        for text in pieces:  # written piece by piece: the block's whole text at once added 330 MB to the peak
            self._fh.write(text)

    @staticmethod
    def _cast(tab, schema):
        """A block of the estimates in the file's column types (a log read in chunks may change a
        column's type between them: integers in one, with gaps as floats in the next)."""
        try:
            return tab.select(schema.names).cast(schema)
        except (ValueError, TypeError, NotImplementedError) as exc:  # pyarrow's ArrowInvalid is a ValueError
            raise OutputError(f"cannot write Parquet: a column changes type between blocks of the log "
                              f"({_first_line(exc)}); write CSV, or give the column one type") from None

    def _errors(self, frame, settled, steady):
        from ..runtime.filter import usable

        self.settled_rows += int(np.count_nonzero(settled))
        self.steady_rows += int(np.count_nonzero(steady))
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
            for sums, rows in ((self._settled, settled), (self._steady, steady)):
                s, n, v = sums.get(state, (0.0, 0, 0.0))
                sums[state] = (s + float(np.sum(err[ok & rows] ** 2)), n + int((ok & rows).sum()),
                               v + float(np.sum(var[ok & rows])))

    def settled(self, sums=None) -> tuple:
        """``({state: RMS error after the start-up}, {state: RMS of the predicted std over those
        rows, or over every compared row when none is after the start-up})``."""
        sums = self._settled if sums is None else sums
        rms = _rms({k: (s, n) for k, (s, n, _) in sums.items()})
        predicted = {k: math.sqrt(v / n) if n else math.sqrt(self._predicted[k][0] / self._predicted[k][1])
                     if self._predicted[k][1] else math.nan for k, (_, n, v) in sums.items()}
        return rms, predicted

    def steady(self) -> tuple:
        """:meth:`settled` over the rows also after the start-up of every pause (restarted or carried)."""
        return self.settled(self._steady)

    def attach(self, path, data: bytes):
        """Write ``data`` to ``path`` with the estimates file, all or nothing, when the writer closes
        (a plot of them: an interrupted run left a new plot beside the previous estimates); at once
        without an estimates file."""
        if self._ctx is None:
            write_bytes(path, data)
        else:
            self.also[path] = data

    def frame(self):
        if not self.frames:
            return None
        pd = _pandas()
        return pd.concat(self.frames, ignore_index=True)


def _rms(errors):
    return {state: math.sqrt(s / n) if n else math.nan for state, (s, n) in errors.items()}


# -- the CSV text of a block of numbers, formatted by Arrow ------------------------------------------------
# pandas writes a float as numpy's text of it (the shortest digits that read back as the same double,
# positional for 1e-4 <= |x| < 1e16 and scientific otherwise, as Python's repr) and NaN as an empty cell:
# that formatting is most of the time of writing 1M rows.  Arrow's cast of doubles to text gives the same
# shortest digits several times faster, in its own notation only where it differs: '1' for 1.0, and its
# own choice of positional or scientific ('0.00001', '1e+15').  Those cells are mended below ('.0'
# appended to whole numbers; Python's repr for the few others), so that the file is byte for byte the
# one pandas writes (tests/test_write_fast.py compares them).

#: cells formatted and written at a time: a 3M-row run peaked at 602 MB (pandas' writer: 553; 2 ** 21
#: cells: 810) and ran 3 % faster than with 2 ** 21
_FAST_CELLS = 2 ** 17


def _fast_csv(frame):
    """The CSV rows of ``frame`` (no header) exactly as ``frame.to_csv(index=False, header=False,
    lineterminator='\\n')`` writes them, or None when a column is neither float64 nor integers, or
    pyarrow is missing (pandas writes those).

    Parameters
    ----------
    frame : pandas.DataFrame
        A block of estimates.

    Returns
    -------
    str or None
        The rows, each ended by a newline.
    """
    pieces = _fast_pieces(frame)
    return None if pieces is None else "".join(pieces)


def _fast_pieces(frame):
    """:func:`_fast_csv` in pieces of :data:`_FAST_CELLS` cells: an iterator of text, or None."""
    if not _arrow_agrees():
        return None
    pa = require_extra("pyarrow", NEEDS_PYARROW)
    pc = require_extra("pyarrow.compute", NEEDS_PYARROW)

    # numpy's own dtypes only: pandas writes a nullable column's <NA> and a text column's quotes itself
    if not len(frame.dtypes) or not all(isinstance(d, np.dtype) and (d == np.float64 or d.kind in "iu")
                                        for d in frame.dtypes):
        return None
    arrays = [frame.iloc[:, i].to_numpy() for i in range(frame.shape[1])]
    return _pieces(arrays, len(frame), pa, pc)


def _pieces(arrays, rows, pa, pc):
    """The text of ``rows`` rows of the columns ``arrays``, :data:`_FAST_CELLS` cells at a time."""
    empty = '""' if len(arrays) == 1 else ""  # the csv module quotes the one empty cell of a row
    step = max(_FAST_CELLS // len(arrays), 1)
    for start in range(0, rows, step):
        cells = [_cells(a[start:start + step], pa, pc) for a in arrays]
        joined = pc.binary_join_element_wise(*cells, ",", null_handling="replace", null_replacement=empty)
        lines = pc.binary_join_element_wise(joined, pa.scalar("\n"), "")
        offsets = np.frombuffer(lines.buffers()[1], np.int32, len(lines) + 1, lines.offset * 4)
        yield lines.buffers()[2].to_pybytes()[offsets[0]:offsets[-1]].decode("ascii")


#: doubles of every notation: Arrow's text of them mended must be numpy's (checked once per process)
_PROBE = (0.0, -0.0, 1.0, -3.0, 0.1, 1 / 3, 1e-4, 9.999e-5, -1.25e-5, 1e-6, 9.9e-7, 1e-7, 5e-324, 2.0 ** 53,
          123456789012345.6, 1e15, 1e16, 1e21, 1.7976931348623157e308, math.inf, -math.inf, math.nan)


@functools.lru_cache(maxsize=1)
def _arrow_agrees() -> bool:
    """Whether pyarrow is installed and its text of :data:`_PROBE`, mended, is numpy's (another
    version of Arrow may lay its numbers out otherwise: pandas writes them then)."""
    try:
        pa = require_extra("pyarrow", NEEDS_PYARROW)
        pc = require_extra("pyarrow.compute", NEEDS_PYARROW)
    except CfdesignError:  # a speed-up here, not a need: pandas writes the CSV without it
        return False
    probe = np.array(_PROBE)
    want = np.where(np.isnan(probe), None, probe.astype(str).astype(object))
    return _cells(probe, pa, pc).to_pylist() == want.tolist()


def _cells(values, pa, pc):
    """The text of each cell of a column as pandas' ``to_csv`` writes it.

    Parameters
    ----------
    values : numpy.ndarray
        One column of a block: float64 or integers.
    pa, pc : module
        ``pyarrow`` and ``pyarrow.compute``.

    Returns
    -------
    pyarrow.StringArray
        A text per cell, null for NaN.
    """
    if values.dtype.kind in "iu":
        return pc.cast(pa.array(values), pa.string())  # str(int)
    nan = np.isnan(values)
    strings = pc.cast(pa.array(values, mask=nan), pa.string())
    size = np.abs(values)
    sci = pc.fill_null(pc.match_substring(strings, "e"), False).to_numpy(zero_copy_only=False)
    fixed = ((size >= 1e-4) & (size < 1e16)) | (values == 0)  # pandas positional
    plain = fixed & ~sci
    # Arrow's '3' and '-0': pandas' '3.0' and '-0.0'
    with np.errstate(invalid="ignore"):  # trunc of a NaN
        whole = plain & (values == np.trunc(values))
    strings = _mend(strings, whole, pa, pc, lambda s: pc.binary_join_element_wise(s, pa.scalar(".0"), ""))
    # both scientific: Arrow's 'e-7' is pandas' 'e-07'
    both = ~fixed & sci
    strings = _mend(strings, both, pa, pc, lambda s: pc.replace_substring_regex(s, r"e([+-])(\d)$", r"e\10\2"))
    # Arrow's positional '0.0000123' and '0.000001' are pandas' '1.23e-05' and '1e-06'
    small = ~sci & (size >= 1e-6) & (size < 1e-4)
    strings = _mend(strings, small, pa, pc, _small)
    other = ~nan & ~plain & ~both & ~small
    if other.any():  # the rest ('inf', '1e+15', '123456789012345.6'): Python's repr, one by one
        strings = pc.replace_with_mask(strings, pa.array(other), pa.array([repr(v) for v in values[other].tolist()]))
    return strings


def _mend(strings, where, pa, pc, mend):
    """``strings`` with the cells ``where`` (a boolean per cell) passed through ``mend``."""
    if not where.any():
        return strings
    mask = pa.array(where)
    return pc.replace_with_mask(strings, mask, mend(strings.filter(mask)))


def _small(strings):
    """Arrow's positional text of 1e-6 <= |x| < 1e-4 in pandas' notation ('0.0000123' -> '1.23e-05')."""
    pc = require_extra("pyarrow.compute", NEEDS_PYARROW)

    for zeros, exp in (("0000", "05"), ("00000", "06")):
        strings = pc.replace_substring_regex(strings, rf"^(-?)0\.{zeros}([1-9])(\d+)$", rf"\1\2.\3e-{exp}")
        strings = pc.replace_substring_regex(strings, rf"^(-?)0\.{zeros}([1-9])$", rf"\1\2e-{exp}")
    return strings
