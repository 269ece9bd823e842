"""Helpers shared by the subcommands: JSON output and CSV input."""
from __future__ import annotations

import sys
from typing import Any

from ..io.jsonable import json_text
from ..io.table_input import read_csv_columns  # noqa: F401  (re-exported: capstan and dahl fits read CSV)


def add_json_flag(parser) -> None:
    """Add the ``--json`` flag every result-printing command has."""
    parser.add_argument("--json", action="store_true", help="print results as JSON (for scripts)")


def print_json(value: Any, stream=None) -> None:
    """Print ``value`` as JSON (NumPy scalars and arrays converted; NaN -> null)."""
    (stream or sys.stdout).write(json_text(value))
