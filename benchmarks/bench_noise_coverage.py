"""Coverage of the 95 % intervals ``cfdesign noise`` prints, over Monte-Carlo static logs.

    python benchmarks/bench_noise_coverage.py [--reps 50] [--case NAME ...] [--list]

Each case is a static recording of known white noise density N, rate random walk K and bias
instability B (flicker frequency noise of one-sided PSD ``B^2 / (2 pi f)``, whose Allan deviation
is flat at ``sqrt(2 ln 2 / pi) B``: IEEE Std 952-1997, Annex C), at a rate and for a duration.
Every repetition is written as a CSV with a time column and read as a user runs it,
``cfdesign noise LOG --column gyro_z --time time`` (the command's ``main`` in this process, to
spare the interpreter's start-up; the numbers are the printed ones).  Per case and term the table
gives how often the term was reported, the mean estimate over the truth, the share of the
reported 95 % intervals that hold the truth, and the measured spread of ``ln(estimate)`` beside
the one the intervals state (their width over ``2 x 1.96``).  A term reported where the truth has
none is counted as ``invented``.

Runtime: about 12 minutes for every case at ``--reps 50`` on one core (the 3-hour cases most).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import tempfile
from pathlib import Path

import numpy as np

from cfdesign.cli import main as cli

#: name -> (seconds, rate Hz, N u/sqrt(Hz), K u/sqrt(s), B u)
CASES = {
    "N 1k 10m": (600, 1000, 2e-3, 0, 0), "N 50 3h": (10800, 50, 2e-3, 0, 0),
    "NK 50 10m": (600, 50, 2e-3, 2e-4, 0), "NK 50 1h": (3600, 50, 2e-3, 2e-4, 0),
    "NK 50 3h": (10800, 50, 2e-3, 2e-4, 0), "NK 200 10m": (600, 200, 2e-3, 2e-4, 0),
    "NK 200 1h": (3600, 200, 2e-3, 2e-4, 0), "NK 1k 10m": (600, 1000, 2e-3, 2e-4, 0),
    "NKweak 50 1h": (3600, 50, 2e-3, 2e-5, 0),
    "NB 50 1h": (3600, 50, 2e-3, 0, 5e-4), "NB 50 3h": (10800, 50, 2e-3, 0, 5e-4),
    "NB 200 10m": (600, 200, 2e-3, 0, 5e-4), "NB 1k 10m": (600, 1000, 2e-3, 0, 5e-4),
}
_LINE = {s: re.compile(s + r" = ([-0-9.e+]+) \S+ \(95% CI ([-0-9.e+]+) to ([-0-9.e+]+)") for s in "NKB"}


def flicker(n, rate, B, rng):
    """``n`` readings of flicker frequency noise of one-sided PSD ``B^2 / (2 pi f)`` (shaped white
    noise over eight times the recording, so that its lowest frequencies are not missing)."""
    size = 8 * n
    f = np.fft.rfftfreq(size, 1 / rate)
    amp = np.zeros_like(f)
    amp[1:] = B / np.sqrt(2 * math.pi * f[1:])
    spectrum = (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))) * amp * math.sqrt(rate / size / 2)
    return np.fft.irfft(spectrum, size)[:n] * size


def recording(seconds, rate, N, K, B, rng):
    """A sensor at rest: white noise (std ``N sqrt(rate)``), a random walk (steps ``K / sqrt(rate)``), flicker."""
    n = round(seconds * rate)
    y = N * math.sqrt(rate) * rng.standard_normal(n)
    if K:
        y += np.cumsum(K / math.sqrt(rate) * rng.standard_normal(n))
    if B:
        y += flicker(n, rate, B, rng)
    return y


def run_cli(path) -> dict:
    """``{symbol: (value, low, high)}`` as ``cfdesign noise`` prints them."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = cli(["noise", str(path), "--column", "gyro_z", "--time", "time", "--unit", "rad/s"])
    if code:
        raise RuntimeError(f"cfdesign noise {path} exited {code}")
    found = {s: p.search(out.getvalue()) for s, p in _LINE.items()}
    return {s: tuple(float(v) for v in m.groups()) for s, m in found.items() if m}


def case_row(name, reps, folder) -> str:
    seconds, rate, N, K, B = CASES[name]
    got = {"N": [], "K": [], "B": []}
    for rep in range(reps):
        rng = np.random.default_rng(1000 + rep)
        y = recording(seconds, rate, N, K, B, rng)
        t = 100.0 + np.arange(len(y)) / rate
        path = Path(folder) / "static.csv"
        np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="time,gyro_z", comments="",
                   fmt=["%.6f", "%.9e"])
        for symbol, value in run_cli(path).items():
            got[symbol].append(value)
    parts = []
    for symbol, true in (("N", N), ("K", K), ("B", B)):
        v = np.array(got[symbol]).reshape(-1, 3)
        if not true:
            if len(v):
                parts.append(f"{symbol} invented {len(v)}/{reps}")
            continue
        if not len(v):
            parts.append(f"{symbol} 0/{reps}")
            continue
        cover = int(np.sum((v[:, 1] <= true) & (true <= v[:, 2])))
        spread = float(np.std(np.log(v[:, 0]), ddof=1)) if len(v) > 2 else math.nan
        stated = float(np.mean(np.log(v[:, 2] / v[:, 1]) / (2 * 1.96)))
        parts.append(f"{symbol} {len(v)}/{reps} est/true {np.mean(v[:, 0]) / true:.3f} covered {cover / len(v):4.0%} "
                     f"sd(ln) {spread:.3g} stated {stated:.3g}")
    return f"{name:13s} " + "; ".join(parts)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reps", type=int, default=50)
    p.add_argument("--case", action="append", choices=list(CASES), help="default: every case")
    p.add_argument("--list", action="store_true", help="list the cases (seconds, Hz, N, K, B) and exit")
    args = p.parse_args(argv)
    if args.list:
        for name, figures in CASES.items():
            print(name, figures)
        return
    print(f"{args.reps} logs per case through `cfdesign noise`: reported, mean estimate / truth, share of 95 % "
          "intervals holding the truth, measured sd of ln(estimate) and the one the intervals state")
    with tempfile.TemporaryDirectory() as folder:
        for name in args.case or list(CASES):
            print(case_row(name, args.reps, folder), flush=True)


if __name__ == "__main__":
    main()
