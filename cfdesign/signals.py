"""Signal dispositions for the length of a block, put back after it.

The command (:func:`cfdesign.cli.main`) stops on SIGTERM and SIGHUP as on Ctrl-C, so that its
temporary files are removed; a fleet's local workers (:func:`cfdesign.logs.run_logs`) are started
ignoring the signals a terminal or a job scheduler sends to every process of the group, so that
the process that started them stops them.  Both set dispositions for a block and restore them.
"""

from __future__ import annotations

import contextlib
import signal

__all__ = ["disposed"]


@contextlib.contextmanager
def disposed(signals, disposition, *, only_default: bool = False):
    """Give each of ``signals`` ``disposition`` while the block runs; the previous ones after it.

    Parameters
    ----------
    signals : iterable of int
        The signals (``signal.SIGTERM``, ...).
    disposition : callable or signal.SIG_IGN
        A handler ``(signum, frame)`` or ``signal.SIG_IGN`` (a disposition to ignore is inherited
        by the processes the block starts, through ``exec``).
    only_default : bool
        Leave alone a signal whose disposition is not the default one: a signal the process
        ignores stays ignored (``nohup``), a handler of the user's stays.

    Yields
    ------
    None
        The block, run with the dispositions.  Outside the main thread, where Python sets no
        handler, nothing changes.

    Examples
    --------
    >>> import signal
    >>> from cfdesign.signals import disposed
    >>> before = signal.getsignal(signal.SIGTERM)
    >>> with disposed([signal.SIGTERM], signal.SIG_IGN):
    ...     signal.getsignal(signal.SIGTERM) == signal.SIG_IGN
    True
    >>> signal.getsignal(signal.SIGTERM) == before
    True
    """
    previous = {}
    try:
        for signum in signals:
            if not only_default or signal.getsignal(signum) == signal.SIG_DFL:
                previous[signum] = signal.signal(signum, disposition)
    except ValueError:  # not the main thread
        pass
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
