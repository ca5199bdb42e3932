"""Re-check a gain table numerically: complementarity, stability and (with the spec) the gains.

``verify`` walks the design path backwards (DESIGN.md): from the table's own ``F, B, H, K``
and sensor relations it rebuilds every band numerically and checks

(a) complementarity: ``sum_i T_i = 1`` as an exact polynomial identity (coefficients within
    ``1e-12`` relative) at every phase, and over a frequency grid for single-rate tables;
(b) stability: the closed-loop poles of a single-rate table, or the monodromy multipliers
    of a periodic one, strictly inside the unit circle (left half-plane when continuous).
    The phases of a multirate table between measurements are open loop (eigenvalues on the
    unit circle) by design, so the monodromy is what must be stable;
(c) with the spec: re-designing from it gives the same gains (``rtol``).

Band of sensor ``j``: ``T_j = (C_o adj(vI - A) G_j + D_j den) / den * rel_j`` (MATH.md §1)
with ``rel_j = v**order`` (continuous) or the ZOH chain relation ``N_order / N_0`` (discrete,
:func:`cfdesign.symbolic.observer.discrete_relation`, here in floating point).  numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np

__all__ = ["Check", "verify_table", "band_polynomials"]

IDENTITY_RTOL = 1e-12
GRID_ATOL = 1e-9


@dataclass(frozen=True)
class Check:
    """One verification result: ``name``, ``ok`` and a one-line ``detail``."""

    name: str
    ok: bool
    detail: str

    def line(self) -> str:
        return f"{'PASS' if self.ok else 'FAIL'} {self.name}: {self.detail}"


def _closed_loop(table, K):
    F, H = table.F, table.H
    n = len(F)
    if table.gain_form == "filter":
        IKH = np.eye(n) - K @ H
        return F @ IKH, np.hstack([table.B, F @ K]), IKH[0], np.concatenate([np.zeros(table.B.shape[1]), K[0]])
    G = np.hstack([table.B, K])
    return F - K @ H, G, np.eye(n)[0], np.zeros(G.shape[1])


def _adjugate(A, den):
    """Coefficient matrices of adj(vI - A), highest power first (Faddeev-LeVerrier)."""
    n = len(A)
    out, M = [np.eye(n)], np.eye(n)
    for k in range(1, n):
        M = A @ M + den[k] * np.eye(n)
        out.append(M)
    return out


def _relations(table):
    """``{order: (num, den)}`` of the sensor relations, highest power first."""
    orders = {s["order"] for s in table.sensors}
    if table.domain == "s":
        return {d: (np.r_[1.0, np.zeros(d)], np.ones(1)) for d in orders}
    m = max(orders)
    T = table.sample_time_s
    Fd = np.array([[T ** (j - i) / factorial(j - i) if j >= i else 0.0 for j in range(m)] for i in range(m)])
    Bd = np.array([T ** (m - i) / factorial(m - i) for i in range(m)])
    den = np.poly(Fd).real if m else np.ones(1)
    adj = _adjugate(Fd, den) if m else []
    nums = [np.array([M[i] @ Bd for M in adj]) for i in range(m)] + [den]
    return {d: (np.ones(1), np.ones(1)) if d == 0 else (nums[d], nums[0]) for d in orders}


def band_polynomials(table, phase: int = 0):
    """``({sensor: (num, den)}, den_cl)``: every band of one phase as polynomials (highest first)."""
    A, G, Co, D = _closed_loop(table, table.K[phase])
    den = np.poly(A).real
    adj = _adjugate(A, den)
    relations = _relations(table)
    columns = {}
    p = table.B.shape[1]
    for s in table.sensors:
        j = s["index"] if s["role"] == "input" else p + s["index"]
        num = np.array([D[j]] + [Co @ adj[k] @ G[:, j] + D[j] * den[k + 1] for k in range(len(A))])
        rel_num, rel_den = relations[s["order"]]
        columns[s["name"]] = (np.polymul(num, rel_num), np.polymul(den, rel_den))
    return columns, den


def _identity_residual(bands) -> float:
    """Relative size of ``sum_i num_i / den_i - 1`` cleared of denominators."""
    common = np.ones(1)
    for _, d in bands.values():
        common = common if _same_poly(common, d) else np.polymul(common, d)
    total, scale = -common, np.abs(common).max()
    for num, d in bands.values():
        q, _r = np.polydiv(common, d)
        term = np.polymul(num, q)
        total = np.polyadd(total, term)
        scale = max(scale, np.abs(term).max())
    return float(np.abs(np.trim_zeros(total, "f") if total.size else total).max(initial=0.0) / scale)


def _same_poly(a, b):
    return len(a) == len(b) and np.allclose(a, b, rtol=1e-14, atol=0)


def _grid_error(table, bands) -> float:
    dt = table.sample_time_s
    w = np.logspace(-4, np.log10(np.pi / dt if dt else 1e4), 400) if dt else np.logspace(-4, 4, 400)
    x = np.exp(1j * w * dt) if dt else 1j * w
    total = sum(np.polyval(num, x) / np.polyval(den, x) for num, den in bands.values())
    return float(np.abs(total - 1).max())


def _complementarity(table) -> list:
    worst, worst_phase = 0.0, 0
    for k in range(len(table.K)):
        residual = _identity_residual(band_polynomials(table, k)[0])
        if residual > worst:
            worst, worst_phase = residual, k
    ok = worst <= IDENTITY_RTOL
    where = f" (worst at phase {worst_phase})" if len(table.K) > 1 else ""
    checks = [Check("complementary (polynomial identity)", ok,
                    f"sum of bands - 1 has relative coefficient size {worst:.2e}{where}, tolerance {IDENTITY_RTOL:g}")]
    if len(table.K) == 1:
        err = _grid_error(table, band_polynomials(table, 0)[0])
        checks.append(Check("complementary (frequency grid)", err <= GRID_ATOL,
                            f"max |sum of bands - 1| = {err:.2e} over 400 frequencies, tolerance {GRID_ATOL:g}"))
    return checks


def _stability(table) -> Check:
    maps = [_closed_loop(table, K)[0] for K in table.K]
    if len(maps) == 1:
        eig = np.linalg.eigvals(maps[0])
        what, margin = "closed-loop poles", (eig.real.max() if table.domain == "s" else np.abs(eig).max())
        ok = margin < 0 if table.domain == "s" else margin < 1
        bound = "max real part" if table.domain == "s" else "spectral radius"
    else:
        Phi = np.eye(len(table.F))
        for A in maps:
            Phi = A @ Phi
        eig = np.linalg.eigvals(Phi)
        what, bound, margin = "monodromy multipliers", "spectral radius", np.abs(eig).max()
        ok = margin < 1
    return Check(f"stable ({what})", bool(ok), f"{bound} {margin:.6g}")


def _same_design(table, spec, rtol) -> list:
    from .designer import design

    fresh = design(spec)
    if fresh.period != table.period or fresh.K[0].shape != table.K[0].shape:
        return [Check("gains match the spec", False, f"re-design has period {fresh.period} and K shape "
                      f"{fresh.K[0].shape}; the table has {table.period} and {table.K[0].shape}")]
    scale = max(np.abs(K).max() for K in fresh.K) or 1.0
    err = max(np.abs(a - b).max() for a, b in zip(fresh.K, table.K, strict=True)) / scale
    model = max(np.abs(getattr(fresh, m) - getattr(table, m)).max() for m in ("F", "B", "H"))
    checks = [Check("gains match the spec", err <= rtol and model <= rtol,
                    f"max relative gain difference {err:.2e}, model difference {model:.2e}, tolerance {rtol:g}")]
    if spec.sha256 and table.provenance.get("spec_sha256") not in ("", spec.sha256):
        checks.append(Check("spec hash (note)", True, "the spec file differs from the one the table was designed "
                            "from (same gains, so only comments or formatting changed)"
                            if checks[0].ok else "the spec file differs from the one the table was designed from"))
    return checks


def verify_table(table, spec=None, rtol: float = 1e-9) -> list:
    """All checks for ``table`` (and ``spec`` when given), as a list of :class:`Check`."""
    checks = [*_complementarity(table), _stability(table)]
    if spec is not None:
        checks += _same_design(table, spec, rtol)
    return checks
