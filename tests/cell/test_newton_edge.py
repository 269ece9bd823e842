"""The cell Newton next to the edge G(0) = 0 of the quarter loop's domain (issue 15).

On the reload S- -> SF+ of a loaded cell, theta' nearly vanishes at the apex C (G(0) =
(theta'_C lambda)^2 / 2 ~ 1e-5): the BC integrals go as ln G(0) and the Newton in R/P crawled
(kernels.cell_step.newton now runs in ln G(0) there).  The cell below is one of the random cells of
``benchmarks/bench_table.random_arrays(100, seed=6)`` with the head-gap criterion: before the chart,
its first reload increment ran into the 4096 sub-step guard and ended short of the imposed course
length (C = 3.00767 mm for 3.02137 mm) with status ok.  The NumPy reference fails on this cell
(no convergence from the first unloading on), so the expected numbers here are the load program's
imposed course lengths and the equations of the model themselves at the batch's states: eq 6 and
the course length by the NumPy forward map (:func:`knitsim.cell.quarter_loop.quarter_loop`), and
the arc length of BC (eq 9) by adaptive quadrature (``scipy.integrate.quad``) of
ds = lambda du / sqrt(2 G(u)), G(u) = G(0) + 2 |k1'| sin^2(u/2), with break points graded toward C.
(The NumPy forward map's s_BC is itself off there: 2e-4 mm at G(0) = 1e-5, 8e-3 mm at 1e-6.)
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import quad

from knitsim.cell.batch import run_batch
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams
from knitsim.cell.quarter_loop import quarter_loop
from knitsim.cell.stages import Stage

CELL = CellParams(B=0.1995972728716258, d=0.5544287281545511, L=13.210583343541156, W0=4.460215973683098,
                  C0=2.7219560331452897, m=0.033599844958794776, phi0=-0.02645786559622301,
                  unloading_rule="hong_constant_t", jamming_criterion="head_gap", force_cap_N=10.0,
                  in_plane_width=0.7)


def test_reload_next_to_the_domain_edge_reaches_the_imposed_course_length():
    prog = cycles(0.10, 0.60, 3, max_increment=0.01)
    n = 114  # loading to 0.60, unloading to 0.10, the first four reload increments
    prog = LoadProgram(prog.strain[:n], prog.cycle[:n], prog.direction[:n], prog.waypoints)
    h = run_batch([CELL], prog)
    assert np.all(h.status[:, 0] == 0)
    # every increment ends at its imposed course length C0 (1 + strain) (the reload's slide event
    # lies inside increment 110, at C = 3.00883 mm, so that row ends sliding)
    np.testing.assert_allclose(h.values["C"][:, 0], CELL.C0 * (1.0 + prog.strain), rtol=0, atol=1e-9)
    assert h.stage[109, 0] == Stage.S_UNLOAD and np.all(h.stage[110:, 0] == Stage.S_LOAD)
    # the recorded states solve the model: eq 6 (g = 0) and the course length C, by the NumPy map
    v = {k: h.values[k][:, 0] for k in ("alpha", "beta", "gamma", "phi", "P", "C", "s_BC")}
    ql = quarter_loop(v["alpha"], v["beta"], v["gamma"], v["phi"], v["P"], CELL.B, CELL.d)
    assert np.max(np.abs(ql.g)) < 1e-9 * CELL.d
    np.testing.assert_allclose(ql.C, v["C"], rtol=0, atol=1e-9)
    # the reload rows sit next to the edge (G(0) < 1e-2, T > 0: k1' < 0), and there the arc length
    # of BC (eq 9) by quadrature is the recorded s_BC and closes the yarn length L = 4 (s_AB + s_BC)
    for i in range(110, n):
        beta, gamma, a = v["beta"][i], v["gamma"][i], v["alpha"][i] - v["gamma"][i]
        b = beta - gamma
        k1p = ql.k1p[i]
        g0 = 2.0 * np.sin(0.5 * (b + a)) * np.sin(0.5 * (b - a)) + k1p * (1.0 + np.cos(beta))
        assert 0.0 < g0 < 1e-2 and k1p < 0.0
        u_b = np.pi - beta
        pts = [0.0] + [u for u in np.sqrt(g0 / -k1p) * np.logspace(0, 6, 13) if u < u_b] + [u_b]
        f = lambda u: 1.0 / np.sqrt(2.0 * (g0 - 2.0 * k1p * np.sin(0.5 * u) ** 2))  # noqa: E731
        s_bc = np.sqrt(CELL.B / v["P"][i]) * sum(quad(f, pts[j], pts[j + 1], epsabs=0.0, epsrel=1e-13, limit=200)[0]
                                                for j in range(len(pts) - 1))
        assert abs(v["s_BC"][i] - s_bc) < 1e-10
        assert abs(4.0 * (ql.s_AB[i] + s_bc) - CELL.L) < 1e-9
