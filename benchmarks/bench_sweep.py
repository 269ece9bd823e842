"""Sweep throughput: 10^5 single-cell cycles on 1 and 2 local Dask workers vs the SciPy reference.

The cell is the paper's E-glass plain knit (scenes/paper/e_glass_cyclic.toml: Dusserre
2015, Table 1, section 2.2) through 3 cycles 0.10 -> 0.60 (section 2.3) with a coarse
increment (``--increment``, default 0.02), over a Latin hypercube of the friction ratio m
in [0.10, 0.30] and phi0 in [-0.09, 0.09] rad.  10^5 cycles = 33,334 cells of 3 cycles;
``--samples`` shrinks it (the rates are per cell and per cycle, so they extrapolate).

Reports, as JSON on stdout:

- Warp batched sweep (``knitsim.sweep.run_sweep``, chunks of ``--chunk-size`` cells, one
  kernel run per chunk) on a Dask LocalCluster of 1 and of 2 single-threaded worker
  processes: wall time, cells/s, cycles/s, and the speed-up 2 vs 1 worker;
- the per-cell float64 SciPy reference (engine "reference") on ``--ref-samples`` of the
  same cells, in this process: cells/s, and the ratio Warp(1 worker) / reference.

Wall times include starting the cluster and each worker's Warp start (kernels come from
the on-disk cache: run once beforehand to compile).  Not a test::

    python benchmarks/bench_sweep.py --samples 2000
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _scene(increment: float) -> dict:
    import tomllib

    with open(ROOT / "scenes" / "paper" / "e_glass_cyclic.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["load"]["max_increment"] = increment
    doc["rules"]["force_cap_N"] = 10.0
    return doc


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=math.ceil(1e5 / 3), help="cells (3 cycles each)")
    ap.add_argument("--increment", type=float, default=0.02, help="largest strain increment")
    ap.add_argument("--chunk-size", type=int, default=512)
    ap.add_argument("--ref-samples", type=int, default=2, help="cells run by the SciPy reference")
    ap.add_argument("--workers", default="1,2", help="Dask worker counts to time")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")

    from knitsim.cell.engine import simulate
    from knitsim.sweep.runner import plan_sweep, run_sweep

    doc = _scene(args.increment)
    sweep = {"method": "lhs", "samples": args.samples, "seed": 2015, "chunk_size": args.chunk_size,
             "parameters": {"friction.m": {"min": 0.10, "max": 0.30},
                            "friction.phi0": {"min": -0.09, "max": 0.09}}}
    t = time.perf_counter()
    plan = plan_sweep(doc, sweep, engine="warp", device="cpu")
    t_plan = time.perf_counter() - t
    n_inc = len(plan.programs[0])
    cycles = int(plan.programs[0].cycle.max())
    print(f"bench_sweep: {args.samples} cells x {cycles} cycles, {n_inc} increments (max {args.increment}), "
          f"{len(plan.chunks)} chunks; plan + validation {t_plan:.1f} s", file=sys.stderr, flush=True)
    # compile / load the kernels once (not timed)
    simulate(plan.params[0], plan.programs[0], engine="warp", device="cpu")

    result = {"cells": args.samples, "cycles_per_cell": cycles, "increments": n_inc,
              "max_increment": args.increment, "chunk_size": args.chunk_size, "cpu_count": os.cpu_count(),
              "plan_validation_s": t_plan, "warp": {}}
    tmp = Path(tempfile.mkdtemp(prefix="knitsim-bench-sweep-"))
    datasets = {}
    try:
        for w in [int(x) for x in args.workers.split(",")]:
            out = tmp / f"w{w}"
            t = time.perf_counter()
            run = run_sweep(plan, out, workers=w, progress=sys.stderr, plots=False)
            wall = time.perf_counter() - t
            datasets[w] = run.dataset
            result["warp"][str(w)] = {"wall_s": wall, "cells_per_s": args.samples / wall,
                                      "cycles_per_s": args.samples * cycles / wall,
                                      "cells_not_finished": int((run.dataset["expected_end"].values != 1).sum())}
            print(f"bench_sweep: {w} worker(s): {wall:.1f} s, {args.samples / wall:.1f} cells/s",
                  file=sys.stderr, flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ws = sorted(result["warp"], key=int)
    if len(ws) >= 2:
        result["speedup"] = result["warp"][ws[0]]["wall_s"] / result["warp"][ws[-1]]["wall_s"]
        import numpy as np
        a, b = datasets[int(ws[0])], datasets[int(ws[-1])]
        result["identical_across_workers"] = bool(np.array_equal(a["peak_force_per_wale_N"].values,
                                                                 b["peak_force_per_wale_N"].values, equal_nan=True))

    cells = [p for ps in plan.params[: args.ref_samples] for p in ps]
    t = time.perf_counter()
    simulate(cells, plan.programs[0], engine="reference")
    wall = time.perf_counter() - t
    result["reference"] = {"cells": len(cells), "wall_s": wall, "cells_per_s": len(cells) / wall}
    result["warp_1_worker_over_reference"] = result["warp"][ws[0]]["cells_per_s"] / result["reference"]["cells_per_s"]
    json.dump(result, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
