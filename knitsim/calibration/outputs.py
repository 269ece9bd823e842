"""What ``knitsim calibrate`` writes: the calibrated materials, scenes to run, and the evidence.

- ``materials.toml``: a material library (:mod:`knitsim.material_library`) with the one
  calibrated yarn (its friction law, rules, effects, and the standard errors) and one knit per
  specimen (L, W0, C0, phi0 in rad): what new scenes name (``materials = ...``), e.g. to blend
  two calibrated knits in a graded specimen;
- ``<specimen>.cell.toml``: a cell scene of the specimen's calibrated cell, every value spelled
  out (``knitsim cell`` and ``knitsim sweep`` read it as it is);
- ``<specimen>.patch.toml``: the specimen as a patch scene (``[specimen]``: its width and
  gauge length; ``knitsim run`` reads it as it is; its ``curve.csv`` force_N is the fit's total
  force);
- ``calibration.json``: every estimate with its std error, range and bound flag, the
  correlations, each specimen's fit (numbers and curves);
- ``report.md``: the same for a reader; ``fit_<specimen>.png``: each fit in its band, with
  its share inside the band and its RMS, and the weighted residuals.

A calibration with a flag (:attr:`knitsim.calibration.joint.JointResult.flags`: the optimiser did not
converge, a parameter at a bound or not identified, a cell that did not solve, specimens that do not look
like one yarn) says so in every file:
``calibration.json`` (``flags``, ``usable``), the top of ``report.md`` ("NOT A CALIBRATION YOU CAN
USE"), a comment block at the top of ``materials.toml`` and of each scene (so a file reused elsewhere
carries it), and the title of each plot.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..material_library import LibraryKnit, LibraryYarn, library_document
from ..scene.schema import dumps
from .specimen import pretension_strain
from .joint import JointResult

_RULES = ("unloading_rule", "reload_rule", "jamming_criterion", "force_cap_N")


def _rules(p) -> dict:
    """The rules of a calibrated cell; a default force cap (None: 50 B / d^2) is left out, so that a scene
    of the calibrated yarn takes its own default too."""
    return {r: getattr(p, r) for r in _RULES if getattr(p, r) is not None}


def library_of(result: JointResult, yarn_name: str, source: str = "") -> dict:
    """The library document of a calibration: its yarn and one knit per specimen."""
    p = result.fits[0].params
    std = {e.name: e.std_error for e in result.estimates if e.specimen is None}
    if result.flags:
        source = (f"{source} ({UNUSABLE}: {len(result.flags)} flags, listed at the top of the file it "
                  "wrote and in its report.md)").strip()
    yarn = LibraryYarn(yarn_name, d=p.d, B=p.B, in_plane_width=p.in_plane_width,
                       friction={"model": p.friction, "m": p.m, "dahl_sigma": p.dahl_sigma}, rules=_rules(p),
                       effects=p.effects.as_dict() if p.effects.on else {}, std_errors=std,
                       source=f"knitsim calibrate {source}".strip(), flags=tuple(result.flags))
    knits = [LibraryKnit(f.name, yarn_name, L=f.params.L, W0=f.params.W0, C0=f.params.C0, phi0=f.params.phi0,
                         source=f"knitsim calibrate {source}: specimen {f.name}".strip(), flags=tuple(result.flags))
             for f in result.fits]
    return library_document([yarn], knits, title=f"calibrated by knitsim calibrate {source}".strip())


def _cell_tables(p) -> dict:
    out = {"yarn": {"d": p.d, "B": p.B}, "knit": {"L": p.L, "W0": p.W0, "C0": p.C0},
           "friction": {"model": p.friction, "m": p.m, "phi0": p.phi0, "dahl_sigma": p.dahl_sigma},
           "rules": _rules(p)}
    if p.in_plane_width is not None:
        out["yarn"]["in_plane_width"] = p.in_plane_width
    if p.effects.on:
        out["effects"] = p.effects.as_dict()
    return out


#: the first line of what a flagged calibration writes, everywhere
UNUSABLE = "NOT A CALIBRATION YOU CAN USE"


def flag_lines(result: JointResult) -> list[str]:
    """The comment block of a flagged calibration (empty when it has no flag): a heading and one line per flag."""
    flags = result.flags
    if not flags:
        return []
    return ([f"{UNUSABLE}: {len(flags)} flag{'s' if len(flags) > 1 else ''} (calibration.json, report.md):"]
            + [f"  - {x}" for x in flags] + [""])


def _header(result: JointResult, text: str) -> str:
    return "\n".join(flag_lines(result) + [text])


def _fit_line(f) -> str:
    band = "" if f.in_band_fraction is None else f", {100 * f.in_band_fraction:.0f} % of the strain range in the band"
    off, tare = f.offset_N, f.tare_N
    off = ("" if off is None else f"; of the model plus a fitted force offset of {off:+.4g} {f.offset_unit} (the lab's "
           "zero: this scene runs the model itself)")
    off += ("" if tare is None else f"; of the model less its force at grip strain 0, {tare:.4g} {f.offset_unit} (a "
            "file tared with the knit mounted: this scene runs the model itself)")
    return f"fit: RMS {f.rms_N:.4g} {f.force_unit} ({100 * f.rms_rel:.2g} %){band}{off}"


def _knit_notes_of(result: JointResult, f) -> str:
    """Lines (each after a newline) of :attr:`JointResult.knit_notes` of specimen ``f``: its own knit variables
    that the rows do not set, said in its scenes' headers."""
    return "".join(f"\nnote: {x}" for x in result.knit_notes_of(f.name))


