"""Immutable description of a patch: ``courses x wales`` cells with per-cell parameters.

Layout: cell ``[i, j]`` is course ``i`` (0 at the lower grip) of wale column
``j``.  Every per-cell parameter is an array of shape ``(courses, wales)``,
and so are the rules (friction model, Table 4 completions, jamming criterion,
force cap) and the model extensions (an :class:`~knitsim.cell.effects.EffectSet`
per cell): a preform mixes yarns, so a patch mixes Coulomb and Dahl regions,
rule sets and effects by material.

A cell of the array may stand for a block of identical stitches (a
specimen described by its width and gauge length, :mod:`knitsim.scene.patch_scene`):
``course_count[i, j]`` stitches in series along the wale and ``wale_count[i, j]``
wales in parallel (1 and 1 by default: every cell one stitch).  A column is then
a strip of the specimen: the cells along it carry the same *total* force
``F_j = wale_count x force per wale`` (equilibrium of a cut across the strip), and
their changes in course length, each times its course count, add up to the grip
displacement.  ``gauge_length`` (the distance between the grips) makes every
column's rest length that length and the grip strain the displacement over it.

Identical cells are solved once (:meth:`PatchModel.grouping`): cells with the
same parameters (and wale count) in the same column start from the same state
and, in series, carry the same force, so they stay identical; columns made of
the same multiset of cells (with the same course counts, so of the same rest
length) carry the same grip displacement and stay identical too.  A uniform
patch thus collapses to one cell.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import numpy as np

from ..arrays import row_ids as _row_ids
from ..cell.effects import NO_EFFECTS, effect_set_codes
from ..cell.material import CellParams, default_force_cap_N, may_refuse
from ..errors import KnitsimInputError

#: per-cell parameters that maps may set (CellParams names), units mm, N mm^2, -, 1/mm, rad;
#: in_plane_width is NaN where it is not given (the cell then jams with its d)
PARAM_NAMES = ("d", "B", "m", "dahl_sigma", "L", "W0", "C0", "phi0", "in_plane_width")
#: rules of each cell (CellParams names): per-cell object arrays of a patch
RULE_NAMES = ("friction", "unloading_rule", "reload_rule", "jamming_criterion", "force_cap_N")


#: the most wales (courses) a patch holds across (along): a [patch] of single stitches as much as a specimen's
#: width over W0 (gauge length over C0)
MAX_STITCHES_PER_AXIS = 100_000
#: a specimen with fewer stitches than this across (along) has none that is not at a free edge (a grip): the
#: model's stitch is an interior one, a periodic loop between neighbours like itself on every side
INTERIOR_STITCHES = 3


def specimen_size_notes(width: float, gauge_length: float, wales, courses) -> tuple[str | None, str | None]:
    """``(refusal, warning)`` of a specimen ``width`` x ``gauge_length`` [mm] whose bands hold ``wales`` across and
    whose strips hold ``courses`` between the grips (numbers or arrays, each at least one, which the callers check
    naming their own keys), each None where there is none.

    Refused: more than :data:`MAX_STITCHES_PER_AXIS` on an axis (more than a patch may hold: no grips hold such
    a specimen, e.g. a gauge length of 1e9 mm).  Warned of: fewer than :data:`INTERIOR_STITCHES` on an axis
    (every stitch at a free edge or a grip, which the model does not describe), with the sizes read as cm
    (:func:`cm_hint`)."""
    wales, courses = np.asarray(wales, float), np.asarray(courses, float)
    most = max(float(wales.max()), float(courses.max()))
    if most > MAX_STITCHES_PER_AXIS:
        return (f"the specimen holds {float(wales.max()):.4g} wales x {float(courses.max()):.4g} courses, more than "
                f"the {MAX_STITCHES_PER_AXIS:,} a patch may hold on an axis: no grips hold such a specimen (sizes "
                "are in mm)"), None
    wales, courses = float(wales.min()), float(courses.min())
    counts = f"{wales:.4g} wales x {courses:.4g} courses"
    few = INTERIOR_STITCHES * (1.0 - 1e-9)                 # (13.2 mm / 4.4 mm rounds to 2.9999999999999996)
    if min(wales, courses) < few:
        edge = wales < few
        return None, (f"the specimen {width:.6g} mm wide, {gauge_length:.6g} mm between the grips holds {counts}: "
                      f"fewer than {INTERIOR_STITCHES} stitches {'across' if edge else 'along'}, every one at a "
                      f"{'free edge' if edge else 'grip'}, where the model's stitch (an interior, periodic loop) is "
                      "not the knit's" + cm_hint(width, gauge_length, wales, courses))
    return None, None


def cell_name(i: int, j: int, blocks: bool = False, bracketed: bool = False) -> str:
    """Cell ``[i, j]`` of a patch as its scene indexes it: ``course i, wale j``, or a specimen's ``band i, strip j``
    (``blocks``: its zones and maps index bands and strips, and a block holds many courses); ``bracketed``:
    ``cell [course i, wale j]``, ``block [band i, strip j]``."""
    where = f"band {i}, strip {j}" if blocks else f"course {i}, wale {j}"
    return f"{'block' if blocks else 'cell'} [{where}]" if bracketed else where


def cm_hint(width: float, gauge_length: float, wales: float, courses: float) -> str:
    """``; if the sizes are in cm, ...``: the sizes in mm and the counts they would make.  Sizes in cm typed as
    mm make a specimen ten times narrower and shorter than meant (a width of 5 for 5 cm ran as 1.1 wales of
    E-glass without a word).  ``""`` where the sizes in mm would not make a specimen either (less than a stitch
    or more than a patch holds on an axis): no hint that does not help."""
    if not (1.0 <= 10 * min(wales, courses) and 10 * max(wales, courses) <= MAX_STITCHES_PER_AXIS):
        return ""
    return (f"; if the sizes are in cm, write them in mm (width = {10 * width:.6g}, gauge_length = "
            f"{10 * gauge_length:.6g}: {10 * wales:.4g} wales x {10 * courses:.4g} courses)")


def _number(v) -> float:
    """A parameter as a float field value (None, an absent in-plane width, is NaN)."""
    return float("nan") if v is None else float(v)


#: CellParams' own rules, the default of a patch
_DEFAULT = CellParams(B=1.0, d=1.0, L=10.0, W0=4.0, C0=2.0)


class _DefaultCap(float):
    """A cell's default force cap [N] (50 B / d^2 of its own yarn) as the resolved rules hold it: a number to
    the couplings, and marked as the default in the value itself, so that a copy of the model
    (``dataclasses.replace``, which passes the resolved rules back in) keeps the label, and a copy with another
    B or d gets a default cap of its own, as :class:`~knitsim.cell.material.CellParams` does (a blind probe's
    copy lost the label; a separate flag is not passed on by ``replace``)."""

    __slots__ = ()


def _value_codes(values: np.ndarray) -> np.ndarray:
    """An integer per value, equal for equal values; all zeros at once where every value is the first (a
    patch's rules are mostly one: sorting 10^6 objects took 0.3 s a rule)."""
    if len(values) == 0 or bool(np.all(values == values[0])):
        return np.zeros(len(values), np.int64)
    return np.unique(values, return_inverse=True)[1].ravel()


@dataclass(frozen=True)
class Grouping:
    """Cells grouped into independent solves.

    Attributes
    ----------
    group_of_cell : ndarray of int, shape [courses, wales]
        Group solved for each cell.
    cells : dict of str to ndarray, shape [n_groups]
        The parameters of each group's cell: :data:`PARAM_NAMES` (float; NaN: no in-plane width),
        :data:`RULE_NAMES` (objects) and ``effects`` (EffectSet objects), taken from the patch's
        arrays without a loop over the cells; ``params`` builds the validated
        :class:`~knitsim.cell.material.CellParams` list from them on first use.
    rep : ndarray of int, shape [n_groups, 2]
        (course, wale) of a cell that stands for each group (names the cell in errors).
    group_column : ndarray of int, shape [n_groups]
        Column class of each group.
    group_count : ndarray of int, shape [n_groups]
        Cells of the group in one column of its class (multiplicity in series).
    group_count : ndarray of float, shape [n_groups]
        Stitches of the group in series in one column of its class (sum of the course
        counts of its cells; whole numbers for a patch of single stitches).
    column_class : ndarray of int, shape [wales]
        Column class of each wale column.
    class_rest_length : ndarray, shape [n_classes]
        Rest length of a column of the class, sum of course count x C0 along it [mm].
    group_wales : ndarray of float, shape [n_groups]
        Wales in parallel of each cell of the group (1 for single stitches): the column's
        total force is ``group_wales x`` the group's force per wale.
    class_wales : ndarray of float, shape [n_classes]
        Mean number of wales of a column of the class along its rest length (its force per
        wale is its total force over this; 1 for single stitches).
    reference_length : float
        Grip strain = grip displacement / this [mm]: the gauge length of a specimen, else the
        columns' common rest length (their mean when they differ).
    """

    group_of_cell: np.ndarray
    cells: dict
    rep: np.ndarray
    group_column: np.ndarray
    group_count: np.ndarray
    column_class: np.ndarray
    class_rest_length: np.ndarray
    group_wales: np.ndarray | None = None
    class_wales: np.ndarray | None = None
    reference_length: float | None = None

    def __post_init__(self):
        if self.group_wales is None:
            object.__setattr__(self, "group_wales", np.ones(self.n_groups))
        if self.class_wales is None:
            object.__setattr__(self, "class_wales", np.ones(len(self.class_rest_length)))
        if self.reference_length is None:
            per_wale = self.class_rest_length[self.column_class]
            ref = float(per_wale[0]) if np.all(per_wale == per_wale[0]) else float(per_wale.mean())
            object.__setattr__(self, "reference_length", ref)


    @property
    def n_groups(self) -> int:
        """Groups solved."""
        return len(self.group_column)

    def where(self, g: int) -> str:
        """The patch cell that stands for group ``g``, as errors name it."""
        i, j = self.rep[g]
        return f"cell[{int(i)}, {int(j)}]"

    @property
    def d_jam(self) -> np.ndarray:
        """In-plane jamming width of each group's cell [mm]: its in-plane width, or d where none."""
        w = np.asarray(self.cells["in_plane_width"], dtype=np.float64)
        return np.where(np.isnan(w), self.cells["d"], w)

    def cell_params(self, g: int) -> CellParams:
        """The validated :class:`~knitsim.cell.material.CellParams` of group ``g`` (an error names the patch
        cell that stands for it)."""
        c = self.cells
        vals = {n: float(c[n][g]) for n in PARAM_NAMES}
        if not np.isfinite(vals["in_plane_width"]):
            vals["in_plane_width"] = None
        return CellParams(**vals, **{r: c[r][g] for r in RULE_NAMES},
                          effects=c["effects"][g]).validated(where=self.where(g))

    @property
    def params(self) -> list:
        """One validated :class:`~knitsim.cell.material.CellParams` per group (built on first use:
        10^6 cells take seconds here; the Warp engine builds its model from ``cells`` instead, and
        :meth:`validate` checks them without it)."""
        cached = self.__dict__.get("_params")
        if cached is None:
            cached = [self.cell_params(g) for g in range(self.n_groups)]
            object.__setattr__(self, "_params", cached)
        return cached

    def validate(self) -> None:
        """Raise the :class:`~knitsim.errors.KnitsimInputError` that :attr:`params` raises, for the first group
        whose cell :meth:`CellParams.validated <knitsim.cell.material.CellParams.validated>` refuses (the same
        message, naming the same patch cell), without a CellParams per group.

        The arrays flag the groups it may refuse (:func:`~knitsim.cell.material.may_refuse`, a superset) and
        only those are built and validated, in group order: ``knitsim run``'s domain check of a 300 x 300
        random patch built and validated 90,000 CellParams where none was bad (most of the 2.6 s its check
        spent besides the rest-state launch, on a 2-core box; 12.6 s on a GPU host's).
        """
        c = self.cells
        if "_params" in self.__dict__:
            return                               # every group validated already
        cells = {n: c[n] for n in PARAM_NAMES if n != "in_plane_width"}
        # a non-finite width is no width (as cell_params reads it)
        w = np.asarray(c["in_plane_width"], dtype=np.float64)
        cells["in_plane_width"] = np.where(np.isfinite(w), w, np.nan)
        cells.update({r: c[r] for r in RULE_NAMES}, effects=c["effects"])
        for g in np.nonzero(may_refuse(cells, self.n_groups))[0]:
            self.cell_params(int(g))

    @property
    def n_classes(self) -> int:
        """Column classes."""
        return len(self.class_rest_length)


def _grid_size(name: str, v) -> int:
    """A patch's courses or wales: a whole number >= 1 (a zero, negative, fractional or text size failed
    inside numpy: a blind probe of the API)."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < 1:
        raise KnitsimInputError(f"PatchModel.{name} = {v!r}: expected a whole number >= 1")
    return int(v)


@dataclass(frozen=True)
class PatchModel:
    """A patch of cells.

    Attributes
    ----------
    courses, wales : int
        Cells along a wale column (in series) and wale columns (in parallel).
    fields : dict of str to ndarray, shape [courses, wales]
        :data:`PARAM_NAMES`, float64 (units as :class:`~knitsim.cell.material.CellParams`).
    rules : dict of str to ndarray of object, shape [courses, wales]
        :data:`RULE_NAMES` of every cell (a single value is broadcast to every cell).
    effects : ndarray of EffectSet, shape [courses, wales], optional
        The model extensions of every cell (none by default).
    course_count, wale_count : ndarray, shape [courses, wales], optional
        Stitches in series along the wale and wales in parallel that each cell stands for
        (module docstring); 1 by default.  Positive, finite; not necessarily whole numbers
        (a specimen's band holds band length / C0 courses).
    gauge_length : float, optional
        Distance between the grips [mm]: every column's rest length (sum of course count x C0)
        must equal it, and the grip strain is the displacement over it.  Absent: the columns'
        common rest length, or their mean when they differ (each mounted at its own).
    pretension : float
        Strain of the knit between the grips at grip strain 0 (a specimen pretensioned before the
        tester's strain origin, :func:`knitsim.calibration.specimen.pretension_strain`); needs
        ``gauge_length``, and every column's rest length is then ``gauge_length / (1 + pretension)``.
        0: the knit is at rest at grip strain 0.
    """

    courses: int
    wales: int
    fields: dict
    rules: dict = field(default_factory=dict)
    effects: np.ndarray | None = None
    course_count: np.ndarray | None = None
    wale_count: np.ndarray | None = None
    gauge_length: float | None = None
    pretension: float = 0.0

    @property
    def grip_offset(self) -> float:
        """Grip strain from the knit at rest to the strain origin: pretension / (1 + pretension)."""
        return self.pretension / (1.0 + self.pretension)

    def __post_init__(self):
        # checked before numpy sees them: a zero, negative, fractional or text size, a missing or misshapen
        # field failed deep inside numpy (a blind probe of the API)
        for name in ("courses", "wales"):
            object.__setattr__(self, name, _grid_size(name, getattr(self, name)))
        shape = (self.courses, self.wales)
        for n in PARAM_NAMES:
            if n not in self.fields:
                raise KnitsimInputError(f"PatchModel.fields: no {n!r} (expected {', '.join(PARAM_NAMES)})")
            if np.shape(self.fields[n]) != shape:
                raise KnitsimInputError(f"PatchModel.fields[{n!r}]: shape {np.shape(self.fields[n])}, expected "
                                        f"(courses, wales) = {shape}")
        for name in ("course_count", "wale_count"):
            v = getattr(self, name)
            a = np.ones(shape) if v is None else np.array(np.broadcast_to(np.asarray(v, dtype=np.float64), shape))
            if not np.all(np.isfinite(a) & (a > 0)):
                raise KnitsimInputError(f"{name}: every cell must stand for a positive, finite number of stitches")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        pre = float(self.pretension)
        if not (np.isfinite(pre) and 0.0 <= pre <= 0.5):
            raise KnitsimInputError(f"pretension = {self.pretension!r}: a strain of the knit in [0, 0.5]")
        object.__setattr__(self, "pretension", pre)
        if pre > 0 and self.gauge_length is None:
            raise KnitsimInputError("pretension: needs the gauge length (a specimen between grips)")
        if self.gauge_length is not None:
            g = float(self.gauge_length)
            if not (np.isfinite(g) and g > 0):
                raise KnitsimInputError(f"gauge_length = {self.gauge_length!r}: must be > 0 mm")
            rest = self.column_rest_length()
            g_rest = g / (1.0 + pre)
            bad = np.nonzero(np.abs(rest - g_rest) > 1e-9 * g)[0]
            if len(bad):
                j = int(bad[0])
                what = f"the gauge length {g:.9g} mm" + (f" / (1 + pretension {pre:.9g})" if pre else "")
                raise KnitsimInputError(f"column {j}: rest length {rest[j]:.9g} mm (sum of course count x C0) is not "
                                        f"{what}")
            object.__setattr__(self, "gauge_length", g)
        unknown = sorted(set(self.rules) - set(RULE_NAMES))
        if unknown:
            # (a blind probe's rules={"unload_rule": ...} ran with the default rule without a word)
            raise KnitsimInputError(f"rules.{unknown[0]}: unknown rule (expected one of {', '.join(RULE_NAMES)})")
        rules = {}
        for r in RULE_NAMES:
            v = self.rules.get(r, getattr(_DEFAULT, r))
            if isinstance(v, np.ndarray) and v.shape == shape:
                rules[r] = v
            else:
                a = np.empty(shape, dtype=object)
                a[...] = v
                rules[r] = a
        # a default force cap (None) is each cell's own, 50 B / d^2 (knitsim.cell.material.default_force_cap_N):
        # the rules hold numbers, which the couplings read as such; a default resolved earlier (_DefaultCap, the
        # rules of a model copied with dataclasses.replace) is resolved again from this model's B and d
        cap = rules["force_cap_N"]
        unset = np.frompyfunc(lambda x: x is None or isinstance(x, _DefaultCap), 1, 1)(cap).astype(bool)
        if unset.any():
            cap = np.array(cap, dtype=object)
            with np.errstate(divide="ignore", invalid="ignore"):
                own = default_force_cap_N(np.asarray(self.fields["B"], float), np.asarray(self.fields["d"], float))
            cap[unset] = np.frompyfunc(_DefaultCap, 1, 1)(np.broadcast_to(own, shape)[unset])
            rules["force_cap_N"] = cap
        object.__setattr__(self, "rules", rules)
        #: per cell, True where its force cap is the default (rules.force_cap_N not given), for the summary
        object.__setattr__(self, "cap_is_default", unset)
        eff = self.effects
        if not (isinstance(eff, np.ndarray) and eff.shape == shape):
            a = np.empty(shape, dtype=object)
            a.fill(NO_EFFECTS if eff is None else eff)
            object.__setattr__(self, "effects", a)

    @classmethod
    def uniform(cls, params: CellParams, courses: int, wales: int) -> "PatchModel":
        """A patch of ``courses x wales`` copies of one cell."""
        params = params.validated()
        courses, wales = _grid_size("courses", courses), _grid_size("wales", wales)
        fields = {n: np.full((courses, wales), _number(getattr(params, n))) for n in PARAM_NAMES}
        return cls(int(courses), int(wales), fields, {r: getattr(params, r) for r in RULE_NAMES}, params.effects)

    @classmethod
    def from_cells(cls, cells: list[list[CellParams]]) -> "PatchModel":
        """A patch from a nested list ``cells[course][wale]`` (each cell its own rules and effects)."""
        if not len(cells) or not len(cells[0]):
            raise KnitsimInputError("cells: expected a nested list cells[course][wale] of at least one cell")
        courses, wales = len(cells), len(cells[0])
        fields = {n: np.empty((courses, wales)) for n in PARAM_NAMES}
        rules = {r: np.empty((courses, wales), dtype=object) for r in RULE_NAMES}
        effects = np.empty((courses, wales), dtype=object)
        for i in range(courses):
            if len(cells[i]) != wales:
                raise KnitsimInputError(f"cells[{i}]: {len(cells[i])} wales, expected {wales}")
            for j in range(wales):
                p = cells[i][j]
                for r in RULE_NAMES:
                    rules[r][i, j] = getattr(p, r)
                for n in PARAM_NAMES:
                    fields[n][i, j] = _number(getattr(p, n))
                effects[i, j] = p.effects
        return cls(courses, wales, fields, rules, effects)

    @property
    def shape(self) -> tuple[int, int]:
        """(courses, wales)."""
        return (self.courses, self.wales)

    @property
    def cell_count(self) -> int:
        """Cells in the patch (courses x wales)."""
        return self.courses * self.wales

    @classmethod
    def specimen(cls, params: CellParams, width: float, gauge_length: float,
                 pretension: float = 0.0) -> "PatchModel":
        """A uniform specimen ``width`` x ``gauge_length`` [mm] of one knit: one cell standing for
        ``gauge_length / (1 + pretension) / C0`` courses of ``width / W0`` wales."""
        params = params.validated()
        for name, v in (("width", width), ("gauge_length", gauge_length), ("pretension", pretension)):
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(v):
                raise KnitsimInputError(f"specimen {name} = {v!r}: expected a finite number")
        # at least one wale across and one course along, as the scene's [specimen] asks: a width and gauge in
        # metres (0.05, 0.1) made 0.01 wales and a force 1,000 times too small (a blind probe of the API)
        if width < params.W0:
            raise KnitsimInputError(f"specimen width = {width!r} mm: narrower than one wale (W0 = {params.W0:g} mm); "
                                    "widths are in mm")
        if gauge_length / (1.0 + max(float(pretension), 0.0)) < params.C0:
            raise KnitsimInputError(f"specimen gauge_length = {gauge_length!r} mm: shorter than one course "
                                    f"(C0 = {params.C0:g} mm); lengths are in mm")
        refusal, _ = specimen_size_notes(width, gauge_length, width / params.W0,
                                         gauge_length / (1.0 + max(float(pretension), 0.0)) / params.C0)
        if refusal is not None:
            raise KnitsimInputError(f"specimen {width!r} x {gauge_length!r} mm: {refusal}")
        base = cls.uniform(params, 1, 1)
        return cls(1, 1, base.fields, base.rules, base.effects,
                   course_count=np.array([[gauge_length / (1.0 + pretension) / params.C0]]),
                   wale_count=np.array([[width / params.W0]]), gauge_length=gauge_length, pretension=pretension)

    def cell(self, i: int, j: int) -> CellParams:
        """Parameters of cell ``[course i, wale j]`` (validated)."""
        vals = {n: float(self.fields[n][i, j]) for n in PARAM_NAMES}
        if not np.isfinite(vals["in_plane_width"]):
            vals["in_plane_width"] = None
        rules = {r: self.rules[r][i, j] for r in RULE_NAMES}
        if self.cap_is_default[i, j]:
            rules["force_cap_N"] = None          # the default, as the cell scene gives it (its value: cap_N)
        return CellParams(**vals, **rules, effects=self.effects[i, j]).validated(where=f"cell[{i}, {j}]")

    def effect_codes(self) -> tuple[np.ndarray, list]:
        """An integer per cell naming its effect set, and the distinct sets in the order of the codes
        (:func:`~knitsim.cell.effects.effect_set_codes`, row-major)."""
        codes, uniq = effect_set_codes(self.effects.ravel())
        return codes.reshape(self.shape), uniq

    def material_codes(self) -> np.ndarray:
        """An integer per cell naming its rules and effects (equal codes: equal rules and effects)."""
        parts = [_value_codes(np.asarray(self.rules[r]).ravel()) for r in RULE_NAMES]
        parts.append(self.effect_codes()[0].ravel())
        _, first, inverse = np.unique(_row_ids(np.stack(parts, axis=1)), return_index=True, return_inverse=True)
        # numbered in the order the cells first hold them (row-major), as the groups always were
        rank = np.empty(len(first), np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        return rank[inverse.ravel()].reshape(self.shape)

    @property
    def unit_counts(self) -> bool:
        """Every cell a single stitch (the classic ``courses x wales`` patch)."""
        return bool(np.all(self.course_count == 1.0) and np.all(self.wale_count == 1.0))

    @property
    def blocks(self) -> bool:
        """Its cells are blocks of stitches (``bands x strips``): a specimen between grips, even where a block
        happens to hold one stitch, or cells of other counts."""
        return self.gauge_length is not None or not self.unit_counts

    def column_rest_length(self) -> np.ndarray:
        """Rest length of each wale column, sum of course count x C0 along it [mm], shape [wales]."""
        if np.all(self.course_count == 1.0):
            return self.fields["C0"].sum(axis=0)
        return (self.course_count * self.fields["C0"]).sum(axis=0)

    def column_wales(self) -> np.ndarray:
        """Mean wale count of each column along its rest length, shape [wales] (1 for single stitches)."""
        if np.all(self.wale_count == 1.0):
            return np.ones(self.wales)
        length = self.course_count * self.fields["C0"]
        return (length * self.wale_count).sum(axis=0) / length.sum(axis=0)

    def grouping(self, dedup: bool = True) -> Grouping:
        """Group identical cells (see the module docstring); ``dedup=False``: one group per cell."""
        courses, wales = self.shape
        # (an absent in-plane width, NaN, groups as one value); the wale count is part of a cell's identity
        counts = self.course_count
        if dedup:
            stack = np.stack([np.nan_to_num(self.fields[n], nan=-1.0) for n in PARAM_NAMES]
                             + [self.material_codes().astype(float), self.wale_count], axis=-1)
            mat_id = _row_ids(stack.reshape(-1, stack.shape[-1])).reshape(courses, wales)
            # a column class is the multiset of its materials, with their stitch counts (order along the
            # column is irrelevant in series)
            # (each column's distinct materials in ascending id and their count sums, over every column at once:
            # the (column, material) pairs sorted, the sums added in course order as a column's own bincount
            # does; a column's key is the bytes of both, equal exactly where ids and sums are: the sums are
            # positive and finite. A loop of np.unique per column took 0.5 s of a 10^6-cell patch's set-up)
            pair = (np.arange(wales, dtype=np.int64)[:, None] * (int(mat_id.max()) + 1) + mat_id.T).ravel()
            pairs, pair_inv = np.unique(pair, return_inverse=True)
            pair_sums = np.bincount(pair_inv.ravel(), weights=counts.T.ravel(), minlength=len(pairs))
            pair_ids = pairs % (int(mat_id.max()) + 1)
            bounds = np.searchsorted(pairs // (int(mat_id.max()) + 1), np.arange(wales + 1))
            col_keys = [pair_ids[a:b].tobytes() + pair_sums[a:b].tobytes() for a, b in zip(bounds[:-1], bounds[1:])]
            classes: dict = {}
            column_class = np.array([classes.setdefault(k, len(classes)) for k in col_keys], dtype=np.int64)
            # a group is a (column class, material): numbered in the order the cells first hold them, wale
            # column by column, course by course (vectorised: the loops over the cells and over the groups
            # took 72 s of a 600 x 600 patch's first increment, O(groups x courses))
            key = (column_class[None, :] * (int(mat_id.max()) + 1) + mat_id).T.ravel()   # (j, i) order
            _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
            rank = np.empty(len(first), np.int64)
            rank[np.argsort(first, kind="stable")] = np.arange(len(first))
            order_g = rank[inverse.ravel()]                            # each cell's group, (j, i) order
            group_of_cell = order_g.reshape(wales, courses).T.copy()
            n_groups = len(first)
            group_column = np.empty(n_groups, np.int64)
            group_column[order_g] = np.repeat(column_class, courses)
            # each group's count and representative from the first column of its class
            _, first_col = np.unique(column_class, return_index=True)
            in_first = np.zeros(wales, bool)
            in_first[first_col] = True
            cells_j = np.repeat(np.arange(wales), courses)
            cells_i = np.tile(np.arange(courses), wales)
            sel = in_first[cells_j]
            g_sel, i_sel, j_sel = order_g[sel], cells_i[sel], cells_j[sel]
            unit = bool(np.all(counts == 1.0))
            group_count = np.bincount(g_sel, weights=None if unit else counts[i_sel, j_sel],
                                      minlength=n_groups).astype(np.float64)
            _, at = np.unique(g_sel, return_index=True)                # first course of each group (sorted g)
            rep = np.stack([i_sel[at], j_sel[at]], axis=1).astype(np.int64)
        else:
            column_class = np.arange(wales, dtype=np.int64)
            group_of_cell = np.arange(courses * wales, dtype=np.int64).reshape(courses, wales)
            group_column = np.tile(np.arange(wales), courses).astype(np.int64)
            group_count = counts.ravel().astype(np.float64)
            rep = np.stack(np.unravel_index(np.arange(courses * wales), (courses, wales)), axis=1)
        ri, rj = rep[:, 0], rep[:, 1]
        # (the representatives' flat indices once: indexing each field with (ri, rj) computed them per field)
        flat = ri * wales + rj
        cells = {n: np.asarray(self.fields[n], dtype=np.float64).ravel()[flat] for n in PARAM_NAMES}
        cells.update({r: self.rules[r].ravel()[flat] for r in RULE_NAMES})
        cells["effects"] = self.effects.ravel()[flat]
        n_cls = int(column_class.max()) + 1
        # (bincount adds in group order, as the loop over the groups did)
        rest = np.bincount(group_column, weights=group_count * cells["C0"], minlength=n_cls).astype(np.float64)
        group_wales = np.asarray(self.wale_count, dtype=np.float64)[ri, rj]
        _, first = np.unique(column_class, return_index=True)   # the first wale column of each class
        class_wales = self.column_wales()[first]
        ref = self.gauge_length
        if ref is not None:
            # (equal to it within 1e-9, checked; exactly it for the grip strain); a pretensioned knit
            # rests shorter than the gauge length, and the solver's grip strain runs from its rest state
            rest[:] = ref if self.pretension == 0 else ref / (1.0 + self.pretension)
        return Grouping(group_of_cell, cells, np.asarray(rep, np.int64), group_column, group_count, column_class,
                        rest, group_wales, class_wales, ref)
