"""Where the paper specimen's time goes: per kernel, per kind of cell-step, per column trial.

The paper's specimen (23 wales x 110 courses, random phi0, 3 cycles 0.1-0.6, no merging) through
``run_patch`` once, with the Warp launches and the coupling's trials observed from outside (wrappers:
the code run is the library's):

- each kernel's launches, wall time and threads;
- the first pass's time split between cell-steps from the committed state ("cold") and from the last
  trial's end ("warm"), by least squares over the trials;
- the cell-steps the first pass leaves to the full step, by kind (reload from slack, jammed unloading,
  an event inside the increment, and of those the ones whose target lies beyond the last trial's last
  located event: what a resume from that event would save);
- the column trials per increment, and how far each increment's first trial misses the column tolerance.

Usage (benchmarks/README.md's "Where the specimen's core goes now" was measured so)::

    python benchmarks/profile_specimen.py [--increments K]
"""
from __future__ import annotations

import argparse
import collections
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp
import warp._src.context as wp_context

sys.path.insert(0, str(Path(__file__).parent))
from bench_table import patch_model, prefix  # noqa: E402

from knitsim.cell.load_program import cycles  # noqa: E402
from knitsim.cell.stages import Stage  # noqa: E402
from knitsim.patch import coupling  # noqa: E402
from knitsim.patch.runner import run_patch  # noqa: E402


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--increments", type=int, default=0, help="the first K increments only (0: all 620)")
    a = ap.parse_args(argv)
    pm, _ = patch_model("random-phi0", 23, 110)
    prog = cycles(0.10, 0.60, 3, 0.005)
    if a.increments:
        prog = prefix(prog, a.increments)
    run_patch(pm, prefix(prog, 2), device="cpu", dedup=False)        # compile

    kernels = collections.defaultdict(lambda: [0, 0.0, 0])
    now = {"regular": 0.0, "full": 0.0}
    launch = wp_context.launch

    def timed_launch(kernel, dim=0, *args, **kw):
        t = time.perf_counter()
        out = launch(kernel, dim, *args, **kw)
        dt = time.perf_counter() - t
        key = getattr(kernel, "key", str(kernel))
        e = kernels[key]
        e[0] += 1
        e[1] += dt
        e[2] += int(dim if isinstance(dim, int) else dim[0])
        if key.startswith("regular_step"):
            now["regular"] += dt
        elif key.startswith("step_kernel"):
            now["full"] += dt
        return out

    solver = {}
    init, trial, begin = coupling.PatchSolver.__init__, coupling.WarpBackend.trial, coupling.WarpBackend.begin_increment
    rows, first_miss = [], []
    kinds = collections.Counter()

    def patch_init(self, *args, **kw):
        init(self, *args, **kw)
        solver["ps"] = self

    def patch_begin(self):
        begin(self)
        self._profile_event_C = np.full(self.n, np.nan)
        solver["first"] = True

    def patch_trial(self, strain, direction, increment, mask=None):
        m = np.ones(self.n, bool) if mask is None else np.asarray(mask, bool)
        # (the coupling's trials on the device keep the warm flags in control.warm and return no rows: read them)
        warm = (self.control.warm.numpy() != 0) if self.device_trials else self._warm.copy()
        C_start = self.s0.C.numpy()
        stage0, jam0 = self.s0.stage.numpy(), self.s0.jammed.numpy() != 0
        event_C = getattr(self, "_profile_event_C", np.full(self.n, np.nan))
        now["regular"] = now["full"] = 0.0
        out = trial(self, strain, direction, increment, mask)
        t = out if out else self.trial_state()
        rows.append((int((~warm & m).sum()), int((warm & m).sum()), now["regular"], now["full"]))
        pending = np.zeros(self.n, bool)
        for cells, count in self.solver._pending:
            pending[cells.numpy()[:int(count.numpy()[0])]] = True
        pending &= m
        slack = stage0 == int(Stage.SLACK)
        resumable = np.isfinite(event_C) & ((t["C"] - event_C) * (event_C - C_start) > 0)
        if solver.get("first"):
            kinds["first trials"] += int(pending.sum())
        else:
            kinds["later: reload from slack"] += int((pending & slack).sum())
            kinds["later: jammed unloading"] += int((pending & jam0 & (direction < 0)).sum())
            other = pending & ~slack & ~(jam0 & (direction < 0))
            kinds["later: event inside the increment"] += int(other.sum())
            kinds["  of which beyond the last trial's last event"] += int((other & resumable).sum())
        ev = self.solver.event_arrays()
        inside = (ev["kind"] != self._ev_reversal) & (ev["kind"] != self._ev_reload)
        last = np.full(self.n, np.nan)
        last[ev["cell"][inside]] = ev["C"][inside]
        ends_ok = (t["status"] == 0) & (t["stage"] != int(Stage.SLACK))
        self._profile_event_C = np.where(m & np.isfinite(last), np.where(ends_ok, last, np.nan), event_C)
        if solver.get("first"):
            ps = solver["ps"]
            Ft = ps.p * t["F"]
            fmax = np.full(ps.n_cls, -np.inf)
            fmin = np.full(ps.n_cls, np.inf)
            np.maximum.at(fmax, ps.col, Ft)
            np.minimum.at(fmin, ps.col, Ft)
            carries = fmax > 1e-6
            first_miss.append(((fmax - fmin) / (ps.force_tol + ps.force_rtol * np.abs(fmax)))[carries])
            solver["first"] = False
        return out

    coupling.PatchSolver.__init__ = patch_init
    coupling.WarpBackend.trial = patch_trial
    coupling.WarpBackend.begin_increment = patch_begin
    wp_context.launch = wp.launch = timed_launch
    t0, c0 = time.perf_counter(), time.process_time()
    h = run_patch(pm, prog, device="cpu", dedup=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    wp_context.launch = wp.launch = launch

    in_kernels = sum(v[1] for v in kernels.values())
    print(f"specimen 23 x 110 random phi0, {len(prog)} increments: wall {wall:.2f} s, CPU {cpu:.2f} s, "
          f"{sum(v[0] for v in kernels.values())} launches, {in_kernels:.2f} s in them")
    for key, (n, t, threads) in sorted(kernels.items(), key=lambda kv: -kv[1][1])[:10]:
        print(f"  {key[:40]:40s} {n:7d} launches {t:8.3f} s {threads:10d} threads {1e6 * t / max(threads, 1):7.3f} us each")
    r = np.array(rows, float)
    for j, name in ((2, "first pass"), (3, "full step")):
        coef = np.linalg.lstsq(r[:, :2], r[:, j], rcond=None)[0]
        print(f"{name}: {r[:, j].sum():.2f} s; per cell-step {1e6 * coef[0]:.2f} us cold ({int(r[:, 0].sum())}), "
              f"{1e6 * coef[1]:.2f} us warm ({int(r[:, 1].sum())})")
    print("cell-steps left to the full step:")
    for k, v in kinds.items():
        print(f"  {k}: {v}")
    trials, counts = np.unique(h.column_iterations, return_counts=True)
    print("column trials per increment:", ", ".join(f"{int(t)}: {int(c)}" for t, c in zip(trials, counts)))
    miss = np.concatenate(first_miss) if first_miss else np.zeros(0)
    edges = (0, 1, 10, 100, np.inf)
    print("first trial's spread / tolerance, column-increments carrying force:",
          ", ".join(f"[{lo:g}, {hi:g}): {int(np.sum((miss >= lo) & (miss < hi)))}" for lo, hi in zip(edges, edges[1:])))


if __name__ == "__main__":
    main()
