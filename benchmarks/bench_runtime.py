"""Speed of the Python runtime and of the generated C filter, each beside a baseline.

Run by hand from the repository root:  python benchmarks/bench_runtime.py [--samples N] [--c-steps M]
Accuracy of the generated C alone (section 6):  python benchmarks/bench_runtime.py --c-agreement [--long]
The phase lock alone (section 7):  python benchmarks/bench_runtime.py --lock

On the robot-heading DCKF3 table of Carreira et al. (the "dckf3" example: single rate, heading
wrapped) and the multirate position table (period 50), with 1,000,000 samples of a slow
sinusoid plus noise:

1. batch: ``Runtime(table).run(readings)`` in samples/s beside ``scipy.signal.lfilter`` on
   the same data (the DCKF3's three bands as IIR filters, summed; target run >= 0.5 x
   lfilter; the periodic table has no LTI bands);
2. streaming (process CPU time, best of 3): ``Runtime.step`` per sample, with float and with
   numpy-scalar readings, beside a generic Python loop doing the same arithmetic with floats and
   lists, beside the DCKF3 written by hand as straight-line float code (the loop a user writes for
   one filter; no checks of the readings), and beside ``imufusion.Ahrs.update`` (Fusion's
   Python binding, a compiled 9D AHRS:
   target step <= 1.0x its time; ``pip install imufusion``), and ``Runtime.run`` on blocks of
   10,000 samples with the state carried over (target > 1e6 samples/s);
   The streaming step is also timed on chain tables of n = 2 .. 16 states beside Fusion;
3. compiled C (``cfdesign.codegen.write_c``, ``cc -std=c99 -O2``): ns per step over
   10,000,000 chained steps (target < 10 ns for the DCKF3), beside two baselines in the same
   program and loop: a call that only copies the inputs, and a one-pole IIR.

   Slow sensors are given only at the ticks the table reads them (NaN or left out between), as
   a stream delivers them; for the multirate table a row also times ``step`` with the slow
   sensor's value repeated every tick (each repeat refused as faster than designed, warned once;
   target <= 1.2x the step on the readings given at their arrivals).

4. a large state: ``Runtime.run`` of an n = 200 table on 500 samples (target < 1 s) and
   ``verify_table`` on chains of n = 100, 200 and 500 states;
5. start-up: ``cfdesign --version`` beside ``python -c "import numpy"`` (target <= 1.5x),
   whether ``cfdesign run`` imports matplotlib or sympy (it must not), and the first
   ``estimate_attitude`` call on 1,000 samples in a fresh process (it designs the channels'
   default gains; target < 0.5 s, no sympy).

6. ``--c-agreement`` (alone; seconds): the generated C against the Python runtime, built with the
   tests' driver (``tests/fixtures/codegen_driver.c.in``): (a) double built with other compilers
   and options (``-ffast-math``, contraction, x87) on the tests' signal, 2 % of the readings
   missing and passed as ``<PREFIX>_MISSING``; (b) whether a NaN reading survives ``-O3
   -ffast-math``; (c) float, max error over max|estimate|; (d) an hour of the position example
   (50 Hz IMU, 1 Hz GPS whose clock runs 200 ppm slow, each fix seen on the tick after it arrives)
   in float, with and without the phase lock of ``docs/guide/c-export.md``, against the truth;
   with ``--long`` (minutes) also (e) float over 10 million steps of a turning heading and of a
   position 5 km from the origin, against the double runtime.
7. ``--lock`` (alone; seconds): the streaming step's phase lock on the rows of
   ``tests/test_runtime_lock.py`` (100 Hz gyro, 10 Hz odometry, 1 Hz compass; 8,000 rows, RMS
   after the first 2,000): the whole schedule 37 ticks late, locked and with ``lock=False``,
   beside the aligned rows; sensors at offsets of their own through the locked step and through
   ``ArrivalKalman.step`` with the time of a tick of each (process time, best of 3); and
   ``Runtime.run`` on 200,000 rows late by 37 ticks beside the same rows aligned.

Prints figures only; no assertions on time.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from string import Template

import numpy as np
import scipy
from scipy.signal import lfilter

import cfdesign
from cfdesign.codegen import write_c
from cfdesign.linear import startup_steps
from cfdesign.runtime import Runtime, wrap
from cfdesign.sim.signals import sinusoid_readings

EXAMPLES = {"dckf3": "robot heading (DCKF3)", "position": "position (multirate)"}
BLOCK = 10_000
C_CFLAGS = ["-std=c99", "-O2"]
#: samples cycled through by the C timing driver (a power of two)
C_TABLE = 65536

# The C timing driver: reads C_TABLE rows of doubles, then runs `steps` chained calls of each
# function through a volatile pointer (so none is inlined) and prints ns per call.
DRIVER = Template(r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "${prefix}_filter.h"

#define ROWS ${rows}
typedef ${prefix}_real (*step_fn)(${prefix}_state *, const ${prefix}_real *, const ${prefix}_real *);
static ${prefix}_real U[ROWS][${PREFIX}_NU_ALLOC], Y[ROWS][${PREFIX}_NY_ALLOC];

/* baseline: the call and the input copy only */
static ${prefix}_real copy_only(${prefix}_state *s, const ${prefix}_real u[], const ${prefix}_real y[])
{
    int i;
    for (i = 0; i < ${PREFIX}_NU; ++i)
        s->u_last[i] = u[i];
    return y[0];
}

/* baseline: a one-pole IIR on the first measurement */
static ${prefix}_real one_pole(${prefix}_state *s, const ${prefix}_real u[], const ${prefix}_real y[])
{
    (void)u;
    s->x[0] += (${prefix}_real)0.1 * (y[0] - s->x[0]);
    return s->x[0];
}

static double ns_per_step(step_fn volatile fn, long steps)
{
    struct timespec t0, t1;
    ${prefix}_state s;
    double acc = 0;
    long k;

    ${prefix}_init(&s);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (k = 0; k < steps; ++k)
        acc += fn(&s, U[k & (ROWS - 1)], Y[k & (ROWS - 1)]);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (acc != acc)
        fprintf(stderr, "(NaN estimate)\n");
    return ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / steps;
}

int main(int argc, char **argv)
{
    double row[${PREFIX}_NU + ${PREFIX}_NY];
    long steps = argc > 2 ? atol(argv[2]) : 10000000L;
    FILE *in = argc > 1 ? fopen(argv[1], "rb") : NULL;
    int k, i;

    if (!in)
        return 2;
    for (k = 0; k < ROWS && fread(row, sizeof row[0], ${PREFIX}_NU + ${PREFIX}_NY, in); ++k) {
        for (i = 0; i < ${PREFIX}_NU; ++i)
            U[k][i] = (${prefix}_real)row[i];
        for (i = 0; i < ${PREFIX}_NY; ++i)
            Y[k][i] = (${prefix}_real)row[${PREFIX}_NU + i];
    }
    ns_per_step(${prefix}_step, steps / 10);  /* warm-up: clock speed, caches */
    printf("%.3f %.3f %.3f\n", ns_per_step(${prefix}_step, steps), ns_per_step(copy_only, steps),
           ns_per_step(one_pole, steps));
    return 0;
}
""")


