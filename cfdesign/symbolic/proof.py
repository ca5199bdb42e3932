"""Exact complementarity proofs: the bands of an observer sum to one.

Continuous (Carreira et al. eq. (1)): ``sum_i T_i(s) = 1``; discrete (Carreira et al. eq. (34)):
``sum_i T_i(z) = 1``.  The proof writes ``sum_i T_i - 1`` over the bands' common
denominator: the identity holds for every value of the variable and of every symbolic gain
exactly when the numerator expands to the zero polynomial.  Before that, a check free of the
gains settles most observers: when the sensors' relations are a trajectory of the model, the
bands sum to one for every gain.  When it does not, ``sum_i T_i - 1``
is reduced with ``sympy.cancel`` to the canonical ``p/q`` form (``p`` and ``q`` coprime,
expanded) that shows what is left.  No floating point is involved; numeric gains are kept as
exact rationals.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import sympy as sp

__all__ = ["Proof", "prove", "explain"]


@dataclass(frozen=True)
class Proof:
    """The outcome of a complementarity proof.

    Attributes
    ----------
    structure : str
        Name of the observer proved.
    variable : sympy.Symbol
        ``s`` (continuous) or ``z`` (discrete).
    bands : Mapping
        ``{sensor: T_i}`` as derived by the engine (derived when first read if the proof
        holds).
    total : sympy expression
        ``sum_i T_i`` in canonical form (``1`` when the proof holds).
    residual : sympy expression
        ``sum_i T_i - 1`` in canonical form (``0`` when the proof holds).
    parameters : tuple
        Symbols left free (the identity holds for all their values).
    reason : str
        Why a proof that fails fails, in terms of the model and the sensors (a continuous
        model given as discrete, a sample time left symbolic, the sensor whose relation the
        model does not follow); ``""`` when the proof holds.
    """

    structure: str
    variable: sp.Symbol
    bands: dict
    total: object
    residual: object
    parameters: tuple
    reason: str = ""

    @property
    def holds(self) -> bool:
        """True when ``sum_i T_i - 1`` is identically zero."""
        return self.residual == 0

    @property
    def verdict(self) -> str:
        """One line: ``HOLDS: the bands sum to 1 identically in s, k1, ...`` or ``FAILS: ...``."""
        free = ", ".join(map(str, (self.variable, *self.parameters)))
        if self.holds:
            return f"HOLDS: the bands sum to 1 identically in {free}"
        return f"FAILS: the bands sum to {self.total}, not 1"

    def text(self) -> str:
        """Plain-text rendering: every band, the sum, the residual, the verdict and why a proof fails.

        Returns
        -------
        str
            Several lines, as ``cfdesign prove`` prints them.

        Examples
        --------
        >>> import cfdesign
        >>> print(cfdesign.cf2().proof().text())
        Complementarity proof for cf2 (order 1) (variable s)
          T_rate(s)  = s/(k + s)
          T_angle(s) = k/(k + s)
          sum        = 1
          sum - 1    = 0
          HOLDS: the bands sum to 1 identically in s, k
        """
        v = self.variable
        width = max(len(k) for k in self.bands) + len(f"T_({v})")
        lines = [f"Complementarity proof for {self.structure} (variable {v})"]
        lines += [f"  {f'T_{k}({v})':<{width}} = {expr}" for k, expr in self.bands.items()]
        lines += [f"  {'sum':<{width}} = {self.total}",
                  f"  {'sum - 1':<{width}} = {self.residual}",
                  f"  {self.verdict}"]
        if self.reason:
            lines.append(f"  why: {self.reason}")
        return "\n".join(lines)

    def latex(self) -> str:
        """LaTeX rendering of the bands, their sum and the residual.

        Returns
        -------
        str
            An ``aligned`` environment (without the surrounding ``$$``).
        """
        v = sp.latex(self.variable)
        rows = [rf"T_{{\mathrm{{{k}}}}}({v}) &= {sp.latex(e)}" for k, e in self.bands.items()]
        terms = " + ".join(rf"T_{{\mathrm{{{k}}}}}" for k in self.bands)
        rows.append(rf"{terms} - 1 &= {sp.latex(self.residual)}")
        return r"\begin{aligned}" + r" \\ ".join(rows) + r"\end{aligned}"

    def to_dict(self) -> dict:
        """JSON-ready form of the proof (``cfdesign prove --json``).

        Returns
        -------
        dict
            ``structure``, ``variable``, ``bands`` (``{sensor: str}``), ``sum``, ``residual``
            (strings), ``holds`` (bool) and ``reason`` (str, ``""`` when it holds).
        """
        return {
            "structure": self.structure,
            "variable": str(self.variable),
            "bands": {k: str(e) for k, e in self.bands.items()},
            "sum": str(self.total),
            "residual": str(self.residual),
            "holds": self.holds,
            "reason": self.reason,
        }

    def __str__(self):
        return self.text()

    def _repr_latex_(self):
        return f"$${self.latex()}$$"


def prove(observer) -> Proof:
    """Prove (or refute) exactly that the bands of an observer sum to one.

    Continuous (Carreira et al. eq. (1)): ``sum_i T_i(s) = 1``; discrete (Carreira et al.
    eq. (34)): ``sum_i T_i(z) = 1``.  It holds for every gain when the sensors' relations are a
    trajectory of the model (:attr:`Observer.relations_follow_the_model
    <cfdesign.symbolic.observer.Observer.relations_follow_the_model>`, no gain involved).
    Otherwise, over the bands' common denominator, ``sum_i T_i - 1`` has the numerator
    :attr:`Observer.residual_numerator <cfdesign.symbolic.observer.Observer.residual_numerator>`;
    the identity holds for every value of the variable and of every symbolic gain exactly when
    that expands to the zero polynomial (``docs/derivations.md``, "One observer").  When it does not, ``sum_i T_i - 1``
    is reduced with ``sympy.cancel`` to its canonical ``p/q`` form to show what is left.

    Parameters
    ----------
    observer : Observer
        Symbolic or numeric (numbers are exact rationals).

    Returns
    -------
    Proof
        The outcome; ``holds`` is True when the bands sum to exactly one, and when it is not,
        ``reason`` says why (:func:`~cfdesign.symbolic.proof.explain`).

    Raises
    ------
    StructureError
        ``observer`` is not an Observer (a structure's name: ``cfdesign.structure(name)``
        builds it).

    Examples
    --------
    >>> import cfdesign
    >>> proof = cfdesign.prove(cfdesign.dckf3())
    >>> proof.holds, proof.residual
    (True, 0)
    """
    from .observer import Observer

    if not isinstance(observer, Observer):  # a name or a python-control system raised a raw AttributeError
        from ..errors import StructureError

        hint = f": build it with cfdesign.structure({observer!r})" if isinstance(observer, str) else ""
        raise StructureError(f"prove takes an Observer, got {type(observer).__name__}{hint}")
    if observer.relations_follow_the_model or observer.residual_numerator == 0:  # holds, no band reduced
        return Proof(observer.name, observer.variable, _Bands(observer), sp.Integer(1), sp.Integer(0),
                     observer.parameters)
    bands = observer.bands
    total = sp.cancel(sp.together(sum(bands.values())))
    residual = sp.cancel(sp.together(total - 1))
    reason = "" if residual == 0 else explain(observer)
    return Proof(observer.name, observer.variable, dict(bands), total, residual, observer.parameters, reason)


def explain(observer) -> str:
    """Why the bands of an observer do not sum to one, in terms a user can act on.

    The bands sum to one for every gain when the sensors' relations are a trajectory of the
    model (``docs/derivations.md``, "Bands, and why they sum to one"), so a proof that fails
    has a relation the model does not follow.  The usual ways to get there are named first: a
    continuous ``F, B`` given with ``domain='z'``, a sample time left symbolic beside numeric
    ``F, B``, ``F, B`` sampled at another sample time than the one given; otherwise each
    relation the model does not follow is named with the one the model implies.

    Parameters
    ----------
    observer : Observer
        Symbolic or numeric.

    Returns
    -------
    str
        One sentence or more; ``""`` when the relations follow the model (the proof holds).

    Examples
    --------
    A numeric ``F, B`` sampled at 0.01 s, given without ``sample_time=``:

    >>> import cfdesign
    >>> gyro, compass = cfdesign.Sensor.input("gyro", "rate"), cfdesign.Sensor.measurement("compass", "angle", 0)
    >>> obs = cfdesign.Observer([[1]], [[0.01]], [[1]], [[0.5]], [gyro, compass], domain="z")
    >>> print(explain(obs).split("; ")[-1])
    pass sample_time=0.01 (s), the sample time F and B follow
    """
    if observer.relations_follow_the_model:
        return ""
    for cause in (_continuous_model_as_discrete, _symbolic_sample_time, _other_sample_time):
        reason = cause(observer)
        if reason:
            return reason
    return _unfollowed_relations(observer)


def _default_relations(obs) -> bool:
    """True when every sensor has the chain's relation (none written by hand)."""
    return all(x.relation is None for x in obs.sensors)


