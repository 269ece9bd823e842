"""Compile every knitsim Warp module for one device into the kernel cache, in parallel.

A cold cache on CUDA costs NVRTC tens of seconds to a minute per module (the generic cell step,
one specialised instance per kernel key, the elastica, inverse and head-gap modules); Warp compiles
them one at a time on first launch.  This loads them all at once (one thread per module, up to the
number of cores), so that a benchmark or a first run that follows finds them cached.  Not a test.

    python benchmarks/warm_kernel_cache.py --device cuda
    python benchmarks/warm_kernel_cache.py --device cuda --only branch_points cell_arrays cell_tangent \
        cell_step__coulomb_plain_w4d column_trials backend_trials state_read   # what a random-phi0 E-glass patch launches (bench_patch.py)
"""
from __future__ import annotations

import argparse
import importlib
import itertools
import pkgutil
import time

import warp as wp


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--only", nargs="+", default=None,
                    help="load only these modules (names after knitsim.kernels., a key's instance as "
                         "cell_step__<key name>): a run that launches few of them waits for those only")
    args = ap.parse_args()

    from knitsim import warp_runtime
    import knitsim.kernels as kpkg
    from knitsim.kernels.specialise import KernelKey, cell_step_module

    device = warp_runtime.resolve_device(args.device)
    mods = [importlib.import_module(f"knitsim.kernels.{m.name}") for m in pkgutil.iter_modules(kpkg.__path__)]
    mods += [cell_step_module(KernelKey(*flags)) for flags in itertools.product((False, True), repeat=3)]
    # only the modules that hold Warp code (kernels/__init__ and the key registry hold none)
    mods = [m for m in mods if any(isinstance(v, (wp.Kernel, wp.Function)) for v in vars(m).values())]
    if args.only:
        known = {m.__name__.rsplit(".", 1)[-1]: m for m in mods}
        unknown = sorted(set(args.only) - set(known))
        if unknown:
            raise SystemExit(f"--only: no Warp module {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        mods = [known[n] for n in args.only]
    t0 = time.perf_counter()
    warp_runtime.preload(mods, device)
    print(f"{len(mods)} Warp modules loaded on {device} in {time.perf_counter() - t0:.1f} s "
          f"(cache: {warp_runtime.kernel_cache_dir()})")


if __name__ == "__main__":
    main()
