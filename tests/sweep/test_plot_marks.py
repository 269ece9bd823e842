"""The sweep plot shows, on its axes, the samples whose values carry a model warning, and draws a parameter
whose values are names as points.

A blind probe read a title saying "1 with a later cycle carrying nearly no force (not marked)" above a smooth
line through that sample, and lines joining the values of a rule (an order, not a scale).  The flags' sources
are tested with the checks (tests/io/test_checks.py); here flags are set by hand on a real sweep's dataset and
the figure must ring exactly those samples, in every panel, and name the kinds in its title."""
from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np

import knitsim.sweep.plots as plots
from knitsim.sweep.runner import plan_sweep, run_sweep

SCENE = {"engine": "warp", "device": "cpu", "yarn": {"material": "e_glass"},
         "knit": {"material": "e_glass_plain"}, "friction": {"m": 0.2, "phi0": 0.0},
         "load": {"type": "cycles", "lower_strain": 0.27, "upper_strain": 0.3, "cycles": 3,
                  "max_increment": 0.01}}


def _figures(ds, tmp_path, monkeypatch):
    figs = []
    monkeypatch.setattr(plots, "_png", lambda fig: figs.append(fig) or b"")
    plots.plot_sweep(ds, tmp_path)
    return figs


def test_samples_with_model_warnings_are_ringed_in_every_panel(tmp_path, monkeypatch):
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.1, 0.2, 0.3]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    for k in ("reload_loss_continues", "zero_force_cycle", "reload_below_earlier_loading", "heads_interpenetrate",
              "reload_above_first_loading", "rest_state_compressive", "loop_creates_energy"):
        ds[k].values[:] = 0
    ds["reload_loss_continues"].values[:] = [0, 1, 0]
    ds["zero_force_cycle"].values[:] = [0, 0, 1]
    (fig,) = _figures(ds, tmp_path, monkeypatch)
    title = fig._suptitle.get_text()
    assert "1 losing force cycle after cycle (reload_loss_continues; orange)" in title
    assert "1 with a later cycle carrying nearly no force (zero_force_cycle; orange)" in title
    assert "not marked" not in title
    orange = mcolors.to_rgba("tab:orange")
    for ax in fig.axes:
        rings = [c for c in ax.collections
                 if len(c.get_edgecolor()) and np.allclose(c.get_edgecolor()[0], orange)]
        # one ring per cycle drawn (3), around the two flagged samples' points only (values kept; a value
        # that does not exist, the residual strain of a cycle never unloaded, has no point to ring)
        xs = [set(np.asarray(r.get_offsets())[np.isfinite(np.asarray(r.get_offsets())[:, 1]), 0]) for r in rings]
        assert len(rings) == 3 and set().union(*xs) and all(x <= {0.2, 0.3} for x in xs)
        if ax is fig.axes[0]:                            # the peaks: every sample has one
            assert set().union(*xs) == {0.2, 0.3}


def test_a_parameter_of_names_is_drawn_as_points(tmp_path, monkeypatch):
    plan = plan_sweep(SCENE, {"parameters": {"rules.unloading_rule": {"values": ["dusserre", "hong_constant_t"]}}})
    ds = run_sweep(plan, tmp_path / "out", workers=0, progress=None, plots=False).dataset
    (fig,) = _figures(ds, tmp_path, monkeypatch)
    drawn = [ln for ax in fig.axes for ln in ax.get_lines() if len(ln.get_xdata()) == 2]
    assert drawn and all(ln.get_linestyle() == "None" for ln in drawn)
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.1, 0.2]}}})
    ds = run_sweep(plan, tmp_path / "num", workers=0, progress=None, plots=False).dataset
    (fig,) = _figures(ds, tmp_path, monkeypatch)
    assert any(ln.get_linestyle() != "None" for ax in fig.axes for ln in ax.get_lines())
