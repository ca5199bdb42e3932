"""Speed of the Python runtime and of the generated C filter, each beside a baseline.

Run by hand from the repository root:  python benchmarks/bench_runtime.py [--samples N] [--c-steps M]

On the robot-heading DCKF3 table of Carreira et al. (the "dckf3" example: single rate, heading
wrapped) and the multirate position table (period 50), with 1,000,000 samples of a slow
sinusoid plus noise:

1. batch: ``Runtime(table).run(readings)`` in samples/s beside ``scipy.signal.lfilter`` on
   the same data (the DCKF3's three bands as IIR filters, summed; target run >= 0.5 x
   lfilter; the periodic table has no LTI bands);
2. streaming: ``Runtime.step`` per sample beside a plain Python loop doing the same arithmetic
   with floats, and ``Runtime.run`` on blocks of 10,000 samples with the state carried over
   (target > 1e6 samples/s);
3. compiled C (``cfdesign.codegen.write_c``, ``cc -std=c99 -O2``): ns per step over
   10,000,000 chained steps (target < 10 ns for the DCKF3), beside two baselines in the same
   program and loop: a call that only copies the inputs, and a one-pole IIR.

Prints figures only; no assertions on time.
"""

from __future__ import annotations

import argparse
import math
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from string import Template

import numpy as np
import scipy
from scipy.signal import lfilter

import cfdesign
from cfdesign.codegen import write_c
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
def readings(table, N, seed=0, amplitude=None):
    """A slow sinusoid through every sensor plus noise (:func:`cfdesign.sim.sinusoid_readings`)."""
    return sinusoid_readings(table, N, seed=seed, amplitude=amplitude)


def columns(table, data) -> list:
    """The readings in runtime order: inputs by index, then measurements by index."""
    rt = Runtime(table)
    return [data[name] for name in rt.inputs + rt.measurements]


def timed(fn, repeat=1):
    """Best wall time of ``fn()`` over ``repeat`` runs (s) and its last result."""
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


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
    """The runtime's step with Python floats and lists only (no numpy): the streaming baseline."""
    F, B, H = (np.asarray(a, dtype=float).tolist() for a in (table.F, table.B, table.H))
    K = [np.asarray(k, dtype=float).tolist() for k in table.K]
    rt = Runtime(table)
    p, n, N_ = len(rt.inputs), len(F), range(len(F))
    angle = {s.name for s in table.sensors if s.order == 0}
    wrapped = [bool(table.wrap_angle) and name in angle for name in rt.measurements]
    pi, tau, state = math.pi, 2 * math.pi, {"x": [0.0] * n, "u": [0.0] * p, "phase": 0}

    def step(row):
        x, u, Kp = state["x"], state["u"], K[state["phase"]]
        u = [v if v == v else u[j] for j, v in enumerate(row[:p])]
        e = [0.0 if y != y else y - sum(h * xj for h, xj in zip(Hi, x, strict=True))
             for y, Hi in zip(row[p:], H, strict=True)]
        e = [pi - (pi - v) % tau if w else v for v, w in zip(e, wrapped, strict=True)]
        c = [sum(k * v for k, v in zip(Kp[r], e, strict=True)) for r in N_]
        if table.gain_form == "filter":
            x = [a + b for a, b in zip(x, c, strict=True)]
            c = [0.0] * n
        est = x[0]
        x = [sum(f * xj for f, xj in zip(F[r], x, strict=True)) + sum(b * uj for b, uj in zip(B[r], u, strict=True))
             + c[r] for r in N_]
        if table.wrap_angle:
            x[0], est = pi - math.fmod(math.fmod(pi - x[0], tau) + tau, tau), pi - math.fmod(
                math.fmod(pi - est, tau) + tau, tau)
        state.update(x=x, u=u, phase=(state["phase"] + 1) % len(K))
        return est

    return step


def streaming_rows(table, data, N):
    rt = Runtime(table)
    names = rt.inputs + rt.measurements
    rows = list(zip(*(c.tolist() for c in columns(table, data)), strict=True))
    t_step, est_step = timed(lambda: [rt.step(**dict(zip(names, r, strict=True))) for r in rows])
    plain = plain_python_filter(table)
    t_plain, est_plain = timed(lambda: [plain(r) for r in rows])
    agree = float(np.max(np.abs(wrap(np.subtract(est_plain, est_step)))))
    blocks = Runtime(table)
    t_block, _ = timed(lambda: [blocks.run({k: v[i:i + BLOCK] for k, v in data.items()}) for i in range(0, N, BLOCK)])
    return [("Runtime.step per sample", N / t_step, f"{1e6 * t_step / N:.1f} us/step"),
            ("plain Python floats loop", N / t_plain, f"{1e6 * t_plain / N:.1f} us/step (agrees to {agree:.0e})"),
            (f"Runtime.run, {BLOCK:,}-sample blocks", N / t_block, "target > 1e6/s")], t_step / N


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


# ---------------------------------------------------------------------- report
def print_section(title, results):
    print(f"\n{title}")
    print(f"  {'table':<24} {'measured':<38} {'samples/s':>11}  note")
    for label, rows in results:
        for k, (what, rate, note) in enumerate(rows):
            rate_text = "-" if rate is None else f"{rate:.3g}"
            print(f"  {label if k == 0 else '':<24} {what:<38} {rate_text:>11}  {note}")


def compiler_version():
    cc = shutil.which("cc")
    if cc is None:
        return "none"
    return subprocess.run([cc, "--version"], check=False, capture_output=True, text=True).stdout.splitlines()[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="samples for the Python figures")
    parser.add_argument("--c-steps", type=int, default=10_000_000, help="steps of the C timing loop")
    args = parser.parse_args(argv)
    N = args.samples
    print(f"cfdesign {cfdesign.__version__} runtime benchmark: {N:,} samples (Python), {args.c_steps:,} steps (C)")
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
