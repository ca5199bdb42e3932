r"""Design by crossover: gains that put the hand-over between adjacent bands where asked.

A crossover is the frequency where two adjacent bands have equal magnitude
(:meth:`cfdesign.analysis.FrequencyResponse.crossovers` finds them on a designed filter; this
module goes the other way).  Bands are ordered by the derivative order of their sensor (the
angle or position sensor is the low-pass band, the top derivative the high-pass one), and
crossover ``i`` is between bands ``i`` and ``i + 1``.

Continuous closed forms (``docs/derivations.md``, section "Design by crossover"; derived by
:func:`cfdesign.symbolic.crossover.crossover_solution` with sympy, and pinned by the tests):

* ``cf2`` order 1, ``T_angle = k/(s + k)``, ``T_rate = s/(s + k)``: ``|k| = |j w_c|`` gives
  ``k = w_c``;
* ``cf2`` order 2, ``T_angle = (k1 s + k2)/d``, ``T_rate = s^2/d``: with the closed-loop poles of
  damping ``zeta`` (``k1 = 2 zeta w_n``, ``k2 = w_n^2``), ``k2^2 + k1^2 w_c^2 = w_c^4`` gives

  .. math:: w_n = w_c \sqrt{\sqrt{1 + 4\zeta^4} - 2\zeta^2}
                = \frac{w_c}{\sqrt{\sqrt{1 + 4\zeta^4} + 2\zeta^2}}

  (the second form is the one computed: the first cancels for a large damping);

* ``cfn`` / ``cf3`` (the sparse pattern of Carreira et al. eq. (13) extended),
  ``T_j = k_{n-1-j} s^j / d``: ``|T_j| = |T_{j+1}|`` at ``w_j`` gives
  ``k_{n-1-j} = k_{n-2-j} w_j`` with ``k_0 = 1``, so ``k_i = w_{n-2} w_{n-3} ... w_{n-1-i}``
  (for the CF³: ``k1 = w_1``, ``k2 = w_0 w_1``).

Discrete filters have ZOH relations, so the magnitudes on the unit circle differ from the
continuous ones: the gains are solved numerically (Brent's method or a least-squares Newton
iteration on the log-magnitude differences, started from the continuous closed form times
``T``, the per-step gain it approximates), the
damping of cf2 order 2 is imposed on the poles ``z = e^{sT}`` (Ackermann's formula), and the
result is checked with the band responses of :mod:`cfdesign.linear` for the estimate the table
outputs.

numpy and scipy only.
"""

from __future__ import annotations

import math

import numpy as np

from . import linear
from .errors import SpecError
from .gains import column_order

__all__ = ["crossover_gains", "crossover_check", "continuous_crossover_gains", "DEFAULT_DAMPING", "CROSSOVER_RTOL"]

#: damping ratio of the closed-loop poles of cf2 order 2 unless the design file gives one
DEFAULT_DAMPING = 1 / math.sqrt(2)
#: the solved bands must have equal magnitude at each crossover to this relative tolerance
CROSSOVER_RTOL = 1e-6
#: a closed-loop decay per step (rate times sample time) below this is within the rounding of the
#: discrete closed loop's eigenvalues around z = 1 (a few hundred units of the last place)
POLE_ROUNDING = 1e-13


def _bands_by_order(structure):
    """Sensor names by derivative order (one sensor per order), low-pass first."""
    orders = [s.order for s in structure.sensors]
    if len(set(orders)) != len(orders):
        raise SpecError(f"crossover: {structure.name} has two sensors of the same derivative order; a crossover "
                        "design needs one band per order (use optimal gains or [gains])")
    return [s.name for s in sorted(structure.sensors, key=lambda s: s.order)]


