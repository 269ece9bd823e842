"""Failure counts and throughput of the load cycle on a random batch (seeded).

Reproduces the robustness numbers of the cycle (issue: unloading from a jammed
state, SF- folds): N random cells (E-glass / basalt-like from Table 1 and
section 2.2 of Dusserre 2015, scattered 2 %, m in [0, 0.4], phi0 in
[-phimax, phimax], both unloading rules, force cap 5 N) run through the paper's
program (3 cycles 0.10-0.60, increment 0.01).  Prints the final status counts
and the snap/fold/unjam event counts of the Warp batch (and of the NumPy
reference on a sample), and the throughput in cell-increments per second.
Not a test.

    python benchmarks/bench_cycle_robustness.py                   # 1000 cells, CPU
    python benchmarks/bench_cycle_robustness.py --ref 20          # + reference on 20 cells
    python benchmarks/bench_cycle_robustness.py --device cuda --cells 1000
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import time

import numpy as np

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import run_cells_reference
from knitsim.cell.history import STATUS_NAMES
from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.data import dusserre2015


def random_cells(n: int, seed: int = 1, scatter: float = 0.02) -> list[CellParams]:
    """The cells of tests/cell/test_batch.py::_random_cells (same draw order)."""
    paper = dusserre2015()
    k = paper["knit"]
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        name = "e_glass" if i % 2 == 0 else "basalt"
        y = paper["yarn"][name]
        B, d, L, W0, C0 = (y["bending_stiffness_N_mm2"], y["yarn_diameter_mm"], k["stitch_length_mm"][name],
                           k["wale_width_mm"], k["course_length_mm"])
        s = lambda: 1.0 + rng.uniform(-scatter, scatter)  # noqa: E731
        m = rng.uniform(0.0, 0.4)
        pm = math.atan(m)
        out.append(CellParams(B=B * s(), d=d * s(), L=L * s(), W0=W0 * s(), C0=C0 * s(), m=m,
                              phi0=rng.uniform(-pm, pm),
                              unloading_rule=("dusserre", "hong_constant_t")[i % 2], force_cap_N=5.0))
    return out


def summarise(h) -> dict:
    final = collections.Counter(STATUS_NAMES[int(s)] for s in h.status[-1])
    kinds = collections.Counter(e["kind"] for e in h.events)
    return {"final_status": dict(final), "events": dict(kinds),
            "nan": int(sum(int(np.isnan(v).sum()) for v in h.values.values()))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--ref", type=int, default=0, help="also run the NumPy reference on the first N cells")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    prog = cycles(0.10, 0.60, 3, max_increment=0.01)
    cells = random_cells(a.cells, a.seed)
    out = {"cells": a.cells, "increments": len(prog), "device": a.device}
    run_batch(cells[:2], cycles(0.10, 0.20, 1, max_increment=0.1), device=a.device)  # compile first
    t0 = time.perf_counter()
    h = run_batch(cells, prog, device=a.device)
    dt = time.perf_counter() - t0
    out["warp"] = summarise(h) | {"seconds": dt, "cell_increments_per_s": a.cells * len(prog) / dt}
    if a.ref:
        t0 = time.perf_counter()
        r = run_cells_reference(cells[:a.ref], prog)
        dt = time.perf_counter() - t0
        out["reference"] = summarise(r) | {"cells": a.ref, "seconds": dt,
                                           "cell_increments_per_s": a.ref * len(prog) / dt}
        hw = run_batch(cells[:a.ref], prog, device=a.device)
        out["reference"]["warp_same_cells"] = summarise(hw)
    print(json.dumps(out, indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)
    return out


if __name__ == "__main__":
    main()
