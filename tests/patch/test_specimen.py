"""Specimens between grips: cells that stand for blocks of stitches (issue 16).

Sources: a uniform specimen is its cell (identity: every stitch in series carries the same
force, every wale in parallel the same strain, so the grip force is wales x the cell's force
and the grip strain the cell's strain); parallel strips of different loop heights, each
course count = gauge length / C0, all run at the grip strain (rigid grips: equal displacement
over equal rest lengths), so the grip force is the sum of their single cells' forces times
their wale counts; bands in series carry the same total force, so their force per wale
differs by the ratio of their wale counts, and their elongations add (hand combination of
the single-cell loading curves).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import monotonic
from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError
from knitsim.patch.coupling import COL_OK
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Table 1 / section 2.2 / section 3.4 (dusserre2015.toml), and a tighter knit of the same yarn
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
Q = P.replace(L=13.0, W0=4.0, C0=2.4)
WIDTH, GAUGE = 50.0, 100.0


def test_uniform_specimen_is_its_cell(device):
    prog = monotonic(0.4, 0.02)
    cell = run_batch([P], prog, device=device).force_per_wale[:, 0]
    model = PatchModel.specimen(P, WIDTH, GAUGE)
    # the tester's counts: gauge / C0 courses, width / W0 wales
    assert model.course_count[0, 0] == GAUGE / 2.7 and model.wale_count[0, 0] == WIDTH / 4.4
    h = run_patch(model, prog, device=device)
    assert np.all(h.column_status == COL_OK)
    np.testing.assert_allclose(h.force_per_wale_N, cell, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(h.force_N, WIDTH / 4.4 * cell, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(h.cell_field("strain")[:, 0, 0], prog.strain, rtol=0, atol=1e-14)


def test_parallel_strips_of_different_loop_heights_run_at_the_grip_strain(device):
    """Two halves across the width, each with its own number of courses between the same grips."""
    prog = monotonic(0.4, 0.02)
    cells = run_batch([P, Q], prog, device=device).force_per_wale
    half = WIDTH / 2
    fields = {n: np.array([[float(getattr(P, n)), float(getattr(Q, n))]]) for n in ("d", "B", "m", "L", "W0", "C0",
                                                                                     "phi0", "dahl_sigma")}
    fields["in_plane_width"] = np.full((1, 2), np.nan)
    model = PatchModel(1, 2, fields, {"force_cap_N": 10.0}, course_count=GAUGE / fields["C0"],
                       wale_count=half / fields["W0"], gauge_length=GAUGE)
    np.testing.assert_allclose(model.column_rest_length(), [GAUGE, GAUGE], rtol=1e-15)
    h = run_patch(model, prog, device=device)
    assert np.all(h.column_status == COL_OK)
    # both strips at the grip strain (not the mean rest length of differently long columns)
    strain = h.cell_field("strain")
    np.testing.assert_allclose(strain[:, 0, 0], prog.strain, atol=1e-14)
    np.testing.assert_allclose(strain[:, 0, 1], prog.strain, atol=1e-14)
    expect = half / 4.4 * cells[:, 0] + half / 4.0 * cells[:, 1]
    np.testing.assert_allclose(h.force_N, expect, rtol=1e-12)
    np.testing.assert_allclose(h.column_force_N, cells, rtol=1e-12)


def _loading_curve(p, top, inc, device):
    h = run_batch([p], monotonic(top, inc), device=device)
    ok = h.status[:, 0] == 0
    return h.values["C"][ok, 0], h.force_per_wale[ok, 0]


def test_series_bands_carry_one_total_force_and_add_elongations(device):
    """Bands along the gauge length: the tighter band has more wales across the width, so it
    carries less force per wale at the same grip force; the elongations add."""
    prog = monotonic(0.3, 0.01)
    h_band = GAUGE / 2
    fields = {n: np.array([[float(getattr(P, n))], [float(getattr(Q, n))]]) for n in ("d", "B", "m", "L", "W0",
                                                                                       "C0", "phi0", "dahl_sigma")}
    fields["in_plane_width"] = np.full((2, 1), np.nan)
    nc = h_band / fields["C0"]
    pw = WIDTH / fields["W0"]
    model = PatchModel(2, 1, fields, {"force_cap_N": 10.0}, course_count=nc, wale_count=pw, gauge_length=GAUGE)
    h = run_patch(model, prog, device=device)
    assert np.all(h.column_status == COL_OK)
    F = h.force_N
    f = h.cell_field("F")                               # per wale, [increment, band, strip]
    np.testing.assert_allclose(pw[0, 0] * f[:, 0, 0], F, rtol=1e-7)
    np.testing.assert_allclose(pw[1, 0] * f[:, 1, 0], F, rtol=1e-7)
    assert np.all(f[3:, 1, 0] < f[3:, 0, 0])            # the band of more wales: less force per wale
    # rigid grips: course counts x changes of course length add up to the grip displacement
    C = h.cell_field("C")
    u = nc[0, 0] * (C[:, 0, 0] - P.C0) + nc[1, 0] * (C[:, 1, 0] - Q.C0)
    np.testing.assert_allclose(u, prog.strain * GAUGE, rtol=1e-10, atol=1e-10)
    # hand combination of the single-cell loading curves at equal total force
    Cp, Fp = _loading_curve(P, 0.9, 0.002, device)
    Cq, Fq = _loading_curve(Q, 0.9, 0.002, device)
    lo = max(pw[0, 0] * Fp[1], pw[1, 0] * Fq[1])
    hi = min(pw[0, 0] * Fp.max(), pw[1, 0] * Fq.max())
    rows = (F > lo) & (F < hi)
    assert rows.sum() >= 8
    hand = (nc[0, 0] * (np.interp(F[rows] / pw[0, 0], Fp[1:], Cp[1:]) - P.C0)
            + nc[1, 0] * (np.interp(F[rows] / pw[1, 0], Fq[1:], Cq[1:]) - Q.C0))
    np.testing.assert_allclose(prog.strain[rows] * GAUGE, hand, rtol=2e-3)


def test_gauge_length_must_be_every_column_rest_length():
    fields = {n: np.full((1, 1), float(getattr(P, n))) for n in ("d", "B", "m", "L", "W0", "C0", "phi0", "dahl_sigma")}
    fields["in_plane_width"] = np.full((1, 1), np.nan)
    with pytest.raises(KnitsimInputError, match="is not the gauge length"):
        PatchModel(1, 1, fields, course_count=np.array([[10.0]]), gauge_length=GAUGE)
    with pytest.raises(KnitsimInputError, match="positive, finite"):
        PatchModel(1, 1, fields, wale_count=np.array([[0.0]]))


def test_the_api_refuses_what_the_scene_refuses():
    """PatchModel from Python: sizes 0, -1, 2.5 or "3" and a field of another shape failed inside numpy;
    a specimen 0.05 x 0.1 (metres by mistake) was accepted as 0.011 wales with a force 1,000 times too small
    (a blind probe).  Each is refused naming what is wrong, as the scene's [patch] and [specimen] are."""
    import numpy as np

    from knitsim.cell.material import CellParams
    from knitsim.errors import KnitsimInputError
    from knitsim.patch.model import PatchModel

    c = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.0)
    for courses in (0, -1, 2.5, "3", True):
        with pytest.raises(KnitsimInputError, match=r"PatchModel.courses = .*: expected a whole number >= 1"):
            PatchModel.uniform(c, courses, 2)
    good = PatchModel.uniform(c, 2, 2)
    with pytest.raises(KnitsimInputError, match=r"fields\['C0'\]: shape \(3,\), expected \(courses, wales\) = \(2, 2\)"):
        PatchModel(2, 2, dict(good.fields, C0=np.ones(3)))
    with pytest.raises(KnitsimInputError, match="no 'C0'"):
        PatchModel(2, 2, {k: v for k, v in good.fields.items() if k != "C0"})
    with pytest.raises(KnitsimInputError, match="narrower than one wale .*widths are in mm"):
        PatchModel.specimen(c, width=0.05, gauge_length=0.1)
    with pytest.raises(KnitsimInputError, match="shorter than one course"):
        PatchModel.specimen(c, width=50.0, gauge_length=2.0)
    # 1e9 mm / C0 = 2.7 mm = 3.7e8 courses: more than a patch may hold (before: a specimen of 370 million courses)
    with pytest.raises(KnitsimInputError, match=r"3\.704e\+08 courses, more than the 100,000 a patch may hold"):
        PatchModel.specimen(c, width=50.0, gauge_length=1e9)
    with pytest.raises(KnitsimInputError, match="at least one cell"):
        PatchModel.from_cells([])
    assert PatchModel.specimen(c, width=50.0, gauge_length=100.0).wale_count[0, 0] == pytest.approx(50.0 / 4.4)
