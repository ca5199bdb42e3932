"""Design: spec -> noise -> Riccati -> GainTable, against independent computations."""

import dataclasses
import re

import numpy as np
import pytest
from scipy import linalg

import cfdesign
from cfdesign.designer import design, designed_observer, multirate_schedule
from cfdesign.errors import SpecError
from cfdesign.gains import load_gains
from cfdesign.spec import example_path, load_spec, parse_spec


def dckf3_spec(**changes):
    data = {
        "structure": "dckf3",
        "sensors": {
            "gyro": {"rate_hz": 5.0, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-3}},
            "compass": {"rate_hz": 5.0, "noise": {"std": 0.04}},
            "odometry": {"rate_hz": 5.0, "noise": {"std": 0.01}},
        },
    }
    data.update(changes)
    return parse_spec(data)


def test_dckf3_gains_match_scipy_dare_with_hand_built_covariances():
    """Q by the closed-form Van Loan integral of Fc = [[0,1],[0,0]], Qc = diag(q, qb)."""
    T, q, qb = 0.2, 0.05**2 * 0.2, 1e-3**2
    Q = np.array([[q * T + qb * T**3 / 3, qb * T**2 / 2], [qb * T**2 / 2, qb * T]])
    R = np.diag([0.04**2, 0.01**2])
    F, H = np.array([[1, T], [0, 1]]), np.array([[1.0, 0], [1, 0]])
    P = linalg.solve_discrete_are(F.T, H.T, Q, R)
    K_filter = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    for form, K_ref in (("predictor", F @ K_filter), ("filter", K_filter)):
        table = design(dckf3_spec(gain_form=form))
        assert np.allclose(table.Q, Q, rtol=1e-10, atol=0)
        assert np.allclose(table.K[0], K_ref, rtol=1e-8, atol=0)
        assert np.allclose(table.P[0], P, rtol=1e-8, atol=0)
        assert table.gain_form == form


def test_designed_dckf3_symbolic_bands_sum_to_one_and_are_stable():
    table = design(load_spec(example_path("robot-heading")))
    obs = cfdesign.dckf3().with_gains({**table.gains, "T": table.sample_time_s})
    assert obs.proof().holds
    assert all(abs(complex(p)) < 1 for p in obs.poles())
    assert table.checks["complementary"] and table.checks["stable"]


def test_ckf3_continuous_matches_scipy_care():
    table = design(load_spec(example_path("ckf3")))
    F, H, Q, R = table.F, table.H, table.Q, table.R
    P = linalg.solve_continuous_are(F.T, H.T, Q, R)
    assert np.allclose(table.K[0], P @ H.T @ np.linalg.inv(R), rtol=1e-8)  # Carreira et al. eq. (23)
    # Q: the accelerometer PSD through Bc = [0, 1]^T; R: the PSDs of the velocity and position sensors
    assert np.allclose(Q, [[0, 0], [0, 0.003**2]])
    assert np.allclose(R, np.diag([0.05**2 / 10, 0.01**2 / 100]))


def test_fixed_cf3_gains_error_matches_closed_form():
    """CF3 error variance (q_a + k1^2 r_v + k2^2 r_p) / (2 k1 k2), from the bands of eqs. (4)-(6)."""
    table = design(load_spec(example_path("cf3")))
    k1, k2 = table.gains["k1"], table.gains["k2"]
    q_a, r_p, r_v = table.Q[1, 1], table.R[0, 0], table.R[1, 1]
    assert table.P[0][0, 0] == pytest.approx((q_a + k1**2 * r_v + k2**2 * r_p) / (2 * k1 * k2), rel=1e-10)
    # the hand-tuned CF3 is worse than the CKF3 optimum for the same sensors
    assert table.P[0][0, 0] > design(load_spec(example_path("ckf3"))).P[0][0, 0]


def test_sparse_cf3_without_gains_reports_no_finite_optimum():
    spec = load_spec(example_path("cf3"))
    data = {"structure": "cf3", "sensors": {s.name: {"rate_hz": s.rate_hz, "noise": {"std": s.noise.std}
                                                     if s.noise.std is not None else {"density": s.noise.density}}
                                            for s in spec.sensors}}
    with pytest.raises(SpecError, match="no finite optimum"):
        design(parse_spec(data))


