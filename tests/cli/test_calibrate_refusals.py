"""``knitsim calibrate`` refuses, before it prints or writes anything, a scene the fit would refuse and a
strain the specimen's knit cannot reach (a column in per cent).

The scenes and curves are written here by hand: Dusserre's E-glass knit L = 14.1, C0 = 2.7 mm, whose
quarter-stitch cell is a straight yarn at C = C0 (1 + strain) = L/2, i.e. at strain L / (2 C0) - 1 = 1.611
(the expected limits below are that formula, worked by hand, with the bounds each scene gives).
"""
from __future__ import annotations

import re

import pytest

from knitsim.calibration.scene import load_calibration_scene
from knitsim.cli import main
from knitsim.errors import KnitsimInputError
from knitsim.scene.schema import dumps


def _curve(top, n=11):
    """n rows from strain 0 to ``top`` (header row 1, so the last data row is spreadsheet row n + 1)."""
    return "strain,load_N\n" + "".join(f"{top * k / (n - 1)!r},{0.5 * k}\n" for k in range(n))


def _run(tmp_path, capsys, doc, curve):
    (tmp_path / "a.csv").write_text(curve)
    (tmp_path / "cal.toml").write_text(dumps(doc))
    rc = main(["calibrate", str(tmp_path / "cal.toml"), "--out", str(tmp_path / "out")])
    cap = capsys.readouterr()
    return rc, cap


def _one_line_refusal(tmp_path, rc, cap):
    assert rc == 2, cap.err
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("knitsim: error: "), cap.err    # no progress header first
    assert "Traceback" not in cap.err and cap.out == ""
    assert not (tmp_path / "out").exists()
    return lines[0]


def test_strain_in_per_cent_is_refused_naming_file_row_column_and_value(tmp_path, capsys, e_glass_calibration):
    """Strains 0..20 (per cent of 0..0.2): 20 >= 1.611, refused at the file's largest strain, row 12."""
    rc, cap = _run(tmp_path, capsys, e_glass_calibration("refusals"), _curve(20.0))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert re.search(r"specimens\[0\]: .*a\.csv: row 12, column strain: 20 is a strain the specimen's knit "
                     r"cannot reach", line), line
    assert "grip strain < 1.611" in line
    assert "Is the column in per cent? A strain of 5 % is 0.05." in line


def test_a_strain_below_one_beyond_reach_is_refused_without_the_per_cent_hint(tmp_path, e_glass_calibration):
    doc = e_glass_calibration("refusals")
    (tmp_path / "a.csv").write_text(_curve(0.9))
    doc["specimens"][0]["knit"]["C0"] = 4.0            # 14.1 / 8 - 1 = 0.7625 < 0.9
    (tmp_path / "cal.toml").write_text(dumps(doc))
    with pytest.raises(KnitsimInputError, match=r"0\.9 is a strain .*grip strain < 0\.7625\)\.$"):
        load_calibration_scene(tmp_path / "cal.toml")


def test_the_reach_is_the_loosest_the_fit_allows(tmp_path, e_glass_calibration):
    """Strain 1.7: beyond 1.611 with L and C0 as stated; within reach when L may rise to 14.1 e^(4 x 0.02)
    = 15.27 mm (1.829); beyond again through a pretension of up to 0.2: (1 + 1.611) / 1.2 - 1 = 1.176 with
    L, C0 as stated (strain 1.3 < 1.611 then refused)."""
    (tmp_path / "a.csv").write_text(_curve(1.7))
    doc = e_glass_calibration("refusals")
    (tmp_path / "cal.toml").write_text(dumps(doc))
    with pytest.raises(KnitsimInputError, match=r"1\.7 is a strain .*grip strain < 1\.611"):
        load_calibration_scene(tmp_path / "cal.toml")
    doc["calibration"]["per_specimen"] = ["L"]
    doc["specimens"][0]["uncertainty"] = {"L": 0.02}
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")       # L at its upper bound reaches it
    doc = e_glass_calibration("refusals")
    doc["calibration"]["per_specimen"] = ["pretension"]
    doc["calibration"]["bounds"] = {"pretension": [0.0, 0.2]}
    doc["specimens"][0]["pretension_sd"] = 0.01
    (tmp_path / "a.csv").write_text(_curve(1.3))
    (tmp_path / "cal.toml").write_text(dumps(doc))
    with pytest.raises(KnitsimInputError, match=r"1\.3 is a strain .*pretension of 0\.2.*grip strain < 1\.176"):
        load_calibration_scene(tmp_path / "cal.toml")
    doc["calibration"]["bounds"] = {"pretension": [0.0, 0.05]}     # (2.611 / 1.05) - 1 = 1.487 > 1.3
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")


