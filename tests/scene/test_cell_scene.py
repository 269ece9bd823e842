"""Cell scenes: paper scenes, library look-ups, eq 10, phi0 forms, cross-field checks, batches, round trip."""
from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import pytest

from knitsim.errors import KnitsimInputError
from knitsim.scene.cell_scene import load_cell_scene

REPO = Path(__file__).resolve().parents[2]
PAPER = sorted((REPO / "scenes" / "paper").glob("*.toml"))

BASE = {
    "engine": "reference",
    "yarn": {"material": "e_glass"},
    "knit": {"material": "e_glass_plain"},
    "friction": {"m": 0.2},
    "load": {"type": "monotonic", "target_strain": 0.5, "max_increment": 0.05},
}


def scene(**changes):
    d = copy.deepcopy(BASE)
    for dotted, v in changes.items():
        *head, last = dotted.split("__")
        node = d
        for h in head:
            node = node.setdefault(h, {})
        if v is None:
            node.pop(last, None)
        else:
            node[last] = v
    return d


def refused(data, match, overrides=()):
    with pytest.raises(KnitsimInputError, match=match) as info:
        load_cell_scene(data, list(overrides))
    assert "\n" not in str(info.value)


def test_paper_scenes_present_and_valid():
    names = {p.name for p in PAPER}
    assert names == {"e_glass_monotonic.toml", "basalt_monotonic.toml", "e_glass_cyclic.toml",
                     "e_glass_cyclic_constant_t.toml"}
    s = {p.stem: load_cell_scene(p) for p in PAPER}
    # Table 1 / section 2.2 / section 3.4 values reach the cell
    e = s["e_glass_monotonic"].params[0]
    assert (e.d, e.B, e.L, e.W0, e.C0, e.m, e.phi0, e.force_cap_N) == (0.58, 0.31, 14.1, 4.4, 2.7, 0.20, 0.0, 10.0)
    b = s["basalt_monotonic"].params[0]
    assert (b.d, b.B, b.L, b.m) == (0.56, 0.20, 13.1, 0.17)
    # section 2.3: 3 cycles between 0.10 and 0.60 (waypoints 0, 0.6, 0.1, 0.6, 0.1, 0.6, 0.1)
    c = s["e_glass_cyclic"]
    assert c.program.waypoints == (0.0, 0.6, 0.1, 0.6, 0.1, 0.6, 0.1)
    # at 0.005: 0.6/0.005 = 120 up, then 5 branches of 0.5/0.005 = 100
    assert len(c.program) == 120 + 5 * 100
    assert c.params[0].unloading_rule == "dusserre"
    assert s["e_glass_cyclic_constant_t"].params[0].unloading_rule == "hong_constant_t"
    assert s["e_glass_cyclic_constant_t"].params[0].replace(unloading_rule="dusserre") == c.params[0]
    assert all(x.engine == "warp" for x in s.values())


def test_explicit_keys_override_the_library():
    p = load_cell_scene(scene(yarn__B=0.25, knit__L=15.0)).params[0]
    assert (p.B, p.d, p.L, p.W0) == (0.25, 0.58, 15.0, 4.4)
    p = load_cell_scene(scene(yarn={"d": 0.5, "B": 0.3}, knit={"L": 14.0, "W0": 4.0, "C0": 2.5})).params[0]
    assert (p.d, p.B, p.L, p.W0, p.C0) == (0.5, 0.3, 14.0, 4.0, 2.5)


def test_m_from_eq10_and_from_library():
    # eq 10: m = (e^{mu theta} - 1)/(e^{mu theta} + 1) tan(theta/2), mu_k = 0.156, theta = 110 deg
    # (section 3.4); by hand: exp(0.156 * 1.91986) = 1.34913, tanh part 0.14862, tan(55 deg) = 1.42815
    s = load_cell_scene(scene(friction={"mu_k": 0.156, "coiling_angle_deg": 110.0}))
    assert s.params[0].m == pytest.approx(0.14862 * 1.42815, rel=2e-4)
    assert s.params[0].m == pytest.approx(0.212, abs=5e-4)     # coiling.py: "0.212, not the paper's 0.20"
    # the coiling angle defaults to the yarn material's mean (110 deg for E-glass, section 3.4)
    assert load_cell_scene(scene(friction={"mu_k": 0.156})).params[0].m == s.params[0].m
    # no m at all: the yarn's section 3.4 value
    assert load_cell_scene(scene(friction={})).params[0].m == 0.20


