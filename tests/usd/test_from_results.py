"""USD frames from simulated patches (knitsim.usd.from_results): structure, lattice, round trip, bad input.

Expected values: the patch's own history (counts, saved increments, W and C of
the cells, summed here independently into the lattice; its rest state
``group_rest`` and grip strains), the float64 forward
map :func:`knitsim.cell.quarter_loop.quarter_loop` (Y_C, W of each cell's state,
eqs 6-9), the symmetry construction of the full stitch (head apex at
x0 + W/4, A at x0 + W/2, sinker apex at x0 + 3W/4; knitsim.usd.yarn_geometry
docstring), periodicity of a uniform patch (period W along a course, C along
a wale), the grip span of a column (its rest length + grip strain x the rest
length: a slack column is drawn to it, README "USD export") and the stage label
table knitsim.cell.stages.LABEL_CODES.  Time code k is increment k, 0 the rest
state (curve.csv's numbering).
"""
from __future__ import annotations

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

from knitsim.cell.load_program import cycles  # noqa: E402
from knitsim.cell.material import CellParams  # noqa: E402
from knitsim.cell.quarter_loop import quarter_loop  # noqa: E402
from knitsim.errors import KnitsimInputError  # noqa: E402
from knitsim.io.patch_results import patch_summary, write_patch_results  # noqa: E402
from knitsim.patch.model import PatchModel  # noqa: E402
from knitsim.patch.runner import run_patch  # noqa: E402
from knitsim.usd import read_patch_usd  # noqa: E402
from knitsim.usd import yarn_geometry as yg  # noqa: E402
from knitsim.usd.from_results import (export_history, export_results, record_from_history,  # noqa: E402
                                      record_from_results)

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2
PROG = cycles(0.10, 0.40, 1, 0.1)
N_PTS = 9
SCENE = "# a scene\n[patch]\nwales = 3\n"


@pytest.fixture(scope="module")
def uniform():
    m = PatchModel.uniform(P, 3, 4)
    return m, run_patch(m, PROG, engine="warp")


@pytest.fixture(scope="module")
def mixed():
    rng = np.random.default_rng(3)
    cells = [[P.replace(phi0=float(rng.uniform(-1, 1) * np.arctan(0.2)), L=float(13.6 + 0.5 * rng.random()))
              for _ in range(3)] for _ in range(2)]
    m = PatchModel.from_cells(cells)
    return m, run_patch(m, PROG, engine="warp")


def _selected(n, stride):
    idx = list(range(0, n, stride))
    return idx + ([n - 1] if idx[-1] != n - 1 else [])


def with_rest(h, name):
    """A per-cell quantity over increments 0 (the rest state, ``h.group_rest``) .. n, shape (n + 1, courses, wales)."""
    goc = h.group_of_cell
    if name == "x":
        rest = h.group_rest["x"][goc]
    elif name in ("W", "C"):
        x = h.group_rest["x"][goc]
        ql = quarter_loop(x[..., 0], x[..., 1], x[..., 2], x[..., 3], x[..., 4], P.B, P.d)   # eq 6 at rest
        rest = ql.W if name == "W" else h.group_rest["C"][goc]
    elif name == "F":
        rest = h.group_rest["F"][goc]
    return np.concatenate([rest[None], h.cell_field(name)], axis=0)


def pitch_scale(C, grip_strain, C0):
    """Per time and column, the course pitch scale that puts the column's drawn length (the last course's
    origin + its C) at the grip span, rest length x (1 + grip strain); 1 where the cells fill it (loaded)."""
    span = C0.sum(axis=0)[None, :] * (1.0 + np.asarray(grip_strain)[:, None])
    top = C[:, -1, :]
    s = (span - top) / (C.sum(axis=1) - top)
    return np.minimum(s, 1.0)


