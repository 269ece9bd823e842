"""knitsim diagnose: is anything missing from the model, where do a simulation and measured curves
disagree, and which effect explains it.

    knitsim diagnose MEASURED.csv [MORE.csv ...] --scene SCENE.toml --json OUT.json --report OUT.html

Each CSV is a measured curve of the same specimen: columns strain,
force_per_wale_N (N or N/wale), optional cycle (from 1, or from 0), direction
(load / unload, up / down, L / U, + / -), rate_mm_s; comma, semicolon or tab
separated, Excel's UTF-8 BOM and decimal commas accepted.
Each curve's noise is estimated from that curve alone unless given (--noise-N
FILE=SD, or the scene's [diagnosis] noise_N / [[diagnosis.noise]]). The scene
says what is known of the specimen and what is calibrated.

The verdict is "none" when the calibrated model explains the curves within
their noise, an effect when one clears both the evidence threshold (BIC drop
> 10) and the size threshold (it removes half of the gap beyond the noise),
and "unexplained" otherwise, with the stage where the gap lies.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from ..errors import KnitsimInputError
from .common import naming_scene


def register(subparsers) -> None:
    """Add ``knitsim diagnose``."""
    p = subparsers.add_parser(
        "diagnose", help="sim-to-real gap: calibrate, test the fit against the noise, rank the unmodelled effects",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("curves", nargs="+", metavar="MEASURED.csv", help="measured curves of one specimen")
    p.add_argument("--scene", required=True, metavar="SCENE.toml", help="diagnosis scene (specimen, [diagnosis])")
    p.add_argument("--json", dest="json_out", metavar="OUT.json", help="write the diagnosis as JSON")
    p.add_argument("--report", metavar="OUT.html", help="write an HTML report with figures")
    p.add_argument("--device", help="Warp device (cpu, cuda, cuda:N, auto); default: the scene's")
    p.add_argument("--effects", metavar="a,b,...", help="effects to try (default: the scene's, else all)")
    p.add_argument("--noise-N", action="append", default=[], metavar="[FILE=]SD",
                   help="noise sd [N per wale] of FILE (repeat per file), or of every curve; default: estimated "
                        "from each curve itself")
    p.add_argument("--no-pair", action="store_true", help="skip the best-pair search")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--overwrite", action="store_true", help="replace existing --json / --report files (else refused)")
    p.set_defaults(func=run)


def _check_out(path: str | None, suffix: str, flag: str, overwrite: bool) -> Path | None:
    from ..io.results import prepare_output_file
    return prepare_output_file(path, overwrite, flag, suffix=suffix)


def run(args) -> int:
    """``knitsim diagnose``: diagnose the measured curves, write ``--json`` / ``--report`` if asked and
    print the summary."""
    from dataclasses import replace

    from ..diagnosis.diagnose import diagnose
    from ..diagnosis.effects import check_effects
    from ..diagnosis.measured import read_measured_curve
    from ..diagnosis.report import fit_uncertainty, write_report
    from ..io.jsonable import json_text
    from ..io.results import atomic_write_bytes
    from ..scene.diagnosis_scene import load_diagnosis_scene

    # every input is checked before any solve
    json_out = _check_out(args.json_out, ".json", "--json", args.overwrite)
    report = _check_out(args.report, ".html", "--report", args.overwrite)
    with naming_scene(args.scene, "diagnose"):
        setup = load_diagnosis_scene(args.scene, device=args.device)
    if args.effects:
        setup = replace(setup, effects=check_effects([e.strip() for e in args.effects.split(",") if e.strip()],
                                                     where="--effects"))
    if args.no_pair:
        setup = replace(setup, pair=False)
    noise = _noise_args(args.noise_N, args.curves, setup.noise_N)
    curves = [read_measured_curve(c, noise.get(c)) for c in args.curves]
    for c in curves:
        # what was read, in the units it was read in: a column per specimen or in kN shows here, before the fits
        print(f"read {c.source}: {len(c)} rows, strain {float(c.strain.min()):.4g} to {float(c.strain.max()):.4g}, "
              f"force {float(c.force.min()):.4g} to {float(c.force.max()):.4g} N per wale, "
              f"{int(c.cycle.max()) - int(c.cycle.min()) + 1} cycle(s)"
              + "".join(f"; {n}" for n in c.notes), flush=True)
    setup = replace(setup, noise_N=noise or None)
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    result = diagnose(curves, setup, progress=progress).as_dict()
    for out in (json_out, report):
        if out is not None:
            out.parent.mkdir(parents=True, exist_ok=True)
    if json_out is not None:
        atomic_write_bytes(json_out, json_text(result, indent=1).encode())
    if report is not None:
        write_report(result, report)
    v = result["verdict"]
    b = result["baseline"]
    nz = result["noise"]
    def fitted(k: str, x: float) -> str:
        # the fit's standard error beside its value, where it has one (a blind probe read m 0.337 on a basalt pull
        # with no way to tell whether 0.25 was within it), else why not (the report's words: fit_uncertainty)
        kind, v = fit_uncertainty(k, b["std_errors"], b["at_bounds"])
        if kind == "se":
            return f"{k} = {x:.4g} +- {v:.2g}"
        return f"{k} = {x:.4g}" + {"bound": f" (at its {v} bound)", "undetermined": " (not determined by the data)",
                                   None: ""}[kind]

    print(f"baseline: rms {b['rms_N']:.4g} N per wale ({', '.join(fitted(k, x) for k, x in b['params'].items())}; "
          "+- one standard error)")
    for c in nz["curves"]:
        grows = f" + {100.0 * c['per_N']:.3g} % of the force" if c.get("per_N") else ""
        if c.get("strain_sd"):
            grows += f", strain jitter {c['strain_sd']:.2g} (times the curve's slope)"
        print(f"  noise of {c['source']}: {c['sigma_N']:.3g} N{grows} ({c['method']}"
              f"{'' if c['estimable'] else ': ' + c['note']})")
    if b["outliers"]:
        print(f"  {len(b['outliers'])} outlier row(s) left out: " + ", ".join(
            f"{Path(o['source']).name} row {o['row']} ({o['z']:+.1f} sd)" for o in b["outliers"][:5]))
    within = {True: "within noise", False: "NOT within noise", None: "cannot be judged"}[nz["baseline_within_noise"]]
    print(f"fit: chi2/dof {nz['baseline_chi2_per_dof']:.4g} (1 +- {nz['expected_sd']:.2g} for noise alone): {within}")
    print(_stage_line(result))
    for c in result["candidates"]:
        if c["score"] is None:
            print(f"  {c['effect']:<24s} not identifiable: {c['note']}")
        elif c.get("flagged_curves"):
            # its fit's chi2 is no model's (rows held at a failed increment): no score, share or p to show
            print(f"  {c['effect']:<24s} {c['note']}")
        else:
            share = "n/a" if c["share_of_excess"] is None else f"{c['share_of_excess']:.0%}"
            prob = "  n/a" if c["probability"] is None else f"{c['probability']:.3f}"
            fit = "" if c.get("chi2_per_dof") is None else (
                f"  chi2/dof {c['chi2_per_dof']:.3g}{' within noise' if c.get('within_noise') else ''}")
            # only the verdict's effect is named; others may pass the same tests (a closer rival, a pair)
            mark = "  named" if v.get("effect") is not None and v.get("effect") == c["effect"] else (
                "  passes the naming tests" if c["significant"] and c["practical"] else "")
            print(f"  {c['effect']:<24s} p {prob}  score {c['score']:10.4g}  share of gap {share:>6s}{fit}"
                  f"  shrink {c['shrink']:6.1%}{mark}"
                  f"{'  (evidence rests on assumed noise)' if c.get('rests_on_assumed_noise') else ''}")
    probs = ", ".join(f"{k} {p:.2f}" for k, p in sorted(v["probabilities"].items(), key=lambda kv: -kv[1])[:4])
    conf = "confident" if v["confident"] else "not confident"
    if v["kind"] == "none":
        print(f"verdict: none, nothing is missing ({conf}: {v['reason']})")
    elif v["kind"] == "unexplained":
        print(f"verdict: unexplained ({conf}: {v['reason']})")
    else:
        print(f"verdict: {v['effect']} (stage {v['stage']}, shrink {v['shrink']:.1%}, {conf}: {v['reason']})")
    print(f"probabilities: {probs}")
    if result["pair"] is not None:
        pr = result["pair"]
        print(f"best pair: {' + '.join(pr['effects'])}: rms {pr['rms_N']:.4g} N, shrink {pr['shrink']:.1%}, "
              f"{'a significant' if pr['significant'] else 'no significant'} gain over the best effect alone "
              f"(BIC {pr['gain_over_best']:+.4g})"
              + (f"; at the bounds of its search (values not estimated): {pr['at_bounds_note']}"
                 if pr.get("at_bounds_note") else ""))
    print(f"({result['timing_s']:.1f} s)")
    return 0


def _stage_line(result: dict) -> str:
    """The console's "gap by stage" line: each stage's share of the baseline's chi2 excess, where there is a gap.

    Where the baseline fits within the noise there is none, and the shares are of the noise's own excess: a
    confident ``none`` printed "gap by stage: unloading_sliding 82 %" beside "nothing is missing", which reads as
    a gap (the README: a ``none`` verdict names no stage).  The JSON keeps the stages' figures."""
    b, nz = result["baseline"], result["noise"]
    shares = {k: b["stages"][k]["share"] for k in result["where"]}
    if all(v is None or not math.isfinite(v) for v in shares.values()):
        # no stage's chi2 exceeds what its rows' noise gives: there is no gap to share out
        return "gap by stage: none beyond the noise (no stage's chi2 exceeds its row count)"
    if nz.get("baseline_within_noise") is True or (result.get("verdict") or {}).get("kind") == "none":
        # (a `none` where every curve's noise is assumed: the baseline within that assumed noise)
        return ("gap by stage: none beyond the noise (the baseline fits within it; how its chi2 falls on the stages "
                "is the noise's)")
    return "gap by stage: " + ", ".join(f"{k} {v:.0%}" if v is not None and math.isfinite(v) else f"{k} n/a"
                                        for k, v in shares.items())


