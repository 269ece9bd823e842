"""Sweep runner: batched chunks, resume, interruption, assembled dataset, Dask."""
from __future__ import annotations

import copy
import json
import time

import numpy as np
import pytest

from knitsim.cell.engine import simulate
from knitsim.errors import KnitsimInputError
from knitsim import warp_runtime
from knitsim.sweep import runner
from knitsim.sweep.runner import assemble, plan_sweep, run_sweep

# E-glass cell of Dusserre (2015) (Table 1, section 2.2) with a tiny 2-cycle program
# (13 increments) to stay fast; the quantities compared do not depend on the resolution.
SCENE = {
    "engine": "warp", "device": "cpu",
    "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
    "friction": {"m": 0.2, "phi0": 0.0},
    "load": {"type": "cycles", "lower_strain": 0.1, "upper_strain": 0.4, "cycles": 2, "max_increment": 0.1},
}
GRID = {"chunk_size": 2, "curves": True,
        "parameters": {"friction.m": {"values": [0.1, 0.2, 0.3]}, "friction.phi0": {"values": [0.0, 0.05]}}}


def _run(tmp_path, sweep=GRID, scene=SCENE, name="out", **kw):
    plan = plan_sweep(scene, sweep)
    return plan, run_sweep(plan, tmp_path / name, workers=0, progress=None, plots=False, **kw)


def test_grid_dataset_equals_a_direct_simulate(tmp_path):
    plan, run = _run(tmp_path)
    ds = run.dataset
    assert list(ds["peak_force_per_wale_N"].dims) == ["friction.m", "friction.phi0", "cycle"]
    assert list(ds["friction.m"].values) == [0.1, 0.2, 0.3]
    assert list(ds["friction.phi0"].values) == [0.0, 0.05]
    assert list(ds["cycle"].values) == [1, 2]
    assert len(plan.chunks) == 3                       # 6 samples / chunk_size 2
    # independent path: the same cells built by hand, one simulate call
    base = plan.base.params[0]
    cells = [base.replace(m=m, phi0=p) for m in (0.1, 0.2, 0.3) for p in (0.0, 0.05)]
    h = simulate(cells, plan.programs[0], engine="warp", device="cpu")
    F = ds["force_per_wale_N"].values.reshape(6, -1)
    np.testing.assert_allclose(F, h.force_per_wale.T, rtol=1e-12, atol=1e-14)
    assert np.array_equal(ds["final_status"].values.reshape(6), h.status[-1])
    # peak force of cycle 1: the largest force of cycle 1's rows
    peak1 = np.array([h.force_per_wale[h.cycle == 1, c].max() for c in range(6)])
    # a cell that failed has no results (NaN), its status says why; the others are the simulation's
    failed = ~np.isin(h.status[-1], (0, 2))
    peak1[failed] = np.nan
    np.testing.assert_allclose(ds["peak_force_per_wale_N"].sel(cycle=1).values.reshape(6), peak1, rtol=1e-12)
    assert [f["sample"] for f in runner.failed_samples(ds)] == list(np.nonzero(failed)[0])
    # the file on disk holds the same
    import xarray as xr
    with xr.open_dataset(tmp_path / "out" / "results.nc", engine="scipy") as back:
        np.testing.assert_array_equal(back["peak_force_per_wale_N"].values, ds["peak_force_per_wale_N"].values)
    csv = (tmp_path / "out" / "results.csv").read_text().splitlines()
    assert len(csv) == 1 + 6 * 2                       # samples x cycles


def test_delete_one_chunk_and_resume_recomputes_only_it(tmp_path, monkeypatch):
    plan, run = _run(tmp_path)
    ref = run.dataset
    (tmp_path / "out" / "chunks" / "chunk_00001.npz").unlink()
    calls = []
    real = runner.run_chunk
    monkeypatch.setattr(runner, "run_chunk", lambda t: calls.append(t["chunk"]) or real(t))
    run2 = run_sweep(plan_sweep(SCENE, GRID), tmp_path / "out", resume=True, workers=0, progress=None, plots=False)
    assert calls == [1] and run2.skipped == [0, 2]
    assert run2.dataset.identical(ref)


