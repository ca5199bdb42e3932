"""GainTable: the designed filter as data - model, gains per phase, predicted error, provenance.

A gain table holds everything needed to run the filter and to re-check it: the discrete (or
continuous) model ``F, B, H``, the gain ``K[k]`` of every phase of the period in the named
gain form, the predicted steady-state covariances, the sensors and how they enter, and where
it came from (spec hash, toolkit version, solver residuals).  JSON floats are written with
``repr`` precision, so a save/load round trip is exact.

Gain forms (docs/derivations.md, "Gain forms"; :mod:`cfdesign.linear`):

* ``predictor``: ``x[k+1] = F x[k] + B u[k] + K[k] (y[k] - H x[k])``, estimate ``x[k]``;
* ``filter``: ``x+[k] = x-[k] + K[k] (y[k] - H x-[k])``, ``x-[k+1] = F x+[k] + B u[k]``,
  estimate ``x+[k]``;
* ``continuous``: ``x' = F x + B u + K (y - H x)``.

At a phase where a measurement sensor has no reading, its column of ``K[k]`` is exactly zero.
"""

from __future__ import annotations

import json
import keyword
import math
import numbers
import os
import re
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from . import linear
from .errors import GainTableError, InputError
from .files import path_of, read_limited, utf8_text
from .linear import GAIN_FORMS
from .spec import MAX_RATE_HZ, QUANTITY_ORDERS

#: largest difference (relative to the bands' size) between the polynomial transfer functions
#: of :meth:`GainTable.transfer_functions` and the table's bands before a warning
POLYNOMIAL_RTOL = 1e-6

__all__ = ["GainTable", "SensorPort", "Schedule", "load_gains", "validate", "schema", "column_order",
           "FORMAT_VERSION", "DERIVATIVE_NAMES"]

_ORDERS = ("acceleration", "jerk", "snap", "crackle", "pop")
#: the names the designer gives a chain's states, by family and derivative order
#: (``cfdesign.designer.state_names``), and the unit of each family's quantity
DERIVATIVE_NAMES = {"linear": ("position", "velocity", *_ORDERS),
                    "angle": ("angle", "angle_rate", *(f"angle_{d}" for d in _ORDERS)),
                    "heading": ("heading", "heading_rate", *(f"heading_{d}" for d in _ORDERS))}
_FAMILY_UNITS = {"linear": "m", "angle": "rad", "heading": "rad"}
_PER_SECOND = ("", "/s", "/s²", "/s³", "/s⁴", "/s⁵", "/s⁶")

#: largest gain table file read (bytes) and largest period and state a table may have: checked
#: before anything is allocated or computed (the designer caps the period at the same value)
MAX_TABLE_BYTES = 64_000_000
MAX_PERIOD = 10_000
MAX_STATES = 500
#: highest derivative order a sensor may read: a kinematic chain of n states is driven by the
#: n-th derivative, so the largest state bounds it
MAX_ORDER = MAX_STATES
#: largest magnitude of a table's matrix entries: with states within the runtime's
#: :data:`~cfdesign.runtime.filter.STATE_LIMIT` (the same) no product of one step can overflow
MAX_ENTRY = 1e150
#: sample times and rates a table may have (seconds, hertz), :data:`cfdesign.spec.MAX_RATE_HZ`: beyond
#: them the frequency grid and the ZOH relations lose every digit

#: version of the JSON layout written by :meth:`GainTable.save <cfdesign.gains.GainTable.save>`
FORMAT_VERSION = 1
SCHEMA_PATH = Path(__file__).resolve().parent / "schemas" / f"gaintable-{FORMAT_VERSION}.schema.json"


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of the gain table format.

    Returns
    -------
    dict
        The schema of ``cfdesign/schemas/gaintable-1.schema.json`` (:data:`FORMAT_VERSION`).
    """
    return json.loads(SCHEMA_PATH.read_text())


def validate(data: dict, source: str = "gain table"):
    """Check a parsed gain table and build it.

    The JSON schema fixes the fields and types; how the parts fit together (shapes, sensor
    ports, schedule) is checked when the :class:`~cfdesign.gains.GainTable` is built from them.  Size limits
    (states, period, nesting) are checked first.

    Parameters
    ----------
    data : dict
        The table's JSON form, as :func:`json.load` gives it.
    source : str
        What to call the table in messages (a file name).

    Returns
    -------
    GainTable
        The validated table.

    Raises
    ------
    GainTableError
        The data fails the schema or a size limit, or its parts do not fit together; the
        message names the field.
    """
    _check_sizes(data, source)
    _check_numbers(data, source)
    _check_schema(data, source)
    return GainTable._from_json(data, source)


def _check_sizes(d, source):
    """Refuse tables larger than the limits before building arrays from them."""
    if not isinstance(d, dict):
        return
    period, n = (len(v) if isinstance(v, list) else 0 for v in (d.get("K"), d.get("F")))  # other types: the schema
    if period > MAX_PERIOD:
        raise GainTableError(f"{source}: a period of {period} phases is more than {MAX_PERIOD}")
    if n > MAX_STATES:
        raise GainTableError(f"{source}: {n} states is more than {MAX_STATES}")


def _check_numbers(value, source, where=""):
    """Refuse a number that is not a finite double (an integer of 400 digits, or ``1e309``, which
    JSON reads as inf) anywhere in the table before any use.  The matrices were checked on
    their own; an inf in ``gains``, ``checks`` or ``provenance`` loaded, then the table could not
    be written (``cfdesign export --format json``: an internal error)."""
    if isinstance(value, dict):
        for key, item in value.items():
            _check_numbers(item, source, f"{where}/{key}" if where else str(key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _check_numbers(item, source, f"{where}/{i}")
    elif isinstance(value, int) and not isinstance(value, bool) and abs(value) > 2 ** 1023:
        raise GainTableError(f"{source}: {where or '(top level)'}: {str(value)[:20]}... is beyond the range of a "
                             "double")
    elif isinstance(value, float) and not math.isfinite(value):
        raise GainTableError(f"{source}: {where or '(top level)'}: {value} is not a finite number (a number beyond "
                             f"the range of a double, such as 1e309, reads as {'-' if value < 0 else ''}inf)")


def _check_schema(data, source):
    import jsonschema

    if isinstance(data, dict) and data.get("format_version") not in (None, FORMAT_VERSION):
        raise GainTableError(f"{source}: unsupported format_version {data.get('format_version')!r} "
                             f"(this cfdesign reads {FORMAT_VERSION})")
    try:
        jsonschema.validate(_one_phase(data), schema())
    except jsonschema.ValidationError as exc:
        where = "/".join(map(str, exc.absolute_path)) or "(top level)"
        raise GainTableError(f"{source}: schema violation at {where}: {_schema_message(exc)}") from None


def _schema_message(exc) -> str:
    """jsonschema's message with the value it quotes cut short: a whole table quoted (a list at
    the top level, ``sensors`` as an object) pushed what is wrong past the end of the line."""
    text, quoted = exc.message, repr(exc.instance)
    if len(quoted) > 80 and quoted in text:
        kind = {dict: "an object", list: "an array", str: "a string"}.get(type(exc.instance), "a value")
        text = text.replace(quoted, f"{quoted[:60]}... ({kind})", 1)
    return text


#: the per-phase fields of the JSON form and the type of their leaves: the schema gives each phase
#: of them the same item schema (a matrix of numbers; a list of sensor names for ``measured``)
_PHASE_FIELDS = {"K": (int, float), "P": (int, float), "P_filtered": (int, float), "measured": (str,)}


def _one_phase(data):
    """``data`` with each per-phase field cut to its first phase, where every phase is of the
    item type the schema asks (checked here, in one pass of plain type tests): the schema then
    checks one phase instead of walking 30,000 matrices (4 s for a period of 10,000).  Where a
    phase is of another type the field is left whole, so the schema names the phase."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for key, leaf in _PHASE_FIELDS.items():
        items = data.get(key)
        if isinstance(items, list) and len(items) > 1 and all(_nested_of(item, leaf, 2 if leaf != (str,) else 1)
                                                                for item in items):
            out[key] = items[:1]
    return out


