"""The strapdown EKF of the low-cost 3D localization paper, the planar EKF of the outdoor localization paper and
the TRIAD attitude (cfdesign.nav.strapdown_ekf, .planar_ekf, .triad)."""

import math

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.errors import InputError
from cfdesign.linear import wrap
from cfdesign.nav.mps import mps_quaternion
from cfdesign.nav.planar_ekf import PlanarEKF, planar_step
from cfdesign.nav.strapdown_ekf import N_STATES, StrapdownEKF, norm_observation, strapdown_step
from cfdesign.nav.triad import triad_matrix, triad_quaternion
from cfdesign.sim.helicopter import (
    MAGNETIC_FIELD_ENU_G,
    TABLE1,
    Manoeuvre,
    helicopter_manoeuvre,
    simulate_readings,
)


def _attitude_error_deg(q_true, q_est):
    """Angle (deg) of the rotation between two attitude series."""
    dq = rot.multiply(rot.conjugate(q_true), q_est)
    return np.degrees(2 * np.arcsin(np.clip(np.linalg.norm(dq[..., 1:], axis=-1), 0.0, 1.0)))


def _fd_jacobian(fun, x, h=1e-6):
    """Central finite-difference Jacobian of ``fun`` at ``x``."""
    cols = []
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.column_stack(cols)


# ---------------------------------------------------------------------------- TRIAD
def test_triad_exact_on_noise_free_vectors():
    rng = np.random.default_rng(3)
    q = rot.normalize(rng.normal(size=(50, 4)))
    R = rot.to_matrix(q)                                   # body -> reference
    r1, r2 = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    b1, b2 = (np.einsum("kji,kj->ki", R, r) for r in (r1, r2))   # R^T r
    np.testing.assert_allclose(triad_matrix(b1, b2, r1, r2), R, atol=1e-12)
    np.testing.assert_allclose(triad_quaternion(b1, b2, r1, r2), q, atol=1e-12)
    # eq. (7) of the low-cost 3D localization paper: [r1 | r2 | r1 x r2] = C [b1 | b2 | b1 x b2]
    C = triad_matrix(b1[0], b2[0], r1[0], r2[0])
    lhs = np.column_stack([r1[0], r2[0], np.cross(r1[0], r2[0])])
    np.testing.assert_allclose(C @ np.column_stack([b1[0], b2[0], np.cross(b1[0], b2[0])]), lhs, atol=1e-12)


