"""Where a random-phi0 patch's time goes: CPU time, trial steps and unconverged columns per phase
(cycle, direction, reversal) of the 3-cycle program 0.10-0.60 at 0.005 (the specimen's).  Not a test.

    python benchmarks/bench_profile_patch.py 23x10          # 23 wales x 10 courses, all 620 increments
    python benchmarks/bench_profile_patch.py 23x110 100     # the paper specimen, first 100 increments
"""
import os, sys, time, numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_patch import model as patch_model
from knitsim import warp_runtime
from knitsim.cell.load_program import cycles, LoadProgram
from knitsim.patch.runner import run_patch
from knitsim.patch import coupling
warp_runtime.init()
W, Cn = (int(v) for v in (sys.argv[1] if len(sys.argv) > 1 else "23x10").split("x"))
K = int(sys.argv[2]) if len(sys.argv) > 2 else 0
pm, _ = patch_model("random-phi0", W, Cn)
prog = cycles(0.10, 0.60, 3, 0.005)
if K: prog = LoadProgram(prog.strain[:K], prog.cycle[:K], prog.direction[:K], prog.waypoints)
run_patch(pm, LoadProgram(prog.strain[:2], prog.cycle[:2], prog.direction[:2], prog.waypoints), dedup=False)
rec = []
orig_trial = coupling.WarpBackend.trial
def trial(self, strain, direction, increment, *a, **k):
    t0 = time.process_time()
    out = orig_trial(self, strain, direction, increment, *a, **k)
    rec.append((increment, time.process_time() - t0))  # noqa
    return out
coupling.WarpBackend.trial = trial
orig_step = coupling.PatchSolver.step
inc = []
def step(self, g, d, i=0):
    st0 = self.cells["stage"].copy(); c0 = time.process_time()
    r = orig_step(self, g, d, i)
    inc.append((i, time.process_time() - c0, int(r.iterations.max()), np.bincount(st0, minlength=5), np.bincount(r.cells["stage"], minlength=5), int((r.column_status==1).sum()), int(np.sum(getattr(self, 'jump_columns', 0))), int(np.sum(getattr(self, 'cut_columns', 0)))))
    if i % 10 == 0 or inc[-1][1] > 2:
        print(i, f"c{prog.cycle[i]} d{prog.direction[i]} e={g:.3f} cpu {inc[-1][1]:.3f} s trials {inc[-1][2]} "
              f"cells by stage SF+ S+ SF- S- slack {np.bincount(r.cells['stage'], minlength=5).tolist()} "
              f"cpu so far {sum(x[1] for x in inc):.1f}", flush=True)
    return r
coupling.PatchSolver.step = step
t0, c0 = time.perf_counter(), time.process_time()
h = run_patch(pm, prog, dedup=False)
print(f"{W}x{Cn} x {len(prog)} incr: wall {time.perf_counter()-t0:.2f} s cpu {time.process_time()-c0:.2f} s; trials {sum(x[2] for x in inc)}; "
      f"cpu in trial steps {sum(x[1] for x in rec if x[0] >= 0):.2f} s (the rest: coupling, tangents, recording)")
import collections
agg = collections.defaultdict(lambda: [0, 0.0, 0, 0, 0, 0])
tr = collections.defaultdict(float)
for (i, dt, it, s0, s1, nc, nj, ncut) in inc:
    rev = i > 0 and prog.direction[i] != prog.direction[i-1]
    key = f"c{prog.cycle[i]}{'+' if prog.direction[i] > 0 else '-'}{' rev' if rev else ''}"
    a = agg[key]; a[0] += 1; a[1] += dt; a[2] += it; a[3] += nc; a[4] += nj; a[5] += ncut
print(f"{'phase':<10} {'incr':>5} {'cpu s':>8} {'trials':>7} {'tr/inc':>7} {'ms/trial':>8} {'notconv':>7} {'jump':>5} {'cut':>5}")
for k, a in agg.items():
    print(f"{k:<10} {a[0]:>5} {a[1]:>8.2f} {a[2]:>7} {a[2]/a[0]:>7.2f} {1e3*a[1]/max(a[2],1):>8.2f} {a[3]:>7} {a[4]:>5} {a[5]:>5}")
print("final status", np.bincount(h.groups["status"][-1], minlength=4), "col not conv", int((h.column_status==1).sum()))