def _nested_of(value, leaf, depth) -> bool:
    """``value`` is a list nested ``depth`` deep whose leaves are exactly of the types ``leaf``
    (``bool`` is not an ``int`` here, as for JSON Schema's ``number``)."""
    if not isinstance(value, list):
        return False
    if depth == 1:
        return all(type(v) in leaf for v in value)
    return all(_nested_of(v, leaf, depth - 1) for v in value)


def _check_table(t, source):
    """Shapes, ports and schedule of a table fit together (GainTableError naming the part)."""
    if t.domain not in ("s", "z") or t.gain_form not in GAIN_FORMS:
        raise GainTableError(f"{source}: domain {t.domain!r} / gain_form {t.gain_form!r} unknown")
    if (t.domain == "s") != (t.gain_form == "continuous"):
        raise GainTableError(f"{source}: gain_form {t.gain_form!r} does not go with domain {t.domain!r}")
    dt = t.sample_time_s
    if t.domain == "z" and not (isinstance(dt, (int, float)) and not isinstance(dt, bool)
                                and 1 / MAX_RATE_HZ <= dt <= MAX_RATE_HZ):
        raise GainTableError(f"{source}: sample_time_s must be a positive number of seconds (from {1 / MAX_RATE_HZ:g} "
                             f"to {MAX_RATE_HZ:g}) for a discrete table, got {dt!r}")
    if len(t.K) > MAX_PERIOD:
        raise GainTableError(f"{source}: a period of {len(t.K)} phases is more than {MAX_PERIOD}")
    n = np.shape(t.F)[0] if np.ndim(t.F) == 2 else 0
    if n == 0:
        raise GainTableError(f"{source}: F is empty: a filter needs at least one state")
    m, p = np.shape(t.H)[0], np.shape(t.B)[1] if np.ndim(t.B) == 2 else -1
    for key, shape in {"F": (n, n), "B": (n, p), "H": (m, n), "Q": (n, n), "R": (m, m)}.items():
        _shape_of(getattr(t, key), shape, f"{source}: {key}")
    if not t.K:
        raise GainTableError(f"{source}: K has no phase")
    for key, shape in (("K", (n, m)), ("P", (n, n)), ("P_filtered", (n, n))):
        if len(getattr(t, key)) != len(t.K):
            raise GainTableError(f"{source}: {key} has {len(getattr(t, key))} phases, K has {len(t.K)}")
        for k, M in enumerate(getattr(t, key)):
            _shape_of(M, shape, f"{source}: {key}[{k}]")
    _check_ports(t.sensors, p, m, source)
    _check_schedule(t, source)


def _check_ports(ports, p, m, source):
    if not ports:
        raise GainTableError(f"{source}: sensors: a table needs at least one sensor")
    names = [s.name for s in ports]
    dup = sorted({x for x in names if names.count(x) > 1})
    if dup:
        raise GainTableError(f"{source}: sensors: duplicate name(s) {', '.join(dup)}")
    for s in ports:
        if not (isinstance(s.name, str) and s.name.isascii() and s.name.isidentifier()) or keyword.iskeyword(s.name):
            raise GainTableError(f"{source}: sensors: name {s.name!r} is not an ASCII identifier (or is a keyword)")
        if (s.role not in ("input", "measurement") or not 0 <= s.order <= MAX_ORDER
                or not 1 / MAX_RATE_HZ <= s.rate_hz <= MAX_RATE_HZ):
            raise GainTableError(f"{source}: sensors.{s.name}: role {s.role!r}, order {str(s.order)[:20]}, "
                                 f"rate {s.rate_hz} Hz is not a valid port (order 0 to {MAX_ORDER}, rate "
                                 f"{1 / MAX_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz)")
    for role, count in (("input", p), ("measurement", m)):
        idx = sorted(s.index for s in ports if s.role == role)  # listed in any order
        if idx != list(range(count)):
            raise GainTableError(f"{source}: sensors: {role} indices {sorted(idx)} do not match the {count} "
                                 f"{'columns of B' if role == 'input' else 'rows of H'}")


def _check_schedule(t, source):
    sched = t.schedule
    names = tuple(s.name for s in t.sensors if s.role == "measurement")
    if not isinstance(sched, Schedule) or sched.measurements != names:
        raise GainTableError(f"{source}: the schedule does not list the measurement sensors {', '.join(names)}")
    if sched.period != len(t.K):
        raise GainTableError(f"{source}: measured has {sched.period} phases, K has {len(t.K)}")
    idle = ~sched.mask()
    for k, K in enumerate(t.K):
        cols = np.flatnonzero(idle[k] & np.any(np.asarray(K) != 0, axis=0))
        if cols.size:
            raise GainTableError(f"{source}: K[{k}] has a gain for {names[cols[0]]}, which the schedule does "
                                 f"not read at phase {k}")


