"""Carreira et al.'s Tables I and II (robot heading), full reproduction, with timing.

Run by hand from the repository root:  python benchmarks/bench_carreira.py [RUNS] [--reading std|variance]

Designs the twelve filters (six two-sensor CFs, six three-sensor CF³s), runs each on RUNS
(default 100) Monte-Carlo simulations of the 2440-s rounded square, and prints both tables
beside the paper's values with the ratio ours/paper, the checks (best rows, ordering), and
where the time goes: the designs, one simulation of the sensors, one filter run.  Prints
figures only; no assertions.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

from cfdesign.reproduce.carreira import ROWS, design_row, reproduce, run_filter  # noqa: E402
from cfdesign.sim import robot_heading  # noqa: E402


def timed(fn, *args, repeat=1):
    """Result and mean wall time of ``fn(*args)``; with ``repeat > 1`` after one warm-up call."""
    if repeat > 1:
        fn(*args)
    t0 = time.perf_counter()
    for _ in range(repeat):
        out = fn(*args)
    return out, (time.perf_counter() - t0) / repeat


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="?", type=int, default=100)
    parser.add_argument("--reading", choices=sorted(robot_heading.READINGS), default="std")
    args = parser.parse_args(argv)
    reading = robot_heading.READINGS[args.reading]

    _, t_design = timed(lambda: [design_row(row, reading) for row in ROWS])
    sc = robot_heading.scenario(reading)
    signals, t_sim = timed(sc.signals, 0, repeat=5)
    row = ROWS[0]
    _, t_filter = timed(run_filter, row, design_row(row, reading), sc, signals, repeat=20)
    result, t_total = timed(lambda: reproduce(args.runs, reading=reading, progress=True))

    print(result.text())
    print()
    print(f"timing: {len(ROWS)} designs {t_design:.2f} s (first call; cached after), one simulation of the "
          f"three sensors ({sc.trajectory.steps} steps) {1e3 * t_sim:.1f} ms, one filter run {1e3 * t_filter:.2f} ms "
          f"({sc.trajectory.steps / t_filter / 1e6:.2f} M steps/s); reproduction with {args.runs} runs "
          f"{t_total:.2f} s")


if __name__ == "__main__":
    main()
