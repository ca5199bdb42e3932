"""Numeric side of a filter with numbers for its gains: python-control models and responses.

No plotting here (see :mod:`cfdesign.plot`) and no sympy: the observer hands over its band
polynomials as float coefficient arrays
(:meth:`Observer.band_coefficients <cfdesign.symbolic.Observer.band_coefficients>`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linear import response

__all__ = ["transfer_functions", "named_transfer_functions", "FrequencyResponse", "frequency_response",
           "default_frequencies", "angular_frequencies"]


def transfer_functions(observer) -> dict:
    """The band of every sensor of a numeric observer as a python-control transfer function.

    Continuous bands are in ``s``; discrete ones carry ``dt`` = the sample time (s).  The
    ``'sum'`` entry is the exact sum reduced by the symbolic proof (``1`` when the filter is
    complementary), not a numerically added model of inflated order.  Each is named after its
    sensor (:func:`named_transfer_functions`).

    Parameters
    ----------
    observer : cfdesign.symbolic.Observer
        With numbers for every gain (and the sample time):
        :meth:`Observer.with_gains <cfdesign.symbolic.Observer.with_gains>`.

    Returns
    -------
    dict
        ``{sensor: control.TransferFunction, ..., 'sum': control.TransferFunction}``.

    Raises
    ------
    GainError
        The observer still has symbolic parameters.
    StructureError
        ``observer`` is not a cfdesign Observer (a python-control system, a gain table).

    Examples
    --------
    >>> import cfdesign
    >>> tfs = cfdesign.transfer_functions(cfdesign.cf2().with_gains(k=2))
    >>> sorted(tfs), tfs["angle"].name, tfs["angle"].input_labels
    (['angle', 'rate', 'sum'], 'T_angle', ['angle'])
    """
    _require_observer(observer, "transfer_functions")
    coefficients = observer.band_coefficients()  # first: a symbolic sample time gave float()'s TypeError
    dt = float(observer.sample_time) if observer.discrete else 0
    return named_transfer_functions(coefficients, dt, observer.name, observer.sum_coefficients())


def _require_observer(observer, what: str) -> None:
    """StructureError unless ``observer`` is a cfdesign Observer (its attributes were read first:
    a python-control system, a gain table or None raised a raw AttributeError)."""
    if hasattr(observer, "band_coefficients") and hasattr(observer, "sample_time"):
        return
    from .errors import StructureError

    if hasattr(observer, "dt") and hasattr(observer, "ninputs"):
        hint = "; build one from a control.StateSpace with Observer.from_statespace(sys, K, sensors)"
    elif hasattr(observer, "transfer_functions") and hasattr(observer, "K"):
        hint = "; a gain table has its own: table.transfer_functions(), table.bode(), table.observer()"
    else:
        hint = ""
    raise StructureError(f"{what} takes a cfdesign Observer with numeric gains, got {type(observer).__name__}{hint}")


def angular_frequencies(omega) -> np.ndarray:
    """A frequency grid given by a caller, checked: text gave numpy's raw ValueError, a matrix a
    broadcast error deep in the plot.

    Parameters
    ----------
    omega : array_like
        Angular frequencies (rad/s).

    Returns
    -------
    ndarray, shape (N,)
        ``omega`` as floats.

    Raises
    ------
    InputError
        ``omega`` is not a non-empty 1-D array of finite real numbers.
    """
    from .errors import InputError

    try:
        w = np.asarray(omega, dtype=float)
    except (TypeError, ValueError):
        w = None
    if w is None or w.ndim != 1 or w.size == 0 or not np.isfinite(w).all():
        shape = "" if w is None else f" of shape {w.shape}"
        raise InputError(f"omega must be a non-empty 1-D array of finite angular frequencies (rad/s), got "
                         f"{type(omega).__name__}{shape}")
    return w


def named_transfer_functions(coefficients: dict, dt, label: str = "", total=None) -> dict:
    """Transfer functions from band polynomials, each named after its sensor.

    System ``'T_<sensor>'``, input ``'<sensor>'`` (the common quantity seen through that
    sensor), output ``'estimate'``; ``'sum'`` (input ``'quantity'``) when ``total`` is given.

    Parameters
    ----------
    coefficients : dict
        ``{sensor: (num, den)}``, highest power first.
    dt : float
        Sample time (s); 0 or None for continuous bands.
    label : str
        Name of the filter (unused in the systems' names; kept for messages).
    total : (num, den), optional
        The sum of the bands.

    Returns
    -------
    dict
        ``{sensor: control.TransferFunction}`` (and ``'sum'``).
    """
    import control

    out = {name: control.tf(num, den, dt or 0, inputs=[name], outputs=["estimate"], name=f"T_{name}")
           for name, (num, den) in coefficients.items()}
    if total is not None:
        out["sum"] = control.tf(*total, dt or 0, inputs=["quantity"], outputs=["estimate"], name="sum")
    return out


def _band_poles(coefficients, dt):
    roots = np.concatenate([np.roots(den) for _, den in coefficients.values()])
    if dt:
        roots = np.log(roots[np.abs(roots) > 0].astype(complex)) / dt
    mags = np.abs(roots[np.abs(roots) > 0])
    return mags


def default_frequencies(coefficients, dt=None, points: int = 800) -> np.ndarray:
    """A frequency grid for the bands' responses.

    Log-spaced two decades either side of the pole magnitudes, capped at Nyquist for
    discrete bands.

    Parameters
    ----------
    coefficients : dict
        ``{sensor: (num, den)}`` band polynomials.
    dt : float, optional
        Sample time (s) of discrete bands.
    points : int
        Number of frequencies.

    Returns
    -------
    ndarray, shape (points,)
        Angular frequencies (rad/s).
    """
    mags = _band_poles(coefficients, dt)
    lo, hi = (mags.min(), mags.max()) if mags.size else (1.0, 1.0)
    lo, hi = lo / 100, hi * 100
    if dt:
        hi = np.pi / dt
        lo = min(lo, hi / 1e4)
    return np.logspace(np.log10(lo), np.log10(hi), points)


@dataclass(frozen=True)
class FrequencyResponse:
    """Complex responses of every band on a frequency grid.

    Attributes
    ----------
    omega : ndarray
        Frequencies in rad/s.
    bands : dict
        ``{sensor: complex ndarray}`` band responses ``T_i(j w)`` or ``T_i(e^{j w dt})``.
    dt : float or None
        Sample time in seconds (discrete) or None (continuous).
    coefficients : dict
        ``{sensor: (num, den)}`` band polynomials (highest power first).
    evaluate : callable, optional
        ``evaluate(omega) -> {sensor: complex ndarray}``, the responses ``bands`` were computed
        with, for :meth:`crossovers` to refine on; default: the band polynomials.  A gain table's
        Bode plot passes its state-space responses, which stay accurate where the polynomials do
        not (poles within rounding of ``z = 1``).
    """

    omega: np.ndarray
    bands: dict
    dt: float | None
    coefficients: dict
    evaluate: object = None

    @property
    def total(self) -> np.ndarray:
        """Sum of the band responses, computed numerically (1 for a complementary filter)."""
        return np.sum(list(self.bands.values()), axis=0)

    def magnitude_db(self, name: str) -> np.ndarray:
        """Magnitude of one band (or ``'sum'``) in dB.

        Parameters
        ----------
        name : str
            Sensor name, or ``'sum'``.

        Returns
        -------
        ndarray
            ``20 log10 |T(j w)|`` on ``omega``.
        """
        resp = self.total if name == "sum" else self.bands[name]
        with np.errstate(divide="ignore"):
            return 20 * np.log10(np.abs(resp))

    def phase_deg(self, name: str) -> np.ndarray:
        """Phase of one band (or ``'sum'``) in degrees, unwrapped.

        Parameters
        ----------
        name : str
            Sensor name, or ``'sum'``.

        Returns
        -------
        ndarray
            Phase (deg) on ``omega``.
        """
        resp = self.total if name == "sum" else self.bands[name]
        return np.degrees(np.unwrap(np.angle(resp)))

    def dominant_order(self) -> list:
        """Band names ordered by the frequency at which each band rises to dominance (low-pass first).

        A band's rise is the lowest frequency of the grid where its magnitude reaches 1/2 (bands
        that sum to one each pass about half the signal where they take over), or, for a band that
        never does (a weak band-pass), half its own peak.  Not the frequency of the peak: in a
        discrete table a band of a rate or acceleration sensor grows without bound towards the
        Nyquist frequency (the held input's zero at z = -1 divided out), where a band-pass and a
        high-pass band then both peaked, and the crossovers were drawn between the wrong bands.
        Bands that rise at the same frequency come larger first there: two heading sensors both
        in the low-pass band (a 0.95 and a 0.05 share from DC) had been taken in name order, the
        weak one first, and the crossover drawn from it rather than from the band that carries DC.

        Returns
        -------
        list of str
            The band (sensor) names, the one that dominates at the lowest frequencies first.
        """
        def rise(v):
            m = np.abs(v)
            i = np.argmax(m >= (0.5 if m.max() >= 0.5 else m.max() / 2))
            return self.omega[i], -m[i]

        first = {k: rise(v) for k, v in self.bands.items()}
        return sorted(first, key=lambda k: (*first[k], k))

    def crossovers(self) -> list:
        """Where adjacent bands have equal magnitude.

        Bands are taken in :meth:`dominant_order`; each hands over to the next band that reaches
        its magnitude where the two are the largest of all bands (a band that stays below, e.g. a
        weak band-pass, is skipped: where it meets another band a third one is larger, so no
        hand-over happens there).  The first such sign change of ``log|T_a| - log|T_b|`` on the
        grid, from one strict sign to the other (a band that only touches another is no
        hand-over), is refined with Brent's method on the responses the grid was computed with
        (``evaluate``; by default the band polynomials).

        Returns
        -------
        list of (str, str, float)
            ``(band_a, band_b, w)`` with ``w`` in rad/s.

        Examples
        --------
        >>> import cfdesign
        >>> resp = cfdesign.frequency_response(cfdesign.cf3().with_gains(k1=2, k2=1))
        >>> [(a, b, round(w, 6)) for a, b, w in resp.crossovers()]
        [('position', 'velocity', 0.5), ('velocity', 'acceleration', 2.0)]
        """
        order = self.dominant_order()
        found, current = [], order[0] if order else None
        for b in order[1:]:
            w = self._equal_magnitude(current, b)
            if w is not None:
                found.append((current, b, w))
                current = b
        return found

    def _log_ratio(self, a, b, w):
        # refined on the responses the grid holds: polynomials that had lost poles near z = 1 had
        # no sign change where the state-space grid had one (brentq's 'f(a) and f(b) must have
        # different signs' from a gain table's Bode plot)
        if self.evaluate is not None:
            bands = self.evaluate(np.array([w], dtype=float))
            return float(np.log(np.abs(bands[a][0])) - np.log(np.abs(bands[b][0])))
        return (np.log(np.abs(response(*self.coefficients[a], w, self.dt)))
                - np.log(np.abs(response(*self.coefficients[b], w, self.dt))))

    def _equal_magnitude(self, a, b):
        from scipy.optimize import brentq

        with np.errstate(divide="ignore"):
            d = np.log(np.abs(self.bands[a])) - np.log(np.abs(self.bands[b]))
        pair = np.maximum(np.abs(self.bands[a]), np.abs(self.bands[b]))
        others = [np.abs(v) for k, v in self.bands.items() if k not in (a, b)]
        # on the upper envelope: a weak band meeting a band where a third one dominates is no hand-over
        # (a 0.05-share compass 'crossed' the gyro band at 0.34 rad/s, under the 0.95-share odometry)
        top = pair >= np.max(others, axis=0) if others else np.ones(pair.shape, dtype=bool)
        # a change of strict sign: a band that touches another (equal on a grid point, below on both sides)
        # had been a hand-over to it there, and the real one after it was lost
        finite = np.isfinite(d)
        signed = np.flatnonzero(finite & (d != 0))
        lo, hi = signed[:-1], signed[1:]
        gaps = np.cumsum(~finite)  # no non-finite point between lo and hi: only equal magnitudes (d = 0)
        cross = (np.sign(d[lo]) != np.sign(d[hi])) & (gaps[hi - 1] == gaps[lo])
        on_top = np.array([top[i:j + 1].all() for i, j in zip(lo[cross], hi[cross], strict=True)], dtype=bool)
        if not on_top.any():
            return None
        i, j = lo[cross][on_top][0], hi[cross][on_top][0]
        return float(brentq(lambda w: self._log_ratio(a, b, w), self.omega[i], self.omega[j], xtol=1e-14))


def frequency_response(observer, omega=None, points: int = 800) -> FrequencyResponse:
    """Evaluate every band of a numeric observer on a frequency grid.

    Parameters
    ----------
    observer : cfdesign.symbolic.Observer
        With numbers for every gain (and the sample time).
    omega : array_like, optional
        Angular frequencies (rad/s); default :func:`default_frequencies`.
    points : int
        Size of the default grid.

    Returns
    -------
    FrequencyResponse
        Every band's complex response on the grid ``omega`` (rad/s).

    Raises
    ------
    GainError
        The observer still has symbolic parameters, or the responses overflow (gains too
        large, or a pole on the grid).
    StructureError
        ``observer`` is not a cfdesign Observer (a python-control system, a gain table).
    InputError
        ``omega`` is not a non-empty 1-D array of finite angular frequencies (rad/s).

    Examples
    --------
    >>> import cfdesign
    >>> resp = cfdesign.frequency_response(cfdesign.cf2().with_gains(k=2), omega=[0.2, 2.0, 20.0])
    >>> bool(abs(resp.bands["angle"][0]) > abs(resp.bands["rate"][0]))   # the angle band below the crossover
    True
    >>> resp.crossovers()                                          # (band, band, rad/s)
    [('angle', 'rate', 2.0)]
    """
    _require_observer(observer, "frequency_response")
    coefficients = observer.band_coefficients()
    dt = float(observer.sample_time) if observer.discrete else None
    if omega is None:
        omega = default_frequencies(coefficients, dt, points)
    omega = angular_frequencies(omega)
    bands = {name: response(num, den, omega, dt) for name, (num, den) in coefficients.items()}
    if not all(np.all(np.isfinite(b)) for b in bands.values()):
        from .errors import GainError

        raise GainError(f"{observer.name}: the band responses overflow double precision on the frequency grid "
                        "(gains too large, or a pole on the grid)")
    return FrequencyResponse(omega, bands, dt, coefficients)
