"""The Riccati solvers over problem classes, not examples: a table with a verdict per case.

Run from the repository root (about 10-15 minutes; ``--quick`` for a few cases of each class):

    python benchmarks/bench_riccati_sweep.py [--quick] [--only carex,darex,random,periodic]

1. carex / darex: every parametric example of the CAREX / DAREX collections (Abels and
   Benner, SLICOT Working Notes 1999-14 and 1999-16) over its parameter range in decades
   (eps from 1e-12 to 1e12 where the collection allows it, n up to 200), generated with
   ../shared/data/riccati/are_cases.py (skipped when absent);
2. random: seeded random problems of tests/riccati_sweep_cases.py (generic, singular Q,
   nearly unstabilisable, modes on the stability boundary seen or unseen by Q, badly scaled),
   n = 1 to 12, CARE and DARE;
3. periodic: periodic_dare on random periodic schedules against the lifted DARE solved by
   scipy and by our dare (benchmarks/bench_riccati.py's lifted_periodic_reference).

Reference for n <= 12: the stable deflating subspace of the extended pencil in mpmath at 50
digits, polished by defect correction (``pencil_reference``), which also decides whether a
stabilising solution exists (a pencil eigenvalue on the boundary: none).  Larger n: the
collection's closed form, else the long-double defect correction of bench_riccati.py.

Columns: case, parameter, n, condition (our estimate when we solve), our relative error, scipy's,
our and scipy's relative residuals (80-bit long double), verdict:

* ``pass``: relative error <= 1e-10, closed loop stabilising, residual no worse than scipy's
  (or below 1e-14);
* ``pass (ill-cond)``: error above 1e-10 but below 10 * condition * eps, and reported (a warning, or
  the result's ``forward_error`` within a factor 10 of it);
* ``refused ok``: no stabilising solution exists and we raised a cfdesign error or flagged the
  solution marginal; ``refused ok (boundary)``: a pencil eigenvalue lies within sqrt(eps) (relative)
  of the boundary, where rounding the data alone can put it (a boundary eigenvalue is double), and
  we refused with a cfdesign error or flagged the solution marginal;
* ``refused (ill-cond)``: AccuracyError where our condition estimate exceeds 1/eps;
* ``marginal (flagged)``: returned with ``marginal=True`` and a warning;
* ``WRONG``: anything else (a wrong answer, a wrong refusal, a raw exception).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.linalg as sla

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]
sys.argv, _argv = sys.argv[:1], sys.argv  # bench_riccati parses its own options at import
import bench_riccati as br  # noqa: E402

sys.argv = _argv
from riccati_sweep_cases import RANDOM_CLASSES, pencil_reference, random_problem  # noqa: E402

from cfdesign.errors import AccuracyError, CfdesignError  # noqa: E402
from cfdesign.riccati import care, dare, periodic_dare  # noqa: E402

EPS = np.finfo(float).eps
DECADES = tuple(10.0**k for k in range(-12, 13))
#: (collection, nr1, nr2, parameter, values, extra keyword arguments)
SWEEP = (
    ("carex", 2, 1, "eps", DECADES, {}),
    ("carex", 2, 2, "eps", DECADES, {}),
    ("carex", 2, 3, "eps", DECADES, {}),
    ("carex", 2, 4, "eps", (0.0, *DECADES), {}),
    ("carex", 2, 5, "eps", (0.0, *DECADES), {}),
    ("carex", 2, 6, "eps", DECADES, {}),
    ("carex", 2, 7, "eps", DECADES, {}),
    ("carex", 2, 8, "eps", DECADES, {}),
    ("carex", 3, 1, "n", (2, 3, 5, 10, 20, 50, 100), {}),
    ("carex", 3, 2, "n", (2, 3, 4, 8, 16, 64, 128, 200), {}),
    ("carex", 4, 1, "n", (2, 3, 5, 10, 15, 21, 25, 30, 40), {}),
    ("carex", 4, 3, "n", (2, 3, 5, 15, 30, 60, 100), {}),
    ("darex", 2, 1, "eps", DECADES, {}),
    ("darex", 2, 2, "eps", DECADES, {}),
    ("darex", 2, 3, "eps", (0.0, *DECADES), {}),
    ("darex", 2, 4, "eps", DECADES, {}),
    ("darex", 2, 5, "eps", (1.5, 2.0, *DECADES[13:]), {}),
    ("darex", 4, 1, "n", (2, 3, 5, 10, 30, 100, 200), {}),
    ("darex", 4, 1, "eps", DECADES, {"n": 30}),
)


def reference(kind, A, B, Q, R, X_closed, starts):
    """(X or None, exists, how): the independent reference of one case."""
    n = A.shape[0]
    if n <= 12:
        X, boundary = pencil_reference(kind, A, B, Q, R)
        scale = 1.0 if kind == "dare" else max(1.0, np.abs(np.linalg.eigvals(A)).max())
        # a boundary eigenvalue of the pencil is double (lam and its mirror image meet), so rounding the
        # data by eps moves it by about sqrt(eps): within that, refusing and solving are both right
        if boundary <= np.sqrt(EPS) * scale:
            return X, None, f"pencil {boundary:.1e}"
        return X, X is not None, f"pencil {boundary:.1e}"
    if isinstance(X_closed, str):
        from test_riccati import butterworth_chain_solution

        return butterworth_chain_solution(n), True, "closed form"
    if X_closed is not None:
        return X_closed, True, "closed form"
    start = next((X for X in starts if X is not None and br._stabilising(kind, A, B, R, X)), None)
    if start is not None:
        X, step = br._ld_defect_correction(kind, A, B, Q, R, start)
        if step <= 1e-15:
            return X, True, "long double"
    return None, True, "none"


def run(kind, A, B, Q, R, X_closed=None):
    """One case: our and scipy's solutions against the reference, with a verdict."""
    solver = sla.solve_continuous_are if kind == "care" else sla.solve_discrete_are
    ours = care if kind == "care" else dare
    row = {"n": A.shape[0], "cond": None, "err_o": None, "err_s": None, "res_o": None, "res_s": None}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            X_s = solver(A, B, Q, R)
            X_s = X_s if np.all(np.isfinite(X_s)) else None
        except (np.linalg.LinAlgError, ValueError):
            X_s = None
        t0 = time.process_time()
        try:
            sol, outcome = ours(A, B, Q, R), None
        except CfdesignError as exc:
            sol, outcome = None, exc
        except Exception as exc:  # noqa: BLE001 - a raw exception is a fault in itself, reported as WRONG
            sol, outcome = None, exc
        row["ms"] = 1e3 * (time.process_time() - t0)
    warned = any(issubclass(w.category, RuntimeWarning) for w in caught)
    X_o = None if sol is None else sol.X
    ref, exists, row["ref"] = reference(kind, A, B, Q, R, X_closed, (X_s, X_o))
    for tag, X in (("o", X_o), ("s", X_s)):
        if X is not None:
            row[f"res_{tag}"] = br.relres_long_double(kind, A, B, Q, R, X)
            if ref is not None:
                row[f"err_{tag}"] = br.rel(X, ref)
    if sol is not None:
        row["cond"] = sol.condition
    row["outcome"] = ("marginal" if sol.marginal else "solved") if sol is not None else type(outcome).__name__
    row["verdict"] = verdict(kind, A, B, R, sol, outcome, exists, row, warned)
    return row


