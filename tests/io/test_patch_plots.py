"""The patch run's figures show what the summary says: the maps at the last cycle's peak and at the
end, and the summary's warnings under the force-strain curve.

Expected values come from the load program's definition (cycles 0.10 -> 0.40: the last cycle's largest
grip strain is 0.40; a monotonic pull peaks at its end) and from the figure's layout (each wrapped
warning line adds 0.16 in at 110 dpi).

Cells past the domain on the strain map: two wale columns of identical cells, C0 = 2.7 and 2.9 mm, take the
same grip displacement u = g x (their mean rest length, 5.6 mm): a column of identical cells in series stretches
each cell by u / 2, so at grip strain 0.6 the cells of wale 0 are at 0.6 x 5.6 / 5.4 = 0.622 (past the domain's
0.6, knitsim.cell.domain) and those of wale 1 at 0.6 x 5.6 / 5.8 = 0.579 (inside): hand-computed.
"""
from __future__ import annotations

import io

import numpy as np
import pytest

from knitsim.cell.load_program import cycles, monotonic
from knitsim.cell.material import CellParams
from knitsim.io.patch_results import map_figure, map_rows, plot_force_strain, plot_map
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


def test_the_strain_map_hatches_the_cells_past_the_domain_with_a_legend():
    short, long_ = P, P.replace(C0=2.9)
    h = run_patch(PatchModel.from_cells([[short, long_], [short, long_]]), monotonic(0.6, 0.05), engine="warp")
    assert h.cell_field("strain")[-1] == pytest.approx(np.array([[0.6222, 0.5793]] * 2), abs=1e-4)
    fig = map_figure(h, "strain")
    (ax,) = [a for a in fig.axes if a.get_xlabel() == "wale"]
    (hatched,) = [c for c in ax.collections if c.get_hatch() == "///"]
    # one square per cell past the domain, drawn over wale 0 (x from -0.5 to 0.5), courses 0 and 1
    squares = [p.vertices for p in hatched.get_paths()]
    assert len(squares) == 2
    assert sorted((v[:, 0].min(), v[:, 0].max(), v[:, 1].min()) for v in squares) == [(-0.5, 0.5, -0.5),
                                                                                       (-0.5, 0.5, 0.5)]
    (legend,) = fig.legends
    assert [t.get_text() for t in legend.get_texts()][0].startswith("past the model's domain: strain above 0.6")
    # a pull that stays inside: no hatch, no legend
    inside = run_patch(PatchModel.from_cells([[short, long_]]), monotonic(0.3, 0.1), engine="warp")
    fig = map_figure(inside, "strain")
    assert not fig.legends and not [c for a in fig.axes for c in a.collections if c.get_hatch()]


def test_the_hatch_is_one_rectangle_per_run_of_cells_along_a_course():
    """The cells past the domain, hatched as runs (one square per cell drew 90,000 squares a panel on a 300 x 300
    patch, 21 s): the runs of a hand-made mask, on uneven cell edges (a specimen's blocks), by their definition."""
    from knitsim.io.patch_results import _hatched_runs

    mask = np.array([[1, 1, 0, 1],
                     [0, 1, 1, 1],
                     [0, 0, 0, 0]], bool)
    xe, ye = np.array([0.0, 1.0, 3.0, 4.0, 7.0]), np.array([0.0, 2.0, 5.0, 6.0])
    got = sorted((v[:, 0].min(), v[:, 0].max(), v[:, 1].min(), v[:, 1].max())
                 for v in (p.vertices for p in _hatched_runs(xe, ye, mask).get_paths()))
    # course 0: wales 0-1 and wale 3; course 1: wales 1-3
    assert got == [(0.0, 3.0, 0.0, 2.0), (1.0, 7.0, 2.0, 5.0), (4.0, 7.0, 0.0, 2.0)]
