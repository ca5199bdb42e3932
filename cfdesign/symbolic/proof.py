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

__all__ = ["Proof", "prove"]


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
    """

    structure: str
    variable: sp.Symbol
    bands: dict
    total: object
    residual: object
    parameters: tuple

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
        """Plain-text rendering: every band, the sum, the residual and the verdict.

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
            (strings) and ``holds`` (bool).
        """
        return {
            "structure": self.structure,
            "variable": str(self.variable),
            "bands": {k: str(e) for k, e in self.bands.items()},
            "sum": str(self.total),
            "residual": str(self.residual),
            "holds": self.holds,
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
        The outcome; ``holds`` is True when the bands sum to exactly one.

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
    return Proof(observer.name, observer.variable, dict(bands), total, residual, observer.parameters)


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
