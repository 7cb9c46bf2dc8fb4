"""Parallel tasks: results whatever the worker count; a dead worker is one clear failure."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from macrostate_mj.core.errors import RunFailure
from macrostate_mj.core.parallel import PARENT_POLL_S, local_results, render_threads


def square(x: int) -> int:
    return x * x


def die(x: int) -> int:
    os.kill(os.getpid(), signal.SIGKILL)      # what a native crash looks like to the pool
    return x


def test_results_are_the_same_for_one_and_two_workers():
    assert sorted(local_results(square, range(6), 1)) == sorted(local_results(square, range(6), 2))
    assert render_threads(2) >= 1


def test_a_worker_that_dies_is_a_run_failure_not_a_traceback():
    with pytest.raises(RunFailure, match="rerun the same command"):
        list(local_results(die, [1, 2], 2))


def _children(pid: int) -> set[int]:
    """Live (not zombie) processes whose parent is `pid`."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_end_when_their_parent_is_killed():
    """A killed run (SIGKILL: no cleanup of its own) leaves no worker computing as an orphan."""
    parent = subprocess.Popen([sys.executable, "-c", "import time\n"
                               "from macrostate_mj.core.parallel import local_results\n"
                               "list(local_results(time.sleep, [120, 120], 2))"])
    try:
        deadline = time.monotonic() + 60
        while len(workers := _children(parent.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
        assert len(workers) >= 2
        time.sleep(1.0)                     # the workers are up and sleeping in their task
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 10 * PARENT_POLL_S
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers)
