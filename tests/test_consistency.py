"""Consistency at a seam a fuzzing pass found open.

1. ``design(spec)`` on a spec built or edited in Python (``dataclasses.replace``) applies the
   rules of a design file, with parse_spec's own message naming the field, instead of a raw
   TypeError or AttributeError from deep inside.

The designs use the stored position structure (no sympy), so the file stays well under 2 s of CPU.
"""

import copy
import dataclasses

import numpy as np
import pytest

from cfdesign.designer import Structure, design, design_from_structure
from cfdesign.errors import SpecError
from cfdesign.spec import parse_spec

#: 100 Hz accelerometer driving the model, 3 Hz GPS: 100/3 base steps, a period of 100 with reads at 0, 33, 67
POSITION = {"name": "position", "structure": "position", "gain_form": "predictor", "sensors": {
    "accelerometer": {"measures": "acceleration", "rate_hz": 100.0, "noise": {"density": 0.02},
                      "bias": {"model": "random_walk", "density": 1e-3}},
    "gps": {"measures": "position", "rate_hz": 3.0, "noise": {"std": 1.5}}}}


@pytest.fixture(scope="module")
def structure():
    return Structure.load("position")


@pytest.fixture(scope="module")
def spec():
    return parse_spec(POSITION)


@pytest.fixture(scope="module")
def table(structure, spec):
    return design_from_structure(structure, spec)


def _sensor(spec, which, **changes):
    """``spec`` with sensor ``which`` edited in Python."""
    return dataclasses.replace(spec, sensors=tuple(dataclasses.replace(s, **changes) if s.name == which else s
                                                   for s in spec.sensors))


def _file(**edits):
    """POSITION with entries edited as a design file would carry them (``a.b.c``: a nested key;
    ``None``: left out)."""
    data = copy.deepcopy(POSITION)
    for path, value in edits.items():
        *outer, key = path.split(".")
        where = data
        for part in outer:
            where = where[part]
        if value is None:
            where.pop(key, None)
        else:
            where[key] = value
    return data


# ------------------------------------------------------------------ 1. design() checks a spec made in Python
#: (what the Python user wrote, the same mistake in a design file)
EDITS = {
    "rate as text": (lambda s: _sensor(s, "gps", rate_hz="3"), {"sensors.gps.rate_hz": "3"}),
    "negative rate": (lambda s: _sensor(s, "gps", rate_hz=-3.0), {"sensors.gps.rate_hz": -3.0}),
    "NaN rate": (lambda s: _sensor(s, "gps", rate_hz=float("nan")), {"sensors.gps.rate_hz": float("nan")}),
    "no noise": (lambda s: _sensor(s, "gps", noise=None), {"sensors.gps.noise": None}),
    "NaN offset": (lambda s: _sensor(s, "gps", offset_s=float("nan")), {"sensors.gps.offset_s": float("nan")}),
    "gains as a list": (lambda s: dataclasses.replace(s, gains=[1]), {"gains": [1]}),
    "sample time as text": (lambda s: dataclasses.replace(s, sample_time_s="0.01"), {"sample_time_s": "0.01"}),
    "unknown gain form": (lambda s: dataclasses.replace(s, gain_form="kalman"), {"gain_form": "kalman"}),
    "crossover as text": (lambda s: dataclasses.replace(s, crossover={"hz": "2 Hz"}), {"crossover": {"hz": "2 Hz"}}),
    "a sensor table missing its noise": (
        lambda s: dataclasses.replace(s, sensors={"gps": {"rate_hz": 3.0}, "accelerometer": {"rate_hz": 100.0}}),
        {"sensors": {"gps": {"rate_hz": 3.0}, "accelerometer": {"rate_hz": 100.0}}}),
}


@pytest.mark.parametrize("kind", sorted(EDITS))
def test_design_refuses_a_python_edit_as_parse_spec_refuses_the_file(spec, structure, kind):
    edit, file_edits = EDITS[kind]
    with pytest.raises(SpecError) as from_file:
        parse_spec(_file(**file_edits))
    for run in (design, lambda s: design_from_structure(structure, s)):
        with pytest.raises(SpecError) as from_python:
            run(edit(spec))
        assert str(from_python.value) == str(from_file.value)


@pytest.mark.parametrize("edit, message", [
    (lambda s: dataclasses.replace(s, sensors=(s.sensors[1], s.sensors[1])), "sensors.gps: two sensors of that name"),
    (lambda s: dataclasses.replace(s, sensors=({"name": "gps", "rate_hz": 3.0},)), "sensors[0] must be a SensorSpec"),
    (lambda s: dataclasses.replace(s, sensors="gps"), "sensors must be a tuple of SensorSpec, got str"),
    (lambda s: _sensor(s, "gps", name="gps reading"), "sensors.gps reading: sensor names must be ASCII identifiers"),
])
def test_design_names_what_only_python_can_get_wrong(spec, edit, message):
    with pytest.raises(SpecError, match=message.replace("[", r"\[")):
        design(edit(spec))


def test_python_values_a_file_cannot_spell_still_design(spec, structure, table):
    """numpy numbers, a list of sensors, ``gains={}``, a noise given as a table, a bias left None
    (constant): what design can compute with gives the very table of the plain spec."""
    gps = dataclasses.replace(spec.sensor("gps"), rate_hz=np.float32(3.0), noise={"std": 1.5}, bias=None)
    edited = dataclasses.replace(spec, sensors=[spec.sensor("accelerometer"), gps], gains={},
                                 sample_time_s=np.float64(0.01))
    again = design_from_structure(structure, edited)
    assert again.sample_time_s == table.sample_time_s and again.schedule == table.schedule
    assert all(np.array_equal(a, b) for a, b in zip(again.K, table.K, strict=True))
