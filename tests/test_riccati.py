"""Tests of cfdesign.riccati: CARE / DARE on the CAREX/DAREX benchmark set, high-precision
references (mpmath), data validation and the Kalman estimator helpers.

The benchmark cases (Abels & Benner's CAREX and DAREX collections plus the cases of scipy's
and python-control's test suites) are read from tests/fixtures/riccati_cases.{npz,json},
written by tests/fixtures/riccati_make_cases.py."""

from __future__ import annotations

import dataclasses
import json
import warnings
from fractions import Fraction
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest
import scipy.linalg as sla

from cfdesign.errors import (
    CfdesignError,
    NoStabilisingSolutionError,
    NotDetectableError,
    NotStabilisableError,
    RiccatiError,
)
from cfdesign.riccati import care, dare, kalman_continuous, kalman_discrete
from cfdesign.riccati.extended import dd_dot
from cfdesign.riccati.lyapunov import ClosedLoop
from cfdesign.riccati.problem import Problem
from cfdesign.riccati.refinement import evaluate, update

FIXTURES = Path(__file__).resolve().parent / "fixtures"


def load_cases():
    """The benchmark cases as dicts: name, kind, expect, source, A, B, Q, R, S, E, X_ref (None if absent)."""
    meta = json.loads((FIXTURES / "riccati_cases.json").read_text())
    with np.load(FIXTURES / "riccati_cases.npz") as data:
        arrays = {key: data[key] for key in data.files}
    fields = ("A", "B", "Q", "R", "S", "E", "X_ref")
    return [{**record, **{key: arrays.get(f"{record['name']}/{key}") for key in fields}} for record in meta["cases"]]


CASES = {c["name"]: c for c in load_cases()}


def _case(name):
    return CASES[name]


def _args(c):
    return c["A"], c["B"], c["Q"], c["R"], c["S"], c["E"]


def _rel(X, ref):
    return float(np.linalg.norm(X - ref) / np.linalg.norm(ref))


def _defaults(c):
    n, m = c["B"].shape
    E = np.eye(n) if c["E"] is None else c["E"]
    S = np.zeros((n, m)) if c["S"] is None else c["S"]
    return E, S


def gain(c, X):
    """The gain of the case at X: R^-1 (B'XE + S') (CARE) or (R + B'XB)^-1 (B'XA + S') (DARE)."""
    A, B, R = c["A"], c["B"], c["R"]
    E, S = _defaults(c)
    if c["kind"] == "care":
        return np.linalg.solve(R, B.conj().T @ X @ E + S.conj().T)
    return np.linalg.solve(R + B.conj().T @ X @ B, B.conj().T @ X @ A + S.conj().T)


def residual(c, X):
    """Riccati residual of the case at X in plain double precision."""
    A, B, Q, R = c["A"], c["B"], c["Q"], c["R"]
    E, S = _defaults(c)
    if c["kind"] == "care":
        L = E.conj().T @ X @ B + S
        return A.conj().T @ X @ E + E.conj().T @ X @ A - L @ np.linalg.solve(R, L.conj().T) + Q
    L = A.conj().T @ X @ B + S
    return A.conj().T @ X @ A - E.conj().T @ X @ E - L @ np.linalg.solve(R + B.conj().T @ X @ B, L.conj().T) + Q


def _relres(c, X):
    """Relative residual in plain double precision (scale: roughly the size of the terms)."""
    res = residual(c, X)
    A, E = c["A"], _defaults(c)[0]
    lin = 2 * np.linalg.norm(A.conj().T @ X @ E) if c["kind"] == "care" else (
        np.linalg.norm(A.conj().T @ X @ A) + np.linalg.norm(E.conj().T @ X @ E))
    return float(np.linalg.norm(res) / (lin + np.linalg.norm(c["Q"]) + np.linalg.norm(res - c["Q"])))


def _stable(c, X):
    lam = sla.eigvals(c["A"] - c["B"] @ gain(c, X), _defaults(c)[0])
    return bool(np.all(lam.real < 0) if c["kind"] == "care" else np.all(np.abs(lam) < 1))


# ---------------------------------------------------------------------------------------
# high-precision references
# ---------------------------------------------------------------------------------------
def mp_newton(kind, A, B, Q, R, X0, S=None, E=None, iters=8, dps=50):
    """Newton (Kleinman / Hewer) in mpmath from X0 on the exact float data.

    Each step solves, through its Kronecker form, Ac'X E + E'X Ac + W = 0 (CARE) or
    Ac'X Ac - E'X E + W = 0 (DARE) with W = Q - S K - K'S' + K'R K and Ac = A - B K.
    """
    n, m = np.shape(B)
    S = np.zeros((n, m)) if S is None else S
    E = np.eye(n) if E is None else E
    with mp.workdps(dps):
        A, B, Q, R, S, E, X = (mp.matrix(np.asarray(M).tolist()) for M in (A, B, Q, R, S, E, X0))
        for _ in range(iters):
            if kind == "care":
                K = mp.inverse(R) * (B.H * X * E + S.H)
            else:
                K = mp.inverse(R + B.H * X * B) * (B.H * X * A + S.H)
            Ac = A - B * K
            W = Q - S * K - K.H * S.H + K.H * R * K
            L, R2 = (Ac, E) if kind == "care" else (Ac, Ac)
            M, v = mp.matrix(n * n, n * n), mp.matrix(n * n, 1)
            for i in range(n):
                for j in range(n):
                    v[i * n + j] = -W[i, j]
                    for k in range(n):
                        for col in range(n):
                            first = mp.conj(L[k, i]) * R2[col, j]
                            second = mp.conj(E[k, i]) * (Ac[col, j] if kind == "care" else -E[col, j])
                            M[i * n + j, k * n + col] = first + second
            x = mp.lu_solve(M, v)
            X = mp.matrix([[x[i * n + j] for j in range(n)] for i in range(n)])
        return np.array(X.tolist(), dtype=complex if np.iscomplexobj(X0) else float)


