"""Patch throughput: the paper's specimen (23 wales x 110 courses = 2,530 E-glass cells) through the
3-cycle program 0.10-0.60 (Dusserre 2015, section 2.3), wall time and cell-increments per second.

Cases: ``uniform`` (identical cells, solved once per column class: the exact deduplication),
``uniform-nodedup`` (every cell its own solve: the cost of a fully heterogeneous patch of the
same behaviour) and ``random-phi0`` (phi0 uniform in [-phimax, phimax]: every cell differs).
Warp runs one CPU thread per launch on the CPU device.  Prints a table; ``--json PATH`` writes it.
Not a test.

    python benchmarks/bench_patch.py                                  # CPU, all cases
    python benchmarks/bench_patch.py --cases uniform-nodedup --increments 60
    python benchmarks/bench_patch.py --device cuda --size 1000x1000 --cases random-phi0
    python benchmarks/bench_patch.py --device cuda --size 1000x1000 --cases random-phi0 --increments 8 \
        --coupling device numpy                   # the coupling on the device against its NumPy twin
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams
from knitsim.patch.coupling import PatchSolver
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch

# Table 1, section 2.2, section 3.4 (dusserre2015.toml)
E_GLASS = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.20, force_cap_N=10.0)


def model(case: str, wales: int, courses: int) -> tuple[PatchModel, bool]:
    pm = PatchModel.uniform(E_GLASS, courses, wales)
    if case == "random-phi0":
        rng = np.random.default_rng(2015)
        fields = dict(pm.fields)
        fields["phi0"] = rng.uniform(-1, 1, (courses, wales)) * np.arctan(E_GLASS.m)
        pm = PatchModel(courses, wales, fields, pm.rules)
    return pm, case != "uniform-nodedup"


def print_device_time(pm: PatchModel, prog: LoadProgram, device: str, dedup: bool, top: int = 15) -> None:
    """Run ``prog`` on ``pm`` again under Warp's activity timing (CUDA events around each launch and
    copy: the run is slower than untimed) and print the device time per kernel and copy kind, their
    sum, and the run's wall time: the part of the wall the device is busy, and with what."""
    wp.synchronize()
    t0 = time.perf_counter()
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
    try:
        run_patch(pm, prog, device=device, dedup=dedup)
    finally:
        results = wp.timing_end()
    wall = time.perf_counter() - t0
    per: dict[str, list[float]] = {}
    for r in results:
        name = r.name.split("(")[0]
        per.setdefault(name, []).append(r.elapsed)
    busy = sum(sum(v) for v in per.values()) / 1e3
    print(f"device activity under timing: {len(results)} launches/copies, {busy:.2f} s busy of {wall:.2f} s wall "
          f"({busy / wall:.0%})")
    for name, v in sorted(per.items(), key=lambda kv: -sum(kv[1]))[:top]:
        print(f"  {sum(v) / 1e3:9.3f} s  {len(v):7d} x  {name}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--size", default="23x110", help="WALESxCOURSES (default: the paper's 23x110)")
    ap.add_argument("--cases", nargs="+", default=["uniform", "uniform-nodedup", "random-phi0"])
    ap.add_argument("--increments", type=int, default=0, help="time only the first K increments (0: all 620)")
    ap.add_argument("--max-increment", type=float, default=0.005)
    ap.add_argument("--coupling", nargs="+", choices=("device", "numpy"), default=["device"],
                    help="where the coupling's branch model and column solve run (PatchSolver.device_branch_points): "
                         "on the cells' device (the default) or in NumPy (their twin); both: a same-run A/B")
    ap.add_argument("--progress", action="store_true", help="print each increment's wall time as it ends")
    ap.add_argument("--kernel-timing", action="store_true",
                    help="CUDA: after the timed run, run the same increments again under Warp's activity timing "
                         "(CUDA events around every launch and copy) and print where the device time went, "
                         "against that run's wall time")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    wales, courses = (int(v) for v in a.size.lower().split("x"))
    prog = cycles(0.10, 0.60, 3, a.max_increment)
    if a.increments:
        prog = LoadProgram(prog.strain[:a.increments], prog.cycle[:a.increments], prog.direction[:a.increments],
                           prog.waypoints)
    head2 = LoadProgram(prog.strain[:2], prog.cycle[:2], prog.direction[:2], prog.waypoints)
    rows = []
    for case, coupling in ((c, k) for c in a.cases for k in a.coupling):
        PatchSolver.device_branch_points = coupling == "device"
        # compile (not timed): the same case on a 16 x 16 patch, so that every kernel key and module the run
        # launches is built here (a 2 x 1 uniform patch left the large patch's keys to be compiled in the timed
        # run: minutes on CUDA)
        t0 = time.perf_counter()
        small, small_dedup = model(case, 16, 16)
        run_patch(small, head2, device=device, dedup=small_dedup)
        wp.synchronize()
        warmup = time.perf_counter() - t0
        pm, dedup = model(case, wales, courses)
        stamps = []
        wp.synchronize()
        t0 = time.perf_counter()
        def tick(done, total):
            stamps.append(time.perf_counter())
            if a.progress:
                print(f"  {case}: increment {done}/{total} at {stamps[-1] - t0:.2f} s", flush=True)

        h = run_patch(pm, prog, device=device, dedup=dedup, progress=tick)
        wp.synchronize()
        wall = time.perf_counter() - t0
        # the increments after the first (the first builds the patch's arrays, and compiles what the warm-up did not)
        later = stamps[-1] - stamps[0] if len(stamps) > 1 else math.nan
        cells = pm.cell_count
        rows.append({"case": case, "coupling": coupling, "device": device, "wales": wales, "courses": courses,
                     "cells": cells,
                     "increments": len(prog), "distinct_solves": h.info["n_groups"], "warmup_s": warmup, "wall_s": wall,
                     "cell_increments_per_s": cells * len(prog) / wall,
                     "first_increment_s": stamps[0] - t0 if stamps else math.nan,
                     "later_cell_increments_per_s": cells * (len(stamps) - 1) / later if later > 0 else math.nan,
                     "solve_increments_per_s": h.info["n_groups"] * len(prog) / wall,
                     "mean_trials_per_increment": float(h.column_iterations.max(axis=1).mean()),
                     "non_converged_column_increments": int(np.sum(h.column_status == 1)),
                     "columns_stopped_at_end": int(np.sum(h.column_status[-1] == 2)),
                     "peak_force_per_wale_N": float(h.force_per_wale_N.max())})
    head = ("case", "coupling", "cells", "increments", "distinct_solves", "warmup_s", "wall_s", "cell_increments_per_s",
            "first_increment_s", "later_cell_increments_per_s",
            "mean_trials_per_increment", "non_converged_column_increments", "columns_stopped_at_end")
    print(" | ".join(head), flush=True)
    for r in rows:
        print(" | ".join(f"{r[k]:.4g}" if isinstance(r[k], float) else str(r[k]) for k in head), flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=2)
    if a.kernel_timing:
        # after the table (a run cut short by a time limit keeps it): the last case again, under timing
        print_device_time(pm, prog, device, dedup)


if __name__ == "__main__":
    main()
