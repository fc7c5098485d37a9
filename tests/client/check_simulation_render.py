#!/usr/bin/python3
"""phasecast-render --simulation as a user runs it, checked by an independent
reader: h5py reads the orbit store that `phasecast-precompute simulate`
wrote, and the positions the GPU computed for a frame past the first chunk of
frames must be the simulated ones, taken to the world by that frame's support
transform (float64 here). The door swings in the PNG frames; a store of
another scene is refused in one line naming what differs; the scene's [view]
draws what the same flags draw."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
from PIL import Image


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, **kw)


def check_view(precompute: str, render: str, scenes: Path, work: Path) -> None:
    """The scene's [view] is what the flags would say: the same pixels."""
    viewed = work / "viewed.toml"
    viewed.write_text((scenes / "cloth_door.toml").read_text() + "\n[view]\neye = [1.5, 1.2, 2.5]\n"
                      "target = [0, 0.6, 0]\nfov = 35\nfloor = \"none\"\nlight = \"sun\"\nexposure = 1.3\n")
    store = work / "viewed.h5"
    r = run([precompute, "simulate", str(viewed), "--schedule", "open 0.3", "-o", str(store)])
    assert r.returncode == 0, r.stderr
    common = ["--simulation", str(store), "--frames", "10", "--size", "64x64", "--dump-vertices", "9"]
    r = run([render, *common, str(work / "view_scene.npy"), "--out", str(work / "view_scene")])
    assert r.returncode == 0, r.stderr
    r = run([render, *common, str(work / "view_flags.npy"), "--out", str(work / "view_flags"), "--eye",
             "1.5,1.2,2.5", "--target", "0,0.6,0", "--fov", "35", "--backdrop", "off", "--light", "sun",
             "--exposure", "1.3"])
    assert r.returncode == 0, r.stderr
    r = run([render, *common, str(work / "view_default.npy"), "--out", str(work / "view_default"),
             "--light", "grace"])
    assert r.returncode == 0, r.stderr
    same = (work / "view_scene/frame_000009.png").read_bytes() == (work / "view_flags/frame_000009.png").read_bytes()
    assert same, "the scene's [view] and the same view given as flags draw different pixels"
    assert (work / "view_scene/frame_000009.png").read_bytes() != (work / "view_default/frame_000009.png").read_bytes()
    light = np.load(work / "view_scene.npy")[:, 3:]
    assert np.abs(light - np.load(work / "view_default.npy")[:, 3:]).max() > 1e-3, "--light overrides the scene's"
    # A floor height of its own: the backdrop's floor moves (the door's lowest point is y = 0).
    floors = []
    for name, floor in (("floor_low", "-0.6"), ("floor_rest", None)):
        text = (scenes / "cloth_door.toml").read_text() + "\n[view]\neye = [1.5, 1.2, 2.5]\ntarget = [0, 0.6, 0]\n"
        (work / f"{name}.toml").write_text(text + (f"floor = {floor}\n" if floor else ""))
        r = run([precompute, "simulate", str(work / f"{name}.toml"), "--schedule", "open 0.1", "-o",
                 str(work / f"{name}.h5")])
        assert r.returncode == 0, r.stderr
        r = run([render, "--simulation", str(work / f"{name}.h5"), "--frames", "1", "--size", "64x64", "--out",
                 str(work / name)])
        assert r.returncode == 0, r.stderr
        floors.append(np.asarray(Image.open(work / name / "frame_000000.png"), dtype=np.int16))
    assert np.abs(floors[0] - floors[1]).max() > 20, "[view] floor = -0.6 draws the floor where it was"


