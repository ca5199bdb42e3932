"""Noise identification (cfdesign.allan, ``cfdesign noise``) on synthetic recordings with known
white noise density N and rate random walk K (the Allan-variance model of IEEE Std 952 and
El-Sheimy et al., *Analysis and modeling of inertial sensors using Allan variance*)."""

import math
import re
import sys

import numpy as np
import pytest

from cfdesign.allan import edf_simple, identify_noise, noise_toml, oadev
from cfdesign.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

N_TRUE, K_TRUE, RATE = 1.7e-4, 2.0e-5, 100.0  # rad/s/sqrt(Hz), rad/s/sqrt(s), Hz


def gyro(seconds, N=N_TRUE, K=K_TRUE, rate=RATE, seed=0):
    """A gyro at rest: white noise of density N (per-sample std N sqrt(f)) plus a random-walk bias."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate)
    y = N * math.sqrt(rate) * rng.standard_normal(n)
    if K:
        y += np.cumsum(K / math.sqrt(rate) * rng.standard_normal(n))
    return y


@pytest.fixture(scope="module")
def two_hours():
    return gyro(7200)


def test_two_hours_at_100_hz_recovers_N_and_K(two_hours):
    fit = identify_noise(two_hours, RATE, "gyro_x")
    assert fit.white_density == pytest.approx(N_TRUE, rel=0.10)
    assert fit.random_walk_density == pytest.approx(K_TRUE, rel=0.25)
    for key, true in (("white", N_TRUE), ("random_walk", K_TRUE)):
        term = fit.terms[key]
        assert term.ci[0] <= true <= term.ci[1]
        assert term.tau_range_s[0] < term.tau_range_s[1]
    assert fit.bias_instability is None and "bias_instability" in fit.missing
    assert fit.terms["white"].tau_range_s[0] == pytest.approx(0.01)
    assert fit.design_entries() == {"noise": {"density": fit.white_density},
                                    "bias": {"model": "random_walk", "density": fit.random_walk_density}}


def test_white_only_returns_only_white():
    fit = identify_noise(gyro(600, K=0, seed=1), RATE)
    assert fit.white_density == pytest.approx(N_TRUE, rel=0.05)
    assert set(fit.terms) == {"white"}
    assert fit.random_walk_density is None and fit.design_entries() == {"noise": {"density": fit.white_density}}


@pytest.mark.parametrize("seed", [1028, 1041, 1042])
def test_white_only_ten_minutes_claims_no_term_on_its_last_octaves(seed):
    """Ten minutes of white noise at 50 Hz whose last two octave points (82 and 164 s, a few
    degrees of freedom each) happened to sit high: a bias instability B = 3e-5 was reported over
    them, its slope (-0.4 to -0.7, white noise's) unchecked because two such points give it to
    +-0.9.  No term may rest on a slope the recording does not resolve."""
    rng = np.random.default_rng(seed)
    fit = identify_noise(N_TRUE * math.sqrt(50.0) * rng.standard_normal(30_000), 50.0)
    assert set(fit.terms) == {"white"}
    assert "slope to +-" in fit.missing["bias_instability"]


def test_random_walk_only_returns_only_the_random_walk():
    fit = identify_noise(gyro(600, N=0, seed=2), RATE)
    assert set(fit.terms) == {"random_walk"}
    assert fit.random_walk_density == pytest.approx(K_TRUE, rel=0.25)
    assert fit.white_density is None


@pytest.mark.parametrize("seconds", [5, 10, 60])
def test_a_random_walk_alone_has_the_degrees_of_freedom_of_its_correlated_octaves(seconds):
    """A random walk without white noise: its readings' differences are white, so the Allan
    variance at the first octave alone is a chi-square of about one degree of freedom per reading.
    The fit combines it with the next octaves, whose estimates are noisier and correlated with it
    (0.7 to 0.9 between neighbours): over 400 seeds of 10 s and of 60 s the fitted K^2 scattered
    as 0.67 (+-0.05) of that point's degrees of freedom.  The interval took the point's own
    (95 % intervals covered K in 85 to 90 % of recordings); it must take the fit's."""
    n = int(seconds * RATE)
    fit = identify_noise(gyro(seconds, N=0, seed=4), RATE)
    best_point = float(edf_simple(n + 1, 1, -2))
    assert 0.5 < fit.terms["random_walk"].edf / best_point < 0.8


def test_a_random_walk_that_looks_like_a_ramp_is_the_random_walk():
    """One hour of N = 2e-3 and K = 5e-5: over the last octaves this realisation of the random
    walk is fitted as well by a rate ramp, and eliminating both terms at once lost K (every term
    reported 'no share').  The elimination drops one term at a time and keeps the random walk
    where it explains the same octaves; the dropped terms keep their reasons."""
    rng = np.random.default_rng(0)
    f, n = 100.0, 360_000
    x = 2e-3 * math.sqrt(f) * rng.standard_normal(n) + np.cumsum(5e-5 / math.sqrt(f) * rng.standard_normal(n))
    fit = identify_noise(x, f)
    assert fit.random_walk_density == pytest.approx(5e-5, rel=0.25)
    assert "rate_ramp" not in fit.terms and "no share" not in fit.missing["bias_instability"]


def test_a_genuine_rate_ramp_is_reported_as_a_ramp():
    """A linear drift of 1e-6 u/s under white noise (two hours) has the ramp's slope +1 over
    four octaves: the random walk fits it clearly worse, so the ramp is what is reported."""
    rng = np.random.default_rng(3)
    f, n = 100.0, 720_000
    x = 2e-3 * math.sqrt(f) * rng.standard_normal(n) + 1e-6 * np.arange(n) / f
    fit = identify_noise(x, f)
    assert fit.random_walk_density is None and fit.terms["rate_ramp"].value == pytest.approx(1e-6, rel=0.15)


def test_a_recording_too_short_for_the_random_walk_says_so():
    fit = identify_noise(gyro(60, seed=3), RATE)  # the random walk dominates only beyond ~15 s averaging
    assert fit.random_walk_density is None
    assert "longer" in fit.missing["random_walk"]
    assert "not identified" in fit.summary("rad/s")
    assert "# bias: no random walk identified" in noise_toml([fit])


def test_overlapping_adev_matches_allantools(two_hours):
    allantools = pytest.importorskip("allantools")
    tau, adev, m = oadev(two_hours[:200_000], RATE)
    t2, ad2, _, _ = allantools.oadev(two_hours[:200_000], rate=RATE, data_type="freq", taus=tau)
    assert np.allclose(t2, tau) and np.allclose(ad2, adev, rtol=1e-12, atol=0)
    for alpha in (2, 0, -2):
        ours = edf_simple(200_001, m, alpha)
        theirs = [allantools.edf_simple(200_001, int(k), alpha) for k in m]
        assert np.allclose(ours, theirs, rtol=1e-12)


def test_white_noise_closed_form():
    """White samples of std s at rate f: AVAR(m) = s^2 / m, i.e. N = s / sqrt(f) (cfdesign.noise's convention)."""
    rng = np.random.default_rng(4)
    y = 0.3 * rng.standard_normal(400_000)
    _tau, adev, m = oadev(y, 50.0)
    assert np.allclose(adev[:8] ** 2 * m[:8] / 0.09, 1, rtol=0.02)


@pytest.mark.parametrize("x, rate, message", [
    (np.ones(10), 100.0, "too few"),
    (np.r_[np.zeros(50), np.nan], 100.0, "not finite"),
    (np.zeros(100), 100.0, "constant"),
    (np.arange(100.0), 0.0, "rate_hz"),
    (["0.1"] * 10 + ["a"] * 10, 100.0, "real numbers are needed"),  # numpy's ValueError
    ([1j] * 20, 100.0, "real numbers are needed"),  # float()'s TypeError
    (np.arange(20.0) * 1j, 100.0, "real numbers are needed"),  # the imaginary part dropped with a warning
])
def test_bad_recordings(x, rate, message):
    with pytest.raises(InputError, match=message):
        identify_noise(x, rate)


def _log(path, columns, rate=RATE, time=True):
    n = len(next(iter(columns.values())))
    head = (["time"] if time else []) + list(columns)
    rows = [",".join(head)]
    for i in range(n):
        rows.append(",".join(([f"{i / rate:.6f}"] if time else []) + [repr(float(v[i])) for v in columns.values()]))
    path.write_text("\n".join(rows) + "\n")
    return path


def test_cli_three_axes_to_design_file_entries(cli, tmp_path):
    axes = {f"gyro_{a}": gyro(300, seed=10 + i) for i, a in enumerate("xyz")}
    log = _log(tmp_path / "static.csv", axes)
    code, out, err = cli("noise", log, "--column", "gyro_x,gyro_y", "--column", "gyro_z", "--time", "time",
                         "-o", tmp_path / "noise.toml", "--plot", tmp_path / "adev.png", "--unit", "rad/s")
    assert code == 0, err
    assert out.count("white noise density N: N =") == 3 and "rad/s/sqrt(Hz)" in out
    data = tomllib.loads((tmp_path / "noise.toml").read_text())
    assert set(data["sensors"]) == set(axes)
    for entry in data["sensors"].values():
        assert entry["rate_hz"] == pytest.approx(RATE)
        assert entry["noise"]["density"] == pytest.approx(N_TRUE, rel=0.1)
    assert (tmp_path / "adev.png").read_bytes()[:4] == b"\x89PNG"


def test_noise_entries_design_a_filter(cli, tmp_path):
    """The loop: a static log -> cfdesign noise -> a design file -> design -> verify."""
    from cfdesign.designer import design
    from cfdesign.spec import parse_spec

    log = _log(tmp_path / "gyro.csv", {"gyro": gyro(600, seed=7)}, time=False)
    assert cli("noise", log, "--column", "gyro", "--rate-hz", 100, "-o", tmp_path / "n.toml")[0] == 0
    text = (tmp_path / "n.toml").read_text()
    assert 'port = "rate"' in text  # the header says what a pasted table needs besides measures
    sensors = tomllib.loads(text)["sensors"]
    if "bias" not in sensors["gyro"]:  # 600 s may not show K: the comment says what the design then needs
        assert 'needs bias = { model = "random_walk", density = ... }' in text
    sensors["gyro"].setdefault("bias", {"model": "random_walk", "density": K_TRUE})
    sensors["gyro"]["port"] = "rate"
    spec = parse_spec({"structure": "cf2", "order": 2, "discrete": True,
                       "sensors": {**sensors, "angle": {"rate_hz": 100.0, "noise": {"std": 0.01}}}})
    table = design(spec)
    assert table.checks["complementary"] and table.checks["stable"]


@pytest.mark.parametrize("args, message, time", [
    (["--column", "nope", "--rate-hz", "100"], "no column 'nope'", True),
    (["--column", "gyro"], "has no time column ('time', 't' or 'timestamp'", False),
    (["--column", "gyro", "--rate-hz", "100", "--time", "time"], "not both", True),
    (["--column", "gyro", "--rate-hz", "100", "--time-unit", "ms"], "--rate-hz reads none", True),
    (["--column", "gyro", "--rate-hz", "-1"], "positive", True),
])
def test_cli_errors_are_one_line(cli, tmp_path, args, message, time):
    log = _log(tmp_path / "g.csv", {"gyro": gyro(10)}, time=time)
    code, _out, err = cli("noise", log, *args)
    assert code == 2 and message in err and err.count("\n") == 1


def test_cli_bad_cells_and_times_name_the_line(cli, tmp_path):
    log = tmp_path / "bad.csv"
    log.write_text("time,gyro\n0,0.1\n0.01,abc\n")
    code, _, err = cli("noise", log, "--column", "gyro", "--rate-hz", 100)
    assert code == 2 and "line 3" in err and "'gyro'" in err
    log.write_text("time,gyro\n" + "".join(f"{t},{0.1 * (-1) ** i}\n"
                                            for i, t in enumerate([0, 0.01, 0.02, 0.5, 0.51] + [0.52] * 0)))
    code, _, err = cli("noise", log, "--column", "gyro", "--time", "time")
    assert code == 2 and "line 5" in err and "evenly sampled" in err


def test_cli_reads_a_csv_with_a_byte_order_mark(cli, tmp_path):
    """A spreadsheet's UTF-8 export starts with a BOM; cfdesign run reads such logs, and noise
    said there was no column 'time' (header '?time')."""
    log = _log(tmp_path / "g.csv", {"gyro": gyro(60)})
    plain = cli("noise", log, "--column", "gyro", "--time", "time")
    log.write_bytes(b"\xef\xbb\xbf" + log.read_bytes())
    code, out, err = cli("noise", log, "--column", "gyro", "--time", "time")
    assert code == 0, err
    assert out == plain[1]


def test_cli_rate_from_jittered_times_is_the_nominal_rate(cli, tmp_path):
    """A time column with jitter gave rate_hz = 99.99998..., and a design file with that entry
    beside a 10 Hz sensor was refused (not a fraction of the base rate)."""
    from cfdesign.designer import design
    from cfdesign.spec import parse_spec

    rng = np.random.default_rng(3)
    n = 6000
    t = np.arange(n) / RATE + 0.002 * rng.uniform(-1, 1, n)  # +-0.2 tick of jitter
    log = tmp_path / "j.csv"
    log.write_text("time,gyro\n" + "".join(f"{a:.6f},{float(v)!r}\n" for a, v in zip(t, gyro(n / RATE), strict=True)))
    code, _, err = cli("noise", log, "--column", "gyro", "--time", "time", "-o", tmp_path / "n.toml")
    assert code == 0, err
    sensors = tomllib.loads((tmp_path / "n.toml").read_text())["sensors"]
    assert sensors["gyro"]["rate_hz"] == 100.0
    sensors["gyro"].update(port="rate", bias={"model": "random_walk", "density": K_TRUE})
    table = design(parse_spec({"structure": "cf2", "order": 2, "discrete": True,
                               "sensors": {**sensors, "angle": {"rate_hz": 10.0, "noise": {"std": 0.01}}}}))
    assert table.period == 10


@pytest.mark.parametrize("stamps", ["jitter of 0.45 step", "pairs stamped together"])
def test_cli_times_jittered_up_to_half_a_step_are_read(cli, tmp_path, stamps):
    """Stamps jittered by +-0.4 step (one step in a few then 1.6 steps) or readings stamped in
    pairs as their packet arrives (steps of 0.05 and 1.95) were refused as jumps ('cut the log at
    the gap') although no reading was missing; cfdesign run takes such stamps. A reading that is
    missing from a jittered log is still named at its line."""
    rng = np.random.default_rng(5)
    n = 6000
    t = np.arange(n) / RATE
    t = t + (0.0045 * rng.uniform(-1, 1, n) if stamps.startswith("jitter") else np.r_[0.0, 0.0095] [np.arange(n) % 2])
    y = gyro(n / RATE)
    log = tmp_path / "j.csv"
    log.write_text("time,gyro\n" + "".join(f"{a:.6f},{float(v)!r}\n" for a, v in zip(t, y, strict=True)))
    code, out, err = cli("noise", log, "--column", "gyro", "--time", "time")
    assert code == 0 and "at 100 Hz" in out, err
    rows = zip(np.delete(t, 4000), y, strict=False)
    log.write_text("time,gyro\n" + "".join(f"{a:.6f},{float(v)!r}\n" for a, v in rows))
    code, _, err = cli("noise", log, "--column", "gyro", "--time", "time")
    line = int(re.search(r"line (\d+):", err).group(1))
    assert code == 2 and abs(line - 4002) <= 8 and err.count("\n") == 1  # within the jitter's reach


def test_cli_time_column_of_dates(cli, tmp_path):
    """ISO 8601 times give the rate as seconds do (as ``cfdesign run`` reads them); a time cell
    that is neither is named."""
    rng = np.random.default_rng(2)
    x = 0.01 * rng.standard_normal(4000)
    start = 1714564800.0  # 2024-05-01T12:00:00 UTC
    from datetime import datetime, timezone

    dates = [datetime.fromtimestamp(start + k / 100, timezone.utc).isoformat() for k in range(4000)]
    (tmp_path / "s.csv").write_text("time,gyro\n" + "".join(f"{k / 100},{v}\n" for k, v in enumerate(x)))
    (tmp_path / "d.csv").write_text("time,gyro\n" + "".join(f"{d},{v}\n" for d, v in zip(dates, x, strict=True)))
    outs = [cli("noise", tmp_path / f, "--column", "gyro", "--time", "time") for f in ("s.csv", "d.csv")]
    assert outs[0][0] == outs[1][0] == 0 and outs[0][1] == outs[1][1]
    (tmp_path / "d.csv").write_text("time,gyro\n" + "".join(f"{d},{v}\n" for d, v in zip(dates, x, strict=True))
                                    + "later,0.1\n")
    code, _, err = cli("noise", tmp_path / "d.csv", "--column", "gyro", "--time", "time")
    assert code == 2 and "line 4002" in err and "ISO 8601 date" in err
    # the same column through cfdesign run reads the same times (one date reader)
    from cfdesign.logs.columns import _numeric
    from cfdesign.timing import date_seconds

    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"time": ["2024-05-01T12:00:00,5", "2024-05-01 12:00:01.25+01:00", "2024-05-01T11:00:02Z"]})
    assert _numeric(frame, ["time"], "log", 2, "time")["time"].tolist() == [
        date_seconds(c) for c in frame["time"]] == [1714564800.5, 1714564801.25 - 3600, 1714561202.0]


