"""Convert the real wale-wise tensile data into measured-curve CSVs for ``knitsim diagnose``.

Run from anywhere (stdlib + NumPy only)::

    python scenes/diagnosis/real/make_real_curves.py [--data DIR] [--out DIR]

``--data`` is the folder holding ``do2020_single_jersey_tensile/`` and
``singal2024_knit_uniaxial/`` (default: ``<repo>/../shared/data``); ``--out``
is where the CSVs go (default: this folder).  The output is deterministic:
the same input gives the same bytes.

Each CSV has the columns of :mod:`knitsim.diagnosis.measured`:
``strain`` (wale-wise engineering strain = strain of the course length C),
``force_per_wale_N`` (specimen force / number of wales across the width),
``cycle`` (1) and ``direction`` (``load``); loading only, strain increasing
from 0.  What was done to the raw data and every assumption (notably the
number of wales, which no source gives) is in README.md next to this file.
"""
from __future__ import annotations

import argparse
import csv
import gzip
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEFAULT_DATA = HERE.parents[3] / "shared" / "data"

N_ROWS = 150             # rows per curve (resampling / strain bins)
GLITCH_N = 3.0           # [N] one-frame excursion of the video-read force, up and back, larger than this = misread

# ---------------------------------------------------------------------------------------------
# Number of wales across the specimen: width / wale spacing W0.  No source gives it (README).
# do2020: the specimen width is not in the data; 50 mm assumed (ISO 13934-1 strip width).
#         W0 = L / K_w with Munden's dimensionless constant K_w = 3.9 (3.8 dry, 4.1 wet relaxed).
# singal: width = fabric_width_mm of runs_summary.csv; W0 acrylic = 2.9 mm (the x box size of the
#         authors' stockinette simulation init, Init_stockinette.dat, = 11.28 / 3.89, Munden-like);
#         cotton: W0 = L_cotton / 3.89 with L_cotton = 8.5 mm estimated (README).
# ---------------------------------------------------------------------------------------------
DO2020_WIDTH_MM = 50.0
MUNDEN_KW = 3.9
DO2020 = {  # output name: (file stem, loop length L [mm])
    "do2020_jersey_4p5mm_ww": ("test_const4.5_ww", 4.5),
    "do2020_jersey_6p5mm_ww": ("test_const6.5_ww", 6.5),
}
SINGAL = {  # output name: (sample_id, wale spacing W0 [mm])
    "singal2024_acrylic_stockinette_y": ("Acrylic_Yarn_Stockinette_Y", 2.9),
    "singal2024_cotton_stockinette_y": ("Pearlized_Cotton_Stockinette_Y", 8.5 / 3.89),
}


def n_wales(width_mm: float, w0_mm: float) -> int:
    """Whole number of wales across a width (nearest integer of width / W0)."""
    return int(round(width_mm / w0_mm))


def write_curve(path: Path, strain: np.ndarray, force: np.ndarray) -> None:
    """Write a loading-only measured curve (fixed formats, so the bytes are reproducible)."""
    if not (np.all(np.isfinite(strain)) and np.all(np.isfinite(force))):
        raise ValueError(f"{path}: NaN in the output")
    if strain[0] != 0.0 or np.any(np.diff(strain) <= 0) or np.any(force < 0):
        raise ValueError(f"{path}: strain must start at 0 and increase, force must be >= 0")
    with open(path, "w", newline="") as fh:
        fh.write("strain,force_per_wale_N,cycle,direction\n")
        for s, f in zip(strain, force):
            fh.write(f"{s:.6f},{f:.6f},1,load\n")


# --------------------------------------------------------------------------------------- do2020
def read_tsv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    a = np.loadtxt(path, skiprows=1, delimiter="\t", ndmin=2)
    return a[:, 0], a[:, 1]


def do2020_curve(folder: Path, stem: str, loop_length: float) -> dict:
    """Mid-line of the high / low experimental bounds, per wale, on N_ROWS strains from 0.

    Both bounds are interpolated linearly on a common grid from 0 to the smaller of their
    final strains; the mid-line is their mean, the half-band their half difference.
    """
    s_hi, f_hi = read_tsv(folder / f"{stem}_high.tsv")
    s_lo, f_lo = read_tsv(folder / f"{stem}_low.tsv")
    for s in (s_hi, s_lo):
        if np.any(np.diff(s) <= 0):  # the files are strictly increasing in strain (checked)
            raise ValueError(f"{stem}: strain not increasing")
    top = min(s_hi[-1], s_lo[-1])
    grid = np.linspace(0.0, top, N_ROWS)
    hi, lo = np.interp(grid, s_hi, f_hi), np.interp(grid, s_lo, f_lo)
    w0 = loop_length / MUNDEN_KW
    nw = n_wales(DO2020_WIDTH_MM, w0)
    return {"strain": grid, "force": 0.5 * (hi + lo) / nw, "half_band": 0.5 * np.abs(hi - lo) / nw,
            "wales": nw, "W0": w0, "top": top}


# --------------------------------------------------------------------------------------- singal
def read_singal(folder: Path, sample_id: str) -> tuple[dict, dict]:
    """Frames of one sample grouped by run, and its runs_summary rows by run."""
    runs: dict[int, dict] = {}
    with gzip.open(folder / "uniaxial_force_extension.csv.gz", "rt", newline="") as fh:
        for r in csv.DictReader(fh):
            if r["sample_id"] != sample_id:
                continue
            d = runs.setdefault(int(r["run"]), {"frame": [], "force": [], "pin": [], "clamp": []})
            d["frame"].append(int(r["frame"]))
            d["force"].append(float(r["force_N"]))
            d["pin"].append(float(r["pin_strain"]) if r["pin_strain"] else np.nan)
            d["clamp"].append(float(r["clamp_strain"]))
    runs = {k: {n: np.asarray(v) for n, v in d.items()} for k, d in runs.items()}
    with open(folder / "runs_summary.csv", newline="") as fh:
        summary = {int(r["run"]): r for r in csv.DictReader(fh) if r["sample_id"] == sample_id}
    return runs, summary


