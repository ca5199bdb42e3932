"""Logs as loggers and spreadsheets write them: placeholders in empty cells, true/false cells,
spreadsheet error values, rows pandas cannot split, clocks that wrap or restart, a header written
twice, invisible characters around names, time columns named as an Arduino names them."""

import numpy as np
import pandas as pd
import pytest

from cfdesign.errors import DataError
from cfdesign.linear import wrap
from cfdesign.logs import read_columns, run_log
from cfdesign.timing import place


def small_log(n=400, seed=1):
    """A turning robot: 100 Hz gyro, odometry at rows 3, 13, ..., compass at rows 37, 137, ...
    (empty cells between), headings wrapped."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    psi = 2.0 + 0.6 * t + 0.2 * np.sin(t)
    odo, com = np.full(n, np.nan), np.full(n, np.nan)
    odo[3::10] = psi[3::10] + 0.005 * rng.standard_normal(len(odo[3::10]))
    com[37::100] = psi[37::100] + 0.05 * rng.standard_normal(len(com[37::100]))
    gyro = np.gradient(psi, 0.01) + 0.01 * rng.standard_normal(n)
    return pd.DataFrame({"time": t, "gyro": gyro, "odometry": wrap(odo), "compass": wrap(com)})


@pytest.fixture(scope="module")
def reference(heading):
    """The small log and its estimates, run from the DataFrame."""
    log = small_log()
    return log, run_log(heading, log).estimates["heading"].to_numpy()


def lines_of(log) -> list:
    return log.to_csv(index=False).splitlines()


def test_inf_in_every_empty_cell_is_a_rejected_reading_not_a_forward_filled_column(heading, reference, tmp_path):
    """A logger that writes inf (or 1e999) where a slow sensor has no reading: the estimates are the
    empty cells', every such cell is counted as rejected, and no note calls the column forward-filled
    (the inf repeated on every row made it look so: 'a value that differs from the one before is
    read as a reading', and 46 of the 756 inf cells were counted as rejected)."""
    log, expected = reference
    gaps = {s: int(log[s].isna().sum()) for s in ("odometry", "compass")}
    for token in ("inf", "-inf", "1e999"):
        log.to_csv(tmp_path / "log.csv", index=False, na_rep=token)
        result = run_log(heading, tmp_path / "log.csv")
        assert np.allclose(result.estimates["heading"], expected, rtol=0, atol=1e-12), token
        assert result.unused["rejected"] == gaps, token
        assert not any("forward-filled" in note for note in result.notes), result.notes


def test_a_column_with_a_text_cell_is_read_to_the_last_bit(tmp_path):
    """A column pandas cannot read as numbers (a 'NaN ' padded by a fixed-width export) is read cell
    by cell: pandas 2's ``to_numeric`` read 1582 of these 5000 shortest reprs of doubles an ulp off
    (pandas 3 none), and ``1e999`` as no number (pandas 3: inf).  Reference: Python's float()."""
    rng = np.random.default_rng(7)
    x = rng.standard_normal(5000) * np.exp(rng.uniform(-30, 30, 5000))
    cells = [repr(float(v)) for v in x] + ["NaN ", "1e999", "-1E+999", "1e-999"]
    pd.DataFrame({"time": np.arange(len(cells)), "a": cells}).to_csv(tmp_path / "log.csv", index=False)
    got = read_columns(tmp_path / "log.csv", ["a"])["a"]
    np.testing.assert_array_equal(got, [float(c) for c in cells])


@pytest.mark.parametrize("how", ["csv", "parquet", "frame"])
def test_true_false_cells_of_a_sensor_are_refused_naming_the_first(heading, reference, tmp_path, how):
    """pandas reads a column of True/False as booleans, which numpy takes as 1 and 0: a gyro column
    of them ran with exit 0.  A CSV's, a Parquet file's and a DataFrame's are refused naming the
    first cell (a CSV's line, a Parquet file's row)."""
    log = reference[0].assign(gyro=reference[0]["gyro"] > 0.6)
    where = {"csv": "line 2", "parquet": "row 1", "frame": "line 2"}[how]
    data = log if how == "frame" else tmp_path / f"log.{how}"
    if how == "csv":
        log.to_csv(data, index=False)
    elif how == "parquet":
        log.to_parquet(data, index=False)
    with pytest.raises(DataError, match=rf"{where}: column 'gyro' holds true/false values, not numbers: "
                                        f"{bool(log['gyro'].iloc[0])}$"):
        run_log(heading, data)


@pytest.mark.parametrize("cell, hint", [
    ("#DIV/0!", "a spreadsheet's error value: the formula of that cell failed"),
    ("#VALUE!", "a spreadsheet's error value"),
    ("-", "a dash: leave a cell without a reading empty, or write nan"),
    ("--", "a dash"),
])
def test_spreadsheet_error_values_and_dashes_are_named_as_what_they_are(heading, reference, tmp_path, cell, hint):
    """'#DIV/0!' in a cell was named 'a comment line'; a dash had no hint.  Both are refused naming
    the cell's line, with what the cell likely is (a dash may be a number cut to its sign)."""
    lines = lines_of(reference[0])
    cells = lines[101].split(",")
    cells[2] = cell
    (tmp_path / "log.csv").write_text("\n".join([*lines[:101], ",".join(cells), *lines[102:]]) + "\n")
    with pytest.raises(DataError, match=r"log\.csv line 102: column 'odometry' is not a number: .*"
                                        rf"\({pytest.importorskip('re').escape(hint)}"):
        run_log(heading, tmp_path / "log.csv")


def test_rows_pandas_cannot_split_are_named_by_their_file_line(heading, reference, tmp_path):
    """A row of extra cells and a quote never closed were pandas' words ('Error tokenizing data.
    C error: Expected 4 fields in line 7, saw 5', 'EOF inside string starting at row 300', a row
    that is no file line): now one line naming the file line, counted here over the comment and
    blank lines before it; a quote closed lines later names the cell that swallowed them."""
    lines = ["# logger 1.2", "", *lines_of(reference[0])]
    extra = [*lines[:300], "", lines[300] + ",7", *lines[301:]]
    (tmp_path / "extra.csv").write_text("\n".join(extra) + "\n")
    with pytest.raises(DataError, match=r"extra\.csv line 302: 5 cells under a header of 4 columns \(a line "):
        run_log(heading, tmp_path / "extra.csv")
    quote = [*lines[:300], '2.97,"0.6', *lines[301:]]
    (tmp_path / "quote.csv").write_text("\n".join(quote) + "\n")
    with pytest.raises(DataError, match=r'quote\.csv line 301: a quote \(\"\) opened in a cell is never closed'):
        run_log(heading, tmp_path / "quote.csv")
    closed = [*quote[:350], '3.47,"0.6",,', *quote[351:]]
    (tmp_path / "closed.csv").write_text("\n".join(closed) + "\n")
    with pytest.raises(DataError, match=r"closed\.csv line 301: column 'gyro' is not a number: .*\(a quote opened "
                                        r"in this cell is closed lines later"):
        run_log(heading, tmp_path / "closed.csv")


COUNTER = np.arange(300) * 10_000  # 100 Hz in microseconds


@pytest.mark.parametrize("times, scale, hint", [
    ((COUNTER + 2**32 - 1_000_000) % 2**32, 1e-6, r"a counter that wraps at 2\^32 us \(4294\.967 s, 71\.58 min\)\? "
                                                   r"Add 2\^32 us to the times from there on"),
    ((COUNTER + 2**32 - 1_000_000) % 2**32, 1.0, r"a counter that wraps at 2\^32 of the column's unit\? Add 2\^32 "),
    ((COUNTER // 1000 + 2**16 - 1000) % 2**16, 1e-3, r"a counter that wraps at 2\^16 ms \(65\.536 s\)\? Add 2\^16 ms"),
    (np.where(np.arange(300) < 150, COUNTER + 5_000_000, COUNTER - 1_500_000), 1e-6, "the clock restarted"),
    (COUNTER[[*range(150), 151, 150, *range(152, 300)]], 1e-6, r"rows out of order\? Sort them by time$"),
])
def test_a_time_that_goes_back_says_why(times, scale, hint):
    """A 32-bit microsecond counter wraps every 71.6 min, a 16-bit millisecond one every 65.5 s; a
    logger that restarts, or two recordings in one file, starts its clock again; rows may be out of
    order.  Each was 'time 0.0 goes back from 4294.96': the message now says which it likely is."""
    t = times.astype(float) * scale
    with pytest.raises(DataError, match=r"line \d+: time .* goes back from .*: " + hint):
        place(t, 0.01, rate=False)


def test_a_wrapping_counter_is_refused_on_one_line_leaving_no_output(heading, reference, tmp_path):
    """End to end: a uint32 microsecond counter named ``time_us`` that wraps 1 s into the log is
    refused on one line naming the line and the wrap, and no estimates file is left."""
    log = reference[0].rename(columns={"time": "time_us"})
    log["time_us"] = (np.arange(len(log)) * 10_000 + 2**32 - 1_000_000) % 2**32
    log.to_csv(tmp_path / "log.csv", index=False)
    with pytest.raises(DataError) as err:
        run_log(heading, tmp_path / "log.csv", output=tmp_path / "e.csv")
    assert "\n" not in str(err.value), err.value
    assert "line 102: time 0.0 goes back from 4294.957296" in str(err.value), err.value
    assert "wraps at 2^32 us" in str(err.value), err.value
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv"]


def test_the_header_written_twice(heading, reference, tmp_path):
    """Two logs written into one file: the second header is named as the header again (it was 'not
    a number: time' alone).  A header written twice at the top is not read, and the note says so
    (it called the names the columns' units)."""
    log, expected = reference
    lines = lines_of(log)
    (tmp_path / "two.csv").write_text("\n".join([*lines[:201], lines[0], *lines[1:]]) + "\n")
    with pytest.raises(DataError, match=r"two\.csv line 202: column 'time' is .*: 'time' \(the header again: two "
                                        "logs written into one file"):
        run_log(heading, tmp_path / "two.csv")
    (tmp_path / "top.csv").write_text("\n".join([lines[0], *lines]) + "\n")
    result = run_log(heading, tmp_path / "top.csv")
    assert np.allclose(result.estimates["heading"], expected, rtol=0, atol=1e-12)
    assert any(n.endswith("top.csv line 2 repeats the header and is not read") for n in result.notes), result.notes
    assert not any("units" in n for n in result.notes), result.notes


def test_invisible_characters_around_names_are_stripped(heading, reference, tmp_path):
    """A zero-width space after 'gyro' (pasted from a web page) printed as 'gyro ' in 'missing
    column(s) gyro (columns: time, gyro , ...)'; it is stripped as spaces are."""
    log, expected = reference
    lines = lines_of(log)
    (tmp_path / "log.csv").write_text("\n".join(["time,gyro\u200b,\u2060odometry,compass\ufeff", *lines[1:]]) + "\n")
    got = run_log(heading, tmp_path / "log.csv").estimates
    assert list(got.columns[:1]) == ["time"] and np.allclose(got["heading"], expected, rtol=0, atol=1e-12)


def test_time_columns_named_as_arduino_and_others_name_them(heading, reference, tmp_path):
    """``time_millis`` is the time in milliseconds, as ``time_ms``; a column named ``millis`` (an
    Arduino's clock), ``elapsed_ms`` or ``ts`` is no time column, and the note that rows are taken
    one a tick names it with the options that read it."""
    log, expected = reference
    ms = log.rename(columns={"time": "time_millis"}).assign(time_millis=np.arange(len(log)) * 10)
    assert np.allclose(run_log(heading, ms).estimates["heading"], expected, rtol=0, atol=1e-12)
    for name, options in (("millis", "--time millis --time-unit ms"), ("elapsed_ms", "--time elapsed_ms"),
                          ("ts", "--time ts")):
        notes = run_log(heading, ms.rename(columns={"time_millis": name})).notes
        assert any(f"column {name!r} looks like a time: {options})" in n for n in notes), notes


def test_a_row_without_its_trailing_empty_cells_reads_them_as_empty(heading, reference, tmp_path):
    """A writer that leaves a row's trailing empty cells out (``2.5,0.61`` under four columns): the
    missing cells are empty, as in the same log written whole; a row of its time alone holds the gyro
    and the note on input gaps counts it (nothing is read in silence from another cell)."""
    log, expected = reference
    lines = lines_of(log)
    short = [*lines[:251], ",".join(lines[251].split(",")[:2]), *lines[252:]]
    assert log.iloc[250][["odometry", "compass"]].isna().all()  # the row's own trailing cells are empty
    (tmp_path / "short.csv").write_text("\n".join(short) + "\n")
    assert np.allclose(run_log(heading, tmp_path / "short.csv").estimates["heading"], expected, rtol=0, atol=1e-12)
    alone = [*lines[:251], lines[251].split(",")[0], *lines[252:]]
    (tmp_path / "alone.csv").write_text("\n".join(alone) + "\n")
    held = log.assign(gyro=log["gyro"].where(log.index != 250))
    result = run_log(heading, tmp_path / "alone.csv")
    assert np.allclose(result.estimates["heading"], run_log(heading, held).estimates["heading"], rtol=0, atol=1e-12)
    assert any(n.startswith("gyro (an input) has no reading at 1 of 400 ticks") for n in result.notes), result.notes


def _written(log, tmp_path, name, sep=",", decimal=".", header=None, extra=None):
    """``log`` written as a spreadsheet or logger writes it: separated by ``sep``, with ``decimal``
    points or commas, ``header`` instead of its names, one ``extra`` column of text after its own."""
    log = log.assign(**{extra: "a, b; c"}) if extra else log
    text = log.to_csv(index=False, sep=sep, decimal=decimal, header=header or True)
    (tmp_path / name).write_text(text)
    return tmp_path / name


@pytest.mark.parametrize("sep, decimal, name", [
    (";", ",", "temp, C"),   # a European spreadsheet: a name with a comma split the header at it
    ("\t", ".", "temp, C"),
    ("\t", ",", "note; x"),  # tab-separated, a semicolon in a name
    (",", ".", "note; x"),   # already read: the comma comes first
    (";", ",", None),        # already read: decimal commas, no separator in a name
])
def test_a_separator_written_in_a_name_does_not_split_the_header(heading, reference, tmp_path, sep, decimal, name):
    """The separator is the one that splits the header and the first row into as many cells: a
    semicolon or tab log with a comma in a name ('temp, C') was split at that comma and refused as
    'missing column(s) gyro, ...' beside the very names, or '3 cells under a header of 2 columns'."""
    log, expected = reference
    header = [*log.columns, name] if name else None
    path = _written(log, tmp_path, "log.csv", sep, decimal, header, "x" if name else None)
    got = run_log(heading, path).estimates
    assert np.allclose(got["heading"], expected, rtol=0, atol=1e-12)
    assert (name in got.columns) if name else True


def test_a_first_row_that_splits_at_commas_as_the_header_does_is_not_the_separator(tmp_path):
    """``time;gyro, rad/s`` over ``0;0,01``: both split into two cells at commas as at semicolons
    (a first row whose time is a whole number); the next row, ``0,01;0,02``, does not (it was read
    as comma-separated and refused: '3 cells under a header of 2 columns')."""
    from cfdesign.logs.read import read_log

    path = tmp_path / "tie.csv"
    path.write_text("time;gyro, rad/s\n0;0,01\n0,01;0,02\n0,02;0,03\n")
    got = read_log(path)
    assert list(got.columns) == ["time", "gyro, rad/s"] and got["gyro, rad/s"].tolist() == [0.01, 0.02, 0.03]


@pytest.mark.parametrize("sep, decimal", [(",", "."), (";", ",")])
def test_a_windows_spreadsheet_csv_is_read_with_its_names(heading, reference, tmp_path, sep, decimal):
    """A spreadsheet's "CSV (comma delimited)" on Windows is Windows-1252, not UTF-8: a unit in a
    name ('Temp [\u00b0C]', 't [\u00b5s]') or an accent in a text cell was refused as 'not UTF-8
    text'.  The log is read (the estimates as the UTF-8 file's), its names as written; a byte that is
    not UTF-8 after the first 64 kB of a UTF-8 log is still refused, naming it."""
    log, expected = reference
    log = log.assign(**{"Temp [\u00b0C]": 21.5, "note": ["caf\u00e9 \u20ac"] + [""] * (len(log) - 1)})
    path = tmp_path / "win.csv"
    path.write_bytes(log.to_csv(index=False, sep=sep, decimal=decimal).encode("cp1252"))
    got = run_log(heading, path).estimates
    assert np.allclose(got["heading"], expected, rtol=0, atol=1e-12)
    assert got["note"].iloc[0] == "caf\u00e9 \u20ac" and (got["Temp [\u00b0C]"] == 21.5).all()
    # the bytes that tell are in a comment line before an ASCII header; a byte Windows-1252 leaves unused later on
    commented = tmp_path / "commented.csv"
    commented.write_bytes(b"# logged at 25 \xb0C\n" + log.to_csv(index=False).encode("cp1252")[:-1] + b"\x81\n")
    assert np.allclose(run_log(heading, commented).estimates["heading"], expected, rtol=0, atol=1e-12)
    late = tmp_path / "late.csv"
    late.write_bytes(log.assign(note="x" * 200).to_csv(index=False).encode() + b"9,1,,,21.5,caf\xe9\n")
    with pytest.raises(DataError, match=r"not UTF-8 text \(byte e9 at byte \d+\)"):
        run_log(heading, late)


@pytest.mark.parametrize("before, gap, where", [
    (["# logger 1.2", "# 2024-05-01"], "gyro", "line 63"),  # two comment lines, the header, 59 rows
    (["sep=,"], "time", "line 62"),
    ([], "units", "line 62"),                              # the row of units under the header
    ([], "blank", "line 62"),                              # a blank line among the rows
    ([], "parquet", "row 60"),
])
def test_noise_names_the_line_of_the_file(tmp_path, before, gap, where):
    """``cfdesign noise`` named the row of an empty cell or a time jump as 'line row + 2', whatever
    came before the rows: comment lines, a ``sep=`` line, a row of units, blank lines, and a Parquet
    log's rows as lines.  It names them as ``cfdesign run`` does."""
    from cfdesign.allan import read_log_columns

    log = pd.DataFrame({"time": np.arange(100) * 0.01, "gyro": np.linspace(0.0, 1.0, 100)})
    bad = log.copy()
    if gap == "time":
        bad.loc[59:, "time"] += 5.0
    else:
        bad.loc[59, "gyro"] = np.nan
    if gap == "parquet":
        bad.to_parquet(tmp_path / "log.parquet", index=False)
        path = tmp_path / "log.parquet"
    else:
        lines = bad.to_csv(index=False).splitlines()
        lines = ([lines[0], "s,rad/s", *lines[1:]] if gap == "units" else
                 [*lines[:30], "", *lines[30:]] if gap == "blank" else lines)
        path = tmp_path / "log.csv"
        path.write_text("\n".join([*before, *lines]) + "\n")
    with pytest.raises(DataError, match=rf"log\.\w+ {where}: column '(gyro|time)' (is empty|jumps by)"):
        read_log_columns(path, ["gyro"], "time")


@pytest.mark.parametrize("header, times, unit, error", [
    ("time", np.arange(300) * 10, None, r"the times in 'time' step by 10 s \(0\.1 Hz\), read as seconds: times in "
                                        r"milliseconds.*give --time-unit ms\|us\|ns \(--time-unit s if they are"),
    ("time", 45413.5 + np.arange(300) * 0.01 / 86400, None, r"\(8\.64e\+06 Hz\), read as seconds: a spreadsheet's "
                                                            "date numbers"),
    ("time", np.arange(300) * 10, "ms", None),
    ("time", np.arange(300) * 10.0, "s", None),          # seconds said to be seconds: 0.1 Hz
    ("time [ms]", np.arange(300) * 10, None, None),
    ("time", pd.Timestamp("2024-05-01") + pd.to_timedelta(np.arange(300) * 2, unit="s"), None, None),  # dates
])
def test_noise_refuses_times_whose_unit_is_a_guess(tmp_path, header, times, unit, error):
    """``cfdesign noise`` on times in milliseconds read as seconds ran at 0.1 Hz, exit 0, with a note
    and every density off by sqrt(1000) (``cfdesign run`` refuses them against the table's rate); a
    spreadsheet's date numbers in days ran at 8.64 MHz without a word.  Numbers whose unit neither
    --time-unit, the name nor a row of units gives are refused outside 1 Hz .. 1 MHz."""
    from cfdesign.allan import read_log_columns

    pd.DataFrame({header: times, "gyro": np.sin(np.arange(300.0))}).to_csv(tmp_path / "log.csv", index=False)
    if error:
        with pytest.raises(DataError, match=error):
            read_log_columns(tmp_path / "log.csv", ["gyro"], header, unit)
    else:
        rate = read_log_columns(tmp_path / "log.csv", ["gyro"], header, unit)[0]
        assert rate == pytest.approx(100.0 if header.endswith("[ms]") or unit == "ms" else 0.1 if unit else 0.5)


def test_several_mappings_in_one_map_option_are_named(heading, reference, tmp_path, cli):
    """``--map a=x,b=y`` looked for one column named 'x,b=y' ('missing column(s) x,b=y (sensor a)'):
    the option takes one mapping, repeated."""
    log, _ = reference
    log.to_csv(tmp_path / "log.csv", index=False)
    code, _, err = cli("run", heading.save(tmp_path / "g.json"), tmp_path / "log.csv", "-o", tmp_path / "e.csv",
                       "--map", "gyro=gyro,compass=compass")
    assert code == 2 and "one SENSOR=COLUMN per --map; repeat it for each" in err and err.count("\n") == 1


def test_a_ros_export_runs_on_its_nanosecond_time_without_options(heading, reference):
    """``rostopic echo -p`` writes ``%time``, integer nanoseconds since 1970: taken as the time, in ns,
    without --time and --time-unit (it ran one row a tick, exit 0, with a note)."""
    log = reference[0].drop(index=[50, 51, 52]).reset_index(drop=True)  # three IMU rows lost: times tell
    expected = run_log(heading, log).estimates["heading"].to_numpy()
    ns = 1_700_000_000 * 10**9 + np.round(log["time"].to_numpy() * 1e9).astype(np.int64)
    ros = log.drop(columns=["time"]).assign(**{"%time": ns})[["%time", "gyro", "odometry", "compass"]]
    got = run_log(heading, ros).estimates
    assert np.allclose(got["heading"], expected, rtol=0, atol=1e-9) and got["%time"].tolist() == ns.tolist()



def test_a_time_named_in_camel_case_with_its_unit_gets_both_options(heading, reference):
    """ArduPilot's ``TimeUS`` (microseconds since boot) is no time column by its name: the note names
    ``--time TimeUS --time-unit us``, which run it (it named ``--time TimeUS`` alone, which read
    microseconds as seconds and stopped)."""
    log, expected = reference
    us = log.rename(columns={"time": "TimeUS"}).assign(TimeUS=23_456_789 + np.arange(len(log)) * 10_000)
    notes = run_log(heading, us).notes
    assert any("column 'TimeUS' looks like a time: --time TimeUS --time-unit us)" in n for n in notes), notes
    got = run_log(heading, us, time="TimeUS", time_unit="us").estimates["heading"]
    assert np.allclose(got, expected, rtol=0, atol=1e-12)
