"""cfdesign's AttitudeFilter on BROAD beside VQF, Madgwick, Mahony and Fusion, with its ablation.

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0).  The ten
development trials live in ``shared/data/broad`` beside the checkout.

Metric (the dataset's own, as in BROAD's ``example_code/broad_utils.py``): ``e = q_est ⊗
conj(q_ref)`` (error in the Earth frame); total ``2 acos|e_w|``, heading ``2 atan|e_z/e_w|``,
inclination ``2 acos sqrt(e_w² + e_z²)``; RMSE in degrees over samples with ``movement == 1``
and a finite reference.  No heading offset is removed: BROAD's reference is already
expressed in ENU and its own evaluation compares directly; every filter is treated alike.

Filters (one parameter set for all trials; all start from their own first sample):

* ``ours9d``, ``ours6d``: :class:`cfdesign.nav.AttitudeFilter` with its defaults, with and
  without the magnetometer (6D: heading from heading zero, so its heading error is the
  sensor's initial heading; compare its inclination);
* ``vqf``: VQF 9D, package defaults (D. Laidig, T. Seel, Information Fusion 91, 2023);
* ``madgwick``: package ``ahrs`` 0.4, ``beta = 0.12`` (BROAD's best common value over all 39
  trials); it estimates in a north-west-up frame and is turned into ENU by ``q_z(90°) ⊗ q``,
  as BROAD's ``process_data.py`` does, from the first sample's attitude;
* ``mahony``: package ``ahrs``, ``Kp = 0.74, Ki = 0.0012`` (BROAD's best), compared as it
  is (with the ``q_z(90°)`` turn its heading error is 85-90° on every trial; without it the
  errors are in line with BROAD's published figures), from the first sample's attitude;
* ``fusion``: package ``imufusion`` (x-io Fusion), ENU convention, the settings of its README
  example (gain 0.5, gyroscope range 2000 °/s, acceleration and magnetic rejection 10°,
  rejection timeout 5 s) and its gyro bias (offset) estimation at its defaults.

Times are per trial (about 55,000 samples at 285.7 Hz), one process, the tables of
``ours`` designed before timing (the first construction at a rate costs ~0.1 s).  ``ours``
runs in plain Python; ``vqf`` and ``fusion`` in C/C++; ``madgwick`` and ``mahony`` in numpy
loops.

Run::

    python benchmarks/bench_broad.py [--data PATH] [--ablation] [--loo] [--reversed] [--proxies [WORDS]]
                                     [--only ours9d,vqf]
    python benchmarks/bench_broad.py --accel-angle

``--ablation``: ours9d with each mechanism off (parameters of AttitudeParams), mean and per
trial.  ``--loo``: leave-one-out over the constants tuned on these trials: for each held-out
trial and each constant, the value of a small grid that is best on the other nine, then
scored on the held-out trial (the other constants at their defaults).  ``--reversed``: every
trial played backwards, a motion none of the filters was tuned on (time reversal keeps the
specific force and the field, negates the body rate; the reference moves by one sample so
that each estimate is scored against the attitude after its gyro sample, as forwards).

``--accel-angle``: only the accelerometer's pitch as the angle sensor of a ``cf2`` tilt design (the
figures of ``docs/guide/noise-and-crossover.md``, "An angle from the accelerometer"): its noise at rest
(trial 01's first 31 s), its error in the motion of trial 10, and a pitch filter's predicted std against
its error after the start-up, with the angle's figure at rest and in motion.

``--proxies``: the ten trials turned into recordings none of the filters was tuned on (see
``PROXIES``: another mounting of the sensor, other sample rates, a noisier, biased or mis-scaled
gyro, the field in Gauss or with a hard-iron offset, time reversal, starts 10 s and 30 s into
the motion, with no rest to learn the gyro bias from; and BROAD's categories the ten lack: rest
breaks in the motion, trials of 240-360 s, an office field that varies with the position, a gyro
bias step; and transforms that must not change the figures: resampled to 100, 50, 25 Hz or up to
1000 Hz, a vertical gyro bias of 0.03 or 0.06 rad/s, a gyro 4 times noisier than the default density,
the field's dip turned to 0, -60 and 82 deg, the recording started 30 s or 60 s in, started upside
down or on its side, a gyro bias of 0.03 rad/s about x; and units the filter cannot fully undo: the
field normalised sample by sample, the specific force in g), ours9d, ours6d,
VQF and Madgwick on each: mean total and inclination RMSE per proxy,
the trials where ours9d's total is worse than Madgwick's, and ours9d's wins against VQF in total
and in inclination. ``--proxies WORDS`` keeps the proxies whose name contains one of the
comma-separated words.

Optional dependencies (bench only, never needed by cfdesign or its tests):
``pip install vqf ahrs imufusion``.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from cfdesign import rotations as rot
from cfdesign.nav import AttitudeFilter, mps_quaternion
from cfdesign.nav.broad import broad_rmse, load_trial

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
ENU_FROM_NWU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])
#: the issue's bar: VQF's and Madgwick's figures are those of the same run
MODULES = {"vqf": "vqf", "madgwick": "ahrs", "mahony": "ahrs", "fusion": "imufusion"}


def initial_quaternion(d):
    """First-sample attitude (body -> ENU) from the MPS, for the ``ahrs`` filters."""
    return mps_quaternion(d["acc"][0], d["mag"][0])


def run_ours(d, magnetometer=True, **params):
    f = AttitudeFilter(d["rate"], magnetometer=magnetometer, **params)
    return f.run(d["gyr"], d["acc"], d["mag"] if magnetometer else None)


def run_ours9d(d):
    return run_ours(d)


def run_ours6d(d):
    return run_ours(d, magnetometer=False)


def run_madgwick(d):
    from ahrs.filters import Madgwick
    q0 = rot.multiply(rot.conjugate(ENU_FROM_NWU), initial_quaternion(d))
    q = Madgwick(gyr=d["gyr"], acc=d["acc"], mag=d["mag"], frequency=d["rate"], gain=0.12, q0=q0).Q
    return rot.multiply(ENU_FROM_NWU, q)


def run_mahony(d):
    from ahrs.filters import Mahony
    q0 = initial_quaternion(d)
    return Mahony(gyr=d["gyr"], acc=d["acc"], mag=d["mag"], frequency=d["rate"], k_P=0.74, k_I=0.0012, q0=q0).Q


def run_vqf(d):
    from vqf import VQF
    f = VQF(1.0 / d["rate"])
    return f.updateBatch(np.ascontiguousarray(d["gyr"]), np.ascontiguousarray(d["acc"]),
                         np.ascontiguousarray(d["mag"]))["quat9D"]


def run_fusion(d):
    import imufusion
    settings = imufusion.AhrsSettings()
    settings.convention = imufusion.CONVENTION_ENU
    settings.gain = 0.5
    settings.gyroscope_range = 2000.0
    settings.acceleration_rejection = 10.0
    settings.magnetic_rejection = 10.0
    settings.rejection_timeout = 5.0
    settings.sample_rate = d["rate"]
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    bias_settings = imufusion.BiasSettings()
    bias_settings.sample_rate = d["rate"]
    bias = imufusion.Bias()
    bias.set_settings(bias_settings)
    gyr, acc, mag = np.degrees(d["gyr"]), d["acc"] / 9.80665, d["mag"]     # °/s, g
    out = np.empty((len(gyr), 4))
    for k in range(len(gyr)):
        ahrs.update(bias.update(gyr[k]), acc[k], mag[k])
        out[k] = ahrs.get_quaternion()
    return out


FILTERS = {"ours9d": run_ours9d, "ours6d": run_ours6d, "vqf": run_vqf, "madgwick": run_madgwick,
           "mahony": run_mahony, "fusion": run_fusion}

#: ablation rows: (label, AttitudeParams overrides)
ABLATION = [
    ("all mechanisms", {}),
    ("no rest detection (zero-rotation channel, rest designs)", {"rest_detection": False}),
    ("no gyro bias during motion (tilt channel)", {"motion_bias": False}),
    ("no magnetic disturbance rejection", {"mag_rejection": False}),
    ("rejection, but a new field accepted after 20 s", {"mag_new_field_s": 20.0}),
    ("no acceleration-disturbance designs", {"accel_rejection": False}),
    ("tilt from the instantaneous accelerometer", {"inertial_tilt": False}),
    ("no start-up from the bias prior (DARE gains)", {"gyro_bias_std0": 0.0}),
    ("no shock clipping (accel_shock_sigma 1e15)", {"accel_shock_sigma": 1e15}),
]

#: constants tuned on the ten trials, the grids --loo searches (factors of the default)
TUNED = {"velocity_noise_density": (0.5, 0.71, 1.0, 1.41, 2.0), "tilt_drift_density": (0.5, 0.71, 1.0, 1.41, 2.0),
         "heading_noise_density": (0.5, 0.71, 1.0, 1.41, 2.0), "mag_tolerance_rad": (0.71, 0.85, 1.0, 1.2, 1.41),
         "mag_new_field_s": (0.5, 0.71, 1.0, 1.41, 2.0), "accel_shock_sigma": (1.0, 1.5, 2.0, 3.0)}


def available(names):
    out = []
    for name in names:
        module = MODULES.get(name)
        if module is not None:
            try:
                __import__(module)
            except ImportError:
                print(f"skipping {name}: optional package '{module}' is not installed (pip install {module})")
                continue
        out.append(name)
    return out


def reversed_trial(d, bias=None):
    """The trial played backwards: every sample's specific force, field, reference and movement flag
    in reverse order, and the body rates negated and moved by one sample: the rate of reversed sample
    ``k`` turns the attitude of original sample ``N-k`` into that of ``N-1-k``, so it is the negated
    rate of original sample ``N-k`` (sample 0, whose predecessor there is none, reads no rotation).
    The gyro's bias is negated with the rate unless given (``bias``, rad/s): then the reversed rate is
    ``2 bias - w`` and sample 0 reads ``bias``."""
    out = dict(d)
    b = np.zeros(3) if bias is None else np.asarray(bias, dtype=float)
    gyr = np.empty_like(d["gyr"])
    gyr[0] = b
    gyr[1:] = -d["gyr"][::-1][:-1] + (0.0 if bias is None else 2.0 * b)
    out["gyr"] = gyr
    for key in ("acc", "mag", "ref", "movement"):
        out[key] = np.ascontiguousarray(d[key][::-1])
    return out


def rotated_trial(d, angle_deg=120.0, axis=(1.0, 2.0, 3.0)):
    """The sensor mounted otherwise: every reading turned by a fixed rotation ``R`` of ``angle_deg`` about
    ``axis`` (the new body frame is ``R`` times the old), the reference ``q ⊗ R⁻¹``."""
    axis = np.asarray(axis, dtype=float)
    r = rot.from_rotation_vector(np.radians(angle_deg) * axis / np.linalg.norm(axis))
    out = dict(d)
    for key in ("gyr", "acc", "mag"):
        out[key] = np.ascontiguousarray(rot.rotate(np.tile(r, (len(d[key]), 1)), d[key]))
    out["ref"] = rot.multiply(d["ref"], rot.conjugate(r))
    return out


def decimated_trial(d, m):
    """An IMU at ``rate / m``: every reading the mean of ``m`` samples (the anti-alias average an IMU
    applies), scored against the reference at the block's last sample (the block's rates turn the
    attitude of the previous block's end into it)."""
    n = len(d["gyr"]) // m * m
    out = dict(d)
    for key in ("gyr", "acc", "mag"):
        out[key] = np.ascontiguousarray(d[key][:n].reshape(-1, m, 3).mean(axis=1))
    out["ref"], out["movement"] = d["ref"][m - 1:n:m], d["movement"][m - 1:n:m]
    out["rate"] = d["rate"] / m
    return out