def test_resume_after_the_chunks_folder_was_removed_computes_them_all_again(tmp_path):
    # a blind probe: a finished sweep's chunks/ removed (results.nc holds them), --resume failed on every chunk's
    # write ("after fixing the cause, finish with --resume", which failed again): the folder is made again and every
    # chunk computed, the results those of the uninterrupted run
    import shutil
    plan, run = _run(tmp_path)
    shutil.rmtree(tmp_path / "out" / "chunks")
    run2 = run_sweep(plan_sweep(SCENE, GRID), tmp_path / "out", resume=True, workers=0, progress=None, plots=False)
    assert sorted(run2.computed) == [0, 1, 2] and run2.skipped == []
    assert run2.dataset.identical(run.dataset)


def test_failure_in_a_chunk_keeps_earlier_chunks_and_resume_completes(tmp_path, monkeypatch):
    _, full = _run(tmp_path, name="full")
    real = runner.run_chunk

    def failing(task):
        if task["chunk"] == 1:
            raise RuntimeError("simulated crash in chunk 1")
        return real(task)

    monkeypatch.setattr(runner, "run_chunk", failing)
    with pytest.raises(RuntimeError, match="simulated crash"):
        _run(tmp_path, name="cut")
    chunks = sorted(p.name for p in (tmp_path / "cut" / "chunks").iterdir())
    assert chunks == ["chunk_00000.npz"]               # finished, no partial file of chunk 1
    monkeypatch.setattr(runner, "run_chunk", real)
    run = run_sweep(plan_sweep(SCENE, GRID), tmp_path / "cut", resume=True, workers=0, progress=None, plots=False)
    assert run.skipped == [0] and sorted(run.computed) == [1, 2]
    for k in ("peak_force_per_wale_N", "residual_strain", "energy_N_mm", "force_per_wale_N", "final_status"):
        np.testing.assert_array_equal(run.dataset[k].values, full.dataset[k].values)


def test_resume_of_a_different_sweep_is_refused(tmp_path):
    _run(tmp_path)
    other = copy.deepcopy(GRID)
    other["parameters"]["friction.m"]["values"] = [0.1, 0.25, 0.3]
    with pytest.raises(KnitsimInputError, match="different sweep"):
        run_sweep(plan_sweep(SCENE, other), tmp_path / "out", resume=True, workers=0, progress=None)
    with pytest.raises(KnitsimInputError, match="--resume"):
        run_sweep(plan_sweep(SCENE, GRID), tmp_path / "out", workers=0, progress=None)   # no silent overwrite
    # the refusal names the keys of the [sweep] table that differ (a blind probe's --resume --curves read only
    # "the [sweep] table": --curves sets sweep.curves, which the run being resumed did not keep)
    no_curves = dict(GRID, curves=False)
    _run(tmp_path, no_curves, name="nc")
    with pytest.raises(KnitsimInputError, match=r"sweep\.curves False -> True.*--curves sets sweep\.curves"):
        run_sweep(plan_sweep(SCENE, GRID), tmp_path / "nc", resume=True, workers=0, progress=None)


def test_unknown_key_path_is_named():
    with pytest.raises(KnitsimInputError, match=r'"friction\.mm".*unknown key'):
        plan_sweep(SCENE, {"parameters": {"friction.mm": {"values": [0.1]}}})


def test_a_sample_violating_w0_ge_4d_is_refused_before_solving(monkeypatch):
    # section 3.1 / Hong: W0 >= 4 d = 2.32 mm for E-glass (d = 0.58 mm, Table 1)
    monkeypatch.setattr(runner, "run_chunk", lambda t: pytest.fail("solved before validation"))
    with pytest.raises(KnitsimInputError) as exc:
        plan_sweep(SCENE, {"parameters": {"knit.W0": {"values": [4.4, 2.0]}}})
    msg = str(exc.value)
    assert "sample 1" in msg and "knit.W0 = 2.0" in msg and ">= 4 d" in msg
    # every such sample counted, not the first alone (a blind probe's hypercube named its sample 217 only)
    with pytest.raises(KnitsimInputError, match=r"sample 0 .*\(2 more of the 4 samples are refused too: samples 1, 3;"):
        plan_sweep(SCENE, {"parameters": {"knit.W0": {"values": [2.0, 2.1, 4.4, 2.2]}}})


