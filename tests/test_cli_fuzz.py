"""A second adversarial pass over the command line (design, verify, export, bode, noise): each
test is one class of input that gave a traceback-free but unclear error, or a silent wrong
result, before; the outcome allowed is a named one-line error with exit status 2 (a verify FAIL:
1) or a correct result, and no file replaced."""

import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cfdesign
from cfdesign.errors import SpecError
from cfdesign.spec import parse_spec

# as the ``cfdesign`` command's own process (cli.console): jsonschema without its optional IRI
# checker, whose grammars took 3 s of CPU at the first gain table read here
sys.modules.setdefault("rfc3987_syntax", None)

FUZZ = settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

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
    text = HEADING_TOML.replace(f"[sensors.{player}]\n", f'[sensors.{player}]\nport = "{port}"\n')
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