def _continuous_model_as_discrete(obs) -> str:
    """A continuous ``F, B`` (its relations ``s**order`` follow it) given with ``domain='z'``."""
    if not obs.discrete or not _default_relations(obs):
        return ""
    from .observer import s

    rows = obs.model_readings(relation=lambda x: s**x.order, variable=s)
    if any(sp.cancel(got - want) != 0 for _, got, want in rows):
        return ""
    return ("F and B are a continuous model (x' = F x + B u follows the relations s**order) given with "
            "domain='z': sample it first (cfdesign.symbolic.zoh(F, B, T), or control.c2d with "
            "Observer.from_statespace), or build the observer with domain='s'")


def _symbolic_sample_time(obs) -> str:
    """The sample time left a symbol (no ``sample_time=``) while ``F, B`` are numbers without it."""
    t = obs._sample_time_symbol
    if t is None or obs.F.has(t) or obs.B.has(t):
        return ""
    uses = [x.name for x in obs.sensors if obs.relation(x).has(t)]
    if not uses:
        return ""
    fit = _fitting_sample_time(obs)
    if fit is not None:
        act = f"pass sample_time={float(fit):g} (s), the sample time F and B follow"
    else:
        act = "pass sample_time=<the model's sample time, s>"
        if not (obs.F.free_symbols | obs.B.free_symbols | obs.H.free_symbols) and _default_relations(obs):
            act += (" (no sample time makes these F and B follow the relations: with it given, the proof names "
                    "the relation they do not follow)")
    which = "relation of " + uses[0] if len(uses) == 1 else "relations of " + ", ".join(uses)
    return (f"the sample time {t} is left symbolic (no sample_time= given) while F and B hold no {t}: "
            f"the {which} involve{'s' if len(uses) == 1 else ''} {t} and the model does not; {act}")


