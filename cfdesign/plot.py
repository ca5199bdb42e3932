"""Plots: Bode diagrams of the bands and their sum (matplotlib is imported lazily)."""

from __future__ import annotations

import numpy as np

from .analysis import angular_frequencies, frequency_response
from .gains import require_table

__all__ = ["bode_plot", "table_bode_plot", "lifted_system", "figure_bytes", "FIGURE_FORMATS"]


def bode_plot(observer, omega=None, *, hz: bool = False, title: str | None = None, fig=None):
    """Bode diagram of every band of a numeric observer and of their sum.

    The sum is computed numerically from the band responses, so a complementary filter
    shows it on 0 dB / 0 deg across the whole grid.  Each crossover between adjacent bands
    (equal magnitude,
    :meth:`FrequencyResponse.crossovers <cfdesign.analysis.FrequencyResponse.crossovers>`) is
    marked with a dotted line and its frequency.  Discrete filters are drawn up to the Nyquist frequency.

    Parameters
    ----------
    observer : Observer
        With numbers for every gain (:meth:`Observer.with_gains <cfdesign.symbolic.Observer.with_gains>`).
    omega : array_like, optional
        Frequencies in rad/s; default: two decades around the poles.
    hz : bool
        Label the frequency axis in Hz instead of rad/s.
    title : str, optional
        Figure title; default: "Bode diagram of" the observer's name and its domain.
    fig : matplotlib Figure, optional
        Figure to draw into (two axes are added).

    Returns
    -------
    matplotlib.figure.Figure
        The figure: magnitude (dB) and phase (deg) axes.

    Raises
    ------
    GainError
        The observer still has symbolic parameters.
    StructureError
        ``observer`` is not a cfdesign Observer (a python-control system, a gain table: its own
        ``table.bode()``).
    InputError
        ``omega`` is not a non-empty 1-D array of positive finite angular frequencies (rad/s, at
        most 1e100).
    """
    resp = frequency_response(observer, _plot_frequencies(omega))
    return _draw_bands(resp, hz, title or _default_title(observer), fig)


def _plot_frequencies(omega):
    """A caller's grid for a Bode diagram: finite (:func:`angular_frequencies`), positive (the axis is
    logarithmic: 0 has no place on it and gave matplotlib's raw 'Axis limits cannot be NaN or Inf',
    a negative frequency was dropped without a word) and at most 1e100 rad/s, where every band has long
    reached its asymptote (1e300 overflowed the continuous responses).  ``None`` stays ``None``
    (the default grid).

    Raises
    ------
    InputError
        A frequency is not finite, not positive or above 1e100 rad/s.
    """
    if omega is None:
        return None
    from .errors import InputError

    w = angular_frequencies(omega)
    bad = w[(w <= 0) | (w > 1e100)]
    if bad.size:
        raise InputError(f"omega: a Bode diagram's frequencies must lie in (0, 1e100] rad/s (log axis), got {bad[0]:g}")
    return w


def _draw_bands(resp, hz, title, fig):
    """Bode diagram of a :class:`~cfdesign.analysis.FrequencyResponse` (bands, sum, crossovers)."""
    import matplotlib.pyplot as plt

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
    _finish_axes(ax_mag, ax_ph, resp, unit, title)
    fig.tight_layout()
    return fig


def _default_title(observer):
    kind = f"discrete, T = {float(observer.sample_time):g} s" if observer.discrete else "continuous"
    return f"Bode diagram of {observer.name} ({kind})"


def _finish_axes(ax_mag, ax_ph, resp, unit, title):
    low = max(-80.0, min(np.nanmin(resp.magnitude_db(k)) for k in resp.bands)) - 5
    ax_mag.set_ylim(low, 10)
    ax_mag.set_ylabel("magnitude (dB)")
    ax_mag.set_title(_wrapped(title))
    ax_mag.legend(loc="lower left", bbox_to_anchor=(0.0, 0.08), fontsize=8)
    ax_ph.set_ylabel("phase (deg)")
    ax_ph.set_xlabel(f"frequency ({unit})" + (" - up to Nyquist" if resp.dt else ""))
    for ax in (ax_mag, ax_ph):
        ax.grid(True, which="both", alpha=0.3)


def _wrapped(title: str, width: int = 72) -> str:
    """A title broken into lines that fit the figure's width (a long table name was clipped at
    both ends)."""
    import textwrap

    return "\n".join(textwrap.fill(line, width) for line in str(title).splitlines() or [""])


def table_bode_plot(table, omega=None, *, hz: bool = False, title: str | None = None, fig=None):
    """Bode diagram of a gain table, from its own ``F, B, H, K`` (numpy; no sympy).

    Single-rate tables: every band of the estimate the table outputs, their sum and the
    crossovers, as :func:`bode_plot` draws them for an observer.  Multirate tables have no
    single set of bands (they change with the phase): the figure shows the gains of every
    phase, and the frequency response of the lifted system at the period rate
    (:func:`lifted_system`, evaluated with ``control.frequency_response``) from each sensor's
    reading, held over the period, to the estimate at phase 0.

    Parameters
    ----------
    table : GainTable
        The gain table whose bands are drawn.
    omega : array_like, optional
        Angular frequencies in rad/s, also with ``hz=True``; default: a grid spanning the poles.
    hz : bool
        Label the frequency axis in Hz instead of rad/s.
    title : str, optional
        Figure title.
    fig : matplotlib.figure.Figure, optional
        Figure to draw into.

    Returns
    -------
    matplotlib.figure.Figure
        The figure: magnitude (dB) and phase (deg) axes.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    InputError
        ``omega`` is not a non-empty 1-D array of positive finite angular frequencies (rad/s, at
        most 1e100).

    Examples
    --------
    >>> import cfdesign
    >>> from cfdesign.plot import table_bode_plot
    >>> table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    >>> fig = table_bode_plot(table, hz=True)
    >>> len(fig.axes)
    2
    """
    require_table(table, "table_bode_plot")
    omega = _plot_frequencies(omega)
    from .analysis import FrequencyResponse, default_frequencies
    from .verify import band_polynomials

    if table.period == 1:
        coefficients = band_polynomials(table)[0]
        dt = table.sample_time_s if table.domain == "z" else None
        omega = default_frequencies(coefficients, dt) if omega is None else omega
        from . import linear

        # the state-space responses: the polynomials lose poles that lie within rounding of z = 1
        from .verify import phase_realisation

        real = phase_realisation(table)

        def evaluate(w):
            return linear.band_responses(real, table.sensors, table.domain, dt, w)

        resp = FrequencyResponse(omega, evaluate(omega), dt, coefficients, evaluate)
        kind = f"discrete, T = {dt:g} s, {table.output}" if dt else "continuous"
        return _draw_bands(resp, hz, title or f"Bode diagram of {table.name} ({kind})", fig)
    return _multirate_figure(table, omega, hz, title, fig)


