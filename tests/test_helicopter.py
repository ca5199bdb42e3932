"""Vasconcelos et al.'s helicopter: the manoeuvre's kinematics and a shortened Table 2 reproduction."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from cfdesign import rotations as rot
from cfdesign.cli import main
from cfdesign.reproduce import helicopter
from cfdesign.sim import helicopter as heli


@pytest.fixture(scope="module")
def truth():
    return heli.helicopter_manoeuvre(heli.Manoeuvre(start_speed_m_s=2.0, helix_s=30.0))


def _central(x, dt):
    return (x[2:] - x[:-2]) / (2 * dt)


def test_kinematics_consistent(truth):
    dt = truth.dt_s
    assert np.max(np.abs(_central(truth.position_m, dt) - truth.velocity_m_s[1:-1])) < 1e-3
    assert np.max(np.abs(_central(truth.velocity_m_s, dt) - truth.acceleration_m_s2[1:-1])) < 1e-3
    q = truth.quaternion  # q' = q (x) [0, w] / 2
    omega = 2 * rot.multiply(rot.conjugate(q[1:-1]), _central(q, dt))[:, 1:]
    assert np.max(np.abs(omega - truth.body_rate_rad_s[1:-1])) < 1e-3
    f = rot.rotate(q, truth.specific_force_m_s2) + heli.GRAVITY_ENU
    assert np.max(np.abs(f - truth.acceleration_m_s2)) < 1e-9
    mean = 0.5 * (truth.body_rate_rad_s[1:] + truth.body_rate_rad_s[:-1])
    assert np.max(np.abs(truth.mean_body_rate_rad_s - mean)) < 1e-4


def test_shape_of_the_manoeuvre(truth):
    helix = truth.t_s > 25.0
    radius = np.hypot(*(truth.velocity_m_s[helix, :2].T)) / np.abs(truth.body_rate_rad_s[helix]).max()
    assert np.all(radius > 10.0)
    assert truth.velocity_m_s[-1, 2] == pytest.approx(0.5)
    assert np.all(np.abs(truth.specific_force_m_s2[:, :2]) < 1e-9)  # thrust along body z
    assert np.degrees(np.abs(truth.euler_rad[:, 2])).max() == pytest.approx(9.65, abs=0.05)


def test_readings_follow_table1(truth):
    r = heli.simulate_readings(truth, 3)
    assert np.all(np.isnan(r.gps_enu_m[1:50])) and np.all(np.isfinite(r.gps_enu_m[::50]))
    gyro_err = r.gyro_rad_s - truth.mean_body_rate_rad_s
    assert np.allclose(gyro_err.mean(axis=0), heli.TABLE1.gyro_bias, atol=3e-5)
    acc_err = r.accel_m_s2 - truth.mean_specific_force_m_s2
    assert np.allclose(acc_err.mean(axis=0), heli.TABLE1.accel_bias, atol=5e-4)
    assert np.allclose(acc_err.std(axis=0), heli.TABLE1.accel_noise_std_m_s2, rtol=0.1)


def test_short_reproduction_beats_bounds():
    m = heli.Manoeuvre(helix_s=40.0)
    result = helicopter.reproduce(1, seed=1, manoeuvre=m)
    for row in helicopter.PAPER:
        maes = np.array(result.values[row][0])
        assert np.all(np.isfinite(maes))
        assert maes[0] < 2.5  # m
        assert np.all(maes[1:] < 0.2)  # deg
    data = result.to_dict()
    json.dumps(data)
    assert data["rows"]["nominal"][0]["paper"] == 1.39
    assert "Table 2" in result.text()


def test_cli_entry_points(capsys, monkeypatch):
    full = helicopter.reproduce
    short = lambda *a, **k: full(1, seed=0, manoeuvre=heli.Manoeuvre(helix_s=10.0))  # noqa: E731
    monkeypatch.setattr(helicopter, "reproduce", short)
    parser = argparse.ArgumentParser()
    helicopter.add_arguments(parser)
    assert helicopter.run(parser.parse_args(["--json"])) == 0
    assert json.loads(capsys.readouterr().out)["paper"] == "helicopter"
    for name in ("helicopter", "seed004"):  # the command's name and its former name
        assert main(["reproduce", name, "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["paper"] == "helicopter"
