"""Batched load cycle of quarter-stitch cells (Dusserre 2015 Table 4), float64 Warp.

Device code only; the Python side is :mod:`knitsim.cell.batch`, the NumPy
oracle :mod:`knitsim.cell.cycle` (``CellCycle.advance`` / ``run``), whose
semantics this module mirrors cell by cell.

One thread advances one cell by one load increment:

1. *reversal*: when the imposed direction changes, the stage becomes SF- / SF+
   and s_BC and the soft quantity are frozen (:func:`reverse`);
2. *trial solve* of the stage's four conditions at the target course length
   (:func:`stage_conditions`, the table of :mod:`knitsim.cell.stages`); a failed
   solve is retried on a halved sub-step, down to SUBSTEP_FLOOR C0 (at most
   ``max_halvings`` halvings in a row: :func:`may_halve`); a stick sub-step whose
   first Newton step (the branch's tangent times the sub-step) is long is shortened
   before it is tried (PREDICTED_STEP_MAX; the reference only halves: the same
   equilibria and events, reached along another partition);
3. *events* (slide, jam, unjam, slack, force_cap, cone) that fire inside the
   increment are *located* by swapping the driving condition C for the event
   condition (phi = +/-phimax, W = 4d, F = 0, F = cap) and solving with C free
   (model.md, numerical hints); the nearest one along the path is applied and
   the cell goes on toward the target (several events per increment).  An
   event already satisfied at the start of the sub-step (within EVENT_TOL)
   happens there; one that the branch cannot reach is retried on a halved
   sub-step (rules in :mod:`knitsim.cell.stages`).

Dahl friction (Dahl 1976, alpha = 1) is solved as a residual of the per-cell
Newton, with the conditions {L, C, soft} (soft = Rn loading, T unloading, W = 4d
jammed)::

    r_dahl = tan(phi) - [s m + (tan(phi_old) - s m) exp(-sigma s xi / m)],
    xi = -(s_BC - s_BC_old)

where s (the slip direction, so that s xi = |xi|) is the sign of
tan(phi_stick) - tan(phi_old) of the stick trial (s_BC frozen), as in the
reference.  Its derivatives are forward-mode duals like every other residual.
The reference instead nests a scalar root search on the slip around the
four-condition solve: the two are independent checks.

Status codes are those of :mod:`knitsim.cell.history`; a failed cell keeps
its last converged state.

Launches (issue 15): :func:`step_kernel` (one increment, state in -> state out) and
:func:`program_kernel` (a range of increments in place, rows recorded) take the model,
state, event buffer and history as structs (:mod:`knitsim.kernels.cell_arrays`).  Where a
kernel key allows it (:data:`REGULAR_PASS`), each has a first pass
(:func:`regular_step_kernel`, :func:`regular_kernel`) that advances only the increments
that are regular (one trial, no event: :func:`_advance_cell_variant`) and lists the other
cells for the full kernel's launch, bit for bit the one-pass results.  Those keys also have
:func:`substep_kernel`, the full step in slices of a few sub-steps: a cell whose increment is
not done by then is suspended (its walk kept in :class:`~knitsim.kernels.cell_arrays.SuspendedArrays`)
and listed for the next launch, so that the cells still walking are compacted between launches;
bit for bit the one-launch results again.
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.history import (
    STATUS_EVENT_NOT_LOCATED, STATUS_FORCE_CAP, STATUS_NO_CONVERGENCE, STATUS_OK,
)
from knitsim.cell.quantities import Q_BETA, Q_C, Q_F, Q_L, Q_P, Q_PHI, Q_R, Q_RN, Q_S_BC, Q_T, Q_W
from knitsim.cell.stages import (
    EVENT_TOL, LABEL_CODES, MAX_DAHL_HALVINGS, OPENING_BISECTIONS, OPENING_XTOL, PROBE_STEP, REACHED_RTOL,
    RELOAD_RHO_SEED, SUBSTEP_FLOOR, ZERO_CONTACT, Stage,
)

from .cell_arrays import EventArrays, HistoryArrays, ModelArrays, StateArrays, SuspendedArrays
from .dahl import dahl_alpha1_dual
from .effects import (
    BIT_BENDING, BIT_COILING, BIT_COMPACTION, BIT_EXTENSION, BIT_NORMAL_LOAD, BIT_VELOCITY, E_B, E_D, E_L, E_M,
    E_P0, E_RN0, E_Z, P_BEND_H, P_BEND_SIGMA, P_COIL_MU, P_COMP_K, P_COMP_MIN, P_EXT_C, P_LOAD_N, P_LOAD_REF,
    P_RATE_P, P_RATE_REF, _M_MAX, _RN_FLOOR, coiling_friction, compaction_ratio, compaction_ratio_dual, dahl_bending_state, extension_ratio,
    extension_ratio_dual, has,
    normal_load_factor, velocity_factor,
)
from .elastica import (
    PI, Dual, d_add, d_addc, d_const, d_cos, d_div, d_exp, d_mul, d_neg, d_scale, d_seed, d_sin, d_sqrt, d_sub,
    d_tan, dual, elastica_ab, vec5d,
)
from .head_gap import head_gap_dual, head_gap_value
from .inverse import (
    _ARMIJO, _MAX_BACKTRACK, _MAX_DZ, STATUS_CONVERGED, STATUS_DOMAIN, STATUS_MAX_ITER,
    STATUS_NONFINITE, STATUS_SINGULAR, all_finite, evaluate_x, imposed_residual, mat55d, max_abs5, quantity_scale,
    solve5, vec4d,
)
from .quarter_loop import (
    N_QUANTITIES, CellEval, admissible, force_per_wale, quantity, quarter_loop_g0, quarter_loop_rho, sin_gamma_of_rho,
    vecQd,
)
from .specialise import INIT_KEY

wp.set_module_options({"max_unroll": 1, "enable_backward": False})

# ------------------------------------------------------------------ kernel key (issue 15)
#: The kernel key this instance of the module is compiled for: :func:`knitsim.kernels.specialised`
#: runs this file once per key (as ``knitsim.kernels.cell_step__<key>``) with ``KERNEL_KEY`` set;
#: in the generic module (``knitsim.kernels.cell_step`` itself) it is absent, and every friction
#: law, effect and jamming criterion is chosen per cell at run time.  The ``WITH_*`` flags are read
#: through ``wp.static``: the code of a law, effect or criterion that the key switches off is not
#: generated at all (a constant condition drops its branch), so a Coulomb kernel carries no Dahl
#: code, a kernel without effects no effect code, a W = 4d kernel no head-gap residual.  The
#: arithmetic of what remains is the generic module's, line for line.
_KEY = globals().get("KERNEL_KEY")
WITH_COULOMB = _KEY is None or not _KEY.dahl
WITH_DAHL = _KEY is None or bool(_KEY.dahl)
WITH_EFFECTS = _KEY is None or bool(_KEY.effects)
WITH_GAP = _KEY is None or bool(_KEY.gap)
#: the keys with a first pass of regular increments (:func:`regular_kernel`): Coulomb friction without
#: effects, whose regular increment is one trial of the whole increment
REGULAR_PASS = _KEY is not None and not _KEY.dahl and not _KEY.effects

# ------------------------------------------------------------------ codes
SF_LOAD = wp.constant(int(Stage.SF_LOAD))
S_LOAD = wp.constant(int(Stage.S_LOAD))
SF_UNLOAD = wp.constant(int(Stage.SF_UNLOAD))
S_UNLOAD = wp.constant(int(Stage.S_UNLOAD))
SLACK = wp.constant(int(Stage.SLACK))

ST_OK = wp.constant(STATUS_OK)
ST_NO_CONV = wp.constant(STATUS_NO_CONVERGENCE)
ST_CAP = wp.constant(STATUS_FORCE_CAP)
ST_NOT_LOCATED = wp.constant(STATUS_EVENT_NOT_LOCATED)

LBL_ADHERENCE = wp.constant(LABEL_CODES["adherence"])
LBL_SLIDING = wp.constant(LABEL_CODES["sliding"])
LBL_JAMMING = wp.constant(LABEL_CODES["jamming"])
LBL_SLACK = wp.constant(LABEL_CODES["slack"])

#: event kinds recorded by the kernel (names in :data:`EVENT_NAMES`)
EV_SLIDE, EV_JAM, EV_UNJAM, EV_SLACK, EV_FORCE_CAP, EV_REVERSAL, EV_RELOAD, EV_CONE = range(8)
EVENT_NAMES = ("slide", "jam", "unjam", "slack", "force_cap", "reversal", "reload", "cone")
_EV_SLIDE = wp.constant(EV_SLIDE)
_EV_JAM = wp.constant(EV_JAM)
_EV_UNJAM = wp.constant(EV_UNJAM)
_EV_SLACK = wp.constant(EV_SLACK)
_EV_CAP = wp.constant(EV_FORCE_CAP)
_EV_REVERSAL = wp.constant(EV_REVERSAL)
_EV_RELOAD = wp.constant(EV_RELOAD)
_EV_CONE = wp.constant(EV_CONE)
_EVENT_TOL = wp.constant(wp.float64(EVENT_TOL))
_PROBE_STEP = wp.constant(wp.float64(PROBE_STEP))
_REACHED_RTOL = wp.constant(wp.float64(REACHED_RTOL))
_ZERO_CONTACT = wp.constant(wp.float64(ZERO_CONTACT))
_RHO_SEED = wp.constant(wp.float64(RELOAD_RHO_SEED))
_SUBSTEP_FLOOR = wp.constant(wp.float64(SUBSTEP_FLOOR))
_MAX_DAHL_HALVINGS = wp.constant(MAX_DAHL_HALVINGS)
_OPENING_XTOL = wp.constant(wp.float64(OPENING_XTOL))
_OPENING_BISECTIONS = wp.constant(OPENING_BISECTIONS)
#: rounds and relative tolerance of the secant on B(C) at a located event (bending_fixed_point)
_BEND_ROUNDS = wp.constant(20)
_BEND_RTOL = wp.constant(wp.float64(1.0e-13))
#: the secant also stops where it no longer gains within this relative tolerance (the event solve's own
#: noise in C; its conditions are met to NEWTON_TOL, 1e-11 of d, and an ill-conditioned event C follows them
#: more loosely)
_BEND_NOISE_RTOL = wp.constant(wp.float64(1.0e-10))

#: condition code of the Dahl residual in a condition set (quantity codes are >= 0)
COND_DAHL = wp.constant(-1)
#: condition code of jamming with a compacting yarn, W = 4 d_eff(Rn) (yarn_compaction); >= 0 like a
#: quantity code, since it may replace the C condition when a jam is located (ev_code >= 0)
COND_JAM = wp.constant(100)
#: condition code of an extensible yarn's length, L = L_0 (1 + c (P - P_0)) (yarn_extension), in slot 0
COND_EXT = wp.constant(101)
#: condition code of jamming by contact: the heads of neighbouring loops at centreline distance d_jam
#: (jamming_criterion = "head_gap", kernels.head_gap), d_jam shrinking with Rn under yarn_compaction
COND_GAP = wp.constant(102)
#: condition code of sliding at the friction cone's edge where the friction ratio is a function of the state
#: (coiling_angle_friction: m(beta), eq 10; normal_load_friction: m (Rn / Rn_ref)^(n - 1), eq 5):
#: phi = s atan(m_eff(beta, Rn)), target s = +1 / -1, the ratio read at the solution itself
COND_PHI_EFF = wp.constant(103)
#: ``which`` of branch_sign_change for the cone's edge at the state's own friction ratio, phi_edge(q) - phi
SIGN_CONE_EDGE = wp.constant(-1)
#: events kept per cell and increment (more are counted, not stored)
MAX_EVENTS_PER_STEP = 8
vec8d = wp.types.vector(length=MAX_EVENTS_PER_STEP, dtype=wp.float64)
vec8i = wp.types.vector(length=MAX_EVENTS_PER_STEP, dtype=wp.int32)
#: extra data of the special residuals: (tan(phi_old), s_BC_old, s, sigma, m) of Dahl, (k, Rn_0, c_min)
#: of jamming, (c, P_0) of the extensible yarn; a Coulomb cell whose friction ratio is a function of the
#: state holds (m0, mu_k, n, Rn_ref) of friction_ratio in the Dahl slots 0-3
vec10p = wp.types.vector(length=10, dtype=wp.float64)
_MAXEV = wp.constant(MAX_EVENTS_PER_STEP)

NEWTON_MAX_ITER = wp.constant(60)
_MAX_DANGLE = wp.constant(wp.float64(0.3))
NEWTON_TOL = wp.constant(wp.float64(1.0e-11))
#: a Newton whose line search stalls (no step lowers |r|^2: the residual is at its rounding floor),
#: or that reaches NEWTON_MAX_ITER, with every scaled residual below this counts as converged.  At high load (alpha - gamma ~ 1e-4,
#: the moment at the apex ~ 1e-5 of its scale) the residuals' own rounding reaches 3e-11, above
#: NEWTON_TOL, and a solve there stalled one ulp short and was halved down to failure.
NEWTON_TOL_STALLED = wp.constant(wp.float64(1.0e-9))
#: a warm-started solve (solve_coulomb_warm) iterates to this, or to the residuals' rounding floor, in at
#: most POLISH_MAX_ITER steps
POLISH_TOL = wp.constant(wp.float64(1.0e-13))
POLISH_MAX_ITER = wp.constant(2)
#: longest first Newton step (max norm, Newton variables) a later coupling trial takes without evaluating its
#: end (:func:`newton_solve`'s ``max_unverified``): Newton's error after it, ~1e-12 |r''|, is below NEWTON_TOL
WARM_STEP_MAX = wp.constant(wp.float64(1.0e-6))
#: the Newton runs in the chart with ln G(0) in place of R/P when G(0) (theta'_C lambda)^2 / 2, of
#: elastica BC, is below this (and below cos(alpha - gamma), where the chart is one to one) at its start
#: (:func:`newton`).  1e-2 until the stick stages' crawl was traced: a reload SF+ with Rn frozen at
#: G(0) ~ 0.05 took 22 iterations for a sub-step of 0.007 mm, its line search accepting steps of 1/32 to
#: 1/64 (the L residual of the full step 60 times that of the start); with 0.5, 3.7 iterations a solve on
#: the same cells, results within 3e-11 N (300 random cells x 3 cycles)
G0_CHART = wp.constant(wp.float64(0.5))
#: at most this many events located per increment (as the reference)
MAX_EVENT_LOOPS = wp.constant(12)
#: guard on the sub-steps of one increment (the reference has none; it is never reached in practice)
MAX_SUBSTEPS = wp.constant(4096)
#: status of :func:`newton_first` when its first Newton step is longer than asked (no iteration taken)
STATUS_STEP_LONG = wp.constant(100)
#: a sub-step's trial solve is not attempted when the first Newton step from the sub-step's converged start
#: (the branch's tangent times the sub-step) is longer than this in the Newton variables (max norm): the
#: sub-step is first shortened so that the step is about PREDICTED_STEP_TARGET (below, :func:`advance_cell`)
PREDICTED_STEP_MAX = wp.constant(wp.float64(0.1))
PREDICTED_STEP_TARGET = wp.constant(wp.float64(0.05))
#: a Dahl stick trial whose first Newton step is longer than PREDICTED_STEP_MAX is not solved where the step
#: moves phi by more than this [rad]: the step's sign of phi is the slip direction (:func:`dahl_sign`)
DAHL_SIGN_DPHI = wp.constant(wp.float64(1.0e-3))


# ------------------------------------------------------------------ material
@wp.struct
class Material:
    """One cell's parameters (read from the model arrays, see knitsim.cell.batch)."""

    B: wp.float64
    d: wp.float64
    L: wp.float64
    W0: wp.float64
    C0: wp.float64
    m: wp.float64
    phimax: wp.float64
    phi0: wp.float64
    sigma: wp.float64
    cap: wp.float64
    w_jam: wp.float64
    dahl: int
    hong: int
    mirror: int
    closure: int  # 1: "release_beta" stick closure (knitsim.cell.stages.STICK_CLOSURES)
    gap: int  # jamming criterion: 0 W = 4 d_jam (Hong), 1 head gap = d_jam (contact of neighbouring heads)
    comp_k: wp.float64  # yarn_compaction (issue 6): compliance [1/N], 0 when off
    comp_rn0: wp.float64  # its rest normal load [N]
    comp_min: wp.float64  # its smallest d_eff / d
    ext_c: wp.float64  # yarn_extension (issue 6): tensile compliance [1/N], 0 when off
    ext_p0: wp.float64  # its rest yarn force P_0 [N] (L is the length at P_0)
    fr_state: int  # 1: the friction ratio is a function of the state (coiling and/or normal load, Coulomb)
    fr_m0: wp.float64  # its factor: m x velocity factor, or the velocity factor alone under coiling
    fr_mu: wp.float64  # coiling_angle_friction's mu_k of eq 10, 0 when off
    fr_n: wp.float64  # normal_load_friction's n of eq 5, 1 when off
    fr_ref: wp.float64  # its reference normal load [N]
    bend_h: wp.float64  # bending_hysteresis (issue 6): h of B (1 + h z), 0 when off
    bend_sigma: wp.float64  # its Dahl rate in the strain
    bend_z0: wp.float64  # z at the course length bend_C (the increment's start)
    bend_C: wp.float64  # that course length [mm]
    bend_s: wp.float64  # the increment's direction, +1 / -1 (0: no bending over it, z stays bend_z0)


