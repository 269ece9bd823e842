"""A long column of random cells reloading from slack converges: the coupling tells a cell's force jump from the
cells' own force resolution.

Found by ``knitsim run`` of a 300 x 300 random-phi0 E-glass patch (scenes/random_phi0.toml's knit, the paper's
cycles 0.1 -> 0.6) on a GPU: columns 257 and 186 did not converge at increments 124 and 125, where they reload
from slack (grip strain 0.24, F = 1.3e-4 N per wale), and were held there (flagged: summary, console). The same
column alone on the CPU, with either coupling, does the same. Two points of one cell at one length (within
1e-11 C0) differed in force by 1e-6 to 1e-5 of F, just above the column's force tolerance (1e-10 N): the cells'
own resolution where F = 2 P sin(gamma) << P, which the jump detector took for a discontinuity of the cell's
force and cut the column's trials short (kernels/branch_points.py JUMP_RTOL).

Where the expectation comes from: a column of cells in series has an equilibrium at every grip displacement
(Phi(F), the sum of the cells' length changes at the common force F less u, is monotone non-decreasing in F:
knitsim.patch.coupling), so every increment must converge; the converged column's cells carry one force within
the coupling's tolerance.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.load_program import LoadProgram
from knitsim.patch.coupling import COL_OK, PatchSolver
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch
from knitsim.scene.patch_scene import load_patch_scene

SCENE = """title = "E-glass, random initial friction angle phi0, 300 x 300"
engine = "warp"
device = "cpu"
seed = 2015
[patch]
wales = 300
courses = 300
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.20
[rules]
force_cap_N = 10.0
[maps.phi0]
type = "random"
low = -1.0
high = 1.0
scale = "phimax"
[load]
type = "cycles"
cycles = 3
lower_strain = 0.1
upper_strain = 0.6
max_increment = 0.01
"""


@pytest.mark.parametrize("on_device", [True, False], ids=["device-coupling", "numpy-coupling"])
def test_a_random_column_reloading_from_slack_converges(tmp_path, monkeypatch, on_device):
    path = tmp_path / "patch.toml"
    path.write_text(SCENE)
    scene = load_patch_scene(str(path), [], engine=None, device="cpu")
    grouping = scene.model.grouping(dedup=False)
    goc = grouping.group_of_cell
    # the column that failed: its 300 cells as the scene made them (phi0 drawn from the scene's seed)
    column = PatchModel.from_cells([[grouping.cell_params(int(goc[i, 257]))] for i in range(goc.shape[0])])
    prog = scene.program
    n = 126                                             # through the reload from slack (increments 124, 125)
    program = LoadProgram(prog.strain[:n], prog.cycle[:n], prog.direction[:n], prog.waypoints)
    monkeypatch.setattr(PatchSolver, "device_branch_points", on_device)
    h = run_patch(column, program, engine="warp", device="cpu", dedup=True, **scene.solver_options)
    assert np.all(h.column_status[:, 0] == COL_OK), np.flatnonzero(h.column_status[:, 0] != COL_OK) + 1
    assert np.all(h.groups["status"] == 0)
    # increment 124 is the reload: the column carries force again, one force along it (the coupling's
    # tolerance: 1e-10 N + 1e-8 F)
    F = np.asarray(h.groups["F"])[123]
    assert h.force_per_wale_N[122] == 0.0 and h.force_per_wale_N[123] > 1e-4
    assert F.max() - F.min() <= 1e-10 + 1e-8 * F.max()
