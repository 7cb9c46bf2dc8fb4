"""The one exception the CLI turns into a one-line message and exit code 2."""


class UserError(Exception):
    """Bad input a user can fix: the message names the problem and the fix."""


class RunFailure(Exception):
    """Not bad input: the run itself failed (the physics left its valid regime). The CLI prints
    one line and exits 1; what was done before the failure is kept."""
