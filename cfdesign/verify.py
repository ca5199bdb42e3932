"""Re-check a gain table numerically: complementarity, stability and (with the spec) the gains.

``verify`` walks the design path backwards: from the table's own ``F, B, H, K``
and sensor relations it rebuilds every band numerically and checks

(a) complementarity: ``sum_i T_i = 1`` as an exact polynomial identity (coefficients within
    ``1e-12`` relative) at every phase, and over a frequency grid for single-rate tables
    (responses from the state-space form, error relative to the size of the cancelling
    terms, so that it holds at high sample rates as well).  High-degree coefficients carry
    rounding errors far above ``1e-12`` (an n = 20 chain at 100 Hz: 4e-4); a residual within
    ten times its rounding estimate (the bands recomputed with the states in reverse order)
    FAILs with "cannot be decided in double precision", never PASSes;
(b) stability: the closed-loop poles of a single-rate table, or the monodromy multipliers
    of a periodic one, strictly inside the unit circle (left half-plane when continuous).
    The phases of a multirate table between measurements are open loop (eigenvalues on the
    unit circle) by design, so the monodromy is what must be stable;
(c) covariances: ``P`` and ``P_filtered``, behind every predicted standard deviation, satisfy
    the Lyapunov recursion of the table's own gains (:func:`covariance_check`);
(d) rates (discrete tables): each sensor's ``rate_hz`` is the rate at which the schedule reads it,
    evenly spaced (:func:`rate_check`);
(e) with the spec: re-designing from it gives the same gains (``rtol``).

Band of sensor ``j``: ``T_j = (C_o adj(vI - A) G_j + D_j den) / den * rel_j``
(docs/derivations.md, "One observer"), with ``rel_j = v**order`` (continuous) or the ZOH
chain relation ``N_order / N_0`` (discrete), all from :mod:`cfdesign.linear`.  numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

from . import linear
from .errors import InputError

__all__ = ["Check", "verify_table", "numeric_checks", "covariance_check", "rate_check", "band_polynomials",
           "phase_realisation", "frequency_grid", "polynomial_error"]

IDENTITY_RTOL = 1e-12
GRID_RTOL = 1e-9


@dataclass(frozen=True)
class Check:
    """One verification result.

    Attributes
    ----------
    name : str
        What was checked (``complementary (polynomial identity)``, ``stable (closed-loop
        poles)``, ``same gains as the spec``, ...).
    ok : bool
        The check holds.
    detail : str
        One line: the measured figure and its tolerance, or what differs (the gain, entry and
        phase).
    """

    name: str
    ok: bool
    detail: str

    def line(self) -> str:
        """The check as one line of ``cfdesign verify``'s output.

        Returns
        -------
        str
            ``PASS name: detail`` or ``FAIL name: detail``.
        """
        return f"{'PASS' if self.ok else 'FAIL'} {self.name}: {self.detail}"


def phase_realisation(table, phase: int = 0, output: str | None = None):
    """One phase of a table as a :class:`cfdesign.linear.Realisation`.

    Parameters
    ----------
    table : GainTable
        The gain table whose realisation is wanted.
    phase : int
        Phase of the gain schedule.
    output : {'posterior', 'prior'}, optional
        The estimate realised (default: the one the table declares).

    Returns
    -------
    cfdesign.linear.Realisation
        The matrices ``A, G, C, D`` of the phase.
    """
    output = table.output if output is None else output
    return linear.realisation(table.F, table.B, table.H, table.K[phase], table.gain_form, output)


def band_polynomials(table, phase: int = 0, output: str | None = None):
    """Every band of one phase as polynomials in ``s`` or ``z`` (highest power first).

    Parameters
    ----------
    table : GainTable
        The gain table whose bands are wanted.
    phase : int
        Phase of the gain schedule.
    output : {'posterior', 'prior'}, optional
        The estimate whose bands to give (default: the one the table declares).

    Returns
    -------
    bands : dict
        ``{sensor: (num, den)}`` coefficient arrays.
    den : ndarray
        The closed-loop denominator every band shares.

    Examples
    --------
    >>> import cfdesign
    >>> from cfdesign.verify import band_polynomials
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> bands, den = band_polynomials(table)
    >>> sorted(bands), den.round(4).tolist()
    (['compass', 'gyro_heading', 'odometry_rate'], [1.0, -1.346, 0.5067])
    """
    return linear.band_polynomials(phase_realisation(table, phase, output), table.sensors, _relations(table))


def _relations(table) -> dict:
    """:func:`cfdesign.linear.chain_relations` of the table's sensors: the same for every phase and
    every check, computed once (``O(n^3)`` per sensor order for an ``n``-chain)."""
    return _chain_relations(frozenset(s.order for s in table.sensors), table.domain, table.sample_time_s)


@lru_cache(maxsize=8)
def _chain_relations(orders: frozenset, domain: str, dt) -> dict:
    return linear.chain_relations(orders, domain, dt)


def frequency_grid(table, points: int = 400) -> np.ndarray:
    """Frequencies of the grid check.

    Log-spaced from ``1e-3`` times the slowest closed-loop pole (or ``1e-4`` rad/s) to just
    below Nyquist (discrete: the ZOH relation of an acceleration sensor has a pole at
    ``z = -1``) or ``1e3`` times the fastest pole (continuous).

    Parameters
    ----------
    table : GainTable
        The gain table whose bands the grid must resolve.
    points : int
        Number of frequencies.

    Returns
    -------
    ndarray, shape (points,)
        Angular frequencies (rad/s), ascending.
    """
    dt = table.sample_time_s
    eig = np.linalg.eigvals(linear.closed_loop(table.F, table.H, table.K[0], table.gain_form))
    rates = np.abs(np.log(eig[np.abs(eig) > 0].astype(complex))) / dt if dt else np.abs(eig)
    rates = rates[rates > 0]
    lo = min(1e-4, 1e-3 * rates.min()) if rates.size else 1e-4
    hi = 0.999 * np.pi / dt if dt else max(1e4, 1e3 * rates.max(initial=0.0))
    return np.logspace(np.log10(lo), np.log10(hi), points)


def polynomial_error(table, output: str | None = None) -> tuple:
    """How far the bands' polynomials (:func:`band_polynomials`) are from the bands themselves.

    The expanded polynomials lose the closed-loop dynamics when the poles sit within rounding
    of ``z = 1`` (a crossover at 5e-9 of the sample rate: the constant coefficient ``1 - k1 +
    k2 T`` keeps no digit of ``k2 T``), while the state-space responses
    (:func:`cfdesign.linear.band_responses`) keep them.  The two are compared on
    :func:`frequency_grid`, the difference relative to the size of the bands there.

    Parameters
    ----------
    table : GainTable
        A single-rate table.
    output : {'posterior', 'prior'}, optional
        The estimate (default: the one the table declares).

    Returns
    -------
    error : float
        ``max |T_poly - T| / (1 + sum_i |T_i|)`` over the grid and the bands (``inf`` where a
        band cannot be evaluated).
    omega : float
        The angular frequency (rad/s) of the largest difference.
    """
    omega = frequency_grid(table)
    dt = table.sample_time_s if table.domain == "z" else None
    exact = linear.band_responses(phase_realisation(table, 0, output), table.sensors, table.domain, dt, omega)
    size = 1.0 + sum(np.abs(r) for r in exact.values())
    worst = np.zeros(len(omega))
    with np.errstate(all="ignore"):
        for name, (num, den) in band_polynomials(table, 0, output)[0].items():
            diff = np.abs(linear.response(num, den, omega, dt) - exact[name]) / size
            worst = np.maximum(worst, np.where(np.isfinite(diff), diff, np.inf))
    i = int(np.argmax(worst))
    return float(worst[i]), float(omega[i])


def _grid_error(table, phase: int = 0) -> float:
    """:func:`cfdesign.linear.complementarity_error` of the table's bands on :func:`frequency_grid`."""
    responses = linear.band_responses(phase_realisation(table, phase), table.sensors, table.domain,
                                      table.sample_time_s, frequency_grid(table))
    return linear.complementarity_error(responses)


