"""The streaming step specialised to one table: straight-line Python on floats.

:meth:`cfdesign.runtime.Runtime.step` is called once per sample from a robot loop or a ROS
callback, where numpy's per-call overhead (a dozen small arrays) costs more than the filter
itself.  This module writes the step of one table as straight-line Python on plain floats - the
recursion of :mod:`cfdesign.linear` (``e = y - H x``, ``x+ = x + L e``, ``x <- F x + B u + Kp e``)
with the table's numbers written in as constants, the products with zero coefficients left out,
the gains of a multirate table looked up per phase - the same operations, in the same order, as
the generated C (:mod:`cfdesign.codegen`).

The source is built from numbers and names only: each constant is the ``repr`` of a finite
float, the keyword arguments are the table's sensor names - ASCII identifiers that are not
keywords, checked by the table and again here against ``[A-Za-z_][A-Za-z0-9_]*`` - and every
other name is fixed by this module.  No other text from the table (its name, its provenance)
enters it, and no text is evaluated as an expression.
"""

from __future__ import annotations

import functools
import keyword
import math
import numbers
import re
from decimal import Decimal

from ..errors import CfdesignError
from ..linear import gain_pair, wrap_scalar

#: states up to this size are read and written element by element
_UNROLLED = 16
#: step sources up to this long keep their compiled code for the next runtime of the same table
#: (a runtime per log, per call); larger ones (thousands of products) are compiled each time
_CACHED_SOURCE = 100_000
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
#: the real scalar types other than float that readings have come as (int, numpy's floats and
#: ints, Fraction, ...; not bool, refused as a reading): a reading of one of these is converted
#: by ``float()`` without the full check (``_as_float``)
_REALS = {int}

__all__ = ["compile_step"]


def _as_float(v):
    """A reading that is not a Python float as one (the step's slow path), or None if it is not a
    real number.

    Python and numpy reals (``int``, ``Fraction``, ``numpy.float32``, ``numpy.int64``,
    ``numpy.float64``, a 0-d array) become the float of their value, so that the state stays in
    Python floats: a numpy scalar kept in it would make every later step compute in numpy
    scalars (2.5x slower) and a ``float32`` one in single precision.  An int too large for a
    float becomes +-inf (beyond the reading limit: rejected and counted).  A masked numpy value
    (``numpy.ma.masked``, a 0-d masked array) is a missing reading, NaN (its ``item()`` was the
    value under the mask, or 0.0).  Text, None, complex, a ``Decimal`` and arrays of one value or
    more are not real numbers here.
    """
    if getattr(v, "shape", None) == () and hasattr(v, "item"):  # a numpy scalar or 0-d array
        if bool(getattr(v, "mask", False)):  # numpy.ma: a masked value
            return math.nan
        v = v.item()
    if isinstance(v, numbers.Real) and not isinstance(v, (bool, Decimal)):
        try:
            return float(v)
        except OverflowError:
            return math.inf if v > 0 else -math.inf
    return None


def real_float(v):
    """A reading as a Python float, or None if it is not a real number (see ``_as_float``).

    Fast for a float and for the real types seen before (``_REALS``: int, a numpy float
    once one has come); an int too large for a float is +-inf.

    Parameters
    ----------
    v : object
        The reading.

    Returns
    -------
    float or None
        Its value, or None for text, None, a bool, complex, a ``Decimal`` or an array of one value or more.
    """
    if type(v) is float:
        return v
    if type(v) in _REALS:
        try:
            return float(v)
        except OverflowError:
            return math.inf if v > 0 else -math.inf
    out = _as_float(v)
    if out is not None and isinstance(v, numbers.Real):
        _REALS.add(type(v))
    return out


def _num(v: float) -> str:
    v = float(v)
    if not math.isfinite(v):  # a table is checked at load; this guards the source anyway
        raise ValueError(f"constant {v!r} is not finite")
    return repr(v)


def _dot(coeffs, names, lookup=None) -> str:
    """``c0*n0 + c1*n1 ...`` over the non-zero coefficients (``lookup[i]`` when per phase)."""
    terms = []
    for i, (c, name) in enumerate(zip(coeffs, names, strict=True)):
        if c == 0:
            continue
        coef = f"{lookup}[{i}]" if lookup else (None if c == 1.0 else _num(c))
        terms.append(f"{coef}*{name}" if coef else name)
    return " + ".join(terms) or "0.0"


