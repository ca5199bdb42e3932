"""AttitudeFilter on synthetic data, one mechanism per test: streaming, rest and bias, magnetic and
acceleration disturbances, the velocity (inertial-frame) tilt channel, bad input, the designed tables."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cfdesign import rotations as rot
from cfdesign.errors import AttitudeInputError, CfdesignError
from cfdesign.nav import (
    AttitudeFilter,
    AttitudeParams,
    EulerAttitudeFilter,
    design_attitude,
    design_channel,
    estimate_attitude,
    mps_euler,
    mps_quaternion,
)
from cfdesign.nav.attitude_filter import GRAVITY, STATE_FIELDS
from cfdesign.nav.triad import triad_quaternion

RATE = 100.0
FUZZ = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
FIELD = np.array([0.0, 20.0, -40.0])        # µT, ENU: north and down (dip 63°)
BIAS = np.array([0.01, -0.02, 0.015])       # rad/s


def motion(n, rate=RATE, still_s=0.0, amplitude=(2.5, 0.8, 0.7)):
    """A sensor at rest for ``still_s`` and then turning smoothly (rates up to ~1 rad/s): quaternions (N, 4)."""
    t = np.arange(n) / rate
    ramp = np.clip((t - still_s) / 2.0, 0.0, 1.0)[:, None]
    euler = ramp * np.column_stack([amplitude[0] * np.sin(0.3 * t), amplitude[1] * np.sin(0.5 * t + 0.4),
                                    amplitude[2] * np.sin(0.7 * t + 1.1)])
    return rot.normalize(rot.from_euler(euler + np.array([0.4, 0.0, 0.0])))


def imu(q, rate=RATE, field=None, accel_enu=None, bias=BIAS, seed=1, noise=(0.003, 0.03, 0.3)):
    """Gyro (rate over each interval + bias + noise), specific force and field readings of an attitude track."""
    rng = np.random.default_rng(seed)
    n = len(q)
    d = rot.multiply(rot.conjugate(q[:-1]), q[1:])
    d *= np.sign(d[:, :1])
    rates = np.vstack([np.zeros((1, 3)), 2 * d[:, 1:] * rate])
    gyr = rates + bias + rng.normal(0, noise[0], (n, 3))
    R = rot.to_matrix(q)
    up = np.tile([0.0, 0.0, GRAVITY], (n, 1)) + (0.0 if accel_enu is None else accel_enu)
    acc = np.einsum("nji,nj->ni", R, up) + rng.normal(0, noise[1], (n, 3))
    field = np.tile(FIELD, (n, 1)) if field is None else field
    mag = np.einsum("nji,nj->ni", R, field) + rng.normal(0, noise[2], (n, 3))
    return gyr, acc, mag


def errors(est, q):
    """Heading and inclination errors (deg) of ``est`` against ``q`` (error in ENU, as BROAD measures)."""
    e = rot.multiply(est, rot.conjugate(q))
    e *= np.sign(e[:, :1])
    heading = np.degrees(2 * np.arctan2(e[:, 3], e[:, 0]))
    incl = np.degrees(2 * np.arccos(np.clip(np.hypot(e[:, 0], e[:, 3]), 0, 1)))
    return heading, incl


# ---------------------------------------------------------------------- streaming
def test_stream_and_batch_agree_and_state_restores():
    q = motion(3000, still_s=5.0)
    gyr, acc, mag = imu(q)
    gyr[700], acc[900], mag[1100] = np.nan, 1e6, np.nan
    batch = AttitudeFilter(RATE).run(gyr, acc, mag)
    f = AttitudeFilter(RATE)
    stream = np.array([f.step(g, a, m) for g, a, m in zip(gyr[:1500], acc[:1500], mag[:1500], strict=True)])
    saved = f.state()
    assert list(saved) == list(STATE_FIELDS)
    g = AttitudeFilter(RATE)
    g.restore(saved)
    rest = np.array([g.step(*row) for row in zip(gyr[1500:], acc[1500:], mag[1500:], strict=True)])
    assert np.abs(np.vstack([stream, rest]) - batch).max() <= 1e-12       # they are identical
    assert g.missing == {"gyr": 1, "acc": 1, "mag": 1}
    with pytest.raises(AttitudeInputError, match="missing qw"):
        g.restore({k: v for k, v in saved.items() if k != "qw"})
    with pytest.raises(AttitudeInputError, match="bx must be finite"):
        g.restore({**saved, "bx": math.nan})


@pytest.fixture(scope="module")
def running_state():
    """The state of a 9D filter 3 s into a rest (every channel's recursion has run)."""
    f = AttitudeFilter(RATE)
    for _ in range(300):
        f.step([0.01, 0.0, 0.0], [0.0, 0.1, 9.8], [20.0, 0.0, -40.0])
    return f.state()


EXPONENTS = st.sampled_from([-320.0, -1.0, 0.0, 1.0, 99.0, 101.0, 155.0, 200.0, 308.0]) | st.floats(-320, 308)
MAGNITUDE = st.builds(lambda sign, exp: sign * 10.0 ** exp, st.sampled_from([-1.0, 1.0]), EXPONENTS)


# an edited rest-noise estimate (the state's gyro or accelerometer deviation at rest) is warned of, as it should be
@pytest.mark.filterwarnings("ignore:(gyr|acc). at rest the .* is about:UserWarning")
@FUZZ
@given(edits=st.dictionaries(st.sampled_from(STATE_FIELDS), MAGNITUDE | st.sampled_from([0.0, 0.5, 1.0, 2.0, 3.0]),
                             min_size=1, max_size=8), nine=st.booleans())
@example(edits={"r11": 1e99, "qw": -1e-320, "px": -1.0}, nine=False)  # its run left r01² one ulp over r00 r11
def test_an_edited_state_is_refused_by_name_or_runs_finite(running_state, edits, nine):
    """A state no run reaches (a bias of 1e308, a covariance that is not positive semi-definite, a
    negative counter, a level out of range) was restored as it was, and the next steps raised
    ValueError (math domain error), ZeroDivisionError or filled the state with inf and NaN."""
    f = AttitudeFilter(RATE, magnetometer=nine)
    before = f.state()
    try:
        f.restore({**running_state, **edits})
    except AttitudeInputError as exc:
        assert f.state() == before
        assert any(name in str(exc) for name in edits)
        return
    rng = np.random.default_rng(0)
    still = np.array([0.01, 0.0, 0.0, 0.0, 0.1, 9.8, 20.0, 0.0, -40.0])
    for k in range(60):                 # still on, then moving
        row = still + (1e-4 if k < 30 else 0.3) * rng.standard_normal(9)
        q = f.step(row[:3], row[3:6], row[6:])
    assert all(map(math.isfinite, f.state().values())) and abs(math.hypot(*q) - 1.0) < 1e-12
    AttitudeFilter(RATE, magnetometer=nine).restore(f.state())


BAD_SAMPLE = st.sampled_from([math.nan, math.inf, -math.inf, 0.0, 1e308, 1e-320, 1e154, 1e-160, 99.99, 1e3])


@pytest.mark.filterwarnings("ignore::UserWarning")  # random readings: the unit and noise checks speak up
@FUZZ
@given(seed=st.integers(0, 2**32 - 1), rate=st.sampled_from([1e-3, 0.1, 100.0, 1e6]),
       params=st.fixed_dictionaries({}, optional={"gyro_range_rps": st.sampled_from([1.0, 5.0]),
                                                  "gyro_bias_std0": st.sampled_from([0.0, 1e-6, 10.0]),
                                                  "max_speed_mps": st.sampled_from([1e-3, 0.1]),
                                                  "max_accel_time_s": st.sampled_from([0.01, 1.0])}),
       bad=st.lists(st.tuples(st.integers(0, 199), st.integers(0, 8), BAD_SAMPLE), max_size=20))
def test_every_state_a_run_leaves_restores(seed, rate, params, bad):
    """restore's bounds hold for every state the step leaves: a bias beyond the gyro's range (a
    tilt or heading channel learns one from readings at the range) and field norms to 1e154 are
    states a run reaches, and are restored."""
    rng = np.random.default_rng(seed)
    rows = np.hstack([rng.normal(0, 3.0, (200, 3)), rng.normal(0, 30.0, (200, 3)), rng.normal(0, 40.0, (200, 3))])
    rows[:, 5] += 9.8
    rows[:80:2, :3], rows[:80:2, 3:6] = 1e-3, [0.0, 0.0, 9.8]          # stretches of rest
    for k, j, value in bad:
        rows[k, j] = value
    f = AttitudeFilter(rate, **params)
    for k, row in enumerate(rows):
        f.step(row[:3], row[3:6], row[6:])
        if k % 50 == 49:
            AttitudeFilter(rate, **params).restore(f.state())


def test_six_d_ignores_the_field_and_holds_heading_at_rest():
    q = motion(6000, still_s=60.0)                                    # 60 s still
    gyr, acc, mag = imu(q)
    f = AttitudeFilter(RATE, magnetometer=False)
    est = f.run(gyr, acc, None)
    assert np.array_equal(est, AttitudeFilter(RATE, magnetometer=False).run(gyr, acc, mag * 0 + 5.0))
    heading, _ = errors(est, q)
    assert np.ptp(heading[300:]) < 0.3            # a 0.015 rad/s vertical bias: 50° a minute without the rest channel
    with pytest.raises(AttitudeInputError, match="mag is missing"):
        AttitudeFilter(RATE).run(gyr, acc, None)


# ---------------------------------------------------------------------- rest and bias
def test_rest_is_detected_and_the_bias_learnt_at_rest():
    q = motion(1500, still_s=8.0)
    gyr, acc, mag = imu(q)
    out = AttitudeFilter(RATE).run(gyr, acc, mag, details=True)
    t = np.arange(len(q)) / RATE
    assert not out.rest[t < 1.4].any() and out.rest[(t > 1.7) & (t < 7.9)].all()   # rest_time_s 1.5 s
    assert not out.rest[t > 9.0].any()
    assert np.abs(out.bias[int(6 * RATE)] - BIAS).max() < 1e-3            # 0.06 °/s after 4.5 s of rest
    off = AttitudeFilter(RATE, rest_detection=False).run(gyr, acc, mag, details=True)
    assert not off.rest.any() and np.abs(off.bias[int(6 * RATE)] - BIAS).max() > 3e-3


@pytest.mark.parametrize("magnetometer", [True, False])
def test_a_rest_relearns_a_bias_that_stepped_during_the_motion(magnetometer):
    """20 s at rest, 40 s of motion in which the bias steps by 0.5 deg/s (a temperature step: ~70 times
    what the bias random walk lets it move in that time), then a rest: the rest's first reading of the bias
    widens the prior it contradicts, so the rest learns the new bias in seconds, as it learnt the first."""
    q = motion(6000, still_s=20.0)
    q = np.vstack([q, np.tile(q[-1], (1000, 1))])                    # a rest from 60 s
    step = np.radians(0.5) * np.array([0.6, -0.64, 0.48])
    gyr, acc, mag = imu(q)
    gyr[5000:] += step                                              # at 50 s
    out = AttitudeFilter(RATE, magnetometer=magnetometer).run(gyr, acc, mag if magnetometer else None, details=True)
    t = np.arange(len(q)) / RATE
    start = t[np.argmax(out.rest & (t > 60.0))]                      # the stop's transient settles first
    assert 61.5 < start < 67.0 and out.rest[t >= start].all()
    # 2 s into the rest the bias is the new one to 0.03 deg/s (from the prior the random walk left: 0.23 deg/s off)
    assert np.degrees(np.abs(out.bias[int((start + 2.0) * RATE)] - BIAS - step).max()) < 0.03


# ---------------------------------------------------------------------- magnetic disturbance
def magnet_run(**params):
    q = motion(9000, still_s=5.0)
    field = np.tile(FIELD, (len(q), 1))
    field[4000:6000] += [18.0, -6.0, 12.0]                             # a magnet for 20 s
    gyr, acc, mag = imu(q, field=field)
    return q, AttitudeFilter(RATE, **params).run(gyr, acc, mag, details=True)


def test_magnetic_disturbance_is_rejected_and_heading_reconverges_without_a_jump():
    q, out = magnet_run()
    heading, _ = errors(out.quaternion, q)
    assert out.mag_disturbed[4020:6000].mean() > 0.95 and not out.mag_disturbed[6100:].any()
    assert not out.mag_disturbed[1000:4000].any()
    assert np.abs(heading[4000:6000]).max() < 1.0                     # the gyro carries the heading
    assert np.abs(heading[7000:]).max() < 1.0
    assert np.abs(np.diff(heading))[5950:6500].max() < 0.02           # re-converges without a jump (deg/sample)
    _, off = magnet_run(mag_rejection=False)
    assert np.abs(errors(off.quaternion, q)[0][4000:6000]).max() > 10.0


def test_a_new_homogeneous_field_is_accepted_after_a_while_of_motion():
    q = motion(9000, still_s=3.0)
    turn = np.radians(20.0)
    moved = 1.1 * np.array([math.sin(turn) * 20.0, math.cos(turn) * 20.0, -40.0])   # another room
    field = np.tile(FIELD, (len(q), 1))
    field[2000:] = moved
    gyr, acc, mag = imu(q, field=field)
    out = AttitudeFilter(RATE).run(gyr, acc, mag, details=True)
    assert out.mag_disturbed[2050:5900].all()                          # 40 s (mag_new_field_s) ...
    assert not out.mag_disturbed[6100:].any()                          # ... then the new field is the reference
    heading, _ = errors(out.quaternion, q)
    assert abs(np.median(heading[8500:]) - 20.0) < 2.0                  # it now follows the new north


@pytest.mark.parametrize("rate", [100.0, 400.0])
def test_a_still_sensor_does_not_accept_a_magnet_beside_it_at_any_rate(rate):
    """A magnet put down beside a still sensor is not a new homogeneous field: it is accepted only after
    the sensor turned (``mag_new_field_rotation_rad``, here 0.7 rad within ``mag_new_field_s`` 15 s).
    The turn was summed from the raw rate, whose noise adds up with the square root of the rate: at
    400 Hz (gyro 2e-3 rad/s/sqrt(Hz)) the noise alone turned the still sensor by about 1 rad and the
    magnet's field became the reference; at 100 Hz by 0.5 rad, and it did not."""
    rng = np.random.default_rng(3)
    n, density = round(25.0 * rate), 2e-3
    gyr = rng.normal(0.0, density * math.sqrt(rate), (n, 3))
    acc = np.tile([0.0, 0.0, GRAVITY], (n, 1)) + rng.normal(0.0, 3e-3 * math.sqrt(rate), (n, 3))
    mag = np.tile(FIELD, (n, 1))
    mag[round(5.0 * rate):, 0] += 15.0                                     # the magnet, from 5 s on
    out = AttitudeFilter(rate, gyro_noise_density=density, mag_new_field_s=15.0,
                         mag_new_field_rotation_rad=0.7).run(gyr, acc, mag, details=True)
    assert out.mag_disturbed[round(6.0 * rate):].all()


# ---------------------------------------------------------------------- acceleration disturbance
def test_taps_and_vibration_leave_the_tilt_alone():
    q = motion(4000, still_s=40.0)
    accel = np.zeros((len(q), 3))
    accel[1000:3000:50, 0] = 150.0                                    # taps: +150 m/s² ...
    accel[1001:3000:50, 0] = -150.0                                   # ... and the rebound (no net velocity)
    accel[1000:3000, 2] += 3.0 * np.sin(2 * np.pi * 40.0 * np.arange(2000) / RATE)   # vibration
    gyr, acc, mag = imu(q, accel_enu=accel)
    _, incl = errors(AttitudeFilter(RATE).run(gyr, acc, mag), q)
    assert incl[1000:].max() < 0.5
    _, classic = errors(AttitudeFilter(RATE, inertial_tilt=False, rest_detection=False).run(gyr, acc, mag), q)
    assert classic[1000:].max() > 1.0


def still_run(magnetometer, shock=None, n=3000, given=False, **params):
    """A still sensor (``n`` samples at 100 Hz, gyro bias and noise) with ``shock = (sample, m/s² on x, samples)``
    added to its specific force (``given``: the filter started from the true attitude): the attitude estimates
    (N, 4)."""
    q = rot.normalize(np.tile(rot.from_euler(np.array([[0.3, -0.2, 1.0]]))[0], (n, 1)))
    gyr, acc, mag = imu(q)
    if shock is not None:
        k, size, samples = shock
        acc[k:k + samples, 0] += size
    f = AttitudeFilter(RATE, magnetometer=magnetometer, initial=q[0] if given else None, **params)
    return f.run(gyr, acc, mag if magnetometer else None)


def turned(a, b):
    """The angle (deg) between the attitudes of ``a`` and ``b`` (N, 4), sample by sample."""
    return np.degrees(2 * np.arccos(np.clip(np.abs((a * b).sum(axis=1)), 0.0, 1.0)))


@pytest.mark.parametrize("magnetometer", [True, False])
def test_a_shock_of_one_or_a_few_samples_barely_moves_the_attitude(magnetometer):
    clean = still_run(magnetometer)
    for shock, limit in (((1500, 200.0, 1), 0.5), ((1500, 100.0, 3), 1.0)):
        assert turned(still_run(magnetometer, shock), clean)[1500:].max() < limit
        # the same shock taken as a specific force (no clipping) turns the attitude by degrees
        unclipped = still_run(magnetometer, shock, accel_shock_sigma=1e15)
        assert turned(unclipped, clean)[1500:].max() > 2.0


@pytest.mark.parametrize("magnetometer", [True, False])
def test_a_shock_is_clipped_with_a_given_initial_attitude_too(magnetometer):
    """With ``initial`` no start-up runs; its specific forces are counted instead and the clipping starts once
    the start-up's ``1 / tilt_alpha`` (202 at 100 Hz) have been seen.  A shock before that (sample 5) is taken
    whole, as it was before the count (the clipping then never started at all)."""
    clean = still_run(magnetometer, n=1500, given=True)
    shock = (1000, 200.0, 1)                                          # t = 10 s
    assert turned(still_run(magnetometer, shock, n=1500, given=True), clean)[1000:].max() < 0.5
    unclipped = still_run(magnetometer, shock, n=1500, given=True, accel_shock_sigma=1e15)
    assert turned(unclipped, clean)[1000:].max() > 2.0
    early = still_run(magnetometer, (5, 200.0, 1), n=1500, given=True)
    np.testing.assert_array_equal(early, still_run(magnetometer, (5, 200.0, 1), n=1500, given=True,
                                                   accel_shock_sigma=1e15))
    assert turned(early, clean)[5:].max() > 2.0


@pytest.mark.parametrize("given", [False, True])
def test_the_clipping_starts_at_the_same_sample_with_or_without_an_initial_attitude(given):
    """Both start at the first sample ``k`` (from 0) with ``k tilt_alpha >= 1`` (sample 202 at 100 Hz): a shock
    there is clipped, one a sample sooner is taken whole (the same run as with the clipping off)."""
    alpha = AttitudeFilter(RATE).design.constants["tilt_alpha"]
    first = math.ceil(1.0 / alpha)
    for k, clipped in ((first - 1, False), (first, True)):
        est = still_run(False, (k, 200.0, 1), n=first + 20, given=given)
        unclipped = still_run(False, (k, 200.0, 1), n=first + 20, given=given, accel_shock_sigma=1e15)
        assert np.array_equal(est, unclipped) != clipped


def test_an_initial_attitude_takes_gravitys_norm_when_its_count_ends():
    """With ``initial`` the start-up that measures gravity's norm (``tilt_f``, the tilt-error test's reference)
    does not run; it is taken from the low-passed specific force when the count of ``1 / tilt_alpha`` ends
    (it stayed 0, so the test that restarts a tilt seen through an error could never pass)."""
    q0 = rot.from_euler(np.array([[0.3, -0.2, 1.0]]))[0]
    f = AttitudeFilter(RATE, initial=q0, magnetometer=False)
    first = math.ceil(1.0 / f.design.constants["tilt_alpha"])
    up = rot.rotate(rot.conjugate(q0[None, :]), np.array([[0.0, 0.0, 9.81]]))[0]  # gravity in the body frame
    for k in range(first + 5):
        f.step([0.0, 0.0, 0.0], up)
        if k == first - 3:
            assert f.state()["tilt_f"] == 0.0
    assert f.state()["tilt_f"] == pytest.approx(9.81, rel=1e-3)


def test_a_state_saved_during_the_count_of_an_initial_attitude_restores():
    """``tilt_n`` counts down from 0 with ``initial``: such a state restores and continues the run unchanged;
    one below the count's end (``-1 / tilt_alpha``, 202 at 100 Hz) is refused by name."""
    q0 = rot.from_euler(np.array([[0.3, -0.2, 1.0]]))[0]
    f, g = AttitudeFilter(RATE, initial=q0), AttitudeFilter(RATE, initial=q0)
    for _ in range(50):
        f.step([0.0, 0.0, 0.0], [0.0, 0.0, GRAVITY])
    assert f.state()["tilt_n"] == -50.0
    g.restore(f.state())
    assert g.step([0.1, 0.0, 0.0], [0.0, 0.2, GRAVITY]) == f.step([0.1, 0.0, 0.0], [0.0, 0.2, GRAVITY])
    with pytest.raises(AttitudeInputError, match=r"tilt_n = -300\.0 must be a whole number from -203"):
        g.restore({**f.state(), "tilt_n": -300.0})


@pytest.mark.parametrize("seconds", [0.1, 0.5])
def test_a_genuine_tilt_change_is_followed_as_without_the_shock_clipping(seconds):
    """30 deg about x in ``seconds`` (gyro and accelerometer both see it), between two rests."""
    t = np.arange(2000) / RATE
    angle = np.radians(30.0) * np.clip((t - 10.0) / seconds, 0.0, 1.0)
    q = rot.normalize(rot.from_euler(np.column_stack([angle, np.zeros_like(t), np.zeros_like(t)])))
    gyr, acc, mag = imu(q)
    for magnetometer in (True, False):
        m = mag if magnetometer else None
        est = AttitudeFilter(RATE, magnetometer=magnetometer).run(gyr, acc, m)
        unclipped = AttitudeFilter(RATE, magnetometer=magnetometer, accel_shock_sigma=1e15).run(gyr, acc, m)
        assert turned(est, unclipped).max() < 0.05
        _, incl = errors(est, q)
        assert incl[1000:].max() < 0.5


def test_sustained_acceleration_weights_the_tilt_corrections_down():
    """Once the integrated speed passes max_speed_mps (4 m/s), the velocity channel runs its
    disturbance designs: a sustained acceleration above ~4 m/s² no longer pulls the tilt (below
    that, the default tilt bandwidth absorbs it before the speed grows: 18° either way at 3 m/s²)."""
    q = motion(4000, still_s=10.0, amplitude=(0.5, 0.1, 0.1))
    accel = np.zeros((len(q), 3))
    accel[1500:2300, 0] = 6.0                                          # a vehicle speeding up hard for 8 s
    accel[2300:3100, 0] = -6.0                                         # and braking
    gyr, acc, mag = imu(q, accel_enu=accel)
    out = AttitudeFilter(RATE).run(gyr, acc, mag, details=True)
    off = AttitudeFilter(RATE, accel_rejection=False).run(gyr, acc, mag, details=True)
    assert out.accel_level[1500:3100].max() >= 2 and (out.tilt_weight[1500:3100] < 1).any()
    assert not off.accel_level.any()
    _, incl_on = errors(out.quaternion, q)
    _, incl_off = errors(off.quaternion, q)
    assert incl_on[1500:3200].max() < 0.3 * incl_off[1500:3200].max()    # measured 7° against 37°


def test_fast_hand_strokes_do_not_weight_the_tilt_down():
    """Hand strokes faster than max_speed_mps (velocity 5 m/s x 1 Hz east, half that north: 0.8 m
    of travel) pass it for under max_reach_m / max_speed_mps (0.25 s) at a time: the levels wait
    for a speed that lasts. Engaged at once, they weighted the fast half of each stroke down and
    turned the zero-mean motion into a tilt error (measured 2.3 deg RMS against 0.9)."""
    q = motion(6000, still_s=10.0)
    t = np.arange(len(q)) / RATE
    on = (t > 12.0) * 2 * np.pi * 5.0
    accel = np.column_stack([on * np.cos(2 * np.pi * t), 0.5 * on * np.cos(2 * np.pi * t + 0.7), np.zeros(len(q))])
    gyr, acc, mag = imu(q, accel_enu=accel)
    held = AttitudeFilter(RATE).run(gyr, acc, mag, details=True)
    at_once = AttitudeFilter(RATE, max_reach_m=1e-3).run(gyr, acc, mag, details=True)
    rms = [np.sqrt(np.mean(errors(out.quaternion, q)[1][2000:] ** 2)) for out in (held, at_once)]
    assert held.speed.max() > 5.0 and at_once.accel_level.max() >= 2
    assert rms[0] < 0.5 * rms[1]


def test_a_tilt_error_does_not_lock_the_acceleration_levels():
    """A 6.6 deg/s gyro bias from a moving start tilts the estimate, the integrated speed passes
    max_speed_mps and the levels weight the tilt corrections down; the speed then grew without end
    (310 m/s, level 5 to the last sample, inclination 104 deg RMS, with 5 deg/s). After
    max_accel_time_s the velocity channel restarts on its motion design and corrects the tilt.
    (5 deg/s, once enough to engage the levels, is now learnt before they engage, and so is 6 since the
    tilt channel reads the corrections through the lagged attitude; 7.2 deg/s still ends on the levels.)"""
    q = motion(9000, still_s=0.0)
    gyr, acc, _ = imu(q, bias=np.radians([6.6, -5.5, 6.6]))
    out = AttitudeFilter(RATE, magnetometer=False).run(gyr, acc, None, details=True)
    assert out.accel_level.max() >= 1                                     # the levels did engage
    assert out.speed[-3000:].max() < 8.0 and not out.accel_level[-3000:].any()   # measured 3.6 m/s
    _, incl = errors(out.quaternion, q)
    assert np.sqrt(np.mean(incl[-3000:] ** 2)) < 25.0                     # measured 5.3 deg


def test_the_velocity_channel_rides_out_translation():
    """Back-and-forth translation (bounded velocity) while turning: the inertial-frame velocity
    channel keeps the tilt within a bound (so does the classic filter on the instantaneous
    accelerometer, with these gains and this fast translation)."""
    q = motion(6000, still_s=3.0)
    t = np.arange(len(q)) / RATE
    accel = np.column_stack([2.0 * np.sin(3.0 * t), 2.0 * np.cos(2.3 * t), 1.5 * np.sin(2.0 * t)]) * (t > 5)[:, None]
    gyr, acc, mag = imu(q, accel_enu=accel)
    _, incl = errors(AttitudeFilter(RATE).run(gyr, acc, mag), q)
    _, classic = errors(AttitudeFilter(RATE, inertial_tilt=False).run(gyr, acc, mag), q)
    assert np.sqrt(np.mean(incl[1000:] ** 2)) < 0.75                        # measured 0.45°
    assert np.sqrt(np.mean(classic[1000:] ** 2)) < 0.75                     # measured 0.45°


def test_the_inertial_frame_tilt_holds_while_turning():
    """Turning at up to ~1 rad/s with no translation: the specific force low-passed in the
    inertial frame gives the tilt (0.035° measured); the classic filter, correcting towards
    each body-frame reading, lags the rotation (0.45°)."""
    q = motion(6000, still_s=3.0)
    gyr, acc, mag = imu(q)
    _, incl = errors(AttitudeFilter(RATE).run(gyr, acc, mag), q)
    _, classic = errors(AttitudeFilter(RATE, inertial_tilt=False).run(gyr, acc, mag), q)
    ours, theirs = np.sqrt(np.mean(incl[1000:] ** 2)), np.sqrt(np.mean(classic[1000:] ** 2))
    assert ours < 0.1 and theirs > 3 * ours, (ours, theirs)


def coning(rate, seconds=5.0, cone=0.3, hz=2.0, fine=8):
    """A coning motion (the body's x axis sweeping a cone of half-angle ``cone`` about ENU z at ``hz``):
    the gyro as an integrating IMU reads it (each reading the body rate averaged over its interval, no
    noise, no bias), the specific force at each interval's end, and the attitude there."""
    w = 2 * math.pi * hz
    n = round(seconds * rate)
    c, s = math.cos(cone / 2), math.sin(cone / 2)

    def track(t):
        return np.stack([np.full_like(t, c), s * np.cos(w * t), s * np.sin(w * t), 0 * t], axis=1)

    t = (np.arange(n * fine) + 0.5) / (rate * fine)
    dq = np.stack([0 * t, -s * w * np.sin(w * t), s * w * np.cos(w * t), 0 * t], axis=1)
    gyr = (2 * rot.multiply(rot.conjugate(track(t)), dq)[:, 1:]).reshape(n, fine, 3).mean(axis=1)
    q = track(np.arange(1, n + 1) / rate)
    acc = np.einsum("nji,j->ni", rot.to_matrix(q), [0.0, 0.0, GRAVITY])
    return gyr, acc, q


def test_the_attitude_does_not_drift_with_the_rate_under_coning():
    """A coning motion read by an integrating gyro (rates averaged over each interval) at 50 and 400 Hz,
    6D (heading the gyro's alone): the heading must not drift with the sample interval.  Integrated one
    averaged rate at a time, the attitude drifted by 1.9° RMS over 5 s at 50 Hz (0.03° at 400 Hz); with
    the two-sample coning term 0.005° and 0.0001°."""
    rms = {}
    for rate in (50.0, 400.0):
        gyr, acc, q = coning(rate)
        est = AttitudeFilter(rate, magnetometer=False, initial=q[0]).run(gyr, acc)
        heading, incl = errors(est, q)
        rms[rate] = math.sqrt(np.mean(heading ** 2) + np.mean(incl ** 2))
    assert rms[50.0] < 0.1 and abs(rms[50.0] - rms[400.0]) < 0.1, rms


# ---------------------------------------------------------------------- bad input
def test_impossible_and_non_finite_samples_are_missing_and_counted():
    q = motion(3000, still_s=5.0)
    gyr, acc, mag = imu(q)
    clean = AttitudeFilter(RATE).run(gyr, acc, mag)
    bad_acc, bad_gyr = acc.copy(), gyr.copy()
    bad_acc[1000] = [1e6, 0.0, 0.0]                                    # one impossible specific force
    bad_gyr[1200] = [np.nan, 0.0, 0.0]
    bad_gyr[1300] = [5e3, 0.0, 0.0]                                    # one impossible rate
    f = AttitudeFilter(RATE)
    est = f.run(bad_gyr, bad_acc, mag)
    assert f.missing == {"gyr": 2, "acc": 1, "mag": 0}
    assert np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(est * clean, axis=1)), 0, 1))).max() < 0.3
    assert np.isfinite(estimate_attitude(np.full((50, 3), np.nan), np.full((50, 3), np.nan), None, RATE)).all()


