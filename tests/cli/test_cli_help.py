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