def _kind(structure):
    """``('cf2-1' | 'cf2-2' | 'chain', gain names in solve order)`` or a SpecError."""
    pattern, gains = structure.pattern, structure.gains
    n_meas, n_states = len(structure.H), len(structure.Fc)
    if n_meas == 1 and all(isinstance(row[0], str) for row in pattern) and len(gains) == n_states:
        if n_states == 1:
            return "cf2-1", gains
        if n_states == 2 and len(structure.sensors) == 2:
            return "cf2-2", [pattern[0][0], pattern[1][0]]
    # the sparse chain pattern: only the last row free, entry j of it drives band j
    last = pattern[-1]
    if (all(not isinstance(e, str) and e == 0 for row in pattern[:-1] for e in row)
            and all(isinstance(e, str) for e in last) and len(set(last)) == len(last)
            and np.allclose(structure.H, np.eye(n_states)) and len(structure.sensors) == n_states + 1):
        return "chain", list(last)  # last[j] gains the sensor of order j
    raise SpecError(f"crossover: not available for {structure.name} (its {len(gains)} gains are not fixed by "
                    "crossover frequencies alone); crossover designs take cf2, cf3 and cfn with sparse gains")


def continuous_crossover_gains(structure, hz, damping=None) -> dict:
    """The continuous closed forms (module docstring) for the given crossovers.

    cf2 order 1: ``k = w``; cf2 order 2: ``k1 = 2 zeta w_n``, ``k2 = w_n^2`` with
    ``w_n = w sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2)``; chains: ``k_i = w_(m-1) ... w_(m-i)``
    (``w = 2 pi hz``).

    Parameters
    ----------
    structure : cfdesign.designer.Structure
        cf2 (order 1 or 2), cf3 or a sparse cfn.
    hz : sequence of float
        Crossover frequencies, ascending, in Hz.
    damping : float, optional
        cf2 order 2 only: damping ratio (default ``1/sqrt(2)``).

    Returns
    -------
    dict
        ``{gain name: value}`` (1/s, 1/s^2, ...).

    Raises
    ------
    SpecError
        A damping for a structure other than cf2 order 2, or a count of frequencies other than
        the number of bands minus one.
    """
    kind, names = _kind(structure)
    w = [2 * math.pi * f for f in hz]
    _count(structure, hz)
    if kind != "cf2-2" and damping is not None:
        raise SpecError(f"crossover.damping: applies to cf2 order 2 only ({structure.name} has no free shape)")
    if kind == "cf2-1":
        return {names[0]: w[0]}
    if kind == "cf2-2":
        zeta = DEFAULT_DAMPING if damping is None else damping
        wn = _natural_frequency(w[0], zeta)
        return {names[0]: 2 * zeta * wn, names[1]: wn**2}
    # chain: k_i = w_{m-1} ... w_{m-i}, name of k_i = last[m - i] (m = number of states)
    m = len(names)
    out, prod = {}, 1.0
    for i in range(1, m + 1):
        prod *= w[m - i]
        out[names[m - i]] = prod
    return out


def _natural_frequency(wc, zeta):
    """``w_n`` of the cf2 order 2 poles of damping ``zeta`` crossing over at ``wc`` (rad/s):
    ``wc / sqrt(sqrt(1 + 4 zeta^4) + 2 zeta^2)``, equal to ``wc sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2)``
    without its cancellation (a damping of 1000 lost every digit, 1e6 gave ``w_n = 0``)."""
    return wc / math.sqrt(math.hypot(1.0, 2 * zeta**2) + 2 * zeta**2)


def _poles(zeta, wn):
    """Roots of ``s^2 + 2 zeta wn s + wn^2`` to full relative accuracy: for ``zeta > 1`` the slow
    root is ``wn^2`` over the fast one, not their difference (``numpy.roots`` gave the slow root of
    a damping of 1e6 with an absolute error of the fast one's rounding)."""
    if zeta >= 1:
        fast = -wn * (zeta + math.sqrt((zeta - 1) * (zeta + 1)))
        return np.array([fast, wn**2 / fast], dtype=complex)
    im = wn * math.sqrt((1 - zeta) * (1 + zeta))
    return np.array([complex(-zeta * wn, im), complex(-zeta * wn, -im)])


