"""Exact laws of the series/parallel coupling of a patch (knitsim.patch.coupling), each checked by a method
that does not use the coupling: the cell run on its own, a patch of one column, a reordered patch.

Derivations (README, "Patches: series/parallel coupling"):

- Series.  The cells of a column carry one force F (equilibrium of a cut anywhere along it) and their
  changes in course length add up to the grip displacement u = grip strain x reference length (rigid
  grips).  Each cell's force is a function of its own path of lengths alone (the cell law), so the cell
  run on its own through the lengths the patch committed for it, with the grip's loading direction of
  each increment, must report the column's force at every increment.
- Parallel.  The columns share u and nothing else (no course-wise coupling), so a column's solution
  depends on u alone and the grip force is the sum of the columns' forces: each column run alone as a
  one-column patch at the same displacement (its grip strain u over its own rest length, not over the
  patch's mean: columns of another C0 are of another rest length) carries the force it carries in the patch.
- Permutation.  Series: the column's equations (one F, a sum of lengths) are symmetric in its cells, so the
  order of the cells along a column does not change F.  Parallel: the grip force is a sum over columns,
  symmetric in them.  Where dedup makes two columns one class (the same multiset of cells), they are solved
  once: bit for bit.
- Second law.  The grip's work over a closed strain cycle is the sum of the cells' works (F du = sum_j F_j
  sum_i dC_ij): friction at the crossing only dissipates, so a closed cycle's hysteresis is >= 0 on cycles
  that do not start from a jammed reversal (README, "Loops that return energy": Table 4's closures can
  return energy after a jam; the programs here stay below the jam), within the trapezoids' error that the
  run reports (energy_error_estimate_N_mm, knitsim.cell.cycle.dissipated_energy_error).
- Frictionless limit.  With m = 0 a cell never leaves its stage (README, "Rules where Table 4 is silent"):
  its force is a function of its length, the same up and down; a column of such cells then has one
  solution per u, and the patch's loading and unloading coincide at every grip strain.

Tolerances: a column is converged when its cells' forces agree within TOL(F) = force_tol + force_rtol |F|
(1e-10 N + 1e-8 |F|, knitsim.patch.coupling.PatchSolver) and its lengths add up to u within
column_length_tolerance (16 roundings of its rest length).  Two solves of one column, each within TOL of
the exact force, differ by at most 2 TOL; a sum over columns by the sum of theirs.  The reference (NumPy)
cell engine and the Warp batch agree to 1e-12 N here (added).  Largest deviations measured on these
patches (2-core CPU): series 0.50 TOL (reference engine and batch alike); parallel 3.0e-4 of 2 TOL per column
(1.2e-13 N); permutation 1.6e-13 N on the grip force, 5.7e-4 of TOL on a column; frictionless 5.5e-4 of
the bound (4.7e-12 N); hysteresis of every closed cycle 0.25 to 0.82 N mm (all positive).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import run_cell
from knitsim.cell.load_program import LoadProgram, cycles, monotonic
from knitsim.cell.material import CellParams
from knitsim.io.patch_results import patch_summary
from knitsim.patch.coupling import COL_OK, column_length_tolerance
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Dusserre 2015 Table 1 / section 2.2 (dusserre2015.toml): E-glass and basalt on one knit (W0, C0), and a tighter
# knit of the E-glass (L, W0, C0 smaller) for columns of another rest length
EG = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
BA = CellParams(B=0.20, d=0.56, L=13.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
TIGHT = EG.replace(L=13.0, W0=4.0, C0=2.4)
PHIMAX = float(np.arctan(EG.m))
#: the coupling's tolerances (knitsim.patch.coupling.PatchSolver defaults) [N, -]
FORCE_TOL, FORCE_RTOL = 1e-10, 1e-8
#: the reference engine against the Warp batch on one cell [N]
ENGINE_TOL = 1e-12


def tol(F):
    """The coupling's force tolerance at force F [N]."""
    return FORCE_TOL + FORCE_RTOL * np.abs(F)


def scaled(program: LoadProgram, k: float) -> LoadProgram:
    """The same program with every strain times k (the same displacement over a rest length 1/k as long)."""
    return LoadProgram(program.strain * k, program.cycle, program.direction, np.asarray(program.waypoints) * k)


def _heterogeneous_3x4():
    """3 courses x 4 wales: E-glass and the tight knit mixed (wale 3 all tight: a shorter column), phi0 random."""
    phi = np.random.default_rng(7).uniform(-1, 1, (3, 4)) * PHIMAX
    yarn = [[EG, TIGHT, EG, TIGHT], [TIGHT, EG, EG, TIGHT], [EG, EG, TIGHT, TIGHT]]
    return [[yarn[i][j].replace(phi0=float(phi[i, j])) for j in range(4)] for i in range(3)]


