"""Predicted against measured error: what ``cfdesign design`` prints and ``cfdesign run --std``
writes, against the error of the estimates ``cfdesign run`` writes for a simulated log.

Each case designs a table through the command line (``cfdesign design SPEC -o g.json``, or a
built-in example; a continuous example is discretised with ``cfdesign discretize`` as a user
would), draws a long log whose sensors follow the design file's noise model exactly (white noise
of the stated std or density, a bias random walk of the stated density, sampled exactly over each
tick, the table's own tick, a time column with jitter of 3 % of a tick, slow sensors at their own
offsets), runs it with ``cfdesign run g.json log.csv -o est.csv --std`` (and ``--prediction``)
and prints, per case and state, the predicted std (the figure ``cfdesign design`` prints for the
first state, else the table's covariance: the RMS over the period for a multirate table), the
RMS of the written ``<state>_std`` column, the measured RMS error after the start-up, their
ratios, the Monte-Carlo standard error of the measured variance (batch means over 50 batches,
which allows for the errors' correlation in time), and the ratio of the two figures
``cfdesign run --reference`` prints itself (the RMS error after its start-up, and the
predicted std beside it).

Run: ``python benchmarks/bench_predicted.py [--scale X] [--case NAME ...]``: all cases 16 minutes
(``--scale 0.25``: 7 minutes, with Monte-Carlo errors twice as large).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from cfdesign.cli import main as cli
from cfdesign.gains import load_gains
from cfdesign.spec import example_path

#: multirate heading: 100 Hz gyro, 10 Hz odometry, 1 Hz compass (case b; the odometry and compass
#: arrive at their own offsets in the log)
HEADING_MULTIRATE = """
name = "heading, multirate"
structure = "dckf3"
gain_form = "{form}"
wrap_angle = true
[sensors.gyro]
measures = "rate"
rate_hz = 100.0
noise = {{ std = {gyro} }}
bias = {{ model = "random_walk", density = {gyro_bias} }}
[sensors.odometry]
measures = "angle"
rate_hz = 10.0
noise = {{ std = {odometry} }}
[sensors.compass]
measures = "angle"
rate_hz = 1.0
noise = {{ std = {compass} }}
"""
#: the noise of case b (a test takes other numbers, whose errors decorrelate faster)
HEADING_NOISE = {"gyro": 0.01, "gyro_bias": 1.0e-3, "odometry": 0.02, "compass": 0.05}

#: 3 Hz GPS beside a 100 Hz accelerometer: a non-integer rate ratio (case c)
GPS_3HZ = """
name = "position, 3 Hz GPS"
structure = "position"
gain_form = "{form}"
[sensors.accelerometer]
measures = "acceleration"
rate_hz = 100.0
noise = {{ std = {accelerometer} }}
bias = {{ model = "random_walk", density = {accelerometer_bias} }}
[sensors.gps]
measures = "position"
rate_hz = 3.0
noise = {{ std = {gps} }}
"""
#: the noise of case c
GPS_NOISE = {"accelerometer": 0.05, "accelerometer_bias": 1.0e-3, "gps": 1.0}

JITTER = 0.03  # time stamps: uniform jitter of +-3 % of a tick
SETTLE_S = 300.0  # start-up left out of the comparison

#: rows per case: enough for a Monte-Carlo standard error of each variance near or below 2 % (the
#: slow modes - a bias tracked over minutes, a 1 Hz GPS - need millions of ticks)
ROWS = {"dckf3": 4_000_000, "robot-heading": 400_000, "position": 10_000_000, "tilt": 24_000_000,
        "ckf3": 8_000_000, "heading": 1_600_000, "missing": 1_600_000, "gps3": 4_000_000}


def _quiet(argv: list) -> str:
    """Run ``cfdesign`` with ``argv``; return its stdout (stderr swallowed); raise on failure."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli(argv)
    if code:
        raise RuntimeError(f"cfdesign {' '.join(argv)} failed ({code}): {err.getvalue().strip()}")
    return out.getvalue()