@wp.func
def bends(mat: Material) -> wp.bool:
    """Whether the cell's B follows its bending Dahl state (bending_hysteresis on)."""
    out = wp.static(WITH_EFFECTS)
    if wp.static(WITH_EFFECTS):
        out = mat.bend_h != wp.float64(0.0)
    return out


@wp.func
def bending_z(mat: Material, C: wp.float64) -> wp.float64:
    """The bending Dahl state at course length C of the increment: Dahl's closed form over the
    monotone strain (C - bend_C) / C0 from bend_z0 (kernels.effects.dahl_bending_state), so that
    z, hence B, is a function of the state's own C and not of where the increments fall."""
    z = mat.bend_z0
    if mat.bend_s != wp.float64(0.0):
        de = wp.max(mat.bend_s * (C - mat.bend_C), wp.float64(0.0)) / mat.C0
        z = dahl_bending_state(mat.bend_z0, mat.bend_s * de, mat.bend_sigma)
    return z


@wp.func
def stiffness_at(mat: Material, C: wp.float64) -> wp.float64:
    """The bending stiffness of a state at course length C: B (1 + h z(C)) under bending
    hysteresis (read at the solution itself), else B."""
    B = mat.B
    if bends(mat):
        B = mat.B * (wp.float64(1.0) + mat.bend_h * bending_z(mat, C))
    return B


# ------------------------------------------------------------------ Newton
@wp.func
def dahl_residual(cell: CellEval, dp: vec10p):
    """Dahl relation (alpha = 1) over the increment as a Dual residual.

    ``dp = (tan(phi_old), s_BC_old, s, sigma, m)``; slip xi = -(s_BC - s_BC_old),
    so ``s xi = |xi|`` on the branch sought (Dahl 1976; knitsim.friction.dahl).
    """
    t_old = dp[0]
    s = dp[2]
    m = dp[4]
    t = d_tan(quantity(cell, Q_PHI))
    xi = d_sub(d_const(dp[1]), quantity(cell, Q_S_BC))
    return d_sub(t, dahl_alpha1_dual(t_old, xi, s, dp[3], m))


@wp.func
def jam_residual(cell: CellEval, w_jam: wp.float64, dp: vec10p):
    """W - w_jam d_eff(Rn)/d: jamming at four compacted diameters, the load read at the solution itself."""
    ratio = compaction_ratio_dual(quantity(cell, Q_RN), dp[6], dp[5], dp[7])
    return d_sub(quantity(cell, Q_W), d_scale(ratio, w_jam))


@wp.func
def extension_residual(cell: CellEval, L_rest: wp.float64, dp: vec10p):
    """L - L_0 (1 + c (P - P_0)) (kernels.effects.extension_ratio): the length that the yarn force at
    the solution itself gives (implicit: a length lagged by one increment is a first-order error in
    the increment, large beside the noise of a measured curve on the stiff jammed branch)."""
    ratio = extension_ratio_dual(quantity(cell, Q_P), dp[9], dp[8])
    return d_sub(quantity(cell, Q_L), d_scale(ratio, L_rest))


@wp.func
def gap_residual(cell: CellEval, z: vec5d, d_jam: wp.float64, dp: vec10p, B: wp.float64):
    """head gap - d_jam d_eff(Rn)/d: neighbouring heads in contact (jamming_criterion = "head_gap"), the
    compacted width read at the solution itself as in jam_residual (ratio 1 without compaction)."""
    a = d_exp(d_seed(z[0], 0))
    ratio = compaction_ratio_dual(quantity(cell, Q_RN), dp[6], dp[5], dp[7])
    return d_sub(head_gap_dual(cell, a, B), d_scale(ratio, d_jam))


@wp.func
def friction_ratio(beta: wp.float64, Rn: wp.float64, m0: wp.float64, mu: wp.float64, n: wp.float64,
                   ref: wp.float64):
    """The friction ratio of the state (kernels.effects, read at the state instead of the increment's
    start) and its partial derivatives: returns (m, dm/dbeta, dm/dRn).

    m = m0 c(beta) f(Rn), capped at M_EFF_MAX: c the coiling ratio of eq 10 at the coiling angle beta,
    tanh(mu beta / 2) tan(beta / 2) (kernels.friction.coiling_ratio_m; 1 when mu = 0), f the
    normal-load factor of eq 5, (max(|Rn|, floor Rn_ref) / Rn_ref)^(n - 1) (kernels.effects
    .normal_load_factor; 1 when n = 1)."""
    c = wp.float64(1.0)
    dc = wp.float64(0.0)
    if mu > wp.float64(0.0):
        th = wp.tanh(wp.float64(0.5) * mu * beta)
        t = wp.tan(wp.float64(0.5) * beta)
        c = th * t
        dc = wp.float64(0.5) * mu * (wp.float64(1.0) - th * th) * t + wp.float64(0.5) * th * (wp.float64(1.0) + t * t)
    f = wp.float64(1.0)
    df = wp.float64(0.0)
    if n != wp.float64(1.0):
        a = wp.abs(Rn)
        fl = _RN_FLOOR * ref
        if a > fl:
            f = wp.pow(a / ref, n - wp.float64(1.0))
            df = (n - wp.float64(1.0)) * f / a
            if Rn < wp.float64(0.0):
                df = -df
        else:
            f = wp.pow(fl / ref, n - wp.float64(1.0))
    m = m0 * c * f
    dmb = m0 * dc * f
    dmr = m0 * c * df
    if m > _M_MAX:
        m = _M_MAX
        dmb = wp.float64(0.0)
        dmr = wp.float64(0.0)
    return m, dmb, dmr


@wp.func
def phi_edge_residual(cell: CellEval, s: wp.float64, dp: vec10p):
    """phi - s atan(m(beta, Rn)): sliding at the edge s = +1 / -1 of the state's own friction cone
    (friction_ratio; Coulomb cells with coiling_angle_friction or normal_load_friction).  Implicit: a
    ratio lagged by one increment is a first-order error in the increment, and near F = 0 on unloading
    (Rn -> 0 raises the ratio when n < 1) it moved the slack point by 0.1 mm from one halving to the
    next (knitsim issue 12)."""
    be = quantity(cell, Q_BETA)
    rn = quantity(cell, Q_RN)
    m, dmb, dmr = friction_ratio(be.v, rn.v, dp[0], dp[1], dp[2], dp[3])
    k = s / (wp.float64(1.0) + m * m)
    return dual(quantity(cell, Q_PHI).v - s * wp.atan(m), quantity(cell, Q_PHI).g - k * (dmb * be.g + dmr * rn.g))


@wp.func
def residuals_ext(cell: CellEval, z: vec5d, codes: wp.vec4i, targets: vec4d, dp: vec10p, B: wp.float64,
                  d: wp.float64):
    """As kernels.inverse.residuals, with codes COND_DAHL (the Dahl residual), COND_JAM
    (W = 4 d_eff(Rn), target the rigid yarn's jam width), COND_GAP (head gap = d_eff(Rn), target
    the rigid yarn's in-plane width) and COND_EXT (the extensible yarn's length, target the rest
    length).  ``z`` are the Newton variables of ``cell`` (the head gap needs alpha - gamma at full
    precision)."""
    r = vec5d()
    J = mat55d()
    r[0] = cell.g / d
    J[0] = cell.dg / d
    for k in range(4):
        c = codes[k]
        # residuals the kernel key switches off are constant False: their code is not generated
        is_dahl = wp.static(WITH_DAHL)
        if wp.static(WITH_DAHL):
            is_dahl = c == COND_DAHL
        is_jam = wp.static(WITH_EFFECTS)
        is_ext = wp.static(WITH_EFFECTS)
        if wp.static(WITH_EFFECTS):
            is_jam = c == COND_JAM
            is_ext = c == COND_EXT
        is_gap = wp.static(WITH_GAP)
        if wp.static(WITH_GAP):
            is_gap = c == COND_GAP
        is_edge = wp.static(WITH_EFFECTS)
        if wp.static(WITH_EFFECTS):
            is_edge = c == COND_PHI_EFF
        if is_dahl:
            rd = dahl_residual(cell, dp)
            r[k + 1] = rd.v
            J[k + 1] = rd.g
        elif is_jam:
            rj = jam_residual(cell, targets[k], dp)
            r[k + 1] = rj.v / d
            J[k + 1] = rj.g / d
        elif is_ext:
            re = extension_residual(cell, targets[k], dp)
            r[k + 1] = re.v / d
            J[k + 1] = re.g / d
        elif is_gap:
            rg = gap_residual(cell, z, targets[k], dp, B)
            r[k + 1] = rg.v / d
            J[k + 1] = rg.g / d
        elif is_edge:
            rp = phi_edge_residual(cell, targets[k], dp)
            r[k + 1] = rp.v
            J[k + 1] = rp.g
        else:
            rk, gk = imposed_residual(cell, c, targets[k], B, d)
            r[k + 1] = rk
            J[k + 1] = gk
    return r, J


@wp.func
def sin_gamma(z: vec5d) -> wp.float64:
    """sin(gamma) = -(R/P) cos(beta + phi) (eq 7, R_Y = P sin gamma)."""
    return -z[2] * wp.cos(z[1] + z[3])


@wp.func
def evaluate_zr(z: vec5d, B: wp.float64, d: wp.float64):
    """The cell at z = (ln(alpha - gamma), beta, R/P, phi, ln P), gradients with respect to z.

    R/P replaces gamma (as in knitsim.cell.inverse): with gamma as unknown, R and
    k1' are 0/0 where the contact force is horizontal (beta + phi = pi/2) at zero
    force per wale."""
    a = d_exp(d_seed(z[0], 0))
    P = d_exp(d_seed(z[4], 4))
    return quarter_loop_rho(a, d_seed(z[1], 1), d_seed(z[2], 2), d_seed(z[3], 3), P, B, d)


@wp.func
def zr_admissible(z: vec5d) -> wp.bool:
    """kernels.quarter_loop.admissible in the variables (ln(alpha - gamma), beta, R/P, phi, ln P).

    Same conditions, with k1' = cos(gamma) - (R/P) sin(beta + phi) and without
    the test cos(beta + phi) != 0, which R/P makes unnecessary (the slack point
    of S- sits exactly at beta + phi = pi/2)."""
    ok = bool(False)
    a = wp.exp(z[0])
    beta = z[1]
    phi = z[3]
    P = wp.exp(z[4])
    sg = sin_gamma(z)
    if wp.isfinite(a) and wp.isfinite(beta) and wp.isfinite(z[2]) and wp.isfinite(phi) and wp.isfinite(P) and wp.isfinite(sg):
        if wp.abs(sg) < wp.float64(1.0) and wp.abs(phi) < wp.float64(0.5) * PI:
            gamma = wp.asin(sg)
            b = beta - gamma
            if a > wp.float64(0.0) and b > a and b < PI and beta < PI and P > wp.float64(0.0):
                k1p = wp.cos(gamma) - z[2] * wp.sin(beta + phi)
                D = wp.float64(2.0) * wp.sin(wp.float64(0.5) * (b + a)) * wp.sin(wp.float64(0.5) * (b - a))
                ok = D + k1p * (wp.float64(1.0) + wp.cos(beta)) > wp.float64(1.0e-12)
    return ok


@wp.func
def x_of_z(z: vec5d):
    """(alpha, beta, gamma, phi, P) from the Newton variables."""
    g = wp.asin(sin_gamma(z))
    return vec5d(g + wp.exp(z[0]), z[1], g, z[3], wp.exp(z[4]))


@wp.func
def z_of(x: vec5d, q: vecQd):
    """Newton variables of a state: R/P from the stored quantities (no 0/0)."""
    return vec5d(wp.log(x[0] - x[2]), x[1], q[Q_R] / q[Q_P], x[3], wp.log(x[4]))


@wp.func
def apex_g0(z: vec5d) -> wp.float64:
    """G(0) = (theta'_C lambda)^2 / 2 of elastica BC (kernels.elastica: D + k1' (1 + cos beta)) at
    the Newton variables z = (ln(alpha - gamma), beta, R/P, phi, ln P).

    With sin(gamma) = -(R/P) cos(beta + phi) and k1' = cos(gamma) - (R/P) sin(beta + phi) (eq 7),
    D + k1' (1 + cos beta) = cos a + cos gamma - (R/P) (sin(beta + phi) + sin phi)."""
    bp = z[1] + z[3]
    rc = z[2] * wp.cos(bp)
    return wp.cos(wp.exp(z[0])) + wp.sqrt(wp.float64(1.0) - rc * rc) - z[2] * (wp.sin(bp) + wp.sin(z[3]))


@wp.func
def rho_of_g0(a: Dual, beta: Dual, w: Dual, phi: Dual):
    """R/P of the state with G(0) = exp(w) (the inverse of apex_g0 at fixed a, beta, phi), as a Dual.

    G(0) = cos a + sqrt(1 - rho^2 c^2) - rho s, c = cos(beta + phi), s = sin(beta + phi) + sin phi,
    is a quadratic in rho once squared: with E = G(0) - cos a,
    rho = (-E s + sgn(s) sqrt(s^2 + c^2 (1 - E^2))) / (s^2 + c^2), the root with
    sqrt(1 - rho^2 c^2) = E + rho s >= 0.  Where E < 0 (G(0) < cos a: every state near the edge
    G(0) = 0) it is the only root, rho s > 0, and dG(0)/drho = -(rho c^2 / cos gamma + s) never
    vanishes: the chart is one to one there.  1 + E = G(0) + 2 sin^2(a/2) is formed without
    cancellation (G(0) and a both tiny at the edge)."""
    bp = d_add(beta, phi)
    c = d_cos(bp)
    s = d_add(d_sin(bp), d_sin(phi))
    h = d_sin(d_scale(a, wp.float64(0.5)))
    e1 = d_add(d_exp(w), d_scale(d_mul(h, h), wp.float64(2.0)))  # 1 + E
    E = d_addc(e1, wp.float64(-1.0))
    c2 = d_mul(c, c)
    s2 = d_mul(s, s)
    disc = d_add(s2, d_mul(c2, d_mul(e1, d_addc(d_neg(e1), wp.float64(2.0)))))  # s^2 + c^2 (1+E)(1-E)
    root = d_sqrt(disc)
    if s.v < wp.float64(0.0):
        root = d_neg(root)
    return d_div(d_sub(root, d_mul(E, s)), d_add(s2, c2))


@wp.func
def chart_to_zr(zc: vec5d, chart: int) -> vec5d:
    """The Newton variables (ln(alpha - gamma), beta, R/P, phi, ln P) of a point of the chart
    (chart 1: ln G(0) in place of R/P, see :func:`newton`)."""
    z = zc
    if chart != 0:
        z[2] = rho_of_g0(d_const(wp.exp(zc[0])), d_const(zc[1]), d_const(zc[2]), d_const(zc[3])).v
    return z


@wp.func
def force_gradient(zc: vec5d, chart: int) -> vec5d:
    """dF/dz of the force per wale at a point of the chart (the Newton variables, or with chart 1 ln G(0) in
    place of R/P): F = 2 P sin(gamma), sin(gamma) = -(R/P) cos(beta + phi) (eq 7), the laws of the
    assembly (:func:`~knitsim.kernels.quarter_loop.force_per_wale`), without the elastica integrals."""
    beta = d_seed(zc[1], 1)
    phi = d_seed(zc[3], 3)
    rho = d_seed(zc[2], 2)
    if chart != 0:
        rho = rho_of_g0(d_exp(d_seed(zc[0], 0)), beta, d_seed(zc[2], 2), phi)
    return force_per_wale(d_exp(d_seed(zc[4], 4)), sin_gamma_of_rho(rho, d_cos(d_add(beta, phi)))).g


@wp.func
def evaluate_chart(zc: vec5d, chart: int, B: wp.float64, d: wp.float64):
    """:func:`evaluate_zr` at a point of the chart, gradients with respect to the chart's variables."""
    cell = CellEval()
    if chart == 0:
        cell = evaluate_zr(zc, B, d)
    else:
        a = d_exp(d_seed(zc[0], 0))
        beta = d_seed(zc[1], 1)
        phi = d_seed(zc[3], 3)
        w = d_seed(zc[2], 2)
        rho = rho_of_g0(a, beta, w, phi)
        # elastica BC reads G(0) = exp(w) itself, not D + k1'(1 + cos beta) formed again from rho by
        # cancellation (relative rounding 1e-16 / G(0) in its ln G(0) integrals: issue 14)
        cell = quarter_loop_g0(a, beta, rho, phi, d_exp(d_seed(zc[4], 4)), d_exp(w), B, d)
    return cell


@wp.func
def enter_chart(z0: vec5d):
    """The chart :func:`newton_solve` iterates in from z0 (its docstring): (z0 in that chart, 1), ln G(0) in
    place of R/P, near the edge G(0) = 0; else (z0, 0)."""
    z = z0
    chart = int(0)
    g0 = apex_g0(z0)
    if g0 < G0_CHART and g0 < wp.cos(wp.exp(z0[0])):
        chart = int(1)
        z[2] = wp.log(g0)
    return z, chart


@wp.func
def branch_slope(dF: vec5d, J: mat55d, B: wp.float64, d: wp.float64) -> wp.float64:
    """dF/dC of a converged state on its branch, from the Jacobian J of its Newton and the gradient dF of
    its force (implicit function theorem; :mod:`knitsim.kernels.cell_tangent` derives it): the stage's
    conditions with the driving condition (C(z) - C) / s_C in slot 1 (row 2), so dr/dC = -e_2 / s_C and
    dz/dC = J^-1 e_2 / s_C.  J and dF in the same variables (either chart).  NaN where J is singular."""
    e = vec5d()
    e[2] = wp.float64(1.0) / quantity_scale(Q_C, B, d)
    dz, singular = solve5(J, e)
    k = wp.float64(wp.nan)
    if not singular:
        k = wp.dot(dF, dz)
    return k


