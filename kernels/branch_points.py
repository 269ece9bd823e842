"""The patch coupling's branch model on the device: each group's points of its branch within an increment and
the monotone model C(f) through them, one thread per group (float64 Warp).

Twin and test oracle: :class:`knitsim.patch.coupling.BranchPoints` (the module docstring of
:mod:`knitsim.patch.coupling`, "The column as a scalar problem in its force", says what the model is and why).
Every kernel here is one row of the twin's vectorised NumPy, written in the same order of operations:

- :func:`add_point`, :func:`add_points_kernel` -- ``BranchPoints.add``: a new point, dropping the points it contradicts;
- :func:`prepare_model_kernel`  -- ``BranchPoints.prepare``: the points sorted by force, each interval's
  envelope of its end tangents (or chord), the end slopes and curvatures of the extrapolations;
- :func:`model_kernel`          -- ``BranchPoints.model``: C(f) and dC/df;
- :func:`jump_kernel`           -- ``BranchPoints.jump``: points that bracket f across a step of the force.

A group keeps at most :data:`SIZE` points (the twin's default ``size``).  The stored rows are indexed by group;
the kernels run over a list of groups (the prepared ones, those still iterating).
"""
from __future__ import annotations

import sys

import warp as wp

wp.set_module_options({"enable_backward": False})

#: points kept per group (``PatchSolver.branch_points``, BranchPoints' ``size``)
SIZE = 8
#: the bounds of a cell's tangent dF/dC [N/mm], the largest column force the search grows its bracket to and
#: its first guess where it has no lower bound [N], at a patch of the usual knits' scales: the NumPy twin's
#: too (knitsim.patch.coupling takes them from here).  A patch far from those scales has them times its scale
#: factors (knitsim.patch.coupling.CouplingScale): the kernels take them as arguments (BranchArrays.k_min,
#: k_max; column_newton_kernel's force_start, force_max), not as constants
TANGENT_MIN, TANGENT_MAX, COLUMN_FORCE_MAX, COLUMN_FORCE_START = 1e-6, 1e6, 1e12, 1e-6
INF = wp.constant(wp.float64(wp.inf))
#: a cell's force "jumps" (a discontinuity no column force meets, :func:`jumps`) only where its two points at
#: one length differ by more than the column's force tolerance and by more than this fraction of the force.
#: Below it the difference is the cell solves' own resolution: where a cell reloads from slack its force F is
#: a small difference (F = 2 P sin(gamma), F << P), resolved to ~1e-10 N, the column's force tolerance; a
#: 300-cell column of a random patch reloading at grip strain 0.24 (F = 1.3e-4 N) saw two such points differ by
#: 1e-6 to 1e-5 of F, was cut short as a jump and held unconverged (knitsim run of a 300 x 300 random patch:
#: 2 column-increments); with this floor it converges in 11 trials.  A real jump (a slide onset's drop, a jam)
#: is orders larger; a jump below the floor is iterated, and flagged unconverged where it does not close
JUMP_RTOL = 1e-5
JUMP_RTOL_WP = wp.constant(wp.float64(JUMP_RTOL))