def test_phi0_forms():
    phimax = math.atan(0.2)
    assert load_cell_scene(scene(friction__phi0="phimax")).params[0].phi0 == phimax
    assert load_cell_scene(scene(friction__phi0="-phimax")).params[0].phi0 == -phimax
    assert load_cell_scene(scene(friction__phi0_deg=5.0)).params[0].phi0 == pytest.approx(math.radians(5.0))
    refused(scene(friction__phi0=0.3), r"^friction\.phi0 = 0\.3: must lie in \[-phimax, phimax\] = \[-0\.1974, 0\.1974\] rad")
    refused(scene(friction__phi0=0.0, friction__phi0_deg=1.0),
            r"^friction\.phi0_deg = 1\.0: give one of friction\.phi0, phi0_deg and phi0_fraction, not phi0 and phi0_deg")
    # a friction angle beyond pi/2 rad cannot be one (phimax = atan(m) < pi/2): 30 is said to look like degrees
    # (a blind probe's phi0 = 30 was refused by the bound alone); 0.3 rad is not, and phi0_deg = 30 is degrees
    refused(scene(friction__phi0=30), r"^friction\.phi0 = 30\.0: .* rad \(= \+/-11\.31 deg, m = 0\.2\); 30 looks like "
                                      r"degrees: phi0 is in radians \(30 deg = 0\.5236 rad; friction\.phi0_deg")
    with pytest.raises(KnitsimInputError) as e:
        load_cell_scene(scene(friction__phi0=0.3))
    assert "looks like degrees" not in str(e.value)
    with pytest.raises(KnitsimInputError) as e:
        load_cell_scene(scene(friction__phi0_deg=30.0))
    assert "looks like degrees" not in str(e.value)


def test_phi0_as_a_fraction_of_phimax():
    # phi0 = fraction x phimax, phimax = atan(m) (eq 10's cone): the identity at m = 0.2 and at eq 10's m
    assert load_cell_scene(scene(friction__phi0_fraction=0.5)).params[0].phi0 == pytest.approx(0.5 * math.atan(0.2))
    p = load_cell_scene(scene(friction={"mu_k": 0.156, "coiling_angle_deg": 110.0, "phi0_fraction": -1.0})).params[0]
    assert p.phi0 == pytest.approx(-math.atan(p.m), rel=1e-15)
    refused(scene(friction__phi0_fraction=1.2), r"^friction\.phi0_fraction = 1\.2: must be <= 1")
    refused(scene(friction__phi0_fraction=0.1, friction__phi0_deg=1.0), r"^friction\.phi0_fraction = 0\.1: give one of")
    # a batch cell stating phi0 another way drops the base's
    d = scene(friction__phi0=0.1)
    d["cells"] = [{}, {"friction": {"phi0_fraction": 0.25}}, {"friction": {"phi0_deg": 2.0}}]
    s = load_cell_scene(d)
    assert [c.phi0 for c in s.params] == pytest.approx([0.1, 0.25 * math.atan(0.2), math.radians(2.0)])


def test_set_replaces_the_scenes_other_way_of_stating_a_quantity():
    # before: --set friction.phi0_deg=3 on a scene with phi0 = 0 was refused as both given
    s = load_cell_scene(scene(friction__phi0=0.0), ["friction.phi0_deg=3"])
    assert s.params[0].phi0 == pytest.approx(math.radians(3.0))
    s = load_cell_scene(scene(friction__phi0_deg=3.0), ["friction.phi0_fraction=-0.5"])
    assert s.params[0].phi0 == pytest.approx(-0.5 * math.atan(0.2))
    # m stated by eq 10 in the scene, replaced by an explicit m (and the other way round)
    s = load_cell_scene(scene(friction={"mu_k": 0.156, "coiling_angle_deg": 110.0}), ["friction.m=0.3"])
    assert s.params[0].m == 0.3
    s = load_cell_scene(scene(friction={"m": 0.3}), ["friction.mu_k=0.156"])
    assert s.params[0].m == pytest.approx(0.212, abs=5e-4)   # eq 10 with the yarn's 110 deg (test above)


