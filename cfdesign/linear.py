"""The numeric meaning of a gain table: gain forms, closed loop, bands, one angle wrap.

numpy only on the runtime's path (the frequency responses of :func:`band_responses`, which
the runtime never calls, use scipy's balancing and Schur form): this is the module the runtime,
the designer, ``verify``, the analysis and the C generator share, so that a gain form means
one thing everywhere.  The symbolic engine (:mod:`cfdesign.symbolic.observer`) derives the
same objects exactly; the tests hold the two against each other.  Derivations:
``docs/derivations.md``, sections "One observer" and "Gain forms".

Gain forms
----------
A discrete table stores one gain ``K[k]`` per phase in a *named* form:

* ``predictor`` (Carreira et al. eq. (25)):
  ``x[k+1] = F x[k] + B u[k] + K (y[k] - H x[k])``;
* ``filter`` (the measurement update whose gain Carreira et al. eq. (28) write):
  ``x+[k] = x[k] + K (y[k] - H x[k])``, ``x[k+1] = F x+[k] + B u[k]``.

Both are the same recursion written with two gains (:func:`gain_pair`): the *predictor gain*
``Kp`` that carries the innovation into the next prediction and the *update gain* ``L`` that
gives the estimate after this step's readings,

.. math::

    e[k] = y[k] - H x[k],\\qquad x^+[k] = x[k] + L e[k],\\qquad
    x[k+1] = F x[k] + B u[k] + K_p e[k],\\qquad K_p = F L,

with ``L = K`` for the filter form and ``L = F^{-1} K`` for the predictor form.  Either
table can therefore output the one-step *prior* estimate ``x[k]`` or the *posterior*
``x+[k]``; :func:`realisation` writes the chosen output as a state-space system.  Continuous
tables (``x' = F x + B u + K (y - H x)``) have only the prior form.

Bands
-----
With the realisation ``x[k+1] = A x + G w``, ``est = C x + D w`` (``w`` the readings, inputs
first) and a sensor relation ``rel_j`` (reading = ``rel_j`` x quantity), the band of sensor
``j`` is ``T_j = (C adj(vI - A) G_j + D_j det(vI - A)) / det(vI - A) * rel_j`` and the bands
sum to one for any stabilising gain (see the derivation).  :func:`band_polynomials` computes
them in floating point in ``O(n^3)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = [
    "GAIN_FORMS",
    "OUTPUTS",
    "wrap",
    "wrap_scalar",
    "default_output",
    "gain_pair",
    "gain_in_form",
    "has_posterior",
    "closed_loop",
    "loop_radius",
    "STARTUP_DECAY",
    "startup_steps",
    "Realisation",
    "realisation",
    "posterior_covariance",
    "zoh_chain",
    "chain_relations",
    "characteristic_polynomial",
    "output_adjugate",
    "adjugate_coefficients",
    "wrap_inplace",
    "band_polynomials",
    "response",
    "band_responses",
    "complementarity_error",
    "identity_residual",
    "identity_polynomial",
    "is_stable",
    "spectral_margin",
]

#: the named gain forms of a table
GAIN_FORMS = ("predictor", "filter", "continuous")
#: the factor by which the slowest mode of a filter's error has shrunk at the end of its start-up
#: (:func:`startup_steps`): to 1 %
STARTUP_DECAY = 100.0
#: what a discrete filter can output: the prediction before this step's readings, or the
#: estimate after them
OUTPUTS = ("prior", "posterior")

_TWO_PI = 2.0 * math.pi
#: entries per piece of the elementwise passes over long arrays (128 KB of doubles): the
#: temporaries stay in cache, and a piece already within range is skipped
CHUNK = 1 << 14


# ---------------------------------------------------------------------------- angle wrap
def wrap(angle):
    """Wrap angles (rad) to ``(-pi, pi]``: ``a - 2 pi ceil((a - pi) / (2 pi))``.

    This is the one wrap of cfdesign: the runtime, the simulations and the generated C
    (``templates/filter.c.in``, the same operations in the same order) use it.  An angle
    already in ``(-pi, pi]`` comes back unchanged, bit for bit; an angle outside whose
    rounded result lands an ulp outside is moved by one more turn.  NaN (a missing angle) and
    inf give NaN, for a scalar as for an array.

    Parameters
    ----------
    angle : float or array_like
        Angles in radians.

    Returns
    -------
    ndarray
        Wrapped angles, same shape (a 0-d array for a scalar input).

    Examples
    --------
    >>> float(wrap(3 * math.pi / 2)), float(wrap(-math.pi))
    (-1.5707963267948966, 3.141592653589793)
    """
    a = np.array(angle, dtype=float)
    return wrap_inplace(a) if a.ndim else np.asarray(wrap_scalar(float(a)))


def wrap_scalar(a: float) -> float:
    """:func:`wrap` of one float with ``math`` (same operations, same result, no numpy).

    Parameters
    ----------
    a : float
        Angle (rad).

    Returns
    -------
    float
        The angle in ``(-pi, pi]`` (rad); unchanged, bit for bit, when already inside.
    """
    if -math.pi < a <= math.pi:
        return a
    if not math.isfinite(a):  # NaN (a missing angle) or inf: NaN, as the array path gives
        return math.nan
    r = a - _TWO_PI * math.ceil((a - math.pi) / _TWO_PI)
    return r - _TWO_PI if r > math.pi else (r + _TWO_PI if r <= -math.pi else r)


def wrap_inplace(a: np.ndarray) -> np.ndarray:
    """:func:`wrap` of a float array, in place: only the entries outside ``(-pi, pi]`` change.

    Parameters
    ----------
    a : ndarray of float
        Angles (rad), modified in place.

    Returns
    -------
    ndarray
        ``a``.
    """
    if not a.size:
        return a
    rows = a.reshape(1) if a.ndim == 0 else a
    step = max(1, CHUNK * len(rows) // max(1, rows.size))
    with np.errstate(invalid="ignore"):
        for start in range(0, len(rows), step):  # piece by piece: the temporaries stay in cache
            b = rows[start:start + step]
            lo, hi = b.min(), b.max()
            if lo > -math.pi and hi <= math.pi:  # all inside: nothing to do (NaN fails these comparisons)
                continue
            if not (math.isfinite(lo) and math.isfinite(hi)):  # inf has no turn count: NaN, as wrap_scalar gives
                b[np.isinf(b)] = np.nan
            t = np.subtract(b, math.pi)  # a - 2 pi ceil((a - pi) / (2 pi)); an entry inside gets 0 turns
            np.divide(t, _TWO_PI, out=t)
            np.ceil(t, out=t)
            np.multiply(t, _TWO_PI, out=t)
            np.subtract(b, t, out=b)
            # NaN-ignoring max and min (np.nanmax without its Python-level checks)
            if np.fmax.reduce(b, axis=None, initial=-math.inf) > math.pi or \
                    np.fmin.reduce(b, axis=None, initial=math.inf) <= -math.pi:
                b[b > math.pi] -= _TWO_PI  # a result rounded an ulp outside: one more turn
                b[b <= -math.pi] += _TWO_PI
    return a


# ---------------------------------------------------------------------------- gain forms
def default_output(form: str) -> str:
    """The estimate a gain form outputs when a table does not say.

    Parameters
    ----------
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).

    Returns
    -------
    {'prior', 'posterior'}
        ``prior`` for predictor (and continuous) tables, ``posterior`` for filter tables.

    Raises
    ------
    ValueError
        An unknown gain form.
    """
    _check_form(form)
    return "posterior" if form == "filter" else "prior"


def _check_form(form):
    if form not in GAIN_FORMS:
        raise ValueError(f"gain form must be one of {', '.join(GAIN_FORMS)}, got {form!r}")


def gain_pair(F, K, form: str):
    """``(Kp, L)``: the predictor gain and the update gain of a gain ``K`` in ``form``.

    ``filter``: ``L = K``, ``Kp = F K``.  ``predictor``: ``Kp = K``, ``L = F^-1 K`` (None when
    ``F`` is singular: such a table has no posterior output).  ``continuous``: ``Kp = K``,
    ``L = None``.

    Parameters
    ----------
    F : ndarray (n, n)
        State transition matrix.
    K : ndarray (n, m)
        Gain in ``form``.
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).

    Returns
    -------
    tuple of ndarray
        ``(Kp, L)``, each (n, m); ``L`` may be None.
    """
    _check_form(form)
    F, K = np.asarray(F, dtype=float), np.asarray(K, dtype=float)
    if form == "filter":
        return F @ K, K
    if form == "continuous" or K.shape[1] == 0:
        return K, (None if form == "continuous" else K)
    if not has_posterior(F, form):
        return K, None
    return K, np.linalg.solve(F, K)


def has_posterior(F, form: str) -> bool:
    """Whether gains in ``form`` give the estimate after a step's readings (an update gain).

    The filter form always does; the predictor form when ``F`` is invertible (condition
    number at most 1e12: ``L = F^-1 K``); continuous tables never.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State transition matrix.
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).

    Returns
    -------
    bool
        True when an update gain ``L`` exists for ``form``.

    Examples
    --------
    >>> has_posterior([[1.0, 0.2], [0.0, 0.0]], "predictor"), has_posterior([[1.0]], "filter")
    (False, True)
    """
    _check_form(form)
    if form != "predictor":
        return form == "filter"
    F = np.ascontiguousarray(F, dtype=float)
    return _well_conditioned(F.shape, F.tobytes())


@lru_cache(maxsize=64)
def _well_conditioned(shape, data: bytes) -> bool:
    """``cond(F) <= 1e12`` for the matrix of ``shape`` whose doubles are ``data``.

    Memoised on the bytes: every phase of a multirate table asks it of the same ``F`` (through
    :func:`gain_pair`), and the SVD behind it cost more than the rest of a phase's work.
    """
    return bool(np.linalg.cond(np.frombuffer(data, dtype=float).reshape(shape)) <= 1e12)


def gain_in_form(F, Kp, form: str) -> np.ndarray:
    """The gain in ``form`` whose predictor gain is ``Kp``: the inverse of :func:`gain_pair`.

    ``predictor`` and ``continuous``: ``Kp`` itself; ``filter``: ``F^-1 Kp``.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State transition matrix.
    Kp : array_like, shape (n, m)
        Predictor gain (``x[k+1] = F x + B u + Kp (y - H x)``).
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).

    Returns
    -------
    ndarray, shape (n, m)
        The gain in ``form``.

    Raises
    ------
    ValueError
        The filter form of a singular ``F`` (no filter gain gives that predictor gain).

    Examples
    --------
    >>> gain_in_form([[2.0]], [[1.0]], "filter").tolist(), gain_in_form([[2.0]], [[1.0]], "predictor").tolist()
    ([[0.5]], [[1.0]])
    """
    _check_form(form)
    F, Kp = np.asarray(F, dtype=float), np.asarray(Kp, dtype=float)
    if form != "filter":
        return Kp
    try:
        return np.linalg.solve(F, Kp)
    except np.linalg.LinAlgError:
        raise ValueError("a singular F has no filter-form gain for this predictor gain") from None


def closed_loop(F, H, K, form: str) -> np.ndarray:
    """State matrix of the error dynamics: ``F - Kp H`` (= ``F (I - K H)`` in filter form).

    Parameters
    ----------
    F : array_like, shape (n, n)
        State matrix (transition matrix when discrete).
    H : array_like, shape (m, n)
        Measurement matrix.
    K : array_like, shape (n, m)
        Gain in ``form``.
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).

    Returns
    -------
    ndarray, shape (n, n)
        The error dynamics' state matrix.

    Examples
    --------
    >>> from cfdesign.linear import closed_loop
    >>> closed_loop([[1.0]], [[1.0]], [[0.5]], "filter").tolist()
    [[0.5]]
    """
    Kp, _ = gain_pair(F, K, form)
    return np.asarray(F, dtype=float) - Kp @ np.asarray(H, dtype=float)


def loop_radius(F, H, gains, form: str) -> float:
    """Spectral radius of the error dynamics over one period of a discrete table's gains.

    One gain: the closed loop's (:func:`closed_loop`); several (a multirate table): its
    monodromy matrix, the product of the phases' closed loops.  Below 1 the filter forgets
    any error; above 1 its estimates diverge whatever the readings.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Transition matrix.
    H : array_like, shape (m, n)
        Measurement matrix.
    gains : sequence of array_like, each (n, m)
        The gain of every phase, in ``form``.
    form : {'predictor', 'filter'}
        The gain form.

    Returns
    -------
    float
        The spectral radius; ``inf`` when the product overflows.

    Examples
    --------
    >>> from cfdesign.linear import loop_radius
    >>> loop_radius([[1.0]], [[1.0]], [[[0.5]], [[0.0]]], "filter")
    0.5
    """
    Phi = np.eye(len(np.asarray(F)))
    with np.errstate(over="ignore", invalid="ignore"):
        for K in gains:
            Phi = closed_loop(F, H, K, form) @ Phi
    return float(np.abs(np.linalg.eigvals(Phi)).max()) if np.all(np.isfinite(Phi)) else math.inf


def startup_steps(F, H, gains, form: str, decay: float = STARTUP_DECAY) -> float:
    """Base steps a discrete table's start-up takes: its slowest error mode shrinking ``decay`` times.

    A filter started from a wrong state (the first reading's noise, a velocity or a bias it has
    yet to learn) forgets that error at the pace of its closed loop.  Over one period of ``p``
    phases the error's slowest mode shrinks by the spectral radius ``r`` of the monodromy
    matrix (:func:`loop_radius`; the closed loop itself when ``p = 1``), so per base step by
    ``rho = r ** (1 / p)``, and it has shrunk ``decay`` times after

    .. math::

        n = \\frac{\\ln(\\mathrm{decay})}{-\\ln \\rho} = \\frac{p \\ln(\\mathrm{decay})}{-\\ln r}

    base steps.  Within a period the decay is not uniform (a multirate table's error drops at
    its slow readings), and a repeated pole adds a factor growing like the step count, so the
    figure is the slowest mode's time scale, not a bound on every state's error.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Transition matrix.
    H : array_like, shape (m, n)
        Measurement matrix.
    gains : sequence of array_like, each (n, m)
        The gain of every phase, in ``form``.
    form : {'predictor', 'filter'}
        The gain form.
    decay : float
        How many times the slowest mode shrinks (default :data:`STARTUP_DECAY`, to 1 %).

    Returns
    -------
    float
        Base steps (not rounded); 0 when the error dies in finite time (radius 0), ``inf``
        when it does not die (radius 1 or more).

    Raises
    ------
    ValueError
        ``decay`` is not a number greater than 1, or ``form`` is not a discrete gain form.

    Examples
    --------
    >>> from cfdesign.linear import startup_steps
    >>> round(startup_steps([[1.0]], [[1.0]], [[[0.1]]], "filter"), 2)  # 0.9 a step: ln 100 / -ln 0.9
    43.71
    """
    if not (isinstance(decay, (int, float)) and not isinstance(decay, bool) and decay > 1):
        raise ValueError(f"decay must be a number greater than 1, got {decay!r}")
    if form not in ("predictor", "filter"):
        raise ValueError(f"the start-up is counted in the steps of a discrete gain form (predictor, filter), "
                         f"not {form!r}")
    radius = loop_radius(F, H, gains, form)
    if radius >= 1:
        return math.inf
    if radius == 0:
        return 0.0
    return len(gains) * math.log(decay) / -math.log(radius)


@dataclass(frozen=True)
class Realisation:
    """One phase of a filter as a linear system of its readings ``w = [u; y]``.

    ``x[k+1] = A x[k] + G w[k]`` and the output states ``xo[k] = C x[k] + D w[k]`` (the first
    row is the estimate of the common quantity).  Continuous: ``x' = A x + G w``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
        State matrix.
    G : ndarray, shape (n, p + m)
        Reading matrix: inputs ``u`` (p columns), then measurements ``y`` (m).
    C : ndarray, shape (n, n)
        Output matrix of the output states.
    D : ndarray, shape (n, p + m)
        Feedthrough of the readings to the output states.
    output : {'prior', 'posterior'}
        The estimate meant: ``prior`` (the one-step prediction) or ``posterior`` (after the step's
        readings).
    delta : ndarray, shape (n, n), optional
        ``I - A`` computed as ``(I - F) + Kp H`` (discrete), without the cancellation of
        ``1 - A_ii`` when the gains are tiny (fast sampling): what the frequency responses near
        ``z = 1`` need.
    """

    A: np.ndarray
    G: np.ndarray
    C: np.ndarray
    D: np.ndarray
    output: str
    #: ``I - A`` computed as ``(I - F) + Kp H`` (discrete), without the cancellation of ``1 - A_ii``
    #: when the gains are tiny (fast sampling): what the frequency responses near ``z = 1`` need
    delta: np.ndarray | None = None


def realisation(F, B, H, K, form: str, output: str | None = None) -> Realisation:
    """The filter of one phase as ``(A, G, C, D)`` (see :class:`Realisation`).

    ``A = F - Kp H``, ``G = [B, Kp]``; prior output ``C = I``, ``D = 0``; posterior output
    ``C = I - L H``, ``D = [0, L]`` (module docstring).

    Parameters
    ----------
    F, B, H : array_like
        The model, shapes (n, n), (n, p), (m, n).
    K : array_like, shape (n, m)
        Gain in ``form``.
    form : {'predictor', 'filter', 'continuous'}
        The gain form: ``predictor`` (``x[k+1] = F x + B u + K (y - H x)``), ``filter``
        (``x+ = x + K (y - H x)``, then ``x[k+1] = F x+ + B u``) or ``continuous``
        (``x' = F x + B u + K (y - H x)``).
    output : {'prior', 'posterior'}, optional
        Default :func:`default_output` of the form.

    Returns
    -------
    Realisation
        The matrices ``A, G, C, D`` of the phase.

    Raises
    ------
    ValueError
        ``output`` is not ``prior``/``posterior``, or the posterior is asked of a continuous
        table or of a predictor table whose ``F`` is singular.
    """
    output = default_output(form) if output is None else output
    if not isinstance(output, str) or output not in OUTPUTS:  # (an array: 'truth value ... ambiguous')
        raise ValueError(f"output must be one of {', '.join(OUTPUTS)}, got {output!r}")
    F, B, H = (np.asarray(M, dtype=float) for M in (F, B, H))
    Kp, L = gain_pair(F, K, form)
    n, p = F.shape[0], B.shape[1]
    A = F - Kp @ H
    G = np.hstack([B, Kp])
    delta = (np.eye(n) - F) + Kp @ H
    if output == "prior":
        return Realisation(A, G, np.eye(n), np.zeros_like(G), output, delta)
    if L is None:
        raise ValueError("a posterior estimate needs a discrete table with an invertible F"
                         if form != "continuous" else "a continuous table has no posterior estimate")
    return Realisation(A, G, np.eye(n) - L @ H, np.hstack([np.zeros((n, p)), L]), output, delta)


def posterior_covariance(P, H, L, R) -> np.ndarray:
    """Covariance after the update ``x+ = x + L (y - H x)`` for any gain (Joseph form).

    ``P+ = (I - L H) P (I - L H)' + L R L'``; equal to ``(I - L H) P`` for the Kalman gain.

    Parameters
    ----------
    P : array_like, shape (n, n)
        Prior covariance.
    H : array_like, shape (m, n)
        Measurement matrix.
    L : array_like, shape (n, m)
        Update gain.
    R : array_like, shape (m, m)
        Measurement-noise covariance (per sample).

    Returns
    -------
    ndarray, shape (n, n)
        The posterior covariance, symmetric.
    """
    P, H, L, R = (np.asarray(M, dtype=float) for M in (P, H, L, R))
    IKH = np.eye(len(P)) - L @ H
    return IKH @ P @ IKH.T + L @ R @ L.T


def is_stable(eigenvalues, domain: str) -> bool:
    """Strict stability of a set of eigenvalues.

    Parameters
    ----------
    eigenvalues : array_like
        Eigenvalues (poles) to test.
    domain : {'s', 'z'}
        ``s`` for a continuous filter, ``z`` for a discrete one.

    Returns
    -------
    bool
        Every eigenvalue in the open left half-plane (``s``) or the open unit disc (``z``).
    """
    return spectral_margin(eigenvalues, domain) < 0


def spectral_margin(eigenvalues, domain: str) -> float:
    """How far the eigenvalues are from the stability boundary.

    Parameters
    ----------
    eigenvalues : array_like
        Eigenvalues (poles) to measure.
    domain : {'s', 'z'}
        ``s`` for a continuous filter, ``z`` for a discrete one.

    Returns
    -------
    float
        ``max Re(lambda)`` (``s``) or ``max |lambda| - 1`` (``z``): negative means stable;
        ``-inf`` for no eigenvalue.
    """
    eig = np.asarray(eigenvalues)
    if not eig.size:
        return -math.inf
    return float(eig.real.max()) if domain == "s" else float(np.abs(eig).max() - 1.0)


# ---------------------------------------------------------------------------- kinematic chains
def zoh_chain(m: int, dt: float):
    """Numeric ZOH model of an ``m``-state kinematic chain driven by its ``m``-th derivative.

    ``F[i, j] = dt^(j-i) / (j-i)!`` (``j >= i``), ``B[i] = dt^(m-i) / (m-i)!``: the exact
    discretisation of ``m`` integrators in a row with the input held over each sample (no
    factorial overflow for long chains).

    Parameters
    ----------
    m : int
        Number of states.
    dt : float
        Sample time (s).

    Returns
    -------
    F : ndarray, shape (m, m)
        State transition matrix, ``F[i, j] = dt**(j-i) / (j-i)!``.
    B : ndarray, shape (m,)
        Input vector, ``B[i] = dt**(m-i) / (m-i)!``.

    Examples
    --------
    >>> from cfdesign.linear import zoh_chain
    >>> F, B = zoh_chain(2, 0.1)
    >>> F.tolist(), B.tolist()
    ([[1.0, 0.1], [0.0, 1.0]], [0.005000000000000001, 0.1])
    """
    c = [1.0]  # dt^k / k!, built up so that long chains neither overflow nor lose digits
    for k in range(1, m + 1):
        c.append(c[-1] * dt / k)
    F = np.array([[c[j - i] if j >= i else 0.0 for j in range(m)] for i in range(m)])
    B = np.array([c[m - i] for i in range(m)])
    return F.reshape(m, m), B


def chain_relations(orders, domain: str, dt: float | None = None) -> dict:
    """The relation ``reading = num/den x quantity`` of a sensor of each derivative order.

    Continuous: ``s**order``.  Discrete: the ZOH chain of the highest order ``M``; the relation
    of order ``j`` is ``G_j / G_0`` with ``G_i`` the transfer from the held ``M``-th derivative
    to the sampled ``i``-th (order 1 of a 1-chain: ``(z - 1)/dt``).  ``O(M^3)`` for each order
    asked (one row of the adjugate each), not for every order of the chain.

    Parameters
    ----------
    orders : iterable of int
        The sensors' derivative orders.
    domain : {'s', 'z'}
        ``s`` for a continuous filter, ``z`` for a discrete one.
    dt : float, optional
        Sample time (s), discrete only.

    Returns
    -------
    dict
        ``{order: (num, den)}``, polynomials highest power first, not reduced.
    """
    orders = set(orders)
    if domain == "s":
        return {d: (np.r_[1.0, np.zeros(d)], np.ones(1)) for d in orders}
    M = max(orders, default=0)
    if M == 0:
        return {0: (np.ones(1), np.ones(1))} if orders else {}
    Fd, Bd = zoh_chain(M, dt)
    den = characteristic_polynomial(Fd)
    rows = np.eye(M)
    # G_i's numerator for the orders asked only (each is O(M^3)): G_M's is den itself
    nums = {d: den if d == M else output_adjugate(Fd, rows[d], den) @ Bd for d in orders | {0}}
    return {d: (np.ones(1), np.ones(1)) if d == 0 else (nums[d], nums[0]) for d in orders}


# ---------------------------------------------------------------------------- bands
def characteristic_polynomial(A) -> np.ndarray:
    """Coefficients of ``det(vI - A)``, highest power first.

    La Budde's method: ``A`` itself or its transpose where either is upper Hessenberg (the closed
    loops of kinematic chains: a shift plus a gain column or row), else an orthogonal
    (Householder) reduction to upper Hessenberg form ``H``; then the recurrence of the
    characteristic polynomials of its leading blocks,
    ``p_(i+1) = (v - h_ii) p_i - sum_m h_(i-m,i) (h_(i,i-1) ... h_(i-m+1,i-m)) p_(i-m)``
    (R. Rehman, I. C. F. Ipsen, *La Budde's method for computing characteristic polynomials*,
    2011).  Unlike the product of ``v - lambda`` over the eigenvalues it keeps the coefficients
    of stiff matrices: a continuous CF3 with poles at -5.7e4 and -0.31 rad/s had its constant
    coefficient off by 8e-12 relative (the small eigenvalue carries the large one's absolute
    error), and the bands failed the identity check.  numpy only.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Square matrix.

    Returns
    -------
    ndarray, shape (n + 1,)
        Real coefficients (``[1.]`` for an empty matrix).
    """
    A = np.asarray(A, dtype=float)
    if not np.any(np.tril(A, -2)):  # already upper Hessenberg: the recurrence alone, no rounding added
        H = A
    elif not np.any(np.triu(A, 2)):  # lower Hessenberg (a chain's closed loop): its transpose is upper
        H = A.T
    else:
        H = _hessenberg(A)
    n = len(H)
    P = np.zeros((n + 1, n + 1))  # row k: p_k, lowest power first
    P[0, 0] = 1.0
    for i in range(n):
        P[i + 1, 1:] = P[i, :-1]
        P[i + 1] -= H[i, i] * P[i]
        if i:
            sub = np.cumprod(H[np.arange(i, 0, -1), np.arange(i - 1, -1, -1)])  # m = 1 .. i
            P[i + 1] -= (H[np.arange(i - 1, -1, -1), i] * sub) @ P[i - 1::-1]
    return P[n, ::-1].copy()


def _hessenberg(A):
    """Upper Hessenberg form of ``A`` by Householder reflections (orthogonally similar)."""
    H = np.array(A, dtype=float)
    n = len(H)
    for k in range(n - 2):
        x = H[k + 1:, k]
        alpha = np.linalg.norm(x)
        if alpha == 0.0:
            continue
        v = x.copy()
        v[0] += math.copysign(alpha, x[0])
        v /= np.linalg.norm(v)
        H[k + 1:, k:] -= 2.0 * np.outer(v, v @ H[k + 1:, k:])
        H[:, k + 1:] -= 2.0 * np.outer(H[:, k + 1:] @ v, v)
        H[k + 2:, k] = 0.0
    return H


def output_adjugate(A, c, den=None) -> np.ndarray:
    """Rows ``c adj(vI - A)`` by power of ``v``.

    The Faddeev-LeVerrier recursion applied to one output row, ``O(n^3)`` in all:
    ``W[0] = c``, ``W[k] = W[k-1] A + den[k] c`` and ``c adj(vI - A) = sum_k W[k] v^(n-1-k)``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix of the realisation.
    c : array_like, shape (n,)
        Output row.
    den : array_like, optional
        :func:`characteristic_polynomial` of ``A``, if already known.

    Returns
    -------
    ndarray, shape (n, n)
        Row ``k`` is the coefficient of ``v^(n-1-k)``.
    """
    A = np.asarray(A, dtype=float)
    c = np.asarray(c, dtype=float)
    den = characteristic_polynomial(A) if den is None else den
    n = len(A)
    W = np.empty((n, n))
    if n:
        W[0] = c
    for k in range(1, n):
        W[k] = W[k - 1] @ A + den[k] * c
    return W


def adjugate_coefficients(A, den=None) -> np.ndarray:
    """The coefficient matrices of ``adj(vI - A) = sum_k M[k] v^(n-1-k)``.

    Faddeev-LeVerrier: ``M[0] = I``, ``M[k] = A M[k-1] + den[k] I``.  ``O(n^4)``: for one
    output row use :func:`output_adjugate`.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Square matrix.
    den : array_like, optional
        :func:`characteristic_polynomial` of ``A``, if already known.

    Returns
    -------
    ndarray, shape (n, n, n)
        ``M[k]``, ``k = 0 .. n-1``.
    """
    A = np.asarray(A, dtype=float)
    den = characteristic_polynomial(A) if den is None else den
    n = len(A)
    M = np.empty((n, n, n))
    if n:
        M[0] = np.eye(n)
    for k in range(1, n):
        M[k] = A @ M[k - 1] + den[k] * np.eye(n)
    return M


def band_polynomials(real: Realisation, ports, relations: dict, row: int = 0):
    """Every band of one phase as polynomials (highest power first).

    Parameters
    ----------
    real : Realisation
        The phase (:func:`realisation`).
    ports : sequence
        Sensors with ``name`` and ``order``, in column order of ``G``/``D`` (inputs by
        index, then measurements by index), e.g. ``GainTable.sensors``.
    relations : dict
        ``{order: (num, den)}`` from :func:`chain_relations`.
    row : int
        Output row (state) whose bands are wanted; 0 is the estimate of the common quantity.

    Returns
    -------
    tuple
        ``({name: (num, den)}, den_closed_loop)``.
    """
    den = characteristic_polynomial(real.A)  # monic: nothing to trim
    W = output_adjugate(real.A, real.C[row], den)
    rel = {order: (_trimmed(relations[order][0]), _trimmed(relations[order][1])) for order in {s.order for s in ports}}
    out = {}
    for j, s in enumerate(ports):
        d = real.D[row, j]
        num = np.concatenate([[d], W @ real.G[:, j] + d * den[1:]])
        rel_num, rel_den = rel[s.order]
        out[s.name] = (np.convolve(_trimmed(num), rel_num), np.convolve(den, rel_den))
    return out, den


def _trimmed(p) -> np.ndarray:
    """Coefficients without leading zeros (``[0.]`` for the zero polynomial), as ``np.polymul``
    takes its factors: multiplying trimmed factors by ``np.convolve`` gives its product without
    the two ``poly1d`` objects it builds, which cost most of a phase's band polynomials."""
    p = np.atleast_1d(np.asarray(p, dtype=float))
    nz = np.flatnonzero(p)
    return p[nz[0]:] if nz.size else np.zeros(1)


