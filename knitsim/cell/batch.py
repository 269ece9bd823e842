"""Batched load cycle of N quarter-stitch cells on a Warp device (Dusserre 2015 Table 4).

Model / State / Control, as ``warp.sim``:

- :class:`CellModel`: immutable struct-of-arrays of per-cell parameters, each
  of shape ``(1 or N,)`` and read in the kernels as ``p[i % p.shape[0]]``;
- :class:`CellBatchState`: the evolving state of every cell (made by
  :meth:`CellModel.state`, initialised to Table 4's initial state);
- :class:`CellControl`: the imposed strain of the course length and the load
  direction of this increment (shape ``(1 or N,)``, made by :meth:`CellModel.control`);
- :class:`CellSolver`: ``step(state_in, state_out, control)`` advances every
  cell by one increment in one kernel launch (:mod:`knitsim.kernels.cell_step`).

Semantics are those of the NumPy reference :class:`knitsim.cell.cycle.CellCycle`
(its oracle, :func:`knitsim.cell.cycle.run_cells_reference`): reversal, trial
solve, events located inside the increment, halving, status flags.  Two
methods differ on purpose: events are located by swapping the driving
condition C for the event condition (the reference runs a root search on C),
and Dahl friction is a residual of the per-cell Newton (the reference nests a
root search on the slip).

:func:`run_batch` runs a whole :class:`~knitsim.cell.load_program.LoadProgram`
and returns a :class:`~knitsim.cell.history.BatchHistory`; history rows are
written on the device and copied to the host once at the end.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.errors import KnitsimInputError

from .effects import EFFECT_STATE, PARAM_COLUMNS
from .history import (HISTORY_QUANTITIES, STATUS_NAMES, STATUS_NO_REST_STATE, STATUS_OK, BatchHistory,
                      head_gap_values)
from .inverse import DEFAULT_STARTS
from .load_program import LoadProgram
from .material import CellParams
from .quantities import CODE, QUANTITY_NAMES
from .stages import LABEL_CODES, MAX_HALVINGS, STICK_CLOSURES

_LABEL_NAMES = {v: k for k, v in LABEL_CODES.items()}


def _k():
    # imported lazily: ``import knitsim.cell`` must not need Warp initialised
    from knitsim.kernels import cell_step

    return cell_step


_FLOAT_FIELDS = ("B", "d", "L", "W0", "C0", "m", "phi0", "sigma", "cap", "djam")
_INT_FIELDS = ("friction", "unloading", "reload", "criterion")


class CellModel:
    """Per-cell parameters as device arrays (immutable after construction).

    Attributes (wp.array, shape ``[1 or cell_count]``)
    ---------------------------------------------------
    B : float64
        Bending stiffness [N mm^2].
    d : float64
        Yarn diameter [mm].
    L, W0, C0 : float64
        Stitch length, wale width and course length at rest [mm].
    m : float64
        Friction ratio tan(phimax) [-].
    phi0 : float64
        Initial friction angle [rad].
    sigma : float64
        Dahl stiffness [1/mm] (used where friction is Dahl).
    cap : float64
        Force per wale at which a cell stops [N].
    djam : float64
        In-plane yarn width that jams loops [mm] (``CellParams.d_jam``); jammed at W = 4 djam.
    friction : int32
        0 Coulomb (Table 4 switching), 1 Dahl.
    unloading : int32
        0 ``"dusserre"``, 1 ``"hong_constant_t"``.
    reload : int32
        0 ``"freeze_rn"``, 1 ``"mirror_unloading"``.
    criterion : int32
        Jamming criterion: 0 ``"w_4d"`` (W = 4 djam), 1 ``"head_gap"`` (neighbouring heads at
        centreline distance djam, :mod:`knitsim.kernels.head_gap`).
    effect_mask : int32
        Bits of the model extensions that are on (:data:`knitsim.cell.effects.EFFECT_BITS`).
    effect_params : float64, shape ``[1 or cell_count, len(PARAM_COLUMNS)]``
        Their parameters (:data:`knitsim.cell.effects.PARAM_COLUMNS`).
    cell_count : int
    params : list of CellParams
        The validated parameters (one per cell).
    """

    def __init__(self, arrays: dict, cell_count: int, params: list, device: str):
        self.__dict__["_frozen"] = False
        for name, arr in arrays.items():
            setattr(self, name, arr)
        self.cell_count = int(cell_count)
        self.params = list(params)
        self.device = device
        self.__dict__["_frozen"] = True

    def __setattr__(self, name, value):
        if self.__dict__.get("_frozen"):
            raise AttributeError(f"CellModel is immutable (tried to set {name!r})")
        self.__dict__[name] = value

    @classmethod
    def from_params(cls, params: Sequence[CellParams], device: str = "cpu") -> "CellModel":
        """Build the model of ``len(params)`` cells (each validated; errors name the cell)."""
        warp_runtime.init()
        device = warp_runtime.resolve_device(device)
        if isinstance(params, CellParams):
            params = [params]
        params = list(params)
        if not params:
            raise KnitsimInputError("cells: at least one cell is needed, got an empty list")
        checked = []
        for i, p in enumerate(params):
            if not isinstance(p, CellParams):
                raise KnitsimInputError(f"cells[{i}] = {p!r}: expected a CellParams")
            p = p.validated(where=f"cells[{i}]")
            if p.friction == "dahl" and p.m <= 0:
                raise KnitsimInputError(f"cells[{i}].m = {p.m!r}: Dahl friction needs m > 0 (saturation tan(phi) = m)")
            checked.append(p)
        cols = {
            "B": [p.B for p in checked], "d": [p.d for p in checked], "L": [p.L for p in checked],
            "W0": [p.W0 for p in checked], "C0": [p.C0 for p in checked], "m": [p.m for p in checked],
            "phi0": [p.phi0 for p in checked], "sigma": [p.dahl_sigma for p in checked],
            "cap": [p.force_cap_N for p in checked],
            "djam": [p.d_jam for p in checked],
            "friction": [int(p.friction == "dahl") for p in checked],
            "unloading": [int(p.unloading_rule == "hong_constant_t") for p in checked],
            "reload": [int(p.reload_rule == "mirror_unloading") for p in checked],
            "criterion": [int(p.jamming_criterion == "head_gap") for p in checked],
        }
        cols["effect_mask"] = [p.effects.mask for p in checked]
        arrays = {}
        for name, vals in cols.items():
            a = np.asarray(vals, dtype=np.float64 if name in _FLOAT_FIELDS else np.int32)
            if np.all(a == a[0]):
                a = a[:1]  # broadcast (1 or N): a uniform parameter costs one value
            arrays[name] = wp.array(a, dtype=wp.float64 if name in _FLOAT_FIELDS else wp.int32, device=device)
        rows = np.stack([p.effects.row() for p in checked])
        if np.all(rows == rows[:1]):
            rows = rows[:1]
        arrays["effect_params"] = wp.array(rows, dtype=wp.float64, device=device)
        return cls(arrays, len(checked), checked, device)

    def _arrays(self) -> list:
        return [getattr(self, n) for n in _FLOAT_FIELDS + _INT_FIELDS]

    def _effect_arrays(self) -> list:
        return [self.effect_mask, self.effect_params]

    def nbytes(self) -> int:
        """Device bytes of the parameter arrays."""
        return int(sum(a.capacity for a in self._arrays() + self._effect_arrays()))

    def state(self) -> "CellBatchState":
        """A state initialised to Table 4's initial state (C0, W0, L, phi0), solved on the device."""
        st = CellBatchState.empty(self.cell_count, self.device)
        starts = wp.array(np.asarray(DEFAULT_STARTS, dtype=np.float64), dtype=wp.float64, device=self.device)
        wp.launch(_k().init_kernel, dim=self.cell_count, inputs=self._arrays() + [starts],
                  outputs=st._arrays(), device=self.device)
        wp.launch(_k().init_effects_kernel, dim=self.cell_count, inputs=[self.B, self.d, self.L, self.m, st.q],
                  outputs=[st.eff], device=self.device)
        # no admissible rest state (knitsim.cell.domain.rest_state_problem): none found, or a contact
        # force R < 0 (the unilateral contact at B would pull): flagged before any increment
        status = st.status.numpy()
        R = st.q.numpy()[:, CODE["R"]]
        bad = (status != STATUS_OK) | ~(R >= 0.0)
        if np.any(bad):
            status[bad] = STATUS_NO_REST_STATE
            st.status.assign(wp.array(status, dtype=wp.int32, device=self.device))
        return st

    def control(self) -> "CellControl":
        """A control (strain 0, loading, no rate) broadcast to every cell."""
        return CellControl(wp.zeros(1, dtype=wp.float64, device=self.device),
                           wp.ones(1, dtype=wp.int32, device=self.device),
                           wp.zeros(1, dtype=wp.float64, device=self.device))


