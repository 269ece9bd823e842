"""Forward map of the quarter stitch (Dusserre 2015 eqs 6-9), float64 Warp.

``quarter_loop(a, beta, gamma, phi, P, B, d)`` takes the five unknowns as
:class:`~knitsim.kernels.elastica.Dual` numbers (``a = alpha - gamma`` rather than
alpha, so that a stays accurate when it falls to 1e-7 at high load) and returns
every quantity of :mod:`knitsim.cell.quantities` with its gradient, indexed by the
shared codes, plus the intrinsic residual g of eq 6 (third line).

Frame and signs follow model.md: X from the vertical through the apex C, Y up
from A; force -P (cos gamma, sin gamma) at A; contact force
R (sin(beta + phi), -cos(beta + phi)) at B.
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.quantities import (
    QUANTITY_NAMES,
    Q_ALPHA, Q_BETA, Q_GAMMA, Q_PHI, Q_P,
    Q_W, Q_C, Q_L, Q_S_AB, Q_S_BC, Q_X_A, Q_X_B, Q_Y_B, Q_Y_C,
    Q_T, Q_M, Q_R, Q_RN, Q_RT, Q_F,
)

from .elastica import (
    PI, Dual, vec5d, d_add, d_addc, d_const, d_cos, d_div, d_mul, d_neg, d_scale,
    d_sin, d_sqrt, d_sub, d_tan, dual, elastica_ab, elastica_bc_g0,
)

wp.set_module_options({"max_unroll": 1})

N_QUANTITIES = len(QUANTITY_NAMES)
vecQd = wp.types.vector(length=N_QUANTITIES, dtype=wp.float64)
matQ5d = wp.types.matrix(shape=(N_QUANTITIES, 5), dtype=wp.float64)


@wp.struct
class CellEval:
    """All quantities of one cell: values ``q[code]``, gradients ``dq[code]`` (rows),
    and the intrinsic residual ``g = X_B - X_A - (d/2) sin(beta)`` [mm] (eq 6) with
    its gradient ``dg``.  Gradients are with respect to the seeds of the inputs."""

    q: vecQd
    dq: matQ5d
    g: wp.float64
    dg: vec5d


@wp.func
def _put(q: vecQd, dq: matQ5d, code: int, x: Dual):
    q[code] = x.v
    dq[code] = x.g
    return q, dq


@wp.func
def force_per_wale(P: Dual, sg: Dual) -> Dual:
    """F = 2 P sin(gamma) (eq 7): the force per wale, carried by the two legs of a loop."""
    return d_scale(d_mul(P, sg), wp.float64(2.0))


@wp.func
def sin_gamma_of_rho(rho: Dual, cbp: Dual) -> Dual:
    """sin(gamma) = -(R/P) cos(beta + phi) (eq 7, R_Y = P sin gamma), from rho = R/P and cbp = cos(beta + phi)."""
    return d_neg(d_mul(rho, cbp))


@wp.func
def _assemble(a: Dual, beta: Dual, gamma: Dual, sg: Dual, cg: Dual, phi: Dual, P: Dual, k1p: Dual, R: Dual,
              g0: Dual, g0_given: int, B: wp.float64, d: wp.float64):
    """Eqs 6-9 from the unknowns plus sin/cos(gamma), k1' and R (eq 7).

    The one assembly of the quarter stitch; :func:`quarter_loop` (gamma given),
    :func:`quarter_loop_rho` (R/P given) and :func:`quarter_loop_g0` only differ in how they form
    sin(gamma), cos(gamma), k1' and R, and their gradients carry the chain rule
    of the chosen unknowns through.  With ``g0_given`` != 0, ``g0`` is G(0) = D + k1' (1 + cos beta)
    of elastica BC, passed to it instead of formed there (:func:`~knitsim.kernels.elastica.elastica_bc_g0`).
    """
    half = wp.float64(0.5)
    hd = half * d
    alpha = d_add(gamma, a)
    b = d_sub(beta, gamma)
    lam = d_sqrt(d_div(d_const(B), P))  # length scale sqrt(B/P)

    # elastica AB (eq 8), in the frame turned by gamma
    s_ab, x0, y0 = elastica_ab(a, b)
    s_ab = d_mul(lam, s_ab)
    x0 = d_mul(lam, x0)
    y0 = d_mul(lam, y0)
    dX_ab = d_sub(d_mul(x0, cg), d_mul(y0, sg))  # X_B - X_A (eq 8)
    Y_B = d_add(d_mul(x0, sg), d_mul(y0, cg))

    # equilibrium (eq 7)
    T = d_neg(d_mul(P, k1p))
    Rn = d_mul(R, d_cos(phi))
    Rt = d_mul(R, d_sin(phi))
    F = force_per_wale(P, sg)

    # elastica BC (eq 9); D = cos a - cos b = y0^2 / (2 lambda^2)
    D = d_scale(d_mul(d_sin(d_scale(d_add(b, a), half)), d_sin(d_scale(d_sub(b, a), half))), wp.float64(2.0))
    A0 = g0
    if g0_given == 0:
        A0 = d_add(D, d_mul(k1p, d_addc(d_cos(beta), wp.float64(1.0))))  # G(0)
    s_bc, xb, dy, thc = elastica_bc_g0(D, k1p, beta, A0)
    s_bc = d_mul(lam, s_bc)
    X_B = d_mul(lam, xb)
    Y_C = d_add(Y_B, d_mul(lam, dy))
    M = d_mul(P, d_add(y0, d_mul(k1p, d_sub(Y_C, Y_B))))  # eq 7

    # geometry (eq 6)
    sb = d_sin(beta)
    X_A = d_sub(X_B, dX_ab)
    W = d_scale(d_sub(X_B, d_scale(sb, hd)), wp.float64(4.0))
    C = d_scale(d_add(Y_B, d_scale(d_cos(beta), hd)), wp.float64(2.0))
    L = d_scale(d_add(s_ab, s_bc), wp.float64(4.0))
    g = d_sub(dX_ab, d_scale(sb, hd))

    q = vecQd()
    dq = matQ5d()
    q, dq = _put(q, dq, Q_ALPHA, alpha)
    q, dq = _put(q, dq, Q_BETA, beta)
    q, dq = _put(q, dq, Q_GAMMA, gamma)
    q, dq = _put(q, dq, Q_PHI, phi)
    q, dq = _put(q, dq, Q_P, P)
    q, dq = _put(q, dq, Q_W, W)
    q, dq = _put(q, dq, Q_C, C)
    q, dq = _put(q, dq, Q_L, L)
    q, dq = _put(q, dq, Q_S_AB, s_ab)
    q, dq = _put(q, dq, Q_S_BC, s_bc)
    q, dq = _put(q, dq, Q_X_A, X_A)
    q, dq = _put(q, dq, Q_X_B, X_B)
    q, dq = _put(q, dq, Q_Y_B, Y_B)
    q, dq = _put(q, dq, Q_Y_C, Y_C)
    q, dq = _put(q, dq, Q_T, T)
    q, dq = _put(q, dq, Q_M, M)
    q, dq = _put(q, dq, Q_R, R)
    q, dq = _put(q, dq, Q_RN, Rn)
    q, dq = _put(q, dq, Q_RT, Rt)
    q, dq = _put(q, dq, Q_F, F)

    out = CellEval()
    out.q = q
    out.dq = dq
    out.g = g.v
    out.dg = g.g
    return out


@wp.func
def quarter_loop(a: Dual, beta: Dual, gamma: Dual, phi: Dual, P: Dual, B: wp.float64, d: wp.float64):
    """Quantities of the quarter stitch from (alpha - gamma, beta, gamma, phi, P).

    B: bending stiffness [N mm^2]; d: yarn diameter [mm].  Call only on an
    admissible state (:func:`admissible`).
    """
    cg = d_cos(gamma)
    sg = d_sin(gamma)
    bp = d_add(beta, phi)
    k1p = d_add(cg, d_mul(sg, d_tan(bp)))  # eq 7
    R = d_neg(d_div(d_mul(P, sg), d_cos(bp)))  # from R_Y = -R cos(beta + phi) = P sin(gamma)
    return _assemble(a, beta, gamma, sg, cg, phi, P, k1p, R, d_const(wp.float64(0.0)), 0, B, d)


@wp.func
def d_asin(a: Dual):
    return dual(wp.asin(a.v), a.g / wp.sqrt(wp.float64(1.0) - a.v * a.v))


@wp.func
def _assemble_rho(a: Dual, beta: Dual, rho: Dual, phi: Dual, P: Dual, g0: Dual, g0_given: int, B: wp.float64,
                  d: wp.float64):
    """gamma, k1' and R from rho = R/P (eq 7), then the shared assembly (G(0) given when ``g0_given``)."""
    bp = d_add(beta, phi)
    cbp = d_cos(bp)
    sbp = d_sin(bp)
    sg = sin_gamma_of_rho(rho, cbp)
    gamma = d_asin(sg)
    cg = d_cos(gamma)
    k1p = d_sub(cg, d_mul(rho, sbp))  # eq 7
    R = d_mul(P, rho)
    return _assemble(a, beta, gamma, sg, cg, phi, P, k1p, R, g0, g0_given, B, d)