def response(num, den, omega, dt: float | None = None) -> np.ndarray:
    """Frequency response of ``num/den``.

    Parameters
    ----------
    num, den : array_like
        Polynomial coefficients, highest power first.
    omega : array_like
        Angular frequencies (rad/s).
    dt : float, optional
        Sample time (s): evaluate at ``e^{j omega dt}``; else at ``j omega``.

    Returns
    -------
    ndarray of complex
        The response at each of ``omega``.
    """
    omega = np.asarray(omega, dtype=float)
    x = np.exp(1j * omega * dt) if dt else 1j * omega
    with np.errstate(all="ignore"):
        return np.polyval(num, x) / np.polyval(den, x)


def band_responses(real: Realisation, ports, domain: str, dt, omega, row: int = 0) -> dict:
    """Every band's frequency response from the state-space form (no polynomial expansion).

    ``T_j(v) = (C (vI - A)^-1 G_j + D_j) rel_j(v)`` at ``v = j omega`` or ``e^{j omega dt}``,
    with the chain relations evaluated the same way (``rel_d = G_d / G_0``, ``G_i`` the
    transfer from the held top derivative to state ``i`` of the ZOH chain).  Accurate where
    the expanded polynomials are not: poles clustered near ``z = 1`` at high sample rates.

    Parameters
    ----------
    real : Realisation
        The phase (:func:`realisation`).
    ports : sequence
        Sensors with ``name`` and ``order``, in column order of ``G``/``D``.
    domain : {'s', 'z'}
        ``s`` for a continuous filter, ``z`` for a discrete one.
    dt : float or None
        Sample time (s) of a discrete filter.
    omega : array_like
        Angular frequencies (rad/s).
    row : int
        Output row (state); 0 is the estimate of the common quantity.

    Returns
    -------
    dict
        ``{name: complex ndarray}`` over ``omega``.
    """
    omega = np.asarray(omega, dtype=float)
    if domain == "s":  # vI - A = shift I + base
        v = shift = 1j * omega
        base = -real.A
    else:  # zI - A = (z - 1) I + (I - A), both parts accurate near z = 1
        shift = np.expm1(1j * omega * dt)
        v = 1.0 + shift
        base = np.eye(len(real.A)) - real.A if real.delta is None else real.delta
    orders = sorted({s.order for s in ports})
    if domain == "s":
        rel = {d: (v**d, np.zeros(len(v))) for d in orders}
    else:
        rel = dict(zip(orders, zip(*zoh_relation_response(orders, dt, shift), strict=True), strict=True))
    # where a relation is beyond 2^2100 (or not finite) no double T brings the band into range: the band
    # is reported as not evaluable (inf, :func:`_scaled_product`) without solving for T there
    hopeless = np.zeros(len(shift), dtype=bool)
    for m, e in rel.values():
        hopeless |= ~np.isfinite(m) | (e > 2100)
    T = np.full((len(shift), real.G.shape[1]), np.inf, dtype=complex)
    T[~hopeless] = _resolvent_outputs(base, shift[~hopeless], real.G, real.C[row]) + real.D[row]
    return {s.name: _scaled_product(T[:, j], *rel[s.order]) for j, s in enumerate(ports)}


