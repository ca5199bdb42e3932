"""The ``cfdesign`` command.

User errors (unknown structure, bad gains, unreadable files) print one line on stderr and
exit with status 2; a proof or check that fails exits with 1; tracebacks mean a bug.  Stopped by
Ctrl-C, SIGTERM or SIGHUP, a command cleans up, prints one line and exits with 128 + the signal.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import os
import re
import signal
import sys
from pathlib import Path

from . import __version__
from .errors import CfdesignError, GainError, InternalError, OutputError, SpecError, install_hint
from .files import check_distinct, is_dir, write_files
from .signals import disposed

__all__ = ["main", "parse_gains"]


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage errors on one line, exit status 2."""

    def error(self, message):
        raise CfdesignError(f"{self.prog}: {message}")

    def _print_message(self, message, file=None):
        """Write ``--help`` and ``--version`` as argparse does, but let a failed write be told:
        argparse drops its OSError, and ``cfdesign --version > /dev/full`` exited 0 with nothing
        written (:func:`main` names a full disk under stdout on one line, exit 2)."""
        if message:
            (file or sys.stderr).write(message)


def _named(text: str) -> str:
    """argparse ``type`` of every file, folder, example and scheduler name: an empty one is refused.

    ``-o ""`` (a shell variable left unset) wrote nothing with exit 0 (design), wrote into the
    current folder (export c, run), designed the built-in example instead of the file
    (``design ""``), and ``verify --spec ""`` compared the table with nothing and passed."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r} is empty or blank: it names nothing (a shell variable left unset?)")
    return text


#: what ``-`` names where a command reads a file: standard input (``cat d.toml | cfdesign design -``)
STDIN = "/dev/stdin"


def _input(text: str) -> str:
    """argparse ``type`` of a file a command reads: :func:`_named`, and ``-`` is standard input,
    as for ``cfdesign run``'s logs (it was a file named '-': 'No such file or directory')."""
    return STDIN if _named(text) == "-" else text


def _output(text: str) -> str:
    """argparse ``type`` of every file a command writes: :func:`_named`, and not ``-``.

    ``-o -`` wrote a file named '-' in silence (design, export, discretize, noise, the plots):
    cfdesign writes files, not standard output."""
    if _named(text) == "-":
        raise argparse.ArgumentTypeError("'-' would be a file named '-': cfdesign writes files, not standard output; "
                                         "name one")
    return text


def parse_gains(text: str) -> dict:
    """Parse ``'k1=2,k2=1'`` (``cfdesign bode --gains``) into exact numbers; never evaluates the text.

    Parameters
    ----------
    text : str
        Comma-separated ``name=value`` items; values are decimal numbers or fractions.

    Returns
    -------
    dict
        ``{name: sympy number}``, exact (``0.5`` becomes ``1/2``).

    Raises
    ------
    GainError
        An item not of the form ``name=value``, a name given twice, or a value that is not a
        number.

    Examples
    --------
    >>> from cfdesign.cli import parse_gains
    >>> parse_gains("k1=2, k2=0.5")
    {'k1': 2, 'k2': 1/2}
    """
    from .symbolic.observer import parse_number

    values = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name.isidentifier():
            raise GainError(f"gain {item!r} is not of the form name=value")
        if name in values:
            raise GainError(f"gain {name!r} given twice")
        values[name] = parse_number(value, f"gain {name}")
    return values


def _structure(args):
    from .symbolic import structure

    return structure(args.structure, order=args.order, bands=args.bands, full=getattr(args, "full", None) or None,
                     discrete=getattr(args, "discrete", None) or None)


def _numeric(args):
    """The structure with every gain (and, if discrete, the sample time) given numbers."""
    from .symbolic.observer import parse_number

    obs = _structure(args)
    values = parse_gains(args.gains)
    if "T" in values:
        raise GainError("give the sample time with --sample-time, not as a gain")
    if args.sample_time is not None:
        if not obs.discrete:
            raise GainError(f"{obs.name} is continuous: --sample-time does not apply")
        values["T"] = parse_number(args.sample_time, "--sample-time")
        if values["T"] <= 0:
            raise GainError(f"--sample-time must be positive, got {args.sample_time}")
    elif obs.discrete:
        raise GainError(f"{obs.name} is discrete: give --sample-time T (seconds)")
    _within_design_limits(values)
    extra = sorted(set(values) - {p.name for p in obs.parameters})
    if extra:
        raise GainError(f"{obs.name} has no gain(s) {', '.join(extra)} (gains: {', '.join(obs.gains)})")
    missing = [g for g in obs.gains if g not in values]
    if missing:
        raise GainError(f"{obs.name} needs a value for gain(s) {', '.join(missing)}")
    return obs.with_gains(values)


def _within_design_limits(values):
    """Refuse a gain or sample time a design file would refuse: beyond them the frequency grid
    and the responses lose every digit (``--sample-time 1e-300`` drew a plot of nothing)."""
    from .spec import GAIN_RANGE, RATE_RANGE

    for name, value in values.items():
        what, span = ("--sample-time", RATE_RANGE) if name == "T" else (f"gain {name}", GAIN_RANGE)
        if value and not span[0] <= abs(float(value)) <= span[1]:  # as the file's number, a double
            raise GainError(f"{what}: {float(value):g} is outside the limits {span[0]:g} to {span[1]:g} of a design "
                            "file (check the units)")


