"""USD time codes of a run: time code 0 the rest state, time code k increment k, the stride counted from
rest, increments the knit did not reach left out, the run's warnings and the code legends in the file.

Expected values come from the run's own results files, read here independently of the exporter:
curve.csv (row 0 is the rest state: grip strain 0 and its force per wale; row k increment k;
``columns_held``), columns.csv (``status``), cells.nc (strain at ``increment=k``, the ``flag_meanings`` of
``status``) and summary.json (``warnings``); the rest geometry from the cell's Table 4 initial state
(C = C0, W = W0: the cell parameters); the stride rule (0, s, 2s, ..., and the last).
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd  # noqa: E402

from knitsim.cell.load_program import cycles  # noqa: E402
from knitsim.cell.material import CellParams  # noqa: E402
from knitsim.cell.stages import LABEL_CODES  # noqa: E402
from knitsim.io.patch_results import patch_summary, write_patch_results  # noqa: E402
from knitsim.patch.model import PatchModel  # noqa: E402
from knitsim.patch.runner import run_patch  # noqa: E402
from knitsim.usd import read_patch_usd  # noqa: E402
from knitsim.usd import yarn_geometry as yg  # noqa: E402
from knitsim.usd.from_results import export_history, export_results  # noqa: E402
from knitsim.usd.instanced import read_specimen_usd  # noqa: E402

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2
PROG = cycles(0.10, 0.30, 1, 0.05)          # the tester's uni.toml: 10 increments, slack at the end
COURSES, WALES = 5, 4


def _run(params, tmp):
    m = PatchModel.uniform(params, COURSES, WALES)
    h = run_patch(m, PROG, engine="warp")
    summary = patch_summary(h, h.info["ref_length_mm"], model=m)
    out = tmp / "res"
    write_patch_results(out, h, summary, "# uniform\n", model=m, plot=False)
    return m, h, summary, out


@pytest.fixture(scope="module")
def uniform(tmp_path_factory):
    return _run(P, tmp_path_factory.mktemp("uniform"))


@pytest.fixture(scope="module")
def capped(tmp_path_factory):
    """The tester's repro: rules.force_cap_N = 0.09, reached at grip strain 0.15 (increment 3)."""
    return _run(P.replace(force_cap_N=0.09), tmp_path_factory.mktemp("capped"))


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _root_attr(path, name, t):
    stage = Usd.Stage.Open(str(path))            # held: a prim of a dropped stage has expired
    return stage.GetPrimAtPath("/Patch").GetAttribute(name).Get(t)


def test_time_code_0_is_the_rest_state_and_k_is_increment_k(tmp_path, uniform):
    m, h, _, out = uniform
    res = export_history(h, m.fields, tmp_path / "c.usdc", layout="courses")
    back = read_patch_usd(res.path)
    curve = _csv(out / "curve.csv")
    assert np.array_equal(back.time_codes, np.arange(len(curve), dtype=float))      # increments 0 .. n
    for row in curve:
        k = int(row["increment"])
        assert _root_attr(res.path, "knitsim:grip_strain", k) == pytest.approx(float(row["grip_strain"]), abs=1e-15)
    # time code 0: the rest state, force per wale of curve.csv's row 0 in every cell, and the Table 4 geometry
    # (C = C0, W = W0): A at x = j W0 + W0/2, y = i C0
    np.testing.assert_allclose(back.fields["force_per_wale_N"][0], float(curve[0]["force_per_wale_N"]), rtol=1e-6)
    assert np.all(back.fields["stage"][0] == LABEL_CODES["adherence"]) and np.all(back.fields["strain"][0] == 0)
    i, j = np.meshgrid(np.arange(COURSES), np.arange(WALES), indexing="ij")
    np.testing.assert_allclose(back.A[0, ..., 0], j * P.W0 + P.W0 / 2, atol=1e-5)
    np.testing.assert_allclose(back.A[0, ..., 1], i * P.C0, atol=1e-5)
    # time code k: cells.nc's increment k
    import xarray as xr
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        for k in range(1, h.n_increments + 1):
            np.testing.assert_allclose(back.fields["strain"][k], ds["strain"].sel(increment=k).values, atol=1e-7)


def test_stride_counts_from_the_rest_state_and_keeps_the_last(tmp_path, uniform):
    m, h, _, _ = uniform
    for layout, read in (("courses", read_patch_usd), ("instanced", read_specimen_usd)):
        res = export_history(h, m.fields, tmp_path / f"{layout}.usda", stride=3, layout=layout)
        assert list(read(res.path).time_codes) == [0, 3, 6, 9, 10]                  # n = 10 increments
        info = read(res.path).info
        # what the file says of its time samples (no "frames_in_input": it named the written count)
        assert "frames_in_input" not in info
        assert info["timeline"]["time_samples"] == 5 and info["timeline"]["increments_in_run"] == 10
        assert info["timeline"]["stride"] == 3 and info["timeline"]["time_code_0_is_increment"] == 0


