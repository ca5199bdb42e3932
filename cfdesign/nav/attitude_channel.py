"""One attitude channel: the designed discrete ``cf2`` (order 2) that both attitude filters run.

Each channel (an Euler angle in :class:`~cfdesign.nav.EulerAttitudeFilter`, an ENU error
component in :func:`~cfdesign.nav.estimate_attitude`) is the chain of Vasconcelos et al.
Sec. 2.1 with the gyro as its rate input and the Magneto-Pendular Sensor as its angle
measurement (derivation: ``docs/derivations.md``)::

    λ[k+1] = λ[k] + T (u[k] + c[k]),   c[k+1] = c[k]          (c = -b, the rate correction)
    F = [[1, T], [0, 1]],   B = [T, 0]^T,   H = [1, 0]

with the update (filter-form) gains ``λ+ = λ- + k1 e``, ``c+ = c- + k2 e`` (``k2`` in 1/s).
Two tables drive a filter: one for the tilt channels (pitch, roll; x, y) and one for heading.

Where the gains come from:

* by default :func:`design_channel` designs them from the sensors' noise figures with the
  numeric design stage on the stored structure ``cf2-order2-discrete``
  (:mod:`cfdesign.nav.stored_design`: Van Loan, DARE; no sympy), cached;
* a user's own design: any :class:`~cfdesign.gains.GainTable` of this model (a filter- or
  predictor-form table: the update gain is taken with :func:`cfdesign.linear.gain_pair`), or
  a :class:`~cfdesign.spec.FilterSpec` of structure ``cf2`` order 2, discrete.
  :func:`channel_gains` checks that it fits the filter's sample time.
"""

from __future__ import annotations

import functools

import numpy as np

from .. import linear
from ..errors import AttitudeInputError, TableMismatchError
from ..spec import parse_spec
from .attitude_inputs import positive, rate
from .stored_design import as_table, check_fits, design_stored

__all__ = ["STRUCTURE", "channel_spec", "design_channel", "channel_tables", "channel_gains", "gain_schedule"]

#: the stored structure of a channel
STRUCTURE = "cf2-order2-discrete"
_MODEL = "the cf2 chain (order 2): states [angle, rate correction], a rate input, an angle measurement"


def channel_spec(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std):
    """The design spec of one channel: ``cf2`` order 2, discrete, filter gain form, at ``rate_hz``.

    Two sensors at the same rate: ``rate``, the gyro (white noise and a random-walk bias), and
    ``angle``, the angle reading (white noise).  :func:`design_channel` designs it without
    sympy; ``cfdesign.design(channel_spec(...))`` gives the same table.

    Parameters
    ----------
    rate_hz : float
        Sample rate of the gyro and of the angle reading (Hz).
    gyro_noise_std : float
        Gyro white noise, rad/s per sample (std at ``rate_hz``: density times ``sqrt(rate_hz)``).
    gyro_bias_density : float
        Random walk of the gyro bias, rad/s/sqrt(s); positive.
    angle_noise_std : float
        Noise of the angle reading (e.g. the Magneto-Pendular Sensor's), rad per sample.

    Returns
    -------
    FilterSpec
        The spec named ``attitude channel``, structure ``cf2``, order 2, discrete.

    Raises
    ------
    SpecError
        A figure the spec rejects (a rate that is not positive, a negative noise std, a bias
        density that is not positive); the message names the field.

    Notes
    -----
    The units are those of an attitude channel; :class:`~cfdesign.nav.AttitudeFilter` uses the
    same chain for its velocity channel in m/s², m/s²/sqrt(s) and m/s.

    Examples
    --------
    >>> from cfdesign.nav.attitude_channel import channel_spec
    >>> spec = channel_spec(100.0, 0.002, 1e-5, 0.05)
    >>> spec.structure, spec.order, spec.discrete, spec.gain_form
    ('cf2', 2, True, 'filter')
    """
    return parse_spec({
        "name": "attitude channel", "structure": "cf2", "order": 2, "discrete": True, "gain_form": "filter",
        "sensors": {
            "rate": {"measures": "rate", "rate_hz": rate_hz, "noise": {"std": gyro_noise_std},
                     "bias": {"model": "random_walk", "density": gyro_bias_density}},
            "angle": {"measures": "angle", "rate_hz": rate_hz, "noise": {"std": angle_noise_std}},
        }})


@functools.lru_cache(maxsize=64)
def _design_cached(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std):
    return design_stored(channel_spec(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std), STRUCTURE)