def _nlerp(t, ref, t_new):
    """The reference at times ``t_new`` (s): each row interpolated between the samples at ``t`` either side
    (normalised linear interpolation; NaN where either is NaN)."""
    k = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, len(t) - 2)
    a = ((t_new - t[k]) / (t[k + 1] - t[k]))[:, None]
    q0, q1 = ref[k], ref[k + 1]
    q1 = q1 * np.where(np.sum(q0 * q1, axis=1) < 0.0, -1.0, 1.0)[:, None]
    q = (1.0 - a) * q0 + a * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def resampled_trial(d, rate):
    """An IMU at ``rate`` (Hz, any, above or below the trial's): each rate the mean over its interval of the
    recorded rates (sample ``k`` taken as the rate over the interval that ends at it, so the new rates turn
    the attitude as the recorded ones did); specific force and field low-passed when decimating (zero-phase
    6th-order Butterworth at 0.4 ``rate``) and interpolated linearly at the new sample times; the
    reference interpolated there (``_nlerp``), the movement flag of the nearest sample."""
    from scipy.signal import butter, sosfiltfilt

    r0, n = d["rate"], len(d["gyr"])
    t = np.arange(n) / r0
    t_new = np.arange(1.0, np.floor(t[-1] * rate) + 1.0) / rate
    out = dict(d)
    held = np.vstack([np.zeros((1, 3)), np.cumsum(d["gyr"], axis=0) / r0])        # integral of the held rate
    edges = np.concatenate([[t_new[0] - 1.0 / rate], t_new])
    turn = np.column_stack([np.interp(edges, np.concatenate([[-1.0 / r0], t]), held[:, i]) for i in range(3)])
    out["gyr"] = np.ascontiguousarray(np.diff(turn, axis=0) * rate)
    sos = butter(6, 0.4 * rate, fs=r0, output="sos") if rate < r0 else None
    for key in ("acc", "mag"):
        x = d[key] if sos is None else sosfiltfilt(sos, d[key], axis=0)
        out[key] = np.ascontiguousarray(np.column_stack([np.interp(t_new, t, x[:, i]) for i in range(3)]))
    out["ref"] = _nlerp(t, d["ref"], t_new)
    out["movement"] = d["movement"][np.minimum(np.round(t_new * r0).astype(int), n - 1)]
    out["rate"] = rate
    return out


