"""The streaming runtime's phase locked to the readings as they arrive.

A multirate table reads each slow sensor at its phases of the period.  A robot loop that steps
:class:`~cfdesign.runtime.Runtime` once per base tick from its own start sees a 1 Hz GPS at
whatever tick its clock puts it: at phase 17 of a table that reads it at phase 0 every reading had
no gain and was lost.  :meth:`PhaseLock.unscheduled` is called by the compiled step
(:mod:`cfdesign.runtime.step`) for such a reading and moves the phase when that is exact: when one
shift of the whole schedule (:func:`cfdesign.timing.rotation`, the rule the log path uses per
stretch) puts this sensor on its phases and keeps every other sensor whose last reading had a gain
(within :data:`LOCK_STALE_READINGS` of its spacings) on its own, the nearest such shift first.  The
step then runs again at the new phase.  A reading no shift can place (sensors at offsets of their own,
a sensor faster than the table reads it, ``lock=False``) is counted in
:attr:`Runtime.counts <cfdesign.runtime.Runtime.counts>` and warned of once per runtime and
sensor, naming :class:`~cfdesign.runtime.arrivals.ArrivalKalman`, the filter that uses every
reading as it arrives.

Steps of phase-aligned readings never call it: their cost and numbers are those of the fixed
schedule (and of the generated C, which has no lock: ``docs/guide/c-export.md``).  Nor do the
repeats of a value held and given every tick once the sensor has been warned of: the step refuses
a reading before :attr:`PhaseLock.soon` (faster than designed) and counts it as the rule does.
"""

from __future__ import annotations

import math
import numbers
import warnings

import numpy as np

from ..errors import CfdesignError
from ..timing import _pattern, rotation

__all__ = ["PhaseLock", "LOCK_STALE_READINGS"]

#: a sensor whose last reading with a gain is more than this many of its designed spacings old no longer holds
#: the schedule: a compass gone for good kept the odometry that came back 3 ticks later off its gains (4500 of
#: 4500 readings lost, 0.18 rad RMS against 0.0014 with it), so a relock keeps only the sensors still read
LOCK_STALE_READINGS = 3