@pytest.mark.parametrize("engine", ["reference", "batch"])
def test_series_each_cell_of_an_unlike_column_is_the_cell_alone_at_its_length(engine):
    """A column of three unlike cells (two C0, three phi0) pulled to grip strain 0.4: at every increment the
    cells carry the column's force (within TOL), their lengths add up to u (column_length_tolerance), and each
    cell run alone through its committed lengths (the NumPy reference engine, or the Warp batch) reports the
    column's force within TOL (measured 0.50 TOL)."""
    cells = [[EG.replace(phi0=0.6 * PHIMAX)], [TIGHT.replace(phi0=-0.5 * PHIMAX)], [EG.replace(phi0=-0.9 * PHIMAX)]]
    prog = monotonic(0.4, 0.02)
    model = PatchModel.from_cells(cells)
    h = run_patch(model, prog, dedup=False)
    assert np.all(h.column_status == COL_OK)
    C, F, Fc = h.groups["C"], h.groups["F"], h.column_force_N[:, 0]
    assert Fc[-1] > 1.5 * Fc[1] > 0, "the column carries a rising force"
    assert np.all(np.abs(F - Fc[:, None]) <= tol(Fc)[:, None])
    groups = model.grouping(False)
    C0 = np.array([p.C0 for p in groups.params])
    rest = C0.sum()
    np.testing.assert_allclose((C - C0).sum(axis=1), prog.strain * rest, rtol=0,
                               atol=float(column_length_tolerance(np.array([rest]))[0]))
    for g, p in enumerate(groups.params):
        alone = LoadProgram(C[:, g] / p.C0 - 1.0, prog.cycle, prog.direction, prog.waypoints)
        f = (run_cell(p, alone) if engine == "reference" else run_batch([p], alone, device="cpu")).force_per_wale[:, 0]
        dev = np.abs(f - Fc)
        assert np.all(dev <= tol(Fc) + ENGINE_TOL), (g, float((dev / tol(Fc)).max()))


@pytest.mark.parametrize("dedup", [True, False])
def test_parallel_grip_force_is_the_sum_of_each_column_alone_at_the_same_displacement(dedup):
    """3 x 4 patch, columns unlike (yarn and phi0), one shorter (all tight: 7.2 mm against 7.8 mm), through two
    cycles 0.1-0.4: each column alone as a one-column patch, driven at the patch's displacement (grip strain x
    reference length / its own rest length), carries the patch's column force within 2 TOL, and the grip force
    is their sum within the sum of those (measured 3.0e-4 of 2 TOL)."""
    cells = _heterogeneous_3x4()
    prog = cycles(0.1, 0.4, 2, 0.025)
    h = run_patch(PatchModel.from_cells(cells), prog, dedup=dedup)
    assert np.all(h.column_status == COL_OK)
    ref = h.info["ref_length_mm"]
    total, bound = np.zeros_like(h.force_N), np.zeros_like(h.force_N)
    for j in range(4):
        column = PatchModel.from_cells([[row[j]] for row in cells])
        alone = run_patch(column, scaled(prog, ref / float(column.column_rest_length()[0])), dedup=dedup)
        assert np.all(alone.column_status == COL_OK)
        Fj = alone.column_force_N[:, 0]
        assert np.all(np.abs(h.column_force_N[:, j] - Fj) <= 2 * tol(Fj)), j
        total += Fj
        bound += 2 * tol(Fj)
    assert np.all(np.abs(h.force_N - total) <= bound)


@pytest.mark.parametrize("dedup", [True, False])
def test_reordering_the_cells_of_columns_or_the_columns_leaves_the_grip_force(dedup):
    """The 3 x 4 patch with its columns reordered, and with the cells of each column rotated (a different
    rotation per column): the grip force within the sum of 2 TOL over the columns, each column's force within
    2 TOL of its own before (measured 1.6e-13 N; 5.7e-4 TOL)."""
    cells = _heterogeneous_3x4()
    prog = cycles(0.1, 0.4, 2, 0.025)
    h = run_patch(PatchModel.from_cells(cells), prog, dedup=dedup)
    bound = (2 * tol(h.column_force_N)).sum(axis=1)
    perm = [2, 0, 3, 1]
    hp = run_patch(PatchModel.from_cells([[row[j] for j in perm] for row in cells]), prog, dedup=dedup)
    rotated = [[cells[(i + j) % 3][j] for j in range(4)] for i in range(3)]
    hr = run_patch(PatchModel.from_cells(rotated), prog, dedup=dedup)
    for other, cols in ((hp, perm), (hr, list(range(4)))):
        assert np.all(other.column_status == COL_OK)
        assert np.all(np.abs(other.force_N - h.force_N) <= bound)
        assert np.all(np.abs(other.column_force_N - h.column_force_N[:, cols]) <= 2 * tol(h.column_force_N[:, cols]))