def printed_std(summary: str) -> dict:
    """The predicted std of the first state that ``cfdesign design`` prints, per output: the
    single-rate figure, or a multirate table's RMS over the period."""
    found = {}
    for line in summary.splitlines():
        m = re.search(r"predicted steady-state std .*\((posterior|prior)\): ([0-9.e+-]+)"
                      r"(?: at the worst phase, ([0-9.e+-]+) RMS over the period)?", line)
        if m:
            found[m.group(1)] = float(m.group(3) or m.group(2))
    return found


def design(workdir: Path, name: str, spec_text: str | None = None, example: str | None = None,
           discretize_hz: float | None = None) -> tuple:
    """Design (and discretise) a case through the command line; return the table's path, the
    table, the printed figures and the sensors' figures."""
    table_path = workdir / f"{name}.json"
    if spec_text is not None:
        spec_path = workdir / f"{name}.toml"
        spec_path.write_text(spec_text)
    else:
        spec_path = example_path(example)
    summary = _quiet(["design", str(spec_path), "-o", str(table_path)])
    if discretize_hz:
        continuous = table_path
        table_path = workdir / f"{name}_d.json"
        summary = _quiet(["discretize", str(continuous), "--rate-hz", f"{discretize_hz:g}",
                          "-o", str(table_path)])
    return table_path, load_gains(table_path), printed_std(summary), _sensor_figures(spec_path)


def _bias_steps(q: float, T: float, n: int, rng) -> tuple:
    """A bias random walk of density ``q`` (unit/sqrt(s)) sampled exactly: its value at each tick
    and its mean over the tick that follows (the reading of an input held over the tick)."""
    if q == 0:
        return np.zeros(n), np.zeros(n)
    cov = q * q * np.array([[T, T * T / 2], [T * T / 2, T ** 3 / 3]])
    steps = rng.standard_normal((n, 2)) @ np.linalg.cholesky(cov).T
    b = np.concatenate(([0.0], np.cumsum(steps[:-1, 0])))
    return b, b + steps[:, 1] / T


def _sensor_figures(spec_path) -> dict:
    """``{sensor: (per-sample std, bias density)}`` of the design file."""
    from cfdesign.spec import load_spec

    spec = load_spec(spec_path)
    return {x.name: (float(np.sqrt(x.noise.variance(x.rate_hz))), float(np.sqrt(x.bias.psd)))
            for x in spec.sensors}


def simulate(table, figures: dict, rows: int, offsets: dict, rng, missing: float = 0.0) -> tuple:
    """A log of ``rows`` base ticks that follows the table's sensors exactly.

    The truth is a chain of integrators driven by a smooth input held over each tick (angle from a
    rate; position and velocity from an acceleration, ``x[k+1] = F x[k] + B u[k]`` with the
    table's own ``F``, ``B``); an input sensor reads the input plus its bias (mean over the tick
    of an exact random walk) plus white noise; a measurement reads the state it measures (its
    ``order``: 0 angle/position, 1 velocity) plus white noise, at its rate, from the tick given
    in ``offsets`` (the ticks nearest ``j * base / rate + offset``); ``missing`` of the slow
    readings are left out at random.

    Returns
    -------
    log : DataFrame
        ``time`` (s, jittered) and one column per sensor.
    truth : dict
        ``{state: true value per tick}`` (a bias state in the table's own sign).
    """
    T = table.sample_time_s
    k = np.arange(rows)
    inp = next(s for s in table.sensors if s.role == "input")
    order = inp.order
    accel = 0.3 * np.sin(2 * np.pi * 0.05 * k * T) + 0.1 * np.sin(2 * np.pi * 0.37 * k * T + 1.0)
    sigma, q = figures[inp.name]
    b_tick, b_mean = _bias_steps(q, T, rows, rng)
    derivs = [None] * (order + 1)
    derivs[order] = accel
    for level in range(order - 1, -1, -1):  # x[k+1] = x[k] + T x'[k] (+ T^2/2 x''[k] for position)
        step = T * derivs[level + 1] + (T * T / 2 * derivs[level + 2] if level + 2 <= order else 0.0)
        derivs[level] = np.concatenate(([0.0], np.cumsum(step[:-1])))
    log = {"time": k * T + rng.uniform(-JITTER, JITTER, rows) * T,
           inp.name: accel + b_mean + sigma * rng.standard_normal(rows)}
    for s in table.sensors:
        if s.role != "measurement":
            continue
        ratio = (1.0 / T) / s.rate_hz
        at = np.unique(np.round(np.arange(0, rows / ratio + 1) * ratio + offsets.get(s.name, 0)).astype(int))
        at = at[at < rows]
        if missing and ratio > 1:
            at = at[rng.random(at.size) >= missing]
        col = np.full(rows, np.nan)
        col[at] = derivs[s.order][at] + figures[s.name][0] * rng.standard_normal(at.size)
        log[s.name] = col
    truth = {}
    for i, state in enumerate(table.states):
        if i <= order - 1 or (i == 0):
            truth[state] = derivs[i]
        else:  # the bias state: x_j = -b B[r] / F[r, j] cancels the bias in the input row r
            r = int(np.argmax(np.abs(table.B[:, inp.index])))
            truth[state] = -b_tick * table.B[r, inp.index] / table.F[r, i]
    return pd.DataFrame(log), truth


