"""The domain check from arrays (knitsim.cell.domain.check_cell_arrays, ``knitsim run``'s check_patch_domain)
gives the verdicts of the per-object check it replaced.

The oracle is the per-object check as it stood before (main at fa130c4), copied below verbatim:
``ParameterDomain.why_outside`` on each CellParams, the rest states of the distinct (B, d, L, W0, C0, phi0) by
``CellModel.from_params(...).state()`` (or the NumPy reference), and check_patch_domain on
``grouping.params`` (one validated CellParams per group).  It shares no code with the array path but the
kernels and CellParams.validated (the law of the messages).  The patches hold hand-made cells whose verdicts
are known from the domain's table (knitsim.cell.domain: the box; E-glass of Dusserre 2015, Table 1 and section
2.2, lengthened to L = 20 mm pulls at rest, R < 0; its rest force per wale ~0.02 N lies above a cap of 0.015 N),
and the bundled scenes (mixed materials in zones, random phi0).  The tests assert that the hand-made cells
reach every verdict (so that agreement is not agreement on nothing).
"""
from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from knitsim.cell.domain import DOMAIN, ParameterDomain, check_cell_arrays, check_cells
from knitsim.cell.effects import NO_EFFECTS, EffectSet
from knitsim.cell.material import CellParams, may_refuse
from knitsim.cli.run import check_patch_domain
from knitsim.errors import KnitsimInputError
from knitsim.patch.model import PatchModel
from knitsim.scene.patch_scene import load_patch_scene

EGLASS = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2)     # Table 1, section 2.2
STRAINS = [0.0, 0.1, 0.4]


# --- the oracle: the per-object check before the array path (main at fa130c4), verbatim ----------------------

def _old_ratios(p):
    closing = 2.0 * p.C0 + p.W0 - 4.0 * p.d
    return {"d": p.d, "B": p.B, "W0_over_djam": p.W0 / p.d_jam, "C0_over_d": p.C0 / p.d,
            "L_over_closing": p.L / closing if closing > 0 else math.inf, "m": p.m}


def _old_why_outside(domain, p):
    ratios = _old_ratios(p)
    names = {"d": "d", "B": "B", "W0_over_djam": "W0 / d_jam", "C0_over_d": "C0 / d",
             "L_over_closing": "L / (2 C0 + W0 - 4 d)", "m": "m"}
    for key, v in ratios.items():
        lo, hi = getattr(domain, key)
        if not (lo * (1.0 - 1e-9) <= v <= hi * (1.0 + 1e-9)):
            return f"{names[key]} = {v:.4g} outside the model's domain [{lo:g}, {hi:g}] (knitsim.cell.domain)"
    if abs(p.phi0) > p.phimax + 1e-12:
        return f"phi0 = {p.phi0:.4g} rad outside the friction cone [-atan m, atan m] = +/-{p.phimax:.4g}"
    return None


def _old_no_rest_reason(R):
    if R is not None and R < 0.0:
        return (f"no rest state: the contact at B would pull (R = {R:.3g} N < 0 at rest): "
                "the loop is too loose to press on its neighbour")
    return "no rest state: Table 4's initial state (C0, W0, L, phi0) has no equilibrium of the quarter loop"


