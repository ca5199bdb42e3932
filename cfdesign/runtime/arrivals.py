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

from ..linear import posterior_covariance, wrap_inplace, wrap_scalar
from .filter import held, usable

__all__ = ["ArrivalKalman"]


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
    """

    def __init__(self, table, output=None, x0=None):
        self.F, self.B, self.H = table.F, table.B, table.H
        self.Q, self.R = np.asarray(table.Q, dtype=float), np.asarray(table.R, dtype=float)
        self.n = self.F.shape[0]
        self.x = np.zeros(self.n) if x0 is None else np.asarray(x0, dtype=float).copy()
        self.P = np.array(table.P[0], dtype=float)
        self.u_last = np.zeros(self.B.shape[1])
        self.posterior = (output or table.output) == "posterior"
        self.wrap_angle = bool(table.wrap_angle)
        self._wrap_rows = np.array([self.wrap_angle and s.order == 0 for s in table.measurements], dtype=bool)
        self._inputs = [s.name for s in table.inputs]
        self._measurements = [s.name for s in table.measurements]
        self.counts = {}
        self._rows = {}  # the H, R rows of each set of sensors read at a tick

    def run(self, u, y):
        """Run the ticks of ``u`` (inputs, NaN where missing) and ``y`` (readings, NaN where none).

        Parameters
        ----------
        u : ndarray, shape (N, p)
            Inputs per tick, in the order of the table's inputs.
        y : ndarray, shape (N, m)
            Measurements per tick, in the order of the table's measurements.

        Returns
        -------
        states : ndarray, shape (N, n)
            The output state of every tick.
        stds : ndarray, shape (N, n)
            The predicted standard deviation of every state of the output, per tick.
        """
        N = len(u)
        states, stds = np.empty((N, self.n)), np.empty((N, self.n))
        u, y = self._cleaned(u, y)
        seen = ~np.isnan(y)
        F, B, Q = self.F, self.B, self.Q
        x, P = self.x, self.P
        for k in range(N):
            rows = seen[k]
            if rows.any():
                x_post, P_post = self._update(x, P, y[k], rows)
            else:
                x_post, P_post = x, P
            out, cov = (x_post, P_post) if self.posterior else (x, P)
            states[k] = out
            stds[k] = np.sqrt(np.maximum(np.diag(cov), 0.0))
            x = F @ x_post + B @ u[k]
            P = F @ P_post @ F.T + Q
            if self.wrap_angle:
                x[0] = wrap_scalar(x[0])
        if self.wrap_angle:
            wrap_inplace(states[:, 0])
        self.x, self.P = x, 0.5 * (P + P.T)
        if N:
            self.u_last = u[-1].copy()
        return states, stds

    def _update(self, x, P, y, rows):
        key = rows.tobytes()
        if key not in self._rows:
            idx = np.flatnonzero(rows)
            self._rows[key] = (idx, self.H[idx], self.R[np.ix_(idx, idx)], self._wrap_rows[idx])
        idx, H, R, wrap_rows = self._rows[key]
        e = y[idx] - H @ x
        for i in np.flatnonzero(wrap_rows):
            e[i] = wrap_scalar(e[i])
        PHt = P @ H.T
        L = np.linalg.solve(H @ PHt + R, PHt.T).T
        return x + L @ e, posterior_covariance(P, H, L, R)

    def _cleaned(self, u, y):
        """Inputs held over missing or rejected values; rejected readings made missing; both counted."""
        u, y = np.array(u, dtype=float), np.array(y, dtype=float)
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