@wp.func
def newton(z0: vec5d, codes: wp.vec4i, targets: vec4d, dp: vec10p, B: wp.float64, d: wp.float64):
    """:func:`newton_first` without a bound on its first step: returns (z, q, status)."""
    z, q, st, step0, slope = newton_first(z0, codes, targets, dp, B, d, wp.float64(0.0), False)
    return z, q, st


@wp.func
def newton_first(z0: vec5d, codes: wp.vec4i, targets: vec4d, dp: vec10p, B: wp.float64, d: wp.float64,
                 max_first: wp.float64, want_slope: wp.bool):
    """:func:`newton_solve` with the cell step's tolerances: returns (z, q, status, step0, slope)."""
    z, q, st, step0, n, slope = newton_solve(z0, codes, targets, dp, B, d, max_first, NEWTON_TOL,
                                             NEWTON_TOL_STALLED, NEWTON_MAX_ITER, wp.float64(0.0), want_slope)
    return z, q, st, step0, slope


@wp.func
def newton_solve(z0: vec5d, codes: wp.vec4i, targets: vec4d, dp: vec10p, B: wp.float64, d: wp.float64,
                 max_first: wp.float64, tol: wp.float64, tol_stalled: wp.float64, max_iter: int,
                 max_unverified: wp.float64, want_slope: wp.bool):
    """The Newton solve of one cell: g = 0 (eq 6) and the four conditions ``codes`` = ``targets``
    (Table 4; :func:`residuals_ext`), in the variables z = (ln(alpha - gamma), beta, R/P, phi, ln P).
    The one Newton of the package: the cell step (:func:`newton_first`) and the inverse solve
    (:func:`solve_conditions_kernel`, ``knitsim.cell.warp_solve.solve_batch``) both call it.

    Near the edge G(0) = 0 of the domain (:func:`apex_g0`; theta' vanishes at the apex C, where
    T > 0) the iteration runs in the chart (ln(alpha - gamma), beta, ln G(0), phi, ln P) instead
    (:func:`rho_of_g0`), chosen at the start when G(0) < G0_CHART and G(0) < cos(alpha - gamma).
    There the integrals of BC go as -(sqrt(B/T)/2) ln G(0) (L, s_BC, X_B, W: the near-straight
    stretch at C), and G(0) is a small difference of O(1) terms: in R/P the residuals curve on a
    scale of G(0) itself, and the line search crawled (steps of 1/32 to 1/2048, 60 iterations,
    sub-steps halved to 1e-5 mm on the reloads S- -> SF+); with ln G(0) as a variable the edge
    is at -infinity and the same solves converge in 3 to 6 iterations.  Same equations, same
    root (the charts agree on their overlap); only the path of the iterates differs.

    Each step is damped (|dz_i| <= 1, angle steps <= 0.3 rad) and backtracked (Armijo on |r|^2),
    the backtracking starting from 4 times the step length accepted last (at most 1).

    With ``max_first > 0`` the solve stops before its first step when that step is longer than
    ``max_first`` (max norm of dz, before damping), with status STATUS_STEP_LONG, z0 and the step: from
    a converged state of the same conditions that step is the branch's tangent times the change of
    the driving condition, so it predicts where the branch goes and whether the step can converge at once.

    Converged when every scaled residual is <= ``tol``; after ``max_iter`` steps, or where the line
    search finds no decrease, also when they are <= ``tol_stalled`` (creeping along the rounding floor).

    With ``max_unverified > 0``, a first step no longer than it (max norm of dz) is taken without
    evaluating its end, and the solve stops there converged: from a state that converged on the same
    conditions a little away (a patch's later coupling trial, whose C moved by the column's correction)
    Newton's error after that step is of the order of |r''| |dz|^2, about 1e-12 |r''| at 1e-6, below
    the cell step's tolerance (NEWTON_TOL): the step is the root to that tolerance, the end's
    quantities are those of the start carried along the step to first order (q + dq/dz dz, their error
    of the same order), and the evaluation that would only confirm it is saved.  Its slope dF/dC comes
    from the start's Jacobian (:func:`branch_slope`; O(|dz|) from the end's, far below its use).

    With ``want_slope``, a converged solve also gives the branch's slope dF/dC at its solution, from the
    Jacobian of its last iterate (:func:`branch_slope`, :func:`force_gradient`): what the tangent kernel
    computes there with one more evaluation.

    Returns (z, q, status, step0, steps, slope): the solution (or last admissible iterate) in the
    variables z, all quantities at it, an inverse status code (0 converged), the first step (in the
    chart's variables; z[3] = phi in both) where the solve stopped for it (else zero), the Newton
    steps taken, and dF/dC where the unverified step was taken, or, with ``max_unverified > 0`` or
    ``want_slope``, the solve converged (else NaN).
    """
    st = int(STATUS_MAX_ITER)
    step0 = vec5d()
    z = z0
    q = vecQd()
    n = int(0)
    slope = wp.float64(wp.nan)
    if not zr_admissible(z0):
        st = int(STATUS_DOMAIN)
    else:
        z, chart = enter_chart(z0)
        cell = evaluate_chart(z, chart, B, d)
        zr = chart_to_zr(z, chart)
        r, J = residuals_ext(cell, zr, codes, targets, dp, B, d)
        q = cell.q
        short = bool(False)
        if all_finite(r, J) and max_unverified > wp.float64(0.0):
            # the short first step, its end not evaluated (docstring); before the loop, so that nothing of
            # it stays live there.  A start already converged gives its slope too
            if max_abs5(r) <= tol:
                slope = branch_slope(quantity(cell, Q_F).g, J, B, d)
            else:
                dz0, singular0 = solve5(J, -r)
                if not singular0 and max_abs5(dz0) <= max_unverified:
                    z_end = chart_to_zr(z + dz0, chart)
                    if zr_admissible(z_end):
                        slope = branch_slope(quantity(cell, Q_F).g, J, B, d)
                        q = cell.q + cell.dq * dz0
                        zr = z_end
                        n = 1
                        st = int(STATUS_CONVERGED)
                        short = True
        if not all_finite(r, J):
            st = int(STATUS_NONFINITE)
        elif not short:
            f = wp.dot(r, r)
            lam_prev = wp.float64(1.0)
            while True:
                if max_abs5(r) <= tol:
                    st = int(STATUS_CONVERGED)
                    break
                if n >= max_iter:
                    st = int(STATUS_MAX_ITER)
                    if max_abs5(r) <= tol_stalled:
                        st = int(STATUS_CONVERGED)  # creeping along the rounding floor
                    break
                dz, singular = solve5(J, -r)
                if singular:
                    st = int(STATUS_SINGULAR)
                    break
                mx = max_abs5(dz)
                if n == 0 and max_first > wp.float64(0.0) and mx > max_first:
                    st = int(STATUS_STEP_LONG)
                    step0 = dz
                    break
                if mx > _MAX_DZ:
                    dz = dz * (_MAX_DZ / mx)
                # keep the angle steps moderate, as the reference does: the map is only locally smooth
                ma = wp.max(wp.abs(dz[1]), wp.abs(dz[3]))
                if ma > _MAX_DANGLE:
                    dz = dz * (_MAX_DANGLE / ma)
                # the backtracking starts at 4 times the last accepted step (at most 1): where the line
                # search needs lambda = 1/32 iteration after iteration it tries 3 lengths, not 6
                lam = wp.min(wp.float64(1.0), wp.float64(4.0) * lam_prev)
                accepted = bool(False)
                any_adm = bool(False)
                any_nonfinite = bool(False)
                for k in range(_MAX_BACKTRACK):
                    zt = z + dz * lam
                    zrt = chart_to_zr(zt, chart)
                    if zr_admissible(zrt):
                        any_adm = True
                        ct = evaluate_chart(zt, chart, B, d)
                        rt, Jt = residuals_ext(ct, zrt, codes, targets, dp, B, d)
                        if all_finite(rt, Jt):
                            ft = wp.dot(rt, rt)
                            if ft <= (wp.float64(1.0) - wp.float64(2.0) * _ARMIJO * lam) * f:
                                z = zt
                                zr = zrt
                                r = rt
                                J = Jt
                                f = ft
                                q = ct.q
                                accepted = True
                                break
                        else:
                            any_nonfinite = True
                    lam = lam * wp.float64(0.5)
                n += 1
                if accepted:
                    lam_prev = lam
                if not accepted:
                    if not any_adm:
                        st = int(STATUS_DOMAIN)
                    elif any_nonfinite:
                        st = int(STATUS_NONFINITE)
                    elif max_abs5(r) <= tol_stalled:
                        st = int(STATUS_CONVERGED)  # at the rounding floor of the residuals
                    else:
                        st = int(STATUS_MAX_ITER)
                    break
            if want_slope and st == STATUS_CONVERGED:
                slope = branch_slope(force_gradient(z, chart), J, B, d)
        z = zr
    return z, q, st, step0, n, slope


@wp.func
def no_dahl():
    return vec10p()


@wp.func
def effect_params(mat: Material):
    """The residuals' extra data without Dahl: the compaction law of the jammed condition and the
    extensible yarn's law."""
    dp = vec10p()
    if mat.fr_state != 0:
        dp[0] = mat.fr_m0
        dp[1] = mat.fr_mu
        dp[2] = mat.fr_n
        dp[3] = mat.fr_ref
    dp[5] = mat.comp_k
    dp[6] = mat.comp_rn0
    dp[7] = mat.comp_min
    dp[8] = mat.ext_c
    dp[9] = mat.ext_p0
    return dp


@wp.func
def length_code(mat: Material) -> int:
    """Condition on the yarn length: L, or L = L_0 (1 + c (P - P_0)) with an extensible yarn."""
    c = int(Q_L)
    if mat.ext_c > wp.float64(0.0):
        c = int(COND_EXT)
    return c


@wp.func
def jam_code(mat: Material) -> int:
    """Condition of jamming: W = 4 d, or W = 4 d_eff(Rn) with a compacting yarn; the head gap = d
    (d_eff(Rn)) under the contact criterion."""
    c = int(Q_W)
    if mat.gap != 0:
        c = int(COND_GAP)
    elif mat.comp_k > wp.float64(0.0):
        c = int(COND_JAM)
    return c


@wp.func
def jam_target(mat: Material) -> wp.float64:
    """Target of jam_code: the jamming wale width 4 d_jam, or the in-plane width d_jam itself."""
    t = mat.w_jam
    if mat.gap != 0:
        t = wp.float64(0.25) * mat.w_jam
    return t


@wp.func
def jam_width(mat: Material, Rn: wp.float64) -> wp.float64:
    """Wale width at which loops jam, 4 d_eff (kernels.effects.compaction_ratio at the load Rn)."""
    w = mat.w_jam
    compacting = wp.static(WITH_EFFECTS)
    if wp.static(WITH_EFFECTS):
        compacting = mat.comp_k > wp.float64(0.0)
    if compacting:
        w = mat.w_jam * compaction_ratio(Rn, mat.comp_rn0, mat.comp_k, mat.comp_min)
    return w


@wp.func
def jam_clearance(z: vec5d, q: vecQd, mat: Material) -> wp.float64:
    """How far a state is from jamming [mm], >= 0 unjammed: W - 4 d_eff (Hong), or the head gap
    minus d_eff (contact of neighbouring heads, kernels.head_gap)."""
    w = jam_width(mat, q[Q_RN])
    v = q[Q_W] - w
    by_gap = wp.static(WITH_GAP)
    if wp.static(WITH_GAP):
        by_gap = mat.gap != 0
    if by_gap:
        v = head_gap_value(wp.exp(z[0]), q, stiffness_at(mat, q[Q_C])) - wp.float64(0.25) * w
    return v


# ------------------------------------------------------------------ Table 4
@wp.func
def stage_conditions(stage: int, jammed: int, soft: int, frozen_soft: wp.float64, frozen_sbc: wp.float64,
                     mat: Material, C: wp.float64):
    """The four imposed quantities of a stage at course length C (CellCycle.conditions).

    Slots: 0 L, 1 C (the driving condition, swapped for an event condition when
    an event is located), 2 the hard condition (s_BC, phi = +/-phimax, or the
    Dahl residual), 3 the soft condition frozen at entry (W = 4d when jammed).
    """
    codes = wp.vec4i(length_code(mat), Q_C, Q_S_BC, soft)
    tg = vec4d(mat.L, C, frozen_sbc, frozen_soft)
    if mat.dahl != 0:
        codes[2] = COND_DAHL
    elif stage == S_LOAD:
        codes[2] = Q_PHI
        tg[2] = mat.phimax
    elif stage == S_UNLOAD:
        codes[2] = Q_PHI
        tg[2] = -mat.phimax
    if (stage == S_LOAD or stage == S_UNLOAD) and mat.dahl == 0 and mat.fr_state != 0:
        codes[2] = COND_PHI_EFF
        tg[2] = wp.float64(1.0)
        if stage == S_UNLOAD:
            tg[2] = wp.float64(-1.0)
    if jammed != 0:
        codes[3] = jam_code(mat)
        tg[3] = jam_target(mat)
    return codes, tg


@wp.func
def phi_edge(q: vecQd, mat: Material) -> wp.float64:
    """The friction cone's half-angle at the state q: phimax, or atan of the state's own friction ratio
    (friction_ratio) where it is a function of the state."""
    e = mat.phimax
    state_ratio = wp.static(WITH_EFFECTS)
    if wp.static(WITH_EFFECTS):
        state_ratio = mat.fr_state != 0
    if state_ratio:
        m, dmb, dmr = friction_ratio(q[Q_BETA], q[Q_RN], mat.fr_m0, mat.fr_mu, mat.fr_n, mat.fr_ref)
        e = wp.atan(m)
    return e


@wp.func
def is_loading(stage: int) -> wp.bool:
    return stage == SF_LOAD or stage == S_LOAD


@wp.func
def is_sliding(stage: int) -> wp.bool:
    return stage == S_LOAD or stage == S_UNLOAD


@wp.func
def stage_label(stage: int, jammed: int) -> int:
    """Label code (knitsim.cell.stages.LABEL_CODES) of a stage."""
    lbl = int(LBL_ADHERENCE)
    if stage == SLACK:
        lbl = int(LBL_SLACK)
    elif jammed != 0:
        lbl = int(LBL_JAMMING)
    elif is_sliding(stage):
        lbl = int(LBL_SLIDING)
    return lbl


@wp.func
def no_contact(q: vecQd) -> wp.bool:
    """The contact force vanishes: |R| <= ZERO_CONTACT P (phi undetermined; stages.ZERO_CONTACT)."""
    return wp.abs(q[Q_R]) <= _ZERO_CONTACT * wp.max(wp.abs(q[Q_P]), wp.float64(1.0e-12))


@wp.func
def seed_contact(z: vec5d) -> vec5d:
    """Newton start at a zero-contact state: R/P = RELOAD_RHO_SEED instead of 0 (singular there)."""
    zs = z
    if wp.abs(z[2]) <= _ZERO_CONTACT:
        zs[2] = _RHO_SEED
    return zs


@wp.func
def reverse(direction: int, q: vecQd, mat: Material, soft_old: int, fsoft_old: wp.float64):
    """Load reversal (CellCycle.reverse): returns (stage, soft, frozen_soft, frozen_sbc)."""
    frozen_sbc = q[Q_S_BC]
    stage = int(SF_LOAD)
    soft = int(Q_RN)
    if direction < 0:
        stage = int(SF_UNLOAD)
        soft = int(Q_BETA)
        if mat.hong != 0 or mat.dahl != 0:
            soft = int(Q_T)
        if no_contact(q):
            # no contact force to unload: the cell is slack at once (CellCycle.reverse)
            stage = int(SLACK)
    else:
        tiny = wp.abs(q[Q_RN]) < _ZERO_CONTACT * wp.max(q[Q_P], wp.float64(1.0e-12))
        if tiny and mat.mirror != 0:
            # the mirror of the unloading: SF- freezes beta (Coulomb; S+ then T), Dahl's unloading T throughout
            soft = int(Q_BETA)
            if mat.dahl != 0:
                soft = int(Q_T)
    fsoft = q[soft]
    if mat.dahl == 0 and mat.m == wp.float64(0.0) and stage != SLACK:
        # frictionless: one curve for loading and unloading, the loading branch's
        # soft condition stays frozen (CellCycle.reverse)
        soft = soft_old
        fsoft = fsoft_old
        stage = int(S_UNLOAD)
        if direction > 0:
            stage = int(S_LOAD)
    return stage, soft, fsoft, frozen_sbc


@wp.func
def event_value(kind: int, z: vec5d, q: vecQd, stage: int, mat: Material) -> wp.float64:
    """Signed event function at the state (z, q), positive once the event happened
    (CellCycle.event_functions)."""
    v = wp.float64(0.0)
    if kind == _EV_SLIDE:
        if stage == SF_LOAD:
            v = q[Q_PHI] - phi_edge(q, mat)
        else:
            v = -phi_edge(q, mat) - q[Q_PHI]
    elif kind == _EV_JAM:
        v = -jam_clearance(z, q, mat)
    elif kind == _EV_CAP:
        v = q[Q_F] - mat.cap
    elif kind == _EV_SLACK:
        # F -> 0 or the contact opens, Rn -> 0 (CellCycle.event_functions): eq 7 gives F = -2 R cos(beta + phi),
        # so R = 0 is F = 0; where beta + phi passes pi/2 there too F only touches 0 and Rn alone changes sign
        v = wp.max(-q[Q_F], -q[Q_RN])
    elif kind == _EV_CONE:
        if stage == SF_UNLOAD:
            v = q[Q_PHI] - phi_edge(q, mat)
        else:
            v = -phi_edge(q, mat) - q[Q_PHI]
    return v


