"""The 22-state strapdown INS / GPS / TRIAD extended Kalman filter of the low-cost 3D localization system.

The EKF baseline of *Low-cost 3D localization with strapdown IMU, GPS and 3-axis
magnetometer* (equation numbers below are that paper's): quaternion, velocity and position
state with online bias and scale-factor states, TRIAD alignment and observations, and a
quaternion-norm pseudo-observation.  Frames as :mod:`cfdesign.rotations`: ENU local frame,
FLU body, quaternions ``[w, x, y, z]`` body -> ENU, gravity
:data:`cfdesign.rotations.GRAVITY_ENU` (``a_n = R_nb f_b + g_n``).

State (22): ``x = [q (4), v (3), r (3), b_g (3), s_g (3), b_a (3), s_a (3)]`` - attitude, ENU
velocity and position, gyro bias and scale factor, accelerometer bias and scale factor.

* Sensor model, eq. (11): ``f̃ = s_a ∘ f + b_a + w`` (per axis; likewise the gyro),
  so the corrected inputs are ``ω = (ω̃ - b_g) / s_g`` and ``f = (f̃ - b_a) / s_a``; ``s`` is the
  scale factor itself (1 for a perfect sensor), ``b`` and ``s`` are random walks (eqs. (12)-(13)).
* Prediction, eq. (8) (strapdown mechanisation of eqs. (2)-(4)), our reading of the
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
    centripetal term, ``f - ω × v_b`` (Vasconcelos et al. Sec. 2.2,
    :func:`cfdesign.nav.mps.centripetal_compensation`), which the paper leaves out;
  - GPS position and velocity in the local frame (eqs. (5)-(6) give the conversion; inputs
    here are already ENU), ``H`` selects ``r`` or ``v``; NaN rows are skipped;
  - the norm pseudo-observation ``e = 1 - |q|`` (eq. (9)), measured as 0 after every
    prediction, ``H = [-q^T / |q|, 0]``, ``R = σ_norm²``.

* Initial alignment: TRIAD on the first accelerometer and magnetometer samples
  (Sec. 3.1), biases 0, scale factors 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import rotations as rot
from ..errors import InputError
from ..rotations import GRAVITY_ENU
from ..runtime.filter import usable
from .attitude_inputs import finite_vector, held_rows, rate, rows
from .kalman_update import first_finite, joseph_update, noise_figure
from .mps import centripetal_compensation
from .triad import triad_quaternion

__all__ = ["N_STATES", "EkfEstimate", "StrapdownEKF", "strapdown_step", "norm_observation"]

#: number of states of :class:`StrapdownEKF`
N_STATES = 22
_Q, _V, _R = slice(0, 4), slice(4, 7), slice(7, 10)
_BG, _SG, _BA, _SA = slice(10, 13), slice(13, 16), slice(16, 19), slice(19, 22)
_UP = np.array([0.0, 0.0, 1.0])


def _present(**readings) -> tuple:
    """Each ``(M, 3)`` array with its unusable rows (not finite, or beyond the reading limit) made
    NaN, and ``{name: rows given but unusable}``."""
    out, missing = [], {}
    for name, a in readings.items():
        bad = ~usable(a).all(axis=1)
        missing[name] = int((bad & ~np.isnan(a).all(axis=1)).sum())
        out.append(np.where(bad[:, None], np.nan, a))
    return (*out, missing)


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
    p = rot.from_rotation_vector(phi)
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
    C = rot.to_matrix(q)
    w, x, y, z = q
    f0, f1, f2 = f
    jac = 2.0 * np.array([
        [-z * f1 + y * f2, y * f1 + z * f2, -2 * y * f0 + x * f1 + w * f2, -2 * z * f0 - w * f1 + x * f2],
        [z * f0 - x * f2, y * f0 - 2 * x * f1 - w * f2, x * f0 + z * f2, w * f0 - 2 * z * f1 + y * f2],
        [-y * f0 + x * f1, z * f0 + w * f1 - 2 * x * f2, -w * f0 + z * f1 - 2 * y * f2, x * f0 + y * f1]])
    return C, C @ f, jac


def strapdown_step(x, gyro, accel, dt: float, *, jacobian: bool = True):
    """One strapdown prediction, eq. (8) of the low-cost 3D localization paper, and its Jacobian (module docstring).

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
        The predicted state ``x(k+1)``, same layout as ``x``.
    F : ndarray (22, 22), only if ``jacobian``
        The state-transition Jacobian ``∂x(k+1)/∂x(k)``.
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
    for block, h in ((_V, dt), (_R, 0.5 * dt * dt)):
        F[block, _Q] = dCf * h
        F[block, _BA] = dv_dba * h
        F[block, _SA] = dv_dsa * h
    F[_R, _V] = dt * np.eye(3)
    return x_next, F


