"""Hardening, one property-based test per class of fault: mutated valid inputs may only give a
documented outcome - a named error with exit status 2, a verify FAIL with exit 1, or a correct
result - never a traceback, a silent pass, a NaN that spreads, or a lost file."""

import dataclasses
import functools
import json
import math
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cfdesign
from cfdesign.errors import CfdesignError, GainTableError, SpecError
from cfdesign.gains import GainTable, Schedule, load_gains
from cfdesign.runtime import Runtime
from cfdesign.spec import parse_spec
from cfdesign.verify import verify_table

FUZZ = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def heading():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))


@pytest.fixture(scope="module")
def position():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))


# ---------------------------------------------------------------------- 1. verify checks what runs
def _renamed(table, a, b):
    names = {a: b, b: a}
    sensors = tuple(dataclasses.replace(s, name=names.get(s.name, s.name)) for s in table.sensors)
    meas = [s.name for s in sensors if s.role == "measurement"]
    per_phase = [[names.get(x, x) for x in table.schedule.names(k)] for k in range(table.period)]
    return dataclasses.replace(table, sensors=sensors, schedule=Schedule.from_names(meas, per_phase))


MUTATIONS = {
    "swap names": lambda t: _renamed(t, "compass", "odometry"),
    "gain form": lambda t: dataclasses.replace(t, gain_form="filter" if t.gain_form == "predictor" else "predictor"),
    "wrap": lambda t: dataclasses.replace(t, wrap_angle=not t.wrap_angle),
    "output": lambda t: dataclasses.replace(t, output="prior" if t.output == "posterior" else "posterior"),
    "sample time": lambda t: dataclasses.replace(t, sample_time_s=t.sample_time_s * 1.001),
    "rate": lambda t: dataclasses.replace(t, sensors=tuple(dataclasses.replace(s, rate_hz=s.rate_hz * 2)
                                                           if s.name == "gyro" else s for s in t.sensors)),
    "structure": lambda t: dataclasses.replace(t, structure="cf3"),
    # read by the runtime too: Q, R (gains recomputed for another arrival pattern), P (--std),
    # the state names (the estimate columns) and whether the gains are Kalman gains
    "Q": lambda t: dataclasses.replace(t, Q=t.Q * 1.01),
    "R": lambda t: dataclasses.replace(t, R=t.R * 0.99),
    "P": lambda t: dataclasses.replace(t, P=[P * 1.01 for P in t.P]),
    "P_filtered": lambda t: dataclasses.replace(t, P_filtered=[P * 1.01 for P in t.P_filtered]),
    "states": lambda t: dataclasses.replace(t, states=t.states[::-1]),
    "kalman": lambda t: dataclasses.replace(t, provenance={**t.provenance, "solver": {"method": "fixed"}}),
    # not run, but what a reader of the JSON (and design's summary) sees: k22 = 1e300 beside the
    # designed K passed verify --spec
    "named gain": lambda t: dataclasses.replace(t, gains={**t.gains, "k22": 1e300}),
    "named gain left out": lambda t: dataclasses.replace(t, gains={k: v for k, v in t.gains.items() if k != "k22"}),
}


@FUZZ
@given(kind=st.sampled_from(sorted(MUTATIONS)), entry=st.tuples(st.integers(0, 1), st.integers(0, 1)),
       scale=st.sampled_from([1.01, 0.99, 1.0001]))
def test_verify_spec_fails_any_table_that_runs_a_different_filter(heading, kind, entry, scale):
    spec = cfdesign.load_spec(cfdesign.example_path("dckf3"))
    altered = MUTATIONS[kind](heading)
    failed = [c for c in verify_table(altered, spec) if not c.ok]
    assert failed and any(c.name.startswith("spec") or "gains" in c.name for c in failed), kind
    # a changed gain is named with its entry and relative size
    K = heading.K[0].copy()
    K[entry] *= scale
    lines = [c.line() for c in verify_table(dataclasses.replace(heading, K=[K]), spec) if not c.ok]
    assert lines and f"K[0][{entry[0]},{entry[1]}]" in lines[-1] and f"{abs(scale - 1):.2e}"[:3] in lines[-1]


def test_verify_names_the_field_and_cannot_be_forged(heading, tmp_path, cli):
    spec = cfdesign.example_path("dckf3")
    t = dataclasses.replace(MUTATIONS["gain form"](heading), name="x\nPASS everything: fine\nPASS")
    path = t.save(tmp_path / "g.json")
    code, out, _ = cli("verify", path, "--spec", spec)
    assert code == 1 and "FAIL spec: gain_form: the table has 'filter', the spec gives 'predictor'" in out
    assert [line for line in out.splitlines() if line.startswith("PASS everything")] == []


# ---------------------------------------------------------------------- 2. bad numbers never poison
BAD = st.sampled_from([np.inf, -np.inf, np.nan, 1e308, -1e308])


@FUZZ
@given(data=st.data())
def test_bad_readings_are_missing_counted_and_never_spread(heading, data):
    rng = np.random.default_rng(0)
    n = 400
    readings = {s.name: 0.01 * rng.standard_normal(n) for s in heading.sensors}
    placed = data.draw(st.lists(st.tuples(st.sampled_from(list(readings)), st.integers(0, n - 1), BAD),
                                min_size=1, max_size=12))
    for name, k, value in placed:
        readings[name][k] = value
    rt = Runtime(heading)
    est = rt.run(readings)
    assert np.all(np.isfinite(rt.x)) and np.all(np.isfinite(est[: min(k for _, k, _ in placed)]))
    stream = Runtime(heading)
    ref = np.array([stream.step(**{s: readings[s][k] for s in readings}) for k in range(n)])
    assert np.allclose(est, ref, rtol=1e-9, atol=1e-9, equal_nan=True)
    rejected = sum(1 for name, k, v in {(a, b): (a, b, c) for a, b, c in placed}.values() if not np.isnan(v))
    assert sum(rt.counts.get("rejected", {}).values()) == rejected


@FUZZ
@given(state=st.fixed_dictionaries({"x": st.lists(st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [1.7e308, -1e200, 1e150]), max_size=3),
                                    "phase": st.one_of(st.integers(-2, 3), st.floats(), st.booleans(), st.text()),
                                    "u_last": st.lists(st.floats(), max_size=2)}))
def test_restore_validates_what_it_is_given(heading, state):
    rt = Runtime(heading)
    before = rt.state()
    try:
        rt.restore(state)
    except CfdesignError:
        assert rt.state() == before
        return
    assert np.all(np.isfinite(rt.x)) and rt.phase == 0
    for _ in range(3):  # a state it accepts cannot overflow (1.7e308 did: every estimate NaN)
        rt.step(gyro=0.0, compass=0.1, odometry=0.1)
    assert np.all(np.isfinite(rt.x))


def test_table_entries_beyond_the_limit_are_named(heading, tmp_path):
    d = json.loads(heading.to_json())
    d["F"][0][1] = 1e200
    (tmp_path / "g.json").write_text(json.dumps(d))
    with pytest.raises(GainTableError, match=r"F has an entry of magnitude 1e\+200, beyond the limit"):
        load_gains(tmp_path / "g.json")


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_json_tables_with_non_numbers_are_refused(heading, tmp_path, token):
    text = heading.to_json().replace(repr(float(heading.K[0][0, 0])), token, 1)
    (tmp_path / "g.json").write_text(text)
    with pytest.raises(GainTableError, match=f"{token} is not a JSON number"):
        load_gains(tmp_path / "g.json")


@pytest.mark.parametrize("key, value", [("K", 5), ("F", True), ("F", 1.5), ("K", "abc")])
def test_json_tables_with_matrices_that_are_not_lists_are_a_named_error(heading, tmp_path, cli, key, value):
    data = json.loads(heading.to_json())
    data[key] = value
    (tmp_path / "g.json").write_text(json.dumps(data))
    with pytest.raises(GainTableError, match=f"schema violation at {key}"):
        load_gains(tmp_path / "g.json")
    code, _, err = cli("verify", tmp_path / "g.json")
    assert code == 2 and "schema violation" in err


def test_json_tables_may_list_their_sensors_in_any_order(heading):
    data = json.loads(heading.to_json())
    data["sensors"] = data["sensors"][::-1]
    table = cfdesign.GainTable.from_dict(data)
    assert table.sensors == heading.sensors


@FUZZ
@given(field=st.sampled_from(["std", "density"]), value=st.sampled_from([1e200, 1e-160, 1e300, 1e-300, 1e101]))
def test_overflowing_noise_figures_are_named(tmp_path_factory, field, value):
    path = tmp_path_factory.mktemp("spec") / "d.toml"
    path.write_text(f'structure = "dckf3"\n[sensors.gyro]\nrate_hz = 5.0\nnoise = {{ {field} = {value!r} }}\n'
                    'bias = { model = "random_walk", density = 1e-4 }\n[sensors.compass]\nrate_hz = 5.0\n'
                    'noise = { std = 0.1 }\n[sensors.odometry]\nrate_hz = 5.0\nnoise = { std = 0.01 }\n')
    with pytest.raises(SpecError, match=rf"sensors\.gyro\.noise\.{field}"):
        cfdesign.design(cfdesign.load_spec(path))


# ---------------------------------------------------------------------- 3. outputs are never lost
def test_failed_design_keeps_the_previous_table(tmp_path, cli):
    old = tmp_path / "old.json"
    old.write_text("previous")
    code, _, err = cli("design", "-o", old, "--bode", tmp_path / "no" / "such" / "dir" / "b.png")
    assert code == 2 and "cannot write" in err and old.read_text() == "previous"
    code, _, err = cli("design", "-o", old, "--bode", tmp_path)  # a directory
    assert code == 2 and "is a directory" in err and old.read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json"]  # no temporaries left


