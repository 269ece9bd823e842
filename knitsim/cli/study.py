"""``knitsim study NAME``: rerun a paper's model studies and tabulate its claims.

``knitsim study dusserre2015 [--json] [--out DIR]`` runs Dusserre (2015)
section 4 (Figs 7, 8, 11) with the E-glass data, prints each claim with the
paper's value, ours and a verdict, and writes the table (``.txt``, ``.json``)
and PNG figures to DIR.  ``knitsim study dusserre2015-experiment`` calibrates
physically defensible changes of the model (in-plane width, jamming by
contact, unloading rule, compaction, Dahl friction) to the cyclic experiment's
peaks and residual strain (Fig. 10) and says which reaches them.
"""
from __future__ import annotations

from pathlib import Path

from ..studies import STUDIES
from ..io.jsonable import json_text
from ..io.results import add_output_flags, prepare_output_dir, record_outputs
from .common import add_json_flag, plain_help, print_json

#: what each study writes into --out (recorded there: --overwrite removes these and nothing else)
STUDY_OUTPUTS = {"dusserre2015": ("dusserre2015_claims.txt", "dusserre2015_claims.json", "dusserre2015_fig7.png",
                                  "dusserre2015_fig8.png", "dusserre2015_fig11.png"),
                 "dusserre2015-experiment": ("dusserre2015_experiment.txt", "dusserre2015_experiment.json",
                                             "dusserre2015_experiment.png")}


def register(subparsers) -> None:
    """Add ``knitsim study``."""
    p = subparsers.add_parser("study", help="rerun a paper's model studies and tabulate its claims",
                              description=plain_help(__doc__.split("\n\n")[0]))
    p.add_argument("name", choices=STUDIES, help="the study")
    p.add_argument("--out", metavar="DIR", help="write the table and PNG figures here")
    add_output_flags(p)
    p.add_argument("--increment", type=float, default=0.01, help="strain increment (default 0.01)")
    p.add_argument("--jamming-criterion", default="w_4d", choices=("w_4d", "head_gap"),
                   help="W = 4d (paper) or heads touching (head gap = d)")
    p.add_argument("--force-cut", default="2Psin", choices=("2Psin", "2P"),
                   help="force per wale 2 P sin(gamma) (default) or 2 P")
    add_json_flag(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """``knitsim study``: run the named study, print its table (or JSON) and write the table and
    figures to ``--out`` if given."""
    if args.out:
        prepare_output_dir(args.out, overwrite=args.overwrite, writes=STUDY_OUTPUTS[args.name])
    if args.name == "dusserre2015-experiment":
        return _run_experiment(args)
    from ..studies import dusserre2015 as study
    res = study.run(increment=args.increment, jamming_criterion=args.jamming_criterion,
                    force_cut=args.force_cut)
    out = {"variant": res["variant"], "rows": res["rows"]}
    if args.out:
        d = Path(args.out)
        record_outputs(d, STUDY_OUTPUTS[args.name])
        (d / "dusserre2015_claims.txt").write_text(study.table_text(res) + "\n")
        (d / "dusserre2015_claims.json").write_text(json_text(out))
        out["figures"] = [str(p) for p in study.figures(res, d)]
    if args.json:
        print_json(out)
    else:
        print(study.table_text(res))
        for f in out.get("figures", []):
            print("wrote", f)
    return 0


def _run_experiment(args) -> int:
    """The cyclic experiment (Fig. 10) against calibrated candidate changes of the model."""
    import sys

    from ..studies import dusserre2015_experiment as study
    res = study.run(increment=args.increment, progress=lambda n: print(f"calibrating {n} ...", file=sys.stderr))
    if args.out:
        d = Path(args.out)
        record_outputs(d, STUDY_OUTPUTS[args.name])
        (d / "dusserre2015_experiment.txt").write_text(study.table_text(res) + "\n")
        (d / "dusserre2015_experiment.json").write_text(json_text(res))
        res["figures"] = [str(p) for p in study.figures(res, d)]
    if args.json:
        print_json(res)
    else:
        print(study.table_text(res))
        for f in res.get("figures", []):
            print("wrote", f)
    return 0
