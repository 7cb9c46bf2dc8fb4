"""Progress bars for long work (rich), shared by the commands."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn


@contextlib.contextmanager
def sim_progress(total: float, label: str, unit: str = "sim s"
                 ) -> Iterator[Callable[[float], None]]:
    """Yield `advance(done)` that sets the bar to `done` of `total` (e.g. simulated seconds)."""
    columns = (TextColumn("{task.description}"), BarColumn(),
               TextColumn(f"{{task.completed:.0f}}/{{task.total:.0f}} {unit}"),
               TimeRemainingColumn())
    with Progress(*columns, transient=True) as bar:
        task = bar.add_task(label, total=total)

        def advance(done: float) -> None:
            bar.update(task, completed=min(total, done))

        yield advance
