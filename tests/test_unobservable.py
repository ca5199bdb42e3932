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


#: a sparse cfn(4) (one gain per band) whose search for the least position variance ran to the
#: stability boundary: before, it was taken (a pole at |z| = 0.99998, acceleration std ~1e3 times the
#: Kalman gain's, written by `cfdesign run` without a word)
SPARSE_ON_THE_EDGE = {"name": "edge", "structure": "cfn", "bands": 4, "full": False, "discrete": True,
                      "gain_form": "filter", "output": "posterior", "sensors": {
                          "jerk": {"measures": "jerk", "rate_hz": 10.0, "noise": {"std": 0.00237}},
                          "acceleration": {"measures": "acceleration", "rate_hz": 10.0, "noise": {"std": 0.00626}},
                          "velocity": {"measures": "velocity", "rate_hz": 10.0, "noise": {"std": 0.00139}},
                          "position": {"measures": "position", "rate_hz": 10.0, "noise": {"density": 0.00819}}}}


def test_a_sparse_search_that_ends_on_the_stability_boundary_is_refused():
    """The output's variance keeps falling toward the boundary while another state's error grows
    without bound: refused, naming the pole, the state and the full-gain alternative, which designs."""
    from cfdesign.errors import SpecError

    with pytest.raises(SpecError, match=r"no optimum inside the stable region.*\|z\| = [0-9.]+ \(1 - [0-9.e-]+\).*"
                                        r"error std of \w+ is [0-9.e+]+ times the Kalman gain's.*full = true"):
        cfdesign.design(parse_spec(SPARSE_ON_THE_EDGE))
    table = cfdesign.design(parse_spec({**SPARSE_ON_THE_EDGE, "full": True}))
    assert table.checks["stable"]
