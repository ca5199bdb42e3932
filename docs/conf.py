"""Sphinx configuration of the cfdesign site.

Build (warnings are errors; the notebooks are executed and a failing cell fails the build)::

    python -m pip install -e ".[docs]"
    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
# The notebooks' kernels must draw with IPython's inline backend so that their figures land in
# the pages: a backend forced from outside (MPLBACKEND=Agg in CI) would draw them nowhere.
os.environ.pop("MPLBACKEND", None)

import cfdesign  # noqa: E402

project = "cfdesign"
author = "the cfdesign developers"
copyright = "the cfdesign developers, BSD-3-Clause"
version = release = cfdesign.__version__

extensions = [
    "myst_nb",  # MyST Markdown pages and executed notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
]

# -- pages ---------------------------------------------------------------------------------------
root_doc = "index"
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "README.md", "**.ipynb_checkpoints"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]

# The notebooks live in notebooks/ (the test suite executes them there); the site executes a
# copy of each at build time, so the pages show their plots.  A failing cell fails the build.
NOTEBOOKS = HERE / "notebooks"
NOTEBOOKS.mkdir(exist_ok=True)
for _nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
    _dst = NOTEBOOKS / _nb.name
    if not _dst.exists() or _dst.read_bytes() != _nb.read_bytes():
        shutil.copyfile(_nb, _dst)
nb_execution_mode = os.environ.get("CFDESIGN_DOCS_EXECUTE", "force")
nb_execution_raise_on_error = True
nb_execution_timeout = 600
nb_execution_in_temp = True
nb_merge_streams = True

# -- API reference -------------------------------------------------------------------------------
autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": False}
autodoc_typehints = "none"  # numpydoc sections carry the types, with units and frames
autodoc_preserve_defaults = True
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

# Every cross-reference must resolve: a link to a renamed or undocumented name fails the build
# (-W) instead of silently rendering as plain text.  Internal names are written with their full
# dotted path (the module that defines them, e.g. ``cfdesign.designer.design`` for
# ``cfdesign.design``).  The build has no network, so there is no intersphinx: the names of
# other projects and of the standard library cannot resolve and are the only ones ignored.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|scipy|sympy|pandas|matplotlib)(\..+)?"),  # third-party (no intersphinx)
    (r"py:.*", r"(json|tempfile|datetime|os|pathlib|functools)\..+"),  # standard library
]
nitpick_ignore = [
    ("py:func", "open"),  # builtin
]



def _dataclass_fields() -> set:
    """Field names of the public dataclasses: their docstrings describe them (numpydoc
    ``Attributes``/``Parameters``), so autodoc's own entries for them would repeat it."""
    import dataclasses
    import importlib
    import inspect
    import pkgutil

    names = set()
    for info in pkgutil.walk_packages(cfdesign.__path__, "cfdesign."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if inspect.isclass(obj) and dataclasses.is_dataclass(obj) and obj.__module__.startswith("cfdesign"):
                names.update(f.name for f in dataclasses.fields(obj))
    return names


_FIELDS = _dataclass_fields()


def _skip_fields(app, what, name, obj, skip, options):
    if what == "class" and name in _FIELDS and not callable(obj) and not isinstance(obj, property):
        return True
    return None


def _public_bases(app, name, obj, options, bases):
    """The "Bases:" line names only documented classes: cfdesign's internal mixins
    (``cfdesign.sim.trajectory.SampledTimes``, ``cfdesign.sim.sensors._Sensor``) are not in
    any ``__all__``, have no page, and a link to them could not resolve."""
    import importlib

    def documented(cls):
        if not cls.__module__.startswith("cfdesign"):
            return True
        return cls.__name__ in getattr(importlib.import_module(cls.__module__), "__all__", ())

    bases[:] = [b for b in bases if documented(b)]


def setup(app):
    app.connect("autodoc-skip-member", _skip_fields)
    app.connect("autodoc-process-bases", _public_bases)


# -- HTML ----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"cfdesign {version}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_static_path: list[str] = []
