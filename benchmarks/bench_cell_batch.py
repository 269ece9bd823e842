"""Throughput of the batched Warp load cycle (cell-increments per second).

Runs N cells (E-glass / basalt-like, scattered a few %, m in [0, 0.4], both
unloading rules) through the paper's 3-cycle program 0.10-0.60 (increment
0.01), times the steps (after compilation), and times the per-cell NumPy/SciPy
reference looping over a sample of the same cells, on a prefix of the same
program, for the ratio.  Prints a table; ``--json PATH`` writes the numbers.
Not a test.

    python benchmarks/bench_cell_batch.py                       # CPU, 1e2..1e5
    python benchmarks/bench_cell_batch.py --device cuda --sizes 10000 100000 1000000 10000000
    python benchmarks/bench_cell_batch.py --sizes 2000 --generic      # the generic kernel, for the ratio
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
import warp as wp

from knitsim import warp_runtime
from knitsim.cell.batch import CellModel, CellSolver, memory_per_cell
from knitsim.cell.cycle import run_cell
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams


def make_cells(n: int, seed: int = 0) -> list[CellParams]:
    rng = np.random.default_rng(seed)
    knits = [(0.31, 0.58, 14.1), (0.20, 0.56, 13.1)]  # Table 1 / section 2.2 (dusserre2015.toml)
    out = []
    for i in range(n):
        B, d, L = knits[i % 2]
        s = 1.0 + rng.uniform(-0.02, 0.02, 5)
        m = float(rng.uniform(0.0, 0.4))
        out.append(CellParams(B=B * s[0], d=d * s[1], L=L * s[2], W0=4.4 * s[3], C0=2.7 * s[4], m=m,
                              phi0=float(rng.uniform(-1, 1)) * math.atan(m),
                              unloading_rule=("dusserre", "hong_constant_t")[i % 2], force_cap_N=10.0))
    return out


def prefix(prog: LoadProgram, n: int) -> LoadProgram:
    return LoadProgram(prog.strain[:n], prog.cycle[:n], prog.direction[:n], prog.waypoints)


def bench_batch(n: int, prog: LoadProgram, device: str, specialise: bool = True) -> dict:
    cells = make_cells(n)
    t0 = time.perf_counter()
    model = CellModel.from_params(cells, device)
    s0 = model.state()
    s1 = model.state()
    wp.synchronize_device(device)
    t_init = time.perf_counter() - t0
    solver = CellSolver(model, specialise=specialise)
    for k, _ in solver.groups:
        wp.load_module(k, device=device)  # compiled before the timing
    ctrl = model.control()
    t0, c0 = time.perf_counter(), time.process_time()
    for i in range(len(prog)):
        ctrl.set(prog.strain[i], prog.direction[i])
        solver.step(s0, s1, ctrl, i)
        s0, s1 = s1, s0
    wp.synchronize_device(device)
    dt = time.perf_counter() - t0
    cpu = time.process_time() - c0
    status = np.bincount(s0.status.numpy(), minlength=4).tolist()
    mem = memory_per_cell(model, s0, len(prog))
    return {"cells": n, "increments": len(prog), "init_s": t_init, "step_s": dt, "cpu_s": cpu,
            "cell_increments_per_s": n * len(prog) / dt, "status_counts": status, "bytes_per_cell": mem}


def bench_reference(n_sample: int, prog: LoadProgram) -> float:
    cells = make_cells(n_sample)
    t0 = time.perf_counter()
    for p in cells:
        run_cell(p, prog)
    return n_sample * len(prog) / (time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000, 100000])
    ap.add_argument("--increments", type=int, default=0,
                    help="time only the first K increments of the program (0: all 310)")
    ap.add_argument("--ref-sample", type=int, default=2, help="cells run by the NumPy reference")
    ap.add_argument("--ref-increments", type=int, default=40, help="increments run by the reference")
    ap.add_argument("--generic", action="store_true",
                    help="the generic kernel (every law chosen per cell) instead of one kernel per kernel key")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    prog = cycles(0.10, 0.60, 3, max_increment=0.01)
    if a.increments:
        prog = prefix(prog, a.increments)
    from knitsim.kernels.specialise import INIT_KEY, cell_step_module
    t0 = time.perf_counter()
    wp.load_module(cell_step_module(None if a.generic else INIT_KEY), device=device)
    compile_s = time.perf_counter() - t0
    ref_rate = bench_reference(a.ref_sample, prefix(prog, a.ref_increments)) if a.ref_sample > 0 else float("nan")
    rows = [bench_batch(n, prog, device, not a.generic) for n in a.sizes]
    print(f"device {device}; module load/compile {compile_s:.2f} s; reference {ref_rate:.1f} cell-incr/s "
          f"({a.ref_sample} cells x {min(a.ref_increments, len(prog))} increments)")
    print(f"{'cells':>10} {'incr':>5} {'init s':>8} {'step s':>9} {'cpu s':>9} {'cell-incr/s':>12} {'x ref':>8} {'B/cell':>8}  status ok/nc/cap/nl")
    for r in rows:
        r["ratio_vs_reference"] = r["cell_increments_per_s"] / ref_rate
        print(f"{r['cells']:>10} {r['increments']:>5} {r['init_s']:>8.2f} {r['step_s']:>9.2f} {r['cpu_s']:>9.2f} "
              f"{r['cell_increments_per_s']:>12.0f} {r['ratio_vs_reference']:>8.0f} "
              f"{r['bytes_per_cell']['total']:>8.0f}  {r['status_counts']}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"device": device, "compile_s": compile_s, "reference_cell_increments_per_s": ref_rate,
                       "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