def norm_observation(x) -> tuple[float, np.ndarray]:
    """The quaternion-norm pseudo-observation ``e = 1 - |q|`` (eq. (9), module docstring).

    Parameters
    ----------
    x : ndarray, shape (22,)
        The EKF state.

    Returns
    -------
    e : float
        Innovation of the pseudo-observation.
    H : ndarray, shape (22,)
        Its Jacobian row.
    """
    q = x[_Q]
    n = math.sqrt(float(q @ q))
    H = np.zeros(N_STATES)
    H[_Q] = -q / n
    return 1.0 - n, H


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
    missing : dict
        Readings treated as missing (:meth:`StrapdownEKF.run`, Notes): ``{'gyr', 'acc', 'mag',
        'gps_pos', 'gps_vel'}``.
    """

    quaternion: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    states: np.ndarray
    covariance_min_eig: np.ndarray
    covariance_trace: np.ndarray
    covariance_asymmetry: np.ndarray
    final_covariance: np.ndarray
    missing: dict = field(default_factory=dict)


class StrapdownEKF:
    """The 22-state strapdown INS / GPS / TRIAD EKF of the low-cost 3D localization paper (module docstring).

    Parameters
    ----------
    rate_hz : float
        IMU rate (Hz), the prediction rate.
    gyro_noise_std : float
        Gyro white noise per sample (rad/s).
    accel_noise_std : float
        Accelerometer white noise per sample (m/s²).
    gyro_bias_density, accel_bias_density : float
        Bias random-walk densities (rad/s/√s, m/s²/√s), eq. (12).
    scale_density : float
        Scale-factor random-walk density (1/√s) of both sensors, eq. (13).
    gps_pos_std, gps_vel_std : float
        GPS position (m) and velocity (m/s) noise per axis.
    triad_std : float
        TRIAD attitude noise per axis (rad).
    mag_rate_hz : float, optional
        Magnetometer (TRIAD) rate (Hz); must divide ``rate_hz``.  Default: ``rate_hz``.
    mag_reference_enu : array_like (3,)
        Earth magnetic field in ENU (direction only matters; default magnetic North).
    norm_std : float
        Noise (standard deviation, unitless) of the norm pseudo-observation (eq. (9)).
    initial_std : dict, optional
        Initial standard deviations; keys ``gyro_bias`` (rad/s, default 1°/s), ``accel_bias``
        (m/s², 0.2), ``scale`` (0.02), ``velocity`` (m/s, 10 unless given/measured).
    gyro_range_rps, accel_range_mps2 : float
        Readings whose norm is beyond these are impossible and treated as missing (defaults 100
        rad/s and 1000 m/s², as :class:`~cfdesign.nav.AttitudeParams`).

    Raises
    ------
    InputError
        A rate outside [1e-3, 1e6] Hz, a ``mag_rate_hz`` that does not divide ``rate_hz``, a
        noise figure that is not a finite positive number (a density: non-negative), a
        ``mag_reference_enu`` that is not a finite non-zero 3-vector, or an ``initial_std``
        with an unknown key or a bad value; the message names the argument.

    Notes
    -----
    Cost: about 280 µs per IMU step (Python 3.11, numpy 2, one core: prediction, norm
    pseudo-observation, TRIAD at 10 Hz, GPS at 1 Hz and the per-step eigenvalue diagnostics;
    100-s helicopter run of :mod:`cfdesign.sim.helicopter` at 50 Hz), 6.4 times the adaptive CF's in the
    same run (``python benchmarks/bench_compare.py --seeds 1``).
    """

    def __init__(self, rate_hz: float, *, gyro_noise_std: float, accel_noise_std: float, gyro_bias_density: float,
                 accel_bias_density: float, scale_density: float, gps_pos_std: float, gps_vel_std: float,
                 triad_std: float, mag_rate_hz: float | None = None, mag_reference_enu=(0.0, 1.0, 0.0),
                 norm_std: float = 1e-3, initial_std: dict | None = None, gyro_range_rps: float = 100.0,
                 accel_range_mps2: float = 1000.0):
        rate_hz = rate(rate_hz, error=InputError)
        self.dt = 1.0 / rate_hz
        mag_rate = rate_hz if mag_rate_hz is None else rate(mag_rate_hz, "mag_rate_hz", error=InputError)
        self.mag_every = round(rate_hz / mag_rate)
        if self.mag_every < 1 or not math.isclose(self.mag_every * mag_rate, rate_hz, rel_tol=1e-9):
            raise InputError(f"mag_rate_hz {mag_rate:g} must divide rate_hz {rate_hz:g}")
        self.gyro_range_rps = noise_figure("gyro_range_rps", gyro_range_rps)
        self.accel_range_mps2 = noise_figure("accel_range_mps2", accel_range_mps2)
        stds = {"gyro_noise_std": gyro_noise_std, "accel_noise_std": accel_noise_std, "gps_pos_std": gps_pos_std,
                "gps_vel_std": gps_vel_std, "triad_std": triad_std, "norm_std": norm_std}
        densities = {"gyro_bias_density": gyro_bias_density, "accel_bias_density": accel_bias_density,
                     "scale_density": scale_density}
        stds = {name: noise_figure(name, value) for name, value in stds.items()}
        densities = {name: noise_figure(name, value, allow_zero=True) for name, value in densities.items()}
        self.mag_reference = rows("mag_reference_enu", [mag_reference_enu], 3, error=InputError)[0]
        if not (np.isfinite(self.mag_reference).all() and np.abs(self.mag_reference).sum() > 0):
            raise InputError(f"mag_reference_enu must be a finite non-zero 3-vector, got {mag_reference_enu!r}")
        if initial_std is not None and not isinstance(initial_std, dict):
            raise InputError(f"initial_std must be a dict, got {type(initial_std).__name__}")
        self.init_std = {"gyro_bias": math.radians(1.0), "accel_bias": 0.2, "scale": 0.02, "velocity": 10.0}
        unknown = sorted(map(str, set(initial_std or {}) - set(self.init_std)))
        if unknown:
            raise InputError(f"initial_std: unknown key(s) {', '.join(unknown)}; known: {', '.join(self.init_std)}")
        for key, value in (initial_std or {}).items():
            self.init_std[key] = noise_figure(f"initial_std[{key!r}]", value)
        gyro_noise_std, accel_noise_std, gps_pos_std, gps_vel_std, triad_std, norm_std = stds.values()
        gyro_bias_density, accel_bias_density, scale_density = densities.values()
        self.gps_pos_std, self.gps_vel_std = gps_pos_std, gps_vel_std
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
        """Initial attitude by TRIAD (Sec. 3.1): specific force ~ up, field ~ reference.

        Parameters
        ----------
        acc : array_like, shape (3,)
            Specific force in the body frame (m/s²), at rest.
        mag : array_like, shape (3,)
            Magnetic field in the body frame (any unit).

        Returns
        -------
        ndarray, shape (4,)
            ``[w, x, y, z]``, body -> ENU; NaN when the vectors are parallel or zero.
        """
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
        """TRIAD attitude observation (eqs. (7), (10)); skipped on unusable vectors."""
        force = (acc - x[_BA]) / x[_SA]
        omega = (gyro - x[_BG]) / x[_SG]
        q = x[_Q]
        v_body = rot.to_matrix(q).T @ x[_V]
        g_body = centripetal_compensation(force, omega, v_body)
        z = self.align(g_body, mag)
        if not np.isfinite(z).all():
            return x, P
        if z @ q < 0:
            z = -z
        return joseph_update(x, P, z - q, self.H_q, self.R_triad)

    def _norm_update(self, x, P):
        e, H = norm_observation(x)
        return joseph_update(x, P, np.array([-e]), H[None, :], self.R_norm)

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

        Raises
        ------
        InputError
            An array that is not of real numbers or of the wrong shape, an initial position or
            velocity that is not three finite numbers, or unusable first accelerometer and
            magnetometer samples (the alignment fails); the message names the argument.
            Also an update the noise figures make singular or not finite
            (:func:`~cfdesign.nav.kalman_update.joseph_update`).

        Notes
        -----
        Readings that are not finite or beyond :data:`~cfdesign.runtime.filter.READING_LIMIT`
        (a rate or specific force: with a norm beyond ``gyro_range_rps`` or ``accel_range_mps2``)
        are missing: a gyro or accelerometer row holds the last usable one (before the first,
        the first), a field or GPS row is skipped; every one is counted in
        ``EkfEstimate.missing`` (for the field and the fixes, the rows given but unusable: a
        NaN row is no reading and is not counted).
        """
        gyr = rows("gyr", gyr, 3, error=InputError)
        if len(gyr) == 0:
            raise InputError("gyr is empty: need at least one sample")
        acc = rows("acc", acc, 3, len(gyr), error=InputError)
        mag = rows("mag", mag, 3, error=InputError)
        M = len(mag)
        if M not in (len(gyr), len(gyr) + 1) or M == 0:
            raise InputError(f"mag has {M} rows: M = N or N + 1 (N = {len(gyr)}, the rows of gyr) and at least one "
                             "are needed")
        gps_p = rows("gps_pos_enu", gps_pos_enu, 3, M, error=InputError)
        gps_v = np.full((M, 3), np.nan) if gps_vel_enu is None else rows("gps_vel_enu", gps_vel_enu, 3, M,
                                                                          error=InputError)
        gyr, missing_gyr = held_rows(gyr, self.gyro_range_rps)
        acc, missing_acc = held_rows(acc, self.accel_range_mps2)
        mag, gps_p, gps_v, missing = _present(mag=mag, gps_pos=gps_p, gps_vel=gps_v)
        missing = {"gyr": missing_gyr, "acc": missing_acc, **missing}
        initial_position, initial_velocity = (
            first_finite(fixes) if value is None else finite_vector(name, value, error=InputError)
            for name, value, fixes in (("initial_position", initial_position, gps_p),
                                       ("initial_velocity", initial_velocity, gps_v)))
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
        return EkfEstimate(quaternion=rot.normalize(s[:, _Q]), position=s[:, _R].copy(), velocity=s[:, _V].copy(),
                           states=s, covariance_min_eig=out["diag"][:, 0], covariance_trace=out["diag"][:, 1],
                           covariance_asymmetry=out["diag"][:, 2], final_covariance=P, missing=missing)

    def _observe(self, k, x, P, gyr, acc, mag_k, pos_k, vel_k):
        """All observations available at sample ``k``: TRIAD (at its rate), GPS position, velocity."""
        if k % self.mag_every == 0 and np.isfinite(mag_k).all():
            i = min(k, len(acc) - 1)
            j = max(k - 1, 0)
            x, P = self._triad_update(x, P, 0.5 * (acc[i] + acc[j]), mag_k, 0.5 * (gyr[i] + gyr[j]))
        if np.isfinite(pos_k).all():
            x, P = joseph_update(x, P, pos_k - x[_R], self.H_r, self.R_pos)
        if np.isfinite(vel_k).all():
            x, P = joseph_update(x, P, vel_k - x[_V], self.H_v, self.R_vel)
        return x, P
