"""Bad input of ``knitsim calibrate``, ``[specimen]`` and ``[[grades]]``: one line naming the file, key and
value, exit status 2, no traceback, and nothing written (the checks run before any work starts).  And
``knitsim calibrate``'s progress and --out policy (refuse results unless --resume or --overwrite)."""
from __future__ import annotations

import copy

import pytest

from knitsim.cli import main
from knitsim.scene.schema import dumps

CURVE = "strain,load_N\n" + "".join(f"{0.02 * k},{0.5 * k}\n" for k in range(11))


def _set(doc, path, value):
    *head, last = path
    for k in head:
        doc = doc[k]
    if value is _DEL:
        del doc[last]
    else:
        doc[last] = value


_DEL = object()


@pytest.mark.parametrize("path, value, curve, match", [
    (("specimens", 0, "width"), _DEL, CURVE, r"specimens\[0\]\.width: missing required key"),
    (("specimens", 0, "width"), -50.0, CURVE, r"specimens\[0\]\.width = -50\.0: must be > 0 mm"),
    (("specimens", 0, "gauge_length"), 2.0, CURVE,
     r"specimens\[0\]\.gauge_length = 2\.0: shorter than one course \(knit\.C0 = 2\.7 mm\)"),
    (("specimens", 0, "width"), 3.0, CURVE,
     r"specimens\[0\]\.width = 3\.0: narrower than one wale \(knit\.W0 = 4\.4 mm\)"),
    # more than a patch may hold (1e9 / C0 = 2.7 mm: 3.7e8 courses), as the [specimen] of knitsim run; before,
    # calibrated against as a specimen of 370 million courses
    (("specimens", 0, "gauge_length"), 1e9, CURVE,
     r"specimens\[0\]\.gauge_length = 1000000000\.0: the specimen holds .* x 3\.704e\+08 courses, more than the "
     r"100,000 a patch may hold"),
    (("specimens", 0, "width"), 3.0, CURVE, r"narrower than one wale .*; if the sizes are in cm, write them in mm "
                                            r"\(width = 30, "),
    (("specimens", 0, "knit", "C0"), _DEL, CURVE, r"specimens\[0\]\.knit\.C0: missing required key"),
    (None, None, "strain,force_kN\n0,0\n0.1,1\n", r"specimens\[0\]\.curve: .*a\.csv: no force column"),
    (None, None, "strain,load_N\n0,0\n0.1,abc\n", r"specimens\[0\]\.curve: .*a\.csv: row 3, column load_N"),
    (None, None, "time_s,load_N\n0,0\n0.1,1\n", r"specimens\[0\]\.curve: .*a\.csv: no strain column"),
])
def test_calibrate_refuses_bad_input_in_one_line(tmp_path, capsys, path, value, curve, match, e_glass_calibration):
    doc = e_glass_calibration("bad input", starts=2)
    if path is not None:
        _set(doc, path, value)
    (tmp_path / "a.csv").write_text(curve)
    (tmp_path / "cal.toml").write_text(dumps(doc))
    rc = main(["calibrate", str(tmp_path / "cal.toml"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("knitsim: error: ")
    import re
    assert re.search(match, lines[0]), lines[0]
    assert not (tmp_path / "out").exists()


SPECIMEN = {"title": "bad input", "specimen": {"width": 50.0, "gauge_length": 100.0, "strips": 2, "bands": 2},
            "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"}, "rules": {"force_cap_N": 10.0},
            "load": {"type": "monotonic", "target_strain": 0.1, "max_increment": 0.05}}
GRADE = {"from": "e_glass_plain", "to": "e_glass_plain", "axis": "courses"}


@pytest.mark.parametrize("edit, match", [
    ({"specimen": {"width": 50.0}}, r"specimen\.gauge_length: missing"),
    ({"specimen": {"width": -5.0, "gauge_length": 100.0}}, r"specimen\.width = -5\.0: must be > 0 mm"),
    ({"specimen": {"width": 50.0, "gauge_length": 2.0}},
     r"specimen\.gauge_length = 2\.0: shorter than one course \(C0 = 2\.7 mm\): strip 0 holds 0\.7407 courses"),
    ({"specimen": {"width": 3.0, "gauge_length": 100.0}},
     r"specimen\.width = 3\.0: narrower than one wale \(W0 = 4\.4 mm\): band 0 holds 0\.6818 wales"),
    ({"grades": [dict(GRADE, to="basalt_plain")]}, r"grades\[0\]\.to = \"basalt_plain\": a grade blends knits of one "
                                                   r"yarn: 'e_glass_plain' is of yarn 'e_glass', 'basalt_plain' of "
                                                   r"yarn 'basalt'"),
    ({"grades": [dict(GRADE, fractions=[0.0, 1.5])]}, r"grades\[0\]\.fractions\[1\] = 1\.5: a blend fraction is in "
                                                      r"\[0, 1\]"),
    ({"grades": [dict(GRADE, fractions=[-0.2, 1.0])]}, r"grades\[0\]\.fractions\[0\] = -0\.2: a blend fraction"),
    ({"grades": [{"from": "e_glass_plain", "to": "e_glass_plain"}]}, r"grades\[0\]\.axis: missing required key"),
    ({"grades": [dict(GRADE, to="nope")]}, r"grades\[0\]\.to = \"nope\": unknown knit"),
    # 50 bands over 100 mm of C0 = 2.7 mm courses: 0.74 course per block, a cell less than a stitch
    ({"specimen": {"width": 50.0, "gauge_length": 100.0, "bands": 50}},
     r"specimen\.bands = 50: the block at band 0, strip 0 holds 0\.7407 courses, less than one stitch: at most "
     r"37 bands"),
    # sizes no grips hold: 1e9 mm / C0 = 2.7 mm is 3.7e8 courses, 1e9 / W0 = 4.4 mm 2.3e8 wales, more than the
    # 100,000 a [patch] may hold (before: run, "a block standing for 420,875,421 stitches", exit 0)
    ({"specimen": {"width": 50.0, "gauge_length": 1e9}},
     r"specimen\.gauge_length = 1000000000\.0: the specimen holds 11\.36 wales x 3\.704e\+08 courses, more than "
     r"the 100,000 a patch may hold"),
    ({"specimen": {"width": 1e9, "gauge_length": 100.0}},
     r"specimen\.width = 1000000000\.0: the specimen holds 2\.273e\+08 wales x 37\.04 courses, more than"),
    # less than a wale across says what the sizes make in mm read as cm (30 / 4.4 = 6.818 wales)
    ({"specimen": {"width": 3.0, "gauge_length": 100.0}},
     r"band 0 holds 0\.6818 wales; if the sizes are in cm, write them in mm \(width = 30, gauge_length = 1000: "
     r"6\.818 wales x 370\.4 courses\)"),
    # ... and nothing of cm where 10 times the sizes are no specimen either (0.01 / 4.4 mm: 0.0023 wale)
    ({"specimen": {"width": 0.001, "gauge_length": 100.0}}, r"band 0 holds 0\.0002273 wales$"),
    # a cap below the force per wale the knit carries at rest (E-glass: about 0.02 N, above 0.015 N):
    # no program can load it (before: run, then "the peak 0.02159 N per wale is the cap" and advice to
    # lower the program's strain, which cannot help)
    ({"rules": {"force_cap_N": 0.015}}, r"block\(s\) cannot be loaded, e\.g\. band 0, strip 0: its force per "
                                        r"wale at rest, 0\.02\d* N, is already at or above force_cap_N = 0\.015 N"),
    # a block is named by band and strip, as the specimen's zones and maps index it (before, "course 1, wale 0",
    # read as the second of a strip's courses): a zone too tight for a rest state in band 1 of strip 0, and a map's
    # phi0 outside the cone (m = 0.2: |phi0| <= 0.1974 rad), first in band 0 of strip 1 (0 -> 0.3 across)
    ({"specimen": {"width": 50.0, "gauge_length": 100.0, "strips": 2, "bands": 3},
      "zones": [{"courses": [1, 2], "wales": [0, 1], "knit": {"L": 9.0}}]},
     r"^knitsim: error: .*: 1 of 6 block\(s\) have no admissible rest state, e\.g\. band 1, strip 0: .*; that "
     r"block's C0 = 2\.7 \(knit\.C0\), W0 = 4\.4 \(knit\.W0\), L = 9\.0 \(zones\[0\]\.knit\.L\)"),
    ({"specimen": {"width": 50.0, "gauge_length": 100.0, "strips": 2, "bands": 3},
      "maps": {"phi0": {"type": "gradient", "axis": "wales", "start": 0.0, "end": 0.3}}},
     r"maps\.phi0 = 0\.3: must lie in .* at block \[band 0, strip 1\]$"),
])
def test_specimen_and_grades_refuse_bad_input_in_one_line(tmp_path, capsys, edit, match):
    doc = copy.deepcopy(SPECIMEN)
    doc.update(copy.deepcopy(edit))
    (tmp_path / "s.toml").write_text(dumps(doc))
    rc = main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    import re
    assert re.search(match, lines[0]), lines[0]
    assert not (tmp_path / "out").exists()


def test_progress_and_the_out_policy(tmp_path, capsys, e_glass_calibration):
    (tmp_path / "a.csv").write_text(CURVE)
    (tmp_path / "cal.toml").write_text(dumps(e_glass_calibration("bad input", starts=2)))
    out = tmp_path / "out"
    argv = ["calibrate", str(tmp_path / "cal.toml"), "--out", str(out)]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc in (0, 1), err
    # 1 own start + 2 Latin-hypercube starts screened; one start refined (at most 2 evaluations)
    assert "knitsim calibrate: starts screened: 3/3 (100%)" in err
    assert "knitsim calibrate: start 1/1: evaluations: 2/2 (100%)" in err
    assert (out / "calibration.json").is_file() and not (out / "calibration_checkpoint.pkl").exists()
    assert main(argv) == 2
    assert "); add --overwrite to replace them or --resume to continue it" in \
        capsys.readouterr().err
    assert main(argv + ["--resume"]) == 2
    assert "--resume: no checkpoint" in capsys.readouterr().err
    assert main(argv + ["--resume", "--overwrite"]) == 2
    assert "choose one" in capsys.readouterr().err
    assert main(argv + ["--overwrite", "--no-progress"]) in (0, 1)
    assert "starts screened" not in capsys.readouterr().err


def test_a_specimen_of_few_stitches_is_said_before_the_run_with_its_counts_and_the_sizes_in_cm(tmp_path, capsys):
    # 5 x 10 meant as cm: 5 / W0 = 5 / 4.4 = 1.136 wales x 10 / C0 = 10 / 2.7 = 3.704 courses, every wale at a free
    # edge (fewer than 3 across: no interior one); in mm 50 x 100, 11.36 x 37.04. Before: run without a word, the
    # console saying "5 mm wide"
    import json
    doc = copy.deepcopy(SPECIMEN)
    doc["specimen"] = {"width": 5.0, "gauge_length": 10.0}
    doc["output"] = {"plot": False, "cell_fields": False}
    (tmp_path / "s.toml").write_text(dumps(doc))
    rc = main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 0, err
    lines = err.splitlines()
    warned = [k for k, line in enumerate(lines) if "specimen 5 mm wide, 10 mm between the grips holds 1.136 wales "
              "x 3.704 courses: fewer than 3 stitches across" in line]
    assert len(warned) == 1, err                             # once, before the run's first line
    assert warned[0] < next(k for k, line in enumerate(lines) if line.startswith("knitsim run: specimen 5 mm wide"))
    assert "(width = 50, gauge_length = 100: 11.36 wales x 37.04 courses)" in lines[warned[0]]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert [w["code"] for w in summary["warnings"]].count("specimen_few_stitches") == 1
    # 3 wales and 3 courses hold an interior stitch: nothing said (13.2 = 3 x 4.4, 8.1 = 3 x 2.7)
    doc["specimen"] = {"width": 13.2, "gauge_length": 8.1}
    (tmp_path / "s.toml").write_text(dumps(doc))
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out3"), "--no-progress"]) == 0
    assert "specimen_few_stitches" not in (tmp_path / "out3" / "summary.json").read_text()
    assert "fewer than 3 stitches" not in capsys.readouterr().err
