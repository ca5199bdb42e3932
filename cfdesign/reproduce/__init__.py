"""Reproductions of the papers' results: ``cfdesign reproduce PAPER [options]``.

``carreira``: Tables I and II of Carreira et al., *Complementary Filter Design with Three
Frequency Bands: Robot Attitude Estimation* - every assignment of a gyro, a compass and
odometry to the bands of a CF and a CF³, designed by the toolkit, run by the runtime on
Monte-Carlo simulations of the robot-heading scenario (:mod:`cfdesign.reproduce.carreira`).

``helicopter``: Table 2 of Vasconcelos et al.'s helicopter navigation system - the
manoeuvre flown with the Euler-angle attitude filter and the multirate position filter
(:mod:`cfdesign.reproduce.helicopter`).

``compare``: every navigation filter on the same scenarios, errors and cost per step
(:mod:`cfdesign.reproduce.compare`).

Each paper's module provides ``add_arguments(parser)`` (its options) and ``run(args)``.
Former names of the commands still work; they are left out of the help and of this reference.
"""

from __future__ import annotations

from importlib import import_module

__all__ = ["add_parser", "PAPERS"]

#: papers that can be reproduced, with a one-line description
PAPERS = {
    "carreira": "Carreira et al., three-band complementary filters: Tables I and II (robot heading)",
    "helicopter": "Vasconcelos et al., helicopter navigation: Table 2 (mean absolute errors)",
    "compare": "CF against the EKF baselines and the adaptive CF: errors and cost per step, same scenarios",
}

# former names, still accepted (not in __all__: internal names, kept out of the help and the reference)
ALIASES = {"seed001": "carreira", "seed004": "helicopter"}


def add_parser(subparsers, load: bool = True):
    """Add ``reproduce`` (one sub-command per paper) to an argparse ``subparsers`` object.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        What ``parser.add_subparsers()`` returned.
    load : bool
        Import each paper's module and add its options.  ``False`` lists the papers without
        importing their modules: what every other command needs, so that
        ``cfdesign --version`` or ``cfdesign run`` start fast.

    Returns
    -------
    argparse.ArgumentParser
        The ``reproduce`` parser.

    Examples
    --------
    >>> import argparse
    >>> from cfdesign.reproduce import add_parser
    >>> parser = argparse.ArgumentParser(prog="cfdesign")
    >>> _ = add_parser(parser.add_subparsers(dest="command"))
    >>> parser.parse_args(["reproduce", "carreira", "--runs", "2"]).runs
    2
    """
    p = subparsers.add_parser("reproduce", help="reproduce a paper's results (" + ", ".join(PAPERS) + ")",
                              description="Reproduce a paper's tables: ours beside the paper's, with the ratio.")
    papers = p.add_subparsers(dest="paper", required=True, metavar="PAPER", parser_class=type(p))
    for name, description in PAPERS.items():
        q = papers.add_parser(name, help=description, description=description)
        _load(q, name, load)
    for alias, name in ALIASES.items():
        # no help= : argparse leaves the alias out of the list of papers (metavar hides the choices)
        q = papers.add_parser(alias, description=f"Alias of '{name}': {PAPERS[name]}")
        _load(q, name, load)
    # argparse lists the choices in its "invalid choice" message: list the current names only
    papers.choices = _Papers(papers.choices)
    return p


class _Papers(dict):
    """The ``PAPER`` choices: every name (former ones too) is accepted, only the current are listed."""

    def __iter__(self):
        return (name for name in super().__iter__() if name not in ALIASES)


def _load(parser, name, load):
    if load:
        module = import_module(f".{name}", __name__)
        module.add_arguments(parser)
        parser.set_defaults(run=module.run)
