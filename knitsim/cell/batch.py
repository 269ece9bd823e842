"""Batched load cycle of N quarter-stitch cells on a Warp device (Dusserre 2015 Table 4).

Model / State / Control, as ``warp.sim``:

- :class:`CellModel`: immutable struct-of-arrays of per-cell parameters, each
  of shape ``(1 or N,)`` and read in the kernels as ``p[i % p.shape[0]]``;
- :class:`CellBatchState`: the evolving state of every cell (made by
  :meth:`CellModel.state`, initialised to Table 4's initial state);
- :class:`CellControl`: the imposed strain of the course length and the load
  direction of this increment (shape ``(1 or N,)``, made by :meth:`CellModel.control`);
- :class:`CellSolver`: ``step(state_in, state_out, control)`` advances every
  cell by one increment (:mod:`knitsim.kernels.cell_step`), one kernel launch per
  kernel key present (friction law, effects, jamming criterion:
  :mod:`knitsim.kernels.specialise`); ``run_program`` runs a range of increments
  of a load program with no host synchronisation, recording every ``stride``-th
  row into preallocated arrays (:class:`ProgramHistory`); on a GPU it runs each
  increment in two passes (``compact``): the regular increments of every cell
  (one trial, no event: a small kernel whose warps do one kind of work), then the
  full step on the few cells the first pass listed, in slices of a few sub-steps
  (``slices``) with the cells still walking compacted between the launches.

:meth:`CellModel.from_arrays` builds the model of N cells from per-cell arrays
(vectorised validation, no Python loop over the cells).

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

from .effects import EFFECT_STATE, NO_EFFECTS, PARAM_COLUMNS, EffectSet, effect_set_codes
from .history import (HISTORY_QUANTITIES, STATUS_EVENT_NOT_LOCATED, STATUS_FORCE_CAP, STATUS_NAMES,
                      STATUS_NO_CONVERGENCE, STATUS_NO_REST_STATE, STATUS_OK, BatchHistory, head_gap_values,
                      rest_at_cap_reason, solver_stop_reason)
from .inverse import DEFAULT_STARTS
from .load_program import LoadProgram
from .material import CellParams, default_force_cap_N
from .quantities import CODE, QUANTITY_NAMES
from .stages import (
    DAHL_SIGMA_MAX, DAHL_SIGMA_TOO_STIFF, FRICTION_MODELS, JAMMING_CRITERIA, LABEL_CODES, MAX_HALVINGS, RELOAD_RULES,
    M_MAX, M_TOO_LARGE, STICK_CLOSURES, UNLOADING_RULES,
    stage_labels,
)

_LABEL_NAMES = {v: k for k, v in LABEL_CODES.items()}


#: the fields of the kernels' structs (knitsim.kernels.cell_arrays), in the order of the host lists
_MODEL_STRUCT_FIELDS = ("B", "d", "L", "W0", "C0", "m", "phi0", "sigma", "cap", "djam", "friction", "unloading",
                        "reload", "criterion", "eff_mask", "eff_params")
_STATE_STRUCT_FIELDS = ("x", "q", "C", "stage", "jammed", "soft", "fsoft", "fsbc", "status", "direction", "gap", "eff")


def _fill(struct, fields: Sequence[str], arrays: list):
    """Set a Warp struct's array fields from a list (same order)."""
    assert len(fields) == len(arrays)
    for name, a in zip(fields, arrays):
        setattr(struct, name, a)
    return struct


def _compact(a: np.ndarray) -> np.ndarray:
    """A per-cell column as stored: one value when every cell has the same (broadcast 1 or N)."""
    a = np.atleast_1d(a)
    return a[:1] if a.size and np.all(a == a[0]) else a


def _device_arrays(cols: dict, rows: np.ndarray, device: str) -> dict:
    """The model's device arrays from host columns (each compacted to one value when uniform)."""
    arrays = {}
    for name, vals in cols.items():
        dt = np.float64 if name in _FLOAT_FIELDS else np.int32
        a = _compact(np.asarray(vals, dtype=dt))
        arrays[name] = wp.array(a, dtype=wp.float64 if name in _FLOAT_FIELDS else wp.int32, device=device)
    if np.all(rows == rows[:1]):
        rows = rows[:1]
    arrays["effect_params"] = wp.array(np.ascontiguousarray(rows), dtype=wp.float64, device=device)
    return arrays


def _k():
    # imported lazily: ``import knitsim.cell`` must not need Warp initialised
    from knitsim.kernels import cell_step

    return cell_step


