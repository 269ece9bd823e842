"""Export time and file size of knit patches as USD (not a test).

Cases: a 23 x 110 patch over 300 frames (both orientations: 110 courses of 23
wales and 23 courses of 110 wales), and a 10^5-cell patch (250 courses x 400
wales) over a few frames.  Quarter centrelines come from a stand-in (straight
leg + circular arc, as in tests/usd/test_yarn_geometry.py), scaled per cell so
that W varies across the patch; the patch stretches along y over the frames.
Prints a table.

Run:  MPLBACKEND=Agg python benchmarks/bench_usd_export.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from knitsim.usd import read_patch_usd, render_quicklook, write_patch_usd


def standin_quarter(W, Y_C, alpha, n):
    """Straight leg from A = (W/4, 0) at angle alpha + circular arc to (0, Y_C)."""
    a = alpha
    l, r = np.linalg.solve([[np.cos(a), -np.sin(a)], [np.sin(a), 1 + np.cos(a)]], [-W / 4, Y_C])
    s = np.linspace(0.0, l + r * (np.pi - a), n)
    A = np.array([W / 4, 0.0])
    centre = A + l * np.array([np.cos(a), np.sin(a)]) + r * np.array([-np.sin(a), np.cos(a)])
    th = a + np.clip(s - l, 0.0, None) / r
    return np.where((s <= l)[:, None], A + s[:, None] * np.array([np.cos(a), np.sin(a)]),
                    centre + r * np.stack([np.sin(th), -np.cos(th)], axis=1))


def make_frames(courses, wales, n_frames, n, seed=0):
    """Stacked frames: each cell's quarter is the frame's base quarter scaled by W/W_base."""
    rng = np.random.default_rng(seed)
    lam = 1.0 + 0.05 * rng.random((courses, wales))
    qs, Ws, Cs, st, phi, F = [], [], [], [], [], []
    for f in range(n_frames):
        e = 0.6 * f / max(n_frames - 1, 1)                # change in length along y, 0 .. 60 %
        Wb, Cb = 4.0 * (1 - 0.3 * e), 2.8 * (1 + e)
        base = standin_quarter(Wb, 0.7 * Cb + 1.0, 1.3 - 0.4 * e, n)
        qs.append((lam[..., None, None] * base).astype(np.float64))
        Ws.append(lam * Wb)
        Cs.append(np.full((courses, wales), Cb))
        st.append(np.full((courses, wales), min(int(4 * e / 0.6), 3), dtype=np.int32))
        phi.append(np.full((courses, wales), 0.3 * e))
        F.append(np.full((courses, wales), 5.0 * e))
    return {"quarter_xy": np.stack(qs), "W": np.stack(Ws), "C": np.stack(Cs),
            "time": np.arange(n_frames) * 0.1,
            "fields": {"stage": np.stack(st), "phi": np.stack(phi), "F": np.stack(F)}}


def run_case(label, courses, wales, n_frames, n, ppq, tmp, ext=".usdc", stride=1, quicklook=False):
    frames = make_frames(courses, wales, n_frames, n)
    path = os.path.join(tmp, f"bench{ext}")
    res = write_patch_usd(path, frames, 0.6, material_id=0, color_by="stage", stride=stride,
                          scene_text="# bench", points_per_quarter=ppq)
    t0 = time.perf_counter()
    back = read_patch_usd(path)
    t_read = time.perf_counter() - t0
    t_ql = float("nan")
    if quicklook:
        t0 = time.perf_counter()
        render_quicklook(path, os.path.join(tmp, "bench.png"), dpi=80)
        t_ql = time.perf_counter() - t0
    verts = courses * res.vertices_per_course
    row = (label, f"{courses}x{wales}", len(res.time_codes), res.points_per_quarter, verts,
           res.file_bytes / 2**20, res.seconds, t_read, t_ql,
           res.file_bytes / (verts * len(res.time_codes)))
    assert back.points.shape[0] == len(res.time_codes)
    os.remove(path)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames, for a smoke run")
    ap.add_argument("--n", type=int, default=9, help="points per quarter given by the 'simulator'")
    args = ap.parse_args()
    nf = 30 if args.quick else 300
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(run_case("110 courses x 23 wales", 110, 23, nf, args.n, None, tmp, quicklook=True))
        rows.append(run_case("23 courses x 110 wales", 23, 110, nf, args.n, None, tmp))
        rows.append(run_case("110x23, 6 pts/quarter", 110, 23, nf, args.n, 6, tmp))
        rows.append(run_case("110x23, stride 10", 110, 23, nf, args.n, None, tmp, stride=10))
        rows.append(run_case("110x23 .usda, stride 10", 110, 23, nf, args.n, None, tmp, ext=".usda", stride=10))
        rows.append(run_case("1e5 cells", 250, 400, 3, args.n, None, tmp, quicklook=not args.quick))
        rows.append(run_case("1e5 cells, 6 pts/quarter", 250, 400, 3, args.n, 6, tmp))
    hdr = ("case", "courses x wales", "frames", "pts/qtr", "vertices/frame", "file MiB", "write s", "read s",
           "quicklook s", "B/vertex/frame")
    print(" | ".join(hdr))
    print(" | ".join("---" for _ in hdr))
    for r in rows:
        print(f"{r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} | {r[5]:.1f} | {r[6]:.2f} | {r[7]:.2f} | "
              f"{r[8]:.2f} | {r[9]:.1f}")


if __name__ == "__main__":
    main()
