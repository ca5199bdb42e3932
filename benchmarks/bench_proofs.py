"""Time the symbolic synthesis + exact complementarity proof of every named filter.

Target (issue: symbolic engine): each filter of the papers (Carreira et al.'s CF, CF³, CKF³,
DCKF³; Vasconcelos et al.'s position filter) proved in under 1 s.
Baseline in the same run: sympy.simplify on the same sum, the generic way one would check it.
Second table: design-file chains, the proof against the canonical reduction of the bands.
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
    chains()


#: design-file chains (states by derivative order, a bias state, full symbolic gain): (order, inputs, measurements)
CHAINS = {
    "chain 2, two inputs, p v": (2, ["acc_a", "acc_b"], [("p", 0), ("v", 1)]),
    "chain 3, p v": (3, ["jerk"], [("p", 0), ("v", 1)]),
    "chain 3, p a": (3, ["jerk"], [("p", 0), ("a", 2)]),
}


def chains():
    """The proof as cfdesign design runs it (no band brought to lowest terms when it holds)
    against the canonical reduction of the sum of the bands in lowest terms, the first way
    it was written; an order-3 chain with p, v and a sensors (12 gains) took minutes that way."""
    from cfdesign.symbolic.filters import chain

    print(f"\n{'chain (discrete, bias state)':30s} {'gains':>5s} {'proof (s)':>10s} {'canonical (s)':>14s} "
          f"{'canonical/proof':>16s}  holds")
    for name, args in CHAINS.items():
        proof, t_proof = timed(lambda args=args: chain(*args, bias=True, discrete=True).proof())
        obs = chain(*args, bias=True, discrete=True)
        residual, t_canon = timed(lambda obs=obs: sp.cancel(sp.together(sum(obs.bands.values()) - 1)))
        assert (residual == 0) == proof.holds
        print(f"{name:30s} {len(obs.gains):5d} {t_proof:10.3f} {t_canon:14.2f} {t_canon / t_proof:16.1f}  "
              f"{proof.holds}")
    big, t_big = timed(lambda: chain(3, ["jerk"], [("p", 0), ("v", 1), ("a", 2)], bias=True, discrete=True).proof())
    print(f"{'chain 3, p v a':30s} {12:5d} {t_big:10.3f} {'(minutes)':>14s} {'':>16s}  {big.holds}")


if __name__ == "__main__":
    main()
