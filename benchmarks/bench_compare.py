"""CF versus EKF: every navigation filter on the shared scenarios, over several seeds.

Errors (position RMSE, maximum inside the GPS outage, heading and attitude RMSE) and the cost
per step of each filter, measured in the same process on this machine; averaged over seeds.
Run: python benchmarks/bench_compare.py [--seeds 5]
"""

import argparse
import time

import numpy as np

from cfdesign.reproduce.compare import FILTERS, HEADER, SCENARIOS, compare


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    for scenario in SCENARIOS:
        runs = [compare(scenario, seed) for seed in range(args.seeds)]
        print(f"\nscenario: {scenario}, mean over {args.seeds} seeds")
        print("  ".join(f"{h:>17s}" for h in HEADER[2:]), " filter")
        for name in FILTERS:
            rows = [r for rs in runs for r in rs if r.filter == name]
            if not rows:
                continue
            means = [np.nanmean([getattr(r, f) for r in rows]) if any(np.isfinite(getattr(r, f)) for r in rows)
                     else np.nan for f in ("position_rmse_m", "outage_max_m", "heading_rmse_deg",
                                           "attitude_rmse_deg", "us_per_step")]
            print("  ".join(f"{m:17.3g}" for m in means), f" {name}: {FILTERS[name]}")
    print(f"\n{time.perf_counter() - start:.1f} s in all")


if __name__ == "__main__":
    main()
