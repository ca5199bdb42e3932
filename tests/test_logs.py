"""Real logs: timestamps placed on ticks, sensors locked to when they arrive, gapped columns at
batch speed, bad logs refused on one line, nothing half-written, Parquet, blocks, many logs."""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import read_csv_exact

import cfdesign
from cfdesign.errors import CfdesignError, DataError
from cfdesign.linear import wrap
from cfdesign.logs import run_log, run_logs
from cfdesign.runtime import Runtime
from cfdesign.sim.gaussian import model_log
from cfdesign.spec import parse_spec


def heading_log(odometry_row, compass_row, n=30_000, seed=0, jitter=0.03):
    """A turning robot at 100 Hz: gyro every row, odometry every 10th row from ``odometry_row``,
    compass every 100th from ``compass_row`` (empty cells between), timestamps jittered by
    ``jitter`` ticks (std), headings wrapped.  Returns the log and the true heading."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    t = np.arange(n) * dt
    psi = 2.0 + 6.0 * np.sin(0.05 * t) + 0.3 * t  # crosses +-pi many times
    gyro = np.gradient(psi, dt) + 0.01 * rng.standard_normal(n) + 0.002
    odo, com = np.full(n, np.nan), np.full(n, np.nan)
    odo[odometry_row::10] = psi[odometry_row::10] + 0.005 * rng.standard_normal(len(odo[odometry_row::10]))
    com[compass_row::100] = psi[compass_row::100] + 0.05 * rng.standard_normal(len(com[compass_row::100]))
    log = pd.DataFrame({"time": t + jitter * dt * rng.standard_normal(n), "gyro": gyro, "odometry": wrap(odo),
                        "compass": wrap(com), "truth": wrap(psi), "lap": np.arange(n) // 1000})
    return log, psi


def rms_after(est, truth, start=3000):
    return float(np.sqrt(np.mean(wrap(est[start:] - truth[start:]) ** 2)))


def test_a_log_at_half_the_table_s_rate_without_times_is_named_so(heading):
    """A 50 Hz log through the 100 Hz heading table without a time column ran 0.17 rad RMS off in heading (rows taken
    one a tick), its notes naming each sensor's rate alone: the note on the missing time column now says the rows
    are 2 ticks apart; the log at 100 Hz, without its time column too, says nothing of it."""
    log, _ = heading_log(3, 37, n=6000)
    assert not any("ticks apart" in n for n in run_log(heading, log.drop(columns=["time"])).notes)
    half = log.iloc[1::2].drop(columns=["time"])
    note = next(n for n in run_log(heading, half).notes if "no time column" in n)
    assert "arrives 2 times as often" in note and "a log at 50 Hz through a 100 Hz table" in note


# ---------------------------------------------------------------------- the issue's example
@pytest.mark.filterwarnings("ignore:.*has no gain:UserWarning")  # readings off the schedule on purpose
def test_sensors_at_their_own_offsets_run_as_well_as_aligned_ones(heading, tmp_path, cli):
    """100 Hz gyro, 10 Hz odometry at rows 3, 13, ..., 1 Hz compass at rows 37, 137, ..., jittered
    timestamps, gapped columns, through the CLI: RMS within 1.25x of the aligned log's."""
    aligned, psi = heading_log(0, 0)
    offset, _ = heading_log(3, 37)
    table = heading.save(tmp_path / "g.json")
    rms = {}
    for name, log in (("aligned", aligned), ("offset", offset)):
        log.to_csv(tmp_path / f"{name}.csv", index=False)
        code, _, err = cli("run", table, tmp_path / f"{name}.csv", "-o", tmp_path / f"{name}_est.csv")
        assert code == 0, err
        est = pd.read_csv(tmp_path / f"{name}_est.csv")
        assert list(est.columns) == ["time", "heading", "gyro_correction", "truth", "lap"]  # extras passed through
        rms[name] = rms_after(est["heading"].to_numpy(), psi)
        if name == "offset":
            assert "compass 37 ticks, odometry 3 ticks" in err and "gains recomputed" in err
    assert rms["offset"] <= 1.25 * rms["aligned"], rms
    assert rms["aligned"] < 3 * heading.predicted_std  # and it is the designed accuracy
    # without locking the readings off the schedule would have been lost (1.9 rad in the issue);
    # Runtime.run, as its steps, locks to the odometry and loses the compass only
    rows = {k: offset[k].to_numpy() for k in ("gyro", "odometry", "compass")}
    rt, fixed = Runtime(heading), Runtime(heading, lock=False)
    lost = fixed.run(rows)
    assert rms_after(lost, psi) > 20 * rms["offset"] and fixed.counts["unscheduled"]["compass"] == 300
    assert rms_after(rt.run(rows), psi) < 0.1 * rms_after(lost, psi) and rt.counts == {"unscheduled": {"compass": 300}}


GPS3 = {"name": "imu 100 Hz + gps 3 Hz", "structure": "position", "gain_form": "filter", "sensors": {
    "accelerometer": {"rate_hz": 100.0, "noise": {"std": 0.05}, "bias": {"model": "random_walk", "density": 1e-3}},
    "gps": {"rate_hz": 3.0, "noise": {"std": 2.0}}}}


@pytest.fixture(scope="module")
def gps3():
    return cfdesign.design(parse_spec(GPS3))


def test_a_sensor_faster_than_the_table_has_every_reading_used(heading, gps3, tmp_path, cli):
    """A GPS at 3.3 Hz into a table designed for 3 Hz (a 10 Hz compass into a 1 Hz table): a table
    with a model runs its Kalman filter over the arrivals, every reading used (on the schedule
    only 1 reading in 13 had a gain: 21 m RMS where 0.52 m was designed); a table without one
    (fixed gains) counts the readings off its schedule, on stderr and in the result."""
    import dataclasses

    table = gps3
    x, readings = model_log(table, 12_000, seed=3)
    fix = np.unique(np.rint(np.arange(0, 12_000, 100 / 3.3)).astype(int))
    gps = np.full(12_000, np.nan)
    gps[fix] = x[fix, 0] + 2.0 * np.random.default_rng(4).standard_normal(len(fix))
    pd.DataFrame({"time": np.arange(12_000) * 0.01, "accelerometer": readings["accelerometer"], "gps": gps,
                  "truth": x[:, 0]}).to_csv(tmp_path / "fast.csv", index=False)
    code, _, err = cli("run", table.save(tmp_path / "g.json"), tmp_path / "fast.csv", "-o", tmp_path / "e.csv")
    assert code == 0 and "gps arrives at 3.297 Hz but the table reads it at 3 Hz: every reading is used" in err
    assert "not used" not in err
    est = pd.read_csv(tmp_path / "e.csv")["position"].to_numpy()
    assert np.sqrt(np.mean((est[4000:] - x[4000:, 0]) ** 2)) < 1.2 * table.predicted_std
    log, _ = heading_log(0, 0, n=1000)
    log["compass"] = np.where(np.arange(1000) % 10 == 0, log["truth"], np.nan)
    hand = dataclasses.replace(heading, provenance={**heading.provenance, "solver": {"method": "hand-tuned"}})
    assert run_log(hand, log).unused == {"unscheduled": {"compass": 90}}
    # beside a sensor off its schedule, the note names what runs (it said 'gains recomputed ...')
    log, _ = heading_log(3, 0, n=3000)
    log["compass"] = np.where(np.arange(3000) % 10 == 0, log["truth"], np.nan)
    r = run_log(heading, log)
    assert r.unused == {} and any("odometry 3 ticks" in n and "as they arrive" in n for n in r.notes)
    assert not any("recomputed" in n or "locked" in n for n in r.notes)


def test_a_rate_a_few_percent_off_the_design_is_named(gps3):
    """A GPS at 2.94 or 3.06 Hz into a table designed for 3 Hz (its rate_hz 2 % off): a note names
    both rates, none claims a fixed offset for it (it said 'readings arrive gps 74 ticks after the
    table's schedule' and nothing on the rate), and every reading is used."""
    table = gps3
    x, readings = model_log(table, 9000, seed=3)
    rng = np.random.default_rng(4)
    for rate, sign in ((2.94, "-2.0 %"), (3.06, "+2.0 %")):
        fix = np.rint(np.arange(0, 9000, 100 / rate)).astype(int)
        gps = np.full(9000, np.nan)
        gps[fix] = x[fix, 0] + 2.0 * rng.standard_normal(len(fix))
        r = run_log(table, pd.DataFrame({"time": np.arange(9000) * 0.01, "accelerometer": readings["accelerometer"],
                                         "gps": gps}))
        assert r.unused == {}
        assert any(n.startswith(f"gps arrives at {rate:.3g}") and f"the table reads it at 3 Hz ({sign}" in n
                   for n in r.notes), r.notes
        assert not any("ticks after" in n for n in r.notes), r.notes


def test_rates_that_are_not_integer_ratios_design_verify_and_run(tmp_path, cli):
    """A 3 Hz GPS with a 100 Hz IMU (position filter): period 100 with fixes at ticks 0, 33, 67;
    on a simulated log with timestamps, the position RMS is within 1.3x of the predicted std."""
    spec = tmp_path / "gps.toml"
    spec.write_text('name = "imu 100 Hz + gps 3 Hz"\nstructure = "position"\ngain_form = "filter"\n'
                    '[sensors.accelerometer]\nrate_hz = 100.0\nnoise = { std = 0.05 }\n'
                    'bias = { model = "random_walk", density = 1e-3 }\n'
                    '[sensors.gps]\nrate_hz = 3.0\nnoise = { std = 2.0 }\n')
    assert cli("design", spec, "-o", tmp_path / "g.json")[0] == 0
    assert cli("verify", tmp_path / "g.json", "--spec", spec)[0] == 0
    table = cfdesign.load_gains(tmp_path / "g.json")
    assert table.period == 100 and table.schedule.phases("gps") == (0, 33, 67)
    x, readings = model_log(table, 60_000, seed=3)
    rng = np.random.default_rng(4)
    log = pd.DataFrame({"t": np.arange(60_000) * 0.01 + 2e-4 * rng.standard_normal(60_000), **readings,
                        "true_position": x[:, 0], "true_velocity": x[:, 1]})
    log.to_parquet(tmp_path / "log.parquet")
    code, out, err = cli("run", tmp_path / "g.json", tmp_path / "log.parquet", "-o", tmp_path / "est.parquet",
                         "--reference", "true_position", "--reference", "velocity=true_velocity", "--std")
    assert code == 0, err
    est = pd.read_parquet(tmp_path / "est.parquet")
    assert {"position_std", "velocity_std", "accelerometer_bias_std"} <= set(est.columns)
    assert np.array_equal(est["true_position"], x[:, 0])  # the reference columns are passed through too
    err_p = est["position"].to_numpy()[5000:] - x[5000:, 0]
    predicted = np.sqrt(np.mean([table.P_filtered[k][0, 0] for k in np.arange(5000, 60_000) % 100]))
    assert np.sqrt(np.mean(err_p ** 2)) <= 1.3 * predicted
    assert "RMS error of position:" in out and "RMS error of velocity:" in out


def test_a_drifting_sensor_is_followed(heading):
    """The compass's clock runs 0.5 % fast: its arrivals slip through the schedule, the log runs
    the Kalman filter over the readings as they arrive, no reading is lost; the note on its
    offset (it starts 37 ticks late) names that filter (it said 'the schedule is locked to the
    arrivals', which did not run)."""
    log, psi = heading_log(0, 0, n=40_000, jitter=0.0)
    com = np.full(40_000, np.nan)
    arrivals = np.round(37 + np.arange(0, 40_000 - 40, 100 / 1.005)).astype(int)
    com[arrivals] = psi[arrivals]
    log["compass"] = wrap(com)
    result = run_log(heading, log, reference="truth")
    assert result.unused == {} and any("changes" in n for n in result.notes)
    assert any("compass 37 ticks" in n and "as they arrive" in n for n in result.notes), result.notes
    assert not any("locked" in n or "recomputed" in n for n in result.notes), result.notes
    assert rms_after(result.estimates["heading"].to_numpy(), psi) < 3 * heading.predicted_std


def test_drifting_clocks_on_both_slow_sensors_meet_the_predicted_error(heading):
    """Odometry 2 % fast, compass 2 % slow: the pattern changes on almost every compass reading,
    so no periodic gain holds; the Kalman filter over the actual arrivals uses every reading
    and its error is the predicted one (and each row's std is that of its own tick)."""
    n = 30_000
    log, psi = heading_log(0, 0, n=n, jitter=0.0)
    odo, com = np.full(n, np.nan), np.full(n, np.nan)
    k_odo = np.round(3 + np.arange(0, n, 10 / 1.02)).astype(int)
    k_com = np.round(37 + np.arange(0, n - 40, 100 / 0.98)).astype(int)
    rng = np.random.default_rng(1)
    odo[k_odo[k_odo < n]] = psi[k_odo[k_odo < n]] + 0.005 * rng.standard_normal(np.sum(k_odo < n))
    com[k_com] = psi[k_com] + 0.05 * rng.standard_normal(len(k_com))
    log["odometry"], log["compass"] = wrap(odo), wrap(com)
    result = run_log(heading, log, std=True)
    assert result.unused == {} and any("as they arrive" in n for n in result.notes)
    err = rms_after(result.estimates["heading"].to_numpy(), psi)
    predicted = float(np.sqrt(np.mean(result.estimates["heading_std"].to_numpy()[3000:] ** 2)))
    assert 0.75 * predicted < err < 1.25 * predicted, (err, predicted)


def test_missed_readings_are_bridged_by_the_kalman_filter_over_the_arrivals(heading):
    """A log drawn from the table's model: odometry with dropouts of 1 to 6 readings that stops
    for good at 100 s, a compass that starts at 40 s.  From each missed reading until its
    covariance is back on the table's, the log runs the Kalman filter of the table's model over
    the readings that arrive, so its estimate and std are that filter's (the table's fixed gains,
    kept through the outages, had 1.27 times its RMS error: a compass gain made for a heading the
    odometry held, and small gains on the readings after each dropout)."""
    from cfdesign.runtime.arrivals import ArrivalKalman

    n = 15_000
    x, readings = model_log(heading, n, seed=7)
    odo = readings["odometry"]
    rng = np.random.default_rng(5)
    for start in range(300, 9000, 600):  # runs of 1..6 readings lost
        odo[start:start + 10 * int(rng.integers(1, 7))] = np.nan
    odo[10_000:] = np.nan
    readings["compass"][:4_000] = np.nan
    result = run_log(heading, pd.DataFrame({"time": np.arange(n) * 0.01, **readings}), std=True)
    assert result.unused == {}
    est, std = result.estimates["heading"].to_numpy(), result.estimates["heading_std"].to_numpy()
    kf = ArrivalKalman(heading, x0=[odo[0], 0.0])
    states, stds = kf.run(readings["gyro"][:, None], np.column_stack([readings[s.name] for s in heading.measurements]))
    for start in (3000, 10_000):  # over the log, and after the odometry stopped
        assert rms_after(est, x[:, 0], start) <= 1.02 * rms_after(states[:, 0], x[:, 0], start)
    assert np.max(np.abs(std[3000:] / stds[3000:, 0] - 1)) < 0.01


def test_the_arrival_kalman_filter_is_the_table_on_its_own_schedule(heading):
    """On the schedule the table was designed for, the covariance recursion starts at the DARE's
    fixed point and stays there: the same estimates as the table's runtime, the table's stds."""
    from cfdesign.runtime.arrivals import ArrivalKalman

    log, _ = heading_log(0, 0, n=1000, jitter=0.0)
    readings = {s: log[s].to_numpy() for s in ("gyro", "odometry", "compass")}
    x0 = [0.5, 0.0]
    _, expected = Runtime(heading, x0=x0).run(readings, states=True)
    kf = ArrivalKalman(heading, x0=x0)
    y = np.column_stack([readings[s.name] for s in heading.measurements])
    states, stds = kf.run(readings["gyro"][:, None], y)
    assert np.max(np.abs(wrap(states[:, 0] - expected[:, 0]))) < 1e-9
    assert np.max(np.abs(states[:, 1] - expected[:, 1])) < 1e-9
    table_std = np.sqrt([np.diag(heading.P_filtered[k % heading.period]) for k in range(1000)])
    assert np.allclose(stds, table_std, rtol=1e-9)


