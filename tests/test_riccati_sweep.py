"""care / dare / periodic_dare over problem classes: a representative subset of the sweep.

The full sweep (every parametric CAREX / DAREX example over its range, random problems of
n = 1..12, random periodic schedules) is ``python benchmarks/bench_riccati_sweep.py``; these
cases are the hardest of each class it found, with their own generators
(tests/riccati_sweep_cases.py, after Abels and Benner's CAREX / DAREX collections) and an
independent 50-digit reference (the stable deflating subspace of the extended pencil), so
they need nothing from shared/.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import riccati_sweep_cases as rc
import scipy.linalg as sla

from cfdesign.errors import AccuracyError, NoStabilisingSolutionError, NotDetectableError
from cfdesign.riccati import care, dare, periodic_dare


def _rel(X, ref):
    return np.linalg.norm(X - ref) / np.linalg.norm(ref)


def _stabilising(kind, A, B, K):
    lam = np.linalg.eigvals(A - B @ K)
    return bool(np.all(lam.real < 0) if kind == "care" else np.all(np.abs(lam) < 1))


@pytest.mark.parametrize(("kind", "make", "param"), [
    ("care", rc.carex_2_1, 1e-12), ("care", rc.carex_2_1, 1e12),  # scipy: 4.8e-5, 2.9e-6
    ("care", rc.carex_2_3, 1e-12), ("care", rc.carex_2_3, 1e12),  # condition 3e12, 7e17
    ("dare", rc.darex_2_1, 1e-12), ("dare", rc.darex_2_1, 1e12),  # scipy at 1e12: 9.2e-4
    ("dare", rc.darex_2_3, 0.0), ("dare", rc.darex_2_3, 1e12),  # condition 1e48 at 1e12
    ("dare", rc.darex_2_5, 1e12),  # scipy: 0.62
    ("dare", lambda r: rc.darex_4_1(100, r), 1e-12),
])
def test_collection_extremes_against_closed_form(kind, make, param):
    A, B, Q, R, X = make(param)
    sol = (care if kind == "care" else dare)(A, B, Q, R)
    assert _rel(sol.X, X) <= 1e-10
    assert not sol.marginal and _stabilising(kind, A, B, sol.K)


def test_carex_2_8_against_the_pencil_reference():
    """A closed loop 5e-13 from the axis (scipy's X is wrong by 4.7e-4)."""
    A, B, Q, R, _ = rc.carex_2_8(1e-6)
    ref, boundary = rc.pencil_reference("care", A, B, Q, R)
    assert ref is not None and boundary > 1e-14
    sol = care(A, B, Q, R)
    assert _rel(sol.X, ref) <= 1e-10 and not sol.marginal


@pytest.mark.parametrize("eps", [1e-13, 1e-12, 1e-9, 3e-9, 1e-7])
def test_carex_2_5_follows_the_float_data(eps):
    """Hamiltonian eigenvalues +-eps +- i: rounding the data moves them by up to ~5e-8, onto the axis for
    some eps (1e-12, 1e-9) and off it for others (1e-13: 1.05e-8).  The solver must follow the float data:
    stable with the reference's margin where the pencil is off the axis, marginal (warned) where it is on."""
    A, B, Q, R, _ = rc.carex_2_5(eps)
    ref, boundary = rc.pencil_reference("care", A, B, Q, R)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol = care(A, B, Q, R)
    if ref is None:  # no stabilising solution of the float data
        assert sol.marginal and any("marginal" in str(w.message) for w in caught)
    else:
        assert not sol.marginal
        assert sol.stability_margin == pytest.approx(boundary, rel=1e-3)
        assert _rel(sol.X, ref) <= max(1e-10, 10 * sol.condition * np.finfo(float).eps)


def test_carex_2_6_small_eps_is_refused_as_the_float_data_have_no_solution():
    """Formed in double, Q is indefinite for eps = 1e-12: the pencil has eigenvalues on the axis."""
    A, B, Q, R, _ = rc.carex_2_6(1e-12)
    ref, boundary = rc.pencil_reference("care", A, B, Q, R)
    assert ref is None and boundary < 1e-20
    with pytest.raises(NoStabilisingSolutionError, match=r"stability boundary"):
        care(A, B, Q, R)
    A, B, Q, R, _ = rc.carex_2_6(1e-6)  # solvable (Q still positive definite)
    assert _rel(care(A, B, Q, R).X, rc.pencil_reference("care", A, B, Q, R)[0]) <= 1e-10


def test_a_large_eigenvalue_off_the_axis_is_not_named_on_the_boundary():
    """CAREX 2.6 at eps = 1e-11 has a stabilising solution (the pencil reference finds it; closed-loop
    eigenvalues from -1e11 to -582).  The boundary check had named the real eigenvalue s = 612 "on the
    stability boundary" (its tolerance, sqrt(eps) times the pencil's norm of 1e12, was 1.5e4): now the
    distance is also measured against the eigenvalue's size.  scipy refuses the data after balancing its
    pencil ("eigenvalues too close to the imaginary axis") and the sign function does not converge; scipy
    without balancing is 2e-9 from the solution, and Newton's method takes it to the reference."""
    A, B, Q, R, _ = rc.carex_2_6(1e-11)
    ref = rc.pencil_reference("care", A, B, Q, R)[0]
    assert ref is not None
    with pytest.raises(np.linalg.LinAlgError):
        sla.solve_continuous_are(A, B, Q, R)  # balanced, as the first estimate
    sol = care(A, B, Q, R)
    assert sol.method == "schur-unbalanced" and not sol.marginal
    assert _rel(sol.X, ref) <= max(1e-10, 10 * sol.condition * np.finfo(float).eps)
    assert _stabilising("care", A, B, sol.K)


def test_a_refusal_says_x_is_undetermined_only_when_the_condition_says_so():
    """CAREX 2.8 at eps = 1e6: the sign-function estimate is wrong in every digit and Newton's method stalls
    there at a condition estimate of 9e4, far below 1/eps; that shows a bad start, not an undetermined X, so
    the refusal must not claim the latter (it did).  (The solution exists and Newton's method keeps it,
    rounded, at a relative residual of 2e-17, but no first estimate reaches it yet.)"""
    A, B, Q, R, _ = rc.carex_2_8(1e6)
    try:
        sol = care(A, B, Q, R)
    except AccuracyError as exc:
        assert "every first estimate failed" in str(exc) and "not determined" not in str(exc)
    else:  # once an estimate reaches it: the reference's accuracy, as far as the condition allows
        ref = rc.pencil_reference("care", A, B, Q, R)[0]
        assert _rel(sol.X, ref) <= max(1e-10, 10 * sol.condition * np.finfo(float).eps) and not sol.marginal


RANDOM = [(kind, cls, n, seed) for kind in ("care", "dare")
          for cls, n, seed in (("generic", 4, 0), ("singular_q", 3, 1), ("near_unstabilisable", 2, 0),
                               ("boundary_observed", 4, 0), ("boundary_unobserved", 3, 0), ("badly_scaled", 4, 2))]


@pytest.mark.parametrize(("kind", "cls", "n", "seed"), RANDOM)
def test_random_classes_against_the_pencil_reference(kind, cls, n, seed):
    A, B, Q, R = rc.random_problem(kind, cls, n, seed)
    ref, _ = rc.pencil_reference(kind, A, B, Q, R)
    solve = care if kind == "care" else dare
    if ref is None:  # only the unobserved boundary mode class: a named refusal, never an answer
        assert cls == "boundary_unobserved"
        with pytest.raises(NotDetectableError, match="not observable from the weight Q"):
            solve(A, B, Q, R)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = solve(A, B, Q, R)
    tol = max(1e-10, 10 * sol.condition * np.finfo(float).eps)
    assert _rel(sol.X, ref) <= tol
    assert not sol.marginal and _stabilising(kind, A, B, sol.K)


def test_random_periodic_schedule_against_the_recursion():
    """Phases measuring 0-2 outputs; the periodic solution is the recursion's fixed point."""
    from test_periodic_dare import naive_recursion

    rng = np.random.default_rng(7)
    n, N = 3, 5
    A = [rng.standard_normal((n, n)) / np.sqrt(n) * 1.1 for _ in range(N)]
    C = [rng.standard_normal((p, n)) for p in (2, 0, 1, 0, 1)]
    R = [np.eye(c.shape[0]) * 0.5 for c in C]
    Q = [np.diag(10.0 ** rng.uniform(-3, 0, n)) for _ in range(N)]
    sol = periodic_dare(A, C, Q, R)
    ref = naive_recursion(A, C, Q, R, tol=1e-16)
    assert max(_rel(P, Pr) for P, Pr in zip(sol.P, ref, strict=True)) <= 1e-10
    assert np.max(np.abs(sol.monodromy_multipliers)) < 1

