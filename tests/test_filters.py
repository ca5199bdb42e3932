"""Named filters against independent derivations: hand-typed formulas and a linear solve.

The engine derives bands with the adjugate of (vI - A).  Here every band is checked
(a) against the formula typed from Carreira et al. / docs/derivations.md and (b) against a
derivation that solves the observer equations for the estimate with sympy.linsolve, one
sensor at a time.
"""

import pytest
import sympy as sp

import cfdesign
from cfdesign.symbolic.observer import T, s, z

k, k1, k2, k3, k4, k5 = sp.symbols("k k1 k2 k3 k4 k5")
k11, k12, k21, k22 = sp.symbols("k11 k12 k21 k22")


def same(a, b):
    return sp.cancel(sp.together(a - b)) == 0


def solve_band(F, B, H, K, var, reading, role, index, discrete_filter=False):
    """psi_hat / psi for one sensor, by solving (vI - F + KH) X = B u + K y (predictor form)."""
    n = F.shape[0]
    X = sp.Matrix(sp.symbols(f"x0:{n}"))
    u = sp.zeros(B.shape[1], 1)
    y = sp.zeros(H.shape[0], 1)
    (u if role == "input" else y)[index] = reading  # reading expressed per unit psi
    eqs = (var * sp.eye(n) - F + K * H) * X - B * u - K * y
    (sol,) = sp.linsolve(list(eqs), list(X))
    return sp.cancel(sol[0])


# --------------------------------------------------------------------------- CF (two sensors)
def test_cf2_first_order_matches_textbook():
    obs = cfdesign.cf2(order=1)
    assert same(obs.bands["angle"], k / (s + k))
    assert same(obs.bands["rate"], s / (s + k))
    assert obs.proof().holds


def test_cf2_second_order_matches_math_md():
    obs = cfdesign.cf2(order=2)
    den = s**2 + k1 * s + k2
    assert same(obs.bands["angle"], (k1 * s + k2) / den)
    assert same(obs.bands["rate"], s**2 / den)
    assert obs.proof().holds


@pytest.mark.parametrize("order", [1, 2])
def test_cf2_discrete_proof_and_independent_solve(order):
    obs = cfdesign.cf2(order=order, discrete=True)
    assert obs.proof().holds
    band = solve_band(obs.F, obs.B, obs.H, obs.K, z, 1, "measurement", 0)
    assert same(obs.bands["angle"], band)


# --------------------------------------------------------------------------- CF3
def test_cf3_matches_carreira_eqs_4_to_6():
    obs = cfdesign.cf3()
    den = s**2 + k1 * s + k2
    assert same(obs.bands["acceleration"], s**2 / den)  # eq. (4), high-pass
    assert same(obs.bands["velocity"], k1 * s / den)  # eq. (5), band-pass
    assert same(obs.bands["position"], k2 / den)  # eq. (6), low-pass
    assert obs.proof().holds


def test_cf3_poles_and_zeros_match_eqs_7_8():
    obs = cfdesign.cf3()
    expected = {-(k1 + sp.sqrt(k1**2 - 4 * k2)) / 2, -(k1 - sp.sqrt(k1**2 - 4 * k2)) / 2}
    assert {sp.simplify(p) for p in obs.poles()} == {sp.simplify(p) for p in expected}
    zeros = obs.zeros()
    assert zeros["acceleration"] == [0, 0] and zeros["velocity"] == [0] and zeros["position"] == []


# --------------------------------------------------------------------------- CKF3
def test_ckf3_matches_derivation_of_math_md_s4():
    obs = cfdesign.ckf3()
    den = s**2 + (k11 + k22) * s + (k11 * k22 + k21 - k12 * k21)
    assert same(obs.bands["acceleration"], (1 - k12) * s**2 / den)
    assert same(obs.bands["velocity"], (k12 * s + k22) * s / den)
    assert same(obs.bands["position"], (k11 * s + k11 * k22 + k21 - k12 * k21) / den)
    assert obs.proof().holds


def test_ckf3_independent_linear_solve():
    obs = cfdesign.ckf3()
    F, B, H, K = obs.F, obs.B, obs.H, obs.K
    assert same(obs.bands["acceleration"], solve_band(F, B, H, K, s, s**2, "input", 0))
    assert same(obs.bands["velocity"], solve_band(F, B, H, K, s, s, "measurement", 1))
    assert same(obs.bands["position"], solve_band(F, B, H, K, s, 1, "measurement", 0))


