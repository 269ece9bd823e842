"""The far side of the friction cone while loading, and the slack where the contact opens (issue 14).

Why SF+ needs no ``phi -> -phimax`` event (knitsim.cell.stages, "far side"): with Rn frozen,
tan(phi) = Rt / Rn and loading raises Rt, so the far edge is crossed only with Rn <= 0, a pulling
contact or none.  The case that reached it: a cell of the documented domain whose S- unloading
passed R = 0 where beta + phi passed pi/2 as well, so that F = -2 R cos(beta + phi) (eq 7) only
touched 0 and the slack event on F was missed; a reload then froze the tensile Rn and the stick
ran to phi -> -pi/2.  Expected numbers come from eq 7 (an identity of the state), from an
independent solve of the S- branch beyond the opening (knitsim.cell.inverse.solve_state) and from
the engines against each other (the Warp batch and the float64 NumPy reference, to the
batch-vs-reference tolerance of tests/cell/test_batch.py).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import run_cell
from knitsim.cell.domain import DOMAIN
from knitsim.cell.history import STATUS_NO_REST_STATE
from knitsim.cell.inverse import solve_state
from knitsim.cell.load_program import piecewise_linear
from knitsim.cell.material import CellParams
from knitsim.cell.stages import ZERO_CONTACT, Stage

# found by a random draw of the domain (d 0.22 mm, W0/d 6.0, C0/d 5.0, L ratio 1.85, m 0.48)
CELL = CellParams(B=0.4385149492904808, d=0.22156689428292023, L=4.967701304010959, W0=1.3323723144582553,
                  C0=1.117674823475989, m=0.48033314441994523, phi0=0.3490001530258707, unloading_rule="dusserre",
                  reload_rule="freeze_rn", force_cap_N=380.16155947939245)
# jammed at 0.4, unloaded through the opening of the contact, reloaded
PROGRAM = piecewise_linear([0.0, 0.4, 0.05, 0.3], 0.02)
QUANTITIES = ("alpha", "beta", "gamma", "phi", "P", "W", "C", "s_BC", "T", "Rn", "F")


@pytest.fixture(scope="module")
def runs():
    assert DOMAIN.why_outside(CELL) is None
    return run_batch([CELL], PROGRAM), run_cell(CELL, PROGRAM)


def _slack(h):
    return next(e for e in h.events if e["kind"] == "slack")


def test_slack_is_located_where_the_contact_opens(runs):
    h, r = runs
    ev = _slack(r)
    i = ev["increment"]
    # S- at the start of the increment, slack at its end: the event inside the increment
    assert r.stage[i - 1, 0] == Stage.S_UNLOAD and r.stage[i, 0] == Stage.SLACK
    C_a, C_b = r.values["C"][i - 1, 0], CELL.C0 * (1.0 + PROGRAM.strain[i])
    assert C_b < ev["C"] < C_a
    # why F alone missed it: the S- branch continued to the end of the increment (independent solve,
    # phi = -phimax and T frozen) carries F > 0 with a pulling contact, Rn < 0
    T = r.values["T"][i - 1, 0]
    x0 = [r.values[k][i - 1, 0] for k in ("alpha", "beta", "gamma", "phi", "P")]
    beyond = solve_state({"L": CELL.L, "C": C_b, "phi": -CELL.phimax, "T": T}, x0, CELL.B, CELL.d)
    assert beyond.success and beyond.state.F > 0 and beyond.state.Rn < 0
    # eq 7 at the located state: F = -2 R cos(beta + phi) = 0
    assert abs(ev["F"]) <= 1e-9
    # the Warp batch locates the same point
    assert _slack(h)["C"] == pytest.approx(ev["C"], rel=1e-6)


def test_engines_agree_through_the_reload(runs):
    h, r = runs
    np.testing.assert_array_equal(h.status, r.status)
    np.testing.assert_array_equal(h.stage, r.stage)
    np.testing.assert_array_equal(h.jammed, r.jammed)
    for k in QUANTITIES:
        a, b = h.values[k], r.values[k]
        rel = np.abs(a - b) / np.maximum(np.abs(b), 1e-3)
        assert rel.max() <= 1e-6, (k, rel.max())
    assert [(e["increment"], e["kind"]) for e in h.events] == [(e["increment"], e["kind"]) for e in r.events]
    for eh, er in zip(h.events, r.events):
        if "C" in er:
            assert eh["C"] == pytest.approx(er["C"], rel=1e-6)


@pytest.mark.parametrize("which", [0, 1])
def test_no_pulling_contact_and_no_far_side(runs, which):
    """The invariant of stages.py, "far side", on both engines: never Rn < -ZERO_CONTACT P, and no SF+
    state beyond -phimax; the reload slides to +phimax (the loading direction) and the cell runs on."""
    h = runs[which]
    assert np.all(h.values["Rn"] >= -ZERO_CONTACT * h.values["P"])
    loading_stick = h.stage == Stage.SF_LOAD
    assert np.all(h.values["phi"][loading_stick] >= -CELL.phimax - 1e-9)
    kinds = [e["kind"] for e in h.events]
    k = kinds.index("reload")
    assert kinds[k + 1] == "slide" and h.status[-1, 0] == 0


def assert_far_side_invariant(h, cells) -> None:
    """No SF+ state with phi < -phimax and no pulling contact (Rn < -ZERO_CONTACT P) in a history."""
    run = h.status[0] != STATUS_NO_REST_STATE
    pm = np.array([c.phimax for c in cells])
    phi, Rn, P = h.values["phi"][:, run], h.values["Rn"][:, run], h.values["P"][:, run]
    far = (h.stage[:, run] == Stage.SF_LOAD) & (phi < -pm[run] - 1e-9)
    assert not far.any(), f"SF+ beyond -phimax: cells {np.nonzero(run)[0][far.any(0)]}"
    pull = Rn < -ZERO_CONTACT * P
    assert not pull.any(), f"pulling contact: cells {np.nonzero(run)[0][pull.any(0)]}"


def test_invariant_over_random_domain_cells():
    """Random cells of the domain box (all rules) through an unload-reload waypoint program (Warp)."""
    rng = np.random.default_rng(14)
    cells = []
    for i in range(16):
        d = math.exp(rng.uniform(math.log(DOMAIN.d[0]), math.log(DOMAIN.d[1])))
        B = math.exp(rng.uniform(math.log(DOMAIN.B[0]), math.log(DOMAIN.B[1])))
        W0, C0 = d * rng.uniform(*DOMAIN.W0_over_djam), d * rng.uniform(*DOMAIN.C0_over_d)
        L = (2 * C0 + W0 - 4 * d) * rng.uniform(*DOMAIN.L_over_closing)
        m = rng.uniform(*DOMAIN.m)
        cells.append(CellParams(B=B, d=d, L=L, W0=W0, C0=C0, m=m, phi0=rng.uniform(-1, 1) * math.atan(m),
                                unloading_rule=("dusserre", "hong_constant_t")[i % 2],
                                reload_rule=("freeze_rn", "mirror_unloading")[(i // 2) % 2],
                                force_cap_N=20.0 * B / d ** 2))
    h = run_batch(cells, piecewise_linear([0.0, 0.4, 0.05, 0.3, 0.0, 0.5], 0.02))
    assert_far_side_invariant(h, cells)
