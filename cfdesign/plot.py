"""Plots: Bode diagrams of the bands and their sum (matplotlib is imported lazily)."""

from __future__ import annotations

import numpy as np

from .analysis import frequency_response

__all__ = ["bode_plot"]


def bode_plot(observer, omega=None, *, hz: bool = False, title: str | None = None, fig=None):
    """Bode diagram of every band of a numeric observer and of their sum.

    The sum is computed numerically from the band responses, so a complementary filter
    shows it on 0 dB / 0 deg across the whole grid.  Each crossover between adjacent bands
    (equal magnitude, :meth:`FrequencyResponse.crossovers`) is marked with a dotted line
    and its frequency.  Discrete filters are drawn up to the Nyquist frequency.

    Parameters
    ----------
    observer : Observer
        With numbers for every gain (:meth:`Observer.with_gains`).
    omega : array_like, optional
        Frequencies in rad/s; default: two decades around the poles.
    hz : bool
        Label the frequency axis in Hz instead of rad/s.
    title : str, optional
    fig : matplotlib Figure, optional
        Figure to draw into (two axes are added).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    resp = frequency_response(observer, omega)
    scale, unit = (1 / (2 * np.pi), "Hz") if hz else (1.0, "rad/s")
    f = resp.omega * scale
    fig = fig or plt.figure(figsize=(8, 6.5))
    ax_mag, ax_ph = fig.subplots(2, 1, sharex=True)
    for name in resp.dominant_order():
        line, = ax_mag.semilogx(f, resp.magnitude_db(name), label=f"T_{name}")
        ax_ph.semilogx(f, resp.phase_deg(name), color=line.get_color())
    ax_mag.semilogx(f, resp.magnitude_db("sum"), "k--", lw=2, label="sum of bands")
    ax_ph.semilogx(f, resp.phase_deg("sum"), "k--", lw=2)
    crossovers = resp.crossovers()
    for a, b, w in crossovers:
        level = 20 * np.log10(abs(np.interp(w, resp.omega, np.abs(resp.bands[a]))))
        ax_mag.plot(w * scale, level, "o", color="0.3", ms=5)
        for ax in (ax_mag, ax_ph):
            ax.axvline(w * scale, color="0.5", ls=":", lw=1)
        ax_ph.text(w * scale, 0.02, f" {a}/{b}: {w * scale:.3g} {unit}", rotation=90, fontsize=7,
                   ha="right", va="bottom", color="0.25", transform=ax_ph.get_xaxis_transform())
    if crossovers:
        ax_mag.plot([], [], ":", color="0.5", marker="o", ms=4, label="crossover")
    _finish_axes(ax_mag, ax_ph, resp, unit, title or _default_title(observer))
    fig.tight_layout()
    return fig


def _default_title(observer):
    kind = f"discrete, T = {float(observer.sample_time):g} s" if observer.discrete else "continuous"
    return f"Bode diagram of {observer.name} ({kind})"


def _finish_axes(ax_mag, ax_ph, resp, unit, title):
    low = max(-80.0, min(np.nanmin(resp.magnitude_db(k)) for k in resp.bands)) - 5
    ax_mag.set_ylim(low, 10)
    ax_mag.set_ylabel("magnitude (dB)")
    ax_mag.set_title(title)
    ax_mag.legend(loc="lower left", bbox_to_anchor=(0.0, 0.08), fontsize=8)
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel(f"frequency ({unit})" + (" - up to Nyquist" if resp.dt else ""))
    for ax in (ax_mag, ax_ph):
        ax.grid(True, which="both", alpha=0.3)
