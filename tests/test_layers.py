"""Layers only look down: sim/ imports nothing from nav/ or runtime/; runtime/ and nav/ do not import sympy.

Each check runs in a fresh interpreter, so that what the test process has already imported
cannot hide an import.
"""

import json
import subprocess
import sys
import textwrap

import pytest


def _modules_after(code: str) -> list:
    """``sorted(sys.modules)`` after running ``code`` in a fresh interpreter."""
    script = textwrap.dedent(code) + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _import_all(package: str) -> str:
    """Code that imports ``package`` and every module in it."""
    return f"""
        import importlib, pkgutil
        import {package} as pkg
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            importlib.import_module(info.name)
        """


def _under(modules, *packages):
    return [m for m in modules if any(m == p or m.startswith(p + ".") for p in packages)]


def test_sim_imports_nothing_from_nav_or_runtime():
    modules = _modules_after(_import_all("cfdesign.sim"))
    assert "cfdesign.sim.helicopter" in modules and "cfdesign.sim.ground" in modules
    assert _under(modules, "cfdesign.nav", "cfdesign.runtime") == []


@pytest.mark.parametrize("package", ["cfdesign.runtime", "cfdesign.nav"])
def test_runtime_and_nav_never_import_sympy(package):
    modules = _modules_after(_import_all(package))
    assert f"{package}.filter" in modules or f"{package}.position" in modules
    assert _under(modules, "sympy", "cfdesign.symbolic") == []
