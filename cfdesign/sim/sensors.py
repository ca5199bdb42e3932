"""Sensor models: turn a :class:`~cfdesign.sim.trajectory.Trajectory` into readings.

The noise and bias of a model are the objects a design file builds
(:class:`cfdesign.noise.WhiteNoise`, :class:`cfdesign.noise.Bias`), read with the same
conventions (:mod:`cfdesign.noise`), so a simulation can generate exactly the noise a
design assumed:

* a **rate sensor** (gyro) reads the *mean* rate over each sample interval - the
  delta-angle of an integrating gyro divided by ``T``, the zero-order-hold input of Carreira et
  al. eq. (25) - plus its bias and white noise.  White noise of per-sample standard deviation
  ``sigma`` at ``f`` Hz is the average over ``1/f`` s of a white noise of PSD
  ``sigma**2 / f``; a random-walk bias of density ``d`` is integrated exactly over each
  interval (mean ``b_k + I_k/T`` with ``Var I_k = d^2 T^3/3``, ``Cov(I_k, b_(k+1) - b_k) =
  d^2 T^2/2``), which is the Van Loan discretisation the designer uses;
* a **heading sensor** (compass, odometry heading) samples the heading at each sample time,
  plus an offset (constant or random walk), a drift (a constant rate error integrated, as
  odometry's), a heading-dependent magnetic perturbation and white noise; its readings are
  wrapped to (-pi, pi].

Sensors slower than the trajectory read every ``n``-th sample (``n`` an integer); the other
samples, and dropped readings, are NaN - the runtime's "missing" (cfdesign.runtime).  Every
random draw comes from the generator passed in: :func:`simulate` gives each sensor its own
stream, seeded by the run's seed and the sensor's name.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..linear import wrap
from ..noise import Bias, WhiteNoise
from .trajectory import Trajectory

__all__ = ["RateSensor", "HeadingSensor", "MagneticPerturbation", "simulate", "cumulative_trapezoid",
           "interval_mean_readings", "noisy_samples"]


@dataclass(frozen=True)
class MagneticPerturbation:
    """Heading-dependent compass error ``amplitude_rad * sin(harmonic * psi + phase_rad)`` (rad).

    ``harmonic = 1`` is a hard-iron-like error, ``2`` a soft-iron-like one.  Carreira et al.
    Sec. V-A: ``20 sin(psi)`` (read as degrees, as their robot-heading scenario does).  Call
    it with the true heading (rad) to get the error (rad).

    Parameters
    ----------
    amplitude_rad : float
        Amplitude of the error (rad).
    harmonic : int
        Multiple of the heading in the sine.
    phase_rad : float
        Phase of the sine (rad).

    Examples
    --------
    >>> import math
    >>> from cfdesign.sim import MagneticPerturbation
    >>> error = MagneticPerturbation(math.radians(20.0))
    >>> round(math.degrees(float(error(math.pi / 2))), 6)
    20.0
    """

    amplitude_rad: float
    harmonic: int = 1
    phase_rad: float = 0.0

    def __call__(self, heading_rad):
        return self.amplitude_rad * np.sin(self.harmonic * np.asarray(heading_rad) + self.phase_rad)


#: defaults: no white noise, no bias
_NO_NOISE = WhiteNoise(std=0.0)
_NO_BIAS = Bias()


@dataclass(frozen=True, kw_only=True)
class _Sensor:
    """What every sensor model has: white noise, bias, rate and dropouts."""

    noise: WhiteNoise = _NO_NOISE
    bias: Bias = _NO_BIAS
    rate_hz: float | None = None
    dropout: float = 0.0

    def every(self, dt_s: float) -> int:
        """Trajectory samples per reading; the sensor rate must divide the trajectory rate.

        Parameters
        ----------
        dt_s : float
            The trajectory's sample time (s).

        Returns
        -------
        int
            Samples between two readings (1 when the sensor has no ``rate_hz``: it reads at
            every sample).

        Raises
        ------
        InputError
            ``rate_hz`` is not the trajectory rate divided by a positive integer.
        """
        if self.rate_hz is None:
            return 1
        ratio = 1.0 / (dt_s * self.rate_hz) if self.rate_hz > 0 else 0.0
        if round(ratio) < 1 or not math.isclose(ratio, round(ratio), rel_tol=1e-9):
            raise InputError(f"rate_hz: {self.rate_hz:g} Hz is not the trajectory rate {1 / dt_s:g} Hz divided by an "
                            "integer")
        return round(ratio)

    def sensor_rate_hz(self, dt_s: float) -> float:
        """The rate the sensor reads at on a trajectory sampled every ``dt_s``.

        Parameters
        ----------
        dt_s : float
            The trajectory's sample time (s).

        Returns
        -------
        float
            Readings per second (Hz): ``rate_hz``, or the trajectory rate when it has none.

        Raises
        ------
        InputError
            As :meth:`every`.
        """
        return 1.0 / (dt_s * self.every(dt_s))

    def _keep(self, values, every, rng):
        """NaN where the sensor does not read (off its rate) or the reading is dropped."""
        if not 0.0 <= self.dropout < 1.0:
            raise InputError(f"dropout: a probability in [0, 1) is needed, got {self.dropout!r}")
        out = np.full(len(values), np.nan)
        out[::every] = values[::every]
        if self.dropout:
            out[rng.random(len(out)) < self.dropout] = np.nan
        return out


def _bias_path(bias: Bias, steps: int, dt_s: float, rng):
    """Bias at the ``steps + 1`` sample times and its mean over each of the ``steps`` intervals.

    A constant bias is ``bias.value``; a random walk starts at ``bias.value`` and is drawn
    exactly with its within-interval integral (module docstring).
    """
    if bias.model == "constant":
        return np.full(steps + 1, bias.value), np.full(steps, bias.value)
    q = bias.psd
    increments = math.sqrt(q * dt_s) * rng.normal(size=steps)
    integrals = 0.5 * dt_s * increments + math.sqrt(q * dt_s**3 / 12) * rng.normal(size=steps)
    at_samples = bias.value + np.concatenate([[0.0], np.cumsum(increments)])
    return at_samples, at_samples[:-1] + integrals / dt_s


@dataclass(frozen=True, kw_only=True)
class RateSensor(_Sensor):
    """A rate gyro (or any rate sensor): mean rate over each interval + bias + white noise (rad/s).

    Parameters
    ----------
    noise : WhiteNoise
        Per-sample std (rad/s) at ``rate_hz``, or a density (rad/s/sqrt(Hz)).
    bias : Bias
        Constant ``value`` (rad/s) or a random walk (density rad/s/sqrt(s), starting at ``value``).
    rate_hz : float, optional
        Sensor rate; default the trajectory's.  A slower sensor averages over its own interval.
    dropout : float
        Probability that a reading is missing (NaN).
    """

    def read(self, trajectory: Trajectory, rng) -> np.ndarray:
        """Simulated readings over the trajectory's intervals.

        Parameters
        ----------
        trajectory : Trajectory
            The truth, ``N + 1`` samples.
        rng : numpy.random.Generator
            Source of the noise and dropouts.

        Returns
        -------
        ndarray, shape (N,)
            Mean rate over each interval plus bias and white noise (rad/s); NaN where the
            sensor does not read (a slower rate) or the reading is dropped.

        Raises
        ------
        InputError
            The sensor rate does not divide the trajectory rate, or ``dropout`` is not in [0, 1).
        """
        dt, steps = trajectory.dt_s, trajectory.steps
        every = self.every(dt)
        white = math.sqrt(self.noise.psd(self.sensor_rate_hz(dt)) / dt) * rng.normal(size=steps)
        mean = trajectory.rate_rad_s + _bias_path(self.bias, steps, dt, rng)[1] + white
        if every > 1:  # the mean over each of the sensor's own intervals, at its first sample
            whole = steps // every * every
            blocks = mean[:whole].reshape(-1, every).mean(axis=1)
            mean = np.full(steps, np.nan)
            mean[:whole:every] = blocks
        return self._keep(mean, every, rng)


@dataclass(frozen=True, kw_only=True)
class HeadingSensor(_Sensor):
    """A heading sensor (compass, odometry): heading + offset + drift + perturbation + white noise.

    Parameters
    ----------
    noise : WhiteNoise
        Per-sample std (rad) at ``rate_hz``, or a density (rad/sqrt(Hz)).
    bias : Bias
        Offset: constant ``value`` (rad) or a random walk (rad/sqrt(s), starting at ``value``).
    rate_hz : float, optional
        Sensor rate (Hz); default the trajectory's.  As for :class:`RateSensor`.
    dropout : float
        Probability that a reading is missing (NaN).
    drift_rad_s : float
        A constant rate error (rad/s) integrated into the heading (odometry's wheel-radius error).
    perturbation : callable, optional
        Heading-dependent error ``f(true heading)`` (rad), e.g. :class:`MagneticPerturbation`.
    """

    drift_rad_s: float = 0.0
    perturbation: object = None

    def read(self, trajectory: Trajectory, rng) -> np.ndarray:
        """Simulated readings at the trajectory's sample times.

        Parameters
        ----------
        trajectory : Trajectory
            The truth, ``N + 1`` samples.
        rng : numpy.random.Generator
            Source of the noise and dropouts.

        Returns
        -------
        ndarray, shape (N + 1,)
            Heading plus offset, drift, perturbation and white noise, wrapped to (-pi, pi] (rad);
            NaN where the sensor does not read or the reading is dropped.

        Raises
        ------
        InputError
            The sensor rate does not divide the trajectory rate, or ``dropout`` is not in [0, 1).
        """
        dt, steps = trajectory.dt_s, trajectory.steps
        every = self.every(dt)
        psi = trajectory.heading_rad
        error = _bias_path(self.bias, steps, dt, rng)[0] + self.drift_rad_s * trajectory.t_s
        if self.perturbation is not None:
            error = error + self.perturbation(psi)
        white = math.sqrt(self.noise.variance(self.sensor_rate_hz(dt))) * rng.normal(size=steps + 1)
        return self._keep(wrap(psi + error + white), every, rng)


def simulate(trajectory: Trajectory, sensors: dict, seed: int) -> dict:
    """Readings of every sensor for one run.

    Each sensor draws from its own generator seeded by ``(seed, crc32(name))``: the same seed
    gives the same readings, and adding or removing a sensor leaves the others' noise
    unchanged.

    Parameters
    ----------
    trajectory : Trajectory
        The truth.
    sensors : dict
        ``{name: RateSensor | HeadingSensor}``.
    seed : int
        Seed of the run.

    Returns
    -------
    dict
        ``{name: ndarray}``: shape (N,) for rate sensors (one reading per interval, rad/s),
        (N + 1,) for heading sensors (one per sample time, rad); NaN where a reading is
        missing.

    Raises
    ------
    InputError
        A sensor's rate or dropout does not fit; the message names the sensor.

    Examples
    --------
    >>> from cfdesign.noise import WhiteNoise
    >>> from cfdesign.sim import HeadingSensor, RateSensor, rounded_square, simulate
    >>> traj = rounded_square(straight_s=20.0, turn_s=5.0, legs=1)
    >>> readings = simulate(traj, {"gyro": RateSensor(noise=WhiteNoise(std=0.01)),
    ...                            "compass": HeadingSensor(noise=WhiteNoise(std=0.05), rate_hz=1.0)}, seed=0)
    >>> readings["gyro"].shape, readings["compass"].shape
    ((125,), (126,))
    """
    out = {}
    for name, model in sensors.items():
        rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
        try:
            out[name] = model.read(trajectory, rng)
        except InputError as exc:
            raise InputError(f"sensor {name}: {exc}") from None
    return out


def cumulative_trapezoid(values, h):
    """Cumulative trapezoidal integral along axis 0, from 0.

    Parameters
    ----------
    values : ndarray, shape (N + 1, ...)
        Samples on a uniform grid.
    h : float
        Grid step.

    Returns
    -------
    ndarray, shape (N + 1, ...)
        The integral at each sample (0 at the first).
    """
    steps = 0.5 * h * (values[1:] + values[:-1])
    return np.concatenate([np.zeros((1, *values.shape[1:])), np.cumsum(steps, axis=0)])


def interval_mean_readings(t_s, means, bias, noise_std, prefix, seed) -> np.ndarray:
    """Per-axis :class:`RateSensor` readings of a signal given by its interval means.

    Each axis is given to the sensor model as a :class:`~cfdesign.sim.trajectory.Trajectory`
    whose "heading" is the signal's running integral, so the model's mean rate is the mean of
    the signal over each interval.

    Parameters
    ----------
    t_s : ndarray, shape (N + 1,)
        Sample times (s).
    means : ndarray, shape (N, 3)
        The signal's mean over each interval (rad/s or m/s^2).
    bias : sequence of 3 floats
        Constant bias per axis.
    noise_std : float
        White noise per sample (standard deviation, in the readings' unit).
    prefix : str
        Sensor name prefix (``gyro``): axis ``x`` draws from the stream of ``gyro_x``.
    seed : int
        Seed of the run.

    Returns
    -------
    ndarray, shape (N, 3)
        Readings per interval and axis, in the unit of ``means``.
    """
    dt = float(t_s[1] - t_s[0])
    out = np.empty_like(means)
    for i, axis in enumerate("xyz"):
        integral = np.concatenate([[0.0], np.cumsum(means[:, i]) * dt])
        sensor = RateSensor(noise=WhiteNoise(std=noise_std), bias=Bias(value=float(bias[i])))
        name = f"{prefix}_{axis}"
        out[:, i] = simulate(Trajectory(t_s, integral, np.zeros_like(t_s)), {name: sensor}, seed)[name]
    return out


def noisy_samples(truth, std, every, name, seed) -> np.ndarray:
    """Samples of a signal plus white noise at every ``every``-th sample, NaN elsewhere.

    Parameters
    ----------
    truth : ndarray, shape (N, ...)
        The true signal, one row per sample.
    std : float
        Noise per sample.
    every : int
        Keep every ``every``-th sample.
    name : str
        Stream name (the noise is seeded by ``(seed, crc32(name))``).
    seed : int
        Seed of the noise generator.

    Returns
    -------
    ndarray, shape (N, ...)
        Noisy samples, NaN where no sample is kept.
    """
    rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
    out = np.full(truth.shape, np.nan)
    out[::every] = truth[::every] + std * rng.normal(size=truth[::every].shape)
    return out
