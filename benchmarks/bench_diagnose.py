"""Benchmark: one diagnosis of a two-test lab specimen (about 1,200 rows), all effects (issue 12: < 60 s on one core).

The specimen (:func:`knitsim.diagnosis.synthetic.make_specimen`): a monotonic pull to 5 N per
wale and the paper's three cycles 0.10-0.60, each with its own noise, offset, jitter and the
flaws of a real file.  Reports the wall time of the whole diagnosis (noise per curve,
baseline, every candidate, the basin check and the greedy pair) and, as the ratio the project
reports, its cost in units of one baseline calibration measured in the same run.

    taskset -c 0 python benchmarks/bench_diagnose.py [--device cpu] [--no-pair] [--effect NAME|none]

Run it on one core (``taskset -c 0``); Warp's CPU kernels are serial.
"""
from __future__ import annotations

import argparse
import time

from knitsim import warp_runtime
from knitsim.diagnosis.calibrate import calibrate_baseline
from knitsim.diagnosis.diagnose import DiagnosisSetup, diagnose
from knitsim.diagnosis.effects import DEFAULT_STUDY_FREE
from knitsim.diagnosis.synthetic import make_specimen, material_params


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--no-pair", action="store_true")
    ap.add_argument("--effect", default="coiling_angle_friction", help="hidden effect, or none")
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    warp_runtime.init()
    effect = None if args.effect == "none" else args.effect
    case = make_specimen(args.seed, material="e_glass", effect=effect, strength=0.6)
    base = material_params("e_glass")
    curves = case.curves
    n = sum(len(c) for c in curves)
    weights = [1.0 / c.noise.sigma_N * (c.force * 0 + 1) for c in curves]
    # warm-up: kernels compiled and loaded before timing
    calibrate_baseline(curves, base, max_nfev=2, device=args.device)
    t = time.perf_counter()
    calibrate_baseline(curves, base, free=DEFAULT_STUDY_FREE, device=args.device, max_nfev=20, weights=weights,
                       offsets=True)
    t_base = time.perf_counter() - t
    setup = DiagnosisSetup(base=base, free=DEFAULT_STUDY_FREE, device=args.device, pair=not args.no_pair)
    t = time.perf_counter()
    r = diagnose(curves, setup).as_dict()
    t_diag = time.perf_counter() - t
    print(f"specimen: pull to 5 N ({len(curves[0])} rows) + 3 cycles 0.10-0.60 ({len(curves[1])} rows) = {n} rows, "
          f"hidden effect {args.effect}")
    print(f"baseline calibration (20 evaluations): {t_base:.2f} s")
    print(f"diagnosis, {len(setup.effects)} effects{'' if args.no_pair else ' + greedy pair'}: {t_diag:.2f} s "
          f"= {t_diag / t_base:.1f} baseline calibrations (target: < 60 s on one core)")
    v = r["verdict"]
    print(f"verdict: {v['kind']} {v['effect'] or ''} (confident {v['confident']}), shrink {v['shrink']:.1%}")


if __name__ == "__main__":
    main()
