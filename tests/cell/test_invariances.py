"""Exact invariances of the quarter-stitch cell, from dimensional analysis (an independent method).

Derivation (docs/model.md, eqs 6-9, Table 4; Dusserre 2015 section 3).  Take a cell (B, d, L, W0, C0,
in-plane width w) and the cell (k B, s d, s L, s W0, s C0, s w), every length scaled by s and the bending
stiffness by k.  If (alpha, beta, gamma, phi, P) solves the first at course length C, then
(alpha, beta, gamma, phi, (k / s^2) P) solves the second at s C:

- elastica, eqs 8-9: B theta'' = P sin(theta - gamma) on AB and B theta'' = P k1' sin(theta) on BC.  With
  the arc length s u and P' = (k / s^2) P, (k B) d^2 theta / d(s u)^2 = (k / s^2) B theta''(u) =
  P' sin(...): the same angles theta(u) at the scaled arc length.  So every length of the shape (s_AB, s_BC,
  X_B, Y_B, Y_C, the head's bulge) scales by s and the angles (alpha, beta, gamma) are unchanged;
- geometry, eq 6: W / 4 = X_B - (d / 2) sin(beta), C / 2 = Y_B + (d / 2) cos(beta), X_B - X_A =
  (d / 2) sin(beta), L / 4 = s_AB + s_BC: each is linear and homogeneous in the lengths, so it holds at
  (s W, s C, s d, s L) with the same angles;
- equilibrium, eq 7: R_Y = -R cos(beta + phi) = P sin(gamma), k1' = cos(gamma) + sin(gamma) tan(beta + phi),
  T = -P k1': homogeneous of degree 1 in the forces (P, R, Rn, Rt, T, F = 2 P sin(gamma)) at fixed angles,
  so every force scales by k / s^2 and k1' is unchanged; the moment M = P x length by k / s;
- Coulomb friction: phi = +/-phimax with m = tan(phimax) = Rt / Rn, a ratio of forces: m is unchanged
  (friction needs no rescaling);
- Table 4's conditions and events: the imposed strain C / C0 - 1 is dimensionless (the same program);
  the frozen values (s_BC, a length; Rn or T, forces; beta, an angle) are taken from the scaled state and
  scale with it; the events phi = +/-phimax (an angle), W = 4 w and head gap = w (lengths: both sides
  scale by s), F = 0 and the contact's opening Rn = 0 (forces, zero either way) and F = force cap (a force:
  the default cap 50 B / d^2 scales by k / s^2 by itself, an explicit one must be scaled so) happen at the
  same strain;
- Dahl friction: tan(phi_new) = s m + (tan(phi_old) - s m) exp(-sigma |d xi| / m), with the slip xi = -s_BC a
  length: sigma [1/mm] must scale by 1 / s for sigma |d xi| to be unchanged.

Hence the strain-force curve of any program keeps its strains, stages and events, and its forces scale by
k / s^2: by 1 / s^2 at fixed B (geometric similarity), unchanged with B scaled by s^2 too, by k at fixed
geometry (stiffness scaling).  The energies: per unit strain as the forces (k / s^2), in N mm
(times C0) by k / s.

Tolerances.  A scaled run is the same sequence of dimensionless solves: both engines scale their residuals
by the cell's own units (lengths by d, forces by B / d^2: knitsim.cell.inverse._scale,
kernels/inverse.py quantity_scale), their Newton steps and sub-steps by C0, their Dahl slip brackets by d.
The results may differ only by where rounding stops each Newton: the reference stops at a scaled residual of
1e-12 (knitsim.cell.inverse.solve_state, finite-difference Jacobian), the kernel at 1e-11 (NEWTON_TOL; 1e-9
where its line search stalls at the rounding floor, NEWTON_TOL_STALLED), amplified by the branch's
conditioning near the slack point.  Measured: at most 1e-9 (reference), 6e-13 (batch) of the force, with the
force judged against max(|F|, 1e-3 x its peak) as tests/cell/test_batch.py does.  The asserted bounds, 1e-7
(reference) and 1e-9 (batch), leave room for the conditioning and still catch any tolerance stated in
absolute units (an event tolerance of 1e-9 N on a force scale of 1e-7 N: a 100 % error where it fires).
"""
from __future__ import annotations


