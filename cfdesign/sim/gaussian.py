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

The truth is simulated without the runtime: the recursion ``x[k+1] = F x[k] + d[k]`` of the
drive ``d = B u + w``, lifted over blocks of ``L`` steps (the states inside every block at
once, vectorised over the blocks, then the block-start states ``x[(p+1)L] = F^L x[pL] + c[p]``
one block at a time), so the check is independent of the filter it checks.  Not an IIR filter
of ``(zI - F)^-1``: a model's ``F`` has its poles at ``z = 1`` (integrators, random-walk
biases), and the direct form's rounding then grows like a repeated integrator of it - over
200,000 steps of the position example's triple integrator the truth drifted by 1 m, more than
the filter's predicted error (0.8 m).
"""

from __future__ import annotations

import numpy as np

from ..gains import require_table

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

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    """
    require_table(table, "model_log")
    rng = np.random.default_rng(seed)
    F, B, H = (np.asarray(a, dtype=float) for a in (table.F, table.B, table.H))
    n, p, m = F.shape[0], B.shape[1], H.shape[0]
    t = np.arange(n_steps)
    u = input_amplitude * np.sin(2 * np.pi * t[:, None] / (500.0 + 37.0 * np.arange(p)))
    w = rng.multivariate_normal(np.zeros(n), table.Q, size=n_steps, method="cholesky")
    x = _states(F, u @ B.T + w)
    v = rng.multivariate_normal(np.zeros(m), table.R, size=n_steps, method="cholesky")
    y = x @ H.T + v
    y[~table.schedule.mask()[t % table.period]] = np.nan
    names = [s.name for s in table.sensors]
    return x, dict(zip(names, [*u.T, *y.T], strict=True))


def _states(F, d) -> np.ndarray:
    """``x[0] = 0``, ``x[k+1] = F x[k] + d[k]`` for every ``k``: the recursion lifted over blocks of
    ``L ~ sqrt(N)`` steps (O(sqrt(N)) numpy calls, the rounding of the recursion itself)."""
    N, n = d.shape
    L = max(1, int(np.ceil(np.sqrt(N))))
    P = -(-N // L)
    D = np.zeros((P * L, n))
    D[:N] = d
    D = D.reshape(P, L, n)
    inner = np.empty((P, L, n))  # the states of every block started from zero
    z = np.zeros((P, n))
    for j in range(L):
        inner[:, j] = z
        z = z @ F.T + D[:, j]
    FL = np.linalg.matrix_power(F, L)
    starts = np.empty((P, n))  # x[pL], one block after the other
    x = np.zeros(n)
    for q in range(P):
        starts[q] = x
        x = FL @ x + z[q]
    Fj = np.eye(n)
    for j in range(L):  # x[pL + j] = F^j x[pL] + (the block's own drive)
        inner[:, j] += starts @ Fj.T
        Fj = F @ Fj
    return inner.reshape(P * L, n)[:N]