# ---------------------------------------------------------------------- data
def readings(table, N, seed=0, amplitude=None, arrivals=True):
    """A slow sinusoid through every sensor plus noise (:func:`cfdesign.sim.sinusoid_readings`); each
    slow sensor only at the ticks the table reads it (NaN between), as a stream delivers it
    (``arrivals=False``: every sensor every tick, a held value repeated)."""
    return sinusoid_readings(table, N, seed=seed, amplitude=amplitude, arrivals=arrivals)


def columns(table, data) -> list:
    """The readings in runtime order: inputs by index, then measurements by index."""
    rt = Runtime(table)
    return [data[name] for name in rt.inputs + rt.measurements]


def timed(fn, repeat=1, clock=time.perf_counter):
    """Best time of ``fn()`` over ``repeat`` runs (s) and its last result."""
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = clock()
        out = fn()
        best = min(best, clock() - t0)
    return best, out


def cpu_timed(fn, repeat=3):
    """:func:`timed` in this process's CPU time: the streaming figures are single-threaded Python
    and C calls, and on a shared machine the wall clock counts the time other processes run."""
    return timed(fn, repeat, time.process_time)


# ---------------------------------------------------------------------- (i) batch
def lfilter_bands(table, data):
    """The DCKF3's sensor bands as IIR filters through lfilter, summed (the batch baseline)."""
    bands = cfdesign.dckf3().with_gains({**table.gains, "T": table.sample_time_s}).band_coefficients()

    def run():
        total = None
        for name, (num, den) in bands.items():
            num = np.concatenate([np.zeros(len(den) - len(num)), num])
            out = lfilter(num, den, data[name])
            total = out if total is None else total + out
        return total

    return run


def batch_rows(table, data, N):
    """Runtime.run beside lfilter; for angle tables also on readings that stay within +-pi."""
    cases = {"Runtime.run (batch)": data}
    if table.wrap_angle:
        cases["Runtime.run, heading within +-pi"] = readings(table, N, amplitude=2.5)
    times = {what: timed(lambda d=d: Runtime(table).run(d), repeat=3)[0] for what, d in cases.items()}
    if table.period != 1 or table.structure != "dckf3":
        return [(what, N / t, "") for what, t in times.items()] + [
            ("scipy lfilter", None, "n/a: a periodic table has no LTI bands")]
    t_lf, _ = timed(lfilter_bands(table, data), repeat=3)
    notes = ["heading crosses +-pi", "angle readings need no unwrap"]
    return [(what, N / t, f"{t_lf / t:.2f} x lfilter (target >= 0.5); {note}")
            for (what, t), note in zip(times.items(), notes, strict=False)] + [
        ("scipy lfilter, 3 bands summed", N / t_lf, "baseline")]