def test_ckf3_printed_eqs_15_17_differ_from_the_model_but_also_sum_to_one():
    """Carreira et al. eqs. (15)-(17) do not follow from eqs. (10)-(14) (docs/derivations.md, "Three-band filters")."""
    printed = cfdesign.ckf3_printed()
    derived = cfdesign.ckf3().bands
    assert same(sum(printed.values()), 1)
    for name in ("acceleration", "velocity", "position"):
        assert not same(printed[name], derived[name]), name
    # they coincide only where the model's extra terms vanish (k12 = 0 and k11 k22 = 0 ...)
    sub = {k12: 0, k11: 0}
    assert same(printed["acceleration"].subs(sub), derived["acceleration"].subs(sub))


def test_ckf3_with_sparse_gain_is_cf3():
    sparse = cfdesign.ckf3().subs(k11=0, k12=0)
    cf3 = cfdesign.cf3()
    for name in cf3.bands:
        assert same(sparse.bands[name].subs({k21: k2, k22: k1}), cf3.bands[name])


# --------------------------------------------------------------------------- DCKF3
def test_dckf3_matches_math_md_s5():
    obs = cfdesign.dckf3()
    den = z**2 + (k11 + k12 - 2) * z + (1 - k11 - k12 + T * k21 + T * k22)
    assert same(obs.bands["gyro"], (z - 1) ** 2 / den)
    assert same(obs.bands["compass"], (k11 * (z - 1) + T * k21) / den)
    assert same(obs.bands["odometry"], (k12 * (z - 1) + T * k22) / den)
    assert obs.proof().holds


def test_dckf3_independent_linear_solve():
    obs = cfdesign.dckf3()
    F, B, H, K = obs.F, obs.B, obs.H, obs.K
    assert same(obs.bands["gyro"], solve_band(F, B, H, K, z, (z - 1) / T, "input", 0))
    assert same(obs.bands["compass"], solve_band(F, B, H, K, z, 1, "measurement", 0))
    assert same(obs.bands["odometry"], solve_band(F, B, H, K, z, 1, "measurement", 1))


def test_dckf3_reproduces_eq32_denominator_exactly():
    obs = cfdesign.dckf3()
    assert sp.expand(obs.characteristic_polynomial * z**-2 - cfdesign.eq32_denominator()) == 0


def test_dckf3_printed_labels_are_mixed_up():
    """Eq. (29) is the gyro band, eq. (30) odometry, eq. (31)*(1-z^-1)/(T z^-1) compass."""
    printed = cfdesign.dckf3_printed()
    derived = cfdesign.dckf3().bands
    for name in ("gyro", "compass", "odometry"):
        assert same(printed[name], derived[name]), name
    # the paper calls eq. (30) the transfer from the compass psi: it is not the compass band
    assert not same(printed["odometry"], derived["compass"])
    assert same(sum(printed.values()), 1)


# --------------------------------------------------------------------------- n bands
@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_cfn_matches_closed_form(n):
    m = n - 1
    gains = sp.symbols(f"k1:{n}")
    den = s**m + sum(gains[i] * s ** (m - 1 - i) for i in range(m))
    obs = cfdesign.cfn(n)
    names = ("position", "velocity", "acceleration", "jerk", "snap", "crackle")
    for j in range(m):
        assert same(obs.bands[names[j]], gains[m - 1 - j] * s**j / den), (n, j)
    assert same(obs.bands[names[m]], s**m / den)
    assert obs.proof().holds


@pytest.mark.parametrize("n", [2, 3, 4])
def test_cfn_full_gain_independent_solve(n):
    obs = cfdesign.cfn(n, full=True)
    assert obs.proof().holds
    F, B, H, K = obs.F, obs.B, obs.H, obs.K
    m = n - 1
    top = ("position", "velocity", "acceleration", "jerk")[m]
    assert same(obs.bands[top], solve_band(F, B, H, K, s, s**m, "input", 0))
    assert same(obs.bands["position"], solve_band(F, B, H, K, s, 1, "measurement", 0))


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_cfn_discrete_zoh_chain_proof(n):
    assert cfdesign.cfn(n, discrete=True).proof().holds


def test_cfn_rejects_bad_n():
    for bad in (1, 8, 2.5, "3"):
        with pytest.raises(cfdesign.StructureError):
            cfdesign.cfn(bad)


def test_counts_are_whole_numbers():
    """cf2(order=2.0) failed with a raw TypeError from list arithmetic and order=True built order 1;
    a numpy integer for cfn's n (a loop over np.arange) was refused."""
    import numpy as np

    assert cfdesign.cfn(np.int64(3)).bands == cfdesign.cfn(3).bands
    assert cfdesign.cf2(order=np.int64(2)).name == "cf2 (order 2)"
    for bad in (2.0, True, "2", 3):
        with pytest.raises(cfdesign.StructureError, match=f"cf2 order must be 1 or 2, got {bad!r}"):
            cfdesign.cf2(order=bad)
    for bad in (2.0, "3", 1, 8):
        with pytest.raises(cfdesign.StructureError, match="cfn needs a whole number of bands"):
            cfdesign.cfn(bad)
