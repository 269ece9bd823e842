"""knitsim diagnose-study: blind study of the diagnosis on synthetic specimens with a withheld effect.

    knitsim diagnose-study [--cases N] [--seed S] [--out DIR] [--jobs N] [--specimen lab|single] [--json]

Generates N synthetic specimens (a share --none-fraction of them effect-free,
the others with one hidden effect at a random strength) and diagnoses each
without its label. A "lab" specimen (the default: the E-glass knit, half of
them effect-free, exactly) is tested twice, a monotonic pull to 5 N per wale and three cycles 0.10-0.60, each with its own noise (1 %
of its peak + 0.002 N), a load-cell offset, negative readings near zero,
strain jitter, sometimes an outlier row, and 0.5 % specimen scatter.

Writes DIR/cases/*.json, DIR/cases.csv, DIR/summary.json and DIR/summary.md
(rewritten after every case): the false-alarm rate on effect-free specimens
with its 95 % Wilson and Clopper-Pearson intervals, top-1 accuracy on
identifiable effects, the Dahl cases misattributed, seconds per case. A study
killed at any moment resumes where it stopped with --resume (the finished cases
are kept; --resume on an empty or absent --out starts the study, so one
command both starts and resumes it); --summary-only summarises it without
running; an --out that holds a study is refused without --resume or --overwrite.
"""
from __future__ import annotations

import argparse
import contextlib
import math
import sys
from pathlib import Path

from ..diagnosis.effects import BASELINE_VARIABLES, DEFAULT_STUDY_FREE
from ..errors import KnitsimInputError
from ..io.output_dir import output_lock
from ..io.results import add_output_flags, prepare_output_dir
from .common import add_json_flag, print_json


def register(subparsers) -> None:
    """Add ``knitsim diagnose-study``."""
    p = subparsers.add_parser(
        "diagnose-study", help="blind study of the diagnosis on synthetic curves with a withheld effect",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=40, metavar="N", help="number of cases (default 40)")
    p.add_argument("--seed", type=int, default=0, help="seed of the study plan (default 0)")
    p.add_argument("--out", metavar="DIR", default="diagnose_study", help="output folder (default diagnose_study)")
    p.add_argument("--specimen", default="lab", choices=("lab", "single"),
                   help="lab: two tests per specimen with real-file flaws (default); single: one clean test")
    p.add_argument("--effects", default=None, metavar="A,B,...",
                   help="effects that may be hidden (default all; lab: all but velocity_friction, one rate)")
    p.add_argument("--noise-rel", type=float, default=None, metavar="X",
                   help="force noise sd / peak force (default: the paper's capstan scatter, 0.013)")
    p.add_argument("--scatter-rel", type=float, default=None, metavar="X",
                   help="specimen scatter of L, W0, C0, d (default 0.005 lab, 0.01 single)")
    p.add_argument("--none-fraction", type=float, default=None, metavar="X",
                   help="share of effect-free cases (default 0.5 lab, exactly; 0.25 single, drawn)")
    p.add_argument("--materials", default=None, metavar="A,B",
                   help="materials of the specimens (default e_glass for lab, e_glass,basalt for single)")
    p.add_argument("--free", default=",".join(DEFAULT_STUDY_FREE), metavar="A,B,...",
                   help="baseline parameters the diagnosis calibrates (default m,phi0,d,L,C0: the friction and "
                        "the scattered geometry; any of m, phi0, B, d, L, W0, C0)")
    p.add_argument("--device", default="cpu", help="Warp device: cpu, cuda, cuda:N or auto")
    p.add_argument("--only", default=None, metavar="I,J,...",
                   help="run only these cases of the plan (0-based indices, the index column of cases.csv): "
                        "a case is the same specimen as in the whole study of --cases and --seed")
    p.add_argument("--resume", action="store_true", help="continue the study in --out (its finished cases are kept)")
    add_output_flags(p, resumable=True, what="study")
    p.add_argument("--summary-only", action="store_true",
                   help="run nothing: summarise the cases already finished in --out")
    p.add_argument("--jobs", type=int, default=1, metavar="N",
                   help="cases run at once, one process each (default 1; results do not depend on it)")
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    # one command at a time in a folder: two at once (a second --resume while the first runs) write over each
    # other's checkpoint and results (knitsim.io.output_dir.output_lock; held before --overwrite empties it)
    with output_lock(args.out, "diagnose-study"):
        return _run_locked(args)