def _check_output(t, source):
    _require_output(t.output, source)
    if t.output == "posterior" and not _has_posterior(t):
        raise GainTableError(f"{source}: a posterior output needs a discrete table with an invertible F")


def _has_posterior(t) -> bool:
    """Every phase's gain has an update gain (:func:`cfdesign.linear.gain_pair`).  Whether it
    does depends on ``F``, the gain form and the gains' shape, which all phases share, not on
    the gains' values: asked once, not once per phase (an SVD of ``F`` each)."""
    return t.domain == "z" and linear.gain_pair(t.F, t.K[0], t.gain_form)[1] is not None


def _shape_of(M, shape, what):
    got = np.shape(M)
    if len(got) != 2 or got != shape:
        raise GainTableError(f"{what} must be {shape[0]}x{shape[1]}, got {'x'.join(map(str, got)) or 'a scalar'}")


@dataclass(frozen=True)
class SensorPort:
    """How one sensor enters a table.

    Attributes
    ----------
    name : str
        The sensor's name (an identifier; the log column and C macro are named after it).
    role : {'input', 'measurement'}
        ``input``: drives the model through column ``index`` of ``B`` every step;
        ``measurement``: compared with row ``index`` of ``H x`` at the phases the
        :class:`Schedule` lists.
    index : int
        Column of ``B`` or row of ``H``.
    order : int
        Derivative order of the common quantity it reads: 0 angle/position, 1 rate,
        2 acceleration.
    rate_hz : float
        Its rate (Hz).
    """

    name: str
    role: str
    index: int
    order: int
    rate_hz: float

    @classmethod
    def from_dict(cls, d: dict) -> SensorPort:
        """A port from its JSON form.

        Parameters
        ----------
        d : dict
            ``{"name", "role", "index", "order", "rate_hz"}``.

        Returns
        -------
        SensorPort
            The port.
        """
        return cls(str(d["name"]), str(d["role"]), int(d["index"]), int(d["order"]), float(d["rate_hz"]))

    def to_dict(self) -> dict:
        """The JSON form of the port.

        Returns
        -------
        dict
            ``{"name", "role", "index", "order", "rate_hz"}``.
        """
        return {"name": self.name, "role": self.role, "index": self.index, "order": self.order,
                "rate_hz": self.rate_hz}


@dataclass(frozen=True)
class Schedule:
    """Which measurement rows a multirate table reads at each phase of its period.

    Attributes
    ----------
    measurements : tuple of str
        Measurement sensor names in row order (row ``i`` of ``H``).
    active : tuple of tuple of int
        ``active[k]``: the rows read at phase ``k``, ascending; ``len(active)`` is the period.
    """

    measurements: tuple
    active: tuple

    @classmethod
    def from_names(cls, measurements, per_phase) -> Schedule:
        """A schedule from one list of sensor names per phase.

        Parameters
        ----------
        measurements : sequence of str
            Measurement sensor names in row order of ``H``.
        per_phase : sequence of sequence of str
            ``per_phase[k]``: the sensors read at phase ``k``; its length is the period.

        Returns
        -------
        Schedule
            The schedule, period ``len(per_phase)``.

        Raises
        ------
        ValueError
            A phase lists an unknown or a repeated sensor.

        Examples
        --------
        >>> from cfdesign.gains import Schedule
        >>> Schedule.from_names(["compass", "odometry"], [["compass", "odometry"], ["odometry"]]).active
        ((0, 1), (1,))
        """
        measurements = tuple(measurements)
        active = []
        for k, names in enumerate(per_phase):
            unknown = [x for x in names if x not in measurements]
            if unknown or len(set(names)) != len(names):
                what = f"unknown sensor(s) {', '.join(map(repr, unknown))}" if unknown else "a repeated sensor"
                raise ValueError(f"phase {k} lists {what} (measurements: {', '.join(measurements) or 'none'})")
            active.append(tuple(sorted(measurements.index(x) for x in names)))
        return cls(measurements, tuple(active))

    @classmethod
    def every(cls, measurements, every: dict, period: int) -> Schedule:
        """A schedule where sensor ``name`` is read at the phases ``k`` with ``k % every[name] == 0``.

        Parameters
        ----------
        measurements : sequence of str
            Measurement sensor names in row order of ``H``.
        every : dict
            ``{name: n}``: read every ``n`` base steps (``n`` divides ``period``).
        period : int
            Number of phases (base steps).

        Returns
        -------
        Schedule
            The schedule, period ``period``.

        Examples
        --------
        >>> from cfdesign.gains import Schedule
        >>> s = Schedule.every(["compass", "odometry"], {"compass": 5, "odometry": 1}, 5)
        >>> s.phases("compass"), s.names(1)
        ((0,), ['odometry'])
        """
        measurements = tuple(measurements)
        return cls.from_names(measurements, [[x for x in measurements if k % every[x] == 0] for k in range(period)])

    @classmethod
    def from_ticks(cls, measurements, ticks: dict, period: int) -> Schedule:
        """A schedule where sensor ``name`` is read at the phases ``ticks[name]``.

        Parameters
        ----------
        measurements : sequence of str
            Measurement sensor names in row order of ``H``.
        ticks : dict
            ``{name: iterable of int}``: base ticks at which the sensor is read, taken modulo
            ``period``.
        period : int
            Number of phases (base steps).

        Returns
        -------
        Schedule
            The schedule, period ``period``.
        """
        measurements = tuple(measurements)
        sets = {x: {int(t) % period for t in ticks[x]} for x in measurements}
        return cls.from_names(measurements, [[x for x in measurements if k in sets[x]] for k in range(period)])

    def phases(self, name: str) -> tuple:
        """The phases at which one sensor is read.

        Parameters
        ----------
        name : str
            A measurement sensor of the schedule.

        Returns
        -------
        tuple of int
            Ascending phases in ``range(period)``.

        Raises
        ------
        InputError
            ``name`` is not a measurement of the schedule (a ValueError, as before).
        """
        if name not in self.measurements:  # (tuple.index raised 'tuple.index(x): x not in tuple')
            raise InputError(f"the schedule has no measurement {name!r} (measurements: "
                             f"{', '.join(self.measurements) or 'none'})")
        i = self.measurements.index(name)
        return tuple(k for k in range(self.period) if i in self.active[k])

    def shifted(self, offsets: dict) -> Schedule:
        """The schedule with some sensors read later.

        Parameters
        ----------
        offsets : dict
            ``{name: phases}``: sensor ``name`` is read ``offsets[name]`` phases later (modulo the
            period); sensors not named are left as they are.

        Returns
        -------
        Schedule
            A new schedule of the same period.

        Examples
        --------
        >>> from cfdesign.gains import Schedule
        >>> Schedule.every(["gps"], {"gps": 5}, 5).shifted({"gps": 2}).phases("gps")
        (2,)
        """
        ticks = {x: [k + int(offsets.get(x, 0)) for k in self.phases(x)] for x in self.measurements}
        return Schedule.from_ticks(self.measurements, ticks, self.period)

    def rotated(self, phase: int) -> Schedule:
        """The same schedule started later: its phase 0 is this one's ``phase``.

        Parameters
        ----------
        phase : int
            Phase of this schedule that becomes phase 0 (taken modulo the period).

        Returns
        -------
        Schedule
            A new schedule of the same period.
        """
        k = phase % self.period
        return Schedule(self.measurements, self.active[k:] + self.active[:k])

    @property
    def period(self) -> int:
        """Number of phases (base-rate steps) of the schedule."""
        return len(self.active)

    def rows(self, phase: int) -> tuple:
        """Rows of ``H`` read at a phase.

        Parameters
        ----------
        phase : int
            Phase, taken modulo the period.

        Returns
        -------
        tuple of int
            Ascending row indices.
        """
        return self.active[phase % self.period]

    def names(self, phase: int) -> list:
        """Names of the sensors read at a phase.

        Parameters
        ----------
        phase : int
            Phase, taken modulo the period.

        Returns
        -------
        list of str
            The sensors read at ``phase``, in row order of ``H`` (empty when none is read).
        """
        return [self.measurements[i] for i in self.rows(phase)]

    def mask(self) -> np.ndarray:
        """Which row is read at which phase.

        Returns
        -------
        ndarray of bool, shape (period, m)
            ``mask[k, i]``: row ``i`` of ``H`` is read at phase ``k``.
        """
        out = np.zeros((self.period, len(self.measurements)), dtype=bool)
        for k, rows in enumerate(self.active):
            out[k, list(rows)] = True
        return out

    def per_phase_names(self) -> list:
        """The sensors read at every phase.

        Returns
        -------
        list of list of str
            ``[names(0), names(1), ...]``: the ``measured`` field of the JSON form.
        """
        return [self.names(k) for k in range(self.period)]


