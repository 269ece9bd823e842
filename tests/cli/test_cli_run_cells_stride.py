"""``output.cells_stride``: cells.nc written at a stride, read back and drawn by ``knitsim usd``.

Where the expected values come from:

- the increments: the scene's own cycle definition, counted by hand.  ``cycles`` loads 0 -> 0.30, unloads
  to 0.10, twice, each leg cut into ceil(leg / max_increment) equal steps (knitsim.cell.load_program,
  section 2.3 programs): 0.30 / 0.03 = 10 loading steps, 0.20 / 0.03 -> 7 steps per later leg, so the grip
  turns after increments 10 (peak), 17 (valley) and 24 (peak) and the run ends at 31.  The same turning
  points are read again from curve.csv's ``direction`` column (the last row before it changes), written by
  another writer than cells.nc's;
- the rule of the option (README, "cells.nc at a stride"): the increments at multiples of s, the turning
  points and the last;
- the values: the stride-1 run of the same scene (every variable of the strided file at its increments is
  the stride-1 file's at the same increments, ``.sel(increment=...)``), and ``knitsim usd`` of the stride-1
  folder (its points at the strided file's time codes), read with pxr's own Usd API.
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from knitsim.cli import main

SCENE = """title = "3 x 4 E-glass patch, random phi0, two cycles"
engine = "warp"
device = "cpu"
seed = 7
[patch]
wales = 3
courses = 4
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.20
[rules]
force_cap_N = 10.0
[maps.phi0]
type = "random"
low = -1.0
high = 1.0
scale = "phimax"
[load]
type = "cycles"
lower_strain = 0.10
upper_strain = 0.30
cycles = 2
max_increment = 0.03
[output]
plot = false
checkpoint_every = 0
"""
N = 31                      # 10 + 3 x 7 increments (module docstring)
TURNS = [10, 17, 24]        # the last increment of each leg but the last
STRIDE = 4


def expected_increments(stride: int) -> list[int]:
    """The rule, from the hand count: multiples of the stride, the turning points, the last."""
    return sorted({k for k in range(1, N + 1) if k % stride == 0} | set(TURNS) | {N})


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("stride")
    scene = tmp / "patch.toml"
    scene.write_text(SCENE)
    for name, extra in (("s1", []), ("s4", ["--set", f"output.cells_stride={STRIDE}"])):
        rc = main(["run", str(scene), "--out", str(tmp / name), "--no-progress", *extra])
        assert rc in (0, 1)
    return tmp


def test_the_selection_rule_by_hand():
    """knitsim.arrays: the rule shared by cells.nc and the USD's --stride, on cases counted by hand."""
    from knitsim.arrays import stride_select, turning_rows
    assert list(stride_select(range(0, 11), 3)) == [0, 3, 6, 9, 10]          # the USD's 0, s, 2s, ..., last
    assert list(stride_select(range(1, 8), 10, keep=[3])) == [3, 7]         # a stride past the run: kept + last
    assert list(stride_select(range(1, 8), 1)) == list(range(1, 8))
    assert list(stride_select([], 3)) == []
    assert list(turning_rows([1, 1, -1, -1, 1])) == [1, 3] and list(turning_rows([1])) == []


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_strided_file_holds_the_multiples_the_turning_points_and_the_last(runs):
    import xarray as xr
    rows = _csv(runs / "s4" / "curve.csv")[1:]                          # row 0 is the rest state
    assert [int(r["increment"]) for r in rows] == list(range(1, N + 1))   # curve.csv keeps every increment
    d = [r["direction"] for r in rows]
    assert [int(rows[i]["increment"]) for i in range(N - 1) if d[i] != d[i + 1]] == TURNS
    want = expected_increments(STRIDE)
    assert want == [4, 8, 10, 12, 16, 17, 20, 24, 28, 31]
    with xr.open_dataset(runs / "s4" / "cells.nc", engine="h5netcdf") as s4, \
            xr.open_dataset(runs / "s1" / "cells.nc", engine="h5netcdf") as s1:
        assert list(s4["increment"].values) == want
        assert list(s1["increment"].values) == list(range(1, N + 1))
        assert set(s4.variables) == set(s1.variables)
        timed = [v for v in s1.variables if "increment" in s1[v].dims]
        # every per-increment variable: per-cell fields, group states, column forces and statuses, grip force,
        # head gaps, and the grip_strain / cycle / direction coordinates
        assert {"strain", "state_x", "state_W", "state_C", "state_s_AB", "column_force_N", "column_status",
                "force_N", "head_gap", "grip_strain", "cycle", "direction"} <= set(timed)
        for v in s1.variables:
            a = s1[v].sel(increment=want) if v in timed else s1[v]
            assert a.identical(s4[v]), v
        # ds.sel(increment=k) still reads increment k: the valley of cycle 1, by its grip strain in curve.csv
        assert float(s4["grip_strain"].sel(increment=17)) == float(rows[16]["grip_strain"]) == pytest.approx(0.10)
        assert s4.attrs["cells_stride"] == STRIDE and "cells_stride" not in s1.attrs
        assert s4.attrs["increments_written"].startswith(f"increments at multiples of {STRIDE}, the program's "
                                                         "turning points")
        assert f"{len(want)} of the run's {N} increments" in s4.attrs["increments_written"]
    # the other outputs hold every increment, as at stride 1
    for name in ("curve.csv", "columns.csv"):
        assert (runs / "s4" / name).read_bytes() == (runs / "s1" / name).read_bytes()
    s1s, s4s = (json.loads((runs / n / "summary.json").read_text()) for n in ("s1", "s4"))
    assert "cells_nc" not in s1s
    assert s4s["cells_nc"]["cells_stride"] == STRIDE and s4s["cells_nc"]["increments_in_file"] == len(want)
    assert s4s["cells_nc"]["increments_in_run"] == N
    assert "cells_stride = 4" in (runs / "s4" / "scene.resolved.toml").read_text()
    assert "cells_stride = 1" in (runs / "s1" / "scene.resolved.toml").read_text()


