"""Plotting a log's estimates: :func:`~cfdesign.logs.plot_log`."""

from __future__ import annotations

import math

import numpy as np

from ..linear import wrap
from .columns import TIME_UNITS, _numeric
from .read import _Lines
from .ticks import _startup_ticks


def plot_log(table, estimates, references=None, time=None, time_unit="s", restarts=()):
    """Every state over time with its predicted +-2 sigma band; against its reference where given.

    The error panels shade the start-up (:func:`~cfdesign.linear.startup_steps`): the error of
    the initial state, dying away at the closed loop's pace, is not in the band, which is the
    filter's steady state.  Their titles give the RMS error over every row and after the start-up.

    Parameters
    ----------
    table : GainTable
        The gain table the estimates came from (it names the states and sensors).
    estimates : pandas.DataFrame
        ``LogResult.estimates`` (with the ``<state>_std`` and ``<state>_reference``
        columns that :func:`run_log` adds when references are given).
    references : dict, optional
        ``{state: column}``: these states get a panel of the error inside the +-2 sigma band.
    time : str, optional
        The time column (else the row number is the x axis).
    time_unit : {'s', 'ms', 'us', 'ns'}
        The unit of a numeric time column (:data:`TIME_UNITS`); the axis is in seconds.
    restarts : sequence of int
        Base ticks (from the log's first) where a pause of the logger ended and state 0 started
        again (:func:`run_log`): the start-up after each is shaded too.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per state (and per reference error).
    """
    import matplotlib.pyplot as plt

    refs = references or {}
    rows = sum(2 if s in refs else 1 for s in table.states)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.2 * rows), sharex=True, squeeze=False)
    x, xlabel = _time_axis(estimates, time, TIME_UNITS[time_unit])
    startup = _startup_ticks(table) if table.domain == "z" and len(x) else None  # (logs run discrete tables)
    if startup is not None:  # where it ends on the x axis: without a time column, a row is a base tick
        startup_s = startup * table.sample_time_s
        end = x[0] + (startup_s if time else startup)
    ax_iter = iter(axes[:, 0])
    wrapped = table.states[0] if table.wrap_angle else None
    units = dict(zip(table.states, (f" ({u})" if u else "" for u in table.state_units()), strict=True))
    gaps = _gaps(x)

    def cut(values):  # lines and bands break at a gap of the log (a pause) instead of bridging it
        out = np.array(values, dtype=float)
        out[gaps] = np.nan
        return out

    for name in table.states:
        ax = next(ax_iter)
        est = estimates[name].to_numpy()
        ax.plot(x, cut(_broken(est) if name == wrapped else est), lw=0.8, label=f"{name} (estimate)")
        if name in refs:
            ref = estimates[f"{name}_reference"].to_numpy()
            ax.plot(*_sparse(x, ref, gaps, name == wrapped), lw=0.8, ls="--", label="reference")
            ax2 = next(ax_iter)
            err = est - estimates[f"{name}_reference"].to_numpy()
            err = wrap(err) if table.wrap_angle and name == table.states[0] else err
            band = cut(2 * estimates[f"{name}_std"].to_numpy()) if f"{name}_std" in estimates else None
            if startup is not None:  # the start-up: the error of the initial state dying away, outside the band
                ax2.axvspan(x[0], min(end, x[-1]), color="#fde9b5", lw=0, zorder=0,
                            label=f"start-up (first {startup_s:.3g} s)" if math.isfinite(startup_s)
                            else "start-up (the error does not die away)")
                for e in restarts:  # and the start-up after each pause
                    at = x[0] + e * (table.sample_time_s if time else 1)
                    ax2.axvspan(at, min(at + end - x[0], x[-1]), color="#fde9b5", lw=0, zorder=0)
            ax2.plot(*_sparse(x, err, gaps), lw=0.6, color="C3", label="error")
            if band is not None:
                ax2.fill_between(x, -band, band, color="0.85", label="predicted ±2σ")
            ok = np.isfinite(err)
            after = ok & (x >= end) if startup is not None else None
            for e in restarts if startup is not None else ():
                at = x[0] + e * (table.sample_time_s if time else 1)
                after &= ~((x >= at) & (x < at + end - x[0]))
            title = f"RMS {np.sqrt(np.mean(err[ok] ** 2)):.3g}"
            if after is not None and after.any():
                title += f"; after the start-up {np.sqrt(np.mean(err[after] ** 2)):.3g}"
            ax2.set_ylabel(f"{name} error{units[name]}")
            ax2.set_title(title, fontsize=9, loc="right")
            ax2.legend(loc="upper right", fontsize=8)
        elif f"{name}_std" in estimates:
            band = 2 * estimates[f"{name}_std"].to_numpy()
            ax.fill_between(x, cut(est - band), cut(est + band), color="0.85", label="predicted ±2σ")
        ax.set_ylabel(f"{name}{units[name]}")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel(xlabel)
    fig.suptitle(table.name, fontsize=10)
    fig.tight_layout()
    return fig


def _time_axis(estimates, time, scale=1.0):
    """``(x, label)``: the time column in seconds (``scale`` seconds a unit; dates as seconds after
    the first row), or the row number."""
    if not time:
        return np.arange(len(estimates)), "row"
    col = estimates[time]
    if col.dtype.kind in "fiu" and scale != 1.0:  # nanoseconds since 1970: seconds from the first row
        raw = col.to_numpy()  # whole numbers subtracted before they become floats: exact
        return (raw - raw[0]).astype(float) * scale, f"{time} (s after the first row)"
    if col.dtype.kind in "fiu":
        return col.to_numpy(dtype=float), f"{time} (s)"
    x = _numeric(estimates, [time], "estimates", _Lines().at, time)[time]
    return x - x[0], f"{time} (s after {col.iloc[0]})"


def _gaps(x):
    """Rows that follow a gap of the x axis of more than ten median steps (a logger's pause):
    the plot's lines and bands break there rather than draw a straight line across it."""
    out = np.zeros(len(x), dtype=bool)
    if len(x) > 2:
        step = np.diff(np.asarray(x, dtype=float))
        out[1:] = step > 10 * np.median(step)
    return out


def _sparse(x, values, gaps, angle=False):
    """``(x, y)`` of a line through the rows of ``values`` that hold a number, broken at the log's
    gaps (and, for an ``angle``, at its +-pi wraps): a reference from a joined file, a number on
    every other row of the union, had been drawn as NaN-separated points, which show nothing.

    Parameters
    ----------
    x : ndarray
        The x axis (s, or rows).
    values : ndarray
        One value a row, NaN where the row has none.
    gaps : ndarray of bool
        The rows that follow a pause of the log (:func:`_gaps`).
    angle : bool
        Break the line where the angle wraps (:func:`_broken`).

    Returns
    -------
    tuple of ndarray
        The x and y of the rows drawn, y NaN where the line breaks.
    """
    keep = np.isfinite(values) | gaps
    y = np.array(values[keep], dtype=float)
    y = _broken(y) if angle else y
    y[gaps[keep]] = np.nan
    return np.asarray(x)[keep], y


def _broken(angle):
    """An angle with NaN at its +-pi wraps, so the plot has no vertical lines there."""
    out = np.array(angle, dtype=float)
    out[1:][np.abs(np.diff(out)) > np.pi] = np.nan
    return out
