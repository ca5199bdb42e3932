"""What a run of a log gives: :class:`~cfdesign.logs.LogResult`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class LogResult:
    """What running a table on a log gave.

    Attributes
    ----------
    estimates : pandas.DataFrame or None
        One row per log row: the time column (if any), a column per state (the table's
        ``states``), ``<state>_std`` columns when asked for,
        and the log's other columns.  None when the estimates were written to a file only.
    samples : int
        Rows run.
    rms : dict
        ``{state: RMS error against the reference column}`` over every row (angles wrapped to
        (-pi, pi]); NaN when no row has a finite reference to compare with.  It includes the
        start-up, where the error of the initial state is still dying away.
    unused : dict
        Readings not used, by reason and sensor: ``rejected`` (inf, or beyond the runtime's
        :data:`~cfdesign.runtime.filter.READING_LIMIT`), ``unscheduled`` (no gain at its
        tick), ``same_tick`` (a second reading of a sensor on one base tick), ``before_start``
        (logged more than half a tick before the first row where the inputs read).
    notes : list of str
        What a user should know: offsets found, gains recomputed, rate mismatches.
    output : Path or None
        The file written.
    source : str
        The log's name (its path, or the name given).
    rms_settled : dict
        ``{state: RMS error}`` over the rows after the start-up (``startup_s``); NaN when no
        row after it has a finite reference (the log ends within it).
    predicted_std : dict
        ``{state: predicted standard deviation}`` of the estimate that ran, over the rows of
        ``rms_settled`` (over every compared row when none is after the start-up): the root
        mean square of the ``<state>_std`` column there (the table's figure; a multirate
        table's averaged over its phases; widened through missed readings; of the gains
        recomputed for the log where they were).  What ``rms_settled`` should come to.
    startup_s : float
        The start-up's length in seconds: :func:`~cfdesign.linear.startup_steps` of the table
        (its slowest error mode shrunk :data:`~cfdesign.linear.STARTUP_DECAY` times), rounded up
        to whole base ticks; ``inf`` when the error does not die away (a state no sensor
        corrects).  NaN when the log was run without a reference.
    settled_samples : int
        Rows after the start-up (and after the start-up that follows each restart).
    pauses : int
        Pauses of the logger: more than :data:`~cfdesign.timing.PAUSE_TICKS` ticks without a
        reading of an input sensor.
    restarts : int
        The pauses after which the first state started again from the first direct reading
        (it disagreed with the state carried over): their start-up is left out of
        ``rms_settled``; that of a pause carried over is not.
    consistency : dict
        ``{sensor: ratio}`` per measurement sensor read after the start-ups (of the log and of
        every pause): how large its innovations (the reading less the one-step prediction, ``y - H
        x``) are against their predicted std (``sqrt(H P H' + R)``: ``P`` the prior covariance of
        the gains that ran, ``R`` the sensor's noise in the design file), robustly:
        ``sqrt(median(nu^2 / S) / 0.4549)`` (0.4549 is the median of chi-square with one degree
        of freedom; :mod:`cfdesign.logs.consistency`).  About 1 on a log that follows the design;
        below 1/3 the design file over-states the sensor's noise (or gives it in other units:
        degrees for radians, 57 times), above 3 the sensor is noisier than it says (a note
        either way).  Empty for a table without a noise model.
    consistency_rms : dict
        ``{sensor: sqrt(mean(nu^2 / S))}``: the same, not robust (a few outliers raise it).
    noise_estimate : dict
        ``{sensor: std}`` in the sensor's unit: about its noise as the log has it, the
        innovations' variance less the share the design predicts of the estimate's error in it
        (:meth:`Innovations.noise <cfdesign.logs.consistency.Innovations.noise>`): a figure for
        the design file where ``consistency`` is far from 1.
    """

    estimates: object
    samples: int
    rms: dict = field(default_factory=dict)
    unused: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    output: Path | None = None
    source: str = ""
    rms_settled: dict = field(default_factory=dict)
    predicted_std: dict = field(default_factory=dict)
    startup_s: float = math.nan
    settled_samples: int = 0
    pauses: int = 0
    restarts: int = 0
    consistency: dict = field(default_factory=dict)
    consistency_rms: dict = field(default_factory=dict)
    noise_estimate: dict = field(default_factory=dict)

    @property
    def without_gain(self) -> int:
        """Readings not used for any reason (the number ``cfdesign run`` reports)."""
        return sum(sum(v.values()) for v in self.unused.values())

    def summary(self) -> dict:
        """One row of a fleet's summary table (``summary.csv`` of :func:`run_logs`).

        Returns
        -------
        dict
            ``log``, ``samples``, ``readings_not_used``, and for each reference ``rms_<state>``
            (over every row), ``rms_settled_<state>`` (after the start-up, ``startup_s``) and
            ``predicted_std_<state>``, what the settled figure should come to for this log
            (``predicted_std``: missed readings and recomputed gains make it differ from log to log),
            ``consistency_<sensor>`` for each measurement sensor read after the start-up
            (``consistency``: 1 where the log follows the design's noise figures), then ``notes``:
            the log's notes (what ``cfdesign run`` prints for one log: a cut last line, offsets
            found, gains recomputed), joined by a vertical bar.
        """
        row = {"log": self.source, "samples": self.samples, "readings_not_used": self.without_gain}
        for k, v in self.rms.items():
            row.update({f"rms_{k}": v, f"rms_settled_{k}": self.rms_settled.get(k, math.nan),
                        f"predicted_std_{k}": self.predicted_std.get(k, math.nan)})
        if self.rms:
            row["startup_s"] = self.startup_s
        row.update({f"consistency_{k}": v for k, v in self.consistency.items()})
        row["notes"] = " | ".join(self.notes)
        return row
