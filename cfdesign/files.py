"""Writing files so that nothing is lost or half-written.

Every file cfdesign writes goes through :func:`write_files`: each is first written in full to
a temporary file beside its target (same directory, so the final rename is atomic on POSIX
and Windows), flushed and synced; only when *every* file of the set is complete are they
renamed into place, in turn.  A target that exists and is neither a regular file nor a directory
(``/dev/stdout``, ``/dev/null``, a pipe) is written into instead, after every file is staged and
before any is replaced: a rename would replace the device itself.  A failure while writing (a full disk, an unwritable
directory, a target that is a directory) removes the temporaries and leaves the previous
files untouched; only a failure between two renames of complete files on the same disk,
which does not happen in practice, could leave a set half replaced.  New
files get the permissions the user's umask gives an ordinary file (``0o666 & ~umask``), not
the owner-only mode of :func:`tempfile.mkstemp`.
"""

from __future__ import annotations

import contextlib
import contextvars
import glob
import os
import stat
import tempfile
from pathlib import Path

from .errors import OutputError

__all__ = ["write_files", "write_into", "write_text", "write_bytes", "open_atomic", "check_distinct", "is_dir",
           "read_limited", "not_a_device", "utf8_text", "path_of", "file_path", "temporaries",
           "run_tag"]


def is_dir(path) -> bool:
    """Whether ``path`` names an existing directory; False for a path that cannot name one.

    :meth:`pathlib.Path.is_dir` raises for a name longer than the system allows (``OSError``:
    File name too long) and for a NUL character (``ValueError``): both reached users as an
    internal error.  Here they are "not a directory", and the open or write that follows names
    the problem.

    Parameters
    ----------
    path : str or Path
        Any path.

    Returns
    -------
    bool
        True only for an existing directory (or a link to one).
    """
    try:
        return stat.S_ISDIR(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def read_limited(path, limit: int) -> bytes:
    """The bytes of a file, reading at most ``limit + 1`` of them.

    A size from ``stat`` says nothing of a device or a pipe (``/dev/zero`` has size 0 and no
    end): reading one whole took all the memory there was.

    Parameters
    ----------
    path : str or Path
        The file to read.
    limit : int
        The most bytes the caller takes.

    Returns
    -------
    bytes
        The whole file when it holds at most ``limit`` bytes; else its first ``limit + 1``
        bytes (the caller refuses it).

    Raises
    ------
    OSError
        The file cannot be opened or read.
    """
    with open(path, "rb") as fh:
        return fh.read(limit + 1)


def path_of(value, error, what: str) -> Path:
    """The path a loader was given, or ``error`` naming what it was given instead.

    ``load_spec(None)`` (or a number, a list) raised Python's TypeError from deep in
    ``pathlib``, and ``load_gains("")`` read the current directory ('.: Is a directory').

    Parameters
    ----------
    value : str, bytes or os.PathLike
        What the caller passed as the file.
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise.
    what : str
        What the message starts with: the function (``'load_spec'``), or ``'cannot write'``.

    Returns
    -------
    Path
        The path (bytes decoded as the file system does).

    Raises
    ------
    CfdesignError
        ``error``: ``value`` is not a path, or an empty or blank one.
    """
    if isinstance(value, (bytes, os.PathLike)):
        value = os.fsdecode(value)
    if not isinstance(value, str):
        raise error(f"{what}: {value!r:.60} is not a path (str or os.PathLike) but {type(value).__name__}")
    if not value.strip():
        raise error(f"{what}: {value!r} is empty or blank: it names no file")
    return Path(value)


def utf8_text(raw: bytes) -> str:
    """The text of a file cfdesign reads (a design file, a gain table): UTF-8, a byte-order mark
    dropped (some Windows editors write one; a gain table with one was refused).

    Parameters
    ----------
    raw : bytes
        The file's bytes.

    Returns
    -------
    str
        The text.

    Raises
    ------
    ValueError
        The bytes are not UTF-8 text: the message names the first bad byte and its offset, or
        the NUL bytes of UTF-16 (what Notepad's "Unicode" writes) or of a binary file.
    """
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw:
        kind = "is UTF-16 text" if raw.startswith((b"\xff\xfe", b"\xfe\xff")) else "holds NUL bytes (UTF-16 or binary)"
        raise ValueError(f"not UTF-8 text: it {kind}; save it as UTF-8")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text (byte {raw[exc.start:exc.start + 1].hex()} at byte {exc.start}, "
                         "Latin-1 or another code page?); save it as UTF-8") from None


def not_a_device(path) -> str | None:
    """Why ``path`` cannot be read as a file of data: it is a character or block device
    (``/dev/zero``, ``/dev/urandom``: endless), else None.  Pipes pass (``<(zcat log.gz)``).

    Parameters
    ----------
    path : str or Path
        Any path.

    Returns
    -------
    str or None
        ``'it is a device, not a file'``, or None.
    """
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None  # the open that follows names the problem
    return "it is a device, not a file" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else None


def check_distinct(named: dict, inputs=()):
    """Refuse a command whose files name one file twice (an output that is an input or another
    output would replace it: ``-o x.png --bode x.png`` lost the gain table; two inputs that are one
    file would be read twice: ``--join com.csv --join com.csv``).

    Parameters
    ----------
    named : dict
        ``{role: path}`` (``'-o'``, ``'--plot'``, ``'the gain table'``); ``None`` paths are skipped.
        Paths are the same when they resolve to one path or name one existing file (links).
    inputs : collection of str
        The roles that are read, not written: two of them that are one file are "given twice".

    Raises
    ------
    OutputError
        Two roles name the same file; the message names both.
    """
    items = [(role, Path(path)) for role, path in named.items() if path is not None and str(path) != ""]
    for i, (role, path) in enumerate(items):
        for other, earlier in items[:i]:
            if _same(path, earlier):
                why = "the same file given twice" if role in inputs and other in inputs else \
                    "one file for both, one would replace the other"
                raise OutputError(f"{role} {path} is {other} {earlier}: {why}")


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):  # one does not exist yet (or is a symlink loop, or has a NUL character)
        return os.path.realpath(a) == os.path.realpath(b)


