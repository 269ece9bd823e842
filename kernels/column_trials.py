"""The patch coupling's bookkeeping of each trial on the device (issue 15, item 4: the host off the critical path).

After each trial step of a patch's cells, :meth:`knitsim.patch.coupling.PatchSolver._solve` reads every group's
trial (its packed read, :mod:`knitsim.kernels.state_read`) and

- per column: its cells' largest and smallest force, whether a cell failed or stopped at its cap, how far its
  lengths are from adding up to the grip displacement, and the largest gap of a good cell's force to the
  column's (:func:`column_reads_kernel`: one thread per column over its groups in ascending order, the sums of
  ``numpy.bincount``, bit for bit);
- per group: the stall count of its branch model, its new branch points (the trial's, and the slide onset it
  crossed), its fallback tangent, its last good trial, and the length bounds of its model from its good and
  failed trials (:func:`trial_book_kernel`).

On a 10^6-group patch that was ~0.2 s of host NumPy a trial, against ~0.05 s of cell kernels on one H200.
Twin and test oracle: the NumPy lines of ``PatchSolver._solve`` and ``PatchSolver._committed_columns`` they
replace, the same operations in the same order (``tests/patch/test_device_coupling.py``).
"""
from __future__ import annotations

import warp as wp

from .branch_points import INF, BranchArrays, add_point, jumps, np_clip
from .state_read import READ_C, READ_F, READ_JAMMED, READ_STAGE, READ_STATUS

wp.set_module_options({"enable_backward": False})


@wp.struct
class TrialBookArrays:
    """Each group's record of its trials within one increment (the NumPy twin: the locals of the same names in
    ``PatchSolver._solve``)."""
    C_last: wp.array(dtype=wp.float64)      # its last good trial [mm, N]
    F_last: wp.array(dtype=wp.float64)
    good_hi: wp.array(dtype=wp.float64)     # the extreme lengths of its good trials [mm]
    good_lo: wp.array(dtype=wp.float64)
    fail_hi: wp.array(dtype=wp.float64)     # the nearest lengths at which a trial failed [mm] (+-inf: none)
    fail_lo: wp.array(dtype=wp.float64)
    dir_min: wp.array(dtype=wp.float64)     # the increment's direction's bounds [mm]
    dir_max: wp.array(dtype=wp.float64)
    k: wp.array(dtype=wp.float64)           # the fallback tangent dF/dC [N/mm]


@wp.kernel
def column_jump_kernel(b: BranchArrays, rows: wp.array(dtype=wp.int32), col: wp.array(dtype=wp.int32),
                       p: wp.array(dtype=wp.float64), F_star: wp.array(dtype=wp.float64), force_tol: wp.float64,
                       force_rtol: wp.float64, out: wp.array(dtype=wp.int32)):
    """out[k] = 1 where a prepared group of column k jumps across its column's force per wale F_star / p
    (BranchPoints.jump at the tolerance (force_tol + force_rtol F_star) / p; out zeroed before)."""
    g = rows[wp.tid()]
    k = col[g]
    pg = p[g]
    if jumps(b, g, F_star[k] / pg, (force_tol + force_rtol * F_star[k]) / pg) != 0:
        wp.atomic_max(out, k, 1)


@wp.kernel
def trial_strain_kernel(
    col: wp.array(dtype=wp.int32),
    live: wp.array(dtype=wp.int32),
    single: wp.array(dtype=wp.int32),
    u_single: wp.array(dtype=wp.float64),
    C_try: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    committed_strain: wp.array(dtype=wp.float64),
    strain: wp.array(dtype=wp.float64),
):
    """The strain each group is stepped to: a single-group column's grip strain, else C_try / C0 - 1; the
    committed strain of the groups of columns no longer live."""
    g = wp.tid()
    s = committed_strain[g]
    if live[col[g]] != 0:
        if single[g] != 0:
            s = u_single[g]
        else:
            s = C_try[g] / C0[g] - wp.float64(1.0)
    strain[g] = s


