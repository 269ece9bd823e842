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
    with pytest.raises(KnitsimInputError, match="belongs to another scene"):
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
