#!/usr/bin/python3
"""Checks of the committed recorded streams in tests/data/ (README.md there).

A second reader of the recording format, written from docs/protocol.md with
python3-protobuf and h5py only: it shares no code with the C++ server.

  recorded_streams.py decode RECORDING PACKAGE PROTO_DIR
      decode the file, check it against docs/protocol.md and the package
  recorded_streams.py replay-live SERVER_BIN RECORDING PACKAGE PROTO_DIR WORK
      send the recorded impulses to a fresh phasecast-server over ZeroMQ and
      require its frames to be bit-identical to the recorded ones
  recorded_streams.py golden RENDER_BIN RECORDING PACKAGE GOLDEN_DIR WORK
      render the recording with phasecast-render --replay and compare the frames
      named in GOLDEN_DIR (frame_NNNNNN.png) with those images
  recorded_streams.py make-golden RENDER_BIN RECORDING PACKAGE PROTO_DIR GOLDEN_DIR
      (re)write the golden images of a recording (only scripts/regen-test-data does)
"""
import os
import re
import signal
import subprocess
import sys
import time

MAGIC = b"PHCREC1\n"
# Golden images are compared within this tolerance: llvmpipe builds of other
# Mesa versions round a few edge pixels differently; a changed shape or light
# moves far more than this.
GOLDEN_MEAN_ABS_LIMIT = 1.0        # mean |difference| over all channels, of 255
GOLDEN_FAR_PIXELS_LIMIT = 0.005    # fraction of pixels off by more than 24 in some channel
GOLDEN_SIZE = "160x120"
GOLDEN_LIGHT = "sun"
# Closer views where the scene camera shows the behaviour too small (the toy
# is 8 cm tall on a 24 cm dashboard). Scene name from the package's attribute.
GOLDEN_VIEWS = {"toy_dashboard_tiny": ["--eye", "0.1,0.1,0.2", "--target", "0,0.035,0"]}


def load_pb(proto_dir):
    sys.path.insert(0, proto_dir)
    import phasecast_pb2 as pb
    return pb


def read_varint(data, pos):
    value = shift = 0
    while True:
        if pos >= len(data):
            return None, pos
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return value, pos
        shift += 7


def read_recording(path, pb):
    """The RecordEntry messages of a recording, in file order."""
    data = open(path, "rb").read()
    if not data.startswith(MAGIC):
        raise AssertionError(f"{path}: does not start with the magic {MAGIC!r}")
    entries, pos = [], len(MAGIC)
    while pos < len(data):
        size, start = read_varint(data, pos)
        if size is None or start + size > len(data):
            break  # a truncated final record ends the stream (docs/protocol.md)
        entry = pb.RecordEntry()
        entry.ParseFromString(data[start:start + size])
        entries.append(entry)
        pos = start + size
    return entries


def fnv1a64(path):
    h = 0xCBF29CE484222325
    for byte in open(path, "rb").read():
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def frames_of(entries):
    return [e.frame for e in entries if e.WhichOneof("entry") == "frame"]


def impulses_of(entries):
    return [e.impulse for e in entries if e.WhichOneof("entry") == "impulse"]


# ---- decode ---------------------------------------------------------------------------

def decode(recording, package, proto_dir):
    import h5py
    pb = load_pb(proto_dir)
    entries = read_recording(recording, pb)
    assert entries and entries[0].WhichOneof("entry") == "header", "the first record is not the header"
    header = entries[0].header
    assert header.format_version == 1, header.format_version
    assert header.rate_hz > 0, header.rate_hz
    assert len(header.scenes) == 1, header.scenes
    assert header.scenes[0].content_hash == fnv1a64(package), \
        f"header names content hash {header.scenes[0].content_hash:016x}, the package hashes to {fnv1a64(package):016x}"
    with h5py.File(package, "r") as f:
        r_u = f["reduction/U_u"].shape[1]
        r_a = f["appearance/U_a"].shape[1] if "appearance" in f else 0
        names = [n.decode() if isinstance(n, bytes) else n for n in f["palette/names"][:]]
        scene = f.attrs["scene"]
        scene = scene.decode() if isinstance(scene, bytes) else str(scene)
    assert header.scenes[0].scene == scene, (header.scenes[0].scene, scene)

    kinds = [e.WhichOneof("entry") for e in entries[1:]]
    assert kinds and kinds[0] == "created", f"the second record is {kinds[:1]}, expected 'created'"
    created = entries[1].created
    assert created.scene == scene and created.state.mode == 0 and created.state.palette_index == -1, created

    frames = frames_of(entries)
    assert len(frames) > 100, f"only {len(frames)} frames"
    by_frame = {}
    for i, f in enumerate(frames):
        assert f.instance == created.instance and f.scene == scene, f
        assert f.frame == created.frame + i and f.seq == frames[0].seq + i, f"frame {i}: {f.frame}, seq {f.seq}"
        assert len(f.q_u) == r_u and len(f.q_a) == r_a and len(f.support) == 12, \
            f"frame {f.frame}: {len(f.q_u)} q_u, {len(f.q_a)} q_a, {len(f.support)} support floats"
        assert -1 <= f.palette_index < len(names), f.palette_index
        by_frame[f.frame] = f

    impulses = impulses_of(entries)
    assert len(impulses) >= 2, f"only {len(impulses)} impulses"
    # Each applied impulse is written before its frame, and that frame starts an IRF of its entry.
    for pos, e in enumerate(entries):
        if e.WhichOneof("entry") != "impulse":
            continue
        imp = e.impulse
        assert imp.HasField("at_frame") and imp.WhichOneof("entry") == "index", imp
        assert 0 <= imp.index < len(names), imp
        later = [x.frame.frame for x in entries[pos + 1:] if x.WhichOneof("entry") == "frame"]
        assert later and later[0] == imp.at_frame, f"impulse at {imp.at_frame} is not written just before its frame"
        landed = by_frame[imp.at_frame]
        assert landed.palette_index == imp.index and landed.irf_t == 0 and landed.irf >= 0, landed
    moving = sum(f.palette_index >= 0 for f in frames)
    print(f"{os.path.basename(recording)}: {len(frames)} frames of '{scene}' (r_u={r_u}, r_a={r_a}), "
          f"{len(impulses)} impulses ({', '.join(names[i.index] for i in impulses)}), {moving} frames in IRFs")


