"""Generated C99 filter: agrees with the Python runtime, refuses what C cannot take, and
matches the committed copy in tests/fixtures/codegen_dckf3/.

After an intended change to the generated code, regenerate the committed copy with::

    CFDESIGN_REGENERATE=1 python -m pytest tests/test_codegen.py -k committed

and review the diff.
"""

import dataclasses
import difflib
import os
import re
import shutil
import subprocess
from pathlib import Path
from string import Template

import numpy as np
import pytest

import cfdesign
from cfdesign.codegen import STRICT_CFLAGS, STRICT_CXXFLAGS, render_c, write_c
from cfdesign.errors import CfdesignError
from cfdesign.gains import Schedule
from cfdesign.runtime import Runtime, wrap
from cfdesign.sim.signals import sinusoid_readings

FIXTURES = Path(__file__).parent / "fixtures"
COMMITTED = FIXTURES / "codegen_dckf3"
CC = shutil.which("cc")
CFLAGS = ["-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror"]
N = 100_000
#: float precision: max |C - Python| <= FLOAT_BOUND * max |estimate| (as cfdesign.codegen documents)
FLOAT_BOUND = {"dckf3": 2e-6, "position": 1e-4}

needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler: 'cc' is not on PATH, the generated C is not compiled")


@pytest.fixture(scope="module")
def tables():
    return {name: cfdesign.design(cfdesign.load_spec(cfdesign.example_path(name)))
            for name in ("dckf3", "position")}


@pytest.fixture(scope="module")
def reference(tables):
    """``{name: (readings, Python runtime estimates)}`` on the shared test signal (the streaming
    step, whose operation order the C follows; the batch path agrees to rounding)."""
    out = {}
    for name, table in tables.items():
        data = readings(table)
        rt, names = Runtime(table, lock=False), list(data)  # the C's fixed schedule (its lock is manual)
        stream = np.array([rt.step(**{n: data[n][k] for n in names}) for k in range(N)])  # the C's operation order
        assert np.max(np.abs(stream - Runtime(table).run(data))) <= 1e-9 * np.max(np.abs(stream))
        out[name] = data, stream
    return out


def readings(table, seed=1):
    """A slow sinusoid through every sensor plus noise, 2 % NaN; the heading crosses +-pi."""
    return sinusoid_readings(table, N, seed=seed, missing=0.02)


def run_c(table, data, folder, precision, cflags=()):
    """Generate, compile with the driver fixture (and ``cflags``), run on ``data``; the C estimates."""
    prefix = write_c(table, folder, precision=precision)[0].name.removesuffix("_gains.h")
    driver = folder / "driver.c"
    template = Template((FIXTURES / "codegen_driver.c.in").read_text())
    driver.write_text(template.substitute(prefix=prefix, PREFIX=prefix.upper()))
    exe = folder / "driver"
    build = subprocess.run([CC, *CFLAGS, *cflags, "-o", str(exe), str(driver), str(folder / f"{prefix}_filter.c"),
                            "-lm"],
                           capture_output=True, text=True)
    assert build.returncode == 0, f"generated C does not compile:\n{build.stderr}"
    rt = Runtime(table)
    rows = np.column_stack([data[name] for name in rt.inputs + rt.measurements]).astype(np.float64)
    rows.tofile(folder / "in.bin")
    subprocess.run([str(exe), str(folder / "in.bin"), str(folder / "out.bin")], check=True)
    return np.fromfile(folder / "out.bin", dtype=np.float64)


def difference(table, c, py):
    """Max |C - Python|; headings modulo 2 pi (+pi and -pi are the same heading)."""
    diff = c - py
    return float(np.max(np.abs(wrap(diff) if table.wrap_angle else diff)))


