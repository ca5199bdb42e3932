"""A streaming attitude filter for real IMUs: designed channels, rest, magnetic and acceleration disturbances.

:class:`AttitudeFilter` estimates the attitude of a gyro + accelerometer (+ magnetometer)
sample by sample, in plain Python floats (no numpy per step), and exports as C99
(:mod:`cfdesign.codegen.attitude`).  :func:`cfdesign.nav.estimate_attitude` is a thin call of
it.  The derivation is in ``docs/derivations.md`` ("Attitude from real IMUs"); in short, the
gyro propagates the attitude and four designed complementary channels correct it, each a
``cf2`` channel (:mod:`cfdesign.nav.attitude_channel`, gains from the DARE of
:func:`~cfdesign.nav.design_channel`, no sympy):

* **tilt: a velocity channel.** The specific force rotated into the estimated ENU frame
  integrates to the sensor's velocity change; a device that is hand-held, worn or carried
  has a bounded velocity.  Each horizontal axis is the chain ``v' = f_E + c``,
  ``c' = g (gyro noise)`` with the pseudo-measurement ``v = 0``: a ``cf2`` channel whose
  rate input is the horizontal specific force (noise: the accelerometer's), whose "bias" is
  ``-g`` times the tilt error (its random walk: ``g`` times the gyro noise) and whose angle
  reading is the zero velocity (noise: how far the velocity strays, ``velocity_noise_density``).
  Its bias correction is applied as a rotation of the attitude, so the filter low-passes the
  specific force in the almost inertial frame of the gyro, where the average of the
  acceleration is the bounded velocity change (the idea of filtering the accelerometer in an
  almost inertial frame is from VQF: D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation
  estimation with bias estimation and magnetic disturbance rejection", Information Fusion 91,
  2023).  For an accelerometer far less noisy than the motion the DARE gives the damping
  ``1/sqrt(2)`` and the natural frequency ``sqrt(g sigma_tilt / sigma_v)``: a second-order
  Butterworth low-pass of the inertial specific force, derived rather than chosen.
  It starts after a start-up of one time constant of that low-pass (``1 / omega``): from the
  tilt of the first specific force, the tilt is turned by the gyro and set upright on the running
  mean of the specific forces so far (of the vectors: a moving sensor's mean specific force is
  gravity plus its velocity change over the time, its mean direction is not), and the tilt channel
  (below) waits, so the settling of a first reading's noise is not read as gyro bias (no start-up
  with a given initial attitude).  A sensor moving at the start leaves the start-up's tilt off by
  its velocity change over it (up to ``max_speed_mps``, taken as three standard deviations),
  which the velocity channel removes with the envelope ``exp(-omega t / sqrt(2))``: over its 2 %
  settling time ``4 sqrt(2) / omega`` the tilt channel takes that decaying error as reading noise
  (its reading variance widened by it, as white noise of the same correlation time), not as gyro
  bias.
* **gyro bias during motion: a tilt channel** (``cf2``: its attitude error kept in the body
  frame, where the bias is constant, moved by the gyro and read as the velocity channel's tilt,
  noise ``tilt_noise_density``), whose rate correction is the gyro bias: learnt slowly, over
  minutes, from the tilt corrections the velocity channel makes.  Those lag the tilt (by about
  ``1 / omega``, 2 s), so they are mapped into the body frame not with the current attitude but with its
  first two rows passed through the velocity channel's own step (``_lagged``: the correction a bias draws
  is those lagged rows times the bias; the rotation matrix low-passed like the specific force is VQF's
  measurement matrix for its bias during motion), and the covariance recursion moves the channel's angle
  by the bias at their mean squared gain ``h²`` (1 for a steady attitude, less as a rotation blurs them).
  Without a rest, a bias of 1.7 deg/s about a horizontal body axis is learnt to 0.1 deg/s in 60 s (0.8
  with the current attitude).
* **heading: a heading channel** (``cf2``: the heading driven by the gyro, read from the
  magnetometer's horizontal direction, noise ``heading_noise_density``), switched off while the
  field is disturbed.
* **rest: a zero-rotation channel** (``cf2``: the body's rotation since rest began, read as
  zero, noise the gyro's own noise over one sample), whose rate correction is the full gyro
  bias, vertical axis included: a rest of a second or two averages the gyro into the bias.  Its
  bias variance starts from what the random walk left, widened at the rest's start to what its first
  reading of the bias (the detector's low-passed rate) says the bias errs by, so a bias that stepped
  during the motion (a temperature change) is relearnt in that time too.

The tilt, heading and zero-rotation channels run the Kalman covariance recursion of their own
table (``F, Q, R``; its fixed point is the table's DARE covariance, so the steady gains are the
designed ones) from the bias prior ``gyro_bias_std0`` (the heading channel: the smaller
``heading_bias_std0``, the field's heading erring with the orientation): a large bias is learnt
in seconds; a channel that cannot update (field disturbed, reading missing) only predicts, its
variance grows, and it resumes with a larger but smooth gain (no jump); a rest hands its bias
variance to the other two; a newly accepted field clears the heading's correlation with the bias.

Modes and their tables (one design each): the velocity channel runs a rest design at rest
(zero velocity is then exact: noise the accelerometer's over one sample), the motion design
otherwise, and designs with a larger velocity noise (factors 4, 16, ... 1024: the tilt bandwidth
halved at each level) when the speed the channel has integrated has exceeded ``max_speed_mps``
for longer than a hand's stroke, ``max_reach_m / max_speed_mps``
(level ``1 + floor(log2(v² / max_speed²))``) (a sustained acceleration: the specific force
is not gravity plus a bounded velocity change, so the tilt corrections are weighted down), for at
most ``max_accel_time_s`` at a time (longer, it is a tilt error: the velocity restarts from zero
on the motion design).  Sooner, once the designs have run for the start-up's time ``1 / omega``, a
specific force that is steady and whose norm is gravity's (the start-up's) is a tilt error of the
estimate (a gyro spike, a clipped accelerometer), not an acceleration, which would add to the norm:
the start-up runs again, as after a gap in the gyro (``_tilt_error``).
Every threshold is in physical units, derived from the noise figures where it can be:

* rest: for ``rest_time_s`` the gyro and the specific force stay within
  ``rest_sigma * sqrt(3)`` times their per-sample noise (std per axis, from the densities) of
  their ``rest_filter_s`` low-pass, or within twice the noise measured where that is larger, and the
  low-passed rate within ``3 gyro_bias_std0`` of the bias estimate.  The noise measured is each
  sensor's floor: its white noise from the differences of successive samples (low-passed over
  ``rest_filter_s``; a motion smooth at the sample rate hardly adds to it, unlike to the deviation from
  the low-pass), followed down at once, risen by at most a factor 2 per second while the deviation
  could be rest and kept within 1/16 to 16 times the densities' variance (``REST_FLOOR_*``).  A sensor
  as noisy as its density, or quieter, keeps the designed thresholds (its floor stays below their
  9/4); a gyro 4 times noisier than its density, which never rested, rests within seconds and learns
  its bias (and of a slow motion its noise hides, reads no more as rest than a filter built with its
  true density).  A sensor more than twice as noisy as its density at rest is warned of once
  (``UserWarning``): the channels' gains still take the density, so set it (``cfdesign noise`` on a
  still log);
* magnetic disturbance: the field's norm and dip angle (low-passed over ``mag_filter_s``)
  against a reference learned online (running mean, then a ``mag_reference_s`` low-pass
  while undisturbed; until the ``mag_filter_s`` low-pass has settled it is a running mean of
  the readings and the reference is that mean, so one noisy first reading cannot seed it; and it
  starts only once the tilt's start-up is over, as a dip read through an unsettled tilt is not the
  field's; so is the heading the start-up's fields set, checked against no reference and read through that
  tilt, whose error turns the field's horizontal direction by up to ``tan(dip)`` times as much: it is reopened
  then to the prior of a heading not known at all, as with no field before; a device started in motion beside
  a magnet keeps no heading of it): a
  change of the norm by ``dN`` or of the dip by ``dD`` hides a field
  change that can turn the heading by ``dN / B_h`` or ``dD B / B_h``, so the field is disturbed
  when ``|dN| / B`` or ``|dD|`` exceeds ``mag_tolerance_rad * cos(dip)``; a new field is
  accepted after ``mag_new_field_s`` in which it stayed consistent while the sensor turned by
  at least ``mag_new_field_rotation_rad`` (the idea of accepting a new homogeneous field after
  a while of motion is VQF's; the turn is summed from the rest detector's low-passed rate, whose
  noise, unlike the raw rate's, does not add up faster at a higher sample rate).  A reference that
  has not yet held for ``mag_provisional_s`` (the first one, or one relearnt after a restart or
  taken over from such a one) is provisional: nothing says the field at the start was the clean one
  (a device started beside a motor or on a steel table), so a new field replaces it once it has held
  as long as the reference had (at least ``mag_first_field_s``; the same turn), and the heading the
  provisional field set is reopened to the prior of a heading not known at all (VQF, too, accepts its
  first field sooner than a later new one).  A provisional reference the field has left for longer than
  the reference itself had held is no better evidence than the field that left it (a device started with
  a magnet fixed beside it: its first fraction of a second set both the reference and the heading):
  while it lasts the heading follows the field, its reading variance widened ``mag_follow_factor`` times
  (the heading's bandwidth about halved) and no gyro bias learnt from it, so an error that turns with the
  sensor averages out instead of the first moment's being held;
* shocks: a specific force within the sensor's range but far off the recent ones (a tap, a knock, an
  impact: one sample or a few) would enter the velocity channel with its full weight, a velocity step that
  the tilt then follows for seconds (2.7 deg from one sample of 200 m/s² at 100 Hz).  Its deviation from the
  rest detector's low-pass is clipped to ``accel_shock_sigma`` times the recent spread (the root of that
  detector's low-passed squared deviation, or of its noise floor), Huber-like, before any channel or the
  detector sees it; the clipped deviation still raises the spread, so a sustained change is followed within
  a tenth of a second (``_shock_clipped``).  Only once the tilt's start-up is over (``1 / omega``, longer than
  the low-pass's time constant): before, the spread of a sensor started in motion is not yet measured.  A
  given ``initial`` attitude runs no start-up: its specific forces are counted (``tilt_n``, down from 0) and
  the clipping starts once as many have been seen as the start-up takes (a shock before is taken whole);
* bad samples: non-finite readings, a rate above ``gyro_range_rps`` or a specific force above
  ``accel_range_mps2`` (physically impossible for the sensor) are missing and counted: a
  missing rate holds the last good one, a missing specific force or field skips its channel (the rest test
  keeps the accelerometer's side as its last reading left it, so an accelerometer slower than the gyro, NaN
  between its readings, still lets the sensor rest).
  A gap in the gyro longer than the tilt's start-up (``1 / omega``, 2 s by default), or one over which the
  held rate turned the attitude by more than ``GAP_TURN_RAD`` (0.3 rad: 0.3 s at 1 rad/s), has lost the
  attitude (the body turned unseen; the held rate only extrapolates): the first rate after it
  runs the start-up again from the specific force, keeping the heading held through the gap (in
  9D the field then sets it: the heading channel's prior is reopened) and the gyro bias.  Without
  it the tilt error a gap leaves is read as a sustained acceleration and the dip it skews as a
  magnetic disturbance, which held it for tens of seconds;
* units: readings in g or deg/s are warned of (the filter runs on): a median specific force far
  from gravity, and a gyro that turns gravity, over short quiet windows, more than 2.5 times faster
  than the accelerometer shows it turning (57 times in deg/s, slow motion too; ``_GyroUnits``); turning
  it as far but another way, the gyro's axes are warned of as not the accelerometer's (an axis flipped, x and
  y swapped, NED against ENU: 51 to 82 deg RMS off in heading, warned of as deg/s before, a flipped z not at all).
  A field whose angle to gravity wanders as the sensor turns is warned of as in other axes than the
  accelerometer's (``_check_field_frame``), and so is one that turns against the gyro's turn
  (``_check_field_turn``: a ground robot turning about gravity alone, which the two checks above do not see).

The gyro turns the attitude by ``(w - b) T`` plus the two-sample coning term
``(u_prev x u) / 12`` of strapdown attitude algorithms, so that rates averaged over their interval
(an IMU's anti-alias filter, a decimated log) integrate alike at any sample rate.

Frames: attitude of the body (sensor) frame relative to **ENU** (x east, y north, z up);
quaternions ``[w, x, y, z]`` map body to ENU; rates (rad/s), specific force (m/s²) and the
field (any consistent unit) in the body frame.
"""

from __future__ import annotations

import functools
import math
import sys
from dataclasses import dataclass, fields, replace

import numpy as np

from ..errors import AttitudeInputError
from ..linear import wrap_scalar
from ..runtime.step import real_float
from .attitude_channel import design_channel

__all__ = ["AttitudeFilter", "AttitudeParams", "AttitudeRun", "AttitudeDesign", "GRAVITY", "STATE_FIELDS",
           "STATE_LIMIT", "design_attitude"]

#: standard gravity (m/s²): converts the velocity channel's correction into an angle
GRAVITY = 9.80665
#: velocity-noise factors of the acceleration-disturbance designs (levels 1, 2, ...: the speed squared
#: beyond max_speed_mps² doubling per level; each level quarters the tilt bandwidth)
DISTURBANCE_FACTORS = (4.0, 16.0, 64.0, 256.0, 1024.0)
#: the velocity channel's settling after its start-up, in its time constants ``1 / omega`` from the first
#: specific force: the start-up (one) and the 2 % settling time ``4 / (zeta omega)`` (``zeta = 1/sqrt(2)``)
#: in which it removes what the start-up left of a sensor that was moving (the velocity it had)
TILT_SETTLE = 1.0 + 4.0 * math.sqrt(2.0)

#: a gap in the gyro over which the held rate (less the bias) turned the attitude by more than this (rad) runs the
#: tilt's start-up again, as a gap longer than the start-up does: the body turned unseen and the held rate only
#: extrapolates (gaps of 0.5-1.9 s while turning at ~1 rad/s left 3-21 deg RMS over the next 25-30 s, one of
#: 1 s still 20 deg off 20 s later; with the restart 1.1-6.4 deg; below about 0.3 rad the restart's own start-up
#: in motion costs more than the extrapolation: a 0.1-0.2 s gap 0.3-0.6 deg held, 0.9-1.0 deg restarted)
GAP_TURN_RAD = 0.3

#: the variance of a heading not known at all (uniform on the circle): the 9D heading channel's prior
#: without a given initial attitude, and after a gap in the gyro
HEADING_VAR0 = math.pi * math.pi / 3.0

#: rest detection's noise floors (``gyro_floor``, ``accel_floor``), in units of the low-passed squared
#: deviation's designed mean at rest (white noise of the densities): the quietest the sensor's white noise
#: (``gyro_noise``, ``accel_noise``: from successive samples) has been, followed down at once, risen by at most
#: a factor 2 per ``REST_FLOOR_DOUBLING_S`` seconds while the deviation is below ``REST_FLOOR_K * REST_FLOOR_CAP``
#: (could be rest), bounded to ``[1 / REST_FLOOR_CAP, REST_FLOOR_CAP]`` (16: a sensor 4 times noisier than its
#: density); rest is a deviation within ``REST_FLOOR_K`` times the floor or the designed threshold, whichever is
#: larger; a deviation at rest (``gyro_rest_dev``, ``accel_rest_dev``) above ``REST_FLOOR_WARN`` (twice the density
#: in std) is warned of, once
REST_FLOOR_K, REST_FLOOR_CAP, REST_FLOOR_DOUBLING_S, REST_FLOOR_WARN = 4.0, 16.0, 1.0, 4.0