# ---------------------------------------------------------------------- (ii) streaming
def plain_python_filter(table):
    """The same filter as generic Python on floats and lists (no numpy, no specialisation): the
    streaming baseline a user would write by hand."""
    from cfdesign.linear import gain_pair, wrap_scalar

    pairs = [gain_pair(table.F, K, table.gain_form) for K in table.K]
    F, B, H = (np.asarray(a, dtype=float).tolist() for a in (table.F, table.B, table.H))
    Kp = [kp.tolist() for kp, _ in pairs]
    L0 = [lo[0].tolist() for _, lo in pairs]
    active = table.schedule.mask().tolist()
    rt = Runtime(table)
    p, n, N_ = len(rt.inputs), len(F), range(len(F))
    wrapped = [bool(table.wrap_angle) and s.order == 0 for s in table.measurements]
    state = {"x": [0.0] * n, "u": [0.0] * p, "phase": 0}

    def step(row):
        x, ph = state["x"], state["phase"]
        u = [v if v == v else state["u"][j] for j, v in enumerate(row[:p])]
        e = [y - sum(h * xj for h, xj in zip(Hi, x, strict=True)) if y == y and a else 0.0
             for y, Hi, a in zip(row[p:], H, active[ph], strict=True)]
        e = [wrap_scalar(v) if w else v for v, w in zip(e, wrapped, strict=True)]
        est = x[0] + sum(g * v for g, v in zip(L0[ph], e, strict=True))
        x = [sum(f * xj for f, xj in zip(F[r], x, strict=True)) + sum(b * uj for b, uj in zip(B[r], u, strict=True))
             + sum(k * v for k, v in zip(Kp[ph][r], e, strict=True)) for r in N_]
        if table.wrap_angle:
            x[0], est = wrap_scalar(x[0]), wrap_scalar(est)
        state.update(x=x, u=u, phase=(ph + 1) % len(Kp))
        return est

    return step


def hand_written_filter(table):
    """The table's filter as straight-line Python on float locals, written for its shape (two
    states, one input, two measurements of the first state: the robot-heading DCKF3), as a user
    would write it for this one filter: the issue's "plain-float loop of the same 2-state filter"
    (0.6 us).  No checks of the readings (the runtime's step rejects non-finite and impossible
    ones, and counts them).  None for tables of another shape."""
    from cfdesign.linear import gain_pair, wrap_scalar

    F, B, H = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H))
    if F.shape != (2, 2) or B.shape != (2, 1) or H.shape != (2, 2) or len(table.K) != 1 or H[:, 1].any():
        return None
    Kp, L = (np.asarray(a, dtype=float).tolist() for a in gain_pair(table.F, table.K[0], table.gain_form))
    (f00, f01), (f10, f11) = F.tolist()
    b0, b1 = B[:, 0].tolist()
    h0, h1 = H[:, 0].tolist()
    (k00, k01), (k10, k11) = Kp
    l0, l1 = L[0]
    wrap = wrap_scalar if table.wrap_angle else (lambda v: v)
    x = [0.0, 0.0]

    def step(u, y0, y1):
        x0, x1 = x
        e0, e1 = wrap(y0 - h0 * x0), wrap(y1 - h1 * x0)
        x[0] = wrap(f00 * x0 + f01 * x1 + b0 * u + k00 * e0 + k01 * e1)
        x[1] = f10 * x0 + f11 * x1 + b1 * u + k10 * e0 + k11 * e1
        return wrap(x0 + l0 * e0 + l1 * e1)

    return step


def imufusion_step():
    """``imufusion.Ahrs.update`` (Fusion, a full 9D AHRS in C, through its Python binding) per
    sample, as a user calls it: the per-sample cost a Python robot loop pays for a compiled filter."""
    try:
        import imufusion
    except ImportError:
        return None
    ahrs = imufusion.Ahrs()
    g, a, m = np.array([0.01, 0.02, 0.03]), np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.0, 0.5])
    n = 200_000

    def run():
        for _ in range(n):
            ahrs.update(g, a, m, 0.01) if _FUSION_DT else ahrs.update(g, a, m)

    return cpu_timed(run)[0] / n


def _fusion_takes_dt():
    try:
        import imufusion

        imufusion.Ahrs().update(np.zeros(3), np.array([0.0, 0.0, 1.0]), np.ones(3), 0.01)
        return True
    except (ImportError, TypeError):
        return False


_FUSION_DT = _fusion_takes_dt()


