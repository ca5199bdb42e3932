"""A second adversarial pass over the command line (design, verify, export, bode, noise): each
test is one class of input that gave a traceback-free but unclear error, or a silent wrong
result, before; the outcome allowed is a named one-line error with exit status 2 (a verify FAIL:
1) or a correct result, and no file replaced."""

import dataclasses
import json
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cfdesign
from cfdesign.errors import CfdesignError, SpecError
from cfdesign.runtime import Runtime
from cfdesign.spec import parse_spec

FUZZ = settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

#: a single-rate discrete filter: cheap to design, export and run
CF2 = {"name": "tilt", "structure": "cf2", "order": 2, "discrete": True, "sensors": {
    "gyro": {"port": "rate", "rate_hz": 100.0, "noise": {"density": 2e-4},
             "bias": {"model": "random_walk", "density": 1e-5}},
    "accel": {"port": "angle", "rate_hz": 100.0, "noise": {"std": 0.01}}}}

#: the heading filter of the conftest's log tests, in a file (three sensors, three ports)
HEADING_TOML = """name = "h"
structure = "dckf3"
[sensors.gyro]
rate_hz = 100.0
noise = { std = 0.01 }
bias = { model = "random_walk", density = 1e-4 }
[sensors.compass]
rate_hz = 1.0
noise = { std = 0.05 }
[sensors.odometry]
rate_hz = 10.0
noise = { std = 0.005 }
"""

#: the same sensors all at 100 Hz: a single-rate design, 5 times cheaper than the multirate one
SINGLE_RATE_TOML = HEADING_TOML.replace("rate_hz = 1.0", "rate_hz = 100.0").replace("rate_hz = 10.0", "rate_hz = 100.0")


@pytest.fixture(scope="module")
def tilt():
    return cfdesign.design(parse_spec(CF2))


def _one_line_error(code, err, status=2):
    """The CLI's promise for bad input: exit ``status``, one line on stderr, no traceback."""
    assert code == status and err.count("\n") == 1 and err.startswith("cfdesign") and "Traceback" not in err, err


# ---------------------------------------------------------------------- ports that rename into a clash
@FUZZ
@given(player=st.sampled_from(["gyro", "compass", "odometry"]), port=st.sampled_from(["gyro", "compass", "odometry"]),
       second=st.booleans())
def test_a_sensor_playing_a_port_that_leaves_two_of_one_name_is_named(tmp_path_factory, cli, player, port, second):
    """``port = "compass"`` on the gyro (the compass left as it was) renamed the structure into
    two sensors called gyro: an unnamed 'duplicate sensor name(s): gyro', without the file or
    the field.  Two sensors playing one port did not say which."""
    text = SINGLE_RATE_TOML.replace(f"[sensors.{player}]\n", f'[sensors.{player}]\nport = "{port}"\n')
    other = next(s for s in ("gyro", "compass", "odometry") if s not in (player, port))
    if second:  # a second sensor plays the same port
        text = text.replace(f"[sensors.{other}]\n", f'[sensors.{other}]\nport = "{port}"\n')
    path = tmp_path_factory.mktemp("ports") / "d.toml"
    path.write_text(text)
    code, _, err = cli("design", path)
    if player == port and not second:  # a sensor that plays its own port: the file as it was
        assert code == 0, err
        return
    _one_line_error(code, err)
    assert f"{path}: sensors." in err and ".port: " in err, err
    assert ("both play" if second else "two sensors would be called") in err, err
    with pytest.raises(SpecError):  # the library says the same (no StructureError of the renamed observer)
        cfdesign.design(cfdesign.load_spec(path))


