"""The Euler-angle attitude complementary filter of Vasconcelos et al. (Sec. 2, Fig. 2).

Euler channels ``λ = (ψ, θ, φ)`` (yaw, pitch, roll) driven by the gyro through
``u_λ = Q(λ) ω`` (:func:`cfdesign.rotations.euler_rate_matrix`), corrected by the
Magneto-Pendular Sensor (:mod:`cfdesign.nav.mps`), with the gyro bias kept in body rates.
Each channel is the designed ``cf2`` of :mod:`cfdesign.nav.attitude_channel`: one table for
the tilt channels (pitch, roll), one for yaw.  Use it for vehicles that stay far from
``θ = ±90°`` (helicopters, cars, fixed wings in normal flight); :func:`cfdesign.nav.estimate_attitude`
is the singularity-free form.

Frames: attitude of the body (sensor) frame relative to **ENU** (x east, y north, z up);
Euler angles ZYX ``[yaw, pitch, roll]``; quaternions ``[w, x, y, z]`` map body to ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import rotations as rot
from ..errors import AttitudeInputError
from ..linear import wrap_scalar
from ..runtime.filter import usable
from .attitude_channel import channel_gains, channel_tables, design_channel
from .attitude_inputs import imu_inputs, initial_quaternion, positive, rate, usable_rows
from .mps import mps_euler

__all__ = ["EulerAttitudeFilter", "EulerEstimate"]


@dataclass(frozen=True)
class EulerEstimate:
    """Output of :meth:`EulerAttitudeFilter.run`; attitude of the body relative to **ENU**.

    Attributes
    ----------
    euler : ndarray (N, 3)
        ZYX ``[yaw, pitch, roll]`` (rad), yaw wrapped to ``(-pi, pi]``.
    bias : ndarray (N, 3)
        Body-rate gyro bias estimate ``b_ω`` (rad/s).
    quaternion : ndarray (N, 4)
        The same attitude as ``[w, x, y, z]``, body -> ENU.
    gains : dict
        The :class:`~cfdesign.gains.GainTable` per channel group: ``"tilt"`` (pitch, roll)
        and ``"heading"`` (yaw).
    """

    euler: np.ndarray
    bias: np.ndarray
    quaternion: np.ndarray
    gains: dict


class EulerAttitudeFilter:
    """The Euler-angle attitude complementary filter with body-rate gyro bias (Vasconcelos et al.).

    Per channel ``λ ∈ (ψ, θ, φ)``, in filter form at every sample ``k`` (Vasconcelos et al.
    Sec. 2.1, Fig. 2; derivation in ``docs/derivations.md``)::

        e      = y_λ[k] - λ⁻[k]                  (yaw innovation wrapped to (-pi, pi])
        λ[k]   = λ⁻[k] + k1 e
        b_ω    = b_ω - Q(λ)^-1 (k2 e)            (bias kept in body rates, Fig. 2's dotted box)
        λ⁻[k+1] = λ[k] + T Q(λ[k]) (ω[k] - b_ω)  (u_λ = Q(λ) ω)

    with ``y_λ`` the MPS (:func:`cfdesign.nav.mps.mps_euler`, centripetal compensation when a
    body velocity is given) and ``k1, k2`` the update gains of two designed channel tables
    (:mod:`cfdesign.nav.attitude_channel`): tilt for pitch and roll, heading for yaw.

    Parameters
    ----------
    rate_hz : float
        IMU (and MPS) sample rate (Hz).
    gyro_noise_std : float, optional
        Gyro white noise, rad/s per sample.
    gyro_bias_density : float, optional
        Gyro bias random walk, rad/s/sqrt(s).
    tilt_noise_std, heading_noise_std : float, optional
        MPS roll/pitch resp. yaw noise, rad per sample.
    declination_rad : float
        Magnetic declination (positive east).
    tables : pair, optional
        ``(tilt, heading)``: a user's own design instead of the four noise figures, each a
        :class:`~cfdesign.gains.GainTable` of the ``cf2`` order-2 channel at ``rate_hz`` (e.g.
        from :func:`cfdesign.design <cfdesign.designer.design>`, :func:`cfdesign.gains.load_gains` or
        :func:`cfdesign.nav.design_channel`) or a :class:`~cfdesign.spec.FilterSpec` of it.
        Give either ``tables`` or all four noise figures, which are designed with
        :func:`cfdesign.nav.design_channel` (no sympy).

    Raises
    ------
    AttitudeInputError
        A missing or invalid noise figure, a rate outside [1e-3, 1e6] Hz, a declination that is
        not a number within [-pi, pi], or both tables and noise figures given.
    TableMismatchError
        A table that is not the channel's model or not at ``rate_hz`` (the message names it).

    Notes
    -----
    Frame ENU, Euler ZYX of the body relative to ENU.  ``Q(λ)`` is singular at pitch ±90°:
    use :func:`cfdesign.nav.estimate_attitude` for attitudes that get there.  Missing data: a
    gyro row with NaN holds the attitude (zero rate); a non-finite or zero accelerometer row
    skips the whole correction; a non-finite or zero field row skips the yaw correction.
    """

    def __init__(self, rate_hz, *, gyro_noise_std=None, gyro_bias_density=None, tilt_noise_std=None,
                 heading_noise_std=None, declination_rad=0.0, tables=None):
        self.rate_hz = rate(rate_hz)
        try:
            self.declination_rad = float(declination_rad)
        except (TypeError, ValueError, OverflowError):
            raise AttitudeInputError(f"declination_rad must be a number, got {declination_rad!r}") from None
        if not abs(self.declination_rad) <= math.pi:  # NaN too
            raise AttitudeInputError(f"declination_rad must be within [-pi, pi], got {declination_rad!r}")
        figures = {"gyro_noise_std": gyro_noise_std, "gyro_bias_density": gyro_bias_density,
                   "tilt_noise_std": tilt_noise_std, "heading_noise_std": heading_noise_std}

        def design_pair():
            missing = [name for name, value in figures.items() if value is None]
            if missing:
                raise AttitudeInputError(f"{missing[0]} is missing: give the noise figures or "
                                         "tables=(tilt, heading)")
            for name, value in figures.items():
                positive(name, value)
            return (design_channel(rate_hz, gyro_noise_std, gyro_bias_density, tilt_noise_std),
                    design_channel(rate_hz, gyro_noise_std, gyro_bias_density, heading_noise_std))

        tilt, heading = channel_tables(tables, [k for k, v in figures.items() if v is not None], design_pair)
        timing = f"rate_hz {self.rate_hz:g} Hz"
        k_tilt = channel_gains(tilt, "tables[0] (tilt)", 1.0 / self.rate_hz, timing)
        k_heading = channel_gains(heading, "tables[1] (heading)", 1.0 / self.rate_hz, timing)
        self.gains = {"tilt": tilt, "heading": heading}
        # per channel (ψ, θ, φ)
        self.k1 = np.array([k_heading[0], k_tilt[0], k_tilt[0]])
        self.k2 = np.array([k_heading[1], k_tilt[1], k_tilt[1]])

    def run(self, gyr, acc, mag, velocity_body=None, initial=None) -> EulerEstimate:
        """Filter a whole log, sample by sample, from the initial attitude (Vasconcelos et al. Sec. 2.1).

        At each sample the Magneto-Pendular Sensor reading corrects the attitude and the bias,
        then the gyro propagates the attitude to the next sample.  Each call starts afresh: no
        state is kept between calls.

        Parameters
        ----------
        gyr : array_like (N, 3)
            Body rate, rad/s, body (sensor) frame, at ``rate_hz``; N >= 1.  A row that is not
            finite or beyond :data:`~cfdesign.runtime.filter.READING_LIMIT` counts as a zero
            reading.
        acc : array_like (N, 3)
            Specific force, m/s², body frame (points up at rest).  A row that is not finite or is
            zero skips the whole correction of its sample.
        mag : array_like (N, 3) or None
            Magnetic field, body frame, any consistent unit (Gauss, uT or normalised: only its
            direction is used).  A row that is not finite or is zero skips the yaw correction;
            None: yaw is never corrected (the gyro's integral from the initial yaw).
        velocity_body : array_like (N, 3), optional
            Velocity in the body frame, m/s: the MPS then compensates the centripetal
            acceleration, ``a - ω̂ × v_B`` with the bias-corrected rate (computed per sample,
            slower); a row that is not finite skips the correction of its sample.
        initial : array_like (3,), optional
            Initial ZYX ``[yaw, pitch, roll]`` (rad), body relative to ENU; default: the MPS of
            the first usable sample (:func:`~cfdesign.nav.attitude_inputs.initial_quaternion`).

        Returns
        -------
        EulerEstimate
            Per sample, after its correction: Euler angles (yaw wrapped to (-pi, pi]), body-rate
            gyro bias (rad/s), the quaternion ``[w, x, y, z]`` body -> ENU, and the two tables.

        Raises
        ------
        AttitudeInputError
            An input that is not (N, 3) or whose length differs from ``gyr``'s, an empty
            ``gyr``, or an ``initial`` that is not three finite numbers.

        Examples
        --------
        >>> import numpy as np
        >>> from cfdesign.nav import EulerAttitudeFilter
        >>> f = EulerAttitudeFilter(100.0, gyro_noise_std=0.002, gyro_bias_density=1e-5,
        ...                         tilt_noise_std=0.05, heading_noise_std=0.1)
        >>> acc = np.tile([0.0, 0.0, 9.81], (200, 1))                              # level, still
        >>> mag = np.tile([0.2 * np.sin(0.3), 0.2 * np.cos(0.3), -0.4], (200, 1))  # yaw 0.3 rad
        >>> f.run(np.zeros((200, 3)), acc, mag).euler[-1].round(6)
        array([0.3, 0. , 0. ])
        >>> est = f.run(np.tile([0.0, 0.0, 0.01], (200, 1)), acc, None)  # no field: yaw from the gyro
        >>> round(float(est.euler[-1, 0]), 4)
        0.0199
        """
        gyr, acc, mag, vel = imu_inputs(gyr, acc, mag, velocity_body)
        acc, mag = usable_rows(acc), usable_rows(mag)
        if vel is not None:  # a velocity that is not usable: the compensated reading is not either
            acc = np.where(usable(vel).all(axis=1)[:, None], acc, np.nan)
        gyr = np.where(usable(gyr).all(axis=1)[:, None], gyr, 0.0)
        y = None if vel is not None else mps_euler(acc, mag, declination_rad=self.declination_rad).tolist()
        lam = [float(v) for v in self._initial(acc, mag, initial)]
        b = [0.0, 0.0, 0.0]
        T = 1.0 / self.rate_hz
        gains = (self.k1.tolist(), self.k2.tolist())
        out_e, out_b = np.empty((len(gyr), 3)), np.empty((len(gyr), 3))
        for k, w in enumerate(gyr.tolist()):
            rate = [w[0] - b[0], w[1] - b[1], w[2] - b[2]]
            yk = y[k] if y is not None else self._mps_one(acc[k], None if mag is None else mag[k], rate, vel[k])
            lam, b = _euler_correct(lam, b, yk, gains)
            out_e[k], out_b[k] = lam, b
            lam = _euler_propagate(lam, [w[0] - b[0], w[1] - b[1], w[2] - b[2]], T)
        return EulerEstimate(out_e, out_b, rot.normalize(rot.from_euler(out_e)), self.gains)

    def _initial(self, acc, mag, initial):
        if initial is not None:
            lam = np.asarray(initial, dtype=float)
            if lam.shape != (3,) or not np.isfinite(lam).all():
                raise AttitudeInputError(f"initial must be finite [yaw, pitch, roll] in rad, got {initial!r}")
            return lam.copy()
        q0 = initial_quaternion(acc, mag, self.declination_rad, None)
        return rot.to_euler(q0)

    def _mps_one(self, a, m, rate, v):
        return mps_euler(a, m, declination_rad=self.declination_rad, rate=np.asarray(rate),
                         velocity_body=v).tolist()


def _euler_propagate(lam, rate, T):
    """``λ + T Q(λ) ω`` (Vasconcelos et al. Sec. 2.1) in Python floats; yaw wrapped."""
    psi, theta, phi = lam
    sf, cf = math.sin(phi), math.cos(phi)
    ct, tt = math.cos(theta), math.tan(theta)
    wy, wz = rate[1], rate[2]
    return [wrap_scalar(psi + T * (sf * wy + cf * wz) / ct), theta + T * (cf * wy - sf * wz),
            phi + T * (rate[0] + tt * (sf * wy + cf * wz))]


def _euler_correct(lam, b, y, gains):
    """Measurement update ``λ += k1 e``, ``b_ω -= Q(λ)^-1 (k2 e)``; channels with a NaN MPS are skipped."""
    (k1p, k1t, k1r), (k2p, k2t, k2r) = gains
    e = [y[0] - lam[0], y[1] - lam[1], y[2] - lam[2]]
    e = [v if v == v else 0.0 for v in e]                   # NaN: channel not measured
    e[0] = wrap_scalar(e[0])
    psi, theta, phi = wrap_scalar(lam[0] + k1p * e[0]), lam[1] + k1t * e[1], lam[2] + k1r * e[2]
    dpsi, dtheta, dphi = k2p * e[0], k2t * e[1], k2r * e[2]
    st, ct, sf, cf = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
    b = [b[0] - (-st * dpsi + dphi), b[1] - (ct * sf * dpsi + cf * dtheta), b[2] - (ct * cf * dpsi - sf * dtheta)]
    return [psi, theta, phi], b
