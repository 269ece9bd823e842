"""Heterogeneous patches of quarter-stitch cells: ``wales x courses`` cells between rigid grips.

- :mod:`.model`: the patch description (size, per-cell parameter arrays [courses, wales]);
- :mod:`.maps`: per-cell parameter maps (uniform, regions, gradients, files, seeded random);
- :mod:`.coupling`: the series (along a wale column) / parallel (across columns) solver;
- :mod:`.runner`: a patch through a load program, with progress, checkpoint and resume.
"""
from .model import PARAM_NAMES, PatchModel, Grouping

__all__ = ["PARAM_NAMES", "PatchModel", "Grouping"]
