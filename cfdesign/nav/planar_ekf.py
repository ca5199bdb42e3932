"""The planar EKF of the outdoor localization paper: pose ``[x, y, θ]`` and odometer scale ``α``.

The EKF baseline of the paper on outdoor localization with an optical navigation sensor, an
IMU and GPS (equation numbers below are that paper's): odometry and a yaw gyro drive the pose,
GPS fixes and the heading of the chord between fixes correct it, with a motion-dependent
variance of that heading and single-GPS / DGPS modes.

State ``[x, y, θ, α]`` (m, m, rad, odometer scale).  Prediction, eq. (4) (read from the
extraction)::

    x += α ρ cos Φ,   y += α ρ sin Φ,   θ += ω Δt,   α unchanged,   Φ = θ + ω Δt / 2,

covariance eq. (5): ``P = J_x P J_x^T + J_u diag(σ_ρ², σ_ω²) J_u^T + σ_α² ζ ζ^T``,
``ζ = [0, 0, 0, 1]^T``.  Update, eqs. (10)-(13): ``z = [x_gps, y_gps, atan2(Δy, Δx)]`` with the
heading of the chord between the previous and the current fix, ``H = [I_3 0]``,

.. math:: R = \\mathrm{diag}\\big(σ_{gps}^2,\\ σ_{gps}^2,\\
          (σ_θ (Σ|ω| + κ_ω)/(Σρ + κ_ρ))^2\\big).

Our reading of eq. (13): ``Σ|ω| = Σ_k |ω_k| Δt_k`` is the absolute angle turned (rad) and
``Σρ`` the distance travelled (m, odometer readings ``ρ_k``) over the samples since the
previous fix; ``σ_gps`` and ``σ_θ`` are chosen by the fix's GPS mode.  The chord heading is
compared with ``θ`` at the current fix, the innovation wrapped to ``(-π, π]``; a fix with no
previous fix gives a position-only update.

Impossible readings are missing and counted, as in the other filters of :mod:`cfdesign.nav`
(whose rates and specific forces are checked against the sensor's range): a yaw rate beyond
``gyro_range_rps``, a distance beyond ``speed_range_mps`` times its interval, and a fix that the
vehicle could not have reached from the last fix used at ``speed_range_mps``, with a margin of
:data:`FIX_MARGIN` standard deviations of the two fixes' difference (the first fix: from the
``initial_state`` given, its std ``initial_std``; by default nothing checks it, as it is the
initial state).  A fix position has no range of its own (map coordinates reach millions of
metres), so it is judged against the last fix used; when two fixes in a row are refused and
agree with each other by the same test, the fix used before them was the wrong one (an
unchecked first fix, or an initial state far off): the position restarts from the second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..linear import wrap_scalar
from ..runtime.filter import usable
from .attitude_inputs import MIN_RATE_HZ, finite_vector, held_rows, rows
from .kalman_update import first_finite, joseph_update, noise_figure

__all__ = ["PlanarEstimate", "PlanarEKF", "planar_step", "FIX_MARGIN"]

#: standard deviations of the difference of two fixes a jump may exceed the distance the vehicle
#: can travel between them by before the later fix is impossible (a 2-D normal beyond 6 sigma:
#: a chance of 1.5e-8)
FIX_MARGIN = 6.0


@dataclass(frozen=True)
class PlanarEstimate:
    """Filtered estimates of :meth:`PlanarEKF.run` after each sample (``N`` rows).

    Attributes
    ----------
    x, y : ndarray (N,)
        Position (m).
    theta : ndarray (N,)
        Heading (rad, counter-clockwise from the x axis), wrapped to ``(-π, π]``.
    alpha : ndarray (N,)
        Odometer scale factor (true distance = ``α ρ``).
    covariance : ndarray (N, 4, 4)
        A posteriori covariance.
    heading_std : ndarray (N,)
        Standard deviation (rad) of the chord-heading measurement used at that sample (eq. (13)), NaN
        when there was none.
    gps_std_used : ndarray (N,)
        GPS position standard deviation used at that sample (by mode), NaN without a fix.
    missing : dict
        Readings treated as missing (:meth:`PlanarEKF.run`, Notes): ``{'distance', 'gyro_z',
        'gps_xy'}``.
    """

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    alpha: np.ndarray
    covariance: np.ndarray
    heading_std: np.ndarray
    gps_std_used: np.ndarray
    missing: dict = field(default_factory=dict)


def planar_step(state, rho: float, omega: float, dt: float, *, jacobian: bool = True):
    """Prediction of the planar EKF, eq. (4), and its Jacobians.

    Parameters
    ----------
    state : sequence of 4 floats
        ``[x, y, θ, α]``: position (m), heading (rad), odometer scale.
    rho : float
        Odometer distance over the interval (m).
    omega : float
        Yaw rate over the interval (rad/s).
    dt : float
        Interval (s).
    jacobian : bool
        Also return the Jacobians.

    Returns
    -------
    new : ndarray, shape (4,)
        The predicted state.
    Jx : ndarray, shape (4, 4)
        Only with ``jacobian``: with respect to the state.
    Ju : ndarray, shape (4, 2)
        Only with ``jacobian``: with respect to ``u = [ρ, ω]``.
    """
    x, y, theta, alpha = state
    phi = theta + 0.5 * omega * dt
    c, s = math.cos(phi), math.sin(phi)
    new = np.array([x + alpha * rho * c, y + alpha * rho * s, theta + omega * dt, alpha])
    if not jacobian:
        return new
    Jx = np.array([[1.0, 0.0, -alpha * rho * s, rho * c], [0.0, 1.0, alpha * rho * c, rho * s],
                   [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    Ju = np.array([[alpha * c, -0.5 * dt * alpha * rho * s], [alpha * s, 0.5 * dt * alpha * rho * c],
                   [0.0, dt], [0.0, 0.0]])
    return new, Jx, Ju


class PlanarEKF:
    """The planar EKF of the outdoor localization paper: pose ``[x, y, θ]`` and odometer scale ``α`` (module docstring).

    Inputs: odometer distance and yaw gyro per sample; GPS fixes with their mode.

    Parameters
    ----------
    odo_noise_std : float
        Odometer distance noise per sample (m).
    gyro_noise_std : float
        Gyro rate noise per sample (rad/s).
    gps_std : dict
        GPS position noise per axis (m) by mode, ``{'single': ..., 'dgps': ...}``.
    kappa_omega, kappa_rho : float
        ``κ_ω`` (rad) and ``κ_ρ`` (m) of eq. (13).
    sigma_heading : float or dict
        ``σ_θ`` of eq. (13) (rad per rad·m⁻¹, i.e. m·rad/rad: the heading std is
        ``σ_θ (Σ|ω| + κ_ω) / (Σρ + κ_ρ)``), one value or a dict by mode.
    alpha_noise_std : float
        ``σ_α`` of eq. (1), the scale's random walk per sample.
    initial_std : tuple of 4 floats
        Initial standard deviations of ``[x, y, θ, α]`` (m, m, rad, unitless scale).
    gyro_range_rps : float
        A yaw rate beyond it is impossible and treated as missing (default 100 rad/s, as
        :class:`~cfdesign.nav.AttitudeParams`).
    speed_range_mps : float
        A speed beyond it is impossible (default 100 m/s): a distance beyond it times its
        interval is missing, and so is a fix further than it allows from the last fix used
        (module docstring).

    Raises
    ------
    InputError
        A noise figure, ``κ_ω``, ``κ_ρ``, ``σ_θ`` or initial std that is not a finite positive
        number (``alpha_noise_std``: non-negative; the two ranges: up to 1e15), a ``gps_std`` that names no mode or the
        mode ``''``, or a ``sigma_heading`` that does not give one value per GPS mode; the
        message names the argument.

    Notes
    -----
    Cost: about 15 µs per sample (Python 3.11, numpy 2; 3000 samples at 10 Hz, GPS at 1 Hz).
    """

    def __init__(self, *, odo_noise_std: float, gyro_noise_std: float, gps_std: dict | None = None,
                 kappa_omega: float, kappa_rho: float, sigma_heading, alpha_noise_std: float = 1e-5,
                 initial_std=(10.0, 10.0, math.pi, 0.1), gyro_range_rps: float = 100.0,
                 speed_range_mps: float = 100.0):
        if gps_std is not None and not isinstance(gps_std, dict):
            raise InputError(f"gps_std must be a dict {{mode: std}}, got {type(gps_std).__name__}")
        self.gps_std = {str(mode): noise_figure(f"gps_std[{mode!r}]", value)
                        for mode, value in (gps_std or {"single": 3.0, "dgps": 0.5}).items()}
        if not self.gps_std or "" in self.gps_std:
            raise InputError("gps_std must name at least one GPS mode, and '' (no fix) is not one")
        modes = set(self.gps_std)
        self.sigma_heading = ({str(mode): noise_figure(f"sigma_heading[{mode!r}]", value)
                               for mode, value in sigma_heading.items()} if isinstance(sigma_heading, dict)
                              else dict.fromkeys(modes, noise_figure("sigma_heading", sigma_heading)))
        if set(self.sigma_heading) != modes:
            raise InputError("sigma_heading must give one value per GPS mode")
        self.U = np.diag([noise_figure("odo_noise_std", odo_noise_std) ** 2,
                          noise_figure("gyro_noise_std", gyro_noise_std) ** 2])
        self.kappa_omega = noise_figure("kappa_omega", kappa_omega)
        self.kappa_rho = noise_figure("kappa_rho", kappa_rho)
        self.alpha_var = noise_figure("alpha_noise_std", alpha_noise_std, allow_zero=True) ** 2
        stds = rows("initial_std", initial_std, error=InputError)
        if stds.shape != (4,):
            raise InputError(f"initial_std must be 4 numbers (the stds of x, y, theta, alpha), got {stds.shape}")
        self.initial_std = np.array([noise_figure(f"initial_std[{i}]", v) for i, v in enumerate(stds)])
        self.gyro_range_rps = noise_figure("gyro_range_rps", gyro_range_rps)
        self.speed_range_mps = noise_figure("speed_range_mps", speed_range_mps)

    def heading_std(self, mode: str, turned: float, travelled: float) -> float:
        """GPS-heading standard deviation of eq. (13): ``σ_θ (Σ|ω| + κ_ω) / (Σρ + κ_ρ)``.

        Parameters
        ----------
        mode : str
            GPS mode (a key of ``gps_std``: ``'single'``, ``'dgps'``).
        turned : float
            ``Σ|ω| dt`` since the last fix (rad).
        travelled : float
            ``Σρ`` since the last fix (m).

        Returns
        -------
        float
            Standard deviation (rad) of the heading derived from consecutive fixes.
        """
        return self.sigma_heading[mode] * (turned + self.kappa_omega) / (abs(travelled) + self.kappa_rho)

    def run(self, distance, gyro_z, dt_s, gps_xy, gps_mode, *, initial_state=None) -> PlanarEstimate:
        """Filter one run.

        Parameters
        ----------
        distance, gyro_z : array_like (N,)
            Odometer distance ``ρ_k`` (m) and yaw rate ``ω_k`` (rad/s) over sample interval ``k``.
        dt_s : float or array_like (N,)
            Interval durations (s).
        gps_xy : array_like (N, 2)
            GPS fix at the end of interval ``k`` (m); NaN rows: no fix.
        gps_mode : array_like (N,) of str
            ``'single'``, ``'dgps'`` or ``''`` (no fix).
        initial_state : array_like (4,), optional
            ``[x, y, θ, α]`` before the first interval; default the first fix, ``θ = 0``, ``α = 1``.

        Returns
        -------
        PlanarEstimate
            Position (m), heading (rad), odometer scale and covariance after every sample.

        Raises
        ------
        InputError
            An array that is not of real numbers (``gps_mode``: of text) or of another shape or
            length, an interval that is not a finite positive number of seconds up to 1000, a
            GPS mode other than those of ``gps_std`` and ``''``, or an ``initial_state`` that is
            not four finite numbers; the message names the argument (and the row).
            Also an update the noise figures make singular or not finite
            (:func:`~cfdesign.nav.kalman_update.joseph_update`).

        Notes
        -----
        A distance or rate that is not finite, beyond
        :data:`~cfdesign.runtime.filter.READING_LIMIT` or impossible (beyond ``speed_range_mps``
        times its interval, beyond ``gyro_range_rps``) is missing: it holds the last usable one
        (before the first, the first); a fix given but unusable (inf, beyond the limit) or
        impossible (module docstring) is skipped.  All are counted in ``PlanarEstimate.missing``.
        """
        rho = rows("distance", distance, error=InputError)
        N = len(rho)
        omega = rows("gyro_z", gyro_z, n=N, error=InputError)
        try:
            one = np.ndim(dt_s) == 0
        except ValueError:  # a ragged list: rows names it
            one = False
        dt = rows("dt_s", np.broadcast_to(dt_s, (N,)) if one else dt_s, n=N, error=InputError)
        bad_dt = np.flatnonzero(~((dt > 0) & (dt <= 1.0 / MIN_RATE_HZ)))
        if bad_dt.size:
            raise InputError(f"dt_s must be a positive number of seconds up to {1.0 / MIN_RATE_HZ:g}, got "
                             f"{float(dt[bad_dt[0]])!r} at row {bad_dt[0]}")
        gps = rows("gps_xy", gps_xy, 2, N, error=InputError)
        mode = np.asarray(gps_mode)
        if mode.shape != (N,) or mode.dtype.kind not in "UO" or not all(isinstance(m, str) for m in mode.tolist()):
            raise InputError(f"gps_mode must be {N} strings (a GPS mode, or '' for no fix)")
        unknown = sorted(set(mode.tolist()) - set(self.gps_std) - {""})
        if unknown:
            raise InputError(f"gps_mode: unknown mode(s) {', '.join(map(repr, unknown[:5]))}; the modes are "
                             f"{', '.join(map(repr, self.gps_std))} and '' (no fix)")
        with np.errstate(invalid="ignore", over="ignore"):  # NaN, inf: held_rows's to count
            rho, missing_rho = held_rows(rho, bad=~(np.abs(rho) <= self.speed_range_mps * dt))
        omega, missing_omega = held_rows(omega, self.gyro_range_rps)
        bad_fix = ~usable(gps).all(axis=1)
        missing = {"distance": missing_rho, "gyro_z": missing_omega,
                   "gps_xy": int((bad_fix & ~np.isnan(gps).all(axis=1) & (mode != "")).sum())}
        gps = np.where(bad_fix[:, None], np.nan, gps)
        given = initial_state is not None
        if initial_state is None:
            first = first_finite(gps)
            initial_state = [*(np.zeros(2) if first is None else first), 0.0, 1.0]
        state, P = finite_vector("initial_state", initial_state, 4, error=InputError), np.diag(self.initial_std**2)
        out = np.empty((N, 4))
        cov = np.empty((N, 4, 4))
        used = np.full((N, 2), np.nan)
        elapsed = 0.0                                           # since the last fix used (or the start)
        # where the next fix must be reachable from, and its std: the initial position given (the
        # default initial state is the first fix, which nothing checks), then the last fix used
        ref = (state[:2].copy(), float(np.hypot(*self.initial_std[:2]))) if given else None
        last_fix, turned, travelled = None, 0.0, 0.0
        refused = None                                          # (fix, its std, time since it)
        zeta = np.zeros((4, 4))
        zeta[3, 3] = self.alpha_var
        for k in range(N):
            state, Jx, Ju = planar_step(state, rho[k], omega[k], dt[k])
            P = Jx @ P @ Jx.T + Ju @ self.U @ Ju.T + zeta          # eq. (5)
            P = 0.5 * (P + P.T)
            turned += abs(omega[k]) * dt[k]
            travelled += rho[k]
            elapsed += dt[k]
            if refused is not None:
                refused = (refused[0], refused[1], refused[2] + dt[k])
            fix = gps[k] if np.isfinite(gps[k]).all() and mode[k] in self.gps_std else None
            if fix is not None:
                sg = self.gps_std[mode[k]]
                if ref is None or self._reachable(fix, sg, *ref, elapsed):
                    state, P, used[k] = self._gps_update(state, P, fix, mode[k], last_fix, turned, travelled)
                elif refused is not None and self._reachable(fix, sg, *refused):
                    state, P = _restart(state, P, fix, sg)  # the fix used before these two was the wrong one
                    used[k, 0] = sg
                else:                                      # impossible: missing, counted
                    missing["gps_xy"] += 1
                    refused, fix = (fix, sg, 0.0), None
                if fix is not None:
                    last_fix, ref, elapsed, refused, turned, travelled = fix, (fix, sg), 0.0, None, 0.0, 0.0
            state[2] = _wrap(state[2])
            out[k], cov[k] = state, P
        return PlanarEstimate(x=out[:, 0], y=out[:, 1], theta=out[:, 2], alpha=out[:, 3], covariance=cov,
                              heading_std=used[:, 1], gps_std_used=used[:, 0], missing=missing)

    def _reachable(self, fix, std, other, other_std, elapsed) -> bool:
        """Whether ``fix`` is within reach of ``other`` (a fix ``elapsed`` seconds earlier) at
        ``speed_range_mps``, with :data:`FIX_MARGIN` standard deviations of their difference."""
        gap = math.hypot(fix[0] - other[0], fix[1] - other[1])
        return gap <= self.speed_range_mps * elapsed + FIX_MARGIN * math.hypot(std, other_std)

    def _gps_update(self, state, P, fix, mode, last_fix, turned, travelled):
        """GPS update, eqs. (6)-(13): position, plus the chord heading when a previous fix exists."""
        sg = self.gps_std[mode]
        if last_fix is None:
            H, z, R, s_head = np.eye(4)[:2], fix, sg**2 * np.eye(2), np.nan
            innovation = z - state[:2]
        else:
            d = fix - last_fix
            chord = math.atan2(d[1], d[0]) + (math.pi if travelled < 0 else 0.0)
            s_head = self.heading_std(mode, turned, travelled)
            H, R = np.eye(4)[:3], np.diag([sg**2, sg**2, s_head**2])
            innovation = np.array([fix[0] - state[0], fix[1] - state[1], _wrap(chord - state[2])])
        state, P = joseph_update(state, P, innovation, H, R)
        return state, P, (sg, s_head)


def _restart(state, P, fix, std):
    """The position restarted from ``fix``: ``x, y`` the fix, their covariance the fix's, no
    correlation with the heading and scale (the position they were correlated with was wrong)."""
    state = state.copy()
    state[:2] = fix
    P = P.copy()
    P[:2, :] = 0.0
    P[:, :2] = 0.0
    P[0, 0] = P[1, 1] = std**2
    return state, P


def _wrap(angle):
    """:func:`cfdesign.linear.wrap_scalar`, passing a non-finite angle through (a NaN reading stays NaN)."""
    return wrap_scalar(angle) if math.isfinite(angle) else angle
