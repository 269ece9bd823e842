"""A/B of the cell step kernel: another version of ``kernels/cell_step.py`` against the installed one, same
cells, same device, one process (the ratio the project reports for a kernel change).

The other version is a file, e.g. main before a change::

    git show 4254f5d:kernels/cell_step.py > /tmp/cell_step_base.py
    python benchmarks/bench_kernel_ab.py /tmp/cell_step_base.py --device cpu --cells 2000 --increments 0
    python benchmarks/bench_kernel_ab.py /tmp/cell_step_base.py --device cuda --cells 1000000 --increments 62 --stride 10

It is loaded once per kernel key as its own module (as :func:`knitsim.kernels.specialise.cell_step_module`
loads the installed file), so it must keep the installed file's kernel signatures.  Cells: the random
batch of ``bench_table.random_arrays``; program: the paper's 3 cycles 0.10-0.60 at 0.01, or its first
``--increments`` K.  Prints each version's wall and CPU time and rate, its final statuses and the largest
difference of every recorded quantity between the two.  Not a test.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_table import prefix, random_arrays  # noqa: E402


def other_module(path: str, key):
    """``path`` compiled for one kernel key, as its own module."""
    name = f"knitsim.kernels._ab_{key.name}"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        mod.KERNEL_KEY = key
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("other", help="the other kernels/cell_step.py")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--cells", type=int, default=300)
    ap.add_argument("--increments", type=int, default=62, help="first K increments of the 3 cycles (0: all 310)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stride", type=int, default=1,
                    help="rows recorded (and compared) every STRIDE increments: 11 quantities x 8 bytes per cell and "
                         "row, twice (5.5 GB a version at 10^6 cells x 62 rows)")
    a = ap.parse_args()

    from knitsim import warp_runtime
    from knitsim.cell.batch import CellModel, CellSolver
    from knitsim.cell.history import HISTORY_QUANTITIES
    from knitsim.cell.load_program import cycles

    warp_runtime.init()
    dev = warp_runtime.resolve_device(a.device)
    prog = prefix(cycles(0.10, 0.60, 3, max_increment=0.01), a.increments)
    model = CellModel.from_arrays(**random_arrays(a.cells, a.seed), device=dev)
    runs = {}
    for name in ("other", "installed"):
        solver = CellSolver(model, event_capacity=16 * a.cells + 64)
        if name == "other":
            solver.groups = [(other_module(a.other, k.KERNEL_KEY), idx) for k, idx in solver.groups]
        state = model.state()
        solver.run_program(state, prefix(prog, 2), stride=1)  # compile (not timed)
        state = model.state()
        wp.synchronize_device(dev)
        t, c = time.perf_counter(), time.process_time()
        hist = solver.run_program(state, prog, stride=a.stride)
        wp.synchronize_device(dev)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        status = np.bincount(state.status.numpy(), minlength=4).tolist()
        runs[name] = (hist.q.numpy(), hist.stage.numpy())
        rate = a.cells * len(prog) / wall
        print(f"{name:9s}: {a.cells} cells x {len(prog)} increments on {dev}: {wall:.2f} s wall, {cpu:.2f} s CPU, "
              f"{rate:.3g} cell-increments / s, status ok / no_convergence / force_cap / not_located {status}",
              flush=True)
        runs[name + "_rate"] = rate
    (qa, sa), (qb, sb) = runs["other"], runs["installed"]
    print(f"installed / other rate: {runs['installed_rate'] / runs['other_rate']:.2f}")
    print(f"rows with another stage: {(sa != sb).sum()} of {sa.size}; cells with any: "
          f"{np.unique(np.nonzero(sa != sb)[1]).size}")
    for k, name in enumerate(HISTORY_QUANTITIES):
        d = np.abs(qa[k] - qb[k])
        worst = np.nanmax(d)
        print(f"  max |d {name}| = {worst:.3e} ({np.unique(np.nonzero(d > 1e-9)[1]).size} cells above 1e-9)")


if __name__ == "__main__":
    main()