def test_phi0_swept_as_a_fraction_of_phimax_reaches_every_samples_cone():
    """An LHS over m and phi0 together: phi0 in radians over +-0.09 leaves the cone phimax = atan(m) of the
    samples with m < tan(0.09) (refused before any solve); phi0_fraction is each sample's own cone, phi0 =
    fraction x atan(m) (the identity), and the scene's phi0 = 0.0 gives way to it."""
    params = {"friction.m": {"min": 0.0, "max": 0.6}}
    with pytest.raises(KnitsimInputError, match=r"friction\.phi0 = .*must lie in \[-phimax, phimax\]"):
        plan_sweep(SCENE, {"method": "lhs", "samples": 40, "seed": 3,
                           "parameters": {**params, "friction.phi0": {"min": -0.09, "max": 0.09}}})
    plan = plan_sweep(SCENE, {"method": "lhs", "samples": 40, "seed": 3,
                              "parameters": {**params, "friction.phi0_fraction": {"min": -0.95, "max": 0.95}}})
    m, frac = np.array(plan.table).T
    assert min(m) < np.tan(0.09) and max(np.abs(frac)) > 0.85          # the draw has the samples that were refused
    phi0 = np.array([cells[0].phi0 for cells in plan.params])
    np.testing.assert_allclose(phi0, frac * np.arctan(m), rtol=1e-15, atol=0)


def test_lhs_dataset_has_a_sample_dimension_with_parameter_coordinates(tmp_path):
    sweep = {"method": "lhs", "samples": 5, "seed": 3, "chunk_size": 5,
             "parameters": {"friction.m": {"min": 0.1, "max": 0.3}, "knit.L": {"min": 13.6, "max": 14.6}}}
    plan, run = _run(tmp_path, sweep)
    ds = run.dataset
    assert ds["peak_force_per_wale_N"].dims == ("sample", "cycle")
    assert ds["friction.m"].dims == ("sample",)
    np.testing.assert_array_equal(ds["knit.L"].values, [r[1] for r in plan.table])
    # the cells ran with those values
    assert [p[0].L for p in plan.params] == list(ds["knit.L"].values)


@pytest.mark.parametrize("method", ["grid", "lhs"])
def test_the_swept_parameters_axes_carry_their_units_in_results_nc(tmp_path, method):
    # a blind probe: results.nc labelled its axes by key path only, knit.L's mm and phi0_deg's deg not said, while
    # every result variable had its units; the unit is the scene field's (knitsim.scene.cell_scene)
    import xarray as xr
    params = {"knit.L": {"min": 14.0, "max": 14.2}, "friction.phi0_deg": {"min": -2.0, "max": 2.0},
              "friction.m": {"min": 0.15, "max": 0.25}}
    if method == "grid":
        params = {k: dict(v, count=2) for k, v in params.items()}
    sweep = {"method": method, "parameters": params, **({"samples": 3} if method == "lhs" else {})}
    _run(tmp_path, sweep)
    with xr.open_dataset(tmp_path / "out" / "results.nc") as ds:
        assert ds["knit.L"].attrs["units"] == "mm" and ds["friction.phi0_deg"].attrs["units"] == "deg"
        assert "units" not in ds["friction.m"].attrs                     # a ratio: the scene states no unit
        assert ds["knit.L"].attrs["key_path"] == "knit.L"