def file_path(value) -> Path:
    """The path of a file to write: :func:`path_of`, and not a name ending in a slash.

    ``-o new/`` (a folder meant) wrote a file named ``new``: :class:`~pathlib.Path` drops the
    trailing slash.

    Parameters
    ----------
    value : str, bytes or os.PathLike
        What the caller passed as the file.

    Returns
    -------
    Path
        The path.

    Raises
    ------
    OutputError
        ``value`` is not a path, is empty, or ends in a slash (an existing directory named so is
        refused where it is written: 'it is a directory').
    """
    path = path_of(value, OutputError, "cannot write")
    text = os.fsdecode(value)
    if text.endswith(("/", os.sep)) and not is_dir(path):
        raise OutputError(f"cannot write {text}: a name ending in '/' names a directory, and this writes a file "
                          "(name the file)")
    return path


def _umask_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_files(contents: dict) -> list:
    """Write several files all-or-nothing.

    Parameters
    ----------
    contents : dict
        ``{path: bytes or str}``; text is written as UTF-8.

    Returns
    -------
    list of Path
        The paths written, in order.

    Raises
    ------
    OutputError
        A target is not a path, cannot be written (its directory is missing or read-only, it is
        a directory, the disk is full) or two targets are one file; no target was changed.
    """
    for path in contents:
        file_path(path)
    check_distinct({f"output {i + 1}": path for i, path in enumerate(contents)})
    _commit(contents, [])
    return [Path(path) for path in contents]


def _commit(contents: dict, staged: list):
    """Stage ``contents`` ``{path: bytes or str}`` beside ``staged``, ``[(path, complete temporary)]``,
    then put them all in place; every temporary left is removed, whatever stops it (an error, Ctrl-C)."""
    streams = []
    try:
        for path, data in contents.items():
            path, data = Path(path), data.encode("utf-8") if isinstance(data, str) else data
            if _special(path):
                streams.append((path, data))
            else:
                staged.append((path, _stage(path, data)))
        for path, data in streams:  # after every file is staged, before any is replaced
            _write_through(path, data)
        for path, tmp in staged:
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        for _, tmp in staged:
            Path(tmp).unlink(missing_ok=True)


def _special(path: Path) -> bool:
    """An existing target that is neither a regular file nor a directory: a device, a pipe or
    ``/dev/stdout``.  It is written into, never replaced: the rename of a temporary file put a
    regular file in place of ``/dev/null`` (as root), and ``-o /dev/stdout`` wrote no output."""
    try:
        mode = os.stat(path).st_mode  # through symlinks: /dev/stdout -> /proc/self/fd/1 -> a pipe
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def _write_through(path: Path, data: bytes):
    try:
        with open(path, "wb") as fh:
            fh.write(data)
    except BrokenPipeError:  # its reader went away (-o /dev/stdout | head): not an error of ours
        raise
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def _stage(path: Path, data: bytes) -> str:
    """``data`` in a complete temporary file beside ``path``; its name."""
    with _temporary(path, "wb") as (fh, tmp):
        fh.write(data)
    return tmp


#: the run whose temporary files this context writes (a fleet's worker), in their names
_RUN = contextvars.ContextVar("cfdesign_run", default="")


