"""The Python runtime: run a designed filter (a GainTable) on sensor readings.

numpy only; scipy.signal.lfilter is imported lazily by the fast batch path.  The filter is
the table's observer, in its named gain form (seed 001 eq. (25); DESIGN.md):

* ``predictor``:  ``est[k] = x[k][0]``;  ``x[k+1] = F x[k] + B u[k] + K[k] (y[k] - H x[k])``
* ``filter``:     ``x+ = x[k] + K[k] (y[k] - H x[k])``;  ``est[k] = x+[0]``;
  ``x[k+1] = F x+ + B u[k]``

with ``k`` counting base-rate steps and ``K[k]`` the gain of phase ``k mod period``.

Missing readings (a NaN, or a sensor left out of ``step``): a missing measurement
contributes nothing at that step (its gain column is skipped); a missing input holds the
last input received (zero before the first).  At phases where the table schedules no
reading of a sensor its gain column is zero, so a reading given there has no effect.
Angle tables (``wrap_angle``) wrap every innovation of an angle sensor and the estimate to
(-pi, pi], so a compass crossing +-180 deg does not jolt the estimate.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import CfdesignError

__all__ = ["Runtime", "wrap"]

#: block length of the vectorised batch path (a multiple of the period is used)
_BLOCK = 64


def wrap(angle):
    """Wrap angles (rad) to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2 * np.pi)


def _wrap_scalar(a: float) -> float:
    return math.pi - math.fmod(math.fmod(math.pi - a, 2 * math.pi) + 2 * math.pi, 2 * math.pi)