# ---------------------------------------------------------------------- C of a filter that diverges
@FUZZ
@given(scale=st.sampled_from([0.5, 1.0, 3.0, 60.0, 1e4]), row=st.integers(0, 1))
def test_c_export_refuses_what_the_runtime_refuses(tilt, tmp_path_factory, cli, scale, row):
    """A gain edited so that the filter diverges was exported to C in silence, while
    :class:`Runtime` (and ``cfdesign run``) refused the same table: the firmware got a filter
    whose estimates grow whatever the readings.  Reference: the Runtime's verdict."""
    K = tilt.K[0].copy()
    K[row] *= scale
    table = dataclasses.replace(tilt, K=[K])
    folder = tmp_path_factory.mktemp("c")
    path = table.save(folder / "g.json")
    try:
        Runtime(table)
        runs = True
    except CfdesignError as exc:
        runs, why = False, str(exc)
    code, _, err = cli("export", path, "--format", "c", "-o", folder / "c")
    if runs:
        assert code == 0 and len(list((folder / "c").iterdir())) == 3, err
    else:
        _one_line_error(code, err)
        assert why in err and "unstable" in err and not (folder / "c").exists()


# ---------------------------------------------------------------------- a C export onto a file
@pytest.mark.parametrize("target", ["file", "link to nothing", "/dev/null"])
def test_c_export_onto_something_not_a_directory_says_so(tilt, tmp_path, cli, target):
    """``export --format c -o gains.csv`` said 'cannot write to gains.csv: File exists'."""
    table = tilt.save(tmp_path / "g.json")
    out = tmp_path / "out"
    if target == "file":
        out.write_text("keep me")
    elif target == "link to nothing":
        out.symlink_to(tmp_path / "nowhere")
    else:
        out = "/dev/null"
    code, _, err = cli("export", table, "--format", "c", "-o", out)
    _one_line_error(code, err)
    assert "is not a directory" in err and "3 files" in err
    if target == "file":
        assert out.read_text() == "keep me"


# ---------------------------------------------------------------------- bode numbers a design refuses
def _design_accepts(gain, sample_time) -> bool:
    """The reference: whether a design file with these numbers passes its checks."""
    spec = {**CF2, "sample_time_s": sample_time, "gains": {"k1": gain, "k2": 0.001}}
    try:
        parse_spec(spec)
    except SpecError:
        return False
    return True


NUMBERS = ["1e-300", "1e-101", "1e-100", "0.5", "1e100", "1e101", "1e300", "1e-320", "5e-400"]


@FUZZ
@given(gain=st.sampled_from(NUMBERS), sample_time=st.sampled_from(["0.01", "1e-9", "1e-10", "1e9", "2e9", "1e-5000"]))
def test_bode_takes_the_numbers_a_design_file_takes(tmp_path_factory, monkeypatch, cli, gain, sample_time):
    """``bode --sample-time 1e-300`` (or 1e-5000, a number no double holds: it was 0 in the
    plot) drew a figure of nothing with exit 0; a gain of 1e300 likewise.  Reference: the design
    file's own limits (parse_spec) on the same numbers.  (The bands are computed, not drawn.)"""
    import cfdesign.cli
    import cfdesign.plot
    from cfdesign.analysis import frequency_response

    monkeypatch.setattr(cfdesign.plot, "bode_plot", lambda obs, hz=False: frequency_response(obs))
    monkeypatch.setattr(cfdesign.cli, "_figure_bytes", lambda fig, target: b"figure")
    out = tmp_path_factory.mktemp("bode") / "b.png"
    code, _, err = cli("bode", "cf2", "--order", "2", "--discrete", "--gains", f"k1={gain},k2=0.001",
                       "--sample-time", sample_time, "-o", out)
    if _design_accepts(float(gain), float(sample_time)) and float(gain) != 0 and float(sample_time) != 0:
        assert code in (0, 2) and (code == 0) == out.exists(), err  # 2: a response beyond a double, named
        if code:
            _one_line_error(code, err)
    else:
        _one_line_error(code, err)
        assert ("gain k1" in err or "--sample-time" in err) and not out.exists()


# ---------------------------------------------------------------------- schema messages that quote a table
@pytest.mark.parametrize("edit", ["table in a list", "sensors as an object", "K as an object"])
def test_a_schema_violation_says_what_is_wrong_within_the_line(tilt, tmp_path, cli, edit):
    """jsonschema quotes the value it refuses: a whole table in a list (or ``sensors`` given as
    an object) filled the 2000-character line with numbers, and 'is not of type' fell off it."""
    data = tilt.to_dict()
    if edit == "table in a list":
        data = [data] * 50
    elif edit == "sensors as an object":
        data["sensors"] = {s["name"]: s for s in data["sensors"]} | {f"x{i}": {"a": list(range(50))} for i in range(50)}
    else:
        data["K"] = {"phase": data["K"] * 2000}
    path = tmp_path / "g.json"
    path.write_text(json.dumps(data))
    code, _, err = cli("verify", path)
    _one_line_error(code, err)
    assert "is not of type" in err and len(err) < 400, err