def butterworth_chain_solution(n, dps=50):
    """Exact CARE solution of CAREX 4.1 (integrator chain, Q = e1 e1', R = 1).

    The optimal closed loop has the Butterworth polynomial of order n as characteristic
    polynomial, so the last column of X is its coefficient vector; A'X + XA - kk' + Q = 0
    with A the shift then gives X row by row.
    """
    with mp.workdps(dps):
        g = mp.pi / (2 * n)
        coef = [mp.mpf(1)]
        for j in range(1, n):
            coef.append(coef[-1] * mp.cos((j - 1) * g) / mp.sin(j * g))
        X = mp.matrix(n, n)
        for i in range(n):
            X[i, n - 1] = coef[i]
            for j in range(1, n):
                X[i, j - 1] = coef[i] * coef[j] - (X[i - 1, j] if i else 0)
        return np.array(X.tolist(), dtype=float)


# ---------------------------------------------------------------------------------------
# the benchmark set
# ---------------------------------------------------------------------------------------
def reference(c, X0):
    """X_ref; else the closed form (CAREX 4.1); else a 50-digit Newton solution from X0 (n <= 6).

    Kleinman's / Hewer's Newton iteration converges to the stabilising solution from any
    stabilising starting gain, so X0 (scipy's solution) only needs to be stabilising.
    """
    if c["X_ref"] is not None:
        return c["X_ref"], "X_ref"
    if c["name"] == "carex_4_1":
        return butterworth_chain_solution(c["A"].shape[0]), "closed form"
    if c["A"].shape[0] <= 6:
        return mp_newton(c["kind"], c["A"], c["B"], c["Q"], c["R"], X0, c["S"], c["E"], iters=8), "mpmath"
    return None, "none"


def scipy_solution(c):
    solver = sla.solve_continuous_are if c["kind"] == "care" else sla.solve_discrete_are
    try:
        return solver(c["A"], c["B"], c["Q"], c["R"], e=c["E"], s=c["S"])
    except (np.linalg.LinAlgError, ValueError):
        return None


@pytest.mark.parametrize("name", list(CASES))
def test_benchmark_case(name):
    c = _case(name)
    solve = care if c["kind"] == "care" else dare
    if c["expect"] == "no_stabilizing_solution":
        with pytest.raises(CfdesignError, match="stabilising"):
            solve(*_args(c))
        return
    if c["expect"] == "marginal":
        try:
            with pytest.warns(RuntimeWarning, match="marginal"):
                sol = solve(*_args(c))
        except CfdesignError as exc:
            assert "marginal" in str(exc)
            return
        assert sol.marginal and any("marginal" in w for w in sol.warnings)
        return
    sol = solve(*_args(c))
    assert not sol.marginal and sol.stability_margin > 0 and sol.relative_residual <= 1e-13
    assert _stable(c, sol.X)
    assert np.allclose(sol.X, sol.X.conj().T, rtol=0, atol=1e-14 * np.abs(sol.X).max())
    X_scipy = scipy_solution(c)
    ref, _ = reference(c, X_scipy if X_scipy is not None else sol.X)
    if ref is None:  # n > 6 without a published solution: residual at least as small as scipy's
        assert _relres(c, sol.X) <= max(1e-13, 10 * _relres(c, X_scipy) if X_scipy is not None else 0)
        return
    err = _rel(sol.X, ref)
    assert err <= 1e-10, err
    if X_scipy is not None:  # never less accurate than scipy (up to rounding)
        assert err <= max(_rel(X_scipy, ref), 1e-14), (err, _rel(X_scipy, ref))


def test_carex_2_8_against_mpmath():
    """Closed-loop margin 5e-13 (poor separation of the closed-loop spectrum): X to 1e-10."""
    c = _case("carex_2_8")
    sol = care(*_args(c))
    X_scipy = sla.solve_continuous_are(c["A"], c["B"], c["Q"], c["R"])
    ref = mp_newton("care", c["A"], c["B"], c["Q"], c["R"], X_scipy)  # scipy's X only starts the iteration
    assert _rel(sol.X, ref) <= 1e-10
    assert not sol.marginal and 4e-13 < sol.stability_margin < 6e-13