@dataclass
class CellBatchState:
    """Evolving state of N cells (device arrays, leading axis N).

    Attributes
    ----------
    x : float64 [N, 5]
        (alpha, beta, gamma, phi, P) [rad, N].
    q : float64 [N, n_quantities]
        Every quantity of :data:`~knitsim.cell.quantities.QUANTITY_NAMES` at x.
    C : float64 [N]
        Course length of the cell [mm] (stays at C_slack while slack).
    stage, jammed : int32 [N]
        :class:`~knitsim.cell.stages.Stage` code and jammed flag.
    soft : int32 [N]
        Quantity code of the soft condition (Rn, beta or T).
    frozen_soft, frozen_sbc : float64 [N]
        Values frozen at the entry of the stage.
    status : int32 [N]
        :data:`~knitsim.cell.history.STATUS_NAMES` code.
    direction : int32 [N]
        Direction of the last increment (+1 loading, -1 unloading).
    head_gap : float64 [N]
        Centreline distance between the heads of neighbouring loops of a course [mm]
        (:mod:`knitsim.cell.head_gap`), of every accepted state: below the in-plane width
        the loops interpenetrate.
    eff : float64 [N, len(EFFECT_STATE)]
        Effective parameters of the last increment and the effects' own state
        (:data:`knitsim.cell.effects.EFFECT_STATE`); the given ones where no effect is on.
    """

    x: wp.array
    q: wp.array
    C: wp.array
    stage: wp.array
    jammed: wp.array
    soft: wp.array
    frozen_soft: wp.array
    frozen_sbc: wp.array
    status: wp.array
    direction: wp.array
    head_gap: wp.array
    eff: wp.array | None = None

    def __post_init__(self):
        if self.eff is None:
            self.eff = wp.zeros((int(self.C.shape[0]), len(EFFECT_STATE)), dtype=wp.float64, device=self.C.device)

    @classmethod
    def empty(cls, n: int, device: str) -> "CellBatchState":
        f, i = wp.float64, wp.int32
        return cls(wp.zeros((n, 5), dtype=f, device=device), wp.zeros((n, len(QUANTITY_NAMES)), dtype=f, device=device),
                   wp.zeros(n, dtype=f, device=device), wp.zeros(n, dtype=i, device=device),
                   wp.zeros(n, dtype=i, device=device), wp.zeros(n, dtype=i, device=device),
                   wp.zeros(n, dtype=f, device=device), wp.zeros(n, dtype=f, device=device),
                   wp.zeros(n, dtype=i, device=device), wp.zeros(n, dtype=i, device=device),
                   wp.zeros(n, dtype=f, device=device))

    def _arrays(self) -> list:
        return [self.x, self.q, self.C, self.stage, self.jammed, self.soft, self.frozen_soft,
                self.frozen_sbc, self.status, self.direction, self.head_gap]

    @property
    def cell_count(self) -> int:
        return int(self.C.shape[0])

    def nbytes(self) -> int:
        return int(sum(a.capacity for a in self._arrays() + [self.eff]))

    def values(self) -> dict[str, np.ndarray]:
        """Host copies of every quantity by name, shape [N]."""
        q = self.q.numpy()
        return {name: q[:, k].copy() for k, name in enumerate(QUANTITY_NAMES)}


