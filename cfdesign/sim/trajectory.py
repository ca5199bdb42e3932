"""Ground-truth trajectories: a heading profile and a speed, sampled every ``dt_s`` seconds.

A :class:`Trajectory` holds ``N + 1`` sample times ``t_k = k dt`` and the true heading at
each (continuous, not wrapped, so that whole turns are counted), and the speed.  Rate
sensors read the ``N`` intervals between the samples, angle sensors the samples themselves
(:mod:`cfdesign.sim.sensors`).

Turns are smooth: the heading follows the raised-cosine profile

.. math:: \\psi(t) = \\psi_0 + \\Delta\\psi\\left(s - \\frac{\\sin 2\\pi s}{2\\pi}\\right),
          \\qquad s = \\frac{t - t_0}{d} \\in [0, 1],

whose rate ``(Δψ/d)(1 - cos 2πs)`` and angular acceleration are zero at both ends, so a
turn of ``Δψ`` in ``d`` seconds has no step in rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..linear import wrap

__all__ = ["Trajectory", "Segment", "smooth_turn", "from_segments", "rounded_square"]


class SampledTimes:
    """Sample time and step count of a record sampled at the times ``t_s`` (N + 1 of them)."""

    t_s: np.ndarray

    @property
    def dt_s(self) -> float:
        """Sample time (s)."""
        return float(self.t_s[1] - self.t_s[0])

    @property
    def steps(self) -> int:
        """Number ``N`` of sample intervals (one filter step each)."""
        return len(self.t_s) - 1


@dataclass(frozen=True)
class Trajectory(SampledTimes):
    """Sampled truth of a planar robot.

    Attributes
    ----------
    t_s : ndarray, shape (N + 1,)
        Sample times (s), ``t_k = k dt_s``.
    heading_rad : ndarray, shape (N + 1,)
        True heading (rad, counter-clockwise), continuous: it is not wrapped.
    speed_m_s : ndarray, shape (N + 1,)
        Forward speed (m/s).
    """

    t_s: np.ndarray
    heading_rad: np.ndarray
    speed_m_s: np.ndarray

    @property
    def duration_s(self) -> float:
        """Duration (s) from the first sample to the last."""
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def rate_rad_s(self) -> np.ndarray:
        """Mean turn rate over each interval, shape (N,): what an integrating gyro reads."""
        return np.diff(self.heading_rad) / self.dt_s

    @property
    def wrapped_heading_rad(self) -> np.ndarray:
        """The heading wrapped to (-pi, pi], as a compass reports it."""
        return wrap(self.heading_rad)

    def position_m(self) -> np.ndarray:
        """Planar position from the origin, by the trapezoidal rule on speed and heading.

        Returns
        -------
        ndarray, shape (N + 1, 2)
            ``[x, y]`` (m) in the plane the heading is measured in (x along heading 0).
        """
        v = self.speed_m_s[:, None] * np.column_stack([np.cos(self.heading_rad), np.sin(self.heading_rad)])
        steps = 0.5 * (v[1:] + v[:-1]) * self.dt_s
        return np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])


@dataclass(frozen=True)
class Segment:
    """A straight run, then a smooth turn.

    Parameters
    ----------
    straight_s : float
        Duration of the straight run (s), ``>= 0``.
    turn_rad : float
        Heading change of the turn (rad), positive counter-clockwise (left).
    turn_s : float
        Duration of the turn (s), ``> 0``.
    """

    straight_s: float
    turn_rad: float
    turn_s: float

    @property
    def duration_s(self) -> float:
        """Duration of the segment (s): the straight run and the turn."""
        return self.straight_s + self.turn_s


def smooth_turn(s):
    """Fraction of a turn done at normalised time ``s``: ``s - sin(2 pi s)/(2 pi)``.

    Parameters
    ----------
    s : float or array_like
        Normalised time ``(t - t0) / d``, clipped to [0, 1].

    Returns
    -------
    ndarray
        From 0 to 1, with zero rate and zero angular acceleration at both ends.

    Examples
    --------
    >>> from cfdesign.sim import smooth_turn
    >>> smooth_turn([0.0, 0.5, 1.0, 2.0]).tolist()
    [0.0, 0.5, 1.0, 1.0]
    """
    s = np.clip(s, 0.0, 1.0)
    return s - np.sin(2 * np.pi * s) / (2 * np.pi)


def from_segments(segments, *, dt_s: float, start_heading_rad: float = 0.0, speed_m_s: float = 0.1) -> Trajectory:
    """Trajectory of straight runs and smooth turns, one :class:`Segment` after another.

    The total duration must be a whole number of samples; turns need not start on a sample.

    Parameters
    ----------
    segments : sequence of Segment or (straight_s, turn_rad, turn_s)
        The pieces, in order: a straight of ``straight_s`` seconds, then a turn through
        ``turn_rad`` (rad) taking ``turn_s`` seconds.
    dt_s : float
        Sample time (s).
    start_heading_rad : float
        Heading at ``t = 0`` (rad).
    speed_m_s : float
        Constant forward speed (m/s).

    Returns
    -------
    Trajectory
        The sampled trajectory.

    Raises
    ------
    InputError
        No segment, a negative straight run, a turn of zero duration, a non-positive sample
        time, or a duration that is not a whole number of samples.

    Examples
    --------
    >>> import math
    >>> from cfdesign.sim import Segment, from_segments
    >>> traj = from_segments([Segment(10.0, math.pi / 2, 5.0)], dt_s=0.5)
    >>> traj.steps, traj.duration_s, round(float(traj.heading_rad[-1]), 6)
    (30, 15.0, 1.570796)
    """
    segments = [Segment(*s) if not isinstance(s, Segment) else s for s in segments]
    if not segments or dt_s <= 0 or any(s.straight_s < 0 or s.turn_s <= 0 for s in segments):
        raise InputError("trajectory: give at least one segment, straight_s >= 0, turn_s > 0 and dt_s > 0")
    total = sum(s.duration_s for s in segments)
    steps = round(total / dt_s)
    if steps < 1 or not math.isclose(steps * dt_s, total, rel_tol=1e-9):
        raise InputError(f"trajectory: duration {total:g} s is not a whole number of {dt_s:g}-s samples")
    t = np.arange(steps + 1) * dt_s
    heading = np.full(steps + 1, float(start_heading_rad))
    start = 0.0
    for seg in segments:
        turn_start = start + seg.straight_s
        heading += seg.turn_rad * smooth_turn((t - turn_start) / seg.turn_s)
        start += seg.duration_s
    return Trajectory(t, heading, np.full(steps + 1, float(speed_m_s)))


def rounded_square(*, start_heading_rad: float = 0.0, straight_s: float = 600.0, turn_s: float = 10.0,
                   legs: int = 4, dt_s: float = 0.2, speed_m_s: float = 0.1, left: bool = True) -> Trajectory:
    """The path of Carreira et al. Sec. V-A: ``legs`` times straight for ``straight_s``, then 90 deg in ``turn_s``.

    With the defaults (600 s, 10 s, four legs, left turns) the robot is back at its start
    heading after 2440 s.  Start near +-180 deg (e.g. 135 deg) and the heading crosses the
    wrap-around during the first turn.

    Parameters
    ----------
    start_heading_rad : float
        Heading at ``t = 0`` (rad).
    straight_s : float
        Duration of each straight run (s).
    turn_s : float
        Duration of each 90-degree turn (s).
    legs : int
        Number of straight-and-turn legs.
    dt_s : float
        Sample time (s); 0.2 s is the paper's 5 Hz.
    speed_m_s : float
        Forward speed (m/s).
    left : bool
        Turn left (counter-clockwise) or right.

    Returns
    -------
    Trajectory
        The sampled trajectory.

    Raises
    ------
    InputError
        As :func:`from_segments`.

    Examples
    --------
    >>> from cfdesign.sim import rounded_square
    >>> traj = rounded_square()
    >>> traj.duration_s, traj.steps
    (2440.0, 12200)
    """
    turn = (np.pi / 2) if left else (-np.pi / 2)
    return from_segments([Segment(straight_s, turn, turn_s)] * legs, dt_s=dt_s,
                         start_heading_rad=start_heading_rad, speed_m_s=speed_m_s)
