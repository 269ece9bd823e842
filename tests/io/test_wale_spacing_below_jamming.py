"""W below 4 w (the model's jamming limit) is warned where the user looks: cell and patch summaries, console,
plot, sweep flags.

Where the expected outcomes come from:

- the limit itself: W = 4 d is the jamming condition of Hong et al. (2002) and of Dusserre (2015), Table 4 (J+
  holds W = 4 d): four yarn widths across a wale; with an in-plane width w, 4 w (README, "The yarn's in-plane
  width");
- hand-made rows for the check's definition (W in mm against 4 w = 2.32 mm, rounding within 1e-3 of 4 w not
  counted);
- the w_4d criterion holds W >= 4 w by construction (a unilateral constraint), so a w_4d cell pulled into jamming
  is never warned; the head_gap criterion jams at head contact and does not hold W (README, "Interpenetration"):
  the blind probe's calibrated specimen cell (E-glass, Table 1, w = 0.79 mm, m = 0.45) jammed by head contact
  at strain 0.484 and reached W = 0.956 x 4 w at strain 0.6, with no warning.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import cycles, monotonic
from knitsim.cell.material import CellParams
from knitsim.io.checks import wale_spacing_below_jamming
from knitsim.io.patch_results import patch_summary
from knitsim.io.results import summarise
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

SPECIMEN = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.45, in_plane_width=0.79, force_cap_N=50.0)


def test_the_check_by_its_definition():
    strain = np.array([0.1, 0.2, 0.3, 0.4])
    W = np.array([[3.0, 3.0], [2.32 * (1 - 1e-4), 2.5], [2.2, 2.4], [2.0, 2.33]])   # 4 w = 2.32 mm (w = 0.58)
    (w,) = wale_spacing_below_jamming(strain, W, 0.58, direction=np.array([1, 1, 1, -1]))
    assert w.code == "wale_spacing_below_jamming"
    assert "OUTSIDE THE MODEL" in w.message and "in 2 of 4 increments and 1 cell(s)" in w.message
    assert f"down to W = {2.0 / 2.32:.3g} x 4 w" in w.message and "while loading and unloading" in w.message
    # rounding at the w_4d contact (W = 4 w within 1e-3) and NaN rows are not warned
    assert wale_spacing_below_jamming(strain, np.array([2.32, 2.3199, np.nan, 3.0]), 0.58) == []


def test_head_gap_cell_past_4w_is_warned_and_w_4d_is_not():
    h = run_batch([SPECIMEN.replace(jamming_criterion="head_gap"), SPECIMEN], monotonic(0.6, 0.005))
    s = summarise(h, ["head_gap", "w_4d"])
    codes = [[w["code"] for w in c["warnings"]] for c in s["cells"]]
    assert "wale_spacing_below_jamming" in codes[0]
    assert "wale_spacing_below_jamming" not in codes[1]
    (w,) = [w for w in s["warnings"] if w["code"] == "wale_spacing_below_jamming"]
    assert w["cell"] == "head_gap"
    ratio = float(w["message"].split("down to W = ")[1].split(" x 4 w")[0])
    assert ratio == pytest.approx(np.nanmin(h.values["W"][:, 0]) / (4 * 0.79), abs=1e-3)
    assert ratio < 1.0


def test_a_patch_past_4w_is_warned():
    model = PatchModel.uniform(SPECIMEN.replace(jamming_criterion="head_gap"), 2, 2)
    h = run_patch(model, cycles(0.1, 0.6, 1, max_increment=0.01))
    s = patch_summary(h, float(model.column_rest_length()[0]), model=model)
    assert "wale_spacing_below_jamming" in [w["code"] for w in s["warnings"]]


def test_a_sweep_carries_it_per_sample(tmp_path):
    # the same specimen cell, head_gap against w_4d: the flag of each sample is its cell summary's warning
    from knitsim.sweep.runner import plan_sweep, run_sweep, warning_samples
    scene = {"yarn": {"material": "e_glass", "in_plane_width": 0.79}, "knit": {"material": "e_glass_plain"},
             "friction": {"m": 0.45}, "rules": {"force_cap_N": 50.0},
             "load": {"type": "monotonic", "target_strain": 0.6, "max_increment": 0.01}}
    plan = plan_sweep(scene, {"parameters": {"rules.jamming_criterion": {"values": ["head_gap", "w_4d"]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    assert ds["wale_spacing_below_jamming"].values.ravel().tolist() == [1, 0]
    assert [r["sample"] for r in warning_samples(ds, "wale_spacing_below_jamming")] == [0]


def test_yarn_compaction_jams_at_its_compacted_width_and_is_not_warned():
    # yarn_compaction jams at W = 4 d_eff, d_eff down to compaction_min x w (knitsim.cell.effects): a w_4d cell
    # with it holds W >= 4 d_eff, below 4 w by design; the limit is the compacted floor (the do2020 predictions'
    # calibrated yarn went to 0.59 x 4 w, and was warned before the floor was taken)
    from knitsim.cell.effects import EffectSet
    from knitsim.io.checks import jam_width_floor
    eff = EffectSet(on=("yarn_compaction",), compaction_k=20.0, compaction_min=0.5)
    assert jam_width_floor(np.array([0.79, 0.79]), np.array([eff, None], dtype=object)).tolist() == [0.395, 0.79]
    p = SPECIMEN.replace(effects=eff)
    h = run_batch([p], monotonic(0.6, 0.005))
    assert np.nanmin(h.values["W"][:, 0]) < 4 * 0.79 * (1 - 1e-3)           # below 4 w ...
    assert np.nanmin(h.values["W"][:, 0]) >= 4 * 0.79 * 0.5 * (1 - 1e-3)     # ... not below 4 x the floor
    s = summarise(h, ["compacting"])
    assert "wale_spacing_below_jamming" not in [w["code"] for w in s["warnings"]]
