"""Result writers for cell runs: curve.csv, events.csv, summary.json, scene.resolved.toml, plot.png.

Every writer reads only a :class:`~knitsim.cell.history.BatchHistory` (the
structure every engine returns).  Files are written atomically: each is first
written into a temporary sibling and renamed into place, and
:func:`write_cell_results` builds the whole set in a hidden sibling directory
before moving the files into the output directory, ``summary.json`` last; an
error on the way leaves no half-written file behind.

``curve.csv`` has, cell by cell, the rest state (strain 0: Table 4's
initialisation at C0, W0, L, phi0, whose force per wale is not zero) and then
one row per increment::

    cell, cycle, direction, stage, strain, force_per_wale_N, alpha, beta, gamma,
    phi, P, W, C, s_BC, status

``direction`` is ``load`` / ``unload``, ``stage`` the label of
:func:`knitsim.cell.stages.stage_label` (adherence / sliding / jamming /
slack), ``status`` the cell's status name (ok / force_cap / no_convergence /
event_not_located).  ``strain`` is the imposed strain of the course length
((C - C0)/C0 of the program); ``C`` is the cell's own course length [mm], which
differs from ``C0 (1 + strain)`` only while the cell is slack (it stays where
the force reached 0) or stopped.  Angles in rad, lengths in mm, forces in N.
A cell that stops (force cap, a failure) has one row with its status at the
state where it stopped (the located cap state, or the last converged state
inside the increment it could not finish: its ``C`` says where); the later rows
keep their strain and status, with no values (``nan``): the cell never reached
them.
"""
from __future__ import annotations

import functools
import math
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..cell.cycle import dissipated_energies
from ..cell.history import STATUS_FORCE_CAP, STATUS_NAMES, STATUS_OK, BatchHistory
from ..cell.material import DEFAULT_FORCE_CAP_TEXT
from ..cell.stages import LABEL_CODES, stage_label, stage_label_codes
from ..errors import KnitsimInputError
from .checks import (ENERGY_KINDS, compressive_rest_state, cut_by_force_cap, cycle_warnings, energy_creating_loops,
                     interpenetration, jam_width_floor, reloads_below_first_loading, work_kinds,
                     wale_spacing_below_jamming)
from .jsonable import json_text
from .output_dir import (RECORD_NAME, add_output_flags, check_output_dir,  # noqa: F401 - the CLIs' import
                         prepare_output_dir, prepare_output_file, record_outputs, recorded_outputs, scene_inputs,
                         stamp_outputs)

CURVE_COLUMNS = ("cell", "cycle", "direction", "stage", "strain", "force_per_wale_N", "alpha", "beta",
                 "gamma", "phi", "P", "W", "C", "s_BC", "status")
EVENT_COLUMNS = ("cell", "increment", "strain", "kind", "C", "event_strain", "force_per_wale_N", "from", "to", "status",
                 "reason")
OUTPUT_FILES = ("curve.csv", "events.csv", "scene.resolved.toml", "plot.png", "summary.json")
_LABELS = {v: k for k, v in LABEL_CODES.items()}
_QUANTITIES = ("alpha", "beta", "gamma", "phi", "P", "W", "C", "s_BC")

#: what each rule value means (labelled in summaries and plots)
RULE_MEANINGS = {
    "friction": {"coulomb": "Coulomb stick/slide switching (Table 4)",
                 "dahl": "Dahl smooth stick-slip of tan(phi) with the slip at B"},
    "unloading_rule": {"dusserre": "SF- freezes beta, S- freezes T (Table 4)",
                       "hong_constant_t": "T constant through the whole unloading (Hong et al. 2002)"},
    "reload_rule": {"mirror_unloading": "reloading from Rn ~ 0 freezes beta in SF+ (mirror of SF-)",
                    "freeze_rn": "SF+ freezes Rn as printed in Table 4"},
    "jamming_criterion": {"w_4d": "jamming at W = 4 d (Hong et al. 2002)",
                          "head_gap": "jamming when neighbouring loop heads come within d"},
}


