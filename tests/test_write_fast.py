"""The estimates' CSV formatted by Arrow is byte for byte the one pandas' ``to_csv`` writes."""

import bz2
import gzip
import io
import sys

import numpy as np
import pandas as pd
import pytest

import cfdesign
from cfdesign.logs import run_log
from cfdesign.logs import write as write_mod
from cfdesign.logs.write import _fast_csv, _Writer
from cfdesign.spec import parse_spec

pytest.importorskip("pyarrow")

AWKWARD = [0.0, -0.0, 1.0, -3.0, 1e15, 1e16, 9999999999999998.0, 2.0 ** 53, 123456789012345.6, 1e-4,
           9.999e-5, 1e-5, 1.25e-5, 1e-6, 9.9e-7, 1e-7, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
           1e21, 1e100, -1.5e-300, 0.1, 1 / 3, np.inf, -np.inf, np.nan]


def pandas_rows(frame) -> str:
    """The reference: pandas' own CSV of the frame's rows."""
    buf = io.StringIO()
    frame.to_csv(buf, index=False, header=False, lineterminator="\n")
    return buf.getvalue()


def awkward_frame(n=40_000, seed=3):
    """Columns of every kind of double a filter may write (random bit patterns cover the rest)."""
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2 ** 64, n, dtype=np.uint64).view(np.float64)
    scale = 10.0 ** rng.integers(-9, 19, n)
    return pd.DataFrame({"special": rng.choice(AWKWARD, n), "bits": bits,
                         "whole": np.round(rng.standard_normal(n) * 10.0 ** rng.integers(0, 17, n)),
                         "scaled": rng.standard_normal(n) * scale, "normal": rng.standard_normal(n),
                         "gapped": np.where(rng.random(n) < 0.7, np.nan, rng.standard_normal(n)),
                         "count": rng.integers(-10 ** 15, 10 ** 15, n), "flag": rng.integers(0, 2, n).astype(np.uint8)})


def test_rows_match_pandas_for_awkward_doubles():
    frame = awkward_frame()
    assert frame["special"].isna().any() and (np.signbit(frame["special"]) & (frame["special"] == 0)).any()
    text = _fast_csv(frame)
    assert text is not None
    assert text == pandas_rows(frame)


@pytest.mark.parametrize("column", ["special", "gapped", "normal", "count"])
def test_one_column_matches_pandas(column):
    frame = awkward_frame(5_000)[[column]]  # a row's one empty cell is written '""'
    assert _fast_csv(frame) == pandas_rows(frame)


def test_blocks_longer_than_a_chunk(monkeypatch):
    monkeypatch.setattr(write_mod, "_FAST_CELLS", 7_777)  # 972 rows of 8 columns a chunk
    frame = awkward_frame(5_000)
    assert _fast_csv(frame) == pandas_rows(frame)


def test_other_columns_left_to_pandas(monkeypatch):
    frame = awkward_frame(100)
    assert _fast_csv(frame.assign(name="a,b")) is None  # text: quoted by the csv module
    assert _fast_csv(frame.astype({"normal": np.float32})) is None
    assert _fast_csv(frame.astype({"gapped": "Float64"})) is None
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # pyarrow not installed
    write_mod._arrow_agrees.cache_clear()
    assert _fast_csv(frame) is None
    monkeypatch.undo()
    write_mod._arrow_agrees.cache_clear()
    assert _fast_csv(frame) is not None


def test_arrow_that_lays_numbers_out_otherwise_is_not_used(monkeypatch):
    """Another Arrow's notation (here: exponents without their sign) turns the fast path off."""
    import pyarrow.compute as pc

    cast = pc.cast
    monkeypatch.setattr(pc, "cast", lambda *a, **k: pc.replace_substring(cast(*a, **k), "e+", "e"))
    write_mod._arrow_agrees.cache_clear()
    try:
        assert not write_mod._arrow_agrees()
        assert _fast_csv(awkward_frame(100)) is None
    finally:
        monkeypatch.undo()
        write_mod._arrow_agrees.cache_clear()
    assert write_mod._arrow_agrees()


def hidden(frame):
    frame.attrs.update(hidden=[], references=[], wrap=None)
    return frame


@pytest.mark.parametrize("name, unpack", [("est.csv", bytes), ("est.csv.gz", gzip.decompress),
                                          ("est.csv.bz2", bz2.decompress)])
def test_writer_files_match_pandas(tmp_path, name, unpack):
    """The header once, every block's rows in order, through the compressors, written atomically."""
    frame = awkward_frame(3_000).rename(columns={"normal": "a,b"})  # a header cell that needs quotes
    blocks = [frame.iloc[:1000], frame.iloc[1000:1000], frame.iloc[1000:]]
    with _Writer(tmp_path / name, keep=False) as writer:
        for block in blocks:
            writer.write(hidden(block.copy()), np.ones(len(block), bool))
    buf = io.StringIO()
    frame.to_csv(buf, index=False, lineterminator="\n")
    assert unpack((tmp_path / name).read_bytes()).decode() == buf.getvalue()
    assert [p.name for p in tmp_path.iterdir()] == [name]  # no temporary left beside it


def test_text_column_still_written_by_pandas(tmp_path):
    frame = awkward_frame(200).assign(note=lambda f: np.where(f["count"] > 0, "up, fast", "down"))
    with _Writer(tmp_path / "est.csv", keep=False) as writer:
        writer.write(hidden(frame.copy()), np.ones(len(frame), bool))
    buf = io.StringIO()
    frame.to_csv(buf, index=False, lineterminator="\n")
    assert (tmp_path / "est.csv").read_text() == buf.getvalue()


def test_run_log_file_same_with_and_without_arrow(tmp_path, monkeypatch):
    table = cfdesign.design(parse_spec({"name": "h", "structure": "dckf3", "wrap_angle": True, "sensors": {
        "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
        "odometry": {"rate_hz": 10.0, "noise": {"std": 0.005}}, "compass": {"rate_hz": 1.0, "noise": {"std": 0.05}}}}))
    n = 5_000
    rng = np.random.default_rng(0)
    t, k = np.arange(n) * 0.01, np.arange(n)
    psi = np.sin(0.1 * t)
    pd.DataFrame({"time": t, "gyro": 0.1 * np.cos(0.1 * t) + 0.01 * rng.standard_normal(n),
                  "odometry": np.where(k % 10 == 3, psi + 0.005 * rng.standard_normal(n), np.nan),
                  "compass": np.where(k % 100 == 37, psi + 0.05 * rng.standard_normal(n), np.nan),
                  "seq": k}).to_csv(tmp_path / "log.csv", index=False)
    run_log(table, tmp_path / "log.csv", output=tmp_path / "fast.csv.gz", std=True, block_rows=1_500)
    monkeypatch.setattr(write_mod, "_fast_pieces", lambda frame: None)
    run_log(table, tmp_path / "log.csv", output=tmp_path / "pandas.csv.gz", std=True, block_rows=1_500)
    fast, slow = (gzip.decompress((tmp_path / f).read_bytes()) for f in ("fast.csv.gz", "pandas.csv.gz"))
    assert fast == slow
    assert fast.count(b"time,") == 1 and len(fast.splitlines()) == n + 1
