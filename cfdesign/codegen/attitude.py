"""The attitude filter (:class:`cfdesign.nav.AttitudeFilter`) as portable C99.

:func:`write_attitude_c` writes two files for a filter (its rate, parameters, mode and
designed tables):

* ``<prefix>.h``: ``<prefix>_state``, a struct of doubles named and ordered as
  :data:`cfdesign.nav.attitude_filter.STATE_FIELDS` (so a state saved in Python with
  :meth:`~cfdesign.nav.AttitudeFilter.state` maps field by field), ``<prefix>_init`` and
  ``<prefix>_step(state, gyr, acc, mag, q_out)``;
* ``<prefix>.c``: the step, C99 with ``<math.h>`` only (``sqrt, sin, cos, asin, atan2, log2,
  floor, ceil, fabs``), no allocation, no globals beyond constant tables; every designed number
  is written as the shortest decimal literal that reads back as the Python float (a correctly
  rounding compiler, as GCC and Clang are, gives the same double; a hexadecimal literal would be
  exact by the standard, but C++ before C++17 has none).  Every name with file scope starts with
  ``<prefix>_`` or ``<PREFIX>_`` (constants, helper functions, macros), so two filters with
  different prefixes build together, also with their ``.c`` files included into one translation
  unit, and a macro of the program's (``PI``, ``T``) cannot reach them.

The step performs the operations of ``cfdesign.nav.attitude_filter._step`` in the same
order, so with IEEE doubles (no extended precision, no contraction into fused multiply-adds:
the default with ``-std=c99``; not ``-ffast-math``) the two agree to the last bits of libm:
``tests/test_attitude_codegen.py`` compiles it with the warnings the C export promises
(``tests/test_codegen.py``'s ``STRICT``: ``-std=c99 -pedantic -Wall -Wextra -Werror -Wconversion
-Wshadow -Wdouble-promotion -Wcast-qual -Wstrict-prototypes -Wmissing-prototypes -Wundef
-Wfloat-equal``) and as C++11, and requires ``|C - Python| <= 1e-9`` on every quaternion
component, sample by sample, on synthetic runs with missing and impossible readings.  Only double
precision is generated.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from string import Template

from .. import __version__
from ..errors import CfdesignError
from ..files import write_into
from .c99 import _comment_text, _literal, check_c_names, check_c_prefix

__all__ = ["render_attitude_c", "write_attitude_c"]


def write_attitude_c(attitude_filter, directory, *, prefix="cf_attitude") -> list[Path]:
    """Write ``<prefix>.h`` and ``<prefix>.c`` for ``attitude_filter`` into ``directory`` (created if missing).

    Parameters
    ----------
    attitude_filter : cfdesign.nav.AttitudeFilter
        The filter: its rate, parameters, 6D/9D mode, initial attitude and tables.
    directory : str or Path
        Folder the two files are written to (created with its parents if missing).
    prefix : str
        Prefix of the C names and files; a C identifier, not starting with ``_``, not the name
        of a C99 standard header (``math``: the file ``math.h`` would replace ``<math.h>``).

    Returns
    -------
    list of Path
        The two files written.

    Raises
    ------
    CfdesignError
        A bad prefix, or the files cannot be written (OutputError).

    Examples
    --------
    >>> from cfdesign.nav import AttitudeFilter
    >>> from cfdesign.codegen.attitude import write_attitude_c
    >>> [path.name for path in write_attitude_c(AttitudeFilter(100.0), "c_out")]
    ['cf_attitude.h', 'cf_attitude.c']
    """
    return write_into(directory, render_attitude_c(attitude_filter, prefix=prefix))


def render_attitude_c(attitude_filter, *, prefix="cf_attitude") -> dict:
    """The generated C99 files of an attitude filter as ``{file name: text}``, without writing them.

    The code is the filter's step for its rate, parameters, 6D/9D mode, initial attitude and
    designed tables (every number a decimal literal that reads back exactly); ``<prefix>_init`` starts from the
    state :meth:`~cfdesign.nav.AttitudeFilter.reset` gives, not from the filter's current
    state.  :func:`write_attitude_c` writes the same texts.

    Parameters
    ----------
    attitude_filter : cfdesign.nav.AttitudeFilter
        The filter to export (left unchanged).
    prefix : str
        Prefix of the C names (``<prefix>_state``, ``<prefix>_init``, ``<prefix>_step``) and of
        the file names; a C identifier, not starting with ``_``, not the name of a C99
        standard header, making no name C99 reserves or does not tell apart
        (:func:`~cfdesign.codegen.check_c_names`).

    Returns
    -------
    dict
        ``{"<prefix>.h": text, "<prefix>.c": text}``.

    Raises
    ------
    CfdesignError
        ``attitude_filter`` is not an :class:`~cfdesign.nav.AttitudeFilter`, ``prefix`` is not a
        usable C identifier, or a designed number is not finite.

    Examples
    --------
    >>> from cfdesign.nav import AttitudeFilter
    >>> from cfdesign.codegen.attitude import render_attitude_c
    >>> files = render_attitude_c(AttitudeFilter(100.0), prefix="imu_att")
    >>> sorted(files)
    ['imu_att.c', 'imu_att.h']
    >>> "void imu_att_init(imu_att_state *s);" in files["imu_att.h"]
    True
    """
    from ..nav import attitude_filter as af
    from ..nav.attitude_filter import (
        HEADING_VAR0,
        STATE_FIELDS,
        STATE_LIMIT,
        TILT_SETTLE,
        AttitudeFilter,
        _coefficients,
    )

    if not isinstance(attitude_filter, AttitudeFilter):
        raise CfdesignError(f"an AttitudeFilter is needed, got {type(attitude_filter).__name__}")
    prefix = _check_prefix(prefix)
    design = attitude_filter.design
    (T, rest_alpha, th_g2, th_a2, th_b2, rest_min, m_alpha, ref_alpha, north, speed2, g_range2, a_range2, tol,
     new_s, new_rot, first_s, prov_s, follow_f, hold_var, velocity, tilt, heading, rest, use_rest, use_mag, use_levels,
     use_bias, inertial, max_acc_s, hold_s, tilt_alpha, lp_var, settle_ratio, var_g, var_a,
     floor_up, d_scale, shock_lim2) = _coefficients(design)
    initial = attitude_filter._initial
    fresh = attitude_filter.__class__.__new__(attitude_filter.__class__)   # the priors as reset() sets them
    fresh.__dict__.update(attitude_filter.__dict__)
    fresh.reset()
    state = fresh.state()
    priors = [state[name] for name in ("r00", "r01", "r11", "t00", "t01", "t11", "h00", "h01", "h11")]
    fields = {
        "prefix": prefix, "PREFIX": prefix.upper(), "rate_hz": _number(design.rate_hz),
        "nine": int(attitude_filter.magnetometer),
        "state_fields": "\n".join(f"    double {name};" for name in STATE_FIELDS),
        "initial_note": "; the initial attitude given" if initial is not None else "",
        "T": _number(T), "rest_alpha": _number(rest_alpha), "rest_gyro_th2": _number(th_g2),
        "rest_accel_th2": _number(th_a2),
        "rest_bias_th2": _number(th_b2), "rest_time": _number(rest_min), "mag_alpha": _number(m_alpha),
        "mag_ref_alpha": _number(ref_alpha), "north": _number(north), "speed2": _number(speed2),
        "max_accel_time": _number(max_acc_s), "accel_hold": _number(hold_s), "tilt_alpha": _number(tilt_alpha),
        "state_limit": _number(STATE_LIMIT),
        "tilt_settle": _number(TILT_SETTLE), "settle_ratio": _number(settle_ratio),
        "gyro_range2": _number(g_range2), "accel_range2": _number(a_range2), "mag_tol": _number(tol),
        "mag_new_time": _number(new_s), "mag_new_turn": _number(new_rot), "mag_first_time": _number(first_s),
        "mag_provisional": _number(prov_s), "mag_follow": _number(follow_f), "hold_var": _number(hold_var),
        "rest_lp_var": _number(lp_var), "rest_gyro_var": _number(var_g), "rest_accel_var": _number(var_a),
        "rest_floor_up": _number(floor_up), "rest_diff_scale": _number(d_scale),
        "rest_floor_k": _number(af.REST_FLOOR_K),
        "gap_turn_rad": _number(af.GAP_TURN_RAD),
        "rest_floor_cap": _number(af.REST_FLOOR_CAP), "shock_lim2": _number(shock_lim2),
        "gravity": _number(_gravity()), "pi": _number(math.pi), "two_pi": _number(2 * math.pi),
        "heading_var0": _number(HEADING_VAR0),
        "n_velocity": len(velocity),
        "velocity": ",\n".join(f"    {{{_number(k1)}, {_number(k2)}}}" for k1, k2 in velocity),
        "tilt": ", ".join(_number(v) for v in tilt), "heading": ", ".join(_number(v) for v in heading),
        "rest": ", ".join(_number(v) for v in rest), "priors": ", ".join(_number(v) for v in priors),
        "initial": ", ".join(_number(v) for v in ([1.0, *initial] if initial is not None else [0.0] * 5)),
        "use_rest": int(use_rest), "use_mag_check": int(use_mag), "use_levels": int(use_levels),
        "use_motion_bias": int(use_bias), "inertial": int(inertial),
    }
    out = {}
    for stem, what in (("h", "the attitude filter's state and functions"),
                       ("c", "the attitude filter's step (C99, libm only, no allocation)")):
        name = f"{prefix}.{stem}"
        header = _header(name, what, attitude_filter, prefix)
        out[name] = Template(_template(f"attitude.{stem}.in")).substitute(fields, header=header)
    return check_c_names(out, prefix)


#: the headers of the C99 standard library: a file ``<prefix>.h`` of one of these names, found
#: through ``-I``, would be included in place of the standard one (``math.h``: no ``ceil``)
C99_HEADERS = frozenset("""
    assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdarg
    stdbool stddef stdint stdio stdlib string tgmath time wchar wctype
