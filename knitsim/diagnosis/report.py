"""HTML report of a sim-to-real diagnosis (issue 6, step 4: "how far").

Reads only the result dict of the diagnosis (the JSON written by
``knitsim diagnose --json``; layout in :mod:`knitsim.diagnosis.diagnose`) and
renders one self-contained page: no external asset, the two figures embedded
as base64 ``data:image/png`` URIs, every string from the result passed
through :func:`html.escape` (curve sources, notes and reasons come from user
files).

Figures (matplotlib, Agg canvas, no pyplot state):

- :func:`figure_curves`: one panel per measured curve, force per wale [N]
  against the strain of the course length; panels of
  ``PANEL_SIZE_IN`` at ``DPI``, in at most ``MAX_COLUMNS`` columns.
- :func:`figure_stage_bars`: RMS force error per stage key, baseline / best
  effect / best pair side by side; ``BARS_SIZE_IN`` at ``DPI``.

Numbers are shown with 4 significant digits (percentages with 3); NaN and
missing values as "n/a".
"""
from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path
from typing import Any, Mapping

from ..errors import KnitsimInputError
from .effects import parameter_unit
from ..io.results import atomic_write_bytes

#: resolution of both figures [dots per inch]
DPI = 100
#: size of one panel of :func:`figure_curves` [in] (width, height)
PANEL_SIZE_IN = (5.0, 3.8)
#: panels per row in :func:`figure_curves`
MAX_COLUMNS = 2
#: size of :func:`figure_stage_bars` [in] (width, height)
BARS_SIZE_IN = (8.0, 4.5)

_REQUIRED = ("noise", "baseline", "where", "candidates", "verdict", "curves")
_REQUIRED_BASELINE = ("params", "rms_N", "stages")
_REQUIRED_CURVE = ("strain", "measured", "baseline")
_STRAIN_LABEL = "strain of the course length, C/C0 - 1 [-]"
_FORCE_LABEL = "force per wale [N]"


# ------------------------------------------------------------------ checks
def _missing(where: str) -> KnitsimInputError:
    return KnitsimInputError(f"{where}: missing")


def _check(result: Any) -> None:
    """Raise :class:`KnitsimInputError` naming the first missing required key."""
    if not isinstance(result, Mapping):
        raise KnitsimInputError(f"result: expected a dict, got {type(result).__name__}")
    for key in _REQUIRED:
        if key not in result or (result[key] is None and key != "candidates"):
            raise _missing(f"result[{key!r}]")
    base = result["baseline"]
    if not isinstance(base, Mapping):
        raise KnitsimInputError(f"result['baseline']: expected a dict, got {type(base).__name__}")
    for key in _REQUIRED_BASELINE:
        if key not in base:
            raise _missing(f"result['baseline'][{key!r}]")
    for i, curve in enumerate(result["curves"]):
        for key in _REQUIRED_CURVE:
            if not isinstance(curve, Mapping) or key not in curve:
                raise _missing(f"result['curves'][{i}][{key!r}]")
    for i, cand in enumerate(result["candidates"] or []):
        if not isinstance(cand, Mapping) or "effect" not in cand:
            raise _missing(f"result['candidates'][{i}]['effect']")


# -------------------------------------------------------------- formatting
def _is_nan(v: Any) -> bool:
    return isinstance(v, float) and not math.isfinite(v)


def _fmt(v: Any, sig: int = 4) -> str:
    """A number with ``sig`` significant digits, booleans as yes/no, None/NaN as n/a."""
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(x):
        return "n/a" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return f"{x:.{sig}g}"


def _pct(v: Any) -> str:
    """A fraction as a percentage with 3 significant digits."""
    if v is None or _is_nan(v):
        return "n/a"
    return f"{100.0 * float(v):.3g} %"


def _e(v: Any) -> str:
    return html.escape(str(v), quote=True)


