"""Our Monte-Carlo numbers beside a paper's: mean, confidence interval, ratio, agreement."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..sim.metrics import mean_ci

__all__ = ["Comparison", "RATIO_RANGE", "MAX_RUNS", "MAX_SEED", "format_table", "order_disagreements", "json_text",
           "check_runs", "runs_text"]

#: ratios ours/paper outside this range are explained, not hidden
RATIO_RANGE = (1 / 3, 3.0)
#: most Monte-Carlo runs of a reproduction (``--runs``)
MAX_RUNS = 10_000
#: largest seed of a run (numpy's generators take non-negative integers; 2**63 - 1 keeps every
#: ``seed + run`` an int64)
MAX_SEED = 2**63 - 1 - MAX_RUNS


def check_runs(runs, seed, runs_needed: bool = True):
    """Refuse a count of runs or a seed a reproduction cannot use, naming the option.

    Parameters
    ----------
    runs : int
        Monte-Carlo runs (``--runs``): from 1 to :data:`MAX_RUNS`.
    seed : int
        Seed of the first run (``--seed``): from 0 to :data:`MAX_SEED`.
    runs_needed : bool
        Check ``runs`` (False: a reproduction without runs, ``compare``).

    Raises
    ------
    SpecError
        Either is not an integer in its range (a negative seed was a ValueError from numpy,
        ``--runs 10**20`` an OverflowError: internal errors).
    """
    from ..errors import SpecError

    def whole(v):
        return isinstance(v, int) and not isinstance(v, bool)

    if runs_needed and not (whole(runs) and 1 <= runs <= MAX_RUNS):
        raise SpecError(f"runs (--runs) must be a whole number from 1 to {MAX_RUNS}, got {runs!r}")
    if not (whole(seed) and 0 <= seed <= MAX_SEED):
        raise SpecError(f"seed (--seed) must be a whole number from 0 to {MAX_SEED}, got {seed!r}")


@dataclass(frozen=True)
class Comparison:
    """One row of a reproduced table: its label cells, our per-run values, the paper's value.

    Parameters
    ----------
    cells : tuple of str
        The row's label columns (e.g. the sensors in each band).
    values : tuple of float
        Our value in every run.
    paper : float
        The paper's value.
    note : str
        Why the row is where it is (printed when its ratio is out of range).
    confidence : float
        Level of the interval of :attr:`stats`.
    """

    cells: tuple
    values: tuple
    paper: float
    note: str = ""
    confidence: float = 0.95

    @property
    def stats(self) -> tuple:
        """``(mean, low, high)``: mean over the runs and its Student-t interval, clipped at 0.

        The values are mean squares: a t-interval of a few skewed values can reach below
        zero, which says only that the interval is wide.
        """
        mean, low, high = mean_ci(self.values, self.confidence)
        return mean, max(low, 0.0), high

    @property
    def mean(self) -> float:
        """Our mean over the runs."""
        return self.stats[0]

    @property
    def ratio(self) -> float:
        """Ours over the paper's."""
        return self.mean / self.paper

    @property
    def in_range(self) -> bool:
        """Whether the ratio ours/paper lies within :data:`RATIO_RANGE`."""
        return RATIO_RANGE[0] <= self.ratio <= RATIO_RANGE[1]

    def to_dict(self, names) -> dict:
        """The row's JSON form.

        Parameters
        ----------
        names : sequence of str
            Keys for the label cells (``low_pass``, ``high_pass``, ...).

        Returns
        -------
        dict
            Cells, ``mse``, ``ci``, ``confidence``, ``paper``, ``ratio``, ``ratio_in_range``,
            ``runs`` and ``note``; NaN bounds as None.
        """
        mean, low, high = self.stats
        return {**dict(zip(names, self.cells, strict=True)), "mse": mean,
                "ci": [_finite(low), _finite(high)], "confidence": self.confidence,
                "paper": self.paper, "ratio": self.ratio, "ratio_in_range": self.in_range,
                "runs": list(self.values), "note": self.note}