def cmd_prove(args) -> int:
    proof = _structure(args).proof()
    if args.json:
        print(json.dumps(proof.to_dict(), indent=2))
    else:
        print(proof.text())
    return 0 if proof.holds else 1


def cmd_bode(args) -> int:
    from .plot import bode_plot

    obs = _numeric(args)
    for path in write_files({args.output: _figure_bytes(bode_plot(obs, hz=args.hz), args.output)}):
        print(f"wrote {path}")
    return 0


def cmd_design(args) -> int:
    from .designer import design
    from .spec import example_path, load_spec

    if args.spec and args.example:
        raise CfdesignError("give a design file or --example, not both")
    if args.hz and not args.bode:  # (ignored, as export's C options were: see cmd_export)
        raise CfdesignError("cfdesign design: --hz is the frequency axis of the --bode plot; give --bode FILE.png too")
    path = args.spec or example_path(args.example or "robot-heading")
    check_distinct({"the design file": path, "-o": args.output, "--bode": args.bode})
    spec = load_spec(path)
    try:
        table = design(spec)
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None
    outputs = {}  # everything is computed before anything is written, then written all or nothing
    if args.output:
        outputs[args.output] = table.to_json()
    if args.bode:
        outputs[args.bode] = _bode_png(spec, table, args.bode, getattr(args, "hz", False))
    print(_summary(table))
    for path in write_files(outputs):
        print(f"wrote {path}")
    return 0


def _bode_png(spec, table, target, hz=False) -> bytes:
    """The Bode plot of a designed filter, rendered in memory: the bands of a single-rate
    filter; for a multirate one, its gains per phase and the lifted system at the period rate
    (:meth:`GainTable.bode <cfdesign.gains.GainTable.bode>`)."""
    from .designer import designed_observer
    from .plot import bode_plot

    if table.period != 1:
        return _figure_bytes(table.bode(hz=hz), target)
    return _figure_bytes(bode_plot(designed_observer(spec, table), hz=hz), target)


def _summary(table) -> str:
    kind = (f"discrete, T = {table.sample_time_s:g} s, {table.gain_form} gains"
            if table.domain == "z" else "continuous")
    lines = [f"{table.name}: {table.structure} ({kind})"]
    if table.period > 1:
        lines.append(f"  multirate: period {table.period} steps; measurements per phase: "
                     + ", ".join(f"{k}:{'+'.join(table.schedule.names(k))}" for k in range(table.period)
                                 if table.schedule.rows(k)))
        for k, K in enumerate(table.K):  # each state's gains on the phase's readings, named
            rows = table.schedule.rows(k)
            if rows:
                names = [table.measurements[i].name for i in rows]
                lines.append(f"  K[{k}]: " + "; ".join(
                    f"{state} <- " + ", ".join(f"{name} {K[r, i]:.6g}" for name, i in zip(names, rows, strict=True))
                    for r, state in enumerate(table.states)))
    elif table.gains:
        lines.append("  gains: " + ", ".join(f"{name} = {table.gains[name]:.6g}" for name in sorted(table.gains)))
    else:  # a table without named gains (discretised, recomputed): the matrix, a row per state
        rows = ", ".join("[" + ", ".join(f"{v:.6g}" for v in row) + "]" for row in table.K[0].tolist())
        lines.append(f"  K = [{rows}] (rows: {', '.join(table.states)})")
    of = f"of {table.states[0]}{_unit(table)}"
    if table.domain == "z":
        other = "prior" if table.output == "posterior" else "posterior"
        names = {"posterior": "estimate after each step's readings (posterior)",
                 "prior": "one-step prediction (prior)"}
        lines.append(f"  predicted steady-state std {of}, {names[table.output]}: {_std_text(table, table.output)}  "
                     "<- the default output")
        from .linear import has_posterior

        alone = other == "posterior" and not has_posterior(table.F, table.gain_form)  # (its P_filtered is P)
        lines.append(f"  predicted steady-state std {of}, {names[other]}: " + (
            "none (F is singular or ill-conditioned: predictor gains give no update gain)" if alone
            else _std_text(table, other)))
    else:
        lines.append(f"  predicted steady-state std {of}: {table.predicted_std:.6g}")
    c = table.checks
    roots = c.get("poles", c.get("monodromy_multipliers"))
    what = "poles" if "poles" in c else "monodromy multipliers"
    lines.append(f"  {what}: " + ", ".join(f"{complex(*p):.6g}" for p in roots))
    how = "exact proof" if c.get("exact_proof", True) else "structural, checked numerically"  # (discretised)
    lines.append(f"  complementary ({how}): {c['complementary']}; stable: {c['stable']}")
    solver = table.provenance["solver"]
    if "crossover_hz" in solver:
        lines.append("  crossovers: " + ", ".join(f"{a}/{b} at {f:g} Hz (magnitude ratio {r:.6f})"
                                                  for a, b, f, r in solver["crossovers"]))
    if solver.get("kalman_predicted_variance") is not None:
        which = f" ({table.output} output)" if table.domain == "z" else ""
        mine, best = solver["predicted_variance"] ** 0.5, solver["kalman_predicted_variance"] ** 0.5
        lines.append(f"  predicted std of these gains{which}: {mine:.6g}; Kalman optimum for the same sensors{which}: "
                     f"{best:.6g}")
    residual = f", residual {solver['residual']:.2e}" if "residual" in solver else ""
    lines.append(f"  solver: {solver['method']}{residual}")
    # every line printable and a line alone: a design file's name with a newline printed a line of
    # its own ("PASS all checks"), with an escape sequence it cleared the terminal
    return "\n".join(_one_line(line, 2000) for line in lines)


