"""The one exception the CLI turns into a one-line message and exit code 2."""


class UserError(ValueError):
    """Bad input a user can fix: the message names the problem and the fix.

    A `ValueError`, so that library callers catch it the way Python signals a bad argument
    (`except ValueError` around `get_scenario(name)` works without knowing our types). The price:
    inside the package, an `except ValueError` must never wrap code that can raise a `UserError`,
    or it would swallow the user's message; keep those try blocks to the parsing call alone.
    """


class RunFailure(Exception):
    """Not bad input: the run itself failed (the physics left its valid regime). The CLI prints
    one line and exits 1; what was done before the failure is kept."""
