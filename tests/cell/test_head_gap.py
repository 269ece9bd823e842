"""Head-to-head centreline distance of neighbouring loops vs brute force.

Independent method: sample the centreline of the quarter loop
(:func:`knitsim.cell.quarter_loop.centreline`), build the whole head by the
mirror X -> -X (symmetry about the apex, Hong et al. 2002), the neighbouring
head by the shift X -> X + W (wale spacing), and take the smallest distance
over all pairs of sampled points.
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.head_gap import head_gap, interpenetrating, max_abscissa
from knitsim.cell.inverse import initial_state, solve_state
from knitsim.cell.quarter_loop import centreline

B, D = 0.31, 0.58          # E-glass, Dusserre (2015) Table 1
KNIT = dict(C0=2.7, W0=4.4, L=14.1)


def _brute(x, n=1601):
    c = centreline(*x, B, D, n_points=n)
    head = np.concatenate([np.stack([c["X"], c["Y"]], 1), np.stack([-c["X"], c["Y"]], 1)])
    w = 4.0 * c["X"][0]                      # X_A = W/4 (eq 6)
    other = head + np.array([w, 0.0])
    dist = np.sqrt(((head[:, None, :] - other[None, :, :]) ** 2).sum(-1))
    return dist.min()


@pytest.fixture(scope="module")
def states():
    r0 = initial_state(KNIT["C0"], KNIT["W0"], KNIT["L"], 0.0, B, D)
    out = [r0.x]
    guess = r0.x
    for c in (3.4, 4.0):                       # stretched along the wale, S+ with m = 0 (Rn frozen)
        r = solve_state({"C": c, "L": KNIT["L"], "phi": 0.0, "Rn": float(r0.state.Rn)}, guess, B, D)
        assert r.success
        out.append(r.x)
        guess = r.x
    return out


def test_head_gap_matches_brute_force(states):
    for x in states:
        g = float(head_gap(*x, B, D))
        # sampling error of the brute force ~ (spacing)^2 / curvature radius: < 1e-5 mm here
        assert g == pytest.approx(_brute(x), abs=2e-5)


def test_heads_bulge_beyond_a(states):
    # theta passes pi/2 between A and B, so X_max > X_A = W/4 and the gap < W/2
    for x in states:
        c = centreline(*x, B, D, n_points=801)
        assert float(max_abscissa(*x, B, D)) > c["X"][0]
        assert float(max_abscissa(*x, B, D)) == pytest.approx(c["X"].max(), abs=1e-5)


def test_interpenetration_flag():
    assert interpenetrating(0.5, D) and not interpenetrating(0.6, D)
