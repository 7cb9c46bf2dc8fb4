"""Command-line entry point: a thin layer over the library API.

Every command lives in a sibling module (found by scanning this package) and imports its heavy
dependencies lazily, so that `macrostate-mj --help` stays fast. Bad input, whether a `UserError`
from the library or a bad value caught by the parser (`params`), becomes one line on stderr and
exit code 2, never a traceback; on any failure the outputs the command created are tidied by
`params.finish`.
"""

import importlib
import sys

import typer

from macrostate_mj.app import params
from macrostate_mj.app.cli.app import app
from macrostate_mj.core.errors import RunFailure, UserError
from macrostate_mj.core.registry import scan

# Every command module of this package registers its commands on `app` as it is imported: the
# registries' rule (`core.registry.scan`), so a new command is a new module. `app` itself is one
# of them (already imported), `__main__` is skipped by the rule.
for _module in scan(__name__):
    importlib.import_module(_module)

# typer 0.29 vendors click and exports only `BadParameter` of its exception tree; its base class
# is click's UsageError, which every parser error (bad flag, missing argument) derives from.
UsageError: type[Exception] = typer.BadParameter.__mro__[1]
INTERRUPTED = 130               # the shell's code for a process stopped by SIGINT


def _flag_for(param: str | None, argv: list[str]) -> str | None:
    """The running command's flag for the library parameter a `UserError` names, if any: the
    library's parameters carry their flags' names."""
    if param is None:
        return None
    command = typer.main.get_command(app)
    for token in argv:
        sub = getattr(command, "commands", {}).get(token)
        if sub is not None:
            command = sub
    for option in command.params:
        if option.name == param:
            return next((o for o in option.opts if o.startswith("--")), None)
    return None


def _run(argv: list[str] | None) -> object:
    """The command's return value; on failure its created outputs are tidied, then it re-raises."""
    params.begin()
    try:
        code = app(args=argv, prog_name="macrostate-mj", standalone_mode=False)
    except (UsageError, UserError):
        params.finish(bad_input=True)
        raise
    except BaseException:
        params.finish(bad_input=False)
        raise
    if code == INTERRUPTED:     # typer turns Ctrl-C into this exit code instead of raising
        params.finish(bad_input=False)
        raise KeyboardInterrupt
    return code


def main(argv: list[str] | None = None) -> None:
    """Run the CLI on `argv` (default: the process's arguments); always ends in SystemExit."""
    try:
        code = _run(argv)
    except UsageError as err:
        if type(err).__name__ == "NoArgsIsHelpError":
            sys.exit(0)         # a group called bare: typer printed its help on raising this
        where = err.ctx.command_path if err.ctx else "macrostate-mj"
        message = " ".join(err.format_message().split())
        print(f"error: {message} (see `{where} --help`)", file=sys.stderr)
        sys.exit(2)
    except UserError as err:
        flag = _flag_for(err.param, sys.argv[1:] if argv is None else argv)
        print(f"error: {flag}: {err}" if flag else f"error: {err}", file=sys.stderr)
        sys.exit(2)
    except RunFailure as err:
        print(f"failed: {err}", file=sys.stderr)
        sys.exit(1)
    except (typer.Abort, KeyboardInterrupt):
        print("interrupted", file=sys.stderr)
        sys.exit(INTERRUPTED)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
