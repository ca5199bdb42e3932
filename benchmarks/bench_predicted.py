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

``--random N [--seed S]``: N design files drawn from the class users write (:func:`random_spec`:
every named structure and the chain, noise over 2-3 decades, bias random walks, slow sensors at
whole and fractional rate ratios and their own ``offset_s``, gain form, output, ``wrap_angle``,
ports, crossovers), each with a log long enough for its slowest mode (:data:`TAUS`); a state
outside its Monte-Carlo band is flagged (:func:`flagged`).  ``--random 60 --seed 2``: 60 cases in
about 20 minutes on one core (``--scale 0.5``: 10).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from cfdesign.cli import main as cli
from cfdesign.gains import load_gains
from cfdesign.linear import wrap
from cfdesign.spec import example_path
from cfdesign.timing import nearest_tick

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
           discretize_hz: float | None = None, gain_form: str = "predictor") -> tuple:
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
                          "--gain-form", gain_form, "-o", str(table_path)])
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
    rate; position and velocity from an acceleration: the exact zero-order hold of the chain,
    ``x[k+1] = F x[k] + B u[k]``); each input sensor reads the input plus its own bias (mean over
    the tick of an exact random walk) plus white noise; a measurement reads the state it measures
    (its ``order``: 0 angle/position, 1 velocity) plus white noise, at its rate, from the offset
    given in ``offsets`` (ticks, not necessarily whole: the ticks nearest ``j * base / rate +
    offset``, rounded as the designer rounds, :func:`cfdesign.timing.nearest_tick`); ``missing``
    of the slow readings are left out at random.  An angle table (``wrap_angle``) turns at a
    steady 0.5 rad/s on top, so its readings and truth wrap many times; they are written wrapped
    to (-pi, pi].

    Parameters
    ----------
    table : GainTable
        The discrete table whose sensors the log follows.
    figures : dict
        ``{sensor: (per-sample std (u), bias density (u/sqrt(s)))}``.
    rows : int
        Base ticks.
    offsets : dict
        ``{measurement sensor: offset (ticks)}``; default 0.
    rng : numpy.random.Generator
    missing : float
        Fraction of the slow sensors' readings left out.

    Returns
    -------
    log : DataFrame
        ``time`` (s, jittered) and one column per sensor.
    truth : dict
        ``{state: true value per tick}`` (a bias state in the table's own sign).
    """
    T = table.sample_time_s
    k = np.arange(rows)
    inputs = sorted((s for s in table.sensors if s.role == "input"), key=lambda s: s.index)
    order = inputs[0].order
    accel = 0.3 * np.sin(2 * np.pi * 0.05 * k * T) + 0.1 * np.sin(2 * np.pi * 0.37 * k * T + 1.0)
    if table.wrap_angle:
        accel = accel + 0.5
    derivs = _zoh_chain(accel, order, T)
    biases = {s.name: _bias_steps(figures[s.name][1], T, rows, rng) for s in inputs}  # (at tick, mean over it)
    log = {"time": k * T + rng.uniform(-JITTER, JITTER, rows) * T}
    for s in inputs:
        log[s.name] = accel + biases[s.name][1] + figures[s.name][0] * rng.standard_normal(rows)
    for s in table.sensors:
        if s.role != "measurement":
            continue
        ratio = (1.0 / T) / s.rate_hz
        at = np.unique(nearest_tick(np.arange(0, rows / ratio + 1) * ratio + offsets.get(s.name, 0)).astype(int))
        at = at[at < rows]
        if missing and ratio > 1:
            at = at[rng.random(at.size) >= missing]
        col = np.full(rows, np.nan)
        col[at] = derivs[s.order][at] + figures[s.name][0] * rng.standard_normal(at.size)
        log[s.name] = wrap(col) if table.wrap_angle and s.order == 0 else col
    return pd.DataFrame(log), _truth(table, inputs, derivs, {name: b[0] for name, b in biases.items()})


def _zoh_chain(top: np.ndarray, order: int, T: float) -> list:
    """``[x, x', ..., x^(order)]`` per tick of a chain of integrators started at rest and driven by
    ``top`` held over each tick: ``x^(l)[k+1] = sum_m T^m / m! x^(l+m)[k]`` (exact)."""
    derivs = [None] * (order + 1)
    derivs[order] = top
    for level in range(order - 1, -1, -1):
        step = sum(T ** m / math.factorial(m) * derivs[level + m] for m in range(1, order - level + 1))
        derivs[level] = np.concatenate(([0.0], np.cumsum(step[:-1])))
    return derivs


def _truth(table, inputs: list, derivs: list, bias_ticks: dict) -> dict:
    """``{state: true value}``: the chain's states, and a bias state as the value that cancels the
    inputs' biases where they enter (``x_c = -sum_j b_j B[r, j] / F[r, c]``, row ``r`` the
    input's largest entry of ``B``); an angle wrapped in an angle table."""
    order = inputs[0].order
    truth = {}
    for i, state in enumerate(table.states):
        if i < order:
            truth[state] = wrap(derivs[i]) if table.wrap_angle and i == 0 else derivs[i]
            continue
        value = np.zeros_like(derivs[0])
        for s in inputs:
            r = int(np.argmax(np.abs(table.B[:, s.index])))
            value -= bias_ticks[s.name] * table.B[r, s.index] / table.F[r, i]
        truth[state] = value
    return truth


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
    if table.wrap_angle:
        w[:, 0] = wrap(w[:, 0])
    q_ratio = np.diag(np.cov(w.T).reshape(len(table.states), -1)) / np.diag(table.Q)
    r_ratio = []
    for s in sorted((s for s in table.sensors if s.role == "measurement"), key=lambda s: s.index):
        v = log[s.name].to_numpy() - x @ table.H[s.index]
        if table.wrap_angle and s.order == 0:
            v = wrap(v)
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
    output = "prior" if prediction else table.output  # --prediction: the prior, whatever the table's output
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


# ------------------------------------------------------------------ random design files (--random N)
#: what each structure's sensors measure: (inputs, measurements), names as the structure's ports
_PORTS = {"cf2": (["rate"], ["angle"]), "dckf3": (["gyro"], ["compass", "odometry"]),
          "position": (["accelerometer"], ["gps"]), "cf3": (["acceleration"], ["velocity", "position"]),
          "ckf3": (["acceleration"], ["velocity", "position"])}
_CFN = ["position", "velocity", "acceleration", "jerk"]
_MEASURES = {"rate": "rate", "angle": "angle", "gyro": "rate", "compass": "angle", "odometry": "angle",
             "accelerometer": "acceleration", "gps": "position", "acceleration": "acceleration",
             "velocity": "velocity", "position": "position", "jerk": "jerk"}
#: base rates (Hz) and slow-sensor ratios base/rate: whole and fractional (100/3: a 3 Hz GPS beside 100 Hz)
_BASES = (5.0, 10.0, 20.0, 50.0, 100.0)
_RATIOS = (1, 1, 2, 3, 4, 5, 10, 2.5, 10 / 3, 7.5, 100 / 3, 25 / 3)


def _log_uniform(rng, low: float, high: float) -> float:
    """A number between ``low`` and ``high`` spread evenly in its logarithm (3 significant digits)."""
    return float(f"{math.exp(rng.uniform(math.log(low), math.log(high))):.3g}")


def _layout(rng) -> tuple:
    """A structure and its options: ``(top-level TOML lines, inputs, measurements, bias state?,
    discrete?, sparse (single-rate) gains?)``; a chain's sensors as ``(name, measures)``."""
    kind = str(rng.choice(["cf2", "dckf3", "position", "cf3", "ckf3", "cfn", "chain"]))
    lines, *rest = _layout_of(kind, rng)
    return [f'structure = "{kind}"', *lines], *rest


def _layout_of(kind: str, rng) -> tuple:
    """:func:`_layout` of a structure ``kind``."""
    if kind == "cf2":
        order, discrete = int(rng.integers(1, 3)), bool(rng.random() < 0.7)
        return ([f"order = {order}", f"discrete = {str(discrete).lower()}"], *_named(kind), order == 2,
                discrete, False)
    if kind == "dckf3":
        return [], *_named(kind), True, True, False
    if kind == "position":
        discrete = bool(rng.random() < 0.8)
        return ([] if discrete else ["discrete = false"]), *_named(kind), True, discrete, False
    if kind in ("cf3", "ckf3"):
        discrete = kind == "cf3" and rng.random() < 0.6
        return (["discrete = true"] if discrete else []), *_named(kind), False, discrete, kind == "cf3"
    if kind == "cfn":
        bands, full = int(rng.integers(2, 5)), bool(rng.random() < 0.7)
        lines = [f"bands = {bands}", f"full = {str(full).lower()}", "discrete = true"]
        names = _CFN[:bands]
        return lines, [(names[-1], names[-1])], [(n, n) for n in names[-2::-1]], False, True, not full
    order = int(rng.integers(1, 4))
    quantity = ["angle", "rate"] if order == 1 else ["position", "velocity", "acceleration", "jerk"]
    inputs = [(f"{quantity[order]}_{c}", quantity[order]) for c in "ab"[: int(rng.integers(1, 3))]]
    levels = sorted(int(rng.integers(0, order)) for _ in range(int(rng.integers(1, 3))))
    measurements = [(f"{quantity[lvl]}_{j}", quantity[lvl]) for j, lvl in enumerate(levels)]
    bias = bool(rng.random() < 0.6)
    return [f"order = {order}", "discrete = true"], inputs, measurements, bias, True, False


def _named(kind: str) -> tuple:
    """``(inputs, measurements)`` of a named structure, as ``(port, measures)``."""
    ins, outs = _PORTS[kind]
    return [(n, _MEASURES[n]) for n in ins], [(n, _MEASURES[n]) for n in outs]


def random_spec(rng) -> tuple:
    """A design file of the class users write, drawn at random.

    A structure (``cf2`` order 1/2, continuous or discrete; ``dckf3``; ``position``; ``cf3``
    discrete, or continuous with a crossover; ``ckf3``; ``cfn`` of 2-4 bands, full or sparse;
    a ``chain`` of order 1-2 with one or two inputs), noise std or density spread over 2-3
    decades, bias random walks where the structure has a bias state, slow measurements at whole
    and fractional rate ratios with random ``offset_s`` (discrete, full gains), ``gain_form``,
    ``output``, ``wrap_angle`` for angle filters, a ``sample_time_s`` now and then, sensors
    renamed through ``port`` now and then.

    Returns
    -------
    text : str
        The TOML design file.
    discretize_hz : float or None
        The rate to run a continuous design at (``cfdesign discretize``), else None.
    """
    return _spec_text(rng, *_layout(rng))


def _spec_text(rng, lines, inputs, measurements, bias, discrete, sparse) -> tuple:
    """The TOML text of :func:`random_spec`'s draw."""
    base = float(rng.choice(_BASES))
    kind = lines[0].split('"')[1]
    multirate = discrete and not sparse and rng.random() < 0.7
    tuned = []  # crossover or partly fixed gains: single-rate designs only
    if not multirate and kind == "cf2" and rng.random() < 0.3:
        tuned.append(f"[crossover]\nhz = {_log_uniform(rng, 0.01, 0.05 * base)}"
                     + (f"\ndamping = {rng.uniform(0.4, 1.5):.2f}" if "order = 2" in lines else ""))
    elif not multirate and kind == "dckf3" and rng.random() < 0.3:
        tuned.append("[gains]\nk22 = 0.0")
    head = ['name = "random"', *lines]
    is_angle = all(m in ("angle", "rate") for _, m in inputs + measurements)
    if discrete:
        head.append(f'gain_form = "{rng.choice(["predictor", "filter"])}"')
        if rng.random() < 0.4:
            head.append(f'output = "{rng.choice(["posterior", "prior"])}"')
        if rng.random() < 0.2:
            head.append(f"sample_time_s = {1 / base!r}")
    if is_angle and rng.random() < 0.5:
        head.append("wrap_angle = true")
    body = []
    for name, measures in inputs:
        noise = _noise(rng, 1e-3, 3e-1, base)
        walk = (f', bias = {{ model = "random_walk", density = {_log_uniform(rng, 1e-5, 1e-2)} }}'
                if bias and (len(inputs) == 1 or rng.random() < 0.7) else "")
        body.append(_sensor(rng, name, measures, base, noise + walk))
    for name, measures in measurements:
        ratio = float(rng.choice(_RATIOS)) if multirate else 1.0
        rate = base / ratio
        extra = _noise(rng, 1e-3, 1.0, rate)
        if discrete and rng.random() < 0.6:
            extra += f", offset_s = {float(f'{rng.uniform(0, 1 / rate):.4g}') * 0.999:.4g}"
        body.append(_sensor(rng, name, measures, rate, extra))
    if sparse and not discrete:  # the sparse CF3 has no finite continuous optimum: by crossover
        f1 = _log_uniform(rng, 0.05, 0.1 * base)
        body.append(f"[crossover]\nhz = [{f1}, {float(f'{f1 * rng.uniform(3, 30):.3g}')}]")
    text = "\n".join(head) + "\n" + "\n".join(body + tuned) + "\n"
    return text, (None if discrete else base)


def _noise(rng, low: float, high: float, rate: float) -> str:
    """``noise = { std = ... }`` or the same figure as a density (u/sqrt(Hz)), spread over ``low``-``high``."""
    std = _log_uniform(rng, low, high)
    if rng.random() < 0.5:
        return f"noise = {{ std = {std} }}"
    return f"noise = {{ density = {float(f'{std / math.sqrt(rate):.3g}')} }}"


def _sensor(rng, port: str, measures: str, rate: float, figures: str) -> str:
    """A ``[sensors.NAME]`` table; now and then the sensor gets a name of its own and plays ``port``."""
    named = port in _CFN + list(_MEASURES) and rng.random() < 0.3 and "_" not in port
    name, line = (f"my_{port}", f'port = "{port}"\n') if named else (port, "")
    return (f"[sensors.{name}]\n{line}measures = \"{measures}\"\nrate_hz = {rate!r}\n"
            + "".join(f"{item.strip()}\n" for item in _split_top(figures)))


def _split_top(figures: str) -> list:
    """``'noise = {..}, bias = {..}, offset_s = x'`` into its top-level assignments."""
    items, depth, start = [], 0, 0
    for i, c in enumerate(figures):
        depth += c == "{"
        depth -= c == "}"
        if c == "," and depth == 0:
            items.append(figures[start:i])
            start = i + 1
    return [*items, figures[start:]]


def slowest_ticks(table) -> float:
    """The closed loop's slowest time constant (base ticks): ``-period / ln |rho|``, ``rho`` the
    largest multiplier of the product of the per-phase error transitions over a period."""
    n = table.F.shape[0]
    phi = np.eye(n)
    for K in table.K:
        step = table.F - K @ table.H if table.gain_form == "predictor" else table.F @ (np.eye(n) - K @ table.H)
        phi = step @ phi
    rho = float(np.max(np.abs(np.linalg.eigvals(phi))))
    return math.inf if rho >= 1 else table.period / -math.log(max(rho, 1e-300))


#: rows of a random case: this many slowest time constants (settled after SETTLE_TAUS of them),
#: within RANDOM_ROWS (times --scale); a case slower than MAX_TAU_SHARE of its rows is drawn again
TAUS, SETTLE_TAUS, RANDOM_ROWS, MAX_TAU_SHARE = 4000, 20, (20_000, 400_000), 1 / 400


def random_case(rng, index: int, workdir: Path, scale: float) -> tuple:
    """Draw design files until one designs and settles within the rows allowed; design it
    through the command line. Returns ``(text, made, rows, settle_s, redraws)`` with ``made`` as
    :func:`design` returns it (discretised at the sensors' rate when continuous)."""
    redraws = []
    while True:
        text, hz = random_spec(rng)
        form = str(rng.choice(["predictor", "filter"]))
        try:
            made = design(workdir, f"random{index}", spec_text=text, discretize_hz=hz, gain_form=form)
        except RuntimeError as exc:
            redraws.append(str(exc).split(": ", 1)[-1][:160])
            continue
        tau = slowest_ticks(made[1])
        low, high = (int(r * scale) for r in RANDOM_ROWS)
        rows = int(min(max(TAUS * tau, low), high))
        if tau > MAX_TAU_SHARE * rows:
            redraws.append(f"too slow to settle in {high} rows (time constant {tau:.0f} ticks)")
            continue
        settle_s = max(SETTLE_TAUS * tau, 1.0) * made[1].sample_time_s
        return text, made, rows, settle_s, redraws


#: a state is flagged when measured / predicted (or measured / std column) is further from 1 than
#: BAND_SE standard errors of the measured std plus BAND_BIAS, or the std column's RMS differs from the
#: prediction by more than COLUMN_RTOL (both are covariances: no Monte-Carlo error)
BAND_SE, BAND_BIAS, COLUMN_RTOL = 4.0, 0.03, 0.01


def flagged(row: dict) -> bool:
    """Whether a :func:`compare` row is outside its Monte-Carlo band (see :data:`BAND_SE`); the
    standard error of the std is half the variance's (``mc_se_var``)."""
    band = BAND_SE * row["mc_se_var"] / 2 + BAND_BIAS
    return (abs(row["ratio"] - 1) > band or abs(row["ratio_column"] - 1) > band
            or abs(row["std_column"] / row["predicted"] - 1) > COLUMN_RTOL)


def random_run(rng, index: int, workdir: Path, scale: float) -> tuple:
    """One random case end to end: draw and design (:func:`random_case`), simulate at the design
    file's offsets, run through ``cfdesign run --std`` (``--prediction`` three times in ten) and
    compare. Returns ``(text, table, rows, settle_s, redraws, compare rows)``."""
    text, (t_path, table, printed, fig), rows, settle_s, redraws = random_case(rng, index, workdir, scale)
    offsets = {name: offset / table.sample_time_s for name, offset in _offsets(workdir, index).items()}
    log, truth = simulate(table, fig, rows, offsets, rng)
    prediction = bool(rng.random() < 0.3)
    return text, table, rows, settle_s, redraws, compare(t_path, table, log, truth, printed, workdir, prediction,
                                                         settle_s)


def run_random(n: int, seed: int, scale: float) -> int:
    """``--random N``: N random design files (:func:`random_spec`), each designed, simulated and
    run through the command line, printed with its rows; a state outside its Monte-Carlo band is
    flagged (:func:`flagged`). Returns the number of flagged cases."""
    rng = np.random.default_rng(seed)
    bad, ratios = [], []
    print(f"{'case':8s} {'output':9s} {'state':24s} {'predicted':>10s} {'std col':>10s} {'measured':>10s} "
          f"{'ratio':>6s} {'r(col)':>6s} {'MC se':>6s} flag")
    with tempfile.TemporaryDirectory() as tmp:
        for index in range(n):
            text, table, rows, settle_s, redraws, found = random_run(rng, index, Path(tmp), scale)
            name = f"#{index}"
            print(f"{name} {table.structure}, T = {table.sample_time_s:g} s, period {table.period}, "
                  f"{table.gain_form}/{table.output}, {rows} rows, settle {settle_s:.3g} s"
                  + (f"; {len(redraws)} redrawn: {redraws}" if redraws else ""))
            print("    " + text.strip().replace("\n", "\n    "))
            for r in found:
                ratios.append(r["ratio"])
                print(f"{name:8s} {r['output']:9s} {r['state']:24s} {r['predicted']:10.4g} {r['std_column']:10.4g} "
                      f"{r['measured']:10.4g} {r['ratio']:6.3f} {r['ratio_column']:6.3f} "
                      f"{50 * r['mc_se_var']:5.1f}% " + ("FLAG" if flagged(r) else ""), flush=True)
            if any(flagged(r) for r in found):
                bad.append(name)
    q = np.quantile(ratios, [0, 0.5, 1])
    print(f"{n} cases, {len(ratios)} states: measured/predicted min {q[0]:.3f} median {q[1]:.3f} max {q[2]:.3f}; "
          f"flagged {len(bad)}: {' '.join(bad) or 'none'}")
    return len(bad)


def _offsets(workdir: Path, index: int) -> dict:
    """``{sensor: offset_s (s)}`` of random case ``index``'s design file."""
    from cfdesign.spec import load_spec

    return {x.name: x.offset_s for x in load_spec(workdir / f"random{index}.toml").sensors if x.offset_s}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", type=float, default=1.0, help="times each case's rows (ROWS)")
    p.add_argument("--case", nargs="*", help="substrings of the cases to run (default all)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--random", type=int, metavar="N", help="N random design files instead of the cases")
    args = p.parse_args(argv)
    if args.random:
        run_random(args.random, args.seed, args.scale)
        return 0
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
