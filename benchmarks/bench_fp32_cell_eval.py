"""What float32 would buy the cell's evaluation, and what it would cost in precision (issue 15, item 2:
"measure fp32 where the NumPy twin's tolerances allow it, and say which").

The cell step's work is the evaluation of one quarter stitch with the gradients of its 20 quantities
(``kernels/quarter_loop.py`` over ``kernels/elastica.py``: the elastica integrals of eqs 8-9 by Gauss-Legendre
rules, every value a dual number carrying its 5 derivatives); a Newton iteration is one such evaluation and a
5 x 5 solve.  This script builds two twins of those two modules from their source text, one as shipped
(float64) and one with every float64 made float32 (values, gradients, node tables, constants), each with the
same small kernel that evaluates the cell at a list of states; and compares them:

- **speed**: evaluations per second of each twin on the device (after a warm-up launch), and, on CUDA, the
  registers and local memory per thread of each kernel (``wp.get_cuda_kernel_properties``);
- **precision**: the float32 values and gradients against the float64 ones at the same states, as relative
  errors per quantity, and the float32 residual of the Newton's five conditions at float64 solutions: the
  floor a float32 Newton could converge to, against the cell step's tolerance (``NEWTON_TOL`` = 1e-11, scaled
  residuals) and the tests' 1e-9 in F and C.

The states are real: the committed states of the benchmark's random batch (``bench_table.random_arrays``: the
E-glass / basalt-like cells of ``bench_cell_batch.py``, both unloading rules) through the first ``--increments``
of the 3-cycle program, every increment, run by the library on the CPU; repeated to ``--cells`` for timing.
Nothing here is shipped: the twins live in a temporary folder.

Usage::

    python benchmarks/bench_fp32_cell_eval.py --device cuda --cells 1000000
    python benchmarks/bench_fp32_cell_eval.py --device cpu --cells 20000 --json out.json
"""
from __future__ import annotations

import argparse
import importlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_table import prefix, random_arrays  # noqa: E402

import knitsim.kernels as kernels  # noqa: E402
from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import CellModel, CellSolver  # noqa: E402
from knitsim.cell.load_program import cycles  # noqa: E402
from knitsim.cell.quantities import Q_F, Q_P, Q_R, QUANTITY_NAMES  # noqa: E402

#: appended to each twin of quarter_loop.py: the cell at each state z = (ln(alpha - gamma), beta, R/P, phi, ln P),
#: seeded as the cell step's evaluate_zr seeds it (kernels/cell_step.py), values and gradients written out
_EVAL_KERNEL = '''

from .elastica import d_exp, d_seed


@wp.kernel
def bench_evaluate_kernel(z: wp.array(dtype=vec5d), B: wp.float64, d: wp.float64, q_out: wp.array(dtype=vecQd),
                          dq_out: wp.array(dtype=matQ5d), g_out: wp.array(dtype=wp.float64)):
    i = wp.tid()
    zi = z[i]
    a = d_exp(d_seed(zi[0], 0))
    P = d_exp(d_seed(zi[4], 4))
    cell = quarter_loop_rho(a, d_seed(zi[1], 1), d_seed(zi[2], 2), d_seed(zi[3], 3), P, B, d)
    q_out[i] = cell.q
    dq_out[i] = cell.dq
    g_out[i] = cell.g
'''


def build_twins(folder: Path) -> dict:
    """Two packages in ``folder``, ``twin64`` (the shipped source) and ``twin32`` (every float64 made float32),
    each with elastica.py, quarter_loop.py and :data:`_EVAL_KERNEL`; returns their quarter_loop modules."""
    src = Path(kernels.__file__).resolve().parent
    out = {}
    for name, to32 in (("twin64", False), ("twin32", True)):
        pkg = folder / name
        pkg.mkdir(parents=True, exist_ok=True)
        (pkg / "__init__.py").write_text("")
        for f in ("elastica.py", "quarter_loop.py"):
            text = (src / f).read_text()
            if f == "quarter_loop.py":
                text += _EVAL_KERNEL
            if to32:
                text = text.replace("float64", "float32")
            (pkg / f).write_text(text)
    sys.path.insert(0, str(folder))
    for name in ("twin64", "twin32"):
        out[name] = importlib.import_module(f"{name}.quarter_loop")
    return out