#: the filter state, in the order of :meth:`AttitudeFilter.state` and the C struct
STATE_FIELDS = (
    "qw", "qx", "qy", "qz",              # attitude, body -> ENU
    "bx", "by", "bz",                    # gyro bias, body, rad/s
    "vx", "vy",                          # velocity channel: horizontal velocity (ENU, m/s)
    "ex", "ey", "ez",                    # tilt channel: its attitude minus the filter's (body frame, rad)
    "ra0", "ra1", "ra2", "ra3", "ra4", "ra5",  # tilt channel: the attitude's first two rows through the velocity
    "rv0", "rv1", "rv2", "rv3", "rv4", "rv5",  # channel's step: its tilt (s) and velocity over g (s²) per unit bias
    "px", "py", "pz",                    # zero-rotation channel: rotation since rest began (body, rad)
    "gx", "gy", "gz",                    # rest detection: low-passed rate (body, rad/s)
    "fx", "fy", "fz",                    # rest detection: low-passed specific force (body, m/s²)
    "gyro_dev", "accel_dev",             # rest detection: low-passed squared deviations from those
    "gyro_noise", "accel_noise",         # rest detection: white noise from successive samples, low-passed
    "gyro_floor", "accel_floor",         # rest detection: noise floors (the noise's quietest)
    "lax", "lay", "laz",                 # rest detection: last good specific force (m/s²)
    "gyro_rest_dev", "accel_rest_dev",   # those deviations low-passed over the rests (0: no rest yet)
    "rest_time",                         # time still (s)
    "r00", "r01", "r11",                 # zero-rotation channel: covariance of its Kalman recursion
    "t00", "t01", "t11",                 # tilt channel: covariance of its Kalman recursion
    "h00", "h01", "h11",                 # heading channel: covariance of its Kalman recursion
    "norm_lp", "dip_lp",                 # field norm and dip (rad), low-passed
    "norm_ref", "dip_ref", "ref_n",      # reference field and how many readings it averages
    "norm_new", "dip_new", "new_n",      # candidate new field (while disturbed), readings averaged
    "new_time", "new_turn",              # time the candidate held (s) and the rotation meanwhile (rad)
    "dist_time",                         # time the field has been disturbed without a break (s)
    "disturbed", "level",                # field disturbed (0/1); acceleration-disturbance level
    "accel_time",                        # time the levels have run (s; negative: the motion design for that long)
    "tilt_n",                            # start-up: specific forces the initial tilt averages (with a given
                                         # initial attitude: minus those seen until shocks are clipped)
    "tilt_f",                            # start-up: norm of their mean (m/s², upright after each correction;
                                         # with an initial attitude: the low-passed norm when its count ends)
    "lgx", "lgy", "lgz",                 # last good rate (rad/s)
    "started", "missing_gyr", "missing_acc", "missing_mag",
    "gap_n",                             # rates missing in a row since the start (a gap in the gyro); with
                                         # started 0 and gap_n > 0 the start-up keeps the heading (a restart)
)
_INDEX = {name: i for i, name in enumerate(STATE_FIELDS)}
#: the largest magnitude :meth:`AttitudeFilter.restore` accepts in a state field that has no
#: tighter bound (velocities, angles, covariances, times, counters): its square divided by the
#: smallest threshold a parameter can set (1e-30) stays finite, so no step from it overflows
STATE_LIMIT = 1e100
#: the state's field norms (low-passed, reference, candidate): means of the norms of field
#: readings, each one whose square is finite (the step's test of a field reading)
_NORMS = ("norm_lp", "norm_ref", "norm_new")
_MAX_NORM = math.sqrt(sys.float_info.max)
#: the state's counters: whole numbers from 0 (readings averaged, samples missing); ``tilt_n`` also from
#: ``-1 / tilt_alpha`` (with a given initial attitude, counted down until shocks are clipped)
_COUNTERS = ("ref_n", "new_n", "tilt_n", "missing_gyr", "missing_acc", "missing_mag", "gap_n")


@dataclass(frozen=True)
class AttitudeParams:
    """Parameters of :class:`AttitudeFilter`: noise figures (SI densities) and physical thresholds.

    Densities are rate independent (per-sample stds follow as ``density * sqrt(rate_hz)``).
    The defaults are those of a consumer MEMS IMU; six were tuned on BROAD's ten development
    trials, one value for all (``tilt_drift_density`` with ``velocity_noise_density``: the tilt
    bandwidth; ``heading_noise_density``, ``mag_tolerance_rad``, ``mag_new_field_s``,
    ``accel_shock_sigma``); ``benchmarks/bench_broad.py --loo`` checks them by leave-one-out
    (1.78-1.89 deg mean total, against 1.776 in-sample).  Another,
    ``heading_bias_std0``, was chosen on those trials started without a rest (``--proxies``).

    Attributes
    ----------
    gyro_noise_density : float
        Gyro white noise, rad/s/sqrt(Hz) (default 2e-4, 0.011 deg/s/sqrt(Hz)).
    gyro_bias_density : float
        Gyro bias random walk, rad/s/sqrt(s) (default 1e-5).
    accel_noise_density : float
        Accelerometer white noise, m/s²/sqrt(Hz) (default 3e-3).
    tilt_drift_density : float
        How fast the gyro-propagated tilt drifts in motion, rad/s/sqrt(Hz): the gyro's white
        noise and what motion adds to it (scale factor, misalignment, vibration); the velocity
        channel's "bias" random walk is ``g`` times it (default 8e-4; tuned on BROAD with
        ``velocity_noise_density``).
    velocity_noise_density : float
        How far the sensor's velocity strays from zero, m/s/sqrt(Hz): the noise of the velocity
        channel's zero-velocity reading.  With ``tilt_drift_density`` it sets the tilt bandwidth
        ``sqrt(g sigma_tilt / sigma_v)`` (default 0.032: 0.5 rad/s; tuned on BROAD).
    tilt_noise_density : float
        Noise of the tilt the velocity channel yields, rad/sqrt(Hz), as the tilt channel that
        learns the gyro bias during motion reads it (default 0.05; the larger, the slower that
        channel learns the bias).
    heading_noise_density : float
        Magnetometer heading noise including indoor field distortion, rad/sqrt(Hz) (default
        0.008; tuned on BROAD).
    declination_rad : float
        Magnetic declination, positive east.
    gyro_bias_std0 : float
        Prior std of the gyro bias (rad/s), default 0.0175 (1 deg/s): the zero-rotation and tilt
        channels' Kalman recursions start from it; 0 starts every channel at its table's DARE
        covariance (the designed gains from the first step).
    heading_bias_std0 : float
        Prior std of the gyro bias as the heading channel's recursion starts from it (rad/s,
        default 2.5e-4, 0.014 deg/s).  Smaller than ``gyro_bias_std0`` because the field's heading errs with the
        orientation, by degrees over seconds (soft iron, misalignment, local distortion, a tilt
        still settling), which a 1 deg/s prior reads as deg/s of bias within a second; the rest
        and tilt channels, whose readings do not depend on the orientation, learn a large bias
        fast.  Chosen on the ten development trials started from 1 s before their motion, with no
        rest (``bench_broad.py --proxies "no rest"``), as the value of 6.25e-5 .. 5e-4 (factors of 2)
        best with a gyro bias of (1, -1.5, 0.5) deg/s added, which the field must teach about the
        vertical (mean total 5.30 / 4.55 / 4.43 / 4.90 deg for 6.25e-5 / 1.25e-4 / 2.5e-4 / 5e-4);
        without the bias smaller is better (3.14 / 3.14 / 3.35 / 3.84), as the field where those trials
        move is 2-4 deg off the north of the field at their rest, which their reference keeps: a smaller
        prior follows it less.  The trials as recorded start at rest, whose bias variance the heading
        channel takes over, and do not depend on it.
    rest_time_s, rest_filter_s, rest_sigma : float
        Rest detection: still for ``rest_time_s`` (default 1.5 s) within ``rest_sigma``
        (default 3) noise stds of the ``rest_filter_s`` (default 0.5 s) low-pass.
    mag_tolerance_rad : float
        Heading error (rad) tolerated from a field change the norm and dip checks cannot see
        (default 0.14, 8 deg; tuned on BROAD).
    mag_filter_s, mag_reference_s : float
        Low-pass of the field's norm and dip (default 0.2 s) and of the reference field
        (default 20 s).
    mag_new_field_s, mag_new_field_rotation_rad : float
        A new field is accepted after holding for ``mag_new_field_s`` (default 40 s; tuned on BROAD) while the
        sensor turned by ``mag_new_field_rotation_rad`` (default pi/2).
    mag_first_field_s, mag_provisional_s : float
        A reference field that has held for less than ``mag_provisional_s`` (default 10 s) since
        the start, a restart or its own acceptance is provisional: a new field replaces it after
        holding as long as the reference had, and at least ``mag_first_field_s`` (default 2 s),
        while the sensor turned by ``mag_new_field_rotation_rad``; the heading is then reopened.
        A device started in a disturbed field (beside a motor) takes the clean one seconds after
        it leaves, not ``mag_new_field_s``; a disturbance from ``mag_provisional_s`` after the
        start on is rejected as before, and an earlier one only if it is shorter than the
        reference's age.  BROAD's development trials as recorded are the same to 0.001 deg for
        either from 1 to 8 s and 5 to 20 s; ``mag_first_field_s`` was chosen on those trials
        started in the middle of their motion (``--proxies``: 30 s in, mean total 5.22 deg before,
        3.46 / 3.61 / 3.79 / 4.75 with 1 / 2 / 4 / 8 s; 2 s keeps a floor of seconds), and
        ``mag_provisional_s`` on synthetic tracks (a disturbance from 8 s on is rejected).
    mag_follow_factor : float
        While the field has left a provisional reference for longer than the reference had held, the
        heading follows the field with its reading variance widened this many times, learning no gyro
        bias from it (default 4: the heading's bandwidth about halved, as VQF halves its gain for a
        field disturbed beyond its rejection time; chosen on BROAD's development trials started in the
        middle of their motion, ``--proxies``: 4 / 8 / 16 give 6.50 / 6.55 / 6.78 deg mean total started
        10 s in, 3.43 / 3.45 / 3.50 started 30 s in, against 7.83 / 3.61 without; the trials as recorded
        start at rest, whose reference is no longer provisional, and do not depend on it).
    accel_shock_sigma : float
        A specific force whose deviation from the rest detector's low-pass is more than this many times
        the recent spread (the root of the low-passed squared deviation, or of the noise floor where that is
        larger) is a shock (a tap, a knock, an impact: far more than the body's own acceleration), and its
        deviation is clipped to that many times the spread before any channel or detector sees it (Huber's
        clipping).  Default 4: white noise on three axes goes beyond it about once in 5e9 samples; tuned on
        BROAD's ten development trials among 4, 6, 8 and 12 (mean total 9D 1.776 / 1.779 / 1.780 / 1.782 deg,
        1.784 without; the tapping trial 1.03 deg, 1.11 without).  A sustained change raises the spread, as the
        clipped deviation enters it, by up to a factor ``1 + alpha (sigma² - 1)`` per step (``alpha`` the rest
        low-pass's coefficient; 16 per tenth of a second at 100 Hz), so a motion's onset is followed; a shock
        of 200 m/s² at rest moves the attitude by 0.01 deg (2.7 unclipped).  From the end of the tilt's
        start-up on (``1 / omega``: 2 s by default); with a given ``initial`` attitude, which runs none, from
        as many specific forces after the start.  At least 1; 1e15 turns the clipping off.
    max_speed_mps : float
        Speed (m/s) of the velocity channel beyond which the specific force is taken as a
        sustained acceleration and the tilt corrections are weighted down (default 4); also the
        largest velocity change a start in motion leaves in the start-up's tilt, which the tilt
        channel takes as reading noise while the velocity channel settles.
    max_reach_m : float
        How far a hand-held device moves in one stroke (m, default 1: an arm's reach; chosen, not
        tuned).  A speed beyond ``max_speed_mps`` engages the acceleration-disturbance designs only
        once it has lasted ``max_reach_m / max_speed_mps`` (0.25 s): a hand moving that fast for
        longer would leave its reach, so it is a sustained acceleration; a shorter excursion is a
        fast stroke of a bounded motion, whose velocity averages out (weighting its fast parts down
        would turn the zero-mean motion into a tilt error).
    max_accel_time_s : float
        Longest a sustained acceleration is taken to last (s, default 30; chosen, not tuned: no
        dev trial reaches ``max_speed_mps``).  A speed beyond ``max_speed_mps`` for longer is a
        tilt error (a gyro bias, a wrong initial attitude), not an acceleration: the velocity
        channel restarts from zero velocity and runs its motion design for as long again.
    gyro_range_rps, accel_range_mps2 : float
        Readings above these magnitudes are impossible and treated as missing (defaults
        100 rad/s and 1000 m/s²).
    rest_detection, mag_rejection, accel_rejection, motion_bias, inertial_tilt : bool
        The mechanisms, each on by default (off for ablation studies): the rest designs and the
        zero-rotation channel; the magnetic disturbance check (off: every field corrects the
        heading); the acceleration-disturbance designs; the tilt channel (gyro bias during
        motion); the velocity channel's integration of the specific force (off: each step's
        velocity is that step's specific force alone, the classic complementary filter on the
        instantaneous accelerometer direction, with the same gains).
    """

    gyro_noise_density: float = 2e-4
    gyro_bias_density: float = 1e-5
    accel_noise_density: float = 3e-3
    tilt_drift_density: float = 8e-4
    velocity_noise_density: float = 0.032
    tilt_noise_density: float = 0.05
    heading_noise_density: float = 0.008
    declination_rad: float = 0.0
    gyro_bias_std0: float = 0.0175
    heading_bias_std0: float = 2.5e-4
    rest_time_s: float = 1.5
    rest_filter_s: float = 0.5
    rest_sigma: float = 3.0
    mag_tolerance_rad: float = 0.14
    mag_filter_s: float = 0.2
    mag_reference_s: float = 20.0
    mag_new_field_s: float = 40.0
    mag_new_field_rotation_rad: float = math.pi / 2
    mag_first_field_s: float = 2.0
    mag_provisional_s: float = 10.0
    mag_follow_factor: float = 4.0
    accel_shock_sigma: float = 4.0
    max_speed_mps: float = 4.0
    max_accel_time_s: float = 30.0
    max_reach_m: float = 1.0
    gyro_range_rps: float = 100.0
    accel_range_mps2: float = 1000.0
    rest_detection: bool = True
    mag_rejection: bool = True
    accel_rejection: bool = True
    motion_bias: bool = True
    inertial_tilt: bool = True

    def checked(self) -> AttitudeParams:
        """Check every parameter and return them converted: numbers as floats, switches as bools.

        Ranges: ``declination_rad`` within [-pi, pi]; ``gyro_bias_std0``, ``heading_bias_std0``
        and ``mag_new_field_rotation_rad`` from 0 to 1e15; every other number in [1e-15, 1e15], and
        ``mag_tolerance_rad`` below pi/2 and ``accel_shock_sigma`` at least 1 as well; the five
        switches True or False (a Python or numpy bool, not a number).

        Returns
        -------
        AttitudeParams
            A new instance with the converted values (``self`` is frozen and left as it is).

        Raises
        ------
        AttitudeInputError
            The first field, in declaration order, that is not a number (a bool or text is not one; a
            switch: not a bool), is
            not finite or is out of its range, then an ``accel_shock_sigma`` below 1, then a
            ``mag_tolerance_rad`` not below pi/2; the message names the field.

        Examples
        --------
        >>> from cfdesign.nav import AttitudeParams
        >>> AttitudeParams(rest_time_s=2).checked().rest_time_s
        2.0
        >>> AttitudeParams(mag_tolerance_rad=2.0).checked()
        Traceback (most recent call last):
        ...
        cfdesign.errors.AttitudeInputError: mag_tolerance_rad must be below pi/2, got 2.0
        """
        from .attitude_inputs import number

        values = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(f.default, bool):
                if not isinstance(value, (bool, np.bool_)):
                    raise AttitudeInputError(f"{f.name} must be True or False, got {value!r}")
                values[f.name] = bool(value)
                continue
            value = number(f.name, value)  # not a bool (True was 1 rad of declination), not text
            if not math.isfinite(value):
                raise AttitudeInputError(f"{f.name} must be finite, got {value!r}")
            if f.name == "declination_rad":
                if abs(value) > math.pi:
                    raise AttitudeInputError(f"declination_rad must be within [-pi, pi], got {value!r}")
            elif f.name in ("gyro_bias_std0", "heading_bias_std0", "mag_new_field_rotation_rad"):
                if not 0 <= value <= 1e15:  # 1e308 overflowed when squared (an OverflowError)
                    raise AttitudeInputError(f"{f.name} must be from 0 to 1e15, got {value!r}")
            elif not 1e-15 <= value <= 1e15:
                raise AttitudeInputError(f"{f.name} must be a positive number (1e-15 .. 1e15), got {value!r}")
            values[f.name] = value
        if values["accel_shock_sigma"] < 1.0:  # below: every sample is a shock, the tilt stops following
            raise AttitudeInputError(f"accel_shock_sigma must be at least 1 (1e15: no clipping), "
                                     f"got {values['accel_shock_sigma']!r}")
        if values["mag_tolerance_rad"] >= math.pi / 2:
            raise AttitudeInputError(f"mag_tolerance_rad must be below pi/2, got {values['mag_tolerance_rad']!r}")
        return replace(self, **values)