def fit_uncertainty(name: str, errors: Mapping | None, at_bounds: Mapping | None) -> tuple[str | None, Any]:
    """How a fitted parameter's uncertainty reads, for the console and the report alike: ("bound", side) where the
    fit rests on a bound (no estimate), ("se", value) for a positive standard error, ("undetermined", None) for
    a zero or non-finite one (a direction the data do not constrain: the covariance's pseudo-inverse gives it
    no variance), (None, None) where there is none."""
    if name in (at_bounds or {}):
        return "bound", at_bounds[name]
    e = (errors or {}).get(name)
    if e is None:
        return None, None
    return ("se", e) if math.isfinite(e) and e > 0 else ("undetermined", None)


def _uncertainty_text(name: str, errors: Mapping | None, at_bounds: Mapping | None) -> str:
    kind, v = fit_uncertainty(name, errors, at_bounds)
    if kind == "se":
        return f"± {_fmt(v, 2)}"
    return {"bound": f"at its {v} bound", "undetermined": "not determined by the data", None: ""}[kind]


def _params_text(params: Mapping | None, errors: Mapping | None = None, at_bounds: Mapping | None = None) -> str:
    """``name = value ± se`` (or why there is none) joined by commas (escaped)."""
    if not params:
        return "none"
    parts = []
    for name, val in params.items():
        txt = f"{name} = {_fmt(val)}"
        unc = _uncertainty_text(name, errors, at_bounds)
        if unc:
            txt += f" ({unc})" if not unc.startswith("±") else f" {unc}"
        unit = parameter_unit(name)
        if unit and unit != "-":
            txt += f" {unit}"
        parts.append(txt)
    return _e(", ".join(parts))


def _table(headers: list[str], rows: list[list[str]], cls: str = "") -> str:
    """An HTML table; ``rows`` cells are already escaped HTML."""
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>\n" for row in rows)
    attr = f' class="{cls}"' if cls else ""
    return f"<table{attr}>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}</tbody>\n</table>\n"


# ------------------------------------------------------------ what is best
def _best_candidate(result: Mapping) -> Mapping | None:
    """The candidate named by the verdict, else the top-ranked one (None if no candidate)."""
    cands = result.get("candidates") or []
    eff = (result.get("verdict") or {}).get("effect")
    for c in cands:
        if eff is not None and c.get("effect") == eff:
            return c
    return cands[0] if cands else None


def _best_label(result: Mapping) -> str:
    verdict = result.get("verdict") or {}
    eff = verdict.get("effect")
    if eff is not None:
        # on the plots too: a verdict that is not confident says so (a blind probe read only "best model")
        return f"best model: {eff}" + ("" if verdict.get("confident", True) else " (not confident)")
    best = _best_candidate(result)
    if best is not None:
        return f"best candidate: {best.get('effect')} (not significant)"
    return "best model"


def _pair_label(pair: Mapping | None) -> str:
    effects = (pair or {}).get("effects") or []
    return "best pair: " + " + ".join(str(x) for x in effects) if effects else "best pair"


def _stage_order(result: Mapping) -> list[str]:
    """Stage keys as ordered in ``where``, then any other baseline stage key."""
    keys = [str(k) for k in result.get("where") or []]
    for k in (result["baseline"].get("stages") or {}):
        if str(k) not in keys:
            keys.append(str(k))
    return keys


def _stage_rms(stages: Mapping | None, key: str) -> float:
    st = (stages or {}).get(key)
    if not st or st.get("rms_N") is None:
        return math.nan
    return float(st["rms_N"])


def _stage_bar_data(result: Mapping) -> tuple[list[str], list[tuple[str, list[float]]]]:
    """Stage keys (ordered as ``where``) and the RMS error series of the bar chart."""
    keys = _stage_order(result)
    series = [("baseline", [_stage_rms(result["baseline"].get("stages"), k) for k in keys])]
    best = _best_candidate(result)
    if best is not None:
        series.append((_best_label(result), [_stage_rms(best.get("stages"), k) for k in keys]))
    pair = result.get("pair")
    if pair:
        series.append((_pair_label(pair), [_stage_rms(pair.get("stages"), k) for k in keys]))
    return keys, series


