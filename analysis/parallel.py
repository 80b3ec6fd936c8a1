"""Run independent closed-loop jobs over worker processes, with a progress bar."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")

__all__ = ["map_jobs"]


def map_jobs(
    fn: Callable[[Any], T], jobs: Sequence[Any], workers: int | None, desc: str, progress: bool
) -> list[T]:
    """``[fn(job) for job in jobs]`` over ``workers`` processes (default: the cores; 1: here).

    ``fn`` must be a module-level function (it is pickled).  Results keep the jobs' order.
    """
    from tqdm.auto import tqdm

    workers = workers or os.cpu_count() or 1
    out: list[T] = []
    with tqdm(total=len(jobs), disable=not progress, desc=desc, unit="run") as bar:
        if workers == 1 or len(jobs) <= 1:
            for job in jobs:
                out.append(fn(job))
                bar.update()
        else:
            with ProcessPoolExecutor(min(workers, len(jobs))) as ex:
                for r in ex.map(fn, jobs):
                    out.append(r)
                    bar.update()
    return out