def test_failed_c_export_keeps_the_previous_set(heading, tmp_path, cli):
    table = heading.save(tmp_path / "g.json")
    out = tmp_path / "c"
    assert cli("export", table, "--format", "c", "-o", out)[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    (out / "dckf3_filter.c").unlink()
    (out / "dckf3_filter.c").mkdir()  # the last file of the set cannot be written
    code, _, err = cli("export", table, "--format", "c", "-o", out, "--precision", "float")
    assert code == 2 and "is a directory" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == {
        k: v for k, v in before.items() if k != "dckf3_filter.c"}


@pytest.mark.parametrize("fmt", ["json", "csv"])
@pytest.mark.parametrize("flag, named", [(["--prediction"], "--prediction only applies"),
                                         (["--precision", "float"], "--precision only applies"),
                                         (["--prefix", "imu"], "--prefix only applies"),
                                         (["--prefix", "imu", "--prediction"], "--prefix, --prediction only apply")])
def test_c_only_export_options_are_refused_for_json_and_csv(heading, tmp_path, cli, fmt, flag, named):
    """`export --format json --prediction` wrote the table with its own output and said nothing;
    the refusal names the options in a sentence ("--prediction only apply" for one of them)."""
    table = heading.save(tmp_path / "g.json")
    code, _, err = cli("export", table, "--format", fmt, "-o", tmp_path / f"out.{fmt}", *flag)
    assert code == 2 and err.count("\n") == 1 and f"{named} to --format c, not {fmt}" in err
    assert not (tmp_path / f"out.{fmt}").exists()


def test_written_files_follow_the_umask(heading, tmp_path, cli):
    old = os.umask(0o022)
    try:
        table = heading.save(tmp_path / "g.json")
        cli("export", table, "--format", "csv", "-o", tmp_path / "g.csv")
    finally:
        os.umask(old)
    for p in (tmp_path / "g.json", tmp_path / "g.csv"):
        assert stat.S_IMODE(p.stat().st_mode) == 0o644


# ---------------------------------------------------------------------- 4. semantic checks
def test_wrap_angle_is_for_angles_only():
    spec = cfdesign.load_spec(cfdesign.example_path("position"))
    with pytest.raises(SpecError, match="wrap_angle: position is not an angle filter"):
        cfdesign.design(dataclasses.replace(spec, wrap_angle=True))


@FUZZ
@given(name=st.sampled_from(["gyrö", "compass", "2x", "class", "ψ"]))
def test_sensor_names_are_ascii_identifiers_everywhere(heading, tmp_path_factory, name):
    d = heading.to_dict()
    d["sensors"] = [dict(s, name=name) if s["name"] == "odometry" else s for s in d["sensors"]]
    d["measured"] = [[name if x == "odometry" else x for x in m] for m in d["measured"]]
    path = tmp_path_factory.mktemp("t") / "g.json"
    path.write_text(json.dumps(d))
    with pytest.raises(GainTableError, match=r"duplicate|identifier|schema"):
        load_gains(path)
    spec = {"structure": "dckf3", "sensors": {name: {"rate_hz": 5.0, "noise": {"std": 0.1}}}}
    if name != "compass":
        with pytest.raises(SpecError, match="ASCII identifiers"):
            cfdesign.parse_spec(spec)


@FUZZ
@given(rate=st.sampled_from([0.5, 50.0, 1000.0, 19500.0, 2e5]), example=st.sampled_from(["dckf3", "position"]),
       form=st.sampled_from(["predictor", "filter"]))
def test_design_and_verify_agree_at_any_rate(rate, example, form):
    spec = cfdesign.load_spec(cfdesign.example_path(example))
    spec = dataclasses.replace(spec, gain_form=form,
                               sensors=tuple(dataclasses.replace(s, rate_hz=rate) for s in spec.sensors))
    table = cfdesign.design(spec)
    assert [c.line() for c in verify_table(table, spec) if not c.ok] == []


def test_tiny_fixed_gains_are_a_clear_error():
    spec = cfdesign.load_spec(cfdesign.example_path("cf3"))
    with pytest.raises((SpecError, CfdesignError), match="gains"):
        cfdesign.design(dataclasses.replace(spec, gains={"k1": 1e-300, "k2": 1e-300}))


# ---------------------------------------------------------------------- 5. sizes checked first
def test_huge_periods_and_files_are_refused_before_work(position, tmp_path):
    d = position.to_dict()
    d["K"] = d["K"] * 300  # period 15,000
    path = tmp_path / "g.json"
    path.write_text(json.dumps(d))
    with pytest.raises(GainTableError, match="period of 15000 phases is more than 10000"):
        load_gains(path)
    (tmp_path / "deep.json").write_text("[" * 100_000)
    with pytest.raises(GainTableError, match=r"nested too deeply|not valid JSON"):
        load_gains(tmp_path / "deep.json")
    (tmp_path / "deep.toml").write_text("a = " + "[" * 100_000)
    with pytest.raises(SpecError, match="malformed TOML"):
        cfdesign.load_spec(tmp_path / "deep.toml")


def test_float_export_refuses_constants_out_of_float_range(heading):
    from cfdesign.codegen import render_c

    B = heading.B.copy()  # (a gain of 1e39 makes the filter unstable, which the export refuses first)
    B[0, 0] = 1e39
    with pytest.raises(CfdesignError, match="outside the range of float"):
        render_c(dataclasses.replace(heading, B=B), precision="float")
    text = render_c(dataclasses.replace(heading, name="ends in a trigraph ??/"))
    assert all("??" not in t for t in text.values())


# ---------------------------------------------------------------------- 6. no tracebacks for users
ARGS = st.lists(st.sampled_from(["design", "verify", "run", "export", "prove", "bode", "--format", "c", "json",
                                 "-o", "/nonexistent/x", ".", "--spec", "--example", "nope", "dckf3", "--gains",
                                 "k1=1", "--sample-time", "-1", "--bands", "99", "--order", "0", "x.json", ""]),
                max_size=6)


@settings(max_examples=60, deadline=None)
@given(argv=ARGS)
def test_cli_never_shows_a_traceback(argv):
    from conftest import run_cli

    code, _, err = run_cli(*argv)
    assert code in (0, 1, 2), (argv, code, err)
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, (argv, err)


@pytest.mark.parametrize("solver", ["dare", "care"])
def test_zero_size_riccati_data_is_a_named_error(solver, capfd):
    import cfdesign.riccati as ric
    from cfdesign.errors import RiccatiError

    with pytest.raises(RiccatiError, match="0x0: a Riccati equation needs at least one state"):
        getattr(ric, solver)(np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)))
    assert "DGGES" not in capfd.readouterr().err  # no raw LAPACK message


@FUZZ
@given(solver=st.sampled_from(["dare", "care", "periodic"]), which=st.sampled_from("ABQR"),
       scale=st.sampled_from([1e151, 1e200, 1e300, -1e200]),
       tol=st.sampled_from([None, 0, -1, np.nan, np.inf, 1.0, "x"]))
def test_riccati_data_beyond_a_double_and_bad_tolerances_are_named(solver, which, scale, tol):
    """A = 1e200 I gave 'SVD did not converge' (LinAlgError) from the PBH test, the periodic solver
    'array must not contain infs or NaNs' from its monodromy product; rtol='x' a UFuncTypeError."""
    import cfdesign.riccati as ric
    from cfdesign.errors import RiccatiError

    data = {"A": np.array([[1.0, 0.2], [0.0, 1.0]]), "B": np.array([[0.02], [0.2]]), "Q": np.eye(2), "R": np.eye(1)}
    if tol is None:
        data[which] = data[which] * scale
    fn = {"dare": ric.dare, "care": ric.care, "periodic": lambda A, B, Q, R, **kw: ric.periodic_dare(
        [A] * 3, [B.T, None, None], [Q] * 3, [R, None, None], **kw)}[solver]
    kw = {} if tol is None else {"tol" if solver == "periodic" else "rtol": tol}
    with pytest.raises(RiccatiError):
        fn(data["A"], data["B"], data["Q"], data["R"], **kw)


def test_a_periodic_product_that_overflows_is_named():
    from cfdesign.errors import RiccatiError
    from cfdesign.riccati import periodic_dare

    N = 400  # 10 ** 400
    with pytest.raises(RiccatiError, match="monodromy matrix\\) overflows"):
        periodic_dare([np.diag([10.0, 1.0])] * N, [np.array([[1.0, 0.0]])] + [None] * (N - 1), [np.eye(2)] * N,
                      [np.eye(1)] + [None] * (N - 1))


# ---------------------------------------------------------------------- found by a second pass
@FUZZ
@given(key=st.sampled_from(["F", "B", "H", "K", "Q", "R", "P", "rate_hz", "sample_time_s", "order"]),
       value=st.sampled_from([10 ** 400, -(10 ** 400), 1e300, 5e-324, 1e-300, 2.0 ** 63]))
def test_out_of_range_table_numbers_are_named_or_fail_verify(heading, position, tmp_path_factory, key, value):
    from conftest import run_cli

    for table in (heading, position):
        d = json.loads(table.to_json())
        if key in ("rate_hz", "order"):
            d["sensors"][0][key] = value
        elif key == "sample_time_s":
            d[key] = value
        else:
            row = d[key][0] if key in ("K", "P") else d[key]
            row[-1][0] = value
        path = tmp_path_factory.mktemp("t") / "g.json"
        path.write_text(json.dumps(d))
        code, out, err = run_cli("verify", path)
        assert code in (0, 1, 2), (key, value, err)
        assert code != 0 or abs(value) < 1 or key in ("P", "Q", "R"), (key, value, out)  # no PASS of a huge one
        assert "internal error" not in err and len(err.strip().splitlines()) <= 1, (key, value, err)


def test_an_overflowing_identity_is_no_identity():
    from cfdesign.linear import identity_residual

    assert identity_residual({"a": ([np.nan], [1.0]), "b": ([1.0], [1.0])}) == np.inf


def single_rate_continuous():
    """A continuous table whose sensors share one rate (what ``discretize`` takes)."""
    return cfdesign.design(parse_spec({"structure": "cf2", "order": 2, "sensors": {
        "rate": {"rate_hz": 100.0, "noise": {"density": 1.7e-3}, "bias": {"model": "random_walk", "density": 2e-4}},
        "angle": {"rate_hz": 100.0, "noise": {"density": 0.01}}}}))


@pytest.mark.parametrize("rate", [1e300, 1e-300, float("nan")])
def test_discretize_refuses_rates_beyond_the_limits(tmp_path, cli, rate):
    table = single_rate_continuous().save(tmp_path / "c.json")
    code, _, err = cli("discretize", table, "--rate-hz", rate, "-o", tmp_path / "d.json")
    assert code == 2 and "--rate-hz" in err
    d = json.loads((tmp_path / "c.json").read_text())
    d["F"][1][1] = 1e5  # expm(F T) = e^2000
    (tmp_path / "c.json").write_text(json.dumps(d))
    code, _, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 50, "-o", tmp_path / "d.json")
    assert code == 2 and "overflows" in err and not (tmp_path / "d.json").exists()


@pytest.mark.skipif(not os.path.exists("/proc/self/mem"), reason="needs /proc/self/mem (a file whose read fails)")
@pytest.mark.parametrize("command", [["noise", "/proc/self/mem", "--column", "a", "--rate-hz", "5"],
                                     ["verify", "/proc/self/mem"], ["design", "/proc/self/mem"]])
def test_a_read_that_fails_after_the_open_is_a_named_error(cli, command):
    code, _, err = cli(*command)
    assert code == 2 and "cannot read" in err and "/proc/self/mem: Input/output error" in err


@pytest.mark.parametrize("roles", [("-o", "--bode"), ("-o", "spec")])
def test_one_file_for_two_roles_is_refused_and_nothing_is_lost(tmp_path, cli, roles):
    spec = tmp_path / "d.toml"
    spec.write_text(cfdesign.example_path("cf3").read_text())
    target = tmp_path / "x.png"
    target.write_bytes(b"previous")
    paths = {"-o": target, "--bode": target, "spec": spec}
    argv = ["design", spec] + [a for r in roles if r != "spec" for a in (r, paths[r])]
    if "spec" in roles:
        argv += ["--bode", spec]
    code, _, err = cli(*argv)
    assert code == 2 and "one file for both" in err
    assert target.read_bytes() == b"previous" and spec.read_text() == cfdesign.example_path("cf3").read_text()