class Runtime:
    """A running filter built from a :class:`~cfdesign.gains.GainTable`.

    Parameters
    ----------
    table : GainTable
        A discrete table (``domain = 'z'``).
    x0 : array_like, optional
        Initial state (default zeros).

    Examples
    --------
    >>> rt = Runtime(table)                          # doctest: +SKIP
    >>> rt.step(gyro=0.01, compass=0.3, odometry=0.29)   # streaming, one sample
    >>> est = rt.run({"gyro": w, "compass": c, "odometry": o})   # whole arrays
    """

    def __init__(self, table, x0=None):
        if table.domain != "z":
            raise CfdesignError(f"{table.name} is a continuous-time table; the runtime runs discrete tables "
                                "(design a discrete structure: dckf3, position, or cf2/cf3/cfn with discrete = true)")
        self.table = table
        self.F, self.B, self.H = (np.array(m, dtype=float) for m in (table.F, table.B, table.H))
        self.K = [np.array(k, dtype=float) for k in table.K]
        self.n, self.period, self.form = self.F.shape[0], len(self.K), table.gain_form
        by_index = sorted(table.sensors, key=lambda s: s["index"])
        self.inputs = [s["name"] for s in by_index if s["role"] == "input"]
        self.measurements = [s["name"] for s in by_index if s["role"] == "measurement"]
        angle = {s["name"] for s in table.sensors if s["order"] == 0}
        self._wrap_rows = np.array([bool(table.wrap_angle) and m in angle for m in self.measurements])
        self._x0 = np.zeros(self.n) if x0 is None else np.array(x0, dtype=float).reshape(self.n)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self):
        """Back to the initial state, phase 0, no input received."""
        self.x = self._x0.copy()
        self.phase = 0
        self.u_last = np.zeros(len(self.inputs))

    def state(self) -> dict:
        """A JSON-ready snapshot (``x``, ``phase``, ``u_last``) for :meth:`restore`."""
        return {"x": self.x.tolist(), "phase": int(self.phase), "u_last": self.u_last.tolist()}

    def restore(self, state: dict):
        """Continue from a snapshot taken with :meth:`state`."""
        x = np.array(state["x"], dtype=float)
        if x.shape != (self.n,) or not 0 <= int(state["phase"]) < self.period:
            raise CfdesignError(f"state does not fit {self.table.name}: x must have {self.n} entries and "
                                f"0 <= phase < {self.period}")
        self.x, self.phase = x, int(state["phase"])
        self.u_last = np.array(state["u_last"], dtype=float).reshape(len(self.inputs))

    # ------------------------------------------------------------------ streaming
    def step(self, **readings) -> float:
        """Advance one base-rate step; returns the estimate of the common quantity at this step."""
        unknown = set(readings) - set(self.inputs) - set(self.measurements)
        if unknown:
            raise CfdesignError(f"unknown sensor(s) {', '.join(sorted(unknown))}; "
                                f"{self.table.name} reads {', '.join(self.inputs + self.measurements)}")
        u = np.array([readings.get(name, np.nan) for name in self.inputs], dtype=float)
        u = np.where(np.isnan(u), self.u_last, u)
        y = np.array([readings.get(name, np.nan) for name in self.measurements], dtype=float)
        est = self._advance(u, y)
        self.u_last = u
        return est

    def _advance(self, u, y) -> float:
        x, K = self.x, self.K[self.phase]
        seen = ~np.isnan(y)
        innovation = np.where(seen, y - self.H @ x, 0.0)
        if self._wrap_rows.any():
            innovation = np.where(self._wrap_rows, wrap(innovation), innovation)
        correction = K[:, seen] @ innovation[seen]
        if self.form == "filter":
            post = x + correction
            est = post[0]
            x = self.F @ post + self.B @ u
        else:
            est = x[0]
            x = self.F @ x + self.B @ u + correction
        if self.table.wrap_angle:
            x[0], est = _wrap_scalar(x[0]), _wrap_scalar(est)
        self.x, self.phase = x, (self.phase + 1) % self.period
        return float(est)

    # ------------------------------------------------------------------ batch
    def run(self, readings: dict, *, states: bool = False):
        """Run on whole arrays ``{sensor: (N,) array}``; the state carries over between calls.

        Every sensor must be present (use NaN for missing samples).  Returns the (N,)
        estimates, or ``(estimates, x)`` with the (N, n) states ``x[k]`` before step ``k``
        when ``states`` is true.  Without NaNs the work is vectorised (see
        :meth:`_run_vectorised`); with NaNs it is a loop of :meth:`step`.
        """
        cols = self._columns(readings)
        if any(np.isnan(c).any() for c in cols):
            return self._run_loop(*self._split(cols), states)
        if self.period == 1 and not states and len(cols[0]):
            lti = _LtiBands.of(self)
            if lti is not None:
                return lti.run(self, self._unwrapped_columns(cols))
        return self._run_vectorised(*self._split(cols), states)

    def _columns(self, readings) -> list:
        """One contiguous float array per sensor: inputs (by column of B), then measurements."""
        names = self.inputs + self.measurements
        missing = [n for n in names if n not in readings]
        if missing:
            raise CfdesignError(f"no readings for {', '.join(missing)} (use NaN for missing samples)")
        cols = [np.ascontiguousarray(readings[n], dtype=float).reshape(-1) for n in names]
        if len({len(c) for c in cols}) > 1:
            lengths = ", ".join(f"{n}: {len(c)}" for n, c in zip(names, cols, strict=True))
            raise CfdesignError(f"readings differ in length ({lengths})")
        return cols

    def _split(self, cols):
        N, p = len(cols[0]), len(self.inputs)
        u = np.column_stack(cols[:p]) if p else np.zeros((N, 0))
        y = np.column_stack(cols[p:]) if len(cols) > p else np.zeros((N, 0))
        return u, y

    def _run_loop(self, u, y, states):
        N = len(u)
        est, xs = np.empty(N), np.empty((N, self.n))
        for k in range(N):
            xs[k] = self.x
            uk = np.where(np.isnan(u[k]), self.u_last, u[k])
            est[k] = self._advance(uk, y[k])
            self.u_last = uk
        return (est, xs) if states else est

    def _run_vectorised(self, u, y, states):
        """Blocked form of the recursion: block-boundary states by ``lfilter`` on the lifted
        system ``x[(p+1)L] = A^L x[pL] + c[p]``, then the ``L`` phases of every block at
        once, vectorised over the blocks (``L`` a multiple of the period)."""
        N = len(u)
        if N == 0:
            return (np.empty(0), np.empty((0, self.n))) if states else np.empty(0)
        y = self._unwrapped(y)
        L = self.period * max(1, _BLOCK // self.period)
        P = -(-N // L)
        pad = P * L - N
        A = self._phase_maps(L)
        W = np.concatenate([np.hstack([u, y]), np.zeros((pad, u.shape[1] + y.shape[1]))])
        W = W.reshape(P, L, -1)
        G = [np.hstack([self.B, self._input_gain(j)]) for j in range(L)]
        Phi, C = self._lift(A, G, W)
        X = _boundary_states(Phi, C, self.x)  # (P, n): x at the start of every block
        est, xs = np.empty((P, L)), np.empty((P, L, self.n))
        for j in range(L):
            xs[:, j] = X
            yj = W[:, j, u.shape[1]:]
            if self.form == "filter":
                Kj = self.K[(self.phase + j) % self.period]
                est[:, j] = (X + (yj - X @ self.H.T) @ Kj.T)[:, 0]
            else:
                est[:, j] = X[:, 0]
            X = X @ A[j].T + W[:, j] @ G[j].T
        est, xs = est.reshape(-1)[:N], xs.reshape(-1, self.n)[:N]
        self._finish(xs[-1], u[-1], y[-1], N)
        if self.table.wrap_angle:
            est, xs[:, 0] = wrap(est), wrap(xs[:, 0])
        return (est, xs) if states else est

    def _finish(self, x_last, u_last, y_last, N):
        """State after the batch: one more exact step from the last stored state."""
        self.x, self.phase = x_last.copy(), (self.phase + N - 1) % self.period
        self._advance(u_last, y_last)
        self.u_last = u_last.copy()

    def _phase_maps(self, L):
        """Closed-loop state matrix of each phase of a block (offset by the current phase)."""
        out = []
        for j in range(L):
            K = self.K[(self.phase + j) % self.period]
            out.append(self.F @ (np.eye(self.n) - K @ self.H) if self.form == "filter" else self.F - K @ self.H)
        return out

    def _input_gain(self, j):
        K = self.K[(self.phase + j) % self.period]
        return self.F @ K if self.form == "filter" else K

    def _lift(self, A, G, W):
        """``Phi = A[L-1]...A[0]`` and ``c[p] = sum_j A[L-1]...A[j+1] G[j] w[pL+j]``."""
        L = len(A)
        M = [None] * L
        acc = np.eye(self.n)
        for j in reversed(range(L)):
            M[j] = acc @ G[j]
            acc = acc @ A[j]
        return acc, np.einsum("jnq,pjq->pn", np.array(M), W)

    def _unwrapped(self, y):
        """Angle readings made continuous and brought within pi of the current estimate."""
        if not self._wrap_rows.any():
            return y
        p = len(self.inputs)
        cols = self._unwrapped_columns([*np.zeros((p, len(y))), *y.T])
        return np.column_stack(cols[p:])

    def _unwrapped_columns(self, cols):
        p = len(self.inputs)
        out = list(cols)
        for i in np.flatnonzero(self._wrap_rows):
            col = _unwrap(out[p + i])
            shift = 2 * np.pi * np.round((col[0] - (self.H @ self.x)[i]) / (2 * np.pi))
            out[p + i] = col - shift if shift else col
        return out


class _LtiBands:
    """A single-rate table as IIR filters, one per sensor, through scipy's lfilter.

    The band of input ``j`` is ``num_j / den`` with ``den = det(zI - A)`` and
    ``num_j = C_o adj(zI - A) G_j + D_j den``.  lfilter's direct-form-II-transposed state is
    the observable canonical state ``z = T x`` of this realisation, with rows
    ``T_i = C_o (A^(i-1) + a_1 A^(i-2) + ... + a_(i-1) I)``; so the filter starts from
    ``zi = T x0`` and hands back ``x = T^-1 sum_j zf_j``, exactly the state the streaming
    recursion would hold.  Tables whose ``(A, C_o)`` is badly observable (``T`` ill
    conditioned) use the blocked path instead.
    """

    def __init__(self, den, nums, T, Tinv):
        self.den, self.nums, self.T, self.Tinv = den, nums, T, Tinv

    @classmethod
    def of(cls, rt):
        cached = getattr(rt, "_lti", False)
        if cached is not False:
            return cached
        n, K = rt.n, rt.K[0]
        A = rt._phase_maps(1)[0]
        G = np.hstack([rt.B, rt._input_gain(0)])
        Co = (np.eye(n) - K @ rt.H)[0] if rt.form == "filter" else np.eye(n)[0]
        D = np.concatenate([np.zeros(rt.B.shape[1]), K[0] if rt.form == "filter" else np.zeros(K.shape[1])])
        den = np.poly(A).real
        adj = _adjugate_coefficients(A, den)
        nums = [np.concatenate([[D[j]], [Co @ adj[k] @ G[:, j] + D[j] * den[k + 1] for k in range(n)]])
                for j in range(G.shape[1])]
        T = np.array([Co @ _adjugate_coefficients(A, den)[i] for i in range(n)])
        lti = None
        if np.linalg.cond(T) < 1e8:
            lti = cls(den, nums, T, np.linalg.inv(T))
        rt._lti = lti
        return lti

    def run(self, rt, cols):
        from scipy.signal import lfilter

        zf = np.zeros(len(self.den) - 1)
        est = None
        for j, (num, col) in enumerate(zip(self.nums, cols, strict=True)):
            zi = self.T @ rt.x if j == 0 else np.zeros_like(zf)
            out, z = lfilter(num, self.den, col, zi=zi)
            est = out if est is None else np.add(est, out, out=est)
            zf += z
        rt.x = self.Tinv @ zf
        rt.phase, rt.u_last = 0, np.array([c[-1] for c in cols[: len(rt.inputs)]])
        if rt.table.wrap_angle:
            rt.x[0] = _wrap_scalar(rt.x[0])
            if est.min() <= -np.pi or est.max() > np.pi:
                np.subtract(np.pi, est, out=est)  # wrap in place: pi - mod(pi - a, 2 pi)
                np.mod(est, 2 * np.pi, out=est)
                np.subtract(np.pi, est, out=est)
        return est


def _unwrap(col):
    """``np.unwrap`` for sparse jumps: only the samples after a jump of more than pi move."""
    d = np.diff(col)
    jumps = np.flatnonzero(np.abs(d) > np.pi)
    if not jumps.size:
        return col
    shifts = -2 * np.pi * np.round(d[jumps] / (2 * np.pi))
    if jumps.size > 3:
        edges = np.concatenate([[0], jumps + 1, [len(col)]])
        return col + np.repeat(np.concatenate([[0.0], np.cumsum(shifts)]), np.diff(edges))
    col = col.copy()
    for j, shift in zip(jumps, shifts, strict=True):  # a few jumps: shift each tail in place
        col[j + 1:] += shift
    return col


def _boundary_states(Phi, C, x0):
    """``X[p+1] = Phi X[p] + C[p]``, ``X[0] = x0``, for all p at once with scipy's lfilter."""
    from scipy.signal import lfilter

    n, P = len(x0), len(C)
    den = np.poly(Phi).real
    # Z[k+1] = Phi Z[k] + S[k], Z[0] = 0, S = [x0, C[0], C[1], ...]: then X[p] = Z[p + 1]
    S = np.vstack([x0[None, :], C])
    out = np.zeros((P + 1, n))
    adj = _adjugate_coefficients(Phi, den)  # (zI - Phi)^-1 = sum_i adj[i] z^(n-1-i) / den
    for i in range(n):
        for j in range(n):
            num = np.concatenate([[0.0], adj[:, i, j]])
            out[:, i] += lfilter(num, den, S[:, j])
    return out[1:]


def _adjugate_coefficients(Phi, den):
    """Coefficients (highest power first) of adj(zI - Phi) by the Faddeev-LeVerrier recursion."""
    n = len(Phi)
    coeffs = np.empty((n, n, n))
    M = np.eye(n)
    coeffs[0] = M
    for k in range(1, n):
        M = Phi @ M + den[k] * np.eye(n)
        coeffs[k] = M
    return coeffs
