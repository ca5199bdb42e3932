"""Filter design specifications: sensors, noise, rates; TOML design files.

A design file names a structure and describes each of its sensors::

    name = "robot heading"
    structure = "dckf3"            # cf2, cf3, ckf3, dckf3, cfn, position
    gain_form = "predictor"        # discrete: predictor | filter
    # sample_time_s = 0.2          # default: 1 / the fastest sensor's rate
    # wrap_angle = true            # a heading: angle readings and the estimate live in (-pi, pi]
    # output = "posterior"         # discrete: the estimate after each step's readings (default),
    #                              # or "prior", the one-step prediction
    # discrete = true              # cf2, cf3, cfn, chain: continuous unless true
    # order = 2                    # cf2 only;  bands = 4  # cfn only
    # full = true                  # cfn only: a full gain matrix (cfn with 3 bands and full = true is the CKF3)
    # structure = "chain"          # a general kinematic chain: order = the inputs' derivative order,
    #                              # every sensor says what it measures (any number per order:
    #                              # two gyros); role = "input" | "measurement" optional
    # [gains]                      # optional: fixed (hand-tuned) gains instead of optimal ones;
    # k1 = 12.6                    # a subset fixes those gains and optimises the others
    # [crossover]                  # optional: gains that put the band crossovers here instead
    # hz = 0.5                     # Hz; two bands: one frequency, three bands: [0.05, 2.0]
    # damping = 0.707              # cf2 order 2 only: damping ratio of the closed-loop poles

    [sensors.gyro]
    measures = "rate"              # optional check against the structure
    rate_hz = 5.0
    noise = { std = 0.0447 }       # u per sample, or { density = ... } in u/sqrt(Hz)
    bias = { model = "random_walk", density = 1e-4 }   # u/sqrt(s); or constant, value
    # port = "compass"             # optional: the structure's sensor this one plays (default: its name)
    # offset_s = 0.37              # optional: the first reading arrives this long after the base tick 0
    #                              # (a measurement of a discrete design)

Units are SI in the sensor's own quantity ``u`` (rad, rad/s, m, m/s^2).  A noise or bias
figure may instead be text with a datasheet unit, converted to SI by :mod:`cfdesign.units` and
checked against the field (a white-noise density is ``u/sqrt(Hz)``, a random walk
``u/sqrt(s)``)::

    noise = { density = "0.3 deg/sqrt(h)" }                  # a gyro's angle random walk
    bias = { model = "random_walk", density = "10 deg/h/sqrt(h)" }
    noise = { std = "3 mG" }                                   # a magnetometer, rms

Text from a design file is only ever read as TOML data: nothing in it is evaluated.
"""

from __future__ import annotations

import difflib
import hashlib
import keyword
import math
import numbers
import os
import re
import sys
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

from .errors import SpecError
from .files import path_of, read_limited, utf8_text
from .noise import Bias, WhiteNoise
from .units import Quantity, check_bases, check_sensor_figures, parse_quantity, parse_unit

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["SensorSpec", "FilterSpec", "load_spec", "parse_spec", "example_path", "EXAMPLES", "QUANTITY_ORDERS"]

#: what a sensor may measure (``measures = ...``), as the derivative order of the common quantity
QUANTITY_ORDERS = {
    "angle": 0,
    "position": 0,
    "rate": 1,
    "velocity": 1,
    "acceleration": 2,
    "jerk": 3,
}

EXAMPLES_DIR = Path(__file__).resolve().parent / "examples"
#: built-in example design files, by short name
EXAMPLES = {
    "robot-heading": "robot_heading_dckf3.toml",
    "dckf3": "dckf3_fig5.toml",
    "cf3": "cf3_continuous.toml",
    "ckf3": "ckf3_continuous.toml",
    "position": "position_imu_gps.toml",
    "tilt": "tilt_cf2_continuous.toml",
}
_TOP_KEYS = {"name", "structure", "gain_form", "sample_time_s", "discrete", "order", "bands", "sensors",
             "description", "gains", "wrap_angle", "output", "crossover", "full"}
_SENSOR_KEYS = {"measures", "rate_hz", "noise", "bias", "port", "offset_s", "role"}
#: other spellings of a key, for the hint of an unknown one (a name no closer than this to the key)
_ALIASES = {"freq": ("hz", "rate_hz"), "frequency": ("hz", "rate_hz"), "f": ("hz", "rate_hz"), "sigma": ("std",),
            "stddev": ("std",), "std_dev": ("std",), "fs": ("rate_hz",), "hz": ("rate_hz",), "rate": ("rate_hz",),
            "dt": ("sample_time_s",), "type": ("model",), "kind": ("measures",), "delay": ("offset_s",)}