def mixed_log(n=6000, seed=3):
    """A heading log of three stretches: on the table's schedule, then odometry three ticks late
    with a compass that slips a tick now and then, then a third of the slow readings missed and
    a 3-s outage of both.  Returns the log (exact times) and the true heading."""
    log, psi = heading_log(0, 0, n=n, seed=seed, jitter=0.0)
    rng = np.random.default_rng(seed)
    odo, com = log["odometry"].to_numpy().copy(), log["compass"].to_numpy().copy()
    third = n // 3
    odo[third:2 * third], com[third:2 * third] = np.nan, np.nan
    late = np.arange(third + 3, 2 * third, 10)
    odo[late] = wrap(psi[late] + 0.005 * rng.standard_normal(len(late)))
    slip = np.arange(third + 37, 2 * third, 100) + rng.integers(0, 2, len(range(third + 37, 2 * third, 100)))
    com[slip] = wrap(psi[slip] + 0.05 * rng.standard_normal(len(slip)))
    for col in (odo, com):
        read = np.flatnonzero(~np.isnan(col[2 * third:])) + 2 * third
        col[rng.choice(read, len(read) // 3, replace=False)] = np.nan
        col[2 * third + 700:2 * third + 1000] = np.nan
    log["odometry"], log["compass"] = odo, com
    return log, psi


def per_tick_kalman(table, x0, u, y, prior=False):
    """The Kalman filter over the arrivals written out plainly, one tick at a time (the
    reference of :class:`ArrivalKalman`, whose ticks without a reading are taken in closed form):
    the states and standard deviations of a heading table (every reading an angle) after each
    tick's readings and, with ``prior``, before them."""
    F, B, H, Q, R = (np.asarray(M, dtype=float) for M in (table.F, table.B, table.H, table.Q, table.R))
    x, P = np.array(x0, dtype=float), np.array(table.P[0], dtype=float)
    states, stds = np.empty((len(u), len(x))), np.empty((len(u), len(x)))
    priors, prior_stds = np.empty((len(u), len(x))), np.empty((len(u), len(x)))
    for k, (uk, yk) in enumerate(zip(u, y, strict=True)):
        priors[k], prior_stds[k] = x, np.sqrt(np.diag(P))
        rows = np.flatnonzero(~np.isnan(yk))
        if rows.size:
            Hk, Rk = H[rows], R[np.ix_(rows, rows)]
            L = P @ Hk.T @ np.linalg.inv(Hk @ P @ Hk.T + Rk)
            A = np.eye(len(x)) - L @ Hk
            x, P = x + L @ wrap(yk[rows] - Hk @ x), A @ P @ A.T + L @ Rk @ L.T
        states[k], stds[k] = x, np.sqrt(np.diag(P))
        x, P = F @ x + B @ uk, F @ P @ F.T + Q
        x[0] = wrap(x[0])
    return (priors, prior_stds) if prior else (states, stds)


def test_the_arrival_kalman_filter_coasts_as_it_steps(heading, monkeypatch):
    """The ticks without a reading are taken in closed form, 64 at a time: on a log mixing
    on-schedule stretches, late and slipping readings and missed ones (and an outage longer than
    64 ticks), in two calls split mid-gap, the states and stds are those of the filter stepped
    one tick at a time, to rounding (1e-12 of each column's largest value); and run_log, whose
    Runtime stretches hand over to that filter where readings are missed, gives the same
    estimates as with the closed form cut to one tick."""
    from cfdesign.runtime.arrivals import ArrivalKalman

    log, _ = mixed_log()
    u = log[["gyro"]].to_numpy()
    y = log[[s.name for s in heading.measurements]].to_numpy()
    x0 = [float(log["odometry"][0]), 0.0]
    cut = 2345  # a tick between readings: the second call starts mid-gap
    assert (~np.isnan(y)).any(axis=1)[cut - 1:cut + 1].sum() == 0
    for output in ("posterior", "prior"):
        expected, expected_std = per_tick_kalman(heading, x0, u, y, prior=output == "prior")
        kf = ArrivalKalman(heading, output, x0=x0)
        parts = [kf.run(u[:cut], y[:cut]), kf.run(u[cut:], y[cut:])]
        states, stds = (np.concatenate(a) for a in zip(*parts, strict=True))
        diff = np.abs(states - expected)
        diff[:, 0] = np.abs(wrap(diff[:, 0]))
        assert np.all(diff <= 1e-12 * np.abs(expected).max(axis=0)), (output, diff.max(axis=0))
        assert np.allclose(stds, expected_std, rtol=1e-12, atol=0), output

    on_schedule, _ = heading_log(0, 0, n=len(log), seed=3, jitter=0.0)
    bridged = log.copy()  # the middle stretch back on the schedule: Runtime stretches, bridged where missed
    middle = slice(len(log) // 3, 2 * len(log) // 3)
    bridged.loc[middle, ["odometry", "compass"]] = on_schedule.loc[middle, ["odometry", "compass"]]
    fast = [run_log(heading, x, std=True) for x in (log, bridged)]
    monkeypatch.setattr(ArrivalKalman, "COAST", 1)
    slow = [run_log(heading, x, std=True) for x in (log, bridged)]
    assert any("as they arrive" in n for n in fast[0].notes) and not any("changes" in n for n in fast[1].notes)
    for f, s in zip(fast, slow, strict=True):
        for col in ("heading", "gyro_correction", "heading_std", "gyro_correction_std"):
            a, b = f.estimates[col].to_numpy(), s.estimates[col].to_numpy()
            d = np.abs(wrap(a - b)) if col == "heading" else np.abs(a - b)
            assert d.max() <= 1e-12 * np.abs(b).max(), (col, d.max())


# ---------------------------------------------------------------------- the logs people have
def test_dates_as_times_run_as_seconds(heading, tmp_path):
    """ISO 8601 text in a CSV and a time-zone-aware datetime column in Parquet are placed as the
    same times in seconds; the estimates equal those of the numeric log, the time column is
    written back as it was; a cell that is no date is named."""
    log, _ = heading_log(3, 37, n=3000)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    start = pd.Timestamp("2024-05-01T12:00:00")
    dated = log.assign(time=(start + pd.to_timedelta(log["time"] - log["time"].iloc[0], unit="s")))
    iso = dated.assign(time=dated["time"].dt.strftime("%Y-%m-%dT%H:%M:%S.%f"))
    iso.to_csv(tmp_path / "iso.csv", index=False)
    dated.assign(time=dated["time"].dt.tz_localize("Europe/Lisbon")).to_parquet(tmp_path / "dt.parquet")
    for path in (tmp_path / "iso.csv", tmp_path / "dt.parquet"):
        result = run_log(heading, path)
        assert np.allclose(result.estimates["heading"].to_numpy(), expected, atol=1e-12, rtol=0), path
    assert run_log(heading, tmp_path / "iso.csv").estimates["time"].iloc[1] == iso["time"].iloc[1]
    iso.loc[5, "time"] = "soon"
    iso.to_csv(tmp_path / "bad.csv", index=False)
    forms = r"neither a number \(seconds, or the --time-unit ms\|us\|ns\) nor an ISO 8601 date and time"
    with pytest.raises(DataError, match=rf"line 7: column 'time' is {forms} \(2024-05-01T12:00:00.010\): 'soon'"):
        run_log(heading, tmp_path / "bad.csv")
    for other in ("12:00:00.010", "2024/05/01 12:00:00", "01.05.2024 12:00:00"):  # named, with the forms read
        iso.assign(time=other).to_csv(tmp_path / "other.csv", index=False)
        with pytest.raises(DataError, match=f"line 2: column 'time' is {forms} .*: '{other}'"):
            run_log(heading, tmp_path / "other.csv")


def test_a_continuous_table_is_refused_saying_how_to_discretise_it():
    """A continuous table (the tilt, cf3 and ckf3 examples as ``cfdesign design`` writes them) cannot
    run a log: the error names ``cfdesign discretize`` (it named nothing to do)."""
    tilt = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("tilt")))
    log = pd.DataFrame({"time": [0.0, 0.005], "gyro": [0.1, 0.1], "accelerometer": [0.2, 0.2]})
    with pytest.raises(CfdesignError, match=r"continuous-time table; logs run discrete tables \(discretise it .*"
                                            r"cfdesign discretize TABLE --rate-hz R"):
        run_log(tilt, log)


def test_missing_cells_padded_with_spaces_are_missing(heading, tmp_path):
    """'NaN ' or 'NULL  ' (a fixed-width export pads its cells) was 'not a number'; they are gaps as
    'NaN' and empty cells are, and a cell that is neither a number nor a gap is still refused."""
    log, _ = heading_log(3, 37, n=300)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    for token in ("NaN ", " nan  ", "NULL   ", "#N/A "):
        log.to_csv(tmp_path / "log.csv", index=False, na_rep=token)
        got = run_log(heading, tmp_path / "log.csv").estimates["heading"].to_numpy()
        assert np.allclose(got, expected, rtol=0, atol=1e-12), token
    log.to_csv(tmp_path / "log.csv", index=False, na_rep="-")
    with pytest.raises(DataError, match="line 2: column 'compass' is not a number: '-'"):
        run_log(heading, tmp_path / "log.csv")


def test_durations_as_times_run_as_seconds(heading, tmp_path):
    """A time column of durations (timedelta; a Parquet duration column) is seconds: it was refused
    as 'neither a number nor an ISO 8601 date'."""
    log, _ = heading_log(3, 37, n=1000)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    durations = log.assign(time=pd.to_timedelta(log["time"], unit="s"))
    durations.to_parquet(tmp_path / "log.parquet")
    for data in (durations, tmp_path / "log.parquet"):
        got = run_log(heading, data).estimates
        assert np.allclose(got["heading"].to_numpy(), expected, rtol=0, atol=1e-9)
        assert got["time"].dtype.kind == "m"  # written as the log had it


def test_times_in_nanoseconds_or_milliseconds_run_with_their_unit(heading, tmp_path, cli):
    """The integer nanoseconds since 1970 of a ROS ``rostopic echo -p`` export (``%time``) run as the
    seconds do, by the column's name or with ``--time-unit ns``, the column written as it was; read
    as seconds (``--time-unit s``), the error names nanoseconds (it asked 'are the times in
    seconds?' of a 'gap' of 1e7 s); milliseconds in Python with ``time_unit='ms'``."""
    from cfdesign.logs.plot import _time_axis

    log, _ = heading_log(0, 0, n=1000, jitter=0.0)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    ns = log.drop(columns="time")
    ns.insert(0, "%time", 1_700_000_000_000_000_000 + np.arange(1000, dtype=np.int64) * 10_000_000)
    ns.to_csv(tmp_path / "ros.csv", index=False)
    table = heading.save(tmp_path / "g.json")
    code, _, err = cli("run", table, tmp_path / "ros.csv", "-o", tmp_path / "e.csv", "--time-unit", "s")
    assert code == 2 and "times in nanoseconds? They are read as seconds unless --time-unit ns is given" in err
    code, _, err = cli("run", table, tmp_path / "ros.csv", "-o", tmp_path / "e.csv")  # '%time' is ROS's: ns
    assert code == 0 and np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-12), err
    code, _, err = cli("run", table, tmp_path / "ros.csv", "-o", tmp_path / "e.csv", "--time", "%time",
                       "--time-unit", "ns")
    assert code == 0, err
    est = pd.read_csv(tmp_path / "e.csv")
    assert np.allclose(_time_axis(est, "%time", 1e-9)[0][:3], [0.0, 0.01, 0.02])  # the plot's axis: seconds
    assert np.allclose(est["heading"], expected, rtol=0, atol=1e-12)
    assert np.array_equal(est["%time"], ns["%time"])  # as the log had it
    ms = log.assign(time=(log["time"] * 1000).round().astype(np.int64))
    assert np.allclose(run_log(heading, ms, time_unit="ms").estimates["heading"], expected, rtol=0, atol=1e-12)
    with pytest.raises(CfdesignError, match="time unit 'min' is none of s, ms, us, ns"):
        run_log(heading, ms, time_unit="min")


def test_comment_lines_before_the_header_and_numpy_savetxt_headers(heading, tmp_path, cli):
    """Lines starting with '#' (and blank lines) before the header are skipped, and the header of
    ``numpy.savetxt`` (``# time,gyro,...`` over rows of numbers) is the header; messages name the
    file's own lines.  Both were 'missing column(s) ... (columns: # logged by ...)'."""
    log, _ = heading_log(0, 0, n=500)
    log = log.drop(columns="lap")
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    table = heading.save(tmp_path / "g.json")
    (tmp_path / "comments.csv").write_text("# logged by robot 7\n\n# 100 Hz\n" + log.to_csv(index=False))
    np.savetxt(tmp_path / "savetxt.csv", log.to_numpy(), delimiter=";", header="run 3\n" + ";".join(log.columns))
    for name in ("comments.csv", "savetxt.csv"):
        code, _, err = cli("run", table, tmp_path / name, "-o", tmp_path / "e.csv")
        assert code == 0, err
        assert np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-12)
    text = (tmp_path / "comments.csv").read_text().splitlines()
    text[10] = "0.07x" + text[10][text[10].index(","):]  # line 11 of the file
    (tmp_path / "bad.csv").write_text("\n".join(text) + "\n")
    code, _, err = cli("run", table, tmp_path / "bad.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "bad.csv line 11: column 'time' is neither a number" in err, err


def test_columns_named_with_their_units(heading, tmp_path, cli):
    """A time column named with its unit (``Time (ms)``, ``t [sec]``) is the time, in that unit (it
    was no time column: every row one tick); a sensor's column named with a unit cfdesign does not
    know is not taken in silence: the error gives the --map that takes it as it is."""
    log, _ = heading_log(0, 0, n=500)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    ms = log.assign(time=(log["time"] * 1000).round(3)).rename(columns={"time": "Time (ms)"})
    assert np.allclose(run_log(heading, ms).estimates["heading"], expected, rtol=0, atol=1e-12)
    assert np.allclose(run_log(heading, log.rename(columns={"time": "t [sec]"})).estimates["heading"], expected,
                       rtol=0, atol=1e-12)
    # --time-unit overrides the name: 'time (s)' over milliseconds (a logger's wrong label) is read in ms
    mislabelled = ms.rename(columns={"Time (ms)": "time (s)"})
    assert np.allclose(run_log(heading, mislabelled, time_unit="ms").estimates["heading"], expected, rtol=0, atol=1e-12)
    with pytest.raises(DataError, match=r"base rate is 0.1\d* Hz .* --time-unit ms is given"):
        run_log(heading, mislabelled)
    log.rename(columns={"gyro": "gyro [LSB]"}).to_csv(tmp_path / "units.csv", index=False)
    table = heading.save(tmp_path / "g.json")
    code, _, err = cli("run", table, tmp_path / "units.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "not taken in silence: --map \"gyro=gyro [LSB]\" reads it as it is" in err, err
    code, _, err = cli("run", table, tmp_path / "units.csv", "-o", tmp_path / "e.csv", "--map", "gyro=gyro [LSB]")
    assert code == 0 and "'LSB' is no unit cfdesign knows; read as it is, in the table's rad/s" in err, err
    assert np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name, unit, factor, said", [("gyro [rad/s]", None, 1.0, None),
                                                      ("Gyro (deg/s)", None, 180 / np.pi, "deg/s"),
                                                      ("gyro [dps]", None, 180 / np.pi, "dps"),
                                                      ("gyro", "mrad/s", 1000.0, "mrad/s"),
                                                      ("gyro", "°/s", 180 / np.pi, "°/s"), ("gyro", "-", 1.0, None)])
def test_a_sensor_column_in_a_unit_of_its_own_is_read_in_it(heading, tmp_path, cli, name, unit, factor, said):
    """A gyro logged in deg/s (named so, ``gyro [deg/s]``, or by a row of units under the header) was
    either refused as a missing column or, mapped or under a row of units, read as rad/s in silence: 57
    times too fast.  A column whose unit cfdesign knows is now read in it, converted to the unit the
    table's sensor reads, with a note; the estimates equal those of the log in rad/s."""
    log, _ = heading_log(0, 0, n=500)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    other = log.assign(gyro=log["gyro"] * factor).rename(columns={"gyro": name})
    text = other.to_csv(index=False, float_format="%.17g", lineterminator="\n")
    if unit is not None:
        head, _, rows = text.partition("\n")
        text = head + "\n" + ",".join(unit if c == "gyro" else "" for c in other.columns) + "\n" + rows
    (tmp_path / "log.csv").write_text(text, encoding="utf-8")
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.csv", "-o", tmp_path / "e.csv")
    assert code == 0, err
    assert np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-9)
    assert (f"is in {said}: read as rad/s" in err) == (said is not None), err
    assert "no unit cfdesign knows" not in err, err


def test_a_column_in_a_unit_of_another_quantity_is_refused(heading):
    """A sensor's or reference's column whose unit is of another quantity than the table reads there
    (a gyro in m/s, a reference heading in m) is refused naming both units, not read."""
    log, truth = heading_log(0, 0, n=500)
    with pytest.raises(DataError, match=r"column 'gyro \[m/s\]' is in m/s, but the table's sensor gyro reads rad/s"):
        run_log(heading, log.rename(columns={"gyro": "gyro [m/s]"}))
    with pytest.raises(DataError, match=r"column 'truth \[m\]' is in m, but the table's reference for heading "
                                        r"reads rad"):
        run_log(heading, log.assign(**{"truth [m]": truth}), reference="truth [m]")
    converted = run_log(heading, log.assign(**{"truth [deg]": np.degrees(truth)}), reference="truth [deg]")
    assert converted.rms["heading"] == pytest.approx(run_log(heading, log.assign(truth=truth),
                                                             reference="truth").rms["heading"], rel=1e-12)



def test_a_sensor_s_own_clock_after_an_underscore_is_no_unit_of_its_readings(heading):
    """``compass_us`` (the compass's own timestamp in us) with no ``compass`` column had been taken as the
    compass in microseconds and refused as not radians; it is a missing compass, and mapped it is read as it
    is, without a note on units (a unit after an underscore is a time column's only)."""
    log, _ = heading_log(0, 0, n=300)
    clock = log.rename(columns={"compass": "compass_us"})
    with pytest.raises(DataError, match=r"missing column\(s\) compass \(columns: .*compass_us"):
        run_log(heading, clock)
    mapped = run_log(heading, clock, mapping={"compass": "compass_us"})
    assert not any("compass_us" in n for n in mapped.notes), mapped.notes
    assert mapped.estimates["heading"].to_numpy() == pytest.approx(run_log(heading, log).estimates["heading"], abs=0)


def test_a_column_by_its_unit_is_taken_only_where_it_can_be_converted(heading):
    """A column named with a unit is the sensor's only where cfdesign converts it: a table whose state
    names do not tell what its gyro reads took ``gyro [deg/s]`` and ran it as it is, 57 times too fast
    with no note on its unit (it is refused with the --map that reads it as it is); two such columns
    for one sensor were called units cfdesign does not know, with a --map for each."""
    import dataclasses

    log, _ = heading_log(0, 0, n=300)
    own = dataclasses.replace(heading, states=("psi", "b"))
    deg = log.assign(gyro=np.degrees(log["gyro"])).rename(columns={"gyro": "gyro [deg/s]"})
    with pytest.raises(DataError, match=r"state names do not tell what its sensor reads\) is not taken in "
                                        r"silence: --map \"gyro=gyro \[deg/s\]\" reads it as it is"):
        run_log(own, deg)
    mapped = run_log(own, deg, mapping={"gyro": "gyro [deg/s]"}, reference="truth")
    assert "column 'gyro [deg/s]': 'deg/s' is not converted: the table's state names do not tell what its sensor " \
           "gyro reads; read as it is, in the table's units" in mapped.notes, mapped.notes
    assert run_log(heading, deg).estimates["heading"].to_numpy() == pytest.approx(
        run_log(heading, log).estimates["heading"].to_numpy(), abs=1e-9)
    both = log.rename(columns={"gyro": "gyro [rad/s]"}).assign(**{"Gyro (dps)": np.degrees(log["gyro"])})
    with pytest.raises(DataError, match=r"sensor gyro has 2 columns named with a unit \(gyro \[rad/s\], Gyro "
                                        r"\(dps\)\): --map \"gyro=COLUMN\" takes one$"):
        run_log(heading, both)


