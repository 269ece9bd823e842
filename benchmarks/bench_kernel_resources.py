"""Registers and local memory per thread of the cell-step kernels on CUDA (``wp.get_cuda_kernel_properties``).

A GPU thread of the step kernel that needs more registers than the hardware gives it (255 on sm_90) keeps
the rest of its working set in local memory: per-thread stack in L1 / L2 / DRAM, read and written through
the whole increment.  This prints, for the kernel keys given (default: the random benchmark batch's, Coulomb
without effects with W = 4 d jamming, and the generic kernel), the register count and the local memory of the
program, first-pass and step kernels, at the block size Warp launches them with (256).  Compiles what it
asks for (minutes on a cold cache).  Not a test.

Without a GPU, ``--ptxas`` measures the same offline: Warp compiles the module to PTX for sm_90
(``wp.compile_aot_module``, NVRTC, no device needed) and the CUDA toolkit's ``ptxas -v`` assembles it and
reports registers, stack frame (the local memory) and spill bytes per kernel.  Where that ptxas is older
than Warp's NVRTC, the PTX's ``.version`` line is lowered to the one ptxas names (said on the console; the
kernels use nothing newer: on 2026-11-27 ptxas 13.0 on the 2-core box gave 255 registers and 9,824 B for
``program_kernel``, exactly what the H100 reported).  About 2.5 minutes per key on one core.

    python benchmarks/bench_kernel_resources.py                 # the benchmark batch's key and the generic kernel
    python benchmarks/bench_kernel_resources.py --all-keys      # every one of the 8 keys
    python benchmarks/bench_kernel_resources.py --ptxas         # offline, no GPU: the batch's key
"""
from __future__ import annotations

import argparse
import itertools
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import warp as wp

from knitsim import warp_runtime
from knitsim.kernels.specialise import KernelKey, cell_step_module

KERNELS = ("program_kernel", "regular_kernel", "substep_kernel", "step_kernel", "regular_step_kernel")


def offline(keys, arch: int = 90) -> None:
    """Registers, stack frame and spills of ``keys``' kernels from ``ptxas -v`` on Warp's PTX for sm_``arch``."""
    ptxas = shutil.which("ptxas")
    if ptxas is None:
        raise SystemExit("bench_kernel_resources --ptxas: no ptxas on PATH (the CUDA toolkit's assembler)")
    print(f"{'kernel key':<26} {'kernel':<20} {'registers':>9} {'stack B / thread':>17} {'spill stores B':>15}  (sm_{arch}, {ptxas})")
    with tempfile.TemporaryDirectory() as tmp:
        for key in keys:
            mod = cell_step_module(key)
            out = Path(tmp) / (key.name if key else "generic")
            path, = wp.compile_aot_module(mod.__name__, arch=arch, module_dir=str(out), use_ptx=True)
            ptx = Path(path).read_bytes().replace(b"\x00", b"")
            have = re.search(rb"^\.version (\d+\.\d+)", ptx, re.M).group(1).decode()
            fixed = out / "fixed.ptx"

            def assemble(text: bytes):
                fixed.write_bytes(text)
                return subprocess.run([ptxas, f"-arch=sm_{arch}", "-v", "-o", str(out / "x.cubin"), str(fixed)],
                                      capture_output=True, text=True)

            r = assemble(ptx)
            m = re.search(r"Unsupported \.version (\d+\.\d+); current version is '(\d+\.\d+)'", r.stderr)
            if m:
                print(f"(PTX .version {have} lowered to {m.group(2)} for this ptxas)")
                r = assemble(re.sub(rb"^\.version \d+\.\d+", f".version {m.group(2)}".encode(), ptx, count=1, flags=re.M))
            if r.returncode:
                raise SystemExit(f"ptxas failed:\n{r.stderr[-2000:]}")
            lines = r.stderr.splitlines()
            for i, line in enumerate(lines):
                m = re.search(r"Function properties for (\w+?)_[0-9a-f]{8}_cuda_kernel_forward", line)
                if m and m.group(1) in KERNELS:
                    stack = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores", lines[i + 1])
                    regs = re.search(r"Used (\d+) registers", lines[i + 2])
                    print(f"{key.name if key else 'generic':<26} {m.group(1):<20} {regs.group(1):>9} {stack.group(1):>17} "
                          f"{stack.group(2):>15}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--all-keys", action="store_true")
    ap.add_argument("--ptxas", action="store_true", help="offline: Warp's PTX for sm_90 through the toolkit's ptxas -v")
    a = ap.parse_args(argv)
    warp_runtime.init()
    keys = ([KernelKey(*bits) for bits in itertools.product((False, True), repeat=3)] if a.all_keys
            else [KernelKey(dahl=False, effects=False, gap=False)])
    if a.ptxas:
        offline(keys)
        return
    device = warp_runtime.resolve_device(a.device)
    if not str(device).startswith("cuda"):
        raise SystemExit("bench_kernel_resources: CUDA only (registers and local memory are CUDA properties)")
    keys = keys + [None]
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
