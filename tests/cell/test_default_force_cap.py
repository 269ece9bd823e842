"""The default force cap is the yarn's own force scale, 50 B / d^2, not an absolute 50 N.

Where the expected outcomes come from:

- the scaling of the elastica (docs/model.md, eqs 8-9: lengths scale with sqrt(B / P), so at one knit
  geometry every force is proportional to B): a yarn of a tenth of the E-glass B (Dusserre 2015, Table 1;
  knit of section 2.2) carries a tenth of its force at every strain, and its default cap is a tenth too;
- the blind probe's case that this replaces: with the old default of 50 N that thin yarn, pulled to strain 1
  (far into jamming, W = 4 d at 0.685), failed to converge at 15.08 N per wale (status no_convergence, exit 1),
  164 B / d^2; the solver's reach over 2,000 random cells of the domain was at least 79 B / d^2
  (knitsim.cell.material.FORCE_CAP_PER_FORCE_SCALE), so the default cap is met, an expected end;
- an explicit force_cap_N is kept as given (hand-made values);
- a copy of a patch model (``dataclasses.replace``) is the same patch: its default caps stay labelled default,
  and a copy with another B takes 50 B / d^2 of that B (hand-computed: 50 x 0.62 / 0.58^2 = 92.15 N), as
  ``CellParams.replace`` does, while a cap the copy is given is kept as given.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from knitsim.cell.batch import CellModel, run_batch
from knitsim.cell.history import STATUS_FORCE_CAP
from knitsim.cell.load_program import monotonic
from knitsim.cell.material import FORCE_CAP_PER_FORCE_SCALE, CellParams, default_force_cap_N
from knitsim.patch.model import PatchModel

E_GLASS = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2)   # Table 1, section 2.2


def test_default_cap_is_the_yarns_force_scale_and_follows_its_B_and_d():
    p = CellParams(**E_GLASS)
    assert p.force_cap_N is None and p.cap_is_default
    assert p.cap_N == pytest.approx(50.0 * 0.31 / 0.58 ** 2)           # 46.08 N for the paper's E-glass
    thin = p.replace(B=0.031, d=0.29, L=7.05, W0=2.2, C0=1.35)         # the knit scaled by 1/2, B by 1/10
    assert thin.cap_N == pytest.approx(50.0 * 0.031 / 0.29 ** 2)
    assert p.as_dict()["force_cap_N"] == pytest.approx(p.cap_N)        # outputs carry the value in N
    # an explicit cap stays what the user gave, whatever B and d
    q = CellParams(**E_GLASS, force_cap_N=10.0)
    assert q.cap_N == 10.0 and not q.cap_is_default and q.replace(B=0.031).cap_N == 10.0
    assert FORCE_CAP_PER_FORCE_SCALE == 50.0


def test_a_thin_yarn_pulled_far_into_jamming_stops_at_its_default_cap_not_in_a_failure():
    thick = CellParams(**E_GLASS)
    thin = thick.replace(B=0.031)
    h = run_batch([thick, thin], monotonic(1.0, 0.005))
    for j, p in enumerate((thick, thin)):
        assert h.status[-1, j] == STATUS_FORCE_CAP, "stopped at the cap, an expected end"
    F = h.force_per_wale
    stop = [int(np.argmax(h.status[:, j] == STATUS_FORCE_CAP)) for j in range(2)]
    # both stop at the same strain (same shape, forces in proportion to B) ...
    assert stop[0] == stop[1]
    # ... at their own caps (the event is located on the cap) ...
    assert F[stop[0], 0] == pytest.approx(thick.cap_N, rel=1e-6)
    assert F[stop[1], 1] == pytest.approx(thin.cap_N, rel=1e-6)
    # ... and the thin yarn's force is a tenth of the thick one's on every row before (the scaling)
    assert np.allclose(F[:stop[0], 1], 0.1 * F[:stop[0], 0], rtol=1e-6, atol=1e-12)


def test_from_arrays_and_patches_take_each_cells_own_default():
    B = np.array([0.31, 0.031])
    model = CellModel.from_arrays(B, 0.58, 14.1, 4.4, 2.7, m=0.2)
    assert [p.cap_N for p in model.params] == pytest.approx(list(default_force_cap_N(B, 0.58)))
    cells = [[CellParams(**E_GLASS), CellParams(**dict(E_GLASS, B=0.031))],
             [CellParams(**E_GLASS, force_cap_N=7.0), CellParams(**E_GLASS)]]
    patch = PatchModel.from_cells(cells)
    cap = np.asarray(patch.rules["force_cap_N"], float)
    assert cap == pytest.approx(np.array([[50 * 0.31 / 0.58 ** 2, 50 * 0.031 / 0.58 ** 2],
                                          [7.0, 50 * 0.31 / 0.58 ** 2]]))
    assert patch.cap_is_default.tolist() == [[True, True], [False, True]]
    assert patch.cell(0, 1).cap_N == pytest.approx(50 * 0.031 / 0.58 ** 2)


def test_a_scene_without_force_cap_N_labels_the_default_in_its_rules():
    from knitsim.io.results import rules_of
    from knitsim.scene.cell_scene import load_cell_scene
    doc = {"yarn": {"material": "e_glass", "B": 0.031}, "knit": {"material": "e_glass_plain"},
           "friction": {"m": 0.2}, "load": {"type": "monotonic", "target_strain": 0.6}}
    scene = load_cell_scene(doc)
    p = scene.params[0]
    assert p.cap_is_default and p.cap_N == pytest.approx(50 * 0.031 / 0.58 ** 2)
    cap = rules_of(p)["force_cap_N"]
    assert cap["value"] == pytest.approx(p.cap_N) and "50 B / d^2" in cap["meaning"]
    assert "force_cap_N" not in scene.to_toml()            # a re-run of the resolved scene takes the default too
    given = load_cell_scene(doc, ["rules.force_cap_N=5"]).params[0]
    assert given.cap_N == 5.0 and "50 B / d^2" not in rules_of(given)["force_cap_N"]["meaning"]


def test_a_copied_patch_model_keeps_its_default_caps_labelled_and_its_own():
    from knitsim.io.patch_results import rule_sets
    cells = [[CellParams(**E_GLASS), CellParams(**E_GLASS, force_cap_N=7.0)]]
    patch = PatchModel.from_cells(cells)
    same = dataclasses.replace(patch, pretension=0.0)
    assert same.cap_is_default.tolist() == [[True, False]]                 # before: [[False, False]]
    assert np.asarray(same.rules["force_cap_N"], float).ravel() == pytest.approx([46.0761, 7.0], rel=1e-5)
    (default_set,) = [r for r in rule_sets(same) if r["force_cap_N"]["value"] != 7.0]
    assert "50 B / d^2" in default_set["force_cap_N"]["meaning"]
    assert same.cell(0, 0).force_cap_N is None and same.cell(0, 1).force_cap_N == 7.0
    # another B: the default is that yarn's own (before: the first model's 46.08 N, labelled not default)
    fields = dict(patch.fields, B=np.full((1, 2), 0.62))
    stiffer = dataclasses.replace(patch, fields=fields)
    assert stiffer.cap_is_default.tolist() == [[True, False]]
    assert np.asarray(stiffer.rules["force_cap_N"], float).ravel() == pytest.approx([92.1522, 7.0], rel=1e-5)
    # a cap given to the copy is the user's, not a default
    given = dataclasses.replace(patch, rules=dict(patch.rules, force_cap_N=5.0))
    assert not given.cap_is_default.any() and np.asarray(given.rules["force_cap_N"], float).tolist() == [[5.0, 5.0]]
