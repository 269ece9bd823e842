"""Time of a patch run's checkpoint saves, and of a resume's read of its rows, for a patch of ``--groups``
distinct cells through ``--increments`` increments, saved every ``--every``: the rows since the last save
written as one chunk file (knitsim.patch.records, what run_patch does) against every row so far pickled at
every save (``--pickled``: what it did before).  Synthetic rows of the run's keys, shapes and dtypes; the
solver's state, the same in both, is left out.  Not a test.

    python benchmarks/bench_checkpoint_saves.py --groups 90000 --increments 310 --every 50 [--pickled]

Measured on the 2-core CPU dev box, shared (a 300 x 300 random patch's records, 2.5 GB): pickled, 7 saves
took 44.7 and 53.0 s (the last pickle 2.51 GB; peak RSS 7.5 GB); chunks, 1.6 to 7.4 s over four runs (the
disk's write-back; 0.405 GB a chunk; peak RSS 2.6 GB), and a resume read the rows back in 0.9 to 1.1 s.
"""
from __future__ import annotations

import argparse
import pickle
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from knitsim.io.results import atomic_write_bytes
from knitsim.patch.records import RunRecords, read_chunks, write_chunk


def _row(rng, groups: int, wales: int) -> dict:
    f = rng.random
    return {"force_N": float(f()), "force_per_wale_N": float(f()), "column_force_N": f(wales),
            "column_status": np.zeros(wales, np.int64), "column_iterations": np.ones(wales, np.int64),
            "column_slack_mm": f(wales), "g_C": f(groups), "g_F": f(groups), "g_phi": f(groups),
            "g_label": np.zeros(groups, np.int8), "g_status": np.zeros(groups, np.int8), "g_x": f((groups, 5)),
            "g_W": f(groups), "g_s_AB": f(groups), "g_head_gap": f(groups)}


def _peak_rss() -> str:
    try:
        return next(line.split(":")[1].strip() for line in open("/proc/self/status") if line.startswith("VmHWM"))
    except (OSError, StopIteration):
        return "?"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--groups", type=int, default=90_000)
    ap.add_argument("--increments", type=int, default=310)
    ap.add_argument("--every", type=int, default=50)
    ap.add_argument("--wales", type=int, default=300)
    ap.add_argument("--pickled", action="store_true", help="every row so far pickled at every save (before)")
    a = ap.parse_args(argv)
    one = _row(np.random.default_rng(0), a.groups, a.wales)
    saves = list(range(a.every, a.increments, a.every)) + [a.increments]
    folder = Path(tempfile.mkdtemp(prefix="knitsim-bench-ck-"))
    ck = folder / "checkpoint.pkl"
    total = 0.0
    try:
        rows = {k: [] for k in one} if a.pickled else RunRecords(a.increments)
        done, chunks = 0, []
        for s in saves:
            for i in range(done, s):
                for k, v in one.items():
                    if a.pickled:
                        rows[k].append(v.copy() if isinstance(v, np.ndarray) else v)
                    else:
                        rows.put(i, k, v)
            t0 = time.perf_counter()
            if a.pickled:
                atomic_write_bytes(ck, pickle.dumps({"done": s}) + pickle.dumps({"rows": rows},
                                                                                 protocol=pickle.HIGHEST_PROTOCOL))
                size = ck.stat().st_size
            else:
                chunks.append(write_chunk(folder / "checkpoint_rows", rows, done, s, "f" * 64))
                atomic_write_bytes(ck, pickle.dumps({"done": s, "chunks": chunks}))
                size = chunks[-1]["bytes"]
            dt = time.perf_counter() - t0
            total += dt
            print(f"save at {s}: {dt:.2f} s, {size / 1e9:.3f} GB written", flush=True)
            done = s
        print(f"{'pickled' if a.pickled else 'chunks'}: {len(saves)} saves, {total:.1f} s in all; peak RSS "
              f"{_peak_rss()}")
        if not a.pickled:
            del rows
            t0 = time.perf_counter()
            back = RunRecords(a.increments)
            read_chunks(ck, chunks, a.increments, "f" * 64, back)
            print(f"resume: the rows read back in {time.perf_counter() - t0:.1f} s")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
