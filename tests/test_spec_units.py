"""Datasheet units in design files: ``noise = { density = "0.3 deg/sqrt(h)" }``.

Each conversion against its SI value worked out by hand; a design file written with datasheet
units designs the very gain table of the same file written in SI; every unit that does not fit
its field, every unknown or malformed one, is one line from ``cfdesign design`` (exit 2).
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest

import cfdesign
from cfdesign.designer import Structure, design_from_structure
from cfdesign.errors import SpecError
from cfdesign.spec import load_spec, parse_spec
from cfdesign.units import STANDARD_GRAVITY, parse_quantity

DEG = math.pi / 180
G = 9.80665  # standard gravity, m/s^2 (3rd CGPM 1901; ISO 80000-3)


def dim(angle=0, length=0, time=0, field=0):
    return tuple(Fraction(e) for e in (angle, length, time, field))


RATE_DENSITY, RATE_RW = dim(angle=1, time=Fraction(-1, 2)), dim(angle=1, time=Fraction(-3, 2))
ACCEL_DENSITY = dim(length=1, time=Fraction(-3, 2))
#: text, SI value by hand, dimension (angle, length, time, magnetic field)
CONVERSIONS = [
    ("0.3 deg/sqrt(h)", 0.3 * math.pi / 180 / 60, RATE_DENSITY),  # sqrt(3600 s) = 60 sqrt(s)
    ("0.3 deg/√h", 0.3 * math.pi / 180 / 60, RATE_DENSITY),
    ("0.3 deg/sqrt(hr)", 0.3 * math.pi / 180 / 60, RATE_DENSITY),
    ("0.3°/√h", 0.3 * math.pi / 180 / 60, RATE_DENSITY),
    ("0.005 deg/s/sqrt(Hz)", 0.005 * math.pi / 180, RATE_DENSITY),
    ("0.005 °/s/√Hz", 0.005 * math.pi / 180, RATE_DENSITY),
    ("0.005 dps/rtHz", 0.005 * math.pi / 180, RATE_DENSITY),
    ("0.005 deg/s Hz^-1/2", 0.005 * math.pi / 180, RATE_DENSITY),  # units side by side multiply
    ("0.3 deg h^-1/2", 0.3 * math.pi / 180 / 60, RATE_DENSITY),
    ("0.01 m s^-2", 0.01, dim(length=1, time=-2)),
    ("0.3 º/√h", 0.3 * math.pi / 180 / 60, RATE_DENSITY),  # the masculine ordinal, typed for a degree
    ("0.3 ˚/√h", 0.3 * math.pi / 180 / 60, RATE_DENSITY),  # the ring above
    ("0.01 dph", 0.01 * math.pi / 180 / 3600, dim(angle=1, time=-1)),  # degrees per hour
    ("\u22120.5 deg/s", -0.5 * math.pi / 180, dim(angle=1, time=-1)),  # a PDF's minus sign
    ("0.005 deg/s*Hz^-1/2", 0.005 * math.pi / 180, RATE_DENSITY),
    ("0.005 deg/s*Hz^(-1/2)", 0.005 * math.pi / 180, RATE_DENSITY),
    ("3.8 mdps/sqrt(Hz)", 3.8e-3 * math.pi / 180, RATE_DENSITY),
    ("3.8 mdps/√Hz", 3.8e-3 * math.pi / 180, RATE_DENSITY),
    ("150 ug/sqrt(Hz)", 150e-6 * G, ACCEL_DENSITY),
    ("150 µg/√Hz", 150e-6 * G, ACCEL_DENSITY),  # the micro sign U+00B5
    ("150 μg/√Hz", 150e-6 * G, ACCEL_DENSITY),  # the Greek mu U+03BC
    ("0.02 m/s/sqrt(h)", 0.02 / 60, ACCEL_DENSITY),
    ("10 deg/h/sqrt(h)", 10 * math.pi / 180 / 3600 / 60, RATE_RW),
    ("1e-4 deg/s/sqrt(s)", 1e-4 * math.pi / 180, RATE_RW),
    ("0.3 uT", 0.3e-6, dim(field=1)),
    ("0.3 µT rms", 0.3e-6, dim(field=1)),
    ("3 mG", 3e-7, dim(field=1)),
    ("2 G", 2e-4, dim(field=1)),
    ("50 nT", 50e-9, dim(field=1)),
    ("1.5 mT", 1.5e-3, dim(field=1)),
    ("2.5 m", 2.5, dim(length=1)),
    ("25 cm", 0.25, dim(length=1)),
    ("4 mm", 4e-3, dim(length=1)),
    ("0.6 mg", 0.6e-3 * G, dim(length=1, time=-2)),
    ("2 g", 2 * G, dim(length=1, time=-2)),
    ("0.01 m/s^2", 0.01, dim(length=1, time=-2)),
    ("0.01 m/s²", 0.01, dim(length=1, time=-2)),
    ("3 deg/hr", 3 * math.pi / 180 / 3600, dim(angle=1, time=-1)),
    ("2 deg/min", 2 * math.pi / 180 / 60, dim(angle=1, time=-1)),
    ("5 mrad", 5e-3, dim(angle=1)),
    ("0.5 mrad/ms", 0.5, dim(angle=1, time=-1)),
    ("-0.5 deg/s", -0.5 * math.pi / 180, dim(angle=1, time=-1)),
    ("1e-3 rad/s/sqrt(Hz)", 1e-3, RATE_DENSITY),
]


@pytest.mark.parametrize("text, value, dimension", [c for c in CONVERSIONS if c[1] is not None])
def test_a_datasheet_figure_is_its_si_value(text, value, dimension):
    q = parse_quantity(text)
    assert q.dimension == dimension
    assert q.value == pytest.approx(value, rel=4e-16, abs=0)  # a rounding at most, never a factor


def test_g_is_standard_gravity():
    assert STANDARD_GRAVITY == 9.80665


@pytest.mark.parametrize("text, message", [("0.3 deg//h", r"expected a unit at '/h'"),
                                           ("0.3 deg/s)", r"expected '\*' or '/' between units at '\)'")])
def test_a_malformed_unit_is_refused_naming_where(text, message):
    with pytest.raises(SpecError, match=message):
        parse_quantity(text)


# -- a design file in datasheet units is the design file in SI ------------------------------------
IMU = """name = "pitch from a MEMS IMU"
structure = "cf2"
order = 2
discrete = true
sample_time_s = 0.005
[sensors.gyro]
port = "rate"
measures = "rate"
rate_hz = 200.0
noise = {{ density = {gyro} }}
bias = {{ model = "random_walk", density = {rrw} }}
[sensors.inclinometer]
port = "angle"
rate_hz = 50.0
noise = {{ std = {tilt} }}
"""
DATASHEET = {"gyro": '"0.005 deg/s/sqrt(Hz)"', "rrw": '"10 deg/h/sqrt(h)"', "tilt": '"0.1 deg"'}
HAND = {"gyro": 0.005 * math.pi / 180, "rrw": 10 * math.pi / 180 / 3600 / 60, "tilt": 0.1 * math.pi / 180}
GPS = """structure = "position"
gain_form = "filter"
[sensors.accelerometer]
measures = "acceleration"
rate_hz = 50.0
noise = {{ density = {accel} }}
bias = {{ model = "random_walk", density = {vrw} }}
[sensors.gps]
measures = "position"
rate_hz = 1.0
noise = {{ std = {gps} }}
"""
GPS_DATASHEET = {"accel": '"150 ug/sqrt(Hz)"', "vrw": '"2 ug/sqrt(s)"', "gps": '"2.5 m"'}
GPS_HAND = {"accel": 150e-6 * G, "vrw": 2e-6 * G, "gps": 2.5}


#: the IMU file with the sensors named as the stored structure's ports (it has no port renaming)
IMU_PORTS = IMU.replace('[sensors.gyro]\nport = "rate"', "[sensors.rate]").replace(
    '[sensors.inclinometer]\nport = "angle"', "[sensors.angle]")


@pytest.mark.parametrize("template, datasheet, hand, stored", [(IMU_PORTS, DATASHEET, HAND, "cf2-order2-discrete"),
                                                               (GPS, GPS_DATASHEET, GPS_HAND, "position")],
                         ids=["cf2-gyro-tilt", "position-imu-gps"])
def test_datasheet_units_design_the_same_table_as_si(tmp_path, template, datasheet, hand, stored):
    """The SI file holds the numbers the units convert to (each within a rounding of the hand value:
    ``10 deg/h/sqrt(h)`` is one unit in the last place from ``10*pi/180/3600/60``); the two files
    make equal specs and identical gains and covariances (stored structures: no sympy, fast)."""
    si = {key: parse_quantity(text.strip('"')).value for key, text in datasheet.items()}
    assert all(si[key] == pytest.approx(hand[key], rel=4e-16, abs=0) for key in hand)
    (tmp_path / "datasheet.toml").write_text(template.format(**datasheet), encoding="utf-8")
    (tmp_path / "si.toml").write_text(template.format(**{k: repr(v) for k, v in si.items()}), encoding="utf-8")
    a, b = load_spec(tmp_path / "datasheet.toml"), load_spec(tmp_path / "si.toml")
    assert dataclasses.replace(a, sha256="") == dataclasses.replace(b, sha256="")  # units kept aside
    assert a.sha256 != b.sha256  # the recorded hash is of the file's bytes, as for any edit
    structure = Structure.load(stored)
    ta, tb = design_from_structure(structure, a), design_from_structure(structure, b)
    assert len(ta.K) == len(tb.K) and len(ta.P) == len(tb.P)
    assert all(np.array_equal(x, y) for x, y in zip(ta.K, tb.K, strict=True))
    assert all(np.array_equal(x, y) for x, y in zip(ta.P, tb.P, strict=True))


def test_the_unit_check_survives_a_spec_edited_in_python():
    """No ``measures``: the order comes from the structure's port, after checked_spec's round trip."""
    spec = parse_spec({"structure": "cf2", "order": 2, "discrete": True, "sensors": {
        "rate": {"rate_hz": 100.0, "noise": {"density": "0.3 deg/h"},
                 "bias": {"model": "random_walk", "density": "10 deg/h/sqrt(h)"}},
        "angle": {"rate_hz": 100.0, "noise": {"std": "0.5 deg"}}}})
    spec = dataclasses.replace(spec, name="edited")
    structure = Structure.load("cf2-order2-discrete")
    with pytest.raises(SpecError, match=r"sensors\.rate\.noise\.density: \"0\.3 deg/h\" is an angle rate \(rad/s\), "
                                        r"but a white-noise density of a rate sensor is rad/s/sqrt\(Hz\): did you "
                                        r"mean deg/sqrt\(h\)\?"):
        design_from_structure(structure, spec)
    # a figure replaced in Python is checked as the number it now is
    rate = dataclasses.replace(spec.sensors[0], noise=cfdesign.noise.WhiteNoise(density=1e-4))
    table = design_from_structure(structure, dataclasses.replace(spec, sensors=(rate, spec.sensors[1])))
    assert table.K[0].shape == (2, 1)


# -- refusals: one line, exit 2 ---------------------------------------------------------------------
BASE = {"gyro": '"0.005 deg/s/sqrt(Hz)"', "rrw": '"10 deg/h/sqrt(h)"', "tilt": '"0.1 deg"'}
REFUSED = [
    ({"gyro": '"0.3 deg/h"'}, 'sensors.gyro.noise.density: "0.3 deg/h" is an angle rate (rad/s), but a white-noise '
                              "density of a rate sensor is rad/s/sqrt(Hz): did you mean deg/sqrt(h)?"),
    ({"gyro": '"0.005 deg/s"'}, "did you mean deg/s/sqrt(Hz)?"),
    ({"rrw": '"10 deg/h"'}, "sensors.gyro.bias.density: \"10 deg/h\" is an angle rate (rad/s), but a bias random-"
                            "walk density of a rate sensor is rad/s/sqrt(s): did you mean deg/h/sqrt(h)?"),
    ({"tilt": '"0.3 deg/sqrt(h)"'}, "sensors.inclinometer.noise.std: \"0.3 deg/sqrt(h)\" is rad/s/sqrt(Hz), but "
                                    "a per-sample noise std of an angle sensor is rad"),
    ({"tilt": '"0.002 deg/sqrt(Hz)"'}, "it fits a white-noise density: noise = { density = ... }"),
    ({"gyro": '"0.3 degs/sqrt(h)"'}, "sensors.gyro.noise.density: \"0.3 degs/sqrt(h)\": unknown unit 'degs' "
                                     "(did you mean 'deg'?) (known: rad, mrad, deg, °, dph,"),
    ({"gyro": '"0.3deg//h"'}, "sensors.gyro.noise.density: \"0.3deg//h\": expected a unit at '/h'"),
    ({"gyro": '"0.3 deg/(s"'}, "unbalanced '('"),
    ({"gyro": '"-0.3 deg/sqrt(h)"'}, 'sensors.gyro.noise.density must not be negative, got "-0.3 deg/sqrt(h)"'),
    ({"gyro": '"inf deg/sqrt(h)"'}, 'sensors.gyro.noise.density: "inf deg/sqrt(h)": the number must be finite'),
    ({"gyro": '"nan deg/sqrt(h)"'}, "the number must be finite"),
    ({"gyro": '"1e999 deg/sqrt(h)"'}, "beyond the range of a double"),
    ({"gyro": '"8.7e-5"'}, 'sensors.gyro.noise.density: "8.7e-5" has no unit: an SI figure is a TOML number'),
    ({"gyro": '"deg/sqrt(h)"'}, "must be a number, or a number and then its unit"),
    ({"gyro": '"0.3 Hz^-1/2"'}, "not a figure of one quantity"),
    ({"tilt": '"2 mm"'}, 'sensors.inclinometer.noise.std: "2 mm" is in length units (m, m/s, m/s^2, g, ...), '
                         'beside sensors.gyro.noise.density: "0.005 deg/s/sqrt(Hz)" in angle units (rad, deg, '
                         'rad/s, ...); a design '
                         "estimates one quantity"),
    ({"tilt": '"3 mG"'}, "a magnetometer's heading noise in rad is about its field noise over the horizontal field"),
    ({"tilt": '"1 mg"'}, "an accelerometer's tilt noise in rad is about its acceleration noise over g"),
]


@pytest.mark.parametrize("change, message", REFUSED, ids=[f"refused{i}" for i in range(len(REFUSED))])
def test_a_unit_that_does_not_fit_is_one_line_exit_2(tmp_path, cli, change, message):
    path = tmp_path / "imu.toml"
    path.write_text(IMU.format(**{**BASE, **change}), encoding="utf-8")
    code, _, err = cli("design", path, "-o", tmp_path / "gains.json")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    assert not (tmp_path / "gains.json").exists()


def test_a_unit_beside_what_the_sensor_measures_is_refused(tmp_path, cli):
    path = tmp_path / "gps.toml"
    text = GPS.format(**GPS_DATASHEET).replace('measures = "position"', 'measures = "angle"')
    path.write_text(text, encoding="utf-8")
    code, _, err = cli("design", path)
    assert code == 2 and err.count("\n") == 1
    assert ('sensors.gps.noise.std: "2.5 m" is in length units (m, m/s, m/s^2, g, ...), but the sensor measures '
            "angle: give it in angle units (rad, deg, rad/s, ...)") in err


def test_a_unit_on_a_rate_is_refused_with_the_number_in_hz(tmp_path, cli):
    """``rate_hz`` is named for its unit: ``"0.2 kHz"`` is not read, the line to write is given."""
    path = tmp_path / "imu.toml"
    path.write_text(IMU.format(**BASE).replace("rate_hz = 200.0", 'rate_hz = "0.2 kHz"'), encoding="utf-8")
    code, _, err = cli("design", path)
    assert code == 2 and err.count("\n") == 1
    assert "sensors.gyro.rate_hz must be a number, got '0.2 kHz'; write rate_hz = 200.0 (a TOML number" in err
    path.write_text(IMU.format(**BASE).replace("rate_hz = 200.0", 'rate_hz = "5 ms"'), encoding="utf-8")
    code, _, err = cli("design", path)
    assert code == 2 and "rate_hz is a TOML number of Hz, without quotes or unit" in err


def test_a_constant_bias_takes_a_signed_unit():
    spec = parse_spec({"structure": "cf2", "sensors": {
        "rate": {"measures": "rate", "rate_hz": 100.0, "noise": {"std": "0.1 deg/s"},
                 "bias": {"model": "constant", "value": "-0.5 deg/s"}},
        "angle": {"measures": "angle", "rate_hz": 100.0, "noise": {"std": "0.5 deg"}}}})
    assert spec.sensor("rate").bias.value == pytest.approx(-0.5 * DEG, rel=4e-16)
    with pytest.raises(SpecError, match=r'sensors\.rate\.bias\.value: "0\.5 deg" is an angle \(rad\), but a '
                                        r"constant bias of a rate sensor is rad/s"):
        parse_spec({"structure": "cf2", "sensors": {
            "rate": {"measures": "rate", "rate_hz": 100.0, "noise": {"std": 0.001},
                     "bias": {"model": "constant", "value": "0.5 deg"}},
            "angle": {"measures": "angle", "rate_hz": 100.0, "noise": {"std": 0.01}}}})


# -- cfdesign noise -o: the datasheet figure beside the SI one ------------------------------------
def _fit(white, random_walk):
    from types import SimpleNamespace

    term = lambda v: SimpleNamespace(value=v, ci=(0.9 * v, 1.1 * v), tau_range_s=(0.01, 10.0))  # noqa: E731
    return SimpleNamespace(name="x", rate_hz=100.0, band_limit_s=None, unresolved_from_s=None,
                           terms={"white": term(white), "random_walk": term(random_walk)}, missing={})


@pytest.mark.parametrize("unit, white, rw, shown", [
    ("rad/s", 0.29 * DEG / 60, 12 * DEG / 3600 / 60, ("= 0.29 deg/sqrt(h)", "= 12 deg/h/sqrt(h)")),
    ("deg/s", 0.005, 1e-4, ("= 0.3 deg/sqrt(h)", "= 21.6 deg/h/sqrt(h)")),  # 0.005 deg/s/sqrt(Hz) * 60
    ("m/s^2", 150e-6 * G, 2e-6 * G, ("= 150 ug/sqrt(Hz)", "= 2 ug/sqrt(s)")),
])
def test_noise_toml_gives_the_datasheet_figure(unit, white, rw, shown):
    from cfdesign.allan import noise_toml

    text = noise_toml([_fit(white, rw)], unit=unit)
    noise, bias = (line for line in text.splitlines() if line.startswith(("noise =", "bias =")))
    assert f"# {unit}/sqrt(Hz) {shown[0]}; " in noise and f"# {unit}/sqrt(s) {shown[1]}; " in bias


def test_noise_toml_without_a_known_unit_gives_none():
    from cfdesign.allan import noise_toml

    text = noise_toml([_fit(1e-3, 1e-5)], unit="u")
    assert "# u/sqrt(Hz); 95% CI" in text and "# u/sqrt(s); 95% CI" in text


@pytest.mark.parametrize("unit, scale", [("deg/s", DEG), ("°/s rms", DEG), ("mrad/s", 1e-3), ("rad/s", 1.0)])
def test_noise_toml_of_a_column_not_in_si_loads_back_as_its_si_value(unit, scale):
    """``cfdesign noise --unit deg/s -o``: its figures were bare numbers in deg/s, which a design file
    reads as SI (57 times too large); a known unit other than SI now goes with the figure as text."""
    from cfdesign.allan import noise_toml

    text = noise_toml([_fit(0.005, 1e-4)], unit=unit)
    tables = "\n".join(line for line in text.splitlines() if not line.startswith("[sensors."))
    design = f'structure = "cf2"\norder = 2\n[sensors.rate]\nmeasures = "rate"\n{tables}\n' \
             '[sensors.angle]\nmeasures = "angle"\nrate_hz = 100.0\nnoise = { std = 0.01 }\n'
    from cfdesign.spec import tomllib

    rate = parse_spec(tomllib.loads(design)).sensor("rate")
    assert rate.noise.density == pytest.approx(0.005 * scale, rel=1e-15)
    assert rate.bias.density == pytest.approx(1e-4 * scale, rel=1e-15)
