"""Domain cells that ended without converging on the paper's program (issue 14), each with its cause.

The cells are random cells of :data:`knitsim.cell.domain.DOMAIN` from
``benchmarks/bench_convergence.py`` (seed 0) and helper-12's report, on the paper's program
(3 cycles 0.10-0.60, increment 0.01, Dusserre 2015 section 2.3).  The expected numbers are not
replayed output: they are the program's imposed course lengths, identities of the model (two
unloadings from the same state follow the same branch; T frozen by Hong's rule), the equations
themselves by the NumPy forward map, and the float64 NumPy reference engine (another Newton,
another event logic) where it converges.
"""
from __future__ import annotations

import numpy as np

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import CellCycle, dissipated_energy
from knitsim.cell.domain import DOMAIN
from knitsim.cell.history import STATUS_FORCE_CAP, STATUS_OK
from knitsim.cell.inverse import initial_state
from knitsim.cell.load_program import LoadProgram, cycles, piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.cell.quarter_loop import quarter_loop
from knitsim.cell.stages import ZERO_CONTACT, Stage

PROGRAM = cycles(0.10, 0.60, 3, max_increment=0.01)


def _head(prog: LoadProgram, n: int) -> LoadProgram:
    return LoadProgram(prog.strain[:n], prog.cycle[:n], prog.direction[:n], prog.waypoints)


def test_unloading_next_to_the_domain_edge_converges_in_every_cycle():
    """Hong's S- unloading at G(0) ~ 1e-7 (theta' nearly vanishes at the apex C).

    Before: in the Newton's ln G(0) chart, elastica BC re-formed G(0) from R/P by cancellation, so its
    ln G(0) integrals (hence the residual of L) carried a rounding of 1e-9..4e-9 of d, above the
    Newton's stall tolerance; the second unloading halved to the floor at C = 0.65929 mm (the first,
    on the same branch, happened to pass).  Expected: every row at its imposed C; the second and third
    unloadings, which start from the same jammed state at strain 0.6 (the reversal unjams at once and
    slides at the same C), retrace the first (identity of the model: same state, same conditions);
    eq 6 (g = 0) by the NumPy forward map."""
    p = CellParams(B=0.15393564241170105, d=0.13764454727733266, L=2.908776201754969, W0=0.9504880774840897,
                   C0=0.5778278637365293, m=0.3244583373007889, phi0=-0.26215385170437283,
                   unloading_rule="hong_constant_t", reload_rule="freeze_rn", jamming_criterion="head_gap",
                   in_plane_width=0.17100176484685498, force_cap_N=348.19471482942345)
    assert DOMAIN.why_outside(p) is None
    h = run_batch([p], PROGRAM)
    assert np.all(h.status[:, 0] == STATUS_OK)
    np.testing.assert_allclose(h.values["C"][:, 0], p.C0 * (1.0 + PROGRAM.strain), rtol=0, atol=1e-9)
    s = np.asarray(PROGRAM.strain)
    first = np.nonzero((PROGRAM.direction < 0) & (PROGRAM.cycle == 1))[0]
    for c in (2, 3):
        later = np.nonzero((PROGRAM.direction < 0) & (PROGRAM.cycle == c))[0]
        np.testing.assert_allclose(s[later], s[first], atol=1e-12)
        for name in ("F", "T", "P", "W", "phi"):
            np.testing.assert_allclose(h.values[name][later, 0], h.values[name][first, 0], rtol=1e-8, atol=1e-10)
    assert np.all(h.stage[first[5:], 0] == Stage.S_UNLOAD)
    v = {k: h.values[k][:, 0] for k in ("alpha", "beta", "gamma", "phi", "P")}
    ql = quarter_loop(v["alpha"], v["beta"], v["gamma"], v["phi"], v["P"], p.B, p.d)
    assert np.max(np.abs(ql.g)) < 1e-9 * p.d


def test_cap_below_the_rest_force_stops_both_engines_at_rest():
    """The paper's E-glass knit (Dusserre 2015 Table 1, m = 0.20) with its cap set to half its own
    rest force (float64 initial state): both engines stop it at rest, status force_cap, no increment
    solved.  Before, the cap event (a crossing from below) never fired for a cell above it at rest:
    30 of 10^4 random domain cells (bench_convergence, seed 0, cap 20 B / d^2), tight loops near the
    end of their rest branch (L / (2 C0 + W0 - 4 d) 1.60-1.76, F at rest 1.02-1.59 x the cap), loaded
    up the jammed branch to 11-19 x the cap until alpha - gamma underflowed: no_convergence."""
    p = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.20, phi0=0.05)
    F_rest = float(initial_state(p.C0, p.W0, p.L, p.phi0, p.B, p.d).state.F)
    assert F_rest > 0.0
    p = p.replace(force_cap_N=0.5 * F_rest)
    prog = _head(PROGRAM, 10)
    for h in (run_batch([p], prog), CellCycle(p).run(prog)):
        assert np.all(h.status[:, 0] == STATUS_FORCE_CAP)
        np.testing.assert_allclose(h.force_per_wale[:, 0], F_rest, rtol=1e-8)
        flag = [e for e in h.events if e["kind"] == "flag"]
        assert len(flag) == 1 and flag[0]["increment"] == 0 and "at rest" in flag[0]["reason"]


