"""What an installed cfdesign (a wheel, not this checkout) needs: its data files ship, and a missing
optional package is one line naming the extra that installs it.

The wheel ships the files of ``[tool.setuptools.package-data]`` only: a resource the code opens
(a structure, an example, a schema, a C template) outside those globs worked from the checkout and
failed from every install.  Each optional package is imported through
:func:`cfdesign.errors.require_extra`, whose message names an extra of pyproject.toml that
installs that package.
"""

import ast
import fnmatch
import re
import sys
from importlib import metadata
from pathlib import Path

import pytest

import cfdesign
from cfdesign.errors import EXTRAS, CfdesignError, install_hint, require_extra

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "cfdesign"
#: every package an extra installs that cfdesign's code may import (EXTRAS, and those of the other extras)
OPTIONAL = {*EXTRAS, "allantools", "ipywidgets", "sphinx", "numpydoc", "jupyter", "nbclient", "nbformat"}


def _pyproject():
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def _names(requirements) -> set:
    """The distributions requirements install: ``dask[distributed]>=2024.1`` -> dask, distributed."""
    out = set()
    for req in requirements:
        m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[([^\]]*)\])?", req)
        out.add(m.group(1).lower().replace("_", "-"))
        out.update(e.strip().lower() for e in (m.group(2) or "").split(",") if e.strip())
    return out


def _sources():
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def test_package_data_ships_every_file_of_the_package():
    """Every file in cfdesign/ other than Python source matches a glob of package-data (so the
    wheel and the sdist carry it); the resource folders the code opens hold such files."""
    globs = _pyproject()["tool"]["setuptools"]["package-data"]["cfdesign"]
    data = [p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*")
            if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts]
    unshipped = [f for f in data if not any(fnmatch.fnmatch(f, g) for g in globs)]
    assert data and not unshipped, f"not in [tool.setuptools.package-data]: {unshipped}"
    from cfdesign.designer import STRUCTURES_DIR
    from cfdesign.gains import SCHEMA_PATH
    from cfdesign.spec import EXAMPLES_DIR

    opened = [*STRUCTURES_DIR.iterdir(), *EXAMPLES_DIR.iterdir(), SCHEMA_PATH,
              *(PACKAGE / "codegen" / "templates").iterdir()]
    assert all(p.relative_to(PACKAGE).as_posix() in data for p in opened)


def test_the_code_opens_files_of_the_package_only_through_the_known_folders():
    """A new ``Path(__file__)`` or ``importlib.resources`` site is a new resource: add its files to
    package-data (and its folder to the test above)."""
    known = {"designer.py": 1, "gains.py": 1, "spec.py": 1, "codegen/c99.py": 1, "codegen/attitude.py": 1}
    sites = {}
    for path in _sources():
        text = path.read_text()
        n = text.count("Path(__file__)") + len(re.findall(r"resources\.files\(", text))
        if n:
            sites[path.relative_to(PACKAGE).as_posix()] = n
    assert sites == known


def test_every_optional_import_goes_through_require_extra():
    """No ``import pandas`` (pyarrow, dask, ...) in cfdesign: a bare one is a ModuleNotFoundError
    traceback in a base install, or a second copy of the message; each literal module given to
    ``require_extra`` has its extra."""
    bare, unknown = [], []
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                mods = [node.module]
            elif (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "require_extra"
                  and isinstance(node.args[0], ast.Constant)):
                unknown += [f"{path.name}:{node.lineno}"] if install_hint(node.args[0].value) is None else []
                continue
            else:
                continue
            bare += [f"{path.relative_to(PACKAGE)}:{node.lineno} {m}" for m in mods if m.split(".")[0] in OPTIONAL]
    assert not bare, f"import these through cfdesign.errors.require_extra: {bare}"
    assert not unknown


def test_each_extra_a_message_names_installs_the_module():
    """``pip install "cfdesign[EXTRA]"`` for a missing module: EXTRA is an extra of pyproject.toml
    and lists the distribution that provides the module (found from the installed ones)."""
    extras = _pyproject()["project"]["optional-dependencies"]
    provides = metadata.packages_distributions()
    for module, extra in EXTRAS.items():
        assert extra in extras, (module, extra)
        dists = {d.lower().replace("_", "-") for d in provides.get(module, [module])}
        assert dists & _names(extras[extra]), f"{extra} does not install {module} ({dists})"


