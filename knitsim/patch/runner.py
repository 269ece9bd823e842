"""Run a patch through a grip-strain program, with progress, checkpoints and resume.

:func:`run_patch` solves each grip increment with
:class:`~knitsim.patch.coupling.PatchSolver` and records, per increment, the
grip force, the column forces and flags, and the per-cell fields (strain of
the course length, stage label, phi, force, status) and, per group of
identical cells, the state x = (alpha, beta, gamma, phi, P) with W and s_AB,
from which the yarn geometry is rebuilt (:mod:`knitsim.usd.from_results`).  With ``checkpoint``
set, the solver state and the rows so far are written atomically every
``checkpoint_every`` increments, when the run is interrupted by Ctrl-C, and once
more when the program is finished (so that the outputs written after the solve
can be written again from it: a resume of a finished solve solves nothing);
``resume=True`` continues from that file and gives the same results as an
uninterrupted run (the state is restored bit for bit).  A checkpoint is refused
on another device than its own (devices differ in rounding: a run continued on
another one would mix the two).

The file holds two pickles: a small header (:func:`read_checkpoint_header`: fingerprint, increments
done of how many, device, the caller's ``meta``, the chunks that hold the rows) and the body (the solver
state), so that a command can say what a checkpoint holds without reading the rows.  The rows are written
once, in chunks beside it (:mod:`knitsim.patch.records`: ``checkpoint_rows/000050-000100.npz``, the rows of
one checkpoint interval each); before, every checkpoint pickled every finished row again (a 300 x 300 random
patch's 7 saves took 31 s of its run on a GPU host, 4.4 s each, the pickle reaching 2.5 GB).  A checkpoint of
an older knitsim (the rows inside its pickle) still resumes; its next save writes them into chunks.
"""
from __future__ import annotations

import hashlib
import pickle
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..cell.history import STATUS_OK, head_gap_values
from ..cell.load_program import LoadProgram
from ..cell.stages import stage_label_codes
from ..errors import KnitsimInputError
from .coupling import COL_OK, PatchSolver
from .model import PatchModel
from .records import (RunRecords, chunk_problem, read_chunks, remove_rows_dir, remove_stray_chunks, rows_dir_of,
                      write_chunk)

CHECKPOINT_NAME = "checkpoint.pkl"
#: the folder of the checkpoint's rows, beside it (:func:`knitsim.patch.records.rows_dir_of`)
CHECKPOINT_ROWS_NAME = rows_dir_of(CHECKPOINT_NAME).name
_ROW_KEYS = ("force_N", "force_per_wale_N", "column_force_N", "column_status", "column_iterations", "column_slack_mm",
             "g_C", "g_F", "g_phi", "g_label", "g_status", "g_x", "g_W", "g_s_AB", "g_head_gap")
#: per-group geometry rows (checkpoints written before they existed lack them)
_GEOMETRY_KEYS = ("g_x", "g_W", "g_s_AB", "g_head_gap")
#: bytes a run keeps per group and increment: the g_ rows (C, F, phi, W, s_AB, head gap and the state x's five
#: values in float64; the stage label and status in int8)
RECORD_BYTES_PER_GROUP = 11 * 8 + 2 * 1
#: copies of those records a run holds at its peak, cells.nc aside: the rows (written in place, one array per
#: key; a checkpoint writes them into its chunk files, no copy) and what the summary and the plots derive from
#: them after the solve.  Measured (tracemalloc, a 60 x 60 random patch through 3 cycles: 3600 groups x 310
#: increments, 100 MB of records): 1.2 copies in the solve, 1.6 in the plots.  (It was 3 while the solve held
#: 3.2: the rows' lists, the arrays stacked from them at the end and a checkpoint's pickle of the rows.)
RECORD_COPIES = 2
#: more copies where cells.nc is written (``output.cell_fields``): its per-cell fields and their netCDF
#: encoding, held in memory, are the peak of the run: 3.0 copies in all measured on a 100 x 100 random patch
#: (3.3 on the 60 x 60 one, whose fixed costs weigh more)
CELL_FIELDS_COPIES = 1