@dataclass
class CellControl:
    """Imposed load of one increment.

    Attributes
    ----------
    strain : float64 [1 or N]
        Strain of the course length; each cell is driven to ``C = C0 (1 + strain)``.
    direction : int32 [1 or N]
        +1 loading, -1 unloading (a change triggers the Table 4 reversal).
    rate : float64 [1 or N]
        Test (crosshead) rate of the increment [mm/s], read by ``velocity_friction``
        only; 0 means not given (no velocity effect).
    """

    strain: wp.array
    direction: wp.array
    rate: wp.array | None = None

    def __post_init__(self):
        if self.rate is None:
            self.rate = wp.zeros(1, dtype=wp.float64, device=self.strain.device)

    def set(self, strain: float, direction: int, rate: float = 0.0) -> None:
        """Impose one strain, direction (and test rate) on every cell (device fill, no host sync)."""
        if int(direction) not in (1, -1):
            raise KnitsimInputError(f"control.direction = {direction!r}: expected +1 or -1")
        self.strain.fill_(float(strain))
        self.direction.fill_(int(direction))
        self.rate.fill_(float(rate))


class CellSolver:
    """Advance N cells by one load increment (one kernel launch).

    Parameters
    ----------
    model : CellModel
    max_halvings : int
        Most halvings in a row of a failed sub-step (default
        :data:`~knitsim.cell.stages.MAX_HALVINGS`); halving also stops at
        :data:`~knitsim.cell.stages.SUBSTEP_FLOOR` C0.  Then the cell is flagged
        ``no_convergence`` (or ``event_not_located``).
    event_capacity : int, optional
        Events kept on the device (default 64 per cell); more are counted and dropped.
    stick_closure : str
        ``"release_beta"`` (default) or ``"table4"``: see :mod:`knitsim.cell.stages`.
    """

    def __init__(self, model: CellModel, max_halvings: int = MAX_HALVINGS, event_capacity: int | None = None,
                 stick_closure: str = "release_beta"):
        if stick_closure not in STICK_CLOSURES:
            raise KnitsimInputError(f"stick_closure = {stick_closure!r}: expected one of {', '.join(STICK_CLOSURES)}")
        self.stick_closure = stick_closure
        if not (isinstance(max_halvings, (int, np.integer)) and 0 <= max_halvings <= 60):
            raise KnitsimInputError(f"max_halvings = {max_halvings!r}: expected a whole number in 0..60")
        self.model = model
        self.max_halvings = int(max_halvings)
        cap = 64 * model.cell_count + 64 if event_capacity is None else int(event_capacity)
        dev = model.device
        self._ev_count = wp.zeros(1, dtype=wp.int32, device=dev)
        self._ev = [wp.zeros(max(cap, 1), dtype=t, device=dev)
                    for t in (wp.int32, wp.int32, wp.int32, wp.float64, wp.int32, wp.int32)]

    def step(self, state_in: CellBatchState, state_out: CellBatchState, control: CellControl,
             increment: int = 0) -> None:
        """One increment for all cells; ``increment`` labels the events it records."""
        n = self.model.cell_count
        if n == 0:
            return
        wp.launch(_k().step_kernel, dim=n,
                  inputs=self.model._arrays() + self.model._effect_arrays()
                  + [self.max_halvings, int(self.stick_closure == "release_beta")]
                  + state_in._arrays() + [state_in.eff]
                  + [control.strain, control.direction, control.rate, int(increment)],
                  outputs=state_out._arrays() + [state_out.eff] + [self._ev_count] + self._ev,
                  device=self.model.device)

    def events(self) -> list[dict]:
        """Events recorded so far (host copy), ordered by cell, then as they happened."""
        k = _k()
        total = int(self._ev_count.numpy()[0])
        n = min(total, self._ev[0].shape[0])
        if total > n:
            raise RuntimeError(f"event buffer overflow: {total} events, capacity {n}; pass event_capacity=")
        cell, incr, kind, C, lf, lt = (a.numpy()[:n] for a in self._ev)
        order = np.lexsort((np.arange(n), cell))
        out = []
        for j in order:
            e = {"cell": int(cell[j]), "increment": int(incr[j]), "kind": k.EVENT_NAMES[int(kind[j])], "C": float(C[j])}
            if lf[j] >= 0:
                e["from"] = _LABEL_NAMES[int(lf[j])]
                e["to"] = _LABEL_NAMES[int(lt[j])]
            out.append(e)
        return out