def _other_sample_time(obs) -> str:
    """Numeric ``F, B`` sampled at another sample time than the observer's (numeric) one."""
    if not obs.discrete or obs._sample_time_symbol is not None:
        return ""
    fit = _fitting_sample_time(obs)
    if fit is None or fit == obs.sample_time:
        return ""
    return (f"F and B follow a sample time of {float(fit):g} s, not the sample_time={float(obs.sample_time):g} "
            "given: give the model's sample time, or sample F and B at the one given")


def _fitting_sample_time(obs):
    """The positive sample time at which numeric ``F, B, H`` follow the chain's relations, or None."""
    from .observer import discrete_relation

    if not _default_relations(obs) or (obs.F.free_symbols | obs.B.free_symbols | obs.H.free_symbols):
        return None
    t = sp.Dummy("T", positive=True)
    common = sp.Integer(0)  # gcd of every coefficient (in t) of every difference's numerator (in v)
    for _, got, want in obs.model_readings(relation=lambda x: discrete_relation(x.order, obs.chain_order, t)):
        for c in sp.Poly(sp.numer(sp.together(got - want)), obs.variable).coeffs():
            common = sp.gcd(common, c)
    if common == 0 or common.free_symbols != {t}:
        return None
    fits = sorted(r for r in sp.roots(sp.Poly(common, t)) if r.is_positive)
    return fits[0] if fits else None


