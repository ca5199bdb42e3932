"""cfdesign.blas: small solves run with one BLAS thread, and the library's threads come back."""

import numpy as np
import pytest

threadpoolctl = pytest.importorskip("threadpoolctl")

import cfdesign.riccati.api as api  # noqa: E402
from cfdesign.blas import SMALL, single_thread  # noqa: E402
from cfdesign.riccati import dare  # noqa: E402


def _blas_threads():
    return {i["filepath"]: i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}


def test_small_problems_run_single_threaded_and_restore_the_threads():
    before = _blas_threads()
    assert before, "no BLAS library seen by threadpoolctl"
    with single_thread(2):
        assert set(_blas_threads().values()) == {1}
    with single_thread(SMALL + 1):
        assert _blas_threads() == before
    assert _blas_threads() == before


def test_a_riccati_solve_of_a_small_model_runs_with_one_blas_thread(monkeypatch):
    """The solver (here its inner ``_solve``) sees one thread; the answer is unchanged."""
    seen, inner = [], api._solve

    def spy(*args, **kwargs):
        seen.append(set(_blas_threads().values()))
        return inner(*args, **kwargs)

    A, B, Q, R = np.array([[1.0, 0.1], [0.0, 1.0]]), np.array([[0.0], [0.1]]), np.eye(2), np.eye(1)
    expected = dare(A, B, Q, R).X
    monkeypatch.setattr(api, "_solve", spy)
    assert np.array_equal(dare(A, B, Q, R).X, expected) and seen == [{1}]


def test_the_per_frequency_solves_of_a_large_state_run_with_one_blas_thread(monkeypatch):
    """verify of an n = 200 chain took 13.9 s with two OpenBLAS threads on a loaded 2-core machine
    (0.30 s with one): the band responses' loop of solves runs single-threaded whatever n, and
    gives the same responses."""
    from cfdesign import linear

    n = SMALL + 36
    rng = np.random.default_rng(3)
    base = np.diag(np.linspace(0.5, 2.0, n)) + 0.01 * rng.standard_normal((n, n))
    G, c, shift = rng.standard_normal((n, 2)), rng.standard_normal(n), 1j * np.linspace(0.1, 3.0, 5)
    seen, inner = [], linear._schur_outputs

    def spy(*args):
        seen.append(set(_blas_threads().values()))
        return inner(*args)

    monkeypatch.setattr(linear, "_schur_outputs", spy)
    with threadpoolctl.threadpool_limits(2, user_api="blas"):
        out = linear._resolvent_outputs(base, shift, G, c)
    assert seen == [{1}]
    direct = np.array([c @ np.linalg.solve(s * np.eye(n) + base, G) for s in shift])
    assert np.allclose(out, direct, rtol=1e-10, atol=0)
