"""Export time and file size of simulated knit patches as USD, on the real path (not a test).

Cases (geometry from the cells' elastica states through the Warp centreline
kernel, :mod:`knitsim.usd.from_results`):

- ``simulated``: a 10-course x 6-wale E-glass patch with random phi0 (every
  cell its own solve) run through one load-unload cycle with
  :func:`knitsim.patch.runner.run_patch`, then exported (.usda and .usdc) and
  exported again from its saved results folder (``knitsim usd``);
- ``specimen``: the paper's specimen size, 110 courses x 23 wales = 2,530
  cells, over 300 frames.  Frames are synthesised from a cell history: one
  course of 23 random-phi0 cells is simulated through the 3-cycle 0.10-0.60
  program (Dusserre 2015 section 2.3), and each of the 2,530 cells takes the
  states of one of them with B and P scaled by the same factor c in [0.8, 1.2]
  (the shape depends on B/P only, eqs 8-9, so the yarn is that cell's, but the
  kernel solves 2,530 distinct states per frame, as a fully heterogeneous run
  would make it);
- ``1e5``: a 250 x 400 = 10^5-cell patch synthesised the same way, a few frames.

Columns: kernel seconds (centreline of every cell and frame), write seconds
(USD authoring, incl. lattice and colours), file size, read-back seconds,
quick-look seconds.

Run:  MPLBACKEND=Agg python benchmarks/bench_usd_export.py [--quick] [--device cuda]
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np

from knitsim import warp_runtime
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams
from knitsim.io.patch_results import patch_summary, write_patch_results
from knitsim.patch.model import PatchModel
from knitsim.patch.runner import run_patch
from knitsim.usd import read_patch_usd, render_quicklook
from knitsim.usd.from_results import PatchRecord, export_record, export_results, record_from_history

# Table 1, section 2.2 (dusserre2015.toml)
E_GLASS = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.20, force_cap_N=10.0)


def random_phi0(courses, wales, seed=2015):
    pm = PatchModel.uniform(E_GLASS, courses, wales)
    fields = dict(pm.fields)
    fields["phi0"] = np.random.default_rng(seed).uniform(-1, 1, (courses, wales)) * np.arctan(E_GLASS.m)
    return PatchModel(courses, wales, fields, pm.rules)


def synthesise(rec0: PatchRecord, courses, wales, n_frames, seed=0) -> PatchRecord:
    """A courses x wales record whose cells take the states of rec0's groups, B and P scaled by c."""
    rng = np.random.default_rng(seed)
    G0 = rec0.x.shape[1]
    src = rng.integers(0, G0, courses * wales)
    c = rng.uniform(0.8, 1.2, courses * wales)
    x = rec0.x[:n_frames][:, src].copy()
    x[..., 4] *= c
    goc = np.arange(courses * wales).reshape(courses, wales)
    # rec0 has one cell per group (a 1-course patch, no dedup): cell fields by group = by cell
    cf = {k: v[:n_frames].reshape(n_frames, -1)[:, src].reshape(n_frames, courses, wales)
          for k, v in rec0.cell_fields.items()}
    params = {k: v.reshape(-1)[src].reshape(courses, wales) for k, v in rec0.params.items()}
    params["B"] = params["B"] * c.reshape(courses, wales)
    return PatchRecord(goc, x, rec0.W[:n_frames, src], rec0.C[:n_frames, src], rec0.s_AB[:n_frames, src], cf, params,
                       {k: v[:n_frames] for k, v in rec0.frame_scalars.items()}, "# synthesised", "synthesised")