#: ``measures`` of one family or the other, never both in a design (its states are one quantity);
#: acceleration and jerk may be either (there is no separate angular acceleration)
_FAMILIES = {"angle": "angular", "rate": "angular", "position": "linear", "velocity": "linear"}
#: keys of a sensor or of [crossover] written at the top level: where they go
_TOP_ELSEWHERE = {**{key: f"; {key} is a key of a sensor: write it under its [sensors.NAME] header"
                     for key in _SENSOR_KEYS},
                  "hz": "; write it under a [crossover] header", "damping": "; write it under a [crossover] header"}
#: keys of a sensor's noise or bias written in the sensor's own table
_SENSOR_ELSEWHERE = {"std": "; white noise is noise = { std = ... }", "model": "; write bias = { model = ... }",
                     "density": "; write noise = { density = ... } (white noise) or bias = { model = \"random_walk\", "
                                "density = ... }", "value": "; a constant bias is bias = { value = ... }",
                     "name": "; a sensor's name is its table's: [sensors.NAME]"}


@dataclass(frozen=True)
class SensorSpec:
    """One sensor of a design: what it measures, its rate, white noise and bias.

    Attributes
    ----------
    name : str
        The sensor's name: an ASCII identifier (it names log columns and C macros); the
        structure's port of that name unless ``port`` says otherwise.
    rate_hz : float
        Sample rate (Hz).
    noise : cfdesign.noise.WhiteNoise
        White noise: a density (units/sqrt(Hz)) or a per-sample standard deviation (units).
    bias : cfdesign.noise.Bias
        Constant bias (units) or random walk (density in units/sqrt(s)).
    measures : str, optional
        What the sensor reads (a key of :data:`~cfdesign.spec.QUANTITY_ORDERS`: ``angle``, ``rate``,
        ``position``, ``velocity``, ``acceleration``, ...); checked against the structure.
    port : str, optional
        The structure's sensor this one plays (default: its own name).
    offset_s : float
        Delay of the first reading after base tick 0 (s), less than the sensor's period.
    role : {'input', 'measurement'}, optional
        Structure ``chain`` only: inferred from ``measures`` when left out.
    units : tuple
        ``((key, cfdesign.units.Quantity), ...)``: the figures the file gave with a unit
        (``noise.density``, ``noise.std``, ``bias.density``, ``bias.value``), already converted
        to SI in ``noise`` and ``bias``; kept to check their dimensions against the sensor's
        derivative order, and left out of comparisons (a figure with a unit and its SI number
        make equal specs).
    """

    name: str
    rate_hz: float
    noise: WhiteNoise
    bias: Bias
    measures: str | None = None
    port: str | None = None
    offset_s: float = 0.0
    #: ``input`` or ``measurement`` (structure ``chain``; inferred from ``measures`` when left out)
    role: str | None = None
    #: ``((key, Quantity), ...)``: the figures given with a unit (see :mod:`cfdesign.units`)
    units: tuple = field(default=(), compare=False, repr=False)


@dataclass(frozen=True)
class FilterSpec:
    """A whole design: structure, options, gain form and sensors.

    Built by :func:`load_spec` (a TOML design file) or :func:`parse_spec` (a dict); the keys
    are described in the module docstring.

    Attributes
    ----------
    name : str
        Design name (default: the structure).
    structure : str
        ``cf2``, ``cf3``, ``ckf3``, ``dckf3``, ``cfn``, ``position`` or ``chain``.
    sensors : tuple of SensorSpec
        The sensors, in file order.
    gain_form : {'predictor', 'filter'}
        Discrete gain form: ``x[k+1] = F x + B u + K (y - H x)`` or the measurement update
        ``x+ = x- + K (y - H x-)``.
    sample_time_s : float, optional
        Base sample time (s); default ``1 /`` the fastest sensor's rate.
    discrete : bool, optional
        ``cf2``, ``cf3``, ``cfn``, ``chain``: the sampled (ZOH) model instead of the continuous one.
    order : int, optional
        ``cf2``: 1 or 2; ``chain``: the inputs' derivative order.
    bands : int, optional
        ``cfn``: the number of bands.
    sha256 : str
        SHA-256 of the design file's bytes (recorded in the gain table's provenance).
    description : str
        Free text.
    gains : dict, optional
        ``{gain name: value}``: fixed (hand-tuned) gains; the others are optimised.
    wrap_angle : bool
        The quantity is a heading: angle readings and the estimate live in (-pi, pi].
    output : {'posterior', 'prior'}, optional
        The estimate the table gives (default: the posterior for discrete designs).
    crossover : dict, optional
        ``{'hz': (f1, ...), 'damping': zeta or None}``: a design by crossover
        (:mod:`cfdesign.crossover`), frequencies in Hz.
    full : bool, optional
        ``cfn``: a full gain matrix instead of the sparse CF3 pattern.
    """

    name: str
    structure: str
    sensors: tuple
    gain_form: str = "predictor"
    sample_time_s: float | None = None
    discrete: bool | None = None
    order: int | None = None
    bands: int | None = None
    sha256: str = ""
    description: str = ""
    gains: dict | None = None
    wrap_angle: bool = False
    output: str | None = None
    #: ``{'hz': (f1, ...), 'damping': zeta or None}``: a design by crossover (:mod:`cfdesign.crossover`)
    crossover: dict | None = None
    #: cfn: a full gain matrix instead of the sparse CF3 pattern
    full: bool | None = None

    def sensor(self, name: str) -> SensorSpec:
        """The sensor of a given name.

        Parameters
        ----------
        name : str
            Sensor name.

        Returns
        -------
        SensorSpec
            The sensor called ``name``.

        Raises
        ------
        SpecError
            No sensor of that name (the structure needs it).
        """
        for x in self.sensors:
            if x.name == name:
                return x
        raise SpecError(f"sensors.{name}: missing (the structure {self.structure} needs it)")


