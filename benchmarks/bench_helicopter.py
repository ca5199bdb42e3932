"""Vasconcelos et al.'s Table 2 (helicopter), full reproduction:
``python benchmarks/bench_helicopter.py [--runs N] [--json]``.

Prints the table (ours beside the paper's, with the ratio) and the wall-clock time of the run.
"""

from __future__ import annotations

import argparse
import time

from cfdesign.reproduce import helicopter


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    helicopter.add_arguments(parser)
    args = parser.parse_args()
    start = time.perf_counter()
    status = helicopter.run(args)
    elapsed = time.perf_counter() - start
    print(f"\n{args.runs} runs in {elapsed:.1f} s ({elapsed / args.runs:.2f} s per run, both rows)")
    return status


if __name__ == "__main__":
    raise SystemExit(main())
