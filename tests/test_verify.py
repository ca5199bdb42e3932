"""cfdesign verify / export / run, assert_complementary, schema: good tables pass, tampered ones fail."""

import dataclasses
import json
import pathlib
import subprocess

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


def cli(*args):
    """The command in this process, as a CompletedProcess."""
    from conftest import run_cli

    code, out, err = run_cli(*args)
    return subprocess.CompletedProcess(args, code, out, err)


@pytest.mark.parametrize("name", EXAMPLES)
def test_designed_tables_pass_every_check(name, tables):
    checks = verify_table(tables[name], cfdesign.load_spec(cfdesign.example_path(name)))
    assert all(c.ok for c in checks), [c.line() for c in checks]
    assert_complementary(tables[name], spec=cfdesign.example_path(name))


@pytest.mark.parametrize("name", EXAMPLES)
def test_a_gain_edited_after_the_design_fails_the_covariance_check(name, tables):
    """Scaling the gains by 3 % keeps the filter complementary and stable, so only the stale
    covariances (every predicted standard deviation) can tell: without --spec, verify names them."""
    t = tables[name]
    edited = dataclasses.replace(t, K=[k * 1.03 for k in t.K])
    failed = [c for c in verify_table(edited) if not c.ok]
    assert [c.name for c in failed] == ["covariances of these gains"], [c.line() for c in failed]
    assert "not those of these gains" in failed[0].detail


@pytest.mark.parametrize("gain, value", [("k1", 1e-12), ("k2", 1e-12), ("k2", 1e-6)])
def test_near_marginal_fixed_gains_pass_the_covariance_check(gain, value):
    """A pole at -8e-14 (k2 = 1e-12) makes the Lyapunov equation ill-conditioned; its solution is
    still backward stable, which is what the check measures (an entrywise scale failed it)."""
    from cfdesign.verify import covariance_check

    spec = cfdesign.load_spec(cfdesign.example_path("cf3"))
    table = cfdesign.design(dataclasses.replace(spec, gains={**spec.gains, gain: value}))
    check = covariance_check(table)
    assert check.ok, check.line()


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
    assert [c.name for c in failed] == ["stable (closed-loop poles)", "covariances of these gains"]
    with pytest.raises(AssertionError, match="stable"):
        assert_complementary(dataclasses.replace(t, K=K))


def test_unstable_periodic_gain_fails(tables):
    t = tables["position"]
    K = [k.copy() for k in t.K]
    K[0][:, 0] = [3.0, 0.0, 0.0]
    failed = [c.name for c in verify_table(dataclasses.replace(t, K=K)) if not c.ok]
    assert failed == ["stable (monodromy multipliers)", "covariances of these gains"]


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
    assert r.returncode == 0 and "6 of 6 checks hold" in r.stdout
    data = json.loads(good.read_text())
    data["K"][0][1][0] = 5.0
    (tmp_path / "unstable.json").write_text(json.dumps(data))
    r = cli("verify", str(tmp_path / "unstable.json"))
    assert r.returncode == 1 and r.stdout.count("FAIL") == 2  # unstable, so P is not its covariance either
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


def test_spec_comparison_is_linear_in_the_period(tables, monkeypatch):
    """Comparing a long period's gains with the spec's costs O(period): the gain scale was
    recomputed over every phase for each phase (period 10000: verify --spec took 99 s, 5 s now;
    timed by hand, as the suite asserts no times: here the period-4000 table is compared)."""
    import cfdesign.designer as designer
    from cfdesign.gains import Schedule
    from cfdesign.verify import _same_design

    t = tables["position"]
    N = 4000
    long = dataclasses.replace(t, K=[t.K[k % t.period] for k in range(N)], P=[t.P[k % t.period] for k in range(N)],
                               P_filtered=[t.P_filtered[k % t.period] for k in range(N)],
                               schedule=Schedule(t.schedule.measurements,
                                                 tuple(t.schedule.active[k % t.period] for k in range(N))))
    monkeypatch.setattr(designer, "design", lambda spec: long)  # the spec's table: the same one
    checks = _same_design(long, cfdesign.load_spec(cfdesign.example_path("position")), 1e-9)
    assert [c.ok for c in checks] == [True]


