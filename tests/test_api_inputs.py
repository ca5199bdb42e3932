"""Classes of input a notebook user passes to the Python API: each gives the clean call's result or
a cfdesign error naming the argument, never a silent misreading (bools read as 0/1, a DataFrame's
named axes read by position, a rate or noise figure of ``True`` or ``"100"``)."""

import re

import numpy as np
import pandas as pd
import pytest

import cfdesign
from cfdesign.errors import CfdesignError, InputError
from cfdesign.nav import AttitudeFilter, PositionFilter, estimate_attitude
from cfdesign.nav.attitude_inputs import rows
from cfdesign.runtime import Runtime

RNG = np.random.default_rng(7)
N = 60
GYR = 0.02 * RNG.standard_normal((N, 3))
ACC = np.array([0.3, -0.2, 9.8]) + 0.05 * RNG.standard_normal((N, 3))
MAG = np.array([0.05, 0.2, -0.4]) + 0.002 * RNG.standard_normal((N, 3))
NOISE = {"accel_noise_std": 0.05, "accel_bias_density": 1e-3, "gps_noise_std": 2.0}


@pytest.fixture(scope="module")
def heading():
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("robot-heading")))
    data = {"odometry_rate": 0.1 + 0.01 * RNG.standard_normal(N), "gyro_heading": 0.01 * RNG.standard_normal(N),
            "compass": 0.05 * RNG.standard_normal(N)}
    return table, data


@pytest.mark.parametrize("call", [
    lambda rt, d: rt.run({**d, "odometry_rate": d["odometry_rate"] > 0.1}),       # a mask as readings
    lambda rt, d: rt.run({**d, "compass": np.ma.masked_array(d["compass"] > 0)}),
    lambda rt, d: rt.run({**d, "compass": [True] * N}),
    lambda rt, d: rt.step(odometry_rate=True),
    lambda rt, d: rt.step(compass=np.bool_(False)),
    lambda rt, d: Runtime(rt.table, x0=[True, False]),
])
def test_runtime_refuses_bools(heading, call):
    rt = Runtime(heading[0])
    before = rt.state()
    with pytest.raises(CfdesignError, match=r"real numbers|not a number"):
        call(rt, heading[1])
    assert rt.state() == before


def test_runtime_case_hint(heading):
    with pytest.raises(CfdesignError, match=r"'COMPASS'.*case-sensitive"):
        Runtime(heading[0]).run(pd.DataFrame({k.upper() if k == "compass" else k: v for k, v in heading[1].items()}))


@pytest.mark.parametrize("bad", [lambda a: a > 0, lambda a: np.ma.masked_array(a > 0), lambda a: (a > 0).tolist()])
def test_attitude_refuses_bool_arrays(bad):
    with pytest.raises(InputError, match="gyr: real numbers"):
        estimate_attitude(bad(GYR), ACC, MAG, 100.0)
    with pytest.raises(InputError, match="acc_body: real numbers"):
        PositionFilter(10.0, 1.0, **NOISE).run(bad(ACC), np.tile([1.0, 0, 0, 0], (N, 1)), np.full((N, 3), np.nan))


@pytest.mark.parametrize("names", [["x", "y", "z"], ["gyro_X", "gyro_Y", "gyro_Z"], ["a", "b", "c"]])
def test_dataframe_axes_in_order_or_unnamed_are_read_by_position(names):
    frame = pd.DataFrame(GYR, columns=names, index=pd.date_range("2024", periods=N, freq="10ms"))
    got = estimate_attitude(frame, pd.DataFrame(ACC, columns=list("XYZ")), MAG, 100.0)
    assert np.array_equal(got, estimate_attitude(GYR, ACC, MAG, 100.0))


@pytest.mark.parametrize("names, fix", [(["Z", "Y", "X"], "gyr[['X', 'Y', 'Z']]"),
                                        (["gy", "gx", "gz"], "gyr[['gx', 'gy', 'gz']]")])
def test_dataframe_axes_named_out_of_order_are_refused(names, fix):
    """Columns named z, y, x were read as x, y, z; re-sorting them by name would undo a remap that
    kept the sensor's names (``concat([g.gy, -g.gx, g.gz])``): neither is taken, the fix is named."""
    frame = pd.DataFrame(GYR, columns=names)
    with pytest.raises(InputError, match=re.escape(fix) + r".*gyr\.to_numpy\(\)"):
        estimate_attitude(frame, ACC, MAG, 100.0)


def test_dataframe_quaternion_xyzw_refused():
    q = np.tile([np.cos(0.2), 0.0, 0.0, np.sin(0.2)], (N, 1))
    acc, gps = np.tile([0.0, 0.0, 9.80665], (N, 1)), np.full((N, 3), np.nan)
    with pytest.raises(InputError, match=r"not in the order w, x, y, z.*\['qw', 'qx', 'qy', 'qz'\]"):
        PositionFilter(10.0, 1.0, **NOISE).run(acc, pd.DataFrame(q[:, [1, 2, 3, 0]], columns=["qx", "qy", "qz", "qw"]),
                                               gps)


def test_dataframe_transposed_refused():
    frame = pd.DataFrame(GYR[:3].T, index=["x", "y", "z"])  # N == 3: the shape alone cannot tell
    with pytest.raises(InputError, match=r"gyr: .*one axis per row.*gyr\.T"):
        rows("gyr", frame, 3)
    with pytest.raises(InputError, match=r"gyr: .*one axis per row"):
        estimate_attitude(frame, ACC[:3], MAG[:3], 100.0)


@pytest.mark.parametrize("value", [True, np.bool_(True), "100", [100.0], 1j])
@pytest.mark.parametrize("build", [
    AttitudeFilter,
    lambda r: PositionFilter(r, 1.0, **NOISE),
    lambda r: PositionFilter(10.0, r, **NOISE),
    lambda r: PositionFilter(10.0, 1.0, **{**NOISE, "gps_noise_std": r}),
    lambda r: AttitudeFilter(100.0, gyro_noise_density=r),
    lambda r: AttitudeFilter(100.0, declination_rad=r),
])
def test_numbers_refuse_bools_and_text(build, value):
    with pytest.raises(CfdesignError, match="must be a number"):
        build(value)


@pytest.mark.parametrize("value", [np.float32(100.0), np.int64(100), np.array(100.0), 100])
def test_numpy_rates_are_numbers(value):
    assert AttitudeFilter(value).rate_hz == 100.0
    assert PositionFilter(value, 1.0, **NOISE).table.period == 100
