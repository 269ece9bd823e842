"""The ``--out`` folder policy shared by every command that writes one.

A folder is knitsim's only as far as knitsim wrote into it: every writer records the names it
writes in a hidden record, ``.knitsim-outputs.json``, in the folder (:func:`record_outputs`), before
it writes them.  Then

* an absent or empty folder, or one with only other files (the scene, its map CSVs, a README), is
  used as it is, provided none of those files has a name the command writes;
* a folder where recorded outputs exist "holds results": refused unless ``--resume`` or
  ``--overwrite``; ``--overwrite`` removes the recorded outputs, and only them (never a file the
  command reads: the scene and the files it names);
* a file that knitsim did not write and would write over is refused, ``--overwrite`` or not.

Before, ``--overwrite`` removed every file of a results-like suffix (.csv, .toml, .md, ...) in the
folder, whoever wrote it: a blind probe's ``knitsim run scene.toml --out . --overwrite`` deleted the
scene, its map CSV and its README.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import sys
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import KnitsimInputError

#: the hidden record of what knitsim wrote into an --out folder (names relative to the folder; a name
#: ending in "/" is a sub-folder)
RECORD_NAME = ".knitsim-outputs.json"
#: what knitsim writes inside the sub-folders it records (a sweep's chunks, a study's cases, a patch run's
#: checkpoint rows (knitsim.patch.records); their atomic writes' temporary files start with a dot): anything
#: else there is the user's (a blind probe's note saved in chunks/ went with the folder)
FOLDER_FILES = {"chunks": ("chunk_*.npz", ".chunk_*"), "cases": ("case_*.json", ".case_*"),
                "checkpoint_rows": ("[0-9]*-[0-9]*.npz", ".[0-9]*-[0-9]*.npz.*.tmp")}


def check_output_dir(out_dir: str | Path) -> Path:
    """Refuse an output path that cannot hold the results (before any work).

    The path must be a folder or not exist, and a folder must be creatable there (tried, then
    undone) or, when it exists, writable (a temporary file created and removed): ``os.access`` on
    the parent said yes to ``/proc/nope``, whose folder then failed after the whole solve.
    """
    if not str(out_dir).strip():
        # (an empty --out fell back to the default folder without a word: a blind probe)
        raise KnitsimInputError("--out = '': empty; give a folder (or leave --out out for the default)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise KnitsimInputError(f"--out = {str(out)!r}: exists and is not a directory")
    try:
        if out.is_dir():
            fd, probe = tempfile.mkstemp(prefix=".knitsim-probe-", dir=out)
            os.close(fd)
            os.unlink(probe)
        else:
            made = []
            p = out.absolute()
            while not p.exists():
                made.append(p)
                p = p.parent
            if not p.is_dir():
                raise KnitsimInputError(f"--out = {str(out)!r}: {p} is not a directory")
            for d in reversed(made):
                d.mkdir()
            for d in made:
                d.rmdir()
    except OSError as exc:
        raise KnitsimInputError(f"--out = {str(out)!r}: cannot write there ({exc.strerror or exc})") from None
    return out


#: the lock of an --out folder a command is writing into (:func:`output_lock`)
LOCK_NAME = ".knitsim.lock"


def _pid_runs(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine (signal 0 checks, sends nothing)."""
    if pid <= 0 or os.name == "nt":            # (Windows' os.kill would end the process: assume it runs)
        return pid > 0
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                            # another user's process (EPERM): it runs
        return True
    return True


def _lock_holder(path: Path) -> tuple[int, str, str] | None:
    """(pid, host, command) of a lock file, or None where it cannot be read as one."""
    try:
        pid, host, command = path.read_text().split("\n")[:3]
        return int(pid), host, command
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def _folder_flock(folder: Path) -> Iterator[None]:
    """An exclusive ``flock`` on the folder itself while the lock file is made or taken over: two commands that
    find the same dead holder's lock at the same instant would otherwise both remove it, the later removing the
    earlier's new lock, and both go on.  The kernel releases a flock with its process (no file left behind by a
    crash); where the platform has none (Windows) or the file system refuses it (some network mounts), nothing
    is held and the O_EXCL lock file alone decides, as before."""
    try:
        import fcntl
        fd = os.open(folder, os.O_RDONLY)
    except (ImportError, OSError):
        yield
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            pass
        yield
    finally:
        os.close(fd)                                # (closing releases the flock)


