"""A design whose states no sensor sees is refused naming the states, through the API and the CLI."""

import pytest

import cfdesign
from cfdesign.errors import NotDetectableError
from cfdesign.spec import parse_spec


def _chain(discrete, wheel_rate):
    return {"name": "velocity only", "structure": "chain", "order": 2, "discrete": discrete, "sensors": {
        "accel": {"measures": "acceleration", "rate_hz": 100.0, "noise": {"std": 0.05}},
        "wheel": {"measures": "velocity", "rate_hz": wheel_rate, "noise": {"std": 0.02}}}}


@pytest.mark.parametrize(("discrete", "wheel_rate"), [(False, 100.0), (True, 100.0), (True, 10.0)])
def test_a_position_no_sensor_measures_is_named(discrete, wheel_rate):
    """Velocity measured, position not: the observability matrix has the position as its null space,
    continuous, discrete single-rate (DARE) and multirate (periodic DARE) alike; the solver's own
    finding (the mode) stays in the message."""
    with pytest.raises(NotDetectableError) as err:
        cfdesign.design(parse_spec(_chain(discrete, wheel_rate)))
    msg = str(err.value)
    assert msg.startswith("position is not observable from the measurements (wheel: velocity)")
    assert "velocity is" not in msg and "PBH" in msg


def test_the_cli_names_the_unseen_state_on_one_line(cli, tmp_path):
    """Through ``cfdesign design``: one line on stderr, exit 2, no table written."""
    spec = tmp_path / "s.toml"
    spec.write_text('name = "velocity only"\nstructure = "chain"\norder = 2\ndiscrete = true\n'
                    '[sensors.accel]\nmeasures = "acceleration"\nrate_hz = 100.0\nnoise = { std = 0.05 }\n'
                    '[sensors.wheel]\nmeasures = "velocity"\nrate_hz = 10.0\nnoise = { std = 0.02 }\n')
    code, _, err = cli("design", spec, "-o", tmp_path / "g.json")
    assert code == 2 and not (tmp_path / "g.json").exists()
    assert len(err.strip().splitlines()) == 1
    assert "position is not observable from the measurements (wheel: velocity)" in err
