"""Tables of design files drawn at random (``benchmarks/bench_predicted.py --random``'s generator):
``cfdesign verify --spec`` passes every check of a table the designer wrote, and the generated C
filter follows the Python runtime sample by sample.  The class of tables users write, not only the
built-in examples (``tests/test_codegen.py``, ``tests/test_verify.py``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import cfdesign
from cfdesign.errors import CfdesignError
from cfdesign.runtime import Runtime
from cfdesign.spec import parse_spec

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

_spec = importlib.util.spec_from_file_location(
    "bench_predicted", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_predicted.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

ROWS = 4000


def discrete_draw(seed):
    """The first design file of the generator's stream ``seed`` that designs a discrete table with
    full gains (sparse searches are slow, and continuous tables have no C): ``(text, table)``."""
    rng = np.random.default_rng(seed)
    while True:
        layout = bench._layout(rng)
        text = bench._spec_text(rng, *layout)[0]
        if layout[-1] or not layout[-2]:
            continue
        try:
            return text, cfdesign.design(parse_spec(tomllib.loads(text)))
        except CfdesignError:
            continue


#: position (predictor), cfn of 4 bands at period 30, a wrapped dckf3 in filter form giving the prior at
#: period 15, a chain with two inputs and two angle readings at period 20, a chain in filter form (prior)
@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
@pytest.mark.parametrize("seed", [21, 25, 33, 29, 39])
def test_a_random_table_verifies_against_its_file_and_runs_alike_in_c(seed, cli, tmp_path):
    from test_codegen import CC, difference, readings, run_c

    text, table = discrete_draw(seed)
    (tmp_path / "s.toml").write_text(text)
    code, out, err = cli("design", tmp_path / "s.toml", "-o", tmp_path / "g.json")
    assert code == 0, err
    code, out, err = cli("verify", tmp_path / "g.json", "--spec", tmp_path / "s.toml")
    assert code == 0, out + err
    if CC is None:
        pytest.skip("no C compiler: 'cc' is not on PATH, the generated C is not compiled")
    data = {name: values[:ROWS] for name, values in readings(table).items()}
    rt = Runtime(table, lock=False)  # the generated C runs the fixed schedule (its lock is manual)
    stream = np.array([rt.step(**{name: data[name][k] for name in data}) for k in range(ROWS)]).ravel()
    c = run_c(table, data, tmp_path, "double")
    assert c.size == stream.size
    assert difference(table, c, stream) <= 1e-12 * max(1.0, np.abs(stream).max())
