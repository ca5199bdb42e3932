"""One BLAS thread for the small dense problems of a design.

OpenBLAS (the BLAS of numpy's and scipy's wheels) hands even a 2 x 2 LU back-substitution to
its worker threads.  On a machine whose cores are busy - a robot computer running other nodes,
a CI runner, ``pytest -n auto`` - every such call waits for a core: measured here with both
cores loaded, ``scipy.linalg.lapack.dgetrs`` on a 2 x 2 took 20 ms instead of 1 us, and the
first :func:`cfdesign.nav.estimate_attitude` call (ten 2-state channel designs) 1.2 s instead
of 0.12 s.  Designs and Riccati solves of up to :data:`SMALL` states therefore run with one
BLAS thread (threadpoolctl, scoped to the call); larger ones keep the library's threads, except
in loops of many solves each too small to share (:func:`one_thread`: the band responses' solve per
frequency).
Without threadpoolctl the calls run unchanged.
"""

from __future__ import annotations

import contextlib
import functools

import numpy as np

SMALL = 64
"""Largest state dimension whose solves run with one BLAS thread."""


@functools.cache
def _controller():
    """threadpoolctl's view of the loaded BLAS libraries (scipy's loaded first), or None."""
    try:
        import scipy.linalg  # noqa: F401  (loads scipy's BLAS so that it is controlled too)
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


class _OneThread:
    """Set the given BLAS libraries to one thread on entry and back to their counts on exit."""

    def __init__(self, busy):
        self.busy = busy  # [(library controller, its thread count)]

    def __enter__(self):
        for lib, _ in self.busy:
            lib.set_num_threads(1)
        return self

    def __exit__(self, *exc):
        for lib, threads in self.busy:
            lib.set_num_threads(threads)
        return False


def single_thread(n: int):
    """A context in which BLAS runs one thread when ``n <= SMALL`` (else nothing changes).

    Only the BLAS libraries running more than one thread are touched, directly through their
    controllers: threadpoolctl's ``limit`` re-reads every library's state on each call (24.5
    against 9.6 us per entry and exit with two OpenBLAS pools of two threads).

    Parameters
    ----------
    n : int
        The state dimension of the problem about to be solved.

    Returns
    -------
    contextlib.AbstractContextManager

    Examples
    --------
    >>> from cfdesign.blas import single_thread
    >>> with single_thread(2):
    ...     pass
    """
    return one_thread() if n <= SMALL else contextlib.nullcontext()


def one_thread():
    """A context in which BLAS runs one thread, whatever the problem's size.

    For loops of many solves each too small to share among threads: the per-frequency solves of
    :func:`cfdesign.linear.band_responses` (a verify of an n = 200 chain took 13.9 s with two
    OpenBLAS threads on a loaded 2-core machine, 0.30 s with one).

    Returns
    -------
    contextlib.AbstractContextManager
    """
    controller = _controller()
    if controller is None:
        return contextlib.nullcontext()
    busy = [(lib, threads) for lib in controller.lib_controllers
            if lib.user_api == "blas" and (threads := lib.num_threads) > 1]
    # nothing to limit (OPENBLAS_NUM_THREADS=1, one core): no context to enter
    return _OneThread(busy) if busy else contextlib.nullcontext()


def _states(A) -> int:
    """The state dimension of ``A`` (a matrix or a list of them; 0 when it has no shape)."""
    try:
        shape = np.shape(A)
    except (ValueError, TypeError):
        return 0
    return int(shape[-1]) if shape else 0


def small_problem(fn):
    """Decorate a solver whose first argument is the state matrix (or a list of them): it runs
    under :func:`single_thread` of that matrix's size."""

    @functools.wraps(fn)
    def wrapper(A, *args, **kwargs):
        with single_thread(_states(A)):
            return fn(A, *args, **kwargs)

    return wrapper
