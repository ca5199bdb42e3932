"""Simulation: trajectories, sensor models and the scenarios of the papers.

* :mod:`~cfdesign.sim.trajectory` - sampled truth (heading profile, speed); smooth turns;
  the rounded square of Carreira et al.
* :mod:`~cfdesign.sim.sensors` - rate and heading sensors: white noise, constant or
  random-walk bias, drift, heading-dependent magnetic perturbation, sample rate, dropouts.
  Seeded, reproducible, vectorised; noise given with the design's own objects
  (:class:`cfdesign.noise.WhiteNoise`, :class:`cfdesign.noise.Bias`).
* :mod:`~cfdesign.sim.signals` - a heading sensor as a rate (differenced), a gyro as a
  heading (dead reckoned), and the white noise a design assumes for each.
* :mod:`~cfdesign.sim.metrics` - accumulated heading error, MSE, Student-t intervals.
* :mod:`~cfdesign.sim.robot_heading` - Carreira et al.'s robot-heading scenario (Sec. V-A) and the
  reading of its noise figures.

SI units throughout (s, rad, rad/s, m, m/s).
"""

from .metrics import heading_error, mean_ci, mse
from .sensors import HeadingSensor, MagneticPerturbation, RateSensor, simulate
from .signals import difference_heading, differenced_noise, integrate_rate, integrated_noise
from .trajectory import Segment, Trajectory, from_segments, rounded_square, smooth_turn

__all__ = ["Trajectory", "Segment", "smooth_turn", "from_segments", "rounded_square",
           "RateSensor", "HeadingSensor", "MagneticPerturbation", "simulate",
           "integrate_rate", "difference_heading", "integrated_noise", "differenced_noise",
           "heading_error", "mse", "mean_ci"]