def test_an_unknown_shared_variable_is_refused_before_anything_is_printed(tmp_path, capsys, e_glass_calibration):
    doc = e_glass_calibration("refusals")
    doc["calibration"]["shared"] = ["B", "bogus"]
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert "calibration.shared: 'bogus' is not a yarn variable" in line


@pytest.mark.parametrize("name, bounds, where", [("d", [0.01, 50.0], "calibration.shared"),
                                                  ("W0", [0.9, 1.1], "calibration.per_specimen")])
def test_bounds_of_a_variable_not_fitted_are_refused(tmp_path, capsys, e_glass_calibration, name, bounds, where):
    """A bound on d while d is not in calibration.shared (the user believes d fitted within it): before, the fit
    ran to the end with d held at its start, the bound binding nothing, and nothing said."""
    doc = e_glass_calibration("refusals")
    doc["calibration"].setdefault("bounds", {})[name] = bounds
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert f"calibration.bounds.{name} = {bounds}: {name} is not fitted (not in {where})" in line


def test_a_tail_cut_off_with_end_strain_is_not_refused(tmp_path, e_glass_calibration):
    # a test run on to strain 1.8, past what the knit reaches (1.611 for L = 14.1, C0 = 2.7), with the fit
    # stopped at 0.2 by end_strain: the tail is not fitted, so the file is read (a lab keeps its whole record)
    doc = e_glass_calibration("refusals")
    (tmp_path / "a.csv").write_text("strain,load_N\n" + "".join(f"{0.02 * k!r},{0.5 * k}\n" for k in range(91)))
    doc["specimens"][0]["end_strain"] = 0.2
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")


def test_a_band_with_one_file_in_per_cent_is_refused(tmp_path, e_glass_calibration):
    # the two envelopes of one specimen's scatter cover one test: one ending at 20 and the other at 0.2
    # (the same test in per cent) end 100 times apart
    doc = e_glass_calibration("refusals")
    spec = doc["specimens"][0]
    del spec["curve"], spec["noise_N"]
    spec["band"] = ["lo.csv", "hi.csv"]
    (tmp_path / "lo.csv").write_text(_curve(0.2))
    (tmp_path / "hi.csv").write_text(_curve(20.0).replace(",0.5", ",0.6"))
    (tmp_path / "cal.toml").write_text(dumps(doc))
    with pytest.raises(KnitsimInputError, match=r"ten times apart or more\. Is the column in per cent"):
        load_calibration_scene(tmp_path / "cal.toml")


@pytest.mark.parametrize("shared, bounds, expect", [
    # a blind probe's start B = 5 (the scene's) with bounds [0.05, 2]: before, started from 2 without a word
    (["B", "m"], {"B": [0.05, 2.0]}, "B's start, the scene's 5 N mm^2, lies outside its bounds [0.05, 2]"),
    # the scene's m 0.3 above bounds [0.4, 0.9]
    (["B", "m"], {"m": [0.4, 0.9]}, "m's start, the scene's 0.3, lies outside its bounds [0.4, 0.9]"),
    # m bounds beyond the cell's domain (M_MAX = 5: phimax above 79 deg)
    (["B", "m"], {"m": [0.0, 100.0]}, "calibration.bounds.m = [0.0, 100.0]: expected 0 <= low < high <= 5"),
])
def test_a_start_outside_its_bounds_and_an_absurd_range_are_refused(tmp_path, capsys, e_glass_calibration, shared,
                                                                   bounds, expect):
    doc = e_glass_calibration("refusals")
    if "B" in bounds:
        doc["yarn"]["B"] = 5.0
    doc["calibration"]["shared"] = shared
    doc["calibration"]["bounds"] = bounds
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert expect in line, line


