"""Exact invariances of a patch of cells under length and stiffness scaling (dimensional analysis).

Derivation: tests/cell/test_invariances.py (module docstring) shows that a cell with every length times s
and B times k runs the same strain program through the same states, its forces times k / s^2.  A patch adds
the series/parallel coupling (knitsim.patch.coupling): the cells of a column carry one force per wale and
their elongations add up to the grip displacement u = strain x column rest length; the columns share the
grip strain and their forces add.  Scaling every cell alike scales every rest length and every elongation
by s (so the grip strain is unchanged) and every force by k / s^2: the equations of the coupling are
homogeneous, and the scaled patch's solution is the unscaled one's, forces times k / s^2.  A patch of
identical cells is its cell (tests/patch/test_specimen.py: every cell in series at one force, at the grip
strain).

Tolerances: a column is converged when its cells' forces agree within force_tol + force_rtol |F| (1e-10 N +
1e-8 |F|, knitsim.patch.coupling.PatchSolver) and its lengths add up to u within column_length_tolerance
(relative to C0); two runs, each within its own tolerance of the exact column force, differ by at most
2 force_rtol |F| + force_tol (1 + s^2 / k) after the scaled one is divided by k / s^2.  A cell's strain moves
by a force error over its slope dF/d(strain), at least SLOPE_MIN on this program (the cells' least, on their
sliding plateaus: 0.146 N per unit strain, measured on the unscaled cells).  The cells themselves agree to
1e-9 (tests/cell/test_invariances.py).  Measured on the patch below: forces 5e-13 and strains 2e-13 (s = 0.2
or 3, k = 1); at the domain's corner of the force scale (B = 0.001 N mm^2, d = 2 mm: B / d^2 = 2.5e-4 N)
forces 3.4e-8 and strains 1.2e-6, the fingerprint of force_tol in newtons (3.7e-7 N in unscaled units there;
at k = 0.01 at fixed geometry, B / d^2 = 9.2e-3 N, strains 1.9e-8), still within the coupling's tolerance.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.patch.coupling import COL_OK
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Dusserre 2015 Table 1 / section 2.2 (E-glass), m 0.3 and the calibrated specimen's in-plane width 0.79 mm
# (jamming near strain 0.47), as tests/cell/test_invariances.py
BASE = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.3, in_plane_width=0.79)
#: loading into the jam, unloading from it, a reload, an unloading to slack (grip strain ~0.08) and a reload
PROGRAM = piecewise_linear([0.0, 0.55, 0.1, 0.55, 0.0, 0.3], 0.025)
#: phi0 of each cell [course][wale]: unlike cells in each column, so that the coupling has work to do
PHI0 = [[0.0, 0.2], [-0.15, 0.1]]
#: the coupling's tolerances (knitsim.patch.coupling.PatchSolver defaults)
FORCE_TOL, FORCE_RTOL = 1e-10, 1e-8
#: the cells' least slope dF/d(strain) where they carry force on PROGRAM [N per wale per unit strain], rounded down
SLOPE_MIN = 0.1


def scaled(s: float, k: float, **kw) -> CellParams:
    """BASE with ``kw``, every length times s and B times k."""
    p = {**BASE, **kw}
    for n in ("d", "L", "W0", "C0", "in_plane_width"):
        p[n] = p[n] * s
    p["B"] = p["B"] * k
    return CellParams(**p)


def patch(s: float, k: float) -> PatchModel:
    return PatchModel.from_cells([[scaled(s, k, phi0=phi) for phi in row] for row in PHI0])


@pytest.fixture(scope="module")
def unscaled():
    h = run_patch(patch(1.0, 1.0), PROGRAM, dedup=False)
    assert np.all(h.column_status == COL_OK)
    assert h.force_per_wale_N.min() == 0.0 and h.force_per_wale_N.max() > 1.0, "slack and jammed on the way"
    return h


@pytest.mark.parametrize("s,k", [(0.2, 1.0), (3.0, 1.0), (0.6, 0.36), (1.0, 7.3), (2.0 / 0.58, 0.001 / 0.31),
                                 (0.1 / 0.58, 10.0 / 0.31)])
def test_heterogeneous_patch_is_similar_under_length_and_stiffness_scaling(unscaled, s, k):
    """Grip force per wale and column forces x k / s^2, cell strains unchanged, every column converged; the
    last two cases are the domain's corners of the force scale (knitsim.cell.domain: d = 2 mm with B = 0.001
    N mm^2, B / d^2 = 2.5e-4 N; d = 0.1 mm with B = 10 N mm^2, B / d^2 = 1000 N)."""
    h = run_patch(patch(s, k), PROGRAM, dedup=False)
    assert np.all(h.column_status == COL_OK)
    c = k / s ** 2
    for got, ref in ((h.force_per_wale_N, unscaled.force_per_wale_N), (h.column_force_N, unscaled.column_force_N)):
        bound = 2 * FORCE_RTOL * np.abs(ref) + FORCE_TOL * (1 + 1 / c)
        assert np.all(np.abs(got / c - ref) <= bound), np.max(np.abs(got / c - ref) / bound)
    # the strains, to the force bound over the least slope (and the cells' own 1e-9)
    peak = np.abs(unscaled.force_per_wale_N).max()
    strain_bound = 1e-9 + (2 * FORCE_RTOL * peak + FORCE_TOL * (1 + 1 / c)) / SLOPE_MIN
    np.testing.assert_allclose(h.cell_field("strain"), unscaled.cell_field("strain"), rtol=0, atol=strain_bound)


def test_patch_of_identical_cells_is_its_scaled_cell():
    """A 3 x 2 patch of one cell scaled by s = 0.25, k = 1 (forces x 16), its columns solved cell by cell
    (no dedup), against the unscaled cell alone (batch): identity of a uniform patch and similarity at once."""
    cell = run_batch([scaled(1.0, 1.0)], PROGRAM, device="cpu").force_per_wale[:, 0]
    h = run_patch(PatchModel.uniform(scaled(0.25, 1.0), 3, 2), PROGRAM, dedup=False)
    assert np.all(h.column_status == COL_OK)
    c = 16.0
    bound = 2 * FORCE_RTOL * np.abs(cell) + FORCE_TOL * (1 + 1 / c)
    assert np.all(np.abs(h.force_per_wale_N / c - cell) <= bound)
    assert np.all(np.abs(h.column_force_N / c - cell[:, None]) <= bound[:, None])


@pytest.mark.xfail(strict=True, reason=(
    "the patch coupling's force tolerances are in newtons (knitsim.patch.coupling.PatchSolver force_tol = 1e-10 N "
    "beside force_rtol = 1e-8; a column is slack where its forces are below force_tol): at B / d^2 = 9.2e-7 N that "
    "is 1e-4 of the force scale, and the grip force near the slack (grip strain 0.1 on the way down) is 7.7 % of "
    "1e-3 x the peak off the unscaled patch (1.9 % at B / d^2 = 2.8e-6 N, 3.5e-6 at 9.2e-6 N, 3.4e-8 at the "
    "domain's corner 2.5e-4 N). Scaling force_tol alone (1e-16 N) does not restore it: the columns then fail to "
    "converge (2e6 off at that row), as the cells' tangents dF/dC are clipped to [1e-6, 1e6] N/mm (K_MIN, K_MAX: "
    "kernels/branch_points.py TANGENT_MIN, TANGENT_MAX) and this patch's are ~1e-7; with both scaled by k (NumPy "
    "coupling, monkeypatched) the scaled patch is the unscaled one to 2e-13. The force search's start (1e-6 N) and "
    "ceiling (COLUMN_FORCE_MAX 1e12 N) are in newtons too. A fix states these in the cells' units (B / d^2, "
    "B / d^2 / C0) through the device coupling's kernels: not small, not done here"))
def test_patch_forces_scale_by_k_alone_at_a_tiny_force_scale(unscaled):
    """Stiffness scaling B -> k B at fixed geometry, k = 1e-6 (B = 3.1e-7 N mm^2: below the domain's box, where
    the equations hold as well): forces x k at the coupling's relative tolerance, judged as the cells are
    (against max(|F|, 1e-3 x the peak), bound 1e-6: 100 x the 2 force_rtol a scale-free coupling meets)."""
    k = 1e-6
    h = run_patch(patch(1.0, k), PROGRAM, dedup=False)
    ref = unscaled.force_per_wale_N
    dev = np.abs(h.force_per_wale_N / k - ref) / np.maximum(np.abs(ref), 1e-3 * np.abs(ref).max())
    assert dev.max() <= 1e-6, (dev.max(), int(dev.argmax()))
