"""Tests of cfdesign.riccati.periodic_dare (filter form, Vasconcelos et al. sec. 3), each checked
against two independent computations: the recursion iterated to convergence and, for one
slow sensor, the lifted standard DARE solved by scipy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla

from cfdesign.errors import NotDetectableError, NotStabilisableError, RiccatiError
from cfdesign.riccati import kalman_discrete, periodic_dare

T = 1 / 50  # IMU at 50 Hz
N = 50  # GPS at 1 Hz
G0 = 9.81


def position_model(dt=T, accel_sigma=0.6e-3 * G0, bias_sigma=1e-4):
    """Per-axis position filter of Vasconcelos et al.: state [p, v, b_a], accelerometer as input.

    Q: accelerometer white noise through the input matrix [dt^2/2, dt, 0] (variance
    accel_sigma^2 per sample) plus a random-walk accelerometer bias (bias_sigma^2 dt).
    """
    F = np.array([[1.0, dt, -dt**2 / 2], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
    g = np.array([[dt**2 / 2], [dt], [0.0]])
    Q = accel_sigma**2 * (g @ g.T) + np.diag([0.0, 0.0, bias_sigma**2 * dt])
    return F, Q


GPS_H = np.array([[1.0, 0.0, 0.0]])
GPS_R = np.array([[10.0]])  # GPS noise variance 10 m^2 (Vasconcelos et al. Table 1)


def gps_schedule(period=N):
    C = [GPS_H] + [np.zeros((0, 3))] * (period - 1)
    R = [GPS_R] + [np.zeros((0, 0))] * (period - 1)
    return C, R


def naive_recursion(A, C, Q, R, tol=1e-15, max_periods=50_000):
    """Iterate the periodic Riccati recursion from P = 0 until one period changes P[0] by < tol."""
    N_ = len(C)
    A = A if isinstance(A, list) else [A] * N_
    Q = Q if isinstance(Q, list) else [Q] * N_
    P = np.zeros_like(A[0])
    for _ in range(max_periods):
        start, Ps = P, []
        for k in range(N_):
            Ps.append(P)
            if C[k].shape[0]:
                S = C[k] @ P @ C[k].T + R[k]
                P = P - P @ C[k].T @ np.linalg.solve(S, C[k] @ P)
            P = A[k] @ P @ A[k].T + Q[k]
            P = 0.5 * (P + P.T)
        if np.linalg.norm(P - start) <= tol * np.linalg.norm(P):
            return Ps
    raise AssertionError("the naive recursion did not converge")


def rel(X, ref):
    return float(np.linalg.norm(X - ref) / np.linalg.norm(ref))


@pytest.fixture(scope="module")
def gps_filter():
    F, Q = position_model()
    C, R = gps_schedule()
    return F, C, Q, R, periodic_dare(F, C, Q, R)


def test_matches_the_naive_recursion_at_every_phase(gps_filter):
    F, C, Q, R, sol = gps_filter
    ref = naive_recursion(F, C, Q, R)
    assert sol.period == N and len(sol.P) == N
    assert max(rel(P, Pr) for P, Pr in zip(sol.P, ref, strict=True)) <= 1e-10


def test_matches_the_lifted_dare(gps_filter):
    """One sensor at phase 0: P[0] solves the DARE of (F^N, H, sum F^i Q F^i', R)."""
    F, _, Q, _, sol = gps_filter
    powers = [np.linalg.matrix_power(F, i) for i in range(N + 1)]
    QN = sum(Fi @ Q @ Fi.T for Fi in powers[:N])
    P0 = sla.solve_discrete_are(powers[N].T, GPS_H.T, QN, GPS_R)
    assert rel(sol.P[0], P0) <= 1e-10


def test_gain_forms_and_phases_without_measurement(gps_filter):
    F, _, Q, _, sol = gps_filter
    P0 = sol.P[0]
    Kf = P0 @ GPS_H.T @ np.linalg.inv(GPS_H @ P0 @ GPS_H.T + GPS_R)
    assert np.allclose(sol.K_filter[0], Kf, rtol=1e-12)
    assert np.allclose(sol.K_predictor[0], F @ Kf, rtol=1e-12)
    assert np.allclose(sol.P_filtered[0], (np.eye(3) - Kf @ GPS_H) @ P0, rtol=1e-10, atol=1e-16)
    for k in range(1, N):
        assert sol.K_filter[k].shape == (3, 0) and sol.K_predictor[k].shape == (3, 0)
        assert np.array_equal(sol.P_filtered[k], sol.P[k])
    # the open-loop propagation between GPS fixes (the paper's remark)
    assert np.allclose(sol.P[2], F @ sol.P[1] @ F.T + Q, rtol=1e-13)


def test_every_phase_satisfies_the_recursion(gps_filter):
    F, C, Q, R, sol = gps_filter
    worst = 0.0
    for k in range(N):
        P = sol.P[k]
        if C[k].shape[0]:
            P = P - P @ C[k].T @ np.linalg.solve(C[k] @ P @ C[k].T + R[k], C[k] @ P)
        nxt = sol.P[(k + 1) % N]
        worst = max(worst, rel(F @ P @ F.T + Q, nxt))
    assert worst <= 1e-12 and sol.residual <= 1e-12


def test_monodromy_multipliers(gps_filter):
    F, C, _, _, sol = gps_filter
    Phi = np.eye(3)
    for k in range(N):  # phase 0 acts first: Phi = prod_{k=N-1..0} F (I - K_f[k] C[k])
        Phi = F @ (np.eye(3) - sol.K_filter[k] @ C[k]) @ Phi
    expected = np.sort_complex(np.linalg.eigvals(Phi))
    assert np.allclose(np.sort_complex(sol.monodromy_multipliers), expected, atol=1e-12)
    assert np.all(np.abs(sol.monodromy_multipliers) < 1)


def test_result_is_frozen(gps_filter):
    sol = gps_filter[-1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.period = 3
    with pytest.raises(ValueError):
        sol.P[0][0, 0] = 0.0


def test_two_sensors_at_different_rates():
    """GPS position at 1 Hz (phase 0) and a velocity sensor at 5 Hz (every 10th phase)."""
    F, Q = position_model()
    Hv, Rv = np.array([[0.0, 1.0, 0.0]]), np.array([[0.01]])
    C, R = [], []
    for k in range(N):
        rows = ([GPS_H] if k == 0 else []) + ([Hv] if k % 10 == 0 else [])
        noises = ([GPS_R[0, 0]] if k == 0 else []) + ([Rv[0, 0]] if k % 10 == 0 else [])
        C.append(np.vstack(rows) if rows else np.zeros((0, 3)))
        R.append(np.diag(noises) if noises else np.zeros((0, 0)))
    sol = periodic_dare(F, C, Q, R)
    ref = naive_recursion(F, C, Q, R)
    assert max(rel(P, Pr) for P, Pr in zip(sol.P, ref, strict=True)) <= 1e-10
    assert [K.shape[1] for K in sol.K_filter[:11]] == [2] + [0] * 9 + [1]


def test_time_varying_dynamics():
    """Alternating sample intervals: A and Q change with the phase as well."""
    (F1, Q1), (F2, Q2) = position_model(0.01), position_model(0.03)
    A, Q = [F1, F2] * 5, [Q1, Q2] * 5
    C = [GPS_H] + [np.zeros((0, 3))] * 9
    R = [GPS_R] + [None] * 9
    sol = periodic_dare(A, C, Q, R)
    assert max(rel(P, Pr) for P, Pr in zip(sol.P, naive_recursion(A, C, Q, R), strict=True)) <= 1e-10


def test_measured_every_phase_equals_the_standard_dare():
    F, Q = position_model(bias_sigma=1e-2)
    g = kalman_discrete(F, GPS_H, Q, GPS_R)
    sol = periodic_dare(F, [GPS_H] * 3, Q, GPS_R)
    assert all(rel(P, g.P) <= 1e-10 for P in sol.P)
    assert np.allclose(sol.K_filter[1], g.K_filter, rtol=1e-9)


def test_undetectable_multiplier_is_named():
    A = np.diag([1.1, 0.5])
    C = [np.array([[0.0, 1.0]]), np.zeros((0, 2))]
    with pytest.raises(NotDetectableError, match=r"multiplier at z = 1\.21 is unstable and not observable"):
        periodic_dare(A, C, np.eye(2), [np.eye(1), None])


def test_unexcited_unit_circle_mode_raises():
    F, Q = position_model(bias_sigma=0.0)  # a constant bias: no stabilising solution
    C, R = gps_schedule()
    with pytest.raises(NotStabilisableError, match="not excited by the process noise Q"):
        periodic_dare(F, C, Q, R)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((np.eye(2), [np.ones((1, 2))] * 3, [np.eye(2)] * 2, 1.0), "one common length"),
        ((np.eye(2), [np.ones((1, 2)), None], np.eye(2), [np.eye(2), None]), r"R\[0\] must be 1x1 \(got 2x2\)"),
        ((np.eye(2), [np.ones((1, 2)), None], np.eye(2), [1.0, 1.0]), r"R\[1\] must be empty"),
        ((np.eye(2), [np.ones((1, 3))], np.eye(2), 1.0), r"C\[0\] must be 1x2 \(got 1x3\)"),
        ((np.eye(2), np.ones((1, 2)), -np.eye(2), 1.0), r"Q\[0\] must be positive semidefinite"),
        ((np.eye(2), np.ones((1, 2)), np.eye(2), -1.0), r"R\[0\] must be positive definite"),
        (([np.eye(2), np.full((2, 2), np.nan)], np.ones((1, 2)), np.eye(2), 1.0), r"A\[1\] contains NaN"),
    ],
)
def test_invalid_periodic_data_is_named(args, message):
    with pytest.raises(RiccatiError, match=message):
        periodic_dare(*args)


