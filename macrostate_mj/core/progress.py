"""Progress of long work: rich's bars on a terminal, plain log lines where there is none."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TaskID,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

LOG_EVERY = 10  # percent of a task between two plain lines
_quiet = False   # `macrostate-mj --quiet`: no bars, no log lines (errors and results still print)


def set_quiet(quiet: bool) -> None:
    global _quiet
    _quiet = quiet


def live() -> bool:
    """Whether long work may draw live bars: stderr is a terminal and `--quiet` is off."""
    return not _quiet and Console(stderr=True).is_terminal


class LoggedProgress(Progress):
    """rich's Progress on stderr (stdout stays for results such as `bench --json`).

    Where stderr is no terminal (nohup, CI, a batch job) rich's live bars show nothing until the
    end, so a two-hour `experiment oc` would leave an empty log; there each task with a known
    total also logs one line each time it completes another LOG_EVERY percent.
    """

    def __init__(self, *columns: Any, console: Console | None = None, **kwargs: Any) -> None:
        console = console or Console(stderr=True)
        self._plain = not console.is_terminal
        self._quiet = bool(kwargs.pop("disable", False)) or _quiet
        # no live display off a terminal: its final render would only repeat the logged lines
        super().__init__(*columns, console=console, disable=self._quiet or self._plain, **kwargs)
        self._logged: dict[TaskID, int] = {}  # last tenth logged; 0 % is not (see _log)

    def update(self, task_id: TaskID, **kwargs: Any) -> None:
        super().update(task_id, **kwargs)
        self._log(task_id)

    def advance(self, task_id: TaskID, advance: float = 1) -> None:
        super().advance(task_id, advance)
        self._log(task_id)

    def _log(self, task_id: TaskID) -> None:
        if not self._plain or self._quiet:
            return
        task = next((t for t in self.tasks if t.id == task_id), None)
        if task is None or not task.total:
            return
        step = int(min(task.percentage, 100.0) // LOG_EVERY)
        # nothing at 0 %: a bad input found as the work starts then stays a one-line error
        if step > self._logged.get(task_id, 0):
            self._logged[task_id] = step
            elapsed = task.elapsed or 0.0
            left = task.time_remaining
            eta = "" if left is None or step >= 10 else (
                f", about {left:.0f} s left" if left < 90 else f", about {left / 60:.0f} min left")
            self.console.print(f"{time.strftime('%H:%M:%S')} {task.description.strip()}: "
                               f"{task.percentage:.0f} % after {elapsed / 60:.1f} min{eta}",
                               highlight=False, markup=False, soft_wrap=True)


@contextlib.contextmanager
def sim_progress(total: float, label: str, unit: str = "sim s"
                 ) -> Iterator[Callable[[float], None]]:
    """Yield `advance(done)` that sets the bar to `done` of `total` (e.g. simulated seconds)."""
    columns = (TextColumn("{task.description}"), BarColumn(),
               TextColumn(f"{{task.completed:.0f}}/{{task.total:.0f}} {unit}"),
               TimeRemainingColumn())
    with LoggedProgress(*columns, transient=True) as bar:
        task = bar.add_task(label, total=total)

        def advance(done: float) -> None:
            bar.update(task, completed=min(total, done))

        yield advance


@contextlib.contextmanager
def stage_progress() -> Iterator[Callable[..., None]]:
    """Yield `report(stage, done, total=1.0)`: one bar per pipeline stage, kept when done."""
    with LoggedProgress(TextColumn("{task.description:<28}"), BarColumn(), TaskProgressColumn(),
                        TimeElapsedColumn(), TimeRemainingColumn()) as bar:
        tasks: dict[str, TaskID] = {}

        def report(stage: str, done: float, total: float = 1.0) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done)

        yield report
