"""Sweep --resume and a material library (``materials = FILE``) that changes between a run and its resume.

Where the expected behaviour comes from:

* the defect report of a blind probe (``knitsim sweep --resume`` reused the chunks of a sweep after the
  library they were computed with had changed: "2 chunk(s) computed, 2 reused", a map mixing two yarns,
  sweep.json still recording the old B): a resume must be refused when what determines the results
  differs, naming what changed, and pointing to a new --out or --overwrite;
* ``knitsim run``'s checkpoint (knitsim.patch.runner.fingerprint), which hashes the resolved cells, not
  the scene text, and so refuses such a resume: the sweep follows the same rule;
* knitsim.sweep.runner's docstring: a resume of the same sweep computes only the missing chunks and its
  results do not depend on how the work was split (identical to an uninterrupted run);
* the scene schema's ``materials`` field: "material library file ..., relative to the scene".

The yarn and knit are Dusserre's E-glass (Table 1, section 2.2: d = 0.58 mm, B = 0.31 N mm^2;
L = 14.1, W0 = 4.4, C0 = 2.7 mm), written as a library by hand; a coarse program keeps it fast.
"""
from __future__ import annotations

import json

import pytest

import knitsim
from knitsim.cli import main
from knitsim.errors import KnitsimInputError
from knitsim.sweep.runner import plan_sweep, run_sweep

LIB = """[yarns.myglass]
d = 0.58
B = 0.31
[yarns.myglass.friction]
model = "coulomb"
m = 0.2
[knits.myknit]
yarn = "myglass"
L = 14.1
W0 = 4.4
C0 = 2.7
[knits.otherknit]
yarn = "myglass"
L = 14.1
W0 = 4.4
C0 = 2.7
"""

SCENE = """title = "lib sweep"
materials = "lib.toml"
engine = "warp"
device = "cpu"
[knit]
material = "myknit"
[friction]
model = "coulomb"
m = 0.2
phi0 = 0.0
[rules]
force_cap_N = 10.0
[load]
type = "cycles"
lower_strain = 0.1
upper_strain = 0.5
cycles = 2
max_increment = 0.1
[sweep]
method = "grid"
chunk_size = 1
[sweep.parameters]
"""


def _write(folder, parameters='"friction.m" = { values = [0.15, 0.2, 0.25, 0.3] }\n'):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "lib.toml").write_text(LIB)
    (folder / "sw.toml").write_text(SCENE + parameters)
    return folder / "sw.toml"


def test_resume_after_the_library_changed_is_refused_and_an_unchanged_resume_reuses_chunks(tmp_path, monkeypatch,
                                                                                         capsys):
    _write(tmp_path)
    monkeypatch.chdir(tmp_path)                      # the probe's layout: relative names, run beside the scene
    args = ["sweep", "sw.toml", "--workers", "0", "--no-plot", "--out"]
    assert main(args + ["full"]) == 0                # the uninterrupted reference
    assert main(args + ["cut"]) == 0
    for i in (2, 3):                                 # as if killed after 2 of 4 chunks
        (tmp_path / "cut" / "chunks" / f"chunk_0000{i}.npz").unlink()
    manifest = (tmp_path / "cut" / "sweep.json").read_text()
    capsys.readouterr()

    lib = tmp_path / "lib.toml"
    lib.write_text(LIB.replace("B = 0.31", "B = 0.62"))          # the library is edited meanwhile
    assert main(args + ["cut", "--resume"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "--resume" in err and "different sweep" in err and "resolved inputs differ" in err
    assert "yarn.B 0.31 -> 0.62" in err and "material library lib.toml" in err           # names what changed
    assert "new --out" in err and "--overwrite" in err                                   # and the way out
    assert sorted(p.name for p in (tmp_path / "cut" / "chunks").iterdir()) == ["chunk_00000.npz", "chunk_00001.npz"]
    assert (tmp_path / "cut" / "sweep.json").read_text() == manifest                     # nothing written

    lib.write_text(LIB)                              # the library back as it was: the same sweep
    assert main(args + ["cut", "--resume"]) == 0
    assert "2 chunk(s) computed, 2 reused" in capsys.readouterr().err
    for f in ("results.nc", "results.csv", "chunks/chunk_00002.npz", "chunks/chunk_00003.npz"):
        assert (tmp_path / "cut" / f).read_bytes() == (tmp_path / "full" / f).read_bytes(), f


def test_a_change_to_a_swept_library_material_names_the_sample_and_a_new_version_is_refused(tmp_path, monkeypatch):
    """The base scene's cells are unchanged (knit myknit); only the swept sample's knit (otherknit) changed
    in the library: the refusal names that sample.  A different knitsim version is refused too."""
    scene = _write(tmp_path, '"knit.material" = { values = ["myknit", "otherknit"] }\n')
    monkeypatch.chdir(tmp_path)
    run_sweep(plan_sweep(scene), tmp_path / "o", workers=0, progress=None, plots=False)
    (tmp_path / "o" / "chunks" / "chunk_00001.npz").unlink()
    lib = tmp_path / "lib.toml"
    lib.write_text(LIB.replace("[knits.otherknit]\nyarn = \"myglass\"\nL = 14.1", "[knits.otherknit]\n"
                               "yarn = \"myglass\"\nL = 14.5"))
    with pytest.raises(KnitsimInputError, match=r"different sweep.*1 of 2 sample\(s\), e\.g\. sample 1 "
                                                r"\(knit\.material = \"otherknit\"\).*material library lib\.toml"):
        run_sweep(plan_sweep(scene), tmp_path / "o", resume=True, workers=0, progress=None, plots=False)
    lib.write_text(LIB)
    monkeypatch.setattr(knitsim, "__version__", "999.0")
    with pytest.raises(KnitsimInputError, match=r"knitsim version .* -> 999\.0"):
        run_sweep(plan_sweep(scene), tmp_path / "o", resume=True, workers=0, progress=None, plots=False)
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    run = run_sweep(plan_sweep(scene), tmp_path / "o", resume=True, workers=0, progress=None, plots=False)
    assert run.skipped == [0] and run.computed == [1]


def test_the_library_is_read_relative_to_the_scene_and_its_values_are_in_the_manifest(tmp_path, monkeypatch):
    scene = _write(tmp_path / "scene")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")        # before: "no such material library file (lib.toml)"
    plan = plan_sweep(str(scene))
    assert plan.base.params[0].B == 0.31 and plan.base.params[0].L == 14.1
    assert plan.scene_doc["materials"] == "lib.toml"                     # the scene as written is kept
    from knitsim.sweep.runner import manifest
    man = json.loads(json.dumps(manifest(plan)))
    assert man["inputs"]["knitsim"] == knitsim.__version__ and len(man["inputs"]["samples_cells"]) == 4
    assert man["hash"] == plan.hash