def streaming_rows(table, data, N):
    rt = Runtime(table)
    names = rt.inputs + rt.measurements
    rows = list(zip(*(c.tolist() for c in columns(table, data)), strict=True))
    kwargs = [dict(zip(names, r, strict=True)) for r in rows]
    t_step, est_step = cpu_timed(lambda: rt.reset() or [rt.step(**kw) for kw in kwargs])
    np_rows = list(zip(*columns(table, data), strict=True))  # numpy scalars, as iterating arrays gives
    np_kwargs = [dict(zip(names, r, strict=True)) for r in np_rows]
    rt_np = Runtime(table)
    t_np, _ = cpu_timed(lambda: rt_np.reset() or [rt_np.step(**kw) for kw in np_kwargs])
    rt2 = Runtime(table)
    t_values, _ = cpu_timed(lambda: rt2.reset() or [rt2.step_values(*r) for r in rows])
    plain = plain_python_filter(table)
    t_plain, est_plain = timed(lambda: [plain(r) for r in rows], clock=time.process_time)
    agree = float(np.max(np.abs(wrap(np.subtract(est_plain, est_step)))))
    hand = hand_written_filter(table)
    if hand is not None:
        t_hand, est_hand = timed(lambda: [hand(*r) for r in rows], clock=time.process_time)
        hand_agree = float(np.max(np.abs(wrap(np.subtract(est_hand, est_step)))))
    blocks = Runtime(table)
    t_block, _ = timed(lambda: [blocks.run({k: v[i:i + BLOCK] for k, v in data.items()}) for i in range(0, N, BLOCK)])
    out = [("Runtime.step(**readings)", N / t_step, f"{1e6 * t_step / N:.2f} us/step"),
           ("Runtime.step, numpy float64 readings", N / t_np, f"{1e6 * t_np / N:.2f} us/step"),
           ("Runtime.step_values(*readings)", N / t_values, f"{1e6 * t_values / N:.2f} us/step"),
           ("generic Python floats loop (lists)", N / t_plain,
            f"{1e6 * t_plain / N:.2f} us/step (agrees to {agree:.0e}); step is {t_plain / t_step:.1f}x faster"),
           *([("hand-written straight-line floats", N / t_hand, f"{1e6 * t_hand / N:.2f} us/step (agrees to "
               f"{hand_agree:.0e}), no reading checks; Runtime.step = {t_step / t_hand:.2f}x its time")]
             if hand is not None else []),
           (f"Runtime.run, {BLOCK:,}-sample blocks", N / t_block, "target > 1e6/s")]
    fusion = imufusion_step()
    if fusion is not None:
        if table.period > 1:  # a slow sensor's last value repeated every tick: off the schedule, refused one by one
            held = readings(table, N, arrivals=False)
            held_rows = [dict(zip(names, r, strict=True))
                         for r in zip(*(c.tolist() for c in columns(table, held)), strict=True)]
            rt_held = Runtime(table)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "given more often than the table reads it": said once, on purpose
                t_held, _ = cpu_timed(lambda: rt_held.reset() or [rt_held.step(**kw) for kw in held_rows])
            out.append(("Runtime.step, slow values every tick", N / t_held,
                        f"{1e6 * t_held / N:.2f} us/step = {t_held / t_step:.2f}x the step above (target <= 1.2x): "
                        "each repeat is off the schedule, refused as faster than designed (warned once)"))
        out.append(("imufusion.Ahrs.update (Fusion, C)", 1 / fusion,
                    f"{1e6 * fusion:.2f} us/update; Runtime.step = {t_step / N / fusion:.2f}x (target <= 1.0x), "
                    f"with numpy readings {t_np / N / fusion:.2f}x"))
    else:
        out.append(("imufusion.Ahrs.update", None, "skipped: pip install imufusion"))
    return out, t_step / N


def state_size_rows(N=100_000):
    """``Runtime.step`` per sample on chain tables of n = 2 .. 16 states beside
    ``imufusion.Ahrs.update``: the specialised step's cost grows with the non-zero products
    (``n^2 / 2`` for a chain's triangular ``F``, plus the gains)."""
    fusion = imufusion_step()
    rows = []
    for n in (2, 3, 4, 6, 8, 12, 16):
        rt = Runtime(chain_table(n))
        readings = [{"u": 0.1, "y": 0.2 + 1e-6 * k} for k in range(N)]
        t = cpu_timed(lambda rt=rt, readings=readings: [rt.step(**r) for r in readings])[0] / N
        ratio = f"; {t / fusion:.2f}x imufusion.Ahrs.update ({1e6 * fusion:.2f} us)" if fusion else ""
        rows.append((f"Runtime.step, n = {n}", 1 / t, f"{1e6 * t:.2f} us/step{ratio}"))
    return rows


def chain_table(n, dt=0.01):
    """An ``n``-state ZOH chain table (input of order ``n``, an angle reading), filter form."""
    from cfdesign import linear
    from cfdesign.gains import GainTable, Schedule, SensorPort

    F, b = linear.zoh_chain(n, dt)
    K = np.zeros((n, 1))
    K[0, 0], K[1, 0] = 0.5, 0.01
    return GainTable(name=f"chain {n}", structure="custom", domain="z", sample_time_s=dt, gain_form="filter",
                     sensors=(SensorPort("u", "input", 0, n, 100.0), SensorPort("y", "measurement", 0, 0, 100.0)),
                     F=F, B=b[:, None], H=np.eye(n)[:1], K=[K], P=[np.eye(n)], P_filtered=[np.eye(n)],
                     schedule=Schedule.from_names(["y"], [["y"]]), Q=np.eye(n), R=np.eye(1),
                     states=tuple(f"d{i}" for i in range(n)))


def large_state_rows():
    """``Runtime`` on an n = 200 chain table, 500 samples (target < 1 s), and verify at n = 100,
    200, 500 (every check runs: the long chains' identity cannot be decided in double precision,
    so the rounding estimate runs too)."""
    from cfdesign.verify import verify_table

    table = chain_table(200)
    rng = np.random.default_rng(0)
    data = {"u": rng.standard_normal(500), "y": rng.standard_normal(500)}
    t_run, _ = timed(lambda: Runtime(table).run(data))
    rows = [("Runtime(table).run, n = 200, 500 samples", 500 / t_run, f"{t_run:.3f} s including set-up (target < 1 s)")]
    for n in (100, 200, 500):
        big = chain_table(n)
        t_verify, _ = timed(lambda big=big: verify_table(big))
        rows.append((f"verify_table, n = {n}", None, f"{t_verify:.3f} s"))
    return rows


