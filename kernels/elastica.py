"""Elastica integrals of the quarter stitch (Dusserre 2015 eqs 8-9), float64 Warp.

Device building blocks only; the Python side is :mod:`knitsim.cell.warp_solve`.

Forward-mode derivatives
------------------------
Every quantity is carried as a :class:`Dual`: a value and its gradient with
respect to five seeds (the unknowns of the inverse solve).  The quadrature rules
below are fixed, so the gradient is the exact derivative of the discrete rule
(nodes that move with the parameters included); no finite differences anywhere.

Dimensionless integrals
-----------------------
Lengths scale with ``lambda = sqrt(B/P)`` (model.md, "Elastica"): the angles fix
the shape, P its size.  All integrals here are in units of ``lambda``.

AB (eq 8): ``B theta'' = P sin(theta - gamma)``, ``theta'(A) = 0``, so with
``q = theta - gamma`` running from ``a = alpha - gamma`` to ``b = beta - gamma``,
``theta'^2 = (2P/B) (cos a - cos q)`` and ``ds = lambda dq / sqrt(2 (cos a - cos q))``.
The 1/sqrt singularity at A is removed by ``cos(q/2) = cos(a/2) sin(psi)``
(model.md), which turns eq 8 into Legendre's form with modulus ``k = cos(a/2)``::

    s_AB  = lambda * int dpsi / Delta,          Delta^2 = 1 - k^2 sin^2 psi
    x0_AB = lambda * int (1/Delta - 2 Delta) dpsi        (cos q = 1 - 2 Delta^2)
    y0_AB = lambda * sqrt(2 (cos a - cos b)) = (B/P) theta'_B       (closed form)

With ``t = pi/2 - psi`` (t = 0 at A), ``Delta^2 = sin^2 t + k'^2 cos^2 t`` and
``k' = sin(a/2)``.  At high load ``a -> 0`` and ``1/Delta`` peaks on a width k'
next to A: the interval is split at ``t1 = min(t_B, 0.5)`` and the near-A piece
is graded by ``tan t = k' sinh(u)``, which makes it ``int du / sqrt(1 + k'^2 sinh^2 u)``
(smooth, bounded by 1, range ``ln(2 tan t1 / k')``), integrated by panels of
Gauss-Legendre nodes, as many as the range needs; the far piece ``[t1, t_B]``
is regular (one rule) and empty when ``t_B <= t1``.

BC (eq 9, with model.md's sign: theta' continuous at B): with ``u = pi - theta``,
``theta'^2 = (2P/B) G(u)``, ``G = D + k1' (cos beta + cos u)``, ``D = cos a - cos b``,
u from 0 (C) to ``pi - beta`` (B).  ``G(pi - beta) = D > 0`` and, for ``k1' > 0``,
G is smallest at B: the integrand has a near 1/sqrt singularity at B when D is
small.  ``sin(u/2) = sqrt(m) sin(chi)``, ``m = G(0) / (2 k1')`` makes
``G = G(0) cos^2 chi`` and ``du / sqrt(2G) = dchi / (sqrt(k1') cos(u/2))``: regular for
any D (one rule).  For ``k1' < 0`` (T > 0, met at high load) G is smallest at C
and G(0) -> 0 as the load grows: ``sin(u/2) = c sinh(rho)``, ``c^2 = G(0) / (2|k1'|)``
grades toward C like the near-A piece of AB (same panels).  For
``|k1'| <= 1e-6 G(0)`` (G nearly constant) ``u = (pi - beta)(1 - cos v)/2`` is used.
Closed forms: ``theta'_C lambda = sqrt(2 G(0))``,
``(Y_C - Y_B)/lambda = 2 (1 + cos beta) / (sqrt(2 G(0)) + sqrt(2 D))``.
"""
from __future__ import annotations

import numpy as np
import warp as wp

wp.set_module_options({"max_unroll": 1})

vec5d = wp.types.vector(length=5, dtype=wp.float64)

