"""Time of each increment of a random batch (the cells of ``bench_table.random_arrays``), one launch per
increment with the cells sorted by stage, with and without the two passes; with the two passes, how
many cells the first pass left for the full step.  Shows which increments cost the time.  Not a test.

    python benchmarks/bench_increment_profile.py --device cuda --cells 1000000 --increments 62
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_table import random_arrays  # noqa: E402

from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import CellModel, CellSolver, ProgramHistory  # noqa: E402
from knitsim.cell.load_program import cycles  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--cells", type=int, default=2000)
    ap.add_argument("--increments", type=int, default=62)
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    prog = cycles(0.10, 0.60, 3, max_increment=0.01)
    model = CellModel.from_arrays(**random_arrays(a.cells), device=device)
    for compact in (True, False):
        solver, state = CellSolver(model, event_capacity=16 * a.cells + 64), model.state()
        hist = ProgramHistory.empty(model, len(prog), 10, False)
        rows = []
        for k in range(a.increments):
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            solver.run_program(state, prog, 10, k, k + 1, hist, per_increment=True, sort_by_stage=True,
                               compact=compact)
            wp.synchronize_device(device)
            dt = time.perf_counter() - t0
            left = sum(int(c.numpy()[0]) for _, c in solver._pending) if compact else None
            rows.append((k, dt, left))
        print(f"{'two passes' if compact else 'one pass'}, sorted by stage: {sum(r[1] for r in rows):.3f} s "
              f"for {a.cells} cells x {a.increments} increments on {device} ({wp.get_device(device).name})")
        print(f"{'incr':>5} {'strain':>7} {'dir':>4} {'ms':>9}" + ("" if not compact else f" {'left for the full step':>24}"))
        for k, dt, left in rows:
            print(f"{k:>5} {prog.strain[k]:>7.3f} {int(prog.direction[k]):>4} {1e3 * dt:>9.1f}"
                  + ("" if left is None else f" {left:>24}"))


if __name__ == "__main__":
    main()