@dataclass(frozen=True)
class GainTable:
    """A designed filter: model, per-phase gains and predicted errors.

    Attributes
    ----------
    name, structure : str
        Design name and structure (``dckf3``, ``position``, ...).
    domain : {'s', 'z'}
        Continuous (``s``) or discrete (``z``) model.
    sample_time_s : float or None
        Base sample time (s); None for continuous filters.
    gain_form : {'predictor', 'filter', 'continuous'}
        See :mod:`cfdesign.linear` for what each form means.
    states : tuple of str
        A name per state (``heading``, ``gyro_correction``, ``position``, ``velocity``,
        ``accelerometer_bias``): the columns of estimate logs.  Tables written without them
        get ``x0, x1, ...``.
    output : {'posterior', 'prior'}
        The estimate the runtimes return by default: after each step's readings (posterior,
        covariance ``P_filtered``) or the one-step prediction (prior, ``P``).  Tables written
        without it get the posterior where the table has one.
    sensors : tuple of SensorPort
        Inputs by column of ``B``, then measurements by row of ``H`` (the column order of
        :func:`cfdesign.linear.realisation`'s ``G``).
    F, B, H : ndarray
        Model matrices (the discrete model for ``domain = 'z'``).
    K : list of ndarray
        Gain per phase, shape (n, m) each; ``len(K)`` is the period.
    P : list of ndarray
        Predicted (a-priori) steady-state error covariance per phase.
    P_filtered : list of ndarray
        A-posteriori covariance per phase (equal to ``P`` where nothing is measured).
    schedule : Schedule
        The measurement rows read at each phase; a gain column of a row not read at a
        phase is exactly zero.
    gains : dict
        ``{gain symbol: value}`` for single-rate tables (e.g. ``k11``); empty when periodic.
    wrap_angle : bool
        The quantity is an angle on a circle (a heading): runtimes wrap the innovations of
        angle sensors and the estimate to (-pi, pi].
    Q, R : ndarray
        Process and measurement noise covariances used (per sample for discrete tables).
    provenance : dict
        ``spec_sha256``, ``cfdesign_version``, ``created_utc``, ``solver`` details.
    checks : dict
        ``complementary`` (exact proof verdict), ``poles`` or ``monodromy_multipliers``
        (as ``[re, im]`` pairs) and ``stable``.
    options : dict
        The structure options (``order``, ``bands``, ``discrete``, ``full``).

    Raises
    ------
    GainTableError
        On construction, when the parts do not fit together: shapes, sensor ports (each
        column of ``B`` and row of ``H`` exactly one sensor, names unique), an empty model,
        a schedule that disagrees with the gains, or state names that are not distinct
        identifiers.

    See Also
    --------
    cfdesign.designer.design : builds a table from a design file.
    load_gains : reads one back.

    Examples
    --------
    >>> import cfdesign
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
    >>> table.period, table.sample_time_s, table.gain_form, table.output
    (50, 0.02, 'filter', 'posterior')
    >>> table.states
    ('position', 'velocity', 'accelerometer_bias')
    >>> table.schedule.phases("gps")
    (0,)
    """

    name: str
    structure: str
    domain: str
    sample_time_s: float | None
    gain_form: str
    sensors: tuple
    F: np.ndarray
    B: np.ndarray
    H: np.ndarray
    K: list
    P: list
    P_filtered: list
    schedule: Schedule
    Q: np.ndarray
    R: np.ndarray
    gains: dict = field(default_factory=dict)
    wrap_angle: bool = False
    output: str = ""
    states: tuple = ()
    options: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    def __post_init__(self):
        ports = tuple(SensorPort.from_dict(s) if isinstance(s, dict) else s for s in self.sensors)
        ports = column_order(ports)
        object.__setattr__(self, "sensors", ports)
        _check_table(self, self.name)
        if not self.output:  # tables written before the output was declared: the posterior where it exists
            object.__setattr__(self, "output", "posterior" if _has_posterior(self) else "prior")
        _check_output(self, self.name)
        n = len(self.F)
        if not self.states:
            object.__setattr__(self, "states", tuple(f"x{i}" for i in range(n)))
        object.__setattr__(self, "states", tuple(self.states))
        names = self.states
        if len(names) != n or len(set(names)) != n or not all(isinstance(s, str) and s.isascii() and s.isidentifier()
                                                             for s in names):
            raise GainTableError(f"{self.name}: states must be {n} distinct ASCII identifiers, got {list(names)}")

    def __repr__(self) -> str:
        """What the table is, in one line, without its matrices: the dataclass repr printed every phase's
        gain and covariances (22 kB for the 50 phases of the position example).

        Examples
        --------
        >>> import cfdesign
        >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
        >>> table  # doctest: +ELLIPSIS
        <GainTable 'IMU + GPS position (...)': position, discrete T = 0.02 s, filter form, period 50, ...>
        >>> repr(table).split("; ")[2]
        'sensors accelerometer (input, order 2, 50 Hz), gps (measurement, order 0, 1 Hz)>'
        """
        timing = ("continuous" if self.sample_time_s is None
                  else f"discrete T = {self.sample_time_s:g} s, {self.gain_form} form")
        ports = ", ".join(f"{s.name} ({s.role}, order {s.order}, {s.rate_hz:g} Hz)" for s in self.sensors)
        return (f"<GainTable {self.name!r}: {self.structure}, {timing}, period {self.period}, "
                f"output {self.output}; states {', '.join(self.states)}; sensors {ports}>")

    def _family(self):
        """The quantity family of a designer's chain (a key of :data:`DERIVATIVE_NAMES`), from the
        name of state 0; None for a table of other names."""
        return next((f for f, names in DERIVATIVE_NAMES.items() if self.states and self.states[0] == names[0]), None)

    def sensor_units(self) -> dict:
        """The unit of what each sensor reads, where the state names tell the quantity (as
        :meth:`state_units`): the quantity's unit per second to the power of the sensor's
        derivative order (a gyro of a heading table reads rad/s, a GPS of a position table m).

        Returns
        -------
        dict
            ``{sensor: unit}`` in the order of ``sensors``; ``''`` for every sensor of a table
            whose states have other names (a user's own, ``x0``, ...).

        Examples
        --------
        >>> import cfdesign
        >>> cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position"))).sensor_units()
        {'accelerometer': 'm/s²', 'gps': 'm'}
        """
        family = self._family()
        return {s.name: _FAMILY_UNITS[family] + _PER_SECOND[s.order]
                if family is not None and s.order < len(_PER_SECOND) else "" for s in self.sensors}

    def state_units(self) -> tuple:
        """The unit of every state, where the state names tell it (``''`` where they do not).

        The designer names a chain's states by their quantity and derivative order
        (``heading``, ``heading_rate``; ``position``, ``velocity``; :data:`DERIVATIVE_NAMES`)
        and a bias state after its sensor (``gyro_bias``, ``accelerometer_correction``): such a
        state has the unit of what its sensor reads.  Angles are in rad, positions in m, their
        derivatives per second to the power of the order.  A table with other names (a user's
        own, ``x0``, ...) has no known units.

        Returns
        -------
        tuple of str
            One unit per state, in the order of ``states``.

        Examples
        --------
        >>> import cfdesign
        >>> cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position"))).state_units()
        ('m', 'm/s', 'm/s²')
        """
        family = self._family()
        if family is None:
            return ("",) * len(self.states)
        orders = {s.name: s.order for s in self.sensors}
        units = []
        for name in self.states:
            stem, _, index = name.rpartition("_")
            name = stem if index.isdigit() and stem else name  # velocity_1: a name made unique by its index
            owner = name.rsplit("_", 1)[0] if name.endswith(("_bias", "_correction")) else None
            if name in DERIVATIVE_NAMES[family]:
                order = DERIVATIVE_NAMES[family].index(name)
            elif owner is not None:
                order = orders.get(owner, QUANTITY_ORDERS.get(owner))  # a shared bias: `rate_correction`
            else:
                order = None
            units.append(_FAMILY_UNITS[family] + _PER_SECOND[order] if order is not None and order < len(_PER_SECOND)
                         else "")
        return tuple(units)

    @property
    def period(self) -> int:
        """Number of phases of the gain schedule (1 for a single-rate table)."""
        return len(self.K)

    @property
    def inputs(self) -> tuple:
        """Input sensors, by column of ``B``."""
        return tuple(s for s in self.sensors if s.role == "input")

    @property
    def measurements(self) -> tuple:
        """Measurement sensors, by row of ``H``."""
        return tuple(s for s in self.sensors if s.role == "measurement")

    @property
    def has_kalman_gains(self) -> bool:
        """The gains came from the table's model by a Riccati equation (DARE, periodic DARE,
        CARE), so ``cfdesign.designer.gains_for_schedule`` can recompute them for another
        arrival pattern; fixed or hand-typed gains have no model to recompute them from."""
        solver = self.provenance.get("solver", {})
        method = str(solver.get("method", "") if isinstance(solver, dict) else "")
        return method.startswith(("dare", "periodic_dare", "care"))

    def sensor(self, name: str) -> SensorPort:
        """The port of one sensor.

        Parameters
        ----------
        name : str
            Sensor name.

        Returns
        -------
        SensorPort
            Its role, row or column, derivative order and rate.

        Raises
        ------
        GainTableError
            The table has no sensor of that name (the message lists its sensors).
        """
        for s in self.sensors:
            if s.name == name:
                return s
        raise GainTableError(f"{self.name} has no sensor {name!r} (sensors: {', '.join(self.sensor_names())})")

    @property
    def predicted_std(self) -> float:
        """Predicted steady-state standard deviation of the estimate the table outputs
        (``output``; first state); for a multirate table the largest of its phases' (the RMS over
        the period, which the RMS error over a whole log approaches, is the 'predicted' figure of
        ``cfdesign run --reference`` and the second one of the design summary)."""
        return self.predicted_std_of(self.output)

    def predicted_std_of(self, output: str, state: int = 0) -> float:
        """Predicted steady-state standard deviation of one state, worst phase.

        Parameters
        ----------
        output : {'posterior', 'prior'}
            ``posterior``: the estimate after the step's readings (covariance ``P_filtered``);
            ``prior``: the one-step prediction (``P``).
        state : int
            Index of the state (0: the common quantity).

        Returns
        -------
        float
            Standard deviation in the state's unit (rad, m, ...).

        Raises
        ------
        GainTableError
            ``output`` is not ``'posterior'`` or ``'prior'`` (any other word gave the prior's),
            or ``state`` is not a state index.

        Examples
        --------
        >>> import cfdesign
        >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
        >>> table.predicted_std_of("posterior") <= table.predicted_std_of("prior")
        True
        """
        _require_output(output, self.name)
        n = self.F.shape[0]
        if isinstance(state, bool) or not isinstance(state, numbers.Integral) or not 0 <= state < n:
            raise GainTableError(f"{self.name}: state must be an index from 0 to {n - 1} ({', '.join(self.states)}), "
                                 f"got {state!r}")
        covs = self.P_filtered if output == "posterior" else self.P
        return float(np.sqrt(max(c[state, state] for c in covs)))

    def phase_model(self, phase: int) -> tuple:
        """The model and gain of one phase.

        Parameters
        ----------
        phase : int
            Phase, taken modulo the period.

        Returns
        -------
        F, B, H_k, K_k : ndarray
            ``H_k`` keeps the rows of the sensors measured at that phase and ``K_k`` their gain
            columns (the per-phase view of a multirate table); ``F`` and ``B`` are the table's.

        Raises
        ------
        InputError
            ``phase`` is not an integer.
        """
        if isinstance(phase, bool) or not isinstance(phase, numbers.Integral):  # ('a' % period: a raw TypeError)
            raise InputError(f"{self.name}: phase must be an integer, got {phase!r:.40}")
        rows = list(self.schedule.rows(phase))
        return self.F, self.B, self.H[rows, :], self.K[phase % self.period][:, rows]

    def sensor_names(self, role: str | None = None) -> list:
        """Sensor names, inputs first (by column of ``B``), then measurements (by row of ``H``).

        Parameters
        ----------
        role : {'input', 'measurement'}, optional
            Only the sensors of this role.

        Returns
        -------
        list of str
            The names, inputs first, then measurements.

        Raises
        ------
        InputError
            ``role`` is another value (a misspelt role listed no sensor).
        """
        if role not in (None, "input", "measurement"):
            raise InputError(f"{self.name}: role must be 'input' or 'measurement' (or None for all), got {role!r:.40}")
        return [s.name for s in self.sensors if role is None or s.role == role]

    # ------------------------------------------------------------------ python-control and plots
    def transfer_functions(self, output: str | None = None) -> dict:
        """The band of every sensor of a single-rate table as a python-control transfer function.

        Each band is named after its sensor (system ``T_<sensor>``, input ``<sensor>``, output
        ``estimate``) and computed from the table's own ``F, B, H, K`` for the estimate it
        outputs; ``dt`` is the sample time (0 for continuous tables).  ``'sum'`` is exactly 1
        when the bands pass the complementarity identity
        (:func:`cfdesign.linear.identity_residual`).  numpy and python-control only.

        A transfer function holds polynomial coefficients, which cannot represent a filter
        whose poles lie within rounding of ``z = 1`` (crossovers below about 1e-7 of the sample
        rate): where its response is more than ``POLYNOMIAL_RTOL`` (1e-6) from the table's bands
        (:func:`cfdesign.verify.polynomial_error`) a ``RuntimeWarning`` says so and by how much;
        :meth:`bode` and ``cfdesign verify`` use the state-space responses, which stay accurate.

        Parameters
        ----------
        output : {'posterior', 'prior'}, optional
            The estimate whose bands to give (default: the table's ``output``).

        Returns
        -------
        dict
            ``{sensor: control.TransferFunction, ..., 'sum': control.TransferFunction}``.

        Raises
        ------
        GainTableError
            A multirate table (its bands change with the phase: see :meth:`bode` and
            :func:`cfdesign.plot.lifted_system`), or an ``output`` other than ``'posterior'`` and
            ``'prior'``.

        Examples
        --------
        >>> import cfdesign
        >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
        >>> sorted(table.transfer_functions())
        ['compass', 'gyro_heading', 'odometry_rate', 'sum']
        """
        from .analysis import named_transfer_functions
        from .verify import IDENTITY_RTOL, band_polynomials, polynomial_error

        if output is not None:
            _require_output(output, self.name)
        if self.period != 1:
            raise GainTableError(f"{self.name} is multirate (period {self.period}): its bands change with the phase; "
                                 "cfdesign.plot.lifted_system(table) gives the lifted system at the period rate")
        error, omega = polynomial_error(self, output)
        if not error <= POLYNOMIAL_RTOL:
            import warnings

            warnings.warn(f"{self.name}: its bands as polynomials differ from the filter by up to {error:.3g} "
                          f"(relative, at {omega / (2 * math.pi):.4g} Hz): the poles are too close to z = 1 for "
                          "polynomial coefficients at this sample rate; table.bode() and "
                          "cfdesign.linear.band_responses give the accurate responses", RuntimeWarning, stacklevel=2)
        bands = band_polynomials(self, 0, output)[0]
        exact = linear.identity_residual(bands) <= IDENTITY_RTOL
        total = (np.ones(1), np.ones(1)) if exact else None
        tfs = named_transfer_functions(bands, self.sample_time_s if self.domain == "z" else 0, self.name, total)
        if not exact:
            import functools
            import operator

            tfs["sum"] = functools.reduce(operator.add, tfs.values())
        return tfs

    def bode(self, omega=None, *, hz: bool = False, title: str | None = None, fig=None):
        """Bode diagram of the table.

        Draws :func:`cfdesign.plot.table_bode_plot`: the bands and their crossovers; for
        multirate tables the per-phase gains and the lifted system's response at the period rate.

        Parameters
        ----------
        omega : array_like, optional
            Angular frequencies in rad/s, also with ``hz=True`` (as ``control.bode_plot``);
            default: a grid spanning the poles.
        hz : bool
            Label the frequency axis in Hz instead of rad/s.
        title : str, optional
            Figure title (default: the table's name).
        fig : matplotlib.figure.Figure, optional
            Figure to draw into.

        Returns
        -------
        matplotlib.figure.Figure
            The figure: magnitude (dB) and phase (deg) axes.

        Raises
        ------
        InputError
            ``omega`` is not a non-empty 1-D array of positive finite angular frequencies (rad/s,
            at most 1e100).
        """
        from .plot import table_bode_plot

        return table_bode_plot(self, omega, hz=hz, title=title, fig=fig)

    def observer(self):
        """The symbolic observer of a single-rate table, with its gains.

        Gives bands, the exact proof, poles and zeros of the estimate the table outputs: posterior
        tables as the filter-form update gain, prior tables as the predictor gain.  Needs sympy.

        Returns
        -------
        cfdesign.symbolic.Observer
            The observer of the table's structure with the table's gains (and sample time)
            substituted.

        Raises
        ------
        GainTableError
            A multirate table (its bands change with the phase).

        Notes
        -----
        The observer is built from the table's stored doubles, taken as exact rationals, so its
        proof is exact arithmetic on those numbers: the gains as stored, the model ``F, B, H`` as
        the simplest rational within two ulp of each double (``_model_exact``), so that a
        sampled chain's ``T^2/2`` and ``T^3/6`` (5e-05 and 1.6666666666666668e-07 at 100 Hz) are
        the ``1/20000`` and ``1/6000000`` the structure has.  A ``chain`` with two or more inputs of one
        order (two gyros) stores weighted ``B`` columns whose rounded sum can miss the chain's
        column by an ulp: its proof then fails by about 1e-17 although the design was proved
        (the table does not record the exact weights).  ``cfdesign verify`` checks such tables
        with a rounding tolerance; :func:`cfdesign.designer.designed_observer` with the design
        file rebuilds the exact structure.
        """
        from .symbolic.observer import Observer, Sensor

        if self.period != 1:
            raise GainTableError(f"{self.name} is multirate (period {self.period}): its bands change with the phase")
        sensors = [Sensor(s.name, s.order, s.role, s.index) for s in self.sensors]
        F, B, H = (_model_exact(M) for M in (self.F, self.B, self.H))
        if self.domain == "s":
            return Observer(F, B, H, _exact(self.K[0]), sensors, name=self.name)
        Kp, L = linear.gain_pair(self.F, self.K[0], self.gain_form)
        form, K = ("filter", L) if self.output == "posterior" else ("predictor", Kp)
        obs = Observer(F, B, H, _exact(K), sensors, domain="z",
                       sample_time=self.sample_time_s, gain_form=form, name=self.name)
        return obs

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        """The JSON form of the table.

        Returns
        -------
        dict
            Plain lists and numbers, with ``format_version``; ``measured`` lists the sensors read
            at each phase (the schedule).
        """
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["sensors"] = [s.to_dict() for s in self.sensors]
        d["states"] = list(self.states)
        d["measured"] = self.schedule.per_phase_names()
        del d["schedule"]
        for key in ("F", "B", "H", "Q", "R"):
            d[key] = np.asarray(d[key]).tolist()
        for key in ("K", "P", "P_filtered"):
            d[key] = [np.asarray(m).tolist() for m in d[key]]
        return {"format_version": FORMAT_VERSION, **d}

    def to_json(self) -> str:
        """The table as JSON text.

        Returns
        -------
        str
            Full float precision; no NaN or Infinity tokens.
        """
        return json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n"

    def save(self, path) -> Path:
        """Write the table as JSON, atomically.

        A failure leaves any previous file as it was (:mod:`cfdesign.files`).

        Parameters
        ----------
        path : str or Path
            File to write (conventionally ``*.json``).

        Returns
        -------
        Path
            The path written.

        Raises
        ------
        OutputError
            The file cannot be written.

        Examples
        --------
        >>> import cfdesign, tempfile, pathlib
        >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
        >>> path = table.save(pathlib.Path(tempfile.mkdtemp()) / "gains.json")
        >>> cfdesign.load_gains(path).K[0].shape == table.K[0].shape
        True
        """
        from .files import write_text

        return write_text(path, self.to_json())

    @classmethod
    def from_dict(cls, d: dict, source: str = "gain table") -> GainTable:
        """Build a table from its JSON form after validating it (:func:`validate`).

        Parameters
        ----------
        d : dict
            The JSON form (:meth:`to_dict`).
        source : str
            What to call the table in messages.

        Returns
        -------
        GainTable
            The validated table.

        Raises
        ------
        GainTableError
            The data fails the schema or its parts do not fit together.
        """
        return validate(d, source)

    @classmethod
    def _from_json(cls, d: dict, source: str) -> GainTable:
        kw = {k: d[k] for k in cls.__dataclass_fields__ if k in d}
        try:
            n, m = len(d["F"]), len(d["H"])
            p = len(d["B"][0]) if d["B"] else 0
            shapes = {"F": (n, n), "B": (n, p), "H": (m, n), "Q": (n, n), "R": (m, m)}
            for key, shape in shapes.items():
                kw[key] = _array(d[key], shape, f"{source}: {key}")
            for key in ("K", "P", "P_filtered"):
                shape = (n, m) if key == "K" else (n, n)
                kw[key] = [_array(M, shape, f"{source}: {key}[{k}]") for k, M in enumerate(d[key])]
            kw["sensors"] = tuple(SensorPort.from_dict(s) for s in d["sensors"])
            _check_ports(kw["sensors"], p, m, source)
            names = [s.name for s in column_order(kw["sensors"]) if s.role == "measurement"]
            kw["schedule"] = Schedule.from_names(names, d["measured"])
        except ValueError as exc:
            raise GainTableError(f"{source}: {exc}") from None
        return cls(**kw)


