"""BatchHistory's events by cell (knitsim.cell.history).

Expected: the definition, the events of a cell filtered from the whole list in its order (the per-cell scan
that events_of replaced)."""
from __future__ import annotations

import numpy as np

from knitsim.cell.history import BatchHistory


def _history(events, n_cells=3, rows=4):
    z = np.zeros((rows, n_cells))
    return BatchHistory(np.linspace(0.1, 0.4, rows), np.ones(rows, int), np.ones(rows, int), z.astype(int),
                        z.astype(int), z.astype(int), {"C": z.copy(), "F": z.copy()}, events, [])


def test_events_of_a_cell_are_its_events_in_their_order():
    rng = np.random.default_rng(3)
    events = [{"cell": int(c), "increment": int(k), "kind": str(kind)}
              for c, k, kind in zip(rng.integers(0, 3, 40), rng.integers(0, 4, 40), rng.choice(["slide", "jam"], 40))]
    events.append({"increment": 2, "kind": "slack"})           # an event without a cell is cell 0's (one-cell runs)
    events.append({"cell": np.int64(2), "increment": 3, "kind": "flag"})
    h = _history(events)
    for c in range(4):
        expected = [e for e in events if int(e.get("cell", 0)) == c]
        assert h.events_of(c) == expected
        assert h.events_of(np.int32(c)) == expected
    assert h.events_of(1) is not h.events_of(1)                # a list of its own each time
    # a new events list is indexed anew
    h.events = events[:5]
    assert h.events_of(0) == [e for e in events[:5] if int(e.get("cell", 0)) == 0]
    h.events.append({"cell": 0, "increment": 3, "kind": "unjam"})
    assert h.events_of(0)[-1]["kind"] == "unjam"
    # cell(): the one-cell history keeps that cell's events, renumbered
    one = _history(events).cell(2)
    assert [dict(e, cell=2) for e in one.events] == [e for e in events if int(e.get("cell", 0)) == 2]