def normalised_field_trial(d):
    """The field normalised sample by sample (unit vectors, as some loggers write it): its direction kept,
    its norm, which the disturbance check reads, lost."""
    out = dict(d)
    out["mag"] = np.ascontiguousarray(d["mag"] / np.linalg.norm(d["mag"], axis=1, keepdims=True))
    return out


def dip_trial(d, turn_deg):
    """The trial in a field of another dip: every field reading turned, in ENU through the reference, by
    ``turn_deg`` about east (positive: towards the horizontal; 67 from BROAD's 67 deg makes it 0) and back
    into the body frame.  The horizontal field still points north; the reference's own error enters the
    turned field (about half a degree, more in heading the steeper the new field)."""
    q = _finite_ref(d["ref"])
    turn = rot.from_rotation_vector(np.radians(turn_deg) * np.array([1.0, 0.0, 0.0]))
    field = rot.rotate(np.tile(turn, (len(q), 1)), rot.rotate(q, d["mag"]))
    out = dict(d)
    out["mag"] = np.ascontiguousarray(rot.rotate(rot.conjugate(q), field))
    return out


def modified_trial(d, noise=None, gyr_bias=None, gyr_scale=1.0, mag_scale=1.0, hard_iron=None, seed=0,
                   acc_scale=1.0):
    """The trial's readings altered as another sensor would give them: extra white noise (stds of
    gyr, acc, mag per sample), a constant gyro bias (rad/s), a gyro scale factor, the specific force
    (``acc_scale``) or the field (``mag_scale``) in other units, or a hard-iron offset (body frame, the
    field's unit)."""
    out = dict(d)
    rng = np.random.default_rng(seed)
    gyr, acc, mag = d["gyr"] * gyr_scale, d["acc"] * acc_scale, d["mag"] * mag_scale
    if gyr_bias is not None:
        gyr = gyr + np.asarray(gyr_bias)
    if noise is not None:
        gyr = gyr + noise[0] * rng.standard_normal(gyr.shape)
        acc = acc + noise[1] * rng.standard_normal(acc.shape)
        mag = mag + noise[2] * mag_scale * rng.standard_normal(mag.shape)
    if hard_iron is not None:
        mag = mag + np.asarray(hard_iron) * mag_scale
    out["gyr"], out["acc"], out["mag"] = (np.ascontiguousarray(x) for x in (gyr, acc, mag))
    return out


