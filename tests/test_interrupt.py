"""A command stopped by a signal (Ctrl-C, SIGTERM, SIGHUP) leaves no temporary file, keeps the
previous outputs, prints one line and exits 128 + the signal; a fleet's workers leave nothing."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cfdesign import files
from cfdesign.cli import main
from cfdesign.errors import DataError
from cfdesign.logs import fleet, run_log
from cfdesign.logs import write as write_mod
from cfdesign.signals import disposed

posix = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="SIGTERM/SIGHUP handlers need POSIX signals")

#: the child: ``cfdesign export`` whose fsync of the staged table says 'ready' and waits to be signalled
CHILD = """
import os, sys, time
sys.modules["rfc3987_syntax"] = None  # as cfdesign.cli.console: jsonschema without its 1 s IRI checker
import cfdesign.files as files
def fsync(fd):
    print("ready", flush=True)
    time.sleep(30)
files.os = type("os", (), {**{k: getattr(os, k) for k in dir(os) if not k.startswith("__")}, "fsync": fsync})
if len(sys.argv) > 3:
    import signal
    signal.signal(getattr(signal, sys.argv[3]), signal.SIG_IGN)
from cfdesign.cli import main
sys.exit(main(["export", sys.argv[1], "--format", "json", "-o", sys.argv[2]]))
"""


def _log(n=600):
    t = np.arange(n) * 0.01
    odo = np.where(np.arange(n) % 10 == 3, 0.3 * t, np.nan)
    com = np.where(np.arange(n) % 100 == 37, 0.3 * t, np.nan)
    return pd.DataFrame({"time": t, "gyro": np.full(n, 0.3), "odometry": odo, "compass": com})


def _signalled(tmp_path, table_path, sig):
    out = tmp_path / "out.json"
    out.write_text("PREVIOUS")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(table_path), str(out)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env)
    assert child.stdout.readline() == "ready\n"  # the table staged in its temporary file
    child.send_signal(sig)
    _, err = child.communicate(timeout=60)
    return child.returncode, err, out, sorted(p.name for p in tmp_path.iterdir())


@posix
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGHUP"])
def test_sigterm_and_sighup_remove_the_temporary_and_keep_the_previous_output(heading, tmp_path, sig):
    """Python died of SIGTERM and SIGHUP at once (exit -15, -1, nothing said), leaving
    ``.out.json.XXXX.tmp`` beside the output; now as Ctrl-C: cleaned up, one line, 128 + N."""
    table = tmp_path / "g.json"
    heading.save(table)
    status, err, out, files = _signalled(tmp_path, table, getattr(signal, sig))
    assert status == 128 + getattr(signal, sig)
    assert err == f"cfdesign: interrupted ({sig})\n"
    assert out.read_text() == "PREVIOUS"
    assert files == ["g.json", "out.json"]


@posix
def test_a_signal_the_process_ignores_stays_ignored(heading, tmp_path):
    """``nohup cfdesign ...``: SIGHUP ignored before the command starts must not stop it."""
    table = tmp_path / "g.json"
    heading.save(table)
    child = CHILD.replace('    time.sleep(30)\n', '    time.sleep(0.5)\n    return os.fsync(fd)\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen([sys.executable, "-c", child, str(table), str(tmp_path / "o.json"), "SIGHUP"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout.readline() == "ready\n"
    proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert (tmp_path / "o.json").read_text() == table.read_text()


@posix
def test_main_puts_back_the_handlers_it_found():
    """The handlers are the command's alone: a process calling main() keeps its own."""
    mine = lambda signum, frame: None  # noqa: E731
    before = signal.signal(signal.SIGTERM, mine), signal.signal(signal.SIGHUP, signal.SIG_DFL)
    try:
        assert main(["prove", "cf2", "--json"]) == 0
        assert signal.getsignal(signal.SIGTERM) is mine
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, before[0])
        signal.signal(signal.SIGHUP, before[1])


def test_ctrl_c_as_a_compressed_estimates_file_closes_removes_its_temporary(heading, tmp_path, monkeypatch):
    """The writer closed its compressor, then the file: a KeyboardInterrupt (or a full disk) in the
    compressor's close left ``.e.csv.gz.XXXX.tmp`` and its descriptor open for as long as the
    exception was kept (a notebook keeps the last one: ``sys.last_traceback``)."""
    class Stopping:
        def __init__(self, fh):
            self.fh = fh

        def __getattr__(self, name):
            return getattr(write_mod._gzip(self.fh), name) if name != "close" else self._close

        def write(self, data):
            return len(data)

        def _close(self):
            raise KeyboardInterrupt

    monkeypatch.setitem(write_mod._PACK, ".gz", Stopping)
    out = tmp_path / "e.csv.gz"
    out.write_bytes(b"PREVIOUS")
    with pytest.raises(KeyboardInterrupt) as kept:
        run_log(heading, _log(), output=out)
    assert out.read_bytes() == b"PREVIOUS"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.csv.gz"]
    assert kept.value is not None  # (held until here: its frames hold the writer)