# ---------------------------------------------------------------------- agreement
@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
@needs_cc
@pytest.mark.parametrize("name", ["dckf3", "position"])
@pytest.mark.parametrize("precision", ["double", "float"])
def test_c_agrees_with_python_runtime(name, precision, tables, reference, tmp_path):
    table = tables[name]
    data, py = reference[name]
    if table.wrap_angle:  # the test signal really crosses +-pi
        assert np.any(np.abs(np.diff(py)) > np.pi)
    c = run_c(table, data, tmp_path, precision)
    assert c.shape == py.shape and np.isfinite(c).all()
    bound = 1e-12 if precision == "double" else FLOAT_BOUND[name] * np.max(np.abs(py))
    assert difference(table, c, py) <= bound


@needs_cc
@pytest.mark.parametrize("output", ["posterior", "prior"])
def test_filter_form_angle_table_agrees_for_both_outputs(tables, tmp_path, output):
    """Filter gains with heading wrap (the examples cover predictor + wrap and filter, no wrap),
    the default posterior output and the prediction (``output='prior'``)."""
    spec = cfdesign.load_spec(cfdesign.example_path("dckf3"))
    table = cfdesign.design(dataclasses.replace(spec, gain_form="filter", output=output))
    data = {k: v[:20_000] for k, v in readings(table).items()}
    c = run_c(table, data, tmp_path, "double")
    assert difference(table, c, Runtime(table).run(data)) <= 1e-12


def memory(table):
    """``||h||_2``: the largest 2-norm of the closed loop's response of state 0 to a unit error
    in one state at one phase (the gain from per-step rounding to the estimate): the square
    root of the largest diagonal entry of ``W = S + M^T W M``, with ``M`` the monodromy matrix
    from that phase and ``S`` the sum over one period."""
    from scipy.linalg import solve_discrete_lyapunov

    A = [ph.A for ph in Runtime(table)._phases]
    n, worst = len(table.F), 0.0
    for start in range(table.period):
        M, S = np.eye(n), np.zeros((n, n))
        for k in range(table.period):
            S += np.outer(M[0], M[0])
            M = A[(start + k) % table.period] @ M
        worst = max(worst, float(np.max(np.diag(solve_discrete_lyapunov(M.T, S)))) ** 0.5)
    return worst



def memory_1(table, tol=1e-12):
    """``||h||_1``: the largest sum of ``|h_k|``, the closed loop's response of state 0 to a unit
    error in one state at one phase, summed over the steps until it has died away (the gain from
    roundings that add up coherently over the filter's memory)."""
    A = [ph.A for ph in Runtime(table)._phases]
    n, P, worst = len(table.F), table.period, 0.0
    for start in range(P):
        M, total, k = np.eye(n), np.zeros(n), 0
        while k % P or np.max(np.abs(M[0])) > tol * max(1.0, total.max()):
            total += np.abs(M[0])
            M = A[(start + k) % P] @ M
            k += 1
        worst = max(worst, float(total.max()))
    return worst

TWO_COMPASSES = """
name = "heading, gyro at 50 Hz, compasses at 10 and 5 Hz with offsets"
structure = "chain"
order = 1
discrete = true
wrap_angle = true
[sensors.gyro]
measures = "rate"
rate_hz = 50.0
noise = { density = 1.7e-4 }
bias = { model = "random_walk", density = 2e-5 }
[sensors.compass]
measures = "angle"
rate_hz = 10.0
offset_s = 0.04
noise = { std = 0.02 }
[sensors.beacon]
measures = "angle"
rate_hz = 5.0
offset_s = 0.14
noise = { std = 0.05 }
"""


@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
@needs_cc
def test_float_error_is_within_the_rounding_bound_of_a_long_memory_heading_table(tmp_path):
    """float C against double Python: a rounding of eps_f |x| per operation (about 8 a step)
    reaches the estimate through the closed loop, so the error is at most
    8 eps_f max|estimate| ||h||_2 (random rounding). This table's memory (||h||_2 = 300, against
    4.7 for the dckf3 example) took it past the 2e-6 x max|estimate| documented for heading
    tables (measured 3.3e-6 x)."""
    import tomllib

    from cfdesign.spec import parse_spec

    table = cfdesign.design(parse_spec(tomllib.loads(TWO_COMPASSES)))
    data = sinusoid_readings(table, 20_000, seed=1, missing=0.02)
    c = run_c(table, data, tmp_path, "float")
    py = Runtime(table, lock=False).run(data)                   # the C keeps the fixed schedule
    h = memory(table)
    assert h > 100                                              # a long memory: the case in point
    assert difference(table, c, py) <= 8 * 2.0**-24 * np.max(np.abs(py)) * h