def drop_glitches(force: np.ndarray, threshold: float = GLITCH_N) -> np.ndarray:
    """Mask of frames to keep: drop one-frame excursions (up and back, or down and back) > threshold.

    A misread gauge digit shows as one frame far from both neighbours on the same side;
    a real load step stays at its new level (it is followed by a slow relaxation, not a return).
    """
    keep = np.ones(len(force), bool)
    a = force[1:-1] - force[:-2]
    b = force[1:-1] - force[2:]
    keep[1:-1] = ~((np.sign(a) == np.sign(b)) & (np.abs(a) > threshold) & (np.abs(b) > threshold))
    return keep


def strain_at_force(strain: np.ndarray, force: np.ndarray, level: float) -> float:
    i = np.nonzero(force >= level)[0]
    return float(strain[i[0]]) if len(i) else np.inf


def singal_curve(folder: Path, sample_id: str, w0: float) -> dict:
    """One representative run from rest, cleaned, loading envelope, binned in strain.

    - runs from rest only (first force reading 0);
    - strain column: ``pin_strain`` where the run has it, else ``clamp_strain``;
    - representative run: the (lower) median of the runs' strain at the first frame with F >= 10 N;
    - glitches dropped (:func:`drop_glitches`), frames up to the (first) maximum force kept;
    - strain made non-decreasing in time by its running maximum (removes the +-0.002
      tracking jitter; the strain is held constant during the hand-held holds);
    - loading envelope: N_ROWS - 1 equal strain bins on (0, strain at F_max]; each non-empty
      bin gives the frame with its highest force (the peak of a load step, not the relaxed
      force at the end of the hold that follows it), after a first row (0, 0) at rest.
    """
    runs, summary = read_singal(folder, sample_id)
    cand = []
    for k in sorted(runs):
        d = runs[k]
        if d["force"][0] != 0.0:
            continue
        col = "pin" if np.all(np.isfinite(d["pin"])) else "clamp"
        cand.append((strain_at_force(d[col], d["force"], 10.0), k, col))
    cand.sort()
    s10, run, col = cand[(len(cand) - 1) // 2]
    d = runs[run]
    keep = drop_glitches(d["force"])
    f, s = d["force"][keep], d[col][keep]
    imax = int(np.argmax(f))
    f, s = f[: imax + 1], s[: imax + 1]
    env_s = np.maximum.accumulate(np.maximum(s, 0.0))
    edges = np.linspace(0.0, env_s[-1], N_ROWS)
    b = np.searchsorted(edges, env_s, side="left")   # bin j covers (edges[j-1], edges[j]]; 0 = at rest
    idx = []
    for j in np.unique(b[b > 0]):
        rows = np.nonzero(b == j)[0]
        idx.append(int(rows[np.argmax(f[rows])]))    # the bin's highest force (first of ties)
    strain = np.concatenate([[0.0], env_s[idx]])
    force = np.concatenate([[0.0], f[idx]])
    width = float(summary[run]["fabric_width_mm"])
    nw = n_wales(width, w0)
    return {"strain": strain, "force": force / nw, "wales": nw, "W0": w0, "run": run, "column": f"{col}_strain",
            "strain_at_10N": s10, "dropped": int((~keep).sum()), "width_mm": width,
            "force_max_N": float(f[-1]), "summary_force_max_N": float(summary[run]["force_max_N"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder with the two data sets")
    ap.add_argument("--out", type=Path, default=HERE, help="output folder (default: this folder)")
    args = ap.parse_args(argv)
    need = [args.data / "do2020_single_jersey_tensile", args.data / "singal2024_knit_uniaxial"]
    missing = [str(p) for p in need if not p.is_dir()]
    if missing:
        # the raw data sets are not shipped with the repository (the curves made from them are)
        print(f"make_real_curves: error: no data set folder {', '.join(missing)}; give the folder that holds "
              "do2020_single_jersey_tensile/ and singal2024_knit_uniaxial/ with --data", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for name, (stem, L) in DO2020.items():
        c = do2020_curve(args.data / "do2020_single_jersey_tensile", stem, L)
        write_curve(args.out / f"{name}.csv", c["strain"], c["force"])
        print(f"{name}: {c['wales']} wales (W0 = {c['W0']:.3f} mm, width {DO2020_WIDTH_MM} mm), "
              f"strain 0-{c['top']:.4f}, F_max/wale = {c['force'][-1]:.4f} N, "
              f"half-band: median {np.median(c['half_band']):.4f} N, max {c['half_band'].max():.4f} N per wale")
    for name, (sid, w0) in SINGAL.items():
        c = singal_curve(args.data / "singal2024_knit_uniaxial", sid, w0)
        write_curve(args.out / f"{name}.csv", c["strain"], c["force"])
        print(f"{name}: run {c['run']} ({c['column']}, strain at 10 N {c['strain_at_10N']:.4f}), "
              f"{c['dropped']} glitch frames dropped, {len(c['strain'])} rows, width {c['width_mm']} mm, "
              f"{c['wales']} wales (W0 = {c['W0']:.3f} mm), F_max = {c['force_max_N']} N "
              f"(summary {c['summary_force_max_N']}), strain at F_max {c['strain'][-1]:.4f}, "
              f"F_max/wale = {c['force'][-1]:.4f} N")
    return 0


if __name__ == "__main__":
    sys.exit(main())