def test_run_and_noise_refuse_an_output_that_is_another(heading, tmp_path, cli):
    table = heading.save(tmp_path / "g.json")
    log = tmp_path / "log.csv"
    log.write_text("time,gyro,compass,odometry\n" + "".join(f"{k / 5},0.01,0.0,0.0\n" for k in range(40)))
    (tmp_path / "link.json").symlink_to(table)
    for argv in (["run", table, log, "-o", tmp_path / "e.png", "--plot", tmp_path / "e.png"],
                 ["run", tmp_path / "link.json", log, "-o", table],
                 ["noise", log, "--column", "gyro", "--rate-hz", 5, "-o", tmp_path / "n.png", "--plot",
                  tmp_path / "n.png"],
                 ["discretize", table, "--rate-hz", 5, "-o", table],
                 ["export", table, "--format", "csv", "-o", tmp_path / "link.json"]):
        code, _, err = cli(*argv)
        assert code == 2 and "one file for both" in err, (argv, err)
    assert cfdesign.load_gains(table).name == heading.name and not (tmp_path / "e.png").exists()


@pytest.mark.parametrize("argv, outputs", [
    (["design", "--example", "cf3", "-o", "g.json", "--bode", "b.png"], ["g.json", "b.png"]),
    (["discretize", "c.json", "--rate-hz", "50", "-o", "d.json"], ["d.json"])])
def test_a_closed_pipe_on_stdout_does_not_stop_the_writes(tmp_path, monkeypatch, argv, outputs):
    import sys

    from cfdesign.cli import main

    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

        def fileno(self):
            raise ValueError("no file")  # _quiet_stdout has nothing to redirect

    monkeypatch.chdir(tmp_path)
    single_rate_continuous().save("c.json")
    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(argv) == 0
    assert all((tmp_path / name).stat().st_size > 0 for name in outputs)


def test_a_symlink_loop_as_output_is_a_named_error(heading, tmp_path, cli):
    """A file export replaces the loop by the file (the atomic rename replaces the link); the C
    export wants a folder there and names what it cannot do."""
    table = heading.save(tmp_path / "g.json")
    loop = tmp_path / "loop.json"
    for fmt in ("json", "csv", "c"):
        if loop.is_symlink() or loop.exists():
            loop.unlink()
        loop.symlink_to(loop)
        code, _, err = cli("export", table, "--format", fmt, "-o", loop)
        if fmt == "c":
            assert code == 2 and "cannot write to" in err and loop.is_symlink(), err
        else:
            assert code == 0 and not loop.is_symlink() and loop.stat().st_size > 0, err
    assert cfdesign.load_gains(table).name == heading.name


def test_a_bad_log_among_many_is_a_summary_row_not_a_dask_traceback(heading, tmp_path):
    from cfdesign.logs.fleet import _run_one

    (tmp_path / "bad.csv").write_text("time,x\n0,1\n")
    row = _run_one(heading, str(tmp_path / "bad.csv"), str(tmp_path / "e.csv"), {})
    assert row["samples"] == 0 and "missing column(s) gyro" in row["error"]


# ---------------------------------------------------------------------- found by the audit of issue 12
SPEC_FIELDS = {  # where a number sits in a valid design, and how to put one there
    "sensors.rate.rate_hz": lambda d, v: d["sensors"]["rate"].__setitem__("rate_hz", v),
    "sensors.angle.noise.std": lambda d, v: d["sensors"]["angle"].__setitem__("noise", {"std": v}),
    "sample_time_s": lambda d, v: d.__setitem__("sample_time_s", v),
    "crossover.hz": lambda d, v: d["crossover"].__setitem__("hz", v),
    "crossover.damping": lambda d, v: d["crossover"].__setitem__("damping", v),
}


@FUZZ
@given(field=st.sampled_from(sorted(SPEC_FIELDS)),
       value=st.sampled_from([10 ** 400, -(10 ** 400), 1e300, 1e200, 1e12, 1e-12, 1e-300, 5e-324]))
def test_design_numbers_beyond_their_limits_are_named(field, value):
    """An integer beyond a double was an OverflowError (exit 3); a crossover at 1e308 Hz or a
    damping of 1e300 overflowed inside the gain formulas (exit 3)."""
    d = {"structure": "cf2", "order": 2, "discrete": True, "crossover": {"hz": 0.5, "damping": 0.7}, "sensors": {
        "rate": {"rate_hz": 100.0, "noise": {"density": 1e-3}}, "angle": {"rate_hz": 100.0, "noise": {"std": 0.01}}}}
    SPEC_FIELDS[field](d, value)
    try:
        table = cfdesign.design(parse_spec(d))
    except SpecError as exc:
        assert field in str(exc) or "gains" in str(exc) or "crossover" in str(exc), str(exc)
        return
    except CfdesignError as exc:
        assert "sensors" in str(exc) or "gains" in str(exc), str(exc)
        return
    assert np.isfinite(table.predicted_std) and all(c.ok for c in verify_table(table)), (field, value)


@FUZZ
@given(gain=st.sampled_from(["k1", "k2"]), value=st.sampled_from([1e-30, 1e-20, 1e-12, 1e-300, 1e-320, 1e-6]))
def test_one_tiny_fixed_gain_is_refused_or_predicts_a_covariance(gain, value):
    """k1 = 1e-30 beside k2 = 15.8 gave P = [[-4e-5, 1e12], [-1e12, -6e-4]]: a negative variance let
    through by a check relative to the garbage entries, and a NaN predicted std with exit 0."""
    from cfdesign.designer import covariance_ok

    spec = cfdesign.load_spec(cfdesign.example_path("cf3"))
    try:
        table = cfdesign.design(dataclasses.replace(spec, gains={**spec.gains, gain: value}))
    except SpecError as exc:
        assert "gains" in str(exc)
        return
    assert np.isfinite(table.predicted_std) and all(covariance_ok(P) for P in table.P + table.P_filtered)


@pytest.mark.parametrize("fails", [False, True])
def test_cli_prints_a_warning_on_one_line_and_only_when_it_succeeds(monkeypatch, cli, fails):
    import warnings

    import cfdesign.cli as cli_module

    def warns(args):
        warnings.warn("marginal solution:\nsecond line", RuntimeWarning, stacklevel=1)
        if fails:
            raise SpecError("the spec is bad")
        return 0

    monkeypatch.setattr(cli_module, "cmd_prove", warns)
    code, _, err = cli("prove", "cf2")
    assert err.strip().splitlines() == (["cfdesign: error: the spec is bad"] if fails else
                                        ["cfdesign: warning: marginal solution: second line"])
    assert code == (2 if fails else 0)


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # a GPS reading every step, on purpose
@FUZZ
@given(value=st.sampled_from([np.float16(0.5), np.float32(0.1), np.array(0.25), 10 ** 400, -(10 ** 400),
                              np.int64(2)]) | st.fractions(max_denominator=1000),
       api=st.sampled_from(["step", "step_values"]))
def test_a_reading_of_any_number_type_runs_as_a_float(position, value, api):
    """A float16 reading made the whole state float16 for good (3 digits, inf past 65504); a
    Fraction was stored as the held input (a state() that json cannot write); an integer beyond a
    double was an OverflowError. Each reading becomes a float, or inf (missing, counted)."""
    from fractions import Fraction

    rt, ref = Runtime(position), Runtime(position)
    step = (lambda r, u: r.step(accelerometer=u, gps=1.0)) if api == "step" else (lambda r, u: r.step_values(u, 1.0))
    try:
        as_float = float(value)
    except OverflowError:
        as_float = np.inf
    for r, u in ((rt, value), (ref, as_float)):
        step(r, u)
        for _ in range(3):
            r.step(accelerometer=0.1, gps=1.0)
    assert all(type(v) is float for v in rt._S[: rt.n] + rt._U), [type(v) for v in rt._S + rt._U]
    assert rt.state() == ref.state() and rt.counts == ref.counts
    json.dumps(rt.state())
    assert isinstance(value, Fraction) or abs(as_float) < 1e300 or rt.counts["rejected"] == {"accelerometer": 1}


BAD_ARRAYS = [["a", "b"], "abc", [None, None], [1 + 1j, 0j], np.zeros(2, dtype=complex), [[1.0], [1.0, 2.0]],
              [10 ** 400, 0], [{}, {}], [b"1", b"2"], np.zeros((2, 2)), [0.1] * 60 + ["x"]]


@FUZZ
@given(where=st.sampled_from(["run", "x0", "restore x", "restore u_last", "step_values", "readings"]),
       value=st.sampled_from([*BAD_ARRAYS, None]))
def test_runtime_arrays_that_are_not_real_numbers_are_named(position, where, value):
    """Runtime(x0=...), run, restore and step_values converted with numpy or Python and let
    ValueError, TypeError or OverflowError out (a complex array lost its imaginary part)."""
    rt = Runtime(position)
    rt.step(accelerometer=0.1, gps=1.0)
    before = rt.state()
    if value is None and where != "readings":
        return
    with pytest.raises(CfdesignError) as raised:
        if where == "run":
            rt.run({"accelerometer": value, "gps": np.ones(len(value)) if len(value) > 2 else [1.0, 1.0]})
        elif where == "readings":  # run(None) was a TypeError; a (2, 2) array was read as four samples
            rt.run(value if value is None or isinstance(value, str) else {"accelerometer": value, "gps": value})
        elif where == "x0":
            Runtime(position, x0=value if isinstance(value, str) else [*value, 0.0])
        elif where == "step_values":
            rt.step_values(*([0.0] * (3 + len(value) % 2)))
        else:
            key = where.split()[1]
            rt.restore({**before, key: list(value) + [0.0] * (3 - len(value) if key == "x" else 0)})
    assert rt.state() == before and "\n" not in str(raised.value)  # numpy's repr of a long array took lines


def test_an_attitude_reading_beyond_a_double_is_missing_and_counted():
    """An int reading too large for a float is an impossible reading, as the runtime's step takes it
    (rejected and counted), not an error; the arguments of the filter beyond a double are errors (below)."""
    from cfdesign.nav import AttitudeFilter

    f = AttitudeFilter(100.0)
    q = f.step([0.0, 0.0, 10 ** 400], [0.0, 0.0, 9.81], [0.2, 0.0, -0.4])
    assert f.missing == {"gyr": 1, "acc": 0, "mag": 0} and all(map(math.isfinite, f.state().values()))
    assert q == AttitudeFilter(100.0).step([0.0, 0.0, math.nan], [0.0, 0.0, 9.81], [0.2, 0.0, -0.4])


