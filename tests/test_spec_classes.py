"""Classes of design-file mistakes: each gives one line naming the key and the fix, never a silent
ignore or a misleading 'missing field'; the nearest key for typos ('did you mean')."""

import re
from pathlib import Path

import pytest

import cfdesign
from cfdesign.errors import SpecError
from cfdesign.spec import did_you_mean, load_spec

DCKF3 = (Path(__file__).parent / "fixtures" / "dckf3_5hz.toml").read_text()
CF2 = """structure = "cf2"
order = 2
discrete = true
[sensors.rate]
rate_hz = 100.0
noise = { std = 0.01 }
bias = { model = "random_walk", density = 1e-4 }
[sensors.angle]
rate_hz = 100.0
noise = { std = 0.05 }
[crossover]
hz = 0.5
"""
CHAIN = """structure = "chain"
order = 1
[sensors.gyro]
measures = "rate"
rate_hz = 100.0
noise = { std = 0.01 }
bias = { model = "random_walk", density = 1e-4 }
[sensors.compass]
measures = "angle"
rate_hz = 100.0
noise = { std = 0.05 }
"""
COMPASS = "rate_hz = 5.0\nnoise = { std = 0.04 }"


def _edit(text, old, new):
    assert old in text
    return text.replace(old, new, 1)