@wp.func
def event_tol(kind: int, mat: Material) -> wp.float64:
    """Zero of an event function at the start of a sub-step (stages.EVENT_TOL; times d for W, times the yarn's
    force scale B / d^2 for F and Rn: CellCycle._event_tol)."""
    t = _EVENT_TOL
    if kind == _EV_JAM or kind == _EV_UNJAM:
        t = _EVENT_TOL * mat.d
    elif kind == _EV_SLACK or kind == _EV_CAP:
        t = _EVENT_TOL * mat.B / (mat.d * mat.d)
    return t


@wp.func
def event_active(kind: int, stage: int, jammed: int, soft: int, mat: Material) -> wp.bool:
    ok = bool(False)
    if kind == _EV_CONE:
        ok = mat.dahl == 0 and mat.m > wp.float64(0.0) and mat.closure != 0 and soft == Q_BETA and stage == SF_UNLOAD
    elif kind == _EV_SLIDE:
        ok = mat.dahl == 0 and mat.m > wp.float64(0.0) and (stage == SF_LOAD or stage == SF_UNLOAD)
    elif kind == _EV_JAM:
        ok = jammed == 0
    elif kind == _EV_CAP:
        ok = is_loading(stage)
    elif kind == _EV_SLACK:
        ok = not is_loading(stage)
    return ok


@wp.func
def event_condition(kind: int, stage: int, mat: Material):
    """(code, target) of the condition that replaces C when the event is located."""
    code = jam_code(mat)
    tg = jam_target(mat)  # jam, unjam
    if kind == _EV_SLIDE:
        code = int(Q_PHI)
        tg = mat.phimax
        if stage == SF_UNLOAD:
            tg = -mat.phimax
    elif kind == _EV_CAP:
        code = int(Q_F)
        tg = mat.cap
    elif kind == _EV_SLACK:
        code = int(Q_F)
        tg = wp.float64(0.0)
    elif kind == _EV_CONE:
        code = int(Q_PHI)
        tg = -mat.phimax
        if stage == SF_UNLOAD:
            tg = mat.phimax
    if (kind == _EV_SLIDE or kind == _EV_CONE) and mat.fr_state != 0:
        # the edge of the state's own cone (friction_ratio): phi = +/-atan(m(beta, Rn))
        code = int(COND_PHI_EFF)
        tg = wp.float64(1.0)
        if (kind == _EV_SLIDE and stage == SF_UNLOAD) or (kind == _EV_CONE and stage != SF_UNLOAD):
            tg = wp.float64(-1.0)
    return code, tg


@wp.func
def event_condition_at(kind: int, stage: int, mat: Material, q_end: vecQd):
    """event_condition, with the slack event located on Rn = 0 where only the contact opened at the
    trial end (Rn < 0 there while F >= 0: F only touched 0, or dipped below it and came back inside
    the sub-step; R = 0 is a zero of F too, eq 7) (CellCycle._slack_function)."""
    code, tg = event_condition(kind, stage, mat)
    if kind == _EV_SLACK and -q_end[Q_RN] > -q_end[Q_F]:
        code = int(Q_RN)
    return code, tg


@wp.func
def transition(kind: int, stage: int, jammed: int, soft: int, frozen_soft: wp.float64, status: int, q: vecQd):
    """Stage change of a located event (CellCycle._transition)."""
    if kind == _EV_SLIDE:
        if stage == SF_LOAD:
            stage = int(S_LOAD)
            # S+ freezes Rn (Table 4); after a mirror reload (beta frozen in SF+) it freezes T, the
            # mirror of S- (CellCycle._transition: Rn ~ 0 there selects the zero-force family)
            if soft == Q_BETA:
                soft = int(Q_T)
            else:
                soft = int(Q_RN)
        else:
            stage = int(S_UNLOAD)
            soft = int(Q_T)
        frozen_soft = q[soft]
    elif kind == _EV_CONE:
        # stick kept, the beta closure released: T (SF-) or Rn (SF+) frozen from here
        soft = int(Q_RN)
        if stage == SF_UNLOAD:
            soft = int(Q_T)
        frozen_soft = q[soft]
    elif kind == _EV_JAM:
        jammed = 1
    elif kind == _EV_UNJAM:
        jammed = 0
    elif kind == _EV_SLACK:
        stage = int(SLACK)
    elif kind == _EV_CAP:
        status = int(ST_CAP)
    return stage, jammed, soft, frozen_soft, status


@wp.func
def locatable(kind: int) -> wp.bool:
    """Events found by their event function (unjam is the active-set check; reversal, reload are imposed)."""
    return kind == _EV_SLIDE or kind == _EV_JAM or kind == _EV_SLACK or kind == _EV_CAP or kind == _EV_CONE


@wp.func
def in_range(C: wp.float64, Ca: wp.float64, Cb: wp.float64) -> wp.bool:
    lo = wp.min(Ca, Cb)
    hi = wp.max(Ca, Cb)
    tol = wp.float64(1.0e-12) * wp.max(wp.float64(1.0), hi)
    return wp.isfinite(C) and C >= lo - tol and C <= hi + tol


@wp.func
def may_halve(failures: int, step: wp.float64, max_halvings: int, mat: Material) -> wp.bool:
    """Whether a failed sub-step is retried on half its length: at most ``max_halvings`` times in a
    row, and not below SUBSTEP_FLOOR C0 (stages.SUBSTEP_FLOOR; CellCycle._may_halve)."""
    return failures <= max_halvings and wp.float64(0.5) * wp.abs(step) >= _SUBSTEP_FLOOR * mat.C0


# ------------------------------------------------------------------ solves
@wp.func
def bending_fixed_point(x: vec5d, q: vecQd, st: int, codes: wp.vec4i, tg: vec4d, dp: vec10p, C: wp.float64,
                        mat: Material):
    """An event solve (C free) under bending hysteresis: the state must be solved with B of its own C.

    ``x, q, st``: the solve with B(C), located at C_e(C).  The located C is a scalar function of the
    C at which B is read, so the event's C is the root of g(c) = C_e(c) - c, found by the secant
    method from c = C and c = C_e(C) (a plain fixed point c <- C_e(c) diverges where a stiffness that
    changes fast, h sigma / C0 ~ 10 per mm, meets a stage whose frozen force makes the event move
    by more than 1 / (d ln B / dC) per unit of ln B)."""
    xn = x
    qn = q
    s = st
    ca = C
    ga = wp.float64(0.0)
    cb = C
    gb = wp.float64(0.0)
    tol = _BEND_RTOL * wp.max(wp.float64(1.0), wp.abs(C))
    floor = _BEND_NOISE_RTOL * wp.max(wp.float64(1.0), wp.abs(C))
    g_last = wp.float64(0.0)
    settled = bool(False)
    if s == STATUS_CONVERGED:
        ga = qn[Q_C] - ca
        settled = wp.abs(ga) <= tol
        cb = qn[Q_C]
    for k in range(_BEND_ROUNDS):
        if s == STATUS_CONVERGED and not settled:
            xn, qn, s = newton(xn, codes, tg, dp, stiffness_at(mat, cb), mat.d)
            if s == STATUS_CONVERGED:
                g_last = gb
                gb = qn[Q_C] - cb
                if wp.abs(gb) <= tol:
                    settled = True
                elif k > 0 and wp.abs(gb) <= floor and wp.abs(gb) >= wp.abs(g_last):
                    # the secant no longer gains: g is at the noise of the event's own solve (its C to
                    # NEWTON_TOL of an ill-conditioned event condition, e.g. F = 0 at the slack point), where
                    # it wanders by 1e-12..2e-11 mm round after round and never meets the 1e-13 above
                    settled = True
                else:
                    cn = qn[Q_C]  # the plain fixed point where the secant's slope is degenerate
                    if gb != ga:
                        cn = cb - gb * (cb - ca) / (gb - ga)
                    ca = cb
                    ga = gb
                    cb = cn
    if not settled:
        s = int(STATUS_MAX_ITER)  # the event's C and its B did not settle: not a state of the law
    return xn, qn, s


@wp.func
def solve_coulomb(x: vec5d, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                  mat: Material, C: wp.float64, ev_code: int, ev_target: wp.float64):
    """Equilibrium of a Coulomb stage at C (or, with ev_code >= 0, at the event condition, C free)."""
    xn, qn, st, step0, slope = solve_coulomb_first(x, stage, jammed, soft, fs, fsbc, mat, C, ev_code, ev_target,
                                                   wp.float64(0.0), False)
    return xn, qn, st == STATUS_CONVERGED


@wp.func
def solve_coulomb_first(x: vec5d, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                        mat: Material, C: wp.float64, ev_code: int, ev_target: wp.float64, max_first: wp.float64,
                        want_slope: wp.bool):
    """:func:`solve_coulomb` with :func:`newton_first`'s bound on the first step: returns (x, q, status, step0,
    slope), ``slope`` the branch's dF/dC at the solution with ``want_slope`` (:func:`newton_solve`; NaN at an
    event condition or unconverged)."""
    codes, tg = stage_conditions(stage, jammed, soft, fs, fsbc, mat, C)
    if ev_code >= 0:
        codes[1] = ev_code
        tg[1] = ev_target
    dp = effect_params(mat)
    xn, qn, st, step0, slope = newton_first(x, codes, tg, dp, stiffness_at(mat, C), mat.d, max_first,
                                            want_slope and ev_code < 0)
    if ev_code >= 0 and bends(mat):
        xn, qn, st = bending_fixed_point(xn, qn, st, codes, tg, dp, C, mat)
    return xn, qn, st, step0, slope


@wp.func
def solve_coulomb_warm(x: vec5d, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                       mat: Material, C: wp.float64, want_slope: wp.bool):
    """:func:`solve_coulomb` at C from the state of a trial of the same increment, on the same branch at a C a
    little away (a patch's later coupling trial).  A first Newton step shorter than WARM_STEP_MAX is taken
    without evaluating its end (:func:`newton_solve`'s ``max_unverified``); otherwise the solve is iterated
    past NEWTON_TOL to the residuals' rounding floor (POLISH_TOL, at most POLISH_MAX_ITER steps; converged as
    the cell step's where the floor lies above it): a solve stopped at NEWTON_TOL from another start differs
    from the trial's by up to 3e-10 N at a few mN, above a column's tolerance there (the paper specimen: 8
    unconverged column-increments against 1).  Returns (x, q, converged, slope): ``slope`` dF/dC where the
    short step was taken or, with ``want_slope``, the solve converged; else NaN."""
    codes, tg = stage_conditions(stage, jammed, soft, fs, fsbc, mat, C)
    xn, qn, st, step0, n, slope = newton_solve(x, codes, tg, effect_params(mat), stiffness_at(mat, C), mat.d,
                                               wp.float64(0.0), POLISH_TOL, NEWTON_TOL, POLISH_MAX_ITER,
                                               WARM_STEP_MAX, want_slope)
    return xn, qn, st == STATUS_CONVERGED, slope


@wp.func
def solve_coulomb_cont(x: vec5d, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                       mat: Material, C_from: wp.float64, C_goal: wp.float64):
    """solve_coulomb at C_goal; if Newton fails from x, walk there in 4 sub-steps (guesses only:
    the result is the same equilibrium at C_goal, events are still judged on the endpoints)."""
    xt, qt, ok, step0, slope = solve_coulomb_trial(x, stage, jammed, soft, fs, fsbc, mat, C_from, C_goal, wp.float64(0.0),
                                                   False)
    return xt, qt, ok


@wp.func
def solve_coulomb_trial(x: vec5d, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                        mat: Material, C_from: wp.float64, C_goal: wp.float64, max_first: wp.float64,
                        want_slope: wp.bool):
    """:func:`solve_coulomb_cont` from the converged state x at C_from, not attempted when its first Newton step
    is longer than ``max_first`` (> 0; :func:`newton_first`): returns (x_t, q_t, ok, step0, slope), ``step0``
    that step where the solve was not attempted, else zero; ``slope`` the branch's dF/dC at x_t where
    ``want_slope`` and the direct solve converged (NaN after the four sub-steps)."""
    xt, qt, st, step0, slope = solve_coulomb_first(x, stage, jammed, soft, fs, fsbc, mat, C_goal, -1, wp.float64(0.0),
                                                   max_first, want_slope)
    good = st == STATUS_CONVERGED
    if not good and st != STATUS_STEP_LONG:
        slope = wp.float64(wp.nan)
        xx = x
        good = bool(True)
        for k in range(1, 5):
            if good:
                Ck = C_from + (C_goal - C_from) * wp.float64(k) * wp.float64(0.25)
                xx, qt, okk = solve_coulomb(xx, stage, jammed, soft, fs, fsbc, mat, Ck, -1, wp.float64(0.0))
                good = bool(okk)
        xt = xx
    return xt, qt, good, step0, slope


@wp.func
def slide_predicted(x: vec5d, q: vecQd, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                    mat: Material, C_from: wp.float64, C_goal: wp.float64, step0: vec5d):
    """The slide of a stick stage located directly (phi at the cone's edge imposed, C free) when the branch's
    tangent (``step0``: the first Newton step of the sub-step C_from -> C_goal from the converged state x)
    puts it inside the sub-step: returns (found, x_e, q_e).

    Found only where the solve converges inside the sub-step, past its start, with no other event of the
    stage fired on the way (its function <= its tolerance at x and > 0 at the slide) and, unloading, the
    contact still closed: that is the slide the sub-steps would locate from a trial beyond it, reached
    without the trials.  Near the S+ -> SF- reversal the stick branch turns past phi = -phimax within
    0.01 mm, where trials of predicted length took 20 sub-steps of 5-11 iterations before one passed it."""
    found = bool(False)
    xe = x
    qe = q
    if event_active(_EV_SLIDE, stage, jammed, soft, mat):
        tol = event_tol(_EV_SLIDE, mat)
        f0 = event_value(_EV_SLIDE, x, q, stage, mat)
        dphi = step0[3]  # the Newton variables' phi, in either chart
        if stage == SF_UNLOAD:
            dphi = -dphi
        if f0 < -tol and f0 + dphi > wp.float64(0.0):
            code, etg = event_condition(_EV_SLIDE, stage, mat)
            xs, qs, oks = solve_coulomb(x, stage, jammed, soft, fs, fsbc, mat, C_goal, code, etg)
            if oks and in_range(qs[Q_C], C_from, C_goal) and qs[Q_C] != C_from:
                clean = is_loading(stage) or qs[Q_RN] >= wp.float64(0.0)
                for kind in range(8):
                    if kind != _EV_SLIDE and locatable(kind) and event_active(kind, stage, jammed, soft, mat):
                        if event_value(kind, x, q, stage, mat) <= event_tol(kind, mat) and \
                                event_value(kind, xs, qs, stage, mat) > wp.float64(0.0):
                            clean = False
                if clean:
                    found = True
                    xe = xs
                    qe = qs
    return found, xe, qe


@wp.func
def narrowed_past(z: vec5d, q: vecQd, stage: int, mat: Material, mat_from: Material) -> wp.bool:
    """Whether the friction cone narrowed past a stuck contact between the materials ``mat_from``
    (at the start of the sub-step) and ``mat`` (at its end): inside the sliding limit of the one,
    outside the other's.

    Only an effect that lowers m does this (eq 5 at a rate below the reference, eq 10, ...). The
    stick stage pushes phi toward that limit, so the contact stays outside and its slide event
    cannot be located (that needs its function <= 0 at the start): it slides at the start. (The
    cone's far side after a reversal is left to cone_at_start: unloading moves phi back inside.)"""
    tol = event_tol(_EV_SLIDE, mat)
    out = event_value(_EV_SLIDE, z, q, stage, mat_from) <= tol and event_value(_EV_SLIDE, z, q, stage, mat) > tol
    if mat.fr_state != 0:
        # the cone is the state's own (friction_ratio), the same at both ends; only the velocity factor of
        # a new increment's rate moves it: a stick state found outside it at a sub-step's start slides there
        out = event_value(_EV_SLIDE, z, q, stage, mat) > tol
    return out


@wp.func
def cone_at_start(x: vec5d, q: vecQd, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                  mat: Material, C: wp.float64, C_target: wp.float64) -> wp.bool:
    """Whether the cone event happens at the cell's C itself (CellCycle._cone_at_start): its function
    is zero there (reversal from sliding) and a probe step of PROBE_STEP C0 toward the target
    leaves the cone, or fails."""
    out = bool(False)
    if event_active(_EV_CONE, stage, jammed, soft, mat):
        f0 = event_value(_EV_CONE, x, q, stage, mat)
        if wp.abs(f0) <= event_tol(_EV_CONE, mat):
            h = _PROBE_STEP * mat.C0
            if C_target < C:
                h = -h
            xp, qp, okp = solve_coulomb(x, stage, jammed, soft, fs, fsbc, mat, C + h, -1, wp.float64(0.0))
            out = (not okp) or event_value(_EV_CONE, xp, qp, stage, mat) > wp.float64(0.0)
    return out


