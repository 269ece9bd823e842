"""Registers and local memory per thread of the cell-step kernels on CUDA (``wp.get_cuda_kernel_properties``).

A GPU thread of the step kernel that needs more registers than the hardware gives it (255 on sm_90) keeps
the rest of its working set in local memory: per-thread stack in L1 / L2 / DRAM, read and written through
the whole increment.  This prints, for the kernel keys given (default: the random benchmark batch's, Coulomb
without effects with W = 4 d jamming, and the generic kernel), the register count and the local memory of the
program, first-pass and step kernels, at the block size Warp launches them with (256).  Compiles what it
asks for (minutes on a cold cache).  Not a test; CUDA only.

    python benchmarks/bench_kernel_resources.py                 # the benchmark batch's key and the generic kernel
    python benchmarks/bench_kernel_resources.py --all-keys      # every one of the 8 keys
"""
from __future__ import annotations

import argparse
import itertools

import warp as wp

from knitsim import warp_runtime
from knitsim.kernels.specialise import KernelKey, cell_step_module

KERNELS = ("program_kernel", "regular_kernel", "step_kernel", "regular_step_kernel")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--all-keys", action="store_true")
    a = ap.parse_args(argv)
    warp_runtime.init()
    device = warp_runtime.resolve_device(a.device)
    if not str(device).startswith("cuda"):
        raise SystemExit("bench_kernel_resources: CUDA only (registers and local memory are CUDA properties)")
    keys = ([KernelKey(*bits) for bits in itertools.product((False, True), repeat=3)] if a.all_keys
            else [KernelKey(dahl=False, effects=False, gap=False)]) + [None]
    print(f"{'kernel key':<26} {'kernel':<20} {'registers':>9} {'local memory B / thread':>24}  ({wp.get_device(device).name})")
    for key in keys:
        mod = cell_step_module(key)
        for name in KERNELS:
            kernel = getattr(mod, name, None)
            if kernel is None:
                continue
            props = wp.get_cuda_kernel_properties(kernel, device)
            print(f"{key.name if key else 'generic':<26} {name:<20} {props['register_count']:>9} {props['local_memory_size']:>24}",
                  flush=True)


if __name__ == "__main__":
    main()
