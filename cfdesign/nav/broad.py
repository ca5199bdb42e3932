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
    """Read one trial of the BROAD benchmark (Laidig et al., Data 2021) from its ``.mat`` file.

    Parameters
    ----------
    path : str or Path
        A trial file of the dataset (e.g. ``01_undisturbed_slow_rotation_A.mat``), read with
        :func:`scipy.io.loadmat`.

    Returns
    -------
    dict
        ``gyr`` (N, 3): body rate, rad/s; ``acc`` (N, 3): specific force, m/s²; ``mag``
        (N, 3): magnetic field, uT (all three in the sensor frame, C-contiguous); ``ref``
        (N, 4): the optical ground truth ``[w, x, y, z]``, sensor frame relative to ENU, NaN
        rows where the markers were lost; ``pos`` (N, 3): the marker's position, m (NaN rows
        likewise); ``movement`` (N,) bool: the samples the metric
        scores (:func:`broad_rmse`); ``rate``: the sample rate, Hz.

    Raises
    ------
    FileNotFoundError
        No file at ``path`` (other unreadable files raise what :func:`scipy.io.loadmat` raises).
    KeyError
        The file lacks one of the trial's fields (not a BROAD trial).

    Examples
    --------
    >>> from cfdesign.nav import AttitudeFilter
    >>> from cfdesign.nav.broad import broad_rmse, load_trial
    >>> d = load_trial("BROAD/data_mat/01_undisturbed_slow_rotation_A.mat")  # doctest: +SKIP
    >>> q = AttitudeFilter(d["rate"]).run(d["gyr"], d["acc"], d["mag"])  # doctest: +SKIP
    >>> broad_rmse(q, d["ref"], d["movement"])  # doctest: +SKIP
    (0.86..., 0.60..., 0.61...)
    """
    from scipy.io import loadmat

    d = loadmat(path)
    return {"gyr": np.ascontiguousarray(d["imu_gyr"]), "acc": np.ascontiguousarray(d["imu_acc"]),
            "mag": np.ascontiguousarray(d["imu_mag"]), "ref": d["opt_quat"], "pos": d["opt_pos"],
            "movement": d["movement"].ravel().astype(bool), "rate": float(d["sampling_rate"].item())}


def broad_rmse(q_est, q_ref, movement) -> tuple:
    """Attitude errors as BROAD scores them: total, heading and inclination RMSE in degrees.

    The metric of the dataset (Laidig et al., BROAD, Data 2021; module docstring): the error
    ``e = q_est * conj(q_ref)`` in the Earth frame, split into a rotation about the vertical
    (heading) and the remaining tilt (inclination), RMSE over the samples with ``movement`` set
    and a finite reference.  No heading offset is removed and the quaternions' signs do not
    matter.

    Parameters
    ----------
    q_est : array_like (N, 4)
        Estimated attitude ``[w, x, y, z]``, sensor frame -> ENU (normalised here).
    q_ref : ndarray (N, 4)
        Reference attitude in the same convention (``load_trial(...)["ref"]``); NaN rows are
        left out.
    movement : array_like (N,) of bool
        The samples to score (BROAD's movement phases).

    Returns
    -------
    tuple of float
        ``(total, heading, inclination)`` RMSE in degrees; NaN each (numpy warns of an empty
        mean) when no sample is scored.

    Examples
    --------
    A constant error of 10 degrees about ENU up is all heading:

    >>> import math
    >>> import numpy as np
    >>> from cfdesign.nav.broad import broad_rmse
    >>> h = math.radians(5.0)
    >>> q_est = np.array([[math.cos(h), 0.0, 0.0, math.sin(h)]] * 3)
    >>> q_ref = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [np.nan] * 4])
    >>> [round(x, 6) for x in broad_rmse(q_est, q_ref, [True, True, True])]
    [10.0, 10.0, 0.0]
    """
    q_ref = q_ref / np.linalg.norm(q_ref, axis=1, keepdims=True)
    e = rot.multiply(rot.normalize(q_est), rot.conjugate(q_ref))
    e = e[np.asarray(movement, dtype=bool) & np.isfinite(e).all(axis=1)]
    total = 2 * np.arccos(np.clip(np.abs(e[:, 0]), 0, 1))
    heading = 2 * np.arctan(np.abs(e[:, 3] / e[:, 0]))
    incl = 2 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), 0, 1))
    return tuple(float(np.degrees(np.sqrt(np.mean(x**2)))) for x in (total, heading, incl))
