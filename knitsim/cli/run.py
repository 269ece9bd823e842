"""``knitsim run``: run a patch scene (cells in series along wales, columns in parallel).

``knitsim run SCENE.toml [--set key=value ...] [--out DIR] [--resume] [--engine warp|reference]
[--device cpu|cuda|auto] [--usd FILE [--usd-stride N] [--color-by FIELD] [--usd-points N]] [--json]``

The scene (:mod:`knitsim.scene.patch_scene`) is validated in full before any
work.  A progress bar goes to stderr; the patch state is checkpointed into
``DIR/checkpoint.pkl`` (its rows in chunks in ``DIR/checkpoint_rows/``, each written once: see
:mod:`knitsim.patch.records`) every ``output.checkpoint_every`` increments, on
Ctrl-C and when the solve is finished, before any output is written; ``--resume``
continues from it (same results as an uninterrupted run; from a finished solve
it writes the outputs without solving again, on the device that solved: another
is refused).  On Ctrl-C, during the solve or while the outputs are written, the
command says what the checkpoint holds and prints the command that continues
the run (exit status 130; SIGTERM and SIGHUP are taken as a Ctrl-C, exit status 143 and 129: :func:`knitsim.cli.main`).
Results (:mod:`knitsim.io.patch_results`) go to
``DIR`` (default ``<scene stem>_out``), the USD file first, then the result set
(``summary.json`` last: its presence marks a complete set); the checkpoint and its
rows are removed once they are written.
With ``--usd FILE`` the patch is also written as USD (``.usda`` text for small
patches, ``.usdc`` / ``.usd`` binary crate for large ones; see
:mod:`knitsim.usd.from_results`), the same file ``knitsim usd DIR --out FILE``
writes from the saved results (time code k is increment k, 0 the rest state; increments
after the knit stopped, every column held, are not written; the run's warnings go into the
file).  ``FILE`` is checked writable before any work, and the USD options
(``--usd-stride``, ``--color-by``, ``--usd-points``, ``--usd-layout``) are refused
without ``--usd``.  It is written to a hidden file beside ``FILE``
and renamed in when complete.  An existing ``FILE`` is replaced only with
``--overwrite``; on ``--resume`` (which excludes ``--overwrite``) only where the
interrupted run had that consent (its checkpoint records the file it may write).
The first line says what the grid stands for: ``wales x courses`` single stitches, or a
specimen's ``strips x bands`` blocks with the wales and courses of each strip
(:class:`knitsim.io.patch_results.SpecimenLayout`); the USD of a specimen draws
every stitch, each an instance of its block's stitch (:mod:`knitsim.usd.instanced`).
Exit status 0 when the run ended as expected (summary ``all_expected_end``: no failed cell, no column that
failed to converge other than one held at its cells' force cap; a stop at the force cap is an expected end,
its warning shown), 1 otherwise, 2 on bad input, 130 on Ctrl-C, 143 on SIGTERM, 129 on SIGHUP.
"""
from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import KnitsimInputError
from ..io.output_dir import output_lock
from ..cell.effects import effect_set_codes
from ..io.checks import calibration_warnings, inert_effect_warnings
from ..io.results import add_output_flags
from .common import Progress, add_json_flag, naming_scene, print_json


#: warnings said before the run (zones that overlap, a specimen of few stitches), not again after it
_SAID_BEFORE_THE_RUN = ("zones_overlap", "specimen_few_stitches", "effect_without_strength")


def register(subparsers) -> None:
    """Add ``knitsim run``."""
    p = subparsers.add_parser(
        "run", help="run a patch scene (wales x courses cells between rigid grips)",
        description="Run a patch scene: series cells along each wale column, columns in parallel; writes "
                    "curve.csv, columns.csv, cells.nc, summary.json, PNG plots and scene.resolved.toml.")
    p.add_argument("scene", metavar="SCENE.toml", help="patch scene file (see scenes/)")
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[], dest="overrides",
                   help="override a scene key, type-checked, e.g. --set patch.wales=5 (repeatable)")
    p.add_argument("--out", metavar="DIR", default=None, help="output directory (default: <scene stem>_out)")
    p.add_argument("--resume", action="store_true", help="continue from DIR/checkpoint.pkl")
    add_output_flags(p, resumable=True)
    p.add_argument("--engine", choices=("warp", "reference"), default=None, help="override the scene's engine")
    p.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:N or auto")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    from .usd import add_usd_options
    p.add_argument("--usd", metavar="FILE", default=None,
                   help="also export the patch to USD (.usda text, .usdc/.usd binary crate for large patches)")
    add_usd_options(p, prefix="usd-")
    add_json_flag(p)
    p.set_defaults(func=_run)


#: the keys that set each quantity of the domain's box (knitsim.cell.domain.quantity_name), named in a patch's
#: outside_domain warning with the zone, map or table that set them
_DOMAIN_KEYS = {"d": ("d",), "B": ("B",), "W0 / d_jam": ("W0", "d"), "C0 / d": ("C0", "d"),
                "L / (2 C0 + W0 - 4 d)": ("L", "C0", "W0", "d"), "m": ("m",), "phi0": ("phi0", "m")}