def run_batch(params, program: LoadProgram, device: str = "cpu",
              progress: Callable[[int, int], None] | None = None, max_halvings: int = MAX_HALVINGS,
              stick_closure: str = "release_beta") -> BatchHistory:
    """Run N cells through a strain program on a Warp device.

    Parameters
    ----------
    params : list of CellParams, or CellModel
        The cells (each validated before any solve).
    program : LoadProgram
        Imposed strains of the course length, ``C = C0 (1 + strain)``.
    device : str
        Warp device (``"cpu"``, ``"cuda"``, ``"cuda:N"``, ``"auto"``); ignored
        when ``params`` is a model.
    progress : callable, optional
        ``progress(done, n)`` as increments finish (the program runs in chunks of 25 then).
    max_halvings, stick_closure
        See :class:`CellSolver`.

    Returns
    -------
    BatchHistory
        One row per increment, one column per cell; events with their ``cell``;
        a ``flag`` event at the first increment where a cell's status is not ok.
    """
    model = params if isinstance(params, CellModel) else CellModel.from_params(params, device)
    if not isinstance(program, LoadProgram) or len(program) == 0:
        raise KnitsimInputError(f"program = {program!r}: expected a non-empty LoadProgram")
    dev = model.device
    n, nc = len(program), model.cell_count
    solver = CellSolver(model, max_halvings, stick_closure=stick_closure)
    s0 = model.state()
    s0_status0 = s0.status.numpy().copy()
    q0 = s0.q.numpy()
    rest = {name: q0[:, CODE[name]].copy() for name in HISTORY_QUANTITIES}
    rest.update(stage=s0.stage.numpy().copy(), jammed=s0.jammed.numpy().copy())
    codes = wp.array(np.asarray([CODE[k] for k in HISTORY_QUANTITIES], np.int32), dtype=wp.int32, device=dev)
    hq = wp.zeros((len(HISTORY_QUANTITIES), n, nc), dtype=wp.float64, device=dev)
    hs, hj, hst = (wp.zeros((n, nc), dtype=wp.int32, device=dev) for _ in range(3))
    hg = wp.zeros((n, nc), dtype=wp.float64, device=dev)
    k = _k()
    with_effects = any(p.effects.on for p in model.params)
    he = wp.zeros((len(EFFECT_STATE) if with_effects else 0, n, nc), dtype=wp.float64, device=dev)
    rate = program.rate
    prog = [wp.array(np.asarray(program.strain, np.float64), dtype=wp.float64, device=dev),
            wp.array(np.asarray(program.direction, np.int32), dtype=wp.int32, device=dev),
            wp.array(np.zeros(1) if rate is None else np.asarray(rate, np.float64), dtype=wp.float64, device=dev)]
    # the whole program in one launch (chunks only to report progress): the increments loop on the device
    chunk = n if progress is None else max(1, min(n, 25))
    for k0 in range(0, n, chunk):
        k1 = min(n, k0 + chunk)
        wp.launch(k.program_kernel, dim=nc,
                  inputs=model._arrays() + model._effect_arrays()
                  + [solver.max_halvings, int(solver.stick_closure == "release_beta")]
                  + s0._arrays() + [s0.eff] + prog + [k0, k1] + [solver._ev_count] + solver._ev
                  + [codes, hq, hs, hj, hst, hg, he], device=dev)
        if progress is not None:
            progress(k1, n)
    hqn = hq.numpy()
    values = {name: hqn[j] for j, name in enumerate(HISTORY_QUANTITIES)}
    values.update(head_gap_values(hg.numpy(), [p.d_jam for p in model.params]))
    if with_effects:
        hen = he.numpy()
        values.update({name: hen[j] for j, name in enumerate(EFFECT_STATE)})
    status = hst.numpy()
    # a cell without a rest state has no state at all: NaN beside its status (never a made-up number)
    norest = np.asarray(s0_status0 == STATUS_NO_REST_STATE)
    if np.any(norest):
        for v in values.values():
            v[:, norest] = np.nan
        for name in HISTORY_QUANTITIES:
            rest[name][norest] = np.nan
    events = solver.events()
    for c in np.nonzero(np.any(status != STATUS_OK, axis=0))[0]:
        i0 = int(np.argmax(status[:, c] != STATUS_OK))
        events.append({"cell": int(c), "increment": i0, "kind": "flag",
                       "reason": STATUS_NAMES[int(status[i0, c])], "status": STATUS_NAMES[int(status[i0, c])]})
    events.sort(key=lambda e: (e["cell"], e["increment"], e["kind"] == "flag"))
    return BatchHistory(np.asarray(program.strain), np.asarray(program.cycle), np.asarray(program.direction),
                        hs.numpy(), hj.numpy(), status, values, events, list(model.params), rest)


def memory_per_cell(model: CellModel, state: CellBatchState, n_increments: int) -> dict[str, float]:
    """Device bytes per cell: model, two states (in/out), history of ``n_increments`` rows."""
    nc = model.cell_count
    hist = n_increments * (len(HISTORY_QUANTITIES) * 8 + 3 * 4)
    return {"model": model.nbytes() / nc, "states": 2 * state.nbytes() / nc, "history": float(hist),
            "total": model.nbytes() / nc + 2 * state.nbytes() / nc + hist}