def test_an_interrupted_run_replaces_its_plot_and_estimates_together_or_neither(heading, tmp_path, monkeypatch):
    """The plot was put in place before the estimates' last flush: Ctrl-C then left a new plot
    beside the previous estimates (the second fsync: the estimates' before, the plot's now)."""
    pytest.importorskip("matplotlib")
    import cfdesign.files as files

    calls = []

    def fsync(fd):
        calls.append(fd)
        if len(calls) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(files.os, "fsync", fsync)
    est, png = tmp_path / "e.csv", tmp_path / "p.png"
    est.write_text("PREVIOUS")
    png.write_text("PREVIOUS")
    with pytest.raises(KeyboardInterrupt):
        run_log(heading, _log(), output=est, plot=png)
    assert est.read_bytes() == png.read_bytes() == b"PREVIOUS"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.csv", "p.png"]


def test_an_interrupted_fleet_removes_what_its_killed_workers_were_writing(heading, tmp_path, monkeypatch):
    """A worker still writing as the cluster closes is killed (after Dask's wait): it left
    ``.a.csv.XXXX.tmp`` of 60 MB beside a 2-million-row log's estimates.  Another run's older
    temporary stays."""
    pytest.importorskip("dask.distributed")
    old = tmp_path / "out" / ".b.csv.older123.tmp"
    old.parent.mkdir()
    old.write_text("another run's")
    os.utime(old, (time.time() - 60, time.time() - 60))

    live = old.parent / ".b.csv.0123abcd4567.xyz98765.tmp"  # another run's, writing now into the same folder

    def killed(dask, Client, LocalCluster, table, paths, targets, *args):
        live.write_text("being written")
        (targets[0].parent / f".{targets[0].name}.{args[-1]}.abcd1234.tmp").write_text("half")  # this run's
        raise KeyboardInterrupt

    monkeypatch.setattr(fleet, "_run_on_dask", killed)
    with pytest.raises(KeyboardInterrupt):
        fleet.run_logs(heading, [tmp_path / "a.csv", tmp_path / "b.csv"], tmp_path / "out")
    assert sorted(p.name for p in old.parent.iterdir()) == sorted([old.name, live.name])


def test_a_fleet_worker_writes_its_temporaries_under_its_run_s_tag(heading, tmp_path, monkeypatch):
    """What the parent removes after an interruption is named by its run: two fleet runs at once into
    one folder, the first interrupted removed the second's temporaries as they were being written."""
    seen = []

    def fake_run_log(table, path, output, **kwargs):
        with files.open_atomic(output):
            seen.extend(p.name for p in Path(output).parent.iterdir() if p.suffix == ".tmp")
        raise DataError("stop")

    monkeypatch.setattr(fleet, "run_log", fake_run_log)
    row = fleet._run_one(heading, str(tmp_path / "a.csv"), tmp_path / "e.csv", {}, "feed0123beef")
    assert row["error"] == "stop"
    assert len(seen) == 1 and seen[0].startswith(".e.csv.feed0123beef.") and seen[0].endswith(".tmp")
    assert files.temporaries(tmp_path / "e.csv", "feed0123beef") == []  # completed: moved into place


@posix
def test_a_fleet_s_worker_processes_ignore_ctrl_c_and_the_stops_its_parent_handles():
    """Ctrl-C at a terminal signals every process of its group: each Dask worker printed a
    traceback; SIGTERM or SIGHUP to all (systemd, Slurm, a closed terminal) killed them mid-file."""
    probe = "import signal as s; print([s.getsignal(x) == s.SIG_IGN for x in (s.SIGINT, s.SIGTERM, s.SIGHUP)])"
    before = {s: signal.getsignal(s) for s in fleet._STOPS}
    with disposed(fleet._STOPS, signal.SIG_IGN):
        seen = subprocess.run([sys.executable, "-S", "-c", probe], capture_output=True, text=True).stdout
    assert seen == "[True, True, True]\n"
    assert {s: signal.getsignal(s) for s in fleet._STOPS} == before