def example_path(name: str = "robot-heading") -> Path:
    """Path of a built-in example design file.

    Parameters
    ----------
    name : str
        ``robot-heading`` (default), ``dckf3``, ``cf3``, ``ckf3``, ``position`` or ``tilt``
        (:data:`EXAMPLES`).

    Returns
    -------
    Path
        Path of the TOML file shipped with cfdesign.

    Raises
    ------
    SpecError
        No built-in example of that name.

    Examples
    --------
    >>> from cfdesign.spec import example_path
    >>> example_path("position").name
    'position_imu_gps.toml'
    """
    if name not in EXAMPLES:
        raise SpecError(f"no built-in example {name!r}; choose one of {', '.join(EXAMPLES)}")
    return EXAMPLES_DIR / EXAMPLES[name]


#: largest design file read (bytes): a design is a few hundred bytes
MAX_SPEC_BYTES = 1_000_000
#: rates and frequencies a design may name (Hz), and so its times (s): beyond them the ZOH
#: relations and the frequency grid lose every digit (a gain table has the same limits)
MAX_RATE_HZ = 1e9
RATE_RANGE = (1 / MAX_RATE_HZ, MAX_RATE_HZ)
#: crossover damping ratios accepted (a ratio of 1e300 overflowed the gain formulas)
DAMPING_RANGE = (1e-6, 1e6)
#: fixed gains accepted, by magnitude (zero aside): their products with the model stay normal doubles
GAIN_RANGE = (1e-100, 1e100)
#: most sensors a design may have: the exact proof grows faster than cubically with them (32: 5 s;
#: 100: 4 min; 1000, a 60 kB file: 17 GB and no end)
MAX_SENSORS = 32


_FROM_TEXT = "cfdesign.parse_spec(tomllib.loads(text)) reads a design given as text"


def _toml_text(value) -> bool:
    """Whether ``value`` is a design written out as TOML text rather than a path: it spans lines,
    or it is one line of TOML (a ``key = value`` or ``[table]``) and names no file.  A path that
    only starts like one (``lr=0.1.toml``, ``k=2/design.toml``) is not TOML, and stays a path."""
    if not isinstance(value, str) or not value.strip():
        return False
    if "\n" in value.strip():
        return True
    if not re.match(r"\s*(\[[^\]]+\]|[A-Za-z0-9_\"-]+\s*=)", value) or os.path.exists(value):
        return False
    try:
        return bool(tomllib.loads(value))
    except tomllib.TOMLDecodeError:
        return False


def require_spec(value, what: str) -> None:
    """Refuse anything but a :class:`FilterSpec` where a function needs one.

    A path or a dict passed as a spec used to fail deep inside with a raw ``AttributeError``.

    Parameters
    ----------
    value : object
        What the caller was given.
    what : str
        The function, as the message names it (``'design'``).

    Raises
    ------
    SpecError
        ``value`` is not a FilterSpec; the message says how to make one from a path
        (:func:`load_spec`) or a dict (:func:`parse_spec`).
    """
    if isinstance(value, FilterSpec):
        return
    if _toml_text(value):
        raise SpecError(f"{what} takes a FilterSpec, got TOML text: {_FROM_TEXT}")
    if isinstance(value, (str, bytes, os.PathLike)):
        hint = f": read the design file with cfdesign.load_spec({os.fsdecode(value)!r})"
    elif isinstance(value, dict):
        hint = ": validate the dict with cfdesign.parse_spec(data)"
    else:
        hint = " (cfdesign.load_spec(path) reads a design file)"
    raise SpecError(f"{what} takes a FilterSpec, got {type(value).__name__}{hint}")


