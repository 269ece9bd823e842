"""Helpers shared by the subcommands: JSON output and CSV input."""
from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import KnitsimInputError
from ..io.jsonable import json_text


def add_json_flag(parser) -> None:
    """Add the ``--json`` flag every result-printing command has."""
    parser.add_argument("--json", action="store_true", help="print results as JSON (for scripts)")


def print_json(value: Any, stream=None) -> None:
    """Print ``value`` as JSON (NumPy scalars and arrays converted; NaN -> null)."""
    (stream or sys.stdout).write(json_text(value))


def read_csv_columns(path: str | Path, required: Iterable[str], optional: Iterable[str] = (),
                     numeric: Iterable[str] | None = None) -> dict[str, np.ndarray]:
    """Read named columns of a CSV file, with clear errors for user mistakes.

    Parameters
    ----------
    path : path-like
        The CSV file; its first row names the columns (with units, e.g. ``F0_N``).
    required, optional : iterable of str
        Column names that must / may be present.
    numeric : iterable of str, optional
        Columns to parse as finite floats (default: all required and optional
        columns present).  A NaN, an empty cell or text there is an error naming
        the column and the row.

    Returns
    -------
    dict of str to ndarray
        Float arrays for numeric columns, arrays of str otherwise.
    """
    path = Path(path)
    if not path.is_file():
        raise KnitsimInputError(f"{path}: no such file")
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise KnitsimInputError(f"{path}: the file is empty") from None
        rows = [r for r in reader if any(c.strip() for c in r)]
    required, optional = list(required), list(optional)
    missing = [c for c in required if c not in header]
    if missing:
        raise KnitsimInputError(f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(header)})")
    if not rows:
        raise KnitsimInputError(f"{path}: no data rows")
    present = required + [c for c in optional if c in header]
    numeric = set(present if numeric is None else numeric)
    out: dict[str, np.ndarray] = {}
    for name in present:
        j = header.index(name)
        cells = []
        for i, row in enumerate(rows, start=2):
            cell = row[j].strip() if j < len(row) else ""
            if name in numeric:
                try:
                    v = float(cell)
                except ValueError:
                    raise KnitsimInputError(f"{path}: row {i}, column {name}: {cell!r} is not a number") from None
                if not math.isfinite(v):
                    raise KnitsimInputError(f"{path}: row {i}, column {name}: {cell!r} is not finite")
                cells.append(v)
            else:
                cells.append(cell)
        out[name] = np.asarray(cells, dtype=float if name in numeric else object)
    return out
