"""Design files: every built-in example loads; bad files give one clear line naming the field."""


from pathlib import Path

import pytest

from cfdesign.errors import SpecError
from cfdesign.spec import EXAMPLES, example_path, load_spec

GOOD = (Path(__file__).parent / "fixtures" / "dckf3_5hz.toml").read_text()


@pytest.mark.parametrize("name", EXAMPLES)
def test_examples_load(name):
    spec = load_spec(example_path(name))
    assert spec.sensors and spec.sha256


BAD = [
    (GOOD.replace("std = 0.04", "std = -0.04"), "sensors.compass.noise.std"),
    (GOOD.replace("std = 0.04", "std = nan"), "sensors.compass.noise.std must be finite"),
    (GOOD.replace("[sensors.compass]", "[sensors.compass]\nmeasures = \"spin\""), "sensors.compass.measures"),
    (GOOD.replace("[sensors.compass]", "[sensors.compass]\nmeasures = \"rate\""), "sensors.compass.measures"),
    (GOOD.replace("rate_hz = 5.0\nnoise = { std = 0.01 }", "rate_hz = 1.5915494309189535\nnoise = { std = 0.01 }"),
     "sensors.odometry.rate_hz"),
    (GOOD.replace('structure = "dckf3"', ""), "structure: missing field"),
    (GOOD.replace("noise = { std = 0.04 }", ""), "sensors.compass.noise: missing field"),
    (GOOD.replace("[sensors.odometry]\nrate_hz = 5.0\n", "[sensors.odometry]\n"), "sensors.odometry.rate_hz: missing"),
    (GOOD + "\n[sensors.baro]\nrate_hz = 5.0\nnoise = { std = 1.0 }\n", "sensors.baro"),
    (GOOD.replace("dckf3", "dckf9"), "unknown structure"),
    (GOOD.replace("std = 0.05", "std = '__import__(\"os\").system(\"touch pwned\")'"), "must be a number"),
    (GOOD.replace("[sensors.gyro]", "[sensors.gyro"), "malformed TOML"),
    (GOOD.replace('model = "random_walk", density = 1e-3', 'model = "constant", value = 0.01'),
     "sensors.gyro.bias"),
    (GOOD.replace("std = 0.04", "std = 0.0"), "sensors.compass.noise: zero measurement noise"),
    (GOOD.replace("rate_hz = 5.0\nnoise = { std = 0.04 }", "rate_hz = 5.0\nnoise = { std = 0.04 }\ncolour = 1"),
     "sensors.compass.colour: unknown field"),
    (GOOD.replace('structure = "dckf3"', 'structure = "dckf3"\norder = 2'), "order: does not apply"),
]


@pytest.mark.parametrize("text, field", BAD, ids=[f"bad{i}" for i in range(len(BAD))])
def test_bad_design_files_one_line_exit_2_nothing_written(text, field, tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    spec = tmp_path / "bad.toml"
    spec.write_text(text)
    out = tmp_path / "gains.json"
    code, _, err = cli("design", spec, "-o", out)
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert field in err
    assert not out.exists() and not (tmp_path / "pwned").exists()


def test_a_design_file_with_a_byte_order_mark_loads(tmp_path):
    """Editors on Windows save UTF-8 with a BOM: it was 'malformed TOML: Invalid statement (at line 1)'."""
    plain, marked = tmp_path / "plain.toml", tmp_path / "bom.toml"
    plain.write_text(GOOD)
    marked.write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    assert load_spec(marked).sensors == load_spec(plain).sensors


def test_missing_file():
    with pytest.raises(SpecError, match="cannot read design file"):
        load_spec("/nonexistent/design.toml")


def test_cli_design_default_example_writes_table_and_bode(tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = cli("design", "-o", "g.json", "--bode", "b.png")
    assert code == 0, err
    assert "dckf3" in out and "complementary (exact proof): True" in out
    assert (tmp_path / "g.json").stat().st_size > 500 and (tmp_path / "b.png").stat().st_size > 10_000


def test_toml_text_where_a_path_or_dict_goes():
    """TOML text given to load_spec came back whole in a 'No such file' message over many lines;
    parse_spec said only 'a design must be a table'; design() advised load_spec(the text)."""
    import cfdesign
    from cfdesign.spec import parse_spec, require_spec

    one_line = 'structure = "cf2"'
    for text in (GOOD, one_line, "[sensors.gyro]"):
        for call in (load_spec, parse_spec, lambda t: require_spec(t, "design")):
            with pytest.raises(SpecError, match=r"tomllib\.loads\(text\)") as err:
                call(text)
            assert "\n" not in str(err.value)
    # a path stays a path, one that starts as a key = value too (a sweep's folder k=2/): it was told
    # it was TOML text
    for path in ("no/such/design.toml", "k=2/design.toml", "lr=0.1.toml", "[draft] design.toml"):
        with pytest.raises(SpecError, match="cannot read design file"):
            load_spec(path)
        with pytest.raises(SpecError, match=r"read the design file with cfdesign\.load_spec"):
            require_spec(path, "design")
    assert cfdesign.design(parse_spec(__import__("tomllib").loads(GOOD))).K


def test_port_hint_reads_what_the_sensor_measures():
    """A 'gyro' measuring rate on cf2 was told port = "angle" (the first name in the alphabet)."""
    import cfdesign
    from cfdesign.spec import parse_spec

    for measures, port in (("rate", "rate"), ("angle", "angle")):
        data = {"structure": "cf2", "sensors": {"mine": {"measures": measures, "rate_hz": 100.0,
                                                          "noise": {"std": 0.01}}}}
        with pytest.raises(SpecError, match=f'port = "{port}": it reads {measures}'):
            cfdesign.design(parse_spec(data))