def lifted_system(table):
    """The lifted system of a multirate table over one period.

    With every reading ``w`` held over the period and ``x[k+1] = A_k x + G_k w`` at phase
    ``k`` (:func:`cfdesign.linear.realisation` with the phase's gain), one period maps
    ``x[0]`` to ``Phi x[0] + sum_k (A_{N-1} ... A_{k+1}) G_k w`` with the monodromy matrix
    ``Phi``; the output is the table's estimate at phase 0, ``C_0 x + D_0 w``.

    Parameters
    ----------
    table : GainTable
        A discrete table (single-rate tables give their one-step system).

    Returns
    -------
    control.StateSpace
        Sample time ``N T`` (s); inputs named after the sensors, output ``'estimate'``.

    Examples
    --------
    >>> import cfdesign
    >>> from cfdesign.plot import lifted_system
    >>> sys = lifted_system(cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position"))))
    >>> sys.dt, sys.input_labels
    (1.0, ['accelerometer', 'gps'])
    """
    import control

    from .verify import phase_realisation

    phases = [phase_realisation(table, k) for k in range(table.period)]
    n = len(table.F)
    Phi, Bl = np.eye(n), np.zeros_like(phases[0].G)
    for real in phases:
        Phi, Bl = real.A @ Phi, real.A @ Bl + real.G
    return control.ss(Phi, Bl, phases[0].C[:1], phases[0].D[:1], table.period * table.sample_time_s,
                      inputs=[s.name for s in table.sensors], outputs=["estimate"], name="lifted")


def _multirate_figure(table, omega, hz, title, fig):
    import control
    import matplotlib.pyplot as plt

    fig = fig or plt.figure(figsize=(8, 7.5))
    ax_k, ax_mag = fig.subplots(2, 1)
    K = np.array(table.K)
    phases = np.arange(table.period)
    states = table.states
    for j, s in enumerate(table.measurements):
        for i in range(K.shape[1]):
            if np.any(K[:, i, j]):
                ax_k.step(phases, K[:, i, j], where="post", label=f"K[{states[i]}, {s.name}] ({table.gain_form})")
    ax_k.set_xlabel("phase (base-rate steps)")
    ax_k.set_ylabel("gain")
    ax_k.set_title(_wrapped(title or f"{table.name}: gains per phase (period {table.period})"))
    ax_k.grid(True, alpha=0.3)
    ax_k.legend(fontsize=8)
    sys = lifted_system(table)
    nyquist = np.pi / sys.dt
    omega = np.logspace(np.log10(nyquist) - 4, np.log10(0.999 * nyquist), 400) if omega is None else omega
    scale, unit = (1 / (2 * np.pi), "Hz") if hz else (1.0, "rad/s")
    for j, name in enumerate(sys.input_labels):
        resp = control.frequency_response(sys[0, j], omega)
        with np.errstate(divide="ignore"):
            ax_mag.semilogx(resp.omega * scale, 20 * np.log10(np.abs(resp.magnitude).ravel()),
                            label=f"{name} -> estimate")
    ax_mag.set_xlabel(f"frequency ({unit}) - up to the period's Nyquist")
    ax_mag.set_ylabel("magnitude (dB)")
    ax_mag.set_title(f"lifted system at the period rate (T = {sys.dt:g} s), readings held over a period")
    ax_mag.grid(True, which="both", alpha=0.3)
    ax_mag.legend(fontsize=8)
    fig.tight_layout()
    return fig


#: image formats the commands write, by file suffix
FIGURE_FORMATS = ("png", "pdf", "svg")


def figure_bytes(fig, target) -> bytes:
    """``fig`` rendered in memory in the format the suffix of ``target`` names, then closed.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure to render.
    target : str or Path
        The file the bytes are for: ``.png`` (also without a suffix), ``.pdf`` or ``.svg``.

    Returns
    -------
    bytes
        The encoded image (PNG, PDF or SVG).

    Raises
    ------
    CfdesignError
        Another suffix (the bytes would not be what the name says).
    """
    import io
    from pathlib import Path

    import matplotlib.pyplot as plt

    from .errors import CfdesignError

    fmt = Path(target).suffix.lstrip(".").lower() or "png"
    try:
        if fmt not in FIGURE_FORMATS:
            raise CfdesignError(f"cannot write {target}: unknown image format {fmt!r} "
                                f"(use {', '.join('.' + f for f in FIGURE_FORMATS)})")
        buffer = io.BytesIO()
        fig.savefig(buffer, dpi=120, format=fmt)
        return buffer.getvalue()
    finally:
        plt.close(fig)
