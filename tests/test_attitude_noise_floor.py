"""Rest detection against the noise floor the filter measures (``_noise_floor``): a gyro noisier than the
density the filter was built with still rests and learns its bias, a gyro as noisy as its density rests
exactly as with the designed thresholds alone, a long motion is never read as rest, and the user is told
once of a sensor noisier than its density.

Synthetic tracks (``motion`` and ``imu`` of tests/test_attitude_filter.py) at 100 Hz in 6D; the gyro's
per-sample noise is the default density's (``2e-4 * sqrt(100)`` rad/s) times ``scale``.
"""

import re
import warnings

import numpy as np
import pytest
from test_attitude_codegen import needs_cc, run_c
from test_attitude_filter import RATE, imu, motion

import cfdesign.nav.attitude_filter as attitude_filter
from cfdesign.nav import AttitudeFilter, AttitudeParams

BIAS = np.array([0.01, -0.02, 0.015])
GYRO_STD = AttitudeParams().gyro_noise_density * np.sqrt(RATE)
ACCEL_STD = AttitudeParams().accel_noise_density * np.sqrt(RATE)


def readings(scale, n, still_s, amplitude=(2.5, 0.8, 0.7), seed=3):
    """Gyro and specific force of a sensor still for ``still_s`` and then turning (``motion``), its gyro
    ``scale`` times as noisy as the default density, its accelerometer as noisy as its density."""
    gyr, acc, _ = imu(motion(n, still_s=still_s, amplitude=amplitude), bias=BIAS, seed=seed,
                      noise=(scale * GYRO_STD, ACCEL_STD, 0.0))
    return gyr, acc


