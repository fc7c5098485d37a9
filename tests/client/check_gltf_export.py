#!/usr/bin/python3
"""Independent check of phasecast-export: a second reader of the .glb (struct
and json, written from the glTF 2.0 specification), h5py for the package and
python3-protobuf for the recording (tests/data/recorded_streams.py), sharing
no code with the C++ exporter.

At every recorded frame the glTF evaluation, mean + sum_k weight_k target_k
placed by the support node's animated translation and rotation, must equal
x_bar + U_u q_u (eq. 7) from the HDF5 datasets followed by the recorded
support transform, within 1e-5 relative. With --light white the vertex
colours must equal the constant-radiance exit radiance of the mean transfer.

With THREE_LOADER (scripts/gltf-validate/load-three.mjs) the same file is also
loaded by three.js's GLTFLoader under node, its AnimationMixer played to one
recorded frame (large q_u and a moved support), and the world positions
three.js gives there must equal x_bar + U_u q_u placed by the recorded support,
within 1e-5 relative: the issue's "loads in a three.js test page", without a
browser.

  check_gltf_export.py EXPORT_BIN PACKAGE RECORDING PROTO_DIR WORKDIR [THREE_LOADER]
"""
import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))
import recorded_streams  # noqa: E402  (read_recording, load_pb)

RELATIVE_TOLERANCE = 1e-5
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
DTYPES = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}


class Glb:
    """The JSON and BIN chunks of a binary glTF file, and typed accessor reads."""

    def __init__(self, path):
        data = Path(path).read_bytes()
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        assert magic == b"glTF" and version == 2, (magic, version)
        assert length == len(data), f"header length {length}, file {len(data)} bytes"
        json_len, json_type = struct.unpack_from("<II", data, 12)
        assert json_type == 0x4E4F534A, "first chunk is not JSON"
        self.json = json.loads(data[20:20 + json_len])
        bin_start = 20 + json_len
        bin_len, bin_type = struct.unpack_from("<II", data, bin_start)
        assert bin_type == 0x004E4942, "second chunk is not BIN"
        self.bin = data[bin_start + 8:bin_start + 8 + bin_len]

    def accessor(self, index):
        a = self.json["accessors"][index]
        view = self.json["bufferViews"][a["bufferView"]]
        assert view.get("byteStride", 0) == 0, "interleaved views are not expected"
        n = COMPONENTS[a["type"]]
        offset = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        values = np.frombuffer(self.bin, dtype=DTYPES[a["componentType"]], count=a["count"] * n, offset=offset)
        return values.reshape(a["count"], n) if n > 1 else values

    def node_named(self, name):
        return next(i for i, n in enumerate(self.json["nodes"]) if n.get("name") == name)


def quaternion_matrix(q):
    x, y, z, w = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_package(path):
    with h5py.File(path, "r") as f:
        return {
            "x_bar": f["reduction/mean_shape"][:].astype(np.float64),
            "U_u": f["reduction/U_u"][:].astype(np.float64),
            "attached": f["mesh/attached"][:].astype(bool),
            "dt": float(f.attrs["dt"]),
            "M_bar": f["appearance/mean_transfer"][:].astype(np.float64) if "appearance" in f else None,
        }


def recorded_frames(recording, proto_dir):
    """(frame number, q_u, 3x4 support) of the first instance with frames."""
    pb = recorded_streams.load_pb(proto_dir)
    frames = [e.frame for e in recorded_streams.read_recording(recording, pb) if e.HasField("frame")]
    instance = frames[0].instance
    return [(f.frame, np.array(f.q_u, dtype=np.float64),
             np.array(f.support, dtype=np.float64).reshape(3, 4) if len(f.support) else np.eye(3, 4))
            for f in frames if f.instance == instance]


