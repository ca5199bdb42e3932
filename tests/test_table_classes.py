"""Adversarial pass over gain tables, export and verify, one property per class of input that was
mishandled: a number beyond the double range in any field, a sensor name too long for C, an output
name ending in '/', and a sensor that differs from the spec's in one field."""

import dataclasses
import json
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cfdesign
from cfdesign.codegen import render_c
from cfdesign.errors import CfdesignError, GainTableError, OutputError
from cfdesign.export import write_gain_csv
from cfdesign.files import open_atomic, write_text
from cfdesign.gains import Schedule, load_gains
from cfdesign.verify import verify_table

FUZZ = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def cf3():
    """A continuous table with named gains (cheap to design) and its spec."""
    spec = cfdesign.load_spec(cfdesign.example_path("cf3"))
    return spec, cfdesign.design(spec)


@pytest.fixture(scope="module")
def position():
    """A discrete multirate table (the C generator's input)."""
    return cfdesign.design(cfdesign.load_spec(cfdesign.example_path("position")))


def numeric_leaves(value, path=()):
    """The path of every number in a JSON value."""
    if isinstance(value, dict):
        return [p for key, item in value.items() for p in numeric_leaves(item, (*path, key))]
    if isinstance(value, list):
        return [p for i, item in enumerate(value) for p in numeric_leaves(item, (*path, i))]
    return [path] if isinstance(value, (int, float)) and not isinstance(value, bool) else []


def test_a_number_beyond_the_double_range_is_refused_wherever_it_is(cf3, tmp_path):
    """``1e309`` reads as inf: in a matrix it was refused, in ``gains``, ``checks`` or
    ``provenance`` it loaded, and writing the table (``export --format json``) then failed with an
    internal error.  Every number of the table, replaced in turn, is refused by load_gains with
    the field named."""
    data = cf3[1].to_dict()
    leaves = numeric_leaves(data)
    assert any(p[0] == "gains" for p in leaves) and any(p[0] == "provenance" for p in leaves)
    path = tmp_path / "t.json"
    for where in leaves:
        for token in ("1e309", "-1e400"):
            edited = json.loads(json.dumps(data))
            node = edited
            for key in where[:-1]:
                node = node[key]
            node[where[-1]] = "@"
            path.write_text(json.dumps(edited).replace('"@"', token))
            with pytest.raises(GainTableError) as info:
                load_gains(path)
            if where[0] in ("gains", "checks", "provenance"):  # matrices name the matrix ('K[0] has a value ...')
                assert "/".join(map(str, where)) in str(info.value) and "inf" in str(info.value)


@FUZZ
@given(length=st.integers(64, 20_000))
def test_a_sensor_name_too_long_for_c_is_named_briefly_with_the_advice(position, length):
    """A 5000-character sensor name filled the error line with the C name, and the advice at its
    end was cut off (the CLI caps a line at 2000 characters)."""
    table = position
    names = {"gps": "g" * length}
    sensors = [dataclasses.replace(s, name=names.get(s.name, s.name)) for s in table.sensors]
    measured = [s.name for s in sensors if s.role == "measurement"]
    schedule = Schedule.from_names(measured, [[names.get(x, x) for x in table.schedule.names(k)]
                                              for k in range(table.period)])
    with pytest.raises(CfdesignError) as info:
        render_c(dataclasses.replace(table, sensors=sensors, schedule=schedule))
    message = str(info.value)
    assert len(message) < 300 and message.endswith("C code needs a shorter prefix or sensor name")
    assert f"has {len('POSITION_Y_') + length} characters" in message


@pytest.mark.parametrize("writer", ["save", "csv", "text", "stream"])
def test_an_output_name_ending_in_a_slash_is_not_written_as_a_file(cf3, tmp_path, writer):
    """``-o out/`` (a folder meant) wrote a file named ``out``: pathlib drops the slash."""
    table = cf3[1]
    write = {"save": table.save, "csv": lambda p: write_gain_csv(table, p), "text": lambda p: write_text(p, "x"),
             "stream": lambda p: open_atomic(p).__enter__()}[writer]
    for name in ("new/", "new//", "sub/new/"):
        with pytest.raises(OutputError, match=re.escape(f"cannot write {tmp_path}/{name}: a name ending in '/'")):
            write(f"{tmp_path}/{name}")
        assert not list(tmp_path.iterdir())
    (tmp_path / "folder").mkdir()
    with pytest.raises(OutputError, match="it is a directory"):
        write(f"{tmp_path}/folder/")


@FUZZ
@given(data=st.data())
def test_verify_names_the_sensor_field_that_differs_from_the_spec_and_by_how_much(cf3, data):
    """Every sensor listed in full, rates as ``5 Hz``, hid a rate differing below the sixth digit
    (the two lists read the same) and named no field: the FAIL line names the sensor, the field
    and both values, the rate's relative difference to two digits."""
    spec, table = cf3
    sensor = data.draw(st.sampled_from(table.sensors))
    key = data.draw(st.sampled_from(["rate_hz", "order", "rate_hz"]))
    if key == "rate_hz":
        relative = data.draw(st.sampled_from([1, -1])) * 10.0 ** data.draw(st.integers(-11, -1))
        value = sensor.rate_hz * (1 + relative)
    else:
        value = sensor.order + 1
    sensors = [dataclasses.replace(s, **{key: value}) if s == sensor else s for s in table.sensors]
    checks = verify_table(dataclasses.replace(table, sensors=sensors), spec)
    lines = [c.line() for c in checks if not c.ok]
    line = next(x for x in lines if x.startswith("FAIL spec: sensors"))
    assert f"{sensor.name} {key}: the table has {value!r}, the spec {getattr(sensor, key)!r}" in line
    if key == "rate_hz":
        assert f"(relative difference {(value - sensor.rate_hz) / sensor.rate_hz:+.1e})" in line


@pytest.mark.parametrize("example", ["cf3", "position", "robot-heading", "tilt"])
def test_a_file_that_is_not_a_table_says_what_it_is(cf3, position, tmp_path, example):
    """An empty file, the CSV export and a design file given as the table all said 'not valid JSON:
    Expecting value: line 1 column 1 (char 0)'; each now says what it is and what to read.  A cut
    table (which starts as one) keeps the JSON parser's place of the fault."""
    path = tmp_path / "t.json"
    cases = {"": "the file is empty", "\ufeff \r\n": "the file is empty",
             cfdesign.example_path(example).read_text(): "looks like a design file (TOML)"}
    for table in (cf3[1], position):
        write_gain_csv(table, tmp_path / "g.csv")
        cases[(tmp_path / "g.csv").read_text()] = "is a CSV of the gains"
        cases[table.to_json()[:-40]] = "not valid JSON: Expecting"
    cases["[1, 2"] = "not valid JSON: Expecting ',' delimiter"
    for text, told in cases.items():
        path.write_text(text)
        with pytest.raises(GainTableError, match=re.escape(told)):
            load_gains(path)
