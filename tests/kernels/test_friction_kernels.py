"""Warp twins of the friction laws (kernels/friction.py) equal the float64 references."""
from __future__ import annotations

import numpy as np
import warp as wp

from knitsim.friction import capstan, coiling
from knitsim.kernels import friction as kf


def _run(device, b, p, n, V, Fn, theta, mu):
    arrs = [wp.array(np.asarray(x, dtype=np.float64), dtype=wp.float64, device=device)
            for x in (b, p, n, V, Fn, theta, mu)]
    N = max(len(x) for x in (b, p, n, V, Fn, theta, mu))
    outs = [wp.zeros(N, dtype=wp.float64, device=device) for _ in range(3)]
    wp.launch(kf.eval_friction_laws, dim=N, inputs=arrs + outs, device=device)
    return [o.numpy() for o in outs]


def test_twins_equal_reference(device):
    rng = np.random.default_rng(2015)
    N = 256
    b = rng.uniform(0.05, 0.3, N)
    p = rng.uniform(-0.05, 0.1, N)
    n = rng.uniform(0.8, 1.0, N)
    V = rng.uniform(0.1, 20.0, N)
    Fn = rng.uniform(0.05, 20.0, N)
    theta = rng.uniform(0.05, 3.0, N)
    mu = rng.uniform(0.0, 0.5, N)
    mu_w, ft_w, m_w = _run(device, b, p, n, V, Fn, theta, mu)
    mu_ref = np.array([capstan.mu_k_eq5(b[i], p[i], n[i], V[i], Fn[i]) for i in range(N)])
    ft_ref = np.array([capstan.tangential_load_eq2(Fn[i], b[i], p[i], n[i], V[i]) for i in range(N)])
    np.testing.assert_allclose(mu_w, mu_ref, rtol=1e-12)
    np.testing.assert_allclose(ft_w, ft_ref, rtol=1e-12)
    np.testing.assert_allclose(m_w, coiling.m_eq10(theta, mu), rtol=1e-12, atol=1e-15)


def test_batch_axis_broadcast(device):
    # Parameters with a leading axis of 1 broadcast over the batch (i % shape[0]);
    # section 3.4 values: mu_k(0.5 mm/s, 1 N) = 0.156 (E-glass, Table 3).
    Fn = np.array([1.0, 2.0, 4.0])
    mu_w, ft_w, _ = _run(device, [0.159], [0.0246], [0.948], [0.5], Fn, [1.0], [0.1])
    assert abs(mu_w[0] - 0.156) < 5e-4
    np.testing.assert_allclose(ft_w, mu_w * Fn, rtol=1e-13)