def _old_check_cells(params, engine="warp", device="cpu", domain=DOMAIN):
    """(outside, no_rest, rest_F) lists, as check_cells gave them."""
    from knitsim.cell.batch import CellModel
    from knitsim.cell.domain import _solve_rest_state
    from knitsim.cell.history import STATUS_NO_REST_STATE
    from knitsim.cell.quantities import CODE

    params = list(params)
    key = lambda p: (p.B, p.d, p.L, p.W0, p.C0, p.phi0)  # noqa: E731
    outside = [_old_why_outside(domain, p) for p in params]
    keys, first = {}, []
    for p in params:
        if key(p) not in keys:
            keys[key(p)] = len(first)
            first.append(p)
    why_u = [None] * len(first)
    if first and engine == "warp":
        st = CellModel.from_params(first, device=device).state()
        status0 = np.asarray(st.status.numpy())
        R = np.asarray(st.q.numpy()[:, CODE["R"]])
        F_u = [float(v) for v in st.q.numpy()[:, CODE["F"]]]
        for i in np.nonzero(status0 == STATUS_NO_REST_STATE)[0]:
            why_u[i] = _old_no_rest_reason(float(R[i]) if np.isfinite(R[i]) else None)
    elif first:
        F_u = []
        for i, p in enumerate(first):
            res, ok = _solve_rest_state(p)
            F_u.append(float(res.state.F) if ok else float("nan"))
            if not ok or float(res.state.R) < 0.0:
                why_u[i] = _old_no_rest_reason(float(res.state.R) if ok else None)
    no_rest = [why_u[keys[key(p)]] for p in params]
    rest_F = [float("nan") if why_u[keys[key(p)]] is not None else F_u[keys[key(p)]] for p in params]
    return outside, no_rest, rest_F


def _old_at_cap(rest_F, caps):
    return [None if not (F >= cap) else
            (f"its force per wale at rest, {F:.4g} N, is already at or above force_cap_N = {cap:.4g} N: "
             "no load program can start from it; raise force_cap_N above the rest force")
            for F, cap in zip(rest_F, caps)]


def _old_check_patch_domain(model, grip_strains, engine, device):
    """check_patch_domain's verdicts before the array path (its memory check left out: unchanged)."""
    grouping = model.grouping(dedup=True)
    n_cells = int(grouping.group_of_cell.size)
    outside, no_rest, rest_F = _old_check_cells(grouping.params, engine=engine, device=device)
    cells_of = np.bincount(grouping.group_of_cell.ravel(), minlength=len(grouping.params))
    for whys, what, source in ((no_rest, "have no admissible rest state", " (knitsim.cell.domain)"),
                               (_old_at_cap(rest_F, [p.cap_N for p in grouping.params]), "cannot be loaded", "")):
        bad = [g for g, why in enumerate(whys) if why is not None]
        if bad:
            n = int(cells_of[bad].sum())
            i, j = np.argwhere(np.isin(grouping.group_of_cell, bad))[0]
            raise KnitsimInputError(f"{n} of {n_cells} cell(s) {what}, e.g. course {i}, wale {j}: "
                                    f"{whys[int(grouping.group_of_cell[i, j])]}{source}")
    warnings, counts, example = [], {}, None
    for g, why in enumerate(outside):
        if why is not None:
            name = why.split(" = ")[0]
            counts[name] = counts.get(name, 0) + int(cells_of[g])
            if example is None:
                # the example named by its first cell (course, wale), as check_patch_domain now names it
                i, j = (int(v) for v in np.argwhere(grouping.group_of_cell == g)[0])
                example = f"cell [course {i}, wale {j}]: {why}"
    if counts:
        n = int(sum(cells_of[g] for g, why in enumerate(outside) if why is not None))
        by = ", ".join(f"{k} ({v})" for k, v in counts.items())
        warnings.append({"code": "outside_domain",
                         "message": f"extrapolation: {n} of {n_cells} cell(s) outside the model's domain box, "
                                    f"by quantity: {by}; e.g. {example}"})
    why = DOMAIN.why_program_outside(grip_strains)
    if why is not None:
        warnings.append({"code": "outside_domain", "message": f"extrapolation: grip {why}"})
    return warnings


def _outcome(f, *args):
    """What ``f(*args)`` gives: its value, or the message of the KnitsimInputError it raises."""
    try:
        return ("ok", f(*args))
    except KnitsimInputError as exc:
        return ("error", str(exc))


# --- hand-made cells of known verdicts -----------------------------------------------------------------------

