"""``knitsim usd``: export a saved patch run to USD for visual checks.

``knitsim usd RESULTS_DIR --out FILE [--color-by stage|phi|force|material|strain] [--stride N]
[--points N] [--usd-layout auto|courses|instanced] [--quicklook PNG] [--device cpu|cuda|auto] [--json]``

Reads ``cells.nc`` (per-group states x = (alpha, beta, gamma, phi, P), W, C,
s_AB per saved increment) and ``scene.resolved.toml`` of a ``knitsim run``
results folder and writes the same file that ``knitsim run --usd`` writes
(:mod:`knitsim.usd.from_results`): ``.usda`` text, ``.usdc`` / ``.usd`` binary
crate (use it for large patches).  A specimen (cells that stand for blocks of
stitches) is drawn stitch by stitch, each stitch an instance of its block's
shape (:mod:`knitsim.usd.instanced`).  Time code k is increment k (0 the rest
state) where cells.nc holds the rest state, else increment k + 1 (the file says
which); a folder whose cells.nc was written at ``output.cells_stride`` draws the
increments it holds, at their own time codes (the file lists them); increments
after the knit stopped (every column held: the force cap, failed cells) are not
written, and the file says so with the run's warnings.
The output path is checked writable before any work.  Exit status 0, or 2 on
bad input.
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import KnitsimInputError
from ..io.results import add_output_flags, prepare_output_file
from ..usd.from_results import LAYOUTS, MAX_POINTS, MIN_POINTS
from .common import add_json_flag, print_json

COLOR_CHOICES = ("stage", "phi", "force", "material", "strain")


#: defaults of the USD options shared by knitsim usd and knitsim run (argparse dest -> value)
USD_OPTION_DEFAULTS = {"color_by": "stage", "usd_stride": 1, "usd_points": None, "usd_layout": "auto"}


def add_usd_options(p, prefix: str = "") -> None:
    """``--color-by``, ``--[usd-]stride``, ``--usd-points``, ``--usd-layout`` (shared with ``knitsim run``).

    With a ``prefix`` (``knitsim run``, where they only apply with ``--usd``) their defaults are None, so that
    :func:`usd_options_without_usd` can tell which were given; :func:`check_usd_options` fills them in."""
    dflt = (lambda name: None) if prefix else USD_OPTION_DEFAULTS.get
    p.add_argument("--color-by", default=dflt("color_by"), metavar="FIELD",
                   help=f"displayColor by one of {', '.join(COLOR_CHOICES)} (default stage; force: the force per "
                        "wale of each cell [N], the file's force_per_wale_N)")
    p.add_argument(f"--{prefix}stride", dest="usd_stride", type=int, default=dflt("usd_stride"), metavar="N",
                   help="write increments 0, N, 2N, ... counted from the rest state, and the last one written; "
                        "default 1")
    p.add_argument("--usd-points", dest="usd_points", type=int, default=None, metavar="N",
                   help="points per quarter centreline (6 to 1000, default 9)")
    p.add_argument("--usd-layout", dest="usd_layout", default=dflt("usd_layout"), metavar="LAYOUT",
                   help="courses (one yarn curve per course), instanced (one stitch shape per distinct cell, "
                        "placed at every stitch of it) or auto (default: instanced when the distinct cells are "
                        "at most a quarter of the cells, as in a uniform patch)")
    p.set_defaults(usd_stride_flag=f"--{prefix}stride")


def usd_options_without_usd(args) -> list[str]:
    """The USD options of ``knitsim run`` given on its command line (their values not None), by flag."""
    flags = {"color_by": "--color-by", "usd_stride": args.usd_stride_flag, "usd_points": "--usd-points",
             "usd_layout": "--usd-layout"}
    return [flag for dest, flag in flags.items() if getattr(args, dest, None) is not None]


def check_usd_options(args) -> None:
    """Validate the shared options before any work (exit 2 with one line); options not given take their
    defaults."""
    for dest, value in USD_OPTION_DEFAULTS.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)
    if args.color_by not in COLOR_CHOICES:
        raise KnitsimInputError(f"--color-by = {args.color_by!r}: expected one of {', '.join(COLOR_CHOICES)}")
    if args.usd_stride < 1:
        raise KnitsimInputError(f"{args.usd_stride_flag} = {args.usd_stride}: must be >= 1")
    if args.usd_layout not in LAYOUTS:
        raise KnitsimInputError(f"--usd-layout = {args.usd_layout!r}: expected one of {', '.join(LAYOUTS)}")
    if args.usd_points is not None and args.usd_points < MIN_POINTS:
        raise KnitsimInputError(f"--usd-points = {args.usd_points}: must be >= {MIN_POINTS}")
    if args.usd_points is not None and args.usd_points > MAX_POINTS:
        raise KnitsimInputError(f"--usd-points = {args.usd_points}: must be <= {MAX_POINTS} (200 points already "
                                "draw the centreline within 1e-4 mm; the file grows with them)")


def register(subparsers) -> None:
    """Add ``knitsim usd``."""
    p = subparsers.add_parser(
        "usd", help="export a saved patch run (knitsim run results folder) to USD",
        description="Export a knitsim run results folder to USD: one BasisCurves yarn per course (or, for a "
                    "specimen or a patch of few distinct cells, one stitch shape per distinct cell instanced at "
                    "every stitch), one time sample per saved increment, per-cell primvars (stage, phi, force, "
                    "strain, material).")
    p.add_argument("results", metavar="RESULTS_DIR", help="results folder of knitsim run (with cells.nc)")
    p.add_argument("--out", metavar="FILE", required=True, help="output .usda (text) or .usdc/.usd (binary crate)")
    add_usd_options(p)
    p.add_argument("--quicklook", metavar="PNG", default=None,
                   help="also render the first and last frame from the USD file into this PNG")
    p.add_argument("--device", default="cpu", help="Warp device of the centreline kernel: cpu, cuda, cuda:N, auto")
    add_output_flags(p, what="file")
    add_json_flag(p)
    p.set_defaults(func=_run)


def unfinished_run(results) -> str | None:
    """Why a results folder holds no complete run, where it holds the checkpoint of an interrupted
    ``knitsim run`` and no ``summary.json`` (written last: its presence marks a complete set); None otherwise.
    Says how far the run got and the command that finishes it (recorded in the checkpoint)."""
    from ..patch.runner import CHECKPOINT_NAME, read_checkpoint_header

    folder = Path(results)
    ck = folder / CHECKPOINT_NAME
    if not ck.is_file() or (folder / "summary.json").is_file():
        return None
    try:
        head = read_checkpoint_header(ck)
    except Exception as exc:  # noqa: BLE001 - a damaged checkpoint: still an unfinished run
        return (f"RESULTS_DIR = {str(results)!r}: holds the checkpoint of an unfinished knitsim run ({ck}, not "
                f"readable: {exc}) and no results; run it again")
    done, total = int(head["done"]), head.get("total")
    meta = head.get("meta") or {}
    cmd = meta.get("resume_command") or f"knitsim run SCENE.toml --out {folder} --resume (the run's own scene)"
    where = f" (in {meta['cwd']})" if meta.get("cwd") else ""
    held = (f"its solve is finished ({done}/{total} increments) but its outputs were not written"
            if total is not None and done >= total else
            f"its checkpoint {ck} holds {done}{'' if total is None else f'/{total}'} solved increment(s)")
    old = ("" if head.get("format") else
           " (a checkpoint of an older knitsim, which does not record its device: a warp run may be refused on "
           "--resume and then runs again with --overwrite in place of --resume)")
    return (f"RESULTS_DIR = {str(results)!r}: the run is unfinished (interrupted): {held}, and there are no results "
            f"to export yet; finish it with{where}: {cmd}{old}; then run knitsim usd again")


def _run(args) -> int:
    from .. import warp_runtime
    from ..usd.export import check_usd_path
    from ..usd.from_results import DEFAULT_POINTS, export_results
    check_usd_options(args)
    why = unfinished_run(args.results)
    if why is not None:
        raise KnitsimInputError(why)
    folder = Path(args.results)
    if folder.is_dir() and (folder / "cells.nc").is_file() and not (folder / "summary.json").is_file():
        # summary.json is written last: without it the set is incomplete (a run stopped while writing its
        # results), and its warnings (a failed or capped run) would be missing from the file (a blind probe)
        raise KnitsimInputError(f"RESULTS_DIR = {str(args.results)!r}: has cells.nc but no summary.json, which "
                                "knitsim run writes last: the results are incomplete (a run stopped while writing "
                                "them); run it again with --overwrite")
    if folder.is_dir() and (folder / "summary.json").is_file():
        # its warnings (a failed or capped run, energy, overlaps) go into the file: a summary that does not read
        # would drop them without a word (a blind probe's `echo '{' > summary.json` exported silently)
        import json
        try:
            doc = json.loads((folder / "summary.json").read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise KnitsimInputError(f"RESULTS_DIR = {str(args.results)!r}: its summary.json does not read ({exc}): "
                                    "the results are damaged; run the scene again with --overwrite") from None
        if not isinstance(doc, dict):
            raise KnitsimInputError(f"RESULTS_DIR = {str(args.results)!r}: its summary.json holds no summary (a "
                                    f"{type(doc).__name__}): the results are damaged; run the scene again with "
                                    "--overwrite")
    prepare_output_file(args.out, args.overwrite)
    # writable before any work: the parent a folder, and a file can be created in it (pxr's own error came
    # as a traceback after the export)
    check_usd_path(args.out, "--out")
    prepare_output_file(args.quicklook, args.overwrite, "--quicklook", suffix=".png")
    device = warp_runtime.resolve_device(args.device)
    res = export_results(args.results, args.out, color_by=args.color_by, stride=args.usd_stride,
                         n_points=args.usd_points or DEFAULT_POINTS, device=device, quicklook=args.quicklook,
                         layout=args.usd_layout)
    # what the run itself warned of (a failed or capped run): the file shows those states too, so said here
    run_warnings = _run_warnings(args.results)
    tl = res.timeline
    doc = {"usd": res.path, "bytes": res.file_bytes, "time_codes": len(res.time_codes), "courses": res.courses,
           "wales": res.wales, "vertices_per_course": res.vertices_per_course, "seconds": res.seconds,
           "fallback_cells_max": max(res.fallback_cells) if res.fallback_cells else 0,
           "stitches_drawn": res.stitches or None, "prototypes": res.prototypes or None,
           "quicklook": args.quicklook, "run_warnings": run_warnings,
           "time_code_0_is_increment": tl["time_code_0_is_increment"],
           "last_increment_written": tl["last_increment_written"], "increments_in_run": tl["increments_in_run"],
           "increments_not_written": tl.get("increments_not_written"),
           # a results folder written at output.cells_stride: the increments it holds (None: every one)
           "saved_increments": tl.get("saved_increments")}
    if args.json:
        print_json(doc)
    else:
        what = (f"instanced: {res.stitches:,} stitches drawn as instances of {res.prototypes} stitch "
                f"shape{'' if res.prototypes == 1 else 's'}, at most {res.courses} courses x {res.wales} wales"
                if res.stitches else
                f"{res.courses} courses x {res.wales} wales")
        print(f"knitsim usd: wrote {res.path} ({res.file_bytes / 2**20:.2f} MiB, {len(res.time_codes)} time samples, "
              f"{what}) in {res.seconds:.2f} s"
              + (f"; quick-look {args.quicklook}" if args.quicklook else ""), file=sys.stderr)
        for line in timeline_lines(tl):
            print(f"knitsim usd: {line}", file=sys.stderr)
        for w in run_warnings:
            print(f"knitsim usd: warning: the run shown ({Path(args.results) / 'summary.json'}): {w['code']}: "
                  f"{w['message']}", file=sys.stderr)
    return 0


def timeline_lines(tl: dict) -> list[str]:
    """What a user is told of an exported timeline (``UsdExportResult.timeline``): the increments left out,
    and a time code 0 that is not the rest state."""
    out = []
    if tl.get("saved_increments_are"):
        # a results folder written at output.cells_stride: the file's time codes have gaps
        n = len(tl.get("saved_increments", []))
        out.append(f"note: the results hold {n} of the run's {tl['increments_in_run']} increments (cells.nc written "
                   "at output.cells_stride): time codes are their increment numbers, the others are not drawn "
                   "(customLayerData knitsim.timeline.saved_increments)")
    if tl.get("increments_not_written"):
        out.append(f"note: increments {tl['increments_not_written']} of {tl['increments_in_run']} not written: "
                   f"{tl['why_not_written']}")
    if tl.get("time_code_0_is_increment", 0) != 0:
        out.append("note: the results hold no rest state (cells.nc of an older knitsim): time code k is increment "
                   "k + 1, not k (customLayerData knitsim.timeline)")
    return out


#: the run's warnings that say its later states are not the knit's (held, failed or capped)
_RUN_STOP_CODES = ("run_stopped_by_failed_cells", "run_held_by_unconverged_columns", "force_cap_reached",
                   "program_cut_by_force_cap")


def _run_warnings(results) -> list[dict]:
    """The run's warnings of :data:`_RUN_STOP_CODES` from its ``summary.json`` (none without one)."""
    import json
    try:
        doc = json.loads((Path(results) / "summary.json").read_text())
    except (OSError, ValueError):
        return []
    return [w for w in doc.get("warnings", []) if isinstance(w, dict) and w.get("code") in _RUN_STOP_CODES]
