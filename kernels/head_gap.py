"""Distance between the heads of neighbouring loops of a course, float64 Warp (jamming by contact).

Device twin of :mod:`knitsim.cell.head_gap` (its docstring derives the result):
the centreline distance between the heads of neighbouring loops of a course is
``W - 2 X_max``, X_max the largest abscissa of the quarter loop A -> B -> C,
reached where the tangent is vertical (theta = pi/2):

- alpha < pi/2 < beta: on AB, eq 8 from A to theta = pi/2, i.e. the AB
  integrals with ``b = pi/2 - gamma`` in the frame turned by gamma;
- beta <= pi/2: on BC, eq 9 from theta = pi/2 to C, whose first integral there
  is ``D(pi/2) = D + k1' cos(beta)`` (D = cos a - cos b, the value at B);
- alpha >= pi/2: X decreases from A on, X_max = X_A.

Everything is a :class:`~knitsim.kernels.elastica.Dual`, so the gap can be an
imposed condition of the per-cell Newton (the head-gap jam and its located
event, :mod:`knitsim.kernels.cell_step`) as well as a checked quantity.
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.quantities import Q_ALPHA, Q_BETA, Q_GAMMA, Q_P, Q_T, Q_W, Q_X_A

from .elastica import (
    PI, Dual, d_add, d_const, d_cos, d_div, d_mul, d_neg, d_scale, d_sin, d_sqrt, d_sub, elastica_ab,
    elastica_bc,
)
from .quarter_loop import CellEval, quantity, vecQd

wp.set_module_options({"max_unroll": 1, "enable_backward": False})


@wp.func
def max_abscissa(a: Dual, alpha: Dual, beta: Dual, gamma: Dual, P: Dual, X_A: Dual, k1p: Dual,
                 B: wp.float64) -> Dual:
    """Largest abscissa X_max [mm] of the quarter loop (knitsim.cell.head_gap.max_abscissa).

    ``a = alpha - gamma`` at full precision (it falls to 1e-7 at high load)."""
    half_pi = wp.float64(0.5) * PI
    half = wp.float64(0.5)
    lam = d_sqrt(d_div(d_const(B), P))
    out = X_A
    if alpha.v < half_pi and beta.v > half_pi:
        # vertical tangent on AB: eq 8 from A to theta = pi/2
        s, x0, y0 = elastica_ab(a, d_sub(d_const(half_pi), gamma))
        out = d_add(X_A, d_mul(lam, d_sub(d_mul(x0, d_cos(gamma)), d_mul(y0, d_sin(gamma)))))
    elif beta.v <= half_pi:
        # vertical tangent on BC: eq 9 from theta = pi/2 to C
        b = d_sub(beta, gamma)
        D = d_scale(d_mul(d_sin(d_scale(d_add(b, a), half)), d_sin(d_scale(d_sub(b, a), half))), wp.float64(2.0))
        s, xh, dy, thc = elastica_bc(d_add(D, d_mul(k1p, d_cos(beta))), k1p, d_const(half_pi))
        out = d_mul(lam, xh)
    return out


@wp.func
def head_gap_dual(cell: CellEval, a: Dual, B: wp.float64) -> Dual:
    """``W - 2 X_max`` of an evaluated cell, with its gradient (the seeds of ``cell``)."""
    P = quantity(cell, Q_P)
    k1p = d_neg(d_div(quantity(cell, Q_T), P))  # T = -P k1' (eq 7)
    xm = max_abscissa(a, quantity(cell, Q_ALPHA), quantity(cell, Q_BETA), quantity(cell, Q_GAMMA), P,
                      quantity(cell, Q_X_A), k1p, B)
    return d_sub(quantity(cell, Q_W), d_scale(xm, wp.float64(2.0)))


@wp.func
def head_gap_value(a: wp.float64, q: vecQd, B: wp.float64) -> wp.float64:
    """``W - 2 X_max`` [mm] of a solved state: its quantities ``q`` and ``a = alpha - gamma``."""
    P = d_const(q[Q_P])
    k1p = d_const(-q[Q_T] / q[Q_P])
    xm = max_abscissa(d_const(a), d_const(q[Q_ALPHA]), d_const(q[Q_BETA]), d_const(q[Q_GAMMA]), P,
                      d_const(q[Q_X_A]), k1p, B)
    return q[Q_W] - wp.float64(2.0) * xm.v


@wp.kernel
def head_gap_kernel(a: wp.array(dtype=wp.float64), q: wp.array2d(dtype=wp.float64), B: wp.array(dtype=wp.float64),
                    out: wp.array(dtype=wp.float64)):
    """Head gap of N solved states (rows of q, ``a = alpha - gamma``); test/diagnostic kernel."""
    i = wp.tid()
    qi = vecQd()
    for k in range(q.shape[1]):
        qi[k] = q[i, k]
    out[i] = head_gap_value(a[i], qi, B[i % B.shape[0]])