#: bytes a patch scene holds per cell (of the courses x wales grid) from its loading to the end of its run, its
#: records aside: the per-cell parameter arrays, their origins and rules (object arrays), the grouping of
#: identical cells and what the outputs derive from them.  Measured (peak resident set, less the 0.1 GB of the
#: imports): a uniform 1000 x 1000 patch through 6 increments (records negligible), 1.7 GB for its 10^6 cells
#: (load_patch_scene alone, uniform or random phi0: 1.06 GB; with the grouping 1.27-1.39 GB; 2000 x 2000, 4.3 GB
#: and 5.1 GB).  A 7000 x 7000 patch (49 million cells, under the 50 million cap) was killed for memory while its
#: scene loaded, at 24 GB, without a word (a blind probe)
SCENE_BYTES_PER_CELL = 1700


def scene_memory_bytes(n_cells: int) -> int:
    """The memory a patch of ``n_cells`` cells needs for its per-cell scene [bytes], its records aside
    (:data:`SCENE_BYTES_PER_CELL`; :func:`record_memory_bytes` counts the records)."""
    return int(n_cells) * SCENE_BYTES_PER_CELL


def record_memory_bytes(n_groups: int, n_increments: int, cell_fields: bool = True,
                        cells_increments: int | None = None) -> int:
    """The memory a run of ``n_groups`` groups through ``n_increments`` increments needs at its peak for its
    per-group records [bytes] (:data:`RECORD_BYTES_PER_GROUP`, :data:`RECORD_COPIES` and, with ``cell_fields``
    (cells.nc written), :data:`CELL_FIELDS_COPIES` more of the ``cells_increments`` increments cells.nc holds,
    default all: ``output.cells_stride`` writes fewer): a 1000 x 1000 random patch through the paper's 620
    increments, 167 GB (112 GB without cells.nc); the paper's specimen with random phi0, 0.42 GB."""
    cells = int(n_increments) if cells_increments is None else int(cells_increments)
    rows = RECORD_COPIES * int(n_increments) + (CELL_FIELDS_COPIES * cells if cell_fields else 0)
    return rows * RECORD_BYTES_PER_GROUP * int(n_groups)


