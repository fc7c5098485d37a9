#!/usr/bin/python3
"""A separate subscriber process, independent of the C++ client code: starts
phasecast-server on loopback, decodes its frames with python3-protobuf, sends
an impulse from a DEALER, downloads U_u in chunks and compares it with h5py's
reading of the package, then stops the server with SIGINT."""
import os
import re
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import zmq


def recv_frame(sub, pb):
    if not sub.poll(10000):
        raise AssertionError("no frame within 10 s")
    topic, payload = sub.recv_multipart()
    frame = pb.Frame()
    frame.ParseFromString(payload)
    assert topic == f"inst/{frame.instance}/".encode(), topic
    return frame


def call(dealer, pb, request):
    dealer.send_multipart([b"", request.SerializeToString()])
    if not dealer.poll(10000):
        raise AssertionError("no reply within 10 s")
    _, payload = dealer.recv_multipart()
    reply = pb.Reply()
    reply.ParseFromString(payload)
    assert reply.id == request.id, (reply.id, request.id)
    return reply


def main(server_bin, make_fixture, proto_dir, work):
    sys.path.insert(0, proto_dir)
    import phasecast_pb2 as pb

    os.makedirs(work, exist_ok=True)
    package = os.path.join(work, "plate.h5")
    subprocess.run([make_fixture, "-o", package], check=True, stdout=subprocess.DEVNULL)
    server = subprocess.Popen([server_bin, package, "--rate", "100", "--cmd", "tcp://127.0.0.1:*",
                               "--pub", "tcp://127.0.0.1:*"], stdout=subprocess.PIPE, text=True)
    try:
        m = None
        while m is None:
            line = server.stdout.readline()
            assert line, "server exited before listening"
            m = re.search(r"listening cmd=(\S+) pub=(\S+)", line)
        cmd, pub = m.group(1), m.group(2)
        ctx = zmq.Context()
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.SUBSCRIBE, b"inst/1/")
        sub.connect(pub)
        dealer = ctx.socket(zmq.DEALER)
        dealer.connect(cmd)

        first = recv_frame(sub, pb)
        second = recv_frame(sub, pb)
        assert second.seq == first.seq + 1 and second.frame == first.frame + 1
        assert first.scene == "plate" and len(first.q_u) == 4 and len(first.support) == 12
        assert first.palette_index == -1 and first.irf == -1

        req = pb.Request(id=11)
        req.impulse.instance = 1
        req.impulse.name = b"open"
        reply = call(dealer, pb, req)
        assert reply.ok, reply.error
        at = reply.impulse.at_frame
        frame = recv_frame(sub, pb)
        while frame.frame < at:
            assert frame.palette_index == -1
            frame = recv_frame(sub, pb)
        assert frame.frame == at and frame.palette_index == 2 and frame.irf_t == 0, frame

        # Thin-client basis download of U_u, compared with the package as h5py reads it.
        data = b""
        total = None
        while total is None or len(data) < total:
            req = pb.Request(id=12)
            req.basis.scene = b"plate"
            req.basis.part = pb.U_U
            req.basis.offset = len(data)
            req.basis.max_bytes = 256
            reply = call(dealer, pb, req)
            assert reply.ok, reply.error
            total = reply.basis.total_bytes
            data += reply.basis.data
        info = reply.basis.info
        U = np.frombuffer(data, dtype="<f4").reshape(tuple(info.shape))
        with h5py.File(package, "r") as f:
            assert np.array_equal(U, f["reduction/U_u"][:])
            mean = f["reduction/mean_shape"][:]
        x = mean + U @ np.asarray(frame.q_u, dtype=np.float32)  # eq. 7
        assert np.all(np.isfinite(x))

        bad = pb.Request(id=13)
        bad.impulse.instance = 1
        bad.impulse.name = b"opn"
        reply = call(dealer, pb, bad)
        assert not reply.ok
        assert reply.error == "impulse: instance 1 (plate): unknown palette entry 'opn' " \
                              "(expected one of close, stop, open)", reply.error
        dealer.close(0)
        sub.close(0)
        ctx.term()
    finally:
        server.send_signal(signal.SIGINT)
        out, _ = server.communicate(timeout=20)
    assert server.returncode == 0, server.returncode
    assert "phasecast-server: stopped after" in out, out

    # A package of another format version fails at start with one clear line.
    future = os.path.join(work, "future.h5")
    with open(package, "rb") as src, open(future, "wb") as dst:
        dst.write(src.read())
    with h5py.File(future, "r+") as f:
        f.attrs["format_version"] = np.int32(3)
    r = subprocess.run([server_bin, future, "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 1, r.returncode
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("phasecast-server: "), r.stderr
    assert "future.h5" in r.stderr and "unknown format_version 3 (this build reads 1 to 2)" in r.stderr, r.stderr
    print("ok: frames decoded, impulse landed in frame", at, "and U_u downloaded")


if __name__ == "__main__":
    main(*sys.argv[1:5])
