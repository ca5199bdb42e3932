"""The attitude filter as C99: compiled with -Werror, agrees with Python sample by sample (double, 1e-9)."""

import re
import shutil
import subprocess

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.codegen.attitude import render_attitude_c, write_attitude_c
from cfdesign.errors import CfdesignError
from cfdesign.nav import AttitudeFilter
from cfdesign.nav.attitude_filter import STATE_FIELDS

CC = shutil.which("cc")
CFLAGS = ["-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror"]
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler: 'cc' is not on PATH, the generated C is not compiled")

DRIVER = r"""
#include <stdio.h>
#include <string.h>
#include "cf_attitude.h"
#ifdef DRIVER_MARKED  /* missing readings come as CF_ATTITUDE_MISSING (no NaN under -ffast-math) */
#define ABSENT(v) ((v) >= CF_ATTITUDE_MISSING)
#else
#define ABSENT(v) ((v) != (v))
#endif
/* stdin: n, a flag and (flag 1) the state to start from, then n rows of 9 doubles (gyr, acc,
   mag; a NaN mag[0] passes NULL), binary; stdout: n rows of the quaternion, then the final state */
int main(void)
{
    cf_attitude_state s;
    double row[9], q[4];
    long n, k, given;

    cf_attitude_init(&s);
    if (fread(&n, sizeof n, 1, stdin) != 1 || fread(&given, sizeof given, 1, stdin) != 1)
        return 1;
    if (given && fread(&s, sizeof s, 1, stdin) != 1)
        return 3;
    for (k = 0; k < n; ++k) {
        if (fread(row, sizeof(double), 9, stdin) != 9)
            return 2;
        cf_attitude_step(&s, row, row + 3, ABSENT(row[6]) ? NULL : row + 6, q);
        fwrite(q, sizeof(double), 4, stdout);
    }
    fwrite(&s, sizeof s, 1, stdout);
    return 0;
}
"""