#: start of a trimmed trial after the first movement sample, and the convergence window left unscored (s)
TRIM_S, CONVERGE_S = 10.0, 10.0


def trimmed_trial(d, trim_s=TRIM_S, from_motion=True):
    """The trial started in the middle of its motion (``trim_s`` after the first movement sample, no
    rest before it; ``from_motion`` False: ``trim_s`` after the recording's start, which may leave a
    shorter rest); the first ``CONVERGE_S`` are not scored, for every filter alike."""
    start = (int(np.argmax(d["movement"])) if from_motion else 0) + round(trim_s * d["rate"])
    out = {key: d[key][start:] for key in ("gyr", "acc", "mag", "ref", "movement")}
    out = {key: np.ascontiguousarray(value) for key, value in out.items()}
    out["movement"][:round(CONVERGE_S * d["rate"])] = False
    out["rate"] = d["rate"]
    return out


#: the quiet start of every dev trial (s; each rests for 33 s or more before its motion): its readings are
#: the recorded noise (and gyro bias) the rest-break proxy synthesises rests from
REST_S = 25.0
#: rest breaks inserted by ``breaks_trial``: (fraction of the motion, duration in s)
BREAKS = ((0.25, 5.0), (0.5, 10.0), (0.75, 20.0))


def _finite_ref(ref):
    """``ref`` with every NaN row replaced by the last finite one before it (the first finite one at the start)."""
    ok = np.isfinite(ref).all(axis=1)
    idx = np.where(ok, np.arange(len(ref)), 0)
    idx = np.maximum.accumulate(idx)
    idx[~ok[idx]] = int(np.argmax(ok))
    return ref[idx] / np.linalg.norm(ref[idx], axis=1, keepdims=True)


def _concat(parts):
    keys = ("gyr", "acc", "mag", "ref", "movement")
    out = {key: np.ascontiguousarray(np.concatenate([p[key] for p in parts])) for key in keys}
    out["rate"] = parts[0]["rate"]
    return out


def _slice(d, start, stop):
    out = {key: d[key][start:stop] for key in ("gyr", "acc", "mag", "ref", "movement")}
    out["rate"] = d["rate"]
    return out


def rest_segment(d, k, seconds, offset=0):
    """``seconds`` of rest at the reference attitude of sample ``k`` (NaN rows: the last finite one), synthesised
    from the trial's quiet start (``REST_S``) from sample ``offset`` on: the gyro as recorded there (its bias and
    noise), the specific force the recorded magnitude of gravity turned into the body frame plus the recorded
    noise, the field of sample ``k``'s neighbourhood (0.1 s, turned to ``k``'s attitude by the reference: the
    Earth-fixed field there) plus the recorded noise.  ``movement`` is 0 (BROAD scores motion only)."""
    n, quiet = round(seconds * d["rate"]), round(REST_S * d["rate"])
    if offset + n > quiet:
        raise ValueError(f"a rest of {seconds} s from {offset} does not fit in the quiet start of {REST_S} s")
    ref = _finite_ref(d["ref"])
    q = ref[k]
    acc0, mag0 = d["acc"][:quiet], d["mag"][:quiet]
    g = float(np.linalg.norm(acc0, axis=1).mean())
    w = round(0.05 * d["rate"])
    window = slice(max(k - w, 0), k + w + 1)
    field_enu = rot.rotate(ref[window], d["mag"][window]).mean(axis=0)
    block = slice(offset, offset + n)
    acc = rot.rotate(rot.conjugate(q), [0.0, 0.0, g]) + (acc0[block] - acc0.mean(axis=0))
    mag = rot.rotate(rot.conjugate(q), field_enu) + (mag0[block] - mag0.mean(axis=0))
    return {"gyr": d["gyr"][block], "acc": acc, "mag": mag, "ref": np.tile(q, (n, 1)),
            "movement": np.zeros(n, dtype=bool), "rate": d["rate"]}


def breaks_trial(d, breaks=BREAKS):
    """The trial with rests inserted into its motion (``BREAKS``: at fractions of the motion, for so many
    seconds), each at the reference attitude where it is inserted (``rest_segment``), as BROAD's trials
    with breaks (three rests of 10 s in the motion) hold the sensor still mid-motion."""
    first = int(np.argmax(d["movement"]))
    last = len(d["movement"]) - int(np.argmax(d["movement"][::-1]))
    parts, start = [], 0
    for fraction, seconds in breaks:
        k = first + round(fraction * (last - first))
        parts += [_slice(d, start, k + 1), rest_segment(d, k, seconds)]
        start = k + 1
    return _concat([*parts, _slice(d, start, len(d["movement"]))])


def quiet_bias(d):
    """The gyro's mean over the trial's quiet start (``REST_S``): its bias, rad/s."""
    return d["gyr"][:round(REST_S * d["rate"])].mean(axis=0)


def long_trial(d):
    """A long trial (BROAD's combined trials last 240-360 s): the trial up to the end of its motion, then
    played back to its start (``reversed_trial`` keeping the gyro's bias: the reversed rate is
    ``2 b - w`` with ``b`` the bias of ``quiet_bias``, so the bias does not change sign at the turn); the
    attitude is continuous at the turn."""
    last = len(d["movement"]) - int(np.argmax(d["movement"][::-1]))
    forward = _slice(d, 0, last)
    return _concat([forward, reversed_trial(forward, bias=quiet_bias(d))])