def zoh_relation_response(orders, dt: float, shift):
    r"""The ZOH chain relations ``rel_d = G_d / G_0`` at ``z = 1 + shift``, as mantissa and exponent.

    ``G_i`` is the transfer from the held ``M``-th derivative to the sampled ``i``-th
    (``M = max(orders)``; :func:`zoh_chain`).  With ``G_i = dt^(M-i) eta_i / (M-i)!`` the chain
    ``(zI - F) G = B`` becomes free of ``dt`` and of factorials:

    .. math::

        (z - 1)\,\eta_i = \sum_{j=i+1}^{M} \binom{M-i}{j-i} \eta_j, \qquad \eta_M = 1,

    a back substitution (componentwise backward stable) whose entries stay in range when the
    vector is rescaled by powers of two as it grows, and
    ``rel_d = dt^-d M!/(M-d)! eta_d / eta_0``.  Solving ``(zI - F) G = B`` as it stands
    under- and overflows for long chains (``G_0 ~ dt^M / (z - 1)^M``) and loses ``G_0`` near
    its zero at ``z = -1`` in a normwise solve.

    Parameters
    ----------
    orders : sequence of int
        Derivative orders, ascending.
    dt : float
        Sample time (s).
    shift : ndarray of complex
        ``z - 1`` at each frequency (``expm1(j omega dt)``).

    Returns
    -------
    mantissas : list of ndarray of complex
        One per order.
    exponents : list of ndarray of float
        ``rel_d = mantissa * 2**exponent``.
    """
    M = max(orders, default=0)
    nf = len(shift)
    eta = np.zeros((nf, M + 1), dtype=complex)
    eta[:, M] = 1.0
    scale = np.zeros(nf)  # eta (true) = eta (stored) * 2**scale
    pascal = [1]  # the exact integers C(M - i, 0 .. M - i), one row of Pascal's triangle per step
    for i in range(M - 1, -1, -1):
        pascal = [a + b for a, b in zip([0, *pascal], [*pascal, 0], strict=True)]
        binom = np.array(pascal[1:], dtype=float)  # C(M - i, j - i) for j = i+1 .. M, each correctly rounded
        eta[:, i] = (eta[:, i + 1:] @ binom) / shift  # eta_M = 1 carries the input term
        big = np.abs(eta[:, i])
        grow = np.where(big > 2.0**500, np.ceil(np.log2(np.maximum(big, 1.0))), 0.0)
        eta *= np.exp2(-grow)[:, None]
        scale += grow
    mants, exps = [], []
    for d in orders:
        m_d, e_d = _frexp(eta[:, d])
        m_0, e_0 = _frexp(eta[:, 0])
        factor = math.lgamma(M + 1) - math.lgamma(M - d + 1)
        with np.errstate(divide="ignore", invalid="ignore"):  # eta_0 out of range: no finite relation
            mants.append(np.where(m_0 != 0, m_d / np.where(m_0 != 0, m_0, 1.0), np.inf))
        exps.append(e_d - e_0 + (factor / math.log(2) - d * math.log2(dt)))
    return mants, exps


