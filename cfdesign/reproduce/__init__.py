"""Reproductions of the papers' results: ``cfdesign reproduce PAPER [options]``.

``seed001``: Tables I and II of Carreira et al. (seed 001), every assignment of a gyro, a
compass and odometry to the bands of a CF and a CF³, designed by the toolkit, run by the
runtime on Monte-Carlo simulations (:mod:`cfdesign.reproduce.seed001`).

``seed004``: Table 2 of Vasconcelos et al. (seed 004), the helicopter manoeuvre with the
Euler-angle attitude filter and the multirate position filter
(:mod:`cfdesign.reproduce.seed004`).

``compare``: every navigation filter on the same scenarios, errors and cost per step
(:mod:`cfdesign.reproduce.compare`).

Each paper's module provides ``add_arguments(parser)`` (its options) and ``run(args)``.
"""

from __future__ import annotations

from importlib import import_module

__all__ = ["add_parser", "PAPERS"]

#: papers that can be reproduced, with a one-line description
PAPERS = {
    "seed001": "Carreira et al., three-band complementary filters: Tables I and II (robot heading)",
    "seed004": "Vasconcelos et al., helicopter navigation: Table 2 (mean absolute errors)",
    "compare": "CF against the seeds' EKFs and the adaptive CF: errors and cost per step, same scenarios",
}


def add_parser(subparsers):
    """Add ``reproduce`` (one sub-command per paper) to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("reproduce", help="reproduce a paper's results (" + ", ".join(PAPERS) + ")",
                              description="Reproduce a paper's tables: ours beside the paper's, with the ratio.")
    papers = p.add_subparsers(dest="paper", required=True, metavar="PAPER", parser_class=type(p))
    for name, description in PAPERS.items():
        module = import_module(f".{name}", __name__)
        q = papers.add_parser(name, help=description, description=description)
        module.add_arguments(q)
        q.set_defaults(run=module.run)
    return p
