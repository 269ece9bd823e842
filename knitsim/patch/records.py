"""A patch run's per-increment records, and the chunk files that keep them in its checkpoint.

:class:`RunRecords` holds the rows of :func:`knitsim.patch.runner.run_patch`, one array per key of shape
``[n_increments, ...]``, row ``i`` written in place: the history is built from these arrays as they are (before,
lists of per-increment arrays were stacked at the end by ``np.asarray``, a second full copy of the records).

A checkpoint keeps the rows beside its pickle, in the folder :func:`rows_dir_of` (``OUT/checkpoint_rows`` for
``OUT/checkpoint.pkl``), one NumPy archive per checkpoint interval, ``START-STOP.npz`` with rows
``START .. STOP - 1`` of every key and ``_meta`` (the run's fingerprint and the range), written once, through a
temporary sibling and a rename (:func:`write_chunk`).  The checkpoint's header lists the chunks with their
ranges, sizes and the archive's CRC-32 of every member (:func:`chunk_problem`, :func:`read_chunks` check them).
Before, every checkpoint pickled every finished row again: a 300 x 300 random patch's 7 saves took 31 s (4.4 s
each, the pickle reaching 2.5 GB), a sixth of its run, on a GPU host.
"""
from __future__ import annotations

import json
import os
import re
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..errors import KnitsimInputError

#: a chunk's file name: its first row and the row after its last (:func:`chunk_name`)
CHUNK_RE = re.compile(r"^(\d{6,})-(\d{6,})\.npz$")
#: what a chunk's ``_meta`` says it is (a foreign ``.npz`` lacks it)
CHUNK_KIND = "knitsim patch checkpoint rows"


def rows_dir_of(ck: str | Path) -> Path:
    """The folder of the chunks of the checkpoint ``ck``: ``STEM_rows`` beside it (``checkpoint_rows``)."""
    ck = Path(ck)
    return ck.with_name(f"{ck.stem}_rows")


def chunk_name(start: int, stop: int) -> str:
    """File name of the chunk of rows ``start .. stop - 1``: ``000050-000100.npz``."""
    return f"{int(start):06d}-{int(stop):06d}.npz"


class RunRecords:
    """The per-increment rows of a run: one array per key, shape ``[n_increments, ...]``, filled in place.

    Parameters
    ----------
    n : int
        Rows (the program's increments).

    Notes
    -----
    A key's array is allocated at its first row, with that row's shape and dtype, by ``np.empty`` (the
    operating system commits its pages as the rows are written).  A later row of a wider dtype promotes the
    array (``np.result_type``), so the arrays are those ``np.asarray`` made of the list of rows.
    """

    def __init__(self, n: int):
        self.n = int(n)
        self.arrays: dict[str, np.ndarray] = {}

    def put(self, i: int, key: str, value) -> None:
        """Row ``i`` of ``key``."""
        a = self.arrays.get(key)
        v = np.asarray(value)
        if a is None:
            a = self.arrays[key] = np.empty((self.n,) + v.shape, dtype=v.dtype)
        elif v.dtype != a.dtype and np.result_type(a.dtype, v.dtype) != a.dtype:
            a = self.arrays[key] = a.astype(np.result_type(a.dtype, v.dtype))
        a[i] = v

    def put_rows(self, start: int, key: str, block: np.ndarray) -> None:
        """Rows ``start .. start + len(block) - 1`` of ``key`` (a chunk read back, or an older checkpoint's)."""
        block = np.asarray(block)
        a = self.arrays.get(key)
        if a is None:
            a = self.arrays[key] = np.empty((self.n,) + block.shape[1:], dtype=block.dtype)
        elif a.shape[1:] != block.shape[1:] or a.dtype != block.dtype:
            raise ValueError(f"{key}: rows of shape {block.shape[1:]} and dtype {block.dtype}, expected "
                             f"{a.shape[1:]} and {a.dtype}")
        a[start:start + len(block)] = block

    def drop(self, keys) -> None:
        """Forget ``keys`` (not recorded any further)."""
        for k in keys:
            self.arrays.pop(k, None)


