"""Outputs of a specimen run say what its blocks stand for (issue 16): columns.csv, cells.nc, summary.json.

Expected numbers are the tester's arithmetic and independent runs: a strip of width s of a
knit of wale spacing W0 holds s / W0 wales and gauge / C0 courses; both strips of a specimen
run at the grip strain (rigid grips, equal rest lengths), so a strip's total force is its
wale count times its single cell's force per wale (run alone with run_batch at the grip
strains); the grip force is the sum of the strips'; bands in series of equal length make
the strip's wale count the mean of theirs along its length.
"""
from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import monotonic
from knitsim.cell.material import CellParams
from knitsim.io.patch_results import (COLUMNS_COLUMNS, columns_csv, patch_summary, specimen_layout,
                                      write_patch_results)
from knitsim.patch.model import PARAM_NAMES, PatchModel
from knitsim.patch.runner import run_patch

# Table 1 / section 2.2 (dusserre2015.toml), and a tighter knit of the same yarn
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
Q = P.replace(L=13.0, W0=4.0, C0=2.4)
WIDTH, GAUGE = 50.0, 100.0
PROG = monotonic(0.3, 0.05)


def _fields(rows):
    f = {n: np.array([[float(getattr(c, n)) if getattr(c, n) is not None else np.nan for c in r] for r in rows])
         for n in PARAM_NAMES}
    return f


@pytest.fixture(scope="module")
def halves():
    """Two halves across the width: strip 0 of P, strip 1 of Q (each its own courses between the grips)."""
    f = _fields([[P, Q]])
    model = PatchModel(1, 2, f, {"force_cap_N": 10.0}, course_count=GAUGE / f["C0"],
                       wale_count=(WIDTH / 2) / f["W0"], gauge_length=GAUGE)
    return model, run_patch(model, PROG)


def test_columns_csv_gives_each_strips_total_force_and_wales(halves):
    model, h = halves
    cells = run_batch([P, Q], PROG).force_per_wale                    # each knit alone at the grip strain
    wales = np.array([WIDTH / 2 / P.W0, WIDTH / 2 / Q.W0])
    rows = list(csv.DictReader(io.StringIO(columns_csv(h, specimen_layout(model)))))
    assert tuple(rows[0].keys()) == COLUMNS_COLUMNS
    assert len(rows) == 2 * len(PROG)
    # increments numbered as in curve.csv: 1 .. n (0 is the rest state there)
    assert [int(r["increment"]) for r in rows[::2]] == list(range(1, len(PROG) + 1))
    F = np.array([float(r["force_N"]) for r in rows]).reshape(-1, 2)
    w = np.array([float(r["wales"]) for r in rows]).reshape(-1, 2)
    fw = np.array([float(r["force_per_wale_N"]) for r in rows]).reshape(-1, 2)
    np.testing.assert_allclose(w, np.broadcast_to(wales, w.shape), rtol=1e-15)
    np.testing.assert_allclose(F, wales * cells, rtol=1e-10)
    np.testing.assert_allclose(fw, cells, rtol=1e-10)
    np.testing.assert_allclose(F.sum(axis=1), h.force_N, rtol=1e-12)          # the grip force is theirs


def test_summary_and_cells_nc_say_what_each_block_stands_for(halves, tmp_path):
    model, h = halves
    summary = patch_summary(h, h.info["ref_length_mm"], model=model)
    assert summary["cell_is"] == "block of stitches" and summary["cells"] == 2
    assert "wales" not in summary and (summary["bands"], summary["strips"]) == (1, 2)
    sp = summary["specimen"]
    assert (sp["width_mm"], sp["gauge_length_mm"]) == pytest.approx((WIDTH, GAUGE), rel=1e-14)
    for j, c in enumerate((P, Q)):
        assert sp["strip"][j]["width_mm"] == pytest.approx(WIDTH / 2, rel=1e-14)
        assert sp["strip"][j]["wales"] == pytest.approx(WIDTH / 2 / c.W0, rel=1e-14)
        assert sp["strip"][j]["courses"] == pytest.approx(GAUGE / c.C0, rel=1e-14)
    stitches = WIDTH / 2 / P.W0 * GAUGE / P.C0 + WIDTH / 2 / Q.W0 * GAUGE / Q.C0
    assert summary["stitches"] == pytest.approx(stitches, rel=1e-14)
    assert sp["band"][0]["wales"] == pytest.approx(WIDTH / 2 / P.W0 + WIDTH / 2 / Q.W0, rel=1e-14)
    # the peak per wale is the grip force over the wales across the width
    c1 = summary["cycles"][0]
    assert c1["peak_force_per_wale_N"] == pytest.approx(c1["peak_force_N"] / summary["wales_across"], rel=1e-12)
    write_patch_results(tmp_path / "o", h, summary, "# scene", model=model, plot=True)
    import xarray as xr
    with xr.open_dataset(tmp_path / "o" / "cells.nc", engine="h5netcdf") as ds:
        np.testing.assert_allclose(ds["course_count"].values, [[GAUGE / P.C0, GAUGE / Q.C0]], rtol=1e-15)
        np.testing.assert_allclose(ds["wale_count"].values, [[WIDTH / 2 / P.W0, WIDTH / 2 / Q.W0]], rtol=1e-15)
        assert ds.attrs["cell_is"] == "block of stitches" and ds.attrs["stitches"] == pytest.approx(stitches)
        assert ds.attrs["width_mm"] == pytest.approx(WIDTH) and ds.attrs["gauge_length_mm"] == GAUGE
        np.testing.assert_allclose(ds["column_force_N"].values.sum(axis=1), h.force_N, rtol=1e-12)
        # a block's force per wale times its wales is the strip's total force (series: one force per strip)
        np.testing.assert_allclose(ds["force_per_wale_N"].values[:, 0, :] * ds["wale_count"].values[0],
                                   ds["column_force_N"].values, rtol=1e-12)
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["specimen"]["strips"] == 2
    with pytest.raises(ValueError, match="pass its model"):
        write_patch_results(tmp_path / "p", h, summary, "# scene", plot=False)


def test_a_strip_of_graded_bands_holds_the_mean_of_their_wales():
    """Two bands in series of equal length: the strip's wale count is the mean of the bands' (length-weighted)."""
    f = _fields([[P], [Q]])
    model = PatchModel(2, 1, f, {"force_cap_N": 10.0}, course_count=(GAUGE / 2) / f["C0"],
                       wale_count=WIDTH / f["W0"], gauge_length=GAUGE)
    lay = specimen_layout(model)
    assert lay.column_wales[0] == pytest.approx(0.5 * (WIDTH / P.W0 + WIDTH / Q.W0), rel=1e-14)
    assert lay.column_courses[0] == pytest.approx(GAUGE / 2 / P.C0 + GAUGE / 2 / Q.C0, rel=1e-14)
    assert "strip 0: 11.36-12.5 wales x 39.35 courses" in lay.describe()    # 50/4.4, 50/4.0; 50/2.7 + 50/2.4
    classic = specimen_layout(PatchModel.uniform(P, 3, 2))
    assert not classic.blocks and classic.describe().startswith("2 wales x 3 courses = 6 cells")