@wp.func
def slide_at_start(x: vec5d, q: vecQd, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                   mat: Material, mat_from: Material, C: wp.float64, C_target: wp.float64) -> wp.bool:
    """Whether a stick stage slides at once: when an effect narrowed the cone past its state
    (narrowed_past), or, starting at zero contact force
    (CellCycle._slide_at_start), when a probe step of PROBE_STEP C0 from R/P = RELOAD_RHO_SEED does."""
    out = bool(False)
    stick = (stage == SF_LOAD or stage == SF_UNLOAD) and mat.m > wp.float64(0.0)
    if stick and narrowed_past(x, q, stage, mat, mat_from):
        out = True
    elif stick and no_contact(q):
        h = _PROBE_STEP * mat.C0
        if C_target < C:
            h = -h
        xp, qp, okp = solve_coulomb(seed_contact(x), stage, jammed, soft, fs, fsbc, mat, C + h, -1, wp.float64(0.0))
        # at zero contact no tangential force can be held: a probe beyond either edge of the cone slides
        # (CellCycle._slide_at_start: the far edge is the seed's sign, not a direction of slip)
        out = (not okp) or event_value(_EV_SLIDE, xp, qp, stage, mat) >= -event_tol(_EV_SLIDE, mat) \
            or wp.abs(qp[Q_PHI]) >= phi_edge(qp, mat) - event_tol(_EV_SLIDE, mat)
    return out


@wp.func
def unjam_at_start(x: vec5d, q: vecQd, stage: int, soft: int, fs: wp.float64, fsbc: wp.float64, mat: Material,
                   C: wp.float64, C_goal: wp.float64) -> wp.bool:
    """Whether a jammed unloading cell whose jammed branch has no solution toward C_goal unjams at its
    C itself (CellCycle._unjam_at_start): the unjammed branch passes through its state (clearance
    >= -EVENT_TOL d_jam at C) and is clear of contact at C_goal (active set, as the unjam check).

    The jammed branch can end where the loops would open: a jammed SF- that slides keeps the jam
    condition in place of T, and the jammed S- branch has no solution on unloading past the slide
    point (its Newton's residual falls only in proportion to the sub-step, down to the floor),
    while the unjammed S- (T frozen at the slide, the value the state holds) passes through it and
    opens (issue 14: a domain cell, head-gap jamming, reversal at strain 0.6)."""
    xa, qa, oka = solve_coulomb(x, stage, 0, soft, fs, fsbc, mat, C, -1, wp.float64(0.0))
    out = bool(False)
    if oka and jam_clearance(xa, qa, mat) >= -event_tol(_EV_UNJAM, mat):
        xu, qu, oku = solve_coulomb_cont(xa, stage, 0, soft, fs, fsbc, mat, C, C_goal)
        out = oku and jam_clearance(xu, qu, mat) >= wp.float64(0.0)
    return out


@wp.func
def cone_which(mat: Material) -> int:
    """branch_sign_change's quantity for the cone's edge: phimax - phi, or the state's own edge."""
    w = int(Q_PHI)
    if mat.fr_state != 0:
        w = int(SIGN_CONE_EDGE)
    return w


@wp.func
def branch_sign_change(x: vec5d, q: vecQd, stage: int, jammed: int, soft: int, fs: wp.float64, fsbc: wp.float64,
                       mat: Material, C_from: wp.float64, C_goal: wp.float64, which: int, offset: wp.float64,
                       sgn: wp.float64):
    """The last state of the branch before sgn (q[which] - offset) turns negative inside C_from -> C_goal
    (Rn: the contact opens; F; phimax - phi: the cone), >= 0 at C_from and < 0 at C_goal: bisection on
    its sign, each point solved from the last state where it is >= 0; a point with no solution counts as
    past the change (CellCycle._sign_change, which says why not Newton: R = 0 is singular, Rn = 0 is met
    at phi = -pi/2 too).

    Returns (x_a, q_a, C_a), the quantity >= 0 at C_a, within OPENING_XTOL max(1, C) of where it is < 0
    (C_a the solved course length of q_a; C_from where the quantity is < 0 at every point tried)."""
    xa = x
    qa = q
    Ca = C_from
    Cb = C_goal
    for k in range(_OPENING_BISECTIONS):
        if wp.abs(Cb - Ca) > _OPENING_XTOL * wp.max(wp.float64(1.0), wp.abs(Cb)):
            Cm = wp.float64(0.5) * (Ca + Cb)
            xm, qm, okm = solve_coulomb(xa, stage, jammed, soft, fs, fsbc, mat, Cm, -1, wp.float64(0.0))
            v = wp.float64(0.0)
            if which == SIGN_CONE_EDGE:
                v = phi_edge(qm, mat) - qm[Q_PHI]
            else:
                v = sgn * (qm[which] - offset)
            if okm and v >= wp.float64(0.0):
                xa = xm
                qa = qm
                Ca = Cm
            else:
                Cb = Cm
    Cout = Ca
    if Ca != C_from:
        Cout = qa[Q_C]  # the solved C, as the events located by Newton report it
    return xa, qa, Cout


@wp.func
def dahl_sign(x: vec5d, q_old: vecQd, jammed: int, soft: int, fs: wp.float64, mat: Material, C: wp.float64,
              predict: wp.bool):
    """Stick trial (s_BC frozen at its old value) at C: slip direction s (0: stick solves it).

    With ``predict`` (x a converged state of these conditions, q_old its quantities) a stick trial whose
    first Newton step is long (above PREDICTED_STEP_MAX: the stick branch leaves the cone far behind, where
    its Newton crawled for 40-60 iterations and failed, the increment then halved) is not solved: its
    first step is the stick branch's tangent times the change of C, and where that moves phi by more than
    DAHL_SIGN_DPHI the sign of tan(phi_stick) - tan(phi_old) is the sign of that change (tan is monotone;
    only a turn of phi along the stick branch within the increment could undo it).  Returns the start
    itself as the stick state then.  Returns (s, x_stick, q_stick, ok, solved)."""
    codes, tg = stage_conditions(SF_LOAD, jammed, soft, fs, q_old[Q_S_BC], mat, C)
    codes[2] = Q_S_BC
    bound = wp.float64(0.0)
    if predict:
        bound = PREDICTED_STEP_MAX
    xs, qs, st, step0, slope = newton_first(x, codes, tg, effect_params(mat), stiffness_at(mat, C), mat.d, bound,
                                            False)
    if st == STATUS_STEP_LONG:
        if wp.abs(step0[3]) > DAHL_SIGN_DPHI:
            s = wp.float64(1.0)
            if step0[3] < wp.float64(0.0):
                s = wp.float64(-1.0)
            return s, x, q_old, True, False
        xs, qs, st = newton(x, codes, tg, effect_params(mat), stiffness_at(mat, C), mat.d)
    r0 = wp.tan(qs[Q_PHI]) - wp.tan(q_old[Q_PHI])
    s = wp.float64(1.0)
    if r0 < wp.float64(0.0):
        s = wp.float64(-1.0)
    elif r0 == wp.float64(0.0):
        s = wp.float64(0.0)
    return s, xs, qs, st == STATUS_CONVERGED, True


@wp.func
def solve_dahl(x: vec5d, q_old: vecQd, s: wp.float64, jammed: int, soft: int, fs: wp.float64,
               mat: Material, C: wp.float64, ev_code: int, ev_target: wp.float64):
    """Dahl equilibrium from the state q_old at C (or at the event condition): Newton on the
    intrinsic condition, L, C, the soft condition and the Dahl residual."""
    codes, tg = stage_conditions(SF_LOAD, jammed, soft, fs, wp.float64(0.0), mat, C)
    codes[2] = COND_DAHL
    if ev_code >= 0:
        codes[1] = ev_code
        tg[1] = ev_target
    dp = effect_params(mat)
    dp[0] = wp.tan(q_old[Q_PHI])
    dp[1] = q_old[Q_S_BC]
    dp[2] = s
    dp[3] = mat.sigma
    dp[4] = mat.m
    xn, qn, st = newton(x, codes, tg, dp, stiffness_at(mat, C), mat.d)
    if ev_code >= 0 and bends(mat):
        xn, qn, st = bending_fixed_point(xn, qn, st, codes, tg, dp, C, mat)
    ok = st == STATUS_CONVERGED
    # the root must lie on the slip branch s xi >= 0 (the reference brackets xi in [0, s hi])
    xi = q_old[Q_S_BC] - qn[Q_S_BC]
    if ok and s * xi < -wp.float64(1.0e-12) * mat.d:
        ok = False
    return xn, qn, ok


@wp.func
def solve_dahl_at(x: vec5d, q_old: vecQd, jammed: int, soft: int, fs: wp.float64, mat: Material, C: wp.float64,
                  predict: wp.bool):
    """Dahl increment from q_old to C: stick trial for the slip direction (``predict``: see
    :func:`dahl_sign`), then the Dahl solve (from the stick state, else from x).

    Returns (x, q, s, ok)."""
    s, xs, qs, ok, solved = dahl_sign(x, q_old, jammed, soft, fs, mat, C, predict)
    xn = xs
    qn = qs
    if ok and s != wp.float64(0.0):
        xn, qn, ok = solve_dahl(xs, q_old, s, jammed, soft, fs, mat, C, -1, wp.float64(0.0))
        if not ok and solved:
            xn, qn, ok = solve_dahl(x, q_old, s, jammed, soft, fs, mat, C, -1, wp.float64(0.0))
    if not ok:
        # the stick trial or its Dahl solve failed (near a vanishing contact force the stick branch runs off the
        # cone, ill-conditioned): the slip direction whose Dahl solve has its root on its own side (solve_dahl
        # checks s xi >= 0), where exactly one has; else the increment fails as before (and is halved)
        xp, qp, okp = solve_dahl(x, q_old, wp.float64(1.0), jammed, soft, fs, mat, C, -1, wp.float64(0.0))
        xm, qm, okm = solve_dahl(x, q_old, wp.float64(-1.0), jammed, soft, fs, mat, C, -1, wp.float64(0.0))
        if okp and not okm:
            xn = xp
            qn = qp
            s = wp.float64(1.0)
            ok = True
        elif okm and not okp:
            xn = xm
            qn = qm
            s = wp.float64(-1.0)
            ok = True
    return xn, qn, s, ok


@wp.func
def dahl_event_by_bisection(x: vec5d, q_old: vecQd, s: wp.float64, jammed: int, soft: int, fs: wp.float64,
                            mat: Material, C_from: wp.float64, C_goal: wp.float64, kind: int, stage: int):
    """An event of a Dahl sub-step under bending hysteresis located by bisection on its sign, where the
    event solve with C free (solve_dahl, B(C) by bending_fixed_point) failed: its event C follows the B at
    which it is read so steeply (d C_e / d c ~ -100 at a slack point while B falls fast after a reversal) that
    the secant runs off.  Each point is solved at its C imposed, so B is that of its own C exactly; the event
    value is <= 0 at C_from (the sub-step's start) and > 0 at C_goal (its end); a point with no solution
    counts as past the event (as branch_sign_change).  Returns (x_a, q_a): the last point before the
    event, within OPENING_XTOL max(1, C) of it (the start itself where no point before it is found)."""
    xa = x
    qa = q_old
    Ca = C_from
    Cb = C_goal
    for k in range(_OPENING_BISECTIONS):
        if wp.abs(Cb - Ca) > _OPENING_XTOL * wp.max(wp.float64(1.0), wp.abs(Cb)):
            Cm = wp.float64(0.5) * (Ca + Cb)
            xm, qm, okm = solve_dahl(xa, q_old, s, jammed, soft, fs, mat, Cm, -1, wp.float64(0.0))
            if okm and event_value(kind, xm, qm, stage, mat) <= wp.float64(0.0):
                xa = xm
                qa = qm
                Ca = Cm
            else:
                Cb = Cm
    return xa, qa


@wp.func
def label_dahl(stage: int, q: vecQd, mat: Material) -> int:
    """Dahl has no switch: sliding once tan(phi) is within 5 % of +/-m (CellCycle._label_dahl)."""
    out = stage
    if stage != SLACK:
        if is_loading(stage):
            out = int(SF_LOAD)
            if wp.abs(wp.tan(q[Q_PHI]) - mat.m) <= wp.float64(0.05) * mat.m:
                out = int(S_LOAD)
        else:
            out = int(SF_UNLOAD)
            if wp.abs(wp.tan(q[Q_PHI]) + mat.m) <= wp.float64(0.05) * mat.m:
                out = int(S_UNLOAD)
    return out


@wp.func
def push_event(n: int, kinds: vec8i, Cs: vec8d, Fs: vec8d, froms: vec8i, tos: vec8i, kind: int, C: wp.float64,
               F: wp.float64, label_from: int, label_to: int):
    """Append an event (at C, with the force per wale F there) to the increment's buffer (the first
    MAX_EVENTS_PER_STEP are kept, all are counted)."""
    if n < _MAXEV:
        kinds[n] = kind
        Cs[n] = C
        Fs[n] = F
        froms[n] = label_from
        tos[n] = label_to
    return n + 1, kinds, Cs, Fs, froms, tos


@wp.func
def take_event(kind: int, C: wp.float64, stage: int, jammed: int, soft: int, frozen_soft: wp.float64, status: int,
               q: vecQd, n: int, kinds: vec8i, Cs: vec8d, Fs: vec8d, froms: vec8i, tos: vec8i):
    """A located event of ``kind`` at C: the stage change it makes (:func:`transition`) and its record in the
    increment's buffer (:func:`push_event`, from the label before to the label after)."""
    label_from = stage_label(stage, jammed)
    s2, j2, soft2, fs2, st2 = transition(kind, stage, jammed, soft, frozen_soft, status, q)
    n2, kinds2, Cs2, Fs2, froms2, tos2 = push_event(n, kinds, Cs, Fs, froms, tos, kind, C, q[Q_F], label_from,
                                                    stage_label(s2, j2))
    return s2, j2, soft2, fs2, st2, n2, kinds2, Cs2, Fs2, froms2, tos2


@wp.func
def lerp5(a: vec5d, b: vec5d, t: wp.float64):
    return a + (b - a) * t


@wp.func
def interp_t(f0: wp.float64, f1: wp.float64) -> wp.float64:
    t = wp.float64(1.0)
    den = f1 - f0
    if den != wp.float64(0.0):
        t = wp.clamp(-f0 / den, wp.float64(0.0), wp.float64(1.0))
    return t


@wp.func
def read_material(i: int, model: ModelArrays):
    """Cell ``i``'s parameters (each model array of shape 1 or N, read as ``p[i % p.shape[0]]``)."""
    mat = Material()
    mat.B = model.B[i % model.B.shape[0]]
    mat.d = model.d[i % model.d.shape[0]]
    mat.L = model.L[i % model.L.shape[0]]
    mat.W0 = model.W0[i % model.W0.shape[0]]
    mat.C0 = model.C0[i % model.C0.shape[0]]
    mat.m = model.m[i % model.m.shape[0]]
    mat.phimax = wp.atan(mat.m)
    mat.phi0 = model.phi0[i % model.phi0.shape[0]]
    mat.sigma = model.sigma[i % model.sigma.shape[0]]
    mat.cap = model.cap[i % model.cap.shape[0]]
    mat.w_jam = wp.float64(4.0) * model.djam[i % model.djam.shape[0]]  # Hong's W = 4d, d the in-plane jam width
    mat.dahl = model.friction[i % model.friction.shape[0]]
    mat.hong = model.unloading[i % model.unloading.shape[0]]
    mat.mirror = model.reload[i % model.reload.shape[0]]
    mat.gap = model.criterion[i % model.criterion.shape[0]]
    mat.comp_k = wp.float64(0.0)
    mat.comp_rn0 = wp.float64(0.0)
    mat.comp_min = wp.float64(1.0)
    mat.ext_c = wp.float64(0.0)
    mat.ext_p0 = wp.float64(0.0)
    mat.fr_state = 0  # the friction ratio is m (apply_effects sets the state's law)
    mat.bend_h = wp.float64(0.0)  # no bending hysteresis (apply_effects sets its law)
    mat.bend_sigma = wp.float64(0.0)
    mat.bend_z0 = wp.float64(0.0)
    mat.bend_C = wp.float64(0.0)
    mat.bend_s = wp.float64(0.0)
    mat.fr_m0 = mat.m
    mat.fr_mu = wp.float64(0.0)
    mat.fr_n = wp.float64(1.0)
    mat.fr_ref = wp.float64(1.0)
    return mat


