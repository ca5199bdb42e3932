"""Speed and accuracy of cfdesign.riccati beside scipy and the naive recursion.

Run from the repository root (one run prints every table; about a minute):

    python benchmarks/bench_riccati.py [--threads N] [--only speed,cases,fast,periodic] [--sweep]

BLAS runs single-threaded unless ``--threads`` says otherwise: the thread variables are set
before numpy is imported, and threadpoolctl (when installed) pins the pools as well; the
setting in force is printed first.

1. speed: random well-conditioned DARE and CARE, n = 30, 100, 200 (A = randn(n, n)/sqrt(n),
   B = randn(n, n/4), Q = I, R = I, fixed seed): best wall time of scipy's solver and of
   ours (interleaved calls), their ratio, and the relative residual of both solutions
   evaluated in 80-bit long double (independent of our double-double arithmetic);
2. every CAREX/DAREX case of tests/fixtures/riccati_cases.*: relative error of X (against
   X_ref, the closed form of CAREX 4.1, or a 50-digit mpmath Newton solution for n <= 6
   started from scipy's X, so independent of ours), ours and scipy's, the relative
   residuals, times, and a pass/fail verdict with the rules of tests/test_riccati.py;
3. the fast-sampling estimator DARE (double integrator at Ts = 1e-4) against mpmath;
4. periodic_dare for (period 50, 3 states) and (period 1000, 9 states) beside the naive
   recursion iterated to convergence, both measured in this run.
5. with ``--sweep`` (a few minutes more): every parametric CAREX / DAREX example over its
   parameter range (eps from 1 down to 1e-10 or up to 1e8-1e10, n up to 200-300 states),
   regenerated with the collection's generators (``--cases-module``, default
   ../shared/data/riccati/are_cases.py): our and scipy's relative forward errors against an
   independent reference (60-digit mpmath Newton for n <= 8, the collection's closed form,
   or a long-double defect correction; else the bound condition * relative residual), the
   long-double relative residuals, whether each closed loop stabilises, the times and their
   ratio;
6. with ``--sweep``: periodic_dare over periods 1 to 1000, one measurement at different
   phases, the 3 Hz GPS on a 100 Hz base, nearly blind or unobservable sensors and unstable
   dynamics, against the lifted (monodromy) DARE solved by scipy, the recursion iterated to
   convergence, and the closed form of the scalar case.

Prints figures only; no assertions on time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import timeit
import warnings
from pathlib import Path

SECTIONS = ("speed", "cases", "fast", "periodic")
ARE_CASES = Path(__file__).resolve().parents[2] / "shared" / "data" / "riccati" / "are_cases.py"
_parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
_parser.add_argument("--threads", type=int, default=1, help="BLAS threads (default 1)")
_parser.add_argument("--only", default=",".join(SECTIONS), help="comma-separated sections: " + ", ".join(SECTIONS))
_parser.add_argument("--sweep", action="store_true",
                     help="also sweep every parametric CAREX/DAREX example over its parameter range (a few minutes)")
_parser.add_argument("--cases-module", type=Path, default=ARE_CASES,
                     help="the CAREX/DAREX generators (are_cases.py) for --sweep")
ARGS = _parser.parse_args() if __name__ == "__main__" else _parser.parse_args([])
if __name__ == "__main__":
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[_var] = str(ARGS.threads)

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.linalg as sla  # noqa: E402

try:
    from threadpoolctl import threadpool_info, threadpool_limits
except ImportError:  # pragma: no cover - optional
    threadpool_info = threadpool_limits = None

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from cfdesign.errors import CfdesignError  # noqa: E402
from cfdesign.riccati import care, dare, periodic_dare  # noqa: E402


def blas_setting():
    """One line saying how many threads each BLAS/OpenMP pool runs."""
    env = ", ".join(f"{v}={os.environ.get(v, '(unset)')}" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"))
    if threadpool_info is None:
        return f"{env}; threadpoolctl not installed"
    pools = "; ".join(f"{p['internal_api']} {p.get('version') or ''} ({Path(p['filepath']).name}): "
                      f"{p['num_threads']} thread(s)" for p in threadpool_info())
    return f"{env}; threadpoolctl: {pools or 'no pools found'}"


def best_time(fn, repeat=5):
    """Best wall time of one call, in seconds."""
    number = max(1, int(0.05 / max(timeit.timeit(fn, number=1), 1e-6)))
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number


def rel(X, ref):
    return float(np.linalg.norm(X - ref) / np.linalg.norm(ref))


def fmt(x):
    return "-" if x is None else f"{x:.1e}"


# ---------------------------------------------------------------------------------------
# 1. speed on random well-conditioned problems
# ---------------------------------------------------------------------------------------
def random_problem(n, seed=None):
    """A = randn(n, n)/sqrt(n) (spectral radius about 1), B = randn(n, n/4), Q = I, R = I."""
    rng = np.random.default_rng(n if seed is None else seed)
    m = max(1, n // 4)
    return rng.normal(size=(n, n)) / np.sqrt(n), rng.normal(size=(n, m)), np.eye(n), np.eye(m)


def _ld_solve(W, Y):
    """W^-1 Y in long double: a double LU solve refined twice on a long-double residual."""
    Wd = np.asarray(W, dtype=float)
    G = np.linalg.solve(Wd, np.asarray(Y, dtype=float)).astype(np.longdouble)
    for _ in range(2):
        G = G + np.linalg.solve(Wd, np.asarray(Y - W @ G, dtype=float))
    return G


def relres_long_double(kind, A, B, Q, R, X):
    """||Res(X)|| / (size of the terms), every product in 80-bit long double (independent of cfdesign)."""
    A, B, Q, R, X = (np.asarray(M, dtype=np.longdouble) for M in (A, B, Q, R, X))
    if kind == "care":
        T = A.T @ X
        L = X @ B
        N = L @ _ld_solve(R, L.T)
        res, terms = T + T.T - N + Q, 2 * np.linalg.norm(T.astype(float))
    else:
        AX = A.T @ X
        T1, L = AX @ A, AX @ B
        N = L @ _ld_solve(R + B.T @ X @ B, L.T)
        res, terms = T1 - X - N + Q, np.linalg.norm(T1.astype(float)) + np.linalg.norm(X.astype(float))
    theta = terms + np.linalg.norm(Q.astype(float)) + np.linalg.norm(N.astype(float))
    return float(np.linalg.norm(res.astype(float)) / theta)


def paired_best_times(f_ref, f_ours, args, reps):
    """Best wall time of ``f_ref(*args)`` and ``f_ours(*args)`` over `reps` interleaved calls."""
    f_ref(*args), f_ours(*args)  # warm up
    t_ref, t_ours = [], []
    for _ in range(reps):
        for f, out in ((f_ref, t_ref), (f_ours, t_ours)):
            start = time.perf_counter()
            f(*args)
            out.append(time.perf_counter() - start)
    return min(t_ref), min(t_ours)


def bench_speed(sizes=(30, 100, 200)):
    long_double = np.finfo(np.longdouble).nmant >= 63
    print("1. Speed: random well-conditioned problems (A = randn(n,n)/sqrt(n), B = randn(n,n/4), Q = I, R = I);")
    print("   best wall time over interleaved calls; relative residuals in "
          + ("80-bit long double" if long_double else "double (no extended long double on this platform)"))
    head = (f"{'kind':4s} {'n':>4s} {'m':>3s} {'ms scipy':>9s} {'ms ours':>9s} {'ours/scipy':>10s} "
            f"{'res scipy':>9s} {'res ours':>9s} {'steps':>5s}  ours <= scipy")
    print(head)
    print("-" * len(head))
    for kind, solver, ours in (("dare", sla.solve_discrete_are, dare), ("care", sla.solve_continuous_are, care)):
        for n in sizes:
            A, B, Q, R = random_problem(n)
            t_scipy, t_ours = paired_best_times(solver, ours, (A, B, Q, R),
                                                reps=40 if n <= 30 else (12 if n <= 100 else 6))
            X_scipy, sol = solver(A, B, Q, R), ours(A, B, Q, R)
            r_scipy = relres_long_double(kind, A, B, Q, R, X_scipy)
            r_ours = relres_long_double(kind, A, B, Q, R, sol.X)
            print(f"{kind:4s} {n:4d} {B.shape[1]:3d} {1e3 * t_scipy:9.2f} {1e3 * t_ours:9.2f} {t_ours / t_scipy:10.2f} "
                  f"{r_scipy:9.1e} {r_ours:9.1e} {sol.refinement_steps:5d}  {'yes' if r_ours <= r_scipy else 'NO'}")
    print()


# ---------------------------------------------------------------------------------------
# 2. the benchmark set
# ---------------------------------------------------------------------------------------
def run_case(c):
    """One row of the table: (ours, scipy, verdict) figures for one case."""
    from test_riccati import _relres, _stable, mp_newton, reference, scipy_solution
    solve = care if c["kind"] == "care" else dare
    args = (c["A"], c["B"], c["Q"], c["R"], c["S"], c["E"])
    row = {"name": c["name"], "kind": c["kind"], "n": c["A"].shape[0], "expect": c["expect"]}
    X_scipy = scipy_solution(c)
    row["t_scipy"] = best_time(lambda: scipy_solution(c), repeat=3)
    try:
        sol = solve(*args)
        row["t_ours"] = best_time(lambda: solve(*args), repeat=3)
        row["outcome"] = "marginal" if sol.marginal else "solved"
    except CfdesignError as exc:
        sol, row["outcome"], row["t_ours"] = None, f"raised {type(exc).__name__}", None
    row["scipy_outcome"] = "raised" if X_scipy is None else "solved"
    if c["expect"] == "no_stabilizing_solution":
        row["pass"] = sol is None
        return row
    if c["expect"] == "marginal":
        row["pass"] = sol is None or sol.marginal
        return row
    start = X_scipy if X_scipy is not None else (sol.X if sol is not None else None)
    ref, row["ref"] = reference(c, start) if sol is not None else (None, "none")
    row["err"] = rel(sol.X, ref) if sol is not None and ref is not None else None
    row["err_scipy"] = rel(X_scipy, ref) if X_scipy is not None and ref is not None else None
    if row["ref"] == "X_ref" and row["n"] <= 6:  # is the published X exact for the float data?
        hp = mp_newton(c["kind"], c["A"], c["B"], c["Q"], c["R"], start, c["S"], c["E"], iters=8)
        row["xref_vs_hp"], row["err_hp"] = rel(ref, hp), rel(sol.X, hp)
    row["res"] = _relres(c, sol.X) if sol is not None else None
    row["res_scipy"] = _relres(c, X_scipy) if X_scipy is not None else None
    ok = sol is not None and not sol.marginal and _stable(c, sol.X)
    if ok and row["err"] is not None:
        ok = row["err"] <= 1e-10 and (row["err_scipy"] is None or row["err"] <= max(row["err_scipy"], 1e-14))
    elif ok:
        ok = row["res"] <= max(1e-13, 10 * (row["res_scipy"] or 0))
    row["pass"] = ok
    return row


def bench_cases():
    from test_riccati import CASES

    print("2. CAREX / DAREX benchmark set (relative errors of X; residuals in plain double)")
    head = (f"{'case':22s} {'kind':4s} {'n':>3s} {'expect':8s} {'ref':11s} {'err ours':>9s} {'err scipy':>9s} "
            f"{'res ours':>9s} {'res scipy':>9s} {'ms ours':>8s} {'ms scipy':>8s}  verdict")
    print(head)
    print("-" * len(head))
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for c in CASES.values():
            r = run_case(c)
            rows.append(r)
            t_ours = "-" if r["t_ours"] is None else f"{1e3 * r['t_ours']:.1f}"
            verdict = ("PASS" if r["pass"] else "FAIL") + ("" if r["outcome"] == "solved" else f" ({r['outcome']})")
            print(f"{r['name']:22s} {r['kind']:4s} {r['n']:3d} {r['expect'][:8]:8s} {r.get('ref', '-'):11s} "
                  f"{fmt(r.get('err')):>9s} {fmt(r.get('err_scipy')):>9s} {fmt(r.get('res')):>9s} "
                  f"{fmt(r.get('res_scipy')):>9s} {t_ours:>8s} {1e3 * r['t_scipy']:8.1f}  {verdict}")
    with_ref = [r for r in rows if r.get("err") is not None]
    worst = max(with_ref, key=lambda r: r["err"])
    worst_s = max((r for r in with_ref if r["err_scipy"] is not None), key=lambda r: r["err_scipy"])
    better = sum(r["err"] < r["err_scipy"] for r in with_ref if r["err_scipy"] is not None)
    equal = sum(r["err"] == r["err_scipy"] for r in with_ref if r["err_scipy"] is not None)
    print(f"\n   cases passed: {sum(r['pass'] for r in rows)}/{len(rows)}")
    print(f"   cases with a reference: {len(with_ref)}; ours more accurate on {better}, equal on {equal}, "
          f"less accurate on {len(with_ref) - better - equal}")
    print(f"   worst relative error: ours {worst['err']:.1e} ({worst['name']}), "
          f"scipy {worst_s['err_scipy']:.1e} ({worst_s['name']})")
    for r in rows:
        if r.get("xref_vs_hp", 0) > 1e-14:
            print(f"   note: X_ref of {r['name']} is {r['xref_vs_hp']:.1e} from the 50-digit solution of the "
                  f"float data; ours is {r['err_hp']:.1e} from it")
    for r in rows:
        if r.get("err_scipy") is not None and r["err_scipy"] > 1e-8:
            print(f"   {r['name']}: ours {fmt(r['err'])}, scipy {fmt(r['err_scipy'])}")
    print()


# ---------------------------------------------------------------------------------------
# 3. fast sampling
# ---------------------------------------------------------------------------------------
def bench_fast_sampling():
    from test_riccati import mp_newton

    print("3. Fast sampling: estimator DARE of the double integrator, Ts = 1e-4, C = [1, 0]")
    print(f"{'q':>8s} {'R':>8s} {'err ours':>9s} {'err scipy':>9s} {'ms ours':>8s} {'ms scipy':>8s}")
    T = 1e-4
    A, C = np.array([[1.0, T], [0.0, 1.0]]), np.array([[1.0, 0.0]])
    for q, r in [(1e-6, 1e-2), (1e-6, 1.0), (1e-6, 100.0), (1e-9, 1.0), (1e-12, 1.0)]:
        Q, R = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]]), np.array([[r]])
        sol = dare(A.T, C.T, Q, R)
        X_scipy = sla.solve_discrete_are(A.T, C.T, Q, R)
        ref = mp_newton("dare", A.T, C.T, Q, R, X_scipy, iters=8)
        t_ours = best_time(lambda Q=Q, R=R: dare(A.T, C.T, Q, R))
        t_scipy = best_time(lambda Q=Q, R=R: sla.solve_discrete_are(A.T, C.T, Q, R))
        print(f"{q:8.0e} {r:8.0e} {rel(sol.X, ref):9.1e} {rel(X_scipy, ref):9.1e} "
              f"{1e3 * t_ours:8.2f} {1e3 * t_scipy:8.2f}")
    print()


# ---------------------------------------------------------------------------------------
# 4. periodic DARE
# ---------------------------------------------------------------------------------------
def periodic_problem(period, axes):
    """Position filter of Vasconcelos et al. on `axes` axes, IMU at `period` Hz, GPS (10 m^2) at 1 Hz, phase 0."""
    from test_periodic_dare import GPS_R, position_model

    F1, Q1 = position_model(1.0 / period)
    F, Q = np.kron(np.eye(axes), F1), np.kron(np.eye(axes), Q1)
    H = np.kron(np.eye(axes), np.array([[1.0, 0.0, 0.0]]))
    C = [H] + [np.zeros((0, 3 * axes))] * (period - 1)
    R = [GPS_R[0, 0] * np.eye(axes)] + [np.zeros((0, 0))] * (period - 1)
    return F, C, Q, R


def bench_periodic():
    from test_periodic_dare import naive_recursion

    print("4. Periodic DARE (filter form) against the naive recursion iterated to convergence")
    print(f"{'period':>6s} {'n':>3s} {'ms ours':>9s} {'ms naive':>10s} {'speed-up':>9s} {'periods':>8s} "
          f"{'max |mu|':>9s} {'residual':>9s} {'ours vs naive':>13s}")
    for period, axes in [(50, 1), (1000, 3)]:
        F, C, Q, R = periodic_problem(period, axes)
        sol = periodic_dare(F, C, Q, R)
        t_ours = best_time(lambda F=F, C=C, Q=Q, R=R: periodic_dare(F, C, Q, R))
        start = time.perf_counter()
        ref = naive_recursion(F, C, Q, R, tol=1e-14)
        t_naive = time.perf_counter() - start
        periods = count_periods(F, C, Q, R, tol=1e-14)
        err = max(rel(P, Pr) for P, Pr in zip(sol.P, ref, strict=True))
        print(f"{period:6d} {3 * axes:3d} {1e3 * t_ours:9.2f} {1e3 * t_naive:10.1f} {t_naive / t_ours:8.0f}x "
              f"{periods:8d} {np.max(np.abs(sol.monodromy_multipliers)):9.4f} {sol.residual:9.1e} {err:13.1e}")
    print()


def count_periods(F, C, Q, R, tol):
    """Periods the naive recursion needs (same stopping rule as naive_recursion)."""
    n = F.shape[0]
    P, periods = np.zeros((n, n)), 0
    while True:
        start, periods = P, periods + 1
        P = naive_period(F, C, Q, R, P)
        if np.linalg.norm(P - start) <= tol * np.linalg.norm(P):
            return periods


def naive_period(F, C, Q, R, P):
    for Ck, Rk in zip(C, R, strict=True):
        if Ck.shape[0]:
            P = P - P @ Ck.T @ np.linalg.solve(Ck @ P @ Ck.T + Rk, Ck @ P)
        P = F @ P @ F.T + Q
        P = 0.5 * (P + P.T)
    return P


# ---------------------------------------------------------------------------------------
# 5. parameter sweep of the CAREX / DAREX families
# ---------------------------------------------------------------------------------------
_SMALL_EPS = (1.0, 1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
_LARGE_EPS = (1.0, 1e2, 1e4, 1e6, 1e8)
#: (collection, nr1, nr2, parameter name, values): every parametric example of CAREX and DAREX
SWEEP = (
    ("carex", 2, 1, "eps", _SMALL_EPS),
    ("carex", 2, 2, "eps", _SMALL_EPS),
    ("carex", 2, 3, "eps", (1e-2, *_LARGE_EPS)),
    ("carex", 2, 4, "eps", _SMALL_EPS),
    ("carex", 2, 5, "eps", (1.0, 1e-2, 1e-4, 1e-6, 1e-8, 0.0)),
    ("carex", 2, 6, "eps", (1e-2, *_LARGE_EPS)),
    ("carex", 2, 7, "eps", _SMALL_EPS[:-1]),
    ("carex", 2, 8, "eps", _SMALL_EPS[:-1]),
    ("carex", 3, 1, "n", (5, 10, 20, 50, 100)),
    ("carex", 3, 2, "n", (8, 16, 64, 128, 200)),
    ("carex", 4, 1, "n", (2, 5, 10, 15, 21, 30)),
    ("carex", 4, 3, "n", (5, 15, 30, 60, 100)),
    ("darex", 2, 1, "eps", (1e-8, 1e-4, 1.0, 1e4, 1e6, 1e8)),
    ("darex", 2, 2, "eps", _LARGE_EPS),
    ("darex", 2, 3, "eps", (1e-2, *_LARGE_EPS)),
    ("darex", 2, 4, "eps", (1e-8, 1e-4, 1e-2, *_LARGE_EPS)),
    ("darex", 2, 5, "eps", (1.0, 1e2, 1e4, 1e6, 1e8, 1e10)),
    ("darex", 4, 1, "n", (10, 30, 100, 200, 300)),
)


def _load_generators(path):
    import importlib.util

    spec = importlib.util.spec_from_file_location("are_cases", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _gain(kind, A, B, R, X):
    if kind == "care":
        return np.linalg.solve(R, B.T @ X)
    return np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)


def _stabilising(kind, A, B, R, X):
    """Whether the gain at X stabilises (A - B K), eigenvalues in plain double (independent of cfdesign)."""
    with np.errstate(all="ignore"):
        try:
            lam = np.linalg.eigvals(A - B @ _gain(kind, A, B, R, X))
        except np.linalg.LinAlgError:
            return False
    return bool(np.all(lam.real < 0) if kind == "care" else np.all(np.abs(lam) < 1))


def _ld_defect_correction(kind, A, B, Q, R, X0, steps=6):
    """Reference for n > 8: defect correction with the residual in 80-bit long double.

    Returns (X, size of the last correction relative to X); the correction is scipy's
    Lyapunov / Stein solve at the current gain (see tests/test_riccati.py::_ld_reference).
    """
    from test_riccati import _ld_reference

    X = _ld_reference(kind, A, B, Q, R, X0, steps=steps)
    X1 = _ld_reference(kind, A, B, Q, R, X, steps=1)
    return X1, rel(X1, X)


def sweep_reference(kind, A, B, Q, R, starts, X_closed):
    """(reference X, how it was obtained) on the float data, independent of cfdesign.

    n <= 8: 50-digit mpmath Newton from the first stabilising start (scipy's X first), to
    convergence.  Larger n: the closed form where the collection gives one, else the long
    double defect correction when it converges, else None (the table then shows the
    forward-error bound condition * relative residual).
    """
    from test_riccati import butterworth_chain_solution, mp_newton

    n = A.shape[0]
    start = next((X for X in starts if X is not None and np.all(np.isfinite(X)) and _stabilising(kind, A, B, R, X)),
                 None)
    if n <= 8 and start is not None:
        X = mp_newton(kind, A, B, Q, R, start, iters=10, dps=60)
        X1 = mp_newton(kind, A, B, Q, R, X, iters=1, dps=60)
        if rel(X1, X) <= 1e-15:  # two more steps leave the rounded X unchanged: converged
            return X1, "mpmath"
    if isinstance(X_closed, str):
        return butterworth_chain_solution(n), "closed form"
    if X_closed is not None:
        return X_closed, "closed form"
    if start is not None:
        X, step = _ld_defect_correction(kind, A, B, Q, R, start)
        if step <= 1e-15:
            return X, "long double"
    return None, "bound"


def sweep_case(kind, A, B, Q, R, X_closed):
    solver = sla.solve_continuous_are if kind == "care" else sla.solve_discrete_are
    ours = care if kind == "care" else dare
    row = {"n": A.shape[0]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            X_s = solver(A, B, Q, R)
            if not np.all(np.isfinite(X_s)):
                X_s = None
        except (np.linalg.LinAlgError, ValueError):
            X_s = None
        row["t_scipy"] = best_time(lambda: solver(A, B, Q, R), repeat=3) if X_s is not None else None
        try:
            sol = ours(A, B, Q, R)
            row["outcome"] = "marginal" if sol.marginal else "solved"
            row["t_ours"] = best_time(lambda: ours(A, B, Q, R), repeat=3)
        except CfdesignError as exc:
            sol, row["outcome"], row["t_ours"] = None, type(exc).__name__, None
            row["message"] = str(exc)
    X_o = None if sol is None else sol.X
    ref, row["ref"] = sweep_reference(kind, A, B, Q, R, (X_s, X_o, X_closed if not isinstance(X_closed, str) else None),
                                      X_closed)
    for tag, X in (("ours", X_o), ("scipy", X_s)):
        row[f"stab_{tag}"] = None if X is None else _stabilising(kind, A, B, R, X)
        row[f"res_{tag}"] = None if X is None else relres_long_double(kind, A, B, Q, R, X)
        row[f"err_{tag}"] = None if X is None or ref is None else rel(X, ref)
    if sol is not None:
        row["cond"], row["claimed"] = sol.condition, sol.forward_error
        if ref is None:  # first-order forward-error bound from our condition estimate
            row["err_ours"] = sol.condition * max(row["res_ours"], np.finfo(float).eps)
    return row


def bench_sweep(path):
    gen = _load_generators(path)
    print("5. Parameter sweep of the CAREX / DAREX families (ref: mpmath 60 digits for n <= 8, else the closed "
          "form,\n   else long-double defect correction, else 'bound' = condition * relative residual); "
          "stab: closed loop\n   stabilising (eigenvalues in double); res: relative residual in long double")
    head = (f"{'example':10s} {'param':>9s} {'n':>3s} {'outcome':26s} {'ref':11s} {'err ours':>9s} {'err scipy':>9s} "
            f"{'res ours':>9s} {'res scipy':>9s} {'stab':>5s} {'cond':>8s} {'ms ours':>8s} {'ms scipy':>8s} "
            f"{'ratio':>6s}")
    print(head)
    print("-" * len(head))
    rows = []
    for coll, nr1, nr2, pname, values in SWEEP:
        make = gen.carex if coll == "carex" else gen.darex
        kind = "care" if coll == "carex" else "dare"
        for v in values:
            d = make(nr1, nr2, **{pname: v})
            if coll == "darex" and d.get("S") is not None:
                continue
            X_closed = "butterworth" if (coll, nr1, nr2) == ("carex", 4, 1) else d["X_ref"]
            row = sweep_case(kind, d["A"], d["B"], d["Q"], d["R"], X_closed)
            row.update(example=f"{coll[0]}{nr1}.{nr2}", param=f"{pname}={v:g}")
            rows.append(row)
            stab = "/".join("-" if row[f"stab_{t}"] is None else ("y" if row[f"stab_{t}"] else "N")
                            for t in ("ours", "scipy"))
            ratio = (row["t_ours"] / row["t_scipy"]) if row["t_ours"] and row["t_scipy"] else None
            t_o = "-" if row["t_ours"] is None else f"{1e3 * row['t_ours']:.2f}"
            t_s = "-" if row["t_scipy"] is None else f"{1e3 * row['t_scipy']:.2f}"
            print(f"{row['example']:10s} {row['param']:>9s} {row['n']:3d} {row['outcome'][:26]:26s} {row['ref']:11s} "
                  f"{fmt(row['err_ours']):>9s} {fmt(row['err_scipy']):>9s} {fmt(row['res_ours']):>9s} "
                  f"{fmt(row['res_scipy']):>9s} {stab:>5s} {fmt(row.get('cond')):>8s} {t_o:>8s} {t_s:>8s} "
                  f"{'-' if ratio is None else f'{ratio:.2f}':>6s}", flush=True)
    print("\n   stab = ours/scipy; outcome names our error class when we raise")
    for r in rows:
        if r.get("message"):
            print(f"   {r['example']} {r['param']}: {r['message']}")
    print()
    return rows


def lifted_periodic_reference(A, C, Q, R, solver=None):
    """P[0..N-1] of the periodic filter from the lifted (monodromy) DARE, solved by scipy (or ``solver``,
    called as ``solver(A, B, Q, R, S)`` and returning a result with ``.X``, e.g. cfdesign's dare).

    Over one period ``x[N] = Phi x[0] + w`` and the period's measurements ``y = Gamma x[0] + v``,
    where ``v`` holds the process noise that reached each measurement, so ``w`` and ``v`` are
    correlated (cross covariance ``S``).  The a-priori covariance at phase 0 is the stabilising
    solution of ``dare(Phi', Gamma', W, V, s=S)``; one sweep of the recursion gives the others.
    Independent of cfdesign (no composition of Riccati maps, no doubling).
    """
    N, n = len(C), A[0].shape[0]
    trans = [[None] * (N + 1) for _ in range(N + 1)]  # trans[j][i] = A[j-1] ... A[i]
    for i in range(N + 1):
        trans[i][i] = np.eye(n)
        for j in range(i + 1, N + 1):
            trans[j][i] = A[j - 1] @ trans[j - 1][i]
    meas = [j for j in range(N) if C[j].shape[0]]
    Gam = np.vstack([C[j] @ trans[j][0] for j in meas])
    W = sum(trans[N][i + 1] @ Q[i] @ trans[N][i + 1].T for i in range(N))
    off = np.cumsum([0] + [C[j].shape[0] for j in meas])
    V, S = np.zeros((off[-1], off[-1])), np.zeros((n, off[-1]))
    for a, j in enumerate(meas):
        for b, h in enumerate(meas):
            blk = np.zeros((C[j].shape[0], C[h].shape[0]))
            for i in range(min(j, h)):
                blk += C[j] @ trans[j][i + 1] @ Q[i] @ trans[h][i + 1].T @ C[h].T
            V[off[a]:off[a + 1], off[b]:off[b + 1]] = blk + (R[j] if j == h else 0)
        for i in range(j):
            S[:, off[a]:off[a + 1]] += trans[N][i + 1] @ Q[i] @ trans[j][i + 1].T @ C[j].T
    if solver is None:
        P = [sla.solve_discrete_are(trans[N][0].T, Gam.T, W, V, s=S)]
    else:
        P = [solver(trans[N][0].T, Gam.T, W, V, S).X]
    for k in range(N - 1):
        Pk = P[-1]
        if C[k].shape[0]:  # Joseph form
            K = np.linalg.solve(C[k] @ Pk @ C[k].T + R[k], C[k] @ Pk).T
            IKC = np.eye(n) - K @ C[k]
            Pk = IKC @ Pk @ IKC.T + K @ R[k] @ K.T
        P.append(A[k] @ Pk @ A[k].T + Q[k])
    return P


def _schedule(N, phases, H, R):
    n = H.shape[1]
    return ([H if k in phases else np.zeros((0, n)) for k in range(N)],
            [R if k in phases else np.zeros((0, 0)) for k in range(N)])


def periodic_sweep_cases():
    """(name, A, C, R, Q, exact P[0] or None) of the periodic sweep."""
    from test_periodic_dare import position_model

    F, Q = position_model()  # 50 Hz IMU
    F1, Q1 = position_model(0.01)  # 100 Hz IMU
    H, Rg = np.array([[1.0, 0.0, 0.0]]), np.array([[10.0]])
    out = [(f"GPS once per period, N={N}", F, *_schedule(N, {0}, H, Rg), Q, None) for N in (1, 2, 7, 50, 333, 1000)]
    out += [(f"100 Hz, GPS at phase {ph}", F1, *_schedule(100, {ph}, H, Rg), Q1, None) for ph in (1, 25, 99)]
    out.append(("3 Hz GPS on 100 Hz (0,33,67)", F1, *_schedule(100, {0, 33, 67}, H, Rg), Q1, None))
    out.append(("same, GPS R = 1e-12", F1, *_schedule(100, {0, 33, 67}, H, np.array([[1e-12]])), Q1, None))
    out.append(("same, GPS R = 1e12 (nearly blind)", F1, *_schedule(100, {0, 33, 67}, H, np.array([[1e12]])), Q1, None))
    out.append(("same, C = [1e-8 0 0]", F1, *_schedule(100, {0, 33, 67}, 1e-8 * H, Rg), Q1, None))
    out.append(("velocity + 1e-10 position, N=50", F, *_schedule(50, {0}, np.array([[1e-10, 1.0, 0.0]]), Rg), Q, None))
    out.append(("no measurement at all, N=50", F, *_schedule(50, set(), H, Rg), Q, None))
    for N in (100, 400, 1000):  # x[k+1] = 1.05 x[k] + w, measured once per period: closed form
        import mpmath as mp

        with mp.workdps(60):
            a = mp.mpf("1.05")
            phi2, W = a ** (2 * N), sum(a ** (2 * i) for i in range(N))
            exact = float((-(1 - phi2 - W) + mp.sqrt((1 - phi2 - W) ** 2 + 4 * W)) / 2)
        out.append((f"unstable scalar 1.05, N={N}", np.array([[1.05]]), *_schedule(N, {0}, np.ones((1, 1)),
                                                                                     np.ones((1, 1))),
                    np.eye(1), exact))
    return out


def bench_periodic_sweep():
    from test_periodic_dare import naive_recursion

    print("6. Periodic DARE sweep: ours against the lifted (monodromy) DARE with correlated noise solved by scipy,")
    print("   the recursion iterated to convergence (up to 20000 periods) and, where one exists, the closed form")
    head = (f"{'case':36s} {'N':>5s} {'outcome':22s} {'vs lifted':>9s} {'vs naive':>9s} {'vs exact':>9s} "
            f"{'lift/naive':>10s} {'max |mu|':>9s} {'residual':>9s} {'ms ours':>8s}")
    print(head)
    print("-" * len(head))
    for name, A, C, R, Q, exact in periodic_sweep_cases():
        N = len(C)
        try:
            sol = periodic_dare(A, C, Q, R)
            t = best_time(lambda A=A, C=C, Q=Q, R=R: periodic_dare(A, C, Q, R), repeat=3)
            outcome = "solved"
        except CfdesignError as exc:
            sol, t, outcome = None, None, type(exc).__name__
        errs, refs = [], {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                refs["lifted"] = lifted_periodic_reference([A] * N, C, [Q] * N, R)
            except (np.linalg.LinAlgError, ValueError):
                refs["lifted"] = None
            try:
                refs["naive"] = naive_recursion(A, C, Q, R, tol=1e-15, max_periods=max(1, 200_000 // N))
            except (AssertionError, np.linalg.LinAlgError):
                refs["naive"] = None
        for key in ("lifted", "naive"):
            ok = sol is not None and refs[key] is not None
            errs.append(max(rel(P, Pr) for P, Pr in zip(sol.P, refs[key], strict=True)) if ok else None)
        errs.append(abs(sol.P[0][0, 0] - exact) / exact if sol is not None and exact is not None else None)
        spread = (max(rel(P, Pr) for P, Pr in zip(refs["lifted"], refs["naive"], strict=True))
                  if refs["lifted"] is not None and refs["naive"] is not None else None)
        mu = "-" if sol is None else f"{np.max(np.abs(sol.monodromy_multipliers)):.6f}"
        print(f"{name:36s} {N:5d} {outcome:22s} {fmt(errs[0]):>9s} {fmt(errs[1]):>9s} {fmt(errs[2]):>9s} "
              f"{fmt(spread):>10s} {mu:>9s} {fmt(None if sol is None else sol.residual):>9s} "
              f"{'-' if t is None else f'{1e3 * t:.2f}':>8s}", flush=True)
    print()


if __name__ == "__main__":
    if threadpool_limits is not None:
        threadpool_limits(ARGS.threads)
    print(f"numpy {np.__version__}, scipy {scipy.__version__}, Python {sys.version.split()[0]}")
    print(f"BLAS threads: {blas_setting()}\n")
    only = {x.strip() for x in ARGS.only.split(",")}
    for name, section in (("speed", bench_speed), ("cases", bench_cases), ("fast", bench_fast_sampling),
                          ("periodic", bench_periodic)):
        if name in only:
            section()
    if ARGS.sweep:
        bench_sweep(ARGS.cases_module)
        bench_periodic_sweep()
