"""The sweep planner and ``knitsim run`` check every cell against the model's domain before any solve.

Expected classes come from the domain's stated box (knitsim.cell.domain: m in [0.05, 0.5]) and from an
independent solve of the rest state: the float64 NumPy reference (:func:`knitsim.cell.inverse.initial_state`)
gives R < 0 at rest for the E-glass knit (Dusserre 2015, section 2.2) lengthened to L = 20 mm (a
pulling contact: no admissible rest state), R > 0 at the paper's L = 14.1 mm.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from knitsim.cell.domain import DOMAIN_INSIDE, DOMAIN_NO_REST_STATE, DOMAIN_OUTSIDE_BOX
from knitsim.cell.engine import simulate
from knitsim.cell.history import STATUS_NO_REST_STATE
from knitsim.cell.inverse import initial_state
from knitsim.cli import main
from knitsim.sweep.plots import _failed, _no_rest, _outside, plot_sweep
from knitsim.sweep.runner import domain_samples, failed_samples, plan_sweep, run_sweep

SCENE = {
    "engine": "warp", "device": "cpu",
    "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
    "friction": {"m": 0.2, "phi0": 0.0},
    "load": {"type": "cycles", "lower_strain": 0.1, "upper_strain": 0.4, "cycles": 1, "max_increment": 0.1},
}
# L = 14.1 (the paper's) and 20 mm (contact pulls at rest); m = 0.2 (inside) and 0.6 (beyond the box's 0.5)
GRID = {"chunk_size": 2, "curves": True,
        "parameters": {"knit.L": {"values": [14.1, 20.0]}, "friction.m": {"values": [0.2, 0.6]}}}


def test_independent_rest_states():
    # the premise of the expected classes, by the NumPy reference (not the engine the planner asks)
    R = {L: float(initial_state(2.7, 4.4, L, 0.0, 0.31, 0.58).state.R) for L in (14.1, 20.0)}
    assert R[14.1] > 0 and R[20.0] < 0


def test_sweep_flags_before_solving_and_solves_only_the_model(tmp_path, monkeypatch):
    plan = plan_sweep(SCENE, GRID)
    expected = np.array([[DOMAIN_INSIDE], [DOMAIN_OUTSIDE_BOX], [DOMAIN_NO_REST_STATE], [DOMAIN_NO_REST_STATE]])
    np.testing.assert_array_equal(plan.domain, expected)          # known before any chunk runs
    assert "m = 0.6" in plan.domain_reasons[1][0] and "would pull" in plan.domain_reasons[2][0]
    solved = []
    real = simulate

    def counting(params, program, **kw):
        solved.extend((p.L, p.m) for p in params)
        return real(params, program, **kw)

    monkeypatch.setattr("knitsim.cell.engine.simulate", counting)
    run = run_sweep(plan, tmp_path / "o", workers=0, progress=None, plots=False)
    assert sorted(solved) == [(14.1, 0.2), (14.1, 0.6)]              # no rest state: not solved
    ds = run.dataset
    np.testing.assert_array_equal(ds["domain"].values, expected[:, 0].reshape(2, 2))
    st = ds["final_status"].values
    assert (st[1] == STATUS_NO_REST_STATE).all()
    assert np.isnan(ds["peak_force_per_wale_N"].values[1]).all() and np.isnan(ds["force_per_wale_N"].values[1]).all()
    # outside the box: solved, the simulation's own results kept
    h = real([plan.params[1][0]], plan.programs[0], engine="warp", device="cpu")
    np.testing.assert_allclose(ds["force_per_wale_N"].values[0, 1], h.force_per_wale[:, 0], rtol=1e-12)
    # listed with their reasons, apart from solver failures
    assert failed_samples(ds) == []
    assert [r["sample"] for r in domain_samples(ds, DOMAIN_NO_REST_STATE)] == [2, 3]
    assert [r["sample"] for r in domain_samples(ds, DOMAIN_OUTSIDE_BOX)] == [1]
    assert "would pull" in domain_samples(ds, DOMAIN_NO_REST_STATE)[0]["reason"]
    # a library call writes them too, where the plot's title points (summary.json), as the command does
    kept = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert set(kept) == set(run.summary) and run.files["summary.json"] == tmp_path / "o" / "summary.json"
    assert [r["sample"] for r in kept["no_rest_state"]] == [2, 3] and [r["sample"] for r in kept["outside_domain"]] == [1]
    assert kept["failed"] == [] and kept["samples"] == 4
    csv = (tmp_path / "o" / "results.csv").read_text().splitlines()
    assert csv[0].endswith(",domain") and [r.rsplit(",", 1)[1] for r in csv[1:]] == \
        ["inside", "outside_domain", "no_rest_state", "no_rest_state"]
    # plots: the rest-less samples are not drawn as failures, and the title counts each kind
    assert not _failed(ds).any() and _no_rest(ds).sum() == 2 and _outside(ds).sum() == 1
    assert plot_sweep(ds, tmp_path / "o")[0].stat().st_size > 0


def test_sweep_cli_summary_lists_the_domain(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('engine = "warp"\ndevice = "cpu"\n[yarn]\nmaterial = "e_glass"\n[knit]\n'
                     'material = "e_glass_plain"\n[friction]\nm = 0.2\nphi0 = 0.0\n[load]\ntype = "cycles"\n'
                     'lower_strain = 0.1\nupper_strain = 0.4\ncycles = 1\nmax_increment = 0.1\n[sweep]\n'
                     'method = "grid"\nchunk_size = 2\n[sweep.parameters]\n"knit.L" = { values = [14.1, 20.0] }\n'
                     '"friction.m" = { values = [0.2, 0.6] }\n')
    rc = main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--json", "--no-plot"])
    cap = capsys.readouterr()
    s = json.loads(cap.out)
    assert rc == 0 and len(s["no_rest_state"]) == 2 and len(s["outside_domain"]) == 1 and s["failed"] == []
    assert "2 of 4 sample(s) have no admissible rest state" in cap.err      # said before the solve
    # the same lists, with their reasons, stay in the output folder (the plot's title points there)
    kept = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert [r["sample"] for r in kept["no_rest_state"]] == [2, 3] and [r["sample"] for r in kept["outside_domain"]] == [1]
    assert all("would pull" in r["reason"] for r in kept["no_rest_state"]) and kept["failed"] == []


def test_patch_run_refuses_a_rest_less_cell_before_any_work(tmp_path, capsys):
    from pathlib import Path
    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / "o"
    rc = main(["run", str(repo / "scenes" / "random_phi0.toml"), "--out", str(out), "--no-progress",
               "--set", "knit.L=20"])
    err = capsys.readouterr().err
    assert rc == 2 and "no admissible rest state" in err and "would pull" in err and not out.exists()


def test_patch_run_warns_outside_the_box(tmp_path, capsys):
    from pathlib import Path
    repo = Path(__file__).resolve().parents[2]
    rc = main(["run", str(repo / "scenes" / "random_phi0.toml"), "--out", str(tmp_path / "o"), "--no-progress",
               "--json", "--set", "patch.wales=2", "--set", "patch.courses=2", "--set", "load.max_increment=0.1",
               "--set", "friction.m=0.6"])
    s = json.loads(capsys.readouterr().out)
    w = [x for x in s["warnings"] if x["code"] == "outside_domain"]
    assert rc in (0, 1) and len(w) == 1 and "4 of 4 cell(s)" in w[0]["message"] and "m (4)" in w[0]["message"]