# ------------------------------------------------------------------ effects (issue 6)
@wp.func
def apply_effects(mat: Material, mask: int, params: wp.array2d(dtype=wp.float64), r: int, q: vecQd,
                  z_old: wp.float64, P_rest: wp.float64, Rn_rest: wp.float64, C_start: wp.float64,
                  dstrain: wp.float64, rate: wp.float64):
    """The cell's parameters for one increment with the effects of ``mask`` on (knitsim.cell.effects).

    m is read from the state at the start of the increment (increment-lagged); for a
    Coulomb cell with coiling or normal-load friction the ratio's law is also handed to the
    sliding condition and the slide and cone events (``fr_*`` fields: friction_ratio, read at the
    solution itself, implicit), so that the lagged m is only what the frictionless test and the
    Dahl law read; the compaction and extension laws are handed to the residuals, which read the
    load at the solution itself (implicit); under bending hysteresis B is that of the state's
    own C (``bend_*`` fields, stiffness_at: Dahl's closed form from z_old at C_start over the
    increment's monotone strain, whose direction is that of ``dstrain``), so that a located event
    and an increment's end read B where they lie (mat.B stays the yarn's own).
    """
    m = mat.m
    mat_m0 = mat.m
    if has(mask, BIT_COILING):
        m = coiling_friction(q[Q_BETA], params[r, P_COIL_MU])
    if has(mask, BIT_NORMAL_LOAD):
        m = m * normal_load_factor(q[Q_RN], params[r, P_LOAD_N], params[r, P_LOAD_REF])
    if has(mask, BIT_VELOCITY):
        m = m * velocity_factor(rate, params[r, P_RATE_P], params[r, P_RATE_REF])
    if m != mat.m:
        m = wp.min(m, _M_MAX)
        mat.m = m
        mat.phimax = wp.atan(m)
    if mat.dahl == 0 and (has(mask, BIT_COILING) or has(mask, BIT_NORMAL_LOAD)):
        # Coulomb: the sliding condition and the slide and cone events read the ratio at the state itself
        # (friction_ratio); m and phimax above stay the increment-lagged values (Dahl, the frictionless test)
        mat.fr_state = 1
        mat.fr_m0 = mat_m0
        mat.fr_mu = wp.float64(0.0)
        mat.fr_n = wp.float64(1.0)
        mat.fr_ref = wp.float64(1.0)
        if has(mask, BIT_COILING):
            mat.fr_m0 = wp.float64(1.0)
            mat.fr_mu = params[r, P_COIL_MU]
        if has(mask, BIT_NORMAL_LOAD):
            mat.fr_n = params[r, P_LOAD_N]
            mat.fr_ref = params[r, P_LOAD_REF]
        if has(mask, BIT_VELOCITY):
            mat.fr_m0 = mat.fr_m0 * velocity_factor(rate, params[r, P_RATE_P], params[r, P_RATE_REF])
    if has(mask, BIT_COMPACTION):
        # implicit: the jammed condition reads the load at the solution (a lagged width oscillates
        # on the stiff jammed branch); see jam_residual
        mat.comp_k = params[r, P_COMP_K]
        mat.comp_rn0 = Rn_rest
        mat.comp_min = params[r, P_COMP_MIN]
    if has(mask, BIT_BENDING):
        mat.bend_h = params[r, P_BEND_H]
        mat.bend_sigma = params[r, P_BEND_SIGMA]
        mat.bend_z0 = z_old
        mat.bend_C = C_start
        mat.bend_s = wp.float64(0.0)
        if dstrain > wp.float64(0.0):
            mat.bend_s = wp.float64(1.0)
        elif dstrain < wp.float64(0.0):
            mat.bend_s = wp.float64(-1.0)
    if has(mask, BIT_EXTENSION):
        # implicit, as the compaction: the length condition reads P at the solution (extension_residual)
        mat.ext_c = params[r, P_EXT_C]
        mat.ext_p0 = P_rest
    return mat


@wp.func
def material_from_effective(mat: Material, m: wp.float64) -> Material:
    """The material with the effective m of the state (the lagged one; d, L and B are implicit)."""
    out = mat
    out.m = m
    out.phimax = wp.atan(m)
    return out


@wp.func
def blend_material(a: Material, b: Material, t: wp.float64) -> Material:
    """The lagged friction ratio a fraction t of the way from a to b (b itself at t >= 1); B is read
    at each state's own C (stiffness_at)."""
    out = b
    if t < wp.float64(1.0):
        out.m = a.m + (b.m - a.m) * t
        out.phimax = wp.atan(out.m)
    return out


# ------------------------------------------------------------------ initial state
@wp.func
def closing_force(al: wp.float64, be: wp.float64, ga: wp.float64, B: wp.float64, d: wp.float64) -> wp.float64:
    """P that closes g = 0 (eq 6, third line) at phi = 0 (knitsim.cell.quarter_loop.closing_force);
    -1 where no P does."""
    P = wp.float64(-1.0)
    a = al - ga
    b = be - ga
    if a > wp.float64(0.0) and b > a and b < PI:
        s, x0, y0 = elastica_ab(d_const(a), d_const(b))
        xhat = x0.v * wp.cos(ga) - y0.v * wp.sin(ga)
        target = wp.float64(0.5) * d * wp.sin(be)
        if xhat > wp.float64(0.0) and target > wp.float64(0.0):
            P = B * (xhat / target) * (xhat / target)
    return P


if _KEY is not None and _KEY == INIT_KEY:
    # the inverse solve needs none of the optional residuals: it is compiled in the instance of the
    # state initialisation only, which every batch loads

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
        """The inverse solve (``knitsim.cell.warp_solve.solve_batch``): g = 0 (eq 6) and
        quantity[codes[i, k]] = targets[i, k], k = 0..3, by the cell step's Newton (:func:`newton_solve`,
        converged at ``tol``, no relaxed floor).

        Inputs, shape (1 or N, ...): codes [.,4], targets [.,4], B [N mm^2], d [mm],
        x_guess [.,5] = (alpha, beta, gamma, phi, P) [rad, N].  Outputs, shape N:
        x_out [N,5], status [N] (kernels.inverse's codes), iters [N] (Newton steps taken).  A guess
        outside the domain is returned as it is, with status STATUS_DOMAIN.
        """
        i = wp.tid()
        ic = i % codes.shape[0]
        it_ = i % targets.shape[0]
        ig = i % x_guess.shape[0]
        Bi = B[i % B.shape[0]]
        di = d[i % d.shape[0]]
        cds = wp.vec4i(codes[ic, 0], codes[ic, 1], codes[ic, 2], codes[ic, 3])
        tg = vec4d(targets[it_, 0], targets[it_, 1], targets[it_, 2], targets[it_, 3])
        x = vec5d(x_guess[ig, 0], x_guess[ig, 1], x_guess[ig, 2], x_guess[ig, 3], x_guess[ig, 4])
        st = int(STATUS_DOMAIN)
        n = int(0)
        if admissible(x[0] - x[2], x[1], x[2], x[3], x[4]):
            # R/P of the guess from its quantities (z_of: no 0/0 where beta + phi = pi/2)
            z, q, st, step0, n, slope = newton_solve(z_of(x, evaluate_x(x, Bi, di).q), cds, tg, vec10p(), Bi, di,
                                                     wp.float64(0.0), tol, tol, max_iter, wp.float64(0.0), False)
            x = x_of_z(z)
        for k in range(5):
            x_out[i, k] = x[k]
        status[i] = st
        iters[i] = n


@wp.kernel
def init_kernel(model: ModelArrays, starts: wp.array2d(dtype=wp.float64), s_out: StateArrays):
    """Table 4 initial state {C0, W0, L, phi0}: multistart at phi = 0 (the starts of
    knitsim.cell.inverse.initial_state, first converged wins), then continuation in phi; and the
    effects' state at rest (the given m, d, L, B, z = 0, and the rest values P_0, Rn_0)."""
    i = wp.tid()
    mat = read_material(i, model)
    codes = wp.vec4i(Q_C, Q_W, Q_L, Q_PHI)
    tg = vec4d(mat.C0, mat.W0, mat.L, wp.float64(0.0))
    found = bool(False)
    # default (alpha - gamma, beta, R/P, phi, P) guess, used only if no start converges
    x = vec5d(wp.log(wp.float64(1.1)), wp.float64(1.7), -wp.sin(wp.float64(0.1)) / wp.cos(wp.float64(1.7)),
              wp.float64(0.0), wp.log(wp.float64(0.15)))
    q = vecQd()
    for k in range(starts.shape[0]):
        if not found:
            al = starts[k, 0]
            be = starts[k, 1]
            ga = starts[k, 2]
            P = closing_force(al, be, ga, mat.B, mat.d)
            if P > wp.float64(0.0):
                z0 = vec5d(wp.log(al - ga), be, -wp.sin(ga) / wp.cos(be), wp.float64(0.0), wp.log(P))
                xk, qk, st = newton(z0, codes, tg, no_dahl(), mat.B, mat.d)
                if st == STATUS_CONVERGED:
                    found = True
                    x = xk
                    q = qk
    status = int(ST_OK)
    if not found:
        status = int(ST_NO_CONV)
        xk, qk, st = newton(x, codes, tg, no_dahl(), mat.B, mat.d)
        x = xk
        q = qk
        if not zr_admissible(xk):
            x = vec5d(wp.log(wp.float64(1.1)), wp.float64(1.7), -wp.sin(wp.float64(0.1)) / wp.cos(wp.float64(1.7)),
                      wp.float64(0.0), wp.log(wp.float64(0.15)))
        q = evaluate_zr(x, mat.B, mat.d).q
    elif mat.phi0 != wp.float64(0.0):
        # continuation in phi (knitsim.cell.inverse.continue_along, step 0.05 rad, 8 halvings)
        nsteps = wp.max(1, int(wp.ceil(wp.abs(mat.phi0) / wp.float64(0.05))))
        h = mat.phi0 / wp.float64(nsteps)
        value = wp.float64(0.0)
        halvings = int(0)
        sgn = wp.sign(h)
        while (mat.phi0 - value) * sgn > wp.float64(1.0e-14) * wp.max(wp.float64(1.0), wp.abs(mat.phi0)):
            nxt = value + h
            if (mat.phi0 - nxt) * sgn < wp.float64(0.0):
                nxt = mat.phi0
            tg[3] = nxt
            xk, qk, st = newton(x, codes, tg, no_dahl(), mat.B, mat.d)
            if st == STATUS_CONVERGED:
                x = xk
                q = qk
                value = nxt
            else:
                halvings += 1
                if halvings > 8:
                    status = int(ST_NO_CONV)
                    break
                h = h * wp.float64(0.5)
    stage = int(SF_LOAD)
    if mat.dahl == 0 and mat.phi0 >= mat.phimax - wp.float64(1.0e-12):
        stage = int(S_LOAD)  # phi0 = phimax: at the sliding limit already (m = 0: slides from the start)
    xo = x_of_z(x)
    for k in range(5):
        s_out.x[i, k] = xo[k]
    for k in range(N_QUANTITIES):
        s_out.q[i, k] = q[k]
    s_out.C[i] = q[Q_C]
    s_out.stage[i] = stage
    s_out.jammed[i] = 0
    s_out.soft[i] = int(Q_RN)
    s_out.fsoft[i] = q[Q_RN]
    s_out.fsbc[i] = q[Q_S_BC]
    s_out.status[i] = status
    s_out.direction[i] = 1
    s_out.gap[i] = head_gap_value(wp.exp(x[0]), q, mat.B)
    s_out.eff[i, E_M] = mat.m
    s_out.eff[i, E_D] = mat.d
    s_out.eff[i, E_L] = mat.L
    s_out.eff[i, E_B] = mat.B
    s_out.eff[i, E_Z] = wp.float64(0.0)
    s_out.eff[i, E_P0] = q[Q_P]
    s_out.eff[i, E_RN0] = q[Q_RN]


# ------------------------------------------------------------------ one increment
@wp.func
def write_events(i: int, increment: int, n_written: int, n_ev: int, e_kind: vec8i, e_C: vec8d, e_F: vec8d,
                 e_from: vec8i, e_to: vec8i, ev: EventArrays) -> int:
    """Append events ``n_written .. min(n_ev, MAX_EVENTS_PER_STEP) - 1`` of cell i's increment to the event
    buffer (those before were written by a suspended call); returns how many of the increment's are
    written now."""
    nk = wp.min(n_ev, _MAXEV)
    if nk > n_written:
        base = wp.atomic_add(ev.count, 0, nk - n_written)
        cap_ev = ev.cell.shape[0]
        for k in range(n_written, nk):
            j = base + k - n_written
            if j < cap_ev:
                ev.cell[j] = i
                ev.incr[j] = increment
                ev.kind[j] = e_kind[k]
                ev.C[j] = e_C[k]
                ev.F[j] = e_F[k]
                ev.label_from[j] = e_from[k]
                ev.label_to[j] = e_to[k]
    return wp.max(nk, n_written)


@wp.func
def suspend_walk(i: int, sus: SuspendedArrays, z: vec5d, q: vecQd, C: wp.float64, step: wp.float64,
                 fs: wp.float64, fsbc: wp.float64, stage: int, jammed: int, soft: int, status: int, failures: int,
                 n_located: int, guard: int, n_ev: int, n_written: int):
    """Keep cell i's sub-step walk at the top of sub-step ``guard`` (:class:`SuspendedArrays`)."""
    for k in range(5):
        sus.z[i, k] = z[k]
    for k in range(N_QUANTITIES):
        sus.q[i, k] = q[k]
    sus.real[i, 0] = C
    sus.real[i, 1] = step
    sus.real[i, 2] = fs
    sus.real[i, 3] = fsbc
    sus.ints[i, 0] = stage
    sus.ints[i, 1] = jammed
    sus.ints[i, 2] = soft
    sus.ints[i, 3] = status
    sus.ints[i, 4] = failures
    sus.ints[i, 5] = n_located
    sus.ints[i, 6] = guard
    sus.ints[i, 7] = n_ev
    sus.ints[i, 8] = n_written
    sus.active[i] = 1


@wp.func
def resume_walk(i: int, sus: SuspendedArrays):
    """The state of cell i's suspended walk (:func:`suspend_walk`): z, q, C, fs, fsbc, stage, jammed, soft,
    status, events counted, events written."""
    z = vec5d(sus.z[i, 0], sus.z[i, 1], sus.z[i, 2], sus.z[i, 3], sus.z[i, 4])
    q = vecQd()
    for k in range(N_QUANTITIES):
        q[k] = sus.q[i, k]
    return (z, q, sus.real[i, 0], sus.real[i, 2], sus.real[i, 3], int(sus.ints[i, 0]), int(sus.ints[i, 1]),
            int(sus.ints[i, 2]), int(sus.ints[i, 3]), int(sus.ints[i, 7]), int(sus.ints[i, 8]))


@wp.func
def resume_walk_counters(i: int, sus: SuspendedArrays):
    """The counters of cell i's suspended walk: the sub-step, failed trials in a row, events located, the
    sub-step to resume at."""
    return sus.real[i, 1], int(sus.ints[i, 4]), int(sus.ints[i, 5]), int(sus.ints[i, 6])