def _frexp(x):
    """``x = m * 2**e`` for complex ``x`` (``|m|`` in [0.5, 1), ``e`` float; 0 gives ``(0, 0)``)."""
    _, e = np.frexp(np.abs(x))
    return np.ldexp(x.real, -e) + 1j * np.ldexp(x.imag, -e), e.astype(float)


def _scaled_product(t, m, e):
    """``t * m * 2**e`` without intermediate over- or underflow.

    ``inf`` where the product is beyond the double range or a factor is not finite (a band
    that cannot be evaluated; the callers report it instead of a NaN).
    """
    mt, et = _frexp(np.where(np.isfinite(t), t, 0.0))
    total = e + et
    bad = ~(np.isfinite(t) & np.isfinite(m) & (total < 1000))
    with np.errstate(under="ignore"):
        out = mt * np.where(bad, 0.0, m) * np.exp2(np.where(bad, 0.0, total))
    out[bad] = np.inf
    return out


def _resolvent_outputs(base, shift, G, c) -> np.ndarray:
    r"""``c (shift_k I + base)^-1 G`` for every shift: ``(len(shift), q)``.

    The states are balanced first (:func:`_balanced`).  Small states (n <= 6): one batched LU
    solve per frequency.  Larger ones: one complex Schur form ``base = Z S Z^H`` (O(n^3),
    scipy) and two triangular solves per frequency (O(n^2)), ``y = (S + s I)^-1 Z^H G_j`` and
    ``l = c Z (S + s I)^-1``; ``T = c Z y``.  The Schur form is only normwise backward stable, so
    it is trusted where the first-order rounding bound

    .. math::

        |\delta T_j| \le 4 n u \left(\|l\| \,(\|base\|_F \|y\| + \|G_j\|) + \|c\| \|y\|\right)

    (a perturbation ``E`` of ``S`` changes ``T`` by ``l E y``; those of ``Z^H G`` and ``c Z`` by
    ``l dW`` and ``dc y``) is below ``1e-12 |T_j|``; elsewhere the frequency is solved again by
    LU with iterative refinement to a componentwise backward error of rounding level
    (:func:`_refined_solve`).  This matters for long kinematic chains: the input column ``B`` has entries
    ``dt^(n-i)/(n-i)!`` spanning hundreds of orders of magnitude and the input band's
    ``c (vI - A)^-1 B`` is ``1e17`` (n = 14, 100 Hz) to ``1e57`` (n = 30) times below the
    normwise error of the Schur route, while the LU solve of the balanced, nearly
    triangular matrix keeps it to ``1e-13``.  The cost stays one factorisation plus
    ``O(n^2)`` per frequency when the Schur route is accurate.
    """
    n = len(base)
    base, G, c = _balanced(base, G, c)
    if n <= 6:
        X = np.linalg.solve(shift[:, None, None] * np.eye(n) + base, np.broadcast_to(G, (len(shift), *G.shape)))
        return np.einsum("i,kij->kj", c, X)
    from .blas import one_thread

    with one_thread():  # one solve per frequency, each too small to share (cfdesign.blas)
        return _schur_outputs(base, shift, G, c)


