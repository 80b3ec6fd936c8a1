"""How many threads the numerical libraries under the toolkit use: BLAS on one thread by default.

The closed loop's dense algebra is small (the law's and the KDE's products at the paper's size,
NMPC's quadratic programs), and OpenBLAS spreading a small product over two cores makes the
threads fight: an NMPC run of 4 time units took 22.8 s unpinned against 1.9 s on one thread
(issue "Speed where users wait").  :func:`limited_blas` holds BLAS to :func:`blas_threads` threads
(``threadpoolctl``) while a run steps; ``MEANFIELD_BLAS_THREADS`` (or ``meanfield run --threads``)
chooses another count.  One thread also keeps a run's numbers independent of the machine's cores.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

from meanfield.errors import ParameterError

__all__ = ["ENV", "blas_threads", "limited_blas"]

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
