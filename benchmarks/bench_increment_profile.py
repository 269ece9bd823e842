"""Time of each increment of a random batch (the cells of ``bench_table.random_arrays``), one launch per
increment with the cells sorted by stage: ``run_batch``'s GPU default (two passes, the full step in
``SUBSTEP_SLICES``), or with ``--compare-passes`` two passes against one pass (no slices), with how many
cells the first pass left for the full step.  On CUDA the same increments are run again under
``wp.ScopedTimer`` for each kernel's summed GPU time.  Shows which increments cost the time.  Not a test.

    python benchmarks/bench_increment_profile.py --device cuda --cells 1000000 --increments 62
"""
from __future__ import annotations

import argparse
import collections
import os
import sys
import time

import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_table import random_arrays  # noqa: E402

from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import SUBSTEP_SLICES, CellModel, CellSolver, ProgramHistory  # noqa: E402
from knitsim.cell.load_program import cycles  # noqa: E402


def _timed_increments(model, prog, increments, device, kw):
    """Per-increment wall times (synchronised) of one run from the rest state; the rest state's time."""
    solver = CellSolver(model, event_capacity=16 * model.cell_count + 64)
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    state = model.state()
    wp.synchronize_device(device)
    rest = time.perf_counter() - t0
    hist = ProgramHistory.empty(model, len(prog), 10, False)
    rows = []
    for k in range(increments):
        t = time.perf_counter()
        solver.run_program(state, prog, 10, k, k + 1, hist, **kw)
        wp.synchronize_device(device)
        dt = time.perf_counter() - t
        left = (sum(int(c.numpy()[0]) for _, c in solver._pending) if kw.get("compact") and not kw.get("slices")
                else None)
        rows.append((k, dt, left))
    return rows, rest


def _kernel_times(model, prog, increments, device, kw):
    """Each kernel's summed GPU time [ms] and launch count over the same increments (CUDA only)."""
    solver, state = CellSolver(model, event_capacity=16 * model.cell_count + 64), model.state()
    hist = ProgramHistory.empty(model, len(prog), 10, False)
    with wp.ScopedTimer("increments", cuda_filter=wp.TIMING_ALL, synchronize=True, print=False) as timer:
        for k in range(increments):
            solver.run_program(state, prog, 10, k, k + 1, hist, **kw)
    agg = collections.defaultdict(lambda: [0, 0.0])
    for r in timer.timing_results:
        agg[r.name][0] += 1
        agg[r.name][1] += r.elapsed
    return timer.elapsed, sorted(agg.items(), key=lambda kv: -kv[1][1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--cells", type=int, default=2000)
    ap.add_argument("--increments", type=int, default=62)
    ap.add_argument("--compare-passes", action="store_true",
                    help="two passes against one pass, without slices (the 2026-11-27 profile)")
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    cuda = wp.get_device(device).is_cuda
    prog = cycles(0.10, 0.60, 3, max_increment=0.01)
    model = CellModel.from_arrays(**random_arrays(a.cells), device=device)
    if a.compare_passes:
        modes = [("two passes", dict(compact=True)), ("one pass", dict(compact=False))]
    else:
        modes = [("run_batch's default", dict(compact=True, slices=SUBSTEP_SLICES if cuda else ()))]
    for name, extra in modes:
        kw = dict(per_increment=True, sort_by_stage=True, **extra)
        _timed_increments(model, prog, 2, device, kw)          # compiles (not reported)
        rows, rest = _timed_increments(model, prog, a.increments, device, kw)
        total = sum(r[1] for r in rows)
        print(f"{name}, sorted by stage: {total:.3f} s for {a.cells} cells x {a.increments} increments on {device} "
              f"({wp.get_device(device).name}): {a.cells * a.increments / total:.3e} cell-increments / s; "
              f"rest state {rest:.3f} s (not in the total)")
        with_left = rows[0][2] is not None
        print(f"{'incr':>5} {'strain':>7} {'dir':>4} {'ms':>9}" + (f" {'left for the full step':>24}" if with_left else ""))
        for k, dt, left in rows:
            print(f"{k:>5} {prog.strain[k]:>7.3f} {int(prog.direction[k]):>4} {1e3 * dt:>9.1f}"
                  + (f" {left:>24}" if with_left else ""))
        if cuda:
            elapsed, kernels = _kernel_times(model, prog, a.increments, device, kw)
            print(f"per kernel, the same increments again ({elapsed:.1f} ms):")
            for kname, (count, ms) in kernels[:12]:
                print(f"  {ms:10.1f} ms {count:6d}  {kname[:100]}")


if __name__ == "__main__":
    main()
