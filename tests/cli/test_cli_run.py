"""``knitsim run`` in-process: shipped scenes run small, outputs are complete and consistent, bad input exits 2."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from knitsim.cli import main
from knitsim.io.output_dir import RECORD_NAME
from knitsim.io.patch_results import CURVE_COLUMNS

REPO = Path(__file__).resolve().parents[2]
SMALL = ["--set", "patch.wales=2", "--set", "patch.courses=3", "--set", "load.max_increment=0.05"]
FILES = {"curve.csv", "columns.csv", "cells.nc", "scene.resolved.toml", "force_strain.png", "strain_map.png",
         "stage_map.png", "summary.json"}


@pytest.mark.parametrize("name", ["random_phi0", "stitch_length_gradient", "two_zone_basalt_e_glass"])
def test_scene_runs_small(capsys, tmp_path, name):
    sets = SMALL + (["--set", "zones[0].courses=[1, 3]", "--set", "zones[0].wales=[0, 2]"]
                    if name.startswith("two_zone") else [])
    rc = main(["run", str(REPO / "scenes" / f"{name}.toml"), "--out", str(tmp_path / "o"), "--json",
               "--no-progress", *sets])
    cap = capsys.readouterr()
    summary = json.loads(cap.out)
    assert rc == (0 if summary["all_expected_end"] else 1)       # a stop at the force cap is an expected end
    assert {p.name for p in (tmp_path / "o").iterdir()} == FILES | {RECORD_NAME}   # checkpoint removed when done
    with open(tmp_path / "o" / "curve.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0].keys()) == CURVE_COLUMNS
    # increment 0 is the rest state (grip strain 0), then the program's increments
    assert len(rows) == summary["n_increments"] + 1
    assert rows[0]["increment"] == "0" and float(rows[0]["grip_strain"]) == 0.0
    rows = rows[1:]
    F = np.array([float(r["force_N"]) for r in rows])
    Fw = np.array([float(r["force_per_wale_N"]) for r in rows])
    np.testing.assert_allclose(F / 2, Fw, rtol=1e-12)                  # 2 wales: per wale = total / 2
    assert summary["cells"] == 6
    import xarray as xr
    with xr.open_dataset(tmp_path / "o" / "cells.nc", engine="h5netcdf") as ds:
        assert ds["strain"].shape == (summary["n_increments"], 3, 2)
        # labelled: one cell's history by its course and wale, increments numbered as in curve.csv
        one = ds.sel(course=2, wale=1)
        assert one["strain"].shape == (summary["n_increments"],)
        assert list(ds["increment"].values) == [int(r["increment"]) for r in rows]
        assert set(ds["direction"].values) <= {"load", "unload"} and "unknown" not in ds.dims
        assert ds["strain"].encoding.get("zlib") or ds["strain"].encoding.get("compression") == "gzip"
        np.testing.assert_allclose(ds["column_force_N"].values.sum(axis=1), F, rtol=1e-12)


def test_bad_input_exits_2(capsys, tmp_path):
    rc = main(["run", str(REPO / "scenes" / "random_phi0.toml"), "--out", str(tmp_path / "o"),
               "--set", "patch.wales=-1"])
    err = capsys.readouterr().err
    assert rc == 2 and "patch.wales = -1: must be >= 1" in err and "Traceback" not in err
    rc = main(["run", str(REPO / "scenes" / "random_phi0.toml"), "--out", str(tmp_path / "o"), "--resume"])
    assert rc == 2 and "no checkpoint" in capsys.readouterr().err


@pytest.mark.parametrize("command, text, key", [
    ("run", '[patch]\nwales = 2\ncourses = 2\n[yarn]\nmaterial = "e_glass"\n[knit]\nL = 14.1\nW0 = 4.4\nC0 = 0.0\n'
            '[load]\ntype = "monotonic"\ntarget_strain = 0.1\n', "knit.C0 = 0.0"),
    ("cell", '[yarn]\nmaterial = "e_glass"\n[knit]\nL = 14.1\nW0 = 2.0\nC0 = 2.7\n[friction]\nm = 0.2\n'
             '[load]\ntype = "monotonic"\ntarget_strain = 0.1\n', "knit.W0 = 2.0"),
])
def test_a_bad_scene_names_its_file_then_its_key(tmp_path, capsys, command, text, key):
    """A user with several scenes is told which one is wrong: the error names the file, then the key (a blind
    probe: only TOML syntax errors named the file); exit 2, no output folder."""
    scene = tmp_path / "mine.toml"
    scene.write_text(text)
    assert main([command, str(scene), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"knitsim: error: {scene}: {key}"), err
    assert not (tmp_path / "o").exists()


def test_a_cell_without_a_rest_state_is_refused_naming_the_scene(tmp_path, capsys):
    """Every error of a scene names its file first (a key alone does not say which of a user's scenes is wrong);
    the domain check's refusal did not (a blind probe: "knitsim: error: 2 of 12 cell(s) have no admissible rest
    state ..."). A loose E-glass loop, L = 16 mm (W0 4.4, C0 2.7): its contact would pull at rest."""
    scene = REPO / "scenes" / "random_phi0.toml"
    rc = main(["run", str(scene), "--out", str(tmp_path / "o"), "--set", "knit.L=16.0", *SMALL])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith(f"knitsim: error: {scene}: 6 of 6 cell(s) have no admissible rest state"), err
    assert not (tmp_path / "o").exists()
    # knitsim cell likewise
    cell = REPO / "scenes" / "paper" / "e_glass_monotonic.toml"
    assert main(["cell", str(cell), "--out", str(tmp_path / "c"), "--set", "knit.L=16.0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"knitsim: error: {cell}: ") and "no rest state" in err, err
    assert not (tmp_path / "c").exists()


_TIGHT_BASE = ('[yarn]\nmaterial = "e_glass"\n[knit]\nmaterial = "e_glass_plain"\n[friction]\nm = 0.2\n'
               '[load]\ntype = "monotonic"\ntarget_strain = 0.1\nmax_increment = 0.05\n')


@pytest.mark.parametrize("cells, key", [
    ('[patch]\nwales = 2\ncourses = 2\n[[zones]]\nlabel = "tight"\ncourses = [1, 2]\nknit = { L = 10.0 }\n',
     "L = 10.0 (zones[0].knit.L)"),
    ('[patch]\nwales = 3\ncourses = 2\n[maps.L]\ntype = "gradient"\naxis = "wales"\nstart = 14.1\nend = 9.0\n',
     "L = 11.55 (maps.L)"),
    ('[patch]\nwales = 2\ncourses = 2\n[[zones]]\ncourses = [1, 2]\nrules = { force_cap_N = 0.01 }\n',
     "force_cap_N = 0.01 (zones[0].rules.force_cap_N)"),
], ids=["zone", "gradient", "cap"])
def test_a_cell_the_model_cannot_run_names_the_zone_or_map_that_set_it(tmp_path, capsys, cells, key):
    """A zone or a gradient that leaves some cells without a rest state, or a zone's force cap below the rest
    force (E-glass's 0.022 N per wale), is refused naming the key that set them and its value at the cell named
    (the scene's own text: L = 10 in zones[0]; the gradient 14.1 -> 9.0 over 3 wales puts 11.55 on wale 1,
    E-glass's rest state needs about 14; the zone's cap 0.01 N): the refusal named neither (a blind probe:
    "2 of 4 cell(s) have no admissible rest state, e.g. course 1, wale 0: no rest state: ..."; "raise
    force_cap_N" of a scene whose [rules] cap is 10 N). Exit 2, no output folder."""
    scene = tmp_path / "tight.toml"
    scene.write_text(cells + _TIGHT_BASE)
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert ("have no admissible rest state" in err or "cannot be loaded" in err) and "Traceback" not in err, err
    assert f"that cell's {key}" in err or f", {key}" in err, err
    if "rest state" in err:
        assert "that cell's C0 = 2.7 (knit.C0), W0 = 4.4 (knit.W0)" in err, err
    assert not (tmp_path / "o").exists()


def test_resume_of_a_finished_run_says_it_is_finished(tmp_path, capsys):
    # a finished run removes its checkpoint: --resume read "no checkpoint ... to resume from", as if lost (a probe)
    scene, out = REPO / "scenes" / "random_phi0.toml", tmp_path / "o"
    assert main(["run", str(scene), "--out", str(out), *SMALL]) == 0
    before = (out / "summary.json").read_bytes()
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--resume", *SMALL]) == 2
    err = capsys.readouterr().err
    assert f"--resume: the run in {out} is finished (its summary.json is written, last): nothing to resume" in err
    assert (out / "summary.json").read_bytes() == before             # nothing touched