def checked_spec(spec, what: str = "design") -> FilterSpec:
    """A FilterSpec built or edited in Python, read again by the rules of :func:`parse_spec`.

    ``dataclasses.replace(spec, ...)`` and ``FilterSpec(...)`` skip :func:`parse_spec`: a rate
    given as text, ``noise=None`` or ``gains=[1]`` failed deep inside :func:`cfdesign.design`
    with a raw ``TypeError`` or ``AttributeError``.  Here every field is turned back into its
    design-file table and parsed, so the same rules apply with the same messages, naming the
    field (``sensors.gyro.rate_hz must be positive, got -5``).  A field left ``None`` counts as
    left out of the file (its default); a sensor given as a table, or a noise or bias given as
    one, is read as :func:`parse_spec` reads it.

    Parameters
    ----------
    spec : FilterSpec
        The design to check.
    what : str
        The function, as a message naming a wrong type names it (``'design'``).

    Returns
    -------
    FilterSpec
        The spec as :func:`parse_spec` gives it (numbers as floats, gains ``{}`` as none).

    Raises
    ------
    SpecError
        ``spec`` is not a FilterSpec, its sensors are not SensorSpecs (or tables), two sensors
        share a name, or a field is invalid by the rules of a design file; the message names it.

    Examples
    --------
    >>> import dataclasses, cfdesign
    >>> from cfdesign.spec import checked_spec
    >>> spec = cfdesign.load_spec(cfdesign.example_path("tilt"))
    >>> checked_spec(dataclasses.replace(spec, sample_time_s=-0.01))
    Traceback (most recent call last):
    ...
    cfdesign.errors.SpecError: sample_time_s must be positive, got -0.01
    """
    require_spec(spec, what)
    return parse_spec(_spec_table(spec), sha256=spec.sha256)


def _spec_table(spec: FilterSpec) -> dict:
    """The design-file table of a FilterSpec, :func:`parse_spec`'s inverse; fields left None left out."""
    crossover, gains = spec.crossover, spec.gains
    if isinstance(crossover, dict) and isinstance(crossover.get("hz"), tuple):  # parse_spec's own form
        crossover = {**crossover, "hz": list(crossover["hz"])}
    if isinstance(gains, dict) and not gains:  # no fixed gains (an empty [gains] table is refused in a file)
        gains = None
    table = {"name": spec.name, "structure": spec.structure, "sensors": _sensor_tables(spec.sensors),
             "gain_form": spec.gain_form, "sample_time_s": spec.sample_time_s, "discrete": spec.discrete,
             "order": spec.order, "bands": spec.bands, "description": spec.description, "gains": gains,
             "wrap_angle": spec.wrap_angle, "output": spec.output, "crossover": crossover, "full": spec.full}
    return {key: value for key, value in table.items() if value is not None}


def _sensor_tables(sensors) -> dict:
    """``{name: table}`` of a FilterSpec's sensors (a dict of tables passes as it is)."""
    if isinstance(sensors, dict):
        return sensors
    if not isinstance(sensors, (tuple, list)):
        raise SpecError(f"sensors must be a tuple of SensorSpec, got {type(sensors).__name__}")
    tables = {}
    for i, x in enumerate(sensors):
        if not isinstance(x, SensorSpec):
            raise SpecError(f"sensors[{i}] must be a SensorSpec, got {type(x).__name__} (cfdesign.parse_spec "
                            "reads a [sensors.NAME] table into one)")
        field = _sensor_name(x.name)
        if x.name in tables:
            raise SpecError(f"{field}: two sensors of that name; each sensor needs its own")
        body = {"rate_hz": x.rate_hz, "noise": _figures(x.noise, WhiteNoise, ("density", "std")),
                "bias": _figures(x.bias, Bias, ("model", "density", "value")), "measures": x.measures,
                "port": x.port, "offset_s": x.offset_s, "role": x.role}
        tables[x.name] = _with_units({key: value for key, value in body.items() if value is not None}, x.units)
    return tables


def _with_units(body: dict, units) -> dict:
    """A sensor's table with each figure it was given with a unit written as that text again
    (its checks need the unit), unless the figure has been changed since."""
    for key, q in units if isinstance(units, tuple) else ():
        part, _, name = key.partition(".")
        figures = body.get(part)
        if isinstance(figures, dict) and isinstance(q, Quantity) and figures.get(name) == q.value:
            body[part] = {**figures, name: q.text}
    return body