def runs_text(seeds) -> str:
    """The runs of a report's heading: ``20 runs (seeds 0..19)``, ``1 run (seed 0; no interval)``.

    Parameters
    ----------
    seeds : sequence of int
        The seeds of the runs, in order (at least one).

    Returns
    -------
    str
        The count and the seeds; one run says why its interval column shows ``-``.
    """
    if len(seeds) == 1:
        return f"1 run (seed {seeds[0]}; no 95% interval from one run)"
    return f"{len(seeds)} runs (seeds {seeds[0]}..{seeds[-1]})"


def _finite(x):
    return None if math.isnan(x) else x


def _ci_text(low, high) -> str:
    return "-" if math.isnan(low) else f"[{low:.2e}, {high:.2e}]"


def format_table(title: str, headers, rows) -> str:
    """A plain-text table: label columns, then ours, its interval, the paper's value and the ratio.

    Rows whose ratio lies outside :data:`RATIO_RANGE` are flagged ``*`` and their notes are
    printed under the table.

    Parameters
    ----------
    title : str
        Heading printed above the table.
    headers : sequence of str
        Names of the label columns.
    rows : sequence of Comparison
        The rows: ours beside the paper's.

    Returns
    -------
    str
        The table, lines separated by newlines.
    """
    conf = f"{rows[0].confidence:.0%} CI" if rows else "CI"
    head = [*headers, "MSE ours", conf, "paper", "ours/paper"]
    body = []
    for row in rows:
        mean, low, high = row.stats
        flag = "" if row.in_range else " *"
        body.append([*row.cells, f"{mean:.2e}", _ci_text(low, high), f"{row.paper:.2e}", f"{row.ratio:.3g}{flag}"])
    widths = [max(len(str(r[i])) for r in [head, *body]) for i in range(len(head))]
    lines = [title, "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))]
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in body]
    notes = [f"  * {' / '.join(r.cells)}: {r.note}" for r in rows if not r.in_range and r.note]
    return "\n".join(lines + notes)


def order_disagreements(ours, paper, tie: float = 0.05) -> list:
    """Index pairs that the paper orders one way and we the other.

    Pairs whose paper values lie within ``tie`` (relative) of each other are ties in the
    paper's rounding and constrain nothing.

    Parameters
    ----------
    ours, paper : sequence of float
        Values of the same rows.
    tie : float
        Relative spread below which two paper values are a tie.

    Returns
    -------
    list of (int, int)
        ``(i, j)`` pairs that the paper orders one way and ``ours`` the other.

    Examples
    --------
    >>> from cfdesign.reproduce.report import order_disagreements
    >>> order_disagreements([1.0, 2.0, 3.0], [1.0, 3.0, 2.0])
    [(1, 2)]
    """
    bad = []
    for i in range(len(paper)):
        for j in range(i + 1, len(paper)):
            if abs(paper[i] - paper[j]) <= tie * max(paper[i], paper[j]):
                continue
            if (ours[i] < ours[j]) != (paper[i] < paper[j]):
                bad.append((i, j))
    return bad


def _finite_or_none(value):
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def json_text(data) -> str:
    """Strict JSON of a result.

    A quantity that could not be computed (NaN, e.g. the interval of a single run) is
    ``null``, never the non-standard ``NaN``.

    Parameters
    ----------
    data : dict
        Nested dicts, lists and numbers.

    Returns
    -------
    str
        Indented JSON; NaN and infinities are written as ``null``.

    Examples
    --------
    >>> from cfdesign.reproduce.report import json_text
    >>> json_text({"ci": [float("nan"), 1.0]}).split()
    ['{', '"ci":', '[', 'null,', '1.0', ']', '}']
    """
    import json

    return json.dumps(_finite_or_none(data), indent=1, allow_nan=False)