def test_the_noise_extra_runs_cfdesign_noise():
    """``cfdesign noise`` reads its log as ``cfdesign run`` does: the noise extra holds the logs extra."""
    extras = _pyproject()["project"]["optional-dependencies"]
    assert _names(extras["logs"]) <= _names(extras["noise"])


def test_require_extra_names_the_extra_on_one_line(monkeypatch):
    for name in ["pyarrow", *(m for m in sys.modules if m.startswith("pyarrow."))]:  # as if not installed
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(CfdesignError) as info:
        require_extra("pyarrow.parquet", "Parquet needs pyarrow")
    assert str(info.value) == 'Parquet needs pyarrow: pip install "cfdesign[logs]"'
    assert require_extra("pandas", "x") is sys.modules["pandas"]


@pytest.mark.parametrize("hidden, call, extra", [
    ("pandas", lambda t, d: cfdesign.logs.run_log(t, d / "log.csv"), "logs"),
    ("pandas", lambda t, d: cfdesign.logs.read_log(d / "log.csv"), "logs"),
    ("dask", lambda t, d: cfdesign.logs.run_logs(t, [d / "log.csv"], d / "out"), "fleet"),
])
def test_a_function_of_a_missing_extra_raises_its_install_line(hidden, call, extra, tmp_path, monkeypatch):
    """What a base install (no extra) sees calling the logs' functions: a CfdesignError naming the
    extra, not a ModuleNotFoundError."""
    import cfdesign.logs

    table = cfdesign.design(cfdesign.load_spec(cfdesign.spec.example_path("dckf3")))
    (tmp_path / "log.csv").write_text("time,gyro,compass,odometry\n0,0,0.1,0.1\n0.2,0,0.1,0.1\n")
    for name in [hidden, *(m for m in sys.modules if m.startswith(hidden + "."))]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(CfdesignError, match=re.escape(f'pip install "cfdesign[{extra}]"')):
        call(table, tmp_path)


# Python 3.10 (requires-python): its datetime.fromisoformat reads only the layout isoformat() writes

#: (any one character before the time; an offset of hours and minutes, perhaps seconds and microseconds)
_LAYOUT_310 = re.compile(r"\d{4}-\d{2}-\d{2}(?:.\d{2}(?::\d{2}(?::\d{2}(?:\.\d{3}|\.\d{6})?)?)?"
                         r"(?:[+-]\d{2}:\d{2}(?::\d{2}(?:\.\d{6})?)?)?)?")


@pytest.mark.parametrize("text", ["1970-01-01T00:01:00.5Z", "2024-05-01 12:00:00,5+01:00", "2024-05-01T12:00:00.010",
                                  "2024-05-01T12:00:00.1234567+0100", "2024-05-01T12:00:00,25-0330", "2024-05-01",
                                  "2024-05-01T12:00:00+01", "2024-05-01T12:00+0100", "2024-05-01t12:00:00.5",
                                  "2024-05-01T12:00:00.5+01:00:30", "20240501T120000.25Z"])
def test_dates_read_under_python_310_as_under_311(text, monkeypatch):
    """:func:`cfdesign.timing.date_seconds` (time columns of dates) under a ``fromisoformat`` that
    refuses what 3.10's refuses gives the seconds 3.11's gives (the docstring's own example,
    ``...00:01:00.5Z``, had been a ValueError on 3.10; so had an offset of hours only, ``+0100`` after
    a time without seconds, a lower-case ``t``, an offset with seconds and a date without hyphens)."""
    import datetime

    from cfdesign.timing import date_seconds

    real = datetime.datetime

    class Py310(real):
        @classmethod
        def fromisoformat(cls, s):
            if not _LAYOUT_310.fullmatch(s):
                raise ValueError(f"Invalid isoformat string: {s!r}")
            return real.fromisoformat(s)

    want = date_seconds(text)
    monkeypatch.setattr(datetime, "datetime", Py310)
    assert date_seconds(text) == want
    with pytest.raises(ValueError):
        date_seconds("2024-05-01T12:00:00 UTC")
