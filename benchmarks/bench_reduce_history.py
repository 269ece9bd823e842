"""The host side of a sweep's chunk: ``reduce_history`` (knitsim.sweep.runner) per cell, before and after.

A sweep's driver summarises every cell of a solved batch on the host (issue 15, "host side off the critical
path"): at 5.7 ms a cell a 10^5-sample GPU sweep spent ~570 s there against ~30 s of solving.  This script
runs a batch of varied random cells through a program once on the CPU (Warp), caches the history under
``.devscratch/`` (a pickle: the same cells are not run again), then times ``reduce_history`` on it twice in
the same run, each in a fresh process on the same history:

- ``before``: the package at ``--base`` (a git commit; extracted with ``git archive`` into a temporary folder),
- ``after``: the working tree's package;

and checks that both give the same arrays (NaN where NaN).  ``--profile N`` prints the cProfile of the working
tree's ``reduce_history`` (the N largest cumulative entries).

The cells (:func:`varied_cells`): bench_cell_batch's random E-glass / basalt-like cells (m in [0, 0.4], both
unloading rules, cap 10 N), with every tenth cell changed to reach the other ends a sweep meets: Dahl friction,
the head-gap jamming criterion (heads and wale spacing past the jamming limit), a cap of 0.05-0.3 N (stopped at
the cap), a 30 % thicker yarn under a cap of 1e12 N (cells that fail on the jammed branch), yarn compaction, a
large m, and, one cell in 40, a 20 % shorter loop (without a rest state: status no_rest_state).  ``--program
reload`` uses cycles of growing amplitude (0 -> 0.3 -> 0.1 -> 0.45 -> 0.1 -> 0.6), whose reloads past the
earlier maximum need the monotonic pull (``reference``) of ``reload_below_first_loading``.

    python benchmarks/bench_reduce_history.py                      # 400 cells, paper program, before/after
    python benchmarks/bench_reduce_history.py --cells 2000 --base a3224d1
    python benchmarks/bench_reduce_history.py --profile 30 --only after

Not a test.  On a shared machine the before/after ratio is the figure to read (both in the same run).
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCRATCH = ROOT / ".devscratch"


def varied_cells(n: int, seed: int = 0) -> list:
    """``n`` random cells (module docstring), validated."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_cell_batch import make_cells

    from knitsim.cell.effects import EffectSet

    rng = np.random.default_rng(seed + 1)
    out = []
    for i, p in enumerate(make_cells(n, seed)):
        k = i % 10
        if k == 1:
            p = p.replace(friction="dahl", dahl_sigma=float(rng.uniform(20.0, 80.0)))
        elif k == 3:
            p = p.replace(jamming_criterion="head_gap")
        elif k == 5:
            p = p.replace(force_cap_N=float(rng.uniform(0.05, 0.3)))
        elif k == 7:
            p = p.replace(d=1.3 * p.d, force_cap_N=1e12)        # jams early: most fail up the jammed branch
        elif k == 6 and i % 40 == 6:
            p = p.replace(L=0.8 * p.L, force_cap_N=1e12)        # no rest state (status no_rest_state)
        elif k == 8:
            p = p.replace(effects=EffectSet(on=("yarn_compaction",), compaction_k=float(rng.uniform(0.5, 5.0)),
                                            compaction_min=0.7))
        elif k == 9:
            p = p.replace(m=float(rng.uniform(0.5, 0.8)), phi0=0.0)
        out.append(p)
    return out


def program(name: str):
    from knitsim.cell.load_program import cycles, piecewise_linear

    if name == "paper":
        return cycles(0.10, 0.60, 3, 0.01)          # the paper's program, increment 0.01: 310 rows
    if name == "reload":
        return piecewise_linear([0.0, 0.3, 0.1, 0.45, 0.1, 0.6], 0.01)
    raise SystemExit(f"--program {name!r}: paper or reload")


