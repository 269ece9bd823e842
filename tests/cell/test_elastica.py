"""Elastica integrals of eqs 8-9 vs Carlson closed forms (an independent method)."""
from __future__ import annotations

import numpy as np

from knitsim.cell import elastica as el


def _ab_states(n=400, seed=0):
    rng = np.random.default_rng(seed)
    a = 10.0 ** rng.uniform(-8.0, np.log10(2.0), n)          # high load down to 1e-8
    u_b = a + rng.uniform(0.01, 3.5, n)
    return a, np.minimum(u_b, 2.0 * np.pi - a - 0.05)         # includes u_B > pi


def test_ab_quadrature_matches_carlson_closed_form():
    # Legendre F, E in Carlson form (scipy elliprf/elliprd) vs graded Gauss-Legendre
    a, u_b = _ab_states()
    assert np.any(u_b > np.pi)                                  # passes the direction of -P
    got = el.ab_integrals(a, u_b)
    ref = el.ab_integrals_carlson(a, u_b)
    for g, r in zip(got, ref):
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-13 * np.max(np.abs(ref[0])))


def test_ab_high_load_limit_log_growth():
    # limit case a -> 0: K(k) ~ ln(4/k'), so s_AB(a) - s_AB(a/10) -> -ln(10)
    u_b = 1.5
    s1 = el.ab_integrals(1e-6, u_b)[0]
    s2 = el.ab_integrals(1e-7, u_b)[0]
    np.testing.assert_allclose(s2 - s1, np.log(10.0), rtol=1e-9)


def test_ab_quadrature_converged_in_node_count():
    # node-count convergence study (module constant N_AB): doubling changes nothing
    a, u_b = _ab_states(100, seed=3)
    s1 = el.ab_integrals(a, u_b, el.N_AB)[0]
    s2 = el.ab_integrals(a, u_b, 2 * el.N_AB)[0]
    np.testing.assert_allclose(s1, s2, rtol=1e-13)


def test_bc_quadrature_matches_carlson_closed_form():
    rng = np.random.default_rng(1)
    beta = rng.uniform(0.3, 3.0, 2000)
    delta = 10.0 ** rng.uniform(-2.0, 0.3, 2000)
    k1p = rng.uniform(-0.3, 3.0, 2000)                          # T of either sign
    d0 = el.bc_D(0.0, np.pi - beta, delta, k1p)
    ok = d0 > 1e-2
    got = el.bc_integrals(beta[ok], delta[ok], k1p[ok])
    ref = el.bc_integrals_carlson(beta[ok], delta[ok], k1p[ok])
    for g, r in zip(got, ref):
        assert np.max(np.abs(g - r) / np.abs(ref[0])) < 1e-12


def test_bc_delta_is_eq8_curvature_at_b():
    # theta' continuous at B (no point moment): D(v_B) = cos(a) - cos(u_B) of eq 8,
    # here written as a product of sines (trig identity)
    a, u_b = 0.4, 1.7
    np.testing.assert_allclose(el.bc_delta(a, u_b), np.cos(a) - np.cos(u_b), rtol=1e-14)
