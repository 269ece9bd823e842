"""Kernel keys: one compiled instance of :mod:`knitsim.kernels.cell_step` per (friction law, effects,
jamming criterion), so that a batch's kernels carry only the code its cells use (issue 15).

:func:`cell_step_module` runs ``cell_step.py`` once per key as its own module
(``knitsim.kernels.cell_step__<key>``, its own Warp module and kernel cache entry) with
``KERNEL_KEY`` set; ``cell_step`` reads the key's ``WITH_*`` flags through ``wp.static``, and a
branch whose flag is off is not generated.  The generic module (key ``None``) is
``knitsim.kernels.cell_step`` itself: every law chosen per cell at run time, as before.

A batch may still mix laws, effects and criteria from cell to cell: :func:`group_cells` splits it
into one index list per key, the caller launches one kernel per group on the full state arrays
(each thread advances the cell ``cells[tid]``), so results stay in the caller's order.
"""
from __future__ import annotations

import functools
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class KernelKey:
    """What a kernel instance compiles in: Dahl (else Coulomb) friction, the model extensions
    (effects), jamming by the head gap (else W = 4 d_jam only)."""

    dahl: bool
    effects: bool
    gap: bool

    @property
    def name(self) -> str:
        return "_".join(("dahl" if self.dahl else "coulomb", "effects" if self.effects else "plain",
                         "gap" if self.gap else "w4d"))


#: the key of the state initialisation (Table 4's initial solve uses none of the optional residuals)
INIT_KEY = KernelKey(dahl=False, effects=False, gap=False)


@functools.lru_cache(maxsize=None)
def cell_step_module(key: KernelKey | None):
    """The :mod:`~knitsim.kernels.cell_step` instance compiled for ``key`` (None: the generic one)."""
    if key is None:
        from . import cell_step
        return cell_step
    name = f"{__package__}.cell_step__{key.name}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name("cell_step.py"))
    mod = importlib.util.module_from_spec(spec)
    mod.KERNEL_KEY = key
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        del sys.modules[name]
        raise
    return mod


def group_cells(dahl: np.ndarray, effects: np.ndarray, gap: np.ndarray) -> list[tuple[KernelKey, np.ndarray]]:
    """Split N cells by kernel key.

    Parameters
    ----------
    dahl, effects, gap : array of bool, shape [N]
        Per cell: Dahl friction, any effect on, head-gap jamming criterion.

    Returns
    -------
    list of (KernelKey, int32 array of cell indices in increasing order), one per key present,
    in a fixed order (Coulomb before Dahl, plain before effects, W = 4d before head gap).
    """
    code = (np.asarray(dahl, bool).astype(np.int32) * 4 + np.asarray(effects, bool).astype(np.int32) * 2
            + np.asarray(gap, bool).astype(np.int32))
    out = []
    for c in np.unique(code):
        idx = np.flatnonzero(code == c).astype(np.int32)
        out.append((KernelKey(dahl=bool(c & 4), effects=bool(c & 2), gap=bool(c & 1)), idx))
    return out
