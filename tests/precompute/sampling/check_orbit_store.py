#!/usr/bin/python3
"""Simulates the tiny plant (it has rods, so every dataset is present), reads
the orbit store with h5py, independently of the C++ reader, and checks it
against the layout in docs/simulator.md: names, shapes, dtypes, invariants."""
import subprocess
import sys

import h5py
import numpy as np


def text(v):
    return v.decode() if isinstance(v, bytes) else v


def main(tool: str, scene: str, path: str) -> None:
    subprocess.run([tool, "simulate", scene, "--schedule", "right 0.2; stop 0.1", "-o", path], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with h5py.File(path, "r") as f:
        a = f.attrs
        assert text(a["format"]) == "phasecast-orbits"
        assert int(a["format_version"]) == 2 and a["format_version"].dtype == np.int32
        assert text(a["scene"]) == "plant_pot_tiny"
        assert text(a["source"]) == "phasecast-simulator"
        assert abs(float(a["dt"]) - 0.02) < 1e-12
        V = f["mesh/rest_positions"].shape[0]
        assert f["mesh/rest_positions"].dtype == np.float32 and f["mesh/rest_positions"].shape == (V, 3)
        assert f["mesh/triangles"].dtype == np.uint32 and f["mesh/triangles"].shape[1] == 3
        assert f["mesh/segments"].dtype == np.uint32 and f["mesh/segments"].shape == (7, 2)
        assert f["mesh/triangles"][:].max() < V and f["mesh/segments"][:].max() < V
        assert f["mesh/pinned"].dtype == np.uint8 and f["mesh/pinned"].shape == (V,)
        names = [text(n) for n in f["palette/names"][:]]
        assert names == ["left", "stop", "right"], names
        D = len(names)
        for k in ("alpha_impulse", "alpha_forcing"):
            assert f["palette/" + k].dtype == np.float32 and f["palette/" + k].shape == (D, 3)
        kin = f["palette/kinematics"][:]
        assert kin.dtype == np.float32 and kin.shape == (D, 11)
        assert kin[2, 6] == 0 and abs(kin[2, 7] - 0.5) < 1e-6  # translational, rate +0.5 m/s
        N = f["frames/positions"].shape[0]
        assert N == 15
        for k in ("positions", "velocities"):
            d = f["frames/" + k]
            assert d.dtype == np.float32 and d.shape == (N, 3 * V) and np.isfinite(d[:]).all()
        assert f["frames/palette"].dtype == np.int32 and list(f["frames/palette"][:]) == [2] * 10 + [1] * 5
        support = f["frames/support"][:]
        assert support.dtype == np.float32 and support.shape == (N, 12)
        assert np.allclose(support[:, [0, 5, 10]], 1) and abs(support[10, 3] - 0.1) < 1e-6  # 0.2 s at 0.5 m/s
        start, length, pal = f["irfs/start"][:], f["irfs/length"][:], f["irfs/palette"][:]
        assert start.dtype == length.dtype == pal.dtype == np.int32
        assert list(start) == [0, 10] and list(length) == [10, 5] and list(pal) == [2, 1]
        cont = f["irfs/continues"][:]
        assert cont.dtype == np.uint8 and list(cont) == [0, 1]  # a schedule is one continuous orbit
        # Positions are in the support frame: pinned stem vertices never move.
        pinned = f["mesh/pinned"][:].astype(bool)
        P = f["frames/positions"][:].reshape(N, V, 3)
        assert np.array_equal(P[:, pinned], np.broadcast_to(f["mesh/rest_positions"][:][pinned], P[:, pinned].shape))
    print("orbit store layout OK")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])
