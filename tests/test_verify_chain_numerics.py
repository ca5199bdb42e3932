"""verify on long kinematic chains: the frequency-grid check is evaluated accurately or says it cannot."""

import dataclasses
import warnings

import mpmath as mp
import numpy as np
import pytest

from cfdesign import linear
from cfdesign.gains import GainTable, Schedule, SensorPort
from cfdesign.riccati import kalman_discrete
from cfdesign.verify import verify_table


def _chain_table(n, dt, K=None):
    F, b = linear.zoh_chain(n, dt)
    H = np.eye(n)[:1]
    if K is None:  # the Kalman gain of the chain driven by white noise on its top derivative
        K = kalman_discrete(F, H, np.outer(b, b), np.array([[1e-2]])).K_filter
    return GainTable(name=f"chain {n}", structure="custom", domain="z", sample_time_s=dt, gain_form="filter",
                     sensors=(SensorPort("u", "input", 0, n, 1 / dt), SensorPort("y", "measurement", 0, 0, 1 / dt)),
                     F=F, B=b[:, None], H=H, K=[K], P=[np.eye(n)], P_filtered=[np.eye(n)],
                     schedule=Schedule.from_names(["y"], [["y"]]), Q=np.eye(n), R=np.eye(1),
                     states=tuple(f"d{i}" for i in range(n)))


def _grid(checks):
    return next(c for c in checks if c.name == "complementary (frequency grid)")


@pytest.mark.parametrize("n", [6, 10, 14, 20])
def test_grid_check_passes_a_kalman_chain_at_100_hz(n):
    # states scaled dt^i apart: an unbalanced solve gave an input band off by 20 near Nyquist (n = 10)
    check = _grid(verify_table(_chain_table(n, 0.01)))
    assert check.ok, check.detail


def test_zoh_relations_match_the_direct_solve():
    dt, M = 0.1, 5
    shift = np.expm1(1j * np.array([0.3, 3.0, 30.0]) * dt)
    F, B = linear.zoh_chain(M, dt)
    G = np.array([np.linalg.solve((1 + s) * np.eye(M) - F, B) for s in shift])
    G = np.concatenate([G, np.ones((len(shift), 1))], axis=1)
    mants, exps = linear.zoh_relation_response([0, 1, 3, M], dt, shift)
    for d, m, e in zip([0, 1, 3, M], mants, exps, strict=True):
        np.testing.assert_allclose(m * np.exp2(e), G[:, d] / G[:, 0], rtol=1e-12)


def test_n200_chain_gives_no_nan_and_no_warning():
    n = 200
    K = np.zeros((n, 1))
    K[0, 0], K[1, 0] = 0.5, 0.01
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check = _grid(verify_table(_chain_table(n, 0.01, K)))
    assert not check.ok and "cannot be evaluated accurately" in check.detail and "nan" not in check.detail


@pytest.mark.parametrize("n", [14, 20])
def test_resolvent_outputs_against_mpmath_on_a_long_chain(n):
    """The input column B of an n-chain spans dt^n/n! .. dt, and c (vI - A)^-1 B is 1e17 (n = 14)
    to 1e32 (n = 20) times below the normwise error of a complex Schur solve: that route gave an
    input band of 1e16 and a grid error of 1.0 (false FAIL) for every n >= 13.  Each output must
    match a 50-digit solve of the same matrices to 1e-11."""
    dt = 0.01
    table = _chain_table(n, dt)
    real = linear.realisation(table.F, table.B, table.H, table.K[0], "filter", "posterior")
    omega = np.array([1e-3, 0.5, 3.1, 60.0, 310.0])
    shift = np.expm1(1j * omega * dt)
    got = linear._resolvent_outputs(real.delta, shift, real.G, real.C[0])
    with mp.workdps(50):
        delta, G, c = (mp.matrix(M.tolist()) for M in (real.delta, real.G, real.C[:1]))
        for k, s in enumerate(shift):
            M = delta + mp.mpc(s.real, s.imag) * mp.eye(n)
            for j in range(G.cols):
                ref = complex((c * mp.lu_solve(M, G[:, j]))[0])
                assert abs(got[k, j] - ref) <= 1e-11 * abs(ref), (k, j, got[k, j], ref)


def test_grid_check_still_fails_a_non_complementary_long_chain():
    """The accurate long-chain route must not pass what is not complementary: a model F off by
    1e-6 in one entry, or an input port declared of the wrong order for B, must FAIL."""
    n, dt = 20, 0.01
    good = _chain_table(n, dt)
    F = good.F.copy()
    F[0, 1] *= 1 + 1e-6
    bad_F = dataclasses.replace(good, F=F)
    port = good.sensors[0]
    bad_B = dataclasses.replace(good, sensors=(dataclasses.replace(port, order=n - 1), good.sensors[1]))
    assert _grid(verify_table(good)).ok
    for table in (bad_F, bad_B):
        check = _grid(verify_table(table))
        assert not check.ok, check.detail


def _identity(checks):
    return next(c for c in checks if c.name == "complementary (polynomial identity)")


def test_identity_check_says_when_double_precision_cannot_decide():
    """n = 20 Kalman chain at 100 Hz: the bands sum to one exactly for any gain, but the degree-20
    coefficients carry rounding errors of 4e-4 (reversing the state order changes the residual
    from 4.5e-4 to 2.9e-4).  The check cannot PASS on that, but must say that double precision
    cannot decide it rather than report a non-complementary table; the grid check passes."""
    checks = verify_table(_chain_table(20, 0.01))
    check = _identity(checks)
    assert not check.ok and "cannot be decided in double precision" in check.detail
    assert _grid(checks).ok


@pytest.mark.parametrize("n", [4, 6, 10])
def test_identity_check_small_tables_and_genuine_failures(n):
    """Small tables are decided as before (PASS, no note), and a model F off by 1e-6 is a plain
    FAIL: its residual (2e-6) stands far above the rounding estimate (1e-14 .. 1e-10)."""
    good = _chain_table(n, 0.01)
    check = _identity(verify_table(good))
    assert (check.ok or n == 10) and ("cannot be decided" in check.detail) == (n == 10)
    F = good.F.copy()
    F[0, 1] *= 1 + 1e-6
    check = _identity(verify_table(dataclasses.replace(good, F=F)))
    assert not check.ok and "cannot be decided" not in check.detail
    assert 1e-6 <= float(check.detail.split("size ")[1].split(",")[0]) <= 1e-5


def test_identity_check_does_not_pass_overflowing_coefficients():
    """A gain of 1e300 overflows the coefficients to NaN; 'NaN > worst' is false, so the check
    used to PASS with 'relative coefficient size 0.00e+00'."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        check = _identity(verify_table(_chain_table(8, 1.0, np.full((8, 1), 1e300))))
    assert not check.ok and "not finite" in check.detail