@pytest.mark.parametrize("changes, match", [
    (dict(yarn__B=-0.31), r"^yarn\.B = -0\.31: must be > 0 N mm\^2$"),
    (dict(yarn__B=math.nan), r"^yarn\.B = nan: must be a finite number$"),
    (dict(yarn__B="stiff"), r'^yarn\.B = "stiff": expected a number$'),
    (dict(yarn__material="kevlar"), r"^yarn\.material = 'kevlar': unknown yarn \(known: basalt, e_glass\)$"),
    (dict(knit__material="rib"), r"^knit\.material = 'rib': unknown knit"),
    (dict(knit__W0=2.0), r"^knit\.W0 = 2\.0: must be >= 4 d = 2\.32 mm \(yarn\.d = 0\.58; loops jammed already\)$"),
    (dict(knit__L=7.0), r"^knit\.L = 7\.0: too short to close a loop: needs > 2 C0 \+ W0 - 4 d = 7\.48 mm$"),
    (dict(yarn__material=None), r"^yarn\.d: missing \(give yarn\.d or yarn\.material = one of basalt, e_glass\)$"),
    (dict(yarn__colour="red"), r'^yarn\.colour = "red": unknown key'),
    (dict(friction__mu_k=0.15), r"^friction\.mu_k = 0\.15: give either friction\.m or friction\.mu_k"),
    (dict(friction__model="dahl"), r'^friction\.dahl_sigma = 0\.0: friction\.model = "dahl" needs a stiffness > 0'),
    (dict(friction__model="dahl", friction__dahl_sigma=1e7), r'^friction\.dahl_sigma = 10000000\.0: above 1e\+06 1/mm'),
    # a probe's friction.m = 0 under Dahl friction (its saturation tan(phi) = m) was refused as "cells[0].m", a key
    # in no file (the batch's backstop); named as the patch scene names it
    (dict(friction__model="dahl", friction__dahl_sigma=100.0, friction__m=0.0),
     r'^friction\.m = 0\.0: Dahl friction needs m > 0'),
    # a blind probe's --set friction.dahl_sigma=5 on a Coulomb scene ran Coulomb without a word
    (dict(friction__dahl_sigma=5.0), r'^friction\.dahl_sigma = 5\.0: not used by friction\.model = "coulomb"'),
    (dict(rules__unloading_rule="hong"), r'^rules\.unloading_rule = "hong": expected one of dusserre, hong_constant_t$'),
    (dict(engine="gpu"), r'^engine = "gpu": expected one of warp, reference$'),
    (dict(device="tpu"), r'^device = "tpu": expected cpu, cuda, cuda:N or auto$'),
    (dict(load=None), r"^load: missing required table \[load\]"),
    (dict(load__type="ramp"), r'^load\.type = "ramp": expected one of monotonic, cycles, piecewise$'),
    (dict(load__target_strain=None), r'^load\.target_strain: missing \(load\.type = "monotonic" needs it\)$'),
    (dict(load__upper_strain=0.6), r'^load\.upper_strain = 0\.6: not used by load\.type = "monotonic"'),
    # a quarter stitch of length L/4 spans C/2: C < L/2, strain < 14.1/5.4 - 1 = 1.611
    (dict(load__target_strain=2.0), r"^load\.target_strain = 2\.0: strain 2 cannot be reached: .* strain < 1\.611$"),
    (dict(load__max_increment=0.0), r"^load\.max_increment = 0\.0: must be > 0$"),
    # an increment past the whole program (1e9) records one row: a cycle's stages cannot show (at most 0.1)
    (dict(load__max_increment=1e9), r"^load\.max_increment = 1000000000\.0: must be <= 0\.1$"),
    # too long a program names what set its length (a blind probe's load.cycles = 100000 was told only of the
    # increment): the monotonic program's target and the increment
    (dict(load__max_increment=1e-7),
     r"^load\.max_increment = 1e-07: load\.target_strain = 0\.5 gives 5000000 increments .*shorter program$"),
])
def test_bad_scenes_refused_naming_key_and_value(changes, match):
    refused(scene(**changes), match)


