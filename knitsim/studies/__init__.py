"""Studies that rerun a paper's numerical experiments and tabulate its claims.

Each study module defines ``run(...) -> dict`` (a table of rows: claim, what
is compared, the paper's value and ours) and ``figures(result, out_dir)``.
:data:`STUDIES` maps names to modules for the ``knitsim study`` command.
"""
from __future__ import annotations

import math

from ..cell.load_program import MAX_INCREMENTS
from ..errors import KnitsimInputError

STUDIES = ("dusserre2015", "dusserre2015-experiment")


def check_increment(increment: float, largest: float, travel: float) -> None:
    """Refuse a study's strain increment (``knitsim study --increment``) outside (0, ``largest``], or one that
    makes its longest program, ``travel`` of strain travelled, longer than
    :data:`~knitsim.cell.load_program.MAX_INCREMENTS`: said of the increment given, not of the scene keys
    (``load.max_increment``, ``load.cycles``) that a study has none of (a probe's ``--increment 1e-9`` was
    refused naming them)."""
    if not (math.isfinite(increment) and 0 < increment <= largest):
        raise KnitsimInputError(f"increment = {increment!r}: must lie in (0, {largest:g}]")
    n = math.ceil(travel / increment * (1.0 - 1e-12))      # (3.1 / 1e-7 rounds to 31000000.000000004)
    if n > MAX_INCREMENTS:
        raise KnitsimInputError(f"increment = {increment!r}: the study's longest program travels a strain of "
                                f"{travel:g}, {n} increments (more than {MAX_INCREMENTS}); use a larger increment")
