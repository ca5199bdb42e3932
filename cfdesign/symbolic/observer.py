"""The symbolic engine: a linear observer of a kinematic chain -> band transfer functions.

Every filter in cfdesign is an observer (``docs/derivations.md``, section "One observer")

.. math::

    \\dot{\\hat x} = F\\hat x + B u + K (y - H \\hat x)                 \\quad (s)

    \\hat x[k+1] = F\\hat x[k] + B u[k] + K (y[k] - H \\hat x[k])     \\quad (z,\\ predictor)

where ``u`` stacks the readings of the "derivative" sensors (gyro rate, accelerometer) and
``y`` the readings of the sensors measured against the state.  The estimate of the common
quantity (angle, position) is :math:`\\hat\\psi = C\\hat x` with ``C = [1, 0, ..., 0]``.

Each sensor reads the common quantity through a known relation: an angle sensor reads
``psi``, a rate sensor ``s psi`` and an accelerometer ``s**2 psi`` (continuous), or their
sampled counterparts (discrete, see :func:`discrete_relation`).  The *band* of a sensor is
the transfer function from the common quantity, routed through that sensor, to the
estimate: ``T_i = G_i * D_i`` with ``G_i`` the transfer from the sensor's reading to the
estimate and ``D_i`` the relation.  If the relations are those the model implies, the
estimation error is autonomous and the bands sum to one for ANY gain (Carreira et al. eqs. (1)
and (34)); :meth:`Observer.proof` checks it exactly with the gains left symbolic.

This package is the only one in cfdesign that imports sympy.
"""

from __future__ import annotations

import keyword
import math
import numbers
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from functools import cached_property

import numpy as np
import sympy as sp

from ..errors import GainError, ProofError, StructureError
from ..spec import QUANTITY_ORDERS

__all__ = [
    "QUANTITY_ORDERS",
    "Sensor",
    "Observer",
    "discrete_relation",
    "integrator_chain",
    "zoh",
    "zoh_chain",
    "s",
    "z",
    "T",
]

#: Laplace variable
s = sp.Symbol("s")
#: z-transform variable
z = sp.Symbol("z")
#: sample time in seconds (kept symbolic unless substituted)
T = sp.Symbol("T", positive=True)



def _order_of(measures) -> int:
    if isinstance(measures, bool):
        raise StructureError(f"sensor 'measures' must be a quantity name or an order, got {measures!r}")
    if isinstance(measures, numbers.Integral):
        if measures < 0:
            raise StructureError(f"sensor derivative order must be >= 0, got {measures}")
        return int(measures)
    if isinstance(measures, str) and measures in QUANTITY_ORDERS:
        return QUANTITY_ORDERS[measures]
    known = ", ".join(sorted(QUANTITY_ORDERS))
    raise StructureError(f"unknown sensor quantity {measures!r}; expected one of {known} or an integer order")


@dataclass(frozen=True)
class Sensor:
    """How one sensor enters the observer and how it relates to the common quantity.

    Parameters
    ----------
    name : str
        A Python/C identifier (it reaches generated C code), unique within the observer.
    order : int
        Derivative order of the common quantity the sensor reads: 0 angle/position,
        1 rate/velocity, 2 acceleration.
    role : {'input', 'measurement'}
        ``'input'``: the reading drives the model through column ``index`` of ``B``;
        ``'measurement'``: it is compared with row ``index`` of ``H x``.
    index : int
        Column of ``B`` or row of ``H``.
    relation : sympy expression, optional
        Explicit transfer ``D(var)`` with ``reading = D * quantity``.  By default it is
        ``s**order`` (continuous) or :func:`discrete_relation` (discrete).
    bias_state : int, optional
        Input sensors only: the state that estimates this sensor's bias (its correction),
        where the design puts the bias random walk.

    Raises
    ------
    StructureError
        A name that is not an identifier, an unknown role or order, a negative index, a bias
        state that is not a non-negative integer or is given to a measurement.

    Examples
    --------
    >>> from cfdesign import Sensor
    >>> Sensor.measurement("compass", "angle", 0)
    Sensor(name='compass', order=0, role='measurement', index=0, relation=None, bias_state=None)
    """

    name: str
    order: int
    role: str
    index: int
    relation: object = None
    bias_state: int | None = None

    def __post_init__(self):
        if not (isinstance(self.name, str) and self.name.isidentifier() and not keyword.iskeyword(self.name)):
            raise StructureError(f"sensor name {self.name!r} is not a valid identifier")
        if self.role not in ("input", "measurement"):
            raise StructureError(f"sensor {self.name!r}: role must be 'input' or 'measurement', got {self.role!r}")
        object.__setattr__(self, "order", _order_of(self.order))
        if not isinstance(self.index, numbers.Integral) or self.index < 0:
            raise StructureError(f"sensor {self.name!r}: index must be a non-negative integer, got {self.index!r}")
        # bias_state='x' gave a raw TypeError, -1 put the bias random walk on the last state
        if self.bias_state is not None and (isinstance(self.bias_state, bool) or not isinstance(
                self.bias_state, numbers.Integral) or self.bias_state < 0):
            raise StructureError(f"sensor {self.name!r}: bias_state must be a state index (an integer >= 0), "
                                 f"got {self.bias_state!r}")
        if self.bias_state is not None and self.role != "input":
            raise StructureError(f"sensor {self.name!r}: only input sensors have a bias state")

    @classmethod
    def input(cls, name: str, measures, column: int = 0, relation=None, bias_state=None) -> Sensor:
        """A sensor whose reading is the model input.

        Parameters
        ----------
        name : str
            Identifier, unique within the observer.
        measures : int or str
            Derivative order of the common quantity it reads, or its name (``'rate'``,
            ``'acceleration'``, ...: :data:`~cfdesign.spec.QUANTITY_ORDERS`).
        column : int
            Column of ``B`` it drives.
        relation : sympy expression, optional
            Explicit transfer ``D(var)`` with ``reading = D * quantity``.
        bias_state : int, optional
            The state that estimates this sensor's bias.

        Returns
        -------
        Sensor
            The input sensor (role ``input``).

        Raises
        ------
        StructureError
            A name that is not an identifier, an unknown quantity, a negative column or a
            ``bias_state`` that is not a state index.

        Examples
        --------
        >>> from cfdesign import Sensor
        >>> Sensor.input("gyro", "rate").order
        1
        """
        return cls(name, measures, "input", column, relation, bias_state)

    @classmethod
    def measurement(cls, name: str, measures, row: int, relation=None) -> Sensor:
        """A sensor compared with a row of ``H x``.

        Parameters
        ----------
        name : str
            Identifier, unique within the observer.
        measures : int or str
            Derivative order of the common quantity it reads, or its name (``'angle'``,
            ``'velocity'``, ...).
        row : int
            Row of ``H``.
        relation : sympy expression, optional
            Explicit transfer ``D(var)`` with ``reading = D * quantity``.

        Returns
        -------
        Sensor
            The measurement sensor (role ``measurement``).

        Raises
        ------
        StructureError
            A name that is not an identifier, an unknown quantity or a negative row.

        Examples
        --------
        >>> from cfdesign import Sensor
        >>> Sensor.measurement("compass", "angle", 0).order
        0
        """
        return cls(name, measures, "measurement", row, relation)


