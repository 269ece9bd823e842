"""Newton inverse solve and forward-mode Jacobian of the quarter stitch (Warp).

Sources of the expected numbers: model.md's check values of the paper knits'
initial state (from its independent float64 SciPy implementation, paper data
of dusserre2015.toml); central differences of the forward map (an independent
derivative); states built by the forward map and recovered by the inverse
(round trip: the inverse must return the state that produced the targets).
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from knitsim.cell import warp_solve
from knitsim.cell.quantities import CODE, QUANTITY_NAMES
from knitsim.data import dusserre2015
from knitsim.errors import KnitsimInputError

PAPER = dusserre2015()

# states on a wale-wise stretch path of the E-glass knit (B 0.31, d 0.58), from low to high load
# (rounded to 8 digits; projected below onto g = 0, the intrinsic condition of eq 6)
_ROUNDED = np.array([
    [1.218147, 1.660135, 0.074085, 0.0, 0.145839],
    [1.22529492, 1.69571347, 0.21231402, 0.156, 0.14141735],
    [1.21685052, 1.84856798, 0.16546132, 0.156, 0.11541225],
    [1.17963033, 2.03455679, 0.39813261, 0.156, 0.13196943],
    [1.21817291, 2.14473517, 1.07444096, 0.156, 0.38293985],
    [1.36398464, 2.20365475, 1.36255918, 0.156, 2.25359421],   # alpha - gamma ~ 1.4e-3
    [1.4195912, 2.22655131, 1.41958463, 0.156, 6.73507988],    # alpha - gamma ~ 7e-6
])
B_EG, D_EG = 0.31, 0.58


def _exact_states():
    """The rounded states made exact: alpha, beta, phi, P kept, gamma solved from g = 0."""
    x, status, _ = warp_solve.solve_batch(("alpha", "beta", "phi", "P"), _ROUNDED[:, [0, 1, 3, 4]], B_EG, D_EG, _ROUNDED)
    assert np.all(status == 0)
    assert np.all(np.abs(x - _ROUNDED).max(axis=1) < 1e-6)
    return x


STATES = _exact_states()

# Dusserre 2015 Table 4 condition sets
TABLE4 = {
    "init": ("C", "W", "L", "phi"),
    "SF+": ("s_BC", "Rn", "L", "phi"),
    "S+": ("Rn", "L", "phi", "C"),
    "J+": ("W", "L", "phi", "C"),
    "SF-": ("beta", "s_BC", "L", "phi"),
    "S-": ("T", "L", "phi", "C"),
}


def _knit(name):
    y = PAPER["yarn"][name]
    k = PAPER["knit"]
    return y["yarn_diameter_mm"], y["bending_stiffness_N_mm2"], k["stitch_length_mm"][name], k["wale_width_mm"], k["course_length_mm"]


@pytest.mark.parametrize("knit, expected", [
    ("e_glass", (1.218147, 1.660135, 0.074085, 0.145839)),   # model.md check values
    ("basalt", (1.173696, 1.818129, 0.348877, 0.150118)),
])
def test_initial_state_matches_model_md(device, knit, expected):
    d, B, L, W0, C0 = _knit(knit)
    x, status, it = warp_solve.solve_batch(TABLE4["init"], [C0, W0, L, 0.0], B, d, [1.2, 1.7, 0.1, 0.0, 0.15], device=device)
    assert status[0] == 0
    a, b, g, _, P = x[0]
    assert (a, b, g) == pytest.approx(expected[:3], abs=6e-7)  # 6 decimals in model.md
    assert P == pytest.approx(expected[3], abs=6e-7)
    q = warp_solve.forward_batch(x[0], B, d, device=device)
    assert q["C"][0] == pytest.approx(C0, abs=1e-10) and q["W"][0] == pytest.approx(W0, abs=1e-10)
    assert abs(q["g"][0]) < 1e-10


def test_forward_jacobian_vs_central_differences(device):
    q, dq, g, dg = warp_solve.forward_jacobian_batch(STATES, B_EG, D_EG, device=device)
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(dq))
    J = np.concatenate([dq, dg[:, None, :]], axis=1)  # (N, n_quantities + 1, 5)
    names = QUANTITY_NAMES + ("g",)
    row_scale = np.abs(J).max(axis=2)  # per state and quantity: its largest partial
    a = STATES[:, 0] - STATES[:, 2]
    for j in range(5):
        # steps: a fraction of alpha - gamma for the two angles it is made of, else relative
        h = (1e-4 * a) if j in (0, 2) else 1e-6 * np.maximum(np.abs(STATES[:, j]), 0.1)

        def f(m):
            xs = STATES.copy()
            xs[:, j] += m * h
            out = warp_solve.forward_batch(xs, B_EG, D_EG, device=device)
            return np.stack([out[n] for n in names], axis=1)

        # fourth-order central difference
        fd = (8 * (f(1) - f(-1)) - (f(2) - f(-2))) / (12 * h[:, None])
        err = np.abs(J[:, :, j] - fd)
        assert np.all(err <= 1e-6 * row_scale + 1e-12), (j, np.unravel_index(np.argmax(err / (row_scale + 1e-300)), err.shape))


@pytest.mark.parametrize("stage", list(TABLE4))
def test_newton_recovers_forward_mapped_states(device, stage):
    conditions = TABLE4[stage]
    q = warp_solve.forward_batch(STATES, B_EG, D_EG, device=device)
    targets = np.stack([q[c] for c in conditions], axis=1)
    rng = np.random.default_rng(4)
    guess = STATES.copy()
    # perturb: angles by 1 %, alpha - gamma and P by up to 10 % (relative)
    a = (STATES[:, 0] - STATES[:, 2]) * np.exp(rng.uniform(-0.1, 0.1, len(STATES)))
    guess[:, 1:4] += rng.uniform(-0.01, 0.01, (len(STATES), 3))
    guess[:, 0] = guess[:, 2] + a
    guess[:, 4] *= np.exp(rng.uniform(-0.1, 0.1, len(STATES)))
    x, status, iters = warp_solve.solve_batch(conditions, targets, B_EG, D_EG, guess, device=device)
    assert np.all(status == 0), (stage, status, iters)
    assert np.all(iters <= 20)
    np.testing.assert_allclose(x[:, 1:], STATES[:, 1:], rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(x[:, 0] - x[:, 2], STATES[:, 0] - STATES[:, 2], rtol=1e-6)


def test_batch_equals_one_at_a_time_bitwise(device):
    conds = np.array([[CODE[c] for c in TABLE4[s]] for s in TABLE4] * 2)[: len(STATES)]
    q = warp_solve.forward_batch(STATES, B_EG, D_EG, device=device)
    targets = np.array([[q[QUANTITY_NAMES[c]][i] for c in conds[i]] for i in range(len(STATES))])
    guess = STATES * np.array([1.0, 1.002, 1.0, 1.0, 1.05])
    xb, sb, ib = warp_solve.solve_batch(conds, targets, B_EG, D_EG, guess, device=device)
    for i in range(len(STATES)):
        xi, si, ii = warp_solve.solve_batch(conds[i], targets[i], B_EG, D_EG, guess[i], device=device)
        assert np.array_equal(xi[0], xb[i]) and si[0] == sb[i] and ii[0] == ib[i]


def test_hopeless_cells_fail_cleanly(device):
    d, B, L, W0, C0 = _knit("e_glass")
    guess = [1.2, 1.7, 0.1, 0.0, 0.15]
    targets = np.array([
        [C0, W0, L, 0.0],        # fine: control
        [C0, W0, 1.0, 0.0],      # yarn far too short for the loop: no state exists
        [30.0, 30.0, L, 0.0],    # wale and course longer than the yarn
    ])
    x, status, iters = warp_solve.solve_batch(TABLE4["init"], targets, B, d, guess, device=device, max_iter=30)
    assert status[0] == 0
    assert np.all(status[1:] != 0)
    assert np.all(np.isfinite(x))  # the last admissible iterate, never NaN
    # a guess outside the domain (alpha < gamma) is refused with status 4
    x, status, _ = warp_solve.solve_batch(TABLE4["init"], targets[0], B, d, [0.1, 1.7, 0.2, 0.0, 0.15], device=device)
    assert status[0] == 4 and np.all(np.isfinite(x))


@pytest.mark.parametrize("kwargs, field", [
    (dict(B=-1.0), "B"),
    (dict(d=0.0), "d"),
    (dict(targets=[2.7, np.nan, 14.1, 0.0]), "targets"),
    (dict(conditions=("C", "W", "L", "mu")), "conditions"),
    (dict(conditions=("C", "C", "L", "phi")), "conditions"),
    (dict(x_guess=[1.2, 1.7, 0.1]), "x_guess"),
    (dict(B=[0.3, 0.3], d=[0.5, 0.5, 0.5]), "d"),
])
def test_bad_input_raises(kwargs, field):
    args = dict(conditions=TABLE4["init"], targets=[2.7, 4.4, 14.1, 0.0], B=0.31, d=0.58, x_guess=[1.2, 1.7, 0.1, 0.0, 0.15])
    args.update(kwargs)
    with pytest.raises(KnitsimInputError, match=field):
        warp_solve.solve_batch(**args)


@pytest.mark.skipif(importlib.util.find_spec("knitsim.cell.quarter_loop") is None, reason="NumPy reference not present")
def test_forward_map_matches_numpy_reference(device):
    """Two independent implementations of eqs 6-9 (NumPy reference, knitsim.cell.quarter_loop) agree."""
    from knitsim.cell.quarter_loop import quarter_loop

    got = warp_solve.forward_batch(STATES, B_EG, D_EG, device=device)
    ref = quarter_loop(*STATES.T, B_EG, D_EG, a=STATES[:, 0] - STATES[:, 2])
    for name in QUANTITY_NAMES + ("g",):
        r = np.asarray(getattr(ref, name))
        scale = np.maximum(np.abs(r), 1.0)
        assert np.all(np.abs(got[name] - r) <= 1e-10 * scale), (name, got[name], r)
