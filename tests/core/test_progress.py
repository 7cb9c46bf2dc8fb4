"""Long work shows progress in a log file too, not only on a terminal."""

import io
import re

from rich.console import Console

from macrostate_mj.core.progress import LoggedProgress


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