def test_load_keys_group_samples_by_program_and_cells_multiply(tmp_path):
    scene = dict(SCENE, cells=[{"label": "a"}, {"label": "b", "friction": {"m": 0.3}}])
    sweep = {"chunk_size": 8, "curves": True, "parameters": {"load.upper_strain": {"values": [0.3, 0.4]}}}
    plan, run = _run(tmp_path, sweep, scene)
    ds = run.dataset
    assert len(plan.programs) == 2 and len(plan.chunks) == 2      # one chunk per program
    assert ds["peak_force_per_wale_N"].dims == ("load.upper_strain", "cell", "cycle")
    assert list(ds["cell_label"].values) == ["a", "b"]
    # the imposed strain of each sample's program peaks at its upper strain
    np.testing.assert_allclose(np.nanmax(ds["imposed_strain"].values, axis=1), [0.3, 0.4])


def test_a_swept_key_that_a_cell_sets_itself_is_warned(tmp_path):
    # a blind probe: a sweep of friction.m over a scene whose cell b states its own m (or phi0 another way, phi0_deg)
    # ran b at its own value in every sample, its results repeated under every m, without a word: a cell's own keys
    # replace the base tables' (cell_scene._merge); warned (a control cell held fixed is a design), not refused
    scene = dict(SCENE, cells=[{"label": "a"}, {"label": "b", "friction": {"m": 0.3, "phi0_deg": 1.0}}])
    sweep = {"parameters": {"friction.m": {"values": [0.1, 0.2]}, "friction.phi0": {"values": [0.0, 0.05]},
                            "knit.L": {"values": [14.0, 14.1]}}}
    plan, run = _run(tmp_path, sweep, scene)
    # the identity the warning states: cell b's friction is one in every sample, cell a's follows the sweep
    assert {(c[1].m, c[1].phi0) for c in plan.params} == {(0.3, float(np.radians(1.0)))}
    assert len({(c[0].m, c[0].phi0) for c in plan.params}) == 4
    assert [w["code"] for w in plan.warnings] == ["swept_key_set_by_cell"] * 2
    assert "cells[1].friction.m = 0.3, cell b" in plan.warnings[0]["message"]
    assert "cells[1].friction.phi0_deg = 1" in plan.warnings[1]["message"]
    assert run.summary["warnings"] == plan.warnings
    # a key no cell sets (knit.L), or a scene whose cells set none of the swept keys: no warning
    assert plan_sweep(dict(SCENE, cells=[{"label": "a"}, {"label": "b", "knit": {"C0": 2.8}}]), sweep).warnings == []


def test_a_scene_that_leaves_the_swept_keys_to_the_sweep_runs():
    # a blind probe's hand-made scene gave knit W0 and C0 and left L to the sweep: refused as "knit.L: missing";
    # and a sweep of friction.dahl_sigma over --set friction.model=dahl as "dahl_sigma = 0.0: needs a stiffness > 0",
    # its --set refused as a swept key: no way to run either from the command line.  The base is then the first
    # sample's scene; every sample gets its values (E-glass, Table 1 and section 2.2, written out)
    scene = dict(SCENE, yarn={"d": 0.58, "B": 0.31}, knit={"W0": 4.4, "C0": 2.7})
    plan = plan_sweep(scene, {"parameters": {"knit.L": {"values": [14.0, 14.1]}}})
    assert [cells[0].L for cells in plan.params] == [14.0, 14.1]
    plan = plan_sweep(SCENE, {"parameters": {"friction.dahl_sigma": {"values": [5.0, 50.0]}}},
                      overrides=["friction.model=dahl"])
    assert [cells[0].dahl_sigma for cells in plan.params] == [5.0, 50.0]
    # a scene that misses a key the sweep does not give is refused as before, naming the key
    with pytest.raises(KnitsimInputError, match=r"^knit.L: missing"):
        plan_sweep(scene, {"parameters": {"friction.m": {"values": [0.1, 0.2]}}})
    # one whose first sample fails otherwise: that sample is named (knit.W0 = 2.2 below 4 d = 2.32 mm)
    with pytest.raises(KnitsimInputError, match=r"^sweep sample 0 \(knit.L = 14.0, knit.W0 = 2.2\): knit.W0 = 2.2: "
                                                r"must be >= 4 d"):
        plan_sweep(dict(scene, knit={"C0": 2.7}), {"parameters": {"knit.L": {"values": [14.0]},
                                                                  "knit.W0": {"values": [2.2, 4.4]}}})


