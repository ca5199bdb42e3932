"""The named complementary filters of the papers, as small constructors on the engine.

Each returns an :class:`~cfdesign.symbolic.observer.Observer` with the paper's symbol
names, so its bands can be compared with the printed equations of Carreira et al.,
*Complementary Filter Design with Three Frequency Bands: Robot Attitude Estimation*.

Where the paper's printed transfer functions do not follow from its own state-space model,
cfdesign derives from the model and offers the printed versions separately
(:func:`ckf3_printed`, :func:`dckf3_printed`), named as such (``docs/derivations.md``,
section "Three-band filters", derives both):

* CKF³: eqs. (15)-(17) have the denominator ``(1 + k12) s^2 + (k11 + k22) s + k21``; the
  model of eqs. (10)-(14) gives ``s^2 + (k11 + k22) s + k11 k22 + k21 - k12 k21`` and other
  numerators.  Both sets sum to one; the printed one belongs to the block diagram of the
  paper's Fig. 3, not to eqs. (10)-(14).
* DCKF³: against the ports of eqs. (25)-(27), eq. (29) is the gyro band, eq. (30) the
  odometry band, and eq. (31) times ``(1 - z^-1)/(T z^-1)`` the compass band; the paper's
  F-labels do not match these ports (they match its Fig. 6 arrangement), the sum and the
  denominator eq. (32) are right (:func:`dckf3` reproduces eq. (32) exactly).
"""

from __future__ import annotations

import numbers

import sympy as sp

from ..errors import StructureError
from ..gains import DERIVATIVE_NAMES as _NAMES
from .observer import Observer, Sensor, T, integrator_chain, s, z, zoh

__all__ = ["cf2", "cf3", "ckf3", "dckf3", "cfn", "chain", "position", "ckf3_printed", "dckf3_printed",
           "eq32_denominator", "STRUCTURES", "STRUCTURE_OPTIONS", "structure"]

#: names of the derivatives of the common quantity, by order (sensor names of cfn): the
#: designer's names of a linear chain's states (:data:`cfdesign.gains.DERIVATIVE_NAMES`)
DERIVATIVE_NAMES = _NAMES["linear"]


def _observer(Fc, Bc, H, K, sensors, name, discrete):
    """Observer of the continuous model ``(Fc, Bc)``, or of its exact ZOH model in ``z``."""
    if not discrete:
        return Observer(Fc, Bc, H, K, sensors, name=name)
    F, B = zoh(Fc, Bc)
    return Observer(F, B, H, K, sensors, domain="z", sample_time=T, name=name, continuous=(Fc, Bc))


#: rate-gyro model with a rate-correction state: psi' = u + c, c' = 0 (c = -gyro bias)
_BIASED_RATE = (sp.Matrix([[0, 1], [0, 0]]), sp.Matrix([1, 0]))