def _rounding_spread(table, phase: int) -> float:
    """Rounding-error estimate of the identity residual of one phase.

    The bands are computed a second time from the realisation with its states in reverse
    order (the same bands in exact arithmetic, rounded differently); the largest coefficient
    of the difference of the two residual polynomials, relative to the size of the terms,
    estimates how much of the residual is rounding.  A residual that is not well above it
    cannot tell a complementary table from one that is not.
    """
    real = phase_realisation(table, phase)
    r = slice(None, None, -1)
    flipped = linear.Realisation(real.A[r][:, r], real.G[r], real.C[:, r], real.D, real.output,
                                 None if real.delta is None else real.delta[r][:, r])
    with np.errstate(all="ignore"):
        t0, s0 = linear.identity_polynomial(linear.band_polynomials(real, table.sensors, _relations(table))[0])
        t1, s1 = linear.identity_polynomial(linear.band_polynomials(flipped, table.sensors, _relations(table))[0])
        spread = np.abs(np.polysub(t0, t1)).max(initial=0.0) / max(s0, s1)
    return float(spread) if np.isfinite(spread) else np.inf


#: a residual within this factor of its rounding-error estimate cannot be told from rounding
_UNDECIDED_FACTOR = 10.0


def _complementarity(table) -> list:
    """The identity check of every phase; a phase's bands depend on ``F, B, H`` and its own
    ``K[k]`` only, so phases with the same gain matrix (a long period's many phases without a
    reading, all ``K = 0``) are checked once, at their first phase."""
    worst, worst_phase, seen = 0.0, 0, set()
    for k in range(len(table.K)):
        key = np.ascontiguousarray(table.K[k], dtype=float).tobytes()
        if key in seen:
            continue
        seen.add(key)
        with np.errstate(over="ignore", invalid="ignore"):
            residual = linear.identity_residual(band_polynomials(table, k)[0])
        if not residual <= worst:
            worst, worst_phase = residual, k
    ok = worst <= IDENTITY_RTOL
    where = f" (worst at phase {worst_phase})" if len(table.K) > 1 else ""
    size = f"{worst:.2e}" if np.isfinite(worst) else "not finite (the coefficients overflow)"
    detail = (f"sum of the {table.output} output's bands - 1 has relative coefficient size {size}{where}, "
              f"tolerance {IDENTITY_RTOL:g}")
    if not ok:
        spread = _rounding_spread(table, worst_phase)
        if not worst > _UNDECIDED_FACTOR * spread:
            detail += (f"; cannot be decided in double precision: the coefficients' rounding error is about "
                       f"{spread:.1e} (two equivalent state orders differ by that much); the frequency-grid check "
                       f"decides")
    checks = [Check("complementary (polynomial identity)", ok, detail)]
    if len(table.K) == 1:
        err = _grid_error(table)
        detail = (f"max |sum of bands - 1| / (1 + sum |band|) = {err:.2e} over 400 frequencies, tolerance {GRID_RTOL:g}"
                  if np.isfinite(err) else "cannot be evaluated accurately: a band is beyond the double range on "
                  "the grid (the sensor relations of this chain order over- or underflow)")
        checks.append(Check("complementary (frequency grid)", err <= GRID_RTOL, detail))
    return checks