# ------------------------------------------------------------------ atomic I/O
def umask_mode(mode: int = 0o666) -> int:
    """``mode`` as the process' umask lets a newly created file have it (what ``open`` would give)."""
    mask = os.umask(0)
    os.umask(mask)
    return mode & ~mask


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary sibling and a rename.

    The file gets the permissions a plain ``open`` would give it under the umask (the temporary
    file's private 0600 would keep colleagues on a shared cluster from reading results)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, umask_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


# ------------------------------------------------------------------- tables
def _num(v: float) -> str:
    v = float(v)
    return repr(v) if math.isfinite(v) else "nan"


def curve_csv(history: BatchHistory) -> str:
    """The text of ``curve.csv`` (see the module docstring)."""
    h = history
    labels = h.label_codes()
    F = h.force_per_wale
    lines = [",".join(CURVE_COLUMNS)]
    direction = ["load" if d > 0 else "unload" for d in h.direction]
    for c in range(h.n_cells):
        cols = [h.values[q][:, c] for q in _QUANTITIES]
        if h.rest is not None:
            # the rest state (C0, W0, L, phi0: Table 4's initialisation) before the first increment
            r = h.rest
            lines.append(",".join([str(c), str(int(h.cycle[0])), "load",
                                   stage_label(int(r["stage"][c]), bool(r["jammed"][c])), _num(0.0),
                                   _num(r["F"][c])] + [_num(r[q][c]) for q in _QUANTITIES] + ["ok"]))
        # the rows after the one where the cell stopped hold that state at strains it never reached: no values
        solved = _stopped_rows(h.status[:, c])
        for i in range(len(h.strain)):
            values = [F[i, c]] + [col[i] for col in cols] if i < solved else [math.nan] * (1 + len(cols))
            row = [str(c), str(int(h.cycle[i])), direction[i], _LABELS[int(labels[i, c])], _num(h.strain[i])] \
                + [_num(v) for v in values] + [STATUS_NAMES[int(h.status[i, c])]]
            lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _csv_cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return _num(v)
    s = str(v)
    return '"' + s.replace('"', '""') + '"' if any(ch in s for ch in ',"\n') else s


def events_csv(history: BatchHistory) -> str:
    """The text of ``events.csv``: one row per located event, in order of cell and increment.

    ``strain`` is the imposed strain of the increment, ``event_strain`` the
    strain of the cell at the event, ``C / C0 - 1``, ``force_per_wale_N`` its force there (a cycle's energy
    integrates the rows and these points between them: :func:`cell_summary`).
    """
    h = history
    lines = [",".join(EVENT_COLUMNS)]
    evs = sorted(h.events, key=lambda e: (e.get("cell", 0), e.get("increment", 0)))
    for e in evs:
        c = int(e.get("cell", 0))
        inc = int(e.get("increment", 0))
        C = e.get("C")
        C0 = h.params[c].C0 if c < len(h.params) else None
        row = {"cell": c, "increment": inc, "strain": float(h.strain[inc]) if 0 <= inc < len(h.strain) else None,
               "kind": e.get("kind"), "C": None if C is None else float(C),
               "event_strain": None if (C is None or C0 is None) else float(C) / C0 - 1.0,
               "force_per_wale_N": None if e.get("F") is None else float(e["F"]),
               "from": e.get("from"), "to": e.get("to"), "status": e.get("status"), "reason": e.get("reason")}
        lines.append(",".join(_csv_cell(row[k]) for k in EVENT_COLUMNS))
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ summary
def _stopped_rows(status: np.ndarray) -> int:
    """Number of meaningful rows of a cell.

    The first flagged row is the state where the cell stopped, kept: the located
    cap state of a cell stopped by the force cap, the last converged state inside
    the increment it could not finish of a failed cell.  The rows after it repeat
    that state at strains the cell never reached (dropped).
    """
    return int(stopped_rows(np.asarray(status)[:, None])[0])


def stopped_rows(status: np.ndarray) -> np.ndarray:
    """:func:`_stopped_rows` of every column of ``status`` [n, k] at once (int64, shape [k])."""
    bad = np.asarray(status) != STATUS_OK
    return np.where(bad.any(axis=0), bad.argmax(axis=0) + 1, bad.shape[0]).astype(np.int64)


#: what the stage rules mean to a Dahl cell: nothing (its friction state follows the slip at B through every
#: stage; a blind probe found the summaries of Dahl runs naming "SF- freezes beta, S- freezes T" while the
#: rule changed no number)
DAHL_UNUSED_RULE = ("not used by Dahl friction (its friction angle follows the slip at B in every stage; its "
                    "large-sigma limit is Coulomb friction with unloading_rule = \"hong_constant_t\")")


def rule_meaning(key: str, value, friction: str) -> str:
    """What the rule ``key = value`` means for a cell of the ``friction`` law (summaries and plots)."""
    if friction == "dahl" and key in ("unloading_rule", "reload_rule"):
        return DAHL_UNUSED_RULE
    return RULE_MEANINGS.get(key, {}).get(str(value), "")


#: rule sets listed in a cell plot's legend (the others counted)
RULE_SETS_SHOWN = 6


def _rules_label(p) -> str:
    """A cell's rules in a few words, as the plot's legend gives them (Dahl: no unloading or reload rule, which
    it does not use: :func:`rule_meaning`)."""
    rules = f"unload {p.unloading_rule}, reload {p.reload_rule}, " if p.friction != "dahl" else ""
    return f"{p.friction}, {rules}{p.jamming_criterion}, cap {p.cap_N:.4g} N" + (" (default)" if p.cap_is_default else "")


def rules_of(params) -> dict:
    """The rules a cell ran with, each with its meaning."""
    out = {}
    for key, attr in (("friction", "friction"), ("unloading_rule", "unloading_rule"),
                      ("reload_rule", "reload_rule"), ("jamming_criterion", "jamming_criterion")):
        v = getattr(params, attr)
        out[key] = {"value": v, "meaning": rule_meaning(key, v, params.friction)}
    out["force_cap_N"] = {"value": float(params.cap_N),
                          "meaning": "a cell stops when its force per wale reaches this value"
                          + (f" ({DEFAULT_FORCE_CAP_TEXT}; rules.force_cap_N sets another)"
                             if params.cap_is_default else "")}
    return out



def _stitch_energy(h, cell: int, B: float):
    """The cell's stored energy along its path, rest first (:func:`knitsim.cell.quarter_loop.stitch_energy_along`)."""
    from ..cell.quarter_loop import stitch_energy_along

    names = ("alpha", "beta", "gamma", "phi", "P")
    # each row's energy once (the check of a loop from a loading asks for its start row twice)
    return functools.lru_cache(maxsize=None)(stitch_energy_along(
        [h.rest[n][cell] for n in names], np.stack([np.asarray(h.values[n])[:, cell] for n in names], axis=1), B))


def _event_points(events, C0) -> list[tuple[int, float, float]]:
    """(increment, strain C / C0 - 1, force) of each located event of a cell that has a finite C and F, in order:
    what :func:`cycle_numbers` puts between the rows of a cycle's path."""
    return [(int(e.get("increment", -1)), float(e["C"]) / C0 - 1.0, float(e["F"])) for e in events
            if "C" in e and "F" in e and math.isfinite(e["C"]) and math.isfinite(e["F"])]


class SummaryRows:
    """The load program's rows as every cell's summary reads them (:func:`cell_summary`): built once for a
    batch (:func:`summarise`, :func:`knitsim.sweep.runner.reduce_history`), not once per cell."""

    def __init__(self, history: BatchHistory):
        self.strain = np.asarray(history.strain, float)
        self.cycle = np.asarray(history.cycle)
        self.direction = np.asarray(history.direction)
        #: (cycle number, its rows) of each cycle, in order
        self.cycles = [(k, np.nonzero(self.cycle == k)[0]) for k in np.unique(self.cycle)]


#: how a cycle's residual strain was found (:func:`cycle_numbers`' ``residual_from``): not at all, at a located
#: slack event, interpolated between the rows around the zero of the force
RESIDUAL_FROM = (None, "event", "interpolated")


def cycle_numbers(h: BatchHistory, cells, n_ok, events: list, rows_of: SummaryRows) -> dict[str, np.ndarray]:
    """The numbers of :func:`cell_summary`'s ``cycles`` (its docstring says what each is) of the cells ``cells``
    at once, each over its first ``n_ok`` rows (:func:`stopped_rows`), with its ``events``
    (:meth:`BatchHistory.events_of`, one list per cell).

    Returns
    -------
    dict of str to ndarray, shape [len(cells), len(rows_of.cycles)]
        ``reached`` (the cell has rows in the cycle: the others' values are NaN / -1), ``peak_force_per_wale_N``,
        ``strain_at_peak``, ``residual_strain`` (NaN: none), ``residual_from`` (index into
        :data:`RESIDUAL_FROM`), ``energy_N_per_strain``, ``energy_kind`` (index into
        :data:`knitsim.io.checks.ENERGY_KINDS`), ``closed``.
    """
    cells = np.asarray(cells, dtype=np.int64)
    n_ok = np.asarray(n_ok, dtype=np.int64)
    m, nq = len(cells), len(rows_of.cycles)
    out = {k: np.full((m, nq), np.nan) for k in ("peak_force_per_wale_N", "strain_at_peak", "residual_strain",
                                                  "energy_N_per_strain")}
    out["reached"] = np.zeros((m, nq), bool)
    out["residual_from"] = np.zeros((m, nq), np.int8)
    out["energy_kind"] = np.full((m, nq), -1, np.int8)
    out["closed"] = np.zeros((m, nq), bool)
    if not m:
        return out
    Fh, Ch, St = h.force_per_wale, h.values["C"], h.status
    C0 = np.array([h.params[c].C0 for c in cells])
    strain, direction = rows_of.strain, rows_of.direction
    rest_F = None if h.rest is None else np.asarray(h.rest["F"])[cells]
    slack = [[e for e in ev if e.get("kind") == "slack" and "C" in e] for ev in events]
    # each cell's located events with a finite C and F, as (its rank in cells, increment, strain, force), in order
    ev = [(i, inc, e_s, e_f) for i, (c, evs) in enumerate(zip(cells, events))
          for inc, e_s, e_f in _event_points(evs, h.params[c].C0)]
    ev_cell = np.array([e[0] for e in ev], np.int64)
    ev_inc = np.array([e[1] for e in ev], np.int64)
    ev_s, ev_f = np.array([e[2] for e in ev], float), np.array([e[3] for e in ev], float)
    col = np.arange(m)
    for q, (_, R) in enumerate(rows_of.cycles):
        if not len(R):
            continue
        nv = np.sum(R[:, None] < n_ok[None, :], axis=0)          # the cell's rows of the cycle: R[:nv]
        reached = nv > 0
        out["reached"][:, q] = reached
        if not reached.any():
            continue
        F = Fh[np.ix_(R, cells)]
        valid = np.arange(len(R))[:, None] < nv
        j = R[np.argmax(np.where(valid, F, -np.inf), axis=0)]
        peak = Fh[j, cells]
        # (the imposed strain; where the cell stopped inside an increment, its own strain there)
        at_peak = np.where(St[j, cells] == STATUS_OK, strain[j], Ch[j, cells] / C0 - 1.0)
        if R[0] == 0 and rest_F is not None:
            # a first cycle that unloads from rest peaks at the rest state (a blind probe read 0 N at -0.005)
            from_rest = rest_F > peak
            peak = np.where(from_rest, rest_F, peak)
            at_peak = np.where(from_rest, 0.0, at_peak)
        out["peak_force_per_wale_N"][:, q] = np.where(reached, peak, np.nan)
        out["strain_at_peak"][:, q] = np.where(reached, at_peak, np.nan)
        # residual strain: where F reaches 0 on this cycle's unloading branch (its rows U[:nu]), at a located slack
        # event, else between the rows of the first step from F > 0 to F <= 0 (from the row before the branch)
        U = R[direction[R] < 0]
        nu = np.sum(U[:, None] < n_ok[None, :], axis=0)
        if len(U):
            P = np.concatenate([[U[0] - 1], U]) if U[0] > 0 else U
            lead = len(P) - len(U)
            Fa, Fb = Fh[np.ix_(P[:-1], cells)], Fh[np.ix_(P[1:], cells)]
            down = (Fa > 0) & (Fb <= 0) & (np.arange(len(P) - 1)[:, None] < (nu + lead - 1))
            has = down.any(axis=0) & (nu > 0)
            if has.any():
                t_at = np.argmax(down, axis=0)
                a, b = P[t_at], P[t_at + 1]
                fa, fb = Fh[a, cells], Fh[b, cells]
                ea, eb = Ch[a, cells] / C0 - 1.0, Ch[b, cells] / C0 - 1.0
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = fa / (fa - fb)
                    res = ea + t * (eb - ea)
                out["residual_strain"][has, q] = res[has]
                out["residual_from"][has, q] = 2
            for i in np.flatnonzero(nu > 0):
                lo, hi = int(U[0]), int(U[nu[i] - 1])
                hit = [e for e in slack[i] if lo <= int(e["increment"]) <= hi]
                if hit:
                    out["residual_strain"][i, q] = float(hit[0]["C"]) / h.params[cells[i]].C0 - 1.0
                    out["residual_from"][i, q] = 1
        # the cycle's work along each cell's path: its rows from the row before the cycle (the first cycle from
        # the rest state), with the located events inside the cycle's increments (a slide onset, a slack) put
        # between its rows, before the row of their increment, in the order they happened: the kinks there are
        # the trapezoids' error, O(increment) without them (a blind probe: a cycle's energy 32 % low at
        # max_increment 0.1, 4 % at 0.02; with them within 0.1 % at 0.1).  Every cell's path at once: its items
        # (rows, rest state, events) sorted by cell and place, the paths of one length summed as rows of a matrix
        # (dissipated_energies: each row's sum is dissipated_energy's of that path)
        idx = np.flatnonzero(reached)
        loads = direction[R] > 0
        first_load = int(np.argmax(loads)) if loads.any() else len(R)
        path_all = np.concatenate([[R[0] - 1], R]) if R[0] > 0 else R
        lead = len(path_all) - len(R)
        head = 1 if (R[0] == 0 and rest_F is not None) else 0         # the rest state first
        n_path = np.where(reached, lead + nv, 0)                      # rows of each cell's path
        rank = np.full(m, -1)
        rank[idx] = np.arange(len(idx))
        counts = n_path[idx]
        k_in = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        r_rank = np.repeat(np.arange(len(idx)), counts)
        rows, r_cell = path_all[k_in], idx[r_rank]
        s_rows = Ch[rows, cells[r_cell]] / C0[r_cell] - 1.0
        # closure judged on the program's strain (a slack cell's own stays where its force reached 0)
        parts = [(r_rank, 2 * (head + k_in) + 1, s_rows, Fh[rows, cells[r_cell]],
                  np.where(St[rows, cells[r_cell]] == STATUS_OK, strain[rows], s_rows))]
        if head:
            parts.append((np.arange(len(idx)), np.ones(len(idx), np.int64), np.zeros(len(idx)), rest_F[idx],
                          np.zeros(len(idx))))
        if len(ev_cell):
            at = np.minimum(np.searchsorted(path_all, ev_inc), len(path_all) - 1)
            on = (path_all[at] == ev_inc) & (at < n_path[ev_cell]) & (head + at > 0)
            parts.append((rank[ev_cell[on]], 2 * (head + at[on]), ev_s[on], ev_f[on], ev_s[on]))
        p_rank, p_key, p_s, p_f, p_i = (np.concatenate(x) for x in zip(*parts))
        order = np.argsort(p_rank * (2 * (len(path_all) + 2)) + p_key, kind="stable")
        S, Fp, Ip = p_s[order], p_f[order], p_i[order]
        length = np.bincount(p_rank, minlength=len(idx))
        start = np.cumsum(length) - length
        for L in np.unique(length):
            g = np.flatnonzero(length == L)
            take = start[g][:, None] + np.arange(L)
            Ms, Mf, Mi = S[take], Fp[take], Ip[take]
            value = dissipated_energies(Ms, Mf) if L > 1 else np.zeros(len(g))
            closed, kind = work_kinds(nu[idx[g]] > 0, first_load < nv[idx[g]], L, Mi[:, 0], Mi[:, -1],
                                      Mi.max(axis=1) - Mi.min(axis=1))
            out["energy_N_per_strain"][idx[g], q] = value
            # hysteresis (closed cycle), work (open), loading_work, unloading_work (a cycle that never loads)
            out["energy_kind"][idx[g], q] = kind
            out["closed"][idx[g], q] = closed
    return out


def cycle_entries(h: BatchHistory, cell: int, n_ok: int, events: list, rows_of: SummaryRows) -> list[dict]:
    """The ``cycles`` of :func:`cell_summary` (its docstring says what each number is): one entry per cycle
    that the cell reached, over its first ``n_ok`` rows (:func:`_stopped_rows`), with its ``events``
    (:meth:`BatchHistory.events_of`): :func:`cycle_numbers` of the one cell."""
    num = cycle_numbers(h, [cell], [n_ok], [events], rows_of)
    C0 = h.params[cell].C0
    out = []
    for q, (k, _) in enumerate(rows_of.cycles):
        if not num["reached"][0, q]:
            continue
        res, how = float(num["residual_strain"][0, q]), RESIDUAL_FROM[int(num["residual_from"][0, q])]
        value = float(num["energy_N_per_strain"][0, q])
        out.append({"cycle": int(k), "peak_force_per_wale_N": float(num["peak_force_per_wale_N"][0, q]),
                    "strain_at_peak": float(num["strain_at_peak"][0, q]),
                    "residual_strain": None if how is None else res, "residual_strain_from": how,
                    "energy_N_per_strain": value, "energy_N_mm": value * C0,
                    "energy_kind": ENERGY_KINDS[int(num["energy_kind"][0, q])], "closed": bool(num["closed"][0, q])})
    return out


def first_jamming_rows(codes: np.ndarray, n_ok) -> np.ndarray:
    """Per column of stage label codes ``codes`` [n, k] (:meth:`BatchHistory.label_codes`), the first of its
    first ``n_ok`` rows (one number per column) labelled jamming; -1 where none is."""
    codes = np.asarray(codes)
    jammed = (codes == LABEL_CODES["jamming"]) & (np.arange(codes.shape[0])[:, None] < np.asarray(n_ok))
    return np.where(jammed.any(axis=0), jammed.argmax(axis=0), -1)


def first_jamming(events: list, jam_row: int, C, C0: float) -> tuple[float | None, str | None]:
    """``strain_at_first_jamming`` and ``strain_at_first_jamming_from`` of :func:`cell_summary`: at the cell's
    first located ``jam`` event, else at its first jammed row ``jam_row`` (:func:`first_jamming_rows`; -1:
    none) of its course lengths ``C``."""
    jam = [e for e in events if e.get("kind") == "jam" and "C" in e]
    if jam:
        return float(jam[0]["C"]) / C0 - 1.0, "event"
    if jam_row < 0:
        return None, None
    return float(C[jam_row] / C0 - 1.0), "row"


def stop_point(h: BatchHistory, cell: int, final: int) -> dict:
    """Where the cell stopped (:func:`cell_summary`): ``stop_row`` (its first row not ok; None where it ran the
    program), ``expected_end`` (completed, or stopped at the force cap), and, of a failed cell, its
    ``last_converged_strain`` and ``last_converged_force_per_wale_N``; ``stopped_at_strain`` the imposed strain
    of the stop row."""
    flagged = np.flatnonzero(h.status[:, cell] != STATUS_OK)
    stop_row = int(flagged[0]) if len(flagged) else None   # the increment where the cell stopped
    expected = final in (STATUS_OK, STATUS_FORCE_CAP)
    failed = stop_row is not None and not expected
    return {"stop_row": stop_row, "expected_end": expected,
            "stopped_at_strain": None if stop_row is None else float(h.strain[stop_row]),  # imposed strain
            # where a failed cell stays: its last converged state, inside the increment it could not finish (the
            # state its later rows hold, status not ok; the strain and force the stop's reason names)
            "last_converged_strain": float(h.values["C"][stop_row, cell]) / h.params[cell].C0 - 1.0 if failed else None,
            "last_converged_force_per_wale_N": float(h.force_per_wale[stop_row, cell]) if failed else None}


def reference_warnings(rows_of: SummaryRows, F_ok, n_ok: int, warnings, reference) -> list:
    """:func:`knitsim.io.checks.reloads_below_first_loading` of a cell's first ``n_ok`` rows (force ``F_ok``)
    against ``reference`` (:func:`first_loading_curve`; None: none), leaving out the cycles its cycle
    ``warnings`` flagged already."""
    if reference is None:
        return []
    # the same knit pulled monotonically (summarise's reference): a reload past the earlier maximum that
    # stays below it
    ref_s, ref_F = reference
    below = {int(w.cycle) for w in warnings if w.code in ("reload_below_earlier_loading", "zero_force_cycle")
             and w.cycle is not None}
    return reloads_below_first_loading(rows_of.strain[:n_ok], F_ok, rows_of.cycle[:n_ok],
                                       rows_of.direction[:n_ok], ref_s, ref_F, flagged=below)


def cell_summary(history: BatchHistory, cell: int, label: str = "", notes: dict | None = None,
                 reference=None) -> dict:
    """Summary numbers of one cell.

    Per cycle: peak force per wale and the imposed strain where it occurs;
    residual strain, the strain ``C / C0 - 1`` where the force reaches 0 on
    the unloading branch (located ``slack`` event; else linear interpolation
    between the two rows around the zero; null if the force never reaches 0);
    ``oint F d(strain)`` over the cycle's rows (strain = C / C0 - 1 from the
    cell's own C, from the last row of the previous cycle; the first cycle from
    the rest state), as ``energy_N_per_strain`` and times C0 as
    ``energy_N_mm``, with ``energy_kind`` (:func:`knitsim.io.checks.cycle_work`):
    the ``hysteresis`` of a closed cycle, the ``work`` of an open one, the
    ``loading_work`` of a loading only, the ``unloading_work`` of an unloading only
    (warning ``cycle_without_loading``).

    Also: strain at the first jamming (located ``jam`` event, else the first
    jammed row), rows per status, the final status and whether it is the
    expected end of the run (completed, or stopped at the force cap).  A failed
    cell: ``stopped_at_strain`` is the imposed strain of the increment it could
    not finish, ``final_force_per_wale_N`` its force at the last increment it
    finished, and ``last_converged_strain`` / ``last_converged_force_per_wale_N``
    the state it reached inside the failed increment and holds on its later rows
    (the strain and force its stop reason names).
    """
    return _cell_summary(history, cell, label, notes, reference, SummaryRows(history))


def _cell_summary(h: BatchHistory, cell: int, label: str, notes: dict | None, reference,
                  rows_of: SummaryRows) -> dict:
    p = h.params[cell]
    F = h.force_per_wale[:, cell]
    status = h.status[:, cell]
    n_ok = _stopped_rows(status)
    events = h.events_of(cell)
    cycles_out = cycle_entries(h, cell, n_ok, events, rows_of)
    codes = stage_label_codes(h.stage[:, cell:cell + 1], h.jammed[:, cell:cell + 1])
    jam_strain, jam_from = first_jamming(events, int(first_jamming_rows(codes, n_ok)[0]), h.values["C"][:, cell], p.C0)

    counts = {STATUS_NAMES[int(s)]: int(np.sum(status == s)) for s in np.unique(status)}
    final = int(status[-1])
    flag = next((e for e in events if e.get("kind") == "flag"), None)
    stop = stop_point(h, cell, final)
    stop_row, expected = stop["stop_row"], stop["expected_end"]
    if stop["last_converged_strain"] is not None:
        # a failed cell's row of the increment it could not finish holds its last converged state (at its own
        # strain): a cycle whose peak is that state says so (knitsim run's cycle figures stop before the
        # increment where cells failed: its peak is over the increments completed)
        for c in cycles_out:
            if (c["cycle"] == int(rows_of.cycle[stop_row])
                    and c["peak_force_per_wale_N"] == stop["last_converged_force_per_wale_N"]):
                c["peak_is_last_converged_state"] = True
    cut = []
    if final == STATUS_OK:
        end = "completed the load program"
    elif final == STATUS_FORCE_CAP:
        cut = cut_by_force_cap(h.strain, h.direction, h.cycle, stop_row, p.cap_N)
        end = (f"stopped at the force cap (force per wale = {p.cap_N:g} N), "
               + ("before the program's unloadings: later cycles not run (warning "
                  "program_cut_by_force_cap)" if cut else "the expected end of a run to the cap"))
    else:
        reason = flag.get("reason", "") if flag else ""
        end = f"FAILED ({STATUS_NAMES[final]}): {reason}"
    peaks = [(c["cycle"], c["peak_force_per_wale_N"]) for c in cycles_out]
    warnings = cut + cycle_warnings(peaks, h.strain[:n_ok], F[:n_ok], h.cycle[:n_ok], h.direction[:n_ok],
                                    residuals={c["cycle"]: c["residual_strain"] for c in cycles_out})
    warnings += reference_warnings(rows_of, F[:n_ok], n_ok, warnings, reference)
    if h.rest is not None:
        warnings += compressive_rest_state(h.rest["F"][cell])
    if h.rest is not None and n_ok:
        warnings += energy_creating_loops(np.concatenate([[0.0], h.strain[:n_ok]]),
                                          np.concatenate([[h.rest["F"][cell]], F[:n_ok]]), p.C0,
                                          stored_at=_stitch_energy(h, cell, p.B))
    if "interpenetrating" in h.values:
        warnings += interpenetration(h.strain[:n_ok], h.values["interpenetrating"][:n_ok, cell],
                                     h.values["head_gap"][:n_ok, cell], p.d_jam, direction=h.direction[:n_ok])
    # W below 4 w: past the model's jamming limit (the head-gap criterion lets it happen after the heads touch)
    warnings += wale_spacing_below_jamming(h.strain[:n_ok], h.values["W"][:n_ok, cell],
                                           float(jam_width_floor(p.d_jam, p.effects)), direction=h.direction[:n_ok])
    return {
        "cell": cell, "label": label,
        "params": {k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v)
                   for k, v in p.as_dict().items()},
        "notes": notes or {},
        "rules": rules_of(p),
        "final_status": STATUS_NAMES[final],
        "end": end,
        "expected_end": expected,
        "stopped_at_strain": stop["stopped_at_strain"],
        "final_force_per_wale_N": float(F[n_ok - 1]) if n_ok else None,
        "last_converged_strain": stop["last_converged_strain"],
        "last_converged_force_per_wale_N": stop["last_converged_force_per_wale_N"],
        "status_counts": counts,
        "strain_at_first_jamming": jam_strain,
        "strain_at_first_jamming_from": jam_from,
        "cycles": cycles_out,
        "warnings": [w.as_dict() for w in warnings],
    }