import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import dissipated_energy, run_cell
from knitsim.cell.load_program import piecewise_linear
from knitsim.cell.material import CellParams

# Dusserre 2015 Table 1 (E-glass: d, B), section 2.2 (L, W0, C0), m 0.3 (within the domain's 0.05-0.5) and the
# calibrated specimen's in-plane width 0.79 mm (README, "The paper's experiment, explained"), so that the
# cell jams (W = 4 w) near strain 0.47 and the program below crosses every stage: adherence, sliding,
# jamming, the reversal from the jam (slide and unjam at once), a second jam, an unloading to slack at
# strain ~0.084 and a reload from slack
BASE = dict(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.3, phi0=0.0, in_plane_width=0.79)
PROGRAM = [0.0, 0.55, 0.1, 0.55, 0.0, 0.3]
#: the reference engine's shorter program (~2 s a run): jam, the reversal from it, slack, reload from slack
REF_PROGRAM = [0.0, 0.55, 0.0, 0.2]

#: the rules where Table 4 is silent, each with its own events (knitsim.cell.stages), and the events each
#: crosses on PROGRAM: Table 4's unloading goes slack (F = 0 at strain ~0.084) and reloads from slack; Hong's
#: constant T, the head-gap criterion and Dahl friction come back to strain 0 still loaded.  (The reload rule
#: ``freeze_rn`` differs from the default only on a reload at zero contact force, R ~ 0, which this cell
#: does not reach: it goes slack at beta + phi = pi/2 with R > 0, and both rules then freeze Rn.)
RULES = {
    "dusserre": {},
    "hong_constant_t": dict(unloading_rule="hong_constant_t"),
    "head_gap": dict(jamming_criterion="head_gap"),
    "dahl": dict(friction="dahl", dahl_sigma=30.0),
}
CROSSES = {"dusserre": {"jam", "unjam", "slack", "reload"}, "hong_constant_t": {"jam", "unjam"},
           "head_gap": {"jam", "unjam"}, "dahl": {"jam", "unjam"}}

#: (s, k): every length times s, B times k.  Inside the domain's box (knitsim.cell.domain: d 0.1-2 mm,
#: B 0.001-10 N mm^2) but one far outside it, where the equations hold as well
SCALES = [(0.25, 1.0), (3.0, 1.0), (0.3, 0.09), (1.0, 7.3), (1.0, 0.01), (2.0, 0.01), (1e-3, 1e-6)]

#: bounds of the relative deviation (module docstring, "Tolerances")
RTOL_BATCH = 1e-9
RTOL_REFERENCE = 1e-7
LENGTHS = ("W", "C", "s_BC", "head_gap")
FORCES = ("F", "P", "T", "Rn")
ANGLES = ("alpha", "beta", "gamma", "phi")


def scaled(s: float, k: float, **kw) -> CellParams:
    """The cell of ``kw`` over BASE with every length times s and B times k; a Dahl sigma [1/mm] times 1 / s;
    an explicit force cap times k / s^2 (a default one, 50 B / d^2, follows by itself)."""
    p = {**BASE, **kw}
    for n in ("d", "L", "W0", "C0", "in_plane_width"):
        p[n] = p[n] * s
    p["B"] = p["B"] * k
    if p.get("dahl_sigma"):
        p["dahl_sigma"] = p["dahl_sigma"] / s
    if p.get("force_cap_N") is not None:
        p["force_cap_N"] = p["force_cap_N"] * k / s ** 2
    return CellParams(**p)


def _rel(a, b):
    """|a - b| / max(|b|, 1e-3 max|b|) (a force near zero judged against its curve's peak)."""
    b = np.asarray(b, float)
    return np.abs(np.asarray(a, float) - b) / np.maximum(np.abs(b), 1e-3 * np.max(np.abs(b)))