def test_the_reference_numbers_are_what_the_tests_assume():
    """The tests above lean on these facts of the limits: a guard against a limit moved."""
    assert _design_accepts(1e100, 0.01) and not _design_accepts(1e101, 0.01) and not _design_accepts(0.5, 1e-10)
    assert float("5e-400") == 0 and np.finfo(float).tiny > 1e-320 > 0


# ---------------------------------------------------------------------- offsets the design dropped
@FUZZ
@given(discrete=st.booleans(), sensor=st.sampled_from(["gyro", "accel"]), offset=st.sampled_from([0.0, 0.004, 0.0099]))
def test_an_offset_the_design_cannot_place_is_named(discrete, sensor, offset):
    """``offset_s`` on a continuous design, or on an input (read at every base tick), was
    accepted and dropped: the table was the one without it.  A measurement of a discrete design
    takes one (at the base rate it reads every tick whatever the offset: period 1)."""
    data = json.loads(json.dumps(CF2))
    data["discrete"] = discrete
    data["sensors"][sensor]["offset_s"] = offset
    if offset and (not discrete or sensor == "gyro"):
        with pytest.raises(SpecError, match=rf"sensors\.{sensor}\.offset_s: .*(continuous|an input)"):
            cfdesign.design(parse_spec(data))
    else:
        assert cfdesign.design(parse_spec(data)).period == 1  # a base-rate measurement reads at every tick


# ---------------------------------------------------------------------- '-' for a file a command reads
@pytest.fixture
def stdin_from():
    """Point file descriptor 0 at a file for one call (the CLI reads '-' as /dev/stdin)."""
    import contextlib
    import os

    @contextlib.contextmanager
    def point(path):
        saved = os.dup(0)
        with open(path, "rb") as fh:
            os.dup2(fh.fileno(), 0)
        try:
            yield
        finally:
            os.dup2(saved, 0)
            os.close(saved)
    return point


@pytest.mark.parametrize("command", ["design", "verify", "verify --spec", "export", "discretize"])
def test_dash_reads_standard_input_as_run_reads_its_logs(tilt, tmp_path, cli, stdin_from, command):
    """``cfdesign design -`` (and verify, export, discretize) looked for a file named '-'; the
    result from standard input is the result from the file (the reference)."""
    spec = tmp_path / "d.toml"
    spec.write_text(HEADING_TOML)
    table = tilt.save(tmp_path / "g.json")
    continuous = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("tilt"))).save(tmp_path / "c.json")
    out = tmp_path / "out.json"
    argv, source = {"design": (["design", "-", "-o", out], spec),
                    "verify": (["verify", "-"], table),
                    "verify --spec": (["verify", table, "--spec", "-"], spec),
                    "export": (["export", "-", "--format", "json", "-o", out], table),
                    "discretize": (["discretize", "-", "--rate-hz", "50", "-o", out], continuous)}[command]
    with stdin_from(source):
        piped = cli(*argv)
    named = cli(*[source if a == "-" else a for a in argv])
    assert piped[0] == named[0] == (1 if command == "verify --spec" else 0), piped  # tilt is not the file's design
    assert piped[1].replace(str(source), "/dev/stdin") == named[1].replace(str(source), "/dev/stdin")


@pytest.mark.parametrize("argv", [["verify", "-", "--spec", "-"], ["run", "-", "-", "-o", "e.csv"]])
def test_two_inputs_cannot_both_be_standard_input(cli, argv):
    code, _, err = cli(*argv)
    _one_line_error(code, err)
    assert "both be standard input" in err or "standard input ('-') can be one file only" in err, err


