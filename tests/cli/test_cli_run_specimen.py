"""``knitsim run`` on a ``[specimen]`` scene: every output states the specimen, and obeys its identities.

A 40 mm x 50 mm specimen of 2 strips x 2 bands: strip 0 all of knit P (Table 1 / section 2.2,
E-glass: W0 4.4, C0 2.7 mm), strip 1 of P in its lower band and a tighter knit Q of the same yarn
(W0 4.0, C0 2.4 mm) in its upper band.  Expected numbers are the tester's arithmetic and the
equilibrium of series and parallel elements, not the code's output:

- counts: a band of length 50/2 holds 25 / C0 courses, a strip of width 40/2 holds 20 / W0 wales;
- series (strip 1): its bands carry one total force (a cut across the strip), so
  wale_count x force per wale is the same in both, and their elongations
  course_count x (C - C0) add up to the grip displacement = grip strain x 50 mm;
- parallel: every strip runs at the grip strain (rigid grips, equal rest lengths: strip 0 is its
  cell at the grip strain, run alone), and the grip force is the sum of the strips' total forces;
- force per wale = grip force / the wales across the width (20/4.4 for strip 0; for strip 1 the
  mean of 20/4.4 and 20/4.0 along its length, its two bands being equally long).
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import monotonic
from knitsim.cell.material import CellParams
from knitsim.cli import main
from knitsim.scene.schema import dumps

WIDTH, GAUGE = 40.0, 50.0
P = dict(L=14.1, W0=4.4, C0=2.7)
Q = dict(L=13.0, W0=4.0, C0=2.4)
SCENE = {"title": "two strips, the right one of two bands in series", "engine": "warp", "device": "cpu",
         "specimen": {"width": WIDTH, "gauge_length": GAUGE, "strips": 2, "bands": 2},
         "yarn": {"material": "e_glass"}, "knit": dict(P),
         "friction": {"model": "coulomb", "m": 0.2, "phi0": 0.0}, "rules": {"force_cap_N": 10.0},
         "zones": [{"label": "tighter knit", "courses": [1, 2], "wales": [1, 2], "knit": dict(Q)}],
         "load": {"type": "monotonic", "target_strain": 0.3, "max_increment": 0.05},
         "output": {"checkpoint_every": 0}}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("specimen")
    scene = d / "specimen.toml"
    scene.write_text(dumps(SCENE))
    out = d / "o"
    import contextlib
    import io
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()) as so:
        rc = main(["run", str(scene), "--out", str(out), "--no-progress", "--usd", str(out / "s.usda")])
    return rc, out, err.getvalue(), so.getvalue()


def test_header_and_summary_state_the_specimen(run):
    rc, out, err, stdout = run
    assert rc == 0, err
    c_p, c_q, w_p, w_q = 25 / P["C0"], 25 / Q["C0"], 20 / P["W0"], 20 / Q["W0"]
    header = err.splitlines()[0]
    assert header.startswith(f"knitsim run: specimen 40 mm wide, 50 mm between the grips (grip strain = grip "
                             f"displacement / 50 mm): 2 strips x 2 bands = 4 blocks")
    assert f"strip 0: {w_p:.4g} wales x {2 * c_p:.4g} courses" in header                 # 4.545 x 18.52
    assert f"strip 1: {w_p:.4g}-{w_q:.4g} wales x {c_p + c_q:.4g} courses" in header     # 4.545-5 x 19.68
    s = json.loads((out / "summary.json").read_text())
    assert s["cell_is"] == "block of stitches" and (s["bands"], s["strips"], s["cells"]) == (2, 2, 4)
    assert "wales" not in s and "courses" not in s            # no per-stitch counts of a [patch]
    assert s["stitches"] == pytest.approx(3 * c_p * w_p + c_q * w_q, rel=1e-12)
    sp = s["specimen"]
    assert (sp["width_mm"], sp["gauge_length_mm"]) == pytest.approx((WIDTH, GAUGE), rel=1e-14)
    assert sp["strip"][1]["wales"] == pytest.approx((w_p + w_q) / 2, rel=1e-12)
    assert s["wales_across"] == pytest.approx(w_p + (w_p + w_q) / 2, rel=1e-12)
    assert "gauge length (50 mm)" in s["grip_strain_is"]
    c = s["cycles"][0]
    assert c["grip_displacement_at_peak_mm"] == pytest.approx(0.3 * GAUGE, rel=1e-12)
    assert c["peak_force_per_wale_N"] == pytest.approx(c["peak_force_N"] / s["wales_across"], rel=1e-12)
    # the text summary gives the total force and the force per wale with its divisor
    assert f"peak {c['peak_force_N']:.4g} N ({c['peak_force_per_wale_N']:.4g} N per wale of the " \
           f"{s['wales_across']:.4g} wales across the width)" in stdout
    assert "stitches drawn as instances" in err


def test_series_elongations_add_and_parallel_forces_add(run):
    rc, out, _, _ = run
    import xarray as xr
    with open(out / "curve.csv", newline="") as fh:
        curve = list(csv.DictReader(fh))[1:]
    e = np.array([float(r["grip_strain"]) for r in curve])
    F = np.array([float(r["force_N"]) for r in curve])
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        cc, wc = ds["course_count"].values, ds["wale_count"].values
        C0 = ds["C0"].values
        strain = ds["strain"].values                         # (n, band, strip)
        fpw = ds["force_per_wale_N"].values
        col_total = ds["column_force_N"].values
        np.testing.assert_allclose(cc, [[25 / P["C0"]] * 2, [25 / P["C0"], 25 / Q["C0"]]], rtol=1e-14)
        np.testing.assert_allclose(wc, [[20 / P["W0"]] * 2, [20 / P["W0"], 20 / Q["W0"]]], rtol=1e-14)
        assert ds.attrs["cell_is"] == "block of stitches" and ds.attrs["gauge_length_mm"] == GAUGE
    # series: the elongations of the bands of each strip add up to the grip displacement
    elong = (cc * C0)[None] * strain                         # course_count x (C - C0) [mm]
    np.testing.assert_allclose(elong.sum(axis=1), (e * GAUGE)[:, None] * np.ones((1, 2)), rtol=1e-6, atol=1e-9)
    # ... and its bands carry one total force (more wales in the tighter band: less force per wale)
    total = wc[None] * fpw
    np.testing.assert_allclose(total[:, 0, 1], total[:, 1, 1], rtol=1e-6)
    np.testing.assert_allclose(total[:, 0, :], col_total, rtol=1e-6)
    # parallel: strip 0 runs at the grip strain (it is its cell, run alone), the grip force is the strips' sum
    np.testing.assert_allclose(strain[:, :, 0], np.repeat(e[:, None], 2, axis=1), rtol=1e-9, atol=1e-12)
    alone = run_batch([CellParams(B=0.31, d=0.58, m=0.2, phi0=0.0, force_cap_N=10.0, **P)],
                      monotonic(0.3, 0.05)).force_per_wale[:, 0]
    np.testing.assert_allclose(fpw[:, 0, 0], alone, rtol=1e-6)
    np.testing.assert_allclose(col_total.sum(axis=1), F, rtol=1e-12)
    with open(out / "columns.csv", newline="") as fh:
        cols = list(csv.DictReader(fh))
    np.testing.assert_allclose(np.array([float(r["force_N"]) for r in cols]).reshape(-1, 2), col_total, rtol=1e-12)
    np.testing.assert_allclose([float(r["wales"]) for r in cols[:2]],
                               [20 / P["W0"], (20 / P["W0"] + 20 / Q["W0"]) / 2], rtol=1e-12)


def test_usd_draws_every_stitch_between_the_grips(run):
    """The instanced USD: whole stitches by cumulative rounding (each strip draws round(its courses) and
    each band round(its wales)), and each strip's drawn height is its courses x C, the grip length within
    one stitch."""
    from knitsim.usd.instanced import read_specimen_usd
    _, out, _, _ = run
    u = read_specimen_usd(out / "s.usda")
    c_p, c_q, w_p, w_q = 25 / P["C0"], 25 / Q["C0"], 20 / P["W0"], 20 / Q["W0"]
    courses = [round(2 * c_p), round(c_p + c_q)]                  # 19, 20 along strips 0 and 1
    wales = [[round(w_p), round(2 * w_p) - round(w_p)], [round(w_p), round(w_p + w_q) - round(w_p)]]
    drawn = sum(courses_b * w for courses_b, w in
                [(round(c_p), wales[0][0]), (courses[0] - round(c_p), wales[1][0]),
                 (round(c_p), wales[0][1]), (courses[1] - round(c_p), wales[1][1])])
    assert len(u.proto_indices) == drawn
    import xarray as xr
    with xr.open_dataset(out / "cells.nc", engine="h5netcdf") as ds:
        C = (ds["C0"].values * (1 + ds["strain"].values))[-1]           # block course lengths at the end
    assert u.time_codes[-1] == 6                                     # the last increment is drawn (0: rest)
    for j in range(2):
        # the top stitch's A' plus its course length: the strip's drawn height, within a course of the grips'
        # distance (u = 0.3 x 50 mm)
        height = u.positions[-1][u.strip == j, 1].max() + C[1, j]
        assert abs(height - GAUGE * 1.3) < C[:, j].max(), (j, height)