def _kernel_module(key):
    """The cell_step instance compiled for a kernel key (None: the generic one)."""
    from knitsim.kernels.specialise import cell_step_module

    return cell_step_module(key)


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

    def __init__(self, arrays: dict, cell_count: int, params: list | None, device: str,
                 host: dict | None = None):
        self.__dict__["_frozen"] = False
        for name, arr in arrays.items():
            setattr(self, name, arr)
        self.cell_count = int(cell_count)
        self._params = None if params is None else list(params)
        self._host = host
        self.device = device
        self.__dict__["_frozen"] = True

    def __setattr__(self, name, value):
        if self.__dict__.get("_frozen"):
            raise AttributeError(f"CellModel is immutable (tried to set {name!r})")
        self.__dict__[name] = value

    @property
    def params(self) -> list:
        """The validated parameters, one :class:`CellParams` per cell (built on first use for a model
        made by :meth:`from_arrays`: a million cells take seconds here, not in the build)."""
        if self._params is None:
            h, n = self._host, self.cell_count
            col = {k: np.broadcast_to(v, (n,)) for k, v in h.items() if k != "effects"}
            names = {"friction": FRICTION_MODELS, "unloading": UNLOADING_RULES, "reload": ("freeze_rn", "mirror_unloading"),
                     "criterion": JAMMING_CRITERIA}
            eff = h["effects"]
            per_cell = isinstance(eff, np.ndarray)
            self.__dict__["_params"] = [
                CellParams(B=float(col["B"][i]), d=float(col["d"][i]), L=float(col["L"][i]), W0=float(col["W0"][i]),
                           C0=float(col["C0"][i]), m=float(col["m"][i]), phi0=float(col["phi0"][i]),
                           friction=names["friction"][col["friction"][i]], dahl_sigma=float(col["sigma"][i]),
                           unloading_rule=names["unloading"][col["unloading"][i]],
                           reload_rule=names["reload"][col["reload"][i]],
                           jamming_criterion=names["criterion"][col["criterion"][i]],
                           force_cap_N=float(col["cap"][i]),
                           in_plane_width=None if col["djam"][i] == col["d"][i] else float(col["djam"][i]),
                           effects=eff[i] if per_cell else eff)
                for i in range(n)]
        return self._params

    @property
    def d_jam(self) -> np.ndarray:
        """In-plane jamming width of every cell [mm], shape [cell_count] (host copy)."""
        if self._host is not None:
            return np.broadcast_to(self._host["djam"], (self.cell_count,)).astype(float)
        return np.array([p.d_jam for p in self._params])

    @property
    def has_effects(self) -> bool:
        """Whether any cell has a model extension on."""
        return bool(np.any(self._host["effect_mask"] != 0))

    def kernel_groups(self, specialise: bool = True) -> list:
        """The cells split by kernel key (:func:`knitsim.kernels.specialise.group_cells`): a list of
        (cell_step module, device index array); one group of every cell (empty index) when all share
        a key, or with ``specialise=False`` (the generic kernel, every law chosen per cell)."""
        cache = self.__dict__.setdefault("_groups", {})
        if specialise not in cache:
            if not specialise:
                cache[specialise] = [(_kernel_module(None), wp.zeros(0, dtype=wp.int32, device=self.device))]
            else:
                from knitsim.kernels.specialise import group_cells

                n, h = self.cell_count, self._host
                col = lambda k: np.broadcast_to(h[k], (n,))  # noqa: E731
                groups = group_cells(col("friction") == 1, col("effect_mask") != 0, col("criterion") == 1)
                cache[specialise] = [
                    (_kernel_module(key), wp.zeros(0, dtype=wp.int32, device=self.device) if len(groups) == 1
                     else wp.array(idx, dtype=wp.int32, device=self.device)) for key, idx in groups]
                # a cold cache compiles the groups' modules together rather than one per first launch
                warp_runtime.preload([m for m, _ in cache[specialise]], self.device)
        return cache[specialise]

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
            "cap": [p.cap_N for p in checked],
            "djam": [p.d_jam for p in checked],
            "friction": [int(p.friction == "dahl") for p in checked],
            "unloading": [int(p.unloading_rule == "hong_constant_t") for p in checked],
            "reload": [int(p.reload_rule == "mirror_unloading") for p in checked],
            "criterion": [int(p.jamming_criterion == "head_gap") for p in checked],
        }
        cols["effect_mask"] = [p.effects.mask for p in checked]
        rows = np.stack([p.effects.row() for p in checked])
        host = {k: _compact(np.asarray(v)) for k, v in cols.items()}
        return cls(_device_arrays(cols, rows, device), len(checked), checked, device, host)

    @classmethod
    def from_arrays(cls, B, d, L, W0, C0, m=0.0, phi0=0.0, *, friction="coulomb", dahl_sigma=0.0,
                    unloading_rule="dusserre", reload_rule="mirror_unloading", jamming_criterion="w_4d",
                    force_cap_N=None, in_plane_width=None, effects=None, device: str = "cpu",
                    where=None) -> "CellModel":
        """Build the model of N cells from per-cell arrays, without a Python loop over the cells.

        Each argument is a scalar (every cell) or an array of shape [N] (the fields of
        :class:`CellParams`, same units; the string fields may be arrays of names; NaN in an
        ``in_plane_width`` array: none, the cell jams at d).  ``effects`` is one
        :class:`~knitsim.cell.effects.EffectSet` for every cell (None: none) or an object array of
        them, shape [N] (a few distinct sets: they are told apart once, not per cell).  Every field is
        validated as :meth:`CellParams.validated` does, vectorised; the error names the first bad
        cell and field (``cells[i].m = -0.1: ...``; ``where(i)`` names cell i instead of
        ``cells[i]``).  ``params`` is built only when asked for.  ``force_cap_N`` None (the default):
        each cell's default cap, 50 B / d^2 (:func:`~knitsim.cell.material.default_force_cap_N`).
        """
        warp_runtime.init()
        device = warp_runtime.resolve_device(device)
        fl = {"B": B, "d": d, "L": L, "W0": W0, "C0": C0, "m": m, "phi0": phi0, "dahl_sigma": dahl_sigma}
        if force_cap_N is not None:
            fl["force_cap_N"] = force_cap_N
        shapes = {k: np.shape(v) for k, v in fl.items()}
        names = {"friction": (friction, FRICTION_MODELS), "unloading_rule": (unloading_rule, UNLOADING_RULES),
                 "reload_rule": (reload_rule, RELOAD_RULES), "jamming_criterion": (jamming_criterion, JAMMING_CRITERIA)}
        shapes.update({k: np.shape(v[0]) for k, v in names.items()})
        if in_plane_width is not None:
            shapes["in_plane_width"] = np.shape(in_plane_width)
        n, first = 1, None
        for k, sh in shapes.items():
            if len(sh) > 1:
                raise KnitsimInputError(f"cells.{k}: expected a scalar or a 1-d array, got shape {sh}")
            if sh and sh[0] != 1:
                if n not in (1, sh[0]):
                    raise KnitsimInputError(f"cells.{k}: {sh[0]} values, but cells.{first} has {n}")
                n, first = sh[0], k

        def bad(name, mask, vals, why):
            i = int(np.argmax(np.broadcast_to(mask, (n,))))
            v = np.broadcast_to(vals, (n,))[i]
            v = v.item() if isinstance(v, np.generic) else v
            raise KnitsimInputError(f"{where(i) if where else f'cells[{i}]'}.{name} = {v!r}: {why}")

        f = {}
        for k, v in fl.items():
            try:
                a = np.asarray(v, dtype=np.float64)
            except (TypeError, ValueError):
                raise KnitsimInputError(f"cells.{k}: must be finite numbers") from None
            a = np.broadcast_to(a, (n,))
            if not np.all(np.isfinite(a)):
                bad(k, ~np.isfinite(a), a, "must be a finite number")
            f[k] = a
        if force_cap_N is None:   # each cell's default cap (B and d checked below, so guard the division)
            with np.errstate(divide="ignore", invalid="ignore"):
                f["force_cap_N"] = default_force_cap_N(f["B"], np.where(f["d"] > 0, f["d"], 1.0))
        for k in ("B", "d", "L", "W0", "C0", "force_cap_N"):
            if np.any(f[k] <= 0):
                bad(k, f[k] <= 0, f[k], "must be > 0")
        if np.any(f["m"] < 0):
            bad("m", f["m"] < 0, f["m"], "the friction ratio must be >= 0")
        if np.any(f["m"] > M_MAX):
            bad("m", f["m"] > M_MAX, f["m"], M_TOO_LARGE)
        codes = {}
        for k, (v, allowed) in names.items():
            a = np.broadcast_to(np.asarray(v), (n,))
            c = np.full(n, -1, np.int32)
            for j, name in enumerate(allowed):
                c[a == name] = j
            if np.any(c < 0):
                bad(k, c < 0, a, f"expected one of {', '.join(allowed)}")
            codes[k] = c
        # the kernel's reload flag is 1 for "mirror_unloading" (as from_params)
        codes["reload_rule"] = (codes["reload_rule"] == RELOAD_RULES.index("mirror_unloading")).astype(np.int32)
        djam = f["d"]
        if in_plane_width is not None:
            w = np.broadcast_to(np.asarray(in_plane_width, dtype=np.float64), (n,))
            if np.any(np.isinf(w)):
                bad("in_plane_width", np.isinf(w), w, "must be a finite number or None")
            # NaN: no in-plane width given (the cell jams at its compact diameter; its W0 is checked against
            # 4 d below, and the message names W0, not a width the user did not give)
            given = ~np.isnan(w)
            if np.any(given & (w < f["d"])):
                bad("in_plane_width", given & (w < f["d"]), w, "the in-plane width cannot be below the compact diameter d")
            if np.any(given & (f["W0"] < 4.0 * w)):
                bad("in_plane_width", given & (f["W0"] < 4.0 * w), w, "loops jammed at rest: W0 < 4 in_plane_width")
            djam = np.where(given, w, f["d"])
        if np.any(f["W0"] < 4.0 * f["d"]):
            bad("W0", f["W0"] < 4.0 * f["d"], f["W0"], "the wale width at rest must be >= 4 d (loops jammed already)")
        lmin = 2.0 * f["C0"] + f["W0"] - 4.0 * f["d"]
        if np.any(f["L"] <= lmin):
            bad("L", f["L"] <= lmin, f["L"], "too short to close a loop: needs > 2 C0 + W0 - 4 d")
        pm = np.arctan(f["m"])
        if np.any(np.abs(f["phi0"]) > pm + 1e-12):
            bad("phi0", np.abs(f["phi0"]) > pm + 1e-12, f["phi0"], "must lie in [-phimax, phimax], phimax = atan(m)")
        dahl = codes["friction"] == 1
        if np.any(dahl & (f["dahl_sigma"] <= 0)):
            bad("dahl_sigma", dahl & (f["dahl_sigma"] <= 0), f["dahl_sigma"], "Dahl friction needs a stiffness > 0 (1/mm)")
        if np.any(dahl & (f["dahl_sigma"] > DAHL_SIGMA_MAX)):
            bad("dahl_sigma", dahl & (f["dahl_sigma"] > DAHL_SIGMA_MAX), f["dahl_sigma"], DAHL_SIGMA_TOO_STIFF)
        if np.any(dahl & (f["m"] <= 0)):
            bad("m", dahl & (f["m"] <= 0), f["m"], "Dahl friction needs m > 0 (saturation tan(phi) = m)")
        eff = NO_EFFECTS if effects is None else effects
        if isinstance(eff, np.ndarray) and eff.dtype == object and eff.ndim == 1:
            if len(eff) != n:
                raise KnitsimInputError(f"cells.effects: {len(eff)} effect sets for {n} cells")
            codes_e, uniq = effect_set_codes(eff)
            for k, e in enumerate(uniq):
                if not isinstance(e, EffectSet):
                    raise KnitsimInputError(f"cells.effects: {e!r} is not an EffectSet (knitsim.cell.effects)")
                e.validated(where="cells.effects")
            mask = np.array([e.mask for e in uniq], np.int32)[codes_e]
            rows = np.stack([e.row() for e in uniq])[codes_e]
        elif isinstance(eff, EffectSet):
            eff.validated(where="cells.effects")
            mask, rows = np.int32(eff.mask), eff.row()[None]
        else:
            raise KnitsimInputError(f"cells.effects = {effects!r}: expected one EffectSet (knitsim.cell.effects) "
                                    "or an array of them, one per cell")
        cols = {"B": f["B"], "d": f["d"], "L": f["L"], "W0": f["W0"], "C0": f["C0"], "m": f["m"], "phi0": f["phi0"],
                "sigma": f["dahl_sigma"], "cap": f["force_cap_N"], "djam": djam,
                "friction": codes["friction"], "unloading": codes["unloading_rule"],
                "reload": codes["reload_rule"], "criterion": codes["jamming_criterion"],
                "effect_mask": mask}
        host = {k: (v if np.ndim(v) == 0 else _compact(np.asarray(v))) for k, v in cols.items()}
        host["effects"] = eff
        return cls(_device_arrays(cols, rows, device), n, None, device, host)

    def _arrays(self) -> list:
        return [getattr(self, n) for n in _FLOAT_FIELDS + _INT_FIELDS]

    def _effect_arrays(self) -> list:
        return [self.effect_mask, self.effect_params]

    def arrays(self):
        """The parameter arrays as one Warp struct (:class:`knitsim.kernels.cell_arrays.ModelArrays`), made once."""
        if "_struct" not in self.__dict__:
            from knitsim.kernels.cell_arrays import ModelArrays
            self.__dict__["_struct"] = _fill(ModelArrays(), _MODEL_STRUCT_FIELDS,
                                             self._arrays() + self._effect_arrays())
        return self.__dict__["_struct"]

    def nbytes(self) -> int:
        """Device bytes of the parameter arrays."""
        return int(sum(a.capacity for a in self._arrays() + self._effect_arrays()))

    def state(self) -> "CellBatchState":
        """A state initialised to Table 4's initial state (C0, W0, L, phi0), solved on the device."""
        st = CellBatchState.empty(self.cell_count, self.device)
        starts = wp.array(np.asarray(DEFAULT_STARTS, dtype=np.float64), dtype=wp.float64, device=self.device)
        from knitsim.kernels.specialise import INIT_KEY

        k = _kernel_module(INIT_KEY)  # the initial solve uses no optional residual: any key's kernel
        wp.launch(k.init_kernel, dim=self.cell_count, inputs=[self.arrays(), starts, st.arrays()], device=self.device)
        # no admissible rest state (knitsim.cell.domain.rest_state_problem): none found, or a contact
        # force R < 0 (the unilateral contact at B would pull): flagged before any increment
        status = st.status.numpy()
        q = st.q.numpy()
        R = q[:, CODE["R"]]
        bad = (status != STATUS_OK) | ~(R >= 0.0)
        # a rest state already at or above the force cap: the cell stops there (history.rest_at_cap_reason)
        at_cap = ~bad & (q[:, CODE["F"]] >= self.cap.numpy())
        if np.any(bad) or np.any(at_cap):
            status[bad] = STATUS_NO_REST_STATE
            status[at_cap] = STATUS_FORCE_CAP
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
        """A state of ``n`` cells on ``device``, every array zero."""
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

    def arrays(self):
        """The state's arrays as one Warp struct (:class:`knitsim.kernels.cell_arrays.StateArrays`)."""
        from knitsim.kernels.cell_arrays import StateArrays
        return _fill(StateArrays(), _STATE_STRUCT_FIELDS, self._arrays() + [self.eff])

    @property
    def cell_count(self) -> int:
        """Cells in the batch."""
        return int(self.C.shape[0])

    def nbytes(self) -> int:
        """Device bytes of the state arrays."""
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
    warm : int32 [1 or N]
        Read by :meth:`CellSolver.step` only: 1 where ``state_out`` already holds the cell's
        converged trial of this increment from the same ``state_in`` that fired no event (but a
        reversal or a reload at its start, which the step makes again) and so ended on the branch
        it started on (a patch's later coupling trial, the column's lengths corrected a little):
        its Newton starts from that state and is iterated past the step's tolerance, the same
        equilibrium in fewer iterations (within ~1e-10 N of a start from ``state_in``, not bit for
        bit).  Default 0: every step starts from ``state_in``.
    """

    strain: wp.array
    direction: wp.array
    rate: wp.array | None = None
    warm: wp.array | None = None

    def __post_init__(self):
        if self.rate is None:
            self.rate = wp.zeros(1, dtype=wp.float64, device=self.strain.device)
        if self.warm is None:
            self.warm = wp.zeros(1, dtype=wp.int32, device=self.strain.device)

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
    specialise : bool
        One kernel per kernel key (friction law, effects, jamming criterion), one launch per group
        of cells (default); False runs the generic kernel (every law chosen per cell at run time),
        with the same results.
    """

    def __init__(self, model: CellModel, max_halvings: int = MAX_HALVINGS, event_capacity: int | None = None,
                 stick_closure: str = "release_beta", specialise: bool = True):
        if stick_closure not in STICK_CLOSURES:
            raise KnitsimInputError(f"stick_closure = {stick_closure!r}: expected one of {', '.join(STICK_CLOSURES)}")
        self.stick_closure = stick_closure
        if not (isinstance(max_halvings, (int, np.integer)) and 0 <= max_halvings <= 60):
            raise KnitsimInputError(f"max_halvings = {max_halvings!r}: expected a whole number in 0..60")
        self.model = model
        self.max_halvings = int(max_halvings)
        self.groups = model.kernel_groups(specialise)
        self._group_host = None  # the groups' index arrays on the host, copied at the first subset step
        cap = 64 * model.cell_count + 64 if event_capacity is None else int(event_capacity)
        dev = model.device
        self._ev_count = wp.zeros(1, dtype=wp.int32, device=dev)
        self._ev = [wp.zeros(max(cap, 1), dtype=t, device=dev)
                    for t in (wp.int32, wp.int32, wp.int32, wp.float64, wp.float64, wp.int32, wp.int32)]
        from knitsim.kernels.cell_arrays import EventArrays
        self._ev_struct = _fill(EventArrays(), ("count", "cell", "incr", "kind", "C", "F", "label_from", "label_to"),
                                [self._ev_count] + self._ev)

    def step(self, state_in: CellBatchState, state_out: CellBatchState, control: CellControl,
             increment: int = 0, cells: np.ndarray | None = None, compact: bool | None = None,
             slope_out: wp.array | None = None) -> None:
        """One increment for all cells; ``increment`` labels the events it records.

        ``cells`` (optional, increasing cell indices): advance only these; the other rows of
        ``state_out`` are left as they are (each cell's step reads only its own rows).
        ``compact``: in two passes (:meth:`run_program`), the same results; default: with at least
        :data:`COMPACT_STEP_MIN_CELLS` cells.
        ``slope_out`` (optional, float64 [N]): each advanced cell's slope dF/dC [N/mm] on its branch at its
        end, from the Jacobian of the step's last Newton solve (implicit function theorem, as
        :mod:`knitsim.kernels.cell_tangent` computes it with one more evaluation), where the increment
        fired no event past its start (a reversal or reload there enters the branch it ends on) and no effect is on;
        NaN elsewhere (Dahl, slack, stopped, an event inside the increment)."""
        n = self.model.cell_count
        if n == 0:
            return
        dev = self.model.device
        if compact is None:
            compact = n >= COMPACT_STEP_MIN_CELLS
        groups = self.groups if cells is None else self._subset(np.asarray(cells, dtype=np.int32))
        no_count = self.__dict__.setdefault("_no_count", wp.zeros(0, dtype=wp.int32, device=dev))
        if slope_out is None:
            slope_out = self.__dict__.setdefault("_no_slope", wp.zeros(0, dtype=wp.float64, device=dev))
        model_s, s_in, s_out = self.model.arrays(), state_in.arrays(), state_out.arrays()
        for g, (k, cells) in enumerate(groups):
            if cells is None:
                continue
            m = cells.shape[0] or n
            common = [model_s, self.max_halvings, int(self.stick_closure == "release_beta"), s_in,
                      control.strain, control.direction, control.rate, int(increment), s_out, self._ev_struct,
                      control.warm, slope_out]
            count = no_count
            if compact and getattr(k, "REGULAR_PASS", False):
                # the first pass lists the cells it leaves; the full step takes the first count[0] of them
                pending, count = self._pending_buffers()[g]
                wp.launch(k.zero_count_kernel, dim=1, inputs=[count], device=dev)
                wp.launch(k.regular_step_kernel, dim=m, inputs=[cells, no_count, pending, count] + common, device=dev)
                cells = pending
            wp.launch(k.step_kernel, dim=m, inputs=[cells, count, no_count, no_count] + common, device=dev)

    def _pending_buffers(self, second: bool = False) -> list:
        """Per kernel group: the list of cells the first pass leaves for the full step, and its count
        (``second``: another such list, for the sliced full step's ping-pong)."""
        return self.__dict__.setdefault("_pending2" if second else "_pending", [
            (wp.zeros(cells.shape[0] or self.model.cell_count, dtype=wp.int32, device=self.model.device),
             wp.zeros(1, dtype=wp.int32, device=self.model.device)) for _, cells in self.groups])

    def _suspended(self):
        """Where the sliced full step keeps the walks it suspends (:class:`~knitsim.kernels.cell_arrays.SuspendedArrays`,
        one row per cell, made on first use)."""
        if "_sus" not in self.__dict__:
            from knitsim.kernels.cell_arrays import SUSPENDED_INTS, SUSPENDED_REALS, SuspendedArrays
            n, dev = self.model.cell_count, self.model.device
            sus = SuspendedArrays()
            sus.active = wp.zeros(n, dtype=wp.int32, device=dev)
            sus.z = wp.zeros((n, 5), dtype=wp.float64, device=dev)
            sus.q = wp.zeros((n, len(QUANTITY_NAMES)), dtype=wp.float64, device=dev)
            sus.real = wp.zeros((n, SUSPENDED_REALS), dtype=wp.float64, device=dev)
            sus.ints = wp.zeros((n, SUSPENDED_INTS), dtype=wp.int32, device=dev)
            self._sus = sus
        return self._sus

    def _subset(self, cells: np.ndarray) -> list:
        """The kernel groups restricted to ``cells``: (module, device index array, or None where the
        group has none of them)."""
        if cells.size == self.model.cell_count:
            return self.groups
        if self._group_host is None:
            self._group_host = [None if g.shape[0] == 0 else g.numpy().copy() for _, g in self.groups]
        host = self._group_host
        dev = self.model.device
        out = []
        for (k, _), idx in zip(self.groups, host):
            # an empty index array is a group of every cell (step: dim = cells.shape[0] or n)
            sub = cells if idx is None else cells[np.isin(cells, idx, assume_unique=True)]
            out.append((k, wp.array(sub, dtype=wp.int32, device=dev) if sub.size else None))
        return out

    def run_program(self, state: CellBatchState, program: LoadProgram, stride: int = 1,
                    k_start: int = 0, k_stop: int | None = None, history: "ProgramHistory | None" = None,
                    per_increment: bool = False, sort_by_stage: bool = False,
                    compact: bool = False, slices: Sequence[int] = ()) -> "ProgramHistory":
        """Advance ``state`` in place through increments ``k_start .. k_stop - 1`` of ``program``, recording
        every ``stride``-th row into preallocated device arrays; no host synchronisation.

        One launch per kernel group for the whole range (the increments loop on the device), or with
        ``per_increment`` one launch per increment (the same arithmetic); that increment loop is
        captured once as a graph (a CUDA graph on the GPU) and replayed on later calls with the same
        state, program and history objects.

        Parameters
        ----------
        state : CellBatchState
            Advanced in place.
        program : LoadProgram
        stride : int
            Rows recorded: increments ``stride - 1, 2 stride - 1, ...`` (row r holds increment
            ``(r + 1) stride - 1``).
        k_start, k_stop : int
            The increments to run (default: all).
        history : ProgramHistory, optional
            Where to record (made with :meth:`ProgramHistory.empty` for this program and stride);
            a new one by default.
        per_increment : bool
            One launch per increment instead of one per range.
        sort_by_stage : bool
            With ``per_increment``: before each increment the cells of each group are sorted on the
            device by their stage (radix sort, no host synchronisation), so that neighbouring
            threads (a GPU warp) do the same kind of work; the results are the same.  The increment
            loop is then not captured as a graph (the sort is not a kernel launch).
        compact : bool
            With ``per_increment``: each increment in two launches for the kernel keys that have a
            first pass (Coulomb without effects): every cell's regular increment first (one trial,
            no event), then the full step on the cells listed by the first pass, compacted on the
            device (no host synchronisation; the second launch's threads beyond the count return at
            once).  A GPU warp then does one kind of work in each launch; the results are the same
            bit for bit (``cell_step._advance_cell_variant``).
        slices : sequence of int
            With ``compact``: the full step of the listed cells in launches of at most ``slices[0]``,
            ``slices[1]``, ... sub-steps per cell (``substep_kernel``), then one launch that finishes
            them; the cells still inside their increment are suspended (their walk kept on the device)
            and compacted between launches, so that a GPU warp does not wait for its slowest cell's
            whole increment.  The same results bit for bit.  Default: none (the full step in one launch).
        """
        if not (isinstance(stride, (int, np.integer)) and stride >= 1):
            raise KnitsimInputError(f"stride = {stride!r}: expected a whole number >= 1")
        n = len(program)
        k_stop = n if k_stop is None else int(k_stop)
        dev, model = self.model.device, self.model
        hist = ProgramHistory.empty(model, n, stride, model.has_effects) if history is None else history
        if hist.stride != stride:
            raise KnitsimInputError(f"history recorded with stride {hist.stride}, asked for {stride}")
        slices = tuple(int(b) for b in slices)
        if any(b < 1 for b in slices):
            raise KnitsimInputError(f"slices = {slices!r}: expected sub-step budgets >= 1")
        key = (id(state), id(program), id(hist), int(k_start), k_stop, bool(per_increment), bool(compact), slices)
        graphs = self.__dict__.setdefault("_graphs", {})
        if key in graphs:
            # the objects are held with the graph, so their ids cannot be reused meanwhile
            wp.capture_launch(graphs[key][0])
            return hist
        prog = self.__dict__.setdefault("_programs", {})
        if id(program) not in prog:
            rate = program.rate
            prog[id(program)] = (program, [
                wp.array(np.asarray(program.strain, np.float64), dtype=wp.float64, device=dev),
                wp.array(np.asarray(program.direction, np.int32), dtype=wp.int32, device=dev),
                wp.array(np.zeros(1) if rate is None else np.asarray(rate, np.float64), dtype=wp.float64, device=dev)])
        arrays = prog[id(program)][1]
        ranges = [(k, k + 1) for k in range(k_start, k_stop)] if per_increment else [(k_start, k_stop)]
        sort = bool(sort_by_stage and per_increment)
        compact = bool(compact and per_increment)
        no_count = self.__dict__.setdefault("_no_count", wp.zeros(0, dtype=wp.int32, device=dev))
        no_slope = self.__dict__.setdefault("_no_slope", wp.zeros(0, dtype=wp.float64, device=dev))
        if compact:
            pending = self._pending_buffers()
            if slices:
                pending2 = self._pending_buffers(second=True)
                sus = self._suspended()
        if sort:
            bufs = self.__dict__.setdefault("_sort", [
                tuple(wp.zeros(2 * (cells.shape[0] or model.cell_count), dtype=wp.int32, device=dev) for _ in range(2))
                for _, cells in self.groups])
        model_s, state_s, hist_s = model.arrays(), state.arrays(), hist.arrays()

        def launches():
            for k0, k1 in ranges:
                for g, (k, cells) in enumerate(self.groups):
                    m = cells.shape[0] or model.cell_count
                    if sort:
                        keys, order = bufs[g]
                        wp.launch(k.stage_key_kernel, dim=m,
                                  inputs=[cells, state.stage, state.jammed, state.status], outputs=[keys, order],
                                  device=dev)
                        wp.utils.radix_sort_pairs(keys, order, m)
                        cells = order
                    common = [model_s, self.max_halvings, int(self.stick_closure == "release_beta"), state_s] + arrays
                    rest = [k0, k1, int(stride), self._ev_struct, hist_s, no_slope]
                    count = no_count
                    if compact and getattr(k, "REGULAR_PASS", False):
                        # the first pass lists the cells it leaves; the full step takes the first count[0]
                        cells_pending, count = pending[g]
                        wp.launch(k.zero_count_kernel, dim=1, inputs=[count], device=dev)
                        wp.launch(k.regular_kernel, dim=m, inputs=[cells, no_count, cells_pending, count] + common + rest,
                                  device=dev)
                        cells = cells_pending
                        if slices:
                            # the full step in slices of sub-steps, the cells still walking compacted
                            # between them (ping-pong lists), then one launch finishing them
                            lists = [pending[g], pending2[g]]
                            tail = [k0, int(stride), self._ev_struct, hist_s, sus]
                            for r, budget in enumerate(slices):
                                nxt, nxt_count = lists[(r + 1) % 2]
                                wp.launch(k.zero_count_kernel, dim=1, inputs=[nxt_count], device=dev)
                                wp.launch(k.substep_kernel, dim=m, inputs=[cells, count, nxt, nxt_count] + common + tail
                                          + [budget, no_slope], device=dev)
                                cells, count = nxt, nxt_count
                            wp.launch(k.substep_kernel, dim=m, inputs=[cells, count, no_count, no_count] + common + tail
                                      + [int(k.MAX_SUBSTEPS), no_slope], device=dev)
                            continue
                    wp.launch(k.program_kernel, dim=m, inputs=[cells, count, no_count, no_count] + common + rest,
                              device=dev)

        if per_increment and not sort:
            # the increment loop captured once as a graph (CUDA graph; Warp's recorded launches on the
            # CPU), replayed: no host work per launch on later calls (one launch per range needs none)
            for k, _ in self.groups:
                wp.load_module(k, device=dev)  # compiled before the capture (nothing else is loaded)
            with wp.ScopedCapture(device=dev, force_module_load=False) as capture:
                launches()
            graphs[key] = (capture.graph, state, program, hist)
            wp.capture_launch(capture.graph)
        else:
            launches()
        return hist

    def event_counts(self) -> tuple[int, int]:
        """(events recorded so far, events the buffer keeps): more recorded than kept is an overflow."""
        return int(self._ev_count.numpy()[0]), int(self._ev[0].shape[0])

    def event_arrays(self) -> dict[str, np.ndarray]:
        """Events recorded so far as host arrays (``cell``, ``increment``, ``kind`` code, ``C``, ``F`` the force
        per wale at the event, ``label_from``, ``label_to``), ordered by cell, then as they happened."""
        total = int(self._ev_count.numpy()[0])
        n = min(total, self._ev[0].shape[0])
        if total > n:
            raise RuntimeError(f"event buffer overflow: {total} events, capacity {n}; pass event_capacity=")
        cols = [a[:n].numpy() for a in self._ev]      # (only the n recorded: the buffer holds ~64 per cell)
        order = np.lexsort((np.arange(n), cols[0]))
        return {name: c[order] for name, c in zip(("cell", "increment", "kind", "C", "F", "label_from", "label_to"),
                                                    cols)}

    def events(self) -> list[dict]:
        """Events recorded so far (host copy), ordered by cell, then as they happened."""
        k = _k()
        a = self.event_arrays()
        cell, incr, kind, C, F, lf, lt = (a[n] for n in ("cell", "increment", "kind", "C", "F", "label_from", "label_to"))
        out = []
        for j in range(len(cell)):
            e = {"cell": int(cell[j]), "increment": int(incr[j]), "kind": k.EVENT_NAMES[int(kind[j])], "C": float(C[j]),
                 "F": float(F[j])}
            if lf[j] >= 0:
                e["from"] = _LABEL_NAMES[int(lf[j])]
                e["to"] = _LABEL_NAMES[int(lt[j])]
            out.append(e)
        return out