def available_memory_bytes() -> int | None:
    """The memory this machine can give a process now [bytes]: /proc/meminfo's MemAvailable (Linux), else the free
    physical pages; None where neither is known."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import os
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


class PatchInterrupted(Exception):
    """The run stopped before the end of the program (``stop_after``); the checkpoint holds its work."""

    def __init__(self, done: int, path: Path | None):
        super().__init__(f"stopped after {done} increments; checkpoint {path}")
        self.done, self.path = done, path


@dataclass
class PatchHistory:
    """One row per grip increment.

    Attributes
    ----------
    grip_strain, cycle, direction : ndarray, shape [n]
        Imposed grip strain (grip displacement / column rest length), cycle (from 1), +1/-1.
    force_N, force_per_wale_N : ndarray, shape [n]
        Grip force, sum of the columns' total forces [N], and that force per wale (mean column force;
        for cells that stand for blocks of stitches, the grip force over the columns' mean wale counts).
    column_force_N, column_slack_mm : ndarray, shape [n, wales]
        Force per wale of each column [N] (a strip's total force over its mean wale count); length left
        over by the grips in a slack column [mm].
    column_status, column_iterations : ndarray of int, shape [n, wales]
        :data:`~knitsim.patch.coupling.COLUMN_STATUS_NAMES` code; trial steps of the increment.
    group_of_cell : ndarray of int, shape [courses, wales]
    groups : dict of str to ndarray, shape [n, n_groups]
        Per group: ``C`` [mm], ``F`` [N], ``phi`` [rad], ``label`` (stage label code), ``status``;
        and, for the geometry, ``x`` (shape [n, n_groups, 5]: alpha, beta, gamma, phi [rad], P [N]),
        ``W``, ``s_AB`` and ``head_gap`` [mm] with ``interpenetrating`` (1 where the heads of
        neighbouring loops overlap) (absent when resumed from a checkpoint that predates them).
    C0 : ndarray, shape [courses, wales]
    group_d_jam : ndarray, shape [n_groups]
        In-plane width of each group [mm] (the interpenetration threshold).
    rest_force_N, rest_force_per_wale_N : float
        Grip force and force per wale of the rest state, before the first increment (the model's
        rest force is not zero; a column's is the mean of its cells').
    group_rest : dict of str to ndarray, optional
        Per group, its rest state before the first increment: ``C`` [mm] and ``F`` [N], shape [n_groups],
        ``x`` (shape [n_groups, 5], as ``groups["x"]``), ``W`` and ``s_AB`` [mm], the stage ``label`` (as
        ``groups["label"]``) and the group's bending stiffness ``B`` [N mm^2].
    wall_s : float
        Seconds spent solving (this run plus the runs it resumed).
    """

    grip_strain: np.ndarray
    cycle: np.ndarray
    direction: np.ndarray
    force_N: np.ndarray
    force_per_wale_N: np.ndarray
    column_force_N: np.ndarray
    column_status: np.ndarray
    column_iterations: np.ndarray
    column_slack_mm: np.ndarray
    group_of_cell: np.ndarray
    groups: dict
    C0: np.ndarray
    wall_s: float = 0.0
    info: dict = field(default_factory=dict)
    group_d_jam: np.ndarray | None = None
    rest_force_N: float = 0.0
    rest_force_per_wale_N: float = 0.0
    group_rest: dict | None = None

    @property
    def n_increments(self) -> int:
        """Grip increments recorded (rows)."""
        return len(self.grip_strain)

    @property
    def shape(self) -> tuple[int, int]:
        """(courses, wales) of the patch."""
        return tuple(self.group_of_cell.shape)

    def cell_field(self, name: str) -> np.ndarray:
        """A per-cell field over time, shape [n, courses, wales]: ``strain`` ((C - C0)/C0),
        ``C``, ``F``, ``phi``, ``label``, ``status``, ``W``, ``s_AB`` or ``x`` (shape [n, courses, wales, 5])."""
        if name == "strain":
            return self.groups["C"][:, self.group_of_cell] / self.C0[None] - 1.0
        return self.groups[name][:, self.group_of_cell]


def fingerprint(model: PatchModel, program: LoadProgram, **options) -> str:
    """Hash of everything that determines the results (checked on resume): the model, the program and the
    ``options`` (engine, dedup, the device that solves, the solver's options)."""
    h = hashlib.sha256()
    h.update(repr((model.courses, model.wales, sorted(options.items()))).encode())
    for r in sorted(model.rules):
        h.update(repr((r, model.rules[r].tolist())).encode())
    # the distinct effect sets and which cell holds which (every cell's as_dict() cost 50 us a cell)
    codes, uniq = model.effect_codes()
    h.update(repr([e.as_dict() for e in uniq]).encode())
    h.update(np.ascontiguousarray(codes).tobytes())
    for n in sorted(model.fields):
        h.update(n.encode())
        h.update(np.ascontiguousarray(model.fields[n]).tobytes())
    if not model.unit_counts or model.gauge_length is not None:
        # blocks of stitches (a specimen); a patch of single stitches hashes as it always did
        h.update(repr(model.gauge_length).encode())
        h.update(np.ascontiguousarray(model.course_count).tobytes())
        h.update(np.ascontiguousarray(model.wale_count).tobytes())
        if model.pretension:
            h.update(repr(("pretension", model.pretension)).encode())
    for a in (program.strain, program.cycle, program.direction):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _committed_geometry(backend, committed: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Committed per-group state x [n_groups, 5], W and s_AB [n_groups] of either backend (from its
    ``committed`` read where that holds them: WarpBackend's packed read)."""
    if committed is not None and "x" in committed:
        return committed["x"], committed["W"], committed["s_AB"]
    from ..cell.quantities import CODE
    s0 = backend.s0
    if hasattr(s0, "x"):                        # WarpBackend: a CellBatchState of device arrays
        # the two columns of q, not the whole table (20 values a cell: 0.8 s of a 10^6-cell patch's 5
        # increments on the H200, copied to the host for two of them)
        return (s0.x.numpy().copy(), np.array(s0.q[:, CODE["W"]].numpy(), dtype=np.float64),
                np.array(s0.q[:, CODE["s_AB"]].numpy(), dtype=np.float64))
    return (np.array([np.asarray(s.x, dtype=float) for s in s0]),   # ReferenceBackend: CellStates
            np.array([float(s.q["W"]) for s in s0]), np.array([float(s.q["s_AB"]) for s in s0]))


def _atomic_pickle(path: Path, *objs) -> None:
    """``objs`` pickled one after the other into one file, written atomically."""
    from ..io.results import atomic_write_bytes, record_outputs
    record_outputs(path.parent, [path.name])         # knitsim's to replace with --overwrite (io.output_dir)
    atomic_write_bytes(path, b"".join(pickle.dumps(o, protocol=pickle.HIGHEST_PROTOCOL) for o in objs))


#: header keys of a checkpoint (:func:`read_checkpoint_header`); 3: the rows in chunk files beside it (the
#: header's ``chunks``), no longer in its body
CHECKPOINT_FORMAT = 3


def read_checkpoint_header(path: str | Path) -> dict:
    """What a checkpoint holds, without its rows: ``done`` (increments solved), ``total`` (the program's
    increments; None in a checkpoint of an older knitsim), ``fingerprint``, ``engine``, ``device`` (None where
    older), ``wall_s``, ``meta`` (what the caller stored, e.g. the command that resumes; {} where none) and,
    from format 3 on, ``chunks``: the files of its rows (:mod:`knitsim.patch.records`; absent where older: the
    rows are in its body).

    Raises whatever unpickling raises on a damaged file."""
    with open(path, "rb") as fh:
        head = pickle.load(fh)
    if not isinstance(head, dict) or "done" not in head:
        raise ValueError("not a knitsim patch checkpoint")
    if "rows" in head:                                  # an older checkpoint: one pickle, no header
        head = {k: v for k, v in head.items() if k not in ("rows", "solver")}
    head.setdefault("total", None)
    head.setdefault("device", None)
    head.setdefault("engine", None)
    head.setdefault("meta", {})
    return head


def _read_checkpoint(path: Path) -> tuple[dict, dict]:
    """(header, body) of a checkpoint file, any format (its rows are in the body before format 3)."""
    with open(path, "rb") as fh:
        head = pickle.load(fh)
        if isinstance(head, dict) and "rows" in head:   # older: one pickle
            return read_checkpoint_header(path), head
        body = pickle.load(fh)
    return head, body


def _rows_of_older_checkpoint(ck: Path, saved_rows, done: int, rows: RunRecords) -> None:
    """Rows ``0 .. done - 1`` of a checkpoint of an older knitsim (format 2 and before: its body's ``rows``, a
    list of per-increment rows per key) into ``rows``.  Geometry rows that it lacks, or holds for fewer
    increments (a checkpoint that predates them, resumed by a knitsim that recorded them), are left out."""
    if not isinstance(saved_rows, dict):
        raise KnitsimInputError(f"--resume: {ck} is not a readable checkpoint (no rows)")
    for k in _ROW_KEYS:
        v = saved_rows.get(k, [])
        if len(v) != done:
            if k in _GEOMETRY_KEYS:
                continue
            raise KnitsimInputError(f"--resume: {ck} is not a readable checkpoint ({k}: {len(v)} rows of {done})")
        for i, row in enumerate(v):
            rows.put(i, k, row)


def remove_checkpoint(ck: str | Path) -> None:
    """Remove the checkpoint ``ck`` and its rows (:func:`knitsim.patch.records.remove_rows_dir`): the pickle
    first (chunks without it are no checkpoint), then the chunks and their folder."""
    ck = Path(ck)
    ck.unlink(missing_ok=True)
    remove_rows_dir(ck)


def device_identity(engine: str, device) -> str:
    """The device that solves, as far as it changes the rounding of the results: ``cpu``, or a CUDA device's
    name and architecture (two cards of one model give the same results; the reference engine is NumPy)."""
    if engine != "warp":
        return "cpu (reference engine, NumPy)"
    name = str(device)
    if name.startswith("cuda"):
        try:
            import warp as wp
            d = wp.get_device(name)
            return f"cuda ({d.name}, sm_{d.arch})"
        except Exception:  # noqa: BLE001 - no CUDA here: the alias is all there is to say
            return name
    return "cpu"


def _check_solver_options(options: dict) -> None:
    """Refuse a keyword PatchSolver does not take, naming it (a blind probe's tol=1e-3 raised TypeError)."""
    import inspect
    known = set(inspect.signature(PatchSolver.__init__).parameters) - {"self", "grouping", "engine", "device"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise KnitsimInputError(f"{unknown[0]} = {options[unknown[0]]!r}: not a solver option of run_patch "
                                f"(expected one of {', '.join(sorted(known))})")


def run_patch(model: PatchModel, program: LoadProgram, engine: str = "warp", device: str = "cpu",
              dedup: bool = True, progress: Callable[[int, int], None] | None = None,
              checkpoint: str | Path | None = None, checkpoint_every: int = 50, resume: bool = False,
              stop_after: int | None = None, checkpoint_meta: dict | None = None,
              **solver_options) -> PatchHistory:
    """Run a patch through a grip-strain program.

    Parameters
    ----------
    model : PatchModel
    program : LoadProgram
        Grip strains (grip displacement / column rest length).
    engine : {"warp", "reference"}
    device : str
        Warp device (warp engine).
    dedup : bool
        Solve identical cells once (exact; see :meth:`PatchModel.grouping`).
    progress : callable, optional
        ``progress(done, total)`` after each increment.
    checkpoint : path, optional
        Checkpoint file (``OUT/checkpoint.pkl``; its rows in chunks in ``OUT/checkpoint_rows``, see
        :mod:`knitsim.patch.records`); None: no checkpoints.
    checkpoint_every : int
        Increments between checkpoints (0: none in between; with ``checkpoint`` set, the finished solve and
        a Ctrl-C are still checkpointed).
    resume : bool
        Continue from ``checkpoint`` (refused if it belongs to another scene, options or device, or where a
        chunk of its rows is missing, cut short or not its own).  A checkpoint of a finished solve gives its
        history without solving.  One of an older knitsim, its rows inside its pickle, resumes too.
    stop_after : int, optional
        Stop (with a checkpoint) after this many increments: raises :class:`PatchInterrupted`.
    checkpoint_meta : dict, optional
        Stored in the checkpoint's header (:func:`read_checkpoint_header`), e.g. the command that resumes.
    **solver_options
        Passed to :class:`~knitsim.patch.coupling.PatchSolver`.

    Returns
    -------
    PatchHistory
    """
    if not isinstance(program, LoadProgram) or len(program) == 0:
        raise KnitsimInputError(f"program = {program!r}: expected a non-empty LoadProgram")
    grouping = model.grouping(dedup)
    _check_solver_options(solver_options)
    solver = PatchSolver(grouping, engine, device, **solver_options)
    # the rest state (before any increment, and before a resume restores a later one)
    group_rest = {k: np.asarray(solver.cells[k], float).copy() for k in ("C", "F")}
    # its angles and P, and each group's B: the stored bending energy of the rest state (the energy check of
    # knitsim.io.patch_results judges loops that start on a loading with it)
    group_rest["x"], group_rest["W"], group_rest["s_AB"] = _committed_geometry(solver.backend)
    group_rest["B"] = np.asarray(grouping.cells["B"], float).copy()
    # its stage label (the USD export draws the rest state as time code 0, coloured by stage)
    group_rest["label"] = stage_label_codes(solver.cells["stage"], solver.cells["jammed"]).astype(np.int8)
    cnt = grouping.group_count.astype(float)
    n_cls = grouping.n_classes
    pw = np.asarray(grouping.group_wales, float)
    # each column's total rest force (its cells' p f, n-weighted), and the wales it holds
    col_rest = (np.bincount(grouping.group_column, weights=cnt * pw * solver.cells["F"], minlength=n_cls)
                / np.bincount(grouping.group_column, weights=cnt, minlength=n_cls))[grouping.column_class]
    col_wales = np.asarray(grouping.class_wales, float)[grouping.column_class]
    single_stitches = bool(np.all(col_wales == 1.0))
    n = len(program)
    dev_id = device_identity(engine, getattr(solver.backend, "device", device))
    ck = Path(checkpoint) if checkpoint is not None else None
    # (only a checkpoint needs it: hashing a 10^6-cell patch's fields and rules took 0.3 s)
    fp = _run_fingerprint(model, program, engine, dev_id, dedup, solver_options) if ck is not None else None
    # the rows, written in place into one array per key (no list of rows stacked at the end: a second copy)
    rows = RunRecords(n)
    # (a checkpoint of an older knitsim may lack the geometry rows: then none are recorded)
    geometry = True
    # the chunks the checkpoint lists, and the rows they hold (0 .. written - 1)
    chunks: list = []
    written = 0
    start, wall_before = 0, 0.0
    if resume:
        if ck is None:
            raise KnitsimInputError("--resume: no checkpoint file given (needs --out DIR)")
        if ck.is_file():
            try:
                head, saved = _read_checkpoint(ck)
            except Exception as exc:  # noqa: BLE001 - a damaged file is a user-level problem
                raise KnitsimInputError(f"--resume: {ck} is not a readable checkpoint ({exc})") from None
            if head.get("fingerprint") != fp:
                raise KnitsimInputError(_resume_mismatch(ck, head, engine, dev_id))
            start, wall_before = int(head["done"]), float(head["wall_s"])
            if "chunks" in head:
                read_chunks(ck, head["chunks"], start, fp, rows)
                chunks, written = list(head["chunks"]), start
            else:
                # an older checkpoint: its rows in its body, lists of per-increment rows (written into chunks,
                # all of them, by this run's first save)
                _rows_of_older_checkpoint(ck, saved.get("rows"), start, rows)
            geometry = all(k in rows.arrays for k in _GEOMETRY_KEYS)
            rows.drop(() if geometry else _GEOMETRY_KEYS)
            solver.set_state(saved["solver"])
    wales = model.wales
    cls = grouping.column_class

    def save(done: int, wall: float) -> None:
        nonlocal chunks, written
        if ck is None:
            return
        from ..io.results import record_outputs
        ck.parent.mkdir(parents=True, exist_ok=True)
        # knitsim's to replace with --overwrite (io.output_dir), recorded before they are written
        record_outputs(ck.parent, [ck.name, rows_dir_of(ck).name + "/"])
        # the rows since the last save, written once (the checkpoint lists them only once they are whole)
        listed = chunks + ([write_chunk(rows_dir_of(ck), rows, written, done, fp)] if done > written else [])
        _atomic_pickle(ck, {"format": CHECKPOINT_FORMAT, "fingerprint": fp, "done": done, "total": n,
                            "engine": engine, "device": dev_id, "wall_s": wall,
                            "meta": dict(checkpoint_meta or {}), "chunks": listed},
                       {"solver": solver.get_state()})
        chunks, written = listed, done
        remove_stray_chunks(ck, chunks)

    t0 = time.perf_counter()
    i = start
    # A checkpoint must hold the state between two increments: the solver updates its tangents and branch
    # history during an increment, and a state saved halfway would resume onto another trial path. So a
    # Ctrl-C during an increment lets it finish (a second one stops at once, keeping the last checkpoint).
    clean, stop = [True], []

    def on_sigint(signum, frame):
        if stop or clean[0]:
            raise KeyboardInterrupt
        stop.append(signum)
        # said at once: an increment can take minutes (the reference engine, a large patch), and a Ctrl-C that
        # said nothing until it ended read as a hang
        import sys
        print(f"knitsim: interrupted: increment {i + 1} of {n} finishes first, then the checkpoint is written; "
              f"interrupt again to stop at once, keeping the last checkpoint (increment {written})",
              file=sys.stderr, flush=True)

    old_handler = None
    if ck is not None and threading.current_thread() is threading.main_thread():
        old_handler = signal.signal(signal.SIGINT, on_sigint)
    filled = start                                     # rows recorded
    try:
        for i in range(start, n):
            clean[0] = False
            r = solver.step(float(program.strain[i]), int(program.direction[i]), i)
            c = r.cells
            colT = r.column_force[cls]                 # total force of each column (strip)
            rows.put(i, "force_N", float(np.sum(colT)))
            if single_stitches:
                colF = colT
                # equal column forces: the force per wale is that force exactly (a sum / wales would round)
                rows.put(i, "force_per_wale_N", float(colF[0]) if np.all(colF == colF[0]) else float(np.mean(colF)))
            else:
                colF = colT / col_wales                # a strip's force per wale (its mean wale count)
                rows.put(i, "force_per_wale_N", float(np.sum(colT) / np.sum(col_wales)))
            rows.put(i, "column_force_N", colF)
            rows.put(i, "column_status", r.column_status[cls])
            rows.put(i, "column_iterations", r.iterations[cls])
            rows.put(i, "column_slack_mm", r.column_slack[cls])
            rows.put(i, "g_C", c["C"])
            rows.put(i, "g_F", c["F"])
            rows.put(i, "g_phi", c["phi"])
            rows.put(i, "g_label", stage_label_codes(c["stage"], c["jammed"]).astype(np.int8))
            rows.put(i, "g_status", c["status"].astype(np.int8))
            if geometry:
                gx, gW, gs = _committed_geometry(solver.backend, c)
                rows.put(i, "g_x", gx)
                rows.put(i, "g_W", gW)
                rows.put(i, "g_s_AB", gs)
                rows.put(i, "g_head_gap", c["head_gap"])
            filled = i + 1
            clean[0] = True
            if stop:
                raise KeyboardInterrupt
            if progress is not None:
                progress(i + 1, n)
            done = i + 1
            if ck is not None and checkpoint_every > 0 and done % checkpoint_every == 0 and done < n:
                save(done, wall_before + time.perf_counter() - t0)
            if stop_after is not None and done >= stop_after and done < n:
                save(done, wall_before + time.perf_counter() - t0)
                raise PatchInterrupted(done, ck)
        wall = wall_before + time.perf_counter() - t0
        if ck is not None and start < n:
            # the finished solve, before the caller writes its outputs: a Ctrl-C there loses no solving
            # (a resume of it builds the history without solving again)
            save(n, wall)
    except KeyboardInterrupt:
        if clean[0] and filled > start:
            save(filled, wall_before + time.perf_counter() - t0)
        raise
    finally:
        if old_handler is not None:
            signal.signal(signal.SIGINT, old_handler)
    # every row is recorded (the loop ran to the end of the program): the arrays as they are
    arr = rows.arrays
    groups = {"C": arr["g_C"], "F": arr["g_F"], "phi": arr["g_phi"], "label": arr["g_label"],
              "status": arr["g_status"]}
    if all(k in arr for k in _GEOMETRY_KEYS):
        groups.update(x=arr["g_x"], W=arr["g_W"], s_AB=arr["g_s_AB"])
        # the interpenetration check of every committed state (knitsim.cell.history.HEAD_GAP_QUANTITIES)
        groups.update(head_gap_values(arr["g_head_gap"], grouping.d_jam))
    C0 = model.fields["C0"]
    info = {"engine": engine, "device": getattr(solver.backend, "device", "cpu"), "dedup": bool(dedup),
            "wales_represented": float(np.sum(col_wales)),
            "n_groups": grouping.n_groups, "n_column_classes": grouping.n_classes,
            "ref_length_mm": solver.ref_length, "resumed_from": start,
            "rest_grip_strain": 0.0 - model.grip_offset,  # 0.0 - : no "-0.0" without pretension
            "pretension": model.pretension,
            "trial_steps": int(arr["column_iterations"].max(axis=1).sum()) if n else 0}
    # grip strain from the tester's origin (a pretensioned specimen: negative while it is pretensioned)
    grip = np.asarray(program.strain) - model.grip_offset if model.pretension else np.asarray(program.strain)
    return PatchHistory(grip, np.asarray(program.cycle), np.asarray(program.direction),
                        arr["force_N"], arr["force_per_wale_N"], arr["column_force_N"], arr["column_status"], arr["column_iterations"],
                        arr["column_slack_mm"], grouping.group_of_cell, groups, C0, wall, info,
                        grouping.d_jam, float(np.sum(col_rest)),
                        float(np.mean(col_rest)) if single_stitches else float(np.sum(col_rest) / np.sum(col_wales)),
                        group_rest)


def _run_fingerprint(model, program, engine: str, dev_id: str, dedup: bool, solver_options: dict) -> str:
    """The fingerprint a run's checkpoint carries: the device is part of what determines the results
    (rounding); the reference engine runs on none."""
    return fingerprint(model, program, engine=engine, dedup=bool(dedup),
                       **({"device": dev_id} if engine == "warp" else {}), **solver_options)


def resume_refusal(ck: str | Path, head: dict, model: PatchModel, program: LoadProgram, engine: str = "warp",
                   device: str = "cpu", dedup: bool = True, changes: str | None = None, **solver_options) -> str:
    """Why the checkpoint ``ck`` (its header ``head``, :func:`read_checkpoint_header`) cannot be resumed by a run
    of ``model`` and ``program`` (another scene, map, library, program, engine, device or solver option), or
    ``""`` where it can: what :func:`run_patch` refuses, asked before any work (a blind probe's ``knitsim run
    --resume`` said "resuming from ..." and then refused).  So is a chunk of its rows that is missing, or of
    another size than written (:func:`knitsim.patch.records.chunk_problem`).  ``changes``: what changed in the
    scene, in words (:func:`knitsim.cli.run.scene_changes`), said where the scene is the reason."""
    dev_id = device_identity(engine, device)
    if head.get("fingerprint") != _run_fingerprint(model, program, engine, dev_id, dedup, solver_options):
        return _resume_mismatch(Path(ck), head, engine, dev_id, changes)
    # its rows: every chunk file there, of the size it was written with (their contents are checked as the
    # run reads them)
    return chunk_problem(Path(ck), head["chunks"], int(head["done"])) if "chunks" in head else ""


def _resume_mismatch(ck: Path, head: dict, engine: str, dev_id: str, changes: str | None = None) -> str:
    """Why a checkpoint does not fit this run (one line): its device, its engine, or the scene."""
    saved_dev, saved_engine = head.get("device"), head.get("engine")
    if saved_engine is not None and saved_engine != engine:
        return (f"--resume: {ck} was computed by the {saved_engine} engine, this run uses {engine}: resume with "
                f"--engine {saved_engine}, or run again without --resume")
    if saved_dev is not None and saved_dev != dev_id:
        alias = "cpu" if saved_dev.startswith("cpu") else "cuda"
        return (f"--resume: {ck} was computed on {saved_dev}, this run is on {dev_id}: devices differ in rounding "
                f"and a run continued on another one would mix the two; resume with --device {alias} (on a "
                f"machine with that device), or run again without --resume")
    if saved_dev is None and engine == "warp":
        return (f"--resume: {ck} was written by an older knitsim that did not record its device (or belongs to "
                "another scene, program or engine): it cannot be resumed safely; run again without --resume "
                "(--overwrite)")
    # (before: "remove it or run without --resume", and a plain run into that --out is refused: it holds results)
    what = changes or ("the scene, or a file it names: a map, a material library, changed since it was written")
    return (f"--resume: {ck} belongs to another scene, program or engine ({what}); resume with the scene it was "
            "written with, or start again with --overwrite (or another --out)")


def all_ok(history: PatchHistory) -> bool:
    """Whether every column converged at every increment and every cell ended ok."""
    return bool(np.all(history.column_status == COL_OK) and np.all(history.groups["status"] == STATUS_OK))
