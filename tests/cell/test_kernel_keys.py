"""Specialised kernels (one per kernel key) and the model built from arrays (issue 15).

Expected values come from identities: a specialised kernel is the generic kernel with the code of
the laws a key switches off removed, so a mixed batch split into one launch per key gives the
generic kernel's results bit for bit, in the caller's order; a model built from arrays holds the
same per-cell parameters as one built from CellParams, so its runs are bit for bit the same; a
strided history holds every stride-th row of the full one.
"""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from knitsim.cell.batch import CellModel, CellSolver, ProgramHistory, memory_per_cell, run_batch
from knitsim.cell.history import HISTORY_QUANTITIES
from knitsim.cell.effects import EffectSet
from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError
from knitsim.kernels.specialise import KernelKey, group_cells

# E-glass plain knit, Dusserre (2015) Table 1 and section 2.2
GLASS = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=-0.05, force_cap_N=10.0)
PROG = cycles(0.10, 0.60, 1, max_increment=0.1)


def test_group_cells_splits_by_key_in_order():
    groups = group_cells(np.array([1, 0, 0, 1, 0], bool), np.array([0, 0, 1, 0, 0], bool),
                         np.array([0, 1, 0, 0, 1], bool))
    assert [(k, idx.tolist()) for k, idx in groups] == [
        (KernelKey(False, False, True), [1, 4]), (KernelKey(False, True, False), [2]),
        (KernelKey(True, False, False), [0, 3])]


def test_mixed_batch_of_specialised_kernels_is_the_generic_kernel_bit_for_bit(device):
    # the order interleaves the keys, so that a result written to the wrong cell would show
    cells = [GLASS.replace(friction="dahl", dahl_sigma=20.0),
             GLASS,
             GLASS.replace(jamming_criterion="head_gap"),
             GLASS.replace(effects=EffectSet(on=("normal_load_friction",), load_n=0.9, load_ref_N=0.1)),
             GLASS.replace(phi0=0.1)]
    spec = run_batch(cells, PROG, device=device)
    gen = run_batch(cells, PROG, device=device, specialise=False)
    assert len(CellSolver(CellModel.from_params(cells, device)).groups) == 4
    # bit for bit on the CPU (LLVM compiles the same arithmetic alike in every module); NVRTC
    # may contract multiply-adds differently per module: on an H100 the specialised and generic
    # kernels differed from bitwise (by < 1e-6 relative, the precision of the printed mismatch);
    # on CUDA they are held to issue 15's 1e-9 relative (not yet run there)
    same = np.testing.assert_array_equal if device == "cpu" else (
        lambda a, b, err_msg="": np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12, err_msg=err_msg))
    for k in gen.values:
        same(spec.values[k], gen.values[k], err_msg=k)
    np.testing.assert_array_equal(spec.stage, gen.stage)
    np.testing.assert_array_equal(spec.status, gen.status)
    if device == "cpu":
        assert spec.events == gen.events
    # and each cell is itself alone (batching and grouping change nothing)
    one = run_batch([cells[3]], PROG, device=device)
    np.testing.assert_array_equal(spec.values["F"][:, 3], one.values["F"][:, 0])


def test_model_from_arrays_is_the_model_from_params(device):
    rng = np.random.default_rng(3)
    n = 6
    m = rng.uniform(0.0, 0.4, n)
    arr = dict(B=0.31 * (1 + rng.uniform(-0.02, 0.02, n)), d=0.58, L=14.1, W0=4.4, C0=2.7, m=m,
               phi0=rng.uniform(-1, 1, n) * np.arctan(m), force_cap_N=10.0,
               unloading_rule=np.where(np.arange(n) % 2 == 0, "dusserre", "hong_constant_t"))
    cells = [CellParams(B=float(arr["B"][i]), d=0.58, L=14.1, W0=4.4, C0=2.7, m=float(m[i]), phi0=float(arr["phi0"][i]),
                        force_cap_N=10.0, unloading_rule=str(arr["unloading_rule"][i])) for i in range(n)]
    ma = CellModel.from_arrays(**arr, device=device)
    assert ma.params == cells
    a = run_batch(ma, PROG)
    b = run_batch(cells, PROG, device=device)
    for k in b.values:
        np.testing.assert_array_equal(a.values[k], b.values[k], err_msg=k)



