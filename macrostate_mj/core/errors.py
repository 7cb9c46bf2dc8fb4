"""The one exception the CLI turns into a one-line message and exit code 2."""


class UserError(ValueError):
    """Bad input a user can fix: the message names the problem and the fix.

    A `ValueError`, so that library callers catch it the way Python signals a bad argument
    (`except ValueError` around `get_scenario(name)` works without knowing our types). The price:
    inside the package, an `except ValueError` must never wrap code that can raise a `UserError`,
    or it would swallow the user's message; keep those try blocks to the parsing call alone.

    `param` names the Python parameter (or config field) at fault, so that the CLI can name its
    own flag for it (`--head-speed` for `head_speed`) while the message names what a library
    caller passed.
    """

    def __init__(self, message: str, param: str | None = None):
        super().__init__(message)
        self.param = param

    def __reduce__(self) -> tuple:
        """Keep `param` when the error crosses from a worker process."""
        return type(self), (str(self), self.param)


class RunFailure(Exception):
    """Not bad input: the run itself failed (the physics left its valid regime). The CLI prints
    one line and exits 1; what was done before the failure is kept."""
