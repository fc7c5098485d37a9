#!/usr/bin/python3
"""The Blender simulator end to end on a tiny towel-on-door .blend (docs/simulator.md, "Blender"):
simulate twice (the same bits), the door swings and the towel follows, run + validate through
Blender, a resumed run gives the same package, the drawn objects arrive as Blender's meshes, and
each failure a user can meet names its cause."""
import filecmp
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
    # The towel's rail moves with the door: in the door's frame it stays put (a wrong axis
    # mapping between Blender and Phasecast would swing it), while the towel below it sways.
    with h5py.File(f"{d}/sim1.h5", "r") as f:
        pinned = f["mesh/pinned"][:].astype(bool) if "mesh/pinned" in f else None
    p = x1.reshape(len(x1), -1, 3)
    pinned = pinned if pinned is not None and pinned.any() else np.isclose(p[0, :, 1], p[0, :, 1].max())
    rail = np.abs(p[:, pinned] - p[0, pinned]).max()
    assert rail < 1e-3, f"the rail moves {rail} m in the door's frame"
    sway = np.abs(p[:, ~pinned] - p[0, ~pinned]).max()
    assert sway > 0.02, f"the towel does not sway in the door's frame (at most {sway} m)"


def check_free_fall(precompute, d):
    """Blender's cloth advances frame_dt seconds a frame: an unpinned towel falls 1/2 g t^2."""
    falling = edited_blend(d, "falling.blend", "t = bpy.data.objects['Towel'].modifiers['Cloth']\n"
                           "t.settings.vertex_group_mass = ''\nt.settings.air_damping = 0\n"
                           "bpy.data.objects['DoorCollider'].modifiers.clear()")
    scene = write(d, "falling.toml", scene_text(blend=falling))
    tool(precompute, "simulate", scene, "--schedule", "stop 0.4", "-o", f"{d}/fall.h5")
    x, _ = positions(f"{d}/fall.h5")
    y = x.reshape(len(x), -1, 3)[:, :, 1].mean(axis=1)
    dt, settled, k = 0.02, 25, len(y) - 1  # recording starts after settle = 0.5 s
    expected = 0.5 * 9.81 * (((settled + k) * dt) ** 2 - (settled * dt) ** 2)
    assert abs((y[0] - y[k]) - expected) < 0.03 * expected, f"fell {y[0] - y[k]} m, 1/2 g t^2 = {expected} m"


def check_run(precompute, scene, d):
    common = ["--chains", "2", "--irfs-per-chain", "3", "--no-appearance", "--seed", "3", "-j", "1"]
    tool(precompute, "run", scene, "-o", f"{d}/a.h5", *common)
    # One thread: chain 0 finishes its 3 IRFs, chain 1 stops after its first.
    tool(precompute, "run", scene, "-o", f"{d}/b.h5", *common, "--stop-after-irfs", "4", expect=1)
    r = tool(precompute, "run", scene, "-o", f"{d}/b.h5", *common, "--resume")
    assert "chain 1: its simulator cannot continue a checkpoint; sampling the chain again" in r.stderr, r.stderr
    assert "chain 0:" not in r.stderr, "a finished chain was sampled again"
    with h5py.File(f"{d}/a.h5", "r") as a, h5py.File(f"{d}/b.h5", "r") as b:
        for name in ("reduction/U_u", "portrait/q_u", "portrait/irf_start", "portrait/nearest_irf"):
            assert np.array_equal(a[name][:], b[name][:]), f"{name} differs after a resumed run"
    # Chains spread over MPI ranks: each rank runs its own Blender processes; the same package bytes.
    mpirun = shutil.which("mpirun")
    if mpirun:
        ranks = subprocess.run([mpirun, "--oversubscribe", "--allow-run-as-root", "-np", "3", precompute, "run", scene,
                                "-o", f"{d}/m.h5", *common], capture_output=True, text=True, timeout=600)
        assert ranks.returncode == 0, ranks.stderr[-2000:]
        assert filecmp.cmp(f"{d}/a.h5", f"{d}/m.h5", shallow=False), "3 MPI ranks wrote other package bytes"
    r = tool(precompute, "validate", scene, f"{d}/a.h5", "--schedule", "open 0.4; stop 0.6")
    assert "NRMSE" in r.stdout, r.stdout
    # Blender dying in the middle of a chain fails the run with its last lines, and writes no package.
    dying = write(d, "dying.sh", '#!/bin/bash\n# the mode follows "--": describe runs, simulate dies\n'
                  'args=("$@"); for i in "${!args[@]}"; do [[ ${args[i]} == -- ]] && mode=${args[i+1]}; done\n'
                  '[[ $mode == describe ]] && exec blender "$@"\n'
                  'echo Blender 3.4.1\necho "Error: Segmentation fault" >&2\nexit 139\n')
    os.chmod(dying, 0o755)
    r = tool(precompute, "run", scene, "-o", f"{d}/c.h5", *common, env={**os.environ, "PHASECAST_BLENDER": dying},
             expect=1)
    assert "it exited with status 139; its last lines: Blender 3.4.1 | Error: Segmentation fault" in r.stderr, \
        r.stderr[-1500:]
    assert not os.path.exists(f"{d}/c.h5"), "a failed run wrote a package"