def _count(structure, hz):
    bands = _bands_by_order(structure)
    if len(hz) != len(bands) - 1:
        raise SpecError(f"crossover.hz: {structure.name} has {len(bands)} bands ({', '.join(bands)}), so "
                        f"{len(bands) - 1} crossover frequenc{'y' if len(bands) == 2 else 'ies'}; got {len(hz)}")
    return bands


def crossover_check(structure, model, K, form, output, dt, hz) -> list:
    """The magnitude ratio of adjacent bands at each requested crossover.

    Parameters
    ----------
    structure : cfdesign.designer.Structure
        The structure whose crossover constraints are checked.
    model : dict
        ``F, B, H`` (discrete at ``dt``).
    K : array_like, shape (n, m)
        The gain, in ``form``.
    form : {'continuous', 'predictor', 'filter'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).
    output : {'prior', 'posterior'}
        The estimate meant: ``prior`` (the one-step prediction) or ``posterior`` (after the step's
        readings).  Discrete tables only.
    dt : float or None
        Sample time (s) of a discrete design.
    hz : sequence of float
        Crossover frequencies (Hz).

    Returns
    -------
    list of (str, str, float, float)
        ``(band_a, band_b, hz, |T_a| / |T_b|)``; the ratio is 1 where the crossover is met.
    """
    bands = _bands_by_order(structure)
    real = linear.realisation(model["F"], model["B"], model["H"], K, form, output)
    omega = 2 * np.pi * np.asarray(hz, dtype=float)
    resp = linear.band_responses(real, column_order(structure.sensors), "z" if dt else "s", dt, omega)
    return [(bands[i], bands[i + 1], float(hz[i]), float(abs(resp[bands[i]][i]) / abs(resp[bands[i + 1]][i])))
            for i in range(len(hz))]


def crossover_gains(structure, model, dt, form, output, hz, damping=None) -> dict:
    """Gains whose adjacent bands have equal magnitude at the given frequencies.

    Continuous structures take the closed forms of :func:`continuous_crossover_gains`;
    discrete ones are solved numerically on the ZOH bands of the table's output, starting from
    the closed forms (Ackermann pole placement for the damping of cf2 order 2), and checked
    with :func:`crossover_check`.

    Parameters
    ----------
    structure : cfdesign.designer.Structure
        cf2 (order 1 or 2), cf3 or a sparse cfn, continuous or discrete.
    model : dict
        ``F, B, H`` (discrete at ``dt``).
    dt : float or None
        Sample time (s) of a discrete design.
    form : {'continuous', 'predictor', 'filter'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).
    output : {'prior', 'posterior'}
        The estimate whose bands are meant (discrete tables).
    hz : sequence of float
        Crossover frequencies, ascending, in Hz.
    damping : float, optional
        cf2 order 2: damping ratio of the closed-loop poles (default ``1/sqrt(2)``).

    Returns
    -------
    dict
        ``{gain name: value}``.

    Raises
    ------
    SpecError
        The structure does not take a crossover design, the count of frequencies is not the
        number of bands minus one, a frequency is at or above Nyquist, no stabilising gain
        meets them (the message names the crossover), or the gains put a closed-loop pole within
        double rounding of ``z = 1`` (the message names the pole and its time constant).
    """
    hz = [float(f) for f in hz]
    _count(structure, hz)
    if dt and hz[-1] >= 0.5 / dt:
        raise SpecError(f"crossover.hz: {hz[-1]:g} Hz is not below the Nyquist frequency {0.5 / dt:g} Hz")
    start = continuous_crossover_gains(structure, hz, damping)
    if not dt:
        gains = start
    else:
        kind, names = _kind(structure)
        if kind == "cf2-2":
            gains = _discrete_damped(structure, model, dt, form, output, hz, damping, names)
        else:
            gains = _discrete_square(structure, model, dt, form, output, hz, names, start)
    K = _gain_matrix(structure, gains)
    if not linear.is_stable(np.linalg.eigvals(linear.closed_loop(model["F"], model["H"], K, form)),
                            "z" if dt else "s"):
        slow = _slowest_pole(structure, start)
        if dt and slow * dt < POLE_ROUNDING:
            raise SpecError(f"crossover: at {_hz(hz)}{_damping_text(damping, structure)} the slowest closed-loop pole "
                            f"of {structure.name} is {slow:.3g} rad/s (a time constant of {1 / slow:.3g} s), "
                            f"{slow * dt:.2g} of a step at {1 / dt:g} Hz: within double rounding of z = 1, so no "
                            "discrete table holds it; choose a higher crossover, a smaller damping or a lower "
                            "sample rate")
        raise SpecError(f"crossover: the gains that put the crossovers at {_hz(hz)} do not stabilise "
                        f"{structure.name}")
    for a, b, f, ratio in crossover_check(structure, model, K, form, output, dt, hz):
        if not abs(ratio - 1) <= CROSSOVER_RTOL:
            raise SpecError(f"crossover.hz: no gains of {structure.name} put the {a}/{b} crossover at {f:g} Hz "
                            f"(closest: magnitude ratio {ratio:.4g}); choose frequencies further apart or "
                            "further below Nyquist")
    return gains