def test_sparse_discrete_cf2_optimum_is_a_local_minimum_and_no_better_than_kalman():
    data = {"structure": "cf3", "discrete": True, "sensors": {
        "acceleration": {"rate_hz": 50.0, "noise": {"std": 0.5}},
        "velocity": {"rate_hz": 50.0, "noise": {"std": 0.3}},
        "position": {"rate_hz": 50.0, "noise": {"std": 0.05}}}}
    table = design(parse_spec(data))
    from cfdesign.designer import _output_covariance

    F, H, Q, R = table.F, table.H, table.Q, table.R
    assert table.output == "posterior"  # the variance minimised is that of the estimate the table outputs
    best = table.P_filtered[0][0, 0]
    k1, k2 = table.gains["k1"], table.gains["k2"]
    for d1, d2 in ((1.01, 1), (0.99, 1), (1, 1.01), (1, 0.99)):
        K = np.array([[0, 0], [k2 * d2, k1 * d1]])
        assert _output_covariance(F, H, K, Q, R, "predictor", "posterior")[0, 0] >= best * (1 - 1e-9)
    assert best >= table.provenance["solver"]["kalman_predicted_variance"]


def test_multirate_position_filter_gains_zero_between_fixes():
    table = design(load_spec(example_path("position")))
    assert table.period == 50 and table.sample_time_s == pytest.approx(0.02)
    for k, K in enumerate(table.K):
        if k == 0:
            assert table.schedule.names(k) == ["gps"] and np.abs(K).max() > 0
        else:
            assert table.schedule.names(k) == [] and np.all(K == 0)
    assert table.checks["stable"] and table.checks["complementary"]
    assert table.phase_model(0)[2].shape == (1, 3) and table.phase_model(1)[2].shape == (0, 3)
    # lifted check: P[0] solves the DARE of (F^N, H, sum F^i Q F^iT, R) (docs/derivations.md, "Multirate gains")
    F, H, Q, R = table.F, table.H, table.Q, table.R
    FN = np.linalg.matrix_power(F, 50)
    QN = sum(np.linalg.matrix_power(F, i) @ Q @ np.linalg.matrix_power(F, i).T for i in range(50))
    P0 = linalg.solve_discrete_are(FN.T, H.T, QN, R)
    assert np.allclose(table.P[0], P0, rtol=1e-8)


def test_multirate_schedule_lcm_and_errors():
    dt, s = multirate_schedule({"imu": 20.0, "a": 10.0, "b": 4.0}, inputs=["imu"])
    assert dt == 1 / 20 and s.period == 10 and s.measurements == ("a", "b")
    assert s.names(0) == ["a", "b"] and s.names(2) == ["a"] and s.names(5) == ["b"] and s.rows(7) == ()
    assert s.rows(10) == (0, 1)  # phases wrap around the period
    dt, s = multirate_schedule({"imu": 50.0, "gps": 0.7}, inputs=["imu"])  # 50/0.7 = 500/7: 7 fixes every 500 ticks
    assert s.period == 500 and s.phases("gps") == (0, 71, 143, 214, 286, 357, 429)
    dt, s = multirate_schedule({"imu": 100.0, "gps": 3.0, "baro": 10.0}, inputs=["imu"], offsets_s={"baro": 0.03})
    assert s.period == 100 and s.phases("gps") == (0, 33, 67) and s.phases("baro")[:2] == (3, 13)
    with pytest.raises(SpecError, match=r"sensors\.gps\.rate_hz.*not a fraction of the base rate"):
        multirate_schedule({"imu": 50.0, "gps": 50.0 / 3.14159265358979}, inputs=["imu"])
    # a GPS declared at 3.333 Hz (one fix every 0.3 s) is refused with a rate that designs, and that rate does
    for typed, period in ((3.333, 30), (1.003, 100), (0.13, 7692)):
        imu = 1000.0 if typed == 0.13 else 100.0
        with pytest.raises(SpecError, match=r"rate_hz = ([0-9.]+) is .* % from it, with a period of") as info:
            multirate_schedule({"imu": imu, "gps": typed}, inputs=["imu"])
        advised = float(re.search(r"rate_hz = ([0-9.]+)", str(info.value)).group(1))
        assert abs(advised / typed - 1) <= 0.01
        assert multirate_schedule({"imu": imu, "gps": advised}, inputs=["imu"])[1].period == period
    with pytest.raises(SpecError, match=r"input sensor imu must run at the base rate"):
        multirate_schedule({"imu": 10.0, "gps": 20.0}, inputs=["imu"])
    # the slowest rate the cap allows runs; slower ones are named as too slow (they were called "not a
    # fraction of the base rate", 0.05 Hz beside 1 kHz being exactly 1/20000 of it)
    assert multirate_schedule({"imu": 1000.0, "gps": 0.1}, inputs=["imu"])[1].period == 10_000
    for slow in (0.05, 0.09, 1e-300):
        with pytest.raises(SpecError, match=r"sensors\.gps\.rate_hz: .* Hz is slower than the period of at most "
                                            r"10000 base steps allows: at least 0\.1 Hz"):
            multirate_schedule({"imu": 1000.0, "gps": slow}, inputs=["imu"])


