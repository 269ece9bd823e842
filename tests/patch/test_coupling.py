"""Series / parallel coupling against single-cell runs (independent combinations of single-cell curves).

Sources: a uniform patch is the single cell (identity: equal force in series, equal
strain in parallel); a series column of two materials: at equal force the changes
in length add (hand combination of the single-cell loading curves C(F)); parallel
columns: at equal strain the forces add; a graded column lies between the uniform
columns of its extreme materials (monotonicity of the force in L, checked on the
single cells).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import cycles, monotonic
from knitsim.cell.material import CellParams
from knitsim.patch.coupling import COL_OK
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Table 1 / section 2.2 / section 3.4 (dusserre2015.toml)
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
Q = P.replace(L=13.5)


def test_uniform_patch_is_the_single_cell_exactly(device):
    prog = cycles(0.10, 0.60, 1, 0.02)
    single = run_batch([P], prog, device=device).force_per_wale[:, 0]
    h = run_patch(PatchModel.uniform(P, 3, 4), prog, device=device)
    assert h.info["n_groups"] == 1
    assert np.array_equal(h.force_per_wale_N, single)
    assert np.array_equal(h.column_force_N, np.repeat(single[:, None], 4, axis=1))
    assert np.all(h.column_status == COL_OK)


@pytest.mark.parametrize("criterion", ["w_4d", "head_gap"])
def test_uniform_patch_with_in_plane_width_is_the_single_cell(device, criterion):
    """In-plane width and jamming by contact run in patches as in the cell (identity), and the
    patch records the head gap and the interpenetration flag of every committed state."""
    p = P.replace(in_plane_width=0.79, m=0.45, jamming_criterion=criterion, force_cap_N=50.0)
    prog = cycles(0.10, 0.60, 1, 0.02)
    cell = run_batch([p], prog, device=device)
    h = run_patch(PatchModel.uniform(p, 3, 2), prog, device=device)
    assert np.array_equal(h.force_per_wale_N, cell.force_per_wale[:, 0])
    assert np.array_equal(h.groups["head_gap"][:, 0], cell.values["head_gap"][:, 0])
    assert np.array_equal(h.groups["interpenetrating"][:, 0], cell.values["interpenetrating"][:, 0])
    # W = 4 w lets the heads overlap before it jams; contact jamming never does (README)
    assert h.groups["interpenetrating"].any() == (criterion == "w_4d")


def test_uniform_patch_without_dedup(device):
    # every cell its own solve: identical cells get identical trials, the column force is
    # that of the single cell up to the rounding of the imposed strain (C0 + u/n vs C0 (1 + e))
    prog = cycles(0.10, 0.60, 1, 0.02)
    single = run_batch([P], prog, device=device).force_per_wale[:, 0]
    h = run_patch(PatchModel.uniform(P, 3, 2), prog, device=device, dedup=False)
    assert h.info["n_groups"] == 6
    np.testing.assert_allclose(h.force_per_wale_N, single, rtol=1e-10, atol=1e-13)
    assert np.all(h.column_status == COL_OK)


def test_uniform_reference_engine_equals_reference_cell():
    from knitsim.cell.cycle import run_cell
    prog = monotonic(0.1, 0.05)
    single = run_cell(P, prog).force_per_wale[:, 0]
    h = run_patch(PatchModel.uniform(P, 2, 1), prog, engine="reference", dedup=False)
    np.testing.assert_allclose(h.force_per_wale_N, single, rtol=1e-9, atol=1e-12)


def _loading_curve(p, top, inc, device):
    h = run_batch([p], monotonic(top, inc), device=device)
    ok = h.status[:, 0] == 0          # up to the force cap (the jammed branch diverges)
    return h.values["C"][ok, 0], h.force_per_wale[ok, 0]


def test_series_two_materials_add_lengths_at_equal_force(device):
    prog = monotonic(0.4, 0.01)
    h = run_patch(PatchModel.from_cells([[P], [Q]]), prog, device=device)
    assert np.all(h.column_status == COL_OK)
    Cp, Fp = _loading_curve(P, 0.9, 0.002, device)
    Cq, Fq = _loading_curve(Q, 0.9, 0.002, device)
    u = h.grip_strain * (P.C0 + Q.C0)
    F = h.column_force_N[:, 0]
    # compare where both single cells are on monotone loading branches covering F
    lo = max(Fp[1], Fq[1])
    hi = min(Fp.max(), Fq.max())
    rows = (F > lo) & (F < hi)
    assert rows.sum() >= 8
    for Fc in (Fp, Fq):
        assert np.all(np.diff(Fc[1:]) > 0)
    hand = (np.interp(F[rows], Fp[1:], Cp[1:]) - P.C0) + (np.interp(F[rows], Fq[1:], Cq[1:]) - Q.C0)
    np.testing.assert_allclose(u[rows], hand, rtol=2e-3)
    # the cells' own strains add up to the grip displacement (rigid grips)
    dC = h.groups["C"] - np.array([P.C0, Q.C0])
    np.testing.assert_allclose(dC.sum(axis=1), u, rtol=1e-12, atol=1e-12)


def test_parallel_two_materials_add_forces_at_equal_strain(device):
    prog = cycles(0.10, 0.50, 1, 0.025)
    h = run_patch(PatchModel.from_cells([[P, Q], [P, Q]]), prog, device=device)
    single = run_batch([P, Q], prog, device=device).force_per_wale
    np.testing.assert_array_equal(h.column_force_N, single)
    np.testing.assert_array_equal(h.force_N, single[:, 0] + single[:, 1])


def test_graded_patch_between_uniform_patches(device):
    prog = monotonic(0.4, 0.02)
    L = np.linspace(13.5, 14.1, 4)
    graded = PatchModel.from_cells([[P.replace(L=float(x))] * 2 for x in L])
    hg = run_patch(graded, prog, device=device)
    hp = run_patch(PatchModel.uniform(P, 4, 2), prog, device=device)
    hq = run_patch(PatchModel.uniform(Q, 4, 2), prog, device=device)
    assert np.all(hg.column_status == COL_OK)
    lo = np.minimum(hp.force_per_wale_N, hq.force_per_wale_N)
    hi = np.maximum(hp.force_per_wale_N, hq.force_per_wale_N)
    tol = 1e-9
    assert np.all(hg.force_per_wale_N >= lo - tol) and np.all(hg.force_per_wale_N <= hi + tol)
    # and strictly inside once the cells slide (not a copy of either)
    assert np.all((hg.force_per_wale_N[5:] > lo[5:]) & (hg.force_per_wale_N[5:] < hi[5:]))


def test_uniform_patch_with_an_effect_is_the_single_cell(device):
    """The model extensions run in patches as in the cell engine (identity: a uniform patch is its cell)."""
    from knitsim.cell.effects import EffectSet
    p = P.replace(effects=EffectSet(on=("yarn_compaction",), compaction_k=20.0), force_cap_N=50.0)
    prog = cycles(0.10, 0.60, 1, 0.02)
    cell = run_batch([p], prog, device=device)
    h = run_patch(PatchModel.uniform(p, 3, 2), prog, device=device)
    assert np.array_equal(h.force_per_wale_N, cell.force_per_wale[:, 0])
    assert np.all(h.column_status == COL_OK)


def test_columns_of_different_friction_laws_and_rules_are_their_cells(device):
    """A patch mixes Coulomb and Dahl columns with their own unloading rules (parallel columns at one
    grip strain: each uniform column carries its own cell's force, the grip the sum)."""
    a = P.replace(force_cap_N=50.0)
    b = P.replace(friction="dahl", dahl_sigma=30.0, unloading_rule="hong_constant_t", force_cap_N=50.0)
    prog = cycles(0.10, 0.50, 1, 0.02)
    single = run_batch([a, b], prog, device=device).force_per_wale
    model = PatchModel.from_cells([[a, b], [a, b]])
    assert model.grouping().n_groups == 2
    h = run_patch(model, prog, device=device)
    np.testing.assert_allclose(h.column_force_N, single, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(h.force_N, single.sum(axis=1), rtol=1e-12)


def test_a_series_column_that_cannot_pass_a_cap_stops_at_it(device):
    """An E-glass / basalt column (Table 1's two yarns, section 2.2's knits, caps of 10 N) pulled past where its
    cells, in series, reach the cap.  Expected, by series equilibrium and the single cells (each run alone to its
    cap: at the cap F the column's length is the sum of the cells' lengths at F): the program's last grip
    displacement lies beyond that sum, so the column stops at the cap as a uniform column's cell does (status
    force_cap, within FORCE_CAP_RTOL of it, never above).  Before, the jammed branch is so steep there (9.43 N at
    grip strain 0.73, 13.5 N beyond the cap at 0.74) that the column's sub-increments all failed: it was held as
    not converged at 9.43 N, 5.7 % under the cap, then resumed on the grip's reversal."""
    from knitsim.cell.history import STATUS_FORCE_CAP
    from knitsim.io.checks import FORCE_CAP_RTOL
    basalt = CellParams(B=0.20, d=0.56, L=13.1, W0=4.4, C0=2.7, m=0.17, force_cap_N=10.0)
    top = 0.76
    h = run_patch(PatchModel.from_cells([[P], [basalt]]), monotonic(top, 0.01), device=device)
    # each cell alone: its length where it stops at the cap (bounded by the cell's own location of the event)
    at_cap = []
    for p in (P, basalt):
        cell = run_batch([p], monotonic(1.0, 0.002), device=device)
        k = int(np.flatnonzero(cell.status[:, 0] == STATUS_FORCE_CAP)[0])
        assert cell.force_per_wale[k, 0] == pytest.approx(10.0, rel=1e-9)
        at_cap.append(cell.values["C"][k, 0] - p.C0)
    assert top * (P.C0 + basalt.C0) > sum(at_cap)        # the grip goes past the column's length at the cap
    F = h.column_force_N[:, 0]
    assert F.max() <= 10.0 * (1.0 + 1e-9)
    status = np.asarray(h.groups["status"])
    capped = np.flatnonzero((status == STATUS_FORCE_CAP).any(axis=1))
    assert capped.size, f"never stopped at the cap: held at {F[-1]:.4g} N"
    k = int(capped[0])
    assert F[k] >= (1.0 - FORCE_CAP_RTOL) * 10.0 and np.all(F[k:] == F[k])
    assert (status[:k] == 0).all() and (status[-1] == STATUS_FORCE_CAP).any()


def test_a_column_stopped_at_its_weakest_cells_cap_carries_one_force_no_more_than_that_cap(device):
    """A column of E-glass stitches with one stitch of a stiffer yarn capped at 6 N per wale between them, pulled
    to grip strain 0.8.  Expected, from series equilibrium: at every increment every cell of the column carries the
    column's force (to the coupling's tolerance), so the column never carries more than its weakest cell's cap and
    stops there.  Before, a column whose last trial left the capped cell at 6 N (status ok) beside E-glass
    cells at 6.17 N was committed as it stood and stopped at the cap: cells 0.17 N apart, the column's force
    reported 6.11 N per wale, above the cap its weakest cell cannot pass."""
    from knitsim.cell.history import STATUS_FORCE_CAP
    other = P.replace(B=0.5, d=0.62, L=14.5, W0=4.6, C0=2.8, m=0.35, force_cap_N=6.0)
    h = run_patch(PatchModel.from_cells([[P], [other], [P]]), monotonic(0.8, 0.01), device=device)
    F = np.asarray(h.groups["F"])
    assert (F.max(axis=1) - F.min(axis=1)).max() <= 1e-10 + 1e-8 * F.max()
    assert h.column_force_N.max() <= 6.0 * (1.0 + 1e-9)
    assert (np.asarray(h.groups["status"])[-1] == STATUS_FORCE_CAP).any()


def test_a_column_held_short_of_the_grip_holds_on_unloading_until_the_grip_comes_back(device):
    """A column of a tight stitch (L / (2 C0 + W0 - 4 d) = 1.64, 10.4 N per wale at rest) between two loose ones
    (0.02 and 0.0002 N): its cells' rest forces cannot balance near rest with every cell moving in the grip's
    direction, so it is held (not converged) from its first increments while the grip goes to 0.296.  Expected
    (README, "Runs that stop"): a held column keeps its state until the grip comes back to its cells' lengths, so
    its cells keep the held state while the grip unloads to 0.182, above them, and no cell ever carries more than
    its force cap (20 N).  Before, solved at once on the grip's reversal, its cells were sent along their unloading
    branches to lengths longer than they held: 2,485 N per wale, status ok, under a cap of 20 N."""
    from knitsim.scene.patch_scene import load_patch_scene
    zones = [{"courses": [k, k + 1], "knit": dict(C0=C0, W0=W0, L=L), "friction": {"m": 0.148, "phi0": phi0}}
             for k, (C0, W0, L, phi0) in enumerate([(2.9603, 3.6983, 13.5663, 0.0532),
                                                    (2.4927, 4.1334, 11.1565, -0.0624),
                                                    (2.9500, 4.3284, 15.6725, 0.1183)])]
    sc = load_patch_scene({"engine": "warp", "device": device, "patch": {"wales": 1, "courses": 3},
                           "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
                           "friction": {"m": 0.148}, "rules": {"force_cap_N": 20.0}, "zones": zones,
                           "load": {"type": "piecewise", "waypoints": [0.296, 0.182, 0.314], "max_increment": 0.01}})
    h = run_patch(sc.model, sc.program, device=device)
    F, C = np.asarray(h.groups["F"]), np.asarray(h.groups["C"])
    assert np.all(np.abs(F) <= 20.0)
    u = h.grip_strain * h.info["ref_length_mm"]
    length = (C - np.array([2.9603, 2.4927, 2.9500])).sum(axis=1)    # the cells' lengths' sum [mm]
    top = int(np.flatnonzero(np.asarray(h.direction) < 0)[0]) - 1    # the grip's first reversal, at 0.296
    held = (h.column_status[:, 0] != COL_OK) & (np.asarray(h.direction) < 0) & (u > length + 1e-9)
    assert held.sum() >= 5, held.sum()                                # the grip unloads above the held cells
    assert np.all(C[held] == C[top]) and np.all(F[held] == F[top])