def design_channel(rate_hz, gyro_noise_std, gyro_bias_density, angle_noise_std):
    """Gains of one attitude channel from noise figures, designed without sympy.

    :func:`~cfdesign.nav.attitude_channel.channel_spec` designed by the numeric stage alone.  The
    DARE of the model in the module docstring gives the filter-form gain ``[k1, k2]``
    (``table.gains``), the same as ``cfdesign.design(channel_spec(...))`` bit for bit, from the
    numeric design stage on the stored structure :data:`~cfdesign.nav.attitude_channel.STRUCTURE`
    (Van Loan discretisation, DARE).  Cached: equal arguments return the same
    :class:`~cfdesign.gains.GainTable`.

    Parameters
    ----------
    rate_hz : float
        Sample rate of the channel (Hz).
    gyro_noise_std : float
        Gyro white noise, rad/s per sample.
    gyro_bias_density : float
        Random walk of the gyro bias, rad/s/sqrt(s).
    angle_noise_std : float
        Noise of the angle reading, rad per sample.

    Returns
    -------
    GainTable
        The discrete filter-form table at ``1 / rate_hz``: ``gains`` is ``{'k1': .., 'k2': ..}``
        (``k1`` dimensionless, ``k2`` in 1/s), with the model ``F, Q, R`` and the DARE
        covariance ``P``.

    Raises
    ------
    AttitudeInputError
        A rate outside [1e-3, 1e6] Hz, or a figure that is not a finite positive number up to
        1e100 (checked before the design); the message names it.

    Examples
    --------
    >>> from cfdesign.nav import design_channel
    >>> table = design_channel(100.0, 0.002, 1e-5, 0.05)
    >>> round(table.gains["k1"], 6), round(table.gains["k2"], 8)
    (0.000748, 1.999e-05)
    >>> table is design_channel(100.0, 0.002, 1e-5, 0.05)
    True
    """
    figures = {"gyro_noise_std": gyro_noise_std, "gyro_bias_density": gyro_bias_density,
               "angle_noise_std": angle_noise_std}
    rate_hz = rate(rate_hz)
    for name, value in figures.items():
        figures[name] = positive(name, value)
        if figures[name] > _MAX_FIGURE:
            raise AttitudeInputError(f"{name} must be at most {_MAX_FIGURE:g} (its square is a variance), "
                                     f"got {value!r}")
    return _design_cached(rate_hz, *figures.values())


#: the largest noise figure a channel is designed from (a design file's limit: its square is finite)
_MAX_FIGURE = 1e100


def channel_tables(tables, given, design_pair):
    """``(tilt, heading)`` tables: from ``tables`` or, without them, ``design_pair()`` of the noise figures.

    Parameters
    ----------
    tables : pair or None
        ``(tilt, heading)``, each a GainTable or a FilterSpec (designed here).
    given : list of str
        Names of the noise figures the caller was given: giving both tables and noise
        figures is an error.
    design_pair : callable
        Designs ``(tilt, heading)`` from the noise figures.

    Returns
    -------
    tuple
        ``(tilt, heading)``: ``design_pair()`` without ``tables``, else the two tables as
        :class:`~cfdesign.gains.GainTable` (a spec is designed on
        :data:`~cfdesign.nav.attitude_channel.STRUCTURE`).  Whether a table fits the filter's
        model and sample time is :func:`channel_gains`'s check.

    Raises
    ------
    AttitudeInputError
        ``tables`` and noise figures (``given`` not empty) both given.
    TableMismatchError
        ``tables`` is not a pair, an entry is neither a GainTable nor a FilterSpec, or a spec
        is not the ``cf2`` order-2 discrete channel.

    Examples
    --------
    >>> from cfdesign.nav import design_channel
    >>> from cfdesign.nav.attitude_channel import channel_tables
    >>> tilt = design_channel(100.0, 0.002, 1e-5, 0.05)
    >>> channel_tables((tilt, tilt), [], None) == (tilt, tilt)
    True
    >>> channel_tables((tilt, tilt), ["gyro_noise_std"], None)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: give either tables or the noise figures (gyro_noise_std), not both
    """
    if tables is None:
        return design_pair()
    if given:
        raise AttitudeInputError(f"give either tables or the noise figures ({', '.join(given)}), not both")
    try:
        tilt, heading = tables
    except (TypeError, ValueError, OverflowError):
        raise TableMismatchError("tables: a pair (tilt, heading) of GainTables or FilterSpecs is needed") from None
    return as_table(tilt, STRUCTURE, "tables[0] (tilt)"), as_table(heading, STRUCTURE, "tables[1] (heading)")


