"""``knitsim calibrate``: one yarn calibrated jointly on several specimens (issue 16).

``knitsim calibrate SCENE.toml [--out DIR] [--set key=value ...] [--device cpu|cuda|auto] [--overwrite] [--json]``

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
Exit status 0 when the fit converged, every cell solved and no parameter is at
a bound; 1 otherwise (the flags are printed and in the report); 2 on bad input.
"""
from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

from ..io.results import add_output_flags, prepare_output_dir
from .common import add_json_flag, print_json


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
    add_output_flags(p)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    t0 = time.perf_counter()
    from ..calibration.joint import calibrate_joint
    from ..calibration.outputs import write_calibration
    from ..calibration.scene import load_calibration_scene

    scene = load_calibration_scene(args.scene, args.overrides, device=args.device)
    out = prepare_output_dir(args.out or f"{Path(args.scene).stem}_calibrated", overwrite=args.overwrite)
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
        result = calibrate_joint(sp, scene.setup,
                                 progress=lambda line: print(f"knitsim calibrate: {line}", file=sys.stderr,
                                                             flush=True))
    files = write_calibration(out, result, scene, str(args.scene))
    print(f"knitsim calibrate: done in {time.perf_counter() - t0:.1f} s; wrote {', '.join(sorted(files))} to {out}",
          file=sys.stderr, flush=True)
    for line in result.flags:
        print(f"knitsim calibrate: warning: {line}", file=sys.stderr, flush=True)
    if not result.success:
        print(f"knitsim calibrate: warning: {result.message}", file=sys.stderr, flush=True)
    if args.json:
        print_json(result.as_dict(curves=False))
    else:
        for e in result.estimates:
            flag = f"  AT {e.at_bound.upper()} BOUND ({e.bound_note})" if e.at_bound else ""
            print(f"{e.label:28s} {e.value:12.5g} +- {e.std_error:.3g} {e.unit}{flag}")
        for f in result.fits:
            band = "" if f.in_band_fraction is None else f"; {100 * f.in_band_fraction:.0f} % of the strain range " \
                                                         "inside the band"
            print(f"{f.name}: RMS {f.rms_N:.4g} N ({100 * f.rms_rel:.2g} %){band}; cells {f.status}")
    return 0 if result.success and not result.flags else 1