def test_run_reads_its_table_from_standard_input(tilt, tmp_path, cli, stdin_from):
    """``cfdesign run - log.csv``: the estimates are those of the table named by its file."""
    table = tilt.save(tmp_path / "g.json")
    log = tmp_path / "log.csv"
    log.write_text("time,gyro,accel\n" + "".join(f"{k / 100},0.01,{0.001 * k}\n" for k in range(50)))
    with stdin_from(table):
        piped = cli("run", "-", log, "-o", tmp_path / "piped.csv")
    named = cli("run", table, log, "-o", tmp_path / "named.csv")
    assert piped[0] == named[0] == 0, piped
    assert (tmp_path / "piped.csv").read_text() == (tmp_path / "named.csv").read_text()


# ---------------------------------------------------------------------- encodings of files a command reads
ENCODINGS = {"utf-8 with a BOM": lambda t: b"\xef\xbb\xbf" + t.encode(), "utf-16": lambda t: t.encode("utf-16"),
             "utf-16-be": lambda t: t.encode("utf-16-be"), "latin-1": lambda t: t.replace('"h"', '"h\u00e9"')
             .replace('"tilt"', '"tilt\u00e9"').encode("latin-1"), "crlf": lambda t: t.replace("\n", "\r\n").encode()}


@pytest.mark.parametrize("encoding", sorted(ENCODINGS))
@pytest.mark.parametrize("kind", ["design file", "gain table"])
def test_a_file_in_another_encoding_is_read_or_named_as_such(tilt, tmp_path, cli, kind, encoding):
    """A gain table with a byte-order mark was refused ('decode using utf-8-sig') where a design
    file with one was read; UTF-16 and Latin-1 files gave Python's codec messages; a UTF-16 file
    without a BOM was 'malformed TOML: Invalid statement'.  UTF-8 (with or without a BOM, any
    line ends) reads as the plain file does; another encoding is named."""
    text = HEADING_TOML if kind == "design file" else tilt.to_json()
    path = tmp_path / "f"
    path.write_bytes(ENCODINGS[encoding](text))
    plain = tmp_path / "plain"
    plain.write_text(text)
    argv = ["design"] if kind == "design file" else ["verify"]
    code, out, err = cli(*argv, path)
    if encoding in ("utf-8 with a BOM", "crlf"):
        assert (code, out.replace(str(path), "")) == cli(*argv, plain)[:2] and code == 0, err
    else:
        _one_line_error(code, err)
        assert f"{path}: not UTF-8 text" in err and "save it as UTF-8" in err
        assert ("byte e9 at byte" if encoding == "latin-1" else "UTF-16") in err, err


def test_an_integer_beyond_a_double_in_a_table_is_named(tilt, tmp_path, cli):
    """An integer of 5,000 digits met Python's conversion limit, whose message advised calling
    sys.set_int_max_str_digits()."""
    path = tmp_path / "g.json"
    path.write_text(tilt.to_json().replace('"sample_time_s": 0.01', '"sample_time_s": 1' + "0" * 5000))
    code, _, err = cli("verify", path)
    _one_line_error(code, err)
    assert "an integer of 5001 digits is beyond the range of a double" in err and "sys." not in err


# ---------------------------------------------------------------------- the Python API: what a dict or a path may be
NUMBER_TYPES = {"rate_hz": [np.int64(100), np.uint16(100), Fraction(100), np.float32(100)],
                "std": [Fraction(1, 100), np.float32(0.01), np.int32(1)]}


@FUZZ
@given(field=st.sampled_from(sorted(NUMBER_TYPES)), data=st.data())
def test_a_design_dict_takes_any_real_number_type(tilt, field, data):
    """``rate_hz = np.int64(100)`` (or a Fraction) was 'must be a number' while np.float64 passed.
    Reference: the design from the same numbers as floats."""
    value = data.draw(st.sampled_from(NUMBER_TYPES[field]))
    typed, plain = json.loads(json.dumps(CF2)), json.loads(json.dumps(CF2))
    for spec, number in ((typed, value), (plain, float(value))):
        if field == "std":
            spec["sensors"]["accel"]["noise"] = {"std": number}
        else:
            spec["sensors"]["accel"]["rate_hz"] = spec["sensors"]["gyro"]["rate_hz"] = number
    assert np.array_equal(cfdesign.design(parse_spec(typed)).K[0], cfdesign.design(parse_spec(plain)).K[0])


