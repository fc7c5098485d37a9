#!/usr/bin/env python3
"""How often a sheet (leaf) passes through a rod (stem, branch, petiole) in an
orbit store. Self-contact keeps triangles apart but sees a rod as a line, so
nothing keeps a leaf off a stem; since rods are drawn as tubes
(`render = { tube = k }`) such a crossing would show. Reads the store with h5py
(independent of the C++ code): /mesh/segments, /mesh/triangles,
/frames/positions.

For every `--step`th frame it counts rod segments crossing a triangle they
share no vertex with (exact segment-triangle test), and the closest approach of
a triangle vertex to a rod segment that no triangle joins it to.

  /usr/bin/python3 bench/leaf_rod_crossings.py <work>/checkpoints/orbits.h5 --step 4 --skip 27:54
  (scenes/paper/plant_pot.toml: vertices 27..53 are stem_frame, which is not drawn)
"""
import argparse

import h5py
import numpy as np


def crossings(x, seg, tri, unjoined):
    """Rod segments through triangles (pairs sharing no vertex) in one frame."""
    a, b = x[seg[:, 0]], x[seg[:, 1]]
    t0, t1, t2 = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    smin, smax = np.minimum(a, b), np.maximum(a, b)
    tmin, tmax = np.minimum(np.minimum(t0, t1), t2), np.maximum(np.maximum(t0, t1), t2)
    overlap = ((smin[:, None] <= tmax[None]) & (smax[:, None] >= tmin[None])).all(axis=2) & unjoined
    i, j = np.nonzero(overlap)
    if len(i) == 0:
        return 0
    d, e1, e2, s = b[i] - a[i], t1[j] - t0[j], t2[j] - t0[j], a[i] - t0[j]  # Moller-Trumbore
    h = np.cross(d, e2)
    det = (e1 * h).sum(1)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
    q = np.cross(s, e1)
    u, v, t = (s * h).sum(1) * inv, (d * q).sum(1) * inv, (e2 * q).sum(1) * inv
    return int((ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)).sum())


def closest(x, seg, verts, far):
    """Least distance from a triangle vertex to a segment no triangle joins it to."""
    a, b, p = x[seg[:, 0]], x[seg[:, 1]], x[verts]
    d = b - a
    t = np.clip(((p[:, None] - a[None]) * d[None]).sum(2) / (d * d).sum(1)[None], 0, 1)
    dist = np.linalg.norm(p[:, None] - (a[None] + t[..., None] * d[None]), axis=2)
    return float(np.where(far, dist, np.inf).min())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store", help="orbit store (HDF5) written by phasecast-precompute")
    ap.add_argument("--step", type=int, default=10, help="check every STEP-th frame (default 10)")
    ap.add_argument("--skip", default="", help="LO:HI: leave out segments among vertices LO..HI-1 (undrawn rods)")
    args = ap.parse_args()
    with h5py.File(args.store, "r") as f:
        seg = f["mesh/segments"][:].astype(np.int64)
        tri = f["mesh/triangles"][:].astype(np.int64)
        if args.skip:
            lo, hi = (int(v) for v in args.skip.split(":"))
            seg = seg[~((seg >= lo) & (seg < hi)).all(axis=1)]
        unjoined = ~(seg[:, None, :, None] == tri[None, :, None, :]).any(axis=(2, 3))
        verts = np.unique(tri)
        # vertex-segment pairs joined by a triangle (a leaf on its petiole) are attachments
        joined = np.zeros((len(verts), len(seg)), dtype=bool)
        for k, pair in enumerate(seg):
            touching = np.unique(tri[np.isin(tri, pair).any(axis=1)])
            joined[np.isin(verts, touching), k] = True
        positions = f["frames/positions"]
        frames, crossed, worst, nearest = 0, 0, 0, np.inf
        for fr in range(0, positions.shape[0], args.step):
            x = positions[fr].reshape(-1, 3).astype(np.float64)
            k = crossings(x, seg, tri, unjoined)
            frames, crossed, worst = frames + 1, crossed + (k > 0), max(worst, k)
            nearest = min(nearest, closest(x, seg, verts, ~joined))
    print(f"{args.store}: {frames} frames (every {args.step}th), {len(seg)} rod segments, {len(tri)} triangles: "
          f"{crossed} frames with a rod segment through a triangle (worst {worst} pairs); closest triangle vertex "
          f"to a rod it is not joined to: {nearest * 1000:.2f} mm")


if __name__ == "__main__":
    main()