NOT_REAL = {"text": lambda a: a.astype(str), "complex": lambda a: a + 1j, "None": lambda a: [[None, *r[1:]] for r in a],
            "text row": lambda a: "0.1"}


@pytest.mark.parametrize("form", sorted(NOT_REAL))
@pytest.mark.parametrize("which", ["gyr", "acc", "mag"])
@pytest.mark.parametrize("api", ["step", "run", "estimate_attitude"])
def test_readings_that_are_not_real_numbers_are_named_and_change_nothing(form, which, api):
    """Text was parsed ('0.1' ran as 0.1; step took the string '123' as the rates 1, 2, 3), complex
    readings lost their imaginary part (a numpy warning) and None ran as NaN in run but was refused
    by step with a message naming none of the arguments."""
    arrays = {"gyr": np.zeros((3, 3)), "acc": np.tile([0.0, 0.0, 9.8], (3, 1)), "mag": np.tile(FIELD, (3, 1))}
    arrays[which] = NOT_REAL[form](arrays[which]) if form != "text row" or api == "step" else "0.1"
    f = AttitudeFilter(RATE)
    before = f.state()
    with pytest.raises(AttitudeInputError, match=rf"^{which}\b"):
        if api == "step":
            f.step(*(arrays[k] if form == "text row" and k == which else arrays[k][0] for k in ("gyr", "acc", "mag")))
        elif api == "run":
            f.run(arrays["gyr"], arrays["acc"], arrays["mag"])
        else:
            estimate_attitude(arrays["gyr"], arrays["acc"], arrays["mag"], RATE)
    assert f.state() == before