def check_drawn_meshes(package):
    """The drawn objects are the package's static points as Blender evaluates them: the door board
    cut 8 x 8 on each face by its subdivision (flat, hard edges), the round rail (smooth sides on a
    circle of 12 mm, flat ends), not their bounding boxes."""
    with h5py.File(package, "r") as f:
        static = f["mesh/deformable"][:] == 0
        x, n = f["mesh/rest_positions"][:][static], f["mesh/normals"][:][static]
    door, rail = x[:, 2] <= 0.001, x[:, 2] > 0.001  # Blender's y in [0, 0.04] and [-0.042, -0.018]
    assert door.sum() == 6 * 9 * 9, f"{door.sum()} door points, expected 486 (6 faces of 9 x 9)"
    assert np.allclose(np.abs(n[door]).max(axis=1), 1, atol=1e-5), "the door's normals are not its faces'"
    assert rail.sum() == 4 * 16, f"{rail.sum()} rail points, expected 64 (16 per end ring, sides and ends)"
    side = np.abs(n[rail][:, 0]) < 1e-4
    radial = x[rail][side][:, 1:] - [1.864, 0.03]
    radius = np.linalg.norm(radial, axis=1)
    assert side.sum() == 32 and np.allclose(radius, 0.012, atol=1e-5), f"rail radii {radius.min()}..{radius.max()}"
    assert np.allclose(np.einsum("ij,ij->i", radial / radius[:, None], n[rail][side][:, 1:]), 1, atol=1e-3), \
        "the rail's side normals are not radial (smooth)"
    assert np.allclose(np.abs(n[rail][~side][:, 0]), 1, atol=1e-5), "the rail's ends are not flat"
    check_static_winding(package)


def check_static_winding(package):
    """Every static triangle winds counter-clockwise seen from the side its points' normals face."""
    with h5py.File(package, "r") as f:
        static = f["mesh/deformable"][:] == 0
        x, n, t = f["mesh/rest_positions"][:], f["mesh/normals"][:], f["mesh/triangles"][:]
    t = t[static[t].all(axis=1)]
    face = np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])
    facing = np.einsum("ij,ij->i", face, n[t].sum(axis=1))
    assert len(t) and (facing > 0).all(), f"{(facing <= 0).sum()} of {len(t)} static triangles face inwards"


def check_mirrored_drawn_object(precompute, d):
    """A drawn object under a mirror (negative scale) keeps its outward winding."""
    mirrored = edited_blend(d, "mirrored.blend", "bpy.data.objects['Door'].scale = (1, -1, 1)")
    scene = write(d, "mirrored.toml", scene_text(blend=mirrored))
    tool(precompute, "run", scene, "-o", f"{d}/mirrored.h5", "--chains", "1", "--irfs-per-chain", "2",
         "--no-appearance", "--no-check", "--allow-missing-entries", "-j", "1")
    check_static_winding(f"{d}/mirrored.h5")


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
               "Blender is not installed (no 'blender' on the PATH): install Debian's package 'blender'",
               env={**os.environ, "PATH": "/nonexistent"})
    fails_with(precompute, write(d, "env.toml", scene_text()), "is not an executable file",
               env={**os.environ, "PHASECAST_BLENDER": f"{d}/no-such-blender"})
    fails_with(precompute, write(d, "unknown.toml", scene_text(deformable='["Towl"]')),
               "deformable object 'Towl' is not an object of")
    fails_with(precompute, write(d, "unknown2.toml", scene_text(deformable='["Towl"]')),
               "(its objects: Door, DoorCollider, Hinge, Rail, Towel)")
    animated = edited_blend(d, "animated.blend", "bpy.data.objects['Hinge'].keyframe_insert('rotation_euler', frame=1)")
    fails_with(precompute, write(d, "animated.toml", scene_text(blend=animated)),
               "the support 'Hinge' has animation or constraints: Phasecast moves it (remove them)")
    fails_with(precompute, write(d, "body.toml", scene_text(extra='\n[[body]]\nname = "x"\n')),
               "the .blend's settings apply")
    hang = write(d, "hang.sh", "#!/bin/sh\necho Blender 3.4.1\necho reading the file\nexec sleep 60\n")
    crash = write(d, "crash.sh", "#!/bin/sh\necho Blender 3.4.1\necho Segmentation fault >&2\nexit 3\n")
    for script in (hang, crash):
        os.chmod(script, 0o755)
    timeout = scene_text().replace('support = "Hinge"', 'support = "Hinge"\ntimeout = 1')
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
        check_free_fall(precompute, d)
        check_run(precompute, scene, d)
        check_drawn_meshes(f"{d}/a.h5")
        check_mirrored_drawn_object(precompute, d)
        check_failures(precompute, d)
    print("blender simulator: ok")


if __name__ == "__main__":
    main(sys.argv[1])
