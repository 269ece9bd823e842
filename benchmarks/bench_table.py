"""The throughput figures of issue 15 in one table (cell-increments per second, seconds).

Rows (each timed after compilation; ratios are taken in the same run):

- ``batch``: random cells (E-glass / basalt-like, m in [0, 0.4], both unloading rules:
  ``bench_cell_batch.make_cells``) through the paper's 3-cycle program 0.10-0.60 (increment 0.01,
  310 increments), or its first ``--increments`` increments; the specialised kernels (one per
  kernel key) beside the generic kernel (``specialise=False``) on the same cells; on CUDA also one
  launch per increment (as a CUDA graph, sorted by stage, in two passes, both: ``graph_row``), above
  10^6 cells only the last;
- ``build``: building the model of 10^6 cells from arrays (``CellModel.from_arrays``) and, for the
  ratio, from a list of ``CellParams`` (10^5 cells, the per-cell path);
- ``specimen``: the paper's specimen (23 wales x 110 courses) with random phi0, 3 cycles
  (increment 0.005), every cell its own solve (no merging of identical cells);
- ``patch``: a WALESxCOURSES random-phi0 patch (default 1000x1000 on CUDA) through the first
  ``--patch-increments`` increments.

CPU rows report the process CPU time beside the wall time, and their rates per CPU second: Warp's
CPU backend runs a launch on one thread, so CPU seconds are one-core seconds even on a shared
machine; CUDA rates are per wall second.  Not a test.

    python benchmarks/bench_table.py                       # CPU: 2000-cell batch, build, specimen
    python benchmarks/bench_table.py --device cuda         # + 10^6 / 10^7 cells x 62 increments, 1000x1000 patch
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_cell_batch import make_cells  # noqa: E402
from bench_patch import model as patch_model  # noqa: E402

from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import SUBSTEP_SLICES, CellModel, CellSolver  # noqa: E402
from knitsim.cell.load_program import LoadProgram, cycles  # noqa: E402
from knitsim.patch.runner import run_patch  # noqa: E402


def random_arrays(n: int, seed: int = 0) -> dict:
    """The cells of ``make_cells`` as arrays (same distribution, drawn vectorised)."""
    rng = np.random.default_rng(seed)
    even = np.arange(n) % 2 == 0
    s = 1.0 + rng.uniform(-0.02, 0.02, (5, n))
    m = rng.uniform(0.0, 0.4, n)
    return dict(B=np.where(even, 0.31, 0.20) * s[0], d=np.where(even, 0.58, 0.56) * s[1],
                L=np.where(even, 14.1, 13.1) * s[2], W0=4.4 * s[3], C0=2.7 * s[4], m=m,
                phi0=rng.uniform(-1, 1, n) * np.arctan(m),
                unloading_rule=np.where(even, "dusserre", "hong_constant_t"), force_cap_N=10.0)


def prefix(prog: LoadProgram, n: int) -> LoadProgram:
    return prog if not n else LoadProgram(prog.strain[:n], prog.cycle[:n], prog.direction[:n], prog.waypoints)


def timed(fn, device):
    wp.synchronize_device(device)
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    wp.synchronize_device(device)
    return out, time.perf_counter() - t0, time.process_time() - c0


def batch_row(model: CellModel, prog: LoadProgram, device: str, specialise: bool, stride: int) -> dict:
    # a few events per cell over the program (64 per cell by default: 18 GB at 10^7 cells)
    solver = CellSolver(model, specialise=specialise, event_capacity=16 * model.cell_count + 64)
    state = model.state()
    solver.run_program(state, prefix(prog, 2), stride=1)  # compile (not timed)
    state = model.state()
    _, wall, cpu = timed(lambda: solver.run_program(state, prog, stride=stride), device)
    status = np.bincount(state.status.numpy(), minlength=4).tolist()
    n = model.cell_count * len(prog)
    return {"cells": model.cell_count, "increments": len(prog), "kernels": "specialised" if specialise else "generic",
            "wall_s": wall, "cpu_s": cpu, "cell_increments": n, "status_ok_nc_cap_nl": status}


def graph_row(model: CellModel, prog: LoadProgram, device: str, stride: int, sort: bool = False,
              compact: bool = False) -> dict:
    """One launch per increment, captured once as a CUDA graph (first call), replayed (timed); or, with
    ``sort``, the cells sorted by stage on the device before each increment (no graph); with
    ``compact``, each increment in two passes (regular increments, then the listed rest, its full step
    in run_batch's slices of sub-steps, ``SUBSTEP_SLICES``)."""
    from knitsim.cell.batch import ProgramHistory

    solver = CellSolver(model, event_capacity=16 * model.cell_count + 64)
    state, fresh = model.state(), model.state()
    hist = ProgramHistory.empty(model, len(prog), stride, model.has_effects)
    kw = dict(stride=stride, history=hist, per_increment=True, sort_by_stage=sort, compact=compact,
              slices=SUBSTEP_SLICES if compact else ())
    solver.run_program(state, prog, **kw)  # capture
    for dst, src in zip(state._arrays() + [state.eff], fresh._arrays() + [fresh.eff]):
        wp.copy(dst, src)
    _, wall, cpu = timed(lambda: solver.run_program(state, prog, **kw), device)
    kind = ", ".join(["specialised"] + (["two passes, sliced full step"] if compact else [])
                     + (["sorted by stage"] if sort else ["graph per increment"]))
    return {"cells": model.cell_count, "increments": len(prog), "kernels": kind,
            "wall_s": wall, "cpu_s": cpu, "cell_increments": model.cell_count * len(prog)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--batch-sizes", type=int, nargs="+", default=None,
                    help="batch sizes (default: 2000 on CPU; 2000, 10^6, 10^7 on CUDA)")
    ap.add_argument("--increments", type=int, default=None,
                    help="increments of the batch program (default: all 310 on CPU, 62 on CUDA; 2000 cells run all 310)")
    ap.add_argument("--no-generic", action="store_true", help="skip the generic-kernel rows")
    ap.add_argument("--no-batch", action="store_true", help="skip the batch rows")
    ap.add_argument("--no-build", action="store_true", help="skip the model-building rows")
    ap.add_argument("--stride", type=int, default=10, help="history rows recorded every STRIDE increments")
    ap.add_argument("--patch-size", default=None, help="WALESxCOURSES of the random patch, or none (default 1000x1000 on CUDA, none on CPU)")
    ap.add_argument("--patch-increments", type=int, default=62)
    ap.add_argument("--no-specimen", action="store_true")
    ap.add_argument("--specimen-increments", type=int, default=0, help="time only the first K specimen increments (0: all 620)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    cuda = wp.get_device(device).is_cuda
    # rates per wall second on CUDA, per CPU second (one core) on the CPU
    clock = "wall_s" if cuda else "cpu_s"
    sizes = [] if a.no_batch else (a.batch_sizes or ([2000, 10**6, 10**7] if cuda else [2000]))
    full = cycles(0.10, 0.60, 3, max_increment=0.01)

    class Rows(list):
        # each row is printed as it is measured (a run stopped at a time limit keeps what it had)
        def append(self, r):
            super().append(r)
            print("measured:", json.dumps(r), flush=True)
            if a.json:
                with open(a.json, "w") as f:
                    json.dump({"device": device, "rows": list(self), "complete": False}, f, indent=2)

    rows = Rows()

    # --- build
    if not a.no_build:
        arr = random_arrays(10**6)
        model, wall, cpu = timed(lambda: CellModel.from_arrays(**arr, device=device), device)
        rows.append({"figure": "build 10^6 cells from arrays", "wall_s": wall, "cpu_s": cpu})
        cells = make_cells(10**5)
        _, wall, cpu = timed(lambda: CellModel.from_params(cells, device), device)
        rows.append({"figure": "build 10^5 cells from CellParams", "wall_s": wall, "cpu_s": cpu})
        del cells, model

    # --- batches
    for n in sizes:
        prog = full if n <= 2000 and a.increments is None else prefix(full, a.increments or (62 if cuda else 0))
        model = CellModel.from_arrays(**random_arrays(n), device=device)
        # (above 10^6 cells only the fastest way: each row is minutes there)
        kinds = [] if n > 10**6 else [True] if a.no_generic else [True, False]
        res = {sp: batch_row(model, prog, device, sp, a.stride) for sp in kinds}
        if cuda and n <= 10**6:
            res["graph"] = graph_row(model, prog, device, a.stride)
            res["sorted"] = graph_row(model, prog, device, a.stride, sort=True)
            res["compact"] = graph_row(model, prog, device, a.stride, compact=True)
        if cuda or n <= 10**4:
            res["compact sorted"] = graph_row(model, prog, device, a.stride, sort=True, compact=True)
        for sp, r in res.items():
            r["figure"] = f"batch {n} cells x {len(prog)} incr ({r['kernels']})"
            if False in res and sp is not False:
                r["speedup_vs_generic"] = res[False][clock] / r[clock]
            rows.append(r)

    # --- the paper's specimen, random phi0, no merging
    if not a.no_specimen:
        pm, _ = patch_model("random-phi0", 23, 110)
        prog = prefix(cycles(0.10, 0.60, 3, 0.005), a.specimen_increments)
        run_patch(pm, prefix(prog, 2), device=device, dedup=False)  # compile
        h, wall, cpu = timed(lambda: run_patch(pm, prog, device=device, dedup=False), device)
        rows.append({"figure": f"specimen 23x110 random phi0 x {len(prog)} incr (no merging)", "wall_s": wall,
                     "cpu_s": cpu, "cell_increments": pm.cell_count * len(prog),
                     "mean_trials_per_increment": float(h.column_iterations.max(axis=1).mean()),
                     "non_converged_column_increments": int((h.column_status == 1).sum())})

    # --- a large random patch
    psize = a.patch_size or ("1000x1000" if cuda else None)
    if psize and psize.lower() != "none":
        wales, courses = (int(v) for v in psize.lower().split("x"))
        prog = prefix(cycles(0.10, 0.60, 3, 0.005), a.patch_increments)
        # compile (not timed): a small patch of the same cells compiles the same kernels (the step's two
        # passes from COMPACT_STEP_MIN_CELLS cells on)
        run_patch(patch_model("random-phi0", 16, 16)[0], prefix(prog, 2), device=device, dedup=False)
        pm, _ = patch_model("random-phi0", wales, courses)
        h, wall, cpu = timed(lambda: run_patch(pm, prog, device=device, dedup=False), device)
        rows.append({"figure": f"patch {wales}x{courses} random phi0 x {len(prog)} incr", "wall_s": wall, "cpu_s": cpu,
                     "cell_increments": pm.cell_count * len(prog),
                     "mean_trials_per_increment": float(h.column_iterations.max(axis=1).mean()),
                     "non_converged_column_increments": int((h.column_status == 1).sum())})

    print(f"device {device} ({wp.get_device(device).name}); CPU s = process CPU time (one thread per CPU launch)")
    print(f"{'figure':<58} {'wall s':>9} {'cpu s':>9} {'cell-incr/' + clock[:-2] + ' s':>15} {'x generic':>9} "
          f"{'trials':>7}")
    for r in rows:
        rate = r["cell_increments"] / r[clock] if "cell_increments" in r else math.nan
        r["cell_increments_per_" + clock] = rate
        print(f"{r['figure']:<58} {r['wall_s']:>9.3f} {r['cpu_s']:>9.3f} {rate:>15.4g} "
              f"{r.get('speedup_vs_generic', math.nan):>9.2f} {r.get('mean_trials_per_increment', math.nan):>7.2f}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"device": device, "rows": list(rows), "complete": True}, f, indent=2)


if __name__ == "__main__":
    main()
