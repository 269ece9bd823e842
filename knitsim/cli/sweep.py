"""``knitsim sweep``: a grid or Latin-hypercube sweep of any cell-scene parameter.

``knitsim sweep SCENE.toml [--sweep SWEEP.toml] [--out DIR] [--resume]
[--workers N] [--scheduler ADDR] [--engine warp|reference] [--device ...]
[--curves] [--set key=value ...] [--chunk-size N] [--no-plot] [--json]``

The ``[sweep]`` table (in the scene, or a separate file with ``--sweep``) is
described in :mod:`knitsim.sweep.spec`; every sample is validated before
anything runs.  Results go to ``DIR`` (default ``<scene stem>_sweep``):
``sweep.json``, ``chunks/``, ``results.nc``, ``results.csv``,
``plot_sweep.png`` (:mod:`knitsim.sweep.runner`) and ``summary.json``: the
samples that failed, have no rest state, lie outside the domain's box,
return energy, rest compressed or stopped at the force cap, each with its
reason (what ``--json`` prints, and what the plot's title counts).  Exit
status 1 when the solver failed on a sample (a missing result), as ``knitsim
cell`` and ``run`` do for a failed cell, or when the plot could not be drawn
(``plot_error`` in ``summary.json``; the results are written).  Chunks run on a local Dask
cluster with one worker process per core (no more than the chunks to run;
``--workers N``: at most the cores) unless ``--workers 0`` (in this
process) or ``--scheduler tcp://host:port`` (an existing cluster).  Killing a
run keeps the finished chunks; ``--resume`` finishes it.  One sweep at a time
writes into a folder (:func:`knitsim.io.output_dir.output_lock`): a second one
is refused with exit status 2, and the lock of a killed one is taken over.
"""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from ..cell.engine import ENGINES
from ..errors import KnitsimInputError
from ..io.output_dir import output_lock
from ..io.results import add_output_flags, prepare_output_dir, scene_inputs
from .common import Progress, add_json_flag, naming_scene, print_json, resume_command

#: samples from which the validation of a sweep's samples shows its progress (about 1 ms a sample: 5 s)
PLAN_PROGRESS_SAMPLES = 5000


def register(subparsers) -> None:
    """Add ``knitsim sweep``."""
    parser = subparsers.add_parser(
        "sweep", help="sweep cell-scene parameters over a grid or a Latin hypercube (batched, Dask)",
        description="Run a cell scene over a grid or Latin-hypercube sample of any of its parameters "
                    "([sweep] table); chunks of samples are batched into single engine calls and run on "
                    "Dask workers; results: results.nc (xarray), results.csv, plot_sweep.png.")
    parser.add_argument("scene", metavar="SCENE.toml", help="cell scene, with a [sweep] table unless --sweep")
    parser.add_argument("--sweep", metavar="SWEEP.toml", default=None,
                        help="separate file holding the [sweep] table (replaces the scene's)")
    parser.add_argument("--out", metavar="DIR", default=None, help="output directory (default: <scene stem>_sweep)")
    parser.add_argument("--resume", action="store_true", help="finish an interrupted sweep in --out")
    add_output_flags(parser, resumable=True)
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="local Dask worker processes, at most one per core (default: one per core, no more "
                             "than the chunks to run); 0: run in this process")
    parser.add_argument("--scheduler", metavar="ADDR", default=None,
                        help="address of an existing Dask scheduler, e.g. tcp://host:8786 "
                             "(workers need knitsim and --out on a shared file system)")
    parser.add_argument("--engine", choices=ENGINES, default=None, help="override the scene's engine")
    parser.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:N or auto")
    parser.add_argument("--curves", action="store_true", help="also keep force per wale vs increment of every cell")
    parser.add_argument("--chunk-size", type=int, default=None, metavar="N", help="override sweep.chunk_size")
    parser.add_argument("--set", metavar="KEY=VALUE", action="append", default=[], dest="overrides",
                        help="override a key of the base scene (repeatable)")
    parser.add_argument("--no-plot", action="store_true", help="do not write plot_sweep.png")
    add_json_flag(parser)
    parser.set_defaults(func=_run)


def _announce_domain(plan) -> None:
    """Before any solve: how many samples lie outside the model (not solved) or its domain's box."""
    from ..cell.domain import DOMAIN_NO_REST_STATE, DOMAIN_OUTSIDE_BOX

    if plan.domain is None:
        return
    for code, what in ((DOMAIN_NO_REST_STATE, "have no admissible rest state (outside the model): not solved"),
                       (DOMAIN_OUTSIDE_BOX, "lie outside the domain's box (knitsim.cell.domain): solved, "
                                            "flagged as extrapolated")):
        rows = (plan.domain == code).any(axis=1)
        if rows.any():
            first = next(r for i in map(int, rows.nonzero()[0]) for c, r in enumerate(plan.domain_reasons[i])
                         if plan.domain[i, c] == code)
            print(f"knitsim sweep: {int(rows.sum())} of {plan.n_samples} sample(s) {what}; e.g. {first}",
                  file=sys.stderr, flush=True)