def _unit(table) -> str:
    """`` (rad)`` or `` (m)`` after the name of state 0 when its unit is known."""
    unit = table.state_units()[0]
    return f" ({unit})" if unit else ""


def _std_text(table, output: str) -> str:
    """The predicted std of state 0 for ``output``; a multirate table's worst phase and its RMS
    over the period (what a log's error averages to), both named."""
    worst = table.predicted_std_of(output)
    if table.period == 1:
        return f"{worst:.6g}"
    covs = table.P_filtered if output == "posterior" else table.P
    rms = (sum(float(c[0, 0]) for c in covs) / len(covs)) ** 0.5
    return f"{worst:.6g} at the worst phase, {rms:.6g} RMS over the period"


def cmd_export(args) -> int:
    from .gains import load_gains

    c_only = [flag for flag, given in (("--precision", args.precision), ("--prefix", args.prefix),
                                       ("--prediction", args.prediction)) if given]
    if args.format != "c" and c_only:  # (ignored, they left a JSON or CSV table without what was asked)
        verb = "applies" if len(c_only) == 1 else "apply"
        raise CfdesignError(f"cfdesign export: {', '.join(c_only)} only {verb} to --format c, not {args.format}")
    check_distinct({"the gain table": args.table, "-o": args.output})
    table = load_gains(args.table)
    if args.format == "json":
        written = [table.save(args.output)]
    elif args.format == "csv":
        from .export import write_gain_csv

        written = [write_gain_csv(table, args.output)]
    else:
        from .codegen import write_c

        written = write_c(table, args.output, prefix=args.prefix, precision=args.precision or "double",
                          output="prior" if args.prediction else None)
    for path in written:
        print(f"wrote {path}")
    return 0


def cmd_verify(args) -> int:
    from .gains import load_gains
    from .spec import load_spec
    from .verify import verify_table

    if args.table == args.spec == STDIN:
        raise CfdesignError("cfdesign verify: the gain table and --spec cannot both be standard input ('-')")
    table = load_gains(args.table)
    spec = load_spec(args.spec) if args.spec else None
    checks = verify_table(table, spec, args.rtol)
    for check in checks:
        print(_one_line(check.line(), 2000))
    failed = [c for c in checks if not c.ok]
    print(f"{_one_line(repr(table.name))}: {len(checks) - len(failed)} of {len(checks)} checks hold")
    return 1 if failed else 0


def cmd_run(args) -> int:
    from .gains import load_gains
    from .logs import INTERNAL, run_log, run_logs

    check_distinct({"the gain table": args.table, "-o": args.output, "--plot": args.plot})
    stdin = ["-" in args.data, args.table == STDIN, STDIN in (args.join or [])]
    if sum(stdin) > 1 or (args.join or []).count(STDIN) > 1:
        raise CfdesignError("cfdesign run: standard input ('-') can be one file only (the gain table, a log or a "
                            "--join file)")
    table = load_gains(args.table)
    logs, fleet = _log_paths(args.data)
    options = {"time": args.time, "time_unit": args.time_unit, "mapping": _pairs(args.map, "--map", "SENSOR=COLUMN"),
               "reference": args.reference or None, "std": args.std, "prediction": args.prediction}
    if args.workers is not None and args.workers < 1:
        raise CfdesignError(f"--workers must be a positive number of processes, got {args.workers}")
    # a folder (named so, or existing) or logs named as a folder or a glob run as a fleet, however many match
    folder = is_dir(args.output) or args.output.endswith(("/", os.sep))
    if fleet or args.workers or args.scheduler or folder:
        if args.join:
            raise CfdesignError("--join merges files into one log; several logs (a folder or a glob of logs, "
                                "--workers or --scheduler) are not joined: run each log with its --join files")
        if args.plot:
            raise CfdesignError("--plot draws one log; run the logs one by one to plot them")
        if not folder and Path(args.output).suffix.lower() in (".csv", ".parquet", ".pq"):
            raise CfdesignError(f"-o {args.output} names an estimates file, but several logs (a folder or a glob of "
                                "logs, --workers or --scheduler) write a folder of them and summary.csv: name a "
                                "folder (out/), or run one log without --workers and --scheduler")
        suffix = ".parquet" if args.format == "parquet" else ".csv"
        rows = run_logs(table, logs, args.output, workers=args.workers, scheduler=args.scheduler, suffix=suffix,
                        **options)
        failed = [r for r in rows if "error" in r]
        for r in failed:
            named = r["error"] if r["error"].startswith(r["log"]) else f"{r['log']}: {r['error']}"
            print(f"cfdesign: {named}", file=sys.stderr)
        noted = sum(1 for r in rows if r.get("notes"))
        print(f"wrote {len(rows) - len(failed)} estimate files and {Path(args.output) / 'summary.csv'}"
              + (f" ({noted} log{'s' if noted > 1 else ''} with notes: its notes column)" if noted else ""))
        return 3 if any(r["error"].startswith(INTERNAL) for r in failed) else 2 if failed else 0
    result = run_log(table, logs[0], output=args.output, plot=args.plot, progress=True, join=args.join, **options)
    for note in result.notes:
        print(f"cfdesign: {note}", file=sys.stderr)
    if result.without_gain:
        detail = "; ".join(f"{UNUSED.get(kind, kind)} ({kind}): " + ", ".join(f"{k} {v}" for k, v in per.items())
                           for kind, per in result.unused.items())
        print(f"cfdesign: {result.without_gain} readings were not used ({detail})", file=sys.stderr)
    units = dict(zip(table.states, table.state_units(), strict=True))
    for state, rms in result.rms.items():
        if rms != rms:  # NaN: every reference reading was empty, inf or beyond the reading limit
            print(f"RMS error of {state}: none (no row has a finite reference to compare with)")
            continue
        print(_rms_line(state, result, f" {units[state]}" if units.get(state) else ""))
    print(f"wrote {args.output} ({result.samples} samples)" + (f" and {args.plot}" if args.plot else ""))
    return 0