def _unfollowed_relations(obs) -> str:
    """Each relation the model does not follow, beside the one it implies."""
    (_, estimate, _), *measured = obs.model_readings()
    out = [] if sp.cancel(estimate - 1) == 0 else [_inputs_not_integrated(obs, estimate)]
    for x, got, want in measured if estimate != 0 else ():
        reads = sp.factor(sp.cancel(got / estimate))  # what the measurement reads of the quantity C X
        if sp.cancel(reads - want) != 0:
            out.append(f"measurement {x.name} is declared {_kind(x.order)}, relation {want}, but row {x.index} "
                       f"of H reads {reads} times the quantity{_like(obs, reads)}")
    return "the sensors' relations are not a trajectory of the model: " + "; ".join(out)


def _inputs_not_integrated(obs, estimate) -> str:
    """What exact input readings make of the estimate, when it is not the quantity itself."""
    inputs = [x for x in obs.sensors if x.role == "input"]
    if not inputs:
        return "no input sensor drives the model, so exact readings leave the estimate at 0, not the quantity"
    names = ", ".join(x.name for x in inputs)
    if estimate == 0:
        return f"the input(s) {names} do not reach the estimate (check the columns of B and the output row)"
    if len(inputs) > 1:
        return (f"F and B do not integrate the inputs {names} into the common quantity: exact readings drive "
                f"the estimate to ({sp.factor(estimate)}) times the quantity, not 1{_chain_hint(obs)}")
    x, rel = inputs[0], obs.relation(inputs[0])
    implied = sp.factor(sp.cancel(rel / estimate))
    return (f"F and B do not integrate input {x.name}, declared {_kind(x.order)} with relation {rel}, into the common "
            f"quantity: exact {x.name} readings drive the estimate to ({sp.factor(estimate)}) times the quantity, "
            f"not 1; this model needs the relation {implied}{_like(obs, implied)}{_chain_hint(obs)}")


def _names(order) -> str:
    """``rate/velocity``: the quantity names of a derivative order (``""`` beyond them)."""
    from ..spec import QUANTITY_ORDERS

    return "/".join(name for name, k in QUANTITY_ORDERS.items() if k == order)


def _kind(order) -> str:
    """``'rate/velocity' (order 1)``."""
    return f"'{_names(order)}' (order {order})" if _names(order) else f"order {order}"


def _like(obs, relation) -> str:
    """`` (the relation of an order-k sensor)`` when ``relation`` is a chain relation, else ``""``."""
    from .observer import discrete_relation

    for k in range(4):  # angle to jerk; in a discrete chain, a sensor of order k makes it at least of order k
        chain = max(obs.chain_order, k)
        standard = discrete_relation(k, chain, obs.sample_time) if obs.discrete else obs.variable**k
        if sp.cancel(relation - standard) == 0:
            return f" (the relation of an order-{k} '{_names(k)}' sensor)"
    return ""


def _chain_hint(obs) -> str:
    """The chain model the relations assume, when the observer is that chain with one top-order input."""
    from .observer import integrator_chain, zoh_chain

    m = obs.chain_order
    inputs = [x for x in obs.sensors if x.role == "input"]
    if obs.n_states != m or len(inputs) != 1 or inputs[0].order != m or not _default_relations(obs):
        return ""
    F, B = zoh_chain(m, obs.sample_time) if obs.discrete else integrator_chain(m)
    if F == obs.F and B == obs.B[:, inputs[0].index]:
        return ""
    how = f"cfdesign.symbolic.zoh_chain({m}, T)" if obs.discrete else f"cfdesign.symbolic.integrator_chain({m})"
    return f"; the chain the relations assume has F = {F.tolist()}, B = {B.T.tolist()[0]} ({how})"


class _Bands(Mapping):
    """An observer's bands, derived when first read (a proof that holds needs none of them)."""

    def __init__(self, observer):
        self._observer = observer

    def __getitem__(self, name):
        return self._observer.bands[name]

    def __iter__(self):
        return iter(x.name for x in self._observer.sensors)

    def __len__(self):
        return len(self._observer.sensors)

    def __repr__(self):
        return repr(dict(self))
