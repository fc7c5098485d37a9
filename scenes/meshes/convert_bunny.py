#!/usr/bin/env python3
"""Converts the Stanford bunny of the npm package `bunny` (1.0.1, public domain,
https://www.npmjs.com/package/bunny, a closed 1839-vertex version of the Stanford
3D Scanning Repository bunny) into scenes/meshes/bunny.obj, decimated by
shortest-edge collapses (link condition and normal-flip checks keep it a closed
manifold) and scaled to 8 cm height with its base at y = 0, centred in x and z.

Run once:  npm pack bunny && tar xzf bunny-1.0.1.tgz &&
           node -e 'require("fs").writeFileSync("bunny.json", JSON.stringify(require("./package")))' &&
           python3 convert_bunny.py bunny.json bunny.obj 240
"""
import json
import sys

import numpy as np


def decimate(P, F, target_vertices):
    faces = {i: tuple(f) for i, f in enumerate(F)}
    vf = {v: set() for v in range(len(P))}
    for i, f in faces.items():
        for v in f:
            vf[v].add(i)
    alive = set(range(len(P)))

    def neighbours(v):
        return {u for fi in vf[v] for u in faces[fi]} - {v}

    def normal(f, pos):
        a, b, c = (pos[f[0]], pos[f[1]], pos[f[2]])
        return np.cross(b - a, c - a)

    while len(alive) > target_vertices:
        edges = sorted({(min(a, b), max(a, b)) for f in faces.values() for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))},
                       key=lambda e: (np.linalg.norm(P[e[0]] - P[e[1]]), e))
        collapsed = False
        for a, b in edges:
            if len(neighbours(a) & neighbours(b)) != 2:  # link condition: stays manifold
                continue
            mid = 0.5 * (P[a] + P[b])
            ok = True
            for fi in (vf[a] | vf[b]):
                f = faces[fi]
                if a in f and b in f:
                    continue
                moved = P.copy()
                moved[a] = mid
                moved[b] = mid
                n0, n1 = normal(f, P), normal(f, moved)
                if np.dot(n0, n1) <= 0.2 * np.linalg.norm(n0) * np.linalg.norm(n1):
                    ok = False
                    break
            if not ok:
                continue
            P[a] = mid
            for fi in list(vf[b]):
                f = faces[fi]
                if a in f:
                    for v in f:
                        vf[v].discard(fi)
                    del faces[fi]
                else:
                    faces[fi] = tuple(a if v == b else v for v in f)
                    vf[a].add(fi)
            vf[b] = set()
            alive.discard(b)
            collapsed = True
            break
        if not collapsed:
            break
    order = sorted(alive)
    index = {v: i for i, v in enumerate(order)}
    return P[order], np.array([[index[v] for v in f] for f in faces.values()])


def main():
    data = json.load(open(sys.argv[1]))
    P = np.array(data["positions"], dtype=float)
    F = np.array(data["cells"], dtype=int)
    P, F = decimate(P, F, int(sys.argv[3]))
    P -= [0.5 * (P[:, 0].min() + P[:, 0].max()), P[:, 1].min(), 0.5 * (P[:, 2].min() + P[:, 2].max())]
    P *= 0.08 / P[:, 1].max()
    with open(sys.argv[2], "w") as out:
        out.write("# Stanford bunny (Stanford 3D Scanning Repository) from the npm package 'bunny' 1.0.1\n")
        out.write("# (public domain, Mikola Lysenko), decimated by scenes/meshes/convert_bunny.py to\n")
        out.write(f"# {len(P)} vertices / {len(F)} triangles; metres, 8 cm tall, base at y = 0.\n")
        for p in P:
            out.write(f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n")
        for f in F:
            out.write(f"f {f[0] + 1} {f[1] + 1} {f[2] + 1}\n")
    print(f"{len(P)} vertices, {len(F)} triangles, Euler characteristic {len(P) - len(F) // 2 * 3 + len(F)}")


if __name__ == "__main__":
    main()
