"""The series coupling of a column (knitsim.patch.coupling.PatchSolver) on cells whose law is known in
closed form, against the exact column force from an independent root finder.

Source: a column of cells in series carries one force F and its lengths add up to the grip
displacement, ``sum_g (C_g(F) - C0) = u``.  Each cell here is a one-dimensional elastoplastic slider
with slack, a caricature of the stitch's stages (stick: elastic k1; S+: loading slide with
hardening h, a plateau k1 h / (k1 + h) after a kink; S-: unloading slide back towards its zero-force
length a0 with slope h2; slack: F = 0 for C <= a0), for which C_g(F) on the branch of an increment
is explicit.  The exact column force of every increment is then the root of a monotone scalar
equation, found by ``scipy.optimize.brentq`` on the closed form, the states evolved with it: no
part of the coupling is used.  The cells differ (yield, hardening, zero-force length), so that some
are on a plateau while others stick, go slack at different grip positions and reload from slack:
the cases of issue 15 item 5.  The coupling must match the exact force at every increment, converge
on every increment, and do so in few trials.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from knitsim.cell.load_program import cycles
from knitsim.cell.material import CellParams
from knitsim.cell.stages import Stage
from knitsim.patch.coupling import COL_OK, PatchSolver
from knitsim.patch.model import PatchModel

C0 = 2.7
K1 = 5.0          # N/mm, elastic (stick) stiffness


class Slider:
    """Closed-form cells: zero-force length ``a`` (state), ``F = k1 max(0, C - a)``, loading yield
    ``F <= Y0 + h (a - a0)``, unloading slide where ``F < h2 (a - a0)``, ``a >= a0`` (h2 < h: the
    unloading slide stays below the loading yield)."""

    def __init__(self, a0, Y0, h, h2):
        self.a0, self.Y0, self.h, self.h2 = (np.asarray(v, float) for v in (a0, Y0, h, h2))

    def step(self, a, C):
        """The state and force after a monotone step from zero-force length ``a`` to ``C``."""
        Fe = K1 * (C - a)
        a_load = (K1 * C - self.Y0 + self.h * self.a0) / (K1 + self.h)
        a_unload = np.maximum(self.a0, (K1 * C + self.h2 * self.a0) / (K1 + self.h2))
        a1 = np.where(Fe > self.Y0 + self.h * (a - self.a0), a_load,
                      np.where(Fe < self.h2 * (a - self.a0), a_unload, a))
        return a1, np.maximum(0.0, K1 * (C - a1))

    def length_at(self, a, F, direction):
        """C(F) of each cell on the branch of a step from ``a`` in ``direction`` (F > 0)."""
        if direction > 0:
            yield_F = self.Y0 + self.h * (a - self.a0)
            return np.where(F <= yield_F, a + F / K1, self.a0 + (F - self.Y0) / self.h + F / K1)
        slide_F = self.h2 * (a - self.a0)
        return np.where(F >= slide_F, a + F / K1, self.a0 + F / self.h2 + F / K1)


class SliderBackend:
    """The trial-step interface of knitsim.patch.coupling (WarpBackend's) for Slider cells."""

    def __init__(self, law: Slider):
        self.law, self.n = law, len(law.a0)
        self.a = law.a0.copy()
        self.C = np.full(self.n, C0)
        self.t_a, self.t_C = self.a.copy(), self.C.copy()
        self.res_a, self.res_C = self.a.copy(), self.C.copy()

    def _out(self, a, C):
        law = self.law
        F = np.maximum(0.0, K1 * (C - a))
        slack = C <= a
        sliding_up = np.isclose(F, law.Y0 + law.h * (a - law.a0), rtol=1e-12, atol=1e-15) & ~slack
        sliding_dn = (a > law.a0) & np.isclose(F, law.h2 * (a - law.a0), rtol=1e-12, atol=1e-15) & ~slack
        stage = np.where(slack, Stage.SLACK, np.where(sliding_up, Stage.S_LOAD,
                                                      np.where(sliding_dn, Stage.S_UNLOAD, Stage.SF_LOAD)))
        z = np.zeros(self.n)
        return {"C": C.copy(), "F": F, "phi": z, "W": z, "stage": stage.astype(np.int32),
                "jammed": np.zeros(self.n, np.int32), "status": np.zeros(self.n, np.int32), "head_gap": z}

    def committed(self):
        return self._out(self.a, self.C)

    def tangent(self, trial, direction=0):
        """dF/dC of the branch: elastic k1, or the slide's plateau; NaN where slack."""
        law = self.law
        a, C = (self.t_a, self.t_C) if trial else (self.a, self.C)
        st = self._out(a, C)["stage"]
        up, dn = K1 * law.h / (K1 + law.h), K1 * law.h2 / (K1 + law.h2)
        if trial:
            k = np.where(st == Stage.S_LOAD, up, np.where(st == Stage.S_UNLOAD, dn, K1))
        else:   # the stage that the increment's direction continues or a reversal enters
            k = np.where((st == Stage.S_LOAD) & (direction > 0), up,
                         np.where((st == Stage.S_UNLOAD) & (direction < 0), dn, K1))
        return np.where(st == Stage.SLACK, np.nan, k)

    def trial(self, strain, direction, increment):
        self.t_C = C0 * (1.0 + np.asarray(strain, float))
        self.t_a, _ = self.law.step(self.a, self.t_C)
        return self._out(self.t_a, self.t_C)

    def begin_increment(self):
        self.res_a, self.res_C = self.a.copy(), self.C.copy()

    def accept(self, mask):
        self.res_a = np.where(mask, self.t_a, self.res_a)
        self.res_C = np.where(mask, self.t_C, self.res_C)

    def end_increment(self):
        self.a, self.C = self.res_a.copy(), self.res_C.copy()
        return self.committed()


def test_column_force_equals_the_exact_root_through_plateaus_slack_and_reloads():
    rng = np.random.default_rng(15)
    n = 6
    # h2 < h keeps the unloading slide below the loading yield at every state (a stable law)
    h = rng.uniform(0.002, 0.05, n)
    law = Slider(a0=C0 * (1.0 + rng.uniform(0.12, 0.2, n)), Y0=rng.uniform(0.05, 0.12, n),
                 h=h, h2=h * rng.uniform(0.3, 0.9, n))
    grouping = PatchModel.from_cells([[CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=C0)]] * n).grouping(False)
    solver = PatchSolver(grouping, engine="reference")
    solver.backend = SliderBackend(law)
    solver.cells = solver.backend.committed()
    solver.k = np.full(n, K1)
    prog = cycles(0.10, 0.60, 2, 0.01)
    a_exact = law.a0.copy()
    trials, slack_seen, reload_from_slack = [], 0, 0
    for e, d in zip(prog.strain, prog.direction):
        u = e * n * C0
        # exact: the column is slack where the cells' zero-force lengths leave the grips' distance over
        if np.sum(law.length_at(a_exact, 1e-300, d) - C0) >= u:
            F_exact = 0.0
            C_exact = np.minimum(a_exact, law.a0)
        else:
            F_exact = brentq(lambda F: np.sum(law.length_at(a_exact, F, d) - C0) - u, 1e-300, 100.0,
                             xtol=1e-15, rtol=1e-15)
            C_exact = law.length_at(a_exact, F_exact, d)
        a_exact, _ = law.step(a_exact, C_exact)
        if d > 0 and solver.cells["stage"].min() == Stage.SLACK and F_exact > 0:
            reload_from_slack += 1
        r = solver.step(float(e), int(d))
        assert r.column_status[0] == COL_OK
        np.testing.assert_allclose(r.column_force[0], F_exact, rtol=2e-8, atol=1e-10)
        slack_seen += F_exact == 0.0
        trials.append(int(r.iterations[0]))
    # the program went slack and reloaded from slack, and every increment took few trials
    assert slack_seen > 0 and reload_from_slack > 0
    assert np.mean(trials) <= 4.0 and max(trials) <= 12
