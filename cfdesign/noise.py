"""Sensor noise models -> process and measurement covariances.

Units (SI inside, the sensor's own quantity ``u``: rad, rad/s, m, m/s^2, ...):

* white noise as a continuous **density** ``nd`` in ``u/sqrt(Hz)``: two-sided power
  spectral density ``q = nd**2`` in ``u^2/Hz`` (= ``u^2 s``);
* white noise as a per-sample **standard deviation** ``sigma`` in ``u`` at the sensor's
  sample rate ``f``: the two are tied by ``sigma**2 = q * f`` (``q = sigma**2 * T``), the
  convention of a sampled white noise whose samples are averages over ``T = 1/f``;
* bias as a **random walk** with density ``bd`` in ``u/sqrt(s)`` (rate of change of the bias
  is white with PSD ``bd**2``), or a **constant** ``value`` in ``u`` (not a noise: it only
  enters simulations, and a filter cannot learn it without a random-walk model).

Continuous process noise ``Qc`` becomes the exact discrete covariance for sample time ``T``
with Van Loan's method (C. F. Van Loan, "Computing integrals involving the matrix
exponential", IEEE TAC 23(3), 1978):

.. math:: Q_d = \\int_0^T e^{F\\tau} Q_c e^{F^T\\tau} d\\tau,\\qquad
          \\exp\\left(\\begin{bmatrix}-F & Q_c\\\\ 0 & F^T\\end{bmatrix}T\\right)
          = \\begin{bmatrix}\\cdot & F_d^{-1}Q_d\\\\ 0 & F_d^T\\end{bmatrix}.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .errors import SpecError

__all__ = ["WhiteNoise", "Bias", "van_loan", "zoh"]


#: noise and bias figures cfdesign accepts (their squares, times any rate, stay normal doubles)
FIGURE_RANGE = (1e-100, 1e100)


def _positive(value, field, allow_zero=True):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):  # numpy's scalars are Real
        raise SpecError(f"{field} must be a number, got {value!r}")
    if isinstance(value, np.generic):  # compared as itself, a float32 overflowed casting the range's 1e100
        value = float(value)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise SpecError(f"{field} must be a finite {kind} number, got {value!r}")
    if value and not FIGURE_RANGE[0] <= value <= FIGURE_RANGE[1]:
        raise SpecError(f"{field}: {value:g} is outside {FIGURE_RANGE[0]:g} to {FIGURE_RANGE[1]:g}, the range whose "
                        "squares double precision can hold (check the units)")
    return float(value)


@dataclass(frozen=True)
class WhiteNoise:
    """White measurement or input noise of one sensor, in its unit ``u``.

    Give exactly one of ``density`` and ``std``.

    Parameters
    ----------
    density : float, optional
        Noise density (u/sqrt(Hz)); the two-sided PSD is ``density**2``.
    std : float, optional
        Standard deviation per sample (u).
    field : str
        The design-file field named in errors (``sensors.gyro.noise``).

    Raises
    ------
    SpecError
        Both or neither given, or a figure that is negative, not finite, or outside
        :data:`~cfdesign.noise.FIGURE_RANGE`.

    Examples
    --------
    >>> from cfdesign.noise import WhiteNoise
    >>> w = WhiteNoise(std=0.01)            # rad per sample, at 100 Hz:
    >>> w.psd(100.0), w.variance(100.0)
    (1e-06, 0.0001)
    """

    density: float | None = None
    std: float | None = None
    field: str = "noise"

    def __post_init__(self):
        if (self.density is None) == (self.std is None):
            raise SpecError(f"{self.field}: give exactly one of 'density' (u/sqrt(Hz)) and 'std' (u per sample)")
        # stored as doubles: a figure of np.float32 kept psd() and variance() in single precision
        if self.density is not None:
            object.__setattr__(self, "density", _positive(self.density, f"{self.field}.density"))
        else:
            object.__setattr__(self, "std", _positive(self.std, f"{self.field}.std"))

    def psd(self, rate_hz: float) -> float:
        """Continuous PSD ``q`` (u^2/Hz): ``density**2`` or ``std**2 / rate_hz``.

        Parameters
        ----------
        rate_hz : float
            Sample rate (Hz) at which ``std`` applies.

        Returns
        -------
        float
            The PSD ``q`` (u^2/Hz, ``u`` the sensor's unit).
        """
        return self.density**2 if self.density is not None else self.std**2 / rate_hz

    def variance(self, rate_hz: float) -> float:
        """Per-sample variance (u^2): ``std**2`` or ``density**2 * rate_hz``.

        Parameters
        ----------
        rate_hz : float
            Sample rate (Hz).

        Returns
        -------
        float
            The variance of one sample (u^2, ``u`` the sensor's unit).
        """
        return self.std**2 if self.std is not None else self.density**2 * rate_hz


@dataclass(frozen=True)
class Bias:
    """Sensor bias: constant, or a random walk.

    Parameters
    ----------
    model : {'constant', 'random_walk'}
        ``constant``: a fixed offset ``value`` (enters simulations only); ``random_walk``: a
        bias whose rate of change is white with ``density``, which the design estimates.
    density : float
        Random-walk density (u/sqrt(s)); positive for a random walk.
    value : float
        Constant bias (u).
    field : str
        The design-file field named in errors (``sensors.gyro.bias``).

    Raises
    ------
    SpecError
        An unknown model, a density or value that is not a finite number in range, a random
        walk without a density, a constant bias with one.
    """

    model: str = "constant"
    density: float = 0.0
    value: float = 0.0
    field: str = "bias"

    def __post_init__(self):
        if self.model not in ("constant", "random_walk"):
            raise SpecError(f"{self.field}.model must be 'constant' or 'random_walk', got {self.model!r}")
        object.__setattr__(self, "density", _positive(self.density, f"{self.field}.density"))
        if (isinstance(self.value, (bool, np.bool_)) or not isinstance(self.value, numbers.Real)
                or not math.isfinite(self.value)):
            raise SpecError(f"{self.field}.value must be a finite number, got {self.value!r}")
        object.__setattr__(self, "value", float(self.value))
        if self.model == "random_walk" and self.density == 0:
            raise SpecError(f"{self.field}: a random-walk bias needs a positive density (u/sqrt(s))")
        if self.model == "constant" and self.density:  # (it was dropped: a design without the bias's drift)
            raise SpecError(f"{self.field}.density: a density is the figure of model = 'random_walk' (the model "
                            "defaults to 'constant', which takes a value only); add model = \"random_walk\"")

    @property
    def psd(self) -> float:
        """PSD of the bias rate of change (u^2/s); 0 for a constant bias."""
        return self.density**2 if self.model == "random_walk" else 0.0


def van_loan(F, Qc, T: float):
    """Exact discretisation of ``x' = F x + w`` with white ``w``, ``E[w w^T] = Qc delta``.

    Van Loan's method: ``expm([[-F, Qc], [0, F^T]] T)`` gives ``Fd = e^{F T}`` and
    ``Qd = int_0^T e^{F t} Qc e^{F^T t} dt`` (``docs/derivations.md``, "Exact discretisation of
    the process noise (Van Loan)").

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous state matrix (1/s).
    Qc : array_like, shape (n, n)
        Continuous process-noise PSD (state units^2 / s).
    T : float
        Sample time (s).

    Returns
    -------
    Fd : ndarray, shape (n, n)
        State transition matrix ``e^{F T}``.
    Qd : ndarray, shape (n, n)
        Per-sample process-noise covariance, symmetric.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.noise import van_loan
    >>> Fd, Qd = van_loan([[0, 1], [0, 0]], np.diag([0.0, 1.0]), 0.1)
    >>> print(Qd.round(6))
    [[0.000333 0.005   ]
     [0.005    0.1     ]]
    """
    from scipy.linalg import expm

    F, Qc = np.atleast_2d(F).astype(float), np.atleast_2d(Qc).astype(float)
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -F, Qc, F.T
    E = expm(M * T)
    Fd = E[n:, n:].T
    Qd = Fd @ E[:n, n:]
    return Fd, (Qd + Qd.T) / 2


def zoh(F, B, T: float):
    """Zero-order-hold discretisation: ``Fd = e^{F T}``, ``Bd = int_0^T e^{F t} dt B``.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous state matrix (1/s).
    B : array_like, shape (n, p)
        Continuous input matrix.
    T : float
        Sample time (s).

    Returns
    -------
    Fd : ndarray, shape (n, n)
        State transition matrix ``e^{F T}``.
    Bd : ndarray, shape (n, p)
        Input matrix of the held input.

    Examples
    --------
    >>> from cfdesign.noise import zoh
    >>> Fd, Bd = zoh([[0, 1], [0, 0]], [[0], [1]], 0.1)
    >>> Bd.ravel().tolist()
    [0.005000000000000001, 0.1]
    """
    from scipy.linalg import expm

    F, B = np.atleast_2d(F).astype(float), np.asarray(B, dtype=float).reshape(len(F), -1)
    n, p = B.shape
    M = np.zeros((n + p, n + p))
    M[:n, :n], M[:n, n:] = F, B
    E = expm(M * T)
    return E[:n, :n], E[:n, n:]
