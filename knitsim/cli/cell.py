"""``knitsim cell``: run quarter-stitch cells (Dusserre 2015) through a load program.

``knitsim cell SCENE.toml [--out DIR] [--set key=value ...] [--engine warp|reference]
[--device cpu|cuda|auto] [--json]``

The scene (:mod:`knitsim.scene.cell_scene`) is read, overridden, validated and
resolved before anything is solved or written; the results go to ``DIR``
(default ``<scene stem>_out`` in the working directory): ``curve.csv``,
``events.csv``, ``scene.resolved.toml``, ``plot.png`` and ``summary.json``
(:mod:`knitsim.io.results`).  Progress goes to stderr; ``--json`` prints the
summary on stdout.
"""
from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

from ..cell.engine import ENGINES, check_engine, simulate
from ..io.checks import calibration_warnings, inert_effect_warnings
from ..io.results import (OUTPUT_FILES, add_output_flags, first_loading, prepare_output_dir, run_info, scene_inputs,
                          summarise, write_cell_results)
from ..scene.cell_scene import load_cell_scene
from .common import Progress, add_json_flag, naming_scene, print_json


def register(subparsers) -> None:
    """Add ``knitsim cell``."""
    parser = subparsers.add_parser(
        "cell", help="run quarter-stitch cells through a load program (Dusserre 2015)",
        description="Run one cell or a batch (scene [[cells]]) through a strain program and write "
                    "curve.csv, events.csv, summary.json, scene.resolved.toml and plot.png.")
    parser.add_argument("scene", metavar="SCENE.toml", help="cell scene file (see scenes/paper/)")
    parser.add_argument("--out", metavar="DIR", default=None, help="output directory (default: <scene stem>_out)")
    parser.add_argument("--set", metavar="KEY=VALUE", action="append", default=[], dest="overrides",
                        help="override a scene key, type-checked, e.g. --set yarn.B=0.25 "
                             "or --set cells[1].friction.m=0.3 (repeatable)")
    parser.add_argument("--engine", choices=ENGINES, default=None, help="override the scene's engine")
    parser.add_argument("--device", default=None, help="Warp device: cpu, cuda, cuda:N or auto (warp engine)")
    add_output_flags(parser)
    add_json_flag(parser)
    parser.set_defaults(func=_run)


def check_cells_domain(params, labels, strains, engine: str = "reference", device: str = "cpu") -> list[dict]:
    """Before any solve: a cell without an admissible rest state is an error (one line, naming the
    cell: it is outside the model, knitsim.cell.domain.rest_state_problem), and so is one whose rest
    state already carries its force cap (rest_at_cap_problem); a cell or a program
    outside the documented domain's box is an extrapolation: returned as warnings for the summary.

    The rest state is judged by the engine that will run the cells (:func:`knitsim.cell.domain.check_cells`,
    as ``knitsim run`` and ``knitsim sweep`` judge theirs): a cell is refused exactly where that engine would
    flag it ``no_rest_state`` at rest, and the cap is checked against that engine's rest force.  The
    reference's continuation in L (:func:`~knitsim.cell.domain.rest_state_problem`) only words a refusal:
    where its branch ended.  (A blind probe's tight corner cell, d = 0.1, B = 10, W0 = 5.5 d, C0 = 4 d, L
    ratio 1.765, has a rest state that the Warp engine, whose Newton runs in ln(alpha - gamma), solves and
    the reference's continuation stops short of: it runs with the Warp engine.)"""
    from ..cell.domain import DOMAIN, check_cells, rest_at_cap_problem, rest_state_problem
    from ..errors import KnitsimInputError

    check = check_cells(params, engine=engine, device=device)
    rest_F = check.rest_F_array
    warnings = []
    for i, (p, label) in enumerate(zip(params, labels)):
        name = str(label) if str(label).startswith("cell") else f"cell {label}"
        if check.no_rest_mask[i]:
            # the engine's verdict, worded by the reference's continuation (where its branch ended, or the
            # pulling contact's force); a cell the reference reaches and the engine does not: the engine's words
            why = rest_state_problem(p, engine, device) or f"{check.no_rest_reason(i)} (engine = \"{engine}\")"
            raise KnitsimInputError(f"{name}: {why} (knitsim.cell.domain)")
        why = rest_at_cap_problem(float(rest_F[i]), p.cap_N)
        if why is not None:
            raise KnitsimInputError(f"{name}: {why}")
        why = check.outside_reason(i)
        if why is not None:
            warnings.append({"code": "outside_domain", "message": f"extrapolation: {why}", "cell": label})
    why = DOMAIN.why_program_outside(strains)
    if why is not None:
        warnings.append({"code": "outside_domain", "message": f"extrapolation: {why}", "cell": "all"})
    return warnings