def real_states(n_cells: int, n_increments: int, seed: int = 0) -> tuple[np.ndarray, float, float]:
    """Committed states z of the benchmark batch (one B and d: the first cell's, since the twins' kernel takes
    them as scalars; the angles and R/P of every cell), every increment of the program's first ``n_increments``,
    by the library on the CPU.  Rows: states that carry force (F > 0, not slack)."""
    arr = random_arrays(n_cells, seed)
    # one yarn for all (the kernel's B and d are scalars): the batch's even cells' E-glass-like yarn
    arr["B"] = np.full(n_cells, 0.31)
    arr["d"] = np.full(n_cells, 0.58)
    model = CellModel.from_arrays(**arr, device="cpu")
    solver = CellSolver(model, event_capacity=16 * n_cells + 64)
    state = model.state()
    prog = prefix(cycles(0.10, 0.60, 3, max_increment=0.01), n_increments)
    zs = []
    for k in range(len(prog)):
        solver.run_program(state, prog, k_start=k, k_stop=k + 1)
        x, q = state.x.numpy(), state.q.numpy()
        ok = (q[:, Q_F] > 0.0) & (x[:, 0] > x[:, 2]) & (x[:, 4] > 0.0) & (state.status.numpy() == 0)
        z = np.stack([np.log(x[:, 0] - x[:, 2]), x[:, 1], q[:, Q_R] / q[:, Q_P], x[:, 3], np.log(x[:, 4])], axis=1)
        zs.append(z[ok])
    return np.concatenate(zs), 0.31, 0.58


def evaluate(mod, z: np.ndarray, B: float, d: float, device: str, dtype, reps: int) -> tuple[dict, float, dict]:
    """Values, gradients and intrinsic residual of the cell at ``z`` by twin ``mod`` in ``dtype``; the best
    wall time of ``reps`` launches after a warm-up; the kernel's CUDA resources where known."""
    n = len(z)
    zd = wp.array(z.astype(dtype), dtype=mod.vec5d, device=device)
    q = wp.zeros(n, dtype=mod.vecQd, device=device)
    dq = wp.zeros(n, dtype=mod.matQ5d, device=device)
    g = wp.zeros(n, dtype=mod.wp.float32 if dtype == np.float32 else mod.wp.float64, device=device)
    args = [zd, dtype(B), dtype(d), q, dq, g]
    wp.launch(mod.bench_evaluate_kernel, dim=n, inputs=args, device=device)      # compile + warm-up
    wp.synchronize_device(device)
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        wp.launch(mod.bench_evaluate_kernel, dim=n, inputs=args, device=device)
        wp.synchronize_device(device)
        best = min(best, time.perf_counter() - t0)
    res = {}
    if wp.get_device(device).is_cuda:
        try:
            props = wp.get_cuda_kernel_properties(mod.bench_evaluate_kernel, device)
            res = {"registers": int(props["register_count"]), "local_bytes": int(props["local_memory_size"])}
        except Exception as exc:  # noqa: BLE001 - an older Warp: say so, keep the timings
            res = {"unavailable": str(exc)}
    return {"q": q.numpy().astype(float), "dq": dq.numpy().astype(float), "g": g.numpy().astype(float)}, best, res