def _more(what: str, summary: dict) -> str:
    """Where the samples a warning does not print are: summary.json's list (with --json), or, past the ones it
    lists, results.csv / results.nc (``<what>_listed``)."""
    return summary.get(f"{what}_listed") or f"summary.json's {what} list; --json prints it"


def _run(args) -> int:
    from ..sweep.runner import check_scheduler, check_workers, plan_sweep
    from ..sweep.spec import parse_sweep, split_scene
    from ..scene.schema import load_toml

    check_workers(args.workers, args.scheduler)
    if args.chunk_size is not None and args.chunk_size < 1:
        raise KnitsimInputError(f"--chunk-size = {args.chunk_size}: expected a whole number >= 1")
    # (errors of a --sweep file name that file, not the scene)
    with naming_scene(args.scene, "sweep") if args.sweep is None else contextlib.nullcontext():
        doc = load_toml(args.scene)
        _, table, _ = split_scene(doc, args.sweep)
        if isinstance(table, dict):
            table = dict(table)
            if args.curves:
                table["curves"] = True
            if args.chunk_size is not None:
                table["chunk_size"] = args.chunk_size
        spec = parse_sweep(table)
    if args.resume and args.overwrite:
        raise KnitsimInputError("--resume and --overwrite: choose one (finish the sweep in --out, or replace it)")
    with contextlib.redirect_stdout(sys.stderr):     # Warp's banner must not reach stdout (--json)
        with naming_scene(args.scene, "sweep"):
            # (each sample's scene is validated, about 1 ms a sample: said for a long sweep, nothing for a short one)
            validating = Progress(spec.samples, "knitsim sweep: validating the samples' scenes: samples",
                                  enabled=spec.samples >= PLAN_PROGRESS_SAMPLES)
            try:
                plan = plan_sweep(args.scene, spec, overrides=args.overrides, engine=args.engine,
                                  device=args.device, progress=validating)
            finally:
                validating.close()
    out_dir = args.out if args.out is not None else f"{Path(args.scene).stem}_sweep"
    check_scheduler(args.scheduler)                  # (before the folder is made)
    # one sweep at a time in a folder (two --resume at once both ran the missing chunks and wrote the results),
    # held before --overwrite empties it
    with output_lock(out_dir, "sweep"):
        return _run_locked(args, plan, out_dir)


