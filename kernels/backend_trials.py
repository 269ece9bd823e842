"""What the patch's cell backend keeps of each trial, on the device (issue 15, item 4).

After each trial step of a patch's cells :class:`knitsim.patch.coupling.WarpBackend` keeps, per cell,

- the slide onset the trial crossed (C, F of its last event where that is a slide and the trial ends sliding,
  not jammed: the kink of the cell's branch), from the step's event buffer (:func:`last_events_kernel`,
  :func:`trial_reads_kernel`);
- whether its next trial may start its Newton from this one (CellControl.warm: converged on the committed
  branch, or on the branch a reversal or reload at the increment's start enters, no other event, not slack);
- which of the trial's cells it left ok (:func:`good_trials_kernel`: the coupling keeps their points and
  tangents; the host no longer reads every cell's status after each trial);
- the trial's tangent dF/dC (the step's own slope, else the branch tangent kernel's) and which trial
  tangents an accepted trial makes the committed state's (:func:`trial_tangent_kernel`,
  :func:`accept_tangents_kernel`).

Twin and test oracle: the NumPy lines of ``WarpBackend.trial``, ``tangent`` and ``accept`` (the backend's host
mode, used with the NumPy coupling): ``tests/patch/test_device_coupling.py`` runs patches both ways.
"""
from __future__ import annotations

import warp as wp

from .cell_arrays import StateArrays

wp.set_module_options({"enable_backward": False})


@wp.kernel
def last_events_kernel(
    ev_cell: wp.array(dtype=wp.int32),
    ev_kind: wp.array(dtype=wp.int32),
    kind_reversal: int,
    kind_reload: int,
    last: wp.array(dtype=wp.int32),
    entered: wp.array(dtype=wp.int32),
    other: wp.array(dtype=wp.int32),
):
    """Of each cell (last, entered, other zeroed / -1 before): the index of its last event in the buffer (a
    cell's events are appended in the order they happen), whether it had a reversal or reload (events at the
    increment's start) and whether it had any other event."""
    e = wp.tid()
    c = ev_cell[e]
    wp.atomic_max(last, c, e)
    kind = ev_kind[e]
    if kind == kind_reversal or kind == kind_reload:
        wp.atomic_max(entered, c, 1)
    else:
        wp.atomic_max(other, c, 1)


@wp.kernel
def trial_reads_kernel(
    trial: StateArrays,
    committed: StateArrays,
    stepped: wp.array(dtype=wp.int32),
    last: wp.array(dtype=wp.int32),
    entered: wp.array(dtype=wp.int32),
    other: wp.array(dtype=wp.int32),
    ev_kind: wp.array(dtype=wp.int32),
    ev_C: wp.array(dtype=wp.float64),
    ev_F: wp.array(dtype=wp.float64),
    kind_slide: int,
    stage_slack: int,
    stage_s_load: int,
    stage_s_unload: int,
    status_ok: int,
    slide_C: wp.array(dtype=wp.float64),
    slide_F: wp.array(dtype=wp.float64),
    warm: wp.array(dtype=wp.int32),
    k1_ok: wp.array(dtype=wp.int32),
):
    """Cell i's slide onset (NaN: none), its warm-start flag (kept where not ``stepped``) and its trial
    tangent forgotten where stepped."""
    i = wp.tid()
    stage = trial.stage[i]
    jam = trial.jammed[i]
    sC = wp.float64(wp.nan)
    sF = wp.float64(wp.nan)
    j = last[i]
    if j >= 0 and ev_kind[j] == kind_slide and (stage == stage_s_load or stage == stage_s_unload) and jam == 0:
        sC = ev_C[j]
        sF = ev_F[j]
    slide_C[i] = sC
    slide_F[i] = sF
    if stepped[i] != 0:
        same = (trial.status[i] == status_ok and (stage == committed.stage[i] or entered[i] != 0)
                and jam == committed.jammed[i] and stage != stage_slack and other[i] == 0)
        if same:
            warm[i] = 1
        else:
            warm[i] = 0
        k1_ok[i] = 0


@wp.kernel
def good_trials_kernel(
    stepped: wp.array(dtype=wp.int32),
    status: wp.array(dtype=wp.int32),
    status_ok: int,
    use: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
):
    """The cells of the trial (``stepped``) that it left ok: ``use``, the good trials whose tangents and points the
    coupling keeps; count[0] counts them (zeroed before)."""
    i = wp.tid()
    if stepped[i] != 0 and status[i] == status_ok:
        use[i] = 1
        wp.atomic_add(count, 0, 1)
    else:
        use[i] = 0


@wp.kernel
def tangent_need_kernel(
    use: wp.array(dtype=wp.int32),
    slope: wp.array(dtype=wp.float64),
    status: wp.array(dtype=wp.int32),
    not_ok: int,
    masked_status: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
):
    """The cells whose trial tangent the step did not give (in ``use``, slope not finite) keep their status, the
    others are given ``not_ok`` (the tangent kernel then gives NaN there after reading only the parameters);
    count[0] counts the former (zeroed before)."""
    i = wp.tid()
    if use[i] != 0 and not wp.isfinite(slope[i]):
        masked_status[i] = status[i]
        wp.atomic_add(count, 0, 1)
    else:
        masked_status[i] = not_ok


@wp.kernel
def trial_tangent_kernel(
    use: wp.array(dtype=wp.int32),
    slope: wp.array(dtype=wp.float64),
    launched: wp.array(dtype=wp.float64),
    any_launched: int,
    kt: wp.array(dtype=wp.float64),
    k1: wp.array(dtype=wp.float64),
    k1_ok: wp.array(dtype=wp.int32),
):
    """kt = the step's slope where finite, else the tangent kernel's (``launched``), in ``use``; NaN elsewhere;
    kept as the trial tangent (k1, k1_ok) of the cells in ``use``."""
    i = wp.tid()
    k = wp.float64(wp.nan)
    if use[i] != 0:
        k = slope[i]
        if not wp.isfinite(k):
            if any_launched != 0:
                k = launched[i]
            else:
                k = wp.float64(wp.nan)
        k1[i] = k
        k1_ok[i] = 1
    kt[i] = k


@wp.kernel
def accept_tangents_kernel(
    mask: wp.array(dtype=wp.int32),
    k1: wp.array(dtype=wp.float64),
    k1_ok: wp.array(dtype=wp.int32),
    kr: wp.array(dtype=wp.float64),
    kr_ok: wp.array(dtype=wp.int32),
):
    """The trial tangents of the accepted cells become their results' (kr, kr_ok)."""
    i = wp.tid()
    if mask[i] != 0:
        kr[i] = k1[i]
        kr_ok[i] = k1_ok[i]
