"""Running tables on logs: speed against the plainest pipeline, memory on a big log, a fleet on Dask.

    python benchmarks/bench_logs.py [--rows 1000000] [--big-rows 10000000] [--logs 8] [--fleet]
    python benchmarks/bench_logs.py --bridging        # section 5 alone (seconds)

Prints, from one run:

1. ``cfdesign run`` on a 1M-row heading log (gyro 100 Hz, odometry 10 Hz and compass 1 Hz
   in gapped columns at their own offsets, jittered timestamps) against the same job done as
   plainly as possible in the same run: ``pandas.read_csv`` + one ``scipy.signal.lfilter`` per
   column + ``DataFrame.to_csv`` (the baseline; it ignores time, gaps and offsets), and the same
   log with its compass in a 1 Hz file of its own (``--join``);
2. the peak memory (max RSS) of ``cfdesign run`` on a ``--big-rows`` log, in a child process, and
   with its compass in a 1 Hz file of its own (``--join``);
3. ``--logs`` logs run with 1 and 2 Dask workers (``--fleet`` alone runs only this; the best of
   ``--repeat`` runs of each, in turn, after an untimed fleet of one short log): the speed-up, for
   logs of each size of ``--fleet-rows`` (the fixed cost of a fleet run - the cluster's start and
   close, the workers' imports - is the same for every size, so the speed-up grows with the logs);
4. rows/s of ``run_log`` (CSV in, CSV out, as ``cfdesign run``) on ``--path-rows`` rows of each
   path a log can take (``--paths`` alone runs only this): (a) every sensor on the table's
   schedule; (b) slow sensors late by their own offsets (recomputed gains); (c) jittered times
   and a compass that slips a tick now and then (the Kalman filter over the arrivals); (d) a
   quarter of the slow readings missed (Runtime bridged by that filter); (e) the compass's clock
   0.5 % fast.  The ratio is to ``Runtime.run`` on the readings of (a) in memory, as many rows
   (the batch baseline, measured in the same run); the time of reading and writing the CSV
   alone (pandas) is shown beside each.
5. ``--bridging`` alone (accuracy, not speed): the RMS error of a table's fixed gains over logs
   with missed readings, over that of the Kalman filter of its model over the readings that do
   arrive (``ArrivalKalman``, which ``run_log`` bridges such stretches with), and ``run_log``'s
   own: the 100/10/1 Hz heading log of ``tests/test_logs.py`` whose odometry drops out and stops
   (the test's seeds) and a 100 Hz IMU with a 3 Hz GPS that loses runs of 1 to 10 fixes.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

GPS3 = {"name": "imu 100 Hz + gps 3 Hz", "structure": "position", "gain_form": "filter", "sensors": {
    "accelerometer": {"rate_hz": 100.0, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-3}},
    "gps": {"rate_hz": 3.0, "noise": {"std": 2.0}}}}
HEADING = {"name": "heading 100/10/1 Hz", "structure": "dckf3", "wrap_angle": True, "sensors": {
    "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
    "odometry": {"rate_hz": 10.0, "noise": {"std": 0.005}},
    "compass": {"rate_hz": 1.0, "noise": {"std": 0.05}}}}


def write_log(path, rows, seed=0, chunk=1_000_000, joined=None):
    """A heading log in blocks (bounded memory): odometry at rows 3, 13, ..., compass at 37, 137, ...;
    with ``joined``, the compass's rows in that file of their own (``time,compass``: ``--join``)."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    with open(path, "w", newline="") as fh, open(joined or os.devnull, "w", newline="") as other:
        for start in range(0, rows, chunk):
            k = np.arange(start, min(start + chunk, rows))
            t = k * 0.01
            psi = 2.0 + 6.0 * np.sin(0.05 * t) + 0.3 * t
            odo = np.where(k % 10 == 3, psi + 0.005 * rng.standard_normal(len(k)), np.nan)
            com = np.where(k % 100 == 37, psi + 0.05 * rng.standard_normal(len(k)), np.nan)
            wrap = lambda a: a - 2 * np.pi * np.ceil((a - np.pi) / (2 * np.pi))  # noqa: E731
            frame = pd.DataFrame({"time": t + 3e-4 * rng.standard_normal(len(k)),
                                  "gyro": 0.3 + 0.3 * np.cos(0.05 * t) + 0.01 * rng.standard_normal(len(k)),
                                  "odometry": wrap(odo), "compass": wrap(com)})
            if joined:
                frame.dropna(subset="compass")[["time", "compass"]].to_csv(other, index=False, header=start == 0,
                                                                           lineterminator="\n")
                frame = frame.drop(columns="compass")
            frame.to_csv(fh, index=False, header=start == 0, lineterminator="\n")