def _run_locked(args, plan, out_dir) -> int:
    """The sweep into ``out_dir``, whose lock this command holds."""
    from ..sweep.runner import MANIFEST, SWEEP_OUTPUTS, SweepChunkError, run_sweep

    # only once every sample is planned (validated): --overwrite emptied the folder of an earlier sweep before a
    # typo'd key or a bad sample was refused (a blind probe lost its results to it)
    out = prepare_output_dir(out_dir,
                             overwrite=args.overwrite,
                             resume=args.resume, resumable=MANIFEST, writes=SWEEP_OUTPUTS,
                             inputs=scene_inputs(args.scene) + scene_inputs(args.sweep))
    _announce_domain(plan)
    from ..io.checks import calibration_warnings
    for w in calibration_warnings(getattr(plan.base, "calibration_flags", [])):
        # the sweep's base scene (or the library it names) is a flagged calibration's: every sample is
        print(f"knitsim sweep: warning: {w['message']}", file=sys.stderr, flush=True)
    for w in plan.warnings:
        # a swept key that a cell states itself: that cell is not swept
        print(f"knitsim sweep: warning: {w['message']}", file=sys.stderr, flush=True)
    workers = args.workers
    if workers is None and plan.device != "cpu" and not args.scheduler:
        workers = 1                                   # one GPU: one worker process feeds it
    # as typed, without --overwrite (a blind probe was told to resume with --overwrite --resume, refused)
    resume_cmd = resume_command("sweep", [args.scene] + (["--sweep", args.sweep] if args.sweep else [])
                                + ["--out", str(out)])
    try:
        run = run_sweep(plan, out, resume=args.resume, workers=workers, scheduler=args.scheduler,
                        plots=not args.no_plot)
    except KeyboardInterrupt:
        done = len(list((out / "chunks").glob("chunk_*.npz"))) if (out / "chunks").is_dir() else 0
        print(f"knitsim sweep: interrupted; {done}/{len(plan.chunks)} finished chunk(s) kept in {out / 'chunks'}; "
              f"finish with: {resume_cmd}", file=sys.stderr, flush=True)
        return 130
    except (SweepChunkError, OSError) as exc:
        # (an OSError: a chunk or a result file that could not be written, a full disk: a traceback before; a
        # closed pipe goes on to knitsim.cli.main)
        if isinstance(exc, BrokenPipeError):
            raise
        done = len(list((out / "chunks").glob("chunk_*.npz"))) if (out / "chunks").is_dir() else 0
        what = str(exc) if isinstance(exc, SweepChunkError) else f"a file could not be written or read ({exc})"
        print(f"knitsim sweep: {what}; {done}/{len(plan.chunks)} finished chunk(s) kept; "
              f"after fixing the cause, finish with: {resume_cmd}", file=sys.stderr, flush=True)
        return 1
    summary = run.summary                            # written to summary.json by run_sweep
    failed, n_bad = summary["failed"], summary["failed_count"]
    print(f"knitsim sweep: {len(run.computed)} chunk(s) computed, {len(run.skipped)} reused, "
          f"{run.wall_s:.1f} s; wrote {', '.join(sorted(summary['files']))} to {out}", file=sys.stderr, flush=True)
    if n_bad:
        # the fraction, as the domain's counts say theirs (a blind probe's "7 sample cell(s) failed" left the
        # reader to find the total 40 lines above)
        n_all = plan.n_samples * plan.n_cells
        print(f"knitsim sweep: warning: {n_bad} of {n_all} sample cell(s) failed ({100 * n_bad / n_all:.3g} %; no "
              "results: NaN in results.nc, grey in the plots):", file=sys.stderr, flush=True)
        for f in failed[:20]:
            print(f"  sample {f['sample']} ({', '.join(f'{k} = {v:.6g}' if isinstance(v, float) else f'{k} = {v}' for k, v in f['parameters'].items())})"
                  f"{'' if f.get('cell') is None else ' cell ' + str(f['cell'])}: {f['reason']}",
                  file=sys.stderr, flush=True)
        if n_bad > 20:
            print(f"  ... and {n_bad - 20} more ({_more('failed', summary)})", file=sys.stderr, flush=True)
    for what, note in (("no_rest_state", "outside the model, not solved: NaN in results.nc, grey squares / "
                                         "//-hatched in the plots"),
                       ("outside_domain", "outside the domain's box, solved (an extrapolation: convergence is "
                                          "promised inside the box only): ringed / dotted in the plots"),
                       ("loop_creates_energy", "a closed loop returns energy, oint F dC < 0: not a hysteresis; "
                                               "Table 4's frozen force closures, README 'Loops that return "
                                               "energy'; variable loop_creates_energy in results.nc / results.csv"),
                       ("rest_state_compressive", "the rest state carries a compressive force (the knit is not "
                                                  "free at C0, W0); its loops from rest are not judged; variable "
                                                  "rest_state_compressive in results.nc / results.csv"),
                       ("heads_interpenetrate", "the heads of neighbouring loops overlap: knitsim cell on the "
                                                "sample says where; variable heads_interpenetrate in results.nc / "
                                                "results.csv"),
                       ("zero_force_cycle", "a later cycle carries nearly no force (a few per cent of the largest "
                                            "earlier peak); variable zero_force_cycle in results.nc / results.csv"),
                       ("reload_below_earlier_loading", "a later cycle reloads below half the earlier force at the "
                                                        "earlier maximum, or its envelope falls; variable "
                                                        "reload_below_earlier_loading in results.nc / results.csv"),
                       ("reload_loss_continues", "cycles to the same strain go on losing peak force after their "
                                                 "first reload (no shakedown); variable reload_loss_continues in "
                                                 "results.nc / results.csv"),
                       ("reload_above_first_loading", "a later cycle reloads above the first loading at the same "
                                                      "strain; variable reload_above_first_loading in results.nc / "
                                                      "results.csv"),
                       ("reload_below_first_loading", "a reload past an earlier maximum carries below 90 % of "
                                                      "the same cell's monotonic pull; variable "
                                                      "reload_below_first_loading in results.nc / results.csv"),
                       ("wale_spacing_below_jamming", "OUTSIDE THE MODEL: W below 4 x the in-plane width, the "
                                                      "model's jamming limit (head_gap criterion); variable "
                                                      "wale_spacing_below_jamming in results.nc / results.csv"),
                       ("stopped_at_force_cap", "a stop, not a failure, but the rest of the program was not run: "
                                                "that cycle's peak is the cap (peak_at_force_cap = 1), its energy "
                                                "loading work if it never unloaded (energy_kind), later cycles NaN "
                                                "in results.nc / results.csv; grey stars and triangles in the "
                                                "plots")):
        rows, count = summary[what], summary[f"{what}_count"]
        if count:
            print(f"knitsim sweep: warning: {count} sample cell(s) {what} ({note}):", file=sys.stderr, flush=True)
            for f in rows[:10]:
                print(f"  sample {f['sample']}{'' if f.get('cell') is None else ' cell ' + str(f['cell'])}: "
                      f"{f['reason']}", file=sys.stderr, flush=True)
            if count > 10:
                print(f"  ... and {count - 10} more ({_more(what, summary)})", file=sys.stderr, flush=True)
    if run.plot_error:
        # the results are complete without the figure; the status says something is missing
        print(f"knitsim sweep: error: plot_sweep.png could not be drawn ({run.plot_error}); results.nc, "
              f"results.csv and summary.json are complete", file=sys.stderr, flush=True)
    if args.json:
        print_json(summary)
    else:
        print(f"{plan.n_samples} samples -> {out / 'results.nc'}")
    # a sample the solver failed on is a missing result, as a failed cell is for knitsim cell and run:
    # exit status 1 (samples outside the model, with no rest state, are part of the map: said, status 0)
    return 1 if n_bad or run.plot_error else 0