def animation_outputs(glb, node_support, node_mesh):
    """Keyframe times, weights (frames x r_u), translations and rotations."""
    anim = glb.json["animations"][0]
    out = {}
    for ch in anim["channels"]:
        sampler = anim["samplers"][ch["sampler"]]
        assert sampler["interpolation"] == "LINEAR", sampler
        out["times"] = glb.accessor(sampler["input"])
        key = (ch["target"]["node"], ch["target"]["path"])
        out[key] = glb.accessor(sampler["output"])
    return (out["times"], out[(node_mesh, "weights")], out[(node_support, "translation")],
            out[(node_support, "rotation")])


def check_positions(glb, pkg, frames):
    support, mesh_node = glb.node_named("support"), glb.json["nodes"][glb.node_named("support")]["children"][0]
    prim = glb.json["meshes"][glb.json["nodes"][mesh_node]["mesh"]]["primitives"][0]
    mean = glb.accessor(prim["attributes"]["POSITION"]).astype(np.float64)
    targets = np.stack([glb.accessor(t["POSITION"]).astype(np.float64) for t in prim["targets"]])
    r_u = pkg["U_u"].shape[1]
    assert targets.shape[0] == r_u, f"{targets.shape[0]} morph targets, r_u = {r_u}"
    times, weights, translations, rotations = animation_outputs(glb, support, mesh_node)
    weights = weights.reshape(len(frames), r_u)
    first = frames[0][0]
    expected_times = np.array([(n - first) * pkg["dt"] for n, _, _ in frames])
    assert np.allclose(times, expected_times, rtol=1e-6, atol=1e-6), "keyframe times are not (frame - first) * dt"

    # Vertex i of the support's mesh is the i-th attached point (docs/gltf.md).
    S = pkg["attached"].size
    x_all = pkg["x_bar"].reshape(S, 3)
    scale = np.abs(x_all).max()
    worst_local = worst_world = 0.0
    for i, (_, q_u, support_3x4) in enumerate(frames):
        # The package side: eq. 7 from the HDF5 datasets, q_u from the recording.
        x = (pkg["x_bar"] + pkg["U_u"] @ q_u).reshape(S, 3)[pkg["attached"]]
        world_ref = x @ support_3x4[:, :3].T + support_3x4[:, 3]
        # The glTF side: morph targets, then the support node's TRS.
        local = mean + np.tensordot(weights[i].astype(np.float64), targets, axes=1)
        world = local @ quaternion_matrix(rotations[i]).T + translations[i].astype(np.float64)
        worst_local = max(worst_local, np.abs(local - x).max())
        worst_world = max(worst_world, np.abs(world - world_ref).max())
    assert np.abs(weights).max() > 0, "the morph weights never move: nothing was checked"
    assert worst_local <= RELATIVE_TOLERANCE * scale, f"support frame: worst error {worst_local:.3g} (scale {scale:.3g})"
    assert worst_world <= RELATIVE_TOLERANCE * scale, f"world: worst error {worst_world:.3g} (scale {scale:.3g})"
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(rotations[:, 3]), 0, 1))).max()
    print(f"positions match at all {len(frames)} frames: worst error {worst_local:.3g} (support frame), "
          f"{worst_world:.3g} (world), scene scale {scale:.3g}; largest |q_u| {np.abs(weights).max():.3g}, "
          f"support turned up to {angle:.1f} deg, moved up to {np.abs(translations).max():.3g}")
    return prim


def check_white_colours(glb, pkg, prim):
    """White furnace: only k = 0 sees light, L_0 = 4 pi Y_0 in every channel."""
    if pkg["M_bar"] is None:
        return
    S = pkg["attached"].size
    expected = pkg["M_bar"].reshape(S, 3, 16)[:, :, 0] * 4 * np.pi * 0.2820947917738781
    expected = np.clip(expected, 0, 1)[pkg["attached"]]
    colours = glb.accessor(prim["attributes"]["COLOR_0"])
    assert np.allclose(colours, expected, rtol=1e-5, atol=1e-6), np.abs(colours - expected).max()
    print(f"vertex colours match M_bar . L (white light) at {len(colours)} points")