def precision(e64: dict, e32: dict) -> dict:
    """Relative errors of the float32 twin against the float64 one: per quantity (values, against
    max(|q|, 1e-3 x the quantity's largest |q|), so that a quantity through zero is judged at its scale),
    the gradients (per quantity, row norm against the largest row norm), and the intrinsic residual g [mm]."""
    q64, q32 = e64["q"], e32["q"]
    scale = np.maximum(np.abs(q64), 1e-3 * np.abs(q64).max(axis=0))
    rel = np.abs(q32 - q64) / scale
    dn = np.linalg.norm(e64["dq"], axis=2)
    drel = np.linalg.norm(e32["dq"] - e64["dq"], axis=2) / np.maximum(dn, 1e-3 * dn.max(axis=0))
    fin = np.isfinite(rel).all(axis=1) & np.isfinite(drel).all(axis=1)
    out = {"states": int(len(q64)), "nonfinite_float32": int((~fin).sum()), "per_quantity": {}}
    for k, name in enumerate(QUANTITY_NAMES):
        r, dr = rel[fin, k], drel[fin, k]
        out["per_quantity"][name] = {"value_median": float(np.median(r)), "value_max": float(r.max()),
                                     "gradient_median": float(np.median(dr)), "gradient_max": float(dr.max())}
    gerr = np.abs(e32["g"] - e64["g"])[fin]
    out["intrinsic_residual_g_mm"] = {"float64_max": float(np.abs(e64["g"][fin]).max()),
                                      "float32_median": float(np.median(gerr)), "float32_max": float(gerr.max())}
    allr = rel[fin]
    out["value_median_all"], out["value_max_all"] = float(np.median(allr)), float(allr.max())
    alld = drel[fin]
    out["gradient_median_all"], out["gradient_max_all"] = float(np.median(alld)), float(alld.max())
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--cells", type=int, default=1_000_000, help="states evaluated per launch (timing)")
    ap.add_argument("--batch", type=int, default=400, help="cells of the batch whose states are used")
    ap.add_argument("--increments", type=int, default=62)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    t0 = time.perf_counter()
    z, B, d = real_states(a.batch, a.increments)
    print(f"{len(z)} committed states with force ({a.batch} cells x {a.increments} increments, CPU, "
          f"{time.perf_counter() - t0:.1f} s)", flush=True)
    with tempfile.TemporaryDirectory(prefix="knitsim_fp32_twin_") as tmp:
        twins = build_twins(Path(tmp))
        reps = int(np.ceil(a.cells / len(z)))
        zt = np.tile(z, (reps, 1))[:a.cells]
        e64, t64, r64 = evaluate(twins["twin64"], zt, B, d, device, np.float64, a.reps)
        e32, t32, r32 = evaluate(twins["twin32"], zt, B, d, device, np.float32, a.reps)
    name = wp.get_device(device).name if wp.get_device(device).is_cuda else "cpu"
    prec = precision({k: v[:len(z)] for k, v in e64.items()}, {k: v[:len(z)] for k, v in e32.items()})
    report = {"device": name, "cells": a.cells, "distinct_states": int(len(z)),
              "float64": {"wall_s": t64, "evals_per_s": a.cells / t64, **r64},
              "float32": {"wall_s": t32, "evals_per_s": a.cells / t32, **r32},
              "speedup_float32": t64 / t32, "precision": prec}
    print(f"device {name}: {a.cells} evaluations (values + 5-gradients of 20 quantities)")
    for k in ("float64", "float32"):
        r = report[k]
        extra = (f", {r['registers']} registers, {r['local_bytes']} B local / thread" if "registers" in r else "")
        print(f"  {k}: {r['wall_s'] * 1e3:8.2f} ms  {r['evals_per_s']:.3e} evaluations / s{extra}")
    print(f"  float32 / float64 speed: x{report['speedup_float32']:.2f}")
    print(f"precision of float32 against float64 at {prec['states']} states ({prec['nonfinite_float32']} not finite "
          f"in float32): values median {prec['value_median_all']:.1e}, max {prec['value_max_all']:.1e}; gradients "
          f"median {prec['gradient_median_all']:.1e}, max {prec['gradient_max_all']:.1e}")
    for nm in ("F", "C", "W", "P", "R", "T"):
        if nm in prec["per_quantity"]:
            p = prec["per_quantity"][nm]
            print(f"  {nm:>3}: value median {p['value_median']:.1e} max {p['value_max']:.1e}; "
                  f"gradient median {p['gradient_median']:.1e} max {p['gradient_max']:.1e}")
    gi = prec["intrinsic_residual_g_mm"]
    print(f"  intrinsic residual g (eq 6) at the float64 solutions: float64 {gi['float64_max']:.1e} mm, float32 "
          f"median {gi['float32_median']:.1e} max {gi['float32_max']:.1e} mm (the step's tolerance: 1e-11 scaled)")
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    return report


if __name__ == "__main__":
    main()
