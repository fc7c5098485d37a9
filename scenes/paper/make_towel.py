#!/usr/bin/env python3
"""Writes scenes/paper/meshes/towel.obj: the paper-scale cloth of Table 1
(3 332 vertices, 6 402 triangles; the paper's has 3 310 / 6 365), a towel
folded over a rail on the door so that its two layers hang 6 mm apart, closer
than twice the contact thickness: the cloth is in persistent self-contact, and
the air of an opening door presses the front layer onto the back one (Fig. 8).

The towel is a grid of WIDTH_CELLS x LENGTH_CELLS cells laid along a path in
the door's (y, z) plane: up the front layer, over a half circle around the
rail, down the back layer. Cells alternate their diagonal so the sheet has no
preferred shear direction. Units are metres, in the door's frame (front face
z = 0, hinge x = z = 0).

Run:  python3 scenes/paper/make_towel.py > scenes/paper/meshes/towel.obj
"""
import math

WIDTH_CELLS, LENGTH_CELLS = 33, 97
X0, X1 = 0.2, 0.7          # towel width along the door
RAIL_Y, RAIL_Z = 1.85, 0.03  # rail centre line (the fold's axis)
FOLD_RADIUS = 0.008        # half circle over the rail
GAP = 0.006                # between the hanging layers (thickness 4 mm: < 2x)
NECK = 0.04                # length over which each layer closes from the fold to GAP
FRONT, BACK = 0.72, 0.62   # hanging length of each layer below the rail


def path():
    """Polyline (y, z) from the front layer's hem over the rail to the back hem."""
    front = [(RAIL_Y - FRONT, RAIL_Z + GAP / 2), (RAIL_Y - NECK, RAIL_Z + GAP / 2)]
    arc = [(RAIL_Y + FOLD_RADIUS * math.sin(a), RAIL_Z + FOLD_RADIUS * math.cos(a))
           for a in (math.pi * k / 16 for k in range(17))]
    back = [(RAIL_Y - NECK, RAIL_Z - GAP / 2), (RAIL_Y - BACK, RAIL_Z - GAP / 2)]
    return front + arc + back


def resample(points, count):
    """count + 1 points at equal arc length along the polyline."""
    lengths = [0.0]
    for (y0, z0), (y1, z1) in zip(points, points[1:]):
        lengths.append(lengths[-1] + math.hypot(y1 - y0, z1 - z0))
    out, seg = [], 0
    for k in range(count + 1):
        s = lengths[-1] * k / count
        while seg < len(points) - 2 and lengths[seg + 1] < s:
            seg += 1
        t = (s - lengths[seg]) / max(lengths[seg + 1] - lengths[seg], 1e-15)
        (y0, z0), (y1, z1) = points[seg], points[seg + 1]
        out.append((y0 + t * (y1 - y0), z0 + t * (z1 - z0)))
    return out


def main():
    rows = resample(path(), LENGTH_CELLS)
    print(f"# towel over a rail: {WIDTH_CELLS + 1} x {LENGTH_CELLS + 1} vertices (make_towel.py)")
    for y, z in rows:
        for i in range(WIDTH_CELLS + 1):
            print(f"v {X0 + (X1 - X0) * i / WIDTH_CELLS:.6f} {y:.6f} {z:.6f}")
    n = WIDTH_CELLS + 1
    for j in range(LENGTH_CELLS):
        for i in range(WIDTH_CELLS):
            a, b, c, d = j * n + i + 1, j * n + i + 2, (j + 1) * n + i + 2, (j + 1) * n + i + 1
            if (i + j) % 2 == 0:
                print(f"f {a} {b} {c}\nf {a} {c} {d}")
            else:
                print(f"f {a} {b} {d}\nf {b} {c} {d}")


if __name__ == "__main__":
    main()
