r"""The Kalman filter of a table's model over the readings as they actually arrive.

A table's gains assume a periodic schedule.  A sensor whose rate drifts (a 1 Hz compass whose
clock runs 2 % fast) or whose readings straddle half a base tick has no periodic arrival
pattern: each new pattern would need its own periodic gains.  For such logs
:func:`cfdesign.logs.run_log` runs this instead: the Kalman filter of the table's own model
(``F, B, H, Q, R``) with the gain of each tick from the covariance recursion over the
readings present at that tick,

.. math::

    S = H_k P H_k^T + R_k,\quad L = P H_k^T S^{-1},\quad
    \hat x^+ = x + L (y_k - H_k x),\quad P^+ = (I - L H_k) P (I - L H_k)^T + L R_k L^T,

    x \leftarrow F \hat x^+ + B u,\qquad P \leftarrow F P^+ F^T + Q,

``H_k, R_k, y_k`` the rows of the sensors read at tick ``k`` (Joseph form for ``P^+``).  On a
periodic pattern the recursion converges to the table's periodic-DARE gains, so it is the
same filter where both apply; its covariances are the predicted errors of the ticks as they
happened.  The conventions are :class:`~cfdesign.runtime.Runtime`'s: the input ``u`` of tick
``k`` drives the step to ``k + 1``; a missing input holds the last one; a reading that is inf
or beyond :data:`~cfdesign.runtime.filter.READING_LIMIT` is missing and counted
(``rejected``); angle innovations and the estimate are wrapped with
:func:`cfdesign.linear.wrap` in angle tables.  numpy only.
"""

from __future__ import annotations

import numpy as np

from ..errors import CfdesignError
from ..linear import OUTPUTS, gain_pair, posterior_covariance, wrap_inplace, wrap_scalar
from .filter import held, real_array, state_vector, usable

__all__ = ["ArrivalKalman", "MissedReadings"]


