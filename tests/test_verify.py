"""cfdesign verify / export / run, assert_complementary, schema: good tables pass, tampered ones fail."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

import cfdesign
from cfdesign.errors import GainTableError
from cfdesign.gains import load_gains, validate
from cfdesign.testing import assert_complementary
from cfdesign.verify import band_polynomials, verify_table

EXAMPLES = ["robot-heading", "dckf3", "position", "ckf3", "cf3"]


@pytest.fixture(scope="module")
def tables():
    return {name: cfdesign.design(cfdesign.load_spec(cfdesign.example_path(name))) for name in EXAMPLES}


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "cfdesign", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("name", EXAMPLES)
def test_designed_tables_pass_every_check(name, tables):
    checks = verify_table(tables[name], cfdesign.load_spec(cfdesign.example_path(name)))
    assert all(c.ok for c in checks), [c.line() for c in checks]
    assert_complementary(tables[name], spec=cfdesign.example_path(name))


def test_numeric_bands_match_the_symbolic_engine(tables):
    table = tables["dckf3"]
    numeric, _ = band_polynomials(table, output="prior")  # the predictor's own estimate (tests/test_linear.py: both)
    symbolic = cfdesign.dckf3().with_gains({**table.gains, "T": table.sample_time_s}).band_coefficients()
    z = np.exp(1j * np.linspace(0.01, 3.0, 30))
    for name, (num, den) in numeric.items():
        ref = np.polyval(symbolic[name][0], z) / np.polyval(symbolic[name][1], z)
        assert np.allclose(np.polyval(num, z) / np.polyval(den, z), ref, rtol=1e-9, atol=1e-12)


def test_unstable_gain_fails(tables):
    t = tables["dckf3"]
    K = [k.copy() for k in t.K]
    K[0][1, 0] = 5.0
    failed = [c for c in verify_table(dataclasses.replace(t, K=K)) if not c.ok]
    assert [c.name for c in failed] == ["stable (closed-loop poles)"]
    with pytest.raises(AssertionError, match="stable"):
        assert_complementary(dataclasses.replace(t, K=K))


def test_unstable_periodic_gain_fails(tables):
    t = tables["position"]
    K = [k.copy() for k in t.K]
    K[0][:, 0] = [3.0, 0.0, 0.0]
    failed = [c.name for c in verify_table(dataclasses.replace(t, K=K)) if not c.ok]
    assert failed == ["stable (monodromy multipliers)"]


@pytest.mark.parametrize("matrix", ["F", "B"])
def test_altered_model_breaks_the_sensor_relation(matrix, tables):
    t = tables["dckf3"]
    M = getattr(t, matrix).copy()
    M[0, 0] *= 1.01  # F: the angle integrator leaks; B: the gyro no longer integrates to the angle
    failed = [c.name for c in verify_table(dataclasses.replace(t, **{matrix: M})) if not c.ok]
    assert "complementary (polynomial identity)" in failed


def test_spec_mismatch_fails(tables, tmp_path):
    spec = cfdesign.example_path("dckf3")
    other = tmp_path / "other.toml"
    other.write_text(spec.read_text().replace("std = 0.002 ", "std = 0.004 "))
    failed = [c for c in verify_table(tables["dckf3"], cfdesign.load_spec(other)) if not c.ok]
    assert failed and failed[0].name == "gains match the spec"


def test_cli_verify_exit_codes(tables, tmp_path):
    good = tables["dckf3"].save(tmp_path / "good.json")
    r = cli("verify", str(good), "--spec", str(cfdesign.example_path("dckf3")))
    assert r.returncode == 0 and "4 of 4 checks hold" in r.stdout
    data = json.loads(good.read_text())
    data["K"][0][1][0] = 5.0
    (tmp_path / "unstable.json").write_text(json.dumps(data))
    r = cli("verify", str(tmp_path / "unstable.json"))
    assert r.returncode == 1 and r.stdout.count("FAIL") == 1
    del data["K"]
    (tmp_path / "missing.json").write_text(json.dumps(data))
    r = cli("verify", str(tmp_path / "missing.json"))
    assert r.returncode == 2 and "'K' is a required property" in r.stderr and r.stderr.count("\n") == 1
    (tmp_path / "garbage.json").write_text("{not json")
    assert cli("verify", str(tmp_path / "garbage.json")).returncode == 2
    assert cli("verify", str(tmp_path / "absent.json")).returncode == 2


def test_schema_rejects_bad_shapes(tables):
    data = tables["position"].to_dict()
    validate(data)
    data["K"][3] = [[0.0], [0.0]]
    with pytest.raises(GainTableError, match=r"K\[3\] must be 3x1"):
        validate(data)
    data = tables["position"].to_dict()
    data["gain_form"] = "smoother"
    with pytest.raises(GainTableError, match="gain_form"):
        validate(data)
    data = tables["position"].to_dict()
    data["sensors"][0]["name"] = "gps rate"
    with pytest.raises(GainTableError, match="sensors/0/name"):
        validate(data)


def test_json_export_round_trip_is_exact(tables, tmp_path):
    src = tables["position"].save(tmp_path / "a.json")
    r = cli("export", str(src), "--format", "json", "-o", str(tmp_path / "b.json"))
    assert r.returncode == 0, r.stderr
    a, b = load_gains(src), load_gains(tmp_path / "b.json")
    assert all(np.array_equal(x, y) for x, y in zip(a.K + a.P, b.K + b.P, strict=True))


def test_csv_export_has_every_gain(tables, tmp_path):
    src = tables["position"].save(tmp_path / "a.json")
    assert cli("export", str(src), "--format", "csv", "-o", str(tmp_path / "g.csv")).returncode == 0
    rows = (tmp_path / "g.csv").read_text().splitlines()
    assert rows[0] == "phase,state,gps" and len(rows) == 1 + 50 * 3
    assert float(rows[1].split(",")[2]) == tables["position"].K[0][0, 0]


def test_cli_run_matches_runtime_and_rejects_bad_csv(tables, tmp_path):
    table = tables["dckf3"]
    src = table.save(tmp_path / "g.json")
    rng = np.random.default_rng(3)
    N = 500
    data = {n: rng.normal(size=N) * 0.1 for n in ("gyro", "compass", "odometry")}
    lines = ["time,gyro,compass,odometry"] + [
        f"{0.2 * k},{float(data['gyro'][k])!r},{'' if k % 4 == 0 else repr(float(data['compass'][k]))},"
        f"{float(data['odometry'][k])!r}"
        for k in range(N)]
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
    r = cli("run", str(src), str(tmp_path / "log.csv"), "-o", str(tmp_path / "est.csv"))
    assert r.returncode == 0, r.stderr
    out = np.loadtxt(tmp_path / "est.csv", delimiter=",", skiprows=1)
    data["compass"][::4] = np.nan
    ref = cfdesign.Runtime(table).run(data)
    assert np.max(np.abs(out[:, 1] - ref)) < 1e-12 and np.allclose(out[:, 0], 0.2 * np.arange(N))
    bad = {
        "missing.csv": "time,gyro,compass\n0,1,2\n",
        "text.csv": "gyro,compass,odometry\n1,2,3\n1,abc,3\n",
        "ragged.csv": "gyro,compass,odometry\n1,2,3\n1,2\n",
        "extra.csv": "gyro,compass,odometry,baro\n1,2,3,4\n",
    }
    for name, text in bad.items():
        (tmp_path / name).write_text(text)
        out_path = tmp_path / f"out_{name}"
        r = cli("run", str(src), str(tmp_path / name), "-o", str(out_path))
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, (name, r.stderr)
        assert not out_path.exists() and not list(tmp_path.glob(f".out_{name}*"))
    assert "line 3" in cli("run", str(src), str(tmp_path / "text.csv"), "-o", "x.csv", cwd=tmp_path).stderr