def summarise(history: BatchHistory, labels: list[str] | None = None, notes: list[dict] | None = None,
              reference: BatchHistory | None = None, **info) -> dict:
    """The ``summary.json`` document: run information plus :func:`cell_summary` of each cell.

    ``reference``: the same cells pulled monotonically to the program's largest strain (:func:`first_loading`),
    for the check of a reload past the earlier maximum against the first loading's continuation."""
    labels = labels or [f"cell {i}" for i in range(history.n_cells)]
    notes = notes or [{} for _ in range(history.n_cells)]
    rows_of = SummaryRows(history)
    cells = [_cell_summary(history, i, labels[i], notes[i], first_loading_curve(reference, i), rows_of)
             for i in range(history.n_cells)]
    out = dict(info)
    out.update(n_cells=history.n_cells, n_increments=int(len(history.strain)),
               all_expected_end=all(c["expected_end"] for c in cells),
               warnings=[dict(w, cell=c["label"]) for c in cells for w in c["warnings"]], cells=cells)
    return out


def first_loading_curve(reference: BatchHistory | None, cell: int) -> tuple | None:
    """(strain, force per wale) of ``cell``'s monotonic pull in ``reference`` (:func:`first_loading`) up to where it
    stopped, the ``reference`` :func:`cell_summary` takes; None without one."""
    if reference is None:
        return None
    n = _stopped_rows(np.asarray(reference.status[:, cell]))
    return np.asarray(reference.strain[:n], float), np.asarray(reference.force_per_wale[:n, cell], float)