def test_a_column_of_two_uses_is_checked_for_both_and_its_units_agree(heading, tmp_path):
    """A column that feeds a sensor and a reference (or two references) was checked against the first
    only: a gyro in deg/s given as the heading's reference ran; it is refused naming the reference and
    --reference.  A column named in one unit over a row of units giving another is refused (either may
    be wrong), one given twice alike is read once; a row's unit in brackets around brackets
    (``(mrad/(s))``) lost its last one and was read as it is."""
    log, truth = heading_log(0, 0, n=300)
    deg = log.assign(gyro=np.degrees(log["gyro"])).rename(columns={"gyro": "gyro [deg/s]"})
    with pytest.raises(DataError, match=r"'gyro \[deg/s\]' is in deg/s, but the table's reference for heading "
                                        r"reads rad \(another quantity\): give the right column with --reference"):
        run_log(heading, deg, reference="gyro [deg/s]")
    with pytest.raises(DataError, match=r"reference for gyro_correction reads rad/s"):
        run_log(heading, log.assign(**{"truth [deg]": np.degrees(truth)}),
                reference=["truth [deg]", "gyro_correction=truth [deg]"])
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    for name, cell, factor in (("gyro [deg/s]", "rad/s", None), ("gyro [deg/s]", "dps", 180 / np.pi),
                               ("gyro", "(mrad/(s))", 1000.0)):
        text = log.assign(gyro=log["gyro"] * (factor or 1)).rename(columns={"gyro": name}).to_csv(
            index=False, float_format="%.17g", lineterminator="\n")
        head, _, rows = text.partition("\n")
        units = ",".join(cell if c == "gyro" else "" for c in log.columns)
        (tmp_path / "u.csv").write_text(f"{head}\n{units}\n{rows}", encoding="utf-8")
        if factor is None:
            with pytest.raises(DataError, match=r"'gyro \[deg/s\]' is named in deg/s but the row of units gives "
                                                r"it rad/s"):
                run_log(heading, tmp_path / "u.csv")
            continue
        got = run_log(heading, tmp_path / "u.csv")
        assert np.allclose(got.estimates["heading"], expected, rtol=0, atol=1e-9)
        assert sum("read as rad/s" in n for n in got.notes) == 1, got.notes


def test_the_header_written_twice_is_no_row_of_units(heading, tmp_path):
    """A header written twice (its second line not read) gave each sensor a note that its own name was no
    unit cfdesign knows."""
    lines = heading_log(0, 0, n=200)[0].to_csv(index=False).splitlines()
    (tmp_path / "top.csv").write_text("\n".join([lines[0], *lines]) + "\n")
    notes = run_log(heading, tmp_path / "top.csv").notes
    assert not any("no unit" in n or "read as" in n for n in notes), notes


def test_spreadsheet_exports_and_extra_columns(heading, tmp_path):
    log, _ = heading_log(0, 0, n=500)
    text = log.to_csv(index=False, lineterminator="\r\n")
    (tmp_path / "excel.csv").write_bytes(b"\xef\xbb\xbf" + text.encode())
    a = run_log(heading, tmp_path / "excel.csv").estimates
    b = run_log(heading, log).estimates
    assert list(a.columns) == list(b.columns) and np.allclose(a["heading"], b["heading"], atol=0)


def test_semicolons_tabs_decimal_commas_and_spaced_names_read_as_commas(heading, tmp_path):
    """A header 'time ,gyro ' was refused (the columns were read by their stripped names); a
    semicolon- (with decimal commas) or tab-separated export was one column named 'time;gyro;...';
    decimal commas were looked for in the first row only (all integers at time 0: refused), and
    not at all in tab-separated exports."""
    log, _ = heading_log(3, 37, n=600)
    log.loc[0, ["time", "gyro", "truth"]] = 0.0  # a first row of integers: no decimal comma to see in it
    expected = run_log(heading, log).estimates["heading"].to_numpy()

    def integers_first(text, sep):
        lines = text.split("\n")
        return "\n".join([lines[0], sep.join(["0", "0", "", "", "0", "0"]), *lines[2:]])

    files = {"spaced.csv": log.rename(columns={"time": "time ", "gyro": " gyro "}).to_csv(index=False),
             "semicolons.csv": integers_first(log.to_csv(index=False, sep=";", decimal=","), ";"),
             "semicolons_dots.csv": log.to_csv(index=False, sep=";"),
             "tabs.tsv": log.to_csv(index=False, sep="\t"),
             "tabs_commas.tsv": integers_first(log.to_csv(index=False, sep="\t", decimal=","), "\t")}
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        for rows in (None, 250):  # in one piece and in blocks
            got = run_log(heading, tmp_path / name, block_rows=rows).estimates
            assert list(got.columns) == ["time", "heading", "gyro_correction", "truth", "lap"], name
            assert np.allclose(got["heading"], expected, rtol=0, atol=1e-12), name
            assert got["truth"].dtype.kind == "f", name  # passed-through columns stay numbers


def test_logs_separated_by_spaces_as_numpy_savetxt_writes_them(heading, tmp_path):
    """``numpy.savetxt``'s default separator is a space, with or without its '# ' header: the
    header was one column ('missing column(s) gyro, ...', or the first row's numbers as names);
    columns are split at spaces where the header and the first row split into as many cells."""
    log, _ = heading_log(3, 37, n=600)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    names = " ".join(log.columns)
    np.savetxt(tmp_path / "hashed.txt", log.to_numpy(float), header=names)
    np.savetxt(tmp_path / "plain.txt", log.to_numpy(float), header=names, comments="")
    aligned = log.to_string(index=False, na_rep="nan", float_format="{:.17g}".format)  # runs of spaces
    (tmp_path / "aligned.txt").write_text(aligned)
    for name in ("hashed.txt", "plain.txt", "aligned.txt"):
        for rows in (None, 250):
            got = run_log(heading, tmp_path / name, block_rows=rows).estimates
            assert list(got.columns) == ["time", "heading", "gyro_correction", "truth", "lap"], name
            assert np.allclose(got["heading"], expected, rtol=0, atol=1e-9), name


