"""Compiling the loops on several cores the first time: numba's cache filled by forked processes.

The compiled loops (:mod:`meanfield._compiled.core`) compile on their first call and are read from
numba's on-disk cache by every later process. On a new machine the first closed loop
therefore compiles them all, one after the other, on one core: about 4.5 s for the paper's
step, of which the law alone is about 2 s (docs page *Scale*). Numba compiles one function
at a time per process (a global lock), so the only way to use a second core is a second
process.

:func:`compile_in_parallel` does that for a block of code that is about to compile: if,
inside the block, a loop is about to compile with nothing in numba's on-disk cache, the
process first forks one child per *task* (say, the controller's first call and the crowd's
first step). Each child runs its task, which compiles that part's loops and writes them to
the cache, and exits; the block goes on compiling its own loops meanwhile. When the block
ends (or later, when the caller says: ``wait=False``), the children are awaited, and the loops
they compiled are then read from the cache instead of being compiled a second time. A task works
on the child's copy of the process (a fork), so nothing it changes reaches the parent: the run's
results are the same with or without this.

Nothing is forked (and the block runs as before) unless all of these hold: the block
compiles a loop whose cache is empty (a warm cache costs one index read), the platform is
Linux (``os.fork``), at least two CPUs are usable, this is the main thread and no other
Python thread runs (a fork copies only the calling thread: a lock another thread held, numba's
compiler lock say, would stay held in the child), the compiled path is on, and
``MEANFIELD_PARALLEL_COMPILE`` is not ``0``. It happens at most once per process. A child
that fails or takes longer than ``timeout`` seconds is dropped (killed if need be); whatever
it did not cache, the parent compiles when it needs it, as without this.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
import warnings
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from meanfield._compiled import core as compiled

__all__ = ["compile_in_parallel", "parallel_compile_possible", "ENV"]

ENV = "MEANFIELD_PARALLEL_COMPILE"
"""``MEANFIELD_PARALLEL_COMPILE=0`` (or ``false``/``no``/``off``): never fork to compile."""

_used = False  # at most once per process


def _usable_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def parallel_compile_possible() -> bool:
    """Whether :func:`compile_in_parallel` may fork here (all its conditions but the cache's)."""
    return (
        not _used
        and os.environ.get(ENV, "1").strip().lower() not in {"0", "false", "no", "off"}
        and sys.platform.startswith("linux")
        and hasattr(os, "fork")
        and threading.current_thread() is threading.main_thread()
        and threading.active_count() == 1
        and _usable_cpus() >= 2
        and compiled.enabled()
    )


def _fork(task: Callable[[], Any]) -> int | None:
    """Run ``task`` in a forked child that exits without returning here; its pid (None: no fork)."""
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        with warnings.catch_warnings():  # (Python >= 3.12 warns about forking a threaded process)
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
    except OSError:
        return None
    if pid:
        return pid
    status = 1
    try:  # the child: quiet, never back into the caller's code, no atexit handlers
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        warnings.simplefilter("ignore")
        task()
        status = 0
    finally:
        os._exit(status)


def _await(pids: list[int], timeout: float) -> None:
    """Wait for the children, at most ``timeout`` seconds in all; kill those still running."""
    deadline = time.monotonic() + timeout
    waiting = list(pids)
    try:
        while waiting:
            for pid in list(waiting):
                try:
                    done, _ = os.waitpid(pid, os.WNOHANG)
                except ChildProcessError:  # (reaped elsewhere)
                    done = pid
                if done:
                    waiting.remove(pid)
            if waiting:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.01)
    finally:  # a timeout, or Ctrl-C while waiting: no child outlives the wait
        for pid in waiting:
            try:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            except (ProcessLookupError, ChildProcessError):
                pass


class Compilers:
    """The children a :func:`compile_in_parallel` block forked (none if it forked nothing), until reaped.

    :meth:`wait` reaps them, waiting at most until the block's ``timeout`` runs out (counted from the
    block's end) and killing those still running then.  Children never waited for are killed when the
    process exits (or this object is collected): what they had cached stays cached.
    """

    def __init__(self, timeout: float) -> None:
        self.pids: list[int] = []
        self.timeout = timeout
        self._deadline: float | None = None
        weakref.finalize(self, _await, self.pids, 0.0)

    def _start_clock(self) -> None:
        self._deadline = time.monotonic() + self.timeout

    def wait(self) -> None:
        """Reap the children (at once if there are none, or if they were already reaped)."""
        if self.pids:
            deadline = self._deadline if self._deadline is not None else time.monotonic() + self.timeout
            _await(self.pids, max(0.0, deadline - time.monotonic()))
        self.pids.clear()


@contextmanager
def compile_in_parallel(
    tasks: Sequence[Callable[[], Any]], timeout: float = 60.0, *, wait: bool = True
) -> Iterator[Compilers]:
    """Run the block; if it meets a loop with an empty cache, compile ``tasks`` in forked children meanwhile.

    Parameters
    ----------
    tasks : sequence of callables
        Each is called with no argument in its own child process, which then exits; what it
        returns or raises is dropped. A task should call the part of the code whose loops
        the block does *not* compile (the block's own loops compile in the parent). All run at
        the parent's priority: with three processes on two cores, the block and the longest
        task finish soonest when they share the cores evenly.
    timeout : float
        Seconds to wait for the children after the block, in all (then they are killed).
    wait : bool
        True: the block's end waits for the children. False: it does not; the caller waits with
        the yielded :class:`Compilers` (``.wait()``) just before it calls what the tasks compile,
        and meanwhile goes on with work of its own (whatever it compiles there, it compiles
        itself, beside the children).

    Yields
    ------
    Compilers
        The children forked (none when nothing was).

    Examples
    --------
    ``ClosedLoop`` computes the first density (the KDE's loops) while the controller's and
    the crowd's first steps compile in two children::

        with compile_in_parallel([controller_first_call, crowd_first_step]):
            density = crowd.density()

    When that density compiled nothing (the Fokker-Planck crowd's), it forked nothing, and the
    first step's act (the law, here) runs as ``with compile_in_parallel([crowd_first_step])``.
    """
    children = Compilers(timeout)
    if not tasks or not parallel_compile_possible():
        yield children
        return

    def fork_tasks() -> None:
        global _used
        _used = True
        compiled.prepare_compiler()  # once here rather than once in every child
        for task in tasks:
            pid = _fork(task)
            if pid is not None:
                children.pids.append(pid)

    unregister = compiled.before_cold_compile(fork_tasks)
    try:
        yield children
    except BaseException:
        _await(children.pids, 0.0)  # an error in the block (Ctrl-C, say): the children are killed at once
        children.pids.clear()
        raise
    finally:
        unregister()
        children._start_clock()
    if wait:
        children.wait()