@dataclass(frozen=True)
class AttitudeDesign:
    """The designed tables of a filter at one rate, and the numbers its step runs.

    Attributes
    ----------
    rate_hz : float
        Sample rate (Hz) the gains were designed for.
    params : AttitudeParams
        Noise figures the gains were designed from.
    tables : dict
        ``{name: GainTable}``: ``velocity`` (motion), ``velocity_rest``, ``velocity_level1`` ..
        (acceleration disturbance), ``tilt``, ``heading``, ``rest`` (zero rotation); every one a
        ``cf2`` channel at the sample rate (``docs/derivations.md``).
    velocity : tuple of (k1, k2)
        Velocity-channel gains: ``[0]`` motion, ``[1]`` rest, ``[2:]`` the disturbance levels.
    channels : dict
        ``{'tilt' | 'heading' | 'rest': (q00, q01, q11, r, kalman, k1, k2)}``: the table's process
        noise per step and reading variance, which the filter's Kalman recursion of the table
        runs (``kalman`` 1), or its fixed gains (``kalman`` 0, a table whose gains are not its
        own Kalman gains); the recursion's steady state is the table's DARE gain.
    priors : dict
        ``{'tilt' | 'heading' | 'rest': (p00, p01, p11)}``: the covariance each recursion starts
        from (the table's DARE covariance when ``gyro_bias_std0`` is 0).
    constants : dict
        The derived thresholds and filter coefficients (``docs/derivations.md``).
    """

    rate_hz: float
    params: AttitudeParams
    tables: dict
    velocity: tuple
    channels: dict
    priors: dict
    constants: dict


def design_attitude(rate_hz, params=None, tables=None) -> AttitudeDesign:
    """Design the tables of :class:`AttitudeFilter` at ``rate_hz`` (cached; no sympy).

    Every channel is a ``cf2`` table of :func:`~cfdesign.nav.design_channel`, from the noise
    densities of ``params`` turned into per-sample stds at ``rate_hz``: the velocity channel's
    motion, rest and acceleration-disturbance designs, the tilt, heading and zero-rotation
    channels (module docstring), with the derived thresholds.  Without ``tables`` the design is
    cached: equal rate and parameters return the same :class:`~cfdesign.nav.attitude_filter.AttitudeDesign`.

    Parameters
    ----------
    rate_hz : float
        Sample rate (Hz), in (0, 1e6].
    params : AttitudeParams, optional
        Noise figures and thresholds (checked with :meth:`AttitudeParams.checked`); default
        ``AttitudeParams()``.
    tables : dict or pair, optional
        A user's own designs of the ``tilt`` and/or ``heading`` channels in place of the
        designed ones: a dict with those keys or the pair ``(tilt, heading)``, each a
        :class:`~cfdesign.gains.GainTable` or :class:`~cfdesign.spec.FilterSpec` of the ``cf2``
        order-2 discrete channel at ``rate_hz`` (e.g. :func:`cfdesign.nav.design_channel`).

    Returns
    -------
    AttitudeDesign
        The tables, gains, Kalman-recursion numbers, priors and constants the filter's step
        runs.

    Raises
    ------
    AttitudeInputError
        A bad rate (checked first) or parameter.
    TableMismatchError
        ``tables`` is neither a dict nor a pair, has a key other than ``tilt`` and
        ``heading``, or holds a table that is not the channel's model at ``1 / rate_hz``.

    Examples
    --------
    >>> from cfdesign.nav import design_attitude, design_channel
    >>> design = design_attitude(100.0)
    >>> len(design.velocity)            # motion, rest and five disturbance levels
    7
    >>> design is design_attitude(100.0)
    True
    >>> tilt = design_channel(100.0, 0.002, 1e-5, 0.05)
    >>> design_attitude(100.0, tables={"tilt": tilt}).tables["tilt"] is tilt
    True
    """
    rate_hz = _rate(rate_hz)
    params = (AttitudeParams() if params is None else params).checked()
    design = _design(rate_hz, params)
    if tables is None:
        return design
    return _with_tables(design, tables)


def _with_tables(design: AttitudeDesign, tables) -> AttitudeDesign:
    """``design`` with the user's tilt and/or heading tables (checked to fit the sample time)."""
    from ..errors import TableMismatchError
    from .attitude_channel import STRUCTURE, channel_gains
    from .stored_design import as_table

    if isinstance(tables, dict):
        unknown = sorted(set(tables) - {"tilt", "heading"})
        if unknown:
            raise TableMismatchError(f"tables: unknown channel(s) {', '.join(map(str, unknown))}; "
                                     "give 'tilt' and/or 'heading'")
        given = dict(tables)
    else:
        try:
            tilt, heading = tables
        except (TypeError, ValueError, OverflowError):
            raise TableMismatchError("tables: a pair (tilt, heading) or a dict of GainTables or FilterSpecs is "
                                     "needed") from None
        given = {"tilt": tilt, "heading": heading}
    T = 1.0 / design.rate_hz
    timing = f"the sample interval at rate_hz {design.rate_hz:g} Hz"
    new, channels, priors = dict(design.tables), dict(design.channels), dict(design.priors)
    for name, value in given.items():
        table = as_table(value, STRUCTURE, f"tables[{name!r}]")
        gains = channel_gains(table, f"tables[{name!r}]", T, timing)
        new[name] = table
        channels[name], priors[name] = _channel(table, gains, _prior(name, table, design.params))
    return replace(design, tables=new, channels=channels, priors=priors)


def _prior(name, table, p) -> tuple:
    """Where a channel's Kalman recursion starts: its angle known to its reading (heading: not at
    all, variance pi²/3), the bias to ``gyro_bias_std0`` (heading: ``heading_bias_std0``); the
    table's DARE covariance when ``gyro_bias_std0`` is 0."""
    P = np.asarray(table.P[0], dtype=float)
    if p.gyro_bias_std0 == 0:
        return float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
    r = float(np.asarray(table.R, dtype=float).reshape(-1)[0])
    angle = {"heading": HEADING_VAR0, "rest": r}.get(name, r)
    return angle, 0.0, (p.heading_bias_std0 if name == "heading" else p.gyro_bias_std0) ** 2


def _channel(table, gains, prior) -> tuple:
    """``(q00, q01, q11, r, kalman, k1, k2)`` of a channel table (see :class:`AttitudeDesign`), and its prior."""
    from .attitude_channel import _is_kalman

    Q = np.asarray(table.Q, dtype=float)
    r = float(np.asarray(table.R, dtype=float).reshape(-1)[0])
    kalman = 1.0 if _is_kalman(table, gains) else 0.0
    return (float(Q[0, 0]), float(Q[0, 1]), float(Q[1, 1]), r, kalman, gains[0], gains[1]), tuple(prior)


@functools.lru_cache(maxsize=16)
def _design(rate_hz: float, p: AttitudeParams) -> AttitudeDesign:
    T = 1.0 / rate_hz
    root = math.sqrt(rate_hz)
    gyro_std, accel_std = p.gyro_noise_density * root, p.accel_noise_density * root
    v_std = p.velocity_noise_density * root
    drift = GRAVITY * p.tilt_drift_density
    tables = {"velocity": design_channel(rate_hz, accel_std, drift, v_std),
              "velocity_rest": design_channel(rate_hz, accel_std, GRAVITY * p.gyro_noise_density, accel_std * T)}
    for j, factor in enumerate(DISTURBANCE_FACTORS, start=1):
        tables[f"velocity_level{j}"] = design_channel(rate_hz, accel_std, drift, v_std * factor)
    tables["tilt"] = design_channel(rate_hz, gyro_std, p.gyro_bias_density, p.tilt_noise_density * root)
    tables["heading"] = design_channel(rate_hz, gyro_std, p.gyro_bias_density, p.heading_noise_density * root)
    tables["rest"] = design_channel(rate_hz, gyro_std, p.gyro_bias_density, gyro_std * T)
    gains = {name: (float(t.gains["k1"]), float(t.gains["k2"])) for name, t in tables.items()}
    velocity = (gains["velocity"], gains["velocity_rest"],
                *(gains[f"velocity_level{j}"] for j in range(1, len(DISTURBANCE_FACTORS) + 1)))
    channels, priors = {}, {}
    for name in ("tilt", "heading", "rest"):
        channels[name], priors[name] = _channel(tables[name], gains[name], _prior(name, tables[name], p))
    rest_std = p.rest_sigma * math.sqrt(3.0)
    rest_alpha = -math.expm1(-T / p.rest_filter_s)
    constants = {
        "T": T,
        "rest_alpha": rest_alpha,
        "rest_gyro_th2": (rest_std * gyro_std) ** 2,
        "rest_accel_th2": (rest_std * accel_std) ** 2,
        "rest_bias_th2": max(3.0 * p.gyro_bias_std0, rest_std * gyro_std) ** 2,
        # the mean of the detector's squared deviation (three axes of white noise from its first-order
        # low-pass, after the update) at rest: the unit of the noise floors
        "rest_gyro_var": 6.0 * gyro_std ** 2 * (1.0 - rest_alpha) ** 2 / (2.0 - rest_alpha),
        "rest_accel_var": 6.0 * accel_std ** 2 * (1.0 - rest_alpha) ** 2 / (2.0 - rest_alpha),
        # the noise floors' largest rise per step (a factor 2 per REST_FLOOR_DOUBLING_S)
        "rest_floor_up": 2.0 ** (T / REST_FLOOR_DOUBLING_S),
        # white noise from the difference of successive samples (twice the variance per axis) in the units of
        # those means: a motion smooth at the sample rate hardly adds to it, unlike to the deviation
        "rest_diff_scale": (1.0 - rest_alpha) ** 2 / (2.0 - rest_alpha),
        # a shock: the specific force's deviation from the rest low-pass (before its update) beyond
        # accel_shock_sigma times the spread the low-passed squared deviation (after the update, so (1 - alpha)
        # times that deviation, 1 - alpha = exp(-T / rest_filter_s)) has measured; at most 1e300 (a low-pass with no
        # memory, alpha = 1, measures no spread: nothing is clipped)
        "shock_lim2": math.exp(min(2.0 * (math.log(p.accel_shock_sigma) + T / p.rest_filter_s), 690.0)),
        "mag_alpha": -math.expm1(-T / p.mag_filter_s),
        "mag_ref_alpha": -math.expm1(-T / p.mag_reference_s),
        "north": math.atan2(math.cos(p.declination_rad), math.sin(p.declination_rad)),
        "speed2": p.max_speed_mps ** 2,
        "accel_hold_s": p.max_reach_m / p.max_speed_mps,
        "tilt_alpha": T * math.sqrt(GRAVITY * p.tilt_drift_density / p.velocity_noise_density),
        # variance of the rest detector's low-passed rate about the bias, per axis (white noise through its
        # first-order low-pass): what a rest's first reading of the bias errs by from noise alone
        "rest_lp_var": gyro_std ** 2 * rest_alpha / (2.0 - rest_alpha),
        "gyro_range2": p.gyro_range_rps ** 2,
        "accel_range2": p.accel_range_mps2 ** 2,
    }
    return AttitudeDesign(rate_hz, p, tables, velocity, channels, priors, constants)


def _rate(rate_hz) -> float:
    """``rate_hz`` checked before anything is designed or allocated."""
    from .attitude_inputs import rate

    return rate(rate_hz)


@dataclass
class AttitudeRun:
    """What :meth:`AttitudeFilter.run` returns with ``details=True`` (one row per sample).

    Attributes
    ----------
    quaternion : ndarray (N, 4)
        ``[w, x, y, z]`` (w >= 0), body -> ENU.
    bias : ndarray (N, 3)
        Gyro bias estimate, body frame, rad/s.
    rest : ndarray (N,) of bool
        Rest detected.
    mag_disturbed : ndarray (N,) of bool
        Magnetic field disturbed (heading on the gyro); always False in 6D.
    accel_level : ndarray (N,) of int
        Acceleration-disturbance level of the velocity channel (0: none; ``j``: velocity noise
        times ``DISTURBANCE_FACTORS[j - 1]``).
    tilt_weight : ndarray (N,)
        The tilt correction's gain relative to the motion design's (0 before the first
        specific force; the rest design's is larger than 1).
    speed : ndarray (N,)
        The velocity channel's horizontal speed (m/s): past ``max_speed_mps`` the tilt
        corrections are weighted down.
    missing : dict
        ``{'gyr': n, 'acc': n, 'mag': n}``: samples treated as missing.
    """

    quaternion: np.ndarray
    bias: np.ndarray
    rest: np.ndarray
    mag_disturbed: np.ndarray
    accel_level: np.ndarray
    tilt_weight: np.ndarray
    speed: np.ndarray
    missing: dict