def _provenance(result: JointResult, source: str) -> dict:
    """A flagged calibration's scenes carry its flags (the runs on them say so: material_library.flagged_materials)."""
    return ({"provenance": {"source": f"knitsim calibrate {source}".strip(), "flags": list(result.flags)}}
            if result.flags else {})


def cell_scene_of(result: JointResult, k: int, source: str, device: str = "cpu") -> str:
    """The TOML of specimen ``k``'s calibrated cell scene (monotonic to the end of its rows)."""
    f = result.fits[k]
    doc = {"title": f"{f.name}: calibrated cell (knitsim calibrate)", "engine": "warp", "device": device}
    doc.update(_provenance(result, source))
    doc.update(_cell_tables(f.params))
    pre = float(f.pretension)
    end = float(f.strain[-1]) if pre == 0 else float(pretension_strain(float(f.strain[-1]), pre))
    doc["load"] = {"type": "monotonic", "target_strain": end,
                   "max_increment": result.setup.max_increment}
    pre_line = ("" if pre == 0 else
                f"\npretensioned specimen: the cell's strain is the knit's, (1 + {pre:.6g})(1 + grip strain) - 1 "
                f"(grip strain 0 at {pre:.6g}, where it carries {f.pretension_N:.4g} {f.force_unit}); the patch scene runs in "
                "grip strain")
    header = (f"Specimen {f.name}, calibrated jointly with {', '.join(g.name for g in result.fits if g is not f) or 'no other'}"
              f" by knitsim calibrate {source}\n"
              f"the cell of one stitch: force per wale; the specimen's total force is {f.wales:.6g} x it "
              f"(its wales)\n{_fit_line(f)}{_knit_notes_of(result, f)}{pre_line}\nunits N, mm, rad")
    return dumps(doc, header=_header(result, header))


