"""Is the complementary filter as good as the EKF for less?  One comparison, same scenarios.

The complementary-filter papers claim a complementary filter comes close to an EKF (or UKF)
at a fraction of the cost (Alves Neto et al. Sec. 5, Vasconcelos et al. Sec. 1).  This module
runs every filter on the same simulated data and measures, in the same process, its errors
and its cost per step:

* ``cf`` - Vasconcelos et al.'s navigation system: :class:`~cfdesign.nav.EulerAttitudeFilter`
  (MPS with centripetal compensation from a body velocity) and
  :class:`~cfdesign.nav.PositionFilter` (multirate gains), every gain designed by cfdesign
  from the noise figures;
* ``adaptive`` - Alves Neto et al.'s adaptive CF (:mod:`cfdesign.nav.adaptive`; needs a
  forward speed: odometry on the ground, the velocity sensor's speed on the helicopter, with
  10 satellites);
* ``ekf003`` - the 22-state strapdown INS/GPS/magnetometer EKF
  (:class:`~cfdesign.nav.strapdown_ekf.StrapdownEKF`);
* ``ekf002`` - the planar odometry/gyro/GPS EKF [x, y, θ, α]
  (:class:`~cfdesign.nav.planar_ekf.PlanarEKF`; needs odometry, ground vehicles only).

Scenarios: ``ground`` - a robot on uneven terrain with a 60-s GPS outage
(:func:`cfdesign.sim.ground.ground_robot_scenario`); ``helicopter`` - Vasconcelos et al.'s
manoeuvre (:mod:`cfdesign.sim.helicopter`).  The body velocity the CF's MPS needs comes from odometry
(ground: ``[v_odo, 0, 0]``) or from a velocity sensor (helicopter: the true body velocity,
as in ``cfdesign reproduce helicopter``).  The two EKF baselines are described in
``docs/derivations.md``, section "Navigation filters"; ``ekf003`` and ``ekf002`` are their
filter names in the tables and the JSON.

Every filter starts from the true initial velocity (the vehicle's state at switch-on is known)
and aligns its attitude and position from its own first readings.  The planar EKF integrates
the body z gyro as the heading rate, which is its model: on uneven terrain the tilt makes that
wrong, and its heading error shows it.

Metrics: horizontal position RMSE over the run and its maximum inside the outage (m),
heading RMSE (deg, wrapped), total attitude RMSE (deg, angle of ``q_est conj(q_true)``; not
for the planar EKF), and the wall-clock microseconds per step of ``run`` on this machine.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Result", "compare", "add_arguments", "run", "FILTERS", "SCENARIOS", "DURATION_RANGE"]

#: durations (s) of the ground scenario ``compare`` takes (``--duration``)
DURATION_RANGE = (10.0, 10_000.0)

#: The filters compared, ``{name: description}`` (``--filters`` takes the names)
FILTERS = {"cf": "complementary filter (Vasconcelos et al., designed gains)",
           "adaptive": "adaptive CF (Alves Neto et al.)",
           "ekf003": "strapdown INS/GPS/magnetometer EKF, 22 states", "ekf002": "planar odometry/gyro/GPS EKF"}
#: The simulated scenarios: a ground robot and the helicopter manoeuvre
SCENARIOS = ("ground", "helicopter")


@dataclass(frozen=True)
class Result:
    """One filter on one scenario: errors and cost.

    Attributes
    ----------
    scenario : {'ground', 'helicopter'}
        The simulated scenario: the ground robot or the helicopter.
    filter : str
        A key of :data:`FILTERS`.
    position_rmse_m : float
        RMS horizontal position error (m).
    outage_max_m : float
        Largest position error during the GPS outage (m); NaN without one.
    heading_rmse_deg : float
        RMS heading error (deg).
    attitude_rmse_deg : float
        RMS total attitude error (deg); NaN for the planar EKF.
    us_per_step : float
        Measured cost (microseconds per IMU step).
    """

    scenario: str
    filter: str
    position_rmse_m: float
    outage_max_m: float
    heading_rmse_deg: float
    attitude_rmse_deg: float
    us_per_step: float

    def row(self) -> list:
        """The result as a row of the printed table.

        Returns
        -------
        list
            Filter key, description, the errors and the cost.
        """
        return [self.filter, FILTERS[self.filter], self.position_rmse_m, self.outage_max_m, self.heading_rmse_deg,
                self.attitude_rmse_deg, self.us_per_step]


def _timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def _attitude_errors(q_est, q_true, euler_est=None, euler_true=None):
    from .. import rotations as quat
    from ..linear import wrap

    e = quat.multiply(quat.normalize(q_est), quat.conjugate(q_true))
    total = 2 * np.arccos(np.clip(np.abs(e[:, 0]), 0, 1))
    yaw_est = quat.to_euler(q_est)[:, 0] if euler_est is None else euler_est
    yaw_true = quat.to_euler(q_true)[:, 0] if euler_true is None else euler_true
    heading = wrap(yaw_est - yaw_true)
    return _rms_deg(heading), _rms_deg(total)


def _rms_deg(x) -> float:
    return float(np.degrees(np.sqrt(np.mean(np.square(x)))))


def _position_errors(est_xy, true_xy, outage_mask):
    err = np.linalg.norm(est_xy - true_xy, axis=1)
    keep = np.isfinite(err)
    outage = err[outage_mask & keep]
    return float(np.sqrt(np.mean(err[keep] ** 2))), float(outage.max()) if outage.size else math.nan


# ---------------------------------------------------------------------------- scenarios
def _ground(seed: int, duration_s: float):
    from ..sim.ground import ground_robot_scenario

    s = ground_robot_scenario(seed, duration_s=duration_s, outages=((0.4 * duration_s, 0.6 * duration_s),))
    t = s.t_s[1:]  # reading row k belongs to t_s[k + 1]
    outage = np.zeros(len(t), dtype=bool)
    for a, b in s.outages:
        outage |= (t >= a) & (t <= b)
    v_body = np.column_stack([s.odometry_speed_m_s, np.zeros((len(t), 2))])
    return {"scenario": s, "truth_q": s.quaternion[1:], "truth_p": s.position_m[1:], "outage": outage,
            "gyr": s.gyro_rad_s, "acc": s.accel_m_s2, "mag": s.mag, "gps": s.gps_enu_m,
            "gps_v": s.gps_velocity_enu_m_s, "v_body": v_body, "rate": 1.0 / s.dt_s, "v0": s.velocity_m_s[0],
            "odometry": s.odometry_speed_m_s, "n_satellites": s.n_satellites,
            "errors": _ground_noise(s)}


def _ground_noise(s) -> dict:
    """Noise figures the filters are designed for (per-sample stds at the IMU rate)."""
    from ..sim.ground import GROUND_ERRORS as e

    rate = 1.0 / s.dt_s
    return {"gyro_std": e.gyro_noise_density * math.sqrt(rate), "accel_std": e.accel_noise_density * math.sqrt(rate),
            "gps_std": e.gps_noise_std_m, "gps_vel_std": e.gps_velocity_noise_std_m_s}


def _helicopter(seed: int, _duration_s: float):
    from .. import rotations as quat
    from ..sim import helicopter as heli

    truth = heli.helicopter_manoeuvre()
    r = heli.simulate_readings(truth, seed)
    n = truth.steps
    v_body = np.einsum("kji,kj->ki", quat.to_matrix(truth.quaternion[:n]), truth.velocity_m_s[:n])
    e = heli.TABLE1
    speed = np.linalg.norm(v_body, axis=1)  # the velocity sensor the CF's MPS uses, as forward speed
    return {"scenario": truth, "truth_q": truth.quaternion[:n], "truth_p": truth.position_m[:n],
            "outage": np.zeros(n, dtype=bool), "gyr": r.gyro_rad_s, "acc": r.accel_m_s2, "mag": r.mag_g[:n],
            "gps": r.gps_enu_m[:n], "gps_v": None, "v_body": v_body, "rate": 1.0 / truth.dt_s,
            "v0": truth.velocity_m_s[0], "odometry": speed, "n_satellites": np.full(n, 10),
            "errors": {"gyro_std": e.gyro_noise_std_rad_s, "accel_std": e.accel_noise_std_m_s2,
                       "gps_std": e.gps_noise_std_m, "gps_vel_std": 0.1}}


# ---------------------------------------------------------------------------- filters
def _run_cf(d, ground: bool):
    """Vasconcelos et al.'s system.  Its samples are at ``t_k`` with GPS fixes on phase 0 of each second;
    the ground readings belong to ``t_{k+1}``, so they are shifted one row (nothing at ``t_0``)."""
    from ..nav import EulerAttitudeFilter, PositionFilter

    e = d["errors"]
    attitude = EulerAttitudeFilter(d["rate"], gyro_noise_std=e["gyro_std"], gyro_bias_density=1e-4,
                                   tilt_noise_std=1e-2, heading_noise_std=1e-2)
    position = PositionFilter(d["rate"], 1.0, accel_noise_std=e["accel_std"], accel_bias_density=1e-2,
                              gps_noise_std=e["gps_std"])

    mag, gps, v_body = d["mag"], d["gps"], d["v_body"]
    if ground:
        mag, v_body = (np.vstack([x[:1], x[:-1]]) for x in (mag, v_body))
        gps = np.vstack([np.full((1, 3), np.nan), gps[:-1]])

    def go():
        att = attitude.run(d["gyr"], d["acc"], mag, velocity_body=v_body)
        pos = position.run(d["acc"], att.quaternion, gps, initial_velocity=d["v0"])
        return att, pos

    (att, pos), seconds = _timed(go)
    if ground:  # row k is t_k: rows 1..N-1 are the truth rows 0..N-2 (t_1..t_{N-1}); last row repeated
        return (np.vstack([att.quaternion[1:], att.quaternion[-1:]]), np.vstack([pos.position[1:], pos.position[-1:]]),
                seconds)
    return att.quaternion, pos.position, seconds


def _run_adaptive(d):
    from ..nav.adaptive import AdaptiveCF

    f = AdaptiveCF(d["rate"], v_max=2.0 if d["odometry"].max() < 2.0 else 2.0 * d["odometry"].max())
    est, seconds = _timed(lambda: f.run(d["gyr"], d["acc"], d["mag"], d["odometry"], d["gps"], d["n_satellites"]))
    return est.quaternion, est.position, seconds


def _run_ekf003(d, ground: bool):
    from ..nav.strapdown_ekf import StrapdownEKF

    e = d["errors"]
    f = StrapdownEKF(d["rate"], gyro_noise_std=e["gyro_std"], accel_noise_std=e["accel_std"], gyro_bias_density=1e-4,
                     accel_bias_density=1e-3, scale_density=1e-5, gps_pos_std=e["gps_std"],
                     gps_vel_std=e["gps_vel_std"], triad_std=math.radians(2.0), mag_rate_hz=10.0)
    mag, gps, gps_v = d["mag"], d["gps"], d["gps_v"]
    if ground:  # readings at t[k+1]: give the EKF rows at t[0..N]; at t[0] no fix, the first field repeated
        pad = np.full((1, 3), np.nan)
        mag = np.vstack([mag[:1], mag])
        gps, gps_v = (np.vstack([pad, x]) for x in (gps, gps_v))
    est, seconds = _timed(lambda: f.run(d["gyr"], d["acc"], mag, gps, gps_v, initial_velocity=d["v0"]))
    rows = slice(1, None) if ground else slice(0, len(d["truth_q"]))
    return est.quaternion[rows], est.position[rows], seconds


def _run_ekf002(d):
    from ..nav.planar_ekf import PlanarEKF

    s = d["scenario"]
    dt = 1.0 / d["rate"]
    f = PlanarEKF(odo_noise_std=0.05 * dt, gyro_noise_std=d["errors"]["gyro_std"], kappa_omega=0.05,
                  kappa_rho=1.0, sigma_heading=1.0)
    fix = np.isfinite(d["gps"][:, 0])
    est, seconds = _timed(lambda: f.run(s.odometry_speed_m_s * dt, d["gyr"][:, 2], dt, d["gps"][:, :2],
                                        np.where(fix, "single", "")))
    return est, seconds


def _result(name, scenario, d, q, p, seconds):
    pos, outage = _position_errors(p[:, :2], d["truth_p"][:, :2], d["outage"])
    heading, total = _attitude_errors(q, d["truth_q"])
    return Result(scenario, name, pos, outage, heading, total, 1e6 * seconds / len(d["gyr"]))


def compare(scenario: str = "ground", seed: int = 0, duration_s: float = 300.0, filters=None) -> list:
    """Run the navigation filters on one scenario.

    Parameters
    ----------
    scenario : {'ground', 'helicopter'}
        The ground robot with a GPS outage (:mod:`cfdesign.sim.ground`) or the helicopter of
        Vasconcelos et al. (:mod:`cfdesign.sim.helicopter`).
    seed : int
        Seed of the simulation.
    duration_s : float
        Length of the ground scenario (s).
    filters : sequence of str, optional
        Keys of :data:`FILTERS` (default all; the planar EKF runs on the ground only).

    Returns
    -------
    list of Result
        One per filter that applies to the scenario.

    Raises
    ------
    SpecError
        An unknown scenario, a negative seed, or a ground scenario's duration outside
        :data:`DURATION_RANGE`.
    """
    from ..errors import SpecError
    from .report import check_runs

    if scenario not in SCENARIOS:
        raise SpecError(f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}")
    check_runs(None, seed, runs_needed=False)
    if scenario == "ground" and not (isinstance(duration_s, (int, float)) and not isinstance(duration_s, bool)
                                     and DURATION_RANGE[0] <= duration_s <= DURATION_RANGE[1]):  # NaN too
        raise SpecError(f"duration (--duration) must be from {DURATION_RANGE[0]:g} to {DURATION_RANGE[1]:g} s, got "
                        f"{duration_s!r} (shorter: no GPS outage to measure; longer: more memory than a run needs)")
    from ..linear import wrap

    ground = scenario == "ground"
    d = _ground(seed, duration_s) if ground else _helicopter(seed, duration_s)
    names = [f for f in (filters or FILTERS) if ground or f != "ekf002"]  # the planar EKF is for ground vehicles
    out = []
    for name in names:
        if name == "ekf002":
            est, seconds = _run_ekf002(d)
            p = np.column_stack([est.x, est.y])
            pos, outage = _position_errors(p, d["truth_p"][:, :2], d["outage"])
            yaw_true = _truth_yaw(d["truth_q"])
            heading = _rms_deg(wrap(est.theta - yaw_true))
            out.append(Result(scenario, name, pos, outage, heading, math.nan, 1e6 * seconds / len(d["gyr"])))
            continue
        if name == "adaptive":
            q, p, seconds = _run_adaptive(d)
        else:
            q, p, seconds = (_run_cf if name == "cf" else _run_ekf003)(d, ground)
        out.append(_result(name, scenario, d, q, p, seconds))
    return out


def _truth_yaw(q):
    from .. import rotations as quat

    return quat.to_euler(q)[:, 0]


# ---------------------------------------------------------------------------- report
HEADER = ["filter", "what", "pos RMSE m", "outage max m", "heading RMSE deg", "attitude RMSE deg", "us/step"]


def format_results(results) -> str:
    rows = [HEADER] + [[r[0], r[1], *(f"{v:.3g}" if np.isfinite(v) else "-" for v in r[2:])]
                       for r in (x.row() for x in results)]
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(HEADER))]
    return "\n".join("  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)) for row in rows)


def verdict(results) -> str:
    """One line: the CF's error and cost relative to the strapdown EKF on the same run."""
    by = {r.filter: r for r in results}
    if "cf" not in by or "ekf003" not in by:
        return ""
    cf, ekf = by["cf"], by["ekf003"]
    return (f"CF / strapdown EKF: position RMSE x{cf.position_rmse_m / ekf.position_rmse_m:.2f}, "
            f"attitude RMSE x{cf.attitude_rmse_deg / ekf.attitude_rmse_deg:.2f}, "
            f"cost per step x{cf.us_per_step / ekf.us_per_step:.3f}")


