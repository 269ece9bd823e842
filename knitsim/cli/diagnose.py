"""``knitsim diagnose``: where a simulation and measured curves disagree, and which effect explains it.

    knitsim diagnose MEASURED.csv [MORE.csv ...] --scene SCENE.toml --json OUT.json --report OUT.html

Each CSV is a measured curve of the same specimen (columns ``strain``,
``force_per_wale_N``, optional ``cycle``, ``direction``, ``rate_mm_s``;
:mod:`knitsim.diagnosis.measured`); the scene says what is known of the
specimen and what is calibrated (:mod:`knitsim.scene.diagnosis_scene`).
The diagnosis itself is :func:`knitsim.diagnosis.diagnose.diagnose`.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from ..errors import KnitsimInputError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "diagnose", help="sim-to-real gap: calibrate, locate the gap by stage, rank the unmodelled effects",
        description=__doc__.split("\n\n")[0] + "\n\n" + __doc__.split("\n\n")[2])
    p.add_argument("curves", nargs="+", metavar="MEASURED.csv", help="measured curves of one specimen")
    p.add_argument("--scene", required=True, metavar="SCENE.toml", help="diagnosis scene (specimen, [diagnosis])")
    p.add_argument("--json", dest="json_out", metavar="OUT.json", help="write the diagnosis as JSON")
    p.add_argument("--report", metavar="OUT.html", help="write an HTML report with figures")
    p.add_argument("--device", help="Warp device (cpu, cuda, cuda:N, auto); default: the scene's")
    p.add_argument("--effects", metavar="a,b,...", help="effects to try (default: the scene's, else all)")
    p.add_argument("--no-pair", action="store_true", help="skip the best-pair search")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def _check_out(path: str | None, suffix: str, flag: str) -> Path | None:
    if path is None:
        return None
    out = Path(path)
    if out.suffix.lower() != suffix:
        raise KnitsimInputError(f"{flag} = {path!r}: expected a {suffix} file")
    if out.exists() and out.is_dir():
        raise KnitsimInputError(f"{flag} = {path!r}: is a folder")
    return out


def run(args) -> int:
    from dataclasses import replace

    from ..diagnosis.diagnose import diagnose
    from ..diagnosis.effects import check_effects
    from ..diagnosis.measured import read_measured_curve
    from ..diagnosis.report import write_report
    from ..io.jsonable import json_text
    from ..io.results import atomic_write_bytes
    from ..scene.diagnosis_scene import load_diagnosis_scene

    # every input is checked before any solve
    json_out = _check_out(args.json_out, ".json", "--json")
    report = _check_out(args.report, ".html", "--report")
    setup = load_diagnosis_scene(args.scene, device=args.device)
    if args.effects:
        setup = replace(setup, effects=check_effects([e.strip() for e in args.effects.split(",") if e.strip()],
                                                     where="--effects"))
    if args.no_pair:
        setup = replace(setup, pair=False)
    curves = [read_measured_curve(c) for c in args.curves]
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    result = diagnose(curves, setup, progress=progress)
    for out in (json_out, report):
        if out is not None:
            out.parent.mkdir(parents=True, exist_ok=True)
    if json_out is not None:
        atomic_write_bytes(json_out, json_text(result, indent=1).encode())
    if report is not None:
        write_report(result, report)
    v = result["verdict"]
    b = result["baseline"]
    print(f"baseline: rms {b['rms_N']:.4g} N per wale ({', '.join(f'{k} = {x:.4g}' for k, x in b['params'].items())});"
          f" noise sd {result['noise']['sigma_N']:.3g} N")
    print("gap by stage: " + ", ".join(f"{k} {b['stages'][k]['share']:.0%}" for k in result["where"]))
    for c in result["candidates"]:
        if c["score"] is None:
            print(f"  {c['effect']:<24s} not identifiable: {c['note']}")
        else:
            print(f"  {c['effect']:<24s} rms {c['rms_N']:.4g} N  shrink {c['shrink']:6.1%}  score {c['score']:10.4g}"
                  f"  {'significant' if c['significant'] else ''}")
    if v["effect"] is None:
        print(f"verdict: no effect is significant ({v['reason']})")
    else:
        print(f"verdict: {v['effect']} (stage {v['stage']}, shrink {v['shrink']:.1%}, "
              f"{'confident' if v['confident'] else 'not confident'}: {v['reason']})")
    if result["pair"] is not None:
        pr = result["pair"]
        print(f"best pair: {' + '.join(pr['effects'])}: rms {pr['rms_N']:.4g} N, shrink {pr['shrink']:.1%}, "
              f"{'a significant' if pr['significant'] else 'no significant'} gain over the best effect alone "
              f"(BIC {pr['gain_over_best']:+.4g})")
    print(f"({result['timing_s']:.1f} s)")
    return 0
