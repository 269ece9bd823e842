"""Distance between the heads of neighbouring loops of a course (jamming geometry).

Hong et al. (2002) and Dusserre (2015, Table 4) jam the knit at W = 4d, an
approximation of "the heads of neighbouring loops of a course touch".  The head
of a loop is the yarn from the inflection point A through B to the apex C and
on, mirrored about X = 0, to the other A (:func:`knitsim.cell.quarter_loop.centreline`).
The neighbouring loop of the same course is the same head shifted by W along
X (wale spacing).  For a point p of one head and the mirror image q' = (W - X_q,
Y_q) of a point q of the other half-head::

    |p - q'| >= |W - X_p - X_q| >= W - 2 X_max,

with equality for p = q at the largest abscissa X_max of the quarter loop: the
centreline distance between neighbouring heads is exactly ``W - 2 X_max``.  The
quarter loop bulges beyond A and B: theta runs from alpha at A through pi/2 (the
tangent is vertical where X is largest) to pi at C, so X_max is reached at
theta = pi/2, found in closed form from the elastica integrals of the sub-arc
(eq 8 from A to that point, or eq 9 from that point to C).

Loops *interpenetrate* when the gap is below the yarn diameter d.
"""
from __future__ import annotations

import numpy as np

from knitsim.cell import elastica
from knitsim.cell.quarter_loop import quarter_loop


def max_abscissa_of(st, B, *, a=None):
    """Largest abscissa X_max [mm] of solved quarter loops ``st`` (a :class:`QuarterLoop`).

    ``a`` is ``alpha - gamma`` at full precision (high load); from ``st`` when not given.
    NaN where the state is inadmissible.
    """
    alpha, beta, gamma = (np.asarray(z, float) for z in (st.alpha, st.beta, st.gamma))
    aa = (alpha - gamma) if a is None else np.broadcast_to(np.asarray(a, float), alpha.shape)
    lam = np.sqrt(B / np.asarray(st.P, float))
    half = 0.5 * np.pi
    # case 1: vertical tangent on AB (alpha < pi/2 < beta): eq 8 from A to theta = pi/2
    u_star = half - gamma
    on_ab = (alpha < half) & (beta > half)
    ub_ab = np.where(on_ab, u_star, np.maximum(beta - gamma, aa + 1e-3))
    _, x0, y0 = elastica.ab_integrals(np.where(on_ab, aa, 0.5), np.where(on_ab, ub_ab, 1.0))
    x_ab = st.X_A + lam * (x0 * np.cos(gamma) - y0 * np.sin(gamma))
    # case 2: vertical tangent on BC (beta <= pi/2): eq 9 from theta = pi/2 to C, whose
    # curvature there is D(pi/2) of the whole BC arc (v = pi - theta = pi/2)
    on_bc = beta <= half
    v_b = np.pi - beta
    delta = elastica.bc_delta(aa, beta - gamma)
    d_half = elastica.bc_D(half, v_b, delta, st.k1p)
    _, x_bc, _ = elastica.bc_integrals(np.full_like(beta, half), np.where(on_bc, d_half, 1.0),
                                       np.where(on_bc, st.k1p, 1.0))
    x_bc = lam * x_bc
    # case 3: alpha >= pi/2: X decreases from A on
    x_max = np.where(on_ab, x_ab, np.where(on_bc, x_bc, st.X_A))
    return np.where(st.admissible, x_max, np.nan)


def head_gap_of(st, B, *, a=None):
    """``W - 2 X_max`` [mm] of solved quarter loops ``st`` (see the module docstring)."""
    return st.W - 2.0 * max_abscissa_of(st, B, a=a)


def max_abscissa(alpha, beta, gamma, phi, P, B, d, *, a=None):
    """Largest abscissa X_max [mm] of the quarter loop A -> B -> C (scalar or arrays).

    Parameters
    ----------
    alpha, beta, gamma, phi, P : array_like
        State (rad, N); see :mod:`knitsim.cell.quantities`.
    B, d : float
        Bending stiffness [N mm^2] and yarn diameter [mm].
    a : array_like, optional
        ``alpha - gamma`` at full precision (high load).

    Returns
    -------
    ndarray
        X_max; NaN where the state is inadmissible.
    """
    return max_abscissa_of(quarter_loop(alpha, beta, gamma, phi, P, B, d, a=a), B, a=a)


def head_gap(alpha, beta, gamma, phi, P, B, d, *, a=None):
    """Centreline distance between the heads of neighbouring loops of a course [mm].

    ``W - 2 X_max`` (see the module docstring); W from eq 6.  Below d the loops
    interpenetrate.
    """
    return head_gap_of(quarter_loop(alpha, beta, gamma, phi, P, B, d, a=a), B, a=a)


def interpenetrating(gap, d) -> np.ndarray:
    """Whether neighbouring heads overlap: centreline gap below the yarn diameter."""
    return np.asarray(gap) < d
