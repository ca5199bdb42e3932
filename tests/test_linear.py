"""The numeric linear core (cfdesign.linear) against the symbolic engine and hand-written recursions."""

import math

import numpy as np
import pytest
import sympy as sp

import cfdesign
from cfdesign import linear
from cfdesign.symbolic.observer import Observer, discrete_relation, z
from cfdesign.verify import band_polynomials


@pytest.fixture(scope="module")
def dckf3_table():
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3")))


# ---------------------------------------------------------------------- wrap
def test_wrap_range_identity_and_scalar_agreement():
    rng = np.random.default_rng(0)
    edges = [math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 0.0, 1e300, -1e300]
    edges += [math.nextafter(e, d) for e in (math.pi, -math.pi, 3 * math.pi, -3 * math.pi) for d in (-10, 10)]
    a = np.concatenate([rng.uniform(-50, 50, 10_000), edges, rng.uniform(-1e6, 1e6, 1000)])
    w = linear.wrap(a)
    assert np.all((w > -math.pi) & (w <= math.pi))
    small = np.abs(a) < 1e7  # the same angle up to the rounding of 2 pi k (|a| eps)
    tol = 1e-12 + 4e-16 * np.abs(a[small])
    assert np.all(np.abs(np.cos(w[small]) - np.cos(a[small])) <= tol)
    assert np.all(np.abs(np.sin(w[small]) - np.sin(a[small])) <= tol)
    inside = (a > -math.pi) & (a <= math.pi)
    assert np.array_equal(w[inside], a[inside])  # bit for bit
    assert [linear.wrap_scalar(float(v)) for v in a] == w.tolist()
    b = a.copy()
    assert np.array_equal(linear.wrap_inplace(b), w) and np.array_equal(b, w)
    assert float(linear.wrap(-math.pi)) == math.pi


def test_wrap_of_nan_and_inf_is_nan_for_scalars_as_for_arrays():
    for v in (math.nan, math.inf, -math.inf):
        assert math.isnan(linear.wrap_scalar(v)) and math.isnan(float(linear.wrap(v)))
    with np.errstate(all="raise"):  # no invalid-value warning from inf - inf either
        assert np.isnan(linear.wrap(np.array([math.nan, math.inf, -math.inf, 4.0]))[:3]).all()


# ---------------------------------------------------------------------- gain forms
def _random_table_matrices(seed, n=3, p=1, m=2):
    rng = np.random.default_rng(seed)
    F = np.eye(n) + 0.1 * np.triu(rng.normal(size=(n, n)), 1)
    return F, rng.normal(size=(n, p)), rng.normal(size=(m, n)), 0.2 * rng.normal(size=(n, m))


@pytest.mark.parametrize("form", ["predictor", "filter"])
def test_realisation_runs_the_named_recursion(form):
    """Both outputs of the realisation equal the gain form's recursion written out by hand."""
    F, B, H, K = _random_table_matrices(1)
    rng = np.random.default_rng(2)
    u, y = rng.normal(size=(50, 1)), rng.normal(size=(50, 2))
    prior = linear.realisation(F, B, H, K, form, "prior")
    post = linear.realisation(F, B, H, K, form, "posterior")
    x = xr = np.array([0.3, -0.1, 0.2])
    for k in range(50):
        w = np.concatenate([u[k], y[k]])
        if form == "predictor":  # x[k+1] = F x + B u + K (y - H x); the update gain is F^-1 K
            x_post = x + np.linalg.solve(F, K) @ (y[k] - H @ x)
            x_next = F @ x + B @ u[k] + K @ (y[k] - H @ x)
        else:  # x+ = x + K (y - H x); x[k+1] = F x+ + B u
            x_post = x + K @ (y[k] - H @ x)
            x_next = F @ x_post + B @ u[k]
        assert np.allclose(prior.C @ xr + prior.D @ w, x, atol=1e-12)
        assert np.allclose(post.C @ xr + post.D @ w, x_post, atol=1e-12)
        xr = prior.A @ xr + prior.G @ w
        x = x_next
        assert np.allclose(xr, x, atol=1e-12)
    assert linear.default_output(form) == ("prior" if form == "predictor" else "posterior")


def test_singular_F_has_no_posterior_for_predictor_gains():
    F, B, H, K = _random_table_matrices(3)
    F[:, 0] = 0.0
    assert linear.gain_pair(F, K, "predictor")[1] is None
    with pytest.raises(ValueError, match="invertible F"):
        linear.realisation(F, B, H, K, "predictor", "posterior")
    with pytest.raises(ValueError, match="gain form"):
        linear.gain_pair(F, K, "smoother")


def test_closed_loop_of_both_forms():
    F, _, H, K = _random_table_matrices(4)
    assert np.allclose(linear.closed_loop(F, H, K, "filter"), F @ (np.eye(3) - K @ H))
    assert np.allclose(linear.closed_loop(F, H, K, "predictor"), F - K @ H)
    assert np.allclose(linear.closed_loop(F, H, K, "continuous"), F - K @ H)


# ---------------------------------------------------------------------- bands
def _symbolic_bands(obs):
    return obs.band_coefficients()


def _same_response(numeric, symbolic, dt):
    w = np.linspace(0.01, 0.99 * math.pi / dt if dt else 20.0, 40)
    for name, (num, den) in numeric.items():
        a = linear.response(num, den, w, dt)
        b = linear.response(*symbolic[name], w, dt)
        assert np.allclose(a, b, rtol=1e-9, atol=1e-12), name