def test_a_run_cut_by_the_force_cap_writes_the_increments_the_knit_reached(tmp_path, capped):
    """columns.csv: every column is 'stopped' from increment 3 to the end (curve.csv columns_held = 4): the
    knit stays as at increment 3 while the grip goes on; only increments 0..3 are written."""
    m, h, summary, out = capped
    rows = _csv(out / "curve.csv")
    held = [int(r["increment"]) for r in rows if int(r["columns_held"]) == WALES]
    first = held[0]
    assert held == list(range(first, h.n_increments + 1)) and first == 3           # the tail the knit did not reach
    assert all(r["status"] == "stopped" for r in _csv(out / "columns.csv") if int(r["increment"]) >= first)
    # the history and the results folder (cells.nc's rest_state_*) both have the rest state: time code = increment
    for res, off in ((export_history(h, m.fields, tmp_path / "h.usda", summary=summary), 0),
                     (export_results(out, tmp_path / "r.usda"), 0)):
        u = read_specimen_usd(res.path)
        assert list(u.time_codes) == list(range(0, first + 1 - off))
        tl = u.info["timeline"]
        assert tl["last_increment_written"] == first and tl["increments_not_written"] == f"{first + 1}-{h.n_increments}"
        # the run's warnings (summary.json) and flags, and the legend of the status codes (cells.nc's own)
        doc = json.loads((out / "summary.json").read_text())
        assert list(u.info["run"]["warning_codes"]) == [w["code"] for w in doc["warnings"]]
        assert {"force_cap_reached", "program_cut_by_force_cap"} <= set(u.info["run"]["warning_codes"])
        assert u.info["run"]["all_expected_end"] == doc["all_expected_end"]
        assert u.info["run"]["grip_strain_at_force_cap"] == doc["grip_strain_at_force_cap"]
        import xarray as xr
        with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
            meanings = ds["status"].attrs["flag_meanings"].split()
            codes = [int(c) for c in ds["status"].attrs["flag_values"]]
        assert list(u.info["field_legends"]["status"]["labels"]) == meanings
        assert list(u.info["field_legends"]["status"]["codes"]) == codes
        # the increment reaching the cap is drawn, its columns marked held (curve.csv columns_held)
        assert list(_root_attr(res.path, "knitsim:column_held", first - off)) == [1] * WALES
        assert _root_attr(res.path, "knitsim:columns_held", first - off) == WALES
        assert list(_root_attr(res.path, "knitsim:column_held", first - 1 - off)) == [0] * WALES


def test_a_complete_run_writes_every_increment(tmp_path, uniform):
    m, h, summary, out = uniform
    u = read_specimen_usd(export_results(out, tmp_path / "r.usda").path)
    assert "increments_not_written" not in u.info["timeline"]
    assert u.info["timeline"]["last_increment_written"] == h.n_increments
    assert list(u.info["run"]["warning_codes"]) == [w["code"] for w in summary["warnings"]]


def test_force_primvar_says_it_is_per_wale_in_newton(tmp_path, uniform):
    m, h, _, _ = uniform
    res = export_history(h, m.fields, tmp_path / "c.usda", layout="courses", color_by="force")
    back = read_patch_usd(res.path)
    assert "force_per_wale_N" in back.fields and "force" not in back.fields
    assert back.info["legend"]["field"] == "force_per_wale_N" and back.info["legend"]["units"] == "N"
    stage = Usd.Stage.Open(res.path)
    pv = stage.GetPrimAtPath("/Patch/Yarns/course_0000").GetAttribute("primvars:knitsim:force_per_wale_N")
    assert "per wale" in pv.GetDocumentation() and "[N]" in pv.GetDocumentation()


def test_non_uniform_patch_says_its_joins_are_a_display_artefact(tmp_path, uniform):
    m, h, _, _ = uniform
    u = read_specimen_usd(export_history(h, m.fields, tmp_path / "u.usda").path)
    assert "non_uniform" not in u.info.get("drawing", {})
    rng = np.random.default_rng(3)
    cells = [[P.replace(phi0=float(rng.uniform(-1, 1) * np.arctan(0.2))) for _ in range(3)] for _ in range(2)]
    mm = PatchModel.from_cells(cells)
    hh = run_patch(mm, cycles(0.10, 0.20, 1, 0.1), engine="warp")
    b = read_patch_usd(export_history(hh, mm.fields, tmp_path / "n.usda").path)
    assert b.info["drawing"]["non_uniform"] == yg.NON_UNIFORM_NOTE


def test_a_strided_folder_of_a_run_cut_by_the_force_cap_ends_at_its_first_saved_held_increment(tmp_path, capped):
    """cells.nc at output.cells_stride 4 of the capped run: PROG loads 0 -> 0.30 in 6 steps of 0.05 and unloads
    to 0.10 in 4, so it turns after increment 6 and ends at 10; the file holds 4, 8 (multiples of 4), 6 and 10.
    curve.csv says every column is held from increment 3: of the saved increments the first held one, 4, is the
    last the knit reached, and it is the last written."""
    m, h, summary, _ = capped
    out = tmp_path / "res4"
    write_patch_results(out, h, summary, "# uniform\n", model=m, plot=False, cells_stride=4)
    held = [int(r["increment"]) for r in _csv(out / "curve.csv") if int(r["columns_held"]) == WALES]
    assert held[0] == 3 and held[-1] == h.n_increments == 10
    u = read_specimen_usd(export_results(out, tmp_path / "r4.usda").path)
    assert list(u.time_codes) == [0, 4]
    tl = u.info["timeline"]
    assert list(tl["saved_increments"]) == [4, 6, 8, 10] and tl["increments_in_run"] == 10
    assert tl["last_increment_written"] == 4 and tl["increments_not_written"] == "5-10"
    # where the hold began is not among the saved increments: said as the span it lies in (curve.csv: 3), not as
    # "from increment 5 on" (a probe's strided export named a later increment than the run's own USD)
    assert "from an increment in 1-4 on" in tl["why_not_written"] and "from increment 5" not in tl["why_not_written"]
    # the increment drawn at time code 4 is cells.nc's increment 4 (its strain)
    import xarray as xr
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        np.testing.assert_allclose(np.ravel(u.fields["strain"][1]), np.unique(ds["strain"].sel(increment=4).values),
                                   atol=1e-7)              # a uniform patch: one distinct cell, one strain
