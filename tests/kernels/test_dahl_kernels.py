"""Warp twin of the Dahl update equals the float64 reference (knitsim.friction.dahl)."""
from __future__ import annotations

import numpy as np
import warp as wp

from knitsim.friction.dahl import dahl_increment as dahl_increment_ref
from knitsim.kernels import dahl as kd


@wp.kernel
def _alpha1_kernel(F: wp.array(dtype=wp.float64), dx: wp.array(dtype=wp.float64),
                   sigma: wp.array(dtype=wp.float64), Fc: wp.array(dtype=wp.float64),
                   out: wp.array(dtype=wp.float64)):
    i = wp.tid()
    out[i] = kd.dahl_increment_alpha1(F[i], dx[i], sigma[i], Fc[i])


def _states(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    F = rng.uniform(-1.5, 1.5, n)  # includes |F| > Fc (odd extension)
    dx = rng.choice([-1.0, 1.0], n) * 10 ** rng.uniform(-9, 1, n)
    dx[:20] = 0.0
    sigma = rng.uniform(0.05, 50.0, n)
    Fc = rng.uniform(0.2, 1.2, n)
    alpha = rng.choice([0.3, 0.5, 1.0 - 1e-7, 1.0, 1.0 + 1e-7, 1.5, 3.0], n)
    F[20:40] = Fc[20:40] * np.sign(dx[20:40])  # exactly saturated (u = 0)
    return F, dx, sigma, Fc, alpha


def _arr(a, device):
    return wp.array(np.ascontiguousarray(a, dtype=np.float64), dtype=wp.float64, device=device)


def test_general_update_equals_reference(device):
    F, dx, sigma, Fc, alpha = _states()
    out = wp.zeros(F.size, dtype=wp.float64, device=device)
    wp.launch(kd.dahl_increment_kernel, dim=F.size,
              inputs=[_arr(F, device), _arr(dx, device), _arr(sigma, device), _arr(Fc, device), _arr(alpha, device)],
              outputs=[out], device=device)
    np.testing.assert_allclose(out.numpy(), dahl_increment_ref(F, dx, sigma, Fc, alpha), rtol=1e-12, atol=1e-14)


def test_alpha1_update_equals_reference(device):
    F, dx, sigma, Fc, _ = _states(seed=1)
    out = wp.zeros(F.size, dtype=wp.float64, device=device)
    wp.launch(_alpha1_kernel, dim=F.size,
              inputs=[_arr(F, device), _arr(dx, device), _arr(sigma, device), _arr(Fc, device)],
              outputs=[out], device=device)
    np.testing.assert_allclose(out.numpy(), dahl_increment_ref(F, dx, sigma, Fc, 1.0), rtol=1e-13, atol=1e-15)


def test_batch_axis_broadcasts(device):
    # parameters of length 1 are shared by every state (p[i % p.shape[0]])
    F, dx, _, _, _ = _states(n=64, seed=2)
    out = wp.zeros(F.size, dtype=wp.float64, device=device)
    wp.launch(kd.dahl_increment_kernel, dim=F.size,
              inputs=[_arr(F, device), _arr(dx, device), _arr([3.0], device), _arr([0.4], device), _arr([2.0], device)],
              outputs=[out], device=device)
    np.testing.assert_allclose(out.numpy(), dahl_increment_ref(F, dx, 3.0, 0.4, 2.0), rtol=1e-12, atol=1e-14)
