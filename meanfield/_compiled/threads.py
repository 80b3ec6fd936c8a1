"""How many threads the numerical libraries under the toolkit use: BLAS on one thread, the crowd's loops on every core.

The closed loop's dense algebra is small (the law's and the KDE's products at the paper's size,
NMPC's quadratic programs), and OpenBLAS spreading a small product over two cores makes the
threads fight: an NMPC run of 4 time units took 22.8 s unpinned against 1.9 s on one thread
(issue "Speed where users wait").  :func:`limited_blas` holds BLAS to :func:`blas_threads` threads
(``threadpoolctl``) while a run steps; ``MEANFIELD_BLAS_THREADS`` (or ``meanfield run --threads``)
chooses another count.  One thread also keeps a run's numbers independent of the machine's cores.

The crowd's per-human loops (the field at each human, the noise and Euler–Maruyama, the binning)
run on numba's threads, every core by default (numba's ``NUMBA_NUM_THREADS``); :func:`set_loop_threads`
(``meanfield run --crowd-threads``) uses fewer.  Their results do not depend on the count
(:data:`meanfield._compiled.core.PARALLEL_CHUNK`).

A command's counts hold while it runs (:func:`command_threads`): ``meanfield.cli.app.main(["run", ...,
"--threads", "2"])`` called from Python leaves the caller's variable and loop threads as they were.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

from meanfield.errors import ParameterError

__all__ = ["ENV", "blas_threads", "command_threads", "limited_blas", "loop_threads", "set_loop_threads"]

ENV = "MEANFIELD_BLAS_THREADS"
"""The environment variable that sets the BLAS threads of a run (default 1)."""


def blas_threads() -> int:
    """The BLAS threads a run uses: ``MEANFIELD_BLAS_THREADS``, 1 when it is unset.

    Raises
    ------
    ParameterError
        Named ``MEANFIELD_BLAS_THREADS`` when it is not an integer >= 1.
    """
    text = os.environ.get(ENV, "").strip()
    if not text:
        return 1
    if not text.isdigit() or int(text) < 1:
        raise ParameterError(ENV, text, "an integer >= 1 (the BLAS threads of a run)")
    return int(text)


@contextmanager
def limited_blas(threads: int | None = None) -> Iterator[int]:
    """Hold the BLAS libraries loaded in this process to ``threads`` threads (default
    :func:`blas_threads`) inside the block; the previous counts come back after it."""
    from threadpoolctl import threadpool_limits

    n = blas_threads() if threads is None else int(threads)
    with threadpool_limits(limits=n, user_api="blas"):
        yield n


def loop_threads() -> int | None:
    """The threads of the compiled loops' ``prange`` (numba's ``get_num_threads``); None on the numpy path."""
    from meanfield._compiled.core import enabled

    if not enabled():
        return None
    import numba

    return int(numba.get_num_threads())


def set_loop_threads(threads: int) -> None:
    """Run the compiled loops' ``prange`` on ``threads`` threads from now on (nothing on the numpy path).

    Raises
    ------
    ParameterError
        Named ``threads`` when it is not an integer from 1 to numba's ``NUMBA_NUM_THREADS`` (the cores by default).
    """
    from meanfield._compiled.core import enabled

    if not enabled():
        return
    import numba

    most = int(numba.config.NUMBA_NUM_THREADS)
    if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= most:
        raise ParameterError("threads", threads, f"an integer from 1 to {most} (numba's NUMBA_NUM_THREADS)")
    numba.set_num_threads(threads)


@contextmanager
def command_threads(blas: int | None = None, loops: int | None = None) -> Iterator[None]:
    """Inside the block, ``MEANFIELD_BLAS_THREADS`` is ``blas`` and the compiled loops run on ``loops`` threads (None:
    as they are); after it, the variable (set or unset) and the loops' count are as they were.

    ``meanfield run --threads N --crowd-threads M``: a command's threads end with the command, in its own process
    and in a Python caller of :func:`meanfield.cli.app.main` alike (until 2026-12-07 the variable stayed set in the
    caller, and every later run there held BLAS to ``N`` threads).

    Raises
    ------
    ParameterError
        As :func:`set_loop_threads`, for a bad ``loops``.
    """
    env = os.environ.get(ENV)
    before = loop_threads()
    try:
        if blas is not None:
            os.environ[ENV] = str(int(blas))
        if loops is not None:
            set_loop_threads(loops)
        yield
    finally:
        if env is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = env
        if loops is not None and before is not None:
            import numba

            numba.set_num_threads(before)