def assert_similar(h, j: int, r, i: int, s: float, k: float, rtol: float) -> float:
    """Cell j of history h is cell i of r scaled by (s, k): same statuses, stages, events, angles; lengths
    times s, forces times k / s^2.  Returns the largest relative deviation of a force."""
    assert np.array_equal(h.status[:, j], r.status[:, i])
    assert np.all(r.status[:, i] == 0), "the unscaled cell runs the whole program"
    assert np.array_equal(h.stage[:, j], r.stage[:, i])
    assert np.array_equal(h.jammed[:, j], r.jammed[:, i])
    cf = k / s ** 2
    worst = 0.0
    for n in FORCES:
        dev = _rel(h.values[n][:, j] / cf, r.values[n][:, i])
        assert dev.max() <= rtol, (n, dev.max(), int(dev.argmax()))
        worst = max(worst, float(dev.max()))
    for n in LENGTHS:
        dev = _rel(h.values[n][:, j] / s, r.values[n][:, i])
        assert dev.max() <= rtol, (n, dev.max(), int(dev.argmax()))
    for n in ANGLES:
        np.testing.assert_allclose(h.values[n][:, j], r.values[n][:, i], rtol=0, atol=rtol, err_msg=n)
    ev_h = [(e["increment"], e["kind"]) for e in h.events if e["cell"] == j]
    ev_r = [(e["increment"], e["kind"]) for e in r.events if e["cell"] == i]
    assert ev_h == ev_r
    for eh, er in zip((e for e in h.events if e["cell"] == j), (e for e in r.events if e["cell"] == i)):
        if "C" in er:
            assert eh["C"] / s == pytest.approx(er["C"], rel=rtol)
    # the loop work per unit strain scales as the forces
    w_h = dissipated_energy(h.strain, h.values["F"][:, j]) / cf
    w_r = dissipated_energy(r.strain, r.values["F"][:, i])
    assert w_h == pytest.approx(w_r, rel=rtol, abs=rtol * np.abs(r.values["F"][:, i]).max())
    return worst


@pytest.fixture(scope="module")
def batch():
    """Every rule at scale 1 and at every (s, k), one batched run on the CPU (~1 s)."""
    cells = [scaled(s, k, **kw) for kw in RULES.values() for s, k in [(1.0, 1.0)] + SCALES]
    return run_batch(cells, piecewise_linear(PROGRAM, 0.025), device="cpu")


@pytest.mark.parametrize("rule", list(RULES))
@pytest.mark.parametrize("s,k", SCALES)
def test_batch_cycle_is_similar_under_length_and_stiffness_scaling(batch, rule, s, k):
    """Geometric similarity (k = 1: forces / s^2; k = s^2: forces unchanged) and stiffness scaling
    (s = 1: forces x k) of a full cycle with jamming, unjamming, slack and a reload from slack, each rule where
    Table 4 is silent and Dahl friction (sigma / s), in the batched Warp engine."""
    n = 1 + len(SCALES)
    i = list(RULES).index(rule) * n
    j = i + 1 + SCALES.index((s, k))
    kinds = {e["kind"] for e in batch.events if e["cell"] == i}
    # the program crosses what it is meant to (the jam is W = 4 w, or the head gap = w)
    assert CROSSES[rule] <= kinds, kinds
    assert_similar(batch, j, batch, i, s, k, RTOL_BATCH)


def test_batch_dahl_sigma_is_a_stiffness_per_length(batch):
    """The control of the Dahl case: sigma [1/mm] left unscaled while the lengths scale by 3, the slip of each
    increment is 3 times longer in units of 1 / sigma (sigma |d xi| / m tripled), the law no longer the same
    function of the strain, and the forces leave the similarity by far more than the bound (measured 12 %)."""
    n = 1 + len(SCALES)
    i = list(RULES).index("dahl") * n
    h = run_batch([scaled(3.0, 1.0, friction="dahl", dahl_sigma=30.0 * 3.0)], piecewise_linear(PROGRAM, 0.025),
                  device="cpu")
    assert np.all(h.status == 0)
    dev = _rel(h.values["F"][:, 0] * 9.0, batch.values["F"][:, i])
    assert dev.max() > 1e-2, dev.max()


