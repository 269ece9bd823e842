"""The NumPy reference engine against the Warp engine on random cells of the domain, default force cap.

Each cell (``bench_convergence.random_domain_cells``: the documented domain's box, both rules of each kind,
its force cap replaced by the default 50 B / d^2) runs through one program with both engines: ``mono``
(monotonic to strain 0.8, increments 0.01) or ``cycles`` (two cycles 0.1 -> 0.6, increments 0.01).  Prints,
per cell, each engine's final status, the largest relative difference of the force per wale over the rows
both solved (status ok in the Warp history), and the reference's time (cut at ``--timeout`` seconds), then
how many cells end alike.  The reference runs one cell per worker process (``--jobs``).  Not a test: the
README's figures of the reference on jammed branches (2026-11-29: seed 7 ``mono`` 29 of 30 alike, seed 8
``cycles`` 17 of 20) come from it.

    python benchmarks/bench_reference_agreement.py --cells 30 --seed 7 --program mono --jobs 2
    python benchmarks/bench_reference_agreement.py --cells 20 --seed 8 --program cycles --json out.json
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import signal
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def program(kind: str):
    from knitsim.cell.load_program import cycles, monotonic
    return monotonic(0.8, max_increment=0.01) if kind == "mono" else cycles(0.1, 0.6, 2, max_increment=0.01)


def cells(n: int, seed: int) -> list:
    from bench_convergence import random_domain_cells
    return [dataclasses.replace(c, force_cap_N=None) for c in random_domain_cells(n, seed)]


class _Timeout(Exception):
    pass


def _alarm(*_):
    raise _Timeout()


def reference_one(args) -> dict:
    """The reference's run of one cell: final status, force per wale per row, seconds (None: cut)."""
    from knitsim.cell.cycle import run_cell
    from knitsim.cell.history import STATUS_NAMES
    k, cell, kind, timeout = args
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(int(timeout))
    t = time.perf_counter()
    try:
        r = run_cell(cell, program(kind))
        out = {"cell": k, "status": STATUS_NAMES[int(r.status[-1, 0])], "F": r.values["F"][:, 0].tolist()}
    except _Timeout:
        out = {"cell": k, "status": f"over {timeout} s", "F": None}
    finally:
        signal.alarm(0)
    out["seconds"] = time.perf_counter() - t
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", type=int, default=30)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--program", choices=("mono", "cycles"), default="mono")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=int, default=240, help="seconds per cell for the reference")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from knitsim import warp_runtime
    from knitsim.cell.batch import run_batch
    from knitsim.cell.history import STATUS_NAMES

    warp_runtime.init()
    cs = cells(a.cells, a.seed)
    h = run_batch(cs, program(a.program))
    with mp.Pool(a.jobs) as pool:
        ref = pool.map(reference_one, [(k, c, a.program, a.timeout) for k, c in enumerate(cs)], chunksize=1)
    rows, alike = [], 0
    for r in ref:
        k = r["cell"]
        warp = STATUS_NAMES[int(h.status[-1, k])]
        rel = None
        if r["F"] is not None:
            Fr, Fw = np.asarray(r["F"]), h.values["F"][:, k]
            ok = (h.status[:, k] == 0) & np.isfinite(Fr)
            if ok.any():
                rel = float(np.max(np.abs(Fr[ok] - Fw[ok]) / np.maximum(np.abs(Fw[ok]), 1e-3)))
        same = warp == r["status"]
        alike += same
        rows.append({"cell": k, "warp": warp, "reference": r["status"], "max_rel_F": rel,
                     "reference_s": round(r["seconds"], 2), "alike": same})
        print(f"{k:4d}  warp {warp:16s} reference {r['status']:16s} max rel F "
              f"{'-' if rel is None else f'{rel:.1e}':8s} {r['seconds']:7.1f} s{'' if same else '  <- differs'}",
              flush=True)
    print(f"{alike} of {len(rows)} cells end alike (seed {a.seed}, program {a.program})")
    if a.json:
        Path(a.json).write_text(json.dumps({"seed": a.seed, "program": a.program, "alike": alike, "cells": rows},
                                           indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
