#!/usr/bin/python3
"""bench/transfer_interpolants.py --lobe against a second reading. Three square
flaps of a package's mesh tilt with q_u (a linear displacement, so each flap
stays flat and its normal is (-dz/dx, -dz/dy, 1) normalised, computed here
without the script's mesh code). Each point's transfer is the clamped cosine
at that normal, A_l Y_l(n) in bands 1 and 2 (shared/reference constants, the
script's order), scaled per point and channel, plus a term in bands 1 and 2
that is no lobe, a pattern in bands 0 and 3 whose amplitude is affine in q_u,
and noise. numpy reads it again: a weighted least-squares fit per point,
channel and band (lstsq, equal and unequal cluster sizes), the weighted rank-1
model of what that leaves, and its truncation, sigma ratio and shares against
the paper model's variation; the script must agree to 1e-4 and take more than
half the paper model's error off. The vertex normal is checked to be
angle-weighted, as the stage's. Bad packages give one-line errors."""
import json
import os
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
fields[..., 1:9] += 0.05 * (q_u[:, 0] ** 2 - q_u[:, 1])[:, None, None, None] * rng.normal(size=(S, 3, 8))  # no lobe
sizes = rng.integers(1, 8, 40)  # the representatives' clusters, of unequal sizes
fields = fields.astype(np.float32).astype(np.float64)  # what the file holds

path, package = f"{work}/lobe.transfers.h5", f"{work}/lobe.package.h5"
write_transfers(path, fields, roles, q_u, rest, np.ones(S), "three flaps", np.repeat(np.arange(40), sizes))
def write_package(name, rest_positions, mean_shape, basis):
    with h5py.File(name, "w") as f:
        f["reduction/mean_shape"] = mean_shape.reshape(-1).astype(np.float32)
        f["reduction/U_u"] = basis.astype(np.float32)
        f["mesh/triangles"] = np.array(triangles, np.uint32)
        f["mesh/rest_positions"] = rest_positions.astype(np.float32)


write_package(package, rest, rest, u_u)


def run(*extra, ok=True):
    out = f"{work}/lobe.json"
    r = subprocess.run([script, path, "--rank-a", "1", "--json", out, *extra], capture_output=True, text=True)
    if not ok:
        return r
    assert r.returncode == 0, r.stderr
    return json.load(open(out))


def numpy_reading(weighting):
    """The lobe model read a second time: per point, channel and band a weighted least-squares fit of
    intercept + s Y_l(n) (numpy's lstsq), then the weighted rank-1 model of what it leaves."""
    w = np.ones(40) if weighting == "equal" else sizes.astype(float)
    w /= w.sum()
    left = fields.copy()
    for band, cols in ((slice(1, 4), slice(0, 3)), (slice(4, 9), slice(3, 8))):
        k = cols.stop - cols.start
        for p_ in range(S):
            x = y[rep, p_, cols]
            design = np.concatenate([np.hstack([np.sqrt(wi) * np.eye(k), np.sqrt(wi) * xi[:, None]])
                                     for wi, xi in zip(w, x)])
            for c in range(3):
                target = np.concatenate([np.sqrt(wi) * fi for wi, fi in zip(w, fields[rep, p_, c, band])])
                s_ = np.linalg.lstsq(design, target, rcond=None)[0][-1]
                left[:, p_, c, band] -= s_ * y[:, p_, cols]
    left, whole = left.reshape(T, -1), fields.reshape(T, -1)
    m_left, m_whole = w @ left[rep], w @ whole[rep]
    a_left, a_whole = np.sqrt(w)[:, None] * (left[rep] - m_left), np.sqrt(w)[:, None] * (whole[rep] - m_whole)
    sv_left, u = np.linalg.svd(a_left, full_matrices=False)[1:]
    d = left[reported] - m_left
    truncated = d - np.outer(d @ u[0], u[0])
    return {"truncation": np.linalg.norm(truncated, 2) / np.linalg.norm(whole[reported] - m_whole, 2),
            "sigma_ratio": sv_left[1] / np.linalg.svd(a_whole, compute_uv=False)[0],
            "share": 1 - (a_left ** 2).sum() / (a_whole ** 2).sum(),
            "share_reported": 1 - (d ** 2).sum() / ((whole[reported] - m_whole) ** 2).sum()}


def close(a, b, what):
    assert abs(a - b) <= 1e-4 * abs(b), (what, a, b)


rep, reported = roles == 0, roles == 2
paper = run()
assert paper["truncation"]["reported"] > 0.05 and paper["clusters_sigma_ratio"] > 0.05, paper
readings = {}
for weighting in ("equal", "cluster-size"):
    lobe, truth = run("--lobe", package, "--weighting", weighting), numpy_reading(weighting)
    readings[weighting] = truth
    close(lobe["truncation"]["reported"], truth["truncation"], "truncation")
    close(lobe["clusters_sigma_ratio"], truth["sigma_ratio"], "sigma_(r+1) / the paper's sigma_1")
    close(lobe["lobe_share"]["representatives"], truth["share"], "share")
    close(lobe["lobe_share"]["reported"], truth["share_reported"], "share at the reported nodes")
    assert truth["truncation"] < 0.5 * paper["truncation"]["reported"], (truth, paper["truncation"])
# the weights must matter here, or the loop above could not tell them apart
assert abs(readings["equal"]["share"] - readings["cluster-size"]["share"]) > 1e-3, readings

# the normal at a vertex is angle-weighted, as the stage's (core/src/mesh_geometry.cpp): two faces
# meeting at right angles in the vertex, of areas 0.5 and sqrt(2), weigh alike; a degenerate face
# adds nothing and a point on no face gets (0, 0, 1)
sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
from normal_lobe import vertex_normals  # noqa: E402

corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-2, 0, 2], [5, 5, 5]], float)
n = vertex_normals(corners, np.array([[0, 1, 2], [0, 2, 3], [0, 1, 1]]))
expected = np.array([0, 0, 1]) + np.array([1, 0, 1]) / np.sqrt(2)
assert np.allclose(n[0], expected / np.linalg.norm(expected)) and np.allclose(n[4], [0, 0, 1]), n

write_package(f"{work}/lobe.bad.h5", rest[:-1], rest[:-1], u_u[:-3])
moved = rest.copy()
moved[0, 0] += 0.5
write_package(f"{work}/lobe.other.h5", moved, rest, u_u)
for bad, expected in ((f"{work}/lobe.bad.h5", "expected 48 scene points"), (path, "/reduction/mean_shape: missing"),
                      (f"{work}/lobe.other.h5", "/mesh/rest_positions: expected the transfers file's"),
                      (f"{work}/missing.h5", "expected the package")):
    r = run("--lobe", bad, ok=False)
    assert r.returncode != 0 and expected in r.stderr and len(r.stderr.strip().splitlines()) == 1, (bad, r.stderr)
print("transfer_interpolants.py --lobe: closed form held")