@dataclass
class ProgramHistory:
    """Rows of a run recorded on the device (:meth:`CellSolver.run_program`), preallocated.

    Attributes
    ----------
    stride : int
        Row r holds increment ``(r + 1) stride - 1``.
    codes : int32 [n_quantities]
        Quantity codes of ``q`` (:data:`~knitsim.cell.history.HISTORY_QUANTITIES`).
    q : float64 [n_quantities rows, N]
        Those quantities (F = 0 while slack), quantity-major: row r of quantity k is ``q[k rows + r]``
        (:meth:`quantities` reshapes it).  Not [n_quantities, rows, N]: a Warp array's strides are
        32-bit byte counts, and that array's first stride passes 2^31 bytes at 310 rows of 10^6 cells.
    stage, jammed, status : int32 [rows, N]
    head_gap : float64 [rows, N]
    eff : float64 [len(EFFECT_STATE) rows or 0, N]
        The effects' state, laid out as ``q`` (none recorded when no cell has an effect on).
    """

    stride: int
    codes: wp.array
    q: wp.array
    stage: wp.array
    jammed: wp.array
    status: wp.array
    head_gap: wp.array
    eff: wp.array

    @classmethod
    def empty(cls, model: CellModel, n_increments: int, stride: int = 1, with_effects: bool = False):
        """A zeroed history of the cells of ``model``, on its device.

        Parameters
        ----------
        model : CellModel
            The batch whose cells are recorded.
        n_increments : int
            Increments of the run.
        stride : int
            Record every ``stride``-th increment (``n_increments // stride`` rows).
        with_effects : bool
            Record the effects' state (``eff`` with ``len(EFFECT_STATE)`` quantities; else none).

        Returns
        -------
        ProgramHistory
        """
        dev, nc = model.device, model.cell_count
        rows = n_increments // stride
        codes = wp.array(np.asarray([CODE[k] for k in HISTORY_QUANTITIES], np.int32), dtype=wp.int32, device=dev)
        shapes = cls.shapes(rows, nc, with_effects)
        return cls(int(stride), codes, wp.zeros(shapes["q"], dtype=wp.float64, device=dev),
                   *(wp.zeros(shapes[name], dtype=wp.int32, device=dev) for name in ("stage", "jammed", "status")),
                   wp.zeros(shapes["head_gap"], dtype=wp.float64, device=dev),
                   wp.zeros(shapes["eff"], dtype=wp.float64, device=dev))

    @staticmethod
    def shapes(rows: int, nc: int, with_effects: bool = False) -> dict:
        """The shapes of the recorded arrays for ``rows`` rows of ``nc`` cells (:class:`ProgramHistory`)."""
        n_eff = len(EFFECT_STATE) if with_effects else 0
        return {"q": (len(HISTORY_QUANTITIES) * rows, nc), "stage": (rows, nc), "jammed": (rows, nc),
                "status": (rows, nc), "head_gap": (rows, nc), "eff": (n_eff * rows, nc)}

    def quantities(self) -> tuple[np.ndarray, np.ndarray]:
        """``q`` and ``eff`` on the host as [quantity, row, cell] arrays."""
        rows, nc = self.stage.shape
        q, eff = self.q.numpy(), self.eff.numpy()
        return q.reshape(-1, rows, nc), eff.reshape(-1, rows, nc)

    def _arrays(self) -> list:
        return [self.codes, self.q, self.stage, self.jammed, self.status, self.head_gap, self.eff]

    def arrays(self):
        """The history's arrays as one Warp struct (:class:`knitsim.kernels.cell_arrays.HistoryArrays`)."""
        from knitsim.kernels.cell_arrays import HistoryArrays
        return _fill(HistoryArrays(), ("codes", "q", "stage", "jammed", "status", "gap", "eff"), self._arrays())


