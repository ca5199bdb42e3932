"""Many logs on Dask: :func:`~cfdesign.logs.run_logs` and its ``summary.csv``."""

from __future__ import annotations

import logging
import os
import secrets
import signal
from pathlib import Path

from ..errors import CfdesignError, DataError, require_extra
from ..files import run_tag, temporaries, write_text
from ..gains import require_table
from ..signals import disposed
from .columns import _first_line
from .run import _same_file, run_log

#: how the summary of :func:`run_logs` begins the error of a log that met a fault of cfdesign, not of the log
INTERNAL = "internal error"


#: Dask settings of the local cluster of :func:`run_logs` (a batch job with no dashboard), each measured
#: on 8 logs of a million rows, 2 workers on 2 cores:
#:
#: - Dask's local workers start with ``MALLOC_TRIM_THRESHOLD_=65536`` (so that freed memory goes back to
#:   the system at once): every block's arrays then come fresh from the kernel, page by page, and a log
#:   of 500,000 rows ran 1.75 times slower in a worker (1.26 against 0.72 s).  The workers keep glibc's
#:   own adaptive threshold (None unsets a variable of Dask's list); a MALLOC_TRIM_THRESHOLD_ of the
#:   user's environment still reaches them.  Memory stays bounded by the blocks
#:   (:data:`~cfdesign.logs.run.BLOCK_ROWS`) either way.
#: - A worker samples its running task's stack every 10 ms for the dashboard's profile, and checks its
#:   memory every 100 ms and the machine's every 500 ms; with as many workers as cores these threads
#:   take the cores' time from the logs (8.9 against 7.9 s).  No profile; memory every second (the
#:   memory limits still hold), the machine every 5 s.
_CLUSTER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                   "distributed.worker.profile.enabled": False,
                   "distributed.worker.memory.monitor-interval": "1s",
                   "distributed.admin.system-monitor.interval": "5s"}


#: the endings of a compressed file's name, left off the names of the estimate files of a fleet
_PACKED_SUFFIXES = (".gz", ".bz2", ".xz", ".zip")


def _log_stem(path) -> str:
    """A log's name without its extensions: ``flight`` of ``flight.csv``, ``flight.csv.gz``.

    Parameters
    ----------
    path : str or Path
        The log.

    Returns
    -------
    str
        The name an estimate file of a fleet takes (:func:`run_logs`) before its own suffix.
    """
    path = Path(path)
    if path.suffix.lower() in _PACKED_SUFFIXES:
        path = Path(path.stem)
    return path.stem


