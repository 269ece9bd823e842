"""Convergence of the series coupling of a column (knitsim.patch.coupling) through unloading to slack and
reloads from slack, checked against an independent replay of every cell on its own.

Sources: in series the cells carry one force and their length changes add up to the grip
displacement (rigid grips).  Each cell of the patch is replayed alone through the course lengths the
patch committed for it (``run_batch`` on a one-cell program of those strains, the loading direction of
each increment the grip's): by the identity of series equilibrium, the force the single cell reports
at every committed length must equal the column force (to the coupling's tolerance), for every cell,
at every increment, slack included (F = 0).  The cells differ in phi0 across [-phimax, phimax], as in
a random-phi0 patch: some slide, some stick, and they go slack at different lengths, the cases that
the coupling must converge on (benchmarks/README.md, "Where the patch's time goes").
"""
from __future__ import annotations

import numpy as np

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams
from knitsim.cell.stages import LABEL_CODES
from knitsim.patch.coupling import COL_OK
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Table 1 / section 2.2 / section 3.4 (dusserre2015.toml)
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)
PHIMAX = float(np.arctan(P.m))


def test_column_converges_through_slack_and_reload_and_each_cell_is_its_own_single_cell(device):
    phi0 = np.array([[-0.9, 0.35], [0.8, -0.4], [-0.1, 0.95], [0.5, -0.75]]) * PHIMAX
    cells = [[P.replace(phi0=float(v)) for v in row] for row in phi0]
    prog = cycles(0.10, 0.60, 2, 0.01)
    h = run_patch(PatchModel.from_cells(cells), prog, device=device, dedup=False)
    # every column converged at every increment, within few trials
    assert np.all(h.column_status == COL_OK)
    assert h.column_iterations.max(axis=1).mean() < 6.0
    C, label = h.groups["C"], h.groups["label"]
    # the program reaches slack on unloading and reloads from it (the case under test)
    slack = label == LABEL_CODES["slack"]
    reload = np.nonzero(np.diff(prog.direction) > 0)[0] + 1
    assert slack.any() and slack[reload - 1].any()
    # the lengths add up to the grip displacement where the column carries force
    g_col = np.asarray(PatchModel.from_cells(cells).grouping(False).group_column)
    C0 = P.C0
    u = prog.strain * C0 * len(cells)
    for j in range(2):
        dC = (C[:, g_col == j] - C0).sum(axis=1)
        loaded = h.column_force_N[:, j] > 0
        np.testing.assert_allclose(dC[loaded], u[loaded], rtol=0, atol=1e-9)
        # a slack column is longer than the grips' distance (the rest is slack, reported)
        assert np.all(dC[~loaded] >= u[~loaded] - 1e-9)
    # each cell alone, driven through its own committed lengths, reports the column's force
    groups = PatchModel.from_cells(cells).grouping(False)
    for g, p in enumerate(groups.params):
        single = LoadProgram(C[:, g] / p.C0 - 1.0, prog.cycle, prog.direction, prog.waypoints)
        f = run_batch([p], single, device=device, ).force_per_wale[:, 0]
        col_F = h.column_force_N[:, g_col[g]]
        tol = 1e-10 + 1e-8 * np.abs(col_F)
        np.testing.assert_array_less(np.abs(f - col_F), 10 * tol + 1e-12)
