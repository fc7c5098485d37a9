#!/usr/bin/env python3
"""How often a sheet (leaf) passes through a rod (stem, branch, petiole) in an
orbit store. Self-contact keeps triangles apart but sees a rod as a line, so
nothing keeps a leaf off a stem; since rods are drawn as tubes
(`render = { tube = k }`) such a crossing would show. Reads the store with h5py
(independent of the C++ code): /mesh/segments, /mesh/triangles,
/frames/positions.

For every `--step`th frame it counts rod segments crossing a triangle they
share no vertex with (exact segment-triangle test), and the least clearance of
a triangle from a rod's tube (distance from the rod's axis less its radius,
over the triangle's corners, edge midpoints and centroid; triangles touching
the rod's ends, a leaf on its petiole, are left out). Simulated triangles, not
the subdivided ones drawn.

  /usr/bin/python3 bench/leaf_rod_crossings.py <work>/checkpoints/orbits.h5 --step 4 --skip 27:54 \
      --radius 0:100000:0.003 --radius 0:27:0.006
  (scenes/paper/plant_pot.toml: vertices 0..26 are the stem, 6 mm, 27..53 stem_frame, not
  drawn; every other rod is given the branches' 3 mm, which overstates the 2 mm petioles)
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


def samples(x, tri):
    """Points of each triangle: its corners, edge midpoints and centroid (7 per triangle)."""
    c = x[tri]
    mids = (c + np.roll(c, -1, axis=1)) / 2
    return np.concatenate([c, mids, c.mean(axis=1, keepdims=True)], axis=1)  # F x 7 x 3


def clearance(x, seg, radius, tri, far):
    """Least (distance to a rod's axis - its radius) over triangle sample points,
    leaving out triangles joined to the rod: negative means inside a tube."""
    a, b = x[seg[:, 0]], x[seg[:, 1]]
    p = samples(x, tri).reshape(-1, 3)
    d = b - a
    t = np.clip(((p[:, None] - a[None]) * d[None]).sum(2) / (d * d).sum(1)[None], 0, 1)
    dist = np.linalg.norm(p[:, None] - (a[None] + t[..., None] * d[None]), axis=2) - radius[None]
    dist = dist.reshape(len(tri), 7, len(seg)).min(axis=1)
    return float(np.where(far, dist, np.inf).min())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store", help="orbit store (HDF5) written by phasecast-precompute")
    ap.add_argument("--step", type=int, default=10, help="check every STEP-th frame (default 10)")
    ap.add_argument("--skip", default="", help="LO:HI: leave out segments among vertices LO..HI-1 (undrawn rods)")
    ap.add_argument("--radius", action="append", default=[], metavar="LO:HI:R",
                    help="tube radius R (m) of the segments among vertices LO..HI-1; repeatable, later ones win "
                         "(default 0: distance to the axis)")
    args = ap.parse_args()
    with h5py.File(args.store, "r") as f:
        seg = f["mesh/segments"][:].astype(np.int64)
        tri = f["mesh/triangles"][:].astype(np.int64)
        if args.skip:
            lo, hi = (int(v) for v in args.skip.split(":"))
            seg = seg[~((seg >= lo) & (seg < hi)).all(axis=1)]
        unjoined = ~(seg[:, None, :, None] == tri[None, :, None, :]).any(axis=(2, 3))
        radius = np.zeros(len(seg))
        for spec in args.radius:
            lo, hi, r = spec.split(":")
            radius[((seg >= int(lo)) & (seg < int(hi))).all(axis=1)] = float(r)
        # triangles joined to a segment (touching a triangle at one of its ends:
        # a leaf on its petiole) are attachments, not approaches
        touching = [np.unique(tri[np.isin(tri, pair).any(axis=1)]) for pair in seg]
        far = np.stack([~np.isin(tri, t).any(axis=1) for t in touching], axis=1)  # F x S
        positions = f["frames/positions"]
        frames, crossed, worst, nearest = 0, 0, 0, np.inf
        for fr in range(0, positions.shape[0], args.step):
            x = positions[fr].reshape(-1, 3).astype(np.float64)
            k = crossings(x, seg, tri, unjoined)
            frames, crossed, worst = frames + 1, crossed + (k > 0), max(worst, k)
            nearest = min(nearest, clearance(x, seg, radius, tri, far))
    print(f"{args.store}: {frames} frames (every {args.step}th), {len(seg)} rod segments, {len(tri)} triangles: "
          f"{crossed} frames with a rod segment through a triangle (worst {worst} pairs); least clearance of a "
          f"triangle from a rod's tube it is not joined to (distance to the axis - radius; < 0: inside): "
          f"{nearest * 1000:.2f} mm")


if __name__ == "__main__":
    main()
