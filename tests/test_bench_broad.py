"""The proxies of ``benchmarks/bench_broad.py``: their readings agree with their reference exactly.

A proxy is only a fair test of a filter if its reference is the attitude its readings describe.  A
synthetic trial whose readings are exact (gyro = body rate + a constant bias; specific force =
gravity, field = a constant ENU field, both turned into the body frame, plus white noise) is turned
into each proxy, and the proxy's readings are checked against its own reference: consecutive
references differ by the gyro's rotation (bias removed), the specific force turned into ENU is
gravity and the field is the ENU field (plus what the proxy adds: the office's field, the bias step).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from cfdesign import rotations as rot

_spec = importlib.util.spec_from_file_location(
    "bench_broad", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_broad.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

RATE = 50.0
BIAS = np.array([0.004, -0.006, 0.003])
GRAVITY = 9.81
FIELD_ENU = np.array([0.0, 18.0, -40.0])
ACC_STD, MAG_STD = 0.03, 0.4


@pytest.fixture(scope="module")
def trial():
    return synthetic_trial()


def synthetic_trial(seed=0):
    """30 s at rest, 40 s of motion through space, 10 s at rest; exact readings plus white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(80.0 * RATE)) / RATE
    movement = (t >= 30.0) & (t < 70.0)
    w = movement[:, None] * np.column_stack([np.sin(0.7 * t), 0.5 * np.cos(1.3 * t), 0.8 * np.sin(0.4 * t + 1.0)])
    steps = rot.from_rotation_vector(w / RATE)
    q = np.empty((len(t), 4))
    q[0] = rot.from_rotation_vector([0.2, -0.1, 0.5])
    for k in range(1, len(t)):
        q[k] = rot.multiply(q[k - 1], steps[k])
    back = rot.conjugate(q)
    s = np.clip(t - 30.0, 0.0, 40.0)
    pos = np.column_stack([0.6 * np.sin(0.3 * s), 0.8 * (1.0 - np.cos(0.2 * s)), 0.3 * np.sin(0.5 * s)])
    ref = q.copy()
    ref[1500:1510] = np.nan                              # the markers lost for a moment in the motion
    return {"gyr": w + BIAS, "acc": rot.rotate(back, [0.0, 0.0, GRAVITY]) + ACC_STD * rng.standard_normal((len(t), 3)),
            "mag": rot.rotate(back, FIELD_ENU) + MAG_STD * rng.standard_normal((len(t), 3)),
            "ref": ref, "pos": pos, "movement": movement, "rate": RATE}


def gyro_mismatch(d, bias):
    """Largest angle (rad) between the rotation of consecutive references and the gyro's (``bias`` removed)."""
    ref = d["ref"]
    ok = np.isfinite(ref[1:]).all(axis=1) & np.isfinite(ref[:-1]).all(axis=1)
    step_ref = rot.multiply(rot.conjugate(ref[:-1][ok]), ref[1:][ok])
    step_gyr = rot.from_rotation_vector((d["gyr"][1:][ok] - bias[1:][ok]) / d["rate"])
    e = rot.multiply(rot.conjugate(step_gyr), step_ref)
    return float(np.max(2 * np.arcsin(np.clip(np.linalg.norm(e[:, 1:], axis=1), 0.0, 1.0))))


def enu(d, key):
    """The readings ``key`` turned into ENU by the reference (rows with a reference)."""
    ok = np.isfinite(d["ref"]).all(axis=1)
    return rot.rotate(d["ref"][ok], d[key][ok]), ok


PROXIES = {"backwards": bench.reversed_trial, "breaks": bench.breaks_trial, "long": bench.long_trial,
           "repeated": bench.repeated_trial, "office": bench.office_trial, "bias step": bench.bias_step_trial,
           "breaks, bias step": lambda d: bench.bias_step_trial(bench.breaks_trial(d))}


@pytest.mark.parametrize("name", list(PROXIES))
def test_proxy_readings_agree_with_its_reference(name, trial):
    d = trial
    out = PROXIES[name](d)
    n = len(out["gyr"])
    assert all(len(out[key]) == n for key in ("acc", "mag", "ref", "movement"))
    bias = np.tile(-BIAS if name == "backwards" else BIAS, (n, 1))      # played backwards, the bias is negated
    if "bias step" in name:
        # the step from halfway through the motion to the end, rests included
        base = bench.breaks_trial(d) if "breaks" in name else d
        first, last = np.flatnonzero(base["movement"])[[0, -1]]
        changed = np.flatnonzero(np.any(out["gyr"] != base["gyr"], axis=1))
        assert changed[0] == (first + last + 1) // 2 and len(changed) == n - changed[0]
        bias[changed[0]:] += bench.BIAS_STEP
    assert gyro_mismatch(out, bias) < 1e-9
    # the rests of "breaks" hold a block of the recorded noise (its mean is not zero) and the field of a
    # 0.1-s window (noise averaged over 5 samples at 50 Hz)
    shortest = min(s for _, s in bench.BREAKS) * RATE if "breaks" in name else n
    window = 2 * round(0.05 * RATE) + 1 if "breaks" in name else n
    acc, ok = enu(out, "acc")
    np.testing.assert_allclose(acc.mean(axis=0), [0.0, 0.0, GRAVITY],
                               atol=4 * ACC_STD / np.sqrt(min(ok.sum(), shortest)))
    assert np.std(acc - [0.0, 0.0, GRAVITY]) < 1.5 * ACC_STD
    field, ok = enu(out, "mag")
    if name == "office":
        disturbance = bench.office_field(d["pos"] - d["pos"][0])[ok]
        assert 5.0 < np.max(np.linalg.norm(disturbance, axis=1)) < 30.0      # uT, the brief's range
        field = field - disturbance
    np.testing.assert_allclose(field.mean(axis=0), FIELD_ENU, atol=4 * MAG_STD / np.sqrt(min(ok.sum(), window)))
    assert np.std(field - FIELD_ENU) < 1.5 * MAG_STD