def discrete_relation(order: int, chain_order: int, sample_time=T):
    """Sampled relation ``reading = D(z) * quantity`` for a ZOH kinematic chain.

    The chain ``psi^(chain_order) = w`` with ``w`` held constant over each sample time
    (zero-order hold, the assumption of Carreira et al. Sec. IV) gives exact discrete transfers
    ``G_j(z)`` from ``w`` to the sampled ``j``-th derivative; the relation of a sensor of
    order ``j`` is ``D_j = G_j / G_0`` (``docs/derivations.md``, section "Relations").

    Parameters
    ----------
    order : int
        Derivative order the sensor reads (0 for the quantity itself).
    chain_order : int
        Order of the chain (the highest derivative any sensor reads).
    sample_time : sympy symbol or number
        Sample time ``T`` (s); symbolic by default.

    Returns
    -------
    sympy expression
        ``D(z)``.

    Raises
    ------
    StructureError
        ``order`` outside ``0 .. chain_order``.

    Examples
    --------
    >>> from cfdesign.symbolic import discrete_relation
    >>> discrete_relation(1, 1), discrete_relation(1, 2)
    ((z - 1)/T, 2*(z - 1)/(T*(z + 1)))
    """
    if not 0 <= order <= chain_order:
        raise StructureError(f"relation of order {order} needs 0 <= order <= chain order {chain_order}")
    if order == 0:
        return sp.Integer(1)
    Fd, Bd = zoh_chain(chain_order, sample_time)
    g = _chain_transfers(Fd, Bd)
    return sp.factor(sp.cancel(g[order] / g[0]))


def integrator_chain(m: int):
    """Continuous model of ``m`` integrators in a row, driven by the ``m``-th derivative.

    Parameters
    ----------
    m : int
        Number of states.

    Returns
    -------
    F : sympy.Matrix, shape (m, m)
        Ones on the superdiagonal.
    B : sympy.Matrix, shape (m, 1)
        One in the last row.
    """
    F = sp.Matrix(m, m, lambda i, j: 1 if j == i + 1 else 0)
    B = sp.Matrix(m, 1, lambda i, _: 1 if i == m - 1 else 0)
    return F, B


def zoh(Fc, Bc, sample_time=T):
    """Exact zero-order-hold discretisation: ``F = e^{Fc T}``, ``B = int_0^T e^{Fc t} dt Bc``.

    For the kinematic chains here ``Fc`` is nilpotent, so both are polynomials in ``T``.

    Parameters
    ----------
    Fc, Bc : sympy.Matrix
        Continuous model, shapes (n, n) and (n, p).
    sample_time : sympy symbol or number
        Sample time ``T`` (s); symbolic by default.

    Returns
    -------
    F, B : sympy.Matrix
        The discrete model.
    """
    tau = sp.Dummy("tau", nonnegative=True)
    n = Fc.shape[0]
    if (Fc**n).is_zero_matrix:  # nilpotent: the exponential series stops after n terms
        Phi = sum(((Fc * tau) ** k / sp.factorial(k) for k in range(1, n)), sp.eye(n))
    else:
        Phi = sp.simplify((Fc * tau).exp())
    B = (Phi * Bc).applyfunc(lambda e: sp.integrate(sp.expand(e), (tau, 0, sample_time)))
    return Phi.subs(tau, sample_time).applyfunc(sp.expand), B.applyfunc(sp.expand)


def zoh_chain(m: int, sample_time=T):
    """ZOH model of an ``m``-state chain: ``F[i, j] = T**(j-i)/(j-i)!``, ``B[i] = T**(m-i)/(m-i)!``.

    Parameters
    ----------
    m : int
        Number of states.
    sample_time : sympy symbol or number
        Sample time ``T`` (s); symbolic by default.

    Returns
    -------
    F, B : sympy.Matrix
        ``F`` (m x m) and ``B`` (m x 1), exact in ``sample_time``.

    Examples
    --------
    >>> from cfdesign.symbolic import zoh_chain
    >>> F, B = zoh_chain(2)
    >>> F.tolist(), B.tolist()
    ([[1, T], [0, 1]], [[T**2/2], [T]])
    """
    return zoh(*integrator_chain(m), sample_time)


def _chain_transfers(Fd, Bd):
    """Transfers from the held top derivative to each sampled state (and 1 for the input)."""
    m = Fd.shape[0]
    M = z * sp.eye(m) - Fd
    adj, det = M.adjugate(method="berkowitz"), M.det(method="berkowitz")
    col = adj * Bd
    return [sp.cancel(col[i] / det) for i in range(m)] + [sp.Integer(1)]


def _sensor_tuple(sensors) -> tuple:
    """``sensors`` as a tuple of :class:`Sensor`, or a StructureError saying what was given."""
    if isinstance(sensors, (str, bytes, Sensor)) or not isinstance(sensors, Iterable):
        raise StructureError(f"sensors must be a sequence of Sensor, got {type(sensors).__name__}")
    sensors = tuple(sensors)
    bad = [type(x).__name__ for x in sensors if not isinstance(x, Sensor)]
    if bad:
        raise StructureError(f"sensors must be Sensor objects (Sensor.input, Sensor.measurement), got {bad[0]}")
    return sensors


def _check_signal_names(sys, sensors) -> None:
    """Refuse a python-control system whose own input/output names differ from the sensors'."""
    for role, labels, default in (("input", sys.input_labels, "u"), ("measurement", sys.output_labels, "y")):
        by_index = {x.index: x.name for x in sensors if x.role == role}
        for i, label in enumerate(labels):
            if label == f"{default}[{i}]" or i not in by_index:
                continue  # python-control's default name, or a missing sensor (reported by the observer)
            if label != by_index[i]:
                what = "input" if role == "input" else "output"
                raise StructureError(f"{sys.name}: {what} {i} is named {label!r} but the {role} sensor at index {i} "
                                     f"is {by_index[i]!r}; name the sensors after the system's signals "
                                     "(or reorder them)")


