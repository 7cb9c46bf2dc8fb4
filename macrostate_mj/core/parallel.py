"""Independent tasks on local worker processes or a Ray cluster, results as they complete.

Tasks carry their own seeds, so a result never depends on the worker, process or machine that
computed it; callers order results themselves where order matters.
"""

from __future__ import annotations

import logging
import os
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from macrostate_mj.core.errors import RunFailure, UserError

Runner = Callable[[Callable[[Any], Any], Sequence[Any], int], Iterator[Any]]


def render_threads(workers: int) -> int:
    """llvmpipe threads per worker: the cores shared out, so that workers' renderers do not
    fight over the same cores (Mesa's default is one thread per core in every process)."""
    return max(1, (os.cpu_count() or 1) // workers)


def torch_threads(workers: int = 1) -> int:
    """torch threads per worker of the one-class runs: the cores shared out, at most 2 (their
    small convolutions gain little from more)."""
    return max(1, min(2, render_threads(workers)))


PARENT_POLL_S = 1.0     # how often a worker checks that its parent is alive


def _start_worker(threads: int, parent: int) -> None:
    """Worker initializer: runs before any GL context or torch exists in the worker, so each
    worker's renderer and torch use its share of the cores (two workers on two cores do not
    fight; an LP_NUM_THREADS or OMP_NUM_THREADS the user exported wins); and ends the worker
    once the `parent` that started it is gone (killed, say), rather than leave it computing
    as an orphan. Cached work is written atomically, so what it had half done is lost only."""
    os.environ.setdefault("LP_NUM_THREADS", str(threads))
    os.environ.setdefault("OMP_NUM_THREADS", str(threads))

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


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
                             initializer=_start_worker,
                             initargs=(render_threads(workers), os.getpid())) as pool:
        futures = [pool.submit(fn, t) for t in tasks]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        except BrokenProcessPool:
            raise RunFailure("a worker process died abruptly (a crash in native code); the "
                             "finished work is kept: rerun the same command to resume") from None


def ray_runner(address: str) -> Runner:
    """Connect to Ray: `local` starts an instance in this process (never joining a cluster
    already running here), `auto` finds this machine's cluster, HOST:PORT is a cluster's head
    (`ray start --head`). Every node needs this package installed (no runtime_env ships it: its
    native dependencies could not travel). A task travels pickled, its input files with it
    (`core.cache.ShipsFiles`), and returns its outputs as bytes, which the driver writes."""
    try:
        import ray
    except ImportError:
        raise UserError("--ray needs Ray: pip install 'macrostate-mj[ray]' (or pip install ray)"
                        ) from None
    if address not in ("local", "auto"):
        _check_head(address)
    try:
        ray.init(address=address, ignore_reinit_error=True, log_to_driver=False,
                 include_dashboard=False, logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError) as err:
        raise UserError(f"cannot connect to Ray at {address}: {err}".splitlines()[0]) from None

    def results(fn: Callable[[Any], Any], tasks: Sequence[Any], workers: int) -> Iterator[Any]:
        remote = ray.remote(num_cpus=1)(fn)
        pending = [remote.remote(t) for t in tasks]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            try:
                yield ray.get(ready[0])
            except ray.exceptions.RayTaskError as err:
                # the first failure is the one reported: the rest, dropped, are not printed
                os.environ.setdefault("RAY_IGNORE_UNHANDLED_ERRORS", "1")
                raise _task_error(err, address) from None

    return results


def _check_head(address: str) -> None:
    """Fail in one line, before `ray.init` retries for minutes, where no Ray head of ours
    answers at `address`: nothing listening, a head that wants a token this process lacks (one
    started where a Ray token exists, ~/.ray/auth_token), or a port that is not a head's. Ray
    connects to this machine's address for a loopback host (its head does not listen on
    127.0.0.1 alone), so that is where we look too."""
    target = _bootstrap(address)
    host, _, port = target.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host or "127.0.0.1", int(port)), timeout=3).close()
    except (OSError, ValueError):
        where = address if target == address else f"{address} (Ray connects to {target})"
        raise UserError(f"cannot reach a Ray cluster at {where}; start one with "
                        "`ray start --head` or pass --ray local") from None
    if address.startswith("ray://"):
        return
    try:
        from ray._raylet import GcsClient
        from ray.exceptions import AuthenticationError, RpcError
    except ImportError:         # another Ray: ray.init reports what it finds
        return
    saved = os.dup(2)           # the refusal is logged by Ray's C++ core, straight to fd 2
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            GcsClient(address=target)
    except AuthenticationError:
        raise UserError(f"the Ray cluster at {address} wants its token: export "
                        "RAY_AUTH_MODE=token and RAY_AUTH_TOKEN=<the token> (`ray get-auth-token` "
                        "on the head prints it), as on every node") from None
    except RpcError:
        raise UserError(f"no Ray head answers at {address}: give the port its `ray start "
                        "--head` printed (--port, 6379 by default)") from None
    except Exception:           # anything else: ray.init says what
        return
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _bootstrap(address: str) -> str:
    """The address `ray.init(address)` connects to (`localhost:P` becomes this machine's)."""
    if address.startswith("ray://"):
        return address
    try:
        from ray._private.services import canonicalize_bootstrap_address
        return canonicalize_bootstrap_address(address) or address
    except Exception:           # a Ray without it, or an address it cannot parse: as given
        return address


def _task_error(err: Exception, address: str) -> Exception:
    """A task's failure as the CLI reports it: a node without this package as a one-line
    `UserError` naming the fix; our own errors as themselves (as from local workers)."""
    cause = getattr(err, "cause", None)
    if isinstance(cause, UserError | RunFailure):
        return cause
    missing = _missing_module(err)
    if missing is not None:
        return UserError(f"a node of the Ray cluster at {address} cannot import {missing}: "
                         "install macrostate-mj there, in the environment its `ray start` runs "
                         "from (pip install 'macrostate-mj[ray]')")
    return err


def _missing_module(err: Exception) -> str | None:
    """The module a task's worker could not import, if that is why it failed: Ray wraps the
    `ModuleNotFoundError` (in a `RaySystemError` when it was the task's arguments that could
    not be unpickled), so its text is the last resort."""
    seen: Any = err
    for _ in range(4):
        if isinstance(seen, ModuleNotFoundError):
            return seen.name
        seen = getattr(seen, "cause", None) or getattr(seen, "client_exc", None)
    found = re.search(r"ModuleNotFoundError: No module named '([\w.]+)'", str(err))
    return found.group(1) if found else None


def runner_for(ray_address: str | None) -> Runner:
    return ray_runner(ray_address) if ray_address else local_results
