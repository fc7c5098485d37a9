#!/usr/bin/python3
"""Independent check of phasecast-render --dump-vertices: NumPy reads the .npy
and .csv dumps, h5py reads the package, and the GPU positions must equal
x = x_bar + U_u q_u (eq. 7) followed by the support transform, computed here
in float64. The radiance must equal (M_bar + U_a q_a) . L for the white
furnace light (constant radiance 1, L_0 = 4 pi Y_0 in every channel)."""
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np


def main(make_fixture: str, render: str, workdir: str) -> None:
    work = Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    package = work / "plate.h5"
    subprocess.run([make_fixture, "-o", str(package)], check=True, stdout=subprocess.DEVNULL)
    irf, t = 3, 25
    for ext in ("npy", "csv"):
        out = work / f"dump.{ext}"
        subprocess.run([render, "--package", str(package), "--play-irf", str(irf), "--size", "32x32",
                        "--light", "white", "--dump-vertices", str(t), str(out)],
                       check=True, stdout=subprocess.DEVNULL)
    gpu_npy = np.load(work / "dump.npy")
    gpu_csv = np.loadtxt(work / "dump.csv", delimiter=",", skiprows=1)
    assert gpu_npy.dtype == np.float32 and gpu_npy.shape[1] == 6, gpu_npy.shape
    # 9 significant digits in the CSV round-trip float32 exactly.
    assert np.array_equal(gpu_npy, gpu_csv.astype(np.float32)), "npy and csv dumps differ"

    with h5py.File(package, "r") as f:
        node = int(f["portrait/irf_start"][irf]) + t
        x_bar = f["reduction/mean_shape"][:].astype(np.float64)
        U_u = f["reduction/U_u"][:].astype(np.float64)
        q_u = f["portrait/q_u"][node].astype(np.float64)
        support = f["portrait/support"][node].astype(np.float64).reshape(3, 4)
        deformable = f["mesh/deformable"][:].astype(bool)
        attached = f["mesh/attached"][:].astype(bool)
        M_bar = f["appearance/mean_transfer"][:].astype(np.float64)
        U_a = f["appearance/U_a"][:].astype(np.float64)
        q_a = f["portrait/q_a"][node].astype(np.float64)
    S = deformable.size
    x = x_bar.reshape(S, 3) + np.where(deformable[:, None], (U_u @ q_u).reshape(S, 3), 0.0)
    x = np.where(attached[:, None], x @ support[:, :3].T + support[:, 3], x)
    err = np.linalg.norm(gpu_npy[:, :3] - x, axis=1)
    assert np.all(err <= 1e-5 * np.linalg.norm(x, axis=1) + 1e-7), f"worst position error {err.max()}"

    # White furnace: only k = 0 of each channel sees light; rotation leaves band 0 unchanged.
    transfer = (M_bar + U_a @ q_a).reshape(S, 3, 16)
    expected = transfer[:, :, 0] * 4 * np.pi * 0.2820947917738781
    assert np.allclose(gpu_npy[:, 3:], expected, rtol=1e-5, atol=1e-6), np.abs(gpu_npy[:, 3:] - expected).max()
    print(f"vertex dump matches: {S} points, worst position error {err.max():.3g}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