def model_check(table, log: pd.DataFrame, truth: dict) -> tuple:
    """The simulation against the table's own model: the sample covariances of the process noise
    ``w[k] = x[k+1] - F x[k] - B u[k]`` (over the simulated truth and the input readings) and of
    each measurement's noise ``y - H x``, divided by the table's ``Q`` and ``R`` (1 where the
    simulation is the model; a diagonal entry of ``Q`` only).

    Returns
    -------
    q_ratio : ndarray, shape (n,)
        ``diag(cov(w)) / diag(Q)``.
    r_ratio : ndarray, shape (m,)
        ``var(y - H x) / diag(R)``.
    """
    x = np.column_stack([truth[s] for s in table.states])
    inputs = [s for s in table.sensors if s.role == "input"]
    u = np.column_stack([log[s.name].to_numpy() for s in sorted(inputs, key=lambda s: s.index)])
    w = x[1:] - x[:-1] @ table.F.T - u[:-1] @ table.B.T
    q_ratio = np.diag(np.cov(w.T).reshape(len(table.states), -1)) / np.diag(table.Q)
    r_ratio = []
    for s in sorted((s for s in table.sensors if s.role == "measurement"), key=lambda s: s.index):
        v = log[s.name].to_numpy() - x @ table.H[s.index]
        r_ratio.append(np.nanvar(v) / table.R[s.index, s.index])
    return q_ratio, np.array(r_ratio)


def batch_se(sq: np.ndarray, batches: int = 50) -> float:
    """Relative standard error of the mean of ``sq`` by batch means."""
    n = sq.size // batches
    means = sq[: n * batches].reshape(batches, n).mean(axis=1)
    return float(means.std(ddof=1) / np.sqrt(batches) / means.mean())


def _rms_lines(stdout: str) -> dict:
    """``{state: (settled RMS, predicted)}`` from the ``RMS error of STATE: ...`` lines that
    ``cfdesign run --reference`` prints."""
    found = {}
    for m in re.finditer(r"RMS error of (\S+): .*?; ([0-9.e+-]+)(?: \S+)? after the start-up.*?; "
                         r"predicted ([0-9.e+-]+)", stdout):
        found[m.group(1)] = (float(m.group(2)), float(m.group(3)))
    return found


