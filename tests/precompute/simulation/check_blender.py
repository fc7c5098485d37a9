#!/usr/bin/python3
"""The Blender simulator end to end on a tiny towel-on-door .blend (docs/simulator.md, "Blender"):
simulate twice (the same bits), the door swings and the towel follows, run + validate through
Blender, a resumed run gives the same package, and each failure a user can meet names its cause."""
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

SKIP = 77
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))


def scene_text(blend="door.blend", deformable='["Towel"]', extra=""):
    with open(os.path.join(ROOT, "scenes", "blender", "cloth_door.toml")) as f:
        text = f.read()
    text = text.split("[demo]")[0]  # the demo script is relative to the shipped scene
    text = text.replace('blend = "cloth_door.blend"', f'blend = "{blend}"')
    text = text.replace('deformable = ["Towel"]', f"deformable = {deformable}")
    return text + extra


def write(folder, name, text):
    path = os.path.join(folder, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def tool(precompute, *args, env=None, expect=0):
    r = subprocess.run([precompute, *args], capture_output=True, text=True, env=env, timeout=600)
    if (r.returncode == 0) != (expect == 0):
        sys.exit(f"{' '.join(args)}: exit {r.returncode}\n{r.stderr[-3000:]}")
    return r


def positions(path):
    with h5py.File(path, "r") as f:
        return f["frames/positions"][:], f["frames/support"][:]


def fails_with(precompute, scene, needle, env=None):
    r = tool(precompute, "simulate", scene, "--schedule", "open 0.1", "-o", scene + ".h5", env=env, expect=1)
    last = r.stderr.strip().splitlines()[-1]
    assert needle in last, f"expected '{needle}' in: {last}"
    assert not os.path.exists(scene + ".h5"), "a failed simulation left an output"


def check_simulation(precompute, scene, d):
    for i in (1, 2):
        tool(precompute, "simulate", scene, "--schedule", "open 0.8; stop 0.6", "-o", f"{d}/sim{i}.h5")
    (x1, s1), (x2, _) = positions(f"{d}/sim1.h5"), positions(f"{d}/sim2.h5")
    assert np.array_equal(x1, x2), "Blender is not deterministic run to run"
    # The door turns by 1.5 rad/s for 0.8 s about -y (cloth side first), then holds.
    angle = np.arctan2(s1[:, 8], s1[:, 0])
    assert abs(angle[-1] - 1.2) < 0.05, f"door angle {angle[-1]}"
    moved = np.abs(x1 - x1[0]).reshape(len(x1), -1, 3).max(axis=(1, 2))
    assert moved.max() > 0.02, f"the towel does not follow the door (at most {moved.max()} m in the door's frame)"


def check_run(precompute, scene, d):
    common = ["--chains", "2", "--irfs-per-chain", "3", "--no-appearance", "--seed", "3"]
    tool(precompute, "run", scene, "-o", f"{d}/a.h5", *common)
    tool(precompute, "run", scene, "-o", f"{d}/b.h5", *common, "--stop-after-irfs", "2", expect=1)
    r = tool(precompute, "run", scene, "-o", f"{d}/b.h5", *common, "--resume")
    assert "cannot continue a checkpoint; sampling the chain again" in r.stderr, r.stderr[-2000:]
    with h5py.File(f"{d}/a.h5", "r") as a, h5py.File(f"{d}/b.h5", "r") as b:
        for name in ("reduction/U_u", "portrait/q_u", "portrait/irf_start", "portrait/nearest_irf"):
            assert np.array_equal(a[name][:], b[name][:]), f"{name} differs after a resumed run"
    r = tool(precompute, "validate", scene, f"{d}/a.h5", "--schedule", "open 0.4; stop 0.6")
    assert "NRMSE" in r.stdout, r.stdout


def edited_blend(d, name, edit):
    """door.blend with `edit` (Python run inside Blender) applied, saved as NAME."""
    code = f"import bpy\n{edit}\nbpy.ops.wm.save_as_mainfile(filepath={os.path.join(d, name)!r})\n"
    subprocess.run(["blender", "-b", os.path.join(d, "door.blend"), "--factory-startup", "--python-expr", code],
                   check=True, capture_output=True, timeout=300)
    return name


def check_failures(precompute, d):
    shrinking = edited_blend(d, "shrinking.blend", "b = bpy.data.objects['Towel'].modifiers.new('Build', 'BUILD')\n"
                             "b.frame_start, b.frame_duration, b.use_reverse = 20, 10, True")
    r = tool(precompute, "simulate", write(d, "shrinking.toml", scene_text(blend=shrinking)), "--schedule",
             "open 0.6", "-o", f"{d}/shrinking.h5", expect=1)
    assert "'Towel' has 32 vertices at frame 21 but 35 at the first frame (a modifier that changes the " \
           "topology?)" in r.stderr, r.stderr
    loose = edited_blend(d, "loose.blend", "bpy.data.objects['Door'].parent = None")
    fails_with(precompute, write(d, "loose.toml", scene_text(blend=loose)),
               "'Door' is not a child of the support 'Hinge': parent it so it moves with the support")
    fails_with(precompute, write(d, "missing.toml", scene_text()),
               "is not installed", env={**os.environ, "PATH": "/nonexistent"})
    fails_with(precompute, write(d, "env.toml", scene_text()), "is not an executable file",
               env={**os.environ, "PHASECAST_BLENDER": f"{d}/no-such-blender"})
    fails_with(precompute, write(d, "unknown.toml", scene_text(deformable='["Towl"]')),
               "deformable object 'Towl' is not an object of")
    fails_with(precompute, write(d, "body.toml", scene_text(extra='\n[[body]]\nname = "x"\n')),
               "the .blend's settings apply")
    hang = write(d, "hang.sh", "#!/bin/sh\necho Blender 3.4.1\necho reading the file\nexec sleep 60\n")
    crash = write(d, "crash.sh", "#!/bin/sh\necho Blender 3.4.1\necho Segmentation fault >&2\nexit 3\n")
    for script in (hang, crash):
        os.chmod(script, 0o755)
    timeout = scene_text().replace('drawn = ["Door"]', 'drawn = ["Door"]\ntimeout = 1')
    fails_with(precompute, write(d, "hang.toml", timeout), "no answer within 1 s ([simulator] timeout); its last "
               "lines: Blender 3.4.1 | reading the file", env={**os.environ, "PHASECAST_BLENDER": hang})
    fails_with(precompute, write(d, "crash.toml", timeout), "it exited with status 3; its last lines: Blender 3.4.1 "
               "| Segmentation fault", env={**os.environ, "PHASECAST_BLENDER": crash})


def main(precompute):
    if shutil.which("blender") is None:
        print("blender is not installed (scripts/install-deps installs it): skipped")
        sys.exit(SKIP)
    with tempfile.TemporaryDirectory() as d:
        subprocess.run(["blender", "-b", "--factory-startup", "--python",
                        os.path.join(ROOT, "scripts", "blender", "make-example.py"), "--",
                        f"{d}/door.blend", "--cells", "4", "6"], check=True, capture_output=True, timeout=300)
        scene = write(d, "door.toml", scene_text())
        check_simulation(precompute, scene, d)
        check_run(precompute, scene, d)
        check_failures(precompute, d)
    print("blender simulator: ok")


if __name__ == "__main__":
    main(sys.argv[1])
