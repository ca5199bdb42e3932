"""Consistency at two seams a fuzzing pass found open.

1. ``design(spec)`` on a spec built or edited in Python (``dataclasses.replace``) applies the
   rules of a design file, with parse_spec's own message naming the field, instead of a raw
   TypeError or AttributeError from deep inside.
2. ``verify`` without ``--spec`` fails a table whose sensors' ``rate_hz`` disagree with its
   schedule (the reads per period, the sample time, the spacing of the reads).

The designs use the stored position structure (no sympy), so the file stays well under 2 s of CPU.
"""

import copy
import dataclasses

import numpy as np
import pytest

from cfdesign.designer import Structure, design, design_from_structure, gains_for_schedule
from cfdesign.errors import SpecError
from cfdesign.gains import Schedule
from cfdesign.spec import parse_spec
from cfdesign.verify import rate_check, verify_table

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


# ------------------------------------------------------------------ 2. verify: rate_hz against the schedule
def _failed(table):
    return [c.line() for c in verify_table(table) if not c.ok]


def _with_rate(table, name, rate):
    return dataclasses.replace(table, sensors=tuple(dataclasses.replace(s, rate_hz=rate) if s.name == name else s
                                                    for s in table.sensors))


def test_designed_tables_read_each_sensor_at_its_rate(structure, spec, table):
    """A fractional ratio (3 Hz beside 100 Hz: gaps of 33 and 34), an integer one (10 Hz: every 10
    ticks), an offset, the filter form, a rate within the designer's 1e-9 of a fraction, and the
    gains a log's arrivals reschedule (the GPS 10 ticks late) all pass."""
    assert table.schedule.phases("gps") == (0, 33, 67)
    tables = [table, gains_for_schedule(table, table.schedule.shifted({"gps": 10}))]
    for edit in ({"rate_hz": 10.0}, {"offset_s": 0.2}, {"rate_hz": 3.0 * (1 + 5e-10)}):
        tables.append(design_from_structure(structure, _sensor(spec, "gps", **edit)))
    tables.append(design_from_structure(structure, dataclasses.replace(spec, gain_form="filter")))
    for t in tables:
        reads = len(t.schedule.phases("gps"))
        # the reference: the GPS's reads in one period over the period's duration
        rate = next(s.rate_hz for s in t.sensors if s.name == "gps")
        assert reads / (t.period * t.sample_time_s) == pytest.approx(rate, rel=1e-9)
        assert _failed(t) == []
        assert rate_check(t).ok and f"gps {rate:g} Hz" in rate_check(t).detail


@pytest.mark.parametrize("rate", [6.0, 1.0, 3.3, 3.0 * (1 + 1e-6)])
def test_a_declared_rate_the_schedule_does_not_read_is_the_only_failure(table, rate):
    lines = _failed(_with_rate(table, "gps", rate))
    assert lines == [f"FAIL sensor rates match the schedule: gps declares {rate:.10g} Hz, the schedule reads it at "
                     "3 of 100 phases of 0.01 s: 3 Hz (tolerance 1e-08): the table runs a sensor at another rate than "
                     "its noise figures were converted at"]


def test_an_input_at_another_rate_than_the_tick_fails(table):
    (line,) = _failed(_with_rate(table, "accelerometer", 50.0))
    assert "accelerometer declares 50 Hz, an input, read at every tick of 0.01 s: 100 Hz" in line


def test_a_sample_time_the_rates_do_not_fit_fails_naming_every_sensor(table):
    lines = _failed(dataclasses.replace(table, sample_time_s=0.02))
    (line,) = [x for x in lines if x.startswith("FAIL sensor rates")]
    assert "accelerometer declares 100 Hz" in line and "gps declares 3 Hz" in line and ": 1.5 Hz" in line


def test_reads_bunched_in_the_period_fail_though_their_count_is_right(table):
    """Three reads in a period of 100 phases are 3 Hz only if spread 33 or 34 phases apart."""
    moved = {0: 0, 33: 1, 67: 2}
    phases = [[] for _ in range(table.period)]
    for k in table.schedule.phases("gps"):
        phases[moved[k]] = ["gps"]
    K = [table.K[1]] * table.period  # phase 1: no reading
    for old, new in moved.items():
        K[new] = table.K[old]
    bunched = dataclasses.replace(table, schedule=Schedule.from_names(["gps"], phases), K=K)
    check = rate_check(bunched)
    assert not check.ok and "gps declares 3 Hz, a read every 33.3333 phases" in check.detail
    assert "gaps of 1, 98 phases" in check.detail


def test_cli_verify_prints_the_failure_and_exits_1(table, tmp_path, cli):
    path = _with_rate(table, "gps", 1.0).save(tmp_path / "gains.json")
    code, out, _ = cli("verify", path)
    assert code == 1
    assert "FAIL sensor rates match the schedule: gps declares 1 Hz, the schedule reads it at 3 of 100 phases" in out
    code, out, _ = cli("verify", table.save(tmp_path / "good.json"))
    assert code == 0 and "PASS sensor rates match the schedule" in out