def startup_rows():
    """``cfdesign --version`` beside ``python -c "import numpy"`` (best of 7 each), and what
    ``cfdesign run`` imports."""
    def best(cmd):
        times = []
        for _ in range(7):
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            times.append(time.perf_counter() - t0)
        return min(times)

    t_numpy = best([sys.executable, "-c", "import numpy"])
    t_version = best([sys.executable, "-m", "cfdesign", "--version"])
    probe = ("import sys\nfrom cfdesign.cli import build_parser\nbuild_parser(['run'])\n"
             "import cfdesign.logs, cfdesign.runtime, cfdesign.gains, cfdesign.timing\n"
             "print(int('matplotlib' in sys.modules), int('sympy' in sys.modules))")
    mpl, sym = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True,
                              text=True).stdout.split()
    first = ("import sys, time\nimport numpy as np\nfrom cfdesign.nav import estimate_attitude\n"
             "n = 1000\nacc = np.tile([0.0, 0.0, 9.81], (n, 1))\nmag = np.tile([0.0, 20.0, -40.0], (n, 1))\n"
             "t0 = time.perf_counter()\nestimate_attitude(np.zeros((n, 3)), acc, mag, 100.0)\n"
             "print(time.perf_counter() - t0, int('sympy' in sys.modules))")
    calls = [subprocess.run([sys.executable, "-c", first], check=True, capture_output=True,
                            text=True).stdout.split() for _ in range(3)]
    t_first, sym_nav = min(float(c[0]) for c in calls), calls[0][1]
    return [("cfdesign --version", None, f"{1e3 * t_version:.0f} ms = {t_version / t_numpy:.2f}x "
                                         f"'python -c \"import numpy\"' ({1e3 * t_numpy:.0f} ms); target <= 1.5x"),
            ("cfdesign run's modules", None, f"import matplotlib: {'yes' if mpl == '1' else 'no'}, "
                                              f"sympy: {'yes' if sym == '1' else 'no'}"),
            ("first estimate_attitude call", None, f"{1e3 * t_first:.0f} ms on 1,000 samples (best of 3 "
                                                   f"fresh processes; target < 500 ms), sympy imported: "
                                                   f"{'yes' if sym_nav == '1' else 'no'}")]


# ---------------------------------------------------------------------- (iii) C
def c_rows(table, data, steps, folder, t_python_step):
    """Generate, compile and time the C step beside the baselines; [] without a compiler."""
    cc = shutil.which("cc")
    if cc is None:
        return [("compiled C", None, "skipped: no C compiler ('cc') on PATH")]
    prefix = write_c(table, folder)[0].name.removesuffix("_gains.h")
    (folder / "bench.c").write_text(DRIVER.substitute(prefix=prefix, PREFIX=prefix.upper(), rows=C_TABLE))
    np.column_stack(columns(table, data))[:C_TABLE].astype(np.float64).tofile(folder / "in.bin")
    exe = folder / "bench"
    subprocess.run([cc, *C_CFLAGS, "-o", str(exe), str(folder / "bench.c"), str(folder / f"{prefix}_filter.c"),
                    "-lm"], check=True)
    out = subprocess.run([str(exe), str(folder / "in.bin"), str(steps)], check=True, capture_output=True, text=True)
    step, copy, iir = (float(v) for v in out.stdout.split())
    target = " (target < 10 ns)" if table.structure == "dckf3" else ""
    return [(f"C {prefix}_step (double)", 1e9 / step, f"{step:.2f} ns/step{target}"),
            ("C baseline: call + input copy", 1e9 / copy, f"{copy:.2f} ns/step"),
            ("C baseline: one-pole IIR", 1e9 / iir, f"{iir:.2f} ns/step"),
            ("Python Runtime.step (above)", 1 / t_python_step, f"{1e9 * t_python_step:,.0f} ns/step, "
                                                                f"{t_python_step * 1e9 / step:,.0f} x the C step")]


# ---------------------------------------------------------------------- (6) C agreement
#: the tests' C driver: rows of doubles in, one estimate per row out
AGREEMENT_DRIVER = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "codegen_driver.c.in"
#: a missing reading, as the driver passes it with -DDRIVER_MARK_MISSING (no NaN: -ffast-math)
MARK = -1e301


def c_estimates(table, data, folder, precision="double", cflags=("-std=c99", "-O2"), cc="cc"):
    """Generate ``table``'s C, compile it with the tests' driver (``cflags``, compiler ``cc``) and
    run it on ``data``'s rows; the C's estimates, one per row."""
    folder.mkdir(parents=True, exist_ok=True)
    prefix = write_c(table, folder, precision=precision)[0].name.removesuffix("_gains.h")
    template = Template(AGREEMENT_DRIVER.read_text())
    (folder / "driver.c").write_text(template.substitute(prefix=prefix, PREFIX=prefix.upper()))
    exe = folder / "driver"
    subprocess.run([shutil.which(cc), *cflags, "-o", str(exe), str(folder / "driver.c"),
                    str(folder / f"{prefix}_filter.c"), "-lm"], check=True, capture_output=True, text=True)
    np.column_stack(columns(table, data)).astype(np.float64).tofile(folder / "in.bin")
    subprocess.run([str(exe), str(folder / "in.bin"), str(folder / "out.bin")], check=True)
    return np.fromfile(folder / "out.bin", dtype=np.float64)


def max_error(table, a, b) -> float:
    """max |a - b|, headings modulo 2 pi; NaN when either has a NaN."""
    diff = wrap(a - b) if table.wrap_angle else a - b
    return float(np.max(np.abs(diff))) if np.isfinite(diff).all() else math.nan