def test_batch_explicit_force_cap_scaled_as_the_forces_stops_at_the_same_strain():
    """An explicit cap is a force: scaled by k / s^2 the cell stops at the same increment, at its cap.  The
    default cap (50 B / d^2) scales so by itself (its own test: tests/cell/test_default_force_cap.py)."""
    prog = piecewise_linear([0.0, 0.7], 0.025)
    cells = [scaled(1.0, 1.0, force_cap_N=2.0), scaled(0.25, 1.0, force_cap_N=2.0), scaled(3.0, 0.01, force_cap_N=2.0),
             scaled(1.0, 1.0), scaled(0.25, 1.0), scaled(3.0, 0.01)]
    h = run_batch(cells, prog, device="cpu")
    assert h.status[-1, 0] == h.status[-1, 3] == 2 and any(e["kind"] == "force_cap" for e in h.events if e["cell"] == 0)
    for i, j, (s, k) in ((0, 1, (0.25, 1.0)), (0, 2, (3.0, 0.01)), (3, 4, (0.25, 1.0)), (3, 5, (3.0, 0.01))):
        assert h.params[j].cap_N == pytest.approx(h.params[i].cap_N * k / s ** 2, rel=1e-14)
        stop_i = int(np.argmax(h.status[:, i] != 0))
        stop_j = int(np.argmax(h.status[:, j] != 0))
        assert stop_i == stop_j
        np.testing.assert_allclose(h.force_per_wale[:, j] * s ** 2 / k, h.force_per_wale[:, i], rtol=RTOL_BATCH)


@pytest.mark.parametrize("rule", ["dusserre", pytest.param("hong_constant_t", marks=pytest.mark.slow),
                                  pytest.param("dahl", marks=pytest.mark.slow)])
def test_reference_cycle_is_similar_under_length_and_stiffness_scaling(rule):
    """The NumPy reference (an independent engine: root search on C for the events, finite-difference Newton,
    nested slip search for Dahl) through the same cycle, the cell scaled by s = 3 and k = 0.01 at once
    (forces x 1/900), at increments of 0.05 (the events are located, not read off the rows)."""
    prog = piecewise_linear(REF_PROGRAM, 0.05)
    kw = RULES[rule]
    r = run_cell(scaled(1.0, 1.0, **kw), prog)
    h = run_cell(scaled(3.0, 0.01, **kw), prog)
    for x in (r, h):
        for e in x.events:
            e.setdefault("cell", 0)
    kinds = {e["kind"] for e in r.events}
    assert CROSSES[rule] <= kinds, kinds
    assert_similar(h, 0, r, 0, 3.0, 0.01, RTOL_REFERENCE)


def test_reference_and_batch_forces_scale_by_k_alone_at_a_tiny_force_scale():
    """Stiffness scaling B -> k B at fixed geometry far below the domain's box (k = 1e-7: B = 3.1e-8 N mm^2,
    B / d^2 = 9.2e-8 N): the equations hold at any k, so forces x k, the same stages and events.  A tolerance
    stated in newtons shows here: the event functions of the slack and the force cap were judged 'zero at the
    start of a sub-step' below EVENT_TOL = 1e-9 N, so the cell went slack one increment early, where its force
    was 5.7e-10 N (0.0057 N unscaled): 100 % off the unscaled curve at the reload (both engines).  Now in
    B / d^2 (knitsim.cell.stages.EVENT_TOL)."""
    prog = piecewise_linear(REF_PROGRAM, 0.05)
    k = 1e-7
    h = run_batch([scaled(1.0, 1.0), scaled(1.0, k)], prog, device="cpu")
    assert_similar(h, 1, h, 0, 1.0, k, RTOL_BATCH)
    r = run_cell(scaled(1.0, 1.0), prog)
    rk = run_cell(scaled(1.0, k), prog)
    for x in (r, rk):
        for e in x.events:
            e.setdefault("cell", 0)
    assert_similar(rk, 0, r, 0, 1.0, k, RTOL_REFERENCE)