@needs_cc
def test_float_error_of_a_drifting_position_is_within_the_coherent_rounding_bound(tmp_path):
    """A 200 Hz CKF3 (discretised) whose position drifts to 1.5e5 m: the increment T v added to the
    position every step varies slowly against its ulp, so the float roundings repeat step after
    step and add up over the filter's memory instead of averaging out.  The error stays within
    the worst-case 8 eps_f max|estimate| ||h||_1; the random-rounding figure with ||h||_2 does not
    hold here (measured 2.0e0 m against 0.51 m on a Monte-Carlo log of 200,000 steps)."""
    import tomllib

    from cfdesign.discretize import discretize_table
    from cfdesign.spec import parse_spec

    spec = parse_spec(tomllib.loads(CKF3_200HZ))
    table = discretize_table(cfdesign.design(spec), 200.0)
    n = 30_000
    t = np.arange(n) / 200.0
    rng = np.random.default_rng(3)
    v = 1000.0 + 5.0 * np.sin(0.05 * t)                          # m/s: the position reaches 1.5e5 m
    p = np.concatenate([[0.0], np.cumsum(v[:-1] / 200.0)])
    data = {"acceleration": np.gradient(v, t) + 0.04 * rng.standard_normal(n),
            "velocity": v + 0.01 * rng.standard_normal(n), "position": p + 0.05 * rng.standard_normal(n)}
    c = run_c(table, data, tmp_path, "float")
    py = Runtime(table).run(data)
    bound = 8 * 2.0**-24 * np.max(np.abs(py))
    h1 = memory_1(table)
    assert h1 > 20 * memory(table)                                # a long, smooth memory: the case in point
    assert difference(table, c, py) <= bound * h1


CKF3_200HZ = """
name = "robot axis, CKF3 at 200 Hz"
structure = "ckf3"
[sensors.acceleration]
measures = "acceleration"
rate_hz = 200.0
noise = { density = 0.003 }
[sensors.velocity]
measures = "velocity"
rate_hz = 200.0
noise = { std = 0.01 }
[sensors.position]
measures = "position"
rate_hz = 200.0
noise = { std = 0.05 }
"""

# ---------------------------------------------------------------------- refusals
@pytest.mark.parametrize("bad", ["2gyro", "gyro rate", "gyro-1", "", "while", "gyrö"])
def test_sensor_name_must_be_an_identifier(bad, tables):
    table = tables["dckf3"]
    sensors = [dataclasses.replace(s, name=bad) if s.name == "gyro" else s for s in table.sensors]
    with pytest.raises(CfdesignError, match=re.escape(repr(bad))):  # refused by the table or by the C generator
        render_c(dataclasses.replace(table, sensors=sensors))


def renamed(table, names):
    """``table`` with its sensors renamed (``{old: new}``), schedule included."""
    sensors = [dataclasses.replace(s, name=names.get(s.name, s.name)) for s in table.sensors]
    measured = [s.name for s in sensors if s.role == "measurement"]
    per_phase = [[names.get(x, x) for x in table.schedule.names(k)] for k in range(table.period)]
    return dataclasses.replace(table, sensors=sensors, schedule=Schedule.from_names(measured, per_phase))