def run(gyr, acc, floor=True, monkeypatch=None):
    """A 6D run with details; ``floor=False``: the threshold forced to the design's (the floor's factor 0)."""
    if not floor:
        monkeypatch.setattr(attitude_filter, "REST_FLOOR_K", 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return AttitudeFilter(RATE, magnetometer=False).run(gyr, acc, details=True)


def test_a_gyro_4x_noisier_than_its_density_rests_and_learns_its_bias(monkeypatch):
    """25 s still then 15 s of turning, the gyro 4 times noisier than the density: with the designed
    thresholds alone it never rests and keeps a bias error of 0.015 rad/s; against the floor it rests
    within 6 s (the floor doubling every second from the design's, then ``rest_time_s``: measured 3.5 s),
    learns the bias to 1e-3 rad/s by the end of the still (measured 3.5e-4) and the rest ends when the
    motion begins."""
    gyr, acc = readings(4.0, 4000, still_s=25.0)
    out = run(gyr, acc)
    first = int(np.argmax(out.rest))
    assert out.rest.any() and first < 6 * RATE
    assert np.abs(out.bias[2499] - BIAS).max() < 1e-3
    assert not out.rest[int(26.5 * RATE):].any()                 # the motion (from 25 s, ramping up over 2 s)
    design = run(gyr, acc, floor=False, monkeypatch=monkeypatch)
    assert not design.rest.any() and np.abs(design.bias[2499] - BIAS).max() > 5e-3


def test_a_gyro_as_noisy_as_its_density_rests_exactly_as_designed(monkeypatch):
    """The same track with the density's noise (and half of it: a quieter sensor than the design): rest
    flags, bias and attitude are those of the designed thresholds alone, to the last bit."""
    for scale in (1.0, 0.5):
        gyr, acc = readings(scale, 4000, still_s=25.0)
        out = run(gyr, acc)
        with monkeypatch.context() as m:
            design = run(gyr, acc, floor=False, monkeypatch=m)
        assert out.rest[:2500].mean() > 0.9
        np.testing.assert_array_equal(out.rest, design.rest)
        np.testing.assert_array_equal(out.quaternion, design.quaternion)
        np.testing.assert_array_equal(out.bias, design.bias)


@pytest.mark.parametrize(("scale", "amplitude"), [(1.0, (0.15, 0.05, 0.05)), (4.0, (0.3, 0.1, 0.1))])
def test_five_minutes_of_slow_rotation_are_never_read_as_rest(scale, amplitude):
    """5 min of slow turning from the first sample (rates up to 0.08 rad/s, 4.5 deg/s, for the density's
    gyro; up to 0.16 rad/s for one 4 times noisier): never rest.  The floor measures the white noise from
    successive samples, which so slow a motion hardly changes (a floor that tracked the deviation itself
    rose to its bound in this motion and read half of it as rest); the 4x gyro's floor is its noise."""
    gyr, acc = readings(scale, int(300 * RATE), still_s=0.0, amplitude=amplitude, seed=5)
    f = AttitudeFilter(RATE, magnetometer=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                          # no rest: nothing to warn of
        out = f.run(gyr, acc, details=True)
    assert not out.rest.any()
    floor = f.state()["gyro_floor"] / f.design.constants["rest_gyro_var"]
    assert 0.5 * scale ** 2 < floor < 1.5 * scale ** 2        # measured 0.94 and 15.0


def test_the_floor_is_no_looser_than_the_true_density():
    """A 4x gyro in a motion so slow (up to 0.09 rad/s) that its noise hides it in part: the floor reads as
    rest no more than a filter built with the gyro's true density (measured 775 against 791 of 12000
    samples; the designed thresholds alone: none, nor any rest at all)."""
    gyr, acc = readings(4.0, int(120 * RATE), still_s=0.0, amplitude=(0.15, 0.05, 0.05), seed=5)
    ours = run(gyr, acc).rest.sum()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        true = AttitudeFilter(RATE, magnetometer=False, gyro_noise_density=8e-4).run(gyr, acc, details=True)
    assert ours <= true.rest.sum()


def test_the_noisy_gyro_is_warned_of_once_and_the_right_one_not():
    """The 4x gyro: one UserWarning over a run and further steps, naming the ratio (about 4) and how to set
    the density; the density's gyro: none."""
    gyr, acc = readings(4.0, 3000, still_s=30.0)
    f = AttitudeFilter(RATE, magnetometer=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f.run(gyr[:2000], acc[:2000])
        for g, a in zip(gyr[2000:2200], acc[2000:2200], strict=True):
            f.step(g, a)
        f.run(gyr[2200:], acc[2200:])
    noisy = [str(w.message) for w in caught if "as noisy" in str(w.message)]
    assert len(noisy) == 1 and all(w.category is UserWarning for w in caught)
    ratio = float(re.search(r"gyr: at rest the gyro is about ([0-9.]+) times as noisy", noisy[0]).group(1))
    assert 3.6 < ratio < 4.4
    assert "gyro_noise_density" in noisy[0] and "cfdesign noise" in noisy[0] and "accelerometer" not in noisy[0]
    gyr, acc = readings(1.0, 3000, still_s=30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f = AttitudeFilter(RATE, magnetometer=False)
        f.run(gyr[:2000], acc[:2000])
        for g, a in zip(gyr[2000:2200], acc[2000:2200], strict=True):
            f.step(g, a)
    assert f.rest


@needs_cc
def test_c_follows_the_floor_sample_by_sample(tmp_path):
    """The generated C on the 4x gyro still then turning: the floor rises, rest is detected against it,
    and C agrees with Python on every quaternion and on the final state (floors included)."""
    gyr, acc = readings(4.0, 2000, still_s=14.0)
    f = AttitudeFilter(RATE, magnetometer=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = f.run(gyr, acc, details=True)
    assert out.rest.any()
    q_c, state_c = run_c(tmp_path, f, gyr, acc, None)
    assert np.abs(q_c - out.quaternion).max() <= 1e-9
    state = f.state()
    assert all(abs(state_c[k] - state[k]) <= 1e-9 * max(1.0, abs(state[k])) for k in state)
    assert state["gyro_floor"] > 4.0 * f.design.constants["rest_gyro_var"]
