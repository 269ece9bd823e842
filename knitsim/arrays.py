"""Array helpers shared by the cell and patch packages."""
from __future__ import annotations

import numpy as np


def row_ids(flat: np.ndarray) -> np.ndarray:
    """An id per row of ``flat`` [n, k], equal for equal rows (the inverse of ``np.unique(flat, axis=0)``).

    Each column is factorised on its own and the codes combined into one integer where their product fits
    in 63 bits: ``np.unique(axis=0)`` sorted 10^6 rows of 15 values in 4.6 s, the combined key in 0.1 s."""
    codes, radix = [], 1
    for c in flat.T:
        u, inv = np.unique(c, return_inverse=True)
        codes.append((inv.ravel().astype(np.int64), len(u)))
        radix *= max(len(u), 1)
    if radix >= 2**62:
        return np.unique(flat, axis=0, return_inverse=True)[1].ravel()
    key = np.zeros(len(flat), np.int64)
    for inv, n in codes:
        key = key * n + inv
    return np.unique(key, return_inverse=True)[1].ravel()