def test_carex_4_1_against_closed_form():
    """Integrator chain, X entries from 1 to 1e20."""
    c = _case("carex_4_1")
    ref = butterworth_chain_solution(c["A"].shape[0])
    sol = care(*_args(c))
    assert _rel(sol.X, ref) <= 1e-10


def test_butterworth_reference_solves_care():
    n = 6
    X = butterworth_chain_solution(n)
    A, B = np.eye(n, k=1), np.eye(n)[:, -1:]
    Q = np.zeros((n, n))
    Q[0, 0] = 1
    res = A.T @ X + X @ A - X @ B @ B.T @ X + Q
    assert np.linalg.norm(res) <= 1e-12 * np.linalg.norm(X) ** 2
    assert _rel(care(A, B, Q, 1).X, X) <= 1e-13


# ---------------------------------------------------------------------------------------
# fast sampling: the discrete double-integrator estimator at Ts = 1e-4
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(("q", "r"), [(1e-6, 1e-2), (1e-6, 100.0), (1e-9, 1.0)])
def test_fast_sampling_dare_against_mpmath(q, r):
    T = 1e-4
    A = np.array([[1.0, T], [0.0, 1.0]])
    C = np.array([[1.0, 0.0]])
    Q = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    R = np.array([[r]])
    sol = dare(A.T, C.T, Q, R)
    X_scipy = sla.solve_discrete_are(A.T, C.T, Q, R)
    ref = mp_newton("dare", A.T, C.T, Q, R, X_scipy, iters=6)
    err, err_scipy = _rel(sol.X, ref), _rel(X_scipy, ref)
    assert err <= 1e-12
    assert err <= max(err_scipy, 1e-14)
    assert sol.forward_error <= 1e-12 and 0 < sol.stability_margin < 1e-2


# ---------------------------------------------------------------------------------------
# results and gains
# ---------------------------------------------------------------------------------------
def test_gain_and_closed_loop_match_their_definitions():
    rng = np.random.default_rng(1)
    A, B, S = rng.normal(size=(4, 4)), rng.normal(size=(4, 2)), 0.1 * rng.normal(size=(4, 2))
    E = np.eye(4) + 0.1 * rng.normal(size=(4, 4))
    Q, R = np.eye(4), np.diag([1.0, 2.0])
    sc = care(A, B, Q, R, S, E)
    assert np.allclose(sc.K, np.linalg.solve(R, B.T @ sc.X @ E + S.T), rtol=1e-12, atol=1e-12)
    assert np.allclose(np.sort_complex(sc.closed_loop_eigenvalues),
                       np.sort_complex(sla.eigvals(A - B @ sc.K, E)), atol=1e-10)
    sd = dare(A / 3, B, Q, R, S, E)
    assert np.allclose(sd.K, np.linalg.solve(R + B.T @ sd.X @ B, B.T @ sd.X @ A / 3 + S.T), rtol=1e-12, atol=1e-12)
    assert sd.kind == "dare" and sc.kind == "care" and sd.method == "schur"
    assert sd.condition > 1 and sd.forward_error < 1e-14 and sd.warnings == ()