def _matrix(name: str, value, rows=None, cols=None) -> sp.Matrix:
    if hasattr(value, "dt") and hasattr(value, "ninputs"):  # a python-control system, not a matrix
        raise StructureError(f"{name} is a python-control {type(value).__name__}, not a matrix; build the observer "
                             "with Observer.from_statespace(sys, K, sensors)")
    if isinstance(value, Mapping):  # its keys were read as the entries ('F is text')
        raise StructureError(f"{name} is a {type(value).__name__}, not a matrix (nested lists or an array)")
    _no_text(name, value)
    _no_bool(name, value)
    if _ndim(value) > 2:  # sympy's raw NotImplementedError 'SymPy supports just 1D and 2D matrices'
        raise StructureError(f"{name} must be a matrix (2-D), got an array of shape {np.shape(value)}")
    try:
        M = sp.Matrix(value)
    except (TypeError, ValueError, sp.SympifyError) as exc:  # ragged or non-numeric input
        reason = " ".join(str(exc).split())  # sympy's message spans lines
        raise StructureError(f"{name} is not a matrix: {reason}") from None
    for (i, j), e in np.ndenumerate(np.array(M.tolist(), dtype=object).reshape(M.shape)):
        if isinstance(e, sp.Basic) and e.has(sp.nan, sp.oo, -sp.oo, sp.zoo):
            raise GainError(f"{name}[{i}][{j}] must be finite, got {e}")
    # floats (a numpy gain from control.dlqe, 0.5 * k) as the exact numbers they print as: with
    # sympy Floats the bands of a discrete observer summed to (X)/(X) - 5.6e-17 and the proof failed
    M = M.applyfunc(lambda e: e.xreplace({f: exact_number(float(f)) for f in e.atoms(sp.Float)})
                    if isinstance(e, sp.Basic) and e.has(sp.Float) else e)
    for (i, j), e in np.ndenumerate(np.array(M.tolist(), dtype=object).reshape(M.shape)):
        if isinstance(e, sp.Basic) and e.is_number and e.is_real is False:
            # a complex entry gave bands that do not sum to one: a proof that failed for no fault of the filter
            raise StructureError(f"{name}[{i}][{j}] is complex ({e}); the model, gains and output are real")
    if M.shape == (0, 0) and rows:
        M = sp.zeros(rows, cols or 0)
    if (rows is not None and M.shape[0] != rows) or (cols is not None and M.shape[1] != cols):
        want = (f"{rows}x{cols}" if cols is not None else f"{rows}x(inputs): one row per state") if rows is not None \
            else f"(measurements)x{cols}: one column per state"
        raise StructureError(f"{name} must be {want}, got {M.shape[0]}x{M.shape[1]}")
    return M


def _no_text(name, value):
    """Text in a matrix is refused, never evaluated (``sympy.Matrix`` would sympify
    ``"__import__('os')"``); a symbol is ``sympy.Symbol('k1')``."""
    if isinstance(value, (str, bytes)):
        raise StructureError(f"{name} is text ({value[:40]!r}), not a matrix; matrices take numbers and sympy "
                             "expressions (sympy.Symbol('k1') for a gain symbol): text is never evaluated")
    if isinstance(value, (sp.Basic, sp.MatrixBase)) or (isinstance(value, np.ndarray) and value.dtype.kind in "biufc"):
        return
    if isinstance(value, Iterable):
        for item in (value.flat if isinstance(value, np.ndarray) else value):
            _no_text(name, item)


def _ndim(value) -> int:
    """Dimensions of an array-like (0 for a sympy matrix, a list of them, which sympy stacks into
    one, or nested lists numpy cannot shape: a ragged matrix, told by sympy)."""
    if isinstance(value, sp.MatrixBase) or (isinstance(value, (list, tuple))
                                            and any(isinstance(v, sp.MatrixBase) for v in value)):
        return 0
    try:
        return np.ndim(value)
    except ValueError:
        return 0


def _no_bool(name, value):
    """A bool in a matrix is refused: sympy keeps it as a logical ``true`` (a deprecation warning),
    and the bands then failed with sympy's raw 'BooleanAtom not allowed in this context'."""
    if isinstance(value, (bool, np.bool_, sp.logic.boolalg.BooleanAtom)) or (isinstance(value, np.ndarray)
                                                                            and value.dtype.kind == "b"):
        raise StructureError(f"{name} holds a bool ({value if np.ndim(value) == 0 else 'dtype bool'}), not a "
                             "number: write 1 or 0")
    if isinstance(value, np.ndarray) and value.dtype == object:  # entries of any type: a bool among them
        value = value.flat
    elif isinstance(value, (sp.Basic, sp.MatrixBase, np.ndarray, str, bytes)) or not isinstance(value, Iterable):
        return
    for item in value:
        _no_bool(name, item)


def exact_number(value, name: str = "value"):
    """An exact sympy number from a Python number (floats by their decimal repr).

    Strings are not accepted: parse user text with :func:`parse_number` first, which
    never evaluates it.
    """
    if isinstance(value, sp.Basic):
        if not value.is_number or not value.is_real:
            raise GainError(f"{name} must be a real number, got {value}")
        return value
    if isinstance(value, np.ndarray) and value.ndim == 0:  # a 0-d array: float(K @ h), K[i, j] of a product
        value = value[()]
    if isinstance(value, Decimal):  # exact decimal (not a numbers.Real): Fraction takes it as written
        if not value.is_finite():
            raise GainError(f"{name} must be finite, got {value!r}")
        fr = Fraction(value)
        return sp.Rational(fr.numerator, fr.denominator)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise GainError(f"{name} must be a real number, got {value!r}")
    if isinstance(value, numbers.Integral):
        return sp.Integer(int(value))
    if not math.isfinite(float(value)):
        raise GainError(f"{name} must be finite, got {value!r}")
    # every binary float (np.float32 too, which Fraction() refused with a raw TypeError) by its shortest repr
    fr = Fraction(repr(float(value))) if isinstance(value, (float, np.floating)) else Fraction(value)
    return sp.Rational(fr.numerator, fr.denominator)


def model_number(value, name: str = "value"):
    """A model entry as an exact rational: the simplest rational within two ulp of the double.

    A sampled model's entries are rounded values of exact ones (``T^3/6`` at ``T = 0.01`` is
    stored as 1.6666666666666668e-07; ``control.c2d`` of an integrator at 0.013 s gives
    ``B = 0.012999999999999999``); taken by their decimal value, ``B`` no longer equals the
    integral of ``F`` over the sample time and the exact proof of a complementary filter fails
    by 1e-17.  Entries that are not rounded rationals (``exp(-T/tau)``) move by at most two ulp.

    Parameters
    ----------
    value : float
        A finite real number (integers are returned as they are).
    name : str
        How an error names the entry.

    Returns
    -------
    sympy.Rational
        The rational of smallest denominator within ``2 ulp(value)`` of ``value``.

    Raises
    ------
    GainError
        ``value`` is not a finite real number.
    """
    exact = exact_number(value, name)  # the checks: real, finite
    if exact.is_Integer:
        return exact
    v = float(value)

    def simplest(lo, hi):  # the rational of smallest denominator in [lo, hi], 0 < lo <= hi
        n = math.floor(lo)
        if n == lo or n + 1 <= hi:
            return Fraction(n if n == lo else n + 1)
        return n + 1 / simplest(1 / (hi - n), 1 / (lo - n))

    x, tol = Fraction(abs(v)), Fraction(2 * math.ulp(v))
    q = simplest(x - tol, x + tol) if x > tol else x
    return sp.Rational(int(math.copysign(1, v)) * q.numerator, q.denominator)