class ArrivalKalman:
    """The Kalman filter of a table's model with gains from the readings' actual arrivals.

    Parameters
    ----------
    table : GainTable
        A discrete table with Kalman gains (its ``Q`` and ``R`` are the model's discrete noise
        covariances).
    output : {'posterior', 'prior'}, optional
        The estimate returned: after the tick's readings (default: the table's output) or the
        one-step prediction.
    x0 : array_like, optional
        Initial state (default zero); the covariance starts at the table's ``P[0]``.

    Attributes
    ----------
    x : ndarray
        The one-step prediction of the next tick's state.
    P : ndarray
        Its error covariance.
    u_last : ndarray
        The last inputs received (held when one is missing).
    counts : dict
        ``{'rejected': {sensor: n}}``: readings (inputs and measurements) treated as missing, as
        :attr:`Runtime.counts <cfdesign.runtime.Runtime.counts>` names them.

    Raises
    ------
    CfdesignError
        An output other than ``prior`` or ``posterior``, or an ``x0`` that is not the table's
        number of finite values (:func:`~cfdesign.runtime.filter.state_vector`).
    """

    def __init__(self, table, output=None, x0=None):
        self.F, self.B, self.H = table.F, table.B, table.H
        self.Q, self.R = np.asarray(table.Q, dtype=float), np.asarray(table.R, dtype=float)
        self.n = self.F.shape[0]
        output = table.output if output is None else output
        if not isinstance(output, str) or output not in OUTPUTS:
            raise CfdesignError(f"output must be one of {', '.join(OUTPUTS)}, got {output!r}")
        self.x = np.zeros(self.n) if x0 is None else state_vector(x0, "x0", self.n).copy()
        self.P = np.array(table.P[0], dtype=float)
        self.u_last = np.zeros(self.B.shape[1])
        self.posterior = output == "posterior"
        self.wrap_angle = bool(table.wrap_angle)
        self._wrap_rows = np.array([self.wrap_angle and s.order == 0 for s in table.measurements], dtype=bool)
        self._inputs = [s.name for s in table.inputs]
        self._measurements = [s.name for s in table.measurements]
        self.counts = {}
        self._rows = {}  # the H, R rows of each set of sensors read at a tick
        self._closed_cache = {}  # (Z, K, W) of c ticks coasted in closed form (_closed)
        self._coast_ticks = self.COAST if not self.wrap_angle or np.array_equal(self.F[:, 0], np.eye(self.n)[0]) else 1

    def step(self, **readings) -> float:
        """One base tick with this tick's readings, as :meth:`Runtime.step
        <cfdesign.runtime.Runtime.step>` takes them; returns the estimate.

        The streaming form of :meth:`run` (one tick of it: the same numbers as a run over the
        whole arrays, to rounding): every reading is used at the tick it arrives, whatever its
        phase, offset or rate.  numpy only; about 60 us a tick for a 2-state heading table
        (the compiled :meth:`Runtime.step <cfdesign.runtime.Runtime.step>` of the table's fixed
        gains takes about 1 us).

        Parameters
        ----------
        **readings : float
            ``sensor=value`` in the sensor's units (rad, rad/s, m, m/s^2, ...); a sensor left out
            or given as NaN has no reading this tick (a missing input holds its last value), an inf
            or a value beyond :data:`~cfdesign.runtime.filter.READING_LIMIT` is treated as missing
            and counted in ``counts``.

        Returns
        -------
        float
            The estimate of the common quantity (state 0): after this tick's readings, or the
            prediction (``output``).

        Raises
        ------
        CfdesignError
            A sensor the table does not have (the message names those it has), or a reading
            that is not a real number; raised before anything changes.

        Examples
        --------
        >>> import cfdesign
        >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))
        >>> kf = ArrivalKalman(table)
        >>> est = [kf.step(accelerometer=0.0, gps=1.0 if k == 17 else float("nan")) for k in range(20)]
        >>> est[16], round(est[17], 3)      # the fix at tick 17 is used (the table reads the GPS at phase 0)
        (0.0, 0.063)
        """
        from .step import real_float

        unknown = set(readings) - set(self._inputs) - set(self._measurements)
        if unknown:
            raise CfdesignError(f"unknown sensor(s) {', '.join(sorted(unknown))}; the table reads "
                                f"{', '.join(self._inputs + self._measurements)}")
        row = []
        for name in self._inputs + self._measurements:
            v = readings.get(name, np.nan)
            f = real_float(v)
            if f is None:
                raise CfdesignError(f"{name}: reading {v!r} is not a number")
            row.append(f)
        p = len(self._inputs)
        states, _ = self.run(np.array([row[:p]]).reshape(1, p), np.array([row[p:]]).reshape(1, -1))
        return float(states[0, 0])

    def run(self, u, y, *, priors=False):
        """Run the ticks of ``u`` (inputs, NaN where missing) and ``y`` (readings, NaN where none).

        Parameters
        ----------
        u : ndarray, shape (N, p)
            Inputs per tick, in the order of the table's inputs.
        y : ndarray, shape (N, m)
            Measurements per tick, in the order of the table's measurements.
        priors : bool
            Also return the prior variance of every measurement at the ticks that read, the
            ``H P H'`` of the innovation's predicted variance ``H P H' + R`` (an innovation
            consistency check: :mod:`cfdesign.logs.consistency`).

        Returns
        -------
        states : ndarray, shape (N, n)
            The output state of every tick.
        stds : ndarray, shape (N, n)
            The predicted standard deviation of every state of the output, per tick.
        hph : ndarray, shape (N, m)
            Only with ``priors=True``: the diagonal of ``H P H'`` of the prior at each tick that
            reads (NaN at the others).

        Raises
        ------
        CfdesignError
            ``u`` or ``y`` is not real numbers of those shapes (one ``N`` for both).
        """
        u, y = self._cleaned(u, y)
        N = len(u)
        states, stds = np.empty((N, self.n)), np.empty((N, self.n))
        seen = ~np.isnan(y)
        read = np.flatnonzero(seen.any(axis=1)).tolist()
        hph = np.full(y.shape, np.nan) if priors else None
        x, P = self.x, self.P
        if not read or read[0]:  # the ticks before the first reading
            x, P = self._coast(x, P, u[:read[0] if read else N], states, stds)
        for e, end in zip(read, [*read[1:], N][:len(read)], strict=True):  # a tick that reads, those up to the next
            if hph is not None:
                hph[e] = ((self.H @ P) * self.H).sum(axis=1)
            x_post, P_post = self._update(x, P, y[e], seen[e])
            x_next, P_next = self._coast(x_post, P_post, u[e:end], states[e:end], stds[e:end])
            if not self.posterior:
                states[e], stds[e] = x, np.sqrt(np.maximum(np.diag(P), 0.0))
            x, P = x_next, P_next
        if self.wrap_angle:
            wrap_inplace(states[:, 0])
        self.x, self.P = x, 0.5 * (P + P.T)
        if N:
            self.u_last = u[-1].copy()
        return (states, stds, hph) if priors else (states, stds)

    def _coast(self, x, P, u, states, stds):
        """Ticks from one with state ``x`` and covariance ``P`` (after its readings) on, with inputs
        ``u``, the ticks after the first reading nothing: their states and standard deviations
        written into ``states, stds``, the prior of the tick after them returned.  The steps
        ``x <- F x + B u, P <- F P F' + Q`` are taken in closed form, up to :attr:`COAST` ticks
        at a time (:meth:`_closed`): the same recursion to rounding, without a numpy call per
        tick.  In an angle table whose state 0 feeds back other than as itself (``F[:, 0]`` not
        the first unit vector), one tick at a time: the angle is wrapped every tick there
        (elsewhere a wrap moves no other state, so the rows are wrapped afterwards)."""
        n, C = self.n, self._coast_ticks
        for a in range(0, len(u), C):
            c = min(C, len(u) - a)
            Z, K, W = self._closed(c)
            X = (Z @ np.concatenate([x, u[a:a + c].ravel()])).reshape(c + 1, n)
            if self.wrap_angle and not -np.pi < X[:, 0].min() <= X[:, 0].max() <= np.pi:
                wrap_inplace(X[:, 0])
            V = K @ P.ravel() + W
            states[a:a + c] = X[:c]
            stds[a:a + c] = np.sqrt(np.maximum(V[:c * n], 0.0)).reshape(c, n)
            x, P = X[c], V[c * n:].reshape(n, n)
        return x, P

    #: ticks coasted at once in closed form (``_coast``)
    COAST = 64

    def _closed(self, c):
        """``(Z, K, W)`` of ``c`` ticks in closed form (:func:`_closed_form`, built once per table
        and ``c``)."""
        if c not in self._closed_cache:
            self._closed_cache[c] = _closed_form(self.F, self.B, self.Q, c)
        return self._closed_cache[c]

    def _update(self, x, P, y, rows):
        key = rows.tobytes()
        if key not in self._rows:
            idx = np.flatnonzero(rows)
            H = self.H[idx]
            self._rows[key] = (idx, H, H.T.copy(), self.R[np.ix_(idx, idx)],
                               np.flatnonzero(self._wrap_rows[idx]).tolist())
        idx, H, Ht, R, wrap_rows = self._rows[key]
        e = y[idx] - H @ x
        for i in wrap_rows:
            e[i] = wrap_scalar(e[i])
        PHt = P @ Ht
        S = H @ PHt + R
        L = PHt / S[0, 0] if len(idx) == 1 else np.linalg.solve(S, PHt.T).T  # one reading: no LAPACK call
        return x + L @ e, posterior_covariance(P, H, L, R)

    def _cleaned(self, u, y):
        """Inputs held over missing or rejected values; rejected readings made missing; both counted."""
        u, y = real_array(u, "u").copy(), real_array(y, "y").copy()
        p, m = len(self._inputs), len(self._measurements)
        if u.ndim != 2 or y.ndim != 2 or u.shape[1] != p or y.shape[1] != m or len(u) != len(y):
            raise CfdesignError(f"u and y must be (N, {p}) and (N, {m}) arrays (inputs and measurements per tick), "
                                f"got shapes {u.shape} and {y.shape}")
        bad_y = ~usable(y) & ~np.isnan(y)
        self._count(self._measurements, bad_y)
        y[bad_y] = np.nan
        bad_u = ~usable(u)
        self._count(self._inputs, bad_u & ~np.isnan(u))
        return (held(u, bad_u, self.u_last) if bad_u.any() else u), y

    def _count(self, names, mask):
        for name, c in zip(names, mask.sum(axis=0), strict=True):
            if c:
                bucket = self.counts.setdefault("rejected", {})
                bucket[name] = bucket.get(name, 0) + int(c)


