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


def _dckf3_bands_by_hand(K, T, w):
    """Prior bands of the DCKF3 from its matrices: T_i = C (zI - F + K H)^-1 [B | K] times the
    sensor's relation ((z - 1)/T for the gyro rate), independent of the symbolic engine."""
    F, B, H, C = np.array([[1, T], [0, 1.0]]), np.array([[T], [0.0]]), np.array([[1, 0], [1, 0.0]]), np.eye(1, 2)
    z = np.exp(1j * np.asarray(w) * T)
    G = np.array([(C @ np.linalg.solve(x * np.eye(2) - F + K @ H, np.hstack([B, K])))[0] for x in z])
    return {"gyro": G[:, 0] * (z - 1) / T, "compass": G[:, 1], "odometry": G[:, 2]}


@pytest.mark.parametrize("K", [[[0.0280736, 0.560937], [0.000140127, 0.00279986]],
                               [[0.00190725, 0.953626], [9.52153e-06, 0.00476076]]])
def test_crossover_is_drawn_from_the_band_that_carries_dc(K):
    """Compass and odometry both low-pass (the Kalman gains of getting-started's heading.toml:
    shares 0.05 and 0.95 from DC; of the dckf3 example: 0.002 and 0.998): the plot marked
    'compass/gyro: 0.14 rad/s' (and 0.0105), where the weak compass band meets the gyro's under
    the odometry band; the hand-over is odometry/gyro, where those two are equal."""
    from scipy.optimize import brentq

    K, T = np.array(K), 0.2
    g = cfdesign.dckf3().with_gains(k11=K[0, 0], k12=K[0, 1], k21=K[1, 0], k22=K[1, 1], T=T)
    grid = np.logspace(-4, np.log10(np.pi / T), 400)
    by_hand = _dckf3_bands_by_hand(K, T, grid)
    assert np.all(np.abs(by_hand["odometry"]) > np.abs(by_hand["compass"]))  # the compass never leads

    def ratio(w):
        b = _dckf3_bands_by_hand(K, T, [w])
        return np.log(abs(b["odometry"][0])) - np.log(abs(b["gyro"][0]))

    i = np.flatnonzero(np.abs(by_hand["gyro"]) > np.abs(by_hand["odometry"]))[0]
    (a, b, w), = cfdesign.frequency_response(g).crossovers()
    assert (a, b) == ("odometry", "gyro")
    assert w == pytest.approx(brentq(ratio, grid[i - 1], grid[i], xtol=1e-14), rel=1e-9)


def _bands(w):
    """A low-pass and a high-pass band, and a band that touches the low-pass at 1 rad/s (equal
    there, below it on both sides) and never leads."""
    w = np.asarray(w, dtype=float)
    s = 1j * w
    low = 1 / (s + 1)
    return {"low": low, "touch": low * (2 * w / (1 + w * w)), "high": s**4 / (s + 1) ** 4}


def test_a_band_that_touches_another_takes_no_hand_over():
    """On a grid holding 1 rad/s the touching band's log ratio to the low-pass is 0 there, + on both
    sides: that zero was a sign change, 'low/touch: 1.0' was marked and the real hand-over, low to
    high where |s + 1|^3 = w^4, lost.  A crossing on a grid point (low/high of a first-order pair
    at 1 rad/s) is still one."""
    from scipy.optimize import brentq

    from cfdesign.analysis import FrequencyResponse

    grid = np.logspace(-3, 3, 801)
    assert grid[400] == 1.0
    resp = FrequencyResponse(omega=grid, bands=_bands(grid), dt=None, coefficients={}, evaluate=_bands)
    want = brentq(lambda w: 1.5 * np.log1p(w * w) - 4 * np.log(w), 1.0, 3.0, xtol=1e-14)
    (a, b, w), = resp.crossovers()
    assert (a, b) == ("low", "high") and w == pytest.approx(want, rel=1e-9)

    def pair(w):
        s = 1j * np.asarray(w, dtype=float)
        return {"low": 1 / (s + 1), "high": s / (s + 1)}

    (a, b, w), = FrequencyResponse(omega=grid, bands=pair(grid), dt=None, coefficients={},
                                   evaluate=pair).crossovers()
    assert (a, b) == ("low", "high") and w == pytest.approx(1.0, rel=1e-12)
