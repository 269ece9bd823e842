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
    python benchmarks/bench_convergence.py --no-sweeps --cells 2000 --failures fails.json
    python benchmarks/bench_convergence.py --no-sweeps --cells 1000000 --chunk 5000 --jobs 16 --store conv_chunks

``--dahl-sigma`` runs every random cell with Dahl friction (that rate), ``--effects`` switches kernel
effects on for every random cell, at the strengths of ``--effect-param`` (the EffectSet defaults leave
most effects without strength: normal-load n = 1, rate p = 0, compaction k = 0, bending h = 0,
extension c = 0):

    python benchmarks/bench_convergence.py --no-sweeps --cells 2000 --dahl-sigma 20 \\
        --effects bending_hysteresis --effect-param bend_h=0.3
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


def random_domain_cells(n: int, seed: int = 0, domain=None, friction: dict | None = None) -> list:
    """N cells drawn from the documented domain (see the module docstring); ``friction``: CellParams
    fields given to every cell (``friction``, ``dahl_sigma``, ``effects``), the draws unchanged."""
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
                              force_cap_N=20.0 * B / d ** 2, **(friction or {})))
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


def friction_fields(dahl_sigma: float, effects: tuple, effect_params: dict) -> dict:
    """The CellParams fields of ``--dahl-sigma``, ``--effects`` and ``--effect-param`` (empty: the
    Coulomb cells without effects of the domain)."""
    from knitsim.cell.effects import EffectSet

    out = {}
    if dahl_sigma > 0:
        out.update(friction="dahl", dahl_sigma=dahl_sigma)
    if effects or effect_params:
        out["effects"] = EffectSet(on=tuple(effects), **effect_params)
    return out


def run_chunk(n: int, seed: int, device: str, increment: float, chunk: int, start: int,
              friction: dict | None = None) -> dict:
    """The counts of one chunk of random cells (cells start .. start + chunk of the seed's stream)."""
    from knitsim import warp_runtime
    from knitsim.cell.history import STATUS_NAMES
    from knitsim.cell.load_program import cycles
    from knitsim.cell.stages import Stage, stage_label

    warp_runtime.init()
    prog = cycles(0.10, 0.60, 3, max_increment=increment)
    cells = random_domain_cells(min(chunk, n - start), seed=seed * 1_000_003 + start // chunk, friction=friction)
    t0 = time.process_time()
    r = run_states(cells, prog, device)
    counts, where, failures = collections.Counter(), collections.Counter(), []
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
    return {"start": start, "cells": len(cells), "increments": len(prog), "counts": dict(counts),
            "nan": int((~r["finite"]).sum()), "where": dict(where), "failures": failures,
            "cpu_s": time.process_time() - t0}


def bench_random(n: int, seed: int, device: str, increment: float, chunk: int, jobs: int = 1,
                 store: Path | None = None, friction: dict | None = None, tag: str = "") -> dict:
    """Counts over N random cells, in chunks; with ``jobs`` > 1 the chunks run in worker processes
    (Warp's CPU backend runs a launch on one thread); with ``store`` each finished chunk is kept
    there as JSON and a re-run with the same arguments only runs the chunks still missing."""
    import concurrent.futures
    import multiprocessing

    starts = list(range(0, n, chunk))
    done = {}
    if store is not None:
        store.mkdir(parents=True, exist_ok=True)
        key = lambda st: store / f"seed{seed}_incr{increment:g}_chunk{chunk}_n{n}{tag}_start{st}.json"  # noqa: E731
        for st in starts:
            if key(st).exists():
                done[st] = json.loads(key(st).read_text())
    todo = [st for st in starts if st not in done]
    t0 = time.perf_counter()

    def keep(res):
        done[res["start"]] = res
        if store is not None:
            tmp = key(res["start"]).with_suffix(".tmp")
            tmp.write_text(json.dumps(res))
            tmp.replace(key(res["start"]))
        print(f"  chunk at {res['start']}: {res['cells']} cells, {res['counts']}, {res['cpu_s']:.0f} CPU s "
              f"({len(done)}/{len(starts)} chunks)", file=sys.stderr, flush=True)

    if jobs > 1 and len(todo) > 1:
        ctx = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(jobs, mp_context=ctx) as ex:
            futs = [ex.submit(run_chunk, n, seed, device, increment, chunk, st, friction) for st in todo]
            for f in concurrent.futures.as_completed(futs):
                keep(f.result())
    else:
        for st in todo:
            keep(run_chunk(n, seed, device, increment, chunk, st, friction))
    dt = time.perf_counter() - t0
    parts = [done[st] for st in starts]
    counts, where = collections.Counter(), collections.Counter()
    for p in parts:
        counts.update(p["counts"])
        where.update(p["where"])
    incs = parts[0]["increments"]
    cpu = sum(p["cpu_s"] for p in parts)
    return {"cells": n, "increments": incs, "seconds": dt, "cpu_s": cpu, "counts": dict(counts),
            "nan": sum(p["nan"] for p in parts), "where": dict(where),
            "failures": [f for p in parts for f in p["failures"]],
            "cell_increments_per_cpu_s": n * incs / cpu if cpu > 0 else math.nan}


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
    ap.add_argument("--no-sweeps", action="store_true", help="skip the bundled sweeps")
    ap.add_argument("--failures", default=None, help="write the failed cells' parameters to this JSON file")
    ap.add_argument("--json", default=None, help="write the counts to this JSON file")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes for the random chunks (CPU: one core each)")
    ap.add_argument("--store", default=None,
                    help="keep each finished chunk here; a re-run with the same arguments resumes")
    ap.add_argument("--dahl-sigma", type=float, default=0.0, help="Dahl friction at this rate for every random cell "
                    "(0: Coulomb)")
    ap.add_argument("--effects", default="", help="comma-separated kernel effects switched on for every random cell")
    ap.add_argument("--effect-param", action="append", default=[], metavar="NAME=VALUE",
                    help="an effect strength (EffectSet field), e.g. bend_h=0.3 (repeatable)")
    a = ap.parse_args(argv)
    effects = tuple(e for e in a.effects.split(",") if e)
    params = {k: float(v) for k, v in (kv.split("=", 1) for kv in a.effect_param)}
    friction = friction_fields(a.dahl_sigma, effects, params)
    tag = "".join([f"_dahl{a.dahl_sigma:g}" if a.dahl_sigma > 0 else ""] + [f"_{e}" for e in effects]
                  + [f"_{k}{v:g}" for k, v in sorted(params.items())])

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
        rnd = bench_random(a.cells, a.seed, device, a.increment, a.chunk, jobs=a.jobs,
                           store=Path(a.store) if a.store else None, friction=friction, tag=tag)
        rows.append((f"random domain cells{tag.replace('_', ' ')}, paper's program (incr {a.increment:g}, seed {a.seed})",
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
