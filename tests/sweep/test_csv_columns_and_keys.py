"""results.csv holds one value per header column (an identity of the file's own header), each under its
name: a blind probe found the three columns of where a failed cell stopped (stopped_at_strain,
last_converged_strain, last_converged_force_per_wale_N) never written, so every later value, the domain
among them, sat one column to the left of its name (pandas read domain = NaN, stopped_at_strain =
"inside").  The values are checked against the dataset the file is written from.  And the keys that say how
a sweep runs (engine, device) are not swept: each sample would carry a label it did not run with."""
from __future__ import annotations

import csv
import io
import re

import numpy as np

from knitsim.sweep.runner import dataset_csv, plan_sweep, run_sweep

# E-glass cell of Dusserre (2015) (Table 1, section 2.2); m = 3 (outside the domain) fails in its
# loading (the probe's sample: no convergence at strain 0.56), m = 0.2 runs the program
SCENE = {"engine": "warp", "device": "cpu", "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
         "friction": {"m": 0.2, "phi0": 0.0},
         "load": {"type": "cycles", "lower_strain": 0.1, "upper_strain": 0.6, "cycles": 1, "max_increment": 0.02}}


def test_every_row_has_a_value_under_every_header_column(tmp_path):
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.2, 3.0]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    text = dataset_csv(ds)
    assert (tmp_path / "out" / "results.csv").read_text() == text
    rows = list(csv.reader(io.StringIO(text)))
    header, data = rows[0], rows[1:]
    assert all(len(r) == len(header) for r in data)
    rec = [dict(zip(header, r)) for r in data]
    assert [r["friction.m"] for r in rec] == ["0.2", "3.0"]
    assert rec[0]["domain"] == "inside" and rec[1]["domain"] == "outside_domain"
    assert rec[0]["stopped_at_strain"] == "" and rec[0]["final_status"] == "ok"
    for k in ("stopped_at_strain", "last_converged_strain", "last_converged_force_per_wale_N"):
        v = float(ds[k].sel({"friction.m": 3.0}).values.ravel()[0])
        assert np.isfinite(v) and float(rec[1][k]) == v, k
    assert rec[1]["final_status"] not in ("ok", "force_cap")