def _pauses_text(result) -> str:
    """What the settled rows leave out besides the log's start-up: the start-up after each restart
    (a pause after which the first state started again), not after a pause carried over."""
    restarts, carried = result.restarts, result.pauses - result.restarts
    text = ""
    if restarts:
        text = (", and as long after the restart after the pause" if result.pauses == 1 else
                f", and as long after each restart ({restarts} of {result.pauses} pauses)")
    if carried:
        text += ("; after the pause, carried over, every row counts" if carried == 1 and not restarts else
                 f"; after {carried} pause{'s' * (carried > 1)} carried over, every row counts")
    return text


def _rms_line(state, result, unit="") -> str:
    """``RMS error of STATE: X over all rows; Y after the start-up (first S s); predicted Z``: the
    error over every row, over the rows after the start-up (the settled filter), and the predicted
    standard deviation the settled figure should come to (``LogResult.predicted_std``)."""
    settled = result.rms_settled.get(state, float("nan"))
    startup = result.startup_s
    if settled == settled:
        after = f"{settled:.6g}{unit} after the start-up (first {startup:.3g} s{_pauses_text(result)})"
    elif startup == float("inf"):
        after = "none after the start-up (the table's error does not die away: a state no sensor corrects)"
    elif result.settled_samples:
        after = f"none after the start-up (first {startup:.3g} s): no row after it has a finite reference"
    else:
        after = f"none after the start-up (the log ends within it: its first {startup:.3g} s)"
    predicted = result.predicted_std.get(state, float("nan"))
    return (f"RMS error of {state}: {result.rms[state]:.6g}{unit} over all rows; {after}"
            + (f"; predicted {predicted:.6g}{unit}" if predicted == predicted else ""))


#: why readings were not used, by their key in ``LogResult.unused``: the line ``cfdesign run`` prints says it in words
UNUSED = {"rejected": "inf or beyond the reading limit", "unscheduled": "at a phase without a gain",
          "same_tick": "a second reading of a sensor on one base tick, the first used",
          "before_start": "more than half a tick before the first row where the inputs read"}

#: the logs a folder given to ``cfdesign run`` holds (a compressed CSV as well)
LOG_SUFFIXES = (".csv", ".parquet", ".pq", ".csv.gz", ".csv.bz2", ".csv.xz", ".csv.zip")


def _log_paths(items) -> tuple:
    """Files named, globbed or in named directories (CSV and Parquet), in a stable order, and
    whether they are a fleet (several files, or a directory or a glob, whatever it matched)."""
    import glob

    out = []
    fleet = len(items) > 1
    for item in items:
        p = Path("/dev/stdin" if item == "-" else item)  # '-': the log on standard input (copied: logs.read._spooled)
        if is_dir(p):
            found = sorted(q for q in p.iterdir() if "".join(q.suffixes[-2:]).lower() in LOG_SUFFIXES
                           or q.suffix.lower() in LOG_SUFFIXES)
            fleet = True
        elif any(c in item for c in "*?["):
            found = sorted(Path(q) for q in glob.glob(item))
            fleet = True
        else:
            found = [p]
        if not found:
            raise CfdesignError(f"no log files in {item}")
        out += found
    return out, fleet


def _pairs(items, option, form) -> dict:
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise CfdesignError(f"{option} {item!r} is not of the form {form}")
        if re.search(r",\s*[^,=\s]+\s*=", value):  # 'a=x,b=y': one column named 'x,b=y' was looked for
            raise CfdesignError(f"{option} {item!r}: one {form} per {option}; repeat it for each "
                                f"({option} {key.strip()}={value.split(',')[0].strip()} {option} ...)")
        if key.strip() in out:  # the last one winning in silence ran a sensor on the column not meant
            raise CfdesignError(f"{option} {key.strip()} is given twice ({out[key.strip()]!r} and {value.strip()!r})")
        out[key.strip()] = value.strip()
    return out