def test_stage_structure_and_metadata(tmp_path, mixed):
    m, h = mixed
    path = tmp_path / "p.usda"
    res = export_history(h, m.fields, path, scene_text=SCENE, stride=2, n_points=N_PTS)
    sel = _selected(h.n_increments + 1, 2)                              # increments 0 (rest) .. n
    stage = Usd.Stage.Open(str(path))
    assert stage
    curves = [p for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]
    assert len(curves) == m.courses                                     # one yarn per course
    for c in curves:
        bc = UsdGeom.BasisCurves(c)
        assert list(bc.GetCurveVertexCountsAttr().Get()) == [m.wales * 4 * (N_PTS - 1) + 1]
        assert bc.GetPointsAttr().GetTimeSamples() == [float(k) for k in sel]
    assert UsdGeom.GetStageMetersPerUnit(stage) == 0.001
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, float(h.n_increments))
    info = stage.GetRootLayer().customLayerData["knitsim"]
    assert info["scene"] == SCENE
    assert list(info["frame_indices"]) == sel
    np.testing.assert_array_equal(np.array(info["frame_scalars"]["grip_strain"]),
                                  np.concatenate([[0.0], h.grip_strain])[sel])
    assert info["timeline"]["time_code_0_is_increment"] == 0 and info["timeline"]["stride"] == 2
    assert info["metadata"]["fallback_cells"] == ",".join("0" for _ in sel)
    assert list(res.time_codes) == [float(k) for k in sel]


def test_round_trip_cell_positions(tmp_path, mixed):
    """Apexes and A points at the cumulative W / C lattice (a slack column's pitch scaled to the grip span),
    Y_C from the float64 forward map; time code 0 is the rest state."""
    m, h = mixed
    path = tmp_path / "p.usdc"
    export_history(h, m.fields, path, stride=3, n_points=N_PTS)
    back = read_patch_usd(path)
    sel = _selected(h.n_increments + 1, 3)
    assert np.array_equal(back.time_codes, np.array(sel, float))
    x = with_rest(h, "x")[sel]                                          # (T, courses, wales, 5)
    W, C = with_rest(h, "W")[sel], with_rest(h, "C")[sel]
    Y_C = quarter_loop(x[..., 0], x[..., 1], x[..., 2], x[..., 3], x[..., 4], m.fields["B"], m.fields["d"]).Y_C
    s = pitch_scale(C, np.concatenate([[0.0], h.grip_strain])[sel], m.fields["C0"])
    assert np.any(s < 0.99)                                             # the unloading leaves slack columns
    x0 = np.concatenate([np.zeros_like(W[..., :1]), np.cumsum(W, axis=-1)[..., :-1]], axis=-1)
    y0 = np.concatenate([np.zeros_like(C[:, :1]), np.cumsum(C, axis=1)[:, :-1]], axis=1) * s[:, None, :]
    tol = 2e-6 * (np.abs(x0).max() + W.max() + np.abs(y0).max() + C.max())   # float32 positions
    np.testing.assert_allclose(back.head_apex[..., 0], x0 + W / 4, atol=tol, rtol=0)
    np.testing.assert_allclose(back.head_apex[..., 1], y0 + Y_C, atol=tol, rtol=0)
    np.testing.assert_allclose(back.A[..., 0], x0 + W / 2, atol=tol, rtol=0)
    np.testing.assert_allclose(back.A[..., 1], y0, atol=tol, rtol=0)
    np.testing.assert_allclose(back.sinker_apex[..., 0], x0 + 3 * W / 4, atol=tol, rtol=0)
    np.testing.assert_allclose(back.sinker_apex[..., 1], y0 - Y_C, atol=tol, rtol=0)
    # fields as simulated
    np.testing.assert_array_equal(back.fields["stage"][1:], h.cell_field("label")[np.array(sel[1:]) - 1])
    np.testing.assert_allclose(back.fields["force_per_wale_N"], with_rest(h, "F")[sel], rtol=1e-6)
    # extents hold every vertex (+- d/2) and the patch's lattice
    d = m.fields["d"].max()
    assert np.all(back.extents[:, :, 0, :] <= back.points.min(axis=2) - d / 2 + 1e-5)
    assert np.all(back.extents[:, :, 1, :] >= back.points.max(axis=2) + d / 2 - 1e-5)
    assert np.all(back.extents[:, :, 1, 0] >= W.sum(axis=-1) - 1e-4)