def _schur_outputs(base, shift, G, c):
    """:func:`_resolvent_outputs` of a balanced state of more than 6: the Schur route, checked
    frequency by frequency, and LU with refinement where its bound does not hold."""
    from scipy.linalg import schur, solve_triangular

    n = len(base)
    S, Z = schur(base.astype(complex), output="complex")
    W, cz = Z.conj().T @ G, c @ Z
    out = np.empty((len(shift), G.shape[1]), dtype=complex)
    bound = np.empty(out.shape)
    diag = np.diag_indices(n)
    u = np.finfo(float).eps / 2
    nb, nc, ng = np.linalg.norm(base), np.linalg.norm(c), np.linalg.norm(G, axis=0)
    with np.errstate(all="ignore"):  # out of range: inf / nan, refused by the bound; the callers report it
        for k, s in enumerate(shift):
            M = S.copy()
            M[diag] += s
            y = solve_triangular(M, W, check_finite=False)
            left = solve_triangular(M, cz, trans="T", check_finite=False)
            out[k] = cz @ y
            ny, nl = np.linalg.norm(y, axis=0), np.linalg.norm(left)
            bound[k] = 4 * n * u * (nl * (nb * ny + ng) + nc * ny)
        redo = np.flatnonzero(~np.all(bound <= 1e-12 * np.abs(out), axis=1))
        for k in redo:
            out[k] = _refined_solve(shift[k] * np.eye(n) + base, G, c)
    return out