def option_rows(tables, folder):
    """(a), (b), (c): the double C under other options, NaN under fast-math, and float."""
    builds = [("gcc", "-std=c99 -O2"), ("gcc", "-std=c99 -O2 -ffast-math"), ("gcc", "-std=gnu11 -O2 -march=native"),
              ("gcc", "-std=c99 -O2 -mfpmath=387"), ("clang", "-std=c99 -O2"), ("clang", "-std=c99 -O3 -ffast-math")]
    out = []
    for name, table in tables.items():
        data = sinusoid_readings(table, 100_000, seed=1, missing=0.02, amplitude=1.5e4 if name == "position" else None)
        rt = Runtime(table, lock=False)                       # the C's fixed schedule
        names = rt.inputs + rt.measurements
        with warnings.catch_warnings():                       # every sensor every tick, as the tests
            warnings.simplefilter("ignore")
            py = np.array([rt.step(**{n: data[n][k] for n in names}) for k in range(100_000)])
        unit, size = "rad" if table.wrap_angle else "m", np.max(np.abs(py))
        marked = {k: np.where(np.isnan(v), MARK, v) for k, v in data.items()}
        for cc, flags in builds:
            if shutil.which(cc) is None:
                continue
            c = c_estimates(table, marked, folder / name, cflags=[*flags.split(), "-DDRIVER_MARK_MISSING"], cc=cc)
            err = max_error(table, c, py)
            out.append((f"(a) {name} double", f"{cc} {flags}", f"max |C - Python| {err:.2g} {unit} "
                        f"({err / size:.2g} of max|estimate| {size:.3g} {unit}); bit for bit: {err == 0}"))
        for cc in ("gcc", "clang"):
            if shutil.which(cc) is not None:
                c = c_estimates(table, data, folder / name, cflags=["-std=c99", "-O3", "-ffast-math"], cc=cc)
                out.append((f"(b) {name} NaN readings", f"{cc} -O3 -ffast-math",
                            f"{np.count_nonzero(~np.isfinite(c)):,} of {len(c):,} estimates not finite"))
        data = sinusoid_readings(table, 100_000, seed=1, missing=0.02)  # the tests' signal
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            py = Runtime(table, lock=False).run(data)
        c = c_estimates(table, data, folder / name, precision="float")
        out.append((f"(c) {name} float", "gcc -std=c99 -O2", f"max |C - Python| "
                    f"{max_error(table, c, py) / np.max(np.abs(py)):.2g} x max|estimate| (the tests' signal)"))
    return out


def sensor_specs(example) -> dict:
    """``{name: SensorSpec}`` of a built-in example's design file (noise and bias)."""
    return {s.name: s for s in cfdesign.load_spec(cfdesign.example_path(example)).sensors}