def check_patch_domain(model, grip_strains, engine: str, device: str, dedup: bool = True,
                       cell_fields: bool = True, cells_increments: int | None = None,
                       origins: dict | None = None) -> list[dict]:
    """Before any solve: every distinct cell of the patch against the model's domain (knitsim.cell.domain), and
    the run's records against the machine's memory (:func:`check_record_memory`; ``cell_fields``: cells.nc is
    written, holding ``cells_increments`` increments, default all).

    A cell without an admissible rest state is an error (one line: how many cells, the first one's
    course and wale, the reason, and, given the scene's ``origins`` (:attr:`PatchScene.origins`), that cell's
    C0, W0, L and phi0 with the key that set each: a zone's, a map's or the base knit's): the model cannot run
    it, and a column holding it has no rest state either.  So is a cell whose rest state already carries its force
    cap (no program can load it; the key that set the cap named likewise).  Cells outside the domain's box, and a
    grip program whose strains leave it, are an
    extrapolation: returned as ``outside_domain`` warnings for the summary (how many cells, by the
    quantity outside).  Identical cells are checked once (the patch's grouping).  The strains the cells
    reach are judged after the run, from the results (a pretension, or cells in series with stiffer ones,
    take them past the grip's): :func:`knitsim.io.patch_results.patch_summary`.
    """
    import numpy as np

    from ..cell.domain import DOMAIN, check_cell_arrays, quantity_name
    from ..patch.model import cell_name
    from ..scene.schema import fmt

    grouping = model.grouping(dedup=True)
    n_cells = int(grouping.group_of_cell.size)
    # (dedup off: every cell is a group of its own)
    check_record_memory(grouping.n_groups if dedup else n_cells, len(grip_strains), dedup, cell_fields=cell_fields,
                        cells_increments=cells_increments)
    # every group's cell validated (CellParams.validated's message, naming the patch cell), then judged from
    # the groups' arrays: a CellParams per group, validated, and a per-object check made the 300 x 300 random
    # patch's check 4.6-5.0 s on a 2-core box (27 s on a GPU host); from the arrays 2.1-2.4 s, of which the
    # rest-state launch of its 90,000 cells on the CPU is 2.0-2.2 s
    grouping.validate()
    check = check_cell_arrays(grouping.cells, engine=engine, device=device)
    cells_of = np.bincount(grouping.group_of_cell.ravel(), minlength=grouping.n_groups)
    caps = np.asarray(grouping.cells["force_cap_N"], dtype=np.float64)

    def keys_of(i: int, j: int, named) -> str:
        """``; that cell's K = V (the key that set it), ...`` of cell [i, j] for the keys ``named`` ("" without
        the scene's origins)."""
        if origins is None or not named:
            return ""
        unit = "block" if model.blocks else "cell"
        return f"; that {unit}'s " + ", ".join(
            f"{k} = {fmt(float(model.fields[k][i, j] if k in model.fields else caps[grouping.group_of_cell[i, j]]))} "
            f"({origins[k][i, j]})" for k in named if k in origins)

    for bad, why_of, what, source, named in (
            (check.no_rest_mask, check.no_rest_reason, "have no admissible rest state", " (knitsim.cell.domain)",
             ("C0", "W0", "L", "phi0")),
            (check.at_cap_mask(caps), lambda g: check.at_cap_reason(g, caps[g]), "cannot be loaded", "",
             ("force_cap_N",))):
        if bad.any():
            n = int(cells_of[bad].sum())
            i, j = np.argwhere(bad[grouping.group_of_cell])[0]
            # a specimen's block by band and strip, as its zones and maps index them (before, "course 1, wale 0")
            unit, where = ("block" if model.blocks else "cell"), cell_name(int(i), int(j), model.blocks)
            # the keys that set the cell (a zone's knit.L, a gradient map: a blind probe's refusal named neither)
            keys = keys_of(int(i), int(j), named)
            raise KnitsimInputError(f"{n} of {n_cells} {unit}(s) {what}, e.g. {where}: "
                                    f"{why_of(int(grouping.group_of_cell[i, j]))}{source}{keys}")
    warnings = []
    out = check.outside_mask
    if out.any():
        by = ", ".join(f"{k} ({v})" for k, v in check.outside_counts(cells_of).items())
        g = int(np.argmax(out))
        # the example's cell and the keys that set its quantity (a blind probe's warning named neither: which of
        # 10^4 cells, set by which zone or map?)
        i, j = (int(v) for v in np.argwhere(grouping.group_of_cell == g)[0])
        w = model.fields.get("in_plane_width")
        named = _DOMAIN_KEYS[quantity_name(int(check.outside_code[g]))]
        if "d" in named and w is not None and np.isfinite(w[i, j]) and named[0] == "W0":
            named = ("W0", "in_plane_width")          # d_jam is the in-plane width where given
        warnings.append({"code": "outside_domain",
                         "message": f"extrapolation: {int(cells_of[out].sum())} of {n_cells} "
                                    f"{'block' if model.blocks else 'cell'}(s) outside the "
                                    f"model's domain box, by quantity: {by}; e.g. {cell_name(i, j, model.blocks, True)}: "
                                    f"{check.outside_reason(g)}{keys_of(i, j, named)}"})
    why = DOMAIN.why_program_outside(grip_strains)
    if why is not None:
        warnings.append({"code": "outside_domain", "message": f"extrapolation: grip {why}"})
    return warnings


