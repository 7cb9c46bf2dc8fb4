"""Parallel tasks: results whatever the worker count; a dead worker is one clear failure."""

import os
import signal

import pytest

from macrostate_mj.core.errors import RunFailure
from macrostate_mj.core.parallel import local_results, render_threads


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