def run_logs(table, paths, outdir, *, workers=None, scheduler=None, suffix=".csv", **options) -> list:
    """Run a table on many logs in parallel on Dask; write one estimate file per log and a
    summary table (``summary.csv``: one row per log) in ``outdir`` (created if missing).

    Parameters
    ----------
    table : GainTable
        The gain table every log is run through.
    paths : list of str or Path
        The logs (CSV or Parquet).
    outdir : str or Path
        Folder the estimates are written to, one file per log.
    workers : int, optional
        Processes of a local Dask cluster (default: the number of CPUs).
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``) instead of a local cluster.
    suffix : str
        Extension of the estimate files (``.csv`` or ``.parquet``).
    **options
        As :func:`run_log` (time, mapping, reference, std, prediction).

    Returns
    -------
    list of dict
        The summary rows, in the order of ``paths``; a log that could not be run has ``error``:
        its one-line message, beginning with :data:`INTERNAL` for a fault of cfdesign.

    Raises
    ------
    GainTableError
        ``table`` is not a GainTable (a path: read it with :func:`~cfdesign.gains.load_gains`).
    CfdesignError
        Dask is not installed, ``workers`` and ``scheduler`` are both given, the scheduler
        cannot be reached, ``outdir`` cannot be created, the local workers did not start (a
        script that calls ``run_logs`` outside ``if __name__ == "__main__":``, which every
        worker process imports again), or the table cannot run any log (a continuous or
        unstable table, as :func:`run_log` and :class:`~cfdesign.runtime.Runtime` refuse it),
        named before the workers start.
    DataError
        Two logs of the same name (their estimates would overwrite each other), or a log
        that cannot be run (as :func:`run_log`).
    """
    require_table(table, "run_logs")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise CfdesignError(f"workers must be a positive number of processes, got {workers!r}")  # (-1 hangs Dask)
    if workers is not None and scheduler:
        raise CfdesignError("workers and scheduler exclude each other: an existing scheduler has its own workers")
    dask = require_extra("dask", "running many logs needs Dask")
    distributed = require_extra("dask.distributed", "running many logs needs Dask")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    outdir = Path(outdir)
    targets = [outdir / (_log_stem(p) + suffix) for p in paths]
    first = {}
    for i, t in enumerate(targets):
        j = first.setdefault(t, i)
        if j != i:
            raise DataError(f"{paths[j]} and {paths[i]} have the same name; their estimates would both be {t}")
    same = [str(p) for p, t in zip(paths, targets, strict=True) if _same_file(p, t)]
    if same:
        raise DataError(f"{same[0]}: its estimates would replace the log itself (write them to another folder, "
                        "or with another --format)")
    environ = dict(os.environ)  # Dask's settings for its workers (one BLAS thread, ...) are left in it: put back
    run = secrets.token_hex(6)  # names this run's temporary files: another run's in outdir are not removed
    try:
        rows = _run_on_dask(dask, Client, LocalCluster, table, paths, targets, outdir, workers, scheduler, options,
                            run)
    except BaseException:  # Ctrl-C, ...: the local workers, closed, may have been killed writing an estimate file
        if not scheduler:
            for tmp in (tmp for t in targets for tmp in temporaries(t, run)):
                tmp.unlink(missing_ok=True)
        raise
    finally:
        _put_back(environ)
    write_text(outdir / "summary.csv", _summary_csv(rows))
    return rows


def _put_back(environ: dict):
    """``os.environ`` as ``environ``: Dask's nanny sets its workers' settings (``OMP_NUM_THREADS=1``, ...) in
    the environment of the process that starts them, where a notebook's later subprocesses would inherit them."""
    for k in set(os.environ) - set(environ):
        del os.environ[k]
    for k, v in environ.items():
        if os.environ.get(k) != v:
            os.environ[k] = v


def _run_on_dask(dask, Client, LocalCluster, table, paths, targets, outdir, workers, scheduler, options,
                 run) -> list:
    """The logs' summary rows, each log run by :func:`_run_one` on the scheduler's workers, or on a local cluster's."""
    from ..runtime.filter import Runtime

    # a table no log can run (continuous, unstable, no posterior) is named once, before the workers start
    Runtime(table, output="prior" if options.get("prediction") else None)
    if scheduler:
        try:
            client, cluster = Client(scheduler), None
        except (OSError, ValueError, TypeError) as exc:  # unreachable or not an address: the user's to fix
            raise CfdesignError(f"cannot connect to the Dask scheduler {scheduler}: {_first_line(exc)}") from None
    else:
        _refuse_in_worker_start()
        # no dashboard; the scheduler's HTTP server on a free port of this machine: on 8787, its default, it
        # warned on stderr when another cluster (another fleet run at the same time) had that port; the
        # workers start ignoring _STOPS (inherited through exec): one sent during the start (a second or two) is lost
        with dask.config.set(_CLUSTER_CONFIG), disposed(_STOPS, signal.SIG_IGN):
            try:
                cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                       processes=True, dashboard_address=None,
                                       scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                       silence_logs=logging.ERROR)  # no shutdown warnings
            except RuntimeError as exc:  # Dask's "Nanny failed to start." once a worker process died starting
                raise CfdesignError(f"the local Dask workers did not start ({_first_line(exc)}): {_GUARD}") from None
        client = Client(cluster)
    try:
        try:  # once connected: an unreachable scheduler leaves no empty folder
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CfdesignError(f"cannot create {outdir}: {exc.strerror or exc}") from None
        futures = [client.submit(_run_one, table, str(p), str(t), options, run, pure=False)
                   for p, t in zip(paths, targets, strict=True)]
        rows = client.gather(futures, errors="skip")  # what still fails is an internal error of that log
        done = {r["log"]: r for r in rows}
        rows = [done.get(str(p)) or {"log": str(p), "samples": 0, "error": _failure(f)}
                for p, f in zip(paths, futures, strict=True)]
    finally:
        dask_log = logging.getLogger("distributed")  # closing: a slow worker is killed after 4 s, which it
        level = dask_log.level                          # logged as a WARNING on stderr (a busy machine, not a fault)
        dask_log.setLevel(logging.ERROR)
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        finally:
            dask_log.setLevel(level)
    return rows