def parse_number(text: str, name: str = "value"):
    """Parse ``'2'``, ``'0.5'``, ``'1e-3'`` or ``'1/3'`` exactly, without evaluating code."""
    try:
        fr = Fraction(text.strip())
        finite = math.isfinite(float(fr)) and (float(fr) != 0 or fr == 0)  # 1e-400: no double, it rounds to 0
    except (ValueError, ZeroDivisionError):
        raise GainError(f"{name} must be a number, got {text!r}") from None
    except OverflowError:
        finite = False
    if not finite:
        raise GainError(f"{name} must be a finite double-precision number, got {text!r}")
    return sp.Rational(fr.numerator, fr.denominator)


def _sample_time_of(sample_time, *matrices):
    """The sample time of a discrete observer: ``sample_time``, else the one symbol named ``T``
    in the matrices, else the engine's ``T``; refused when the matrices hold another symbol of
    the sample time's name (``Symbol("T")`` beside ``Symbol("T", positive=True)``)."""
    free = set().union(*(M.free_symbols for M in matrices))
    if sample_time is None:
        named = [x for x in free if x.name == T.name]
        sample_time = named[0] if len(named) == 1 else T
    if isinstance(sample_time, sp.Symbol):
        if any(x.name == sample_time.name and x != sample_time for x in free):
            raise StructureError(
                f"the matrices hold a symbol {sample_time.name} that is not the sample time {sample_time.name} (the "
                "same name with other assumptions, which never cancel): write both with one symbol")
    return sample_time


