"""Layers only look down: sim/ imports nothing from nav/ or runtime/; runtime/ and nav/ never import sympy.

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
    assert f"{package}.filter" in modules or f"{package}.quaternion_attitude" in modules
    assert _under(modules, "sympy", "cfdesign.symbolic") == []


def test_nav_filters_run_without_sympy():
    """The filters design their default gains without the symbolic engine, at construction or first call."""
    modules = _modules_after("""
        import time
        import numpy as np
        from cfdesign.nav import estimate_attitude
        rng = np.random.default_rng(0)
        n = 1000
        gyr = rng.normal(0.0, 0.01, (n, 3))
        acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0.0, 0.05, (n, 3))
        mag = np.tile([0.0, 20.0, -40.0], (n, 1))
        start = time.perf_counter()
        estimate_attitude(gyr, acc, mag, 100.0)
        print(f"estimate_attitude: first call on 1,000 samples {time.perf_counter() - start:.3f} s")
        import sys
        assert "sympy" not in sys.modules
        from cfdesign.nav import EulerAttitudeFilter, PositionFilter
        EulerAttitudeFilter(100.0, gyro_noise_std=0.005, gyro_bias_density=1e-4, tilt_noise_std=0.01,
                            heading_noise_std=0.02).run(gyr, acc, mag)
        pf = PositionFilter(50.0, 1.0, accel_noise_std=0.006, accel_bias_density=1e-3, gps_noise_std=3.0)
        pf.run(acc, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.full((n, 3), np.nan))
        """)
    assert "cfdesign.nav.position" in modules and "cfdesign.designer" in modules
    assert _under(modules, "sympy", "cfdesign.symbolic") == []



def test_the_command_reads_tables_without_jsonschemas_iri_checker(tmp_path):
    """``cfdesign`` checks a table against its schema with jsonschema, whose optional IRI checker
    (rfc3987_syntax, installed with Jupyter) took 1 s to import; the command's process goes
    without it (no table's schema asks for a format), a library user's process keeps it."""
    from cfdesign import design
    from cfdesign.spec import parse_spec

    spec = {"name": "h", "structure": "cf2", "discrete": True,
            "sensors": {"rate": {"rate_hz": 100.0, "noise": {"std": 0.01}},
                        "angle": {"rate_hz": 100.0, "noise": {"std": 0.05}}}}
    path = design(parse_spec(spec)).save(tmp_path / "g.json")
    modules = _modules_after(f"""
        import sys
        from cfdesign.cli import console
        sys.argv = ["cfdesign", "verify", {str(path)!r}]
        assert console() == 0
        """)
    assert "jsonschema" in modules and _under(modules, "rfc3987_syntax") in ([], ["rfc3987_syntax"])
    modules = _modules_after(f"""
        import cfdesign
        cfdesign.load_gains({str(path)!r})
        import rfc3987_syntax  # where it is installed, a library user still has it
        """) if _installed("rfc3987_syntax") else None
    assert modules is None or "rfc3987_syntax.syntax_helpers" in modules


def _installed(name) -> bool:
    import importlib.util

    return importlib.util.find_spec(name) is not None