def cmd_noise(args) -> int:
    from .allan import adev_plot, identify_noise, noise_toml, read_log_columns

    if args.rate_hz is not None and args.time is not None:
        raise CfdesignError("cfdesign noise: give the sample rate by --rate-hz R or by --time COLUMN, not both")
    from .spec import RATE_RANGE

    if args.rate_hz is not None and not RATE_RANGE[0] <= args.rate_hz <= RATE_RANGE[1]:
        raise CfdesignError(f"cfdesign noise: --rate-hz must be a positive number of hertz from {RATE_RANGE[0]:g} "
                            f"to {RATE_RANGE[1]:g}, got {args.rate_hz:g}")
    check_distinct({"the log": args.log, "-o": args.output, "--plot": args.plot})
    columns = [c.strip() for item in args.column for c in item.split(",") if c.strip()]
    if not columns:
        raise CfdesignError("cfdesign noise: name at least one --column")
    twice = next((c for i, c in enumerate(columns) if c in columns[:i]), None)
    if twice is not None:
        raise CfdesignError(f"cfdesign noise: --column names {twice!r} twice")
    if args.time_unit is not None and args.rate_hz is not None:
        raise CfdesignError("cfdesign noise: --time-unit is the unit of the time column; --rate-hz reads none")
    units = [u.strip() for u in args.unit.split(",")]
    if len(units) not in (1, len(columns)) or not all(units):
        raise CfdesignError(f"cfdesign noise: --unit takes one unit, or one per --column ({len(columns)}), "
                            f"comma-separated; got {args.unit!r}")
    units = units * len(columns) if len(units) == 1 else units
    rate, data = read_log_columns(args.log, columns, args.time, args.time_unit, find_time=args.rate_hz is None)
    if rate is None and args.rate_hz is None:
        raise CfdesignError(f"cfdesign noise: {args.log} has no time column ('time', 't' or 'timestamp', in any case "
                            "or with a unit): give the sample rate, --rate-hz R, or the column, --time COLUMN")
    rate = args.rate_hz if rate is None else rate
    fits = [identify_noise(data[c], rate, name=c) for c in columns]
    for fit, unit in zip(fits, units, strict=True):
        print(fit.summary(unit))
    outputs = {}
    if args.output:
        outputs[args.output] = noise_toml(fits, source=str(args.log), unit=units)
    if args.plot:
        outputs[args.plot] = _figure_bytes(adev_plot(fits, unit=units), args.plot)
    for path in write_files(outputs):
        print(f"wrote {path}")
    return 0


def cmd_discretize(args) -> int:
    from .discretize import discretize_table
    from .gains import load_gains

    check_distinct({"the gain table": args.table, "-o": args.output})
    continuous = load_gains(args.table)
    table = discretize_table(continuous, args.rate_hz, args.gain_form)
    print(_summary(table))
    described = max(s.rate_hz for s in continuous.sensors)  # one rate: discretize_table refuses several
    if abs(described - table.sensors[0].rate_hz) > 1e-9 * described:
        f = table.sensors[0].rate_hz
        print(f"cfdesign discretize: note: the sensors were described at {described:g} Hz; at {f:g} Hz the predicted "
              f"error takes every measurement as read at every step with the variance of its noise density at "
              f"{f:g} Hz (PSD x {f:g}: the mean of a {described:g} Hz sensor over each step, not its readings taken "
              f"as they come); for the error of the readings you will have, give each measurement's rate_hz = "
              f"{f:g} and noise = {{ std = ... }} of those readings in the design file and design again",
              file=sys.stderr)
    for path in write_files({args.output: table.to_json()}):
        print(f"wrote {path}")
    return 0


def _figure_bytes(fig, target) -> bytes:
    from .plot import figure_bytes

    return figure_bytes(fig, target)