def _advance_cell_variant(regular_only: bool, sliced: bool = False):
    """:func:`advance_cell`, or with ``regular_only`` its first pass :func:`advance_regular`, or with
    ``sliced`` the full step in slices :func:`advance_sliced` (issue 15 item 2).

    ``regular_only`` keeps only an increment's regular path: no reversal or reload at its start, one
    trial of the whole increment that converges on a short first Newton step and fires no event (no
    slide, jam, slack, cone or opening; not jammed on unloading).  On any other path it returns False
    at once, before it writes anything: the cell's state is untouched and the full step
    (``advance_cell``) takes the increment from the same start.  Where it returns True, it has done the
    full step's arithmetic in the full step's order, so the two-pass increment is bit for bit the
    one-pass increment.  The code of the other paths is not generated into it (``wp.static``): a GPU
    warp of the first pass does one kind of work, and the few cells with an event are compacted
    into a second launch (:func:`regular_kernel`, :func:`program_kernel` with a count).  Coulomb
    friction without effects only (the kernel keys :data:`REGULAR_PASS` allows).

    ``sliced`` walks at most ``budget`` sub-steps of the Coulomb path per call: where the increment is
    not done by then, it stores what the walk carries (``sus``, :class:`SuspendedArrays`), writes the
    events located so far and returns False, the state arrays untouched; the next call on that cell
    resumes the walk where it stopped, in the same arithmetic, so the result is bit for bit the one-call
    increment.  A GPU warp then waits for the slowest of its cells' next few sub-steps, not for the
    slowest cell's whole increment (a reversal: 3 to 16 sub-steps per cell, up to 246 Newton
    iterations), and the cells still walking are compacted between calls (:func:`substep_kernel`).
    Only the keys of :data:`REGULAR_PASS` (without effects: what the walk carries is its state alone).
    The other variants take ``sus`` and ``budget`` and ignore them (no code is generated for them).
    """

    def advance_cell(
        i: int,
        model: ModelArrays,
        max_halvings: int,
        closure: int,
        s_in: StateArrays,
        # control of this increment
        strain_i: wp.float64,
        dir_i: int,
        rate_i: wp.float64,
        increment: int,
        s_out: StateArrays,
        ev: EventArrays,
        # the sliced variant: where a suspended walk is kept, and the sub-steps this call may take
        sus: SuspendedArrays,
        budget: int,
        # 1: ``s_out`` holds this cell's converged trial of this increment from ``s_in``, without an event
        # (a patch's later coupling trial, :class:`knitsim.cell.batch.CellControl`)
        warm_i: int,
        # where the step writes each cell's slope dF/dC at its end where its last solve gave it, NaN elsewhere
        # (empty: not written, and not computed)
        slope_out: wp.array(dtype=wp.float64),
    ):
        """Advance cell ``i`` by one increment to ``C = C0 (1 + strain_i)`` (CellCycle.run, one row).

        Reads the state ``s_in`` at the start and writes ``s_out`` at the end: they may be the same arrays
        (a cell reads and writes only its own row), as :func:`program_kernel` passes them.

        With ``warm_i`` the Newton of the increment's first sub-step starts from the state ``s_out``
        holds (the last trial's end, on the same branch: no event, the same stage) instead of the
        state at the start: the same equilibrium, reached in one to three iterations instead of three to
        five and without the predicted sub-steps (:func:`solve_coulomb_warm`: a first step shorter than
        WARM_STEP_MAX taken without evaluating its end, else iterated past the cell step's tolerance, since
        a warm solve stopped at it is another point of the tolerance band than the trial's, and at a few
        mN that left columns unconverged).  Everything else (the checks at the start, the events judged
        between the start and the end) is the same; where that solve fails, the sub-step is solved from
        the start as without ``warm_i``.  ``slope_out`` (where given: a patch's trials) gets the branch's
        slope dF/dC at the end from the Jacobian of the last solve (:func:`newton_solve`'s ``want_slope``,
        or the warm short step's), where no event fired and no effect is on (NaN elsewhere: the tangent
        kernel's cases, and the solves that do not give it)."""
        mat = read_material(i, model)
        mat.closure = closure
        q = vecQd()
        for k in range(N_QUANTITIES):
            q[k] = s_in.q[i, k]
        # the cell travels in Newton variables z (kernels below name them x)
        x = z_of(vec5d(s_in.x[i, 0], s_in.x[i, 1], s_in.x[i, 2], s_in.x[i, 3], s_in.x[i, 4]), q)
        C = s_in.C[i]
        stage = int(s_in.stage[i])
        jammed = int(s_in.jammed[i])
        soft = int(s_in.soft[i])
        fs = s_in.fsoft[i]
        fsbc = s_in.fsbc[i]
        status = int(s_in.status[i])
        dir_old = int(s_in.direction[i])
        dir_new = dir_i
        C_target = mat.C0 * (wp.float64(1.0) + strain_i)

        # --- effects (issue 6): this increment's parameters from the state at its start
        mask = int(model.eff_mask[i % model.eff_mask.shape[0]])
        z_bend = s_in.eff[i, E_Z]
        # the lagged friction ratio goes linearly from that of the last increment (mat_old) to this one's
        # (mat) along the increment, so that a sudden change of state (a reversal) cannot make it jump
        mat_old = mat
        # the kernel key's switches (constant False: the branch is not generated)
        with_effects = wp.static(WITH_EFFECTS)
        if wp.static(WITH_EFFECTS):
            with_effects = mask != 0
        if with_effects:
            de = (C_target - C) / mat.C0
            if stage == SLACK and C_target <= C:
                de = wp.float64(0.0)  # a slack loop does not bend
            mat_old = material_from_effective(mat, s_in.eff[i, E_M])
            mat = apply_effects(mat, mask, model.eff_params, i % model.eff_params.shape[0], q, z_bend, s_in.eff[i, E_P0],
                                s_in.eff[i, E_RN0], C, de, rate_i)

        # events of this increment (kind, C, from-label, to-label), committed at the end
        n_ev = int(0)
        e_kind = vec8i()
        e_C = vec8d()
        e_F = vec8d()
        e_from = vec8i()
        e_to = vec8i()
        # events of this increment already in the event buffer (written by a suspended call)
        n_written = int(0)

        # --- a walk suspended by an earlier call (the sliced variant) resumes where it stopped: the
        # start of the increment (reversal, reload) is behind it
        resumed = bool(False)
        if wp.static(sliced):
            if sus.active[i] != 0:
                resumed = True
                x, q, C, fs, fsbc, stage, jammed, soft, status, n_ev, n_written = resume_walk(i, sus)

        # --- reversal (Table 4: SF- on unloading, SF+ on reloading)
        if dir_new != dir_old and status == ST_OK and stage != SLACK and not resumed:
            if wp.static(regular_only):
                return False
            stage, soft, fs, fsbc = reverse(dir_new, q, mat, soft, fs)
            n_ev, e_kind, e_C, e_F, e_from, e_to = push_event(n_ev, e_kind, e_C, e_F, e_from, e_to, _EV_REVERSAL, C,
                                                              q[Q_F], -1, -1)

        go = status == ST_OK

        # --- slack: no load until the imposed C returns to where the cell went slack
        if go and stage == SLACK:
            if C_target - C <= _REACHED_RTOL * C_target:
                go = False  # asked for no more than its slack length (to rounding): it stays slack
            else:
                if wp.static(regular_only):
                    return False
                stage, soft, fs, fsbc = reverse(1, q, mat, soft, fs)
                x = seed_contact(x)
                n_ev, e_kind, e_C, e_F, e_from, e_to = push_event(n_ev, e_kind, e_C, e_F, e_from, e_to, _EV_RELOAD, C,
                                                                  q[Q_F], -1, -1)

        go_coulomb = wp.static(WITH_COULOMB)
        if wp.static(WITH_COULOMB):
            go_coulomb = go and mat.dahl == 0
        go_dahl = wp.static(WITH_DAHL)
        if wp.static(WITH_DAHL):
            go_dahl = go and mat.dahl != 0
        # the branch's slope dF/dC at the end, from the Jacobian of the last sub-step's solve where slope_out is
        # given and no event fired in the increment past its start (a reversal or a reload at the start enters
        # the branch the walk is on) (NaN: not known)
        slope = wp.float64(wp.nan)
        n_start = n_ev
        if go_coulomb:
            # ---------------------------------------------------- Coulomb (Table 4)
            # walked in sub-steps: a failed solve halves the sub-step (at most
            # max_halvings times in a row), a converged one doubles it back, and
            # events are checked on every sub-step (CellCycle.advance)
            step = C_target - C
            C_start = C
            matg = mat
            failures = int(0)
            n_located = int(0)
            guard0 = int(0)
            if wp.static(sliced):
                if resumed:
                    step, failures, n_located, guard0 = resume_walk_counters(i, sus)
            # a later coupling trial of the increment: the last trial's end state (read before s_out is written)
            warm_go = warm_i != 0 and not resumed and not with_effects
            x_warm = x
            if warm_go:
                q_warm = vecQd()
                for k in range(N_QUANTITIES):
                    q_warm[k] = s_out.q[i, k]
                x_warm = z_of(vec5d(s_out.x[i, 0], s_out.x[i, 1], s_out.x[i, 2], s_out.x[i, 3], s_out.x[i, 4]), q_warm)
            for guard in range(guard0, MAX_SUBSTEPS):
                C_from = C
                if wp.abs(C_target - C_from) <= _REACHED_RTOL * C_target:
                    break
                if wp.static(regular_only):
                    if guard > 0:
                        return False  # the first trial did not reach the target
                if wp.static(sliced):
                    if guard - guard0 >= budget:
                        # this call's sub-steps are spent: the walk is kept for the next call
                        n_written = write_events(i, increment, n_written, n_ev, e_kind, e_C, e_F, e_from, e_to, ev)
                        suspend_walk(i, sus, x, q, C, step, fs, fsbc, stage, jammed, soft, status, failures,
                                     n_located, guard, n_ev, n_written)
                        return False
                if wp.abs(step) > wp.abs(C_target - C_from):
                    step = C_target - C_from
                C_goal = C_from + step
                if with_effects:
                    matg = blend_material(mat_old, mat, (C_goal - C_start) / (C_target - C_start))
                kind0 = int(-1)
                mat_from = matg
                if with_effects:
                    mat_from = blend_material(mat_old, mat, (C_from - C_start) / (C_target - C_start))
                if cone_at_start(x, q, stage, jammed, soft, fs, fsbc, matg, C, C_target):
                    kind0 = int(_EV_CONE)
                elif slide_at_start(x, q, stage, jammed, soft, fs, fsbc, matg, mat_from, C, C_target):
                    kind0 = int(_EV_SLIDE)
                if kind0 >= 0:
                    if wp.static(regular_only):
                        return False
                    stage, jammed, soft, fs, status, n_ev, e_kind, e_C, e_F, e_from, e_to = take_event(
                        kind0, C, stage, jammed, soft, fs, status, q, n_ev, e_kind, e_C, e_F, e_from, e_to)
                    n_located += 1
                    continue
                # the branch's tangent bounds the sub-step: a trial whose first Newton step is long would crawl
                # (the line search accepts steps of 1/16 to 1/64) or fail after NEWTON_MAX_ITER iterations
                # where the branch turns fast (the S+ -> SF- reversal, R/P -> 0.05 within 0.01 mm); it is
                # shortened at once to a step the tangent predicts at PREDICTED_STEP_TARGET, which is not a failure
                if wp.static(regular_only):
                    if jammed != 0 and not is_loading(stage):
                        return False  # the jammed unloading's active-set check (below) is not regular
                if jammed != 0 and not is_loading(stage):
                    # jammed unloading: the unjam at the start is checked before the jammed trial, which has no
                    # solution where the unjammed branch opens (the reversal from a jammed state: its direct
                    # solve and its sub-step walk fail after up to 60 Newton iterations each, then this check
                    # finds the unjam in about 6)
                    if unjam_at_start(x, q, stage, soft, fs, fsbc, matg, C_from, C_goal):
                        stage, jammed, soft, fs, status, n_ev, e_kind, e_C, e_F, e_from, e_to = take_event(
                            _EV_UNJAM, C, stage, jammed, soft, fs, status, q, n_ev, e_kind, e_C, e_F, e_from, e_to)
                        n_located += 1
                        continue
                pred = PREDICTED_STEP_MAX
                if is_sliding(stage) or jammed != 0 or no_contact(q) or wp.abs(step) <= wp.float64(4.0) * _SUBSTEP_FLOOR * matg.C0:
                    pred = wp.float64(0.0)
                xt = x
                qt = q
                ok = bool(False)
                step0 = vec5d()
                warmed = bool(False)
                slope_w = wp.float64(wp.nan)
                if warm_go and guard == 0:
                    # the whole increment from the last trial's end: no predicted sub-steps (that trial walked them)
                    xt, qt, warmed, slope_w = solve_coulomb_warm(x_warm, stage, jammed, soft, fs, fsbc, matg, C_goal,
                                                                 slope_out.shape[0] > 0)
                    ok = warmed
                if not warmed:
                    # (the slope of its end, for a patch's coupling: slope_out given)
                    xt, qt, ok, step0, slope_w = solve_coulomb_trial(x, stage, jammed, soft, fs, fsbc, matg, C_from,
                                                                     C_goal, pred, slope_out.shape[0] > 0)
                first = max_abs5(step0)
                # the nearest event of the sub-step, committed below
                best_kind = int(-1)
                best_C = wp.float64(0.0)
                best_x = x
                best_q = q
                if first > wp.float64(0.0):
                    if wp.static(regular_only):
                        return False
                    found, xe, qe = slide_predicted(x, q, stage, jammed, soft, fs, fsbc, matg, C_from, C_goal, step0)
                    if not found:
                        short = step * wp.max(PREDICTED_STEP_TARGET / first, wp.float64(1.0 / 1024.0))
                        if wp.abs(short) < wp.float64(2.0) * _SUBSTEP_FLOOR * matg.C0:
                            short = wp.sign(step) * wp.float64(2.0) * _SUBSTEP_FLOOR * matg.C0
                        step = short
                        continue
                    # the slide, located directly: no trial
                    best_kind = int(_EV_SLIDE)
                    best_C = qe[Q_C]
                    best_x = xe
                    best_q = qe
                if best_kind < 0:
                    if wp.static(regular_only):
                        if not ok:
                            return False
                    # (a jammed unloading trial that failed: its unjam at the start was checked before the trial)
                    if not ok:
                        failures += 1
                        if not may_halve(failures, step, max_halvings, matg):
                            status = int(ST_NO_CONV)
                            break
                        step = step * wp.float64(0.5)
                        continue
                    opened = bool(False)
                    if not is_loading(stage) and qt[Q_RN] < wp.float64(0.0):
                        if wp.static(regular_only):
                            return False
                        # the trial end pulls: the contact opened inside the sub-step (the branch went through
                        # Rn = 0 and on with R < 0, outside the model).  The sub-step ends where it opens, and
                        # every event is judged on that part of the branch (CellCycle.advance)
                        opened = True
                        xt, qt, C_goal = branch_sign_change(x, q, stage, jammed, soft, fs, fsbc, matg, C_from, C_goal, Q_RN,
                                                             wp.float64(0.0), wp.float64(1.0))
                    # events fired inside the increment
                    any_fired = bool(False)
                    for kind in range(8):
                        # the slack of a sub-step that ends where its contact opens is decided below
                        if locatable(kind) and event_active(kind, stage, jammed, soft, matg) and not (opened and kind == _EV_SLACK):
                            f0 = event_value(kind, x, q, stage, matg)
                            f1 = event_value(kind, xt, qt, stage, matg)
                            tol = event_tol(kind, matg)
                            if f1 > wp.float64(0.0) and f0 <= tol:
                                if wp.static(regular_only):
                                    return False
                                any_fired = True
                                xe = x
                                qe = q
                                oke = bool(True)
                                if f0 < -tol and no_contact(q):
                                    # phi is undetermined at a zero-contact start: judge the event on
                                    # a probe step (the new branch's limit); if it holds there, or the
                                    # probe fails, the event happens at the start
                                    hp = _PROBE_STEP * matg.C0
                                    if C_goal < C_from:
                                        hp = -hp
                                    xp, qp, okp = solve_coulomb(seed_contact(x), stage, jammed, soft, fs, fsbc, matg, C_from + hp, -1, wp.float64(0.0))
                                    if (not okp) or event_value(kind, xp, qp, stage, matg) >= -tol:
                                        f0 = wp.float64(0.0)
                                if f0 < -tol:
                                    code, etg = event_condition_at(kind, stage, matg, qt)
                                    xg = lerp5(x, xt, interp_t(f0, f1))
                                    xe, qe, oke = solve_coulomb(xg, stage, jammed, soft, fs, fsbc, matg, C_goal, code, etg)
                                    if not oke:
                                        xe, qe, oke = solve_coulomb(xt, stage, jammed, soft, fs, fsbc, matg, C_goal, code, etg)
                                elif kind == _EV_CONE and not no_contact(q):
                                    # zero at the start, but cone_at_start's probe stayed inside the cone: the
                                    # branch dips into the cone and leaves it further on, located by bisection
                                    # on the sign of phimax - phi (CellCycle._locate)
                                    xe, qe, Ce = branch_sign_change(x, q, stage, jammed, soft, fs, fsbc, matg, C_from, C_goal,
                                                                    cone_which(matg), matg.phimax, wp.float64(-1.0))
                                    oke = Ce != C_from
                                # else: already satisfied at the start of the sub-step, it happens there
                                if oke and in_range(qe[Q_C], C_from, C_goal):
                                    if best_kind < 0 or wp.abs(qe[Q_C] - C_from) < wp.abs(best_C - C_from):
                                        best_kind = kind
                                        best_C = qe[Q_C]
                                        best_x = xe
                                        best_q = qe
                    # active set while unloading jammed: the unjammed branch at the target (walked there
                    # from the start when Newton fails from it; where it has no solution, the cell stays
                    # jammed: CellCycle._try_unjam)
                    if wp.static(not regular_only):
                        if jammed != 0 and not is_loading(stage):
                            xu, qu, oku = solve_coulomb_cont(x, stage, 0, soft, fs, fsbc, matg, C_from, C_goal)
                            if oku and jam_clearance(xu, qu, matg) >= wp.float64(0.0):
                                any_fired = True
                                # the unjammed branch at the start: at the reversal from a jammed
                                # state it passes through the jammed state itself (event at the start)
                                xa, qa, oka = solve_coulomb(x, stage, 0, soft, fs, fsbc, matg, C_from, -1, wp.float64(0.0))
                                xe = x
                                qe = q
                                oke = bool(True)
                                if not (oka and jam_clearance(xa, qa, matg) >= -event_tol(_EV_UNJAM, matg)):
                                    xe, qe, oke = solve_coulomb(xu, stage, 0, soft, fs, fsbc, matg, C_goal, jam_code(matg), jam_target(matg))
                                if oke and in_range(qe[Q_C], C_from, C_goal):
                                    if best_kind < 0 or wp.abs(qe[Q_C] - C_from) < wp.abs(best_C - C_from):
                                        best_kind = int(_EV_UNJAM)
                                        best_C = qe[Q_C]
                                        best_x = xe
                                        best_q = qe
                    if opened:
                        # slack on the part of the branch before the opening (CellCycle.advance): eq 7,
                        # F = -2 R cos(beta + phi), with R -> 0+ there; where cos(beta + phi) > 0 at the opening, F
                        # is < 0 just before it, so F reached 0 first at beta + phi = pi/2 (R > 0, a regular zero):
                        # bisection on its sign; else the cell goes slack where the contact opens, if R -> 0 there
                        # (the friction angle inside the cone); else (Rn -> 0 with a tangential force left and no
                        # cone or slide event) the sub-step is halved
                        any_fired = True
                        ks = int(-1)
                        xs = xt
                        qs = qt
                        C_slack = C_goal
                        if wp.cos(qt[Q_BETA] + qt[Q_PHI]) > wp.float64(0.0) and q[Q_F] > wp.float64(0.0):
                            xs, qs, C_slack = branch_sign_change(x, q, stage, jammed, soft, fs, fsbc, matg, C_from, C_goal, Q_F,
                                                                wp.float64(0.0), wp.float64(1.0))
                            ks = int(_EV_SLACK)
                        elif no_contact(qt):
                            ks = int(_EV_SLACK)
                        if ks >= 0 and (best_kind < 0 or wp.abs(C_slack - C_from) < wp.abs(best_C - C_from)):
                            best_kind = ks
                            best_C = C_slack
                            best_x = xs
                            best_q = qs
                    if not any_fired:
                        failures = 0
                        x = xt
                        q = qt
                        C = C_goal
                        slope = slope_w   # of this sub-step's end (NaN where its solve did not give it)
                        step = step * wp.float64(2.0)
                        continue
                    if best_kind < 0:
                        # the trial end fired an event its branch cannot reach: the solve jumped
                        # to another branch; retried on a halved sub-step (CellCycle.advance)
                        failures += 1
                        if not may_halve(failures, step, max_halvings, matg):
                            status = int(ST_NOT_LOCATED)
                            break
                        step = step * wp.float64(0.5)
                        continue
                failures = 0
                x = best_x
                q = best_q
                C = best_C
                stage, jammed, soft, fs, status, n_ev, e_kind, e_C, e_F, e_from, e_to = take_event(
                    best_kind, C, stage, jammed, soft, fs, status, q, n_ev, e_kind, e_C, e_F, e_from, e_to)
                if status != ST_OK or stage == SLACK:
                    break
                n_located += 1
                if n_located >= MAX_EVENT_LOOPS:
                    break
                step = C_target - C
        elif go_dahl:
            # ---------------------------------------------------- Dahl (sub-stepped on failure)
            if wp.static(regular_only):
                return False  # (no first pass for Dahl: REGULAR_PASS)
            C_start = C
            matg = mat
            n_ev0 = n_ev
            nsub = int(1)
            # the slip direction predicted from the stick branch's tangent (dahl_sign) only without effects: with
            # a lagged friction ratio or stiffness the Dahl path depends on how the increment is split, hence on
            # which solves fail, and a Dahl solve started from the state instead of the stick trial fails elsewhere
            dahl_predict = not with_effects
            done = bool(False)
            for attempt in range(wp.min(max_halvings, _MAX_DAHL_HALVINGS) + 1):
                if not done:
                    n_ev = n_ev0
                    tx = x
                    tq = q
                    tC = C
                    tstage = stage
                    tjam = jammed
                    tsoft = soft
                    tfs = fs
                    tstatus = status
                    failed = bool(False)
                    for k in range(1, nsub + 1):
                        if not failed and tstatus == ST_OK and tstage != SLACK:
                            Ck = C_start + (C_target - C_start) * wp.float64(k) / wp.float64(nsub)
                            if with_effects:
                                matg = blend_material(mat_old, mat, wp.float64(k) / wp.float64(nsub))
                            for loop in range(MAX_EVENT_LOOPS):
                                if not failed:
                                    xt, qt, s, ok = solve_dahl_at(tx, tq, tjam, tsoft, tfs, matg, Ck, dahl_predict and tjam == 0)
                                    if not ok:
                                        failed = True
                                        break
                                    best_kind = int(-1)
                                    best_C = wp.float64(0.0)
                                    best_x = tx
                                    best_q = tq
                                    for kind in range(8):
                                        if locatable(kind) and event_active(kind, tstage, tjam, tsoft, matg):
                                            f0 = event_value(kind, tx, tq, tstage, matg)
                                            f1 = event_value(kind, xt, qt, tstage, matg)
                                            if f1 > wp.float64(0.0) and f0 >= -event_tol(kind, matg) and f0 <= event_tol(kind, matg):
                                                # already satisfied at the start: it happens there
                                                if best_kind < 0 or wp.abs(tC - tC) < wp.abs(best_C - tC):
                                                    best_kind = kind
                                                    best_C = tC
                                                    best_x = tx
                                                    best_q = tq
                                            elif f1 > wp.float64(0.0) and f0 <= wp.float64(0.0):
                                                code, etg = event_condition_at(kind, tstage, matg, qt)
                                                xg = lerp5(tx, xt, interp_t(f0, f1))
                                                se = s
                                                if se == wp.float64(0.0):
                                                    se = wp.float64(1.0)  # stick solved it: xi = 0 either way
                                                xe, qe, oke = solve_dahl(xg, tq, se, tjam, tsoft, tfs, matg, Ck, code, etg)
                                                if not oke:
                                                    xe, qe, oke = solve_dahl(xt, tq, se, tjam, tsoft, tfs, matg, Ck, code, etg)
                                                if bends(matg) and not (oke and in_range(qe[Q_C], tC, Ck)):
                                                    xe, qe = dahl_event_by_bisection(tx, tq, se, tjam, tsoft, tfs, matg, tC, Ck, kind,
                                                                                     tstage)
                                                    oke = True
                                                if not (oke and in_range(qe[Q_C], tC, Ck)):
                                                    failed = True  # the reference's root search raises
                                                elif best_kind < 0 or wp.abs(qe[Q_C] - tC) < wp.abs(best_C - tC):
                                                    best_kind = kind
                                                    best_C = qe[Q_C]
                                                    best_x = xe
                                                    best_q = qe
                                    if failed:
                                        break
                                    # unjam (active set): the reference applies it at the target itself
                                    if tjam != 0 and not is_loading(tstage):
                                        xu, qu, su, oku = solve_dahl_at(tx, tq, 0, tsoft, tfs, matg, Ck, False)
                                        if oku and jam_clearance(xu, qu, matg) >= wp.float64(0.0):
                                            if best_kind < 0 or wp.abs(Ck - tC) < wp.abs(best_C - tC):
                                                best_kind = int(_EV_UNJAM)
                                                best_C = Ck
                                                best_x = xu  # the unjammed solution (W >= W_jam) at the sub-step end
                                                best_q = qu
                                    if best_kind < 0:
                                        tx = xt
                                        tq = qt
                                        tC = Ck
                                        break
                                    tx = best_x
                                    tq = best_q
                                    tC = best_C
                                    if best_kind == _EV_UNJAM:
                                        tC = Ck
                                    tstage, tjam, tsoft, tfs, tstatus, n_ev, e_kind, e_C, e_F, e_from, e_to = take_event(
                                        best_kind, tC, tstage, tjam, tsoft, tfs, tstatus, tq,
                                        n_ev, e_kind, e_C, e_F, e_from, e_to)
                                    if tstatus != ST_OK or tstage == SLACK or tC == Ck:
                                        break
                    if not failed:
                        done = True
                        x = tx
                        q = tq
                        C = tC
                        stage = tstage
                        jammed = tjam
                        soft = tsoft
                        fs = tfs
                        status = tstatus
                    nsub = nsub * 2
            if not done:
                n_ev = n_ev0
                status = int(ST_NO_CONV)
        relabel = wp.static(WITH_DAHL)
        if wp.static(WITH_DAHL):
            relabel = mat.dahl != 0
        if relabel:
            stage = label_dahl(stage, q, mat)

        # --- commit
        xo = x_of_z(x)
        for k in range(5):
            s_out.x[i, k] = xo[k]
        for k in range(N_QUANTITIES):
            s_out.q[i, k] = q[k]
        s_out.C[i] = C
        s_out.stage[i] = stage
        s_out.jammed[i] = jammed
        s_out.soft[i] = soft
        s_out.fsoft[i] = fs
        s_out.fsbc[i] = fsbc
        s_out.status[i] = status
        s_out.direction[i] = dir_new
        # the interpenetration check of every accepted state (issue 13): the heads' centreline gap (a
        # state that did not move keeps its gap bit for bit: z is rebuilt from x at every increment)
        gap = s_in.gap[i]
        if go:
            gap = head_gap_value(wp.exp(x[0]), q, stiffness_at(mat, C))
        s_out.gap[i] = gap
        for k in range(s_in.eff.shape[1]):
            s_out.eff[i, k] = s_in.eff[i, k]
        if with_effects:
            s_out.eff[i, E_M] = mat.m
            if mat.fr_state != 0:
                s_out.eff[i, E_M] = wp.tan(phi_edge(q, mat))  # the ratio at the committed state
            s_out.eff[i, E_D] = jam_width(mat, q[Q_RN]) * (mat.d / mat.w_jam)
            s_out.eff[i, E_L] = mat.L * extension_ratio(q[Q_P], mat.ext_p0, mat.ext_c)
            s_out.eff[i, E_B] = stiffness_at(mat, C)
            if bends(mat):
                z_bend = bending_z(mat, C)  # where the increment ended (a slack or a failed one stops short of C_target)
            s_out.eff[i, E_Z] = z_bend
        if slope_out.shape[0] > 0:
            # (with effects the conditions move with the increment: no branch slope, as the tangent kernel)
            if n_ev != n_start or status != ST_OK or with_effects:
                slope = wp.float64(wp.nan)
            slope_out[i] = slope
        write_events(i, increment, n_written, n_ev, e_kind, e_C, e_F, e_from, e_to, ev)
        if wp.static(sliced):
            if resumed:
                sus.active[i] = 0
        return True

    return wp.func(advance_cell, name="advance_regular" if regular_only else ("advance_sliced" if sliced else "advance_cell"))


