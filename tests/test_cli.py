"""The cfdesign command: outputs, exit codes, one-line errors."""

import json
import subprocess
import sys

import pytest

from cfdesign.cli import build_parser, main, parse_gains


def run(*args, cwd=None):
    """The command in this process (``cwd``: run from that folder)."""
    import os

    from conftest import run_cli

    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        return run_cli(*args)
    finally:
        os.chdir(old)


def test_the_entry_points_start(tmp_path):
    """The installed command and ``python -m cfdesign`` (the only subprocesses of these tests)."""
    proc = subprocess.run([sys.executable, "-m", "cfdesign", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("cfdesign ")
    proc = subprocess.run([sys.executable, "-m", "cfdesign", "verify", str(tmp_path / "none.json")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.startswith("cfdesign: error:") and "Traceback" not in proc.stderr


def test_prove_json_keys_and_exit_zero(capsys):
    assert main(["prove", "dckf3", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["variable"] == "z" and data["holds"] is True and data["sum"] == "1"
    assert set(data["bands"]) == {"gyro", "compass", "odometry"}


@pytest.mark.parametrize("argv", [["cf2"], ["cf2", "--order", "2"], ["cf3"], ["ckf3"], ["cfn", "--bands", "5"]])
def test_prove_text(argv, capsys):
    assert main(["prove", *argv]) == 0
    out = capsys.readouterr().out
    assert "HOLDS" in out and "sum - 1" in out


def test_prove_failing_structure_exits_one(monkeypatch, capsys):
    import sympy as sp

    from cfdesign import Observer, symbolic
    from cfdesign.symbolic.observer import T

    def broken():
        d = symbolic.dckf3()
        return Observer(d.F, sp.Matrix([T / 2, 0]), d.H, d.K, d.sensors, domain="z", name="broken")

    monkeypatch.setitem(symbolic.STRUCTURES, "dckf3", broken)
    assert main(["prove", "dckf3", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["holds"] is False


def test_bode_writes_png(tmp_path):
    out = tmp_path / "b.png"
    code, _, stderr = run("bode", "dckf3", "--gains", "k11=0.3,k12=0.2,k21=0.01,k22=0.02",
                               "--sample-time", "0.2", "-o", str(out))
    assert code == 0, stderr
    assert out.stat().st_size > 10_000


@pytest.mark.parametrize("args, message", [
    (["prove", "cf9"], "unknown structure"),
    (["bode", "cf3", "--gains", "k1=2", "-o", "x.png"], "needs a value for gain(s) k2"),
    (["bode", "cf3", "--gains", "k1=2,k2=1,k9=3", "-o", "x.png"], "no gain(s) k9"),
    (["bode", "cf3", "--gains", "k1=2,k2=abc", "-o", "x.png"], "must be a number"),
    (["bode", "cf3", "--gains", "k1=2,k2=__import__('os')", "-o", "x.png"], "must be a number"),
    (["bode", "cf3", "--gains", "k1=2,k2=1", "--sample-time", "0.1", "-o", "x.png"], "continuous"),
    (["bode", "dckf3", "--gains", "k11=1,k12=1,k21=1,k22=1", "--sample-time", "0", "-o", "x.png"], "positive"),
    (["bode", "dckf3", "--gains", "k11=1,k12=1,k21=1,k22=1", "--sample-time", "-0.1", "-o", "x.png"], "positive"),
    (["bode", "dckf3", "--gains", "k11=1,k12=1,k21=1,k22=1", "-o", "x.png"], "--sample-time"),
    (["bode", "cf3", "--gains", "k1=2,k2=nan", "-o", "x.png"], "must be a number"),
    (["prove"], "required"),
])
def test_user_errors_one_line_no_traceback(args, message, tmp_path):
    code, _, stderr = run(*args, cwd=tmp_path)
    assert code == 2
    assert stderr.count("\n") == 1 and "Traceback" not in stderr
    assert message in stderr
    assert not (tmp_path / "x.png").exists()


def test_parse_gains_exact():
    from sympy import Rational

    assert parse_gains("k1=0.1, k2=1/3") == {"k1": Rational(1, 10), "k2": Rational(1, 3)}


@pytest.mark.parametrize("paper", ["carreira", "seed001"])
def test_reproduce_carreira_json_under_its_name_and_its_former_name(paper, capsys):
    """``seed001`` is the former name of ``carreira``: same command, same JSON."""
    assert main(["reproduce", paper, "--runs", "1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["paper"] == "carreira" and data["runs"] == 1 and len(data["tables"]["II"]) == 6


def test_reproduce_help_lists_the_papers_by_name_not_the_aliases():
    code, stdout, _ = run("reproduce", "--help")
    assert code == 0
    assert "carreira" in stdout and "helicopter" in stdout and "compare" in stdout
    assert "seed0" not in stdout


def test_reproduce_unknown_paper_lists_the_papers_by_name_not_the_aliases():
    """An unknown paper: one line, exit 2, the current names only (the aliases were listed)."""
    code, _, stderr = run("reproduce", "nosuch")
    assert code == 2 and len(stderr.strip().splitlines()) == 1, stderr
    assert "'nosuch'" in stderr and all(name in stderr for name in ("carreira", "helicopter", "compare"))
    assert "seed0" not in stderr


def test_reproduce_heading_counts_one_run_and_says_why_its_interval_is_missing():
    """``--runs 1`` printed ``1 runs (seeds 0..0)`` beside an unexplained ``-`` interval."""
    from cfdesign.reproduce.report import runs_text

    assert runs_text((7,)) == "1 run (seed 7; no 95% interval from one run)"
    assert runs_text(tuple(range(3, 23))) == "20 runs (seeds 3..22)"


def test_design_help_names_every_built_in_example():
    """``--example`` accepts every key of ``EXAMPLES``; its help says so (``dckf3`` was left out)."""
    from cfdesign.spec import EXAMPLES

    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["design"]
    text = " ".join(next(a for a in sub._actions if a.dest == "example").help.split())
    assert all(name in text.replace(",", " ").split() for name in EXAMPLES), text


def test_design_names_the_state_of_its_predicted_std_and_the_phase_of_a_multirate_one(cli):
    """The printed std is state 0's (position), and for a multirate table the worst phase's,
    beside its RMS over the period (what the error of a log averages to)."""
    code, out, err = cli("design", "--example", "position")
    assert code == 0, err
    line = next(x for x in out.splitlines() if "<- the default output" in x)
    assert "std of position" in line and "at the worst phase" in line and "RMS over the period" in line


def test_noise_reads_the_parquet_log_its_help_names(tmp_path):
    """``cfdesign noise`` reads Parquet as ``cfdesign run`` does; its help said "CSV log"."""
    import numpy as np
    import pandas as pd

    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["noise"]
    assert "Parquet" in next(a for a in sub._actions if a.dest == "log").help
    rng = np.random.default_rng(0)
    pd.DataFrame({"t": np.arange(5_000) / 100.0, "gyro": 0.01 * rng.standard_normal(5_000)}).to_parquet(
        tmp_path / "static.parquet")
    code, out, err = run("noise", str(tmp_path / "static.parquet"), "--column", "gyro", "--time", "t")
    assert code == 0, err
    assert out.startswith("gyro: 50 s at 100 Hz")


@pytest.mark.parametrize("hidden, args, hint", [
    (["matplotlib.pyplot"], ["bode", "cf3", "--gains", "k1=2,k2=1", "-o", "x.png"], "pip install matplotlib"),
    (["matplotlib.pyplot"], ["design", "-o", "g.json", "--bode", "x.png"], "pip install matplotlib"),
    (["pyarrow", "pyarrow.parquet"], ["run", "GAINS", "log.csv", "-o", "x.parquet"], 'pip install "cfdesign[logs]"'),
    (["pyarrow", "pyarrow.parquet"], ["noise", "log.parquet", "--column", "gyro", "--rate-hz", "5"],
     'pip install "cfdesign[logs]"'),
])
def test_a_missing_dependency_is_named_on_one_line_with_its_install(hidden, args, hint, tmp_path, monkeypatch):
    """Without matplotlib (or pyarrow beside pandas) a command said "internal error ... please report
    it" (exit 3); it is the installation's: one line naming what to install, exit 2, nothing written."""
    import numpy as np
    import pandas as pd

    from cfdesign import design
    from cfdesign.spec import example_path, load_spec

    gains = tmp_path / "gains.json"
    design(load_spec(example_path("dckf3"))).save(gains)
    log = pd.DataFrame({"time": np.arange(50) * 0.2, "gyro": 0.0, "compass": 0.1, "odometry": 0.1})
    log.to_csv(tmp_path / "log.csv", index=False)
    log.to_parquet(tmp_path / "log.parquet")
    before = sorted(p.name for p in tmp_path.iterdir())
    for name in hidden:
        monkeypatch.setitem(sys.modules, name, None)
    code, _, err = run(*[str(gains) if a == "GAINS" else a for a in args], cwd=tmp_path)
    assert code == 2 and err.count("\n") == 1 and "internal error" not in err, err
    assert err.startswith("cfdesign: error:") and hint in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_missing_module_of_cfdesign_itself_stays_an_internal_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "cfdesign.plot", None)
    code, _, err = run("bode", "cf3", "--gains", "k1=2,k2=1", "-o", "x.png", cwd=tmp_path)
    assert code == 3 and "internal error" in err and not (tmp_path / "x.png").exists()


def test_discrete_help_names_the_structures_it_changes(capsys):
    """``--discrete`` named ``position``, which is discrete with or without it."""
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["prove"]
    text = next(a for a in sub._actions if a.dest == "discrete").help
    named = text.split(":")[0].replace(",", " ").split()
    extra = {"cfn": ["--bands", "3"]}
    for structure in ("cf2", "cf3", "ckf3", "dckf3", "cfn", "position"):
        variables = []
        for flag in ([], ["--discrete"]):
            code = main(["prove", structure, *extra.get(structure, []), *flag, "--json"])
            out = capsys.readouterr().out
            variables.append(json.loads(out)["variable"] if code == 0 else None)
        assert (variables == ["s", "z"]) == (structure in named), (structure, variables, text)


def test_standard_output_on_a_full_disk_is_an_error_of_the_output_not_a_bug(monkeypatch, capsys):
    """``cfdesign prove cf2 > /dev/full`` said 'internal error ... please report it' (exit 3): a full
    disk under stdout is told on one line as an output error (exit 2).  An OSError of another kind
    is still a bug."""
    import errno
    import io

    class Full(io.StringIO):
        def flush(self):
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("cfdesign.cli._quiet_stdout", lambda: None)  # (pytest's capture has no real descriptor)
    class FullAtOnce(io.StringIO):  # /dev/full: the write itself fails, which argparse ignored (exit 0)
        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

    for stream in (Full, FullAtOnce):
        monkeypatch.setattr(sys, "stdout", stream())
        for argv in (["prove", "cf2"], ["--version"], ["run", "--help"]):  # argparse's own output too
            assert main(argv) == 2, (stream, argv)
            assert capsys.readouterr().err == "cfdesign: error: cannot write to standard output: " \
                                              "No space left on device\n"

    class Broken(io.StringIO):
        def flush(self):
            raise OSError(errno.EBADF, "Bad file descriptor")

    monkeypatch.setattr(sys, "stdout", Broken())
    assert main(["prove", "cf2"]) == 3
    assert "internal error (OSError" in capsys.readouterr().err