def readings(n=8000, rate=100.0, seed=3):
    """A tumbling sensor (rates to 2 rad/s) at rest for 3 s first, with a gyro bias, noise, a
    magnetic disturbance, and bad samples of every kind."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    moving = np.clip((t - 3.0) / 2.0, 0.0, 1.0)[:, None]
    euler = moving * np.column_stack([2.5 * np.sin(0.3 * t), 1.2 * np.sin(0.5 * t + 0.4),
                                      1.0 * np.sin(0.7 * t + 1.1)])
    q = rot.normalize(rot.from_euler(euler))
    d = rot.multiply(rot.conjugate(q[:-1]), q[1:])
    rates = np.vstack([np.zeros((1, 3)), 2 * d[:, 1:] * rate])
    gyr = rates + np.array([0.01, -0.02, 0.015]) + rng.normal(0, 0.003, (n, 3))
    R = rot.to_matrix(q)
    acc = np.einsum("nji,j->ni", R, [0.0, 0.0, 9.81]) + rng.normal(0, 0.05, (n, 3))
    field = np.tile([0.0, 20.0, -40.0], (n, 1))
    field[4000:5000] += [15.0, 0.0, 10.0]                        # a magnet nearby for 10 s
    mag = np.einsum("nji,nj->ni", R, field) + rng.normal(0, 0.5, (n, 3))
    gyr[1200:1203] = np.nan
    gyr[1500] = 1e9                                              # impossible rate
    acc[2000] = 1e6                                              # impossible specific force
    acc[2100:2110] = np.nan
    mag[3000:3100] = np.nan                                      # no field readings (NULL)
    mag[3200] = 0.0
    return gyr, acc, mag


def run_c(tmp_path, f, gyr, acc, mag, state=None, cflags=()):
    """The generated C of ``f`` compiled (with ``cflags`` besides the strict ones) and run (from
    ``state``, a dict of :meth:`AttitudeFilter.state`, else from its init): (quaternions, final
    state dict)."""
    write_attitude_c(f, tmp_path)
    (tmp_path / "driver.c").write_text(DRIVER)
    exe = tmp_path / "driver"
    build = subprocess.run([CC, *CFLAGS, *cflags, f"-I{tmp_path}", "-o", str(exe), str(tmp_path / "driver.c"),
                            str(tmp_path / "cf_attitude.c"), "-lm"], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    rows = np.hstack([gyr, acc, np.full_like(acc, np.nan) if mag is None else mag])
    start = b"" if state is None else np.array([state[k] for k in STATE_FIELDS], dtype=np.float64).tobytes()
    payload = b"".join([np.array([len(rows), state is not None], dtype=np.int64).tobytes(), start,
                        np.ascontiguousarray(rows, dtype=np.float64).tobytes()])
    out = subprocess.run([str(exe)], input=payload, capture_output=True, timeout=60)
    assert out.returncode == 0, out.stderr
    data = np.frombuffer(out.stdout, dtype=np.float64)
    q = data[:4 * len(rows)].reshape(-1, 4)
    return q, dict(zip(STATE_FIELDS, data[4 * len(rows):].tolist(), strict=True))


@needs_cc
@pytest.mark.parametrize("magnetometer", [True, False])
def test_c_agrees_with_python_sample_by_sample(tmp_path, magnetometer):
    gyr, acc, mag = readings()
    mag = mag if magnetometer else None
    f = AttitudeFilter(100.0, magnetometer=magnetometer)
    q_c, state_c = run_c(tmp_path, f, gyr, acc, mag)
    q_py = np.array([f.step(g, a, None if mag is None or not np.isfinite(m).all() else m)
                     for g, a, m in zip(gyr, acc, mag if mag is not None else acc, strict=True)])
    assert np.abs(q_c - q_py).max() <= 1e-9                   # measured ~2e-16
    state_py = f.state()
    assert max(abs(state_c[k] - state_py[k]) / max(1.0, abs(state_py[k])) for k in STATE_FIELDS) <= 1e-9
    assert state_c["missing_acc"] == 11 and state_c["missing_gyr"] == 4
    if magnetometer:
        assert state_c["missing_mag"] == 101


@needs_cc
def test_the_missing_marker_needs_no_nan_under_fast_math(tmp_path):
    """``CF_ATTITUDE_MISSING`` (finite, beyond every range) marks a missing gyro or accelerometer
    reading where NaN cannot (-ffast-math lets the compiler assume there is none): the C built with
    -ffast-math and fed the marker counts the same missing readings as Python fed NaN and follows it
    to the rounding of reassociation (1e-9 measured ~1e-15)."""
    gyr, acc, mag = readings(n=4000)
    f = AttitudeFilter(100.0)
    header = render_attitude_c(f)["cf_attitude.h"]
    marker = float(re.search(r"#define CF_ATTITUDE_MISSING (\S+)", header).group(1))
    marked = [np.where(np.isnan(x), marker, x) for x in (gyr, acc, mag)]
    q_c, state_c = run_c(tmp_path, f, *marked, cflags=["-ffast-math", "-DDRIVER_MARKED"])
    assert np.abs(q_c - f.run(gyr, acc, mag)).max() <= 1e-9
    assert (state_c["missing_gyr"], state_c["missing_acc"], state_c["missing_mag"]) == (4, 11, 101)


@needs_cc
def test_c_runs_an_initial_attitude_and_the_ablation_switches(tmp_path):
    gyr, acc, mag = readings()
    initial = rot.from_euler([0.3, 0.1, -0.2])
    f = AttitudeFilter(100.0, initial=initial, rest_detection=False, inertial_tilt=False, mag_rejection=False)
    q_c, _ = run_c(tmp_path, f, gyr, acc, mag)
    assert np.abs(q_c - f.run(gyr, acc, mag)).max() <= 1e-9
    assert np.degrees(2 * np.arccos(min(1.0, abs(q_c[0] @ initial)))) < 1.0     # starts from the initial attitude


@needs_cc
@pytest.mark.parametrize("magnetometer", [True, False])
def test_c_agrees_on_shocks_counted_from_an_initial_attitude(tmp_path, magnetometer):
    """With ``initial`` the clipping starts after the start-up's count of specific forces (tilt_n counted down):
    a shock before it (sample 10, taken whole) and after it (sample 250, clipped; both at rest), as in Python
    (the readings' bad samples and motion follow)."""
    gyr, acc, mag = readings(n=3300)
    acc[10, 0] += 200.0
    acc[250, 0] += 200.0
    mag = mag if magnetometer else None
    f = AttitudeFilter(100.0, magnetometer=magnetometer, initial=[1.0, 0.0, 0.0, 0.0])    # the true attitude
    q_c, state_c = run_c(tmp_path, f, gyr, acc, mag)
    assert np.abs(q_c - f.run(gyr, acc, mag)).max() <= 1e-9
    state_py = f.state()
    assert max(abs(state_c[k] - state_py[k]) / max(1.0, abs(state_py[k])) for k in STATE_FIELDS) <= 1e-9
    unclipped = AttitudeFilter(100.0, magnetometer=magnetometer, initial=[1.0, 0.0, 0.0, 0.0],
                               accel_shock_sigma=1e15).run(gyr, acc, mag)
    assert np.abs(q_c[:250] - unclipped[:250]).max() <= 1e-9                  # the early shock was taken whole
    assert np.abs(q_c[250:] - unclipped[250:]).max() > 1e-3                   # the late shock was clipped


@needs_cc
def test_c_agrees_through_the_acceleration_levels_and_their_time_limit(tmp_path):
    """An 8 deg/s bias from a moving start: the levels engage, run out of time (max_accel_time_s)
    and the velocity channel restarts (and the tilt channel's lagged rows with it); C follows Python
    through it and through a restored state.  (5 deg/s with 10 s did, until the tilt channel learnt the
    bias in motion before the levels ran out.)"""
    gyr, acc, _ = readings(n=6000)
    gyr = gyr + np.radians([8.0, -6.4, 8.0])
    f = AttitudeFilter(100.0, magnetometer=False, max_accel_time_s=5.0)
    restarted = False
    for g, a in zip(gyr, acc, strict=True):
        f.step(g, a)
        restarted = restarted or f.state()["accel_time"] < 0.0
    assert restarted
    f.reset()
    out = f.run(gyr, acc, None, details=True)
    assert out.accel_level.max() >= 1
    q_c, state_c = run_c(tmp_path, f, gyr, acc, None)
    assert np.abs(q_c - out.quaternion).max() <= 1e-9
    assert state_c["accel_time"] == f.state()["accel_time"]
    state_py = f.state()
    assert max(abs(state_c[k] - state_py[k]) / max(1.0, abs(state_py[k])) for k in STATE_FIELDS) <= 1e-9


@needs_cc
def test_c_agrees_from_a_restored_state_whose_variances_round_below_zero(tmp_path):
    """A restored state at rest with a huge zero-rotation bias variance (r11 = 1e99): the prediction
    makes the covariance singular to rounding and the Kalman update rounds r11 below zero; Python
    raised ValueError (math domain error) in the rest's sqrt(r11 / h11), C would have made the
    state NaN.  Both now keep the variance at zero
    and agree, through missing and impossible samples too."""
    f = AttitudeFilter(100.0)
    still = (np.tile([0.01, 0.0, 0.0], (300, 1)), np.tile([0.0, 0.1, 9.8], (300, 1)), np.tile([20.0, 0.0, -40.0],
                                                                                                (300, 1)))
    f.run(*still)
    state = {**f.state(), "r11": 1e99}     # valid; one prediction makes it singular (r00 ~ T^2 r11, r01 ~ T r11)
    f.restore(state)
    gyr, acc, mag = readings(n=6000)
    gyr, acc, mag = (np.vstack([a, b]) for a, b in ((still[0], gyr), (still[1], acc), (still[2], mag)))
    q_c, state_c = run_c(tmp_path, f, gyr, acc, mag, state=state)
    q_py = np.array([f.step(g, a, m if np.isfinite(m[0]) else None) for g, a, m in zip(gyr, acc, mag, strict=True)])
    assert np.isfinite(q_py).all() and np.abs(q_c - q_py).max() <= 1e-9
    assert all(abs(state_c[k] - v) <= 1e-9 * max(1.0, abs(v)) for k, v in f.state().items())


EXTREMES = [np.nan, np.inf, -np.inf, 0.0, 1e308, -1e308, 1e200, 1e-320, 5e-324, 1e154, 1.5e154, 1e-160, 1e-170,
            99.999, 100.0, 100.001, 999.99, 1000.0, 1e3 + 1e-9]


@needs_cc
# readings at every extreme look like g and deg/s: the filter says so, as it should, and runs on
@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize(("rate", "magnetometer"), [(1e-3, True), (1e6, False)])
def test_c_agrees_with_python_on_readings_at_every_extreme(tmp_path, rate, magnetometer):
    """Readings at and around every limit (the ranges 100 rad/s and 1000 m/s^2, squares that
    overflow or underflow, subnormals, inf, NaN) in any entry, at the slowest and fastest rates:
    C and Python take the same readings as missing (counted alike) and agree to the last bit."""
    rng = np.random.default_rng(int(rate))
    gyr, acc, mag = readings(n=6000)
    for a in (gyr, acc, mag):
        hit = rng.random(a.shape) < 0.03
        a[hit] = rng.choice(EXTREMES, size=hit.sum()) * rng.choice([-1.0, 1.0], size=hit.sum())
    f = AttitudeFilter(rate, magnetometer=magnetometer)
    q_c, state_c = run_c(tmp_path, f, gyr, acc, mag if magnetometer else None)
    q_py = np.array([f.step(g, a, m if np.isfinite(m[0]) else None) for g, a, m in zip(gyr, acc, mag, strict=True)])
    assert np.isfinite(q_py).all() and np.array_equal(q_c, q_py)
    assert state_c == f.state() and min(n for k, n in f.missing.items() if magnetometer or k != "mag") > 100


def test_generated_c_names_the_filter_and_refuses_bad_prefixes():
    files = render_attitude_c(AttitudeFilter(285.0, declination_rad=0.1), prefix="imu_att")
    assert set(files) == {"imu_att.h", "imu_att.c"}
    assert "GENERATED FILE - DO NOT EDIT" in files["imu_att.c"] and "declination_rad=0.1" in files["imu_att.c"]
    for text in files.values():  # the call that writes them again names them as they are (not cf_attitude.*)
        assert "write_attitude_c(AttitudeFilter(rate_hz, ...), directory, prefix='imu_att')\n" in text
    assert "directory)\n" in render_attitude_c(AttitudeFilter(285.0))["cf_attitude.h"]
    assert "malloc" not in files["imu_att.c"] and "#include <math.h>" in files["imu_att.c"]
    with pytest.raises(CfdesignError, match="C identifier"):
        render_attitude_c(AttitudeFilter(100.0), prefix="1bad")
    for bad in ("math", "stddef", "Stdio"):         # <prefix>.h would shadow the standard header under -I
        with pytest.raises(CfdesignError, match="C standard header"):
            render_attitude_c(AttitudeFilter(100.0), prefix=bad)
    with pytest.raises(CfdesignError, match="reserved"):
        render_attitude_c(AttitudeFilter(100.0), prefix="_imu")
    with pytest.raises(CfdesignError, match="AttitudeFilter"):
        render_attitude_c("not a filter")


@needs_cc
def test_c_agrees_through_a_rest_that_relearns_a_stepped_bias(tmp_path):
    """The bias steps by 0.5 deg/s in the motion, then a rest: C widens the bias prior at the rest's
    start as Python does, and both learn the new bias."""
    gyr, acc, mag = readings(n=6000)
    step = np.radians(0.5) * np.array([0.6, -0.64, 0.48])
    gyr[4500:] += step
    rng = np.random.default_rng(5)
    still = 1500
    gyr = np.vstack([gyr, np.array([0.01, -0.02, 0.015]) + step + rng.normal(0, 0.003, (still, 3))])
    acc = np.vstack([acc, acc[-1] + rng.normal(0, 0.05, (still, 3))])
    mag = np.vstack([mag, mag[-1] + rng.normal(0, 0.5, (still, 3))])
    f = AttitudeFilter(100.0)
    out = f.run(gyr, acc, mag, details=True)
    assert out.rest[-500:].all()
    assert np.degrees(np.abs(out.bias[-1] - [0.01, -0.02, 0.015] - step).max()) < 0.03
    q_c, state_c = run_c(tmp_path, f, gyr, acc, mag)
    assert np.abs(q_c - out.quaternion).max() <= 1e-9
    assert abs(state_c["r11"] - f.state()["r11"]) <= 1e-9 * abs(f.state()["r11"])


#: one translation unit with two attitude filters (6D and 9D) and a table filter, after the
#: program's own macros PI and T (Arduino.h defines PI): each filter's names carry its prefix
UNITY = r"""
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#define PI 3.14159
#define T 0.01
#include "att6.c"
#include "att9.c"
#include "heading_filter.c"

int main(void)
{
    const double gyr[3] = {0.01, -0.02, 0.3}, acc[3] = {0.5, -0.3, 9.7}, mag[3] = {3.0, 19.0, -41.0};
    const heading_real u[HEADING_NU_ALLOC] = {0.1}, y[HEADING_NY_ALLOC] = {0.2, 0.25};
    double q6[4], q9[4];
    att6_state a;
    att9_state b;
    heading_state h;
    heading_real est = 0;
    int k;

    att6_init(&a);
    att9_init(&b);
    heading_init(&h);
    for (k = 0; k < 50; ++k) {
        att6_step(&a, gyr, acc, NULL, q6);
        att9_step(&b, gyr, acc, mag, q9);
        est = heading_step(&h, u, y);
    }
    printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", q6[0], q6[1], q6[2], q6[3],
           q9[0], q9[1], q9[2], q9[3], (double)est);
    return 0;
}
"""
#: the libm functions the attitude step may call (sincos: GCC's fusion of sin and cos)
LIBM = {"sqrt", "sin", "cos", "sincos", "asin", "atan2", "log2", "exp", "floor", "ceil", "fabs"}


@needs_cc
def test_attitude_filters_and_a_table_filter_build_as_one_unit_under_the_promised_warnings(tmp_path):
    """A 6D and a 9D attitude filter and a heading filter in one translation unit (a unity build)
    after ``#define PI`` and ``#define T``, under the promised warnings as C99 and as C++11: every
    file-scope name carries its prefix (the attitude C's static T, PI, REST[...] and clamp() were
    bare, so two filters redefined them and a program's PI macro broke them), no float == (under
    -Wfloat-equal), decimal literals (C++11 has no hexadecimal floating ones).  The results equal
    Python's; the object calls only libm and defines only the prefix's init and step."""
    import cfdesign
    from cfdesign.codegen import STRICT_CFLAGS, STRICT_CXXFLAGS, write_c
    from cfdesign.runtime import Runtime

    write_attitude_c(AttitudeFilter(100.0, magnetometer=False), tmp_path, prefix="att6")
    write_attitude_c(AttitudeFilter(100.0, magnetometer=True), tmp_path, prefix="att9")
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))
    write_c(table, tmp_path, prefix="heading")
    (tmp_path / "unity.c").write_text(UNITY)
    f6, f9, rt = AttitudeFilter(100.0, magnetometer=False), AttitudeFilter(100.0, magnetometer=True), Runtime(table)
    for _ in range(50):
        q6 = f6.step([0.01, -0.02, 0.3], [0.5, -0.3, 9.7])
        q9 = f9.step([0.01, -0.02, 0.3], [0.5, -0.3, 9.7], [3.0, 19.0, -41.0])
        est = rt.step(gyro=0.1, compass=0.2, odometry=0.25)
    cxx = shutil.which("c++")
    for compiler, flags in [(CC, STRICT_CFLAGS), *([(cxx, STRICT_CXXFLAGS)] if cxx else [])]:
        exe = tmp_path / "unity"
        build = subprocess.run([compiler, *flags, "-O1", "-o", str(exe), str(tmp_path / "unity.c"), "-lm"],
                               capture_output=True, text=True)
        assert build.returncode == 0, f"{compiler} {' '.join(flags)}:\n{build.stderr}"
        got = [float(v) for v in subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()]
        assert np.abs(np.array(got) - [*q6, *q9, est]).max() <= 1e-12
    nm = shutil.which("nm")
    if nm:
        obj = tmp_path / "att9.o"
        subprocess.run([CC, *STRICT_CFLAGS, "-O2", "-c", "-o", str(obj), str(tmp_path / "att9.c")], check=True)
        symbols = [line.split() for line in subprocess.run([nm, str(obj)], capture_output=True, text=True,
                                                           check=True).stdout.splitlines()]
        assert {s[-1] for s in symbols if s[0] == "U"} <= LIBM
        defined = {s[-1]: s[-2] for s in symbols if len(s) == 3}
        assert {name for name, kind in defined.items() if kind in "TDBCG"} == {"att9_init", "att9_step"}
        assert not set(defined.values()) & set("DdBbCGgSs")      # no writable data: state is the caller's


def test_a_prefix_whose_names_are_posix_math_macros_is_refused():
    """Prefix M made ``static const double M_PI``, which <math.h> defines as a macro under g++ and
    -std=gnu99 ('expected unqualified-id before numeric constant'); m makes m_PI, which is free."""
    with pytest.raises(CfdesignError, match=r"C name 'M_PI' is a macro of <math.h> in POSIX"):
        render_attitude_c(AttitudeFilter(100.0), prefix="M")
    files = render_attitude_c(AttitudeFilter(100.0), prefix="m")
    assert "static const double m_PI = 3.141592653589793;" in files["m.c"]