class AttitudeFilter:
    """Streaming attitude filter (gyro + accelerometer, + magnetometer in 9D): module docstring.

    Parameters
    ----------
    rate_hz : float
        Sample rate (Hz), in (0, 1e6]; one sample of every sensor per step.
    params : AttitudeParams, optional
        Noise figures and thresholds; keyword arguments override single fields
        (``AttitudeFilter(285.7, declination_rad=0.05)``).
    magnetometer : bool
        True (9D): the heading follows the magnetometer; False (6D): the heading is the gyro's
        integral from the initial heading, held at rest.
    initial : array_like (4,), optional
        Initial quaternion ``[w, x, y, z]`` (body -> ENU), its heading taken as known as a running
        filter knows it (the heading table's DARE variance); default: the tilt of the first
        usable specific force, heading zero (in 9D the first fields then set the heading: the
        heading channel starts from a uniform prior).
    tables : dict or pair, optional
        A user's own ``tilt`` and/or ``heading`` channel designs (:func:`design_attitude`).
    **overrides
        Fields of :class:`AttitudeParams` replacing those of ``params`` (e.g.
        ``declination_rad=0.05``, ``mag_rejection=False``).

    Raises
    ------
    AttitudeInputError
        For a bad rate (checked before anything is designed), a ``params`` that is not an
        :class:`AttitudeParams`, an override that is not one of its fields, a bad parameter
        value or a bad initial attitude.
    TableMismatchError
        ``tables`` that do not fit the channels at ``rate_hz`` (:func:`design_attitude`).

    Notes
    -----
    ``step`` and ``run`` are the same arithmetic: a run equals its samples stepped one by one
    (tested to 1e-12; they are in fact identical).

    Examples
    --------
    A still sensor whose gyro reads 0.01 rad/s about z: after ``rest_time_s`` (1.5 s) the rest
    is detected and the zero-rotation channel learns the bias.

    >>> import numpy as np
    >>> from cfdesign.nav import AttitudeFilter
    >>> f = AttitudeFilter(100.0, magnetometer=False)
    >>> out = f.run(np.tile([0.0, 0.0, 0.01], (300, 1)), np.tile([0.0, 0.0, 9.81], (300, 1)), details=True)
    >>> bool(out.rest[-1]), round(float(out.bias[-1, 2]), 3)
    (True, 0.01)
    """

    def __init__(self, rate_hz, params=None, *, magnetometer=True, initial=None, tables=None, **overrides):
        rate_hz = _rate(rate_hz)
        if params is not None and not isinstance(params, AttitudeParams):
            raise AttitudeInputError(f"params must be an AttitudeParams, got {type(params).__name__}")
        params = params or AttitudeParams()
        unknown = sorted(set(overrides) - {f.name for f in fields(AttitudeParams)})
        if unknown:
            raise AttitudeInputError(f"unknown parameter(s) {', '.join(unknown)}; see AttitudeParams")
        self.design = design_attitude(rate_hz, replace(params, **overrides), tables)
        self.rate_hz = rate_hz
        self.params = self.design.params
        self.magnetometer = bool(magnetometer)
        self._initial = None if initial is None else _initial_quaternion(initial)
        self._coef = _coefficients(self.design)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self):
        """Back to the state before the first sample."""
        s = [0.0] * len(STATE_FIELDS)
        s[_INDEX["qw"]] = 1.0
        if self._initial is not None:
            s[0:4] = self._initial
            s[_INDEX["started"]] = 1.0
        for name in ("rest", "tilt", "heading"):
            i = _INDEX[name[0] + "00"]
            s[i:i + 3] = self.design.priors[name]
        c = self.design.constants
        s[_INDEX["gyro_floor"]], s[_INDEX["accel_floor"]] = c["rest_gyro_var"], c["rest_accel_var"]
        s[_INDEX["gyro_noise"]], s[_INDEX["accel_noise"]] = c["rest_gyro_var"], c["rest_accel_var"]
        if self._initial is not None:
            # a given heading is known as well as a running filter knows it (the heading table's DARE variance)
            s[_INDEX["h00"]] = float(self.design.tables["heading"].P[0][0][0])
        self._s = s
        self._units = _GyroUnits(self.rate_hz, c["gyro_range2"], c["accel_range2"])
        #: the rest deviations beyond which the sensors are warned of as noisier than their densities (None: warned)
        self._noisy = (REST_FLOOR_WARN * c["rest_gyro_var"], REST_FLOOR_WARN * c["rest_accel_var"])

    def state(self) -> dict:
        """A copy of the filter's state, to save it or to continue it later with :meth:`restore`.

        Returns
        -------
        dict
            ``{name: float}`` in :data:`~cfdesign.nav.attitude_filter.STATE_FIELDS` order: the
            attitude ``qw .. qz`` (body -> ENU), the gyro bias ``bx .. bz`` (rad/s, body frame), the
            channels' states and covariances, the detectors' low-passes and counters.  Plain floats: it can be
            written as JSON, and it maps field by field onto the generated C struct
            (:mod:`cfdesign.codegen.attitude`).  The design (rate, parameters, tables) is not
            part of it.

        Examples
        --------
        >>> from cfdesign.nav import AttitudeFilter
        >>> state = AttitudeFilter(100.0).state()
        >>> len(state), state["qw"], state["started"]
        (78, 1.0, 0.0)
        """
        return dict(zip(STATE_FIELDS, self._s, strict=True))

    def restore(self, state: dict):
        """Continue from a state saved with :meth:`state`.

        The state carries no design: restore it into a filter with the same rate, parameters,
        mode and tables to continue the run it was taken from.  The values are taken as they are
        (the attitude is renormalised by the next step).

        Parameters
        ----------
        state : dict
            ``{name: number}`` with exactly the names of :data:`~cfdesign.nav.attitude_filter.STATE_FIELDS`.

        Raises
        ------
        AttitudeInputError
            ``state`` is not a dict, lacks a field or has an unknown one, has a value that is not
            a finite number, or is a state no run of this filter reaches: its ``qw, qx, qy, qz``
            not near a unit quaternion (norm outside (0.5, 2)), a low-passed or held rate beyond
            ``gyro_range_rps``, a specific force beyond ``accel_range_mps2``, a covariance that is
            not positive semi-definite, a noise floor outside 1/16 to 16 times the densities' variance (in
            the rest detector's units), a negative time, a field norm that is negative or whose
            square overflows, a dip outside [-pi/2, pi/2], a
            counter that is not a whole number from 0 (``tilt_n`` from about ``-1 / tilt_alpha``: counted down
            with a given initial attitude), a flag or level out of its values, an
            ``accel_time`` beyond ``max_accel_time_s`` or any field beyond
            :data:`~cfdesign.nav.attitude_filter.STATE_LIMIT`; the message names the field and
            the filter's state is left unchanged.

        Examples
        --------
        >>> from cfdesign.nav import AttitudeFilter
        >>> f = AttitudeFilter(100.0, magnetometer=False)
        >>> saved = f.state()
        >>> q = f.step([0.0, 0.0, 0.1], [0.0, 0.0, 9.81])
        >>> f.restore(saved)
        >>> f.step([0.0, 0.0, 0.1], [0.0, 0.0, 9.81]) == q
        True
        """
        if not isinstance(state, dict):
            raise AttitudeInputError(f"state must be a dict from AttitudeFilter.state(), got {type(state).__name__}")
        missing = [n for n in STATE_FIELDS if n not in state]
        unknown = sorted(set(state) - set(STATE_FIELDS))
        if missing or unknown:
            raise AttitudeInputError(f"state: missing {', '.join(missing) or 'none'}, unknown "
                                     f"{', '.join(unknown) or 'none'}")
        values = []
        for name in STATE_FIELDS:
            try:
                value = float(state[name])
            except (TypeError, ValueError, OverflowError):
                raise AttitudeInputError(f"state: {name} must be a number, got {state[name]!r}") from None
            if not math.isfinite(value):
                raise AttitudeInputError(f"state: {name} must be finite, got {state[name]!r}")
            values.append(value)
        problem = self._impossible(dict(zip(STATE_FIELDS, values, strict=True)))
        if problem:
            raise AttitudeInputError(f"state: {problem}")
        self._s = values
        self._units.buffer = None if self._units.buffer is None else []   # no window across two runs

    def _impossible(self, v) -> str | None:
        """What makes the state ``v`` (``{name: float}``, finite) one no run of this filter reaches,
        or None.  Each bound holds for every state the step leaves (bias, low-passed and held rates
        (low-passed and held rates within the gyro's range, low-passed specific force within the
        accelerometer's, field norms those of readings whose square is finite, covariances positive
        semi-definite, counters whole, flags and levels their values) and keeps the next step finite."""
        p, tol = self.params, 1.0 + 1e-9

        def norm(prefix):
            return math.sqrt(sum(v[prefix + c] ** 2 for c in "xyz"))

        big = [name for name in STATE_FIELDS if abs(v[name]) > STATE_LIMIT and name not in _NORMS]
        if big:
            return f"{big[0]} = {v[big[0]]!r} is beyond {STATE_LIMIT:g}"
        if not 0.5 < math.sqrt(sum(v[name] ** 2 for name in ("qw", "qx", "qy", "qz"))) < 2.0:
            return "qw, qx, qy, qz is not a unit quaternion"
        for name in _NORMS:
            if not 0.0 <= v[name] <= _MAX_NORM:
                return f"{name} = {v[name]!r} is not the norm of a field reading (from 0 to {_MAX_NORM:.4g})"
        for prefix, what, limit in (("g", "the low-passed rate", p.gyro_range_rps),
                                    ("lg", "the last good rate", p.gyro_range_rps),
                                    ("la", "the last good specific force", p.accel_range_mps2),
                                    ("f", "the low-passed specific force", p.accel_range_mps2)):
            if norm(prefix) > limit * tol:
                return (f"{prefix}x, {prefix}y, {prefix}z ({what}) has norm {norm(prefix):.6g}, beyond the sensor's "
                        f"range {limit:g}")
        for name, limit in (("gyro_dev", p.gyro_range_rps), ("accel_dev", p.accel_range_mps2),
                            ("gyro_rest_dev", p.gyro_range_rps), ("accel_rest_dev", p.accel_range_mps2),
                            ("gyro_noise", p.gyro_range_rps), ("accel_noise", p.accel_range_mps2)):
            if not 0.0 <= v[name] <= 4.0 * limit * limit * tol:
                return f"{name} = {v[name]!r} must be from 0 to {4.0 * limit * limit:g} (twice the range, squared)"
        problem = self._impossible_floor(v)
        if problem:
            return problem
        for c in "rth":
            p00, p01, p11 = v[c + "00"], v[c + "01"], v[c + "11"]
            # within rounding: the recursion of a covariance at the boundary (a variance of 1e99 restored at rest
            # left 1e95, 1e97, 1e99, whose p01² is p00 p11 one ulp over) stays there
            if not (p00 >= 0.0 and p11 >= 0.0 and p01 * p01 <= p00 * p11 * tol):
                return f"{c}00, {c}01, {c}11 is not a covariance (positive semi-definite)"
        if not 0.0 <= v["tilt_f"] <= p.accel_range_mps2 * tol:
            return (f"tilt_f = {v['tilt_f']!r} is not the norm of a mean specific force (from 0 to "
                    f"{p.accel_range_mps2:g})")
        for name in ("rest_time", "new_time", "new_turn", "dist_time"):
            if v[name] < 0.0:
                return f"{name} = {v[name]!r} must not be negative"
        for name in ("dip_lp", "dip_ref", "dip_new"):
            if abs(v[name]) > math.pi / 2:
                return f"{name} = {v[name]!r} is not a dip angle (within [-pi/2, pi/2])"
        # tilt_n counts down to the first whole number at or below -1 / tilt_alpha (2 more: rounding)
        low = {"tilt_n": -1.0 / self.design.constants["tilt_alpha"] - 2.0}
        for name in _COUNTERS:
            if v[name] < low.get(name, 0.0) or v[name] != math.floor(v[name]):
                return f"{name} = {v[name]!r} must be a whole number from {math.ceil(low.get(name, 0.0)):d}"
        for name, allowed in (("started", (0.0, 1.0, 2.0)), ("disturbed", (0.0, 1.0)),
                              ("level", tuple(float(j) for j in range(len(self.design.velocity) - 1)))):
            if v[name] not in allowed:
                return f"{name} = {v[name]!r} must be one of {', '.join(f'{a:g}' for a in allowed)}"
        if abs(v["accel_time"]) > p.max_accel_time_s:
            return f"accel_time = {v['accel_time']!r} is beyond max_accel_time_s {p.max_accel_time_s:g}"
        return None

    def _impossible_floor(self, v) -> str | None:
        """What makes the noise floors of the state ``v`` ones no run of this filter reaches, or None: a floor
        outside ``[1 / REST_FLOOR_CAP, REST_FLOOR_CAP]`` times its unit (the deviation's designed mean at rest)."""
        c, tol = self.design.constants, 1.0 + 1e-9
        for sensor, unit in (("gyro", c["rest_gyro_var"]), ("accel", c["rest_accel_var"])):
            low, high, name = unit / REST_FLOOR_CAP, unit * REST_FLOOR_CAP, f"{sensor}_floor"
            if not low / tol <= v[name] <= high * tol:
                return f"{name} = {v[name]!r} must be from {low:.6g} to {high:.6g} (the floor's bounds)"
        return None

    # ------------------------------------------------------------------ readings of the state
    @property
    def quaternion(self) -> tuple:
        """Current attitude ``(w, x, y, z)`` (w >= 0), body -> ENU."""
        w, x, y, z = self._s[0:4]
        return (-w, -x, -y, -z) if w < 0 else (w, x, y, z)

    @property
    def bias(self) -> tuple:
        """Gyro bias estimate ``(bx, by, bz)``, body frame, rad/s."""
        return tuple(self._s[4:7])

    @property
    def rest(self) -> bool:
        """Rest detected at the last step."""
        return self._s[_INDEX["rest_time"]] >= self.params.rest_time_s

    @property
    def mag_disturbed(self) -> bool:
        """Magnetic field disturbed at the last step (heading on the gyro)."""
        return bool(self._s[_INDEX["disturbed"]])

    @property
    def missing(self) -> dict:
        """Samples treated as missing so far: ``{'gyr': n, 'acc': n, 'mag': n}``."""
        return {key: int(self._s[_INDEX[f"missing_{key}"]]) for key in ("gyr", "acc", "mag")}

    # ------------------------------------------------------------------ stepping
    def step(self, gyr, acc, mag=None) -> tuple:
        """One sample: body rate ``gyr`` (rad/s), specific force ``acc`` (m/s²), field ``mag`` (body frame).

        Readings that are not finite or impossible (beyond ``gyro_range_rps`` or
        ``accel_range_mps2``, a zero specific force or field) are not errors: they are counted
        as missing (:attr:`missing`); a missing rate holds the last good one, a missing specific
        force or field skips its channel.  Without ``initial``, the first usable specific force
        sets the tilt (heading zero); until then the attitude stays the identity.

        Parameters
        ----------
        gyr : sequence of 3 float
            Body rate, rad/s, body (sensor) frame (an array of shape (3,), (1, 3) or (3, 1)).
        acc : sequence of 3 float
            Specific force, m/s², body frame (points up at rest).
        mag : sequence of 3 float, optional
            Magnetic field, body frame, any consistent unit (Gauss, uT or normalised: the filter
            uses its direction, its dip and relative changes of its norm); ignored in 6D; None
            in 9D is a missing reading.

        Returns
        -------
        tuple of float
            The attitude ``(w, x, y, z)`` (w >= 0) after this sample, body -> ENU.

        Raises
        ------
        AttitudeInputError
            ``gyr``, ``acc`` or (in 9D) ``mag`` is not three real numbers (text, None, complex
            values are refused as the runtime's ``step`` refuses them); the message names the
            argument and the state is unchanged.

        Warns
        -----
        UserWarning
            The specific force the filter starts from (the first usable one) is below 3 or above
            30 (``acc`` in g?).  The filter runs anyway; :meth:`run` checks the median of its
            arrays instead.  Once: the gyro turns gravity more than 2.5 times faster than the
            accelerometer shows it turning (``gyr`` in deg/s?; checked in blocks of about 4096
            samples, ``_GyroUnits``).  Once: at rest the gyro or the accelerometer is more than twice as noisy
            (in std) as its density (``gyro_noise_density``, ``accel_noise_density``).

        Examples
        --------
        The first sample of a sensor rolled by 0.2 rad sets the tilt from its specific force:

        >>> import math
        >>> from cfdesign.nav import AttitudeFilter
        >>> f = AttitudeFilter(100.0, magnetometer=False)
        >>> q = f.step([0.0, 0.0, 0.0], [0.0, 9.81 * math.sin(0.2), 9.81 * math.cos(0.2)])
        >>> [round(v, 6) + 0.0 for v in q]
        [0.995004, 0.099833, 0.0, 0.0]
        """
        gx, gy, gz = _three("gyr", gyr)
        ax, ay, az = _three("acc", acc)
        mx, my, mz = _NAN3 if mag is None or not self.magnetometer else _three("mag", mag)
        if self._s[_INDEX["started"]] < 2.0:
            # the specific force the filter starts from: one far from gravity's 9.81 is in other units (g)
            f = math.sqrt(ax * ax + ay * ay + az * az)
            if 0.0 < f < 3.0 or 30.0 < f <= self.params.accel_range_mps2:
                _warn_accel_unit("the first specific force", f, stacklevel=3)
        s = self._s
        _step(s, self._coef, ((gx, gy, gz, ax, ay, az, mx, my, mz),), self.magnetometer, [])
        if self._noisy and (s[_I_GREST] > self._noisy[0] or s[_I_FREST] > self._noisy[1]):
            self._warn_noise(stacklevel=3)
        units = self._units
        buffer = units.buffer
        if buffer is not None:
            buffer += (gx, gy, gz, ax, ay, az)
            if len(buffer) >= units.full:
                units.feed(_NO_SAMPLES, _NO_SAMPLES, stacklevel=3)
        return self.quaternion

    def run(self, gyr, acc, mag=None, *, details=False):
        """Every sample of (N, 3) arrays, in order (the same arithmetic as :meth:`step`).

        Parameters
        ----------
        gyr, acc : array_like (N, 3)
            Body rate (rad/s) and specific force (m/s²), body frame.
        mag : array_like (N, 3), optional
            Field (body frame); needed in 9D (a filter built with ``magnetometer=True``).
        details : bool
            Return an :class:`AttitudeRun` (bias, rest, disturbance flags per sample).

        Returns
        -------
        ndarray (N, 4) or AttitudeRun
            Quaternions ``[w, x, y, z]`` (w >= 0), body -> ENU.

        Raises
        ------
        AttitudeInputError
            An array that is not (N, 3) or whose length differs from ``gyr``'s (streams at their own rates:
            :func:`~cfdesign.nav.align_imu`), or no ``mag`` in 9D.

        Warns
        -----
        UserWarning
            The arrays look like other units: a median specific force outside 3 to 30 (``acc``
            in g?); a median rate above 20 or a gyro that turns gravity more than 2.5 times faster
            than the accelerometer shows it turning (``gyr`` in deg/s?, once per filter, as
            :meth:`step` checks it: ``_GyroUnits``); once per filter, at rest the gyro or the accelerometer more
            than twice as noisy (in std) as its density (``gyro_noise_density``, ``accel_noise_density``;
            rest is then detected against the noise measured); more than 5 % of the rows without a rate but with
            a specific force or a field (streams merged by time stamp: put them on the gyro's clock with
            :func:`~cfdesign.nav.align_imu`); in 9D, field readings on a sphere away from zero (a hard-iron
            offset: :func:`~cfdesign.nav.hard_iron_offset`), else a field whose angle to gravity wanders or that
            turns against the gyro's turn (the sensors' axes differ).  The filter runs anyway.
        """
        gyr, acc, mag = _arrays(gyr, acc, mag, self.magnetometer, self.rate_hz)
        self._units.check_median(gyr, stacklevel=3)
        self._units.feed(gyr, acc, stacklevel=3)
        n = len(gyr)
        coef, s, nine = self._coef, self._s, self.magnetometer
        out = []
        # one row of nine floats per sample (one list per row: the nested rows of three cost twice the time)
        samples = np.hstack((gyr, acc, mag if nine else np.full((n, 3), np.nan))).tolist()
        if not details:
            _step(s, coef, samples, nine, out)
            self._warn_noise(stacklevel=3)
            return _unit(out)
        bias, flags = [None] * n, [None] * n
        i_rest, i_dist, i_level = _INDEX["rest_time"], _INDEX["disturbed"], _INDEX["level"]
        i_vx, i_vy = _INDEX["vx"], _INDEX["vy"]
        rest_time, k_motion = self.params.rest_time_s, self.design.velocity[0][1]
        weights = [k2 for _, k2 in self.design.velocity]
        started = _INDEX["started"]
        for k, sample in enumerate(samples):
            weight = _step(s, coef, (sample,), nine, out)
            bias[k] = s[4:7]
            flags[k] = (s[i_rest] >= rest_time, s[i_dist], s[i_level],
                        weights[weight] / k_motion if s[started] and weight >= 0 else 0.0, math.hypot(s[i_vx], s[i_vy]))
        self._warn_noise(stacklevel=3)
        flags = np.array(flags, dtype=float).reshape(n, 5)
        return AttitudeRun(_unit(out), np.array(bias, dtype=float).reshape(n, 3), flags[:, 0] > 0, flags[:, 1] > 0,
                           flags[:, 2].astype(int), flags[:, 3], flags[:, 4], self.missing)


    def _warn_noise(self, stacklevel):
        """Warn, once per filter, of a sensor whose deviation at rest (``gyro_rest_dev``, ``accel_rest_dev``) is
        beyond ``REST_FLOOR_WARN`` times the densities' (``stacklevel``: as :func:`warnings.warn` would take it
        here)."""
        import warnings

        if not self._noisy:
            return
        c, p = self.design.constants, self.params
        noisy = [f"{arg}: at rest the {what} is about {math.sqrt(self._s[i] / unit):.2g} times as noisy as the "
                 f"{name} the filter was designed with ({density:g})"
                 for what, arg, i, unit, name, density in (
                     ("gyro", "gyr", _I_GREST, c["rest_gyro_var"], "gyro_noise_density", p.gyro_noise_density),
                     ("accelerometer", "acc", _I_FREST, c["rest_accel_var"], "accel_noise_density",
                      p.accel_noise_density))
                 if unit > 0.0 and self._s[i] > REST_FLOOR_WARN * unit]
        if noisy:
            self._noisy = None
            warnings.warn(f"{'; '.join(noisy)}: rest is detected against the noise measured, the channels' gains "
                          "still take the density; measure the sensor's from a still log (`cfdesign noise`) and set "
                          "it", UserWarning, stacklevel=stacklevel)


