"""Stages of the load cycle (Dusserre 2015, Table 4) and the rules where it is silent.

One table shared by the NumPy reference cycle and the Warp cycle kernel.

Under strain control the driven quantity of every stage is the course length C
(change in length = (C - C0) / C0).  Table 4 drives phi in the static-friction
steps instead; that traces the same branch as long as C is monotonic in phi
there.  Besides C and the yarn length L, each stage imposes one *hard*
condition (s_BC in static friction: no slip at B; phi = +/-phimax in sliding)
and one *soft* condition, whose value is frozen when the stage is entered.

Jamming is a unilateral contact constraint, W >= 4d (Hong et al. 2002), kept in
every stage: a cell whose solution would have W < 4d is *jammed*, and its soft
condition is replaced by W = 4d.  Table 4's J step is therefore "S_LOAD,
jammed"; unloading from a jammed state is "SF_UNLOAD, jammed" until the
unjammed solution has W >= 4d again (active-set rule; Table 4 is silent).

==========  ============================  ======================  =============
stage       hard conditions (with C, L)   soft (frozen at entry)  events
==========  ============================  ======================  =============
SF_LOAD     s_BC = frozen (stick)         Rn  (Table 4 SF)        phi -> +phimax
S_LOAD      phi = +phimax                 Rn  (Table 4 S)         jam (W -> 4d)
SF_UNLOAD   s_BC = frozen (stick)         beta (Table 4 SF-)      phi -> -phimax,
                                          or T (Hong rule)        F -> 0,
                                                                  cone (beta only)
S_UNLOAD    phi = -phimax                 T   (Table 4 S-)        F -> 0
SLACK       (none: the cell went slack at F = 0 while unloading and carries no
            load until the imposed C returns to the C where it went slack)
==========  ============================  ======================  =============

Output labels: ``jamming`` when jammed, else ``adherence`` (SF_*) or
``sliding`` (S_*), or ``slack``; with the direction ``load`` / ``unload``.

Rules where Table 4 is silent (switchable; labelled in every output):

``unloading_rule``
    ``"dusserre"``: SF- freezes beta (Table 4), S- freezes T.
    ``"hong_constant_t"``: T frozen through the whole unloading (Hong et al. 2002).
``reload_rule``
    On reloading from a state whose contact force is ~0 (after going slack),
    fixing Rn = 0 would reload at zero force for ever.
    ``"mirror_unloading"``: the reload mirrors the unloading: SF+ freezes beta
    instead of Rn (the mirror of SF-) and S+ freezes T (the mirror of S-).
    Why not Rn in S+: where the cell went slack, F = 2 P sin(gamma) = 0 and
    R_Y = -R cos(beta + phi) = P sin(gamma) (eq 7) give R = 0 (beta + phi !=
    pi/2), so the reload starts at zero contact, the beta-frozen stick leaves
    the cone at once and Rn frozen there is 0.  With Rn = 0 (|phi| < pi/2) the
    conditions {L, C, phi = phimax, Rn = 0} are met for *every* C by the
    zero-contact family (R = 0, gamma = 0: a free elastica under horizontal end
    loads, the loop narrowing as it lengthens), which carries F = 0: frozen
    there, Rn no longer ties the force to C.  T = -P cos(gamma) = -P is not
    degenerate there (knitsim issue 13, "the pocket").  A Dahl cell, whose
    unloading freezes T throughout, freezes T through such a reload (its Dahl
    solve is singular on the zero-contact family: it failed to converge).
    ``"freeze_rn"``: Table 4 as printed (Rn frozen even if ~0).
``jamming_criterion``
    ``"w_4d"``: W = 4d (Hong).  ``"head_gap"``: flag when the centreline
    distance between the heads of neighbouring loops of a course falls to d
    (the heads bulge beyond B, so this happens before W = 4d).
``stick_closure`` (argument of the engines, not a CellParams field)
    Table 4's SF- freezes beta and s_BC.  Reversing from sliding at +phimax,
    that stick branch often needs phi > +phimax at once (E-glass/basalt cells,
    m > ~0.15): phi runs to pi/2 within a strain of ~0.006 while F > 0, which
    looks like a fold of C(phi) and defeated the strain-controlled solve.
    Past +phimax the friction the closure asks for is not available, so the
    closure, not the stick, is inadmissible there.
    ``"release_beta"`` (default): event ``cone`` where phi reaches +phimax in
    SF- with beta frozen (located like the other events, on the branch, the
    state is continuous); from there the stick goes on (s_BC still frozen)
    with T frozen at its value at the event (Hong's closure), until phi
    reaches -phimax (slide, S-) or F = 0 (slack).  At the reversal from
    sliding the cone function is zero at the start; a probe step of
    ``PROBE_STEP`` C0 toward the target decides whether the branch leaves the
    cone (or does not continue at all), and the event then happens at the
    reversal point.  ``"table4"``: as printed (no such event; such cells stop
    ``no_convergence``).
``cone`` zero at the start of a sub-step
    At a reversal from sliding the cone function is zero at the start; when the
    probe stays inside the cone but a trial end is outside it, the beta-frozen
    stick dips into the cone and leaves it further on: located by bisection on
    the sign of phimax - phi (not placed at the start).
``EVENT_TOL``
    An event function within EVENT_TOL of zero (rad; times d for W; times the
    yarn's force scale B / d^2 for F and Rn) at the start of a sub-step counts
    as satisfied there: the event happens at the start, without a root search
    whose bracket rounding could miss it.  (In newtons, as it was, a cell of
    B / d^2 = 9e-8 N went slack an increment early, at F = 5.7e-10 N:
    tests/cell/test_invariances.py.)
    This is how unloading from a jammed state unjams at the reversal point
    (the unjammed branch passes through the jammed state itself there).
    A trial end that fires an event its own branch cannot reach (the solve
    jumped to another branch) is retried on a halved sub-step; only when the
    halvings run out is the cell flagged ``event_not_located``.
``force_cap_N``
    The jammed branch's force diverges at its limit strain: a cell stops,
    flagged ``force_cap``, when its force per wale reaches the cap.
``SUBSTEP_FLOOR``, ``MAX_HALVINGS``
    A sub-step whose solve fails (or whose event cannot be located, or whose
    unjamming cannot be decided) is halved and retried, down to
    SUBSTEP_FLOOR C0 (at most MAX_HALVINGS halvings in a row, by default);
    a converged sub-step doubles the step back.  The floor is a length, not a
    count: a stick branch can end within 1e-4 C0 of a reversal (the SF- stick
    of a cell that carries little force, m = 0.1: phi runs from +phimax to
    -phimax over 7e-5 C0, and the beta-frozen stick has no solution beyond),
    and its slide event can only be located from a sub-step that ends on it.
    Only when the floor is reached is the cell flagged.

The far side of the cone while loading (why SF+ has no ``phi -> -phimax`` event)
    In SF+ Table 4 freezes s_BC and Rn, so the friction angle follows the
    tangential force alone: tan(phi) = Rt / Rn.  Rt is the jump of the yarn
    tension across the stuck crossing, leg minus head (it points toward C when
    the leg pulls harder); loading pulls the leg, so along a stick branch
    dRt/dC > 0, and dphi/dC = cos(phi)^2 (dRt/dC) / Rn.  With Rn > 0 phi
    therefore rises toward +phimax (the slide event), and the far edge
    -phimax is only ever met at the start of SF+: at a reversal from S-
    (phi = -phimax), where the limit case dphi/dC > 0 takes the stick into the
    cone at once (the sequence S- -> reversal -> SF+ (adherence) -> S+, as
    Table 4 prints).  The far edge can only be crossed with Rn <= 0: a pulling
    contact (outside the model: the contact at B is unilateral) or no contact.
    Neither is left to reach SF+:

    - unloading goes slack where the contact opens.  Eq 7 gives
      F = -2 R cos(beta + phi); where R and cos(beta + phi) change sign
      together F only touches 0 (or dips below it within one increment and
      comes back), the slack event on F alone was missed, the S- branch went
      on with R < 0 and a reload froze that tensile Rn: the stick then ran
      to phi -> -pi/2 (a domain cell on a waypoint program, tests/cell/
      test_far_side.py).  A sub-step whose trial end pulls (Rn < 0) now ends
      where Rn changes sign along the branch, found by bisection on the sign
      of Rn over converged states (Newton cannot: R = 0 is singular, phi drops
      out, and Rn = 0 is also met at phi = -pi/2), and every event is judged
      on that admissible part: a stick whose Rn -> 0 while its tangential
      force remains leaves the cone first (cone or slide; SF- with beta
      frozen, bench cells 932, 1632, 2305, 1424 of issue 14, which went slack
      at the second zero of F with R < 0); where F reached 0 first
      (cos(beta + phi) > 0 at the opening: beta + phi passed pi/2 with R > 0)
      the slack is there, by bisection on the sign of F; else the cell goes
      slack where the contact opens (R -> 0, |R| < ZERO_CONTACT P).  Same in
      both engines (kernels.cell_step.branch_sign_change, CellCycle._sign_change);
      an F sign change with R > 0 at the trial end is located by Newton on
      F = 0 as before;
    - a reload at zero contact (|R| < ZERO_CONTACT P) decides on a probe
      step whether it slides; the probe's angle beyond *either* edge means
      sliding (with R = 0 no tangential force is held; the edge reached is
      the sign of the seed's R, the imposed motion gives the slip direction).

    The invariant (no SF+ state with phi < -phimax, no state with
    Rn < -ZERO_CONTACT P) is asserted over random cells of the domain through
    random programs (tests/cell/test_convergence_property.py,
    tests/cell/test_far_side.py), Warp batch and NumPy reference alike.

Dahl friction replaces the SF/S switch by one smooth law: tan(phi) follows
the Dahl update of the slip xi = -s_BC (Dahl 1976; see
:mod:`knitsim.friction.dahl`); the soft condition is Rn while loading and T
while unloading; the stage label is ``sliding`` once tan(phi) is within 5 %
of its saturation +/-m, else ``adherence``.
"""
from __future__ import annotations

