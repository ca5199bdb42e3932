r"""The Python runtime: run a designed filter (a GainTable) on sensor readings.

numpy only; scipy.signal.lfilter is imported lazily by the single-rate batch path.  Every phase
``k`` (base-rate steps modulo the period) runs the one recursion of :mod:`cfdesign.linear`,

.. math::

    e = y - H x,\qquad \hat x^+ = x + L_k e,\qquad x \leftarrow F x + B u + K_{p,k} e,

where ``Kp`` and ``L`` are the table's gain in predictor and update form
(:func:`cfdesign.linear.gain_pair`).  The estimate returned is the table's declared output:
the estimate ``x+`` after this step's readings (``output='posterior'``, the default of
designed tables) or the one-step prediction ``x`` (``output='prior'``); either can be asked
for, whatever the gain form.  At phases where nothing is read the two are equal.

Missing readings (a NaN, or a sensor left out of ``step``): a missing measurement
contributes nothing at that step (its innovation is zero); a missing input holds the last
input received (zero before the first).  A measurement the table's schedule does not read
at this phase has no gain there: :meth:`Runtime.step` first locks the phase to it when one
shift of the whole schedule places it (:mod:`cfdesign.runtime.lock`); one still without a gain
has no effect, and is counted and warned of.  Angle tables (``wrap_angle``) wrap every
innovation of an angle sensor and the estimate to (-pi, pi] with
:func:`cfdesign.linear.wrap`, so a compass crossing +-180 deg does not jolt the estimate.
"""

from __future__ import annotations

import hashlib
import json
import numbers

import numpy as np

from .. import linear
from ..errors import CfdesignError
from ..linear import wrap, wrap_scalar

__all__ = ["Runtime", "wrap", "usable", "held", "state_vector", "filter_sha256", "require_stable", "READING_LIMIT",
           "STATE_LIMIT", "UNSTABLE_RTOL"]

#: block length of the vectorised batch path (a multiple of the period is used)
_BLOCK = 64
#: samples per piece of the batch paths, each run relative to its own reference (the
#: rounding of the IIR path's direct form scales with the estimate's excursion over a piece)
_PIECE = 1 << 12
#: states up to this size run the IIR and long-block batch paths; larger ones step block by block
_SMALL = 12
#: stretches shorter than this many blocks run step by step: lifting a block of L phases costs
#: about what 8 L compiled steps do (a 3-state table of period 100, measured)
_LOOP_BLOCKS = 6
#: :meth:`Runtime.run` runs a stretch between readings the lock may place on the fixed schedule when it
#: is this many periods long or more, else steps it (a 3-state table: the vectorised paths' set-up,
#: about 15 us a phase, pays off from some 40 periods on, 50 and 100 ticks)
_FIXED_PERIODS = 40
#: at most this many readings the lock may place, close together, stepped in one piece of
#: :meth:`Runtime.run` (after one that did not move the phase: a sensor at an offset of its own)
_CHAIN = 32
#: "every reading present" for the IIR path's innovation check
_ALL = object()
_NAN = float("nan")
#: readings larger than this in magnitude (SI units: rad, m, rad/s, m/s^2, ...) are not
#: physical: they are treated as missing and counted, like inf, so that they cannot overflow
#: the state
READING_LIMIT = 1e12
#: how to get a discrete table from a continuous one (the messages that refuse one)
DISCRETE_HINT = ("discretise it at the sensors' rate: cfdesign discretize TABLE --rate-hz R; or design a "
                 "discrete structure: dckf3, position, or cf2/cf3/cfn with discrete = true")
#: a table whose error dynamics grow by more than ``1 + UNSTABLE_RTOL`` a period (the spectral
#: radius of :func:`cfdesign.linear.loop_radius`) is refused: its estimates diverge.  A radius of
#: 1 (dead reckoning, a state no sensor corrects) runs
UNSTABLE_RTOL = 1e-9
#: a state :meth:`Runtime.restore` accepts is at most this in magnitude (the limit of a table's
#: entries, :data:`cfdesign.gains.MAX_ENTRY`): one step from it cannot overflow
STATE_LIMIT = 1e150


def require_stable(table) -> None:
    """Refuse a discrete table whose filter diverges: what runs it (:class:`Runtime`, the
    generated C) would give estimates that grow whatever the readings.

    Parameters
    ----------
    table : GainTable
        A discrete table (predictor or filter gains).

    Raises
    ------
    CfdesignError
        Its error dynamics grow by more than ``1 + UNSTABLE_RTOL`` a period (the spectral radius
        of :func:`cfdesign.linear.loop_radius`); a radius of 1 (a state no sensor corrects) passes.
    """
    radius = linear.loop_radius(table.F, table.H, table.K, table.gain_form)
    if not radius <= 1.0 + UNSTABLE_RTOL:
        raise CfdesignError(f"{table.name}: the filter is unstable (its error dynamics grow by {radius:.6g} a "
                            f"period, above 1): its estimates diverge whatever the readings (an edited gain or "
                            f"model?); cfdesign verify names the check")


def filter_sha256(table) -> str:
    """SHA-256 of what a running filter's state means: the same for two tables that run alike.

    It covers the model ``F, B, H``, the gain of every phase and its form, the schedule, the
    sample time, the angle wrap, the sensors (names, roles, orders) and the state names; not
    the table's name, provenance, covariances or declared output (a state is the same for
    either output).  :meth:`cfdesign.runtime.Runtime.state` records it so that
    :meth:`cfdesign.runtime.Runtime.restore` refuses a state taken from another filter, and the
    generated C states it in its header comment.

    Parameters
    ----------
    table : GainTable
        A gain table.

    Returns
    -------
    str
        64 hexadecimal digits.

    Examples
    --------
    >>> import cfdesign
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> len(filter_sha256(table)), filter_sha256(table) == filter_sha256(cfdesign.GainTable.from_dict(table.to_dict()))
    (64, True)
    """
    def floats(a):
        return [float(v).hex() for v in np.asarray(a, dtype=float).reshape(-1)]

    what = {"domain": table.domain, "gain_form": table.gain_form, "wrap_angle": bool(table.wrap_angle),
            "sample_time_s": None if table.sample_time_s is None else float(table.sample_time_s).hex(),
            "shapes": [list(np.shape(table.F)), list(np.shape(table.B)), list(np.shape(table.H))],
            "F": floats(table.F), "B": floats(table.B), "H": floats(table.H), "K": [floats(K) for K in table.K],
            "schedule": [list(rows) for rows in table.schedule.active],
            "sensors": [[s.name, s.role, s.index, s.order] for s in table.sensors], "states": list(table.states)}
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()


def real_array(value, name) -> np.ndarray:
    """``value`` as a float array, or :class:`~cfdesign.errors.CfdesignError` naming ``name``.

    Real numbers only (integer and float arrays, and lists of Python numbers): text, None,
    complex values (``astype(float)`` dropped the imaginary part with a warning), ragged lists
    and integers beyond a double are named, not a ValueError, TypeError or OverflowError.  Bools
    are refused too: a mask passed where readings belong ran as readings of 0 and 1.  The
    masked entries of a ``numpy.ma`` array are missing (NaN): ``asarray`` kept the values under
    the mask, so a glitch masked by the caller was run.
    """
    try:
        if isinstance(value, np.ma.MaskedArray) and value.dtype.kind in "iuf":
            value = value.astype(float).filled(np.nan)
        a = np.asarray(value)
        if a.dtype.kind == "O":  # Python objects: real numbers of mixed types, or anything (None: refused,
            # as step refuses it, not NaN as astype makes it)
            real = all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in a.flat)
            a = a.astype(float) if real else None
    except (TypeError, ValueError, OverflowError):
        a = None
    if a is None or a.dtype.kind not in "iuf":
        shown = " ".join(repr(value).split())  # one line (numpy's repr breaks long arrays over lines)
        raise CfdesignError(f"{name}: real numbers are needed, got {shown[:80]}{'...' if len(shown) > 80 else ''}")
    return a.astype(float, copy=False)