# ---- replay-live ----------------------------------------------------------------------

class Server:
    """A phasecast-server process on loopback, stopped with SIGTERM."""

    def __init__(self, server_bin, args, log):
        self.proc = subprocess.Popen([server_bin, *args, "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"],
                                     stdout=subprocess.PIPE, stderr=open(log, "w"), text=True)
        m = None
        while m is None:
            line = self.proc.stdout.readline()
            if not line:
                raise AssertionError(f"the server ended before listening (log {log})")
            m = re.search(r"listening cmd=(\S+) pub=(\S+)", line)
        self.cmd = m.group(1)

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        assert self.proc.wait(30) == 0, f"server exit status {self.proc.returncode}"


class Commands:
    def __init__(self, pb, endpoint):
        import zmq
        self.pb, self.next_id = pb, 1
        self.socket = zmq.Context.instance().socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.connect(endpoint)

    def call(self, fill):
        request = self.pb.Request(id=self.next_id)
        self.next_id += 1
        fill(request)
        self.socket.send_multipart([b"", request.SerializeToString()])
        if not self.socket.poll(10000):
            raise AssertionError("no reply within 10 s")
        reply = self.pb.Reply()
        reply.ParseFromString(self.socket.recv_multipart()[-1])
        return reply

    def frame(self, instance):
        reply = self.call(lambda r: r.list_instances.SetInParent())
        return next(i.frame for i in reply.instances.instances if i.instance == instance)


def send_windows(frames, impulses, transitions):
    """For each impulse, the first frame from which it may be sent. The server
    checks a new impulse against the entry playing when it arrives
    (/palette/transitions: row 0 at rest, row i + 1 while entry i plays), so it
    is sent inside the run of frames before its own, after the previous impulse
    landed, in which every entry playing allows it."""
    entry = {f.frame: f.palette_index for f in frames}
    windows = []
    for k, imp in enumerate(impulses):
        earliest = impulses[k - 1].at_frame + 1 if k else frames[0].frame + 1
        start = imp.at_frame
        while start - 1 >= earliest and all(transitions[entry[g] + 1][imp.index] for g in (start - 2, start - 1)
                                            if g in entry):
            start -= 1
        windows.append(start)
    return windows


def replay_live(server_bin, recording, package, proto_dir, work):
    pb = load_pb(proto_dir)
    os.makedirs(work, exist_ok=True)
    import h5py
    entries = read_recording(recording, pb)
    frames, impulses = frames_of(entries), impulses_of(entries)
    instance = entries[1].created.instance
    with h5py.File(package, "r") as f:
        transitions = f["palette/transitions"][:]
    windows = send_windows(frames, impulses, transitions)
    for imp, start in zip(impulses, windows):
        assert imp.at_frame - start >= 10, \
            f"impulse at frame {imp.at_frame} leaves only {imp.at_frame - start} frames to send it in (regenerate the data)"
    fresh = os.path.join(work, "fresh.phcrec")
    if os.path.exists(fresh):
        os.remove(fresh)  # the server never replaces a file it records to
    # 60 Hz: every send window is at least 10 frames (1/6 s), a few seconds per recording.
    server = Server(server_bin, [package, "--instances", "1", "--rate", "60", "--record", fresh],
                    os.path.join(work, "server.log"))
    try:
        commands = Commands(pb, server.cmd)
        for imp, start in zip(impulses, windows):
            # Sent as early as allowed, and never later than 2 frames ahead of its frame.
            while commands.frame(instance) < start:
                time.sleep(0.005)
            now = commands.frame(instance)
            assert now + 2 <= imp.at_frame, f"too late to send the impulse for frame {imp.at_frame} (server at {now})"

            def fill(r, imp=imp):
                r.impulse.instance = imp.instance
                r.impulse.index = imp.index
                r.impulse.at_frame = imp.at_frame
            reply = commands.call(fill)
            assert reply.ok, reply.error
        while commands.frame(instance) <= frames[-1].frame:
            time.sleep(0.05)
    finally:
        server.stop()
    replayed = {f.frame: f for f in frames_of(read_recording(fresh, pb))}
    for f in frames:
        g = replayed.get(f.frame)
        assert g is not None, f"the fresh server published no frame {f.frame}"
        assert g.SerializeToString() == f.SerializeToString(), f"frame {f.frame} differs:\n{f}\nvs\n{g}"
    print(f"{os.path.basename(recording)}: {len(frames)} frames replayed bit for bit by a fresh server "
          f"({len(impulses)} impulses sent over ZeroMQ)")