def test_a_cell_label_or_value_holding_a_comma_stays_in_its_column(tmp_path):
    # a blind probe's hand-made scene named its cells "E-glass, m 0.2": each row of results.csv had one column more
    # than its header, and pandas read the label's second half as the cycle; the file is quoted as CSV quotes
    scene = dict(SCENE, cells=[{"label": "E-glass, m 0.2"}, {"label": 'say "b"', "friction": {"m": 0.3}}])
    plan = plan_sweep(scene, {"parameters": {"knit.L": {"values": [14.0, 14.1]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    rows = list(csv.reader(io.StringIO((tmp_path / "out" / "results.csv").read_text())))
    header, data = rows[0], rows[1:]
    assert len(data) == 2 * 2 * 1 and all(len(r) == len(header) for r in data)
    col = {k: header.index(k) for k in ("cell", "cell_label", "cycle", "knit.L")}
    assert [(r[col["cell"]], r[col["cell_label"]], r[col["cycle"]]) for r in data[:2]] == [
        ("0", "E-glass, m 0.2", "1"), ("1", 'say "b"', "1")]
    assert [float(r[col["knit.L"]]) for r in data] == [14.0, 14.0, 14.1, 14.1]
    assert list(ds["cell_label"].values) == ["E-glass, m 0.2", 'say "b"']


def test_engine_and_device_are_not_swept():
    # a blind probe's sweep over engine ran both samples on warp, one labelled "reference"
    import pytest
    from knitsim.errors import KnitsimInputError
    for key, vals in (("engine", ["warp", "reference"]), ("device", ["cpu", "cuda"])):
        with pytest.raises(KnitsimInputError, match=rf'sweep.parameters."{key}": not a parameter of the cells'):
            plan_sweep(SCENE, {"parameters": {key: {"values": vals}}})
    # the title too, and the message names no option the command lacks (it said "--title for engine and device")
    with pytest.raises(KnitsimInputError, match=r'^sweep.parameters."title": not a parameter of the cells: the whole '
                                                r'sweep runs with one title \(give it in the scene\)$'):
        plan_sweep(SCENE, {"parameters": {"title": {"values": ["a", "b"]}}})
    with pytest.raises(KnitsimInputError, match=r"\(give it in the scene, or --engine\)$"):
        plan_sweep(SCENE, {"parameters": {"engine": {"values": ["warp", "reference"]}}})
    # keys a sweep does not read (a blind probe's sweep of output.plot ran two identical samples)
    for key, vals in (("output.plot", [True, False]), ("provenance.source", ["a", "b"]),
                      ("cells[0].label", ["a", "b"])):
        with pytest.raises(KnitsimInputError, match=rf'^sweep.parameters."{re.escape(key)}": not a parameter of the cells: a '
                                                    r'sweep does not read it .*every sample would run the same cells$'):
            plan_sweep(SCENE, {"parameters": {key: {"values": vals}}})


def test_a_text_parameter_beside_flagged_samples_is_plotted(tmp_path):
    # a blind probe: jamming_criterion x m over 2 cycles to 0.6 (head_gap samples flagged loop_creates_energy)
    # ended in a matplotlib ConversionError after results.csv / results.nc were written
    scene = dict(SCENE, load=dict(SCENE["load"], cycles=2))
    plan = plan_sweep(scene, {"parameters": {"rules.jamming_criterion": {"values": ["w_4d", "head_gap"]},
                                             "friction.m": {"values": [0.1, 0.2]}}})
    run = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=True)
    assert int(np.sum(run.dataset["loop_creates_energy"].values == 1)) >= 1
    assert (tmp_path / "out" / "plot_sweep.png").stat().st_size > 10_000


def test_a_stop_at_the_force_cap_in_the_only_cycle_is_listed(tmp_path):
    # a blind probe: in_plane_width 1.0 mm (W0 / 4 w = 1.1: jamming early) stops at the 10 N cap before the
    # unloading of a one-cycle program (knitsim cell warns program_cut_by_force_cap); the sweep listed nothing
    from knitsim.cell.history import STATUS_FORCE_CAP
    from knitsim.sweep.runner import capped_samples
    scene = dict(SCENE, load=dict(SCENE["load"], upper_strain=0.5), rules={"force_cap_N": 10.0})
    plan = plan_sweep(scene, {"parameters": {"yarn.in_plane_width": {"values": [0.58, 1.0]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    assert ds["final_status"].values.ravel().tolist()[1] == STATUS_FORCE_CAP
    rows = capped_samples(ds)
    assert [r["sample"] for r in rows] == [1]
    assert "in cycle 1, whose peak is the cap and whose energy is loading work only" in rows[0]["reason"]


def test_curves_are_nan_where_a_cell_did_not_solve(tmp_path):
    # a blind probe: --curves held a failed cell's last force (and a capped cell's cap) to the program's end
    from knitsim.cell.engine import simulate
    from knitsim.io.results import _stopped_rows
    plan = plan_sweep(SCENE, {"curves": True, "parameters": {"friction.m": {"values": [0.2, 3.0]},
                                                              "rules.force_cap_N": {"values": [0.12, 10.0]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    F = ds["force_per_wale_N"].values.reshape(4, -1)
    cells = [plan.base.params[0].replace(m=m, force_cap_N=cap) for m in (0.2, 3.0) for cap in (0.12, 10.0)]
    h = simulate(cells, plan.programs[0], engine="warp", device="cpu")
    n_stopped = 0
    for c in range(4):
        k = _stopped_rows(h.status[:, c])           # the rows the cell solved (its status says where it stopped)
        np.testing.assert_array_equal(F[c, :k], h.force_per_wale[:k, c])
        assert np.all(np.isnan(F[c, k:]))
        n_stopped += k < F.shape[1]
    assert n_stopped >= 2                          # the capped (0.12 N) and the failed (m = 3) samples


def test_a_grid_range_over_a_whole_number_key_runs():
    # a blind probe: "load.cycles" = { min = 1, max = 3, count = 3 } was refused as '"1.0": expected a whole number'
    plan = plan_sweep(SCENE, {"parameters": {"load.cycles": {"min": 1, "max": 3, "count": 3},
                                             "rules.force_cap_N": {"values": [10.0, 12.5]}}})
    # the programs' cycles: 1, 2, 3 (each twice: the force caps)
    assert sorted(int(p.cycle.max()) for p in plan.programs) == [1, 2, 3]
    assert sorted({float(c.force_cap_N) for cells in plan.params for c in cells}) == [10.0, 12.5]


def test_a_latin_hypercube_over_a_whole_number_key_is_refused_naming_the_grid():
    # a blind probe: an LHS of load.cycles in [1, 3] refused its samples one by one ("load.cycles =
    # 2.3713749647447466: expected a whole number ... narrow the ranges"), which no range can mend
    import pytest
    from knitsim.errors import KnitsimInputError
    with pytest.raises(KnitsimInputError, match=r'^sweep.parameters."load.cycles": a whole number, which a Latin '
                                                r'hypercube cannot draw .*grid axis'):
        plan_sweep(SCENE, {"method": "lhs", "samples": 3, "parameters": {"load.cycles": {"min": 1, "max": 3}}})
    # a real-valued key of the same table draws as before
    plan = plan_sweep(SCENE, {"method": "lhs", "samples": 3, "parameters": {"load.upper_strain": {"min": 0.5,
                                                                                              "max": 0.6}}})
    assert all(0.5 <= row[0] < 0.6 for row in plan.table)


def test_a_set_of_a_swept_key_is_refused():
    # a blind probe: --set friction.m=0.3 on a sweep of friction.m was overridden by the sweep without a word
    import pytest
    from knitsim.errors import KnitsimInputError
    with pytest.raises(KnitsimInputError, match=r"--set friction.m=0.3: friction.m is a parameter of the sweep"):
        plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.1, 0.2]}}}, overrides=["friction.m=0.3"])
    plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.1, 0.2]}}}, overrides=["friction.phi0=0.05"])


def test_a_set_that_a_swept_key_states_another_way_is_refused():
    # a blind probe: --set friction.phi0=0.1 on a sweep of friction.phi0_deg ran every sample at the swept phi0_deg
    # (the sample's value removes the other ways of stating phi0, the schema's alternatives), without a word
    import pytest
    from knitsim.errors import KnitsimInputError
    for swept, override in (("friction.phi0_deg", "friction.phi0=0.1"), ("friction.phi0", "friction.phi0_deg=3"),
                            ("friction.phi0_fraction", "friction.phi0=0.1")):
        values = [-0.5, 0.5] if swept == "friction.phi0_fraction" else [-0.05, 0.05]
        with pytest.raises(KnitsimInputError, match=rf"--set {override}: the sweep's {swept} = .* removes "
                                                    rf"{override.split('=')[0]}"):
            plan_sweep(SCENE, {"parameters": {swept: {"values": values}}}, overrides=[override])
    # a choosing key: a sample of load.type = "cycles" leaves the --set target_strain out
    with pytest.raises(KnitsimInputError, match=r"--set load.target_strain=0.5: the sweep's load.type"):
        plan_sweep(SCENE, {"parameters": {"load.type": {"values": ["cycles", "monotonic"]}}},
                   overrides=["load.target_strain=0.5"])
    # another quantity is kept by every sample: runs, at the --set value
    plan = plan_sweep(SCENE, {"parameters": {"friction.phi0_deg": {"values": [-1.0, 1.0]}}},
                      overrides=["friction.m=0.3"])
    assert [cells[0].m for cells in plan.params] == [0.3, 0.3]


def test_two_axes_stating_one_quantity_are_refused():
    # a blind probe swept friction.phi0 and friction.phi0_deg together: every sample ran the later axis's phi0_deg
    # (it removes phi0 from the sample's scene), results.nc labelled by both, the phi0 axis changing nothing
    import pytest
    from knitsim.errors import KnitsimInputError
    for first, later, vals in (("friction.phi0", "friction.phi0_deg", [-1.0, 1.0]),
                               ("friction.m", "friction.mu_k", [0.15, 0.2]),
                               ("load.upper_strain", "load.type", ["cycles", "monotonic"])):
        with pytest.raises(KnitsimInputError, match=rf'^sweep.parameters."{first}": the later axis "{later}" = .* '
                                                    r'removes it'):
            plan_sweep(SCENE, {"parameters": {first: {"values": [0.5, 0.55] if first.startswith("load") else
                                                      [0.05, 0.1]}, later: {"values": vals}}})
    # two quantities: both reach every sample
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.1, 0.3]},
                                             "friction.phi0_deg": {"values": [-1.0, 1.0]}}})
    assert sorted({(c[0].m, round(float(np.degrees(c[0].phi0)), 12)) for c in plan.params}) == [
        (0.1, -1.0), (0.1, 1.0), (0.3, -1.0), (0.3, 1.0)]