@pytest.mark.parametrize("rate", [100.0, 20.0])
def test_a_resampled_proxy_agrees_with_its_reference(rate, trial):
    """Up or down to any rate: each rate is the mean of the recorded (held) rates over its interval, so
    consecutive references differ by the gyro's rotation (exactly when up-sampling; to the rotations'
    non-commutativity, about 1e-5 rad, when averaging 2.5 samples of ~1 rad/s), and the specific force
    interpolated at the new times is gravity in ENU."""
    out = bench.resampled_trial(trial, rate)
    n = len(out["gyr"])
    assert out["rate"] == rate and n == int((len(trial["gyr"]) - 1) * rate / RATE)     # to the last recorded time
    assert gyro_mismatch(out, np.tile(BIAS, (n, 1))) < (1e-12 if rate > RATE else 3e-5)
    acc, ok = enu(out, "acc")
    np.testing.assert_allclose(acc.mean(axis=0), [0.0, 0.0, GRAVITY], atol=4 * ACC_STD / np.sqrt(ok.sum()))
    assert np.std(acc - [0.0, 0.0, GRAVITY]) < 1.5 * ACC_STD


def test_a_dip_proxy_turns_the_field_about_east(trial):
    """The field turned by 30 deg about east through the reference is, in ENU, the field so turned: its
    north part grows, its down part shrinks, the noise stays the field's."""
    out = bench.dip_trial(trial, 30.0)
    turned = rot.rotate(rot.from_rotation_vector([np.radians(30.0), 0.0, 0.0]), FIELD_ENU)
    field, ok = enu(out, "mag")
    np.testing.assert_allclose(field.mean(axis=0), turned, atol=4 * MAG_STD / np.sqrt(ok.sum()))
    assert np.std(field - turned) < 1.5 * MAG_STD


def test_breaks_are_rests_of_the_given_lengths(trial):
    d = trial
    out = bench.breaks_trial(d)
    added = len(out["gyr"]) - len(d["gyr"])
    assert added == sum(round(s * RATE) for _, s in bench.BREAKS)
    # each break holds the reference still, is not scored, and its gyro reads the recorded bias
    still = np.flatnonzero(np.all(np.abs(out["ref"][1:] - out["ref"][:-1]) < 1e-12, axis=1) & ~out["movement"][1:]) + 1
    moving_part = (still > 30 * 50) & (still < len(out["gyr"]) - 10 * 50)
    assert moving_part.sum() == added
    np.testing.assert_allclose(out["gyr"][still[moving_part]], np.tile(BIAS, (added, 1)))


def test_long_proxies_play_the_motion_twice(trial):
    d = trial
    for proxy in (bench.long_trial, bench.repeated_trial):
        out = proxy(d)
        assert 1.5 * 40 * RATE <= np.sum(out["movement"]) <= 2 * 40 * RATE
        assert len(out["gyr"]) > 1.5 * len(d["gyr"])


def test_the_accelerometer_pitch_and_the_reference_pitch_agree_on_exact_gravity():
    """``--accel-angle`` compares the pitch read from the specific force with the reference's: on gravity turned
    exactly into the body frame of any attitude (pitch within ±80°) the two are the same angle, and that angle is
    the Euler pitch of the attitude."""
    rng = np.random.default_rng(4)
    euler = np.column_stack([rng.uniform(-3, 3, 200), rng.uniform(-1.4, 1.4, 200), rng.uniform(-3, 3, 200)])
    q = rot.from_euler(euler)
    acc = rot.rotate(rot.conjugate(q), np.array([0.0, 0.0, GRAVITY]))
    np.testing.assert_allclose(bench.accel_pitch(acc), bench.reference_pitch(q), atol=1e-12)
    np.testing.assert_allclose(bench.reference_pitch(q), rot.to_euler(q)[:, 1], atol=1e-12)
    assert np.isnan(bench.reference_pitch(np.full((2, 4), np.nan))).all()


@pytest.mark.parametrize(("angle", "axis"),
                         [(180.0, (1.0, 0.0, 0.0)), (90.0, (1.0, 0.0, 0.0)), (120.0, (1.0, 2.0, 3.0))])
def test_a_remounted_proxy_reads_the_same_in_enu(angle, axis, trial):
    """Turning every reading by a mounting ``R`` and the reference by ``R⁻¹`` leaves what the readings say about
    the world (each turned into ENU by its reference) as it was."""
    out = bench.rotated_trial(trial, angle, axis)
    for key in ("gyr", "acc", "mag"):
        np.testing.assert_allclose(enu(out, key)[0], enu(trial, key)[0], atol=1e-9)


def test_the_unit_proxies_keep_the_directions_and_change_the_norms(trial):
    """The field normalised sample by sample keeps each reading's direction at norm 1; the specific force in g
    is the reading over 9.81."""
    unit = bench.PROXIES["units: field normalised sample by sample"](trial)
    np.testing.assert_allclose(np.linalg.norm(unit["mag"], axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(unit["mag"] * np.linalg.norm(trial["mag"], axis=1, keepdims=True), trial["mag"],
                               rtol=1e-12)
    in_g = bench.PROXIES["units: specific force in g"](trial)
    np.testing.assert_allclose(in_g["acc"] * 9.81, trial["acc"], rtol=1e-12)
    np.testing.assert_array_equal(in_g["gyr"], trial["gyr"])