def _stability(table) -> Check:
    if table.domain == "s":
        eig = _eigvals(linear.closed_loop(table.F, table.H, table.K[0], table.gain_form))
        margin = eig.real.max()
        return Check("stable (closed-loop poles)", bool(margin < 0), f"max real part {margin:.6g}")
    what = "closed-loop poles" if len(table.K) == 1 else "monodromy multipliers"
    margin = linear.loop_radius(table.F, table.H, table.K, table.gain_form)
    return Check(f"stable ({what})", bool(margin < 1), f"spectral radius {margin:.6g}")


#: relative residual up to which ``P`` and ``P_filtered`` count as the gains' own covariances:
#: Riccati and Lyapunov solutions leave ~1e-15; an edited gain leaves its relative change
COVARIANCE_RTOL = 1e-7


def covariance_check(table) -> Check:
    """Are ``P`` and ``P_filtered`` the error covariances of the table's own gains?

    The predicted standard deviations (``cfdesign design``, ``--std`` columns, the plot's
    ±2σ band) come from ``P``; a gain edited after the design leaves them stale.  Each phase
    ``k`` of a discrete table must satisfy the Lyapunov recursion of its gain (prior, then
    Joseph-form posterior, :func:`cfdesign.linear.posterior_covariance`)::

        P[k+1] = (F - Kp_k H_k) P[k] (F - Kp_k H_k)' + Kp_k R_k Kp_k' + Q
        P_filtered[k] = (I - L_k H_k) P[k] (I - L_k H_k)' + L_k R_k L_k'

    and a continuous one ``(F - K H) P + P (F - K H)' + Q + K R K' = 0``; ``(Kp_k, L_k)`` from
    :func:`cfdesign.linear.gain_pair`, ``H_k, R_k`` the rows measured at phase ``k``.  The
    residual is a backward error: its Frobenius norm relative to the norms of the terms
    (``2 |A| |P| + |W|`` for the continuous equation), within ``COVARIANCE_RTOL`` (1e-7).

    Parameters
    ----------
    table : GainTable
        The table to check.

    Returns
    -------
    Check
        ``covariances of these gains``: the worst relative residual and where.
    """
    worst, where = 0.0, ""
    Q, R = np.asarray(table.Q, dtype=float), np.asarray(table.R, dtype=float)
    norm = np.linalg.norm
    for k in range(table.period):
        F, _, H, K = table.phase_model(k)
        rows = list(table.schedule.rows(k))
        Rk, P = R[np.ix_(rows, rows)], np.asarray(table.P[k], dtype=float)
        if table.domain == "s":
            A, W = F - K @ H, Q + K @ Rk @ K.T
            terms = [(A @ P + P @ A.T + W, 2 * norm(A) * norm(P) + norm(W), "P")]
        else:
            Kp, L = linear.gain_pair(F, K, table.gain_form)
            A, W = F - Kp @ H, Kp @ Rk @ Kp.T + Q
            nxt = (k + 1) % table.period
            terms = [(A @ P @ A.T + W - table.P[nxt], norm(A) ** 2 * norm(P) + norm(W) + norm(table.P[nxt]),
                      f"P[{nxt}]")]
            if L is None:
                post, size = P, norm(P)
            else:
                IKH = np.eye(len(P)) - L @ H
                post = linear.posterior_covariance(P, H, L, Rk)
                size = norm(IKH) ** 2 * norm(P) + norm(L) ** 2 * norm(Rk)
            terms.append((post - table.P_filtered[k], size + norm(table.P_filtered[k]), f"P_filtered[{k}]"))
        for residual, scale, name in terms:
            error = norm(residual) / scale if scale != 0 else 0.0  # a NaN scale stays NaN
            if not error <= worst:  # NaN counts as the worst
                worst, where = error, name
    ok = bool(worst <= COVARIANCE_RTOL)
    detail = f"relative residual {worst:.3g}{' at ' + where if where else ''}, tolerance {COVARIANCE_RTOL:g}"
    if not ok:
        detail += (": the predicted standard deviations are not those of these gains (a gain edited after "
                   "the design, or P computed inaccurately)")
    return Check("covariances of these gains", ok, detail)