def _refined_solve(M, G, c):
    """``c M^-1 G`` by LU with partial pivoting and fixed-precision iterative refinement.

    Refinement stops when the componentwise backward error
    ``max |G - M X| / (|M| |X| + |G|)`` is at rounding level (Skeel, "Iterative refinement
    implies numerical stability for Gaussian elimination", Math. Comp. 35, 1980: one step
    usually suffices), at most three steps.
    """
    from scipy.linalg import lu_factor, lu_solve

    lu = lu_factor(M, check_finite=False)
    X = lu_solve(lu, G.astype(complex), check_finite=False)
    aM, aG = np.abs(M), np.abs(G)
    tol = 8 * np.finfo(float).eps * len(M)
    for _ in range(3):
        R = G - M @ X
        with np.errstate(divide="ignore", invalid="ignore"):
            berr = np.abs(R) / (aM @ np.abs(X) + aG)
        if not np.nanmax(berr, initial=0.0) > tol:
            break
        X = X + lu_solve(lu, R, check_finite=False)
    return c @ X


def _balanced(base, G, c):
    """``(D^-1 base D, D^-1 G, c D)``: the same ``c (vI + base)^-1 G`` with balanced states.

    ``D`` is the diagonal power-of-two scaling of LAPACK's ``gebal`` (Parlett and Reinsch,
    "Balancing a matrix for calculation of eigenvalues and eigenvectors", Numer. Math. 13,
    1969), so the similarity is exact.  Without it a state whose scale differs by orders of
    magnitude from the others (the ``dt^i`` of a kinematic chain) is lost in a normwise
    backward-stable solve: an n = 10 chain at 100 Hz gave bands off by 20 near Nyquist.
    """
    if not len(base) or not np.all(np.isfinite(base)):
        return base, G, c
    d = balancing(base)
    return base / d[:, None] * d[None, :], G / d[:, None], c * d


