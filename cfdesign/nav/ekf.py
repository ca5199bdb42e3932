"""Extended Kalman filters of seeds 003 (strapdown INS/GPS, 22 states) and 002 (planar, odometer scale).

Frames as :mod:`cfdesign.rotations`: ENU local frame, FLU body, quaternions ``[w, x, y, z]``
body -> ENU, gravity :data:`cfdesign.rotations.GRAVITY_ENU` (``a_n = R_nb f_b + g_n``).

Seed 003 (:class:`StrapdownEKF`)
--------------------------------
State (22): ``x = [q (4), v (3), r (3), b_g (3), s_g (3), b_a (3), s_a (3)]`` - attitude, ENU
velocity and position, gyro bias and scale factor, accelerometer bias and scale factor.

* Sensor model, seed 003 eq. (11): ``f̃ = s_a ∘ f + b_a + w`` (per axis; likewise the gyro),
  so the corrected inputs are ``ω = (ω̃ - b_g) / s_g`` and ``f = (f̃ - b_a) / s_a``; ``s`` is the
  scale factor itself (1 for a perfect sensor), ``b`` and ``s`` are random walks (eqs. (12)-(13)).
* Prediction, seed 003 eq. (8) (strapdown mechanisation of eqs. (2)-(4)), our reading of the
  garbled ``e^{-W Δt} q`` in the body -> ENU convention::

      q(k+1) = q(k) ⊗ exp(ω Δt / 2)           (exact rotation over the interval)
      v(k+1) = v(k) + (C(q(k)) f + g_n) Δt
      r(k+1) = r(k) + v(k) Δt + (C(q(k)) f + g_n) Δt² / 2

  with ``C(q)`` = :func:`cfdesign.rotations.to_matrix` evaluated at the start of the
  interval as printed; ``ω̃``, ``f̃`` are the interval-mean readings.  The covariance is
  propagated with the analytic Jacobian ``F = ∂x(k+1)/∂x(k)`` (:func:`strapdown_step`).
* Process noise at the IMU rate: attitude ``(σ_g Δt / 2)² I_4`` (the gyro white noise,
  ``½ Ξ(q) σ_g² Ξ(q)^T Δt²`` for a unit ``q``, plus the same amount along ``q`` so that the
  norm direction keeps a non-zero variance); velocity/position ``σ_a² [Δt², Δt³/2; Δt³/2,
  Δt⁴/4]`` per axis; random walks ``density² Δt`` on biases and scale factors.
* Observations (eq. (10)), each a Joseph-form update ``P = (I - KH) P (I - KH)^T + K R K^T``,
  symmetrised:

  - TRIAD attitude (eq. (7), :mod:`cfdesign.nav.triad`) from the corrected specific force
    (primary, taken as ``+up`` = ``-g_n`` direction) and the magnetometer, every
    ``rate_hz / mag_rate_hz`` samples; observed as the quaternion itself (eq. (10)), its sign
    chosen nearest the state, ``H = [I_4 0]``, ``R = (σ_triad / 2)² I_4`` (a small rotation
    ``δθ`` moves the vector part by ``δθ / 2``).  The specific force is first corrected for the
    centripetal term, ``f - ω × v_b`` (seed 004 Sec. 2.2,
    :func:`cfdesign.nav.mps.centripetal_compensation`), which seed 003 leaves out;
  - GPS position and velocity in the local frame (eqs. (5)-(6) give the conversion; inputs
    here are already ENU), ``H`` selects ``r`` or ``v``; NaN rows are skipped;
  - the norm pseudo-observation ``e = 1 - |q|`` (eq. (9)), measured as 0 after every
    prediction, ``H = [-q^T / |q|, 0]``, ``R = σ_norm²``.

* Initial alignment: TRIAD on the first accelerometer and magnetometer samples (seed 003
  Sec. 3.1), biases 0, scale factors 1.

Seed 002 (:class:`PlanarEKF`)
-----------------------------
State ``[x, y, θ, α]`` (m, m, rad, odometer scale).  Prediction, seed 002 eq. (4) (read from the
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import rotations as quat
from ..errors import InputError
from ..linear import wrap_scalar
from ..rotations import GRAVITY_ENU
from .mps import centripetal_compensation
from .triad import triad_quaternion

__all__ = ["N_STATES", "EkfEstimate", "StrapdownEKF", "strapdown_step", "norm_observation",
           "PlanarEstimate", "PlanarEKF", "planar_step"]

#: number of states of :class:`StrapdownEKF`
N_STATES = 22
_Q, _V, _R = slice(0, 4), slice(4, 7), slice(7, 10)
_BG, _SG, _BA, _SA = slice(10, 13), slice(13, 16), slice(16, 19), slice(19, 22)
_UP = np.array([0.0, 0.0, 1.0])


# ---------------------------------------------------------------------------- seed 003 helpers
def _left(q) -> np.ndarray:
    """``L(q)`` with ``q ⊗ p = L(q) p`` (Hamilton, ``[w, x, y, z]``)."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def _right(p) -> np.ndarray:
    """``R(p)`` with ``q ⊗ p = R(p) q``."""
    w, x, y, z = p
    return np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])