@needs_cc
def test_sensors_named_like_c_keywords_or_reserved_names_export_and_compile(tables, tmp_path):
    """A sensor's name appears in the C only as the suffix of its index macro (DCKF3_U_INT), so
    any name a table allows exports: 'int', 'double', 'main', '_Bool', '__x' were refused."""
    table = renamed(tables["dckf3"], {"gyro": "int", "compass": "double", "odometry": "_Bool"})
    data = {k: v[:2000] for k, v in readings(table).items()}
    c = run_c(table, data, tmp_path, "double")
    assert difference(table, c, Runtime(table).run(data)) <= 1e-12
    header = (tmp_path / "dckf3_gains.h").read_text()
    assert "#define DCKF3_U_INT 0" in header and "#define DCKF3_Y__BOOL 1" in header
    for name in ("main", "__gyro", "_Gyro", "float"):
        assert f"DCKF3_U_{name.upper()} 0" in render_c(renamed(tables["dckf3"], {"gyro": name}))["dckf3_gains.h"]


def test_sensor_names_clashing_upper_case_are_refused(tables):
    table = tables["dckf3"]
    sensors = [dataclasses.replace(s, name="Compass") if s.name == "odometry" else s for s in table.sensors]
    names = [s.name for s in sensors if s.role == "measurement"]
    schedule = Schedule.from_names(names, [names])
    with pytest.raises(CfdesignError, match="clash"):
        render_c(dataclasses.replace(table, sensors=sensors, schedule=schedule))


@pytest.mark.parametrize("bad", ["static", "1filter", "my-filter", "__cf"])
def test_prefix_must_be_c_identifier(bad, tables, tmp_path):
    with pytest.raises(CfdesignError, match="C prefix"):
        write_c(tables["position"], tmp_path, prefix=bad)


def test_continuous_table_is_refused(tmp_path):
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("ckf3")))
    with pytest.raises(CfdesignError, match="continuous"):
        write_c(table, tmp_path)
    assert not list(tmp_path.iterdir())


def test_bad_precision_and_unwritable_folder(tables, tmp_path):
    with pytest.raises(CfdesignError, match="precision"):
        render_c(tables["position"], precision="half")
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(CfdesignError, match="cannot write"):
        write_c(tables["position"], blocker / "c")


def test_table_name_cannot_end_the_comment(tables):
    table = dataclasses.replace(tables["position"], name="evil */ int x; /*\nmore")
    header = render_c(table)["position_gains.h"]
    assert " * source table : evil * / int x; / *_more\n" in header
    assert header.count("*/") == header.count("/*")


@pytest.mark.parametrize("output", ["posterior", "prior"])
def test_every_file_states_rate_output_and_schedule(output, tmp_path):
    """The header comment of each file says what the step does: the base rate (the call rate),
    the estimate returned and when each sensor is read (a 3 Hz GPS late by 0.37 s beside a
    100 Hz IMU), and the filter_sha256 a Python state of this table records."""
    spec = cfdesign.load_spec(cfdesign.example_path("position"))
    imu, gps = spec.sensors
    spec = dataclasses.replace(spec, sensors=(dataclasses.replace(imu, rate_hz=100.0),
                                              dataclasses.replace(gps, rate_hz=3.0, offset_s=0.05)))
    table = cfdesign.design(spec)
    files = write_c(table, tmp_path, output=output)
    phases = ", ".join(map(str, table.schedule.phases("gps")))
    assert phases == "5, 38, 72"
    for path in files:
        text = path.read_text()
        assert " * rate         : base 100 Hz (T = 0.01 s): one position_step call per base step; gain schedule of " \
               "100 steps (1 s)\n" in text
        assert f" * output       : {output}: " in text
        assert (output == "posterior") == ("(the table's output)" in text)
        assert " * schedule     : accelerometer (input, 100 Hz): every step\n" \
               f" *                gps (measurement, 3 Hz): phases {phases} of 100\n" in text
        assert f" * filter sha256: {Runtime(table).state()['filter_sha256']} " in text