def _noise_args(items, curves, scene_noise) -> dict:
    """``{curve path: sd}`` from ``--noise-N [FILE=]SD`` and the scene's per-file table (matched by path or name)."""
    out: dict = {}

    def match(name: str, where: str):
        hits = [c for c in curves if Path(c).resolve() == Path(name).resolve()] or \
               [c for c in curves if Path(c).name == Path(name).name]
        if not hits:
            raise KnitsimInputError(f"{where}: {name!r} is not among the measured curves ({', '.join(curves)})")
        return hits

    def number(text, where):
        try:
            v = float(text)
        except ValueError:
            raise KnitsimInputError(f"{where}: {text!r} is not a number [N]") from None
        if not (v > 0 and v < float("inf")):
            raise KnitsimInputError(f"{where}: {text!r} must be a noise sd > 0 [N]")
        return v

    if isinstance(scene_noise, dict):
        for name, sd in scene_noise.items():
            for c in match(name, "diagnosis.noise"):
                out[c] = float(sd)
    elif scene_noise is not None:
        out.update({c: float(scene_noise) for c in curves})
    for item in items:
        if "=" in item:
            name, _, sd = item.rpartition("=")
            for c in match(name, f"--noise-N {item}"):
                out[c] = number(sd, f"--noise-N {item}")
        else:
            out.update({c: number(item, f"--noise-N {item}") for c in curves})
    return out