def test_a_friction_ratio_above_m_max_is_named_by_the_key_that_set_it():
    # a blind probe's friction.m = 11.5 was refused as "cell.m = 11.5", a key in no scene (the engines' backstop);
    # eq 10 at a coiling angle near 180 deg: m = tanh(mu theta / 2) tan(theta / 2) = 503 at 179.9 deg, mu_k 0.3
    refused(scene(friction__m=11.5), r"^friction\.m = 11\.5: a friction ratio Rt/Rn above 5 ")
    d = scene(friction={"mu_k": 0.3, "coiling_angle_deg": 179.9})
    refused(d, r"^friction\.mu_k = 0\.3: eq 10 gives m = 503 \(eq 10: mu_k = 0\.3, coiling angle = 179\.9 deg\): "
               r"a friction ratio Rt/Rn above 5 ")
    d = scene()
    d["cells"] = [{}, {"friction": {"m": 6.0}}]
    refused(d, r"^cells\[1\]\.friction\.m = 6\.0: a friction ratio .* \(in cells\[1\]\)$")


def test_a_cycle_count_beyond_the_increment_limit_is_refused_before_its_strains_are_listed():
    # a blind probe's load.cycles = 10^9 was killed for memory (22 GB) before the increments' check: the reach
    # check listed the program's 2 x 10^9 corner strains.  At 10^7 cycles that list is 2 x 10^7 references,
    # 160 MB; the refusal (2 x 10^7 x 2 branches of 0.3 / 0.05 = 6 increments: more than 10^6) needs none of it
    import tracemalloc
    load = {"type": "cycles", "lower_strain": 0.1, "upper_strain": 0.4, "cycles": 10**7, "max_increment": 0.05}
    tracemalloc.start()
    try:
        refused(scene(load=load), r"^load\.max_increment = 0\.05: load\.cycles = 10000000 gives 120000000 increments ")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16e6      # a tenth of the list's 160 MB


def test_cycles_lower_must_be_below_upper():
    load = {"type": "cycles", "lower_strain": 0.6, "upper_strain": 0.6, "cycles": 3}
    refused(scene(load=load), r"^load\.lower_strain = 0\.6: must be < load\.upper_strain = 0\.6$")
    refused(scene(load=dict(load, lower_strain=0.1, cycles=0)), r"^load\.cycles = 0: must be >= 1$")


def test_batch_cells_override_and_name_their_paths():
    d = scene(friction={"mu_k": 0.156, "coiling_angle_deg": 110.0})
    d["cells"] = [{"label": "m=0"}, {"friction": {"m": 0.4}}, {"yarn": {"material": "basalt"},
                                                                "knit": {"material": "basalt_plain"}}]
    s = load_cell_scene(d)
    assert s.labels == ["m=0", "cell 1", "cell 2"]
    assert s.params[0].m == pytest.approx(0.212, abs=5e-4)
    assert s.params[1].m == 0.4                         # m replaces the inherited mu_k/coiling angle
    assert (s.params[2].d, s.params[2].L) == (0.56, 13.1)
    d["cells"].append({"knit": {"W0": 2.0}})
    refused(d, r"^cells\[3\]\.knit\.W0 = 2\.0: must be >= 4 d = 2\.32 mm \(yarn\.d = 0\.58; .*\(in cells\[3\]\)$")
    d["cells"][3] = {"knit": {"W0": 4.4, "wales": 3}}
    refused(d, r'^cells\[3\]\.knit\.wales = 3: unknown key')


def test_set_overrides_are_type_checked():
    s = load_cell_scene(scene(), ["yarn.B=0.25", "load.max_increment=0.1", "rules.force_cap_N=5"])
    assert s.params[0].B == 0.25 and s.params[0].force_cap_N == 5.0 and len(s.program) == 5
    refused(scene(), r'^yarn\.B = "x": expected a number$', ["yarn.B=x"])
    refused(scene(), r"^yarn\.B = -1\.0: must be > 0", ["yarn.B=-1"])


