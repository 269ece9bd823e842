"""Stages of the load cycle (Dusserre 2015, Table 4) and the rules where it is silent.

One table shared by the NumPy reference cycle and the Warp cycle kernel.  Under
strain control the driven quantity of every stage is the course length C
(change in length = (C - C0) / C0); Table 4 drives phi in the static-friction
steps instead, which traces the same branch because C is monotonic in phi there.
Each stage imposes three further conditions; *frozen* values are captured when
the stage is entered.

Jamming (W >= 4d) is treated as a unilateral contact constraint in every stage:
when a stage's solution would have W < 4d, its *soft* condition (the one that
is not L, phi or s_BC) is replaced by W = 4d (the jammed variant of the stage),
and the stage unjams when the soft quantity returns to its frozen value.

=============  ===========  ======================================  ==========
stage          label        conditions besides C (Table 4)          soft
=============  ===========  ======================================  ==========
SF_LOAD        adherence    s_BC = frozen, Rn = frozen, L           Rn
S_LOAD         sliding      Rn = frozen, L, phi = +phimax           Rn
J_LOAD         jamming      W = 4d, L, phi = +phimax                (jammed)
SF_UNLOAD      adherence    beta = frozen, s_BC = frozen, L         beta
S_UNLOAD       sliding      T = frozen, L, phi = -phimax            T
J_UNLOAD       jamming      W = 4d, s_BC = frozen, L                (jammed)
SLACK          slack        F = 0 reached while unloading: the      --
                            cell carries no load until reloading
                            returns to the strain where it went
                            slack
=============  ===========  ======================================  ==========

Rules where Table 4 is silent (switchable, labelled in every output):

- ``unloading_rule``: ``"dusserre"`` (SF-: beta and s_BC frozen; S-: T frozen)
  or ``"hong_constant_t"`` (T frozen during the whole unloading, Hong et al. 2002).
- ``reload_rule`` (reloading from a state whose contact force is ~0, where
  fixing Rn would reload at zero force for ever): ``"mirror_unloading"``
  (SF+ freezes beta and s_BC, like SF-) or ``"freeze_rn"`` (Table 4 as printed).
- ``jamming_criterion``: ``"w_4d"`` (Hong: W = 4d) or ``"head_gap"``
  (centreline distance between neighbouring loop heads = d).
- ``force_cap_N``: the jammed branch's force diverges at its limit strain;
  the cell stops (flagged ``force_cap``) when the force per wale reaches it.
"""
from __future__ import annotations

from enum import IntEnum


class Stage(IntEnum):
    """Stage codes (stored per cell as int32)."""

    SF_LOAD = 0
    S_LOAD = 1
    J_LOAD = 2
    SF_UNLOAD = 3
    S_UNLOAD = 4
    J_UNLOAD = 5
    SLACK = 6

    @property
    def label(self) -> str:
        """Short label for outputs: adherence / sliding / jamming / slack."""
        return _LABELS[self]

    @property
    def loading(self) -> bool:
        """Whether the stage belongs to a loading branch."""
        return self in (Stage.SF_LOAD, Stage.S_LOAD, Stage.J_LOAD)


_LABELS = {
    Stage.SF_LOAD: "adherence", Stage.S_LOAD: "sliding", Stage.J_LOAD: "jamming",
    Stage.SF_UNLOAD: "adherence", Stage.S_UNLOAD: "sliding", Stage.J_UNLOAD: "jamming",
    Stage.SLACK: "slack",
}

UNLOADING_RULES = ("dusserre", "hong_constant_t")
RELOAD_RULES = ("mirror_unloading", "freeze_rn")
JAMMING_CRITERIA = ("w_4d", "head_gap")