def check_record_memory(n_groups: int, n_increments: int, dedup: bool, available: int | None = None,
                        cell_fields: bool = True, cells_increments: int | None = None) -> None:
    """Refuse, before any work, a run whose per-cell records would not fit in the machine's free memory
    (:func:`knitsim.patch.runner.record_memory_bytes` against ``available``, by default
    :func:`~knitsim.patch.runner.available_memory_bytes`; ``cell_fields``: cells.nc is written, the run's peak,
    holding ``cells_increments`` increments, default all: ``output.cells_stride``):
    it would be killed part-way (a 1000 x 1000 random patch through 620 increments keeps 167 GB, 112 GB without
    cells.nc)."""
    from ..patch.runner import (CELL_FIELDS_COPIES, RECORD_BYTES_PER_GROUP, RECORD_COPIES, available_memory_bytes,
                                record_memory_bytes)
    need = record_memory_bytes(n_groups, n_increments, cell_fields, cells_increments)
    free = available_memory_bytes() if available is None else available
    if free is None or need <= free:
        return
    gib = 2.0 ** 30
    cells = n_increments if cells_increments is None else cells_increments
    copies = RECORD_COPIES + (CELL_FIELDS_COPIES * cells / max(n_increments, 1) if cell_fields else 0)
    what = "the rows and what the outputs derive from them" + (
        (", cells.nc's per-cell fields" + (f" ({cells:,} of the increments)" if cells != n_increments else ""))
        if cell_fields else "")
    without = record_memory_bytes(n_groups, n_increments, False)
    lighter = (f"write no cells.nc (output.cell_fields = false: {without / gib:.3g} GiB), " if cell_fields
               and without <= free else "")
    raise KnitsimInputError(
        f"the run would keep {need / gib:.3g} GiB of per-cell records ({n_groups:,} distinct cell(s) x {n_increments:,} "
        f"increments x {RECORD_BYTES_PER_GROUP} bytes, {copies:.3g} copies at its peak: {what}), more than the "
        f"{free / gib:.3g} GiB free on this machine: it would be killed part-way. Take fewer increments (a larger "
        f"load.max_increment), " + lighter + ("" if dedup else "turn dedup on (identical cells solved once), ")
        + "or run a smaller patch")


def zone_overlaps(resolved: dict) -> list[dict]:
    """``zones_overlap`` warnings: zones (and grades) of the resolved scene that share cells, one per pair.

    Zones do not stack: a cell in two of them is the base scene with the later one's own keys, not the
    earlier zone's (a zone giving only ``knit.L`` over a basalt zone makes E-glass cells of that L).  Allowed
    (later ones on top, as the scene schema says), but rarely what a user means, so said before the run.
    A grade is one zone per element in the resolved scene: its elements are taken together
    (:func:`knitsim.scene.patch_scene.grade_of_zone`), so that a zone over a grade of 20 bands is one warning,
    not 20 (a blind probe's).
    """
    from ..scene.patch_scene import grade_of_zone

    zones = resolved.get("zones") or []
    grades = [grade_of_zone(z) for z in zones]
    labels = [z.get("label") for z, g in zip(zones, grades) if g is None]

    def source(i: int, z: dict) -> tuple[str, str]:
        # (key, name): a grade by its name (its elements one source), else a zone by its place in the list (two
        # zones of one label are two zones: keyed by label, their overlap read as a grade's tiling and went
        # unsaid), named by label, by label and rectangle where zones share it, else by rectangle (grade elements
        # come first in the resolved list: an index would not be the scene's [[zones]] index)
        grade = grades[i]
        if grade is not None:
            return "grade:" + grade, (f"grade {grade!r}" if not grade.startswith("grades[") else grade)
        rect = f"courses [{z['courses'][0]}, {z['courses'][1]}) x wales [{z['wales'][0]}, {z['wales'][1]})"
        label = z.get("label")
        name = ((f"zone {label!r}" + (f" on {rect}" if labels.count(label) > 1 else "")) if label else
                f"the zone on {rect}")
        return f"zone:{i}", name

    sources = [source(i, z) for i, z in enumerate(zones)]
    pairs: dict[tuple[str, str], list[tuple[int, int, int, int]]] = {}
    names: dict[str, str] = dict(sources)
    for b in range(len(zones)):
        for a in range(b):
            za, zb = zones[a], zones[b]
            if sources[a][0] == sources[b][0]:
                continue                   # elements of one grade tile its rectangle
            c0, c1 = max(za["courses"][0], zb["courses"][0]), min(za["courses"][1], zb["courses"][1])
            w0, w1 = max(za["wales"][0], zb["wales"][0]), min(za["wales"][1], zb["wales"][1])
            if c1 > c0 and w1 > w0:
                pairs.setdefault((sources[a][0], sources[b][0]), []).append((c0, c1, w0, w1))
    out = []
    for (ka, kb), rects in pairs.items():
        name_a, name_b = names[ka], names[kb]
        # the cells of both, counted once (a grade's elements meet the other zone in adjacent rectangles)
        c0, c1 = min(r[0] for r in rects), max(r[1] for r in rects)
        w0, w1 = min(r[2] for r in rects), max(r[3] for r in rects)
        covered = np.zeros((c1 - c0, w1 - w0), bool)
        for r in rects:
            covered[r[0] - c0:r[1] - c0, r[2] - w0:r[3] - w0] = True
        n = int(covered.sum())
        where = "on" if n == covered.size else "within"
        out.append({"code": "zones_overlap", "message": (
            f"{name_a} and {name_b} overlap {where} courses [{c0}, {c1}) x wales [{w0}, {w1}) ({n} cells): there "
            f"the cells are the base scene with the keys of {name_b} alone, not those of {name_a} (zones do not stack; "
            "the later one is on top); give the overlap its own zone with every key it needs")})
    return out


