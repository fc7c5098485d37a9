#!/usr/bin/python3
"""phasecast-render --simulation as a user runs it, checked by an independent
reader: h5py reads the orbit store that `phasecast-precompute simulate`
wrote, and the positions the GPU computed for a frame past the first chunk of
frames must be the simulated ones, taken to the world by that frame's support
transform (float64 here). The door swings in the PNG frames; a store of
another scene is refused in one line naming what differs."""
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, **kw)


def main(precompute: str, render: str, source_dir: str, workdir: str) -> None:
    work = Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    scenes = Path(source_dir) / "scenes" / "tiny"
    store = work / "run.h5"
    r = run([precompute, "simulate", str(scenes / "cloth_door.toml"), "--schedule", "open 0.8; stop 1.2",
             "-o", str(store)])
    assert r.returncode == 0, r.stderr
    frames, dumped = 80, 70  # chunks of 64 frames: frame 70 is drawn by the second chunk's bases
    out = work / "frames"
    r = run([render, "--simulation", str(store), "--frames", str(frames), "--size", "96x96", "--out", str(out),
             "--dump-vertices", str(dumped), str(work / "dump.npy")])
    assert r.returncode == 0, r.stderr
    assert "drawn as simulated" in r.stdout, r.stdout
    assert len(list(out.glob("frame_*.png"))) == frames

    gpu = np.load(work / "dump.npy")
    with h5py.File(store, "r") as f:
        assert f.attrs["scene_file"] == str((scenes / "cloth_door.toml").resolve())
        x = f["frames/positions"][dumped].astype(np.float64).reshape(-1, 3)
        support = f["frames/support"][dumped].astype(np.float64).reshape(3, 4)
    world = x @ support[:, :3].T + support[:, 3]
    assert np.abs(support[:, :3] - np.eye(3)).max() > 0.1, "the door has not swung by frame 70"
    err = np.linalg.norm(gpu[: len(world), :3] - world, axis=1)
    assert err.max() < 1e-5, f"worst position error {err.max()} m"

    # A store of another scene: one line naming the field that differs.
    r = run([render, "--simulation", str(store), "--scene-file", str(scenes / "plant_pot.toml"), "--frames", "1"])
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and "does not belong" in lines[0] and "vertices" in lines[0], r.stderr
    print(f"simulation drawn as simulated: {len(world)} simulated vertices, worst position error {err.max():.3g} m")


if __name__ == "__main__":
    main(*sys.argv[1:5])