def _add_structure(p):
    p.add_argument("structure", help="cf2, cf3, ckf3, dckf3, cfn or position")
    p.add_argument("--order", type=int, help="cf2 only: 1 (angle + rate) or 2 (with gyro-bias state)")
    p.add_argument("--bands", type=int, help="cfn only: number of bands/sensors n (2..7)")
    p.add_argument("--full", action="store_true", help="cfn only: a full gain matrix (cfn --bands 3 --full is CKF3)")
    p.add_argument("--discrete", action="store_true",
                   help="cf2, cf3, cfn: the ZOH model in z (dckf3 and position are discrete)")


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The ``cfdesign`` parser; the papers' options are loaded only for ``reproduce``."""
    parser = _Parser(prog="cfdesign", description="Design and verify complementary filters.")
    parser.add_argument("--version", action="version", version=f"cfdesign {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("prove", help="derive the bands of a structure and prove they sum to 1")
    _add_structure(p)
    p.add_argument("--json", action="store_true", help="print variable, bands, sum and holds as JSON")
    p.set_defaults(run=cmd_prove)

    p = sub.add_parser("bode", help="Bode plot of every band and of their sum")
    _add_structure(p)
    p.add_argument("--gains", required=True, help="gain values, named as cfdesign prove prints them "
                                                  "(cf3: k1=2,k2=1; continuous gains in SI units, 1/s, 1/s^2, ...)")
    p.add_argument("--sample-time", help="sample time T in seconds (discrete structures)")
    p.add_argument("-o", "--output", required=True, type=_output, help="PNG (or PDF/SVG) file to write")
    p.add_argument("--hz", action="store_true", help="frequency axis in Hz instead of rad/s")
    p.set_defaults(run=cmd_bode)

    p = sub.add_parser("design", help="optimal gains from a TOML design file (default: built-in example)")
    p.add_argument("spec", nargs="?", type=_input,
                   help="design file (TOML), - for standard input; omitted: the built-in example")
    p.add_argument("--example", type=_named,
                   help="built-in example instead of a file: robot-heading (the default), dckf3, cf3, "
                   "ckf3, position, tilt")
    p.add_argument("-o", "--output", type=_output, help="write the gain table (JSON) here")
    p.add_argument("--bode", metavar="FILE.png", type=_output,
                   help="also write the Bode plot of the designed filter (multirate: "
                   "its gains per phase and the lifted system at the period rate)")
    p.add_argument("--hz", action="store_true", help="Bode plot: frequency axis in Hz instead of rad/s")
    p.set_defaults(run=cmd_design)

    p = sub.add_parser("export", help="write a gain table as JSON, CSV or a C99 filter")
    p.add_argument("table", type=_input, help="gain table (JSON) from cfdesign design (- for standard input)")
    p.add_argument("--format", choices=["json", "csv", "c"], required=True,
                   help="json: the gain table; csv: the gains per phase; c: a C99 filter (three files in a directory)")
    p.add_argument("-o", "--output", required=True, type=_output, help="file (json, csv) or directory (c)")
    p.add_argument("--precision", choices=["double", "float"],
                   help="C only: real type (default double)")
    p.add_argument("--prefix", help="C only: identifier prefix of the generated code (default: the table's "
                                    "structure, e.g. dckf3_step)")
    p.add_argument("--prediction", action="store_true",
                   help="C only: the step returns the one-step prediction instead of the table's output "
                        "(by default the estimate after each step's readings)")
    p.set_defaults(run=cmd_export)

    p = sub.add_parser("verify", help="check a gain table: bands sum to 1, stable, (with --spec) gains as designed")
    p.add_argument("table", type=_input, help="gain table (JSON), - for standard input")
    p.add_argument("--spec", type=_input, help="design file the table should come from (- for standard input)")
    p.add_argument("--rtol", type=float, default=1e-9,
                   help="relative tolerance of the comparison with --spec (default 1e-9)")
    p.set_defaults(run=cmd_verify)

    p = sub.add_parser("run", help="run a gain table on logs (CSV or Parquet) of timestamped sensor readings",
                       description="Each row is placed on the table's base tick by its time (nearest tick); slow "
                                   "sensors' columns are empty between readings; the schedule locks to when they "
                                   "arrive.  Readings not used are reported on stderr.")
    p.add_argument("table", type=_input, help="gain table (JSON), - for standard input")
    p.add_argument("data", nargs="+", type=_named,
                   help="log file(s), a directory or a glob; one column per sensor (named as in "
                                           "the table, or --map), a time column, any others (passed through)")
    p.add_argument("-o", "--output", required=True, type=_output,
                   help="estimates file (.csv or .parquet); a directory (created "
                                                         "if missing; a name ending in /) for several logs, a "
                                                         "directory or a glob of logs, with summary.csv")
    p.add_argument("--time", metavar="COLUMN", help="time column in seconds or ISO 8601 dates (default: 'time', "
                                                    "'t' or 'timestamp' in any case, or with a unit: 'time [ms]', "
                                                    "'time_ms'; without one, each row is one base tick)")
    p.add_argument("--time-unit", choices=["s", "ms", "us", "ns"],
                   help="unit of a numeric time column, over the one its name gives (default: that one, "
                        "'time [ms]', else s; ns for the %%time of a ROS rostopic echo -p export)")
    p.add_argument("--join", action="append", metavar="FILE", type=_input,
                   help="a file of the same log's other sensors (one file per sensor or topic: PX4's ulog2csv, "
                        "ROS's rostopic echo -p), its rows merged in by time, each file with its own time column and "
                        "unit (--time-unit: of files whose time's name gives none); only the columns the run uses are "
                        "taken; read whole, so join the slow sensors to the fast one's log (repeatable; one log, not "
                        "several)")
    p.add_argument("--map", action="append", metavar="SENSOR=COLUMN", help="the log column of a sensor (repeatable)")
    p.add_argument("--reference", action="append", metavar="[STATE=]COLUMN",
                   help="a true value to compare with: prints the RMS error over all rows and after the filter's "
                        "start-up, beside the predicted std (repeatable)")
    p.add_argument("--std", action="store_true", help="also write <state>_std, the predicted standard deviations")
    p.add_argument("--plot", metavar="FILE.png", type=_output,
                   help="draw the estimates (against the references, with the "
                                                     "predicted +-2 sigma band)")
    p.add_argument("--prediction", action="store_true",
                   help="write the one-step prediction instead of the table's output (by default the estimate "
                        "after each step's readings)")
    dask = p.add_mutually_exclusive_group()
    dask.add_argument("--workers", type=int, help="several logs: Dask worker processes (default: the CPUs)")
    dask.add_argument("--scheduler", metavar="ADDRESS", type=_named, help="several logs: an existing Dask scheduler")
    p.add_argument("--format", choices=["csv", "parquet"], default="csv", help="several logs: estimate file format")
    p.set_defaults(run=cmd_run)

    p = sub.add_parser("noise", help="noise densities and bias random walk of a static log (Allan deviation)")
    p.add_argument("log", type=_input, help="CSV (with a header row) or Parquet log, sensor at rest; - for "
                                            "standard input")
    p.add_argument("--column", action="append", required=True,
                   help="column to analyse (repeat, or comma-separate, for several axes)")
    p.add_argument("--rate-hz", type=float, help="sample rate of the log (Hz; default: from its time column)")
    p.add_argument("--time", metavar="COLUMN", help="time column (seconds or ISO 8601 dates) to take the rate from "
                   "(default: 'time', 't' or 'timestamp' in any case, or with a unit, as cfdesign run finds it)")
    p.add_argument("--time-unit", choices=["s", "ms", "us", "ns"],
                   help="unit of a numeric --time column, over the one its name gives (default: that one, 'time [ms]', "
                        "else s)")
    p.add_argument("-o", "--output", type=_output, help="write the design-file entries (TOML) here")
    p.add_argument("--plot", metavar="FILE.png", type=_output,
                   help="write the Allan deviation with the fitted asymptotes")
    p.add_argument("--unit", default="u", help="unit of the readings (e.g. rad/s, deg/s), or one per column, "
                   "comma-separated (rad/s,rad/s,rad/s,m/s^2); -o writes a figure in a known non-SI unit "
                   "with it (\"0.005 deg/s/sqrt(Hz)\"), which the design file converts")
    p.set_defaults(run=cmd_noise)

    p = sub.add_parser("discretize", help="run a continuous gain table at a sample rate (ZOH model, held innovation)")
    p.add_argument("table", type=_input, help="continuous gain table (JSON), - for standard input")
    p.add_argument("--rate-hz", type=float, required=True, help="sample rate (Hz) of every sensor")
    p.add_argument("--gain-form", choices=["predictor", "filter"], default="predictor",
                   help="gain form of the discrete table (default predictor)")
    p.add_argument("-o", "--output", required=True, type=_output, help="discrete gain table (JSON) to write")
    p.set_defaults(run=cmd_discretize)

    from .reproduce import add_parser as add_reproduce

    words = [a for a in (argv or []) if not a.startswith("-")]
    add_reproduce(sub, load=argv is None or (bool(words) and words[0] == "reproduce"))
    return parser


def main(argv=None) -> int:
    """Run the ``cfdesign`` command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 success, 1 a proof or check failed, 2 a user error (one line on
        stderr), 3 an internal error (one line asking for a report; ``--debug`` shows the
        traceback), 128 + N stopped by signal N, its files cleaned up (130 Ctrl-C; 143 SIGTERM
        and 129 SIGHUP, which raise as Ctrl-C does while the command runs).

    Examples
    --------
    >>> from cfdesign.cli import main
    >>> main(["prove", "cf2"])  # doctest: +ELLIPSIS
    Complementarity proof for cf2 (order 1) (variable s)
    ...
    0
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    stdout, sys.stdout = sys.stdout, _PipeSafe(sys.stdout)  # a closed pipe must not stop the writes
    try:
        with _stop_as_ctrl_c():
            return _main(argv, "--debug" in argv)
    finally:
        sys.stdout = stdout


def console() -> int:
    """The ``cfdesign`` command (and ``python -m cfdesign``): :func:`main` in a process of its own.

    Such a process may go without what only a library user's process can need: jsonschema is
    imported without its optional IRI format checker, ``rfc3987_syntax`` (installed with Jupyter),
    which compiles some forty grammars at import: 1 s of every command that reads a gain table.
    No table's schema has a ``format`` keyword, so its checks are the same.

    Returns
    -------
    int
        The exit status, as :func:`main`.
    """
    sys.modules.setdefault("rfc3987_syntax", None)  # None: its import fails, and jsonschema goes without it
    return main()


def _main(argv, debug) -> int:
    try:
        nul = next((i for i, a in enumerate(argv) if "\x00" in a), None)
        if nul is not None:  # no file name or value holds one (a shell cannot pass one; main() can)
            raise CfdesignError(f"argument {nul + 1} ({_one_line(argv[nul], 60)!r}) contains a NUL character")
        try:
            args = build_parser(argv).parse_args(argv)
        except SystemExit:  # --help, --version or a usage line printed: a full disk under '> file' is told too
            sys.stdout.flush()
            raise
        with _quiet_arithmetic(debug), _warnings_on_one_line(debug):
            status = args.run(args)
            sys.stdout.flush()  # a full disk under '> file' is told here, not at the interpreter's exit
            return status
    except CfdesignError as exc:
        _error(exc)
        return exc.exit_code
    except BrokenPipeError:  # the reader went away (cfdesign design | head): not an error of ours
        _quiet_stdout()
        return 0
    except OSError as exc:
        if exc.errno not in _FULL or exc.filename is not None:
            return _internal(exc, debug)
        _quiet_stdout()  # what stdout still holds cannot be written either
        _error(OutputError(f"cannot write to standard output: {exc.strerror}"))
        return OutputError.exit_code
    except KeyboardInterrupt as exc:  # Ctrl-C, or a signal of _STOPS: the files were cleaned up on the way here
        return _interrupted(getattr(exc, "signum", signal.SIGINT))
    except Exception as exc:  # noqa: BLE001 - a bug: one line, the traceback only on request
        return _internal(exc, debug)


class _Stopped(KeyboardInterrupt):
    """A signal of :data:`_STOPS` received: raised as Ctrl-C's KeyboardInterrupt is, so that every
    ``finally`` and ``with`` on the way out runs (temporary files removed, a Dask cluster closed)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


#: the signals that stop a command as Ctrl-C does: SIGTERM (timeout, kill, docker stop, systemd,
#: Slurm) and SIGHUP (its terminal closed); by default Python died of them at once, ``finally``
#: blocks unrun, leaving ``.NAME.XXXX.tmp`` beside the output and Dask's semaphore warning
_STOPS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


def _stop_as_ctrl_c():
    """SIGTERM and SIGHUP raise :class:`_Stopped` while the command runs; the previous handlers are
    put back after it (:func:`main` called in a process of its own or another's).  Installed by the
    command alone, never at import: a library user's process keeps its own handlers.  A signal the
    process ignores stays ignored (``nohup cfdesign run ...`` outlives its terminal).
    """
    def stop(signum, frame):
        raise _Stopped(signum)

    return disposed(_STOPS, stop, only_default=True)


def _interrupted(signum: int) -> int:
    """The one line of a command stopped by signal ``signum``; its exit status, 128 + ``signum`` as a
    shell reports a command killed by it (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP)."""
    name = "" if signum == signal.SIGINT else f" ({signal.Signals(signum).name})"
    try:
        print(f"cfdesign: interrupted{name}", file=sys.stderr)
    except (OSError, ValueError):  # its terminal is gone (SIGHUP): there is no one to tell
        pass
    return 128 + signum


#: the errors of a write to a full disk, over a quota or beyond the largest file (stdout redirected to one)
_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


def _internal(exc, debug) -> int:
    """A bug (one line, the traceback only with ``--debug``), or a package the installation lacks."""
    if debug:
        raise exc
    missing = _missing_dependency(exc)
    if missing:  # not a bug: the installation lacks a package this command imports
        print(f"cfdesign: error: this command needs {missing}, which is not installed: "
              f"{install_hint(missing) or 'pip install ' + missing}", file=sys.stderr)
        return CfdesignError.exit_code
    print(f"cfdesign: internal error ({type(exc).__name__}: {_one_line(str(exc))}); please report it with "
          "the command you ran, and rerun with --debug for the traceback", file=sys.stderr)
    return InternalError.exit_code


def _missing_dependency(exc):
    """The top-level name of the package another than cfdesign that ``exc`` failed to import, or None."""
    name = getattr(exc, "name", None) if isinstance(exc, ModuleNotFoundError) else None
    top = (name or "").split(".")[0]
    return top if top and top != "cfdesign" else None


def _quiet_arithmetic(debug):
    """numpy's overflow and invalid-value warnings off: what they would say, a check or a named error
    says on one line (``--debug`` shows them)."""
    if debug:
        return contextlib.nullcontext()
    import numpy as np

    return np.errstate(all="ignore")


@contextlib.contextmanager
def _warnings_on_one_line(debug):
    """Python warnings (a marginal Riccati solution, readings in degrees) as one line each,
    ``cfdesign: warning: ...``, after a command that succeeds; a command that fails says why in
    its error alone.  Python's own format printed the source file, line and code (three
    lines before the error).  ``--debug`` keeps Python's format."""
    import warnings

    if debug:
        yield
        return
    with warnings.catch_warnings(record=True) as caught:
        yield
    for text in dict.fromkeys(str(w.message) for w in caught):  # once each, in order
        print(f"cfdesign: warning: {_one_line(text, 2000)}", file=sys.stderr)


def _one_line(text: str, limit: int = 300) -> str:
    """Text safe to print on one line: control characters replaced, length capped."""
    text = "".join(c if c.isprintable() else " " for c in text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _error(exc):
    message = _one_line(str(exc), 2000).replace(STDIN, "standard input")  # '-' as the user wrote it
    print(message if message.startswith("cfdesign") else f"cfdesign: error: {message}", file=sys.stderr)


class _PipeSafe:
    """stdout that goes quiet when its reader has gone (``cfdesign design -o g.json | head -c1``):
    the command still writes its files (a summary printed first to a closed pipe stopped
    design, noise and discretize before their outputs, with exit status 0)."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self):
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()

    def _gone(self):
        import io

        _quiet_stdout()
        self._stream = io.StringIO()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _quiet_stdout():
    """After a broken pipe: point stdout at devnull so the interpreter's final flush is silent."""
    import os

    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
