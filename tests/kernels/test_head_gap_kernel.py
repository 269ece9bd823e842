"""The head gap on the Warp device (kernels.head_gap) vs its NumPy twin and brute force.

Expected numbers: :func:`knitsim.cell.head_gap.head_gap` (the twin: closed forms of the
elastica sub-arc to the vertical tangent), checked itself against the brute-force smallest
distance between sampled centrelines (tests/cell/test_head_gap.py); here also a brute force
of the sampled centreline's largest abscissa, an independent method.  The states are random
admissible (alpha, beta, gamma, phi, P) covering the three places of the vertical tangent:
on AB (alpha < pi/2 < beta), on BC (beta <= pi/2), none (alpha >= pi/2, X_max = X_A).
"""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from knitsim import warp_runtime
from knitsim.cell.head_gap import head_gap
from knitsim.cell.quantities import QUANTITY_NAMES
from knitsim.cell.quarter_loop import centreline, quarter_loop
from knitsim.kernels import head_gap as hg

warp_runtime.init()
B, D = 0.31, 0.58


def _states(case: str, n: int, rng) -> np.ndarray:
    out = []
    while len(out) < n:
        gamma = rng.uniform(-0.2, 0.6)
        phi = rng.uniform(-0.3, 0.3)
        if case == "ab":
            alpha, beta = rng.uniform(0.9, 1.5), rng.uniform(1.65, 2.4)
        elif case == "bc":
            alpha = rng.uniform(0.5, 1.2)
            beta = rng.uniform(alpha + 0.05, 0.5 * np.pi)
        else:
            alpha = rng.uniform(1.6, 2.0)
            beta = rng.uniform(alpha + 0.05, 2.6)
        x = (alpha, beta, gamma, phi, rng.uniform(0.05, 2.0))
        if bool(quarter_loop(*x, B, D).admissible):
            out.append(x)
    return np.array(out)


def _device_gap(X, device):
    st = quarter_loop(*X.T, B, D)
    q = np.stack([np.asarray(st.quantity(n), float) for n in QUANTITY_NAMES], axis=1)
    out = wp.zeros(len(X), dtype=wp.float64, device=device)
    wp.launch(hg.head_gap_kernel, dim=len(X), device=device,
              inputs=[wp.array(X[:, 0] - X[:, 2], dtype=wp.float64, device=device),
                      wp.array(q, dtype=wp.float64, device=device), wp.array([B], dtype=wp.float64, device=device)],
              outputs=[out])
    return out.numpy()


@pytest.mark.parametrize("case", ["ab", "bc", "apex_side"])
def test_head_gap_kernel_equals_numpy_twin(device, case):
    X = _states(case, 40, np.random.default_rng({"ab": 1, "bc": 2, "apex_side": 3}[case]))
    ref = head_gap(*X.T, B, D, a=X[:, 0] - X[:, 2])
    assert np.all(np.isfinite(ref))
    np.testing.assert_allclose(_device_gap(X, device), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("case", ["ab", "bc", "apex_side"])
def test_head_gap_kernel_vs_sampled_centreline(device, case):
    """W - 2 max(X) of a densely sampled centreline (sampling error ~ h^2 kappa, < 1e-5 mm)."""
    X = _states(case, 4, np.random.default_rng(10))
    gap = _device_gap(X, device)
    for x, g in zip(X, gap):
        c = centreline(*x, B, D, n_points=4001)
        w = float(quarter_loop(*x, B, D).W)   # eq 6 (the random states need not close g = 0)
        assert g == pytest.approx(w - 2.0 * c["X"].max(), abs=2e-5)