#: where ``repeated_trial`` joins the repeat: this long into the rest after the motion, to this long before
#: the motion in the repeat (s)
JOIN_AFTER_S, JOIN_BEFORE_S = 5.0, 1.0


def repeated_trial(d):
    """A long trial (BROAD's combined trials last 240-360 s) played forwards only: the trial up to
    ``JOIN_AFTER_S`` into its final rest, then its motion again (from ``JOIN_BEFORE_S`` before it) with
    the sensor remounted by the rotation ``C`` that makes the attitude continuous at the join (readings
    turned by ``C⁻¹``, the gyro about its bias of ``quiet_bias``; reference ``q ⊗ C``, as
    ``rotated_trial``)."""
    first = int(np.argmax(d["movement"]))
    last = len(d["movement"]) - int(np.argmax(d["movement"][::-1]))
    end = min(last + round(JOIN_AFTER_S * d["rate"]), len(d["movement"]))
    start = first - round(JOIN_BEFORE_S * d["rate"])
    ref = _finite_ref(d["ref"])
    c = rot.multiply(rot.conjugate(ref[start]), ref[end - 1])
    copy = _slice(d, start, len(d["movement"]))
    turn = np.tile(rot.conjugate(c), (len(copy["gyr"]), 1))
    b = quiet_bias(d)
    copy["gyr"] = rot.rotate(turn, d["gyr"][start:] - b) + b
    copy["acc"], copy["mag"] = rot.rotate(turn, d["acc"][start:]), rot.rotate(turn, d["mag"][start:])
    copy["ref"] = rot.multiply(d["ref"][start:], np.tile(c, (len(copy["gyr"]), 1)))
    return _concat([_slice(d, 0, end), copy])


def _positions(d):
    """``opt_pos`` with its NaN rows filled by the last finite one (the first finite one at the start)."""
    pos = d["pos"]
    ok = np.isfinite(pos).all(axis=1)
    idx = np.maximum.accumulate(np.where(ok, np.arange(len(pos)), 0))
    idx[~ok[idx]] = int(np.argmax(ok))
    return pos[idx]


#: the office field of ``office_trial``: amplitude per ENU component (uT), wavelength (m), and the
#: wave directions and phases (fixed, chosen once)
OFFICE_UT, OFFICE_WAVELENGTH_M = 10.0, 2.0
OFFICE_DIRECTIONS = np.array([[0.8, 0.6, 0.0], [-0.36, 0.48, 0.8], [0.48, -0.64, 0.6]])
OFFICE_PHASES = np.array([0.7, 2.1, -1.3])


def office_field(pos):
    """The office's disturbance of the field at ENU positions ``pos`` (m): each ENU component a plane wave
    in space, ``OFFICE_UT * (sin(k_i . p + phi_i) - sin(phi_i))`` (zero at the origin), uT."""
    k = 2.0 * np.pi / OFFICE_WAVELENGTH_M * OFFICE_DIRECTIONS
    return OFFICE_UT * (np.sin(pos @ k.T + OFFICE_PHASES) - np.sin(OFFICE_PHASES))


def office_trial(d):
    """The field of an office (BROAD's office trials: the field varies as the sensor moves through it): the
    ``office_field`` of the marker's position relative to its first one, an ENU vector that changes the
    field's norm and dip, turned into the body frame by the reference and added to the readings."""
    pos = _positions(d)
    disturbance = office_field(pos - pos[0])
    out = dict(d)
    out["mag"] = np.ascontiguousarray(d["mag"] + rot.rotate(rot.conjugate(_finite_ref(d["ref"])), disturbance))
    return out


#: the gyro bias step of ``bias_step_trial`` (rad/s, body frame; 0.5 deg/s): a temperature change mid-motion
BIAS_STEP = np.radians(0.5) * np.array([0.6, -0.64, 0.48])


