"""Names and integer codes of the quantities of a quarter-stitch cell.

One table shared by the NumPy reference (:mod:`knitsim.cell`) and the Warp
kernels (:mod:`knitsim.kernels`): a *condition* imposes ``quantity[code] = target``
in the inverse solve, and the load cycle (Dusserre 2015, Table 4) is written as
sets of four such conditions.

Conventions (Dusserre 2015 section 3, Hong et al. 2002; see docs in
``model.md``): X from the vertical through the loop apex C, Y upward from the
inflection point A; theta(s) is the angle from +X to the tangent, arc length s
runs A -> B -> C, theta_A = alpha, theta_B = beta, theta_C = pi.

==========  ===========================================================  =====
name        definition                                                   unit
==========  ===========================================================  =====
alpha       tangent angle at the inflection point A                      rad
beta        tangent angle at the crossing point B                        rad
gamma       angle between -X and the force P at A                        rad
phi         friction angle at B: R makes phi with the normal, tan = Rt/Rn rad
P           force at A, acting as -P (cos gamma, sin gamma)              N
W           wale width, W/4 = X_B - (d/2) sin(beta) = X_A (eq 6)         mm
C           course length, C/2 = Y_B + (d/2) cos(beta) (eq 6)            mm
L           yarn length per stitch, L/4 = s_AB + s_BC (eq 6)             mm
s_AB        arc length A -> B (eq 8)                                     mm
s_BC        arc length B -> C (eq 9)                                     mm
X_A         abscissa of A                                                mm
X_B         abscissa of B                                                mm
Y_B         ordinate of B                                                mm
Y_C         ordinate of C                                                mm
T           horizontal force at C, T = -P k1' (eq 7)                     N
M           moment at C (eq 7)                                           N mm
R           magnitude of the contact force at B                          N
Rn          normal component of R, R cos(phi)                            N
Rt          tangential component of R (toward C), R sin(phi)             N
F           force per wale, 2 P sin(gamma) (two yarn legs per wale cut)  N
==========  ===========================================================  =====
"""
from __future__ import annotations

QUANTITY_NAMES: tuple[str, ...] = (
    "alpha", "beta", "gamma", "phi", "P",
    "W", "C", "L", "s_AB", "s_BC", "X_A", "X_B", "Y_B", "Y_C",
    "T", "M", "R", "Rn", "Rt", "F",
)

#: code of each quantity, e.g. ``CODE["Rn"]``
CODE: dict[str, int] = {name: i for i, name in enumerate(QUANTITY_NAMES)}

# module-level constants so kernels and Python share one table
(Q_ALPHA, Q_BETA, Q_GAMMA, Q_PHI, Q_P,
 Q_W, Q_C, Q_L, Q_S_AB, Q_S_BC, Q_X_A, Q_X_B, Q_Y_B, Q_Y_C,
 Q_T, Q_M, Q_R, Q_RN, Q_RT, Q_F) = range(len(QUANTITY_NAMES))

#: unknowns of the inverse solve, in this order
UNKNOWN_NAMES: tuple[str, ...] = ("alpha", "beta", "gamma", "phi", "P")