def test_uniform_patch_is_periodic(tmp_path, uniform):
    m, h = uniform
    assert h.info["n_groups"] == 1
    path = tmp_path / "u.usdc"
    export_history(h, m.fields, path, n_points=N_PTS, layout="courses")
    back = read_patch_usd(path)
    k = yg.vertices_per_cell(N_PTS)
    W, C = with_rest(h, "W")[:, 0, 0], with_rest(h, "C")[:, 0, 0]
    # the course pitch: C, or C scaled where the column is slack (the grips closer than its stacked cells)
    pitch = C * pitch_scale(with_rest(h, "C"), np.concatenate([[0.0], h.grip_strain]), m.fields["C0"])[:, 0]
    pts = back.points                                                    # (T, courses, m, 3)
    for j in range(1, m.wales):                                          # period W along the course
        shift = pts[:, :, j * k:(j + 1) * k + 1] - pts[:, :, :k + 1]
        np.testing.assert_allclose(shift[..., 0], np.broadcast_to(j * W[:, None, None], shift.shape[:-1]), atol=2e-5)
        np.testing.assert_allclose(shift[..., 1:], 0.0, atol=2e-5)
    for i in range(1, m.courses):                                        # period: the pitch along the wale
        dy = pts[:, i, :, 1] - pts[:, 0, :, 1]
        np.testing.assert_allclose(dy, np.broadcast_to(i * pitch[:, None], dy.shape), atol=2e-5)
    # the course yarn is continuous across cells: last point of cell j = first of cell j + 1 (A'')
    np.testing.assert_allclose(pts[:, :, -1, 0], np.broadcast_to(m.wales * W[:, None], pts.shape[:2]), atol=2e-5)


def test_uniform_patch_auto_layout_is_instanced_and_draws_the_same_stitches(tmp_path, uniform):
    """A patch of one distinct cell is written instanced by default; every drawn stitch equals the
    same stitch of the course-yarn layout (an independent construction: yg.course_curves), to
    float32 rounding, and the file is smaller."""
    from knitsim.usd.instanced import read_specimen_usd
    m, h = uniform
    res_i = export_history(h, m.fields, tmp_path / "i.usdc", n_points=N_PTS)
    res_c = export_history(h, m.fields, tmp_path / "c.usdc", n_points=N_PTS, layout="courses")
    spec, back = read_specimen_usd(res_i.path), read_patch_usd(res_c.path)
    assert res_i.prototypes == 1 and res_i.stitches == m.courses * m.wales
    assert np.array_equal(spec.time_codes, back.time_codes)
    k = yg.vertices_per_cell(N_PTS)
    for t in range(len(spec.time_codes)):
        pts = spec.stitch_points(t)
        for n in range(pts.shape[0]):
            i, j = int(spec.band[n]), int(spec.strip[n])
            np.testing.assert_allclose(pts[n], back.points[t, i, j * k:(j + 1) * k + 1], atol=2e-5)
    assert res_i.file_bytes < res_c.file_bytes
    with pytest.raises(KnitsimInputError, match="layout = 'rows'"):
        export_history(h, m.fields, tmp_path / "x.usda", layout="rows")


def drop_rest_state(results):
    """A results folder as a knitsim before the rest state was saved wrote it: cells.nc without
    knitsim.usd.from_results.REST_VARIABLES."""
    import xarray as xr
    from knitsim.usd.from_results import REST_VARIABLES
    nc = results / "cells.nc"
    ds = xr.load_dataset(nc, engine="h5netcdf")
    ds = ds.drop_vars([v for v in REST_VARIABLES.values() if v in ds])
    ds.to_netcdf(nc, engine="h5netcdf")


