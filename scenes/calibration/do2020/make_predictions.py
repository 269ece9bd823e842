"""Predict the graded Do et al. (2020) specimens from the jointly calibrated yarn, beside the naive mix.

    python scenes/calibration/do2020/make_predictions.py [--out DIR] [--materials FILE]

Runs the two prediction scenes of this folder (``predict_*.toml``, patch scenes in specimen form
that name the calibrated knits of ``calibrated/materials.toml``, written by
``knitsim calibrate calibrate.toml --out calibrated``)
with the knitsim API, exactly as ``knitsim run`` does, and writes for each case
``prediction_<case>.csv`` (``strain_mm_per_mm, load_N``: grip strain and TOTAL force on the
specimen, the same 50 mm assumed width as the calibration) and ``prediction_<case>.png`` (the
prediction beside the naive mix, the mean of the two uniform curves at equal strain, and the
uniform experimental bands).  ``naive_mix.csv`` holds the naive mix on the same strains.
Deterministic; about a minute on a 2-core CPU.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CASES = {"linear4.5to6.5_ww": "predict_linear4.5to6.5_ww.toml",
         "discont4.5to6.5_ww": "predict_discont4.5to6.5_ww.toml"}
UNIFORM = {"4.5 mm": "test_const4.5_ww", "6.5 mm": "test_const6.5_ww"}


def band(stem: str, strain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper experimental bounds of a uniform specimen at ``strain`` (linear interpolation)."""
    lo = np.loadtxt(HERE / "data" / f"{stem}_low.tsv", skiprows=1)
    hi = np.loadtxt(HERE / "data" / f"{stem}_high.tsv", skiprows=1)
    a, b = np.interp(strain, lo[:, 0], lo[:, 1]), np.interp(strain, hi[:, 0], hi[:, 1])
    return np.minimum(a, b), np.maximum(a, b)


def naive_mix(strain: np.ndarray) -> np.ndarray:
    """The mean of the two uniform band mid-lines at equal strain [N]."""
    mids = [0.5 * sum(band(stem, strain)) for stem in UNIFORM.values()]
    return 0.5 * (mids[0] + mids[1])


def predict(scene_path: Path, materials: Path | None = None):
    from knitsim.patch.runner import all_ok, run_patch
    from knitsim.scene.patch_scene import load_patch_scene
    from knitsim.scene.schema import load_toml
    doc = load_toml(scene_path)
    if materials is not None:
        doc["materials"] = str(materials.resolve())
    else:
        doc["materials"] = str((scene_path.parent / doc["materials"]).resolve())
    s = load_patch_scene(doc)
    h = run_patch(s.model, s.program, engine=s.engine, device=s.device, dedup=s.dedup, **s.solver_options)
    strain = np.concatenate([[0.0], h.grip_strain])
    force = np.concatenate([[h.rest_force_N], h.force_N])
    return strain, force, all_ok(h), s


def plot(case: str, strain, force, ok: bool, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7.5, 5.2), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    s = np.linspace(0.0, 0.31, 311)
    for (name, stem), c in zip(UNIFORM.items(), ("0.80", "0.65")):
        lo, hi = band(stem, s)
        ax.fill_between(s, lo, hi, color=c, alpha=0.8, label=f"uniform {name}: experimental band")
    ax.plot(s, naive_mix(s), "k--", lw=1.3, label="naive mix (mean of the uniform curves)")
    ax.plot(strain, force, color="tab:blue", lw=2.0, label="knitsim prediction (one calibrated yarn)")
    ax.set_xlabel("grip strain [mm/mm]")
    ax.set_ylabel("total force on the 50 mm wide specimen [N]")
    ax.set_title(f"Do 2020 {case}: prediction" + ("" if ok else " (NOT CONVERGED everywhere: see the run)"),
                 fontsize=10)
    ax.set_xlim(0, 0.32)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE, help="output folder (default: this folder)")
    ap.add_argument("--materials", type=Path, default=None, help="material library (default: the scenes')")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    status = 0
    for case, scene in CASES.items():
        strain, force, ok, _ = predict(HERE / scene, args.materials)
        status |= 0 if ok else 1
        rows = "".join(f"{e:.6g},{f:.6g}\n" for e, f in zip(strain, force))
        (args.out / f"prediction_{case}.csv").write_text("strain_mm_per_mm,load_N\n" + rows)
        plot(case, strain, force, ok, args.out / f"prediction_{case}.png")
        print(f"{case}: {len(strain)} rows, force at 0.1 / 0.2 / 0.3: "
              + " / ".join(f"{np.interp(x, strain, force):.3f}" for x in (0.1, 0.2, 0.3))
              + f" N (naive mix {' / '.join(f'{naive_mix(np.array([x]))[0]:.3f}' for x in (0.1, 0.2, 0.3))} N)"
              + ("" if ok else "; NOT CONVERGED everywhere"))
    s = np.round(np.arange(0.0, 0.3101, 0.005), 6)
    (args.out / "naive_mix.csv").write_text("strain_mm_per_mm,load_N\n"
                                           + "".join(f"{e:.6g},{f:.6g}\n" for e, f in zip(s, naive_mix(s))))
    return status


if __name__ == "__main__":
    raise SystemExit(main())