advance_cell = _advance_cell_variant(False)


# ------------------------------------------------------------------ the launches of one increment
#: the first pass (regular increments) of the kernel keys that have one (REGULAR_PASS)
advance_regular = _advance_cell_variant(True) if REGULAR_PASS else None
#: the full step in slices of a few sub-steps (the keys of REGULAR_PASS)
advance_sliced = _advance_cell_variant(False, sliced=True) if REGULAR_PASS else None


@wp.func
def listed_cell(j: int, cells: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32)) -> int:
    """The cell of thread ``j`` of a launch: ``cells[j]`` (empty ``cells``: every cell, ``j``), or -1 beyond
    ``count[0]`` (a list whose length a first pass set on the device; empty ``count``: no limit)."""
    i = j
    if count.shape[0] > 0:
        if j >= count[0]:
            i = -1
    if i >= 0 and cells.shape[0] > 0:
        i = cells[j]
    return i


def _step_kernel_variant(first_pass: bool):
    """:func:`step_kernel`, or with ``first_pass`` :func:`regular_step_kernel`: the same launch with
    :func:`advance_cell` or its first pass (``_advance_cell_variant``)."""
    advance = advance_regular if first_pass else advance_cell

    def step_kernel(
        # the cells this launch advances (a group of one kernel key); empty: every cell, in order
        cells: wp.array(dtype=wp.int32),
        # how many of ``cells`` to advance (count[0], set on the device by a first pass); empty: all
        count: wp.array(dtype=wp.int32),
        # first pass: where it lists the cells it leaves for the full step (pending[:pending_count[0]])
        pending: wp.array(dtype=wp.int32), pending_count: wp.array(dtype=wp.int32),
        model: ModelArrays, max_halvings: int, closure: int,
        s_in: StateArrays,
        # control
        strain: wp.array(dtype=wp.float64), direction: wp.array(dtype=wp.int32), rate: wp.array(dtype=wp.float64),
        increment: int,
        s_out: StateArrays,
        ev: EventArrays,
        # 1 where s_out holds the cell's converged trial of this increment, without an event (CellControl.warm)
        warm: wp.array(dtype=wp.int32),
        # out: the slope dF/dC at each advanced cell's end where its last solve gave it, NaN elsewhere (empty: not written)
        slope: wp.array(dtype=wp.float64),
    ):
        """Advance each cell by one increment to ``C = C0 (1 + strain)`` (CellCycle.run, one row); a first
        pass leaves the ``s_out`` rows of the cells it lists untouched."""
        i = listed_cell(wp.tid(), cells, count)
        if i < 0:
            return
        done = wp.static(advance)(i, model, max_halvings, closure, s_in, strain[i % strain.shape[0]],
                                  int(direction[i % direction.shape[0]]), rate[i % rate.shape[0]], increment,
                                  s_out, ev, SuspendedArrays(), 0, int(warm[i % warm.shape[0]]), slope)
        if wp.static(first_pass):
            if not done:
                pending[wp.atomic_add(pending_count, 0, 1)] = i

    return wp.kernel(step_kernel, name="regular_step_kernel" if first_pass else "step_kernel")


@wp.func
def write_history_row(i: int, row: int, state: StateArrays, hist: HistoryArrays):
    """History row ``row`` of cell i: hist.q[k rows + row, i] = q[i, codes[k]] (F = 0 while slack), stage,
    jam flag, status, head gap and (where recorded) the effects' state (HistoryArrays' layout)."""
    st = state.stage[i]
    rows = hist.stage.shape[0]
    for k in range(hist.codes.shape[0]):
        c = hist.codes[k]
        v = state.q[i, c]
        if c == Q_F and st == SLACK:
            v = wp.float64(0.0)
        hist.q[k * rows + row, i] = v
    hist.stage[row, i] = st
    hist.jammed[row, i] = state.jammed[i]
    hist.status[row, i] = state.status[i]
    hist.gap[row, i] = state.gap[i]
    for j in range(hist.eff.shape[0] // rows):
        hist.eff[j * rows + row, i] = state.eff[i, j]


def _program_kernel_variant(first_pass: bool):
    """:func:`program_kernel`, or with ``first_pass`` :func:`regular_kernel` (one increment only:
    ``k_stop = k_start + 1``)."""
    advance = advance_regular if first_pass else advance_cell

    def program_kernel(
        # the cells this launch advances (a group of one kernel key); empty: every cell, in order
        cells: wp.array(dtype=wp.int32),
        # how many of ``cells`` to advance (count[0], set on the device by a first pass); empty: all
        count: wp.array(dtype=wp.int32),
        # first pass: where it lists the cells it leaves for the full step (pending[:pending_count[0]])
        pending: wp.array(dtype=wp.int32), pending_count: wp.array(dtype=wp.int32),
        model: ModelArrays, max_halvings: int, closure: int,
        # advanced in place
        state: StateArrays,
        # the load program: strain, direction and rate of every increment, and the increments to run
        prog_strain: wp.array(dtype=wp.float64), prog_direction: wp.array(dtype=wp.int32),
        prog_rate: wp.array(dtype=wp.float64), k_start: int, k_stop: int, stride: int,
        ev: EventArrays,
        hist: HistoryArrays,
        # not written (an empty array; advance_cell's slope_out)
        slope: wp.array(dtype=wp.float64),
    ):
        """Advance each cell through increments ``k_start .. k_stop - 1`` of a load program in one launch,
        recording the rows of increments ``stride - 1, 2 stride - 1, ...`` (every row with stride 1) into
        preallocated history arrays: the same arithmetic as one :func:`step_kernel` per increment, without a
        launch (nor a host round trip) per increment.  A first pass lists the cells it leaves (their state
        and row untouched)."""
        i = listed_cell(wp.tid(), cells, count)
        if i < 0:
            return
        for k in range(k_start, k_stop):
            done = wp.static(advance)(i, model, max_halvings, closure, state, prog_strain[k], int(prog_direction[k]),
                                      prog_rate[k % prog_rate.shape[0]], k, state, ev, SuspendedArrays(), 0, 0, slope)
            if not done:
                pending[wp.atomic_add(pending_count, 0, 1)] = i
                return
            if (k + 1) % stride == 0:
                # row r holds increment (r + 1) stride - 1 (every increment with stride 1)
                write_history_row(i, k // stride, state, hist)

    return wp.kernel(program_kernel, name="regular_kernel" if first_pass else "program_kernel")


step_kernel = _step_kernel_variant(False)
program_kernel = _program_kernel_variant(False)
if REGULAR_PASS:
    regular_step_kernel = _step_kernel_variant(True)
    regular_kernel = _program_kernel_variant(True)

    @wp.kernel
    def substep_kernel(
        # the cells this launch advances, the first count[0] of them (a list a first pass or an earlier
        # substep_kernel made on the device)
        cells: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
        # where it lists the cells it suspends (pending[:pending_count[0]]); unused with a budget of MAX_SUBSTEPS
        pending: wp.array(dtype=wp.int32), pending_count: wp.array(dtype=wp.int32),
        model: ModelArrays, max_halvings: int, closure: int,
        # advanced in place
        state: StateArrays,
        prog_strain: wp.array(dtype=wp.float64), prog_direction: wp.array(dtype=wp.int32),
        prog_rate: wp.array(dtype=wp.float64), k: int, stride: int,
        ev: EventArrays,
        hist: HistoryArrays,
        sus: SuspendedArrays,
        budget: int,
        # not written (an empty array; advance_cell's slope_out)
        slope: wp.array(dtype=wp.float64),
    ):
        """Increment ``k`` of the listed cells, at most ``budget`` sub-steps of each (:func:`advance_sliced`):
        a cell whose increment is done is committed and its row recorded as :func:`program_kernel` does;
        the others are suspended and listed for the next launch."""
        i = listed_cell(wp.tid(), cells, count)
        if i < 0:
            return
        done = advance_sliced(i, model, max_halvings, closure, state, prog_strain[k], int(prog_direction[k]),
                              prog_rate[k % prog_rate.shape[0]], k, state, ev, sus, budget, 0, slope)
        if not done:
            pending[wp.atomic_add(pending_count, 0, 1)] = i
            return
        if (k + 1) % stride == 0:
            write_history_row(i, k // stride, state, hist)


@wp.kernel
def zero_count_kernel(count: wp.array(dtype=wp.int32)):
    """count[0] = 0 (a launch, so that a captured graph replays it)."""
    count[0] = 0


@wp.kernel
def stage_key_kernel(cells: wp.array(dtype=wp.int32), stage: wp.array(dtype=wp.int32),
                     jammed: wp.array(dtype=wp.int32), status: wp.array(dtype=wp.int32),
                     keys: wp.array(dtype=wp.int32), values: wp.array(dtype=wp.int32)):
    """Sort key of each cell of a launch: its stage and jammed flag (stopped cells last), so that a
    radix sort puts cells in the same stage side by side (one warp, one kind of work on a GPU)."""
    j = wp.tid()
    i = j
    if cells.shape[0] > 0:
        i = cells[j]
    k = 2 * stage[i] + jammed[i]
    if status[i] != ST_OK:
        k = 2 * SLACK + 2
    keys[j] = k
    values[j] = i