def bias_step_trial(d):
    """The gyro's bias changed by ``BIAS_STEP`` halfway through the motion (a temperature step)."""
    first = int(np.argmax(d["movement"]))
    last = len(d["movement"]) - int(np.argmax(d["movement"][::-1]))
    out = dict(d)
    gyr = d["gyr"].copy()
    gyr[(first + last) // 2:] += BIAS_STEP
    out["gyr"] = gyr
    return out


#: the proxies of ``--proxies``: recordings none of the filters was tuned on, made from the ten
PROXIES = {
    "as recorded": lambda d: d,
    "sensor frame turned 120 deg": rotated_trial,
    "decimated to 95 Hz": lambda d: decimated_trial(d, 3),
    "decimated to 48 Hz": lambda d: decimated_trial(d, 6),
    "noisier (0.5 deg/s, 0.05 m/s2, 1 uT)": lambda d: modified_trial(d, noise=(np.radians(0.5), 0.05, 1.0)),
    "gyro bias (1, -1.5, 0.5) deg/s": lambda d: modified_trial(d, gyr_bias=np.radians([1.0, -1.5, 0.5])),
    "gyro scale +0.5 %": lambda d: modified_trial(d, gyr_scale=1.005),
    "field in Gauss": lambda d: modified_trial(d, mag_scale=0.01),
    "hard iron (1, -0.8, 0.5) uT": lambda d: modified_trial(d, hard_iron=(1.0, -0.8, 0.5)),
    "hard iron (4, -3, 2) uT": lambda d: modified_trial(d, hard_iron=(4.0, -3.0, 2.0)),
    "played backwards": reversed_trial,
    f"started mid-motion ({CONVERGE_S:g} s unscored)": trimmed_trial,
    f"started 30 s into the motion ({CONVERGE_S:g} s unscored)": lambda d: trimmed_trial(d, 30.0),
    "rest breaks of 5, 10, 20 s mid-motion": breaks_trial,
    "long: to the motion's end and back": long_trial,
    "long: the motion twice (remounted)": repeated_trial,
    "office field (10 uT waves, 2 m)": office_trial,
    "gyro bias step 0.5 deg/s mid-motion": bias_step_trial,
    "rest breaks, the bias step after the 2nd": lambda d: bias_step_trial(breaks_trial(d)),
    "resampled to 100 Hz": lambda d: resampled_trial(d, 100.0),
    "resampled to 50 Hz": lambda d: resampled_trial(d, 50.0),
    "resampled to 25 Hz": lambda d: resampled_trial(d, 25.0),
    "upsampled to 1000 Hz": lambda d: resampled_trial(d, 1000.0),
    "gyro bias 0.03 rad/s about z": lambda d: modified_trial(d, gyr_bias=(0.0, 0.0, 0.03)),
    "gyro bias 0.06 rad/s about z": lambda d: modified_trial(d, gyr_bias=(0.0, 0.0, 0.06)),
    "gyro noise 4x the default density": lambda d: modified_trial(
        d, noise=(np.sqrt(15.0) * 2e-4 * np.sqrt(d["rate"]), 0.0, 0.0)),
    "field dip 0 deg (equator), in Gauss": lambda d: modified_trial(dip_trial(d, 67.0), mag_scale=0.01),
    "field dip -60 deg (south)": lambda d: dip_trial(d, 127.0),
    "field dip 82 deg": lambda d: dip_trial(d, -15.0),
    f"recording started 30 s in ({CONVERGE_S:g} s unscored)": lambda d: trimmed_trial(d, 30.0, from_motion=False),
    f"recording started 60 s in ({CONVERGE_S:g} s unscored)": lambda d: trimmed_trial(d, 60.0, from_motion=False),
    f"no rest: from 1 s before the motion ({CONVERGE_S:g} s unscored)": lambda d: trimmed_trial(d, -1.0),
    f"no rest, gyro bias (1, -1.5, 0.5) deg/s ({CONVERGE_S:g} s unscored)": lambda d: modified_trial(
        trimmed_trial(d, -1.0), gyr_bias=np.radians([1.0, -1.5, 0.5])),
    "units: field normalised sample by sample": normalised_field_trial,
    "units: specific force in g": lambda d: modified_trial(d, acc_scale=1.0 / 9.81),
    "start upside down (turned 180 deg about x)": lambda d: rotated_trial(d, 180.0, (1.0, 0.0, 0.0)),
    "start on its side (turned 90 deg about x)": lambda d: rotated_trial(d, 90.0, (1.0, 0.0, 0.0)),
    "gyro bias 0.03 rad/s about x": lambda d: modified_trial(d, gyr_bias=(0.03, 0.0, 0.0)),
}


def _proxy_score(args):
    path, proxy, name = args
    d = PROXIES[proxy](load_trial(path))
    return broad_rmse(FILTERS[name](d), d["ref"], d["movement"])


def proxy_scores(files, names, jobs, proxies=None):
    """``(proxy, {filter: (len(files), 3) array})`` of (total, heading, inclination) RMSE per proxy, in parallel,
    yielded as each proxy is done."""
    proxies = list(PROXIES) if proxies is None else proxies
    with ProcessPoolExecutor(jobs) as pool:
        for proxy in proxies:
            tasks = [(path, proxy, name) for name in names for path in files]
            flat = np.array(list(pool.map(_proxy_score, tasks))).reshape(len(names), len(files), 3)
            yield proxy, dict(zip(names, flat, strict=True))


def select_proxies(spec):
    """The keys of ``PROXIES`` that contain one of the comma-separated words of ``spec`` (all for ``""``)."""
    words = [w.strip().lower() for w in spec.split(",") if w.strip()]
    return [p for p in PROXIES if not words or any(w in p.lower() for w in words)]


def proxy_table(files, jobs, proxies=None, only=None):
    """Print the proxies' table (each row as its proxy is done) for ours9d, ours6d, VQF and Madgwick, or those of
    them in ``only``; return ``{proxy: {filter: (len(files), 3) array}}``."""
    names = available([n for n in ("ours9d", "ours6d", "vqf", "madgwick") if only is None or n in only])
    scores = {}
    print("\nProxies of unseen recordings: mean total / inclination RMSE (deg) over the ten trials; trials where "
          "ours9d's total is worse than Madgwick's; trials where ours9d beats VQF (total, inclination)")
    print("proxy".ljust(42) + "".join(f"{n:>12}" for n in names) + "   worse than Madgwick / beats VQF")
    for proxy, by_name in proxy_scores(files, names, jobs, proxies):
        scores[proxy] = by_name
        row = proxy[:41].ljust(42) + "".join(f"{by_name[n][:, 0].mean():6.2f}/{by_name[n][:, 2].mean():5.2f}"
                                             for n in names)
        if {"ours9d", "vqf", "madgwick"} <= set(names):
            ours, vqf, madgwick = (by_name[n] for n in ("ours9d", "vqf", "madgwick"))
            worse = [f"{files[i].stem[:2]} ({ours[i, 0]:.2f}>{madgwick[i, 0]:.2f})" for i in range(len(files))
                     if ours[i, 0] > madgwick[i, 0]]
            row += (f"   {', '.join(worse) or 'none'} / {int(np.sum(ours[:, 0] < vqf[:, 0]))}, "
                    f"{int(np.sum(ours[:, 2] < vqf[:, 2]))} of {len(files)}")
        print(row, flush=True)
    return scores


def _score(args):
    path, params = args
    d = load_trial(path)
    return broad_rmse(run_ours(d, **params), d["ref"], d["movement"])


def _scores(files, params_list, jobs):
    """``[len(params_list)][len(files)]`` of (total, heading, inclination), in parallel."""
    tasks = [(path, params) for params in params_list for path in files]
    with ProcessPoolExecutor(jobs) as pool:
        flat = list(pool.map(_score, tasks))
    return np.array(flat).reshape(len(params_list), len(files), 3)


def main_table(files, names, reverse=False):
    table = {n: [] for n in names}
    times = {n: [] for n in names}
    print("RMSE deg (total / heading / inclination), then the time per trial in ms"
          + (" - every trial played backwards" if reverse else ""))
    print("trial".ljust(22) + "".join(f"{n:>25}" for n in names))
    for path in files:
        d = reversed_trial(load_trial(path)) if reverse else load_trial(path)
        AttitudeFilter(d["rate"])                        # design the tables before timing
        row = path.stem[:21].ljust(22)
        for n in names:
            t = time.perf_counter()
            q = FILTERS[n](d)
            times[n].append(time.perf_counter() - t)
            table[n].append(broad_rmse(q, d["ref"], d["movement"]))
            tot, hd, inc = table[n][-1]
            row += f"{tot:6.2f}/{hd:5.2f}/{inc:5.2f}{1000 * times[n][-1]:7.0f}"
        print(row, flush=True)
    row = "mean".ljust(22)
    for n in names:
        tot, hd, inc = np.mean(table[n], axis=0)
        row += f"{tot:6.2f}/{hd:5.2f}/{inc:5.2f}{1000 * np.mean(times[n]):7.0f}"
    print(row)
    if {"ours9d", "vqf", "madgwick"} <= set(names):
        ours, vqf, madgwick = (np.array(table[n]) for n in ("ours9d", "vqf", "madgwick"))
        worse = [files[i].stem for i in range(len(files)) if ours[i, 0] > madgwick[i, 0]]
        print(f"\nours9d against VQF: mean total {ours[:, 0].mean():.3f} vs {vqf[:, 0].mean():.3f}, inclination "
              f"{ours[:, 2].mean():.3f} vs {vqf[:, 2].mean():.3f}; trials worse than Madgwick: "
              f"{', '.join(worse) or 'none'}")


def ablation(files, jobs):
    scores = _scores(files, [params for _, params in ABLATION], jobs)
    print("\nAblation of ours9d (mean total / heading / inclination, then total per trial)")
    print("".ljust(56) + "   mean" + "".join(f"{p.stem[:2]:>6}" for p in files))
    for (label, _), s in zip(ABLATION, scores, strict=True):
        tot, hd, inc = s.mean(axis=0)
        print(f"{label[:55]:<56}{tot:5.2f}/{hd:4.2f}/{inc:4.2f}" + "".join(f"{v:6.2f}" for v in s[:, 0]))


def leave_one_out(files, jobs):
    from cfdesign.nav import AttitudeParams

    default = AttitudeParams()
    print("\nLeave-one-out over the tuned constants (mean total RMSE, deg): the value best on nine trials, "
          "scored on the tenth")
    for name, factors in TUNED.items():
        values = [getattr(default, name) * f for f in factors]
        scores = _scores(files, [{name: v} for v in values], jobs)[:, :, 0]      # (values, trials)
        picks, held = [], []
        for i in range(len(files)):
            others = np.delete(scores, i, axis=1).mean(axis=1)
            j = int(np.argmin(others))
            picks.append(factors[j])
            held.append(scores[j, i])
        best = factors[int(np.argmin(scores.mean(axis=1)))]
        print(f"  {name:<24} default {getattr(default, name):.4g}: in-sample {scores[factors.index(1.0)].mean():.3f}, "
              f"leave-one-out {np.mean(held):.3f}; factor picked per fold {picks} (best on all ten: {best})")


#: standard gravity for the accelerometer's angle, m/s²
GRAVITY = 9.81
#: seconds of trial 01's opening rest whose accelerometer x axis gives the angle's noise at rest
ANGLE_REST_S = 31.0


def accel_pitch(acc):
    """The pitch read from the specific force, ``atan2(-a_x, sqrt(a_y² + a_z²))``, rad."""
    return np.arctan2(-acc[:, 0], np.hypot(acc[:, 1], acc[:, 2]))


def reference_pitch(ref):
    """The reference's pitch (body -> ENU), by the same formula on gravity in the body frame; NaN rows stay NaN."""
    R = rot.to_matrix(ref)
    return np.arctan2(-R[:, 2, 0], np.hypot(R[:, 2, 1], R[:, 2, 2]))


def _rms(x):
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2)))