def column_order(ports) -> tuple:
    """Sensors in the column order of a table's ``G``/``D``: inputs by index, then measurements by index.

    Parameters
    ----------
    ports : iterable
        Sensors with ``role`` and ``index`` (:class:`SensorPort`, or a structure's sensors).

    Returns
    -------
    tuple
        The same sensors, in column order.
    """
    return tuple(sorted(ports, key=lambda s: (s.role != "input", s.index)))


def _model_exact(M):
    """Model matrices as exact rationals: the simplest rational within two ulp of each double
    (:func:`cfdesign.symbolic.observer.model_number`: a sampled model's rounded entries as the
    exact ones of its structure)."""
    from .symbolic.observer import model_number

    return [[model_number(float(v)) for v in row] for row in np.asarray(M, dtype=float)]


def _exact(M):
    from .symbolic.observer import exact_number

    return [[exact_number(float(v)) for v in row] for row in np.asarray(M, dtype=float)]


def _array(value, shape, what) -> np.ndarray:
    """A float array of ``shape`` from nested lists (an empty dimension may be given as [])."""
    try:
        a = np.array(value, dtype=float)
    except ValueError:
        raise GainTableError(f"{what} is ragged: its rows differ in length") from None
    if a.size == 0 and 0 in shape:
        a = a.reshape(shape)
    _shape_of(a, shape, what)
    if not np.isfinite(a).all():
        raise GainTableError(f"{what} has a value that is not finite")
    if a.size and np.abs(a).max() > MAX_ENTRY:
        raise GainTableError(f"{what} has an entry of magnitude {np.abs(a).max():.3g}, beyond the limit "
                             f"{MAX_ENTRY:g} of a filter's numbers")
    return a


