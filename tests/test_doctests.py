"""The Examples sections of the docstrings run and give what they show.

Every module of cfdesign (``cfdesign.__main__`` aside, which runs the command line) is searched
for doctests; each module with examples is one test.  Examples that need files written by hand
or draw a plot are marked ``# doctest: +SKIP``.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import numpy as np
import pytest

import cfdesign

MODULES = sorted(m.name for m in pkgutil.walk_packages(cfdesign.__path__, "cfdesign.")
                 if not m.name.endswith("__main__"))
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _tests(name):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    return [t for t in finder.find(module, name) if t.examples]


WITH_EXAMPLES = [name for name in MODULES if _tests(name)]


@pytest.mark.parametrize("name", WITH_EXAMPLES)
def test_docstring_examples(name, monkeypatch, tmp_path):
    tests = _tests(name)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.chdir(tmp_path)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    with np.printoptions(precision=8, suppress=True):
        for test in tests:
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples in {name} failed (output above)"


def test_there_are_examples():
    count = sum(len(t.examples) for name in WITH_EXAMPLES for t in _tests(name))
    assert count >= 200, count