CASES = {
    # a typo or another case in a key, at any level: the nearest key
    "sensor key": (_edit(DCKF3, COMPASS, "rate = 5.0\nnoise = { std = 0.04 }"),
                   "sensors.compass.rate: unknown field; did you mean 'rate_hz'?"),
    "noise key": (_edit(DCKF3, "std = 0.04", "sd = 0.04"),
                  "sensors.compass.noise.sd: unknown field; did you mean 'std'?"),
    "bias key": (_edit(DCKF3, "model =", "modle ="), "sensors.gyro.bias.modle: unknown field; did you mean 'model'?"),
    # another spelling, in the table where it means something else than elsewhere ('freq': a sensor's rate)
    "sensor freq": (_edit(DCKF3, COMPASS, "freq = 5.0\nnoise = { std = 0.04 }"),
                    "sensors.compass.freq: unknown field; did you mean 'rate_hz'?"),
    "top-level fs": (_edit(DCKF3, "structure", "fs = 5.0\nstructure"),
                     "fs: unknown field; did you mean 'rate_hz'? rate_hz is a key of a sensor"),
    "top-level key in another case": (_edit(DCKF3, "structure", "Rate_Hz = 5.0\nstructure"),
                                      "Rate_Hz: unknown field; rate_hz is a key of a sensor"),
    "crossover key": (_edit(CF2, "hz = 0.5", "freq = 0.5"), "crossover.freq: unknown field; did you mean 'hz'?"),
    "top key": (_edit(DCKF3, "structure", "sample_time_s = 0.2\nStructure"), "did you mean 'structure'?"),
    "top key prefix": (_edit(DCKF3, "structure", "sample_time = 0.2\nstructure"), "did you mean 'sample_time_s'?"),
    # a value from a fixed list, in another case or misspelt
    "bias model": (_edit(DCKF3, '"random_walk"', '"randomwalk"'), "got 'randomwalk'; did you mean 'random_walk'?"),
    "gain_form": (_edit(DCKF3, "structure", 'gain_form = "Filter"\nstructure'), "did you mean 'filter'?"),
    "structure": (_edit(DCKF3, '"dckf3"', '"DCKF3"'), "unknown structure 'DCKF3'; choose one of"),
    "measures": (_edit(DCKF3, COMPASS, 'measures = "Angle"\n' + COMPASS), "'Angle' (known: angle"),
    "port": (_edit(DCKF3, COMPASS, 'port = "Compass"\n' + COMPASS), "has no sensor 'Compass'"),
    "gain name": (DCKF3 + "[gains]\nK11 = 0.5\n", "gains: unknown K11"),
    # a key written below the wrong table header (TOML gives it to the last header above it)
    "top key below a sensor": (DCKF3 + "wrap_angle = true\n",
                               "sensors.odometry.wrap_angle: unknown field here; wrap_angle is a key of the top level: "
                               "write it above the [sensors.odometry] header"),
    "top key below gains": (DCKF3 + "[gains]\nk22 = 0.0\noutput = \"prior\"\n", "gains.output: unknown field here"),
    "top key below crossover": (CF2 + "name = 'tilt'\n", "crossover.name: unknown field here"),
    "sensor key below noise": (_edit(DCKF3, COMPASS, "[sensors.compass.noise]\nstd = 0.04\nrate_hz = 5.0"),
                               "sensors.compass.noise.rate_hz: unknown field here; rate_hz is a key of "
                               "sensors.compass"),
    "sensor key below [sensors]": ('structure = "cf2"\n[sensors]\nrate_hz = 5.0\n',
                                   "sensors.rate_hz must be a table, got 5.0; rate_hz is a key of a sensor"),
    "sensor key at the top": ("rate_hz = 5.0\n" + DCKF3, "rate_hz: unknown field; rate_hz is a key of a sensor"),
    "crossover key at the top": ("hz = 0.5\n" + DCKF3, "hz: unknown field; write it under a [crossover] header"),
    "noise key in the sensor": (_edit(DCKF3, COMPASS, "rate_hz = 5.0\nstd = 0.04"),
                                "sensors.compass.std: unknown field; white noise is noise = { std = ... }"),
    # a value where a table goes: not 'missing'
    "noise a number": (_edit(DCKF3, "noise = { std = 0.04 }", "noise = 0.04"),
                       "sensors.compass.noise must be a table, got 0.04"),
    "noise an array": (_edit(DCKF3, "noise = { std = 0.04 }", "[[sensors.compass.noise]]\nstd = 0.04"),
                       "sensors.compass.noise must be a table, got an array"),
    "sensors an array": ('structure = "cf2"\n[[sensors]]\nrate_hz = 5.0\n', "sensors must be a table of sensors"),
    "bias a number": (_edit(DCKF3, '{ model = "random_walk", density = 1e-3 }', "1e-3"),
                      "sensors.gyro.bias must be a table, got 0.001"),
    # a figure the design dropped: a density on a (default) constant bias
    "bias density without model": (_edit(CHAIN, 'model = "random_walk", ', ""),
                                   "sensors.gyro.bias.density: a density is the figure of model = 'random_walk'"),
    "constant bias with density": (_edit(DCKF3, COMPASS, COMPASS + "\nbias = { model = 'constant', density = 0.1 }"),
                                   "sensors.compass.bias.density"),
    # names that clash once upper-cased (C macros), quantities of two families
    "names in two cases": (CHAIN + '[sensors.Gyro]\nmeasures = "rate"\nrate_hz = 100.0\nnoise = { std = 0.02 }\n',
                           "sensors.Gyro: gyro and Gyro differ only in case"),
    "angular and linear": (_edit(CHAIN, '"angle"', '"position"'),
                           "sensors.compass.measures: 'position' (linear) beside gyro's 'rate' (angular)"),
    # a sample time that disagrees with the rates: the message says where the base rate comes from
    "sample time": (_edit(DCKF3, "structure", "sample_time_s = 0.1\nstructure"),
                    "base rate 10 Hz (1 / sample_time_s, sample_time_s = 0.1 s), not 5 Hz"),
    # a design that cannot be computed names what the file gave: the crossover, not 'gains'
    "crossover beyond doubles": (_edit(_edit(CF2, "discrete = true\n", ""), "hz = 0.5", "hz = 1e6"),
                                 "crossover.hz: the predicted error covariance"),
    "sample time rounded": (_edit(DCKF3, "structure", "sample_time_s = 0.066667\nstructure").replace("5.0", "15.0"),
                            "; sample_time_s = 0.06666666666666667 (1 / rate_hz) puts it on the ticks"),
    # a fixed structure's sensor under another name: the port that plays it
    "sensor named otherwise": (_edit(DCKF3, "[sensors.compass]", "[sensors.mag]"),
                               "sensors.mag: dckf3 has no such sensor (it has compass, gyro, odometry); a sensor of "
                               "another name plays one of them with port = "),
    # a slower sensor listed first: the base period is 1 / (3 x 5 Hz), not 3 / 5 Hz (0.6 s had been advised)
    "sample time rounded, slower sensor": (_edit(DCKF3, "structure", "sample_time_s = 0.066667\nstructure"),
                                           "; sample_time_s = 0.06666666666666667 (1 / (3 rate_hz)) puts it"),
}
#: the nearest valid name, where the message lists the valid ones
NEAREST = {"structure": "did you mean 'dckf3'?", "measures": "did you mean 'angle'?",
           "port": "did you mean 'compass'?", "gain name": "did you mean 'k11'?"}