def test_gain_table_round_trip_is_exact(tmp_path):
    table = design(load_spec(example_path("position")))
    path = table.save(tmp_path / "g.json")
    back = load_gains(path)
    for key in ("F", "B", "H", "Q", "R"):
        assert np.array_equal(getattr(back, key), getattr(table, key))
    for a, b in zip(back.K + back.P, table.K + table.P, strict=True):
        assert np.array_equal(a, b)
    assert back.schedule == table.schedule and back.sensors == table.sensors and back.provenance == table.provenance


def test_provenance_names_spec_and_version():
    spec = load_spec(example_path("dckf3"))
    table = design(spec)
    assert table.provenance["spec_sha256"] == spec.sha256 and len(spec.sha256) == 64
    assert table.provenance["cfdesign_version"] == cfdesign.__version__
    assert table.provenance["solver"]["residual"] < 1e-12


def test_designed_observer_is_the_symbolic_structure_with_gains():
    spec = load_spec(example_path("ckf3"))
    obs = designed_observer(spec, design(spec))
    assert obs.is_numeric and obs.proof().holds


def test_cfn_design_file():
    sensors = {n: {"rate_hz": 50.0, "noise": {"std": 0.1}} for n in ("position", "velocity", "acceleration")}
    table = design(parse_spec({"structure": "cfn", "bands": 3, "discrete": True, "sensors": sensors,
                               "gains": {"k1": 2.0, "k2": 1.0}}))
    assert table.checks["stable"] and table.gains == {"k1": 2.0, "k2": 1.0}


def test_fixed_filter_gain_covariance_matches_iterated_recursion():
    """Joseph form: iterate P- -> P+ = (I-KH)P-(I-KH)' + KRK' -> F P+ F' + Q for a NON-optimal K."""
    spec = dckf3_spec(gain_form="filter", gains={"k11": 0.3, "k12": 0.2, "k21": 0.01, "k22": 0.02})
    table = design(spec)
    F, H, Q, R, K = table.F, table.H, table.Q, table.R, table.K[0]
    I_KH = np.eye(2) - K @ H
    P = np.eye(2)
    for _ in range(20000):
        Pp = I_KH @ P @ I_KH.T + K @ R @ K.T
        P = F @ Pp @ F.T + Q
    assert np.allclose(table.P[0], P, rtol=1e-9)
    assert np.allclose(table.P_filtered[0], Pp, rtol=1e-9)
    assert table.predicted_std == pytest.approx(np.sqrt(Pp[0, 0]), rel=1e-9)
    # and the optimum is better
    assert table.provenance["solver"]["kalman_predicted_variance"] < Pp[0, 0]


def test_periodic_gains_every_phase_match_the_iterated_recursion():
    table = design(load_spec(example_path("position")))
    F, H, Q, R = table.F, table.H, table.Q, table.R
    P = np.eye(3)
    for _ in range(1500):  # whole periods (error shrinks by ~0.968 per period), GPS at phase 0
        for k in range(50):
            if k == 0:
                Kf = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
                P = (np.eye(3) - Kf @ H) @ P
            P = F @ P @ F.T + Q
    for k in range(50):
        scale = np.abs(table.P[k]).max()
        assert np.abs(table.P[k] - P).max() <= 1e-10 * scale, k
        if k == 0:
            Kf = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
            assert np.allclose(table.K[0], Kf, rtol=1e-10, atol=0)
            P = (np.eye(3) - Kf @ H) @ P
        P = F @ P @ F.T + Q