@pytest.mark.parametrize("output", ["prior", "posterior"])
def test_bands_match_the_symbolic_engine(dckf3_table, output):
    """Numeric bands of both outputs = the engine's bands of the same observer; both sum to one."""
    t = dckf3_table
    numeric, _ = band_polynomials(t, output=output)
    sym = cfdesign.dckf3()
    T = sp.Rational(str(t.sample_time_s))
    if output == "prior":
        obs = sym.with_gains({**t.gains, "T": t.sample_time_s})
    else:  # the posterior of predictor gains is the filter-form observer with L = F^-1 K
        L = linear.gain_pair(t.F, t.K[0], t.gain_form)[1]
        base = sym.subs(T=T)
        obs = base.with_gain_matrix(L, "filter")
    _same_response(numeric, _symbolic_bands(obs), t.sample_time_s)
    assert linear.identity_residual(numeric) < 1e-12


def test_continuous_bands_match_the_symbolic_engine():
    t = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("ckf3")))
    numeric, den = band_polynomials(t)
    obs = cfdesign.ckf3().with_gain_matrix(t.K[0])
    _same_response(numeric, _symbolic_bands(obs), None)
    assert np.allclose(np.sort_complex(np.roots(den)), np.sort_complex(np.array(obs.poles(), dtype=complex)))


@pytest.mark.parametrize("chain", [1, 2, 3])
def test_chain_relations_match_the_zoh_derivation(chain):
    dt = 0.05
    rel = linear.chain_relations(range(chain + 1), "z", dt)
    zs = np.exp(1j * np.linspace(0.1, 3.0, 7))
    for order in range(chain + 1):
        ref = sp.lambdify(z, discrete_relation(order, chain, sp.Rational(1, 20)), "numpy")(zs)
        got = np.polyval(rel[order][0], zs) / np.polyval(rel[order][1], zs)
        assert np.allclose(got, ref * np.ones_like(zs), rtol=1e-10)


def test_chain_relations_compute_only_the_orders_asked(monkeypatch):
    """An n-chain's relations cost one adjugate row (O(n^3)) per sensor order, not one per order of
    the chain: an input of order 500 and an angle reading took 1000 rows per verify (109 s)."""
    rows = []
    real = linear.output_adjugate
    monkeypatch.setattr(linear, "output_adjugate", lambda A, c, den=None: rows.append(1) or real(A, c, den))
    rel = linear.chain_relations({0, 2, 40}, "z", 0.01)
    assert len(rows) == 2  # orders 0 and 2; order 40's numerator is the characteristic polynomial
    full = {d: real(*linear.zoh_chain(40, 0.01)[:1], np.eye(40)[d]) @ linear.zoh_chain(40, 0.01)[1] for d in (0, 2)}
    assert np.array_equal(rel[2][0], full[2]) and np.array_equal(rel[2][1], full[0])


def test_output_adjugate_is_a_row_of_the_adjugate():
    rng = np.random.default_rng(5)
    A, c = rng.normal(size=(5, 5)), rng.normal(size=5)
    v = sp.Symbol("v")
    adj = (v * sp.eye(5) - sp.Matrix(A)).adjugate()
    full = linear.adjugate_coefficients(A)
    W = linear.output_adjugate(A, c)
    for k in range(5):
        coeff = np.array([[float(sp.Poly(adj[i, j], v).coeff_monomial(v ** (4 - k))) for j in range(5)]
                          for i in range(5)])
        assert np.allclose(full[k], coeff, atol=1e-9) and np.allclose(W[k], c @ coeff, atol=1e-9)


def test_an_observer_with_a_wrong_relation_is_not_complementary(dckf3_table):
    """The identity check can fail: a B that is not the model's ZOH breaks it."""
    t = dckf3_table
    real = linear.realisation(t.F, t.B / 2, t.H, t.K[0], t.gain_form)
    rel = linear.chain_relations({0, 1}, "z", t.sample_time_s)
    bands, _ = linear.band_polynomials(real, t.sensors, rel)
    assert linear.identity_residual(bands) > 1e-3
    # and the symbolic engine agrees that it is not
    d = cfdesign.dckf3()
    assert not Observer(d.F, d.B / 2, d.H, d.K, d.sensors, domain="z").proof().holds


def test_characteristic_polynomial_keeps_the_coefficients_of_stiff_matrices():
    """The closed loop of a continuous CF3 crossing over at 0.05 and 9000 Hz (poles at -5.7e4 and
    -0.31 rad/s): from the eigenvalues its constant coefficient came out 17765.28792181, off by
    8e-12 relative (the small eigenvalue carries the large one's absolute error), and the bands
    failed the identity check."""
    from cfdesign.linear import characteristic_polynomial

    k1, k2 = 56548.66776461628, 17765.287921960844
    assert characteristic_polynomial([[0.0, 1.0], [-k2, -k1]]).tolist() == [1.0, k1, k2]
    # a 3 x 3 that needs the Hessenberg reduction: its coefficients to rounding
    np.testing.assert_allclose(characteristic_polynomial([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-3.0, -k2, -k1]]),
                               [1.0, k1, k2, 3.0], rtol=1e-14)
    rng = np.random.default_rng(1)
    for n in (0, 1, 4, 12):
        B = rng.standard_normal((n, n))
        np.testing.assert_allclose(characteristic_polynomial(B), np.poly(B).real if n else [1.0], atol=1e-12)
