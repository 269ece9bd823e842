"""Tangent dF/dC of a converged cell state on its own branch (implicit function theorem), float64 Warp.

At a converged state of a Coulomb stage the five equations r(z; C) = 0 hold
(:func:`knitsim.kernels.cell_step.residuals_ext`: closure g = 0 and the stage's four
conditions, slot 1 the driving condition ``(C(z) - C) / s_C``, :func:`stage_conditions`).
Along the branch, dr = J dz + (dr/dC) dC = 0 with dr/dC = -e_2 / s_C (only the C row
depends on the imposed course length), so

    dz/dC = J^-1 e_2 / s_C,        dF/dC = (dF/dz) . dz/dC,

with J and dF/dz the forward-mode duals of the cell's own Newton at that state (the
same evaluation, :func:`evaluate_zr`).  This is the exact slope of the branch the cell
is on, where a secant between two trial steps of the patch coupling only approximates
it (and mixes branches across an event).  One evaluation and one 5x5 solve per cell
(:func:`~knitsim.kernels.cell_step.branch_slope`, which a patch's trial step also gives from its own last
Newton, where its increment fired no event past the start: this kernel serves the other cells).

NaN where it is not defined by the equations above: Dahl cells (the Dahl residual
depends on the committed state of the increment), cells with effects (their parameters
move with the increment), slack or stopped cells, a singular J.  The patch coupling
(:mod:`knitsim.patch.coupling`) then keeps its secant.
"""
from __future__ import annotations

import warp as wp

from knitsim.cell.quantities import Q_F

from .cell_step import (
    SLACK, ST_OK, branch_slope, evaluate_zr, read_material, residuals_ext, reverse, stage_conditions, vec10p, z_of,
)
from .cell_arrays import ModelArrays, StateArrays
from .elastica import vec5d
from .quarter_loop import N_QUANTITIES, quantity, vecQd

wp.set_module_options({"max_unroll": 1, "enable_backward": False})


@wp.kernel
def branch_tangent_kernel(
    model: ModelArrays,
    state: StateArrays,
    # the direction of the coming increment (0: none); where it reverses the state's own, the
    # tangent is that of the stage the reversal enters (kernels.cell_step.reverse: SF- / SF+)
    dir_new: int,
    # out
    k: wp.array(dtype=wp.float64),
):
    """k[i] = dF/dC of cell i at its state (module docstring), NaN where undefined."""
    i = wp.tid()
    mat = read_material(i, model)
    kk = wp.float64(wp.nan)
    st = int(state.stage[i])
    if state.status[i] == ST_OK and st != SLACK and mat.dahl == 0 and model.eff_mask[i % model.eff_mask.shape[0]] == 0:
        qi = vecQd()
        for j in range(N_QUANTITIES):
            qi[j] = state.q[i, j]
        sf = int(state.soft[i])
        fs = state.fsoft[i]
        fb = state.fsbc[i]
        if dir_new != 0 and dir_new != state.direction[i]:
            st, sf, fs, fb = reverse(dir_new, qi, mat, sf, fs)
        z = z_of(vec5d(state.x[i, 0], state.x[i, 1], state.x[i, 2], state.x[i, 3], state.x[i, 4]), qi)
        codes, tg = stage_conditions(st, int(state.jammed[i]), sf, fs, fb, mat, state.C[i])
        cell = evaluate_zr(z, mat.B, mat.d)
        r, J = residuals_ext(cell, z, codes, tg, vec10p(), mat.B, mat.d)
        # (reverse() enters SF- / SF+, never SLACK: the guard above holds)
        kk = branch_slope(quantity(cell, Q_F).g, J, mat.B, mat.d)
    k[i] = kk