class PhaseLock:
    """Where a runtime's slow sensors stand against its schedule, and the lock rule.

    Ticks are counted as ``S[n + 1] * period + S[n]`` (periods completed, phase); a move of the
    phase (a relock, ``Runtime.phase = k``) moves the ticks held by as much, so that their
    differences stay the ticks between readings.

    Parameters
    ----------
    table : GainTable
        The runtime's discrete table.
    S : list
        The runtime's state list: ``S[n]`` the phase, ``S[n + 1]`` the periods completed.
    UNS : list of int
        Per-measurement counts of readings without a gain (``Runtime.counts['unscheduled']``).
    ON : list
        Per measurement, the tick of its last reading if that had a gain, else None (the
        compiled step sets it).
    enabled : bool
        Move the phase (``Runtime(lock=True)``); False: count and warn only.
    warn : bool
        Warn of a reading without a gain (``Runtime(warn=True)``); False: count only.
    """

    def __init__(self, table, S, UNS, ON, enabled=True, warn=True):
        self.table, self.S, self.UNS, self.ON = table, S, UNS, ON
        self.n, self.period = table.F.shape[0], table.period
        self.names = [s.name for s in table.measurements]
        patterns = [_pattern(table.schedule, name) for name in self.names]
        self.phases = [set(ph.tolist()) for ph, _ in patterns]
        self.steps = {name: step for name, (_, step) in zip(self.names, patterns, strict=True)}
        self.spacing = [self.period / max(len(ph), 1) for ph, _ in patterns]  # ticks between readings
        #: ticks after its last usable reading from which a sensor's reading is not faster than designed
        self.half = [math.ceil(s / 2) for s in self.spacing]
        self.enabled = bool(enabled) and self.period > 1
        self.warned = set() if warn else set(self.names)  # no warning: as if each sensor had had its one
        #: the frames from the warning to the user's call: ``step`` (``Runtime.run`` sets it while it steps)
        self.stacklevel = 4
        self.last = [None] * len(self.names)
        #: per sensor, the tick before which its reading is refused as faster than designed with nothing
        #: to say (warned of already): the compiled step counts those itself, without :meth:`unscheduled`
        #: (-inf: none known; at most its last usable reading's tick + ``half``, the rule's first test)
        self.soon = [-math.inf] * len(self.names)
        self.reset()

    def reset(self):
        """No reading seen: every sensor free to be placed."""
        self.ON[:] = [None] * len(self.ON)
        self.last[:] = [None] * len(self.names)  # tick of each sensor's last reading without a gain
        self.soon[:] = [-math.inf] * len(self.names)

    def tick(self) -> int:
        """The tick of the next step.

        Returns
        -------
        int
            ``S[n + 1] * period + S[n]`` (ticks; only differences mean anything).
        """
        return self.S[self.n + 1] * self.period + self.S[self.n]

    def moved(self, old: int, new: int):
        """The phase was set from ``old`` to ``new``: the ticks held move with it.

        Parameters
        ----------
        old, new : int
            The phase before and after.
        """
        for held in (self.ON, self.last, self.soon):
            held[:] = [None if t is None else t + new - old for t in held]

    # ------------------------------------------------------------------ the rule
    def unscheduled(self, i: int, phase: int) -> int:
        """A usable reading of measurement ``i`` at ``phase``, where the table has no gain for it.

        Parameters
        ----------
        i : int
            The measurement's row of ``H``.
        phase : int
            The phase of this step.

        Returns
        -------
        int
            The phase to run this step at (the phase is set to it; the step runs again), or -1:
            no shift places it, the reading is counted and (once per sensor) warned of.
        """
        tick = self.tick()
        why, new = self._placed(i, phase, tick) if self.enabled else (self.fixed, None)
        if new is None:
            self.ON[i], self.last[i] = None, tick
            self.UNS[i] += 1
            if self.names[i] not in self.warned:  # the reason is worded only for the one warning
                self.warn(i, phase, why(), self.stacklevel)
            if self.enabled:  # a reading of it before this is refused by the rule's first test
                self.soon[i] = tick + self.half[i]
            return -1
        self.moved(phase, new)
        self.S[self.n] = new
        self.ON[i] = tick + new - phase  # placed: a later sensor's relock in this step must keep it
        return new

    def fixed(self) -> str:
        """Why a reading off the schedule has no gain when the phase cannot move.

        Returns
        -------
        str
            ``lock=False`` named, or (a single-rate table) that the table never reads the sensor.
        """
        return "Runtime(lock=False) keeps the schedule fixed" if self.period > 1 else "the table never reads it"

    def too_soon(self, i: int, gap: int) -> str:
        """Why a reading ``gap`` ticks after the sensor's last one is refused (for the warning).

        Parameters
        ----------
        i : int
            The measurement's row of ``H``.
        gap : int
            Ticks since its last usable reading (fewer than half its designed spacing).

        Returns
        -------
        str
            The gap against the spacing the table reads the sensor at.
        """
        return (f"it came {gap} ticks after its last reading, where the table reads it every {self.spacing[i]:g}: "
                "faster than designed (a value held and repeated?)")

    def faster(self, finite):
        """Where the rule refuses a reading as faster than designed, whatever the phase: it comes
        less than half the sensor's designed spacing after its last usable reading (of these rows,
        or before them as the lock holds it).  The gaps do not move with the phase, so ``Runtime.run``
        finds these once per call; the readings off the schedule that are all such run on the fixed
        schedule (a value held and repeated every tick stays vectorised).

        Parameters
        ----------
        finite : ndarray of bool, shape (N, m)
            Where each measurement has a usable reading, from the next step on.

        Returns
        -------
        ndarray of bool, shape (N, m)
            Readings refused as faster (False where there is none).
        """
        return self.gaps(finite) < np.array(self.half)  # the first test of _placed, for every reading

    def gaps(self, finite):
        """Ticks from each usable reading back to the sensor's last one (inf for its first).

        Parameters
        ----------
        finite : ndarray of bool, shape (N, m)
            Where each measurement has a usable reading, from the next step on (the phase not
            moving in between).

        Returns
        -------
        ndarray, shape (N, m)
            The gaps (ticks) at the readings, inf elsewhere and at a sensor's first reading.
        """
        now, out = self.tick(), np.full(finite.shape, np.inf)
        for i in np.flatnonzero(finite.any(axis=0)):
            rows = np.flatnonzero(finite[:, i])
            held = [t - now for t in (self.ON[i], self.last[i]) if t is not None]
            out[rows, i] = np.diff(rows, prepend=max(held) if held else -np.inf)
        return out

    def _placed(self, i, phase, tick):
        """``(why not, None)`` or ``(None, new phase)``: the shift of the whole schedule that puts
        reading ``i`` at ``phase`` on its phases and keeps the sensors read on schedule on theirs;
        ``why not`` words the reason when called (a value repeated every tick is refused at every
        tick, the reason warned of once)."""
        name = self.names[i]
        on_tick, last = self.ON[i], self.last[i]
        before = on_tick if last is None else last if on_tick is None else max(on_tick, last)
        if before is not None and tick - before < self.half[i]:  # (whole ticks: less than half the spacing)
            return (lambda: self.too_soon(i, tick - before)), None
        on = {self.names[j]: 0 for j, t in enumerate(self.ON)
              if t is not None and j != i and tick - t <= LOCK_STALE_READINGS * self.spacing[j]}
        step = self.steps[name]
        # its offset against one of its phases (several for a pattern such as 0, 33, 67): the nearest
        # first, a reading a tick early before one 32 late (ties: the later)
        for offset in sorted({(phase - p) % step for p in self.phases[i]}, key=lambda o: (min(o, step - o), o)):
            c = rotation({**on, name: offset}, self.steps, self.period)
            if c is not None:
                return None, (phase - c) % self.period
        return (lambda: f"no shift of the whole schedule puts it on its phases and keeps {', '.join(on)} on "
                        "theirs: the sensors arrive at offsets of their own"), None

    def warn(self, i, phase, why, stacklevel=4):
        """Warn once per sensor that a reading had no gain and was not used.

        Parameters
        ----------
        i : int
            The measurement's row of ``H``.
        phase : int
            The phase of its reading.
        why : str
            Why it has no gain there.
        stacklevel : int
            Points the warning at the user's call (``step``, ``run``).

        Warns
        -----
        UserWarning
            At the sensor's first such reading of this runtime.
        """
        name = self.names[i]
        if name in self.warned:
            return
        self.warned.add(name)
        warnings.warn(
            f"{name}: a reading at phase {phase} of {self.table.name!r} (period {self.period}) has no gain ({why}); "
            f"it is not used and is counted in Runtime.counts['unscheduled'] (this warning is given once per "
            f"runtime and sensor). To use every reading as it arrives, step "
            f"cfdesign.runtime.arrivals.ArrivalKalman(table) instead (ArrivalKalman.step(**readings)), or run a "
            f"whole log with cfdesign.logs.run_log", UserWarning, stacklevel=stacklevel)

    # ------------------------------------------------------------------ snapshots
    def state(self) -> dict:
        """What the rule has seen, for ``Runtime.state``.

        Returns
        -------
        dict
            ``{"on": {sensor: ticks since its last reading, which had a gain}, "off": {sensor:
            ticks since its last reading, which had none}}`` (sensors without a reading left out).
        """
        now = self.tick()
        return {key: {n: now - t for n, t in zip(self.names, held, strict=True) if t is not None}
                for key, held in (("on", self.ON), ("off", self.last))}

    def restore(self, state, where="state"):
        """Continue from :meth:`state`, the ticks counted from the phase.

        Parameters
        ----------
        state : dict or None
            :meth:`state`'s dict; None: nothing seen (a snapshot of an earlier cfdesign).
        where : str
            What the snapshot is, for the message.

        Raises
        ------
        CfdesignError
            Not such a dict (unknown sensors, a negative or non-integer count); ``where`` names
            the snapshot.
        """
        state = {"on": {}, "off": {}} if state is None else state
        ok = isinstance(state, dict) and set(state) == {"on", "off"} and all(
            isinstance(d, dict) and set(d) <= set(self.names)
            and all(isinstance(v, numbers.Integral) and not isinstance(v, bool) and v >= 0 for v in d.values())
            for d in state.values())
        if not ok:
            raise CfdesignError(f"{where}: lock must be {{'on': {{sensor: ticks}}, 'off': {{sensor: ticks}}}} (ticks "
                                f"whole numbers >= 0) of {', '.join(self.names) or 'no sensor'}, got {state!r:.80}")
        self.S[self.n + 1] = 0
        self._aged(state)

    def _aged(self, ages):
        """The ticks held set from ``ages`` (:meth:`state`'s form) before the next step."""
        now = self.tick()
        for key, held in (("on", self.ON), ("off", self.last)):
            held[:] = [now - int(ages[key][n]) if n in ages[key] else None for n in self.names]
        for i, name in enumerate(self.names):
            before = [t for t in (self.ON[i], self.last[i]) if t is not None]
            known = self.enabled and before and name in self.warned
            self.soon[i] = max(before) + self.half[i] if known else -math.inf

    def ran(self, before: dict, ticks: int, read: dict):
        """Go on after steps of the batch path (``Runtime.run``, which sets the phase as it goes).

        Parameters
        ----------
        before : dict
            :meth:`state` before them.
        ticks : int
            The steps run.
        read : dict
            ``{i: (ticks before the next step of its last reading with a gain, of its last without)}``
            (None where it had no such reading in them), for each sensor read in them.
        """
        aged = {key: {n: t + ticks for n, t in d.items()} for key, d in before.items()}
        for i, (on, off) in read.items():  # as the steps keep them: a reading without a gain clears "on"
            name = self.names[i]
            if off is not None:
                aged["off"][name] = off
            if on is not None and (off is None or on < off):
                aged["on"][name] = on
            else:
                aged["on"].pop(name, None)
        self._aged(aged)
