"""Render a discrete gain table as a portable C99 filter (see :mod:`cfdesign.codegen`)."""

from __future__ import annotations

import math
import re
from importlib import resources
from pathlib import Path
from string import Template

import numpy as np

from .. import __version__, linear
from ..errors import CfdesignError
from ..files import write_into
from ..gains import require_table
from ..runtime.filter import READING_LIMIT, filter_sha256, require_stable

__all__ = ["write_c", "render_c", "check_c_identifier", "check_c_prefix", "check_c_names", "C99_KEYWORDS",
           "STRICT_CFLAGS", "STRICT_CXXFLAGS"]

#: the warning options every generated file (filter and attitude, double and float) compiles clean
#: under, as C99 with GCC and Clang (the tests build with them); for a program's own files too
STRICT_CFLAGS = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-Wconversion", "-Wshadow",
                 "-Wdouble-promotion", "-Wcast-qual", "-Wstrict-prototypes", "-Wmissing-prototypes", "-Wundef",
                 "-Wfloat-equal")
#: the same promise compiled as C++ (the C-only -Wstrict-prototypes and -Wmissing-prototypes dropped,
#: -Wmissing-declarations their C++ counterpart; not -Wold-style-cast, which C source cannot meet)
STRICT_CXXFLAGS = ("-x", "c++", "-std=c++11", "-pedantic", "-Wall", "-Wextra", "-Werror", "-Wconversion",
                   "-Wshadow", "-Wdouble-promotion", "-Wcast-qual", "-Wmissing-declarations", "-Wundef",
                   "-Wfloat-equal")

#: the reserved words of ISO C99 (6.4.1)
C99_KEYWORDS = frozenset("""
    auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef
    union unsigned void volatile while _Bool _Complex _Imaginary
""".split())

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
#: names C99 reserves by their spelling (7.1.3 with the future library directions of 7.26, and
#: FE_/FP_ of 7.6 and 7.12): reserved where the header is included, and a user's file may include
#: any of them beside the generated header (an <errno.h> macro EKF_N would replace ours)
_RESERVED = (
    (r"(str|mem|wcs)[a-z]", "names starting with str, mem or wcs and a lowercase letter (<string.h>, <stdlib.h>)"),
    (r"(is|to)[a-z]", "names starting with is or to and a lowercase letter (<ctype.h>, <wctype.h>)"),
    (r"E[0-9A-Z]", "names starting with E and a digit or a capital letter (<errno.h>)"),
    (r"LC_[A-Z]", "names starting with LC_ and a capital letter (<locale.h>)"),
    (r"SIG_?[A-Z]", "names starting with SIG or SIG_ and a capital letter (<signal.h>)"),
    (r"(PRI|SCN)[a-zX]", "names starting with PRI or SCN and a lowercase letter or X (<inttypes.h>)"),
    (r"U?INT\w*(_MAX|_MIN|_C)\Z", "names starting with INT or UINT and ending in _MAX, _MIN or _C (<stdint.h>)"),
    (r"F[EP]_[A-Z]", "names starting with FE_ or FP_ and a capital letter (<fenv.h>, <math.h>)"),
)
#: the constants POSIX adds to <math.h> (glibc's with their l, f and fN suffixes): macros wherever a
#: program is built as C++ (g++ defines _GNU_SOURCE) or as GNU C (-std=gnu99, the default)
_POSIX_MATH = re.compile(r"M_(E|LOG2E|LOG10E|LN2|LN10|PI|PI_2|PI_4|1_PI|2_PI|2_SQRTPI|SQRT2|SQRT1_2)(l|f\d*x?)?\Z")
#: significant initial characters C99 guarantees (5.2.4.1): external names, the others
_SIGNIFICANT = {"external": 31, "internal": 63}
#: precision -> (C type, ceil function, literal suffix)
_PRECISIONS = {"double": ("double", "ceil", ""), "float": ("float", "ceilf", "f")}
#: generated files, in the order returned: (template, what the file holds)
_FILES = (("gains.h", "the gain table as C99 constants"),
          ("filter.h", "the filter's state and functions"),
          ("filter.c", "the filter step (C99, libm only, no allocation)"))
_ORDER_NAMES = {0: "angle/position", 1: "rate", 2: "acceleration"}


