#!/usr/bin/python3
"""The server under a crowd of idle peers (issue 50, item 6): with few
descriptors and many TCP connections that never send a ZeroMQ greeting, a
real client is still answered, because the server drops peers that do not
finish the handshake within --handshake-timeout. Also: the server raises its
soft descriptor limit to the hard limit and says so.

Usage: check_server_crowd.py SERVER MAKE_FIXTURE PROTO_DIR WORK"""
import os
import re
import resource
import socket
import subprocess
import sys
import time

import zmq

IDLE = 300  # idle connections: far more than the 96 descriptors the server may hold


def start(server_bin, package, limits, extra):
    def limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, limits)
    server = subprocess.Popen([server_bin, package, "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*",
                               *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              preexec_fn=limit)
    lines = []
    deadline = time.time() + 30
    while time.time() < deadline:
        line = server.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"listening cmd=(\S+) pub=(\S+)", line)
        if m:
            return server, m.group(1), lines
    server.kill()
    raise AssertionError(f"the server did not start: {''.join(lines)} {server.stderr.read()}")


def idle_crowd(endpoint, count):
    host, port = endpoint.removeprefix("tcp://").rsplit(":", 1)
    crowd = []
    for _ in range(count):
        s = socket.socket()
        s.setblocking(False)
        try:
            s.connect((host, int(port)))
        except BlockingIOError:
            pass  # in the kernel's backlog: the server has not accepted it (yet)
        crowd.append(s)
    return crowd


def answered_within(endpoint, pb, seconds):
    """Seconds until a list_scenes request was answered, or None."""
    context = zmq.Context.instance()
    dealer = context.socket(zmq.DEALER)
    dealer.setsockopt(zmq.LINGER, 0)
    dealer.connect(endpoint)
    request = pb.Request(id=7, list_scenes=pb.ListScenes())
    start = time.time()
    dealer.send_multipart([b"", request.SerializeToString()])
    try:
        if not dealer.poll(int(seconds * 1000)):
            return None
        _, payload = dealer.recv_multipart()
        reply = pb.Reply()
        reply.ParseFromString(payload)
        assert reply.ok and reply.scenes.scenes[0].name == "plate", reply
        return time.time() - start
    finally:
        dealer.close()


def main(server_bin, make_fixture, proto_dir, work):
    sys.path.insert(0, proto_dir)
    import phasecast_pb2 as pb
    os.makedirs(work, exist_ok=True)
    package = os.path.join(work, "plate.h5")
    subprocess.run([make_fixture, "-o", package], check=True, stdout=subprocess.DEVNULL)

    # 96 descriptors, soft and hard: the idle crowd uses them all up.
    server, cmd, _ = start(server_bin, package, (96, 96), ["--handshake-timeout", "1"])
    crowd = idle_crowd(cmd, IDLE)
    try:
        time.sleep(0.5)
        took = answered_within(cmd, pb, 20)
        assert took is not None, f"a real client was not answered within 20 s beside {IDLE} idle connections"
        assert server.poll() is None, "the server died under the crowd"
        print(f"answered in {took:.2f} s beside {IDLE} idle connections, 96 descriptors")
    finally:
        for s in crowd:
            s.close()
        server.terminate()
        server.wait(10)

    # A low soft limit under a higher hard one is raised, and said so.
    server, cmd, lines = start(server_bin, package, (64, 4096), [])
    try:
        said = [l for l in lines if "descriptor limit" in l]
        assert said == ["phasecast-server: descriptor limit raised from 64 to 4096\n"], lines
        crowd = idle_crowd(cmd, IDLE)
        took = answered_within(cmd, pb, 10)
        assert took is not None, "not answered with the raised limit"
        for s in crowd:
            s.close()
    finally:
        server.terminate()
        server.wait(10)
    print("ok")


if __name__ == "__main__":
    main(*sys.argv[1:5])
