"""The numeric meaning of a gain table: gain forms, closed loop, bands, one angle wrap.

numpy only: this is the module the runtime, the designer, ``verify``, the analysis and the
C generator share, so that a gain form means one thing everywhere.  The symbolic engine
(:mod:`cfdesign.symbolic.observer`) derives the same objects exactly; the tests hold the two
against each other.  Derivations: ``docs/derivations.md``, sections "One observer" and
"Gain forms".

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

import numpy as np

__all__ = [
    "GAIN_FORMS",
    "OUTPUTS",
    "wrap",
    "wrap_scalar",
    "default_output",
    "gain_pair",
    "closed_loop",
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
    "is_stable",
    "spectral_margin",
]

#: the named gain forms of a table
GAIN_FORMS = ("predictor", "filter", "continuous")
#: what a discrete filter can output: the prediction before this step's readings, or the
#: estimate after them
OUTPUTS = ("prior", "posterior")

_TWO_PI = 2.0 * math.pi


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
    lo, hi = a.min(), a.max()
    if lo > -math.pi and hi <= math.pi:  # all inside: nothing to do (NaN fails these comparisons)
        return a
    if not (np.isfinite(lo) and np.isfinite(hi)):  # inf has no turn count: NaN, as wrap_scalar gives
        a[np.isinf(a)] = np.nan
    with np.errstate(invalid="ignore"):
        t = np.subtract(a, math.pi)  # a - 2 pi ceil((a - pi) / (2 pi)); an entry inside gets 0 turns
        np.divide(t, _TWO_PI, out=t)
        np.ceil(t, out=t)
        np.multiply(t, _TWO_PI, out=t)
        np.subtract(a, t, out=a)
        if np.nanmax(a, initial=-math.inf) > math.pi or np.nanmin(a, initial=math.inf) <= -math.pi:
            a[a > math.pi] -= _TWO_PI  # a result rounded an ulp outside: one more turn
            a[a <= -math.pi] += _TWO_PI
    return a


# ---------------------------------------------------------------------------- gain forms
def default_output(form: str) -> str:
    """The estimate a gain form outputs when a table does not say.

    Parameters
    ----------
    form : {'predictor', 'filter', 'continuous'}

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
    K : ndarray (n, m)
    form : {'predictor', 'filter', 'continuous'}

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
    if np.linalg.cond(F) > 1e12:
        return K, None
    return K, np.linalg.solve(F, K)


def closed_loop(F, H, K, form: str) -> np.ndarray:
    """State matrix of the error dynamics: ``F - Kp H`` (= ``F (I - K H)`` in filter form).

    Parameters
    ----------
    F : array_like, shape (n, n)
    H : array_like, shape (m, n)
    K : array_like, shape (n, m)
        Gain in ``form``.
    form : {'predictor', 'filter', 'continuous'}

    Returns
    -------
    ndarray, shape (n, n)

    Examples
    --------
    >>> from cfdesign.linear import closed_loop
    >>> closed_loop([[1.0]], [[1.0]], [[0.5]], "filter").tolist()
    [[0.5]]
    """
    Kp, _ = gain_pair(F, K, form)
    return np.asarray(F, dtype=float) - Kp @ np.asarray(H, dtype=float)


@dataclass(frozen=True)
class Realisation:
    """One phase of a filter as a linear system of its readings ``w = [u; y]``.

    ``x[k+1] = A x[k] + G w[k]`` and the output states ``xo[k] = C x[k] + D w[k]`` (the first
    row is the estimate of the common quantity).  Continuous: ``x' = A x + G w``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
    G : ndarray, shape (n, p + m)
    C : ndarray, shape (n, n)
    D : ndarray, shape (n, p + m)
    output : {'prior', 'posterior'}
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
    output : {'prior', 'posterior'}, optional
        Default :func:`default_output` of the form.

    Returns
    -------
    Realisation

    Raises
    ------
    ValueError
        ``output`` is not ``prior``/``posterior``, or the posterior is asked of a continuous
        table or of a predictor table whose ``F`` is singular.
    """
    output = default_output(form) if output is None else output
    if output not in OUTPUTS:
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
    L : array_like, shape (n, m)
        Update gain.
    R : array_like, shape (m, m)
        Measurement-noise covariance (per sample).

    Returns
    -------
    ndarray, shape (n, n)
    """
    P, H, L, R = (np.asarray(M, dtype=float) for M in (P, H, L, R))
    IKH = np.eye(len(P)) - L @ H
    return IKH @ P @ IKH.T + L @ R @ L.T


def is_stable(eigenvalues, domain: str) -> bool:
    """Strict stability of a set of eigenvalues.

    Parameters
    ----------
    eigenvalues : array_like
    domain : {'s', 'z'}

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
    domain : {'s', 'z'}

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
    B : ndarray, shape (m,)

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
    to the sampled ``i``-th (order 1 of a 1-chain: ``(z - 1)/dt``).

    Parameters
    ----------
    orders : iterable of int
        The sensors' derivative orders.
    domain : {'s', 'z'}
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
    nums = [output_adjugate(Fd, row, den) @ Bd for row in np.eye(M)] + [den]
    return {d: (np.ones(1), np.ones(1)) if d == 0 else (nums[d], nums[0]) for d in orders}