@pytest.mark.parametrize("call", ["declination", "state", "bias prior"])
def test_attitude_numbers_beyond_a_double_are_named(call):
    from cfdesign.errors import AttitudeInputError
    from cfdesign.nav import AttitudeFilter, estimate_attitude

    f = AttitudeFilter(100.0)
    with pytest.raises(AttitudeInputError):
        if call == "declination":
            estimate_attitude(np.zeros((2, 3)), np.tile([0, 0, 9.81], (2, 1)), None, 100.0, declination_rad=10 ** 400)
        elif call == "state":
            f.restore({**f.state(), "bx": 10 ** 400})
        else:  # its square overflowed
            estimate_attitude(np.zeros((2, 3)), np.tile([0, 0, 9.81], (2, 1)), None, 100.0, gyro_bias_std0=1e308)


@FUZZ
@given(rate=st.sampled_from(["100", "1e-300", "1e300", "1e12"]),
       cell=st.sampled_from(["0.5", "1e160", "1e308", "-1e200"]))
def test_noise_rates_and_readings_beyond_their_limits_are_named(tmp_path_factory, rate, cell):
    """cfdesign noise --rate-hz 1e-300 overflowed (exit 3), 1e300 left no averaging time (exit 3), a
    reading of 1e160 made an infinite Allan variance and a NaN fit (exit 3)."""
    from conftest import run_cli

    d = tmp_path_factory.mktemp("n")
    values = [repr(0.01 * math.sin(k)) for k in range(300)]
    values[7] = cell
    (d / "n.csv").write_text("x\n" + "\n".join(values) + "\n")
    code, out, err = run_cli("noise", d / "n.csv", "--column", "x", "--rate-hz", rate, "-o", d / "n.toml")
    assert code in (0, 2) and "internal error" not in err and len(err.strip().splitlines()) <= 1, err
    assert code == 2 or ("nan" not in out and "inf" not in out), out


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
@pytest.mark.parametrize("command", ["export csv", "export json", "run", "design"])
def test_an_output_that_is_a_pipe_or_a_device_is_written_into_not_replaced(heading, tmp_path, cli, command):
    """The atomic rename put a regular file in place of the target: -o /dev/stdout wrote nothing
    to stdout and, as root, -o /dev/null replaced /dev/null itself for every process."""
    import threading

    table = heading.save(tmp_path / "g.json")
    log = tmp_path / "log.csv"
    log.write_text("time,gyro,compass,odometry\n" + "".join(f"{k / 5},0.01,0.0,0.0\n" for k in range(40)))
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()), daemon=True)
    reader.start()
    argv = {"export csv": ["export", table, "--format", "csv", "-o", fifo],
            "export json": ["export", table, "--format", "json", "-o", fifo],
            "run": ["run", table, log, "-o", fifo], "design": ["design", "--example", "cf3", "-o", fifo]}[command]
    code, _, err = cli(*argv)
    reader.join(timeout=10)
    assert code == 0, err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and got and got[0], command
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "g.json", "log.csv"]  # no temporaries
    if command == "export json":
        assert json.loads(got[0])["name"] == heading.name
    try:
        os.mknod(tmp_path / "null", 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except (OSError, AttributeError):
        return  # no device nodes here (not root, or a container without CAP_MKNOD)
    assert cli(*argv[:-1], tmp_path / "null")[0] == 0
    assert stat.S_ISCHR(os.lstat(tmp_path / "null").st_mode)


@FUZZ
@given(key=st.sampled_from(["K", "F", "gain_form", "wrap_angle", "sample_time_s", "name", "role", "rate_hz"]))
def test_a_key_given_twice_in_a_table_is_refused(heading, tmp_path_factory, key):
    """json keeps the last of two keys: a table could show one K (to a reader, a diff) and run another."""
    text = json.dumps(heading.to_dict())
    doubled = text.replace(f'"{key}": ', f'"{key}": null, "{key}": ', 1)  # json keeps the last: the real one
    path = tmp_path_factory.mktemp("t") / "g.json"
    path.write_text(doubled)
    json.loads(doubled)  # valid JSON for json itself
    with pytest.raises(GainTableError, match=f"key '{key}' given twice"):
        load_gains(path)


@pytest.mark.parametrize("name", ["x\nPASS all checks", "x\x1b[2J", "x\rPASS", "x\u2028PASS", "x\x00"])
def test_design_prints_a_table_name_on_its_own_line_only(tmp_path, cli, name):
    """The summary of design (and discretize) printed the design file's name as it was: a newline
    forged a line of its own, an escape sequence reached the terminal."""
    spec = tmp_path / "d.toml"
    body = [line for line in cfdesign.example_path("cf3").read_text().splitlines() if not line.startswith("name")]
    spec.write_text(f"name = {json.dumps(name)}\n" + "\n".join(body) + "\n")
    code, out, _ = cli("design", spec)
    assert code == 0 and all(line.isprintable() for line in out.splitlines())
    assert not any(line.startswith("PASS") for line in out.splitlines()), out


def test_a_design_with_too_many_sensors_is_refused_before_work():
    """1000 position sensors on a chain (a 60 kB file) took 17 GB and did not finish; 100 took 4 min."""
    from cfdesign.spec import MAX_SENSORS

    sensors = {f"gps{i}": {"measures": "position", "rate_hz": 100.0, "noise": {"std": 1.0}} for i in range(1000)}
    sensors["acc"] = {"measures": "acceleration", "rate_hz": 100.0, "noise": {"std": 0.01}}
    with pytest.raises(SpecError, match=f"1001 sensors is more than a design takes \\(limit {MAX_SENSORS}\\)"):
        parse_spec({"structure": "chain", "order": 2, "discrete": True, "sensors": sensors})


@pytest.mark.parametrize("rtol", ["nan", "inf", "-1", "1e300", "1"])
def test_verify_refuses_a_tolerance_that_passes_anything(heading, tmp_path, cli, rtol):
    """--rtol inf (or nan, or 1e300) passed a table whose gains and sample time were 1.5 times the spec's."""
    table = dataclasses.replace(heading, sample_time_s=heading.sample_time_s * 1.5, K=[heading.K[0] * 1.5])
    code, _, err = cli("verify", table.save(tmp_path / "g.json"), "--spec", cfdesign.example_path("dckf3"),
                       "--rtol", rtol)
    assert code == 2 and "--rtol" in err and len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------------- found by the adversarial driver of issue 12
BAD_PATHS = {"overlong name": lambda d: d / ("x" * 300), "NUL character": lambda d: str(d / "a\x00b.json"),
             "full disk": lambda d: "/dev/full", "missing parent": lambda d: d / "no" / "such" / "f.json",
             "a directory": lambda d: d, "unwritable place": lambda d: "/proc/version"}
PATH_COMMANDS = {  # each writes its output last, after another file it must not have replaced
    "design -o": lambda t, o: ["design", "--example", "cf3", "-o", o],
    "design --bode": lambda t, o: ["design", "--example", "cf3", "-o", t / "keep.json", "--bode", o],
    "export csv": lambda t, o: ["export", t / "g.json", "--format", "csv", "-o", o],
    "run -o": lambda t, o: ["run", t / "g.json", t / "log.csv", "-o", o],
    "run --plot": lambda t, o: ["run", t / "g.json", t / "log.csv", "-o", t / "keep.csv", "--plot", o],
    "run log": lambda t, o: ["run", t / "g.json", o, "-o", t / "keep.csv"],
    "noise --plot": lambda t, o: ["noise", t / "log.csv", "--column", "gyro", "--rate-hz", 5, "--plot", o],
    "verify": lambda t, o: ["verify", o],
}


@settings(FUZZ, max_examples=12)
@given(command=st.sampled_from(sorted(PATH_COMMANDS)), bad=st.sampled_from(sorted(BAD_PATHS)))
def test_paths_the_system_refuses_are_named_and_nothing_is_replaced(heading, tmp_path_factory, command, bad):
    """An overlong file name or a NUL character reached Path.is_dir() and came out as an internal
    error (exit 3); ``run -o est.csv --plot /dev/full`` replaced est.csv before the plot failed."""
    from conftest import run_cli

    d = tmp_path_factory.mktemp("p")
    heading.save(d / "g.json")
    (d / "log.csv").write_text("time,gyro,compass,odometry\n" + "".join(f"{k / 5},0.01,0.1,0.1\n" for k in range(40)))
    for keep in ("keep.json", "keep.csv"):
        (d / keep).write_text("previous")
    code, _, err = run_cli(*PATH_COMMANDS[command](d, BAD_PATHS[bad](d)))
    assert code == 2 and "internal error" not in err and len(err.strip().splitlines()) == 1, (code, err)
    assert (d / "keep.json").read_text() == "previous" and (d / "keep.csv").read_text() == "previous"
    assert not [p.name for p in d.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("entry", [("F", 0, 0, 1e6), ("K", 0, 0, 1e4)])
def test_a_table_whose_filter_diverges_is_not_run_to_empty_estimates(position, tmp_path, cli, entry):
    """An unstable table (an edited F or K) wrote estimate columns of NaN (empty cells) with exit 0."""
    key, i, j, value = entry
    d = position.to_dict()
    (d[key][0] if key == "K" else d[key])[i][j] = value
    (tmp_path / "g.json").write_text(json.dumps(d))
    (tmp_path / "log.csv").write_text("time,accelerometer,gps\n" + "".join(
        f"{k / 50},0.01,{1.0 if k % 50 == 0 else ''}\n" for k in range(3000)))
    (tmp_path / "e.csv").write_text("previous")
    code, _, err = cli("run", tmp_path / "g.json", tmp_path / "log.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "diverge" in err and "unstable" in err and len(err.strip().splitlines()) == 1, err
    assert (tmp_path / "e.csv").read_text() == "previous"
    with pytest.raises(CfdesignError, match="unstable"):  # the Python runtime refuses it as well
        Runtime(GainTable.from_dict(d))


def test_a_table_no_sensor_corrects_runs_and_an_unstable_one_is_named(heading):
    """Radius 1 (dead reckoning: every gain 0) runs, the heading integrating the gyro; above 1 is
    refused before any step, naming the growth a period (it ran the state to inf or NaN)."""
    d = heading.to_dict()
    d["K"] = [np.zeros_like(np.asarray(K)).tolist() for K in d["K"]]
    rt = Runtime(GainTable.from_dict(d))
    names = {s.name: np.full(100, 0.1 if s.role == "input" else np.nan) for s in heading.sensors}
    assert rt.run(names)[-1] == pytest.approx(99 * 0.1 * heading.sample_time_s)
    d["F"][0][0] = 1.05
    with pytest.raises(CfdesignError, match=r"grow by 1\.05"):
        Runtime(GainTable.from_dict(d))


def test_a_time_gap_beyond_the_limit_is_named_before_the_work(heading, tmp_path, cli):
    """A time jump of 2e8 s in a 5 Hz log ran the filter over 1e9 ticks (minutes, gigabytes)."""
    from cfdesign.timing import MAX_GAP_TICKS

    rows = [k * 0.2 + (MAX_GAP_TICKS * 0.2 + 1.0 if k > 20 else 0.0) for k in range(40)]
    (tmp_path / "log.csv").write_text("time,gyro,compass,odometry\n" + "".join(f"{t!r},0.01,0.1,0.1\n" for t in rows))
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "line 23" in err and f"more than {MAX_GAP_TICKS} ticks" in err, err


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
@pytest.mark.parametrize("command", [["verify", "/dev/zero"], ["design", "/dev/zero"], ["verify", "g.json", "--spec",
                                     "/dev/zero"], ["run", "g.json", "/dev/zero", "-o", "e.csv"],
                                     ["noise", "/dev/zero", "--column", "x", "--rate-hz", "5"]])
def test_an_endless_input_is_refused_not_read_into_memory(heading, tmp_path, monkeypatch, cli, command):
    """A device has size 0 for stat: /dev/zero as a table, design file or log was read until the
    memory ran out (22 GB, then the kernel killed the process)."""
    monkeypatch.chdir(tmp_path)
    heading.save("g.json")
    code, _, err = cli(*command)
    assert code == 2 and ("more than" in err or "it is a device" in err) and len(err.strip().splitlines()) == 1, err


@FUZZ
@given(exponent=st.integers(-110, 99))
def test_noise_fits_readings_of_any_scale_or_names_the_scale(exponent):
    """The fit weighted by 1/variance squared them in its normal equations: readings of 1e-75 gave
    a CI up to inf, 1e-90 a CI of nan to nan (exit 0), 1e-160 an internal error."""
    from cfdesign.allan import identify_noise
    from cfdesign.errors import InputError

    y = 10.0 ** exponent * np.random.default_rng(0).standard_normal(3000)
    try:
        fit = identify_noise(y, 100.0)
    except InputError as exc:
        assert np.ptp(y) < 1e-100 and "check the units" in str(exc), str(exc)
        return
    white = fit.terms["white"]
    assert np.all(np.isfinite(white.ci)) and abs(white.value / (10.0 ** exponent / 10) - 1) < 0.05, white


@pytest.mark.parametrize("path, value", [(("checks", "complementary"), "NaN"), (("checks", "stable"), 1),
                                         (("checks", "poles"), [["nan", 0.0]]), (("checks", "poles"), [[1.0]]),
                                         (("options", "order"), "inf"), (("options", "discrete"), "yes")])
def test_a_tables_recorded_checks_have_their_types(tmp_path, cli, path, value):
    """A table's checks took any JSON value: discretize copied complementary = 'NaN' into its table
    and printed 'complementary: NaN' with exit 0; poles as text were written back by export."""
    d = single_rate_continuous().to_dict()
    d[path[0]][path[1]] = value
    (tmp_path / "c.json").write_text(json.dumps(d))
    with pytest.raises(GainTableError, match=f"schema violation at {path[0]}/"):
        load_gains(tmp_path / "c.json")
    code, _, err = cli("discretize", tmp_path / "c.json", "--rate-hz", 100, "-o", tmp_path / "d.json")
    assert code == 2 and "schema violation" in err


@pytest.mark.parametrize("cell", ["inf", "", "nan", "1e300"])
def test_a_reference_with_no_finite_reading_prints_no_nan(heading, tmp_path, cli, cell):
    """A reference column of inf (or empty) printed 'RMS error of heading: nan rad' with exit 0."""
    (tmp_path / "log.csv").write_text("time,gyro,compass,odometry,truth\n" + "".join(
        f"{k / 5},0.01,0.1,0.1,{cell}\n" for k in range(40)))
    code, out, _ = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.csv", "-o", tmp_path / "e.csv",
                       "--reference", "truth")
    assert code in (0, 2) and "nan" not in out.lower(), out


REPRODUCE_BAD = {"--runs": ["-1", "0", "20000", "99999999999999999999", "1e-300"],
                 "--seed": ["-1", "-5", "99999999999999999999", "1e308"],
                 "--duration": ["-1", "0", "1e-300", "5", "nan", "inf", "20000", "1e308"]}


@FUZZ
@given(data=st.data(), argv=st.sampled_from([["carreira", "--runs"], ["helicopter", "--runs"], ["carreira", "--seed"],
                                             ["helicopter", "--seed"], ["compare", "--seed"],
                                             ["compare", "--duration"]]))
def test_reproduce_options_out_of_range_are_named_before_the_work(data, argv):
    """A negative seed was a ValueError from numpy, --runs 10**20 an OverflowError, --duration 1e-300 an
    IndexError and 1e20 numpy's 'Maximum allowed size exceeded': internal errors (exit 3)."""
    from conftest import run_cli

    value = data.draw(st.sampled_from(REPRODUCE_BAD[argv[1]]))
    code, _, err = run_cli("reproduce", *argv, value, "--json")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "internal error" not in err, (argv, value, err)


@pytest.mark.parametrize("loader", ["load_gains", "load_spec"])
def test_a_path_with_a_nul_character_is_named_by_the_loaders(loader):
    """open() raises ValueError for a NUL character: it left load_gains and load_spec as itself."""
    with pytest.raises(CfdesignError, match=r"cannot read .*embedded null byte"):
        getattr(cfdesign, loader)("a\x00b.json")


@FUZZ
@given(header=st.sampled_from(["time,gyro,compass,odometry,", "time,,gyro,compass,odometry",
                               "time,gyro,compass,odometry, ", "time,gyro,,compass,odometry,,",
                               "time,gyro,compass,odometry,\t", "\t,time,gyro,compass,odometry"]),
       big=st.sampled_from([1e308, -1e300, 1e13]))
def test_a_log_column_without_a_name_and_a_reference_beyond_the_limit_are_taken(heading, tmp_path_factory, header,
                                                                                big):
    """A trailing comma in a log's header (a column named '') or a tab as a name was an internal error
    (KeyError); one reference value of 1e308 made the printed RMS error inf."""
    from conftest import run_cli

    d = tmp_path_factory.mktemp("h")
    names = [h.strip() for h in header.split(",")]
    rows = []
    for k in range(40):
        cells = {"time": f"{k / 5}", "gyro": "0.01", "compass": "0.1", "odometry": "0.1"}
        rows.append(",".join(cells.get(n, repr(big) if k == 7 else "0.1") for n in names))
    (d / "log.csv").write_text(header + "\n" + "\n".join(rows) + "\n")
    reference = ["--reference", "Unnamed: 4"] if names[4:5] == [""] else []  # names: stripped, as the log's
    code, out, err = run_cli("run", heading.save(d / "g.json"), d / "log.csv", "-o", d / "e.csv", *reference)
    assert code == 0 and "inf" not in out and "nan" not in out, (out, err)
    assert "Unnamed:" in (d / "e.csv").read_text().splitlines()[0]


CHOICE_FIELDS = {"output": lambda d, v: d.__setitem__("output", v),
                 "gain_form": lambda d, v: d.__setitem__("gain_form", v),
                 "sensors.gps.role": lambda d, v: d["sensors"]["gps"].__setitem__("role", v),
                 "sensors.accelerometer.bias.model": lambda d, v: d["sensors"]["accelerometer"].__setitem__(
                     "bias", {"model": v, "density": 1e-4})}


@FUZZ
@given(field=st.sampled_from(sorted(CHOICE_FIELDS)),
       value=st.sampled_from([{}, [], -1, 3, "inf", "\x1b[2J", "\u202e", True, "", "Prior", 1.5]))
def test_a_choice_field_with_another_value_is_named(field, value):
    """output = {} (or any value not allowed) in a design file was an internal error: the message
    joined the allowed values, None among them (TypeError)."""
    d = {"structure": "position", "sensors": {
        "accelerometer": {"rate_hz": 50.0, "noise": {"std": 0.006}},
        "gps": {"rate_hz": 1.0, "noise": {"std": 3.0}}}}
    CHOICE_FIELDS[field](d, value)
    with pytest.raises(SpecError, match=f"{field} must be one of"):
        parse_spec(d)


# ---------------------------------------------------------------------- navigation baselines: bad readings, arguments
def _baseline_runs(n=40, seed=0):
    """Each baseline filter with clean readings for ``n`` samples of a sensor at rest (GPS fixes
    every 10th row, scattered by 1 m): ``{name: (run(readings), readings, {reading: rows that may
    be corrupted})}``."""
    from cfdesign.nav import PositionFilter
    from cfdesign.nav.adaptive import AdaptiveCF
    from cfdesign.nav.planar_ekf import PlanarEKF
    from cfdesign.nav.strapdown_ekf import StrapdownEKF

    rng = np.random.default_rng(seed)
    gyr = rng.normal(0.0, 0.05, (n, 3))
    acc = np.tile([0.0, 0.0, 9.8], (n, 1)) + rng.normal(0.0, 0.05, (n, 3))
    mag = np.tile([0.0, 20.0, -40.0], (n, 1))
    fixes = np.full((n, 3), np.nan)
    fixes[::10] = rng.normal(0.0, 1.0, (len(fixes[::10]), 3))
    every, fix_rows = np.arange(n), np.arange(0, n, 10)
    ekf = StrapdownEKF(10.0, gyro_noise_std=1e-3, accel_noise_std=1e-2, gyro_bias_density=1e-5,
                       accel_bias_density=1e-4, scale_density=1e-6, gps_pos_std=2.0, gps_vel_std=0.2, triad_std=0.02)
    planar = PlanarEKF(odo_noise_std=0.01, gyro_noise_std=0.01, kappa_omega=0.1, kappa_rho=0.1, sigma_heading=0.1)
    position = PositionFilter(10.0, 1.0, accel_noise_std=0.05, accel_bias_density=1e-3, gps_noise_std=2.0)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    mode = np.where(np.isfinite(fixes[:, 0]), "single", "")
    return {
        "strapdown": (lambda r: ekf.run(r["gyr"], r["acc"], mag, r["gps_pos"]),
                      {"gyr": gyr, "acc": acc, "gps_pos": fixes}, {"gyr": every[1:], "acc": every[1:],
                                                                   "gps_pos": fix_rows[1:]}),
        "planar": (lambda r: planar.run(r["distance"], r["gyro_z"], 0.1, r["gps_xy"], mode),
                   {"distance": np.zeros(n), "gyro_z": gyr[:, 2], "gps_xy": fixes[:, :2]},
                   {"distance": every[1:], "gyro_z": every[1:], "gps_xy": fix_rows[1:]}),
        "adaptive": (lambda r: AdaptiveCF(10.0).run(r["gyr"], acc, mag, r["odometry_speed"], r["gps_enu"],
                                                    np.full(n, 8), initial_position=[0.0, 0.0, 0.0]),
                     {"gyr": gyr, "odometry_speed": np.zeros(n), "gps_enu": fixes},
                     {"gyr": every[1:], "odometry_speed": every[1:], "gps_enu": fix_rows[1:]}),
        "position": (lambda r: position.run(r["acc_body"], r["quat_nb"], r["gps_enu"]),
                     {"acc_body": acc, "quat_nb": quat, "gps_enu": fixes},
                     {"acc_body": every[1:], "quat_nb": every[1:], "gps_enu": fix_rows[1:]}),
    }


_BASELINES = _baseline_runs()
_FINAL = {"strapdown": lambda e: e.position[-1], "planar": lambda e: np.array([e.x[-1], e.y[-1]]),
          "adaptive": lambda e: np.concatenate([e.position[-1], e.euler[-1]]), "position": lambda e: e.position[-1]}


@settings(FUZZ, max_examples=15)
@given(data=st.data(), which=st.sampled_from(sorted(_BASELINES)))
def test_baseline_filters_count_bad_readings_as_missing_and_recover(data, which):
    """The EKFs, the adaptive CF and the position filter ran a NaN or inf gyro row into LinAlgError or
    a math domain error, nan_to_num made an inf rate 1.8e308 (NaN attitudes), a NaN specific force
    refused the whole position run; now every non-finite or impossible reading is missing, held
    (inputs) or skipped (fixes), counted, and the run is the run with those readings missing (NaN)."""
    run, readings, rows = _BASELINES[which]
    bad = {name: a.copy() for name, a in readings.items()}
    missing = {name: a.copy() for name, a in readings.items()}
    placed = data.draw(st.lists(st.tuples(st.sampled_from(sorted(rows)), st.integers(0, 10 ** 6),
                                          st.sampled_from([np.inf, -np.inf, 1e300, 1e13])), min_size=1, max_size=4))
    hit = {}
    for name, k, value in placed:
        row = rows[name][k % len(rows[name])]
        at = (row, 0) if bad[name].ndim == 2 else row          # one entry: the row is unusable
        bad[name][at], missing[name][at] = value, np.nan
        hit.setdefault(name, set()).add(row)
    est, ref = run(bad), run(missing)
    assert np.isfinite(_FINAL[which](est)).all()
    assert est.missing == {**dict.fromkeys(est.missing, 0), **{name: len(r) for name, r in hit.items()}}
    for key, value in vars(est).items():      # an impossible reading is a missing one: nothing else changes
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, vars(ref)[key], err_msg=key)



def _bad_baseline_calls():
    from cfdesign.nav import PositionFilter
    from cfdesign.nav.adaptive import AdaptiveCF
    from cfdesign.nav.planar_ekf import PlanarEKF
    from cfdesign.nav.strapdown_ekf import StrapdownEKF

    figures = dict(gyro_noise_std=1e-3, accel_noise_std=1e-2, gyro_bias_density=1e-5, accel_bias_density=1e-4,
                   scale_density=1e-6, gps_pos_std=2.0, gps_vel_std=0.2, triad_std=0.02)
    planar = dict(odo_noise_std=0.01, gyro_noise_std=0.01, kappa_omega=0.1, kappa_rho=0.1, sigma_heading=0.1)
    n = 20
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 9.8], (n, 1)), np.tile([0.0, 20.0, -40.0], (n, 1))
    gps, quat = np.full((n, 3), np.nan), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    odo, mode = np.full(n, 0.1), np.full(n, "")
    pos = PositionFilter(10.0, 1.0, accel_noise_std=0.05, accel_bias_density=1e-3, gps_noise_std=2.0)
    return {
        "rate_hz": [lambda: StrapdownEKF(0.0, **figures), lambda: StrapdownEKF(float("nan"), **figures),
                    lambda: StrapdownEKF("fast", **figures), lambda: AdaptiveCF(1e-300)],
        "gyro_noise_std": [lambda: StrapdownEKF(50.0, **{**figures, "gyro_noise_std": float("nan")}),
                           lambda: PlanarEKF(**{**planar, "gyro_noise_std": -1.0})],
        "kappa_rho": [lambda: PlanarEKF(**{**planar, "kappa_rho": 0.0})],
        "initial_std": [lambda: StrapdownEKF(50.0, **figures, initial_std={"velocty": 1.0}),
                        lambda: PlanarEKF(**planar, initial_std=(1.0, 1.0, 1.0))],
        "gyr": [lambda: StrapdownEKF(50.0, **figures).run(gyr.T, acc, mag, gps),
                lambda: StrapdownEKF(50.0, **figures).run(gyr[:0], acc[:0], mag[:0], gps[:0]),
                lambda: AdaptiveCF(10.0).run(gyr + 1j, acc, mag, odo, gps, np.full(n, 8))],
        "mag": [lambda: StrapdownEKF(50.0, **figures).run(gyr, acc, mag[:5], gps[:5])],
        "acc_body": [lambda: pos.run(acc.astype(str), quat, gps), lambda: pos.run(acc[:0], quat[:0], gps[:0])],
        "initial_position": [lambda: pos.run(acc, quat, gps, initial_position=[0.0, 0.0]),
                             lambda: AdaptiveCF(10.0).run(gyr, acc, mag, odo, gps, np.full(n, 8),
                                                          initial_position=[np.nan, 0.0, 0.0]),
                             lambda: StrapdownEKF(50.0, **figures).run(gyr, acc, mag, gps,
                                                                      initial_position=[np.inf, 0.0, 0.0])],
        "initial_bias": [lambda: pos.run(acc, quat, gps, initial_bias="abc")],
        "dt_s": [lambda: PlanarEKF(**planar).run(odo, odo, 0.0, gps[:, :2], mode),
                 lambda: PlanarEKF(**planar).run(odo, odo, np.full(n, np.nan), gps[:, :2], mode),
                 lambda: PlanarEKF(**planar).run(odo, odo, [[0.1, 0.1], [0.1]], gps[:, :2], mode)],
        "gps_mode": [lambda: PlanarEKF(**planar).run(odo, odo, 0.1, gps[:, :2], np.full(n, "DGPS"))],
        "initial_state": [lambda: PlanarEKF(**planar).run(odo, odo, 0.1, gps[:, :2], mode, initial_state=[0, 0, 0])],
    }