def test_cli_reads_logs_as_cfdesign_run_does(cli, tmp_path):
    """noise had its own CSV reader: a semicolon or tab export was 'no column', Parquet was not
    read; it reads logs with cfdesign.logs now, and a column named twice is refused."""
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    frame = pd.DataFrame({"time": np.arange(6000) / RATE, "gyro": gyro(60.0)})
    frame.to_csv(tmp_path / "c.csv", index=False)
    frame.to_csv(tmp_path / "s.csv", index=False, sep=";", decimal=",")
    frame.to_csv(tmp_path / "t.tsv", index=False, sep="\t")
    frame.to_parquet(tmp_path / "p.parquet")
    outs = [cli("noise", tmp_path / f, "--column", "gyro", "--time", "time")
            for f in ("c.csv", "s.csv", "t.tsv", "p.parquet")]
    assert all(code == 0 for code, _, _ in outs), [err for _, _, err in outs]
    assert len({out for _, out, _ in outs}) == 1
    (tmp_path / "d.csv").write_text("time,gyro,gyro\n0,1,2\n0.01,1,2\n")
    code, _, err = cli("noise", tmp_path / "d.csv", "--column", "gyro", "--rate-hz", 100)
    assert code == 2 and "'gyro' appears twice" in err and err.count("\n") == 1
    (tmp_path / "g.csv").write_text("time,gyro\n0,1\n0.01,\n0.02,1\n")
    code, _, err = cli("noise", tmp_path / "g.csv", "--column", "gyro", "--rate-hz", 100)
    assert code == 2 and "line 3" in err and "complete recording" in err