def test_jammed_slide_on_unloading_unjams_where_the_jammed_branch_ends():
    """Head-gap jam at strain 0.59, reversal at 0.6: SF- jammed slides at C = 2.71873 mm, and the
    jammed S- (head gap held at d_jam in place of T) has no solution on unloading beyond (its Newton's
    residual fell only in proportion to the sub-step, down to the floor: no_convergence).  The
    unjammed S- (T frozen at the slide, the value the state holds) passes through that state and
    opens.  Expected: the cell unjams at the slide point; the NumPy reference (another Newton and
    event logic) gives the same events at the same C and the same states; the loops are clear of
    contact afterwards (head gap > d_jam); T stays at its frozen value (S-, Table 4)."""
    p = CellParams(B=6.887198753037332, d=0.3337764461387661, L=9.011687449714525, W0=2.4894223481709585,
                   C0=1.7048726192852632, m=0.3548008263023676, phi0=0.17274488491092263,
                   unloading_rule="hong_constant_t", reload_rule="freeze_rn", jamming_criterion="head_gap",
                   in_plane_width=0.4034073420120208, force_cap_N=1236.4063856296186)
    assert DOMAIN.why_outside(p) is None
    prog = _head(PROGRAM, 63)
    h = run_batch([p], prog)
    r = CellCycle(p).run(prog)
    for x in (h, r):
        assert np.all(x.status[:, 0] == STATUS_OK)
    ev_w = [(e["increment"], e["kind"], e["C"]) for e in h.events if e["kind"] != "flag"]
    ev_r = [(e["increment"], e["kind"], e["C"]) for e in r.events if e["kind"] != "flag"]
    assert [e[:2] for e in ev_w] == [e[:2] for e in ev_r]
    assert [e[:2] for e in ev_w if e[0] == 60] == [(60, "reversal"), (60, "slide"), (60, "unjam")]
    np.testing.assert_allclose([e[2] for e in ev_w], [e[2] for e in ev_r], rtol=0, atol=1e-9)
    slide = [e[2] for e in ev_w if e[1] == "slide" and e[0] == 60][0]
    assert [e[2] for e in ev_w if e[1] == "unjam"] == [slide]
    for name in ("F", "T", "W", "head_gap"):
        np.testing.assert_allclose(h.values[name][:, 0], r.values[name][:, 0], rtol=1e-7, atol=1e-9)
    after = slice(60, 63)
    assert np.all(h.jammed[after, 0] == 0) and np.all(h.stage[after, 0] == Stage.S_UNLOAD)
    assert np.all(h.values["head_gap"][after, 0] > p.d_jam)
    assert np.ptp(h.values["T"][after, 0]) < 1e-9 * abs(h.values["T"][60, 0])


def test_contact_opening_inside_an_unloading_substep_is_located_on_the_branch():
    """Bench cell 932 (seed 0, paper's program): Table 4's SF- (beta, s_BC frozen) after the reversal at
    0.6 heads for Rn -> 0, and phi passes +phimax on the way (the stick leaves the cone: event ``cone``).
    Before, a trial sub-step ended past the opening with a pulling contact (R < 0); the cone was never
    seen and the slack event was located at the second zero of F = -2 R cos(beta + phi) (beta + phi =
    pi/2, R < 0): the slack state held a pulling contact and the Warp run ended no_convergence.  Now the
    sub-step ends where Rn changes sign along the branch (bisection on converged states) and the events
    are judged there.  Expected: both engines (different Newtons and event searches) agree on the events
    and their C; the cone event sits on the SF- branch (phi = +phimax with beta and s_BC at their frozen
    values, the reversal's); no state pulls (Rn >= -ZERO_CONTACT P, the unilateral contact); every slack
    state has F = 0 (R = 0 or beta + phi = pi/2, eq 7) with Rn >= 0."""
    p = CellParams(B=0.14066840590192403, d=0.5398217341511322, L=14.018443003389507, W0=4.2577566476830055,
                   C0=2.634773774153177, m=0.3624343622664708, phi0=0.16411806079292926,
                   unloading_rule="dusserre", reload_rule="mirror_unloading", jamming_criterion="head_gap",
                   force_cap_N=9.654412027934193)
    assert DOMAIN.why_outside(p) is None
    h = run_batch([p], PROGRAM)
    r = CellCycle(p).run(PROGRAM)
    for x in (h, r):
        assert np.all(x.status[:, 0] == STATUS_OK)
        assert np.all(x.values["Rn"][:, 0] >= -ZERO_CONTACT * x.values["P"][:, 0])
    ev_w = [(e["increment"], e["kind"], e["C"]) for e in h.events if e["kind"] != "flag"]
    ev_r = [(e["increment"], e["kind"], e["C"]) for e in r.events if e["kind"] != "flag"]
    assert [e[:2] for e in ev_w] == [e[:2] for e in ev_r]
    np.testing.assert_allclose([e[2] for e in ev_w], [e[2] for e in ev_r], rtol=0, atol=1e-8)
    assert [e[1] for e in ev_w if e[0] == 60] == ["reversal", "cone", "slide"]
    cone = next(e for e in r.events if e["kind"] == "cone" and e["increment"] == 60)
    assert abs(cone["phi"] - p.phimax) < 1e-9
    for x in (h, r):
        slack = np.nonzero(x.stage[:, 0] == Stage.SLACK)[0]
        first = [k for k in slack if k == 0 or x.stage[k - 1, 0] != Stage.SLACK]
        assert len(first) == 3                       # one slack per unloading
        for k in first:
            assert x.values["Rn"][k, 0] >= 0.0
    # the last unloading goes slack in S- where R -> 0 (beta + phi != pi/2): F = 0 there because R = 0
    k = [k for k in range(len(PROGRAM)) if r.stage[k, 0] == Stage.SLACK][-1]
    assert r.values["Rn"][k, 0] <= ZERO_CONTACT * r.values["P"][k, 0]