def _run_keys(resolved: dict) -> dict:
    """The resolved scene's keys that make the run (not ``title`` or ``[output]``, which --resume may change),
    flat (``specimen.width``), as plain JSON values: kept in the checkpoint, for :func:`scene_changes`."""
    import json

    from ..scene.schema import flat_keys
    return flat_keys(json.loads(json.dumps({k: v for k, v in resolved.items() if k not in ("title", "output")},
                                       default=str)))


def scene_changes(head: dict, resolved: dict) -> str | None:
    """What changed in the scene since a checkpoint (its header ``head``) was written, in words, for
    --resume's refusal (:func:`knitsim.patch.runner.resume_refusal`): ``changed since it was written: key old ->
    new, ...``, or, where no key differs, that a file the scene names changed; None for a checkpoint that did not
    keep its keys (an older knitsim).  Before, the refusal said "another scene, program or engine" without
    what (a blind probe)."""
    from ..scene.schema import key_changes
    old = (head.get("meta") or {}).get("resolved")
    if not isinstance(old, dict):
        return None
    diff = key_changes(old, _run_keys(resolved))
    if not diff:
        return ("its keys are the same: a file it names, a map or a material library, changed since it was "
                "written, or another knitsim wrote it")
    return "changed since it was written: " + ", ".join(diff[:4]) + (f", and {len(diff) - 4} more" if len(diff) > 4
                                                                      else "")


def resume_command(args, out: Path) -> str:
    """The command that continues this run from its checkpoint: the command line as typed, without
    ``--overwrite`` (it and ``--resume`` exclude each other), with ``--out`` and ``--resume``."""
    from .common import resume_command as command_line
    return command_line("run", [args.scene] + [a for kv in args.overrides for a in ("--set", kv)],
                        ["--out", str(out)] if args.out is None else [])


def interrupted_message(ck: Path | None, total: int, resume_cmd: str, writing: bool = False,
                        failed: str | None = None) -> str:
    """What ``knitsim run`` says on Ctrl-C: the checkpoint kept, up to which increment, and the command that
    continues from it; or that nothing was kept.  ``writing``: the Ctrl-C came while the outputs were
    written, after the solve; ``failed``: not a Ctrl-C, writing them failed so (an OSError's text: a full disk).

    The increment is the checkpoint's own (``done``, :func:`knitsim.patch.runner.read_checkpoint_header`):
    :func:`knitsim.patch.runner.run_patch` writes it on Ctrl-C between two increments, and when the solve is
    finished; a Ctrl-C in the middle of an increment that is not let finish keeps the last one."""
    from ..patch.runner import read_checkpoint_header

    during = " while the outputs were written" if writing else ""
    if failed is not None and ck is not None and ck.is_file():
        # (a disk that filled, a folder made read-only: the solve is kept, said as an interruption is)
        return interrupted_message(ck, total, resume_cmd, writing).replace(
            f"knitsim run: interrupted{during}", f"knitsim run: writing the outputs failed ({failed})", 1)
    if ck is None:
        return (f"knitsim run: interrupted{during}; nothing was kept (output.checkpoint_every = 0: no checkpoint); "
                "run again from the start")
    if not ck.is_file():
        return (f"knitsim run: interrupted before the first checkpoint; nothing was kept in {ck.parent}; run again "
                f"from the start")
    try:
        done = int(read_checkpoint_header(ck)["done"])
    except Exception as exc:  # noqa: BLE001 - a damaged checkpoint: say so instead of a traceback
        return f"knitsim run: interrupted; the checkpoint {ck} cannot be read ({exc}); run again from the start"
    if done >= total:
        return (f"knitsim run: interrupted{during}; the solve is finished and kept: {done}/{total} increment(s) in "
                f"the checkpoint {ck}; the outputs in {ck.parent} are not complete (summary.json is written last); "
                f"write them, without solving again, with: {resume_cmd}")
    return (f"knitsim run: interrupted{during}; {done}/{total} increment(s) kept in the checkpoint {ck} (up to "
            f"increment {done}); continue with: {resume_cmd}")