def test_an_empty_cell_of_a_log_separated_by_spaces_is_refused_naming_its_line(heading, tmp_path, cli):
    """A column-aligned table written with blanks where a slow sensor has no reading (na_rep=''):
    at spaces the blank is no cell, so pandas read each later cell into the column before it
    (the truth read as the compass, the lap as the truth) and ran with exit 0.  Refused, naming
    the first such line (after comment lines and a row of units too); 'nan' in the cell still reads."""
    log, _ = heading_log(0, 0, n=300)
    text = log.to_string(index=False, na_rep="", float_format="{:.17g}".format)
    (tmp_path / "blank.txt").write_text(text + "\n")
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "blank.txt", "-o", tmp_path / "e.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "blank.txt line 3: 4 cells under a header of 6 columns separated by spaces" in err
    assert not (tmp_path / "e.csv").exists()
    lines = text.splitlines()
    (tmp_path / "units.txt").write_text("\n".join(["# logged", lines[0], "s rad/s rad rad rad 1", *lines[1:]]) + "\n")
    with pytest.raises(DataError, match=r"units.txt line 5: 4 cells"):
        run_log(heading, tmp_path / "units.txt")
    with pytest.raises(DataError, match=r"line 3: 4 cells"):
        cfdesign.logs.read_columns(tmp_path / "blank.txt", ["gyro"])
    filled = log.to_string(index=False, na_rep="nan", float_format="{:.17g}".format)
    (tmp_path / "filled.txt").write_text(filled + "\n")
    assert np.allclose(run_log(heading, tmp_path / "filled.txt").estimates["heading"],
                       run_log(heading, log).estimates["heading"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("sep", ["|", " "])
def test_a_header_read_as_one_column_says_how_cells_are_separated(heading, tmp_path, cli, sep):
    """A log separated by '|', or by spaces under a header whose names hold spaces ('time [s]'),
    is one column: the message says so and which separators are read."""
    header = sep.join(["time [s]" if sep == " " else "time", "gyro", "compass", "odometry"])
    (tmp_path / "log.txt").write_text(header + "\n" + "".join(sep.join(["0.2" if k else "0", "1", "2", "3"]) + "\n"
                                                              for k in range(2)))
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.txt", "-o", tmp_path / "e.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "the header is one column: cells are separated by commas" in err


def test_a_separator_after_each_row_s_last_cell_is_no_index(heading, tmp_path, cli):
    """Rows ending in a separator the header does not end in ('0.01,0.5,' under 'time,gyro'): pandas
    took the first cell of each row as an index and every column from its neighbour's cells, the
    gyro's read as times ('time 0.158 goes back'; a monotonic column would have run in silence).
    Empty cells past the header are columns without a name; cells with values there are refused
    on one line naming the line, with the decimal comma of a comma-separated export as the likely
    cause."""
    log, _ = heading_log(3, 37, n=600)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    lines = log.to_csv(index=False).splitlines()
    (tmp_path / "trailing.csv").write_text("\n".join([lines[0], *(line + "," for line in lines[1:])]) + "\n")
    for rows in (None, 250):
        got = run_log(heading, tmp_path / "trailing.csv", block_rows=rows).estimates
        assert np.allclose(got["heading"], expected, rtol=0, atol=1e-12)
    text = "time,gyro,compass,odometry\n0,000,0,100,0,200,0,300\n0,200,0,100,0,200,0,300\n"
    (tmp_path / "commas.csv").write_text(text)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "commas.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "line 2: 8 cells under a header of 4 columns (decimal commas" in err
    (tmp_path / "quoted.csv").write_text('time,gyro,compass,odometry\n"0,0","0,1","0,2","0,3"\n')
    code, _, err = cli("run", tmp_path / "g.json", tmp_path / "quoted.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "'0,0' (a decimal comma: read in a log separated by semicolons" in err


@pytest.mark.parametrize("name, scale", [("time_ms", 1e3), ("t_us", 1e6), ("timestamp", 1.0), ("Timestamp_s", 1.0)])
def test_a_time_column_named_timestamp_or_with_its_unit_after_an_underscore(heading, name, scale):
    """'time_ms' and 'timestamp' were no time column: every row was taken as one tick (a note), so
    a log with dropped rows ran its readings on the wrong ticks; they are the time (in the unit the
    name gives, else seconds)."""
    log, _ = heading_log(3, 37, n=600)
    log = log.drop(index=range(100, 110))
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    named = log.assign(time=np.round(log["time"] * scale, 9)).rename(columns={"time": name})
    result = run_log(heading, named)
    assert result.notes == [] or not any("no time column" in n for n in result.notes), result.notes
    assert np.allclose(result.estimates["heading"], expected, rtol=0, atol=1e-9)


def test_times_written_with_too_few_digits_are_named_so(heading, tmp_path, cli):
    """Unix times written with ten digits ('%.10g': 1700000000) or by '%g' (1.7e+09) repeat
    from row to row: the line said only 'time 1700000000.0 repeats'; it now says to how much the
    times are written against the tick."""
    log, _ = heading_log(3, 37, n=300)
    table = heading.save(tmp_path / "g.json")
    for fmt, step in (("%.10g", "1 s"), ("%g", "1e+08 s")):
        log.assign(time=log["time"] + 1.7e9).to_csv(tmp_path / "log.csv", index=False, float_format=fmt)
        code, _, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv")
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert "repeats 1700000000.0 on the line before" in err and f"the times are written to {step}, coarser " \
            "than the table's tick of 0.01 s (write them with more digits)" in err, err
    log.loc[5, "time"] = log.loc[4, "time"]  # a genuine repeat of times written in full: no such words
    log.to_csv(tmp_path / "log.csv", index=False)
    code, _, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv")
    assert code == 2 and "repeats" in err and "written to" not in err, err


def test_a_spreadsheet_s_sep_line_names_the_separator(heading, tmp_path):
    """A first line 'sep=;' (written so that a spreadsheet opens the file in columns) was read as
    the header: two columns 'sep=' and ''.  It names the separator and is skipped; lines in
    messages are still the file's own."""
    log, _ = heading_log(3, 37, n=300)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    for sep, decimal in ((";", ","), (",", ".")):
        text = log.to_csv(index=False, sep=sep, decimal=decimal)
        (tmp_path / "log.csv").write_text(f"\ufeffsep={sep}\n" + text, encoding="utf-8")
        assert np.allclose(run_log(heading, tmp_path / "log.csv").estimates["heading"], expected, rtol=0, atol=1e-12)
    (tmp_path / "bad.csv").write_text("sep=;\ntime;gyro;compass;odometry\n0;1;2;3\n0,2;1;abc;3\n")
    with pytest.raises(DataError, match=r"bad\.csv line 4: column 'compass' is not a number"):
        run_log(heading, tmp_path / "bad.csv")


def test_sensor_columns_named_in_another_case_are_the_sensors(heading):
    """'GYRO', 'Compass' for the table's gyro and compass (as 'Time' for the time): refused as
    missing; a unique match in another case is the sensor's column."""
    log, _ = heading_log(3, 37, n=600)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    got = run_log(heading, log.rename(columns={"gyro": "GYRO", "compass": "Compass"})).estimates
    assert np.allclose(got["heading"], expected, rtol=0, atol=1e-12)
    with pytest.raises(DataError, match="missing column"):  # two of them: none is taken
        run_log(heading, log.rename(columns={"gyro": "GYRO"}).assign(Gyro=1.0))


def test_a_row_pandas_cannot_parse_in_a_later_block_is_a_user_error(heading, tmp_path, cli, monkeypatch):
    """A big log is read in blocks: a broken row (an unclosed quote, a row of extra cells) far
    into it stopped cfdesign run as an internal error (exit 3), and extra cells were dropped."""
    import cfdesign.logs.run

    monkeypatch.setattr(cfdesign.logs.run, "ONE_PASS_BYTES", 0)
    monkeypatch.setattr(cfdesign.logs.run, "BLOCK_ROWS", 300)
    table = heading.save(tmp_path / "g.json")
    lines = heading_log(3, 37, n=1000)[0].to_csv(index=False).splitlines()
    for name, row, message in (("quote.csv", '"0.5,1,2', 'line 701: a quote (") opened in a cell is never closed'),
                               ("cells.csv", lines[700] + ",1,2", "line 701: 8 cells under a header of 6 columns")):
        (tmp_path / name).write_text("\n".join([*lines[:700], row, *lines[701:]]) + "\n")
        code, _, err = cli("run", table, tmp_path / name, "-o", tmp_path / "out.csv")
        assert code == 2 and len(err.strip().splitlines()) == 1 and message in err, err
        assert not (tmp_path / "out.csv").exists()


def test_map_and_the_python_api_take_dataframes(heading):
    log, _ = heading_log(0, 0, n=2000)
    renamed = log.rename(columns={"gyro": "gz", "compass": "mag_heading"})
    a = run_log(heading, renamed, mapping={"gyro": "gz", "compass": "mag_heading"}).estimates
    b = run_log(heading, log).estimates
    assert np.array_equal(a["heading"].to_numpy(), b["heading"].to_numpy())
    # the runtime takes a DataFrame as it takes a dict of arrays (rows = ticks)
    # run_log starts from the first reading, the most precise one on a shared tick (the odometry's, not the compass's)
    var = {s.name: heading.R[s.index, s.index] for s in heading.measurements if log[s.name].notna()[0]}
    assert len(var) == 2 and min(var, key=var.get) == "odometry"
    c = Runtime(heading, x0=[log[min(var, key=var.get)][0], 0.0]).run(log)
    assert np.max(np.abs(wrap(c - b["heading"].to_numpy()))) < 1e-6
    with pytest.raises(DataError, match=r"--map spin: .* has no sensor 'spin'"):
        run_log(heading, log, mapping={"spin": "gz"})


def test_the_state_starts_from_the_most_precise_direct_reading_of_its_tick(heading):
    """The compass (the noisier sensor) 0.3 rad off on the first row, the odometry right: the start
    is the odometry's reading, whatever the sensors' names (the first by name, the compass, had
    started the heading 0.3 rad off, its error then decaying over the filter's time constant)."""
    log, truth = heading_log(0, 0, n=300)
    log.loc[0, "compass"] = log.loc[0, "odometry"] + 0.3
    est = run_log(heading, log).estimates["heading"].to_numpy()
    assert abs(wrap(est[0] - log.loc[0, "odometry"])) < 0.02 and abs(wrap(est[0] - truth[0])) < 0.05


def test_blocks_equal_one_pass_also_across_a_tick_split_between_blocks(heading):
    """An event log (a row per reading, several rows on one tick) run in blocks of 777 rows
    gives what one block gives."""
    log, _ = heading_log(0, 0, n=3000, jitter=0.0)
    events = []
    for lag, name in ((1e-4, "odometry"), (2e-4, "compass")):
        rows = log[log[name].notna()]
        ev = rows[["time", name]].copy()
        ev["time"] += lag  # logged just after the IMU row: the same tick
        events.append(ev)
    imu = log.drop(columns=["odometry", "compass"])
    event_log = pd.concat([imu, *events]).sort_values("time", kind="stable").reset_index(drop=True)
    one = run_log(heading, event_log).estimates
    blocks = run_log(heading, event_log, block_rows=777).estimates
    assert len(one) == len(event_log) and np.allclose(one["heading"], blocks["heading"], atol=1e-12)
    assert np.allclose(run_log(heading, log).estimates["heading"].to_numpy(),
                       one["heading"].to_numpy()[event_log["gyro"].notna().to_numpy()], atol=1e-9)


def test_the_state_starts_from_the_first_direct_reading_in_any_block(heading, gps3):
    """start='reading' takes the quantity from the log's first direct reading even when that lies
    beyond the first block of rows (a GPS without a fix for the first block, a compass started
    late): the first block started from zero instead, so the estimates of a log depended on its
    block size (a 3 Hz GPS table on a log whose first 5 fixes are missing was 1.4 m apart from row
    0 to the end with blocks of 50 rows; the heading table here 1.97 rad apart, 0.097 rad at the end
    with blocks of 200)."""
    log, _ = heading_log(3, 37, n=3000, jitter=0.0)
    log.loc[:1500, ["odometry", "compass"]] = np.nan  # no direct reading in the first blocks
    one = run_log(heading, log).estimates["heading"].to_numpy()
    for rows in (200, 777):
        assert np.allclose(run_log(heading, log, block_rows=rows).estimates["heading"], one, atol=1e-12)
    _, readings = model_log(gps3, 3000, seed=5)
    gps = readings["gps"].copy()
    gps[: np.flatnonzero(np.isfinite(gps))[5]] = np.nan
    gps += 1000.0  # far from the zero a block without a fix started from
    log = pd.DataFrame({"time": np.arange(3000) * 0.01, "accelerometer": readings["accelerometer"], "gps": gps})
    one = run_log(gps3, log).estimates["position"].to_numpy()
    first = np.flatnonzero(np.isfinite(gps))[0]  # the rows before it are moved back from it by the inputs
    assert abs(one[first] - gps[first]) < 1e-9
    assert np.allclose(run_log(gps3, log, block_rows=50).estimates["position"], one, atol=1e-9)


@pytest.mark.parametrize("option", [{"mapping": [("gyro", "gyro")]}, {"mapping": "gyro=gyro"}, {"reference": 5},
                                    {"reference": ["truth", None]}, {"reference": {"heading": "truth"}}])
def test_column_options_of_another_type_are_named(heading, option):
    """A mapping given as pairs raised dict()'s raw ValueError, a reference given as a number list()'s
    raw TypeError and a None among references a raw AttributeError; a dict as references took its keys."""
    log, _ = heading_log(3, 37, n=300)
    with pytest.raises(CfdesignError, match=r"mapping must be a dict|reference must be a column name"):
        run_log(heading, log, **option)
    assert set(run_log(heading, log, reference=("heading=truth",), mapping={"gyro": "gyro"}).rms) == {"heading"}


@pytest.mark.parametrize("rows", [-5, 0.5, 1.5, True, "100", np.float64(10.0)])
def test_block_rows_that_are_not_a_positive_whole_number_are_refused(heading, rows):
    """block_rows=-5 read no row and said 'the log has a header but no rows', 1.5 raised a raw
    TypeError, True ran one row a block; np.int64 is a number of rows."""
    log, _ = heading_log(3, 37, n=300)
    with pytest.raises(CfdesignError, match="block_rows must be a positive whole number of rows"):
        run_log(heading, log, block_rows=rows)
    assert np.array_equal(run_log(heading, log, block_rows=np.int64(100)).estimates["heading"],
                          run_log(heading, log, block_rows=100).estimates["heading"])


def test_the_base_rate_is_measured_over_the_log_not_per_block(heading):
    """Jitter of 3 % of a tick moves single steps by up to 6 %: a last block of three rows, or a log
    of four, was refused for a rate 1.2 % off; a log 1.5 % off still is, whatever its blocks."""
    log = heading_log(3, 37, n=3003, seed=1, jitter=0.03)[0]
    for seed in range(8):
        log["time"] = np.arange(3003) * 0.01 + 0.0003 * np.random.default_rng(seed).uniform(-1, 1, 3003)
        one = run_log(heading, log).estimates["heading"].to_numpy()
        assert np.allclose(run_log(heading, log, block_rows=1000).estimates["heading"], one, atol=1e-12)
        run_log(heading, log.iloc[:4])
    log["time"] = np.arange(3003) * 0.01015
    for rows in (None, 1000):
        with pytest.raises(DataError, match=r"base rate is 98\.5"):
            run_log(heading, log, block_rows=rows)


def test_the_base_rate_of_rows_jittered_within_half_a_tick_is_their_grid_rate():
    """+-0.35 tick of uniform jitter: a step of 1.6 ticks counted as two (every step at least one)
    read a 100 Hz log as 104 Hz and refused it; a log 2 % off with the same jitter is refused."""
    from cfdesign.timing import check_rate

    rng = np.random.default_rng(4)
    jitter = 0.0035 * rng.uniform(-1, 1, 20_000)
    check_rate(np.arange(20_000) * 0.01 + jitter, 0.01, "log")
    with pytest.raises(DataError, match=r"base rate is 9[78]\.\d+ Hz"):
        check_rate(np.arange(20_000) * 0.0102 + jitter, 0.01, "log")


@pytest.mark.parametrize("drop, jitter", [(0.05, 0.2), (0.1, 0.3), (0.3, 0.3), (0.3, 0.05)])
def test_an_imu_that_drops_rows_is_at_its_rate(heading, drop, jitter):
    """Rows missing at random: the median of all steps took the steps over dropped rows, and a
    100 Hz log missing one row in twenty with +-0.2 tick of jitter was refused as 98.8 Hz (one in
    ten with +-0.3 tick: 96.4 Hz).  It runs, every reading used; 2 % off is still refused."""
    from cfdesign.timing import check_rate

    rng = np.random.default_rng(1)
    keep = rng.random(20_000) > drop
    ticks = np.arange(20_000) + jitter * rng.uniform(-1, 1, 20_000)
    check_rate(ticks[keep] * 0.01, 0.01, "log")
    with pytest.raises(DataError, match=r"base rate is 9[78]\.\d+ Hz"):
        check_rate(ticks[keep] * 0.0102, 0.01, "log")
    log, _ = _jittered(6000)
    log = log[(rng.random(6000) > drop) | log["odometry"].notna().to_numpy()]
    result = run_log(heading, log, reference="truth")
    assert result.unused == {} and result.rms["heading"] < 3 * heading.predicted_std


def test_time_stamps_jittered_within_half_a_tick_put_every_row_on_its_own_tick(heading):
    """Rows jittered uniformly by +-0.35 tick: the base rate is the table's (counting ticks step by
    step made the log 4 % too fast: refused), and every row lands on its own tick (measured from
    the first row's jittered time, one row in ten fell on its neighbour's tick): the estimates
    are those of the same readings on exact ticks."""
    log, _ = heading_log(3, 37, n=4000, seed=2, jitter=0.0)
    exact = run_log(heading, log)
    rng = np.random.default_rng(3)
    for jitter in (0.35, -0.35, 0.1):  # uniform jitter, and a first row at the edge of its range
        times = log["time"] + 0.01 * rng.uniform(-abs(jitter), abs(jitter), len(log))
        times[0] = log["time"][0] + 0.01 * jitter
        result = run_log(heading, log.assign(time=times))
        assert result.unused == {}, result.unused
        assert np.array_equal(result.estimates["heading"], exact.estimates["heading"])


@pytest.mark.parametrize("case", ["drift +0.5%, jitter +-0.3", "drift -0.8%", "drift 200 ppm, 30000 rows",
                                  "jitter +-0.49", "stamped on receipt: delay 0 to 0.9 tick"])
def test_a_drifting_clock_or_jitter_across_a_tick_puts_every_row_on_its_own_tick(case, heading):
    """A log clock that drifts within the 1 % the rate check allows gained or lost a tick every
    1/drift rows (0.5 %: a second gyro row on one tick not used every 200 rows, RMS 1.14 times the
    designed on the 5 Hz heading example); jitter spanning most of a tick left the circular mean of
    the phases undetermined (+-0.49 tick: one IMU row in four on a shared tick).  The grid is now
    fitted to the rows (timing.grid_fit): the estimates are those of the same log on exact ticks."""
    n = 30_000 if "ppm" in case else 4000
    log, _ = heading_log(0, 0, n=n, jitter=0.0)
    exact = run_log(heading, log).estimates["heading"].to_numpy()
    rng = np.random.default_rng(11)
    k = np.arange(n)
    drift = {"drift +0.5%, jitter +-0.3": 1.005, "drift -0.8%": 0.992,
             "drift 200 ppm, 30000 rows": 1.0002}.get(case, 1.0)
    jitter = {"drift +0.5%, jitter +-0.3": rng.uniform(-0.3, 0.3, n), "jitter +-0.49": rng.uniform(-0.49, 0.49, n),
              "stamped on receipt: delay 0 to 0.9 tick": rng.uniform(0, 0.9, n)}.get(case, np.zeros(n))
    result = run_log(heading, log.assign(time=1.7e9 + 0.01 * (k * drift + jitter)))
    assert result.unused == {} and result.notes == [], (result.unused, result.notes)
    assert np.array_equal(result.estimates["heading"].to_numpy(), exact)



@pytest.mark.parametrize("drift, jitter", [(1.005, 0.3), (1.0002, 0.45), (0.992, 0.45)])
def test_grid_fit_keeps_a_drifting_jittered_clock_on_its_ticks_over_every_fitted_row(drift, jitter):
    """The spacing was the median step refined by least squares over all of the first FIT_ROWS rows
    on the ticks that step gave them; a step a few parts in 1e6 off slipped those ticks by half a
    tick within the rows, and a slope fitted to ticks that slipped is the same spacing again: a
    clock 0.5 % fast with +-0.3 tick of jitter had one row in six on a shared tick past row 34,000
    (200 ppm with +-0.45: every third).  The slope is now fitted over a span of rows doubled from
    FIT_START, each on the ticks of the span before."""
    from cfdesign.timing import FIT_ROWS, grid_fit, nearest_tick

    k = np.arange(FIT_ROWS)
    t = 1.7e9 + 0.01 * (drift * k + np.random.default_rng(1).uniform(-jitter, jitter, FIT_ROWS))
    origin, spacing = grid_fit(t, 0.01)
    assert np.array_equal(nearest_tick((t - origin) / spacing), k)
    assert abs(spacing / (0.01 * drift) - 1) * FIT_ROWS < 0.01  # under a hundredth of a tick over the fit

BAD_LOGS = {
    "empty.csv": ("", "empty file"),
    "header.csv": ("time,gyro,compass,odometry\n", "header but no rows"),
    "missing.csv": ("time,gyro,compass\n0,1,2\n", r"missing column\(s\) odometry"),
    "text.csv": ("time,gyro,compass,odometry\n0,1,2,3\n0.2,1,abc,3\n", "line 3: column 'compass' is not a number"),
    "rate.csv": ("time,gyro,compass,odometry\n" + "".join(f"{0.1 * k},1,2,3\n" for k in range(5)),
                 "base rate is 10 Hz .* the table runs at 5 Hz; a gain table is designed for one rate$"),
    "ms.csv": ("time,gyro,compass,odometry\n" + "".join(f"{200 * k},1,2,3\n" for k in range(5)),
               r"base rate is 0\.005 Hz .* \(times in milliseconds\? they are read as seconds unless "
               r"--time-unit ms is given\)"),
    "back.csv": ("time,gyro,compass,odometry\n0,1,2,3\n0.2,1,2,3\n0.1,1,2,3\n", "line 4: time 0.1 goes back"),
    "dup.csv": ("time,gyro,compass,odometry\n0,1,2,3\n0.2,1,2,3\n0.2,1,2,3\n", "line 4: time 0.2 repeats"),
    "nan.csv": ("time,gyro,compass,odometry\n0,1,2,3\n,1,2,3\n",
                r"line 3: no time \(an empty cell; every row needs one\)"),
    "inf.csv": ("time,gyro,compass,odometry\n0,1,2,3\ninf,1,2,3\n", "line 3: time inf is not a finite number"),
    "cells.csv": ("time,gyro,compass,odometry\n0,1,2,3\n0.2,1,2,3,4,5\n",
                  "line 3: 6 cells under a header of 4 columns"),
    "comment.csv": ("time,gyro,compass,odometry\n0,1,2,3\n# restarted\n0.2,1,2,3\n",
                    r"line 3: .*'# restarted' \(a comment line: only those before the header are skipped\)$"),
}


@pytest.mark.parametrize("name", sorted(BAD_LOGS))
def test_bad_logs_one_line_exit_2_nothing_written(name, tmp_path, cli):
    table = cfdesign.design(cfdesign.load_spec(cfdesign.example_path("dckf3"))).save(tmp_path / "g.json")
    text, message = BAD_LOGS[name]
    (tmp_path / name).write_text(text)
    (tmp_path / "out.csv").write_text("previous")
    code, _, err = cli("run", table, tmp_path / name, "-o", tmp_path / "out.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert pytest.importorskip("re").search(message, err), err
    assert (tmp_path / "out.csv").read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["g.json", name, "out.csv"])


BAD_OPTIONS = {  # each ran without a word: the filter on the wrong readings, or a reference lost
    "a column for two sensors": (["--map", "gyro=gz", "--map", "compass=gz"],
                                 "column 'gz' is given to sensors gyro and compass"),
    "a sensor's own column taken": (["--map", "compass=gyro"], "column 'gyro' is given to sensors gyro and compass"),
    "a sensor mapped twice": (["--map", "gyro=gz", "--map", "gyro=gyro"],
                              "--map gyro is given twice ('gz' and 'gyro')"),
    "the time as a sensor": (["--map", "gyro=time"], "column 'time' is both the time and sensor gyro"),
    "a sensor as the time": (["--time", "gz", "--map", "gyro=gz"], "column 'gz' is both the time and sensor gyro"),
    "two references of a state": (["--reference", "truth", "--reference", "heading=compass"],
                                  "state heading already has the reference 'truth'"),
}


@pytest.mark.parametrize("case", sorted(BAD_OPTIONS))
def test_conflicting_map_time_and_reference_options_are_refused(case, heading, tmp_path, cli):
    log, _ = heading_log(0, 0, n=300)
    log.assign(gz=log["gyro"]).to_csv(tmp_path / "log.csv", index=False)
    options, message = BAD_OPTIONS[case]
    table = heading.save(tmp_path / "g.json")
    code, _, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv", *options)
    assert code == 2 and len(err.strip().splitlines()) == 1 and message in err, err
    assert not (tmp_path / "e.csv").exists()


def test_compressed_csv_logs_and_estimates(heading, tmp_path, cli):
    """A CSV compressed with gzip, bz2, xz or zip (one file) runs as the plain CSV, whatever its
    name (a gzip named .csv; a Parquet file named .bin); estimates named .csv.gz are gzip.  Each
    was an error naming a byte of UTF-8 ('0x8b') or, for .csv.gz output, a plain CSV."""
    import bz2
    import gzip
    import lzma
    import zipfile

    from cfdesign.cli import _log_paths
    from cfdesign.logs.fleet import _log_stem

    log, _ = heading_log(0, 0, n=1000)
    text = log.to_csv(index=False).encode()
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    (tmp_path / "gz.csv").write_bytes(gzip.compress(text))
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs/log.csv.bz2").write_bytes(bz2.compress(text))
    (tmp_path / "logs/log.csv.xz").write_bytes(lzma.compress(text))
    with zipfile.ZipFile(tmp_path / "logs/log.csv.zip", "w") as z:
        z.writestr("log.csv", text)
    log.to_parquet(tmp_path / "parquet.bin")
    table = heading.save(tmp_path / "g.json")
    for name in ("gz.csv", "logs/log.csv.bz2", "logs/log.csv.xz", "logs/log.csv.zip", "parquet.bin"):
        code, _, err = cli("run", table, tmp_path / name, "-o", tmp_path / "e.csv.gz")
        assert code == 0, (name, err)
        with gzip.open(tmp_path / "e.csv.gz", "rt") as fh:
            assert np.allclose(pd.read_csv(fh)["heading"], expected, rtol=1e-12, atol=1e-15), name
    assert [p.name for p in _log_paths([str(tmp_path / "logs")])[0]] == ["log.csv.bz2", "log.csv.xz", "log.csv.zip"]
    assert [_log_stem(p) for p in ("a/flight.csv.gz", "flight.parquet", "f.csv.ZIP")] == ["flight", "flight", "f"]


@pytest.mark.skipif(not Path("/dev/stdin").exists(), reason="needs /dev/stdin")
@pytest.mark.parametrize("name", ["/dev/stdin", "-"])
def test_a_log_from_a_pipe_runs_as_the_file(heading, tmp_path, cli, name):
    """``zcat log.csv.gz | cfdesign run g.json /dev/stdin`` (or ``<(zcat log.gz)``): a pipe gives
    its bytes once, and a log's header is read before its rows - the first row was taken as the
    header ('duplicate column(s) 0.5').  A pipe is copied to a temporary file first.  ``-`` is
    standard input too ('cannot read -: no such file')."""
    import gzip
    import os

    log, _ = heading_log(0, 0, n=500)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    data = gzip.compress(log.to_csv(index=False).encode())
    assert len(data) < 60_000  # all of it in the pipe's buffer: written before the run reads it
    read, write = os.pipe()
    os.write(write, data)
    os.close(write)
    stdin = os.dup(0)
    os.dup2(read, 0)
    try:
        code, _, err = cli("run", heading.save(tmp_path / "g.json"), name, "-o", tmp_path / "e.csv")
    finally:
        os.dup2(stdin, 0)
        os.close(stdin)
        os.close(read)
    assert code == 0, err
    assert np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-12)


def _zip_of_two(path):
    import zipfile

    with zipfile.ZipFile(path, "w") as z:
        z.writestr("a.csv", "time,gyro\n")
        z.writestr("b.csv", "time,gyro\n")


UNREADABLE = {  # each was a traceback (exit 3), or a message naming a byte of UTF-8
    "utf16.csv": (lambda p: p.write_bytes("time,gyro,compass,odometry\n0,1,2,3\n".encode("utf-16")),
                  "UTF-16 text; .* save the log as UTF-8"),
    "binary.dat": (lambda p: p.write_bytes(b"\x00\x01\x02" * 100), "not a text file; cfdesign reads CSV"),
    "two.zip": (_zip_of_two, "a zip archive of 2 files .*reads a zip that holds one CSV"),
    "damaged.xlsx": (lambda p: p.write_bytes(b"PK\x03\x04 no archive"), r"\(a damaged zip archive\)"),
    "cut.csv.gz": (lambda p: p.write_bytes(pytest.importorskip("gzip").compress(
        ("time,gyro,compass,odometry\n" + "".join(f"{0.2 * k},1,2,3\n" for k in range(30000))).encode())[:30000]),
        "not a readable log: Compressed file ended"),
}


@pytest.mark.parametrize("name", sorted(UNREADABLE))
def test_a_file_that_is_not_a_csv_log_is_named_on_one_line(name, heading, tmp_path, cli):
    make, message = UNREADABLE[name]
    make(tmp_path / name)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / name, "-o", tmp_path / "e.csv")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert pytest.importorskip("re").search(message, err), err


@pytest.mark.parametrize("output", ["-", "e.zip"])
def test_estimates_to_stdout_or_a_zip_are_refused(output, heading, tmp_path, cli, monkeypatch):
    """``-o -`` wrote a file named '-', ``-o e.zip`` a plain CSV named .zip."""
    monkeypatch.chdir(tmp_path)
    log, _ = heading_log(0, 0, n=300)
    log.to_csv("log.csv", index=False)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), "log.csv", "-o", output)
    assert code == 2 and len(err.strip().splitlines()) == 1 and output in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.json", "log.csv"]


def test_many_logs_on_dask_with_a_summary(heading, tmp_path, cli, capfd, caplog, monkeypatch):
    table = heading.save(tmp_path / "g.json")
    folder = tmp_path / "logs"
    folder.mkdir()
    for i in range(3):
        heading_log(i, 10 * i, n=1500, seed=i)[0].to_csv(folder / f"robot{i}.csv", index=False)
    (folder / "broken.csv").write_text("time,gyro\n0,1\n")
    import contextlib
    import logging
    import socket

    from distributed import LocalCluster

    close = LocalCluster.close

    def slow_close(self, *a, **kw):  # a worker slow to stop is killed after 4 s: Dask warned on stderr
        logging.getLogger("distributed.nanny").warning("Worker process still alive after 4.0 seconds, killing")
        return close(self, *a, **kw)

    monkeypatch.setattr(LocalCluster, "close", slow_close)
    environ = dict(os.environ)
    with socket.socket() as busy:  # Dask's default port taken (another cluster): it warned on stderr
        with contextlib.suppress(OSError):  # taken already
            busy.bind(("", 8787))
            busy.listen()
        code, _, err = cli("run", table, folder, "-o", tmp_path / "out", "--workers", "2", "--reference", "truth")
    assert code == 2 and "broken.csv: " in err and "missing column(s) compass, odometry" in err
    assert dict(os.environ) == environ  # the workers' settings (one BLAS thread, ...) went to them only
    # one line naming the log once; no worker's "Compute Failed" and traceback, no warning on the terminal
    assert len(err.strip().splitlines()) == 1 and err.count("broken.csv") == 1, err
    assert "Compute Failed" not in capfd.readouterr().err
    assert not [r for r in caplog.records if "still alive" in r.getMessage()]  # Dask's handler writes them to stderr
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert list(summary["log"].map(lambda p: p.split("/")[-1])) == ["broken.csv", "robot0.csv", "robot1.csv",
                                                                    "robot2.csv"]
    assert summary["samples"].tolist() == [0, 1500, 1500, 1500] and summary["rms_heading"].notna().sum() == 3
    columns = list(summary.columns)  # the settled RMS beside the RMS over every row: none, 15 s in a 45.5 s start-up
    assert columns[columns.index("rms_heading") + 1] == "rms_settled_heading"
    assert summary["rms_settled_heading"].isna().all() and summary["startup_s"].iloc[1:].tolist() == [45.46] * 3
    # beside them the prediction each log's figure should come to (over every row here: no settled rows)
    assert columns[columns.index("rms_settled_heading") + 1] == "predicted_std_heading"
    assert summary["predicted_std_heading"].iloc[1:].gt(0).all() and summary["predicted_std_heading"].isna().iloc[0]
    # each log's notes, which one log's run prints (they went nowhere): robot1's compass 10 rows late
    assert "compass 10 ticks, odometry 1 ticks after the table's schedule" in summary["notes"].iloc[2]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["robot0.csv", "robot1.csv", "robot2.csv",
                                                                    "summary.csv"]


def test_a_folder_output_or_a_glob_is_a_fleet_however_many_logs_match(heading, tmp_path, cli, monkeypatch):
    """``-o new/`` (a folder that does not exist yet) with one log, and a glob or a folder that
    matches one log, run as a fleet into a folder (not a file named like the folder)."""
    import cfdesign.logs

    runs = []  # the Dask part is tested above
    monkeypatch.setattr(cfdesign.logs, "run_logs", lambda table, paths, outdir, **kw: runs.append(
        ([p.name for p in paths], str(outdir))) or [{"log": str(paths[0]), "samples": 1}])
    table = heading.save(tmp_path / "g.json")
    (tmp_path / "logs").mkdir()
    heading_log(0, 0, n=300)[0].to_csv(tmp_path / "logs" / "robot.csv", index=False)
    for data, out in ((tmp_path / "logs" / "robot.csv", f"{tmp_path / 'new'}/"),
                      (f"{tmp_path}/logs/rob*.csv", tmp_path / "new2"), (tmp_path / "logs", tmp_path / "new3")):
        code, _, err = cli("run", table, data, "-o", out)
        assert code == 0, err
        assert runs.pop() == (["robot.csv"], str(out)) and not Path(out).is_file()


def test_plot_of_a_run(heading, tmp_path, cli):
    log, _ = heading_log(3, 37, n=3000)
    log.to_csv(tmp_path / "log.csv", index=False)
    table = heading.save(tmp_path / "g.json")
    code, _, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv", "--reference", "truth",
                       "--plot", tmp_path / "run.png")
    assert code == 0, err
    assert (tmp_path / "run.png").read_bytes()[:4] == b"\x89PNG"


