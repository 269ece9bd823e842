"""USD export of knit patches: structure, round trip, metadata, bad input.

Expected values: the patch's own input (counts, time codes, lattice sums of W
and C, written independently here), USD's own extent computation
(``UsdGeom.Boundable.ComputeExtentFromPlugins``, an independent method), the
stage label table ``knitsim.cell.stages.LABEL_CODES`` and matplotlib's viridis.
"""
from __future__ import annotations

import importlib.util
import pathlib

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

from knitsim.cell.stages import LABEL_CODES  # noqa: E402
from knitsim.errors import KnitsimInputError  # noqa: E402
from knitsim.usd import read_patch_usd, render_quicklook, write_patch_usd  # noqa: E402
from knitsim.usd import yarn_geometry as yg  # noqa: E402

_spec = importlib.util.spec_from_file_location("_usd_geom_tests", pathlib.Path(__file__).with_name("test_yarn_geometry.py"))
_geom_tests = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_geom_tests)
standin_quarter = _geom_tests.standin_quarter

COURSES, WALES, N = 3, 4, 9
D = 0.5
SCENE = 'name = "demo"\n[knit]\nW0 = 4.0  # mm\nnote = """multi\nline "quoted" text"""\n'


def make_frames(n_frames=5, courses=COURSES, wales=WALES, n=N, seed=0):
    """A stretched patch: W, C, Y_C differ per cell and change with the frame."""
    rng = np.random.default_rng(seed)
    base_W = 4.0 + 0.3 * rng.random((courses, wales))
    base_C = 3.0 + 0.3 * rng.random((courses, wales))
    frames = []
    for f in range(n_frames):
        W = base_W * (1 - 0.03 * f)
        C = base_C * (1 + 0.05 * f)
        Y_C = 0.7 * C + 1.0
        q = np.empty((courses, wales, n, 2))
        for i in range(courses):
            for j in range(wales):
                q[i, j] = standin_quarter(W[i, j], Y_C[i, j], 1.3, n)[0]
        stage = rng.integers(0, 4, (courses, wales))
        frames.append({"quarter_xy": q, "W": W, "C": C, "time": 0.1 * f,
                       "fields": {"stage": stage, "phi": 0.1 * f + 0.01 * rng.random((courses, wales)),
                                  "F": rng.random((courses, wales))}})
    return frames


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    frames = make_frames(6)
    path = tmp_path_factory.mktemp("usd") / "patch.usdc"
    res = write_patch_usd(path, frames, D, material_id=np.arange(COURSES * WALES).reshape(COURSES, WALES) % 2,
                          stride=2, scene_text=SCENE, metadata={"knit": "E-glass", "n": 3}, field_units={"F": "N"})
    return frames, path, res


def test_structure_counts_and_time_samples(written):
    frames, path, res = written
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    curves = [p for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]
    assert len(curves) == COURSES                          # one yarn per course
    m = WALES * 4 * (N - 1) + 1                            # module docstring layout
    for p in curves:
        c = UsdGeom.BasisCurves(p)
        assert list(c.GetCurveVertexCountsAttr().Get()) == [m]
        # stride 2 over 6 frames: 0, 2, 4 and the last frame 5
        assert c.GetPointsAttr().GetTimeSamples() == [0.0, 2.0, 4.0, 5.0]
        assert c.GetExtentAttr().GetTimeSamples() == [0.0, 2.0, 4.0, 5.0]
        assert len(c.GetPointsAttr().Get(5.0)) == m
        assert len(c.GetWidthsAttr().Get()) == m
        np.testing.assert_allclose(np.asarray(c.GetWidthsAttr().Get()), D)
        assert c.GetTypeAttr().Get() == "cubic" and c.GetWrapAttr().Get() == "pinned"
    np.testing.assert_array_equal(res.time_codes, [0, 2, 4, 5])


def test_extents_match_usd_computation(written):
    _, path, _ = written
    stage = Usd.Stage.Open(str(path))
    for p in stage.Traverse():
        if not p.IsA(UsdGeom.BasisCurves):
            continue
        for t in (0.0, 5.0):
            mine = np.asarray(UsdGeom.BasisCurves(p).GetExtentAttr().Get(t))
            usd = np.asarray(UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(p), t))
            np.testing.assert_allclose(mine, usd, rtol=1e-6, atol=1e-6)


