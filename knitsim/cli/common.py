"""Helpers shared by the subcommands: JSON output and CSV input."""
from __future__ import annotations

import contextlib
import re
import sys
from pathlib import Path
from typing import Any, Iterator

from ..errors import KnitsimInputError
from ..io.jsonable import json_text
from ..io.table_input import read_csv_columns  # noqa: F401  (re-exported: capstan and dahl fits read CSV)


@contextlib.contextmanager
def naming_scene(path, command: str | None = None) -> Iterator[None]:
    """Errors of reading the scene ``path`` name the file first (``FILE: key = value: why``) where they do not
    already: a key alone does not say which of a user's scenes is wrong (a blind probe).  With ``command``,
    a scene that has the top-level tables of another command's scenes is said to be one (a probe's
    ``knitsim cell`` on a patch scene read only "seed = 2015: unknown key")."""
    try:
        yield
    except KnitsimInputError as exc:
        msg = str(exc)
        hint = _other_command_hint(path, command)
        # (the loaders write the path as Path() spells it: ./x.toml as x.toml)
        if str(path) in msg or str(Path(path)) in msg:
            if not hint:
                raise
            raise KnitsimInputError(msg + hint) from None
        raise KnitsimInputError(f"{path}: {msg}{hint}") from None


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[list]:
    """SIGTERM (a batch scheduler's time limit, ``kill``, ``timeout``) and SIGHUP (the terminal closed, an ssh
    session dropped) taken as a Ctrl-C while the block runs: each goes to the SIGINT handler in force when it
    arrives (:func:`knitsim.patch.runner.run_patch`'s, which lets the increment under way finish and checkpoints
    it), else raises KeyboardInterrupt; so every command that saves its work and says how to resume on Ctrl-C
    does so on these too (before, SIGTERM ended the process at once: ``knitsim run`` kept only its last periodic
    checkpoint and said nothing; SIGHUP did so until this handled it too).  Yields a list that holds the signals
    that came (:func:`knitsim.cli.main` exits 128 + the first: 143, 129).  The previous handlers are restored
    after; a signal that was ignored when the block began (``nohup``) stays ignored, and outside the main thread
    (where no handler can be set) nothing changes."""
    import signal
    import threading

    got: list = []
    if threading.current_thread() is not threading.main_thread():
        yield got
        return

    def on_signal(signum, frame):
        got.append(signum)
        handler = signal.getsignal(signal.SIGINT)
        if callable(handler):
            handler(signal.SIGINT, frame)
        else:                              # Ctrl-C ignored (a job in the background) or default: still stop
            raise KeyboardInterrupt

    taken = [s for s in (signal.SIGTERM, getattr(signal, "SIGHUP", None))
             if s is not None and signal.getsignal(s) != signal.SIG_IGN]
    old = {s: signal.signal(s, on_signal) for s in taken}
    try:
        yield got
    finally:
        # (None: a handler installed outside Python, which Python cannot put back; the default is what it can)
        for s, h in old.items():
            signal.signal(s, signal.SIG_DFL if h is None else h)


#: top-level tables or keys that only one command's scenes have
_SCENE_KEYS = {"cell": ("cells",), "run": ("patch", "specimen", "zones", "maps", "seed", "grades", "solver"),
               "sweep": ("sweep",), "calibrate": ("calibration", "specimens"), "diagnose": ("diagnosis",)}


def _other_command_hint(path, command: str | None) -> str:
    """`` (it is a scene for knitsim X: it has [k])`` where the scene has another command's keys only."""
    if command is None:
        return ""
    try:
        from ..scene.schema import load_toml
        doc = load_toml(path)
    except (KnitsimInputError, OSError):
        return ""
    # (a sweep's scene is a cell scene, its cells included, with or without its [sweep] table)
    own = {command} | ({"cell"} if command == "sweep" else set())
    if any(k in doc for c in own for k in _SCENE_KEYS.get(c, ())):
        return ""
    for other, keys in _SCENE_KEYS.items():
        have = [k for k in keys if k in doc]
        if other not in own and have:
            return f" (this is a scene for `knitsim {other}`: it has {', '.join(have)})"
    return ""


def add_json_flag(parser) -> None:
    """Add the ``--json`` flag every result-printing command has."""
    parser.add_argument("--json", action="store_true", help="print results as JSON (for scripts)")


