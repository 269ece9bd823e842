"""What the patch coupling reads of a state, packed on the device (issue 15).

The coupling reads C, F (0 while slack), phi, W and the head gap, and stage, jammed and status, of every
group of a state (and the runner the state vector x and s_AB of each committed state).  Read as the state's
own arrays, that was the whole quantity table q (20 values a cell) and five more arrays: ~190 MB a trial for
a 10^6-cell patch, 5.5 s of its 8 increments' 19 s on one H200 in 874 copies to pageable host memory, against
1.4 s of kernels.  Packed here into two small field-major arrays (6 reals, 3 integers a cell: one row per
quantity, so that each quantity is contiguous on the host and its threads' reads on the device coalesce; the
state vector x is the state's own [n, 5] array).  A committed state's packed read is copied into pinned host
buffers (:class:`knitsim.patch.coupling.WarpBackend`); a trial's stays on the device, where the coupling's
kernels judge and book it (:mod:`knitsim.kernels.column_trials`).  Cell-major, the host's copies of the
committed quantities out of the pinned buffer (one cache line per value) took ~60 ms of each increment of a
10^6-cell patch on the H200 host.  A pure copy: the values read are the state's, bit for bit (F where the
cell is slack: 0, as the coupling's law of a slack cell)."""
from __future__ import annotations

import warp as wp

from .cell_arrays import StateArrays

#: rows of the packed reals and integers
READ_C, READ_F, READ_PHI, READ_W, READ_GAP, READ_S_AB = 0, 1, 2, 3, 4, 5
READ_STAGE, READ_JAMMED, READ_STATUS = 0, 1, 2
N_READ_REALS, N_READ_INTS = 6, 3


@wp.kernel
def pack_state_read_kernel(src: StateArrays, q_f: int, q_phi: int, q_w: int, q_sab: int, slack: int,
                           reals: wp.array2d(dtype=wp.float64), ints: wp.array2d(dtype=wp.int32)):
    """``reals[:, i] = (C, F, phi, W, head gap, s_AB)``, ``ints[:, i] = (stage, jammed, status)`` of cell i;
    F = 0 where the stage is ``slack``."""
    i = wp.tid()
    stage = src.stage[i]
    f = src.q[i, q_f]
    if stage == slack:
        f = wp.float64(0.0)
    reals[READ_C, i] = src.C[i]
    reals[READ_F, i] = f
    reals[READ_PHI, i] = src.q[i, q_phi]
    reals[READ_W, i] = src.q[i, q_w]
    reals[READ_GAP, i] = src.gap[i]
    reals[READ_S_AB, i] = src.q[i, q_sab]
    ints[READ_STAGE, i] = stage
    ints[READ_JAMMED, i] = src.jammed[i]
    ints[READ_STATUS, i] = src.status[i]
