#!/usr/bin/python3
"""Runs `phasecast-precompute transfer` on an octahedron-subdivided sphere OBJ
and reads the result with h5py, independently of the C++ reader: dataset
names, shapes, dtypes, attributes, and the exit-radiance convention of
docs/transfer.md (sum_k T[p, c, k] L_ck, albedo and 1/pi included)."""
import math
import subprocess
import sys

import h5py
import numpy as np


def sphere_obj(path: str, levels: int = 3) -> None:
    verts = [np.array(v, float) for v in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(levels):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        nxt = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nxt += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = nxt
    with open(path, "w") as f:
        for v in verts:
            f.write("v %.9f %.9f %.9f\n" % tuple(v))
        for a, b, c in faces:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


def main(tool: str, workdir: str) -> None:
    obj, out = workdir + "/sphere.obj", workdir + "/sphere_transfer.h5"
    sphere_obj(obj)
    subprocess.run([tool, "transfer", obj, "-o", out, "--mode", "shadowed", "--rays", "2048",
                    "--albedo", "0.9,0.5,0.1", "-q"], check=True)
    with h5py.File(out, "r") as f:
        S = f["positions"].shape[0]
        assert f["positions"].dtype == np.float32 and f["positions"].shape == (S, 3)
        assert f["normals"].dtype == np.float32 and f["normals"].shape == (S, 3)
        T = f["transfer"][:]
        assert f["transfer"].dtype == np.float32 and T.shape == (S, 3, 16), T.shape
        mode = f.attrs["mode"]
        assert (mode.decode() if isinstance(mode, bytes) else mode) == "shadowed"
        assert int(f.attrs["rays"]) == 2048 and int(f.attrs["bounces"]) == 2
        assert np.allclose(f.attrs["albedo"], [0.9, 0.5, 0.1])
        n = f["normals"][:]
    # White furnace: L = 1 has only L_0 = 4 pi Y_0; the exit radiance is the albedo (convex).
    L0 = 4 * math.pi * 0.2820947917738781
    exit_radiance = T[:, :, 0] * L0
    assert np.abs(exit_radiance - [0.9, 0.5, 0.1]).max() < 1e-3, exit_radiance
    # Light from +z only in band 1 (L_2 = 1, k = l(l+1)+m = 2 is Y_1^0 ~ z):
    # exit = (rho/pi) (2 pi / 3) 0.488603 n_z.
    expected = 0.9 / math.pi * (2 * math.pi / 3) * 0.4886025119029199 * n[:, 2]
    assert np.abs(T[:, 0, 2] - expected).max() < 1e-3
    print("transfer file OK: %d points" % S)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