def test_unmodelled_biases_and_huge_periods_are_refused():
    data = {"structure": "dckf3", "sensors": {
        "gyro": {"rate_hz": 5.0, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-3}},
        "compass": {"rate_hz": 5.0, "noise": {"std": 0.04}},
        "odometry": {"rate_hz": 5.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-3}}}}
    with pytest.raises(SpecError, match=r"sensors\.odometry\.bias"):
        design(parse_spec(data))
    data["sensors"]["odometry"]["bias"] = {"model": "constant", "value": 0.01}  # simulation only: allowed
    design(parse_spec(data))
    with pytest.raises(SpecError, match="period"):
        multirate_schedule({"imu": 100.0, "a": 100.0 / 101, "b": 100.0 / 103}, inputs=["imu"])


def test_builtin_example_is_carreiras_best_filter():
    """`cfdesign design` designs Table II's best row (LP gyro, BP compass, HP odometry)."""
    from cfdesign.reproduce.carreira import READING, TABLE_II, design_row, scenario
    from cfdesign.reproduce.structures import design_observer

    table = design(load_spec(example_path("robot-heading")))
    row = TABLE_II[0]
    assert (row.low, row.band, row.high) == ("gyro", "compass", "odometry")
    # the reproduction designs for the paper's estimate (the prediction); the example for the
    # estimate it outputs by default (after each step's readings): same row, same spec otherwise
    assert design_row(row).output == "prior" and table.output == "posterior"
    best = design_observer(dataclasses.replace(row.spec(scenario(READING)), output="posterior"), row.observer())
    assert np.allclose(table.K[0], best.K[0], rtol=1e-9, atol=0)
    assert table.gains["k22"] == 0.0 and table.checks["complementary"] and table.checks["stable"]
    roles = {s.name: s.role for s in table.sensors}
    assert roles == {"odometry_rate": "input", "gyro_heading": "measurement", "compass": "measurement"}


def test_ports_and_partial_gains_are_checked():
    base = {"structure": "dckf3", "sensors": {
        "wheel": {"port": "gyro", "rate_hz": 5.0, "noise": {"std": 0.05},
                  "bias": {"model": "random_walk", "density": 1e-3}},
        "compass": {"rate_hz": 5.0, "noise": {"std": 0.04}},
        "odometry": {"rate_hz": 5.0, "noise": {"std": 0.01}}}}
    table = design(parse_spec({**base, "gains": {"k22": 0.0}}))
    assert [s.name for s in table.sensors] == ["wheel", "compass", "odometry"]
    assert table.K[0][1, 1] == 0.0 and table.gains["k22"] == 0.0
    bad = {**base, "sensors": {**base["sensors"], "wheel": {**base["sensors"]["wheel"], "port": "spinner"}}}
    with pytest.raises(SpecError, match=r"sensors\.wheel\.port"):
        design(parse_spec(bad))
    with pytest.raises(SpecError, match="gains: unknown k33"):
        design(parse_spec({**base, "gains": {"k33": 0.0}}))


STORED = {"cf2-order2-discrete": {"structure": "cf2", "order": 2, "discrete": True,
                                  "sensors": {"rate": {"rate_hz": 100.0, "noise": {"std": 0.01},
                                                       "bias": {"model": "random_walk", "density": 1e-4}},
                                              "angle": {"rate_hz": 100.0, "noise": {"std": 0.02}}}},
          "position": {"structure": "position", "gain_form": "filter",
                       "sensors": {"accelerometer": {"rate_hz": 50.0, "noise": {"std": 0.01},
                                                     "bias": {"model": "random_walk", "density": 1e-3}},
                                   "gps": {"rate_hz": 1.0, "noise": {"std": 3.0}}}}}