@wp.func
def quarter_loop_rho(a: Dual, beta: Dual, rho: Dual, phi: Dual, P: Dual, B: wp.float64, d: wp.float64):
    """:func:`quarter_loop` with R/P = rho given instead of gamma (eqs 6-9).

    sin(gamma) = -rho cos(beta + phi), k1' = cos(gamma) - rho sin(beta + phi) and
    R = P rho (eq 7): no 0/0 where the contact force is horizontal at zero force
    per wale (beta + phi = pi/2, gamma = 0), a point the slack event and SF+
    from phi0 < 0 land on.  gamma = asin(sin gamma) carries the rho column of
    the gradients (chain rule) into the shared assembly.
    """
    return _assemble_rho(a, beta, rho, phi, P, d_const(wp.float64(0.0)), 0, B, d)


@wp.func
def quarter_loop_g0(a: Dual, beta: Dual, rho: Dual, phi: Dual, P: Dual, g0: Dual, B: wp.float64, d: wp.float64):
    """:func:`quarter_loop_rho` at a state whose G(0) = D + k1' (1 + cos beta) of elastica BC is known
    to full relative precision, ``g0`` (the cell Newton's chart ln G(0): rho = R/P was formed from it,
    :func:`knitsim.kernels.cell_step.rho_of_g0`); elastica BC reads it instead of forming it again by
    cancellation (:func:`~knitsim.kernels.elastica.elastica_bc_g0`).  Same equations."""
    return _assemble_rho(a, beta, rho, phi, P, g0, 1, B, d)


