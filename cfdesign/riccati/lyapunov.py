"""Lyapunov and Stein equations: the linearised Riccati operators and their inverses.

At a gain ``K`` the Frechet derivative of the Riccati operator is, in the standard
coordinates ``Y = E'DE`` with the closed loop ``M = E^-1 (A - BK)`` (CARE) or
``M = E^-1 (A - E - BK)`` (DARE),

* CARE: the Lyapunov operator ``Y -> M'Y + YM``;
* DARE: the Stein operator ``Y -> (I + M)'Y(I + M) - Y``.

The Stein equation is solved through a Cayley transform, so a closed loop close to the
identity (fast sampling) keeps its digits.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .problem import Problem, from_standard, herm

__all__ = ["stein", "omega_std", "omega_inv", "correction"]


def stein(D, W):
    """Solve ``(I + D)' Y (I + D) - Y + W = 0`` through the Cayley transform.

    With ``M = D (2I + D)^-1`` the equation becomes ``M'Y + YM = -2 (2I + D)^-T W (2I + D)^-1``;
    ``D`` (not ``I + D``) is the input, so a closed loop close to the identity loses no digits.
    """
    F = 2 * np.eye(D.shape[0]) + D
    Fi = np.linalg.inv(F)
    M = D @ Fi
    return herm(sla.solve_continuous_lyapunov(M.conj().T, -2 * Fi.conj().T @ W @ Fi))


def omega_std(kind, M, W):
    """Solve ``M'Y + YM = -W`` (CARE, ``M = Ac``) or ``(I + M)'Y(I + M) - Y = -W`` (DARE, ``M = Ac - I``)."""
    if kind == "care":
        return herm(sla.solve_continuous_lyapunov(M.conj().T, -W))
    return stein(M, W)


def omega_inv(p: Problem, K, W):
    """Solve the linearised Riccati equation in standard coordinates ``Y = E'DE`` at the gain ``K``.

    CARE: ``Ac' D E + E' D Ac = -W``; DARE: ``Ac' D Ac - E' D E = -W``, with ``Ac = A - BK``.
    """
    return omega_std(p.kind, p.closed_loop(K), W)


def correction(p: Problem, K, W):
    """The Newton correction ``D`` with ``Omega(D) = -W`` (original coordinates)."""
    return from_standard(p, omega_inv(p, K, W))