def _whole(value, message: str) -> int:
    """``value`` as an int (numpy integers too); ``message`` and the value in a StructureError otherwise."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)
    raise StructureError(f"{message}, got {value!r}")


def cf2(order: int = 1, *, discrete: bool = False) -> Observer:
    """Two-sensor complementary filter: an angle sensor and a rate sensor.

    ``order=1``: state ``[angle]``, ``T_angle = k/(s + k)``, ``T_rate = s/(s + k)``.
    ``order=2`` (gyro-bias estimation): state ``[angle, rate correction]`` with
    ``F = [[0, 1], [0, 0]]``, ``B = [1, 0]^T``, ``K = [k1, k2]^T``;
    ``T_angle = (k1 s + k2)/(s^2 + k1 s + k2)``, ``T_rate = s^2/(s^2 + k1 s + k2)``.
    The rate correction is minus the estimated gyro bias.  Derivation:
    ``docs/derivations.md``, section "Three-band filters" (CF: two sensors).

    Parameters
    ----------
    order : {1, 2}
        1: angle only; 2: angle and a rate-correction (gyro bias) state.
    discrete : bool
        The exact zero-order-hold model in ``z`` (sample time ``T``, predictor-form gains)
        instead of the continuous one.

    Returns
    -------
    Observer
        Sensors ``rate`` (input, rad/s) and ``angle`` (measurement, rad); gains ``k`` or
        ``k1, k2``.

    Raises
    ------
    StructureError
        An order other than 1 or 2.

    Examples
    --------
    >>> import cfdesign
    >>> cfdesign.cf2(order=2).bands
    {'rate': s**2/(k1*s + k2 + s**2), 'angle': (k1*s + k2)/(k1*s + k2 + s**2)}
    """
    order = _whole(order, "cf2 order must be 1 or 2")  # 2.0 failed deep in list arithmetic, True was order 1
    if order == 1:
        (Fc, Bc), K = integrator_chain(1), sp.Matrix([[sp.Symbol("k")]])
    elif order == 2:
        (Fc, Bc), K = _BIASED_RATE, sp.Matrix(sp.symbols("k1 k2"))
    else:
        raise StructureError(f"cf2 order must be 1 or 2, got {order!r}")
    sensors = [Sensor.input("rate", "rate", bias_state=1 if order == 2 else None),
               Sensor.measurement("angle", "angle", 0)]
    return _observer(Fc, Bc, sp.Matrix([[1] + [0] * (order - 1)]), K, sensors, f"cf2 (order {order})", discrete)


def cfn(n: int, *, full: bool = False, discrete: bool = False) -> Observer:
    """n-band complementary filter: sensors of the quantity and its first ``n - 1`` derivatives.

    State ``[psi, psi', ..., psi^(n-2)]``; the ``(n-1)``-th derivative drives the chain, the
    ``n - 1`` lower ones are measured (``H = I``).  The sparse gain (``full=False``, the CF3
    pattern of Carreira et al. eq. (13)) has the last row ``[k_(n-1), ..., k1]`` and gives
    ``den = s^(n-1) + k1 s^(n-2) + ... + k_(n-1)``, ``T_j = k_(n-1-j) s^j / den`` for
    ``j < n - 1`` and ``T_(n-1) = s^(n-1) / den`` (``docs/derivations.md``, "The n-band chain").

    Parameters
    ----------
    n : int
        Number of bands, 2 to 7.  Sensor names: position, velocity, acceleration, jerk, snap,
        crackle, pop (the highest is the input).
    full : bool
        A full gain ``k{i}{j}`` instead of the sparse pattern (``cfn(3, full=True)`` is the CKF3).
    discrete : bool
        The exact zero-order-hold model in ``z`` (sample time ``T``, predictor-form gains)
        instead of the continuous one.

    Returns
    -------
    Observer
        The ``n``-band observer, with symbolic gains.

    Raises
    ------
    StructureError
        ``n`` outside 2 to 7.

    Examples
    --------
    >>> import cfdesign
    >>> list(cfdesign.cfn(4).bands)
    ['jerk', 'acceleration', 'velocity', 'position']
    """
    n = _whole(n, f"cfn needs a whole number of bands n (an int) with 2 <= n <= {len(DERIVATIVE_NAMES)}")
    if not 2 <= n <= len(DERIVATIVE_NAMES):
        raise StructureError(f"cfn needs a whole number of bands n (an int) with 2 <= n <= {len(DERIVATIVE_NAMES)}, "
                             f"got {n!r}")
    m = n - 1
    if full:
        K = sp.Matrix(m, m, lambda i, j: sp.Symbol(f"k{i + 1}{j + 1}"))
    else:
        K = sp.Matrix(m, m, lambda i, j: sp.Symbol(f"k{m - j}") if i == m - 1 else 0)
    sensors = [Sensor.input(DERIVATIVE_NAMES[m], m)]
    sensors += [Sensor.measurement(DERIVATIVE_NAMES[j], j, j) for j in reversed(range(m))]
    label = f"cfn({n}{', full' if full else ''})"
    return _observer(*integrator_chain(m), sp.eye(m), K, sensors, label, discrete)


def chain(order: int, inputs, measurements, *, weights=None, bias: bool = False, discrete: bool = False,
          name: str = "chain") -> Observer:
    """A general kinematic chain: states by derivative order, any number of sensors of each order.

    State ``[psi, psi', ..., psi^(order-1)]`` (plus a rate-correction state ``c`` when
    ``bias``); the ``order``-th derivative drives the chain.  Every sensor of that order is an
    input and the chain is driven by their weighted sum, ``psi^(order) = sum_i w_i u_i (+ c)``
    with ``sum_i w_i = 1``, so two gyros of a heading chain (``order = 1``) are averaged with
    weights ``w_i`` (by default equal; the designer passes the minimum-variance weights
    ``w_i ~ 1 / q_i`` of their white noise).  With exact readings every ``u_i`` equals the true
    derivative, so the estimation error is autonomous and the bands sum to one for every gain
    and every weights that sum to one (``docs/derivations.md``, "One observer"; "A general
    kinematic chain").  ``bias`` adds the rate-correction state of :func:`cf2` order 2
    (``c' = 0``, ``c`` minus the inputs' common bias).

    Sensors of lower order are measurements: row ``j`` of ``H`` picks the state of the
    sensor's order (two compasses give two equal rows).  The gain is full (``k{i}{j}``), so
    the Kalman gain fits it.

    Parameters
    ----------
    order : int
        Derivative order of the input sensors (1: rate inputs to an angle, 2: accelerations
        to a position), 1 to 6.
    inputs : sequence of str
        Input sensor names (order ``order``), at least one.
    measurements : sequence of (str, int)
        ``(name, derivative order < order)``, at least one.
    weights : sequence of numbers, optional
        One per input, positive, summing to one (taken exactly); default equal weights.
    bias : bool
        Add the rate-correction (input bias) state.
    discrete : bool
        The exact zero-order-hold model in ``z`` (sample time ``T``, predictor-form gains)
        instead of the continuous one.
    name : str
        Label of the observer.

    Returns
    -------
    Observer
        The chain's observer, with symbolic gains.

    Raises
    ------
    StructureError
        An order out of range, no input or no measurement, a measurement of order not below
        the inputs', weights that are not positive or do not sum to one.

    Examples
    --------
    >>> from cfdesign.symbolic.filters import chain
    >>> obs = chain(1, ["gyro_a", "gyro_b"], [("compass", 0)], bias=True)
    >>> obs.gains, obs.proof().holds
    (('k11', 'k21'), True)
    """
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= len(DERIVATIVE_NAMES) - 1:
        raise StructureError(f"chain order must be an integer from 1 to {len(DERIVATIVE_NAMES) - 1}, got {order!r}")
    inputs, measurements = list(inputs), [(str(n), o) for n, o in measurements]
    if not inputs:
        raise StructureError(f"a chain of order {order} needs at least one input sensor of order {order}")
    if not measurements:
        raise StructureError("a chain needs at least one measurement sensor (of order below the inputs')")
    for m_name, m_order in measurements:
        if isinstance(m_order, bool) or not isinstance(m_order, int) or not 0 <= m_order < order:
            raise StructureError(f"sensor {m_name!r}: a measurement of a chain of order {order} must have a "
                                 f"derivative order from 0 to {order - 1}, got {m_order!r}")
    if weights is None:
        weights = [sp.Rational(1, len(inputs))] * len(inputs)
    from .observer import exact_number

    weights = [exact_number(w, f"weight of {n}") for n, w in zip(inputs, weights, strict=True)]
    if any(w <= 0 for w in weights) or sum(weights) != 1:
        raise StructureError(f"chain input weights must be positive and sum to 1 exactly, got {weights}")
    n = order + (1 if bias else 0)
    Fc = sp.zeros(n, n)
    for i in range(order - 1):
        Fc[i, i + 1] = 1
    if bias:
        Fc[order - 1, order] = 1
    Bc = sp.zeros(n, len(inputs))
    for j, w in enumerate(weights):
        Bc[order - 1, j] = w
    H = sp.Matrix([[1 if c == o else 0 for c in range(n)] for _, o in measurements])
    m = len(measurements)
    K = sp.Matrix(n, m, lambda i, j: sp.Symbol(f"k{i + 1}{j + 1}" if n < 10 and m < 10 else f"k{i + 1}_{j + 1}"))
    sensors = [Sensor.input(x, order, column=j, bias_state=order if bias else None) for j, x in enumerate(inputs)]
    sensors += [Sensor.measurement(x, o, row) for row, (x, o) in enumerate(measurements)]
    return _observer(Fc, Bc, H, K, sensors, name, discrete)


def cf3(*, discrete: bool = False) -> Observer:
    """CF3 of Carreira et al. eqs. (4)-(13): sparse gain ``K = [[0, 0], [k2, k1]]``.

    ``T_acceleration = s^2/den`` (high-pass), ``T_velocity = k1 s/den`` (band-pass),
    ``T_position = k2/den`` (low-pass), ``den = s^2 + k1 s + k2``.

    Parameters
    ----------
    discrete : bool
        The exact zero-order-hold model in ``z`` (sample time ``T``, predictor-form gains)
        instead of the continuous one.

    Returns
    -------
    Observer
        Sensors ``acceleration`` (input), ``velocity`` and ``position`` (measurements).

    Examples
    --------
    >>> import cfdesign
    >>> cfdesign.cf3().bands["velocity"]
    k1*s/(k1*s + k2 + s**2)
    """
    obs = cfn(3, discrete=discrete)
    obs.name = "cf3"
    return obs


def ckf3() -> Observer:
    """CKF3 of Carreira et al. eqs. (10)-(14) with the full gain ``[[k11, k12], [k21, k22]]``.

    Derived from the model, not the printed eqs. (15)-(17) (``docs/derivations.md``,
    "Three-band filters"; :func:`ckf3_printed` gives those):
    ``den = s^2 + (k11 + k22) s + k11 k22 + k21 - k12 k21``,
    ``T_acc = (1 - k12) s^2 / den``, ``T_vel = (k12 s + k22) s / den``,
    ``T_pos = (k11 s + k11 k22 + k21 - k12 k21) / den``.

    Returns
    -------
    Observer
        Continuous; sensors ``acceleration`` (input), ``velocity`` and ``position``.

    Examples
    --------
    >>> import cfdesign
    >>> f = cfdesign.ckf3()
    >>> f.gains, f.proof().holds
    (('k11', 'k12', 'k21', 'k22'), True)
    """
    obs = cfn(3, full=True)
    obs.name = "ckf3"
    return obs


def dckf3() -> Observer:
    """DCKF3 of Carreira et al. eqs. (25)-(27): gyro rate input, compass and odometry angles.

    ``F = [[1, T], [0, 1]]``, ``B = [T, 0]^T``, ``H = [[1, 0], [1, 0]]``, full predictor gain
    ``K = [[k11, k12], [k21, k22]]``; the second state is a rate (bias) correction.  Bands
    (``docs/derivations.md``, "Three-band filters"), with
    ``den = z^2 + (k11 + k12 - 2) z + 1 - k11 - k12 + T k21 + T k22`` (eq. (32) times ``z^2``):
    ``T_gyro = (z - 1)^2/den``, ``T_compass = (k11 (z - 1) + T k21)/den``,
    ``T_odometry = (k12 (z - 1) + T k22)/den``.

    Returns
    -------
    Observer
        Discrete, sample time ``T`` symbolic; sensors ``gyro`` (input, rad/s), ``compass``
        and ``odometry`` (measurements, rad).

    Examples
    --------
    >>> import cfdesign
    >>> f = cfdesign.dckf3()
    >>> f.gains, f.bands["gyro"]
    (('k11', 'k12', 'k21', 'k22'), (z - 1)**2/(T*k21 + T*k22 - k11 - k12 + z**2 + z*(k11 + k12 - 2) + 1))
    """
    K = sp.Matrix(2, 2, lambda i, j: sp.Symbol(f"k{i + 1}{j + 1}"))
    sensors = [Sensor.input("gyro", "rate", bias_state=1), Sensor.measurement("compass", "angle", 0),
               Sensor.measurement("odometry", "angle", 1)]
    return _observer(*_BIASED_RATE, sp.Matrix([[1, 0], [1, 0]]), K, sensors, "dckf3", discrete=True)


def position(*, discrete: bool = True) -> Observer:
    """Position filter of Vasconcelos et al. Sec. 3, one axis: state ``[p, v, b_a]``.

    Continuous model ``p' = v``, ``v' = u - b_a``, ``b_a' = 0`` with ``u`` the accelerometer
    (Earth frame ENU, gravity removed, m/s^2) and ``b_a`` its bias; GPS measures ``p`` (m).  Its
    ZOH model is ``F = [[1, T, -T^2/2], [0, 1, -T], [0, 0, 1]]``, ``B = [T^2/2, T, 0]^T``,
    ``H = [1, 0, 0]``, gain ``K = [k1, k2, k3]^T`` (one per phase when multirate;
    ``docs/derivations.md``, "Multirate gains").

    Parameters
    ----------
    discrete : bool
        The ZOH model (default) or the continuous one.

    Returns
    -------
    Observer
        Sensors ``accelerometer`` (input) and ``gps`` (measurement).
    """
    Fc = sp.Matrix([[0, 1, 0], [0, 0, -1], [0, 0, 0]])
    sensors = [Sensor.input("accelerometer", "acceleration", bias_state=2), Sensor.measurement("gps", "position", 0)]
    return _observer(Fc, sp.Matrix([0, 1, 0]), sp.Matrix([[1, 0, 0]]), sp.Matrix(sp.symbols("k1 k2 k3")),
                     sensors, "position", discrete)


def ckf3_printed() -> dict:
    """Carreira et al. eqs. (15)-(17) as printed, turned into bands ``T_1 = F_1 s^2`` etc. (eq. (19)).

    These are NOT the bands of the model of eqs. (10)-(14) (see :func:`ckf3`); they sum to one
    too and are offered only for comparison with the paper.

    Returns
    -------
    dict
        ``{'acceleration', 'velocity', 'position'}`` to sympy expressions in ``s``.
    """
    k11, k12, k21, k22 = sp.symbols("k11 k12 k21 k22")
    den = (1 + k12) * s**2 + (k11 + k22) * s + k21
    return {"acceleration": s**2 / den, "velocity": (k12 * s + k22) * s / den,
            "position": (k11 * s + k21) / den}


def eq32_denominator():
    """The denominator exactly as printed in Carreira et al. eq. (32), in powers of ``z^-1``.

    Returns
    -------
    sympy expression
        ``1 + (k11 + k12 - 2) z^-1 + (1 - k11 - k12 + T k21 + T k22) z^-2``.
    """
    k11, k12, k21, k22 = sp.symbols("k11 k12 k21 k22")
    return (1 - k12 - k11 + T * k21 + T * k22) * z**-2 + (k11 + k12 - 2) * z**-1 + 1


def dckf3_printed() -> dict:
    """Carreira et al. eqs. (29)-(31) as printed, keyed by the port of :func:`dckf3` each belongs to.

    ``'gyro'`` is eq. (29) (printed as psi_hat/psi), ``'odometry'`` is eq. (30), ``'compass'``
    is eq. (31) (printed as psi_hat/omega) times ``(1 - z^-1)/(T z^-1)``: the paper's labels fit
    the sensor arrangement of its Fig. 6, not the ports of eqs. (25)-(27).

    Returns
    -------
    dict
        ``{'gyro', 'compass', 'odometry'}`` to sympy expressions in ``z``.
    """
    k11, k12, k21, k22 = sp.symbols("k11 k12 k21 k22")
    den = eq32_denominator()
    f29 = (z**-2 - 2 * z**-1 + 1) / den
    f30 = ((-k12 + T * k22) * z**-2 + k12 * z**-1) / den
    f31 = ((-T * k11 + T**2 * k21) * z**-3 + T * k11 * z**-2) / ((1 - z**-1) * den)
    return {"gyro": f29, "compass": f31 * (1 - z**-1) / (T * z**-1), "odometry": f30}


#: structures the CLI and the design files know by name
STRUCTURES = {"cf2": cf2, "cf3": cf3, "ckf3": ckf3, "dckf3": dckf3, "cfn": cfn, "position": position}


#: the options each named structure takes (``bands`` is cfn's ``n``)
STRUCTURE_OPTIONS = {"cf2": ("order", "discrete"), "cf3": ("discrete",), "ckf3": (), "dckf3": (),
                     "cfn": ("bands", "full", "discrete"), "position": ("discrete",)}


def structure(name: str, **options) -> Observer:
    """Build a named structure with its options.

    Parameters
    ----------
    name : str
        A key of :data:`~cfdesign.symbolic.filters.STRUCTURES`: ``cf2``, ``cf3``, ``ckf3``, ``dckf3``,
        ``cfn``, ``position``.
    **options
        ``order`` (cf2: 1 or 2); ``bands`` and ``full`` (cfn); ``discrete`` (cf2, cf3, cfn,
        position).  None means the default.

    Returns
    -------
    Observer
        The observer of the structure, with symbolic gains.

    Raises
    ------
    StructureError
        An unknown name, an option that does not apply, cfn without ``bands``.

    Examples
    --------
    >>> import cfdesign
    >>> cfdesign.structure("cf2", order=2, discrete=True).discrete
    True
    """
    if name not in STRUCTURES:
        raise StructureError(f"unknown structure {name!r}; choose one of {', '.join(STRUCTURES)}")
    given = {key: value for key, value in options.items() if value is not None}
    for key in given:
        if key not in STRUCTURE_OPTIONS[name]:
            allowed = ", ".join(STRUCTURE_OPTIONS[name]) or "none"
            raise StructureError(f"option {key!r} does not apply to {name} (its options: {allowed})")
    if name == "cfn":
        if "bands" not in given:
            raise StructureError("cfn needs the number of bands (bands / --bands N)")
        given["n"] = given.pop("bands")
    return STRUCTURES[name](**given)