def _no_constant(token):
    raise ValueError(f"{token} is not a JSON number (gain tables hold finite numbers only)")


def _integer(token):
    """A JSON integer; one of more digits than any double has (309) is refused here, as Python's
    limit of 4300 digits refused it with advice to call sys.set_int_max_str_digits()."""
    if len(token.lstrip("-")) > 309:
        raise ValueError(f"an integer of {len(token.lstrip('-'))} digits is beyond the range of a double")
    return int(token)


def _no_duplicates(pairs) -> dict:
    """A JSON object whose keys are distinct: with two ``K`` a reader (or a diff) sees the first
    and json keeps the last, so a table could show one filter and run another."""
    out = dict(pairs)
    if len(out) != len(pairs):
        seen = set()
        dup = next(k for k, _ in pairs if k in seen or seen.add(k))
        raise ValueError(f"key {dup!r} given twice in one object")
    return out


def _require_output(output, name: str) -> None:
    """GainTableError unless ``output`` names an estimate (``linear.OUTPUTS``)."""
    if not isinstance(output, str) or output not in linear.OUTPUTS:
        raise GainTableError(f"{name}: output must be one of {', '.join(linear.OUTPUTS)}, got {output!r}")


def require_table(value, what: str) -> None:
    """Refuse anything but a :class:`GainTable` where a function needs one.

    A path passed as a table used to fail deep inside with a raw ``AttributeError``.

    Parameters
    ----------
    value : object
        What the caller was given.
    what : str
        The function, as the message names it (``'Runtime'``).

    Raises
    ------
    GainTableError
        ``value`` is not a GainTable; for a path the message says to read it with
        :func:`load_gains`.
    """
    if isinstance(value, GainTable):
        return
    if isinstance(value, (str, bytes, os.PathLike)):
        hint = f": read the table file with cfdesign.load_gains({os.fsdecode(value)!r})"
    else:
        hint = " (cfdesign.design(spec) makes one, cfdesign.load_gains(path) reads one)"
    raise GainTableError(f"{what} takes a GainTable, got {type(value).__name__}{hint}")