def write_c(table, directory, *, prefix=None, precision="double", output=None) -> list[Path]:
    """Write the table as C99 source: ``<prefix>_gains.h``, ``<prefix>_filter.h``, ``<prefix>_filter.c``.

    The files are written atomically (:mod:`cfdesign.files`); the step has the semantics of
    :meth:`cfdesign.runtime.Runtime.step` (module docstring of :mod:`cfdesign.codegen`).

    Parameters
    ----------
    table : GainTable
        A discrete table in ``predictor`` or ``filter`` gain form.
    directory : str or Path
        Output folder (created if missing); existing files of the same names are replaced.
    prefix : str, optional
        Prefix of every C name (files, types, functions, macros upper-cased); default from the
        table's structure (e.g. ``dckf3``), else its name.  Must be a C identifier.
    precision : {'double', 'float'}
        The C arithmetic type.
    output : {'prior', 'posterior'}, optional
        The estimate ``<prefix>_step`` returns: the one-step prediction or the estimate after
        this step's readings; default the table's declared output, as
        :class:`cfdesign.runtime.Runtime`.

    Returns
    -------
    list of Path
        The three files written.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        The table cannot run (continuous, or unstable: :class:`~cfdesign.runtime.Runtime` refuses it
        too), a name is not a C identifier, or a value is not finite.
    OutputError
        The directory or the files cannot be written; no existing file is left half-written.

    Examples
    --------
    >>> import cfdesign, tempfile
    >>> from cfdesign.codegen import write_c
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> [p.name for p in write_c(table, tempfile.mkdtemp(), prefix="heading")]
    ['heading_gains.h', 'heading_filter.h', 'heading_filter.c']
    """
    require_table(table, "write_c")
    return write_into(directory, render_c(table, prefix=prefix, precision=precision, output=output))


def render_c(table, *, prefix=None, precision="double", output=None) -> dict:
    """The generated C files, without writing them (see :func:`write_c`).

    Parameters
    ----------
    table : GainTable
        A discrete table in ``predictor`` or ``filter`` gain form.
    prefix : str, optional
        Prefix of every C name; default from the table's structure.
    precision : {'double', 'float'}
        The C arithmetic type.
    output : {'prior', 'posterior'}, optional
        The estimate the step returns; default the table's declared output.

    Returns
    -------
    dict
        ``{file name: text}``.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        As :func:`write_c`.
    """
    require_table(table, "render_c")
    fields = _fields(table, prefix, precision, output)
    out = {}
    for stem, what in _FILES:
        name = f"{fields['prefix']}_{stem}"
        header = _template("header").substitute(fields, file=name, what=what)
        out[name] = _template(stem).substitute(fields, header=header)
    return check_c_names(out, fields["prefix"])


