"""Convergence counts: the bundled sweeps and N random cells of the documented domain.

Counts the final status of every cell (ok, force_cap, no_convergence,
event_not_located), cells with a NaN in their state, and, for the random
cells, where each failure happened (the stage, jammed or not, and the
increment's direction), in one table.  The random cells are drawn uniformly
from :data:`knitsim.cell.domain.DOMAIN` (d and B log-uniform; W0 / d_jam,
C0 / d, L / (2 C0 + W0 - 4 d), m uniform; phi0 uniform in the cone; both
unloading rules, both reload rules, both jamming criteria, an in-plane width
above d on a quarter of them; force cap 20 B / d^2) and run through the
paper's program (3 cycles 0.10-0.60, Dusserre 2015 section 2.3, increment
``--increment``) in chunks of ``--chunk`` cells (only the state is kept, so
10^6 cells fit a GPU).  Not a test.

    python benchmarks/bench_convergence.py --cells 10000               # CPU
    python benchmarks/bench_convergence.py --device cuda --cells 1000000
    python benchmarks/bench_convergence.py --device cuda --no-sweeps --start 500000 --cells 500000 --json b.json
    python benchmarks/bench_convergence.py --no-sweeps --cells 2000 --failures fails.json
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SWEEPS = ("scenes/sweeps/e_glass_lhs.toml", "scenes/sweeps/e_glass_friction_sweep.toml")


def random_domain_cells(n: int, seed: int = 0, domain=None) -> list:
    """N cells drawn from the documented domain (see the module docstring)."""
    from knitsim.cell.domain import DOMAIN
    from knitsim.cell.material import CellParams

    dom = DOMAIN if domain is None else domain
    rng = np.random.default_rng(seed)
    u = rng.random((n, 12))
    out = []
    for r in u:
        d = math.exp(math.log(dom.d[0]) + r[0] * math.log(dom.d[1] / dom.d[0]))
        B = math.exp(math.log(dom.B[0]) + r[1] * math.log(dom.B[1] / dom.B[0]))
        wide = r[8] < 0.25
        w_ratio = dom.W0_over_djam[0] + r[2] * (dom.W0_over_djam[1] - dom.W0_over_djam[0])
        # an in-plane width between d and the largest that keeps W0 / d_jam in the domain
        djam = d * (1.0 + r[9] * 0.5) if wide else d
        W0 = w_ratio * djam
        C0 = d * (dom.C0_over_d[0] + r[3] * (dom.C0_over_d[1] - dom.C0_over_d[0]))
        closing = 2.0 * C0 + W0 - 4.0 * d
        L = closing * (dom.L_over_closing[0] + r[4] * (dom.L_over_closing[1] - dom.L_over_closing[0]))
        m = dom.m[0] + r[5] * (dom.m[1] - dom.m[0])
        phi0 = (2.0 * r[6] - 1.0) * math.atan(m)
        out.append(CellParams(B=B, d=d, L=L, W0=W0, C0=C0, m=m, phi0=phi0,
                              unloading_rule=("dusserre", "hong_constant_t")[int(r[7] * 2)],
                              reload_rule=("mirror_unloading", "freeze_rn")[int(r[10] * 2)],
                              jamming_criterion=("w_4d", "head_gap")[int(r[11] * 2)],
                              in_plane_width=djam if wide else None,
                              force_cap_N=20.0 * B / d ** 2))
    return out


def run_states(cells: list, program, device: str) -> dict:
    """Final status, stage, jammed flag, direction of each cell, and whether its state is finite."""
    import warp as wp

    from knitsim.cell.batch import CellModel, CellSolver

    model = CellModel.from_params(cells, device)
    s0, s1 = model.state(), model.state()
    solver = CellSolver(model)
    ctrl = model.control()
    first_bad = np.full(len(cells), -1, np.int64)
    st = s0.status.numpy()
    first_bad[st != 0] = 0
    for i in range(len(program)):
        ctrl.set(program.strain[i], program.direction[i])
        solver.step(s0, s1, ctrl, i)
        s0, s1 = s1, s0
        if i % 10 == 9 or i == len(program) - 1:
            st = s0.status.numpy()
            new = (st != 0) & (st != 2) & (first_bad < 0)
            first_bad[new] = i + 1
    wp.synchronize_device(model.device)
    x = s0.x.numpy()
    return {"status": s0.status.numpy(), "stage": s0.stage.numpy(), "jammed": s0.jammed.numpy(),
            "finite": np.all(np.isfinite(x), axis=1), "first_bad_increment": first_bad}


def bench_random(n: int, seed: int, device: str, increment: float, chunk: int, start: int = 0) -> dict:
    from knitsim.cell.history import STATUS_NAMES
    from knitsim.cell.load_program import cycles
    from knitsim.cell.stages import Stage, stage_label

    prog = cycles(0.10, 0.60, 3, max_increment=increment)
    counts = collections.Counter()
    where = collections.Counter()
    failures = []
    nan = 0
    t0 = time.perf_counter()
    # chunk k holds cells k*chunk .. (k+1)*chunk - 1 of the seed, whatever range a call runs: calls over
    # --start/--cells ranges that are multiples of --chunk add up to one run over their union
    if start % chunk:
        raise SystemExit(f"--start {start} is not a multiple of --chunk {chunk}")
    n_end = start + n
    for start in range(start, n_end, chunk):
        cells = random_domain_cells(min(chunk, n_end - start), seed=seed * 1_000_003 + start // chunk)
        r = run_states(cells, prog, device)
        nan += int((~r["finite"]).sum())
        for k, s in enumerate(r["status"]):
            name = STATUS_NAMES.get(int(s), str(s))
            counts[name] += 1
            if name not in ("ok", "force_cap"):
                lab = stage_label(Stage(int(r["stage"][k])), bool(r["jammed"][k]))
                inc = int(r["first_bad_increment"][k])
                dirn = "rest" if inc == 0 else ("load" if prog.direction[max(inc - 1, 0)] > 0 else "unload")
                where[f"{name} at {lab} ({dirn})"] += 1
                failures.append({"index": start + k, "status": name, "stage": lab, "direction": dirn,
                                 "increment_by": inc, **cells[k].as_dict()})
    dt = time.perf_counter() - t0
    return {"cells": n, "increments": len(prog), "seconds": dt, "counts": dict(counts), "nan": nan,
            "where": dict(where), "failures": failures,
            "cell_increments_per_s": n * len(prog) / dt}


def bench_sweep(path: str) -> dict:
    from knitsim.cell.history import STATUS_NAMES
    from knitsim.sweep.runner import plan_sweep, run_sweep

    with tempfile.TemporaryDirectory() as tmp:
        plan = plan_sweep(ROOT / path)
        t0 = time.perf_counter()
        ds = run_sweep(plan, Path(tmp) / "out", workers=0, progress=None, plots=False).dataset
        dt = time.perf_counter() - t0
        status = np.asarray(ds["final_status"].values).reshape(-1)
    names = {**STATUS_NAMES, -1: "not_run"}
    counts = collections.Counter(names.get(int(s), str(int(s))) for s in status)
    return {"sweep": path, "samples": int(status.size), "counts": dict(counts), "seconds": dt}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=10_000, help="random cells of the domain (0: none)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--increment", type=float, default=0.01, help="largest strain increment of the program")
    ap.add_argument("--chunk", type=int, default=20_000, help="cells per batched run")
    ap.add_argument("--start", type=int, default=0,
                    help="first random cell (a multiple of --chunk): split a large count over several calls "
                         "(e.g. --start 0 --cells 500000, then --start 500000 --cells 500000; add the counts)")
    ap.add_argument("--no-sweeps", action="store_true", help="skip the bundled sweeps")
    ap.add_argument("--failures", default=None, help="write the failed cells' parameters to this JSON file")
    ap.add_argument("--json", default=None, help="write the counts to this JSON file")
    a = ap.parse_args(argv)

    from knitsim import warp_runtime
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    rows = []
    if not a.no_sweeps:
        for path in SWEEPS:
            r = bench_sweep(path)
            rows.append((r["sweep"], r["samples"], r["counts"], 0, r["seconds"]))
    rnd = None
    if a.cells > 0:
        rnd = bench_random(a.cells, a.seed, device, a.increment, a.chunk, a.start)
        rows.append((f"random domain cells {a.start}..{a.start + a.cells - 1}, paper's program "
                     f"(incr {a.increment:g}, seed {a.seed})",
                     rnd["cells"], rnd["counts"], rnd["nan"], rnd["seconds"]))
    cols = ("ok", "force_cap", "no_rest_state", "no_convergence", "event_not_located")
    print(f"device {device}")
    print(f"{'run':<64} {'cells':>9} " + " ".join(f"{c:>17}" for c in cols) + f" {'NaN':>5} {'s':>8}")
    for name, n, counts, nan, sec in rows:
        other = {k: v for k, v in counts.items() if k not in cols}
        print(f"{name:<64} {n:>9} " + " ".join(f"{counts.get(c, 0):>17}" for c in cols)
              + f" {nan:>5} {sec:>8.1f}" + (f"  other {other}" if other else ""))
    if rnd and rnd["where"]:
        print("failures of the random cells by where they happened:")
        for k, v in sorted(rnd["where"].items(), key=lambda kv: -kv[1]):
            print(f"  {v:>7}  {k}")
    out = {"device": device, "rows": [dict(zip(("run", "cells", "counts", "nan", "seconds"), r)) for r in rows]}
    if a.failures and rnd:
        Path(a.failures).write_text(json.dumps(rnd["failures"], indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))
    failed = sum(c.get(k, 0) for _, _, c, _, _ in rows for k in ("no_convergence", "event_not_located"))
    return {"failed": failed, **out}


if __name__ == "__main__":
    res = main()
    sys.exit(0)