def patch_scene_of(result: JointResult, k: int, source: str, width_mm: float, gauge_length_mm: float,
                   device: str = "cpu") -> str:
    """The TOML of specimen ``k`` as a patch scene (``[specimen]``: width and gauge length)."""
    f = result.fits[k]
    doc = {"title": f"{f.name}: calibrated specimen (knitsim calibrate)", "engine": "warp", "device": device,
           "specimen": {"width": width_mm, "gauge_length": gauge_length_mm}}
    doc.update(_provenance(result, source))
    pre = float(f.pretension)
    if pre:
        doc["specimen"]["pretension"] = pre
    doc.update(_cell_tables(f.params))
    doc["load"] = {"type": "monotonic", "target_strain": float(f.strain[-1]),
                   "max_increment": result.setup.max_increment}
    header = (f"Specimen {f.name} ({width_mm:g} mm wide, {gauge_length_mm:g} mm between the grips), calibrated by "
              f"knitsim calibrate {source}\n"
              f"{width_mm / f.params.W0:.4g} wales (width / W0), {gauge_length_mm / (1 + pre) / f.params.C0:.4g} "
              + ("courses (gauge length / (1 + pretension) / C0)" if pre else "courses (gauge length / C0)")
              + "; curve.csv force_N is the total force"
              + (f"\npretension: the knit is at strain {pre:.4g} at grip strain 0 ({f.pretension_N:.4g} {f.force_unit}; the run "
                 "starts at rest, at negative grip strain)" if pre else "")
              + f"\n{_fit_line(f)}{_knit_notes_of(result, f)}\nunits N, mm, rad")
    return dumps(doc, header=_header(result, header))


def _fmt(v: float) -> str:
    if v is None or not math.isfinite(v):
        return "-" if v is None else str(v)
    return f"{v:.4g}"


def _flag_cell(e) -> str:
    """The flag column of an estimate: at a bound, not identified, or both."""
    bits = [f"at {e.at_bound} bound"] if e.at_bound in ("low", "high") else []
    if getattr(e, "not_identified", "") or e.at_bound == "not identified":
        bits.append("NOT IDENTIFIED")
    return "; ".join(bits)


def zero_offsets(specimens) -> list[tuple[str, str, float]]:
    """(specimen, file, zero offset [N]) of every file whose load cell zero below zero was tared."""
    return [(s.name, src, z) for s in specimens for src, z in s.zero_offsets_N]


def _covariance_text(r) -> str:
    """What the covariance's factor and row weights were (report.md), or "" where not recorded."""
    if not math.isfinite(getattr(r, "variance_factor", math.nan)):
        return " (the factor on the covariance)"
    info = getattr(r, "row_information", None) or {}
    less = ", ".join(f"{name} {q:.2g}" for name, q in info.items() if q < 1.0)
    return (f" (the covariance's factor max(chi2 / (n - k), 1) = {r.variance_factor:.3g}: scaled up where the rows "
            "scatter beyond their sds, never down"
            + (f"; rows whose residuals run from one to the next count less than one reading each, (1 - rho) / "
               f"(1 + rho) of their lag-1 autocorrelation: {less}" if less else "") + ")")