def test_model_from_arrays_takes_an_effect_set_and_an_in_plane_width_per_cell(device):
    """Per-cell effects (an object array; two equal sets held by two objects are one material) and an
    in-plane width with NaN where a cell has none: the same model as from_params of the same cells
    (an independent path: one validated CellParams per cell), its parameters and its curves bit for bit."""
    bend = EffectSet(on=("bending_hysteresis",), bend_h=0.3)
    effects = np.array([bend, EffectSet(on=("bending_hysteresis",), bend_h=0.3), EffectSet(),
                        EffectSet(on=("yarn_compaction",), compaction_k=10.0), bend], dtype=object)
    width = np.array([np.nan, 0.7, np.nan, 0.62, 0.9])
    cells = [GLASS.replace(effects=e, in_plane_width=None if np.isnan(w) else float(w)) for e, w in zip(effects, width)]
    ma = CellModel.from_arrays(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, phi0=-0.05, force_cap_N=10.0,
                               in_plane_width=width, effects=effects, device=device)
    assert ma.params == cells
    np.testing.assert_array_equal(ma.d_jam, [0.58, 0.7, 0.58, 0.62, 0.9])
    a = run_batch(ma, PROG)
    b = run_batch(cells, PROG, device=device)
    for k in b.values:
        np.testing.assert_array_equal(a.values[k], b.values[k], err_msg=k)
    with pytest.raises(KnitsimInputError, match=r"cell\[0, 3\]\.W0 = 2\.0"):
        CellModel.from_arrays(B=0.31, d=0.58, L=14.1, W0=[4.4, 4.4, 4.4, 2.0], C0=2.7,
                              where=lambda i: f"cell[0, {i}]")

def test_strided_history_holds_every_stride_th_row(device):
    cells = [GLASS, GLASS.replace(m=0.3, phi0=0.2), GLASS.replace(m=0.0, phi0=0.0), GLASS.replace(m=0.1)]
    full = run_batch(cells, PROG, device=device)
    model = CellModel.from_params(cells, device)
    state = model.state()
    hist = CellSolver(model).run_program(state, PROG, stride=3)
    q = hist.quantities()[0]
    rows = np.arange(2, len(PROG), 3)
    np.testing.assert_array_equal(q[HISTORY_QUANTITIES.index("F")], full.values["F"][rows])
    np.testing.assert_array_equal(hist.stage.numpy(), full.stage[rows])
    # one launch per increment, captured as a graph, is the same arithmetic; so is its replay
    solver = CellSolver(model)
    state2, fresh = model.state(), model.state()
    hist2 = solver.run_program(state2, PROG, stride=3, per_increment=True)
    np.testing.assert_array_equal(hist2.quantities()[0], q)
    hist2.q.zero_()
    for dst, src in zip(state2._arrays() + [state2.eff], fresh._arrays() + [fresh.eff]):
        wp.copy(dst, src)
    assert solver.run_program(state2, PROG, stride=3, history=hist2, per_increment=True) is hist2
    np.testing.assert_array_equal(hist2.quantities()[0], q)
    # cells sorted by stage before each increment: the same rows, in the caller's order
    state3 = model.state()
    hist3 = CellSolver(model).run_program(state3, PROG, stride=3, per_increment=True, sort_by_stage=True)
    np.testing.assert_array_equal(hist3.quantities()[0], q)
    # two passes per increment (regular increments, then the listed rest), captured and replayed
    solver4, state4 = CellSolver(model), model.state()
    hist4 = solver4.run_program(state4, PROG, stride=3, per_increment=True, compact=True)
    np.testing.assert_array_equal(hist4.quantities()[0], q)
    for dst, src in zip(state4._arrays() + [state4.eff], fresh._arrays() + [fresh.eff]):
        wp.copy(dst, src)
    hist4.q.zero_()
    solver4.run_program(state4, PROG, stride=3, history=hist4, per_increment=True, compact=True)
    np.testing.assert_array_equal(hist4.quantities()[0], q)


def test_run_batch_sorted_by_stage_is_the_plain_run(device):
    """run_batch's GPU default (one launch per increment, cells sorted by stage) on any device: the same
    rows, statuses and events, in the caller's order (each cell reads and writes only its own rows)."""
    cells = [GLASS, GLASS.replace(m=0.3, phi0=0.2), GLASS.replace(m=0.0, phi0=0.0), GLASS.replace(m=0.1),
             GLASS.replace(friction="dahl", dahl_sigma=30.0), GLASS.replace(unloading_rule="hong_constant_t")]
    plain = run_batch(cells, PROG, device=device, sort_by_stage=False)
    done = []
    sorted_ = run_batch(cells, PROG, device=device, sort_by_stage=True, progress=lambda k, n: done.append(k))
    assert done[-1] == len(PROG)
    for name, v in plain.values.items():
        np.testing.assert_array_equal(sorted_.values[name], v, err_msg=name)
    np.testing.assert_array_equal(sorted_.stage, plain.stage)
    np.testing.assert_array_equal(sorted_.status, plain.status)
    assert sorted_.events == plain.events
    # and in two passes per increment, sorted or not (the Dahl cell has no first pass: its group runs
    # the full step alone)
    for sort in (False, True):
        two = run_batch(cells, PROG, device=device, sort_by_stage=sort, compact=True)
        for name, v in plain.values.items():
            np.testing.assert_array_equal(two.values[name], v, err_msg=name)
        np.testing.assert_array_equal(two.stage, plain.stage)
        np.testing.assert_array_equal(two.status, plain.status)
        assert two.events == plain.events