@pytest.mark.parametrize("phi0, bounds, expect", [
    # 5 degrees typed as radians: phimax = atan(0.3) = 0.2915 rad (the fixture's m); 5 deg = 0.08727 rad.  Before,
    # the start was clipped to +phimax without a word, while B, d, the width and m starts out of range were refused
    (5.0, None, "specimens[0].phi0 = 5 rad: specimen tight's phi0 start lies outside its range [-0.2915, 0.2915] "
                "rad (+-phimax = atan(m), m = 0.3 the start) (in degrees it would be 0.08727 rad)"),
    # inside +-phimax, outside bounds.phi0 = [-0.5, 0.5] of it: +-0.1457 rad
    (0.2, [-0.5, 0.5], "specimens[0].phi0 = 0.2 rad: specimen tight's phi0 start lies outside its range "
                       "[-0.1457, 0.1457] rad (calibration.bounds.phi0 x phimax, m = 0.3 the start)"),
    # a start m of 0 (no friction: phimax = 0) leaves phi0 no room: before, its start was set to 0 without a word
    (0.05, "m0", "specimens[0].phi0 = 0.05 rad: specimen tight's phi0 start lies outside its range [0, 0] rad "
                 "(+-phimax = atan(m), m = 0 the start)"),
])
def test_a_phi0_start_outside_its_range_is_refused(tmp_path, capsys, e_glass_calibration, phi0, bounds, expect):
    doc = e_glass_calibration("refusals")
    if bounds == "m0":
        doc["friction"]["m"], bounds = 0.0, None
    doc["calibration"]["per_specimen"] = ["phi0"]
    doc["specimens"][0]["phi0"] = phi0
    if bounds:
        doc["calibration"]["bounds"] = {"phi0": bounds}
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert expect in line, line


def test_a_phi0_start_inside_its_range_is_not_refused(tmp_path, e_glass_calibration):
    from knitsim.calibration.joint import check_setup
    doc = e_glass_calibration("inside")
    doc["calibration"]["per_specimen"] = ["phi0"]
    doc["specimens"][0]["phi0"] = -0.29            # within -0.2915
    (tmp_path / "a.csv").write_text(_curve(0.2))
    (tmp_path / "cal.toml").write_text(dumps(doc))
    scene = load_calibration_scene(tmp_path / "cal.toml")
    check_setup(scene.specimens, scene.setup)


def test_a_start_inside_its_bounds_is_not_refused(tmp_path, e_glass_calibration):
    # the fixture's B 0.31 and m 0.3 inside [0.05, 2] and [0.1, 0.9]: the scene loads and its setup is accepted
    from knitsim.calibration.joint import check_setup
    doc = e_glass_calibration("inside")
    doc["calibration"]["bounds"] = {"B": [0.05, 2.0], "m": [0.1, 0.9]}
    (tmp_path / "a.csv").write_text(_curve(0.2))
    (tmp_path / "cal.toml").write_text(dumps(doc))
    scene = load_calibration_scene(tmp_path / "cal.toml")
    check_setup(scene.specimens, scene.setup)


def test_an_uncertainty_of_a_geometry_not_fitted_is_refused(tmp_path, capsys, e_glass_calibration):
    """uncertainty.L = 0.02 while L is not in calibration.per_specimen: before, the fit held L at its stated
    value exactly, the uncertainty ignored without a word (a probe's L stated 1 % off: one yarn read as two,
    p = 1e-12); a zero uncertainty (known) and a fitted L are accepted."""
    doc = e_glass_calibration("refusals")
    doc["specimens"][0]["uncertainty"] = {"L": 0.02}
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert ("specimens[0].uncertainty.L = 0.02: L is not fitted (not in calibration.per_specimen), so the fit "
            "would hold it at its stated 14.1 mm exactly") in line, line
    doc["specimens"][0]["uncertainty"] = {"L": 0.0}
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")
    doc["specimens"][0]["uncertainty"] = {"L": 0.02}
    doc["calibration"]["per_specimen"] = ["L"]
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")


