"""Run a parameter sweep of cell scenes: plan, chunks, execution, assembly.

The sweep is a batch axis, not a Python loop: every sample's cells go into one
list of :class:`~knitsim.cell.material.CellParams`, split into chunks of
``chunk_size`` samples, and each chunk is ONE call of
:func:`knitsim.cell.engine.simulate` (one batched Warp run of all its cells).
Samples whose load program differs (a swept ``load.*`` key) are grouped by
program first; a chunk never mixes programs.

Output directory ``OUT``::

    OUT/sweep.json                 manifest: spec, hash, base scene, samples, chunks, versions
    OUT/chunks/chunk_NNNNN.npz     one per chunk, written atomically by whoever ran it
    OUT/results.nc                 xarray Dataset (netCDF3 through SciPy)
    OUT/results.csv                one row per sample, cell and cycle
    OUT/plot_*.png                 (knitsim.sweep.plots)
    OUT/summary.json               the run's figures, each kind of flag counted and its first SUMMARY_LISTED
                                   sample cells listed with their reason (:func:`sweep_summary`; also
                                   :attr:`SweepRun.summary`)

A chunk file is written through a temporary sibling and a rename, by the
process that computed it (in-process, or the Dask worker), so a run that is
killed keeps every finished chunk; ``resume=True`` re-reads the manifest,
refuses a different sweep and computes only the chunks whose file is missing.
What "different" means is :func:`sweep_inputs`: everything that determines the
results, as resolved (every sample's cells after the material library and the
defaults are read, the load programs), the spec, the scene, the engine, the
device and the knitsim version; so a library edited between the run and its
resume is refused, naming the values that changed (the scene only names it).
Results do not depend on the order chunks finish in, nor on the backend.

Per cell and cycle the results are those of
:func:`knitsim.io.results.cell_summary` (one definition of each quantity):
peak force per wale and the imposed strain where it occurs, residual strain,
energy per cycle with what that energy is (``energy_kind``: hysteresis, work,
loading_work; ``closed``) and whether the peak is the force cap
(``peak_at_force_cap``); per cell the strain at the first jamming, the final
status, where it stopped, and ``loop_creates_energy``: 1 where the cell summary carries that warning
(:func:`knitsim.io.checks.energy_creating_loops`: a closed loop with ``oint F dC < 0``), 0 where it
does not, -1 where the cell was not solved.  With ``curves`` the force per wale at every increment
is kept too.

Execution backends: ``workers=0`` runs chunks in this process; otherwise a
Dask ``LocalCluster`` with ``workers`` single-threaded worker processes
(default one per core: Warp's CPU backend runs a launch on one thread), or the
existing Dask cluster at ``scheduler`` (its workers need knitsim installed and
``OUT`` on a shared file system).  Each worker process initialises Warp once
and loads the compiled kernels from the shared on-disk cache.
"""
from __future__ import annotations

import contextlib
import copy
import csv
import hashlib
import io
import json
import logging
import os
import platform
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import KnitsimInputError
from ..io import checks
from ..io.jsonable import json_text
from ..io.results import atomic_write_bytes, atomic_write_text, cell_summary, check_output_dir, record_outputs
from ..scene.cell_scene import CELL_SCENE, load_cell_scene
from ..scene.schema import field_at, flat_keys, fmt, key_changes, load_toml, set_value
from .spec import SweepSpec, canonical_json, parse_sweep, split_scene

MANIFEST = "sweep.json"
CHUNK_DIR = "chunks"
#: every name a sweep writes into its --out (recorded there: --overwrite removes these and nothing else)
SWEEP_OUTPUTS = (MANIFEST, f"{CHUNK_DIR}/", "results.nc", ".results.nc.tmp", "results.csv", "plot_sweep.png",
                 "summary.json")
FORMAT = "knitsim-sweep/4"
#: per cell and cycle
CYCLE_VARS = ("peak_force_per_wale_N", "strain_at_peak", "residual_strain", "energy_N_mm", "energy_N_per_strain")
#: per cell and cycle, integer codes (-1 where the cycle has no results): what its energy is
#: (:data:`ENERGY_KINDS`, knitsim.io.checks.cycle_work), whether its path is closed, and whether its peak is
#: the force cap (the cycle a cell stopped in at its cap).  A blind probe's stops at the 10 N cap were drawn and
#: tabulated as the knit's peaks and hysteresis: the loading work of a cycle never unloaded, 10x the others
CYCLE_FLAGS = ("energy_kind", "closed", "peak_at_force_cap")
#: codes of ``energy_kind``: the names knitsim cell's summary gives (knitsim.io.checks.ENERGY_KINDS)
ENERGY_KINDS = dict(enumerate(checks.ENERGY_KINDS))
#: per cell
CELL_VARS = ("strain_at_first_jamming", "final_status", "expected_end", "loop_creates_energy", "rest_state_compressive",
             "stopped_at_strain", "last_converged_strain", "last_converged_force_per_wale_N", "heads_interpenetrate",
             "zero_force_cycle", "reload_below_earlier_loading", "reload_loss_continues", "reload_above_first_loading",
             "reload_below_first_loading", "wale_spacing_below_jamming")
#: warnings of the cell's summary (knitsim.io.results.cell_summary, as knitsim cell gives them) carried per
#: sample and cell as flags: 1 warned, 0 not, -1 not solved or unknown (a blind probe found heads_interpenetrate
#: and zero_force_cycle in no sweep output)
_WARNING_FLAGS = ("heads_interpenetrate", "zero_force_cycle", "reload_below_earlier_loading",
                  "reload_loss_continues", "reload_above_first_loading", "reload_below_first_loading",
                  "wale_spacing_below_jamming")
#: where a cell stopped (knitsim.io.results.cell_summary): a failed cell (all three), a cell stopped at its force
#: cap (stopped_at_strain only); NaN for a cell that ran the whole program
_STOP_VARS = ("stopped_at_strain", "last_converged_strain", "last_converged_force_per_wale_N")


#: values per temporary array of :func:`reduce_history`'s rules judged for a block of cells at once (2^22: 32 MB
#: of float64)
REDUCE_BLOCK = 1 << 22


class SweepChunkError(RuntimeError):
    """A chunk failed while running (not a user mistake); finished chunks are kept."""


# ------------------------------------------------------------------ planning
@dataclass
class Chunk:
    """One batched engine call: ``samples`` (indices into the sample table) of one program group."""

    index: int
    group: int
    samples: np.ndarray

    @property
    def name(self) -> str:
        """File name of the chunk's results (under ``chunks/``)."""
        return f"chunk_{self.index:05d}.npz"


@dataclass
class SweepPlan:
    """Everything a sweep needs, validated, before anything is solved.

    Attributes
    ----------
    spec : SweepSpec
    scene_doc : dict
        The scene (without ``[sweep]``), command-line overrides applied.
    base : CellScene
        The base scene, resolved.
    engine, device : str
        Engine and (resolved) device.
    table : list of tuple
        The swept values of every sample.
    params : list of list of CellParams
        Per sample, its cells (``n_cells`` each).
    programs : list of LoadProgram
        One per program group; ``group[i]`` is sample ``i``'s.
    loads : list of dict
        The resolved ``[load]`` table of each group.
    group : ndarray of int
    chunks : list of Chunk
    labels : list of str
        Cell labels (of the base scene).
    source : str
        The scene file.
    """

    spec: SweepSpec
    scene_doc: dict
    base: Any
    engine: str
    device: str
    table: list
    params: list
    programs: list
    loads: list
    group: np.ndarray
    chunks: list
    labels: list
    source: str = "<dict>"
    hash: str = ""
    #: :func:`sweep_inputs` (stored in sweep.json; --resume names what differs)
    inputs: dict | None = None
    #: per sample and cell, shape [n_samples, n_cells]: knitsim.cell.domain codes (0 inside, 1 outside the
    #: box: solved, an extrapolation; 2 no admissible rest state: not solved), found before any solve
    domain: np.ndarray | None = None
    #: per sample and cell, the reason of a non-zero domain code (None inside)
    domain_reasons: list | None = None
    #: what the user should know before the results (``code``, ``message``): a swept key that a cell of the scene
    #: states itself (:func:`_cells_not_swept`); printed by the command, in summary.json's ``warnings``
    warnings: list = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        """Samples in the sweep."""
        return len(self.table)

    @property
    def n_cells(self) -> int:
        """Cells per sample."""
        return len(self.labels)

    @property
    def n_cycles(self) -> int:
        """Most cycles of any program group."""
        return max(int(p.cycle.max()) for p in self.programs)

    @property
    def n_increments(self) -> int:
        """Most increments of any program group."""
        return max(len(p) for p in self.programs)


def _chunk_readable(path: Path) -> bool:
    """Whether a chunk file opens as the NumPy archive it was written as."""
    try:
        with np.load(path) as z:
            return "peak_force_per_wale_N" in z.files
    except Exception:              # a damaged file: zipfile.BadZipFile, OSError, ValueError, EOFError ...
        return False