def load_gains(path) -> GainTable:
    """Read a gain table written by :meth:`GainTable.save <cfdesign.gains.GainTable.save>` (or ``cfdesign design -o``).

    Parameters
    ----------
    path : str or Path
        JSON file.

    Returns
    -------
    GainTable
        The validated table.

    Raises
    ------
    GainTableError
        ``path`` is not a path (or is empty), the file cannot be read, is larger than a gain
        table can be, is not UTF-8 JSON (NaN and Infinity tokens and keys given twice in one
        object included), fails the schema, or its parts do not fit together; the message
        names the file and the field.

    Examples
    --------
    >>> import cfdesign, tempfile, pathlib
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> loaded = cfdesign.load_gains(table.save(pathlib.Path(tempfile.mkdtemp()) / "gains.json"))
    >>> loaded.sensor_names(), bool((loaded.K[0] == table.K[0]).all())
    (['odometry_rate', 'gyro_heading', 'compass'], True)
    """
    path = path_of(path, GainTableError, "load_gains")
    try:
        size = path.stat().st_size
        if size > MAX_TABLE_BYTES:
            raise GainTableError(f"{path}: {size} bytes is more than a gain table holds (limit {MAX_TABLE_BYTES})")
        raw = read_limited(path, MAX_TABLE_BYTES)
        if len(raw) > MAX_TABLE_BYTES:  # a device or a pipe: no size until it is read
            raise GainTableError(f"{path}: more than {MAX_TABLE_BYTES} bytes, more than a gain table holds")
    except OSError as exc:
        raise GainTableError(f"cannot read gain table {path}: {exc.strerror or exc}") from None
    except ValueError as exc:  # a NUL character in the path
        raise GainTableError(f"cannot read gain table {str(path)!r}: {exc}") from None
    try:
        text = utf8_text(raw)
    except ValueError as exc:
        raise GainTableError(f"{path}: {exc}") from None
    try:
        data = json.loads(text, parse_constant=_no_constant, parse_int=_integer, object_pairs_hook=_no_duplicates)
    except RecursionError:
        raise GainTableError(f"{path}: not a gain table: JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError (with the place), and the hooks' refusals (a NaN, a key twice)
        what = _not_json(text) if not text.lstrip().startswith("{") else None  # a table starts with '{'
        raise GainTableError(f"{path}: {what or f'not valid JSON: {exc}'}") from None
    return GainTable.from_dict(data, str(path))


#: the first line of a TOML file: a comment, a [section] or [[array]] header, a key = value
_TOML_LINE = re.compile(r"#|\[\[?\s*[A-Za-z_][\w.\"' -]*\]\]?\s*(#.*)?$|[A-Za-z_][\w.-]*\s*=")


def _not_json(text: str) -> str | None:
    """What a file that is not JSON and does not start as a table is, where that can be told: an
    empty file, a CSV of gains, a design file.  Each was 'not valid JSON: Expecting value: line 1
    column 1 (char 0)', which said nothing of what to read instead."""
    body = text.strip()
    if not body:
        return "the file is empty: a gain table is the JSON file that cfdesign design -o writes"
    first = body.splitlines()[0]
    if first.startswith("phase,state"):
        return ("this is a CSV of the gains (cfdesign export --format csv), which holds the gains only: commands "
                "read the JSON gain table (cfdesign design -o, cfdesign export --format json)")
    if _TOML_LINE.match(first):
        return ("this looks like a design file (TOML), not a gain table (JSON): cfdesign design FILE -o table.json "
                "makes its table")
    return None