def balancing(M) -> np.ndarray:
    """The diagonal ``d`` (powers of two) of LAPACK's ``gebal`` scaling of ``M``, no permutation.

    ``D^-1 M D`` with ``D = diag(d)`` has rows and columns of comparable norms (Parlett and
    Reinsch, "Balancing a matrix for calculation of eigenvalues and eigenvectors", Numer. Math.
    13, 1969) and is exactly similar to ``M`` (powers of two).  Used by the frequency responses
    here and by the Riccati solvers' closed loop (:mod:`cfdesign.riccati.lyapunov`).  scipy.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        A finite square matrix.

    Returns
    -------
    ndarray, shape (n,)
    """
    from scipy.linalg import lapack  # gebal itself: scipy's matrix_balance wrapper doubled its cost at n = 30

    M = np.asarray(M)
    if not M.size:
        return np.ones(M.shape[0])
    gebal = lapack.zgebal if np.iscomplexobj(M) else lapack.dgebal
    _, lo, hi, ps, info = gebal(M, scale=1, permute=0)
    if info < 0:
        raise ValueError(f"gebal rejected argument {-info}")
    d = np.ones(M.shape[0])
    d[lo:hi + 1] = ps[lo:hi + 1]
    return d


def complementarity_error(responses: dict) -> float:
    """Scale-aware error of the identity ``sum_i T_i = 1`` on a frequency grid.

    Parameters
    ----------
    responses : dict
        ``{sensor: complex ndarray}`` band responses on one grid.

    Returns
    -------
    float
        ``max |sum_i T_i - 1| / (1 + sum_i |T_i|)``: the error relative to the size of the
        terms that cancel (rounding gives about 1e-15); ``inf`` when a band is not finite
        somewhere on the grid (it cannot be evaluated in double precision there).
    """
    if not all(np.all(np.isfinite(r)) for r in responses.values()):
        return math.inf
    total = sum(responses.values())
    size = 1.0 + sum(np.abs(r) for r in responses.values())
    return float(np.max(np.abs(total - 1.0) / size))