@wp.kernel
def column_reads_kernel(
    col_start: wp.array(dtype=wp.int32),
    col_groups: wp.array(dtype=wp.int32),
    live: wp.array(dtype=wp.int32),
    cnt: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    p: wp.array(dtype=wp.float64),
    reals: wp.array2d(dtype=wp.float64),
    ints: wp.array2d(dtype=wp.int32),
    status_ok: int,
    status_cap: int,
    F_star: wp.array(dtype=wp.float64),
    F_max: wp.array(dtype=wp.float64),
    F_min: wp.array(dtype=wp.float64),
    failed: wp.array(dtype=wp.int32),
    capped: wp.array(dtype=wp.int32),
    sum_n_pF: wp.array(dtype=wp.float64),
    sum_np_F: wp.array(dtype=wp.float64),
    sum_n_dC: wp.array(dtype=wp.float64),
    force_gap: wp.array(dtype=wp.float64),
):
    """Of each live column's packed states (a trial's, or the committed ones with every column live): the
    largest and smallest total force p F of its groups [N], whether one failed (status not ok) or stopped at its
    cap, the sums n (p F) and (n p) F [N] (the two orders of ``PatchSolver``'s NumPy) and n (C - C0) [mm], and
    the largest |F - F_star / p| p of its good groups [N] (0: none)."""
    k = wp.tid()
    if live[k] == 0:
        return
    fmax = -INF
    fmin = INF
    any_failed = int(0)
    any_capped = int(0)
    s1 = wp.float64(0.0)
    s2 = wp.float64(0.0)
    s3 = wp.float64(0.0)
    gmax = wp.float64(0.0)
    for j in range(col_start[k], col_start[k + 1]):
        g = col_groups[j]
        pg = p[g]
        F = reals[READ_F, g]
        ftot = pg * F
        fmax = wp.max(fmax, ftot)
        fmin = wp.min(fmin, ftot)
        st = ints[READ_STATUS, g]
        if st == status_cap:
            any_capped = 1
        if st != status_ok:
            any_failed = 1
        else:
            gap = wp.abs(F - F_star[k] / pg) * pg
            if gap > gmax or gap != gap:
                gmax = gap
        s1 += cnt[g] * ftot
        s2 += cnt[g] * pg * F
        s3 += cnt[g] * (reals[READ_C, g] - C0[g])
    F_max[k] = fmax
    F_min[k] = fmin
    failed[k] = any_failed
    capped[k] = any_capped
    sum_n_pF[k] = s1
    sum_np_F[k] = s2
    sum_n_dC[k] = s3
    force_gap[k] = gmax