def verdict(kind, A, B, R, sol, outcome, exists, row, warned):
    """The rules of the module docstring."""
    if outcome is not None and not isinstance(outcome, CfdesignError):
        return "WRONG (raw exception)"
    if exists is None and (sol is None or sol.marginal):  # boundary within rounding: refusing is right too
        return "refused ok (boundary)" if isinstance(outcome, CfdesignError) or sol is not None else "WRONG"
    if exists is False:
        if sol is None or sol.marginal:
            return "refused ok"
        return "WRONG (answer where none exists)"
    if sol is None:
        cond_too_big = row["cond"] is None or row["cond"] * EPS > 1
        if isinstance(outcome, AccuracyError) and cond_too_big:
            return "refused (ill-cond)"
        return f"WRONG refusal ({type(outcome).__name__})"
    if sol.marginal:
        return "marginal (flagged)"
    if not br._stabilising(kind, A, B, R, sol.X):
        return "WRONG (not stabilising)"
    res_ok = row["res_o"] <= max(row["res_s"] or 0.0, 1e-14)
    if row["err_o"] is None:
        return "pass (no ref)" if res_ok else "WRONG (residual)"
    if row["err_o"] <= 1e-10 and res_ok:
        return "pass"
    if row["err_o"] <= 10 * sol.condition * EPS and (warned or sol.forward_error >= row["err_o"] / 10):
        return "pass (ill-cond)"
    return "WRONG (error)" if row["err_o"] > 1e-10 else "WRONG (residual)"


def fmt(x):
    return "-" if x is None else f"{x:.1e}"


HEAD = (f"{'case':24s} {'parameter':>10s} {'n':>3s} {'outcome':24s} {'cond':>8s} {'err ours':>8s} "
        f"{'err scipy':>9s} {'res ours':>8s} {'res scipy':>9s} verdict")


def show(case, param, row):
    print(f"{case:24s} {param:>10s} {row['n']:3d} {row['outcome'][:24]:24s} {fmt(row['cond']):>8s} "
          f"{fmt(row['err_o']):>8s} {fmt(row['err_s']):>9s} {fmt(row['res_o']):>8s} {fmt(row['res_s']):>9s} "
          f"{row['verdict']}", flush=True)