def test_headers_give_the_unit_of_every_reading_and_state(tables):
    """The sensor macros and the state's comment carry the SI units the step expects (the
    header said 'order 2 (acceleration)' but not m/s^2, and nothing of the state's entries)."""
    files = render_c(tables["position"], prefix="pos")
    assert "#define POS_U_ACCELEROMETER 0  /* accelerometer: input, order 2 (acceleration, m/s^2), 50 Hz */" \
        in files["pos_gains.h"]
    assert "#define POS_Y_GPS 0  /* gps: measurement, order 0 (angle/position, m), 1 Hz */" in files["pos_gains.h"]
    header = files["pos_filter.h"]
    assert " *     x[0] position (m)\n *     x[1] velocity (m/s)\n *     x[2] accelerometer_bias (m/s^2)\n" in header
    assert "(x[0], m)" in header
    heading = render_c(tables["dckf3"])
    assert "gyro: input, order 1 (rate, rad/s), 5 Hz" in heading["dckf3_gains.h"]
    assert "x[1] gyro_correction (rad/s)" in heading["dckf3_filter.h"]


def test_prefix_and_files(tables, tmp_path):
    paths = write_c(tables["position"], tmp_path / "out", prefix="imu_gps", precision="float")
    assert [p.name for p in paths] == ["imu_gps_gains.h", "imu_gps_filter.h", "imu_gps_filter.c"]
    header = paths[1].read_text()
    assert "typedef float imu_gps_real;" in header and "imu_gps_step(imu_gps_state *s" in header
    assert "#define IMU_GPS_Y_GPS 0" in paths[0].read_text()


@pytest.mark.parametrize("options", [{}, {"prefix": "heading"}, {"precision": "float"}, {"output": "prior"},
                                     {"prefix": "heading", "precision": "float", "output": "prior"}])
def test_the_regenerate_command_of_the_comment_writes_the_same_files(options, tables, tmp_path):
    """The do-not-edit comment gives the command that writes the files again; run on their table
    it writes the same files (it gave no options: regenerating a --prefix heading export wrote
    dckf3_* files beside the stale heading_* ones, and a float or prediction export as double, posterior)."""
    from cfdesign.cli import main

    table = tables["dckf3"]
    table.save(tmp_path / "gains.json")
    files = render_c(table, **options)
    command = re.search(r"^ \*     (cfdesign export .*)$", next(iter(files.values())), re.M).group(1)
    assert all(re.search(rf"^ \*     {re.escape(command)}$", text, re.M) for text in files.values())
    words = command.replace("<gains.json>", str(tmp_path / "gains.json")).replace("<dir>", str(tmp_path / "c")).split()
    assert main(words[1:]) == 0
    assert {p.name: p.read_text() for p in (tmp_path / "c").iterdir()} == files


# ---------------------------------------------------------------------- committed copy
_FLOAT = re.compile(r"(?<![\w.])-?(?:\d+\.\d*(?:e[-+]?\d+)?|\d+e[-+]?\d+)f?")


def normalised(text):
    """Text without the created line and version numbers, floats replaced by ``#``; the floats."""
    text = "\n".join(line for line in text.splitlines()
                     if not line.startswith((" * created", " * filter sha256")))  # (of the gains' last bits)
    text = re.sub(r"cfdesign \d+\.\d+\.\d+\S*", "cfdesign <version>", text)
    return _FLOAT.sub("#", text), [float(m.rstrip("f")) for m in _FLOAT.findall(text)]


def test_generated_code_matches_committed_copy(tables):
    files = render_c(tables["dckf3"])
    if os.environ.get("CFDESIGN_REGENERATE"):
        COMMITTED.mkdir(parents=True, exist_ok=True)
        for name, text in files.items():
            (COMMITTED / name).write_text(text)
    regenerate = "CFDESIGN_REGENERATE=1 python -m pytest tests/test_codegen.py -k committed"
    assert sorted(files) == sorted(p.name for p in COMMITTED.iterdir()), f"regenerate with: {regenerate}"
    for name, text in files.items():
        (got, got_numbers), (want, want_numbers) = normalised(text), normalised((COMMITTED / name).read_text())
        diff = "\n".join(difflib.unified_diff(want.splitlines(), got.splitlines(), "committed", "generated",
                                              lineterm=""))
        assert got == want, f"{name} differs from the committed copy ({regenerate}):\n{diff}"
        np.testing.assert_allclose(got_numbers, want_numbers, rtol=1e-9, atol=1e-15, err_msg=name)