def test_first_pass_takes_the_regular_increments_and_lists_the_others(device):
    """The two-pass increment's first pass (cell_step._advance_cell_variant): on the sliding plateau of
    the paper's loading (increments of 0.01, Dusserre 2015 Fig. 10: no event between 0.2 and 0.4 for
    E-glass) every cell's increment is regular and none is left for the second pass; the reversal's
    increment (Table 4: S+ -> SF-, an event) is regular for none.  Both passes are thus exercised by
    the bit-for-bit tests above."""
    cells = [GLASS, GLASS.replace(m=0.3, phi0=0.2), GLASS.replace(unloading_rule="hong_constant_t"),
             GLASS.replace(m=0.1, phi0=0.0)]
    prog = cycles(0.10, 0.60, 1, max_increment=0.01)
    model = CellModel.from_params(cells, device)
    solver, state = CellSolver(model), model.state()
    hist = ProgramHistory.empty(model, len(prog), 1, False)
    reversal = int(np.flatnonzero(np.diff(prog.direction))[0]) + 1
    pending = []
    for k in range(len(prog)):
        solver.run_program(state, prog, 1, k, k + 1, hist, per_increment=True, compact=True)
        pending.append(sum(int(count.numpy()[0]) for _, count in solver._pending))
    plateau = [k for k in range(len(prog)) if 0.2 <= prog.strain[k] <= 0.4 and prog.direction[k] > 0]
    assert len(plateau) > 10 and all(pending[k] == 0 for k in plateau), pending
    assert pending[reversal] == len(cells), pending
    assert pending[0] == len(cells)  # the first increment leaves the rest state (its first stage change)


def test_full_step_in_slices_is_the_one_launch_full_step(device):
    """The full step in slices (``run_program(..., slices=...)``, ``cell_step._advance_cell_variant``
    with ``sliced``): a walk suspended after each budget of sub-steps keeps what it carries exactly and
    resumes in the next launch, so the rows, statuses and events are those of the full step in one
    launch, bit for bit (an identity), sorted by stage or not, captured as a graph and replayed; the
    Dahl cell's group has no sliced step and runs the full step alone.  At the reversal (Table 4:
    S+ -> SF-, several sub-steps per cell at increments of 0.1) a budget of one sub-step suspends
    cells, so the resumed walk is what is compared."""
    # 40 cells of random friction (m in [0, 0.4], phi0 inside the cone, both unloading rules: a mutation
    # that resumes a walk with the sub-step it started with changes some of them) and a Dahl cell,
    # through 3 cycles at increments of 0.1 (several sub-steps per increment)
    rng = np.random.default_rng(1)
    m = rng.uniform(0.0, 0.4, 40)
    cells = [GLASS.replace(m=float(mj), phi0=float(rng.uniform(-1, 1) * np.arctan(mj)),
                           unloading_rule=("dusserre", "hong_constant_t")[j % 2]) for j, mj in enumerate(m)]
    cells.append(GLASS.replace(friction="dahl", dahl_sigma=30.0))
    prog = cycles(0.10, 0.60, 3, max_increment=0.1)
    plain = run_batch(cells, prog, device=device, sort_by_stage=False, compact=True, slices=())
    for sort in (False, True):
        for slices in ((1,), (1, 2), (3,)):
            sliced = run_batch(cells, prog, device=device, sort_by_stage=sort, compact=True, slices=slices)
            for name, v in plain.values.items():
                np.testing.assert_array_equal(sliced.values[name], v, err_msg=f"{name} {sort} {slices}")
            np.testing.assert_array_equal(sliced.stage, plain.stage)
            np.testing.assert_array_equal(sliced.status, plain.status)
            assert sliced.events == plain.events
    # captured as a graph (not sorted), replayed from the start: the same rows
    model = CellModel.from_params(cells, device)
    solver, state, fresh = CellSolver(model), model.state(), model.state()
    hist = solver.run_program(state, prog, per_increment=True, compact=True, slices=(1, 1))
    np.testing.assert_array_equal(hist.quantities()[0][HISTORY_QUANTITIES.index("F")], plain.values["F"])
    for dst, src in zip(state._arrays() + [state.eff], fresh._arrays() + [fresh.eff]):
        wp.copy(dst, src)
    hist.q.zero_()
    solver.run_program(state, prog, history=hist, per_increment=True, compact=True, slices=(1, 1))
    np.testing.assert_array_equal(hist.quantities()[0][HISTORY_QUANTITIES.index("F")], plain.values["F"])
    # the reversal's increment with a budget of one sub-step: cells are suspended after the first
    # sliced launch (its list, the second of the ping-pong), and none is left suspended after the last
    solver, state = CellSolver(model), model.state()
    hist = ProgramHistory.empty(model, len(prog), 1, False)
    reversal = int(np.flatnonzero(np.diff(prog.direction))[0]) + 1
    for k in range(reversal + 1):
        solver.run_program(state, prog, 1, k, k + 1, hist, per_increment=True, compact=True, slices=(1,))
    suspended = sum(int(count.numpy()[0]) for _, count in solver._pending2)
    assert suspended > 0
    sus = solver._suspended()
    assert not sus.active.numpy().any()
    # what memory_per_cell counts for it is what was allocated: the walks and the second list of cells
    allocated = (sum(a.capacity for a in (sus.active, sus.z, sus.q, sus.real, sus.ints))
                 + sum(lst.capacity for lst, _ in solver._pending2))
    assert memory_per_cell(model, state, len(prog), sliced=True)["suspended"] == allocated / model.cell_count
    np.testing.assert_array_equal(hist.quantities()[0][HISTORY_QUANTITIES.index("F"), :reversal + 1],
                                  plain.values["F"][:reversal + 1])


