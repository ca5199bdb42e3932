"""From a specification to optimal gains: structure -> noise model -> Riccati -> GainTable.

The data flow: the symbolic structure gives ``F, B, H`` and the gain pattern;
the sensors' noise gives ``Q`` and ``R``; the Riccati equation (CARE, DARE, or the periodic
DARE when the sensors run at different rates) gives the optimal gains; the exact proof and a
stability check are attached to the resulting :class:`~cfdesign.gains.GainTable`.

Noise model (units in :mod:`cfdesign.noise`): the white noise of an input sensor enters
through its column ``b`` of ``Bc`` as ``Qc += b q b^T`` (continuous designs) or, held over the
step, through the discrete ``B`` as ``Q += B sigma^2 B^T`` (discrete designs,
:func:`held_input_noise`); a random-walk bias enters the sensor's bias state as
``Qc[i, i] += q_bias``, discretised by Van Loan.  A measurement sensor contributes ``R_ii``: its per-sample variance
(discrete) or its PSD (continuous).

Gain patterns: a structure whose gain matrix is full (CKF³, DCKF³, the position filter) gets
the Kalman gain (Carreira et al. eqs. (23), (28); Vasconcelos et al. Sec. 3).  A sparse
pattern (CF³, Carreira et al. eq. (13)) cannot express it; its free gains are chosen to minimise the steady-state error
variance of the estimate, ``P[0, 0]`` of the Lyapunov equation for that gain - the best the
structure can do, which the paper notes is not the optimum in general.
"""

from __future__ import annotations

import functools
import json
import math
import numbers
import platform
import warnings
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from fractions import Fraction
from functools import reduce
from pathlib import Path

import numpy as np
from scipy import linalg

from . import __version__, linear
from .blas import single_thread
from .errors import CfdesignError, NotDetectableError, SpecError
from .gains import DERIVATIVE_NAMES, MAX_PERIOD, GainTable, Schedule, SensorPort, column_order
from .noise import van_loan, zoh
from .riccati import kalman_continuous, kalman_discrete, periodic_dare
from .spec import QUANTITY_ORDERS, FilterSpec, checked_spec, did_you_mean
from .timing import nearest_tick
from .units import check_sensor_figures

#: structures stored for use without the symbolic engine (:meth:`Structure.load`)
STRUCTURES_DIR = Path(__file__).resolve().parent / "structures"

__all__ = ["design", "design_from_structure", "Structure", "numeric_structure", "multirate_schedule",
           "build_structure", "noise_covariances", "held_input_noise",
           "designed_observer"]

_RATE_RTOL = 1e-9


