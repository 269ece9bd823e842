"""Reading measured tables as laboratories write them (CSV from a test machine, from Excel).

:func:`read_csv_columns` accepts what a lab produces and refuses only what is
wrong, naming the file, the row (as a spreadsheet shows it: the header is row
1), the column and the value, and what to do:

- a UTF-8 byte-order mark (Excel's "CSV UTF-8"), or Windows-1252 text;
- CRLF or LF line ends, blank lines, spaces around cells, quoted cells;
- ``,`` ``;`` or tab as the delimiter, found from the header line (the one
  that splits it into the most fields);
- decimal commas where the delimiter is ``;`` or a tab (``0,125``);
- header names matched after trimming spaces and quotes.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Iterable

import numpy as np

from ..errors import KnitsimInputError

_DELIMITERS = (",", ";", "\t")
_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}


def _text(path: Path) -> str:
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8-sig")       # strips Excel's byte-order mark
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def _delimiter(header_line: str) -> str:
    counts = {d: header_line.count(d) for d in _DELIMITERS}
    best = max(_DELIMITERS, key=lambda d: counts[d])
    return best if counts[best] > 0 else ","


def _number(cell: str, decimal_comma: bool) -> float:
    c = cell.strip().replace("\u2212", "-")       # a typographic minus sign
    if decimal_comma and "," in c and "." not in c:
        c = c.replace(",", ".")
    return float(c)


def read_csv_columns(path: str | Path, required: Iterable[str], optional: Iterable[str] = (),
                     numeric: Iterable[str] | None = None) -> dict[str, np.ndarray]:
    """Read named columns of a CSV file (see the module docstring).

    Parameters
    ----------
    path : path-like
        The CSV file; its first non-blank line names the columns (with units, e.g. ``F0_N``).
    required, optional : iterable of str
        Column names that must / may be present.
    numeric : iterable of str, optional
        Columns to parse as finite floats (default: all required and optional
        columns present).  A NaN, an empty cell or text there is an error naming
        the row and the column.

    Returns
    -------
    dict of str to ndarray
        Float arrays for numeric columns, arrays of str otherwise; the key
        ``"_row"`` holds the spreadsheet row number of each data row.
    """
    path = Path(path)
    if not path.is_file():
        raise KnitsimInputError(f"{path}: no such file")
    lines = _text(path).splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise KnitsimInputError(f"{path}: the file is empty")
    delim = _delimiter(lines[first])
    decimal_comma = delim != ","
    reader = csv.reader(lines[first:], delimiter=delim)
    header = [h.strip().strip('"').strip() for h in next(reader)]
    rows, numbers = [], []
    for k, r in enumerate(reader, start=first + 2):
        if any(c.strip() for c in r):
            rows.append(r)
            numbers.append(k)
    required, optional = list(required), list(optional)
    missing = [c for c in required if c not in header]
    if missing:
        raise KnitsimInputError(f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(header)}; "
                                f"read as {_NAMES[delim]}-separated)")
    if not rows:
        raise KnitsimInputError(f"{path}: no data rows")
    present = required + [c for c in optional if c in header]
    numeric = set(present if numeric is None else numeric)
    out: dict[str, np.ndarray] = {}
    for name in present:
        j = header.index(name)
        cells = []
        for line, row in zip(numbers, rows):
            cell = row[j].strip() if j < len(row) else ""
            if name in numeric:
                try:
                    v = _number(cell, decimal_comma)
                except ValueError:
                    raise KnitsimInputError(f"{path}: row {line}, column {name}: {cell!r} is not a number "
                                            "(fix or delete the row)") from None
                if not math.isfinite(v):
                    raise KnitsimInputError(f"{path}: row {line}, column {name}: {cell!r} is not finite "
                                            "(fix or delete the row)")
                cells.append(v)
            else:
                cells.append(cell)
        out[name] = np.asarray(cells, dtype=float if name in numeric else object)
    out["_row"] = np.asarray(numbers, dtype=np.int64)
    return out
