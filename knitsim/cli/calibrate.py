"""``knitsim calibrate``: one yarn calibrated jointly on several specimens (issue 16).

``knitsim calibrate SCENE.toml [--out DIR] [--set key=value ...] [--device cpu|cuda|auto] [--overwrite | --resume]
[--no-progress] [--json]``

The calibration scene (:mod:`knitsim.calibration.scene`) names the specimens
(their measured curves or experimental bands, width, gauge length and stated
knit) and what is fitted: the yarn's variables shared by all, each knit's own.
It is read and checked, and the specimens' files read, before any solve.  The
fit (:func:`knitsim.calibration.joint.calibrate_joint`) shows its progress on
stderr; the results go to ``DIR`` (default ``<scene stem>_calibrated``):
``materials.toml`` (the calibrated yarn and knits, for new scenes),
``<specimen>.cell.toml`` and ``<specimen>.patch.toml`` (ready for ``knitsim
cell``, ``sweep`` and ``run``), ``calibration.json``, ``report.md`` and
``fit_<specimen>.png`` (:mod:`knitsim.calibration.outputs`).
Progress: a bar (a terminal) or a line per tenth (a log) for the starts screened and for each
refined start's evaluations.  The finished work is kept in ``DIR/calibration_checkpoint.pkl``
(the screened starts, each finished refinement, the evaluations of the one under way; removed
when the results are written): after Ctrl-C or a lost session, ``--resume`` continues it and
gives the result of an uninterrupted fit.  An ``--out`` that holds results is refused unless
``--resume`` or ``--overwrite``.
Every check of the scene (the fit's own included: an unknown variable, a strain the knit cannot
reach) runs before anything is printed or written.
Exit status 0 when the fit converged, every cell solved and no parameter is at
a bound or not identified; 1 otherwise: the flags are printed (stderr, and first in the summary on
stdout, "NOT A CALIBRATION YOU CAN USE"), in calibration.json (``flags``, ``usable``), at the top of
report.md, and in a comment block at the top of materials.toml and of each scene written; 2 on bad
input.
"""
from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

from ..io.results import add_output_flags, prepare_output_dir, scene_inputs
from ..errors import KnitsimInputError
from ..io.output_dir import output_lock
from .common import Progress, add_json_flag, naming_scene, print_json

#: the calibration's checkpoint in --out (knitsim.calibration.joint.calibrate_joint)
CHECKPOINT_NAME = "calibration_checkpoint.pkl"


def register(subparsers) -> None:
    """Add ``knitsim calibrate``."""
    p = subparsers.add_parser(
        "calibrate", help="calibrate one yarn jointly on several specimens; write calibrated materials and scenes",
        description="Fit one yarn (B, d, in-plane width, m, effect parameters) shared by several specimens, each "
                    "with its own knit (L, W0, C0 within their uncertainty, phi0); write materials.toml, a cell "
                    "and a patch scene per specimen, calibration.json, report.md and fit plots.")
    p.add_argument("scene", metavar="SCENE.toml", help="calibration scene (see scenes/calibration/)")
    p.add_argument("--out", metavar="DIR", default=None, help="output directory (default: <scene stem>_calibrated)")
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[], dest="overrides",
                   help="override a scene key, e.g. --set calibration.starts=8 (repeatable)")
    p.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:N or auto")
    p.add_argument("--resume", action="store_true", help=f"continue from DIR/{CHECKPOINT_NAME}")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_output_flags(p, resumable=True)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    # one command at a time in a folder: two at once (a second --resume while the first runs) write over each
    # other's checkpoint and results (knitsim.io.output_dir.output_lock; held before --overwrite empties it)
    with output_lock(args.out if args.out is not None else f"{Path(args.scene).stem}_calibrated", "calibrate"):
        return _run_locked(args)


