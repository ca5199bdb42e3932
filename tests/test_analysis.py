"""Numeric models (python-control) and Bode plots."""

import control
import matplotlib
import numpy as np
import pytest

import cfdesign

matplotlib.use("Agg")


def test_transfer_functions_continuous_match_hand_formula():
    tfs = cfdesign.transfer_functions(cfdesign.cf3().with_gains(k1=2, k2=1))
    w = np.array([0.1, 1.0, 10.0])
    s = 1j * w
    den = s**2 + 2 * s + 1
    assert np.allclose(tfs["position"](s), 1 / den)
    assert np.allclose(tfs["velocity"](s), 2 * s / den)
    assert np.allclose(tfs["acceleration"](s), s**2 / den)
    assert tfs["sum"].dt == 0 and np.allclose(tfs["sum"](s), 1)


def test_transfer_functions_discrete_carry_dt_and_sum_to_one():
    obs = cfdesign.dckf3().with_gains(k11=0.3, k12=0.2, k21=0.01, k22=0.02, T=0.2)
    tfs = cfdesign.transfer_functions(obs)
    assert all(tf.dt == pytest.approx(0.2) for tf in tfs.values())
    zz = np.exp(1j * np.linspace(0.01, 3.1, 50))
    total = tfs["gyro"](zz) + tfs["compass"](zz) + tfs["odometry"](zz)
    assert np.max(np.abs(total - 1)) < 1e-12
    # stable: all poles inside the unit circle
    assert np.all(np.abs(control.poles(tfs["gyro"])) < 1)


def test_crossovers_of_cf3_are_analytic():
    """|k2| = |k1 w| at w = k2/k1 and |k1 w| = w^2 at w = k1 (Carreira et al. eqs. (4)-(6))."""
    resp = cfdesign.frequency_response(cfdesign.cf3().with_gains(k1=2, k2=1))
    found = {(a, b): w for a, b, w in resp.crossovers()}
    assert found[("position", "velocity")] == pytest.approx(0.5, rel=1e-9)
    assert found[("velocity", "acceleration")] == pytest.approx(2.0, rel=1e-9)
    assert np.max(np.abs(resp.total - 1)) < 1e-12


def test_crossover_of_first_order_cf_is_the_gain():
    resp = cfdesign.frequency_response(cfdesign.cf2(order=1).with_gains(k=3))
    (a, b, w), = resp.crossovers()
    assert (a, b) == ("angle", "rate") and w == pytest.approx(3.0, rel=1e-9)


def test_discrete_grid_stops_at_nyquist():
    obs = cfdesign.dckf3().with_gains(k11=0.3, k12=0.2, k21=0.01, k22=0.02, T=0.2)
    resp = cfdesign.frequency_response(obs)
    assert resp.omega[-1] == pytest.approx(np.pi / 0.2)


def test_bode_plot_draws_bands_sum_and_crossovers(tmp_path):
    obs = cfdesign.cf3().with_gains(k1=2, k2=1)
    fig = cfdesign.bode_plot(obs)
    ax_mag, ax_ph = fig.axes
    labels = [line.get_label() for line in ax_mag.get_lines()]
    assert {"T_position", "T_velocity", "T_acceleration", "sum of bands"} <= set(labels)
    total = next(line for line in ax_mag.get_lines() if line.get_label() == "sum of bands")
    assert np.max(np.abs(total.get_ydata())) < 1e-9  # on 0 dB
    assert sorted(t.get_text().strip() for t in ax_ph.texts) == ["position/velocity: 0.5 rad/s",
                                                                  "velocity/acceleration: 2 rad/s"]
    path = tmp_path / "bode.png"
    fig.savefig(path)
    assert path.stat().st_size > 10_000