def test_an_axis_of_an_effect_that_no_cell_has_on_is_refused(tmp_path):
    # a blind probe: a sweep of effects.bend_h without bending_hysteresis on ran one result under every h, without a
    # word (the kernels read an effect's parameters only where it is on)
    sweep = {"parameters": {"effects.bend_h": {"values": [0.1, 0.5]}}}
    with pytest.raises(KnitsimInputError, match=r'"effects.bend_h": a parameter of the effect bending_hysteresis, '
                                                r'which no cell has on'):
        plan_sweep(SCENE, sweep)
    with pytest.raises(KnitsimInputError, match=r'"cells\[0\].effects.ext_c": .* yarn_extension'):
        plan_sweep(dict(SCENE, cells=[{"label": "a"}]), {"parameters": {"cells[0].effects.ext_c": {"values": [0.0, 0.01]}}})
    # on (in one cell of the scene, or the base): the axis changes the results
    scene = dict(SCENE, cells=[{"label": "a"}, {"label": "b", "effects": {"on": ["bending_hysteresis"]}}])
    plan, run = _run(tmp_path, sweep, scene)
    peaks = run.dataset["peak_force_per_wale_N"].sel(cycle=2).values     # [h, cell]
    assert peaks[0, 0] == peaks[1, 0] and peaks[0, 1] != peaks[1, 1]


def test_two_worker_local_dask_cluster_gives_the_in_process_results(tmp_path):
    _, ref = _run(tmp_path, name="local")
    t0 = time.perf_counter()
    plan = plan_sweep(SCENE, GRID)
    run = run_sweep(plan, tmp_path / "dask", workers=2, progress=None, plots=False)
    assert time.perf_counter() - t0 < 60
    for k in ("peak_force_per_wale_N", "force_per_wale_N", "final_status", "residual_strain"):
        np.testing.assert_array_equal(run.dataset[k].values, ref.dataset[k].values)
    assert assemble(tmp_path / "dask").identical(run.dataset)


def test_in_plane_width_is_a_sweep_parameter(tmp_path):
    """The yarn's in-plane width w (README): loops jam at W = 4 w, and W falls as the knit is
    stretched wale-wise, so a wider roving jams at a smaller strain (monotonic in w), and
    w = d is the paper's cell exactly (absent = d)."""
    scene = {**SCENE, "load": {"type": "monotonic", "target_strain": 0.75, "max_increment": 0.05},
             "rules": {"force_cap_N": 10.0}}
    sweep = {"curves": True, "parameters": {"yarn.in_plane_width": {"values": [0.58, 0.7, 0.79]}}}
    plan, run = _run(tmp_path, sweep=sweep, scene=scene)
    jam = run.dataset["strain_at_first_jamming"].values.reshape(-1)
    assert np.all(np.isfinite(jam)) and np.all(np.diff(jam) < 0)
    assert plan.base.params[0].in_plane_width is None
    h = simulate([plan.base.params[0]], plan.programs[0], engine="warp", device="cpu")
    np.testing.assert_array_equal(run.dataset["force_per_wale_N"].values.reshape(3, -1)[0], h.force_per_wale[:, 0])


def test_a_compressive_rest_state_is_a_flagged_sample(tmp_path):
    """A stiff yarn on a short course has a compressive rest force (B = 9.84 N mm^2, C0 = 2.0 mm, W0 = 4.4 mm:
    F = -0.89 N per wale at rest, tests/io/test_checks.py), the paper's C0 = 2.7 mm does not: the sweep
    flags the first sample (variable, CSV column, listing) and only it."""
    from knitsim.sweep.runner import compressive_rest_samples, dataset_csv

    sweep = {"chunk_size": 2, "parameters": {"yarn.B": {"values": [9.84]}, "knit.C0": {"values": [2.0, 2.7]}}}
    _, run = _run(tmp_path, sweep=sweep)
    ds = run.dataset
    assert ds["rest_state_compressive"].values.ravel().tolist() == [1, 0]
    rows = compressive_rest_samples(ds)
    assert len(rows) == 1 and rows[0]["parameters"]["knit.C0"] == 2.0 and "compressive" in rows[0]["reason"]
    header, first = dataset_csv(ds).splitlines()[:2]
    col = header.split(",").index("rest_state_compressive")
    assert first.split(",")[col] == "1"
    from knitsim.sweep.plots import _marks, _title
    assert "1 with a compressive rest state" in _title("sweep", _marks(ds))


