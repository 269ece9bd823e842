"""A patch's outputs name the rules its cells ran with: ``summary.json``'s ``rules`` (each set, its meaning and
its cells) and ``cells.nc``'s per-cell flag variables (which cells are Coulomb, which Dahl).  A blind probe
found a patch summary naming no friction law or rule and a cells.nc that could not tell Dahl cells from
Coulomb ones (knitsim cell's summary names them).  Expected values: the scene's own zones (a 4 x 3 patch
whose wales 1 and 2 are Dahl with hong_constant_t: 8 cells, the other 4 Coulomb with the defaults)."""
from __future__ import annotations

import io

import numpy as np
import xarray as xr

from knitsim.io.patch_results import cells_nc, patch_summary
from knitsim.patch.runner import run_patch
from knitsim.scene.patch_scene import load_patch_scene


def test_a_patch_of_two_rule_sets_names_both_with_their_cells():
    doc = {"patch": {"wales": 3, "courses": 4}, "yarn": {"material": "e_glass"},
           "knit": {"material": "e_glass_plain"}, "friction": {"m": 0.2},
           "load": {"type": "monotonic", "target_strain": 0.1, "max_increment": 0.05},
           "zones": [{"wales": [1, 3], "friction": {"model": "dahl", "dahl_sigma": 30.0},
                      "rules": {"unloading_rule": "hong_constant_t"}}]}
    scene = load_patch_scene(doc)
    m = scene.model
    h = run_patch(m, scene.program)
    rules = patch_summary(h, h.info["ref_length_mm"], model=m)["rules"]
    assert [(r["friction"]["value"], r["unloading_rule"]["value"], r["cells"]) for r in rules] == [
        ("coulomb", "dusserre", 4), ("dahl", "hong_constant_t", 8)]
    assert "Dahl" in rules[1]["friction"]["meaning"] and rules[0]["force_cap_N"]["value"] == float(m.rules["force_cap_N"][0, 0])
    ds = xr.open_dataset(io.BytesIO(cells_nc(h, m.fields, None, m.rules)), engine="h5netcdf")
    assert ds["friction"].attrs["flag_meanings"] == "coulomb dahl"
    assert ds["friction"].values.tolist() == [[0, 1, 1]] * 4
    assert ds["unloading_rule"].values.tolist() == [[0, 1, 1]] * 4
    assert np.all(ds["force_cap_N"].values == float(m.rules["force_cap_N"][0, 0]))
    # a Dahl cell runs no stage rule (its friction follows the slip at B): said, not the Coulomb meaning
    assert "not used by Dahl" in rules[1]["unloading_rule"]["meaning"]
    assert "not used by Dahl" in rules[1]["reload_rule"]["meaning"]
    assert "not used" not in rules[0]["unloading_rule"]["meaning"]


def test_a_dahl_cells_stage_rules_change_no_number_and_its_summary_says_they_are_unused():
    """The stage rules belong to the Coulomb (Table 4) cycle: the Dahl law's friction angle follows the slip
    at B in every stage (model.md, "Dahl at the crossing"), so its forces are the same under either
    unloading and reload rule (identity), and the cell summary says the rules are not used (a blind probe
    read "SF- freezes beta, S- freezes T" in a Dahl run's summary)."""
    from knitsim.cell.batch import run_batch
    from knitsim.cell.load_program import cycles
    from knitsim.cell.material import CellParams
    from knitsim.io.results import rules_of

    base = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, friction="dahl", dahl_sigma=50.0,
                      force_cap_N=10.0)
    cells = [base, base.replace(unloading_rule="hong_constant_t"), base.replace(reload_rule="freeze_rn")]
    F = run_batch(cells, cycles(0.1, 0.5, 2, 0.02)).values["F"]
    assert np.array_equal(F[:, 0], F[:, 1]) and np.array_equal(F[:, 0], F[:, 2])
    r = rules_of(base)
    assert "not used by Dahl" in r["unloading_rule"]["meaning"] and "not used by Dahl" in r["reload_rule"]["meaning"]
    assert "Table 4" in rules_of(base.replace(friction="coulomb", dahl_sigma=0.0))["unloading_rule"]["meaning"]