@wp.struct
class BranchArrays:
    """Each group's kept points (C [mm], F [N], K = dF/dC [N/mm], valid) and its prepared model."""
    C: wp.array2d(dtype=wp.float64)
    F: wp.array2d(dtype=wp.float64)
    K: wp.array2d(dtype=wp.float64)
    valid: wp.array2d(dtype=wp.int32)
    # prepared: the points sorted by force (invalid ones last: F = inf, C = NaN), their count m
    Fs: wp.array2d(dtype=wp.float64)
    Cs: wp.array2d(dtype=wp.float64)
    Ks: wp.array2d(dtype=wp.float64)
    m: wp.array(dtype=wp.int32)
    # per interval (SIZE - 1): the slopes dC/df used (da, db), before the chord replaced them (raw), its kind
    da: wp.array2d(dtype=wp.float64)
    db: wp.array2d(dtype=wp.float64)
    da_raw: wp.array2d(dtype=wp.float64)
    db_raw: wp.array2d(dtype=wp.float64)
    convex: wp.array2d(dtype=wp.int32)
    concave: wp.array2d(dtype=wp.int32)
    # the extrapolations beyond the lowest / highest point: slope dC/df and curvature d2C/df2
    s_lo: wp.array(dtype=wp.float64)
    s_hi: wp.array(dtype=wp.float64)
    c_lo: wp.array(dtype=wp.float64)
    c_hi: wp.array(dtype=wp.float64)
    # per group: the model's length bounds [mm], stall count and side (BranchPoints.record), the curvature of
    # the last increment (NaN: none), the fallback tangent dF/dC [N/mm], the length scale C0 [mm]
    C_min: wp.array(dtype=wp.float64)
    C_max: wp.array(dtype=wp.float64)
    stall: wp.array(dtype=wp.int32)
    side: wp.array(dtype=wp.int32)
    curvature: wp.array(dtype=wp.float64)
    k_fallback: wp.array(dtype=wp.float64)
    C_ref: wp.array(dtype=wp.float64)
    # the bounds of a tangent dF/dC [N/mm]: TANGENT_MIN, TANGENT_MAX times the patch's tangent scale factor
    k_min: wp.float64
    k_max: wp.float64


@wp.func
def np_clip(x: wp.float64, lo: wp.float64, hi: wp.float64):
    """numpy.clip: min(max(x, lo), hi), NaN where x is NaN."""
    if wp.isnan(x):
        return x
    y = x
    if y < lo:
        y = lo
    if y > hi:
        y = hi
    return y


@wp.func
def inverse_slope(b: BranchArrays, k: wp.float64):
    """dC/df = 1 / clip(k, b.k_min, b.k_max) of a known positive tangent k, else NaN."""
    if wp.isfinite(k) and k > wp.float64(0.0):
        return wp.float64(1.0) / np_clip(k, b.k_min, b.k_max)
    return wp.float64(wp.nan)


@wp.func
def add_point(b: BranchArrays, g: int, c: wp.float64, f: wp.float64, k: wp.float64, ft: wp.float64):
    """BranchPoints.add of group g's point (c, f, k) [mm, N, N/mm], its column's force per wale ft [N]."""
    # the kept points that the new one contradicts (a monotone branch), a shorter zero-force point, itself
    for s in range(SIZE):
        Ck = b.C[g, s]
        Fk = b.F[g, s]
        conflict = (Fk < f and Ck > c) or (Fk > f and Ck < c)
        dup_zero = Fk == wp.float64(0.0) and f == wp.float64(0.0) and Ck <= c
        if conflict or dup_zero or (Fk == f and Ck == c):
            b.valid[g, s] = 0
    # a zero-force point shorter than a kept one adds nothing
    dominated = False
    full = True
    for s in range(SIZE):
        if b.valid[g, s] != 0:
            if f == wp.float64(0.0) and b.F[g, s] == wp.float64(0.0) and b.C[g, s] > c:
                dominated = True
        else:
            full = False
    if dominated:
        return
    if full:
        # drop the point farthest (in force) from the column's force, on a side that keeps another
        n_hi = int(0)
        n_lo = int(0)
        for s in range(SIZE):
            if b.F[g, s] > ft:
                n_hi += 1
            else:
                n_lo += 1
        drop = int(0)
        best = wp.float64(-INF)
        for s in range(SIZE):
            dist = wp.float64(-1.0)
            Fk = b.F[g, s]
            if (Fk > ft and n_hi >= 2) or (not (Fk > ft) and n_lo >= 2):
                dist = wp.abs(Fk - ft)
            # numpy.argmax: the first maximum, a NaN counting as the maximum
            if best == best and (dist > best or dist != dist):
                best = dist
                drop = s
        b.valid[g, drop] = 0
    slot = int(0)
    for s in range(SIZE - 1, -1, -1):
        if b.valid[g, s] == 0:
            slot = s
    b.C[g, slot] = c
    b.F[g, slot] = f
    b.K[g, slot] = k
    b.valid[g, slot] = 1


