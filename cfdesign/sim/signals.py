"""A sensor in another role: an angle sensor's heading differenced into a rate, a rate
sensor's reading integrated into a heading - and the white noise a design assumes for each.

A complementary filter takes one sensor as its rate input and the others as angle
measurements (``docs/derivations.md``).  Any heading sensor can be the input by differencing its
readings over each sample interval, and a gyro can be an angle measurement by dead
reckoning from a known start.  With ``x[k+1] = x[k] + T u[k]`` (Carreira et al. eq. (25)) the
differenced heading ``u[k] = (y[k+1] - y[k])/T`` is exactly the sampled relation
``(z - 1)/T`` the model implies, so a noise-free reading gives back the truth exactly.

The design needs a white-noise figure for the derived signal.  Two stand-ins, stated here
once:

* differenced heading noise of per-sample std ``sigma`` has std ``sqrt(2) sigma / T``
  (its samples are correlated, MA(1): a white model is an approximation);
* an integrated rate noise of per-sample std ``sigma`` is a random walk; the design takes
  its per-step increment ``sigma T`` as the std of a white angle noise.
"""

from __future__ import annotations

import math

import numpy as np

from ..linear import wrap
from ..noise import WhiteNoise

__all__ = ["integrate_rate", "difference_heading", "integrated_noise", "differenced_noise", "sinusoid_readings"]


def integrate_rate(rate, dt_s: float, start_rad: float) -> np.ndarray:
    """Dead-reckoned heading from interval rates, wrapped: a gyro seen as a heading sensor.

    ``psi[0] = start_rad``, ``psi[k+1] = psi[k] + T rate[k]``; a missing (NaN) rate holds the
    last one received (zero before the first), as the runtime does for inputs.

    Parameters
    ----------
    rate : array_like, shape (N,)
        Rate over each interval (rad/s).
    dt_s : float
        Sample time ``T`` (s).
    start_rad : float
        Heading at the first sample (rad).

    Returns
    -------
    ndarray, shape (N + 1,)
        Heading at the sample times (rad), wrapped to (-pi, pi].

    Examples
    --------
    >>> from cfdesign.sim import integrate_rate
    >>> integrate_rate([0.1, float("nan"), 0.2], 0.5, 0.0).round(6).tolist()
    [0.0, 0.05, 0.1, 0.2]
    """
    rate = np.asarray(rate, dtype=float)
    seen = ~np.isnan(rate)
    last = np.maximum.accumulate(np.where(seen, np.arange(len(rate)), -1))
    held = np.where(last >= 0, rate[np.maximum(last, 0)], 0.0)
    return wrap(start_rad + np.concatenate([[0.0], np.cumsum(held * dt_s)]))


def difference_heading(heading, dt_s: float) -> np.ndarray:
    """Rate over each interval from heading readings: ``wrap(diff(heading)) / T``.

    Wrapping the difference makes a reading that crosses +-180 deg give the small true step.
    A missing reading at either end of an interval makes that rate missing (NaN).

    Parameters
    ----------
    heading : array_like, shape (N + 1,)
        Heading readings (rad).
    dt_s : float
        Sample time ``T`` (s).

    Returns
    -------
    ndarray, shape (N,)
        Rates (rad/s).

    Examples
    --------
    >>> import math
    >>> from cfdesign.sim import difference_heading
    >>> difference_heading([math.pi - 0.01, -math.pi + 0.01], 0.2).round(6).tolist()
    [0.1]
    """
    return wrap(np.diff(np.asarray(heading, dtype=float))) / dt_s


def _std(noise: WhiteNoise, rate_hz: float) -> float:
    return math.sqrt(noise.variance(rate_hz))


def differenced_noise(noise: WhiteNoise, rate_hz: float) -> WhiteNoise:
    """White-noise stand-in for a differenced heading: std ``sqrt(2) sigma / T`` (rad/s).

    Parameters
    ----------
    noise : WhiteNoise
        The heading sensor's noise (rad).
    rate_hz : float
        Its rate ``1/T`` (Hz).

    Returns
    -------
    WhiteNoise
        Per-sample std of the differenced rate (rad/s).
    """
    return WhiteNoise(std=math.sqrt(2.0) * _std(noise, rate_hz) * rate_hz, field=noise.field)


def integrated_noise(noise: WhiteNoise, rate_hz: float) -> WhiteNoise:
    """White-noise stand-in for an integrated rate: its per-step increment ``sigma T`` (rad).

    Parameters
    ----------
    noise : WhiteNoise
        The rate sensor's noise (rad/s).
    rate_hz : float
        Its rate ``1/T`` (Hz).

    Returns
    -------
    WhiteNoise
        Per-sample std of the heading increment (rad).
    """
    return WhiteNoise(std=_std(noise, rate_hz) / rate_hz, field=noise.field)


def sinusoid_readings(table, n: int, *, seed: int = 0, amplitude: float | None = None,
                      missing: float = 0.0, arrivals: bool = False) -> dict:
    """Test readings for any gain table: a slow sinusoid through every sensor, plus noise.

    Each sensor reads the sinusoid's derivative of its order (angle, rate, acceleration, jerk) plus
    white noise of std 0.05; angle tables swing over +-4 rad (so the heading crosses +-pi,
    readings wrapped), others over +-50 m.  Used by the runtime benchmark and the
    C-against-Python tests.

    Parameters
    ----------
    table : GainTable
        A discrete table.
    n : int
        Number of samples.
    seed : int
        Seed of the noise.
    amplitude : float, optional
        Amplitude of the sinusoid (default 4 rad or 50 m).
    missing : float
        Fraction of the samples set to NaN.
    arrivals : bool
        Each measurement only at the ticks where the table's schedule reads it, NaN between (a
        1 Hz GPS once a second, as a stream or a gapped log delivers it); default: every sensor
        at every tick (the readings off the schedule then have no gain, and the runtime counts
        and warns of them).

    Returns
    -------
    dict
        ``{sensor: (n,) ndarray}``, ready for :meth:`cfdesign.runtime.Runtime.run`.
    """
    rng = np.random.default_rng(seed)
    period_s = 2000.0 if table.wrap_angle else 100.0
    amplitude = amplitude or (4.0 if table.wrap_angle else 50.0)
    w = 2 * np.pi / period_s
    t = np.arange(n) * table.sample_time_s
    data = {}
    for s in table.sensors:  # the order-th derivative of the sinusoid (jerk sensors of 4-band chains too)
        values = amplitude * w**s.order * np.sin(w * t + s.order * np.pi / 2) + 0.05 * rng.normal(size=n)
        if table.wrap_angle and s.order == 0:
            values = wrap(values)
        if missing:
            values[rng.random(n) < missing] = np.nan
        if arrivals and s.role == "measurement":
            values[~table.schedule.mask()[np.arange(n) % table.period, s.index]] = np.nan
        data[s.name] = values
    return data