def _text(v: Any) -> str:
    """A value as ``--set`` text (parsed back exactly by the schema's field types)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        # a whole number as one (a grid's {min, max, count} gives floats: 1.0 was refused for load.cycles, a
        # blind probe); a number field reads "2" as 2.0
        return str(int(v)) if v.is_integer() and abs(v) < 2.0 ** 53 else repr(v)
    return str(v)


def _set(doc: dict, key: str, value: Any) -> None:
    """Set the swept ``key`` of ``doc`` to ``value`` (by the schema's own key-path walk and field types).

    The value travels as ``--set`` text (:func:`_text`), so a type error from the schema quotes that text
    (``load.cycles = "1.5"``); it is said with the value as the sweep gave it (``load.cycles = 1.5``)."""
    text = _text(value)
    try:
        set_value(doc, CELL_SCENE, f"{key}={text}")
    except KnitsimInputError as exc:
        quoted = f"{key} = {json.dumps(text)}:"
        msg = str(exc)
        if msg.startswith(quoted):
            raise KnitsimInputError(f"{key} = {fmt(value)}:{msg[len(quoted):]}") from None
        raise


def _load_sample(scene_doc: dict, keys: list[str], row: tuple, base_dir: Path | None, engine, device):
    """The cell scene of ``scene_doc`` with each of ``keys`` set to its value in ``row``, its library file
    (``materials``) read relative to ``base_dir`` (the scene's folder; None: the working directory, a scene
    given as a dict)."""
    doc = copy.deepcopy(scene_doc)
    for k, v in zip(keys, row):
        _set(doc, k, v)
    lib = doc.get("materials")
    if base_dir is not None and isinstance(lib, str) and not Path(lib).is_absolute():
        doc["materials"] = str(base_dir / lib)
    return load_cell_scene(doc, engine=engine, device=device)


#: scene keys that say how a sweep runs, not what it simulates: one value for every sample
NOT_SWEPT = ("engine", "device", "title")
#: scene keys a sweep does not read at all (knitsim cell's plot.png; what wrote the scene), with what says it instead
NOT_READ = {"output.plot": "a sweep draws plot_sweep.png unless --no-plot",
            "provenance.source": "it names what wrote the scene",
            "cells[].label": "it names the cell in the outputs, whose cell_label is the scene's"}


def _check_key(doc: dict, key: str, value: Any) -> None:
    """Refuse a key path that is not a scalar of the cell scene schema, or that says how the sweep runs
    (:data:`NOT_SWEPT`: a blind probe's sweep over ``engine`` ran every sample on warp and labelled one of
    them reference), naming it."""
    if key in NOT_SWEPT:
        # (the command has --engine and --device, no --title: a blind probe was told to use --title)
        option = f", or --{key}" if key in ("engine", "device") else ""
        raise KnitsimInputError(f"sweep.parameters.{json.dumps(key)}: not a parameter of the cells: the whole sweep "
                                f"runs with one {key} (give it in the scene{option})")
    generic = re.sub(r"\[\d+\]", "[]", key)               # (cells[1].label: cells[].label)
    if generic in NOT_READ:
        # (a blind probe's sweep of output.plot ran two identical samples)
        raise KnitsimInputError(f"sweep.parameters.{json.dumps(key)}: not a parameter of the cells: a sweep does not "
                                f"read it ({NOT_READ[generic]}): every sample would run the same cells")
    try:
        _set(copy.deepcopy(doc), key, value)
    except KnitsimInputError as exc:
        msg = str(exc)
        prefix = f"--set {key}: "
        msg = msg[len(prefix):] if msg.startswith(prefix) else msg
        raise KnitsimInputError(f"sweep.parameters.{json.dumps(key)}: {msg}") from None


def _check_lhs_key(key: str) -> None:
    """Refuse a Latin-hypercube range over a whole-number key (``load.cycles``): its draws are real numbers, and
    every sample but a whole one was refused as such, with advice to narrow the range (a blind probe)."""
    f = field_at(CELL_SCENE, key)
    if f is not None and "int" in f.types and "float" not in f.types:
        raise KnitsimInputError(f"sweep.parameters.{json.dumps(key)}: a whole number, which a Latin hypercube cannot "
                                "draw (its samples are real numbers): give it as a grid axis, values = [...] or min, "
                                "max and count (method = \"grid\"), or as one value in the scene")


_KEPT = object()


def _remover(doc: dict, key: str, p) -> Any:
    """The value of the swept parameter ``p`` whose setting removes ``key`` from ``doc`` (by the schema's own rule,
    :func:`~knitsim.scene.schema.set_value`: one quantity stated another way, ``friction.phi0`` / ``phi0_deg``, or a
    choice of keys without it, ``load.type``), else :data:`_KEPT`.  Which keys a value removes depends on the value
    only for a choosing key (a name): a number is tried once (an axis may hold 10^7 of them)."""
    vals = (p.low,) if p.values is None else tuple(dict.fromkeys(
        [p.values[0]] + [v for v in p.values if isinstance(v, (str, bool))]))
    for v in vals:
        trial = copy.deepcopy(doc)
        try:
            _set(trial, p.key, v)
        except KnitsimInputError:
            continue                                   # (the key itself is judged by _check_key)
        if key not in flat_keys(trial):
            return v
    return _KEPT


def _check_overrides_kept(doc: dict, overrides: list[str], spec: SweepSpec) -> None:
    """Refuse a ``--set`` that a swept key removes from some sample (:func:`_remover`; a blind probe's ``--set
    friction.phi0=0.1`` on a sweep of ``friction.phi0_deg`` was dropped by every sample without a word), and an axis
    that a later axis removes (``friction.phi0`` and ``friction.phi0_deg`` both swept: every sample ran the later
    one's value, labelled with both)."""
    kept = flat_keys(doc)
    for a in overrides:
        key = a.split("=", 1)[0].strip()
        if key not in kept:
            continue
        for p in spec.parameters:
            v = _remover(doc, key, p)
            if v is not _KEPT:
                raise KnitsimInputError(
                    f"--set {a}: the sweep's {p.key} = {fmt(v)} removes {key} from the sample's scene (one "
                    "quantity stated two ways, or a choice of keys without it): the --set would be dropped "
                    "without a word; drop one of the two")
    params = spec.parameters
    for i, a in enumerate(params):
        trial = copy.deepcopy(doc)
        try:
            _set(trial, a.key, a.values[0] if a.values is not None else a.low)
        except KnitsimInputError:
            continue
        for b in params[i + 1:]:
            v = _remover(trial, a.key, b)
            if v is not _KEPT:
                raise KnitsimInputError(
                    f"sweep.parameters.{json.dumps(a.key)}: the later axis {json.dumps(b.key)} = {fmt(v)} removes "
                    f"it from the sample's scene (one quantity stated two ways, or a choice of keys without it): "
                    f"those samples would run {b.key} alone, labelled with both; sweep one of the two")


def _cells_not_swept(doc: dict, spec: SweepSpec, labels: list) -> list[dict]:
    """Warnings for a swept key of the base tables (``friction.m``) that a cell of ``[[cells]]`` states itself
    (``friction = { m = 0.4 }``, or another way, ``mu_k``): a cell's own keys replace the base's
    (:func:`knitsim.scene.cell_scene._merge`), so that cell keeps its value in every sample.  Warned, not refused (a
    control cell held fixed is a design); before, not said: a blind probe's cell ran one value through the sweep,
    its results repeated under every value of the axis."""
    from ..scene.cell_scene import cells_stating

    out = []
    for p in spec.parameters:
        own = cells_stating(doc, p.key)
        table, _, name = p.key.partition(".")
        if own:
            i, k = next(iter(own.items()))
            label = labels[i] if i < len(labels) else f"cells[{i}]"
            out.append({"code": "swept_key_set_by_cell",
                        "message": f"sweep.parameters.{json.dumps(p.key)}: {len(own)} of the scene's {len(labels)} "
                                   f"cell(s) set {table}.{name} themselves (e.g. cells[{i}].{table}.{k} = "
                                   f"{fmt(doc['cells'][i][table][k])}, cell {label}): they keep their own value in "
                                   "every sample, the sweep does not reach them (remove a cell's own value if it "
                                   "should follow the sweep)"})
    return out


def _check_effect_axes(spec: SweepSpec, params: list) -> None:
    """Refuse an axis of an effect's parameter (``effects.bend_h``) where no cell of any sample has that effect on
    (``effects.on``): the kernels do not read it, every sample runs the same cells (a blind probe's sweep of
    ``effects.bend_h`` without bending_hysteresis on gave one result under every value, without a word).  A scene
    may state the parameters of effects that are off (a calibration writes them all); an axis of one is a mistake."""
    from ..cell.effects import EFFECT_PARAMETERS

    owner = {c: name for name, cols in EFFECT_PARAMETERS.items() for c in cols}
    swept = [(p.key, owner[p.key.rsplit(".", 1)[-1]]) for p in spec.parameters
             if p.key.rsplit(".", 2)[-2:-1] == ["effects"] and p.key.rsplit(".", 1)[-1] in owner]
    if not swept:
        return
    on = {n for cells in params for c in cells for n in c.effects.on}
    for key, effect in swept:
        if effect not in on:
            raise KnitsimInputError(
                f"sweep.parameters.{json.dumps(key)}: a parameter of the effect {effect}, which no cell has on "
                f"(effects.on): every sample would run the same cells; add \"{effect}\" to effects.on, or leave "
                "the axis out")


def plan_sweep(scene: str | Path | dict, sweep: str | Path | dict | SweepSpec | None = None,
               overrides: list[str] = (), engine: str | None = None, device: str | None = None,
               chunk_size: int | None = None, progress=None) -> SweepPlan:
    """Read and validate a sweep completely: every sample's scene, before any solve.

    Parameters
    ----------
    scene : path or dict
        The cell scene (TOML file or parsed document); may hold the ``[sweep]`` table.
    sweep : path, dict or SweepSpec, optional
        A separate sweep TOML, a ``[sweep]`` table, or a parsed spec; replaces
        the scene's ``[sweep]``.
    overrides : list of str
        ``key=value`` overrides of the base scene (as ``knitsim cell --set``).
    engine, device : str, optional
        Replace the scene's engine / device.
    chunk_size : int, optional
        Replace ``sweep.chunk_size``.
    progress : callable, optional
        ``progress(done, total)`` after each sample's scene is validated (about 1 ms a sample: a blind
        probe's 50,000-sample Latin hypercube spent 50 s here without a word, 10^7 samples would take hours).

    Returns
    -------
    SweepPlan

    Raises
    ------
    KnitsimInputError
        An unknown key path (named), a bad ``[sweep]`` entry, or a sample whose
        scene is invalid (the message gives the sample's values).
    """
    if isinstance(scene, dict):
        doc, source = copy.deepcopy(scene), "<dict>"
    else:
        doc, source = load_toml(scene), str(scene)
    if isinstance(sweep, SweepSpec):
        scene_doc, spec = {k: v for k, v in doc.items() if k != "sweep"}, sweep
    else:
        if isinstance(sweep, dict):
            scene_doc, table = {k: v for k, v in doc.items() if k != "sweep"}, sweep
        else:
            scene_doc, table, _ = split_scene(doc, None if sweep is None else str(sweep))
        if chunk_size is not None:
            table = dict(table, chunk_size=chunk_size)
        spec = parse_sweep(table)
    swept = {p.key for p in spec.parameters}
    for a in overrides:
        key = a.split("=", 1)[0].strip()
        if key in swept:
            # the sweep's values would replace it in every sample without a word (a blind probe)
            raise KnitsimInputError(f"--set {a}: {key} is a parameter of the sweep (its values come from "
                                    "[sweep.parameters]): drop one of the two")
        set_value(scene_doc, CELL_SCENE, a)
    _check_overrides_kept(scene_doc, overrides, spec)
    # a library file (materials = FILE) is relative to the scene, as for knitsim cell and run
    base_dir = None if source == "<dict>" else Path(source).resolve().parent
    try:
        base, base_error = _load_sample(scene_doc, [], (), base_dir, engine, device), None
    except KnitsimInputError as exc:
        base, base_error = None, exc
    for p in spec.parameters:
        _check_key(scene_doc, p.key, p.values[0] if p.values is not None else p.low)
        if spec.method == "lhs":
            _check_lhs_key(p.key)
    table = spec.sample_table()
    keys = spec.keys
    if base is None:
        # a scene that leaves a swept key to the sweep (no knit.L, every sample gives one) is not a scene alone: its
        # base is its first sample's (before, refused as "knit.L: missing", and a --set of it as a swept key); a
        # scene that fails there too is refused naming that sample
        try:
            base = _load_sample(scene_doc, keys, table[0], base_dir, engine, device)
        except KnitsimInputError as exc:
            if str(exc) == str(base_error):          # the scene's own mistake, not the sweep's: said as before
                raise base_error from None
            vals = ", ".join(f"{k} = {fmt(v)}" for k, v in zip(keys, table[0]))
            raise KnitsimInputError(f"sweep sample 0 ({vals}): {exc}") from None

    if base.engine == "warp":
        from .. import warp_runtime
        dev = warp_runtime.resolve_device(base.device)
    else:
        dev = "cpu"

    params, group, programs, loads, group_of = [], [], [], [], {}
    n_cells = len(base.params)
    invalid: dict = {}
    for i, row in enumerate(table):
        try:
            s = _load_sample(scene_doc, keys, row, base_dir, engine, device)
        except KnitsimInputError as exc:
            # refused before any work (bad input: W0 < 4 d, a program the knit cannot reach), but with every
            # such sample counted, not the first alone (a blind probe's Latin hypercube was refused for its
            # sample 217, with no word of how many more)
            vals = ", ".join(f"{k} = {fmt(v)}" for k, v in zip(keys, row))
            invalid[i] = f"sweep sample {i} ({vals}): {exc}"
            s = base
        if len(s.params) != n_cells:  # pragma: no cover - a scalar key cannot change the cell count
            raise KnitsimInputError(f"sweep sample {i}: {len(s.params)} cells, the base scene has {n_cells}")
        gkey = canonical_json(s.resolved["load"])
        if gkey not in group_of:
            group_of[gkey] = len(programs)
            programs.append(s.program)
            loads.append(s.resolved["load"])
        group.append(group_of[gkey])
        params.append(s.params)
        if progress is not None:
            progress(i + 1, len(table))
    group = np.asarray(group, dtype=np.int64)
    if invalid:
        first = next(iter(invalid.values()))
        more = (f" ({len(invalid) - 1} more of the {len(table)} samples are refused too: samples "
                f"{', '.join(map(str, list(invalid)[1:6]))}{', ...' if len(invalid) > 6 else ''}; narrow the "
                "ranges or leave those values out)") if len(invalid) > 1 else ""
        raise KnitsimInputError(first + more)
    _check_effect_axes(spec, params)
    domain, reasons = _domain_of(params, programs, group, base.engine, dev)
    chunks = []
    for g in range(len(programs)):
        idx = np.nonzero(group == g)[0]
        for a in range(0, len(idx), spec.chunk_size):
            chunks.append(Chunk(len(chunks), g, idx[a:a + spec.chunk_size]))
    plan = SweepPlan(spec, scene_doc, base, base.engine, dev, table, params, programs, loads, group, chunks,
                     list(base.labels), source, domain=domain, domain_reasons=reasons)
    plan.warnings = _cells_not_swept(scene_doc, spec, list(base.labels))
    plan.inputs = sweep_inputs(plan)
    plan.hash = sweep_hash(plan, plan.inputs)
    return plan


def _domain_of(params: list, programs: list, group: np.ndarray, engine: str, device: str):
    """Domain codes and reasons of every sample's cells, before any solve (knitsim.cell.domain.check_cells).

    A cell with no admissible rest state (decided by the engine that would run it) is outside the
    model: it is not solved.  A cell outside the domain's box, or a program whose strains leave the
    box, is solved (the box is where convergence is promised, not where the model ends) and flagged
    as an extrapolation.
    """
    from ..cell.domain import DOMAIN, DOMAIN_INSIDE, DOMAIN_OUTSIDE_BOX, check_cells

    ns = len(params)
    nc = len(params[0]) if ns else 0
    flat = [p for cells in params for p in cells]
    check = check_cells(flat, engine=engine, device=device)
    codes = check.codes.reshape(ns, nc)
    why = check.reasons()
    program_why = [DOMAIN.why_program_outside(prog.strain) for prog in programs]
    reasons = []
    for i in range(ns):
        row = []
        for c in range(nc):
            r = why[i * nc + c]
            if codes[i, c] == DOMAIN_INSIDE and program_why[group[i]] is not None:
                codes[i, c], r = DOMAIN_OUTSIDE_BOX, program_why[group[i]]
            row.append(r)
        reasons.append(row)
    return codes, reasons


def _sha(text: str | bytes) -> str:
    return hashlib.sha256(text.encode() if isinstance(text, str) else text).hexdigest()


def _sample_digest(cells: list) -> str:
    """Digest of one sample's resolved cells (every CellParams field, effects included)."""
    return _sha(canonical_json([p.as_dict() for p in cells]))[:16]


def sweep_inputs(plan: SweepPlan) -> dict:
    """Digests of everything that determines a sweep's results, by what they cover.

    The idea of ``knitsim run``'s checkpoint fingerprint (:func:`knitsim.patch.runner.fingerprint`): hash
    what the solver is given, as resolved, not the text that names it.  A scene's ``materials = FILE``
    only names a library; ``cells`` covers every sample's cells after the library, the defaults and the
    sample's values are read, so an edited library changes it.  ``samples_cells`` (one short digest per
    sample) says which samples changed.

    Returns
    -------
    dict
        ``format``, ``knitsim`` (version), ``engine``, ``device``, and SHA-256 digests of ``spec`` (the
        normalised ``[sweep]`` table: parameters, chunking, curves), ``samples`` (the sample table),
        ``scene`` (the scene document, overrides applied), ``cells`` (the resolved cells of every sample),
        ``programs`` (each load program's strains, cycles, directions, rates and which sample runs which);
        and ``samples_cells``.
    """
    from .. import __version__

    per_sample = [_sample_digest(cells) for cells in plan.params]
    prog = hashlib.sha256(np.ascontiguousarray(plan.group, dtype=np.int64).tobytes())
    for p in plan.programs:
        for a in (p.strain, p.cycle, p.direction) + (() if p.rate is None else (p.rate,)):
            prog.update(np.ascontiguousarray(a).tobytes())
        prog.update(b"|")
    return {"format": FORMAT, "knitsim": __version__, "engine": plan.engine, "device": plan.device,
            "spec": _sha(canonical_json(plan.spec.table)),
            "samples": _sha(canonical_json([list(r) for r in plan.table])),
            "scene": _sha(canonical_json(plan.scene_doc)), "cells": _sha("".join(per_sample)),
            "programs": prog.hexdigest(), "samples_cells": per_sample}


def sweep_hash(plan: SweepPlan, inputs: dict | None = None) -> str:
    """SHA-256 identifying a sweep: of :func:`sweep_inputs` (what ``--resume`` compares)."""
    what = dict(inputs if inputs is not None else sweep_inputs(plan))
    what.pop("samples_cells")                    # covered by "cells"
    return _sha(canonical_json(what))


def _changes(old: dict, plan: SweepPlan, inputs: dict) -> str:
    """What differs between a manifest's sweep and ``plan``, in words (for --resume's refusal)."""
    was = old.get("inputs")
    what = []
    for key, name in (("format", "sweep format"), ("knitsim", "knitsim version"), ("engine", "engine"), ("device", "device")):
        if was.get(key) != inputs[key]:
            what.append(f"{name} {was.get(key)} -> {inputs[key]}")
    for key, name in (("spec", "the [sweep] table"), ("samples", "the sample table"), ("scene", "the scene")):
        if was.get(key) != inputs[key]:
            if key == "spec" and isinstance(old.get("spec"), dict):
                # name its keys (a blind probe's --resume --curves read "the [sweep] table differs": the option
                # --curves sets sweep.curves, which the run being resumed did not keep)
                diff = key_changes(flat_keys(old["spec"], "sweep"),
                                   flat_keys(json.loads(json.dumps(plan.spec.table)), "sweep"))
                if diff:
                    name += " (" + ", ".join(diff[:3]) + (", ..." if len(diff) > 3 else "") + (
                        "; --curves sets sweep.curves" if any(d.startswith("sweep.curves ") for d in diff) else "") + ")"
            what.append(name)
    if was.get("cells") != inputs["cells"]:
        # name the values: the base scene's resolved cells are in the manifest
        # (as scene key paths: yarn.B for a scene of one cell, cells[1].yarn.B for a batch)
        a_cells = old.get("base_resolved", {}).get("cells", [])
        b_cells = json.loads(json.dumps(plan.base.resolved.get("cells", [])))
        one = len(a_cells) == len(b_cells) == 1
        diff = key_changes(flat_keys(a_cells[0] if one else a_cells, "" if one else "cells"),
                           flat_keys(b_cells[0] if one else b_cells, "" if one else "cells"))
        # a changed scene, sample table or knitsim explains changed cells; else what the scene names did
        upstream = any(was.get(k) != inputs[k] for k in ("knitsim", "spec", "samples", "scene"))
        olds = was.get("samples_cells")
        if not diff and not upstream and isinstance(olds, list) and len(olds) == len(inputs["samples_cells"]):
            bad = [i for i, (x, y) in enumerate(zip(olds, inputs["samples_cells"])) if x != y]
            if bad:
                i = bad[0]
                vals = ", ".join(f"{k} = {fmt(v)}" for k, v in zip(plan.spec.keys, plan.table[i]))
                diff = [f"those of {len(bad)} of {plan.n_samples} sample(s), e.g. sample {i} ({vals})"]
        lib = plan.scene_doc.get("materials")
        parts = diff[:3] + (["..."] if len(diff) > 3 else [])
        if not upstream:
            parts.append(f"read from the material library {lib}" if isinstance(lib, str)
                         else "from knitsim's built-in materials or defaults")
        if parts:
            what.append("the resolved cells: " + ", ".join(parts))
    if was.get("programs") != inputs["programs"]:
        what.append("the load programs")
    return "; ".join(what) or "its fingerprint"


# ----------------------------------------------------------------- reduction
def reduce_history(history, n_cycles: int, curves: bool = False, reference=None) -> dict[str, np.ndarray]:
    """Scalar results of every cell of a history (see :func:`knitsim.io.results.cell_summary`); ``reference``: the
    cells pulled monotonically (:func:`knitsim.io.results.first_loading`; None where the program does not reload
    past an earlier maximum), the check ``reload_below_first_loading``'s, as ``knitsim cell`` runs it.

    The numbers and flags are ``cell_summary``'s, from the same functions, without what a sweep does not keep
    (messages, rules, parameters): the program's rows are read once for the batch
    (:class:`~knitsim.io.results.SummaryRows`); the cycles' numbers (:func:`~knitsim.io.results.cycle_numbers`),
    the cycle checks (:func:`~knitsim.io.checks.load_cycle_warnings_of`, the cells of one stop row together),
    the stop rows, first jammed rows and the flags of the row rules (heads_interpenetrate,
    wale_spacing_below_jamming, rest_state_compressive) judged for blocks of cells at once; and a cell's loops
    judged for energy only where :func:`knitsim.io.checks.energy_loop_candidates` says one may warn, up to the
    first warning (issue 15: at 5.7 ms a cell, a 10^5-sample GPU sweep spent ~570 s here
    against ~30 s solving; benchmarks/bench_reduce_history.py).

    Returns
    -------
    dict of str to ndarray
        :data:`CYCLE_VARS` of shape ``[n_cells, n_cycles]`` (NaN where a cycle
        was not reached or, for the residual strain, the force never returns
        to 0), :data:`CELL_VARS` of shape ``[n_cells]`` (``final_status`` as
        :data:`knitsim.cell.history.STATUS_NAMES` codes, NaN jamming strain
        if the cell never jams), and with ``curves`` the force per wale
        ``force_per_wale_N`` of shape ``[n_cells, n_increments]``.
    """
    from ..cell.domain import rest_at_cap_problem
    from ..cell.history import STATUS_FORCE_CAP
    from ..cell.stages import stage_label_codes
    from ..io.checks import (below_jamming_width, energy_creating_loops, energy_loop_candidates, heads_overlap,
                             is_compressive, jam_width_floor, load_cycle_warnings_of)
    from ..io.results import (SummaryRows, _stitch_energy, cycle_numbers, first_jamming, first_jamming_rows,
                              first_loading_curve, reference_warnings, stop_point, stopped_rows)

    h = history
    n = h.n_cells
    out = {k: np.full((n, n_cycles), np.nan) for k in CYCLE_VARS}
    out.update({k: np.full((n, n_cycles), -1, dtype=np.int8) for k in CYCLE_FLAGS})
    out["strain_at_first_jamming"] = np.full(n, np.nan)
    out["final_status"] = np.asarray(history.status[-1, :], dtype=np.int32)
    out["expected_end"] = np.zeros(n, dtype=np.int8)
    out["loop_creates_energy"] = np.zeros(n, dtype=np.int8)
    out["rest_state_compressive"] = np.zeros(n, dtype=np.int8)
    for k in _WARNING_FLAGS:
        out[k] = np.zeros(n, dtype=np.int8)
    for k in _STOP_VARS:
        out[k] = np.full(n, np.nan)

    rows_of = SummaryRows(h)
    n_rows = len(rows_of.strain)
    n_ok = stopped_rows(h.status)                              # the rows each cell's summary reads
    jam_rows = np.empty(n, np.int64)
    params = list(h.params)
    d_jam = np.array([p.d_jam for p in params], float)
    C0 = np.array([p.C0 for p in params], float)
    floor = jam_width_floor(d_jam, [p.effects for p in params])
    F_all = h.force_per_wale
    rest_F = None if h.rest is None else np.asarray(h.rest["F"])
    loops = np.zeros(n, bool)                                  # cells whose loops are judged for energy
    # the rules judged row by row, for every cell at once (the rules of cell_summary's checks), in blocks of cells
    # (a few [n_rows, block] temporaries: a GPU chunk's 10^5 cells would need GBs at once)
    block = max(1, REDUCE_BLOCK // max(n_rows, 1))
    events = [h.events_of(c) for c in range(n)]
    qs = [(q, int(k) - 1) for q, (k, _) in enumerate(rows_of.cycles)]     # the out column of each cycle
    # the flags of the cycle checks and the check against the monotonic pull
    cycle_flags = [k for k in _WARNING_FLAGS if k not in ("heads_interpenetrate", "wale_spacing_below_jamming")]
    for c0 in range(0, n, block):
        cols = slice(c0, min(n, c0 + block))
        ok = n_ok[cols]
        num = cycle_numbers(h, np.arange(cols.start, cols.stop), ok, events[cols], rows_of)
        for q, j in qs:
            reached = num["reached"][:, q]
            for k in CYCLE_VARS:
                if k != "energy_N_mm":
                    out[k][cols, j] = np.where(reached, num[k][:, q], np.nan)
            out["energy_N_mm"][cols, j] = np.where(reached, num["energy_N_per_strain"][:, q] * C0[cols], np.nan)
            out["energy_kind"][cols, j] = np.where(reached, num["energy_kind"][:, q], -1)
            out["closed"][cols, j] = np.where(reached, num["closed"][:, q], -1)
            out["peak_at_force_cap"][cols, j] = np.where(reached, 0, -1)
        # the cycle checks, for the cells with the same rows (stopped at the same row) at once
        for v in np.unique(ok):
            at = c0 + np.flatnonzero(ok == v)
            peaks = [[(k, float(num["peak_force_per_wale_N"][c - c0, q])) for q, (k, _) in enumerate(rows_of.cycles)
                      if num["reached"][c - c0, q]] for c in at]
            for c, w in zip(at, load_cycle_warnings_of(peaks, rows_of.strain[:v], np.asarray(F_all[:v, at]),
                                                       rows_of.cycle[:v], rows_of.direction[:v])):
                w += reference_warnings(rows_of, F_all[:v, c], int(v), w, first_loading_curve(reference, c))
                codes = {x.code for x in w}
                for k in cycle_flags:
                    out[k][c] = int(k in codes)
        live = np.arange(n_rows)[:, None] < ok
        jam_rows[cols] = first_jamming_rows(stage_label_codes(h.stage[:, cols], h.jammed[:, cols]), ok)
        if "interpenetrating" in h.values:
            out["heads_interpenetrate"][cols] = np.any(
                heads_overlap(h.values["interpenetrating"][:, cols], h.values["head_gap"][:, cols], d_jam[cols])
                & live, axis=0)
        out["wale_spacing_below_jamming"][cols] = np.any(
            below_jamming_width(h.values["W"][:, cols], floor[cols])[0] & live, axis=0)
        if rest_F is not None:
            out["rest_state_compressive"][cols] = is_compressive(rest_F[cols])
            # the cells that stopped at the same row (all that ran the whole program) have the same strains: the
            # prefilter judges them at once, and only the cells it keeps are judged one by one
            S = np.concatenate([[0.0], rows_of.strain])
            for v in np.unique(ok[ok > 0]):
                at = c0 + np.flatnonzero(ok == v)
                cand = energy_loop_candidates(np.broadcast_to(S[:v + 1, None], (v + 1, len(at))),
                                              np.vstack([rest_F[at][None, :], np.asarray(F_all[:v, at])]))
                loops[at[cand]] = True
    final_status = out["final_status"]
    for c in range(n):
        p = params[c]
        k_ok = int(n_ok[c])
        final = int(final_status[c])
        # a rest state already at or above the cap: the cell stopped at rest (knitsim.cell.history.rest_at_cap_reason),
        # its peak the rest force, not the cap (a probe's cap of 0.0045 N under the rest force 0.0216 N was listed
        # "stopped at its force cap in cycle 1, whose peak is the cap", stopped at the first increment's strain 0.02)
        at_rest = (final == STATUS_FORCE_CAP and rest_F is not None
                   and rest_at_cap_problem(float(rest_F[c]), p.cap_N) is not None)
        if final == STATUS_FORCE_CAP and not at_rest:
            # the cycle of the located cap state (the cell's first row not ok, kept): its peak is the cap
            out["peak_at_force_cap"][c, int(rows_of.cycle[k_ok - 1]) - 1] = 1
        jam, _ = first_jamming(events[c], int(jam_rows[c]), h.values["C"][:, c], p.C0)
        out["strain_at_first_jamming"][c] = np.nan if jam is None else jam
        # where the cell stopped: a failure, or its force cap (cell_summary gives the last converged state of a
        # failure only: a capped cell's is the located cap state, its last row)
        stop = stop_point(h, c, final)
        out["expected_end"][c] = 1 if stop["expected_end"] else 0
        for k in _STOP_VARS:
            out[k][c] = np.nan if stop[k] is None else stop[k]
        if at_rest:
            out["stopped_at_strain"][c] = 0.0
        F_ok = F_all[:k_ok, c]
        if loops[c]:
            out["loop_creates_energy"][c] = int(bool(energy_creating_loops(
                np.concatenate([[0.0], rows_of.strain[:k_ok]]), np.concatenate([[rest_F[c]], F_ok]), p.C0,
                stored_at=_stitch_energy(h, c, p.B), first=True)))
    if curves:
        F = np.array(history.force_per_wale.T, dtype=np.float64)
        # the rows a cell did not solve (after a failure, or past its stop at the force cap) hold its last state:
        # NaN, as the variable's description says (a blind probe read held values as the knit's curve)
        F[np.arange(F.shape[1])[None, :] >= n_ok[:, None]] = np.nan
        out["force_per_wale_N"] = np.ascontiguousarray(F)
    return out


def run_chunk(task: dict) -> dict:
    """Run one chunk (one batched engine call) and write its file atomically.

    ``task`` holds ``path``, ``samples`` (indices), ``params`` (flat list,
    ``n_cells`` per sample), ``solve`` (per cell of ``params``: False for a cell without a rest
    state, which is not solved: status no_rest_state, NaN results), ``n_cells``, ``program``,
    ``n_cycles``, ``engine``, ``device``, ``curves``.  Runs in the driver (``workers=0``) or
    in a Dask worker; returns ``{"chunk", "samples", "wall_s"}``.
    """
    from ..cell.engine import simulate
    from ..cell.history import STATUS_NO_REST_STATE

    t0 = time.perf_counter()
    solve = np.asarray(task.get("solve", [True] * len(task["params"])), dtype=bool)
    n_all = len(task["params"])
    red = {k: np.full((n_all, task["n_cycles"]), np.nan) for k in CYCLE_VARS}
    red.update({k: np.full((n_all, task["n_cycles"]), -1, dtype=np.int8) for k in CYCLE_FLAGS})
    red["strain_at_first_jamming"] = np.full(n_all, np.nan)
    red["final_status"] = np.full(n_all, STATUS_NO_REST_STATE, dtype=np.int32)
    red["expected_end"] = np.zeros(n_all, dtype=np.int8)
    red["loop_creates_energy"] = np.full(n_all, -1, dtype=np.int8)       # -1: not solved
    red["rest_state_compressive"] = np.full(n_all, -1, dtype=np.int8)
    for k in _WARNING_FLAGS:
        red[k] = np.full(n_all, -1, dtype=np.int8)
    for k in _STOP_VARS:
        red[k] = np.full(n_all, np.nan)
    if task["curves"]:
        red["force_per_wale_N"] = np.full((n_all, len(task["program"])), np.nan)
    if solve.any():
        # Warp's messages must not reach stdout (kept for --json)
        from ..io.results import first_loading
        solved = [p for p, s in zip(task["params"], solve) if s]
        with contextlib.redirect_stdout(sys.stderr):
            history = simulate(solved, task["program"], engine=task["engine"], device=task["device"])
            # the cells pulled monotonically, where the program reloads past an earlier maximum (else None)
            reference = first_loading(solved, task["program"], engine=task["engine"], device=task["device"])
        for k, v in reduce_history(history, task["n_cycles"], task["curves"], reference).items():
            red[k][solve] = v
    ns, nc = len(task["samples"]), task["n_cells"]
    arrays = {"samples": np.asarray(task["samples"], dtype=np.int64)}
    for k, v in red.items():
        arrays[k] = v.reshape((ns, nc) + v.shape[1:])
    if task["curves"]:
        arrays["imposed_strain"] = np.asarray(task["program"].strain, dtype=np.float64)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(task["path"], buf.getvalue())
    return {"chunk": task["chunk"], "samples": ns, "wall_s": time.perf_counter() - t0}


def _task(plan: SweepPlan, chunk: Chunk, out: Path) -> dict:
    from ..cell.domain import DOMAIN_NO_REST_STATE

    flat = [p for i in chunk.samples for p in plan.params[i]]
    solve = ([True] * len(flat) if plan.domain is None else
             [bool(plan.domain[i, c] != DOMAIN_NO_REST_STATE) for i in chunk.samples for c in range(plan.n_cells)])
    return {"chunk": chunk.index, "path": str((out / CHUNK_DIR / chunk.name).resolve()), "samples": chunk.samples.tolist(),
            "params": flat, "solve": solve, "n_cells": plan.n_cells, "program": plan.programs[chunk.group],
            "n_cycles": plan.n_cycles, "engine": plan.engine, "device": plan.device, "curves": plan.spec.curves}


# ------------------------------------------------------------------ manifest
def versions() -> dict:
    """Versions of knitsim and the libraries that shape the results."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in ("knitsim", "warp-lang", "numpy", "scipy", "dask", "distributed", "xarray"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def manifest(plan: SweepPlan) -> dict:
    """The ``sweep.json`` document."""
    return {
        "format": FORMAT, "hash": plan.hash, "inputs": plan.inputs if plan.inputs is not None else sweep_inputs(plan),
        "source": plan.source, "spec": plan.spec.table,
        "engine": plan.engine, "device": plan.device, "scene": plan.scene_doc,
        "base_resolved": plan.base.resolved, "parameters": plan.spec.keys, "shape": list(plan.spec.shape),
        "cell_labels": plan.labels, "loads": plan.loads,
        "samples": [list(r) for r in plan.table], "group": plan.group.tolist(),
        "domain": None if plan.domain is None else plan.domain.tolist(),
        "domain_reasons": plan.domain_reasons,
        "chunks": [{"index": c.index, "file": f"{CHUNK_DIR}/{c.name}", "group": c.group,
                    "samples": c.samples.tolist()} for c in plan.chunks],
        "versions": versions(), "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }


def _prepare_out(plan: SweepPlan, out: Path, resume: bool) -> None:
    check_output_dir(out)
    mpath = out / MANIFEST
    if resume:
        if not mpath.is_file():
            raise KnitsimInputError(f"--resume: {mpath} not found (nothing to resume; run without --resume)")
        try:
            old = json.loads(mpath.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise KnitsimInputError(f"--resume: {mpath} is not a sweep manifest ({exc})") from None
        if old.get("hash") != plan.hash:
            advice = "run without --resume into a new --out, or with --overwrite to replace it"
            if not isinstance(old.get("inputs"), dict):
                raise KnitsimInputError(
                    f"--resume: {mpath} was written by an earlier knitsim that did not record the resolved inputs "
                    f"(material library values, load programs, version): its finished chunks cannot be checked "
                    f"against this sweep; {advice}")
            inputs = plan.inputs if plan.inputs is not None else sweep_inputs(plan)
            raise KnitsimInputError(
                f"--resume: {out} holds a different sweep: the resolved inputs differ from those of its finished "
                f"chunks ({_changes(old, plan, inputs)}); reusing them would mix two sweeps: {advice}")
        # a chunks/ folder removed (a finished sweep's, results.nc holding them all): its chunks are computed again
        # (before, each chunk's write failed, "after fixing the cause, finish with --resume", which failed again)
        (out / CHUNK_DIR).mkdir(exist_ok=True)
        return
    if mpath.exists() or (out / CHUNK_DIR).exists():
        raise KnitsimInputError(f"--out = {str(out)!r}: already holds a sweep; add --resume to finish it, "
                                "or choose another --out")
    record_outputs(out, SWEEP_OUTPUTS)
    (out / CHUNK_DIR).mkdir(parents=True, exist_ok=True)
    atomic_write_text(mpath, json.dumps(manifest(plan), indent=1) + "\n")


# ----------------------------------------------------------------- execution
@dataclass
class SweepRun:
    """What :func:`run_sweep` did."""

    out: Path
    computed: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    wall_s: float = 0.0
    files: dict = field(default_factory=dict)
    dataset: Any = None
    #: the flags of the run (failed, rest-less, out-of-box, energy-returning, compressive, force-capped
    #: samples with their reasons) and its figures, as written to summary.json (:func:`sweep_summary`)
    summary: dict = field(default_factory=dict)

    @property
    def samples_per_s(self) -> float:
        """Samples computed per second of this run's wall time [1/s] (NaN when no time was recorded)."""
        return float("nan") if not self.wall_s else self.n_computed_samples / self.wall_s

    n_computed_samples: int = 0
    #: why plot_sweep.png could not be drawn (``"TypeError: ..."``), None when it was or was not asked for
    plot_error: str | None = None


class _Progress:
    def __init__(self, stream, total_chunks: int, total_samples: int, done_chunks: int):
        self.stream, self.total, self.total_samples = stream, total_chunks, total_samples
        self.done, self.samples, self.t0, self.last = done_chunks, 0, time.perf_counter(), 0.0

    def __call__(self, n_samples: int) -> None:
        self.done += 1
        self.samples += n_samples
        now = time.perf_counter()
        if self.stream is None or (now - self.last < 0.5 and self.done < self.total):
            return
        self.last = now
        rate = self.samples / max(now - self.t0, 1e-9)
        # (3 digits: the reference engine's 4 samples in 151 s read "0.0 samples/s", as if none had been solved)
        print(f"knitsim sweep: chunks {self.done}/{self.total}, {rate:.3g} samples/s", file=self.stream, flush=True)


def _run_local(tasks: list[dict], progress: _Progress, done: list) -> None:
    for t in tasks:
        r = run_chunk(t)
        done.append(r["chunk"])
        progress(r["samples"])


@contextlib.contextmanager
def _workers_ignore_sigint():
    """Start worker processes that ignore Ctrl-C: the driver handles it (cancels, closes the cluster, says
    how to resume).  A Ctrl-C at a terminal reaches the whole process group, and each Dask worker process
    printed its own CancelledError / KeyboardInterrupt traceback before the "interrupted" message (a blind
    probe).  An ignored signal stays ignored in a spawned child; the driver's handler is restored at once.

    A SIGTERM or SIGHUP (taken as a Ctrl-C, :func:`knitsim.cli.common.sigterm_as_ctrl_c`) that comes while the
    block starts the cluster is held until the block ends, then delivered: stopping the cluster's start
    half-way left it to Dask's exit hook, which printed ``AssertionError: Status.init`` with its traceback
    after the "interrupted" line (3 of 14 SIGTERMs sent 0.5-11 s into a sweep's start)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():   # signal handlers: the main thread's only
        yield
        return
    held: list = []
    deferred = [s for s in (signal.SIGTERM, getattr(signal, "SIGHUP", None))
                if s is not None and callable(signal.getsignal(s))]
    old_deferred = {s: signal.signal(s, lambda signum, frame: held.append(signum)) for s in deferred}
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        for s, h in old_deferred.items():
            signal.signal(s, h)
        for s in dict.fromkeys(held):
            signal.raise_signal(s)         # (its own handler again: a Ctrl-C, once the cluster is held)


def check_workers(workers: int | None, scheduler: str | None = None) -> None:
    """Refuse a number of local Dask workers that is negative, or more than this machine's cores (with no
    ``scheduler``, which then runs the chunks on its own workers): each worker is a single-threaded process
    (Warp's CPU backend runs a launch on one thread) holding its own Python, Dask and Warp, so more of them than
    cores only share the cores, at about 40 MB each (a blind probe's --workers 1000 on 2 cores started 513
    processes holding 21 GB before it was stopped)."""
    if workers is None:
        return
    if workers < 0:
        raise KnitsimInputError(f"--workers = {workers}: expected 0 (no Dask) or a positive number")
    from ..warp_runtime import usable_cores     # (Warp itself imported only where a sweep runs)

    cores = usable_cores()
    if not scheduler and workers > cores:
        raise KnitsimInputError(f"--workers = {workers}: more than the {cores} core(s) of this machine (each worker "
                                f"is a single-threaded process: more of them only share the cores, each holding its "
                                f"own memory); use at most {cores}, or leave --workers out (one per core)")


#: how long a connection to a ``--scheduler`` is tried before it is refused
SCHEDULER_TIMEOUT = "20s"


def check_scheduler(scheduler: str | None) -> None:
    """Refuse a ``scheduler`` address that cannot be connected to, before any output is written (a blind probe's
    unreachable address was refused after the sweep's folder, manifest and chunks/ were made: a plain rerun was
    then refused as a folder that already holds results)."""
    if not scheduler:
        return
    try:
        from dask.distributed import Client
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise KnitsimInputError(f"--scheduler: Dask is not available ({exc}); use --workers 0") from None
    try:
        Client(scheduler, timeout=SCHEDULER_TIMEOUT).close()
    except (OSError, TimeoutError, ValueError) as exc:
        raise KnitsimInputError(f"--scheduler = {scheduler!r}: cannot connect ({exc})") from None


def _run_dask(tasks: list[dict], progress: _Progress, done: list, workers: int | None,
              scheduler: str | None, stream) -> None:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise KnitsimInputError(f"--workers: Dask is not available ({exc}); use --workers 0") from None
    cluster = None
    try:
        if scheduler:
            try:
                client = Client(scheduler, timeout=SCHEDULER_TIMEOUT)
            except (OSError, TimeoutError, ValueError) as exc:
                raise KnitsimInputError(f"--scheduler = {scheduler!r}: cannot connect ({exc})") from None
        else:
            # no more workers than chunks to run: a worker without a chunk only costs its start and its memory
            from ..warp_runtime import usable_cores

            n = max(1, min(workers or usable_cores(), len(tasks)))
            with _workers_ignore_sigint():
                # (CRITICAL: a worker's ERROR log of a heartbeat to the scheduler closed under it, with three
                # tracebacks, came after an interrupted sweep's "interrupted" line; a chunk's failure comes back
                # on its future, said by knitsim)
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.CRITICAL)
            client = Client(cluster)
        if stream is not None:
            nw = len(client.scheduler_info().get("workers", {}))
            print(f"knitsim sweep: Dask {'cluster ' + scheduler if scheduler else 'local cluster'}, "
                  f"{nw} worker(s)", file=stream, flush=True)
        futures = [client.submit(run_chunk, t, key=f"knitsim-sweep-chunk-{t['chunk']}-{os.getpid()}", pure=False)
                   for t in tasks]
        failed = []
        try:
            for fut in as_completed(futures):
                if fut.status == "error":
                    exc = fut.exception()
                    failed.append((fut.key, exc))
                    continue
                r = fut.result()
                done.append(r["chunk"])
                progress(r["samples"])
        except BaseException:
            client.cancel(futures)
            raise
        if failed:
            key, exc = failed[0]
            raise SweepChunkError(f"{len(failed)} chunk(s) failed, e.g. {key}: {type(exc).__name__}: {exc}")
    finally:
        try:
            if "client" in locals():
                client.close()
        finally:
            if cluster is not None:
                cluster.close()


def run_sweep(plan: SweepPlan, out_dir: str | Path, resume: bool = False, workers: int | None = 0,
              scheduler: str | None = None, progress=sys.stderr, plots: bool = True) -> SweepRun:
    """Run the chunks of a plan that are not done yet, then assemble the results.

    Parameters
    ----------
    plan : SweepPlan
    out_dir : path
        The output directory (see the module docstring).
    resume : bool
        Continue the sweep in ``out_dir`` (same hash required); skip chunks whose file exists.
    workers : int or None
        0: in this process; N > 0: a Dask LocalCluster of N single-threaded
        worker processes; None: one per core.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``); ``workers`` is then ignored.
    progress : file or None
        Where progress lines go (stderr by default).
    plots : bool
        Write the PNG plots.

    Returns
    -------
    SweepRun

    Raises
    ------
    KnitsimInputError
        Output directory in use, ``--resume`` of a different sweep.
    SweepChunkError
        A chunk failed in a Dask worker (finished chunks are kept).
    """
    out = Path(out_dir)
    check_workers(workers, scheduler)
    _prepare_out(plan, out, resume)
    # summary.json says the outputs beside it are complete: not while this run changes them (an interrupted
    # resume of a finished sweep would leave the old one beside new chunks)
    (out / "summary.json").unlink(missing_ok=True)
    run = SweepRun(out)
    pending = []
    for c in plan.chunks:
        path = out / CHUNK_DIR / c.name
        if resume and path.is_file() and _chunk_readable(path):
            run.skipped.append(c.index)
        else:
            if resume and path.is_file() and progress is not None:
                # (chunks are written whole, through a temporary file: one that cannot be read was damaged
                # after; a blind probe's ended in a BadZipFile traceback)
                print(f"knitsim sweep: {path} cannot be read: computed again", file=progress, flush=True)
            pending.append(c)
    if progress is not None:
        print(f"knitsim sweep: {plan.n_samples} samples x {plan.n_cells} cell(s), {len(plan.chunks)} chunk(s) "
              f"({len(run.skipped)} done before), engine {plan.engine}, device {plan.device}",
              file=progress, flush=True)
    tasks = [_task(plan, c, out) for c in pending]
    prog = _Progress(progress, len(plan.chunks), plan.n_samples, len(run.skipped))
    t0 = time.perf_counter()
    try:
        if not tasks:
            pass
        elif workers == 0 and not scheduler:
            _run_local(tasks, prog, run.computed)
        else:
            _run_dask(tasks, prog, run.computed, workers, scheduler, progress)
    finally:
        run.wall_s = time.perf_counter() - t0
        run.n_computed_samples = sum(len(plan.chunks[i].samples) for i in run.computed)
    ds = assemble(out)
    run.dataset = ds
    files = write_results(out, ds, plots=plots)
    run.plot_error = files.pop("plot_error", None)
    run.files = files
    # the flags go where the user looks: the plot's title counts them and says "see summary.json"; a
    # library caller gets the file too, not only the command line.  Written last: its presence says the
    # outputs beside it are complete
    run.files["summary.json"] = out / "summary.json"
    run.summary = sweep_summary(plan, run)
    atomic_write_text(out / "summary.json", json_text(run.summary))
    return run


def sweep_summary(plan: SweepPlan, run: SweepRun) -> dict:
    """The ``summary.json`` document of a finished run: its figures, its files and the flagged sample cells
    with their reasons (failed, no rest state, outside the domain's box, a loop that returns energy, a
    compressive rest state, stopped at the force cap in any cycle, the last included), each kind counted and
    listed up to :data:`SUMMARY_LISTED` (:func:`_listing`)."""
    from ..cell.domain import DOMAIN_NO_REST_STATE, DOMAIN_OUTSIDE_BOX

    ds, out = run.dataset, run.out
    failed = failed_samples(ds)
    no_rest = domain_samples(ds, DOMAIN_NO_REST_STATE)
    energy = energy_creating_samples(ds)
    compressive = compressive_rest_samples(ds)
    capped = capped_samples(ds)
    warned = {k: warning_samples(ds, k) for k in _WARNING_FLAGS}
    outside = domain_samples(ds, DOMAIN_OUTSIDE_BOX)
    return {
        "out": str(out), "hash": plan.hash, "method": plan.spec.method, "parameters": plan.spec.keys,
        "samples": plan.n_samples, "cells_per_sample": plan.n_cells, "chunks": len(plan.chunks),
        "computed_chunks": len(run.computed), "skipped_chunks": len(run.skipped), "wall_s": run.wall_s,
        "samples_per_s": run.samples_per_s, "cells_not_finished": len(failed) + len(no_rest),
        **_listing("failed", failed),
        # outside the model (no rest state: not solved) and outside the domain's box (solved, extrapolated)
        **_listing("no_rest_state", no_rest), **_listing("outside_domain", outside),
        # a closed loop that returns energy (oint F dC < 0: Table 4's frozen force closures), flagged not fixed
        **_listing("loop_creates_energy", energy),
        # a rest state the grips must push to hold (F < 0 at C0, W0): not free at rest
        **_listing("rest_state_compressive", compressive),
        # stopped at the force cap in any cycle (a stop, not a failure): that peak the cap, later cycles NaN
        **_listing("stopped_at_force_cap", capped),
        # the cell's own warnings (knitsim cell's): overlapping heads, a cycle that lost nearly all its force
        **{key: v for k, rows in warned.items() for key, v in _listing(k, rows).items()},
        "files": {k: str(v) for k, v in run.files.items()},
        # the base scene's values (or the library materials it names) come from a flagged calibration: every
        # sample's do (knitsim.io.checks.calibration_warnings)
        "warnings": [{k: v for k, v in w.items() if k != "cell"}
                     for w in checks.calibration_warnings(getattr(plan.base, "calibration_flags", []))]
        + list(plan.warnings),
        # the plot could not be drawn (the results are complete without it): why
        **({"plot_error": run.plot_error} if run.plot_error else {}),
    }


#: flagged samples listed by name in a sweep's summary.json, per kind of flag (the rest counted, and each sample's flag
#: in results.csv / results.nc): a 50,000-sample sweep's lists were 46 MB, ~360 bytes a listed sample
SUMMARY_LISTED = 1000

#: the variable of results.csv / results.nc that holds each listing's flag for every sample
_LISTED_VARIABLE = {"failed": "final_status and expected_end", "no_rest_state": "domain", "outside_domain": "domain",
                    "stopped_at_force_cap": "peak_at_force_cap"}


def _listing(key: str, rows: list[dict]) -> dict:
    """A listing of summary.json: ``key`` (the first :data:`SUMMARY_LISTED` samples), ``key_count`` (all of them)
    and, where some are left out, ``key_listed`` saying where every sample's flag is."""
    out = {f"{key}_count": len(rows), key: rows[:SUMMARY_LISTED]}
    if len(rows) > SUMMARY_LISTED:
        out[f"{key}_listed"] = (f"the first {SUMMARY_LISTED} of {len(rows)}; every sample's flag is in results.csv and "
                                f"results.nc ({_LISTED_VARIABLE.get(key, key)})")
    return out


def write_results(out: Path, ds, plots: bool = True) -> dict[str, Path | str]:
    """Write ``results.nc``, ``results.csv`` and the plots of an assembled dataset.

    Everything is rendered before any file is written (the previous run's ``summary.json``, what says the
    outputs are complete, was removed by :func:`run_sweep` before any chunk ran): a blind probe's plot
    crashed after results.csv and results.nc were written, leaving them looking complete.  A plot that
    cannot be drawn does not cost the results: they are written, ``plot_sweep.png`` is not (an older one is
    removed), and the error is returned under the key ``"plot_error"`` (a string, not a path).

    Returns
    -------
    dict
        File name -> path of each written file, and ``"plot_error"`` when the plot failed.
    """
    from .plots import PLOT_FILES, render_sweep

    text = dataset_csv(ds)
    images, plot_error = {}, None
    if plots:
        try:
            images = render_sweep(ds)
        except Exception as exc:      # noqa: BLE001 - a plot bug must not cost the results; it is reported
            plot_error = f"{type(exc).__name__}: {exc}"
    for name in PLOT_FILES:
        if name not in images:        # --no-plot or a failed plot: no stale figure of an earlier run
            (out / name).unlink(missing_ok=True)
    files: dict = {}
    tmp = out / ".results.nc.tmp"
    ds.to_netcdf(tmp, engine="scipy")
    os.replace(tmp, out / "results.nc")
    files["results.nc"] = out / "results.nc"
    atomic_write_text(out / "results.csv", text)
    files["results.csv"] = out / "results.csv"
    for name, data in images.items():
        atomic_write_bytes(out / name, data)
        files[name] = out / name
    if plot_error is not None:
        files["plot_error"] = plot_error
    return files


# ------------------------------------------------------------------ assembly
def assemble(out_dir: str | Path):
    """The labelled dataset of a sweep directory, from its manifest and chunk files.

    Grid: one dimension per swept parameter (named by its key path, in the
    spec's order) with the grid values as coordinates; LHS: a ``sample``
    dimension with one coordinate per parameter.  Then ``cell`` (only when
    the scene has several ``[[cells]]``), ``cycle`` (from 1) and, with
    curves, ``increment``.  Samples of a missing chunk are NaN with
    ``final_status = -1``; the results of a cell that failed (``expected_end = 0``) are NaN too,
    its ``final_status`` gives the reason, so that no fit or summary takes them for results.

    Returns
    -------
    xarray.Dataset
    """
    import xarray as xr

    from ..cell.domain import DOMAIN_NAMES
    from ..cell.history import STATUS_NAMES

    out = Path(out_dir)
    man = json.loads((out / MANIFEST).read_text())
    keys, shape, spec = man["parameters"], tuple(man["shape"]), man["spec"]
    table = man["samples"]
    ns, labels = len(table), man["cell_labels"]
    nc = len(labels)
    parts, missing = [], []
    for c in man["chunks"]:
        f = out / c["file"]
        if f.is_file():
            with np.load(f) as z:
                parts.append({k: z[k] for k in z.files})
        else:
            missing.append(c["index"])
    if parts:
        ny = parts[0]["peak_force_per_wale_N"].shape[2]
    else:
        ny = 1
    curves = bool(parts) and "force_per_wale_N" in parts[0]
    ni = max((p["force_per_wale_N"].shape[2] for p in parts), default=0) if curves else 0
    data = {k: np.full((ns, nc, ny), np.nan) for k in CYCLE_VARS}
    data.update({k: np.full((ns, nc, ny), -1, dtype=np.int8) for k in CYCLE_FLAGS})
    data["strain_at_first_jamming"] = np.full((ns, nc), np.nan)
    data["final_status"] = np.full((ns, nc), -1, dtype=np.int32)
    data["expected_end"] = np.zeros((ns, nc), dtype=np.int8)
    data["loop_creates_energy"] = np.full((ns, nc), -1, dtype=np.int8)
    data["rest_state_compressive"] = np.full((ns, nc), -1, dtype=np.int8)
    for k in _WARNING_FLAGS:
        data[k] = np.full((ns, nc), -1, dtype=np.int8)
    for k in _STOP_VARS:
        data[k] = np.full((ns, nc), np.nan)
    if curves:
        data["force_per_wale_N"] = np.full((ns, nc, ni), np.nan)
        data["imposed_strain"] = np.full((ns, ni), np.nan)
    for p in parts:
        idx = p["samples"]
        for k in CYCLE_VARS + CYCLE_FLAGS + CELL_VARS:
            if k in p:                      # a chunk written before a flag existed: -1 unknown
                data[k][idx] = p[k]
        if curves:
            n = p["force_per_wale_N"].shape[2]
            data["force_per_wale_N"][idx, :, :n] = p["force_per_wale_N"]
            data["imposed_strain"][idx, :n] = p["imposed_strain"][None, :]
    # a cell that failed (did not finish nor stop at its force cap) has no results: NaN, its status says why
    failed = (data["expected_end"] == 0) & (data["final_status"] >= 0)
    for k in CYCLE_VARS:
        data[k][failed] = np.nan
    for k in CYCLE_FLAGS:
        data[k][failed] = -1
    # and no judgement of its cycles: -1, as the variables' descriptions say (a blind probe read 0 / 1 flags on
    # failed samples, judged on the rows before the failure); its rest state is judged (before any solve)
    for k in _WARNING_FLAGS + ("loop_creates_energy",):
        data[k][failed] = -1
    data["strain_at_first_jamming"][failed] = np.nan
    # where each cell stands with the model's domain, found by the planner before any solve (older
    # manifests without it: unknown, -1)
    dom = man.get("domain")
    data["domain"] = (np.asarray(dom, dtype=np.int8).reshape(ns, nc) if dom is not None
                      else np.full((ns, nc), -1, dtype=np.int8))
    domain_reasons = {f"{i}:{c}": r for i, row in enumerate(man.get("domain_reasons") or [])
                      for c, r in enumerate(row) if r is not None}

    if spec["method"] == "grid":
        lead = list(keys)
        coords = {}
        for j, k in enumerate(keys):
            entry = next(e for e in spec["parameters"] if e["key"] == k)
            vals = entry["values"] if "values" in entry else np.linspace(entry["min"], entry["max"], entry["count"])
            coords[k] = np.asarray(vals)
        reshape = lambda a: a.reshape(shape + a.shape[1:])  # noqa: E731
    else:
        lead = ["sample"]
        coords = {"sample": np.arange(ns, dtype=np.int32)}
        for j, k in enumerate(keys):
            coords[k] = ("sample", np.asarray([r[j] for r in table], dtype=np.float64))
        reshape = lambda a: a  # noqa: E731
    squeeze = nc == 1
    cell_dims = [] if squeeze else ["cell"]
    if not squeeze:
        coords["cell"] = np.arange(nc, dtype=np.int32)
        coords["cell_label"] = ("cell", np.asarray(labels, dtype=str))
    coords["cycle"] = np.arange(1, ny + 1, dtype=np.int32)
    units = {"peak_force_per_wale_N": "N", "strain_at_peak": "1", "residual_strain": "1", "energy_N_mm": "N mm",
             "energy_N_per_strain": "N", "strain_at_first_jamming": "1", "force_per_wale_N": "N",
             "imposed_strain": "1", "stopped_at_strain": "1", "last_converged_strain": "1",
             "last_converged_force_per_wale_N": "N"}
    docs = {
        "peak_force_per_wale_N": "largest force per wale of the cycle",
        "strain_at_peak": "imposed strain (C - C0)/C0 at the peak force",
        "residual_strain": "strain C/C0 - 1 where the force reaches 0 on the cycle's unloading (NaN: never)",
        "energy_N_mm": "oint F dC over the cycle per wale, N mm: the hysteresis of a closed cycle, the work of "
                       "an open one (knitsim.io.checks.cycle_work)",
        "energy_N_per_strain": "oint F d(strain) over the cycle",
        "energy_kind": "what energy_N_mm is (knitsim.io.checks.cycle_work, energy_kind of knitsim cell): "
                       + ", ".join(f"{k} {v}" for k, v in ENERGY_KINDS.items())
                       + " (hysteresis: a closed cycle's dissipated energy; work: an open cycle's, elastic energy "
                       "included; loading_work: a cycle that never unloaded, e.g. cut by the force cap; "
                       "unloading_work: one that never loaded, a program starting by unloading), -1 no value",
        "closed": "1 if the cycle's path ends at the strain it started from (its energy is a hysteresis), 0 if "
                  "not, -1 no value",
        "peak_at_force_cap": "1 for the cycle in which the cell stopped at its force cap: its peak is the cap "
                             "(rules.force_cap_N), not the knit's, and the rest of the program was not run; 0 "
                             "otherwise, -1 no value",
        "strain_at_first_jamming": "strain C/C0 - 1 at the first jamming (NaN: never jammed)",
        "final_status": "status code at the end: " + ", ".join(f"{k} {v}" for k, v in STATUS_NAMES.items())
                        + ", -1 not run",
        "expected_end": "1 if the cell completed the program or stopped at the force cap",
        "loop_creates_energy": "1 if a closed load-then-unload loop of the cell returns energy (oint F dC < 0), or "
                               "an unload-reload loop from a peak does while the stitch's stored bending energy "
                               "did not fall (warning loop_creates_energy, knitsim.io.checks.energy_creating_loops; "
                               "Table 4's frozen force closures, README 'Loops that return energy'), 0 if none "
                               "does, -1 not solved, failed (no judgement of its cycles) or unknown",
        "rest_state_compressive": "1 if the cell's rest state carries a compressive force (F < 0 at C0, W0: the knit "
                                  "is not free at rest; warning rest_state_compressive, knitsim.io.checks."
                                  "compressive_rest_state; its loops from rest are not judged for energy), 0 if not, "
                                  "-1 not solved or unknown",
        "heads_interpenetrate": "1 if the heads of neighbouring loops overlap somewhere in the program (centreline gap "
                                "below the in-plane width: warning heads_interpenetrate of knitsim cell), 0 if not, "
                                "-1 not solved, failed (no judgement of its cycles) or unknown",
        "zero_force_cycle": "1 if a later cycle peaks at a few per cent of the largest earlier peak (warning "
                            "zero_force_cycle of knitsim cell, knitsim.io.checks.zero_force_cycles), 0 if not, -1 not "
                            "solved, failed (no judgement of its cycles) or unknown",
        "reload_below_earlier_loading": "1 if a later cycle carries less than half the earlier force at the earlier "
                                        "maximum strain, or peaks at a new maximum strain below 90 % of an earlier peak "
                                        "(warning reload_below_earlier_loading of knitsim cell, knitsim.io.checks."
                                        "reloads_below_earlier_loading), 0 if not, "
                                        "-1 not solved, failed (no judgement of its cycles) or unknown",
        "reload_loss_continues": "1 if cycles loading to the same strain go on losing peak force after their first "
                                 "reload (a second or later reload below 90 % of the cycle before it: warning "
                                 "reload_loss_continues of knitsim cell, knitsim.io.checks.reloads_without_shakedown), "
                                 "0 if not, -1 not solved, failed (no judgement of its cycles) or unknown",
        "reload_above_first_loading": "1 if a later cycle reloads above 1.25 times the first loading's force at the "
                                      "same strain, below the earlier maximum strain (warning "
                                      "reload_above_first_loading of knitsim cell, knitsim.io.checks."
                                      "reloads_above_first_loading), 0 if not, "
                                      "-1 not solved, failed (no judgement of its cycles) or unknown",
        "reload_below_first_loading": "1 if a reload past an earlier maximum carries less than 90 % of what the "
                                      "same cell pulled monotonically carries there (warning "
                                      "reload_below_first_loading of knitsim cell, knitsim.io.checks."
                                      "reloads_below_first_loading; judged only where the program reloads past an "
                                      "earlier maximum), 0 if not, -1 not solved, failed or unknown",
        "wale_spacing_below_jamming": "1 if the wale spacing W falls below 4 w somewhere in the program (w the "
                                      "in-plane width; outside the model: warning wale_spacing_below_jamming of "
                                      "knitsim cell, knitsim.io.checks.wale_spacing_below_jamming; the head-gap "
                                      "criterion allows it), 0 if not, -1 not solved, failed or unknown",
        "domain": "where the cell stands with the model's domain (knitsim.cell.domain), found before any "
                  "solve: " + ", ".join(f"{k} {v}" for k, v in DOMAIN_NAMES.items())
                  + " (outside_domain: solved, an extrapolation beyond the box where convergence is "
                  "promised; no_rest_state: outside the model, not solved), -1 unknown; reasons in the "
                  "attribute domain_reasons",
        "stopped_at_strain": "a failed cell: the imposed strain of the increment it could not finish; a cell "
                             "stopped at its force cap: the imposed strain of the increment it reached the cap in "
                             "(0: at rest, its rest state at or above the cap; NaN: it ran the whole program)",
        "last_converged_strain": "a failed cell: the strain C/C0 - 1 of its last converged state, inside that "
                                 "increment (NaN: it did not fail)",
        "last_converged_force_per_wale_N": "a failed cell: its force per wale there (NaN: it did not fail)",
        "force_per_wale_N": "force per wale at every increment (NaN past the program's end, and where the cell did "
                            "not solve: after a failure, past a stop at the force cap); increment 0 is the "
                            "program's first increment, not the rest state (knitsim cell's curve.csv row 0)",
        "imposed_strain": "imposed strain of the course length at every increment (increment 0: the program's "
                          "first, not the rest state)",
    }
    vars_ = {}
    for k in CYCLE_VARS + CYCLE_FLAGS:
        a = reshape(data[k])
        vars_[k] = (lead + cell_dims + ["cycle"], a[..., 0, :] if squeeze else a)
    for k in CELL_VARS + ("domain",):
        a = reshape(data[k])
        vars_[k] = (lead + cell_dims, a[..., 0] if squeeze else a)
    if curves:
        a = reshape(data["force_per_wale_N"])
        vars_["force_per_wale_N"] = (lead + cell_dims + ["increment"], a[..., 0, :] if squeeze else a)
        vars_["imposed_strain"] = (lead + ["increment"], reshape(data["imposed_strain"]))
        coords["increment"] = np.arange(ni, dtype=np.int32)
    ds = xr.Dataset(vars_, coords=coords)
    for k in ds.data_vars:
        ds[k].attrs["description"] = docs[k]
        if k in units:
            ds[k].attrs["units"] = units[k]
    # CF flag attributes: a netCDF reader names the codes without the description
    ds["energy_kind"].attrs.update(flag_values=np.array(list(ENERGY_KINDS), dtype=np.int8),
                                   flag_meanings=" ".join(ENERGY_KINDS.values()))
    for k in keys:
        ds[k].attrs["key_path"] = k
        # the axis's unit, the scene field's (a reader of results.nc could not tell knit.L's mm from phi0's rad)
        f = field_at(CELL_SCENE, k)
        if f is not None and f.unit:
            ds[k].attrs["units"] = f.unit
    ds.attrs.update({
        "title": str(man["base_resolved"].get("title", "")), "method": spec["method"],
        "parameters": json.dumps(keys), "spec": json.dumps(spec), "sweep_hash": man["hash"],
        "engine": man["engine"], "device": man["device"], "source": str(man["source"]),
        "missing_chunks": json.dumps(missing), "knitsim_version": str(man["versions"].get("knitsim")),
        "domain_reasons": json.dumps(domain_reasons),
        "created_by": "knitsim sweep",
    })
    return ds


def dataset_csv(ds) -> str:
    """``results.csv``: one row per sample, cell and cycle (parameters first, then the results)."""
    keys = json.loads(ds.attrs["parameters"])
    lead = ["sample"] if ds.attrs["method"] == "lhs" else keys
    has_cell = "cell" in ds.dims
    order = lead + (["cell"] if has_cell else []) + ["cycle"]
    has_domain = "domain" in ds.data_vars
    cell_vars = list(CELL_VARS) + (["domain"] if has_domain else [])
    cols = ["sample"] + keys + (["cell", "cell_label"] if has_cell else []) + ["cycle"] + list(CYCLE_VARS) \
        + list(CYCLE_FLAGS) + cell_vars
    parts = {k: ds[k].transpose(*order) for k in CYCLE_VARS + CYCLE_FLAGS}
    parts.update({k: ds[k].broadcast_like(ds["peak_force_per_wale_N"]).transpose(*order) for k in cell_vars})
    shape = parts["peak_force_per_wale_N"].shape
    flat = {k: np.asarray(v.values).reshape(-1) for k, v in parts.items()}
    idx = np.indices(shape).reshape(len(shape), -1)
    lead_shape = shape[: len(lead)]
    sample = np.ravel_multi_index(idx[: len(lead)], lead_shape) if lead_shape else np.zeros(idx.shape[1], int)
    # csv quoting (a value or cell label holding a comma, "E-glass, m 0.2", split its row into one column more than
    # the header: a blind probe's pandas read the label into the cell column); other rows are as they were
    buf = io.StringIO()
    lines = csv.writer(buf, lineterminator="\n")
    lines.writerow(cols)
    from ..cell.domain import DOMAIN_NAMES
    from ..cell.history import STATUS_NAMES
    names = {**STATUS_NAMES, -1: "not_run"}
    domain_names = {**DOMAIN_NAMES, -1: "unknown"}

    def num(v):
        v = float(v)
        return repr(v) if np.isfinite(v) else ""

    for r in range(idx.shape[1]):
        row = [str(int(sample[r]))]
        if ds.attrs["method"] == "lhs":
            row += [num(ds[k].values[idx[0, r]]) for k in keys]
        else:
            for j, k in enumerate(keys):
                v = ds[k].values[idx[j, r]]
                row.append(num(v) if np.issubdtype(np.asarray(v).dtype, np.number) and not isinstance(v, bool)
                           else str(v))
        if has_cell:
            c = int(idx[len(lead), r])
            row += [str(c), str(ds["cell_label"].values[c])]
        row.append(str(int(idx[-1, r]) + 1))
        row += [num(flat[k][r]) for k in CYCLE_VARS]
        kind = int(flat["energy_kind"][r])
        row.append(ENERGY_KINDS.get(kind, ""))           # empty where the cycle has no value
        row += ["" if int(flat[k][r]) < 0 else str(int(flat[k][r])) for k in ("closed", "peak_at_force_cap")]
        loop = int(flat["loop_creates_energy"][r])
        rest = int(flat["rest_state_compressive"][r])
        row += [num(flat["strain_at_first_jamming"][r]), names.get(int(flat["final_status"][r]), "?"),
                str(int(flat["expected_end"][r])), "" if loop < 0 else str(loop), "" if rest < 0 else str(rest)]
        # where a cell stopped (empty for one that ran the whole program): a blind probe found these three
        # header columns never written, every later value one column to the left of its name
        row += [num(flat[k][r]) for k in _STOP_VARS]
        row += ["" if int(flat[k][r]) < 0 else str(int(flat[k][r])) for k in _WARNING_FLAGS]
        if has_domain:
            row.append(domain_names.get(int(flat["domain"][r]), "?"))
        lines.writerow(row)
    return buf.getvalue()


__all__ = ["assemble", "dataset_csv", "SweepPlan", "SweepRun", "Chunk", "SweepChunkError", "plan_sweep",
           "run_sweep", "run_chunk", "failed_samples", "domain_samples", "energy_creating_samples",
           "compressive_rest_samples",
           "reduce_history", "sweep_hash", "sweep_inputs", "manifest", "write_results", "MANIFEST", "CHUNK_DIR",
           "CYCLE_VARS", "CYCLE_FLAGS", "ENERGY_KINDS", "CELL_VARS"]


def _sample_listing(ds, select, reason, extra: tuple = ()) -> list[dict]:
    """Samples (and cells) where ``select(status, expected_end, domain)`` holds, with ``reason(sample, cell,
    status, domain)`` (and a dict of the ``extra`` variables' values there, when named)."""
    keys = json.loads(ds.attrs["parameters"])
    lead = ["sample"] if ds.attrs["method"] == "lhs" else keys
    has_cell = "cell" in ds.dims
    order = lead + (["cell"] if has_cell else [])
    status = np.asarray(ds["final_status"].transpose(*order).values)
    ok = np.asarray(ds["expected_end"].transpose(*order).values)
    dom = (np.asarray(ds["domain"].transpose(*order).values) if "domain" in ds.data_vars
           else np.full(status.shape, -1, dtype=np.int8))
    more = {k: np.asarray(ds[k].transpose(*order).values) for k in extra if k in ds.data_vars}
    bad = np.argwhere(select(status, ok, dom))
    lead_shape = status.shape[:len(lead)]
    # each parameter's value at every sample, read once (a dataset selection per listed sample, ~0.2 ms each, made a
    # 50,000-sample sweep's listings ~90 s of silence)
    values = {k: np.asarray(ds[k].broadcast_like(ds["final_status"]).transpose(*order).values) for k in keys} \
        if len(bad) else {}
    out = []
    for idx in bad:
        idx = tuple(int(i) for i in idx)
        sel = dict(zip(order, idx))
        sample = int(np.ravel_multi_index(idx[:len(lead)], lead_shape)) if lead_shape else 0
        params = {k: (v[idx].item() if hasattr(v[idx], "item") else v[idx]) for k, v in values.items()}
        args = (sample, sel.get("cell") or 0, int(status[idx]), int(dom[idx]))
        if extra:
            args += ({k: float(v[idx]) for k, v in more.items()},)
        out.append({"sample": sample, "parameters": params, "cell": sel.get("cell"), "reason": reason(*args)})
    return out


def failed_samples(ds) -> list[dict]:
    """The samples whose cell failed: it ran, but neither finished nor stopped at its force cap.

    A cell without an admissible rest state is not among them (it was not run: :func:`domain_samples`).

    Returns
    -------
    list of dict
        ``sample`` (flat index), ``parameters`` (key path -> value), ``cell`` (None for one cell)
        and ``reason``: the status name, and where it stopped (the increment it could not finish, its last
        converged strain and force per wale) where the dataset holds it.
    """
    from ..cell.domain import DOMAIN_NO_REST_STATE
    from ..cell.history import STATUS_NAMES, STATUS_NO_REST_STATE, solver_stop_reason

    def reason(i, c, st, dom, at):
        why = STATUS_NAMES.get(st, "unknown")
        if all(np.isfinite(at.get(k, np.nan)) for k in _STOP_VARS):
            # the stage is not kept in the dataset: knitsim cell on the sample's scene adds it and the cap advice
            why += ": " + solver_stop_reason(st, at["last_converged_strain"], at["stopped_at_strain"], None,
                                             at["last_converged_force_per_wale_N"], float("inf"), False)
        return why

    return _sample_listing(
        ds, lambda st, ok, dom: (ok == 0) & (st >= 0) & (st != STATUS_NO_REST_STATE) & (dom != DOMAIN_NO_REST_STATE),
        reason, extra=_STOP_VARS)


def domain_samples(ds, code: int) -> list[dict]:
    """The samples whose cell has domain code ``code`` (knitsim.cell.domain: 1 outside the box,
    2 no admissible rest state), each with the planner's reason (``reason``) and its status."""
    from ..cell.domain import DOMAIN_NAMES
    from ..cell.history import STATUS_NAMES, STATUS_NO_REST_STATE

    reasons = json.loads(ds.attrs.get("domain_reasons", "{}"))

    def why(i, c, st, dom):
        text = reasons.get(f"{i}:{c}", DOMAIN_NAMES[code])
        return text if st == STATUS_NO_REST_STATE else f"{text} (status {STATUS_NAMES.get(st, 'not_run')})"

    return _sample_listing(ds, lambda st, ok, dom: dom == code, why)


def capped_samples(ds) -> list[dict]:
    """The samples whose cell stopped at its force cap: a stop, not a failure, but the rest of the program
    was not run: the cycles after it have no results (NaN), which a plot would otherwise just omit, and the
    cycle it stopped in has the cap for its peak and loading work for its energy (a blind probe's stop in a
    one-cycle program was reported nowhere, its 10 N peak and loading work drawn as the knit's).

    Returns
    -------
    list of dict
        As :func:`failed_samples`; ``reason`` names the cycles without results.
    """
    from ..cell.history import STATUS_FORCE_CAP

    keys = json.loads(ds.attrs["parameters"])
    order = (["sample"] if ds.attrs["method"] == "lhs" else keys) + (["cell"] if "cell" in ds.dims else [])
    peaks = np.asarray(ds["peak_force_per_wale_N"].transpose(*order, "cycle").values)
    cycles = [int(c) for c in ds["cycle"].values]
    missing = np.isnan(peaks)

    def reason(i, c, st, dom, stop):
        idx = np.unravel_index(i, peaks.shape[:len(order) - ("cell" in ds.dims)]) + (((c,) if "cell" in ds.dims else ()))
        lost = [cyc for cyc, m in zip(cycles, missing[idx]) if m]
        last = max((cyc for cyc, m in zip(cycles, missing[idx]) if not m), default=None)
        if stop.get("stopped_at_strain") == 0.0 and last is not None:
            # stopped at rest (its rest state already at the cap): no cycle ran, its cycle-1 peak is the rest force
            return (f"stopped at rest: its force per wale at rest, {peaks[idx][cycles.index(last)]:.4g} N, is already "
                    "at or above its force cap: no load program can start from it (no cycle run; cycle 1's peak is "
                    "the rest force); raise rules.force_cap_N above the rest force")
        at = (f"in cycle {last}, whose peak is the cap and whose energy is loading work only (the rest of the "
              "program not run)" if last is not None else "")
        gone = (f"before cycle{'s' if len(lost) > 1 else ''} {', '.join(str(x) for x in lost)}: not run (NaN)"
                if lost else "")
        return f"stopped at its force cap {'; '.join(t for t in (at, gone) if t)}; raise rules.force_cap_N to run it all"

    return _sample_listing(ds, lambda st, ok, dom: st == STATUS_FORCE_CAP, reason, extra=("stopped_at_strain",))


def _flagged_samples(ds, var: str, reason: str) -> list[dict]:
    """The samples (and cells) whose per-cell flag ``var`` is 1, each with ``reason``."""
    if var not in ds.data_vars:
        return []
    keys = json.loads(ds.attrs["parameters"])
    order = (["sample"] if ds.attrs["method"] == "lhs" else keys) + (["cell"] if "cell" in ds.dims else [])
    flag = np.asarray(ds[var].transpose(*order).values)
    return _sample_listing(ds, lambda st, ok, dom: flag == 1, lambda i, c, st, dom: reason)


def compressive_rest_samples(ds) -> list[dict]:
    """The samples whose cell has a compressive rest state (``rest_state_compressive == 1``).

    Returns
    -------
    list of dict
        As :func:`failed_samples`; ``reason`` says what the flag means.
    """
    return _flagged_samples(ds, "rest_state_compressive",
                            "the rest state carries a compressive force (F < 0 at C0, W0): the knit is not free "
                            "at rest; its loops from rest are not judged for energy (README, 'Loops that "
                            "return energy')")


#: what each carried warning means, for the listings
_WARNING_REASONS = {
    "heads_interpenetrate": "the heads of neighbouring loops overlap (centreline gap below the in-plane width): the "
                            "jamming criterion lets them pass through each other (jamming_criterion = \"head_gap\" "
                            "stops them at contact); knitsim cell on the sample says where",
    "zero_force_cycle": "a later cycle peaks at a few per cent of the largest earlier peak: it carries nearly no force "
                        "(README, 'Cycles that carry no force'); knitsim cell on the sample says which",
    "reload_below_earlier_loading": "a later cycle reloads below half the earlier force at the earlier maximum, or its "
                                    "envelope falls (Table 4's S+ keeps Rn where sliding began); knitsim cell on the "
                                    "sample says which cycle",
    "reload_loss_continues": "cycles to the same strain go on losing peak force after their first reload, where a "
                             "measured knit settles (Table 4's S+ starts each reload's sliding at a lower Rn); "
                             "knitsim cell on the sample says which cycles",
    "reload_below_first_loading": "a reload past an earlier maximum carries well below the same cell's monotonic "
                                  "pull (Table 4's S+ restarts sliding at a lower Rn); knitsim cell on the sample "
                                  "says where",
    "wale_spacing_below_jamming": "OUTSIDE THE MODEL: the wale spacing falls below 4 x the in-plane width, the "
                                  "model's jamming limit (the head-gap criterion lets it after the heads touch); "
                                  "knitsim cell on the sample says where",
    "reload_above_first_loading": "a later cycle reloads above the first loading at the same strain (Table 4's S+ "
                                  "freezes Rn, or T, where sliding began); knitsim cell on the sample says which "
                                  "cycle and where",
}


def warning_samples(ds, flag: str) -> list[dict]:
    """The samples whose cell carries the cell summary's warning ``flag`` (:data:`_WARNING_FLAGS`).

    Returns
    -------
    list of dict
        As :func:`failed_samples`; ``reason`` says what the warning means.
    """
    return _flagged_samples(ds, flag, _WARNING_REASONS[flag])


def energy_creating_samples(ds) -> list[dict]:
    """The samples whose cell has a closed loop that returns energy (``loop_creates_energy == 1``).

    Returns
    -------
    list of dict
        As :func:`failed_samples`; ``reason`` says what the flag means.
    """
    return _flagged_samples(ds, "loop_creates_energy",
                            "a closed loop returns energy (oint F dC < 0): not a hysteresis; Table 4's frozen "
                            "force closures (README, 'Loops that return energy')")