def test_triad_primary_exact_secondary_projected_and_degenerate():
    # noisy secondary vector: the primary direction is still matched exactly
    C = triad_matrix([0.0, 0.0, 2.0], [0.1, 1.0, 0.3], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(C @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-14)
    assert np.isnan(triad_quaternion([0, 0, 1.0], [0, 0, 3.0], [0, 0, 1.0], [0, 1.0, 0])).all()


def test_triad_matches_mps_quaternion():
    rng = np.random.default_rng(4)
    q = rot.normalize(rng.normal(size=(20, 4)))
    R = rot.to_matrix(q)
    field = np.array([0.0, 0.27, -0.35])                    # north and down, as a real field
    acc = np.einsum("kji,j->ki", R, [0.0, 0.0, 9.8])
    mag = np.einsum("kji,j->ki", R, field)
    np.testing.assert_allclose(triad_quaternion(acc, mag, [0.0, 0.0, 1.0], field), mps_quaternion(acc, mag),
                               atol=1e-12)


# ---------------------------------------------------------------------------- Jacobians
def _random_state(rng):
    x = np.zeros(N_STATES)
    x[0:4] = 1.02 * rot.normalize(rng.normal(size=4))      # slightly non-unit, as in the filter
    x[4:10] = rng.normal(size=6) * 3
    x[10:13] = 0.01 * rng.normal(size=3)
    x[13:16] = 1 + 0.05 * rng.normal(size=3)
    x[16:19] = 0.1 * rng.normal(size=3)
    x[19:22] = 1 + 0.05 * rng.normal(size=3)
    return x


@pytest.mark.parametrize("rate_scale", [1.0, 1e-6])         # ordinary and tiny rotation per step
def test_strapdown_jacobian_matches_finite_differences(rate_scale):
    rng = np.random.default_rng(5)
    for _ in range(5):
        x = _random_state(rng)
        gyro, accel = rate_scale * rng.normal(size=3), rng.normal(size=3) + np.array([0.0, 0.0, 9.8])
        _, F = strapdown_step(x, gyro, accel, 0.02)
        F_fd = _fd_jacobian(lambda s, g=gyro, a=accel: strapdown_step(s, g, a, 0.02, jacobian=False), x)
        np.testing.assert_allclose(F, F_fd, atol=1e-8, rtol=1e-6)


def test_norm_and_planar_jacobians_match_finite_differences():
    rng = np.random.default_rng(6)
    x = _random_state(rng)
    _, H = norm_observation(x)
    np.testing.assert_allclose(H, _fd_jacobian(lambda s: np.array([norm_observation(s)[0]]), x)[0], atol=1e-9)
    state, rho, omega, dt = np.array([1.0, -2.0, 2.5, 1.03]), 0.4, 0.3, 0.1
    _, Jx, Ju = planar_step(state, rho, omega, dt)
    np.testing.assert_allclose(Jx, _fd_jacobian(lambda s: planar_step(s, rho, omega, dt, jacobian=False), state),
                               atol=1e-9)
    Ju_fd = _fd_jacobian(lambda u: planar_step(state, u[0], u[1], dt, jacobian=False), np.array([rho, omega]))
    np.testing.assert_allclose(Ju, Ju_fd, atol=1e-9)


# ---------------------------------------------------------------------------- StrapdownEKF
def _strapdown(rate_hz):
    return StrapdownEKF(rate_hz, gyro_noise_std=TABLE1.gyro_noise_std_rad_s,
                        accel_noise_std=TABLE1.accel_noise_std_m_s2, gyro_bias_density=1e-5,
                        accel_bias_density=1e-4, scale_density=1e-6, gps_pos_std=math.sqrt(10.0), gps_vel_std=0.1,
                        triad_std=math.radians(2.0), mag_rate_hz=10.0, mag_reference_enu=MAGNETIC_FIELD_ENU_G)


def _gps_velocity(traj, gps_pos, seed):
    """GPS velocity fixes (0.1 m/s noise) at the position fixes' rows, NaN elsewhere."""
    noise = 0.1 * np.random.default_rng(seed).normal(size=traj.velocity_m_s.shape)
    return np.where(np.isfinite(gps_pos), traj.velocity_m_s + noise, np.nan)


def test_strapdown_ekf_helicopter_errors_and_gyro_bias():
    traj = helicopter_manoeuvre()                           # 100 s at 50 Hz: straight, then helix
    r = simulate_readings(traj, 1)
    est = _strapdown(50.0).run(r.gyro_rad_s, r.accel_m_s2, r.mag_g, r.gps_enu_m, _gps_velocity(traj, r.gps_enu_m, 1),
                               initial_velocity=traj.velocity_m_s[0])
    assert est.quaternion.shape == (len(traj.t_s), 4) and est.states.shape == (len(traj.t_s), N_STATES)
    pos_err = np.linalg.norm(est.position - traj.position_m, axis=1)
    att_err = _attitude_error_deg(traj.quaternion, est.quaternion)
    assert pos_err.mean() < 1.5 and pos_err.max() < 8.0     # GPS noise 3.2 m per axis
    assert att_err.mean() < 0.3 and att_err.max() < 1.5
    assert np.linalg.norm(est.velocity - traj.velocity_m_s, axis=1)[-2500:].max() < 0.3
    # gyro bias 0.05 deg/s per axis (signs +, -, +): within 20 % at the end
    np.testing.assert_allclose(est.states[-1, 10:13], TABLE1.gyro_bias, rtol=0.2)
    assert (est.covariance_min_eig > 0).all()


def test_strapdown_ekf_long_run_covariance_spd_with_outage():
    m = Manoeuvre(helix_s=340.0, rate_hz=20.0)              # 6 minutes at 20 Hz
    traj = helicopter_manoeuvre(m)
    r = simulate_readings(traj, 2)
    gps = r.gps_enu_m.copy()
    outage = (traj.t_s > 200.0) & (traj.t_s < 230.0)        # 30 s without GPS
    gps[outage] = np.nan
    vel = _gps_velocity(traj, gps, 2)
    est = _strapdown(20.0).run(r.gyro_rad_s, r.accel_m_s2, r.mag_g, gps, vel, initial_velocity=traj.velocity_m_s[0])
    assert np.isfinite(est.states).all()
    assert (est.covariance_min_eig > 0).all()
    assert est.covariance_asymmetry.max() <= 1e-12
    P = est.final_covariance
    assert np.abs(P - P.T).max() <= 1e-12 * np.abs(P).max()
    assert np.linalg.eigvalsh(P)[0] > 0
    pos_err = np.linalg.norm(est.position - traj.position_m, axis=1)
    assert pos_err[outage].max() < 15.0                     # coasting on the IMU, bias estimated
    assert pos_err[traj.t_s > 260.0].mean() < 2.0           # recovered
    assert _attitude_error_deg(traj.quaternion, est.quaternion).max() < 1.5
    assert np.abs(np.linalg.norm(est.states[:, :4], axis=1) - 1).max() < 1e-3   # eq. (9) keeps |q| ~ 1


def test_strapdown_ekf_rejects_bad_rates_and_shapes():
    with pytest.raises(InputError):
        StrapdownEKF(50.0, gyro_noise_std=1e-3, accel_noise_std=1e-2, gyro_bias_density=1e-5,
                     accel_bias_density=1e-4, scale_density=1e-6, gps_pos_std=3.0, gps_vel_std=0.1,
                     triad_std=0.03, mag_rate_hz=7.0)
    with pytest.raises(InputError):
        _strapdown(50.0).run(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((9, 3)), np.zeros((9, 3)), None)


# ---------------------------------------------------------------------------- PlanarEKF
def _planar_path(n=3000, dt=0.1, alpha=1.05, theta0=0.3, seed=0):
    """Planar drive at 2 m/s with a slowly weaving yaw rate; odometer reads distance / alpha.

    GPS at 1 Hz, alternating 100 s of 'single' (3 m) and 100 s of 'dgps' (0.5 m).
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    omega = 0.15 * np.sin(2 * np.pi * t / 60)
    theta = theta0 + np.concatenate([[0.0], np.cumsum(omega * dt)])
    phi = theta[:-1] + 0.5 * omega * dt
    x = np.cumsum(2.0 * dt * np.cos(phi))
    y = np.cumsum(2.0 * dt * np.sin(phi))
    rho = 2.0 * dt / alpha + 0.002 * rng.normal(size=n)
    gyro = omega + 0.002 * rng.normal(size=n)
    has_fix = np.arange(n) % 10 == 9
    mode = np.where((t // 100) % 2 == 0, "single", "dgps")
    std = np.where(mode == "single", 3.0, 0.5)
    gps = np.column_stack([x, y]) + std[:, None] * rng.normal(size=(n, 2))
    gps[~has_fix] = np.nan
    return dict(distance=rho, gyro_z=gyro, dt_s=dt, gps_xy=gps, gps_mode=np.where(has_fix, mode, "")), (x, y, theta[1:])


def _planar():
    return PlanarEKF(odo_noise_std=0.002, gyro_noise_std=0.002, gps_std={"single": 3.0, "dgps": 0.5},
                     kappa_omega=1.0, kappa_rho=0.5, sigma_heading={"single": 4.5, "dgps": 0.75})


def test_planar_ekf_estimates_odometer_scale_and_tracks():
    inputs, (x, y, theta) = _planar_path()
    est = _planar().run(**inputs)
    assert abs(est.alpha[-1] - 1.05) < 0.01
    assert np.abs(est.alpha[1000:] - 1.05).max() < 0.02
    err = np.hypot(est.x - x, est.y - y)
    assert err[1500:].mean() < 0.5 and err[1500:].max() < 1.5
    assert np.degrees(np.abs(wrap(est.theta - theta)))[1500:].max() < 2.0
    assert all(np.linalg.eigvalsh(P)[0] > 0 and np.abs(P - P.T).max() == 0 for P in est.covariance)


def test_planar_ekf_heading_wraps_near_pi():
    inputs, (_, _, theta) = _planar_path(n=1500, theta0=math.pi - 0.05)   # heading crosses +-pi
    est = _planar().run(**inputs, initial_state=[0.0, 0.0, -math.pi + 0.02, 1.0])
    assert np.abs(est.theta).max() <= math.pi
    assert np.degrees(np.abs(wrap(est.theta - theta)))[500:].max() < 3.0


def test_planar_ekf_gps_mode_switches_variance():
    inputs, _ = _planar_path(n=2400)
    ekf = _planar()
    est = ekf.run(**inputs)
    fix = inputs["gps_mode"] != ""
    expected = np.where(inputs["gps_mode"][fix] == "single", 3.0, 0.5)
    np.testing.assert_array_equal(est.gps_std_used[fix], expected)
    assert np.isnan(est.gps_std_used[~fix]).all()
    # position variance after DGPS fixes is well below that after single-mode fixes
    single = est.covariance[fix & (inputs["gps_mode"] == "single"), 0, 0][10:]
    dgps = est.covariance[fix & (inputs["gps_mode"] == "dgps"), 0, 0]
    assert np.median(dgps) < 0.2 * np.median(single)
    # eq. (13) as read: sigma (sum|omega| dt + k_omega) / (sum rho + k_rho), sums since the last fix
    k = np.flatnonzero(fix)[5]
    span = slice(np.flatnonzero(fix)[4] + 1, k + 1)
    turned = np.sum(np.abs(inputs["gyro_z"][span])) * inputs["dt_s"]
    travelled = np.sum(inputs["distance"][span])
    mode = inputs["gps_mode"][k]
    assert est.heading_std[k] == pytest.approx(ekf.sigma_heading[mode] * (turned + 1.0) / (travelled + 0.5))
    # all-DGPS data with the same noise gives a smaller covariance than all-single
    only = {m: ekf.run(**{**inputs, "gps_mode": np.where(fix, m, "")}) for m in ("single", "dgps")}
    assert only["dgps"].covariance[-1, 0, 0] < only["single"].covariance[-1, 0, 0]
