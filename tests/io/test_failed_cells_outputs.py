"""A patch whose cells fail, or whose columns stop converging for good, says where and why, and its
cycle figures stop there (warnings run_stopped_by_failed_cells, run_held_by_unconverged_columns).

Where the expected outcomes come from:

- a failed cell keeps its last converged state (knitsim.cell.history.BatchHistory), so its column holds
  that force on every later row: those rows are not the knit's response, and a cycle's work or a peak taken
  over them is not a result. The hand-made history below has that shape: two columns, two cycles, one cell
  failing on the first unloading, its column's force held from there. A column whose coupling finds no
  balance holds its last converged state the same way (the random-phi0 scene pulled to 0.9 under a 1e12 N
  cap: every column held at 150.8 N per wale from grip strain 0.86 on, its cells still ok); one that fails
  on an increment and moves again later does not (the paper specimen's one unconverged reload increment);
- the bundled E-glass specimen (scenes/specimen_e_glass_cyclic.toml) pulled to grip strain 0.85 with
  force_cap_N = 1e12 jams and then fails up the jammed branch, whose force diverges (W held at the
  jamming width while C grows), far below that cap: every one of its identical cells fails on the
  same row, found here from the run's own cell statuses.
"""
from __future__ import annotations

import json

import numpy as np

from knitsim.cell.history import STATUS_NO_CONVERGENCE, STATUS_OK
from knitsim.cell.material import CellParams
from knitsim.cell.stages import LABEL_CODES
from knitsim.io.patch_results import patch_summary
from knitsim.patch.coupling import COL_NOT_CONVERGED, COL_OK, COL_STOPPED
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import PatchHistory

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)


def _history(fail_row: int | None):
    """1 course x 2 wales, each column its own group; two cycles 0.1 -> 0.3 -> 0.1 in steps of 0.1. With
    ``fail_row`` the second cell fails there (status no_convergence, jammed, its force held at 2 N)."""
    e = np.array([0.1, 0.2, 0.3, 0.2, 0.1, 0.2, 0.3, 0.2, 0.1])
    cyc = np.array([1, 1, 1, 1, 1, 2, 2, 2, 2])
    d = np.array([1, 1, 1, -1, -1, 1, 1, -1, -1])
    col = np.column_stack([10.0 * e - 0.5, 10.0 * e - 0.5])
    n = len(e)
    status = np.full((n, 2), STATUS_OK, np.int8)
    cst = np.full((n, 2), COL_OK)
    label = np.full((n, 2), LABEL_CODES["sliding"], np.int8)
    C = np.repeat((2.7 * (1.0 + e))[:, None], 2, axis=1)
    if fail_row is not None:
        status[fail_row:, 1] = STATUS_NO_CONVERGENCE
        cst[fail_row:, 1] = COL_STOPPED
        label[fail_row:, 1] = LABEL_CODES["jamming"]
        col[fail_row:, 1] = 2.0
        C[fail_row:, 1] = 2.7 * 1.25
    groups = {"C": C, "F": col.copy(), "phi": np.zeros((n, 2)), "label": label, "status": status}
    return PatchHistory(e, cyc, d, col.sum(axis=1), col.mean(axis=1), col, cst, np.ones((n, 2), int),
                        np.zeros((n, 2)), np.array([[0, 1]]), groups, np.full((1, 2), 2.7), info={"n_groups": 2})