@pytest.mark.parametrize("value, said", [("0", "output.cells_stride = 0: must be >= 1"),
                                         ("-1", "output.cells_stride = -1: must be >= 1"),
                                         ("2.5", "output.cells_stride = \"2.5\": expected a whole number"),
                                         ("true", "output.cells_stride = \"true\": expected a whole number"),
                                         ('"x"', "output.cells_stride = \"\\\"x\\\"\": expected a whole number"),
                                         ("x", "output.cells_stride = \"x\": expected a whole number")])
def test_a_bad_stride_is_refused_before_any_work(tmp_path, capsys, value, said):
    scene = tmp_path / "patch.toml"
    scene.write_text(SCENE)
    rc = main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress", "--set",
               f"output.cells_stride={value}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0] == f"knitsim: error: {scene}: {said}", err
    assert not (tmp_path / "o").exists()


def test_a_bad_stride_in_the_scene_file_is_refused(tmp_path, capsys):
    scene = tmp_path / "patch.toml"
    scene.write_text(SCENE + "cells_stride = 2.5\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"knitsim: error: {scene}: output.cells_stride = 2.5: expected a whole number"]


def _points(path):
    """Time codes and the points of every course yarn at each, by pxr's own API."""
    from pxr import Usd, UsdGeom
    stage = Usd.Stage.Open(str(path))
    curves = sorted((UsdGeom.BasisCurves(p) for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)),
                    key=lambda c: str(c.GetPath()))
    codes = curves[0].GetPointsAttr().GetTimeSamples()
    assert all(c.GetPointsAttr().GetTimeSamples() == codes for c in curves)
    root = stage.GetPrimAtPath("/Patch")
    pts = {t: [np.asarray(c.GetPointsAttr().Get(t)) for c in curves] for t in codes}
    scal = {t: (root.GetAttribute("knitsim:grip_strain").Get(t),
                np.asarray(root.GetAttribute("knitsim:column_slack_mm").Get(t))) for t in codes}
    info = dict(stage.GetRootLayer().customLayerData["knitsim"]["timeline"])
    return codes, pts, scal, info


def test_usd_of_a_strided_folder_draws_its_increments_as_the_full_folder_does(runs, capsys):
    pytest.importorskip("pxr")
    for name in ("s1", "s4"):
        assert main(["usd", str(runs / name), "--out", str(runs / f"{name}.usdc")]) == 0
    assert main(["usd", str(runs / "s4"), "--out", str(runs / "s4_2.usdc"), "--stride", "2"]) == 0
    err = capsys.readouterr().err
    assert f"the results hold {len(expected_increments(STRIDE))} of the run's {N} increments" in err
    want = expected_increments(STRIDE)
    c1, p1, r1, _ = _points(runs / "s1.usdc")
    c4, p4, r4, info = _points(runs / "s4.usdc")
    assert c1 == [float(k) for k in range(N + 1)]                       # 0 the rest state, then every increment
    assert c4 == [0.0] + [float(k) for k in want]                       # 0 the rest state, then the saved ones
    for t in c4:
        assert all(np.array_equal(a, b) for a, b in zip(p1[t], p4[t])), t
        # the grip strain and the columns' slack lengths (columns.csv's rows of the saved increments)
        assert r1[t][0] == r4[t][0] and np.array_equal(r1[t][1], r4[t][1]), t
    assert list(info["saved_increments"]) == want and info["saved_increments_are"].startswith("sparse")
    assert info["increments_in_run"] == N and info["last_increment_written"] == N
    # --stride 2 of the saved increments: those at multiples of 2, and the last
    c2, _, _, _ = _points(runs / "s4_2.usdc")
    assert c2 == [0.0] + [float(k) for k in want if k % 2 == 0] + [float(N)]


def test_run_usd_draws_every_increment_whatever_the_cells_stride(runs):
    """``knitsim run --usd`` draws from the run itself, not from cells.nc: every increment at --usd-stride 1."""
    pytest.importorskip("pxr")
    scene = runs / "patch.toml"
    assert main(["run", str(scene), "--out", str(runs / "u4"), "--no-progress", "--set",
                 f"output.cells_stride={STRIDE}", "--usd", str(runs / "u4.usdc")]) in (0, 1)
    if not (runs / "s1.usdc").exists():
        assert main(["usd", str(runs / "s1"), "--out", str(runs / "s1.usdc")]) == 0
    c1, p1, _, _ = _points(runs / "s1.usdc")
    cu, pu, _, info = _points(runs / "u4.usdc")
    assert cu == c1 and "saved_increments" not in info
    assert all(np.array_equal(a, b) for t in c1 for a, b in zip(p1[t], pu[t]))