def channel_gains(table, what: str, sample_time_s: float, timing: str) -> tuple:
    """``(k1, k2)``: the update gains of a channel table, after checking it fits (module docstring).

    The table must be the discrete ``cf2`` order-2 channel (``F = [[1, T], [0, 1]]``,
    ``B = [T, 0]^T``, ``H = [1, 0]``, a rate input and an angle measurement) at the filter's
    sample time, period 1.  A predictor-form gain is turned into the update gain with
    :func:`cfdesign.linear.gain_pair`.

    Parameters
    ----------
    table : GainTable
        A filter- or predictor-form table of the channel (its first gain is used).
    what : str
        How the error message names the table (``tables[0] (tilt)``).
    sample_time_s : float
        The filter's sample time ``T`` (s).
    timing : str
        Where the sample time comes from, for the message (``rate_hz 100 Hz``).

    Returns
    -------
    tuple of float
        ``(k1, k2)``, the update gains ``λ+ = λ- + k1 e``, ``c+ = c- + k2 e`` (``k2`` in 1/s).

    Raises
    ------
    TableMismatchError
        A continuous table, other shapes or sensor orders, another sample time or period, or
        other model matrices; the message names ``what`` and the difference.

    Examples
    --------
    >>> from cfdesign.nav import design_channel
    >>> from cfdesign.nav.attitude_channel import channel_gains
    >>> table = design_channel(100.0, 0.002, 1e-5, 0.05)
    >>> channel_gains(table, "tables[0] (tilt)", 0.01, "rate_hz 100 Hz") == (table.gains["k1"], table.gains["k2"])
    True
    >>> channel_gains(table, "tables[0] (tilt)", 0.005, "rate_hz 200 Hz")
    Traceback (most recent call last):
    ...
    cfdesign.errors.TableMismatchError: tables[0] (tilt): 'attitude channel' has sample time 0.01 s; ...
    """
    T = sample_time_s
    check_fits(table, what, F=[[1.0, T], [0.0, 1.0]], B=[[T], [0.0]], H=[[1.0, 0.0]], orders=(1, 0),
               sample_time_s=T, model=_MODEL, timing=timing)
    _, L = linear.gain_pair(table.F, table.K[0], table.gain_form)
    return float(L[0, 0]), float(L[1, 0])


def _is_kalman(table, gains) -> bool:
    """The gains are the Kalman gain of the table's own covariance, ``P H' (H P H' + R)^-1``."""
    P, r = np.asarray(table.P[0], dtype=float), float(table.R[0][0])
    kalman = P[:, 0] / (P[0, 0] + r)
    return bool(np.allclose(gains, kalman, rtol=1e-6, atol=0))


def gain_schedule(table, gains, bias_std0, steps, rtol=1e-3):
    """Start-up gains ``(k1[k], k2[k])`` of a channel table: its Kalman recursion from a prior.

    The filter-form Riccati recursion of the table's own ``F, Q, R`` (``H = [1, 0]``)::

        K = P⁻ Hᵀ (H P⁻ Hᵀ + R)⁻¹,  P⁺ = (I - K H) P⁻,  P⁻ ← F P⁺ Fᵀ + Q

    from ``P⁻ = diag(R, bias_std0²)``, run until the gain is within ``rtol`` of the table's
    gain ``gains = (k1, k2)`` (its DARE limit) or for ``steps`` steps; the last entry is the
    table's gain itself.  ``bias_std0 = 0``, or a table whose gains are not the Kalman gains of
    its ``P`` and ``R`` (fixed gains, which the recursion does not approach), returns the
    table's gain only.

    Parameters
    ----------
    table : GainTable
        A channel table (:func:`design_channel`) with its ``F``, ``Q``, ``R`` and ``P``.
    gains : pair of float
        The table's update gains ``(k1, k2)`` (:func:`channel_gains`).
    bias_std0 : float
        Prior std of the gyro bias (the rate correction), rad/s; the angle starts known to
        the reading's variance ``R``.
    steps : int
        Most recursion steps run (at least one).
    rtol : float
        Relative tolerance on both gains at which the recursion stops.

    Returns
    -------
    k1, k2 : list of float
        The gains of the steps from the first sample on, equal lengths (at most ``steps + 1``),
        each ending with the table's gain.

    Examples
    --------
    >>> from cfdesign.nav import design_channel
    >>> from cfdesign.nav.attitude_channel import gain_schedule
    >>> table = design_channel(100.0, 0.002, 1e-5, 0.05)
    >>> k1, k2 = gain_schedule(table, (table.gains["k1"], table.gains["k2"]), 0.0175, 1000)
    >>> k1[0], k1[-1] == table.gains["k1"], len(k1) == len(k2)
    (0.5, True, True)
    >>> gain_schedule(table, (0.3, 0.02), 0.0175, 1000)      # fixed gains: no schedule
    ([0.3], [0.02])
    """
    k1_inf, k2_inf = gains
    if bias_std0 == 0 or not _is_kalman(table, gains):
        return [k1_inf], [k2_inf]
    (f00, f01), (f10, f11) = table.F.tolist()
    (q00, q01), (_, q11) = table.Q.tolist()
    r = float(table.R[0][0])
    p00, p01, p11 = r, 0.0, bias_std0 ** 2
    k1s, k2s = [], []
    for _ in range(max(int(steps), 1)):
        s = p00 + r
        k1, k2 = p00 / s, p01 / s
        k1s.append(k1)
        k2s.append(k2)
        if abs(k1 - k1_inf) <= rtol * k1_inf and abs(k2 - k2_inf) <= rtol * k2_inf:
            break
        a00, a01, a11 = (1 - k1) * p00, (1 - k1) * p01, p11 - k2 * p01
        p00 = f00 * f00 * a00 + 2 * f00 * f01 * a01 + f01 * f01 * a11 + q00
        p01 = f00 * f10 * a00 + (f00 * f11 + f01 * f10) * a01 + f01 * f11 * a11 + q01
        p11 = f10 * f10 * a00 + 2 * f10 * f11 * a01 + f11 * f11 * a11 + q11
    k1s.append(k1_inf)
    k2s.append(k2_inf)
    return k1s, k2s
