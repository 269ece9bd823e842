"""``knitsim run --usd`` and ``knitsim usd``: files open in USD, match the run, quick-look, bad input exits 2.

Expected values: the run's own saved outputs (curve.csv rows = increments 0
(rest) .. n, scene.resolved.toml text, summary.json cell counts), the vertex
count of the symmetric full stitch (4 (n - 1) per cell + 1 per course,
knitsim.usd.yarn_geometry) and the stride rule (increments 0, s, 2s, ..., last,
counted from the rest state; time code = increment).  ``knitsim usd`` of a
results folder whose cells.nc holds no rest state draws increments 1 .. n at
time codes 0 .. n - 1 and says so (customLayerData knitsim.timeline).
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

from knitsim.cli import main  # noqa: E402
from knitsim.usd import read_patch_usd  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "random_phi0.toml"
SMALL = ["--set", "patch.wales=2", "--set", "patch.courses=3", "--set", "load.max_increment=0.05"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("run")
    rc = main(["run", str(SCENE), "--out", str(tmp / "o"), "--no-progress", "--json", *SMALL,
               "--usd", str(tmp / "run.usda"), "--usd-stride", "3", "--color-by", "phi"])
    assert rc in (0, 1)
    return tmp


def test_run_usd_file(run_dir):
    n = sum(1 for _ in open(run_dir / "o" / "curve.csv")) - 2            # saved increments (header, rest row)
    sel = list(range(0, n + 1, 3)) + ([n] if n % 3 else [])            # increments 0 (rest) .. n
    stage = Usd.Stage.Open(str(run_dir / "run.usda"))
    curves = [UsdGeom.BasisCurves(p) for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]
    assert len(curves) == 3                                              # one per course
    for c in curves:
        assert list(c.GetCurveVertexCountsAttr().Get()) == [2 * 4 * (9 - 1) + 1]
        assert c.GetPointsAttr().GetTimeSamples() == [float(k) for k in sel]
    assert UsdGeom.GetStageMetersPerUnit(stage) == 0.001 and UsdGeom.GetStageUpAxis(stage) == "Z"
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, float(n))
    info = stage.GetRootLayer().customLayerData["knitsim"]
    assert info["timeline"]["time_code_0_is_increment"] == 0 and info["timeline"]["increments_in_run"] == n
    # the run's warnings, as summary.json holds them
    summary = json.loads((run_dir / "o" / "summary.json").read_text())
    assert list(info["run"]["warning_codes"]) == [w["code"] for w in summary["warnings"]]
    assert info["scene"] == (run_dir / "o" / "scene.resolved.toml").read_text()
    assert info["color_by"] == "phi" and info["legend"]["units"] == "rad"
    back = read_patch_usd(run_dir / "run.usda")
    ext = back.extents
    assert np.all(ext[:, :, 0, :2] <= back.points[..., :2].min(axis=2)) and np.all(
        ext[:, :, 1, :2] >= back.points[..., :2].max(axis=2))


def test_usd_from_results_equals_run_export(run_dir, capsys):
    # the results folder's cells.nc holds the rest state (rest_state_*): time code k is increment k, 0 the rest
    # state (said in the --json document), and every sample equals the run's own file
    full = run_dir / "full.usda"
    assert main(["run", str(SCENE), "--out", str(run_dir / "o1"), "--no-progress", *SMALL,
                 "--usd", str(full), "--color-by", "phi"]) in (0, 1)
    capsys.readouterr()
    out = run_dir / "again.usdc"
    png = run_dir / "ql.png"
    rc = main(["usd", str(run_dir / "o1"), "--out", str(out), "--color-by", "phi",
               "--quicklook", str(png), "--json"])
    assert rc == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert doc["courses"] == 3 and doc["wales"] == 2 and doc["time_code_0_is_increment"] == 0
    a, b = read_patch_usd(full), read_patch_usd(out)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.time_codes, b.time_codes)
    assert a.fields.keys() == b.fields.keys() and all(np.array_equal(a.fields[k], b.fields[k]) for k in a.fields)
    assert a.info["scene"] == b.info["scene"]
    assert b.info["timeline"]["time_code_0_is_increment"] == 0 and a.info["timeline"] == b.info["timeline"]
    import matplotlib.image as mpimg
    img = mpimg.imread(png)
    assert img.shape[0] > 100 and img.shape[1] > 100
    assert np.mean(np.any(img[..., :3] < 0.9, axis=-1)) > 0.02          # not blank: yarn drawn


def test_usd_of_a_run_that_warned_of_held_forces_says_so(run_dir, tmp_path, capsys):
    # the run's folder with a summary.json warning that its cells failed (hand-written): the USD file shows
    # those held states too, so knitsim usd repeats the warning (stderr, and --json run_warnings); an
    # unrelated warning (heads overlap) is not repeated
    folder = tmp_path / "o"
    shutil.copytree(run_dir / "o", folder)
    doc = json.loads((folder / "summary.json").read_text())
    doc["warnings"] = [{"code": "run_stopped_by_failed_cells", "message": "1 cell(s) failed from grip strain 0.2"},
                       {"code": "heads_interpenetrate", "message": "heads overlap"}]
    (folder / "summary.json").write_text(json.dumps(doc))
    assert main(["usd", str(folder), "--out", str(tmp_path / "x.usda")]) == 0
    err = capsys.readouterr().err
    assert "warning: the run shown" in err and "run_stopped_by_failed_cells: 1 cell(s) failed" in err
    assert "heads overlap" not in err
    assert main(["usd", str(folder), "--out", str(tmp_path / "y.usda"), "--json"]) == 0
    assert [w["code"] for w in json.loads(capsys.readouterr().out)["run_warnings"]] == ["run_stopped_by_failed_cells"]


@pytest.mark.parametrize("argv,needle", [
    (["usd", "{tmp}/missing", "--out", "{tmp}/x.usda"], "not a directory"),
    (["usd", "{tmp}/nostate", "--out", "{tmp}/x.usda"], "no per-cell states"),
    # a set without summary.json (written last): a run stopped while writing its results (a blind probe)
    (["usd", "{tmp}/nosummary", "--out", "{tmp}/x.usda"], "no summary.json"),
    # a summary.json that does not read (a blind probe's `echo '{' > summary.json` exported, its warnings dropped)
    (["usd", "{tmp}/badsummary", "--out", "{tmp}/x.usda"], "its summary.json does not read"),
    (["usd", "{tmp}/listsummary", "--out", "{tmp}/x.usda"], "its summary.json holds no summary (a list)"),
    (["usd", "{run}/o", "--out", "{tmp}/x.usda", "--color-by", "colour"], "--color-by = 'colour'"),
    (["usd", "{run}/o", "--out", "{tmp}/x.usda", "--stride", "0"], "--stride = 0"),
    (["usd", "{run}/o", "--out", "{tmp}/x.obj"], "must end in .usda"),
    (["run", str(SCENE), "--out", "{tmp}/r", "--usd", "{tmp}/x.usda", "--usd-stride", "0"], "--usd-stride = 0"),
])
def test_bad_input_exits_2(run_dir, tmp_path, capsys, argv, needle):
    import xarray as xr
    (tmp_path / "nostate").mkdir()
    with xr.open_dataset(run_dir / "o" / "cells.nc", engine="h5netcdf") as ds:
        ds.drop_vars([v for v in ds.data_vars if v.startswith("state_")]).to_netcdf(
            tmp_path / "nostate" / "cells.nc", engine="h5netcdf")
    shutil.copy(run_dir / "o" / "summary.json", tmp_path / "nostate")
    shutil.copytree(run_dir / "o", tmp_path / "nosummary")
    (tmp_path / "nosummary" / "summary.json").unlink()
    shutil.copytree(run_dir / "o", tmp_path / "badsummary")
    (tmp_path / "badsummary" / "summary.json").write_text("{\n")
    shutil.copytree(run_dir / "o", tmp_path / "listsummary")
    (tmp_path / "listsummary" / "summary.json").write_text("[]\n")
    argv = [a.format(tmp=tmp_path, run=run_dir) for a in argv]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2
    lines = [ln for ln in err.strip().splitlines() if "CUDA" not in ln]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in err


ZONED = """
title = "E-glass below basalt"
[patch]
wales = 2
courses = 4
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[[zones]]
label = "basalt"
courses = [2, 4]
yarn = { material = "basalt" }
knit = { material = "basalt_plain" }
[load]
type = "monotonic"
target_strain = 0.1
max_increment = 0.05
"""


def test_quicklook_of_a_zoned_patch_names_the_scene_the_patch_and_each_colour(tmp_path, capsys, monkeypatch):
    # Hand-made: E-glass (Table 1: d 0.58 mm, B 0.31 N mm^2, m 0.20; L 14.1 mm, section 2.2) on courses 0-1,
    # a zone of basalt (d 0.56, B 0.20, m 0.17; L 13.1) on courses 2-3, 4 cells each.  Material ids follow the
    # sorted parameters, d first: basalt is 0.  Before, the title was "specimen of 4 x 2 blocks (bands x
    # strips)" for this patch of single stitches, and the legend read "material_id: 0, 1".
    from matplotlib.figure import Figure
    drawn = []
    real = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (drawn.append(fig), real(fig, *a, **k))[1])
    (tmp_path / "z.toml").write_text(ZONED)
    assert main(["run", str(tmp_path / "z.toml"), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    drawn.clear()
    assert main(["usd", str(tmp_path / "o"), "--out", str(tmp_path / "m.usda"), "--color-by", "material",
                 "--quicklook", str(tmp_path / "m.png")]) == 0
    capsys.readouterr()
    (fig,) = drawn
    assert fig._suptitle.get_text().splitlines() == [
        "E-glass below basalt", "patch of 4 courses x 2 wales (single stitches, drawn instanced); m.usda; colour: "
        "material"]
    (legend,) = fig.legends
    assert legend.get_title().get_text() == "material (material_id)"
    assert [t.get_text().replace("\n    ", " ") for t in legend.get_texts()] == [
        "0: zone 'basalt' (basalt / basalt_plain): d 0.56 mm, B 0.2 N mm^2, m 0.17, L 13.1 mm; 4 cells",
        "1: base knit (e_glass / e_glass_plain): d 0.58 mm, B 0.31 N mm^2, m 0.2, L 14.1 mm; 4 cells"]
    # the file says it too, beside the material_id primvar
    stage = Usd.Stage.Open(str(tmp_path / "m.usda"))
    info = stage.GetRootLayer().customLayerData["knitsim"]
    assert list(info["materials"]["codes"]) == [0, 1] and list(info["materials"]["labels"])[0].startswith(
        "zone 'basalt'")
    # a continuous colour: its quantity with units on the colour bar and in the title
    drawn.clear()
    assert main(["usd", str(tmp_path / "o"), "--out", str(tmp_path / "f.usda"), "--color-by", "force",
                 "--quicklook", str(tmp_path / "f.png")]) == 0
    (fig,) = drawn
    assert fig._suptitle.get_text().endswith("colour: force per wale of the cell [N]")
    assert "force per wale of the cell [N]" in [a.get_ylabel() for a in fig.axes]