def test_resolved_scene_round_trips():
    d = scene(friction={"mu_k": 0.156, "phi0": "phimax"}, rules={"unloading_rule": "hong_constant_t"})
    d["cells"] = [{"label": "a"}, {"yarn": {"B": 0.2}}]
    s = load_cell_scene(d)
    again = load_cell_scene(tomllib.loads(s.to_toml()))
    assert again.params == s.params and again.labels == s.labels
    assert (again.program.strain == s.program.strain).all()
    assert again.resolved == s.resolved


def test_effects_table_makes_the_cells_effects():
    s = load_cell_scene({"yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
                         "friction": {"m": 0.2, "dahl_sigma": 30.0},
                         "effects": {"on": ["yarn_compaction", "dahl_transition"], "compaction_k": 20.0},
                         "load": {"type": "monotonic", "target_strain": 0.3}})
    p = s.params[0]
    assert p.effects.on == ("yarn_compaction",) and p.effects.compaction_k == 20.0
    assert p.friction == "dahl"                       # dahl_transition is the Dahl friction law
    refused({"yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"}, "friction": {"m": 0.2},
             "effects": {"on": ["magic"]}, "load": {"type": "monotonic", "target_strain": 0.3}}, "effects.on")
    refused({"yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"}, "friction": {"m": 0.2},
             "effects": {"on": ["yarn_compaction"], "compaction_k": -1.0},
             "load": {"type": "monotonic", "target_strain": 0.3}}, "compaction_k")


def test_a_library_value_gives_way_to_the_scenes_own_way_of_stating_it(tmp_path):
    """A library yarn's friction by eq 10 (mu_k, coiling angle) and a knit's phi0: a scene stating m and phi0 its
    own way keeps them (before: the library's mu_k was added beside the scene's m and refused as both given)."""
    (tmp_path / "lib.toml").write_text(
        '[yarns.y]\nd = 0.58\nB = 0.31\n[yarns.y.friction]\nmu_k = 0.156\ncoiling_angle_deg = 110.0\n'
        '[knits.k]\nyarn = "y"\nL = 14.1\nW0 = 4.4\nC0 = 2.7\nphi0 = 0.05\n')
    base = {"materials": str(tmp_path / "lib.toml"), "engine": "reference", "knit": {"material": "k"},
            "load": {"type": "monotonic", "target_strain": 0.5, "max_increment": 0.05}}
    p = load_cell_scene(base).params[0]
    assert p.m == pytest.approx(0.212, abs=5e-4) and p.phi0 == 0.05          # the library's, eq 10 (test above)
    p = load_cell_scene({**base, "friction": {"m": 0.3, "phi0_fraction": 0.5}}).params[0]
    assert p.m == 0.3 and p.phi0 == pytest.approx(0.5 * math.atan(0.3))


def test_set_load_type_drops_the_other_types_keys():
    """`--set load.type=cycles` on a monotonic scene was refused for the scene's own target_strain ("not used by
    load.type = cycles"), which --set cannot remove (a probe of the README's `--set overrides any scene key`).
    An override of the choosing key drops the other types' keys; the new type's are then asked for by name.
    A file that states both is still refused (the scene says two programs)."""
    base = scene()                                   # monotonic to 0.5
    refused(base, r'^load\.lower_strain: missing \(load\.type = "cycles" needs it\)$', ["load.type=cycles"])
    s = load_cell_scene(base, ["load.type=cycles", "load.lower_strain=0.1", "load.upper_strain=0.3",
                               "load.cycles=2", "load.max_increment=0.1"])
    # 0 -> 0.3 -> 0.1 -> 0.3 -> 0.1 at steps of 0.1: 3 + 2 + 2 + 2 increments
    assert s.program.waypoints == (0.0, 0.3, 0.1, 0.3, 0.1) and len(s.program) == 9
    both = scene(load={"type": "cycles", "target_strain": 0.5, "lower_strain": 0.1, "upper_strain": 0.3,
                       "cycles": 2})
    refused(both, r'^load\.target_strain = 0\.5: not used by load\.type = "cycles"')
