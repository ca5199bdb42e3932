"""A log kept as one file per sensor (``--join``, ``run_log(join=...)``): the estimates are those
of the files merged with pandas first, each joined file checked as a log is, naming it."""

import gzip
import re

import numpy as np
import pandas as pd
import pytest
from conftest import read_csv_exact

from cfdesign.errors import DataError
from cfdesign.linear import wrap
from cfdesign.logs import run_log


def heading_files(n=1500, seed=4):
    """A turning robot: a 100 Hz gyro file (``time`` in s, a reference and a text column), a 10 Hz
    odometry file with its own stamps (``t``, 3 ms after the gyro's rows it follows) and a 1 Hz
    compass file stamped at the time of gyro rows (equal times: the gyro's row first)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01 + 0.0005 * rng.standard_normal(n)
    psi = 2.0 + 3.0 * np.sin(0.2 * t) + 0.3 * t
    imu = pd.DataFrame({"time": t, "gyro": np.gradient(psi, t) + 0.01 * rng.standard_normal(n),
                        "truth": wrap(psi), "lap": np.arange(n) // 100,
                        "tag": np.where(np.arange(n) < 300, None, "a")})  # text from row 300 on
    k = np.arange(3, n, 10)
    odo = pd.DataFrame({"t": t[k] + 0.003, "odometry": wrap(psi[k] + 0.005 * rng.standard_normal(k.size)),
                        "device_id": 7})
    c = np.arange(37, n, 100)
    com = pd.DataFrame({"time": t[c], "compass": wrap(psi[c] + 0.05 * rng.standard_normal(c.size))})
    return imu, odo, com


def pre_merged(main, others, time="time"):
    """The files merged as a user would with pandas: the columns the run uses, concatenated and
    sorted stably by time."""
    return pd.concat([main, *others], ignore_index=True).sort_values(time, kind="stable", ignore_index=True)


def test_joined_files_give_the_estimates_of_the_pre_merged_log(heading, tmp_path, cli, monkeypatch):
    """Through the CLI, odometry and compass in files of their own (the compass a spreadsheet's
    export: BOM, CRLF) give the pre-merged log's estimates to the last bit, with one row per row of
    the union, the main file's columns passed through; also read in blocks (a big log) of 700 rows,
    a column of text empty in the first ones."""
    imu, odo, com = heading_files()
    imu.to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    (tmp_path / "com.csv").write_bytes(b"\xef\xbb\xbf" + com.to_csv(index=False, lineterminator="\r\n").encode())
    merged = pre_merged(imu, [odo.drop(columns="device_id").rename(columns={"t": "time"}), com])
    expected = run_log(heading, merged, reference="truth", std=True).estimates
    table = heading.save(tmp_path / "g.json")
    code, out, err = cli("run", table, tmp_path / "imu.csv", "--join", tmp_path / "odo.csv", "--join",
                         tmp_path / "com.csv", "--reference", "truth", "--std", "-o", tmp_path / "est.csv")
    assert code == 0, err
    est = read_csv_exact(tmp_path / "est.csv")  # compared to the last bit
    assert list(est.columns) == ["time", "heading", "gyro_correction", "heading_std", "gyro_correction_std",
                                 "truth", "lap", "tag"]  # device_id of the odometry file is not taken
    assert len(est) == len(imu) + len(odo) + len(com)
    for c in ("heading", "gyro_correction", "heading_std"):
        np.testing.assert_array_equal(est[c].to_numpy(), expected[c].to_numpy())
    np.testing.assert_array_equal(est["time"].to_numpy(), merged["time"].to_numpy())
    assert "compass 37 ticks, odometry 3 ticks" in err and "RMS error of heading" in out
    monkeypatch.setattr("cfdesign.logs.run.ONE_PASS_BYTES", 0)  # the main file streamed in blocks
    blocks = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "com.csv"],
                     block_rows=700, reference="truth").estimates
    # to rounding: a log's blocks split the batch run (the pre-merged log's blocks of 700 rows differ by 1e-14 too)
    np.testing.assert_allclose(blocks["heading"].to_numpy(), expected["heading"].to_numpy(), rtol=0, atol=1e-12)
    assert blocks["tag"].fillna("").tolist() == merged["tag"].fillna("").tolist()


def test_a_ros_file_in_nanoseconds_beside_a_px4_file_in_microseconds(heading, tmp_path):
    """PX4's ``sensor_combined.csv`` (``timestamp`` in us, ``--time-unit us``; the gyro as
    ``gyro_rad[2]``) joined with ROS ``rostopic echo -p`` files (``%time`` in ns, on the same clock):
    each file's unit is its own, and the estimates are the pre-merged log's to the last bit."""
    imu, odo, com = heading_files(n=1200, seed=5)
    start = 1_700_000_000_000_000  # us since 1970
    px4 = pd.DataFrame({"timestamp": start + np.round(imu["time"] * 1e6).astype(np.int64),
                        "gyro_rad[2]": imu["gyro"], "device_id": 3})
    ros = [pd.DataFrame({"%time": start * 1000 + np.round(f[c] * 1e9).astype(np.int64), "field.data": f[s]})
           for f, c, s in ((odo, "t", "odometry"), (com, "time", "compass"))]
    px4.to_csv(tmp_path / "sensor_combined.csv", index=False)
    for name, f in zip(("odometry.csv", "compass.csv"), ros, strict=True):
        f.rename(columns={"field.data": name[:-4]}).to_csv(tmp_path / name, index=False)
    merged = pre_merged(px4.drop(columns="device_id").rename(columns={"gyro_rad[2]": "gyro"}),
                        [pd.DataFrame({"timestamp": f["%time"] / 1000, s: f["field.data"]})
                         for f, s in zip(ros, ("odometry", "compass"), strict=True)], "timestamp")
    expected = run_log(heading, merged, time_unit="us").estimates
    got = run_log(heading, tmp_path / "sensor_combined.csv", join=[tmp_path / "odometry.csv", tmp_path / "compass.csv"],
                  mapping={"gyro": "gyro_rad[2]"}, time_unit="us").estimates
    np.testing.assert_array_equal(got["heading"].to_numpy(), expected["heading"].to_numpy())
    np.testing.assert_array_equal(got["timestamp"].to_numpy(), merged["timestamp"].to_numpy())
    assert list(got.columns) == ["timestamp", "heading", "gyro_correction", "device_id"]


def test_a_gzip_log_joined_with_a_parquet_file(heading, tmp_path):
    """The main file gzip-compressed, the compass in Parquet: the estimates file is the one of the
    pre-merged log, cell for cell."""
    pytest.importorskip("pyarrow")
    imu, odo, com = heading_files(n=800, seed=6)
    main = imu.assign(odometry=np.nan)
    for k, row in zip(np.searchsorted(imu["time"], odo["t"]) - 1, odo.itertuples(), strict=True):
        main.loc[k, "odometry"] = row.odometry  # the odometry in the main file, the compass joined
    with gzip.open(tmp_path / "imu.csv.gz", "wt") as fh:
        main.to_csv(fh, index=False)
    com.to_parquet(tmp_path / "compass.parquet", index=False)
    pre_merged(main, [com]).to_csv(tmp_path / "merged.csv", index=False)
    run_log(heading, tmp_path / "merged.csv", output=tmp_path / "expected.csv", reference="truth")
    run_log(heading, tmp_path / "imu.csv.gz", join=tmp_path / "compass.parquet", output=tmp_path / "est.csv",
            reference="truth")
    assert (tmp_path / "est.csv").read_text() == (tmp_path / "expected.csv").read_text()


def _refusals(imu, odo, com):
    """``{case: (files {name: text}, more logs, the output, message)}``: each a one-line refusal naming the file."""
    com_csv = com.to_csv(index=False)
    lines = com_csv.splitlines(keepends=True)
    return {
        "a column in two files": ({"imu.csv": imu.assign(compass=1.0).to_csv(index=False)}, [], "est.csv",
                                  "column 'compass' is in both imu.csv and com.csv"),
        "a sensor in no file": ({"com.csv": com.rename(columns={"compass": "mag"}).to_csv(index=False)}, [],
                                "est.csv",
                                r"missing column\(s\) compass \(columns: .*imu.csv: time, gyro.*com.csv: time, mag"),
        "clocks that differ": ({"com.csv": com.assign(time=com["time"] + 1e9).to_csv(index=False)}, [], "est.csv",
                               r"com.csv: its times \(1000000000 s to .* do not overlap those of imu.csv "
                               r"\(.* s to .* s\): the files' clocks"),
        "a garbage cell": ({"com.csv": com_csv.replace(lines[3].split(",")[1], "#DIV/0!\n", 1)}, [], "est.csv",
                           r"com.csv line 4: column 'compass' is not a number: '#DIV/0!' \(a spreadsheet's error"),
        "a garbage cell of the main file, after joined rows": (
            {"imu.csv": imu.astype({"gyro": object}).assign(gyro=lambda f: f["gyro"].where(f.index != 300, "x"))
             .to_csv(index=False)}, [], "est.csv",
            r"^cfdesign: error: imu.csv line 302: column 'gyro' is not a number"),
        "an empty file": ({"com.csv": ""}, [], "est.csv", r"com.csv: empty file"),
        "a header only": ({"com.csv": lines[0]}, [], "est.csv", r"com.csv: the joined file has a header but no rows"),
        "times that go back": ({"com.csv": "".join([lines[0], lines[2], lines[1], *lines[3:]])}, [], "est.csv",
                               r"com.csv line 3: time .* goes back from"),
        "a reading twice at one time": ({"com.csv": "".join([*lines[:3], lines[2], *lines[3:]])}, [], "est.csv",
                                        r"com.csv line 4: time .* repeats"),
        "a file the run takes nothing from": ({"imu.csv": imu.assign(compass=1.0).to_csv(index=False),
                                               "com.csv": com.rename(columns={"compass": "mag"}).to_csv(index=False)},
                                              [], "est.csv", r"^cfdesign: error: com.csv: none of its columns "
                                              r"\(time, mag\) is one the run uses"),
        "no time column": ({"com.csv": com.rename(columns={"time": "when"}).to_csv(index=False)}, [], "est.csv",
                           r"com.csv: no time column"),
        "several logs": ({"imu2.csv": imu.to_csv(index=False)}, ["imu2.csv"], "out/",
                         "--join merges files into one log"),
        "the output joined": ({}, [], "odo.csv", "the output odo.csv is joined file 1"),
    }


@pytest.mark.parametrize("case", list(_refusals(*heading_files(n=300))))

def test_bad_joined_files_are_refused_on_one_line_naming_the_file(case, heading, tmp_path, cli, monkeypatch):
    imu, odo, com = heading_files(n=400)
    odo = odo.rename(columns={"t": "time"}).drop(columns="device_id")
    files, logs, output, message = _refusals(imu[["time", "gyro"]], odo, com)[case]
    monkeypatch.chdir(tmp_path)
    heading.save(tmp_path / "g.json")
    written = {"imu.csv": imu[["time", "gyro"]].to_csv(index=False), "odo.csv": odo.to_csv(index=False),
               "com.csv": com.to_csv(index=False), **files}
    for name, text in written.items():
        (tmp_path / name).write_text(text)
    code, _, err = cli("run", "g.json", "imu.csv", *logs, "--join", "odo.csv", "--join", "com.csv", "-o", output)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert re.search(message, err), err
    assert not (tmp_path / "est.csv").exists() and not (tmp_path / "out").exists()
    assert (tmp_path / "odo.csv").read_text() == written["odo.csv"]


def px4_files(tmp_path, seed=8):
    """PX4 ``ulog2csv`` topics of a turning robot: ``sensor_combined.csv`` (the gyro as ``gyro_rad[2]``,
    its ``timestamp`` in microseconds since boot jittered by +-0.2 tick, as a logger stamps them;
    the 10 Hz odometry, and a 1 Hz ``vehicle_magnetometer.csv`` (``compass``), each with its own ``timestamp``."""
    imu, odo, com = heading_files(n=1000, seed=seed)
    rng = np.random.default_rng(seed)
    boot = 23_456_789 + np.round((np.arange(len(imu)) + rng.uniform(-0.2, 0.2, len(imu))) * 10_000)
    odometry = np.full(len(imu), np.nan)
    odometry[np.arange(3, len(imu), 10)] = odo["odometry"]
    pd.DataFrame({"timestamp": boot.astype(np.int64), "gyro_rad[2]": imu["gyro"], "odometry": odometry}).to_csv(
        tmp_path / "sensor_combined.csv", index=False)
    rows = np.searchsorted(imu["time"], com["time"])
    pd.DataFrame({"timestamp": boot[rows].astype(np.int64) + 1_300, "compass": com["compass"]}).to_csv(
        tmp_path / "vehicle_magnetometer.csv", index=False)


@pytest.mark.parametrize("given, named", [
    ((), "times in microseconds? They are read as seconds unless --time-unit us is given"),
    (("--time-unit", "ms"), "(times in microseconds? they are read as milliseconds: give --time-unit us)"),
    (("--time-unit", "ns"), "(times in microseconds? they are read as nanoseconds: give --time-unit us)")])
def test_px4_microseconds_read_in_another_unit_name_us(given, named, heading, tmp_path, cli):
    """PX4's jittered ``timestamp`` in microseconds read as seconds, milliseconds or nanoseconds: the
    one-line error names microseconds and ``--time-unit us``, for the main file and for a joined
    one (read as seconds, a step of 1.14 ticks had been called a gap to split the log at; with
    ``--time-unit ms`` given, the message had named milliseconds, the unit given)."""
    px4_files(tmp_path)
    table = heading.save(tmp_path / "g.json")
    run = ("run", table, tmp_path / "sensor_combined.csv", "--join", tmp_path / "vehicle_magnetometer.csv",
           "--map", "gyro=gyro_rad[2]", "-o", tmp_path / "e.csv")
    code, _, err = cli(*run, *given)
    assert code == 2 and named in err and err.count("\n") == 1, err
    code, _, err = cli(*run, "--time-unit", "us")
    assert code == 0, err
    if not given:  # the joined file alone in another unit: the main file's time named in microseconds
        main = pd.read_csv(tmp_path / "sensor_combined.csv").rename(columns={"timestamp": "timestamp_us"})
        main.to_csv(tmp_path / "sensor_combined.csv", index=False)
        code, _, err = cli(*run)
        assert code == 2 and err.startswith("cfdesign: error: " + str(tmp_path / "vehicle_magnetometer.csv"))
        assert named in err, err


def test_a_reference_in_a_joined_file_is_drawn(heading, tmp_path):
    """``--reference`` from a file of its own (PX4's ``vehicle_attitude.csv``): on the rows of the
    union it is a number on every other row, and the plot draws it and its error as lines through
    those rows (drawn row by row, the NaN between them had left both panels empty)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cfdesign.logs.plot import plot_log

    imu, odo, com = heading_files(n=600, seed=9)
    imu.drop(columns="truth").to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    com.to_csv(tmp_path / "com.csv", index=False)
    att = pd.DataFrame({"time": imu["time"] + 0.004, "truth": imu["truth"]})  # stamped apart from the gyro's
    att.to_csv(tmp_path / "att.csv", index=False)
    est = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / f for f in ("odo.csv", "com.csv", "att.csv")],
                  reference="truth", std=True).estimates
    assert est["heading_reference"].notna().sum() == len(att) < len(est)
    fig = plot_log(heading, est, {"heading": "truth"}, "time")
    lines = {ln.get_label(): ln.get_ydata() for ax in fig.axes for ln in ax.get_lines()}
    plt.close(fig)
    for label in ("reference", "error"):
        y = np.asarray(lines[label], dtype=float)
        segments = np.isfinite(y[1:]) & np.isfinite(y[:-1])  # what a line draws: finite neighbours
        assert segments.sum() >= len(att) - 5, label  # a few breaks at the heading's +-pi wraps
    ref = np.asarray(lines["reference"], dtype=float)
    np.testing.assert_array_equal(ref[np.isfinite(ref)], att["truth"].to_numpy()[np.isfinite(ref)])


