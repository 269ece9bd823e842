"""``knitsim run``'s pre-run domain check (``knitsim.cli.run.check_patch_domain``) of a large random-phi0 patch.

The patch is ``scenes/random_phi0.toml`` at ``--size`` (default 300 x 300: every cell its own phi0, so every
cell a distinct group), under the paper's 3-cycle program 0.1-0.6 (increment 0.01, 310 increments), as
``knitsim run`` would check it: the groups validated, the box judged, the rest states solved in one launch
(Warp's CPU backend runs a launch on one thread).  Each run prints the wall time and, apart, the rest-state
launch's (``CellModel.state``).  The first run is the warm-up (the kernel loaded).  Not a test.

    python benchmarks/bench_domain_check.py                   # 300 x 300, cpu, 4 runs
    python benchmarks/bench_domain_check.py --size 1000 --runs 2 --increments 10
"""
from __future__ import annotations

import argparse
import time
import tomllib
from pathlib import Path

from knitsim import warp_runtime
from knitsim.cell.batch import CellModel
from knitsim.cli.run import check_patch_domain
from knitsim.scene.patch_scene import load_patch_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=300, help="courses = wales")
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--increments", type=int, default=0,
                    help="a monotonic program of this many increments of 0.01 instead of the 3 cycles (a 10^6-cell "
                         "patch's 310 increments of records may not fit the machine's memory)")
    a = ap.parse_args()
    with open(Path(__file__).resolve().parents[1] / "scenes" / "random_phi0.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["patch"] = {"wales": a.size, "courses": a.size}
    doc["load"] = ({"type": "cycles", "cycles": 3, "lower_strain": 0.1, "upper_strain": 0.6, "max_increment": 0.01}
                   if not a.increments else
                   {"type": "monotonic", "target_strain": 0.01 * a.increments, "max_increment": 0.01})
    scene = load_patch_scene(doc)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    spent: list = []
    state = CellModel.state

    def timed(self):
        t = time.perf_counter()
        st = state(self)
        spent.append(time.perf_counter() - t)
        return st

    CellModel.state = timed
    for k in range(a.runs):
        spent.clear()
        t = time.perf_counter()
        check_patch_domain(scene.model, scene.program.strain, "warp", device, True)
        total = time.perf_counter() - t
        print(f"{a.size} x {a.size}, run {k}: {total:.2f} s; rest-state launch {sum(spent):.2f} s, "
              f"the rest {total - sum(spent):.2f} s", flush=True)


if __name__ == "__main__":
    main()
