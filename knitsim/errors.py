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


def require_finite(name: str, value, lower: str | None = None):
    """``value`` (a number or an array) as float64, every element finite and, with ``lower`` = ``">0"`` or
    ``">=0"``, above that bound; else :class:`KnitsimInputError` naming ``name`` and the first bad value."""
    import numpy as np
    a = np.asarray(value, dtype=np.float64)
    flat = a.reshape(-1)
    bad = ~np.isfinite(flat)
    if lower == ">0":
        bad |= flat <= 0.0
    elif lower == ">=0":
        bad |= flat < 0.0
    elif lower is not None:
        raise ValueError(f"lower = {lower!r}: expected '>0', '>=0' or None")
    if bad.any():
        v = float(flat[int(np.flatnonzero(bad)[0])])
        raise KnitsimInputError(f"{name} = {v!r}: must be finite" + (f" and {lower[0]} {lower[1:]}" if lower else ""))
    return a