def test_a_damaged_chunk_is_computed_again_on_resume(tmp_path, capsys):
    # a blind probe: a chunk file that is not a valid archive ended --resume in a BadZipFile traceback
    sweep = {"chunk_size": 1, "parameters": {"friction.m": {"values": [0.1, 0.2]}}}
    ref = run_sweep(plan_sweep(SCENE, sweep), tmp_path / "out", workers=0, progress=None, plots=False).dataset
    (tmp_path / "out" / "chunks" / "chunk_00001.npz").write_bytes(b"not an archive")
    import sys
    run = run_sweep(plan_sweep(SCENE, sweep), tmp_path / "out", resume=True, workers=0, progress=sys.stderr,
                    plots=False)
    assert run.skipped == [0] and run.dataset.identical(ref)
    assert "chunk_00001.npz cannot be read: computed again" in capsys.readouterr().err


def test_the_cells_own_warnings_are_carried_per_sample(tmp_path):
    # a blind probe: knitsim cell warns heads_interpenetrate (m 0.2 and 0.5 to 0.6) and zero_force_cycle (m 0.2:
    # cycle 2 peaks at 8 % of cycle 1); no sweep output carried either.  Expected: the warnings of the cell's own
    # summary (knitsim.io.results.cell_summary on the same cells run alone), sample by sample
    from knitsim.cell.engine import simulate
    from knitsim.io.results import cell_summary
    from knitsim.sweep.runner import warning_samples
    scene = dict(SCENE, load=dict(SCENE["load"], cycles=2))
    plan = plan_sweep(scene, {"parameters": {"friction.m": {"values": [0.2, 0.5]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    text = dataset_csv(ds)
    h = simulate([plan.base.params[0].replace(m=m) for m in (0.2, 0.5)], plan.programs[0], engine="warp", device="cpu")
    for flag in ("heads_interpenetrate", "zero_force_cycle", "reload_below_earlier_loading",
                 "reload_loss_continues", "reload_above_first_loading", "wale_spacing_below_jamming"):
        alone = [int(any(w["code"] == flag for w in cell_summary(h, c)["warnings"])) for c in range(2)]
        assert ds[flag].values.ravel().tolist() == alone, flag
        assert [r["sample"] for r in warning_samples(ds, flag)] == [i for i, a in enumerate(alone) if a]
    assert ds["zero_force_cycle"].values.ravel().tolist() == [1, 0]
    header = text.splitlines()[0].split(",")
    assert header[-8:] == ["heads_interpenetrate", "zero_force_cycle", "reload_below_earlier_loading",
                           "reload_loss_continues", "reload_above_first_loading", "reload_below_first_loading",
                           "wale_spacing_below_jamming", "domain"]
    # the paper's cycles never load past an earlier maximum: nothing to compare with a monotonic pull
    assert ds["reload_below_first_loading"].values.ravel().tolist() == [0, 0]


def test_a_reload_below_the_first_loading_is_carried_per_sample(tmp_path):
    # a blind probe: waypoints 0.3, 0.29, 0.5 with Hong's unloading rule end 18 % below the monotonic pull at 0.5
    # (knitsim cell warns reload_below_first_loading); sweeps did not check it.  Expected: the warning of the cell's
    # own summary against its own monotonic pull (knitsim.io.results.first_loading, as knitsim cell runs it), sample
    # by sample, over both unloading rules
    from knitsim.cell.engine import simulate
    from knitsim.io.results import cell_summary, first_loading, first_loading_curve
    from knitsim.sweep.runner import warning_samples
    scene = dict(SCENE, load={"type": "piecewise", "waypoints": [0.3, 0.29, 0.5], "max_increment": 0.01})
    plan = plan_sweep(scene, {"parameters": {"rules.unloading_rule": {"values": ["hong_constant_t", "dusserre"]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    params = [plan.base.params[0].replace(unloading_rule=r) for r in ("hong_constant_t", "dusserre")]
    h = simulate(params, plan.programs[0], engine="warp", device="cpu")
    ref = first_loading(params, plan.programs[0])
    alone = [int(any(w["code"] == "reload_below_first_loading"
                     for w in cell_summary(h, c, reference=first_loading_curve(ref, c))["warnings"])) for c in range(2)]
    assert alone[0] == 1                          # the probe's case is warned
    assert ds["reload_below_first_loading"].values.ravel().tolist() == alone
    assert [r["sample"] for r in warning_samples(ds, "reload_below_first_loading")] == [i for i, a in enumerate(alone)
                                                                                        if a]


def test_a_reload_above_the_first_loading_is_carried_per_sample(tmp_path):
    # the calibrated specimen's cell (m 0.45, in-plane width 0.79 mm) reloads cycle 2 at three times its first
    # loading; with the roving's compact width (0.58 mm = d) it does not.  Expected: the warning of the cell's own
    # summary, sample by sample, in results.nc, results.csv and the sweep's summary
    from knitsim.sweep.runner import warning_samples
    scene = dict(SCENE, friction={"m": 0.45, "phi0": 0.0}, rules={"force_cap_N": 50.0},
                 load=dict(SCENE["load"], cycles=2))
    plan = plan_sweep(scene, {"parameters": {"yarn.in_plane_width": {"values": [0.79, 0.58]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    assert ds["reload_above_first_loading"].values.ravel().tolist() == [1, 0]
    assert [r["sample"] for r in warning_samples(ds, "reload_above_first_loading")] == [0]
    rows = list(csv.DictReader(io.StringIO(dataset_csv(ds))))
    assert {(r["yarn.in_plane_width"], r["reload_above_first_loading"]) for r in rows} == {("0.79", "1"),
                                                                                          ("0.58", "0")}