@pytest.mark.parametrize("name", sorted(STORED))
def test_stored_structures_are_the_symbolic_ones_and_design_alike(name):
    """The structures the navigation filters load without sympy equal a fresh symbolic derivation,
    and the numeric stage alone designs the same table as design()."""
    from cfdesign.designer import Structure, design_from_structure, numeric_structure

    spec = parse_spec(STORED[name])
    fresh, stored = numeric_structure(spec), Structure.load(name)
    assert stored.to_dict() == {**fresh.to_dict(), "name": stored.name} and stored.proved
    a, b = design(spec), design_from_structure(stored, spec)
    assert a.checks["complementary"] and b.checks["complementary"]
    for Ka, Kb in zip(a.K, b.K, strict=True):
        assert np.array_equal(Ka, Kb)
    with pytest.raises(SpecError, match="no stored structure 'nope'"):
        Structure.load("nope")


def test_numeric_stage_runs_without_sympy():
    import subprocess
    import sys

    code = ("import sys\nfrom cfdesign.designer import Structure, design_from_structure\n"
            "from cfdesign.spec import parse_spec\n"
            f"spec = parse_spec({STORED['position']!r})\n"
            "t = design_from_structure(Structure.load('position'), spec)\n"
            "assert t.period == 50 and t.checks['stable']\n"
            "assert 'sympy' not in sys.modules, 'sympy imported'\n")
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("output", ["posterior", "prior"])
def test_the_bode_observer_has_the_bands_of_the_estimate_that_runs(output):
    """`cfdesign design --bode` and `design()`'s exact proof use the bands of the table's output:
    the same as verify's numeric bands of that output."""
    from cfdesign.verify import band_polynomials

    spec = dataclasses.replace(load_spec(example_path("robot-heading")), output=output)
    table = design(spec)
    symbolic = designed_observer(spec, table).band_coefficients()
    numeric, _ = band_polynomials(table)
    z = np.exp(1j * np.linspace(0.05, 3.0, 25))
    for name, (num, den) in numeric.items():
        ref = np.polyval(symbolic[name][0], z) / np.polyval(symbolic[name][1], z)
        assert np.allclose(np.polyval(num, z) / np.polyval(den, z), ref, rtol=1e-8, atol=1e-12), name
    assert table.checks["complementary"] and output in table.checks["complementary_method"]


def test_an_offset_sensor_at_a_fractional_rate_is_scheduled_where_its_readings_land():
    """3 Hz GPS 0.124 s late on a 50 Hz tick: readings at 6.2, 22.87, 39.53 ticks land (as
    cfdesign.timing.place puts them) on 6, 23, 40; round(offset) + round(j p/q) gave 6, 23, 39,
    so a log matching the design file ran as a 'drifting' sensor with recomputed gains."""
    from cfdesign.timing import place

    dt, s = multirate_schedule({"imu": 50.0, "gps": 3.0}, inputs=["imu"], offsets_s={"gps": 0.124})
    imu = np.arange(50) * dt
    gps = 0.124 + np.arange(3) / 3.0
    t = np.concatenate([imu, gps])
    order = np.argsort(t, kind="stable")
    ticks = place(t[order], dt, base_rows=order < 50)[np.argsort(order)][50:]
    assert s.phases("gps") == tuple(int(k) for k in ticks) == (6, 23, 40)


@pytest.mark.parametrize("offset, expected", [(0.01, (1,)), (0.05, (3,)), (0.03, (2,))])
def test_half_tick_offsets_are_scheduled_where_placement_puts_them(offset, expected):
    """1 Hz GPS exactly half a tick late (0.01 s, 0.05 s at 50 Hz): the designer and the log's
    placement use one rounding (timing.nearest_tick, halves up); they differed (floor(x + 1/2)
    against numpy's round-half-even) and a log matching the design file was re-locked."""
    from cfdesign.timing import place

    dt, s = multirate_schedule({"imu": 50.0, "gps": 1.0}, inputs=["imu"], offsets_s={"gps": offset})
    imu = np.arange(50) * dt
    t = np.concatenate([imu, [offset]])
    order = np.argsort(t, kind="stable")
    placed = place(t[order], dt, base_rows=order < 50)[np.argsort(order)][50]
    assert s.phases("gps") == expected == (int(placed),)
