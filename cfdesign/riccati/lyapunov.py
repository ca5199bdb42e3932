"""Lyapunov and Stein equations: the linearised Riccati operators and their inverses.

At a gain ``K`` the Frechet derivative of the Riccati operator is, in the standard
coordinates ``Y = E'DE`` with the closed loop ``M = E^-1 (A - BK)`` (CARE) or
``M = E^-1 (A - E - BK)`` (DARE),

* CARE: the Lyapunov operator ``Y -> M'Y + YM``;
* DARE: the Stein operator ``Y -> (I + M)'Y(I + M) - Y``.

The Stein equation is solved through a Cayley transform, so a closed loop close to the
identity (fast sampling) keeps its digits.  :class:`ClosedLoop` factorises the closed loop
at one gain once (a diagonal balancing similarity, then a real Schur form) and serves every
solve with that operator (the Newton correction, ``Omega^-1(I)`` for the condition number
and the Lyapunov stability certificate) and the closed-loop eigenvalues, each solve costing
one triangular Sylvester solve (Bartels and Stewart, "Solution of the matrix equation
AX + XB = C") and four matrix products.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from ..linear import balancing
from .problem import TINY, Problem, from_standard, herm

__all__ = ["stein", "ClosedLoop"]


def stein(D, W):
    """Solve the Stein equation ``(I + D)' Y (I + D) - Y + W = 0`` through the Cayley transform.

    With ``M = D (2I + D)^-1`` the equation becomes ``M'Y + YM = -2 (2I + D)^-T W (2I + D)^-1``;
    ``D`` (not ``I + D``) is the input, so a closed loop close to the identity loses no digits.

    Parameters
    ----------
    D : ndarray, shape (n, n)
        The closed loop minus the identity.
    W : ndarray, shape (n, n)
        Right-hand side (Hermitian).

    Returns
    -------
    ndarray, shape (n, n)
        ``Y``, Hermitian.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.riccati.lyapunov import stein
    >>> float(stein(np.array([[-0.5]]), np.array([[3.0]]))[0, 0])   # 0.25 Y - Y + 3 = 0
    4.0
    """
    F = 2 * np.eye(D.shape[0]) + D
    Fi = np.linalg.inv(F)
    M = D @ Fi
    return herm(sla.solve_continuous_lyapunov(M.conj().T, -2 * Fi.conj().T @ W @ Fi))


_LWORK = {}


def _schur(M):
    """Real Schur form ``M = U T U'`` and the eigenvalues of ``M`` (LAPACK dgees)."""
    n = M.shape[0]
    if n not in _LWORK:
        _LWORK[n] = max(int(lapack.dgees(lambda wr, wi: None, M, lwork=-1)[-2][0]), 3 * n, 1)
    T, _, wr, wi, U, _, info = lapack.dgees(lambda wr, wi: None, M, lwork=_LWORK[n])
    if info != 0:
        raise np.linalg.LinAlgError(f"the Schur decomposition of the closed loop failed (dgees info {info})")
    return T, U, wr + 1j * wi


def _balance(M):
    """``S^-1 M S`` and the diagonal of ``S`` (powers of two; LAPACK dgebal, scaling only).

    A scaling within a factor 4 is dropped (``S = I``): it would change little, and without
    it one solve serves both the certificate and the condition number.
    """
    scale = balancing(M)
    if scale.max(initial=1.0) <= 4 * scale.min(initial=1.0):
        return M, np.ones(M.shape[0])
    return M / scale[:, None] * scale[None, :], scale