@needs_cc
def test_c_treats_inf_and_huge_readings_as_missing_like_python(tables, tmp_path):
    """inf, -inf and readings beyond the runtime's limit are missing in C as in Python (the
    state never becomes NaN)."""
    table = tables["dckf3"]
    data = {k: v[:5000].copy() for k, v in readings(table).items()}
    data["compass"][[10, 200]] = [np.inf, 1e13]
    data["gyro"][[50, 51]] = [-np.inf, 2e12]
    rt, names = Runtime(table), list(data)
    py = np.array([rt.step(**{n: data[n][k] for n in names}) for k in range(5000)])
    c = run_c(table, data, tmp_path, "double")
    assert np.isfinite(c).all() and difference(table, c, py) <= 1e-12


# ---------------------------------------------------------------------- firmware use
#: the warnings a firmware build turns on; the generated C and a program using it compile clean
STRICT = [*STRICT_CFLAGS, "-O2"]
CXX = shutil.which("c++")
NM = shutil.which("nm")


@needs_cc
def test_missing_marker_is_missing_under_fast_math(tables, tmp_path):
    """``<PREFIX>_MISSING`` (finite, beyond the reading limit) is a missing reading without NaN, so
    it holds under -ffast-math, where a compiler may assume no value is NaN: the C fed it, built
    with -ffast-math, agrees with the Python runtime fed NaN to the rounding of reassociation."""
    table = tables["dckf3"]
    data = {k: v[:20_000].copy() for k, v in readings(table).items()}
    rt = Runtime(table)
    names = rt.inputs + rt.measurements
    py = Runtime(table).run(data)
    marked = {k: np.where(np.isnan(v), -1e301, v) for k, v in data.items()}  # the driver passes _MISSING
    c = run_c(table, marked, tmp_path, "double", cflags=["-ffast-math", "-DDRIVER_MARK_MISSING"])
    assert sum(np.isnan(data[n]).sum() for n in names) > 500
    assert np.isfinite(c).all() and difference(table, c, py) <= 1e-9 * np.max(np.abs(py))


@needs_cc
def test_a_slow_sensor_off_the_schedule_is_locked_by_its_phase_macro(tables, tmp_path):
    """A GPS fix that arrives 17 ticks after phase 0 is ignored unless the schedule is locked to
    it: set ``s->phase = POSITION_PHASE_GPS`` before each fix's step, as the header says.  The
    reference is the Python runtime on the same rows after 33 idle ones (state and input 0), which
    puts the fixes at phase 0 with no phase set."""
    table = tables["position"]
    n, idle = 10_000, 33
    data = {k: v[:n].copy() for k, v in readings(table).items()}
    data["gps"][np.arange(n) % table.period != 17] = np.nan
    padded = {k: np.concatenate([np.zeros(idle) if k != "gps" else np.full(idle, np.nan), v]) for k, v in data.items()}
    py = Runtime(table).run(padded)[idle:]
    locked = run_c(table, data, tmp_path, "double", cflags=["-DDRIVER_LOCK=POSITION_Y_GPS",
                                                            "-DDRIVER_LOCK_PHASE=POSITION_PHASE_GPS"])
    assert difference(table, locked, py) <= 1e-9 * np.max(np.abs(py))
    naive = run_c(table, data, tmp_path, "double")          # the fixes fall at phase 17: never read
    assert difference(table, naive, py) > 1.0


