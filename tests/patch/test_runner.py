"""Patch runs: checkpoint / resume gives the uninterrupted run's results bit for bit; refusals."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.errors import KnitsimInputError
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import PatchInterrupted, run_patch

P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)   # Table 1, section 2.2


def _model():
    rng = np.random.default_rng(3)
    cells = [[P.replace(phi0=float(rng.uniform(-1, 1) * np.arctan(0.2)), L=float(13.6 + 0.5 * rng.random()))
              for _ in range(3)] for _ in range(2)]
    return PatchModel.from_cells(cells)


def test_resume_equals_uninterrupted(tmp_path):
    prog = cycles(0.10, 0.40, 1, 0.05)
    full = run_patch(_model(), prog)
    ck = tmp_path / "checkpoint.pkl"
    with pytest.raises(PatchInterrupted):
        run_patch(_model(), prog, checkpoint=ck, checkpoint_every=2, stop_after=5)
    assert ck.is_file()
    resumed = run_patch(_model(), prog, checkpoint=ck, resume=True)
    assert resumed.info["resumed_from"] == 5
    for name in ("force_N", "column_force_N", "column_status", "column_iterations"):
        assert np.array_equal(getattr(resumed, name), getattr(full, name)), name
    for k in full.groups:
        assert np.array_equal(resumed.groups[k], full.groups[k]), k


def test_resume_refuses_other_scene(tmp_path):
    prog = cycles(0.10, 0.40, 1, 0.05)
    ck = tmp_path / "checkpoint.pkl"
    with pytest.raises(PatchInterrupted):
        run_patch(_model(), prog, checkpoint=ck, stop_after=2)
    # the way out it names is one the --out policy allows (a plain run into a folder of results is refused)
    with pytest.raises(KnitsimInputError, match="belongs to another scene.*start again with --overwrite"):
        run_patch(PatchModel.uniform(P, 2, 3), prog, checkpoint=ck, resume=True)


def test_cell_fields_shapes():
    prog = cycles(0.10, 0.30, 1, 0.1)
    h = run_patch(_model(), prog)
    assert h.cell_field("strain").shape == (len(prog), 2, 3)
    assert np.all(np.isfinite(h.cell_field("strain")))
    # rigid grips: where a column carries force its cells' changes in length add up to the grip
    # displacement; where it is slack (force 0) they exceed it by the reported slack length
    dC = (h.cell_field("strain") * P.C0).sum(axis=1)
    u = h.grip_strain[:, None] * 2 * P.C0
    loaded = h.column_force_N > 0
    np.testing.assert_allclose(dC[loaded], np.broadcast_to(u, dC.shape)[loaded], rtol=1e-10)
    assert (~loaded).any()       # the unloading to 0.10 leaves these columns slack
    np.testing.assert_allclose((dC - u)[~loaded], h.column_slack_mm[~loaded], rtol=1e-12, atol=1e-12)
    assert np.all(h.column_slack_mm[~loaded] > 0)


def test_material_codes_name_equal_rules_and_effects_alike_without_a_loop_over_cells():
    """The vectorised codes (identity of the effect objects first, then their values) against the
    definition, a loop over the cells keyed by (rules, effect set) numbered in row-major order of first
    appearance; two equal EffectSet objects are one material, and the resume fingerprint tells a
    patch from the same patch with one cell's effect changed."""
    from knitsim.cell.effects import EffectSet
    from knitsim.patch.model import RULE_NAMES
    from knitsim.patch.runner import fingerprint

    base = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2)   # Dusserre (2015) Table 1
    e_a, e_b = EffectSet(on=("bending_hysteresis",), bend_h=0.2), EffectSet(on=("bending_hysteresis",), bend_h=0.2)
    rng = np.random.default_rng(3)
    pick = rng.integers(0, 3, (7, 9))
    dahl = rng.random((7, 9)) < 0.3
    cells = [[base.replace(effects=(e_a, e_b, EffectSet())[pick[i, j]],
                           friction="dahl" if dahl[i, j] else "coulomb", dahl_sigma=20.0)
              for j in range(9)] for i in range(7)]
    model = PatchModel.from_cells(cells)
    keys: dict = {}
    expected = np.empty((7, 9), np.int64)
    for idx in np.ndindex(7, 9):
        expected[idx] = keys.setdefault(tuple(model.rules[r][idx] for r in RULE_NAMES) + (model.effects[idx],),
                                        len(keys))
    assert np.array_equal(model.material_codes(), expected)
    assert len(keys) == 4          # {coulomb, dahl} x {bending 0.2 (two equal objects), none}
    prog = cycles(0.1, 0.3, 1, 0.05)
    changed = [row[:] for row in cells]
    changed[6][8] = cells[6][8].replace(effects=EffectSet(on=("bending_hysteresis",), bend_h=0.3))
    other = PatchModel.from_cells(changed)
    assert fingerprint(model, prog) == fingerprint(PatchModel.from_cells(cells), prog)
    assert fingerprint(model, prog) != fingerprint(other, prog)


def test_a_bad_patch_cell_is_named_by_its_place_before_any_work():
    """The patch's model is built from its arrays (no CellParams per cell): a cell with W0 < 4 d
    (loops jammed at rest, Hong et al. 2002's geometry) is refused, named by its course and wale."""
    model = PatchModel.uniform(P, 3, 4)
    fields = {k: np.array(v, dtype=np.float64) for k, v in model.fields.items()}
    fields["W0"][2, 1] = 2.0
    bad = PatchModel(3, 4, fields, model.rules, model.effects)
    with pytest.raises(KnitsimInputError, match=r"cell\[2, 1\]\.W0 = 2\.0"):
        run_patch(bad, cycles(0.10, 0.40, 1, 0.05), dedup=False)