def _run_locked(args) -> int:
    from ..cell.effects import EFFECT_NAMES
    from ..diagnosis.study import STUDY_OUTPUTS, run_study, summary_markdown, verdict_class

    if args.cases < 1:
        raise KnitsimInputError(f"--cases = {args.cases}: expected a whole number >= 1")
    if args.seed < 0:
        raise KnitsimInputError(f"--seed = {args.seed}: expected a whole number >= 0")
    effects = None
    if args.effects is not None:
        effects = tuple(e.strip() for e in args.effects.split(",") if e.strip())
        if not effects:
            raise KnitsimInputError(f"--effects = {args.effects!r}: expected a comma-separated list of effects")
        for e in effects:
            if e not in EFFECT_NAMES:
                raise KnitsimInputError(f"--effects: unknown effect {e!r}; expected some of {', '.join(EFFECT_NAMES)}")
    if args.noise_rel is not None and not (math.isfinite(args.noise_rel) and args.noise_rel >= 0):
        raise KnitsimInputError(f"--noise-rel = {args.noise_rel}: expected a number >= 0")
    if args.scatter_rel is not None and not (math.isfinite(args.scatter_rel) and 0 <= args.scatter_rel < 0.2):
        raise KnitsimInputError(f"--scatter-rel = {args.scatter_rel}: expected a number in [0, 0.2)")
    if args.none_fraction is None:
        args.none_fraction = 0.5 if args.specimen == "lab" else 0.25
    if not (math.isfinite(args.none_fraction) and 0 <= args.none_fraction <= 1):
        raise KnitsimInputError(f"--none-fraction = {args.none_fraction}: expected a number in [0, 1]")
    materials = None
    if args.materials is not None:
        from ..diagnosis.synthetic import MATERIALS
        materials = tuple(m.strip() for m in args.materials.split(",") if m.strip())
        for m in materials or (args.materials,):
            if m not in MATERIALS:
                raise KnitsimInputError(f"--materials: unknown material {m!r}; expected some of {', '.join(MATERIALS)}")

    if args.jobs < 1:
        raise KnitsimInputError(f"--jobs = {args.jobs}: expected a whole number >= 1")
    free = tuple(n.strip() for n in args.free.split(",") if n.strip())
    for n in free:
        if n not in BASELINE_VARIABLES:
            raise KnitsimInputError(f"--free: unknown parameter {n!r}; expected some of {', '.join(BASELINE_VARIABLES)}")
    if not free:
        raise KnitsimInputError(f"--free = {args.free!r}: expected a comma-separated list of "
                                f"{', '.join(BASELINE_VARIABLES)}")

    only = None
    if args.only is not None:
        try:
            only = [int(v) for v in args.only.split(",") if v.strip()]
        except ValueError:
            raise KnitsimInputError(f"--only = {args.only!r}: expected comma-separated case indices, e.g. 9,49,65")
        if not only or any(not 0 <= i < args.cases for i in only):
            raise KnitsimInputError(f"--only = {args.only!r}: expected case indices in 0 .. {args.cases - 1} "
                                    "(the plan of --cases)")
    if args.resume and args.overwrite:
        raise KnitsimInputError("--resume and --overwrite: choose one (continue the study in --out, or replace it)")
    if args.summary_only and not (Path(args.out) / "cases").is_dir():
        # (a probe's --summary-only with a mistyped --out created that folder and an empty study's summary in it)
        raise KnitsimInputError(f"--summary-only: --out = {args.out!r} holds no study (no cases/ folder): nothing to "
                                "summarise; run the study first (without --summary-only), or give its --out")
    if not args.summary_only:
        # the device before any work (and before --overwrite empties --out): a probe's --device cuda:7 on a machine
        # without CUDA recorded its 40 cases as generator failures, and a study "complete", exit 0
        from .. import warp_runtime
        with contextlib.redirect_stdout(sys.stderr):   # Warp's banner must not reach stdout (--json)
            args.device = warp_runtime.resolve_device(args.device)
    prepare_output_dir(args.out, overwrite=args.overwrite, resume=args.resume or args.summary_only, resumable=True,
                       writes=STUDY_OUTPUTS)

    def progress(done, total, eta, rec):
        what = verdict_class(rec.get("verdict")) if rec.get("verdict") else rec.get("error", "?")
        eta_s = "?" if eta is None else f"{eta:.0f} s"
        print(f"[diagnose-study] {done}/{total} cases, ETA {eta_s}: hidden "
              f"{rec['spec']['effect'] or 'none'} -> {what}", file=sys.stderr, flush=True)

    try:
        with contextlib.redirect_stdout(sys.stderr):  # Warp's banner must not reach stdout (--json)
            summary = run_study(args.cases, args.seed, args.out, effects=effects,
                                include_none_fraction=args.none_fraction, noise_rel=args.noise_rel,
                                scatter_rel=args.scatter_rel, device=args.device, progress=progress, free=free,
                                resume=True, jobs=args.jobs, summary_only=args.summary_only,
                                specimen=args.specimen, materials=materials, only=only, replace_other=False)
    except KeyboardInterrupt:
        print(f"knitsim diagnose-study: interrupted; the finished cases are kept in {args.out}/cases and "
              f"summarised in {args.out}/summary.md (marked partial); resume with: {_resume_command(args)}",
              file=sys.stderr, flush=True)
        return 130
    if args.json:
        print_json(summary)
    else:
        print(summary_markdown(summary))
        print(f"written: {args.out}/summary.json, {args.out}/summary.md, {args.out}/cases/")
        if not summary["complete"]:
            print(f"partial: {len(summary['cases_missing'])} of {summary['cases_planned']} planned cases not "
                  "finished; run without --summary-only to finish them")
    return 0


def _resume_command(args) -> str:
    """The command that continues an interrupted study (:func:`knitsim.cli.common.resume_command`)."""
    from .common import resume_command
    return resume_command("diagnose-study", ["--cases", str(args.cases), "--seed", str(args.seed), "--out",
                                             str(args.out)])