def identity_residual(bands: dict) -> float:
    """Relative coefficient size of ``sum_i num_i/den_i - 1`` cleared of denominators.

    Equal denominators are multiplied in once.

    Parameters
    ----------
    bands : dict
        ``{sensor: (num, den)}`` polynomials.

    Returns
    -------
    float
        0 for an exact identity, about the rounding level for a numerically complementary
        set; ``cfdesign verify`` requires at most 1e-12.  ``inf`` when the coefficients overflow
        (never NaN, which every tolerance test would pass).

    Examples
    --------
    >>> from cfdesign.linear import identity_residual
    >>> identity_residual({"rate": ([1.0, 0.0], [1.0, 2.0]), "angle": ([2.0], [1.0, 2.0])})
    0.0
    """
    total, scale = identity_polynomial(bands)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        residual = float(np.abs(total).max(initial=0.0) / scale)
    return residual if np.isfinite(residual) else np.inf  # coefficients that overflowed are no identity


def identity_polynomial(bands: dict):
    """``sum_i num_i/den_i - 1`` cleared of denominators, and the size of its terms.

    Equal denominators are multiplied in once.

    Parameters
    ----------
    bands : dict
        ``{sensor: (num, den)}`` polynomials.

    Returns
    -------
    total : ndarray
        Coefficients of ``sum_i num_i prod_(others) den - prod den``, highest power first.
    scale : float
        Largest coefficient of the terms summed (:func:`identity_residual` is
        ``max |total| / scale``).
    """
    dens = []  # the distinct denominators (bands of one filter share them exactly)
    for _, d in bands.values():
        if not any(len(d) == len(e) and np.array_equal(d, e) for e in dens):
            dens.append(d)
    common = _product(dens)
    total, scale = -common, np.abs(common).max()
    for num, d in bands.values():
        others = [e for e in dens if not (len(d) == len(e) and np.array_equal(d, e))]
        term = np.convolve(num, _product(others))
        total = np.polyadd(total, term)
        scale = max(scale, np.abs(term).max())
    return total, float(scale)


def _product(polys):
    out = np.ones(1)
    for p in polys:
        out = np.convolve(out, p)
    return out
