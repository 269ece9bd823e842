"""The patch run's figures show what the summary says: the maps at the last cycle's peak and at the
end, and the summary's warnings under the force-strain curve.

Expected values come from the load program's definition (cycles 0.10 -> 0.40: the last cycle's largest
grip strain is 0.40; a monotonic pull peaks at its end) and from the figure's layout (each wrapped
warning line adds 0.16 in at 110 dpi).
"""
from __future__ import annotations

import io

import numpy as np
import pytest

from knitsim.cell.load_program import cycles, monotonic
from knitsim.cell.material import CellParams
from knitsim.io.patch_results import map_rows, plot_force_strain, plot_map
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2


@pytest.fixture(scope="module")
def cyclic():
    return run_patch(PatchModel.uniform(P, 2, 2), cycles(0.10, 0.40, 2, 0.1), engine="warp")


def _height_px(png: bytes) -> int:
    from PIL import Image
    return Image.open(io.BytesIO(png)).size[1]


def test_maps_show_the_last_peak_and_the_end(cyclic):
    h = cyclic
    peak, end = map_rows(h)
    assert end == h.n_increments - 1 and h.cycle[peak] == h.cycle[-1] == 2
    assert h.grip_strain[peak] == pytest.approx(0.40, abs=1e-12)
    mono = run_patch(PatchModel.uniform(P, 1, 1), monotonic(0.2, 0.1), engine="warp")
    assert map_rows(mono) == [mono.n_increments - 1]            # the peak is the end: one panel
    for which in ("stage", "strain"):
        assert plot_map(h, which)[:8] == b"\x89PNG\r\n\x1a\n"


def test_warnings_stand_under_the_force_curve(cyclic):
    plain = plot_force_strain(cyclic)
    msg = "x " * 150                                            # 300 characters: 3 lines of at most 120
    warned = plot_force_strain(cyclic, warnings=[{"code": "c", "message": msg}])
    assert _height_px(plain) == round(5 * 110)
    assert abs(_height_px(warned) - (5 + 3 * 0.16) * 110) <= 1
    assert not np.array_equal(np.frombuffer(plain, np.uint8)[:64], np.frombuffer(warned, np.uint8)[:64])
