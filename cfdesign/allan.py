r"""Noise identification from a static recording: overlapping Allan deviation and its fits.

A sensor that sits still reads its own errors.  The Allan variance of such a recording,
computed for averaging times ``tau``, separates the error terms by their slopes on a log-log
plot (IEEE Std 952-1997, Annex C; N. El-Sheimy, H. Hou, X. Niu, *Analysis and modeling of
inertial sensors using Allan variance*, IEEE Trans. Instrum. Meas. 57(1), 2008):

.. math::

    \sigma^2(\tau) = \underbrace{\frac{3 Q^2}{\tau^2}}_{\text{quantisation}}
                   + \underbrace{\frac{N^2}{\tau}}_{\text{white noise}}
                   + \underbrace{\frac{2\ln 2}{\pi} B^2}_{\text{bias instability}}
                   + \underbrace{\frac{K^2 \tau}{3}}_{\text{rate random walk}}
                   + \underbrace{\frac{R^2 \tau^2}{2}}_{\text{rate ramp}} .

* ``N`` (white noise density, ``u/sqrt(Hz)``) is the ADEV of the slope -1/2 asymptote read at
  ``tau = 1 s``; it is the design file's ``noise = { density = N }`` (two-sided PSD ``N^2``,
  the convention of :mod:`cfdesign.noise`: ``sigma^2 = N^2 f`` per sample at rate ``f``).
* ``K`` (rate random walk, ``u/sqrt(s)``) is the slope +1/2 asymptote read at ``tau = 3 s``;
  it is ``bias = { model = "random_walk", density = K }`` (the bias rate of change is white
  with PSD ``K^2``).
* ``B`` (bias instability, ``u``) is the flat part divided by ``sqrt(2 ln 2 / pi) = 0.664``.
  A design file has no entry for it (the filters model a random-walk bias); it is reported.

Method (:func:`identify_noise`):

0. a recording that jumps is refused, naming where: an outlier, a step, motion or an integer
   reading that wrapped puts its variance into one or two differences of adjacent block means,
   which for the model's noises are Gaussian with one spread; read as noise, it passed for white
   noise or a rate random walk with a tight interval around the wrong value (the test:
   :data:`~cfdesign.allan.JUMP_FALSE_ALARM`, :data:`~cfdesign.allan.JUMP_SHARE`);
1. the overlapping Allan deviation at octave-spaced ``tau = m / f``, ``m = 1, 2, 4, ...``
   (D. W. Allan's estimator with all overlapping differences; W. J. Riley, *Handbook of
   Frequency Stability Analysis*, NIST SP 1065, 2008, eq. (11)) from the phase
   ``x = cumsum(y) / f`` of the readings ``y``;
2. the equivalent degrees of freedom (EDF) of each point by the simple formulas of Howe,
   Allan and Barnes (*Properties of signal sources and measurement methods*, 1981; Riley
   SP 1065 Table 5) for the noise type that dominates there;
3. a weighted non-negative least-squares fit of the five-term model above in the variance
   domain (``sigma^2`` is linear in ``Q^2, N^2, B^2, K^2, R^2``), each point weighted by the
   inverse of its variance ``2 sigma^4 / edf``, re-weighted with the model until it settles;
4. each term is reported only where the data show it: it must be significant (more than two
   standard errors above zero), it must *dominate* the fitted variance (at least half of it)
   over a ``tau`` range holding at least two points, the recording must resolve the log-log
   slope there (standard error at most :data:`~cfdesign.allan.SLOPE_RESOLUTION`, half the gap to
   the neighbouring terms' slopes at two standard errors), and over that range the measured
   log-log slope must agree with the model's (the slope check) and no point may fall below the
   model beyond its chi-square interval (:data:`~cfdesign.allan.DEPARTURE_LEVEL`, widened by
   :data:`~cfdesign.allan.MODEL_TOLERANCE`; every term adds variance, so nothing left out
   explains a point below the model): a vibrating "rest" is not read as a flat bias instability.  Otherwise the term is
   ``None`` with the reason (for example: a recording too short for the random walk to
   dominate at any ``tau`` it can resolve).  Terms that fail are dropped one at a time - the
   one with the smallest share of the fitted variance first - and the rest refitted: two terms
   that share the last octaves (a random walk and a rate ramp) split them, so that neither
   dominates until the other is gone;
5. over the last octaves of a recording one realisation of a rate random walk can look like a
   ramp.  Where the fit keeps a ramp and no random walk, the random walk is fitted in its place,
   and kept unless it fits clearly worse (its weighted chi-square larger by
   :data:`~cfdesign.allan.RAMP_EVIDENCE`): the common gyro term, and the one a design file takes;
   likewise a reported bias instability or random walk gives way to the other where the other fits
   the same octaves clearly better (the two split the last octaves, and whichever is dropped
   first leaves the other to claim them); and white noise alone is reported where it fits as well:
   every other term must lower the weighted chi-square by ``RAMP_EVIDENCE`` (a few dozen readings
   of white noise, whose last octaves have a degree of freedom or two, were read as a bias
   instability, a quantisation noise or a random walk in place of white noise);
6. confidence intervals (95 %) from the chi-square distribution with the term's own EDF,
   ``2 theta^2 / var(theta)`` with ``var(theta)`` from the fit, counting the correlation of the
   overlapping estimates at neighbouring octaves (strong for a random walk: a fit of its
   octaves has fewer degrees of freedom than its first octave alone), at most the EDF of the
   term's best single point;
7. band-limited readings: a low-pass filter in the sensor (an IMU's digital low-pass or
   anti-alias filter), or readings held over several rows (a sensor logged faster than it
   updates), lowers the Allan deviation of the white noise at the first octaves below ``N^2 /
   tau``, which no term of the model does.  The first octaves are left out of the fit (steps 3-6)
   while each lies below the model of the octaves after it beyond its chi-square interval
   (:data:`~cfdesign.allan.DEPARTURE_LEVEL`) and that model holds white noise from the next
   octave on (``NoiseFit.band_limit_s`` says from where; the summary and the design-file
   entries say so).
8. a term the recording cannot resolve (a random walk or a drift over its last octaves) is dropped,
   but its variance stays there and the terms kept absorbed it (N read 1 to 3 % high against an
   interval of +-1 %).  The octaves from the first one (after :data:`~cfdesign.allan.MIN_FIT_OCTAVES`)
   that lies above the model of the terms identified beyond its chi-square interval
   (:data:`~cfdesign.allan.DEPARTURE_LEVEL`, widened by :data:`~cfdesign.allan.MODEL_TOLERANCE`) are
   left out and the terms identified again on the rest (``NoiseFit.unresolved_from_s`` says from
   where; the summary and the design-file entries say so).

Why not allantools: its ``oadev`` computes the same deviation (the tests and
``benchmarks/bench_noise.py`` hold the two against each other to 1e-12), but the package has
no fit of ``N, B, K`` and installs pytest and numpydoc as run-time requirements; the estimator
itself is a few lines of numpy.  It is the optional ``noise`` extra, used by the benchmark.

numpy and scipy; reading a log file (:func:`read_log_columns`) takes pandas, as ``cfdesign run``
does (``pip install "cfdesign[logs]"``); matplotlib only in :meth:`NoiseFit.plot`.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DataError, InputError
from .files import not_a_device
from .noise import FIGURE_RANGE
from .spec import RATE_RANGE

#: largest magnitude of a reading identify_noise takes: its square and their sums stay doubles
MAX_READING = FIGURE_RANGE[1]

__all__ = ["oadev", "octave_taus", "edf_simple", "identify_noise", "NoiseFit", "NoiseTerm", "TERMS",
           "read_log_columns", "noise_toml", "adev_plot", "nominal_rate"]

#: the terms of the Allan variance model: name -> (symbol, slope of the ADEV, basis of the variance, unit)
TERMS = {
    "quantization": ("Q", -1.0, lambda t: 3.0 / t**2, "u*s"),
    "white": ("N", -0.5, lambda t: 1.0 / t, "u/sqrt(Hz)"),
    "bias_instability": ("B", 0.0, lambda t: np.full_like(t, 2.0 * math.log(2.0) / math.pi), "u"),
    "random_walk": ("K", 0.5, lambda t, dt=0.0: t / 3.0 + dt**2 / (6.0 * t), "u/sqrt(s)"),
    "rate_ramp": ("R", 1.0, lambda t: t**2 / 2.0, "u/s"),
}
#: the noise type (power-law exponent alpha of the frequency PSD) each term is, for the EDF
_ALPHA = {"quantization": 2, "white": 0, "bias_instability": -1, "random_walk": -2, "rate_ramp": -2}
#: fewest samples a recording must have: 17 give the octaves m = 1, 2, 4, 8, over which the slope of
#: white noise is resolved (standard error 0.23, at most ``SLOPE_RESOLUTION``); 16 give three octaves
#: and a standard error of 0.29, over which no term can be reported
MIN_SAMPLES = 17
#: least white noise per reading, in steps of the readings' resolution, whose density is read: a
#: quantiser's output has the variance of its input plus step^2 / 12 once the input's spread is
#: about half a step or more (0.45 step: sqrt(0.45^2 + 1/12) = 0.535); below it the readings'
#: spread depends on where the true value sits between two levels, not on the sensor's noise
RESOLVED_NOISE = 0.535
#: a band limit's deficit below the white noise line (a share of its variance) shrinks from one
#: octave to the next to at most this much of it, unless it is over half the variance (a filter's
#: stop band): a level deficit is not a band limit but the later octaves standing above the line
BAND_LIMIT_DECAY = 0.8
#: fewest octave points the fit keeps when it leaves out the first, band-limited ones
MIN_FIT_OCTAVES = 4
#: share of the fitted variance a term must reach to dominate
DOMINANCE = 0.5
#: how much worse (chi-square) a rate random walk must fit than a rate ramp over the same octaves
#: for the ramp to be reported instead (about a 2-sigma preference for the ramp); likewise how much
#: better a bias instability must fit than a random walk (or the other way) to take its place, and
#: how much each term reported beside white noise must lower it against white noise alone
RAMP_EVIDENCE = 4.0
#: confidence level of the intervals
CONFIDENCE = 0.95
#: largest standard error of the log-log slope over a term's range: two of them must stay within
#: half a unit, the difference between the slopes of neighbouring terms (white -1/2, flat 0, +1/2),
#: or the recording cannot tell the term from its neighbour's continuation
SLOPE_RESOLUTION = 0.25
#: a term is not reported where a point of its range lies below the fitted model by more than its
#: own chi-square interval at this level allows (widened by ``MODEL_TOLERANCE``): every term adds
#: variance, so no term left out explains a deviation below the model - the recording is not the
#: noise the model describes there (a vibrating "rest" read as a flat bias instability)
DEPARTURE_LEVEL = 0.999
#: factor on the ADEV a point may lie below the model beyond its chi-square interval (a real
#: sensor's anti-alias filter lowers the first octaves)
MODEL_TOLERANCE = 1.5
#: chance that a recording of the model's Gaussian noises is refused as jumping (an outlier or a
#: step, :func:`identify_noise`): the limit on the largest difference of adjacent block means,
#: Bonferroni over every difference tested
JUMP_FALSE_ALARM = 1e-6
#: fewest blocks of an octave whose block-mean differences are tested for a jump
MIN_BLOCKS = 128
#: a jump must also exceed this many steps of the readings' resolution (a quantised sensor
#: reading one level most of the time jumps between levels)
JUMP_LSBS = 8
#: share of an octave's mean square of block-mean differences that jumps must hold to be named
#: (the Allan deviation there 5 % higher than without them)
JUMP_SHARE = 0.1
#: mean square of a standard normal variable over its smallest nine tenths in magnitude:
#: (0.9 - 2 z phi(z)) / 0.9 with z = 1.645, the 95th percentile
TRIMMED_SQUARE = 0.6230155


# ---------------------------------------------------------------------------- the deviation
def octave_taus(n_samples: int, rate_hz: float) -> np.ndarray:
    """Octave-spaced averaging factors ``m = 1, 2, 4, ...`` up to ``(n_samples - 1) // 2``.

    Parameters
    ----------
    n_samples : int
        Length of the recording.
    rate_hz : float
        Sample rate (Hz); the averaging times are ``m / rate_hz``.

    Returns
    -------
    ndarray of int
        ``1, 2, 4, ...``, ascending; empty for fewer than three samples.

    Examples
    --------
    >>> from cfdesign.allan import octave_taus
    >>> octave_taus(100, 10.0).tolist()
    [1, 2, 4, 8, 16, 32]
    """
    top = (n_samples - 1) // 2
    return 2 ** np.arange(int(math.log2(top)) + 1) if top >= 1 else np.zeros(0, dtype=int)


def oadev(y, rate_hz: float, m=None):
    """Overlapping Allan deviation of rate readings ``y`` sampled at ``rate_hz``.

    .. math:: \\sigma^2(\\tau) = \\frac{1}{2\\tau^2 (M - 2m)} \\sum_{i=0}^{M-2m-1}
              (x_{i+2m} - 2x_{i+m} + x_i)^2,\\qquad x_i = \\frac{1}{f}\\sum_{j<i} y_j

    with ``M = len(y) + 1`` phase points and ``tau = m / f`` (Riley, NIST SP 1065, eq. (11);
    the same as ``allantools.oadev(y, rate, 'freq', taus)``).

    Parameters
    ----------
    y : array_like
        Readings at a constant rate, in the sensor's unit ``u`` (rad/s for a gyro).
    rate_hz : float
        Sample rate of ``y`` (Hz).
    m : array_like of int, optional
        Averaging factors; default :func:`octave_taus`.

    Returns
    -------
    (tau_s, adev, m) : tuple of ndarray
        Averaging times ``m / rate_hz`` (s), the Allan deviation at each (in the unit of ``y``), and
        the averaging factors used.
    """
    y = np.asarray(y, dtype=float)
    m = octave_taus(len(y), rate_hz) if m is None else np.asarray(m, dtype=int)
    x = np.concatenate([[0.0], np.cumsum(y - y.mean())]) / rate_hz  # the mean changes no difference
    M = len(x)
    out = np.empty(len(m))
    buffer = np.empty(M)  # one array for every octave's differences, formed in place: 2.3 times faster
    for k, mk in enumerate(m):  # on 1e7 readings than x[2m:] - 2 x[m:-m] + x[:-2m] and its three temporaries
        d = buffer[:M - 2 * mk]
        np.subtract(x[2 * mk:], x[mk:M - mk], out=d)
        d -= x[mk:M - mk]
        d += x[:M - 2 * mk]
        tau = mk / rate_hz
        out[k] = math.sqrt(np.dot(d, d) / (2 * tau**2 * (M - 2 * mk)))
    return m / rate_hz, out, m


def edf_simple(n_phase: int, m, alpha: int):
    """Equivalent degrees of freedom of the overlapping Allan variance.

    The simple formulas of Howe, Allan and Barnes (Riley, NIST SP 1065, Table 5).
    ``allantools.edf_simple`` gives the same values except for flicker FM at ``m = 1``, where
    it drops the square of ``(N - 2)`` in Riley's ``2 (N - 2)^2 / (2.3 N - 4.9)``.

    Parameters
    ----------
    n_phase : int
        Number of phase points (readings + 1).
    m : int or array_like of int
        Averaging factors.
    alpha : int
        Frequency-noise exponent: 2 white PM, 0 white FM, -1 flicker FM, -2 random-walk FM.

    Returns
    -------
    ndarray
        EDF per averaging factor.
    """
    N, m = float(n_phase), np.asarray(m, dtype=float)
    if alpha >= 1:  # white (and flicker) PM
        return (N + 1) * (N - 2 * m) / (2 * (N - m))
    if alpha == 0:
        return (3 * (N - 1) / (2 * m) - 2 * (N - 2) / N) * 4 * m**2 / (4 * m**2 + 5)
    if alpha == -1:
        return np.where(m == 1, 2 * (N - 2) ** 2 / (2.3 * N - 4.9), 5 * N**2 / (4 * m * (N + 3 * m)))
    return (N - 2) / m * ((N - 1) ** 2 - 3 * m * (N - 1) + 4 * m**2) / (N - 3) ** 2


# ---------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class NoiseTerm:
    """One identified term of the Allan variance.

    Attributes
    ----------
    name : str
        ``white``, ``bias_instability``, ``random_walk``, ``quantization`` or ``rate_ramp``.
    symbol : str
        ``N``, ``B``, ``K``, ``Q``, ``R``.
    value : float
        In ``unit`` (the sensor's unit ``u`` per ...).
    ci : (float, float)
        95 % confidence interval.
    tau_range_s : (float, float)
        The averaging times (s) over which the term dominates and was checked.
    slope : float
        The measured log-log slope over that range (the term's own is ``nominal_slope``).
    nominal_slope : float
        The term's own slope (-1/2 for white noise, 0, +1/2 for the random walk, ...).
    edf : float
        Equivalent degrees of freedom of the estimate.
    unit : str
        The term's unit in terms of the sensor's unit ``u`` (``u/sqrt(Hz)``).
    model_slope : float
        The fitted model's slope over that range, all terms together: the slope check compares
        ``slope`` with it (a random walk read where white noise still counts has a model slope
        well below +1/2).  NaN when not recorded.
    """

    name: str
    symbol: str
    value: float
    ci: tuple
    tau_range_s: tuple
    slope: float
    nominal_slope: float
    edf: float
    unit: str
    model_slope: float = math.nan

    def line(self, unit: str = "u") -> str:
        """The term as one line of a summary.

        Parameters
        ----------
        unit : str
            The sensor's unit, substituted for ``u`` in the term's unit.

        Returns
        -------
        str
            ``N = 0.01 rad/s/sqrt(Hz) (95% CI ...; slope ... (fitted model ..., the term
            alone ...) over tau ... s)``.
        """
        unit_text = self.unit.replace("u", unit, 1)
        model = "" if math.isnan(self.model_slope) else f"fitted model {self.model_slope:+.2f}, "
        return (f"{self.symbol} = {self.value:.4g} {unit_text} (95% CI {self.ci[0]:.4g} to {self.ci[1]:.4g}; "
                f"slope {self.slope:+.2f} ({model}the term alone {self.nominal_slope:+.1f}) over tau "
                f"{self.tau_range_s[0]:.3g} to {self.tau_range_s[1]:.3g} s)")


@dataclass(frozen=True)
class NoiseFit:
    """The Allan deviation of one recording and the terms identified in it.

    Attributes
    ----------
    name : str
        The column (sensor) name.
    rate_hz, duration_s : float
        Sample rate (Hz) and length (s) of the recording.
    tau_s, adev, edf : ndarray
        The octave-spaced overlapping Allan deviation and each point's EDF.
    terms : dict
        ``{term name: NoiseTerm}`` for the terms the data show.
    missing : dict
        ``{term name: reason}`` for the terms of the model that are not reported.
    coefficients : dict
        ``{term name: coefficient}`` of the fitted Allan variance model (:data:`TERMS`).
    band_limit_s : float or None
        Where the octaves below this ``tau`` were left out of the fit, as band-limited (a low-pass
        filter in the sensor, or readings held over several rows, lowers them below the white
        noise line); None when every octave was fitted.
    unresolved_from_s : float or None
        Where the octaves from this ``tau`` on were left out of the fit, as lying above the fitted
        model beyond their chi-square interval (a random walk or a drift the recording cannot
        resolve, which the terms reported would otherwise absorb); None when none was.

    Examples
    --------
    >>> import numpy as np
    >>> import cfdesign
    >>> x = 0.01 * np.sqrt(100.0) * np.random.default_rng(0).standard_normal(360_000)
    >>> fit = cfdesign.identify_noise(x, rate_hz=100.0, name="gyro_x")  # 1 h, N = 0.01 u/sqrt(Hz)
    >>> round(fit.white_density, 4), fit.random_walk_density
    (0.01, None)
    >>> fit.design_entries()  # doctest: +ELLIPSIS
    {'noise': {'density': 0.0100...}}
    """

    name: str
    rate_hz: float
    duration_s: float
    tau_s: np.ndarray
    adev: np.ndarray
    edf: np.ndarray
    terms: dict
    missing: dict
    coefficients: dict = field(default_factory=dict)
    band_limit_s: float | None = None
    unresolved_from_s: float | None = None

    # the three figures of a design file
    @property
    def white_density(self) -> float | None:
        """``N`` in ``u/sqrt(Hz)``: the design file's ``noise.density``; None when not shown."""
        return self._value("white")

    @property
    def bias_instability(self) -> float | None:
        """``B`` in ``u`` (reported; a design file has no entry for it); None when not shown."""
        return self._value("bias_instability")

    @property
    def random_walk_density(self) -> float | None:
        """``K`` in ``u/sqrt(s)``: the design file's ``bias.density``; None when not shown."""
        return self._value("random_walk")

    def _value(self, name):
        term = self.terms.get(name)
        return None if term is None else term.value

    def adev_ci(self, level: float = 0.683) -> tuple:
        """Chi-square confidence interval of every ADEV point (Riley, NIST SP 1065, eq. (43)).

        Parameters
        ----------
        level : float
            Confidence level (0.683: one sigma).

        Returns
        -------
        low, high : ndarray
            Bounds at ``tau_s``, in the sensor's unit.
        """
        from scipy.stats import chi2

        lo = self.adev * np.sqrt(self.edf / chi2.ppf(0.5 + level / 2, self.edf))
        hi = self.adev * np.sqrt(self.edf / chi2.ppf(0.5 - level / 2, self.edf))
        return lo, hi

    def model_adev(self, tau_s, terms=None) -> np.ndarray:
        """The fitted Allan deviation.

        Parameters
        ----------
        tau_s : array_like
            Averaging times (s).
        terms : sequence of str, optional
            Only these terms (their asymptotes); default every reported term.

        Returns
        -------
        ndarray
            ADEV in the sensor's unit.
        """
        tau_s = np.asarray(tau_s, dtype=float)
        names = self.terms if terms is None else terms
        A = _basis(tau_s, 1.0 / self.rate_hz if terms is None else 0.0)
        return np.sqrt(sum((self.coefficients[k] * A[:, list(TERMS).index(k)] for k in names), np.zeros_like(tau_s)))

    def design_entries(self) -> dict:
        """The design-file fields the data support.

        Returns
        -------
        dict
            ``{'noise': {'density': N}, 'bias': {'model': 'random_walk', 'density': K}}``, each
            only when identified (a design file's ``[sensors.NAME]`` fields).
        """
        out = {}
        if self.white_density is not None:
            out["noise"] = {"density": self.white_density}
        if self.random_walk_density is not None:
            out["bias"] = {"model": "random_walk", "density": self.random_walk_density}
        return out

    def summary(self, unit: str = "u") -> str:
        """Plain text: one line per term found, one per term not shown with its reason.

        Parameters
        ----------
        unit : str
            The sensor's unit (``rad/s``), substituted for ``u``.

        Returns
        -------
        str
            The lines, separated by newlines, with ``unit`` in the values' units.
        """
        unit = _comment(unit)
        lines = [f"{_comment(self.name)}: {self.duration_s:.6g} s at {self.rate_hz:.6g} Hz, Allan deviation at "
                 f"{len(self.tau_s)} octave-spaced tau from {self.tau_s[0]:.3g} to {self.tau_s[-1]:.3g} s"]
        if self.band_limit_s is not None:
            lines.append(f"  {_band_limit_text(self.band_limit_s)}")
        if self.unresolved_from_s is not None:
            lines.append(f"  {_unresolved_text(self.unresolved_from_s)}")
        for key in TERMS:
            if key in self.terms:
                lines.append(f"  {_LABELS[key]}: {self.terms[key].line(unit)}")
            elif key in _REPORTED:
                lines.append(f"  {_LABELS[key]}: not identified ({self.missing[key]})")
        if "rate_ramp" in self.terms:
            lines.append(f"  {_ramp_text()}")
        return "\n".join(lines)

    def plot(self, ax=None, unit: str = "u"):
        """Log-log Allan deviation with 68 % intervals and the fitted asymptotes.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw into (default: a new figure).
        unit : str
            The sensor's unit, for the axis label.

        Returns
        -------
        matplotlib.figure.Figure
            The figure drawn into.
        """
        return adev_plot([self], ax=ax, unit=unit)


def _band_limit_text(tau_s):
    return (f"octaves below tau {tau_s:.3g} s left out of the fit: the Allan deviation there lies below the white "
            "noise of the octaves after them (a low-pass filter in the sensor, or readings held over several rows)")


def _ramp_text():
    """What a rate ramp in a recording at rest usually is, and what it leaves out: its slope +1 (a reading that
    drifts steadily over minutes: a sensor warming up, a platform that moved slowly) takes the last octaves, where
    a rate random walk would show (a gyro with K = 2e-4 turning 0.02 rad/s over 10 min read K not identified)."""
    return ("a rate ramp over a recording at rest is most often a drift or a motion (the sensor warming up, the "
            "platform moving slowly), which hides the rate random walk K of its octaves: record still, after the "
            "warm-up, or cut the recording to a still stretch")


def _unresolved_text(tau_s):
    return (f"octaves from tau {tau_s:.3g} s on left out of the fit: the Allan deviation there lies above the fitted "
            "model (a random walk or a drift the recording is too short to resolve)")


_LABELS = {"quantization": "quantization noise Q", "white": "white noise density N",
           "bias_instability": "bias instability B", "random_walk": "rate random walk K",
           "rate_ramp": "rate ramp R"}
_REPORTED = ("white", "bias_instability", "random_walk")


def identify_noise(x, rate_hz: float, name: str = "sensor") -> NoiseFit:
    """Identify white noise ``N``, bias instability ``B`` and rate random walk ``K`` of a
    static recording from its overlapping Allan deviation (method: module docstring).

    Parameters
    ----------
    x : array_like
        Readings of one axis at a constant rate, sensor at rest, in its unit ``u`` (rad/s
        for a gyro, m/s^2 for an accelerometer).  Finite values only.
    rate_hz : float
        Sample rate (Hz).
    name : str
        Label (the column name).

    Returns
    -------
    NoiseFit
        ``white_density`` (N, u/sqrt(Hz)), ``random_walk_density`` (K, u/sqrt(s)),
        ``bias_instability`` (B, u), each None when the recording does not show the term
        (``missing`` says why), with 95 % confidence intervals and the tau ranges used.

    Raises
    ------
    InputError
        Readings that are not real numbers (text, None, complex, ragged) or of more than one
        axis (an array of shape (n, 3)), fewer than
        :data:`~cfdesign.allan.MIN_SAMPLES` readings, a value that is not finite or
        beyond ``MAX_READING``, a constant recording or one whose spread is below the smallest
        noise figure (``cfdesign.noise.FIGURE_RANGE``), a rate outside 1e-9 to 1e9 Hz, or a
        recording that jumps (an outlier, a step, motion, an integer that wrapped: a difference of
        adjacent block means beyond :data:`~cfdesign.allan.JUMP_FALSE_ALARM` holding at least
        :data:`~cfdesign.allan.JUMP_SHARE` of its octave's mean square; the message says where), or readings
        whose white noise per reading is below :data:`~cfdesign.allan.RESOLVED_NOISE` of their
        resolution (quantisation hides the sensor's noise).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> fit = identify_noise(0.01 * rng.standard_normal(100_000), 100.0)
    >>> round(fit.white_density, 4), fit.random_walk_density   # 0.01 / sqrt(100)
    (0.001, None)
    """
    from .errors import CfdesignError
    from .runtime.filter import real_array

    try:
        y = real_array(x, f"{name}: readings")
    except CfdesignError as exc:  # text, None, complex or ragged readings
        raise InputError(str(exc)) from None
    if sum(size > 1 for size in y.shape) > 1:  # raveled, three axes became one interleaved recording
        raise InputError(f"{name}: readings of shape {y.shape} hold more than one axis; identify_noise takes one "
                         "(one call per column: identify_noise(x[:, i], rate_hz) for i in range(x.shape[1]))")
    y = y.ravel()
    # numbers.Real: numpy's scalars too (a rate of np.float32(100) from a float32 time column was
    # refused as 'not a positive number of hertz')
    if isinstance(rate_hz, (bool, np.bool_)) or not isinstance(rate_hz, numbers.Real) or not (
            RATE_RANGE[0] <= rate_hz <= RATE_RANGE[1]):  # NaN too
        raise InputError(f"{name}: rate_hz must be a positive number of hertz from {RATE_RANGE[0]:g} to "
                         f"{RATE_RANGE[1]:g} (the rates a design file takes), got {rate_hz!r}")
    rate_hz = float(rate_hz)  # a float32 rate would keep every 1 / rate_hz in single precision
    if len(y) < MIN_SAMPLES:
        raise InputError(f"{name}: {len(y)} readings are too few for an Allan deviation whose slopes tell the noise "
                         f"terms apart (at least {MIN_SAMPLES})")
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise InputError(f"{name}: reading {bad[0]} is not finite ({y[bad[0]]}); the Allan deviation needs a "
                         "complete recording (cut it at the gap)")
    bad = np.flatnonzero(np.abs(y) > MAX_READING)
    if bad.size:  # its square overflows: the Allan variance of 1e160 was inf, then a NaN fit
        raise InputError(f"{name}: reading {bad[0]} ({y[bad[0]]:g}) is beyond {MAX_READING:g}, whose squares the "
                         "Allan variance needs (check the units)")
    if np.ptp(y) == 0:
        raise InputError(f"{name}: the readings are constant: no noise to identify (quantised to one level?)")
    if np.ptp(y) < FIGURE_RANGE[0]:  # their squares underflow: an Allan variance of zeros, then an empty fit
        raise InputError(f"{name}: the readings vary by {np.ptp(y):g} only, below {FIGURE_RANGE[0]:g}, the smallest "
                         "noise figure a design takes (check the units)")
    _check_still(y, float(rate_hz), name)
    tau, adev, m = oadev(y, float(rate_hz))
    keep = adev > 0
    tau, adev, m = tau[keep], adev[keep], m[keep]
    start, fit = _band_limit(tau, adev, m, len(y), float(rate_hz))
    _check_resolved(y, float(rate_hz), fit[1].get("white"), name)
    edf = np.concatenate([np.maximum(edf_simple(len(y) + 1, m[:start], 0), 1.0), fit[3]])
    coefficients = {k: fit[0][i] for i, k in enumerate(TERMS) if k in fit[1]}
    stop = start + fit[4]
    return NoiseFit(name, float(rate_hz), len(y) / float(rate_hz), tau, adev, edf, fit[1], fit[2], coefficients,
                    float(tau[start]) if start else None, float(tau[stop]) if stop < len(tau) else None)


def _check_resolved(y, rate_hz, white, name):
    """InputError where the white noise per reading is below :data:`RESOLVED_NOISE` steps of the
    readings' resolution (the smallest change between adjacent readings): the readings hold too few
    levels for their spread to be the sensor's noise.  With a spread per reading of 0.1 to 0.35 steps
    the density came out 0.2 to 5 times the sensor's, with a tight interval, depending only on where
    the true value sat between two levels."""
    if white is None:
        return
    d = np.diff(y)
    step = float(np.min(np.abs(d[d != 0]))) if d.any() else 0.0
    sigma = white.value * math.sqrt(rate_hz)
    if sigma < RESOLVED_NOISE * step:
        raise InputError(f"{name}: the readings' white noise, {sigma:.3g} per reading, is below {RESOLVED_NOISE:g} of "
                         f"their resolution ({step:.4g} between levels): quantisation hides the sensor's noise and no "
                         "density can be read from them; record at a finer resolution (a smaller range, more "
                         "digits in the log)")


def _band_limit(tau, adev, m, n, rate_hz):
    """``(start, fit)``: the octaves from ``start`` on fitted (:func:`_identify`), those before it
    left out where the readings are band-limited: a sensor's low-pass filter, or readings held
    over several rows (a sensor logged faster than it updates), lowers the Allan deviation of its
    white noise at the first octaves (by about ``1.5 tau_c / tau`` in variance for a filter of time
    constant ``tau_c``), below the ``N^2 / tau`` of every term of the model.  Fitted with them, a
    1 kHz gyro behind a 2nd-order low-pass at 350 Hz or below, or one held over two rows, had no
    term identified at all, and at 400 Hz ``N`` came out 8 % low.  An octave is left out while it
    lies below the model of the octaves after it beyond its chi-square interval
    (:data:`~cfdesign.allan.DEPARTURE_LEVEL`), its deficit shrinks toward the next octave
    (:data:`~cfdesign.allan.BAND_LIMIT_DECAY`), and that model holds white noise from the next
    octave on; at most half the octaves, and all but :data:`~cfdesign.allan.MIN_FIT_OCTAVES`."""
    from scipy.stats import chi2

    fits = {}

    def fit_from(s):
        if s not in fits:
            fits[s] = _identify(tau[s:], adev[s:], m[s:], n, rate_hz)
        return fits[s]

    def below(s):  # the octaves before s band-limited, against the model of those from s on
        fit = fit_from(s)
        white = fit[1].get("white")
        if white is None or white.tau_range_s[0] != tau[s]:
            return False
        model = _basis(tau[:s + 1], 1.0 / rate_hz) @ fit[0]
        edf = np.maximum(edf_simple(n + 1, m[:s], 0), 1.0)
        ratio = adev[:s + 1] ** 2 / model
        if not np.all(ratio[:s] < chi2.ppf(1 - DEPARTURE_LEVEL, edf) / edf):
            return False
        # a band limit's deficit shrinks with tau (about as 1 / tau once it is a small part): a
        # deficit that stays level is the octaves after it standing above the white noise line
        deficit = 1.0 - ratio
        return bool(np.all((deficit[1:] <= BAND_LIMIT_DECAY * deficit[:-1]) | (deficit[:-1] > 0.5)))

    last = min(len(tau) // 2, len(tau) - MIN_FIT_OCTAVES)
    for start in range(last + 1):
        if (below(start) if start else "white" in fit_from(0)[1]):
            while start < last and below(start + 1):  # the next octave is band-limited too
                start += 1
            return start, fit_from(start)
    return 0, fit_from(0)


def _identify(tau, adev, m, n, rate_hz):
    """The terms the octave points show (method steps 3-5 and 8 of the module docstring):
    ``(coef, terms, missing, edf, stop)``, the octaves from ``stop`` on left out of the fit as
    lying above its model (:func:`_above_model`; ``stop = len(tau)`` when none is), ``edf``
    for every octave."""
    fit = _identify_octaves(tau, adev, m, n, rate_hz)
    stop = _above_model(tau, adev, fit, rate_hz)
    if stop == len(tau):
        return (*fit, stop)
    # the refit may leave out more octaves (its model is lower): the first octave left out is its stop
    coef, terms, missing, edf, first = _identify(tau[:stop], adev[:stop], m[:stop], n, rate_hz)
    parts = _basis(tau[stop:], 1.0 / rate_hz) * coef
    tail = _edf(parts, m[stop:], n + 1) if parts.any() else np.maximum(edf_simple(n + 1, m[stop:], 0), 1.0)
    return coef, terms, missing, np.concatenate([edf, tail]), first


def _above_model(tau, adev, fit, rate_hz) -> int:
    """The first octave (at least :data:`MIN_FIT_OCTAVES` in) whose Allan variance lies above the
    fit's model beyond its chi-square interval at :data:`DEPARTURE_LEVEL`, widened by
    :data:`MODEL_TOLERANCE` (``len(tau)`` when none does): a term the recording cannot resolve
    (a random walk or a drift over its last octaves, dropped as unresolved) whose variance the
    terms kept would otherwise absorb.  Fitted with them, ten minutes of white noise and a random
    walk reported as white noise alone had N high by up to 3 % against 95 % intervals of +-1 %
    (12 of 17 such recordings covered N)."""
    from scipy.stats import chi2

    coef, _, _, edf = fit
    model = np.maximum(_basis(tau, 1.0 / rate_hz) @ coef, 1e-300)
    high = chi2.ppf(DEPARTURE_LEVEL, edf) / edf * MODEL_TOLERANCE**2
    above = np.flatnonzero(adev[MIN_FIT_OCTAVES:] ** 2 > model[MIN_FIT_OCTAVES:] * high[MIN_FIT_OCTAVES:])
    return int(above[0]) + MIN_FIT_OCTAVES if above.size else len(tau)


def _identify_octaves(tau, adev, m, n, rate_hz):
    """:func:`_identify` over every octave given: ``(coef, terms, missing, edf)``."""
    fit = _eliminate(tau, adev, m, n, rate_hz, list(TERMS))
    terms = fit[1]
    if "rate_ramp" in terms and "random_walk" not in terms:
        # over the last few octaves of a recording one realisation of a rate random walk can
        # look like a ramp; where the random walk explains the same octaves in place of the ramp,
        # it is the model kept (the common gyro term, and the one a design file takes)
        active = [k for k in TERMS if k in terms or k == "random_walk"]
        walk = _eliminate(tau, adev, m, n, rate_hz, [k for k in active if k != "rate_ramp"])
        worse = _misfit(tau, adev, walk, 1.0 / rate_hz) - _misfit(tau, adev, fit, 1.0 / rate_hz)
        if "random_walk" in walk[1] and worse < RAMP_EVIDENCE:
            walk[2]["rate_ramp"] = (f"a rate random walk explains the same octaves (from "
                                    f"{walk[1]['random_walk'].tau_range_s[0]:.3g} s); the recording cannot tell "
                                    "a ramp from it" + _longer_hint("rate_ramp", n / rate_hz))
            fit = walk
    fit = _swap_long_terms(tau, adev, m, n, rate_hz, fit)
    return _white_alone(tau, adev, m, n, rate_hz, fit)


def _check_still(y, rate_hz, name):
    """InputError where the recording jumps: an outlier, a step, motion or a wrapped integer.

    The Allan variance at ``tau = m / f`` is half the mean square of the differences ``d_j``
    between the means of adjacent blocks of ``m`` readings.  For the noises of the model those
    differences are Gaussian with one variance, so none strays far from their typical size (taken
    from the mean square of the smallest nine tenths of those not zero, which a few jumps do not
    move); a single outlier or step puts its variance into one or two of them and, read through
    the Allan deviation, passes for white noise or a rate random walk with a tight interval around
    the wrong value.  At every octave with at least :data:`MIN_BLOCKS` blocks, a difference beyond
    :data:`JUMP_FALSE_ALARM` (Bonferroni over every difference tested), larger than
    :data:`JUMP_LSBS` steps of the readings' resolution (a quantised sensor reads one level most
    of the time and jumps between levels) is a jump; the largest is named where the jumps are
    material (their excess over the typical square at least :data:`JUMP_SHARE` of the
    octave's mean square and two of its standard errors)."""
    from scipy.stats import norm

    n = len(y)
    x = np.concatenate([[0.0], np.cumsum(y - y.mean())])
    octaves = [mk for mk in octave_taus(n, rate_hz) if n // mk >= MIN_BLOCKS]
    tested = sum(n // mk - 1 for mk in octaves)
    limit = float(norm.isf(JUMP_FALSE_ALARM / (2 * max(tested, 1))))
    worst, resolution = None, None
    for mk in octaves:
        d = np.diff(np.diff(x[::mk][: n // mk + 1]) / mk)
        # the spread from the mean square of the smallest nine tenths of the differences that are
        # not zero (a normal variable's is TRIMMED_SQUARE times its variance): a flood of jumps (an
        # int16 reading wrapping at one sample in twenty) is not its own scale, and a sensor logged
        # faster than it reads (each value held over a few rows: differences of zero) does not shrink it
        dd = d[d != 0] ** 2
        if not dd.size:
            continue
        keep = max(1, int(0.9 * len(dd)))
        spread = math.sqrt(float(np.mean(np.partition(dd, keep - 1)[:keep])) / TRIMMED_SQUARE)
        big = np.abs(d) > limit * spread
        if not big.any():
            continue
        if resolution is None:
            levels = np.unique(y)
            resolution = float(np.min(np.diff(levels)))
        big &= np.abs(d) > JUMP_LSBS * resolution
        # significant, and material: their excess over the typical square is at least JUMP_SHARE of
        # the octave's mean square and two of its standard errors (a gyro whose noise has heavier
        # tails than a normal one, 10-sigma differences among 11,000 that move its Allan deviation
        # by 1.7 %, is noise, not a jump)
        excess = float(np.sum(d[big] ** 2)) - big.sum() * spread**2
        if big.any() and excess > max(JUMP_SHARE, 2 * math.sqrt(2 / len(d))) * float(np.dot(d, d)):
            j = int(np.argmax(np.abs(d)))
            z = abs(d[j]) / spread if spread > 0 else math.inf
            if worst is None or z > worst[0]:
                worst = (z, mk, j, float(d[j]))
    if worst is None:
        return
    z, mk, j, jump = worst
    at = (j + 1) * mk
    over = "reading" if mk == 1 else f"mean over {mk} readings"
    raise InputError(f"{name}: the recording jumps near reading {at} ({at / rate_hz:.6g} s from its start): the {over} "
                     f"changes by {jump:.4g}, {z:.3g} times the typical such change over the recording (at most "
                     f"{limit:.3g} for the noise of a sensor at rest); an outlier, a step, motion or an integer "
                     "reading that wrapped? Cut the recording to a still stretch")


def _swap_long_terms(tau, adev, m, n, rate_hz, fit):
    """A bias instability and a random walk that share the last octaves split them, and the one
    dropped first leaves the other to claim them (an hour of white noise and flicker at 50 Hz: B
    dominated two octaves, was dropped as unresolved, and a K of slope -0.04 took the range).
    Each reported one is refitted with the other in its place, and the other kept where it fits
    clearly better (weighted chi-square lower by :data:`~cfdesign.allan.RAMP_EVIDENCE`)."""
    pair = ("bias_instability", "random_walk")
    for x in pair:
        y = pair[1 - pair.index(x)]
        if x not in fit[1] or y in fit[1]:
            continue
        active = [k for k in TERMS if (k in fit[1] and k != x) or k == y]
        alt = _eliminate(tau, adev, m, n, rate_hz, active)
        here, there = _misfit(tau, adev, fit, 1.0 / rate_hz), _misfit(tau, adev, alt, 1.0 / rate_hz)
        if y in alt[1] and there < here - RAMP_EVIDENCE:
            alt[2][x] = (f"the {_LABELS[y]} explains the same octaves better (weighted chi-square {there:.3g} against "
                         f"{here:.3g})")
            return alt
    return fit


def _white_alone(tau, adev, m, n, rate_hz, fit):
    """White noise alone where the terms reported beside or instead of it do not earn their place
    (each must lower the weighted chi-square by :data:`~cfdesign.allan.RAMP_EVIDENCE`), or where
    nothing is reported.  A term that takes most of the first octaves leaves white noise 'not
    significant', and the elimination then dropped white noise first, ending on a model that fitted
    worse than white noise alone, or on none: 20 to 64 readings of white noise reported a bias
    instability, a quantisation noise or a random walk (in a design file's bias) in place of N in
    38 % to 1 % of recordings, and no term at all in up to 11 %."""
    extra = len(set(fit[1]) - {"white"})
    if "white" in fit[1] and not extra:
        return fit
    alt = _eliminate(tau, adev, m, n, rate_hz, ["white"])
    here, there = _misfit(tau, adev, fit, 1.0 / rate_hz), _misfit(tau, adev, alt, 1.0 / rate_hz)
    if "white" not in alt[1] or there >= here + RAMP_EVIDENCE * extra:
        return fit
    for key in fit[1]:
        if key != "white":
            alt[2][key] = (f"white noise alone fits the recording about as well (weighted chi-square {there:.3g}, "
                           f"{here:.3g} with the other terms: each must lower it by {RAMP_EVIDENCE:g})"
                           + _longer_hint(key, n / rate_hz))
    return alt


def _misfit(tau, adev, fit, dt) -> float:
    """Weighted squared misfit of a fit's variance model (each octave point's variance estimate
    has a relative std of ``sqrt(2 / edf)``): a chi-square, to compare two models."""
    coef, _, _, edf = fit
    model = np.maximum((_basis(tau, dt) * coef).sum(axis=1), 1e-300)
    with np.errstate(over="ignore"):  # a model without the recording's term: inf, the worst fit
        return float(np.sum(edf / 2.0 * (adev**2 / model - 1.0) ** 2))


def _eliminate(tau, adev, m, n, rate_hz, active):
    """Fit the ``active`` terms, drop the one the data show least, refit with the rest, until
    every term left is identified: ``(coef, terms, missing, edf)``."""
    active, dropped = list(active), {}
    while True:
        coef, cov, edf, used, vscale = _fit(tau, adev**2, m, n + 1, active, 1.0 / rate_hz)
        terms, missing = _terms(tau, adev, edf, coef, cov, vscale, used, n / rate_hz, 1.0 / rate_hz)
        gone = [k for k in active if k not in terms]
        if not gone:
            break
        # one at a time: terms that share a stretch of tau (a random walk and a rate ramp over
        # the last octaves of an hour) split it, so neither dominates until the other is gone
        weakest = min(gone, key=lambda k: _largest_share(tau, coef, k, 1.0 / rate_hz))
        dropped[weakest] = missing[weakest]
        active.remove(weakest)
    return coef, terms, {**missing, **dropped}, edf  # a dropped term keeps the reason it was dropped for


def _largest_share(tau, coef, key, dt):
    """The largest share of the fitted Allan variance a term has at any tau (0 when unused)."""
    parts = _basis(tau, dt) * coef
    share = parts[:, list(TERMS).index(key)] / np.maximum(parts.sum(axis=1), 1e-300)
    return float(share.max(initial=0.0))


def _basis(tau, dt=0.0):
    """Columns: each term's variance per unit coefficient; the random walk of sampled readings
    has ``K^2 (tau / 3 + dt^2 / (6 tau))`` exactly (the second part vanishes for long tau)."""
    return np.column_stack([TERMS[k][2](tau, dt) if k == "random_walk" else TERMS[k][2](tau) for k in TERMS])


def _edf(model_parts, m, n_phase):
    """EDF of every point for the noise type that dominates the model there."""
    dominant = np.argmax(model_parts, axis=1)
    names = list(TERMS)
    out = np.array([float(edf_simple(n_phase, mk, _ALPHA[names[d]])) for mk, d in zip(m, dominant, strict=True)])
    return np.maximum(out, 1.0)


def _fit(tau, var, m, n_phase, active, dt):
    """Weighted NNLS of the variance model with the ``active`` terms; ``(coef, cov, edf, used, vscale)``,
    ``cov`` the covariances of ``coef / vscale``: ``cov[0]`` taking the octave points as independent
    (the weights' own), ``cov[1]`` counting their correlation (:func:`_octave_correlation`)."""
    from scipy.optimize import nnls

    A = _basis(tau, dt) * np.array([k in active for k in TERMS], dtype=float)
    # at unit scale (a power of two: exact): the weights are 1 / variance and the normal
    # equations their squares, which overflowed or underflowed for readings of 1e-75 (a CI to inf)
    vscale = 2.0 ** round(math.log2(float(np.median(var))))
    var = var / vscale
    model = var.copy()
    edf = np.asarray(edf_simple(n_phase, m, 0), dtype=float).clip(1.0)
    coef = np.zeros(A.shape[1])
    for _ in range(8):
        w = np.sqrt(edf / 2.0) / model  # 1 / std of each variance estimate
        scale = np.abs(A * w[:, None]).max(axis=0)
        scale[scale == 0] = 1.0
        sol, _ = nnls(A * w[:, None] / scale, var * w, maxiter=50 * A.shape[1])
        new = sol / scale
        parts = A * new
        model_new = np.maximum(parts.sum(axis=1), 1e-300)
        edf = _edf(parts, m, n_phase)
        if np.allclose(new, coef, rtol=1e-6, atol=0):
            coef, model = new, model_new
            break
        coef, model = new, model_new
    used = coef > 0
    w = np.sqrt(edf / 2.0) / model
    Aw = (A * w[:, None])[:, used]
    cov = np.zeros((2, A.shape[1], A.shape[1]))
    if used.any():
        # the fit is a linear map of the variance estimates, coef = P Aw' w var; the estimates of
        # overlapping octaves are correlated (R), so its covariance is the sandwich P Aw' R Aw P
        # and not P alone, which took them as independent
        P = np.linalg.pinv(Aw.T @ Aw)
        both = np.ix_(used, used)
        cov[0][both] = P
        cov[1][both] = P @ Aw.T @ _octave_correlation(m, parts, n_phase) @ Aw @ P
    return coef * vscale, cov, edf, used, vscale  # cov: of coef / vscale (its square underflowed at 1e-100)


#: octaves below which the correlation of two Allan variance estimates is tabulated exactly; from
#: ``m = 2**_CORR_OCTAVES`` on it depends on their distance in octaves only (to three digits)
_CORR_OCTAVES = 4
#: octaves apart up to which the correlation is tabulated; beyond, it falls by the last ratio
_CORR_SPAN = 8


@functools.cache
def _correlation_table(alpha: int) -> np.ndarray:
    """Correlation of the overlapping Allan variance estimates at ``m = 2**j`` and ``2**(j + d)``
    of a long recording of one power-law noise: ``[j, d]`` for ``j <= _CORR_OCTAVES``,
    ``d <= _CORR_SPAN``.

    Each estimate is the mean square of a filter ``h_m`` of the noise's white innovations (block
    means ``m`` apart, differenced; for a random walk its running sum, for white phase noise its
    difference), so two of them have the covariance ``2 sum_l r(l)^2 / n`` with ``r = h_j * h_k``
    their cross-correlation: the correlation is ``|h_j * h_k|^2 / (|h_j * h_j| |h_k * h_k|)``.
    Flicker frequency noise has no finite filter; it takes the random walk's (larger) values.
    """
    def h(mk):
        hy = np.concatenate([-np.ones(mk), np.ones(mk)]) / mk
        if alpha <= -1:
            return np.cumsum(hy)[:-1]
        if alpha >= 1:
            return np.diff(np.concatenate([[0.0], hy, [0.0]]))
        return hy

    def cross(a, b):
        ha, hb = h(a), h(b)[::-1]
        size = len(ha) + len(hb) - 1
        c = np.fft.irfft(np.fft.rfft(ha, size) * np.fft.rfft(hb, size), size)
        return float(np.dot(c, c))

    out = np.empty((_CORR_OCTAVES + 1, _CORR_SPAN + 1))
    for j in range(_CORR_OCTAVES + 1):
        for d in range(_CORR_SPAN + 1):
            a, b = 2**j, 2 ** (j + d)
            out[j, d] = cross(a, b) / math.sqrt(cross(a, a) * cross(b, b))
    return out


def _octave_correlation(m, parts, n_phase) -> np.ndarray:
    """Correlation matrix of the Allan variance estimates at the octave factors ``m`` (powers of
    two) of a recording of ``n_phase`` phase points whose fitted variance is ``parts`` (one column
    per term of :data:`TERMS`).

    The terms are independent noises, so the covariance of two estimates is the sum of each
    term's (the cross-terms between two noises left out): the term's correlation from
    :func:`_correlation_table` times its share of either estimate's variance, ``parts^2 / edf``.
    """
    j = np.round(np.log2(m)).astype(int)
    lo, d = np.minimum.outer(j, j).clip(max=_CORR_OCTAVES), np.abs(np.subtract.outer(j, j))
    spread = np.zeros(parts.shape)
    for i, key in enumerate(TERMS):
        if parts[:, i].any():
            spread[:, i] = parts[:, i] ** 2 / np.maximum(edf_simple(n_phase, m, _ALPHA[key]), 1.0)
    spread /= np.maximum(spread.sum(axis=1, keepdims=True), 1e-300)
    R = np.zeros((len(m), len(m)))
    for i, key in enumerate(TERMS):
        if spread[:, i].any():
            table = _correlation_table(_ALPHA[key])
            fall = table[:, -1] / table[:, -2]  # per octave beyond the table
            rho = table[lo, np.minimum(d, _CORR_SPAN)] * fall[lo] ** np.maximum(d - _CORR_SPAN, 0)
            share = np.sqrt(spread[:, i])
            R += rho * np.outer(share, share)
    return R


def _terms(tau, adev, edf, coef, cov, vscale, used, duration, dt):
    from scipy.stats import chi2

    A = _basis(tau, dt)
    parts = A * coef
    model = np.maximum(parts.sum(axis=1), 1e-300)
    terms, missing = {}, {}
    for i, key in enumerate(TERMS):
        symbol, slope, _, unit = TERMS[key]
        if not used[i]:
            missing[key] = _absent_reason(key, tau, duration)
            continue
        se = math.sqrt(max(cov[0][i, i], 0.0))  # of coef[i] / vscale
        if coef[i] / vscale <= 2 * se:
            missing[key] = (f"not significant: {symbol}^2 = {coef[i]:.3g} is within two standard errors "
                            f"({se * vscale:.2g}) of zero")
            continue
        share = parts[:, i] / model
        dom = np.flatnonzero(share >= DOMINANCE)
        if dom.size < 2:
            where = "at any tau" if dom.size == 0 else f"at more than one tau ({tau[dom[0]]:.3g} s)"
            missing[key] = (f"it does not dominate the Allan deviation {where} from {tau[0]:.3g} to "
                            f"{tau[-1]:.3g} s" + _longer_hint(key, duration))
            continue
        lo, hi = dom[0], dom[-1]
        sel = np.arange(lo, hi + 1)
        measured = _slope(tau[sel], adev[sel], edf[sel])
        expected = _slope(tau[sel], np.sqrt(model[sel]), edf[sel])
        slope_se = _slope_se(tau[sel], edf[sel])
        if slope_se > SLOPE_RESOLUTION:
            # the last octaves of a recording hold a few degrees of freedom each: a term that
            # dominates only there cannot be checked (white noise read as a flat B over the last
            # two points of ten minutes)
            missing[key] = (f"it dominates only from {tau[lo]:.3g} to {tau[hi]:.3g} s, where the recording gives its "
                            f"slope to +-{slope_se:.2g} (at most +-{SLOPE_RESOLUTION:g} tells it from its neighbours')"
                            + _longer_hint(key, duration))
            continue
        ratio = adev[sel] ** 2 / model[sel]
        # above the model a term the recording cannot resolve may start; below it nothing helps
        low = chi2.ppf(1 - DEPARTURE_LEVEL, edf[sel]) / edf[sel] / MODEL_TOLERANCE**2
        off = np.flatnonzero(ratio < low)
        if off.size:
            j = sel[off[np.argmin(ratio[off])]]
            missing[key] = (f"the Allan deviation falls below the fitted model over its range: {adev[j]:.3g} at tau "
                            f"{tau[j]:.3g} s against {math.sqrt(model[j]):.3g}; the recording is not the noise of the "
                            "model there (motion, vibration or a step?)")
            continue
        if abs(measured - expected) > 3 * slope_se + 0.1:
            missing[key] = (f"the slope check fails: the measured slope {measured:+.2f} over tau {tau[lo]:.3g} to "
                            f"{tau[hi]:.3g} s differs from the model's {expected:+.2f} (expected near {slope:+.1f})")
            continue
        # EDF from the fit's variance counting the correlation of the overlapping octave estimates
        # (_fit; strong for the random walk, whose fit of correlated octaves is worse than its best
        # single point), and at most that of the term's best single point, edf_i share_i^2
        spread = math.sqrt(max(cov[1][i, i], 0.0))
        best = float(np.max(edf[sel] * share[sel] ** 2))
        nu = min(2 * (coef[i] / vscale / spread) ** 2 if spread > 0 else math.inf, best)
        lo_var = coef[i] * nu / chi2.ppf(0.5 + CONFIDENCE / 2, nu)
        hi_var = coef[i] * nu / chi2.ppf(0.5 - CONFIDENCE / 2, nu)
        terms[key] = NoiseTerm(key, symbol, math.sqrt(coef[i]), (math.sqrt(lo_var), math.sqrt(hi_var)),
                               (float(tau[lo]), float(tau[hi])), float(measured), slope, float(nu), unit,
                               float(expected))
    return terms, missing


def _absent_reason(key, tau, duration):
    return f"the fit gives it no share of the Allan variance from {tau[0]:.3g} to {tau[-1]:.3g} s" + \
        _longer_hint(key, duration)


def _longer_hint(key, duration):
    if key in ("random_walk", "rate_ramp", "bias_instability"):
        return f"; a recording longer than {duration:.3g} s may show it"
    return ""


def _slope(tau, adev, edf):
    """Weighted log-log slope (var of log sigma about 1 / (2 edf))."""
    if len(tau) < 2:
        return float("nan")
    w = 2 * edf
    X, Y = np.log(tau), np.log(adev)
    xm, ym = np.average(X, weights=w), np.average(Y, weights=w)
    return float(np.sum(w * (X - xm) * (Y - ym)) / np.sum(w * (X - xm) ** 2))


def _slope_se(tau, edf):
    w = 2 * edf
    X = np.log(tau)
    xm = np.average(X, weights=w)
    return float(1.0 / math.sqrt(np.sum(w * (X - xm) ** 2)))


# ---------------------------------------------------------------------------- output
def _key(name: str) -> str:
    """A design-file sensor name from a column name (an ASCII identifier)."""
    import keyword

    key = "".join(c if (c.isascii() and c.isalnum()) else "_" for c in name).strip("_") or "sensor"
    if key[0].isdigit() or keyword.iskeyword(key):
        key = "s_" + key
    return key


def _keys(names) -> list:
    """Distinct design-file sensor names for the columns (:func:`_key`): a column already named
    so keeps its name, the others take the next free ``_2``, ``_3``, ...  Columns 'gyro x' and
    'gyro_x', or two of Greek letters, both became ``gyro_x`` (``sensor``) and the TOML declared
    one table twice, which no reader takes."""
    names = list(names)
    keys = [name if _key(name) == name else None for name in names]
    taken = set()
    for i, key in enumerate(keys):
        if key is not None and key in taken:
            keys[i] = None
        taken.add(key)
    for i, name in enumerate(names):
        if keys[i] is None:
            key, k = _key(name), 2
            while key in taken:
                key, k = f"{_key(name)}_{k}", k + 1
            keys[i] = key
            taken.add(key)
    return keys


def _comment(text: str) -> str:
    return "".join(c if c.isprintable() and c.isascii() else "?" for c in text)


def noise_toml(fits, source: str = "", unit: str = "u") -> str:
    """Design-file entries (TOML) for every fit, as ``cfdesign noise -o`` writes them.

    ``[sensors.NAME]`` with ``rate_hz``, ``noise = { density = N }`` and
    ``bias = { model = "random_walk", density = K }`` where the recording shows them, the rest
    as comments saying why not.  Beside each SI figure, the comment gives it in the unit of a
    datasheet where the column's unit tells which (``# rad/s/sqrt(Hz) = 0.29 deg/sqrt(h)`` for
    a gyro, ``ug/sqrt(Hz)`` for an accelerometer in m/s^2; :mod:`cfdesign.units`).

    Parameters
    ----------
    fits : sequence of NoiseFit
        The fits to write, one ``[sensor]`` table each.
    source : str
        The log's name, for the header comment.
    unit : str or sequence of str
        The columns' unit (``rad/s``), for the comments: one for every fit, or one per fit (a
        gyro's ``rad/s`` beside an accelerometer's ``m/s^2``).

    Returns
    -------
    str
        TOML text.

    Raises
    ------
    InputError
        A unit that is not text, or a sequence of units whose length is not the number of fits.
    """
    raw = [unit] * len(fits) if isinstance(unit, str) else unit
    units = _units(unit, len(fits))
    lines = [f"# Noise identified by cfdesign noise{' from ' + _comment(source) if source else ''}",
             "# (overlapping Allan deviation; 95% confidence intervals; units: the column's unit u,",
             "#  e.g. rad/s for a gyro: N in u/sqrt(Hz), K in u/sqrt(s), B in u; in a known unit other than",
             "#  SI, N and K are written with it, as text the design file converts to SI).",
             "# Add measures = \"...\" (and port = \"...\" where the structure calls the sensor otherwise,",
             "#  e.g. port = \"rate\" for a cf2's gyro) and copy the tables into your design file.", ""]
    for fit, key, unit, given in zip(fits, _keys(fit.name for fit in fits), units, raw, strict=True):
        lines.append(f"[sensors.{key}]" + (f"   # column {_comment(fit.name)!r}" if key != fit.name else ""))
        lines.append(f"rate_hz = {fit.rate_hz!r}")
        if fit.band_limit_s is not None:
            lines.append(f"# {_band_limit_text(fit.band_limit_s)}")
        if fit.unresolved_from_s is not None:
            lines.append(f"# {_unresolved_text(fit.unresolved_from_s)}")
        white, rw, bi = (fit.terms.get(k) for k in ("white", "random_walk", "bias_instability"))
        if white is not None:
            lines.append(f"noise = {{ density = {_figure(white.value, given, '/sqrt(Hz)')} }}   # {unit}/sqrt(Hz)"
                         f"{_datasheet(white.value, given, 'white')}; " + _ci_text(white))
        else:
            lines.append(f"# noise: not identified ({_comment(fit.missing['white'])})")
        if rw is not None:
            lines.append(f"bias = {{ model = \"random_walk\", density = {_figure(rw.value, given, '/sqrt(s)')} }}"
                         f"   # {unit}/sqrt(s)"
                         f"{_datasheet(rw.value, given, 'random_walk')}; " + _ci_text(rw))
        else:
            lines.append(f"# bias: no random walk identified ({_comment(fit.missing['random_walk'])}); if this is "
                         "the rate sensor of a structure that estimates its bias (a cf2 of order 2's gyro, for one), "
                         "it needs bias = { model = \"random_walk\", density = ... } from a longer recording or the "
                         "datasheet; other sensors need none")
        if bi is not None:
            lines.append(f"# bias instability B = {bi.value:.4g} {unit} ({_ci_text(bi)}); the design "
                         "models the bias as a random walk")
        if "rate_ramp" in fit.terms:
            lines.append(f"# {_ramp_text()}")
        lines.append("")
    return "\n".join(lines)


def _figure(value: float, unit: str, per: str) -> str:
    """The TOML value of a figure ``value`` in ``unit`` ``per`` (``/sqrt(Hz)``): a number where the
    unit is SI or unknown (``u``), else text with its unit (``"0.005 deg/s/sqrt(Hz)"``), which a
    design file converts to SI and checks; a bare 0.005 of a deg/s column read as 0.005 rad/s/sqrt(Hz)."""
    from .errors import SpecError
    from .units import _RMS, parse_unit

    try:
        scale = parse_unit(unit)[0]
    except SpecError:
        return f"{value:.6g}"
    if scale == 1.0:
        return f"{value:.6g}"
    return f'"{value:.6g} {" ".join(_RMS.sub("", unit).split())}{per}"'  # the unit's text: no quote, no backslash


#: the datasheet units of a figure, by the SI unit of the column and the figure
_DATASHEET_UNITS = {("rad/s", "white"): "deg/sqrt(h)", ("rad/s", "random_walk"): "deg/h/sqrt(h)",
                    ("m/s^2", "white"): "ug/sqrt(Hz)", ("m/s^2", "random_walk"): "ug/sqrt(s)",
                    ("T", "white"): "nT/sqrt(Hz)", ("rad", "white"): "deg/sqrt(Hz)"}


def _datasheet(value: float, unit: str, term: str) -> str:
    """``' = 0.29 deg/sqrt(h)'``: a figure in the column's unit in the unit a datasheet gives it
    (a gyro's angle random walk in deg/sqrt(h)), or ``''`` for a unit without one."""
    from .errors import SpecError
    from .units import parse_unit, si_unit

    try:
        scale, dim = parse_unit(unit)
    except SpecError:
        return ""
    shown = _DATASHEET_UNITS.get((si_unit(dim), term))
    if shown is None:
        return ""
    return f" = {value * scale / parse_unit(shown)[0]:.3g} {shown}"


def _units(unit, count) -> list:
    """One unit per fit (``_comment``-safe) from one unit or a sequence of ``count``."""
    units = [unit] * count if isinstance(unit, str) else list(unit) if isinstance(unit, Sequence) else None
    if units is None or not all(isinstance(u, str) for u in units):
        raise InputError(f"unit must be text (rad/s) or a sequence of it, one per fit; got {unit!r}")
    if len(units) != count:
        raise InputError(f"give one unit, or one per column ({count}), not {len(units)}: {', '.join(units)}")
    return [_comment(u) for u in units]


def _ci_text(term):
    return (f"95% CI {term.ci[0]:.4g} to {term.ci[1]:.4g}, fitted over tau {term.tau_range_s[0]:.3g} to "
            f"{term.tau_range_s[1]:.3g} s")


def adev_plot(fits, ax=None, unit: str = "u"):
    """Allan deviation of each fit with its 68 % intervals and fitted asymptotes (over the octaves
    fitted; those left out as band-limited shaded).

    Parameters
    ----------
    fits : sequence of NoiseFit
        The fits to draw, one curve (and its fitted terms) each.
    ax : matplotlib.axes.Axes, optional
        Axes to draw into (default: a new figure).
    unit : str or sequence of str
        The sensors' unit, for the axis label: one for every fit, or one per fit (then named in
        each curve's label).

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn into.

    Raises
    ------
    InputError
        A unit that is not text, or a sequence of units whose length is not the number of fits.
    """
    import matplotlib.pyplot as plt

    units = _units(unit, len(fits))
    mixed = len(set(units)) > 1
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.5, 5))
    else:
        fig = ax.figure
    for fit, u in zip(fits, units, strict=True):
        lo, hi = fit.adev_ci()
        pts = ax.errorbar(fit.tau_s, fit.adev, yerr=[fit.adev - lo, hi - fit.adev], fmt="o", ms=4, capsize=2,
                          label=f"{fit.name}{f' ({u})' if mixed else ''}: overlapping ADEV")
        color = pts[0].get_color()
        grid = np.logspace(np.log10(fit.tau_s[0]), np.log10(fit.tau_s[-1]), 200)
        if fit.band_limit_s is not None:  # the band-limited octaves left out of the fit
            ax.axvspan(fit.tau_s[0] / 1.2, fit.band_limit_s / 1.2, color=color, alpha=0.08,
                       label=f"{fit.name}: left out (band-limited)")
            grid = grid[grid >= fit.band_limit_s]
        if fit.terms:
            ax.loglog(grid, fit.model_adev(grid), "-", color=color, lw=1.5, alpha=0.7, label=f"{fit.name}: fit")
        for key, term in fit.terms.items():
            asym = fit.model_adev(grid, [key])
            ax.loglog(grid, asym, "--", color=color, lw=1, alpha=0.8)
            a, b = term.tau_range_s
            mid = math.sqrt(a * b)
            ax.annotate(f"{term.symbol}={term.value:.3g}", (mid, float(fit.model_adev([mid], [key])[0])),
                        fontsize=8, color=color, textcoords="offset points", xytext=(0, 6))
        for key, read_at in (("white", 1.0), ("random_walk", 3.0)):
            if key in fit.terms:
                ax.plot([read_at], [fit.terms[key].value], "x", color=color, ms=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (each column's unit)" if mixed
                  else f"Allan deviation ({units[0] if units else 'u'})")
    ax.set_title("Allan deviation and fitted asymptotes (x: N read at 1 s, K at 3 s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


# ---------------------------------------------------------------------------- reading a log
#: a rate from a time column is the shortest decimal (of the rate or of the period) this close to the
#: measured one (relative, :func:`nominal_rate`): timestamp jitter and a crystal's tolerance (tens of
#: ppm) are not the sensor's nominal rate
RATE_RTOL = 1e-4
#: largest CSV read for noise identification (bytes)
MAX_LOG_BYTES = 2_000_000_000


def read_log_columns(path, columns, time_column: str | None = None, time_unit: str | None = None, *,
                     find_time: bool = False) -> tuple:
    """Read numeric columns from a log, as ``cfdesign run`` reads logs (:func:`cfdesign.logs.read_columns`).

    The reader ``cfdesign noise`` uses: every named column must exist and hold a number on
    every row; with ``time_column`` the rate is that of the even grid that fits the times best,
    its :func:`nominal_rate` (the shortest decimal rate or period within ``RATE_RTOL`` of it:
    jittered stamps of a 100 Hz sensor give 100, not 99.9999855, a rate no other sensor of a
    design file is a fraction of; stamps 3 ms apart 1000/3, not 333.3),
    and the times must increase steadily: no gap longer than 1.5 steps and no step shorter than
    half of one, unless every time is within half a step of its own tick of the even grid that
    fits them best (time stamps jittered by up to half a step, as ``cfdesign run`` takes them).

    Parameters
    ----------
    path : str or Path
        CSV (a BOM, CRLF, semicolon or tab separators are fine) or Parquet file.
    columns : sequence of str
        Columns to read.
    time_column : str, optional
        Column of times to take the rate from: numbers in ``time_unit``, or ISO 8601 dates.
    time_unit : {'s', 'ms', 'us', 'ns'}, optional
        Unit of a numeric time column (:data:`cfdesign.logs.TIME_UNITS`); by default the one
        its name gives (``time [ms]``), else seconds.
    find_time : bool
        Without ``time_column``, take the log's time column as ``cfdesign run`` finds it
        (``cfdesign.logs.read.time_column``: ``time``, ``t``, ``timestamp``, in any case or
        with a unit), if it has one.

    Returns
    -------
    rate_hz : float or None
        From the time column, else None.
    data : dict
        ``{column: ndarray}``.

    Raises
    ------
    DataError
        One line naming the file and the column or line.
    CfdesignError
        pandas is not installed (``pip install "cfdesign[logs]"``).
    """
    from .logs import read_columns
    from .logs.read import _header, _lines, _pipe, _spooled
    from .logs.read import time_column as time_column_of

    path = Path(path)
    try:
        if path.stat().st_size > MAX_LOG_BYTES:
            raise DataError(f"{path}: larger than {MAX_LOG_BYTES} bytes")
        if not_a_device(path):  # /dev/zero: an endless line
            raise DataError(f"cannot read {path}: {not_a_device(path)}")
    except OSError as exc:
        raise DataError(f"cannot read {path}: {exc.strerror or exc}") from None
    if _pipe(path):  # read once into a file: its lines are counted for the messages too
        with _spooled(path, str(path)) as copy:
            return read_log_columns(copy, columns, time_column, time_unit, find_time=find_time)
    if time_column is None and find_time:
        time_column = time_column_of(_header(path))
    data = read_columns(path, columns, time_column, time_unit)
    where = _lines(path).at  # the file's line of a row (comments, units and blank lines counted), a Parquet row
    for c, v in data.items():
        gap = np.flatnonzero(~np.isfinite(v))
        if gap.size:
            raise DataError(f"{path} {where(gap[0])}: column {_comment(c)!r} is empty or not finite; the "
                            "Allan deviation needs a complete recording (cut the log at the gap)")
    rate = None
    if time_column:
        rate = _rate_from_time(path, time_column, data[time_column], where)
        _check_time_unit(path, time_column, rate, time_unit)
    return rate, {c: data[c] for c in columns}


#: rates (Hz) of a time column in seconds that are taken without a unit given: outside them, times in
#: milliseconds (0.1 Hz for 100 Hz) or a spreadsheet's date numbers in days (8.64 MHz) read as seconds
PLAIN_RATES = (1.0, 1e6)


def _check_time_unit(path, name, rate, time_unit):
    """A DataError when the numbers of the time column ``name``, read as seconds or in the unit its
    name or units row gives (``time (s)`` over milliseconds: a logger's wrong label) but not in a
    ``time_unit`` given, give a rate outside :data:`PLAIN_RATES` (``cfdesign noise`` had run, exit 0,
    on times in milliseconds at 0.1 Hz)."""
    from .logs.columns import _named_unit
    from .logs.read import _row_units, read_log

    if PLAIN_RATES[0] <= rate <= PLAIN_RATES[1] or time_unit is not None:
        return
    named = _named_unit(name, _row_units(path))
    if next(iter(read_log(path, [name], chunksize=64)))[name].dtype.kind not in "fiu":  # dates: seconds
        return
    read = f"in {named} as its name says" if named else "as seconds"
    seen = f"the times in {_comment(name)!r} step by {1 / rate:.6g} s ({rate:.6g} Hz), read {read}"
    raise DataError(f"{path}: {seen}: times in milliseconds, microseconds or nanoseconds? give --time-unit ms|us|ns "
                    "(--time-unit s if they are seconds)" if rate < PLAIN_RATES[0] else
                    f"{path}: {seen}: a spreadsheet's date numbers (days)? write seconds or ISO 8601 dates "
                    "(--time-unit s if they are seconds)")


def _rate_from_time(path, name, t, where) -> float:
    if len(t) < 2:
        raise DataError(f"{path}: column {_comment(name)!r} has fewer than two times")
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        raise DataError(f"{path}: column {_comment(name)!r} does not increase")
    bad = np.flatnonzero((dt > 1.5 * step) | (dt < 0.5 * step))
    unit = _grid_step(t)
    if bad.size and not _on_grid(t, unit):
        i = _grid_break(t, unit) - 1  # the step into the first row the grid breaks at
        raise DataError(f"{path} {where(i + 1)}: column {_comment(name)!r} jumps by {dt[i]:.6g} s where the median "
                        f"step is {step:.6g} s; the Allan deviation needs evenly sampled data (cut the log at the gap)")
    return nominal_rate(1.0 / unit)


def _grid_step(t) -> float:
    """The step of the even grid that fits the times best (least squares): the stamps' jitter
    moves it by far less than it moves the span of the first and last (a log of pairs stamped as
    their packet arrives reads 99.98 Hz from its ends, 100 Hz from the grid)."""
    i = np.arange(len(t), dtype=float) - (len(t) - 1) / 2
    return float(np.dot(i, t - np.mean(t)) / np.dot(i, i))


def _on_grid(t, unit) -> bool:
    """Every time within half a step of its own tick of the grid of step ``unit`` that fits them
    best (as ``cfdesign run`` places jittered rows on the nearest tick,
    :func:`cfdesign.timing.nearest_tick`): a stamp jittered by up to half a step (readings stamped
    when a USB packet arrives) is not a gap; a missing or extra reading moves the rows on one side
    of it half a step or more off the grid."""
    from .timing import nearest_tick

    if not unit > 0:
        return False
    ticks = nearest_tick((t - np.mean(t)) / unit + (len(t) - 1) / 2)
    return bool(np.array_equal(ticks, np.arange(len(t), dtype=float)))


def _grid_break(t, step) -> int:
    """The row where the times leave their grid for good (a missing or extra reading): where the
    mean offset from the grid of the up to 64 rows from it differs most from that of the up to 64
    before it.  A lone jittered stamp moves one row; a gap moves every row after it."""
    n = len(t)
    off = (t - t[0]) / step - np.arange(n)
    w = max(1, min(64, n // 4))
    c = np.concatenate([[0.0], np.cumsum(off)])
    i = np.arange(1, n)
    lo, hi = np.maximum(i - w, 0), np.minimum(i + w, n)
    moved = (c[hi] - c[i]) / (hi - i) - (c[i] - c[lo]) / (i - lo)
    return int(i[np.argmax(np.abs(moved))])


def nominal_rate(rate_hz: float, rtol: float = RATE_RTOL) -> float:
    """The nominal rate a measured one stands for: the shortest decimal within ``rtol`` (relative)
    of the rate, or of the sample period where that is shorter.

    A sensor read every 3 ms runs at 1000/3 Hz: its shortest decimal rate within ``rtol``, 333.3 Hz,
    beside a 1 kHz sensor in a design file, made a schedule of 10,000 steps (ratio 10000/3333)
    instead of 3, and a 3.5 ms period (BROAD's IMU) gave 285.7 Hz.

    Parameters
    ----------
    rate_hz : float
        The rate measured from a time column (Hz).
    rtol : float
        Relative tolerance (default ``RATE_RTOL``).

    Returns
    -------
    float
        The nominal rate: the rate or the period written with the fewest significant digits
        (the rate on a tie), as a rate in Hz.

    Examples
    --------
    >>> from cfdesign.allan import nominal_rate
    >>> nominal_rate(99.99998552563129), nominal_rate(99.5), nominal_rate(104.0016)
    (100.0, 99.5, 104.0)
    >>> nominal_rate(333.3331), 1 / nominal_rate(285.7148)   # periods of 3 ms and 3.5 ms
    (333.3333333333333, 0.0035)
    """
    def shortest(value):
        for digits in range(1, 18):
            r = float(f"{value:.{digits}g}")
            if abs(r - value) <= rtol * value:
                return digits, r
        return 18, value

    (rate_digits, rate), (period_digits, period) = shortest(rate_hz), shortest(1.0 / rate_hz)
    return 1.0 / period if period_digits < rate_digits else rate