#: closed forms built (:func:`_closed_form`), by the model's bytes and the ticks; a new
#: ArrivalKalman starts at every missed reading of a bridged log
_CLOSED = {}


def _closed_form(F, B, Q, c):
    """``(Z, K, W)``: ``c`` ticks without a reading in closed form.  The states of the ``c`` ticks
    and the next prior, ``F^i x + sum_{j<i} F^(i-1-j) B u_j`` for ``i = 0..c``, are
    ``Z [x; u_0; ...; u_(c-1)]``; the variances of those ticks and the next prior's covariance
    (row by row), ``diag(F^i P F^i' + W_i)`` and ``F^c P F^c' + W_c`` with
    ``W_i = sum_{j<i} F^j Q F^j'``, are ``K vec(P) + W``.

    Parameters
    ----------
    F, B, Q : ndarray
        The model's transition ``(n, n)``, input ``(n, p)`` and process-noise ``(n, n)``
        matrices, per tick.
    c : int
        Ticks.

    Returns
    -------
    tuple of ndarray
        ``Z`` ``((c + 1) n, n + c p)``, ``K`` ``(c n + n^2, n^2)``, ``W`` ``(c n + n^2,)``.
    """
    key = (F.shape, B.shape, F.tobytes(), B.tobytes(), Q.tobytes(), c)
    if key not in _CLOSED:
        if len(_CLOSED) > 256:
            _CLOSED.clear()
        n, p = F.shape[0], B.shape[1]
        Phi, Ws = [np.eye(n)], [np.zeros((n, n))]
        for _ in range(c):
            Ws.append(F @ Ws[-1] @ F.T + Q)
            Phi.append(F @ Phi[-1])
        G = [M @ B for M in Phi]
        Z = np.zeros(((c + 1) * n, n + c * p))
        for i in range(c + 1):
            Z[i * n:(i + 1) * n, :n] = Phi[i]
            for j in range(i):  # the input of tick j reaches tick i through F^(i-1-j) B
                Z[i * n:(i + 1) * n, n + j * p:n + (j + 1) * p] = G[i - 1 - j]
        diag = [np.kron(Phi[i], Phi[i])[np.arange(n) * (n + 1)] for i in range(c)]  # the rows of (a, a)
        K = np.vstack([*diag, np.kron(Phi[c], Phi[c])])
        W = np.concatenate([*(np.diag(Ws[i]) for i in range(c)), Ws[c].ravel()])
        _CLOSED[key] = (Z, K, W)
    return _CLOSED[key]


