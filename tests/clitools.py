"""Running the CLI from tests, the two ways a user meets it (imported by the test modules)."""

from __future__ import annotations

import subprocess
import sys


def cli(*args: str, **kw) -> subprocess.CompletedProcess:
    """`macrostate-mj ARGS` in a fresh interpreter: exit code, stdout and stderr as a user sees
    them, tracebacks included."""
    return subprocess.run([sys.executable, "-m", "macrostate_mj.app.cli", *args],
                          capture_output=True, text=True, timeout=900, **kw)


def cli_inprocess(capsys, *args: str) -> tuple[int, str, str]:
    """The same command in this process (faster): (exit code, stdout, stderr)."""
    from macrostate_mj.app.cli import main

    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean_error(res: subprocess.CompletedProcess, *words: str) -> None:
    """Bad input: exit code 2, one line on stderr naming the problem, no traceback."""
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    for w in words:
        assert w in lines[0], lines[0]
