"""The real measured curves of scenes/diagnosis/real (issue 6): format, normalisation, scenes, determinism.

Sources of the expected numbers:
- do2020 total forces: the table of /work/shared/data/do2020_single_jersey_tensile/README.md
  (read from the experimental bound files of Do et al. 2020);
- singal maximum force: runs_summary.csv of /work/shared/data/singal2024_knit_uniaxial;
- the wale counts are the assumptions stated in scenes/diagnosis/real/README.md.
"""
from __future__ import annotations

import copy
import csv
import filecmp
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from knitsim.diagnosis.measured import read_measured_curve
from knitsim.scene.cell_scene import load_cell_scene

REAL = Path(__file__).resolve().parents[2] / "scenes" / "diagnosis" / "real"
DATA = REAL.parents[3] / "shared" / "data"
# the raw data live beside the repository (../shared/data), not in it: the checks that read them
# run where they are present and say so where they are not
needs_raw_data = pytest.mark.skipif(not (DATA / "singal2024_knit_uniaxial" / "runs_summary.csv").exists(),
                                    reason=f"raw data not found at {DATA}")
CURVES = ["do2020_jersey_4p5mm_ww", "do2020_jersey_6p5mm_ww",
          "singal2024_acrylic_stockinette_y", "singal2024_cotton_stockinette_y"]
# wales across the specimen, as stated in README.md (assumptions, not data)
WALES = {"do2020_jersey_4p5mm_ww": 43, "do2020_jersey_6p5mm_ww": 30,
         "singal2024_acrylic_stockinette_y": 33, "singal2024_cotton_stockinette_y": 45}


@pytest.mark.parametrize("name", CURVES)
def test_curve_reads_and_is_loading_only(name):
    c = read_measured_curve(REAL / f"{name}.csv")
    assert len(c) >= 100
    assert np.all(np.isfinite(c.strain)) and np.all(np.isfinite(c.force))
    assert c.strain[0] == 0.0 and np.all(np.diff(c.strain) > 0)     # loading only, from rest
    assert np.all(c.force >= 0)
    assert np.all(c.direction == 1) and np.all(c.cycle == 1)


# README table of the do2020 data set: total specimen force [N] at strain 0.1 / 0.2 (high-low range)
DO2020_TABLE = {"do2020_jersey_4p5mm_ww": {0.1: (5.0, 5.1), 0.2: (10.6, 11.5), 0.3: (20.2, 23.1)},
                "do2020_jersey_6p5mm_ww": {0.1: (1.43, 1.47), 0.2: (3.3, 3.7), 0.3: (7.3, 8.9)}}


@pytest.mark.parametrize("name", list(DO2020_TABLE))
def test_do2020_mid_line_times_wales_matches_readme_table(name):
    c = read_measured_curve(REAL / f"{name}.csv")
    for eps, (lo, hi) in DO2020_TABLE[name].items():
        total = np.interp(eps, c.strain, c.force) * WALES[name]
        # the mid-line lies inside the bound range (0.05 N: rounding of the table and of the grid)
        assert lo - 0.05 <= total <= hi + 0.05, (eps, total)


@needs_raw_data
@pytest.mark.parametrize("name", ["singal2024_acrylic_stockinette_y", "singal2024_cotton_stockinette_y"])
def test_singal_maximum_is_summary_max_over_wales(name):
    c = read_measured_curve(REAL / f"{name}.csv")
    sample = {"acrylic": "Acrylic_Yarn_Stockinette_Y", "cotton": "Pearlized_Cotton_Stockinette_Y"}[name.split("_")[1]]
    with open(DATA / "singal2024_knit_uniaxial" / "runs_summary.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["sample_id"] == sample]
    # the representative run is one of the sample's runs: its F_max / wales is the curve's last point
    fmax = {int(r["run"]): float(r["force_max_N"]) for r in rows}
    # (1e-4 N: the CSV's 6 decimals times <= 45 wales)
    assert min(abs(c.force[-1] * WALES[name] - f) for f in fmax.values()) < 1e-4
    # and the curve's maximum strain is below the clamp strain at F_max (pins sit inside the clamps)
    assert c.strain[-1] <= max(float(r["clamp_strain_at_Fmax"]) for r in rows)


def _as_cell_scene(doc: dict) -> dict:
    d = copy.deepcopy(doc)
    d.pop("diagnosis")
    d["load"] = {"type": "monotonic", "target_strain": 0.1}
    return d


@pytest.mark.parametrize("name", CURVES)
def test_scene_loads_and_bounds_respect_the_geometry(name):
    with open(REAL / f"{name}.toml", "rb") as fh:
        doc = tomllib.load(fh)
    diag = doc["diagnosis"]
    assert {"m", "phi0"} <= set(diag["free"])
    assert len(diag["effects"]) == 7
    sc = load_cell_scene(_as_cell_scene(doc))      # W0 >= 4 d, L > 2 C0 + W0 - 4 d, |phi0| <= atan(m)
    p = sc.params[0]
    lo, hi = diag["bounds"]["d"]
    assert lo <= p.d <= hi and hi <= p.W0 / 4.0        # Hong: W0 >= 4 d over the whole d range
    assert p.L > 2 * p.C0 + p.W0 - 4 * lo              # a loop closes at the smallest d too
    blo, bhi = diag["bounds"]["B"]
    assert blo <= p.B <= bhi
    # the measured strain range is reachable: C < L / 2 (straight yarn)
    c = read_measured_curve(REAL / f"{name}.csv")
    assert c.strain[-1] < p.L / (2 * p.C0) - 1


@needs_raw_data
def test_script_reproduces_committed_csvs(tmp_path):
    subprocess.run([sys.executable, str(REAL / "make_real_curves.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True)
    for name in CURVES:
        assert filecmp.cmp(tmp_path / f"{name}.csv", REAL / f"{name}.csv", shallow=False), name