class ClosedLoop:
    """The closed loop at one gain, factorised once for every linearised Riccati solve.

    ``M`` (the closed loop in standard form, see
    :meth:`Problem.closed_loop <cfdesign.riccati.problem.Problem.closed_loop>`) is balanced by a
    diagonal similarity of powers of two, ``Ms = S^-1 M S`` (exact), and put in real Schur
    form: ``Ms = U T U'`` (CARE) or, for the DARE, its Cayley transform
    ``Ms (2I + Ms)^-1 = U T U'``.  With ``Y = S^-1 Z S^-1`` the equations in ``Y`` become the
    same equations in ``Z`` with ``Ms`` and the right-hand side ``S W S``.

    Parameters
    ----------
    p : Problem
        The validated equation.
    K : ndarray, shape (m, n)
        The gain.

    Attributes
    ----------
    scale : ndarray
        Diagonal of ``S``.
    unscaled : bool
        True when ``S = I``.
    Ms : ndarray
        Balanced closed loop (DARE: balanced ``A_c - I`` in standard form).
    eigenvalues : ndarray
        Eigenvalues of the pencil ``(A - BK, E)``.
    distances : ndarray
        Their distances to the stability boundary (positive inside), evaluated without
        cancellation near the unit circle.
    """

    def __init__(self, p: Problem, K):
        self.p, self.K = p, K
        M = p.closed_loop(K)
        if not np.all(np.isfinite(M)):  # LAPACK would complain on stderr
            raise np.linalg.LinAlgError("the closed loop is not finite")
        Ms, scale = _balance(M)
        self.scale, self.Ms = scale, Ms
        self.unscaled = bool(np.all(scale == 1.0))
        if p.kind == "care":
            self.T, self.U, lam = _schur(Ms)
            self.eigenvalues, self.distances = lam, -lam.real
        else:
            F = 2 * np.eye(p.n) + Ms
            _, _, C, info = lapack.dgesv(F.T, Ms.T)  # Cayley transform Ms (2I + Ms)^-1, transposed
            if info != 0:
                raise np.linalg.LinAlgError("the closed loop has an eigenvalue at -1")
            self.T, self.U, mu = _schur(C.T)
            with np.errstate(divide="ignore", invalid="ignore"):
                z = (1 + mu) / (1 - mu)
                self.eigenvalues = z
                # 1 - |z| = (1 - |z|^2) / (1 + |z|) and 1 - |z|^2 = -4 Re(mu) / |1 - mu|^2
                self.distances = -4 * mu.real / (np.abs(1 - mu) ** 2 * (1 + np.abs(z)))

    @property
    def margin(self):
        """Smallest distance of a closed-loop eigenvalue to the boundary."""
        return float(np.min(self.distances, initial=np.inf))

    def solve_balanced(self, Wb, schur_basis=False):
        """Solve the linearised equation in the balanced coordinates.

        ``Ms'Z + Z Ms = -Wb`` (CARE) or ``(I + Ms)'Z(I + Ms) - Z = -Wb`` (DARE).

        Parameters
        ----------
        Wb : ndarray or None
            Right-hand side in the balanced coordinates; None stands for the identity.
        schur_basis : bool
            Return ``U'ZU`` (same eigenvalues, two products fewer).

        Returns
        -------
        ndarray, shape (n, n)
            ``Z``, Hermitian.

        Raises
        ------
        ValueError
            The triangular Sylvester solve fails.
        """
        T, U = self.T, self.U
        C = np.eye(T.shape[0]) if Wb is None else U.T @ Wb @ U
        if self.p.kind == "dare":  # (2I + Ms)^-1 = (I - Cayley)/2 in the Schur basis
            I_T = np.eye(T.shape[0]) - T
            C = 0.5 * (I_T.T @ C @ I_T)
        Z, sc, info = lapack.dtrsyl(T, T, -C, trana="T")
        if info < 0:
            raise ValueError(f"the triangular Sylvester solve failed (dtrsyl info {info})")
        if sc != 1.0:
            Z = Z / sc
        return herm(Z if schur_basis else U @ Z @ U.T)

    def solve_std(self, W):
        """The linearised Riccati equation in standard coordinates ``Y = E'DE``.

        CARE: ``Ac' D E + E' D Ac = -W``; DARE: ``Ac' D Ac - E' D E = -W``, with ``Ac = A - BK``.

        Parameters
        ----------
        W : ndarray, shape (n, n)
            Right-hand side.

        Returns
        -------
        ndarray, shape (n, n)
            ``Y``.
        """
        if self.unscaled:
            return self.solve_balanced(W)
        s = self.scale
        return self.solve_balanced(W * s[:, None] * s[None, :]) / s[:, None] / s[None, :]

    def correction(self, W):
        """The Newton correction ``D`` with ``Omega(D) = -W``, in the original coordinates.

        Parameters
        ----------
        W : ndarray, shape (n, n)
            The residual.

        Returns
        -------
        ndarray, shape (n, n)
            The correction ``D``, Hermitian.
        """
        return from_standard(self.p, self.solve_std(W))

    @cached_property
    def certificate(self):
        """Eigenvalues (ascending) of ``Z = Omega^-1(I)`` in the balanced coordinates, or None.

        ``Z`` positive definite proves the closed loop stable (Lyapunov); None when the solve
        fails.
        """
        try:
            return np.linalg.eigvalsh(self.solve_balanced(None, schur_basis=True))
        except (np.linalg.LinAlgError, ValueError):
            return None

    @cached_property
    def omega_inv_norm(self):
        """``||Omega^-1(I)||_2`` in the original coordinates (``inf`` when the solve fails)."""
        if self.unscaled and self.p.E is None:
            ev = self.certificate
            return np.inf if ev is None else float(max(abs(ev[0]), abs(ev[-1])))
        try:
            return float(np.max(np.abs(np.linalg.eigvalsh(self.correction(np.eye(self.p.n))))))
        except (np.linalg.LinAlgError, ValueError):
            return np.inf

    def condition(self, theta, X):
        """Relative condition number ``||Omega^-1|| theta / ||X||`` of the equation at the factorised gain.

        ``||Omega^-1|| = ||Omega^-1(I)||_2`` holds when ``Omega^-1`` is a positive map, i.e. when
        the closed loop is stable.

        Parameters
        ----------
        theta : float
            Size of the data perturbation (the residual's scale).
        X : ndarray, shape (n, n)
            The solution.

        Returns
        -------
        float
            ``inf`` when the stability certificate does not hold.
        """
        ev = self.certificate
        if ev is None or not ev[0] > 0:
            return np.inf
        return self.omega_inv_norm * theta / max(np.linalg.norm(X), TINY)
