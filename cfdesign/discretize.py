r"""A continuous gain table run at a sample rate: discretisation, and how it compares with re-designing.

A continuous table holds ``x' = F x + B u + K (y - H x)``.  To run it at ``f`` Hz,
:func:`discretize_table` keeps the model exact (zero-order hold of ``F, B``) and holds the
innovation over each step as it holds the input:

.. math::

    F_d = e^{F T},\qquad B_d = \Gamma B,\qquad K_p = \Gamma K,\qquad
    \Gamma = \int_0^T e^{F\tau}\,d\tau,

a predictor-form gain (the filter form is ``L = F_d^{-1} K_p``).  The bands of the result sum
to one exactly (the model is the ZOH model, so the structural argument of
``docs/derivations.md``, "One observer", holds), its poles are ``e^{\lambda T} + O(T^2)`` with
``lambda`` the continuous poles, and its bands follow the continuous ones well below Nyquist.

**Against re-designing at that rate** (``discrete = true`` in the design file): the DARE with
the exact discrete noise (Van Loan's ``Q_d``, per-sample ``R = PSD f``) gives the optimal gain
*for the sampled filter*; the discretised continuous gain is optimal only in the limit
``T -> 0`` (both tend to ``T K``).  At rates far above the filter's bandwidth the two agree to
``O(T)`` and discretising saves a design; near the bandwidth the sampling matters and the
re-designed gain has the lower error (both predicted errors are reported).  Discretise to run
a continuous design you must keep (a hand-tuned or published continuous filter); re-design
when you own the design file.

The predicted error of the result integrates the table's one continuous ``Q`` (the inputs'
noise and the bias walks together) by Van Loan: for an input driving more than one integrator
(an acceleration driving a position) that exceeds the held reading's ``B_d sigma^2 B_d^T`` the
re-design takes by a covariance, so the prediction errs on the safe side.

numpy and scipy only.
"""

from __future__ import annotations

import numbers
from dataclasses import replace

import numpy as np

from . import linear
from .errors import GainTableError
from .gains import MAX_RATE_HZ, GainTable, Schedule, SensorPort, require_table
from .noise import van_loan, zoh

__all__ = ["discretize_table", "innovation_hold"]


def innovation_hold(F, T: float) -> np.ndarray:
    """``Gamma = int_0^T e^{F tau} d tau``: the ZOH input matrix of an identity input.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous state matrix (1/s).
    T : float
        Sample time (s).

    Returns
    -------
    ndarray, shape (n, n)
        ``Gamma``: the integral of ``e^{F tau}`` over one sample time.
    """
    return zoh(F, np.eye(len(F)), T)[1]


