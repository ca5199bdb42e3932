"""How consistent a log is with the design's noise model: the innovation check of
:func:`~cfdesign.logs.run_log`, per measurement sensor.

At every tick a sensor is read, its innovation ``nu = y - H x`` (``x`` the one-step
prediction: the state before the tick's readings) has the predicted variance
``S = H P H' + R``, ``P`` the prior covariance that goes with the gains that ran (the table's
at the tick's phase, those recomputed for the log's arrival pattern, or the Kalman filter's
that bridged missed readings) and ``R`` the sensor's noise from the design file.  On a log that
follows the design, ``nu^2 / S`` is chi-square with one degree of freedom: the ratio
``sqrt(median(nu^2 / S) / CHI2_1_MEDIAN)`` is 1, robust against a few outliers (a glitch, a
reading in the start-up of a restart), and the plain ``sqrt(mean(nu^2 / S))`` too.  A ratio far
below 1 says the design file over-states the sensor's noise (the filter trusts it too little,
and the predicted std is too pessimistic); far above, that it is noisier than said, or in
other units.  The check of innovations against their predicted covariance is the classic
consistency test of a Kalman filter (Bar-Shalom, Li and Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, Sec. 5.4).

The ratios are kept in a fixed histogram of ``log10(nu^2 / S)`` (bounded memory for any log),
so the median is known to :data:`BIN_DECADES` of a decade of ``nu^2 / S``.
"""

from __future__ import annotations

import math

import numpy as np

#: the median of the chi-square distribution with one degree of freedom
CHI2_1_MEDIAN = 0.4549364231195724
#: a sensor whose innovations are more than this many times their predicted std, or less than
#: its inverse, gets a note
CONSISTENCY_RATIO = 3.0
#: readings after the start-up a sensor needs before its ratio makes a note (20 readings of a log that
#: follows the design give a ratio within :data:`CONSISTENCY_RATIO` of 1, no note, in 99.97 % of logs;
#: their median of ``nu^2 / S`` alone is within a factor 2 of its own in only 83 %: tests/test_log_consistency.py)
CONSISTENCY_READINGS = 20
#: the histogram of ``log10(nu^2 / S)``: from ``LOW`` to ``HIGH`` decades in bins of ``BIN_DECADES``
#: (the ratio known to 0.3 %); values beyond either end count in the end bin
LOW, HIGH, BIN_DECADES = -16.0, 16.0, 0.005