#: why local workers fail to start from a script, and what to do (Python's "safe importing of the main module")
_GUARD = ('a script that calls run_logs must do so under if __name__ == "__main__": (each worker process '
          "starts by importing the script again)")


def _refuse_in_worker_start():
    """Refuse to start a cluster inside a worker process that is still importing the user's script.

    Dask starts its local workers with the ``spawn`` method: each imports the parent's main module
    again before it runs.  A script that calls :func:`run_logs` at its top level, unguarded, would then
    start a cluster inside every worker while that worker starts, and Dask failed with pages of
    tracebacks from each process and "Nanny failed to start" in the parent.  Here the worker process
    (doomed, never the user's own) exits at once with one line naming the fix; the parent then fails
    to start its cluster and raises the same as a :class:`CfdesignError`.
    """
    import multiprocessing.process

    if getattr(multiprocessing.process.current_process(), "_inheriting", False):  # spawn's bootstrap flag
        raise SystemExit(f"cfdesign: {_GUARD}")  # printed as one line by the worker, without a traceback


#: the signals a local cluster's worker processes ignore: Ctrl-C at a terminal (SIGINT to every process of
#: the foreground group) printed a traceback of each worker, a closed terminal (SIGHUP) or SIGTERM to every
#: process (systemd, Slurm) killed them mid-file; the process that started them stops as told and closes them
_STOPS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def _failure(future) -> str:
    try:
        exc = future.exception()
    except Exception as e:  # noqa: BLE001 - a cancelled future reports why
        exc = e
    return str(exc).splitlines()[0] if exc else "failed"


def _run_one(table, path, target, options, run=""):
    """Run one log in a worker, its temporary files named after the ``run``; the table arrives
    pickled, as checked by the parent (a worker that validated it again against the JSON schema
    imported jsonschema, 1 s of its first log where jsonschema's optional IRI checker,
    rfc3987_syntax, is installed)."""
    try:
        with run_tag(run):
            return run_log(table, path, output=target, source=path, **options).summary()
    except CfdesignError as exc:  # a bad log is a row of the summary, not a failed task (no worker traceback)
        return {"log": path, "samples": 0, "error": _first_line(exc)}
    except Exception as exc:  # noqa: BLE001 - a fault of cfdesign on one log: the others still run
        # a failed task printed Dask's traceback of it and summarised it as the bare exception ("'__index_level_0__'")
        return {"log": path, "samples": 0, "error": f"{INTERNAL} ({type(exc).__name__}: {_first_line(exc)}); "
                                                    "please report it with the log"}


def _summary_csv(rows) -> str:
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    lines = [",".join(keys)]
    for r in rows:
        lines.append(",".join(_cell(r.get(k, "")) for k in keys))
    return "\n".join(lines) + "\n"


def _cell(v) -> str:
    if isinstance(v, float):
        return repr(v)
    text = str(v)
    return '"' + text.replace('"', '""') + '"' if ("," in text or '"' in text or "\n" in text) else text
