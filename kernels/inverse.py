"""The pieces of the per-cell Newton solve of the quarter stitch (Dusserre 2015 section 3.3) that the
cell step and the forward evaluation share, float64 Warp: the scaled residual of an imposed
condition, the 5x5 solve, the Newton's status codes and step limits, and the forward kernels.

Each cell solves five equations in the five unknowns (alpha, beta, gamma, phi, P):
the intrinsic condition g = X_B - X_A - (d/2) sin(beta) = 0 (eq 6, third line) and
four imposed conditions ``quantity[code_k] = target_k`` (Table 4).  Residuals are scaled to
O(1): g and lengths by d, forces by B/d^2, the moment by B/d, angles by 1 rad.
The Jacobian is exact forward-mode (:class:`~knitsim.kernels.elastica.Dual`), and the 5x5 system
is solved by Gauss elimination with partial pivoting.

The Newton itself is written once, in :func:`knitsim.kernels.cell_step.newton_solve`: the cell
step calls it, and so does the inverse solve of given conditions
(``cell_step.solve_conditions_kernel``, ``knitsim.cell.warp_solve.solve_batch``).

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

from .elastica import d_seed, d_sub, vec5d
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
