"""Slack columns are drawn between the grips, compressed, each stitch keeping its shape.

Expected values: the grip span of a column, its rest length x (1 + grip strain) (the tester's check:
rest length sum C0 = 5 x 2.7 mm, grip strain from curve.csv), and the slack lengths of columns.csv
(``slack_mm``); the shape of every stitch from the float64 forward map of its state (Y_C of
cells.nc's ``state_x``, :func:`knitsim.cell.quarter_loop.quarter_loop`); cells.nc's C for the loaded
increments.  The results folder holds the rest state (cells.nc's rest_state_*): time code k is increment k.
"""
from __future__ import annotations

import csv

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd  # noqa: E402

from knitsim.cell.load_program import cycles  # noqa: E402
from knitsim.cell.material import CellParams  # noqa: E402
from knitsim.cell.quarter_loop import quarter_loop  # noqa: E402
from knitsim.io.patch_results import patch_summary, write_patch_results  # noqa: E402
from knitsim.patch.model import PatchModel  # noqa: E402
from knitsim.patch.runner import run_patch  # noqa: E402
from knitsim.usd import read_patch_usd  # noqa: E402
from knitsim.usd import yarn_geometry as yg  # noqa: E402
from knitsim.usd.from_results import export_results  # noqa: E402
from knitsim.usd.instanced import read_specimen_usd  # noqa: E402

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2
COURSES, WALES, N_PTS = 5, 4, 9


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """The tester's uni.toml: loaded to 0.3, unloaded to 0.1, where every column is slack (force 0)."""
    m = PatchModel.uniform(P, COURSES, WALES)
    h = run_patch(m, cycles(0.10, 0.30, 1, 0.05), engine="warp")
    out = tmp_path_factory.mktemp("slack") / "res"
    write_patch_results(out, h, patch_summary(h, h.info["ref_length_mm"], model=m), "# u\n", model=m, plot=False)
    with open(out / "curve.csv", newline="") as fh:
        grip = {int(r["increment"]): float(r["grip_strain"]) for r in csv.DictReader(fh)}
    with open(out / "columns.csv", newline="") as fh:
        slack = {(int(r["increment"]), int(r["column"])): float(r["slack_mm"]) for r in csv.DictReader(fh)}
    return out, grip, slack


def test_slack_columns_span_the_grips_as_course_yarns(tmp_path, results):
    out, grip, slack = results
    res = export_results(out, tmp_path / "c.usda", layout="courses", n_points=N_PTS)
    back = read_patch_usd(res.path)
    st = Usd.Stage.Open(res.path)
    import xarray as xr
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        goc = ds["group_of_cell"].values
        C_inc = {int(k): ds["state_C"].sel(increment=k).values[goc] for k in ds["increment"].values}
        X_inc = {int(k): ds["state_x"].sel(increment=k).values[goc] for k in ds["increment"].values}
        C_inc[0], X_inc[0] = ds["rest_state_C"].values[goc], ds["rest_state_x"].values[goc]   # increment 0
    assert any(slack[(k, 0)] > 0.5 for k in grip if k > 0)                 # the case the tester saw (0.98 mm)
    for t_idx, t in enumerate(back.time_codes):
        k = int(t)                                                         # time code = increment (0: rest)
        C = C_inc[k]
        drawn = back.A[t_idx, -1, :, 1] + C[-1]                             # last course's origin + its C
        span = COURSES * P.C0 * (1 + grip[k])
        sl = np.array([slack.get((k, j), 0.0) for j in range(WALES)])      # columns.csv starts at increment 1
        if np.all(sl == 0):
            np.testing.assert_allclose(drawn, C.sum(axis=0), atol=2e-5)   # loaded: as the cells stack
        np.testing.assert_allclose(drawn, span, atol=2e-5)                 # always the grip span (the tester)
        attr = st.GetPrimAtPath("/Patch").GetAttribute("knitsim:column_slack_mm").Get(t)
        np.testing.assert_allclose(np.asarray(attr), sl, atol=1e-6)
        # each stitch keeps its own shape: its head apex Y_C above its A, from the float64 forward map of its state
        x = X_inc[k]
        Y_C = quarter_loop(x[..., 0], x[..., 1], x[..., 2], x[..., 3], x[..., 4], P.B, P.d).Y_C
        np.testing.assert_allclose(back.head_apex[t_idx, ..., 1] - back.A[t_idx, ..., 1], Y_C, atol=2e-5)
    assert "slack_columns" in back.info["drawing"]


def test_slack_columns_span_the_grips_instanced(tmp_path, results):
    """The tester's measure on the instanced file: last course's A' y + its C per column."""
    out, grip, slack = results
    u = read_specimen_usd(export_results(out, tmp_path / "i.usda", layout="instanced").path)
    import xarray as xr
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        C_inc = {int(k): float(ds["state_C"].sel(increment=k).values[0]) for k in ds["increment"].values}
        C_inc[0] = float(ds["rest_state_C"].values[0])                      # increment 0, the rest state
    for t_idx, t in enumerate(u.time_codes):
        k = int(t)
        for j in range(WALES):
            y = u.positions[t_idx][u.strip == j, 1]
            np.testing.assert_allclose(y.max() + C_inc[k], COURSES * P.C0 * (1 + grip[k]), atol=2e-5)
            # evenly pitched: the column's courses at equal spacing (the pitch scaled, not one gap)
            np.testing.assert_allclose(np.diff(np.sort(np.unique(np.round(y, 6)))), y.max() / (COURSES - 1), atol=2e-5)


def test_pitch_scale_identity():
    """yarn_geometry.slack_pitch_scale: 1 exactly without slack; with slack s the top of the last stitch,
    s (sum C - C_top) + C_top, is sum C - slack; a specimen's strip by its represented length."""
    C = np.array([[3.0, 2.0], [3.5, 2.5], [4.0, 3.0]])
    assert np.array_equal(yg.slack_pitch_scale(C, [0.0, 0.0]), [1.0, 1.0])
    s = yg.slack_pitch_scale(C, [1.5, 0.0])
    assert s[1] == 1.0
    assert s[0] * (C[:2, 0].sum()) + C[2, 0] == pytest.approx(C[:, 0].sum() - 1.5)
    # blocks: drawn 1, 2, 1 courses, standing for 1.2, 2.1, 0.9; span = drawn length x (1 - slack / represented)
    dr, rp = np.array([[1.0], [2.0], [1.0]]), np.array([[1.2], [2.1], [0.9]])
    s = yg.slack_pitch_scale(C[:, :1], [0.8], drawn=dr, represented=rp)
    length, rep = (dr * C[:, :1]).sum(), (rp * C[:, :1]).sum()
    assert s[0] * (length - C[2, 0]) + C[2, 0] == pytest.approx(length * (1 - 0.8 / rep))