@pytest.mark.parametrize("shared", [["B", "m"], ["B", "m", "in_plane_width"]])
def test_a_later_specimens_knit_that_is_no_cell_is_refused_naming_it(tmp_path, capsys, e_glass_calibration, shared):
    """The second specimen's W0 given in cm (0.44 for 4.4 mm): W0 < 4 x the in-plane width 0.79 mm (the cell's own
    check, Hong 2002: loops jammed at rest).  Before, only the first specimen's knit was checked: with shared
    B, m the fit ran to the end and stopped on a RuntimeError traceback ("the calibrated point is not an
    admissible cell"); with the in-plane width fitted it was refused as that width's start outside "[0.79,
    0.11]"."""
    doc = e_glass_calibration("refusals")
    doc["calibration"]["shared"] = shared
    doc["specimens"].append(dict(doc["specimens"][0], name="loose", curve="b.csv",
                                 knit={"L": 14.1, "W0": 0.44, "C0": 2.7}))
    (tmp_path / "b.csv").write_text(_curve(0.2).replace(",0.5", ",0.6"))
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert "specimens[1].knit: the start yarn on specimen loose's knit as stated: " in line, line
    assert "loops jammed at rest: W0 = 0.44 < 4 in_plane_width" in line, line


def test_every_refusal_names_a_specimen_by_its_key_path(tmp_path, capsys, e_glass_calibration):
    """A second specimen, "loose" ([[specimens]] table 1 from 0): refusals made while its file is read named it
    specimens[1] (``specimens[1].curve: ...``) and those of the fit's checks specimens.loose (its strain beyond
    reach, its uncertainty of a geometry not fitted, a copy of the first specimen's file).  Expected: every one
    names it by the key path the scene's checks and ``--set specimens[1].width=...`` use, specimens[1]."""
    doc = e_glass_calibration("refusals")
    doc["specimens"].append(dict(doc["specimens"][0], name="loose", curve="b.csv"))
    cases = [("b.csv", "strain,load_N\n0,0\n0.1,x\n0.2,1\n0.3,2\n", {}, "specimens[1].curve: "),
             ("b.csv", _curve(20.0), {}, "specimens[1]: "),
             ("b.csv", _curve(0.2).replace(",0.5", ",0.6"), {"uncertainty": {"L": 0.02}},
              "specimens[1].uncertainty.L = 0.02: "),
             ("b.csv", _curve(0.2), {}, "specimens[1].curve: ")]
    for name, text, keys, expect in cases:
        (tmp_path / name).write_text(text)
        doc["specimens"][1] = dict(doc["specimens"][0], name="loose", curve="b.csv", **keys)
        rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
        line = _one_line_refusal(tmp_path, rc, cap)
        assert line.startswith(f"knitsim: error: {expect}") or f": {expect}" in line, line
        assert "specimens.loose" not in line, line


@pytest.mark.parametrize("name, expect", [
    ("tight/2", "specimens[0].name = \"tight/2\": holds '/', which no file name may hold"),
    ("  ", "specimens[0].name = \"  \": empty"),
    # fit_NAME.png, NAME.cell.toml, NAME.patch.toml: the longest is NAME + 11 bytes, 246 + 11 = 257 > 255
    ("t" * 246, "the longest of them 257 bytes, more than a file name may have (255)"),
])
def test_a_specimen_name_that_cannot_name_its_files_is_refused(tmp_path, capsys, e_glass_calibration, name, expect):
    """The specimen's name names the files written for it: before, "tight/2" ran the whole fit and stopped on a
    FileNotFoundError traceback when writing tight/2.cell.toml, and a 250-character name on "File name too
    long" (OSError)."""
    doc = e_glass_calibration("refusals")
    doc["specimens"][0]["name"] = name
    rc, cap = _run(tmp_path, capsys, doc, _curve(0.2))
    line = _one_line_refusal(tmp_path, rc, cap)
    assert expect in line, line


def test_a_specimen_name_of_the_longest_file_name_is_accepted(tmp_path, e_glass_calibration):
    """244 bytes + ".patch.toml" = 255 bytes, the most a file name may have: accepted."""
    doc = e_glass_calibration("refusals")
    doc["specimens"][0]["name"] = "t" * 244
    (tmp_path / "a.csv").write_text(_curve(0.2))
    (tmp_path / "cal.toml").write_text(dumps(doc))
    load_calibration_scene(tmp_path / "cal.toml")
    (tmp_path / ("t" * 244 + ".patch.toml")).write_text("")      # the file system takes it