def test_integer_times_are_written_whole(heading, tmp_path):
    """ROS ``rostopic echo -p`` files joined (``%time``: integer nanoseconds since 1970, to the
    nanosecond): the union's ``%time`` is written as the files had it, as ``pandas.concat`` keeps it,
    not as floats (1.700000000000662e+18, up to 128 ns off); PX4 files in microseconds the same
    (``23457451``, not ``23457451.0``)."""
    imu, odo, com = heading_files(n=600, seed=10)
    start = 1_700_000_000_000_000_017  # ns since 1970, not a multiple of a float's step there (256 ns)
    files = [pd.DataFrame({"%time": start + np.round(f[c] * 1e9).astype(np.int64) + odd, s: f[s]})
             for f, c, s, odd in ((imu, "time", "gyro", 0), (odo, "t", "odometry", 3), (com, "time", "compass", 5))]
    for name, f in zip(("imu", "odo", "com"), files, strict=True):
        f.to_csv(tmp_path / f"{name}.csv", index=False)
    run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "com.csv"],
            output=tmp_path / "est.csv")
    merged = pre_merged(files[0], files[1:], "%time")
    est = pd.read_csv(tmp_path / "est.csv")
    assert est["%time"].dtype == np.int64
    np.testing.assert_array_equal(est["%time"].to_numpy(), merged["%time"].to_numpy())
    px4_files(tmp_path)
    run_log(heading, tmp_path / "sensor_combined.csv", join=tmp_path / "vehicle_magnetometer.csv",
            mapping={"gyro": "gyro_rad[2]"}, time_unit="us", output=tmp_path / "px4.csv")
    times = [line.split(",")[0] for line in (tmp_path / "px4.csv").read_text().splitlines()[1:]]
    assert all(re.fullmatch(r"\d+", t) for t in times), times[:3]


