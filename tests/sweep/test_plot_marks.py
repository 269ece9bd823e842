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


def test_a_grid_given_unsorted_is_drawn_in_the_order_of_its_values(tmp_path, monkeypatch):
    # a blind probe: "friction.m" = [0.3, 0.1, 0.45, 0.2] drew its lines back and forth between the points, and with
    # a second axis (knit.L [14.4, 13.8, 14.1]) heat-map cells over each other on an axis 13.95-14.7 (the edges are
    # midpoints of neighbouring values); the figure does not depend on the order the values are given in
    from matplotlib.collections import QuadMesh
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.3, 0.1, 0.2]}}})
    ds = run_sweep(plan, tmp_path / "one", workers=0, progress=None, plots=False).dataset
    (fig,) = _figures(ds, tmp_path, monkeypatch)
    lines = [ln.get_xdata() for ax in fig.axes for ln in ax.get_lines() if len(ln.get_xdata()) == 3]
    assert lines and all(list(x) == [0.1, 0.2, 0.3] for x in lines)
    plan = plan_sweep(SCENE, {"parameters": {"friction.m": {"values": [0.3, 0.1, 0.2]},
                                             "knit.L": {"values": [14.2, 13.9]}}})
    ds = run_sweep(plan, tmp_path / "two", workers=0, progress=None, plots=False).dataset
    (fig,) = _figures(ds, tmp_path, monkeypatch)
    maps = [ax for ax in fig.axes if ax.get_xlabel() == "knit.L"]     # (not the colour bars)
    meshes = [c for ax in maps for c in ax.collections if isinstance(c, QuadMesh)]
    assert len(meshes) == len(maps) == 6                               # 3 quantities x cycles 1 and 3
    for mesh in meshes:
        xy = mesh.get_coordinates()                       # [y edge, x edge, (x, y)]
        xe, ye = xy[0, :, 0], xy[:, 0, 1]
        np.testing.assert_allclose(xe, [13.75, 14.05, 14.35])            # knit.L 13.9, 14.2: midpoint edges
        np.testing.assert_allclose(ye, [0.05, 0.15, 0.25, 0.35])         # friction.m 0.1, 0.2, 0.3
        # each cell holds its sample's value: the peak of cycle 1 at (m, L)
        z = np.asarray(mesh.get_array()).reshape(3, 2)
        if mesh.axes is maps[0]:
            want = ds["peak_force_per_wale_N"].sel(cycle=1).sortby("friction.m").sortby("knit.L")
            np.testing.assert_array_equal(z, want.transpose("friction.m", "knit.L").values)
