"""Results of running cells through a load program: one structure for every engine.

The NumPy reference (:func:`knitsim.cell.cycle.run_cells_reference`) and the
Warp batch (:mod:`knitsim.cell.batch`) both return a :class:`BatchHistory`;
writers (CSV, plots, USD) read only this.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .stages import EVENT_TOL, stage_label_codes, stage_labels

#: per-increment quantities recorded for every cell
HISTORY_QUANTITIES = ("alpha", "beta", "gamma", "phi", "P", "W", "C", "s_BC", "T", "Rn", "F")

#: per-increment values of the interpenetration check, recorded by every engine on every accepted
#: state: the centreline gap between the heads of neighbouring loops [mm] (knitsim.cell.head_gap)
#: and 1.0 where it is below the in-plane width (the loops pass through each other), else 0.0
HEAD_GAP_QUANTITIES = ("head_gap", "interpenetrating")


def head_gap_values(gap: np.ndarray, d_jam) -> dict[str, np.ndarray]:
    """:data:`HEAD_GAP_QUANTITIES` from the recorded gaps [n_increments, n_cells] and each cell's
    in-plane width ``d_jam`` [mm] (scalar or per cell).  A gap that is not a number (an
    inadmissible state of a flagged cell) does not count as interpenetrating; nor does a gap
    within EVENT_TOL (relative) of d_jam, where the head-gap criterion holds the contact."""
    gap = np.asarray(gap, float)
    d_jam = np.asarray(d_jam, float)
    with np.errstate(invalid="ignore"):
        # a jammed head-gap state holds gap = d_jam to the solver's tolerance: not an overlap
        flag = (gap < d_jam * (1.0 - EVENT_TOL)).astype(float)
    return {"head_gap": gap, "interpenetrating": flag}


#: status codes of a cell (stored per cell as int32)
STATUS_OK = 0
STATUS_NO_CONVERGENCE = 1
STATUS_FORCE_CAP = 2
STATUS_EVENT_NOT_LOCATED = 3
#: the cell has no admissible rest state (knitsim.cell.domain.rest_state_problem): flagged before any
#: increment is solved; it is outside the model's domain, not a failure of the solver
STATUS_NO_REST_STATE = 4
STATUS_NAMES = {STATUS_OK: "ok", STATUS_NO_CONVERGENCE: "no_convergence",
                STATUS_FORCE_CAP: "force_cap", STATUS_EVENT_NOT_LOCATED: "event_not_located",
                STATUS_NO_REST_STATE: "no_rest_state"}


def rest_at_cap_reason(F_rest: float, cap: float) -> str:
    """Why a cell stops at rest with status force_cap: its rest state already carries the cap.

    The cap bounds the force per wale on loading, and its event fires where the force crosses it from
    below; a rest state at or above it (a tight loop near the end of its rest branch, alpha -> gamma,
    carries a large force per wale at rest) would load on past the cap, up the jammed branch whose
    force diverges, until float64 loses alpha - gamma (no_convergence).  Both engines stop such a cell
    at rest (knitsim.cell.batch.CellModel.state, knitsim.cell.cycle.CellCycle.run)."""
    return (f"force per wale at rest F = {F_rest:.4g} N already at force_cap_N = {cap:.4g} N: "
            "the cell stops at rest (raise force_cap_N to load it)")


def solver_stop_reason(status: int, strain: float, strain_to: float | None, label: str | None, F: float, cap: float,
                       loading: bool) -> str:
    """Why a cell stopped short of its load program (status no_convergence or event_not_located), in the
    facts a user can act on: where it stopped (its last converged state: the strain of its course
    length, its stage label (None where it is not kept, a sweep's dataset), its force per wale) and the
    increment it could not finish (``strain_to``; None in a patch, where a cell's target is the column
    coupling's trial).

    On the jammed branch while loading, below the cell's force cap, it also says that a lower cap would
    have been the expected end there: the jammed branch's force diverges (W held at the jamming width
    while C grows, :func:`rest_at_cap_reason`), and the cap is what ends a run on it; a cap far above
    what the branch can carry (1e12 N per wale) otherwise ends every such run in a failure."""
    what = ("no converged solution" if status == STATUS_NO_CONVERGENCE else "an event could not be located")
    msg = (f"{what}{'' if strain_to is None else f' on the increment to strain {strain_to:.4g}'}; "
           f"stopped at strain {strain:.4g} ({'' if label is None else label + ', '}force per wale {F:.4g} N)")
    if label == "jamming" and loading and F < cap:
        msg += (f"; the jammed branch's force diverges and the cell did not reach force_cap_N = {cap:.4g} N: "
                f"a force_cap_N below {F:.3g} N ends the run there as expected")
    return msg


@dataclass
class BatchHistory:
    """One row per increment of the load program, one column per cell.

    Attributes
    ----------
    strain, cycle, direction : ndarray, shape [n_increments]
        The imposed strain of the course length ((C - C0)/C0), the cycle
        number (from 1) and the direction (+1 loading, -1 unloading).
    stage, jammed, status : ndarray of int, shape [n_increments, n_cells]
        Stage code (:class:`~knitsim.cell.stages.Stage`), jammed flag (0/1) and
        status code (:data:`STATUS_NAMES`).  A cell whose status is not ok keeps
        its last converged state in later rows.
    values : dict of str to ndarray, shape [n_increments, n_cells]
        :data:`HISTORY_QUANTITIES` (N, mm, rad); the force per wale ``F`` is 0
        while a cell is slack.
    events : list of dict
        Located stage changes: ``cell``, ``increment``, ``kind``, ``C`` ...
    params : list
        The :class:`~knitsim.cell.material.CellParams` of each cell.
    rest : dict of str to ndarray, shape [n_cells], optional
        The initial state (Table 4's rest: C0, W0, L, phi0) before the first increment:
        :data:`HISTORY_QUANTITIES`, ``stage`` and ``jammed``.
    """

    strain: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    stage: np.ndarray
    jammed: np.ndarray
    status: np.ndarray
    values: dict
    events: list = field(default_factory=list)
    params: list = field(default_factory=list)
    rest: dict | None = None

    @property
    def n_cells(self) -> int:
        """Cells in the batch (columns of the history)."""
        return int(self.stage.shape[1])

    @property
    def force_per_wale(self) -> np.ndarray:
        """Force per wale [N], shape [n_increments, n_cells]."""
        return self.values["F"]

    def label_codes(self) -> np.ndarray:
        """Stage label codes (:data:`~knitsim.cell.stages.LABEL_CODES`) per increment and cell."""
        return stage_label_codes(self.stage, self.jammed)

    def label_array(self, cell: int = 0) -> np.ndarray:
        """Stage labels (adherence / sliding / jamming / slack) of one cell, as an array of str."""
        return stage_labels(self.stage[:, cell], self.jammed[:, cell])

    def labels(self, cell: int = 0) -> list[str]:
        """Stage labels (adherence / sliding / jamming / slack) of one cell."""
        return self.label_array(cell).tolist()

    def events_of(self, cell: int) -> list[dict]:
        """The events of cell ``cell``, in their order in :attr:`events`.

        The events are indexed by cell once per events list (a scan of every event for each cell made a
        batch's summaries quadratic in its cells: 8.5 ms a cell of 500 random cells over 3 cycles, most of
        ``reduce_history``'s time, and 15 million events at 10^6 cells)."""
        key = (id(self.events), len(self.events))
        cached = self.__dict__.get("_events_by_cell")
        if cached is None or cached[0] != key:
            by_cell: dict[int, list] = {}
            for e in self.events:
                by_cell.setdefault(int(e.get("cell", 0)), []).append(e)
            cached = (key, by_cell)
            self.__dict__["_events_by_cell"] = cached
        return list(cached[1].get(int(cell), ()))

    def cell(self, i: int) -> "BatchHistory":
        """The history of cell ``i`` alone (a one-column BatchHistory)."""
        sl = slice(i, i + 1)
        return BatchHistory(self.strain, self.cycle, self.direction, self.stage[:, sl],
                            self.jammed[:, sl], self.status[:, sl],
                            {k: v[:, sl] for k, v in self.values.items()},
                            [dict(e, cell=0) for e in self.events_of(i)],
                            self.params[i:i + 1],
                            None if self.rest is None else {k: v[sl] for k, v in self.rest.items()})

    @staticmethod
    def stack(histories: list["BatchHistory"]) -> "BatchHistory":
        """Join single- or multi-cell histories of the same program along the cell axis."""
        h0 = histories[0]
        events, params, offset = [], [], 0
        for h in histories:
            events += [dict(e, cell=e.get("cell", 0) + offset) for e in h.events]
            params += list(h.params)
            offset += h.n_cells
        cat = lambda name: np.concatenate([getattr(h, name) for h in histories], axis=1)  # noqa: E731
        return BatchHistory(h0.strain, h0.cycle, h0.direction, cat("stage"), cat("jammed"),
                            cat("status"),
                            {k: np.concatenate([h.values[k] for h in histories], axis=1)
                             for k in h0.values},
                            events, params,
                            None if any(h.rest is None for h in histories) else
                            {k: np.concatenate([h.rest[k] for h in histories]) for k in h0.rest})