def report_md(result: JointResult, title: str, source: str, files: list[str], zero_offsets: list | None = None,
              read_notes: list | None = None) -> str:
    """A readable report of the calibration."""
    r = result
    flags = r.flags
    lines = [f"# knitsim calibrate: {title}", ""]
    if flags:
        lines += [f"**{UNUSABLE}:** {len(flags)} flag{'s' if len(flags) > 1 else ''} below. "
                  + ("The fit failed (the optimiser did not converge" + (", or a cell did not solve" if any(
                      f.status != "ok" for f in r.fits) else "") + "): its values are where it stopped, not a "
                     "minimum. " if not r.success else "")
                  + "The files written (materials.toml, the scenes) carry these flags in their header.", "",
                  "## Flags", ""] + [f"- **{x}**" for x in flags] + [""]
    n_off = r.n_offsets
    lines += [f"Scene: `{source}`. {len(r.fits)} specimens, one yarn; "
             + (f"{r.k} parameters fitted ({r.k - n_off} variables and {n_off} force offsets, one per specimen) "
                if n_off else f"{r.k} variables fitted (calibration.zero = \"{r.zero}\": no force offset) ")
             + f"to {r.n} rows (priors included); chi2 = {r.chi2:.4g}, "
             f"chi2 / (n - k) = {r.s2:.3g}" + _covariance_text(r) + ". "
             + ("Objective: the band likelihood (anywhere inside the band at no cost, just outside a Gaussian of "
                "the force accuracy, far outside a Cauchy tail), refined from each mid-line fit. "
                if r.setup.objective == "band" else (
                    "Objective: the band mid-line, sd = half-width (at least the force accuracy). "
                    if all(f.band_low_N is not None for f in r.fits) else
                    # (a blind probe's single curves were said to be weighted by a band's half-width)
                    "Objective: each row of a band at its mid-line, sd = half-width (at least the force "
                    "accuracy); each row of a single curve at the curve, sd = the curve's own noise "
                    "(calibration.json: sd_rule). "))
             + f"{'Converged' if r.success else 'NOT CONVERGED'}: {r.message.rstrip('.')}. Wall time {r.wall_s:.0f} s.", ""]
    if not flags:
        oy = r.one_yarn
        lines += ["No flag: the optimiser converged, every cell solved, and no parameter is at a bound or not "
                  "identified (standard error finite and at most half its range"
                  + ("; a specimen's own knit variable that is not identified is noted under its knit" if r.knit_notes
                     else "") + ")"
                  + ("; the specimens look like one yarn (below)." if oy is not None and oy.ran else "."), ""]
    lines += ["## The yarn (shared by every specimen)", "", "| parameter | value | std error | unit | range | flag |",
              "|---|---|---|---|---|---|"]
    for e in r.estimates:
        if e.specimen is None:
            lines.append(f"| {e.name} | {_fmt(e.value)} | {_fmt(e.std_error)} | {e.unit} | {_fmt(e.low)} .. "
                         f"{_fmt(e.high)} | {_flag_cell(e)} |")
    p = r.fits[0].params
    lines += ["", f"Friction law {p.friction}"
              + (f" (Dahl stiffness {p.dahl_sigma:.4g} / mm)" if p.friction == "dahl" else "")
              + f"; effects {', '.join(p.effects.on) or 'none'}; rules " + ", ".join(f"{k} = {v}" for k, v in
                                                                                    _rules(p).items()) + ".", ""]
    lines += ["## Each specimen's knit", "", "| specimen | parameter | value | std error | unit | stated | "
              "from stated [sd] | flag |", "|---|---|---|---|---|---|---|---|"]
    for e in r.estimates:
        if e.specimen is not None:
            lines.append(f"| {e.specimen} | {e.name} | {_fmt(e.value)} | {_fmt(e.std_error)} | {e.unit} | "
                         f"{_fmt(e.stated)} | {_fmt(e.deviation_sd)} | {_flag_cell(e)} |")
    lines += [""] + [f"- Note: {x}." for x in r.knit_notes]
    lines += ["", "phi0 in rad (a fraction of phimax = atan(m) in the fit); pretension: the knit's strain at grip "
              "strain 0 (the tester's pretension before the strain origin; rows at knit strain "
              "(1 + pretension)(1 + grip strain) - 1).", "", "## Fits", "",
              "| specimen | wales (width / W0) | rows | in the band | in the band +- force accuracy | RMS | "
              "RMS / RMS force | chi2 | pretension | force at grip strain 0 | cells |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for f in r.fits:
        band = "-" if f.in_band_fraction is None else f"{100 * f.in_band_fraction:.0f} %"
        tol = "-" if f.in_band_tolerant is None else f"{100 * f.in_band_tolerant:.0f} %"
        lines.append(f"| {f.name} | {f.wales:.4g} | {len(f.strain)} | {band} | {tol} | {f.rms_N:.4g} {f.force_unit} | "
                     f"{100 * f.rms_rel:.2g} % | {f.chi2:.4g} | {f.pretension:.4g} | {f.pretension_N:.4g} "
                     f"{f.force_unit} | {f.status} |")
    lines += ["", "In the band: the share of the rows (of the strain range) where the model lies between the two "
              "envelopes; +- force accuracy: the band widened by the force reading's accuracy "
              "(calibration.force_accuracy, of the force) on either side: where the envelopes meet or cross the band "
              "has no width, though the specimens scatter and the machine reads no better."]
    lines += zero_md(r)
    if zero_offsets:
        lines += ["", "Load cell zeros below zero, read off the curves' lowest readings (a knit carries no compression) "
                  "and tared (subtracted) before the fit: " + "; ".join(f"{name}: {src} {z:.4g} N"
                                                                      for name, src, z in zero_offsets) + "."]
    if read_notes:
        # what reading the files did (a strain in per cent, a band given upper envelope first): said where the
        # results go, not only on the console
        lines += ["", "Files read: " + "; ".join(f"{name}: {src}: {note}" for name, src, note in read_notes) + "."]
    lines += one_yarn_md(r)
    names = [e.label for e in r.estimates]
    strong = [(names[i], names[j], r.correlation[i, j]) for i in range(len(names)) for j in range(i + 1, len(names))
              if abs(r.correlation[i, j]) > 0.9]
    lines += ["", "## Strong correlations (|r| > 0.9)", ""]
    lines += [f"- {a} / {b}: {c:+.3f}" for a, b, c in strong] or ["none"]
    lines += ["", "## Starts", "", "| start | objective | chi2 before | chi2 after | evaluations |", "|---|---|---|---|---|"]
    lines += [f"| {s['start']} | {s.get('objective', 'midline')} | {s['chi2_start']:.4g} | {s['chi2']:.4g} | {s['nfev']} |"
              for s in r.starts]
    lines += ["", "## Files", ""] + [f"- `{f}`" for f in files] + [""]
    return "\n".join(lines)


def zero_md(result: JointResult) -> list[str]:
    """The report's section on the files' zero (:mod:`knitsim.calibration.joint`, "The files' zero"):
    calibration.zero, and the fitted force offsets or the tares."""
    r = result
    if r.zero == "tared":
        out = ["", "## The files' zero: tared (calibration.zero = \"tared\")", "",
               "Each file's 0 N is taken as the model's state at grip strain 0 (a load cell zeroed with the knit "
               "mounted): each row is fitted as the model's force less its force at grip strain 0 (its rest state), "
               "from the same simulation; no parameter is added. The fit "
               "plots and RMS are of the model less it; the scenes written run the model itself.", "",
               "| specimen | tared at the model's force at grip strain 0 | unit |", "|---|---|---|"]
        out += [f"| {f.name} | {_fmt(f.tare_N)} | {f.offset_unit} |" for f in r.fits]
        return out
    if not r.n_offsets:
        return ["", "The files' zero: absolute (calibration.zero = \"absolute\"): each file's 0 N is taken as the "
                "model's 0 N. A load cell zeroed with the knit mounted reads the model's force at grip strain 0 as "
                "zero: such a file (it reads at rest well below the fitted knit's force there, beyond 5 sd of the "
                "gap: its noise at rest and the fit's standard error of that force) is flagged; set "
                "calibration.zero = \"tared\" (or \"fitted\") for it."] + [f"- Note: {x}." for x in r.zero_notes]
    out = ["", "## Force offsets (one per specimen; calibration.zero = \"fitted\")", "",
           "Each specimen's rows are fitted by the model plus a constant: the weighted least-squares offset of its "
           "rows (weights 1 / sd^2, the law of `knitsim diagnose`), projected out of the fit (the covariance above "
           "is marginal over it) and counted as a parameter. A lab that zeroes its load cell with the knit mounted "
           "reads the knit's rest force as zero: its offset is then minus the model's force at rest. The fit "
           "plots and RMS are of the model plus its offset; the scenes written run the model itself.", "",
           "| specimen | offset | std error | unit | peak measured force | share | model's force at grip strain 0 |",
           "|---|---|---|---|---|---|---|"]
    for f in r.fits:
        out.append(f"| {f.name} | {f.offset_N:+.4g} | {_fmt(f.offset_se_N)} | {f.offset_unit} | {_fmt(f.peak_N)} | "
                   f"{100 * f.offset_share:.3g} % | {_fmt(f.pretension_N)} |")
    notes = r.offset_notes
    if notes:
        out += [""] + [f"- Note: {x}." for x in notes]
    return out


def one_yarn_md(result: JointResult) -> list[str]:
    """The report's section on the one-yarn check (:class:`knitsim.calibration.joint.OneYarnCheck`)."""
    c = result.one_yarn
    if c is None:
        return []
    out = ["", "## One yarn?", ""]
    if not c.ran:
        return out + [f"Not tested: {c.why_not}."]
    band = getattr(c, "objective", "midline") == "band"
    out += [("Tested on the mid-line fit the band likelihood started from (each row at its band's mid-line, sd = "
             "half-width): the F test reads the drop of chi2 against the residual variance of Gaussian rows, and the "
             "band likelihood's cost is none (0 anywhere inside the band, whatever the scatter). " if band else "")
            + f"Each specimen refitted alone with its own {', '.join(c.shared)} (its knit, phi0 and priors as in the "
            f"joint fit), from the joint solution: chi2 {c.chi2_joint:.4g} -> {c.chi2_own:.4g} with "
            f"{c.dof} variables more; F = (drop / {c.dof}) / (chi2 / {c.dof_resid}) = {c.F:.3g}, p = {c.p:.2g} "
            f"(the upper tail of F({c.dof}, {c.dof_resid}): the chance of a drop this large if they are one yarn; "
            f"flagged below {c.threshold:g}). "
            + ("**They do not look like one yarn**: different yarns, or the model cannot make their curves with one "
               "yarn; the calibrated yarn is neither's." if c.flagged else
               "Consistent with one yarn: a yarn each does not fit them better than noise explains (a difference the "
               "knits' stated uncertainties can absorb is not seen)."), "",
            "| specimen | chi2, one yarn | chi2, its own yarn | " + " | ".join(
                f"own {n} [{c.units.get(n, '')}]" for n in c.shared) + " | converged |",
            "|---|---|---|" + "---|" * len(c.shared) + "---|"]
    for name, cj, co, y, ok in zip(c.specimens, c.chi2_joint_each, c.chi2_own_each, c.own_yarns, c.converged):
        out.append(f"| {name} | {cj:.4g} | {co:.4g} | " + " | ".join(_fmt(y[n]) for n in c.shared)
                   + f" | {'yes' if ok else 'no (the drop is then smaller)'} |")
    out += [""]
    if c.largest_pull is not None:
        out += [f"The largest move of a knit from its stated value in the joint fit: {c.pull_text()}.", ""]
    out += [f"Cost: {c.nfev} evaluations of one specimen's cells, {c.wall_s:.1f} s."]
    return out


def plot_fit(fit, title: str = "", flags: list[str] | tuple = ()) -> bytes:
    """PNG of one specimen's fit: its band, the target, the simulation, and the weighted residuals; with
    ``flags`` (the calibration's), "NOT A CALIBRATION YOU CAN USE" and the first flags above it."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(7.5, 6.2), dpi=110)
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    # what the rows were fitted to: the model plus its fitted offset, or less its tare (SpecimenFit.shift_N)
    shown_N = fit.simulated_N + fit.shift_N
    if fit.band_low_N is not None:
        ax.fill_between(fit.strain, fit.band_low_N, fit.band_high_N, color="0.75", label="experimental band")
        inside = (shown_N >= fit.band_low_N) & (shown_N <= fit.band_high_N)
        ax.scatter(fit.strain[~inside], shown_N[~inside], s=10, color="tab:red", zorder=3,
                   label="model outside the band")
    band_fit = getattr(fit, "objective", "midline") == "band"
    ax.plot(fit.strain, fit.target_N, "k--", lw=1, label=("band mid-line" if band_fit else "target (band mid-line)")
            if fit.band_low_N is not None else "measured")
    off, tare = fit.offset_N, fit.tare_N
    ax.plot(fit.strain, shown_N, color="tab:blue", lw=1.6,
            label=f"calibrated model {off:+.3g} N (fitted offset)" if off is not None else
            f"calibrated model - {tare:.3g} N (tared at grip strain 0)" if tare is not None else "calibrated model")
    ax.set_ylabel("force per wale [N]" if fit.force_unit == "N per wale" else "force [N]")
    frac = "" if fit.in_band_fraction is None else f", {100 * fit.in_band_fraction:.0f} % in the band"
    bad = "" if fit.status == "ok" else f", CELL {fit.status.upper()}"
    ax.set_title(title or f"{fit.name}: RMS {fit.rms_N:.3g} {fit.force_unit} ({100 * fit.rms_rel:.2g} %){frac}{bad}",
                 fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax2.axhline(0, color="k", lw=0.8)
    if band_fit and fit.residuals is not None:
        ax2.plot(fit.strain, fit.residuals, color="tab:blue", lw=1)
        ax2.set_ylabel("band likelihood\nresidual")
    else:
        ax2.plot(fit.strain, (shown_N - fit.target_N) / fit.sigma_N, color="tab:blue", lw=1)
        ax2.set_ylabel("(model - target) / sd")
    ax2.set_xlabel("grip strain")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    if flags:
        shown = [x if len(x) <= 110 else x[:107] + "..." for x in flags[:3]]
        more = f" (+{len(flags) - 3} more: report.md)" if len(flags) > 3 else ""
        fig.subplots_adjust(top=0.94 - 0.022 * (len(shown) + 1))
        fig.text(0.01, 0.995, f"{UNUSABLE}{more}\n" + "\n".join(shown), color="tab:red", fontsize=7,
                 va="top", ha="left", weight="bold")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def calibration_outputs(scene) -> tuple[str, ...]:
    """Every name :func:`write_calibration` writes for ``scene``'s specimens (the --out policy's list)."""
    per = [f"{s.name}{suffix}" for s in scene.specimens for suffix in (".cell.toml", ".patch.toml")]
    return ("materials.toml", *per, *(f"fit_{s.name}.png" for s in scene.specimens), "calibration.json",
            "report.md")


def write_calibration(out_dir: str | Path, result: JointResult, scene, source: str) -> dict[str, Path]:
    """Write every output into ``out_dir`` (atomically, ``calibration.json`` last); returns the files."""
    from ..io.results import write_result_set
    files: dict[str, bytes] = {}
    files["materials.toml"] = dumps(library_of(result, scene.yarn_name, source),
                                    header=_header(result, f"material library written by knitsim calibrate {source}\n"
                                                           "units N, mm, rad; std_errors are informative")).encode()
    device = scene.setup.device
    for k, (f, s) in enumerate(zip(result.fits, scene.specimens)):
        files[f"{f.name}.cell.toml"] = cell_scene_of(result, k, source, device).encode()
        files[f"{f.name}.patch.toml"] = patch_scene_of(result, k, source, s.width_mm, s.gauge_length_mm,
                                                       device).encode()
        files[f"fit_{f.name}.png"] = plot_fit(f, flags=result.flags)
    names = sorted(files) + ["calibration.json", "report.md"]
    files["report.md"] = report_md(result, scene.resolved.get("title", source), source, names,
                                   zero_offsets(scene.specimens),
                                   [(s.name, src, note) for s in scene.specimens for src, note in s.read_notes]).encode()
    doc = {"scene": source, "title": scene.resolved.get("title", ""), "yarn": scene.yarn_name,
           "specimens_data": [{"name": s.name, "sources": list(s.sources), "width_mm": s.width_mm,
                               "gauge_length_mm": s.gauge_length_mm, "stated_knit": s.knit,
                               "uncertainty": s.uncertainty, "total_force": s.total, "sd_rule": s.sigma_rule,
                               "zero_offsets_tared_N": dict(s.zero_offsets_N),
                               "read_notes": [f"{src}: {note}" for src, note in s.read_notes]}
                              for s in scene.specimens]}
    doc.update(result.as_dict())
    files["calibration.json"] = (json.dumps(_finite(doc), indent=1, default=_json_default, allow_nan=False)
                                 + "\n").encode()
    return write_result_set(out_dir, files, tuple(names))


def _finite(v):
    """JSON has no infinity or NaN: a not-identified sd (inf) or an absent value is written as null."""
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    if isinstance(v, np.ndarray):
        return _finite(v.tolist())
    if isinstance(v, (float, np.floating)) and not math.isfinite(float(v)):
        return None
    return v


def _json_default(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(type(v).__name__)


__all__ = ["UNUSABLE", "flag_lines", "zero_md", "one_yarn_md", "library_of", "cell_scene_of", "patch_scene_of", "report_md", "plot_fit", "write_calibration"]