def test_phase_macros_name_the_phase_of_each_sensor_read_once_a_period():
    """``<PREFIX>_PHASE_<NAME>`` for the measurements read once a period, none for single-rate; a
    sensor read twice a period (the compass, phases 2 and 7 of 10) is no lock: setting the phase to 2
    at each of its readings would never reach phase 7, where the beacon alone is read."""
    import tomllib

    from cfdesign.spec import parse_spec

    table = cfdesign.design(parse_spec(tomllib.loads(TWO_COMPASSES)))
    gains = next(text for name, text in render_c(table, prefix="h").items() if name.endswith("gains.h"))
    phases = {s: list(table.schedule.phases(s)) for s in table.sensor_names("measurement")}
    assert phases == {"compass": [2, 7], "beacon": [7]}
    got = dict(re.findall(r"#define H_PHASE_(\w+) (\d+)", gains))
    assert got == {"BEACON": "7"} and "compass: phases 2, 7 of 10" in gains
    four = TWO_COMPASSES.replace("rate_hz = 5.0", "rate_hz = 4.0").replace("offset_s = 0.14", "offset_s = 0.0")
    none = next(text for name, text in render_c(cfdesign.design(parse_spec(tomllib.loads(four))), prefix="h").items()
                if name.endswith("gains.h"))
    assert "#define H_PHASE_" not in none and "No sensor is read once a period" in none
    assert "Lock the schedule to a sensor" not in none
    single = render_c(cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3"))))
    assert "#define DCKF3_PHASE_" not in "".join(single.values())


@needs_cc
def test_two_filters_in_one_program_compile_clean_under_strict_warnings(tables, tmp_path):
    """A heading (double) and a position (float) filter with their own prefixes in one program:
    no symbol clash, no warning under a firmware build's flags (C99 and C++), and each object
    defines only ``<prefix>_init`` and ``<prefix>_step``, with no writable data (the state is
    the caller's struct: one per instance, nothing shared between threads)."""
    write_c(tables["dckf3"], tmp_path, prefix="heading")
    write_c(tables["position"], tmp_path, prefix="pos", precision="float")
    (tmp_path / "main.c").write_text(MAIN_TWO_FILTERS)
    sources = [str(tmp_path / f) for f in ("main.c", "heading_filter.c", "pos_filter.c")]
    build = subprocess.run([CC, *STRICT, "-o", str(tmp_path / "main"), *sources, "-lm"], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, check=True)
    heading, pos = map(float, run.stdout.split())
    rt = Runtime(tables["position"])
    rt.x = [5000.0, 0.0, 0.0]
    assert heading == Runtime(tables["dckf3"]).step(gyro=0.1, odometry=0.2) and abs(pos - rt.step(gps=5001.0)) < 1e-3
    if CXX:
        build = subprocess.run([CXX, *STRICT_CXXFLAGS, "-o", str(tmp_path / "main_cc"), *sources, "-lm"],
                               capture_output=True, text=True)
        assert build.returncode == 0, build.stderr
    if NM:
        for prefix in ("heading", "pos"):
            obj = tmp_path / f"{prefix}.o"
            subprocess.run([CC, *STRICT, "-c", "-o", str(obj), str(tmp_path / f"{prefix}_filter.c")], check=True)
            symbols = [line.split() for line in subprocess.run([NM, str(obj)], capture_output=True, text=True,
                                                               check=True).stdout.splitlines()]
            defined = {s[-1]: s[-2] for s in symbols if len(s) == 3}
            assert {name for name, kind in defined.items() if kind in "TDBCG"} == {f"{prefix}_init", f"{prefix}_step"}
            assert not {kind for kind in defined.values()} & set("DdBbCGgSs")


MAIN_TWO_FILTERS = """
#include <math.h>
#include <stdio.h>

#include "heading_filter.h"
#include "pos_filter.h"

int main(void)
{
    heading_state h;
    pos_state p;
    const heading_real hu[HEADING_NU_ALLOC] = {0.1};
    heading_real hy[HEADING_NY_ALLOC];
    const pos_real pu[POS_NU_ALLOC] = {POS_MISSING};
    const pos_real py[POS_NY_ALLOC] = {5001.0f};

    heading_init(&h);
    pos_init(&p);
    p.x[0] = 5000.0f;
    hy[HEADING_Y_COMPASS] = NAN;
    hy[HEADING_Y_ODOMETRY] = 0.2;
    printf("%.17g %.9g\\n", heading_step(&h, hu, hy), (double)pos_step(&p, pu, py));
    return 0;
}
"""
