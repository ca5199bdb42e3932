"""The multirate position filter of Vasconcelos et al., per ENU axis: state ``[p, v, b_a]``, IMU in, GPS fixes.

Model (Vasconcelos et al. Sec. 3; derivation in ``docs/derivations.md``): on each ENU axis,
with the Earth-frame acceleration ``u`` as the input and the accelerometer bias ``b`` as a
slow random walk,

.. math:: x = [p, v, b]^T,\\quad x[k+1] = F x^+[k] + B u[k],\\quad
          F = \\begin{bmatrix}1 & T & -T^2/2\\\\ 0 & 1 & -T\\\\ 0 & 0 & 1\\end{bmatrix},\\quad
          B = [T^2/2,\\ T,\\ 0]^T,

and a GPS position fix ``y = p + n`` every ``N = imu_rate_hz / gps_rate_hz`` steps, applied
in filter form ``x^+[k] = x[k] + K[k] (y[k] - H x[k])``, ``H = [1, 0, 0]``.  The gains
``K[k]`` are the periodic-DARE Kalman gains of the ``position`` structure; they are exactly
zero at the phases without a fix (Vasconcelos et al. Sec. 3), so the filter runs open loop
between fixes.  One gain table serves the three axes (the paper's ``K_iP = I_3 k_iP``), run
by :class:`cfdesign.runtime.Runtime`.  By default the table is designed from the noise
figures by the numeric design stage on the stored ``position`` structure
(:mod:`cfdesign.nav.stored_design`, no sympy); a user's own design can be given instead
(``table=``: a :class:`~cfdesign.gains.GainTable` or a ``position`` FilterSpec).

Input (Vasconcelos et al. Fig. 3, gravity removal; frames as :mod:`cfdesign.rotations`):
the accelerometer reads the specific force in the body frame, ``f_b = R_nb^T (a_n - g_n)``,
so the Earth-frame acceleration is

.. math:: u = R_{nb} f_b + g_n,\\qquad g_n = [0, 0, -9.80665]\\ \\mathrm{m/s^2}\\ \\text{(ENU)}.

``f_b[k]`` is the mean over the interval ``[t_k, t_k+1]`` (an integrating accelerometer), so
it is rotated by the attitude at the interval's midpoint, ``q[k] ⊕ q[k+1]`` normalised
(the slerp midpoint).

Bias frame: as in the paper, each axis estimates the bias of its own input, i.e. the
accelerometer bias seen in ENU, ``b_n = R_nb b_body``, modelled as a slow random walk.
While the vehicle holds its attitude ``b_n`` is constant and ``PositionEstimate.accel_bias``
converges to it; when the vehicle turns, a horizontal body bias turns with it and the
filter tracks its slow part only.  (Carrying the estimate with the attitude,
``b_n <- R[k+1] R[k]^T b_n``, looks exact but destabilises the bias loop once the turn rate
approaches its bandwidth - a 19-s helix against GPS fixes of 3 m: it drifts.)

GPS outages: a NaN fix skips the update (:mod:`cfdesign.runtime`), so the estimate coasts on
the accelerometer and recovers with the next fixes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import rotations as rot
from ..errors import InputError, SpecError, TableMismatchError
from ..rotations import GRAVITY_ENU
from ..runtime.filter import usable
from ..spec import parse_spec
from .attitude_inputs import finite_vector, held_rows, number, rate, rows
from .stored_design import as_table, check_fits, design_stored

__all__ = ["PositionEstimate", "PositionFilter", "position_spec", "design_position", "earth_acceleration"]

#: the stored structure of the filter
STRUCTURE = "position"


@dataclass(frozen=True)
class PositionEstimate:
    """Filtered (a posteriori) estimates at the ``N`` IMU sample times.

    Attributes
    ----------
    position : ndarray (N, 3)
        ENU position (m).
    velocity : ndarray (N, 3)
        ENU velocity (m/s).
    accel_bias : ndarray (N, 3)
        Accelerometer bias as seen in ENU, ``R_nb b_body`` (m/s^2).
    missing : dict
        Rows treated as missing (:meth:`PositionFilter.run`, Notes): ``{'acc_body', 'quat_nb',
        'gps_enu'}``.
    """

    position: np.ndarray
    velocity: np.ndarray
    accel_bias: np.ndarray
    missing: dict = field(default_factory=dict)


def position_spec(imu_rate_hz: float, gps_rate_hz: float, *, accel_noise_std: float, accel_bias_density: float,
                  gps_noise_std: float):
    """Design specification of one axis (the ``position`` structure, filter gain form).

    Parameters
    ----------
    imu_rate_hz, gps_rate_hz : float
        Accelerometer and GPS rates (Hz); the GPS rate must divide the IMU rate.
    accel_noise_std : float
        Accelerometer white noise per sample (m/s^2) at ``imu_rate_hz``.
    accel_bias_density : float
        Random-walk density of the bias (m/s^2/sqrt(s)): larger tracks faster, smooths less.
    gps_noise_std : float
        GPS position noise per fix and axis (m).

    Returns
    -------
    FilterSpec
        The design of one axis (``position`` structure, filter form).

    Raises
    ------
    SpecError
        A figure or rate that is not a number (a bool or text is not one: the message names the
        argument), is not positive and finite, or rates that do not fit.
    """
    args = {"imu_rate_hz": imu_rate_hz, "gps_rate_hz": gps_rate_hz, "accel_noise_std": accel_noise_std,
            "accel_bias_density": accel_bias_density, "gps_noise_std": gps_noise_std}
    v = {name: number(name, value, SpecError) for name, value in args.items()}  # True was 1 m/s^2
    return parse_spec({
        "name": "position axis", "structure": "position", "gain_form": "filter",
        "sensors": {"accelerometer": {"measures": "acceleration", "rate_hz": v["imu_rate_hz"],
                                      "noise": {"std": v["accel_noise_std"]},
                                      "bias": {"model": "random_walk", "density": v["accel_bias_density"]}},
                    "gps": {"measures": "position", "rate_hz": v["gps_rate_hz"],
                            "noise": {"std": v["gps_noise_std"]}}}})


def design_position(imu_rate_hz: float, gps_rate_hz: float, *, accel_noise_std: float, accel_bias_density: float,
                    gps_noise_std: float):
    """The periodic gain table of one axis for these noise figures.

    :func:`position_spec` designed by the numeric stage on the stored ``position`` structure
    (no sympy; the same gains as ``cfdesign.design(position_spec(...))``).

    Parameters
    ----------
    imu_rate_hz, gps_rate_hz : float
        Accelerometer and GPS rates (Hz); the GPS rate must divide the IMU rate.
    accel_noise_std : float
        Accelerometer white noise per sample (m/s^2) at ``imu_rate_hz``.
    accel_bias_density : float
        Random-walk density of the bias (m/s^2/sqrt(s)): larger tracks faster, smooths less.
    gps_noise_std : float
        GPS position noise per fix and axis (m).

    Returns
    -------
    GainTable
        Filter form, base rate ``imu_rate_hz``, period ``imu_rate_hz / gps_rate_hz``.

    Raises
    ------
    SpecError
        As :func:`position_spec`.

    Examples
    --------
    >>> from cfdesign.nav.position import design_position
    >>> table = design_position(50.0, 1.0, accel_noise_std=0.006, accel_bias_density=1e-4, gps_noise_std=1.0)
    >>> table.period, table.states
    (50, ('position', 'velocity', 'accelerometer_bias'))
    """
    return design_stored(position_spec(imu_rate_hz, gps_rate_hz, accel_noise_std=accel_noise_std,
                                       accel_bias_density=accel_bias_density, gps_noise_std=gps_noise_std),
                         STRUCTURE)


def _midpoints(q) -> np.ndarray:
    """Attitude at each interval's midpoint: normalised ``q[k] + s q[k+1]`` (``s`` = +-1 picks the
    nearer sign); the last sample keeps ``q[N-1]``."""
    mid = q.copy()
    sign = np.sign(np.einsum("ki,ki->k", q[:-1], q[1:]))[:, None]
    mid[:-1] = q[:-1] + np.where(sign == 0, 1.0, sign) * q[1:]
    return mid / np.linalg.norm(mid, axis=1, keepdims=True)


def earth_acceleration(acc_body, quat_nb) -> np.ndarray:
    """Acceleration in ENU from the accelerometer: ``u = R_nb f_b + g_n``.

    Each interval uses its midpoint attitude (module docstring).

    Parameters
    ----------
    acc_body : array_like, shape (N, 3)
        Specific force in the body frame (m/s^2).
    quat_nb : array_like, shape (N, 4)
        Attitude ``[w, x, y, z]``, body -> ENU, at the same samples.

    Returns
    -------
    ndarray, shape (N, 3)
        Acceleration in ENU with gravity removed (m/s^2).
    """
    return rot.rotate(_midpoints(np.asarray(quat_nb, dtype=float)), acc_body) + GRAVITY_ENU


class PositionFilter:
    """The position complementary filter of Vasconcelos et al. on three ENU axes (module docstring).

    Parameters
    ----------
    imu_rate_hz, gps_rate_hz : float, optional
        Rates (Hz); the GPS rate must divide the IMU rate (period ``imu/gps`` steps).  Default
        50 and 1 Hz, or those of ``table``.
    accel_noise_std : float, optional
        Accelerometer noise per sample (m/s^2).
    accel_bias_density : float, optional
        Bias random-walk density (m/s^2/sqrt(s)), the designer's tuning knob for the bias gain.
    gps_noise_std : float, optional
        GPS noise per fix and axis (m).
    table : GainTable or FilterSpec, optional
        A user's own design instead of the three noise figures: a discrete table of the
        ``position`` model at the IMU rate with the GPS period (e.g. from
        :func:`cfdesign.design <cfdesign.designer.design>` or
        :func:`~cfdesign.nav.position.design_position`), or a ``position`` spec.  Give
        either ``table`` or all three noise figures (designed by :func:`~cfdesign.nav.position.design_position`,
        no sympy).

    Attributes
    ----------
    table : GainTable
        The periodic gain table shared by the three axes.

    Raises
    ------
    InputError
        A missing noise figure, both a table and noise figures, or rates that do not divide.
    TableMismatchError
        A table that is not the ``position`` model at these rates (the message names it).
    """

    def __init__(self, imu_rate_hz: float | None = None, gps_rate_hz: float | None = None, *,
                 accel_noise_std: float | None = None, accel_bias_density: float | None = None,
                 gps_noise_std: float | None = None, table=None):
        figures = {"accel_noise_std": accel_noise_std, "accel_bias_density": accel_bias_density,
                   "gps_noise_std": gps_noise_std}
        given = [name for name, value in figures.items() if value is not None]
        if table is None:
            missing = [name for name, value in figures.items() if value is None]
            if missing:
                raise InputError(f"{missing[0]} is missing: give the noise figures or table=")
            imu, gps, period = _rates(50.0 if imu_rate_hz is None else imu_rate_hz,
                                      1.0 if gps_rate_hz is None else gps_rate_hz)
            table = design_position(imu, gps, **figures)
        elif given:
            raise InputError(f"give either table or the noise figures ({', '.join(given)}), not both")
        else:
            table = as_table(table, STRUCTURE, "table")
            if table.domain != "z" or len(table.measurements) != 1:
                raise TableMismatchError(f"table: {table.name!r} is not a discrete table with one measurement; "
                                         f"this filter runs {_MODEL}")
            imu, gps, period = _rates(1.0 / table.sample_time_s if imu_rate_hz is None else imu_rate_hz,
                                      table.measurements[0].rate_hz if gps_rate_hz is None else gps_rate_hz)
        T = 1.0 / imu
        check_fits(table, "table", F=[[1.0, T, -T * T / 2], [0.0, 1.0, -T], [0.0, 0.0, 1.0]],
                   B=[[T * T / 2], [T], [0.0]], H=[[1.0, 0.0, 0.0]], orders=(2, 0), sample_time_s=T,
                   period=period, model=_MODEL, timing=f"imu_rate_hz {imu:g} Hz, gps_rate_hz {gps:g} Hz")
        self.table = table
        self._input, self._fix = table.inputs[0].name, table.measurements[0].name

    @property
    def fix_phases(self) -> list:
        """Phases (steps modulo the period) at which the table expects a GPS fix."""
        return list(self.table.schedule.phases(self._fix))

    def run(self, acc_body, quat_nb, gps_enu, *, initial_position=None, initial_velocity=None,
            initial_bias=None) -> PositionEstimate:
        """Filter a whole record; sample 0 is phase 0 of the GPS schedule.

        Parameters
        ----------
        acc_body : array_like (N, 3)
            Specific force in the body frame (m/s^2), mean over ``[t_k, t_k+1]``.
        quat_nb : array_like (N, 4)
            Attitude ``[w, x, y, z]`` body -> ENU at ``t_k`` (an estimate or the truth).
        gps_enu : array_like (N, 3)
            ENU position fixes (m); NaN rows where there is no fix (between fixes, outages).
            Fixes may only fall on :attr:`fix_phases` (every ``imu/gps`` samples from 0).
        initial_position : array_like (3,), optional
            Default: the first fix in ``gps_enu``.
        initial_velocity, initial_bias : array_like (3,), optional
            ENU velocity (m/s) and bias seen in ENU (m/s^2); default zero.

        Returns
        -------
        PositionEstimate
            ENU position (m), velocity (m/s) and accelerometer bias seen in ENU (m/s^2) at every IMU
            sample.

        Raises
        ------
        InputError
            An array that is not of real numbers or of another shape or length, no sample, a
            fix off the GPS schedule, or an initial value that is not three finite numbers; the
            message names the argument.

        Notes
        -----
        A row of ``acc_body`` or ``quat_nb`` that is not finite or beyond
        :data:`~cfdesign.runtime.filter.READING_LIMIT` (a quaternion: or zero) is missing: the
        Earth-frame acceleration holds the last one, a quaternion the last usable one; a fix
        given but unusable (inf, beyond the limit) is skipped.  Each is counted in
        ``PositionEstimate.missing``.
        """
        acc, q, gps = self._checked(acc_body, quat_nb, gps_enu)
        p0, v0, b0 = (None if value is None else finite_vector(name, value, error=InputError) for name, value in
                      (("initial_position", initial_position), ("initial_velocity", initial_velocity),
                       ("initial_bias", initial_bias)))
        q, missing_q = held_rows(q, bad=~(np.linalg.norm(np.where(usable(q), q, 0.0), axis=1) > 0))
        bad_acc = ~usable(acc).all(axis=1)
        u = earth_acceleration(np.where(bad_acc[:, None], 0.0, acc), q)
        u[bad_acc] = np.nan                        # a missing input: the runtime holds the last one
        bad_fix = ~usable(gps).all(axis=1)
        missing = {"acc_body": int(bad_acc.sum()), "quat_nb": missing_q,
                   "gps_enu": int((bad_fix & ~np.isnan(gps).all(axis=1)).sum())}
        gps = np.where(bad_fix[:, None], np.nan, gps)
        runtimes = self._runtimes(gps, p0, v0, b0)
        post = np.stack([rt.run({self._input: u[:, i], self._fix: gps[:, i]}, states=True)[1]
                         for i, rt in enumerate(runtimes)], axis=1)  # (N, axis, state): x+ of every step
        return PositionEstimate(position=post[:, :, 0].copy(), velocity=post[:, :, 1].copy(),
                                accel_bias=post[:, :, 2].copy(), missing=missing)

    def _checked(self, acc_body, quat_nb, gps_enu):
        acc = rows("acc_body", acc_body, 3, error=InputError)
        N = len(acc)
        if N == 0:
            raise InputError("acc_body is empty: need at least one sample")
        q = rows("quat_nb", quat_nb, 4, N, error=InputError)
        gps = rows("gps_enu", gps_enu, 3, N, error=InputError)
        fixes = np.flatnonzero(np.isfinite(gps).any(axis=1))
        stray = fixes[~np.isin(fixes % self.table.period, self.fix_phases)]
        if stray.size:
            raise InputError(f"gps_enu: fix at sample {stray[0]}, off the GPS schedule (phases "
                            f"{self.fix_phases} of {self.table.period}); resample the fixes onto the schedule")
        return acc, q, gps

    def _runtimes(self, gps, p0, v0, b0) -> list:
        """One :class:`~cfdesign.runtime.Runtime` per ENU axis, started at ``[p0, v0, b0]``."""
        from ..runtime import Runtime

        if p0 is None:
            rows = np.flatnonzero(np.isfinite(gps).all(axis=1))
            p0 = gps[rows[0]] if rows.size else np.zeros(3)
        v0 = np.zeros(3) if v0 is None else v0
        b0 = np.zeros(3) if b0 is None else b0
        x0 = np.column_stack([p0, v0, b0])
        return [Runtime(self.table, x0=x0[i], output="posterior") for i in range(3)]


_MODEL = ("the position chain: states [p, v, accelerometer bias], an acceleration input, a position "
          "measurement")


def _rates(imu_rate_hz, gps_rate_hz) -> tuple:
    """``(imu, gps, period)``: positive finite rates whose ratio (the period in IMU steps) is an integer."""
    imu, gps = (rate(value, name, InputError) for name, value in (("imu_rate_hz", imu_rate_hz),
                                                                  ("gps_rate_hz", gps_rate_hz)))
    ratio = imu / gps
    if round(ratio) < 1 or not math.isclose(ratio, round(ratio), rel_tol=1e-9):
        raise InputError(f"gps_rate_hz: {gps:g} Hz must divide imu_rate_hz {imu:g} Hz")
    return imu, gps, round(ratio)