def test_result_is_frozen_and_read_only():
    sol = care([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], np.eye(2), 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.X = None
    with pytest.raises(ValueError):
        sol.X[0, 0] = 1.0
    assert np.allclose(sol.X, [[np.sqrt(3), 1], [1, np.sqrt(3)]])


def test_complex_hermitian_solution():
    A = np.array([[1j, 1.0], [0.0, -1.0]])
    B = np.array([[0.0], [1.0]])
    sol = care(A, B, np.eye(2), 1)
    res = A.conj().T @ sol.X + sol.X @ A - sol.X @ B @ B.T @ sol.X + np.eye(2)
    assert np.linalg.norm(res) <= 1e-13 * np.linalg.norm(sol.X)
    assert np.array_equal(sol.X, sol.X.conj().T)
    assert np.all(sol.closed_loop_eigenvalues.real < 0)


def _scaled_similarity(n=4, seed=0):
    """A random CARE under the diagonal similarity diag(1e-4 .. 1e4): X has entries from 1e-8 to 1e8."""
    rng = np.random.default_rng(seed)
    d = np.logspace(-4, 4, n)
    A = rng.standard_normal((n, n)) / np.sqrt(n) * d[:, None] / d[None, :]
    return A, d[:, None] * rng.standard_normal((n, 2)), np.diag(1 / d**2), np.eye(2), None, None


_COMPLEX_E_S = (np.array([[0.3 + 0.5j, 1], [0.2j, -0.4]]), np.array([[1.0], [1j]]), np.eye(2), np.array([[2.0]]),
                np.array([[0.1j], [0.2]]), np.array([[1.0, 0.2j], [0.0, 2.0]]))


@pytest.mark.parametrize(("kind", "args"), [("dare", _COMPLEX_E_S), ("care", _COMPLEX_E_S),
                                            ("care", _scaled_similarity()), ("dare", _scaled_similarity(seed=1))])
def test_last_small_correction_is_applied(kind, args):
    """A Newton correction of one to four units in the last place was computed and dropped, so X
    stayed scipy's (the badly scaled CARE: entries of 1e-8 wrong from the 13th digit) or
    came out less accurate than scipy's (the complex DARE with E and S: 2.7 eps normwise, scipy
    1.6 eps; its residual in long double 3.3e-16 against scipy's 2.2e-16).  Applied, X is the
    exact solution rounded, entry by entry."""
    sol = (care if kind == "care" else dare)(*args)
    A, B, Q, R, S, E = args
    ref = mp_newton(kind, A, B, Q, R, sol.X, S, E, iters=2, dps=60)
    assert np.max(np.abs(sol.X - ref) / np.abs(ref)) <= 2 * np.finfo(float).eps
    assert sol.forward_error <= 4 * np.finfo(float).eps and sol.relative_residual <= 1e-16


def test_fallbacks_when_scipy_fails(monkeypatch):
    """Matrix sign function (CARE) and doubling (DARE) take over when scipy raises."""
    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("disabled for the test")

    monkeypatch.setattr(sla, "solve_continuous_are", broken)
    monkeypatch.setattr(sla, "solve_discrete_are", broken)
    A, B = np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([[0.0], [1.0]])
    sc = care(A, B, np.eye(2), 1)
    sd = dare(A, B, np.eye(2), 1)
    assert (sc.method, sd.method) == ("sign", "doubling")
    assert sc.relative_residual < 1e-14 and sd.relative_residual < 1e-14
    assert sc.stability_margin > 0 and sd.stability_margin > 0


# ---------------------------------------------------------------------------------------
# the building blocks: double-double products, residual updates, the closed-loop solves
# ---------------------------------------------------------------------------------------
def _exact_product(a, b):
    A = [[Fraction(x) for x in row] for row in a]
    B = [[Fraction(x) for x in row] for row in b]
    return [[sum(A[i][k] * B[k][j] for k in range(a.shape[1])) for j in range(b.shape[1])] for i in range(a.shape[0])]


@pytest.mark.parametrize("grading", [0.0, 2.0, 6.0])
def test_double_double_product_against_exact_rationals(grading):
    """The split BLAS product is accurate to far below u^2 of the row and column maxima, graded data included."""
    rng = np.random.default_rng(7)
    a = rng.normal(size=(4, 9)) * np.exp(grading * rng.normal(size=(4, 9)))
    b = rng.normal(size=(9, 3)) * np.exp(grading * rng.normal(size=(9, 3)))
    hi, lo = dd_dot(a, b)
    exact = _exact_product(a, b)
    scale = np.abs(a).max(axis=1)[:, None] * np.abs(b).max(axis=0)[None, :]
    err = max(float(abs(Fraction(hi[i, j]) + Fraction(lo[i, j]) - exact[i][j]) / Fraction(scale[i, j]))
              for i in range(4) for j in range(3))
    assert err <= 1e-30
    assert np.array_equal(hi, a @ b) or np.max(np.abs(hi - a @ b) / scale) <= 1e-15


@pytest.mark.parametrize("kind", ["care", "dare"])
@pytest.mark.parametrize("with_e", [False, True])
def test_residual_update_matches_a_fresh_evaluation(kind, with_e):
    """After a small step the residual and gain are updated in double precision; they must agree
    with a full double-double evaluation at the new point (descriptor E and cross term S included)."""
    rng = np.random.default_rng(3)
    n, m = 5, 2
    A, B = rng.normal(size=(n, n)) / (2 if kind == "care" else 3), rng.normal(size=(n, m))
    S = 0.1 * rng.normal(size=(n, m))
    E = np.eye(n) + 0.1 * rng.normal(size=(n, n)) if with_e else None
    p = Problem(kind, A, B, np.eye(n), np.diag([1.0, 2.0]), S, E)
    X = (care if kind == "care" else dare)(A, B, np.eye(n), np.diag([1.0, 2.0]), S, E).X
    D = rng.normal(size=(n, n))
    Xn = X + 1e-9 * np.abs(X).max() * (D + D.T)
    ev = evaluate(p, X)
    up, fresh = update(p, X, ev, Xn), evaluate(p, Xn)
    # errs by about u * (step size) relative to the terms: 1e-6 of what a double evaluation would
    assert np.linalg.norm(up.res - fresh.res) <= 1e-22 * fresh.theta
    assert np.abs(up.K - fresh.K).max() <= 4 * np.finfo(float).eps * np.abs(fresh.K).max()  # both rounded


@pytest.mark.parametrize("kind", ["care", "dare"])
def test_closed_loop_solves_the_linearised_equation(kind):
    """ClosedLoop (balanced real Schur form + triangular Sylvester solve) against the Kronecker form."""
    rng = np.random.default_rng(5)
    n = 6
    A = rng.normal(size=(n, n)) * np.logspace(0, 3, n)[None, :] / np.logspace(0, 3, n)[:, None]  # badly scaled
    B, E = rng.normal(size=(n, 2)), np.eye(n) + 0.2 * rng.normal(size=(n, n))
    p = Problem(kind, A / (1 if kind == "care" else 3 * np.abs(A).max()), B, np.eye(n), np.eye(2), np.zeros((n, 2)), E)
    K = (care if kind == "care" else dare)(p.A, p.B, p.Q, p.R, None, p.E).K
    cl = ClosedLoop(p, K)
    W = rng.normal(size=(n, n))
    W = W + W.T
    D = cl.correction(W)
    Ac = p.A - p.B @ K
    if kind == "care":
        op = np.kron(Ac.T, E.T) + np.kron(E.T, Ac.T)  # vec(E' D Ac) + vec(Ac' D E), row-major
    else:
        op = np.kron(Ac.T, Ac.T) - np.kron(E.T, E.T)
    ref = np.linalg.solve(op, -W.ravel()).reshape(n, n)
    assert np.allclose(D, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    lam = sla.eigvals(Ac, E)
    assert np.allclose(np.sort_complex(cl.eigenvalues), np.sort_complex(lam), rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------------------------------
# data errors
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"Q": np.eye(2)}, r"Q must be 3x3 \(got 2x2\)"),
        ({"Q": np.ones((2, 3))}, r"Q must be 3x3 \(got 2x3\)"),
        ({"B": np.ones((2, 1))}, r"B must be 3x1 \(got 2x1\)"),
        ({"R": np.eye(2)}, r"R must be 1x1 \(got 2x2\)"),
        ({"S": np.ones((3, 2))}, r"S must be 3x1 \(got 3x2\)"),
        ({"E": np.eye(2)}, r"E must be 3x3 \(got 2x2\)"),
        ({"A": np.ones((3, 2))}, r"A must be 3x3 \(got 3x2\)"),
        ({"A": np.diag([np.nan, -1.0, -2.0])}, "A contains NaN or Inf"),
        ({"Q": np.array([[1, 0.5, 0], [0, 1, 0], [0, 0, 1.0]])}, "Q must be symmetric"),
        ({"R": [[0.0]]}, "R must be nonsingular"),
        ({"E": np.diag([1.0, 1.0, 0.0])}, "E must be nonsingular"),
    ],
)
def test_invalid_data_is_named(kwargs, message):
    data = {"A": -np.eye(3), "B": np.ones((3, 1)), "Q": np.eye(3), "R": [[1.0]], "S": None, "E": None}
    data.update(kwargs)
    with pytest.raises(RiccatiError, match=message):
        care(**data)