def check_c_names(files: dict, prefix: str) -> dict:
    """Return ``files`` if every C name made from ``prefix`` in them is free and significant, else raise.

    The names are ``<prefix>_*`` and ``<PREFIX>_*`` (the sensors' index macros among them).  A
    name is refused when C99 keeps it for itself, by keyword or by spelling (7.1.3 and the
    future library directions of 7.26: ``str``, ``mem``, ``wcs``, ``is`` or ``to`` and a
    lowercase letter; macros of ``<errno.h>``, ``<locale.h>``, ``<signal.h>``, ``<inttypes.h>``,
    ``<stdint.h>``, ``<fenv.h>``, ``<math.h>``) or POSIX ``<math.h>`` defines (``M_PI``, ``M_E``: macros
    under g++ and ``-std=gnu99``), or when it is longer than the characters C99
    guarantees significant (5.2.4.1): 31 for the external functions ``<prefix>_init`` and
    ``<prefix>_step``, 63 for the other names.

    Parameters
    ----------
    files : dict
        ``{file name: C text}`` as generated.
    prefix : str
        The prefix the names were made with.

    Returns
    -------
    dict
        ``files``, unchanged.

    Raises
    ------
    CfdesignError
        One line naming the first such name and the rule it breaks.

    Examples
    --------
    >>> from cfdesign.codegen import check_c_names
    >>> check_c_names({"a.h": "void string_step(void);"}, "string")
    Traceback (most recent call last):
    ...
    cfdesign.errors.CfdesignError: C name 'string_step' is reserved in C99: names starting with str, mem or wcs ...
    """
    external = {f"{prefix}_init", f"{prefix}_step"}
    text = "\n".join(files.values())
    found = re.findall(rf"\b(?:{re.escape(prefix)}|{re.escape(prefix.upper())})_\w+\b(?!\.)", text)  # not file names
    for name in sorted(set(found), key=found.index):
        rule = next((why for pattern, why in _RESERVED if re.match(pattern, name)), None)
        if name in C99_KEYWORDS:
            rule = "a keyword"
        elif name.startswith("__") or re.match(r"_[A-Z]", name):
            rule = "names starting with __ or _ and a capital letter"
        what = "external" if name in external else "internal"
        if rule is None and len(name) > _SIGNIFICANT[what]:
            rule = (f"{len(name)} characters, beyond the {_SIGNIFICANT[what]} C99 guarantees significant in "
                    f"{'an external name' if what == 'external' else 'a macro or internal name'}")
            raise CfdesignError(f"C name {_shown(name)!r} has {rule}; C code needs a shorter prefix or sensor name")
        if rule is not None:
            raise CfdesignError(f"C name {_shown(name)!r} is reserved in C99: {rule}; C code needs another prefix or "
                                "sensor name")
        if _POSIX_MATH.match(name):  # prefix M: the attitude C's M_PI
            raise CfdesignError(f"C name {name!r} is a macro of <math.h> in POSIX (defined under g++ and "
                                "-std=gnu99); C code needs another prefix")
    return files


def _shown(name: str) -> str:
    """A C name as a message quotes it: cut after 60 characters (a sensor name of 5000 filled the
    line, and the advice at its end was cut off)."""
    return name if len(name) <= 80 else f"{name[:60]}..."


def check_c_identifier(name, what: str) -> str:
    """Return ``name`` if it can be a C identifier, else raise naming ``what``.

    Rejected: anything outside ``[A-Za-z_][A-Za-z0-9_]*``, C99 keywords and names the C
    standard reserves (a leading double underscore, or underscore and capital letter).

    Parameters
    ----------
    name : str
        Candidate identifier (a sensor name, a prefix).
    what : str
        What the name is, for the message (``sensor``, ``prefix``).

    Returns
    -------
    str
        ``name``, unchanged.

    Raises
    ------
    CfdesignError
        The name cannot be used in C.

    Examples
    --------
    >>> from cfdesign.codegen import check_c_identifier
    >>> check_c_identifier("gyro", "sensor")
    'gyro'
    >>> check_c_identifier("int", "sensor")
    Traceback (most recent call last):
    ...
    cfdesign.errors.CfdesignError: sensor 'int' is a C99 keyword; C code needs a valid C identifier
    """
    if not isinstance(name, str) or not _IDENTIFIER.match(name):
        problem = "is not a C identifier (letters, digits and _, not starting with a digit)"
    elif name in C99_KEYWORDS:
        problem = "is a C99 keyword"
    elif name.startswith("__") or re.match(r"_[A-Z]", name):
        problem = "is reserved in C (leading __ or _ and a capital letter)"
    else:
        return name
    raise CfdesignError(f"{what} {_shown(name)!r} {problem}; C code needs a valid C identifier")


def check_c_prefix(prefix) -> str:
    """Return ``prefix`` if it can prefix the names of generated C, else raise.

    A C identifier (:func:`check_c_identifier`) that does not start with ``_``: the generated
    functions and tables have file scope, where C reserves every name with a leading
    underscore, and the header guard (``_X_FILTER_H``) would be reserved everywhere.

    Parameters
    ----------
    prefix : str
        Candidate prefix.

    Returns
    -------
    str
        ``prefix``, unchanged.

    Raises
    ------
    CfdesignError
        The prefix cannot be used; the message names it.

    Examples
    --------
    >>> from cfdesign.codegen import check_c_prefix
    >>> check_c_prefix("heading")
    'heading'
    >>> check_c_prefix("_heading")
    Traceback (most recent call last):
    ...
    cfdesign.errors.CfdesignError: C prefix '_heading' starts with '_': names with file scope that do are ...
    """
    prefix = check_c_identifier(prefix, "C prefix")
    if prefix.startswith("_"):
        raise CfdesignError(f"C prefix {_shown(prefix)!r} starts with '_': names with file scope that do are reserved "
                            "in C (and so is its header guard); C code needs another prefix")
    return prefix


