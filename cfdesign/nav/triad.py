"""TRIAD attitude from two vector pairs (Black 1964, Shuster & Oh 1981), as the low-cost 3D localization paper uses it.

Given two non-parallel vectors measured in the body frame, ``b1`` and ``b2``, and the same
two vectors known in the reference frame, ``r1`` and ``r2``, eq. (7) of *Low-cost 3D localization
with strapdown IMU, GPS and 3-axis magnetometer* reads

.. math:: [\\,r_1 \\mid r_2 \\mid r_1 \\times r_2\\,] = C\\,[\\,b_1 \\mid b_2 \\mid b_1 \\times b_2\\,],

which, solved as printed (``C = A_r A_b^{-1}``), is exact on noise-free vectors but is not a
rotation once the vectors are noisy (the paper notes its "great sensibility to measurement
errors").  The TRIAD algorithm builds an orthonormal triad on each side instead,

.. math:: t_1 = \\frac{v_1}{|v_1|},\\quad t_2 = \\frac{v_1 \\times v_2}{|v_1 \\times v_2|},\\quad
          t_3 = t_1 \\times t_2,\\qquad C = [t_1^r\\, t_2^r\\, t_3^r]\\,[t_1^b\\, t_2^b\\, t_3^b]^T,

so ``C`` is always a rotation, maps ``b1`` exactly onto the direction of ``r1`` (the primary,
trusted vector) and ``b2`` onto ``r2`` as far as the angle between the pairs allows; on
noise-free vectors it equals the eq. (7) solution.  The "improved TRIAD" of Li and Yuan
(2005) cited by that paper is not described in it and is not implemented here.

Frames as :mod:`cfdesign.rotations`: with body measurements and ENU references the
result maps body to ENU, ``r = C b``.
"""

from __future__ import annotations

import numpy as np

from .. import rotations as rot
from .mps import real_vectors

__all__ = ["triad_frame", "triad_matrix", "triad_quaternion"]


def triad_frame(v1, v2) -> np.ndarray:
    """Orthonormal triad of two vectors.

    ``t1 = v1/|v1|``, ``t2 = v1 × v2 / |v1 × v2|``, ``t3 = t1 × t2``.

    Parameters
    ----------
    v1, v2 : array_like, shape (..., 3)
        Primary and secondary vectors (any units).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Columns ``[t1 | t2 | t3]``; NaN where the vectors are zero or parallel (the triad is
        then undefined).
    """
    v1, v2 = np.asarray(v1, dtype=float), np.asarray(v2, dtype=float)
    cross = np.cross(v1, v2)
    n1 = np.linalg.norm(v1, axis=-1, keepdims=True)
    nc = np.linalg.norm(cross, axis=-1, keepdims=True)
    ok = nc > 1e-12 * n1 * np.linalg.norm(v2, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        t1 = v1 / n1
        t2 = np.where(ok, cross / np.where(ok, nc, 1.0), np.nan)
    return np.stack([t1, t2, np.cross(t1, t2)], axis=-1)


def triad_matrix(b1, b2, r1, r2) -> np.ndarray:
    """TRIAD rotation ``C`` (..., 3, 3) with ``r1 ∝ C b1`` exactly and ``r2 ≈ C b2`` (module docstring).

    Parameters
    ----------
    b1, b2 : array_like (..., 3)
        Primary and secondary vectors in the body frame (any units; only directions matter).
    r1, r2 : array_like (..., 3)
        The same vectors in the reference frame.

    Returns
    -------
    ndarray (..., 3, 3)
        Rotation body -> reference (``v_ref = C v_body``); NaN where a pair is parallel.
    """
    return np.einsum("...ij,...kj->...ik", triad_frame(r1, r2), triad_frame(b1, b2))


def triad_quaternion(b1, b2, r1, r2) -> np.ndarray:
    """TRIAD attitude as a quaternion, body -> reference.

    Parameters
    ----------
    b1, b2 : array_like, shape (..., 3)
        Primary and secondary vectors in the body frame (only directions matter).
    r1, r2 : array_like, shape (..., 3)
        The same vectors in the reference frame (ENU).

    Returns
    -------
    ndarray, shape (..., 4)
        ``[w, x, y, z]`` with ``w >= 0``; NaN where undefined (a parallel pair, a zero or
        non-finite vector).

    Raises
    ------
    AttitudeInputError
        A vector that is not real 3-vectors (text, complex, another length); the message names it.

    Examples
    --------
    >>> from cfdesign.nav.triad import triad_quaternion
    >>> triad_quaternion([0, 0, 1], [0, 1, 0], [0, 0, 1], [0, 1, 0]).tolist()
    [1.0, 0.0, 0.0, 0.0]
    """
    b1, b2, r1, r2 = (real_vectors(name, v) for name, v in (("b1", b1), ("b2", b2), ("r1", r1), ("r2", r2)))
    with np.errstate(invalid="ignore", over="ignore"):  # an unusable vector: NaN, as documented
        C = triad_matrix(b1, b2, r1, r2)
    finite = np.isfinite(C).all(axis=(-2, -1))
    q = rot.from_matrix(np.where(finite[..., None, None], C, np.eye(3)))
    return np.where(finite[..., None], q, np.nan)