def multirate_schedule(rates_hz: dict, inputs=(), sample_time_s: float | None = None,
                       offsets_s: dict | None = None) -> tuple:
    """The base tick and the phases at which each sensor is read.

    The base rate is the fastest sensor's (or ``1/sample_time_s``).  A sensor at ``rate_hz``
    reads every ``base/rate`` ticks: when that ratio is a fraction ``p/q`` (a 3 Hz GPS beside a
    100 Hz IMU: ``100/3``) it reads ``q`` times every ``p`` ticks, at the ticks nearest its
    arrival times ``j/rate + offset`` (``round(j p/q + offset/T)``, where :mod:`cfdesign.timing` places
    them: 0, 33, 67 for the GPS).
    The period is the least common multiple of the ``p``.  Input sensors drive the model every
    step and must run at the base rate.

    Parameters
    ----------
    rates_hz : dict
        ``{sensor: rate (Hz)}`` of every sensor.
    inputs : sequence of str
        The input sensors (they must run at the base rate).
    sample_time_s : float, optional
        Base sample time (s); default ``1 /`` the fastest rate.
    offsets_s : dict, optional
        ``{sensor: offset (s)}``: delays a sensor's first reading (a compass that arrives
        0.37 s into each second).

    Returns
    -------
    sample_time_s : float
        The base tick (s).
    schedule : cfdesign.gains.Schedule
        The measurement sensors read at each phase of the period.

    Raises
    ------
    SpecError
        Naming the sensor: a rate that is not a positive number, an input slower than the base
        rate, a rate faster than the base
        rate, a rate slower than ``base / MAX_PERIOD`` (one reading a period at most), or rates
        whose period exceeds :data:`~cfdesign.gains.MAX_PERIOD` steps.

    Examples
    --------
    >>> from cfdesign.designer import multirate_schedule
    >>> T, schedule = multirate_schedule({"imu": 100.0, "gps": 3.0}, inputs=("imu",))
    >>> T, schedule.period, schedule.phases("gps")
    (0.01, 100, (0, 33, 67))
    """
    for name, rate in rates_hz.items():  # 0 raised a raw ZeroDivisionError, a negative rate gave a schedule
        if isinstance(rate, bool) or not isinstance(rate, numbers.Real) or not 0 < rate < math.inf:
            raise SpecError(f"sensors.{name}.rate_hz must be a positive number of hertz, got {rate!r}")
    base = 1.0 / sample_time_s if sample_time_s else max(rates_hz.values())
    offsets_s = offsets_s or {}
    ratios = {}
    origin = f" (1 / sample_time_s, sample_time_s = {sample_time_s:g} s)" if sample_time_s else ""
    for name, rate in rates_hz.items():
        ratio = _ratio(name, base / rate, base, rate, origin)
        if name in inputs and ratio != 1:
            raise SpecError(f"sensors.{name}.rate_hz: input sensor {name} must run at the base rate {base:g} Hz"
                            f"{origin}, not {rate:g} Hz")
        if name not in inputs:
            ratios[name] = ratio
    period = reduce(math.lcm, (r.numerator for r in ratios.values()), 1)
    if period > MAX_PERIOD:
        raise SpecError(f"sensors: the rates give a period of {period} base steps (more than {MAX_PERIOD}); "
                        "choose rates with a smaller common multiple")
    ticks = {}
    for name, r in ratios.items():
        shift = offsets_s.get(name, 0.0) * base
        ticks[name] = [int(nearest_tick(j * r + shift)) for j in range(period * r.denominator // r.numerator)]
    return 1.0 / base, Schedule.from_ticks(list(ratios), ticks, period)


def _ratio(name, ratio, base, rate, origin="") -> Fraction:
    """``base/rate`` as the fraction ``p/q`` it is (to 1e-9), with a period ``p`` within the cap
    (``origin``: where the base rate comes from, for messages)."""
    if ratio < 1 - _RATE_RTOL:
        raise SpecError(f"sensors.{name}.rate_hz: {rate:g} Hz is faster than the base rate {base:g} Hz{origin}"
                        + _exact_sample_time(ratio, rate, origin))
    if ratio > MAX_PERIOD * (1 + _RATE_RTOL):
        raise SpecError(f"sensors.{name}.rate_hz: {rate:g} Hz is slower than the period of at most {MAX_PERIOD} "
                        f"base steps allows: at least {base / MAX_PERIOD:g} Hz beside the base rate {base:g} Hz"
                        f"{origin}")
    frac = Fraction(ratio).limit_denominator(MAX_PERIOD)
    if abs(frac - ratio) > _RATE_RTOL * ratio or frac.numerator > MAX_PERIOD:
        raise SpecError(f"sensors.{name}.rate_hz: {rate:g} Hz is not a fraction of the base rate {base:g} Hz{origin} "
                        f"with a period of at most {MAX_PERIOD} steps (ratio {ratio:.9g})"
                        + (_exact_sample_time(ratio, rate, origin) or _nearest_rate(ratio, base)))
    return frac


def _exact_sample_time(ratio, rate, origin) -> str:
    """The advice on a ``sample_time_s`` rounded in the file (0.033333 beside a 30 Hz sensor; 0.066667
    beside a 10 Hz one, 2 readings every 3 steps): the exact one, when the base rate comes from it
    (``origin``) and ``ratio`` is within 0.1 % of a fraction ``p / q`` with ``q`` up to 100: ``T = q / (p
    rate)``."""
    frac = Fraction(ratio).limit_denominator(100)
    if not origin or not frac or abs(ratio - frac) > 1e-3 * ratio:
        return ""
    p, q = frac.numerator, frac.denominator
    formula = "1 / rate_hz" if p == q == 1 else f"1 / ({p} rate_hz)" if q == 1 else f"{q} / ({p} rate_hz)"
    return f"; sample_time_s = {q / (p * rate)!r} ({formula}) puts it on the ticks"


def _nearest_rate(ratio, base) -> str:
    """The advice on a rate without a short period (a GPS declared at 3.333 Hz beside 100 Hz): the
    rate within 1 % of it whose period is shortest, written with the digits that design it."""
    for bound in (10, 100, 1000, MAX_PERIOD):
        near = Fraction(1 / ratio).limit_denominator(bound)  # rate / base = q / p with p <= bound
        if near and abs(near * ratio - 1) <= 0.01:
            return (f"; rate_hz = {float(base * near):.12g} is {100 * abs(near * ratio - 1):.2g} % from it, with a "
                    f"period of {near.denominator} steps (cfdesign run follows a sensor whose arrivals differ "
                    "from its rate_hz)")
    return ""


@dataclass(frozen=True)
class StructurePort:
    """A sensor of a :class:`Structure`: as :class:`~cfdesign.gains.SensorPort` without the rate,
    plus the state that estimates an input sensor's bias (``bias_state``)."""

    name: str
    role: str
    index: int
    order: int
    bias_state: int | None = None


@dataclass(frozen=True)
class Structure:
    """What a design needs from a structure, as numbers: the output of the symbolic stage.

    The symbolic engine turns a structure (``dckf3``, ``cf2`` order 2, ...) into this once;
    everything after it (noise, Riccati, the gain table) is numpy/scipy and runs without
    sympy, so a navigation filter can design its gains at start-up from a stored structure
    (:meth:`load`).

    Attributes
    ----------
    name : str
        Name of the structure (e.g. ``cf2``).
    discrete : bool
        Discrete structures are the zero-order-hold discretisation of ``(Fc, Bc)``.
    Fc, Bc : ndarray
        The continuous model (the discrete ``F, B`` at any sample time follow from it).
    H : ndarray
        Measurement matrix, shape (m, n).
    pattern : tuple of tuple
        The gain matrix: a gain's name where an entry is free, else its (fixed) value.
    sensors : tuple of StructurePort
        The sensors' ports, inputs then measurements.
    proved : bool
        The exact complementarity proof with the gains left symbolic (so it holds for every
        value they take).
    """

    name: str
    discrete: bool
    Fc: np.ndarray
    Bc: np.ndarray
    H: np.ndarray
    pattern: tuple
    sensors: tuple
    proved: bool

    @classmethod
    def from_observer(cls, obs) -> Structure:
        """The numeric structure of a symbolic observer; runs its exact proof.

        Parameters
        ----------
        obs : cfdesign.symbolic.Observer
            With symbolic gains; a discrete observer must carry its continuous model
            (``continuous=(Fc, Bc)``) for the noise discretisation.

        Returns
        -------
        Structure
            The numeric structure of ``obs``.

        Raises
        ------
        SpecError
            A discrete observer without its continuous model, or whose discrete ``F, B`` are not
            the zero-order hold of it (the noise would be discretised for another model).
        """
        if obs.continuous is None:
            raise SpecError(f"structure {obs.name}: a discrete observer needs its continuous model "
                            "(Observer(..., continuous=(Fc, Bc))) for the noise discretisation")
        Fc, Bc = (np.array(M.evalf(17), dtype=float) for M in obs.continuous)
        out = cls(obs.name, obs.discrete, Fc, Bc, np.array(obs.H.evalf(17), dtype=float),
                  tuple(tuple(row) for row in obs.gain_pattern()),
                  tuple(StructurePort(x.name, x.role, x.index, x.order, x.bias_state) for x in obs.sensors),
                  obs.proof().holds)
        if obs.discrete:
            dt = 0.1 if obs._sample_time_symbol is not None else float(obs.sample_time)
            mine, ref = out.model(dt), obs.numeric_model(dt)
            off = [k for k in ("F", "B") if not np.allclose(mine[k], ref[k], rtol=1e-12, atol=1e-15)]
            if off:  # the user's observer: its continuous model is the one the noise is discretised with
                k, verb = off[0], "is" if len(off) == 1 else "are"
                sym = " (T is symbolic: compared there)" if obs._sample_time_symbol is not None else ""
                raise SpecError(f"structure {obs.name}: its discrete {' and '.join(off)} {verb} not the "
                                f"zero-order hold of continuous=(Fc, Bc) at T = {dt:g} s{sym} ({k} = "
                                f"{_row_text(ref[k])}, the hold gives {_row_text(mine[k])}); build them with "
                                "cfdesign.symbolic.zoh(Fc, Bc, T)")
        return out

    @property
    def domain(self) -> str:
        """``'z'`` for a discrete structure, ``'s'`` for a continuous one."""
        return "z" if self.discrete else "s"

    @property
    def gains(self) -> tuple:
        """Names of the free gains, sorted."""
        return tuple(sorted({e for row in self.pattern for e in row if isinstance(e, str)}))

    @property
    def full_pattern(self) -> bool:
        """Every entry a distinct free gain (the Kalman gain fits it)."""
        names = [e for row in self.pattern for e in row]
        return all(isinstance(e, str) for e in names) and len(set(names)) == len(names)

    def fixed(self, values: dict) -> Structure:
        """The structure with some gains given numbers (the rest stay free).

        Parameters
        ----------
        values : dict
            ``{gain name: value}``; names not in the pattern are ignored.

        Returns
        -------
        Structure
            A new structure with fewer free gains.
        """
        pattern = tuple(tuple(float(values[e]) if isinstance(e, str) and e in values else e for e in row)
                        for row in self.pattern)
        return replace(self, pattern=pattern)

    def model(self, dt: float | None = None) -> dict:
        """The numeric model at a sample time.

        Parameters
        ----------
        dt : float, optional
            Sample time (s) of a discrete structure; ignored for continuous ones.

        Returns
        -------
        dict
            ``F, B, H`` (discrete at ``dt``: the zero-order hold of ``Fc, Bc``) and ``Fc, Bc``.
        """
        if self.discrete:
            F, B = zoh(self.Fc, self.Bc, dt)
        else:
            F, B = self.Fc, self.Bc
        return {"F": F, "B": B, "H": self.H, "Fc": self.Fc, "Bc": self.Bc}

    def to_dict(self) -> dict:
        """The JSON form stored in ``cfdesign/structures/``.

        Returns
        -------
        dict
            Plain lists, strings and numbers (JSON-serialisable).
        """
        return {"name": self.name, "discrete": self.discrete, "Fc": self.Fc.tolist(), "Bc": self.Bc.tolist(),
                "H": self.H.tolist(), "pattern": [list(r) for r in self.pattern],
                "sensors": [vars(x) for x in self.sensors], "proved": self.proved}

    @classmethod
    def from_dict(cls, d: dict) -> Structure:
        """A structure from its JSON form (:meth:`to_dict`).

        Parameters
        ----------
        d : dict
            A dictionary as written by :meth:`to_dict`.

        Returns
        -------
        Structure
            The structure.
        """
        n = len(d["Fc"])
        return cls(d["name"], bool(d["discrete"]), np.array(d["Fc"], dtype=float).reshape(n, n),
                   np.array(d["Bc"], dtype=float).reshape(n, -1), np.array(d["H"], dtype=float).reshape(-1, n),
                   tuple(tuple(r) for r in d["pattern"]), tuple(StructurePort(**x) for x in d["sensors"]),
                   bool(d["proved"]))

    @classmethod
    def load(cls, name: str) -> Structure:
        """A structure stored with cfdesign (``cfdesign/structures/NAME.json``), without sympy.

        Parameters
        ----------
        name : str
            Stored structure, e.g. ``cf2-order2-discrete`` or ``position``.

        Returns
        -------
        Structure
            The stored structure.

        Raises
        ------
        SpecError
            No stored structure of that name (the message lists them).

        Examples
        --------
        >>> from cfdesign.designer import Structure
        >>> s = Structure.load("position")
        >>> s.domain, s.gains, s.proved
        ('z', ('k1', 'k2', 'k3'), True)
        """
        path = STRUCTURES_DIR / f"{name}.json"
        try:
            return cls.from_dict(json.loads(path.read_text()))
        except FileNotFoundError:
            known = ", ".join(sorted(p.stem for p in STRUCTURES_DIR.glob("*.json")))
            raise SpecError(f"no stored structure {name!r} (stored: {known})") from None


#: the design file lines of a discrete filter with multirate sensors, for structures that have no
#: discrete form of their own (ckf3) or whose sparse gains are single-rate only (cf3): the CKF3's
#: full gain over the same three bands
_FULL_CF3 = 'structure = "cfn", bands = 3, full = true, discrete = true'


def multirate_redesign(structure: str) -> str:
    """What to write in a design file for a discrete multirate filter of ``structure``.

    Parameters
    ----------
    structure : str
        A structure's name (``cf3``, ``ckf3``, ``cf2``, ...).

    Returns
    -------
    str
        ``discrete = true`` where the structure's own discrete form takes multirate sensors;
        for ``cf3`` and ``ckf3`` (sparse gains designed for single-rate sensors only, and no
        discrete form) the ``cfn`` of three bands with a full gain.
    """
    return _FULL_CF3 if structure in ("cf3", "ckf3") else "discrete = true"


def build_structure(spec: FilterSpec):
    """The symbolic observer a spec names, with its options and ports applied.

    Parameters
    ----------
    spec : FilterSpec
        The parsed design file.

    Returns
    -------
    cfdesign.symbolic.Observer
        With symbolic gains, its sensors named as in the spec.

    Raises
    ------
    SpecError
        Unknown structure, an option that does not apply to it, a missing ``bands``, a sensor
        that does not fit a port, a ``sample_time_s`` for a continuous structure; the message
        names the field.
    """
    from .errors import StructureError
    from .symbolic.filters import STRUCTURE_OPTIONS, STRUCTURES, structure

    if spec.structure == "chain":
        obs = _chain_observer(spec)
        if spec.sample_time_s is not None and not obs.discrete:
            raise SpecError("sample_time_s: the chain is continuous (set discrete = true)")
        _check_sensors(spec, obs)
        _check_offsets(spec, obs)
        return obs
    if spec.structure not in STRUCTURES:
        raise SpecError(f"structure: unknown structure {spec.structure!r}; choose one of "
                        f"{', '.join([*STRUCTURES, 'chain'])}{did_you_mean(spec.structure, [*STRUCTURES, 'chain'])}")
    if any(x.role is not None for x in spec.sensors):
        raise SpecError(f"sensors.{next(x.name for x in spec.sensors if x.role)}.role: applies to structure "
                        f"chain only ({spec.structure} fixes each sensor's role)")
    options = {"order": spec.order, "bands": spec.bands, "discrete": spec.discrete, "full": spec.full}
    for key, value in options.items():
        if value is not None and key not in STRUCTURE_OPTIONS[spec.structure]:
            hint = f"; a discrete CKF3 is {_FULL_CF3}" if (key, spec.structure) == ("discrete", "ckf3") else ""
            raise SpecError(f"{key}: does not apply to structure {spec.structure}{hint}")
    if spec.structure == "cfn" and spec.bands is None:
        raise SpecError("bands: missing field (cfn needs the number of bands)")
    try:
        obs = structure(spec.structure, **options)
    except StructureError as exc:
        raise SpecError(f"structure {spec.structure}: {exc}") from None
    obs = _apply_ports(spec, obs)
    if spec.sample_time_s is not None and not obs.discrete:
        raise SpecError(f"sample_time_s: {obs.name} is continuous (set discrete = true where the structure allows)")
    _check_sensors(spec, obs)
    _check_offsets(spec, obs)
    return obs


@functools.lru_cache(maxsize=128)
def _cached_structure(name, order, bands, discrete, ports, full=None) -> Structure:
    from .symbolic.filters import structure

    obs = structure(name, order=order, bands=bands, discrete=discrete, full=full)
    return Structure.from_observer(obs.renamed(dict(ports)) if ports else obs)


@functools.lru_cache(maxsize=128)
def _cached_chain(order, inputs, measurements, weights, bias, discrete) -> Structure:
    from fractions import Fraction

    from .symbolic.filters import chain

    return Structure.from_observer(chain(order, inputs, measurements, weights=[Fraction(w) for w in weights],
                                         bias=bias, discrete=discrete))


def numeric_structure(spec: FilterSpec) -> Structure:
    """:func:`build_structure` as a :class:`Structure`, cached.

    The symbolic work, proof included, runs once per structure, options and ports.

    Parameters
    ----------
    spec : FilterSpec
        The parsed design file.

    Returns
    -------
    Structure
        The structure the spec names, with its exact proof run.

    Raises
    ------
    SpecError
        As :func:`build_structure`.
    """
    if spec.structure == "chain":
        order, inputs, measurements, weights, bias = _chain_layout(spec)
        return _cached_chain(order, tuple(inputs), tuple(measurements), tuple(str(w) for w in weights), bias,
                             bool(spec.discrete))
    build_structure(spec)  # checks the spec against the structure (cheap: no band is derived)
    ports = tuple(sorted((x.port, x.name) for x in spec.sensors if x.port is not None))
    return _cached_structure(spec.structure, spec.order, spec.bands, spec.discrete, ports, spec.full)


def _chain_layout(spec: FilterSpec) -> tuple:
    """``(order, inputs, measurements, weights, bias)`` of a ``chain`` design file.

    Each sensor's derivative order comes from ``measures``; sensors of the chain's ``order``
    are inputs (unless ``role`` says otherwise, which is refused), lower orders measurements.
    The inputs are combined with the minimum-variance weights of their white noise,
    ``w_i = (1 / q_i) / sum_j (1 / q_j)`` (``q`` the PSD), exact rationals summing to one; a
    rate-correction (bias) state is added when an input has a random-walk bias.
    """
    from fractions import Fraction

    if spec.order is None:
        raise SpecError("order: missing field (chain: the derivative order of the input sensors, e.g. 1 for "
                        "gyros driving an angle, 2 for accelerometers driving a position)")
    for key, value in (("bands", spec.bands), ("full", spec.full)):
        if value is not None:
            raise SpecError(f"{key}: does not apply to structure chain")
    inputs, measurements = [], []
    for x in spec.sensors:
        field = f"sensors.{x.name}"
        if x.port is not None:
            raise SpecError(f"{field}.port: does not apply to structure chain (its sensors are named by the file)")
        if x.measures is None:
            raise SpecError(f"{field}.measures: missing field (a chain places each sensor by what it measures: "
                            f"{', '.join(QUANTITY_ORDERS)})")
        order = QUANTITY_ORDERS.get(x.measures)
        if order is None:
            raise SpecError(f"{field}.measures: unknown sensor kind {x.measures!r} "
                            f"(known: {', '.join(QUANTITY_ORDERS)}){did_you_mean(x.measures, QUANTITY_ORDERS)}")
        role = x.role or ("input" if order == spec.order else "measurement")
        if role == "input" and order != spec.order:
            raise SpecError(f"{field}.role: an input of a chain of order {spec.order} measures derivative order "
                            f"{spec.order}, not {x.measures!r} (order {order})")
        if role == "measurement" and order >= spec.order:
            raise SpecError(f"{field}.measures: a measurement of a chain of order {spec.order} has a lower "
                            f"derivative order, not {x.measures!r} (order {order}); raise the chain's order")
        if role == "input":
            inputs.append(x)
        else:
            measurements.append((x.name, order))
    if not inputs:
        raise SpecError(f"sensors: a chain of order {spec.order} needs an input sensor measuring derivative order "
                        f"{spec.order} (e.g. measures = \"rate\" for order 1)")
    if not measurements:
        raise SpecError("sensors: a chain needs at least one measurement sensor of a lower derivative order")
    inverse = [1 / Fraction(x.noise.psd(x.rate_hz)) if x.noise.psd(x.rate_hz) > 0 else None for x in inputs]
    if any(v is None for v in inverse):
        weights = [Fraction(1, len(inputs))] * len(inputs) if all(v is None for v in inverse) else \
            [Fraction(0 if v is not None else 1) for v in inverse]
        weights = [w / sum(weights) for w in weights]
    else:
        weights = [v / sum(inverse) for v in inverse]
    if any(w == 0 for w in weights):
        raise SpecError("sensors: an input with zero noise beside a noisy one would take all the weight; give it "
                        "its noise figure")
    bias = any(x.bias.model == "random_walk" for x in inputs)
    return spec.order, [x.name for x in inputs], measurements, weights, bias


def _chain_observer(spec: FilterSpec):
    from .errors import StructureError
    from .symbolic.filters import chain

    order, inputs, measurements, weights, bias = _chain_layout(spec)
    try:
        return chain(order, inputs, measurements, weights=weights, bias=bias, discrete=bool(spec.discrete))
    except StructureError as exc:
        raise SpecError(f"structure chain: {exc}") from None


def _apply_ports(spec, obs):
    """Rename the structure's sensors after the physical sensors that play them (``port``)."""
    ports = {x.port: x.name for x in spec.sensors if x.port is not None}
    if not ports:
        return obs
    known = {s.name for s in obs.sensors}
    for x in spec.sensors:
        if x.port is not None and x.port not in known:
            raise SpecError(f"sensors.{x.name}.port: {obs.name} has no sensor {x.port!r} "
                            f"(it has {', '.join(sorted(known))}){did_you_mean(x.port, known)}")
    players = {}
    for x in spec.sensors:
        if x.port is not None and players.setdefault(x.port, x.name) != x.name:
            raise SpecError(f"sensors.{x.name}.port: {players[x.port]} and {x.name} both play {obs.name}'s port "
                            f"{x.port!r}; one sensor plays each port")
    # a sensor that plays another port keeps its name only if the structure's port of that name is
    # played too: the renamed structure had two sensors of one name (an unnamed StructureError)
    final = [ports.get(s.name, s.name) for s in obs.sensors]
    clash = next((n for n in final if final.count(n) > 1), None)
    if clash is not None:
        raise SpecError(f"sensors.{clash}.port: {clash} plays {obs.name}'s port {spec.sensor(clash).port!r}, and "
                        f"no sensor plays its port {clash!r} (port = {clash!r}): two sensors would be called "
                        f"{clash}; rename the sensor, or name the sensor that plays {clash!r}")
    return obs.renamed(ports)


def _port_hint(sensor, obs) -> str:
    """How a sensor of another name plays a port: the port that reads what it measures, if one does
    (a 'gyro' measuring rate was told port = "angle", the first name in the alphabet)."""
    order = QUANTITY_ORDERS.get(sensor.measures)
    fits = sorted(x.name for x in obs.sensors if x.order == order)
    which = f"port = \"{fits[0]}\": it reads {sensor.measures}" if fits else \
        f"port = \"{sorted(x.name for x in obs.sensors)[0]}\", say"
    return f"; a sensor of another name plays one of them with port = \"...\" ({which})"


def _check_sensors(spec, obs):
    names = {x.name for x in obs.sensors}
    for x in spec.sensors:
        if x.name not in names:
            raise SpecError(f"sensors.{x.name}: {obs.name} has no such sensor (it has {', '.join(sorted(names))})"
                            + (did_you_mean(x.name, names) or _port_hint(x, obs)))
    for s in obs.sensors:
        given = spec.sensor(s.name)
        if given.measures is not None:
            order = QUANTITY_ORDERS.get(given.measures)
            if order is None:
                raise SpecError(f"sensors.{s.name}.measures: unknown sensor kind {given.measures!r} "
                                f"(known: {', '.join(QUANTITY_ORDERS)}){did_you_mean(given.measures, QUANTITY_ORDERS)}")
            if order != s.order:
                raise SpecError(f"sensors.{s.name}.measures: {obs.name} uses {s.name} as a sensor of derivative "
                                f"order {s.order}, not {given.measures!r}")
        check_sensor_figures(s.name, given.units, s.order)  # figures given with a unit fit its quantity


def _check_offsets(spec, obs):
    """Refuse an ``offset_s`` the design would drop in silence: the schedule places only the
    measurements of a discrete design (a continuous one has no ticks; an input is read at
    every base tick)."""
    for s in obs.sensors:
        if not spec.sensor(s.name).offset_s:
            continue
        if not obs.discrete:
            raise SpecError(f"sensors.{s.name}.offset_s: {obs.name} is continuous, without ticks to delay a reading "
                            "to; offsets apply to discrete designs (discrete = true where the structure allows)")
        if s.role == "input":
            raise SpecError(f"sensors.{s.name}.offset_s: {s.name} is an input, read at every base tick; offsets "
                            "apply to measurement sensors")


def noise_covariances(obs, spec: FilterSpec, model: dict, discrete: bool, inputs: bool = True):
    """The noise covariances of a design (before discretisation).

    An input sensor's white noise enters through its column ``b`` of ``Bc`` as
    ``Qc += b q b^T``; a random-walk bias enters the sensor's bias state; a measurement sensor
    gives ``R_ii``.

    Parameters
    ----------
    obs : Structure or cfdesign.symbolic.Observer
        The structure (its sensors, with roles, indices and bias states).
    spec : FilterSpec
        The sensors' noise figures.
    model : dict
        :meth:`Structure.model` (``Fc``, ``Bc``, ``H``).
    discrete : bool
        Give ``R`` as per-sample variances (discrete designs) instead of PSDs.
    inputs : bool
        Include the input sensors' white noise in ``Qc`` (False: only the bias random walks; a
        discrete design adds the held readings' noise itself, :func:`held_input_noise`).

    Returns
    -------
    Qc : ndarray, shape (n, n)
        Continuous process noise PSD over the states.
    R : ndarray, shape (m, m)
        Measurement noise covariance (per sample) or PSD.

    Raises
    ------
    SpecError
        A random-walk bias the structure has no state for, a bias state without process noise
        (optimal gains would not stabilise), zero measurement noise, or figures too large to
        square; the message names the sensor.
    """
    n = model["Fc"].shape[0]
    Qc = np.zeros((n, n))
    R = np.zeros((model["H"].shape[0],) * 2)
    for s in obs.sensors:
        x = spec.sensor(s.name)
        if s.role == "input":
            b = model["Bc"][:, s.index]
            Qc += np.outer(b, b) * (x.noise.psd(x.rate_hz) if inputs else 0.0)
            if s.bias_state is None and x.bias.model == "random_walk":
                raise SpecError(f"sensors.{s.name}.bias: {obs.name} has no state for a bias of {s.name}; "
                                "choose a structure that estimates it (e.g. cf2 order 2, dckf3, position)")
            if s.bias_state is not None:
                shared = [t for t in obs.sensors if t.bias_state == s.bias_state]
                if (x.bias.psd == 0 and spec.gains is None and getattr(spec, "crossover", None) is None
                        and all(spec.sensor(t.name).bias.psd == 0 for t in shared)):
                    raise SpecError(f"sensors.{s.name}.bias: {obs.name} estimates the {s.name} bias, which needs "
                                    "model = 'random_walk' with a density (a constant bias gives the bias state no "
                                    "process noise, so no stabilising optimal gain exists)")
                # the bias enters as the reading does: scaled by the input's weight against the bias state's
                # own entry (1 for the named filters; w_i for the inputs of a weighted chain)
                col, state = np.abs(model["Bc"][:, s.index]), np.abs(model["Fc"][:, s.bias_state])
                weight = col.max() / state.max() if state.max() > 0 else 1.0
                Qc[s.bias_state, s.bias_state] += x.bias.psd * weight**2
        elif x.bias.model == "random_walk":
            raise SpecError(f"sensors.{s.name}.bias: {obs.name} has no state for a bias of {s.name}, so a "
                            "random-walk bias there cannot be designed for (a constant bias is allowed: it "
                            "only enters simulations)")
        else:
            R[s.index, s.index] = x.noise.variance(x.rate_hz) if discrete else x.noise.psd(x.rate_hz)
            if R[s.index, s.index] == 0:
                raise SpecError(f"sensors.{s.name}.noise: zero measurement noise makes R singular; "
                                "give a positive std or density")
    if not (np.all(np.isfinite(Qc)) and np.all(np.isfinite(R))):
        raise SpecError("sensors: a noise or bias figure is too large to square in floating point")
    return Qc, R


def held_input_noise(obs, spec: FilterSpec, model: dict) -> np.ndarray:
    """The discrete process noise of the input sensors' white noise: ``sum_j B_j sigma_j^2 B_j^T``.

    An input reading is held over the step (``x[k+1] = F x[k] + B u[k]``), so its noise ``n[k]``
    (per-sample variance ``sigma^2``, or ``density^2 * rate`` for a density) enters the state as
    ``B n[k]``: a rank-one covariance per input.  The Van Loan integral of the same noise taken as
    continuous white noise (``b q b^T``) agrees for a rate driving an angle, but not beyond: for an
    acceleration driving a position its position entry is ``T^3 q / 3`` against ``T^3 q / 4``
    held, and a chain of order 3 at 10 Hz predicted a velocity error 12 % above the one a log of
    held readings gives (``python benchmarks/bench_predicted.py --random 60 --seed 2``, case 12).

    Parameters
    ----------
    obs : Structure or cfdesign.symbolic.Observer
        The structure (its input sensors and their columns of ``B``).
    spec : FilterSpec
        The sensors' noise figures.
    model : dict
        :meth:`Structure.model` at the design's sample time (the discrete ``B``).

    Returns
    -------
    ndarray, shape (n, n)
        The inputs' share of the discrete ``Q`` (state units squared).
    """
    Q = np.zeros((model["B"].shape[0],) * 2)
    for s in obs.sensors:
        if s.role == "input":
            x = spec.sensor(s.name)
            b = model["B"][:, s.index]
            Q += np.outer(b, b) * x.noise.variance(x.rate_hz)
    return Q


def design(spec: FilterSpec, observer=None) -> GainTable:
    """Design a filter: the gains of ``spec`` and everything a :class:`~cfdesign.gains.GainTable` holds.

    The symbolic structure gives ``F, B, H`` and the gain pattern; the sensors' noise gives
    ``Q`` (held input readings, bias walks by Van Loan) and ``R``; then, by what the spec asks for:

    * a full gain pattern: the Kalman gain from the CARE, the DARE, or the periodic DARE when
      the sensors run at different rates (Carreira et al. eqs. (23), (28); Vasconcelos et
      al. Sec. 3);
    * a sparse pattern (CF3, Carreira et al. eq. (13)): the free gains that minimise the
      steady-state error variance of the estimate (Lyapunov equation);
    * ``[gains]``: those gains fixed (all: hand-tuned; some: the rest optimised);
    * ``[crossover]``: the gains that put the band crossovers at the given frequencies.

    The exact proof is re-run for the bands of the estimate the table outputs: with the
    designed gains substituted (single-rate tables), or with the gains symbolic in the gain
    form whose state is that estimate (multirate: every phase at once); the poles (or
    monodromy multipliers) are checked.  ``docs/derivations.md``, "Optimal gains"
    and "Multirate gains", derives each step.

    Parameters
    ----------
    spec : FilterSpec
        From :func:`~cfdesign.spec.load_spec` or :func:`~cfdesign.spec.parse_spec`.
    observer : cfdesign.symbolic.Observer, optional
        Replaces the structure the spec names: any observer built on the engine, with
        symbolic gains and sensors named as in the spec.

    Returns
    -------
    GainTable
        Model, gain per phase in the spec's gain form, predicted covariances ``P`` (prior) and
        ``P_filtered`` (posterior), ``Q``, ``R``, sensors and schedule, checks and provenance.

    Raises
    ------
    SpecError
        ``spec`` is not a FilterSpec (a path: read it with :func:`~cfdesign.spec.load_spec`), a
        field of a spec built or edited in Python breaks the rules of a design file
        (``cfdesign.spec.checked_spec``: a rate given as text, ``noise=None``), or the spec
        does not fit the structure (a missing or extra sensor, a rate, a bias the structure
        cannot estimate); the message names the field.  An ``observer`` whose bands do not sum
        to one (its model does not follow a sensor's relation: the message says which, as
        ``cfdesign.symbolic.explain``) or whose discrete model is not the zero-order hold
        of its ``continuous`` one.
    RiccatiError
        No stabilising optimal gain exists (a :class:`~cfdesign.errors.NotDetectableError`
        names the mode the sensors cannot see).
    CfdesignError
        The continuous CF3 with white sensor noise has no finite optimum; fixed gains that are
        not stable.

    Examples
    --------
    >>> import cfdesign
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> table.structure, table.gain_form, table.sample_time_s, table.checks["complementary"]
    ('dckf3', 'predictor', 0.2, True)
    >>> print(table.K[0].round(4))
    [[0.6342 0.0198]
     [0.8039 0.    ]]
    """
    spec = checked_spec(spec, "design")  # a spec edited in Python: parse_spec's rules, not a TypeError deep inside
    if observer is None:
        structure = numeric_structure(spec)
    else:
        _check_sensors(spec, observer)
        structure = Structure.from_observer(observer)
        if not structure.proved:  # no gain makes it complementary: the numeric checks would blame the gains
            from .symbolic.proof import explain

            raise SpecError(f"structure {observer.name}: its bands do not sum to one for any gains, so it "
                            f"cannot be designed as a complementary filter: {explain(observer)}")
    table = design_from_structure(structure, spec)
    obs = observer if observer is not None else build_structure(spec)
    if table.period == 1:
        exact = _output_observer(obs, table).proof().holds  # the bands of the estimate the table outputs
        method = f"exact proof with the designed gains, {table.output} output"
    else:  # a gain per phase: the proof with the gains symbolic, of the estimate the table outputs
        exact = _proved_for_output(obs, table.output, structure)
        method = f"exact proof with the gains symbolic, {table.output} output, so it holds at every phase"
    return replace(table, checks={**table.checks, "complementary": exact, "complementary_method": method})


#: exact proofs with the gains symbolic, by observer and gain form (a proof of a long chain takes seconds)
_SYMBOLIC_PROOFS: dict = {}


def _proved_for_output(obs, output: str, structure: Structure) -> bool:
    """The exact proof, with the gains left symbolic, of the bands of the estimate ``output``.

    A discrete observer outputs its state: the prediction in predictor form, the estimate after
    the step's readings in filter form (``x+ = x- + K (y - H x-)``, a direct feedthrough of the
    measurements).  The symbolic gain of either form takes every value, so the proof holds
    for the gain of every phase of a multirate table, whatever form the table's gains are in.
    ``structure`` (built from ``obs``) holds the proof of ``obs`` in its own form.
    """
    import sympy as sp

    form = "filter" if output == "posterior" else "predictor"
    if obs.gain_form == form:
        return structure.proved
    key = (sp.srepr((obs.F, obs.B, obs.H, obs.K, obs.sample_time)), repr(obs.sensors), form)
    if key not in _SYMBOLIC_PROOFS:
        _SYMBOLIC_PROOFS[key] = bool(obs._replace(obs.F, obs.B, obs.H, obs.K, gain_form=form).proof().holds)
    return _SYMBOLIC_PROOFS[key]


def design_from_structure(structure: Structure, spec: FilterSpec) -> GainTable:
    """The numeric stage of :func:`design <cfdesign.designer.design>` (numpy/scipy, no sympy): noise, Riccati, table.

    The table's ``checks['complementary']`` is the structure's exact proof (gains symbolic)
    confirmed by the numeric band identity of the designed gains (:mod:`cfdesign.linear`).

    Parameters
    ----------
    structure : Structure
        From :func:`numeric_structure` or :meth:`Structure.load`.
    spec : FilterSpec
        The sensors, their noise and the design options.

    Returns
    -------
    GainTable
        The designed gain table.

    Raises
    ------
    SpecError
        A field of the spec breaks the rules of a design file (``cfdesign.spec.checked_spec``),
        or the spec does not fit the structure (sensors, gain form or sample time of a
        continuous structure, a bias without a state); the message names the field.
    RiccatiError
        No stabilising optimal gain exists.
    """
    spec = checked_spec(spec, "design_from_structure")
    with single_thread(len(structure.Fc)):  # small dense solves: one BLAS thread (cfdesign.blas)
        return _design_from_structure(structure, spec)


def _design_from_structure(structure: Structure, spec: FilterSpec) -> GainTable:
    _check_sensors(spec, structure)
    _check_wrap(spec, structure)
    structure, fixed = _split_gains(structure, spec.gains)
    inputs = [s.name for s in structure.sensors if s.role == "input"]
    by_row = [s.name for s in column_order(structure.sensors) if s.role == "measurement"]
    rates = {name: spec.sensor(name).rate_hz for name in inputs + by_row}
    if structure.discrete:
        offsets = {name: spec.sensor(name).offset_s for name in by_row}
        dt, schedule = multirate_schedule(rates, inputs, spec.sample_time_s, offsets)  # rows in H order
    else:
        if spec.gain_form == "filter":
            raise SpecError("gain_form: 'filter' applies to discrete filters only")
        if spec.sample_time_s is not None:
            raise SpecError(f"sample_time_s: {structure.name} is continuous "
                            "(set discrete = true where the structure allows)")
        dt, schedule = None, Schedule.from_names(by_row, [by_row])
    model = {**structure.model(dt), "states": state_names(structure, spec)}
    output = _output(spec, structure, model, dt)
    Qc, R = noise_covariances(structure, spec, model, structure.discrete, inputs=not structure.discrete)
    Q = van_loan(model["Fc"], Qc, dt)[1] + held_input_noise(structure, spec, model) if structure.discrete else Qc
    try:
        if spec.crossover is not None:
            result = _crossover_result(structure, model, Q, R, schedule, spec, output, dt)
        elif structure.discrete:
            result = _discrete_gains(structure, model, Q, R, schedule, spec.gain_form, fixed, output)
        else:
            result = _continuous_gains(structure, model, Q, R, fixed)
    except NotDetectableError as exc:
        hidden = _unobservable(structure, spec, model)
        if not hidden:
            raise
        raise NotDetectableError(f"{hidden} ({exc})") from None
    return _table(spec, structure, model, Q, R, dt, schedule, result, output)


def _unobservable(structure, spec, model) -> str:
    """What a failed detectability test means for the design file: the states no measurement
    sees (the null space of the observability matrix ``[H; H F; ...; H F^(n-1)]`` of all the
    measurement rows), e.g. a position with only a velocity measured, and the sensors that are
    measured; ``''`` when every state is seen together and only the schedule leaves a mode unseen."""
    F, H = np.asarray(model["F"], dtype=float), np.asarray(model["H"], dtype=float)
    n = F.shape[0]
    obs = np.vstack([H @ np.linalg.matrix_power(F, k) for k in range(n)]) if H.size else np.zeros((1, n))
    s, vt = np.linalg.svd(obs)[1:]
    rank = int(np.sum(s > 1e-9 * max(s[0], 1e-300)))
    if rank == n:
        return ""
    weight = np.linalg.norm(vt[rank:], axis=0)
    names = state_names(structure, spec)
    hidden = [names[i] for i in range(n) if weight[i] > 1e-6]
    seen = ", ".join(f"{s.name}: {spec.sensor(s.name).measures or 'measurement'}"
                     for s in structure.sensors if s.role == "measurement") or "none"
    one = len(hidden) == 1
    return (f"{', '.join(hidden)} {'is' if one else 'are'} not observable from the measurements ({seen}), so no "
            f"filter corrects {'its' if one else 'their'} drift: add a sensor that measures "
            f"{'it' if one else 'one of them'}, or choose a structure without {'it' if one else 'them'}")


def _output(spec, structure, model, dt=None) -> str:
    """The estimate the table outputs: the spec's ``output``, by default the posterior (after
    each step's readings) for discrete tables; continuous tables have only the prior."""
    if not structure.discrete:
        if spec.output == "posterior":
            raise SpecError(f"output: {structure.name} is continuous; it has no posterior estimate")
        return "prior"
    if not linear.has_posterior(model["F"], spec.gain_form):
        if spec.output != "prior":  # the default too: it fell to the prior in silence, and the design then
            # failed its own covariance check ('too badly scaled'): a chain's F is invertible, but at a
            # sample time of 1e6 s (dckf3) or 2000 s (position) beyond the condition number gain_pair takes
            raise SpecError(f"output: {structure.name}'s F at T = {dt:g} s has condition number "
                            f"{np.linalg.cond(np.asarray(model['F'], dtype=float)):.3g} (the limit is 1e12), so its "
                            "predictor gains give no posterior estimate (the default output); use gain_form = "
                            "'filter', or output = 'prior'")
        return "prior"
    return spec.output or "posterior"


_LINEAR = {"position", "velocity", "acceleration", "jerk"}


def _check_wrap(spec, structure):
    """``wrap_angle`` only for angles: refused when a sensor measures (or a structure's sensor is
    named after) a linear quantity, or for the position structure."""
    if not spec.wrap_angle:
        return
    linear_sensors = [s.name for s in structure.sensors
                      if s.name in _LINEAR or (spec.sensor(s.name).measures or "") in _LINEAR]
    if structure.name == "position" or spec.structure == "position" or linear_sensors:
        what = f"sensor {linear_sensors[0]!r} measures a" if linear_sensors else "it estimates a"
        raise SpecError(f"wrap_angle: {structure.name} is not an angle filter ({what} linear quantity); "
                        "wrapping to (-pi, pi] applies to headings and other angles only")




def state_names(structure, spec) -> tuple:
    """A name per state: the quantity and its derivatives (``heading``, ``heading_rate``;
    ``position``, ``velocity``), and a bias state after its sensor: ``<sensor>_bias`` when the
    state is subtracted from the sensor's reading in the model, ``<sensor>_correction`` when it
    is added (the DCKF3's second state is the rate added to the gyro: minus its bias)."""
    Fc, Bc = structure.Fc, structure.Bc
    n = len(Fc)
    measures = {(spec.sensor(s.name).measures or "") for s in structure.sensors}
    if spec.wrap_angle:
        family = "heading"
    elif structure.name == "position" or measures & _LINEAR or any(s.name in _LINEAR for s in structure.sensors):
        family = "linear"
    else:
        family = "angle"
    names, order = [None] * n, {0: 0}
    for s in structure.sensors:
        if s.role == "input" and s.bias_state is not None:
            rows = np.flatnonzero(Bc[:, s.index])
            sign = Fc[rows[0], s.bias_state] * Bc[rows[0], s.index] if rows.size else 1.0
            names[s.bias_state] = f"{_bias_owner(structure, spec, s)}_{'correction' if sign > 0 else 'bias'}"
    for _ in range(n):  # state j is the derivative of state i when i' = j
        for i, d in list(order.items()):
            for j in np.flatnonzero(Fc[i] == 1.0):
                order.setdefault(int(j), d + 1)
    for i in range(n):
        if names[i] is None:
            d = order.get(i)
            names[i] = DERIVATIVE_NAMES[family][d] if d is not None and d < len(DERIVATIVE_NAMES[family]) else f"x{i}"
    if len(set(names)) < n:
        names = [f"{name}_{i}" if names.count(name) > 1 else name for i, name in enumerate(names)]
    return tuple(names)


def _bias_owner(structure, spec, port) -> str:
    """The name a bias state takes: its input sensor's, or, when several inputs share it (two
    gyros of a chain, averaged), the quantity they measure (``rate``): it is the correction
    of their weighted mean, not of one of them."""
    shared = [s for s in structure.sensors if s.role == "input" and s.bias_state == port.bias_state]
    if len(shared) < 2:
        return port.name
    return spec.sensor(port.name).measures or "input"


def _split_gains(structure, gains):
    """``(structure, fixed)``: a partial ``[gains]`` is substituted (the rest stay free and are
    optimised); a complete one is returned as the fixed gains."""
    if not gains:
        return structure, None
    names = set(structure.gains)
    unknown = sorted(set(gains) - names)
    if unknown:
        raise SpecError(f"gains: unknown {', '.join(unknown)} ({structure.name} has gains "
                        f"{', '.join(sorted(names))}){did_you_mean(unknown[0], names)}")
    if set(gains) == names:
        return structure, gains
    return structure.fixed(gains), None


# ---------------------------------------------------------------------------- gains
def _continuous_gains(obs, model, Q, R, fixed=None):
    F, H = model["F"], model["H"]
    if fixed is not None:
        return _fixed_gains(obs, F, H, Q, R, "continuous", fixed, "prior")
    if obs.full_pattern:
        sol = kalman_continuous(F, H, Q, R)
        return {"K": [sol.K], "P": [sol.P], "P_filtered": [sol.P], "solver": _solver_info(sol.solution)}
    return _sparse_gains(obs, F, H, Q, R, "continuous", "prior", model.get("states"))


def _discrete_gains(obs, model, Q, R, schedule, form, fixed=None, output="posterior"):
    F, H = model["F"], model["H"]
    key = "K_filter" if form == "filter" else "K_predictor"
    if fixed is not None:
        if schedule.period != 1:
            also = "" if obs.full_pattern else f" and write {multirate_redesign(obs.name)} (the CKF3's full gain)"
            raise SpecError("gains: fixed gains apply to single-rate filters only; for multirate sensors leave "
                            f"[gains] out{also}")
        return _fixed_gains(obs, F, H, Q, R, form, fixed, output)
    if schedule.period == 1:
        if obs.full_pattern:
            sol = kalman_discrete(F, H, Q, R)
            return {"K": [getattr(sol, key)], "P": [sol.P], "P_filtered": [sol.P_filtered],
                    "solver": _solver_info(sol.solution)}
        return _sparse_gains(obs, F, H, Q, R, form, output, model.get("states"))
    if not obs.full_pattern:
        raise SpecError(f"structure {obs.name}: sparse gain patterns are designed for single-rate sensors only; for "
                        f"multirate sensors write {multirate_redesign(obs.name)} (the CKF3's full gain)")
    return _periodic_gains(F, H, Q, R, schedule, form)


def _periodic_gains(F, H, Q, R, schedule, form) -> dict:
    """Kalman gains of every phase of ``schedule`` (periodic DARE), in gain form ``form``."""
    key = "K_filter" if form == "filter" else "K_predictor"
    rows = [list(schedule.rows(k)) for k in range(schedule.period)]
    sol = periodic_dare(F, [H[r, :] for r in rows], Q, [R[np.ix_(r, r)] for r in rows])
    K = []
    for r, Kk in zip(rows, getattr(sol, key), strict=True):
        full = np.zeros((F.shape[0], H.shape[0]))
        full[:, r] = Kk
        K.append(full)
    return {"K": K, "P": list(sol.P), "P_filtered": list(sol.P_filtered),
            "solver": {"method": "periodic_dare", "residual": float(sol.residual),
                       "monodromy_multipliers": _pairs(sol.monodromy_multipliers)}}


def gains_for_schedule(table: GainTable, schedule: Schedule) -> GainTable:
    """The table's Kalman gains recomputed for another arrival pattern of its sensors.

    The periodic DARE of the table's own model (``F, H, Q, R``, gain form, output) over
    ``schedule``: what the sensors really do (each slow sensor at its own offset, a rate that is
    a fraction of the base rate) instead of what the design assumed.  numpy/scipy only.

    Raises
    ------
    CfdesignError
        The table's gains are not Kalman gains (fixed or sparse: they have no model to be
        recomputed from), or the pattern leaves the filter undetectable.
    """
    if not table.has_kalman_gains:
        method = str(table.provenance.get("solver", {}).get("method", ""))
        raise CfdesignError(f"{table.name}: its gains are not Kalman gains ({method or 'unknown method'}), so they "
                            "cannot be recomputed for another arrival pattern")
    result = _periodic_gains(table.F, table.H, table.Q, table.R, schedule, table.gain_form)
    _check_covariances(table, result)
    mult = np.array([complex(*p) for p in result["solver"]["monodromy_multipliers"]])
    checks = {**{k: v for k, v in table.checks.items() if k not in ("poles", "numeric")},
              "monodromy_multipliers": _pairs(mult), "stable": bool(np.all(np.abs(mult) < 1))}
    provenance = {**table.provenance, "solver": result["solver"],
                  "rescheduled_from": {"period": table.period, "measured": table.schedule.per_phase_names()}}
    if not checks["stable"]:
        raise CfdesignError(f"{table.name}: the gains for this arrival pattern are not stable (monodromy spectral "
                            f"radius {np.abs(mult).max():.6g})")
    # F, B, H are the table's own (already verified): complementarity holds for any gain, so
    # only the new gains' stability is new information
    return replace(table, K=result["K"], P=result["P"], P_filtered=result["P_filtered"], schedule=schedule,
                   gains={}, checks=checks, provenance=provenance)


def _solver_info(sol) -> dict:
    return {"method": f"{sol.kind} ({sol.method})", "residual": float(sol.residual),
            "relative_residual": float(sol.relative_residual), "condition": float(sol.condition),
            "refinement_steps": int(sol.refinement_steps)}


def _error_covariance(F, H, K, Q, R, form):
    """Steady-state error covariance for a fixed gain (a-priori for discrete forms).

    ``P = A P A' + Q + Kp R Kp'`` with ``A = F - Kp H`` (discrete), ``A P + P A' + Q + K R K' = 0``
    (continuous); gain forms as :func:`cfdesign.linear.gain_pair`.
    """
    A = linear.closed_loop(F, H, K, form)
    Kp, _ = linear.gain_pair(F, K, form)
    with warnings.catch_warnings():  # a near-singular equation (poles near the axis): the callers check P
        warnings.simplefilter("ignore", RuntimeWarning)
        if form == "continuous":
            return linalg.solve_continuous_lyapunov(A, -(Q + K @ R @ K.T))
        return linalg.solve_discrete_lyapunov(A, Q + Kp @ R @ Kp.T)


def _stable(eigs, form) -> bool:
    return linear.is_stable(eigs, "s" if form == "continuous" else "z")


def _pattern_gain(pattern, free, values):
    lookup = dict(zip(free, values, strict=True))
    return np.array([[lookup[e] if isinstance(e, str) else e for e in row] for row in pattern])


def _free_names(pattern):
    return sorted({e for row in pattern for e in row if isinstance(e, str)})


def _kalman_gain(F, H, Q, R, form):
    if form == "continuous":
        sol = kalman_continuous(F, H, Q, R)
        return sol.K, sol.P
    sol = kalman_discrete(F, H, Q, R)
    return (sol.K_filter if form == "filter" else sol.K_predictor), sol.P


def _covariances(F, H, K, Q, R, form, P=None):
    """``(P, P_filtered)``: prior and posterior error covariances of a fixed gain (Joseph form
    with the update gain of :func:`cfdesign.linear.gain_pair`; the prior where there is none)."""
    P = _error_covariance(F, H, K, Q, R, form) if P is None else P
    L = linear.gain_pair(F, K, form)[1]
    return P, (P if L is None else linear.posterior_covariance(P, H, L, R))


def _output_covariance(F, H, K, Q, R, form, output):
    """Covariance of the estimate the table outputs."""
    P, P_filtered = _covariances(F, H, K, Q, R, form)
    return P_filtered if output == "posterior" else P


def _gain_result(K, F, H, Q, R, form, solver, optimum, output):
    """Error covariances of a fixed gain, beside the Kalman optimum ``(K_opt, P_opt)`` for comparison."""
    P, P_filtered = _covariances(F, H, K, Q, R, form)
    K_opt, P_opt = optimum
    best = _covariances(F, H, K_opt, Q, R, form, P_opt)[output == "posterior"]
    mine = P_filtered if output == "posterior" else P
    solver = {**solver, "kalman_predicted_variance": float(best[0, 0]), "predicted_variance": float(mine[0, 0])}
    return {"K": [K], "P": [P], "P_filtered": [P_filtered], "solver": solver}


def _fixed_gains(obs, F, H, Q, R, form, fixed, output):
    """Gains given in the spec: check names and stability, predict the error (Lyapunov)."""
    pattern = obs.pattern
    free = _free_names(pattern)
    missing, extra = sorted(set(free) - set(fixed)), sorted(set(fixed) - set(free))
    if missing or extra:
        what = f"missing {', '.join(missing)}" if missing else f"unknown {', '.join(extra)}"
        raise SpecError(f"gains: {what} ({obs.name} has gains {', '.join(free)})")
    K = _pattern_gain(pattern, free, [fixed[e] for e in free])
    if not _stable(np.linalg.eigvals(linear.closed_loop(F, H, K, form)), form):
        raise SpecError(f"gains: the given gains do not stabilise {obs.name}")
    return _gain_result(K, F, H, Q, R, form, {"method": "fixed gains from the spec; error from the Lyapunov equation"},
                        _kalman_gain(F, H, Q, R, form), output)


def _crossover_result(obs, model, Q, R, schedule, spec, output, dt):
    """Gains from the spec's ``[crossover]`` (:mod:`cfdesign.crossover`), their predicted error
    (Lyapunov) beside the Kalman optimum for the same sensors (None where the noise model has
    no stabilising optimum, e.g. a constant bias)."""
    from .crossover import crossover_check, crossover_gains
    from .errors import RiccatiError

    if schedule.period != 1:
        raise SpecError("crossover: applies to single-rate filters (the bands of a multirate table change "
                        "with the phase)")
    form = spec.gain_form if obs.discrete else "continuous"
    hz, damping = spec.crossover["hz"], spec.crossover["damping"]
    gains = crossover_gains(obs, model, dt, form, output, hz, damping)
    F, H = model["F"], model["H"]
    free = _free_names(obs.pattern)
    K = _pattern_gain(obs.pattern, free, [gains[e] for e in free])
    solver = {"method": "crossover design (cfdesign.crossover): adjacent bands of equal magnitude at "
                        + ", ".join(f"{f:g} Hz" for f in hz) + "; error from the Lyapunov equation",
              "crossover_hz": list(hz), "damping": damping,
              "crossovers": [list(c) for c in crossover_check(obs, model, K, form, output, dt, hz)]}
    try:
        optimum = _kalman_gain(F, H, Q, R, form)
    except RiccatiError as exc:
        P, P_filtered = _covariances(F, H, K, Q, R, form)
        mine = P_filtered if output == "posterior" else P
        solver.update(kalman_predicted_variance=None, kalman_note=str(exc), predicted_variance=float(mine[0, 0]))
        return {"K": [K], "P": [P], "P_filtered": [P_filtered], "solver": solver}
    return _gain_result(K, F, H, Q, R, form, solver, optimum, output)


def _sparse_gains(obs, F, H, Q, R, form, output, names=None):
    """Minimise the error variance of the estimate the table outputs over the free entries of
    the pattern (``names``: the states', for messages)."""
    pattern = obs.pattern
    free = _free_names(pattern)

    def cost(values):
        K = _pattern_gain(pattern, free, values)
        if not _stable(np.linalg.eigvals(linear.closed_loop(F, H, K, form)), form):
            return np.inf
        with warnings.catch_warnings():
            warnings.simplefilter("error", linalg.LinAlgWarning)
            try:
                P = _output_covariance(F, H, K, Q, R, form, output)
            except (linalg.LinAlgWarning, np.linalg.LinAlgError):
                return np.inf  # too close to the stability boundary to evaluate
        return P[0, 0] if np.all(np.isfinite(P)) and P[0, 0] > 0 else np.inf

    from scipy import optimize  # here only: its import is a quarter of a second of every `cfdesign run`

    optimum = _kalman_gain(F, H, Q, R, form)
    K_opt = optimum[0]
    start = _sparse_start(obs, pattern, free, K_opt, cost)
    options = {"xatol": 1e-10, "fatol": 1e-16, "maxiter": 20000, "maxfev": SPARSE_FIRST_EVALUATIONS}
    best = optimize.minimize(cost, start, method="Nelder-Mead", options=options)
    edge = _on_the_edge(pattern, free, best.x, F, H, Q, R, form, optimum[1], names)
    if not best.success and not edge:  # a slow search inside the stable region: resume it, up to 40,000 in all
        options["maxfev"] = 40000 - best.nfev
        best = optimize.minimize(cost, best.x, method="Nelder-Mead", options=options)
        edge = _on_the_edge(pattern, free, best.x, F, H, Q, R, form, optimum[1], names)
    scale = 1e3 * max(1.0, np.abs(K_opt).max())
    if edge:
        raise SpecError(f"structure {obs.name}: its sparse gain pattern has no optimum inside the stable region for "
                        f"these noise figures: the error variance of the estimate keeps falling toward the "
                        f"stability boundary, {edge}; use the full-gain structure ({_full_gain_hint(obs.name)}) "
                        "or give gains in [gains]")
    if not best.success and np.abs(best.x).max() <= scale:
        raise SpecError(f"structure {obs.name}: the search for its best sparse gain did not converge "
                        f"({best.message}); give hand-tuned gains in [gains] or use the full-gain structure")
    if np.abs(best.x).max() > scale:
        reached = ", ".join(f"{name} = {value:.3g}" for name, value in zip(free, best.x, strict=True))
        raise SpecError(f"structure {obs.name}: its sparse gain pattern has no finite optimum for these noise "
                        f"figures (the error variance keeps falling as the gains grow: {reached}); "
                        "give hand-tuned gains in [gains] or use the full-gain structure")
    return _gain_result(_pattern_gain(pattern, free, best.x), F, H, Q, R, form,
                        {"method": "sparse gain: Nelder-Mead on the Lyapunov error variance of the estimate",
                         "iterations": int(best.nit)}, optimum, output)


#: evaluations of a sparse search before it is checked for the stability boundary (the searches of
#: ``bench_predicted --random`` that converged inside it took 160-800; those that crept along the
#: boundary ran out of 40,000, 7-13 s)
SPARSE_FIRST_EVALUATIONS = 4000
#: a sparse search ended on the stability boundary when a relative change of this size in one
#: gain, or in all of them together, makes the loop unstable ...
EDGE_STEP = 1e-3
#: ... and a state's error std there exceeds the Kalman gain's this many times (the searches that
#: crept to the boundary gave 1e5-6e5; inside it, bench_predicted --random's sparse optima gave up to
#: 43, and two up to 2.4e3, taken: no gain of theirs is near the boundary, and their P says it)
EDGE_STD_RATIO = 100.0


def _on_the_edge(pattern, free, x, F, H, Q, R, form, P_kalman, names=None) -> str:
    """Where a sparse search ended on the stability boundary, what shows it (the closed loop's
    slowest pole and the state whose error it inflates); ``''`` inside the stable region.

    The output's error variance can fall all the way to the boundary while the other states'
    errors grow without bound (a pole at ``|z| -> 1`` that the output hardly sees): a table
    built there would give an output near its optimum and the other states' estimates (written
    by ``cfdesign run``) useless, and any model error would be integrated."""
    x = np.asarray(x, dtype=float)
    steps = [*(EDGE_STEP * abs(x[i]) * np.eye(x.size)[i] for i in range(x.size)), EDGE_STEP * x]
    near = any(not _stable(np.linalg.eigvals(linear.closed_loop(F, H, _pattern_gain(pattern, free, x + sign * d),
                                                                form)), form)
               for d in steps for sign in (-1.0, 1.0))
    if not near:
        return ""
    K = _pattern_gain(pattern, free, x)
    try:
        P = _error_covariance(F, H, K, Q, R, form)
    except (linalg.LinAlgError, np.linalg.LinAlgError, ValueError):
        P = np.full_like(F, np.inf)
    ratio = np.sqrt(np.abs(np.diag(P)) / np.maximum(np.diag(P_kalman), np.finfo(float).tiny))
    worst = int(np.nanargmax(np.where(np.isfinite(ratio), ratio, np.inf)))
    if np.isfinite(ratio[worst]) and ratio[worst] <= EDGE_STD_RATIO:
        return ""
    eig = np.linalg.eigvals(linear.closed_loop(F, H, K, form))
    rho = np.abs(eig).max()
    pole = f"Re s = {eig.real.max():.3g}" if form == "continuous" else f"|z| = {rho:.6f} (1 - {1.0 - rho:.2g})"
    state = names[worst] if names else f"state {worst}"
    return (f"where the slowest closed-loop pole is at {pole} and the error std of {state} is "
            f"{ratio[worst]:.3g} times the Kalman gain's")


def _full_gain_hint(name: str) -> str:
    """How to ask for the full gain of a sparse structure in a design file."""
    return {"cf3": 'structure = "ckf3"'}.get(name.split("(")[0], "full = true")


def _sparse_start(obs, pattern, free, K_opt, cost):
    """Start from the Kalman gain's entries at the free positions, else from ones."""
    first = {}
    for i, row in enumerate(pattern):
        for j, e in enumerate(row):
            if isinstance(e, str):
                first.setdefault(e, K_opt[i, j])
    for start in (np.array([first[e] for e in free]), np.ones(len(free)), 0.1 * np.ones(len(free))):
        if np.isfinite(cost(start)):
            return start
    raise CfdesignError(f"{obs.name}: no stabilising gain with the structure's sparse pattern was found")


# ---------------------------------------------------------------------------- table
def _row_text(M) -> str:
    """A small matrix on one line, six significant digits: ``[[1, 0.01], [0, 1]]``."""
    return "[" + ", ".join("[" + ", ".join(f"{v:.6g}" for v in row) + "]" for row in np.atleast_2d(M)) + "]"


def _pairs(values) -> list:
    return [[float(np.real(v)), float(np.imag(v))] for v in values]


def _checks(structure, model, result, schedule, form):
    F, H = model["F"], model["H"]
    if schedule.period > 1:
        mult = np.array([complex(*p) for p in result["solver"]["monodromy_multipliers"]])
        return {"complementary": structure.proved, "complementary_method":
                "exact proof with the gains symbolic, so it holds at every phase",
                "monodromy_multipliers": _pairs(mult), "stable": bool(np.all(np.abs(mult) < 1))}
    K = result["K"][0]
    poles = np.linalg.eigvals(linear.closed_loop(F, H, K, form))
    return {"complementary": structure.proved, "complementary_method":
            "exact proof with the gains symbolic, so it holds for the designed gains",
            "poles": _pairs(poles), "stable": _stable(poles, form)}


def _table(spec, obs, model, Q, R, dt, schedule, result, output) -> GainTable:
    form = spec.gain_form if obs.discrete else "continuous"
    checks = _checks(obs, model, result, schedule, form)
    if not checks["stable"]:
        roots = checks.get("poles", checks.get("monodromy_multipliers"))
        worst = max(abs(complex(*r)) if obs.discrete else complex(*r).real for r in roots)
        raise CfdesignError(f"{spec.name}: the designed filter is not stable (worst pole "
                            f"{'magnitude' if obs.discrete else 'real part'} {worst:.6g})")
    gains = dict(spec.gains or {})
    if len(result["K"]) == 1:
        for i, row in enumerate(obs.pattern):
            for j, e in enumerate(row):
                if isinstance(e, str):
                    gains[e] = float(result["K"][0][i, j])
    _check_covariances(spec, result)
    if obs.discrete and not linear.has_posterior(model["F"], form):  # no update gain: no posterior (output
        result = {**result, "P_filtered": list(result["P"])}  # = 'prior'), the P_filtered verify checks is P
    table = GainTable(
        name=spec.name, structure=spec.structure, domain=obs.domain, sample_time_s=dt, gain_form=form,
        sensors=tuple(SensorPort(s.name, s.role, s.index, s.order, spec.sensor(s.name).rate_hz)
                      for s in obs.sensors),
        F=model["F"], B=model["B"], H=model["H"], K=result["K"], P=result["P"],
        P_filtered=result["P_filtered"], schedule=schedule, Q=Q, R=R, gains=gains, wrap_angle=spec.wrap_angle,
        output=output, states=state_names(obs, spec),
        options={k: v for k, v in (("order", spec.order), ("bands", spec.bands), ("discrete", spec.discrete),
                                   ("full", spec.full)) if v is not None},
        provenance={"spec_sha256": spec.sha256, "cfdesign_version": __version__,
                    "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                    "python": platform.python_version(), "solver": result["solver"]},
        checks=checks,
    )
    return _numerically_checked(table)


def _numerically_checked(table: GainTable) -> GainTable:
    """The table with the numeric checks ``cfdesign verify`` applies to it recorded; a table
    that would fail them is refused here, so design and verify never disagree."""
    from .verify import numeric_checks

    found = numeric_checks(table)
    failed = [c for c in found if not c.ok]
    if failed:
        raise CfdesignError(f"{table.name}: the designed table fails a check `cfdesign verify` applies ("
                            f"{failed[0].line()}); the gains are too close to the stability boundary or too "
                            "badly scaled for double precision")
    return replace(table, checks={**table.checks, "numeric": {c.name: c.detail for c in found}})


def _check_covariances(owner, result):
    """Predicted covariances must be covariances: finite, a non-negative diagonal and no entry
    beyond what its variances allow (``|P_ij| <= sqrt(P_ii P_jj)``, which also bounds the asymmetry).
    Tiny fixed gains or near-marginal loops make the Lyapunov solution meaningless: a gain of
    1e-30 gave a negative variance beside entries of 1e12, and a relative test of the diagonal
    against those entries let it through."""
    crossover = isinstance(owner, FilterSpec) and owner.crossover  # the gains came from [crossover]
    for key in ("P", "P_filtered"):
        for k, P in enumerate(result[key]):
            if not covariance_ok(P):
                raise SpecError(f"{'crossover.hz' if crossover else 'gains'}: the predicted error covariance "
                                f"{key}[{k}] cannot be computed reliably (not finite, a negative variance or entries "
                                f"beyond their variances); the gains{' of these crossovers' if crossover else ''} are "
                                "too small, too large or too close to the stability boundary for double precision")


def covariance_ok(P, rtol: float = 1e-6) -> bool:
    """``P`` is a covariance within rounding: finite, square, its diagonal non-negative (to
    ``1e-12`` of the largest variance) and every entry within ``sqrt(P_ii P_jj)`` (to ``rtol``).

    Parameters
    ----------
    P : array_like
        The matrix.
    rtol : float
        Relative slack of the bound on the entries.

    Returns
    -------
    bool
    """
    P = np.asarray(P, dtype=float)
    if P.ndim != 2 or P.shape[0] != P.shape[1] or not np.all(np.isfinite(P)):
        return False
    if P.size == 0:
        return True
    d = np.diag(P)
    scale = max(float(np.max(np.abs(d))), 1e-300)
    if np.min(d) < -1e-12 * scale:
        return False
    v = np.sqrt(np.maximum(d, 0.0))
    return bool(np.all(np.abs(P) <= np.outer(v, v) * (1 + rtol) + 1e-12 * scale))


def designed_observer(spec: FilterSpec, table: GainTable):
    """The symbolic structure of ``spec`` with a table's (single-rate) gains substituted.

    Parameters
    ----------
    spec : FilterSpec
        The design the table was made from.
    table : GainTable
        A single-rate table.

    Returns
    -------
    cfdesign.symbolic.Observer
        With numeric gains, in the gain form whose estimate is the table's output: its bands,
        proof, poles and zeros are those of the estimate the table runs.

    Raises
    ------
    CfdesignError
        A multirate table (its bands change with the phase).
    """
    if table.period != 1:
        raise CfdesignError(f"{table.name} is periodic (period {table.period}): its bands change with the phase")
    return _output_observer(build_structure(spec), table)


def _output_observer(obs, table):
    """``obs`` with the table's gain written in the form whose estimate is the table's output:
    the update gain in filter form for a posterior table, the predictor gain for a prior one
    (:func:`cfdesign.linear.gain_pair`); its bands are those of the estimate that runs."""
    if not obs.discrete:
        return obs.with_gain_matrix(table.K[0], None, None)
    Kp, L = linear.gain_pair(table.F, table.K[0], table.gain_form)
    form, K = ("filter", L) if table.output == "posterior" else ("predictor", Kp)
    return obs.with_gain_matrix(K, form, table.sample_time_s)