#: relative difference allowed between a sensor's ``rate_hz`` and the rate its schedule reads it at:
#: the designer takes a rate within 1e-9 of a fraction of the base rate; the rest is rounding of ``T``
RATE_RTOL = 1e-8


def rate_check(table) -> Check:
    """Do the sensors' declared rates (``rate_hz``) match the schedule that reads them?

    The runtime reads a measurement at the phases of the table's schedule, and its noise
    figures (``Q``, ``R``) were converted at its ``rate_hz``; a table whose ``rate_hz`` says
    one rate and whose schedule another runs a filter designed for neither.  A measurement
    read ``n`` times in a period of ``N`` phases of ``T`` seconds runs at ``n / (N T)`` Hz,
    evenly: the gaps between its reads (around the period) are ``N/n`` phases, or the two
    whole numbers either side of it when ``N/n`` is a fraction (a 3 Hz GPS beside a 100 Hz
    IMU: 33 and 34); an input is read at every tick, ``1 / T`` Hz.  Gain tables record no
    sensor offsets, so the phase of the first read is free.

    Parameters
    ----------
    table : GainTable
        The table to check.

    Returns
    -------
    Check
        ``sensor rates match the schedule``: each sensor's declared rate, or what differs
        (the sensor, its declared rate and the schedule's rate or gaps), within
        ``RATE_RTOL`` (1e-8) relative.  A continuous table has no schedule: it passes.
    """
    name = "sensor rates match the schedule"
    if table.domain == "s":
        return Check(name, True, "a continuous table reads its sensors continuously; rate_hz only scales the "
                     "noise figures")
    wrong = [w for w in (_rate_mismatch(table, s) for s in table.sensors) if w]
    if wrong:
        return Check(name, False, "; ".join(wrong) + f" (tolerance {RATE_RTOL:g}): the table runs a sensor at "
                     "another rate than its noise figures were converted at")
    rates = ", ".join(f"{s.name} {s.rate_hz:g} Hz" for s in table.sensors)
    return Check(name, True, f"each sensor is read at its rate_hz ({rates}), tolerance {RATE_RTOL:g}")


