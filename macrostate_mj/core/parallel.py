"""Independent tasks on local worker processes or a Ray cluster, results as they complete.

Tasks carry their own seeds, so a result never depends on the worker, process or machine that
computed it; callers order results themselves where order matters.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from macrostate_mj.core.errors import RunFailure, UserError

Runner = Callable[[Callable[[Any], Any], Sequence[Any], int], Iterator[Any]]


def render_threads(workers: int) -> int:
    """llvmpipe threads per worker: the cores shared out, so that workers' renderers do not
    fight over the same cores (Mesa's default is one thread per core in every process)."""
    return max(1, (os.cpu_count() or 1) // workers)


def _pin_render_threads(threads: int) -> None:
    """Worker initializer: runs before any GL context or torch exists in the worker, so each
    worker's renderer and torch use its share of the cores (two workers on two cores do not
    fight). An LP_NUM_THREADS or OMP_NUM_THREADS the user exported wins."""
    os.environ.setdefault("LP_NUM_THREADS", str(threads))
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))


def local_results(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int
                  ) -> Iterator[Any]:
    """In this process for one worker; else a spawn-started process pool (no forked GL), each
    worker's software renderer pinned to its share of the cores."""
    if workers == 1 or len(tasks) <= 1:
        for task in tasks:
            yield fn(task)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                             initializer=_pin_render_threads,
                             initargs=(render_threads(workers),)) as pool:
        futures = [pool.submit(fn, t) for t in tasks]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        except BrokenProcessPool:
            raise RunFailure("a worker process died abruptly (a crash in native code); the "
                             "finished work is kept: rerun the same command to resume") from None


def ray_runner(address: str) -> Runner:
    """Connect to Ray (`local` starts one in-process, `auto` finds this machine's cluster)."""
    try:
        import ray
    except ImportError:
        raise UserError("--ray needs Ray: pip install 'macrostate-mj[ray]' (or pip install ray)"
                        ) from None
    if address not in ("local", "auto"):
        host, _, port = address.removeprefix("ray://").rpartition(":")
        try:
            socket.create_connection((host or "127.0.0.1", int(port)), timeout=3).close()
        except (OSError, ValueError):
            raise UserError(f"cannot reach a Ray cluster at {address}; start one with "
                            "`ray start --head` or pass --ray local") from None
    try:
        ray.init(address=None if address == "local" else address, ignore_reinit_error=True,
                 log_to_driver=False, include_dashboard=False)
    except (ConnectionError, RuntimeError) as err:
        raise UserError(f"cannot connect to Ray at {address}: {err}".splitlines()[0]) from None

    def results(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int) -> Iterator[Any]:
        remote = ray.remote(num_cpus=1)(fn)
        pending = [remote.remote(t) for t in tasks]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])

    return results


def runner_for(ray_address: str | None) -> Runner:
    return ray_runner(ray_address) if ray_address else local_results