def _figures(value, kind, keys):
    """The table of a :class:`~cfdesign.noise.WhiteNoise` or :class:`~cfdesign.noise.Bias`;
    anything else as it is, for :func:`parse_spec` to read or name."""
    if not isinstance(value, kind):
        return value
    return {key: getattr(value, key) for key in keys if getattr(value, key) is not None}


def load_spec(path) -> FilterSpec:
    """Read and validate a TOML design file.

    Nothing in the file is evaluated: it is read as TOML data and every field is checked.

    Parameters
    ----------
    path : str or Path
        The design file.

    Returns
    -------
    FilterSpec
        With ``sha256`` of the file's bytes.

    Raises
    ------
    SpecError
        ``path`` is not a path (or is empty), the file cannot be read, is larger than
        :data:`~cfdesign.spec.MAX_SPEC_BYTES`, is not UTF-8 TOML, or a field is missing or
        invalid; the message names the file and the field.

    Examples
    --------
    >>> import cfdesign
    >>> spec = cfdesign.load_spec(cfdesign.example_path("robot-heading"))
    >>> spec.structure, [s.name for s in spec.sensors]
    ('dckf3', ['odometry_rate', 'gyro_heading', 'compass'])
    """
    if _toml_text(path):  # the whole text came back in a 'No such file' message over many lines
        raise SpecError(f"load_spec takes the path of a design file, got TOML text "
                        f"(starting {' '.join(path.split())[:30]!r}): {_FROM_TEXT}")
    path = path_of(path, SpecError, "load_spec")
    try:
        size = path.stat().st_size
        if size > MAX_SPEC_BYTES:
            raise SpecError(f"{path}: {size} bytes is more than a design file holds (limit {MAX_SPEC_BYTES})")
        text = read_limited(path, MAX_SPEC_BYTES)
        if len(text) > MAX_SPEC_BYTES:  # a device or a pipe: no size until it is read
            raise SpecError(f"{path}: more than {MAX_SPEC_BYTES} bytes, more than a design file holds")
    except OSError as exc:
        raise SpecError(f"cannot read design file {path}: {exc.strerror or exc}") from None
    except ValueError as exc:  # a NUL character in the path
        raise SpecError(f"cannot read design file {str(path)!r}: {exc}") from None
    try:
        source = utf8_text(text)  # a BOM (a Windows editor) is not TOML; dropped
    except ValueError as exc:
        raise SpecError(f"{path}: {exc}") from None
    try:
        data = tomllib.loads(source)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path}: malformed TOML: {exc}") from None
    except RecursionError:
        raise SpecError(f"{path}: malformed TOML: nested too deeply") from None
    try:
        return parse_spec(data, sha256=hashlib.sha256(text).hexdigest())
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None


def parse_spec(data: dict, sha256: str = "") -> FilterSpec:
    """Validate a design given as a dict (the parsed TOML).

    Parameters
    ----------
    data : dict
        The design's keys (see the module docstring).
    sha256 : str
        Checksum of the source text, recorded in the gain table's provenance.

    Returns
    -------
    FilterSpec
        The validated design.

    Raises
    ------
    SpecError
        A field is missing, unknown or invalid; the message names it (``sensors.gyro.rate_hz``).

    Examples
    --------
    >>> from cfdesign.spec import parse_spec
    >>> spec = parse_spec({"structure": "cf2", "sensors": {
    ...     "gyro": {"measures": "rate", "rate_hz": 100.0, "noise": {"density": 0.01}},
    ...     "compass": {"measures": "angle", "rate_hz": 100.0, "noise": {"std": 0.05}}}})
    >>> spec.sensor("gyro").rate_hz
    100.0
    >>> parse_spec({"structure": "cf2", "sensors": {"gyro": {"rate_hz": -1, "noise": {"std": 1}}}})
    Traceback (most recent call last):
    ...
    cfdesign.errors.SpecError: sensors.gyro.rate_hz must be positive, got -1
    """
    if isinstance(data, (str, bytes, os.PathLike)):
        what = "TOML text" if _toml_text(data) else f"a {type(data).__name__}"
        raise SpecError(f"parse_spec takes the design as a dict, got {what}: parse_spec(tomllib.loads(text)) "
                        "reads text, cfdesign.load_spec(path) a file")
    if not isinstance(data, dict):
        raise SpecError("a design must be a table")
    _no_unknown(data, _TOP_KEYS, "", _TOP_ELSEWHERE)
    structure = _text(data, "structure", required=True)
    sensors = data.get("sensors")
    if sensors is not None and not isinstance(sensors, dict):
        raise SpecError(f"sensors must be a table of sensors ([sensors.gyro], [sensors.compass], ...), got "
                        f"{_kind(sensors)}")
    if not sensors:
        raise SpecError("sensors: missing field (one [sensors.NAME] table per sensor)")
    if len(sensors) > MAX_SENSORS:
        raise SpecError(f"sensors: {len(sensors)} sensors is more than a design takes (limit {MAX_SENSORS})")
    parsed = tuple(_sensor(name, body) for name, body in sensors.items())
    _distinct_names(parsed)
    check_bases((f"sensors.{x.name}.{key}", q, x.measures) for x in parsed for key, q in x.units)
    for x in parsed:  # the order is known here from measures; else from the structure's port (designer)
        if QUANTITY_ORDERS.get(x.measures) is not None:
            check_sensor_figures(x.name, x.units, QUANTITY_ORDERS[x.measures])
    return FilterSpec(
        name=_text(data, "name") or structure,
        structure=structure,
        sensors=parsed,
        gain_form=_choice(data, "gain_form", ("predictor", "filter"), "predictor"),
        sample_time_s=_number(data, "sample_time_s", "sample_time_s", positive=True, span=RATE_RANGE),
        discrete=_flag(data, "discrete"),
        order=_integer(data, "order"),
        bands=_integer(data, "bands"),
        sha256=sha256,
        description=_text(data, "description") or "",
        gains=_gains(data.get("gains")),
        wrap_angle=bool(_flag(data, "wrap_angle")),
        output=_choice(data, "output", ("posterior", "prior", None), None),
        crossover=_crossover(data),
        full=_flag(data, "full"),
    )