def first_loading_program(program):
    """The monotonic pull that is the reference of ``reload_below_first_loading`` (:func:`summarise`, ``knitsim
    run``): ``program``'s largest strain at its largest step, where the program loads past an earlier maximum
    after an unloading (:func:`knitsim.io.checks.needs_first_loading_reference`); else None."""
    from ..io.checks import needs_first_loading_reference
    if not needs_first_loading_reference(program.strain, program.direction):
        return None
    from ..cell.load_program import monotonic
    s = np.concatenate([[0.0], np.asarray(program.strain, float)])
    return monotonic(float(np.max(s)), float(np.max(np.abs(np.diff(s)))))


def first_loading(params, program, engine: str = "warp", device: str = "cpu") -> BatchHistory | None:
    """The cells pulled monotonically (:func:`first_loading_program`: the reference of :func:`summarise`), where
    the program loads past an earlier maximum after an unloading; else None."""
    pull = first_loading_program(program)
    if pull is None:
        return None
    from ..cell.engine import simulate
    return simulate(params, pull, engine=engine, device=device)


def summary_json(summary: dict) -> str:
    """``summary`` as JSON text (NaN -> null)."""
    return json_text(summary)


# --------------------------------------------------------------------- plot
_STAGE_COLOURS = {"adherence": "#1f77b4", "sliding": "#2ca02c", "jamming": "#d62728", "slack": "#7f7f7f"}