@wp.func
def quantity(cell: CellEval, code: int):
    """Quantity ``code`` (see knitsim.cell.quantities) of an evaluated cell, as a Dual."""
    return dual(cell.q[code], cell.dq[code])


@wp.func
def admissible(a: wp.float64, beta: wp.float64, gamma: wp.float64, phi: wp.float64, P: wp.float64) -> wp.bool:
    """Whether the integrals of eqs 8-9 exist and are accurate for this state.

    0 < alpha - gamma < beta - gamma < pi (theta increases on AB, theta'_B > 0),
    beta < pi (BC not empty), P > 0, |phi| < pi/2, cos(beta + phi) != 0 (R finite),
    and G(0) = (theta'_C lambda)^2 / 2 > 0 (theta' does not vanish on BC).
    """
    if not (wp.isfinite(a) and wp.isfinite(beta) and wp.isfinite(gamma) and wp.isfinite(phi) and wp.isfinite(P)):
        return False
    b = beta - gamma
    if not (a > wp.float64(0.0) and b > a and b < PI and beta < PI and P > wp.float64(0.0)):
        return False
    if not (wp.abs(phi) < wp.float64(0.5) * PI):
        return False
    cbp = wp.cos(beta + phi)
    if not (wp.abs(cbp) > wp.float64(1.0e-12)):
        return False
    k1p = wp.cos(gamma) + wp.sin(gamma) * wp.tan(beta + phi)
    D = wp.float64(2.0) * wp.sin(wp.float64(0.5) * (b + a)) * wp.sin(wp.float64(0.5) * (b - a))
    A0 = D + k1p * (wp.float64(1.0) + wp.cos(beta))
    return A0 > wp.float64(1.0e-12)
