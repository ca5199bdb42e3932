"""Datasheet units for the noise figures of a design file: ``"0.3 deg/sqrt(h)"`` to SI.

A design file's noise and bias figures are SI numbers in the sensor's own quantity (rad/s for
a gyro, m/s^2 for an accelerometer, ...).  Datasheets never give them so: a gyro's angle random
walk is ``0.3 deg/sqrt(h)`` or ``3.8 mdps/sqrt(Hz)``, an accelerometer's noise ``150 ug/sqrt(Hz)``,
a rate random walk ``10 deg/h/sqrt(h)``, a magnetometer's ``3 mG`` rms.  Converted by hand, a
factor of 60 (``sqrt(h)`` against ``sqrt(s)``) or ``pi/180`` goes wrong in silence.  Here such
a figure may be written as text, a number and a unit expression, and is turned into its SI
value and its dimension, which the design file then checks against the field (see
:func:`check_figure`).

A unit expression is a product or quotient of the known units (:data:`UNITS`), each with an
optional power (``s^2``, ``s²``, ``Hz^-1/2``, ``Hz^(-1/2)``), square roots (``sqrt(Hz)``,
``√Hz``, ``rtHz``) and parentheses; ``a/b/c`` is ``a/(b c)``, and units side by side
multiply (``deg h^-1/2``, ``m s^-2``).  A copy from a PDF may bring the minus sign U+2212,
read as ``-``; ``º`` and ``˚``, often typed for the degree sign, are degrees, and ``dph`` is
degrees per hour.  A trailing ``rms`` is allowed
and ignored.  Dimensions are exponents of four base quantities: angle (rad), length (m), time
(s) and magnetic flux density (T).  The angle is a base of its own here (SI counts the radian
as dimensionless), so that ``deg/s`` and ``1/s`` or ``m/s`` stay apart.  ``g`` is standard
gravity, 9.80665 m/s^2 exactly: the value of the 3rd CGPM (1901), adopted as the standard
acceleration of free fall by ISO 80000-3.

Why not pint: it would be a new base dependency of the runtime path (cfdesign's is numpy
only), it reads ``g`` as the gram and the radian as dimensionless (so ``deg/s`` and ``Hz``
have one dimension, the very confusion to catch), and the need is a closed list of some forty
units of four base quantities with square roots of time, which a small parser covers with
messages that name the field of the design file.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from fractions import Fraction

from .errors import SpecError

__all__ = ["STANDARD_GRAVITY", "UNITS", "BASES", "FIGURES", "Quantity", "parse_quantity", "parse_unit", "si_unit",
           "needed", "check_figure", "check_sensor_figures", "check_bases"]

#: standard acceleration of gravity (m/s^2), exact: 3rd CGPM (1901); ISO 80000-3
STANDARD_GRAVITY = 9.80665

#: the base quantities, in the order of a dimension's exponents, and their SI units
BASES = ("angle", "length", "time", "magnetic field")
_SI = ("rad", "m", "s", "T")
_ANGLE, _LENGTH, _TIME, _FIELD = range(4)


def _dim(angle=0, length=0, time=0, field=0) -> tuple:
    return (Fraction(angle), Fraction(length), Fraction(time), Fraction(field))


_DEG = math.pi / 180
_MICRO = ("u", "µ", "μ")  # ASCII u, the micro sign U+00B5, the Greek mu U+03BC


def _units() -> dict:
    table = {"rad": (1.0, _dim(angle=1)), "mrad": (1e-3, _dim(angle=1)), "deg": (_DEG, _dim(angle=1)),
             "°": (_DEG, _dim(angle=1)), "º": (_DEG, _dim(angle=1)), "˚": (_DEG, _dim(angle=1)),
             "dph": (_DEG / 3600, _dim(angle=1, time=-1)), "mdeg": (_DEG * 1e-3, _dim(angle=1)),
             "arcmin": (_DEG / 60, _dim(angle=1)), "arcsec": (_DEG / 3600, _dim(angle=1)),
             "dps": (_DEG, _dim(angle=1, time=-1)), "mdps": (_DEG * 1e-3, _dim(angle=1, time=-1)),
             "m": (1.0, _dim(length=1)), "km": (1e3, _dim(length=1)), "cm": (1e-2, _dim(length=1)),
             "mm": (1e-3, _dim(length=1)),
             "s": (1.0, _dim(time=1)), "sec": (1.0, _dim(time=1)), "ms": (1e-3, _dim(time=1)),
             "min": (60.0, _dim(time=1)), "h": (3600.0, _dim(time=1)), "hr": (3600.0, _dim(time=1)),
             "Hz": (1.0, _dim(time=-1)), "hz": (1.0, _dim(time=-1)), "kHz": (1e3, _dim(time=-1)),
             "rtHz": (1.0, _dim(time=Fraction(-1, 2))),
             "g": (STANDARD_GRAVITY, _dim(length=1, time=-2)), "mg": (STANDARD_GRAVITY * 1e-3, _dim(length=1, time=-2)),
             "T": (1.0, _dim(field=1)), "mT": (1e-3, _dim(field=1)), "nT": (1e-9, _dim(field=1)),
             "G": (1e-4, _dim(field=1)), "mG": (1e-7, _dim(field=1))}
    for mu in _MICRO:  # micro: urad, µg, μT, ...
        table.update({mu + "rad": (1e-6, _dim(angle=1)), mu + "m": (1e-6, _dim(length=1)),
                      mu + "s": (1e-6, _dim(time=1)), mu + "g": (STANDARD_GRAVITY * 1e-6, _dim(length=1, time=-2)),
                      mu + "T": (1e-6, _dim(field=1))})
    return table


#: the known units: ``{name: (SI scale, dimension)}``, a dimension being the exponents of
#: angle, length, time and magnetic field (:data:`BASES`)
UNITS = _units()


@dataclass(frozen=True)
class Quantity:
    """A figure written with a unit, in SI.

    Attributes
    ----------
    value : float
        The value in SI units of its dimension (rad, m, s, T).
    dimension : tuple of Fraction
        Exponents of angle, length, time and magnetic field.
    text : str
        The text it was read from (``"0.3 deg/sqrt(h)"``).
    """

    value: float
    dimension: tuple
    text: str

    @property
    def base(self):
        """Index in :data:`BASES` of the one base quantity (not time) to the power 1, or None."""
        others = [i for i in (_ANGLE, _LENGTH, _FIELD) if self.dimension[i]]
        return others[0] if len(others) == 1 and self.dimension[others[0]] == 1 else None


_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-zµμ°º˚]+)|(?P<sup>[⁻⁺]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+)|(?P<num>\d+(?:\.\d+)?)"
                    r"|(?P<op>\*\*|[*·⋅/()^√+-]))")
_SUPERSCRIPTS = str.maketrans("⁻⁺⁰¹²³⁴⁵⁶⁷⁸⁹", "-+0123456789")
#: what a copy from a PDF datasheet brings: the minus sign U+2212 for '-'
_PDF = str.maketrans({"\u2212": "-"})
_NUMBER = re.compile(r"\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)")
_NOT_FINITE = re.compile(r"\s*[-+]?(?:inf(?:inity)?|nan)(?![A-Za-z])", re.I)
_RMS = re.compile(r"\s*(?:\brms|\(rms\))\s*$", re.I)


class _Parser:
    """Recursive descent over the tokens of a unit expression; ``(scale, dimension)``."""

    def __init__(self, text: str):
        self.text, self.tokens, pos = text, [], 0
        while pos < len(text.rstrip()):
            m = _TOKEN.match(text, pos)
            if m is None:
                raise SpecError(f"unexpected {text[pos:].strip()[:1]!r} in the unit {text.strip()!r}")
            kind = m.lastgroup
            self.tokens.append((kind, m[kind], m.start(kind)))
            pos = m.end()
        self.i = 0

    def peek(self, kind=None, value=None):
        if self.i >= len(self.tokens):
            return None
        token = self.tokens[self.i]
        return token if (kind is None or token[0] == kind) and (value is None or token[1] in value) else None

    def fail(self, what: str):
        token = self.peek()
        where = f"at {self.text[token[2]:].strip()!r}" if token else "at its end"
        raise SpecError(f"expected {what} {where} in the unit {self.text.strip()!r}")

    def parse(self) -> tuple:
        scale, dim = (1.0, _dim()) if self.peek("op", "/") else self.term()
        while self.peek("op", ("*", "**", "·", "⋅", "/")) or self.peek("name") or self.peek("op", ("√", "(")):
            explicit = self.peek("op", ("*", "**", "·", "⋅", "/"))
            op = explicit[1] if explicit else "*"  # units side by side multiply, as SI writes them: deg h^-1/2
            self.i += bool(explicit)
            s, d = self.term()
            sign = -1 if op == "/" else 1
            scale = scale / s if op == "/" else scale * s
            dim = tuple(a + sign * b for a, b in zip(dim, d, strict=True))
        if self.peek() is not None:
            self.fail("'*' or '/' between units")
        return scale, dim

    def term(self) -> tuple:
        scale, dim = self.factor()
        exponent = self.power()
        return _power(scale, exponent), tuple(exponent * e for e in dim)

    def factor(self) -> tuple:
        token = self.peek()
        if token is None:
            self.fail("a unit")
        kind, value, _ = token
        self.i += 1
        if (kind, value) == ("op", "√") or (kind == "name" and value in ("sqrt", "rt")):
            scale, dim = self.factor()
            return math.sqrt(scale), tuple(e / 2 for e in dim)
        if (kind, value) == ("op", "("):
            inner = self.parse_group()
            return inner
        if kind == "name":
            if value not in UNITS:
                raise SpecError(f"unknown unit {value!r}{_nearest(value)} (known: "
                                f"{', '.join(_KNOWN)}; with powers ^2, ², ^-1/2 and sqrt(...), √, rtHz)")
            return UNITS[value]
        if (kind, value) == ("num", "1"):
            return 1.0, _dim()
        self.i -= 1
        self.fail("a unit")

    def parse_group(self) -> tuple:
        start = self.i
        depth = 1
        for j in range(start, len(self.tokens)):
            depth += {"(": 1, ")": -1}.get(self.tokens[j][1], 0) if self.tokens[j][0] == "op" else 0
            if depth == 0:
                inner = _Parser.__new__(_Parser)
                inner.text, inner.tokens, inner.i = self.text, self.tokens[start:j], 0
                if not inner.tokens:
                    self.fail("a unit")
                result = inner.parse()
                self.i = j + 1
                return result
        raise SpecError(f"unbalanced '(' in the unit {self.text.strip()!r}")

    def power(self) -> Fraction:
        token = self.peek()
        if token and token[0] == "sup":
            self.i += 1
            return Fraction(token[1].translate(_SUPERSCRIPTS))
        if not self.peek("op", ("^", "**")):
            return Fraction(1)
        self.i += 1
        grouped = bool(self.peek("op", "("))
        self.i += grouped
        sign = -1 if self.peek("op", "-") else 1
        self.i += bool(self.peek("op", ("-", "+")))
        number = self.peek("num")
        if number is None:
            self.fail("a power")
        self.i += 1
        exponent = Fraction(number[1])
        if self.peek("op", "/") and self.i + 1 < len(self.tokens) and self.tokens[self.i + 1][0] == "num":
            exponent /= Fraction(self.tokens[self.i + 1][1])
            self.i += 2
        if grouped:
            if not self.peek("op", ")"):
                self.fail("')'")
            self.i += 1
        return sign * exponent


def _power(scale: float, exponent: Fraction) -> float:
    """``scale ** exponent``, square roots by ``math.sqrt`` (correctly rounded)."""
    if exponent.denominator == 2:
        return math.sqrt(scale) ** exponent.numerator
    return scale ** float(exponent)


#: the known units as a message lists them (ASCII micro only)
_KNOWN = [name for name in UNITS if not name.startswith(("µ", "μ")) and name not in ("hz", "sec", "º", "˚")]


def _nearest(name: str) -> str:
    import difflib

    close = difflib.get_close_matches(name, list(UNITS), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def parse_unit(text: str) -> tuple:
    """The SI scale and dimension of a unit expression.

    Parameters
    ----------
    text : str
        A unit expression: ``deg/sqrt(h)``, ``ug/√Hz``, ``m/s^2``, ``mdps/rtHz``.

    Returns
    -------
    tuple
        ``(scale, dimension)``: one of the unit in SI is ``scale`` (float); ``dimension`` the
        exponents of angle, length, time and magnetic field (Fractions).

    Raises
    ------
    SpecError
        An unknown unit (the message lists the known ones) or a malformed expression.

    Examples
    --------
    >>> from cfdesign.units import parse_unit
    >>> scale, dim = parse_unit("deg/sqrt(h)")
    >>> round(scale, 9), [str(e) for e in dim]
    (0.000290888, ['1', '0', '-1/2', '0'])
    """
    text = _RMS.sub("", text)
    if not text.strip():
        raise SpecError("no unit given")
    return _Parser(text).parse()


def parse_quantity(text: str) -> Quantity:
    """A number followed by a unit expression, in SI.

    Parameters
    ----------
    text : str
        ``"0.3 deg/sqrt(h)"``, ``"150 ug/√Hz"``, ``"3 mG"``; the space is optional.

    Returns
    -------
    Quantity
        The SI value, its dimension and ``text``.

    Raises
    ------
    SpecError
        No number first, a number without a unit, a number that is not finite, an unknown
        unit or a malformed expression (:func:`parse_unit`).

    Examples
    --------
    >>> from cfdesign.units import parse_quantity
    >>> q = parse_quantity("150 ug/sqrt(Hz)")
    >>> q.value == 150e-6 * 9.80665, q.base
    (True, 1)
    """
    if not isinstance(text, str):
        raise SpecError(f"a figure with a unit is text, got {text!r}")
    quoted, text = json.dumps(text, ensure_ascii=False), text.translate(_PDF)  # one line: a newline as \n
    if _NOT_FINITE.match(text):
        raise SpecError(f"{quoted}: the number must be finite")
    number = _NUMBER.match(text)
    if number is None:
        raise SpecError(f"{quoted} must be a number, or a number and then its unit (\"0.3 deg/sqrt(h)\")")
    unit = text[number.end():]
    if not _RMS.sub("", unit).strip():
        raise SpecError(f"{quoted} has no unit: an SI figure is a TOML number, without quotes ({number[1]}); "
                        f"else give its unit (\"{number[1]} deg/sqrt(h)\")")
    try:
        scale, dim = parse_unit(unit)
    except SpecError as exc:
        raise SpecError(f"{quoted}: {exc}") from None
    value = float(number[1]) * scale
    if not math.isfinite(value):
        raise SpecError(f"{quoted}: beyond the range of a double")
    return Quantity(value, dim, text)


def si_unit(dimension, half: str = "Hz") -> str:
    """The SI unit of a dimension as text: ``rad/s/sqrt(Hz)``, ``m/s^2``, ``T``.

    Parameters
    ----------
    dimension : tuple of Fraction
        Exponents of angle, length, time and magnetic field.
    half : {'Hz', 's'}
        How a half power of time reads: ``/sqrt(Hz)`` (a white-noise density) or ``/sqrt(s)``
        (a random-walk density).

    Returns
    -------
    str
        The unit, ``1`` for none.
    """
    time = Fraction(dimension[_TIME])
    suffix = ""
    if time.denominator == 2:
        time, suffix = (time - Fraction(1, 2), "/sqrt(Hz)") if half == "Hz" else (time + Fraction(1, 2), "/sqrt(s)")
    parts = [_SI[i] + _exponent(dimension[i]) for i in (_ANGLE, _LENGTH, _FIELD) if dimension[i]]
    if time > 0:
        parts.append("s" + _exponent(time))
    text = "*".join(parts) or ("1" if time >= 0 else "")
    if time < 0:
        text += ("" if text else "1") + "/s" + _exponent(-time)
    return text + suffix


def _exponent(e) -> str:
    e = Fraction(e)
    return "" if e == 1 else f"^{e}" if e.denominator == 1 else f"^({e})"


# -- a design file's figures --------------------------------------------------------------

#: each figure of a sensor: its half powers of time over the sensor's quantity, what it is,
#: and how it is written
FIGURES = {
    "noise.density": (Fraction(1, 2), "a white-noise density", "noise = { density = ... }"),
    "noise.std": (Fraction(0), "a per-sample noise std", "noise = { std = ... }"),
    "bias.density": (Fraction(-1, 2), "a bias random-walk density", 'bias = { model = "random_walk", density = ... }'),
    "bias.value": (Fraction(0), "a constant bias", 'bias = { model = "constant", value = ... }'),
}
#: the field a figure may have been meant for: the other form of white noise, or of bias
_SWAPS = {"noise.density": ("noise.std",), "noise.std": ("noise.density",), "bias.density": ("bias.value",),
          "bias.value": ("bias.density",)}
#: what a sensor of a derivative order reads, by base
_READS = {_ANGLE: ("angle", "rate"), _LENGTH: ("position", "velocity")}
_NAMES = {(_ANGLE, 0): "an angle", (_ANGLE, -1): "an angle rate", (_ANGLE, -2): "an angular acceleration",
          (_LENGTH, 0): "a length", (_LENGTH, -1): "a velocity", (_LENGTH, -2): "an acceleration",
          (_FIELD, 0): "a magnetic field", (None, -1): "a frequency", (None, 1): "a time"}
#: the base of what a sensor ``measures`` (acceleration and jerk may be angular or linear)
MEASURES_BASE = {"angle": _ANGLE, "rate": _ANGLE, "position": _LENGTH, "velocity": _LENGTH}


def needed(key: str, order: int, base: int) -> tuple:
    """The dimension of a figure of a sensor of derivative ``order`` of the quantity ``base``.

    Parameters
    ----------
    key : str
        A key of :data:`FIGURES` (``noise.density``, ...).
    order : int
        The sensor's derivative order (0 angle or position, 1 rate or velocity, ...).
    base : int
        Index in :data:`BASES` of the quantity (angle, length or magnetic field).

    Returns
    -------
    tuple of Fraction
        Exponents of angle, length, time and magnetic field.
    """
    dim = [Fraction(0)] * 4
    dim[base] = Fraction(1)
    dim[_TIME] = FIGURES[key][0] - order
    return tuple(dim)


def _described(q: Quantity, half: str) -> str:
    time = q.dimension[_TIME]
    name = _NAMES.get((q.base, time)) if time.denominator == 1 else None
    unit = si_unit(q.dimension, half)
    return f"{name} ({unit})" if name else unit


def _sensor_kind(order: int, base: int) -> str:
    reads = _READS.get(base, ())
    what = reads[order] if order < len(reads) else {2: "acceleration", 3: "jerk"}.get(order)
    return f"{'an' if what and what[0] in 'aeiou' else 'a'} {what} sensor" if what else \
        f"a sensor of derivative order {order}"


def check_figure(field: str, key: str, q: Quantity, order: int) -> None:
    """Refuse a figure whose unit does not fit the field, with the likely fix.

    A white-noise density is the sensor's quantity times ``sqrt(s)`` (per ``sqrt(Hz)``), a
    per-sample std and a constant bias the quantity, a random-walk density the quantity per
    ``sqrt(s)``; the quantity is the base of ``q`` (an angle, a length or a magnetic field)
    over ``s^order``.

    Parameters
    ----------
    field : str
        The design-file field, for the message (``sensors.gyro.noise.density``).
    key : str
        Which figure (a key of :data:`FIGURES`).
    q : Quantity
        The figure as read.
    order : int
        The sensor's derivative order.

    Raises
    ------
    SpecError
        One line: the text, what it is, what the field needs and, for a known confusion (a
        square root left out, a density given as a std), the fix.
    """
    if q.base is None:
        raise SpecError(f'{field}: "{q.text}" is {_described(q, "Hz")}, not a figure of one quantity: give it in '
                        "units of an angle, a length or a magnetic field (rad, deg, m, g, T, ...) over powers of time")
    need = needed(key, order, q.base)
    if q.dimension == need:
        return
    half = "s" if key == "bias.density" else "Hz"
    raise SpecError(f'{field}: "{q.text}" is {_described(q, half)}, but {FIGURES[key][1]} of '
                    f"{_sensor_kind(order, q.base)} is {si_unit(need, half)}{_hint(key, q, order)}")


def _hint(key: str, q: Quantity, order: int) -> str:
    """``: did you mean deg/sqrt(h)?`` where an edit of the unit fits the field (a square root
    left out or added), or the field the figure fits."""
    unit = q.text[_NUMBER.match(q.text).end():].strip()
    need = needed(key, order, q.base)
    for candidate in _candidates(unit, key):
        try:
            if parse_unit(candidate)[1] == need:
                return f": did you mean {candidate}?"
        except SpecError:
            continue
    other = next((k for k in _SWAPS[key] if needed(k, order, q.base) == q.dimension), None)
    return f"; it fits {FIGURES[other][1]}: {FIGURES[other][2]}" if other else ""


def _candidates(unit: str, key: str) -> list:
    """Edits of a unit for the usual slip, a square root left out: ``deg/h`` for the ARW
    ``deg/sqrt(h)``, ``deg/s`` for ``deg/s/sqrt(Hz)``, ``deg/h`` for the RRW ``deg/h/sqrt(h)``."""
    slow = re.search(r"/\s*(h|hr|min)\s*$", unit)
    sqrt_last = re.sub(r"/\s*(h|hr|min|s|sec)\s*$", r"/sqrt(\1)", unit)
    per = "/sqrt(h)" if re.search(r"\b(h|hr)\b", unit) else "/sqrt(s)" if key == "bias.density" else "/sqrt(Hz)"
    appended = unit + per
    return [sqrt_last, appended] if slow else [appended, sqrt_last]


def check_sensor_figures(name: str, figures, order: int) -> None:
    """:func:`check_figure` for each figure of a sensor given with a unit.

    Parameters
    ----------
    name : str
        The sensor's name (its field is ``sensors.NAME``).
    figures : iterable of tuple
        ``(key, Quantity)``: a sensor's ``SensorSpec.units``.
    order : int
        The sensor's derivative order (from ``measures`` or the structure's port).

    Raises
    ------
    SpecError
        As :func:`check_figure`, for the first figure that does not fit.
    """
    for key, q in figures:
        check_figure(f"sensors.{name}.{key}", key, q, order)


def check_bases(figures) -> None:
    """Refuse figures of one design in units of different base quantities.

    A design estimates one quantity: a gyro in ``deg/s`` beside a compass in ``m``, or a
    magnetometer's ``uT`` beside it, is a unit slip or a figure still to be converted.

    Parameters
    ----------
    figures : iterable of tuple
        ``(field, quantity, measures)``: the design-file field, its :class:`Quantity` and the
        sensor's ``measures`` (or None), in file order.

    Raises
    ------
    SpecError
        A figure of no single base, or of another base than a figure before it or than what
        its sensor ``measures``; one line naming both.
    """
    first = None
    for field, q, measures in figures:
        if q.base is None:
            raise SpecError(f'{field}: "{q.text}" is {_described(q, "Hz")}, not a figure of one quantity: give it in '
                            "units of an angle, a length or a magnetic field (rad, deg, m, g, T, ...) over powers of "
                            "time")
        base = MEASURES_BASE.get(measures)
        if base is not None and base != q.base:
            raise SpecError(f'{field}: "{q.text}" is in {_FAMILY[q.base]}, but the sensor measures '
                            f"{measures}: give it in {_FAMILY[base]}{_convert(q.base, base)}")
        if first is not None and first[1].base != q.base:
            raise SpecError(f'{field}: "{q.text}" is in {_FAMILY[q.base]}, beside {first[0]}: '
                            f'"{first[1].text}" in {_FAMILY[first[1].base]}; a design estimates one '
                            f"quantity: give every figure in units of it{_convert(q.base, first[1].base)}")
        first = first or (field, q)


#: a base quantity's family of units, as a message names it ("150 ug/sqrt(Hz)" is in length units)
_FAMILY = {_ANGLE: "angle units (rad, deg, rad/s, ...)", _LENGTH: "length units (m, m/s, m/s^2, g, ...)",
           _FIELD: "magnetic-field units (T, uT, G, ...)"}


def _convert(one: int, other: int) -> str:
    """How a figure of one base becomes one of the other, where a sensor commonly needs it."""
    pair = {one, other}
    if pair == {_ANGLE, _FIELD}:
        return " (a magnetometer's heading noise in rad is about its field noise over the horizontal field)"
    if pair == {_ANGLE, _LENGTH}:
        return " (an accelerometer's tilt noise in rad is about its acceleration noise over g, 9.80665 m/s^2)"
    return ""