class Observer:
    """A linear observer of a kinematic chain and its complementary bands.

    Parameters
    ----------
    F, B, H, K : array_like (sympy or numeric entries)
        State matrix (n x n), input matrix (n x p), measurement matrix (m x n) and gain
        (n x m).  Symbols in them (gains ``k1``, ..., sample time ``T``) stay symbolic.
    sensors : sequence of Sensor
        One sensor per column of ``B`` and per row of ``H``.
    domain : {'s', 'z'}
        Continuous (Laplace variable ``s``) or discrete (``z``, sample time ``T``).
    sample_time : sympy symbol or positive number, optional
        Discrete only; defaults to the symbol named ``T`` in the matrices, whatever its
        assumptions (``sp.Symbol("T")``), else to cfdesign's ``T`` (positive).
    gain_form : {'predictor', 'filter'}
        Discrete only (``'filter'`` for a continuous observer is a StructureError).
        ``'predictor'``: ``x[k+1] = F x + B u + K (y - H x)`` and the estimate is ``C x``
        (Carreira et al. eq. (25)); ``'filter'``: ``x+ = x- + K (y - H x-)``,
        ``x-[k+1] = F x+ + B u``, the estimate is ``C x+``.
    name : str
        Label used in reports.
    output : array_like, optional
        Row ``C`` (1 x n) that picks the estimate out of the state; default ``[1, 0, ...]``.
    continuous : (Fc, Bc), optional
        Discrete observers built by ZOH from a continuous chain keep it here; the design
        uses it for exact (Van Loan) noise discretisation.  Continuous observers: ``(F, B)``.

    Raises
    ------
    StructureError
        Shapes that do not fit (or an array of more than 2 dimensions), a complex or bool entry, a
        name that is not text, an unknown domain or gain form, a sample time or
        the ``filter`` gain form for a continuous observer, sensors that do not cover every column of ``B`` and row of
        ``H`` exactly once, two different symbols with the sample time's name (a sympy symbol
        is its name and its assumptions: they would print alike and never cancel).
    GainError
        A sample time that is not positive.

    Notes
    -----
    For sensor ``i`` with state-space route ``(A, B_i, C_o, D_i)`` the band is
    ``T_i = (C_o adj(vI - A) B_i + D_i det(vI - A)) / det(vI - A) * rel_i(v)``.

    Examples
    --------
    A two-band filter written by hand: a gyro rate drives the angle, a compass measures it.

    >>> import sympy as sp
    >>> from cfdesign import Observer, Sensor
    >>> k = sp.Symbol("k")
    >>> obs = Observer([[0]], [[1]], [[1]], [[k]],
    ...                [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)])
    >>> obs.bands
    {'gyro': s/(k + s), 'compass': k/(k + s)}
    >>> obs.proof().holds
    True
    """

    def __init__(self, F, B, H, K, sensors, *, domain="s", sample_time=None,
                 gain_form="predictor", name="observer", output=None, continuous=None):
        if not isinstance(name, str):  # name=3 printed 'Complementarity proof for 3'
            raise StructureError(f"name must be text (the observer's label in reports), got {type(name).__name__}")
        F = _matrix("F", F)
        n = F.shape[0]
        if F.shape != (n, n) or n == 0:
            raise StructureError(f"F must be square and non-empty, got {F.shape[0]}x{F.shape[1]}")
        B = _matrix("B", B, n)
        H = _matrix("H", H, None, n)
        K = _matrix("K", K, n, H.shape[0])
        if domain not in ("s", "z"):
            raise StructureError(f"domain must be 's' (continuous) or 'z' (discrete), got {domain!r}")
        if domain == "z":
            sample_time = _sample_time_of(sample_time, F, B, H, K)
            if not isinstance(sample_time, sp.Symbol):
                sample_time = exact_number(sample_time, "sample time T")
                if sample_time <= 0:
                    raise GainError(f"sample time T must be positive, got {sample_time}")
            if gain_form not in ("predictor", "filter"):
                raise StructureError(f"gain_form must be 'predictor' or 'filter', got {gain_form!r}")
        else:
            if sample_time is not None:
                raise StructureError("a continuous observer has no sample time")
            if gain_form not in ("predictor", "continuous"):  # the default, or the form a continuous gain has
                # a filter-form K was taken as x' = F x + B u + K (y - H x) without a word
                raise StructureError(f"gain_form {gain_form!r} applies to discrete observers only; a continuous "
                                     "observer's gain is that of x' = F x + B u + K (y - H x)")
            gain_form = "continuous"
        self.F, self.B, self.H, self.K = F, B, H, K
        self.domain, self.sample_time, self.gain_form, self.name = domain, sample_time, gain_form, name
        self.variable = s if domain == "s" else z
        self.output = _matrix("output", output if output is not None else [[1] + [0] * (n - 1)], 1, n)
        self.sensors = self._check_sensors(_sensor_tuple(sensors))
        if domain == "s":
            continuous = (F, B)
        elif continuous is not None:
            continuous = (_matrix("Fc", continuous[0], n, n), _matrix("Bc", continuous[1], n, B.shape[1]))
        self.continuous = continuous

    @classmethod
    def from_statespace(cls, sys, K, sensors, *, gain_form="predictor", name=None) -> Observer:
        """An observer of the model of a ``control.StateSpace``: ``F = A``, ``B``, ``H = C``.

        Continuous systems (``dt = 0``) give an ``s`` observer; discrete ones a ``z`` observer
        with ``sample_time = dt``.  ``D`` must be zero (the engine's measurements read the
        state only).

        Parameters
        ----------
        sys : control.StateSpace
            The model: continuous (``dt = 0``) or discrete (``dt`` in seconds), any number of
            inputs and outputs.  Each entry is taken as the simplest rational within two ulp of
            its double, so that a model sampled by ``control.c2d`` (``B = 0.012999999999999999``
            for an integrator at 0.013 s) is the exact sampled chain its bands are proved for.
        K : array_like
            The gain (sympy symbols or numbers; a numpy array from ``control.lqe`` or
            ``control.dlqe`` too, each float taken as the decimal it prints as), shape
            (states, outputs).
        sensors : sequence of Sensor
            One per input (column of ``B``) and per output (row of ``C``).
        gain_form : {'predictor', 'filter'}
            Discrete systems only (``'filter'`` for a continuous one is a StructureError).
        name : str, optional
            Label (default: the system's name).

        Returns
        -------
        Observer
            The observer of ``sys`` with gain ``K`` and the given sensors.

        Raises
        ------
        StructureError
            ``sys`` is not a state-space system, has a complex entry, a feedthrough or an unspecified
            sample time (``dt=True``); ``K`` is not (states x outputs); the sensors do not cover
            every input and output exactly once; or its inputs and outputs carry names of their own
            (not python-control's ``u[i]`` / ``y[i]``) that differ from the sensors' names at
            the same column of ``B`` or row of ``C``.
        GainError
            An entry that is not finite.

        Notes
        -----
        Named signals (``control.ss(..., inputs=['gyro'], outputs=['compass'])``) are checked
        against the sensors, so a sensor cannot silently read another signal's column.

        Examples
        --------
        >>> import control, sympy as sp
        >>> from cfdesign import Observer, Sensor
        >>> sys = control.ss([[0]], [[1]], [[1]], [[0]], inputs=["gyro"], outputs=["compass"], name="heading")
        >>> obs = Observer.from_statespace(sys, [[sp.Symbol("k")]],
        ...                                [Sensor.input("gyro", "rate"), Sensor.measurement("compass", "angle", 0)])
        >>> obs.name, obs.proof().holds
        ('heading', True)
        """
        import control

        if not isinstance(sys, control.StateSpace):
            raise StructureError(f"from_statespace needs a control.StateSpace, got {type(sys).__name__} "
                                 "(control.ss(tf) converts a transfer function)")
        if np.any(np.asarray(sys.D) != 0):
            raise StructureError(f"{sys.name}: D must be zero (measurements read the state, no feedthrough)")
        if sys.dt is True:
            raise StructureError(f"{sys.name}: discrete with an unspecified sample time (dt=True); give dt in seconds")
        sensors = _sensor_tuple(sensors)
        _check_signal_names(sys, sensors)
        discrete = bool(sys.dt)

        def to_exact(label, M):
            M = np.asarray(M)
            if np.iscomplexobj(M):  # float() of a complex entry raised a raw TypeError
                if np.any(M.imag != 0):
                    i, j = np.argwhere(M.imag != 0)[0]
                    raise StructureError(f"{sys.name}: {label}[{i}][{j}] is complex ({M[i, j]}); the model is real")
                M = M.real
            return [[model_number(float(v), f"{label} entry") for v in row] for row in M]

        return cls(to_exact("A", sys.A), to_exact("B", sys.B), to_exact("C", sys.C), K, sensors,
                   domain="z" if discrete else "s",
                   sample_time=model_number(float(sys.dt), "dt") if discrete else None,  # as the entries
                   gain_form=gain_form, name=name or sys.name)

    # ------------------------------------------------------------------ structure
    def _check_sensors(self, sensors):
        names = [x.name for x in sensors]
        dup = {x for x in names if names.count(x) > 1}
        if dup:
            raise StructureError(f"duplicate sensor name(s): {', '.join(sorted(dup))}")
        for x in sensors:
            if x.bias_state is not None and x.bias_state >= self.n_states:
                raise StructureError(f"sensor {x.name!r}: bias_state {x.bias_state} is not a state index")
        for role, count, what in (("input", self.B.shape[1], "column of B"),
                                  ("measurement", self.H.shape[0], "row of H")):
            idx = sorted(x.index for x in sensors if x.role == role)
            if idx != list(range(count)):
                raise StructureError(f"every {what} needs exactly one {role} sensor "
                                     f"(have {count}, sensors use {idx})")
        return sensors

    @property
    def n_states(self) -> int:
        """Number of states ``n``."""
        return self.F.shape[0]

    @property
    def discrete(self) -> bool:
        """True for a discrete (``z``) observer."""
        return self.domain == "z"

    @cached_property
    def chain_order(self) -> int:
        """Order of the kinematic chain: the highest derivative any sensor reads."""
        return max(x.order for x in self.sensors)

    @cached_property
    def parameters(self) -> tuple[sp.Symbol, ...]:
        """Free symbols other than ``s``/``z``: the gains, then the sample time if symbolic."""
        free = set().union(*(M.free_symbols for M in (self.F, self.B, self.H, self.K)))
        if self.discrete:
            free.discard(self.sample_time)
        ordered = sorted(free, key=lambda x: x.name)
        if self.discrete and isinstance(self.sample_time, sp.Symbol):
            ordered.append(self.sample_time)
        return tuple(ordered)

    @property
    def _sample_time_symbol(self):
        return self.sample_time if self.discrete and isinstance(self.sample_time, sp.Symbol) else None

    @property
    def gains(self) -> tuple[str, ...]:
        """Names of the symbolic gains still to be given numbers."""
        return tuple(p.name for p in self.parameters if p is not self._sample_time_symbol)

    def symbol(self, name: str) -> sp.Symbol:
        """The sympy symbol of one parameter.

        Parameters
        ----------
        name : str
            A gain name or ``'T'``.

        Returns
        -------
        sympy.Symbol
            The symbol named ``name`` in this observer's expressions.

        Raises
        ------
        GainError
            No parameter of that name (the message lists them).
        """
        for p in self.parameters:
            if p.name == name:
                return p
        known = ", ".join(map(str, self.parameters)) or "none"
        raise GainError(f"{self.name} has no parameter {name!r} (parameters: {known})")

    def relation(self, sensor: Sensor):
        """The relation ``D(v)`` with ``reading = D * quantity`` of one sensor.

        ``v**order`` when continuous, :func:`discrete_relation` when discrete, or the sensor's
        own ``relation``.

        Parameters
        ----------
        sensor : Sensor
            The sensor whose relation to the common quantity is wanted.

        Returns
        -------
        sympy expression
            ``D(v)`` in the observer's variable (``s`` or ``z``).

        Raises
        ------
        StructureError
            The sensor's relation is not a sympy expression (text is never evaluated).
        """
        if sensor.relation is not None:
            if not isinstance(sensor.relation, sp.Basic):
                raise StructureError(f"sensor {sensor.name!r}: relation must be a sympy expression "
                                     f"(text is never evaluated), got {type(sensor.relation).__name__}")
            return sensor.relation
        if not self.discrete:
            return s ** sensor.order
        return discrete_relation(sensor.order, self.chain_order, self.sample_time)

    # ------------------------------------------------------------------ the algebra
    @cached_property
    def _routes(self):
        """Closed-loop A, output C_o, and per sensor (B_i, D_i): the state-space routes."""
        F, B, H, K, C = self.F, self.B, self.H, self.K, self.output
        if self.gain_form == "filter":
            IKH = sp.eye(self.n_states) - K * H
            A, Co, Bz, Dz = F * IKH, C * IKH, F * K, C * K
        else:
            A, Co, Bz, Dz = F - K * H, C, K, sp.zeros(1, K.shape[1])
        routes = {}
        for x in self.sensors:
            if x.role == "input":
                routes[x.name] = (B[:, x.index], sp.Integer(0))
            else:
                routes[x.name] = (Bz[:, x.index], Dz[0, x.index])
        return A, Co, routes

    @cached_property
    def characteristic_polynomial(self):
        """``det(vI - A_cl)``, expanded: the common denominator of every band."""
        return sp.expand(self._resolvent[1])

    @cached_property
    def _resolvent(self):
        A, _, _ = self._routes
        M = self.variable * sp.eye(self.n_states) - A
        return M.adjugate(method="berkowitz"), M.det(method="berkowitz")

    @cached_property
    def bands(self) -> dict:
        """Band transfer functions ``{sensor name: T_i(v)}`` against the common quantity."""
        _, Co, routes = self._routes
        adj, det = self._resolvent
        v = self.variable
        out = {}
        for x in self.sensors:
            Bi, Di = routes[x.name]
            num = sp.expand((Co * adj * Bi)[0, 0] + Di * det)
            rel_num, rel_den = sp.fraction(sp.cancel(self.relation(x)))
            num, den = sp.fraction(sp.cancel(num * rel_num / (sp.expand(det) * rel_den)))
            lead = sp.Poly(den, v).LC()
            if lead.is_number:
                num, den = sp.expand(num / lead), sp.expand(den / lead)
            out[x.name] = _display(num, v) / sp.collect(sp.expand(den), v)
        return out

    @cached_property
    def relations_follow_the_model(self) -> bool:
        """Whether the sensors' relations are a trajectory of the model: the proof for every gain.

        With ``X(v) = (vI - F)^-1 sum_inputs B_i D_i(v)`` (the state the exact inputs drive),
        the relations follow the model when ``H_j X = D_j`` for every measurement ``j`` and
        ``C X = 1``.  Then ``X`` is what the observer's state becomes for exact readings, in
        predictor form (``(vI - F + K H) X = sum_i B_i D_i + K H X``) and in filter form
        alike, so ``sum_i T_i = C X = 1`` for every ``K``: no gain enters the check
        (``docs/derivations.md``, "Bands, and why they sum to one").  A False leaves the
        question to :attr:`residual_numerator`.

        Returns
        -------
        bool
            True when every relation is the model's (each difference cancels to zero).
        """
        return all(sp.cancel(got - want) == 0 for _, got, want in self.model_readings())

    def model_readings(self, F=None, B=None, relation=None, variable=None) -> list:
        """What the model makes of exact readings: each measurement and the estimate, beside its relation.

        ``X(v) = (vI - F)^-1 sum_inputs B_i D_i(v)`` is the state exact inputs drive; the
        estimate reads ``C X`` (wanted: ``1``, the common quantity itself) and measurement ``j``
        reads ``H_j X`` (wanted: its relation ``D_j``).  Every pair equal is
        :attr:`relations_follow_the_model`; a pair that differs says which relation the model
        does not follow.

        Parameters
        ----------
        F, B : sympy.Matrix, optional
            Another model to drive (default: the observer's), of the same shapes.
        relation : callable, optional
            ``relation(sensor) -> D(v)`` (default: :meth:`relation`).
        variable : sympy.Symbol, optional
            The variable ``v`` of ``relation`` (default: the observer's).

        Returns
        -------
        list of (Sensor or None, sympy expression, sympy expression)
            ``(None, C X, 1)`` first, then ``(sensor, H_j X, D_j)`` per measurement, each
            reduced with ``sympy.cancel``.
        """
        F = self.F if F is None else F
        B = self.B if B is None else B
        relation = relation or self.relation
        v = variable or self.variable
        drive = sp.zeros(self.n_states, 1)
        for x in self.sensors:
            if x.role == "input":
                drive += B[:, x.index] * relation(x)
        X = (v * sp.eye(self.n_states) - F).LUsolve(drive).applyfunc(sp.cancel)
        rows = [(None, (self.output * X)[0, 0], sp.Integer(1))]
        rows += [(x, (self.H[x.index, :] * X)[0, 0], relation(x)) for x in self.sensors if x.role != "input"]
        return [(x, sp.cancel(got), want) for x, got, want in rows]

    @cached_property
    def residual_numerator(self):
        """The numerator of ``sum_i T_i(v) - 1`` over one common denominator, expanded.

        With ``T_i = (C adj(vI - A) B_i + D_i det(vI - A)) D_i(v) / det(vI - A)`` (``D_i = n_i /
        d_i`` the sensor's relation, :meth:`relation`) and ``L = lcm(d_i)``,
        ``sum_i T_i - 1 = N / (det(vI - A) L)`` with
        ``N = sum_i (C adj B_i + D_i det) n_i L / d_i - det L``: the bands sum to one for every
        value of the variable and the parameters exactly when ``N`` expands to zero
        (``docs/derivations.md``, "One observer").  No band is brought to lowest terms, so this
        is far cheaper than the bands in lowest terms for large symbolic gain matrices.

        Returns
        -------
        sympy expression
            ``N``, expanded (the integer ``0`` when the bands are complementary).
        """
        _, Co, routes = self._routes
        adj, det = self._resolvent
        parts = []
        for x in self.sensors:
            Bi, Di = routes[x.name]
            rel_num, rel_den = sp.fraction(sp.cancel(self.relation(x)))
            parts.append(((Co * adj * Bi)[0, 0] + Di * det, rel_num, rel_den))
        common = sp.Integer(1)
        for *_, rel_den in parts:
            common = sp.lcm(common, rel_den)
        total = sum(num * rel_num * sp.cancel(common / rel_den) for num, rel_num, rel_den in parts)
        return sp.expand(total - det * common)

    def band_fraction(self, name: str):
        """One band as a numerator and denominator.

        Parameters
        ----------
        name : str
            Sensor name.

        Returns
        -------
        num, den : sympy expression
            Expanded polynomials in the variable.

        Raises
        ------
        StructureError
            No sensor of that name.
        """
        num, den = sp.fraction(sp.cancel(self.bands[self._band_name(name)]))
        return sp.expand(num), sp.expand(den)

    def _band_name(self, name):
        if name not in self.bands:
            raise StructureError(f"{self.name} has no sensor {name!r} (sensors: {', '.join(self.bands)})")
        return name

    def proof(self):
        """Exact complementarity proof: ``sum_i T_i(v) - 1`` reduced to canonical form.

        ``sympy.cancel`` brings a rational function to the unique form ``p/q`` with coprime
        expanded polynomials, so the residual is the zero expression exactly when the identity
        holds for every value of ``v`` and of the symbolic gains.

        Returns
        -------
        Proof
            The bands, their sum and the residual in canonical form; ``holds`` tells whether they
            sum to one.

        Examples
        --------
        >>> import cfdesign
        >>> cfdesign.ckf3().proof().holds
        True
        """
        from .proof import prove

        return prove(self)

    # ------------------------------------------------------------------ poles and zeros
    def poles(self) -> list:
        """Roots of the characteristic polynomial ``det(vI - A_cl)``.

        Returns
        -------
        list of sympy expression
            Repeated by multiplicity; symbolic when gains are.

        Raises
        ------
        ProofError
            The roots cannot be found in closed form.
        """
        return _roots(self.characteristic_polynomial, self.variable, f"poles of {self.name}")

    def zeros(self) -> dict:
        """Roots of every band's numerator.

        Returns
        -------
        dict
            ``{sensor: list of roots}``, repeated by multiplicity.

        Raises
        ------
        ProofError
            The roots cannot be found in closed form.

        Examples
        --------
        >>> import cfdesign
        >>> cfdesign.cf2().zeros()
        {'rate': [0], 'angle': []}
        """
        return {name: _roots(self.band_fraction(name)[0], self.variable, f"zeros of band {name!r}")
                for name in self.bands}

    # ------------------------------------------------------------------ numbers
    def subs(self, values: dict | None = None, /, **kwargs) -> Observer:
        """A copy with numbers for some or all parameters.

        Values are taken exactly: ``0.1`` becomes ``1/10`` so that a proof on the result is
        still exact.

        Parameters
        ----------
        values : dict, optional
            ``{name: number}``: gains by name (or by their sympy symbols, ``f.symbol("k1")``), ``'T'``
            for the sample time (s); numbers are ints, floats, numpy scalars, Fractions, Decimals or
            sympy numbers.
        **kwargs : float
            More ``name=number`` pairs.

        Returns
        -------
        Observer
            A new observer; this one is unchanged.

        Raises
        ------
        GainError
            An unknown name, a value that is not a number, a sample time that is not positive.

        Examples
        --------
        >>> import cfdesign
        >>> cfdesign.cf2().subs(k=0.5).bands
        {'rate': s/(s + 1/2), 'angle': 1/(2*(s + 1/2))}
        """
        values = self._named_values(values, kwargs)
        params = {p.name: p for p in self.parameters}
        unknown = sorted(set(values) - set(params))
        if unknown:
            raise GainError(f"{self.name} has no parameter(s) {', '.join(unknown)} "
                            f"(parameters: {', '.join(params) or 'none'})")
        mapping = {params[k]: exact_number(v, k) for k, v in values.items()}
        sample_time = self.sample_time
        if self._sample_time_symbol in mapping:
            sample_time = mapping[self._sample_time_symbol]
            if sample_time <= 0:
                raise GainError(f"sample time {self._sample_time_symbol} must be positive, got {sample_time}")
        sensors = [Sensor(x.name, x.order, x.role, x.index,
                          None if x.relation is None else x.relation.subs(mapping), x.bias_state)
                   for x in self.sensors]
        return self._replace(*(M.subs(mapping) for M in (self.F, self.B, self.H, self.K)), sensors=sensors,
                             sample_time=sample_time, output=self.output.subs(mapping))

    def _named_values(self, values, kwargs) -> dict:
        """``{name: value}`` from a dict (keys: names or the sympy symbols) and keyword pairs."""
        params = ", ".join(p.name for p in self.parameters) or "none"
        if values is None:
            values = {}
        if not isinstance(values, Mapping):  # with_gains(2): a raw "'int' object is not a mapping"
            raise GainError(f"{self.name}: give the values by name, as name=number pairs or a dict "
                            f"{{name: number}}, not {type(values).__name__} {values!r:.40} (parameters: {params})")
        named = {}
        for key, value in values.items():
            if isinstance(key, sp.Symbol):  # {k11: 0.3} with the symbols of f.parameters: taken by name
                key = key.name
            if not isinstance(key, str):
                raise GainError(f"{self.name}: a parameter is named by its name (str) or its sympy symbol, got "
                                f"{key!r:.40} (parameters: {params})")
            if key in named:
                raise GainError(f"{self.name}: {key} is given twice")
            named[key] = value
        for key, value in kwargs.items():
            if key in named:
                raise GainError(f"{self.name}: {key} is given twice")
            named[key] = value
        return named

    def renamed(self, names: dict, name: str | None = None) -> Observer:
        """The same observer with sensors renamed (e.g. a physical sensor in a port).

        Parameters
        ----------
        names : dict
            ``{old name: new name}``.
        name : str, optional
            New label of the observer.

        Returns
        -------
        Observer
            A new observer with the sensors (and label) renamed.

        Raises
        ------
        StructureError
            An old name that is not a sensor of the observer.
        """
        unknown = sorted(set(names) - {x.name for x in self.sensors})
        if unknown:
            raise StructureError(f"{self.name} has no sensor(s) {', '.join(unknown)}")
        sensors = [Sensor(names.get(x.name, x.name), x.order, x.role, x.index, x.relation, x.bias_state)
                   for x in self.sensors]
        obs = self._replace(self.F, self.B, self.H, self.K, sensors=sensors)
        obs.name = name or self.name
        return obs

    def _replace(self, F, B, H, K, *, sensors=None, sample_time=None, gain_form=None, output=None) -> Observer:
        """A new observer with the given matrices, keeping everything not given."""
        return Observer(F, B, H, K, self.sensors if sensors is None else sensors, domain=self.domain,
                        sample_time=(sample_time if sample_time is not None else self.sample_time)
                        if self.discrete else None,
                        gain_form=gain_form or (self.gain_form if self.discrete else "predictor"),
                        name=self.name, output=self.output if output is None else output,
                        continuous=self.continuous if self.discrete else None)

    def with_gains(self, values: dict | None = None, /, **kwargs) -> Observer:
        """Like :meth:`subs`, but every parameter must be given: the result is fully numeric.

        Parameters
        ----------
        values : dict, optional
            ``{name: number}`` for every gain (and ``'T'`` when the sample time is symbolic); keys as
            in :meth:`subs`.
        **kwargs : float
            More ``name=number`` pairs.

        Returns
        -------
        Observer
            A new observer with no free parameter.

        Raises
        ------
        GainError
            A parameter is missing, unknown or not a number.

        Examples
        --------
        >>> import cfdesign
        >>> g = cfdesign.cf2().with_gains(k=2)
        >>> g.bands, g.poles()
        ({'rate': s/(s + 2), 'angle': 2/(s + 2)}, [-2])
        """
        values = self._named_values(values, kwargs)
        missing = [p.name for p in self.parameters if p.name not in values]
        if missing:
            raise GainError(f"{self.name} needs a value for {', '.join(missing)}")
        return self.subs(values)

    def gain_pattern(self) -> list:
        """The gain matrix as nested lists.

        Returns
        -------
        list of list
            The gain's name (str) where an entry is a free symbol, else its value (float).
        """
        return [[e.name if isinstance(e, sp.Symbol) else float(e) for e in self.K.row(i)]
                for i in range(self.K.rows)]

    def numeric_model(self, sample_time=None) -> dict:
        """The model as float arrays.

        Parameters
        ----------
        sample_time : float, optional
            Sample time (s) substituted when it is symbolic (discrete observers).

        Returns
        -------
        dict
            ``F, B, H`` and, when known, the continuous ``Fc, Bc``.

        Raises
        ------
        GainError
            A discrete observer without a sample time, or a model with free parameters.
        """
        mapping = {}
        if self.discrete and isinstance(self.sample_time, sp.Symbol):
            if sample_time is None:
                raise GainError(f"{self.name} is discrete: give the sample time")
            mapping[self.sample_time] = exact_number(sample_time, "sample time")
            if mapping[self.sample_time] <= 0:  # T = 0 gave B = 0 and F = I without a word
                raise GainError(f"{self.name}: sample time must be positive (s), got {sample_time!r}")
        out = {k: M.subs(mapping) for k, M in (("F", self.F), ("B", self.B), ("H", self.H))}
        if self.continuous is not None:
            out["Fc"], out["Bc"] = self.continuous
        try:
            return {k: np.array(M.evalf(17), dtype=float) for k, M in out.items()}
        except TypeError:
            raise GainError(f"{self.name}: the model still has free parameters") from None

    def with_gain_matrix(self, K, gain_form: str | None = None, sample_time=None) -> Observer:
        """A numeric copy with a given gain matrix.

        Parameters
        ----------
        K : array_like
            Gain, shape (n, m), numbers (taken exactly).
        gain_form : {'predictor', 'filter'}, optional
            Another discrete gain form for ``K``.
        sample_time : float, optional
            Sample time (s) substituted when it is symbolic.

        Returns
        -------
        Observer
            A new, fully numeric observer with gain ``K`` (in ``gain_form``).
        """
        obs = self
        if sample_time is not None and self._sample_time_symbol is not None:
            obs = self.subs({self._sample_time_symbol.name: sample_time})
        K = _matrix("K", K, self.n_states, self.H.shape[0])  # shape and finiteness; a ragged K or a scalar named
        K = K.applyfunc(lambda e: exact_number(e, "K entry"))  # numbers only: no symbol left
        return obs._replace(obs.F, obs.B, obs.H, K, gain_form=gain_form)

    @property
    def is_numeric(self) -> bool:
        """True when no parameter is left symbolic."""
        return not self.parameters

    def band_coefficients(self) -> dict:
        """Every band as float coefficient arrays.

        Returns
        -------
        dict
            ``{sensor: (num, den)}``, highest power first.

        Raises
        ------
        GainError
            The observer still has symbolic parameters.
        """
        if not self.is_numeric:
            raise GainError(f"{self.name} still has symbolic parameters "
                            f"{', '.join(p.name for p in self.parameters)}: substitute numbers first")
        return {name: _coefficients(self.bands[name], self.variable) for name in self.bands}

    def sum_coefficients(self) -> tuple:
        """The exact sum of the bands as float coefficient arrays.

        Returns
        -------
        num, den : ndarray
            ``([1.], [1.])`` when the bands are complementary.

        Raises
        ------
        GainError
            The observer still has symbolic parameters.
        """
        self.band_coefficients()  # same numeric-only check
        return _coefficients(self.proof().total, self.variable)

    def __repr__(self):
        if self.discrete:  # the sample time with its unit ('T=1/5' read as a bare number), or symbolic
            T = self.sample_time
            when = f"T = {T} (symbolic)" if isinstance(T, sp.Symbol) else f"T = {float(T):.12g} s"
            kind = f"discrete, {when}, {self.gain_form} gains"
        else:
            kind = "continuous"
        sensors = ", ".join(f"{x.name}({x.role}, order {x.order})" for x in self.sensors)
        return f"<Observer {self.name}: {kind}; sensors {sensors}>"

    def _repr_latex_(self):
        rows = r" \\ ".join(rf"T_{{\mathrm{{{k}}}}}({self.variable}) &= {sp.latex(v)}" for k, v in self.bands.items())
        return rf"$\begin{{aligned}}{rows}\end{{aligned}}$"


