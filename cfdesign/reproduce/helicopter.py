"""Vasconcelos et al.'s Table 2: mean absolute errors of the navigation system on the helicopter manoeuvre.

Pipeline of one run (the paper's Fig. 3), all filters designed by the toolkit:

1. truth and readings: :mod:`cfdesign.sim.helicopter` (straight path, then an ascending
   helix; IMU 50 Hz, GPS 1 Hz, Table 1's sensor errors);
2. attitude: :class:`cfdesign.nav.EulerAttitudeFilter` (Euler channels, gyro bias
   in body rates, Magneto-Pendular Sensor with centripetal compensation ``a - w x v_B``);
3. position: :class:`cfdesign.nav.PositionFilter` fed by the accelerometer rotated
   with the attitude estimate, gravity removed, and the GPS fixes (periodic gains).

Assumptions where the paper is silent
-------------------------------------
* Trajectory dimensions, speeds and duration, the magnetic field, the bias directions:
  :mod:`cfdesign.sim.helicopter` (5 m/s cruise, 20 s straight, 80-s helix of radius 15 m
  climbing at 0.5 m/s; horizontal field; accelerometer bias on body z; ``--accel-bias xyz``
  puts it on every axis and shows the resulting tilt floor).
* ``v_B`` for the centripetal compensation comes from a velocity sensor (the paper's first
  option, Sec. 2.2), here the true body velocity: the position filter's velocity (its second
  option) needs the two filters interleaved sample by sample, which their batch interfaces
  do not do, and a first attitude pass without compensation is 7 deg off in roll in the turn.
* Filters start from: the MPS attitude of the first sample with zero gyro bias; the first
  GPS fix, the true initial velocity (the vehicle's state at hand-over) and zero
  accelerometer bias.  The "small bias gains" row starts from calibrated biases (the true
  ones, the paper's "careful calibration") and uses bias densities a hundred times smaller.
* Tuning knobs (noise figures the design takes; the paper's Q and R are "tuning knobs" too):
  ``NOMINAL`` and ``SMALL_BIAS_GAINS`` below.
* Mean absolute error ``E|x - x_hat|`` over every sample of the run; position averaged over
  the three ENU axes (the paper's one "X, Y, Z" row), yaw error wrapped; then averaged over
  ``--runs`` Monte-Carlo runs (seeds ``seed .. seed + runs - 1``), with a 95 % Student-t
  interval.  The paper reports one run.

Derivations: ``docs/derivations.md``, sections "Multirate gains" and "Navigation filters".
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

import numpy as np

from ..sim import helicopter as heli
from .report import Comparison, json_text, runs_text

__all__ = ["PAPER", "Tuning", "NOMINAL", "SMALL_BIAS_GAINS", "run_once", "Reproduction", "reproduce",
           "add_arguments", "run"]

#: Table 2 and Sec. 4's small-bias-gain figures: position (m), yaw, pitch, roll (deg)
PAPER = {"nominal": (1.39, 1.16e-2, 1.68e-1, 1.01e-1), "small_bias_gains": (1.2, 8.3e-3, 9.8e-2, 3.4e-2)}
QUANTITIES = ("position (X, Y, Z) [m]", "yaw [deg]", "pitch [deg]", "roll [deg]")


@dataclass(frozen=True)
class Tuning:
    """Design noise figures (SI) of the two filters, and whether biases start calibrated.

    Attributes
    ----------
    accel_bias_density : float
        Accelerometer-bias random walk the position filter is designed for (m/s^2/sqrt(s)).
    gyro_bias_density : float
        Gyro-bias random walk the attitude filter is designed for (rad/s/sqrt(s)).
    mps_noise_std : float
        Noise of the Magneto-Pendular Sensor's tilt and heading (rad).
    calibrated : bool
        The filters start from the true biases (the paper's "small bias gains" row).
    """

    accel_bias_density: float = 1e-2        # m/s^2/sqrt(s)
    gyro_bias_density: float = 1e-4         # rad/s/sqrt(s)
    mps_noise_std: float = 1e-2             # rad, tilt and heading
    calibrated: bool = False


#: The tuning of Table 2's nominal row (biases estimated from zero)
NOMINAL = Tuning()
#: The tuning of the paper's small-bias-gain figures: slow bias random walks, filters started
#: from the true biases
SMALL_BIAS_GAINS = Tuning(accel_bias_density=1e-4, gyro_bias_density=1e-6, calibrated=True)


def _filters(tuning: Tuning, errors: heli.SensorErrors, rate_hz: float):
    from ..nav import EulerAttitudeFilter, PositionFilter

    attitude = EulerAttitudeFilter(rate_hz, gyro_noise_std=errors.gyro_noise_std_rad_s,
                                   gyro_bias_density=tuning.gyro_bias_density, tilt_noise_std=tuning.mps_noise_std,
                                   heading_noise_std=tuning.mps_noise_std, declination_rad=heli.declination_rad())
    position = PositionFilter(rate_hz, errors.gps_rate_hz, accel_noise_std=errors.accel_noise_std_m_s2,
                              accel_bias_density=tuning.accel_bias_density, gps_noise_std=errors.gps_noise_std_m)
    return attitude, position


def _mae(truth: heli.HelicopterTrajectory, position, euler) -> np.ndarray:
    """``[position (m), yaw, pitch, roll (deg)]`` mean absolute errors over the run."""
    from ..linear import wrap

    n = len(position)
    d = euler - truth.euler_rad[:n]
    d[:, 0] = wrap(d[:, 0])
    return np.concatenate([[np.mean(np.abs(position - truth.position_m[:n]))], np.degrees(np.abs(d).mean(axis=0))])


def run_once(truth: heli.HelicopterTrajectory, seed: int, tuning: Tuning = NOMINAL,
             errors: heli.SensorErrors = heli.TABLE1, filters=None) -> np.ndarray:
    """One simulated run of the manoeuvre through both filters.

    Parameters
    ----------
    truth : HelicopterTrajectory
        The manoeuvre (:func:`cfdesign.sim.helicopter.helicopter_manoeuvre`).
    seed : int
        Seed of the sensor noise.
    tuning : Tuning
        Design figures of the filters.
    errors : SensorErrors
        Sensor errors of the simulation (default Table 1).
    filters : (EulerAttitudeFilter, PositionFilter), optional
        Filters built already (default: built from ``tuning`` and ``errors``).

    Returns
    -------
    ndarray, shape (4,)
        Mean absolute errors: position (m), yaw, pitch, roll (deg).
    """
    from .. import rotations as quat

    attitude, position = filters or _filters(tuning, errors, 1.0 / truth.dt_s)
    r = heli.simulate_readings(truth, seed, errors)
    n = truth.steps
    gyro, accel = r.gyro_rad_s, r.accel_m_s2
    if tuning.calibrated:  # the filters start from the calibration
        gyro = gyro - errors.gyro_bias
    v_body = np.einsum("kji,kj->ki", quat.to_matrix(truth.quaternion[:n]), truth.velocity_m_s[:n])
    att = attitude.run(gyro, accel, r.mag_g[:n], velocity_body=v_body)
    bias0 = quat.rotate(att.quaternion[0], errors.accel_bias) if tuning.calibrated else None
    pos = position.run(accel, att.quaternion, r.gps_enu_m[:n], initial_velocity=truth.velocity_m_s[0],
                       initial_bias=bias0)
    return _mae(truth, pos.position, att.euler)


@dataclass(frozen=True)
class Reproduction:
    """Per-run mean absolute errors of both rows, with the settings that produced them.

    Attributes
    ----------
    seeds : tuple of int
        Seeds of the runs.
    accel_bias : {'z', 'xyz'}
        Reading of Table 1's accelerometer bias.
    manoeuvre : Manoeuvre
        The trajectory's dimensions.
    values : dict
        ``{row: list of per-run error arrays}`` for ``nominal`` and ``small_bias_gains``.
    """

    seeds: tuple
    accel_bias: str
    manoeuvre: heli.Manoeuvre
    values: dict

    def comparisons(self, row: str) -> list:
        """Ours beside the paper's, for every quantity of a row.

        Parameters
        ----------
        row : {'nominal', 'small_bias_gains'}
            The row of Table 2: nominal gains or the gains for a small bias.

        Returns
        -------
        list of cfdesign.reproduce.report.Comparison
            One comparison per quantity of the row.
        """
        runs = np.array(self.values[row])
        return [Comparison((q,), tuple(runs[:, i]), PAPER[row][i]) for i, q in enumerate(QUANTITIES)]

    def to_dict(self) -> dict:
        """The JSON form (``cfdesign reproduce helicopter --json``).

        Returns
        -------
        dict
            Plain dicts, lists and numbers (JSON-serialisable).
        """
        rows = {}
        for row in PAPER:
            rows[row] = [{"quantity": c.cells[0], "mae": c.mean, "ci95": [c.stats[1], c.stats[2]],
                          "paper": c.paper, "ratio": c.ratio, "runs": list(c.values)} for c in self.comparisons(row)]
        m = self.manoeuvre
        return {"paper": "helicopter", "runs": len(self.seeds), "seeds": list(self.seeds),
                "accel_bias": self.accel_bias,
                "attitude_filter": "cfdesign.nav.EulerAttitudeFilter",
                "manoeuvre": {"straight_s": m.straight_s, "helix_s": m.helix_s, "speed_m_s": m.speed_m_s,
                              "turn_rate_rad_s": m.turn_rate_rad_s, "climb_m_s": m.climb_m_s, "rate_hz": m.rate_hz},
                "rows": rows, "not_worse_than_paper": self.not_worse()}

    def not_worse(self) -> bool:
        """Whether every figure is no worse than the paper's.

        Returns
        -------
        bool
            True when no figure exceeds the paper's.
        """
        return all(c.ratio <= 1.0 for row in PAPER for c in self.comparisons(row))

    def text(self) -> str:
        """Table 2 as ``cfdesign reproduce helicopter`` prints it.

        Returns
        -------
        str
            The report, lines separated by newlines.
        """
        m = self.manoeuvre
        lines = [f"Vasconcelos et al., helicopter navigation, Table 2: {m.straight_s:g} s straight + "
                 f"{m.helix_s:g} s ascending "
                 f"helix at {m.speed_m_s:g} m/s, IMU {m.rate_hz:g} Hz, GPS 1 Hz; accelerometer bias on "
                 f"{self.accel_bias}; {runs_text(self.seeds)}",
                 "mean absolute error E|x - x_hat| over the run, averaged over the runs (95% CI)"]
        for row, title in (("nominal", "Table 2 (nominal bias gains)"),
                           ("small_bias_gains", "Sec. 4, small bias gains from calibrated biases")):
            lines += ["", title, f"{'quantity':<24}{'MAE ours':>11}  {'95% CI':<22}{'paper':>9}  ours/paper"]
            for c in self.comparisons(row):
                _, low, high = c.stats
                ci = "-" if math.isnan(low) else f"[{low:.2e}, {high:.2e}]"
                lines.append(f"{c.cells[0]:<24}{c.mean:>11.3g}  {ci:<22}{c.paper:>9.3g}  {c.ratio:.3g}")
        lines += ["", f"every figure no worse than the paper's: {'yes' if self.not_worse() else 'NO'}"]
        return "\n".join(lines)


def reproduce(runs: int = 5, *, seed: int = 0, accel_bias: str = "z", manoeuvre: heli.Manoeuvre | None = None,
              progress: bool = False) -> Reproduction:
    """Both rows of Table 2 on ``runs`` simulated runs (module docstring).

    Parameters
    ----------
    runs : int
        Monte-Carlo runs; run ``i`` uses seed ``seed + i`` (the same readings for both rows).
    seed : int
        Seed of the first run.
    accel_bias : {'z', 'xyz'}
        Reading of Table 1's 10-mg accelerometer bias (:data:`cfdesign.sim.helicopter.ACCEL_BIAS_READINGS`).
    manoeuvre : Manoeuvre, optional
        Trajectory dimensions; shorter ones for quick checks.
    progress : bool
        A tqdm bar on stderr.

    Returns
    -------
    Reproduction
        The per-run errors of both rows and the settings.

    Raises
    ------
    SpecError
        ``runs`` not from 1 to :data:`~cfdesign.reproduce.report.MAX_RUNS`, ``seed`` negative, or an
        unknown ``accel_bias``.
    """
    from tqdm import tqdm

    from ..errors import SpecError
    from .report import check_runs

    check_runs(runs, seed)
    if accel_bias not in heli.ACCEL_BIAS_READINGS:
        raise SpecError(f"accel_bias must be one of {sorted(heli.ACCEL_BIAS_READINGS)}, got {accel_bias!r}")
    m = manoeuvre or heli.Manoeuvre()
    truth = heli.helicopter_manoeuvre(m)
    errors = replace(heli.TABLE1, accel_bias_axes=heli.ACCEL_BIAS_READINGS[accel_bias])
    tunings = {"nominal": NOMINAL, "small_bias_gains": SMALL_BIAS_GAINS}
    filters = {row: _filters(t, errors, m.rate_hz) for row, t in tunings.items()}
    seeds = tuple(range(seed, seed + runs))
    values = {row: [] for row in tunings}
    for s in tqdm(seeds, unit="run", file=sys.stderr, disable=None if progress else True):
        for row, t in tunings.items():
            values[row].append(tuple(run_once(truth, s, t, errors, filters[row])))
    return Reproduction(seeds, accel_bias, m, values)


def add_arguments(parser):
    """Options of ``cfdesign reproduce helicopter``: ``--runs``, ``--seed``, ``--accel-bias``, ``--json``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The sub-command's parser.

    Returns
    -------
    argparse.ArgumentParser
        ``parser``, with the options added.
    """
    parser.add_argument("--runs", type=int, default=5, help="Monte-Carlo runs (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first run (runs use seed, seed+1, ...)")
    parser.add_argument("--accel-bias", choices=sorted(heli.ACCEL_BIAS_READINGS), default="z",
                        help="Table 1's 10-mg accelerometer bias on body z (default) or on every axis")
    parser.add_argument("--json", action="store_true", help="print the numbers as JSON instead of the table")
    return parser


def run(args) -> int:
    """Run ``cfdesign reproduce helicopter``: print Table 2 (or JSON).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`add_arguments`.

    Returns
    -------
    int
        Exit status 0.

    Raises
    ------
    SpecError
        ``--runs`` below 1.
    """
    result = reproduce(getattr(args, "runs", 5), seed=getattr(args, "seed", 0),
                       accel_bias=getattr(args, "accel_bias", "z"), progress=not getattr(args, "json", False))
    print(json_text(result.to_dict()) if getattr(args, "json", False) else result.text())
    return 0