@pytest.mark.parametrize(("name", "i"), [(name, i) for name, calls in _bad_baseline_calls().items()
                                         for i in range(len(calls))])
def test_baseline_filters_name_a_bad_argument(name, i):
    """A rate of 0 raised ZeroDivisionError, NaN noise LinAlgError, transposed or empty arrays
    numpy's ValueError, AxisError or IndexError, text and complex arrays were parsed or cut to their
    real part, a wrong-length initial position ValueError, a GPS mode spelt otherwise ran as no fix."""
    with pytest.raises(cfdesign.errors.InputError, match=rf"\b{name}\b"):
        _bad_baseline_calls()[name][i]()


@pytest.mark.parametrize("prefix", ["_x", "_heading", "_"])
def test_a_table_c_prefix_with_a_leading_underscore_is_refused_as_the_attitude_export_refuses_it(heading, tmp_path,
                                                                                                 cli, prefix):
    """cfdesign export --format c --prefix _x wrote _x_init, _x_step (file scope: reserved in C) and
    the guard _X_FILTER_H (reserved everywhere); the attitude export refused the same prefix."""
    from cfdesign.codegen.attitude import render_attitude_c
    from cfdesign.nav import AttitudeFilter

    heading.save(tmp_path / "g.json")
    code, _, err = cli("export", str(tmp_path / "g.json"), "--format", "c", "-o", str(tmp_path / "c"), "--prefix",
                       prefix)
    assert code == 2 and "C prefix" in err and "starts with '_'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c").exists()
    with pytest.raises(CfdesignError, match="starts with '_'"):
        render_attitude_c(AttitudeFilter(100.0), prefix=prefix)