def _run_locked(args) -> int:
    t0 = time.perf_counter()
    from ..calibration.joint import POOR_FIT_S2, calibrate_joint
    from ..calibration.outputs import UNUSABLE, calibration_outputs, write_calibration, zero_offsets
    from ..calibration.scene import load_calibration_scene

    with naming_scene(args.scene, "calibrate"):
        scene = load_calibration_scene(args.scene, args.overrides, device=args.device)
    if args.resume and args.overwrite:
        raise KnitsimInputError("--resume and --overwrite: choose one (continue the calibration in --out, or "
                                "replace it)")
    out = prepare_output_dir(args.out if args.out is not None else f"{Path(args.scene).stem}_calibrated",
                             overwrite=args.overwrite,
                             resume=args.resume, resumable=True, writes=calibration_outputs(scene) + (CHECKPOINT_NAME,),
                             inputs=scene_inputs(args.scene))
    ck = out / CHECKPOINT_NAME
    if args.resume and not ck.is_file():
        raise KnitsimInputError(f"--resume: no checkpoint {ck} to resume from")
    with contextlib.redirect_stdout(sys.stderr):
        from .. import warp_runtime
        device = warp_runtime.resolve_device(scene.setup.device)
        if device != scene.setup.device:
            from dataclasses import replace
            scene.setup = replace(scene.setup, device=device)
        sp = scene.specimens
        print(f"knitsim calibrate: {len(sp)} specimens ({', '.join(s.name for s in sp)}), "
              f"{sum(len(s.strain) for s in sp)} rows; shared {', '.join(scene.setup.shared)}; per specimen "
              f"{', '.join(scene.setup.per_specimen) or 'nothing'}; device {device}", file=sys.stderr, flush=True)
        for name, src, z in zero_offsets(sp):
            print(f"knitsim calibrate: {name}: {src}: the load cell reads {z:.3g} N at rest (below zero: a knit "
                  "carries no compression): tared", file=sys.stderr, flush=True)
        for s in sp:
            for src, note in s.read_notes:
                print(f"knitsim calibrate: {s.name}: {src}: {note}", file=sys.stderr, flush=True)
        bars = []

        def counter(what, total):
            bars.append(Progress(total, f"knitsim calibrate: {what}", not args.no_progress))
            return bars[-1]
        try:
            result = calibrate_joint(sp, scene.setup,
                                     progress=lambda line: print(f"knitsim calibrate: {line}", file=sys.stderr,
                                                                 flush=True),
                                     counter=counter, checkpoint=ck, resume=args.resume)
            files = write_calibration(out, result, scene, str(args.scene))
        except KeyboardInterrupt:
            if ck.is_file():
                print(f"knitsim calibrate: interrupted; the finished work is in {ck}: add --resume to continue",
                      file=sys.stderr, flush=True)
            raise
        finally:
            for b in bars:
                b.close()
    ck.unlink(missing_ok=True)
    print(f"knitsim calibrate: done in {time.perf_counter() - t0:.1f} s; wrote {', '.join(sorted(files))} to {out}",
          file=sys.stderr, flush=True)
    flags = result.flags
    if flags and not args.json:         # the summary on stdout lists them
        print(f"knitsim calibrate: warning: {UNUSABLE}: {len(flags)} flag{'s' if len(flags) > 1 else ''} (listed "
              "in the summary below)", file=sys.stderr, flush=True)
    for line in flags if args.json else ():
        print(f"knitsim calibrate: warning: {line}", file=sys.stderr, flush=True)
    for line in result.notes if args.json else ():
        print(f"knitsim calibrate: note: {line}", file=sys.stderr, flush=True)
    if not result.success and not any(x.startswith("the fit failed") for x in flags):
        print(f"knitsim calibrate: warning: {result.message}", file=sys.stderr, flush=True)
    if args.json:
        print_json(result.as_dict(curves=False))
    else:
        if flags:
            print(f"{UNUSABLE}: {len(flags)} flag{'s' if len(flags) > 1 else ''} (also at the top of report.md, "
                  "materials.toml and the scenes):")
            for line in flags:
                print(f"  - {line}")
        for e in result.estimates:
            flag = f"  AT {e.at_bound.upper()} BOUND ({e.bound_note})" if e.at_bound in ("low", "high") else ""
            if e.not_identified or e.at_bound == "not identified":
                flag += "  NOT IDENTIFIED"
            print(f"{e.label:28s} {e.value:12.5g} +- {e.std_error:.3g} {e.unit}{flag}")
        for f in result.fits:
            band = "" if f.in_band_fraction is None else f"; {100 * f.in_band_fraction:.0f} % of the strain range " \
                                                         "inside the band"
            print(f"{f.name}: RMS {f.rms_N:.4g} {f.force_unit} ({100 * f.rms_rel:.2g} %){band}; chi2 per row "
                  f"{f.chi2_per_row:.3g}; cells {f.status}"
                  + ("" if f.status == "ok" else " (DID NOT SOLVE ON EVERY ROW)"))
        for f in result.fits:
            if f.offset_N is not None:
                print(f"{f.name}: force offset {f.offset_N:+.4g} +- {f.offset_se_N:.2g} {f.offset_unit} "
                      f"({100 * f.offset_share:.3g} % of its peak measured force; the model's force at grip strain 0 "
                      f"{f.pretension_N:.4g} {f.force_unit})")
            if f.tare_N is not None:
                print(f"{f.name}: tared at the model's force at grip strain 0: {f.tare_N:.4g} N"
                      + ("" if f.offset_unit == "N (total)" else " per wale"))
        n_off = result.n_offsets
        print(f"fit: chi2 / (n - k) = {result.s2:.3g} ({result.n} rows and priors, {result.k} "
              + (f"parameters: {result.k - n_off} variables and {n_off} force offsets" if n_off else
                 f"variables, no force offset (calibration.zero = \"{result.zero}\")")
              + f"; about 1 where the model makes the curves within their noise, flagged above {POOR_FIT_S2:g})")
        for line in result.notes:
            print(f"note: {line}")
    return 0 if result.success and not flags else 1
