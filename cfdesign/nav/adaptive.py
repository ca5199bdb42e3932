"""The adaptive complementary filter of Alves Neto et al.: attitude (IMU + compass) and position (GPS + odometry).

Alves Neto et al., *Adaptive complementary filtering algorithm for mobile robot localization*,
Sec. 3 (equation numbers below are that paper's).  Frames as the rest of :mod:`cfdesign.nav`: ENU, FLU body,
quaternions ``[w, x, y, z]`` body -> ENU, Euler angles ZYX ``[yaw ψ, pitch θ, roll φ]``.

Reading of the (garbled) equations
----------------------------------
* Accelerometer tilt, eqs. (3)-(4), written in NED with a forward-right-down body:
  ``θ_a = asin(a_x/|a|)``, ``φ_a = asin(-a_y/(|a| cos θ_a))`` with ``a`` the specific force.  In
  ENU/FLU the body y axis and the sense of pitch flip (our θ > 0 is nose *down*), giving
  ``θ_a = asin(-f_x/|f|)``, ``φ_a = asin(f_y/(|f| cos θ_a))``.  Since ``|f| cos θ_a =
  sqrt(f_y² + f_z²)`` these are the pendular angles of :func:`cfdesign.nav.mps.mps_euler`
  (``atan2`` forms, equal for ``f_z > 0``), which we reuse.
* Magnetic heading ψ_m: the paper uses a levelled two-axis compass; we use the tilt-compensated
  field of :func:`cfdesign.nav.mps.mps_euler` (tilt from the accelerometer, minus the declination).
* Gyro branch, eqs. (10)-(11): ``q' = ½ Ω(g) q``, discretised exactly for a rate held
  over the step, ``q[k] = q[k-1] ⊗ exp(g T / 2)``; its Euler angles, eqs. (7)-(9), by
  :func:`cfdesign.rotations.to_euler`.  The initial attitude, the paper's ``q(0)``, is the
  accelerometer/compass attitude of the first row.
* Fusion, eqs. (12)-(14): ``φ = G_l * φ_a + G_h * φ_g`` (likewise θ, ψ) with first-order
  low/high-pass filters sharing one cut-off ω_c.  With the exact discretisation ``α = exp(-ω_c T)``
  of the pole, ``G_l = (1 - α)/(1 - α z⁻¹)`` and ``G_h = (1 - z⁻¹) α/(1 - α z⁻¹)`` (``G_l + G_h = 1``),
  so the sum obeys ``φ[k] = φ_p + (1 - α)(φ_a[k] - φ_p)``, ``φ_p = φ[k-1] + Δφ_g[k]``.  The gyro
  increment ``Δφ_g`` is taken from the *fused* attitude propagated by the gyro
  (``q_p = q[k-1] ⊗ exp(g T/2)``, ``Δφ_g = φ(q_p) - φ[k-1]``): increments of an open-loop gyro
  quaternion would be computed on a drifting attitude.  The yaw innovation and increment are
  wrapped to ``(-π, π]`` (wrap-safe at ±π).  The recursion also holds with a time-varying ω_c.
* Adaptive cut-offs, eqs. (15)-(17): ``ω_φ = k_φ exp(-|g0 - |a||)``, ``ω_θ = k_θ exp(-|g0 - |a||)``
  (``|a|`` in m/s²), ``ω_ψ = k_ψ exp(-max(|φ|, |θ|))`` with the previous fused roll and pitch (rad).
* Dead reckoning, eq. (18): ``x_o' = v_0 [cosψ cosθ, sinψ cosθ, sinθ]`` in NED with nose-up θ;
  in ENU with our nose-down θ the forward axis is ``[cosψ cosθ, sinψ cosθ, -sinθ]``.
* Position fusion, eqs. (19)-(24): ``x = G_l * x_g + G_h * x_o`` per ENU axis with one cut-off
  ``ω_c = min(ω_v, ω_N)`` (eq. 22), ``ω_v = k_p (1 - exp(-v_0/(v_max - v_0)))`` (eq. 23; ``k_p`` for
  ``v_0 >= v_max``, ``|v_0|`` used), ``ω_N = k_p (1 - exp(-N_sat/(N_max - N_sat)))`` if ``N_sat > 3``
  else 0 (eq. 24; ``k_p`` for ``N_sat >= N_max``).  GPS fixes are slower than the filter: the
  low-pass input is missing between fixes, so the steps since the last fix are applied at the
  next fix at once, ``x = x_p + (1 - Π α_j)(x_g - x_p)`` with ``α_j = exp(-ω_c[j] T)`` - which
  is the per-step recursion with the fix held.  ``ω_c = 0`` (three satellites or fewer, or
  standstill) is pure dead reckoning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import rotations as rot
from ..errors import InputError
from ..linear import wrap_scalar
from ..runtime.filter import usable
from .attitude_inputs import finite_vector, held_rows, rate, rows
from .mps import mps_euler

__all__ = ["AdaptiveEstimate", "AdaptiveCF", "attitude_cutoffs", "position_cutoff", "cutoff_plot"]

G0_M_S2 = 9.80665


@dataclass(frozen=True)
class AdaptiveEstimate:
    """Estimates at the ``N`` input rows.

    Attributes
    ----------
    quaternion : ndarray, shape (N, 4)
        Attitude ``[w, x, y, z]``, body -> ENU.
    euler : ndarray, shape (N, 3)
        ``[yaw, pitch, roll]`` (rad), yaw in ``(-π, π]``.
    position : ndarray, shape (N, 3)
        ENU position (m); NaN before the first GPS fix unless an initial position is given.
    cutoff_attitude : ndarray, shape (N, 3)
        Adapted cut-offs (rad/s) for roll, pitch, yaw (0 where a reading is missing).
    cutoff_position : ndarray, shape (N,)
        Adapted position cut-off (rad/s).
    missing : dict
        Readings treated as missing (:meth:`AdaptiveCF.run`, Notes): ``{'gyr', 'odometry_speed',
        'gps_enu'}``.
    """

    quaternion: np.ndarray
    euler: np.ndarray
    position: np.ndarray
    cutoff_attitude: np.ndarray
    cutoff_position: np.ndarray
    missing: dict = field(default_factory=dict)


def attitude_cutoffs(acc, k_phi, k_theta, g0=G0_M_S2):
    """Roll and pitch cut-offs, Alves Neto et al. eqs. (15)-(16): ``k exp(-|g0 - |a||)``.

    Parameters
    ----------
    acc : array_like, shape (N, 3)
        Specific force in the body frame (m/s²).
    k_phi, k_theta : float
        Nominal roll and pitch cut-offs (rad/s).
    g0 : float
        Gravity (m/s²).

    Returns
    -------
    ndarray, shape (N, 2)
        Roll and pitch cut-offs (rad/s): nominal at rest, smaller under acceleration.
    """
    shrink = np.exp(-np.abs(g0 - np.linalg.norm(np.asarray(acc, dtype=float), axis=-1)))
    return np.stack([k_phi * shrink, k_theta * shrink], axis=-1)


def _saturating(x, x_max, k):
    """``k (1 - exp(-x/(x_max - x)))`` for ``0 <= x < x_max``, ``k`` beyond ``x_max`` (eqs. 23-24)."""
    x = np.asarray(x, dtype=float)
    below = x < x_max
    with np.errstate(divide="ignore", invalid="ignore"):
        value = k * (1.0 - np.exp(-x / np.where(below, x_max - x, 1.0)))
    return np.where(below, value, k)


def position_cutoff(speed, n_satellites, k_p, v_max, n_max):
    """Position cut-off, Alves Neto et al. eqs. (22)-(24): ``min(ω_v, ω_N)``.

    Parameters
    ----------
    speed : array_like, shape (N,)
        Forward speed (m/s); NaN counts as 0.
    n_satellites : array_like, shape (N,)
        Satellites seen.
    k_p : float
        Nominal cut-off (rad/s).
    v_max : float
        Maximum speed (m/s), eq. (23).
    n_max : float
        Satellite count of full confidence, eq. (24).

    Returns
    -------
    ndarray, shape (N,)
        Cut-off (rad/s); 0 with 3 satellites or fewer (the GPS is ignored).
    """
    w_v = _saturating(np.abs(np.nan_to_num(np.asarray(speed, dtype=float))), v_max, k_p)
    n = np.asarray(n_satellites, dtype=float)
    w_n = np.where(n > 3, _saturating(np.where(n > 3, n, 0.0), n_max, k_p), 0.0)
    return np.minimum(w_v, w_n)


class AdaptiveCF:
    """The adaptive complementary filter of Alves Neto et al. (module docstring).

    Parameters
    ----------
    rate_hz : float
        Filter (input row) rate (Hz); the paper runs at 10 Hz.
    k_phi, k_theta, k_psi : float
        Nominal roll, pitch and yaw cut-offs (rad/s), eqs. (15)-(17).  Defaults 0.5, 0.5, 0.3:
        a gyro bias ``b`` costs ``b/k`` (0.2° for 0.1 °/s at 0.5 rad/s, 0.33° at 0.3 rad/s) and
        accelerations lasting longer than ``1/k`` (2 s) leak into the tilt.
    k_p : float
        Nominal position cut-off (rad/s), eqs. (23)-(24).  Default 0.05: a 2.5-m GPS noise at
        1 Hz is cut to ~0.4 m, an odometry drift ``d`` (m/s) costs ``d/k_p``.
    v_max : float
        Maximum speed of the robot (m/s), eq. (23); default 2.
    n_max : float
        Satellite count of full confidence, eq. (24); default 12 (must exceed 3).
    g0 : float
        Gravity (m/s²), eqs. (15)-(16).
    declination_rad : float
        Magnetic declination (rad, positive east), subtracted from the magnetic heading.

    Raises
    ------
    InputError
        A rate outside [1e-3, 1e6] Hz, a parameter that is not a finite number of the right
        sign, or ``n_max <= 3``.

    Notes
    -----
    Cost: roll/pitch cut-offs, pendular and magnetic angles, gyro increments, the position
    cut-off and the dead-reckoning increments are vectorised; the attitude and position
    recursions are loops over the rows, about 43 µs per step in all (Python 3.11, x86-64,
    15 000 steps of :func:`cfdesign.sim.ground.ground_robot_scenario` in 0.64 s).
    """

    def __init__(self, rate_hz, *, k_phi=0.5, k_theta=0.5, k_psi=0.3, k_p=0.05, v_max=2.0, n_max=12.0,
                 g0=G0_M_S2, declination_rad=0.0):
        self.rate_hz = rate(rate_hz, error=InputError)
        self.k_phi, self.k_theta, self.k_psi, self.k_p = (_number(n, v) for n, v in (
            ("k_phi", k_phi), ("k_theta", k_theta), ("k_psi", k_psi), ("k_p", k_p)))
        self.v_max = _number("v_max", v_max, positive=True)
        self.n_max = _number("n_max", n_max, positive=True)
        if self.n_max <= 3:
            raise InputError(f"n_max: more than 3 satellites are needed, got {n_max!r}")
        self.g0 = _number("g0", g0, positive=True)
        self.declination_rad = _number("declination_rad", declination_rad, signed=True)

    @property
    def dt_s(self) -> float:
        """Time between input rows (s): ``1 / rate_hz``."""
        return 1.0 / self.rate_hz

    def run(self, gyr, acc, mag, odometry_speed, gps_enu, n_satellites, *, initial_position=None) -> AdaptiveEstimate:
        """Filter a record; row ``k`` of every input belongs to one time, rows ``1/rate_hz`` apart.

        Parameters
        ----------
        gyr : array_like, shape (N, 3)
            Body rate (rad/s, body frame), the mean over the interval ending at row ``k``.
        acc : array_like, shape (N, 3)
            Specific force (m/s², body frame).
        mag : array_like, shape (N, 3)
            Magnetic field (body frame, any unit).
        odometry_speed : array_like, shape (N,)
            Forward speed (m/s).
        gps_enu : array_like, shape (N, 3)
            Position fixes (m, ENU frame); NaN rows without a fix.
        n_satellites : array_like, shape (N,)
            Satellites seen.
        initial_position : array_like, shape (3,), optional
            Position at row 0; default: the estimate starts at the first GPS fix (NaN before it).

        Returns
        -------
        AdaptiveEstimate
            Attitude, position and the adapted cut-offs at every row.

        Raises
        ------
        InputError
            An input that is not an array of real numbers or of the wrong shape, or an
            ``initial_position`` that is not three finite numbers (the message names it).

        Notes
        -----
        A rate or speed that is not finite or beyond
        :data:`~cfdesign.runtime.filter.READING_LIMIT` is missing and holds the last usable one
        (before the first, the first); such a fix is skipped; an unusable specific force or
        field skips its correction (cut-off 0).  Rates, speeds and fixes treated as missing are
        counted in ``AdaptiveEstimate.missing`` (a NaN fix row is no fix and is not counted).
        """
        gyr, acc, mag, gps = (_rows(n, v, 3) for n, v in (("gyr", gyr), ("acc", acc), ("mag", mag),
                                                          ("gps_enu", gps_enu)))
        speed, n_sat = _rows("odometry_speed", odometry_speed), _rows("n_satellites", n_satellites)
        lengths = {len(v) for v in (gyr, acc, mag, gps, speed, n_sat)}
        if len(lengths) != 1 or 0 in lengths:
            raise InputError("gyr, acc, mag, odometry_speed, gps_enu, n_satellites: one non-zero number of rows is "
                            f"needed, got {[len(v) for v in (gyr, acc, mag, speed, gps, n_sat)]}")
        if initial_position is not None:
            initial_position = finite_vector("initial_position", initial_position, error=InputError)
        gyr, missing_gyr = held_rows(gyr)
        speed, missing_speed = held_rows(speed)
        fix_given = ~np.isnan(gps).all(axis=1)
        gps = np.where(usable(gps).all(axis=1)[:, None], gps, np.nan)
        missing = {"gyr": missing_gyr, "odometry_speed": missing_speed,
                   "gps_enu": int((fix_given & np.isnan(gps).all(axis=1)).sum())}
        euler, cut_att = self._attitude(gyr, acc, mag)
        cut_pos = position_cutoff(speed, n_sat, self.k_p, self.v_max, self.n_max)
        position = self._position(euler, speed, gps, cut_pos, initial_position)
        return AdaptiveEstimate(quaternion=rot.from_euler(euler), euler=euler, position=position,
                                cutoff_attitude=cut_att, cutoff_position=cut_pos, missing=missing)

    # ------------------------------------------------------------------ attitude
    def _attitude(self, gyr, acc, mag):
        """Fused ``[yaw, pitch, roll]`` (N, 3) and the cut-offs (N, 3) for roll, pitch, yaw."""
        T = self.dt_s
        measured = mps_euler(acc, mag, declination_rad=self.declination_rad)        # [ψ_m, θ_a, φ_a]
        cut = np.zeros((len(acc), 3))
        cut[:, :2] = np.nan_to_num(attitude_cutoffs(acc, self.k_phi, self.k_theta, self.g0))
        steps = rot.from_rotation_vector(gyr * T)
        euler = np.empty((len(acc), 3))
        euler[0] = np.nan_to_num(measured[0])
        q = rot.from_euler(euler[0])
        for k in range(1, len(acc)):
            psi, theta, phi = rot.to_euler(rot.multiply(q, steps[k])).tolist()
            psi_m, theta_a, phi_a = measured[k].tolist()
            w_psi = self.k_psi * math.exp(-max(abs(euler[k - 1, 1]), abs(euler[k - 1, 2])))
            cut[k, 2] = w_psi
            if math.isfinite(theta_a):
                theta += (1.0 - math.exp(-cut[k, 1] * T)) * (theta_a - theta)
                phi += (1.0 - math.exp(-cut[k, 0] * T)) * wrap_scalar(phi_a - phi)
            else:
                cut[k, :2] = 0.0
            if math.isfinite(psi_m):
                psi = wrap_scalar(psi + (1.0 - math.exp(-w_psi * T)) * wrap_scalar(psi_m - psi))
            else:
                cut[k, 2] = 0.0
            euler[k] = psi, theta, phi
            q = rot.from_euler(euler[k])
        return euler, cut

    # ------------------------------------------------------------------ position
    def _position(self, euler, speed, gps, cut, initial_position):
        """Odometry dead reckoning (eq. 18) fused with GPS fixes (eqs. 19-24), (N, 3)."""
        T = self.dt_s
        psi, theta = euler[:, 0], euler[:, 1]
        forward = np.stack([np.cos(psi) * np.cos(theta), np.sin(psi) * np.cos(theta), -np.sin(theta)], axis=-1)
        step = (T * speed)[:, None] * forward
        log_alpha = -T * cut                                   # ln α_j per step
        out = np.full((len(step), 3), np.nan)
        x = initial_position
        pending = 0.0                                          # Σ ln α_j since the last fix
        for k in range(len(step)):
            fix = gps[k] if np.isfinite(gps[k]).all() else None
            if x is None:
                if fix is None:
                    continue
                x, pending = fix.copy(), 0.0
                out[k] = x
                continue
            if k:
                x += step[k]
            pending += log_alpha[k]
            if fix is not None:
                x += (1.0 - math.exp(pending)) * (fix - x)
                pending = 0.0
            out[k] = x
        return out


# ---------------------------------------------------------------------------- plot
def cutoff_plot(estimate: AdaptiveEstimate, t_s, ax=None):
    """Draw the adapted cut-offs of roll, pitch, yaw and position over time.

    Parameters
    ----------
    estimate : AdaptiveEstimate
        From :meth:`AdaptiveCF.run`.
    t_s : array_like, shape (N,)
        Times of the estimate's rows (s).
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new figure.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn into.

    Raises
    ------
    InputError
        ``t_s`` does not have one time per row.
    """
    import matplotlib.pyplot as plt

    t = np.asarray(t_s, dtype=float)
    if t.shape != (len(estimate.cutoff_position),):
        raise InputError(f"t_s: shape ({len(estimate.cutoff_position)},) needed, got {t.shape}")
    if ax is None:
        ax = plt.subplots(figsize=(8, 3.5))[1]
    for i, name in enumerate(("roll ω_φ", "pitch ω_θ", "yaw ω_ψ")):
        ax.plot(t, estimate.cutoff_attitude[:, i], label=name, lw=1)
    ax.plot(t, estimate.cutoff_position, label="position ω_c", lw=1.5, color="k")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("cut-off (rad/s)")
    ax.set_title("Adapted cut-off frequencies (Alves Neto et al. eqs. 15-17, 22-24)")
    ax.legend(loc="best", fontsize="small")
    return ax


# ---------------------------------------------------------------------------- validation
def _number(name, value, *, positive=False, signed=False):
    """A finite float, non-negative (or positive, or any sign); InputError naming ``name`` otherwise."""
    try:
        value = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name}: a number is needed, got {value!r}") from None
    if not math.isfinite(value) or (not signed and (value <= 0 if positive else value < 0)):
        kind = "finite" if signed else "positive" if positive else "non-negative"
        raise InputError(f"{name}: a {kind} number is needed, got {value!r}")
    return value


def _rows(name, value, width=None):
    """``value`` as a float array of shape (N,) or (N, width); InputError naming ``name`` otherwise."""
    return rows(name, value, width, error=InputError)