#: on a GPU, a batch of at least this many cells runs one launch per increment with its cells sorted by
#: stage, each increment in two passes (run_batch).  At 10^6 random cells x 62 increments on an H200,
#: same run (bench_table.py; benchmarks/README.md, "Two passes per increment"): 6.03 x 10^6
#: cell-increments / s, against 5.30 x 10^6 sorted in one pass and 2.91 x 10^6 in one launch per
#: range; below this size the per-increment sort and launches cost more than the warps' divergence
#: they save
SORT_BY_STAGE_MIN_CELLS = 10_000
#: CellSolver.step (the patch's trials) runs in two passes from this many cells, on any device: on one
#: CPU core a 23 x 20 random-phi0 patch through the 3 cycles took 6.82 instead of 7.26 CPU s (1.06 x),
#: the same rows; below it, the two extra launches per trial are not paid back
COMPACT_STEP_MIN_CELLS = 256
#: the sub-step budgets of the sliced full step (run_program's ``slices``) that run_batch uses with its
#: two passes: 8 launches of one sub-step, 4 of two, 2 of four, then one finishing the cells still
#: walking.  At 10^6 random cells x 62 increments on an H100, same run (bench_substep_slices.py, README
#: "Throughput"): 1.37 x the unsliced full step (24 launches of one sub-step: 1.39 x; 48: 1.16 x, each
#: launch of 10^6 threads costing even where few are still walking); the same results bit for bit
SUBSTEP_SLICES = (1,) * 8 + (2,) * 4 + (4,) * 2