@wp.kernel
def trial_book_kernel(
    b: BranchArrays,
    book: TrialBookArrays,
    col: wp.array(dtype=wp.int32),
    live: wp.array(dtype=wp.int32),
    single: wp.array(dtype=wp.int32),
    stick: wp.array(dtype=wp.int32),
    p: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    reals: wp.array2d(dtype=wp.float64),
    ints: wp.array2d(dtype=wp.int32),
    status_ok: int,
    stage_slack: int,
    kt: wp.array(dtype=wp.float64),
    slide_C: wp.array(dtype=wp.float64),
    slide_F: wp.array(dtype=wp.float64),
    C_try: wp.array(dtype=wp.float64),
    F_star: wp.array(dtype=wp.float64),
    F_col: wp.array(dtype=wp.float64),
    col_stalled: wp.array(dtype=wp.int32),
    force_gap: wp.array(dtype=wp.float64),
    force_tol: wp.float64,
    force_rtol: wp.float64,
    direction: int,
):
    """One trial's bookkeeping of group g (``PatchSolver._solve`` after its columns are judged): the stall
    count (BranchPoints.record), the trial's point and the slide onset it crossed (BranchPoints.add), the
    fallback tangent, the last good trial, and the model's bounds from the good and failed trials."""
    g = wp.tid()
    k = col[g]
    g_live = live[k] != 0
    pg = p[g]
    tC = reals[READ_C, g]
    tF = reals[READ_F, g]
    failed = ints[READ_STATUS, g] != status_ok
    use = g_live and not failed
    if use:
        # BranchPoints.record: a cell among those that set its column's spread, landing on the same side again
        f_ref = F_star[k] / pg
        f_tol = (force_tol + force_rtol * F_star[k]) / pg
        gap = wp.abs(tF - f_ref)
        side = int(0)
        if not (gap <= f_tol):
            d = tF - f_ref
            if d > wp.float64(0.0):
                side = 1
            elif d < wp.float64(0.0):
                side = -1
        stalled = side != 0 and side == b.side[g] and col_stalled[k] != 0 and gap >= wp.float64(0.5) * (
            force_gap[k] / pg)
        if stalled:
            b.stall[g] = b.stall[g] + 1
        else:
            b.stall[g] = 0
        b.side[g] = side
        # the trial's own tangent where it is one (finite, positive, not slack)
        kg = kt[g]
        if not (wp.isfinite(kg) and kg > wp.float64(0.0) and ints[READ_STAGE, g] != stage_slack):
            kg = wp.float64(wp.nan)
        ft = F_col[k] / pg
        add_point(b, g, tC, tF, kg, ft)
        # the slide onset the trial crossed, from a committed stick state (its slope unknown)
        sC = slide_C[g]
        sF = slide_F[g]
        if stick[g] != 0 and wp.isfinite(sC) and sF > wp.float64(0.0) and (sC - tC) * wp.float64(direction) < wp.float64(0.0):
            add_point(b, g, sC, sF, wp.float64(wp.nan), ft)
        # the fallback tangent: the cell's own, else the secant from its last good trial
        dC = tC - book.C_last[g]
        ks = (tF - book.F_last[g]) / dC
        if not (wp.isfinite(ks) and ks > wp.float64(0.0) and wp.abs(dC) > wp.float64(1e-12) * C0[g]):
            ks = wp.float64(wp.nan)
        knew = ks
        if wp.isfinite(kg):
            knew = kg
        if wp.isfinite(knew):
            book.k[g] = np_clip(knew, b.k_min, b.k_max)
        book.F_last[g] = tF
        book.C_last[g] = tC
    # a failed trial: no longer than halfway to it from the cell's last good length (or no shorter)
    fail_hi = book.fail_hi[g]
    fail_lo = book.fail_lo[g]
    if g_live and failed and single[g] == 0:
        c = C_try[g]
        if c > book.C_last[g]:
            fail_hi = wp.min(fail_hi, c)
        if c < book.C_last[g]:
            fail_lo = wp.max(fail_lo, c)
    good_hi = book.good_hi[g]
    good_lo = book.good_lo[g]
    if use:
        good_hi = wp.max(good_hi, tC)
        good_lo = wp.min(good_lo, tC)
    if good_hi >= fail_hi:
        fail_hi = INF
    if good_lo <= fail_lo:
        fail_lo = -INF
    book.fail_hi[g] = fail_hi
    book.fail_lo[g] = fail_lo
    book.good_hi[g] = good_hi
    book.good_lo[g] = good_lo
    c_max = INF
    if wp.isfinite(fail_hi):
        c_max = wp.float64(0.5) * (good_hi + fail_hi)
    c_min = -INF
    if wp.isfinite(fail_lo):
        c_min = wp.float64(0.5) * (good_lo + fail_lo)
    b.C_max[g] = wp.min(book.dir_max[g], c_max)
    b.C_min[g] = wp.max(book.dir_min[g], c_min)