def test_local_workers_beyond_the_cores_are_refused_and_never_more_than_the_chunks(tmp_path, monkeypatch):
    # expectation: the project's rule that an absurd limit is refused before any work; a worker is a
    # single-threaded process (Warp's CPU backend runs a launch on one thread, the module docstring), so more of
    # them than cores only share the cores (a blind probe's --workers 1000 on 2 cores started 513 processes
    # holding 21 GB before it was stopped)
    from knitsim.cli import main
    monkeypatch.setattr(warp_runtime, "usable_cores", lambda: 2)
    plan = plan_sweep(SCENE, GRID)
    with pytest.raises(KnitsimInputError, match=r"^--workers = 3: more than the 2 core\(s\) of this machine"):
        run_sweep(plan, tmp_path / "r", workers=3, progress=None, plots=False)
    assert not (tmp_path / "r").exists()
    runner.check_workers(3, scheduler="tcp://host:8786")       # an existing cluster's workers are its own
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[load]\ntype = "monotonic"\n'
                     'target_strain = 0.2\nmax_increment = 0.1\n[sweep]\nmethod = "grid"\n[sweep.parameters]\n'
                     '"friction.m" = { values = [0.1, 0.2] }\n')
    assert main(["sweep", str(scene), "--out", str(tmp_path / "c"), "--workers", "3"]) == 2
    assert not (tmp_path / "c").exists()

    # the default (one per core) starts no more workers than there are chunks to run
    import dask.distributed

    class Started(Exception):
        pass

    started = []

    def cluster(n_workers, **kw):
        started.append(n_workers)
        raise Started

    monkeypatch.setattr(warp_runtime, "usable_cores", lambda: 8)
    monkeypatch.setattr(dask.distributed, "LocalCluster", cluster)
    with pytest.raises(Started):
        runner._run_dask([{"chunk": 0}, {"chunk": 1}], None, [], None, None, None)
    assert started == [2]


def test_the_validation_of_a_long_sweeps_samples_shows_its_progress(tmp_path, monkeypatch, capsys):
    # expectation: the project's rule that long work shows progress; each sample's scene is validated before any
    # solve, about 1 ms a sample (a blind probe's 50,000-sample Latin hypercube spent 50 s there without a word)
    calls = []
    plan = plan_sweep(SCENE, GRID, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(i, plan.n_samples) for i in range(1, plan.n_samples + 1)]
    from knitsim.cli import main
    from knitsim.cli import sweep as cli_sweep
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[load]\ntype = "monotonic"\n'
                     'target_strain = 0.2\nmax_increment = 0.1\n[sweep]\nmethod = "grid"\n[sweep.parameters]\n'
                     '"friction.m" = { values = [0.1, 0.2] }\n')
    monkeypatch.setattr(cli_sweep, "PLAN_PROGRESS_SAMPLES", 2)        # a long sweep, as far as the CLI knows
    assert main(["sweep", str(scene), "--out", str(tmp_path / "o"), "--workers", "0", "--no-plot"]) == 0
    assert "knitsim sweep: validating the samples' scenes: samples: 2/2 (100%)" in capsys.readouterr().err
    monkeypatch.setattr(cli_sweep, "PLAN_PROGRESS_SAMPLES", 3)        # a short one: nothing said
    assert main(["sweep", str(scene), "--out", str(tmp_path / "p"), "--workers", "0", "--no-plot"]) == 0
    assert "validating" not in capsys.readouterr().err