def test_no_time_column_means_one_row_per_tick(heading):
    log, _ = heading_log(0, 0, n=1000)
    with_time = run_log(heading, log, start="zero").estimates["heading"].to_numpy()
    without = run_log(heading, log.drop(columns=["time"]), start="zero").estimates["heading"].to_numpy()
    assert np.allclose(with_time, without, atol=1e-12)
    ref = Runtime(heading).run(log)
    assert np.allclose(ref, without, atol=1e-9)


def test_python_result_fields(heading):
    log, _ = heading_log(0, 0, n=5000)
    r = run_log(heading, log, reference="truth", std=True)
    assert r.samples == 5000 and set(r.rms) == {"heading"} and r.without_gain == 0
    assert {"heading_std", "gyro_correction_std"} <= set(r.estimates.columns)


# ---------------------------------------------------------------------- blocks, ticks and columns
def _event_log(n, lags=(1e-4, 2e-4)):
    """The heading log as an event log: the IMU rows, and the odometry and compass in rows of their
    own just after (the same tick; ``lags=(0, 0)``: stamped with the IMU row's time)."""
    log, psi = heading_log(0, 0, n=n, jitter=0.0)
    events = []
    for lag, name in zip(lags, ("odometry", "compass"), strict=True):
        ev = log[log[name].notna()][["time", name]].copy()
        ev["time"] += lag
        events.append(ev)
    imu = log.drop(columns=["odometry", "compass"])
    return pd.concat([imu, *events]).sort_values("time", kind="stable").reset_index(drop=True), psi


def test_a_block_boundary_between_rows_of_one_tick_loses_no_reading(heading):
    """The block ends right after the IMU row of a tick whose odometry and compass rows start the
    next block: they are still that tick's readings (not 'second readings' dropped)."""
    log, _ = _event_log(300)
    one = run_log(heading, log)
    row = int(np.flatnonzero(log["compass"].notna().to_numpy())[1])  # the compass row of tick 100
    for rows in (row - 1, row, 1):  # boundary before the odometry row, before the compass row; every row
        split = run_log(heading, log, block_rows=rows)
        assert split.unused == {} and np.allclose(split.estimates["heading"], one.estimates["heading"], atol=1e-9)


def test_rows_of_different_sensors_may_share_a_time_a_sensor_read_twice_may_not(heading):
    """An event log whose odometry and compass rows carry the IMU row's own time stamp (one loop
    stamps them all) runs as the log with one row per tick, whatever the blocks; a sensor read twice
    at one time is a duplicate, refused naming its line, also across a block boundary."""
    log, _ = _event_log(300, lags=(0.0, 0.0))
    merged = run_log(heading, heading_log(0, 0, n=300, jitter=0.0)[0]).estimates["heading"].to_numpy()
    imu = log["gyro"].notna().to_numpy()
    row = int(np.flatnonzero(log["compass"].notna().to_numpy())[1])  # the compass row of tick 100
    for rows in (None, row - 1, row):  # boundaries before the odometry row and before the compass row
        r = run_log(heading, log, block_rows=rows)
        assert r.unused == {} and np.max(np.abs(r.estimates["heading"].to_numpy()[imu] - merged)) < 1e-9
    dup = pd.concat([log.iloc[:row + 1], log.iloc[row:]], ignore_index=True)  # the compass row twice
    for rows in (None, row + 1):
        with pytest.raises(DataError, match=rf"line {row + 3}: time 1\.0 repeats 1\.0 .*read different sensors"):
            run_log(heading, dup, block_rows=rows)


def test_a_second_reading_on_a_tick_is_the_one_not_used(heading, tmp_path, cli):
    """Two compass readings on one tick: the first is used and the second counted, in one block
    and with a block boundary between them."""
    log, _ = heading_log(0, 0, n=600, jitter=0.0)
    clean = run_log(heading, log).estimates["heading"].to_numpy()
    extra = pd.DataFrame({"time": [2.0004], "compass": [0.0]})  # a bogus second reading at tick 200
    twice = pd.concat([log, extra]).sort_values("time", kind="stable").reset_index(drop=True)
    imu = twice["gyro"].notna().to_numpy()
    row = int(np.flatnonzero(twice["time"].to_numpy() == 2.0004)[0])
    for rows in (None, row):
        r = run_log(heading, twice, block_rows=rows)
        assert r.unused == {"same_tick": {"compass": 1}}
        assert np.max(np.abs(r.estimates["heading"].to_numpy()[imu] - clean)) < 1e-9
    twice.to_csv(tmp_path / "twice.csv", index=False)  # cfdesign run says it in words ('same_tick' alone said little)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "twice.csv", "-o", tmp_path / "e.csv")
    assert code == 0 and ("1 readings were not used (a second reading of a sensor on one base tick, the first used "
                          "(same_tick): compass 1)") in err, err


def test_readings_logged_before_the_first_input_row_are_counted_not_used_late(heading):
    """A log that starts with compass and odometry rows 0.3-0.9 s before the gyro's first row: those
    readings were all put on tick 0, the oldest used (0.9 s late, far beyond the S/2 placement
    latency) and the fresh one there counted as a second reading. Now a reading more than half a
    tick before the first input row is counted (``before_start``) and not used; the rest of the
    log runs as it does without those rows, also with a block boundary after the first input row."""
    log, _ = heading_log(0, 0, n=600, jitter=0.0)
    clean = run_log(heading, log)
    early = pd.DataFrame({"time": [-0.9, -0.3, -0.004], "compass": [2.5, np.nan, np.nan],
                          "odometry": [np.nan, 1.0, 1.9]})  # the last is within half a tick of tick 0
    with_early = pd.concat([early, log], ignore_index=True)
    imu = with_early["gyro"].notna().to_numpy()
    for rows in (None, 4, 5):
        r = run_log(heading, with_early, block_rows=rows)
        assert r.unused == {"before_start": {"compass": 1, "odometry": 1}, "same_tick": {"odometry": 1}}
        got = r.estimates["heading"].to_numpy()
        assert np.isfinite(got[:3]).all()
        assert np.max(np.abs(got[imu] - clean.estimates["heading"].to_numpy())) > 0  # odometry at -0.004 s is used
    no_late = with_early.drop(index=[0, 1])
    assert np.allclose(run_log(heading, with_early).estimates["heading"].to_numpy()[2:],
                       run_log(heading, no_late).estimates["heading"].to_numpy(), atol=1e-12)


def test_text_columns_pass_through_csv_and_parquet_in_blocks(heading, tmp_path, monkeypatch):
    """Columns that are not sensors are passed through whatever they hold: text (empty in the
    first block), integers with a gap in a later block; also when the file is read in chunks."""
    import cfdesign.logs.run

    log, _ = heading_log(0, 0, n=900)
    note = np.full(900, None, dtype=object)
    note[[700, 850]] = ["bump", "stop, then go"]
    log["note"] = note
    log["count"] = np.arange(900.0)
    log.loc[800, "count"] = np.nan
    log.to_csv(tmp_path / "log.csv", index=False)
    ref = run_log(heading, log).estimates
    assert ref["note"].dropna().tolist() == ["bump", "stop, then go"]
    for chunked in (False, True):
        if chunked:
            monkeypatch.setattr(cfdesign.logs.run, "ONE_PASS_BYTES", 0)
        for source in (log, tmp_path / "log.csv"):
            for suffix in (".csv", ".parquet"):
                out = tmp_path / f"est{suffix}"
                run_log(heading, source, output=out, block_rows=300)
                got = pd.read_parquet(out) if suffix == ".parquet" else pd.read_csv(out)
                assert got["note"].dropna().tolist() == ["bump", "stop, then go"]
                assert np.array_equal(got["count"].to_numpy(), log["count"].to_numpy(), equal_nan=True)
                assert np.allclose(got["heading"], ref["heading"], atol=1e-9)


def test_log_columns_that_look_like_estimate_columns(heading, tmp_path):
    """A log column named like a state would replace the estimate: refused on one line.  Columns
    that merely end in _std or _reference are passed through like the others; a reference may
    be a sensor's column, in Parquet as in CSV."""
    log, _ = heading_log(0, 0, n=600)
    with pytest.raises(DataError, match="column 'heading' has the name of a column of the estimates"):
        run_log(heading, log.rename(columns={"truth": "heading"}))
    log["gyro_std"], log["truth_reference"] = 0.01, 1.0
    r = run_log(heading, log, output=tmp_path / "e.csv")
    assert {"gyro_std", "truth_reference"} <= set(pd.read_csv(tmp_path / "e.csv").columns) and r.rms == {}
    log.to_parquet(tmp_path / "log.parquet")
    r = run_log(heading, tmp_path / "log.parquet", reference="compass")
    assert set(r.rms) == {"heading"} and r.rms["heading"] == pytest.approx(run_log(heading, log, reference="compass")
                                                                         .rms["heading"])


def test_std_is_that_of_the_gains_each_stretch_ran(heading):
    """The odometry slips by 3 ticks half-way: the first half runs the table's own gains, the
    second recomputed ones; each row's predicted std is the one of the gains that ran it."""
    log, psi = heading_log(0, 0, n=4000, jitter=0.0)
    odo = np.full(4000, np.nan)
    odo[0:2000:10], odo[2003::10] = psi[0:2000:10], psi[2003::10]
    log["odometry"] = wrap(odo)
    r = run_log(heading, log, std=True)
    expected = np.sqrt([heading.P_filtered[k % 100][0, 0] for k in range(2000)])
    assert np.allclose(r.estimates["heading_std"].to_numpy()[:2000], expected, rtol=1e-12)


def test_fixed_gains_follow_the_slowest_sensor_and_count_the_rest(heading):
    """A multirate table whose gains are not Kalman gains cannot be recomputed: as docs/logs.md
    says, it runs locked to the slowest sensor and the readings off its schedule are counted
    (not an error)."""
    import dataclasses

    hand = dataclasses.replace(heading, provenance={**heading.provenance, "solver": {"method": "hand-tuned"}})
    log, _ = heading_log(3, 37, n=1000)
    r = run_log(hand, log)
    assert r.unused == {"unscheduled": {"odometry": 100}}


def test_a_rotation_that_is_no_sensor_s_own_offset_is_found():
    """A 2 Hz compass 10 ticks late and a 5 Hz odometry on time (period 100): one rotation of
    the schedule, by 60 ticks, fits both; it was missed (the gains recomputed, or with fixed
    gains the odometry readings left without a gain)."""
    from cfdesign.timing import lock_schedule

    table = cfdesign.design(parse_spec({"name": "h", "structure": "dckf3", "wrap_angle": True, "sensors": {
        "gyro": {"rate_hz": 100.0, "noise": {"std": 0.01}, "bias": {"model": "random_walk", "density": 1e-4}},
        "odometry": {"rate_hz": 5.0, "noise": {"std": 0.005}}, "compass": {"rate_hz": 2.0, "noise": {"std": 0.05}}}}))
    arrivals = {"compass": np.arange(10, 1000, 50), "odometry": np.arange(0, 1000, 20)}
    for recompute in (True, False):
        lock = lock_schedule(table, arrivals, 1000, recompute=recompute)
        assert [(s.rotation, s.offsets) for s in lock.segments] == [(60, None)]
        for name, ticks in arrivals.items():
            assert set((ticks - 60) % 100) <= set(table.schedule.phases(name))


def test_two_logs_of_one_name_are_named(heading, tmp_path):
    """Logs whose estimates would overwrite each other (one stem, in two folders or as CSV and
    Parquet) are refused naming both, before any runs."""
    pytest.importorskip("dask.distributed")
    with pytest.raises(DataError, match=r"^a/robot\.csv and b/robot\.parquet have the same name; their estimates "
                                        r"would both be .*robot\.csv$"):
        run_logs(heading, ["a/robot.csv", "b/robot.parquet"], tmp_path)


@pytest.mark.parametrize("workers", ["-1", "0"])
def test_workers_must_be_positive(heading, tmp_path, cli, workers):
    """--workers -1 started a Dask cluster that never came up: the command hung."""
    table = heading.save(tmp_path / "g.json")
    for i in range(2):
        heading_log(0, 0, n=200, seed=i)[0].to_csv(tmp_path / f"r{i}.csv", index=False)
    code, _, err = cli("run", table, tmp_path / "r0.csv", tmp_path / "r1.csv", "-o", tmp_path / "out",
                       "--workers", workers)
    assert code == 2 and "--workers must be a positive number" in err and not (tmp_path / "out").exists()
    with pytest.raises(CfdesignError, match="workers must be a positive number"):
        run_logs(heading, [tmp_path / "r0.csv"], tmp_path / "out", workers=int(workers))


def test_an_unreachable_scheduler_is_a_user_error(heading, tmp_path, cli):
    """Not an 'internal error, please report it' (exit 3)."""
    import dask
    import dask.distributed  # its defaults in dask.config before config.set copies it

    table = heading.save(tmp_path / "g.json")
    heading_log(0, 0, n=200)[0].to_csv(tmp_path / "r0.csv", index=False)
    for address in ("tcp://127.0.0.1:1", "nonsense://x"):
        with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
            code, _, err = cli("run", table, tmp_path / "r0.csv", "-o", tmp_path / "out", "--scheduler", address)
        assert code == 2 and f"cannot connect to the Dask scheduler {address}" in err, err
        assert not (tmp_path / "out").exists()  # (an empty folder was left behind)