def pitch_run(d, gyro_density, angle_density):
    """A ``cf2`` pitch filter (gyro y as the angle's rate, bias density 1e-5 rad/s/√s) run on trial ``d`` by
    :func:`cfdesign.logs.run_log` against the reference pitch: (predicted std, RMS after the start-up, start-up s,
    log length s)."""
    import warnings

    import pandas as pd

    import cfdesign
    from cfdesign.logs import run_log
    from cfdesign.spec import parse_spec

    sensors = {"gyro": {"port": "rate", "rate_hz": d["rate"], "noise": {"density": gyro_density},
                        "bias": {"model": "random_walk", "density": 1e-5}},
               "accelerometer": {"port": "angle", "rate_hz": d["rate"], "noise": {"density": angle_density}}}
    table = cfdesign.design(parse_spec({"name": "pitch", "structure": "cf2", "order": 2, "discrete": True,
                                        "sensors": sensors}))
    t = np.arange(len(d["acc"])) / d["rate"]
    log = pd.DataFrame({"time": t, "gyro": d["gyr"][:, 1], "accelerometer": accel_pitch(d["acc"]),
                        "truth": reference_pitch(d["ref"])}).dropna(subset=["truth"]).reset_index(drop=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_log(table, log, reference="truth")
    state = next(iter(r.rms_settled))
    return r.predicted_std[state], r.rms_settled[state], r.startup_s, float(log["time"].iloc[-1])


def accel_angle(files):
    """The accelerometer's pitch as a tilt design's angle sensor (docs/guide/noise-and-crossover.md): its noise at
    rest (trial 01), its error in motion (trial 10), and a ``cf2`` pitch filter's prediction against its error."""
    from cfdesign import identify_noise

    trials = {p.stem[:2]: p for p in files}
    if not {"01", "03", "10"} <= set(trials):
        print("\n--accel-angle needs trials 01, 03 and 10")
        return
    d1, d10 = load_trial(trials["01"]), load_trial(trials["10"])
    rest = slice(0, round(ANGLE_REST_S * d1["rate"]))
    n_acc = identify_noise(d1["acc"][rest, 0], d1["rate"], "acc_x").white_density
    n_gyro = identify_noise(d1["gyr"][rest, 1], d1["rate"], "gyr_y").white_density
    n_angle = n_acc / GRAVITY
    at_rest = _rms(accel_pitch(d1["acc"][rest]) - reference_pitch(d1["ref"][rest]))
    print(f"\nAccelerometer pitch as an angle sensor: trial 01's first {ANGLE_REST_S:g} s at rest gave N_ax = "
          f"{n_acc:.3g} m/s²/√Hz, N_theta = {n_angle:.2g} rad/√Hz: {n_angle * np.sqrt(d1['rate']):.2g} rad a reading "
          f"at {d1['rate']:.4g} Hz; the angle {at_rest:.2g}"
          f" rad RMS off the reference there (gyro y N = {n_gyro:.2g} rad/s/√Hz)")
    err10 = accel_pitch(d10["acc"]) - reference_pitch(d10["ref"])
    moving = _rms(err10[d10["movement"]])
    print(f"  trial 10, over its motion: the accelerometer's pitch {moving:.3g} rad RMS off the reference, "
          f"{moving / (n_angle * np.sqrt(d1['rate'])):.0f} times its figure at rest")
    for label, density in (("at rest", n_angle), ("in motion", moving / np.sqrt(d10["rate"]))):
        pred, rms, startup, length = pitch_run(d10, n_gyro, density)
        print(f"  cf2 pitch on trial 10, angle figure {label} {density:.2g} rad/√Hz: predicted std {pred:.3g} rad, "
              f"RMS after the start-up {rms:.3g} rad ({rms / pred:.0f} times); "
              f"start-up {startup:.0f} s of {length:.0f} s")
    for key in ("01", "03"):
        d = load_trial(trials[key])
        _, rms, _, _ = pitch_run(d, n_gyro, n_angle)
        print(f"  cf2 pitch (angle figure at rest) on slow rotation trial {key}: {rms:.2g} rad RMS after the start-up")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of BROAD .mat trials")
    parser.add_argument("--only", help="comma-separated filters of " + ", ".join(FILTERS))
    parser.add_argument("--ablation", action="store_true", help="also the ablation table of ours9d")
    parser.add_argument("--loo", action="store_true", help="also the leave-one-out check of the tuned constants")
    parser.add_argument("--jobs", type=int, default=2, help="processes for --ablation, --loo and --proxies")
    parser.add_argument("--reversed", action="store_true", help="also the table of every trial played backwards")
    parser.add_argument("--accel-angle", action="store_true",
                        help="only the accelerometer's pitch as a tilt design's angle sensor (trials 01, 03, 10)")
    parser.add_argument("--proxies", nargs="?", const="", metavar="WORDS",
                        help="also ours9d, ours6d, VQF and Madgwick (those in --only) on proxies of unseen recordings "
                             "(PROXIES); WORDS (comma-separated) keeps the proxies whose name contains one of them")
    args = parser.parse_args(argv)
    files = sorted(args.data.glob("*.mat"))
    if not files:
        print(f"no BROAD trials (*.mat) in {args.data}")
        return 1
    names = available(args.only.split(",") if args.only else list(FILTERS))
    unknown = [n for n in names if n not in FILTERS]
    if unknown:
        print(f"unknown filter(s): {', '.join(unknown)}")
        return 1
    proxies = None if args.proxies is None else select_proxies(args.proxies)
    if proxies == []:
        print(f"--proxies: no proxy matches {args.proxies!r}; the proxies are: {'; '.join(PROXIES)}", file=sys.stderr)
        return 2
    if args.accel_angle:
        accel_angle(files)
        return 0
    main_table(files, names)
    if args.reversed:
        print()
        main_table(files, names, reverse=True)
    if args.proxies is not None:
        proxy_table(files, args.jobs, proxies, args.only.split(",") if args.only else None)
    if args.ablation:
        ablation(files, args.jobs)
    if args.loo:
        leave_one_out(files, args.jobs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
