"""Crossover equations solved with sympy: the closed forms :mod:`cfdesign.crossover` uses.

For a continuous observer every band has the denominator ``det(sI - A)``, so adjacent bands
``a`` and ``b`` (ordered by their sensors' derivative order) have equal magnitude at ``w``
exactly when their numerators do:

.. math:: |N_a(j w)|^2 - |N_b(j w)|^2 = 0,

a polynomial equation in the gains.  One equation per crossover; a structure with one gain
more than crossovers (cf2 order 2) takes the damping ``zeta`` of its poles as the extra
condition (``k1 = 2 zeta w_n``, ``k2 = w_n^2``).  ``docs/derivations.md``, section "Design by
crossover", shows the solutions.
"""

from __future__ import annotations

import sympy as sp

from ..errors import StructureError

__all__ = ["crossover_equations", "crossover_solution"]


def crossover_equations(observer, omegas):
    """The crossover equations ``|N_a(j w_i)|^2 - |N_b(j w_i)|^2`` of a continuous observer.

    Parameters
    ----------
    observer : Observer
        Continuous, with symbolic gains; bands taken in order of their sensors' derivative
        order.
    omegas : sequence
        One crossover frequency (rad/s; sympy symbols or numbers) per pair of adjacent bands.

    Returns
    -------
    list of sympy expression
        Polynomials in the gains, zero at the crossover gains.

    Raises
    ------
    StructureError
        A discrete observer, or a count of frequencies other than the number of bands minus one.
    """
    if observer.discrete:
        raise StructureError("crossover equations in closed form are for continuous observers; discrete "
                             "designs are solved numerically (cfdesign.crossover)")
    names = [x.name for x in sorted(observer.sensors, key=lambda x: x.order)]
    if len(omegas) != len(names) - 1:
        raise StructureError(f"{observer.name} has {len(names)} bands: give {len(names) - 1} crossover frequencies")
    w = sp.Symbol("w", positive=True)
    real = {p: sp.Symbol(p.name, real=True) for p in observer.parameters}
    nums = {}
    for name in names:
        num, _ = observer.band_fraction(name)
        value = sp.expand(num.subs(real).subs(observer.variable, sp.I * w))
        nums[name] = sp.expand(sp.re(value) ** 2 + sp.im(value) ** 2)
    back = {v: k for k, v in real.items()}
    pairs = zip(names[:-1], names[1:], omegas, strict=True)
    return [sp.expand((nums[a] - nums[b]).subs(w, wi).subs(back)) for a, b, wi in pairs]


def crossover_solution(observer, omegas, damping=None) -> dict:
    """The positive solution of :func:`crossover_equations`.

    Parameters
    ----------
    observer : Observer
        Continuous, with symbolic gains.
    omegas : sequence
        Crossover frequencies (rad/s): sympy symbols (declared positive) or numbers.
    damping : sympy expression or float, optional
        Adds the pole shape of a two-gain, one-crossover structure (cf2 order 2).

    Returns
    -------
    dict
        ``{gain symbol: expression}``.

    Raises
    ------
    StructureError
        No unique positive solution, or a damping for a structure other than two gains and
        one crossover.

    Examples
    --------
    >>> import sympy as sp
    >>> import cfdesign
    >>> from cfdesign.symbolic.crossover import crossover_solution
    >>> w1, w2 = sp.symbols("w1 w2", positive=True)
    >>> crossover_solution(cfdesign.cf3(), [w1, w2])
    {k1: w2, k2: w1*w2}
    """
    gains = [observer.symbol(g) for g in observer.gains]
    eqs = crossover_equations(observer, omegas)
    if damping is not None:
        if len(gains) != 2 or len(eqs) != 1:
            raise StructureError("damping applies to a structure with two gains and one crossover (cf2 order 2)")
        wn = sp.Symbol("w_n", positive=True)
        shape = {gains[0]: 2 * damping * wn, gains[1]: wn**2}
        roots = [r for r in sp.solve(eqs[0].subs(shape), wn) if _positive_at_one(r)]
        if len(roots) != 1:
            raise StructureError(f"no unique positive natural frequency solves the crossover of {observer.name}")
        return {g: sp.simplify(e.subs(wn, roots[0])) for g, e in shape.items()}
    positive = {g: sp.Symbol(g.name, positive=True) for g in gains}
    eqs = [e.subs(positive) for e in eqs]
    found = sp.solve(eqs, list(positive.values()), dict=True)
    found = [sol for sol in found if len(sol) == len(gains)]
    if len(found) != 1:
        raise StructureError(f"{observer.name}: the crossover equations have {len(found)} positive solutions")
    return {g: sp.simplify(found[0][positive[g]]) for g in gains}


def _positive_at_one(expr) -> bool:
    """A root is the physical one when it is real and positive (checked with every symbol = 1)."""
    value = complex(expr.subs({x: 1 for x in expr.free_symbols}).evalf())
    return abs(value.imag) < 1e-12 and value.real > 0