def _distinct_names(sensors) -> None:
    """Sensor names unequal once case is folded (they name C macros, upper-cased, and log columns),
    and ``measures`` of one family: angle and rate, or position and velocity."""
    seen, families = {}, {}  # {family: its first sensor}
    for x in sensors:
        other = seen.setdefault(x.name.casefold(), x.name)
        if other != x.name:
            raise SpecError(f"sensors.{x.name}: {other} and {x.name} differ only in case; they would clash as C "
                            "macros and log columns: rename one")
        family = _FAMILIES.get(x.measures)
        first = next((y for f, y in families.items() if family and f not in (None, family)), None)
        families.setdefault(family, x)
        if first is not None:
            raise SpecError(f"sensors.{x.name}.measures: {x.measures!r} ({_FAMILIES[x.measures]}) beside "
                            f"{first.name}'s {first.measures!r} ({_FAMILIES[first.measures]}); a design estimates "
                            "one quantity: angle and rate, or position and velocity")


def _kind(value) -> str:
    """How a value that should be a table reads in a message: ``an array`` or ``0.04``."""
    return "an array (a [[...]] header makes one; write [...])" if isinstance(value, list) else repr(value)


def _crossover(data):
    """``[crossover]``: ``hz`` (a frequency or an ascending list, Hz) and an optional ``damping``."""
    table = data.get("crossover")
    if table is None:
        return None
    if not isinstance(table, dict):
        raise SpecError("crossover must be a table: [crossover] hz = 0.5")
    _no_unknown(table, {"hz", "damping"}, "crossover.", _above(_TOP_KEYS, "the top level", "crossover"))
    if data.get("gains") is not None:
        raise SpecError("crossover: give either [gains] or [crossover], not both")
    hz = table.get("hz")
    if hz is None:
        raise SpecError("crossover.hz: missing field (a frequency in Hz, or a list for three or more bands)")
    values = hz if isinstance(hz, list) else [hz]
    if not values:
        raise SpecError("crossover.hz: give at least one frequency")
    freqs = tuple(_number({"hz": v}, "hz", f"crossover.hz[{i}]" if isinstance(hz, list) else "crossover.hz",
                          positive=True, span=RATE_RANGE) for i, v in enumerate(values))
    if any(freqs[i + 1] <= freqs[i] for i in range(len(freqs) - 1)):
        raise SpecError(f"crossover.hz: the frequencies must increase, got {list(freqs)}")
    return {"hz": freqs, "damping": _number(table, "damping", "crossover.damping", positive=True, span=DAMPING_RANGE)}


def _gains(table):
    """Optional fixed gains ``{name: value}`` (hand-tuned filters); validated, never evaluated."""
    if table is None:
        return None
    if not isinstance(table, dict) or not table:
        raise SpecError("gains must be a table of name = number")
    bad = next((name for name in table if not isinstance(name, str)), None)
    if bad is not None:  # (a dict from Python: a TOML key is a string)
        raise SpecError(f"gains: the name {bad!r} is not a string")
    # (gain names are free: only a top-level key below the [gains] header is refused here)
    _no_unknown(table, set(table) - _TOP_KEYS, "gains.", _above(_TOP_KEYS, "the top level", "gains"))
    return {name: _number(table, name, f"gains.{name}", signed=True, span=GAIN_RANGE) for name in table}