def _scaled(p, k):
    """The cell with every length times k and B times k^2 (its forces unchanged, B / d^2; the same ratios)."""
    return replace(p, d=p.d * k, L=p.L * k, W0=p.W0 * k, C0=p.C0 * k, B=p.B * k * k)


def _known_cells():
    """label -> cell; the label says the verdict the domain's table gives it."""
    e = EGLASS
    closing = lambda C0: 2.0 * C0 + e.W0 - 4.0 * e.d  # noqa: E731
    return {
        "inside": e,
        "inside, phi0 at the cone's edge": replace(e, phi0=math.atan(0.2)),
        "inside, -0.0": replace(e, phi0=-0.0),
        "inside, dahl": replace(e, friction="dahl", dahl_sigma=50.0),
        "inside, other rules": replace(e, unloading_rule="hong_constant_t", reload_rule="freeze_rn",
                                       jamming_criterion="head_gap"),
        "inside, effects": replace(e, effects=NO_EFFECTS.with_on("yarn_compaction", compaction_k=0.5)),
        "inside, in-plane width": replace(e, in_plane_width=0.7),
        "d above": _scaled(e, 4.0),                   # d = 2.32 > 2.0
        "d below": _scaled(e, 0.15),                  # d = 0.087 < 0.1
        "B above": replace(e, B=20.0),
        "B below": replace(e, B=5e-4),
        "W0 / d_jam below": replace(e, in_plane_width=0.9),          # 4.4 / 0.9 = 4.9 < 5.5
        "C0 / d above": replace(e, C0=3.1, L=1.85 * closing(3.1)),   # 5.3 > 5.2
        "C0 / d below": replace(e, C0=2.25, L=1.85 * closing(2.25)),  # 3.9 < 4.0
        "L ratio above, pulls": replace(e, L=20.0),                  # 2.67 > 2.1; R < 0 at rest
        "L ratio below": replace(e, L=1.55 * closing(2.7)),          # 1.55 < 1.6
        "m above": replace(e, m=0.6),
        "m below": replace(e, m=0.02),
        "same rest as inside, m above": replace(e, m=0.7),           # shares the inside cell's rest state
        "cap below the rest force": replace(e, force_cap_N=0.015),   # rest ~0.02 N per wale
    }


def _patch(cells, courses=None):
    """A patch of the cells, wale by wale, each column repeating them (so that dedup has copies to merge)."""
    cells = list(cells)
    courses = courses or 3
    grid = [[cells[(i + j) % len(cells)] for j in range(len(cells))] for i in range(courses)]
    return PatchModel.from_cells(grid)


def _same_check(cells_dict, params, engine="warp", **kw):
    new = check_cell_arrays(cells_dict, engine=engine, **kw)
    outside, no_rest, rest_F = _old_check_cells(params, engine=engine, **kw)
    assert new.outside == outside
    assert new.no_rest == no_rest
    np.testing.assert_array_equal(np.array(new.rest_F), np.array(rest_F))     # bit for bit, NaN as NaN
    assert [math.isnan(x) for x in new.rest_F] == [math.isnan(x) for x in rest_F]
    caps = [p.cap_N for p in params]
    assert new.at_cap(caps) == _old_at_cap(rest_F, caps)
    np.testing.assert_array_equal(new.at_cap_mask(caps), [w is not None for w in _old_at_cap(rest_F, caps)])
    return new


@pytest.mark.parametrize("dedup", [True, False])
def test_the_known_cells_get_the_oracles_verdicts_and_every_verdict_occurs(dedup):
    known = _known_cells()
    g = _patch(known.values()).grouping(dedup=dedup)
    new = _same_check(g.cells, g.params)
    # every verdict is reached: each box quantity outside, no rest state (pulling and none), at the cap
    names = {w.split(" = ")[0] for w in new.outside if w}
    assert names == {"d", "B", "W0 / d_jam", "C0 / d", "L / (2 C0 + W0 - 4 d)", "m"}, names
    assert any(w and "would pull" in w for w in new.no_rest)
    assert any(new.at_cap([p.cap_N for p in g.params]))
    assert not new.outside[0] and not new.no_rest[0]
    by: dict = {}
    for w in new.outside:                    # (DomainCheck.outside_quantities before: by the reasons' names)
        if w is not None:
            by[w.split(" = ")[0]] = by.get(w.split(" = ")[0], 0) + 1
    assert list(new.outside_quantities().items()) == list(by.items())


