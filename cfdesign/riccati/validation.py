"""Data checks and PBH (Hautus) mode tests, with messages that name the matrix or the mode.

Every message names what is wrong in the user's terms: ``"Q must be 3x3 (got 2x3)"``,
``"mode at z = 1.5 is unstable and not reachable from B (PBH test)"``.  The estimator
helpers solve the dual problem (``A = F'``, ``B = H'``) and phrase the same findings as
observability from ``H`` and excitation by the process noise ``Q``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import NotDetectableError, NotStabilisableError, RiccatiError
from ..gains import MAX_ENTRY
from .problem import EPS, TINY, distance, herm

__all__ = ["matrix", "min_eig", "is_psd", "covariance_data", "problem_data", "fmt_mode", "mode_position",
           "unreachable_mode", "check_modes"]


def matrix(name, value, shape=(None, None), *, hermitian=False):
    """Validate one matrix and return it as a 2-D float or complex array.

    A scalar is 1x1; a vector is a row where a row fits, else a column.

    Parameters
    ----------
    name : str
        The matrix's name in messages (``"Q must be 3x3 (got 2x3)"``).
    value : array_like
        The user's matrix (a scalar counts as 1 x 1).
    shape : (int or None, int or None) or 'square'
        Required shape; None entries are free.
    hermitian : bool
        Require symmetry (Hermitian) within ``1e-10`` relative, and symmetrise.

    Returns
    -------
    ndarray
        2-D, float or complex.

    Raises
    ------
    RiccatiError
        Not numeric, not 2-D, the wrong shape, NaN or Inf, an entry beyond
        ``cfdesign.gains.MAX_ENTRY``, or not symmetric.

    Examples
    --------
    >>> from cfdesign.riccati.validation import matrix
    >>> matrix("Q", [[1.0, 2.0]], (2, 2))
    Traceback (most recent call last):
    ...
    cfdesign.errors.RiccatiError: Q must be 2x2 (got 1x2)
    """
    try:
        M = np.array(value, dtype=complex if np.iscomplexobj(value) else float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise RiccatiError(f"{name} must be a numeric matrix ({exc})") from None
    want_r, want_c = (None, None) if shape == "square" else shape
    if M.ndim < 2:  # a scalar is 1x1; a vector is a row where a row fits, else a column
        M = M.reshape((1, -1) if want_c == M.size and want_r in (None, 1) else (-1, 1))
    if M.ndim != 2:
        raise RiccatiError(f"{name} must be a 2-D matrix (got {M.ndim} dimensions)")
    rows, cols = M.shape
    if shape == "square":
        want_r, want_c = rows, rows
    if (want_r is not None and rows != want_r) or (want_c is not None and cols != want_c):
        want = f"{want_r if want_r is not None else rows}x{want_c if want_c is not None else cols}"
        raise RiccatiError(f"{name} must be {want} (got {rows}x{cols})")
    big = np.abs(M).max() if M.size else 0.0  # NaN when an entry is NaN: one pass serves both checks
    if not np.isfinite(big):
        raise RiccatiError(f"{name} contains NaN or Inf")
    if big > MAX_ENTRY:  # products of two overflow: an SVD that did not converge
        raise RiccatiError(f"{name} has an entry of magnitude {big:.3g}, beyond {MAX_ENTRY:g}: the "
                           "products the solver forms would overflow (rescale the problem)")
    if hermitian and M.size:
        Mh = M.conj().T if np.iscomplexobj(M) else M.T
        gap = np.abs(M - Mh).max()
        if gap > 1e-10 * max(big, TINY):
            raise RiccatiError(f"{name} must be symmetric (Hermitian): max |{name} - {name}'| = {gap:.3g}")
        M = 0.5 * (M + Mh)
    return M


def min_eig(M):
    """Smallest eigenvalue of a Hermitian matrix.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Hermitian matrix.

    Returns
    -------
    float
        ``inf`` for an empty matrix.
    """
    return np.linalg.eigvalsh(M)[0] if M.size else np.inf


def is_psd(M):
    """Positive semidefinite up to rounding: ``min eig >= -100 n eps ||M||_2``.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Hermitian.

    Returns
    -------
    bool
        True when ``M`` is positive semidefinite within the tolerance.
    """
    return min_eig(M) >= -100 * M.shape[0] * EPS * max(np.linalg.norm(M, 2), TINY)


def covariance_data(F, H, Q, R):
    """Validate estimator data.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State transition matrix.
    H : array_like, shape (p, n)
        Measurement matrix.
    Q : array_like, shape (n, n)
        Process-noise covariance, positive semidefinite.
    R : array_like, shape (p, p)
        Measurement-noise covariance, positive definite.

    Returns
    -------
    F, H, Q, R : ndarray
        The checked data as float arrays.

    Raises
    ------
    RiccatiError
        A matrix of the wrong shape, not finite, not symmetric, ``Q`` not positive
        semidefinite or ``R`` not positive definite (the message names it).
    """
    F = matrix("F", F, "square")
    n = F.shape[0]
    H = matrix("H", H, (None, n))
    Q = matrix("Q", Q, (n, n), hermitian=True)
    R = matrix("R", R, (H.shape[0], H.shape[0]), hermitian=True)
    if not is_psd(Q):
        raise RiccatiError(f"Q (process noise covariance) must be positive semidefinite (min eig {min_eig(Q):.3g})")
    if min_eig(R) <= 0:
        raise RiccatiError(f"R (measurement noise covariance) must be positive definite (min eig {min_eig(R):.3g})")
    return F, H, Q, R


def problem_data(kind, A, B, Q, R, S, E):
    """Validate the data of a CARE or DARE.

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    Q : array_like, shape (n, n)
        State weight, Hermitian.
    R : array_like, shape (m, m)
        Input weight, Hermitian and nonsingular.
    S : array_like, shape (n, m), or None
        Cross weight.
    E : array_like, shape (n, n), or None
        Descriptor matrix, nonsingular.

    Returns
    -------
    A, B, Q, R, S, E : ndarray
        ``S`` filled in with zeros; ``E`` None for the identity.

    Raises
    ------
    RiccatiError
        A matrix of the wrong shape, not finite or not symmetric, a singular ``E``, or (CARE)
        a singular ``R``; the message names the matrix.
    """
    A = matrix("A", A, "square")
    n = A.shape[0]
    if n == 0:
        raise RiccatiError("A is 0x0: a Riccati equation needs at least one state")
    B = matrix("B", B, (n, None))
    m = B.shape[1]
    if m == 0:
        raise RiccatiError(f"B is {n}x0: a Riccati equation needs at least one input (one measurement for a filter)")
    Q = matrix("Q", Q, (n, n), hermitian=True)
    R = matrix("R", R, (m, m), hermitian=True)
    S = np.zeros((n, m)) if S is None else matrix("S", S, (n, m))
    E = None if E is None else matrix("E", E, (n, n))
    if E is not None and _cond(E) > 1 / (n * EPS):
        raise RiccatiError(f"E must be nonsingular (condition number {_cond(E):.3g})")
    if kind == "care" and _cond(R) > 1 / (m * EPS):
        raise RiccatiError(f"R must be nonsingular for the CARE (condition number {_cond(R):.3g})")
    return A, B, Q, R, S, E


def _cond(M):
    """2-norm condition number (``inf`` when singular), as :func:`numpy.linalg.cond`."""
    s = np.linalg.svd(M, compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = s[0] / s[-1] if s.size else 0.0
    return np.inf if np.isnan(c) else c


# --------------------------------------------------------------------------------------
# PBH checks
# --------------------------------------------------------------------------------------
def fmt_mode(kind, lam):
    """A mode as the user would write it: ``s = -1.5`` or ``z = 0.3+0.4j``.

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    lam : complex
        The eigenvalue.

    Returns
    -------
    str
        ``s = ...`` (CARE) or ``z = ...`` (DARE).

    Examples
    --------
    >>> from cfdesign.riccati.validation import fmt_mode
    >>> fmt_mode("dare", 1.0), fmt_mode("care", 0.5j)
    ('z = 1.0', 's = 0.0+0.5j')
    """
    var = "s" if kind == "care" else "z"
    lam = complex(lam)
    if abs(lam.imag) <= 1e-12 * max(1.0, abs(lam)):
        return f"{var} = {float(f'{lam.real:.6g}')!r}"
    return f"{var} = {float(f'{lam.real:.6g}')!r}{'+' if lam.imag >= 0 else '-'}{float(f'{abs(lam.imag):.6g}')!r}j"


def unreachable_mode(kind, A, E, B, boundary_only=False):
    """PBH test: an eigenvalue of ``(A, E)`` on or beyond the boundary with ``rank [A - lam E, B] < n``.

    ``A - lam E`` is divided by ``max(||A||, |lam| ||E||)`` and ``B`` by its norm first, so only
    exact rank loss counts: a small but nonzero ``B`` is not rejected (the solution then simply
    is ill-conditioned), nor is a large eigenvalue of a nearly singular ``E`` (with ``B`` scaled
    to ``A`` alone, ``E = diag(1, 1e-15)`` and ``B = I`` named the mode at 5e14 unreachable).

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    A : ndarray, shape (n, n)
        State matrix.
    E : ndarray, shape (n, n), or None
        Descriptor matrix; None for the identity.
    B : ndarray, shape (n, m)
        Input matrix.
    boundary_only : bool
        Test only modes on the boundary (not the unstable ones).

    Returns
    -------
    (complex, float, float) or None
        The first such mode, its distance to the boundary and the tolerance within which a
        distance counts as on the boundary (``100 n eps``, times the largest ``|lam|`` for the
        CARE).
    """
    n = A.shape[0]
    Eref = np.eye(n) if E is None else E
    lam = sla.eigvals(A) if E is None else sla.eigvals(A, E)
    d = distance(kind, lam)
    scale = max(1.0, np.max(np.abs(lam), initial=0.0)) if kind == "care" else 1.0
    tol_b = 100 * n * EPS * scale
    bnorm, anorm, enorm = np.linalg.norm(B), np.linalg.norm(A), np.linalg.norm(Eref)
    Bs = B / bnorm if bnorm > 0 else B
    tested = []
    for lam_i, d_i in zip(lam, d, strict=True):
        if (abs(d_i) if boundary_only else d_i) > tol_b or any(abs(lam_i - t) <= tol_b for t in tested):
            continue
        tested.append(lam_i)
        M = np.hstack([(A - lam_i * Eref) / max(anorm, abs(lam_i) * enorm, TINY), Bs])
        smin = np.linalg.svd(M, compute_uv=False)[-1] if n else 1.0
        if smin <= 100 * n * EPS * np.linalg.norm(M):
            return lam_i, float(d_i), float(tol_b)
    return None


def mode_position(kind, lam, d, tol):
    """Where a mode lies, in words: unstable, or on the stability boundary (to within rounding).

    A mode counts as unstable when it is beyond the boundary by more than the tolerance of the
    test that found it, and as on the boundary otherwise; a boundary mode not exactly on it is
    named with its distance and that tolerance, so that a stable mode of a stiff system
    (``s = -2e-8`` beside ``|s| = 1e7``) is not simply said to be on the axis, nor a slightly
    unstable one (``s = 1e-10``) said to be on it.

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    lam : complex
        The mode.
    d : float
        Its distance to the boundary, positive inside (:func:`~cfdesign.riccati.problem.distance`).
    tol : float
        The distance within which the test counted it as on the boundary.

    Returns
    -------
    str
        ``"unstable"``, ``"on the unit circle"``, ``"on the imaginary axis to within rounding
        (...)"``, ...

    Examples
    --------
    >>> from cfdesign.riccati.validation import mode_position
    >>> mode_position("care", 1e-10, -1e-10, 4e-14), mode_position("dare", 1.0, 0.0, 4e-14)
    ('unstable', 'on the unit circle')
    >>> mode_position("dare", 1 + 1e-10, -1e-10, 4e-14)
    'unstable (|z| - 1 = 1e-10)'
    """
    if d < -tol:
        return "unstable" + (f" (|z| - 1 = {-d:.3g})" if kind == "dare" and -d < 1e-4 else "")
    boundary = "the imaginary axis" if kind == "care" else "the unit circle"
    if d == 0:
        return f"on {boundary}"
    off = f"|Re s| = {abs(complex(lam).real):.3g}" if kind == "care" else f"||z| - 1| = {abs(d):.3g}"
    return f"on {boundary} to within rounding ({off}, within the tolerance {tol:.3g})"


def _raise_mode(cls, kind, lam, d, tol, what):
    raise cls(f"mode at {fmt_mode(kind, lam)} is {mode_position(kind, lam, d, tol)} and {what} (PBH test)")


def check_modes(kind, A, B, Q, R, S, E, dual):
    """Stabilisability of ``(A, B)``; for a PSD weight, no unobservable boundary mode of ``(A_r, Q_r)``.

    Parameters
    ----------
    kind : {'care', 'dare'}
        ``care`` (continuous-time equation) or ``dare`` (discrete-time).
    A, B, Q, R, S : ndarray
        The validated data.
    E : ndarray or None
        Descriptor matrix; None for the identity.
    dual : bool
        Phrase the messages for the estimator problem (``A = F'``, ``B = H'``).

    Raises
    ------
    NotStabilisableError, NotDetectableError
        Naming the mode.
    """
    hit = unreachable_mode(kind, A, E, B)
    if hit is not None:
        cls, what = (NotDetectableError, "not observable from H") if dual else (
            NotStabilisableError, "not reachable from B")
        _raise_mode(cls, kind, *hit, what)
    W = np.block([[Q, S], [S.conj().T, R]])
    if min_eig(R) <= 0 or not is_psd(W):
        return  # indefinite weights: no PBH criterion; the solver decides
    RiS = np.linalg.solve(R, S.conj().T)
    Ar, Qr = A - B @ RiS, herm(Q - S @ RiS)
    Eh = None if E is None else E.conj().T
    hit = unreachable_mode(kind, Ar.conj().T, Eh, Qr, boundary_only=True)
    if hit is not None:
        lam, d, tol = hit
        if dual:
            _raise_mode(NotStabilisableError, kind, np.conj(lam), d, tol,
                        "not excited by the process noise Q, so no stabilising solution exists")
        _raise_mode(NotDetectableError, kind, np.conj(lam), d, tol,
                    "not observable from the weight Q, so no stabilising solution exists")
