"""Warp centreline kernel (kernels/centreline.py) against its float64 NumPy twin and identities.

Expected values: :func:`knitsim.cell.quarter_loop.centreline` (the float64
reference, same sample points), the forward map
:func:`knitsim.cell.quarter_loop.quarter_loop` at equilibrium (eq 6: X_A = W/4,
Y_A = 0; apex on X = 0 at Y_C), and the identity |dr/ds| = 1 of an arc-length
parametrisation (an independent check of s against the points).
"""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.quarter_loop import centreline, closing_force, quarter_loop
from knitsim.usd.from_results import quarter_centrelines

B, D = 0.31, 0.58          # E-glass, Dusserre 2015 Table 1 (N mm^2, mm)


def _states(n, seed=0, high_load=True):
    """Admissible states: a = alpha - gamma log-uniform down to 1e-7 (high load) when asked."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        g = rng.uniform(-0.2, 0.6)
        a = 10 ** rng.uniform(-7 if high_load else -1.5, 0.2)
        al = g + a
        be = al + rng.uniform(0.05, 1.5)
        phi = rng.uniform(-0.5, 0.5)
        P = 10 ** rng.uniform(-3, 1)
        if bool(quarter_loop(al, be, g, phi, P, B, D).admissible):
            out.append([al, be, g, phi, P])
    return np.array(out)


@pytest.mark.parametrize("n_points", [6, 9, 21])
def test_matches_reference_at_same_arc_length(device, n_points):
    x = _states(40)
    out = quarter_centrelines(x, B, D, n_points, device=device)
    assert out["ok"].all()
    for i, xi in enumerate(x):
        ref = centreline(*xi, B, D, n_points=n_points)
        np.testing.assert_allclose(out["s"][i], ref["s"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(out["xy"][i, :, 0], ref["X"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(out["xy"][i, :, 1], ref["Y"], rtol=0, atol=1e-9)
        assert out["i_B"] == ref["i_B"]


def test_end_points_at_equilibrium(device):
    """At g = 0 (P from closing_force): A = (W/4, 0), C = (0, Y_C), s_AB, W, C of the forward map (eq 6)."""
    x = _states(30, seed=1, high_load=False)
    x[:, 4] = closing_force(x[:, 0], x[:, 1], x[:, 2], x[:, 3], B, D)
    x = x[np.isfinite(x[:, 4])]
    assert len(x) >= 10
    ql = quarter_loop(x[:, 0], x[:, 1], x[:, 2], x[:, 3], x[:, 4], B, D)
    np.testing.assert_allclose(ql.g, 0.0, atol=1e-12)
    out = quarter_centrelines(x, B, D, 9, device=device)
    np.testing.assert_allclose(out["xy"][:, 0, 0], ql.W / 4, rtol=0, atol=1e-9)   # X_A = W/4 (eq 6)
    np.testing.assert_allclose(out["xy"][:, 0, 1], 0.0, atol=1e-12)               # Y_A = 0
    np.testing.assert_allclose(out["xy"][:, -1, 0], 0.0, atol=1e-9)               # apex on X = 0
    np.testing.assert_allclose(out["xy"][:, -1, 1], ql.Y_C, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["xy"][:, out["i_B"], 0], ql.X_B, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["xy"][:, out["i_B"], 1], ql.Y_B, rtol=0, atol=1e-9)
    for k in ("W", "C", "s_AB", "Y_C"):
        np.testing.assert_allclose(out[k], getattr(ql, k), rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["s"][:, -1], ql.L / 4, rtol=0, atol=1e-9)      # L/4 = s_AB + s_BC


def test_unit_speed(device):
    """|dr/ds| = 1: with many samples the chord lengths tend to the arc-length steps."""
    x = _states(10, seed=2, high_load=False)
    out = quarter_centrelines(x, B, D, 401, device=device)
    ds = np.diff(out["s"], axis=1)
    chord = np.linalg.norm(np.diff(out["xy"], axis=1), axis=-1)
    assert np.all(chord <= ds + 1e-9)               # a chord is never longer than its arc (to quadrature error)
    np.testing.assert_allclose(chord.sum(axis=1), out["s"][:, -1], rtol=1e-4)


def test_inadmissible_gives_nan(device):
    """beta < alpha (theta not monotone) and P <= 0 are flagged, points NaN."""
    x = np.array([[1.0, 0.8, 0.1, 0.0, 1.0], [1.0, 1.8, 0.1, 0.0, -1.0], [1.0, 1.8, 0.1, 0.0, 1.0]])
    out = quarter_centrelines(x, B, D, 9, device=device)
    assert out["ok"].tolist() == [False, False, True]
    assert np.isnan(out["xy"][:2]).all() and np.isfinite(out["xy"][2]).all()