def test_precise_slow_sensor_keeps_its_small_posterior_variance():
    """A 1e-12 m GPS once a period: P+ = P - K S K' cancelled to the rounding of the prior
    (1.3e-23 m^2 for R = 1e-24 in a 100 Hz / 2.7 Hz design; here an indefinite P+); the
    Joseph-form update gives R C P C' / (C P C' + R) and a positive definite P+."""
    F, Q = position_model()
    R_tiny = np.array([[1e-24]])
    C, R = gps_schedule()
    R = [R_tiny, *R[1:]]
    sol = periodic_dare(F, C, Q, R)
    prior = sol.P[0][0, 0]
    assert prior > 1e-12  # the prior after a period of prediction is far above R
    expected = R_tiny[0, 0] * prior / (prior + R_tiny[0, 0])
    assert sol.P_filtered[0][0, 0] == pytest.approx(expected, rel=1e-6)
    assert np.all(np.linalg.eigvalsh(sol.P_filtered[0]) > 0)


@pytest.mark.parametrize("period", [100, 400])
def test_unstable_dynamics_with_a_slow_precise_sensor(period):
    """x[k+1] = 1.05 x[k] + w (Q = 1), measured once per period (R = 1).  Over the period the
    prior grows to 1e18 (period 400), so the update P - K S K' cancelled to the rounding of P and
    the prediction multiplied that error by 1.05^(2 period): P[0] came out 9 % too small while
    the fixed-point residual (the same recursion) read 0.  Against the closed form of the
    scalar lifted equation P = a^(2N) P R / (P + R) + sum_i a^(2i) Q."""
    import mpmath as mp

    with mp.workdps(60):
        a = mp.mpf("1.05")
        phi2, W = a ** (2 * period), sum(a ** (2 * i) for i in range(period))
        b = 1 - phi2 - W
        exact = float((-b + mp.sqrt(b * b + 4 * W)) / 2)
    C = [np.ones((1, 1))] + [np.zeros((0, 1))] * (period - 1)
    R = [np.ones((1, 1))] + [np.zeros((0, 0))] * (period - 1)
    sol = periodic_dare(np.array([[1.05]]), C, np.eye(1), R)
    assert abs(sol.P[0][0, 0] - exact) <= 1e-12 * exact
    # the posterior after the measurement is R P / (P + R), just below R
    assert abs(sol.P_filtered[0][0, 0] - exact / (exact + 1)) <= 1e-14