from enum import IntEnum

import numpy as np


class Stage(IntEnum):
    """Stage codes (stored per cell as int32; the jammed flag is separate)."""

    SF_LOAD = 0
    S_LOAD = 1
    SF_UNLOAD = 2
    S_UNLOAD = 3
    SLACK = 4

    @property
    def loading(self) -> bool:
        """Whether the stage belongs to a loading branch."""
        return self in (Stage.SF_LOAD, Stage.S_LOAD)

    @property
    def sliding(self) -> bool:
        """Whether phi sits at +/-phimax (Coulomb sliding)."""
        return self in (Stage.S_LOAD, Stage.S_UNLOAD)


def stage_label(stage: int, jammed: bool) -> str:
    """Output label of a stage: adherence / sliding / jamming / slack."""
    stage = Stage(int(stage))
    if stage is Stage.SLACK:
        return "slack"
    if jammed:
        return "jamming"
    return "sliding" if stage.sliding else "adherence"


#: label codes used in per-cell output arrays and USD primvars
LABEL_CODES = {"adherence": 0, "sliding": 1, "jamming": 2, "slack": 3}

#: stage_label(stage, jammed) for every stage code (rows) and jammed flag (columns), and their codes: the
#: vectorised lookups below serve histories of millions of rows (the diagnosis reads every fit's labels)
_LABEL_TABLE = np.array([[stage_label(s, j) for j in (False, True)] for s in sorted(int(x) for x in Stage)])
_CODE_TABLE = np.vectorize(LABEL_CODES.get, otypes=[np.int32])(_LABEL_TABLE)