def print_json(value: Any, stream=None) -> None:
    """Print ``value`` as JSON (NumPy scalars and arrays converted; NaN -> null)."""
    (stream or sys.stdout).write(json_text(value))


class Progress:
    """Progress of a long command on stderr, as a terminal or a log file wants it.

    On a terminal: a tqdm bar (a well-kept library: it redraws in place, smooths the rate and
    shows no estimate before it has one).  Elsewhere (a log file, a pipe, CI): plain lines, one
    per tenth of the work, each with the rate and the time left so far, and no carriage returns.

    Parameters
    ----------
    total : int
        Units of work.
    what : str
        Name of the command and the unit, e.g. ``"knitsim run: increments"``.
    enabled : bool
        False: say nothing.
    stream : file, optional
        Default ``sys.stderr``.
    """

    def __init__(self, total: int, what: str, enabled: bool = True, stream=None):
        import time

        self.stream = stream or sys.stderr
        self.total = max(int(total), 1)
        self.what = what
        self.enabled = enabled
        self.done = 0
        self.t0 = time.perf_counter()
        self._next = 0.1
        self.bar = None
        tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        if enabled and tty:
            from tqdm import tqdm
            prefix, _, unit = what.rpartition(": ")
            self.bar = tqdm(total=self.total, desc=prefix or what, unit=(" " + unit) if unit else "it",
                            file=self.stream, dynamic_ncols=True, leave=True)

    def __call__(self, done: int, total: int | None = None) -> None:
        """Report ``done`` units finished (``total`` accepted for the ``progress(i, n)`` callbacks)."""
        import time

        done = int(done)
        if not self.enabled or done <= self.done:
            return
        if self.bar is not None:
            self.bar.update(done - self.done)
            self.done = done
            if done >= self.total:
                self.bar.close()
            return
        self.done = done
        frac = done / self.total
        if frac + 1e-12 >= self._next or done >= self.total:
            while self._next <= frac + 1e-12:
                self._next += 0.1
            dt = time.perf_counter() - self.t0
            rate = done / dt if dt > 0 else float("inf")
            left = (self.total - done) / rate if rate > 0 else float("nan")
            print(f"{self.what}: {done}/{self.total} ({frac:.0%}), {rate:.3g}/s, about {left:.0f} s left",
                  file=self.stream, flush=True)

    def close(self) -> None:
        """Close the progress bar, if one is shown."""
        if self.bar is not None:
            self.bar.close()


_RST_ROLE = re.compile(r":(?:mod|func|class|data|meth|attr|ref|doc):`~?([^`]+)`")


def plain_help(text: str) -> str:
    """A docstring as ``--help`` text: reStructuredText roles and double back-quotes as plain quotes,
    a literal block's ``::`` as ``:``."""
    text = _RST_ROLE.sub(r"\1", text)
    return text.replace("``", "'").replace("::\n", ":\n")


def program_name() -> str:
    """``knitsim`` as the user typed it: ``.venv/bin/knitsim`` where that is how it was called (the README's
    commands) and ``knitsim`` is not the same program on the PATH; plain ``knitsim`` otherwise (the PATH's,
    a test, the API)."""
    import os
    import shutil
    prog = sys.argv[0] if sys.argv else ""
    if os.path.basename(prog) != "knitsim":
        return "knitsim"
    found = shutil.which("knitsim")
    if found is not None and os.path.realpath(found) == os.path.realpath(prog):
        return "knitsim"
    return prog


def resume_command(command: str, fallback_argv: list[str], extra: list[str] = ()) -> str:
    """The command line that continues an interrupted ``knitsim COMMAND``: as typed (:func:`program_name` and
    ``sys.argv``; where it was not called as ``knitsim COMMAND ...``, a test or the API, ``fallback_argv``),
    without ``--resume`` and ``--overwrite`` (which would discard the finished work, and excludes
    ``--resume``), with ``extra`` and ``--resume`` added."""
    import shlex
    argv = sys.argv[2:] if len(sys.argv) > 2 and sys.argv[1] == command else list(fallback_argv)
    argv = [a for a in argv if a not in ("--resume", "--overwrite")] + list(extra) + ["--resume"]
    return f"{shlex.quote(program_name())} {command} " + " ".join(shlex.quote(a) for a in argv)
