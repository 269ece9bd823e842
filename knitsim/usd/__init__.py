"""USD export of knit patches for visual checks (usd-core's ``pxr``).

- :mod:`~knitsim.usd.yarn_geometry` -- full stitches and course yarns from
  quarter-stitch centrelines (pure NumPy; the geometry is derived there);
- :mod:`~knitsim.usd.export` -- :func:`write_patch_usd`, :func:`read_patch_usd`;
- :mod:`~knitsim.usd.quicklook` -- :func:`render_quicklook`, a two-panel PNG
  read back from the USD file.

``pxr`` is imported only when a file is written or read.
"""
from .export import (STAGE_LABELS, PatchUsd, UsdExportResult, read_patch_usd,  # noqa: F401
                     write_patch_usd)
from .quicklook import render_quicklook  # noqa: F401
from .yarn_geometry import (cell_origins, course_curves, landmark_index, patch_points,  # noqa: F401
                            resample_quarters, stitch_points, stitch_polyline)

__all__ = ["write_patch_usd", "read_patch_usd", "render_quicklook", "PatchUsd", "UsdExportResult",
           "STAGE_LABELS", "stitch_polyline", "stitch_points", "course_curves", "patch_points",
           "cell_origins", "landmark_index", "resample_quarters"]