class Innovations:
    """The innovations of each measurement sensor after the start-up, accumulated block by block.

    Parameters
    ----------
    table : GainTable
        The table run (its measurement sensors, in the order of its rows of ``H``, and its noise
        model).
    """

    def __init__(self, table):
        self.table = table
        self.names = table.sensor_names("measurement")
        bins = round((HIGH - LOW) / BIN_DECADES)
        self.hist = np.zeros((len(self.names), bins), dtype=np.int64)
        #: per sensor: readings, sum of nu^2 / S, of S, of H P H'
        self.sums = np.zeros((len(self.names), 4))

    def add(self, nu, S, hph, used):
        """Count readings.

        Parameters
        ----------
        nu, S, hph : ndarray, shape (N, m)
            Innovations (in each sensor's unit), their predicted variances and the share of the
            estimate's error in them (``H P H'``, unit squared) at ``N`` ticks.
        used : ndarray of bool, shape (N, m)
            Which of them are readings the filter used.
        """
        bins = self.hist.shape[1]
        for i in range(len(self.names)):
            ok = used[:, i]
            if not ok.any():
                continue
            z = nu[ok, i] ** 2 / S[ok, i]
            with np.errstate(divide="ignore"):
                at = np.floor((np.log10(z) - LOW) / BIN_DECADES)
            self.hist[i] += np.bincount(np.clip(np.nan_to_num(at, nan=0.0, neginf=0.0), 0, bins - 1).astype(np.intp),
                                        minlength=bins)
            self.sums[i] += (ok.sum(), z.sum(), S[ok, i].sum(), hph[ok, i].sum())

    def ratios(self) -> dict:
        """``{sensor: sqrt(median(nu^2 / S) / CHI2_1_MEDIAN)}`` of the sensors read after the start-up."""
        return {name: math.sqrt(self._median(i) / CHI2_1_MEDIAN) for i, name in enumerate(self.names)
                if self.sums[i, 0]}

    def rms_ratios(self) -> dict:
        """``{sensor: sqrt(mean(nu^2 / S))}`` of the sensors read after the start-up."""
        return {name: math.sqrt(self.sums[i, 1] / self.sums[i, 0]) for i, name in enumerate(self.names)
                if self.sums[i, 0]}

    def noise(self) -> dict:
        """``{sensor: std}``: about the sensor's noise as the log has it, in its unit.

        The innovations' variance ``E``, robustly (the ratio of :meth:`ratios` squared times their
        mean predicted variance), is the estimate's error at the reading plus the sensor's noise
        ``R``.  Under the design's gains the first is ``a + b R``: linear in the noise, ``b`` the
        share of a unit of this sensor's noise that comes back in its innovations through the
        estimate (:func:`noise_shares`), ``a + b R0`` the design's mean ``H P H'`` at the design's
        figure ``R0``.  So ``R = (E - H P H' + b R0) / (1 + b)``, at least zero.  A figure for the
        design file; the error's share is the design's model (its other sensors' noise and
        process noise as given), and the gains are the design's own (not those recomputed for
        the log's arrival pattern).
        """
        if not hasattr(self, "_shares"):
            self._shares = noise_shares(self.table)
        out = {}
        for name, ratio in self.ratios().items():
            i = self.names.index(name)
            n, _, s, hph = self.sums[i]
            r0, b = float(self.table.R[i, i]), self._shares[name]
            out[name] = math.sqrt(max((ratio ** 2 * s / n - hph / n + b * r0) / (1.0 + b), 0.0))
        return out

    def predicted_std(self, name) -> float:
        """The RMS of the predicted std of ``name``'s innovations (``sqrt(mean(S))``)."""
        i = self.names.index(name)
        return math.sqrt(self.sums[i, 2] / self.sums[i, 0])

    def count(self, name) -> int:
        """Readings of ``name`` after the start-up."""
        return int(self.sums[self.names.index(name), 0])

    def _median(self, i) -> float:
        """The median of sensor ``i``'s ``nu^2 / S``, interpolated in its bin of the histogram."""
        counts = self.hist[i]
        cum = np.cumsum(counts)
        half = cum[-1] / 2.0
        k = int(np.searchsorted(cum, half))
        below = cum[k - 1] if k else 0
        frac = (half - below) / counts[k] if counts[k] else 0.5
        return 10.0 ** (LOW + (k + frac) * BIN_DECADES)

    def notes(self, table, slips, named=()) -> list:
        """A note per sensor whose innovations are more than :data:`CONSISTENCY_RATIO` times their
        predicted std or less than its inverse, over :data:`CONSISTENCY_READINGS` readings at least;
        one too large is left to the note that already names the sensor (``named``: those whose
        readings mostly lie far from the estimate, named by the run's note on them).
        ``slips(table, name)`` names the unit mix-ups likely for what the sensor reads."""
        units = table.sensor_units()
        ratios, noise, out = self.ratios(), self.noise(), []
        for name, ratio in ratios.items():
            if self.count(name) < CONSISTENCY_READINGS or 1 / CONSISTENCY_RATIO <= ratio <= CONSISTENCY_RATIO:
                continue
            if ratio > CONSISTENCY_RATIO and name in named:
                continue
            unit = f" {units[name]}" if units.get(name) else ""
            i = table.sensor(name).index
            figure = f"{math.sqrt(table.R[i, i]):.2g}{unit}"
            why = (f"its noise figure in the design file ({figure}) is likely too large, or in other units "
                   f"({slips(table, name)})" if ratio < 1 else
                   f"it is noisier than its figure in the design file ({figure}) says, its error is not white, or "
                   f"its column is in other units ({slips(table, name)})")
            take = (f"take the log's figure: about {noise[name]:.2g}{unit}" if noise[name] > 0 else
                    "the log gives no figure (the estimate's own predicted error exceeds its innovations)")
            out.append(f"{name}: its innovations are {ratio:.2g} times their predicted std "
                       f"({self.predicted_std(name):.2g}{unit}) over {self.count(name)} readings after the start-up: "
                       f"{why}; measure it with `cfdesign noise`, or {take}")
        return out


def noise_shares(table) -> dict:
    """``{sensor: b}``: how much of a unit of each measurement sensor's noise variance comes back in
    its own innovations through the estimate, under the table's gains: ``H P H'`` at the phases
    that read it (their mean), ``P`` the periodic prior covariance of the table's fixed gains
    with that sensor's noise alone (unit variance; no process noise, no other sensor's).

    Parameters
    ----------
    table : GainTable
        A discrete table with a noise model (``Q``, ``R``).

    Returns
    -------
    dict
        ``b`` per measurement sensor (dimensionless, at least 0), NaN for one the table never reads.
    """
    from ..runtime.arrivals import MissedReadings

    n, m = len(table.F), len(table.measurements)
    mask, H = table.schedule.mask(), np.asarray(table.H, dtype=float)
    one, out = MissedReadings(table, "prior"), {}
    one.Q = np.zeros((n, n))  # the table's gains without process noise ...
    for s in table.measurements:
        one.R = np.zeros((m, m))  # this sensor's noise alone, unit variance
        one.R[s.index, s.index] = 1.0
        one._cache = {}
        ticks = [one._tick(k, mask[k]) for k in range(table.period)]  # P <- M P M' + N at each phase
        Phi, S = np.eye(n), np.zeros((n, n))
        for M, N, _, _ in ticks:
            Phi, S = M @ Phi, M @ S @ M.T + N
        P = _fixed_point(Phi, S)  # the prior at phase 0, one period on
        h, seen = H[s.index], []
        for k, (M, N, _, _) in enumerate(ticks):
            if mask[k, s.index]:
                seen.append(float(h @ P @ h))
            P = M @ P @ M.T + N
        out[s.name] = max(float(np.mean(seen)), 0.0) if seen else math.nan
    return out


def _fixed_point(A, S):
    """``P = A P A' + S`` for a stable ``A``, by doubling (Smith's iteration): ``sum_k A^k S A^k'``.
    numpy only: the project's Stein solver (:func:`cfdesign.riccati.lyapunov.stein`) would import
    scipy.linalg and the Riccati package, 0.16 s of every ``cfdesign run``, for a few small solves."""
    P = S.copy()
    for _ in range(64):
        step = A @ P @ A.T
        P = P + step
        A = A @ A
        if np.max(np.abs(step)) <= 1e-15 * max(np.max(np.abs(P)), 1e-300):
            break
    return P