def state_vector(value, name, size) -> np.ndarray:
    """``value`` as ``size`` floats fit to be a runtime's state, or
    :class:`~cfdesign.errors.CfdesignError` naming ``name``.

    Real numbers only (integer and float arrays, lists of Python numbers), exactly ``size``
    of them, each finite and at most :data:`~cfdesign.runtime.filter.STATE_LIMIT` in magnitude
    (one step from such a state cannot overflow).  Used by ``Runtime(x0=...)``,
    :meth:`cfdesign.runtime.Runtime.restore`, the ``x`` and ``u_last`` setters and
    :class:`~cfdesign.runtime.arrivals.ArrivalKalman`, so that no way in can leave a NaN, an inf
    or an overflowing value in the state.

    Parameters
    ----------
    value : array_like
        The proposed values.
    name : str
        What they are (``x0``, ``x``, ``u_last``), for the message.
    size : int
        How many values the state holds.

    Returns
    -------
    ndarray, shape (size,)
        The values as floats.

    Raises
    ------
    CfdesignError
        Not real numbers, another count, or a value not finite or beyond the limit.
    """
    a = real_array(value, name)
    if a.shape != (size,):
        raise CfdesignError(f"{name} must be {size} finite numbers, got shape {a.shape}")
    if not np.all(np.abs(a) <= STATE_LIMIT):
        raise CfdesignError(f"{name} must be finite numbers of magnitude at most {STATE_LIMIT:g}, got "
                            f"{' '.join(repr(a.tolist()).split())[:80]}")
    return a