def test_unstabilisable_mode_is_named():
    A, B = np.diag([1.0, -2.0]), np.array([[0.0], [1.0]])
    with pytest.raises(NotStabilisableError, match=r"mode at s = 1\.0 is unstable and not reachable from B"):
        care(A, B, np.eye(2), 1)
    with pytest.raises(NotStabilisableError, match=r"mode at z = 1\.5 is unstable and not reachable from B"):
        dare(np.diag([1.5, 0.5]), B, np.eye(2), 1)
    with pytest.raises(NotStabilisableError, match="on the imaginary axis"):
        care([[0.0, 1.0], [-1.0, 0.0]], [[0.0], [0.0]], np.eye(2), 1)


def test_slightly_unstable_mode_is_not_called_a_boundary_mode():
    """s = 1e-10 and z = 1 + 1e-10 are unstable by far more than the PBH test's tolerance
    (4e-14); the message called them 'on the imaginary axis' / 'on the unit circle' (an absolute
    1e-9 decided it, and z printed as 1.0)."""
    B = np.array([[0.0], [1.0]])
    with pytest.raises(NotStabilisableError, match=r"mode at s = 1e-10 is unstable and"):
        care(np.diag([1e-10, -1.0]), B, np.eye(2), 1)
    with pytest.raises(NotStabilisableError, match=r"z = 1\.0 is unstable \(\|z\| - 1 = 1e-10\) and"):
        dare(np.diag([1 + 1e-10, 0.5]), B, np.eye(2), 1)