def tally(title, rows):
    counts = {}
    for r in rows:
        key = r["verdict"].split(" (")[0] if r["verdict"].startswith("WRONG") else r["verdict"]
        counts[key] = counts.get(key, 0) + 1
    print(f"   {title}: {len(rows)} cases: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + "\n")


def sweep_collections(quick):
    if not br.ARE_CASES.is_file():
        print(f"1. CAREX / DAREX: skipped ({br.ARE_CASES} not found)\n")
        return
    gen = br._load_generators(br.ARE_CASES)
    print("1. CAREX / DAREX parametric examples over their parameter ranges")
    print(HEAD)
    rows = []
    for coll, nr1, nr2, pname, values, extra in SWEEP:
        make = gen.carex if coll == "carex" else gen.darex
        for v in (values[::6] if quick else values):
            d = make(nr1, nr2, **{pname: v}, **extra)
            X_closed = "butterworth" if (coll, nr1, nr2) == ("carex", 4, 1) else d["X_ref"]
            row = run("care" if coll == "carex" else "dare", d["A"], d["B"], d["Q"], d["R"], X_closed)
            rows.append(row)
            show(f"{coll} {nr1}.{nr2}" + (f" n={extra['n']}" if extra else ""), f"{pname}={v:g}", row)
    tally("CAREX/DAREX", rows)


def sweep_random(quick):
    print("2. Random problems (tests/riccati_sweep_cases.py), seeds 0-2")
    print(HEAD)
    sizes, seeds = ((2, 6), (0,)) if quick else ((1, 2, 3, 5, 8, 12), (0, 1, 2))
    for kind in ("care", "dare"):
        rows = []
        for cls in RANDOM_CLASSES:
            for n in sizes:
                for seed in seeds:
                    row = run(kind, *random_problem(kind, cls, n, seed))
                    rows.append(row)
                    show(f"{kind} {cls}", f"seed={seed}", row)
        tally(f"random {kind.upper()}", rows)


def random_schedule(rng, n, N):
    """A random periodic filter problem: phases with 0-2 measurements, a random stable-ish A."""
    A = [rng.standard_normal((n, n)) / np.sqrt(n) * 1.1 for _ in range(N)]
    C, R, Q = [], [], []
    for k in range(N):
        p = int(rng.integers(0, 3)) if k else int(rng.integers(1, 3))
        C.append(rng.standard_normal((p, n)))
        L = rng.standard_normal((p, p))
        R.append(L @ L.T + 0.1 * np.eye(p))
        G = rng.standard_normal((n, n))
        Q.append(G @ G.T * 10.0 ** rng.uniform(-3, 0))
    return A, C, Q, R


def sweep_periodic(quick):
    print("3. periodic_dare on random schedules against the lifted DARE (scipy with S, and our dare)")
    print(f"{'n':>3s} {'N':>4s} {'seed':>4s} {'outcome':24s} {'vs scipy lift':>13s} {'vs our lift':>11s} "
          f"{'max |mu|':>8s} verdict")
    rows = []
    for n in (1, 2, 3, 5) if not quick else (2,):
        for N in (1, 2, 5, 12, 40) if not quick else (3, 12):
            for seed in (0, 1, 2) if not quick else (0,):
                rng = np.random.default_rng([seed, n, N])
                A, C, Q, R = random_schedule(rng, n, N)
                try:
                    sol, outcome = periodic_dare(A, C, Q, R), "solved"
                except CfdesignError as exc:
                    sol, outcome = None, type(exc).__name__
                ref_s, ref_o = lifted(A, C, Q, R)
                errs = [None if sol is None or r is None else max(br.rel(P, Pr) for P, Pr in zip(sol.P, r, strict=True))
                        for r in (ref_s, ref_o)]
                exists = ref_o is not None or ref_s is not None
                ok = [e for e in errs if e is not None]
                if sol is None:
                    v = "refused ok" if not exists else "WRONG refusal"
                else:
                    v = "pass" if ok and min(ok) <= 1e-10 else ("pass (no ref)" if not ok else "WRONG (error)")
                rows.append({"verdict": v})
                mu = "-" if sol is None else f"{np.max(np.abs(sol.monodromy_multipliers)):.4f}"
                print(f"{n:3d} {N:4d} {seed:4d} {outcome:24s} {fmt(errs[0]):>13s} {fmt(errs[1]):>11s} {mu:>8s} {v}",
                      flush=True)
    tally("periodic", rows)


def lifted(A, C, Q, R):
    """P[0..N-1] from the lifted DARE, solved by scipy and by our dare (None where it fails)."""
    out = []
    for solver in (None, dare):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out.append(br.lifted_periodic_reference(A, C, Q, R, solver=solver))
        except (np.linalg.LinAlgError, ValueError, CfdesignError):
            out.append(None)
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a few cases of each class")
    parser.add_argument("--only", default="carex,darex,random,periodic")
    args = parser.parse_args()
    only = set(args.only.split(","))
    if only & {"carex", "darex"}:
        sweep_collections(args.quick)
    if "random" in only:
        sweep_random(args.quick)
    if "periodic" in only:
        sweep_periodic(args.quick)