def usable(a) -> np.ndarray:
    """Where a reading can be used: finite and within :data:`~cfdesign.runtime.filter.READING_LIMIT`.

    Parameters
    ----------
    a : array_like
        Readings (any shape), in SI units.

    Returns
    -------
    ndarray of bool
        Same shape as ``a``.

    Examples
    --------
    >>> usable([0.1, float("nan"), float("inf"), 2e12]).tolist()
    [True, False, False, False]
    """
    a = np.asarray(a, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(a) & (np.abs(a) <= READING_LIMIT)


def held(u, bad, u_last) -> np.ndarray:
    """Inputs with the values marked ``bad`` replaced by the last good one of their column.

    Parameters
    ----------
    u : ndarray, shape (N, p)
        Inputs per step.
    bad : ndarray of bool, shape (N, p)
        Values not to use (missing or rejected).
    u_last : ndarray, shape (p,)
        The inputs held before the first step.

    Returns
    -------
    ndarray, shape (N, p)
        ``u`` with the bad values replaced (a copy).
    """
    u = np.vstack([u_last[None, :], u])
    good = np.concatenate([np.ones((1, u.shape[1]), dtype=bool), ~bad])
    idx = np.maximum.accumulate(np.where(good, np.arange(len(u))[:, None], 0), axis=0)
    return np.take_along_axis(u, idx, axis=0)[1:]


class Runtime:
    """A running filter built from a :class:`~cfdesign.gains.GainTable`.

    Every step runs the recursion of the module docstring with the table's gain for the
    current phase; the estimate is state 0 (the common quantity, in its unit: rad for a
    heading, m for a position).  numpy only (scipy's ``lfilter`` in the single-rate batch path).

    Parameters
    ----------
    table : GainTable
        A discrete table (``domain = 'z'``).
    x0 : array_like, optional
        Initial state, shape (n,), in the units of the table's ``states`` (default zeros).
    output : {'prior', 'posterior'}, optional
        The estimate returned: the one-step prediction or the estimate after this step's
        readings.  Default: the table's declared ``output``
        (the posterior for tables designed by cfdesign).
    lock : bool, optional
        Lock the phase of :meth:`step` to the readings as they arrive (default True): a usable
        reading of a multirate table's slow sensor at a phase where the table has no gain for it
        moves the phase so that it has one, when one shift of the whole schedule puts it on its
        phases and keeps every sensor whose last reading had a gain on theirs (one not read for
        :data:`~cfdesign.runtime.lock.LOCK_STALE_READINGS` of its spacings no longer counts)
        (:func:`cfdesign.timing.rotation`, the rule :func:`cfdesign.logs.run_log` applies per
        stretch of a log).  A 1 Hz GPS first seen at tick 17 of a table that reads it at phase 0
        moves the phase to 0 there.  A reading no shift places (sensors at offsets of their own, a
        sensor faster than designed) is counted in :attr:`counts` and warned of once per runtime
        and sensor (a :class:`UserWarning` naming
        :class:`~cfdesign.runtime.arrivals.ArrivalKalman`, which uses every reading as it
        arrives).  ``lock=False`` keeps the fixed schedule, as the generated C does (its
        manual lock is ``st.phase = <PREFIX>_PHASE_<NAME>``); readings off it are still counted
        and warned of.  Phase-aligned readings run alike either way.  :meth:`run` gives what
        stepping the same rows gives, the lock included (a log with time stamps:
        :func:`cfdesign.logs.run_log`).
    warn : bool, optional
        Warn of readings without a gain as above (default True); False for a caller that reports
        :attr:`counts` itself (:func:`cfdesign.logs.run_log` names them in its notes and
        ``LogResult.unused``).  They are counted either way.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        A continuous-time table, an unstable one (error dynamics growing by more than
        ``1 + UNSTABLE_RTOL`` a period), or a gain the requested output cannot be formed from
        (a predictor gain with a singular ``F`` asked for the posterior).

    Examples
    --------
    >>> import cfdesign, numpy as np
    >>> from cfdesign.runtime import Runtime
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> rt = Runtime(table)
    >>> rt.inputs, rt.measurements
    (['odometry_rate'], ['gyro_heading', 'compass'])
    >>> round(rt.step(odometry_rate=0.0, gyro_heading=0.1, compass=0.12), 6)   # one sample (rad)
    0.049722
    >>> est = rt.run({"odometry_rate": np.zeros(50), "gyro_heading": np.full(50, 0.1),
    ...               "compass": np.full(50, 0.1)})                               # whole arrays
    >>> est.shape, round(float(est[-1]), 6)
    ((50,), 0.1)
    """

    def __init__(self, table, x0=None, output=None, lock=True, warn=True):
        from ..gains import require_table  # numpy only, as this module

        require_table(table, "Runtime")
        if table.domain != "z":
            raise CfdesignError(f"{table.name} is a continuous-time table; the runtime runs discrete tables "
                                f"({DISCRETE_HINT})")
        self.table = table
        self.F, self.B, self.H = (np.array(m, dtype=float) for m in (table.F, table.B, table.H))
        self.n, self.period = self.F.shape[0], table.period
        self.output = table.output if output is None else output
        try:
            self._phases = [linear.realisation(self.F, self.B, self.H, K, table.gain_form, self.output)
                            for K in table.K]
        except ValueError as exc:
            raise CfdesignError(f"{table.name}: {exc}") from None
        require_stable(table)
        pairs = [linear.gain_pair(self.F, K, table.gain_form) for K in table.K]
        self.Kp = [kp for kp, _ in pairs]
        self.L = [upd if upd is not None else np.zeros_like(kp) for kp, upd in pairs]
        self.posterior = self.output == "posterior"
        self.inputs = table.sensor_names("input")
        self.measurements = table.sensor_names("measurement")
        self._active = table.schedule.mask()
        self._wrap_rows = np.array([bool(table.wrap_angle) and s.order == 0 for s in table.measurements],
                                   dtype=bool)
        self._sha256 = filter_sha256(table)
        #: the batch path's reference shift: ``(v, s)``, or None (see ``_offset_direction``)
        self._shift = _offset_direction(self.F, self.B, self.H, table)
        try:
            self._x0 = np.zeros(self.n) if x0 is None else state_vector(x0, "x0", self.n)
        except CfdesignError as exc:
            raise CfdesignError(f"{table.name}: {exc}") from None
        for name, flag in (("lock", lock), ("warn", warn)):
            if not isinstance(flag, bool):
                raise CfdesignError(f"{name} must be True or False, got {flag!r}")
        from .lock import PhaseLock
        from .step import compile_step

        self._S = [0.0] * self.n + [0, 0]                     # the state floats, the phase, the periods run
        self._U = [0.0] * len(self.inputs)                    # the last inputs received
        self._rej = [0] * (len(self.inputs) + len(self.measurements))  # rejected: inputs, measurements
        self._uns = [0] * len(self.measurements)              # readings at unscheduled phases
        self._on = [None] * len(self.measurements)            # tick of the last reading if it had a gain
        self._lock = PhaseLock(table, self._S, self._uns, self._on, lock, warn)
        self.lock = self._lock.enabled
        self.step, self._step_values, self.step_source = compile_step(
            table, self.output, READING_LIMIT, self._S, self._U, self._rej, self._uns, self._unknown, self._lock)
        self.reset()

    def _unknown(self, readings):
        raise CfdesignError(f"unknown sensor(s) {', '.join(sorted(readings))}; {self.table.name} reads "
                            f"{', '.join(self.inputs + self.measurements)}")

    def __repr__(self) -> str:
        """The table run, the output returned and where the filter stands (its phase), in one line."""
        return (f"<Runtime of {self.table.name!r}: output {self.output}, phase {int(self.phase)} of {self.period}, "
                f"inputs {', '.join(self.inputs) or 'none'}; measurements {', '.join(self.measurements) or 'none'}>")

    # ------------------------------------------------------------------ state
    def reset(self):
        """Back to the initial state, phase 0, no input received, counts cleared, no arrival seen
        by the lock (its warnings are still given once per runtime)."""
        self._S[:] = [*map(float, self._x0), 0, 0]
        self._lock.reset()
        self._U[:] = [0.0] * len(self.inputs)
        self._rej[:] = [0] * len(self._rej)
        self._uns[:] = [0] * len(self._uns)

    @property
    def x(self) -> np.ndarray:
        """The state before the next step (a copy; assign to change it: ``n`` finite numbers of
        magnitude at most :data:`~cfdesign.runtime.filter.STATE_LIMIT`, else a
        :class:`~cfdesign.errors.CfdesignError` and no change)."""
        return np.array(self._S[: self.n])

    @x.setter
    def x(self, value):
        self._S[: self.n] = state_vector(value, "x", self.n).tolist()

    @property
    def phase(self) -> int:
        """The phase of the next step in the table's period (assign an integer: taken modulo the
        period)."""
        return self._S[self.n]

    @phase.setter
    def phase(self, value):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise CfdesignError(f"phase must be an integer, got {value!r}")
        new = int(value) % self.period
        self._lock.moved(self._S[self.n], new)
        self._S[self.n] = new

    @property
    def u_last(self) -> np.ndarray:
        """The last input received of each input sensor (held while one is missing; assign finite
        numbers, as for ``x``)."""
        return np.array(self._U)

    @u_last.setter
    def u_last(self, value):
        self._U[:] = state_vector(value, "u_last", len(self.inputs)).tolist()

    @property
    def counts(self) -> dict:
        """Readings not used, by kind and sensor: ``rejected`` (inf, or beyond
        :data:`~cfdesign.runtime.filter.READING_LIMIT`: treated as missing) and ``unscheduled``
        (a measurement at a phase the schedule does not read: it has no gain)."""
        names = self.inputs + self.measurements
        out = {}
        rej = {names[i]: c for i, c in enumerate(self._rej) if c}
        uns = {self.measurements[i]: c for i, c in enumerate(self._uns) if c}
        if rej:
            out["rejected"] = rej
        if uns:
            out["unscheduled"] = uns
        return out

    @counts.setter
    def counts(self, value):
        if value:
            raise CfdesignError("counts can only be cleared (assign {})")
        self._rej[:] = [0] * len(self._rej)
        self._uns[:] = [0] * len(self._uns)

    def state(self) -> dict:
        """A JSON-ready snapshot of the running filter, for :meth:`restore`.

        Returns
        -------
        dict
            ``{"x": list of float, "phase": int, "u_last": list of float, "lock": dict,
            "table": str, "filter_sha256": str}``: the state before the next step, the phase of the
            next step, the inputs held, what the phase lock has seen (``{"on": {sensor: ticks since
            its last reading, which had a gain}, "off": {sensor: ticks since its last reading,
            which had none}}``),
            and the table it belongs to (its name, and
            :func:`~cfdesign.runtime.filter.filter_sha256`, which :meth:`restore` checks).
        """
        return {"x": self.x.tolist(), "phase": int(self.phase), "u_last": self.u_last.tolist(),
                "lock": self._lock.state(), "table": self.table.name, "filter_sha256": self._sha256}

    def restore(self, state: dict):
        """Continue from a snapshot taken with :meth:`state`.

        A run split at a snapshot gives the same estimates as one run.

        Parameters
        ----------
        state : dict
            A snapshot of :meth:`state` (of a runtime of a table that runs the same filter:
            the same :func:`~cfdesign.runtime.filter.filter_sha256`, whatever its name or
            output).  A snapshot without ``filter_sha256`` (written by an earlier cfdesign) is
            checked by its sizes only; one without ``lock`` restarts the lock (no arrival seen).

        Raises
        ------
        CfdesignError
            The snapshot was taken from another filter (its ``filter_sha256`` differs: the
            message names both tables), does not fit this table (keys, sizes, a phase outside the
            period) or holds a value that is not a finite number (or beyond
            :data:`~cfdesign.runtime.filter.STATE_LIMIT`); the runtime is left unchanged.
        """
        x, phase, u_last = _snapshot(state, self.n, self.period, len(self.inputs), self.table.name, self._sha256)
        before = (self._S[self.n:], list(self._on), list(self._lock.last))
        self._S[self.n] = phase
        try:
            self._lock.restore(state.get("lock"), f"state does not fit {self.table.name}")
        except CfdesignError:
            self._S[self.n:], self._on[:], self._lock.last[:] = before
            raise
        self.x, self.u_last = x, u_last

    # ------------------------------------------------------------------ streaming
    def step(self, **readings) -> float:
        """Advance one base-rate step with this step's readings; returns the estimate.

        Parameters
        ----------
        **readings : float
            ``sensor=value`` in the sensor's units (rad, rad/s, m, m/s^2, ...); a sensor left
            out or given as NaN has no reading this step (a missing input holds its last
            value), an inf or a value beyond :data:`~cfdesign.runtime.filter.READING_LIMIT` is treated as missing and
            counted in :attr:`counts`.

        Returns
        -------
        float
            The estimate of the common quantity (state 0): after this step's readings, or
            the prediction (``output``).

        Raises
        ------
        CfdesignError
            A sensor the table does not have (the message names those it has), or a reading
            that is not a real number (text, None, a complex number, an array); raised before
            the step changes anything.

        Warns
        -----
        UserWarning
            Once per runtime and sensor, at its first usable reading that has no gain at the
            phase reached (after the lock, see ``lock``): the reading is not used; the message
            names the sensor, the phase and :class:`~cfdesign.runtime.arrivals.ArrivalKalman`.

        Notes
        -----
        Straight-line Python specialised to the table when the runtime is built
        (:mod:`cfdesign.runtime.step`, source in ``step_source``): about a microsecond a
        step for the three-sensor heading filter.  A reading at a phase without a gain calls
        the lock (:class:`~cfdesign.runtime.lock.PhaseLock`), which may move :attr:`phase` and run
        the step again there; phase-aligned readings never do, so they cost and give what
        ``lock=False`` and the generated C do.  A repeat of a value held and given every tick,
        refused by the lock as faster than designed once warned of, the step counts itself by one
        comparison of ticks, as the lock would.
        """
        raise NotImplementedError  # replaced per table in __init__ (cfdesign.runtime.step)

    def step_values(self, *values) -> float:
        """:meth:`step` with the readings given in order: the fastest call.

        Parameters
        ----------
        *values : float
            Inputs then measurements, in the order ``inputs`` and ``measurements`` list
            them, in the sensors' units; NaN for no reading.

        Returns
        -------
        float
            The estimate of the common quantity (state 0).

        Raises
        ------
        CfdesignError
            A reading that is not a real number, or a count of readings other than the table's
            sensors; nothing has changed.
        """
        try:
            return self._step_values(*values)
        except TypeError:  # Python's message for a wrong count names no sensor
            names = self.inputs + self.measurements
            if len(values) != len(names):
                raise CfdesignError(f"step_values takes {len(names)} readings ({', '.join(names)}), got "
                                    f"{len(values)}") from None
            raise

    def _advance(self, u, y) -> np.ndarray:
        """One step of the recursion in the module docstring; returns the output state."""
        x, k = self.x, self.phase
        e = self._innovations(x, y, k)
        out = x + self.L[k] @ e if self.posterior else x.copy()
        x = self.F @ x + self.B @ u + self.Kp[k] @ e
        if self.table.wrap_angle:
            x[0], out[0] = wrap_scalar(x[0]), wrap_scalar(out[0])
        self.x, self.phase = x, (k + 1) % self.period
        return out

    def _innovations(self, x, y, phases):
        """``e = y - H x`` for the readings taken at ``phases`` (scheduled and finite), zero for
        the rest, angle rows wrapped; ``x`` and ``y`` are one step's or a stack of steps'."""
        seen = self._active[phases] & np.isfinite(y)
        e = np.where(seen, y - x @ self.H.T, 0.0)
        return np.where(self._wrap_rows, wrap(e), e) if self._wrap_rows.any() else e

    # ------------------------------------------------------------------ batch
    def run(self, readings: dict, *, states: bool = False):
        """Run on whole arrays; the state carries over between calls.

        Gives what stepping the same rows through :meth:`step` gives, the phase lock included
        (``lock``): the estimates, the states, :attr:`counts`, the warnings and :meth:`state`
        afterwards.

        Where every usable reading is on the schedule from the current phase (the common case)
        the work is vectorised (the lifted form over blocks, or the sensors' IIR bands for a
        single-rate table) over every stretch where each scheduled measurement is present; the
        few steps where one is missing run through :meth:`step`'s recursion.  Both give the same
        numbers.  A usable reading off that schedule that the lock may place is stepped through
        :meth:`step` (with the rows before it, when fewer than some 40 periods), which locks the
        phase to it where one shift places it; the rows after it go on as above from the phase
        reached, up to the next reading off the schedule from there.  So once the lock has settled
        the rest of the arrays runs vectorised again: 200,000 rows of the 100/10/1 Hz heading
        filter with every slow sensor 37 ticks late take 0.065 s, aligned ones 0.057 s (every row
        stepped: 0.15 s, about 0.75 us a row; sensors at offsets of their own, which the lock keeps
        refusing, are stepped throughout).  Readings off the schedule that the lock refuses whatever
        the phase (with ``lock=False``; or faster than designed: a value held and repeated every
        tick, each repeat less than half the sensor's spacing after the last) stay on the
        vectorised paths, counted and warned of as :meth:`step` does (the steps would refuse them
        one by one, at 0.75 us a step against 0.65).

        Parameters
        ----------
        readings : dict
            ``{sensor: (N,) array}`` for every sensor of the table, in the sensors' units (other
            keys, such as a DataFrame's time column, are not read).  NaN
            marks a missing sample (a slow sensor's column is NaN between its readings); inf and
            readings beyond :data:`~cfdesign.runtime.filter.READING_LIMIT` are treated as missing and counted in
            :attr:`counts` (``rejected``); readings at phases the schedule does not read have no
            gain and are counted (``unscheduled``).  Missing inputs hold their last value.
        states : bool
            Also return every output state.

        Returns
        -------
        estimates : ndarray, shape (N,)
            The estimate of the common quantity at every step (after the step's readings, or the
            prediction: ``output``).
        x : ndarray, shape (N, n)
            Only with ``states=True``: the output states (the posterior ``x+[k]`` or the prior
            ``x[k]``), columns named by the table's ``states``.

        Raises
        ------
        CfdesignError
            ``readings`` is not a dict (or a DataFrame), a sensor is missing from it, an array is
            not one real number per step, or the arrays differ in length.

        Warns
        -----
        UserWarning
            A usable reading at a phase without a gain (once per runtime and sensor; counted).
        """
        return self._run(readings, states)

    def _run(self, readings, states):
        """:meth:`run`: each reading the lock may place stepped (:class:`_Placeable`, found from
        the phase reached), the stretches between on the fixed schedule."""
        cols = self._columns(readings)
        N = len(cols[0])
        if not states and self.period == 1 and self.n <= _SMALL and N and all(map(_clean, cols)):
            before = self._lock.state()
            out = self._run_clean(cols)  # the common case: every reading present, single rate
            if out is not None:
                self._lock.ran(before, N, {})
                return out
        u, y = self._split(cols)
        if N == 0:
            return (np.empty(0), np.empty((0, self.n))) if states else np.empty(0)
        u = self._held_inputs(u)
        finite = usable(y)
        self._count("rejected", ~finite & ~np.isnan(y))
        y = np.where(finite, y, np.nan)
        pieces, start, budget = [], 0, 1
        placeable = _Placeable.of(self, finite)
        while start < N:  # the fixed schedule up to the next reading the lock may place, that one stepped
            f = placeable.next(start, self.phase) if placeable is not None else N
            if f - start >= _FIXED_PERIODS * self.period or f == N:
                pieces.append(self._run_fixed(u[start:f], y[start:f], states))
                start = f
            if f < N:  # up to `budget` such readings close together stepped at once, while the lock refuses them
                stop, key = placeable.chain(f, budget, _FIXED_PERIODS * self.period), (self.phase - start) % self.period
                pieces.append(self._run_stepped(u[start:stop + 1], y[start:stop + 1], states))
                start = stop + 1
                budget = min(2 * budget, _CHAIN) if (self.phase - start) % self.period == key else 1
        return _joined(pieces, states)

    def _run_fixed(self, u, y, states):
        """Rows without a reading the lock may place (inputs held, readings usable or NaN): the
        fixed schedule, the readings off it counted and warned of as the steps would; vectorised
        over every stretch where each scheduled measurement is present, step by step where one is
        missing.  The lock's ticks go on after them (:meth:`PhaseLock.ran
        <cfdesign.runtime.lock.PhaseLock.ran>`)."""
        N, finite = len(u), ~np.isnan(y)
        before = self._lock.state()
        active = self._active[(self.phase + np.arange(N)) % self.period]
        read = self._unscheduled(finite, active)
        y = np.where(active, y, np.nan)  # NaN: not read at this tick
        irregular = np.flatnonzero((active & ~finite).any(axis=1))
        if len(irregular) > max(16, N // 50):  # gaps everywhere: one loop
            pieces = [self._run_loop(u, y, states)]
        else:
            pieces, start = [], 0
            for k in [*irregular, N]:
                if k > start:
                    pieces.append(self._run_regular(u[start:k], y[start:k], states))
                if k < N:
                    pieces.append(self._run_loop(u[k:k + 1], y[k:k + 1], states))
                start = k + 1
        self._lock.ran(before, N, read)
        return _joined(pieces, states)

    def _run_clean(self, cols):
        """Single-rate, every reading present and usable: the sensors' IIR bands on the columns
        as they are (angle columns unwrapped), no copies into matrices; None when the
        IIR path does not apply or an angle innovation is not within pi (then the general path)."""
        lti = _LtiBands.of(self)
        if lti is None:
            return None
        p = len(self.inputs)
        cols = list(cols)
        for i in np.flatnonzero(self._wrap_rows):
            cols[p + i] = _unwrap(cols[p + i], float(self.H[i] @ self.x))
        return lti.run(self, cols, _ALL if self._wrap_rows.any() else None)

    def _run_regular(self, u, y, states):
        """A stretch where every scheduled measurement is present (NaN where it is not read)
        and the inputs are held: angle readings unwrapped, then the vectorised paths.

        Angle tables: the linear paths run on the unwrapped readings, which is the recursion
        (with its innovations wrapped) only while every angle innovation stays within pi; the
        batch paths check that at every reading, and where it does not hold (a heading that
        turns more than pi between two readings of a slow sensor, or before its first one) the
        stretch runs step by step instead."""
        read = ~np.isnan(y) if self._wrap_rows.any() else None
        lti = _LtiBands.of(self) if self.period == 1 and not states and self.n <= _SMALL else None
        if lti is not None:
            unwrapped = np.nan_to_num(self._unwrapped(y), nan=0.0)  # an unread row has no gain: any value does
            out = lti.run(self, [*u.T, *unwrapped.T], read)
            return self._run_loop(u, y, states) if out is None else out
        if self.n <= _SMALL and len(u) < _LOOP_BLOCKS * self._block_length():
            return self._run_loop(u, y, states)  # a short stretch: the lifting would cost more
        # the blocked form piece by piece, each relative to the state it starts from
        # (_run_vectorised) and its angles unwrapped from there; a piece where an angle turns
        # more than pi between readings runs step by step
        M = self._block_length() * max(1, (16 * _PIECE) // self._block_length())
        pieces = []
        for start in range(0, len(u), M):
            at = slice(start, start + M)
            out = self._run_vectorised(u[at], np.nan_to_num(self._unwrapped(y[at]), nan=0.0), states,
                                       None if read is None else read[at])
            pieces.append(self._run_loop(u[at], y[at], states) if out is None else out)
        if len(pieces) == 1:
            return pieces[0]
        if states:
            return np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces])
        return np.concatenate(pieces)

    def _block_length(self) -> int:
        """Samples per block of :meth:`_run_vectorised`: whole periods; long blocks pay off for
        small states only (the lifting costs that many products of n x n matrices)."""
        return self.period * (max(1, _BLOCK // self.period) if self.n <= _SMALL else 1)

    def _held_inputs(self, u):
        """Inputs with NaN or inf replaced by the last good value (``u_last`` before the first)."""
        bad = ~usable(u)
        if not bad.any():
            return u
        self._count("rejected_inputs", bad & ~np.isnan(u))
        return held(u, bad, self.u_last)

    def _unscheduled(self, finite, active) -> dict:
        """Count and warn of the usable readings (``finite``) where ``active`` has no gain, as the
        steps would at a phase that does not move (``lock=False``, a table that never reads the
        sensor, or readings the lock refuses as faster than designed), the warnings in the order
        of their rows.

        Returns
        -------
        dict
            For :meth:`PhaseLock.ran <cfdesign.runtime.lock.PhaseLock.ran>`: ``{i: (ticks before
            the end of its last reading with a gain, of its last without)}`` per sensor read.
        """
        off = finite & ~active
        self._count("unscheduled", off)
        phase, lock = self.phase, self._lock
        gaps = lock.gaps(finite) if self.lock and off.any() else None
        first = {int(i): int(np.argmax(off[:, i])) for i in np.flatnonzero(off.any(axis=0))}
        for i, k in sorted(first.items(), key=lambda item: (item[1], item[0])):
            why = lock.too_soon(i, int(gaps[k, i])) if gaps is not None else lock.fixed()
            lock.warn(i, (phase + k) % self.period, why, stacklevel=6)  # warn, here, _run_fixed, _run, run
        on = finite & active
        return {int(i): tuple(int(np.argmax(m[::-1, i])) + 1 if m[:, i].any() else None for m in (on, off))
                for i in np.flatnonzero(finite.any(axis=0))}

    def _run_stepped(self, u, y, states):
        """:meth:`run` by :meth:`step`, which applies the lock, counts and warns (inputs held and
        readings usable or NaN already); the lock's ticks advance with the steps."""
        lock = self._lock
        lock.stacklevel = 8  # at the caller of run: warn, unscheduled, the step, _run_loop, here, _run, run
        try:
            return self._run_loop(u, y, states)
        finally:
            lock.stacklevel = 4

    def _count(self, what, mask):
        if mask.any():
            per = mask.sum(axis=0)
            if what == "unscheduled":
                target, start = self._uns, 0
            else:
                target, start = self._rej, 0 if what == "rejected_inputs" else len(self.inputs)
            for i, c in enumerate(per):
                target[start + i] += int(c)

    def _columns(self, readings) -> list:
        """One contiguous float array per sensor: inputs (by column of B), then measurements."""
        names = self.inputs + self.measurements
        if isinstance(readings, (str, bytes)) or not (hasattr(readings, "__contains__")
                                                      and hasattr(readings, "__getitem__")):
            # None was a TypeError ('argument of type NoneType is not iterable')
            raise CfdesignError(f"readings must be a dict (or a DataFrame) of {', '.join(names)}, got "
                                f"{type(readings).__name__}")
        missing = [n for n in names if n not in readings]
        if missing:
            raise CfdesignError(f"no readings for {', '.join(missing)} (use NaN for missing samples)"
                                f"{_case_hint(missing, readings)}")
        cols = [real_array(readings[n], n) for n in names]
        flat = [n for n, c in zip(names, cols, strict=True) if sum(d > 1 for d in c.shape) > 1]
        if flat:  # a (3, 3) array was read as nine samples
            raise CfdesignError(f"{flat[0]}: one value per step is needed, got an array of shape "
                                f"{np.shape(readings[flat[0]])}")
        cols = [np.ascontiguousarray(c).reshape(-1) for c in cols]
        if len({len(c) for c in cols}) > 1:
            lengths = ", ".join(f"{n}: {len(c)}" for n, c in zip(names, cols, strict=True))
            raise CfdesignError(f"readings differ in length ({lengths})")
        return cols

    def _split(self, cols):
        N, p = len(cols[0]), len(self.inputs)
        u = np.column_stack(cols[:p]) if p else np.zeros((N, 0))
        y = np.column_stack(cols[p:]) if len(cols) > p else np.zeros((N, 0))
        return u, y

    def _run_loop(self, u, y, states):
        """Step by step (inputs held and readings cleaned already by :meth:`run`)."""
        N = len(u)
        if not states:  # the compiled step, called by map (no frame between it and this one)
            step = self._step_values
            return np.array(list(map(step, *np.hstack([u, y]).T.tolist())), dtype=float).reshape(N)
        # the compiled step advances the state; the output states are formed from the priors it
        # went through afterwards, all at once (:meth:`_advance` a step: 90 us, this: 3 us), at
        # the phases the steps ran at (the lock may move one inside a step: read after it)
        prior, S, n, step = np.empty((N, self.n)), self._S, self.n, self._step_values
        after = [0] * N
        for k, row in enumerate(np.hstack([u, y]).tolist()):
            prior[k] = S[:n]
            step(*row)
            after[k] = S[n]
        phases = (np.array(after, dtype=np.intp) - 1) % self.period
        xs = prior
        if self.posterior:
            e = self._innovations(prior, y, phases)
            xs = prior + np.einsum("kij,kj->ki", np.asarray(self.L)[phases], e)
            if self.table.wrap_angle:
                xs[:, 0] = wrap(xs[:, 0])
        return xs[:, 0].copy(), xs

    def _run_vectorised(self, u, y, states, read=None):
        """Blocked form of the recursion: block-boundary states by a doubling scan
        (:func:`_boundary_states`) of the lifted system ``x[(p+1)L] = A^L x[pL] + c[p]``, then
        the ``L`` phases of every block at once, vectorised over the blocks (``L`` a multiple of
        the period).  The readings of the quantity and the state run relative to the state's
        quantity at the start (the offset direction of ``_offset_direction``), so the rounding
        scales with their spread over the stretch, not with their size.

        ``read`` (angle tables): where the angle readings are; returns None, the runtime
        unchanged, when an angle innovation is not within pi there (:meth:`_run_regular`)."""
        N = len(u)
        L = self._block_length()
        P = -(-N // L)
        pad = P * L - N
        phases = [self._phases[(self.phase + j) % self.period] for j in range(L)]
        W = np.concatenate([np.hstack([u, y]), np.zeros((pad, u.shape[1] + y.shape[1]))])
        x0 = self.x
        if self._shift is not None:  # relative to the state's quantity: rounding of the spread, not the size
            r = float(x0[0])
            v, s = self._shift
            W -= r * s
            x0 -= r * v
        W = W.reshape(P, L, -1)
        Phi, C = self._lift([ph.A for ph in phases], [ph.G for ph in phases], W)
        X = _boundary_states(Phi, C, x0)  # (P, n): x at the start of every block
        xs, last = np.empty((P, L, self.n)), None
        angle_rows = np.flatnonzero(self._wrap_rows) if read is not None else ()
        if len(angle_rows):
            read = np.concatenate([read, np.zeros((pad, read.shape[1]), dtype=bool)]).reshape(P, L, -1)
        p = u.shape[1]
        for j, ph in enumerate(phases):
            for i in angle_rows:  # the prior at this phase of every block: each innovation within pi?
                at = read[:, j, i]
                if at.any() and np.any(np.abs(W[at, j, p + i] - X[at] @ self.H[i]) >= np.pi):
                    return None
            if j == (N - 1) % L:
                last = X[-1].copy()  # the state before the last sample
            xs[:, j] = X @ ph.C.T + W[:, j] @ ph.D.T if self.posterior else X
            X = X @ ph.A.T + W[:, j] @ ph.G.T
        xs = xs.reshape(-1, self.n)[:N]
        if self._shift is not None:
            xs += r * v
            last += r * v
        est = xs[:, 0].copy()
        self._finish(last, u[-1], y[-1], N)
        if self.table.wrap_angle:
            est, xs[:, 0] = wrap(est), wrap(xs[:, 0])
        return (est, xs) if states else est

    def _finish(self, x_last, u_last, y_last, N):
        """State after the batch: one more exact step from the last stored state."""
        self.x, self.phase = x_last.copy(), (self.phase + N - 1) % self.period
        self._advance(u_last, y_last)
        self.u_last = u_last.copy()

    def _lift(self, A, G, W):
        """``Phi = A[L-1]...A[0]`` and ``c[p] = sum_j A[L-1]...A[j+1] G[j] w[pL+j]``."""
        L = len(A)
        M = [None] * L
        acc = np.eye(self.n)
        for j in reversed(range(L)):
            M[j] = acc @ G[j]
            acc = acc @ A[j]
        return acc, np.einsum("jnq,pjq->pn", np.array(M), W)

    def _unwrapped(self, y):
        """Angle readings (NaN where none) made continuous over the readings present and the
        first brought within pi of the current estimate, so that the linear batch paths see no
        2 pi jumps.  Right when consecutive readings differ by less than pi; where they do not,
        :meth:`_run_vectorised` finds an innovation beyond pi and the stretch runs step by step."""
        if not self._wrap_rows.any():
            return y
        y = y.copy()
        for i in np.flatnonzero(self._wrap_rows):
            seen = np.flatnonzero(~np.isnan(y[:, i]))
            if seen.size:
                y[seen, i] = _unwrap(y[seen, i], float(self.H[i] @ self.x))
        return y


class _Placeable:
    """The usable readings of a :meth:`Runtime.run` call that the lock may place: those of sensors
    some phase does not read, less those it refuses as faster than designed whatever the phase
    (:meth:`PhaseLock.faster <cfdesign.runtime.lock.PhaseLock.faster>`, the first test of the rule:
    it holds from the call's start, the gaps between readings not moving with the phase).  Which
    of them are off the schedule depends on the phase only through ``key``, the phase at row 0
    given where the phase stands at a row (``(phase - row) % period``), which moves only when the
    lock moves the phase; :meth:`next` scans from a row in windows that double, and keeps the
    readings found off the schedule for as long as the key holds (a sensor refused at every
    reading, at an offset of its own, is found once per window, not once per reading)."""

    #: readings scanned in the first window of :meth:`next`
    WINDOW = 64

    def __init__(self, rows, cols, active, N):
        self.rows, self.cols, self.active, self.N = rows, cols, active, N
        self.period = len(active)
        self.key, self.hits, self.pos = None, rows[:0], 0

    @classmethod
    def of(cls, rt, finite):
        """The readings of ``finite`` (usable readings, shape (N, m)) that ``rt``'s lock may place,
        or None when none is off the schedule from the current phase (then none ever is: the phase
        does not move), or the lock is off."""
        if not rt.lock:
            return None
        N = len(finite)
        may = finite & ~rt._active.all(axis=0)  # a sensor read at every phase is on the schedule from any
        if not (may & ~rt._active[(rt.phase + np.arange(N)) % rt.period]).any():
            return None
        may &= ~rt._lock.faster(finite)
        rows, cols = np.nonzero(may)  # in the order of the rows
        placeable = cls(rows, cols, rt._active, N)
        return placeable if placeable.next(0, rt.phase) < N else None

    def next(self, start: int, phase: int) -> int:
        """The first row from ``start`` holding a reading off the schedule.

        Parameters
        ----------
        start : int
            The row to look from.
        phase : int
            The phase row ``start`` runs at (the phase not moving before the row found).

        Returns
        -------
        int
            That row, or ``N`` (the rows of the call) when there is none.
        """
        key = (phase - start) % self.period
        if key != self.key:  # the phase moved: scan again from here
            self.key, self.hits, self.pos = key, self.rows[:0], int(np.searchsorted(self.rows, start))
        k = int(np.searchsorted(self.hits, start))
        if k < len(self.hits):
            return int(self.hits[k])
        pos, window = max(self.pos, int(np.searchsorted(self.rows, start))), self.WINDOW
        while pos < len(self.rows):
            end = min(len(self.rows), pos + window)
            rows = self.rows[pos:end]
            off = ~self.active[(rows + key) % self.period, self.cols[pos:end]]
            self.pos = pos = end
            if off.any():
                self.hits = rows[off]
                return int(self.hits[0])
            window *= 2
        self.hits = self.rows[:0]
        return self.N

    def chain(self, row: int, count: int, gap: int) -> int:
        """Where to stop stepping from a reading found off the schedule.

        Parameters
        ----------
        row : int
            The row of such a reading (:meth:`next`'s).
        count : int
            At most this many of them.
        gap : int
            Each less than this many rows after the one before.

        Returns
        -------
        int
            The row of the last of them.
        """
        hits = self.hits[int(np.searchsorted(self.hits, row)):][:count]
        far = np.flatnonzero(np.diff(hits) >= gap)
        return int(hits[far[0]] if far.size else hits[-1])


def _joined(pieces, states):
    """The estimates (and, ``states``, the output states) of consecutive pieces of a run as one."""
    if len(pieces) == 1:
        return pieces[0]
    if states:
        return np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces])
    return np.concatenate(pieces)


def _case_hint(missing, readings) -> str:
    """The keys of ``readings`` that name a ``missing`` sensor in another case (a DataFrame's
    ``Compass`` for ``compass``), as a hint for the error; empty when there are none."""
    try:
        keys = {str(k).strip().lower(): k for k in readings.keys()}
    except (AttributeError, TypeError):
        return ""
    near = [f"{keys[n.lower()]!r}" for n in missing if n.lower() in keys]
    return f"; readings has {', '.join(near)}: sensor names are case-sensitive" if near else ""


def _offset_dominates(rt, cols) -> bool:
    """Whether the IIR path should run relative to references (``_LtiBands._filtered``):
    the readings of the quantity (its first order-0 column, sampled every ``_PIECE``
    samples) lie farther from zero than 16 times the most they move from one sampled value to
    the next.  Then the rounding of the direct form, which scales with the values it runs on, is
    cut by at least 16 by references re-taken every piece; otherwise (a heading swinging
    through +-pi, a position near the origin) the references could not reduce it and the
    single recursion runs, without their cost."""
    if rt._shift is None:
        return False
    col = cols[int(np.flatnonzero(rt._shift[1])[0])]
    sample = np.append(col[::_PIECE], col[-1])
    return bool(np.abs(sample).max() > 16 * np.abs(np.diff(sample)).max())


def _offset_direction(F, B, H, table):
    """How a constant offset of the common quantity moves the filter: ``(v, s)``, or None.

    ``s`` marks the columns (inputs by column of ``B``, then measurements by row of ``H``) of
    the sensors that read the quantity itself (derivative order 0, from the table's typed ports);
    ``v`` is the state that the offset moves, ``F v + B s_u = v`` and ``H v = s_y`` with
    ``v[0] = 1``: the position but not the velocity or a bias.  Then adding ``c`` to every such
    reading and ``c v`` to the state adds ``c v`` to every later state, whatever the gains (the
    bands sum to one), and the batch paths run on readings and states relative to a reference
    so that their rounding scales with the spread of the values, not with their size.  None
    when no such ``v`` solves the equations to rounding (then the batch runs on the absolute
    values, as before).
    """
    s = np.array([float(port.order == 0) for port in (*table.inputs, *table.measurements)])
    p = B.shape[1]
    n = F.shape[0]
    if not s[p:].any():
        return None
    M = np.vstack([F - np.eye(n), H, np.eye(n)[:1]])
    rhs = np.concatenate([-B @ s[:p], s[p:], [1.0]])
    v = np.linalg.lstsq(M, rhs, rcond=None)[0]
    snapped = np.round(v)
    for cand in (snapped, v):  # the exact 0/1 state of a kinematic chain when it solves
        if np.max(np.abs(M @ cand - rhs)) <= 8 * np.finfo(float).eps * (1.0 + np.abs(M).max() * np.abs(cand).max()):
            return cand, s
    return None


def _snapshot(state, n, period, p, name, sha256):
    """``(x, phase, u_last)`` of a snapshot, checked (see :meth:`Runtime.restore`)."""
    def fail(why):
        raise CfdesignError(f"state does not fit {name}: {why}")

    if not isinstance(state, dict) or not {"x", "phase", "u_last"} <= set(state):
        fail("a snapshot is a dict with x, phase and u_last (from Runtime.state())")
    theirs = state.get("filter_sha256", sha256)
    if theirs != sha256:
        fail(f"it was taken from another filter, {str(state.get('table', 'a table not named'))[:200]!r} "
             f"(filter_sha256 {str(theirs)[:16]}..., this one's {sha256[:16]}...)")
    try:
        x, u_last = state_vector(state["x"], "x", n), state_vector(state["u_last"], "u_last", p)
    except CfdesignError as exc:
        fail(str(exc))
    phase = state["phase"]
    if isinstance(phase, bool) or not isinstance(phase, (int, np.integer)) or not 0 <= phase < period:
        fail(f"phase must be an integer with 0 <= phase < {period}, got {phase!r}")
    return x, int(phase), u_last


#: :class:`_LtiBands` per (filter_sha256, output)
_LTI = {}


class _LtiBands:
    """A single-rate table as IIR filters, one per sensor, sharing one denominator: run as one
    recursion through scipy's lfilter (``_filtered``).

    The band of reading ``j`` is ``num_j / den`` with ``den = det(zI - A)`` and
    ``num_j = C_o adj(zI - A) G_j + D_j den`` (:func:`cfdesign.linear.band_polynomials`
    without the sensor relation).  lfilter's direct-form-II-transposed state is the
    observable canonical state ``z = T x`` of this realisation, with rows
    ``T_i = C_o (A^(i-1) + a_1 A^(i-2) + ... + a_(i-1) I)``
    (:func:`cfdesign.linear.output_adjugate`); so the filter starts from ``zi = T x0`` and
    hands back ``x = T^-1 sum_j zf_j``, exactly the state the streaming recursion would
    hold.  Tables whose ``(A, C_o)`` is badly observable (``T`` ill conditioned), or whose
    closed-loop poles are clustered so near ``z = 1`` that the rounding of ``den``'s
    coefficients moves them by more than :data:`_POLE_RTOL` of their distance to the unit
    circle (fast sampling of a slow filter: the direct form then drifts from the recursion by
    about that much, relative), use the blocked path instead.  Cost: ``O(n^3)`` once per filter.
    """

    def __init__(self, den, nums, T, Tinv, priors=(), from_post=None):
        self.den, self.nums, self.T, self.Tinv = den, nums, T, Tinv
        #: angle tables: ``(rows, T_c, nums_c)`` per distinct angle row ``c`` of ``H``, the IIR
        #: filters of the prior ``c x`` (``T_c`` None: the estimate is that prior)
        self.priors = priors
        #: ``(L0, 1 - sum L0)`` when every row of ``H`` reads state 0 and the output is the
        #: posterior: then ``x0 = (est - L0 y) / (1 - sum L0)`` gives the prior without a filter
        self.from_post = from_post

    @classmethod
    def of(cls, rt):
        """The IIR form of ``rt``'s table, or None where it does not apply; built once per filter
        (:func:`filter_sha256` and output: a runtime built again for the same table, one per log
        or per call, reuses it)."""
        cached = getattr(rt, "_lti", False)
        if cached is not False:
            return cached
        key = (rt._sha256, rt.output)
        if key not in _LTI:
            if len(_LTI) >= 64:
                _LTI.clear()
            _LTI[key] = cls._build(rt)
        rt._lti = _LTI[key]
        return rt._lti

    @classmethod
    def _build(cls, rt):
        ph = rt._phases[0]
        den = linear.characteristic_polynomial(ph.A)
        T = linear.output_adjugate(ph.A, ph.C[0], den)
        nums = [np.concatenate([[d], T @ g + d * den[1:]]) for g, d in zip(ph.G.T, ph.D[0], strict=True)]
        lti = None
        if np.linalg.cond(T) < 1e8 and _pole_sensitivity(ph.A, den) < _POLE_RTOL:
            priors = {}
            for i in np.flatnonzero(rt._wrap_rows):
                priors.setdefault(tuple(rt.H[i]), []).append(i)
            checks, from_post = [], None
            e0 = np.eye(rt.n)[0]
            if rt.posterior and priors and all(np.array_equal(h, e0) for h in rt.H):
                L0 = rt.L[0][0]
                if abs(1.0 - L0.sum()) > 1e-3:
                    from_post = (L0, 1.0 - L0.sum())
            for c, rows in priors.items():
                if (not rt.posterior and np.array_equal(c, ph.C[0])) or from_post is not None:
                    checks.append((rows, None, None))
                    continue
                Tc = linear.output_adjugate(ph.A, np.array(c), den)  # the prior: C = c, D = 0
                checks.append((rows, Tc, [np.concatenate([[0.0], Tc @ g]) for g in ph.G.T]))
            lti = cls(den, nums, T, np.linalg.inv(T), checks, from_post)
        return lti

    def _filtered(self, nums, T, x, cols, shift=None):
        """``sum_j lfilter(nums[j], den, cols[j])`` started from the state ``x`` (through ``T``),
        and the final filter state (the sum of the filters' states), by one recursion.

        The filters share ``den``: their sum is ``1 / den`` applied to
        ``v = sum_j nums[j] * cols[j]`` (short convolutions), started from the same state.  The
        sum of their direct-form-II-transposed states is that recursion's state plus the part of
        the numerators still to come, ``sum_j sum_(m > i) nums[j][m] cols[j][N + i - m]`` in row
        ``i`` (readings before the first count as zero).

        ``shift`` ``(v, s, g)`` (:func:`_offset_direction`; ``g`` the output's move per unit
        offset): the recursion runs on values relative to a reference ``r``, the columns ``s``
        less ``r`` and the state less ``r v``, re-taken at every piece of ``_PIECE`` samples
        from the last output (the recursion's state moves
        by ``(r' - r) g`` times the tail sums of ``den``: its steady state for a constant
        output), so that its rounding scales with the values' spread within a piece, not with
        their size.  Returns the outputs (absolute), the final state relative to ``r`` and ``r``.
        """
        from scipy.signal import lfilter

        N, n = len(cols[0]), len(self.den) - 1
        flags = shift[1] if shift is not None else np.zeros(len(cols))
        terms = [(num, col, bool(f)) for num, col, f in zip(nums, cols, flags, strict=True) if num.any()]
        r = float(x[0]) if shift is not None else 0.0
        zi = T @ (x - r * shift[0]) if shift is not None else T @ x
        tail = np.cumsum(self.den[::-1])[::-1][1:] * (shift[2] if shift is not None else 0.0)
        total = np.empty(N)
        size = _PIECE if shift is not None else linear.CHUNK
        # without references the numerators' sum is formed piece by piece and one recursion runs
        v = np.empty(min(N, size)) if shift is not None else total
        rel = np.empty(min(N, size) + n)
        for start in range(0, N, size):  # piece by piece: the convolutions stay in cache
            piece = v[: min(size, N - start)] if shift is not None else v[start:start + size]
            if start and shift is not None:  # a new reference: the last output
                zi += (total[start - 1] - r) * tail
                r = float(total[start - 1])
            if not terms:
                piece[:] = 0.0
            for j, (num, col, moved) in enumerate(terms):
                window = col[start - n:start + len(piece)] if start else np.concatenate([np.zeros(n), col[:len(piece)]])
                if moved and r:
                    window = np.subtract(window, r, out=rel[: len(window)])
                    if not start:
                        window[:n] = 0.0  # before the first reading: zero, relative to the reference
                part = np.convolve(window, num, mode="valid")  # the piece's outputs of this numerator
                if j:
                    piece += part
                else:
                    piece[:] = part
            if shift is not None:
                out, zi = lfilter([1.0], self.den, piece, zi=zi)
                np.add(out, r, out=total[start:start + len(piece)])
        if shift is None:
            total, zi = lfilter([1.0], self.den, total, zi=zi)
        zf = zi
        last = np.zeros(n)  # the last n readings, newest first
        for num, col, f in zip(nums, cols, flags, strict=True):
            k = min(n, N)
            last[:k] = col[: -n - 1: -1] if N > n else col[::-1]
            if f:
                last[:k] -= r
            zf += np.correlate(num[1:], last, "full")[n - 1:]  # row i: sum_k num[i + 1 + k] last[k]
        return total, zf, r

    def run(self, rt, cols, read=None):
        """The estimates, the runtime advanced; None (the runtime unchanged) when, with ``read``
        (where the angle readings are), an angle innovation is not within pi."""
        shift = self._shift(rt, rt._phases[0].C[0], rt._phases[0].D[0]) if _offset_dominates(rt, cols) else None
        est, zf, r = self._filtered(self.nums, self.T, rt.x, cols, shift)
        if read is not None and not self._within_pi(rt, est, cols, read, shift is not None):
            return None
        rt.x = self.Tinv @ zf + (r * shift[0] if shift is not None else 0.0)
        rt.phase, rt.u_last = 0, np.array([c[-1] for c in cols[: len(rt.inputs)]])
        if rt.table.wrap_angle:
            x = rt.x
            x[0] = wrap_scalar(x[0])
            rt.x = x
            linear.wrap_inplace(est)
        return est

    @staticmethod
    def _shift(rt, c, d=None):
        """``(v, s, g)`` for :meth:`_filtered` of the output ``c x + d w``: ``g`` its move per unit
        offset of the quantity; None where the table has no offset direction or ``g`` is 0."""
        if rt._shift is None:
            return None
        v, s = rt._shift
        g = float(c @ v + (0.0 if d is None else d @ s))
        return (v, s, g) if g else None

    def _within_pi(self, rt, est, cols, read, relative=False) -> bool:
        """Whether every angle innovation (an angle reading less the prior of its row) is within
        pi wherever ``read`` has a reading (``_ALL``: everywhere).  Piece by piece: the prior
        formed from the estimate (``from_post``) and the differences stay in cache.  ``relative``:
        the priors' filters run relative to references, as the estimate's did."""
        p, N = len(rt.inputs), len(est)
        ys = cols[p:]
        def prior(rows, Tc, nums):  # the prior of these rows (relative, as the estimate was)
            shift = self._shift(rt, rt.H[rows[0]]) if relative else None
            return self._filtered(nums, Tc, rt.x, cols, shift)[0]

        groups = [(rows, None if self.from_post is not None else est if Tc is None else prior(rows, Tc, nums))
                  for rows, Tc, nums in self.priors]
        work = np.empty((2, min(N, linear.CHUNK)))
        for start in range(0, N, linear.CHUNK):
            at = slice(start, start + linear.CHUNK)
            shared, gap = work[:, : min(linear.CHUNK, N - start)]
            if self.from_post is not None:  # the prior of state 0: (est - L0 y) / (1 - sum L0)
                L0, scale = self.from_post
                np.copyto(shared, est[at])
                for g, y in zip(L0, ys, strict=True):
                    if g:
                        shared -= np.multiply(y[at], g, out=gap)
                shared /= scale
            for rows, prior in groups:
                for i in rows:
                    np.subtract(ys[i][at], shared if prior is None else prior[at], out=gap)
                    d = gap if read is _ALL else gap[read[at, i]]
                    if d.size and (d.max() >= np.pi or d.min() <= -np.pi):
                        return False
        return True


#: largest pole displacement, relative to the pole's distance to the unit circle, that the
#: rounding of the IIR path's denominator may cause (its estimates then agree with the step's
#: to about 1e-9 relative)
_POLE_RTOL = 1e-8


def _pole_sensitivity(A, den) -> float:
    """``max_i eps sum_k |a_k| |p_i|^(n-k) / |prod_(j != i) (p_i - p_j)| / (1 - |p_i|)``: how far
    rounding the coefficients of ``den = det(zI - A)`` moves its roots ``p_i`` (first-order
    perturbation of a simple root), relative to their distance to the unit circle; inf for a
    repeated root or one on or outside the circle."""
    p = np.linalg.eigvals(A)
    worst = 0.0
    for i, pi in enumerate(p):
        margin = 1.0 - abs(pi)
        gap = abs(np.prod(pi - np.delete(p, i)))
        if margin <= 0 or gap == 0:
            return np.inf
        moved = np.finfo(float).eps * np.sum(np.abs(den) * abs(pi) ** np.arange(len(den) - 1, -1, -1)) / gap
        worst = max(worst, moved / margin)
    return worst


def _clean(col) -> bool:
    """Every value a usable reading (no NaN, inf or beyond :data:`~cfdesign.runtime.filter.READING_LIMIT`): two passes,
    no temporaries; NaN fails both comparisons."""
    return bool(col.min() >= -READING_LIMIT and col.max() <= READING_LIMIT)


def _unwrap(col, near):
    """``col`` made continuous and moved by whole turns so that its first value is within pi of
    ``near``: ``np.unwrap`` for sparse jumps (a jump of more than pi between neighbours is a turn),
    with the first value's turn folded into the same pass; ``col`` itself when nothing moves."""
    shift = 2 * np.pi * np.round((col[0] - near) / (2 * np.pi))
    jumps = _jumps(col)
    if not jumps.size:
        return col - shift if shift else col
    turns = -2 * np.pi * np.round((col[jumps + 1] - col[jumps]) / (2 * np.pi))
    levels = np.concatenate([[0.0], np.cumsum(turns)])
    levels -= shift
    out = np.repeat(levels, np.diff(np.concatenate([[0], jumps + 1, [len(col)]])))
    out += col
    return out


def _jumps(col) -> np.ndarray:
    """The ``k`` where ``|col[k + 1] - col[k]| > pi``, found piece by piece in one cache-sized
    buffer (no array of the length of ``col`` is made)."""
    N = len(col) - 1
    buf, found = np.empty(min(max(N, 0), linear.CHUNK)), []
    for start in range(0, N, linear.CHUNK):
        d = buf[: min(linear.CHUNK, N - start)]
        np.subtract(col[start + 1:start + 1 + len(d)], col[start:start + len(d)], out=d)
        if d.max() > np.pi or d.min() < -np.pi:
            found.append(np.flatnonzero(np.abs(d, out=d) > np.pi) + start)
    return np.concatenate(found) if found else np.empty(0, dtype=np.intp)


def _boundary_states(Phi, C, x0):
    """``X[p+1] = Phi X[p] + C[p]``, ``X[0] = x0``: all ``P`` of them at once by a doubling scan
    (Hillis and Steele, "Data parallel algorithms", CACM 1986), numpy only: after the pass of
    shift ``d`` each ``X[p]`` sums the terms ``Phi^(p-j) S[j]`` of the last ``2 d`` inputs ``S = [x0,
    C[0], ...]``, with ``Phi^d`` squared from pass to pass: ``log2 P`` passes of ``O(P n^2)``.  A few
    blocks or a large state run block by block (``O(n^2)`` each, never ``O(n^4)``).  It replaced
    scipy's lfilter on the transfer functions of ``(zI - Phi)^-1``, whose direct form drifts where the
    poles cluster, and whose import (scipy.signal, 0.9 s) was most of a short log's ``cfdesign run``."""
    n, P = len(x0), len(C)
    X = np.empty((P, n))
    if P == 0:
        return X
    X[0] = x0
    X[1:] = C[:-1]
    if P < 8 or n > 16:
        for p in range(1, P):
            X[p] += Phi @ X[p - 1]
        return X
    A, d = np.asarray(Phi, dtype=float), 1
    while d < P:
        X[d:] += X[:-d] @ A.T  # the product is formed from the previous pass before the sum lands
        d *= 2
        if d < P:
            A = A @ A
    return X