def test_failed_cells_cut_the_cycle_figures_and_say_where_and_why():
    model = PatchModel.uniform(P, 1, 2)
    s = patch_summary(_history(3), 2.7, model=model)
    (w,) = [w for w in s["warnings"] if w["code"] == "run_stopped_by_failed_cells"]
    for words in ("1 cell(s) failed from grip strain 0.2 (increment 4)", "course 0 wale 1",
                  "no converged solution; stopped at strain 0.25 (jamming, force per wale 2 N)", "cycle(s) 2 not run"):
        assert words in w["message"], words
    # it failed unloading: a lower cap would not have ended it there (the cap bounds loading)
    assert "force_cap_N" not in w["message"]
    # cycle 1: its figures over the rows before the failure only (the loading to 0.3: 2.5 N per wale in each
    # column); no work over a part of a cycle; cycle 2 never ran
    (c1,) = s["cycles"]
    assert c1["cycle"] == 1 and c1["cut_at_grip_strain"] == 0.2
    assert c1["peak_force_N"] == 5.0 and c1["grip_strain_at_peak"] == 0.3
    assert not [k for k in c1 if k.endswith("_N_mm")]
    assert s["all_converged"] is False
    # the rule said (knitsim cell's peak counts a failed cell's last converged state): the peak is over the
    # rows before the failure; on the failed row the grips held (1.5 + 2.0) / 2 = 1.75 N per wale (the first
    # column at 10 x 0.2 - 0.5, the failed one held at 2 N)
    assert c1["peak_before_failed_increment"] is True
    assert c1["force_per_wale_N_held_on_failed_increment"] == 1.75


def _unconverged_history(hold: bool):
    """The history above without a failed cell; the second column does not converge from row 3 on and holds
    2 N per wale to the end (``hold``), or only on row 3, moving on after it."""
    h = _history(None)
    h.column_status[3:, 1] = COL_NOT_CONVERGED if hold else COL_OK
    h.column_status[3, 1] = COL_NOT_CONVERGED
    if hold:
        h.column_force_N[3:, 1] = 2.0
        h.groups["label"][3:, 1] = LABEL_CODES["jamming"]
    h.force_N[:] = h.column_force_N.sum(axis=1)
    return h


def test_columns_that_no_longer_converge_cut_the_cycle_figures():
    model = PatchModel.uniform(P, 1, 2)
    s = patch_summary(_unconverged_history(True), 2.7, model=model)
    (w,) = [w for w in s["warnings"] if w["code"] == "run_held_by_unconverged_columns"]
    for words in ("from grip strain 0.2 (increment 4), 1 of 2 column(s) no longer converge",
                  "hold their last converged state to the end of the run", "cycle(s) 2 not run",
                  "wale 1, held at 2 N per wale (jamming)"):
        assert words in w["message"], words
    assert "force_cap_N" not in w["message"]            # held from an unloading: the cap bounds loading only
    (c1,) = s["cycles"]
    assert c1["cut_at_grip_strain"] == 0.2 and not [k for k in c1 if k.endswith("_N_mm")]
    # a column that misses one increment and moves on: counted and marked, nothing cut
    s = patch_summary(_unconverged_history(False), 2.7, model=model)
    assert not [w for w in s["warnings"] if w["code"].startswith("run_")]
    assert [c["cycle"] for c in s["cycles"]] == [1, 2] and s["non_converged_column_increments"] == 1