# ===================================================================== an increment's start, per group
@wp.kernel
def begin_trials_kernel(
    b: BranchArrays,
    book: TrialBookArrays,
    col: wp.array(dtype=wp.int32),
    p: wp.array(dtype=wp.float64),
    C0: wp.array(dtype=wp.float64),
    reals: wp.array2d(dtype=wp.float64),
    ints: wp.array2d(dtype=wp.int32),
    k_c: wp.array(dtype=wp.float64),
    F_col: wp.array(dtype=wp.float64),
    monotone: wp.array(dtype=wp.int32),
    direction: int,
    stage_sf_load: int,
    stage_sf_unload: int,
    committed_strain: wp.array(dtype=wp.float64),
    stick: wp.array(dtype=wp.int32),
):
    """An increment's start of group g (``PatchSolver._solve``'s set-up): the committed state as a point of its
    branch (with its tangent k_c where finite and positive), the direction's bounds where its column is in
    equilibrium (``monotone``), its last good trial and good lengths the committed ones, no failure yet."""
    g = wp.tid()
    k = col[g]
    C = reals[READ_C, g]
    F = reals[READ_F, g]
    kc = k_c[g]
    if not (wp.isfinite(kc) and kc > wp.float64(0.0)):
        kc = wp.float64(wp.nan)
    add_point(b, g, C, F, kc, F_col[k] / p[g])
    d_min = -INF
    d_max = INF
    if monotone[k] != 0 and direction > 0:
        d_min = C
    if monotone[k] != 0 and direction < 0:
        d_max = C
    book.dir_min[g] = d_min
    book.dir_max[g] = d_max
    b.C_min[g] = d_min
    b.C_max[g] = d_max
    book.C_last[g] = C
    book.F_last[g] = F
    book.good_hi[g] = C
    book.good_lo[g] = C
    book.fail_hi[g] = INF
    book.fail_lo[g] = -INF
    committed_strain[g] = C / C0[g] - wp.float64(1.0)
    st = ints[READ_STAGE, g]
    if st == stage_sf_load or st == stage_sf_unload:
        stick[g] = 1
    else:
        stick[g] = 0


@wp.kernel
def branch_curvature_kernel(
    k_c: wp.array(dtype=wp.float64),
    reals: wp.array2d(dtype=wp.float64),
    ints: wp.array2d(dtype=wp.int32),
    use_history: int,
    keep_history: int,
    hist_F: wp.array(dtype=wp.float64),
    hist_kinv: wp.array(dtype=wp.float64),
    hist_stage: wp.array(dtype=wp.int32),
    hist_jammed: wp.array(dtype=wp.int32),
    k_min: wp.float64,
    k_max: wp.float64,
    curvature: wp.array(dtype=wp.float64),
):
    """The curvature d(1/k)/dF of group g's branch from its last two committed points (``PatchSolver._solve``'s
    set-up; ``reads``: the committed state packed): from the tangent ``k_c`` now and the kept one where both
    points are on one branch (the same stage and jammed flag, positive forces that differ, tangents within a
    factor 1.5), NaN elsewhere or without ``use_history``; ``keep_history``: the committed point is kept as the
    next increment's last one.  The tangents are clipped to [k_min, k_max] (the branch model's bounds)."""
    g = wp.tid()
    kc = k_c[g]
    kinv = wp.float64(wp.nan)
    if wp.isfinite(kc) and kc > wp.float64(0.0):
        kinv = wp.float64(1.0) / np_clip(kc, k_min, k_max)
    F = reals[READ_F, g]
    st = ints[READ_STAGE, g]
    jam = ints[READ_JAMMED, g]
    curv = wp.float64(wp.nan)
    if use_history != 0:
        Fh = hist_F[g]
        kh = hist_kinv[g]
        same = st == hist_stage[g] and jam == hist_jammed[g] and F > wp.float64(0.0) and Fh > wp.float64(0.0)
        same = same and F != Fh and kinv <= wp.float64(1.5) * kh and kh <= wp.float64(1.5) * kinv
        c = (kinv - kh) / (F - Fh)
        if same and wp.isfinite(c):
            curv = c
    curvature[g] = curv
    if keep_history != 0:
        hist_F[g] = F
        hist_kinv[g] = kinv
        hist_stage[g] = st
        hist_jammed[g] = jam
