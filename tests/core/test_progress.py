"""Long work shows progress in a log file too, not only on a terminal; its estimate of the time
left holds when workers finish together or a resumed run finds work done."""

import io
import re

from rich.console import Console

from macrostate_mj.core.progress import LoggedProgress, remaining, stage_progress


def _run(console: Console) -> str:
    with LoggedProgress(console=console, transient=True) as bar:
        known = bar.add_task("train DCAE", total=20)
        unknown = bar.add_task("reading frames", total=None)
        for _ in range(20):
            bar.advance(known)
            bar.advance(unknown)
    return console.file.getvalue()


def test_a_log_file_gets_a_line_per_tenth_of_each_task():
    text = _run(Console(file=io.StringIO(), force_terminal=False))
    percents = [int(p) for p in re.findall(r"train DCAE: (\d+) % after", text)]
    assert percents == list(range(10, 101, 10))
    assert "reading frames" not in text  # no total, no percentage to report


def test_a_terminal_gets_the_live_bar_only():
    text = _run(Console(file=io.StringIO(), force_terminal=True))
    assert "% after" not in text


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def _estimates(finished: list[float], total: int, cached: int = 0
               ) -> list[tuple[float, float, float | None]]:
    """(our estimate, true time left, rich's estimate) after each unit that finishes at the
    times given (seconds from the start), `cached` units found done at the start."""
    clock = Clock()
    out = []
    with LoggedProgress(console=Console(file=io.StringIO()), get_time=clock) as bar:
        task = bar.add_task("work", total=total, cached=cached)
        bar.update(task, completed=cached)
        for i, t in enumerate(finished):
            clock.now = t
            bar.update(task, completed=cached + i + 1)
            out.append((remaining(bar.tasks[0]), finished[-1] - t, bar.tasks[0].time_remaining))
    return out


def test_two_workers_finishing_together_do_not_make_the_estimate_short():
    # 8 episodes of ~20 s on 2 workers: pairs finish together
    finished = [20.0, 20.1, 40.0, 40.2, 61.0, 61.1, 80.0, 80.3]
    estimates = _estimates(finished, 8)
    # after the first tenth, while more than one episode's time is left
    for estimate, left, _ in estimates[1:6]:
        assert left / 2 <= estimate <= left * 2, (estimate, left)
    ours, left, rich = estimates[1]
    assert rich < left / 50 and abs(ours - left) < 1     # rich's 30 s window: 0.6 s for 60 s


def test_the_workers_start_up_does_not_make_the_estimate_long():
    # measured: `collect --minutes 8 --episode-minutes 1 --workers 2`, 7 s of start-up (spawned
    # workers import, build their renderer) before the first of 8 episodes of ~1.2 s each
    finished = [7.4, 7.8, 9.9, 10.5, 12.2, 12.7, 14.6, 15.3]
    estimates = _estimates(finished, 8)
    for estimate, left, _ in estimates[2:7]:        # from the third result on
        assert left / 2 <= estimate <= left * 2, (estimate, left)
def test_a_resumed_run_counts_only_its_own_work_in_the_rate():
    # 6 of 10 units cached (at once), the rest 10 s each
    estimates = _estimates([10.0, 20.0, 30.0, 40.0], 10, cached=6)
    assert [round(e) for e, _, _ in estimates] == [30, 20, 10, 0]
    assert [left for _, left, _ in estimates] == [30, 20, 10, 0]


def test_a_stage_s_clock_starts_when_the_work_before_it_last_reported():
    # experiment stages report first when their first unit is done: measured in the clean-clone
    # trial, sim2real's 14 models said "9 s left" with 82 s to go when the clock began there
    clock, text = Clock(), io.StringIO()
    with stage_progress(console=Console(file=text), get_time=clock) as report:
        clock.now = 5.0
        report("collect", 1, 1)
        clock.now = 25.0
        report("models", 1, 14)         # the first model took 20 s
        clock.now = 26.0
        report("models", 2, 14)         # the second came a second later
    assert "models: 14 % after 0.3 min, about 2 min left" in text.getvalue()   # not 9 s