# ---------------------------------------------------------------------- checks
def _check_runnable(table):
    if table.domain != "z" or table.gain_form not in ("predictor", "filter"):
        from ..runtime.filter import DISCRETE_HINT

        raise CfdesignError(f"{table.name} is a continuous-time table ({table.gain_form} gains); C code runs "
                            f"discrete tables in predictor or filter form ({DISCRETE_HINT})")
    require_stable(table)  # the C would diverge as the runtime would, which refuses it


def _default_prefix(table) -> str:
    for text in (table.structure, table.name):
        slug = re.sub(r"[^a-z0-9]+", "_", str(text).lower()).strip("_")
        if slug and not slug[0].isdigit() and slug not in C99_KEYWORDS:
            return slug
    return "cf"


def _sensors(table) -> list:
    """Sensors by role and index, names checked; each role's indices must be 0, 1, ...

    A sensor's name appears in the C only upper-cased after the prefix, in its index macro
    ``<PREFIX>_U_<NAME>`` or ``<PREFIX>_Y_<NAME>`` (and in comments): any identifier makes a
    valid, unreserved macro name there, so names that are C keywords (``int``, ``double``) or
    that start with underscores are fine; only two names that upper-case alike clash."""
    sensors = table.sensors  # inputs by column, then measurements by row (checked by GainTable)
    for s in sensors:
        if not isinstance(s.name, str) or not _IDENTIFIER.match(s.name):
            check_c_identifier(s.name, f"{table.name}: sensor")  # raises, naming the sensor
    macros = [s.name.upper() for s in sensors]
    if len(set(macros)) < len(macros):
        raise CfdesignError(f"{table.name}: sensor names {', '.join(s.name for s in sensors)} clash once "
                            "upper-cased for the C macros; rename one")
    return sensors


# ---------------------------------------------------------------------- rendering
def _fields(table, prefix, precision, output) -> dict:
    """Every substitution of the templates."""
    _check_runnable(table)
    output = table.output if output is None else output
    if not isinstance(output, str) or output not in linear.OUTPUTS:
        raise CfdesignError(f"output must be one of {', '.join(linear.OUTPUTS)}, got {output!r}")
    if not isinstance(precision, str) or precision not in _PRECISIONS:
        raise CfdesignError(f"precision must be 'double' or 'float', got {precision!r}")
    prefix = check_c_prefix(_default_prefix(table) if prefix is None else prefix)
    real, ceil, suffix = _PRECISIONS[precision]
    sensors = _sensors(table)
    n, p, m = table.F.shape[0], table.B.shape[1], table.H.shape[0]
    gains = _gains(table, output)
    shapes = {"F": (n, n), "B": (n, max(p, 1)), "H": (max(m, 1), n), "K": (table.period, n, max(m, 1)),
              "L": (table.period, n, max(m, 1))}
    values = {"F": table.F, "B": table.B, "H": table.H, **gains}
    arrays = {key: _initializer(_padded(values[key], shape, f"{table.name}: {key}"), suffix, what=f"a value of {key}")
              for key, shape in shapes.items()}
    active = table.schedule.mask()
    return {
        **_provenance(table), **_summary(table, output, sensors, prefix), **arrays,
        **_step_code(table, prefix, gains), "prefix": prefix,
        "export_command": _export_command(table, prefix, precision, output),
        "PREFIX": prefix.upper(), "real": real, "ceil": ceil, "n": n, "p": p, "m": m, "p_alloc": max(p, 1),
        "m_alloc": max(m, 1), "period": table.period,
        "sample_time": _literal(table.sample_time_s, suffix, "sample time"),
        "reading_limit": _literal(READING_LIMIT, suffix, "reading limit"),
        "posterior": int(output == "posterior"), "output": output, "wrap_angle": int(bool(table.wrap_angle)),
        "active": _initializer(_padded(active, (table.period, max(m, 1)), "schedule").astype(int), ""),
        "measured": _initializer(active.any(axis=1).astype(int), ""),
        "sensor_macros": _sensor_macros(sensors, prefix, _units(table)[0]),
        "phase_macros": _phase_macros(table, prefix), **_state_text(table),
        "missing": _literal(MISSING, suffix, "missing marker"),
        "pi": _literal(math.pi, suffix, "pi"), "two_pi": _literal(2 * math.pi, suffix, "2 pi"),
    }