def test_round_trip_apex_positions(written):
    frames, path, _ = written
    back = read_patch_usd(path)
    np.testing.assert_array_equal(back.time_codes, [0, 2, 4, 5])
    for ti, f in enumerate([0, 2, 4, 5]):
        fr = frames[f]
        W, C = fr["W"], fr["C"]
        Y_C = fr["quarter_xy"][:, :, -1, 1]
        # lattice: x = W of the cells to the left + W/4, y = C of the cells below + Y_C, head at z = -d/2
        x = np.array([[W[i, :j].sum() + W[i, j] / 4 for j in range(WALES)] for i in range(COURSES)])
        y = np.array([[C[:i, j].sum() + Y_C[i, j] for j in range(WALES)] for i in range(COURSES)])
        expected = np.stack([x, y, np.full_like(x, -D / 2)], axis=-1)
        np.testing.assert_allclose(back.head_apex[ti], expected, rtol=2e-7, atol=1e-6)  # float32
        # sinker apex: point reflection of the apex about A, (3W/4, -Y_C, +d/2) in the stitch frame
        xs = x + W / 2
        ys = y - 2 * Y_C
        np.testing.assert_allclose(back.sinker_apex[ti][..., :2], np.stack([xs, ys], -1), rtol=2e-7, atol=1e-6)
        # per-cell fields
        np.testing.assert_array_equal(back.fields["stage"][ti], fr["fields"]["stage"])
        np.testing.assert_allclose(back.fields["phi"][ti], fr["fields"]["phi"], rtol=1e-7)
    np.testing.assert_array_equal(back.material_id, np.arange(COURSES * WALES).reshape(COURSES, WALES) % 2)


def test_metadata(written):
    _, path, _ = written
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 0.001
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetStartTimeCode() == 0.0 and stage.GetEndTimeCode() == 5.0
    info = stage.GetRootLayer().customLayerData["knitsim"]
    assert info["scene"] == SCENE
    assert info["metadata"] == {"knit": "E-glass", "n": 3}
    assert list(info["frame_indices"]) == [0, 2, 4, 5]
    np.testing.assert_allclose(list(info["time_s"]), [0.0, 0.2, 0.4, 0.5])
    assert stage.GetDefaultPrim().GetPath() == "/Patch"


def test_stage_colours_follow_the_legend(written):
    frames, path, _ = written
    stage = Usd.Stage.Open(str(path))
    info = stage.GetRootLayer().customLayerData["knitsim"]
    legend = info["legend"]
    # the legend's labels are the stage table's, in code order
    assert list(legend["labels"]) == sorted(LABEL_CODES, key=LABEL_CODES.get)
    hexes = list(legend["colors_hex"])
    c = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Patch/Yarns/course_0001"))
    col = np.asarray(UsdGeom.PrimvarsAPI(c).GetPrimvar("displayColor").ComputeFlattened(5.0))
    stage_codes = frames[5]["fields"]["stage"][1]
    apex = yg.landmark_index("head_apex", N, np.arange(WALES))
    for j in range(WALES):
        want = [int(hexes[stage_codes[j]][k:k + 2], 16) / 255 for k in (1, 3, 5)]
        np.testing.assert_allclose(col[apex[j]], want, atol=1e-6)


def test_continuous_colour_and_usda(tmp_path):
    import matplotlib
    frames = make_frames(2, courses=2, wales=2, n=5)
    frames[0]["fields"]["F"][:] = [[0.0, 1.0], [np.nan, 0.5]]
    frames[1]["fields"]["F"][:] = [[2.0, 1.0], [1.0, 1.0]]
    path = tmp_path / "small.usda"
    write_patch_usd(path, frames, 0.3, color_by="F", field_units={"F": "N"}, curve_basis="linear")
    text = path.read_text()
    assert text.startswith("#usda")
    stage = Usd.Stage.Open(str(path))
    legend = stage.GetRootLayer().customLayerData["knitsim"]["legend"]
    assert (legend["vmin"], legend["vmax"], legend["units"]) == (0.0, 2.0, "N")   # over all frames
    c0 = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Patch/Yarns/course_0000"))
    assert c0.GetTypeAttr().Get() == "linear"
    col = np.asarray(UsdGeom.PrimvarsAPI(c0).GetPrimvar("displayColor").ComputeFlattened(0.0))
    apex = yg.landmark_index("head_apex", 5, np.arange(2))
    viridis = matplotlib.colormaps["viridis"]
    np.testing.assert_allclose(col[apex[0]], viridis(0.0)[:3], atol=1e-6)      # F = vmin
    np.testing.assert_allclose(col[apex[1]], viridis(128 / 255)[:3], atol=1e-6)  # F = mid: bin 128 of 256
    c1 = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Patch/Yarns/course_0001"))
    col1 = np.asarray(UsdGeom.PrimvarsAPI(c1).GetPrimvar("displayColor").ComputeFlattened(0.0))
    np.testing.assert_allclose(col1[apex[0]], [1.0, 0.0, 1.0], atol=1e-6)       # NaN: missing colour