class MissedReadings:
    r"""Predicted error of a table's own gains when scheduled readings are missing.

    A table's covariances ``P`` (and ``P_filtered``) are those of its gains with every
    scheduled reading present.  Where one is missing (a GPS outage, a dropped compass reading,
    an ``inf``) the runtime skips its update and the error grows beyond them; it then returns
    to them at the closed loop's rate.  This follows the error covariance of the *fixed* gains
    over the readings present, for the ticks from the first missed reading until it is back on
    the table's (to :attr:`RTOL` of its largest variance):

    .. math::

        P^+ = (I - L_a H_a) P (I - L_a H_a)^T + L_a R_a L_a^T,\qquad P \leftarrow F P^+ F^T + Q,

    ``L_a, H_a, R_a`` the update gain (:func:`cfdesign.linear.gain_pair`), rows and noise of the
    scheduled sensors read at that tick (Joseph form: valid for any gain).  A predictor-form
    table without an update gain uses ``P <- (F - K_a H_a) P (F - K_a H_a)^T + K_a R_a K_a^T + Q``.
    Held inputs are not modelled (their error depends on how the input changed).

    Parameters
    ----------
    table : GainTable
        A discrete table whose ``Q`` and ``R`` are its model's per-tick noise covariances.
    output : {'posterior', 'prior'}, optional
        The estimate whose error is returned (default: the table's output).

    Attributes
    ----------
    P : ndarray or None
        The prior covariance of the next tick while it differs from the table's; None otherwise.
    """

    #: the covariance is back on the table's when every entry is within this fraction of its
    #: largest variance
    RTOL = 1e-9

    def __init__(self, table, output=None):
        self.table = table
        self.posterior = (table.output if output is None else output) == "posterior"  # None: the table's
        self.mask = table.schedule.mask()
        self.F, self.H = np.asarray(table.F, dtype=float), np.asarray(table.H, dtype=float)
        self.Q, self.R = np.asarray(table.Q, dtype=float), np.asarray(table.R, dtype=float)
        self.pairs = [gain_pair(self.F, K, table.gain_form) for K in table.K]
        self._cache = {}
        self.every = table.period * -(-16 // table.period)  # whole periods, at least 16 ticks
        self.P = None

    def stds(self, phases, present, base):
        """Standard deviations of the output at ticks of ``phases``, given the readings present.

        Parameters
        ----------
        phases : ndarray of int, shape (N,)
            The table's phase at each tick, consecutive ticks.
        present : ndarray of bool, shape (N, m)
            Which measurement (in the table's row order) has a usable reading at each tick.
        base : ndarray, shape (N, n)
            The table's standard deviations at those phases (returned where nothing was missed).

        Returns
        -------
        ndarray, shape (N, n)
            The predicted standard deviation of every state of the output at every tick.
        """
        t = self.table
        read = self.mask[phases] & present
        missed = (self.mask[phases] & ~present).any(axis=1)
        k = 0 if self.P is not None else (int(np.argmax(missed)) if missed.any() else len(phases))
        if k == len(phases):
            return base
        out = np.square(base, dtype=float)  # variances
        P = self.P if self.P is not None else np.asarray(t.P[phases[k]], dtype=float)
        L = self.every
        while k < len(phases):
            ph = phases[k]
            outage = k + L <= len(phases) and not read[k:k + L].any()
            if k + L <= len(phases) and (outage or not missed[k:k + L].any()):
                T, e, Phi, S = self._block(ph, outage)  # L ticks of the table's pattern, or of none, at once
                out[k:k + L] = np.einsum("jab,bc,jac->ja", T, P, T) + e
                P = Phi @ P @ Phi.T + S
                k += L
                ph = phases[k - 1]
                if outage:
                    continue
            else:
                M, N, A, c = self._tick(ph, read[k])
                out[k] = np.einsum("ij,ij->i", A @ P, A) + c
                P = M @ P @ M.T + N
                k += 1
                if missed[k - 1] or k % L:  # compared with the table's now and then, after a reading
                    continue
            P = 0.5 * (P + P.T)
            ref = np.asarray(t.P[(ph + 1) % t.period], dtype=float)
            if np.max(np.abs(P - ref)) <= self.RTOL * np.max(np.abs(np.diag(ref))):
                ahead = missed[k:]
                if not ahead.any():
                    self.P = None
                    break
                k += int(np.argmax(ahead))
                P = np.asarray(t.P[phases[k]], dtype=float)
        else:
            self.P = 0.5 * (P + P.T)
        return np.sqrt(np.maximum(out, 0.0))

    def _block(self, phase, outage=False):
        """``(T, e, Phi, S)`` of the ``every`` ticks from ``phase`` with every scheduled reading
        present (or, ``outage``, none): the output variances of tick ``j`` are ``diag(T[j] P T[j]') + e[j]`` for the
        prior ``P`` of the first tick, and the prior after them is ``Phi P Phi' + S`` (the
        products of :meth:`_tick`'s maps, ``M`` and ``N``, over the ticks before)."""
        key = ("block", phase, outage)
        if key not in self._cache:
            n, L = len(self.F), self.every
            T, e = np.empty((L, n, n)), np.empty((L, n))
            Phi, S = np.eye(n), np.zeros((n, n))
            for j in range(L):
                ph = (phase + j) % self.table.period
                M, N, A, c = self._tick(ph, self.mask[ph] & (not outage))
                T[j] = A @ Phi
                e[j] = np.einsum("ij,ij->i", A @ S, A) + c
                Phi, S = M @ Phi, M @ S @ M.T + N
            self._cache[key] = (T, e, Phi, S)
        return self._cache[key]

    def _tick(self, phase, read):
        """``(M, N, A, c)`` of a tick at ``phase`` reading the rows ``read``: the next prior
        ``M P M' + N`` and the output's variances ``diag(A P A') + c``."""
        key = (phase, read.tobytes())
        if key not in self._cache:
            F, Q, n = self.F, self.Q, len(self.F)
            Kp, L = self.pairs[phase]
            rows = np.flatnonzero(read)
            H, R = self.H[rows], self.R[np.ix_(rows, rows)]
            if L is None:  # predictor form without an update gain: the prior is the output
                M = F - Kp[:, rows] @ H
                self._cache[key] = (M, Kp[:, rows] @ R @ Kp[:, rows].T + Q, np.eye(n), np.zeros(n))
            else:
                A = np.eye(n) - L[:, rows] @ H
                C = L[:, rows] @ R @ L[:, rows].T
                out = (A, np.diag(C).copy()) if self.posterior else (np.eye(n), np.zeros(n))
                self._cache[key] = (F @ A, F @ C @ F.T + Q, *out)
        return self._cache[key]