""".split())


def _check_prefix(prefix) -> str:
    """``prefix`` checked: a C identifier, not starting with ``_`` (its names are file-scope, and its
    header guard would be ``_X_H``: both reserved) and not the name of a C99 standard header."""
    prefix = check_c_prefix(prefix)
    if prefix.lower() in C99_HEADERS:
        raise CfdesignError(f"C prefix {prefix!r} would write {prefix}.h, the name of a C standard header, which "
                            "the generated code includes; C code needs another prefix")
    return prefix


def _gravity() -> float:
    from ..nav.attitude_filter import GRAVITY

    return GRAVITY


def _number(value) -> str:
    """A C floating constant equal to ``value`` (finite): the shortest decimal that reads back as
    the same double (:func:`~cfdesign.codegen.c99._literal`), valid in C99 and in C++ before C++17,
    which has no hexadecimal floating literals."""
    value = float(value)
    if not math.isfinite(value):
        raise CfdesignError(f"a value of the attitude filter is not finite ({value!r}); C code needs finite numbers")
    return _literal(value, "", "a value of the attitude filter")


def _header(name, what, attitude_filter, prefix) -> str:
    p = attitude_filter.params
    named = "" if prefix == "cf_attitude" else f", prefix={prefix!r}"  # the regenerated files keep their names
    mode = "9D (magnetometer)" if attitude_filter.magnetometer else "6D (no magnetometer)"
    params = ", ".join(f"{k}={getattr(p, k)!r}" for k in p.__dataclass_fields__)
    lines = [f"{name} - {what}", "",
             "GENERATED FILE - DO NOT EDIT.  Regenerate it from the filter instead:",
             f"    cfdesign.codegen.attitude.write_attitude_c(AttitudeFilter(rate_hz, ...), directory{named})", "",
             f"generator : cfdesign {__version__} (cfdesign.codegen.attitude, C99, double)",
             f"filter    : cfdesign.nav.AttitudeFilter at {attitude_filter.rate_hz!r} Hz, {mode}",
             "frames    : body (sensor) frame relative to ENU; quaternions [w, x, y, z] body -> ENU",
             "parameters:"]
    lines += [f"    {chunk}" for chunk in _wrap_text(params, 96)]
    body = "\n".join(f" * {_comment_text(line)}".rstrip() for line in lines)
    return f"/*\n{body}\n */"


def _wrap_text(text, width):
    out, line = [], ""
    for word in text.split(" "):
        if line and len(line) + 1 + len(word) > width:
            out.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    return [*out, line] if line else out


def _template(name) -> str:
    return resources.files("cfdesign.codegen").joinpath("templates", name).read_text()