# ---------------------------------------------------------------- node tables
#: Gauss-Legendre orders (see module docstring).  Chosen by a sweep over
#: ~10^4 states of load cycles and monotonic stretches to P = 12 N, a - 1e-8
#: (benchmarks/bench_kernels.py): these reach 1e-14 relative (values) and 2e-12
#: (Jacobian) against the former fixed 4 x 16 + 16 / 24 / 4 x 16 rules, which
#: tests/kernels/test_elastica_kernels.py checks against quad and Carlson forms.
#: The graded ranges (AB near A, BC for k1' < 0) get one panel of N_GL_NEAR
#: nodes per NEAR_PANEL_WIDTH_U of the graded variable (1 to N_NEAR_PANELS):
#: realistic loads need one panel, a -> 1e-8 needs 9 (range ln(2 tan t1 / k')).
N_NEAR_PANELS = 12
NEAR_PANEL_WIDTH_U = 2.0
N_GL_NEAR = 14
N_GL_FAR = 8
N_GL_BC = 12
#: split point of AB (in t = pi/2 - psi) between the graded and the plain piece
T_SPLIT = 0.5


def _gl01(n: int, panels: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre nodes and weights on [0, 1] (weights sum to 1)."""
    x, w = np.polynomial.legendre.leggauss(n)
    xs = np.concatenate([(j + 0.5 * (1.0 + x)) / panels for j in range(panels)])
    ws = np.concatenate([0.5 * w / panels for _ in range(panels)])
    return xs, ws


def _vec_const(values: np.ndarray):
    return wp.constant(wp.types.vector(length=len(values), dtype=wp.float64)(*[float(v) for v in values]))


_xn, _wn = _gl01(N_GL_NEAR)
_xf, _wf = _gl01(N_GL_FAR)
_xb, _wb = _gl01(N_GL_BC)
GL_NEAR_X = _vec_const(_xn)
GL_NEAR_W = _vec_const(_wn)
GL_FAR_X = _vec_const(_xf)
GL_FAR_W = _vec_const(_wf)
GL_BC_X = _vec_const(_xb)
GL_BC_W = _vec_const(_wb)
N_NEAR_PANELS_MAX = wp.constant(N_NEAR_PANELS)
N_NEAR_NODES = wp.constant(N_GL_NEAR)
NEAR_PANEL_WIDTH = wp.constant(wp.float64(NEAR_PANEL_WIDTH_U))
N_FAR = wp.constant(N_GL_FAR)
N_BC = wp.constant(N_GL_BC)
T1 = wp.constant(wp.float64(T_SPLIT))
TAN_T1 = wp.constant(wp.float64(np.tan(T_SPLIT)))
PI = wp.constant(wp.float64(np.pi))
K1_GRADED_MIN = wp.constant(wp.float64(1.0e-6))


# ---------------------------------------------------------------- dual numbers
@wp.struct
class Dual:
    """A float64 value and its gradient with respect to five seeds."""

    v: wp.float64
    g: vec5d


@wp.func
def dual(v: wp.float64, g: vec5d):
    r = Dual()
    r.v = v
    r.g = g
    return r


@wp.func
def d_const(v: wp.float64):
    return dual(v, vec5d())


@wp.func
def d_seed(v: wp.float64, k: int):
    """The k-th independent variable, value v."""
    g = vec5d()
    g[k] = wp.float64(1.0)
    return dual(v, g)


@wp.func
def d_add(a: Dual, b: Dual):
    return dual(a.v + b.v, a.g + b.g)


@wp.func
def d_sub(a: Dual, b: Dual):
    return dual(a.v - b.v, a.g - b.g)


@wp.func
def d_neg(a: Dual):
    return dual(-a.v, -a.g)


@wp.func
def d_addc(a: Dual, c: wp.float64):
    return dual(a.v + c, a.g)


@wp.func
def d_scale(a: Dual, c: wp.float64):
    return dual(a.v * c, a.g * c)


@wp.func
def d_mul(a: Dual, b: Dual):
    return dual(a.v * b.v, a.g * b.v + b.g * a.v)


@wp.func
def d_div(a: Dual, b: Dual):
    q = a.v / b.v
    return dual(q, (a.g - b.g * q) / b.v)


@wp.func
def d_inv(a: Dual):
    q = wp.float64(1.0) / a.v
    return dual(q, a.g * (-q * q))


@wp.func
def d_sqrt(a: Dual):
    r = wp.sqrt(a.v)
    return dual(r, a.g * (wp.float64(0.5) / r))


@wp.func
def d_sin(a: Dual):
    return dual(wp.sin(a.v), a.g * wp.cos(a.v))


@wp.func
def d_cos(a: Dual):
    return dual(wp.cos(a.v), a.g * (-wp.sin(a.v)))


@wp.func
def d_tan(a: Dual):
    t = wp.tan(a.v)
    return dual(t, a.g * (wp.float64(1.0) + t * t))


@wp.func
def d_exp(a: Dual):
    e = wp.exp(a.v)
    return dual(e, a.g * e)


@wp.func
def d_log(a: Dual):
    return dual(wp.log(a.v), a.g / a.v)


@wp.func
def d_sinh(a: Dual):
    return dual(wp.sinh(a.v), a.g * wp.cosh(a.v))


@wp.func
def d_cosh(a: Dual):
    return dual(wp.cosh(a.v), a.g * wp.sinh(a.v))


@wp.func
def d_asinh(a: Dual):
    # asinh(x) = log(x + sqrt(1 + x^2)), written for x >= 0 (all uses here)
    x = a.v
    s = wp.sqrt(wp.float64(1.0) + x * x)
    return dual(wp.log(x + s), a.g / s)


@wp.func
def d_atan2(y: Dual, x: Dual):
    r2 = x.v * x.v + y.v * y.v
    return dual(wp.atan2(y.v, x.v), (y.g * x.v - x.g * y.v) / r2)


# ---------------------------------------------------------------- eq 8 (AB)
# The node loops below differentiate by hand: every node depends on only two or
# three parameters of its piece (range and modulus), so each loop accumulates a
# few scalar sums (integrand and its partials) and the 5-seed gradient is
# assembled once per piece by the chain rule.  This is the same exact derivative
# of the same discrete rule as carrying Duals through the loop, at a fraction of
# the cost (no 5-vectors per node, one exp for sinh and cosh, one sin/cos pair).
@wp.func
def near_panels(U: wp.float64) -> int:
    """Panels of a graded range of length U: one per NEAR_PANEL_WIDTH, 1..N_NEAR_PANELS."""
    n = wp.min(wp.float64(N_NEAR_PANELS_MAX), wp.ceil(U / NEAR_PANEL_WIDTH))
    return wp.max(1, int(n))


@wp.func
def _ab_near(U: Dual, kp: Dual):
    """Graded near-A piece: ``int_0^U {1, k'^2 cosh^2 u h^2} h du``, ``h = 1/sqrt(1 + k'^2 sinh^2 u)``.

    Returns (int dt / Delta, int Delta dt) over t in [0, t1] (tan t1 = k' sinh U).
    Panels: one per NEAR_PANEL_WIDTH of U (at most N_NEAR_PANELS), N_GL_NEAR nodes each."""
    one = wp.float64(1.0)
    k = kp.v
    k2 = k * k
    Uv = U.v
    npan = near_panels(Uv)
    inv_np = one / wp.float64(npan)
    a0 = wp.float64(0.0)  # sum w h
    a1 = wp.float64(0.0)  # sum w x dh/du
    a2 = wp.float64(0.0)  # sum w dh/dk'
    b0 = wp.float64(0.0)  # the same for f = k'^2 cosh^2 u h^3
    b1 = wp.float64(0.0)
    b2 = wp.float64(0.0)
    for p in range(npan):
        for j in range(N_NEAR_NODES):
            x = (wp.float64(p) + GL_NEAR_X[j]) * inv_np
            w = GL_NEAR_W[j] * inv_np
            e = wp.exp(Uv * x)
            ei = one / e
            sh = wp.float64(0.5) * (e - ei)
            ch = wp.float64(0.5) * (e + ei)
            h = one / wp.sqrt(one + k2 * sh * sh)
            h2 = h * h
            h3 = h2 * h
            h_u = -k2 * sh * ch * h3
            h_k = -k * sh * sh * h3
            ch2 = ch * ch
            f = k2 * ch2 * h3
            f_u = k2 * (wp.float64(2.0) * ch * sh * h3 + wp.float64(3.0) * ch2 * h2 * h_u)
            f_k = wp.float64(2.0) * k * ch2 * h3 + wp.float64(3.0) * k2 * ch2 * h2 * h_k
            a0 += w * h
            a1 += w * x * h_u
            a2 += w * h_k
            b0 += w * f
            b1 += w * x * f_u
            b2 += w * f_k
    I1 = dual(Uv * a0, U.g * (a0 + Uv * a1) + kp.g * (Uv * a2))
    I2 = dual(Uv * b0, U.g * (b0 + Uv * b1) + kp.g * (Uv * b2))
    return I1, I2


@wp.func
def _ab_far(t1: Dual, span: Dual, kp2: Dual):
    """Plain piece ``t in [t1, t1 + span]``: (int dt / Delta, int Delta dt),
    ``Delta^2 = sin^2 t + k'^2 cos^2 t``."""
    one = wp.float64(1.0)
    k2 = kp2.v
    sp = span.v
    a0 = wp.float64(0.0)
    a1 = wp.float64(0.0)  # sum w dDelta/dt / Delta^2
    a2 = wp.float64(0.0)  # sum w x dDelta/dt / Delta^2
    a3 = wp.float64(0.0)  # sum w dDelta/dk'^2 / Delta^2
    b0 = wp.float64(0.0)
    b1 = wp.float64(0.0)
    b2 = wp.float64(0.0)
    b3 = wp.float64(0.0)
    for j in range(N_GL_FAR):
        x = GL_FAR_X[j]
        w = GL_FAR_W[j]
        t = t1.v + sp * x
        st = wp.sin(t)
        ct = wp.cos(t)
        dl = wp.sqrt(st * st + k2 * ct * ct)
        idl = one / dl
        d_t = st * ct * (one - k2) * idl
        d_k = wp.float64(0.5) * ct * ct * idl
        i2 = idl * idl
        a0 += w * idl
        a1 += w * d_t * i2
        a2 += w * x * d_t * i2
        a3 += w * d_k * i2
        b0 += w * dl
        b1 += w * d_t
        b2 += w * x * d_t
        b3 += w * d_k
    I1 = dual(sp * a0, span.g * (a0 - sp * a2) - (t1.g * a1 + kp2.g * a3) * sp)
    I2 = dual(sp * b0, span.g * (b0 + sp * b2) + (t1.g * b1 + kp2.g * b3) * sp)
    return I1, I2


@wp.func
def elastica_ab(a: Dual, b: Dual):
    """AB integrals of eq 8 in units of sqrt(B/P).

    Parameters: ``a = alpha - gamma`` (> 0), ``b = beta - gamma`` (a < b < pi).
    Returns ``(s_AB, x0_AB, y0_AB)``: arc length and the chord A->B in the frame
    turned by gamma (x0 along (cos gamma, sin gamma)).
    """
    half = wp.float64(0.5)
    kp = d_sin(d_scale(a, half))  # k' = sin(a/2), accurate for tiny a
    kp2 = d_mul(kp, kp)
    # cos a - cos q = 2 sin((q+a)/2) sin((q-a)/2): no cancellation near A
    S = d_sqrt(d_mul(d_sin(d_scale(d_add(b, a), half)), d_sin(d_scale(d_sub(b, a), half))))
    cb = d_cos(d_scale(b, half))
    tb = d_atan2(S, cb)  # t_B = pi/2 - psi_B
    y0 = d_scale(S, wp.float64(2.0))

    # near-A piece, t in [0, t1], graded by tan t = k' sinh u
    t1 = tb
    tan_t1 = d_div(S, cb)
    far = tb.v > T1
    if far:
        t1 = d_const(T1)
        tan_t1 = d_const(TAN_T1)
    U = d_asinh(d_div(tan_t1, kp))
    I1, I2 = _ab_near(U, kp)

    # far piece, t in [t1, t_B]: Delta >= sin(t1), regular (empty when t_B <= t1)
    if far:
        F1, F2 = _ab_far(t1, d_sub(tb, t1), kp2)
        I1 = d_add(I1, F1)
        I2 = d_add(I2, F2)

    s = I1
    x0 = d_sub(I1, d_scale(I2, wp.float64(2.0)))
    return s, x0, y0


# ---------------------------------------------------------------- eq 9 (BC)
@wp.func
def _bc_graded(E: Dual, c: Dual, hyperbolic: wp.bool):
    """``int_0^E {1, 1 - 2 su^2} / sqrt(1 - su^2) dv`` with ``su = c sin v`` (or
    ``c sinh v`` when hyperbolic): the two graded branches of BC (su = sin(u/2)).
    Panels as :func:`_ab_near` in the hyperbolic case, one panel of N_GL_BC otherwise."""
    one = wp.float64(1.0)
    two = wp.float64(2.0)
    Ev = E.v
    cv = c.v
    npan = int(1)
    nn = int(N_GL_BC)
    if hyperbolic:
        npan = near_panels(Ev)
        nn = int(N_NEAR_NODES)
    inv_np = one / wp.float64(npan)
    a0 = wp.float64(0.0)
    a1 = wp.float64(0.0)  # sum w x dh/dsu dsu/dv
    a2 = wp.float64(0.0)  # sum w dh/dsu dsu/dc
    b0 = wp.float64(0.0)
    b1 = wp.float64(0.0)
    b2 = wp.float64(0.0)
    for p in range(npan):
        for j in range(nn):
            x = wp.float64(0.0)
            w = wp.float64(0.0)
            if hyperbolic:
                x = (wp.float64(p) + GL_NEAR_X[j]) * inv_np
                w = GL_NEAR_W[j] * inv_np
            else:
                x = GL_BC_X[j]
                w = GL_BC_W[j]
            v = Ev * x
            s = wp.float64(0.0)
            cs = wp.float64(0.0)
            if hyperbolic:
                e = wp.exp(v)
                ei = one / e
                s = wp.float64(0.5) * (e - ei)
                cs = wp.float64(0.5) * (e + ei)
            else:
                s = wp.sin(v)
                cs = wp.cos(v)
            su = cv * s
            su2 = su * su
            h = one / wp.sqrt(one - su2)
            g1 = su * h * h * h  # dh/dsu
            m2 = one - two * su2
            f2 = h * m2
            g2 = g1 * m2 - wp.float64(4.0) * su * h
            a0 += w * h
            a1 += w * x * g1 * cs
            a2 += w * g1 * s
            b0 += w * f2
            b1 += w * x * g2 * cs
            b2 += w * g2 * s
    I1 = dual(Ev * a0, E.g * (a0 + Ev * cv * a1) + c.g * (Ev * a2))
    I2 = dual(Ev * b0, E.g * (b0 + Ev * cv * b1) + c.g * (Ev * b2))
    return I1, I2


@wp.func
def elastica_bc(D: Dual, k1p: Dual, beta: Dual):
    """BC integrals of eq 9 (theta' continuous at B) in units of sqrt(B/P).

    Parameters: ``D = cos a - cos b`` (> 0, = (theta'_B lambda)^2 / 2),
    ``k1p = k1'`` of eq 7, ``beta``; requires ``G(0) = D + k1' (1 + cos beta) > 0``.
    Returns ``(s_BC, X_B, Y_C - Y_B, theta'_C)``, lengths in lambda, theta'_C in 1/lambda;
    X_B = X_B - X_C with X_C = 0 (the symmetry axis through C).
    """
    A0 = d_add(D, d_mul(k1p, d_addc(d_cos(beta), wp.float64(1.0))))  # G(0)
    s, xb, dy, thc = elastica_bc_g0(D, k1p, beta, A0)
    return s, xb, dy, thc


@wp.func
def elastica_bc_g0(D: Dual, k1p: Dual, beta: Dual, A0: Dual):
    """:func:`elastica_bc` with ``A0 = G(0) = D + k1' (1 + cos beta)`` given by the caller.

    G(0) is a difference of O(1) terms: formed from D, k1' and beta it carries an absolute
    rounding of ~1e-16, i.e. a relative error 1e-16 / G(0), and the BC integrals go as
    ln G(0) where k1' < 0 (the near-straight stretch at C).  The cell Newton's chart with
    ln G(0) as a variable (kernels.cell_step.newton) passes G(0) = exp(ln G(0)) itself, so
    that the integrals, and the residuals built on them, are as smooth as the chart
    (at G(0) ~ 1e-7 the recomputed value made the residuals of L jitter by ~1e-9 of d,
    above the Newton's stall tolerance: issue 14).
    """
    one = wp.float64(1.0)
    half = wp.float64(0.5)
    two = wp.float64(2.0)
    cbeta = d_cos(beta)
    I1 = d_const(wp.float64(0.0))  # int du / sqrt(2G)
    I2 = d_const(wp.float64(0.0))  # int cos u du / sqrt(2G)
    if k1p.v > K1_GRADED_MIN * A0.v:
        # sin(u/2) = sqrt(m) sin chi: G = G(0) cos^2 chi, regular for any D
        cbh = d_cos(d_scale(beta, half))  # sin(u_B/2)
        chi_end = d_atan2(d_mul(cbh, d_sqrt(d_scale(k1p, two))), d_sqrt(D))
        sm = d_sqrt(d_div(A0, d_scale(k1p, two)))
        I1, I2 = _bc_graded(chi_end, sm, False)
        r = d_inv(d_sqrt(k1p))
        I1 = d_mul(I1, r)
        I2 = d_mul(I2, r)
    elif k1p.v < -K1_GRADED_MIN * A0.v:
        # k1' < 0: G = G(0) + 2|k1'| sin^2(u/2) is smallest at C, and G(0) -> 0 at
        # high load; sin(u/2) = c sinh(rho), c^2 = G(0)/(2|k1'|), makes
        # G = G(0) cosh^2 rho and du / sqrt(2G) = drho / (sqrt(|k1'|) cos(u/2))
        nk = d_neg(k1p)
        c = d_sqrt(d_div(A0, d_scale(nk, two)))
        rho_end = d_asinh(d_div(d_cos(d_scale(beta, half)), c))
        I1, I2 = _bc_graded(rho_end, c, True)
        r = d_inv(d_sqrt(nk))
        I1 = d_mul(I1, r)
        I2 = d_mul(I2, r)
    else:
        # u = u_B (1 - cos v)/2, v in [0, pi]: removes 1/sqrt at either end
        uB = d_sub(d_const(PI), beta)
        for j in range(N_BC):
            v = PI * GL_BC_X[j]
            wt = d_scale(uB, half * PI * GL_BC_W[j] * wp.sin(v))
            u = d_scale(uB, half * (one - wp.cos(v)))
            G = d_add(D, d_mul(k1p, d_add(cbeta, d_cos(u))))
            h = d_inv(d_sqrt(d_scale(G, two)))
            I1 = d_add(I1, d_mul(wt, h))
            I2 = d_add(I2, d_mul(wt, d_mul(h, d_cos(u))))
    thC = d_sqrt(d_scale(A0, two))
    thB = d_sqrt(d_scale(D, two))
    dY = d_div(d_scale(d_addc(cbeta, one), two), d_add(thC, thB))
    return I1, I2, dY, thC


# ---------------------------------------------------------------- test/diagnostic kernels
@wp.kernel
def ab_integrals_kernel(
    a: wp.array(dtype=wp.float64),
    b: wp.array(dtype=wp.float64),
    out: wp.array2d(dtype=wp.float64),
):
    """(s_AB, x0_AB, y0_AB) / sqrt(B/P) for each (a, b); shape [N], [N] -> [N, 3]."""
    i = wp.tid()
    s, x0, y0 = elastica_ab(d_const(a[i]), d_const(b[i]))
    out[i, 0] = s.v
    out[i, 1] = x0.v
    out[i, 2] = y0.v


@wp.kernel
def bc_integrals_kernel(
    D: wp.array(dtype=wp.float64),
    k1p: wp.array(dtype=wp.float64),
    beta: wp.array(dtype=wp.float64),
    out: wp.array2d(dtype=wp.float64),
):
    """(s_BC, X_B, Y_C - Y_B, theta'_C) in units of sqrt(B/P); shape [N] x3 -> [N, 4]."""
    i = wp.tid()
    s, xb, dy, thc = elastica_bc(d_const(D[i]), d_const(k1p[i]), d_const(beta[i]))
    out[i, 0] = s.v
    out[i, 1] = xb.v
    out[i, 2] = dy.v
    out[i, 3] = thc.v