def test_readings_of_any_real_type_step_as_their_floats():
    """ints, numpy ints and floats of any width, Fractions and object arrays of numbers are their values."""
    from fractions import Fraction

    rows = [([0, 0, 1], [0, 0, 10], [20, 0, -40]), (np.array([0.0, 0.0, 1.0], dtype=np.float32), np.int64([0, 0, 10]),
                                                   [Fraction(20), np.int8(0), -40.0])]
    results = []
    for gyr, acc, mag in rows:
        f = AttitudeFilter(RATE)
        results.append(f.step(gyr, acc, mag) + f.step(gyr, acc, mag))
        assert all(type(v) is float for v in f.state().values())
    assert results[0] == results[1]
    obj, acc = np.array([[0, 0, 1], [0, 0, 1]], dtype=object), np.tile([0, 0, 10], (2, 1))
    assert np.array_equal(AttitudeFilter(RATE, magnetometer=False).run(obj, acc),
                          AttitudeFilter(RATE, magnetometer=False).run(obj.astype(float), acc.astype(float)))


def test_huge_readings_are_counted_without_a_numpy_warning():
    """1e200 m/s^2 or 1e300 rad/s overflows the unit check's norm: the step counts it as missing;
    run() printed numpy's 'overflow encountered in multiply' first."""
    import warnings

    gyr, acc = np.zeros((20, 3)), np.tile([0.0, 0.0, 9.81], (20, 1))
    gyr[5], acc[6] = [1e300, 1e300, 0.0], [1e200, 0.0, 0.0]
    f = AttitudeFilter(RATE, magnetometer=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.run(gyr, acc, None)
    assert f.missing["gyr"] == 1 and f.missing["acc"] == 1


@pytest.mark.parametrize("rate", [1e12, 0.0, -5.0, math.nan, math.inf, "fast", True, 1e-300])
def test_bad_rates_are_refused_before_anything_is_allocated(rate, monkeypatch):
    import cfdesign.nav.attitude_filter as module

    def no_design(*args, **kwargs):
        raise AssertionError("a design was started for a bad rate")

    monkeypatch.setattr(module, "design_attitude", no_design)
    with pytest.raises(AttitudeInputError, match="rate_hz") as err:
        estimate_attitude(np.zeros((10, 3)), np.zeros((10, 3)), None, rate)
    assert "\n" not in str(err.value)
    with pytest.raises(AttitudeInputError, match="rate_hz"):
        AttitudeFilter(rate)


@pytest.mark.parametrize("kwargs, match", [
    ({"declination_rad": math.nan}, "declination_rad must be finite"),
    ({"declination_rad": 4.0}, "declination_rad must be within"),
    ({"gyro_noise_density": -1.0}, "gyro_noise_density must be a positive"),
    ({"heading_noise_density": "x"}, "heading_noise_density must be a number"),
    ({"heading_bias_std0": -1e-4}, "heading_bias_std0 must be from 0 to 1e15"),
    ({"mag_rejection": 1}, "mag_rejection must be True or False"),
    ({"no_such_option": 1.0}, "unknown parameter"),
])
def test_bad_parameters_are_refused(kwargs, match):
    with pytest.raises(CfdesignError, match=match):
        AttitudeFilter(RATE, **kwargs)


# ---------------------------------------------------------------------- the designed tables
def test_channels_are_designed_tables_and_the_velocity_channel_is_a_butterworth():
    design = design_attitude(RATE)
    assert set(design.tables) >= {"velocity", "velocity_rest", "tilt", "heading", "rest"}
    for table in design.tables.values():
        assert table.structure == "cf2" and math.isclose(table.sample_time_s, 1 / RATE)
    p = AttitudeParams()
    quiet = design_attitude(RATE, AttitudeParams(accel_noise_density=1e-6)).tables["velocity"]
    k1, k2 = quiet.gains["k1"], quiet.gains["k2"]
    wn, zeta = math.sqrt(k2 * RATE), k1 * RATE / (2 * math.sqrt(k2 * RATE))
    assert abs(zeta - 1 / math.sqrt(2)) < 0.01
    assert abs(wn / math.sqrt(GRAVITY * p.tilt_drift_density / p.velocity_noise_density) - 1) < 0.05


def kalman_step(channel, p, T=1 / RATE):
    """One update and prediction of a channel's covariance, as the filter's step runs it."""
    q00, q01, q11, r, _, _, _ = channel
    p00, p01, p11 = p
    k1, k2 = p00 / (p00 + r), p01 / (p00 + r)
    a00, a01, a11 = (1 - k1) * p00, (1 - k1) * p01, p11 - k2 * p01
    return (a00 + 2 * T * a01 + T * T * a11 + q00, a01 + T * a11 + q01, a11 + q11), (k1, k2)


def test_the_channels_kalman_recursions_settle_on_the_tables_gains():
    """The channels run their tables' Kalman recursion: the table's DARE covariance is its fixed
    point (so its steady gain is the designed one), and from the bias prior it gets there."""
    design = design_attitude(RATE)
    for name in ("tilt", "heading", "rest"):
        table, channel = design.tables[name], design.channels[name]
        P = np.asarray(table.P[0])
        (p00, p01, p11), (k1, k2) = kalman_step(channel, (P[0, 0], P[0, 1], P[1, 1]))
        assert np.allclose([p00, p01, p11], [P[0, 0], P[0, 1], P[1, 1]], rtol=1e-6), name
        assert np.allclose([k1, k2], [table.gains["k1"], table.gains["k2"]], rtol=1e-6), name
        p = design.priors[name]
        for _ in range(100_000):                                # 1000 s
            p, gains = kalman_step(channel, p)
        assert abs(gains[0] / table.gains["k1"] - 1) < 0.1, name


def test_readings_in_other_units_are_warned_of():
    """An accelerometer in g (median 1) or a gyro in deg/s runs, with a warning naming the unit."""
    rng = np.random.default_rng(0)
    gyr, acc = 0.01 * rng.standard_normal((200, 3)), np.tile([0.0, 0.0, 9.81], (200, 1))
    f = AttitudeFilter(100.0, magnetometer=False)
    with pytest.warns(UserWarning, match="m/s²"):
        f.run(gyr, acc / 9.81)
    with pytest.warns(UserWarning, match="deg/s"):
        f.run(np.degrees(gyr) + 40.0, acc)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.run(gyr, acc)


def test_a_streamed_accelerometer_in_g_is_warned_of_once():
    """``step`` has no median to check: the specific force it starts from, 1 in g, is warned of once (the
    filter runs on; the velocity channel takes m/s², so readings in g weight the tilt 9.8 times down)."""
    import warnings

    f = AttitudeFilter(100.0, magnetometer=False)
    with pytest.warns(UserWarning, match="first specific force is 1; the filter takes m/s²"):
        f.step([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.step([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])                  # once, at the start
        g = AttitudeFilter(100.0, magnetometer=False)
        g.step([0.0, 0.0, 0.0], [0.0, 0.0, math.nan])            # missing: not the start yet
        g.step([0.0, 0.0, 0.0], [0.0, 0.3, 9.8])


def test_a_noisy_first_field_reading_does_not_latch_a_disturbance_at_rest():
    # A still sensor with a magnetometer ten times noisier than BROAD's (3.2 µT per axis per
    # sample on a 44 µT field of dip 69 deg, as in BROAD's lab).  The first reading once seeded
    # the field's low-pass and its
    # reference: one reading off by a few µT froze the reference at the start-up transient, the
    # field was "disturbed" from then on, and at rest no new field can be accepted (it needs the
    # sensor to turn), so the heading ran on the gyro for good.  Now the low-pass starts as the
    # running mean of the readings and the reference is that mean until the low-pass has settled.
    rng = np.random.default_rng(3)
    n, rate = 500, 100.0
    field = np.array([0.0, 16.0, -41.0])
    mag = field + 3.2 * rng.standard_normal((n, 3))
    mag[0] = [0.0, 16.0, -33.0]                                 # a first reading 7.5 µT short, dip 4 deg off
    gyr = np.zeros((n, 3))
    acc = np.tile([0.0, 0.0, GRAVITY], (n, 1))
    out = AttitudeFilter(rate).run(gyr, acc, mag, details=True)
    assert not out.mag_disturbed.any()


def test_a_noisy_first_specific_force_is_not_read_as_gyro_bias():
    # A still sensor with an accelerometer ten times noisier than BROAD's (0.54 m/s² per axis per
    # sample), default noise figures (so no rest is detected) and a field of dip 69 deg.  The first
    # specific force once set the tilt alone: one 5 deg off, the channels read its settling (and the
    # heading it dragged along) as gyro bias from the 1 deg/s prior, the dip drifted, the field was
    # flagged disturbed at rest for good and the heading ran on that bias.  Now the tilt starts as
    # the running mean of the specific forces (for the tilt low-pass's time constant).
    rng = np.random.default_rng(6)
    n, rate = 3000, 100.0
    gyr = 0.003 * rng.standard_normal((n, 3))
    acc = np.array([0.0, 0.0, GRAVITY]) + 0.54 * rng.standard_normal((n, 3))
    acc[0] = GRAVITY * np.array([np.sin(np.radians(5.0)), 0.0, np.cos(np.radians(5.0))])   # 5 deg off
    mag = np.array([0.0, 16.0, -41.0]) + 0.32 * rng.standard_normal((n, 3))
    out = AttitudeFilter(rate).run(gyr, acc, mag, details=True)
    heading, incl = errors(out.quaternion, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)))
    assert np.degrees(np.abs(out.bias[n // 2:]).max()) < 0.3             # measured 0.05 deg/s (was 1.3 about z)
    assert not out.mag_disturbed[n // 2:].any()
    assert np.abs(heading[n // 2:]).max() < 3.0 and incl[n // 2:].max() < 1.5   # 0.4 and 0.3 deg (were 11.5, 1.9)



def test_a_start_in_motion_does_not_take_the_unsettled_dip_as_the_field():
    # A sensor turning from its first sample while pushed sideways (6 m/s² for the first second):
    # the start-up tilt, from the mean of the specific forces, is then several deg off at its end.
    # The field's reference (norm and dip) once started from the first readings, its dip read
    # through that tilt: once the tilt settled the true dip differed from it by more than the
    # tolerance, the field was "disturbed" from then on (77 % of the run) and the heading ran
    # on the gyro.  Now the reference starts when the tilt's start-up is over.  (The tilt channel
    # is off: this test is about the field's reference.)
    n = 2500
    q = motion(n, still_s=-10.0)
    accel = np.zeros((n, 3))
    accel[:100, 0] = 6.0
    gyr, acc, mag = imu(q, accel_enu=accel, bias=np.zeros(3))
    out = AttitudeFilter(RATE, motion_bias=False).run(gyr, acc, mag, details=True)
    heading, _ = errors(out.quaternion, q)
    assert not out.mag_disturbed.any()
    assert np.abs(heading[2000:]).max() < 10.0                                   # 8.5 deg (was 13.6)


def test_a_start_during_motion_takes_the_tilt_of_the_mean_specific_force():
    # A level sensor, not turning, shaken along a line 45 deg from the vertical from its first sample
    # (5 m/s², twice a second): over the start-up's whole shakes its velocity returns to the first
    # one, so the mean specific force is gravity alone, but its direction leans up to 19 deg to one
    # side (pushed up) and 46 deg to the other (dropping).  The start-up once averaged those
    # directions and ended tilted; now it averages the vectors and ends level.
    n = 200
    t = np.arange(n) / RATE
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    accel = 5.0 * np.cos(4 * np.pi * t)[:, None] * np.array([1.0, 0.0, 1.0])
    gyr, acc, _ = imu(q, accel_enu=accel, bias=np.zeros(3), noise=(0.0, 0.0, 0.0))
    est = AttitudeFilter(RATE, magnetometer=False).run(gyr, acc)
    _, incl = errors(est, q)
    assert incl[-1] < 0.05                                      # 1e-14 deg (was 7.1)


def test_the_settling_of_a_start_in_motion_is_not_read_as_gyro_bias():
    # A sensor turning from its first sample, its gyro without bias, and moving sideways at 1 m/s when
    # the filter starts, braking to a stop over the first second: the start-up (the mean specific force
    # over 2 s) ends off by the velocity lost meanwhile, which the velocity channel then removes over
    # its settling time.  The tilt channel once read that settling as gyro bias (0.48 deg/s, from its
    # 1 deg/s prior) and turned the tilt by it again (1.4 deg after 15 s); now it takes the settling
    # as noise of its reading (the larger, the more of it; a bias present from the start is still
    # learnt, test_attitude.py::test_estimate_attitude_converges_with_bias).
    n = 3000
    t = np.arange(n) / RATE
    q = motion(n, still_s=-10.0)
    accel = np.zeros((n, 3))
    accel[:, 0] = -np.exp(-t / 0.3) / 0.3                              # velocity exp(-t / 0.3 s) m/s
    gyr, acc, _ = imu(q, accel_enu=accel, bias=np.zeros(3))
    out = AttitudeFilter(RATE, magnetometer=False).run(gyr, acc, details=True)
    _, incl = errors(out.quaternion, q)
    assert np.degrees(np.abs(out.bias).max()) < 0.4                      # 0.33 deg/s
    assert incl[1500:].max() < 1.2                                       # 0.97 deg


def test_a_field_with_orientation_dependent_error_is_not_read_as_gyro_bias_before_a_rest():
    # A sensor turning from its first sample (no rest to learn the bias from), its magnetometer
    # mounted 3 deg off the gyro's axes: the heading it gives errs by up to ~3 deg, the error
    # changing with the orientation over seconds (as soft iron, misalignment and distortion do).
    # The heading channel once started from the 1 deg/s bias prior and read that error as
    # 0.7 deg/s of gyro bias within 3 s, which turned the tilt by 1.5 deg; now it starts from
    # heading_bias_std0 (the rest and tilt channels learn a large bias fast).
    n = 1000
    q = motion(n, still_s=-10.0, amplitude=(2.5, 1.2, 1.0))
    gyr, acc, mag = imu(q, bias=np.zeros(3))
    mis = rot.to_matrix(rot.from_rotation_vector(np.radians([3.0, 0.0, 0.0])))
    out = AttitudeFilter(RATE).run(gyr, acc, mag @ mis.T, details=True)
    _, incl = errors(out.quaternion, q)
    assert np.degrees(np.abs(out.bias).max()) < 0.2                              # 0.11 deg/s (was 0.73)
    assert incl[300:].max() < 0.5                                                # 0.13 deg (was 1.5)


def test_the_heading_the_tilt_start_up_read_is_reopened_once_the_tilt_has_settled():
    """The fields of the tilt's start-up (its first 2 s, read through a tilt not yet settled and checked against
    no reference) set the heading only until it ends: with the field turned by 40 deg about the vertical for the
    first 1.5 s (a magnet beside a device started in motion), the heading is that field's during the start-up
    and, from half a second after it, the same as with the clean field throughout to 0.1 deg (measured 0.05)."""
    q = motion(int(8 * RATE), still_s=-10.0)
    c, s = np.cos(np.radians(40.0)), np.sin(np.radians(40.0))
    field = np.tile(FIELD, (len(q), 1))
    field[:int(1.5 * RATE)] = FIELD @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    turned, _ = errors(AttitudeFilter(RATE).run(*imu(q, field=field)), q)
    clean, _ = errors(AttitudeFilter(RATE).run(*imu(q)), q)
    assert np.abs(turned - clean)[int(1.0 * RATE):int(1.5 * RATE)].min() > 30.0
    assert np.abs(turned - clean)[int(2.5 * RATE):].max() < 0.1


def test_a_sensor_mounted_otherwise_gives_the_same_attitude_of_the_body():
    # Every reading turned by a fixed rotation R (the sensor mounted otherwise): the filter's
    # attitude of the new frame, turned back by R, is the attitude of the old one, up to the
    # start-up (the first attitude is the shortest turn of the body's up onto ENU up, which
    # depends on the body frame, until the field sets the heading: 0.2 deg at the first sample,
    # 0.002 deg after one second).  Nothing else in the filter may prefer a body axis.
    n = 1500
    q = motion(n, still_s=3.0)
    gyr, acc, mag = imu(q)
    r = rot.from_rotation_vector(np.radians(120.0) * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0))
    turned = [rot.rotate(np.tile(r, (n, 1)), x) for x in (gyr, acc, mag)]
    est = AttitudeFilter(RATE).run(gyr, acc, mag)
    est_turned = AttitudeFilter(RATE).run(*turned)
    back = rot.multiply(est_turned, np.tile(r, (n, 1)))
    e = rot.multiply(back, rot.conjugate(est))
    assert np.degrees(2 * np.arccos(np.clip(np.abs(e[100:, 0]), 0, 1))).max() < 0.01


@pytest.mark.parametrize("scale", [0.01, 1000.0, 1.0 / 44.7])
def test_the_field_in_any_unit_gives_the_same_attitude(scale):
    """The field in Gauss, nT or normalised to the Earth's (any constant scale, with a field change the
    disturbance check must see): only directions, the dip and relative changes of the norm are used,
    so every quaternion is the same (no threshold in µT)."""
    q = motion(3000, still_s=3.0)
    field = np.tile(FIELD, (len(q), 1))
    field[1500:2000] *= 1.3                                                # a disturbance of the norm
    gyr, acc, mag = imu(q, field=field)
    out = AttitudeFilter(RATE).run(gyr, acc, mag, details=True)
    scaled = AttitudeFilter(RATE).run(gyr, acc, mag * scale, details=True)
    assert out.mag_disturbed[1550:1950].all()
    np.testing.assert_array_equal(scaled.mag_disturbed, out.mag_disturbed)
    np.testing.assert_allclose(scaled.quaternion, out.quaternion, rtol=0, atol=1e-9)


EULER_FIGURES = dict(gyro_noise_std=1e-3, gyro_bias_density=1e-5, tilt_noise_std=0.01, heading_noise_std=0.02)


@pytest.mark.parametrize(("name", "call"), [
    ("rate_hz", lambda: EulerAttitudeFilter(1e-300, **EULER_FIGURES)),
    ("rate_hz", lambda: design_channel(1e300, 1e-3, 1e-5, 0.01)),
    ("declination_rad", lambda: EulerAttitudeFilter(50.0, **EULER_FIGURES, declination_rad=math.nan)),
    ("declination_rad", lambda: EulerAttitudeFilter(50.0, **EULER_FIGURES, declination_rad="east")),
    ("gyro_noise_std", lambda: design_channel(100.0, 1e300, 1e-5, 0.01)),
    ("acc", lambda: mps_quaternion("abc", [0.0, 20.0, -40.0])),
    ("mag", lambda: mps_euler([0.0, 0.0, 9.8], [0.0, 20.0])),
    ("b1", lambda: triad_quaternion([0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])),
])
def test_euler_filter_mps_and_triad_name_a_bad_argument(name, call):
    """A NaN declination ran (every yaw correction skipped), a text one raised ValueError, a rate of
    1e-300 or a figure of 1e300 was named as the design's internal field (sensors.rate.rate_hz),
    text or a wrong length in mps_quaternion or triad_quaternion raised numpy's ValueError."""
    with pytest.raises(AttitudeInputError, match=rf"^{name}\b"):
        call()


def test_euler_filter_mps_and_triad_take_impossible_readings_as_missing_without_warnings():
    """A first specific force or field of 1e300, or an infinite body velocity, printed numpy's
    overflow and invalid-value warnings (the MPS of them); a rate of 1e300 ran as a rate.  Readings
    beyond the reading limit are missing as non-finite ones are, and the MPS of an unusable vector
    is NaN, as documented, in silence."""
    import warnings

    n = 200
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 9.8], (n, 1)), np.tile([0.0, 20.0, -40.0], (n, 1))
    clean = EulerAttitudeFilter(50.0, **EULER_FIGURES).run(gyr, acc, mag).euler
    bad_gyr, bad_acc, bad_mag, vel = gyr.copy(), acc.copy(), mag.copy(), np.zeros((n, 3))
    bad_acc[0], bad_mag[0], bad_gyr[50], vel[60] = 1e300, -1e300, 1e300, np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = EulerAttitudeFilter(50.0, **EULER_FIGURES).run(bad_gyr, bad_acc, bad_mag, velocity_body=vel).euler
        assert np.isfinite(est).all() and np.abs(est[-1] - clean[-1]).max() < 1e-3
        for acc_row in ([0.0, 0.0, 0.0], [math.inf, 0.0, 1.0], [math.nan, 0.0, 1.0]):
            assert np.isnan(mps_quaternion(acc_row, [0.0, 20.0, -40.0])).all()
            assert np.isnan(triad_quaternion(acc_row, [0.0, 20.0, -40.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])).all()
        mps_quaternion([1e300, 1e300, 1.0], [0.0, 20.0, -40.0])
        triad_quaternion([1e300, 1e300, 1.0], [0.0, 20.0, -40.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])
