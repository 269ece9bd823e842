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

Tolerances: a column is converged when its cells' forces agree within force_tol sigma_F + force_rtol |F|
(1e-10 N + 1e-8 |F|, knitsim.patch.coupling.PatchSolver; sigma_F the patch's power-of-two force scale factor,
knitsim.patch.coupling.CouplingScale: 1 for the unscaled patch) and its lengths add up to u within
column_length_tolerance (relative to C0); two runs, each within its own tolerance of the exact column force,
differ by at most 2 force_rtol |F| + force_tol (1 + sigma_F s^2 / k) after the scaled one is divided by k / s^2.
A cell's strain moves by a force error over its slope dF/d(strain), at least SLOPE_MIN on this program (the
cells' least, on their sliding plateaus: 0.146 N per unit strain, measured on the unscaled cells).  The cells
themselves agree to 1e-9 (tests/cell/test_invariances.py).  Measured on the patch below: forces 5e-13 and
strains 2e-13 (s = 0.2 or 3, k = 1); at the domain's corner of the force scale (B = 0.001 N mm^2, d = 2 mm:
B / d^2 = 2.5e-4 N, sigma_F = 2^-6) forces 5.8e-10 of the force (6e-11 N in unscaled units) and strains 1.9e-8.
With force_tol in newtons (before CouplingScale) that corner was 3.4e-8 and 1.2e-6, the fingerprint of a
force_tol of 4e-7 of its force scale; it is now at most ~9e-9 of any patch's (the scale's neutral band ends at
B / d^2 = 0.011 N), and 1.1e-10 of the unscaled patch's.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from knitsim import materials
from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.material_library import load_library
from knitsim.patch.coupling import (COL_OK, FORCE_SCALE_BAND, FORCE_SCALE_REF, LENGTH_SCALE_BAND, LENGTH_SCALE_REF,
                                    CouplingScale, PatchSolver, power_of_two_scale)
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch
from knitsim.scene.patch_scene import load_patch_scene

REPO = Path(__file__).resolve().parents[2]

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
    pm = patch(s, k)
    h = run_patch(pm, PROGRAM, dedup=False)
    assert np.all(h.column_status == COL_OK)
    c = k / s ** 2
    # the scaled patch's force_tol is FORCE_TOL sigma_F (the unscaled one's sigma_F is 1)
    atol = FORCE_TOL * (1 + CouplingScale.of(pm.grouping(False)).force / c)
    for got, ref in ((h.force_per_wale_N, unscaled.force_per_wale_N), (h.column_force_N, unscaled.column_force_N)):
        bound = 2 * FORCE_RTOL * np.abs(ref) + atol
        assert np.all(np.abs(got / c - ref) <= bound), np.max(np.abs(got / c - ref) / bound)
    # the strains, to the force bound over the least slope (and the cells' own 1e-9)
    peak = np.abs(unscaled.force_per_wale_N).max()
    strain_bound = 1e-9 + (2 * FORCE_RTOL * peak + atol) / SLOPE_MIN
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


def _forces_over_k(unscaled, k: float, monkeypatch=None, on_device: bool = True):
    """The patch with B times k at fixed geometry (the coupling on the device, or its NumPy twin): its history and
    each row's |F / k - F_unscaled| against max(|F_unscaled|, 1e-3 x the peak), as the cells are judged."""
    if monkeypatch is not None:
        monkeypatch.setattr(PatchSolver, "device_branch_points", on_device)
    h = run_patch(patch(1.0, k), PROGRAM, dedup=False)
    ref = unscaled.force_per_wale_N
    return h, np.abs(h.force_per_wale_N / k - ref) / np.maximum(np.abs(ref), 1e-3 * np.abs(ref).max())