def _delta_quaternion(phi) -> tuple[np.ndarray, np.ndarray]:
    """``p = exp(φ / 2)`` (:func:`~cfdesign.rotations.from_rotation_vector`) and ``∂p/∂φ`` (4, 3)."""
    p = quat.from_rotation_vector(phi)
    a = math.sqrt(float(phi @ phi))
    if a > 1e-4:
        s = math.sin(0.5 * a) / a
        ds_over_a = (0.5 * math.cos(0.5 * a) * a - math.sin(0.5 * a)) / a**3
    else:                                   # series of sin(a/2)/a and of its derivative / a
        s, ds_over_a = 0.5 - a * a / 48, -1.0 / 24 + a * a / 960
    jac = np.empty((4, 3))
    jac[0] = -0.5 * s * phi
    jac[1:] = s * np.eye(3) + ds_over_a * np.outer(phi, phi)
    return p, jac


def _rotate_with_jacobian(q, f) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``C(q)``, ``C(q) f`` and ``∂(C(q) f)/∂q`` (3, 4), ``C`` as :func:`~cfdesign.rotations.to_matrix`."""
    C = quat.to_matrix(q)
    w, x, y, z = q
    f0, f1, f2 = f
    jac = 2.0 * np.array([
        [-z * f1 + y * f2, y * f1 + z * f2, -2 * y * f0 + x * f1 + w * f2, -2 * z * f0 - w * f1 + x * f2],
        [z * f0 - x * f2, y * f0 - 2 * x * f1 - w * f2, x * f0 + z * f2, w * f0 - 2 * z * f1 + y * f2],
        [-y * f0 + x * f1, z * f0 + w * f1 - 2 * x * f2, -w * f0 + z * f1 - 2 * y * f2, x * f0 + y * f1]])
    return C, C @ f, jac


def strapdown_step(x, gyro, accel, dt: float, *, jacobian: bool = True):
    """One strapdown prediction, seed 003 eq. (8), and its Jacobian (module docstring).

    Parameters
    ----------
    x : ndarray (22,)
        State ``[q, v, r, b_g, s_g, b_a, s_a]``.
    gyro, accel : ndarray (3,)
        Interval-mean readings ``ω̃`` (rad/s) and ``f̃`` (m/s²) in the body frame.
    dt : float
        Sampling period (s).
    jacobian : bool
        Also return ``F = ∂x(k+1)/∂x(k)``.

    Returns
    -------
    x_next : ndarray (22,)
    F : ndarray (22, 22), only if ``jacobian``
    """
    q, v = x[_Q], x[_V]
    omega = (gyro - x[_BG]) / x[_SG]                      # eq. (11) inverted
    force = (accel - x[_BA]) / x[_SA]
    p, dp = _delta_quaternion(omega * dt)
    C, Cf, dCf = _rotate_with_jacobian(q, force)
    acc_n = Cf + GRAVITY_ENU                              # eq. (3)
    x_next = x.copy()
    x_next[_Q] = _left(q) @ p
    x_next[_V] = v + acc_n * dt
    x_next[_R] = x[_R] + v * dt + acc_n * (0.5 * dt * dt)
    if not jacobian:
        return x_next
    F = np.eye(N_STATES)
    dq_dphi = _left(q) @ dp
    F[_Q, _Q] = _right(p)
    F[_Q, _BG] = dq_dphi * (-dt / x[_SG])
    F[_Q, _SG] = dq_dphi * (-dt * omega / x[_SG])
    dv_dba = C * (-1.0 / x[_SA])                          # ∂(C f)/∂b_a, then ∂/∂s_a
    dv_dsa = C * (-force / x[_SA])
    for rows, h in ((_V, dt), (_R, 0.5 * dt * dt)):
        F[rows, _Q] = dCf * h
        F[rows, _BA] = dv_dba * h
        F[rows, _SA] = dv_dsa * h
    F[_R, _V] = dt * np.eye(3)
    return x_next, F


def norm_observation(x) -> tuple[float, np.ndarray]:
    """Pseudo-observation ``e = 1 - |q|`` (seed 003 eq. (9)) and its Jacobian row ``H`` (22,)."""
    q = x[_Q]
    n = math.sqrt(float(q @ q))
    H = np.zeros(N_STATES)
    H[_Q] = -q / n
    return 1.0 - n, H


def _joseph(x, P, innovation, H, R):
    """Kalman update in Joseph form, symmetrised: returns ``x + K ν`` and ``P``."""
    PHt = P @ H.T
    K = np.linalg.solve(H @ PHt + R, PHt.T).T
    A = np.eye(len(x)) - K @ H
    P = A @ P @ A.T + K @ R @ K.T
    return x + K @ innovation, 0.5 * (P + P.T)


@dataclass(frozen=True)
class EkfEstimate:
    """Filtered estimates of :meth:`StrapdownEKF.run` at the ``M`` sample times.

    Attributes
    ----------
    quaternion : ndarray (M, 4)
        Attitude ``[w, x, y, z]`` body -> ENU (normalised copy of the state's ``q``).
    position, velocity : ndarray (M, 3)
        ENU position (m) and velocity (m/s).
    states : ndarray (M, 22)
        Full state ``[q, v, r, b_g, s_g, b_a, s_a]`` (``q`` as estimated, not normalised).
    covariance_min_eig, covariance_trace : ndarray (M,)
        Smallest eigenvalue and trace of the a posteriori covariance.
    covariance_asymmetry : ndarray (M,)
        ``max|P - P^T| / max|P|`` (0 after the symmetrisation).
    final_covariance : ndarray (22, 22)
        The last a posteriori covariance.
    """

    quaternion: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    states: np.ndarray
    covariance_min_eig: np.ndarray
    covariance_trace: np.ndarray
    covariance_asymmetry: np.ndarray
    final_covariance: np.ndarray


class StrapdownEKF:
    """Seed 003's 22-state strapdown INS / GPS / TRIAD extended Kalman filter (module docstring).

    Parameters
    ----------
    rate_hz : float
        IMU rate (Hz), the prediction rate.
    gyro_noise_std : float
        Gyro white noise per sample (rad/s).
    accel_noise_std : float
        Accelerometer white noise per sample (m/s²).
    gyro_bias_density, accel_bias_density : float
        Bias random-walk densities (rad/s/√s, m/s²/√s), seed 003 eq. (12).
    scale_density : float
        Scale-factor random-walk density (1/√s) of both sensors, eq. (13).
    gps_pos_std, gps_vel_std : float
        GPS position (m) and velocity (m/s) noise per axis.
    triad_std : float
        TRIAD attitude noise per axis (rad).
    mag_rate_hz : float, optional
        Magnetometer (TRIAD) rate; must divide ``rate_hz``.  Default: ``rate_hz``.
    mag_reference_enu : array_like (3,)
        Earth magnetic field in ENU (direction only matters; default magnetic North).
    norm_std : float
        Noise of the norm pseudo-observation (eq. (9)).
    initial_std : dict, optional
        Initial standard deviations; keys ``gyro_bias`` (rad/s, default 1°/s), ``accel_bias``
        (m/s², 0.2), ``scale`` (0.02), ``velocity`` (m/s, 10 unless given/measured).

    Notes
    -----
    Cost: about 185 µs per IMU step (Python 3.11, numpy 2, one core: prediction, norm
    pseudo-observation, TRIAD at 10 Hz, GPS at 1 Hz and the per-step eigenvalue diagnostics;
    100-s helicopter run of :mod:`cfdesign.sim.helicopter` at 50 Hz).
    """

    def __init__(self, rate_hz: float, *, gyro_noise_std: float, accel_noise_std: float, gyro_bias_density: float,
                 accel_bias_density: float, scale_density: float, gps_pos_std: float, gps_vel_std: float,
                 triad_std: float, mag_rate_hz: float | None = None, mag_reference_enu=(0.0, 1.0, 0.0),
                 norm_std: float = 1e-3, initial_std: dict | None = None):
        self.dt = 1.0 / float(rate_hz)
        mag_rate = float(rate_hz if mag_rate_hz is None else mag_rate_hz)
        self.mag_every = round(rate_hz / mag_rate)
        if self.mag_every < 1 or not math.isclose(self.mag_every * mag_rate, rate_hz, rel_tol=1e-9):
            raise InputError(f"mag_rate_hz {mag_rate:g} must divide rate_hz {rate_hz:g}")
        self.mag_reference = np.asarray(mag_reference_enu, dtype=float)
        self.init_std = {"gyro_bias": math.radians(1.0), "accel_bias": 0.2, "scale": 0.02, "velocity": 10.0,
                         **(initial_std or {})}
        self.gps_pos_std, self.gps_vel_std = float(gps_pos_std), float(gps_vel_std)
        self.Q = self._process_noise(gyro_noise_std, accel_noise_std, gyro_bias_density, accel_bias_density,
                                     scale_density)
        self.R_triad = (0.5 * triad_std) ** 2 * np.eye(4)
        self.R_pos, self.R_vel = gps_pos_std**2 * np.eye(3), gps_vel_std**2 * np.eye(3)
        self.R_norm = np.array([[norm_std**2]])
        eye = np.eye(N_STATES)
        self.H_q, self.H_v, self.H_r = eye[_Q], eye[_V], eye[_R]

    def _process_noise(self, gyro_std, accel_std, gyro_density, accel_density, scale_density) -> np.ndarray:
        """Discrete process noise at the IMU rate (module docstring)."""
        dt = self.dt
        Q = np.zeros((N_STATES, N_STATES))
        Q[_Q, _Q] = (0.5 * gyro_std * dt) ** 2 * np.eye(4)
        I3 = np.eye(3)
        Q[_V, _V] = accel_std**2 * dt**2 * I3
        Q[_R, _R] = accel_std**2 * dt**4 / 4 * I3
        Q[_V, _R] = Q[_R, _V] = accel_std**2 * dt**3 / 2 * I3
        for block, density in ((_BG, gyro_density), (_BA, accel_density), (_SG, scale_density),
                               (_SA, scale_density)):
            Q[block, block] = density**2 * dt * I3
        return Q

    def align(self, acc, mag) -> np.ndarray:
        """Initial attitude by TRIAD (seed 003 Sec. 3.1): specific force ~ up, field ~ reference."""
        return triad_quaternion(acc, mag, _UP, self.mag_reference)

    def _initial(self, acc0, mag0, position, velocity):
        x = np.zeros(N_STATES)
        x[_Q] = self.align(acc0, mag0)
        if not np.isfinite(x[_Q]).all():
            raise InputError("initial alignment failed: first accelerometer/magnetometer samples unusable")
        x[_SG] = x[_SA] = 1.0
        s = self.init_std
        v_std = s["velocity"] if velocity is None else self.gps_vel_std
        x[_V] = 0.0 if velocity is None else velocity
        x[_R] = 0.0 if position is None else position
        diag = np.concatenate([np.full(4, self.R_triad[0, 0]),
                               np.full(3, v_std**2), np.full(3, self.gps_pos_std**2),
                               np.full(3, s["gyro_bias"] ** 2), np.full(3, s["scale"] ** 2),
                               np.full(3, s["accel_bias"] ** 2), np.full(3, s["scale"] ** 2)])
        return x, np.diag(diag)

    def _triad_update(self, x, P, acc, mag, gyro):
        """TRIAD attitude observation (seed 003 eqs. (7), (10)); skipped on unusable vectors."""
        force = (acc - x[_BA]) / x[_SA]
        omega = (gyro - x[_BG]) / x[_SG]
        q = x[_Q]
        v_body = quat.to_matrix(q).T @ x[_V]
        g_body = centripetal_compensation(force, omega, v_body)
        z = self.align(g_body, mag)
        if not np.isfinite(z).all():
            return x, P
        if z @ q < 0:
            z = -z
        return _joseph(x, P, z - q, self.H_q, self.R_triad)

    def _norm_update(self, x, P):
        e, H = norm_observation(x)
        return _joseph(x, P, np.array([-e]), H[None, :], self.R_norm)

    def run(self, gyr, acc, mag, gps_pos_enu, gps_vel_enu=None, *, initial_position=None,
            initial_velocity=None) -> EkfEstimate:
        """Filter one run.

        Parameters
        ----------
        gyr, acc : array_like (N, 3)
            Body-frame gyro (rad/s) and accelerometer (m/s²) readings, row ``k`` the mean over
            ``[t_k, t_k+1]``.
        mag : array_like (M, 3)
            Magnetometer at the sample times ``t_k``, ``M`` = ``N`` or ``N + 1``; NaN rows skip.
            Only every ``rate_hz / mag_rate_hz``-th row is used.
        gps_pos_enu, gps_vel_enu : array_like (M, 3)
            GPS fixes in the local ENU frame (m, m/s) at ``t_k``; NaN rows (no fix) are skipped;
            ``gps_vel_enu`` may be ``None``.
        initial_position, initial_velocity : array_like (3,), optional
            Initial ENU position and velocity; default the first GPS fix (or zero).

        Returns
        -------
        EkfEstimate
            Estimates at the ``M`` times ``t_k`` (after that instant's observations).
        """
        gyr, acc, mag = (np.asarray(a, dtype=float) for a in (gyr, acc, mag))
        M = len(mag)
        gps_p = np.asarray(gps_pos_enu, dtype=float)
        gps_v = np.full((M, 3), np.nan) if gps_vel_enu is None else np.asarray(gps_vel_enu, dtype=float)
        if len(gyr) != len(acc) or M not in (len(gyr), len(gyr) + 1) or len(gps_p) != M or len(gps_v) != M:
            raise InputError("gyr, acc must have N rows and mag, gps M = N or N + 1 rows")
        if initial_position is None:
            initial_position = _first_finite(gps_p)
        if initial_velocity is None:
            initial_velocity = _first_finite(gps_v)
        x, P = self._initial(acc[0], mag[0], initial_position, initial_velocity)
        out = {k: np.empty((M, n)) for k, n in (("states", N_STATES), ("diag", 3))}
        for k in range(M):
            if k > 0:
                x, F = strapdown_step(x, gyr[k - 1], acc[k - 1], self.dt)
                P = F @ P @ F.T + self.Q
                x, P = self._norm_update(x, 0.5 * (P + P.T))
            x, P = self._observe(k, x, P, gyr, acc, mag[k], gps_p[k], gps_v[k])
            out["states"][k] = x
            out["diag"][k] = (np.linalg.eigvalsh(P)[0], np.trace(P), np.abs(P - P.T).max() / np.abs(P).max())
        s = out["states"]
        return EkfEstimate(quaternion=quat.normalize(s[:, _Q]), position=s[:, _R].copy(), velocity=s[:, _V].copy(),
                           states=s, covariance_min_eig=out["diag"][:, 0], covariance_trace=out["diag"][:, 1],
                           covariance_asymmetry=out["diag"][:, 2], final_covariance=P)

    def _observe(self, k, x, P, gyr, acc, mag_k, pos_k, vel_k):
        """All observations available at sample ``k``: TRIAD (at its rate), GPS position, velocity."""
        if k % self.mag_every == 0 and np.isfinite(mag_k).all():
            i = min(k, len(acc) - 1)
            j = max(k - 1, 0)
            x, P = self._triad_update(x, P, 0.5 * (acc[i] + acc[j]), mag_k, 0.5 * (gyr[i] + gyr[j]))
        if np.isfinite(pos_k).all():
            x, P = _joseph(x, P, pos_k - x[_R], self.H_r, self.R_pos)
        if np.isfinite(vel_k).all():
            x, P = _joseph(x, P, vel_k - x[_V], self.H_v, self.R_vel)
        return x, P


def _first_finite(rows):
    """First all-finite row of ``rows`` or ``None``."""
    ok = np.flatnonzero(np.isfinite(rows).all(axis=1))
    return None if len(ok) == 0 else rows[ok[0]]


# ---------------------------------------------------------------------------- seed 002
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
        Standard deviation of the chord-heading measurement used at that sample (eq. (13)), NaN
        when there was none.
    gps_std_used : ndarray (N,)
        GPS position standard deviation used at that sample (by mode), NaN without a fix.
    """

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    alpha: np.ndarray
    covariance: np.ndarray
    heading_std: np.ndarray
    gps_std_used: np.ndarray


def planar_step(state, rho: float, omega: float, dt: float, *, jacobian: bool = True):
    """Seed 002 eq. (4) and its Jacobians ``J_x`` (4, 4), ``J_u`` (4, 2) with ``u = [ρ, ω]``."""
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
    """Seed 002's EKF: pose ``[x, y, θ]`` and odometer scale ``α`` from odometer, gyro and GPS (module docstring).

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
        Initial standard deviations of ``[x, y, θ, α]``.

    Notes
    -----
    Cost: about 15 µs per sample (Python 3.11, numpy 2; 3000 samples at 10 Hz, GPS at 1 Hz).
    """

    def __init__(self, *, odo_noise_std: float, gyro_noise_std: float, gps_std: dict | None = None,
                 kappa_omega: float, kappa_rho: float, sigma_heading, alpha_noise_std: float = 1e-5,
                 initial_std=(10.0, 10.0, math.pi, 0.1)):
        self.gps_std = dict(gps_std or {"single": 3.0, "dgps": 0.5})
        modes = set(self.gps_std)
        self.sigma_heading = (dict(sigma_heading) if isinstance(sigma_heading, dict)
                              else dict.fromkeys(modes, float(sigma_heading)))
        if set(self.sigma_heading) != modes:
            raise InputError("sigma_heading must give one value per GPS mode")
        self.U = np.diag([odo_noise_std**2, gyro_noise_std**2])
        self.kappa_omega, self.kappa_rho = float(kappa_omega), float(kappa_rho)
        self.alpha_var = alpha_noise_std**2
        self.initial_std = np.asarray(initial_std, dtype=float)

    def heading_std(self, mode: str, turned: float, travelled: float) -> float:
        """``σ_θ (Σ|ω| + κ_ω) / (Σρ + κ_ρ)`` of seed 002 eq. (13) (module docstring's reading)."""
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
        """
        rho, omega = np.asarray(distance, dtype=float), np.asarray(gyro_z, dtype=float)
        N = len(rho)
        dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (N,))
        gps = np.asarray(gps_xy, dtype=float)
        mode = np.asarray(gps_mode).astype(str)
        if initial_state is None:
            first = _first_finite(gps)
            initial_state = [*(np.zeros(2) if first is None else first), 0.0, 1.0]
        state, P = np.asarray(initial_state, dtype=float).copy(), np.diag(self.initial_std**2)
        out = np.empty((N, 4))
        cov = np.empty((N, 4, 4))
        used = np.full((N, 2), np.nan)
        last_fix, turned, travelled = None, 0.0, 0.0
        zeta = np.zeros((4, 4))
        zeta[3, 3] = self.alpha_var
        for k in range(N):
            state, Jx, Ju = planar_step(state, rho[k], omega[k], dt[k])
            P = Jx @ P @ Jx.T + Ju @ self.U @ Ju.T + zeta          # eq. (5)
            P = 0.5 * (P + P.T)
            turned += abs(omega[k]) * dt[k]
            travelled += rho[k]
            if np.isfinite(gps[k]).all() and mode[k] in self.gps_std:
                state, P, used[k] = self._gps_update(state, P, gps[k], mode[k], last_fix, turned, travelled)
                last_fix, turned, travelled = gps[k], 0.0, 0.0
            state[2] = _wrap(state[2])
            out[k], cov[k] = state, P
        return PlanarEstimate(x=out[:, 0], y=out[:, 1], theta=out[:, 2], alpha=out[:, 3], covariance=cov,
                              heading_std=used[:, 1], gps_std_used=used[:, 0])

    def _gps_update(self, state, P, fix, mode, last_fix, turned, travelled):
        """Seed 002 eqs. (6)-(13): position, plus the chord heading when a previous fix exists."""
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
        state, P = _joseph(state, P, innovation, H, R)
        return state, P, (sg, s_head)


def _wrap(angle):
    """:func:`cfdesign.linear.wrap_scalar`, passing a non-finite angle through (a NaN reading stays NaN)."""
    return wrap_scalar(angle) if math.isfinite(angle) else angle