_NAN3 = (math.nan, math.nan, math.nan)
_I_GREST, _I_FREST = _INDEX["gyro_rest_dev"], _INDEX["accel_rest_dev"]
_NO_SAMPLES = np.empty((0, 3))


def _three(name, value) -> tuple:
    """``value`` as three Python floats (``cfdesign.runtime.step.real_float``), or
    :class:`~cfdesign.errors.AttitudeInputError` naming ``name``.  A one-row or one-column array (a
    sample sliced from a log, ``gyr[k:k + 1]``) is its three numbers."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and value.size == 3 and 1 in value.shape:
        value = value.ravel()
    try:
        x, y, z = value
    except (TypeError, ValueError):
        x = y = z = None
    else:
        if type(x) is float and type(y) is float and type(z) is float:
            return x, y, z
        x, y, z = real_float(x), real_float(y), real_float(z)
    if x is None or y is None or z is None or isinstance(value, (str, bytes)):
        shown = " ".join(repr(value).split())
        raise AttitudeInputError(f"{name} must be three real numbers, got {shown[:80]}")
    return x, y, z


def _unit(rows) -> np.ndarray:
    q = np.array(rows, dtype=float).reshape(-1, 4)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, :1] < 0, -q, q)


def _initial_quaternion(initial) -> list:
    try:
        q = [float(v) for v in initial]
    except (TypeError, ValueError, OverflowError):
        raise AttitudeInputError(f"initial must be a quaternion [w, x, y, z], got {initial!r}") from None
    n = math.sqrt(sum(v * v for v in q)) if len(q) == 4 else 0.0
    if len(q) != 4 or not math.isfinite(n) or n == 0:
        raise AttitudeInputError(f"initial must be a finite non-zero quaternion [w, x, y, z], got {initial!r}")
    return [v / n for v in q]


def _arrays(gyr, acc, mag, nine, rate_hz):
    """(N, 3) float arrays; mag required in 9D (None in 6D); ``rate_hz`` for the field-turn check."""
    from .attitude_inputs import vectors

    gyr = vectors("gyr", gyr)
    acc = vectors("acc", acc)
    if nine and mag is None:
        raise AttitudeInputError("mag is missing: this filter is 9D (magnetometer=True); give mag or build a "
                                 "6D filter with magnetometer=False")
    mag = vectors("mag", mag) if nine else None
    for name, value in (("acc", acc), ("mag", mag)):
        if value is not None and len(value) != len(gyr):
            raise AttitudeInputError(f"{name} has {len(value)} rows but gyr has {len(gyr)}: a row is one step of "
                                     f"1 / rate_hz with a reading of every sensor; streams at their own rates go onto "
                                     "the gyro's clock with cfdesign.nav.align_imu first")
    _check_units(gyr, acc)
    _check_merged(gyr, acc, mag)
    if mag is not None and not _check_hard_iron(mag) and not _check_field_frame(acc, mag):
        _check_field_turn(gyr, mag, rate_hz)
    return gyr, acc, mag


def _check_hard_iron(mag) -> bool:
    """Warn when the field readings lie on a sphere away from zero (:func:`~cfdesign.nav.hard_iron_offset`): a
    hard-iron offset, which the filter does not remove (30 µT beside a 50 µT field: 23 deg RMS in heading).
    Returns whether it warned."""
    import warnings

    from .attitude_streams import hard_iron_offset

    offset = hard_iron_offset(mag)
    if offset is not None:
        norm = float(np.median(np.linalg.norm(mag[np.isfinite(mag).all(axis=1)] - offset, axis=1)))
        warnings.warn(f"mag: the readings lie on a sphere centred at ({', '.join(f'{v:.3g}' for v in offset)}), "
                      f"{float(np.linalg.norm(offset)) / norm:.2g} times the field's norm ({norm:.3g}) from zero: a "
                      "hard-iron offset (an uncalibrated magnetometer, a magnet fixed to the device), which the filter "
                      "does not remove and which turns the heading; subtract cfdesign.nav.hard_iron_offset(mag) from "
                      "mag, or log the calibrated field", UserWarning, stacklevel=4)
    return offset is not None


#: the field-frame check (``_check_field_frame``): rows whose specific force is within this of gravity (m/s²) are
#: quiet; at least this many of them; a median absolute deviation of their dip angle beyond this (rad) warns
FRAME_NORM_TOL, FRAME_MIN_ROWS, FRAME_DIP_MAD = 0.5, 100, math.radians(5.0)


def _check_field_frame(acc, mag):
    """Warn when the angle between the specific force and the field (the dip, fixed in a homogeneous field while the
    specific force is gravity) wanders as the sensor turns: the magnetometer's axes are not the accelerometer's (an
    axis flipped, x and y swapped, NED against ENU), which no disturbance rejection tells from a disturbed field
    (28 to 144 deg RMS off in heading, silent).  Its median absolute deviation over the quiet rows is 0.3 deg on
    synthetic tracks and 0.7 to 1.3 deg on every BROAD development trial (those beside magnets too), 14 to 24 deg with
    a field axis flipped or swapped; above :data:`FRAME_DIP_MAD` (5 deg) warns.  A sensor that hardly turns shows
    no spread, and is not warned of (its heading is then off by a constant); one turning about gravity alone (a
    ground robot) shows none either: :func:`_check_field_turn`.  Returns whether it warned."""
    import warnings

    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        na, nm = np.linalg.norm(acc, axis=1), np.linalg.norm(mag, axis=1)
        quiet = (np.abs(na - GRAVITY) < FRAME_NORM_TOL) & (nm > 0.0) & np.isfinite(nm)
        if quiet.sum() < FRAME_MIN_ROWS:
            return False
        dip = np.arcsin(np.clip(np.einsum("ij,ij->i", acc[quiet], mag[quiet]) / (na[quiet] * nm[quiet]), -1.0, 1.0))
    mad = float(np.median(np.abs(dip - np.median(dip))))
    if mad > FRAME_DIP_MAD:
        warnings.warn(f"mag: the angle between the field and gravity varies by {math.degrees(mad):.2g} deg (median "
                      f"absolute deviation; under {math.degrees(FRAME_DIP_MAD):g} in a field that only turns with the "
                      "sensor): the magnetometer's axes may not be the accelerometer's (an axis flipped, x and y "
                      "swapped, NED against ENU; both sensors take one body frame), or the field is disturbed most "
                      "of the time", UserWarning, stacklevel=4)
    return mad > FRAME_DIP_MAD


#: the field-turn check (``_check_field_turn``): windows of this length (s) over which the gyro turns the field by more
#: than this share of its size (rad, about 3 deg) count; at least this many of them; a median cosine between the
#: field's turn and the gyro's at or below this warns (0.75 to 0.998 on the ten BROAD trials, 0.75 beside a magnet
#: fixed 1 cm off; -0.05 to -0.97 there with a field axis flipped or x and y swapped, -0.98 turning about gravity alone
#: with a field axis flipped or swapped or the gyro's z flipped, at 25 to 1000 Hz)
TURN_WINDOW_S, TURN_MIN, TURN_MIN_WINDOWS, TURN_COSINE = 0.2, 0.05, 20, 0.2


def _check_field_turn(gyr, mag, rate_hz):
    """Warn when the field does not turn in the body frame as the gyro turns it (``-w x m``): over the windows of
    :data:`TURN_WINDOW_S` that turn it by more than :data:`TURN_MIN`, the median cosine between the field's change and
    the change the gyro predicts is at most :data:`TURN_COSINE` (a median: one impossible rate does not sway it).
    Catches a magnetometer (or gyro) axis of another sign or order turning about gravity alone (a ground robot: 22 to
    113 deg RMS off in heading, where the dip and the gyro-gravity checks see nothing); cosines are of directions, so
    units do not matter.  Returns whether it warned.

    Parameters
    ----------
    gyr, mag : ndarray (N, 3)
        Body rates (rad/s) and field readings (any unit), one row a sample (NaN rows leave their windows out).
    rate_hz : float
        Sample rate (Hz).
    """
    import warnings

    w = max(3, round(TURN_WINDOW_S * rate_hz))
    n = (len(gyr) - 1) // w * w
    if n < w * TURN_MIN_WINDOWS:
        return False
    with np.errstate(invalid="ignore", over="ignore"):
        predicted = -np.cross(gyr[:n], mag[:n]).reshape(-1, w, 3).sum(axis=1) / rate_hz
        measured = mag[w:n + 1:w] - mag[0:n:w]
        size = np.linalg.norm(mag[0:n:w], axis=1)
        keep = ((np.linalg.norm(predicted, axis=1) > TURN_MIN * size) & np.isfinite(measured).all(axis=1)
                & np.isfinite(predicted).all(axis=1))
        if keep.sum() < TURN_MIN_WINDOWS:
            return False
        p, m = predicted[keep], measured[keep]
        cosine = float(np.median((p * m).sum(axis=1) / (np.linalg.norm(p, axis=1) * np.linalg.norm(m, axis=1))))
    if not cosine <= TURN_COSINE:
        return False
    warnings.warn(f"mag: the field turns in the sensor frame otherwise than the gyro turns it (median cosine of their "
                  f"turns {cosine:.2g}, about 1 when their axes agree): an axis of the magnetometer or of the gyro of "
                  "another sign or order than the accelerometer's (an axis flipped, x and y swapped, NED against ENU; "
                  "all three sensors take one body frame), or the field is disturbed most of the time", UserWarning,
                  stacklevel=4)
    return True


#: the share of the rows of :meth:`AttitudeFilter.run` without a rate but with another sensor's reading, next to a row
#: with a rate (interleaved: a gap in the gyro is not), beyond which
#: the arrays are taken for streams merged by time stamp (``_check_merged``): a gyro that drops readings in a log on
#: its own clock misses a few percent (a phone's about 1 %); a table merged from a gyro and an accelerometer at one
#: rate has none in half its rows, from 200 / 100 / 50 Hz streams 43 %, from a 1000 Hz gyro and a 100 Hz
#: accelerometer 9 %
MERGED_SHARE = 0.05


def _check_merged(gyr, acc, mag):
    """Warn when many rows have no rate but a specific force or a field, between rows with one: rows merged from
    streams at their own rates (one row per time stamp of any sensor), which the filter would take as steps of
    ``1 / rate_hz`` each, turning the attitude by the held rate at every one of them (a 200 / 100 / 50 Hz table run
    at 200 Hz: 134 deg RMS off; at its mean row rate 1 deg, 0.19 on the gyro's clock)."""
    import warnings

    with np.errstate(invalid="ignore"):
        other = np.isfinite(acc).all(axis=1) if mag is None else np.isfinite(acc).all(axis=1) | np.isfinite(mag).all(
            axis=1)
    rated = ~np.isnan(gyr).all(axis=1)
    # beside a row with a rate: interleaved with the gyro's rows (a gap in the gyro is one run, counted twice at most)
    beside = np.zeros(len(gyr), dtype=bool)
    beside[1:] |= rated[:-1]
    beside[:-1] |= rated[1:]
    alone = int((other & ~rated & beside).sum())
    if alone >= 10 and alone > MERGED_SHARE * len(gyr):
        warnings.warn(f"gyr: {alone} of the {len(gyr)} rows ({100.0 * alone / len(gyr):.0f} %) have no rate but "
                      "another sensor's reading: rows merged from streams at their own rates? Each row is taken as one "
                      "step of 1 / rate_hz (the held rate turning the attitude at every row); put the streams on the "
                      "gyro's clock with cfdesign.nav.align_imu(t_gyr, gyr, t_acc, acc, t_mag, mag) and run its "
                      "arrays at its rate_hz", UserWarning, stacklevel=4)


def _check_units(gyr, acc):
    """Warn when the specific forces look like other units than m/s²: the median specific force of a
    hand-held or vehicle IMU is near g (9.8 m/s², 1 in g).  The filter runs anyway (the gyro's units:
    ``_GyroUnits``)."""
    with np.errstate(invalid="ignore", over="ignore"):  # an impossible reading (1e200: inf) is the step's to count
        a = np.linalg.norm(acc, axis=1)
    a = a[np.isfinite(a)]
    if len(a) and not 3.0 <= float(np.median(a)) <= 30.0:
        _warn_accel_unit("the median specific force", float(np.median(a)))


def _warn_accel_unit(what, value, stacklevel=4):
    """Warn that a specific force of ``value`` (``what``: which one) is not in m/s² (gravity 9.81)."""
    import warnings

    warnings.warn(f"acc: {what} is {value:.3g}; the filter takes m/s² (gravity 9.81): readings in g need "
                  "multiplying by 9.80665", UserWarning, stacklevel=stacklevel)


#: the gyro-unit check (``_GyroUnits``): its window (s); a quiet window's specific-force norm: mean within
#: this of gravity, std below this (m/s²); the least gyro turn of a window it counts (rad); the summed gyro turn
#: of the counted windows before it judges (rad); the ratio of the gyro's turn to the accelerometer's beyond
#: which the gyro is in deg/s (57.3 times rad/s); the samples ``step`` gathers before checking them at once
UNIT_WINDOW_S, UNIT_NORM_TOL, UNIT_NORM_STD, UNIT_MIN_TURN, UNIT_TURN, UNIT_RATIO, UNIT_CHUNK = (
    0.1, 0.3, 0.5, 0.02, 5.0, 2.5, 4096)
#: a gyro the check warns of whose turns' RMS is at most this many times the accelerometer's turns' is warned of as
#: of other axes or signs than the accelerometer (turns of one size, in other directions: 0.93 to 1.9 with an axis
#: flipped, x and y swapped or all three negated, at 25 to 1000 Hz), above it as in deg/s (5.8 to 45 on synthetic
#: tracks and BROAD trials in deg/s, 2.3 on trial 28, whose few quiet windows barely turn)
UNIT_AXES_SIZE = 3.0


class _GyroUnits:
    """Whether the gyro reads deg/s: it turns gravity faster than the accelerometer sees gravity turn.

    Over a short quiet window (the specific force's norm steady and gravity's) the specific force is
    gravity, fixed in the world, so in the body frame its direction ``u`` turns as the gyro says:
    ``u' = -w x u``.  Per window of ``UNIT_WINDOW_S`` the accelerometer's turn ``da = u_end - u_start``
    and the gyro's ``dg = -T sum_k w_k x u_(k-1)`` agree in rad/s; in deg/s ``dg`` is 57 times larger.
    The least-squares ratio ``sum |dg|² / sum dg . da`` over the windows that turned by at least
    ``UNIT_MIN_TURN`` is near 1 in rad/s (0.9 to 1.0 on every BROAD development trial and on synthetic
    tracks at 25 to 1000 Hz) and from about 10 to infinite in deg/s (slow and yaw-only motion included:
    about the vertical gravity does not turn, so those windows count for nothing).  Once the counted
    windows have turned by ``UNIT_TURN`` (rad, by the gyro) the check judges, once: a ratio above
    ``UNIT_RATIO`` warns, one at or below it is rad/s (0.77 to 1.01 there; 23 to infinite in deg/s), and
    the check ends either way.  The warning says deg/s when the gyro's turns are larger than the
    accelerometer's (their RMS above ``UNIT_AXES_SIZE`` times), else that the two sensors' axes differ: turns
    of one size in other directions (a ratio of -15 to 15 with an axis flipped or x and y swapped; 3.5 to 4.3 with
    z flipped, which the former bound of 5 let through, 55 deg RMS off in inclination).

    A median rate above 20 (rad/s: far beyond an ordinary motion, an ordinary one in deg/s) warns at
    once in :meth:`AttitudeFilter.run` (it needs no quiet windows: a vibrating sensor has none); either
    warning ends the check, so a filter warns of the gyro's units at most once.  Windows with a missing
    or impossible reading (the step's) do not count.  The check reads the readings only: no estimate
    depends on it.

    Parameters
    ----------
    rate_hz : float
        Sample rate (Hz).
    gyro_range2, accel_range2 : float
        The squared ranges of the gyro ((rad/s)²) and the accelerometer ((m/s²)²): readings beyond are
        impossible (missing to the step).
    """

    def __init__(self, rate_hz, gyro_range2, accel_range2):
        self.window = max(3, round(UNIT_WINDOW_S * rate_hz))
        self.T, self.ranges = 1.0 / rate_hz, (gyro_range2, accel_range2)
        #: ``step``'s samples not yet checked, ``gx, gy, gz, ax, ay, az`` each in a flat list (None once judged),
        #: checked once it holds ``full`` numbers: whole windows of about ``UNIT_CHUNK`` samples
        self.buffer = []
        self.full = 6 * self.window * -(-UNIT_CHUNK // self.window)
        #: over the counted windows: sum |dg|², sum dg . da, sum |da|², sum |dg| (rad), windows
        self.sums = np.zeros(5)

    def check_median(self, gyr, stacklevel):
        """Warn (and end the check) when the median rate of ``gyr`` (N, 3) is above 20 (``stacklevel``: as
        :func:`warnings.warn` would take it here); :meth:`AttitudeFilter.run` calls it on its arrays before
        :meth:`feed`."""
        if self.buffer is None:
            return
        with np.errstate(invalid="ignore", over="ignore"):  # an impossible reading (1e200: inf) is the step's to count
            w = np.linalg.norm(gyr, axis=1)
        w = w[np.isfinite(w)]
        if len(w) and float(np.median(w)) > 20.0:
            self.warn(f"the median rate is {float(np.median(w)):.3g}, beyond any ordinary motion in rad/s",
                      stacklevel + 1)

    def feed(self, gyr, acc, stacklevel):
        """Check the samples gathered so far followed by ``gyr``, ``acc`` ((N, 3) arrays, rad/s and m/s²; N may be
        0): every complete window in turn, the rest kept for the next call.  Warns once (``stacklevel``: as
        :func:`warnings.warn` would take it here) when the counted windows show a gyro in deg/s."""
        if self.buffer is None:
            return
        if self.buffer:
            held = np.fromiter(self.buffer, dtype=float, count=len(self.buffer)).reshape(-1, 6)
            gyr, acc = np.concatenate((held[:, :3], gyr)), np.concatenate((held[:, 3:], acc))
        w = self.window
        m = len(gyr) // w
        self.buffer = np.hstack((gyr[m * w:], acc[m * w:])).ravel().tolist()
        if m == 0:
            return
        dg, da = self._windows(gyr[:m * w].reshape(m, w, 3), acc[:m * w].reshape(m, w, 3))
        if not len(dg):
            return
        gg = (dg * dg).sum(axis=1)
        per = np.column_stack((gg, (dg * da).sum(axis=1), (da * da).sum(axis=1), np.sqrt(gg), np.ones(len(gg))))
        sums = self.sums + np.cumsum(per, axis=0)
        judged = np.flatnonzero(sums[:, 3] >= UNIT_TURN)
        if not len(judged):
            self.sums = sums[-1]
        elif sums[judged[0], 0] > UNIT_RATIO * sums[judged[0], 1]:
            gg, ga, aa, n = sums[judged[0], [0, 1, 2, 4]]
            if gg > UNIT_AXES_SIZE**2 * aa:
                self.warn(f"the gyro turns gravity {_times(gg, ga, aa, n)} faster than the accelerometer shows it "
                          "turning", stacklevel + 1)
            else:  # turns of one size, in other directions
                self.warn_axes(ga / math.sqrt(gg * aa), stacklevel + 1)
        else:
            self.buffer = None                          # rad/s: the check is over

    def _windows(self, g, a):
        """The gyro's and the accelerometer's turns ``dg``, ``da`` (K, 3) of the counted windows among ``g``, ``a``
        (M, W, 3): quiet, with no missing or impossible reading, turned by at least ``UNIT_MIN_TURN``."""
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            g2, f2 = (g * g).sum(axis=2), (a * a).sum(axis=2)
            f = np.sqrt(f2)
            u = a / f[..., None]
            gp, up = g[:, 1:], u[:, :-1]
            dg = -self.T * np.stack((gp[..., 1] * up[..., 2] - gp[..., 2] * up[..., 1],
                                     gp[..., 2] * up[..., 0] - gp[..., 0] * up[..., 2],
                                     gp[..., 0] * up[..., 1] - gp[..., 1] * up[..., 0]), axis=-1).sum(axis=1)
            keep = ((g2 <= self.ranges[0]).all(axis=1) & (f2 <= self.ranges[1]).all(axis=1) & (f > 0.0).all(axis=1)
                    & (np.abs(f.mean(axis=1) - GRAVITY) < UNIT_NORM_TOL) & (f.std(axis=1) < UNIT_NORM_STD)
                    & ((dg * dg).sum(axis=1) >= UNIT_MIN_TURN * UNIT_MIN_TURN))
        return dg[keep], u[keep, -1] - u[keep, 0]

    def warn_axes(self, correlation, stacklevel):
        """Warn that the gyro turns gravity otherwise than the accelerometer shows it turning (``correlation``: of
        their turns over the counted windows, about 1 when the frames agree; ``stacklevel``: as :func:`warnings.warn`
        would take it here), and end the check: a gyro axis of another sign or order than the accelerometer's."""
        import warnings

        self.buffer = None
        warnings.warn(f"gyr: the gyro turns gravity another way than the accelerometer shows it turning (their turns' "
                      f"correlation {correlation:.2g}, about 1 when their axes agree): an axis of the gyro or of the "
                      "accelerometer of another sign or order than the other's (an axis flipped, x and y swapped, "
                      "NED against ENU; both sensors take one body frame), or readings in deg/s", UserWarning,
                      stacklevel=stacklevel)

    def warn(self, what, stacklevel):
        """Warn that the gyro looks like deg/s (``what``: why; ``stacklevel``: as :func:`warnings.warn` would take
        it here), and end the check."""
        import warnings

        self.buffer = None
        warnings.warn(f"gyr: {what}: readings look like deg/s (multiply by pi/180), or the gyro's bias is above "
                      "0.2 rad/s (a still sensor that reads a turn)", UserWarning,
                      stacklevel=stacklevel)


def _times(gg, ga, aa, n) -> str:
    """How many times the gyro's turn is the accelerometer's, from the windows' sums ``sum |dg|²``, ``sum dg . da``,
    ``sum |da|²`` and their number ``n``: the least-squares ratio when the accelerometer's turn is determined (the
    slope ``ga / gg`` three standard errors from 0), else only that it is above ``UNIT_RATIO``."""
    slope = ga / gg
    se = math.sqrt(max(aa - ga * slope, 0.0) / max(n - 1.0, 1.0) / gg)
    return f"about {1.0 / slope:.2g} times" if slope > 3.0 * se else f"more than {UNIT_RATIO:g} times"


def _coefficients(design: AttitudeDesign) -> tuple:
    """The numbers of the step, flattened for speed (see :func:`_step`)."""
    c, p = design.constants, design.params
    return (c["T"], c["rest_alpha"], c["rest_gyro_th2"], c["rest_accel_th2"], c["rest_bias_th2"], p.rest_time_s,
            c["mag_alpha"], c["mag_ref_alpha"], c["north"], c["speed2"], c["gyro_range2"], c["accel_range2"],
            p.mag_tolerance_rad, p.mag_new_field_s, p.mag_new_field_rotation_rad, p.mag_first_field_s,
            p.mag_provisional_s, p.mag_follow_factor, design.priors["rest"][0],
            tuple(design.velocity), design.channels["tilt"], design.channels["heading"], design.channels["rest"],
            p.rest_detection, p.mag_rejection, p.accel_rejection, p.motion_bias, p.inertial_tilt, p.max_accel_time_s,
            c["accel_hold_s"], c["tilt_alpha"], c["rest_lp_var"], _settle_ratio(design), c["rest_gyro_var"],
            c["rest_accel_var"], c["rest_floor_up"], c["rest_diff_scale"], c["shock_lim2"])


def _settle_ratio(design: AttitudeDesign) -> float:
    """How much the start-up's error adds to the tilt channel's reading variance as the velocity channel's
    settling begins, relative to the reading's own (``docs/derivations.md``).

    A sensor moving when the filter starts leaves the start-up's tilt (its mean specific force over
    ``1 / omega``) off by its velocity change ``v`` over that time: ``omega v / g``, ``v`` up to
    ``max_speed_mps`` taken as three standard deviations.  The velocity channel removes it with the
    envelope ``exp(-zeta omega t)``: an error correlated over ``1 / (zeta omega)``, whose variance as
    white noise is ``2 / (zeta omega)`` times its own per unit bandwidth, against the reading's
    ``tilt_noise_density²`` (the tilt table's ``R T``).
    """
    c, p = design.constants, design.params
    omega = c["tilt_alpha"] / c["T"]
    density2 = design.channels["tilt"][3] * c["T"]
    error2 = (omega * p.max_speed_mps / (3.0 * GRAVITY)) ** 2
    return 2.0 * math.sqrt(2.0) / omega * error2 / density2


def _tilt_error(flx, fly, flz, fdev, tilt_f, r0, r1, r2, r3, r4, r5) -> bool:
    """Whether the specific force the velocity channel takes for a sustained acceleration is gravity seen
    through a tilt error of the estimate.

    The rest detector's low-passed specific force ``f`` (body, m/s²) is steady (its mean squared deviation
    ``fdev`` below an eighth of its horizontal part squared ``h²``, ``h`` seen through the estimated
    attitude, whose first two rows are ``r0 .. r5``) and its norm is gravity's as the start-up measured it
    (``tilt_f``): ``| |f|² - g² | < h² / 2``.  A tilt error of ``theta`` shows a horizontal part
    ``h = g sin(theta)`` with the norm unchanged; a real horizontal acceleration ``a`` (estimate upright)
    shows ``h = a`` and ``|f|² = g² + a²``, so the test halves the margin between the two.
    """
    hx = r0 * flx + r1 * fly + r2 * flz
    hy = r3 * flx + r4 * fly + r5 * flz
    h2 = hx * hx + hy * hy
    return 8.0 * fdev < h2 and 2.0 * abs(flx * flx + fly * fly + flz * flz - tilt_f * tilt_f) < h2


def _lagged(a, v, x, T, k1, k2, carry) -> tuple:
    """One step of the velocity channel on one element ``x`` of the attitude's first two rows, per unit gyro
    bias: the drift ``T x`` adds to the tilt ``a``, whose specific force (over ``g``) the velocity ``v``
    integrates (``carry`` 0: from zero), ``k2 v`` corrects the tilt and ``k1 v`` the velocity.

    Returns the new ``a`` and ``v`` and the correction per unit time, ``k2 v / T``: ``x`` through the
    channel's second-order low-pass (``docs/derivations.md``), so ``x`` itself for a steady attitude, within
    ``[-1, 1]`` as ``x`` is (a run stays within; a restored state far off is cut, as ``a`` and ``v`` are at
    :data:`STATE_LIMIT`, so no state the step leaves is one :meth:`AttitudeFilter.restore` refuses)."""
    a += T * x
    v = carry * v + T * a
    c = k2 * v
    a, v, m = a - c, v - k1 * v, c / T
    if -STATE_LIMIT <= a <= STATE_LIMIT and -STATE_LIMIT <= v <= STATE_LIMIT and -1.0 <= m <= 1.0:
        return a, v, m                                  # the common case, without the three calls
    return _clip(a, STATE_LIMIT), _clip(v, STATE_LIMIT), _clip(m, 1.0)


def _clip(x, limit) -> float:
    """``x`` within ``[-limit, limit]`` (NaN: ``-limit``), as ``min(limit, max(-limit, x))`` gives it: a comparison
    instead of those two calls, which cost several times as much in the step's loop."""
    return x if -limit <= x <= limit else (limit if x > limit else -limit)


def _shock_clipped(ax, ay, az, flx, fly, flz, spread2, lim2) -> tuple:
    """The specific force ``a`` (body, m/s²) with its deviation from the rest detector's low-pass ``fl`` clipped to
    ``sqrt(lim2 spread2)`` (Huber's clipping of an outlier): a shock, one sample or a few far beyond the recent
    spread ``spread2`` (the low-passed squared deviation, or the noise floor where that is larger; m²/s⁴), enters
    the channels and the detector as a sample of that bounded deviation in its direction, not with its full
    weight; a sample within it is returned as it is."""
    dx, dy, dz = ax - flx, ay - fly, az - flz
    d2 = dx * dx + dy * dy + dz * dz
    lim = lim2 * spread2
    if d2 <= lim:
        return ax, ay, az
    w = math.sqrt(lim / d2)
    return flx + w * dx, fly + w * dy, flz + w * dz


def _noise_floor(noise, floor, dev, var, up) -> float:
    """The noise floor after one step from ``floor``, given the sensor's low-passed white noise ``noise`` and the
    rest detector's low-passed squared deviation ``dev`` (all in the sensor's units squared; ``var``: the
    deviation's designed mean at rest; ``up``: the largest rise per step): followed down at once, risen by at most
    ``up`` times and not beyond ``noise`` while the deviation could be rest (below ``REST_FLOOR_K *
    REST_FLOOR_CAP`` times ``var``: a fast motion, which adds to the noise too, does not raise it), within
    ``[var / REST_FLOOR_CAP, var * REST_FLOOR_CAP]``."""
    if noise < floor:
        low = var / REST_FLOOR_CAP
        return noise if noise > low else low
    if dev >= REST_FLOOR_K * REST_FLOOR_CAP * var:
        return floor
    floor *= up
    if floor > noise:
        floor = noise
    high = REST_FLOOR_CAP * var
    return floor if floor < high else high


def _step(s, coef, samples, nine, out) -> int:
    """The filter's step on each sample of ``samples``, in order, from and back to the state list ``s``
    (:data:`STATE_FIELDS`); each sample's attitude (normalised, as the state keeps it) is appended to ``out``.

    ``samples``: an iterable of ``(gx, gy, gz, ax, ay, az, mx, my, mz)`` (rad/s, m/s², the field; NaN:
    missing).  Returns the velocity design the last sample used (-1: none).  The state lives in local floats
    for the whole loop (unpacked once, written back once), so :meth:`AttitudeFilter.run` pays no per-sample
    call, unpacking or list write, and :meth:`AttitudeFilter.step` runs the same code on one sample.

    Plain floats, in the order the generated C follows (``cfdesign/codegen/templates/attitude.c.in``).
    """
    (T, r_alpha, th_g2, th_a2, th_b2, rest_min, m_alpha, ref_alpha, north, speed2, g_range2, a_range2,
     tol, new_s, new_rot, first_s, prov_s, follow_f, hold_var, velocity, tilt, heading, restc, use_rest, use_mag_check,
     use_levels, use_motion_bias, inertial, max_acc_s, hold_s, tilt_alpha, lp_var, settle_ratio, var_g, var_a,
     floor_up, d_scale, shock_lim2) = coef
    heading_var0 = HEADING_VAR0
    (qw, qx, qy, qz, bx, by, bz, vx, vy, ex, ey, ez, ra0, ra1, ra2, ra3, ra4, ra5, rv0, rv1, rv2, rv3, rv4, rv5,
     px, py, pz, glx, gly, glz, flx, fly, flz,
     gdev, fdev, gnoise, fnoise, gfloor, ffloor, lax, lay, laz, grest, frest, rest_time, r00, r01, r11,
     t00, t01, t11, h00, h01, h11, norm_lp, dip_lp, norm_ref, dip_ref,
     ref_n, norm_new, dip_new, new_n, new_time, new_turn, dist_time, disturbed, level, acc_time, tilt_n, tilt_f,
     lgx, lgy, lgz, started, miss_g, miss_a, miss_m, gap_n) = s
    jv = -1
    for gx, gy, gz, ax, ay, az, mx, my, mz in samples:
        # readings: an impossible or non-finite one is missing (NaN fails every comparison)
        ox, oy, oz = lgx, lgy, lgz                         # the previous sample's rate (held if it was missing)
        g_ok = gx * gx + gy * gy + gz * gz <= g_range2
        if g_ok:
            # the turn the held rate made over the gap (none without one), squared
            held2 = (gap_n * T) ** 2 * ((lgx - bx) ** 2 + (lgy - by) ** 2 + (lgz - bz) ** 2) if gap_n > 0.0 else 0.0
            lgx, lgy, lgz = gx, gy, gz
            if gap_n * tilt_alpha >= 1.0 or held2 > GAP_TURN_RAD * GAP_TURN_RAD:
                # the gyro was missing for longer than the tilt's start-up, or the held rate turned the attitude by more
                # than GAP_TURN_RAD meanwhile: the held rate has lost the attitude (the body turned unseen), which the
                # velocity channel would take for a sustained acceleration and the field check for a disturbance; the
                # start-up runs again, keeping the heading and the bias
                started = 0.0
            elif started == 2.0:
                gap_n = 0.0
        else:
            miss_g += 1.0
            gx, gy, gz = lgx, lgy, lgz
            if started == 2.0:
                gap_n += 1.0
        f2 = ax * ax + ay * ay + az * az
        acc_ok = 0.0 < f2 <= a_range2
        if not acc_ok:
            miss_a += 1.0
        mag_ok = False
        if nine:
            m2 = mx * mx + my * my + mz * mz
            mag_ok = 0.0 < m2 < math.inf
            if not mag_ok:
                miss_m += 1.0

        jv = -1
        if started < 2.0:
            # the first step: the attitude is the initial one (given, or the tilt of this specific force)
            if started == 0.0:
                if not acc_ok:
                    out.append((qw, qx, qy, qz))        # no attitude yet: the state's, only counted
                    continue
                fn = math.sqrt(f2)
                uw = 1.0 + az / fn
                # the heading (ZYX yaw) to keep: after a gap in the gyro, the one held through it
                yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz)) if gap_n > 0.0 else 0.0
                if uw > 1e-9:
                    qw, qx, qy, qz = uw, ay / fn, -ax / fn, 0.0           # shortest rotation from up_body to e_z
                else:
                    qw, qx, qy, qz = 0.0, 1.0, 0.0, 0.0                   # upside down
                n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
                qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
                tilt_n, tilt_f = 1.0, fn
                if gap_n > 0.0:
                    # turned about ENU z onto the held heading, which in 9D the field then sets (its prior reopened)
                    d = 0.5 * (yaw - math.atan2(2.0 * qx * qy, 1.0 - 2.0 * qy * qy))
                    cw, sz = math.cos(d), math.sin(d)
                    qw, qx, qy, qz = cw * qw - sz * qz, cw * qx - sz * qy, cw * qy + sz * qx, cw * qz + sz * qw
                    h00, h01, gap_n = heading_var0, 0.0, 0.0
            glx, gly, glz = gx, gy, gz
            if acc_ok:
                flx, fly, flz = ax, ay, az
            started = 2.0
            ux = uy = uz = 0.0
            first = True
        else:
            first = False

        # rest detection (body frame)
        glx += r_alpha * (gx - glx)
        gly += r_alpha * (gy - gly)
        glz += r_alpha * (gz - glz)
        gdev += r_alpha * ((gx - glx) * (gx - glx) + (gy - gly) * (gy - gly) + (gz - glz) * (gz - glz) - gdev)
        if g_ok and not first:
            # the gyro's white noise from successive samples (a motion smooth at the sample rate hardly adds to it)
            # and its floor: a sensor noisier than its density rests within its own noise
            gnoise += r_alpha * (d_scale * ((gx - ox) * (gx - ox) + (gy - oy) * (gy - oy) + (gz - oz) * (gz - oz))
                                 - gnoise)
            gfloor = _noise_floor(gnoise, gfloor, gdev, var_g, floor_up)
        # each sensor within the designed threshold or REST_FLOOR_K times its noise floor, whichever is larger
        kg = REST_FLOOR_K * gfloor
        db = (glx - bx) * (glx - bx) + (gly - by) * (gly - by) + (glz - bz) * (glz - bz)
        still = use_rest and gdev < (kg if kg > th_g2 else th_g2) and db < th_b2
        if acc_ok:
            if abs(tilt_n) * tilt_alpha >= 1.0:
                # after the tilt's start-up (its time 1 / omega is past the low-pass's, so the spread is measured),
                # or as many specific forces after a given initial attitude (tilt_n counted down, below)
                ax, ay, az = _shock_clipped(ax, ay, az, flx, fly, flz, fdev if fdev > ffloor else ffloor, shock_lim2)
            elif tilt_n <= 0.0:
                # a given initial attitude (only it reaches here with tilt_n <= 0: the first specific force
                # without one sets tilt_n to 1) runs no start-up; tilt_n counts its specific forces down from 0
                # instead, the start-up's count negated, so the clipping starts at the same sample.  One counter,
                # not a new state field: every start-up and settling condition (0 < tilt_n alpha) is false for it,
                # and a restart (after a gap or a tilt error) sets it to 1 as without an initial attitude
                tilt_n -= 1.0
            flx += r_alpha * (ax - flx)
            fly += r_alpha * (ay - fly)
            flz += r_alpha * (az - flz)
            fdev += r_alpha * ((ax - flx) * (ax - flx) + (ay - fly) * (ay - fly) + (az - flz) * (az - flz) - fdev)
            if tilt_f == 0.0 and tilt_n < 0.0 and -tilt_n * tilt_alpha >= 1.0:
                # a given initial attitude's count done: gravity's norm, which the start-up would have measured
                # (tilt_f, the tilt-error test's reference; 0 had kept that test from ever passing)
                tilt_f = math.sqrt(flx * flx + fly * fly + flz * flz)
            if not first:
                fnoise += r_alpha * (d_scale * ((ax - lax) * (ax - lax) + (ay - lay) * (ay - lay)
                                                + (az - laz) * (az - laz)) - fnoise)
                ffloor = _noise_floor(fnoise, ffloor, fdev, var_a, floor_up)
            lax, lay, laz = ax, ay, az
            ka = REST_FLOOR_K * ffloor
            still = still and fdev < (ka if ka > th_a2 else th_a2)
        else:
            # no specific force this step (an accelerometer slower than the gyro, a dropped reading): its side of
            # the test stays as the last one left it (had it ended every rest, a 100 Hz accelerometer beside a
            # 200 Hz gyro never rested and the bias was never learnt: 4.3 deg RMS against 0.2)
            still = still and rest_time > 0.0
        was_rest = rest_time >= rest_min
        rest_time = rest_time + T if still else 0.0
        rest = rest_time >= rest_min
        if rest:
            # the deviations at rest, low-passed over the rests: how noisy the sensors are (the class warns of it)
            grest = gdev if grest == 0.0 else grest + r_alpha * (gdev - grest)
            frest = fdev if frest == 0.0 else frest + r_alpha * (fdev - frest)

        # the gyro: q <- q (x) exp(u / 2), u = (w - b) T plus the two-sample coning term (u_prev x u) / 12
        if not first:
            ux, uy, uz = (gx - bx) * T, (gy - by) * T, (gz - bz) * T
            ox, oy, oz = (ox - bx) * T, (oy - by) * T, (oz - bz) * T
            ux, uy, uz = (ux + (oy * uz - oz * uy) / 12.0, uy + (oz * ux - ox * uz) / 12.0,
                          uz + (ox * uy - oy * ux) / 12.0)
            ang = math.sqrt(ux * ux + uy * uy + uz * uz)
            if ang > 1e-12:
                sc = math.sin(0.5 * ang) / ang
                cw = math.cos(0.5 * ang)
            else:
                sc, cw = 0.5, 1.0
            dx, dy, dz = sc * ux, sc * uy, sc * uz
            qw, qx, qy, qz = (qw * cw - qx * dx - qy * dy - qz * dz, qw * dx + qx * cw + qy * dz - qz * dy,
                              qw * dy - qx * dz + qy * cw + qz * dx, qw * dz + qx * dy - qy * dx + qz * cw)
        if rest:
            px += ux
            py += uy
            pz += uz
        else:
            px = py = pz = 0.0
        n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
        r0, r1, r2 = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)
        r3, r4, r5 = 2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)
        r6, r7, r8 = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)

        h2, ended = 1.0, False
        # velocity channel (tilt): v += T f_E; e = -v; v += k1 e; tilt turned by k2 e / g
        cx = cy = cz = 0.0
        if acc_ok and 0.0 < tilt_n * tilt_alpha < 1.0:
            # start-up (from the first specific force, not a given attitude): the tilt turns the running mean
            # of the specific forces so far (the gyro's nearly inertial frame: gravity plus the mean
            # acceleration, the velocity change over the time) upright; kept upright, the mean is its norm
            # tilt_f. A mean of the vectors, not of their directions: a moving sensor's accelerations
            # average out as velocity changes, their directions do not. The velocity channel starts from
            # zero velocity after it
            if not first:
                tilt_n += 1.0
                ended = tilt_n * tilt_alpha >= 1.0       # the start-up's last step
                fex = r0 * ax + r1 * ay + r2 * az
                fey = r3 * ax + r4 * ay + r5 * az
                fez = r6 * ax + r7 * ay + r8 * az
                fh = math.sqrt(fex * fex + fey * fey)
                mean_z = tilt_f + (fez - tilt_f) / tilt_n
                mean_h = fh / tilt_n
                tilt_f = math.sqrt(mean_z * mean_z + mean_h * mean_h)
                if fh > 0.0:
                    w = math.atan2(mean_h, mean_z) / fh
                    cx, cy = w * fey, -w * fex
            vx = vy = 0.0
            ra0 = ra1 = ra2 = ra3 = ra4 = ra5 = rv0 = rv1 = rv2 = rv3 = rv4 = rv5 = 0.0
            jv = 1 if rest else 0
        elif acc_ok:
            carry, restart = 1.0, False
            if not inertial:
                vx = vy = 0.0
                carry = 0.0
            vx += T * (r0 * ax + r1 * ay + r2 * az)
            vy += T * (r3 * ax + r4 * ay + r5 * az)
            level = 0.0
            if rest:
                acc_time = 0.0
                jv = 1
            else:
                vv = vx * vx + vy * vy
                if acc_time < 0.0:
                    acc_time = min(0.0, acc_time + T)           # after a tilt error: the motion design
                elif use_levels and vv > speed2:
                    acc_time += T
                    if acc_time < max_acc_s:
                        if acc_time >= hold_s:
                            # longer than a hand's stroke: a sustained acceleration
                            level = min(float(len(velocity) - 2), 1.0 + math.floor(math.log2(vv / speed2)))
                            if acc_time * tilt_alpha >= T and _tilt_error(flx, fly, flz, fdev, tilt_f,
                                                                          r0, r1, r2, r3, r4, r5):
                                # not an acceleration but the estimate's tilt error: the start-up runs again at
                                # the next step, keeping the heading (as after a gap in the gyro) and the bias
                                started, gap_n = 0.0, max(gap_n, 1.0)
                    else:
                        # longer than an acceleration lasts: a tilt error, which only the motion design corrects
                        vx = vy = 0.0
                        acc_time = -max_acc_s
                        restart = True
                else:
                    acc_time = 0.0
                jv = 0 if level == 0.0 else 1 + int(level)
            k1v, k2v = velocity[jv]
            evx, evy = -vx, -vy
            vx += k1v * evx
            vy += k1v * evy
            cx = -k2v * evy / GRAVITY
            cy = k2v * evx / GRAVITY
            # the attitude's first two rows (ENU x, y of each body axis) through the same step (after a restart, which
            # made no correction, as k1 = 1, k2 = 0): the correction a gyro bias b (body) draws from the velocity
            # channel is (lr0 .. lr5) b, lagging the attitude as the correction lags the tilt
            k1m, k2m = (1.0, 0.0) if restart else (k1v, k2v)
            ra0, rv0, lr0 = _lagged(ra0, rv0, r0, T, k1m, k2m, carry)
            ra1, rv1, lr1 = _lagged(ra1, rv1, r1, T, k1m, k2m, carry)
            ra2, rv2, lr2 = _lagged(ra2, rv2, r2, T, k1m, k2m, carry)
            ra3, rv3, lr3 = _lagged(ra3, rv3, r3, T, k1m, k2m, carry)
            ra4, rv4, lr4 = _lagged(ra4, rv4, r4, T, k1m, k2m, carry)
            ra5, rv5, lr5 = _lagged(ra5, rv5, r5, T, k1m, k2m, carry)
            # their mean squared gain (1 for a steady attitude, less as the rotation blurs them): the rate at which
            # the bias moves the tilt channel's angle, in its covariance recursion below
            h2 = 0.5 * (lr0 * lr0 + lr1 * lr1 + lr2 * lr2 + lr3 * lr3 + lr4 * lr4 + lr5 * lr5)
            # tilt channel (gyro bias during motion): reads the tilt the velocity channel gives; while that settles
            # from its start-up, the reading carries what the start-up left (a moving sensor's start-up tilt errs
            # by its velocity change over the start-up), a decaying error taken as reading noise, not gyro bias
            settle = 1.0
            if 0.0 < tilt_n * tilt_alpha < TILT_SETTLE:
                tilt_n += 1.0
                settle += settle_ratio * math.exp(-math.sqrt(2.0) * (tilt_n * tilt_alpha - 1.0))
            if use_motion_bias and not rest:
                # its attitude error, kept in the body frame (where the bias is constant), moves against
                # the velocity channel's correction; its tilt (ENU x, y) is the reading
                ex -= lr0 * cx + lr3 * cy
                ey -= lr1 * cx + lr4 * cy
                ez -= lr2 * cx + lr5 * cy
                q00, q01, q11, rr, kal, k1t, k2t = tilt
                if kal:
                    den = t00 + rr * settle
                    k1t, k2t = t00 / den, t01 / den
                    t00, t01, t11 = (1.0 - k1t) * t00, (1.0 - k1t) * t01, t11 - k2t * t01
                    t11 = t11 if t11 > 0.0 else 0.0   # a variance, not negative by rounding
                e1 = -(r0 * ex + r1 * ey + r2 * ez)
                e2 = -(r3 * ex + r4 * ey + r5 * ez)
                d1, d2, d3 = r0 * e1 + r3 * e2, r1 * e1 + r4 * e2, r2 * e1 + r5 * e2
                ex += k1t * d1
                ey += k1t * d2
                ez += k1t * d3
                bx -= k2t * d1
                by -= k2t * d2
                bz -= k2t * d3
        if not rest:
            q00, q01, q11 = tilt[0], tilt[1], tilt[2]
            t00, t01, t11 = t00 + 2.0 * T * h2 * t01 + T * T * h2 * h2 * t11 + q00, t01 + T * h2 * t11 + q01, t11 + q11

        # heading channel (9D): magnetic disturbance check, then the correction about ENU z
        if nine:
            if ended:
                # the heading the start-up's fields set was read through a tilt not yet settled (a tilt error turns
                # the field's horizontal direction by up to tan(dip) times as much) and checked against no reference
                # (which starts now, below): as unknown as at the start
                h00, h01 = max(h00, heading_var0), 0.0
            if mag_ok:
                nm = math.sqrt(m2)
                mex = r0 * mx + r1 * my + r2 * mz
                mey = r3 * mx + r4 * my + r5 * mz
                mez = r6 * mx + r7 * my + r8 * mz
                dip = math.asin(_clip(-mez / nm, 1.0))
                if 0.0 < tilt_n * tilt_alpha < 1.0:
                    # the tilt's start-up: the dip read through a tilt not yet settled is not the field's,
                    # so the reference starts (from the reading alone, below) once the tilt has settled
                    ref_n = 0.0
                if ref_n * m_alpha < 1.0:
                    # start-up: the low-pass is the running mean of the readings so far, and the reference
                    # is that mean (a single reading is as noisy as the sensor; nothing to check it against)
                    # (ref_n counts it below, as an undisturbed reading)
                    norm_lp += (nm - norm_lp) / (ref_n + 1.0)
                    dip_lp += (dip - dip_lp) / (ref_n + 1.0)
                    norm_ref, dip_ref = norm_lp, dip_lp
                else:
                    norm_lp += m_alpha * (nm - norm_lp)
                    dip_lp += m_alpha * (dip - dip_lp)
                th = tol * math.cos(dip_ref)
                dist = use_mag_check and (abs(norm_lp - norm_ref) > th * norm_ref or abs(dip_lp - dip_ref) > th)
                if dist:
                    # a candidate new field: accepted once it held long enough while the sensor turned
                    if new_n == 0.0:
                        norm_new, dip_new, new_n, new_time, new_turn = norm_lp, dip_lp, 1.0, 0.0, 0.0
                    else:
                        new_n += 1.0
                        a = max(ref_alpha, 1.0 / new_n)
                        norm_new += a * (norm_lp - norm_new)
                        dip_new += a * (dip_lp - dip_new)
                        thn = tol * math.cos(dip_new)
                        if abs(norm_lp - norm_new) <= thn * norm_new and abs(dip_lp - dip_new) <= thn:
                            new_time += T
                            # turned: the rest detector's low-passed rate, whose noise (unlike the raw rate's)
                            # does not add up faster at a higher rate
                            new_turn += T * math.sqrt((glx - bx) * (glx - bx) + (gly - by) * (gly - by)
                                                      + (glz - bz) * (glz - bz))
                            # a reference that has not yet held for prov_s (from the start or a restart) is
                            # provisional: nothing says it was the clean field, so a new one replaces it sooner
                            provisional = ref_n * T < prov_s
                            if new_time >= (max(first_s, ref_n * T) if provisional else new_s) and new_turn >= new_rot:
                                norm_ref, dip_ref, ref_n, dist = norm_new, dip_new, new_n, False
                                new_n = new_time = new_turn = 0.0
                                h01 = 0.0   # the new field's north is not the old one's: its offset is not gyro drift
                                if provisional:
                                    # the heading the provisional field set is as unknown as at the start
                                    h00 = max(h00, heading_var0)
                        else:
                            new_n = new_time = new_turn = 0.0
                else:
                    ref_n += 1.0
                    a = max(ref_alpha, 1.0 / ref_n)
                    norm_ref += a * (norm_lp - norm_ref)
                    dip_ref += a * (dip_lp - dip_ref)
                    new_n = new_time = new_turn = 0.0
                disturbed = 1.0 if dist else 0.0
                dist_time = dist_time + T if dist else 0.0
                q00, q01, q11, rr, kal, hk1, hk2 = heading
                # a provisional reference the field has left for longer than it had held itself is no better
                # evidence than the field that left it: the heading follows the field, its reading variance
                # widened follow_f times, and learns no gyro bias from it (Kalman tables only)
                follow = dist and kal and ref_n * T < prov_s and dist_time > ref_n * T
                if (not dist or follow) and math.sqrt(mex * mex + mey * mey) > 1e-9 * nm:
                    eh = wrap_scalar(north - math.atan2(mey, mex))
                    if kal:
                        den = h00 + (rr * follow_f if follow else rr)
                        hk1, hk2 = h00 / den, (0.0 if follow else h01 / den)
                        h00, h01, h11 = (1.0 - hk1) * h00, (1.0 - hk1) * h01, h11 - hk2 * h01
                        h11 = h11 if h11 > 0.0 else 0.0   # a variance, not negative by rounding
                    cz = hk1 * eh
                    dz = hk2 * eh
                    bx -= r6 * dz
                    by -= r7 * dz
                    bz -= r8 * dz
            q00, q01, q11 = heading[0], heading[1], heading[2]
            h00, h01, h11 = h00 + 2.0 * T * h01 + T * T * h11 + q00, h01 + T * h11 + q01, h11 + q11

        # corrections in ENU: q <- exp(c / 2) (x) q; the channels' horizontal states turn with the heading
        ang_c = math.sqrt(cx * cx + cy * cy + cz * cz)
        if ang_c > 0.0:
            sc = math.sin(0.5 * ang_c) / ang_c
            cw = math.cos(0.5 * ang_c)
            dx, dy, dz = sc * cx, sc * cy, sc * cz
            qw, qx, qy, qz = (cw * qw - dx * qx - dy * qy - dz * qz, cw * qx + dx * qw + dy * qz - dz * qy,
                              cw * qy - dx * qz + dy * qw + dz * qx, cw * qz + dx * qy - dy * qx + dz * qw)
            vx, vy = vx - cz * vy, vy + cz * vx
            ra0, ra3, rv0, rv3 = ra0 - cz * ra3, ra3 + cz * ra0, rv0 - cz * rv3, rv3 + cz * rv0
            ra1, ra4, rv1, rv4 = ra1 - cz * ra4, ra4 + cz * ra1, rv1 - cz * rv4, rv4 + cz * rv1
            ra2, ra5, rv2, rv5 = ra2 - cz * ra5, ra5 + cz * ra2, rv2 - cz * rv5, rv5 + cz * rv2

        # zero-rotation channel at rest: reads "no rotation since rest began"; corrects the attitude
        # (body frame) and the whole gyro bias
        q00, q01, q11, rr, kal, k1r, k2r = restc
        if rest:
            if not was_rest:
                r00, r01 = hold_var, 0.0                    # a new rest: the rotation since it began is zero
                # the rest's first reading of the bias (the detector's low-passed rate) against the bias known so
                # far: an error beyond the variance the random walk left it (a bias changed by a temperature step)
                # is the variance the bias now has (its moment estimate, the low-pass's noise removed)
                d2 = (glx - bx) * (glx - bx) + (gly - by) * (gly - by) + (glz - bz) * (glz - bz)
                r11 = max(r11, d2 / 3.0 - lp_var)
            if kal:
                den = r00 + rr
                k1r, k2r = r00 / den, r01 / den
                r00, r01, r11 = (1.0 - k1r) * r00, (1.0 - k1r) * r01, r11 - k2r * r01
                r11 = r11 if r11 > 0.0 else 0.0   # a variance, not negative by rounding
            e1, e2, e3 = -px, -py, -pz
            px += k1r * e1
            py += k1r * e2
            pz += k1r * e3
            hx, hy, hz = 0.5 * k1r * e1, 0.5 * k1r * e2, 0.5 * k1r * e3
            ang_r = math.sqrt(hx * hx + hy * hy + hz * hz)
            if ang_r > 1e-12:
                sc = math.sin(ang_r) / ang_r
                cw = math.cos(ang_r)
            else:
                sc, cw = 1.0, 1.0
            dx, dy, dz = sc * hx, sc * hy, sc * hz
            qw, qx, qy, qz = (qw * cw - qx * dx - qy * dy - qz * dz, qw * dx + qx * cw + qy * dz - qz * dy,
                              qw * dy - qx * dz + qy * cw + qz * dx, qw * dz + qx * dy - qy * dx + qz * cw)
            bx -= k2r * e1
            by -= k2r * e2
            bz -= k2r * e3
            r00, r01, r11 = r00 + 2.0 * T * r01 + T * T * r11 + q00, r01 + T * r11 + q01, r11 + q11
            # the bias is now known to the zero-rotation channel's variance: so it is to the others
            t00, t01 = tilt[3], 0.0
            ex = ey = ez = 0.0
            if r11 < t11:
                t11 = r11
            if r11 < h11:
                h01 *= math.sqrt(r11 / h11)
                h11 = r11
        else:
            r11 += q11
        n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
        out.append((qw, qx, qy, qz))
    s[:] = (qw, qx, qy, qz, bx, by, bz, vx, vy, ex, ey, ez, ra0, ra1, ra2, ra3, ra4, ra5,
            rv0, rv1, rv2, rv3, rv4, rv5, px, py, pz, glx, gly, glz, flx, fly, flz,
            gdev, fdev, gnoise, fnoise, gfloor, ffloor, lax, lay, laz, grest, frest, rest_time, r00, r01, r11,
            t00, t01, t11, h00, h01, h11, norm_lp, dip_lp, norm_ref, dip_ref,
            ref_n, norm_new, dip_new, new_n, new_time, new_turn, dist_time, disturbed, level, acc_time, tilt_n, tilt_f,
            lgx, lgy, lgz, started, miss_g, miss_a, miss_m, gap_n)
    return jv
