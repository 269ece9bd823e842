"""Benchmark: one diagnosis of a 3-cycle curve with all seven effects (issue 6: under a minute on one core).

Reports the wall time of the whole diagnosis (baseline, seven candidates, greedy
pair) and, as the ratio the project reports, its cost in units of one baseline
calibration measured in the same run.

    python benchmarks/bench_diagnose.py [--device cpu] [--no-pair]

Run it on one core (e.g. ``taskset -c 0``); Warp's CPU kernels are serial.
"""
from __future__ import annotations

import argparse
import time

from knitsim import warp_runtime
from knitsim.diagnosis.calibrate import calibrate_baseline
from knitsim.diagnosis.diagnose import DiagnosisSetup, diagnose
from knitsim.diagnosis.effects import DEFAULT_STUDY_FREE
from knitsim.diagnosis.synthetic import make_case, material_params


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--no-pair", action="store_true")
    ap.add_argument("--effect", default="coiling_angle_friction")
    args = ap.parse_args()
    warp_runtime.init()
    case = make_case(3, material="e_glass", test="cyclic", effect=args.effect, strength=0.6, rates=(1.0,))
    base = material_params("e_glass")
    curves = case.curves
    n = sum(len(c) for c in curves)
    # warm-up: kernels compiled and loaded before timing
    calibrate_baseline(curves, base, max_nfev=2, device=args.device)
    t = time.perf_counter()
    calibrate_baseline(curves, base, free=DEFAULT_STUDY_FREE, device=args.device, max_nfev=30)
    t_base = time.perf_counter() - t
    # the generator scatters L, W0, C0 and d by 1 %: they are calibrated with the friction, as in the study
    setup = DiagnosisSetup(base=base, free=DEFAULT_STUDY_FREE, device=args.device, pair=not args.no_pair)
    t = time.perf_counter()
    r = diagnose(curves, setup)
    t_diag = time.perf_counter() - t
    print(f"curve: 3 cycles 0.10-0.60, {n} measured rows, hidden effect {args.effect}")
    print(f"baseline calibration: {t_base:.2f} s")
    print(f"diagnosis, 7 effects{'' if args.no_pair else ' + greedy pair'}: {t_diag:.2f} s "
          f"= {t_diag / t_base:.1f} baseline calibrations (target: < 60 s on one core)")
    print(f"verdict: {r['verdict']['effect']} (confident {r['verdict']['confident']}), "
          f"shrink {r['verdict']['shrink']:.1%}")


if __name__ == "__main__":
    main()