def _export_command(table, prefix, precision, output) -> str:
    """The command that writes these files again from their table: ``cfdesign export`` with every
    option that made them differ from its defaults (a prefix, float, the prediction)."""
    command = "cfdesign export <gains.json> --format c -o <dir>"
    if prefix != _default_prefix(table):
        command += f" --prefix {prefix}"
    if precision != "double":
        command += f" --precision {precision}"
    if output != table.output:  # the command line can only ask for the prediction
        command += " --prediction" if output == "prior" else f' (in Python: write_c(..., output="{output}"))'
    return command


def _gains(table, output) -> dict:
    """``{'K': predictor gains, 'L': update gains}`` per phase (:func:`cfdesign.linear.gain_pair`)."""
    pairs = [linear.gain_pair(table.F, K, table.gain_form) for K in table.K]
    if output == "posterior" and any(L is None for _, L in pairs):
        raise CfdesignError(f"{table.name}: {output} output needs an invertible F")
    return {"K": np.array([Kp for Kp, _ in pairs]),
            "L": np.array([L if L is not None else np.zeros_like(Kp) for Kp, L in pairs])}


def _step_code(table, prefix, gains) -> dict:
    """The products of the step written out as C statements (see ``templates/filter.c.in``)."""
    F, B, H = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H))
    n, p, m = F.shape[0], B.shape[1], H.shape[0]
    x, e, u = ([f"{name}[{j}]" for j in range(k)] for name, k in (("x", n), ("e", m), ("s->u_last", p)))
    used_k, used_l = gains["K"].any(axis=0), gains["L"].any(axis=0)  # entries non-zero at some phase
    return {"innovations": _lines(_innovations(table, prefix, H, x), 2),
            "corrections": _lines([f"c[{r}] = {_sum('K', r, used_k[r], e)};" for r in range(n)], 2),
            "posterior_estimate": f"est = x[0] + ({_sum('L', 0, used_l[0], e)});",
            "update": _lines(_updates(prefix, F, B, x, u), 1)}


def _innovations(table, prefix, H, x) -> list:
    """``e[i] = y[i] - (H x)[i]``, wrapped for the angle sensors of angle tables; 0 if missing
    or not read at this phase."""
    angle = {s.index for s in table.measurements if s.order == 0}
    out = []
    for i, row in enumerate(H):
        diff = f"y[{i}] - ({_sum(prefix + '_H', i, row, x)})"
        value = f"{prefix}_wrap({diff})" if table.wrap_angle and i in angle else diff
        out.append(f"e[{i}] = ({prefix.upper()}_USABLE(y[{i}]) && {prefix}_ACTIVE[phase][{i}]) ? {value} : 0;")
    return out


def _updates(prefix, F, B, x, u) -> list:
    """``next = (F x) + (B u) + c`` row by row, in the runtime's order; a zero ``B u`` left out."""
    out = []
    for r in range(len(F)):
        terms = [f"({_sum(prefix + '_F', r, F[r], x)})"]
        if B[r].any():
            terms.append(f"({_sum(prefix + '_B', r, B[r], u)})")
        out.append(f"next[{r}] = {' + '.join([*terms, f'c[{r}]'])};")
    return out


def _sum(matrix, row, coefficients, terms) -> str:
    """``matrix[row][j] * terms[j] + ...`` over the non-zero coefficients, in order; ``0`` if none."""
    parts = [f"{matrix}[{row}][{j}] * {t}" for j, t in enumerate(terms) if coefficients[j]]
    return " + ".join(parts) or "0"


def _lines(statements, depth) -> str:
    return "\n".join("    " * depth + s for s in statements)