def add_arguments(parser):
    """Options of ``cfdesign reproduce compare``: ``--scenario``, ``--seed``, ``--duration``, ``--json``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The sub-command's parser.

    Returns
    -------
    argparse.ArgumentParser
        ``parser``, with the options added.
    """
    parser.add_argument("--scenario", choices=[*SCENARIOS, "all"], default="all",
                        help="the ground robot with a GPS outage, the helicopter of Vasconcelos et al., or both "
                             "(default all)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the simulated scenarios (default 0)")
    parser.add_argument("--duration", type=float, default=300.0, help="ground scenario length in s (default 300)")
    parser.add_argument("--json", action="store_true", help="print the numbers as JSON")
    return parser


def run(args) -> int:
    """Run ``cfdesign reproduce compare``: a table per scenario (or JSON).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options of :func:`add_arguments`.

    Returns
    -------
    int
        Exit status 0.
    """
    scenarios = SCENARIOS if args.scenario == "all" else (args.scenario,)
    results = {s: compare(s, args.seed, args.duration) for s in scenarios}
    if args.json:
        from .report import json_text

        print(json_text({s: [r.__dict__ for r in rs] for s, rs in results.items()}))  # no measurement: null
        return 0
    for s, rs in results.items():
        print(f"\nscenario: {s} (seed {args.seed})", file=sys.stdout)
        print(format_results(rs))
        line = verdict(rs)
        if line:
            print(line)
    return 0