def _usd_on_resume(path: str, head: dict, ck: Path) -> None:
    """``--usd FILE`` with ``--resume``: an existing FILE is replaced only where the interrupted run could
    replace it (it was absent when that run started, or it had --overwrite): its checkpoint names the file.
    Otherwise the file is not this run's, and --resume cannot take --overwrite: refused before any work."""
    from ..io.results import prepare_output_file
    from ..usd.export import check_usd_path

    prepare_output_file(path, True, "--usd")                   # a folder, or not writable: refused as always
    check_usd_path(path, "--usd")
    p = Path(path)
    granted = (head.get("meta") or {}).get("usd")
    if p.exists() and granted != str(p.resolve()):
        was = (f"it may write {granted}" if granted else "it was started without --usd")
        raise KnitsimInputError(f"--usd = {path!r}: exists, and the run resumed from {ck} did not have it to "
                                f"replace ({was}); --resume does not replace a file without consent: remove it or "
                                "choose another --usd")


def _write_usd(h, m, args, scene, device, summary=None):
    """The USD file, written to a hidden file beside ``args.usd`` and renamed in when complete (an interrupted
    export leaves no file that looks whole); ``summary``: the run's, whose warnings and flags go into it."""
    import os

    from ..usd.from_results import DEFAULT_POINTS, export_history
    target = Path(args.usd)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:                 # checked before the solve; a folder changed since: still one line
        raise KnitsimInputError(f"--usd = {args.usd!r}: cannot create its folder ({exc.strerror or exc})") from None
    tmp = target.with_name(f".{target.stem}.partial-{os.getpid()}{target.suffix}")
    from ..io.output_dir import RECORD_NAME, record_outputs
    if (target.parent / RECORD_NAME).is_file():
        # into a folder of knitsim's outputs (the run's --out): one of them, replaced by a later --overwrite
        record_outputs(target.parent, [target.name])
    try:
        res = export_history(h, m.fields, str(tmp), scene_text=scene.to_toml(), color_by=args.color_by,
                             course_count=m.course_count, wale_count=m.wale_count, summary=summary,
                             stride=args.usd_stride, n_points=args.usd_points or DEFAULT_POINTS,
                             device=device if scene.engine == "warp" else "cpu", layout=args.usd_layout)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
    return res


def first_loading_of_patch(model, scene, device: str, progress=None):
    """The patch pulled monotonically from rest to its program's largest grip strain at the program's largest
    step (its first loading, continued), where the program loads past an earlier maximum after an unloading
    (:func:`knitsim.io.checks.needs_first_loading_reference`); else None.  Returns (history or None, what the
    summary says of it: ``ran``, ``why``, ``solve_s``).  The reference of ``reload_below_first_loading``: a
    second solve, of the distinct cells only (dedup as the run), over the first loading's increments only.
    ``progress``: ``progress(n)`` gives the progress callback of that solve of n increments (None: none)."""
    from ..io.results import first_loading_program
    from ..patch.runner import run_patch

    pull = first_loading_program(scene.program)
    if pull is None:
        return None, {"ran": False, "why": "the program does not load past an earlier maximum after an unloading: "
                                          "nothing to compare with a monotonic pull"}
    t0 = time.perf_counter()
    ref = run_patch(model, pull, engine=scene.engine, device=device, dedup=scene.dedup,
                    progress=None if progress is None else progress(len(pull)), **scene.solver_options)
    return ref, {"ran": True, "why": "the program loads past an earlier maximum after an unloading: the patch "
                                     "pulled monotonically to its largest grip strain is the reference of "
                                     "reload_below_first_loading", "solve_s": time.perf_counter() - t0,
                 "increments": len(ref.grip_strain)}


def _run(args) -> int:
    # one command at a time in a folder: two at once (a second --resume while the first runs) write over each
    # other's checkpoint and results (knitsim.io.output_dir.output_lock; held before --overwrite empties it)
    with output_lock(_out_dir(args), "run"):
        return _run_locked(args)


def _out_dir(args) -> str:
    """The run's output folder: --out, else the scene's name with ``_out``."""
    return args.out if args.out is not None else f"{Path(args.scene).stem}_out"