#: warnings printed under a cell plot (the rest counted: summary.json has them all)
PLOT_WARNINGS_SHOWN = 6


def warning_lines(warnings, width: int, shown: int | None = None, cell: bool = False) -> list[str]:
    """The lines a plot prints under its axes for a summary's ``warnings`` (dicts with a ``message``; with
    ``cell``, prefixed by their cell), wrapped at ``width``; past ``shown`` of them, a count (the cell and
    patch plots' one form: the figure never looks cleaner than the run)."""
    import textwrap
    warnings = list(warnings or [])
    lines = [ln for w in warnings[:shown]
             for ln in textwrap.wrap("warning: " + (f"{w['cell']}: " if cell and w.get("cell") else "")
                                     + w["message"], width)]
    if shown is not None and len(warnings) > shown:
        lines.append(f"... and {len(warnings) - shown} more warnings (summary.json)")
    return lines


def plot_png(history: BatchHistory, labels: list[str] | None = None, title: str = "",
             warnings: list | None = None) -> bytes:
    """PNG of force per wale vs strain: one line per cell, points coloured by stage, rules in the legend;
    ``warnings`` (the summary's, dicts with a ``message`` and the ``cell``) printed under the axes, as the
    patch plot does, so that the figure never looks cleaner than the run (a cell whose later cycles carry 8 %
    of the first was drawn without a word)."""
    import io
    import textwrap

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    h = history
    labels = labels or [f"cell {i}" for i in range(h.n_cells)]
    lines = warning_lines(warnings, 170, PLOT_WARNINGS_SHOWN, cell=h.n_cells > 1)
    extra = 0.15 * len(lines)
    fig = Figure(figsize=(11, 5.5 + extra), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    # the legend beside the axes, not on them (a blind probe's legend covered the loading branch)
    fig.subplots_adjust(left=0.07, right=0.62, top=1.0 - 0.77 / (5.5 + extra),
                        bottom=(0.6 + extra) / (5.5 + extra))
    if lines:
        fig.text(0.01, 0.01, "\n".join(lines), fontsize=6.5, color="#b22222", va="bottom", ha="left")
    codes = h.label_codes()
    F = h.force_per_wale
    handles = []
    stops = {"failed": [], "force_cap": [], "failed_at": [], "cut": []}
    for c in range(h.n_cells):
        n = _stopped_rows(h.status[:, c])
        eps = h.values["C"][:n, c] / h.params[c].C0 - 1.0
        f = F[:n, c]
        lab = codes[:n, c]
        if h.rest is not None:                     # the rest state (strain 0, its own force), the curve's start
            eps = np.concatenate([[0.0], eps])
            f = np.concatenate([[h.rest["F"][c]], f])
            lab = np.concatenate([[LABEL_CODES[stage_label(int(h.rest["stage"][c]), bool(h.rest["jammed"][c]))]],
                                  lab])
        (line,) = ax.plot(eps, f, lw=0.8, alpha=0.7)
        if c < 8:
            line.set_label(labels[c])
            handles.append(line)
        for name, code in LABEL_CODES.items():
            mask = lab == code
            if mask.any():
                ax.scatter(eps[mask], f[mask], s=6, color=_STAGE_COLOURS[name], zorder=3)
        final = int(h.status[-1, c])
        if final != STATUS_OK and n:
            kind = "force_cap" if final == STATUS_FORCE_CAP else "failed"
            stops[kind].append(labels[c])
            if kind == "failed":
                stops["failed_at"].append(float(eps[-1]))
            elif n < len(h.strain):
                stops["cut"].append(labels[c])
            ax.scatter([eps[-1]], [f[-1]], s=70, marker="X" if kind == "failed" else "v", zorder=4,
                       color="#d62728" if kind == "failed" else "#ff7f0e", edgecolors="black", linewidths=0.5)
    if h.n_cells > 8:
        handles.append(Line2D([], [], color="none", label=f"... {h.n_cells - 8} more cells"))
    for name, col in _STAGE_COLOURS.items():
        handles.append(Line2D([], [], ls="", marker="o", color=col, label=name))
    if stops["failed"]:
        handles.append(Line2D([], [], ls="", marker="X", color="#d62728", markeredgecolor="black",
                              label="FAILED here (no convergence): later rows not solved"))
    if stops["force_cap"]:
        handles.append(Line2D([], [], ls="", marker="v", color="#ff7f0e", markeredgecolor="black",
                              label="stopped at the force cap"))
    # the rule sets, each with its cells (a blind probe: three of five shown, none tied to a curve, and Dahl cells
    # labelled with the unloading and reload rules they do not use)
    sets: dict[str, list[str]] = {}
    for c, p in enumerate(h.params):
        sets.setdefault(_rules_label(p), []).append(labels[c])
    for text, cells in list(sets.items())[:RULE_SETS_SHOWN]:
        who = ", ".join(cells[:3]) + (f" and {len(cells) - 3} more" if len(cells) > 3 else "")
        handles.append(Line2D([], [], color="none", label=(f"{who}: {text}" if len(sets) > 1 else text)))
    if len(sets) > RULE_SETS_SHOWN:
        handles.append(Line2D([], [], color="none", label=f"... {len(sets) - RULE_SETS_SHOWN} more rule sets "
                                                           "(summary.json: each cell's rules)"))
    for hd in handles:
        hd.set_label("\n".join(textwrap.wrap(hd.get_label(), 60)))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.set_xlabel("strain of the course length, C/C0 - 1")
    ax.set_ylabel("force per wale [N]")
    title = title or "knitsim cell"
    if stops["failed"]:
        # where the user looks first: the run did not finish
        failed = stops["failed"]
        if len(failed) == 1:
            what = f"{failed[0]} stopped without converging at strain {stops['failed_at'][0]:.4g} (X)"
        else:
            what = f"{len(failed)} of {h.n_cells} cells stopped without converging (X)"
        title += f"\nFAILED: {what}; why: summary.json"
        ax.set_title(title, fontsize=10, color="#d62728")
    elif stops["cut"]:
        what = stops["cut"][0] if len(stops["cut"]) == 1 else f"{len(stops['cut'])} cells"
        ax.set_title(title + f"\n{what} stopped at the force cap (v) before the program's end: the rest not run",
                     fontsize=10, color="#b35900")
    else:
        ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# --------------------------------------------------------------- whole set
def write_cell_results(out_dir: str | Path, history: BatchHistory, summary: dict, resolved_toml: str,
                       labels: list[str] | None = None, plot: bool = True, title: str = "") -> dict[str, Path]:
    """Write the whole result set into ``out_dir``.

    The files are built in a hidden sibling directory, then stale outputs of
    an earlier run are removed from ``out_dir`` and the new files renamed in,
    ``summary.json`` last (its presence marks a complete set).

    Returns
    -------
    dict of str to Path
        The written files by name.
    """
    files = {"curve.csv": curve_csv(history).encode(), "events.csv": events_csv(history).encode(),
             "scene.resolved.toml": resolved_toml.encode()}
    if plot:
        files["plot.png"] = plot_png(history, labels, title, summary.get("warnings"))
    files["summary.json"] = summary_json(summary).encode()
    return write_result_set(out_dir, files, OUTPUT_FILES)


def write_result_set(out_dir: str | Path, files: dict[str, bytes], known_outputs) -> dict[str, Path]:
    """Write a set of result files atomically, ``summary.json`` last.

    The files are written into a hidden sibling directory, then the stale
    ``known_outputs`` of an earlier run are removed from ``out_dir`` (summary
    first: the set is incomplete from there) and the new files renamed in, in
    the order given (summary.json last: its presence marks a complete set).

    Returns
    -------
    dict of str to Path
        The written files by name.
    """
    out = check_output_dir(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        for name, data in files.items():
            (tmp / name).write_bytes(data)
        ours = set(recorded_outputs(out))         # an earlier run's outputs; a user's file of that name stays
        record_outputs(out, list(known_outputs) + [n for n in files if n not in known_outputs])
        for name in reversed(tuple(known_outputs)):
            if name in ours:
                (out / name).unlink(missing_ok=True)
        for name in files:
            os.replace(tmp / name, out / name)
        stamp_outputs(out, files)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {name: out / name for name in files}


def run_info(scene, device: str, wall_s: float) -> dict:
    """Run information for the summary."""
    from .. import __version__
    return {"knitsim_version": __version__, "scene": scene.source, "title": scene.resolved.get("title", ""),
            "engine": scene.engine, "device": device, "load": scene.resolved["load"],
            "wall_s": wall_s, "written_at": time.strftime("%Y-%m-%dT%H:%M:%S")}
