"""JSON text of result documents: NumPy scalars and arrays converted, non-finite numbers as null.

One converter for every JSON the project writes (summaries, diagnoses, study
records) and prints (``--json``); it imports nothing heavy, so the command
line can use it at start-up.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def jsonable(value: Any) -> Any:
    """``value`` with NumPy types made plain and NaN / inf made None (JSON has no such numbers)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def json_text(value: Any, indent: int = 2) -> str:
    """``value`` as JSON text ending in a newline (:func:`jsonable` first; strict: no NaN)."""
    return json.dumps(jsonable(value), indent=indent, allow_nan=False) + "\n"