def test_one_cell_at_a_time_matches_the_oracle_too():
    for label, p in _known_cells().items():
        g = _patch([p], courses=1).grouping()
        _same_check(g.cells, g.params)
        assert DOMAIN.why_outside(p) == _old_why_outside(DOMAIN, p), label


def test_no_equilibrium_at_rest_is_said_as_before():
    # a loop far too tight for Hong's rest shape (L ratio 1.1): the Warp batch finds no state at all
    e = EGLASS
    p = replace(e, L=1.1 * (2.0 * e.C0 + e.W0 - 4.0 * e.d))
    g = _patch([e, p], courses=2).grouping()
    new = _same_check(g.cells, g.params)
    assert any(w and ("no equilibrium" in w or "would pull" in w) for w in new.no_rest)


def test_the_per_object_reason_is_the_array_one_for_cells_the_validation_would_refuse():
    # phi0 beyond the cone is refused by CellParams.validated, so a patch never reaches the domain's phi0
    # clause; why_outside still words it (unvalidated cells), as before
    for p in (replace(EGLASS, phi0=0.5), replace(EGLASS, phi0=-0.3, m=0.1), replace(EGLASS, m=0.0, phi0=1e-11),
              replace(EGLASS, W0=1.0, C0=0.1), replace(EGLASS, d=3.0, W0=4.0)):
        assert DOMAIN.why_outside(p) == _old_why_outside(DOMAIN, p)
        assert DOMAIN.ratios(p) == _old_ratios(p)
    other = ParameterDomain(m=(0.01, 0.1), L_over_closing=(1.0, 3.0))
    for p in _known_cells().values():
        assert other.why_outside(p) == _old_why_outside(other, p)


@pytest.mark.parametrize("scene", ["two_zone_basalt_e_glass", "random_phi0", "stitch_length_gradient"])
def test_bundled_scenes_check_as_before(scene):
    sc = load_patch_scene(f"scenes/{scene}.toml")
    for dedup in (True, False):
        g = sc.model.grouping(dedup=dedup)
        _same_check(g.cells, g.params)
    assert check_patch_domain(sc.model, sc.program.strain, "warp", "cpu", True) == \
        _old_check_patch_domain(sc.model, sc.program.strain, "warp", "cpu")


