"""Every ``--help`` reads as plain text: no reStructuredText markup from the docstrings it is built from
(issue 14: ``diagnose --help`` showed double back-quotes and ``:mod:`` roles)."""
from __future__ import annotations

import argparse
import re

import pytest

from knitsim.cli import build_parser

RST = re.compile(r"``|:(mod|func|class|data|meth|attr|ref|doc):`")


def _parsers(parser: argparse.ArgumentParser, path: str = "knitsim"):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{path} {name}")


PARSERS = dict(_parsers(build_parser()))


def test_every_subcommand_is_reached():
    # the walk reaches nested subcommands too (capstan fit, dahl simulate, ...)
    assert {"knitsim run", "knitsim diagnose", "knitsim study", "knitsim calibrate"} <= set(PARSERS)
    assert any(p.count(" ") == 2 for p in PARSERS)


@pytest.mark.parametrize("path", sorted(PARSERS))
def test_help_has_no_rst_markup(path):
    text = PARSERS[path].format_help()
    found = RST.search(text)
    assert found is None, f"{path} --help shows {found.group(0)!r}: ...{text[max(0, found.start() - 40):found.end() + 40]}..."


def test_a_scene_for_another_command_is_named_so(tmp_path, capsys):
    """A blind probe gave `knitsim cell` the bundled patch scene and a sweep scene, and read only "seed = 2015:
    unknown key"; `knitsim usd` on a cell's folder read "no cells.nc (... cell_fields = false?)".  Expected:
    the command that reads such a scene (its distinctive tables: [patch], [maps] and seed for run, [sweep] for
    sweep, [calibration] and [[specimens]] for calibrate), and what usd draws."""
    from pathlib import Path
    from knitsim.cli import main
    scenes = Path(__file__).resolve().parents[2] / "scenes"
    cases = [("cell", scenes / "random_phi0.toml", "`knitsim run`: it has patch, maps, seed"),
             ("cell", scenes / "sweeps" / "e_glass_friction_sweep.toml", "`knitsim sweep`: it has sweep"),
             ("run", scenes / "calibration" / "do2020" / "calibrate.toml", "`knitsim calibrate`"),
             ("calibrate", scenes / "random_phi0.toml", "`knitsim run`"),
             # a blind probe's sweep of a patch scene read only "seed = 3: unknown key"
             ("sweep", scenes / "random_phi0.toml", "`knitsim run`: it has patch, maps, seed"),
             # a blind probe's run of a diagnosis scene read only "diagnosis = {...}: unknown key"
             ("run", scenes / "diagnosis" / "real" / "singal2024_acrylic_stockinette_y.toml",
              "`knitsim diagnose`: it has diagnosis"),
             ("cell", scenes / "diagnosis" / "real" / "singal2024_acrylic_stockinette_y.toml",
              "`knitsim diagnose`: it has diagnosis")]
    for cmd, scene, hint in cases:
        assert main([cmd, str(scene), "--out", str(tmp_path / cmd)]) == 2
        assert f"(this is a scene for {hint}" in capsys.readouterr().err
        assert not (tmp_path / cmd).exists()
    # its own scene with a typo: no hint (the error is the typo)
    bad = tmp_path / "typo.toml"
    bad.write_text((scenes / "paper" / "e_glass_monotonic.toml").read_text() + "\nfriction_typo = 1\n")
    assert main(["cell", str(bad), "--out", str(tmp_path / "t")]) == 2
    assert "this is a scene for" not in capsys.readouterr().err
    # a sweep's scene is a cell scene (its cells included): a typo in one gets no hint either
    assert main(["sweep", str(bad), "--out", str(tmp_path / "t")]) == 2
    assert "this is a scene for" not in capsys.readouterr().err
    # diagnose given a patch scene: the command that reads it, beside the missing [diagnosis]
    curve = scenes / "diagnosis" / "real" / "singal2024_acrylic_stockinette_y.csv"
    assert main(["diagnose", str(curve), "--scene", str(scenes / "random_phi0.toml")]) == 2
    assert "(this is a scene for `knitsim run`: it has patch, maps, seed)" in capsys.readouterr().err
    # usd on a cell's results
    assert main(["cell", str(scenes / "paper" / "e_glass_monotonic.toml"), "--out", str(tmp_path / "c")]) == 0
    capsys.readouterr()
    assert main(["usd", str(tmp_path / "c"), "--out", str(tmp_path / "c.usda")]) == 2
    assert "holds the results of `knitsim cell`" in capsys.readouterr().err


def test_a_resume_command_calls_knitsim_as_it_was_typed(monkeypatch, tmp_path):
    """The README runs `.venv/bin/knitsim ...`; the resume hint printed bare `knitsim run ...`, which is not on
    a shell's PATH after those commands (a probe of the README's examples).  The hint now calls the program as
    typed where the PATH's `knitsim` is another (or none), and `knitsim` where it is the same."""
    import os

    from knitsim.cli.common import resume_command

    venv = tmp_path / ".venv" / "bin"
    venv.mkdir(parents=True)
    prog = venv / "knitsim"
    prog.write_text("#!/bin/sh\n")
    prog.chmod(0o755)
    monkeypatch.setattr("sys.argv", [".venv/bin/knitsim", "run", "s.toml", "--overwrite"])
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert resume_command("run", []) == ".venv/bin/knitsim run s.toml --resume"
    monkeypatch.setenv("PATH", str(venv) + os.pathsep + "/nonexistent")
    assert resume_command("run", []) == "knitsim run s.toml --resume"
    monkeypatch.setattr("sys.argv", ["/usr/bin/pytest", "-x"])                 # a test or the API
    assert resume_command("run", ["s.toml"]) == "knitsim run s.toml --resume"