@contextlib.contextmanager
def run_tag(tag: str):
    """Name the temporary files written in the block after the run ``tag`` (``.NAME.TAG.XXXXXXXX.tmp``),
    for :func:`temporaries` to find that run's, and no other's, after its workers were killed.

    Parameters
    ----------
    tag : str
        Letters and digits naming the run.

    Yields
    ------
    None
        The block runs with the temporaries it writes named after ``tag``.
    """
    token = _RUN.set(tag)
    try:
        yield
    finally:
        _RUN.reset(token)


def temporaries(path, tag: str) -> list:
    """The temporary files of ``path`` that the run ``tag`` wrote (:func:`run_tag`) and left.

    A process stopped at once (``kill -9``, a Dask worker killed as its cluster closes) leaves the
    one it was writing; the next write of ``path`` takes a new name and is not confused by it.
    Another run's, perhaps being written at this moment into the same folder, are not listed.

    Parameters
    ----------
    path : str or Path
        The file written.
    tag : str
        The run's tag.

    Returns
    -------
    list of Path
        The temporaries.
    """
    path = Path(path)
    return list(path.parent.glob(f".{glob.escape(path.name)}.{glob.escape(tag)}.*.tmp"))


@contextlib.contextmanager
def _temporary(path: Path, mode: str, **kwargs):
    """A temporary file beside ``path``, complete (flushed, synced, umask mode) on a clean exit
    and removed on any error."""
    if is_dir(path):
        raise OutputError(f"cannot write {path}: it is a directory")
    try:
        run = _RUN.get()  # a fleet worker's: .NAME.RUN.XXXXXXXX.tmp
        fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".",
                                   prefix=f".{path.name}.{run}." if run else f".{path.name}.", suffix=".tmp")
    except (OSError, ValueError) as exc:  # ValueError: a NUL character in the path
        raise OutputError(f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh, tmp
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _umask_mode())
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def open_atomic(path, mode: str = "w", *, also=None, **kwargs):
    r"""Open a file for writing a stream (a large output), replacing it only on success.

    ``path`` is replaced only when the ``with`` block completes without error; else nothing
    changes.  The files of ``also`` are written with it, all or nothing (:func:`write_files`).

    Parameters
    ----------
    path : str or Path
        The file to write; it replaces ``path`` only when the block exits without an error.
    mode : str
        ``'w'`` (text) or ``'wb'``.
    also : dict, optional
        ``{path: bytes or str}`` of files that belong with this one (a plot of the estimates),
        read when the block ends, so it may be filled inside it; none replaces its file unless
        every one, and ``path``, is complete.
    **kwargs
        Passed to :func:`open` (``newline``, ``encoding``).

    Yields
    ------
    file object
        The temporary file to write.

    Raises
    ------
    OutputError
        The file cannot be written or moved into place.

    Examples
    --------
    >>> with open_atomic("estimates.csv", newline="") as fh:   # doctest: +SKIP
    ...     fh.write("time,heading\n")
    """
    path = file_path(path)
    also = {} if also is None else also
    if _special(path):  # a device or a pipe (/dev/stdout): written into, not replaced
        try:
            with open(path, mode, **kwargs) as fh:
                yield fh
        except BrokenPipeError:  # as for stdout: the reader went away
            raise
        except OSError as exc:
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
        write_files(also)
        return
    with _temporary(path, mode, **kwargs) as (fh, tmp):
        yield fh
    staged = [(path, tmp)]
    try:
        for other in also:
            file_path(other)
        check_distinct({"the file": path, **{f"output {i + 2}": p for i, p in enumerate(also)}})
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _commit(also, staged)


def write_text(path, text: str) -> Path:
    """Write one text file (UTF-8), atomically.

    Parameters
    ----------
    path : str or Path
        The file to write.
    text : str
        Its whole content.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    OutputError
        The file cannot be written; a previous file is left as it was.
    """
    return write_files({path: text})[0]


def write_bytes(path, data: bytes) -> Path:
    """Write one binary file, atomically.

    Parameters
    ----------
    path : str or Path
        The file to write.
    data : bytes
        Its whole content.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    OutputError
        The file cannot be written; a previous file is left as it was.
    """
    return write_files({path: data})[0]


def write_into(directory, texts: dict) -> list:
    """A set of files ``{file name: text}`` in ``directory`` (created if missing), all or nothing.

    Parameters
    ----------
    directory : str or Path
        The folder; created if it does not exist.
    texts : dict
        ``{file name: str or bytes}``.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    OutputError
        The directory cannot be created or a file cannot be written; no file was replaced.
    """
    directory = path_of(directory, OutputError, "cannot write")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file, a device, a dangling link: "File exists" named nothing
        raise OutputError(f"cannot write to {directory}: it exists and is not a directory (this writes a "
                          f"directory of {len(texts)} files: name a new or existing directory)") from None
    except OSError as exc:
        raise OutputError(f"cannot write to {directory}: {exc.strerror or exc}") from None
    return write_files({directory / name: text for name, text in texts.items()})