def test_zones_with_cells_outside_the_box_warn_as_before():
    # the two-zone scene with the basalt zone's m beyond the box, and a zone of in-plane width 0.9 (W0 / d_jam)
    import tomllib

    with open("scenes/two_zone_basalt_e_glass.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["friction"]["m"] = 0.02
    doc["zones"][0]["friction"] = {"m": 0.6}
    sc = load_patch_scene(doc)
    new = check_patch_domain(sc.model, [0.0, 0.7], "warp", "cpu", True)
    assert new == _old_check_patch_domain(sc.model, [0.0, 0.7], "warp", "cpu")
    assert len(new) == 2 and "m (2530)" in new[0]["message"] and "grip load strains" in new[1]["message"]
    # with the scene's origins, the example's cell and the key that set the quantity outside (before: "e.g. m = 0.6
    # outside the model's domain [0.05, 0.5]", neither the cell nor the zone named)
    # (the base friction back inside the box: only the zone's cells outside)
    assert named_example(sc, "e.g. cell [course 0, wale 0]: m = 0.02 outside the model's domain [0.05, 0.5] "
                             "(knitsim.cell.domain); that cell's m = 0.02 (friction.m)")
    del doc["friction"]["m"]
    sc = load_patch_scene(doc)
    named = check_patch_domain(sc.model, [0.0, 0.7], "warp", "cpu", True, origins=sc.origins)
    i, j = (int(v) for v in np.argwhere(sc.model.fields["m"] == 0.6)[0])
    assert named[0]["message"].endswith(f"e.g. cell [course {i}, wale {j}]: m = 0.6 outside the model's domain "
                                        "[0.05, 0.5] (knitsim.cell.domain); that cell's m = 0.6 (zones[0].friction.m)")


def test_a_specimens_outside_domain_warning_names_blocks():
    """A specimen's cells are blocks of stitches, named by band and strip (as its zones index them): its warning
    counts blocks and names the example block and the key that set its quantity (a probe's read "1 of 1 cell(s)
    outside ... e.g. m = 0.6", neither the block nor the key named)."""
    sc = load_patch_scene({"engine": "warp", "device": "cpu",
                           "specimen": {"width": 30.0, "gauge_length": 40.0, "strips": 2, "bands": 1},
                           "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
                           "friction": {"m": 0.2}, "zones": [{"wales": [1, 2], "friction": {"m": 0.6}}],
                           "load": {"type": "monotonic", "target_strain": 0.05, "max_increment": 0.01}})
    (w,) = check_patch_domain(sc.model, sc.program.strain, "warp", "cpu", True, origins=sc.origins)
    assert w["message"] == ("extrapolation: 1 of 2 block(s) outside the model's domain box, by quantity: m (1); e.g. "
                            "block [band 0, strip 1]: m = 0.6 outside the model's domain [0.05, 0.5] "
                            "(knitsim.cell.domain); that block's m = 0.6 (zones[0].friction.m)")


def named_example(sc, tail: str) -> bool:
    """Whether check_patch_domain's outside_domain warning of scene ``sc``, given its origins, ends with ``tail``."""
    return check_patch_domain(sc.model, [0.0, 0.7], "warp", "cpu", True, origins=sc.origins)[0]["message"].endswith(tail)


@pytest.mark.parametrize("drop", [(), ("L ratio above, pulls",), ("L ratio above, pulls", "L ratio below")])
def test_check_patch_domain_errors_and_warnings_as_before(drop):
    known = {k: v for k, v in _known_cells().items() if k not in drop}
    model = _patch(known.values(), courses=4)
    new = _outcome(check_patch_domain, model, STRAINS, "warp", "cpu", True)
    assert new == _outcome(_old_check_patch_domain, model, STRAINS, "warp", "cpu")
    assert new[0] == "error"
    # without the cells that cannot run: the warnings, by quantity, with an example
    ok = {k: v for k, v in known.items() if "pulls" not in k and "cap" not in k and "L ratio below" not in k}
    model = _patch(ok.values(), courses=2)
    new = _outcome(check_patch_domain, model, [0.0, 0.65], "warp", "cpu", False)
    assert new == _outcome(_old_check_patch_domain, model, [0.0, 0.65], "warp", "cpu")
    assert new[0] == "ok" and len(new[1]) == 2, new


def test_the_reference_engine_checks_as_before():
    known = _known_cells()
    cells = [known[k] for k in ("inside", "m above", "L ratio above, pulls", "cap below the rest force")]
    g = _patch(cells, courses=2).grouping()
    _same_check(g.cells, g.params, engine="reference")
    model = _patch(cells, courses=2)
    assert _outcome(check_patch_domain, model, STRAINS, "reference", "cpu", True) == \
        _outcome(_old_check_patch_domain, model, STRAINS, "reference", "cpu")


def test_check_cells_of_objects_is_the_array_check():
    params = list(_known_cells().values()) * 2
    new = check_cells(params)
    outside, no_rest, rest_F = _old_check_cells(params)
    assert new.outside == outside and new.no_rest == no_rest
    np.testing.assert_array_equal(np.array(new.rest_F), np.array(rest_F))
    assert new.codes.tolist() == [2 if r else 1 if o else 0 for o, r in zip(outside, no_rest)]
    assert check_cells([]).outside == []


# --- validation: the messages of CellParams.validated, for the cells it refuses ------------------------------

def _bad_cells():
    """Cells CellParams.validated refuses, one per condition, and cells it passes near the edges."""
    e = EGLASS
    lmin = 2.0 * e.C0 + e.W0 - 4.0 * e.d
    bad = [replace(e, B=0.0), replace(e, d=-1.0), replace(e, L=0.0), replace(e, W0=-4.0), replace(e, C0=0.0),
           replace(e, force_cap_N=0.0), replace(e, force_cap_N=-1.0), replace(e, B=float("nan")),
           replace(e, L=float("inf")), replace(e, phi0=float("nan")), replace(e, dahl_sigma=float("inf")),
           replace(e, m=-0.1), replace(e, m=5.5), replace(e, in_plane_width=0.5), replace(e, in_plane_width=1.2),
           replace(e, W0=2.0), replace(e, L=lmin), replace(e, phi0=math.atan(0.2) + 2e-12),
           replace(e, phi0=-0.5), replace(e, friction="stribeck"), replace(e, friction="dahl"),
           replace(e, friction="dahl", dahl_sigma=2e6), replace(e, unloading_rule="x"), replace(e, reload_rule="x"),
           replace(e, jamming_criterion="x"), replace(e, effects="none"),
           replace(e, effects=EffectSet(on=("bogus",))), replace(e, effects=EffectSet(bend_h=2.0))]
    good = [e, replace(e, phi0=math.atan(0.2) + 1e-12), replace(e, L=lmin * (1 + 1e-12)),
            replace(e, W0=4.0 * 0.58 * 1.9, C0=2.0, L=12.0), replace(e, in_plane_width=0.58),
            replace(e, friction="dahl", dahl_sigma=1e6), replace(e, m=5.0), replace(e, m=0.0, phi0=0.0),
            replace(e, force_cap_N=1.0)]
    return bad, good


def _refuses(p) -> bool:
    try:
        p.validated()
    except KnitsimInputError:
        return True
    return False


def _cells_of(params):
    names = ("B", "d", "L", "W0", "C0", "m", "phi0", "dahl_sigma", "force_cap_N", "in_plane_width",
             "friction", "unloading_rule", "reload_rule", "jamming_criterion", "effects")
    return {k: np.fromiter((getattr(p, k) for p in params), dtype=object, count=len(params)) for k in names}


def test_the_array_flags_hold_every_cell_the_per_object_check_refuses():
    bad, good = _bad_cells()
    assert all(_refuses(p) for p in bad) and not any(_refuses(p) for p in good)
    flags = may_refuse(_cells_of(bad + good), len(bad + good))
    assert flags[:len(bad)].all()
    # a superset, but not all: the valid cells at the edges pass (the same arithmetic, math.atan's cone)
    assert not flags[len(bad):].any()
    PatchModel.from_cells([good]).grouping().validate()
    # as floats (the patch's fields), too
    c = _cells_of(bad + good)
    floats = {k: (np.array(v, dtype=np.float64) if k not in ("friction", "unloading_rule", "reload_rule",
              "jamming_criterion", "effects", "force_cap_N", "in_plane_width") else v) for k, v in c.items()}
    assert (may_refuse(floats, len(bad + good))[:len(bad)]).all()
    # random cells around the box: the flags hold every refusal
    rng = np.random.default_rng(7)
    n = 4000
    cells = [CellParams(B=float(rng.uniform(-0.1, 1)), d=float(rng.uniform(-0.05, 1)),
                        L=float(rng.uniform(5, 20)), W0=float(rng.uniform(1, 6)), C0=float(rng.uniform(1, 4)),
                        m=float(rng.uniform(-0.1, 0.6)), phi0=float(rng.uniform(-0.6, 0.6)),
                        in_plane_width=None if rng.uniform() < 0.5 else float(rng.uniform(0.3, 1.2)))
             for _ in range(n)]
    refused = np.array([_refuses(p) for p in cells])
    flags = may_refuse(_cells_of(cells), n)
    assert refused.any() and (~refused).any()
    assert not (refused & ~flags).any()


def test_odd_types_are_flagged_and_the_per_object_check_decides():
    e = EGLASS
    odd = [replace(e, force_cap_N="5"), replace(e, force_cap_N=True), replace(e, B="0.31"), replace(e, m=None),
           replace(e, in_plane_width="0.7"), replace(e, friction=["coulomb"])]
    assert all(_refuses(p) for p in odd)
    assert may_refuse(_cells_of(odd), len(odd)).all()
    fine = [replace(e, B=np.float32(0.31)), replace(e, force_cap_N=np.float64(5.0)), replace(e, m=np.int64(0))]
    assert not any(_refuses(p) for p in fine)
    cells = check_cells(fine)                     # read as floats, as CellParams.validated reads them
    assert cells.no_rest == [None] * 3 and cells.outside[2] is not None


def test_a_patch_of_bad_cells_is_refused_with_the_per_object_message_of_the_first_group():
    bad, _ = _bad_cells()
    for p in bad:
        if isinstance(p.effects, str) or not isinstance(p.friction, str):
            continue                              # a PatchModel's fields and rules hold these as they are
        for where in ((0, 1), (1, 0)):
            grid = [[EGLASS, EGLASS], [EGLASS, EGLASS]]
            grid[where[0]][where[1]] = p
            grid[1][1] = replace(EGLASS, m=-1.0)  # a second bad cell, later in group order
            model = PatchModel.from_cells(grid)
            expected = _outcome(lambda: model.grouping().params)
            assert expected[0] == "error"
            assert _outcome(model.grouping().validate) == expected
            assert _outcome(check_patch_domain, model, STRAINS, "warp", "cpu", True) == expected
            assert _outcome(_old_check_patch_domain, model, STRAINS, "warp", "cpu") == expected


def test_check_cells_names_the_refused_cell():
    with pytest.raises(KnitsimInputError, match=re.escape("cells[2].m = -0.1: the friction ratio must be >= 0")):
        check_cells([EGLASS, EGLASS, replace(EGLASS, m=-0.1)])
    with pytest.raises(KnitsimInputError, match=re.escape("cells[1].force_cap_N = 'x': must be a finite number")):
        check_cells([EGLASS, replace(EGLASS, force_cap_N="x")], engine="reference")


def test_the_warning_names_the_quantities_in_the_order_the_groups_first_hold_them():
    # groups in patch order (wale by wale): the first cell outside is m's, then d's; the old check counted
    # by the reasons in group order, so m comes first although d is judged first within a cell
    known = _known_cells()
    model = _patch([known["inside"], known["m above"], known["d above"], known["B below"]], courses=4)
    new = check_patch_domain(model, STRAINS, "warp", "cpu", True)
    assert new == _old_check_patch_domain(model, STRAINS, "warp", "cpu")
    assert "by quantity: m (4), d (4), B (4); e.g. cell [course 0, wale 1]: m = 0.6" in new[0]["message"], new


def test_an_infinite_in_plane_width_of_a_patch_is_no_width_as_before():
    # Grouping.params reads a non-finite width as none (the cell jams at d); the check did, and does
    fields_cell = replace(EGLASS, in_plane_width=float("inf"))
    model = PatchModel.from_cells([[EGLASS, fields_cell, replace(EGLASS, m=0.6)]])
    new = _outcome(check_patch_domain, model, STRAINS, "warp", "cpu", True)
    assert new == _outcome(_old_check_patch_domain, model, STRAINS, "warp", "cpu") and new[0] == "ok"
    g = model.grouping()
    _same_check(g.cells, g.params)
