"""A sweep sample whose cell stops at its force cap before the program's last cycle is listed and drawn as such.

Expected classes from the caps' orders of magnitude, not from a replay: the E-glass cell of Dusserre (2015)
(Table 1, section 2.2) carries about 0.02 N at rest and tenths of a newton at 0.6 strain (the specimen's
4.4 N is the force of the whole knit), so a cap of 10 N is never reached and a cap of 0.05 N is reached while
cycle 1 loads, before any unloading."""
from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np

import knitsim.sweep.plots as plots
from knitsim.cell.history import STATUS_FORCE_CAP
from knitsim.sweep.runner import capped_samples, failed_samples, plan_sweep, run_sweep

SCENE = {"engine": "warp", "device": "cpu", "yarn": {"material": "e_glass"}, "knit": {"material": "e_glass_plain"},
         "friction": {"m": 0.2, "phi0": 0.0},
         "load": {"type": "cycles", "lower_strain": 0.1, "upper_strain": 0.6, "cycles": 2, "max_increment": 0.05}}


def test_capped_sample_is_listed_and_marked(tmp_path, monkeypatch):
    plan = plan_sweep(SCENE, {"parameters": {"rules.force_cap_N": {"values": [0.05, 10.0]}}})
    ds = run_sweep(plan, tmp_path / "o", workers=0, progress=None, plots=False).dataset
    assert ds["final_status"].values.tolist() == [STATUS_FORCE_CAP, 0]
    assert 0.0 < ds["strain_at_peak"].values[0, 0] < 0.6                  # capped while loading, not at rest
    assert np.isnan(ds["peak_force_per_wale_N"].values[0, 1]) and np.isfinite(ds["peak_force_per_wale_N"].values[1]).all()
    (c,) = capped_samples(ds)
    assert c["sample"] == 0 and "in cycle 1" in c["reason"] and "before cycle 2" in c["reason"]
    assert failed_samples(ds) == []
    figs = []
    monkeypatch.setattr(plots, "_png", lambda fig: figs.append(fig) or b"")
    plots.plot_sweep(ds, tmp_path / "o")
    (fig,) = figs
    title = " ".join(fig._suptitle.get_text().split())           # the title is wrapped to the figure
    assert "1 stopped at the force cap: peak = the cap and energy = loading work" in title
    grey = mcolors.to_rgba("0.45")
    for ax in fig.axes:
        tri = [col for col in ax.collections if col.get_label() == "stopped at the force cap"]
        assert len(tri) == 1 and np.allclose(tri[0].get_offsets()[:, 0], [0.05])
        assert np.allclose(tri[0].get_edgecolor()[0], grey)
    # the capped peak is drawn apart from the line, at the cap (the scene's 0.05 N)
    peak_ax = fig.axes[0]
    (star,) = [col for col in peak_ax.collections if col.get_label() == "peak = the force cap (not the knit's)"]
    np.testing.assert_allclose(star.get_offsets(), [[0.05, 0.05]], rtol=1e-9)
    line1 = peak_ax.get_lines()[0]
    assert line1.get_label() == "cycle 1" and np.isnan(line1.get_ydata()[0]) and np.isfinite(line1.get_ydata()[1])


def test_a_sample_stopped_at_rest_is_not_said_to_peak_at_the_cap(tmp_path, monkeypatch):
    """A probe's Latin hypercube of rules.force_cap_N in [0.001, 0.03] N: the samples whose cap is under the cell's
    rest force were listed "stopped at its force cap in cycle 1, whose peak is the cap" (peak_at_force_cap = 1,
    stopped_at_strain the first increment's 0.05 here), their peak the rest force, above the cap.  Expected: the
    rest force per wale 2 P sin(gamma) of the NumPy reference's rest state (0.0216 N; model.md) is the peak, the
    cell stopped at rest (strain 0), its peak not the cap; a cap above the rest force is reached while loading,
    as before."""
    from knitsim.cell.inverse import initial_state

    rest = initial_state(2.7, 4.4, 14.1, 0.0, 0.31, 0.58).state
    F_rest = float(2.0 * rest.P * np.sin(rest.gamma))
    plan = plan_sweep(SCENE, {"parameters": {"rules.force_cap_N": {"values": [0.5 * F_rest, 0.05]}}})
    ds = run_sweep(plan, tmp_path / "o", workers=0, progress=None, plots=False).dataset
    assert ds["final_status"].values.tolist() == [STATUS_FORCE_CAP, STATUS_FORCE_CAP]
    np.testing.assert_allclose(ds["peak_force_per_wale_N"].values[0, 0], F_rest, rtol=1e-6)
    assert ds["peak_at_force_cap"].values[:, 0].tolist() == [0, 1]
    assert ds["stopped_at_strain"].values[0] == 0.0 and ds["stopped_at_strain"].values[1] > 0.0
    at_rest, loading = capped_samples(ds)
    assert at_rest["reason"].startswith(f"stopped at rest: its force per wale at rest, {F_rest:.4g} N")
    assert "whose peak is the cap" not in at_rest["reason"] and "in cycle 1, whose peak is the cap" in loading["reason"]
    # the plot says so too: one stopped at rest (marked at the axis foot, its rest force on no line and no star),
    # one at the cap (its title said "2 stopped at the force cap: peak = the cap", the rest force drawn as cycle 1's)
    figs = []
    monkeypatch.setattr(plots, "_png", lambda fig: figs.append(fig) or b"")
    plots.plot_sweep(ds, tmp_path / "o")
    (fig,) = figs
    title = " ".join(fig._suptitle.get_text().split())
    assert "1 stopped at the force cap: peak = the cap" in title and "1 stopped at rest:" in title
    peak_ax = fig.axes[0]
    assert np.isnan(peak_ax.get_lines()[0].get_ydata()[0])
    (foot,) = [col for col in peak_ax.collections if col.get_label() == "stopped at rest (cap)"]
    np.testing.assert_allclose(foot.get_offsets()[:, 0], [0.5 * F_rest])
    stars = [col for col in peak_ax.collections if col.get_label() == "peak = the force cap (not the knit's)"]
    assert not any(np.isclose(col.get_offsets()[:, 0], 0.5 * F_rest).any() for col in stars)