def test_an_unguarded_script_is_told_to_guard_its_call(heading, tmp_path, monkeypatch):
    """A script calling run_logs at its top level: every spawned worker imported it again and started
    a cluster of its own; Dask printed pages of tracebacks and "internal error (Nanny failed to start)".
    A worker still importing the script exits with one line; the parent's start failure names the fix."""
    import multiprocessing.process

    import dask.distributed

    heading_log(0, 0, n=200)[0].to_csv(tmp_path / "r0.csv", index=False)
    me = multiprocessing.process.current_process()
    monkeypatch.setattr(me, "_inheriting", True, raising=False)  # as spawn sets it while it imports __main__
    with pytest.raises(SystemExit, match=r'^cfdesign: a script that calls run_logs must do so under '
                                         r'if __name__ == "__main__":'):
        run_logs(heading, [tmp_path / "r0.csv"], tmp_path / "out", workers=1)
    monkeypatch.delattr(me, "_inheriting")

    def dead(*args, **kwargs):  # what Dask raises once a worker process died while starting
        raise RuntimeError("Nanny failed to start.")

    monkeypatch.setattr(dask.distributed, "LocalCluster", dead)
    with pytest.raises(CfdesignError, match=r"^the local Dask workers did not start \(Nanny failed to start\.\): "
                                            r'a script that calls run_logs must do so under if __name__'):
        run_logs(heading, [tmp_path / "r0.csv"], tmp_path / "out", workers=1)
    assert not (tmp_path / "out").exists()


def test_workers_and_scheduler_exclude_each_other(heading, tmp_path, cli):
    """Both given, the scheduler was used and --workers ignored in silence."""
    table = heading.save(tmp_path / "g.json")
    heading_log(0, 0, n=200)[0].to_csv(tmp_path / "r0.csv", index=False)
    code, _, err = cli("run", table, tmp_path / "r0.csv", "-o", tmp_path / "out", "--workers", "2",
                       "--scheduler", "nonsense://x")
    assert code == 2 and err.count("\n") == 1 and "--scheduler: not allowed with argument --workers" in err, err
    with pytest.raises(CfdesignError, match="workers and scheduler exclude each other"):
        run_logs(heading, [tmp_path / "r0.csv"], tmp_path / "out", workers=2, scheduler="nonsense://x")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("how", [["--workers", "1"], ["--scheduler", "nonsense://x"], ["GLOB"]])
@pytest.mark.parametrize("name", ["e.csv", "e.parquet"])
def test_a_fleet_refuses_an_output_named_as_an_estimates_file(heading, tmp_path, cli, how, name):
    """One log with --workers and ``-o e.csv`` wrote a folder named ``e.csv``."""
    table = heading.save(tmp_path / "g.json")
    heading_log(0, 0, n=200)[0].to_csv(tmp_path / "r0.csv", index=False)
    data, extra = (f"{tmp_path}/r*.csv", []) if how == ["GLOB"] else (tmp_path / "r0.csv", how)
    code, _, err = cli("run", table, data, "-o", tmp_path / name, *extra)
    assert code == 2 and err.count("\n") == 1 and f"{name} names an estimates file" in err and "name a folder" in err
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("bad", [np.inf, -np.inf, 5e12])
def test_a_rejected_first_reading_is_not_the_start(heading, bad):
    """The state starts from the first reading the runtime would use: an inf there made every
    estimate of the log NaN."""
    log, _ = heading_log(0, 0, n=600)
    clean = run_log(heading, log.assign(compass=np.where(np.arange(600) == 0, np.nan, log["compass"])))
    log.loc[0, "compass"] = bad
    r = run_log(heading, log)
    assert r.unused == {"rejected": {"compass": 1}}
    assert np.array_equal(r.estimates["heading"].to_numpy(), clean.estimates["heading"].to_numpy())


def test_the_estimates_never_replace_the_log(heading, tmp_path, cli):
    """-o naming the log itself (or, for several logs, their own folder in their own format)
    replaced the logs by the estimates, losing the sensor columns."""
    table = heading.save(tmp_path / "g.json")
    folder = tmp_path / "logs"
    folder.mkdir()
    for i in range(2):
        heading_log(0, 0, n=200, seed=i)[0].to_csv(folder / f"r{i}.csv", index=False)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    code, _, err = cli("run", table, folder / "r0.csv", "-o", folder / "r0.csv")
    assert code == 2 and "is the log itself" in err
    code, _, err = cli("run", table, folder, "-o", folder, "--workers", "1")
    assert code == 2 and "would replace the log itself" in err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_tick_zero_is_the_first_input_row_and_outputs_are_checked(heading, tmp_path, cli):
    """A compass row logged 4 ms before the first IMU row does not shift the IMU rows onto each
    other's ticks; a plot named .jpg and an output that is the gain table are refused."""
    log, psi = heading_log(0, 0, n=6000, jitter=0.0)
    early = pd.DataFrame({"time": [-0.004], "compass": [wrap(psi[0])]})
    shifted = pd.concat([early, log.assign(compass=np.nan)], ignore_index=True)
    r = run_log(heading, shifted)
    assert "same_tick" not in r.unused and r.samples == 6001
    table = heading.save(tmp_path / "g.json")
    log.to_csv(tmp_path / "log.csv", index=False)
    code, _, err = cli("run", table, tmp_path / "log.csv", "-o", tmp_path / "e.csv", "--plot", tmp_path / "p.jpg")
    assert code == 2 and "unknown image format 'jpg'" in err and not (tmp_path / "e.csv").exists()
    code, _, err = cli("run", table, tmp_path / "log.csv", "-o", table)
    assert code == 2 and "is the gain table" in err and cfdesign.load_gains(table).name == heading.name
    with pytest.raises(cfdesign.CfdesignError, match="x0 must be 2 finite numbers"):
        Runtime(heading, x0=[1.0, 2.0, 3.0])


def test_ticks_without_an_input_reading_are_reported(heading):
    """Dropped IMU rows (the time jumps by 2-5 ticks) and a 3 s gap in the IMU stream hold the gyro's
    last reading: said in a note with the count and the longest gap's line, whatever the blocks."""
    log, _ = heading_log(0, 0, n=2000, jitter=0.0)
    drop = [101, 102, 500, 501, 502, 503, *range(1200, 1500)]  # the compass row 1200 and 1300 keep their reading
    log.loc[drop, "gyro"] = np.nan
    log = log.drop(index=[d for d in drop if np.isnan(log.loc[d, "compass"])]).reset_index(drop=True)
    expected = "gyro (an input) has no reading at 306 of 2000 ticks, the longest 300 ticks (3 s) after line 1196"
    for rows in (None, 700, 1195):
        notes = run_log(heading, log, block_rows=rows).notes
        assert any(n.startswith(expected) and n.endswith("the predicted std leaves out the error of the held "
                                                         "value, which grows with the gap") for n in notes), notes


def test_a_float32_time_column_too_coarse_for_the_tick_is_refused(heading):
    """Unix time (1.7e9 s) in float32 steps by 128 s: refused naming the column and its resolution,
    not as 'time repeats'; float32 seconds from the start of a 30 s log run as float64 ones."""
    log, _ = heading_log(0, 0, n=3000, jitter=0.0)
    exact = run_log(heading, log).estimates["heading"].to_numpy()
    short = log.assign(time=log["time"].astype(np.float32))
    assert np.max(np.abs(run_log(heading, short).estimates["heading"].to_numpy() - exact)) < 1e-12
    with pytest.raises(DataError, match=r"column 'time' is float32, whose steps at 1\.7e\+09 s are 128 s, too coarse"):
        run_log(heading, log.assign(time=(log["time"] + 1.7e9).astype(np.float32)))


def test_a_gap_of_many_ticks_runs_in_bounded_pieces(heading, monkeypatch):
    """A log paused for a day (8.6 million ticks without a row between two rows) ran those ticks as
    one array (2.6 GB for 6000 rows): they run in pieces of at most BLOCK_ROWS ticks, with the
    estimates of one piece."""
    import cfdesign.logs.run

    log, _ = heading_log(3, 37, n=2000, jitter=0.0)
    log.loc[1000:, "time"] += 50.0  # 5000 ticks without a row
    whole = run_log(heading, log, block_rows=700).estimates["heading"].to_numpy()
    spans = []
    dense = cfdesign.logs.run._Runner._dense
    monkeypatch.setattr(cfdesign.logs.run._Runner, "_dense", lambda self, ticks, readings, first, last: spans.append(
        last - first + 1) or dense(self, ticks, readings, first, last))
    monkeypatch.setattr(cfdesign.logs.run, "BLOCK_ROWS", 1000)
    pieces = run_log(heading, log, block_rows=700).estimates["heading"].to_numpy()
    assert max(spans) <= 1000 and sum(spans) == 7000
    assert np.max(np.abs(wrap(pieces - whole))) < 1e-9


def test_a_sensor_without_readings_is_reported(heading):
    log, _ = heading_log(0, 0, n=2000)
    log["compass"] = np.nan
    assert run_log(heading, log).notes == ["compass has no reading in the log: the log runs the Kalman filter of "
                                           "the table's model over the readings that arrive"]
    log["gyro"] = np.nan  # an input that never reads: the run integrates nothing, and says so
    assert run_log(heading, log).notes[0] == "gyro (an input) has no reading in the log: the estimates run on an " \
                                             "input of zero"


@pytest.mark.parametrize("readings", [11, 12])
def test_a_fractional_rate_sensor_is_locked_whatever_the_count_of_its_readings(readings):
    """An 8 Hz angle on a 20 Hz base arrives 3, 2, 3, 2 ... ticks apart: the median single
    spacing was 3 (6.67 Hz) for an even count, the sensor was called off-rate and its late
    readings were left without a gain."""
    from cfdesign.designer import design
    from cfdesign.timing import lock_schedule

    table = design(parse_spec({"structure": "cf2", "order": 1, "discrete": True, "sensors": {
        "rate": {"rate_hz": 20.0, "noise": {"std": 0.01}},
        "angle": {"rate_hz": 8.0, "noise": {"std": 0.05}}}}))
    phases = [k for k in range(table.period) if table.schedule.rows(k)]
    ticks = (np.array(phases)[None, :] + table.period * np.arange(readings)[:, None]).ravel()[:readings] + 1
    lock = lock_schedule(table, {"angle": ticks}, int(ticks[-1]) + 5)
    assert lock.offsets == {"angle": 1} and not any("arrives at" in n for n in lock.notes)


def _offset_runs_by_sets(ticks, phases, step):
    """The candidate-set intersection of cfdesign.timing._offset_runs written out plainly."""
    runs, current = [], None
    for t in ticks.tolist():
        cand = {int((t - p) % step) for p in phases}
        if current is not None and current & cand:
            current &= cand
            continue
        current = cand
        runs.append([t, current])
    return [(t, min(c)) for t, c in runs]


def test_offset_runs_of_a_dense_fractional_pattern_are_fast_and_unchanged():
    """A 333.3 Hz sensor beside a 1 kHz base reads 3333 phases of a 10000-tick period: every
    arrival built the set of all 3333 candidate offsets (cfdesign run: 0.18 ms a row, 17 s for
    33330 arrivals); only the run's surviving candidates are tested now."""
    from cfdesign.timing import _offset_runs

    period = 10_000
    phases = np.unique(np.round(np.arange(3333) * period / 3333).astype(np.int64) % period)
    ticks = (phases[None, :] + 7 + period * np.arange(10)[:, None]).ravel()
    assert _offset_runs(ticks, phases, period, period) == [(7, 7)]  # 17 s before, now 0.01 s
    rng = np.random.default_rng(0)
    for _ in range(200):  # small general patterns, arrivals consistent or not: the same runs
        period = int(rng.integers(5, 120))
        phases = np.sort(rng.choice(period, int(rng.integers(1, period)), replace=False))
        members = set(phases.tolist())
        step = next(g for g in range(1, period + 1) if all((p + g) % period in members for p in members))
        if len(phases) * step == period:
            continue
        ticks = np.sort(rng.choice(5 * period, int(rng.integers(1, 4 * period)), replace=False))
        assert _offset_runs(ticks, phases, step, period) == _offset_runs_by_sets(ticks, phases, step)


