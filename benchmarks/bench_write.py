"""Writing the estimates' CSV: Arrow's formatting against pandas' ``to_csv``, in the same run.

    python benchmarks/bench_write.py [--rows 1000000] [--repeat 2]

For a plain heading log (``cfdesign run TABLE LOG -o est.csv``, as bench_logs section 1) and
for each path of bench_logs section 4 (``run_log``, --std), runs the job with the writer as it
is (Arrow's text of the numbers when pyarrow is installed) and with the writer forced to
pandas' ``to_csv`` (the baseline), alternately, best of ``--repeat`` each.  Prints the seconds
spent in the writer's CSV text and the whole run's, the ratios, and whether both files are
byte for byte the same.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from bench_logs import HEADING, PATHS, path_log, write_log


def timed(job, pandas):
    """``(writer seconds, whole seconds)`` of ``job()``, the writer forced to pandas or not."""
    from cfdesign.logs import write

    fast, csv = write._fast_pieces, write._Writer._csv
    spent = [0.0]

    def timed_csv(self, shown, header):
        t0 = time.perf_counter()
        csv(self, shown, header)
        spent[0] += time.perf_counter() - t0

    write._Writer._csv = timed_csv
    if pandas:
        write._fast_pieces = lambda frame: None
    try:
        t0 = time.perf_counter()
        job()
        return spent[0], time.perf_counter() - t0
    finally:
        write._fast_pieces, write._Writer._csv = fast, csv


def compare(label, job, out, repeat):
    """Both writers on ``job`` alternately; one line of figures."""
    best = {True: (float("inf"),) * 2, False: (float("inf"),) * 2}
    texts = {}
    for _ in range(repeat):
        for pandas in (True, False):
            w, whole = timed(job, pandas)
            best[pandas] = (min(best[pandas][0], w), min(best[pandas][1], whole))
            texts[pandas] = out.read_bytes()
    (pw, pall), (fw, fall) = best[True], best[False]
    print(f"   {label:30s} writer {pw:5.2f} -> {fw:5.2f} s ({pw / fw:4.1f}x); whole run {pall:5.2f} -> "
          f"{fall:5.2f} s ({pall / fall:4.2f}x); same bytes: {texts[True] == texts[False]}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)

    import cfdesign
    from cfdesign.cli import main as cli
    from cfdesign.logs import run_log
    from cfdesign.spec import parse_spec

    table = cfdesign.design(parse_spec(HEADING))
    print(f"{args.rows:,} rows, best of {args.repeat}: pandas' to_csv -> Arrow's text (same run)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tpath, out = table.save(tmp / "g.json"), tmp / "est.csv"
        write_log(tmp / "log.csv", args.rows)
        compare("plain log (cfdesign run)", lambda: cli(["run", str(tpath), str(tmp / "log.csv"), "-o", str(out)]),
                out, args.repeat)
        for case, what in PATHS.items():
            path_log(args.rows, case).to_csv(tmp / "path.csv", index=False)
            compare(f"({case}) {what}", lambda: run_log(table, tmp / "path.csv", output=out, std=True),
                    out, args.repeat)


if __name__ == "__main__":
    main()