def _sensor_name(name) -> str:
    """``sensors.NAME``, the field of a sensor whose name is an ASCII identifier and not a keyword."""
    field = f"sensors.{name}"
    if not (isinstance(name, str) and name.isascii() and name.isidentifier()) or keyword.iskeyword(name):
        raise SpecError(f"{field}: sensor names must be ASCII identifiers (letters, digits, _; not starting "
                        "with a digit) and not Python keywords: they name log columns and C macros")
    return field


def _sensor(name, body) -> SensorSpec:
    field = _sensor_name(name)
    if not isinstance(body, dict):
        raise SpecError(f"{field} must be a table, got {_kind(body)}" + (_TOP_ELSEWHERE.get(name) or ""))
    _no_unknown(body, _SENSOR_KEYS, field + ".", {**_above(_TOP_KEYS, "the top level", field), **_SENSOR_ELSEWHERE})
    noise, bias = body.get("noise"), body.get("bias", {})
    for key, value, figures in (("noise", noise, {"std", "density"}), ("bias", bias, {"model", "density", "value"})):
        if isinstance(value, dict):  # first: a sensor key below a [sensors.NAME.noise] header is not 'missing'
            _no_unknown(value, figures, f"{field}.{key}.", _above(_SENSOR_KEYS, field, f"{field}.{key}"))
    rate = _number(body, "rate_hz", f"{field}.rate_hz", positive=True, required=True, span=RATE_RANGE)
    if noise is None:
        raise SpecError(f"{field}.noise: missing field (a table with 'std' or 'density')")
    if not isinstance(noise, dict):
        raise SpecError(f"{field}.noise must be a table, got {_kind(noise)}: noise = {{ std = ... }} (u per sample) "
                        "or { density = ... } (u/sqrt(Hz))")
    units = []  # the figures given with a unit
    white = WhiteNoise(density=_figure(noise, "noise", "density", field, units),
                       std=_figure(noise, "noise", "std", field, units), field=f"{field}.noise")
    if not isinstance(bias, dict):
        raise SpecError(f"{field}.bias must be a table, got {_kind(bias)}: bias = {{ model = \"random_walk\", "
                        "density = ... } or { model = \"constant\", value = ... }")
    bias_spec = Bias(model=_choice(bias, "model", ("constant", "random_walk"), "constant", f"{field}.bias.model"),
                     density=_figure(bias, "bias", "density", field, units) or 0.0,
                     value=_figure(bias, "bias", "value", field, units, signed=True) or 0.0,
                     field=f"{field}.bias")
    offset = _number(body, "offset_s", f"{field}.offset_s") or 0.0
    if offset >= 1.0 / rate:
        raise SpecError(f"{field}.offset_s: {offset:g} s is not less than the sensor's period {1.0 / rate:g} s")
    return SensorSpec(name, rate, white, bias_spec, _text(body, "measures", field=f"{field}.measures"),
                      _text(body, "port", field=f"{field}.port"), offset,
                      _choice(body, "role", ("input", "measurement", None), None, f"{field}.role"), tuple(units))


def _figure(table, part, key, field, units, signed=False):
    """A noise or bias figure: an SI number, or text with a unit (``"0.3 deg/sqrt(h)"``, read by
    :func:`cfdesign.units.parse_quantity` into SI and recorded in ``units`` as ``(key, Quantity)``
    for the dimension checks)."""
    value, name = table.get(key), f"{field}.{part}.{key}"
    if not isinstance(value, str):
        return _number(table, key, name, signed=signed)
    try:
        q = parse_quantity(value)
    except SpecError as exc:
        raise SpecError(f"{name}: {exc}") from None
    if not signed and q.value < 0:
        raise SpecError(f'{name} must not be negative, got "{value}"')
    units.append((f"{part}.{key}", q))
    return q.value


def did_you_mean(word, choices) -> str:
    """``"; did you mean 'std'?"`` naming the choice nearest ``word`` (another case, a typo, a
    known other spelling such as ``freq`` for ``hz``), or ``""`` when none is near.

    Parameters
    ----------
    word : object
        What the file gave (anything but a string has no suggestion).
    choices : iterable of str
        The valid names.

    Returns
    -------
    str
        The hint, to append to a message.
    """
    choices = [c for c in choices if isinstance(c, str)]
    if not isinstance(word, str) or not choices:
        return ""
    folded = {c.casefold(): c for c in choices}
    key = word.casefold().strip()
    near = folded.get(key) or next((folded[a] for a in _ALIASES.get(key, ()) if a in folded), None)
    if near is None:
        close = difflib.get_close_matches(key, list(folded), n=1, cutoff=0.7)
        near = folded[close[0]] if close else None
    return f"; did you mean {near!r}?" if near is not None and near != word else ""