def test_reversal_from_a_jam_returns_energy_and_is_flagged():
    """A domain cell (the slow property test's example, head-gap jamming from strain 0.45) loaded to 0.5
    and unloaded to 0: the reversal from the jammed state slides at 0.451 (jammed SF-) and unjams there;
    S- then freezes T at the slide (Table 4, E -> F), 3.86 N against 1.1 N on loading (the jam raised
    it), and the unloading returns above the loading curve: 4.18 N per wale at strain 0 against 2.39 N at
    rest, oint F dC < 0.  The model, not a solver, does this (same in the NumPy reference; T frozen
    through the whole unloading, Hong's rule, gives the same).  Expected, from independent quantities:
    the friction at the crossing dissipates (-int Rt ds_BC >= 0: Coulomb's Rt opposes the slip) and the
    elastica stores more bending energy at the end than at rest (B/2 int theta'^2 ds on the centreline,
    another integration of eqs 8-9): so the energy the loop returns comes from Table 4's frozen force
    closures, and the summary must say so (warning loop_creates_energy)."""
    from knitsim.cell.quarter_loop import centreline
    from knitsim.io.checks import energy_creating_loops
    from knitsim.io.results import cell_summary

    p = CellParams(B=3.2320405851281793, d=1.0, L=23.236310302405247, W0=8.440690238335081, C0=4.929637001818417,
                   m=0.2397704821942555, phi0=0.08383068096173228, unloading_rule="dusserre",
                   reload_rule="mirror_unloading", jamming_criterion="head_gap", force_cap_N=68.37937397181895)
    assert DOMAIN.why_outside(p) is None
    prog = piecewise_linear([0.0, 0.5, 0.0], 0.05)
    r = CellCycle(p).run(prog)
    h = run_batch([p], prog)
    for x in (h, r):
        assert np.all(x.status[:, 0] == STATUS_OK)
    np.testing.assert_allclose(h.force_per_wale[:, 0], r.force_per_wale[:, 0], rtol=1e-7, atol=1e-9)
    assert r.jammed[9, 0] and not r.jammed[10, 0]                  # jammed at the reversal, unjammed after
    v = {k: np.concatenate([[float(r.rest[k][0])], r.values[k][:, 0]])
         for k in ("alpha", "beta", "gamma", "phi", "P", "s_BC", "Rn", "F")}
    s = np.concatenate([[0.0], prog.strain])
    work = dissipated_energy(s, v["F"]) * p.C0
    rt = v["Rn"] * np.tan(v["phi"])
    friction = -float(np.sum(0.5 * (rt[1:] + rt[:-1]) * np.diff(v["s_BC"])))

    def bending_energy(i):
        c = centreline(*(v[k][i] for k in ("alpha", "beta", "gamma", "phi", "P")), p.B, p.d, n_points=2001)
        kappa = np.gradient(c["theta"], c["s"])
        return 0.5 * p.B * np.trapezoid(kappa * kappa, c["s"])

    assert friction > 0.0
    assert bending_energy(-1) > bending_energy(0)
    assert work < -0.1 * p.C0 * v["F"][0]                          # -2.67 N mm: not rounding
    assert v["F"][-1] > v["F"][0]
    flagged = energy_creating_loops(s, v["F"], p.C0)
    assert len(flagged) == 1 and flagged[0].code == "loop_creates_energy"
    codes = [w["code"] for w in cell_summary(h, 0, "cell")["warnings"]]
    assert "loop_creates_energy" in codes