@pytest.mark.parametrize("coupled", [False, True])
def test_stiff_closed_loop_with_a_slow_stable_mode_is_certified(coupled):
    """A = diag(1e7, -2e-8): the slow mode is stable, so (A, B) is stabilisable whatever B does to
    it.  The closed loop's eigenvalue -2e-8 was compared with a normwise uncertainty
    10 eps ||A - BK|| = 2.2e-8, so the solution was 'marginal', and the PBH test, whose tolerance
    scales with the spectrum (4.4e-7), then called the mode 'on the imaginary axis and not
    reachable from B' (uncoupled) or the solution was returned flagged marginal (coupled), while
    scipy returns the exact X.  The eigenvalue's uncertainty is now also bounded a posteriori,
    from the residual of its eigenpair and the entrywise rounding of A - BK."""
    if coupled:
        A, B = np.array([[1e7, 1.0], [0.0, -2e-8]]), np.array([[1.0], [1e-9]])
    else:
        A, B = np.diag([1e7, -2e-8]), np.array([[1.0], [0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        sol = care(A, B, np.eye(2), 1)
    assert not sol.marginal and sol.stability_margin == pytest.approx(2e-8, rel=0.02)
    if not coupled:  # decoupled: x1 solves 2e7 x - x^2 + 1 = 0, x2 = 1 / 4e-8
        assert _rel(sol.X, np.diag([1e7 + np.sqrt(1e14 + 1), 2.5e7])) <= 1e-15
    assert _relres(_case_dict("care", A, B, np.eye(2), np.eye(1)), sol.X) <= 1e-15


def _case_dict(kind, A, B, Q, R):
    return {"kind": kind, "A": A, "B": B, "Q": Q, "R": R, "S": None, "E": None}


def test_nearly_unstabilisable_is_not_rejected():
    """B = [1e-8, 0]: stabilisable, only ill-conditioned (CAREX 2.1 with eps = 1e-8)."""
    sol = care(np.diag([1.0, -2.0]), [[1e-8], [0.0]], np.ones((2, 2)), 1)
    assert sol.stability_margin > 0.5


def test_large_eigenvalue_of_a_nearly_singular_e_is_not_called_unreachable():
    """E = diag(1, 1e-15), A = I/2: the pencil's mode at z = 5e14 is reachable from B = I, but the
    PBH test scaled B to ||A|| and compared it with ||A - lam E|| = 5e14, so dare() raised
    NotStabilisableError naming that mode 'not reachable from B'.  A B that misses it still must."""
    from cfdesign.riccati.validation import unreachable_mode

    A, E = 0.5 * np.eye(2), np.diag([1.0, 1e-15])
    assert unreachable_mode("dare", A, E, np.eye(2)) is None
    hit = unreachable_mode("dare", A, E, np.array([[1.0], [0.0]]))
    assert hit is not None and abs(hit[0]) == pytest.approx(5e14)
    try:
        dare(A, np.eye(2), np.eye(2), np.eye(2), None, E)
    except NotStabilisableError as exc:
        pytest.fail(f"misnamed: {exc}")
    except RiccatiError:
        pass  # refused as too ill-conditioned: a named error, and a true one


def test_unobservable_boundary_mode_is_named():
    with pytest.raises(NotDetectableError, match=r"mode at s = 0\.0 is on the imaginary axis and not observable"):
        care([[0.0]], [[1.0]], [[0.0]], [[1.0]])


def test_unobservable_unstable_mode_still_has_a_stabilising_solution():
    """A = 1, Q = 0: X = 2 stabilises (X = 0 does not); detectability is not required."""
    sol = care([[1.0]], [[1.0]], [[0.0]], [[1.0]])
    assert np.allclose(sol.X, 2.0) and np.allclose(sol.closed_loop_eigenvalues, -1.0)


def test_no_stabilising_solution_raises():
    """Indefinite Q with Hamiltonian eigenvalues on the axis and no stabilising solution."""
    A, B = np.array([[0.0, 1.0], [-1.0, 0.0]]), np.array([[0.0], [1.0]])
    with pytest.raises(NoStabilisingSolutionError, match="pencil has an eigenvalue on the stability boundary"):
        care(A, B, -10 * np.eye(2), 1)


def test_marginal_solution_is_flagged():
    """CAREX 2.5 (eps = 0): X = [[2, 1], [1, 1]] leaves closed-loop eigenvalues at +/- i."""
    A, B = np.array([[3.0, 1.0], [4.0, 2.0]]), np.ones((2, 1))
    Q = np.array([[-11.0, -5.0], [-5.0, -2.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = care(A, B, Q, 1)
    assert sol.marginal and abs(sol.stability_margin) < 1e-6
    assert np.allclose(sol.X, [[2.0, 1.0], [1.0, 1.0]], atol=1e-6)


# ---------------------------------------------------------------------------------------
# estimator helpers
# ---------------------------------------------------------------------------------------
def _dckf3():
    """DCKF^3 of Carreira et al. eqs. (25)-(28): angle + rate correction, compass and odometry."""
    T = 0.2
    F = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0], [1.0, 0.0]])
    return F, H, np.diag([1e-4, 1e-5]), np.diag([2e-3, 4e-3])


def test_kalman_discrete_names_both_gain_forms():
    F, H, Q, R = _dckf3()
    g = kalman_discrete(F, H, Q, R)
    P = g.P
    innov = H @ P @ H.T + R
    assert np.allclose(g.K_filter, P @ H.T @ np.linalg.inv(innov), rtol=1e-12)
    assert np.allclose(g.K_predictor, F @ g.K_filter, rtol=1e-12)
    assert np.allclose(g.P_filtered, (np.eye(2) - g.K_filter @ H) @ P, rtol=1e-12)
    rhs = F @ P @ F.T + Q - F @ P @ H.T @ np.linalg.solve(innov, H @ P @ F.T)
    assert np.linalg.norm(P - rhs) <= 1e-13 * np.linalg.norm(P)
    assert _rel(P, sla.solve_discrete_are(F.T, H.T, Q, R)) <= 1e-12
    assert np.all(np.abs(g.closed_loop_eigenvalues) < 1)
    assert np.allclose(np.sort_complex(g.closed_loop_eigenvalues),
                       np.sort_complex(np.linalg.eigvals(F - g.K_predictor @ H)))


def test_kalman_discrete_matches_the_filter_recursion():
    """Independent check: run the covariance recursion of the Kalman filter to steady state."""
    F, H, Q, R = _dckf3()
    g = kalman_discrete(F, H, Q, R)
    P = np.eye(2)
    for _ in range(3000):
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        P = F @ (P - K @ H @ P) @ F.T + Q
    assert _rel(P, g.P) <= 1e-10
    assert _rel(K, g.K_filter) <= 1e-9


def test_kalman_continuous():
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    H = np.array([[1.0, 0.0]])
    Q, R = np.diag([0.0, 1.0]), np.array([[1.0]])
    g = kalman_continuous(F, H, Q, R)
    P = g.P
    assert np.allclose(P, [[np.sqrt(2), 1.0], [1.0, np.sqrt(2)]], rtol=1e-14)
    assert np.allclose(g.K, P @ H.T @ np.linalg.inv(R), rtol=1e-14)
    res = F @ P + P @ F.T - P @ H.T @ np.linalg.solve(R, H @ P) + Q
    assert np.linalg.norm(res) <= 1e-14
    assert np.all(g.closed_loop_eigenvalues.real < 0)


def test_estimator_errors_speak_estimation():
    with pytest.raises(NotDetectableError, match=r"mode at z = 1\.2 is unstable and not observable from H"):
        kalman_discrete(np.diag([1.2, 0.5]), [[0.0, 1.0]], np.eye(2), 1)
    with pytest.raises(NotStabilisableError, match="not excited by the process noise Q"):
        kalman_discrete([[1.0, -0.01], [0.0, 1.0]], [[1.0, 0.0]], np.diag([1e-3, 0.0]), 1)
    with pytest.raises(RiccatiError, match=r"R .* must be positive definite"):
        kalman_discrete(np.eye(2) * 0.5, [[1.0, 0.0]], np.eye(2), [[0.0]])
    with pytest.raises(RiccatiError, match=r"Q .* must be positive semidefinite"):
        kalman_continuous(-np.eye(2), [[1.0, 0.0]], -np.eye(2), 1)


# ---------------------------------------------------------------------------------------
# near-singular input weight: the residual's scale
# ---------------------------------------------------------------------------------------
LD = np.longdouble


def _ld_reference(kind, A, B, Q, R, X0, steps=4):
    """Defect correction ``X <- X + Omega^-1(-Res(X))`` with ``Res`` and the gain in long double.

    Independent of cfdesign's double-double code: the residual of the (S = 0, E = I) equation
    is formed in 80-bit arithmetic, the gain by iterative refinement in it, and the correction
    by scipy's Lyapunov / Stein solver in double (it only needs a few correct digits).
    """
    A_, B_, Q_, R_ = (np.asarray(M, LD) for M in (A, B, Q, R))
    X = np.asarray(X0, LD)
    for _ in range(steps):
        W = R_ if kind == "care" else R_ + B_.T @ X @ B_
        Lt = B_.T @ X if kind == "care" else B_.T @ X @ A_
        K = np.linalg.solve(W.astype(float), Lt.astype(float)).astype(LD)
        for _ in range(3):
            K = K + np.linalg.solve(W.astype(float), (Lt - W @ K).astype(float)).astype(LD)
        lin = A_.T @ X + X @ A_ if kind == "care" else A_.T @ X @ A_ - X
        res = (lin - Lt.T @ K + Q_).astype(float)
        Ac = A - B @ K.astype(float)
        if kind == "care":
            D = sla.solve_continuous_lyapunov(Ac.T, -res)
        else:
            D = sla.solve_discrete_lyapunov(Ac.T, res)
        X = X + np.asarray(0.5 * (D + D.T), LD)
    return X.astype(float)


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="needs an 80-bit long double")
@pytest.mark.parametrize("kind", ["care", "dare"])
@pytest.mark.parametrize("seed", [0, 1])
def test_near_singular_input_weight_against_long_double(kind, seed):
    """R = diag(1, 1e-7, ..., 1e-12), n = 30.  The gain term X B R^-1 B' X is small only through
    cancellation (||B K|| ||X|| is 1e7 times ||X B K||), so the rounded exact solution has a residual
    of 2e-10 relative to the terms of the equation alone: the scale must include the size of the
    linearised operator, ||Omega|| ||X||, or an accurate solution is refused (it was, with
    AccuracyError, while scipy's answer is accurate to 1e-11).  The scale must still refuse an X
    that is wrong in the eighth digit."""
    rng = np.random.default_rng(seed)
    n, m = 30, 7
    A, B = rng.standard_normal((n, n)) / np.sqrt(n), rng.standard_normal((n, m))
    Q, R = np.eye(n), np.diag(np.r_[1.0, 10.0 ** -np.arange(7.0, 7 + m - 1)])
    solver = care if kind == "care" else dare
    sol = solver(A, B, Q, R)
    scipy_X = (sla.solve_continuous_are if kind == "care" else sla.solve_discrete_are)(A, B, Q, R)
    X_ref = _ld_reference(kind, A, B, Q, R, scipy_X)
    assert _rel(sol.X, X_ref) <= 1e-14 and sol.relative_residual <= 1e-15
    p = Problem(kind, A, B, Q, R, np.zeros((n, m)), None)
    ev = evaluate(p, X_ref)
    assert np.linalg.norm(ev.res) / ev.theta <= 1e-15  # the rounded exact solution passes
    E = rng.standard_normal((n, n))
    X_bad = X_ref * (1 + 1e-8 * (E + E.T))
    ev = evaluate(p, X_bad)
    assert np.linalg.norm(ev.res) / ev.theta > 1e-10  # an X wrong in the eighth digit does not


def test_marginal_warning_names_the_uncertainty_that_decided():
    """The warning prints the eigenvalue uncertainty the verdict compared the margin with (not
    the closed-loop matrix's, which reads as a certified stable loop): CAREX 2.5 at eps = 0,
    closed-loop eigenvalues on the axis."""
    import re

    A, B = np.array([[3.0, 1.0], [4.0, 2.0]]), np.ones((2, 1))
    Q = np.array([[-11.0, -5.0], [-5.0, -2.0]])
    with pytest.warns(RuntimeWarning, match="marginal solution") as record:
        care(A, B, Q, 1)
    text = next(str(w.message) for w in record if "marginal" in str(w.message))
    margin, unc = map(float, re.search(r"eigenvalue margin (\S+), its uncertainty (\S+)\)", text).groups())
    assert abs(margin) <= unc


def test_stable_loop_with_an_ill_conditioned_eigenvalue_is_certified():
    """An n = 30 kinematic chain at 100 Hz (margin 5.6e-4) and CAREX 4.1 at n = 30 (an integrator
    chain, Butterworth closed loop, margin sin(pi/60) = 0.0523, gain entries up to 5e6).  The
    eigenvalue uncertainty was taken from the unbalanced closed loop (0.225 for CAREX 4.1, above
    its margin), so both were flagged marginal with a warning that X is not stabilising, while
    the returned gains' loops are stable with exactly those margins (80-digit eigenvalues; here
    the roots of the companion polynomial in 40 digits).  The eigensolver balances first; the
    uncertainty must be that of the balanced loop."""
    from cfdesign.linear import zoh_chain

    n = 30
    F, b = zoh_chain(n, 0.01)
    H = np.eye(n)[:1]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        est = kalman_discrete(F, H, np.outer(b, b), np.array([[1e-2]]))
    rho = np.abs(sla.eigvals(F - est.K_predictor @ H)).max()
    assert not est.solution.marginal
    # (its eigenvalues are those of the gain before a last polishing Newton step: 2e-6 apart here)
    assert abs(est.solution.stability_margin - (1 - rho)) <= 1e-5 * (1 - rho)

    A, B = np.eye(n, k=1), np.eye(n)[:, -1:]
    Q = np.zeros((n, n))
    Q[0, 0] = 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        sol = care(A, B, Q, 1)
    with mp.workdps(40):  # A - BK is the companion matrix of s^n + K[n-1] s^(n-1) + ... + K[0]
        roots = mp.polyroots([1.0, *sol.K[0, ::-1]], maxsteps=200, extraprec=200)
        exact_margin = float(-max(mp.re(r) for r in roots))
    assert not sol.marginal and abs(sol.stability_margin - exact_margin) <= 1e-8 * exact_margin
    assert _rel(sol.X, butterworth_chain_solution(n)) <= 1e-14


@pytest.mark.parametrize("dt", [0.01, 1.0])
def test_n50_chain_is_refused_as_too_ill_conditioned(dt):
    """An n = 50 kinematic chain (ZOH, position measured, noise on the 50th derivative).  In
    exact arithmetic (an 80-digit doubling solution) the Kalman gain rounded to double is
    stabilising (spectral radius 0.9692 at dt = 1, 0.99969 at dt = 0.01), but one-ulp changes
    of the gain move the spectral radius by 3e-3, and the covariance, even after the ideal
    diagonal scaling, has condition 2e19: Newton's correction stays at half of X from every
    estimate.  scipy gives up too; the error must say why instead of 'not stabilising'."""
    from cfdesign.errors import AccuracyError
    from cfdesign.linear import zoh_chain

    n = 50
    F, b = zoh_chain(n, dt)
    H, Q, R = np.eye(n)[:1], np.outer(b, b), np.eye(1)
    with pytest.raises((np.linalg.LinAlgError, ValueError)):
        sla.solve_discrete_are(F.T, H.T, Q, R)
    with pytest.raises(AccuracyError, match="too ill-conditioned for double precision"):
        kalman_discrete(F, H, Q, R)