def _rate_mismatch(table, sensor) -> str:
    """What differs between one sensor's ``rate_hz`` and its reads in the schedule; ``''`` if nothing."""
    T, N = table.sample_time_s, table.period
    if sensor.role == "input":
        reads, phases = N, tuple(range(N))
    else:
        phases = table.schedule.phases(sensor.name)
        reads = len(phases)
    actual = reads / (N * T)
    if not abs(sensor.rate_hz - actual) <= RATE_RTOL * max(sensor.rate_hz, actual):
        how = "an input, read at every tick" if sensor.role == "input" else \
            f"the schedule reads it at {reads} of {N} phases"
        return f"{sensor.name} declares {sensor.rate_hz:.10g} Hz, {how} of {T:g} s: {actual:.10g} Hz"
    step = Fraction(N, reads)
    gaps = sorted({(phases[(i + 1) % reads] - phases[i]) % N or N for i in range(reads)})
    if not set(gaps) <= {step.numerator // step.denominator, -(-step.numerator // step.denominator)}:
        return (f"{sensor.name} declares {sensor.rate_hz:.10g} Hz, a read every {float(step):g} phases; the schedule "
                f"reads it at {reads} of {N} phases, but with gaps of {', '.join(map(str, gaps))} phases")
    return ""


def _eigvals(M) -> np.ndarray:
    """Eigenvalues of ``M``; ``[inf]`` when it overflowed (a product of phases that grows without bound)."""
    return np.linalg.eigvals(M) if np.all(np.isfinite(M)) else np.array([np.inf])


#: what a gain table holds that changes what the runtime computes, besides the numbers (``states``
#: names the estimate columns and the references; whether the gains are Kalman gains decides
#: whether a log whose sensors arrive off the schedule gets gains recomputed from ``Q, R``)
_RUNNING_FIELDS = ("structure", "domain", "gain_form", "output", "wrap_angle", "sensors", "schedule", "states",
                   "kalman_gains")

#: matrices the runtime reads besides the gains: the model, the noise ``Q, R`` (gains recomputed
#: for another arrival pattern) and the covariances ``P, P_filtered`` (``--std`` and the plot's band)
_MODEL = ("F", "B", "H", "Q", "R")
_COVARIANCES = ("P", "P_filtered")


def _same_design(table, spec, rtol) -> list:
    """Re-design from ``spec`` and compare everything that changes what the table runs: the
    structure, gain form, output, wrap, sensor ports and their order, schedule, sample time,
    model and every gain; each difference is a FAIL naming the field (and the gain and phase)."""
    from .designer import design

    fresh = design(spec)
    checks = [Check(f"spec: {name}", False, _sensor_differences(table.sensors, fresh.sensors) if name == "sensors"
                    else f"the table has {_show(_field(table, name))}, the spec gives {_show(_field(fresh, name))}")
              for name in _RUNNING_FIELDS if _field(table, name) != _field(fresh, name)]
    if (table.sample_time_s is None) != (fresh.sample_time_s is None) or (
            table.sample_time_s and abs(table.sample_time_s - fresh.sample_time_s) > rtol * fresh.sample_time_s):
        checks.append(Check("spec: sample_time_s", False, f"the table has {table.sample_time_s!r} s, the spec gives "
                            f"{fresh.sample_time_s!r} s{_by(table.sample_time_s, fresh.sample_time_s)}"))
    if checks:  # different filters: comparing their numbers says nothing more
        return checks
    model = max(((_relative(getattr(fresh, m), getattr(table, m)), m) for m in _MODEL), key=lambda w: w[0])
    cov = max(((_relative(getattr(fresh, m)[k], getattr(table, m)[k]), f"{m}[{k}]") for m in _COVARIANCES
               for k in range(table.period)), key=lambda w: w[0])
    scale = max((np.abs(K).max(initial=0.0) for K in fresh.K), default=0.0)  # once: O(period), not per phase
    worst = max((_worst_gain(fresh, table, k, scale) for k in range(table.period)), key=lambda w: w[0])
    ok = max(model[0], cov[0], worst[0]) <= rtol
    detail = (f"max relative difference: gains {worst[0]:.2e}{worst[1]}; model {model[0]:.2e}"
              f"{_at(model)}; covariances {cov[0]:.2e}{_at(cov)}; tolerance {rtol:g}")
    checks = [Check("gains match the spec", ok, detail)]
    shown = _named_gains_differ(fresh.gains, table.gains, rtol)
    if shown:
        checks.append(Check("spec: gains (named)", False, shown))
    if spec.sha256 and table.provenance.get("spec_sha256") not in ("", spec.sha256):
        checks.append(Check("spec hash (note)", True, "the spec file differs from the one the table was designed "
                            "from (same gains, so only comments or formatting changed)"
                            if ok else "the spec file differs from the one the table was designed from"))
    return checks


def _named_gains_differ(spec_gains, table_gains, rtol) -> str:
    """What differs between the named gains a table shows (``gains``, what a reader of the JSON
    and ``cfdesign design`` see) and the spec's; empty when they agree within ``rtol``.  The
    runtime runs ``K``, so a ``gains`` edited apart from ``K`` shows one filter and runs another."""
    if set(spec_gains) != set(table_gains):
        return (f"the table names {', '.join(sorted(map(str, table_gains))) or 'no gains'}, the spec "
                f"{', '.join(sorted(spec_gains)) or 'no gains'}")
    for name in sorted(spec_gains):
        a, b = spec_gains[name], table_gains[name]
        if not abs(a - b) <= rtol * max(abs(a), abs(b)):
            return f"{name}: the table shows {b:.10g}, the spec gives {a:.10g}"
    return ""


def _field(table, name):
    return table.has_kalman_gains if name == "kalman_gains" else getattr(table, name)


def _at(worst) -> str:
    return f" (in {worst[1]})" if worst[0] > 0 else ""


def _relative(a, b) -> float:
    scale = max(np.abs(a).max(initial=0.0), 1e-300)
    return float(np.abs(a - b).max(initial=0.0) / scale)


def _worst_gain(fresh, table, k, scale) -> tuple:
    """``(relative difference, ' at ...')`` of the gain entry of phase ``k`` that differs most.

    ``scale`` is the largest gain entry of the spec's table over all phases (computed once by
    the caller, so comparing a period of N phases costs O(N), not O(N^2)).
    """
    A, B = fresh.K[k], table.K[k]
    tiny = 1e-15 * max(scale, 1e-300)  # relative to the spec's own entry (to the table's where the spec has 0)
    diff = np.abs(A - B) / np.where(np.abs(A) > tiny, np.abs(A), np.maximum(np.abs(B), tiny))
    if not diff.size or diff.max() == 0:
        return 0.0, ""
    i, j = np.unravel_index(np.argmax(diff), diff.shape)
    names = [g for g, v in fresh.gains.items() if fresh.period == 1 and v == A[i, j]]
    what = f" ({names[0]})" if len(names) == 1 else ""
    sensor = fresh.measurements[j].name
    phase = f"phase {k}, " if fresh.period > 1 else ""
    return float(diff[i, j]), (f" at K[{k}][{i},{j}]{what}: {phase}state {i}, {sensor}: table "
                               f"{B[i, j]:.10g}, spec {A[i, j]:.10g}")


def _by(a, b) -> str:
    """`` (relative difference +1.0e-09)`` between two numbers, or ``''`` where it is not defined."""
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and b:
        return f" (relative difference {(a - b) / b:+.1e})"
    return ""


def _sensor_differences(mine, theirs) -> str:
    """What differs between a table's sensors and the spec's, field by field (``compass rate_hz: the
    table has 5.000000005, the spec 5.0 (relative difference +1.0e-09)``).  Both lists in full, each
    rate as ``5 Hz``, hid a difference below the sixth digit: the two lists read the same."""
    ours, spec = {s.name: s for s in mine}, {s.name: s for s in theirs}
    parts = [f"the table has sensor {name}, the spec has none of that name" for name in ours if name not in spec]
    parts += [f"the spec has sensor {name}, the table has none of that name" for name in spec if name not in ours]
    for name in (n for n in ours if n in spec):
        for key in ("role", "index", "order", "rate_hz"):
            a, b = getattr(ours[name], key), getattr(spec[name], key)
            if a != b:
                parts.append(f"{name} {key}: the table has {a!r}, the spec {b!r}"
                             f"{_by(a, b) if key == 'rate_hz' else ''}")
    return "; ".join(parts) or f"the table has {_show(tuple(mine))}, the spec gives {_show(tuple(theirs))}"


def _show(value) -> str:
    if isinstance(value, tuple) and value and hasattr(value[0], "role"):
        return "sensors " + ", ".join(f"{s.name} ({s.role} {s.index}, order {s.order}, {s.rate_hz:g} Hz)"
                                      for s in value)
    if hasattr(value, "active"):
        return f"a schedule of period {value.period} reading " + "; ".join(
            f"{name} at phases {[k for k in range(value.period) if i in value.active[k]][:6]}"
            for i, name in enumerate(value.measurements))
    return repr(value)


def numeric_checks(table) -> list:
    """The checks the designer applies to every table it writes.

    Complementarity (polynomial identity within ``1e-12`` relative at every phase, frequency
    grid within ``1e-9``), stability (poles or monodromy multipliers) and the covariances of
    the gains (:func:`covariance_check`).

    Parameters
    ----------
    table : GainTable
        The gain table to check.

    Returns
    -------
    list of Check
        One result per check, in the order run.
    """
    return [*_complementarity(table), _stability(table), covariance_check(table)]


def verify_table(table, spec=None, rtol: float = 1e-9) -> list:
    """Every check of ``cfdesign verify``: complementarity, stability, covariances, rates and (with a spec) the gains.

    From the table's own ``F, B, H, K`` and sensor relations every band is rebuilt
    numerically: the bands must sum to one as a polynomial identity (coefficients within
    ``1e-12`` relative, every phase) and over a frequency grid (single-rate tables); the closed
    loop must be strictly stable (poles, or the monodromy multipliers of a multirate table);
    ``P`` must be the covariances of the gains (:func:`covariance_check`); a discrete table's
    sensors must be read at their ``rate_hz`` (:func:`rate_check`); with ``spec`` the table is
    re-designed and everything that changes what it runs (sensors, order, gain form, output,
    wrap, sample time, schedule, structure, gains) compared.

    Parameters
    ----------
    table : GainTable
        The table to check (:func:`~cfdesign.gains.load_gains` reads one).
    spec : FilterSpec, optional
        The design file the table should come from.
    rtol : float
        Relative tolerance of the gain, model and sample-time comparison.

    Returns
    -------
    list of Check
        One per check; a check that fails names the field, gain or phase.  No exception for
        a failed check: ``cfdesign verify`` exits 1 when any is not ``ok``.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    SpecError
        ``spec`` is not a FilterSpec (a path: read it with :func:`~cfdesign.spec.load_spec`), or
        re-designing from it fails (the spec does not fit a structure).
    InputError
        ``rtol`` is not a number from 0 up to (not including) 1.

    See Also
    --------
    cfdesign.testing.assert_complementary : the same checks as a test assertion.

    Examples
    --------
    >>> import cfdesign
    >>> from cfdesign.verify import verify_table
    >>> spec = cfdesign.load_spec(cfdesign.example_path("robot-heading"))
    >>> checks = verify_table(cfdesign.design(spec), spec)
    >>> all(c.ok for c in checks)
    True
    >>> print(checks[-1].line())  # doctest: +ELLIPSIS
    PASS ...
    """
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 <= rtol < 1:  # NaN too
        raise InputError(f"rtol (--rtol) must be a relative tolerance from 0 up to (not including) 1, got {rtol!r}: "
                         "NaN or inf passed tables that run another filter (a sample time 1.5 times the spec's)")
    from .gains import require_table
    from .spec import require_spec

    require_table(table, "verify_table")
    if spec is not None:
        require_spec(spec, "verify_table")
    checks = numeric_checks(table)
    if table.domain == "z":
        checks.append(rate_check(table))
    if spec is not None:
        checks += _same_design(table, spec, rtol)
    return checks
