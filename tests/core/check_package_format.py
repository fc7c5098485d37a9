#!/usr/bin/python3
"""Reads the fixture package with h5py, independently of the C++ reader, and
checks it against docs/package-format.md: names, shapes, dtypes, invariants."""
import subprocess
import sys

import h5py
import numpy as np


def main(make_fixture: str, path: str) -> None:
    subprocess.run([make_fixture, "-o", path], check=True, stdout=subprocess.DEVNULL)
    with h5py.File(path, "r") as f:
        a = f.attrs
        assert int(a["format_version"]) == 2
        scene = a["scene"]
        assert (scene.decode() if isinstance(scene, bytes) else scene) == "plate"
        for name in ("dt", "beta", "blend_lambda", "eps_u", "eps_a"):
            assert np.isfinite(a[name]), name
        S = f["mesh/rest_positions"].shape[0]
        F = f["mesh/triangles"].shape[0]
        assert f["mesh/rest_positions"].dtype == np.float32 and f["mesh/rest_positions"].shape == (S, 3)
        assert f["mesh/triangles"].dtype == np.uint32 and f["mesh/triangles"].shape == (F, 3)
        assert f["mesh/triangles"][:].max() < S
        assert f["mesh/normals"].shape == (S, 3)
        assert f["mesh/deformable"].dtype == np.uint8 and f["mesh/deformable"].shape == (S,)
        assert f["mesh/attached"].shape == (S,)

        names = [n.decode() if isinstance(n, bytes) else n for n in f["palette/names"][:]]
        D = len(names)
        assert names == ["close", "stop", "open"]
        assert f["palette/transitions"].shape == (D + 1, D)
        assert f["palette/on_end"].dtype == np.int32
        group = f["palette/group"][:]
        assert group.dtype == np.int32 and group.shape == (D,) and all(0 <= g <= d for d, g in enumerate(group))
        assert f["palette/max_in_a_row"].dtype == np.int32 and f["palette/max_in_a_row"].shape == (D,)
        kin = f["palette/kinematics"]
        assert kin.shape == (D, 11)
        cols = kin.attrs["columns"]
        assert (cols.decode() if isinstance(cols, bytes) else cols).split(",")[7] == "rate"

        U = f["reduction/U_u"][:]
        r_u = U.shape[1]
        assert U.shape == (3 * S, r_u) and U.dtype == np.float32
        assert np.allclose(U.T @ U, np.eye(r_u), atol=1e-4), "U_u must be orthonormal"
        static = np.repeat(f["mesh/deformable"][:] == 0, 3)
        assert not U[static].any(), "rows of static points must be zero"
        assert f["reduction/mean_shape"].shape == (3 * S,)
        sv = f["reduction/singular_values"][:]
        assert np.all(np.diff(sv) <= 1e-6), "singular values decrease"
        assert f["reduction/rel_error"].shape == sv.shape

        q = f["portrait/q_u"][:]
        N = q.shape[0]
        assert q.shape == (N, r_u) and f["portrait/qdot_u"].shape == (N, r_u)
        starts, lengths = f["portrait/irf_start"][:], f["portrait/irf_length"][:]
        assert np.all(starts + lengths <= N)
        near = f["portrait/nearest_irf"][:]
        pal = f["portrait/irf_palette"][:]
        assert near.shape == (N, D) and near.dtype == np.int32
        for d in range(D):
            assert np.all(pal[near[:, d]] == d), "nearest_irf[:, d] names IRFs of entry d"

        r_a = f["appearance/U_a"].shape[1]
        assert f["appearance/U_a"].shape == (48 * S, r_a)
        assert f["appearance/mean_transfer"].shape == (48 * S,)
        assert f["portrait/q_a"].shape == (N, r_a)
        Na = f["appearance/cluster_nodes"].shape[0]
        assert f["appearance/nrbf_centers"].shape == (Na, r_u)
        assert f["appearance/nrbf_weights"].shape == (Na, r_a)
    print(f"package format ok: S={S} F={F} N={N} D={D} r_u={r_u} r_a={r_a}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