def test_a_log_without_times_beside_joined_files_names_its_first_row(heading, tmp_path):
    """A main file whose time cells are all empty, read whole: its first line is named as having no
    time, as alone (the joined files' overlap check compared with no first time: a TypeError)."""
    imu, odo, com = heading_files(n=200)
    imu[["time", "gyro"]].assign(time=np.nan).to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    com.to_csv(tmp_path / "com.csv", index=False)
    with pytest.raises(DataError, match=r"imu.csv line 2: no time \(an empty cell"):
        run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "com.csv"])


def test_a_column_name_twice_in_a_joined_file_is_refused(heading, tmp_path):
    """A joined file naming a column twice is refused naming it, as the main file is (it had been
    read in silence, one of the two taken)."""
    imu, odo, com = heading_files(n=200)
    imu[["time", "gyro"]].to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    com.assign(again=0.0).rename(columns={"again": "compass"}).to_csv(tmp_path / "com.csv", index=False)
    with pytest.raises(DataError, match=r"com.csv: duplicate column\(s\) compass"):
        run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "com.csv"])


def test_each_row_of_the_union_is_named_at_its_file_and_line(heading, tmp_path, monkeypatch):
    """Where each row of the union is, for a message, read in blocks of 50 rows: the main file's line,
    or ``line N of FILE`` of a joined one, as the rows of the files sorted stably by time with pandas
    say (its rows kept as one array, the joined files' own copies let go once merged)."""
    import cfdesign.logs.run as run
    from cfdesign.logs.join import _Join

    imu, odo, com = heading_files(n=400)
    files = {"imu.csv": imu[["time", "gyro"]], "odo.csv": odo.rename(columns={"t": "time"})[["time", "odometry"]],
             "com.csv": com}
    for name, f in files.items():
        f.to_csv(tmp_path / name, index=False)
    made = []

    class Kept(_Join):
        def __init__(self, *args):
            super().__init__(*args)
            made.append(self)

    monkeypatch.setattr(run, "_Join", Kept)
    monkeypatch.setattr(run, "ONE_PASS_BYTES", 0)
    run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "com.csv"], block_rows=50)
    union = pd.concat([f.assign(name=n, line=np.arange(len(f)) + 2) for n, f in files.items()]).sort_values(
        "time", kind="stable", ignore_index=True)
    expected = [f"line {k}" + ("" if n == "imu.csv" else f" of {tmp_path / n}") for n, k in zip(
        union["name"], union["line"], strict=True)]
    assert [made[0].at(i) for i in range(len(union))] == expected
    assert all(f.values is None for f in made[0].files)


