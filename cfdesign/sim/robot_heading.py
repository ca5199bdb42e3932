"""The robot-heading scenario of Carreira et al. (Sec. V-A): a rounded square, with a gyro, a compass and odometry.

Carreira et al., *Complementary Filter Design with Three Frequency Bands: Robot Attitude
Estimation*, simulate a robot's heading to compare every assignment of three sensors to the
bands of a complementary filter (their Tables I and II).  This module is the one place where
the paper's noise figures are read (:class:`Reading`); the simulation, the designs of
:mod:`cfdesign.reproduce.carreira` and the docs all take them from here
(``docs/derivations.md``, section "Robot-heading simulation").

The paper, as printed
---------------------
The robot goes straight for 600 s and turns smoothly 90 deg left in 10 s, four times.
Rate gyro: ``N(0, 2e-3)`` and a 0.8 deg/s bias, compensated.  Compass: ``N(0, 2e-3)`` and a
magnetic perturbation ``20 sin(psi)``.  Odometry: ``N(0, 4e-6)`` and a 0.5 deg/s bias.
Sampling: 5 Hz (Sec. V-B).  It states no units and does not say whether ``x`` in
``N(0, x)`` is a variance.

Our reading (:data:`READING`)
-----------------------------
* ``x`` is a **standard deviation** in SI units per 5-Hz sample - the convention of
  MATLAB's ``normrnd(mu, sigma)``: gyro 2e-3 rad/s, compass 2e-3 rad, odometry heading
  4e-6 rad.  Read as a variance (:data:`READINGS` ``['variance']``) the gyro would have
  0.045 rad/s of noise; dead reckoning with it drifts by ~0.5 rad^2 of mean square error over
  the run, more than the compass's perturbation, and the paper's best rows (the gyro in the
  low-pass band) would become its worst: this reading contradicts the paper's ordering.
* The biases and the perturbation are in **degrees**, as printed: the gyro's 0.8 deg/s is
  subtracted before use (the paper compensates it); odometry's 0.5 deg/s is a heading drift
  (2440 s x 0.5 deg/s = 21.3 rad by the end); the compass reads ``psi + 20 deg sin(psi)``.
* Rate sensors deliver the mean rate over each 0.2-s interval (the ZOH input of eq. (25)).
* The filters model an input's rate bias as a random walk of density
  ``rate_bias_density = 1e-3 rad/s/sqrt(s)`` (not in the paper; a constant bias gives a
  bias state no process noise).  Over a 600-s leg it lets the bias move by 0.025 rad/s
  (1.4 deg/s), the size of the stated biases.

The run starts at 135 deg, so the first turn crosses +-180 deg (heading wrap-around).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import SpecError
from ..noise import Bias, WhiteNoise
from .sensors import HeadingSensor, MagneticPerturbation, RateSensor, simulate
from .signals import difference_heading, differenced_noise, integrate_rate, integrated_noise
from .trajectory import Trajectory, rounded_square

__all__ = ["PAPER", "Reading", "READINGS", "READING", "Scenario", "scenario", "SENSORS", "START_HEADING_DEG"]

#: sensor names, in the order of the paper's tables
SENSORS = ("gyro", "compass", "odometry")
#: start heading (deg): the first left turn crosses +-180 deg
START_HEADING_DEG = 135.0


@dataclass(frozen=True)
class _Paper:
    """Carreira et al. Sec. V-A and V-B as printed: ``N(0, x)`` figures, biases (deg/s), perturbation (deg)."""

    noise_x: dict = field(default_factory=lambda: {"gyro": 2e-3, "compass": 2e-3, "odometry": 4e-6})
    gyro_bias_deg_s: float = 0.8
    odometry_bias_deg_s: float = 0.5
    compass_perturbation_deg: float = 20.0
    rate_hz: float = 5.0
    straight_s: float = 600.0
    turn_s: float = 10.0
    legs: int = 4


#: the paper's figures, unread
PAPER = _Paper()


@dataclass(frozen=True)
class Reading:
    """How the paper's ``N(0, x)`` is read: ``x`` a standard deviation or a variance.

    Units are SI (rad, rad/s) per sample at the paper's 5 Hz.

    Parameters
    ----------
    name : {'std', 'variance'}
        The reading.
    rate_bias_density : float
        Random walk (rad/s/sqrt(s)) the filters assume for their input's rate bias.

    Raises
    ------
    SpecError
        An unknown reading.
    """

    name: str = "std"
    rate_bias_density: float = 1e-3

    def __post_init__(self):
        if self.name not in ("std", "variance"):
            raise SpecError(f"reading must be 'std' or 'variance', got {self.name!r}")

    def std(self, sensor: str) -> float:
        """Per-sample standard deviation of a sensor's white noise under this reading.

        Parameters
        ----------
        sensor : str
            ``gyro``, ``compass`` or ``odometry``.

        Returns
        -------
        float
            rad/s for the gyro, rad otherwise.
        """
        x = PAPER.noise_x[sensor]
        return x if self.name == "std" else math.sqrt(x)

    def describe(self) -> str:
        """The reading in words, for reports.

        Returns
        -------
        str
            One sentence.
        """
        x_is = "a standard deviation" if self.name == "std" else "a variance"
        return (f"N(0, x): x is {x_is} in SI units per {PAPER.rate_hz:g}-Hz sample (gyro rad/s, compass and "
                f"odometry rad); biases and perturbation in degrees; input rate-bias random walk "
                f"{self.rate_bias_density:g} rad/s/sqrt(s) in the designs")


#: both readings of the printed figures
READINGS = {name: Reading(name) for name in ("std", "variance")}
#: the reading this reproduction uses
READING = READINGS["std"]


@dataclass(frozen=True)
class Scenario:
    """The truth, the sensor models and the reading they came from.

    Parameters
    ----------
    trajectory : Trajectory
        The rounded square.
    sensors : dict
        ``{name: RateSensor | HeadingSensor}``.
    reading : Reading
        How the paper's figures were read.
    gyro_compensation_rad_s : float
        Subtracted from the gyro before use (Carreira et al.: the bias "can be compensated").
    """

    trajectory: Trajectory
    sensors: dict
    reading: Reading
    gyro_compensation_rad_s: float = 0.0

    @property
    def rate_hz(self) -> float:
        """Sample rate of the scenario (Hz)."""
        return 1.0 / self.trajectory.dt_s

    def signals(self, seed: int) -> dict:
        """Each sensor as a heading and as a rate, for one run.

        The gyro's rate is its compensated reading and its heading is dead reckoned from the true
        start; a heading sensor's rate is its differenced heading (:mod:`cfdesign.sim.signals`).

        Parameters
        ----------
        seed : int
            Seed of the run.

        Returns
        -------
        dict
            ``{name: {'heading': (N + 1,) rad, 'rate': (N,) rad/s}}``.
        """
        raw = simulate(self.trajectory, self.sensors, seed)
        dt, start = self.trajectory.dt_s, float(self.trajectory.heading_rad[0])
        out = {}
        for name, model in self.sensors.items():
            if isinstance(model, RateSensor):
                rate = raw[name] - self.gyro_compensation_rad_s
                out[name] = {"rate": rate, "heading": integrate_rate(rate, dt, start)}
            else:
                out[name] = {"heading": raw[name], "rate": difference_heading(raw[name], dt)}
        return out

    def noise(self, name: str, role: str) -> WhiteNoise:
        """The white noise the design assumes for a sensor used in a role.

        Parameters
        ----------
        name : str
            Sensor name.
        role : {'rate', 'heading'}
            How the sensor is used (its own kind, or differenced/integrated).

        Returns
        -------
        WhiteNoise
            The sensor's own noise, or the stand-in of :func:`~cfdesign.sim.signals.differenced_noise`
            or :func:`~cfdesign.sim.signals.integrated_noise`.
        """
        model = self.sensors[name]
        native = "rate" if isinstance(model, RateSensor) else "heading"
        if role == native:
            return model.noise
        convert = differenced_noise if role == "rate" else integrated_noise
        return convert(model.noise, self.rate_hz)


def scenario(reading: Reading = READING, *, straight_s: float = PAPER.straight_s,
             start_heading_deg: float = START_HEADING_DEG, linear_gaussian: bool = False) -> Scenario:
    """Carreira et al.'s rounded square and sensors under ``reading``.

    Parameters
    ----------
    reading : Reading
        How ``N(0, x)`` is read (module docstring).
    straight_s : float
        Length of each straight leg (s); the paper's 600 s by default, shorter for tests.
    start_heading_deg : float
        Initial heading; 135 deg makes the first turn cross +-180 deg.
    linear_gaussian : bool
        Keep only what a Kalman design models - white noise on every sensor and a gyro bias
        that is a random walk of density ``reading.rate_bias_density`` - with no constant gyro
        bias, no compass perturbation and no odometry drift.

    Returns
    -------
    Scenario
        The truth and the sensor models.
    """
    dt = 1.0 / PAPER.rate_hz
    traj = rounded_square(start_heading_rad=math.radians(start_heading_deg), straight_s=straight_s,
                          turn_s=PAPER.turn_s, legs=PAPER.legs, dt_s=dt)
    noise = {name: WhiteNoise(std=reading.std(name), field=f"sensors.{name}.noise") for name in SENSORS}
    if linear_gaussian:
        gyro_bias = Bias("random_walk", density=reading.rate_bias_density)
        perturbation, drift, compensation = None, 0.0, 0.0
    else:
        compensation = math.radians(PAPER.gyro_bias_deg_s)
        gyro_bias = Bias("constant", value=compensation)
        perturbation = MagneticPerturbation(math.radians(PAPER.compass_perturbation_deg))
        drift = math.radians(PAPER.odometry_bias_deg_s)
    sensors = {"gyro": RateSensor(noise=noise["gyro"], bias=gyro_bias),
               "compass": HeadingSensor(noise=noise["compass"], perturbation=perturbation),
               "odometry": HeadingSensor(noise=noise["odometry"], drift_rad_s=drift)}
    return Scenario(traj, sensors, reading, compensation)