def test_identity_is_checked_once_per_distinct_gain(tables, monkeypatch):
    """A phase's bands depend on its own K only: the 49 phases of the position table without a
    GPS fix (K = 0) are one check (period 10000: design 3.3 s -> 1.3 s), and a broken phase is
    still found and named."""
    import cfdesign.verify as verify

    t = tables["position"]
    calls = []
    real = verify.band_polynomials
    monkeypatch.setattr(verify, "band_polynomials", lambda table, k, *a: calls.append(k) or real(table, k, *a))
    assert verify._complementarity(t)[0].ok
    assert calls == [0, 1]
    K = [k.copy() for k in t.K]
    F = t.F.copy()
    F[0, 1] *= 1.5  # another model: the bands no longer sum to one at any phase
    checks = verify._complementarity(dataclasses.replace(t, F=F, K=K))
    assert not checks[0].ok and "worst at phase" in checks[0].detail


PERIOD_100 = json.loads((pathlib.Path(__file__).parent / "fixtures" / "period100_tables.json").read_text())


@pytest.mark.parametrize("name", sorted(PERIOD_100["cases"]))
def test_period_100_tables_are_as_before(name, tmp_path):
    """A 3 Hz sensor beside a 100 Hz one (period 100; a chain in predictor form with its posterior
    through F^-1, the position filter in filter form): the gains, covariances, recorded checks and
    every line of verify are those the designer gave before phases shared their work (fixture
    written by that version), and a save/load round trip keeps them."""
    case = PERIOD_100["cases"][name]
    path = tmp_path / "spec.toml"
    path.write_text(case["spec"])
    spec = cfdesign.load_spec(path)
    table = cfdesign.design(spec)
    for key in ("K", "P", "P_filtered"):
        assert [M.tolist() for M in getattr(table, key)] == case[key], key
    assert table.checks == case["checks"]
    new = "PASS sensor rates match the schedule"  # a check added after the fixture was written
    for t in (table, load_gains(table.save(tmp_path / "gains.json"))):
        lines = [c.line() for c in verify_table(t, spec)]
        assert [x for x in lines if not x.startswith(new)] == case["verify"]
        assert sum(x.startswith(new) for x in lines) == 1


def test_posterior_is_checked_once_per_table(tables, monkeypatch):
    """Whether a table has a posterior depends on F, the gain form and the gains' shape, not on
    the gains' values: building a table asks gain_pair once, not once per phase (period 10000:
    three SVDs of F per phase)."""
    import cfdesign.gains as gains

    t = tables["position"]
    calls = []
    real = gains.linear.gain_pair
    monkeypatch.setattr(gains.linear, "gain_pair", lambda *a: calls.append(1) or real(*a))
    dataclasses.replace(t, output="")
    assert len(calls) == 2  # the default output, then its check
    F = np.zeros_like(t.F)  # no update gain of a predictor table: still refused
    K = [np.zeros_like(k) for k in t.K]
    with pytest.raises(GainTableError, match="posterior output needs"):
        dataclasses.replace(t, gain_form="predictor", F=F, K=K, output="posterior")


def test_schema_names_a_bad_phase_of_a_long_table(tables):
    """The schema walks one phase of K, P, P_filtered and measured when all phases have the
    item type; a phase of another type is still found and named."""
    d = json.loads(tables["position"].to_json())
    for key, bad in (("K", [["x"]]), ("P", [[True]]), ("P_filtered", 1.0), ("measured", [1])):
        broken = json.loads(json.dumps(d))
        broken[key][37] = bad
        with pytest.raises(GainTableError, match=f"schema violation at {key}/37"):
            validate(broken)
    assert validate(d).K[37].tolist() == tables["position"].K[37].tolist()