def memory_rows(folder):
    """(c) continued: the float error of the two long-memory tables of ``tests/test_codegen.py``
    (its tables, signals and closed-loop response norms ``||h||_2``, ``||h||_1``) over the rounding
    figure ``8 eps_f max|estimate| ||h||_2``; and ``||h||_2`` of the DCKF3 example."""
    import tomllib

    sys.path.insert(0, str(AGREEMENT_DRIVER.parents[1]))
    from test_codegen import CKF3_200HZ, TWO_COMPASSES, memory, memory_1

    from cfdesign.discretize import discretize_table
    from cfdesign.spec import parse_spec

    dckf3 = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))
    out = [("(c) dckf3", "||h||_2", f"{memory(dckf3):.2g}")]
    two = cfdesign.design(parse_spec(tomllib.loads(TWO_COMPASSES)))
    ckf3 = discretize_table(cfdesign.design(parse_spec(tomllib.loads(CKF3_200HZ))), 200.0)
    n, rng = 30_000, np.random.default_rng(3)                  # the drifting position of the test
    t = np.arange(n) / 200.0
    v = 1000.0 + 5.0 * np.sin(0.05 * t)
    drift = {"acceleration": np.gradient(v, t) + 0.04 * rng.standard_normal(n),
             "velocity": v + 0.01 * rng.standard_normal(n),
             "position": np.concatenate([[0.0], np.cumsum(v[:-1] / 200.0)]) + 0.05 * rng.standard_normal(n)}
    for name, table, data in (("two compasses", two, sinusoid_readings(two, 20_000, seed=1, missing=0.02)),
                              ("ckf3 200 Hz", ckf3, drift)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            py = Runtime(table, lock=False).run(data)
        c = c_estimates(table, data, folder / "memory", precision="float")
        err, size, h2 = max_error(table, c, py), np.max(np.abs(py)), memory(table)
        out.append((f"(c) {name} float", f"||h||_2 {h2:.2g}, ||h||_1 {memory_1(table):.2g}",
                    f"max |C - Python| {err / size:.2g} x max|estimate| ({size:.3g}), "
                    f"{err / (8 * 2.0**-24 * size * h2):.2g} x 8 eps_f max|estimate| ||h||_2"))
    return out


def gps_clock_hour(table, seed=0):
    """An hour of the position example at 50 Hz: the truth oscillating 200 m around 5 km, the
    accelerometer with its design file's noise and bias random walk, a 1 Hz GPS whose fix ``j``
    is the position at ``50.01 j`` ticks (200 ppm slow) with its noise, seen on the tick after.
    Returns the readings, the true position and the ticks of the fixes."""
    rng = np.random.default_rng(seed)
    T, n, w = table.sample_time_s, 180_000, 2 * np.pi / 600.0
    t = np.arange(n) * T
    acc, gps = sensor_specs("position").values()
    bias = np.cumsum(acc.bias.density * math.sqrt(T) * rng.standard_normal(n))
    fix_time = np.arange(int(n / 50.01)) * 50.01 * T
    ticks = np.ceil(fix_time / T - 1e-9).astype(int)
    fixes = np.full(n, np.nan)
    fixes[ticks] = 5200.0 - 200.0 * np.cos(w * fix_time) + gps.noise.std * rng.standard_normal(len(ticks))
    acceleration = 200.0 * w**2 * np.cos(w * t) + bias + acc.noise.std * rng.standard_normal(n)
    return {"accelerometer": acceleration, "gps": fixes}, 5200.0 - 200.0 * np.cos(w * t), ticks


def gps_clock_rows(table, folder):
    """(d): float C, an hour of a 200 ppm GPS clock, with and without the manual phase lock."""
    readings, truth, ticks = gps_clock_hour(table)
    start = [f"-DDRIVER_X0={float(readings['gps'][0])!r}"]
    lock = ["-DDRIVER_LOCK=POSITION_Y_GPS", "-DDRIVER_LOCK_PHASE=POSITION_PHASE_GPS"]
    settled = slice(30_000, None)                             # after the first 10 minutes
    phases = ticks % table.period
    out = [("(d) position, 1 h", "fix phases", f"{np.count_nonzero(phases[1:] == 0)} of the {len(ticks) - 1} later "
            f"fixes at phase 0 (the second at phase {phases[1]})")]
    for label, flags in (("no lock", start), ("st.phase locked", start + lock)):
        c = c_estimates(table, readings, folder / "clock", precision="float", cflags=["-std=c99", "-O2", *flags])
        err = c - truth
        out.append(("(d) position, 1 h, float", label, f"error after 10 min: max {np.max(np.abs(err[settled])):.3g} m, "
                    f"RMS {np.sqrt(np.mean(err[settled] ** 2)):.3g} m, at the end {err[-1]:.3g} m "
                    f"(predicted std {table.predicted_std:.2f} m)"))
    return out


def long_heading(table, n, seed=0):
    """``n`` steps of a heading turning at 0.1-0.5 rad/s (wrapped), readings with the design
    file's noise and a gyro bias random walk, 2 % missing."""
    rng = np.random.default_rng(seed)
    T = table.sample_time_s
    t = np.arange(n) * T
    rate = 0.3 + 0.2 * np.sin(2 * np.pi * t / 300.0)
    psi = np.concatenate([[0.0], np.cumsum(rate[:-1]) * T])
    sensors = sensor_specs("dckf3")
    bias = np.cumsum(sensors["gyro"].bias.density * math.sqrt(T) * rng.standard_normal(n))
    data = {"gyro": rate + bias + sensors["gyro"].noise.std * rng.standard_normal(n)}
    for name in ("compass", "odometry"):
        data[name] = wrap(psi + sensors[name].noise.std * rng.standard_normal(n))
    for v in data.values():
        v[rng.random(n) < 0.02] = np.nan
    return data, psi


def long_position(table, n, seed=0):
    """``n`` steps of a position oscillating 200 m around 5 km, the example's sensors, 2 % of the
    readings missing, the GPS at its schedule's ticks."""
    rng = np.random.default_rng(seed)
    T, w = table.sample_time_s, 2 * np.pi / 600.0
    t = np.arange(n) * T
    acc, gps = sensor_specs("position").values()
    bias = np.cumsum(acc.bias.density * math.sqrt(T) * rng.standard_normal(n))
    data = {"accelerometer": 200.0 * w**2 * np.cos(w * t) + bias + acc.noise.std * rng.standard_normal(n),
            "gps": 5200.0 - 200.0 * np.cos(w * t) + gps.noise.std * rng.standard_normal(n)}
    data["gps"][np.arange(n) % table.period != 0] = np.nan
    for v in data.values():
        v[rng.random(n) < 0.02] = np.nan
    return data


def long_rows(tables, folder, n=10_000_000):
    """(e): float C against the double runtime over ``n`` steps, after the start-up; the position
    also about a local origin (the first fix subtracted from the readings, added back)."""
    out = []
    heading, position = tables["dckf3"], tables["position"]
    data, psi = long_heading(heading, n)
    out.append(long_row(heading, data, folder, f"{n:,} steps, {psi[-1] / (2 * np.pi):,.0f} turns"))
    data = long_position(position, n)
    out.append(long_row(position, data, folder, f"{n:,} steps"))
    origin = data["gps"][np.isfinite(data["gps"])][0]
    local = {**data, "gps": data["gps"] - origin}
    out.append(long_row(position, local, folder, f"{n:,} steps, local origin {origin:.1f} m", offset=origin))
    return out


def long_row(table, data, folder, label, offset=0.0):
    """One row of (e): max and RMS |float C - double runtime| after the start-up, and the
    max over the first 10^6 and over the last 5 10^6 steps."""
    n = len(next(iter(data.values())))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        py = Runtime(table, lock=False).run(data) + offset
    c = c_estimates(table, data, folder / "long", precision="float") + offset
    diff = np.abs(wrap(c - py) if table.wrap_angle else c - py)
    skip = math.ceil(startup_steps(table.F, table.H, table.K, table.gain_form))
    unit = "rad" if table.wrap_angle else "m"
    return (f"(e) {table.structure} float", label,
            f"after the first {skip:,} steps: max {np.max(diff[skip:]):.2g} {unit}, RMS "
            f"{np.sqrt(np.mean(diff[skip:] ** 2)):.2g} {unit}; max over steps {skip:,}-10^6 "
            f"{np.max(diff[skip:1_000_000]):.2g}, over the last 5 10^6 {np.max(diff[n - 5_000_000:]):.2g}")


def agreement(long):
    """Section 6: print the C-against-Python figures."""
    tables = {name: cfdesign.design(cfdesign.load_spec(cfdesign.example_path(name))) for name in EXAMPLES}
    print(f"6. generated C against the Python runtime (cc: {compiler_version()}, clang: "
          f"{compiler_version('clang')})")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rows = option_rows(tables, folder) + memory_rows(folder) + gps_clock_rows(tables["position"], folder)
        if long:
            rows += long_rows(tables, folder)
    for what, how, figure in rows:
        print(f"  {what:<30} {how:<32} {figure}")


# ---------------------------------------------------------------------- (7) lock
def lock_rows():
    """Section 7: RMS error and cost of the locked step, ``lock=False`` and ``ArrivalKalman``."""
    sys.path.insert(0, str(AGREEMENT_DRIVER.parents[1]))
    from test_runtime_lock import HEADING, heading_rows, rms

    from cfdesign.runtime.arrivals import ArrivalKalman
    from cfdesign.spec import parse_spec

    table = cfdesign.design(parse_spec(HEADING))
    (aligned, psi), late, own = heading_rows(0, 0), heading_rows(7, 37)[0], heading_rows(3, 37)[0]
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for label, rows, make in (("aligned", aligned, lambda: Runtime(table)),
                                  ("37 ticks late", late, lambda: Runtime(table)),
                                  ("37 ticks late, lock=False", late, lambda: Runtime(table, lock=False)),
                                  ("own offsets, step", own, lambda: Runtime(table)),
                                  ("own offsets, ArrivalKalman.step", own, lambda: ArrivalKalman(table))):
            ticks = [{k: v for k, v in zip(rows, r, strict=True) if not np.isnan(v)}
                     for r in zip(*rows.values(), strict=True)]  # the tests' stepped() calls, built untimed
            t, est = cpu_timed(lambda ticks=ticks, make=make: [f.step(**r) for f in [make()] for r in ticks])
            out.append((label, f"RMS {rms(est, psi):.5f} rad", f"{1e6 * t / len(psi):.2g} us a tick"))
        big, big_late = (heading_rows(o, c, n=200_000)[0] for o, c in ((0, 0), (7, 37)))
        for label, rows in (("run, 200,000 rows aligned", big), ("run, 200,000 rows 37 ticks late", big_late)):
            t, _ = cpu_timed(lambda rows=rows: Runtime(table).run(rows))
            out.append((label, f"{t:.3g} s", f"{1e6 * t / 200_000:.2g} us a row"))
    print("7. the streaming step's phase lock (heading 100/10/1 Hz, tests/test_runtime_lock.py's rows)")
    for what, figure, cost in out:
        print(f"  {what:<34} {figure:<18} {cost}")


# ---------------------------------------------------------------------- report
def print_section(title, results):
    print(f"\n{title}")
    print(f"  {'table':<24} {'measured':<38} {'samples/s':>11}  note")
    for label, rows in results:
        for k, (what, rate, note) in enumerate(rows):
            rate_text = "-" if rate is None else f"{rate:.3g}"
            print(f"  {label if k == 0 else '':<24} {what:<38} {rate_text:>11}  {note}")


def compiler_version(name="cc"):
    cc = shutil.which(name)
    if cc is None:
        return "none"
    return subprocess.run([cc, "--version"], check=False, capture_output=True, text=True).stdout.splitlines()[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="samples for the Python figures")
    parser.add_argument("--c-steps", type=int, default=10_000_000, help="steps of the C timing loop")
    parser.add_argument("--c-agreement", action="store_true",
                        help="run only section 6: the generated C's agreement with the Python runtime")
    parser.add_argument("--lock", action="store_true", help="run only section 7: the streaming step's phase lock")
    parser.add_argument("--long", action="store_true", help="section 6: add the 10-million-step float runs")
    args = parser.parse_args(argv)
    if args.c_agreement:
        agreement(args.long)
        return 0
    if args.lock:
        lock_rows()
        return 0
    N = args.samples
    print(f"cfdesign {cfdesign.__version__} runtime benchmark: {N:,} samples (Python), {args.c_steps:,} steps (C)")
    print("BLAS threads: OPENBLAS_NUM_THREADS=" + os.environ.get("OPENBLAS_NUM_THREADS", "unset (library default)"))
    print(f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"cc: {compiler_version()} {' '.join(C_CFLAGS)}, {platform.machine()}")
    batch, stream, compiled = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for name, label in EXAMPLES.items():
            table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path(name)))
            data = readings(table, N)
            batch.append((label, batch_rows(table, data, N)))
            rows, t_step = streaming_rows(table, data, N)
            stream.append((label, rows))
            compiled.append((label, c_rows(table, data, args.c_steps, Path(tmp) / name, t_step)))
    print_section("(i) batch", batch)
    print_section("(ii) streaming", stream)
    print_section("(iii) compiled C, chained steps (each step needs the last one's state)", compiled)
    print_section("(ii-b) streaming by state size", [("chains", state_size_rows())])
    print_section("(iv) large states", [("chains", large_state_rows())])
    print_section("(v) start-up", [("command line", startup_rows())])
    return 0


if __name__ == "__main__":
    sys.exit(main())
