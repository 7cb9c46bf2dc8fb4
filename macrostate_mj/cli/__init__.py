"""Command-line entry point: a thin layer over the library API.

Every command lives in a sibling module and imports its heavy dependencies lazily, so that
`macrostate-mj --help` stays fast. A `UserError` anywhere becomes one line on stderr and exit 2.
"""

import sys

from macrostate_mj.cli import bench as _bench  # noqa: F401  (registers commands)
from macrostate_mj.cli import colony as _colony  # noqa: F401
from macrostate_mj.cli import retlo as _retlo  # noqa: F401
from macrostate_mj.cli import sim as _sim  # noqa: F401
from macrostate_mj.cli.app import app
from macrostate_mj.errors import UserError


def main() -> None:
    try:
        app(standalone_mode=True)
    except UserError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