def _table_lookup(table: np.ndarray, stage, jammed) -> np.ndarray:
    """``table[stage, jammed != 0]``, refusing a stage code that is none (as ``Stage(code)`` would)."""
    stage = np.asarray(stage)
    if stage.size and (stage.min() < 0 or stage.max() >= len(table)):
        bad = stage[(stage < 0) | (stage >= len(table))].flat[0]
        raise ValueError(f"{int(bad)} is not a valid Stage")
    # (one flat index: a [stage, jammed] lookup of 10^6 rows converted both index arrays)
    return np.take(table.ravel(), 2 * stage.astype(np.intp) + (np.asarray(jammed) != 0))


def stage_labels(stage, jammed) -> np.ndarray:
    """:func:`stage_label` of arrays of stage codes and jammed flags (same shape), as an array of str."""
    return _table_lookup(_LABEL_TABLE, stage, jammed)


def stage_label_codes(stage, jammed) -> np.ndarray:
    """:data:`LABEL_CODES` of :func:`stage_labels`, int32."""
    return _table_lookup(_CODE_TABLE, stage, jammed)

UNLOADING_RULES = ("dusserre", "hong_constant_t")
RELOAD_RULES = ("mirror_unloading", "freeze_rn")
JAMMING_CRITERIA = ("w_4d", "head_gap")
FRICTION_MODELS = ("coulomb", "dahl")
#: the largest Dahl stiffness [1/mm] a cell takes: beyond it the Dahl transition (m / sigma of slip) is
#: shorter than 3e-7 mm and the law is Coulomb's (a patch at sigma = 1e6 within 1e-6 N of the Coulomb one,
#: a blind probe), while the cell Newton, whose residual turns within that slip, no longer converges (at
#: 1e7, a cycle failed at strain 0.49, and on its first increment at increments of 0.001)
DAHL_SIGMA_MAX = 1.0e6
DAHL_SIGMA_TOO_STIFF = (f"above {DAHL_SIGMA_MAX:g} 1/mm the Dahl law is Coulomb friction to 1e-6 N and its "
                        "solve does not converge: use friction.model = \"coulomb\" with rules.unloading_rule = "
                        "\"hong_constant_t\" (the Dahl law's limit: Hong's constant-T unloading)")