def test_columns_that_are_rotations_of_one_column_carry_one_force():
    """Three columns, each the same three unlike cells in another order: with dedup they are one column class,
    solved once (3 groups, forces equal bit for bit); without, each column solved on its own carries that
    force within 2 TOL."""
    a, b, c = EG.replace(phi0=0.7 * PHIMAX), TIGHT.replace(phi0=-0.3 * PHIMAX), BA.replace(phi0=-0.8 * PHIMAX)
    cells = [[a, c, b], [b, a, c], [c, b, a]]
    model = PatchModel.from_cells(cells)
    prog = cycles(0.1, 0.4, 1, 0.025)
    h = run_patch(model, prog)
    assert h.info["n_groups"] == 3 and model.grouping().n_classes == 1
    assert np.all(h.column_status == COL_OK)
    assert np.array_equal(h.column_force_N, np.repeat(h.column_force_N[:, :1], 3, axis=1))
    hn = run_patch(model, prog, dedup=False)
    assert hn.info["n_groups"] == 9 and np.all(hn.column_status == COL_OK)
    assert np.all(np.abs(hn.column_force_N - h.column_force_N) <= 2 * tol(h.column_force_N))


@pytest.mark.parametrize("seed", [0, 3])
def test_every_closed_cycle_of_a_random_two_yarn_patch_dissipates(seed):
    """4 x 4 patches, E-glass and basalt at random, phi0 uniform over [-phimax, phimax], m random in 0.1-0.45,
    three cycles between random strains (lower 0.05-0.2, upper 0.35-0.5, below the jam): every closed cycle's
    hysteresis (knitsim run's summary) is >= -its energy_error_estimate_N_mm (measured 0.25 to 0.82 N mm, every
    one positive and 18 times its estimate or more)."""
    rng = np.random.default_rng(seed)
    m = float(rng.uniform(0.1, 0.45))
    phi = rng.uniform(-1, 1, (4, 4)) * np.arctan(m)
    yarn = rng.integers(0, 2, (4, 4))
    cells = [[(EG, BA)[yarn[i, j]].replace(m=m, phi0=float(phi[i, j])) for j in range(4)] for i in range(4)]
    model = PatchModel.from_cells(cells)
    prog = cycles(float(rng.uniform(0.05, 0.2)), float(rng.uniform(0.35, 0.5)), 3, 0.01)
    h = run_patch(model, prog)
    assert np.all(h.column_status == COL_OK)
    closed = [c for c in patch_summary(h, h.info["ref_length_mm"], model=model)["cycles"] if c["closed"]]
    assert len(closed) == 2
    for c in closed:
        assert c["hysteresis_energy_N_mm"] >= -c["energy_error_estimate_N_mm"], c


@pytest.mark.parametrize("dedup", [True, False])
def test_a_frictionless_patch_loads_and_unloads_on_one_curve(dedup):
    """3 x 3 patch of E-glass, basalt and the tight knit with m = 0 (phi0 = 0: phimax = 0), two cycles 0-0.4: at
    every grip strain met more than once the grip forces agree within the sum over columns of 2 TOL (measured
    5.5e-4 of it, 4.7e-12 N); the second cycle's hysteresis is zero within its error estimate (7.8e-13 N mm).
    The first cycle starts from the rest state, which is not in equilibrium (README: rest_state_unbalanced), and
    the summary puts the mean of the unequal rest forces before it: its hysteresis is the rest row's (2.0e-3 N
    mm, equal to its estimate), so it is held to its estimate only."""
    e, b, t = EG.replace(m=0.0), BA.replace(m=0.0), TIGHT.replace(m=0.0)
    model = PatchModel.from_cells([[e, b, t], [b, t, e], [e, e, b]])
    prog = cycles(0.0, 0.4, 2, 0.02)
    h = run_patch(model, prog, dedup=dedup)
    assert np.all(h.column_status == COL_OK)
    bound = (2 * tol(h.column_force_N)).sum(axis=1)
    s = np.round(h.grip_strain, 12)
    pairs = 0
    for k in range(len(s)):
        same = np.nonzero(s == s[k])[0]
        pairs += len(same) - 1
        assert np.all(np.abs(h.force_N[same] - h.force_N[k]) <= np.minimum(bound[same], bound[k])), k
    assert pairs >= 3 * 20
    c1, c2 = patch_summary(h, h.info["ref_length_mm"], model=model)["cycles"]
    assert c2["closed"] and abs(c2["hysteresis_energy_N_mm"]) <= c2["energy_error_estimate_N_mm"] + 1e-12
    assert c1["closed"] and abs(c1["hysteresis_energy_N_mm"]) <= c1["energy_error_estimate_N_mm"] * (1 + 1e-6)