@pytest.mark.parametrize("on_device", [True, False], ids=["device_coupling", "numpy_coupling"])
def test_patch_forces_scale_by_k_alone_at_a_tiny_force_scale(unscaled, monkeypatch, on_device):
    """Stiffness scaling B -> k B at fixed geometry, k = 1e-6 (B = 3.1e-7 N mm^2, B / d^2 = 9.2e-7 N: below the
    domain's box, where the equations hold as well): forces x k at the coupling's relative tolerance, judged as the
    cells are (against max(|F|, 1e-3 x the peak), bound 1e-6: 100 x the 2 force_rtol a scale-free coupling meets),
    every column converged, in the unscaled patch's trials (within 5 %); with the coupling on the device and in
    NumPy.

    Where the numbers come from: with the coupling's absolute tolerances and bounds in newtons (force_tol 1e-10
    N, 1e-4 of this patch's force scale; the tangent clips 1e-6 .. 1e6 N/mm against its cells' ~1e-7; the force
    search's start 1e-6 N) the grip force near the slack (grip strain 0.1 on the way down) was 7.7e-2 off, in 671
    trials against 247 (1.9e-2 at B / d^2 = 2.8e-6 N, 3.5e-6 at 9.2e-6 N, 3.4e-8 at the domain's corner 2.5e-4
    N); force_tol alone scaled (1e-16 N) left columns unconverged (2e6 off at that row), the tangents being
    clipped.  In the patch's scales (knitsim.patch.coupling.CouplingScale: sigma_F = 2^-14, sigma_L = 1):
    5.8e-10, strains 1.9e-8, in 245 trials.  Not to 1e-13 as the uniform scalings above: sigma_F is a power of
    two beyond the neutral band's low end (0.011 N), so force_tol sigma_F is 6.6e-9 of this patch's B / d^2
    against 1.1e-10 of the unscaled one's, and one column converges a trial earlier, within the tolerance."""
    h, dev = _forces_over_k(unscaled, 1e-6, monkeypatch, on_device)
    assert np.all(h.column_status == COL_OK)
    assert dev.max() <= 1e-6, (dev.max(), int(dev.argmax()))
    assert h.column_iterations.sum() <= 1.05 * unscaled.column_iterations.sum()


@pytest.mark.parametrize("k", [1e4, 1e8])
def test_patch_forces_scale_by_k_alone_at_a_large_force_scale(unscaled, k):
    """B -> k B at fixed geometry, k = 1e4 and 1e8 (B / d^2 = 9.2e3 and 9.2e7 N): forces x k (bound as the
    tiny scale's) in the unscaled patch's trials (within 5 %).

    Measured: k = 1e4, 2.1e-13 in 247 trials both with force_tol in newtons and in the patch's scale (sigma_F
    = 2^11: the force search and the tangents are far from their bounds there, and 1e-10 N is still 1e-14 of the
    forces); k = 1e8, with force_tol in newtons 1e-18 of the force scale, below the forces' rounding: 1.6e-9 in
    520 trials against 247; in the patch's scale (sigma_F = 2^24) 8.8e-14 in 247."""
    h, dev = _forces_over_k(unscaled, k)
    assert np.all(h.column_status == COL_OK)
    assert dev.max() <= 1e-6, (dev.max(), int(dev.argmax()))
    assert h.column_iterations.sum() <= 1.05 * unscaled.column_iterations.sum()


def test_the_scale_factors_are_powers_of_two_beyond_a_neutral_band():
    """power_of_two_scale: 1 within 2^(band + 1/2) of the reference, beyond it the power of two nearest to the
    value over the band's nearer end, so that a value beyond the band times 2^n, further beyond it, scales by
    exactly 2^n (a tolerance times it is exact in floating point)."""
    ref, band = FORCE_SCALE_REF, FORCE_SCALE_BAND
    for x in (ref, ref * 2.0 ** (band + 0.49), ref * 2.0 ** -(band + 0.49)):
        assert power_of_two_scale(x, ref, band) == 1.0
    assert power_of_two_scale(ref * 2.0 ** (band + 0.51), ref, band) == 2.0
    assert power_of_two_scale(ref * 2.0 ** -(band + 0.51), ref, band) == 0.5
    for x, side in ((9.2e-7, -1), (3.3e-3, -1), (4e2, 1)):
        s = power_of_two_scale(x, ref, band)
        assert np.log2(s) == np.round(np.log2(s)) and np.sign(np.log2(s)) == side
        for n in (1, 7, 30):
            assert power_of_two_scale(x * 2.0 ** (side * n), ref, band) == s * 2.0 ** (side * n)
    assert power_of_two_scale(float("nan"), ref, band) == power_of_two_scale(0.0, ref, band) == 1.0


