"""Switchable model extensions of a cell (issue 6), Warp device code (float64).

The laws, their parameters and why each is written so are in
:mod:`knitsim.cell.effects` (the Python description); here each effect is one
small ``@wp.func`` that maps the parameters of an increment to their effective
value, and :func:`effective_parameters` applies the effects that are on.

Per-cell inputs (``i % shape[0]`` broadcast, as the model arrays):

- ``mask`` (int32): bits of :data:`knitsim.cell.effects.EFFECT_BITS`;
- ``params`` (float64 [1 or N, len(PARAM_COLUMNS)]): the effect parameters;
- the effective state ``eff`` (float64 [N, len(EFFECT_STATE)]): the effective
  m, d, L, B of the last increment, the bending Dahl state z and the rest
  values P_0, Rn_0.
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.effects import EFFECT_BITS, EFFECT_STATE, M_EFF_MAX, PARAM_COLUMNS
from knitsim.cell.quantities import Q_BETA, Q_P, Q_RN

from .dahl import dahl_increment_alpha1
from .elastica import Dual, d_addc, d_const, d_div, d_scale
from .friction import coiling_ratio_m, howell_mu_k

wp.set_module_options({"enable_backward": False})

BIT_COILING = wp.constant(EFFECT_BITS["coiling_angle_friction"])
BIT_NORMAL_LOAD = wp.constant(EFFECT_BITS["normal_load_friction"])
BIT_VELOCITY = wp.constant(EFFECT_BITS["velocity_friction"])
BIT_COMPACTION = wp.constant(EFFECT_BITS["yarn_compaction"])
BIT_BENDING = wp.constant(EFFECT_BITS["bending_hysteresis"])
BIT_EXTENSION = wp.constant(EFFECT_BITS["yarn_extension"])

_col = {name: wp.constant(k) for k, name in enumerate(PARAM_COLUMNS)}
P_COIL_MU = _col["coil_mu_k"]
P_LOAD_N = _col["load_n"]
P_LOAD_REF = _col["load_ref_N"]
P_RATE_P = _col["rate_p"]
P_RATE_REF = _col["rate_ref_mm_s"]
P_COMP_K = _col["compaction_k"]
P_COMP_MIN = _col["compaction_min"]
P_BEND_H = _col["bend_h"]
P_BEND_SIGMA = _col["bend_sigma"]
P_EXT_C = _col["ext_c"]

_st = {name: wp.constant(k) for k, name in enumerate(EFFECT_STATE)}
E_M = _st["m_eff"]
E_D = _st["d_eff"]
E_L = _st["L_eff"]
E_B = _st["B_eff"]
E_Z = _st["z_bend"]
E_P0 = _st["P_rest"]
E_RN0 = _st["Rn_rest"]
N_EFFECT_STATE = len(EFFECT_STATE)

_M_MAX = wp.constant(wp.float64(M_EFF_MAX))
#: normal loads below this fraction of the reference are read as it (Rn -> 0 with n < 1 diverges)
_RN_FLOOR = wp.constant(wp.float64(1.0e-3))


@wp.func
def has(mask: int, bit: int) -> wp.bool:
    return (mask & bit) != 0


@wp.func
def coiling_friction(beta: wp.float64, mu_k: wp.float64) -> wp.float64:
    """Eq 10 with the coiling angle read from the loop: theta = beta, the tangent angle at B."""
    return coiling_ratio_m(beta, mu_k)


@wp.func
def normal_load_factor(Rn: wp.float64, n: wp.float64, Rn_ref: wp.float64) -> wp.float64:
    """Eq 5's normal-load term relative to the reference load, (Rn / Rn_ref)^(n - 1)."""
    x = wp.max(wp.abs(Rn), _RN_FLOOR * Rn_ref)
    return howell_mu_k(wp.float64(1.0), wp.float64(0.0), n, wp.float64(1.0), x / Rn_ref)


@wp.func
def velocity_factor(V: wp.float64, p: wp.float64, V_ref: wp.float64) -> wp.float64:
    """Eq 5's velocity term relative to the reference rate, (V / V_ref)^p (1 where no rate is given)."""
    f = wp.float64(1.0)
    if V > wp.float64(0.0):
        f = howell_mu_k(wp.float64(1.0), p, wp.float64(1.0), V / V_ref, wp.float64(1.0))
    return f


@wp.func
def compaction_ratio_dual(Rn: Dual, Rn_rest: wp.float64, k: wp.float64, c_min: wp.float64):
    """d_eff / d = clamp((1 + k Rn_0) / (1 + k |Rn|), c_min, 1): a yarn that flattens under the crossing
    load beyond the rest load (d is the diameter at rest; below the rest load it keeps d).  The one
    law, as a Dual: the Newton's jamming residual reads it at the solution's own load
    (``cell_step.jam_residual``), :func:`compaction_ratio` at a value."""
    a = Rn
    if Rn.v < wp.float64(0.0):
        a = d_scale(Rn, wp.float64(-1.0))
    r = d_div(d_const(wp.float64(1.0) + k * wp.abs(Rn_rest)), d_addc(d_scale(a, k), wp.float64(1.0)))
    if r.v > wp.float64(1.0):
        r = d_const(wp.float64(1.0))
    elif r.v < c_min:
        r = d_const(c_min)
    return r


@wp.func
def compaction_ratio(Rn: wp.float64, Rn_rest: wp.float64, k: wp.float64, c_min: wp.float64) -> wp.float64:
    """:func:`compaction_ratio_dual` at a value."""
    return compaction_ratio_dual(d_const(Rn), Rn_rest, k, c_min).v


@wp.func
def dahl_bending_state(z: wp.float64, dstrain: wp.float64, sigma: wp.float64) -> wp.float64:
    """Dahl (alpha = 1) in the strain, exact over a monotone increment: z -> s + (z - s) exp(-sigma |de|),
    the Dahl update of the friction law (:func:`kernels.dahl.dahl_increment_alpha1`) with a unit limit."""
    return dahl_increment_alpha1(z, dstrain, sigma, wp.float64(1.0))


@wp.func
def extension_ratio_dual(P: Dual, P_rest: wp.float64, c: wp.float64):
    """L_eff / L = 1 + c (P - P_0): the yarn force at A (where the moment vanishes) stretches the yarn.
    The one law, as a Dual: the Newton's length residual reads it at the solution's own force
    (``cell_step.extension_residual``), :func:`extension_ratio` at a value."""
    return d_addc(d_scale(d_addc(P, -P_rest), c), wp.float64(1.0))


@wp.func
def extension_ratio(P: wp.float64, P_rest: wp.float64, c: wp.float64) -> wp.float64:
    """:func:`extension_ratio_dual` at a value."""
    return extension_ratio_dual(d_const(P), P_rest, c).v
