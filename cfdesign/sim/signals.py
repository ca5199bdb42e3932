"""A sensor in another role: an angle sensor's heading differenced into a rate, a rate
sensor's reading integrated into a heading - and the white noise a design assumes for each.

A complementary filter takes one sensor as its rate input and the others as angle
measurements (MATH.md §1).  Any heading sensor can be the input by differencing its
readings over each sample interval, and a gyro can be an angle measurement by dead
reckoning from a known start.  With ``x[k+1] = x[k] + T u[k]`` (seed 001 eq. (25)) the
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

from ..noise import WhiteNoise
from ..runtime import wrap

__all__ = ["integrate_rate", "difference_heading", "integrated_noise", "differenced_noise"]


def integrate_rate(rate, dt_s: float, start_rad: float) -> np.ndarray:
    """Dead-reckoned heading at the ``N + 1`` sample times from ``N`` interval rates, wrapped.

    ``psi[0] = start_rad``, ``psi[k+1] = psi[k] + T rate[k]``; a missing (NaN) rate holds the
    last one received (zero before the first), as the runtime does for inputs.
    """
    rate = np.asarray(rate, dtype=float)
    seen = ~np.isnan(rate)
    last = np.maximum.accumulate(np.where(seen, np.arange(len(rate)), -1))
    held = np.where(last >= 0, rate[np.maximum(last, 0)], 0.0)
    return wrap(start_rad + np.concatenate([[0.0], np.cumsum(held * dt_s)]))


def difference_heading(heading, dt_s: float) -> np.ndarray:
    """Rate over each of the ``N`` intervals from ``N + 1`` heading readings: ``wrap(diff)/T``.

    Wrapping the difference makes a reading that crosses +-180 deg give the small true step.
    A missing reading at either end of an interval makes that rate missing (NaN).
    """
    return wrap(np.diff(np.asarray(heading, dtype=float))) / dt_s


def _std(noise: WhiteNoise, rate_hz: float) -> float:
    return math.sqrt(noise.variance(rate_hz))


def differenced_noise(noise: WhiteNoise, rate_hz: float) -> WhiteNoise:
    """White-noise stand-in for a differenced heading: std ``sqrt(2) sigma / T`` (rad/s)."""
    return WhiteNoise(std=math.sqrt(2.0) * _std(noise, rate_hz) * rate_hz, field=noise.field)


def integrated_noise(noise: WhiteNoise, rate_hz: float) -> WhiteNoise:
    """White-noise stand-in for an integrated rate: its per-step increment ``sigma T`` (rad)."""
    return WhiteNoise(std=_std(noise, rate_hz) / rate_hz, field=noise.field)