@wp.kernel
def add_points_kernel(
    b: BranchArrays,
    rows: wp.array(dtype=wp.int32),
    C: wp.array(dtype=wp.float64),
    F: wp.array(dtype=wp.float64),
    K: wp.array(dtype=wp.float64),
    f_target: wp.array(dtype=wp.float64),
):
    """BranchPoints.add of group rows[i], its point (C, F, K)[i] (indexed by i), its column's force f_target[i]."""
    i = wp.tid()
    add_point(b, rows[i], C[i], F[i], K[i], f_target[i])


@wp.func
def end_slope(b: BranchArrays, g: int, i: int, j: int, fb: wp.float64):
    """The slope dC/df of an extrapolation from sorted point i: its tangent, else the secant to point j,
    else the fallback ``fb``; within [1/k_max, 1/k_min]."""
    s = inverse_slope(b, b.Ks[g, i])
    sec = (b.Cs[g, j] - b.Cs[g, i]) / (b.Fs[g, j] - b.Fs[g, i])
    if not (b.m[g] >= 2 and wp.isfinite(sec) and sec > wp.float64(0.0)):
        sec = fb
    if not wp.isfinite(s):
        s = sec
    return np_clip(s, wp.float64(1.0) / b.k_max, wp.float64(1.0) / b.k_min)


@wp.func
def end_curvature(b: BranchArrays, g: int, j: int, smooth: bool):
    """d2C/df2 of an extrapolation from the tangents of sorted points j, j+1 where they agree (a smooth bend),
    else the last increment's; 0 where neither is known."""
    c = b.curvature[g]
    if b.m[g] >= 2:
        kj = inverse_slope(b, b.Ks[g, j])
        kj1 = inverse_slope(b, b.Ks[g, j + 1])
        cj = (kj1 - kj) / (b.Fs[g, j + 1] - b.Fs[g, j])
        ratio = kj1 / kj
        c = wp.float64(wp.nan)
        if smooth and wp.isfinite(cj) and ratio <= wp.float64(1.5) and ratio >= wp.float64(1.0) / wp.float64(1.5):
            c = cj
    if not wp.isfinite(c):
        c = wp.float64(0.0)
    return c


@wp.kernel
def prepare_model_kernel(b: BranchArrays, rows: wp.array(dtype=wp.int32)):
    """BranchPoints.prepare of group rows[i]."""
    g = rows[wp.tid()]
    # the points sorted by force, stable (numpy.argsort kind="stable"), the invalid ones last
    m = int(0)
    for a in range(SIZE):
        fa = INF
        if b.valid[g, a] != 0:
            fa = b.F[g, a]
            m += 1
        rank = int(0)
        for s in range(SIZE):
            fs = INF
            if b.valid[g, s] != 0:
                fs = b.F[g, s]
            if fs < fa or (fs == fa and s < a):
                rank += 1
        b.Fs[g, rank] = fa
        cs = wp.float64(wp.nan)
        if b.valid[g, a] != 0:
            cs = b.C[g, a]
        b.Cs[g, rank] = cs
        b.Ks[g, rank] = b.K[g, a]
    b.m[g] = m
    # each interval: the tangent lines of its ends, their upper envelope where the slopes grow across it
    # (convex), lower where they fall (concave), the chord where they contradict it
    for s in range(SIZE - 1):
        h = b.Fs[g, s + 1] - b.Fs[g, s]
        delta = wp.float64(0.0)
        if wp.isfinite(h) and h > wp.float64(0.0):
            delta = (b.Cs[g, s + 1] - b.Cs[g, s]) / h
        if not (delta >= wp.float64(0.0)) and not wp.isnan(delta):
            delta = wp.float64(0.0)
        ka = inverse_slope(b, b.Ks[g, s])
        kb = inverse_slope(b, b.Ks[g, s + 1])
        da = delta
        if wp.isfinite(ka):
            da = ka
        db = delta
        if wp.isfinite(kb):
            db = kb
        lo_d = wp.float64(0.99) * delta
        hi_d = wp.float64(1.01) * delta
        convex = da <= hi_d and lo_d <= db and db >= da
        concave = da >= lo_d and hi_d >= db and db < da
        b.da_raw[g, s] = da
        b.db_raw[g, s] = db
        if not (convex or concave):
            da = delta
            db = delta
        b.da[g, s] = da
        b.db[g, s] = db
        b.convex[g, s] = wp.where(convex, 1, 0)
        b.concave[g, s] = wp.where(concave, 1, 0)
    top = wp.max(m - 1, 0)
    fb = wp.float64(1.0) / np_clip(b.k_fallback[g], b.k_min, b.k_max)
    b.s_lo[g] = end_slope(b, g, 0, wp.min(1, top), fb)
    b.s_hi[g] = end_slope(b, g, top, wp.max(top - 1, 0), fb)
    b.c_lo[g] = end_curvature(b, g, 0, b.convex[g, 0] != 0 or b.concave[g, 0] != 0)
    j = wp.max(top - 1, 0)
    b.c_hi[g] = end_curvature(b, g, j, b.convex[g, j] != 0 or b.concave[g, j] != 0)


