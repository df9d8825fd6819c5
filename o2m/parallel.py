"""Independent fitting tasks (one per muscle or per path) on all cores, with a progress bar."""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")


def worker_context() -> Any:
    """fork where there is one (workers start at once, inherit what the parent imported, and the
    caller's script needs no ``__main__`` guard), else spawn."""
    return multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")


def map_with_progress(fn: Callable[[T], R], tasks: Sequence[T], *, workers: int | None = None, desc: str,
                      unit: str = "it", progress: bool = True) -> list[R]:
    """``[fn(t) for t in tasks]``, in order, on ``workers`` processes (default: all cores; in this
    process when that is 1), updating a tqdm bar as each task finishes. ``fn`` must be picklable
    (a module-level function) when more than one worker runs."""
    from tqdm.auto import tqdm

    workers = max(1, min(workers or os.cpu_count() or 1, len(tasks) or 1))
    out: list[R] = []
    with tqdm(total=len(tasks), desc=desc, unit=unit, disable=not progress) as bar:
        if workers == 1:
            for t in tasks:
                out.append(fn(t))
                bar.update()
        else:
            with ProcessPoolExecutor(max_workers=workers, mp_context=worker_context()) as pool:
                for r in pool.map(fn, tasks):
                    out.append(r)
                    bar.update()
    return out