@pytest.mark.parametrize("period", [1, 5])
def test_unstable_mode_without_process_noise_has_a_stabilising_solution(period):
    """x[k+1] = 1.2 x[k] with no process noise, measured once a period (R = 1): the unstable
    mode is observable, so the stabilising solution exists (P = a^(2N) P R / (P + R), i.e.
    P = a^(2N) - 1 for Q = 0) although the noise does not excite it.  Doubling from P = 0 found
    the other fixed point, P = 0 (its closed loop is A itself), and the solver reported
    'the periodic closed loop is not stable'.  Also with a second, excited and stable state."""
    a = 1.2
    C = [np.ones((1, 1))] + [np.zeros((0, 1))] * (period - 1)
    R = [np.ones((1, 1))] + [None] * (period - 1)
    sol = periodic_dare(np.array([[a]]), C, np.zeros((1, 1)), R)
    assert sol.P[0][0, 0] == pytest.approx(a ** (2 * period) - 1, rel=1e-13)
    assert np.max(np.abs(sol.monodromy_multipliers)) < 1
    A2, Q2 = np.diag([a, 0.5]), np.diag([0.0, 1.0])
    C2 = [np.array([[1.0, 1.0]])] + [np.zeros((0, 2))] * (period - 1)
    sol2 = periodic_dare(A2, C2, Q2, R)
    if period == 1:  # the standard filter DARE
        assert max(rel(P, kalman_discrete(A2, C2[0], Q2, R[0]).P) for P in sol2.P) <= 1e-12
    for k in range(period):  # every phase satisfies the recursion
        P, Cn, Rn = sol2.P[k], C2[k], R[k]
        Pp = P - P @ Cn.T @ np.linalg.solve(Cn @ P @ Cn.T + Rn, Cn @ P) if Cn.shape[0] else P
        assert rel(A2 @ Pp @ A2.T + Q2, sol2.P[(k + 1) % period]) <= 1e-12
    assert np.max(np.abs(sol2.monodromy_multipliers)) < 1