#: the largest friction ratio m = Rt/Rn = tan(phimax) a cell takes: yarn on yarn measures 0.1-0.6 (Dusserre 2015,
#: Tables 2-3, eq 10); m = 5 is already a friction cone of 79 deg.  A blind probe's m = 50 ran with only the
#: domain's extrapolation warning (the domain's box is 0.05-0.5)
M_MAX = 5.0
M_TOO_LARGE = (f"a friction ratio Rt/Rn above {M_MAX:g} (phimax = atan m above 79 deg) is no yarn's: yarn on "
               "yarn measures 0.1-0.6 (Dusserre 2015, Tables 2-3; eq 10)")
#: a Dahl stiffness given to a cell of another friction law (a blind probe's --set friction.dahl_sigma=5 on a
#: Coulomb scene ran Coulomb, silently)
DAHL_SIGMA_UNUSED = ("not used by friction.model = \"coulomb\": set friction.model = \"dahl\" to use it, "
                     "or leave dahl_sigma out")
#: closures of a stick stage whose frozen beta asks for friction beyond the cone
STICK_CLOSURES = ("release_beta", "table4")
#: an event function within EVENT_TOL (rad, or times d for W, or times B / d^2 for F and Rn: the cell's
#: own units, so that a scaled cell decides alike) of zero at the start of a sub-step counts as satisfied
#: there: the event happens at the start
EVENT_TOL = 1.0e-9
#: an imposed course length within this fraction of the cell's own C is reached (rounding): the
#: sub-steps stop there, and a slack cell asked for no more than its slack length stays slack
REACHED_RTOL = 1.0e-15
#: probe step (times C0) that decides whether a ``cone`` event at zero at the start happens there
PROBE_STEP = 1.0e-6
#: shortest sub-step (times C0) that a failed solve is halved to before the cell is flagged
SUBSTEP_FLOOR = 1.0e-9
#: default cap on the halvings of a failed sub-step in a row (the floor ends them first from any
#: increment above 2^-40 C0)
MAX_HALVINGS = 40
#: Dahl friction retries a failed increment on 2, 4, ... 2^k equal sub-increments, each attempt from
#: the start (the Dahl state moves along the path): at most this many doublings
MAX_DAHL_HALVINGS = 8

#: a state whose contact force R is below ZERO_CONTACT P has no contact force: its friction
#: angle is undetermined (R = 0 makes phi drop out of every equation), so
#: - unloading it goes slack at once (there is no load to remove);
#: - reloading it starts Newton from R/P = RELOAD_RHO_SEED instead of 0 (a singular Jacobian);
#: - an event fired in a sub-step that starts there is judged on a probe step of
#:   PROBE_STEP C0 (the limit of the new branch), not on the undetermined phi of the start;
#: - reloading it with the mirror rule freezes beta, not the (vanishing) Rn.
#: 1e-4, not round-off: the slack event is located on F = 0, where R is only ~1e-5 P (its
#: residual conditioning); with 1e-9 such a state froze a tensile Rn ~ -1e-6 N on reloading and
#: the stick branch left the friction cone on the far side (tests/cell/test_batch.py).
ZERO_CONTACT = 1.0e-4
RELOAD_RHO_SEED = 1.0e-3
#: the contact's opening inside an unloading sub-step (its trial end has Rn < 0) is located by bisection on
#: the sign of Rn along the branch, to a bracket of OPENING_XTOL max(1, C) mm, at most OPENING_BISECTIONS
#: halvings (the bracket starts at one sub-step, at most a load increment)
OPENING_XTOL = 1.0e-13
OPENING_BISECTIONS = 64