def test_missed_readings_and_a_slower_sensor_keep_every_reading(heading):
    """A fifth of the odometry and compass readings missing (a median span of ten odometry
    readings then covers about 12 of its periods: 8.3 Hz measured for 10 Hz), or an odometry
    logged at 5 Hz: fewer readings than the table reads are no readings without a gain. All
    odometry readings were refused as off-rate and the heading RMS went from 1.3e-3 to 0.26 rad."""
    log, psi = heading_log(3, 37, n=12_000)
    full = rms_after(run_log(heading, log).estimates["heading"].to_numpy(), psi)
    rng = np.random.default_rng(5)
    for c in ("odometry", "compass"):
        idx = np.flatnonzero(log[c].notna())
        log.loc[rng.choice(idx, len(idx) // 5, replace=False), c] = np.nan
    result = run_log(heading, log)
    assert result.unused == {}
    assert rms_after(result.estimates["heading"].to_numpy(), psi) < 1.5 * full
    assert any("odometry has 8.3" in n and "missed readings or a slower sensor" in n for n in result.notes)
    slow, psi = heading_log(3, 37, n=12_000)
    slow.loc[slow.index % 20 != 3, "odometry"] = np.nan  # 5 Hz
    result = run_log(heading, slow)
    assert result.unused == {} and any("odometry has 5 readings a second" in n for n in result.notes)
    assert rms_after(result.estimates["heading"].to_numpy(), psi) < 3 * full


def test_missed_readings_run_at_batch_speed_with_the_recursion_s_states(heading):
    """A log with a quarter of its slow readings missing runs the step-by-step path; with the
    output states (as run_log asks) each tick took a numpy recursion step (90 us: 10 million
    rows in 15 min). The compiled step now advances, the states are formed afterwards: the
    same numbers as the recursion, at about 3 us a tick (the recursion is not stepped)."""
    log, _ = heading_log(0, 0, n=6000, jitter=0.0)
    rng = np.random.default_rng(5)
    for c in ("odometry", "compass"):
        idx = np.flatnonzero(log[c].notna())
        log.loc[rng.choice(idx, len(idx) // 4, replace=False), c] = np.nan
    readings = {k: log[k].to_numpy() for k in ("gyro", "odometry", "compass")}
    for output in ("posterior", "prior"):
        rt, ref = Runtime(heading, output=output), Runtime(heading, output=output)
        rt._advance = None  # stepping the numpy recursion (90 us a tick) would fail here
        est, xs = rt.run(readings, states=True)
        active = heading.schedule.mask()[np.arange(6000) % heading.period]
        y = np.column_stack([readings[m] for m in rt.measurements])
        y = np.where(active & np.isfinite(y), y, np.nan)
        expected = np.array([ref._advance(np.array([g]), row) for g, row in zip(readings["gyro"], y, strict=True)])
        assert np.max(np.abs(wrap(xs - expected))) < 1e-12 and np.array_equal(est, xs[:, 0])
        assert np.allclose(rt.x, ref.x, rtol=0, atol=1e-12) and rt.phase == ref.phase


def test_a_time_column_by_another_case_or_in_the_index_is_the_time(heading):
    """A tenth of the gyro rows missing: a log whose time column is 'Time', or a DataFrame with
    its time as the index (a DatetimeIndex, or an index named time), ran one row a tick without
    a word (heading RMS 0.23 rad for 1.8e-3, every slow reading called off-rate); a log with no
    time column at all is said to run one row a tick, naming a column that looks like a time."""
    log, psi = heading_log(3, 37, n=12_000)
    keep = np.random.default_rng(1).random(12_000) > 0.1
    keep |= log["compass"].notna().to_numpy() | log["odometry"].notna().to_numpy()
    log, psi = log[keep].reset_index(drop=True), psi[keep]
    timed = run_log(heading, log, reference="truth")
    dates = log.drop(columns="time").set_index(pd.to_datetime(log["time"], unit="s"))
    for variant in (log.rename(columns={"time": "Time"}), log.set_index("time"), dates):
        result = run_log(heading, variant, reference="truth")
        assert result.unused == {} and result.rms["heading"] == pytest.approx(timed.rms["heading"], rel=1e-9)
        assert result.rms["heading"] < 3 * heading.predicted_std
        assert result.estimates.columns[0] in ("Time", "time")
    result = run_log(heading, log.rename(columns={"time": "stamp_s"}))
    assert any("no time column" in n and "'stamp_s'" in n and "--time" in n for n in result.notes)


def test_a_dataframe_index_named_with_a_unit_is_the_time(heading):
    """A column 'time_ms', 't [us]' or 'timestamp' is the time; a DataFrame indexed by one ran one
    row a tick (its note offered --time COLUMN, which cannot name an index): with a tenth of the
    gyro rows missing, 0.011 rad off the timed run. Now the index is the time, in its unit."""
    log, _ = heading_log(3, 37, n=3000)
    keep = np.random.default_rng(2).random(3000) > 0.1
    keep |= log["compass"].notna().to_numpy() | log["odometry"].notna().to_numpy()
    log = log[keep].reset_index(drop=True)
    timed = run_log(heading, log).estimates["heading"].to_numpy()
    for name, scale in (("time_ms", 1e3), ("t [us]", 1e6), ("Timestamp", 1.0)):
        frame = log.assign(time=log["time"] * scale).rename(columns={"time": name}).set_index(name)
        result = run_log(heading, frame)
        assert not any("no time column" in n for n in result.notes), name
        assert result.estimates.columns[0] == name
        assert np.allclose(result.estimates["heading"], timed, rtol=0, atol=1e-9), name


def test_a_csv_column_named_twice_is_refused(heading, tmp_path):
    """pandas reads a second 'compass' as 'compass.1': the log ran on the first without a word."""
    text = heading_log(3, 37, n=200)[0].to_csv(index=False).splitlines()
    (tmp_path / "d.csv").write_text("\n".join([text[0] + ",compass", *(r + ",0" for r in text[1:])]) + "\n")
    with pytest.raises(DataError, match=r"duplicate column.*compass"):
        run_log(heading, tmp_path / "d.csv")


def test_std_follows_missed_readings_as_a_simulation_does(heading):
    """A 5-s outage of odometry and compass every 30 s: the error grows on the gyro alone and
    returns; each row's --std follows it (the table's own gains over the readings present), the
    ensemble RMS error over 20 outages agreeing with the RMS std within sampling error (+-20 %
    over seeds 0-5) during the outage and after it.  The table's steady-state std, which every
    row carried before, is 2.2 times too small half-way through the outage."""
    period, outage, count = 3000, 500, 20
    x, readings = model_log(heading, period * (count + 1), seed=0)
    starts = period * np.arange(1, count + 1)
    for a in starts:
        for name in ("odometry", "compass"):
            readings[name][a:a + outage] = np.nan
    est = run_log(heading, pd.DataFrame(readings), std=True, start="zero").estimates
    err = wrap(est["heading"].to_numpy() - x[:, 0])
    std = est["heading_std"].to_numpy()
    for lo, hi in [(outage // 2, outage), (outage, outage + 250), (outage + 250, 3 * outage)]:
        e = np.sqrt(np.mean([err[a + lo:a + hi] ** 2 for a in starts]))
        s = np.sqrt(np.mean([std[a + lo:a + hi] ** 2 for a in starts]))
        assert 0.7 < e / s < 1.4, (lo, hi, e, s)
    during = np.sqrt(np.mean([std[a + outage // 2:a + outage] ** 2 for a in starts]))
    assert during > 2 * np.sqrt(heading.P_filtered[0][0, 0])
    before = range(starts[0] - 1000, starts[0])  # all readings present: the table's own
    assert np.allclose(std[before], np.sqrt([heading.P_filtered[k % 100][0, 0] for k in before]), rtol=1e-12)


def test_a_parquet_file_of_a_frame_indexed_by_time_runs_on_its_index(heading, tmp_path, cli):
    """``frame.set_index(dates).to_parquet()`` keeps the DatetimeIndex as the field
    ``__index_level_0__``: the run stopped with an internal error (KeyError).  It is the time
    column, as the index of a DataFrame is; an unnamed index of row numbers is left out."""
    log, _ = heading_log(3, 37, n=3000)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    dates = pd.Timestamp("2024-05-01T12:00:00") + pd.to_timedelta(log["time"] - log["time"].iloc[0], unit="s")
    log.drop(columns="time").set_index(pd.DatetimeIndex(dates)).to_parquet(tmp_path / "idx.parquet")
    log.set_index(log.index + 100).to_parquet(tmp_path / "rows.parquet")
    table = heading.save(tmp_path / "g.json")
    for name in ("idx", "rows"):
        code, _, err = cli("run", table, tmp_path / f"{name}.parquet", "-o", tmp_path / f"{name}_est.parquet")
        assert code == 0, err
        est = pd.read_parquet(tmp_path / f"{name}_est.parquet")
        assert np.allclose(est["heading"].to_numpy(), expected, atol=1e-12, rtol=0)
        assert "__index_level_0__" not in est.columns and est.columns[0] == "time"
    assert est["time"].equals(log["time"])


def test_a_fault_of_cfdesign_on_one_log_of_a_fleet_is_one_summary_line_exit_3(heading, tmp_path, cli, monkeypatch):
    """A log that met an internal error (the KeyError of a Parquet index) failed its Dask task:
    the worker printed the traceback and the summary said only "'__index_level_0__'", exit 2 as
    for a bad log.  The log's task returns a row naming an internal error; the others run; exit 3."""
    import cfdesign.logs
    import cfdesign.logs.fleet
    from cfdesign.logs import INTERNAL
    from cfdesign.logs.fleet import _run_one

    def broken(table, path, **kw):
        raise KeyError("__index_level_0__")

    monkeypatch.setattr(cfdesign.logs.fleet, "run_log", broken)
    row = _run_one(heading, "a.parquet", str(tmp_path / "a.csv"), {})
    assert row == {"log": "a.parquet", "samples": 0,
                   "error": f"{INTERNAL} (KeyError: '__index_level_0__'); please report it with the log"}
    monkeypatch.setattr(cfdesign.logs, "run_logs", lambda *a, **kw: [row, {"log": "b.csv", "samples": 10}])
    heading_log(0, 0, n=300)[0].to_csv(tmp_path / "b.csv", index=False)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "b.csv", "-o", f"{tmp_path}/out/")
    assert code == 3 and err.strip() == f"cfdesign: a.parquet: {row['error']}"


@pytest.mark.parametrize("blank", ["", "   ", "\t"])
def test_lines_named_after_blank_lines_are_the_file_s_own(heading, tmp_path, blank):
    """pandas skips blank lines (and lines of spaces): a bad cell, a time that goes back or the
    row before a gap of the gyro, after blank lines, were named a line early for each of them."""
    rows = heading_log(3, 37, n=1000)[0].to_csv(index=False, lineterminator="\n").splitlines()
    text = [*rows[:301], blank, blank, *rows[301:500], *rows[560:]]  # rows 500..559 (gyro and all) left out
    lines = {"cell": 303 + 200 + 1, "back": 303 + 200 + 1}  # the file line after the gap's
    (tmp_path / "gap.csv").write_text("\n".join(text) + "\n")
    note = next(n for n in run_log(heading, tmp_path / "gap.csv").notes if "gyro (an input)" in n)
    assert f"after line {303 + 199}:" in note, note  # the last row before the gap
    cell = text[lines["cell"] - 1].split(",")
    bad = {"cell": ",".join([cell[0], "abc", *cell[2:]]), "back": ",".join(["0.5", *cell[1:]])}
    for kind, row in bad.items():
        path = tmp_path / f"{kind}.csv.gz"
        import gzip

        with gzip.open(path, "wt") as fh:
            fh.write("\n".join([*text[:lines[kind] - 1], row, *text[lines[kind]:]]) + "\n")
        with pytest.raises(DataError, match=rf"line {lines[kind]}: (column 'gyro' is not a number|time 0.5 goes back)"):
            run_log(heading, path)


@pytest.mark.parametrize("cut, rows, noted", [("cells", 399, "cut short"), ("nul", 400, "NUL"),
                                              ("nul-digits", 399, "no line end"), ("digits", 400, None),
                                              ("no-line-end", 400, None)])
def test_a_log_cut_off_while_it_was_written_runs_without_its_cut_end(heading, tmp_path, cli, cut, rows, noted):
    """A power loss leaves a last line without its end (its last cell may have lost digits: a
    reading of 0.00 for 0.0041), and often NUL bytes where the file system had given the file its
    space.  The cut line was run as a reading with its cells cut; NUL bytes stopped the run with a
    message of thousands of '\\x00'.  The cut end is not read, and a note names it; a last line
    without a line end and with all its cells (a file written by hand) is read."""
    log = heading_log(3, 37, n=400)[0].drop(columns="lap")  # the truth last: digits to lose
    text = log.to_csv(index=False, lineterminator="\n")
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    body = text[:len(text) - len(last) - 1]  # up to the last line's start
    data = {"cells": body + last[:12], "digits": body + last[:-3], "nul": text + "\0" * 70_000,
            "nul-digits": body + last[:-3] + "\0" * 512, "no-line-end": text.rstrip("\n")}[cut]
    (tmp_path / "log.csv").write_bytes(data.encode())
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.csv", "-o", tmp_path / "e.csv")
    assert code == 0, err
    est = read_csv_exact(tmp_path / "e.csv")  # times compared to the last bit
    assert len(est) == rows and np.array_equal(est["time"], log["time"].iloc[:rows])
    expected = run_log(heading, log.iloc[:rows]).estimates["heading"].to_numpy()
    assert np.allclose(est["heading"], expected, rtol=0, atol=1e-12)
    notes = [line for line in err.splitlines() if "cut off while it was written" in line]
    assert len(notes) == (noted is not None) and "\\x00" not in err, err
    if noted:
        assert noted in notes[0] and "not read" in notes[0] and ("(401)" in notes[0]) == (rows == 399), notes


def _jittered(n, seed=3):
    log, psi = heading_log(3, 37, n=n, jitter=0.0)
    log["time"] += np.random.default_rng(seed).uniform(-0.3, 0.3, n) * 0.01  # +-0.3 tick
    return log, psi


@pytest.mark.parametrize("block_rows", [None, 2500])
def test_a_logger_paused_and_restarted_off_its_grid_puts_every_row_on_its_own_tick(heading, block_rows):
    """A 10 s pause of every row, the clock back half a tick off the old grid (+-0.3 tick of
    jitter): one gyro reading in six after it shared a tick with the next (3364 not used, the
    arrival pattern 'changing' 671 times); the grid's phase is fitted again after a pause."""
    log, _ = _jittered(12_000)
    log = log.drop(index=range(4000, 5000))
    same = run_log(heading, log, reference="truth")
    log.loc[log.index >= 5000, "time"] += 0.005
    moved = run_log(heading, log, reference="truth", block_rows=block_rows)
    assert same.unused == {} and moved.unused == {}, moved.unused
    assert not any("as they arrive" in n for n in moved.notes), moved.notes  # a shift of one tick at the pause
    assert moved.rms["heading"] <= 1.05 * same.rms["heading"]


def test_rows_jittered_by_nearly_half_a_tick_are_at_their_rate():
    """Uniform jitter of +-0.45 tick, every row present: the slope fitted on ticks that the median
    step gave was a few percent off (300 rows: 32 logs of 40 refused as 4.9 or 5.1 Hz for 5 Hz),
    although the grid the rows are placed on puts each on its own tick; a pause (the clock back
    half a tick off) refused the log the same way.  Its spacing is now that of the rows."""
    from cfdesign.timing import check_rate

    for seed in range(20):
        t = (np.arange(300) + np.random.default_rng(seed).uniform(-0.45, 0.45, 300)) * 0.2
        check_rate(t, 0.2, "log")
        check_rate(np.where(np.arange(300) < 150, t, t + 10.1), 0.2, "log")
        early = (np.arange(3000) + np.random.default_rng(seed).uniform(-0.3, 0.3, 3000)) * 0.2
        check_rate(np.where(np.arange(3000) < 5, early, early + 20.1), 0.2, "log")  # 5 rows, a pause: the
        # longest stretch between pauses is fitted (the first 5 rows' slope refused 22 such logs of 40)
        with pytest.raises(DataError, match="base rate is"):
            check_rate(t * 1.04, 0.2, "log")
        gauss = np.sort(np.arange(300) + np.random.default_rng(seed).normal(0, 0.2, 300)) * 0.2  # a row in a
        check_rate(gauss, 0.2, "log")  # hundred on its neighbour's tick (9 such logs of 40 had been refused)
    k = np.arange(300)
    check_rate(k[k % 7 != 6] * 0.2 + 1.7e9, 0.2, "log")  # every 7th row missing: 6 rows in 7 ticks, not 4.29 Hz


@pytest.mark.parametrize("rows_after", [1, 4])
def test_a_pause_at_the_end_of_a_block_is_rephased_on_the_rows_of_the_next(heading, rows_after):
    """A 10 s pause, the clock back half a tick off, +-0.4 tick of jitter, and a block that ends
    ``rows_after`` rows after the pause: the phase was fitted to those rows alone, and hundreds of
    gyro readings after it shared a tick (same_tick).  The rows of the next block count too, in
    both passes: the estimates are those of one block."""
    log, _ = heading_log(3, 37, n=6000, jitter=0.0)
    log["time"] += np.random.default_rng(2).uniform(-0.4, 0.4, 6000) * 0.01
    log = log.drop(index=range(3000, 4000))
    log.loc[log.index >= 4000, "time"] += 0.005
    whole = run_log(heading, log, reference="truth")
    blocks = run_log(heading, log, reference="truth", block_rows=3000 + rows_after)
    assert whole.unused == blocks.unused == {}, blocks.unused
    assert np.allclose(blocks.estimates["heading"], whole.estimates["heading"], rtol=0, atol=1e-12)


def test_rows_after_a_pause_at_the_end_of_a_block_move_onto_the_reading_of_the_next(heading):
    """After a pause the heading starts again from the first direct reading, and the rows from the
    pause's end to it move with it; with that reading in the next block (a block ending 4 rows
    after the pause, the odometry on its last row, whose tick waits for the next block) the 3 rows
    before it were written where the held gyro had taken them: 0.69 rad off, 8 times the RMS."""
    log, _ = heading_log(3, 37, n=6000, jitter=0.0)
    log = log.drop(index=range(3000, 4000))
    whole = run_log(heading, log, reference="truth")
    blocks = run_log(heading, log, reference="truth", block_rows=3004)
    assert np.allclose(blocks.estimates["heading"], whole.estimates["heading"], rtol=0, atol=1e-12)
    assert blocks.rms["heading"] == pytest.approx(whole.rms["heading"], rel=1e-9)


def test_a_log_whose_first_block_has_no_input_row_is_placed_as_in_one_block(heading):
    """3000 rows of another sensor, half a tick off the gyro's grid, one with a compass reading,
    before the first gyro row: in blocks of 2000 rows the log was placed on the first row's grid
    and its early compass reading used; with the grid of the first input rows, as in one block,
    the estimates are the same and the early reading is counted (before_start)."""
    log, _ = _jittered(8000)
    pre = pd.DataFrame({"time": -30.0 + 0.005 + 0.01 * np.arange(3000), "other": 1.0})
    pre.loc[100, "compass"] = 1.0
    log = pd.concat([pre, log], ignore_index=True)
    whole = run_log(heading, log, reference="truth")
    blocks = run_log(heading, log, reference="truth", block_rows=2000)
    assert whole.unused == blocks.unused == {"before_start": {"compass": 1}}
    assert np.allclose(blocks.estimates["heading"], whole.estimates["heading"], rtol=0, atol=1e-12)


def test_a_row_of_units_under_the_header_is_read_as_units(heading, tmp_path, cli):
    """Loggers write a row of units under the header (``ms,rad/s,rad``): the run stopped on
    line 2 ('not a number').  It is taken as the units and not read, with a note; the time's unit
    there is the time column's (as in ``time [ms]``); lines are still the file's own.  A first row
    of dates with its sensors empty is data."""
    log = heading_log(3, 37, n=1000)[0]
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    rows = log.assign(time=(log["time"] * 1000).round(6)).to_csv(index=False, lineterminator="\n").splitlines()
    for sep in (",", ";"):
        units = sep.join(["ms", "rad/s", "rad", "rad", "rad", ""])
        text = [rows[0], units, *rows[1:]]
        if sep == ";":
            text = [r.replace(",", ";") for r in text]
        (tmp_path / "u.csv").write_text("\n".join(text) + "\n")
        code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "u.csv", "-o", tmp_path / "e.csv")
        assert code == 0 and "u.csv line 2 (ms, rad/s, rad, rad, rad, ) is taken as the columns' units" in err, err
        assert np.allclose(pd.read_csv(tmp_path / "e.csv")["heading"], expected, rtol=0, atol=1e-9)
    text[300] = text[300].replace(text[300].split(";")[1], "abc", 1)
    (tmp_path / "u.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(DataError, match="line 301: column 'gyro' is not a number: 'abc'"):
        run_log(heading, tmp_path / "u.csv")
    dated = log.assign(time=pd.Timestamp("2024-05-01") + pd.to_timedelta(log["time"], unit="s"))
    dated.loc[0, ["gyro", "odometry", "compass", "truth", "lap"]] = np.nan  # a row of a date alone
    dated.to_csv(tmp_path / "d.csv", index=False)
    assert len(run_log(heading, tmp_path / "d.csv").estimates) == 1000


@pytest.mark.parametrize("faster_compass", [False, True])  # the table's gains / the Kalman filter over the arrivals
def test_after_a_pause_of_the_logger_the_heading_starts_again_and_the_band_covers_it(heading, faster_compass):
    """A 10 s pause of every row while the robot turns: the gyro held over it left the heading
    0.1 rad off for tens of seconds after it (the predicted std back at 0.0014 within seconds).
    After a pause the heading starts again from the first direct reading, the band covers the
    error after it, the start-up after it is left out of the settled RMS, and a note says so."""
    log, psi = heading_log(3, 37, n=8000, jitter=0.1)
    if faster_compass:
        log.loc[7::10, "compass"] = wrap(psi[7::10] + 0.05 * np.random.default_rng(1).standard_normal(800))
    paused = log.drop(index=range(2000, 3000)).reset_index(drop=True)
    whole = run_log(heading, log, reference="truth", std=True)
    res = run_log(heading, paused, reference="truth", std=True, block_rows=2500)
    after = res.estimates["time"].to_numpy() >= 30.0
    err = wrap(res.estimates["heading"].to_numpy() - paused["truth"].to_numpy())[after]
    same = wrap(whole.estimates["heading"].to_numpy() - log["truth"].to_numpy())[3000:]
    assert np.sqrt(np.mean(err ** 2)) <= 1.5 * np.sqrt(np.mean(same ** 2)) + 1e-3
    assert np.mean(np.abs(err) <= 2 * res.estimates["heading_std"].to_numpy()[after]) > 0.85
    notes = [n for n in res.notes if "logger paused" in n]
    assert res.pauses == 1 and len(notes) == 1, res.notes
    assert "1 time " in notes[0] and "the longest 10 s from 20 s" in notes[0], notes
    startup = int(np.ceil(res.startup_s / heading.sample_time_s))
    ticks = np.round(paused["time"].to_numpy() / 0.01)
    assert res.settled_samples == np.sum((ticks >= startup) & ((ticks < 3000) | (ticks >= 3000 + startup)))


def test_a_short_pause_bridged_by_the_held_gyro_does_not_restart_the_heading(heading):
    """A 0.61 s pause (61 ticks: a pause by count) of a smoothly turning robot: the held gyro
    carries the heading within the innovation's 3 sigma of the first odometry reading after it, so
    the heading carries on (no restart: swapping it for one reading would throw away its
    precision), the pause is still counted, and every row after the start-up counts as settled."""
    log, _ = heading_log(3, 37, n=6000, jitter=0.1)
    paused = log.drop(index=range(2000, 2061)).reset_index(drop=True)
    res = run_log(heading, paused, reference="truth", std=True)
    assert res.pauses == 1
    note = next(n for n in res.notes if "logger paused" in n)
    assert "after 0 of them" in note, note
    ticks = np.round(paused["time"].to_numpy() / 0.01)
    assert res.settled_samples == np.sum(ticks >= int(np.ceil(res.startup_s / heading.sample_time_s)))
    err = wrap(res.estimates["heading"].to_numpy() - paused["truth"].to_numpy())[2000:2300]
    assert np.sqrt(np.mean(err ** 2)) < 3 * res.predicted_std["heading"]


def test_a_log_without_a_pause_runs_as_before(heading):
    """Inputs that read at most 50 ticks apart are no pause: no restart, no note."""
    log, _ = heading_log(3, 37, n=3000)
    res = run_log(heading, log.drop(index=range(1000, 1049)), reference="truth")
    assert res.pauses == 0 and not any("logger paused" in n for n in res.notes)


@pytest.mark.parametrize("name", ["time_ms", "t [ms]", "Time (ms)"])
def test_a_parquet_time_column_named_with_its_unit_is_the_time_beside_a_datetime_index(heading, tmp_path, name):
    """A Parquet log's time column follows the one naming rule of CSV logs and DataFrames (``_time_name``):
    ``time_ms`` beside an unnamed DatetimeIndex was not taken as a time column, so the index took
    its place as ``time`` (a 100 Hz log read at the 20 Hz of the index was refused).  The index is
    left out as row labels, the estimates equal those of the CSV log."""
    log, _ = heading_log(3, 37, n=3000)
    timed = log.assign(time=log["time"] * 1000).rename(columns={"time": name})
    timed.to_csv(tmp_path / "log.csv", index=False)
    dates = pd.Timestamp("2024-05-01T12:00:00") + pd.to_timedelta(np.arange(len(log)) * 0.05, unit="s")
    timed.set_index(pd.DatetimeIndex(dates)).to_parquet(tmp_path / "log.parquet")
    expected = run_log(heading, tmp_path / "log.csv").estimates
    got = run_log(heading, tmp_path / "log.parquet").estimates
    assert list(got.columns) == list(expected.columns) and got.columns[0] == name
    assert np.allclose(got["heading"].to_numpy(), expected["heading"].to_numpy(), atol=1e-12, rtol=0)
    assert cfdesign.logs.read_columns(tmp_path / "log.parquet", ["gyro"], time=name)[name][1] == pytest.approx(
        log["time"].iloc[1])


def test_a_note_on_a_parquet_log_names_a_row_not_a_line(heading, tmp_path):
    """Parquet has no lines: the note on an input's held ticks names the row (counted from 1) after
    which the longest gap starts; a CSV log's names its file line."""
    log, _ = heading_log(3, 37, n=3000)
    log.loc[1000:1004, "gyro"] = np.nan  # rows 1000..1004 (0-based) without a gyro reading
    log.to_csv(tmp_path / "log.csv", index=False)
    log.to_parquet(tmp_path / "log.parquet", index=False)
    csv_note = next(n for n in run_log(heading, tmp_path / "log.csv").notes if "(an input)" in n)
    note = next(n for n in run_log(heading, tmp_path / "log.parquet").notes if "(an input)" in n)
    assert "after line 1001" in csv_note, csv_note  # row 999 on line 1001 (the header is line 1)
    assert "after row 1000" in note and "line" not in note, note  # the 1000th row


@pytest.mark.parametrize("rows", [None, 500])
def test_an_empty_cell_past_the_first_64_kb_of_a_log_separated_by_spaces_is_refused(heading, tmp_path, rows):
    """Every row of a log separated by spaces is checked for fewer cells than its header, not only
    those of its first 64 kB: a compass that stops partway (blank cells from row 2000, 180 kB in)
    was read with each later cell in the column before it (the truth as the compass), exit 0.
    Refused naming the line (counting a blank line before it), plain and gzipped, whole and in blocks;
    the same log with 'nan' in the cells runs."""
    import gzip

    log, _ = heading_log(0, 0, n=3000)
    log = log.ffill()  # every cell filled (a logger that repeats its last reading) ...
    log.loc[2000:, "compass"] = np.nan  # ... until the compass stops
    lines = log.to_string(index=False, na_rep="", float_format="{:.17g}".format).splitlines()
    lines.insert(1000, "")  # a blank line: the rows after it are a line further on
    text = "\n".join(lines) + "\n"
    (tmp_path / "stops.txt").write_text(text)
    (tmp_path / "stops.txt.gz").write_bytes(gzip.compress(text.encode()))
    first = 2 + 2000 + 1  # the header on line 1, row 2000 (0-based) on line 2002, one blank line before it
    assert len(lines[first - 2].split()) == 6 and len(lines[first - 1].split()) == 5
    assert text.index(lines[first - 1]) > 1 << 16
    for name in ("stops.txt", "stops.txt.gz"):
        with pytest.raises(DataError, match=rf"{name} line {first}: 5 cells under a header of 6 columns"):
            run_log(heading, tmp_path / name, block_rows=rows)
    with pytest.raises(DataError, match=rf"stops.txt line {first}: 5 cells"):
        cfdesign.logs.read_columns(tmp_path / "stops.txt", ["gyro"])
    (tmp_path / "nan.txt").write_text(log.to_string(index=False, na_rep="nan", float_format="{:.17g}".format))
    assert np.allclose(run_log(heading, tmp_path / "nan.txt", block_rows=rows).estimates["heading"],
                       run_log(heading, log).estimates["heading"], rtol=0, atol=1e-9)


def test_jitter_of_a_tenth_of_a_tick_with_a_row_in_seven_missing_is_the_table_rate_and_more_is_ambiguous():
    """+-0.1 tick of jitter with every 7th row, or a random one in seven, missing: accepted for 20
    seeds, and placed on a grid of the table's spacing.  +-0.4 tick with every 7th row missing fits
    6 rows in 7 ticks at 100 Hz as well as every row at 85.7 Hz: the message says the rate cannot
    be told from the times (it named 85.7 Hz as the log's rate)."""
    from cfdesign.timing import check_rate, grid_fit

    for seed in range(20):
        rng = np.random.default_rng(seed)
        k = np.arange(4000)
        for kept in (k[k % 7 != 6][:3000], k[rng.uniform(size=4000) > 1 / 7][:3000]):
            t = (kept + rng.uniform(-0.1, 0.1, len(kept))) * 0.01 + 12.3
            check_rate(t, 0.01, "log")
            assert abs(grid_fit(t, 0.01)[1] / 0.01 - 1) < 1e-3
    rng = np.random.default_rng(1)
    kept = k[k % 7 != 6][:3000]
    with pytest.raises(DataError, match=r"^log: the log's base rate is 85.71\d* Hz with every row present or "
                                        r"99.\d+ Hz with rows missing, .* the rate cannot be told from the times"):
        check_rate(np.sort(kept * 0.01 + 0.004 * rng.uniform(-1, 1, 3000)), 0.01, "log")


def _towed(table, seed, faster=False):
    """A simulated log of ``table`` (its accelerometer and GPS, std 2 m) whose logger paused 20 s
    while the vehicle was towed 5 km (the GPS and the truth moved on, nothing to tell the filter),
    and the row of the first GPS reading after the pause.  ``faster``: a GPS every 7th tick, off
    the table's schedule (the Kalman filter over the arrivals)."""
    n = 6000
    x, readings = model_log(table, n, seed=seed)
    log = pd.DataFrame({"time": np.arange(n) * 0.01, **readings, "truth": x[:, 0]})
    if faster:
        gps = np.full(n, np.nan)
        gps[3::7] = x[3::7, 0] + 2.0 * np.random.default_rng(seed + 99).standard_normal(len(gps[3::7]))
        log["gps"] = gps
    log.loc[4000:, ["gps", "truth"]] += 5000.0
    log = log.drop(index=range(2000, 4000)).reset_index(drop=True)
    return log, int(np.flatnonzero(log["gps"].notna() & (log["time"] >= 40.0 - 1e-9))[0])


@pytest.mark.parametrize("path", ["bridged", "arrivals", "fixed"])
def test_the_reading_that_restarts_the_state_after_a_pause_counts_once(gps3, path):
    """After a pause state 0 starts again from the first direct reading: the state and covariance
    then carried are the prior of that reading's tick, and its update read the same reading again,
    so the predicted std there was 1.41 m (the Kalman filters; 1.88 m for fixed gains) for an error
    of the reading's, 2 m: 1.41 times the std over 40 restarts.  The reading now counts once: the
    std there is the GPS's (the estimate is the reading), and over 40 seeds the RMS error right
    after the restart is within 15 % of the predicted std (10 and 30 ticks on, 30 %: the 3 Hz GPS
    has read again by then, and 40 seeds tell the RMS within 11 %; 1.02 and 0.99 over 200)."""
    import dataclasses

    table = gps3 if path != "fixed" else dataclasses.replace(  # gains with no model to recompute them from
        gps3, provenance={**gps3.provenance, "solver": {"method": "edited"}})
    errors, stds = [], []
    for seed in range(40):
        log, at = _towed(table, seed, faster=path == "arrivals")
        res = run_log(table, log, std=True, reference="truth")
        assert res.pauses == 1 and any("after 1 of them" in n for n in res.notes), res.notes
        est = res.estimates
        assert est["position"][at] == pytest.approx(log["gps"][at], abs=1e-9)
        assert est["position_std"][at] == pytest.approx(2.0, rel=1e-6)
        rows = at + np.array([0, 10, 30])
        errors.append((est["position"] - log["truth"]).to_numpy()[rows])
        stds.append(est["position_std"].to_numpy()[rows])
    ratio = np.sqrt(np.mean(np.square(errors), axis=0)) / np.mean(stds, axis=0)
    assert abs(ratio[0] - 1) < 0.15 and np.all(np.abs(ratio[1:] - 1) < 0.3), ratio  # 40 seeds: +-11 % (1 sigma)


GPS_VEL = {"name": "imu 100 Hz + velocity 10 Hz + gps 3 Hz", "structure": "chain", "order": 2, "discrete": True,
           "gain_form": "filter", "sensors": {
               "acc": {"measures": "acceleration", "rate_hz": 100.0, "noise": {"std": 0.05},
                       "bias": {"model": "random_walk", "density": 1e-3}},
               "gps": {"measures": "position", "rate_hz": 3.0, "offset_s": 0.12, "noise": {"std": 1.5}},
               "vel": {"measures": "velocity", "rate_hz": 10.0, "offset_s": 0.05, "noise": {"std": 0.1}}}}


@pytest.fixture(scope="module")
def gps_vel():
    return cfdesign.design(parse_spec(GPS_VEL))


@pytest.mark.parametrize("path", ["bridged", "arrivals", "fixed"])
def test_rows_from_a_pause_to_the_gps_move_onto_it_past_a_velocity_reading(gps_vel, path):
    """A 20 s pause while the vehicle was towed 5 km and sped up by 3 m/s; after it the 10 Hz
    velocity reads 5 ticks before the 3 Hz GPS.  The held accelerometer had correlated the position
    with the velocity over the pause, so the velocity reading stepped the position (by 14.8 m here)
    and the rows before it, moved onto the GPS by the same amount as the rest, stayed that far off
    (12.7 m here, 37 m on a user's log of a 30 s pause, against a 1.5 m GPS).  Every row from the pause's end to the GPS
    is within 4 GPS stds of the truth, on the table's schedule and off it (arrivals), and with
    fixed gains (no model: a step of the steady gain's, 0.27 m)."""
    import dataclasses

    table = gps_vel if path != "fixed" else dataclasses.replace(  # gains with no model to recompute them from
        gps_vel, provenance={**gps_vel.provenance, "solver": {"method": "edited"}})
    n = 6000
    x, readings = model_log(table, n, seed=5)
    log = pd.DataFrame({"time": np.arange(n) * 0.01, **readings, "truth": x[:, 0]})
    if path == "arrivals":  # the GPS every 29th tick, off the schedule: the Kalman filter over the arrivals
        gps = np.full(n, np.nan)
        gps[12::29] = x[12::29, 0] + 1.5 * np.random.default_rng(6).standard_normal(len(gps[12::29]))
        log["gps"] = gps
    after = np.arange(n) >= 4000
    towed = 5000.0 + 3.0 * (np.arange(n) - 4000) * 0.01
    log.loc[after, ["gps", "truth"]] = log.loc[after, ["gps", "truth"]].add(towed[after], axis=0)
    log.loc[after, "vel"] += 3.0
    log = log.drop(index=range(2000, 4000)).reset_index(drop=True)
    end = 2000
    fix = int(np.flatnonzero(log["gps"].notna().to_numpy()[end:])[0]) + end
    assert log["vel"][end:fix].notna().any()  # a velocity reading between the pause's end and the GPS
    res = run_log(table, log, std=True, reference="truth")
    assert res.pauses == 1 and any("after 1 of them" in n for n in res.notes), res.notes
    err = (res.estimates["position"] - log["truth"]).to_numpy()[end:fix + 1]
    assert np.all(np.abs(err) < 4 * 1.5), err


@pytest.mark.parametrize("block_rows", [None, 128])
def test_a_parquet_log_is_named_by_its_rows_in_the_messages_of_its_cells_and_times(heading, tmp_path, block_rows):
    """A Parquet log has no lines: a cell that is not a number, a time that is empty, goes back,
    repeats with a second reading or leaps were named 'line N' (one past the row, as if it had a
    header line); they name 'row N' (from 1), as the note on held inputs does, and the same log as
    CSV still names its file lines (the header on line 1), whole and in blocks."""
    log = heading_log(3, 37, n=1000)[0]
    bad_cell = log.assign(gyro=log["gyro"].map(repr))  # a column of text, as a logger may write it
    bad_cell.loc[300, "gyro"] = "abc"
    cases = [(bad_cell, "column 'gyro' is not a number: 'abc'", 300)]
    for message, value in {"no time (an empty cell": np.nan, "goes back from": 3.0,
                           "repeats 4.0 on the {} before (times must increase, and rows at one time": 4.0,
                           "s after the {} before, a gap of more than 1000000 ticks": None}.items():
        broken = log.copy()
        if value is None:  # 1e5 s later from row 401 on
            broken.loc[401:, "time"] += 1e5
        else:
            broken.loc[400 if value == 4.0 else 401, "time"] = broken.loc[401, "time"] = value  # 4.0: the gyro twice
        cases.append((broken, message, 401))
    for frame, message, row in cases:
        frame.to_parquet(tmp_path / "log.parquet")
        frame.to_csv(tmp_path / "log.csv", index=False)
        for name, where, noun in (("log.parquet", f"row {row + 1}", "row"), ("log.csv", f"line {row + 2}", "line")):
            with pytest.raises(DataError) as info:
                run_log(heading, tmp_path / name, block_rows=block_rows)
            text = str(info.value)
            assert text.startswith(f"{tmp_path / name} {where}: ") and message.format(noun) in text, text


@pytest.mark.parametrize("output", ["posterior", "prior"])
def test_the_error_of_fixed_gains_over_missed_readings_is_the_joseph_recursion(gps3, output):
    """``MissedReadings.stds`` (whole stretches of the table's pattern, and of no reading, at once)
    against the covariance of the fixed gains stepped tick by tick here, Joseph form: a 3 Hz GPS
    table fed in chunks over an outage of 25 s, scattered dropped fixes and a reading at a
    phase it does not schedule."""
    from cfdesign.runtime.arrivals import MissedReadings

    table, n_ticks = gps3, 9000
    F, H, Q, R = (np.asarray(a, dtype=float) for a in (table.F, table.H, table.Q, table.R))
    assert table.gain_form == "filter"
    phases = np.arange(n_ticks) % table.period
    mask = table.schedule.mask()
    present = np.ones((n_ticks, len(table.measurements)), dtype=bool)
    present[1500:4000] = False
    present[np.random.default_rng(5).integers(0, n_ticks, 12)] = False
    covs = table.P_filtered if output == "posterior" else table.P
    base = np.sqrt(np.array([np.diag(P) for P in covs]))[phases]
    missed = MissedReadings(table, output)
    got = np.concatenate([missed.stds(phases[i:i + 700], present[i:i + 700], base[i:i + 700])
                          for i in range(0, n_ticks, 700)])
    P, want = np.asarray(table.P[0], dtype=float), np.empty_like(base)
    for k, ph in enumerate(phases):
        rows = np.flatnonzero(mask[ph] & present[k])
        K = np.asarray(table.K[ph], dtype=float)[:, rows]
        A = np.eye(len(F)) - K @ H[rows]
        post = A @ P @ A.T + K @ R[np.ix_(rows, rows)] @ K.T
        want[k] = np.sqrt(np.diag(post if output == "posterior" else P))
        P = F @ post @ F.T + Q
    assert not np.allclose(got, base)
    np.testing.assert_allclose(got, want, rtol=1e-7)


def test_missed_readings_default_to_the_tables_output(gps3):
    """``MissedReadings(table)`` follows the table's output, as its docstring says (it followed the
    prior, ``output == 'posterior'`` being False for None): the stds over a missed fix are those of
    ``output=table.output``, and differ from the prior's."""
    from cfdesign.runtime.arrivals import MissedReadings

    assert gps3.output == "posterior"
    phases = np.arange(400) % gps3.period
    present = np.ones((400, len(gps3.measurements)), dtype=bool)
    present[100:300] = False
    base = np.sqrt(np.array([np.diag(P) for P in gps3.P_filtered]))[phases]
    default, posterior, prior = (MissedReadings(gps3, *o).stds(phases, present, base)
                                 for o in ((), ("posterior",), ("prior",)))
    np.testing.assert_array_equal(default, posterior)
    assert not np.allclose(default, prior)


@pytest.mark.parametrize("terminal", [False, True])
def test_the_progress_bar_is_drawn_on_a_terminal_only(heading, monkeypatch, terminal):
    """``cfdesign run``'s bar (a log longer than a block) goes to a terminal; stderr redirected
    to a file or CI's log gets none of its carriage-return lines, only the notes."""
    import io
    import sys

    import cfdesign.logs.run as log_run

    class Stderr(io.StringIO):
        def isatty(self):
            return terminal

    log, _ = heading_log(0, 0, n=400)
    monkeypatch.setattr(log_run, "BLOCK_ROWS", 100)
    monkeypatch.setattr(sys, "stderr", Stderr())
    run_log(heading, log, progress=True)
    drawn = sys.stderr.getvalue()
    assert ("400/400" in drawn and "row" in drawn) if terminal else "\r" not in drawn and "row/s" not in drawn


def test_a_dataframe_s_column_names_are_read_as_a_file_s_header(heading):
    """A DataFrame whose column names carry spaces (`` gyro [deg/s] ``, ``compass ``) had raised a
    raw KeyError; its names are stripped as a CSV header's are, and a name that then repeats
    another is refused as a duplicate."""
    log, _ = heading_log(0, 0, n=500)
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    spaced = log.assign(gyro=np.degrees(log["gyro"])).rename(columns={"gyro": " gyro [deg/s] ", "compass": "compass "})
    assert np.allclose(run_log(heading, spaced).estimates["heading"], expected, rtol=0, atol=1e-12)
    with pytest.raises(DataError, match=r"duplicate column\(s\) gyro"):
        run_log(heading, log.assign(**{"gyro ": log["gyro"]}))
