"""Specimen scenes, material library files and blends of knits (issue 16).

Expected numbers are the tester's arithmetic: a band of length h holds h / C0 courses,
a strip of width s holds s / W0 wales; a linear blend at the centre of element k of n is
t = (k + 1/2) / n of the way from the first knit to the second, its L, W0, C0, phi0 the
weighted means and its yarn the one yarn of both.
"""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from knitsim.errors import KnitsimInputError
from knitsim.material_library import LibraryKnit, LibraryYarn, library_document, load_library
from knitsim.scene.cell_scene import load_cell_scene
from knitsim.scene.patch_scene import load_patch_scene
from knitsim.scene.schema import dumps

YARN = LibraryYarn("y", d=0.26, B=0.01, in_plane_width=0.28, friction={"model": "coulomb", "m": 0.3},
                   rules={"unloading_rule": "hong_constant_t"},
                   effects={"on": ["yarn_compaction"], "compaction_k": 10.0})
OTHER = LibraryYarn("z", d=0.2, B=0.02, friction={"model": "dahl", "m": 0.4, "dahl_sigma": 50.0})
A = LibraryKnit("a", "y", L=4.5, W0=1.2, C0=0.9, phi0=0.1)
B = LibraryKnit("b", "y", L=6.5, W0=1.7, C0=1.3, phi0=-0.1)
Z = LibraryKnit("c", "z", L=5.0, W0=1.3, C0=1.0)
LOAD = {"type": "monotonic", "target_strain": 0.2, "max_increment": 0.05}


@pytest.fixture
def lib(tmp_path):
    path = tmp_path / "materials.toml"
    path.write_text(dumps(library_document([YARN, OTHER], [A, B, Z], title="test library")))
    return path


def specimen(lib, **extra):
    doc = {"materials": str(lib), "specimen": {"width": 50.0, "gauge_length": 100.0},
           "knit": {"material": "a"}, "load": LOAD}
    doc.update(extra)
    return doc


def test_library_round_trip(lib):
    got = load_library(lib)
    assert got.yarns["y"] == YARN and got.knits["b"] == B and got.knits["c"] == Z