@pytest.mark.parametrize("where", ["sensor name", "gain name", "top-level key"])
def test_a_design_dict_with_keys_that_are_not_strings_is_named(where):
    """A sensor or gain named by an int (a dict from Python) raised a raw AttributeError or
    TypeError; two unknown keys of different types made the sort of the message raise."""
    data = json.loads(json.dumps(CF2))
    if where == "sensor name":
        data["sensors"][1] = data["sensors"].pop("accel")
    elif where == "gain name":
        data["gains"] = {1: 0.5}
    else:
        data.update({1: 1, "zz": 2})
    with pytest.raises(SpecError, match={"sensor name": r"sensors\.1: sensor names", "gain name": "gains: the name 1",
                                         "top-level key": "1: unknown field"}[where]):
        parse_spec(data)


@pytest.mark.parametrize("value", [None, 123, ["g.json"], "", "  "])
@pytest.mark.parametrize("loader", ["load_spec", "load_gains"])
def test_the_loaders_name_a_value_that_is_no_path(loader, value):
    """``load_spec(None)`` raised pathlib's TypeError; ``load_gains("")`` read '.' ('Is a directory')."""
    from cfdesign.errors import GainTableError

    error = SpecError if loader == "load_spec" else GainTableError
    with pytest.raises(error, match=rf"^{loader}: .*(not a path|names no file)"):
        getattr(cfdesign, loader)(value)


@pytest.mark.parametrize("value", [None, 123, "", "  "])
@pytest.mark.parametrize("writer", ["save", "write_gain_csv", "write_c"])
def test_the_writers_name_a_value_that_is_no_path(tilt, tmp_path, monkeypatch, writer, value):
    """``table.save(None)`` (and the CSV and C writers) raised a raw TypeError; ``write_c(table, "")``
    wrote the three files into the current folder."""
    from cfdesign.codegen import write_c
    from cfdesign.errors import OutputError
    from cfdesign.export import write_gain_csv

    monkeypatch.chdir(tmp_path)
    call = {"save": tilt.save, "write_gain_csv": lambda p: write_gain_csv(tilt, p),
            "write_c": lambda p: write_c(tilt, p)}
    with pytest.raises(OutputError, match=r"^cannot write: .*(not a path|names no file)"):
        call[writer](value)
    assert not list(tmp_path.iterdir())


def test_table_lookups_name_what_names_nothing(tilt):
    """``schedule.phases('x')`` raised 'tuple.index(x): x not in tuple', ``phase_model('a')`` a
    TypeError of string formatting, and ``sensor_names('inputs')`` listed no sensor in silence."""
    from cfdesign.errors import InputError

    with pytest.raises(InputError, match="no measurement 'x' \\(measurements: accel\\)"):
        tilt.schedule.phases("x")
    with pytest.raises(InputError, match="phase must be an integer"):
        tilt.phase_model("a")
    with pytest.raises(InputError, match="role must be 'input' or 'measurement'"):
        tilt.sensor_names("inputs")
    assert tilt.sensor_names("input") == ["gyro"] and tilt.schedule.phases("accel") == (0,)
    assert np.array_equal(tilt.phase_model(np.int64(3))[3], tilt.K[0])


def test_design_hz_without_a_bode_plot_is_refused(tmp_path, cli):
    """``design --hz`` without ``--bode`` was ignored in silence (export refuses its C-only options
    for json and csv the same way); nothing is written."""
    spec = tmp_path / "d.toml"
    spec.write_text(HEADING_TOML)
    code, out, err = cli("design", spec, "--hz", "-o", tmp_path / "g.json")
    _one_line_error(code, err)
    assert "--hz" in err and "--bode" in err and out == "" and not (tmp_path / "g.json").exists()