def test_results_folder_equals_history(tmp_path, mixed):
    """With the rest state in cells.nc, the results folder's file equals the history's; without it (an older
    results folder) time code k is increment k + 1, said in the file, and its samples are the history's at k + 1."""
    m, h = mixed
    out = tmp_path / "res"
    summary = patch_summary(h, h.info["ref_length_mm"])
    write_patch_results(out, h, summary, SCENE, fields=m.fields, plot=False)
    a = export_history(h, m.fields, tmp_path / "a.usdc", scene_text=SCENE, stride=2, color_by="force",
                       summary=summary)
    b = export_results(out, tmp_path / "b.usdc", stride=2, color_by="force")
    drop_rest_state(out)
    old = export_results(out, tmp_path / "old.usdc", color_by="force")
    ra, rb = read_patch_usd(a.path), read_patch_usd(b.path)
    assert np.array_equal(ra.points, rb.points) and np.array_equal(ra.time_codes, rb.time_codes)
    assert all(np.array_equal(ra.fields[n], rb.fields[n]) for n in ra.fields) and ra.fields.keys() == rb.fields.keys()
    assert np.array_equal(ra.material_id, rb.material_id)
    assert ra.info["scene"] == rb.info["scene"] == SCENE
    assert ra.info["legend"] == rb.info["legend"]
    assert ra.info["timeline"] == rb.info["timeline"] and ra.info["run"] == rb.info["run"]
    # the older folder: no rest state, time code 0 is increment 1, and the file says so
    ro = read_patch_usd(old.path)
    assert ro.info["timeline"]["time_code_0_is_increment"] == 1 and not ro.info["timeline"]["rest_state"]
    assert np.array_equal(ro.time_codes, np.arange(h.n_increments, dtype=float))
    full = read_patch_usd(export_history(h, m.fields, tmp_path / "f.usdc", color_by="force").path)
    assert np.array_equal(full.points[1:], ro.points)
    assert all(np.array_equal(full.fields[n][1:], ro.fields[n]) for n in ro.fields)


def test_a_folder_of_no_run_is_named_for_what_it_is(tmp_path):
    # a blind probe's `knitsim usd` of a sweep's folder and of a folder of other files both read "no cells.nc
    # (was the run made with output.cell_fields = false?)", of runs that never were
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    for name in ("sweep.json", "results.nc", "results.csv", "summary.json"):
        (sweep / name).write_text("{}")
    with pytest.raises(KnitsimInputError, match=r"holds the results of `knitsim sweep` \(samples of single cells"):
        record_from_results(sweep)
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("x")
    with pytest.raises(KnitsimInputError, match=r": not a results folder of `knitsim run` \(no cells\.nc, no "
                                                r"columns\.csv\)"):
        record_from_results(other)
    # a run without cells.nc (its columns.csv there): the option that leaves it out is still named
    (other / "columns.csv").write_text("increment,column\n")
    with pytest.raises(KnitsimInputError, match=r"output\.cell_fields = false"):
        record_from_results(other)


def test_bad_input(tmp_path, mixed):
    m, h = mixed
    with pytest.raises(KnitsimInputError, match="not a directory"):
        record_from_results(tmp_path / "nope")
    out = tmp_path / "res"
    old = type(h)(**{**h.__dict__, "groups": {k: v for k, v in h.groups.items() if k not in ("x", "W", "s_AB")}})
    write_patch_results(out, old, patch_summary(old, old.info["ref_length_mm"]), SCENE, fields=m.fields, plot=False)
    with pytest.raises(KnitsimInputError, match="no per-cell states"):
        record_from_results(out)
    with pytest.raises(KnitsimInputError, match="no per-cell states"):
        record_from_history(old, m.fields)
    with pytest.raises(KnitsimInputError, match="color_by = 'colour'"):
        export_history(h, m.fields, tmp_path / "x.usda", color_by="colour")
    with pytest.raises(KnitsimInputError, match="stride = 0"):
        export_history(h, m.fields, tmp_path / "x.usda", stride=0)
    with pytest.raises(KnitsimInputError, match="n_points = 4"):
        export_history(h, m.fields, tmp_path / "x.usda", n_points=4)
