"""Logs drawn from a gain table's own linear-Gaussian model: the check of its predicted errors.

A table states the model its gains were designed for (discrete tables):

.. math::

    x[k+1] = F x[k] + B u[k] + w[k],\\quad w \\sim N(0, Q),\\qquad
    y[k] = H x[k] + v[k],\\quad v \\sim N(0, R),

with measurement row ``i`` read only at the phases the table's schedule lists.  Run on such a
log, a filter whose gains are the Kalman gains of the model must show the error variances the
table predicts (``P`` for the one-step prediction, ``P_filtered`` for the estimate after the
step's readings); fixed gains must show their Lyapunov prediction.  This is the Monte-Carlo
check of every number the designer prints.

The truth is simulated without the runtime: ``x = sum_j (zI - F)^-1 d_j`` by IIR filtering
(``scipy.signal.lfilter``) of the drive ``d = B u + w``, so the check is independent of the
filter it checks.
"""

from __future__ import annotations

import numpy as np

from ..linear import adjugate_coefficients, characteristic_polynomial

__all__ = ["model_log"]


def model_log(table, n_steps: int, *, seed: int = 0, input_amplitude: float = 0.1) -> tuple:
    """Truth and readings of ``n_steps`` base-rate steps of ``table``'s model.

    Parameters
    ----------
    table : GainTable
        A discrete table.
    n_steps : int
        Number of base-rate steps.
    seed : int
        Random seed.
    input_amplitude : float
        Amplitude of the slow sinusoidal true input ``u`` (units of the input sensor).

    Returns
    -------
    tuple
        ``(x, readings)``: the (n_steps, n) true states and ``{sensor: (n_steps,) array}`` with
        NaN where a measurement is not read (its schedule), ready for ``Runtime.run``.
    """
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    F, B, H = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H))
    n, p, m = F.shape[0], B.shape[1], H.shape[0]
    t = np.arange(n_steps)
    u = input_amplitude * np.sin(2 * np.pi * t[:, None] / (500.0 + 37.0 * np.arange(p)))
    w = rng.multivariate_normal(np.zeros(n), table.Q, size=n_steps, method="cholesky")
    d = u @ B.T + w
    den = characteristic_polynomial(F)
    adj = adjugate_coefficients(F, den)  # (zI - F)^-1 = sum_k adj[k] z^(n-1-k) / den
    x = np.zeros((n_steps, n))
    for i in range(n):
        for j in range(n):
            num = np.concatenate([[0.0], adj[:, i, j]])
            if num.any():
                x[:, i] += lfilter(num, den, d[:, j])
    v = rng.multivariate_normal(np.zeros(m), table.R, size=n_steps, method="cholesky")
    y = x @ H.T + v
    y[~table.schedule.mask()[t % table.period]] = np.nan
    names = [s.name for s in table.sensors]
    return x, dict(zip(names, [*u.T, *y.T], strict=True))
