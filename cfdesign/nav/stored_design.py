"""Gain tables for the navigation filters without the symbolic engine, and the check that one fits.

The filters of :mod:`cfdesign.nav` run designed :class:`~cfdesign.gains.GainTable` s; they
never run the symbolic design stack.  Their default gains come from the numeric design
stage, :func:`cfdesign.designer.design_from_structure` (noise -> Van Loan -> Riccati,
numpy/scipy), applied to a structure stored with cfdesign
(:meth:`cfdesign.designer.Structure.load`): the same gains, bit for bit, as
:func:`cfdesign.design <cfdesign.designer.design>`, without sympy.

A user's own design drives a filter as a ``GainTable`` (from :func:`cfdesign.design <cfdesign.designer.design>`, a
saved table, or this module) or as a :class:`~cfdesign.spec.FilterSpec` of the filter's
structure, designed here.  :func:`check_fits` checks that a table is the model the filter
runs, at the filter's sample time, and raises a one-line
:class:`~cfdesign.errors.TableMismatchError` naming the mismatch otherwise.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from ..designer import Structure, design_from_structure
from ..errors import TableMismatchError
from ..gains import GainTable
from ..spec import FilterSpec

__all__ = ["STORED", "stored_structure", "design_stored", "as_table", "check_fits"]

#: stored structures the filters run: name -> (spec structure, spec options, description)
STORED = {
    "cf2-order2-discrete": ("cf2", {"order": 2, "discrete": True}, "cf2 order 2, discrete"),
    "position": ("position", {}, "position"),
}


@functools.cache
def stored_structure(name: str) -> Structure:
    """The stored structure ``name`` (``cfdesign/structures/NAME.json``), read once.

    Parameters
    ----------
    name : str
        A key of :data:`STORED`.

    Returns
    -------
    cfdesign.designer.Structure
        The structure (the same object on every call).

    Raises
    ------
    SpecError
        No stored structure of that name.
    """
    return Structure.load(name)


def design_stored(spec: FilterSpec, name: str) -> GainTable:
    """Gains for a spec on a stored structure (the numeric design stage, no sympy).

    Sensors that play a structure's sensor under another name (``port``) are renamed as
    :func:`cfdesign.design <cfdesign.designer.design>` does.

    Parameters
    ----------
    spec : FilterSpec
        The sensors and their noise.
    name : str
        A key of :data:`STORED`.

    Returns
    -------
    GainTable
        The designed gain table.

    Raises
    ------
    SpecError
        The spec does not fit the structure.
    """
    structure = stored_structure(name)
    ports = {x.port: x.name for x in spec.sensors if x.port is not None}
    if ports:
        structure = replace(structure, sensors=tuple(replace(s, name=ports.get(s.name, s.name))
                                                     for s in structure.sensors))
    return design_from_structure(structure, spec)


def as_table(value, name: str, what: str) -> GainTable:
    """A value as a gain table: a :class:`~cfdesign.gains.GainTable` itself, or the design of a FilterSpec.

    Parameters
    ----------
    value : GainTable or FilterSpec
        A user's table or design (``tables=`` / ``table=`` of a navigation filter).
    name : str
        The stored structure a spec must be designed on (a key of :data:`STORED`).
    what : str
        How the message names the value.

    Returns
    -------
    GainTable
        ``value`` itself, or the design of ``value`` on the stored structure ``name``.

    Raises
    ------
    TableMismatchError
        Anything else, or a spec of another structure (naming ``what``).
    """
    if isinstance(value, GainTable):
        return value
    if isinstance(value, FilterSpec):
        structure, options, description = STORED[name]
        got = {key: getattr(value, key) for key in options}
        if value.structure != structure or got != options:
            shown = ", ".join([value.structure, *(f"{k} = {v}" for k, v in got.items())])
            raise TableMismatchError(f"{what}: spec {value.name!r} is a {shown} design; this filter runs "
                                     f"{description}")
        return design_stored(value, name)
    raise TableMismatchError(f"{what}: a GainTable or a FilterSpec is needed, got {type(value).__name__}")


def check_fits(table: GainTable, what: str, *, F, B, H, orders: tuple, sample_time_s: float, period: int = 1,
               model: str, timing: str):
    """Check that a table is the filter's model at its sample time.

    Parameters
    ----------
    table : GainTable
        The designed table to check.
    what : str
        How the message names the table (e.g. ``tables[0] (tilt)``).
    F, B, H : array_like
        The model the filter runs (discrete, at ``sample_time_s``).
    orders : tuple of int
        ``(input order, measurement order)`` of its two sensors.
    sample_time_s : float
        The filter's sample time (s).
    period : int
        The multirate period (steps) the filter expects.
    model : str
        The model in words, for the message.
    timing : str
        Where the sample time comes from, for the message (``rate_hz = 100``).

    Raises
    ------
    TableMismatchError
        A continuous table, other shapes, sensor orders, sample time, period or model
        matrices; the message names the difference.
    """
    F, B, H = (np.asarray(M, dtype=float) for M in (F, B, H))
    if table.domain != "z":
        raise TableMismatchError(f"{what}: {table.name!r} is a continuous-time table; this filter runs {model} "
                                 "(a discrete design)")
    shapes = (np.shape(table.F), np.shape(table.B), np.shape(table.H))
    if shapes != (F.shape, B.shape, H.shape):
        raise TableMismatchError(f"{what}: {table.name!r} has {shapes[0][0]} states, {shapes[1][1]} input(s) and "
                                 f"{shapes[2][0]} measurement(s); this filter runs {model}")
    got = (table.inputs[0].order, table.measurements[0].order)
    if got != tuple(orders):
        raise TableMismatchError(f"{what}: {table.name!r} has an input of derivative order {got[0]} and a "
                                 f"measurement of order {got[1]}; this filter runs {model}")
    if not math.isclose(table.sample_time_s, sample_time_s, rel_tol=1e-9):
        raise TableMismatchError(f"{what}: {table.name!r} has sample time {table.sample_time_s:g} s; this filter "
                                 f"steps every {sample_time_s:g} s ({timing})")
    if table.period != period:
        raise TableMismatchError(f"{what}: {table.name!r} has a period of {table.period} step(s); this filter "
                                 f"expects {period} ({timing})")
    scale = max(1.0, float(np.abs(F).max()))
    for key, want in (("F", F), ("B", B), ("H", H)):
        if not np.allclose(getattr(table, key), want, rtol=1e-9, atol=1e-12 * scale):
            raise TableMismatchError(f"{what}: {table.name!r} has another {key} than this filter's model, {model}")
