"""The API reference of the documentation site lists every public name.

The site's pages under ``docs/api/`` document modules with autodoc (``automodule`` with
``:members:``, which follows ``__all__``).  This checks, without building the site, that
every module of cfdesign with an ``__all__`` is documented, that every name of its ``__all__``
reaches the reference (on its own page or on its package's), and that the top-level names of
``cfdesign.__all__`` are listed on the reference's index.  The build itself (``sphinx -W``)
runs in CI after the tests (``.ci/run``).
"""

from __future__ import annotations

import importlib
import pkgutil
import re
from pathlib import Path

import pytest

import cfdesign

DOCS = Path(__file__).resolve().parents[1] / "docs"
API = DOCS / "api"
DIRECTIVE = re.compile(r"^\.\. automodule:: (?P<module>[\w.]+)\n(?P<options>(?:   :.*\n?)*)", re.M)

MODULES = sorted(m.name for m in pkgutil.walk_packages(cfdesign.__path__, "cfdesign.")
                 if not m.name.endswith("__main__"))


def _directives() -> dict:
    """``{module: set of member names or None (all of __all__)}`` over every API page."""
    out = {}
    for page in sorted(API.glob("*.rst")):
        for m in DIRECTIVE.finditer(page.read_text()):
            options = m["options"]
            members = re.search(r":members:(.*)", options)
            if members is None:
                continue
            names = {n.strip() for n in members.group(1).split(",") if n.strip()}
            out[m["module"]] = names or None
    return out


def test_the_site_has_its_pages():
    for page in ("index.md", "getting-started.md", "derivations.md", "logs.md", "reproductions.md",
                 "examples.md", "cli.md", "conf.py", "api/index.rst", "guide/index.md"):
        assert (DOCS / page).is_file(), page
    guide = (DOCS / "guide" / "index.md").read_text()
    for page in ("design", "optimal-gains", "multirate", "noise-and-crossover", "running", "c-export", "verify",
                 "navigation", "features"):
        assert (DOCS / "guide" / f"{page}.md").is_file() and f"\n{page}\n" in guide, page
    examples = (DOCS / "examples.md").read_text()
    for nb in sorted((DOCS.parent / "notebooks").glob("*.ipynb")):
        assert f"notebooks/{nb.stem}" in examples, nb.name


@pytest.mark.parametrize("name", [m for m in MODULES if hasattr(importlib.import_module(m), "__all__")])
def test_every_public_name_is_in_the_reference(name):
    documented = _directives()
    module = importlib.import_module(name)
    parent = importlib.import_module(name.rsplit(".", 1)[0])
    # names a package re-exports are documented on the package's page
    elsewhere = set(getattr(parent, "__all__", ())) if documented.get(parent.__name__, "") is None else set()
    listed = documented.get(name, set())
    if listed is None:
        return
    missing = sorted(set(module.__all__) - listed - elsewhere)
    assert not missing, f"{name}: {missing} are in __all__ but not in the reference"


def test_top_level_names_are_listed():
    index = (API / "index.rst").read_text()
    for name in cfdesign.__all__:
        if name in cfdesign._MODULES or name == "__version__":
            continue
        assert re.search(rf"^   ~[\w.]+\.{name}$", index, re.M), f"cfdesign.{name} is not listed in docs/api/index.rst"
    for name in sorted(cfdesign._MODULES):
        assert (API / f"cfdesign.{name}.rst").is_file() or re.search(rf"automodule:: cfdesign\.{name}\n",
                                                                      "".join(p.read_text() for p in API.glob("*.rst")))


def test_the_build_is_nitpicky():
    """``sphinx -W`` fails on a cross-reference that does not resolve only when the build is
    nitpicky; the names ignored are other projects' and the standard library's (no intersphinx:
    the build has no network), never cfdesign's."""
    conf = (DOCS / "conf.py").read_text()
    assert re.search(r"^nitpicky = True$", conf, re.M)
    ignored = re.search(r"^nitpick_ignore_regex = \[(.*?)^\]", conf, re.M | re.S)
    assert ignored and "cfdesign" not in ignored.group(1)
    assert "sphinx.ext.intersphinx" not in conf