# ---------------------------------------------------------------------- C names: reserved or not significant
#: spellings C99 reserves (7.1.3, 7.26; FE_ 7.6, FP_ 7.12), written here from the standard, not from the code
_C_RESERVED = r"((str|mem|wcs|is|to)[a-z]|E[0-9A-Z]|LC_[A-Z]|SIG_?[A-Z]|(PRI|SCN)[a-zX]|F[EP]_[A-Z]|__|_[A-Z])"


@settings(FUZZ, max_examples=30)
@given(prefix=st.one_of(st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,40}", fullmatch=True),
                        st.sampled_from(["string", "strf", "memo", "wcsx", "isx", "tox", "Ekf", "E1", "signal", "lc_x",
                                         "pri", "scnx", "fp_x", "fe_x", "a" * 27, "b" * 26, "heading"])),
       sensor=st.sampled_from(["compass", "min", "c", "max", "x" * 60, "y" * 50]),
       attitude=st.booleans())
def test_c_export_makes_only_names_c99_leaves_free_and_significant(heading, prefix, sensor, attitude):
    """The export wrote string_init, isx_step (reserved for <string.h>, <ctype.h>), the macro EKF_N
    (<errno.h>), INTEGRATOR_Y_MIN (<stdint.h>) and external names beyond 31 characters that C99
    need not tell apart (a 30-character prefix: <prefix>_init and <prefix>_step); now each is
    refused on one line naming the C name and the rule."""
    import re

    from cfdesign.codegen import render_c
    from cfdesign.codegen.attitude import render_attitude_c

    d = heading.to_dict()
    d["sensors"] = [dict(s, name=sensor) if s["name"] == "compass" else s for s in d["sensors"]]
    d["measured"] = [[sensor if x == "compass" else x for x in m] for m in d["measured"]]
    table = GainTable.from_dict(d)
    try:
        files = render_attitude_c(_attitude(), prefix=prefix) if attitude else render_c(table, prefix=prefix)
    except CfdesignError as e:
        assert "\n" not in str(e) and ("C name" in str(e) or "C prefix" in str(e) or "header" in str(e)), str(e)
        return
    text = "\n".join(files.values())
    names = set(re.findall(rf"\b(?:{prefix}|{prefix.upper()})_\w+\b(?!\.)", text))
    assert {f"{prefix}_init", f"{prefix}_step"} <= names
    for name in names:
        assert not re.match(_C_RESERVED, name) and not re.match(r"U?INT\w*(_MAX|_MIN|_C)\Z", name), name
        assert len(name) <= (31 if name in (f"{prefix}_init", f"{prefix}_step") else 63), name


@functools.lru_cache(maxsize=1)
def _attitude():
    from cfdesign.nav import AttitudeFilter

    return AttitudeFilter(100.0)


@pytest.mark.parametrize("readings", ["abc", [[0.1, 0.2], [0.3]], None, np.full(4096, 0.01 + 1j)],
                         ids=["text", "ragged", "None", "complex"])
def test_noise_readings_that_are_not_real_numbers_are_named(readings):
    """identify_noise gave numpy's ValueError for text or a ragged list, and cut complex readings
    to their real part with only a ComplexWarning."""
    with pytest.raises(cfdesign.errors.InputError, match="readings: real numbers are needed"):
        cfdesign.identify_noise(readings, 100.0)


