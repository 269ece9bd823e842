"""Per-cell Newton solve of the quarter stitch (Dusserre 2015 section 3.3), float64 Warp.

Each cell solves five equations in the five unknowns (alpha, beta, gamma, phi, P):
the intrinsic condition g = X_B - X_A - (d/2) sin(beta) = 0 (eq 6, third line) and
four imposed conditions ``quantity[code_k] = target_k`` (Table 4).

Newton variables ``z = (ln(alpha - gamma), beta, gamma, phi, ln P)``: alpha - gamma
and P stay positive and keep their relative accuracy as alpha - gamma falls
toward 1e-7 at high load (model.md, numerical hints).  Residuals are scaled to
O(1): g and lengths by d, forces by B/d^2, the moment by B/d, angles by 1 rad.
The Jacobian is exact forward-mode (:class:`~knitsim.kernels.elastica.Dual`),
the 5x5 system is solved by Gauss elimination with partial pivoting, and the
step is damped (each |dz_i| <= 1) and backtracked (Armijo on |r|^2 / 2, also
halving out of inadmissible states).

Per-cell parameters have shape ``(1 or N, ...)`` and are read as
``p[i % p.shape[0]]``, so a sweep is a change of array shape.

Status codes: 0 converged (max |r_scaled| <= tol), 1 iteration cap reached or
line search stalled, 2 singular Jacobian, 3 non-finite residual or Jacobian,
4 left the admissible domain (or started outside it).  On failure the last
admissible iterate is returned (never NaN when the guess was finite).
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.quantities import Q_M, Q_P, Q_PHI, Q_T

from .elastica import d_exp, d_seed, d_sub, vec5d
from .quarter_loop import N_QUANTITIES, CellEval, admissible, quarter_loop, quantity

wp.set_module_options({"max_unroll": 1})

mat55d = wp.types.matrix(shape=(5, 5), dtype=wp.float64)
vec4d = wp.types.vector(length=4, dtype=wp.float64)

STATUS_CONVERGED = 0
STATUS_MAX_ITER = 1
STATUS_SINGULAR = 2
STATUS_NONFINITE = 3
STATUS_DOMAIN = 4

_MAX_BACKTRACK = 40
_ARMIJO = wp.constant(wp.float64(1.0e-4))
_MAX_DZ = wp.constant(wp.float64(1.0))


@wp.func
def z_to_x(z: vec5d) -> vec5d:
    a = wp.exp(z[0])
    return vec5d(z[2] + a, z[1], z[2], z[3], wp.exp(z[4]))


@wp.func
def evaluate_z(z: vec5d, B: wp.float64, d: wp.float64):
    """The cell at Newton variables z, gradients with respect to z."""
    a = d_exp(d_seed(z[0], 0))
    beta = d_seed(z[1], 1)
    gamma = d_seed(z[2], 2)
    phi = d_seed(z[3], 3)
    P = d_exp(d_seed(z[4], 4))
    return quarter_loop(a, beta, gamma, phi, P, B, d)


@wp.func
def evaluate_x(x: vec5d, B: wp.float64, d: wp.float64):
    """The cell at x = (alpha, beta, gamma, phi, P), gradients with respect to x."""
    a = d_sub(d_seed(x[0], 0), d_seed(x[2], 2))
    return quarter_loop(a, d_seed(x[1], 1), d_seed(x[2], 2), d_seed(x[3], 3), d_seed(x[4], 4), B, d)


@wp.func
def quantity_scale(code: int, B: wp.float64, d: wp.float64) -> wp.float64:
    """Characteristic size of quantity ``code``: 1 rad, d [mm], B/d^2 [N] or B/d [N mm]."""
    if code <= Q_PHI:
        return wp.float64(1.0)
    if code == Q_P or code >= Q_T:  # P, T, M, R, Rn, Rt, F
        if code == Q_M:
            return B / d
        return B / (d * d)
    return d


@wp.func
def imposed_residual(cell: CellEval, c: int, target: wp.float64, B: wp.float64, d: wp.float64):
    """Scaled residual of one imposed condition ``quantity[c] = target`` (Table 4) and its gradient."""
    sc = quantity_scale(c, B, d)
    qk = quantity(cell, c)
    return (qk.v - target) / sc, qk.g / sc


@wp.func
def residuals(cell: CellEval, codes: wp.vec4i, targets: vec4d, B: wp.float64, d: wp.float64):
    """Scaled residuals r (5) and their Jacobian J = dr/dseed (5x5): the intrinsic condition g = 0 (eq 6,
    scaled by d) and the four imposed conditions."""
    r = vec5d()
    J = mat55d()
    r[0] = cell.g / d
    J[0] = cell.dg / d
    for k in range(4):
        rk, gk = imposed_residual(cell, codes[k], targets[k], B, d)
        r[k + 1] = rk
        J[k + 1] = gk
    return r, J


@wp.func
def max_abs5(r: vec5d) -> wp.float64:
    m = wp.float64(0.0)
    for k in range(5):
        m = wp.max(m, wp.abs(r[k]))
    return m


@wp.func
def all_finite(r: vec5d, J: mat55d) -> wp.bool:
    ok = bool(True)
    for k in range(5):
        if not wp.isfinite(r[k]):
            ok = False
        for j in range(5):
            if not wp.isfinite(J[k, j]):
                ok = False
    return ok


@wp.func
def solve5(A: mat55d, rhs: vec5d):
    """Solve A x = rhs by Gauss elimination with partial pivoting.

    Returns (x, singular): singular when a pivot is below 1e-13 max|A| (rows of
    A are O(1) after residual scaling)."""
    x = vec5d()
    amax = wp.float64(0.0)
    for i in range(5):
        for j in range(5):
            amax = wp.max(amax, wp.abs(A[i, j]))
    tiny = wp.float64(1.0e-13) * amax
    singular = not (amax > wp.float64(0.0))
    for col in range(5):
        # pivot row
        p = col
        pv = wp.abs(A[col, col])
        for i in range(col + 1, 5):
            if wp.abs(A[i, col]) > pv:
                pv = wp.abs(A[i, col])
                p = i
        if not (pv > tiny):
            singular = True
        if p != col:
            for j in range(5):
                t = A[col, j]
                A[col, j] = A[p, j]
                A[p, j] = t
            t = rhs[col]
            rhs[col] = rhs[p]
            rhs[p] = t
        if not singular:
            for i in range(col + 1, 5):
                f = A[i, col] / A[col, col]
                for j in range(col, 5):
                    A[i, j] = A[i, j] - f * A[col, j]
                rhs[i] = rhs[i] - f * rhs[col]
    if not singular:
        for ii in range(5):
            i = 4 - ii
            s = rhs[i]
            for j in range(i + 1, 5):
                s = s - A[i, j] * x[j]
            x[i] = s / A[i, i]
    return x, singular


@wp.func
def z_admissible(z: vec5d) -> wp.bool:
    return admissible(wp.exp(z[0]), z[1], z[2], z[3], wp.exp(z[4]))


@wp.kernel
def solve_conditions_kernel(
    codes: wp.array2d(dtype=wp.int32),
    targets: wp.array2d(dtype=wp.float64),
    B: wp.array(dtype=wp.float64),
    d: wp.array(dtype=wp.float64),
    x_guess: wp.array2d(dtype=wp.float64),
    max_iter: int,
    tol: wp.float64,
    x_out: wp.array2d(dtype=wp.float64),
    status: wp.array(dtype=wp.int32),
    iters: wp.array(dtype=wp.int32),
):
    """Newton solve of g = 0 and quantity[codes[i, k]] = targets[i, k], k = 0..3.

    Inputs, shape (1 or N, ...): codes [.,4], targets [.,4], B [N mm^2], d [mm],
    x_guess [.,5] = (alpha, beta, gamma, phi, P) [rad, N].  Outputs, shape N:
    x_out [N,5], status [N] (module docstring), iters [N] (Newton steps taken).
    """
    i = wp.tid()
    ic = i % codes.shape[0]
    it_ = i % targets.shape[0]
    ig = i % x_guess.shape[0]
    Bi = B[i % B.shape[0]]
    di = d[i % d.shape[0]]
    cds = wp.vec4i(codes[ic, 0], codes[ic, 1], codes[ic, 2], codes[ic, 3])
    tg = vec4d(targets[it_, 0], targets[it_, 1], targets[it_, 2], targets[it_, 3])
    x0 = vec5d(x_guess[ig, 0], x_guess[ig, 1], x_guess[ig, 2], x_guess[ig, 3], x_guess[ig, 4])

    st = int(STATUS_MAX_ITER)
    n = int(0)
    x = x0
    a0 = x0[0] - x0[2]
    if not admissible(a0, x0[1], x0[2], x0[3], x0[4]):
        st = int(STATUS_DOMAIN)
    else:
        z = vec5d(wp.log(a0), x0[1], x0[2], x0[3], wp.log(x0[4]))
        r, J = residuals(evaluate_z(z, Bi, di), cds, tg, Bi, di)
        if not all_finite(r, J):
            st = int(STATUS_NONFINITE)
        else:
            f = wp.dot(r, r)
            while True:
                if max_abs5(r) <= tol:
                    st = int(STATUS_CONVERGED)
                    break
                if n >= max_iter:
                    st = int(STATUS_MAX_ITER)
                    break
                dz, singular = solve5(J, -r)
                if singular:
                    st = int(STATUS_SINGULAR)
                    break
                m = max_abs5(dz)
                if m > _MAX_DZ:
                    dz = dz * (_MAX_DZ / m)
                # backtracking: Armijo on |r|^2, halving out of the domain
                lam = wp.float64(1.0)
                accepted = bool(False)
                any_admissible = bool(False)
                any_nonfinite = bool(False)
                for k in range(_MAX_BACKTRACK):
                    zt = z + dz * lam
                    if z_admissible(zt):
                        any_admissible = True
                        rt, Jt = residuals(evaluate_z(zt, Bi, di), cds, tg, Bi, di)
                        if all_finite(rt, Jt):
                            ft = wp.dot(rt, rt)
                            if ft <= (wp.float64(1.0) - wp.float64(2.0) * _ARMIJO * lam) * f:
                                z = zt
                                r = rt
                                J = Jt
                                f = ft
                                accepted = True
                                break
                        else:
                            any_nonfinite = True
                    lam = lam * wp.float64(0.5)
                n += 1
                if not accepted:
                    if not any_admissible:
                        st = int(STATUS_DOMAIN)
                    elif any_nonfinite:
                        st = int(STATUS_NONFINITE)
                    else:
                        st = int(STATUS_MAX_ITER)
                    break
            x = z_to_x(z)
    for k in range(5):
        x_out[i, k] = x[k]
    status[i] = st
    iters[i] = n


@wp.kernel
def forward_kernel(
    x: wp.array2d(dtype=wp.float64),
    B: wp.array(dtype=wp.float64),
    d: wp.array(dtype=wp.float64),
    q_out: wp.array2d(dtype=wp.float64),
    g_out: wp.array(dtype=wp.float64),
):
    """Quantities of each cell at x = (alpha, beta, gamma, phi, P).

    Shapes: x [1 or N, 5], B, d [1 or N]; q_out [N, n_quantities] by code,
    g_out [N] the intrinsic residual (eq 6) [mm].  NaN where x is inadmissible."""
    i = wp.tid()
    ix = i % x.shape[0]
    xi = vec5d(x[ix, 0], x[ix, 1], x[ix, 2], x[ix, 3], x[ix, 4])
    if admissible(xi[0] - xi[2], xi[1], xi[2], xi[3], xi[4]):
        cell = evaluate_x(xi, B[i % B.shape[0]], d[i % d.shape[0]])
        for k in range(N_QUANTITIES):
            q_out[i, k] = cell.q[k]
        g_out[i] = cell.g
    else:
        nan = wp.float64(wp.nan)
        for k in range(N_QUANTITIES):
            q_out[i, k] = nan
        g_out[i] = nan


@wp.kernel
def forward_jacobian_kernel(
    x: wp.array2d(dtype=wp.float64),
    B: wp.array(dtype=wp.float64),
    d: wp.array(dtype=wp.float64),
    q_out: wp.array2d(dtype=wp.float64),
    dq_dx_out: wp.array3d(dtype=wp.float64),
    g_out: wp.array(dtype=wp.float64),
    dg_dx_out: wp.array2d(dtype=wp.float64),
):
    """As :func:`forward_kernel`, plus forward-mode gradients with respect to
    x = (alpha, beta, gamma, phi, P): dq_dx_out [N, n_quantities, 5], dg_dx_out [N, 5]."""
    i = wp.tid()
    ix = i % x.shape[0]
    xi = vec5d(x[ix, 0], x[ix, 1], x[ix, 2], x[ix, 3], x[ix, 4])
    ok = admissible(xi[0] - xi[2], xi[1], xi[2], xi[3], xi[4])
    cell = CellEval()
    if ok:
        cell = evaluate_x(xi, B[i % B.shape[0]], d[i % d.shape[0]])
    nan = wp.float64(wp.nan)
    for k in range(N_QUANTITIES):
        q_out[i, k] = wp.where(ok, cell.q[k], nan)
        for j in range(5):
            dq_dx_out[i, k, j] = wp.where(ok, cell.dq[k, j], nan)
    g_out[i] = wp.where(ok, cell.g, nan)
    for j in range(5):
        dg_dx_out[i, j] = wp.where(ok, cell.dg[j], nan)