def discretize_table(table: GainTable, rate_hz: float, gain_form: str = "predictor",
                     output: str | None = None) -> GainTable:
    """The continuous ``table`` discretised for ``rate_hz`` (module docstring).

    Parameters
    ----------
    table : GainTable
        A continuous table (``domain = 's'``).
    rate_hz : float
        The rate every sensor is read at (Hz).
    gain_form : {'predictor', 'filter'}
        Gain form of the discrete table: ``predictor`` or ``filter``.
    output : {'posterior', 'prior'}, optional
        Default: the posterior (the estimate after each step's readings).

    Returns
    -------
    GainTable
        ``F, B`` the ZOH model, ``K`` in the named form, ``Q`` by Van Loan, ``R`` per sample
        (``PSD * rate_hz``: at a rate other than the sensors' own, the noise of a reading averaged
        over each step, not of the sensor's readings as they come), the predicted covariances of
        these gains (Lyapunov), checked as ``cfdesign verify`` checks a table.

    Raises
    ------
    GainTableError
        The table is already discrete, its sensors run at different rates (``_check_single_rate``),
        the rate is not a positive number, or the gains do not stabilise the filter at that rate
        (the step is too long for the continuous gains).
    """
    require_table(table, "discretize_table")
    from .designer import _covariances, _numerically_checked

    if table.domain != "s":
        raise GainTableError(f"{table.name} is already discrete (T = {table.sample_time_s:g} s); discretize "
                             "takes a continuous table")
    if isinstance(rate_hz, (bool, np.bool_)) or not isinstance(rate_hz, numbers.Real) or not (
            1 / MAX_RATE_HZ <= rate_hz <= MAX_RATE_HZ):  # numpy's scalars are numbers.Real too
        raise GainTableError(f"--rate-hz must be a positive number of hertz (from {1 / MAX_RATE_HZ:g} to "
                             f"{MAX_RATE_HZ:g}), got {rate_hz!r}")
    rate_hz = float(rate_hz)
    if gain_form not in ("predictor", "filter"):
        raise GainTableError(f"gain form must be predictor or filter, got {gain_form!r}")
    _check_single_rate(table)
    T = 1.0 / rate_hz
    F, B = zoh(table.F, table.B, T)
    Kp = innovation_hold(table.F, T) @ table.K[0]
    if not all(np.isfinite(M).all() for M in (F, B, Kp)):
        raise GainTableError(f"{table.name}: at {rate_hz:g} Hz the discretised model overflows (expm(F T) is not "
                             "finite): the continuous model is far faster than the step")
    K = linear.gain_in_form(F, Kp, gain_form)
    eig = np.linalg.eigvals(linear.closed_loop(F, table.H, K, gain_form))
    if not linear.is_stable(eig, "z"):
        raise GainTableError(f"{table.name}: at {rate_hz:g} Hz the discretised gains do not stabilise the filter "
                             f"(spectral radius {np.abs(eig).max():.6g}); choose a faster rate or re-design at it")
    Q = van_loan(table.F, table.Q, T)[1]
    R = np.asarray(table.R) * rate_hz
    output = output or ("posterior" if linear.gain_pair(F, K, gain_form)[1] is not None else "prior")
    P, P_filtered = _covariances(F, table.H, K, Q, R, gain_form)
    names = table.schedule.measurements
    out = GainTable(
        name=table.name, structure=table.structure, domain="z", sample_time_s=T, gain_form=gain_form,
        sensors=tuple(SensorPort(s.name, s.role, s.index, s.order, float(rate_hz)) for s in table.sensors),
        F=F, B=B, H=np.asarray(table.H, dtype=float), K=[K], P=[P], P_filtered=[P_filtered],
        schedule=Schedule.from_names(names, [list(names)]), Q=Q, R=R, gains={}, wrap_angle=table.wrap_angle,
        output=output, states=table.states, options={**table.options, "discrete": True},
        provenance={**table.provenance, "solver": {
            "method": f"discretised from the continuous table at {rate_hz:g} Hz: F = expm(F T), Kp = Gamma K with "
                      "Gamma = int_0^T expm(F t) dt (innovation held); error from the Lyapunov equation",
            "continuous_predicted_variance": float(table.P[0][0, 0])}},
        checks={"complementary": True, "exact_proof": False,  # _numerically_checked refuses a table that is not
                "complementary_method": "the model is the zero-order hold of the continuous one, so the bands "
                                        "sum to one for any gain (structural); checked numerically below",
                "poles": [[float(p.real), float(p.imag)] for p in eig], "stable": True},
    )
    return replace(_numerically_checked(out), gains={})


def _check_single_rate(table: GainTable) -> None:
    """Refuse a table whose sensors run at different rates.

    The discretised table reads every sensor at every step (``R = PSD * rate_hz``): a slower
    sensor's log has its readings only every few steps, so the filter would run with gains and
    a predicted error made for readings that never come (the CF3 example's 10 Hz position at
    100 Hz: predicted std 0.0126 m, 0.0048 m on a log).  Its periodic gains need a re-design.

    Raises
    ------
    GainTableError
        Naming the slowest sensor and its rate.
    """
    from .designer import multirate_redesign

    rates = {s.rate_hz for s in table.sensors}
    if len(rates) > 1:
        slow = min(table.sensors, key=lambda s: s.rate_hz)
        raise GainTableError(f"{table.name}: {slow.name} runs at {slow.rate_hz:g} Hz, slower than the other sensors "
                             f"({max(rates):g} Hz); a discretised table reads every sensor at every step, so write "
                             f"{multirate_redesign(table.structure)} in the design file and design again (the periodic "
                             "DARE gives the multirate gains)")
