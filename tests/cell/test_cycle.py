"""Tests of the NumPy reference load cycle (Dusserre 2015 Table 4 under strain control).

Expected values come from the event definitions (phi = +/-phimax, W = 4d,
F = 0, docs/model.md "Table 4"), path independence of equilibrium within a
stage (refinement), the second law (a closed strain cycle cannot produce
work), the frictionless limit m = 0 (no dissipation: one curve) and the
conditions Table 4 freezes in each stage.  E-glass knit of Dusserre (2015)
Table 1 / section 2.2 throughout.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from knitsim.cell import cycle as cycle_mod
from knitsim.cell.cycle import CellCycle, dissipated_energy, run_cell
from knitsim.cell.load_program import cycles, monotonic, piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.cell.stages import LABEL_CODES, Stage
from knitsim.data import dusserre2015
from knitsim.errors import KnitsimInputError

_D = dusserre2015()
EGLASS = dict(B=_D["yarn"]["e_glass"]["bending_stiffness_N_mm2"], d=_D["yarn"]["e_glass"]["yarn_diameter_mm"],
              L=_D["knit"]["stitch_length_mm"]["e_glass"], W0=_D["knit"]["wale_width_mm"],
              C0=_D["knit"]["course_length_mm"])


def cell(**kw) -> CellParams:
    return CellParams(**{**EGLASS, **kw})


def _bracket(h, ev):
    """Course lengths at the ends of the increment in which event ``ev`` happened."""
    p = h.params[0]
    i = ev["increment"]
    prev = 0.0 if i == 0 else h.strain[i - 1]
    a, b = p.C0 * (1 + prev), p.C0 * (1 + h.strain[i])
    return min(a, b), max(a, b)


def test_slide_event_located_inside_increment():
    # SF+ from phi0 = -phimax: slide where phi reaches +phimax (Table 4, B)
    m = 0.3
    h = run_cell(cell(m=m, phi0=-math.atan(m)), monotonic(0.1, 0.02))
    slides = [e for e in h.events if e["kind"] == "slide"]
    assert len(slides) == 1
    ev = slides[0]
    assert ev["phi"] == pytest.approx(math.atan(m), abs=1e-9)
    lo, hi = _bracket(h, ev)
    assert lo < ev["C"] < hi
    # independent re-solve of the adherence branch at the event's C
    cc = CellCycle(h.params[0])
    st = cc.initial()
    _, q = cc.solve_at(st, ev["C"])
    assert q["phi"] == pytest.approx(math.atan(m), abs=1e-9)


def test_jam_event_at_w_4d_and_jammed_branch_holds_it():
    p = cell(m=0.2, phi0=math.atan(0.2))
    h = run_cell(p, monotonic(0.76, 0.04))
    jams = [e for e in h.events if e["kind"] == "jam"]
    assert len(jams) == 1
    assert jams[0]["W"] == pytest.approx(4 * p.d, abs=1e-9)          # Hong: W = 4d
    lo, hi = _bracket(h, jams[0])
    assert lo < jams[0]["C"] < hi
    jammed = h.jammed[:, 0] == 1
    assert jammed.any()
    np.testing.assert_allclose(h.values["W"][jammed, 0], 4 * p.d, rtol=1e-9)


def test_slack_event_at_zero_force():
    h = run_cell(cell(m=0.2, unloading_rule="hong_constant_t"), piecewise_linear([0, 0.3, 0.0], 0.05))
    slack = [e for e in h.events if e["kind"] == "slack"]
    assert len(slack) == 1
    assert abs(slack[0]["F"]) < 1e-9
    lo, hi = _bracket(h, slack[0])
    assert lo < slack[0]["C"] < hi
    # slack rows report zero force
    rows = np.array(h.labels()) == "slack"
    assert rows.any() and np.all(h.values["F"][rows, 0] == 0.0)


def test_refinement_same_result_at_shared_strains():
    # equilibrium within a stage is path independent: halving the increment
    # must give the same state at the shared strains (events located exactly)
    p = cell(m=0.3, phi0=-math.atan(0.3))
    coarse = run_cell(p, monotonic(0.76, 0.04))
    fine = run_cell(p, monotonic(0.76, 0.02))
    np.testing.assert_allclose(fine.strain[1::2], coarse.strain, rtol=1e-12)
    for k in ("F", "W", "phi", "beta", "P"):
        np.testing.assert_allclose(fine.values[k][1::2, 0], coarse.values[k][:, 0], rtol=1e-7, atol=1e-10)
    assert coarse.labels() == fine.labels()[1::2]


def test_stage_order_monotonic_in_loading():
    h = run_cell(cell(m=0.3, phi0=-math.atan(0.3)), monotonic(0.76, 0.04))
    codes = [LABEL_CODES[lab] for lab in h.labels()]
    assert codes == sorted(codes)                       # adherence -> sliding -> jamming
    # the adherence stage is short: its end is an event inside the first increments
    assert [(e["from"], e["to"]) for e in h.events] == [("adherence", "sliding"), ("sliding", "jamming")]


@pytest.mark.parametrize("rule", ["hong_constant_t", pytest.param("dusserre", marks=pytest.mark.slow)])
def test_second_law_closed_strain_cycle(rule):
    # load 0 -> 0.4 -> 0.1 -> 0.4: the closed strain loop 0.4 -> 0.1 -> 0.4 cannot produce work
    h = run_cell(cell(m=0.2, unloading_rule=rule), piecewise_linear([0, 0.4, 0.1, 0.4], 0.05))
    assert np.all(h.status == 0)
    i0 = int(np.argmax(h.strain >= 0.4 - 1e-12))
    w = dissipated_energy(h.strain[i0:], h.values["F"][i0:, 0])
    assert w >= -1e-12


def test_frictionless_retraces_loading_curve():
    # m = 0: no friction, nothing dissipates: unloading and reloading retrace loading
    h = run_cell(cell(m=0.0), piecewise_linear([0, 0.4, 0.1, 0.4], 0.05))
    assert np.all(h.status == 0)
    F, s = h.values["F"][:, 0], h.strain
    up1 = {round(x, 9): f for x, f, d, c in zip(s, F, h.direction, h.cycle) if d > 0 and c == 1}
    down = [(round(x, 9), f) for x, f, d in zip(s, F, h.direction) if d < 0]
    assert down
    for x, f in down:
        assert f == pytest.approx(up1[x], rel=1e-7, abs=1e-10)
    i0 = int(np.argmax(s >= 0.4 - 1e-12))
    assert abs(dissipated_energy(s[i0:], F[i0:])) < 1e-9


def test_sf_plus_keeps_sbc_and_rn():
    m = 0.3
    h = run_cell(cell(m=m, phi0=-math.atan(m)), monotonic(0.006, 0.001))
    st0 = CellCycle(h.params[0]).initial()
    adh = np.array(h.labels()) == "adherence"
    assert adh.sum() >= 2
    np.testing.assert_allclose(h.values["s_BC"][adh, 0], st0.q["s_BC"], rtol=1e-9)
    np.testing.assert_allclose(h.values["Rn"][adh, 0], st0.q["Rn"], rtol=1e-9)


def test_s_minus_keeps_t_dusserre_rule():
    h = run_cell(cell(m=0.2), piecewise_linear([0, 0.5, 0.3], 0.005))
    rows = (h.stage[:, 0] == Stage.S_UNLOAD)
    assert rows.sum() >= 3
    t = h.values["T"][rows, 0]
    slide = [e for e in h.events if e["kind"] == "slide" and e["to"] == "sliding" and e["increment"] > 0]
    np.testing.assert_allclose(t, slide[-1]["T"], rtol=1e-9)


def test_hong_rule_keeps_t_through_unloading():
    h = run_cell(cell(m=0.2, unloading_rule="hong_constant_t"), piecewise_linear([0, 0.5, 0.3], 0.02))
    i_rev = int(np.argmax(h.direction < 0))
    t_rev = h.values["T"][i_rev - 1, 0]
    rows = (h.direction < 0) & (h.stage[:, 0] != Stage.SLACK)
    assert rows.sum() >= 5
    np.testing.assert_allclose(h.values["T"][rows, 0], t_rev, rtol=1e-9)
    # the SF- -> S- switch happened inside the unloading
    assert any(e["kind"] == "slide" and e["increment"] >= i_rev for e in h.events)


def test_deterministic():
    p, prog = cell(m=0.2, unloading_rule="hong_constant_t"), piecewise_linear([0, 0.3, 0.1], 0.05)
    a, b = run_cell(p, prog), run_cell(p, prog)
    for k in a.values:
        np.testing.assert_array_equal(a.values[k], b.values[k])
    np.testing.assert_array_equal(a.stage, b.stage)
    assert a.events == b.events


def test_the_reference_reports_each_increment_of_each_cell():
    """A hard increment of the float64 reference can take minutes (a Dahl cell from a compressive rest state:
    25-56 s each): `knitsim cell` with it said nothing until a whole cell was done.  simulate's progress now
    counts cell-increments: two cells x 3 increments give 1..6 of 6, in order (the definition)."""
    from knitsim.cell.engine import simulate

    calls = []
    simulate([cell(m=0.2), cell(m=0.1)], monotonic(0.15, 0.05), engine="reference",
             progress=lambda done, total: calls.append((done, total)))
    assert calls == [(k, 6) for k in range(1, 7)]


def test_head_gap_recorded_and_interpenetration_flag():
    p = cell(m=0.2, phi0=math.atan(0.2))
    h = run_cell(p, monotonic(0.7, 0.05))
    gap = h.values["head_gap"][:, 0]
    flag = h.values["interpenetrating"][:, 0]
    np.testing.assert_array_equal(flag, (gap < p.d).astype(float))
    # with W = 4d the heads overlap before jamming (docs/model.md "Jamming")
    assert flag[~h.jammed[:, 0].astype(bool)].any()


def test_head_gap_criterion_jams_earlier_at_gap_d():
    # W decreases monotonically while loading (rows checked below), so jamming
    # at a W above 4d is jamming earlier than Hong's W = 4d
    p = cell(m=0.2, phi0=math.atan(0.2), jamming_criterion="head_gap")
    h = run_cell(p, monotonic(0.6, 0.05))
    assert np.all(np.diff(h.values["W"][~h.jammed[:, 0].astype(bool), 0]) < 0)
    hg = [e for e in h.events if e["kind"] == "jam"][0]
    assert hg["head_gap"] == pytest.approx(p.d, abs=1e-8)
    assert hg["W"] > 4 * p.d
    lo, hi = _bracket(h, hg)
    assert lo < hg["C"] < hi
    jammed = h.jammed[:, 0] == 1
    assert jammed.any()
    # the contact is the active constraint of the jammed branch: the heads stay at distance d
    # (the condition head gap = d, solved to Newton's tolerance), so no state interpenetrates
    np.testing.assert_allclose(h.values["head_gap"][jammed, 0], p.d, atol=1e-9)
    assert not h.values["interpenetrating"][:, 0].any()


@pytest.mark.parametrize("bad", [
    dict(W0=4 * 0.58 - 0.01), dict(L=2 * 2.7 + 4.4 - 4 * 0.58), dict(B=-0.31), dict(m=-0.1),
    dict(m=0.2, phi0=0.3), dict(unloading_rule="nope"), dict(reload_rule="x"),
    dict(jamming_criterion="w4d"), dict(friction="stribeck"), dict(d=float("nan")),
])
def test_bad_input_refused_before_any_solve(bad, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("solve called")
    monkeypatch.setattr(cycle_mod, "initial_state", boom)
    monkeypatch.setattr(cycle_mod, "solve_state", boom)
    with pytest.raises(KnitsimInputError):
        run_cell(cell(**bad), monotonic(0.1))


@pytest.mark.slow
def test_dahl_large_sigma_approaches_coulomb_hong():
    # Dahl with sigma -> infinity is Coulomb stick/slip; its unloading freezes T (Hong)
    m = 0.2
    prog = piecewise_linear([0, 0.06], 0.03)
    c = run_cell(cell(m=m, unloading_rule="hong_constant_t"), prog)
    dl = run_cell(cell(m=m, friction="dahl", dahl_sigma=1e4), prog)
    assert np.all(dl.status == 0)
    np.testing.assert_allclose(dl.values["F"][-1, 0], c.values["F"][-1, 0], rtol=1e-3)


def test_cone_event_releases_beta_on_unloading_from_sliding():
    # Table 4's SF- (beta, s_BC frozen) reversed from sliding at +phimax asks for
    # phi > +phimax soon (stages: "stick_closure"); the cone event is located
    # on the branch with phi = +phimax, after which beta is released
    p = cell(m=0.24)
    prog = piecewise_linear([0, 0.6, 0.5], 0.05)
    h = run_cell(p, prog)
    assert np.all(h.status == 0)
    cones = [e for e in h.events if e["kind"] == "cone"]
    assert len(cones) == 1
    assert cones[0]["phi"] == pytest.approx(p.phimax, abs=1e-9)
    lo, hi = _bracket(h, cones[0])
    assert lo - 1e-12 <= cones[0]["C"] <= hi + 1e-12
    # it ends the stick within the first unloading increment (strain ~0.004 below the top)
    rev = [e for e in h.events if e["kind"] == "reversal"][0]
    assert cones[0]["increment"] == rev["increment"] and cones[0]["C"] <= rev["C"]
    # S- follows with T frozen at the slide event (Table 4 S-), phi = -phimax
    rows = h.stage[:, 0] == Stage.S_UNLOAD
    assert rows.any()
    np.testing.assert_allclose(h.values["phi"][rows, 0], -p.phimax, atol=1e-9)


def test_stick_closure_checked():
    with pytest.raises(KnitsimInputError):
        CellCycle(cell(m=0.2), stick_closure="nope")


def test_a_cell_without_a_rest_state_is_flagged_by_the_reference_as_by_the_batch():
    """A tight loop (L = 10.3 mm with the paper's W0 and C0) has no rest state: the Warp batch flags it
    no_rest_state before any increment, and the README says the NumPy reference does too; run_cell raised
    "initial_state: no start converged; pass starts=..." instead (a blind probe).  Both engines now give
    the same status on every row and no force."""
    from knitsim.cell.batch import run_batch
    from knitsim.cell.cycle import dissipated_energy, run_cell
    from knitsim.cell.history import STATUS_NO_REST_STATE
    from knitsim.cell.load_program import cycles
    from knitsim.cell.material import CellParams
    from knitsim.errors import KnitsimInputError

    tight = CellParams(B=0.31, d=0.58, L=10.3, W0=4.4, C0=2.7, m=0.2, phi0=0.0)
    prog = cycles(0.1, 0.6, 1, 0.05)
    ref, warp = run_cell(tight, prog), run_batch([tight], prog)
    assert np.all(ref.status[:, 0] == STATUS_NO_REST_STATE) and np.all(warp.status[:, 0] == STATUS_NO_REST_STATE)
    # and the README example's integral refuses a strain and a force of other lengths (numpy broadcast them)
    with pytest.raises(KnitsimInputError, match="must be 1-D arrays of one length"):
        dissipated_energy([0.0, 0.1, 0.2], [0.0, 1.0])


def test_the_reference_follows_a_jammed_branch_to_the_default_cap_past_its_residuals_rounding_floor():
    """A blind probe's random domain cell: on its jammed branch (W = 4 d) the force per wale rises from 5 to 45 N
    within 0.05 of strain, alpha - gamma falls to 1.4e-6 rad and the reference's scaled residuals cannot be
    rounded below 2.3e-12 (its Newton asks for 1e-12): the reference stopped at 30.68 N (strain 0.205),
    flagged no_convergence, below the default cap 50 B / d^2.  A Newton stalled at its rounding floor below
    TOL_STALLED (1e-10) has converged: the cell reaches the cap.  Expected: the
    default cap itself (50 B / d^2, definition) at the located event, and the Warp engine's rows (an independent
    method: forward-mode Jacobian, the Newton in ln(alpha - gamma)) within 1e-6."""
    from knitsim.cell.batch import run_batch
    from knitsim.cell.history import STATUS_FORCE_CAP

    cell = CellParams(B=0.0300708, d=0.1823876, L=3.519506, W0=1.0055157, C0=0.911219, m=0.10704, phi0=0.081112)
    prog = monotonic(0.3, max_increment=0.005)
    ref = run_cell(cell, prog)
    warp = run_batch([cell], prog)
    assert ref.status[-1, 0] == STATUS_FORCE_CAP == warp.status[-1, 0]
    cap = [e for e in ref.events if e["kind"] == "force_cap"]
    assert len(cap) == 1 and cap[0]["F"] == pytest.approx(50.0 * cell.B / cell.d ** 2, rel=1e-9)
    np.testing.assert_array_equal(ref.status, warp.status)
    np.testing.assert_allclose(ref.values["F"], warp.values["F"], rtol=1e-6)
    assert [(e["increment"], e["kind"]) for e in ref.events] == [(e["increment"], e["kind"]) for e in warp.events]


def test_the_floor_budget_is_per_increment_for_the_patch_coupling_s_reference_backend_too(monkeypatch):
    """The same cell as one-cell patch (the patch coupling's reference backend calls CellCycle.advance itself,
    not run): its increments to the cap end 1, 4 and 29 solves at the rounding floor (34 in all, counted on
    run_cell).  With MAX_FLOOR_STEPS = 30 each increment stays within it, so the patch reaches the cap as
    run_cell does (the test above); a budget spent over the run (34 > 30) lost the branch (status
    no_convergence).  Expected: the default cap 50 B / d^2 (definition)."""
    from knitsim.cell.history import STATUS_FORCE_CAP
    from knitsim.patch.model import PatchModel
    from knitsim.patch.runner import run_patch

    monkeypatch.setattr(cycle_mod, "MAX_FLOOR_STEPS", 30)
    cell = CellParams(B=0.0300708, d=0.1823876, L=3.519506, W0=1.0055157, C0=0.911219, m=0.10704, phi0=0.081112)
    prog = monotonic(0.3, max_increment=0.005)
    h = run_patch(PatchModel.uniform(cell, 1, 1), prog, engine="reference", dedup=False)
    assert h.groups["status"][-1, 0] == STATUS_FORCE_CAP
    assert h.groups["F"][-1, 0] == pytest.approx(50.0 * cell.B / cell.d ** 2, rel=1e-9)
