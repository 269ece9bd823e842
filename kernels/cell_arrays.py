"""The arrays a cell step reads and writes, grouped as Warp structs (issue 15 item 3): the model
(per-cell parameters, shape ``(1 or N, ...)``, read as ``p[i % p.shape[0]]``), a state (per cell, shape
``(N, ...)``), the event append buffer and the recorded history rows.  One definition, shared by every
kernel-key instance of :mod:`knitsim.kernels.cell_step` (a struct type is its module's), so that a
host-side struct made once (:meth:`knitsim.cell.batch.CellModel.arrays` and the like) is passed to any of
them.  Field meanings and units: :mod:`knitsim.cell.batch`.  Also the one kernel that only moves state
rows (:func:`select_state_kernel`)."""
from __future__ import annotations

import warp as wp


@wp.struct
class ModelArrays:
    """Per-cell parameters (CellModel): lengths in mm, B in N mm^2, forces in N, angles in rad."""

    B: wp.array(dtype=wp.float64)
    d: wp.array(dtype=wp.float64)
    L: wp.array(dtype=wp.float64)
    W0: wp.array(dtype=wp.float64)
    C0: wp.array(dtype=wp.float64)
    m: wp.array(dtype=wp.float64)
    phi0: wp.array(dtype=wp.float64)
    sigma: wp.array(dtype=wp.float64)
    cap: wp.array(dtype=wp.float64)
    djam: wp.array(dtype=wp.float64)
    friction: wp.array(dtype=wp.int32)
    unloading: wp.array(dtype=wp.int32)
    reload: wp.array(dtype=wp.int32)
    criterion: wp.array(dtype=wp.int32)
    eff_mask: wp.array(dtype=wp.int32)
    eff_params: wp.array2d(dtype=wp.float64)


@wp.struct
class StateArrays:
    """The evolving state of every cell (CellBatchState)."""

    x: wp.array2d(dtype=wp.float64)
    q: wp.array2d(dtype=wp.float64)
    C: wp.array(dtype=wp.float64)
    stage: wp.array(dtype=wp.int32)
    jammed: wp.array(dtype=wp.int32)
    soft: wp.array(dtype=wp.int32)
    fsoft: wp.array(dtype=wp.float64)
    fsbc: wp.array(dtype=wp.float64)
    status: wp.array(dtype=wp.int32)
    direction: wp.array(dtype=wp.int32)
    gap: wp.array(dtype=wp.float64)
    eff: wp.array2d(dtype=wp.float64)


@wp.struct
class EventArrays:
    """The event append buffer: ``count[0]`` counts every event, stored or not (CellSolver.events)."""

    count: wp.array(dtype=wp.int32)
    cell: wp.array(dtype=wp.int32)
    incr: wp.array(dtype=wp.int32)
    kind: wp.array(dtype=wp.int32)
    C: wp.array(dtype=wp.float64)
    # the force per wale at the event (the state it was located at)
    F: wp.array(dtype=wp.float64)
    label_from: wp.array(dtype=wp.int32)
    label_to: wp.array(dtype=wp.int32)


@wp.struct
class HistoryArrays:
    """Recorded rows (ProgramHistory): ``q[k rows + row, i] = state q[i, codes[k]]`` (``rows`` =
    ``stage.shape[0]``), the effects' state in ``eff`` likewise; ``eff`` of shape ``[0, N]`` records none.
    Two-dimensional, quantity-major: a Warp array's strides are 32-bit byte counts, and a
    [quantities, rows, N] float64 array's first stride, 8 rows N bytes, passes 2^31 at 310 rows of
    10^6 cells (the strides wrap and the kernel writes out of bounds); here it is 8 N bytes."""

    codes: wp.array(dtype=wp.int32)
    q: wp.array2d(dtype=wp.float64)
    stage: wp.array2d(dtype=wp.int32)
    jammed: wp.array2d(dtype=wp.int32)
    status: wp.array2d(dtype=wp.int32)
    gap: wp.array2d(dtype=wp.float64)
    eff: wp.array2d(dtype=wp.float64)


@wp.struct
class SuspendedArrays:
    """Cells suspended inside an increment's sub-step walk by the sliced full step (issue 15 item 2:
    the sub-steps of an increment spread over launches, the cells still walking compacted between
    them).  Per cell, what the walk carries from one sub-step to the next, stored exactly (fp64 as
    fp64, the Newton variables z, not x), so that a resumed walk is bit for bit the one-launch walk.

    ``active[i]``: 1 while cell i is suspended.  ``real[i]``: C, the sub-step, the frozen soft-stage
    force, fsbc.  ``ints[i]``: stage, jammed, soft, status, failed trials in a row, events located,
    sub-steps taken, events counted, events already written to the event buffer."""

    active: wp.array(dtype=wp.int32)
    z: wp.array2d(dtype=wp.float64)
    q: wp.array2d(dtype=wp.float64)
    real: wp.array2d(dtype=wp.float64)
    ints: wp.array2d(dtype=wp.int32)


#: widths of SuspendedArrays.real and .ints
SUSPENDED_REALS = 4
SUSPENDED_INTS = 9


@wp.kernel
def select_state_kernel(mask: wp.array(dtype=wp.int32), src: StateArrays, dst: StateArrays):
    """``dst[i] = src[i]`` where ``mask[i]``, for every field of a state (the patch coupling keeps a
    column's trial states as its result this way)."""
    i = wp.tid()
    if mask[i] != 0:
        for k in range(src.x.shape[1]):
            dst.x[i, k] = src.x[i, k]
        for k in range(src.q.shape[1]):
            dst.q[i, k] = src.q[i, k]
        dst.C[i] = src.C[i]
        dst.stage[i] = src.stage[i]
        dst.jammed[i] = src.jammed[i]
        dst.soft[i] = src.soft[i]
        dst.fsoft[i] = src.fsoft[i]
        dst.fsbc[i] = src.fsbc[i]
        dst.status[i] = src.status[i]
        dst.direction[i] = src.direction[i]
        dst.gap[i] = src.gap[i]
        for k in range(src.eff.shape[1]):
            dst.eff[i, k] = src.eff[i, k]
