"""Progress of long work: rich's bars on a terminal, plain log lines where there is none.

The estimate of the time left is this module's own, not rich's: rich's speed is taken over the
updates of the last 30 s, so two workers finishing together, or a resumed run whose cached work
arrives at once, make it wildly short (a collection of 8 episodes said "about 5 s left" with
43 s to go). Here the rate is that of the work done *in this run* (`completed` less the
`cached` part a resumed run found): the slope of a least-squares line through every
(time, work done) point once there are three, so that neither the workers' start-up (paid
before the first result) nor results that arrive in pairs sway it; before that, the work done
over the time since the task began.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    ProgressColumn,
    Task,
    TaskID,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
)
from rich.text import Text

LOG_EVERY = 10  # percent of a task between two plain lines
_quiet = False   # `macrostate-mj --quiet`: no bars, no log lines (errors and results still print)


def set_quiet(quiet: bool) -> None:
    global _quiet
    _quiet = quiet


def live() -> bool:
    """Whether long work may draw live bars: stderr is a terminal and `--quiet` is off."""
    return not _quiet and Console(stderr=True).is_terminal


class Rate:
    """Running least-squares sums of a task's (elapsed s, own work done) points, kept in the
    task's fields by `LoggedProgress`; a point is taken each time the work done grows."""

    def __init__(self) -> None:
        self.n, self.t, self.d, self.tt, self.td, self.last = 0, 0.0, 0.0, 0.0, 0.0, 0.0

    def add(self, elapsed: float, done: float) -> None:
        if done > self.last:
            self.last = done
            self.n += 1
            self.t, self.d = self.t + elapsed, self.d + done
            self.tt, self.td = self.tt + elapsed * elapsed, self.td + elapsed * done

    def slope(self) -> float | None:
        """Work per second through the points, from three of them on."""
        if self.n < 3:
            return None
        var = self.tt - self.t * self.t / self.n
        cov = self.td - self.t * self.d / self.n
        return cov / var if var > 0 and cov > 0 else None


def remaining(task: Task) -> float | None:
    """Seconds left at the rate of this run's own work (None before any); a task's `cached`
    field is the part of `completed` a resumed run found done, its `rate` a `Rate`."""
    done = task.completed - task.fields.get("cached", 0.0)
    elapsed = task.elapsed
    if not task.total or done <= 0 or not elapsed:
        return None
    left = max(0.0, task.total - task.completed)
    rate = task.fields.get("rate")
    slope = rate.slope() if isinstance(rate, Rate) else None
    return left / slope if slope else left * elapsed / done


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "-:--:--"
    whole = int(round(seconds))
    return f"{whole // 3600}:{whole // 60 % 60:02d}:{whole % 60:02d}"


class RemainingColumn(ProgressColumn):
    """The time left by `remaining`."""

    def render(self, task: Task) -> Text:
        return Text(_clock(None if task.finished else remaining(task)),
                    style="progress.remaining")


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
        self._logged: dict[TaskID, int] = {}  # last tenth logged; 0 % is not (see _line)

    @classmethod
    def get_default_columns(cls) -> tuple[ProgressColumn, ...]:
        """rich's default columns with this module's estimate of the time left."""
        return (*super().get_default_columns()[:-1], RemainingColumn())

    def update(self, task_id: TaskID, **kwargs: Any) -> None:
        super().update(task_id, **kwargs)
        self._log(task_id)

    def _log(self, task_id: TaskID) -> None:
        task = next((t for t in self.tasks if t.id == task_id), None)
        if task is not None and task.elapsed is not None:
            task.fields["rate"].add(task.elapsed, task.completed - task.fields.get("cached", 0))
        self._line(task)

    def add_task(self, description: str, *args: Any, **fields: Any) -> TaskID:
        return super().add_task(description, *args, rate=Rate(), **fields)

    def reset(self, task_id: TaskID, **kwargs: Any) -> None:
        super().reset(task_id, rate=Rate(), **kwargs)
        self._logged.pop(task_id, None)

    def advance(self, task_id: TaskID, advance: float = 1) -> None:
        super().advance(task_id, advance)
        self._log(task_id)

    def _line(self, task: Task | None) -> None:
        if not self._plain or self._quiet:
            return
        if task is None or not task.total:
            return
        step = int(min(task.percentage, 100.0) // LOG_EVERY)
        # nothing at 0 %: a bad input found as the work starts then stays a one-line error
        if step > self._logged.get(task.id, 0):
            self._logged[task.id] = step
            elapsed = task.elapsed or 0.0
            left = remaining(task)
            eta = "" if left is None or step >= 10 else (
                f", about {left:.0f} s left" if left < 90 else f", about {left / 60:.0f} min left")
            self.console.print(f"{time.strftime('%H:%M:%S')} {task.description.strip()}: "
                               f"{task.percentage:.0f} % after {elapsed / 60:.1f} min{eta}",
                               highlight=False, markup=False, soft_wrap=True)


@contextlib.contextmanager
def sim_progress(total: float, label: str, unit: str = "sim s"
                 ) -> Iterator[Callable[..., None]]:
    """Yield `advance(done, cached=0)` that sets the bar to `done` of `total` (e.g. simulated
    seconds), `cached` of them found done by a resumed run."""
    columns = (TextColumn("{task.description}"), BarColumn(),
               TextColumn(f"{{task.completed:.0f}}/{{task.total:.0f}} {unit}"),
               RemainingColumn())
    with LoggedProgress(*columns, transient=True) as bar:
        task = bar.add_task(label, total=total, cached=0.0)

        def advance(done: float, cached: float = 0.0) -> None:
            bar.update(task, completed=min(total, done), cached=cached)

        yield advance


@contextlib.contextmanager
def stage_progress(**kwargs: Any) -> Iterator[Callable[..., None]]:
    """Yield `report(stage, done, total=1.0, cached=0)`: one bar per pipeline stage, kept when
    done; `cached` of `done` found done by a resumed run. `kwargs` go to `LoggedProgress`."""
    with LoggedProgress(TextColumn("{task.description:<28}"), BarColumn(), TaskProgressColumn(),
                        TimeElapsedColumn(), RemainingColumn(), **kwargs) as bar:
        tasks: dict[str, TaskID] = {}
        last = [bar.get_time()]            # when the latest report (of any stage) came

        def report(stage: str, done: float, total: float = 1.0, cached: float = 0.0) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total, cached=cached)
                # a stage reports first when its first unit is done: its work began when
                # the work before it last reported (or when the run began)
                next(t for t in bar.tasks if t.id == tasks[stage]).start_time = last[0]
            bar.update(tasks[stage], completed=done, total=total, cached=cached)
            last[0] = bar.get_time()

        yield report