def compare(table_path: Path, table, log: pd.DataFrame, truth: dict, printed: dict, workdir: Path,
            prediction: bool, settle_s: float = SETTLE_S) -> list:
    """Run the log through ``cfdesign run ... --std`` (``--prediction`` too when ``prediction``)
    and compare, per state, the error of the written estimates after ``settle_s`` (s) with the
    prediction: the printed figure for the first state, else the table's covariance (RMS over the
    period), and the RMS of the written ``<state>_std`` column over the same rows."""
    log_path, est_path = workdir / "log.csv", workdir / "est.csv"
    log.assign(**{f"true_{state}": truth[state] for state in table.states}).to_csv(log_path, index=False)
    argv = ["run", str(table_path), str(log_path), "-o", str(est_path), "--std"]
    for state in table.states:
        argv += ["--reference", f"{state}=true_{state}"]
    if prediction:
        argv.append("--prediction")
    said = _rms_lines(_quiet(argv))
    est = pd.read_csv(est_path)
    output = ("prior" if table.output == "posterior" else "posterior") if prediction else table.output
    covs = table.P_filtered if output == "posterior" else table.P
    keep = log["time"].to_numpy() >= settle_s
    rows = []
    for i, state in enumerate(table.states):
        err = est[state].to_numpy() - truth[state]
        if table.wrap_angle and i == 0:
            err = np.angle(np.exp(1j * err))
        sq = err[keep] ** 2
        predicted = printed[output] if i == 0 else float(np.sqrt(np.mean([c[i, i] for c in covs])))
        column = float(np.sqrt(np.mean(est[f"{state}_std"].to_numpy()[keep] ** 2)))
        measured = float(np.sqrt(sq.mean()))
        rows.append({"output": output, "state": state, "predicted": predicted, "std_column": column,
                     "measured": measured, "ratio": measured / predicted,
                     "ratio_column": measured / column, "mc_se_var": batch_se(sq),
                     "run_rms": said[state][0], "run_predicted": said[state][1]})
    return rows


def cases(workdir: Path) -> dict:
    """``{name: (table path, table, printed figures, sensor figures, offsets, missing, rows)}``."""
    out = {}
    for ex, hz in (("dckf3", None), ("robot-heading", None), ("position", None), ("tilt", 200.0)):  # tilt: continuous
        out[f"a:{ex}"] = (*design(workdir, ex, example=ex, discretize_hz=hz), {}, 0.0, ROWS[ex])
    # the CKF3 example's sensors are multirate, which `cfdesign discretize` refuses: its discrete
    # counterpart is the cfn of 3 bands with a full gain (cf3's fixed gains are single-rate only)
    text = Path(example_path("ckf3")).read_text().replace(
        'structure = "ckf3"', 'structure = "cfn"\nbands = 3\nfull = true\ndiscrete = true')
    made = design(workdir, "ckf3_discrete", spec_text=text)
    out["a:ckf3 as discrete cfn"] = (*made, {"position": 3}, 0.0, ROWS["ckf3"])
    for form in ("predictor", "filter"):
        made = design(workdir, f"heading_{form}", spec_text=HEADING_MULTIRATE.format(form=form, **HEADING_NOISE))
        out[f"b/e:heading {form}"] = (*made, {"odometry": 3, "compass": 37}, 0.0, ROWS["heading"])
        if form == "predictor":
            out["d:heading 20% missing"] = (*made, {"odometry": 3, "compass": 37}, 0.2, ROWS["missing"])
        made = design(workdir, f"gps3_{form}", spec_text=GPS_3HZ.format(form=form, **GPS_NOISE))
        out[f"c/e:gps 3 Hz {form}"] = (*made, {"gps": 5}, 0.0, ROWS["gps3"])
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", type=float, default=1.0, help="times each case's rows (ROWS)")
    p.add_argument("--case", nargs="*", help="substrings of the cases to run (default all)")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"{'case':30s} {'output':9s} {'state':24s} {'predicted':>10s} {'std col':>10s} {'measured':>10s} "
          f"{'ratio':>6s} {'r(col)':>6s} {'MC se(var)':>10s} {'run: RMS/predicted':>18s}")
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        for name, (t_path, table, printed, fig, offsets, missing, rows) in cases(workdir).items():
            if args.case and not any(c in name for c in args.case):
                continue
            log, truth = simulate(table, fig, int(rows * args.scale), offsets, rng, missing)
            q_ratio, r_ratio = model_check(table, log, truth)
            print(f"{name:30s} {len(log)} rows; simulation / table: diag Q "
                  + " ".join(f"{r:.3f}" for r in q_ratio) + "; R " + " ".join(f"{r:.3f}" for r in r_ratio))
            for prediction in (False, True):
                for r in compare(t_path, table, log, truth, printed, workdir, prediction):
                    print(f"{name:30s} {r['output']:9s} {r['state']:24s} {r['predicted']:10.4g} "
                          f"{r['std_column']:10.4g} {r['measured']:10.4g} {r['ratio']:6.3f} "
                          f"{r['ratio_column']:6.3f} {100 * r['mc_se_var']:9.2f}% "
                          f"{r['run_rms'] / r['run_predicted']:18.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