def test_a_ctrl_c_during_an_increment_checkpoints_after_it(tmp_path, monkeypatch, capsys):
    # The solver updates its tangents and branch history inside an increment: a checkpoint saved there would
    # resume onto another trial path. A Ctrl-C (SIGINT) arriving inside increment 3 lets it finish; the
    # checkpoint then holds 4 increments and the resumed run equals the uninterrupted one bit for bit.
    import os
    import signal

    from knitsim.patch import coupling

    prog = cycles(0.10, 0.40, 1, 0.05)
    full = run_patch(_model(), prog)
    ck = tmp_path / "checkpoint.pkl"
    step = coupling.PatchSolver.step

    def step_with_ctrl_c(self, grip_strain, direction, increment=0):
        if increment == 3:
            os.kill(os.getpid(), signal.SIGINT)      # arrives while the increment is under way
        return step(self, grip_strain, direction, increment)

    monkeypatch.setattr(coupling.PatchSolver, "step", step_with_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        run_patch(_model(), prog, checkpoint=ck, checkpoint_every=0)
    # said when the Ctrl-C comes, not when the increment ends (an increment may take minutes: a blind probe's
    # reference-engine patch said nothing to a Ctrl-C for minutes): increment 4 (index 3) of the program's 14
    # (0.4 / 0.05 = 8 up, 0.3 / 0.05 = 6 down), no checkpoint written before it (checkpoint_every = 0)
    assert ("knitsim: interrupted: increment 4 of 14 finishes first, then the checkpoint is written; interrupt "
            "again to stop at once, keeping the last checkpoint (increment 0)") in capsys.readouterr().err
    monkeypatch.setattr(coupling.PatchSolver, "step", step)
    resumed = run_patch(_model(), prog, checkpoint=ck, resume=True)
    assert resumed.info["resumed_from"] == 4
    for name in ("force_N", "column_force_N", "column_status", "column_iterations"):
        assert np.array_equal(getattr(resumed, name), getattr(full, name)), name


def test_the_finished_solve_is_checkpointed_and_resumes_without_solving(tmp_path, monkeypatch):
    """The outputs are written after the solve: the solve is checkpointed first (done = every increment of the
    program), so that a Ctrl-C while they are written loses no solving; a resume of it solves nothing and
    gives the uninterrupted history bit for bit."""
    from knitsim.patch import coupling
    from knitsim.patch.runner import read_checkpoint_header

    prog = cycles(0.10, 0.40, 1, 0.05)
    ck = tmp_path / "checkpoint.pkl"
    full = run_patch(_model(), prog, checkpoint=ck, checkpoint_every=4)
    head = read_checkpoint_header(ck)
    assert (head["done"], head["total"]) == (len(prog), len(prog))       # before: the last periodic one, 8

    def no_solving(*a, **kw):
        raise AssertionError("solved again")

    monkeypatch.setattr(coupling.PatchSolver, "step", no_solving)
    again = run_patch(_model(), prog, checkpoint=ck, resume=True)
    assert again.info["resumed_from"] == len(prog)
    for name in ("force_N", "column_force_N", "column_status", "column_slack_mm"):
        assert np.array_equal(getattr(again, name), getattr(full, name)), name
    for k in full.groups:
        assert np.array_equal(again.groups[k], full.groups[k]), k


def test_a_checkpoint_is_refused_on_another_device(tmp_path, monkeypatch):
    """Devices differ in rounding: a run stopped on one and continued on another would mix the two. The
    checkpoint records the device that solved (in its fingerprint and its header); a resume on another is
    refused with what to do. (No CUDA needed: the device this run is on is what device_identity says.)"""
    from knitsim.patch import runner

    prog = cycles(0.10, 0.40, 1, 0.05)
    ck = tmp_path / "checkpoint.pkl"
    with pytest.raises(PatchInterrupted):
        run_patch(_model(), prog, checkpoint=ck, stop_after=3)
    assert runner.read_checkpoint_header(ck)["device"] == "cpu"
    monkeypatch.setattr(runner, "device_identity", lambda engine, device: "cuda (NVIDIA H100 80GB HBM3, sm_90)")
    with pytest.raises(KnitsimInputError, match=r"computed on cpu, this run is on cuda \(NVIDIA H100 80GB HBM3, "
                                                r"sm_90\): devices differ in rounding.*resume with --device cpu"):
        run_patch(_model(), prog, checkpoint=ck, resume=True)
    monkeypatch.undo()
    assert run_patch(_model(), prog, checkpoint=ck, resume=True).info["resumed_from"] == 3   # its own device
    # the fingerprint tells the devices apart (the reference engine runs on none and hashes as before)
    m = _model()
    assert (runner.fingerprint(m, prog, engine="warp", device="cpu")
            != runner.fingerprint(m, prog, engine="warp", device="cuda (NVIDIA H100 80GB HBM3, sm_90)"))


def test_an_unknown_solver_option_is_refused_naming_it():
    # a blind probe's run_patch(..., tol=1e-3) raised TypeError from PatchSolver.__init__
    from knitsim.cell.load_program import monotonic
    from knitsim.cell.material import CellParams
    from knitsim.errors import KnitsimInputError
    from knitsim.patch.model import PatchModel
    from knitsim.patch.runner import run_patch
    pm = PatchModel.uniform(CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2), 2, 1)
    with pytest.raises(KnitsimInputError, match=r"^tol = 0\.001: not a solver option of run_patch .*force_tol"):
        run_patch(pm, monotonic(0.02, 0.01), tol=1e-3)
