"""What the patch coupling reads of a state after each trial, packed on the device (issue 15).

The coupling reads C, F (0 while slack), phi, W and the head gap, and stage, jammed and status, of every
group after each trial (and the runner the state vector x and s_AB of each committed state).  Read as the state's own arrays, that was the whole quantity table q (20 values a
cell) and five more arrays: ~190 MB a trial for a 10^6-cell patch, 5.5 s of its 8 increments' 19 s on one
H200 in 874 copies to pageable host memory, against 1.4 s of kernels.  Packed here into two small
row-major arrays (11 reals, 3 integers a cell), then copied once each into pinned host buffers
(:class:`knitsim.patch.coupling.WarpCellBackend`).  A pure copy: the values read are the state's, bit for
bit (F where the cell is slack: 0, as the coupling's law of a slack cell)."""
from __future__ import annotations

import warp as wp

from .cell_arrays import StateArrays

#: columns of the packed reals (the state vector x takes READ_X .. READ_X + 4) and integers
READ_C, READ_F, READ_PHI, READ_W, READ_GAP, READ_X, READ_S_AB = 0, 1, 2, 3, 4, 5, 10
READ_STAGE, READ_JAMMED, READ_STATUS = 0, 1, 2
N_READ_REALS, N_READ_INTS = 11, 3


@wp.kernel
def pack_state_read_kernel(src: StateArrays, q_f: int, q_phi: int, q_w: int, q_sab: int, slack: int,
                           reals: wp.array2d(dtype=wp.float64), ints: wp.array2d(dtype=wp.int32)):
    """``reals[i] = (C, F, phi, W, head gap, x[0..4], s_AB)``, ``ints[i] = (stage, jammed, status)`` of cell i;
    F = 0 where the stage is ``slack``."""
    i = wp.tid()
    stage = src.stage[i]
    f = src.q[i, q_f]
    if stage == slack:
        f = wp.float64(0.0)
    reals[i, 0] = src.C[i]
    reals[i, 1] = f
    reals[i, 2] = src.q[i, q_phi]
    reals[i, 3] = src.q[i, q_w]
    reals[i, 4] = src.gap[i]
    for j in range(5):
        reals[i, 5 + j] = src.x[i, j]
    reals[i, 10] = src.q[i, q_sab]
    ints[i, 0] = stage
    ints[i, 1] = src.jammed[i]
    ints[i, 2] = src.status[i]