def _slowest_pole(structure, gains) -> float:
    """The smallest decay rate (rad/s) of the continuous closed loop of ``gains`` (0 when not
    stable): the discrete table's pole ``e^{-slow T}`` rounds to 1 when ``slow T`` is below
    :data:`POLE_ROUNDING`."""
    poles = np.linalg.eigvals(linear.closed_loop(structure.Fc, structure.H, _gain_matrix(structure, gains),
                                                 "continuous"))
    return float(max(np.min(-poles.real), 0.0))


def _damping_text(damping, structure):
    return "" if damping is None else f" with damping {damping:g}"


def _hz(hz):
    return ", ".join(f"{f:g} Hz" for f in hz)


def _gain_matrix(structure, gains):
    return np.array([[gains[e] if isinstance(e, str) else float(e) for e in row] for row in structure.pattern])


def _log_ratios(structure, model, dt, form, output, hz, gains):
    K = _gain_matrix(structure, gains)
    return np.array([math.log(r) for *_, r in crossover_check(structure, model, K, form, output, dt, hz)])


def _discrete_square(structure, model, dt, form, output, hz, names, start):
    """As many gains as crossovers: Newton (least squares) on log gains from the continuous start.

    The magnitude conditions have more than one root: a cf2 of order 1 whose posterior estimate
    crosses over at ``w`` has ``L = |z-1| / (1 + |z-1|)`` (stable) and ``|z-1| / (|z-1| - 1)``
    (unstable for ``|z-1| > 1``, a crossover above a sixth of the sample rate).  When the
    continuous start leads to a root that is not met or not stable, other starts (the start
    scaled, then a fixed set of spreads in log gain) are tried and the first stabilising root
    taken; without one the first root is returned for the caller to name."""
    from scipy.optimize import least_squares

    def residual(logk):
        gains = dict(zip(names, np.exp(logk), strict=True))
        with np.errstate(all="ignore"):
            try:
                r = _log_ratios(structure, model, dt, form, output, hz, gains)
            except (ValueError, np.linalg.LinAlgError):
                return np.full(len(hz), 1e3)
        return r if np.all(np.isfinite(r)) else np.full(len(hz), 1e3)

    def solve(x0):
        sol = least_squares(residual, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
        return dict(zip(names, (float(v) for v in np.exp(sol.x)), strict=True)), float(np.max(np.abs(sol.fun)))

    def good(gains, miss):
        if not miss <= CROSSOVER_RTOL / 10:
            return False
        poles = np.linalg.eigvals(linear.closed_loop(model["F"], model["H"], _gain_matrix(structure, gains), form))
        return bool(linear.is_stable(poles, "z"))

    x0 = np.log([start[n] * dt for n in names])  # a continuous gain k is about k T per step
    first = solve(x0)
    if good(*first):
        return first[0]
    rng = np.random.default_rng(0)  # fixed: the same design file gives the same gains
    shifts = [np.full(len(x0), math.log(c)) for c in (0.5, 0.25, 2.0, 0.1, 4.0, 0.03)]
    shifts += list(rng.normal(0.0, 1.5, size=(24, len(x0))))
    for shift in shifts:
        found = solve(x0 + shift)
        if good(*found):
            return found[0]
    return first[0]


def _discrete_damped(structure, model, dt, form, output, hz, damping, names):
    """cf2 order 2: poles ``e^{sT}`` of ``s^2 + 2 zeta w_n s + w_n^2``; ``w_n`` by Brent's method."""
    from scipy.optimize import brentq

    zeta = DEFAULT_DAMPING if damping is None else damping
    F, H = model["F"], model["H"]

    def gains_for(wn):
        Kp = _ackermann(F, H, np.expm1(_poles(zeta, wn) * dt))
        K = linear.gain_in_form(F, Kp, form)
        return dict(zip(names, (float(v) for v in K[:, 0]), strict=True))

    def f(logwn):
        return _log_ratios(structure, model, dt, form, output, hz, gains_for(math.exp(logwn)))[0]

    wc = 2 * math.pi * hz[0]
    # three decades around both wc and the continuous solution (far below wc for a large damping:
    # wc / (2 zeta)), at the same density of 20 points a decade whatever the span
    wn_c = math.log(_natural_frequency(wc, zeta))
    lo = min(wn_c, math.log(wc)) - math.log(1e3)
    hi = min(max(wn_c, math.log(wc)) + math.log(1e3), math.log(10 * math.pi / dt))
    grid = np.linspace(lo, hi, max(121, int(20 * (hi - lo) / math.log(10)) + 1))
    with np.errstate(all="ignore"):
        vals = np.array([f(x) for x in grid])
    idx = np.flatnonzero(np.isfinite(vals[:-1]) & np.isfinite(vals[1:]) & (np.sign(vals[:-1]) != np.sign(vals[1:])))
    if not idx.size:
        raise SpecError(f"crossover.hz: no damping-{zeta:g} gains of {structure.name} put the crossover at "
                        f"{hz[0]:g} Hz at this sample rate")
    # the root nearest the continuous solution
    i = idx[np.argmin(np.abs(grid[idx] - wn_c))]
    return gains_for(math.exp(brentq(f, grid[i], grid[i + 1], xtol=1e-14)))


def _ackermann(F, H, shifts):
    """Predictor gain ``Kp`` (n x 1) placing the poles of ``F - Kp H`` at ``1 + shifts``.

    Ackermann's formula ``Kp = p(F) O^-1 e_n`` with ``p(F) = prod_i (F - I - shift_i I)``: the
    factors are formed from ``F - I`` and ``shift_i = expm1(s_i T)``, never from the expanded
    polynomial, whose powers of ``F`` (close to ``I`` at high sample rates) cancel to rounding
    error (a crossover at 1e-7 of the sample rate has ``p(F)`` of size 1e-15 against terms of size 1).
    """
    n = len(F)
    obs = np.vstack([H @ np.linalg.matrix_power(F, i) for i in range(n)])
    D = np.asarray(F, dtype=float) - np.eye(n)
    pF = np.eye(n, dtype=complex)
    for shift in shifts:
        pF = pF @ (D - shift * np.eye(n))
    e = np.zeros((n, 1))
    e[-1, 0] = 1.0
    return np.real(pF) @ np.linalg.solve(obs, e)
