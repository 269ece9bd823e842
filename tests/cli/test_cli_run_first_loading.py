"""``knitsim run`` checks a reload past the earlier maximum against the patch's own first loading
(reload_below_first_loading), as ``knitsim cell`` does, and solves that reference only where the program needs it.

Where the expected outcomes come from:

- an independent path: ``knitsim cell`` on the same E-glass cell (Dusserre 2015, Table 1, section 2.2; m = 0.2,
  Hong's constant-T unloading) and program (waypoints 0.3, 0.29, 0.5: the blind probe's case of README,
  "Reloads below the first loading") runs its own monotonic pull and warns at strain 0.305: 0.0943 N per wale,
  80 % of 0.117 N; a uniform patch drives every column at the grip strain and reproduces its cell bit for bit
  (knitsim.patch.coupling), so the patch must warn the same at grip strain 0.305;
- needs_first_loading_reference's definition: the paper's cycles 0.1 -> 0.6 (section 2.3) never load past the
  earlier maximum 0.6, so no reference is solved (the bundled main job pays nothing).
"""
from __future__ import annotations

import json

from knitsim.cli import main

SCENE = """title = "E-glass, waypoints 0.3, 0.29, 0.5"
engine = "warp"
device = "cpu"
{patch}
[yarn]
material = "e_glass"
[knit]
material = "e_glass_plain"
[friction]
model = "coulomb"
m = 0.20
[rules]
force_cap_N = 10.0
unloading_rule = "hong_constant_t"
[load]
{load}
max_increment = 0.005
[output]
plot = false
"""
WAYPOINTS = 'type = "piecewise"\nwaypoints = [0.3, 0.29, 0.5]'


def _warning(summary: dict, code: str) -> list:
    return [w for w in summary["warnings"] if w["code"] == code]


def test_run_warns_a_reload_below_the_first_loading_as_cell_does(tmp_path, capsys):
    cell = tmp_path / "cell.toml"
    cell.write_text(SCENE.format(patch="", load=WAYPOINTS))
    patch = tmp_path / "patch.toml"
    patch.write_text(SCENE.format(patch="[patch]\nwales = 2\ncourses = 3", load=WAYPOINTS))
    assert main(["cell", str(cell), "--out", str(tmp_path / "c")]) == 0
    assert main(["run", str(patch), "--out", str(tmp_path / "p")]) == 0
    err = capsys.readouterr().err
    c = json.loads((tmp_path / "c" / "summary.json").read_text())
    p = json.loads((tmp_path / "p" / "summary.json").read_text())
    (wc,), (wp,) = _warning(c, "reload_below_first_loading"), _warning(p, "reload_below_first_loading")
    assert "at strain 0.305, 80% of the 0.117 N per wale" in wc["message"]
    assert "at grip strain 0.305, 80% of the 0.117 N per wale" in wp["message"]
    assert "carries 0.0943 N per wale" in wc["message"] and "carries 0.0943 N per wale" in wp["message"]
    assert "a monotonic pull of the same knit" in err                      # on the console too
    assert p["first_loading_reference"]["ran"] is True
    # the second solve and the checks after the run's progress bar are said (a large patch spent minutes there
    # in silence): the reference's own progress, then the checks, before "done"
    ref_line = err.index("knitsim run: the first loading continued to the program's largest grip strain")
    check_line = err.index("knitsim run: checking the results and writing the outputs (1 distinct cell x ")
    assert ref_line < check_line < err.index("knitsim run: done in")


def test_run_solves_no_reference_where_the_program_never_passes_its_earlier_maximum(tmp_path):
    patch = tmp_path / "patch.toml"
    patch.write_text(SCENE.format(patch="[patch]\nwales = 2\ncourses = 3",
                                  load='type = "cycles"\nlower_strain = 0.1\nupper_strain = 0.6\ncycles = 2'))
    assert main(["run", str(patch), "--out", str(tmp_path / "p")]) == 0
    p = json.loads((tmp_path / "p" / "summary.json").read_text())
    assert p["first_loading_reference"]["ran"] is False
    assert not _warning(p, "reload_below_first_loading")
