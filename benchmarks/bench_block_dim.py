"""The GPU batch at several CUDA block sizes, in one run: 10^6 random cells (``bench_table.random_arrays``)
through the first 62 increments, two passes sorted by stage (``run_batch``'s GPU default, ``graph_row``)
and one launch per range (``batch_row``).  Every ``wp.launch`` of the run gets ``block_dim`` (Warp's
default is 256).  Not a test; CUDA only.

    python benchmarks/bench_block_dim.py --block-dims 256 128 64 --reps 2
"""
from __future__ import annotations

import argparse
import os
import sys

import warp as wp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_table import batch_row, graph_row, prefix, random_arrays  # noqa: E402

from knitsim import warp_runtime  # noqa: E402
from knitsim.cell.batch import CellModel  # noqa: E402
from knitsim.cell.load_program import cycles  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=1_000_000)
    ap.add_argument("--increments", type=int, default=62)
    ap.add_argument("--block-dims", type=int, nargs="+", default=[256, 128])
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--no-range", action="store_true", help="only the two-pass rows")
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device("cuda")
    prog = prefix(cycles(0.10, 0.60, 3, max_increment=0.01), a.increments)
    model = CellModel.from_arrays(**random_arrays(a.cells), device=device)
    launch = wp.launch

    def with_block_dim(bd):
        def launch_bd(kernel, dim, *args, **kw):
            kw.setdefault("block_dim", bd)
            return launch(kernel, dim, *args, **kw)
        return launch_bd

    print(f"{a.cells} random cells x {a.increments} increments on {wp.get_device(device).name}")
    try:
        for rep in range(a.reps):
            for bd in a.block_dims:
                wp.launch = with_block_dim(bd)
                rows = [("two passes, sorted", lambda: graph_row(model, prog, device, 10, sort=True, compact=True))]
                if not a.no_range:
                    rows.append(("one launch per range", lambda: batch_row(model, prog, device, True, 10)))
                for name, fn in rows:
                    r = fn()
                    print(f"rep {rep}  block_dim {bd:>4}  {name:<22} {r['wall_s']:8.2f} s  "
                          f"{r['cell_increments'] / r['wall_s']:.3e} cell-increments / s", flush=True)
    finally:
        wp.launch = launch


if __name__ == "__main__":
    main()
