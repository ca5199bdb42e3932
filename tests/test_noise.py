"""Noise models and exact discretisation, against closed forms."""

import numpy as np
import pytest

from cfdesign.errors import SpecError
from cfdesign.noise import Bias, WhiteNoise, van_loan, zoh


def test_density_and_std_conventions():
    w = WhiteNoise(density=0.01)
    assert w.psd(100.0) == pytest.approx(1e-4)
    assert w.variance(100.0) == pytest.approx(1e-2)  # sigma^2 = q f
    s = WhiteNoise(std=0.1)
    assert s.variance(50.0) == pytest.approx(0.01)
    assert s.psd(50.0) == pytest.approx(0.01 / 50)


def test_van_loan_double_integrator_closed_form():
    """Continuous white acceleration q on [p, v]: Qd = q [[T^3/3, T^2/2], [T^2/2, T]]."""
    q, T = 0.7, 0.05
    Fd, Qd = van_loan([[0, 1], [0, 0]], [[0, 0], [0, q]], T)
    assert np.allclose(Fd, [[1, T], [0, 1]], rtol=0, atol=1e-15)
    assert np.allclose(Qd, q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]]), rtol=1e-12, atol=0)


def test_van_loan_matches_quadrature_on_a_stable_system():
    from scipy.integrate import quad_vec
    from scipy.linalg import expm

    F = np.array([[-0.3, 1.0], [-2.0, -0.5]])
    Qc = np.array([[0.2, 0.05], [0.05, 1.0]])
    T = 0.4
    ref, _ = quad_vec(lambda t: expm(F * t) @ Qc @ expm(F * t).T, 0, T, epsabs=1e-14, epsrel=1e-13)
    assert np.allclose(van_loan(F, Qc, T)[1], ref, rtol=1e-10, atol=1e-14)


def test_zoh_of_position_chain():
    T = 0.02
    Fd, Bd = zoh([[0, 1, 0], [0, 0, -1], [0, 0, 0]], [0, 1, 0], T)
    assert np.allclose(Fd, [[1, T, -T**2 / 2], [0, 1, -T], [0, 0, 1]], atol=1e-15)
    assert np.allclose(Bd.ravel(), [T**2 / 2, T, 0], atol=1e-15)


@pytest.mark.parametrize("kwargs, message", [
    ({}, "exactly one"),
    ({"density": 1.0, "std": 1.0}, "exactly one"),
    ({"std": -1.0}, "non-negative"),
    ({"density": float("nan")}, "finite"),
    ({"std": "1"}, "must be a number"),
])
def test_white_noise_errors(kwargs, message):
    with pytest.raises(SpecError, match=message):
        WhiteNoise(**kwargs)


def test_bias_errors_and_psd():
    assert Bias("random_walk", density=0.1).psd == pytest.approx(0.01)
    assert Bias("constant", value=-0.5).psd == 0
    with pytest.raises(SpecError, match="positive density"):
        Bias("random_walk")
    with pytest.raises(SpecError, match="model"):
        Bias("flicker")


def test_numpy_scalar_figures_are_figures_in_double_precision():
    """WhiteNoise(density=np.float32(2e-3)) was refused ('must be a number'); a numpy scalar is a
    number, stored as a double (psd() of a float32 figure stayed in single precision)."""
    w = WhiteNoise(density=np.float32(2e-3))
    assert type(w.density) is float and w.psd(100.0) == float(np.float32(2e-3)) ** 2
    assert type(WhiteNoise(std=np.int64(1)).std) is float
    b = Bias("random_walk", density=np.float32(1e-5), value=np.int64(0))
    assert type(b.density) is float and type(b.value) is float
    with pytest.raises(SpecError, match="must be a number"):
        WhiteNoise(density=np.bool_(True))
