"""Time the symbolic synthesis + exact complementarity proof of every named filter.

Target (issue: symbolic engine): each filter of the papers (Carreira et al.'s CF, CF³, CKF³,
DCKF³; Vasconcelos et al.'s position filter) proved in under 1 s.
Baseline in the same run: sympy.simplify on the same sum, the generic way one would check it.
Run: python benchmarks/bench_proofs.py
"""

import time

import sympy as sp

import cfdesign

CASES = {
    "cf2 (order 1)": lambda: cfdesign.cf2(order=1),
    "cf2 (order 2)": lambda: cfdesign.cf2(order=2),
    "cf3": cfdesign.cf3,
    "ckf3": cfdesign.ckf3,
    "dckf3": cfdesign.dckf3,
    "position (Vasconcelos et al.)": cfdesign.position,
    **{f"cfn({n})": (lambda n=n: cfdesign.cfn(n)) for n in range(2, 7)},
    "cfn(4, full)": lambda: cfdesign.cfn(4, full=True),
    "cfn(5, full)": lambda: cfdesign.cfn(5, full=True),
    **{f"cfn({n}, discrete)": (lambda n=n: cfdesign.cfn(n, discrete=True)) for n in range(2, 7)},
}
SEED_FILTERS = ("cf2 (order 1)", "cf2 (order 2)", "cf3", "ckf3", "dckf3", "position (Vasconcelos et al.)")


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _synthesise(make):
    obs = make()
    obs.bands  # noqa: B018 - derives and caches the bands
    return obs


def main():
    print(f"{'structure':18s} {'synthesis (s)':>14s} {'proof (s)':>10s} {'total (s)':>10s} "
          f"{'simplify baseline (s)':>22s} {'baseline/proof':>15s}  holds")
    worst = 0.0  # over the papers' filters
    for name, make in CASES.items():
        obs, t_syn = timed(lambda make=make: _synthesise(make))
        proof, t_proof = timed(obs.proof)
        ok, t_base = timed(lambda obs=obs: sp.simplify(sum(obs.bands.values()) - 1) == 0)
        assert ok == proof.holds
        if name in SEED_FILTERS:
            worst = max(worst, t_syn + t_proof)
        print(f"{name:18s} {t_syn:14.3f} {t_proof:10.3f} {t_syn + t_proof:10.3f} {t_base:22.3f} "
              f"{t_base / t_proof:15.1f}  {proof.holds}")
    print(f"slowest paper filter, synthesis + proof: {worst:.3f} s (target < 1 s)")


if __name__ == "__main__":
    main()
