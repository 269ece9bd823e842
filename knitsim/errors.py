"""Errors that knitsim reports to users.

A :class:`KnitsimInputError` is a user mistake (bad scene, bad CSV, impossible
load program).  The command line prints its message on one line and exits with
status 2, without a traceback.  Its message names the offending field and value.
"""


class KnitsimInputError(ValueError):
    """Invalid user input: the message names the field and the value."""


def require(condition: bool, message: str) -> None:
    """Raise :class:`KnitsimInputError` with ``message`` unless ``condition``."""
    if not condition:
        raise KnitsimInputError(message)