def test_curve_csv_says_on_which_rows_columns_are_held():
    # curve.csv's columns_held: 0 on the rest row and before the failure, 1 from the failed cell's row on
    # (its column keeps the cell's last state); the column that misses one increment: 1 on that row only
    import csv
    import io

    from knitsim.io.patch_results import curve_csv

    def held(h):
        return [int(r["columns_held"]) for r in csv.DictReader(io.StringIO(curve_csv(h)))]
    assert held(_history(3)) == [0, 0, 0, 0, 1, 1, 1, 1, 1, 1]
    assert held(_unconverged_history(False)) == [0, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    assert held(_history(None)) == [0] * 10


def test_without_failed_cells_nothing_is_cut():
    s = patch_summary(_history(None), 2.7, model=PatchModel.uniform(P, 1, 2))
    assert [c["cycle"] for c in s["cycles"]] == [1, 2]
    assert not [w for w in s["warnings"] if w["code"] == "run_stopped_by_failed_cells"]
    assert all("cut_at_grip_strain" not in c for c in s["cycles"])
    assert "hysteresis_energy_N_mm" in s["cycles"][1]


def test_a_failed_runs_peak_and_the_cells_say_which_rule_each_uses():
    """A uniform 1 x 1 patch is its cell bit for bit (README, "Patches"). Pulled to 0.9 under a 1e12 N cap it
    fails up the jammed branch inside an increment; knitsim cell's peak is the cell's last converged state
    inside that increment (README: it "counts in its cycle's peak"), knitsim run's stops at the increments
    completed before it (its figures are cut there): two documented rules, two numbers (240 against 91 N per
    wale at increments of 0.01). Each summary says which it used, and the force the run's grips held on the
    failed increment is the cell's peak, bit for bit."""
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import monotonic
    from knitsim.io.results import summarise
    from knitsim.patch.runner import run_patch

    cell = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=0.0, force_cap_N=1e12)
    prog = monotonic(0.9, 0.01)
    model = PatchModel.uniform(cell, 1, 1)
    h = run_patch(model, prog)
    (run_cycle,) = patch_summary(h, h.info["ref_length_mm"], model=model)["cycles"]
    (cell_cycle,) = summarise(run_batch([cell], prog))["cells"][0]["cycles"]
    assert cell_cycle["peak_is_last_converged_state"] is True
    assert run_cycle["peak_before_failed_increment"] is True
    assert run_cycle["force_per_wale_N_held_on_failed_increment"] == cell_cycle["peak_force_per_wale_N"]
    assert run_cycle["peak_force_per_wale_N"] < cell_cycle["peak_force_per_wale_N"]
    assert run_cycle["grip_strain_at_peak"] < cell_cycle["strain_at_peak"] < run_cycle["cut_at_grip_strain"]


def test_knitsim_run_of_a_specimen_failing_up_the_jammed_branch_says_so(tmp_path, capsys):
    from pathlib import Path

    from knitsim.cli import main
    text = (Path(__file__).parents[2] / "scenes" / "specimen_e_glass_cyclic.toml").read_text()
    for old, new in (("force_cap_N = 50.0", "force_cap_N = 1e12"), ("upper_strain = 0.60", "upper_strain = 0.85"),
                     ("cycles = 3", "cycles = 2"), ("max_increment = 0.005", "max_increment = 0.01")):
        assert old in text
        text = text.replace(old, new)
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    rc = main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress"])
    out, err = capsys.readouterr()
    assert rc == 1
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (w,) = [w for w in s["warnings"] if w["code"] == "run_stopped_by_failed_cells"]
    # where: the first increment at which the written cells carry a failed status
    import xarray as xr
    with xr.open_dataset(tmp_path / "o" / "cells.nc", engine="h5netcdf") as ds:
        failed = (ds["status"].values == STATUS_NO_CONVERGENCE).any(axis=(1, 2))
        stop = int(np.argmax(failed))
        grip = float(ds["grip_strain"].values[stop])
        n_cells = int((ds["status"].values[-1] == STATUS_NO_CONVERGENCE).sum())
    assert failed.any() and grip > 0.6                 # on the jammed branch, past the jamming of the paper's cycles
    assert f"{n_cells} cell(s) failed from grip strain {grip:.4g} (increment {stop + 1})" in w["message"]
    assert "(jamming, force per wale" in w["message"] and "did not reach force_cap_N = 1e+12 N" in w["message"]
    assert "cycle(s) 2 not run" in w["message"]
    # the console says it, the cycle line says the cut instead of a work over held forces, the plot's
    # warnings carry it (printed under the axes from the summary)
    assert "knitsim run: warning: " + w["message"] in err
    assert f"cut at grip strain {grip:.4g}, where the force stops being the knit's" in out and "work" not in out
    assert [c["cycle"] for c in s["cycles"]] == [1] and s["cycles"][0]["cut_at_grip_strain"] == grip