def _no_unknown(table, allowed, prefix, elsewhere=None):
    """Refuse a key not in ``allowed``: where it belongs (``elsewhere``: ``{key: hint}``), else the
    nearest allowed key, else the allowed ones."""
    unknown = sorted(set(table) - allowed, key=str)  # (keys of a dict from Python may be of any type)
    if unknown:
        key = unknown[0]
        placed = {str(k).casefold(): v for k, v in (elsewhere or {}).items()}  # 'Rate_Hz' as 'rate_hz'
        folded = str(key).casefold()  # an alias too: 'fs' at the top level is a sensor's rate_hz
        alias = next((a for a in _ALIASES.get(folded, ()) if a in placed), None)
        moved = f"; did you mean {alias!r}? {placed[alias].removeprefix('; ')}" if alias else None
        hint = (placed.get(folded) or moved or did_you_mean(key, allowed)
                or f" (allowed: {', '.join(sorted(allowed))})")
        raise SpecError(f"{prefix}{key}: unknown field{hint}")


def _above(keys, where, header) -> dict:
    """The hints of :func:`_no_unknown` for keys of the table ``where`` written below ``[header]``."""
    return {key: f" here; {key} is a key of {where}: write it above the [{header}] header (a key belongs to the "
                 "last table header above it)" for key in keys}


def _text(table, key, required=False, field=None):
    value = table.get(key)
    if value is None:
        if required:
            raise SpecError(f"{field or key}: missing field")
        return None
    if not isinstance(value, str):
        raise SpecError(f"{field or key} must be a string, got {value!r}")
    return value


def _choice(table, key, allowed, default, field=None):
    value = table.get(key, default)
    if value not in allowed:
        # (None in allowed: the field may be left out; joining it was a TypeError, an internal error)
        raise SpecError(f"{field or key} must be one of {', '.join(a for a in allowed if a is not None)}, got "
                        f"{value!r}{did_you_mean(value, allowed)}")
    return value


def _flag(table, key):
    value = table.get(key)
    if value is not None and not isinstance(value, bool):
        raise SpecError(f"{key} must be true or false, got {value!r}")
    return value


def _integer(table, key):
    value = table.get(key)
    if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Integral)):
        raise SpecError(f"{key} must be an integer, got {value!r}")
    return None if value is None else int(value)


def _quoted_number_hint(key, value) -> str:
    """``'; write rate_hz = 100 (a TOML number: no quotes, no unit)'`` for ``"100 Hz"``, ``"100Hz"``
    or ``"1e-3"``: a number written as text, perhaps with its unit.  A key named for its unit
    (``rate_hz``, ``offset_s``) takes no unit in its value; one given in another unit of the
    key's (``"0.1 kHz"``, ``"5 ms"``) is converted in the hint, never taken as it stands."""
    found = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*", value) if isinstance(
        value, str) else None
    if found is None:
        return ""
    number, unit = found[1], found[2]
    own = {"hz": ("Hz", 1), "rate_hz": ("Hz", 1), "sample_time_s": ("s", -1), "offset_s": ("s", -1)}.get(key)
    if unit and own:
        try:
            scale, dim = parse_unit(unit)
        except SpecError:
            scale, dim = None, None
        if dim != tuple(Fraction(-own[1] if i == 2 else 0) for i in range(4)):
            return f"; {key} is a TOML number of {own[0]}, without quotes or unit"
        number = number if scale == 1 else repr(float(number) * scale)
    return f"; write {key} = {number} (a TOML number: no quotes" + (", no unit)" if unit else ")")


def _number(table, key, field, positive=False, required=False, signed=False, span=None):
    """A finite number (int or float, not bool); ``span=(low, high)`` bounds its magnitude (zero
    aside), naming the field and the limit."""
    value = table.get(key)
    if value is None:
        if required:
            raise SpecError(f"{field}: missing field")
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # numpy's and Fraction, from Python
        raise SpecError(f"{field} must be a number, got {value!r}{_quoted_number_hint(key, value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer of 400 digits
        raise SpecError(f"{field}: {str(value)[:20]}... is beyond the range of a double") from None
    if not math.isfinite(value):
        raise SpecError(f"{field} must be finite, got {value}")
    if positive and value <= 0:
        raise SpecError(f"{field} must be positive, got {value:g}")
    if not signed and value < 0:
        raise SpecError(f"{field} must not be negative, got {value:g}")
    if span and value and not span[0] <= abs(value) <= span[1]:
        raise SpecError(f"{field}: {value:g} is outside the limits {span[0]:g} to {span[1]:g} (check the units)")
    return value