def test_a_term_s_line_shows_the_slope_it_was_checked_against():
    """A random walk read where white noise still counts: the line said 'slope +0.13, expected
    +0.5' although the check compares with the fitted model's slope; it names both now."""
    fit = identify_noise(gyro(1800.0, seed=1), RATE)
    rw = fit.terms["random_walk"]
    assert -0.5 < rw.model_slope < 0.5 and f"fitted model {rw.model_slope:+.2f}" in rw.line()
    assert "the term alone +0.5" in rw.line()


def test_a_rest_that_ends_in_motion_is_refused_and_the_still_part_read():
    """The 44 s before the motion of BROAD trial 26 (phone vibration; Laidig et al.), up to a second
    before the labelled motion: the gyro's x axis already moves at 44.2 s (its 16-reading mean
    changes by 0.077 rad/s, 117 times the typical change). Read as noise, that motion was a flat
    B = 3.4e-3 rad/s over the whole range, 50 times the measured deviation at 14 s; it is named
    now, and the still part before it holds white noise only."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad" / "26_disturbed_phone_vibration_A.mat"
    if not path.exists():
        pytest.skip(f"BROAD data not found at {path} (shared/data/broad sits beside the checkout)")
    from scipy.io import loadmat

    d = loadmat(path, squeeze_me=True)
    rate = float(d["sampling_rate"])
    motion = int(np.argmax(d["movement"] == 1))
    with pytest.raises(InputError, match=r"jumps near reading 126\d\d \(44\.\d+ s from its start\)"):
        identify_noise(d["imu_gyr"][:motion - int(rate), 0], rate)
    fit = identify_noise(d["imu_gyr"][:motion - 2 * int(rate), 0], rate)
    assert set(fit.terms) == {"white"} and 0.8e-4 < fit.white_density < 1.4e-4


def test_a_flat_stretch_is_not_claimed_by_a_random_walk():
    """An hour at 50 Hz of white noise and flicker (B = 3e-5; flicker drawn as a sum of
    Gauss-Markov processes with correlation times an octave apart): B and K split the last
    octaves, B was dropped first (resolved over two octaves only) and a random walk K = 2.9e-6
    whose measured slope was -0.04 took its range. The flat term must be the one reported."""
    from scipy.signal import lfilter

    rate, n, B = 50.0, 180_000, 3e-5
    rng = np.random.default_rng(2)
    y = N_TRUE * math.sqrt(rate) * rng.standard_normal(n)
    rng.standard_normal(n)  # (the draw of the audit's random walk, left out: the recording has none)
    var = B**2 * math.log(2.0) / math.pi  # per process: one-sided PSD B^2 / (pi f) from the octave sum
    for tc in (2.0 / rate) * 2.0 ** np.arange(int(math.log2(4.0 * n / 2.0)) + 1):
        a = math.exp(-1.0 / (rate * tc))
        w = math.sqrt(var * (1 - a * a)) * rng.standard_normal(n)
        y += lfilter([1.0], [1.0, -a], w, zi=[a * math.sqrt(var) * rng.standard_normal()])[0]
    fit = identify_noise(y, rate)
    assert fit.random_walk_density is None
    assert fit.bias_instability == pytest.approx(B, rel=0.25)


def _jumps(y, rate=RATE):
    with pytest.raises(InputError, match="jumps near reading") as err:
        identify_noise(y, rate)
    return str(err.value)


def test_an_outlier_a_step_or_a_wrapped_integer_is_named_not_read_as_noise():
    """One reading of 5 in an hour of N = 1e-3 (per-sample std 0.01) gave N 30 % high with a 0.3 %
    interval that excluded the truth; a step of 0.05 half way gave K = 8.6e-4 (29 times the truth,
    interval excluding it); an int16 reading near its limit wrapped by 65536. Each is named with
    where it is."""
    y = gyro(600.0, N=1e-3, K=3e-5, seed=3)
    spike = y.copy()
    spike[12345] += 5.0
    assert "reading 1234" in _jumps(spike)
    step = y.copy()
    step[30_000:] += 0.05
    at = int(_jumps(step).split("jumps near reading ")[1].split()[0])
    assert abs(at - 30_000) <= 2048
    counts = np.round(gyro(600.0, N=0.5, K=0.0, seed=4)).astype(np.int64) + 32_758  # 5 LSB of noise
    assert re.search(r"changes by -6\.55\d*e\+04", _jumps(((counts + 32_768) % 65_536 - 32_768).astype(float)))


@pytest.mark.parametrize("kind", ["white", "walk", "flicker", "quantised", "held", "heavy-tailed"])
def test_still_recordings_are_not_refused_as_jumping(kind):
    """Recordings of the model's noises, a coarsely quantised one (a few levels), one logged
    faster than the sensor reads (each value held over three rows) and one with rare 10-sigma
    readings (moving its Allan deviation by a few percent) are read, not refused.  (Mostly one
    level, 0.2 steps per reading, is refused, but as quantised: test below.)"""
    rng = np.random.default_rng(11)
    n = 60_000
    if kind == "white":
        y = rng.standard_normal(n)
    elif kind == "walk":
        y = 0.1 * rng.standard_normal(n) + np.cumsum(0.01 * rng.standard_normal(n))
    elif kind == "flicker":
        f = np.fft.rfftfreq(2 * n)
        y = np.fft.irfft(np.fft.rfft(rng.standard_normal(2 * n)) / np.sqrt(np.maximum(f, f[1])))[:n]
    elif kind == "quantised":
        y = np.round(0.6 * rng.standard_normal(n))
    elif kind == "held":
        y = np.repeat(rng.standard_normal(n // 3), 3)
    else:
        y = rng.standard_normal(n)
        y[rng.choice(n, 6, replace=False)] += 10.0
    fit = identify_noise(y, RATE)  # no InputError
    assert fit.terms


def test_columns_whose_names_clash_get_distinct_sensor_tables(cli, tmp_path):
    """Columns 'gyro x' and 'gyro_x' (and two named in Greek) both became [sensors.gyro_x]
    ([sensors.sensor]): noise.toml declared a table twice, which no TOML reader takes, exit 0."""
    rng = np.random.default_rng(2)
    cols = {name: rng.standard_normal(400) for name in ("gyro x", "gyro_x", "\u03c9", "\u03b1")}
    log = tmp_path / "n.csv"
    log.write_text(",".join(cols) + "\n" + "".join(",".join(repr(float(v[i])) for v in cols.values()) + "\n"
                                                  for i in range(400)), encoding="utf-8")
    code, _, err = cli("noise", log, "--column", ",".join(cols), "--rate-hz", 100, "-o", tmp_path / "n.toml")
    assert code == 0, err
    sensors = tomllib.loads((tmp_path / "n.toml").read_text())["sensors"]
    assert list(sensors) == ["gyro_x_2", "gyro_x", "sensor", "sensor_2"]  # a column named so keeps its name
    code, _, err = cli("noise", log, "--column", "gyro_x,gyro_x", "--rate-hz", 100)
    assert code == 2 and "'gyro_x' twice" in err and err.count("\n") == 1


def test_cli_time_in_milliseconds_gives_the_rate_in_hertz(cli, tmp_path):
    """A time column of milliseconds ('time [ms]', or --time-unit ms) was read as seconds: a
    100 Hz log identified at 0.1 Hz, every density off by sqrt(1000), exit 0. Now the name's unit
    or --time-unit gives the rate (the option over the name), and times that give under 1 Hz
    without a unit are refused naming the option (a note beside exit 0 had left the wrong densities
    written); --time-unit s takes them as seconds."""
    y = (0.01 * np.random.default_rng(8).standard_normal(3000)).tolist()
    rows = "".join(f"{10 * k},{v!r}\n" for k, v in enumerate(y))
    (tmp_path / "s.csv").write_text("time,gyro\n" + "".join(f"{k / 100},{v!r}\n" for k, v in enumerate(y)))
    (tmp_path / "named.csv").write_text("time [ms],gyro\n" + rows)
    (tmp_path / "plain.csv").write_text("time,gyro\n" + rows)
    seconds = cli("noise", tmp_path / "s.csv", "--column", "gyro", "--time", "time")
    named = cli("noise", tmp_path / "named.csv", "--column", "gyro", "--time", "time [ms]")
    given = cli("noise", tmp_path / "plain.csv", "--column", "gyro", "--time", "time", "--time-unit", "ms")
    assert seconds[0] == named[0] == given[0] == 0 and "at 100 Hz" in seconds[1]
    assert named[1] == given[1] == seconds[1]
    # without --time, the time column as `cfdesign run` finds it ('time', or one named with its unit)
    assert cli("noise", tmp_path / "s.csv", "--column", "gyro")[:2] == (0, seconds[1])
    assert cli("noise", tmp_path / "named.csv", "--column", "gyro")[:2] == (0, seconds[1])
    assert cli("noise", tmp_path / "plain.csv", "--column", "gyro", "--time-unit", "ms")[:2] == (0, seconds[1])
    code, _, err = cli("noise", tmp_path / "plain.csv", "--column", "gyro", "--time", "time")
    assert code == 2 and "(0.1 Hz), read as seconds" in err and "--time-unit ms" in err and err.count("\n") == 1
    code, out, _ = cli("noise", tmp_path / "plain.csv", "--column", "gyro", "--time", "time", "--time-unit", "s")
    assert code == 0 and "at 0.1 Hz" in out
    (tmp_path / "mislabelled.csv").write_text("time [s],gyro\n" + rows)  # the option overrides a wrong label
    code, out, _ = cli("noise", tmp_path / "mislabelled.csv", "--column", "gyro", "--time", "time [s]",
                       "--time-unit", "ms")
    assert code == 0 and out == seconds[1]
    code, _, err = cli("noise", tmp_path / "mislabelled.csv", "--column", "gyro")  # not at 0.1 Hz in silence
    assert code == 2 and "(0.1 Hz), read in s as its name says" in err and "--time-unit ms" in err
    code, _, err = cli("noise", tmp_path / "s.csv", "--column", "gyro", "--rate-hz", "100", "--time-unit", "ms")
    assert code == 2 and "--time" in err


@pytest.mark.parametrize(("n", "seed", "claimed"), [(20, 8, "random_walk"), (20, 13, "quantization"),
                                                    (32, 12, "bias_instability"), (50, 30, "bias_instability"),
                                                    (32, 8, None), (50, 9, None)])
def test_a_few_dozen_readings_of_white_noise_are_white_noise(n, seed, claimed):
    """20 to 64 readings of white noise: a term that took the first octaves left white noise 'not
    significant', the elimination dropped white noise first and ended on that term alone - a fit
    worse than white noise alone (a random walk K = 0.2 for a design file's bias from 20 readings)
    - or on no term at all. Over 200 seeds, other terms were claimed in 39 % (20 readings) to 1 %
    (64), nothing at all in up to 11 % (50); now in 5.5 % (20 readings: a bias instability or a
    quantisation noise that fits clearly better), 2.5 % (32) and none (64) and never nothing.
    Where white noise alone fits as well, it is what is reported."""
    N = 1.0 / math.sqrt(100.0)  # per-sample std 1 at 100 Hz
    fit = identify_noise(np.random.default_rng(seed).standard_normal(n), 100.0)
    assert set(fit.terms) == {"white"}
    lo, hi = fit.terms["white"].ci
    assert lo <= N <= hi
    if claimed:
        assert "white noise alone fits the recording about as well" in fit.missing[claimed]


def test_numpy_scalar_rates_are_rates():
    """A rate of np.float32(100) or np.int64(100) (read from an array) was refused as 'not a
    positive number of hertz'; it is the rate, taken in double precision."""
    y = gyro(60, K=0, seed=5)
    expected = identify_noise(y, 100.0)
    for rate in (np.float32(100.0), np.int64(100)):
        fit = identify_noise(y, rate)
        assert type(fit.rate_hz) is float and fit.white_density == expected.white_density
    with pytest.raises(InputError, match="positive number of hertz"):
        identify_noise(y, np.bool_(True))


def test_a_three_axis_array_is_refused_not_interleaved():
    """An (n, 3) gyro array was raveled into one recording of 3n readings: three axes of N = 0.1,
    0.2 and 0.3 at 100 Hz for 60 s came back as one of 180 s with N = 0.216. One axis per call; a
    single column or row is one axis."""
    rng = np.random.default_rng(0)
    g = rng.standard_normal((6000, 3)) * np.array([1.0, 2.0, 3.0])
    for x in (g, g.T):
        with pytest.raises(InputError, match=r"shape \(\d+, \d+\) hold more than one axis"):
            identify_noise(x, 100.0)
    one = identify_noise(g[:, 1], 100.0)
    for x in (g[:, 1:2], g[:, 1:2].T):
        fit = identify_noise(x, 100.0)
        assert fit.duration_s == 60.0 and fit.white_density == one.white_density


def test_the_nominal_rate_of_a_sensor_read_every_few_milliseconds_is_its_period_s():
    """A sensor read every 3 ms (1000/3 Hz) was written as 333.3 Hz, the shortest decimal within
    1e-4: beside a 1 kHz gyro in a design file that rate made a schedule of 10,000 base steps (ratio
    10000/3333) instead of 3. The period is the shorter decimal there, and the rate is taken from it."""
    from cfdesign.allan import nominal_rate
    from cfdesign.designer import multirate_schedule

    rate = nominal_rate(1000.0 / 3.0 * (1 + 3e-6))
    assert rate == 1000.0 / 3.0 and nominal_rate(1 / 0.0035 * (1 - 2e-6)) == 1 / 0.0035
    assert (nominal_rate(100.00002), nominal_rate(99.5), nominal_rate(104.0016), nominal_rate(128.0)) == (
        100.0, 99.5, 104.0, 128.0)
    assert multirate_schedule({"gyro": 1000.0, "compass": rate}, ["gyro"])[1].period == 3


@pytest.mark.parametrize(("cutoff_hz", "hold"), [(20.0, 1), (350.0, 1), (None, 3)],
                         ids=["low-pass 20 Hz", "low-pass 350 Hz", "held over 3 rows"])
def test_band_limited_readings_give_the_white_noise_of_the_octaves_after_the_band_limit(cutoff_hz, hold):
    """A 1 kHz gyro behind a 2nd-order low-pass (an IMU's digital low-pass filter) at 350 Hz or
    below, or logged three times faster than it updates, had no term identified at all: its first
    octaves lie below the white noise line N^2 / tau, which no term of the model does. They are
    left out of the fit, said so, and N comes back from the octaves after them."""
    from scipy.signal import butter, lfilter

    rate, N = 1000.0, 1.7e-4
    rng = np.random.default_rng(3)
    y = N * math.sqrt(rate / hold) * rng.standard_normal(60_000 // hold)
    if hold > 1:
        y = np.repeat(y, hold)
    else:
        y = lfilter(*butter(2, cutoff_hz / (rate / 2)), y)
    fit = identify_noise(y, rate, "gyro_x")
    assert fit.white_density == pytest.approx(N, rel=0.05)
    assert set(fit.terms) == {"white"}
    assert fit.band_limit_s is not None and fit.terms["white"].tau_range_s[0] == fit.band_limit_s
    # the octaves left out are below the white noise line; the first one fitted is on it
    on_line = fit.adev * np.sqrt(fit.tau_s) / N
    first = int(np.flatnonzero(fit.tau_s == fit.band_limit_s)[0])
    assert on_line[0] < 0.7 and on_line[first] == pytest.approx(1.0, abs=0.1)
    assert "left out of the fit" in fit.summary()
    text = noise_toml([fit])
    assert "left out of the fit" in text
    assert tomllib.loads(text)["sensors"]["gyro_x"]["noise"]["density"] == pytest.approx(N, rel=0.05)


def test_white_noise_fitted_over_every_octave_has_no_band_limit():
    fit = identify_noise(gyro(600, K=0, seed=4), RATE)
    assert fit.band_limit_s is None and fit.terms["white"].tau_range_s[0] == 1 / RATE
    assert "left out" not in fit.summary()


def test_the_shortest_recording_taken_can_show_white_noise():
    """16 readings give three octaves (m = 1, 2, 4), whose log-log slope no recording resolves to
    SLOPE_RESOLUTION: 200 of 200 seeds of white noise came back with no term at all and the reason
    'not significant'. The fewest readings taken are the fewest that can show white noise."""
    from cfdesign.allan import MIN_SAMPLES, SLOPE_RESOLUTION, _slope_se, octave_taus

    def slope_se(n):
        m = octave_taus(n, 1.0)
        return _slope_se(m.astype(float), np.maximum(edf_simple(n + 1, m, 0), 1.0))

    assert slope_se(MIN_SAMPLES) <= SLOPE_RESOLUTION < slope_se(MIN_SAMPLES - 1)
    with pytest.raises(InputError, match=rf"too few .* \(at least {MIN_SAMPLES}\)"):
        identify_noise(gyro(1, K=0)[:MIN_SAMPLES - 1], RATE)
    found = sum(identify_noise(gyro(1, K=0, seed=s)[:MIN_SAMPLES], RATE).white_density is not None for s in range(20))
    assert found >= 15


@pytest.mark.parametrize("offset", [0.0, 0.25, 0.5])
@pytest.mark.parametrize("spread", [0.15, 0.35])
def test_readings_whose_noise_is_below_their_resolution_are_refused(spread, offset):
    """Readings quantised to steps of 1 whose noise is 0.15 or 0.35 steps per reading: the density
    came out 0.2 to 3.3 times (0.15) or 1.1 to 1.5 times (0.35) the sensor's, with a tight interval,
    depending only on where the true value sat between two levels. Refused, naming the resolution;
    0.6 steps and more are read, within 20 %."""
    rng = np.random.default_rng(5)
    noise = spread * rng.standard_normal(60_000)
    with pytest.raises(InputError, match=r"below 0.535 of their resolution \(1 between levels\)"):
        identify_noise(np.round(offset + noise), RATE)
    fit = identify_noise(np.round(offset + noise * 0.6 / spread), RATE)
    assert fit.white_density == pytest.approx(0.6 / math.sqrt(RATE), rel=0.2)


def test_cli_a_unit_per_column(cli, tmp_path):
    """A gyro beside an accelerometer in one call: --unit rad/s wrote the accelerometer's density as
    rad/s/sqrt(Hz) in noise.toml and the summary. One unit per column is taken (and a count that
    matches neither is refused before the log is read)."""
    rng = np.random.default_rng(8)
    log = _log(tmp_path / "imu.csv", {"gyro_z": gyro(60, K=0), "acc_z": 9.81 + 0.02 * rng.standard_normal(6000)})
    code, out, err = cli("noise", log, "--column", "gyro_z,acc_z", "--time", "time", "--unit", "rad/s, m/s^2",
                         "-o", tmp_path / "n.toml", "--plot", tmp_path / "a.png")
    assert code == 0, err
    text = (tmp_path / "n.toml").read_text()
    gyro_part, acc_part = text.split("[sensors.acc_z]")
    assert "# rad/s/sqrt(Hz)" in gyro_part and "m/s^2" not in gyro_part
    assert "# m/s^2/sqrt(Hz)" in acc_part and "rad/s" not in acc_part
    assert re.search(r"acc_z: .*\n  white noise density N: N = 0.00[0-9]+ m/s\^2/sqrt\(Hz\)", out)
    code, _out, err = cli("noise", tmp_path / "missing.csv", "--column", "gyro_z,acc_z", "--rate-hz", "100",
                          "--unit", "rad/s,m/s^2,T")
    assert code == 2 and "one per --column (2)" in err and err.count("\n") == 1


@pytest.mark.parametrize("unit", [None, 5, ["rad/s", None], b"rad/s"])
def test_a_unit_that_is_not_text_is_an_input_error(unit):
    """noise_toml and adev_plot take a unit or a sequence of units: None, a number or a list holding
    something else raised a raw TypeError ('NoneType' object is not iterable); bytes were units."""
    from cfdesign.allan import adev_plot, noise_toml

    fit = identify_noise(np.random.default_rng(2).standard_normal(2000), RATE, name="a")
    for draw in (noise_toml, adev_plot):
        with pytest.raises(InputError, match="unit must be text"):
            draw([fit, fit] if isinstance(unit, list) else [fit], unit=unit)
    assert "# rad/s/sqrt(Hz)" in noise_toml([fit], unit=("rad/s",))


def test_octaves_standing_above_the_white_noise_line_are_not_a_band_limit(monkeypatch):
    """White noise with a 5 Hz vibration line: the octaves around 0.1 s stand above the white
    noise line, so the first ones lie below the model fitted without them - by a level deficit, not
    one that shrinks with tau as a low-pass filter's does. They are fitted (N within 2 % of the
    readings' own noise); taken for a band limit, three octaves were left out and N came out 3.4 %
    high."""
    import cfdesign.allan as allan

    rng = np.random.default_rng(1)
    t = np.arange(60_000) / RATE
    y = rng.standard_normal(len(t)) + 0.15 * math.sqrt(2) * np.sin(2 * np.pi * 5.0 * t)
    fit = identify_noise(y, RATE)
    assert fit.band_limit_s is None and fit.white_density == pytest.approx(0.1, rel=0.02)
    monkeypatch.setattr(allan, "BAND_LIMIT_DECAY", math.inf)  # the rule is what keeps them
    assert identify_noise(y, RATE).band_limit_s is not None


def test_octaves_above_the_model_of_the_terms_kept_are_left_out_of_their_fit():
    """Ten minutes at 50 Hz of N = 2e-3 and K = 2e-4: the random walk dominates from 17 s, but
    this realisation's last octaves do not resolve it and it is dropped.  White noise alone was
    then fitted over every octave, those up to 164 s too, where the random walk's variance is
    tens of times the white noise's: N came out 1.2 % high against a 95 % interval of +-1 %
    (over 60 such recordings the white-alone ones covered N in 12 of 17).  Octaves above the
    model of the terms kept, beyond their chi-square interval, are left out of the fit and named."""
    N, K, rate = 2e-3, 2e-4, 50.0
    fit = identify_noise(gyro(600, N=N, K=K, rate=rate, seed=19), rate)
    white = fit.terms["white"]
    assert white.ci[0] <= N <= white.ci[1]
    assert set(fit.terms) == {"white"} and fit.unresolved_from_s is not None
    assert white.tau_range_s[1] < fit.unresolved_from_s <= fit.tau_s[-1]
    # the octaves left out do lie above the white noise line beyond their own chi-square interval
    left_out = fit.tau_s >= fit.unresolved_from_s
    assert np.all(fit.adev[left_out] > white.value / np.sqrt(fit.tau_s[left_out]))
    assert f"octaves from tau {fit.unresolved_from_s:.3g} s on left out of the fit" in fit.summary()
    assert "left out of the fit: the Allan deviation there lies above" in noise_toml([fit])


def test_the_octave_named_unresolved_is_the_first_one_left_out_when_the_refit_leaves_out_more():
    """White noise whose Allan deviation stands 2 times high at 2.56 s and 10 times from 5.12 s:
    the fit over every octave leaves out those from 5.12 s, the refit without them (its model
    lower) leaves out 2.56 s as well.  ``unresolved_from_s`` said 5.12 s, so 2.56 s was neither
    fitted nor named as left out."""
    from cfdesign.allan import _identify

    rate, n = 50.0, 30_000
    tau, _, m = oadev(np.random.default_rng(0).standard_normal(n), rate)
    adev = 2e-3 / np.sqrt(tau)
    adev[7] *= 2.0
    adev[8:] *= 10.0
    _, terms, _, edf, stop = _identify(tau, adev, m, n, rate)
    assert tau[stop] == pytest.approx(2.56) and len(edf) == len(tau)
    assert set(terms) == {"white"} and terms["white"].tau_range_s[1] < tau[stop]


def test_a_recording_that_moved_says_its_rate_ramp_hides_k():
    """A still gyro (N = 0.002, K = 2e-4) that turned 0.02 rad/s over ten minutes read a rate ramp and K not
    identified, exit 0: a design then took no bias density.  The summary and the design-file text now say a ramp
    at rest is a drift or motion hiding K; the same recording still says nothing of it (and finds K)."""
    rng = np.random.default_rng(3)
    rate, n = 50.0, 50 * 1800
    t = np.arange(n) / rate
    walk = np.cumsum(2e-4 / math.sqrt(rate) * rng.standard_normal(n))
    still = 0.002 * math.sqrt(rate) * rng.standard_normal(n) + walk
    fit = identify_noise(still, rate, name="gyro")
    assert "rate_ramp" not in fit.terms and fit.random_walk_density == pytest.approx(2e-4, rel=0.35)
    assert "drift or a motion" not in fit.summary() + noise_toml([fit])
    moved = identify_noise(still + 0.02 * np.sin(2 * np.pi * t / 600.0), rate, name="gyro")
    assert "rate_ramp" in moved.terms and moved.random_walk_density is None
    assert "drift or a motion" in moved.summary() and "# a rate ramp over a recording at rest" in noise_toml([moved])
