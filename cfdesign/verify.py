"""Re-check a gain table numerically: complementarity, stability and (with the spec) the gains.

``verify`` walks the design path backwards: from the table's own ``F, B, H, K``
and sensor relations it rebuilds every band numerically and checks

(a) complementarity: ``sum_i T_i = 1`` as an exact polynomial identity (coefficients within
    ``1e-12`` relative) at every phase, and over a frequency grid for single-rate tables;
(b) stability: the closed-loop poles of a single-rate table, or the monodromy multipliers
    of a periodic one, strictly inside the unit circle (left half-plane when continuous).
    The phases of a multirate table between measurements are open loop (eigenvalues on the
    unit circle) by design, so the monodromy is what must be stable;
(c) with the spec: re-designing from it gives the same gains (``rtol``).

Band of sensor ``j``: ``T_j = (C_o adj(vI - A) G_j + D_j den) / den * rel_j``
(docs/derivations.md, "One observer"), with ``rel_j = v**order`` (continuous) or the ZOH
chain relation ``N_order / N_0`` (discrete), all from :mod:`cfdesign.linear`.  numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import linear

__all__ = ["Check", "verify_table", "band_polynomials", "phase_realisation"]

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


def phase_realisation(table, phase: int = 0, output: str | None = None):
    """One phase of ``table`` as a :class:`cfdesign.linear.Realisation` (default: the output the
    table declares)."""
    output = table.output if output is None else output
    return linear.realisation(table.F, table.B, table.H, table.K[phase], table.gain_form, output)


def band_polynomials(table, phase: int = 0, output: str | None = None):
    """``({sensor: (num, den)}, den_cl)``: every band of one phase as polynomials (highest first)."""
    orders = {s.order for s in table.sensors}
    relations = linear.chain_relations(orders, table.domain, table.sample_time_s)
    return linear.band_polynomials(phase_realisation(table, phase, output), table.sensors, relations)


def _grid_error(table, bands) -> float:
    dt = table.sample_time_s
    w = np.logspace(-4, np.log10(np.pi / dt if dt else 1e4), 400) if dt else np.logspace(-4, 4, 400)
    total = sum(linear.response(num, den, w, dt) for num, den in bands.values())
    return float(np.abs(total - 1).max())


def _complementarity(table) -> list:
    worst, worst_phase = 0.0, 0
    for k in range(len(table.K)):
        residual = linear.identity_residual(band_polynomials(table, k)[0])
        if residual > worst:
            worst, worst_phase = residual, k
    ok = worst <= IDENTITY_RTOL
    where = f" (worst at phase {worst_phase})" if len(table.K) > 1 else ""
    checks = [Check("complementary (polynomial identity)", ok,
                    f"sum of the {table.output} output's bands - 1 has relative coefficient size {worst:.2e}{where}, "
                    f"tolerance {IDENTITY_RTOL:g}")]
    if len(table.K) == 1:
        err = _grid_error(table, band_polynomials(table, 0)[0])
        checks.append(Check("complementary (frequency grid)", err <= GRID_ATOL,
                            f"max |sum of bands - 1| = {err:.2e} over 400 frequencies, tolerance {GRID_ATOL:g}"))
    return checks


def _stability(table) -> Check:
    maps = [linear.closed_loop(table.F, table.H, K, table.gain_form) for K in table.K]
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