def _coefficients(expr, var):
    """Float coefficient arrays ``(num, den)``, highest power first, of a rational function."""
    num, den = (sp.Poly(p, var) for p in sp.fraction(sp.cancel(expr)))
    lead = den.LC()
    out = tuple(np.array([float(c / lead) for c in p.all_coeffs()]) for p in (num, den))
    if not all(np.all(np.isfinite(c)) for c in out):
        raise GainError("the gains give band coefficients that overflow double precision")
    return out


def _display(num, var):
    """A readable numerator: factored (shows the zeros) unless that adds a sign or a fraction."""
    factored = sp.factor(num)
    if factored.could_extract_minus_sign() or factored.as_coeff_Mul()[0] != 1:
        return sp.collect(sp.expand(num), var)
    return factored


def _roots(poly_expr, var, what):
    poly = sp.Poly(poly_expr, var)
    if poly.degree() <= 0:
        return []
    if poly.free_symbols - {var} or not any(c.has(sp.Float) for c in poly.all_coeffs()):
        found = sp.roots(poly)
        if sum(found.values()) == poly.degree():
            return [r for r, mult in found.items() for _ in range(mult)]
        if poly.free_symbols - {var}:
            raise ProofError(f"{what}: degree {poly.degree()} polynomial with symbolic coefficients "
                             "has no closed-form roots; substitute numbers for the gains first")
    return list(poly.nroots(n=15))