def test_library_refuses_a_knit_of_an_unknown_yarn(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(dumps(library_document([YARN], [LibraryKnit("q", "nope", 4.0, 1.0, 0.8)])))
    with pytest.raises(KnitsimInputError, match=r"knits\.q\.yarn = 'nope': not a yarn"):
        load_library(path)


def test_cell_scene_takes_the_knit_and_its_yarn_from_the_library(lib):
    s = load_cell_scene({"materials": str(lib), "knit": {"material": "a"}, "load": LOAD})
    p = s.params[0]
    assert (p.L, p.W0, p.C0, p.phi0) == (4.5, 1.2, 0.9, 0.1)
    assert (p.d, p.B, p.in_plane_width, p.m) == (0.26, 0.01, 0.28, 0.3)
    assert p.unloading_rule == "hong_constant_t"
    assert p.effects.on == ("yarn_compaction",) and p.effects.compaction_k == 10.0
    # the scene's own keys win; the resolved scene is explicit (no library needed to reload it)
    s2 = load_cell_scene({"materials": str(lib), "knit": {"material": "a"}, "friction": {"m": 0.5, "phi0": 0.0},
                          "load": LOAD})
    assert s2.params[0].m == 0.5 and s2.params[0].phi0 == 0.0
    again = load_cell_scene(tomllib.loads(s.to_toml()))
    assert again.params == s.params
    with pytest.raises(KnitsimInputError, match=r"knit\.material = 'nope': unknown knit"):
        load_cell_scene({"materials": str(lib), "knit": {"material": "nope"}, "load": LOAD})
    with pytest.raises(KnitsimInputError, match=r"^materials = .*no such material library file"):
        load_cell_scene({"materials": "missing.toml", "knit": {"material": "a"}, "load": LOAD})


def test_counts_follow_from_width_gauge_W0_and_C0(lib):
    """Two halves across the width: the half of shorter loops has more courses between the same grips."""
    s = load_patch_scene(specimen(lib, specimen={"width": 50.0, "gauge_length": 100.0, "strips": 2},
                                  zones=[{"wales": [1, 2], "knit": {"material": "b"}}]))
    m = s.model
    np.testing.assert_array_equal(m.course_count, [[100.0 / 0.9, 100.0 / 1.3]])
    np.testing.assert_array_equal(m.wale_count, [[25.0 / 1.2, 25.0 / 1.7]])
    np.testing.assert_allclose(m.column_rest_length(), [100.0, 100.0], rtol=1e-15)
    assert m.gauge_length == 100.0
    # the resolved scene reloads to the same specimen without the library
    again = load_patch_scene(tomllib.loads(s.to_toml()))
    np.testing.assert_array_equal(again.model.course_count, m.course_count)
    assert again.model.cell(0, 1) == m.cell(0, 1)


def test_linear_blend_along_the_wale(lib):
    s = load_patch_scene(specimen(lib, specimen={"width": 50.0, "gauge_length": 100.0, "bands": 4},
                                  grades=[{"from": "a", "to": "b", "axis": "courses"}]))
    t = (np.arange(4) + 0.5) / 4
    f = s.model.fields
    np.testing.assert_allclose(f["L"][:, 0], 4.5 + 2.0 * t, rtol=1e-15)
    np.testing.assert_allclose(f["W0"][:, 0], 1.2 + 0.5 * t, rtol=1e-15)
    np.testing.assert_allclose(f["C0"][:, 0], 0.9 + 0.4 * t, rtol=1e-15)
    np.testing.assert_allclose(f["phi0"][:, 0], 0.1 - 0.2 * t, rtol=1e-12, atol=1e-16)
    # one yarn throughout: not a ramp of the yarn's numbers
    assert np.all(f["B"] == 0.01) and np.all(f["d"] == 0.26) and np.all(f["m"] == 0.3)
    assert all(e.on == ("yarn_compaction",) for e in s.model.effects.ravel())
    np.testing.assert_allclose(s.model.course_count[:, 0], 25.0 / f["C0"][:, 0], rtol=1e-15)
    np.testing.assert_allclose(s.model.wale_count[:, 0], 50.0 / f["W0"][:, 0], rtol=1e-15)


def test_step_blend_across_the_width(lib):
    s = load_patch_scene(specimen(lib, specimen={"width": 50.0, "gauge_length": 100.0, "strips": 4},
                                  grades=[{"from": "a", "to": "b", "axis": "wales", "profile": "step",
                                           "steps": 2}]))
    np.testing.assert_array_equal(s.model.fields["L"][0], [4.5, 4.5, 6.5, 6.5])


def test_blend_fractions_set_the_ends_of_a_grade(lib):
    """fractions = [a, b]: the blend runs from a to b along the axis, t = a + (b - a)(k + 1/2)/n; a == b is a
    uniform blend (a knit between two calibrated knits of one yarn)."""
    s = load_patch_scene(specimen(lib, specimen={"width": 50.0, "gauge_length": 100.0, "bands": 4},
                                  grades=[{"from": "a", "to": "b", "axis": "courses", "fractions": [0.2, 0.6]}]))
    t = 0.2 + 0.4 * (np.arange(4) + 0.5) / 4
    np.testing.assert_allclose(s.model.fields["L"][:, 0], 4.5 + 2.0 * t, rtol=1e-15)
    u = load_patch_scene(specimen(lib, grades=[{"from": "a", "to": "b", "axis": "wales", "fractions": [0.25, 0.25]}]))
    assert u.model.fields["W0"][0, 0] == pytest.approx(0.75 * 1.2 + 0.25 * 1.7, rel=1e-15)
    assert u.model.fields["phi0"][0, 0] == pytest.approx(0.75 * 0.1 - 0.25 * 0.1, rel=1e-12)


def test_blends_need_one_yarn_and_specimens_their_size(lib):
    with pytest.raises(KnitsimInputError, match=r"^grades\[0\]\.to = \"c\": a grade blends knits of one yarn"):
        load_patch_scene(specimen(lib, grades=[{"from": "a", "to": "c", "axis": "courses"}]))
    with pytest.raises(KnitsimInputError, match=r"^specimen\.gauge_length: missing"):
        load_patch_scene(specimen(lib, specimen={"width": 50.0}))
    with pytest.raises(KnitsimInputError, match=r"^patch\.wales = 3: give either \[patch\]"):
        load_patch_scene(specimen(lib, patch={"wales": 3}))
    with pytest.raises(KnitsimInputError, match=r"^patch\.wales: missing required key"):
        load_patch_scene({"knit": {"material": "e_glass_plain"}, "yarn": {"material": "e_glass"}, "load": LOAD})


def test_maps_of_effect_parameters_set_each_cells_effects():
    """A map of an effect parameter sets it where the effect is on (the effects are a material's, per cell)."""
    doc = {"patch": {"wales": 3, "courses": 2}, "yarn": {"material": "e_glass"},
           "knit": {"material": "e_glass_plain"}, "friction": {"m": 0.2},
           "zones": [{"wales": [1, 3], "effects": {"on": ["yarn_compaction"], "compaction_k": 5.0}}],
           "maps": {"compaction_k": {"type": "gradient", "axis": "wales", "start": 1.0, "end": 3.0}},
           "load": LOAD}
    s = load_patch_scene(doc)
    e = s.model.effects
    assert e[0, 0].on == () and e[0, 0].compaction_k == 0.0          # no compaction there: untouched
    assert (e[1, 1].compaction_k, e[1, 2].compaction_k) == (2.0, 3.0)
    again = load_patch_scene(tomllib.loads(s.to_toml()))
    assert again.model.cell(1, 2) == s.model.cell(1, 2)
    doc["zones"] = []
    with pytest.raises(KnitsimInputError, match=r"no cell has the effect yarn_compaction on"):
        load_patch_scene(doc)


def test_a_zone_outside_a_specimens_strips_or_bands_names_them(lib):
    # a blind probe's specimen of 10 wales in 2 strips was told "the patch has 2 wales"
    doc = specimen(lib, zones=[{"wales": [2, 3], "knit": {"material": "b"}}])
    doc["specimen"].update(strips=2, bands=1)
    with pytest.raises(KnitsimInputError, match=r"zones\[0\]\.wales = \[2, 3\]: expected 0 <= start < stop <= 2 "
                                                r"\(the specimen has 2 strips\)"):
        load_patch_scene(doc)
    doc = specimen(lib, zones=[{"courses": [0, 5], "knit": {"material": "b"}}])
    doc["specimen"].update(strips=2, bands=1)
    with pytest.raises(KnitsimInputError, match=r"\(the specimen has 1 bands\)"):
        load_patch_scene(doc)


@pytest.mark.parametrize("friction, rules, msg", [
    ({"model": "coloumb", "m": 0.2}, {}, r"yarns\.z\.friction\.model = 'coloumb': expected one of coulomb, dahl"),
    ({"model": "dahl", "m": 0.3, "dahl_sigma": 0.0}, {}, r"yarns\.z\.friction\.dahl_sigma = 0\.0: friction\.model = \"dahl\" needs"),
    ({"model": "coulomb", "m": -0.1}, {}, r"yarns\.z\.friction\.m = -0\.1: the friction ratio must be >= 0"),
    ({"m": 0.2}, {"unloading_rule": "hong"}, r"yarns\.z\.rules\.unloading_rule = 'hong': expected one of"),
    ({"m": 0.2}, {"force_cap_N": -1.0}, r"yarns\.z\.rules\.force_cap_N = -1\.0: must be > 0"),
    # a key the scene's table of that name does not hold: refused as the scene's friction.mu before (a blind probe)
    ({"mu": 0.2}, {}, r"yarns\.z\.friction\.mu = 0\.2: unknown key \(expected one of model, m, mu_k, "),
    ({"m": 0.2}, {"force_cap": 3.0}, r"yarns\.z\.rules\.force_cap = 3\.0: unknown key \(expected one of "),
    ({"m": 0.2, "phi0": "zero"}, {}, r"yarns\.z\.friction\.phi0 = \"zero\": expected a number \[rad\]"),
])
def test_a_bad_law_in_a_library_yarn_names_the_file(tmp_path, friction, rules, msg):
    # a blind probe's typo in a library yarn was reported as the scene's zones[0].friction.model
    path = tmp_path / "lib.toml"
    path.write_text(dumps(library_document([LibraryYarn("z", d=0.2, B=0.02, friction=friction, rules=rules)],
                                           [LibraryKnit("k", "z", 4.0, 1.0, 0.8)])))
    with pytest.raises(KnitsimInputError, match=str(path).replace(".", r"\.") + ": " + msg):
        load_library(path)


def test_an_unknown_effect_key_in_a_library_yarn_names_the_file(tmp_path):
    # the yarn's effects fill the scene's [effects]: a misspelt parameter was refused as the scene's effects key
    path = tmp_path / "lib.toml"
    path.write_text(dumps(library_document([LibraryYarn("z", d=0.2, B=0.02, friction={"m": 0.2},
                                                        effects={"on": ["yarn_compaction"], "compaction": 12.0})],
                                           [LibraryKnit("k", "z", 4.0, 1.0, 0.8)])))
    with pytest.raises(KnitsimInputError, match=str(path).replace(".", r"\.") + r": yarns\.z\.effects\.compaction = "
                                                "12\\.0: unknown key"):
        load_library(path)


def test_a_library_value_a_scene_check_refuses_names_its_library_entry(tmp_path):
    """A knit of the library jammed at rest with its yarn (W0 = 1.0 < 4 d = 1.04 mm), and a phi0 given in degrees
    (5, beyond atan 0.3 = 0.29 rad): a blind probe read "knit.W0 = 0.44: must be >= 4 d" of a scene that states
    no W0. Expected: the scene's key, the library entry and file that gave it (cell scene, patch, a zone)."""
    path = tmp_path / "lib.toml"
    path.write_text(dumps(library_document([YARN], [LibraryKnit("tight", "y", L=4.5, W0=1.0, C0=0.9),
                                                    LibraryKnit("deg", "y", L=4.5, W0=1.2, C0=0.9, phi0=5.0), A])))
    src = str(path).replace(".", r"\.")
    w0 = rf"^knit\.W0 \(from knits\.tight of {src}\) = 1\.0: must be >= 4 d = 1\.04 mm \(yarn\.d \(from yarns\.y "
    with pytest.raises(KnitsimInputError, match=w0):
        load_cell_scene({"materials": str(path), "knit": {"material": "tight"}, "load": LOAD})
    with pytest.raises(KnitsimInputError, match=w0):
        load_patch_scene({"materials": str(path), "patch": {"wales": 2, "courses": 2},
                          "knit": {"material": "tight"}, "load": LOAD})
    with pytest.raises(KnitsimInputError, match=rf"^friction\.phi0 \(from knits\.deg of {src}\) = 5\.0: must lie in "
                                                r".*5 looks like degrees.* \(in zones\[0\]\)$"):
        load_patch_scene({"materials": str(path), "patch": {"wales": 2, "courses": 2}, "knit": {"material": "a"},
                          "zones": [{"wales": [0, 1], "knit": {"material": "deg"}}], "load": LOAD})
    # a value the scene states itself is named as before
    with pytest.raises(KnitsimInputError, match=r"^knit\.W0 = 1\.0: must be >= 4 d"):
        load_cell_scene({"materials": str(path), "knit": {"material": "a", "W0": 1.0}, "load": LOAD})