def _provenance(table) -> dict:
    prov = table.provenance or {}
    solver = prov.get("solver") or {}
    fields = {"table_name": table.name, "structure": table.structure, "gain_form": table.gain_form,
              "spec_sha256": prov.get("spec_sha256", "unknown"), "table_version": prov.get("cfdesign_version", "?"),
              "created_utc": prov.get("created_utc", "unknown"), "generator_version": __version__,
              "solver": solver.get("method", "unknown") if isinstance(solver, dict) else solver}
    return {key: _comment_text(value) for key, value in fields.items()}


def _summary(table, output, sensors, prefix) -> dict:
    """The header comment's account of what the step does: its rate, its output, the schedule of
    every sensor and the :func:`~cfdesign.runtime.filter.filter_sha256` of the table."""
    T, period = table.sample_time_s, table.period
    rate = f"base {1.0 / T:g} Hz (T = {T:g} s): one {prefix}_step call per base step"
    if period > 1:
        rate += f"; gain schedule of {period} steps ({period * T:g} s)"
    what = ("the estimate after each step's readings (x+)" if output == "posterior"
            else "the one-step prediction (x, before this step's readings)")
    chosen = "the table's output" if output == table.output else f"chosen at export; the table's own is {table.output}"
    lines = []
    for s in sensors:
        when = "every step" if s.role == "input" else _phases_text(table.schedule.phases(s.name), period, prefix)
        lines.append(f"{s.name} ({s.role}, {s.rate_hz:g} Hz): {when}")
    pad = "\n *" + " " * 16
    return {"rate_line": _comment_text(rate), "output_line": _comment_text(f"{output}: {what} ({chosen})"),
            "schedule_lines": pad.join(_comment_text(line) for line in lines),
            "filter_sha256": filter_sha256(table)}


def _phases_text(phases, period, prefix) -> str:
    """The phases a measurement is read at, briefly: ``every step``, ``phases 2, 7 of 10``,
    ``every 33rd step from phase 1 (300 of 10000)``."""
    phases = list(phases)
    if len(phases) == period:
        return "every step"
    if not phases:
        return f"never (no phase of {period})"
    gaps = set(np.diff(phases).tolist())
    if len(phases) > 8 and len(gaps) == 1:
        return f"every {gaps.pop()} steps from phase {phases[0]} ({len(phases)} of {period} phases)"
    if len(phases) > 8:
        shown = ", ".join(map(str, phases[:8]))
        return f"phases {shown}, ... ({len(phases)} of {period}; {prefix}_ACTIVE lists them)"
    return f"phase{'s' if len(phases) > 1 else ''} {', '.join(map(str, phases))} of {period}"


def _comment_text(value) -> str:
    """Text safe inside a C block comment: printable ASCII on one line, no comment delimiters,
    no trigraphs (``??/`` would splice lines under -Wtrigraphs)."""
    text = "".join(c if " " <= c <= "~" else "_" for c in str(value))
    text = text.replace("*/", "* /").replace("/*", "/ *")
    while "??" in text:
        text = text.replace("??", "? ?")
    return text


def _units(table) -> tuple:
    """The unit of every state in ASCII (``m/s^2``; ``''`` where the table does not tell it):
    :meth:`~cfdesign.gains.GainTable.state_units` with its superscripts spelled out."""
    ascii_powers = str.maketrans({"²": "^2", "³": "^3", "⁴": "^4", "⁵": "^5", "⁶": "^6"})
    return tuple(unit.translate(ascii_powers) for unit in table.state_units())


def _unit(base, order) -> str:
    """The unit of the ``order``-th derivative of a quantity in ``base`` (``rad``, 2: ``rad/s^2``)."""
    return "" if not base else base + ("" if order == 0 else "/s" if order == 1 else f"/s^{order}")


def _state_text(table) -> dict:
    """The state's entries with their units and the estimate's unit, for ``filter.h``."""
    units = _units(table)
    shown = [f"x[{i}] {name}" + (f" ({unit})" if unit else "")
             for i, (name, unit) in enumerate(zip(table.states, units, strict=True))]
    return {"state_list": "\n *     ".join(_comment_text(line) for line in shown),
            "estimate_unit": f", {units[0]}" if units[0] else ""}


