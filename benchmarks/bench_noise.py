"""identify_noise against the truth and against allantools, on synthetic gyro recordings.

    python benchmarks/bench_noise.py [--seeds 20] [--hours 2] [--rate-hz 100]

For each seed a static gyro is simulated (white noise density N plus a rate random walk K,
the Allan-variance model of IEEE Std 952 / El-Sheimy et al.), and three estimates are
compared with the truth:

* cfdesign.identify_noise (weighted fit, terms kept only where they dominate, 95 % CIs);
* the textbook asymptote reading on allantools' overlapping ADEV (``allantools.oadev``,
  octave taus): a slope -1/2 line through the points whose local slope is within 0.1 of -1/2,
  read at tau = 1 s, and a slope +1/2 line through those within 0.1 of +1/2, read at
  tau = 3 s.  allantools has no N/B/K fit of its own, so this is the fit one writes on it;
* the agreement of the two ADEV curves themselves.

Needs the ``noise`` extra (``pip install "cfdesign[noise]"``) for allantools.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from cfdesign.allan import identify_noise, oadev


def recording(seconds, rate, N, K, seed):
    rng = np.random.default_rng(seed)
    n = int(seconds * rate)
    return N * math.sqrt(rate) * rng.standard_normal(n) + np.cumsum(K / math.sqrt(rate) * rng.standard_normal(n))


def textbook(tau, adev):
    """Fixed-slope lines through the points whose local log-log slope is near the term's."""
    slope = np.gradient(np.log(adev), np.log(tau))
    out = {}
    for name, s, at in (("N", -0.5, 1.0), ("K", 0.5, 3.0)):
        sel = np.abs(slope - s) < 0.1
        if sel.sum() == 0:
            out[name] = math.nan
            continue
        intercept = np.mean(np.log(adev[sel]) - s * np.log(tau[sel]))
        out[name] = math.exp(intercept + s * math.log(at))
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--hours", type=float, default=2.0)
    p.add_argument("--rate-hz", type=float, default=100.0)
    args = p.parse_args(argv)
    try:
        import allantools
    except ImportError:
        sys.exit('bench_noise needs allantools: pip install "cfdesign[noise]"')
    N, K = 1.7e-4, 2.0e-5
    rows, cover, worst_adev = [], {"N": 0, "K": 0}, 0.0
    for seed in range(args.seeds):
        y = recording(args.hours * 3600, args.rate_hz, N, K, seed)
        fit = identify_noise(y, args.rate_hz)
        tau, ours, _ = oadev(y, args.rate_hz)
        t2, theirs, _, _ = allantools.oadev(y, rate=args.rate_hz, data_type="freq", taus=tau)
        worst_adev = max(worst_adev, float(np.max(np.abs(theirs / ours - 1))))
        book = textbook(t2, theirs)
        n_hat, k_hat = fit.white_density, fit.random_walk_density
        rows.append((n_hat / N, (k_hat or math.nan) / K, book["N"] / N, book["K"] / K))
        for key, term, true in (("N", fit.terms.get("white"), N), ("K", fit.terms.get("random_walk"), K)):
            if term is not None and term.ci[0] <= true <= term.ci[1]:
                cover[key] += 1
    r = np.array(rows)
    print(f"{args.seeds} recordings of {args.hours:g} h at {args.rate_hz:g} Hz, N = {N:g}, K = {K:g}")
    print(f"overlapping ADEV, cfdesign vs allantools: max relative difference {worst_adev:.1e}")
    print(f"{'estimate / truth':34s} {'N mean':>8s} {'N sd':>7s} {'K mean':>8s} {'K sd':>7s}")
    for label, cols in (("cfdesign.identify_noise", (0, 1)), ("textbook fit on allantools.oadev", (2, 3))):
        a, b = r[:, cols[0]], r[:, cols[1]]
        print(f"{label:34s} {np.nanmean(a):8.4f} {np.nanstd(a):7.4f} {np.nanmean(b):8.4f} {np.nanstd(b):7.4f}")
    print(f"95% CI coverage of identify_noise: N {cover['N']}/{args.seeds}, K {cover['K']}/{args.seeds}")


if __name__ == "__main__":
    main()