@wp.func
def bent_line(x: wp.float64, s: wp.float64, c: wp.float64):
    """(increment, slope) of a line of slope s bent by curvature c at x (coupling._bent_line)."""
    bound = wp.float64(4.0) * s
    if c * x < wp.float64(0.0):
        bound = wp.float64(0.25) * s
    xb = INF
    if c != wp.float64(0.0):
        xb = (bound - s) / c
    inside = wp.abs(x) <= wp.abs(xb)
    xi = xb
    extra = wp.float64(0.0)
    slope = bound
    if inside:
        xi = x
        slope = s + c * x
    else:
        extra = bound * (x - xb)
    d = s * xi + wp.float64(0.5) * c * xi * xi + extra
    return d, slope


@wp.func
def count_at_most(b: BranchArrays, g: int, f: wp.float64):
    """How many of the sorted points have a force <= f."""
    j = int(0)
    for s in range(SIZE):
        if b.Fs[g, s] <= f:
            j += 1
    return j


@wp.func
def model_at(b: BranchArrays, g: int, f: wp.float64):
    """(C, dC/df) of group g's prepared model at its force f (BranchPoints.model)."""
    m = b.m[g]
    j = count_at_most(b, g, f)
    stall = b.stall[g]
    C = wp.float64(0.0)
    dC = wp.float64(0.0)
    if j > 0 and j < m:
        ia = j - 1
        Fa = b.Fs[g, ia]
        Ca = b.Cs[g, ia]
        Fb = b.Fs[g, ia + 1]
        Cb = b.Cs[g, ia + 1]
        da = b.da[g, ia]
        db = b.db[g, ia]
        Ta = Ca + (f - Fa) * da
        Tb = Cb + (f - Fb) * db
        pick_a = Ta <= Tb
        if b.convex[g, ia] != 0:
            pick_a = Ta >= Tb
        Ch = Tb
        dCh = db
        if pick_a:
            Ch = Ta
            dCh = da
        Ch = np_clip(Ch, wp.min(Ca, Cb), wp.max(Ca, Cb))
        if stall > 0:
            # a stalled cell: the Newton step from its fresh end, 2^stall times as long, within half its bracket
            fresh_b = b.side[g] > 0
            d_f = b.da_raw[g, ia]
            if fresh_b:
                d_f = b.db_raw[g, ia]
            d_f = d_f * wp.pow(wp.float64(2.0), wp.float64(stall))
            Tf = Ca + (f - Fa) * d_f
            if fresh_b:
                Tf = Cb + (f - Fb) * d_f
            mid = wp.float64(0.5) * (Ca + Cb)
            lo_C = Ca
            hi_C = mid
            if fresh_b:
                lo_C = mid
                hi_C = Cb
            Ch = np_clip(Tf, lo_C, hi_C)
            dCh = wp.float64(0.0)
            if Tf > lo_C and Tf < hi_C:
                dCh = d_f
        C = Ch
        dC = dCh
        if dC < wp.float64(0.0):
            dC = wp.float64(0.0)
    else:
        # beyond the end points: the end tangent bent by the branch's curvature (straight and doubled while
        # stalled)
        k = int(0)
        s_end = b.s_lo[g]
        c_end = b.c_lo[g]
        if j != 0:
            k = wp.max(m - 1, 0)
            s_end = b.s_hi[g]
            c_end = b.c_hi[g]
        s_e = wp.min(s_end * wp.pow(wp.float64(2.0), wp.float64(stall)), wp.float64(1.0) / b.k_min)
        if stall > 0:
            c_end = wp.float64(0.0)
        d_e, sl_e = bent_line(f - b.Fs[g, k], s_e, c_end)
        C = b.Cs[g, k] + d_e
        dC = sl_e
    lo = b.C_min[g]
    hi = b.C_max[g]
    if C < lo or C > hi:
        dC = wp.float64(0.0)
    return np_clip(C, lo, hi), dC


