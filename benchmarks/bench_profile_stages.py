"""Where the time of a load program goes: the CPU cost of one increment by the cell's state at its start.

Random cells (``bench_table.random_arrays``) through the paper's 3-cycle program (or its first K
increments); each increment is run as disjoint launches of the specialised step kernel, one per
category of cells (cycle, direction, stage, jammed, reversal), timed in CPU seconds of the single
Warp CPU thread.  Prints the categories by their share of the time.  Not a test.

    python benchmarks/bench_profile_stages.py 300        # 300 cells, all 310 increments
    python benchmarks/bench_profile_stages.py 1000 62    # the first 62 increments (the GPU benchmark's)
"""
import os, sys, time, numpy as np, warp as wp
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_table import random_arrays
from knitsim import warp_runtime
from knitsim.cell.batch import CellModel, CellSolver
from knitsim.cell.load_program import cycles
warp_runtime.init()
n = int(sys.argv[1]) if len(sys.argv) > 1 else 300
prog = cycles(0.10, 0.60, 3, max_increment=0.01)
from bench_table import prefix
prog = prefix(prog, int(sys.argv[2]) if len(sys.argv) > 2 else 0)
model = CellModel.from_arrays(**random_arrays(n), device="cpu")
s0, s1 = model.state(), model.state()
solver = CellSolver(model); ctrl = model.control()
(k, _), = solver.groups
names = {0: "SF+", 1: "S+", 2: "SF-", 3: "S-", 4: "slack"}
cost, count = {}, {}
no_count = wp.zeros(0, dtype=wp.int32)  # (step_kernel's count: every listed cell)
no_slope = wp.zeros(0, dtype=wp.float64)  # (step_kernel's slope: not written)
args = lambda cells, i: ([cells, no_count, no_count, no_count, model.arrays(), solver.max_halvings, 1, s0.arrays(),
                          ctrl.strain, ctrl.direction, ctrl.rate, i, s1.arrays(), solver._ev_struct, ctrl.warm,
                          no_slope], [])
prev_dir = 1
for i in range(len(prog)):
    ctrl.set(prog.strain[i], prog.direction[i])
    st, jm, status = s0.stage.numpy(), s0.jammed.numpy(), s0.status.numpy()
    rev = prog.direction[i] != prev_dir
    prev_dir = prog.direction[i]
    phase = f"c{prog.cycle[i]}{'+' if prog.direction[i] > 0 else '-'}"
    cat = np.array([f"{phase} {'stopped' if status[c] else names[st[c]] + ('J' if jm[c] else '')}{' rev' if rev else ''}" for c in range(n)])
    for c in np.unique(cat):
        idx = np.flatnonzero(cat == c).astype(np.int32)
        ins, outs = args(wp.array(idx, dtype=wp.int32), i)
        t0 = time.process_time()
        wp.launch(k.step_kernel, dim=len(idx), inputs=ins, outputs=outs)
        dt = time.process_time() - t0
        cost[c] = cost.get(c, 0.0) + dt
        count[c] = count.get(c, 0) + len(idx)
    s0, s1 = s1, s0
tot = sum(cost.values())
print(f"{n} cells x {len(prog)} incr: {tot:.2f} cpu s, {n*len(prog)/tot:.0f} cell-incr/s")
print(f"{'category':<22} {'cell-incr':>9} {'cpu s':>8} {'share':>6} {'us/cell-incr':>12}")
for c in sorted(cost, key=lambda c: -cost[c]):
    print(f"{c:<22} {count[c]:>9} {cost[c]:>8.2f} {cost[c]/tot:>6.1%} {1e6*cost[c]/count[c]:>12.0f}")
print("status", np.bincount(s0.status.numpy(), minlength=4))