def _overrides_not_reaching(path: str, overrides: list[str], labels: list) -> list[dict]:
    """A warning per ``--set`` of a base key (``friction.m=0.3``) that cells of ``[[cells]]`` state themselves
    (:func:`knitsim.scene.cell_scene.cells_stating`): their own value wins, the --set does not reach them (a blind
    probe's --set friction.m=0.3 ran a cell of m = 0.4 at 0.4, said only in summary.json's params)."""
    from ..scene.cell_scene import CELL_SCENE, cells_stating
    from ..scene.schema import fmt, load_toml, set_value

    if not overrides:
        return []
    doc = load_toml(path)
    for a in overrides:
        set_value(doc, CELL_SCENE, a)            # (as the scene was read: a --set of a cell's key is its own value)
    out = []
    for a in overrides:
        key = a.split("=", 1)[0].strip()
        own = cells_stating(doc, key)
        if own:
            i, k = next(iter(own.items()))
            table = key.partition(".")[0]
            names = ", ".join(str(labels[j]) for j in list(own)[:5]) + (", ..." if len(own) > 5 else "")
            out.append({"code": "set_key_set_by_cell", "cell": "all",
                        "message": f"--set {a}: {len(own)} of the scene's {len(labels)} cell(s) ({names}) set {key} "
                                   f"themselves (e.g. cells[{i}].{table}.{k} = {fmt(doc['cells'][i][table][k])}): "
                                   f"their own value wins, the --set does not reach them (--set cells[{i}].{table}."
                                   f"{k}=... for one)"})
    return out


def _run(args) -> int:
    t_command = time.perf_counter()
    with naming_scene(args.scene, "cell"):
        scene = load_cell_scene(args.scene, args.overrides, engine=args.engine, device=args.device)
    check_engine(scene.engine)   # (before the domain check, which asks the engine for the rest states)
    # (the Warp engine's rest states: one small CPU launch, before the run's device is up; its messages, if
    # any, on stderr: stdout carries only the results)
    with contextlib.redirect_stdout(sys.stderr), naming_scene(args.scene):   # (a refusal names the scene)
        domain_warnings = check_cells_domain(scene.params, scene.labels, scene.program.strain, engine=scene.engine)
    domain_warnings += calibration_warnings(scene.calibration_flags)
    domain_warnings += _overrides_not_reaching(args.scene, args.overrides, scene.labels)
    domain_warnings += inert_effect_warnings([p.effects for p in scene.params], scene.labels)
    out = prepare_output_dir(args.out if args.out is not None else f"{Path(args.scene).stem}_out",
                             overwrite=args.overwrite,
                             writes=OUTPUT_FILES, inputs=scene_inputs(args.scene))
    # stdout carries only the results (--json): Warp's start-up banner and module messages go to stderr
    with contextlib.redirect_stdout(sys.stderr):
        device = scene.device
        if scene.engine == "warp":
            from .. import warp_runtime
            device = warp_runtime.resolve_device(device)
        else:
            device = "cpu"
        n, m = len(scene.params), len(scene.program)
        print(f"knitsim cell: {n} cell(s) x {m} increments, engine {scene.engine}, device {device}",
              file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        # the reference runs one cell after the other: its unit is a cell's increment
        what = ("knitsim cell: increments", m) if scene.engine == "warp" or n == 1 else \
            ("knitsim cell: cell-increments", n * m)
        history = simulate(scene.params, scene.program, engine=scene.engine, device=device,
                           progress=Progress(what[1], what[0]))
        # the first loading's continuation, where the program reloads past an earlier maximum (its check)
        reference = first_loading(scene.params, scene.program, engine=scene.engine, device=device)
    wall = time.perf_counter() - t0
    summary = summarise(history, scene.labels, scene.notes, reference=reference, **run_info(scene, device, wall))
    summary["warnings"] = list(domain_warnings) + list(summary.get("warnings", []))
    files = write_cell_results(out, history, summary, scene.to_toml(), scene.labels, plot=scene.plot,
                               title=scene.resolved.get("title", ""))
    print(f"knitsim cell: done in {time.perf_counter() - t_command:.2f} s (solving {wall:.2f} s); wrote "
          f"{', '.join(sorted(files))} to {out}", file=sys.stderr, flush=True)
    for w in summary["warnings"]:
        print(f"knitsim cell: warning: {w['cell']}: {w['message']}", file=sys.stderr, flush=True)
    failed = [c["label"] for c in summary["cells"] if not c["expected_end"]]
    if failed:
        print(f"knitsim cell: warning: {len(failed)} cell(s) did not reach the end of the program "
              f"({', '.join(failed[:5])}); see summary.json", file=sys.stderr, flush=True)
    if args.json:
        print_json(summary)
        return 1 if failed else 0
    for c in summary["cells"]:
        # a cycle that only unloads has no loaded peak: its figure is its start (warning cycle_without_loading)
        peaks = ", ".join(f"{cy['peak_force_per_wale_N']:.3g}"
                          + (" (unloading only: its start)" if cy.get("energy_kind") == "unloading_work" else "")
                          # (knitsim run's peak stops at the last increment completed before cells failed)
                          + (f" (the last converged state, at strain {cy['strain_at_peak']:.4g}, inside the "
                             "increment the cell could not finish)" if cy.get("peak_is_last_converged_state") else "")
                          for cy in c["cycles"])
        jam = c["strain_at_first_jamming"]
        print(f"{c['label']}: {c['end']}; peak force per wale per cycle [N]: {peaks}; "
              f"first jamming at strain {'-' if jam is None else f'{jam:.4g}'}")
    return 1 if failed else 0