@wp.kernel
def model_kernel(
    b: BranchArrays,
    rows: wp.array(dtype=wp.int32),
    f: wp.array(dtype=wp.float64),
    C: wp.array(dtype=wp.float64),
    dC: wp.array(dtype=wp.float64),
):
    """C[i], dC[i] of group rows[i]'s model at its force f[i]."""
    i = wp.tid()
    c, d = model_at(b, rows[i], f[i])
    C[i] = c
    dC[i] = d


@wp.func
def jumps(b: BranchArrays, g: int, f: wp.float64, f_tol: wp.float64):
    """1 where group g's points bracket f within ~1e-11 C0 and differ by more than f_tol and JUMP_RTOL f in force,
    else 0."""
    j = count_at_most(b, g, f)
    r = 0
    if j >= 1 and j < b.m[g]:
        dCj = b.Cs[g, j] - b.Cs[g, j - 1]
        dFj = b.Fs[g, j] - b.Fs[g, j - 1]
        if dCj <= wp.float64(1e-11) * b.C_ref[g] and dFj > wp.max(f_tol, JUMP_RTOL_WP * f):
            r = 1
    return r


@wp.kernel
def jump_kernel(
    b: BranchArrays,
    rows: wp.array(dtype=wp.int32),
    f: wp.array(dtype=wp.float64),
    f_tol: wp.array(dtype=wp.float64),
    out: wp.array(dtype=wp.int32),
):
    """out[i] = 1 where group rows[i]'s points bracket f[i] within ~1e-11 C0 and differ by more than f_tol[i] (and
    JUMP_RTOL f[i])."""
    i = wp.tid()
    out[i] = jumps(b, rows[i], f[i], f_tol[i])


# ===================================================================== the column's scalar solve
# PatchSolver._solve_columns on the device: Phi(F) = sum_g n_g (C_g(F / p_g) - C0_g) - u of every live
# column, safeguarded Newton on F.  The groups' models run one thread per group; each column's sums run one
# thread per column over its groups in ascending group order (numpy.bincount's order: the same sums bit
# for bit, and deterministic, where atomics would not be).

EPS = wp.constant(wp.float64(sys.float_info.epsilon))


@wp.kernel
def model_at_column_force_kernel(
    b: BranchArrays,
    rows: wp.array(dtype=wp.int32),
    col: wp.array(dtype=wp.int32),
    p: wp.array(dtype=wp.float64),
    F_col: wp.array(dtype=wp.float64),
    C: wp.array(dtype=wp.float64),
    dC: wp.array(dtype=wp.float64),
):
    """C[g], dC[g] of group g = rows[i]'s model at its column's force per wale F_col[col[g]] / p[g]."""
    g = rows[wp.tid()]
    c, d = model_at(b, g, F_col[col[g]] / p[g])
    C[g] = c
    dC[g] = d