def test_stacked_frames_equal_sequence(tmp_path):
    frames = make_frames(3, courses=2, wales=2, n=5)
    stacked = {"quarter_xy": np.stack([f["quarter_xy"] for f in frames]),
               "W": np.stack([f["W"] for f in frames]), "C": np.stack([f["C"] for f in frames]),
               "time": [f["time"] for f in frames],
               "fields": {k: np.stack([f["fields"][k] for f in frames]) for k in frames[0]["fields"]}}
    a = read_patch_usd(write_patch_usd(tmp_path / "a.usdc", frames, 0.3).path)
    b = read_patch_usd(write_patch_usd(tmp_path / "b.usdc", stacked, 0.3).path)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.fields["stage"], b.fields["stage"])
    # decimated: 4 points per quarter -> 12 vertices per cell; apexes unchanged
    c = read_patch_usd(write_patch_usd(tmp_path / "c.usdc", frames, 0.3, points_per_quarter=4).path)
    assert c.points.shape == (3, 2, 2 * 12 + 1, 3)
    np.testing.assert_allclose(c.head_apex, a.head_apex, atol=1e-6)


def test_quicklook_png(written, tmp_path):
    import matplotlib.image as mpimg
    _, path, _ = written
    png = render_quicklook(path, tmp_path / "q.png", dpi=60)
    img = mpimg.imread(png)
    assert img.ndim == 3 and img.shape[1] > img.shape[0]          # two panels side by side
    # the yarn is drawn: many pixels are neither white nor black
    rgb = img[..., :3]
    coloured = (rgb.max(axis=-1) - rgb.min(axis=-1)) > 0.2
    assert coloured.mean() > 0.01
    # decimated drawing (large patches) still draws the yarn
    img2 = mpimg.imread(render_quicklook(path, tmp_path / "q2.png", dpi=60, max_vertices=500))
    assert ((img2[..., :3].max(axis=-1) - img2[..., :3].min(axis=-1)) > 0.2).mean() > 0.01


@pytest.mark.parametrize("mutate, match", [
    (lambda fr: fr.__setitem__("W", fr["W"][:, :-1]), r"\['W'\] must have shape"),
    (lambda fr: fr["quarter_xy"].__setitem__((0, 1, 3, 0), np.nan), r"\['quarter_xy'\] has a non-finite"),
    (lambda fr: fr["fields"].__setitem__("F", np.ones((5, 5))), r"\['F'\] must have shape"),
    (lambda fr: fr["fields"]["stage"].__setitem__((0, 0), 7), r"\['stage'\] = 7"),
    (lambda fr: fr.__setitem__("C", -fr["C"]), r"\['C'\] must be finite and > 0"),
])
def test_bad_frames_raise(tmp_path, mutate, match):
    frames = make_frames(2, courses=2, wales=3, n=5)
    mutate(frames[1])
    with pytest.raises(KnitsimInputError, match=match):
        write_patch_usd(tmp_path / "bad.usdc", frames, 0.3)


def test_bad_options_raise(tmp_path):
    frames = make_frames(2, courses=2, wales=3, n=5)
    with pytest.raises(KnitsimInputError, match="color_by='Rn'"):
        write_patch_usd(tmp_path / "x.usdc", frames, 0.3, color_by="Rn")
    with pytest.raises(KnitsimInputError, match="stride"):
        write_patch_usd(tmp_path / "x.usdc", frames, 0.3, stride=0)
    with pytest.raises(KnitsimInputError, match="path="):
        write_patch_usd(tmp_path / "x.abc", frames, 0.3)
    with pytest.raises(KnitsimInputError, match="^d must"):
        write_patch_usd(tmp_path / "x.usdc", frames, np.ones((3, 3)))
    frames[1]["quarter_xy"] = frames[1]["quarter_xy"][:, :, :4]
    with pytest.raises(KnitsimInputError, match=r"frames\[1\]\['quarter_xy'\] has shape"):
        write_patch_usd(tmp_path / "x.usdc", frames, 0.3)
