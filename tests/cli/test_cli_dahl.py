"""``knitsim dahl fit`` / ``simulate`` run in-process through ``knitsim.cli.main``.

Expected parameters: the ``yarn`` row of knitsim/data/dahl_kes.toml (paper
table), from which scenes/dahl/kes_yarn_loop.csv was synthesised (1 % noise).
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from knitsim.cli import main
from knitsim.data import dahl_kes

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = ROOT / "scenes" / "dahl" / "kes_yarn_loop.csv"
YARN = next(r for r in dahl_kes()["dahl"] if r["sample"] == "yarn")


def _run_json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_fit_bundled_csv_recovers_paper_yarn_row(tmp_path, capsys):
    png = tmp_path / "fit.png"
    out = _run_json(capsys, ["dahl", "fit", str(BUNDLED), "--png", str(png), "--json"])
    assert {"parameters", "stderr", "units", "kes_units", "rms", "n_points", "reversals", "png", "success"} <= out.keys()
    assert out["columns"] == {"x": "kappa_1_mm", "F": "M_N_mm_per_mm"}
    assert png.is_file() and png.stat().st_size > 1000 and out["png"] == str(png)
    for name in ("sigma", "Fc"):
        got = out["kes_units"][name]
        assert abs(got["value"] - YARN[name]) <= 3 * got["stderr"]
        assert got["value"] == pytest.approx(YARN[name], rel=0.02)
    assert out["parameters"]["alpha"] == 1.0 and out["fixed"] == {"alpha": 1.0, "B": 0.0}


def test_fit_default_png_next_to_csv_and_text_output(tmp_path, capsys):
    csv = tmp_path / "loop.csv"
    shutil.copy(BUNDLED, csv)
    assert main(["dahl", "fit", str(csv), "--elastic", "--alpha", "free"]) == 0
    text = capsys.readouterr().out
    assert (tmp_path / "loop_dahl_fit.png").is_file()
    for token in ("sigma", "Fc", "alpha", "B", "gf.cm^2/cm", "+-"):
        assert token in text


def test_simulate_then_fit_xF_columns(tmp_path, capsys):
    csv = tmp_path / "xf.csv"
    assert main(["dahl", "simulate", "--sigma", "2.0", "--Fc", "0.5", "--alpha", "1", "--B", "0.3",
                 "--amplitude", "1.5", "--cycles", "2", "--noise", "0.005", "--seed", "4",
                 "--columns", "x_mm,F_N", "--out", str(csv)]) == 0
    capsys.readouterr()
    assert csv.read_text().splitlines()[0] == "x_mm,F_N"
    out = _run_json(capsys, ["dahl", "fit", str(csv), "--elastic", "--no-png", "--json"])
    assert out["columns"] == {"x": "x_mm", "F": "F_N"} and out["units"]["sigma"] == "N/mm"
    for name, true in (("sigma", 2.0), ("Fc", 0.5), ("B", 0.3)):
        assert abs(out["parameters"][name] - true) <= 3 * out["stderr"][name]


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return str(path)


@pytest.mark.parametrize("case", ["missing column", "nan", "few points", "no reversal", "bad alpha", "row and sigma"])
def test_bad_input_exits_2_with_one_line(case, tmp_path, capsys):
    loop = [f"{x},{x}" for x in [i / 20 for i in range(21)] + [1 - i / 20 for i in range(1, 21)]]
    if case == "missing column":
        argv = ["dahl", "fit", _write(tmp_path / "a.csv", "kappa_1_mm,moment", loop), "--no-png"]
    elif case == "nan":
        argv = ["dahl", "fit", _write(tmp_path / "a.csv", "x_mm,F_N", loop[:-1] + ["0.5,nan"]), "--no-png"]
    elif case == "few points":
        argv = ["dahl", "fit", _write(tmp_path / "a.csv", "x_mm,F_N", ["0,0", "1,1", "0,0"]), "--no-png"]
    elif case == "no reversal":
        argv = ["dahl", "fit", _write(tmp_path / "a.csv", "x_mm,F_N", loop[:21]), "--no-png"]
    elif case == "bad alpha":
        argv = ["dahl", "fit", str(BUNDLED), "--alpha", "-2", "--no-png"]
    else:
        argv = ["dahl", "simulate", "--row", "yarn", "--sigma", "1", "--out", str(tmp_path / "b.csv")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("knitsim: error:")
    expected = {"missing column": "missing column(s) M_N_mm_per_mm", "nan": "not finite", "few points": "need at least",
                "no reversal": "no reversal", "bad alpha": "--alpha = '-2'", "row and sigma": "--row"}[case]
    assert expected in err[0]


@pytest.mark.parametrize("argv", [["dahl", "--help"], ["dahl", "fit", "--help"], ["dahl", "simulate", "--help"]])
def test_help(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    assert "usage: knitsim dahl" in capsys.readouterr().out
