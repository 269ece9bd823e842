"""Warp twin of the Dahl (1976) increment update (float64).

The float64 NumPy reference, with the derivation of the closed forms, is
:func:`knitsim.friction.dahl.dahl_increment`; tests check that these functions
equal it.  At a yarn crossing call them with ``F = tan(phi)``, ``dx = d xi``,
``Fc = m`` and ``sigma`` = the crossing's friction stiffness.

The ``@wp.func`` building blocks:

* :func:`dahl_alpha1_dual`: eq 1 with alpha = 1 (the paper's value),
  ``F_new = s Fc + (F - s Fc) exp(-sigma |dx| / Fc)``, as a dual number in the slip: the one
  place of this law, which the cell's Newton solves as a residual
  (``cell_step.dahl_residual``) and the bending hysteresis reads with ``Fc = 1``
  (``effects.dahl_bending_state``);
* :func:`dahl_increment_alpha1`: the same at a value (bit for bit the closed form written out);
* :func:`dahl_increment`: any alpha > 0 (separable closed form).

:func:`dahl_increment_kernel` evaluates the general update over arrays; every
parameter array has a leading batch axis of length 1 or N, read as
``a[i % a.shape[0]]``.
"""
from __future__ import annotations

import warp as wp

from .elastica import Dual, d_addc, d_const, d_div, d_exp, d_scale


@wp.func
def _log1p(x: wp.float64):
    # log(1 + x) without cancellation for small x (Goldberg's trick), so that
    # alpha close to 1 keeps full accuracy, as np.log1p does in the reference.
    u = wp.float64(1.0) + x
    if u == wp.float64(1.0):
        return x
    return wp.log(u) * x / (u - wp.float64(1.0))


@wp.func
def dahl_alpha1_dual(F: wp.float64, dx: Dual, s: wp.float64, sigma: wp.float64, Fc: wp.float64):
    """Eq 1 with alpha = 1 integrated over a slip ``dx`` of sign ``s`` (``s dx = |dx|``), as a Dual in the
    slip: ``F_new = s Fc + (F - s Fc) exp(-sigma |dx| / Fc)``.  The one law of the Dahl update: the cell's
    Newton solves its residual at the slip of the solution itself (``cell_step.dahl_residual``, with the
    predicted slip direction ``s``), :func:`dahl_increment_alpha1` takes it at a value, and the bending
    hysteresis (``effects.dahl_bending_state``) with ``Fc = 1``."""
    e = d_exp(d_div(d_scale(d_scale(dx, s), -sigma), d_const(Fc)))
    return d_addc(d_scale(e, F - s * Fc), s * Fc)


@wp.func
def dahl_increment_alpha1(F: wp.float64, dx: wp.float64, sigma: wp.float64, Fc: wp.float64):
    """Exact Dahl update over ``dx`` for alpha = 1 (eq 1 integrated): :func:`dahl_alpha1_dual` at a value,
    in the direction of the slip."""
    if dx == wp.float64(0.0):
        return F
    return dahl_alpha1_dual(F, d_const(dx), wp.sign(dx), sigma, Fc).v


@wp.func
def dahl_increment(F: wp.float64, dx: wp.float64, sigma: wp.float64, Fc: wp.float64, alpha: wp.float64):
    """Exact Dahl update over ``dx`` for any alpha > 0 (eq 1 integrated).

    ``u = 1 - s F/Fc`` evolves as ``u (1 + q)^(-1/(alpha-1))`` with
    ``q = (alpha-1) (sigma/Fc) |dx| |u|^(alpha-1)``; ``1 + q <= 0`` (alpha < 1)
    means saturation, ``u = 0``.
    """
    if dx == wp.float64(0.0):
        return F
    if alpha == wp.float64(1.0):
        return dahl_increment_alpha1(F, dx, sigma, Fc)
    s = wp.sign(dx)
    u = wp.float64(1.0) - s * F / Fc
    w = wp.abs(u)
    w_new = wp.float64(0.0)
    if w > wp.float64(0.0):
        am1 = alpha - wp.float64(1.0)
        q = am1 * (sigma / Fc) * wp.abs(dx) * wp.pow(w, am1)
        if q > wp.float64(-1.0):
            w_new = w * wp.exp(-_log1p(q) / am1)
    u_new = w_new
    if u < wp.float64(0.0):
        u_new = -w_new
    return s * Fc * (wp.float64(1.0) - u_new)


@wp.kernel
def dahl_increment_kernel(
    F_in: wp.array(dtype=wp.float64),
    dx: wp.array(dtype=wp.float64),
    sigma: wp.array(dtype=wp.float64),
    Fc: wp.array(dtype=wp.float64),
    alpha: wp.array(dtype=wp.float64),
    F_out: wp.array(dtype=wp.float64),
):
    """``F_out[i] = dahl_increment(F_in[i], dx[i], ...)``; inputs of length 1 or N broadcast."""
    i = wp.tid()
    F_out[i] = dahl_increment(
        F_in[i % F_in.shape[0]],
        dx[i % dx.shape[0]],
        sigma[i % sigma.shape[0]],
        Fc[i % Fc.shape[0]],
        alpha[i % alpha.shape[0]],
    )