@wp.kernel
def column_sums_kernel(
    col_start: wp.array(dtype=wp.int32),
    col_groups: wp.array(dtype=wp.int32),
    live: wp.array(dtype=wp.int32),
    cnt: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    p: wp.array(dtype=wp.float64),
    C: wp.array(dtype=wp.float64),
    dC: wp.array(dtype=wp.float64),
    u: wp.array(dtype=wp.float64),
    r: wp.array(dtype=wp.float64),
    dr: wp.array(dtype=wp.float64),
):
    """r[k] = Phi of live column k (its lengths' sum minus u [mm]), dr[k] = dPhi/dF [mm/N]."""
    k = wp.tid()
    if live[k] == 0:
        return
    s = wp.float64(0.0)
    ds = wp.float64(0.0)
    for j in range(col_start[k], col_start[k + 1]):
        g = col_groups[j]
        s += cnt[g] * (C[g] - C0[g])
        ds += cnt[g] * dC[g] / p[g]
    r[k] = s - u[k]
    dr[k] = ds


@wp.kernel
def column_newton_kernel(
    r: wp.array(dtype=wp.float64),
    dr: wp.array(dtype=wp.float64),
    tol_len: wp.array(dtype=wp.float64),
    F: wp.array(dtype=wp.float64),
    lo: wp.array(dtype=wp.float64),
    hi: wp.array(dtype=wp.float64),
    done: wp.array(dtype=wp.int32),
    force_start: wp.float64,
    force_max: wp.float64,
    still_open: wp.array(dtype=wp.int32),
):
    """One safeguarded Newton step of each open column: bisection (or doubling from force_start while no
    upper bound is known) where the step leaves the bracket; closed at |Phi| <= tol_len, a bracket at rounding,
    or no root below force_max [N].  Counts the columns still open in still_open[0]."""
    k = wp.tid()
    if done[k] != 0:
        return
    rk = r[k]
    if wp.abs(rk) <= tol_len[k]:
        done[k] = 1
        return
    f = F[k]
    if rk < wp.float64(0.0):
        lo[k] = f
    if rk > wp.float64(0.0):
        hi[k] = f
    a = lo[k]
    h = hi[k]
    fn = f - rk / dr[k]
    if not wp.isfinite(fn) or fn <= a or fn >= h:
        if wp.isfinite(h):
            fn = wp.float64(0.5) * (a + h)
        elif a > wp.float64(0.0):
            fn = wp.float64(2.0) * a
        else:
            fn = force_start
    closed = (wp.isfinite(h) and h - a <= wp.float64(4.0) * EPS * h) or (not wp.isfinite(h) and a >= force_max)
    if closed:
        done[k] = 1
    else:
        F[k] = fn
        wp.atomic_add(still_open, 0, 1)


@wp.kernel
def column_bridge_kernel(
    rows: wp.array(dtype=wp.int32),
    col: wp.array(dtype=wp.int32),
    gap: wp.array(dtype=wp.int32),
    r_a: wp.array(dtype=wp.float64),
    r_b: wp.array(dtype=wp.float64),
    C_a: wp.array(dtype=wp.float64),
    C_b: wp.array(dtype=wp.float64),
    C: wp.array(dtype=wp.float64),
):
    """Of a column whose model steps over u (no exact root, its bracket closed on it), the lengths between the
    bracket ends' that add up to u: C = C_a + theta (C_b - C_a)."""
    g = rows[wp.tid()]
    k = col[g]
    if gap[k] != 0:
        theta = wp.float64(0.0)
        if r_b[k] > r_a[k]:
            theta = -r_a[k] / (r_b[k] - r_a[k])
        C[g] = C_a[g] + np_clip(theta, wp.float64(0.0), wp.float64(1.0)) * (C_b[g] - C_a[g])


@wp.kernel
def column_slack_lengths_kernel(
    b: BranchArrays,
    rows: wp.array(dtype=wp.int32),
    col: wp.array(dtype=wp.int32),
    slack: wp.array(dtype=wp.int32),
    C_zero: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    C: wp.array(dtype=wp.float64),
):
    """A column at zero force: each cell a little (1e-6 C0) short of its zero-force length, within its bounds,
    so that the cell solver locates its slack event there."""
    g = rows[wp.tid()]
    if slack[col[g]] != 0:
        C[g] = np_clip(C_zero[g] - wp.float64(1e-6) * C0[g], b.C_min[g], b.C_max[g])
