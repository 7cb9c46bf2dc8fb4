"""Command-line entry point: a thin layer over the library API.

Every command lives in a sibling module and imports its heavy dependencies lazily, so that
`macrostate-mj --help` stays fast. Bad input, whether a `UserError` from the library or a bad
flag caught by the parser, becomes one line on stderr and exit code 2, never a traceback.
"""

import sys

import typer

from macrostate_mj.app.cli import ants as _ants  # noqa: F401
from macrostate_mj.app.cli import bench as _bench  # noqa: F401  (registers commands)
from macrostate_mj.app.cli import collect as _collect  # noqa: F401
from macrostate_mj.app.cli import oc as _oc  # noqa: F401
from macrostate_mj.app.cli import retlo as _retlo  # noqa: F401
from macrostate_mj.app.cli import retlo_sim as _retlo_sim  # noqa: F401
from macrostate_mj.app.cli import sim as _sim  # noqa: F401
from macrostate_mj.app.cli import soak as _soak  # noqa: F401
from macrostate_mj.app.cli.app import app
from macrostate_mj.core.errors import RunFailure, UserError

# typer 0.29 vendors click and exports only `BadParameter` of its exception tree; its base class
# is click's UsageError, which every parser error (bad flag, missing argument) derives from.
UsageError: type[Exception] = typer.BadParameter.__mro__[1]


def main(argv: list[str] | None = None) -> None:
    """Run the CLI on `argv` (default: the process's arguments); always ends in SystemExit."""
    try:
        code = app(args=argv, prog_name="macrostate-mj", standalone_mode=False)
    except UsageError as err:
        if type(err).__name__ == "NoArgsIsHelpError":
            sys.exit(0)         # a group called bare: typer printed its help on raising this
        where = err.ctx.command_path if err.ctx else "macrostate-mj"
        message = " ".join(err.format_message().split())
        print(f"error: {message} (see `{where} --help`)", file=sys.stderr)
        sys.exit(2)
    except UserError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
    except RunFailure as err:
        print(f"failed: {err}", file=sys.stderr)
        sys.exit(1)
    except (typer.Abort, KeyboardInterrupt):
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