def case(label, rec, path, device, stride=1, quicklook=True, n_points=9):
    t0 = time.perf_counter()
    res = export_record(rec, path, stride=stride, n_points=n_points, device=device)
    t_total = time.perf_counter() - t0
    t0 = time.perf_counter()
    back = read_patch_usd(path)
    t_read = time.perf_counter() - t0
    t_ql = float("nan")
    if quicklook:
        t0 = time.perf_counter()
        render_quicklook(path, os.path.splitext(path)[0] + ".png", dpi=80)
        t_ql = time.perf_counter() - t0
    assert back.points.shape[0] == len(res.time_codes)
    courses, wales = rec.shape
    row = {"case": label, "cells": courses * wales, "size": f"{courses}x{wales}", "frames": len(res.time_codes),
           "pts_per_quarter": n_points, "vertices_per_frame": courses * res.vertices_per_course,
           "file_MiB": res.file_bytes / 2**20, "kernel_s": res.geometry_seconds,
           "export_s": t_total, "read_s": t_read, "quicklook_s": t_ql,
           "fallback_cells_max": max(res.fallback_cells)}
    os.remove(path)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames, for a smoke run")
    ap.add_argument("--device", default="cpu", help="Warp device of the simulation and the centreline kernel")
    ap.add_argument("--json", default=None, help="also write the table as JSON here")
    args = ap.parse_args()
    device = warp_runtime.resolve_device(args.device)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        # --- a simulated patch, exported directly and from its results folder
        m = random_phi0(10, 6)
        prog = cycles(0.10, 0.40, 1, 0.02)
        t0 = time.perf_counter()
        h = run_patch(m, prog, engine="warp", device=device)
        print(f"simulated 10x6 patch, {h.n_increments} increments: {time.perf_counter() - t0:.1f} s", flush=True)
        rec = record_from_history(h, m.fields, "# bench")
        rows.append(case("simulated .usda", rec, os.path.join(tmp, "s.usda"), device))
        rows.append(case("simulated .usdc", rec, os.path.join(tmp, "s.usdc"), device))
        out = os.path.join(tmp, "res")
        write_patch_results(out, h, patch_summary(h, h.info["ref_length_mm"]), "# bench", fields=m.fields, plot=False)
        t0 = time.perf_counter()
        export_results(out, os.path.join(tmp, "r.usdc"), device=device)
        rows.append({"case": "knitsim usd RESULTS_DIR (.usdc)", "cells": 60, "size": "10x6",
                     "frames": h.n_increments, "export_s": time.perf_counter() - t0,
                     "file_MiB": os.path.getsize(os.path.join(tmp, "r.usdc")) / 2**20})

        # --- a cell history of 23 random-phi0 cells through the specimen's 3-cycle program
        nf = 30 if args.quick else 300
        prog = cycles(0.10, 0.60, 3, 0.01)
        prog = LoadProgram(prog.strain[:nf], prog.cycle[:nf], prog.direction[:nf], prog.waypoints)
        m1 = random_phi0(1, 23)
        t0 = time.perf_counter()
        h1 = run_patch(m1, prog, engine="warp", device=device, dedup=False)
        print(f"cell history, 23 cells x {h1.n_increments} increments: {time.perf_counter() - t0:.1f} s", flush=True)
        rec0 = record_from_history(h1, m1.fields)
        spec = synthesise(rec0, 110, 23, nf)
        rows.append(case("specimen .usdc", spec, os.path.join(tmp, "spec.usdc"), device))
        rows.append(case("specimen .usdc, 6 pts/quarter", spec, os.path.join(tmp, "spec6.usdc"), device,
                         quicklook=False, n_points=6))
        rows.append(case("specimen .usdc, stride 10", spec, os.path.join(tmp, "spec10.usdc"), device, stride=10,
                         quicklook=False))
        rows.append(case("specimen .usda, stride 10", spec, os.path.join(tmp, "spec10.usda"), device, stride=10,
                         quicklook=False))
        big_frames = 3 if args.quick else 10
        big = synthesise(rec0, 250, 400, nf)
        idx = np.unique(np.linspace(0, nf - 1, big_frames).round().astype(int))
        big = PatchRecord(big.group_of_cell, big.x[idx], big.W[idx], big.C[idx], big.s_AB[idx],
                          {k: v[idx] for k, v in big.cell_fields.items()}, big.params,
                          {k: v[idx] for k, v in big.frame_scalars.items()}, big.scene_text, big.source)
        rows.append(case("1e5 cells .usdc", big, os.path.join(tmp, "big.usdc"), device))
    keys = ("case", "size", "frames", "pts_per_quarter", "vertices_per_frame", "file_MiB", "kernel_s", "export_s",
            "read_s", "quicklook_s", "fallback_cells_max")
    print(" | ".join(keys))
    print(" | ".join("---" for _ in keys))
    for r in rows:
        print(" | ".join(f"{r[k]:.3g}" if isinstance(r.get(k), float) else str(r.get(k, "")) for k in keys))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"device": device, "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
