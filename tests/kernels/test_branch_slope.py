"""The force gradient behind the step's own branch slope (kernels.cell_step.force_gradient), in both charts of
the cell Newton, against the assembly's (kernels.quarter_loop: the dual numbers of the full evaluation).

Expected: an identity.  force_gradient forms dF/dz from eq 7 alone, F = 2 P sin(gamma) with
sin(gamma) = -(R/P) cos(beta + phi) (and, in chart 1, R/P from ln G(0) by rho_of_g0); evaluate_chart carries the
same F through the whole quarter-loop assembly with its gradients.  Both are the exact derivative of the same
function of the same variables, so they agree to rounding (1e-13 relative), in chart 0 (R/P) and in chart 1
(ln G(0), the Newton's variables near the edge G(0) = 0).  The slope itself is checked against the tangent
kernel in tests/patch/test_partial_trials.py.  States: random admissible (alpha, beta, gamma, phi, P).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.cell.quarter_loop import quarter_loop
from knitsim.kernels.cell_step import apex_g0, evaluate_chart, force_gradient
from knitsim.kernels.elastica import vec5d
from knitsim.kernels.quarter_loop import Q_F

warp_runtime.init()
B, D = 0.31, 0.58


@wp.kernel
def gradients_kernel(z: wp.array2d(dtype=wp.float64), chart: int, assembled: wp.array2d(dtype=wp.float64),
                     formed: wp.array2d(dtype=wp.float64)):
    i = wp.tid()
    zc = vec5d(z[i, 0], z[i, 1], z[i, 2], z[i, 3], z[i, 4])
    if chart != 0:
        zc[2] = wp.log(apex_g0(zc))
    cell = evaluate_chart(zc, chart, wp.float64(B), wp.float64(D))
    g = force_gradient(zc, chart)
    for k in range(5):
        assembled[i, k] = cell.dq[Q_F, k]
        formed[i, k] = g[k]


def _states(n: int, rng) -> np.ndarray:
    """Newton variables (ln(alpha - gamma), beta, R/P, phi, ln P) of random admissible states with G(0) > 0."""
    out = []
    while len(out) < n:
        gamma, phi = rng.uniform(-0.3, 0.6), rng.uniform(-0.3, 0.3)
        alpha = gamma + 10.0 ** rng.uniform(-4, 0)          # down to alpha - gamma = 1e-4: high loads
        beta = rng.uniform(max(alpha, gamma) + 0.05, 2.6)
        P = 10.0 ** rng.uniform(-2, 1)
        st = quarter_loop(alpha, beta, gamma, phi, P, B, D)
        if not bool(st.admissible):
            continue
        rho = float(st.quantity("R")) / P
        bp = beta + phi
        g0 = np.cos(alpha - gamma) + np.sqrt(1 - (rho * np.cos(bp)) ** 2) - rho * (np.sin(bp) + np.sin(phi))
        if g0 > 1e-6:
            out.append((np.log(alpha - gamma), beta, rho, phi, np.log(P)))
    return np.array(out)


def test_the_force_gradient_of_eq_7_is_the_assemblys_in_both_charts(device):
    z = _states(60, np.random.default_rng(7))
    zd = wp.array(z, dtype=wp.float64, device=device)
    for chart in (0, 1):
        a = wp.zeros((len(z), 5), dtype=wp.float64, device=device)
        f = wp.zeros((len(z), 5), dtype=wp.float64, device=device)
        wp.launch(gradients_kernel, dim=len(z), inputs=[zd, chart], outputs=[a, f], device=device)
        a, f = a.numpy(), f.numpy()
        assert np.all(np.isfinite(a)) and np.any(np.abs(a[:, 2]) > 0)
        scale = np.max(np.abs(a), axis=1, keepdims=True)      # each state's own gradient size
        assert np.all(np.abs(f - a) <= 1e-13 * scale), (chart, np.max(np.abs(f - a) / scale))