def run_batch(params, program: LoadProgram, device: str = "cpu",
              progress: Callable[[int, int], None] | None = None, max_halvings: int = MAX_HALVINGS,
              stick_closure: str = "release_beta", specialise: bool = True,
              sort_by_stage: bool | None = None, compact: bool | None = None,
              slices: Sequence[int] | None = None) -> BatchHistory:
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
    max_halvings, stick_closure, specialise
        See :class:`CellSolver`.
    sort_by_stage : bool, optional
        One launch per increment with the cells sorted by stage on the device, so that a GPU warp's
        threads do the same kind of work (:meth:`CellSolver.run_program`); the results are the same.
        Default: on a CUDA device with at least :data:`SORT_BY_STAGE_MIN_CELLS` cells.
    compact : bool, optional
        One launch per increment in two passes: the regular increments of every cell, then the
        full step of the cells listed by the first pass (:meth:`CellSolver.run_program`); the
        results are the same.  Default: as ``sort_by_stage``.
    slices : sequence of int, optional
        With ``compact``: the full step in launches of at most so many sub-steps per cell, the cells
        still inside their increment compacted between them (:meth:`CellSolver.run_program`); the
        results are the same.  Default: :data:`SUBSTEP_SLICES` on a CUDA device, none on the CPU
        (where a launch's threads run one after the other and nothing diverges).

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
    with_effects = model.has_effects
    # the whole program in one launch per kernel group (chunks only to report progress): the
    # increments loop on the device
    if sort_by_stage is None:
        sort_by_stage = wp.get_device(dev).is_cuda and nc >= SORT_BY_STAGE_MIN_CELLS
    if compact is None:
        compact = sort_by_stage
    if slices is None:
        slices = SUBSTEP_SLICES if wp.get_device(dev).is_cuda else ()
    chunk = n if progress is None else max(1, min(n, 25))
    s0 = model.state()
    s0_status0 = s0.status.numpy().copy()
    q0 = s0.q.numpy()
    rest = {name: q0[:, CODE[name]].copy() for name in HISTORY_QUANTITIES}
    rest.update(stage=s0.stage.numpy().copy(), jammed=s0.jammed.numpy().copy())
    capacity = None                  # CellSolver's default: 64 events per cell
    while True:
        solver = CellSolver(model, max_halvings, event_capacity=capacity, stick_closure=stick_closure,
                            specialise=specialise)
        hist = ProgramHistory.empty(model, n, 1, with_effects)
        for k0 in range(0, n, chunk):
            k1 = min(n, k0 + chunk)
            solver.run_program(s0, program, 1, k0, k1, hist, per_increment=bool(sort_by_stage or compact),
                               sort_by_stage=bool(sort_by_stage), compact=bool(compact), slices=slices)
            if progress is not None:
                progress(k1, n)
        recorded, kept = solver.event_counts()
        if recorded <= kept:
            break
        # a program of many reversals (a measured curve of tens of cycles) records more events than the
        # default buffer keeps: the same run again with room for every one (the count is exact: the
        # run is deterministic), not an error after the solve
        capacity = recorded + 64
        s0 = model.state()           # (the run advanced the state in place)
    hs, hj, hst, hg = hist.stage, hist.jammed, hist.status, hist.head_gap
    hqn, hen = hist.quantities()
    values = {name: hqn[j] for j, name in enumerate(HISTORY_QUANTITIES)}
    values.update(head_gap_values(hg.numpy(), model.d_jam))
    if with_effects:
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
    cap = model.cap.numpy()      # one value per cell, or one for all (the kernels read cap[i % len])
    C0 = model.C0.numpy()
    stage, jammed = hs.numpy(), hj.numpy()
    for c in np.nonzero(np.any(status != STATUS_OK, axis=0))[0]:
        i0 = int(np.argmax(status[:, c] != STATUS_OK))
        st0 = int(status[i0, c])
        why = STATUS_NAMES[st0]
        if s0_status0[c] == STATUS_FORCE_CAP:
            why = rest_at_cap_reason(float(rest["F"][c]), float(cap[c % cap.shape[0]]))
        elif st0 in (STATUS_NO_CONVERGENCE, STATUS_EVENT_NOT_LOCATED):
            # row i0 holds the last converged state (a failed cell keeps it)
            why = solver_stop_reason(st0, float(values["C"][i0, c]) / float(C0[c % C0.shape[0]]) - 1.0,
                                     float(program.strain[i0]), str(stage_labels(stage[i0:i0 + 1, c], jammed[i0:i0 + 1, c])[0]),
                                     float(values["F"][i0, c]), float(cap[c % cap.shape[0]]),
                                     int(program.direction[i0]) > 0)
        events.append({"cell": int(c), "increment": i0, "kind": "flag", "reason": why,
                       "status": STATUS_NAMES[int(status[i0, c])]})
    events.sort(key=lambda e: (e["cell"], e["increment"], e["kind"] == "flag"))
    return BatchHistory(np.asarray(program.strain), np.asarray(program.cycle), np.asarray(program.direction),
                        stage, jammed, status, values, events, list(model.params), rest)


def memory_per_cell(model: CellModel, state: CellBatchState, n_increments: int,
                    sliced: bool = False) -> dict[str, float]:
    """Device bytes per cell: model, two states (in/out), history of ``n_increments`` rows and, with
    ``sliced`` (``run_batch``'s GPU default), the suspended walks of the sliced full step and its second
    list of cells (:class:`~knitsim.kernels.cell_arrays.SuspendedArrays`)."""
    from knitsim.kernels.cell_arrays import SUSPENDED_INTS, SUSPENDED_REALS

    nc = model.cell_count
    hist = n_increments * (len(HISTORY_QUANTITIES) * 8 + 3 * 4)
    sus = float((5 + len(QUANTITY_NAMES) + SUSPENDED_REALS) * 8 + (1 + SUSPENDED_INTS + 1) * 4) if sliced else 0.0
    return {"model": model.nbytes() / nc, "states": 2 * state.nbytes() / nc, "history": float(hist),
            "suspended": sus, "total": model.nbytes() / nc + 2 * state.nbytes() / nc + hist + sus}