def path_log(n, case, seed=0):
    """A heading log of ``n`` rows taking path ``case`` (module docstring, 4.) as a DataFrame."""
    import pandas as pd

    from cfdesign.linear import wrap

    rng = np.random.default_rng(seed)
    k = np.arange(n)
    t = k * 0.01
    psi = 2.0 + 6.0 * np.sin(0.05 * t) + 0.3 * t
    odo_rows, com_rows = k[k % 10 == (0 if case == "a" else 3)], k[k % 100 == (0 if case == "a" else 37)]
    if case == "c":
        com_rows = np.minimum(com_rows + rng.integers(0, 2, len(com_rows)), n - 1)
        t = t + 3e-4 * rng.standard_normal(n)
    if case == "d":
        odo_rows = np.sort(rng.choice(odo_rows, 3 * len(odo_rows) // 4, replace=False))
        com_rows = np.sort(rng.choice(com_rows, 3 * len(com_rows) // 4, replace=False))
    if case == "e":
        com_rows = np.round(37 + np.arange(0, n - 40, 100 / 1.005)).astype(int)
    odo, com = np.full(n, np.nan), np.full(n, np.nan)
    odo[odo_rows] = psi[odo_rows] + 0.005 * rng.standard_normal(len(odo_rows))
    com[com_rows] = psi[com_rows] + 0.05 * rng.standard_normal(len(com_rows))
    return pd.DataFrame({"time": t, "gyro": 0.3 + 0.3 * np.cos(0.05 * t) + 0.01 * rng.standard_normal(n),
                         "odometry": wrap(odo), "compass": wrap(com)})


PATHS = {"a": "on schedule", "b": "late by offsets", "c": "jitter + slipping compass",
         "d": "missed readings (bridged)", "e": "compass clock 0.5 % fast"}


def paths(table, tmp, rows, repeat=2):
    """Section 4: rows/s of run_log per path beside Runtime.run on the same readings (best of
    ``repeat`` each: the machine may be shared), and the part of it that is the CSV itself
    (pandas.read_csv of the log plus DataFrame.to_csv of the estimates)."""
    import pandas as pd

    from cfdesign.logs import run_log
    from cfdesign.runtime import Runtime

    def best(fn, *args, **kw):
        times, out = [], None
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = fn(*args, **kw)
            times.append(time.perf_counter() - t0)
        return min(times), out

    def csv_alone(log, est, out):
        pd.read_csv(log)
        est.to_csv(out, index=False)

    regular = path_log(rows, "a")
    batch, _ = best(Runtime(table).run, {s: regular[s].to_numpy() for s in ("gyro", "odometry", "compass")},
                    states=True)
    print(f"\n4. {rows:,} rows per path, best of {repeat}: run_log (CSV in and out, --std); the ratio to Runtime.run "
          f"on the regular log's readings in memory (the batch baseline: {rows / batch:,.0f} rows/s); csv: "
          "read_csv of the log + to_csv of the estimates alone")
    for case, what in PATHS.items():
        path_log(rows, case).to_csv(tmp / "path.csv", index=False)
        mine, result = best(run_log, table, tmp / "path.csv", output=tmp / "path_est.csv", std=True)
        io, _ = best(csv_alone, tmp / "path.csv", pd.read_csv(tmp / "path_est.csv"), tmp / "again.csv")
        kalman = "  (Kalman over the arrivals)" if any("as they arrive" in n or "readings a second" in n
                                                      for n in result.notes) else ""
        print(f"   ({case}) {what:27s} {rows / mine:9,.0f} rows/s ({mine:5.1f} s; csv alone {io:4.1f} s); "
              f"ratio {mine / batch:5.1f}x{kalman}")


def baseline(log, out, table):
    """read_csv + one lfilter per column + to_csv: the plainest pipeline, in this process."""
    import pandas as pd
    from scipy.signal import lfilter

    from cfdesign.verify import band_polynomials

    t0 = time.perf_counter()
    df = pd.read_csv(log)
    bands, _ = band_polynomials(table)
    est = None
    for name, (num, den) in bands.items():
        y = lfilter(num, den, np.nan_to_num(df[name].to_numpy()))
        est = y if est is None else est + y
    pd.DataFrame({"time": df["time"], "heading": est, "gyro_correction": est}).to_csv(out, index=False)
    return time.perf_counter() - t0


def ours(table_path, log, out, join=None):
    from cfdesign.cli import main

    t0 = time.perf_counter()
    assert main(["run", str(table_path), str(log), "-o", str(out), *(["--join", str(join)] if join else [])]) == 0
    return time.perf_counter() - t0


def peak_memory(table_path, log, out, join=None) -> float:
    """Max RSS (MB) of ``cfdesign run`` (with ``--join join``) in a child process."""
    more = ["--join", str(join)] if join else []
    code = ("import resource, sys\nfrom cfdesign.cli import main\n"
            f"assert main(['run', {str(table_path)!r}, {str(log)!r}, '-o', {str(out)!r}, *{more!r}]) == 0\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(res.stdout.strip().splitlines()[-1]) / 1024, time.perf_counter() - t0


def fleet(table_path, folder, out, workers) -> float:
    """Seconds of ``cfdesign run TABLE FOLDER -o OUT --workers N`` in this process."""
    from cfdesign.cli import main

    t0 = time.perf_counter()
    assert main(["run", str(table_path), str(folder), "-o", str(out), "--workers", str(workers)]) == 0
    return time.perf_counter() - t0


def fleets(table_path, tmp, logs, sizes, repeat):
    """Section 3: ``logs`` logs of each size run with 1 and then 2 workers, in turn ``repeat`` times (the
    machine may be shared); the best time of each.  A fleet of one short log runs first, untimed: the
    first fleet of a process imported Dask and the command's modules (0.5-2 s) and was the 1-worker one."""
    (tmp / "warm").mkdir()
    write_log(tmp / "warm" / "robot.csv", 1000)
    fleet(table_path, tmp / "warm", tmp / "warm_out", 1)
    print(f"\n3. {logs} logs, 1 and 2 Dask workers (`cfdesign run TABLE DIR -o OUT --workers N`), "
          f"best of {repeat}:")
    for rows in sizes:
        folder = tmp / f"fleet{rows}"
        folder.mkdir()
        for i in range(logs):
            write_log(folder / f"robot{i}.csv", rows, seed=i)
        times = {1: [], 2: []}
        for _ in range(repeat):
            for workers, runs in times.items():
                runs.append(fleet(table_path, folder, tmp / f"out{workers}_{rows}", workers))
        one, two = min(times[1]), min(times[2])
        print(f"   {rows:>10,} rows a log: 1 worker {one:6.2f} s, 2 workers {two:6.2f} s: "
              f"speed-up {one / two:.2f}x (target >= 1.6x)")
        for f in (folder, tmp / f"out1_{rows}", tmp / f"out2_{rows}"):
            for g in f.iterdir():
                g.unlink()


def dropped_heading(table, n=15_000):
    """The log of ``tests/test_logs.py``'s bridging test: odometry losing runs of 1 to 6
    readings that stops for good at 100 s, a compass that starts at 40 s (truth, readings)."""
    from cfdesign.sim.gaussian import model_log

    x, readings = model_log(table, n, seed=7)
    odo, rng = readings["odometry"], np.random.default_rng(5)
    for start in range(300, 9000, 600):
        odo[start:start + 10 * int(rng.integers(1, 7))] = np.nan
    odo[10_000:] = np.nan
    readings["compass"][:4_000] = np.nan
    return x, readings


def dropped_gps(table, n=60_000):
    """A 100 Hz IMU and a 3 Hz GPS (10 minutes) losing a run of 1 to 10 fixes every 20 s."""
    from cfdesign.sim.gaussian import model_log

    x, readings = model_log(table, n, seed=7)
    gps, rng = readings["gps"], np.random.default_rng(5)
    for start in range(1000, n - 2000, 2000):
        gps[start:start + 34 * int(rng.integers(1, 11))] = np.nan  # 3 fixes every 100 ticks
    return x, readings


def bridging(start=3000):
    """Section 5: fixed gains and run_log over missed readings, against the Kalman filter over the arrivals."""
    import pandas as pd

    import cfdesign
    from cfdesign.linear import wrap
    from cfdesign.logs import run_log
    from cfdesign.runtime import Runtime
    from cfdesign.runtime.arrivals import ArrivalKalman
    from cfdesign.spec import parse_spec

    print("\n5. RMS error over missed readings (after the first 30 s), over the Kalman filter's over the arrivals:")
    for spec, log in ((HEADING, dropped_heading), (GPS3, dropped_gps)):
        table = cfdesign.design(parse_spec(spec))
        x, readings = log(table)
        first = readings[table.measurements[0].name]
        x0 = [first[np.isfinite(first)][0]] + [0.0] * (len(table.F) - 1)
        y = np.column_stack([readings[s.name] for s in table.measurements])
        u = np.column_stack([readings[s.name] for s in table.inputs])
        kf = ArrivalKalman(table, x0=x0).run(u, y)[0][:, 0]
        fixed = Runtime(table, x0=x0).run(readings)
        frame = pd.DataFrame({"time": np.arange(len(x)) * table.sample_time_s, **readings})
        ours = run_log(table, frame).estimates[table.states[0]].to_numpy()

        def rms(est, x=x, table=table):
            err = est[start:] - x[start:, 0]
            return float(np.sqrt(np.mean((wrap(err) if table.wrap_angle else err) ** 2)))

        missed = {s.name: int(np.isnan(readings[s.name][table.schedule.mask()[np.arange(len(x)) % table.period,
                                                                                 s.index]]).sum())
                  for s in table.measurements}
        print(f"   {table.name} ({len(x):,} ticks, scheduled readings missed: {missed}): the Kalman filter "
              f"{rms(kf):.3g}; the table's fixed gains {rms(fixed) / rms(kf):.2f} times it; run_log "
              f"{rms(ours) / rms(kf):.3f} times it")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--big-rows", type=int, default=10_000_000)
    ap.add_argument("--logs", type=int, default=8)
    ap.add_argument("--fleet-rows", type=lambda v: [int(r) for r in v.split(",")], default=[500_000, 2_000_000],
                    help="rows of each log of the fleet, comma-separated sizes (default 500000,2000000)")
    ap.add_argument("--path-rows", type=int, default=1_000_000)
    ap.add_argument("--paths", action="store_true", help="run only section 4 (the paths a log can take)")
    ap.add_argument("--fleet", action="store_true", help="run only section 3 (a fleet on 1 and 2 workers)")
    ap.add_argument("--bridging", action="store_true",
                    help="run only section 5 (fixed gains over missed readings against the Kalman filter)")
    ap.add_argument("--repeat", type=int, default=2, help="sections 3 and 4: the best of this many runs")
    args = ap.parse_args(argv)
    if args.bridging:
        bridging()
        return

    import cfdesign
    from cfdesign.spec import parse_spec

    table = cfdesign.design(parse_spec(HEADING))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tpath = table.save(tmp / "g.json")
        print(f"machine: {os.cpu_count()} CPUs; threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
        if args.paths:
            paths(table, tmp, args.path_rows, args.repeat)
            return
        if args.fleet:
            fleets(tpath, tmp, args.logs, args.fleet_rows, args.repeat)
            return

        write_log(tmp / "log.csv", args.rows)
        base = min(baseline(tmp / "log.csv", tmp / "base.csv", table) for _ in range(2))
        mine = min(ours(tpath, tmp / "log.csv", tmp / "est.csv") for _ in range(2))
        write_log(tmp / "imu.csv", args.rows, joined=tmp / "compass.csv")
        joined = min(ours(tpath, tmp / "imu.csv", tmp / "est.csv", tmp / "compass.csv") for _ in range(2))
        print(f"\n1. {args.rows:,} rows: cfdesign run {mine:.2f} s; read_csv + lfilter + to_csv {base:.2f} s; "
              f"ratio {mine / base:.2f}x (target <= 1.5x); the compass in a 1 Hz --join file: {joined:.2f} s "
              f"({joined / mine:.2f}x)")

        if args.big_rows:
            write_log(tmp / "big.csv", args.big_rows)
            size = (tmp / "big.csv").stat().st_size / 1e6
            mb, secs = peak_memory(tpath, tmp / "big.csv", tmp / "big_est.csv")
            print(f"\n2. {args.big_rows:,} rows ({size:.0f} MB of CSV): peak memory {mb:.0f} MB (target < 1000 MB), "
                  f"{secs:.1f} s")
            (tmp / "big.csv").unlink()
            write_log(tmp / "big.csv", args.big_rows, joined=tmp / "big_compass.csv")
            mb, secs = peak_memory(tpath, tmp / "big.csv", tmp / "big_est.csv", tmp / "big_compass.csv")
            print(f"   the compass in a 1 Hz --join file: peak memory {mb:.0f} MB, {secs:.1f} s")
            for f in ("big.csv", "big_compass.csv", "big_est.csv"):
                (tmp / f).unlink(missing_ok=True)

        fleets(tpath, tmp, args.logs, args.fleet_rows, args.repeat)
        paths(table, tmp, args.path_rows, args.repeat)
    print(f"\n(this process: max RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB)")


if __name__ == "__main__":
    main()