def _planar_drive(n=300, seed=0):
    """A robot on a circle at 2 m/s (10 Hz), odometer scale 1.05, 1-m GPS fixes at 1 Hz: the
    readings and the true track."""
    rng = np.random.default_rng(seed)
    dt, w = 0.1, np.full(n, 0.1)
    th = np.cumsum(w * dt)
    truth = np.c_[np.cumsum(0.2 * np.cos(th - 0.005)), np.cumsum(0.2 * np.sin(th - 0.005))]
    fixes = np.full((n, 2), np.nan)
    fixes[::10] = truth[::10] + rng.normal(0.0, 1.0, (n // 10, 2))
    readings = {"distance": 0.2 / 1.05 + rng.normal(0.0, 0.005, n), "gyro_z": w + rng.normal(0.0, 0.005, n),
                "gps_xy": fixes}
    return readings, truth


_PLANAR = dict(odo_noise_std=0.005, gyro_noise_std=0.005, kappa_omega=0.1, kappa_rho=0.1, sigma_heading=0.1,
               gps_std={"single": 1.0})


@settings(FUZZ, max_examples=10)
@given(which=st.sampled_from(["distance", "gyro_z", "gps_xy"]), row=st.integers(1, 29),
       value=st.sampled_from([1e6, -1e6, 1e4, 1e3, -500.0]))
def test_planar_ekf_takes_an_impossible_reading_as_missing(which, row, value):
    """One odometer distance or yaw rate of 1e6 (or a fix 1e6 m off) was used: the odometer scale
    ended 1.05 (distance) to 1e4 (fix) off and the position 25 m to 17 km; as in the other
    filters, a reading the sensor or the vehicle cannot produce (beyond gyro_range_rps, beyond
    speed_range_mps times its interval, a fix out of reach of the last one used) is missing and
    counted: the run is the run with that reading missing."""
    from cfdesign.nav.planar_ekf import PlanarEKF

    readings, _ = _planar_drive()
    bad = {k: v.copy() for k, v in readings.items()}
    missing = {k: v.copy() for k, v in readings.items()}
    at = 10 * row if which == "gps_xy" else 10 * row + 3
    bad[which][at] = bad[which][at] + value
    missing[which][at] = np.nan
    mode = np.where(np.isnan(readings["gps_xy"][:, 0]), "", "single")
    ekf = PlanarEKF(**_PLANAR)
    est = ekf.run(bad["distance"], bad["gyro_z"], 0.1, bad["gps_xy"], mode)
    ref = ekf.run(missing["distance"], missing["gyro_z"], 0.1, missing["gps_xy"], np.where(
        np.isnan(missing["gps_xy"][:, 0]), "", "single"))
    assert est.missing == {**dict.fromkeys(est.missing, 0), which: 1}
    for key in ("x", "y", "theta", "alpha", "covariance"):
        np.testing.assert_array_equal(getattr(est, key), getattr(ref, key), err_msg=key)


@pytest.mark.parametrize("start", ["first fix", "initial state"])
def test_planar_ekf_restarts_from_fixes_that_agree_when_the_first_was_wrong(start):
    """The first fix (or the initial state given) 1e6 m off cannot be checked when it comes; the
    next two fixes, out of its reach but within each other's, restart the position from the
    second: the track ends as close to the truth as the run without it."""
    from cfdesign.nav.planar_ekf import PlanarEKF

    readings, truth = _planar_drive()
    mode = np.where(np.isnan(readings["gps_xy"][:, 0]), "", "single")
    args = (readings["distance"], readings["gyro_z"], 0.1)
    clean = PlanarEKF(**_PLANAR).run(*args, readings["gps_xy"], mode)
    fixes, kw = readings["gps_xy"].copy(), {}
    if start == "first fix":
        fixes[0] += 1e6
    else:
        kw["initial_state"] = [1e6, 0.0, 0.0, 1.0]
    est = PlanarEKF(**_PLANAR).run(*args, fixes, mode, **kw)
    assert est.missing["gps_xy"] == 1
    error = np.hypot(est.x - truth[:, 0], est.y - truth[:, 1])[-50:].max()
    assert error < 2 * np.hypot(clean.x - truth[:, 0], clean.y - truth[:, 1])[-50:].max()
    assert abs(est.alpha[-1] - 1.05) < 0.05


@pytest.mark.parametrize("table", ["continuous", "unstable"])
def test_a_table_no_log_can_run_is_named_before_the_fleet_starts(position, tmp_path, cli, table):
    """cfdesign run TABLE logs/ -o out/ with a continuous (or unstable) table started the Dask
    workers (20 s), then printed the same refusal once per log, 'wrote 0 estimate files' and an
    out/summary.csv of errors; the refusal is one line now, before any worker or file."""
    d = position.to_dict() if table == "unstable" else single_rate_continuous().to_dict()
    if table == "unstable":
        d["F"][0][0] = 1e6
    (tmp_path / "g.json").write_text(json.dumps(d))
    (tmp_path / "logs").mkdir()
    for name in ("a", "b"):
        (tmp_path / "logs" / f"{name}.csv").write_text("time,accelerometer,gps\n0.0,0.01,1.0\n0.02,0.01,\n")
    code, out, err = cli("run", tmp_path / "g.json", tmp_path / "logs", "-o", tmp_path / "out/")
    assert code == 2 and len(err.strip().splitlines()) == 1 and ("continuous" in err or "unstable" in err), err
    assert out == "" and not (tmp_path / "out").exists()


_EKF_FIGURES = {"strapdown": ["gyro_noise_std", "accel_noise_std", "gyro_bias_density", "accel_bias_density",
                              "scale_density", "gps_pos_std", "gps_vel_std", "triad_std", "norm_std"],
                "planar": ["odo_noise_std", "gyro_noise_std", "kappa_omega", "kappa_rho", "sigma_heading",
                           "alpha_noise_std", "gps_std", "initial_std"]}


@settings(FUZZ, max_examples=30)
@given(data=st.data(), which=st.sampled_from(sorted(_EKF_FIGURES)))
def test_ekf_noise_figures_at_the_ends_of_their_range_are_named_or_run_finite(data, which):
    """A GPS std of 5e-324 (its square 0), or 1e15 beside 1e-170, passed the figure checks and
    raised numpy's LinAlgError 'Singular matrix' from the update, or left a covariance of inf and
    NaN (88 of 300 random strapdown settings, 226 of 3000 planar ones); now the update names it."""
    from cfdesign.nav.planar_ekf import PlanarEKF
    from cfdesign.nav.strapdown_ekf import StrapdownEKF

    names = data.draw(st.lists(st.sampled_from(_EKF_FIGURES[which]), min_size=1, max_size=3, unique=True))
    values = data.draw(st.lists(st.sampled_from([5e-324, 1e-300, 1e-170, 1e-12, 1e10, 1e15]), min_size=len(names),
                                max_size=len(names)))
    readings, _ = _planar_drive(n=30)
    base, rows = _BASELINES["strapdown"][1], slice(0, 30)
    try:
        if which == "planar":
            kw = {**_PLANAR, **{k: ({"single": v} if k == "gps_std" else (v, v, v, v) if k == "initial_std" else v)
                                for k, v in zip(names, values, strict=True)}}
            mode = np.where(np.isnan(readings["gps_xy"][:, 0]), "", "single")
            est = PlanarEKF(**kw).run(readings["distance"], readings["gyro_z"], 0.1, readings["gps_xy"], mode)
            numbers = [est.x, est.y, est.theta, est.alpha, est.covariance]
        else:
            kw = dict(gyro_noise_std=1e-3, accel_noise_std=1e-2, gyro_bias_density=1e-5, accel_bias_density=1e-4,
                      scale_density=1e-6, gps_pos_std=2.0, gps_vel_std=0.2, triad_std=0.02)
            kw.update(zip(names, values, strict=True))
            n = len(base["gyr"][rows])
            mag = np.tile([0.0, 20.0, -40.0], (n, 1))
            est = StrapdownEKF(10.0, **kw).run(base["gyr"][rows], base["acc"][rows], mag, base["gps_pos"][rows])
            numbers = [est.states, est.final_covariance]
    except cfdesign.errors.InputError as e:
        assert "\n" not in str(e)
        return
    assert all(np.isfinite(a).all() for a in numbers), (names, values)


def _table_consumers():
    from cfdesign.codegen import render_c, write_c
    from cfdesign.discretize import discretize_table
    from cfdesign.export import write_gain_csv
    from cfdesign.logs import run_log, run_logs
    from cfdesign.plot import table_bode_plot
    from cfdesign.sim.gaussian import model_log

    return {"Runtime": Runtime, "verify_table": verify_table, "render_c": render_c, "table_bode_plot": table_bode_plot,
            "write_c": lambda t: write_c(t, "c_out"), "write_gain_csv": lambda t: write_gain_csv(t, "g.csv"),
            "discretize_table": lambda t: discretize_table(t, 100), "run_log": lambda t: run_log(t, "log.csv"),
            "run_logs": lambda t: run_logs(t, ["log.csv"], "out"), "model_log": lambda t: model_log(t, 10)}


@pytest.mark.parametrize("name", sorted(_table_consumers()))
@pytest.mark.parametrize("value", ["gains.json", os.path.join("firmware", "gains.json"), None, {"K": []}])
def test_a_path_or_other_value_for_a_table_is_named(name, value, tmp_path, monkeypatch):
    """A path (or None, a dict) where a GainTable is needed: one GainTableError naming the function
    and load_gains, not a raw AttributeError from deep inside; nothing is written."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(GainTableError, match=rf"^{name} takes a GainTable, got {type(value).__name__}") as err:
        _table_consumers()[name](value)
    if isinstance(value, str):
        assert f"cfdesign.load_gains({value!r})" in str(err.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["heading.toml", {"structure": "cf2"}, None])
def test_a_path_or_dict_for_a_spec_is_named(value, heading):
    """design(path) and verify_table(table, path) name load_spec (or parse_spec for a dict)."""
    hint = "load_spec('heading.toml')" if isinstance(value, str) else "parse_spec" if isinstance(value, dict) else ""
    calls = [(lambda: cfdesign.design(value), "design")]
    if value is not None:  # verify_table's spec=None: no spec to compare with
        calls.append((lambda: verify_table(heading, value), "verify_table"))
    for call, name in calls:
        with pytest.raises(SpecError, match=rf"^{name} takes a FilterSpec, got {type(value).__name__}") as err:
            call()
        assert hint in str(err.value)


def test_words_and_numbers_that_name_nothing_are_refused(heading):
    """A misspelt output gave the prior's predicted std in silence; a structure's name for an
    observer, a rate of 0 raised raw AttributeError / ZeroDivisionError, a negative rate gave a
    schedule; an unknown output of transfer_functions a raw ValueError."""
    from cfdesign.designer import multirate_schedule
    from cfdesign.errors import StructureError

    assert heading.predicted_std_of("posterior") < heading.predicted_std_of("prior")
    for output in ("posterier", None, 0):
        with pytest.raises(GainTableError, match="output must be one of prior, posterior"):
            heading.predicted_std_of(output)
    with pytest.raises(GainTableError, match="output must be one of"):
        heading.transfer_functions("Posterior")
    for state in (2, -1, 1.0, True):
        with pytest.raises(GainTableError, match=r"state must be an index from 0 to 1 \(heading, gyro_correction\)"):
            heading.predicted_std_of("prior", state)
    with pytest.raises(StructureError, match=r"prove takes an Observer, got str: .*cfdesign\.structure\('cf2'\)"):
        cfdesign.prove("cf2")
    for rate in (0, -50.0, math.nan, math.inf, "100", True):
        with pytest.raises(SpecError, match=r"sensors\.gps\.rate_hz must be a positive number of hertz"):
            multirate_schedule({"imu": 100.0, "gps": rate}, inputs=("imu",))
    assert multirate_schedule({"imu": np.int64(100), "gps": np.float32(1.0)}, inputs=("imu",))[1].period == 100


# ---------------------------------------------------------------------- found by the fourth pass
STATE_VALUES = [[np.inf, 0.0, 0.0], [np.nan, 0.0, 0.0], [1e308, 1e308, 0.0], [1e200, 0.0, 0.0], "abc", None,
                [1 + 1j, 0.0, 0.0], [0.1, 0.2], [[0.1], [0.2], [0.3]], [True, False, True], 1.5, np.nan, True,
                np.int64(1), -3, 10 ** 30, [0.1, -0.2, 5e-324], np.array([0.1, 0.2, 0.3]), [np.inf], [0.25]]


@FUZZ
@given(where=st.sampled_from(["x0", "x", "u_last", "phase", "arrivals x0", "arrivals output"]),
       value=st.sampled_from(STATE_VALUES))
@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
def test_every_way_into_a_runtime_state_is_checked(position, where, value):
    """The ``x`` and ``u_last`` setters stored inf, NaN and 1e308 as they came (u_last = None became
    NaN), the phase setter took 1.5 and True, and ``x0 = [1e308, ...]`` overflowed in a few steps
    (ArrivalKalman's x0 too; its output took any value, a misspelt 'posterior' as 'prior'): each
    way in now takes what restore takes, or raises a named error and changes nothing."""
    from cfdesign.runtime.arrivals import ArrivalKalman

    if where.startswith("arrivals"):
        try:
            kf = ArrivalKalman(position, **({"x0": value} if where == "arrivals x0" else {"output": value}))
        except CfdesignError:
            return
        assert (where == "arrivals x0" or value is None) and np.all(np.abs(kf.x) <= 1e150)
        states, _ = kf.run(np.full((3, 1), 0.1), np.ones((3, 1)))
        assert np.all(np.isfinite(states))
        return
    rt = Runtime(position)
    rt.step(accelerometer=0.1, gps=1.0)
    before = rt.state()
    try:
        if where == "x0":
            rt = Runtime(position, x0=value)
        else:
            setattr(rt, where, value)
    except CfdesignError as exc:
        assert rt.state() == before and "\n" not in str(exc)
        return
    state = rt.state()
    assert all(math.isfinite(v) and abs(v) <= 1e150 for v in state["x"] + state["u_last"]), (where, value)
    assert type(state["phase"]) is int and 0 <= state["phase"] < position.period
    for _ in range(3):
        rt.step(accelerometer=0.1, gps=1.0)
    assert np.all(np.isfinite(rt.x))


@pytest.mark.parametrize("u, y", [(np.ones((3, 1)), np.ones((4, 1))), (np.ones((4, 1)), np.ones((3, 1))),
                                  (np.ones(3), np.ones(3)), (np.ones((3, 2)), np.ones((3, 1))),
                                  (np.ones((3, 1)), np.ones((3, 2))), ([["a"]], [[1.0]]), (None, [[1.0]])])
def test_arrival_kalman_run_names_readings_of_another_shape(position, u, y):
    """ArrivalKalman.run with y longer than u ran len(u) ticks and left the last readings unread in
    silence; other shapes raised numpy's or zip's raw ValueError, text a raw one from float()."""
    from cfdesign.runtime.arrivals import ArrivalKalman

    kf = ArrivalKalman(position)
    x, P = kf.x.copy(), kf.P.copy()
    with pytest.raises(CfdesignError, match=r"must be \(N, 1\) and \(N, 1\) arrays|real numbers are needed"):
        kf.run(u, y)
    assert np.array_equal(kf.x, x) and np.array_equal(kf.P, P)
    states, stds = kf.run(np.full((3, 1), 0.1), np.ones((3, 1)))
    assert states.shape == stds.shape == (3, 3)


@pytest.mark.parametrize("value", [np.array(["prior", "posterior"]), ["float"], np.array([1, 2]), {"a": 1}, 1])
@pytest.mark.parametrize("option", ["Runtime output", "ArrivalKalman output", "render_c output", "render_c precision"])
def test_a_choice_option_of_another_type_is_named(heading, option, value):
    """An array as an output or precision reached ``value in (...)`` and came out as numpy's 'truth
    value of an array ... is ambiguous' or 'unhashable type' (TypeError/ValueError)."""
    from cfdesign.codegen import render_c
    from cfdesign.runtime.arrivals import ArrivalKalman

    call = {"Runtime output": lambda: Runtime(heading, output=value),
            "ArrivalKalman output": lambda: ArrivalKalman(heading, output=value),
            "render_c output": lambda: render_c(heading, output=value),
            "render_c precision": lambda: render_c(heading, precision=value)}[option]
    with pytest.raises(CfdesignError, match=r"must be one of|precision must be"):
        call()


EMPTY_NAME_COMMANDS = [
    ["verify", "g.json", "--spec", ""], ["verify", ""], ["design", ""], ["design", "--example", ""],
    ["design", "--example", "cf3", "-o", ""], ["design", "--example", "cf3", "-o", "k.json", "--bode", " "],
    ["export", "g.json", "--format", "c", "-o", ""], ["export", "g.json", "--format", "json", "-o", ""],
    ["run", "g.json", "log.csv", "-o", ""], ["run", "g.json", "", "-o", "e.csv"],
    ["run", "g.json", "log.csv", "-o", "e.csv", "--plot", ""],
    ["run", "g.json", "log.csv", "-o", "e.csv", "--scheduler", ""],
    ["noise", "log.csv", "--column", "gyro", "--rate-hz", "5", "-o", ""], ["noise", "", "--column", "gyro"],
    ["discretize", "g.json", "--rate-hz", "5", "-o", ""], ["bode", "cf2", "--gains", "k=1", "-o", ""]]


@pytest.mark.parametrize("argv", EMPTY_NAME_COMMANDS, ids=" ".join)
def test_an_empty_file_name_is_refused_not_read_as_none_or_here(heading, tmp_path, monkeypatch, cli, argv):
    """An empty name (a shell variable left unset) was read as 'not given' or as '.': ``verify
    --spec ""`` compared the table with nothing and passed (exit 0), ``design ""`` designed the
    built-in example instead of the file, ``design -o ""`` wrote nothing with exit 0, ``run -o ""``
    and ``export --format c -o ""`` wrote into the current folder."""
    monkeypatch.chdir(tmp_path)
    heading.save("g.json")
    Path("log.csv").write_text("time,gyro,compass,odometry\n" + "".join(f"{k / 5},0.01,0.1,0.1\n" for k in range(40)))
    Path("k.json").write_text("previous")
    before = sorted(p.name for p in tmp_path.iterdir())
    code, _, err = cli(*argv)
    assert code == 2 and "is empty or blank: it names nothing" in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before and Path("k.json").read_text() == "previous"


@pytest.mark.parametrize("argv", [a for a in EMPTY_NAME_COMMANDS
                                  if a[-2] in ("-o", "--plot", "--bode") and not a[-1].strip()], ids=" ".join)
def test_a_dash_as_output_is_refused_not_a_file_named_dash(heading, tmp_path, monkeypatch, cli, argv):
    """``-o -`` (standard output, by custom) wrote a file named '-' in silence: design, export,
    discretize, noise, bode and the plots (run -o - alone was refused)."""
    monkeypatch.chdir(tmp_path)
    heading.save("g.json")
    Path("log.csv").write_text("time,gyro,compass,odometry\n" + "".join(f"{k / 5},0.01,0.1,0.1\n" for k in range(40)))
    argv = ["-" if a in ("", " ") else a for a in argv]
    code, _, err = cli(*argv)
    assert code == 2 and "'-' would be a file named '-'" in err and len(err.strip().splitlines()) == 1, err
    assert not Path("-").exists()


@FUZZ
@given(data=st.data())
def test_a_masked_reading_is_missing_not_the_value_under_the_mask(heading, data):
    """numpy.ma arrays were read through asarray, which keeps the values under the mask: a glitch
    the caller had masked (1e3 rad here) was run as a reading, in run and in step."""
    n = 30
    rng = np.random.default_rng(1)
    readings = {s.name: 0.01 * rng.standard_normal(n) for s in heading.sensors}
    masks = {name: np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n))) for name in readings}
    glitched = {name: np.where(masks[name], 1e3, v) for name, v in readings.items()}
    as_nan = {name: np.where(masks[name], np.nan, v) for name, v in readings.items()}
    masked = {name: np.ma.masked_array(glitched[name], mask=masks[name]) for name in readings}
    expected = Runtime(heading).run(as_nan)
    assert np.allclose(Runtime(heading).run(masked), expected, equal_nan=True)
    rt = Runtime(heading)
    stepped = [rt.step(**{name: masked[name][k] for name in readings}) for k in range(n)]
    assert np.allclose(stepped, expected) and rt.counts == {}