def check_package_view(make_fixture: str, render: str, work: Path) -> None:
    """A package's [view] attributes, written here by h5py, draw what the same flags draw."""
    package = work / "plate_view.h5"
    subprocess.run([make_fixture, "-o", str(package)], check=True, stdout=subprocess.DEVNULL)
    with h5py.File(package, "a") as f:
        f.attrs["camera"] = np.array([0.4, 0.9, 2.2, 0, 0.1, 0, 0, 1, 0, 30], dtype=np.float32)
        f.attrs["floor"] = np.int32(0)
        f.attrs["light"] = "sky"
        f.attrs["exposure"] = 1.7
    common = ["--package", str(package), "--play-irf", "1", "--frames", "3", "--size", "64x64"]
    r = run([render, *common, "--out", str(work / "pkg_scene")])
    assert r.returncode == 0, r.stderr
    r = run([render, *common, "--out", str(work / "pkg_flags"), "--eye", "0.4,0.9,2.2", "--target", "0,0.1,0",
             "--fov", "30", "--backdrop", "off", "--light", "sky", "--exposure", "1.7"])
    assert r.returncode == 0, r.stderr
    scene_png = sorted((work / "pkg_scene").glob("*.png"))[-1]
    assert scene_png.read_bytes() == (work / "pkg_flags" / scene_png.name).read_bytes(), "package view != flags"
    with h5py.File(package, "a") as f:
        f.attrs["light"] = "moon"
    r = run([render, *common])
    assert r.returncode == 1 and "[view] light: light probe 'moon' is unknown" in r.stderr, r.stderr


def check_contact_sheets(source: Path, frames: Path, work: Path) -> None:
    """scripts/contact-sheet of the drawn frames: a 4 x 3 grid of half-size tiles from the first frame to
    the last; of five frames, the widest whole row (4 x 1) with no frame twice."""
    if not shutil.which("ffmpeg"):
        print("contact sheets not checked: ffmpeg is not on PATH (scripts/install-deps installs it)")
        return
    sheet = work / "sheet.png"
    r = run([str(source / "scripts" / "contact-sheet"), str(frames), "-o", str(sheet)])
    assert r.returncode == 0, r.stderr
    assert "4 x 3 frames" in r.stdout and "frame 0 to frame 79 of its 80" in r.stdout, r.stdout
    assert Image.open(sheet).size == (4 * (48 + 4), 3 * (48 + 4))
    few = work / "few"
    few.mkdir(exist_ok=True)
    for name in sorted(frames.glob("frame_*.png"))[:5]:
        shutil.copy(name, few / name.name)
    r = run([str(source / "scripts" / "contact-sheet"), str(few), "-o", str(work / "few.png")])
    assert r.returncode == 0, r.stderr
    assert "4 x 1 frames" in r.stdout and "of its 5" in r.stdout, r.stdout
    assert Image.open(work / "few.png").size == (4 * (48 + 4), 48 + 4)


def main(precompute: str, render: str, source_dir: str, workdir: str, make_fixture: str) -> None:
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
    check_contact_sheets(Path(source_dir), out, work)

    gpu = np.load(work / "dump.npy")
    with h5py.File(store, "r") as f:
        assert f.attrs["scene_file"] == os.path.abspath(scenes / "cloth_door.toml")
        x = f["frames/positions"][dumped].astype(np.float64).reshape(-1, 3)
        support = f["frames/support"][dumped].astype(np.float64).reshape(3, 4)
    world = x @ support[:, :3].T + support[:, 3]
    assert np.abs(support[:, :3] - np.eye(3)).max() > 0.1, "the door has not swung by frame 70"
    err = np.linalg.norm(gpu[: len(world), :3] - world, axis=1)
    assert err.max() < 2e-6, f"worst position error {err.max()} m"  # float32 positions near 2 m

    # A store of another scene: one line naming the field that differs.
    r = run([render, "--simulation", str(store), "--scene-file", str(scenes / "plant_pot.toml"), "--frames", "1"])
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and "does not belong" in lines[0] and "vertices" in lines[0], r.stderr
    check_view(precompute, render, scenes, work)
    check_package_view(make_fixture, render, work)
    print(f"simulation drawn as simulated: {len(world)} simulated vertices, worst position error {err.max():.3g} m")


if __name__ == "__main__":
    main(*sys.argv[1:6])