@contextlib.contextmanager
def output_lock(out_dir: str | Path, command: str) -> Iterator[Path]:
    """Hold ``out_dir``'s lock (:data:`LOCK_NAME`) while ``knitsim COMMAND`` writes there; yields the folder.

    Two commands writing into one folder at once write over each other's files (a blind probe's two
    ``knitsim sweep --resume`` on one folder both ran every missing chunk and both wrote the results), so a
    second one is refused, naming the first.  The lock is created with ``O_CREAT | O_EXCL`` (only one process
    can) and holds the holder's pid, host and command; it is removed when the command ends, however it ends,
    except when its process is killed outright (SIGKILL, a crash): a lock of a pid that no longer runs on this
    host is stale, and taken over with a note on stderr (under a ``flock`` of the folder, so that two commands
    taking over one stale lock at once cannot both proceed).  The folder is created if needed, with its missing
    parents (and they are removed again where the command leaves them empty: a refused scene leaves no folders).
    """
    out = check_output_dir(out_dir)
    # the folders this call creates, deepest first (removed again where left empty)
    created = []
    for d in (out, *out.absolute().parents):
        if d.is_dir():
            break
        created.append(d)
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_NAME
    host = socket.gethostname()
    mine = f"{os.getpid()}\n{host}\nknitsim {command}\n"
    with _folder_flock(out):
        for attempt in range(2):
            try:
                fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = _lock_holder(path)
                if holder is not None and holder[1] == host and not _pid_runs(holder[0]) and attempt == 0:
                    print(f"knitsim {command}: note: {path} is the lock of {holder[2]} (pid {holder[0]}), which no "
                          "longer runs (killed or crashed): taking it over", file=sys.stderr, flush=True)
                    if _lock_holder(path) == holder:      # not meanwhile taken over by another command
                        path.unlink(missing_ok=True)
                    continue
                who = ("another knitsim command (the lock file cannot be read)" if holder is None else
                       f"{holder[2]} (pid {holder[0]}{'' if holder[1] == host else f' on {holder[1]}'})")
                raise KnitsimInputError(
                    f"--out = {str(out_dir)!r}: {who} is writing into this folder (lock {path}); two commands at "
                    "once would write over each other's files: wait for it to finish, or choose another --out (if "
                    f"no such command runs, remove {path})") from None
            with os.fdopen(fd, "w") as f:
                f.write(mine)
            break
    try:
        yield out
    finally:
        with contextlib.suppress(OSError):
            if path.read_text() == mine:         # (still this command's: never another's)
                path.unlink()
        for d in created:
            try:
                d.rmdir()
            except OSError:                     # (not empty: it holds the command's outputs)
                break


def recorded_outputs(out_dir: str | Path) -> list[str]:
    """The names knitsim recorded as written into ``out_dir`` (empty without a record)."""
    path = Path(out_dir) / RECORD_NAME
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return []
    names = doc.get("outputs") if isinstance(doc, dict) else None
    return [n for n in names if isinstance(n, str) and _plain_name(n)] if isinstance(names, list) else []


def _plain_name(name: str) -> bool:
    """A name inside the folder (a record edited to name ``../x`` or ``/etc`` must not be removed)."""
    n = name.rstrip("/")
    return bool(n) and n not in (".", "..") and "/" not in n and "\\" not in n


def _stamps(out: Path) -> dict:
    try:
        doc = json.loads((out / RECORD_NAME).read_text())
    except (OSError, ValueError):
        return {}
    st = doc.get("stamps") if isinstance(doc, dict) else None
    return {k: v for k, v in st.items() if isinstance(v, list) and len(v) == 2} if isinstance(st, dict) else {}


def _stamp_of(p: Path) -> list:
    st = p.stat()
    return [int(st.st_size), int(st.st_mtime_ns)]


def _write_record(out: Path, names: list, stamps: dict) -> Path:
    from .. import __version__
    doc = {"written_by": f"knitsim {__version__}",
           "note": "the files knitsim wrote here; --overwrite removes these and nothing else",
           "outputs": names, "stamps": stamps}
    fd, tmp = tempfile.mkstemp(prefix=".knitsim-outputs-", dir=out)
    with os.fdopen(fd, "w") as fh:
        fh.write(json.dumps(doc, indent=1) + "\n")
    from .results import umask_mode
    os.chmod(tmp, umask_mode())           # as the outputs beside it (mkstemp's 0600 hid it from the group)
    os.replace(tmp, out / RECORD_NAME)
    return out / RECORD_NAME


