"""Shared fixtures and helpers for the cfdesign tests."""

import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


def pytest_configure(config):
    """Every test process goes as the ``cfdesign`` command's (``cli.console``): jsonschema without
    its optional IRI checker (rfc3987_syntax, whose grammars take 1-3 s of CPU at the first table
    read; no schema of ours asks for a format), whichever test module reads a table first.

    One BLAS thread per xdist worker: ``-n auto`` already runs a worker per core, and each
    worker's OpenBLAS threads on top of that (a 20-state verify: 0.4 s alone, 16 s beside another
    worker) made the suite wait on oversubscribed cores."""
    sys.modules.setdefault("rfc3987_syntax", None)
    if os.environ.get("PYTEST_XDIST_WORKER"):
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:
            return
        config._cfdesign_blas_limit = threadpool_limits(limits=1, user_api="blas")


@pytest.fixture
def shared_dir():
    """The project's shared/ folder (beside the checkout in CI); skip when absent."""
    if not SHARED.is_dir():
        pytest.skip(f"shared data folder not found at {SHARED} (it sits beside the checkout in CI)")
    return SHARED


def run_cli(*args) -> tuple:
    """``cfdesign ARGS`` in this process: ``(exit status, stdout, stderr)``.

    The CLI is a thin layer over the library, so its tests call ``cli.main`` directly rather
    than paying for a new interpreter; tests of start-up and entry points use a subprocess.
    """
    import contextlib
    import io

    from cfdesign.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:  # --help and --version exit from argparse
            code = exc.code or 0
    return code, out.getvalue(), err.getvalue()


def read_csv_exact(path, **options):
    """``pandas.read_csv`` reading every number as the nearest double, for a test's own reading of an
    output: pandas before 3.0 read one in six shortest reprs an ulp off by default (its ``round_trip``
    parser is exact; pandas 3 reads them exactly and deprecates the option)."""
    import pandas as pd

    if int(pd.__version__.split(".")[0]) < 3:
        options.setdefault("float_precision", "round_trip")
    return pd.read_csv(path, **options)


@pytest.fixture
def cli():
    """:func:`run_cli` as a fixture."""
    return run_cli


#: the heading filter of the log tests: 100 Hz gyro, 10 Hz odometry, 1 Hz compass
HEADING = {"name": "heading 100/10/1 Hz", "structure": "dckf3", "wrap_angle": True, "sensors": {
    "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
    "odometry": {"rate_hz": 10.0, "noise": {"std": 0.005}},
    "compass": {"rate_hz": 1.0, "noise": {"std": 0.05}}}}


@pytest.fixture(scope="session")
def heading():
    """The table of :data:`HEADING` (a module may define a ``heading`` of its own)."""
    import cfdesign
    from cfdesign.spec import parse_spec

    return cfdesign.design(parse_spec(HEADING))
