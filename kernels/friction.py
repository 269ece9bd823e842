"""Friction laws at a yarn crossing, Warp device code (float64).

Twins of the float64 references in :mod:`knitsim.friction`:

``howell_mu_k(b, p, n, V, Fn)``
    Eq 5, ``mu_k = b V^p Fn^(n-1)`` (twin of ``capstan.mu_k_eq5``).
``howell_tangential_load(b, p, n, V, Fn)``
    Eqs 2 and 5, ``Ft = a Fn^n`` with ``a = b V^p`` at one crossing
    (twin of ``capstan.tangential_load_eq2``).
``coiling_ratio_m(theta, mu_k)``
    Eq 10, ``m = (e^{mu theta} - 1)/(e^{mu theta} + 1) tan(theta/2)``
    (twin of ``coiling.m_eq10``).
``eval_friction_laws`` (kernel)
    Evaluates the three functions over arrays (used by the tests; parameters
    with a leading batch axis of 1 or N, read as ``x[i % x.shape[0]]``).

The Dahl update lives in :mod:`knitsim.kernels.dahl`.
Units: N, mm, s, rad.
"""
from __future__ import annotations

import warp as wp


@wp.func
def howell_mu_k(b: wp.float64, p: wp.float64, n: wp.float64, V: wp.float64, Fn: wp.float64) -> wp.float64:
    """Eq 5: kinetic friction coefficient ``b V^p Fn^(n-1)`` (V [mm/s], Fn [N])."""
    return b * wp.pow(V, p) * wp.pow(Fn, n - wp.float64(1.0))


@wp.func
def howell_tangential_load(b: wp.float64, p: wp.float64, n: wp.float64, V: wp.float64,
                           Fn: wp.float64) -> wp.float64:
    """Eqs 2, 5: tangential load ``a Fn^n`` at one crossing [N], ``a = b V^p``."""
    return b * wp.pow(V, p) * wp.pow(Fn, n)


@wp.func
def coiling_ratio_m(theta: wp.float64, mu_k: wp.float64) -> wp.float64:
    """Eq 10: apparent ratio m at a crossing with coiling angle ``theta`` [rad]."""
    e = wp.exp(mu_k * theta)
    return (e - wp.float64(1.0)) / (e + wp.float64(1.0)) * wp.tan(wp.float64(0.5) * theta)


@wp.kernel
def eval_friction_laws(
    b: wp.array(dtype=wp.float64),
    p: wp.array(dtype=wp.float64),
    n: wp.array(dtype=wp.float64),
    V: wp.array(dtype=wp.float64),
    Fn: wp.array(dtype=wp.float64),
    theta: wp.array(dtype=wp.float64),
    mu_k_in: wp.array(dtype=wp.float64),
    mu_k_out: wp.array(dtype=wp.float64),
    Ft_out: wp.array(dtype=wp.float64),
    m_out: wp.array(dtype=wp.float64),
):
    """Evaluate eq 5, eq 2 and eq 10 per element (inputs broadcast with ``i % shape[0]``)."""
    i = wp.tid()
    bi = b[i % b.shape[0]]
    pi = p[i % p.shape[0]]
    ni = n[i % n.shape[0]]
    vi = V[i % V.shape[0]]
    fi = Fn[i % Fn.shape[0]]
    mu_k_out[i] = howell_mu_k(bi, pi, ni, vi, fi)
    Ft_out[i] = howell_tangential_load(bi, pi, ni, vi, fi)
    m_out[i] = coiling_ratio_m(theta[i % theta.shape[0]], mu_k_in[i % mu_k_in.shape[0]])