def _spec_paths(d, prefix=()):
    for key, value in d.items():
        yield (*prefix, key)
        if isinstance(value, dict):
            yield from _spec_paths(value, (*prefix, key))


SPEC_BASE = {"structure": "cf2", "order": 2, "discrete": True, "gain_form": "filter", "wrap_angle": True,
             "crossover": {"hz": 0.5, "damping": 0.7}, "sensors": {
                 "rate": {"measures": "rate", "rate_hz": 100.0, "noise": {"density": 1e-3},
                          "bias": {"model": "random_walk", "density": 1e-5}},
                 "angle": {"measures": "angle", "rate_hz": 100.0, "noise": {"std": 0.01}, "offset_s": 0.0}}}
WRONG_TYPES = ["5", "", "ψ", True, [1.0, 2.0], [], {}, {"a": 1}, 0, -1, -0.0, 2 ** 64, float("nan"), float("inf"),
               "a\nPASS b", None]


@settings(FUZZ, max_examples=30)
@given(path=st.sampled_from(list(_spec_paths(SPEC_BASE))), value=st.sampled_from(WRONG_TYPES))
def test_a_design_field_of_any_type_is_named_or_designs_and_verifies(path, value):
    """Every field of a design file given a value of another type (or left out, None): a
    SpecError naming the field, or a table that verifies against its own spec.  (A pass over
    2,900 such files of every built-in example found no other outcome.)"""
    import copy

    d = copy.deepcopy(SPEC_BASE)
    where = d
    for key in path[:-1]:
        where = where[key]
    if value is None:
        del where[path[-1]]
    else:
        where[path[-1]] = value
    try:
        spec = parse_spec(d)
        table = cfdesign.design(spec)
    except SpecError as exc:
        assert "\n" not in str(exc) and any(str(k) in str(exc) for k in path), (path, value, str(exc))
        return
    assert [c.line() for c in verify_table(table, spec) if not c.ok] == [], (path, value)