def _sensor_macros(sensors, prefix, base) -> str:
    """``#define <PREFIX>_U_<NAME> i`` and ``<PREFIX>_Y_<NAME> i``, each with its role, order, unit
    (from the unit ``base`` of the quantity, ``''`` if unknown) and rate."""
    lines = []
    for s in sensors:
        kind = "U" if s.role == "input" else "Y"
        unit = _unit(base, s.order)
        note = (f"{s.role}, order {s.order} ({_ORDER_NAMES.get(s.order, '?')}{', ' + unit if unit else ''}), "
                f"{s.rate_hz:g} Hz")
        lines.append(f"#define {prefix.upper()}_{kind}_{s.name.upper()} {s.index}  /* {s.name}: {note} */")
    return "\n".join(lines)


def _phase_macros(table, prefix) -> str:
    """``#define <PREFIX>_PHASE_<NAME> k`` for every measurement the schedule reads once a period
    (none for a single-rate table): the value to give ``s->phase`` before the step of its reading,
    which locks the whole schedule to that sensor.  A sensor read at several phases of a period
    (a 10 Hz compass in a period of 0.2 s) is listed with its phases but has no macro: setting
    ``s->phase`` to one of them at each of its readings would repeat part of the period and skip
    the phases after it (another sensor read only there would never be read)."""
    once, several = [], []
    for s in table.measurements:
        phases = list(table.schedule.phases(s.name))
        if len(phases) == 1 and table.period > 1:
            once.append(f"#define {prefix.upper()}_PHASE_{s.name.upper()} {phases[0]}  /* {s.name}: "
                        f"{_phases_text(phases, table.period, prefix)} */")
        elif 1 < len(phases) < table.period:
            several.append(f" * {s.name}: {_phases_text(phases, table.period, prefix)}")
    if not once and not several:
        return ""
    text = "\n/*\n * the schedule reads a slow sensor only at its phases; a reading at any other phase is\n * ignored."
    if once:
        text += ("  Lock the schedule to a sensor read once a period: when its reading arrives, set\n"
                 f" * s->phase = {prefix.upper()}_PHASE_<NAME> before that step (one sensor; the others fall\n"
                 " * where the period puts them).")
    else:
        text += "  No sensor is read once a period: none\n * can lock the whole schedule."
    if several:
        text += ("\n * Read at several phases, so not a lock (setting s->phase at each of their\n"
                 " * readings would repeat part of the period):\n" + "\n".join(several))
    return text + "\n */\n" + "\n".join(once) + ("\n" if once else "")


def _padded(values, shape, what):
    """``values`` as a float array of ``shape``, zero-padded where a dimension is empty."""
    a = np.asarray(values, dtype=float)
    if not np.isfinite(a).all():
        raise CfdesignError(f"{what} has a value that is not finite; C code needs finite numbers")
    out = np.zeros(shape)
    out[tuple(slice(0, k) for k in a.shape)] = a
    return out


#: the generated ``<PREFIX>_MISSING``: a finite reading beyond READING_LIMIT (missing without NaN)
MISSING = 1e30
#: float: the largest finite value and the smallest positive (subnormal) one
_FLOAT_RANGE = (3.4028234663852886e38, 1.401298464324817e-45)


def _literal(value, suffix, what) -> str:
    """A C floating constant with the value's full precision (``repr``: shortest round trip)."""
    value = float(value)
    if not math.isfinite(value):
        raise CfdesignError(f"{what} is not finite; C code needs finite numbers")
    if suffix == "f" and value and not _FLOAT_RANGE[1] <= abs(value) <= _FLOAT_RANGE[0]:
        raise CfdesignError(f"{what} = {value!r} is outside the range of float (it would overflow or round to "
                            "zero); export with --precision double")
    return repr(value) + suffix


def _initializer(a, suffix, depth=0, what="value") -> str:
    """A brace initializer of a (nested) array, one innermost row per line."""
    if a.ndim == 1:
        items = [str(int(v)) if a.dtype.kind in "iub" else _literal(v, suffix, what) for v in a]
        return "{" + ", ".join(items) + "}"
    sep = ",\n" + "    " * (depth + 1)
    rows = sep.join(_initializer(row, suffix, depth + 1, what) for row in a)
    return "{" + "\n" + "    " * (depth + 1) + rows + "\n" + "    " * depth + "}"


def _template(stem) -> Template:
    return Template((resources.files(__package__) / "templates" / f"{stem}.in").read_text())