def write_chunk(folder: Path, records: RunRecords, start: int, stop: int, fingerprint: str | None) -> dict:
    """Write rows ``start .. stop - 1`` of every key of ``records`` into ``folder`` (:func:`chunk_name`), atomically.

    The archive is written straight from the arrays (``np.savez``, uncompressed: no copy of the rows) to a
    temporary sibling, renamed in when complete.

    Returns
    -------
    dict
        The chunk's entry in the checkpoint's header: ``name``, ``start``, ``stop``, ``bytes`` (its size) and
        ``crc32`` (each member's CRC-32, as the archive records it).
    """
    from ..io.results import umask_mode
    name = chunk_name(start, stop)
    path = folder / name
    folder.mkdir(parents=True, exist_ok=True)
    meta = json.dumps({"kind": CHUNK_KIND, "fingerprint": fingerprint, "start": int(start), "stop": int(stop)})
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, _meta=np.array(meta), **{k: a[start:stop] for k, a in records.arrays.items()})
        os.chmod(tmp, umask_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    with zipfile.ZipFile(path) as z:
        crc = {i.filename: i.CRC for i in z.infolist()}
    return {"name": name, "start": int(start), "stop": int(stop), "bytes": path.stat().st_size, "crc32": crc}


def _way_out(ck: Path) -> str:
    return (f"the rows of the checkpoint {ck} are lost: run again without --resume (--overwrite, or another "
            "--out)")


def chunk_problem(ck: Path, chunks: list, done: int) -> str:
    """Why the chunk files that the checkpoint ``ck`` lists (its header's ``chunks``) cannot give its rows
    ``0 .. done - 1``, from their names, ranges and sizes alone (nothing read); ``""`` where nothing is wrong.

    The chunks must cover the rows exactly, one after the other; each file must exist with the size it was
    written with (one cut short, or replaced, is refused, naming it)."""
    folder = rows_dir_of(ck)
    at = 0
    for c in chunks:
        name = str(c.get("name", ""))
        if not CHUNK_RE.match(name) or int(c.get("start", -1)) != at or int(c.get("stop", -1)) <= at:
            return (f"--resume: {ck} lists a chunk {name!r} of rows {c.get('start')}..{c.get('stop')} where rows "
                    f"from {at} follow: not a checkpoint knitsim wrote; {_way_out(ck)}")
        path = folder / name
        if not path.is_file():
            held = f"increment {at + 1}" if int(c["stop"]) == at + 1 else f"increments {at + 1}..{c['stop']}"
            return f"--resume: {path} is missing: it holds {held} of the checkpoint {ck}; {_way_out(ck)}"
        size = path.stat().st_size
        if size != int(c.get("bytes", -1)):
            return (f"--resume: {path} holds {size} bytes, the checkpoint {ck} wrote {c.get('bytes')}: truncated or "
                    f"replaced since; {_way_out(ck)}")
        at = int(c["stop"])
    if at != done:
        return (f"--resume: {ck} holds {done} increments but its chunks in {folder} cover {at}; "
                f"{_way_out(ck)}")
    return ""


def read_chunks(ck: Path, chunks: list, done: int, fingerprint: str | None, records: RunRecords) -> None:
    """Fill rows ``0 .. done - 1`` of ``records`` from the chunk files of the checkpoint ``ck``.

    Raises
    ------
    KnitsimInputError
        Naming the file: a chunk missing, of another size than written (:func:`chunk_problem`), not a readable
        archive or one whose data fails its CRC-32, of another run (its fingerprint) or rows, or whose members
        differ from what the checkpoint recorded.
    """
    why = chunk_problem(ck, chunks, done)
    if why:
        raise KnitsimInputError(why)
    folder = rows_dir_of(ck)
    keys = None
    for c in chunks:
        path = folder / c["name"]
        try:
            with np.load(path, allow_pickle=False) as z:
                if keys is None:
                    keys = set(z.files)
                elif set(z.files) != keys:
                    # (every chunk of a run holds the same keys: a row left unwritten would be garbage)
                    raise KnitsimInputError(f"--resume: {path} holds other rows than the chunks before it "
                                            f"({', '.join(sorted(set(z.files) ^ keys))}); {_way_out(ck)}")
                crc = {i.filename: i.CRC for i in z.zip.infolist()}
                meta = json.loads(str(z["_meta"]))
                if meta.get("kind") != CHUNK_KIND or meta.get("fingerprint") != fingerprint:
                    raise KnitsimInputError(f"--resume: {path} is not a chunk of the checkpoint {ck} (it belongs "
                                            f"to another run); {_way_out(ck)}")
                if (meta.get("start"), meta.get("stop")) != (c["start"], c["stop"]) or crc != c.get("crc32"):
                    raise KnitsimInputError(f"--resume: {path} is not the chunk the checkpoint {ck} wrote (other "
                                            f"rows or contents); {_way_out(ck)}")
                for k in z.files:
                    if k != "_meta":
                        block = z[k]
                        if len(block) != c["stop"] - c["start"]:
                            raise ValueError(f"{k}: {len(block)} rows")
                        records.put_rows(c["start"], k, block)
        except KnitsimInputError:
            raise
        except Exception as exc:  # noqa: BLE001 - zipfile.BadZipFile (a bad CRC-32), OSError, ValueError, ...
            raise KnitsimInputError(f"--resume: {path} is not a readable chunk of the checkpoint {ck} ({exc}); "
                                    f"{_way_out(ck)}") from None


def remove_stray_chunks(ck: Path, chunks: list) -> None:
    """Remove the chunk files beside the checkpoint ``ck`` that its header does not list (written by a run
    killed before its checkpoint named them; a resume writes its own)."""
    folder = rows_dir_of(ck)
    listed = {c["name"] for c in chunks}
    try:
        entries = list(folder.iterdir())
    except OSError:
        return
    for p in entries:
        if CHUNK_RE.match(p.name) and p.name not in listed:
            p.unlink(missing_ok=True)


def remove_rows_dir(ck: Path) -> None:
    """Remove the chunk files of the checkpoint ``ck`` (and their temporary files), and their folder where that
    leaves it empty (a file of another name is left there, the folder with it)."""
    folder = rows_dir_of(ck)
    try:
        entries = list(folder.iterdir())
    except OSError:
        return
    for p in entries:
        if CHUNK_RE.match(p.name) or (p.name.startswith(".") and p.name.endswith(".tmp")
                                      and CHUNK_RE.match(p.name[1:].rsplit(".", 2)[0])):
            p.unlink(missing_ok=True)
    try:
        folder.rmdir()
    except OSError:
        pass