def history(n: int, prog_name: str, seed: int = 0):
    """(history, reference) of ``n`` varied cells through the program, cached under .devscratch/."""
    SCRATCH.mkdir(exist_ok=True)
    path = SCRATCH / f"reduce_history_{prog_name}_{n}_{seed}.pkl"
    if path.is_file():
        return pickle.loads(path.read_bytes())
    from knitsim.cell.engine import simulate
    from knitsim.io.results import first_loading

    cells, prog = varied_cells(n, seed), program(prog_name)
    t0 = time.perf_counter()
    h = simulate(cells, prog, engine="warp", device="cpu")
    ref = first_loading(cells, prog, engine="warp", device="cpu")
    print(f"# ran {n} cells x {len(prog)} increments on the CPU in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    path.write_bytes(pickle.dumps((h, ref)))
    return h, ref


def describe(h) -> dict:
    from knitsim.cell.history import STATUS_NAMES
    final = np.asarray(h.status[-1])
    return {"cells": h.n_cells, "increments": len(h.strain), "events": len(h.events),
            "final_status": {STATUS_NAMES[int(s)]: int(np.sum(final == s)) for s in np.unique(final)},
            "dahl": sum(p.friction == "dahl" for p in h.params),
            "slack_events": sum(e.get("kind") == "slack" for e in h.events),
            "jam_events": sum(e.get("kind") == "jam" for e in h.events)}


def measure(pkl: str, out: str, repeats: int, profile: int) -> None:
    """In a fresh process (the package on sys.path): time reduce_history on the pickled history, save its
    arrays to ``out`` (.npz) and print its timing as JSON."""
    import knitsim
    from knitsim.sweep.runner import reduce_history

    h, ref = pickle.loads(Path(pkl).read_bytes())
    n_cycles = int(np.max(h.cycle))
    best = np.inf
    for _ in range(repeats):
        # a fresh history each time: nothing cached on it from the run before
        h, ref = pickle.loads(Path(pkl).read_bytes())
        t0 = time.perf_counter()
        red = reduce_history(h, n_cycles, curves=True, reference=ref)
        best = min(best, time.perf_counter() - t0)
    np.savez(out, **red)
    if profile:
        import cProfile
        import pstats
        h, ref = pickle.loads(Path(pkl).read_bytes())
        pr = cProfile.Profile()
        pr.enable()
        reduce_history(h, n_cycles, curves=True, reference=ref)
        pr.disable()
        pstats.Stats(pr, stream=sys.stderr).sort_stats("cumulative").print_stats(profile)
        pstats.Stats(pr, stream=sys.stderr).sort_stats("tottime").print_stats(profile)
    print(json.dumps({"package": os.path.dirname(knitsim.__file__), "s": best, "ms_per_cell": 1e3 * best / h.n_cells}))


def same(a: dict, b: dict) -> list[str]:
    """Keys whose arrays differ (NaN equal to NaN, dtypes and shapes compared)."""
    bad = sorted(set(a) ^ set(b))
    for k in sorted(set(a) & set(b)):
        x, y = a[k], b[k]
        if x.dtype != y.dtype or x.shape != y.shape or not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
            bad.append(k)
    return bad


def machine() -> str:
    cpu = ""
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    load = os.getloadavg() if hasattr(os, "getloadavg") else ()
    return (f"{platform.node()}: {cpu or platform.processor()}, {os.cpu_count()} cores, load average "
            f"{', '.join(f'{x:.2f}' for x in load)}; Python {platform.python_version()}, NumPy {np.__version__}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", type=int, default=400)
    ap.add_argument("--program", default="paper")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--base", default="origin/main", help="git commit of 'before' (default: origin/main)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--profile", type=int, default=0)
    ap.add_argument("--only", choices=("before", "after"), default=None)
    ap.add_argument("--measure", nargs=2, metavar=("PKL", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.measure:
        measure(a.measure[0], a.measure[1], a.repeats, a.profile)
        return
    sys.path.insert(0, str(ROOT))
    h, ref = history(a.cells, a.program, a.seed)
    pkl = SCRATCH / f"reduce_history_{a.program}_{a.cells}_{a.seed}.pkl"
    print("# machine:", machine())
    print("# history:", json.dumps(describe(h)), "reference:", ref is not None)
    base = subprocess.run(["git", "-C", str(ROOT), "rev-parse", a.base], capture_output=True, text=True,
                          check=True).stdout.strip()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = {}
        if a.only in (None, "before"):
            src = Path(tmp) / "base"
            src.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", base, "knitsim"], capture_output=True,
                                     check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
            runs["before"] = str(src)
        if a.only in (None, "after"):
            runs["after"] = str(ROOT)
        for name, path in runs.items():
            out = Path(tmp) / f"{name}.npz"
            env = dict(os.environ, PYTHONPATH=path)
            r = subprocess.run([sys.executable, __file__, "--measure", str(pkl), str(out), "--repeats",
                                str(a.repeats), "--profile", str(a.profile if name == "after" else 0)],
                               env=env, capture_output=True, text=True, cwd=tmp)
            if r.returncode:
                raise SystemExit(f"{name}: failed\n{r.stderr}")
            if a.profile and name == "after":
                print(r.stderr)
            results[name] = json.loads(r.stdout.strip().splitlines()[-1])
            results[name]["arrays"] = dict(np.load(out))
            print(f"{name:6s} ({'base ' + base[:10] if name == 'before' else 'working tree'}): "
                  f"{results[name]['ms_per_cell']:.3f} ms a cell, {results[name]['s']:.2f} s for {h.n_cells} cells "
                  f"(best of {a.repeats}; {results[name]['package']})")
    if len(results) == 2:
        bad = same(results["before"]["arrays"], results["after"]["arrays"])
        print(f"speed-up {results['before']['s'] / results['after']['s']:.1f}x; arrays "
              + ("identical" if not bad else f"DIFFER: {bad}"))
        if bad:
            raise SystemExit(1)


if __name__ == "__main__":
    main()
