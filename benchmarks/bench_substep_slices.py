"""The GPU batch with the full step in slices of sub-steps (``run_program(..., slices=...)``), in one run:
10^6 random cells (``bench_table.random_arrays``) through the first 62 increments, two passes sorted by
stage (``run_batch``'s GPU default), for several slice schedules beside the unsliced full step.  Each
schedule's recorded rows, statuses, stages and events are compared with the unsliced run's, bit for
bit (the sliced walk is the same arithmetic), and the ratio of the wall times is printed.  Not a test.

    python benchmarks/bench_substep_slices.py --schedules "" default "2,2,2,2" "1,1,2,2,4" --reps 2
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_table import prefix, random_arrays, timed  # noqa: E402

from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import SUBSTEP_SLICES, CellModel, CellSolver, ProgramHistory  # noqa: E402
from knitsim.cell.load_program import cycles  # noqa: E402


def schedule(text: str) -> tuple[int, ...]:
    """``"2,2,4"`` -> (2, 2, 4); ``""`` -> () (the full step in one launch); ``"default"`` -> run_batch's
    :data:`~knitsim.cell.batch.SUBSTEP_SLICES`."""
    if text.strip() == "default":
        return SUBSTEP_SLICES
    return tuple(int(t) for t in text.split(",") if t.strip())


def run(model: CellModel, prog, device: str, slices: tuple[int, ...], stride: int, sort: bool):
    """One timed run (after a compiling run of the first increments) and what it recorded."""
    solver = CellSolver(model, event_capacity=16 * model.cell_count + 64)
    kw = dict(per_increment=True, sort_by_stage=sort, compact=True, slices=slices)
    solver.run_program(model.state(), prefix(prog, 2), stride=1, **kw)  # compile (not timed)
    solver = CellSolver(model, event_capacity=16 * model.cell_count + 64)
    state = model.state()
    hist = ProgramHistory.empty(model, len(prog), stride, model.has_effects)
    _, wall, _ = timed(lambda: solver.run_program(state, prog, stride=stride, history=hist, **kw), device)
    rec = {"q": hist.q.numpy(), "stage": hist.stage.numpy(), "status": hist.status.numpy(), "x": state.x.numpy()}
    rec.update({"ev_" + k: v for k, v in solver.event_arrays().items()})
    return wall, rec


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--cells", type=int, default=1_000_000)
    ap.add_argument("--increments", type=int, default=62)
    ap.add_argument("--stride", type=int, default=10)
    ap.add_argument("--schedules", nargs="+", default=["", "default"],
                    help='sub-step budgets of the sliced launches, comma-separated ("": unsliced, the baseline; '
                         '"default": run_batch\'s SUBSTEP_SLICES)')
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--no-sort", action="store_true", help="cells in the caller's order (not sorted by stage)")
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    prog = prefix(cycles(0.10, 0.60, 3, max_increment=0.01), a.increments)
    model = CellModel.from_arrays(**random_arrays(a.cells), device=device)
    scheds = [schedule(s) for s in a.schedules]
    if () not in scheds:
        scheds.insert(0, ())
    name = wp.get_device(device).name if wp.get_device(device).is_cuda else "cpu"
    print(f"{a.cells} random cells x {a.increments} increments on {name}; two passes"
          f"{'' if a.no_sort else ', sorted by stage'}", flush=True)
    base = None
    for rep in range(a.reps):
        walls = {}
        for sl in scheds:
            wall, rec = run(model, prog, device, sl, a.stride, not a.no_sort)
            walls[sl] = wall
            if sl == ():
                base = rec
            same = all(np.array_equal(rec[k], base[k], equal_nan=True) for k in base) if base is not None else None
            ratio = walls[()] / wall if () in walls else float("nan")
            label = "default" if sl == SUBSTEP_SLICES else (",".join(map(str, sl)) or "none")
            print(f"rep {rep}  slices {label:<16} {wall:8.2f} s  "
                  f"{model.cell_count * len(prog) / wall:.3e} cell-increments / s  "
                  f"x{ratio:.2f} against unsliced  bit for bit: {same}", flush=True)


if __name__ == "__main__":
    main()
