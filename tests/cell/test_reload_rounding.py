"""A slack cell asked for its own slack length, to rounding, stays slack (both engines).

Source: Table 4 has no load on a slack loop until the imposed course length exceeds the length
at which it went slack; a length that differs from it only in the last bits of a float64 is that
length (the sub-step loop of both engines already treats |C_target - C| <= REACHED_RTOL C_target as
reached).  Before this rule a reload asked for one ulp more turned the slack cell into a stick
stage (label adherence) whose force was the rounding noise of the slack point (+2.6e-17 N in the
patch of tests/patch/test_column_convergence.py), and a series column then "carried" that force.
"""
from __future__ import annotations

import numpy as np

from knitsim.cell.batch import run_batch
from knitsim.cell.cycle import run_cell
from knitsim.cell.load_program import LoadProgram, cycles
from knitsim.cell.material import CellParams
from knitsim.cell.stages import REACHED_RTOL, Stage

# Table 1 / section 2.2 (dusserre2015.toml): a cell that goes slack on unloading to 10 %
P = CellParams(B=0.31, d=0.58, L=14.1, W0=4.4, C0=2.7, m=0.2, force_cap_N=10.0)


def _slack_then_reload(C_slack: float) -> LoadProgram:
    """The paper's first cycle, then one reload increment to the course length just above C_slack."""
    base = cycles(0.10, 0.60, 1, 0.01)
    C_next = np.nextafter(C_slack, np.inf)
    strain = C_next / P.C0 - 1.0
    # the strain whose C0 (1 + strain) is the slack length plus a few ulps, still within REACHED_RTOL
    while P.C0 * (1.0 + strain) <= C_slack:
        strain = np.nextafter(strain, np.inf)
    C_target = P.C0 * (1.0 + strain)
    assert C_slack < C_target <= C_slack * (1.0 + REACHED_RTOL)
    return LoadProgram(np.append(base.strain, strain), np.append(base.cycle, 2), np.append(base.direction, 1),
                       base.waypoints)


def _engines(device):
    return {"warp": lambda prog: run_batch([P], prog, device=device), "reference": lambda prog: run_cell(P, prog)}


def test_slack_cell_asked_for_its_slack_length_to_rounding_stays_slack(device):
    for name, run in _engines(device).items():
        first = run(cycles(0.10, 0.60, 1, 0.01))
        assert first.stage[-1, 0] == int(Stage.SLACK), f"{name}: the cell must end the first unloading slack"
        # each engine's own slack length (the two locate it to ~1e-10 mm, far above rounding)
        C_slack = float(first.values["C"][-1, 0])
        prog = _slack_then_reload(C_slack)
        h = run(prog)
        assert h.stage[-1, 0] == int(Stage.SLACK), name
        assert h.labels()[-1] == "slack" and h.force_per_wale[-1, 0] == 0.0, name
        assert not any(e.get("kind") == "reload" and e["increment"] == len(prog) - 1 for e in h.events), name
        # a reload by more than rounding does reload: the rule is no wider than rounding
        longer = LoadProgram(np.append(prog.strain[:-1], prog.strain[-1] + 1e-9), prog.cycle, prog.direction,
                             prog.waypoints)
        h = run(longer)
        assert any(e.get("kind") == "reload" and e["increment"] == len(prog) - 1 for e in h.events), name
        assert h.stage[-1, 0] != int(Stage.SLACK), name
