"""The vectorised stage labels (knitsim.cell.stages.stage_labels / stage_label_codes) against the scalar
stage_label, the one place the label rule is written (Dusserre 2015, Table 4 stages; slack over jammed)."""
from __future__ import annotations

import numpy as np
import pytest

from knitsim.cell.stages import LABEL_CODES, Stage, stage_label, stage_label_codes, stage_labels


def test_every_stage_and_jammed_flag_against_the_scalar_rule():
    stage = np.array([[int(s) for s in Stage] * 2])
    jammed = np.array([[0] * len(Stage) + [1] * len(Stage)])
    want = [stage_label(s, bool(j)) for s, j in zip(stage[0], jammed[0])]
    assert stage_labels(stage, jammed)[0].tolist() == want
    assert stage_label_codes(stage, jammed)[0].tolist() == [LABEL_CODES[w] for w in want]
    # jammed read as a flag (any non-zero), as the kernels store it
    assert stage_labels(np.array([0]), np.array([7])).tolist() == ["jamming"]


@pytest.mark.parametrize("bad", [-1, len(Stage)])
def test_an_unknown_stage_code_is_refused_not_wrapped(bad):
    with pytest.raises(ValueError, match=f"{bad} is not a valid Stage"):
        stage_labels(np.array([0, bad]), np.array([0, 0]))