def test_frictionless_batch_retraces_its_loading_curve():
    """m = 0 (Coulomb): the friction cone is a line, nothing switches and nothing dissipates, so unloading and
    reloading retrace the first loading (no hysteresis) and a closed loop does no work.  The reference's test:
    tests/cell/test_cycle.py::test_frictionless_retraces_loading_curve; here the batched engine, jammed at the
    top (the jam is a unilateral constraint, not friction: it is left on the way down where it was met on the
    way up) and scaled (s = 0.3, k = 0.09: forces unchanged).  Bound: the batch's 1e-9 (module docstring)."""
    prog = piecewise_linear([0.0, 0.55, 0.1, 0.55], 0.025)
    cells = [scaled(1.0, 1.0, m=0.0), scaled(0.3, 0.09, m=0.0)]
    h = run_batch(cells, prog, device="cpu")
    assert np.all(h.status == 0)
    assert {"jam", "unjam"} <= {e["kind"] for e in h.events if e["cell"] == 0}
    assert not {"slide", "slack", "cone"} & {e["kind"] for e in h.events}
    s, F = h.strain, h.force_per_wale[:, 0]
    up = {round(x, 9): f for x, f, d, c in zip(s, F, h.direction, h.cycle) if d > 0 and c == 1}
    back = [(round(x, 9), f) for x, f, d, c in zip(s, F, h.direction, h.cycle) if d < 0 or c > 1]
    assert len(back) > 30
    worst = max(abs(f - up[x]) / max(abs(up[x]), 1e-3 * max(up.values())) for x, f in back)
    assert worst <= RTOL_BATCH
    top = int(np.argmax(s >= 0.55 - 1e-12))
    assert abs(dissipated_energy(s[top:], F[top:])) <= RTOL_BATCH * np.max(F) * 2 * 0.45    # |F err| x path length
    np.testing.assert_allclose(h.force_per_wale[:, 1], F, rtol=RTOL_BATCH)


def test_knitsim_cell_scene_summary_is_similar():
    """``knitsim cell``'s path (scene -> engine -> summary) on a scene and on its scaled copy (s = 2, B x 0.01,
    inside the domain): the same stages, per cycle the same strains (peak, residual, first jam) and warnings,
    forces and energies per unit strain x k / s^2, energies in N mm x k / s (the work is F dC, C = C0 (1 +
    strain))."""
    from knitsim.cell.engine import simulate
    from knitsim.io.results import first_loading, summarise
    from knitsim.scene.cell_scene import load_cell_scene

    def scene(s, k):
        return {"engine": "warp", "device": "cpu",
                "yarn": {"d": 0.58 * s, "B": 0.31 * k, "in_plane_width": 0.79 * s},
                "knit": {"L": 14.1 * s, "W0": 4.4 * s, "C0": 2.7 * s},
                "friction": {"m": 0.3, "phi0": 0.0},
                "load": {"type": "piecewise", "waypoints": [0.55, 0.1, 0.55, 0.0, 0.6], "max_increment": 0.05}}

    out = {}
    for s, k in ((1.0, 1.0), (2.0, 0.01)):
        sc = load_cell_scene(scene(s, k))
        h = simulate(sc.params, sc.program, engine=sc.engine, device="cpu")
        pull = first_loading(sc.params, sc.program, engine=sc.engine)
        out[s, k] = summarise(h, sc.labels, reference=pull)["cells"][0]
    a, b = out[1.0, 1.0], out[2.0, 0.01]
    s, k = 2.0, 0.01
    assert a["final_status"] == b["final_status"] == "ok"
    assert [w["code"] for w in a["warnings"]] == [w["code"] for w in b["warnings"]]
    assert a["warnings"], "the scene is meant to raise the summary's checks (reloads, heads)"
    assert b["strain_at_first_jamming"] == pytest.approx(a["strain_at_first_jamming"], rel=RTOL_BATCH)
    assert b["params"]["force_cap_N"] == pytest.approx(a["params"]["force_cap_N"] * k / s ** 2, rel=1e-14)
    assert len(a["cycles"]) == len(b["cycles"]) == 3
    for ca, cb in zip(a["cycles"], b["cycles"]):
        assert cb["energy_kind"] == ca["energy_kind"] and cb["closed"] == ca["closed"]
        assert cb["strain_at_peak"] == pytest.approx(ca["strain_at_peak"], rel=1e-12)
        for key in ("residual_strain",):
            assert (cb[key] is None) == (ca[key] is None)
            if ca[key] is not None:
                assert cb[key] == pytest.approx(ca[key], rel=RTOL_BATCH)
        assert cb["peak_force_per_wale_N"] == pytest.approx(ca["peak_force_per_wale_N"] * k / s ** 2, rel=RTOL_BATCH)
        unit = RTOL_BATCH * ca["peak_force_per_wale_N"]
        assert cb["energy_N_per_strain"] == pytest.approx(ca["energy_N_per_strain"] * k / s ** 2, rel=RTOL_BATCH,
                                                          abs=unit * k / s ** 2)
        assert cb["energy_N_mm"] == pytest.approx(ca["energy_N_mm"] * k / s, rel=RTOL_BATCH, abs=unit * 2.7 * k / s)
