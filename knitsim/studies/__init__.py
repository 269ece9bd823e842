"""Studies that rerun a paper's numerical experiments and tabulate its claims.

Each study module defines ``run(...) -> dict`` (a table of rows: claim, what
is compared, the paper's value and ours) and ``figures(result, out_dir)``.
:data:`STUDIES` maps names to modules for the ``knitsim study`` command.
"""
from __future__ import annotations

STUDIES = ("dusserre2015", "dusserre2015-experiment")