# ---------------------------------------------------------------------------- bands
def characteristic_polynomial(A) -> np.ndarray:
    """Coefficients of ``det(vI - A)``, highest power first.

    Parameters
    ----------
    A : array_like, shape (n, n)

    Returns
    -------
    ndarray, shape (n + 1,)
        Real coefficients (``[1.]`` for an empty matrix).
    """
    A = np.asarray(A, dtype=float)
    return np.poly(A).real if A.size else np.ones(1)


def output_adjugate(A, c, den=None) -> np.ndarray:
    """Rows ``c adj(vI - A)`` by power of ``v``.

    The Faddeev-LeVerrier recursion applied to one output row, ``O(n^3)`` in all:
    ``W[0] = c``, ``W[k] = W[k-1] A + den[k] c`` and ``c adj(vI - A) = sum_k W[k] v^(n-1-k)``.

    Parameters
    ----------
    A : array_like, shape (n, n)
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
    den : array_like, optional
        :func:`characteristic_polynomial` of ``A``, if already known.

    Returns
    -------
    ndarray, shape (n, n, n)
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
    den = characteristic_polynomial(real.A)
    W = output_adjugate(real.A, real.C[row], den)
    out = {}
    for j, s in enumerate(ports):
        d = real.D[row, j]
        num = np.concatenate([[d], W @ real.G[:, j] + d * den[1:]])
        rel_num, rel_den = relations[s.order]
        out[s.name] = (np.polymul(num, rel_num), np.polymul(den, rel_den))
    return out, den


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
    T = _resolvent_outputs(base, shift, real.G, real.C[row]) + real.D[row]
    orders = [s.order for s in ports]
    if domain == "s":
        rel = {d: v**d for d in set(orders)}
    else:
        M = max(orders, default=0)
        if M:
            Fd, Bd = zoh_chain(M, dt)
            Gc = np.linalg.solve(shift[:, None, None] * np.eye(M) + (np.eye(M) - Fd),
                                 np.broadcast_to(Bd[:, None], (len(v), M, 1)))[..., 0]
            Gc = np.concatenate([Gc, np.ones((len(v), 1))], axis=1)
        rel = {d: np.ones(len(v)) if d == 0 else Gc[:, d] / Gc[:, 0] for d in set(orders)}
    return {s.name: T[:, j] * rel[s.order] for j, s in enumerate(ports)}


def _resolvent_outputs(base, shift, G, c) -> np.ndarray:
    """``c (shift_k I + base)^-1 G`` for every shift: ``(len(shift), q)``.

    Small states: one batched solve.  Larger ones (n > 12): one complex Schur form
    ``base = Z S Z^H`` (O(n^3), scipy) and a triangular solve per frequency (O(n^2)), so the cost
    is that of one factorisation, not one per frequency.
    """
    n = len(base)
    if n <= 12:
        X = np.linalg.solve(shift[:, None, None] * np.eye(n) + base, np.broadcast_to(G, (len(shift), *G.shape)))
        return np.einsum("i,kij->kj", c, X)
    from scipy.linalg import schur, solve_triangular

    S, Z = schur(base.astype(complex), output="complex")
    W, cz = Z.conj().T @ G, c @ Z
    out = np.empty((len(shift), G.shape[1]), dtype=complex)
    diag = np.diag_indices(n)
    for k, s in enumerate(shift):
        M = S.copy()
        M[diag] += s
        out[k] = cz @ solve_triangular(M, W, check_finite=False)
    return out


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
        terms that cancel (rounding gives about 1e-15).
    """
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
    residual = float(np.abs(total).max(initial=0.0) / scale)
    return residual if np.isfinite(residual) else np.inf  # coefficients that overflowed are no identity


def _product(polys):
    out = np.ones(1)
    for p in polys:
        out = np.convolve(out, p)
    return out