def _run_locked(args) -> int:
    t_command = time.perf_counter()
    from ..io.patch_results import (PATCH_OUTPUT_FILES, cells_written, force_cap_rows, patch_summary,
                                    specimen_layout, strided_increments, write_patch_results)
    from ..io.results import prepare_output_dir, scene_inputs
    from ..patch.runner import (CHECKPOINT_NAME, CHECKPOINT_ROWS_NAME, read_checkpoint_header, remove_checkpoint,
                                resume_refusal, run_patch)
    from ..scene.patch_scene import load_patch_scene

    if args.resume and args.overwrite:
        raise KnitsimInputError("--resume and --overwrite: choose one (continue the run in --out, or replace it)")
    from .usd import check_usd_options, usd_options_without_usd
    if args.usd is None:
        # refused rather than warned of: they ask for a file that would not be written, and a warning would
        # come after the solve (or scroll by); refusing costs nothing, before any work
        given = usd_options_without_usd(args)
        if given:
            raise KnitsimInputError(f"{', '.join(given)}: USD option(s) given without --usd; they only shape the USD "
                                    "file: add --usd FILE, or leave them out")
    else:
        check_usd_options(args)
        if not args.usd.lower().endswith((".usda", ".usdc", ".usd")):
            raise KnitsimInputError(f"--usd = {args.usd!r}: must end in .usda, .usdc or .usd")
        from ..io.results import prepare_output_file
        from ..usd.export import check_usd_path
        if not args.resume:
            prepare_output_file(args.usd, args.overwrite, "--usd")
            # writable before the solve (a parent that is a file, /proc: pxr failed after the whole solve)
            check_usd_path(args.usd, "--usd")
    with naming_scene(args.scene, "run"):
        scene = load_patch_scene(args.scene, args.overrides, engine=args.engine, device=args.device)
    with contextlib.redirect_stdout(sys.stderr):
        device = "cpu"
        if scene.engine == "warp":
            from .. import warp_runtime
            device = warp_runtime.resolve_device(scene.device)
        # --resume: the checkpoint against this scene, engine and device before the domain check (a blind probe's
        # --resume --engine reference of a warp run's checkpoint was refused only after the reference engine's
        # 51 s rest-state check of its 144 cells)
        ck = Path(_out_dir(args)) / CHECKPOINT_NAME
        head = None
        if args.resume:
            if not ck.is_file() and (ck.parent / "summary.json").is_file():
                # a finished run removes its checkpoint: "no checkpoint" read as if the run were lost
                raise KnitsimInputError(f"--resume: the run in {ck.parent} is finished (its summary.json is "
                                        "written, last): nothing to resume; its results are there (--overwrite "
                                        "runs it again)")
            if not ck.is_file():
                raise KnitsimInputError(f"--resume: no checkpoint {ck} to resume from")
            try:
                head = read_checkpoint_header(ck)
            except Exception as exc:  # noqa: BLE001 - a damaged file is a user-level problem
                raise KnitsimInputError(f"--resume: {ck} is not a readable checkpoint ({exc})") from None
            # another scene (or map, library, device...): refused here, before "resuming from ..." is said
            why = resume_refusal(ck, head, scene.model, scene.program, engine=scene.engine, device=device,
                                 dedup=scene.dedup, changes=scene_changes(head, scene.resolved),
                                 **scene.solver_options)
            if why:
                raise KnitsimInputError(why)
            if args.usd is not None:
                _usd_on_resume(args.usd, head, ck)
        # the model's domain, before any output is touched (a cell without a rest state: error, naming the scene
        # as every error of the scene does)
        with naming_scene(args.scene):
            domain_warnings = check_patch_domain(
                scene.model, scene.program.strain, scene.engine, device, scene.dedup,
                cell_fields=scene.output["cell_fields"],
                cells_increments=len(strided_increments(scene.program.direction, scene.output["cells_stride"])),
                origins=scene.origins)
        overlaps = zone_overlaps(scene.resolved)
        codes, distinct = effect_set_codes(scene.model.effects.ravel())
        n_cells = codes.size
        overlaps += inert_effect_warnings(distinct, [f"{k} of the patch's {n_cells} cells"
                                                     for k in np.bincount(codes, minlength=len(distinct))],
                                          prefixed=False)
        for w in scene.warnings + overlaps:
            print(f"knitsim run: warning: {w['message']}", file=sys.stderr, flush=True)
        domain_warnings += scene.warnings + overlaps
        # (printed with the summary's warnings at the end)
        domain_warnings += [{k: v for k, v in w.items() if k != "cell"}
                            for w in calibration_warnings(scene.calibration_flags)]
    out = prepare_output_dir(_out_dir(args),
                             overwrite=args.overwrite,
                             resume=args.resume, resumable=True, writes=PATCH_OUTPUT_FILES + (CHECKPOINT_NAME, CHECKPOINT_ROWS_NAME + "/"),
                             inputs=scene_inputs(args.scene))
    ck = out / CHECKPOINT_NAME             # (the checkpoint read above, by the folder as prepared)
    total = len(scene.program)
    resume_cmd = resume_command(args, out)
    # what a later command needs to know of this run: how to resume it, and the --usd file it may replace
    import os
    meta = {"resume_command": resume_cmd, "cwd": os.getcwd(), "scene": str(args.scene),
            "usd": str(Path(args.usd).resolve()) if args.usd is not None else None,
            "resolved": _run_keys(scene.resolved)}
    with contextlib.redirect_stdout(sys.stderr):
        m = scene.model
        layout = specimen_layout(m)
        print(f"knitsim run: {layout.describe()}, "
              f"{total} increments, engine {scene.engine}, device {device}, "
              f"dedup {'on' if scene.dedup else 'off'}", file=sys.stderr, flush=True)
        if head is not None and head.get("done", 0) >= total:
            print(f"knitsim run: the checkpoint {ck} holds the finished solve ({total}/{total} increments): writing "
                  "the outputs without solving again", file=sys.stderr, flush=True)
        elif head is not None:
            # said where the user looks (a blind probe found it only in summary.json's resumed_from)
            print(f"knitsim run: resuming from {ck}: {head.get('done', 0)} of {total} increments done",
                  file=sys.stderr, flush=True)
        every = scene.output["checkpoint_every"]
        keep = every > 0 or args.resume
        try:
            h = run_patch(m, scene.program, engine=scene.engine, device=device, dedup=scene.dedup,
                          progress=Progress(total, "knitsim run: increments", not args.no_progress),
                          checkpoint=ck if keep else None, checkpoint_every=every,
                          resume=args.resume, checkpoint_meta=meta, **scene.solver_options)
        except KeyboardInterrupt:
            print(interrupted_message(ck if keep else None, total, resume_cmd), file=sys.stderr, flush=True)
            return 130
    # the solve is in the checkpoint (run_patch saves the finished solve): a Ctrl-C from here loses no solving,
    # and says so. The USD first, then the result set, summary.json last: a folder without summary.json is
    # incomplete, and a USD file is renamed in only when whole.
    try:
        # the patch's first loading continued monotonically, where the program reloads past an earlier maximum
        # (the check reload_below_first_loading, as knitsim cell runs it); none otherwise, at no cost
        # (a large patch's second solve and checks take a while: said, so that the silence after the progress
        # bar does not read as a hang; a 300 x 300 random patch spent over 100 s here before its outputs)
        with contextlib.redirect_stdout(sys.stderr):
            reference, ref_info = first_loading_of_patch(m, scene, device, progress=lambda n: Progress(
                n, "knitsim run: the first loading continued to the program's largest grip strain (the reference "
                   "of the reload check): increments", not args.no_progress))
        if not args.no_progress:
            ng = int(h.info["n_groups"])
            print(f"knitsim run: checking the results and writing the outputs ({ng:,} distinct "
                  f"cell{'' if ng == 1 else 's'} x {h.n_increments:,} increments)", file=sys.stderr, flush=True)
        fc = force_cap_rows(h, m)              # (once for the summary and the force plot)
        summary = patch_summary(h, h.info["ref_length_mm"], model=m, zones=scene.resolved.get("zones"),
                                reference=reference, force_cap=fc, first_loading_reference=ref_info,
                                scene=scene.source, title=scene.resolved.get("title", ""),
                                engine=scene.engine, device=device, load=scene.resolved["load"])
        summary["warnings"] = domain_warnings + list(summary.get("warnings", []))
        stride = scene.output["cells_stride"]
        if scene.output["cell_fields"] and stride != 1:
            # what cells.nc holds, beside the outputs that hold every increment
            summary["cells_nc"] = cells_written(h, stride)
        res = None
        if args.usd is not None:
            # from the run's whole history: the USD's own --usd-stride, not cells.nc's
            res = _write_usd(h, m, args, scene, device, summary)
        files = write_patch_results(out, h, summary, scene.to_toml(), model=m, plot=scene.output["plot"],
                                    cell_fields=scene.output["cell_fields"], title=scene.resolved.get("title", ""),
                                    cells_stride=stride, force_cap=fc)
    except KeyboardInterrupt:
        print(interrupted_message(ck if keep else None, total, resume_cmd, writing=True), file=sys.stderr,
              flush=True)
        return 130
    except OSError as exc:
        # the solve is in the checkpoint: say so and how to write the outputs, not a traceback (a blind probe's
        # full disk); without a checkpoint the error goes on as it is, and so does a closed pipe (knitsim.cli.main)
        if not ck.is_file() or isinstance(exc, BrokenPipeError):
            raise
        print(interrupted_message(ck, total, resume_cmd, writing=True, failed=str(exc)), file=sys.stderr,
              flush=True)
        return 1
    remove_checkpoint(ck)
    if res is not None:
        drawn = (f", {res.stitches:,} stitches drawn as instances of {res.prototypes} stitch "
                 f"shape{'' if res.prototypes == 1 else 's'}"
                 if res.stitches else "")
        print(f"knitsim run: wrote {args.usd} ({res.file_bytes / 2**20:.2f} MiB, {len(res.time_codes)} time "
              f"samples{drawn}) in {res.seconds:.2f} s", file=sys.stderr, flush=True)
        from .usd import timeline_lines
        for line in timeline_lines(res.timeline):
            print(f"knitsim run: USD {line}", file=sys.stderr, flush=True)
    what = (f"{m.cell_count} blocks standing for {layout.stitches:,.0f} stitches" if layout.blocks
            else f"{m.cell_count} represented")
    # (a resumed run's solving time includes the runs it resumed: said, beside this command's own time)
    earlier = " over this and the resumed runs" if h.info.get("resumed_from") else ""
    print(f"knitsim run: done in {time.perf_counter() - t_command:.2f} s (solving {h.wall_s:.2f} s{earlier}: "
          f"{h.info['n_groups']} distinct cells solved for {what}); wrote "
          f"{', '.join(sorted(files))} to {out}", file=sys.stderr, flush=True)
    if "cells_nc" in summary:
        cn = summary["cells_nc"]
        print(f"knitsim run: cells.nc holds {cn['increments_in_file']} of the {cn['increments_in_run']} increments "
              f"(output.cells_stride = {cn['cells_stride']}: {cn['increments_written']})", file=sys.stderr, flush=True)
    for w in summary["warnings"]:
        if w.get("code") in _SAID_BEFORE_THE_RUN:
            continue                       # said before the run (summary.json keeps them)
        print(f"knitsim run: warning: {w['message']}", file=sys.stderr, flush=True)
    if not summary["all_expected_end"]:
        nc, at_cap = summary["non_converged_column_increments"], summary["non_converged_column_increments_at_force_cap"]
        print(f"knitsim run: warning: the run did not end as expected: {nc - at_cap} non-converged column "
              f"increment(s) (besides {at_cap} held at the force cap), {summary['failed_cells_at_end']} failed "
              f"cell(s) at the end, {len(summary['nonfinite_force_rows'])} row(s) with a non-finite force; see "
              "summary.json", file=sys.stderr, flush=True)
    if args.json:
        print_json(summary)
    else:
        for c in summary["cycles"]:
            res = c["residual_grip_strain"]
            work = next((f"{name.replace('_N_mm', '').replace('_', ' ')} {c[name]:.4g} N mm" for name in
                         ("hysteresis_energy_N_mm", "work_N_mm", "loading_work_N_mm", "unloading_work_N_mm")
                         if name in c), "")
            if work and any(w.get("code") == "energy_under_resolved" and f"cycle {c['cycle']}'s " in w.get("message", "")
                            for w in summary.get("warnings", [])):
                work += f" (+/-{c['energy_error_estimate_N_mm']:.2g}: under-resolved, warning above)"
            if "cut_at_grip_strain" in c:
                work = f"cut at grip strain {c['cut_at_grip_strain']:.4g}, where the force stops being the knit's (warning above)"
            peak = (f"{c['peak_force_N']:.4g} N ({c['peak_force_per_wale_N']:.4g} N per wale of the "
                    f"{layout.wales_across:.4g} wales across the width)" if layout.blocks
                    else f"{c['peak_force_per_wale_N']:.4g} N per wale")
            if c.get("peak_is_force_cap"):
                n_cap = c.get("columns_at_force_cap_at_peak", 0)
                n_col = int(summary.get("strips") or summary.get("wales") or 0)
                # the peak per wale is the cap only where every column is at it; else it mixes capped and free ones
                peak += (" (= force cap)" if not n_col or n_cap >= n_col
                         else f" ({n_cap} of {n_col} columns at their force cap)")
            failed_note = ""
            if (c.get("peak_before_failed_increment")
                    and c["force_per_wale_N_held_on_failed_increment"] != c["peak_force_per_wale_N"]):
                # (knitsim cell's peak counts a failed cell's last converged state: this one does not)
                failed_note = (f" (over the increments completed before cells failed; on the failed increment the "
                               f"grips held {c['force_per_wale_N_held_on_failed_increment']:.4g} N per wale, the "
                               "failed cells' columns at their last converged state, which knitsim cell's peak "
                               "counts)")
            how = {"slack_lengths": "located", "linear": "between rows", "secant": "extrapolated"}.get(
                c.get("residual_grip_strain_from"), "")
            if c.get("held_rows"):
                work += f" (includes {c['held_rows']} held row(s): not the knit's force)"
            print(f"cycle {c['cycle']}: peak {peak} at grip strain "
                  f"{c['grip_strain_at_peak']:.3g}{failed_note}; residual strain {'-' if res is None else f'{res:.4g}'}"
                  f"{f' ({how})' if res is not None and how else ''}; {work}")
    return 0 if summary["all_expected_end"] else 1