# ----------------------------------------------------------------- figures
def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def _new_figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def figure_curves(result: dict) -> bytes:
    """PNG of measured and modelled force per wale against strain, one panel per curve.

    Parameters
    ----------
    result : dict
        Result of the diagnosis; reads ``curves`` (``strain``, ``measured``,
        ``baseline``, optional ``best`` and ``pair`` [N per wale], ``source``),
        ``verdict``, ``candidates`` and ``pair`` for the legend.

    Returns
    -------
    bytes
        PNG; panels of ``PANEL_SIZE_IN`` inches at ``DPI``, ``MAX_COLUMNS``
        per row (two curves give a 1000 x 380 pixel image).
    """
    _check(result)
    curves = list(result["curves"])
    n = max(len(curves), 1)
    ncols = min(n, MAX_COLUMNS)
    nrows = -(-n // ncols)
    fig = _new_figure(PANEL_SIZE_IN[0] * ncols, PANEL_SIZE_IN[1] * nrows)
    best_label = _best_label(result)
    pair_label = _pair_label(result.get("pair"))
    if not curves:
        ax = fig.add_subplot(1, 1, 1)
        ax.text(0.5, 0.5, "no curves in the result", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return _png(fig)
    for i, curve in enumerate(curves):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        s = [float(x) for x in curve["strain"]]
        ax.plot(s, [float(x) for x in curve["measured"]], ls="", marker="o", ms=2.5, color="0.25",
                label="measured", zorder=3)
        ax.plot(s, [float(x) for x in curve["baseline"]], lw=1.3, color="tab:blue", label="baseline")
        if curve.get("best") is not None:
            ax.plot(s, [float(x) for x in curve["best"]], lw=1.3, color="tab:red", label=best_label)
        if curve.get("pair") is not None:
            ax.plot(s, [float(x) for x in curve["pair"]], lw=1.3, ls="--", color="tab:green",
                    label=pair_label)
        ax.set_xlabel(_STRAIN_LABEL, fontsize=8)
        ax.set_ylabel(_FORCE_LABEL, fontsize=8)
        ax.set_title(Path(str(curve.get("source", f"curve {i + 1}"))).name, fontsize=9)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    return _png(fig)


def figure_stage_bars(result: dict) -> bytes:
    """PNG of grouped bars: RMS force error per stage key before and after the best effect (and pair).

    Stage keys are ordered as ``result["where"]`` (largest share of the
    baseline's squared error first); a stage a model does not visit has no bar.

    Returns
    -------
    bytes
        PNG of ``BARS_SIZE_IN`` inches at ``DPI`` (800 x 450 pixels).
    """
    _check(result)
    import numpy as np

    keys, series = _stage_bar_data(result)
    fig = _new_figure(*BARS_SIZE_IN)
    ax = fig.add_subplot(1, 1, 1)
    if not keys:
        ax.text(0.5, 0.5, "no stages in the result", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return _png(fig)
    x = np.arange(len(keys))
    width = 0.8 / len(series)
    colours = ("tab:blue", "tab:red", "tab:green")
    for j, (label, vals) in enumerate(series):
        hatch = "//" if j == 2 else None
        ax.bar(x + (j - (len(series) - 1) / 2) * width, vals, width, label=label, color=colours[j % 3],
               hatch=hatch, edgecolor="white" if hatch else None)
    ax.set_xticks(x)
    ax.set_xticklabels(keys, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("RMS force error per wale [N]", fontsize=9)
    ax.set_xlabel("stage", fontsize=9)
    ax.tick_params(axis="y", labelsize=8)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{_e(alt)}" src="data:image/png;base64,{data}">'


# -------------------------------------------------------------------- page
def _offsets_text(c: dict) -> str:
    """``; zero offset FILE v N`` for each curve's fitted load-cell offset of a candidate's fit (escaped)."""
    off = c.get("offsets_N") or {}
    return "".join(f"; zero offset {_e(Path(str(k)).name)} {_e(_fmt(v))} N" for k, v in off.items())


def _naming(c: dict, verdict: dict) -> str:
    """"named" for the verdict's effect; "passes" for another candidate that passes the same tests (the
    verdict names one: a closer rival, or a pair, may pass them too); "no" otherwise."""
    if verdict.get("effect") is not None and verdict.get("effect") == c.get("effect"):
        return "named"
    return "passes" if c.get("significant") and c.get("practical") else "no"


def verdict_sentence(result: dict) -> str:
    """The verdict in one plain-text sentence (not escaped)."""
    v = result.get("verdict") or {}
    eff, stage = v.get("effect"), v.get("stage")
    conf = "confident" if v.get("confident") else "not confident"
    reason = v.get("reason")
    tail = f" ({conf}{': ' + str(reason) if reason else ''})."
    if v.get("kind") == "none":
        return "Verdict: nothing is missing, the model explains these curves within their noise" + tail
    if eff is None:
        where = f"; the largest gap is in stage {stage}" if stage else ""
        return f"Verdict: unexplained, no effect explains the gap{where}" + tail
    where = f" in stage {stage}" if stage else ""
    return (f"Verdict: the gap is best explained by {eff}, mainly{where}; it shrinks the RMS force error "
            f"by {_pct(v.get('shrink'))}" + tail)


def _indicator_table(ind: Any) -> str:
    """Indicators of :func:`knitsim.diagnosis.gap.curve_indicators`, or {model: those}, or anything else."""
    if isinstance(ind, Mapping) and "cycles" in ind:
        ind = {"": ind}
    if isinstance(ind, Mapping) and all(isinstance(x, Mapping) and "cycles" in x for x in ind.values()):
        rows = []
        for model, x in ind.items():
            for c in x.get("cycles") or []:
                rows.append([_e(model), _e(_fmt(c.get("cycle"))), _e(_fmt(c.get("peak_force_N"))),
                             _e(_fmt(c.get("strain_at_peak"))), _e(_fmt(c.get("residual_strain"))),
                             _e(_fmt(c.get("energy_N_per_strain")))])
            rows.append([_e(model), "all", "", "", "", "jamming at strain "
                         + _e(_fmt(x.get("strain_at_first_jamming")))])
        return _table(["model", "cycle", "peak force [N]", "strain at peak", "residual strain",
                       "hysteresis energy [N]"], rows)
    if isinstance(ind, Mapping):
        rows = [[_e(k), _e(_fmt(v) if isinstance(v, (int, float)) or v is None else v)] for k, v in ind.items()]
        return _table(["indicator", "value"], rows)
    return f"<p>{_e(ind)}</p>\n"


_CSS = """
body { font-family: sans-serif; margin: 2em; max-width: 75em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: left; }
th { background: #eee; }
.verdict { font-size: 1.15em; background: #f4f4e8; padding: 0.6em; border-left: 4px solid #997; }
img { max-width: 100%; }
"""


def render_report(result: dict) -> str:
    """The self-contained HTML page of a diagnosis result.

    Parameters
    ----------
    result : dict
        Result of the diagnosis (see the module docstring); ``pair``,
        ``indistinguishable``, ``scene``, ``inputs``, ``timing_s`` and
        ``indicators`` (per curve, also read from each curve) are optional.

    Returns
    -------
    str
        HTML5 text; figures as base64 data URIs, every string escaped.

    Raises
    ------
    KnitsimInputError
        A required key is missing (the message names it).
    """
    _check(result)
    base = result["baseline"]
    verdict = result["verdict"] or {}
    noise = result["noise"] or {}
    title = f"knitsim diagnosis: {result.get('scene') or 'untitled scene'}"
    best = _best_candidate(result)
    pair = result.get("pair")
    out = ["<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n",
           f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n",
           f"<h1>{_e(title)}</h1>\n"]
    out.append(f'<p class="verdict">{_e(verdict_sentence(result))}</p>\n')
    inputs = result.get("inputs") or []
    if inputs:
        out.append("<p>Measured curves: " + ", ".join(f"<code>{_e(p)}</code>" for p in inputs) + "</p>\n")
    # how each file was read (a lab's column names taken for ours, a cycle column from 0, a log that starts by
    # unloading): said on the console's read line and here, where the verdict is read
    read = [(Path(str(c.get("source"))).name, n) for c in result["curves"] for n in c.get("read_notes") or ()]
    if read:
        out.append("<p>How the files were read:</p>\n<ul>\n" + "".join(
            f"<li><code>{_e(src)}</code>: {_e(n)}</li>\n" for src, n in read) + "</ul>\n")
    probs = verdict.get("probabilities") or {}
    if probs:
        out.append("<p>Probabilities (BIC weights over the candidates and none): " + ", ".join(
            f"{_e(k)} {_e(_fmt(p))}" for k, p in sorted(probs.items(), key=lambda kv: -kv[1])) + ".</p>\n")
    if pair and pair.get("effects"):
        gain = pair.get("gain_over_best")
        out.append(f"<p>{_e(_pair_label(pair))}: "
                   f"{'a significant' if pair.get('significant') else 'no significant'} gain over the best effect "
                   f"alone (BIC {_e(_fmt(gain))})"
                   + (f"; at the bounds of its search (values not estimated): {_e(pair['at_bounds_note'])}"
                      if pair.get("at_bounds_note") else "") + ".</p>\n")
    rows = [[_e(c.get("source")), _e(_fmt(c.get("sigma_N")) + (f" + {100.0 * c['per_N']:.3g} % of the force"
                                                                 if c.get("per_N") else "")
                                     + (f", strain jitter {c['strain_sd']:.2g} (times the curve's slope)"
                                        if c.get("strain_sd") else "")),
             _e(c.get("method")), _e(c.get("note"))]
            for c in noise.get("curves") or []]
    if not rows:
        out.append(f"<p>Measurement noise: sigma = {_e(_fmt(noise.get('sigma_N')))} N per wale "
                   f"({_e(noise.get('method', 'method not given'))}).</p>\n")
    else:
        out.append("<h2>Measurement noise, per curve</h2>\n")
        out.append(_table(["curve", "sd [N per wale]", "how", "note"], rows))
    within = {True: "within the noise", False: "NOT within the noise", None: "not judged (no noise known)"}.get(
        noise.get("baseline_within_noise"), "not judged")
    out.append(f"<p>Baseline fit: chi2/dof = {_e(_fmt(noise.get('baseline_chi2_per_dof')))} (1 +- "
               f"{_e(_fmt(noise.get('expected_sd')))} for noise alone): {_e(within)}."
               f"{' ' + _e(noise.get('adequacy_note')) if noise.get('adequacy_note') else ''}</p>\n")
    outl = base.get("outliers") or []
    if outl:
        out.append("<p>Outlier rows left out of the fit: " + ", ".join(
            f"{_e(Path(str(o.get('source'))).name)} row {_e(_fmt(o.get('row')))} ({_e(_fmt(o.get('z')))} sd)"
            for o in outl) + ".</p>\n")

    # baseline
    out.append("<h2>Baseline</h2>\n")
    rows = [[_e(k), _e(_fmt(v)), _e(parameter_unit(k) or "-"),
             _e(_uncertainty_text(k, base.get("std_errors"), base.get("at_bounds")).lstrip("± ") or "n/a")]
            for k, v in (base.get("params") or {}).items()]
    out.append(_table(["parameter", "value", "unit", "standard error"], rows))
    offsets = base.get("offsets_N") or {}
    if offsets:
        # fitted with the baseline: a load cell's zero, not the knit (a curve's rows shifted by it)
        out.append("<p>Load-cell zero offsets fitted with it (added to the model's force per wale): " + ", ".join(
            f"{_e(Path(str(k)).name)} {_e(_fmt(v))} N" for k, v in offsets.items()) + ".</p>\n")
    out.append(f"<p>RMS force error {_e(_fmt(base.get('rms_N')))} N per wale, "
               f"BIC {_e(_fmt(base.get('bic')))}.</p>\n")

    # where
    out.append("<h2>Where: the gap per stage</h2>\n")
    if noise.get("baseline_within_noise") is True:
        # a within-noise chi2 excess shared out reads as a gap where there is none (a `none` names no stage)
        out.append("<p>The baseline fits within the noise: there is no gap beyond it, and the shares below are "
                   "of the noise's own chi2.</p>\n")
    headers = ["stage", "n", "RMS [N]", "max |error| [N]", "share"]
    if best is not None:
        headers.append(f"RMS with {best.get('effect')} [N]")
    if pair:
        headers.append("RMS with the pair [N]")
    rows = []
    stages = base.get("stages") or {}
    for k in _stage_order(result):
        st = stages.get(k) or {}
        row = [_e(k), _e(_fmt(st.get("n"))), _e(_fmt(st.get("rms_N"))), _e(_fmt(st.get("max_abs_N"))),
               _e(_pct(st.get("share")))]
        if best is not None:
            row.append(_e(_fmt(_stage_rms(best.get("stages"), k))))
        if pair:
            row.append(_e(_fmt(_stage_rms(pair.get("stages"), k))))
        rows.append(row)
    out.append(_table(headers, rows, "where"))

    # which
    out.append("<h2>Which: candidate effects, best first</h2>\n")
    cands = result.get("candidates") or []
    if cands:
        rows = [[_e(c.get("effect")), _params_text(c.get("params"), c.get("std_errors"), c.get("at_bounds")) + _offsets_text(c),
                 _e(_fmt(c.get("rms_N"))), _e(_pct(c.get("shrink"))), _e(_fmt(c.get("score"))),
                 _e(_pct(c.get("share_of_excess"))), _e(_fmt(c.get("probability"))),
                 _e(_fmt(c.get("chi2_per_dof")) + {True: " (within)", False: " (beyond)"}.get(c.get("within_noise"), "")),
                 _e(_naming(c, verdict)),
                 _e(_fmt(bool(c.get("identifiable")))),
                 _e(("evidence rests on assumed noise. " if c.get("rests_on_assumed_noise") else "")
                    + (c.get("note") or ""))] for c in cands]
        out.append(_table(["effect", "parameters", "RMS [N]", "shrink", "score", "share of the gap", "probability",
                           "chi2/dof (noise)", "named / passes the naming tests",
                           "identifiable", "note"], rows, "candidates"))
    else:
        out.append("<p>No candidate effect was evaluated.</p>\n")
    indist = result.get("indistinguishable") or []
    if indist:
        out.append("<p>The data cannot tell these effects apart:</p>\n<ul>\n"
                   + "".join(f"<li>{_e(' and '.join(str(x) for x in p))}</li>\n" for p in indist) + "</ul>\n")
    else:
        out.append("<p>No pair of effects was found indistinguishable.</p>\n")

    # how far
    out.append("<h2>How far: the best pair</h2>\n")
    if pair:
        effects = " + ".join(str(x) for x in pair.get("effects") or [])
        out.append(_table(["effects", "parameters", "RMS [N]", "shrink", "score"],
                          [[_e(effects), _params_text(pair.get("params"), pair.get("std_errors"), pair.get("at_bounds")),
                            _e(_fmt(pair.get("rms_N"))), _e(_pct(pair.get("shrink"))),
                            _e(_fmt(pair.get("score")))]], "pair"))
    else:
        out.append("<p>No pair of effects was fitted.</p>\n")
    out.append("<h2>Figures</h2>\n")
    out.append("<p>" + _img(figure_curves(result), "measured and modelled force per wale against strain")
               + "</p>\n")
    out.append("<p>" + _img(figure_stage_bars(result), "RMS force error per stage") + "</p>\n")

    # indicators (optional)
    per_curve = result.get("indicators")
    blocks = []
    for i, curve in enumerate(result["curves"]):
        ind = curve.get("indicators")
        if ind is None and isinstance(per_curve, (list, tuple)) and i < len(per_curve):
            ind = per_curve[i]
        if ind is not None:
            blocks.append(f"<h3>{_e(curve.get('source', f'curve {i + 1}'))}</h3>\n" + _indicator_table(ind))
    if isinstance(per_curve, Mapping):
        blocks.append(_indicator_table(per_curve))
    if blocks:
        out.append("<h2>Indicators per curve</h2>\n" + "".join(blocks))
    if result.get("timing_s") is not None:
        out.append(f"<p>Diagnosis time {_e(_fmt(result['timing_s'], 3))} s.</p>\n")
    out.append("</body>\n</html>\n")
    return "".join(out)


def write_report(result: dict, path) -> Path:
    """Render the report and write it to ``path`` atomically.

    The page is rendered completely before anything is written, then written
    through a temporary sibling and a rename
    (:func:`knitsim.io.results.atomic_write_bytes`): a failure leaves no file
    (and an older report at ``path`` untouched).
    """
    text = render_report(result)
    return atomic_write_bytes(Path(path), text.encode("utf-8"))