@pytest.mark.parametrize("kw, message", [
    (dict(m=[0.1, -0.2, 0.1]), r"cells\[1\]\.m = -0\.2"),
    (dict(phi0=[0.0, 0.0, 0.5]), r"cells\[2\]\.phi0"),
    (dict(friction=["coulomb", "dahl", "coulomb"]), r"cells\[1\]\.dahl_sigma"),
    (dict(unloading_rule="hong"), r"cells\[0\]\.unloading_rule = 'hong'"),
    (dict(L=[14.1, 5.0]), r"cells\.C0: 3 values, but cells\.L has 2"),
])
def test_model_from_arrays_names_the_first_bad_cell(kw, message):
    arr = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=[2.7, 2.7, 2.7], m=0.2, phi0=0.0)
    arr.update(kw)
    with pytest.raises(KnitsimInputError, match=message):
        CellModel.from_arrays(**arr)


def test_step_in_two_passes_is_the_one_pass_step(device):
    """CellSolver.step (a patch's trial: committed state in, trial state out) in two passes gives the
    one-pass rows bit for bit, on all cells and on a subset (the other rows of the output untouched),
    through a loading, a reversal and an unloading (identity: the first pass is the full step's
    regular path, cell_step._advance_cell_variant)."""
    cells = [GLASS, GLASS.replace(m=0.3, phi0=0.2), GLASS.replace(unloading_rule="hong_constant_t"),
             GLASS.replace(friction="dahl", dahl_sigma=30.0), GLASS.replace(m=0.1, phi0=0.0),
             GLASS.replace(jamming_criterion="head_gap")]
    prog = cycles(0.10, 0.60, 1, max_increment=0.02)
    model = CellModel.from_params(cells, device)
    solver = CellSolver(model)
    runs = {}
    for compact in (False, True):
        s_in, s_out, ctrl = model.state(), model.state(), model.control()
        rows = []
        for k in range(len(prog)):
            ctrl.set(prog.strain[k], prog.direction[k])
            subset = np.array([0, 2, 3, 5], np.int32) if k % 3 == 1 else None
            for dst, src in zip(s_out._arrays() + [s_out.eff], s_in._arrays() + [s_in.eff]):
                wp.copy(dst, src)
            solver.step(s_in, s_out, ctrl, k, cells=subset, compact=compact)
            rows.append(np.concatenate([s_out.q.numpy().ravel(), s_out.C.numpy(), s_out.stage.numpy(),
                                        s_out.status.numpy(), s_out.x.numpy().ravel()]))
            s_in, s_out = s_out, s_in
        runs[compact] = np.array(rows)
    np.testing.assert_array_equal(runs[True], runs[False])