def record_outputs(out_dir: str | Path, names: Iterable[str]) -> Path:
    """Add ``names`` (files, or sub-folders written with a trailing ``/``) to ``out_dir``'s record.

    Called by every writer before it writes, so that an interrupted write is still knitsim's to
    replace.  Creates the folder.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    have = recorded_outputs(out)
    new = [n for n in names if n not in have]
    if not new and (out / RECORD_NAME).is_file():
        return out / RECORD_NAME
    return _write_record(out, have + new, _stamps(out))


def stamp_outputs(out_dir: str | Path, names: Iterable[str]) -> None:
    """Note the size and modification time of files just written (recorded): ``--overwrite`` then refuses
    to delete one changed since (a blind probe's hand-edited ``materials.toml`` was deleted without a word)."""
    out = Path(out_dir)
    stamps = _stamps(out)
    for n in names:
        p = out / n
        if p.is_file():
            stamps[n] = _stamp_of(p)
    _write_record(out, recorded_outputs(out), stamps)


def edited_outputs(out_dir: str | Path) -> list[str]:
    """Recorded outputs whose size or modification time differ from the stamp taken when written."""
    out = Path(out_dir)
    edited = []
    for n, stamp in _stamps(out).items():
        p = out / n
        if _plain_name(n) and p.is_file() and _stamp_of(p) != list(stamp):
            edited.append(n)
    return edited


def scene_inputs(scene_path: str | Path | None) -> list[Path]:
    """The files a scene reads: the scene itself and every existing file one of its strings names
    (relative to the scene's folder, as the loaders resolve them: material libraries, maps, data)."""
    if scene_path is None:
        return []
    scene = Path(scene_path)
    found = [scene]
    try:
        from ..scene.schema import load_toml
        doc = load_toml(scene)
    except (KnitsimInputError, OSError):
        return found

    def walk(v):
        if isinstance(v, dict):
            for x in v.values():
                yield from walk(x)
        elif isinstance(v, list):
            for x in v:
                yield from walk(x)
        elif isinstance(v, str) and 0 < len(v) < 4096:
            yield v

    for s in walk(doc):
        for base in (scene.parent, Path.cwd()):
            try:
                p = (base / s) if not Path(s).is_absolute() else Path(s)
                if p.is_file():
                    found.append(p)
            except (OSError, ValueError):
                pass
    return found


def _foreign_in_folders(out: Path, recorded: list[str]) -> list[str]:
    """Entries of the recorded sub-folders that knitsim does not write there (:data:`FOLDER_FILES`)."""
    import fnmatch
    found = []
    for name in recorded:
        d = out / name.rstrip("/")
        pats = FOLDER_FILES.get(name.rstrip("/"))
        if pats is None or not d.is_dir() or d.is_symlink():
            continue
        found += [f"{d.name}/{p.name}" for p in sorted(d.iterdir())
                  if not (p.is_file() and any(fnmatch.fnmatch(p.name, pat) for pat in pats))]
    return found


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def prepare_output_dir(out_dir: str | Path, overwrite: bool = False, resume: bool = False,
                       resumable: bool | str = False, writes: Iterable[str] = (),
                       inputs: Iterable[str | Path] = ()) -> Path:
    """The one policy of every command that writes into ``--out``, applied before any work.

    Parameters
    ----------
    out_dir : path
        The folder.
    overwrite, resume : bool
        The command's flags.  ``resume``: the caller then checks that there is something to resume.
    resumable : bool or str
        The command can resume (said in the refusal); a name: it can resume a folder that holds that file (its
        manifest), so that a folder of another command's results is not offered a ``--resume`` that then fails.
    writes : iterable of str
        The names the command writes (sub-folders with a trailing ``/``): one of them present but
        not recorded as knitsim's is a user's file, refused, ``--overwrite`` or not.
    inputs : iterable of path
        Files the command reads (:func:`scene_inputs`): ``--overwrite`` never removes them, even
        where an earlier command wrote them (a calibration's ``materials.toml`` read by a run).
    """
    out = check_output_dir(out_dir)
    if not out.is_dir():
        return out
    recorded = [n for n in recorded_outputs(out) if (out / n.rstrip("/")).exists()]
    if recorded and not resume:
        if not overwrite:
            shown = ", ".join(n.rstrip("/") for n in recorded[:4]) + (", ..." if len(recorded) > 4 else "")
            can = (out / resumable).exists() if isinstance(resumable, str) else bool(resumable)
            hint = " or --resume to continue it" if can else ""
            raise KnitsimInputError(f"--out = {str(out)!r}: already holds results ({shown}); add --overwrite to "
                                    f"replace them{hint}, or choose another --out (--overwrite removes only the "
                                    "files knitsim wrote there)")
        edited = edited_outputs(out) + _foreign_in_folders(out, recorded)
        if edited:
            raise KnitsimInputError(
                f"--out = {str(out)!r}: {', '.join(edited)} changed since knitsim wrote "
                f"{'it' if len(edited) == 1 else 'them'} (edited or added by hand?): --overwrite would delete "
                f"{'it' if len(edited) == 1 else 'them'}; move {'it' if len(edited) == 1 else 'them'} elsewhere "
                "first, or choose another --out")
        keep = [Path(p) for p in inputs]
        for name in recorded:
            p = out / name.rstrip("/")
            if any(_same_file(p, k) for k in keep):
                continue
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink(missing_ok=True)
    mine = set(recorded_outputs(out))
    foreign = [n.rstrip("/") for n in writes if n not in mine and (out / n.rstrip("/")).exists()]
    # --resume too: it writes the same names at its end (a blind probe's calibrate --resume replaced its own
    # materials.toml, put beside the interrupted run's checkpoint)
    if foreign:
        raise KnitsimInputError(
            f"--out = {str(out)!r}: holds {', '.join(foreign)}, which knitsim did not write there (no record of it "
            f"in {RECORD_NAME}) and would write over: move {'it' if len(foreign) == 1 else 'them'} or choose "
            "another --out")
    return out


def prepare_output_file(path: str | Path | None, overwrite: bool = False, flag: str = "--out",
                        suffix: str | None = None) -> Path | None:
    """The same policy for a command's single output file: an existing one is refused unless ``overwrite``; with
    ``suffix`` (``".png"``) one of another suffix is refused, before the work (a probe's ``dahl fit --png fit.txt``
    ended, after the fit, in matplotlib's traceback "Format 'txt' is not supported")."""
    if path is None:
        return None
    p = Path(path)
    if suffix is not None and p.suffix.lower() != suffix:
        raise KnitsimInputError(f"{flag} = {str(path)!r}: expected a {suffix} file")
    if p.is_dir():
        raise KnitsimInputError(f"{flag} = {str(p)!r}: is a folder")
    if p.exists() and not overwrite:
        raise KnitsimInputError(f"{flag} = {str(p)!r}: exists; add --overwrite to replace it")
    check_file_can_be_created(p, f"{flag} = {str(p)!r}")
    return p


def check_file_can_be_created(path: str | Path, where: str) -> None:
    """Refuse, as ``where: cannot be written: ...``, a file path whose nearest existing folder takes no new file
    (the missing folders below it are created when the file is written): the folder is probed by creating and
    removing a file in it.  ``os.access`` passed a parent that is a file (``afile/x.png``) and ``/proc`` (root may
    "write" there, nothing can be created), and the file failed as a traceback after the work (a blind probe's
    ``knitsim usd --quicklook afile/x.png``, after the USD was written; diagnose's --json, after its fits)."""
    probe = Path(os.path.abspath(path)).parent
    while not os.path.lexists(probe) and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise KnitsimInputError(f"{where}: cannot be written: {probe} is a file, not a folder")
    try:
        fd, name = tempfile.mkstemp(prefix=".knitsim-probe-", dir=probe)
        os.close(fd)
        os.remove(name)
    except OSError as exc:
        raise KnitsimInputError(f"{where}: cannot be written: no file can be created in {probe} "
                                f"({exc.strerror or exc})") from None


def add_output_flags(parser, resumable: bool = False, what: str = "results") -> None:
    """``--overwrite`` (and ``--resume``) with the policy of :func:`prepare_output_dir` in their help."""
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace the {what} of an existing --out: the files an earlier knitsim command "
                             f"wrote there (recorded in {RECORD_NAME}) are removed first, nothing else; without "
                             "it an --out that holds results is refused"
                             + (", unless --resume" if resumable else "")
                             + "; a file named by an option (--usd FILE) is replaced where it exists")
