"""The unshadowed lobe at a state's deformed normal, taken off the stage's transfers.

A diffuse point that nothing shades has the transfer of the clamped cosine
turned to its normal n: band l is A_l Y_l(n) (Ramamoorthi & Hanrahan 2001),
bands 1 and 2 hold nearly all of it and band 3 of the clamped cosine is zero.
When the surface turns, that part of the transfer turns with it, nonlinearly in
q_u and in as many directions as the deformation has. A client that knows the
deformed normal can draw it itself; the paper's model (§4.2) then only needs to
hold the rest. Here each point p and colour channel c gets one scalar per band,

    lobe_pc(q) = sum_{l=1,2} s_pcl (Y_l(n_p(q)) - Y_l-bar_p),

fitted by least squares to the representatives (their weighted means
subtracted), n_p(q) the angle-weighted vertex normal (as the stage's) of the reduced shape
x-bar + U_u q_u (eq. 7) on the package's triangles.
"""
import sys

import h5py
import numpy as np

from transfers_file import REPRESENTATIVE

BANDS = (slice(1, 4), slice(4, 9))  # SH coefficients of bands 1 and 2, in core/src/sh.cpp's order


def sh_bands_1_2(n):
    """Y_k(n) for k = 1..8, the real SH of shared/reference (Condon-Shortley phase), as (P, 9) with k = 0 unused."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    c1, c2a, c2b, c2c, c2d = 0.4886025119029199, 1.092548430592079, 0.9461746957575601, 0.3153915652525201, \
        0.5462742152960395
    zero = np.zeros_like(x)
    return np.stack([zero, -c1 * y, c1 * z, -c1 * x, c2a * x * y, -c2a * y * z, c2b * z * z - c2c, -c2a * x * z,
                     c2d * (x * x - y * y)], axis=1)


def vertex_normals(x, triangles):
    """Angle-weighted vertex normals, as core::vertex_normals (core/src/mesh_geometry.cpp) gives the
    stage's transfer: degenerate faces add nothing, a point with no direction gets (0, 0, 1)."""
    corners = [x[triangles[:, k]] for k in range(3)]
    face = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    length = np.linalg.norm(face, axis=1)
    keep = length > 0
    unit = face[keep] / length[keep, None]
    n = np.zeros_like(x)
    for j in range(3):
        e1 = corners[(j + 1) % 3][keep] - corners[j][keep]
        e2 = corners[(j + 2) % 3][keep] - corners[j][keep]
        angle = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), (e1 * e2).sum(1))
        np.add.at(n, triangles[keep, j], angle[:, None] * unit)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(norm > 0, n / np.where(norm > 0, norm, 1), np.array([0.0, 0.0, 1.0]))


class Lobe:
    """The deformed normals' SH at every node of a transfers file, from the package that made it."""

    def __init__(self, package, q_u, rest):
        """rest: the transfers file's rest positions, which the package's must equal."""
        try:
            p = h5py.File(package, "r")
        except OSError as e:
            sys.exit(f"{package}: expected the package the transfers file was reduced into (HDF5): {e}")
        for name in ("reduction/mean_shape", "reduction/U_u", "mesh/triangles", "mesh/rest_positions"):
            if name not in p:
                sys.exit(f"{package}: /{name}: missing dataset (a phasecast package, docs/package-format.md)")
        x_bar, u_u = p["reduction/mean_shape"][()].astype(np.float64), p["reduction/U_u"][()].astype(np.float64)
        points = len(rest)
        if x_bar.size != 3 * points or u_u.shape != (3 * points, q_u.shape[1]):
            sys.exit(f"{package}: expected {points} scene points and r_u = {q_u.shape[1]} as in the transfers "
                     f"file, got {x_bar.size // 3} points and U_u {u_u.shape[0]} x {u_u.shape[1]}")
        if not np.array_equal(p["mesh/rest_positions"][()], rest):
            sys.exit(f"{package}: /mesh/rest_positions: expected the transfers file's (the package it was "
                     f"reduced into), got other positions")
        triangles = p["mesh/triangles"][()].astype(np.int64)
        self.y = np.stack([sh_bands_1_2(vertex_normals((x_bar + u_u @ q).reshape(-1, 3), triangles))
                           for q in q_u]).astype(np.float32)  # (T, S, 9)

    def fit(self, fields, roles, weights):
        """s_pcl from the representatives, weights w summing to 1; their weighted mean of Y kept."""
        rep = np.where(roles == REPRESENTATIVE)[0]
        y = self.y[rep].astype(np.float64)
        self.y_bar = np.einsum("i,isk->sk", weights, y)
        samples = fields[rep]  # read once: (N_a, S, 3, 16) float32
        f_bar = np.zeros(fields.shape[1:])
        for w, sample in zip(weights, samples):
            f_bar += w * sample
        num = [np.zeros(fields.shape[1:3]) for _ in BANDS]
        den = [np.zeros(fields.shape[1]) for _ in BANDS]
        for w, sample, yi in zip(weights, samples, y):
            d = sample - f_bar
            for b, band in enumerate(BANDS):
                dy = yi[:, band] - self.y_bar[:, band]
                num[b] += w * np.einsum("sck,sk->sc", d[:, :, band], dy)
                den[b] += w * (dy * dy).sum(1)
        self.s = [n / np.maximum(d, 1e-300)[:, None] for n, d in zip(num, den)]  # (S, 3) each

    def at(self, i):
        """The lobe at node i, (S, 3, 16)."""
        out = np.zeros((self.y.shape[1], 3, 16))
        for s, band in zip(self.s, BANDS):
            out[:, :, band] = s[:, :, None] * (self.y[i][:, None, band] - self.y_bar[:, None, band])
        return out

    def block(self, i0, i1):
        return np.stack([self.at(i) for i in range(i0, i1)]).astype(np.float32)
