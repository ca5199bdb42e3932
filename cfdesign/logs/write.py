"""Writing estimates: the estimate columns of a block, and the CSV/Parquet writer (compressed by its name)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..files import open_atomic
from ..linear import wrap
from .columns import _first_line, _pandas


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
        from ..runtime.filter import usable

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