def package_world_positions(pkg, frame):
    """x_bar + U_u q_u (eq. 7) of the attached points, then the support transform."""
    _, q_u, support_3x4 = frame
    x = (pkg["x_bar"] + pkg["U_u"] @ q_u).reshape(pkg["attached"].size, 3)[pkg["attached"]]
    return x @ support_3x4[:, :3].T + support_3x4[:, 3]


def run_loader(command, expect_status, what):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != expect_status:
        sys.stdout.write(result.stdout)
        sys.stderr.write(result.stderr)
        raise AssertionError(f"load-three.mjs {what}: exit status {result.returncode}, expected {expect_status}")
    return result


def check_three(loader, glb_path, pkg, frames, work):
    """three.js's GLTFLoader and AnimationMixer at one recorded frame against eq. 7."""
    node = shutil.which("node")
    assert node, "node is not installed (scripts/install-deps installs it)"
    modules = Path(loader).resolve().parent / "node_modules"
    assert (modules / "three").is_dir(), \
        f"three.js is not installed in {modules}: run npm ci --prefix {modules.parent}"
    # One frame where both the morph weights and the support's motion are large
    # (each relative to its largest over the session), so that three.js's
    # morphing and its node transform are both exercised; by |q_u| alone when
    # the support never moves (toy_dashboard).
    q = np.array([np.abs(q_u).max() for _, q_u, _ in frames])
    moved = np.array([np.abs(support - np.eye(3, 4)).max() for _, _, support in frames])
    index = int(np.argmax(q / q.max() * (moved / moved.max() if moved.max() > 0 else 1)))
    expected = package_world_positions(pkg, frames[index])
    scale = np.abs(pkg["x_bar"]).max()  # the same scale as check_positions
    r_u = pkg["U_u"].shape[1]
    expected_json, three_json = work / "three_expected.json", work / "three_positions.json"
    expected_json.write_text(json.dumps({"positions": expected.tolist()}))
    base = [node, str(loader), str(glb_path), "--keyframe", str(index)]
    # The loader's own comparison (relative to its max |coordinate|) ...
    result = run_loader(base + ["--r-u", str(r_u), "--expected", str(expected_json), "--out", str(three_json)],
                        0, f"at keyframe {index}")
    sys.stdout.write(result.stdout)
    # ... and ours, on the positions it wrote, relative to the scene scale.
    got = np.array(json.loads(three_json.read_text())["positions"], dtype=np.float64)
    assert got.shape == expected.shape, f"three.js gave {got.shape} positions, expected {expected.shape}"
    worst = np.abs(got - expected).max()
    assert worst <= RELATIVE_TOLERANCE * scale, f"three.js: worst error {worst:.3g} (scale {scale:.3g})"
    print(f"three.js at recorded frame {frames[index][0]} (keyframe {index}, largest |q_u| {q[index]:.3g}, "
          f"support moved {moved[index]:.3g} from the identity): worst error {worst:.3g} against "
          f"x_bar + U_u q_u and the recorded support, scale {scale:.3g}")

    # The loader fails when it should: a wrong r_u, positions off by 1e-3 of the scene.
    run_loader(base + ["--r-u", str(r_u + 1)], 1, "with a wrong --r-u")
    off = expected.copy()
    off[len(off) // 2, 1] += 1e-3 * scale
    expected_json.write_text(json.dumps({"positions": off.tolist()}))
    run_loader(base + ["--expected", str(expected_json)], 1, "with one position moved")
    run_loader([node, str(loader)], 2, "without a file")


def main(export_bin, package, recording, proto_dir, workdir, three_loader=None):
    work = Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    out = work / "session.glb"
    subprocess.run([export_bin, package, "-o", str(out), "--recording", recording, "--light", "white"],
                   check=True, stdout=subprocess.DEVNULL)
    glb, pkg = Glb(out), read_package(package)
    frames = recorded_frames(recording, proto_dir)
    prim = check_positions(glb, pkg, frames)
    check_white_colours(glb, pkg, prim)
    if three_loader:
        check_three(three_loader, out, pkg, frames, work)


if __name__ == "__main__":
    if len(sys.argv) not in (6, 7):
        sys.exit(__doc__)
    main(*sys.argv[1:])