@pytest.mark.parametrize("case", CASES)
def test_a_class_of_mistake_is_named_on_one_line(case, tmp_path):
    text, expected = CASES[case]
    path = tmp_path / "d.toml"
    path.write_text(text)
    with pytest.raises(SpecError) as err:
        cfdesign.design(load_spec(path))  # the structure's checks come before any gain is computed
    message = str(err.value)
    assert expected in message and "\n" not in message, message
    assert NEAREST.get(case, "") in message


@pytest.mark.parametrize("word, choices, nearest", [
    ("stddev", ("std", "density"), "std"), ("Frequency", ("hz", "damping"), "hz"),
    (" Rate_Hz", ("rate_hz",), "rate_hz"), ("units", ("noise", "bias", "port", "role"), None),
    ("variance", ("std", "density"), None), (3, ("std",), None)])
def test_the_nearest_name_is_near_or_not_given(word, choices, nearest):
    """A far name gets no suggestion (a variance is not a std): the message lists the allowed keys."""
    assert did_you_mean(word, choices) == (f"; did you mean {nearest!r}?" if nearest else "")


def test_the_cli_prints_the_hint_on_one_line_and_exits_2(tmp_path, cli):
    path = tmp_path / "d.toml"
    path.write_text(CASES["noise key"][0])
    code, _, err = cli("design", path, "-o", tmp_path / "g.json")
    assert code == 2 and err.count("\n") == 1 and "did you mean 'std'?" in err, err
    assert not (tmp_path / "g.json").exists()


def test_what_stays_accepted(tmp_path):
    """Acceleration is of either family (no angular acceleration is named): beside angle and rate it
    designs; an inline [crossover] is the table; a random-walk bias keeps its density."""
    path = tmp_path / "d.toml"
    second_order = _edit(_edit(CHAIN, "order = 1", "order = 2"), 'bias = { model = "random_walk", density = 1e-4 }',
                         '[sensors.acc]\nmeasures = "acceleration"\nrate_hz = 100.0\nnoise = { std = 0.1 }')
    path.write_text(second_order)
    assert cfdesign.design(load_spec(path)).P[0].shape == (2, 2)  # angle and rate: no bias state
    path.write_text(_edit(CF2, "[crossover]\nhz = 0.5\n", "").replace("structure", "crossover = { hz = 0.5 }\n"
                                                                       "structure"))
    assert load_spec(path).crossover == {"hz": (0.5,), "damping": None}
    path.write_text(CHAIN)
    assert load_spec(path).sensor("gyro").bias.psd == pytest.approx(1e-8)


def test_a_rounded_sample_time_beside_a_sensor_read_2_steps_in_3_is_given_exactly():
    """0.066667 s beside a 10 Hz sensor (read 2 steps in 3): the exact sample time, 2 / (3 x 10 Hz),
    not a rate of 9.99995 Hz (the advice for a rate that has no short period)."""
    from cfdesign.designer import multirate_schedule

    with pytest.raises(SpecError, match=re.escape("; sample_time_s = 0.06666666666666667 (2 / (3 rate_hz)) puts it")):
        multirate_schedule({"gps": 10.0}, sample_time_s=0.066667)
