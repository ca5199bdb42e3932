"""Reproductions of the papers' results: ``cfdesign reproduce PAPER``.

``seed001``: Tables I and II of Carreira et al. (seed 001), every assignment of a gyro, a
compass and odometry to the bands of a CF and a CF³, designed by the toolkit, run by the
runtime on Monte-Carlo simulations (:mod:`cfdesign.reproduce.seed001`).

The command-line interface is :func:`add_parser`; the work is done by
:func:`cfdesign.reproduce.seed001.reproduce`.
"""

from __future__ import annotations

import json

__all__ = ["add_parser", "run", "PAPERS"]

#: papers that can be reproduced, with a one-line description
PAPERS = {"seed001": "Carreira et al., three-band complementary filters: Tables I and II (robot heading)"}


def add_parser(subparsers):
    """Add the ``reproduce`` subcommand to an argparse ``subparsers`` object; returns its parser.

    ``cfdesign reproduce seed001 [--runs N] [--seed S] [--reading std|variance] [--json]``
    """
    from ..sim.seed001 import READINGS

    p = subparsers.add_parser("reproduce", help="reproduce a paper's results (seed001: Tables I and II)",
                              description="Reproduce a paper's tables: ours beside the paper's, with the ratio.")
    p.add_argument("paper", choices=sorted(PAPERS), help="; ".join(f"{k}: {v}" for k, v in PAPERS.items()))
    p.add_argument("--runs", type=int, default=20, help="Monte-Carlo runs per row (default 20)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first run (runs use seed, seed+1, ...)")
    p.add_argument("--reading", choices=sorted(READINGS), default="std",
                   help="read the paper's N(0, x) as a standard deviation (default) or a variance")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON instead of the tables")
    p.set_defaults(run=run)
    return p


def run(args) -> int:
    """Run ``cfdesign reproduce``: print the tables (or JSON); exit status 0.

    Raises :class:`cfdesign.errors.SpecError` for a bad ``--runs``.
    """
    from ..sim.seed001 import READINGS
    from .seed001 import reproduce

    result = reproduce(args.runs, seed=args.seed, reading=READINGS[args.reading], progress=not args.json)
    print(json.dumps(result.to_dict(), indent=1) if args.json else result.text())
    return 0