def test_a_patch_has_one_scale_grouped_or_cell_by_cell():
    """The medians are over the stitches (a group weighted by those it stands for), so dedup does not change the
    scale: a 4 x 2 patch whose first column is of one yarn of tiny force scale (k = 1e-6) and whose second holds
    it once beside three unscaled cells has 5 of its 8 cells tiny (sigma_F = 2^-14), though 3 of its 5 groups
    are not."""
    tiny, cells = scaled(1.0, 1e-6), [scaled(1.0, 1.0, phi0=phi) for phi in (0.0, 0.1, 0.2)]
    pm = PatchModel.from_cells([[tiny, tiny]] + [[tiny, c] for c in cells])
    g = pm.grouping(True)
    assert g.n_groups == 5 and np.count_nonzero(g.cells["B"] < 1e-3) == 2      # a median of groups: unscaled
    grouped, single = CouplingScale.of(g), CouplingScale.of(pm.grouping(False))
    assert grouped == single
    assert single.force == 2.0 ** -14 and single.length == 1.0


def _patch_scenes() -> list[Path]:
    """The bundled scenes that are patches or specimens (a top-level [patch] or [specimen] table)."""
    out = []
    for f in sorted((REPO / "scenes").rglob("*.toml")):
        with open(f, "rb") as fh:
            doc = tomllib.load(fh)
        if "patch" in doc or "specimen" in doc:
            out.append(f)
    return out


def test_the_bundled_scenes_and_materials_keep_the_coupling_s_constants():
    """Every bundled patch and specimen scene (scenes/**.toml), every built-in yarn and knit (Dusserre 2015) and
    every bundled material library's (do2020) has CouplingScale 1 for each of its cells, not only its median:
    their coupling runs on force_tol, the tangent bounds and the force search's bounds as they were stated (times
    1.0, exactly), so their results are bit for bit those before the scales were introduced (the 3 patch scenes
    and the specimen's curve.csv, columns.csv and cells.nc compared byte for byte when they were)."""
    scenes = _patch_scenes()
    assert len(scenes) >= 6 and REPO / "scenes" / "specimen_e_glass_cyclic.toml" in scenes
    for f in scenes:
        sc = load_patch_scene(f)
        g = sc.model.grouping(sc.dedup)
        s = CouplingScale.of(g)
        assert (s.force, s.length) == (1.0, 1.0), (f, s)
        for v in np.asarray(g.cells["B"]) / np.asarray(g.cells["d"]) ** 2:
            assert power_of_two_scale(v, FORCE_SCALE_REF, FORCE_SCALE_BAND) == 1.0, (f, v)
        for v in np.asarray(g.cells["C0"]):
            assert power_of_two_scale(v, LENGTH_SCALE_REF, LENGTH_SCALE_BAND) == 1.0, (f, v)
    yarns = [materials.yarn(n) for n in materials.yarn_names()]
    knits = [materials.knit(n) for n in materials.knit_names()]
    for lib in (load_library(f) for f in sorted((REPO / "scenes").rglob("materials.toml"))):
        yarns += list(lib.yarns.values())
        knits += list(lib.knits.values())
    assert len(yarns) >= 3 and len(knits) >= 4
    for y in yarns:
        assert power_of_two_scale(y.B / y.d ** 2, FORCE_SCALE_REF, FORCE_SCALE_BAND) == 1.0, y
    for k in knits:
        assert power_of_two_scale(k.C0, LENGTH_SCALE_REF, LENGTH_SCALE_BAND) == 1.0, k
