"""The API reference of the documentation site lists every public name.

The site's pages under ``docs/api/`` document modules with autodoc (``automodule`` with
``:members:``, which follows ``__all__``).  This checks, without building the site, that
every module of cfdesign with an ``__all__`` is documented, that every name of its ``__all__``
reaches the reference (on its own page or on its package's), and that the top-level names of
``cfdesign.__all__`` are listed on the reference's index.  The build itself (``sphinx -W``)
runs in CI after the tests (``.ci/run``).
"""

from __future__ import annotations

import ast
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


DATA_ROLE = re.compile(r":data:`~?(?P<target>[\w.]+)`")


def _module_sources() -> dict:
    """``{module name: source path}`` of every module of cfdesign."""
    root = DOCS.parent / "cfdesign"
    out = {}
    for path in root.rglob("*.py"):
        parts = path.relative_to(root.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _assigned(path: Path) -> set:
    """The names a module's source binds at its top level by assignment (not by import)."""
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        else:
            targets = []
        names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


def test_every_data_cross_reference_names_the_module_that_assigns_the_value():
    """autodoc documents a module's value (a ``#:`` constant) on the page of the module that
    assigns it, not on that of a package re-exporting it, so ``sphinx -W`` fails on a
    :data: reference that resolves only to the re-export (``cfdesign.codegen``'s
    ``STRICT_CFLAGS``, assigned in ``cfdesign.codegen.c99``).  Each target must resolve as Sphinx
    resolves it - in the docstring's own module or a package above it (which documents what it
    re-exports), then as written - to a module that assigns it."""
    sources = _module_sources()
    assigned = {}
    unresolved = []
    for module, path in sorted(sources.items()):
        for m in DATA_ROLE.finditer(path.read_text()):
            found = False
            # the module, then each package above it (a package's page documents what it re-exports)
            scopes = [module.rsplit(".", i)[0] for i in range(module.count(".") + 1)]
            for full in [f"{scope}.{m['target']}" for scope in scopes] + [m["target"]]:
                owner, _, name = full.rpartition(".")
                if owner in sources:
                    if owner not in assigned:  # parsed once (setdefault parsed it for every reference: 10 s)
                        assigned[owner] = _assigned(sources[owner])
                    found = found or name in assigned[owner]
            if not found:
                unresolved.append(f"{path.relative_to(DOCS.parent)}: {m[0]}")
    assert len(assigned) > 10  # the check found the references it is about
    assert not unresolved, unresolved


def _command_options(command: str, paper: str | None = None) -> dict:
    """``{option: set of choices or None}`` of ``cfdesign COMMAND`` (or ``reproduce PAPER``), as
    the parser has them (``-o`` for ``-o/--output``; help left out)."""
    from cfdesign.cli import build_parser

    parser = build_parser(["reproduce"] if paper else None)
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    if paper:
        sub = next(a for a in sub._actions if a.choices and paper in a.choices).choices[paper]
    return {(a.option_strings[0] if a.option_strings[0] == "-o" else a.option_strings[-1]):
            (set(map(str, a.choices)) if a.choices else None)
            for a in sub._actions if a.option_strings and a.dest != "help"}


def _synopsis_options(synopsis: str) -> dict:
    """``{option: set of choices shown (a|b|c) or None}`` of a usage line as the docs write it."""
    synopsis = synopsis.replace("\\|", "|")
    option = r"(?<![\w-])(?P<opt>-o|--[a-z][a-z-]*)(?: (?P<choices>[\w.]+(?:\|[\w.]+)+)(?=[\] ]|$))?"
    return {m["opt"]: (set(m["choices"].split("|")) if m["choices"] else None)
            for m in re.finditer(option, synopsis)}


COMMANDS = ["prove", "bode", "design", "export", "verify", "run", "noise", "discretize"]


def _readme_synopses() -> dict:
    readme = (DOCS.parent / "README.md").read_text()
    block = re.search(r"^## Command line\n\n```\n(.*?)^```", readme, re.M | re.S).group(1)
    lines = {}
    for line in block.splitlines():
        words = line.split()
        if len(words) > 1 and words[0] == "cfdesign":
            lines[words[1]] = line.split("#")[0]
    # the papers' options are given where the README describes each reproduction
    flat = " ".join(readme.split())
    for paper in ("carreira", "helicopter", "compare"):
        lines[f"reproduce {paper}"] = re.search(rf"`cfdesign reproduce {paper} (\[[^`]*)`", flat).group(1)
    return lines


def _cli_page_synopses() -> dict:
    rows = re.findall(r"^\| `cfdesign (\w+)([^`]*)` \|", (DOCS / "cli.md").read_text(), re.M)
    return {command: rest for command, rest in rows}


PAPERS = ["reproduce carreira", "reproduce helicopter", "reproduce compare"]


@pytest.mark.parametrize("command, where", [(c, "README.md") for c in [*COMMANDS, *PAPERS]]
                         + [(c, "docs/cli.md") for c in COMMANDS])
def test_the_usage_lines_give_every_option_of_the_command_and_no_other(command, where):
    """README's 'Command line' block (and its reproductions' lines) and the command table of
    docs/cli.md (which gives the papers' options as ``[options]``) name every option
    ``cfdesign COMMAND --help`` has, with the same choices, and no option the command does not
    have."""
    synopses = _readme_synopses() if where == "README.md" else _cli_page_synopses()
    assert command in synopses, f"{where} has no usage line for cfdesign {command}"
    documented = _synopsis_options(synopses[command])
    actual = _command_options(*command.split())
    assert sorted(set(actual) - set(documented)) == [], f"{where}: cfdesign {command} options not documented"
    assert sorted(set(documented) - set(actual)) == [], f"{where}: cfdesign {command} has no such options"
    for option, choices in actual.items():
        if choices is not None:
            assert documented[option] == choices, f"{where}: cfdesign {command} {option} takes {sorted(choices)}"


def _pyproject() -> dict:
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    return tomllib.loads((DOCS.parent / "pyproject.toml").read_text())["project"]


def test_every_extra_the_docs_name_exists():
    """``pip install ".[NAME]"`` / ``"cfdesign[NAME]"`` in the README, the docs, the notebooks and
    the package's own messages name extras of pyproject.toml."""
    extras = set(_pyproject()["optional-dependencies"])
    root = DOCS.parent
    files = [root / "README.md", *DOCS.rglob("*.md"), *(root / "notebooks").glob("*.ipynb"),
             *(root / "cfdesign").rglob("*.py")]
    named = {(f.name, name) for f in files if "_build" not in f.parts
             for group in re.findall(r"(?:cfdesign|\.)\[([a-z][\w,-]*)\]", f.read_text()) for name in group.split(",")}
    assert named and all(name in extras for _, name in named), sorted(x for x in named if x[1] not in extras)


def test_the_notebooks_extra_runs_every_notebook():
    """docs/examples.md: ``pip install ".[notebooks]"`` runs the notebooks, so every package a
    notebook imports is the standard library's, cfdesign's or one of cfdesign's dependencies with
    that extra (notebook 07 imports pandas, which only the logs extra gave)."""
    import json
    import sys

    project = _pyproject()
    requirements = [*project["dependencies"], *project["optional-dependencies"]["notebooks"]]
    installed = {re.match(r"[\w.-]+", r).group(0).lower().replace("-", "_") for r in requirements}
    for nb in sorted((DOCS.parent / "notebooks").glob("*.ipynb")):
        cells = json.loads(nb.read_text())["cells"]
        source = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        statements = re.findall(r"^\s*(?:from\s+([\w.]+)\s+import|import\s+([\w., ]+))", source, re.M)
        modules = {part.split(" as ")[0].strip().split(".")[0]
                   for group in statements for item in group if item for part in item.split(",")}
        # (the notebooks' modules have their distribution's name: numpy, sympy, matplotlib, ...)
        missing = sorted(m for m in modules - {"cfdesign", ""} - sys.stdlib_module_names if m.lower() not in installed)
        assert not missing, f"{nb.name} imports {missing}, which the notebooks extra does not install"


def _pages() -> list:
    """The README and every Markdown page of the site (its build output aside)."""
    return [DOCS.parent / "README.md", *(p for p in sorted(DOCS.rglob("*.md")) if "_build" not in p.parts)]


def _resolves(dotted: str) -> bool:
    """Whether ``cfdesign.a.b.c`` is a module or an attribute reached from the longest importable
    module prefix."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for name in parts[i:]:
            if not hasattr(obj, name):
                return False
            obj = getattr(obj, name)
        return True
    return False


def test_the_readme_layout_names_every_module_and_package():
    """The README's Layout section names each module and package directly under cfdesign/
    (``blas.py`` and ``units.py`` had been left out)."""
    readme = (DOCS.parent / "README.md").read_text()
    layout = readme[readme.index("## Layout"):readme.index("## References")]
    root = DOCS.parent / "cfdesign"
    parts = [p.name + ("/" if p.is_dir() else "") for p in sorted(root.iterdir())
             if not p.name.startswith(("__", ".")) and (p.suffix == ".py" or (p / "__init__.py").is_file())]
    assert len(parts) > 20
    missing = [p for p in parts if f"`{p}`" not in layout and f"`cfdesign/{p}`" not in layout]
    assert not missing, f"not in the README's Layout: {missing}"


def test_every_dotted_name_the_pages_give_exists():
    """A name written out in prose (``cfdesign.nav.strapdown_ekf``, ``cfdesign.timing.grid_fit``)
    is not a Sphinx cross-reference, so ``-W`` does not check it: it must still be a module or
    an attribute of one (``cfdesign.nav.ekf`` was neither)."""
    named = {(page.relative_to(DOCS.parent).as_posix(), m.rstrip("."))
             for page in _pages() for m in re.findall(r"(?<![\w/.])cfdesign(?:\.[A-Za-z_]\w*)+", page.read_text())}
    assert named
    missing = sorted((page, name) for page, name in named if not _resolves(name))
    assert not missing, f"names that do not exist: {missing}"


def test_every_option_a_page_gives_a_command_exists():
    """Every ``cfdesign COMMAND ... --option`` written in a page (a console line or inline code)
    names an option that command has: the usage-line test above holds README's and cli.md's
    synopses to the parser, this one the examples of every other page."""
    actual = {c: _command_options(c) for c in COMMANDS}
    actual |= {p: _command_options(*p.split()) for p in PAPERS}
    unknown = []
    for page in _pages():
        text = page.read_text()
        for line in re.findall(r"`(cfdesign [^`]+)`", text) + re.findall(r"^\$? ?(cfdesign .*)$", text, re.M):
            words = line.split("#")[0].split()
            command = " ".join(words[1:3]) if " ".join(words[1:3]) in actual else words[1]
            if command not in actual:  # prose that starts with the name, or 'cfdesign COMMAND --help'
                continue
            for option in re.findall(r"(?<![\w-])(-o|--[a-z][a-z-]*)", " ".join(words)):
                if option not in actual[command] and option not in ("--help", "--debug", "--version"):
                    unknown.append((page.name, command, option))
    assert not unknown, f"options the commands do not have: {sorted(set(unknown))}"


def _toml_blocks() -> list:
    """``(page, n, text)`` of every TOML block of the README and the pages."""
    return [(page.relative_to(DOCS.parent).as_posix(), n, block) for page in _pages()
            for n, block in enumerate(re.findall(r"^```toml\n(.*?)^```", page.read_text(), re.M | re.S))]


@pytest.mark.parametrize("page, n, block", _toml_blocks(), ids=[f"{p}-{n}" for p, n, _ in _toml_blocks()])
def test_every_design_file_a_page_gives_designs(page, n, block):
    """A design file a page asks the reader to save (getting started's ``heading.toml``, the
    crossover file of the noise page) parses and designs, complementary and stable; an excerpt
    (a block that leaves sensors out with ``...``) is at least TOML."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    data = tomllib.loads(block)
    if "..." in block:
        return
    table = cfdesign.design(cfdesign.parse_spec(data))
    assert table.checks["complementary"] and table.checks["stable"], (page, n)



def _python_blocks(page) -> list:
    return re.findall(r"^```python\n(.*?)^```", page.read_text(), re.M | re.S)


@pytest.mark.parametrize("page", [p for p in _pages() if _python_blocks(p)],
                         ids=lambda p: p.relative_to(DOCS.parent).as_posix())
def test_every_name_a_python_block_uses_is_defined_on_its_page(page):
    """A reader pastes a page's Python blocks in order: every name a block reads is a builtin or
    defined (assigned, imported, a function) by that block or an earlier one of the page
    (``rt.run({"gyro": w, ...})`` with ``w`` never defined, ``estimate_attitude(gyr, acc, mag,
    rate_hz)`` with none of them, failed with a NameError)."""
    import ast
    import builtins

    defined, undefined = set(dir(builtins)), []
    for n, block in enumerate(_python_blocks(page)):
        tree = ast.parse(block)
        for node in ast.walk(tree):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                defined.add(node.id)
            elif isinstance(node, ast.alias):
                defined.add((node.asname or node.name).split(".")[0])
            elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                defined.add(node.name)
            elif isinstance(node, ast.arg):
                defined.add(node.arg)
        undefined += [(n, node.id) for node in ast.walk(tree)
                      if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id not in defined]
    assert not undefined, f"names a reader's paste leaves undefined (block, name): {undefined}"