def test_an_unreachable_scheduler_is_refused_before_the_sweeps_folder_is_made(tmp_path, monkeypatch):
    # expectation: the project's rule that bad input is refused before any work and leaves no output (a blind
    # probe's unreachable --scheduler was refused after sweep.json and chunks/ were written; a plain rerun was
    # then refused as a folder that already holds results).  Port 1 of the loopback has no scheduler.
    from knitsim.cli import main
    monkeypatch.setattr(runner, "SCHEDULER_TIMEOUT", "1s")
    scene = tmp_path / "s.toml"
    scene.write_text('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[load]\ntype = "monotonic"\n'
                     'target_strain = 0.2\nmax_increment = 0.1\n[sweep]\nmethod = "grid"\n[sweep.parameters]\n'
                     '"friction.m" = { values = [0.1, 0.2] }\n')
    with pytest.raises(KnitsimInputError, match=r"^--scheduler = 'tcp://127.0.0.1:1': cannot connect"):
        runner.check_scheduler("tcp://127.0.0.1:1")
    assert main(["sweep", str(scene), "--out", str(tmp_path / "c"), "--scheduler", "tcp://127.0.0.1:1"]) == 2
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("method", ["grid", "lhs"])
def test_a_flagged_samples_parameters_are_those_the_dataset_holds_at_its_index(method):
    # expectation (an independent selection): each listed sample's parameters are the dataset's values at that
    # sample's index, read one by one with xarray's isel (what the listing did per sample before it read each
    # parameter's values once); a grid with a text parameter and two cells, a Latin hypercube of one cell
    import xarray as xr
    rng = np.random.default_rng(3)
    if method == "grid":
        m, rule = np.linspace(0.0, 0.4, 7), np.array(["dusserre", "hong_constant_t"])
        dims = ("friction.m", "rules.unloading_rule", "cell")
        flag = (rng.uniform(size=(7, 2, 2)) < 0.4).astype(np.int8)
        ds = xr.Dataset({"final_status": (dims, np.zeros(flag.shape, np.int32)),
                         "expected_end": (dims, np.ones(flag.shape, np.int8)), "zero_force_cycle": (dims, flag)},
                        coords={"friction.m": m, "rules.unloading_rule": rule})
        keys, lead = ["friction.m", "rules.unloading_rule"], ["friction.m", "rules.unloading_rule"]
    else:
        n = 40
        flag = (rng.uniform(size=n) < 0.4).astype(np.int8)
        ds = xr.Dataset({"final_status": ("sample", np.zeros(n, np.int32)), "expected_end": ("sample", np.ones(n, np.int8)),
                         "zero_force_cycle": ("sample", flag), "friction.m": ("sample", rng.uniform(0.0, 0.4, n)),
                         "yarn.B": ("sample", rng.uniform(0.2, 0.4, n))})
        keys, lead = ["friction.m", "yarn.B"], ["sample"]
    ds.attrs["parameters"], ds.attrs["method"] = json.dumps(keys), method
    listed = runner.warning_samples(ds, "zero_force_cycle")
    assert len(listed) == int(flag.sum()) > 0
    for entry, idx in zip(listed, np.argwhere(flag == 1)):
        point = ds.isel(dict(zip(lead, (int(i) for i in idx[:len(lead)]))))
        assert entry["parameters"] == {k: point[k].values.item() for k in keys}
        assert entry["sample"] == int(np.ravel_multi_index(tuple(idx[:len(lead)]), flag.shape[:len(lead)]))
        assert entry["cell"] == (int(idx[-1]) if method == "grid" else None)


def test_a_slow_chunks_rate_is_not_printed_as_zero():
    # a blind probe's reference-engine sweep: 4 samples in one chunk of 151 s printed "0.0 samples/s"
    import io as _io
    out = _io.StringIO()
    progress = runner._Progress(out, total_chunks=1, total_samples=4, done_chunks=0)
    progress.t0 -= 151.0
    progress(4)
    assert "chunks 1/1, 0.0265 samples/s" in out.getvalue()                  # 4 / 151 s