def test_one_file_given_twice_is_named_as_such(heading, tmp_path, cli, monkeypatch):
    """A file joined twice, or joined as well as given as the log, was refused with the message of an
    output ("one would replace the other"): nothing is written there, it would be read twice."""
    imu, _, com = heading_files(n=300)
    monkeypatch.chdir(tmp_path)
    heading.save(tmp_path / "g.json")
    imu[["time", "gyro"]].to_csv("imu.csv", index=False)
    com.to_csv("com.csv", index=False)
    for joins, message in ((["com.csv", "com.csv"], "joined file 2 com.csv is joined file 1 com.csv"),
                           (["imu.csv"], "joined file 1 imu.csv is the log imu.csv")):
        code, _, err = cli("run", "g.json", "imu.csv", *[a for j in joins for a in ("--join", j)], "-o", "est.csv")
        assert code == 2 and err == f"cfdesign: error: {message}: the same file given twice\n", err
    code, _, err = cli("run", "g.json", "imu.csv", "--join", "com.csv", "-o", "com.csv")
    assert code == 2 and "the output com.csv is joined file 1 com.csv: one file for both, one would replace" in err
    assert not (tmp_path / "est.csv").exists()


def test_a_joined_file_in_degrees_is_read_in_them_once(heading, tmp_path):
    """A compass file in degrees (a row of units under its header, or its column named so and
    mapped) gives the estimates of the same file in radians: its readings converted once (scaled
    both as the joined file was read and as the merged rows were, the compass ran 4 mrad off)."""
    imu, odo, com = heading_files(n=800, seed=6)
    odo = odo.rename(columns={"t": "time"})
    imu.to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    com.to_csv(tmp_path / "rad.csv", index=False)
    expected = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "rad.csv"]).estimates
    deg = com.assign(compass=np.degrees(com["compass"]))
    rows = deg.to_csv(index=False, float_format="%.17g", lineterminator="\n").partition("\n")[2]
    (tmp_path / "row.csv").write_text("time,compass\ns,deg\n" + rows)
    deg.rename(columns={"compass": "compass [deg]"}).to_csv(tmp_path / "named.csv", index=False, float_format="%.17g")
    for name, mapping in (("row.csv", None), ("named.csv", {"compass": "compass [deg]"})):
        got = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / name], mapping=mapping)
        assert any("is in deg: read as rad" in n for n in got.notes), got.notes
        assert np.allclose(got.estimates["heading"], expected["heading"], rtol=0, atol=1e-12)


def test_a_joined_column_named_with_its_unit_is_taken_as_in_one_file(heading, tmp_path):
    """A joined compass file's ``compass [deg]`` is the compass's as it is in the main file (it was a
    missing column unless mapped: a joined file found a sensor's column by its name and its case only)."""
    imu, odo, com = heading_files(n=400, seed=6)
    imu.to_csv(tmp_path / "imu.csv", index=False)
    odo.to_csv(tmp_path / "odo.csv", index=False)
    com.to_csv(tmp_path / "rad.csv", index=False)
    com.assign(compass=np.degrees(com["compass"])).rename(columns={"compass": "compass [deg]"}).to_csv(
        tmp_path / "deg.csv", index=False, float_format="%.17g")
    expected = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "rad.csv"]).estimates
    got = run_log(heading, tmp_path / "imu.csv", join=[tmp_path / "odo.csv", tmp_path / "deg.csv"])
    assert "column 'compass [deg]' is in deg: read as rad (times 0.0174533)" in got.notes, got.notes
    assert np.allclose(got.estimates["heading"], expected["heading"], rtol=0, atol=1e-12)