@functools.lru_cache(maxsize=32)
def _compiled(source: str, filename: str):
    """``compile(source, filename, 'exec')``, kept for the tables built again."""
    return compile(source, filename, "exec")


def compile_step(table, output: str, limit: float, S, U, REJ, UNS, unknown, lock):
    """The streaming step of one table as straight-line Python, bound to the state lists given.

    ``step(sensor=value, ...)`` takes the readings by the sensors' names (a sensor left out has
    no reading; any other keyword calls ``unknown(dict)``, which raises), ``step_values(u_0,
    ..., y_0, ...)`` positionally (inputs, then measurements).  Both return the posterior
    estimate ``x[0] + (L e)[0]`` or the prior ``x[0]`` (``output``) and update the lists in
    place.

    Parameters
    ----------
    table : GainTable
        A discrete table.
    output : {'prior', 'posterior'}
        The estimate meant: ``prior`` (the one-step prediction) or ``posterior`` (after the step's
        readings).
    limit : float
        Readings beyond this magnitude (SI) are rejected like inf.
    S : list
        The state floats, then the phase, then (multirate tables) the periods completed.
    U : list
        The last inputs received (held when one is missing).
    REJ : list of int
        Per-sensor counters of rejected readings (inf, or beyond ``limit``; NaN is simply
        missing), inputs then measurements.
    UNS : list of int
        Per-measurement counters of readings at a phase the schedule does not read (``lock``
        counts them, and the step those it refuses as faster than designed).
    unknown : callable
        Called with the unknown keyword readings; it raises.
    lock : PhaseLock
        The runtime's :class:`~cfdesign.runtime.lock.PhaseLock` over ``S`` and ``UNS``.  The step
        sets ``lock.ON[i]`` to the tick of a reading of measurement ``i`` that has a gain
        (multirate tables: ``S[n + 1] * period + phase``).  A usable reading at a phase without a
        gain for it, at a tick before ``lock.soon[i]`` (faster than designed, warned of already),
        the step counts as :meth:`~cfdesign.runtime.lock.PhaseLock.unscheduled` would refuse it
        (``ON[i]`` None, ``last[i]`` and ``soon[i]`` moved on); any other it passes to
        ``lock.unscheduled(i, phase)``: the phase to run the step at instead (it has set it; the
        step runs again there with the readings as received, those of earlier rows it refused or
        rejected as missing: each reading is used or counted once), or -1 (it has counted the
        reading).

    Returns
    -------
    step : callable
        One step from keyword readings (``sensor=value``), returning the estimate.
    step_values : callable
        One step from the readings as positional values, inputs then measurements.
    source : str
        The generated Python source.

    Raises
    ------
    ValueError
        The posterior asked of a table whose ``F`` is singular, or sensor names that are not
        distinct identifiers.

    Notes
    -----
    The steps make every reading a Python float (``_as_float``: numpy scalars and ints by
    their value) and compare it with ``limit`` before they store anything, so the state holds
    Python floats whatever the caller passes, and a reading that is not a real number (text,
    None, a complex, a ``Decimal``, an array) raises :class:`~cfdesign.errors.CfdesignError`
    naming its sensor and leaves the state, the held inputs and the counts as they were.
    """
    F, B, H = table.F, table.B, table.H
    n, p, m, P = F.shape[0], B.shape[1], H.shape[0], table.period
    pairs = [gain_pair(F, K, table.gain_form) for K in table.K]
    Kp = [kp for kp, _ in pairs]
    L = [l0 for _, l0 in pairs]
    posterior = output == "posterior"
    if posterior and any(l0 is None for l0 in L):
        raise ValueError("a posterior estimate needs an invertible F")
    active = table.schedule.mask()
    wrap_rows = [bool(table.wrap_angle) and s.order == 0 for s in table.measurements]
    names = [s.name for s in table.sensors]
    if len(set(names)) != len(names) or not all(_IDENTIFIER.match(x) and not keyword.iskeyword(x) for x in names):
        raise ValueError("sensor names must be distinct ASCII identifiers")
    # every name of the source other than the sensors' keywords is this module's; a sensor may be
    # called anything (``S``, ``PI``, ``u0``, ``unknown``), so an internal name it takes gets a ``_``
    taken = set(names)

    def fresh(base):
        name = base
        while name in taken:
            name += "_"
        taken.add(name)
        return name

    N = {key: fresh(key) for key in ("S", "U", "REJ", "UNS", "ON", "LAST", "SOON", "LOCK", "ph2", "tick",
                                     "step_values", "WRAP", "NAN",
                                     "UNKNOWN", "KP", "LP",
                                     "AC", "K", "A", "L", "ph", "est", "unknown", "make", "AS_FLOAT", "REALS",
                                     "type", "float", "OverflowError")}
    xs, us = [fresh(f"x{i}") for i in range(n)], [fresh(f"u{j}") for j in range(p)]
    es, ys = [fresh(f"e{i}") for i in range(m)], [fresh(f"y{i}") for i in range(m)]
    nx = [fresh(f"n{r}") for r in range(n)]
    S_, U_, REJ_, UNS_, WRAP = (N[k] for k in ("S", "U", "REJ", "UNS", "WRAP"))
    # the limit and pi as literals (constants of the code object: no name look-up, no negation per step)
    LIM, PI = _num(limit), _num(math.pi)
    K_, A_, L_, ph, est = (N[k] for k in ("K", "A", "L", "ph", "est"))
    lines = []
    add = lines.append
    if n > _UNROLLED:  # element by element is faster for small states (no tuple, no slice)
        add(f"    {', '.join(xs)}, = {S_}[:{n}]")
    else:
        for i in range(n):
            add(f"    {xs[i]} = {S_}[{i}]")
    if P > 1:
        add(f"    {ph} = {S_}[{n}]")
    # every reading is made a Python float before anything is stored (a numpy scalar, an int:
    # the float of its value); one that is not a real number (text, None, complex, a Decimal,
    # an array) raises there, and then nothing has changed
    oks = [fresh(f"ok{j}") for j in range(p + m)]
    # (a real number type seen before - int, bool, a numpy float - converted by float(), else
    # checked; an int too large for a float raises OverflowError there: then the check for all)
    if us + ys:
        add("    try:")
    for j, v in enumerate(us + ys):
        add(f"        if {N['type']}({v}) is not {N['float']}:")
        add(f"            {v} = {N['float']}({v}) if {N['type']}({v}) in {N['REALS']} else {N['AS_FLOAT']}({v}, {j})")
    if us + ys:
        add(f"    except {N['OverflowError']}:")
        for j, v in enumerate(us + ys):
            add(f"        {v} = {N['AS_FLOAT']}({v}, {j})")
    for ok, v in zip(oks, us + ys, strict=True):
        add(f"    {ok} = -{LIM} <= {v} <= {LIM}")  # (-literal: folded into one constant)
    for j, u in enumerate(us):  # an input outside the limit (inf) or missing (NaN) holds the last one
        add(f"    if {oks[j]}:")
        add(f"        {U_}[{j}] = {u}")
        add("    else:")
        add(f"        if {u} == {u}:")
        add(f"            {REJ_}[{j}] += 1")
        add(f"        {u} = {U_}[{j}]")
    single = P == 1
    if m and not single:
        add(f"    {K_} = {N['KP']}[{ph}]")
        add(f"    {A_} = {N['AC']}[{ph}]")
        if posterior:
            add(f"    {L_} = {N['LP']}[{ph}]")
    for i in range(m):
        add(f"    {es[i]} = 0.0")
        add(f"    if {oks[p + i]}:")
        if single and not active[0, i]:
            add(f"        {N['LOCK']}({i}, 0)")
        else:
            pad = "        " if single else "            "
            if not single:
                add(f"        if {A_}[{i}]:")
            add(f"{pad}{es[i]} = {ys[i]} - ({_dot(H[i], xs)})")
            if wrap_rows[i]:
                add(f"{pad}if {es[i]} > {PI} or {es[i]} <= -{PI}:")
                add(f"{pad}    {es[i]} = {WRAP}({es[i]})")
            if not single:  # no gain at this phase: the lock moves the phase and steps again, or counts it
                add(f"            {N['ON']}[{i}] = {S_}[{n + 1}] * {P} + {ph}")  # the tick of its reading
                add("        else:")
                # a value held and repeated (faster than designed, warned of): counted as the lock refuses it
                tick = N["tick"]
                add(f"            {tick} = {S_}[{n + 1}] * {P} + {ph}")
                add(f"            if {tick} < {N['SOON']}[{i}]:")
                add(f"                {N['ON']}[{i}] = None")
                add(f"                {N['LAST']}[{i}] = {tick}")
                add(f"                {UNS_}[{i}] += 1")
                add(f"                {N['SOON']}[{i}] = {tick} + {int(lock.half[i])}")
                add("            else:")
                add(f"                {N['ph2']} = {N['LOCK']}({i}, {ph})")
                add(f"                if {N['ph2']} >= 0:")
                # the readings as received, those before row i already counted here as NaN: rejected
                # (not ok) or refused by the lock (no gain at this phase: a reading used at the new
                # phase as well would be counted and used, one refused again counted twice)
                again = us + [f"({ys[j]} if {oks[p + j]} and {A_}[{j}] else {N['NAN']})" for j in range(i)] + ys[i:]
                add(f"                    return {N['step_values']}({', '.join(again)})")
        add(f"    elif {ys[i]} == {ys[i]}:")
        add(f"        {REJ_}[{p + i}] += 1")
    if posterior:
        row = [L[0][0, i] for i in range(m)] if single else [any(l0[0, i] != 0 for l0 in L) for i in range(m)]
        add(f"    {est} = {xs[0]} + ({_dot(row, es, None if single else L_)})" if any(row) else f"    {est} = {xs[0]}")
    else:
        add(f"    {est} = {xs[0]}")
    for r in range(n):
        terms = [_dot(F[r], xs)]
        if B[r].any():
            terms.append(_dot(B[r], us))
        if m:  # a row no gain corrects at any phase adds nothing (not even + 0.0)
            if single and Kp[0][r].any():
                terms.append(_dot(Kp[0][r], es))
            elif not single:
                used = [any(k[r, i] != 0 for k in Kp) for i in range(m)]
                flat = [f"{K_}[{r * m + i}]*{es[i]}" for i in range(m) if used[i]]
                if flat:
                    terms.append(" + ".join(flat))
        add(f"    {nx[r]} = " + " + ".join(f"({t})" for t in terms))
    if table.wrap_angle:
        add(f"    if {nx[0]} > {PI} or {nx[0]} <= -{PI}:")
        add(f"        {nx[0]} = {WRAP}({nx[0]})")
        add(f"    if {est} > {PI} or {est} <= -{PI}:")
        add(f"        {est} = {WRAP}({est})")
    if n > _UNROLLED:
        add(f"    {S_}[:{n}] = {', '.join(nx)},")
    else:
        for i in range(n):
            add(f"    {S_}[{i}] = {nx[i]}")
    if P > 1:  # the phase, and the periods completed (the lock's tick count)
        add(f"    if {ph} == {P - 1}:")
        add(f"        {S_}[{n}] = 0")
        add(f"        {S_}[{n + 1}] += 1")
        add("    else:")
        add(f"        {S_}[{n}] = {ph} + 1")
    add(f"    return {est}")
    body = "\n".join("    " + line for line in lines)
    keywords = ", ".join(f"{name}={N['NAN']}" for name in names)
    rename = "".join(f"        {v} = {name}\n" for v, name in zip(us + ys, names, strict=True))
    unknown_ = N["unknown"]
    source = (f"def {N['make']}({S_}, {U_}, {REJ_}, {UNS_}, {N['ON']}, {N['LAST']}, {N['SOON']}, {N['LOCK']}):\n"
              f"    def step({keywords + ', ' if names else ''}**{unknown_}):\n"
              f"        if {unknown_}:\n            {N['UNKNOWN']}({unknown_})\n{rename}{body}\n"
              f"    def {N['step_values']}({', '.join(us + ys)}):\n{body}\n"
              f"    return step, {N['step_values']}\n")
    def as_float(value, j):
        out = _as_float(value)
        if out is None:
            raise CfdesignError(f"{names[j]}: reading {value!r} is not a number")
        if isinstance(value, numbers.Real):  # a scalar type: float() it next time
            _REALS.add(type(value))
        return out

    namespace = {WRAP: wrap_scalar, N["NAN"]: math.nan, N["UNKNOWN"]: unknown,
                 N["AS_FLOAT"]: as_float, N["REALS"]: _REALS, N["type"]: type, N["float"]: float,
                 N["OverflowError"]: OverflowError,
                 N["KP"]: [tuple(float(v) for v in k.reshape(-1)) for k in Kp],
                 N["LP"]: [tuple(float(v) for v in (l0[0] if l0 is not None else [0.0] * m)) for l0 in L],
                 N["AC"]: [tuple(bool(v) for v in row) for row in active]}
    filename = f"<cfdesign step of a {n}-state table>"
    code = _compiled(source, filename) if len(source) <= _CACHED_SOURCE else compile(source, filename, "exec")
    exec(code, namespace)
    step, step_values = namespace[N["make"]](S, U, REJ, UNS, lock.ON, lock.last, lock.soon, lock.unscheduled)
    return step, step_values, source