# ---------------------------------------------------------------------- very slow rates in predictor form
SLOW = HEADING_TOML.replace("rate_hz = 100.0", "rate_hz = 1e-6").replace("rate_hz = 10.0", "rate_hz = 1e-6").replace(
    "rate_hz = 1.0", "rate_hz = 1e-6")


@pytest.mark.parametrize("option", ["", 'output = "prior"', 'gain_form = "filter"'])
def test_a_sample_time_that_leaves_no_posterior_is_named_not_a_failed_check(tmp_path, cli, option):
    """At 1e-6 Hz (T = 1e6 s) F's condition number passes 1e12: the predictor gains have no update
    gain.  The default output then fell to the prior in silence and the design failed its own
    covariance check ('too badly scaled for double precision'); an explicit prior failed it too
    (P_filtered was the Kalman posterior, which no gain of the table gives).  Now the default is
    a SpecError saying what to write; the prior, or the filter form, designs and verifies."""
    spec = tmp_path / "d.toml"
    spec.write_text(SLOW.replace('structure = "dckf3"', f'structure = "dckf3"\n{option}'))
    code, out, err = cli("design", spec, "-o", tmp_path / "g.json")
    if not option:
        _one_line_error(code, err)
        assert "sensors" not in err and "output: dckf3's F at T = 1e+06 s" in err and "gain_form = 'filter'" in err
        return
    assert code == 0, err
    assert ("(posterior): none" in out) == ("prior" in option), out
    code, out, err = cli("verify", tmp_path / "g.json", "--spec", spec)
    assert code == 0 and "6 of 6 checks hold" in out, out + err


# ---------------------------------------------------------------------- a number written as text
@FUZZ
@given(text=st.sampled_from(["100 Hz", "100", "100Hz", " 1e2 Hz ", "100.0 hz", "1.0e+2"]))
def test_a_number_in_quotes_is_named_with_the_line_to_write(tmp_path_factory, cli, text):
    """``rate_hz = "100 Hz"`` was 'must be a number, got '100 Hz''; the message now gives the line
    to write, and that line designs the file (the reference: the same file written with 100.0)."""
    import re

    folder = tmp_path_factory.mktemp("quoted")
    (folder / "d.toml").write_text(SINGLE_RATE_TOML.replace("rate_hz = 100.0", f'rate_hz = "{text}"', 1))
    code, _, err = cli("design", folder / "d.toml")
    _one_line_error(code, err)
    line = re.search(r"write (rate_hz = \S+) \(a TOML number", err)[1]
    (folder / "fixed.toml").write_text(SINGLE_RATE_TOML.replace("rate_hz = 100.0", line, 1))
    (folder / "plain.toml").write_text(SINGLE_RATE_TOML)
    fixed, plain = cli("design", folder / "fixed.toml"), cli("design", folder / "plain.toml")
    assert fixed[0] == 0 and fixed[:2] == plain[:2], fixed


# ---------------------------------------------------------------------- a periodic DARE beyond double precision
def test_a_multirate_design_whose_innovation_covariance_rounds_to_singular_is_named(tmp_path, cli):
    """Found by fuzzing design files: a compass and an odometry read every 5 days, the odometry's
    noise a density (4e-12 rad^2 per reading) beside a predicted variance of 4e16 rad^2 (a gyro
    bias random walk of 0.84 rad/s/sqrt(s)): ``C P C' + R`` of the two angle readings rounds to a
    singular matrix, and numpy's 'Singular matrix' came out as an internal error (exit 3)."""
    spec = tmp_path / "d.toml"
    spec.write_text("""structure = "dckf3"
[sensors.gyro]
rate_hz = 2.2225065297265893e-06
noise = { std = 0.00047 }
bias = { model = "random_walk", density = 0.84 }
[sensors.compass]
rate_hz = 2.2225065297265893e-06
noise = { std = 0.58 }
[sensors.odometry]
rate_hz = 7.408355099088631e-07
noise = { density = 0.00245 }
""")
    code, _, err = cli("design", spec, "-o", tmp_path / "g.json")
    _one_line_error(code, err)
    assert "innovation covariance C P C' + R at phase 0 is singular in double precision" in err
    assert not (tmp_path / "g.json").exists()
