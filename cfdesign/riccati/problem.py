"""The validated data of one CARE or DARE and the small algebra every stage shares.

Conventions follow :func:`scipy.linalg.solve_continuous_are` and
:func:`scipy.linalg.solve_discrete_are` (control form, ``'`` is the conjugate transpose):

* CARE ``A'XE + E'XA - (E'XB + S) R^-1 (B'XE + S') + Q = 0``, gain ``K = R^-1 (B'XE + S')``;
* DARE ``A'XA - E'XE - (A'XB + S)(R + B'XB)^-1 (B'XA + S') + Q = 0``,
  gain ``K = (R + B'XB)^-1 (B'XA + S')``.

Complex data is carried as its real representation (:func:`realify`), so every stage after
validation works on real matrices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = ["EPS", "TINY", "Problem", "herm", "rel", "distance", "realify", "complexify", "standard_form",
           "from_standard", "gain"]

#: Machine epsilon of float64 (the unit of the convergence and distance tolerances)
EPS = np.finfo(float).eps
#: Smallest normal float64 (guards divisions by a zero norm)
TINY = np.finfo(float).tiny


def norm2_bound(M) -> float:
    """An upper bound of the spectral norm: ``min(||M||_F, sqrt(||M||_1 ||M||_inf))``.

    Both bound ``||M||_2`` (Golub and Van Loan, *Matrix Computations*, 4th ed., 2.3.2) at the
    cost of sums, no SVD.

    Parameters
    ----------
    M : ndarray
        A matrix.

    Returns
    -------
    float
    """
    a = np.abs(M)
    return float(min(np.linalg.norm(M), np.sqrt(a.sum(axis=0).max(initial=0.0) * a.sum(axis=1).max(initial=0.0))))


def herm(M):
    """Hermitian part ``(M + M')/2`` (exactly Hermitian in floating point).

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Square matrix.

    Returns
    -------
    ndarray, shape (n, n)
        The Hermitian part of ``M``.
    """
    return 0.5 * (M + M.conj().T)


def rel(a, b):
    """Relative size ``||a||_F / ||b||_F``, guarded against a zero denominator.

    Parameters
    ----------
    a, b : ndarray
        Numerator and denominator.

    Returns
    -------
    float
        ``||a||_F / ||b||_F``, the denominator at least a tiny positive floor.
    """
    return np.linalg.norm(a) / max(np.linalg.norm(b), TINY)


def distance(kind, lam):
    """Distance of eigenvalues to the stability boundary, positive inside the stable region.

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    lam : array_like of complex
        Eigenvalues (``'care'``: of ``s``; ``'dare'``: of ``z``).

    Returns
    -------
    ndarray
        ``-Re(lam)`` (CARE) or ``1 - |lam|`` (DARE).
    """
    lam = np.asarray(lam)
    return -lam.real if kind == "care" else 1.0 - np.abs(lam)


@dataclass(frozen=True)
class Problem:
    """Validated real data of one CARE or DARE (complex data is realified first).

    Attributes
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    A, Q : ndarray, shape (n, n)
        State matrix and state weight.
    B : ndarray, shape (n, m)
        Input matrix.
    R : ndarray, shape (m, m)
        Input weight.
    S : ndarray, shape (n, m)
        Cross weight (zeros when not given).
    E : ndarray, shape (n, n), or None
        Descriptor matrix; None means the identity.
    """

    kind: str
    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray
    E: np.ndarray | None  # None means identity

    @property
    def n(self):
        """Number of states ``n``."""
        return self.A.shape[0]

    @cached_property
    def AB(self):
        """``[A B]``."""
        return np.hstack([self.A, self.B])

    @cached_property
    def ABE(self):
        """``[A B E]``."""
        return np.hstack([self.A, self.B, self.E])

    @cached_property
    def has_S(self):
        """Whether the cross weight ``S`` is nonzero."""
        return bool(np.any(self.S))

    @cached_property
    def EinvA(self):
        """``E^-1 A``."""
        return self.e_solve(self.A)

    @cached_property
    def EinvB(self):
        """``E^-1 B``."""
        return self.e_solve(self.B)

    def e_solve(self, M, transpose=False):
        """``E^-1 M`` (or ``E^-T M``); ``M`` itself when ``E`` is the identity.

        Parameters
        ----------
        M : ndarray
            Right-hand side.
        transpose : bool
            Solve with ``E^T``.

        Returns
        -------
        ndarray
            ``E^-1 M`` (``E^-T M`` with ``transpose``), the shape of ``M``.
        """
        if self.E is None:
            return M
        return np.linalg.solve(self.E.T if transpose else self.E, M)

    def closed_loop(self, K):
        """Closed-loop matrix in standard form: ``E^-1 (A - BK)``, minus ``I`` for the DARE.

        For the DARE the identity is taken off before ``E^-1`` is applied (``A - E - BK``), so a
        closed loop close to the identity (fast sampling) loses no digits.

        Parameters
        ----------
        K : ndarray, shape (m, n)
            Gain.

        Returns
        -------
        ndarray, shape (n, n)
            The closed-loop matrix in standard form.
        """
        Eref = np.eye(self.n) if self.E is None else self.E
        M = (self.A - Eref) - self.B @ K if self.kind == "dare" else self.A - self.B @ K
        return self.e_solve(M)


def realify(M):
    """Real representation ``[[Re M, -Im M], [Im M, Re M]]`` (an algebra homomorphism).

    Parameters
    ----------
    M : ndarray or None
        Complex matrix; None passes through.

    Returns
    -------
    ndarray or None
        Twice the size in each dimension.
    """
    if M is None:
        return None
    return np.block([[M.real, -M.imag], [M.imag, M.real]])


def complexify(M, rows, cols):
    """Inverse of :func:`realify`, averaging the two copies of each block.

    Parameters
    ----------
    M : ndarray, shape (2 rows, 2 cols)
        Real representation as built by :func:`realify`.
    rows, cols : int
        Size of the complex matrix.

    Returns
    -------
    ndarray of complex, shape (rows, cols)
        The complex matrix.
    """
    return 0.5 * (M[:rows, :cols] + M[rows:, cols:]) + 0.5j * (M[rows:, :cols] - M[:rows, cols:])


def standard_form(p: Problem):
    """The equivalent standard problem in ``Y = E'XE`` (needs ``R`` invertible).

    Parameters
    ----------
    p : Problem
        The validated equation.

    Returns
    -------
    A_r : ndarray
        ``E^-1 (A - B R^-1 S')``.
    G : ndarray
        ``E^-1 B R^-1 B' E^-T``.
    Q_r : ndarray
        ``Q - S R^-1 S'``.
    """
    Rinv_St = np.linalg.solve(p.R, p.S.T)
    Ar = p.e_solve(p.A - p.B @ Rinv_St)
    Bt = p.e_solve(p.B)
    G = herm(Bt @ np.linalg.solve(p.R, Bt.T))
    return Ar, G, herm(p.Q - p.S @ Rinv_St)


def from_standard(p: Problem, Y):
    """``X = E^-T Y E^-1`` from the standard-coordinate ``Y = E'XE``.

    Parameters
    ----------
    p : Problem
        The validated equation.
    Y : ndarray, shape (n, n)
        Solution in standard coordinates.

    Returns
    -------
    ndarray, shape (n, n)
        The solution ``X`` in the original coordinates.
    """
    if p.E is None:
        return Y
    return herm(p.e_solve(p.e_solve(Y, transpose=True).T, transpose=True).T)


def gain(p: Problem, X):
    """The gain in plain double precision (for trial points).

    Parameters
    ----------
    p : Problem
        The validated equation.
    X : ndarray, shape (n, n)
        Riccati solution.

    Returns
    -------
    ndarray, shape (m, n)
        CARE ``R^-1 (B'XE + S')``; DARE ``(R + B'XB)^-1 (B'XA + S')``.
    """
    BX = p.B.T @ X
    if p.kind == "care":
        return np.linalg.solve(p.R, (BX if p.E is None else BX @ p.E) + p.S.T)
    return np.linalg.solve(p.R + BX @ p.B, BX @ p.A + p.S.T)