# ---- golden images --------------------------------------------------------------------

def read_png(path):
    import numpy as np
    from PIL import Image
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)


def render_replay(render_bin, recording, package, out_dir):
    import h5py
    with h5py.File(package, "r") as f:
        scene = f.attrs["scene"]
    scene = scene.decode() if isinstance(scene, bytes) else str(scene)
    os.makedirs(out_dir, exist_ok=True)
    # Without the backdrop: the golden images check the scene's evaluation, not the floor behind it.
    subprocess.run([render_bin, "--replay", recording, "--package", package, "--size", GOLDEN_SIZE,
                    "--light", GOLDEN_LIGHT, "--backdrop", "off", *GOLDEN_VIEWS.get(scene, []), "--out", out_dir],
                   check=True, stdout=subprocess.DEVNULL)


def golden(render_bin, recording, package, golden_dir, work):
    import numpy as np
    names = sorted(n for n in os.listdir(golden_dir) if re.fullmatch(r"frame_\d{6}\.png", n))
    assert len(names) >= 2, f"{golden_dir}: expected at least two golden frames"
    render_replay(render_bin, recording, package, work)
    for name in names:
        want, got = read_png(os.path.join(golden_dir, name)), read_png(os.path.join(work, name))
        assert want.shape == got.shape, f"{name}: size {got.shape} vs golden {want.shape}"
        diff = np.abs(want - got)
        mean, far = diff.mean(), (diff.max(axis=2) > 24).mean()
        assert mean <= GOLDEN_MEAN_ABS_LIMIT and far <= GOLDEN_FAR_PIXELS_LIMIT, \
            f"{name}: mean |diff| {mean:.3f} (limit {GOLDEN_MEAN_ABS_LIMIT}), {100 * far:.2f}% pixels far off " \
            f"(limit {100 * GOLDEN_FAR_PIXELS_LIMIT}%); rendered frames in {work}"
        print(f"{name}: mean |diff| {mean:.3f}, {100 * far:.2f}% pixels far off")
    # The golden frames must show the scene's behaviour: they differ from each other.
    images = [read_png(os.path.join(golden_dir, n)) for n in names]
    for a, b, n in zip(images, images[1:], names[1:]):
        assert np.abs(a - b).mean() > 0.5, f"{n} looks like the frame before it: the golden set shows no motion"


def make_golden(render_bin, recording, package, proto_dir, golden_dir):
    """Renders the recording and keeps rest, the largest deformation and the
    largest support motion (or the last frame) as golden images."""
    import shutil
    import tempfile
    import numpy as np
    frames = frames_of(read_recording(recording, load_pb(proto_dir)))
    q = np.array([f.q_u for f in frames])
    s = np.array([f.support for f in frames])
    picks = [0, int(np.argmax(np.linalg.norm(q - q[0], axis=1))), int(np.argmax(np.linalg.norm(s - s[0], axis=1)))]
    if picks[2] in picks[:2]:
        picks[2] = len(frames) - 1
    with tempfile.TemporaryDirectory() as work:
        render_replay(render_bin, recording, package, work)
        shutil.rmtree(golden_dir, ignore_errors=True)
        os.makedirs(golden_dir)
        for i in sorted(set(picks)):
            name = f"frame_{frames[i].frame:06d}.png"
            shutil.copy(os.path.join(work, name), os.path.join(golden_dir, name))
            print(f"golden {os.path.join(golden_dir, name)}")


def main():
    commands = {"decode": (decode, 3), "replay-live": (replay_live, 5), "golden": (golden, 5),
                "make-golden": (make_golden, 5)}
    if len(sys.argv) < 2 or sys.argv[1] not in commands or len(sys.argv) - 2 != commands[sys.argv[1]][1]:
        print(__doc__, file=sys.stderr)
        return 2
    commands[sys.argv[1]][0](*sys.argv[2:])
    return 0


if __name__ == "__main__":
    sys.exit(main())
