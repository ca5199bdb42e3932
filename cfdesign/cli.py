"""The ``cfdesign`` command.

User errors (unknown structure, bad gains, unreadable files) print one line on stderr and
exit with status 2; a proof or check that fails exits with 1; tracebacks mean a bug.
"""

from __future__ import annotations

import argparse
import json
import sys

from . import __version__
from .errors import CfdesignError, GainError

__all__ = ["main", "parse_gains"]


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage errors on one line, exit status 2."""

    def error(self, message):
        raise CfdesignError(f"{self.prog}: {message}")


def parse_gains(text: str) -> dict:
    """Parse ``'k1=2,k2=1'`` into exact numbers; never evaluates the text."""
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

    return structure(args.structure, order=args.order, bands=args.bands)


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
    extra = sorted(set(values) - {p.name for p in obs.parameters})
    if extra:
        raise GainError(f"{obs.name} has no gain(s) {', '.join(extra)} (gains: {', '.join(obs.gains)})")
    missing = [g for g in obs.gains if g not in values]
    if missing:
        raise GainError(f"{obs.name} needs a value for gain(s) {', '.join(missing)}")
    return obs.with_gains(values)


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
    _save_figure(bode_plot(obs), args.output)
    print(f"wrote {args.output}")
    return 0


def cmd_design(args) -> int:
    from .designer import design, designed_observer
    from .spec import example_path, load_spec

    spec = load_spec(args.spec if args.spec else example_path(args.example))
    table = design(spec)
    fig = None
    if args.bode:
        from .plot import bode_plot

        fig = bode_plot(designed_observer(spec, table))
    print(_summary(table))
    if args.output:  # everything is computed before anything is written
        table.save(args.output)
        print(f"wrote {args.output}")
    if fig is not None:
        _save_figure(fig, args.bode)
        print(f"wrote {args.bode}")
    return 0


def _summary(table) -> str:
    kind = (f"discrete, T = {table.sample_time_s:g} s, {table.gain_form} gains"
            if table.domain == "z" else "continuous")
    lines = [f"{table.name}: {table.structure} ({kind})"]
    if table.period > 1:
        lines.append(f"  multirate: period {table.period} steps; measurements per phase: "
                     + ", ".join(f"{k}:{'+'.join(m)}" for k, m in enumerate(table.measured) if m))
        for k, K in enumerate(table.K):
            if table.measured[k]:
                lines.append(f"  K[{k}] = {K.ravel().tolist()}")
    else:
        lines.append("  gains: " + ", ".join(f"{name} = {value:.6g}" for name, value in table.gains.items()))
    lines.append(f"  predicted steady-state std of the estimate: {table.predicted_std:.6g}")
    c = table.checks
    roots = c.get("poles", c.get("monodromy_multipliers"))
    what = "poles" if "poles" in c else "monodromy multipliers"
    lines.append(f"  {what}: " + ", ".join(f"{complex(*p):.6g}" for p in roots))
    lines.append(f"  complementary (exact proof): {c['complementary']}; stable: {c['stable']}")
    solver = table.provenance["solver"]
    residual = f", residual {solver['residual']:.2e}" if "residual" in solver else ""
    lines.append(f"  solver: {solver['method']}{residual}")
    return "\n".join(lines)


def _save_figure(fig, path):
    import matplotlib.pyplot as plt

    try:
        fig.savefig(path, dpi=120)
    except (OSError, ValueError) as exc:
        raise CfdesignError(f"cannot write {path}: {exc}") from None
    finally:
        plt.close(fig)


def _add_structure(p):
    p.add_argument("structure", help="cf2, cf3, ckf3, dckf3 or cfn")
    p.add_argument("--order", type=int, help="cf2 only: 1 (angle + rate) or 2 (with gyro-bias state)")
    p.add_argument("--bands", type=int, help="cfn only: number of bands/sensors n (2..7)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="cfdesign", description="Design and verify complementary filters.")
    parser.add_argument("--version", action="version", version=f"cfdesign {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("prove", help="derive the bands of a structure and prove they sum to 1")
    _add_structure(p)
    p.add_argument("--json", action="store_true", help="print variable, bands, sum and holds as JSON")
    p.set_defaults(run=cmd_prove)

    p = sub.add_parser("bode", help="Bode plot of every band and of their sum")
    _add_structure(p)
    p.add_argument("--gains", required=True, help="gain values, e.g. k1=2,k2=1")
    p.add_argument("--sample-time", help="sample time T in seconds (discrete structures)")
    p.add_argument("-o", "--output", required=True, help="PNG (or PDF/SVG) file to write")
    p.set_defaults(run=cmd_bode)

    p = sub.add_parser("design", help="optimal gains from a TOML design file (default: built-in example)")
    p.add_argument("spec", nargs="?", help="design file (TOML); omitted: the built-in example")
    p.add_argument("--example", default="robot-heading",
                   help="built-in example when no file is given: robot-heading (default), cf3, ckf3, position")
    p.add_argument("-o", "--output", help="write the gain table (JSON) here")
    p.add_argument("--bode", metavar="FILE.png", help="also write the Bode plot of the designed filter")
    p.set_defaults(run=cmd_design)
    return parser


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    try:
        args = build_parser().parse_args(argv)
        return args.run(args)
    except CfdesignError as exc:
        message = str(exc)
        print(message if message.startswith("cfdesign") else f"cfdesign: error: {message}", file=sys.stderr)
        return exc.exit_code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
