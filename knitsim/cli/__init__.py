"""The ``knitsim`` command line.

Each subcommand lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` (a callable
taking the parsed arguments and returning an exit status).

User mistakes raise :class:`knitsim.errors.KnitsimInputError`; :func:`main`
prints them as one line ``knitsim: error: ...`` and exits with status 2.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from ..errors import KnitsimInputError



def subcommand_modules() -> list[str]:
    """Names of the modules of this package that define a subcommand."""
    names = [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")]
    return sorted(n for n in names if n != "common")


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="knitsim",
        description="Batched simulator of technical knit patches (elastica quarter-stitch cells with friction).",
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"knitsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in subcommand_modules():
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``knitsim`` console command.

    SIGTERM and SIGHUP are taken as a Ctrl-C (:func:`knitsim.cli.common.sigterm_as_ctrl_c`): the commands that
    checkpoint save their work and say how to resume; the exit status is then 128 + the signal (143 for SIGTERM,
    129 for SIGHUP: what a shell, ``timeout`` and a batch scheduler read as "ended by" it, as before), not
    Ctrl-C's 130."""
    from .common import sigterm_as_ctrl_c

    with sigterm_as_ctrl_c() as terminated:
        status = _main(argv)
    return 128 + int(terminated[0]) if terminated and status == 130 else status


def _main(argv: list[str] | None) -> int:
    try:
        # (inside: a Ctrl-C while the parser's imports load, the first half second, is an interrupt too)
        parser = build_parser()
        args = parser.parse_args(argv)
        status = args.func(args)
    except KnitsimInputError as exc:
        print(f"knitsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("knitsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # output piped into a command that stopped reading (e.g. `| head`)
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
