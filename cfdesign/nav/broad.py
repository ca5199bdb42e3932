"""The BROAD benchmark's trials and error metric (Laidig, Caruso, Cereatti, Seel, Data 6(7), 2021).

A trial (``.mat``, read with scipy.io) holds ``imu_gyr`` (rad/s), ``imu_acc`` (m/s^2),
``imu_mag`` (uT), ``opt_quat`` (ground truth [w, x, y, z], sensor frame relative to ENU, NaN
rows where the optical system lost the marker), ``movement`` and ``sampling_rate``.

Error metric (the dataset's own): ``e = q_est * conj(q_ref)`` (error in the Earth frame);
total ``2 acos|e_w|``, heading ``2 atan|e_z / e_w|``, inclination ``2 acos sqrt(e_w^2 + e_z^2)``;
RMSE in degrees over the samples with ``movement == 1`` and a finite reference.  BROAD data are
licensed CC BY 4.0: credit the authors wherever results on them are shown.
"""

from __future__ import annotations

import numpy as np

from .. import rotations as rot

__all__ = ["load_trial", "broad_rmse"]


def load_trial(path) -> dict:
    """One BROAD trial: ``gyr``, ``acc``, ``mag`` (N, 3), ``ref`` (N, 4), ``movement`` (bool), ``rate`` (Hz)."""
    from scipy.io import loadmat

    d = loadmat(path)
    return {"gyr": np.ascontiguousarray(d["imu_gyr"]), "acc": np.ascontiguousarray(d["imu_acc"]),
            "mag": np.ascontiguousarray(d["imu_mag"]), "ref": d["opt_quat"],
            "movement": d["movement"].ravel().astype(bool), "rate": float(d["sampling_rate"].item())}


def broad_rmse(q_est, q_ref, movement) -> tuple:
    """BROAD's ``(total, heading, inclination)`` RMSE in degrees over the movement phases."""
    q_ref = q_ref / np.linalg.norm(q_ref, axis=1, keepdims=True)
    e = rot.multiply(rot.normalize(q_est), rot.conjugate(q_ref))
    e = e[np.asarray(movement, dtype=bool) & np.isfinite(e).all(axis=1)]
    total = 2 * np.arccos(np.clip(np.abs(e[:, 0]), 0, 1))
    heading = 2 * np.arctan(np.abs(e[:, 3] / e[:, 0]))
    incl = 2 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), 0, 1))
    return tuple(float(np.degrees(np.sqrt(np.mean(x**2)))) for x in (total, heading, incl))
