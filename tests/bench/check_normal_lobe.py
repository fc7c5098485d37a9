#!/usr/bin/python3
"""bench/transfer_interpolants.py --lobe against a closed form. Three square
flaps of a package's mesh tilt with q_u (a linear displacement, so each flap
stays flat and its normal is (-dz/dx, -dz/dy, 1) normalised, computed here
without the script's mesh code). Each point's transfer is the clamped cosine
at that normal, A_l Y_l(n) in bands 1 and 2 (shared/reference constants, the
script's order), scaled per point and channel, plus a pattern in bands 0 and 3
whose amplitude is affine in q_u. With the lobe taken off, a rank-1 model holds
every state and the affine interpolant serves them to float precision; the
paper's model at rank 1 cannot (the lobe turns nonlinearly in two directions).
Both are measured against the same variation. Bad packages give one-line errors."""
import json
import subprocess
import sys

import h5py
import numpy as np

from transfers_writer import write_transfers

script, work = sys.argv[1], sys.argv[2]
rng = np.random.default_rng(5)
side = 4  # vertices per flap edge
flaps = [(0.0, 0.0), (2.0, 0.0), (0.0, 2.0)]
grid = np.stack(np.meshgrid(np.linspace(0, 1, side), np.linspace(0, 1, side), indexing="ij"), -1).reshape(-1, 2)
points, triangles, flap_of = [], [], []
for f, (x0, y0) in enumerate(flaps):
    base = len(points)
    points += [(x0 + u, y0 + v, 0.0) for u, v in grid]
    flap_of += [f] * len(grid)
    for i in range(side - 1):
        for j in range(side - 1):
            a, b, c, d = (base + i * side + j, base + (i + 1) * side + j, base + (i + 1) * side + j + 1,
                          base + i * side + j + 1)
            triangles += [(a, b, c), (a, c, d)]  # counter-clockwise seen from +z: normals up
rest = np.array(points)
flap_of = np.array(flap_of)
S = len(rest)
# tilt of flap f: dz/dx = slope_x[f] . q, dz/dy = slope_y[f] . q (about its corner)
slope_x, slope_y = rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
local = rest[:, :2] - np.array(flaps)[flap_of]
u_u = np.zeros((S, 3, 2))
u_u[:, 2, :] = local[:, :1] * slope_x[flap_of] + local[:, 1:] * slope_y[flap_of]
u_u = u_u.reshape(3 * S, 2)

roles = np.array([0] * 40 + [1] * 15 + [2] * 15, np.uint8)
T = len(roles)
q_u = 0.3 * rng.normal(size=(T, 2))


def sh_bands_1_2(n):
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack([-0.4886025119029199 * y, 0.4886025119029199 * z, -0.4886025119029199 * x,
                     1.092548430592079 * x * y, -1.092548430592079 * y * z,
                     0.9461746957575601 * z * z - 0.3153915652525201, -1.092548430592079 * x * z,
                     0.5462742152960395 * (x * x - y * y)], -1)


normal = np.zeros((T, S, 3))
normal[..., 0] = -(q_u @ slope_x.T)[:, flap_of]
normal[..., 1] = -(q_u @ slope_y.T)[:, flap_of]
normal[..., 2] = 1.0
normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
y = sh_bands_1_2(normal)  # (T, S, 8)
scale = rng.uniform(0.3, 1.0, (S, 3))
fields = np.repeat(rng.normal(size=(S, 3, 16))[None], T, 0)
fields[..., 1:4] += scale[None, :, :, None] * 2.0943951 * y[:, :, None, :3]
fields[..., 4:9] += scale[None, :, :, None] * 0.7853982 * y[:, :, None, 3:]
pattern = rng.normal(size=(S, 3, 8))
amplitude = 0.3 + q_u[:, 0] - 0.5 * q_u[:, 1]
fields[..., [0, 9, 10, 11, 12, 13, 14, 15]] += 0.2 * amplitude[:, None, None, None] * pattern[None]
fields[..., [0, 15]] += 0.01 * rng.normal(size=(T, S, 3, 2))  # no function of q_u, and out of the lobe's bands
fields = fields.astype(np.float32).astype(np.float64)  # what the file holds

path, package = f"{work}/lobe.transfers.h5", f"{work}/lobe.package.h5"
write_transfers(path, fields, roles, q_u, rest, np.ones(S), "three flaps")
with h5py.File(package, "w") as f:
    f["reduction/mean_shape"] = rest.reshape(-1).astype(np.float32)
    f["reduction/U_u"] = u_u.astype(np.float32)
    f["mesh/triangles"] = np.array(triangles, np.uint32)


def run(*extra, ok=True):
    out = f"{work}/lobe.json"
    r = subprocess.run([script, path, "--rank-a", "1", "--json", out, *extra], capture_output=True, text=True)
    if not ok:
        return r
    assert r.returncode == 0, r.stderr
    return json.load(open(out))


paper = run()
lobe = run("--lobe", package)
# numpy's reading: the lobe leaves pattern + noise; its rank-1 basis from the representatives
# about their mean, the reported nodes' truncation over their variation about the paper's M-bar
rep, reported = roles == 0, roles == 2
left = fields.copy()
left[..., 1:9] = fields[rep][..., 1:9].mean(0)  # what an exact lobe leaves of bands 1 and 2
left = left.reshape(T, -1)
u = np.linalg.svd(left[rep] - left[rep].mean(0), full_matrices=False)[2][0]
d = left[reported] - left[rep].mean(0)
truncated = d - np.outer(d @ u, u)
whole = fields.reshape(T, -1)
expected = np.linalg.norm(truncated, 2) / np.linalg.norm(whole[reported] - whole[rep].mean(0), 2)
assert 1e-3 < expected < 0.05 and abs(lobe["truncation"]["reported"] - expected) < 1e-3 * expected, \
    (lobe["truncation"], expected)
share = 1 - (left[rep] - left[rep].mean(0)).var(0).sum() / whole[rep].var(0).sum()  # of the variation about the mean
assert abs(lobe["lobe_share"] - share) < 1e-5, (lobe["lobe_share"], share)
assert lobe["interpolants"]["affine"]["reported"] < 2 * expected, lobe["interpolants"]["affine"]
assert paper["truncation"]["reported"] > 0.05, paper["truncation"]
assert paper["interpolants"]["affine"]["reported"] > 0.05, paper["interpolants"]["affine"]
# σ_2/σ_1 of what the lobe leaves, over the paper model's σ_1: one direction and the noise
assert lobe["clusters_sigma_ratio"] < 0.05 < paper["clusters_sigma_ratio"], (lobe, paper)

# cluster-size weights (all 1 here) must fit the same lobe
assert abs(run("--lobe", package, "--weighting", "cluster-size")["lobe_share"] - lobe["lobe_share"]) < 1e-9

with h5py.File(f"{work}/lobe.bad.h5", "w") as f:
    f["reduction/mean_shape"] = rest.reshape(-1)[:-3].astype(np.float32)
    f["reduction/U_u"] = u_u[:-3].astype(np.float32)
    f["mesh/triangles"] = np.array(triangles, np.uint32)
for bad, expected in ((f"{work}/lobe.bad.h5", "expected 48 scene points"), (path, "/reduction/mean_shape: missing"),
                      (f"{work}/missing.h5", "expected the package")):
    r = run("--lobe", bad, ok=False)
    assert r.returncode != 0 and expected in r.stderr and len(r.stderr.strip().splitlines()) == 1, (bad, r.stderr)
print("transfer_interpolants.py --lobe: closed form held")
