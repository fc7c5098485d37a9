#!/usr/bin/python3
"""A format_version 1 package (format_v1/cloth_door.h5, written by the build of
2026-11-28 before version 2) still loads, inspects with the figures that build
printed (cloth_door.inspect.json/.txt, its own output) and serves frames.
h5py reads its positional /appearance/held_out_error independently and the
named figures of phasecast-inspect --json must match them position by
position (docs/package-format.md, "Older versions")."""
import json
import os
import re
import signal
import subprocess
import sys

import h5py
import zmq

V1_ORDER = ["total", "truncation", "interpolation", "of_transfer", "l2_total", "l2_truncation",
            "clusters_l2_truncation", "l2_floor", "of_variation", "l2_of_variation", "l2_floor_of_variation"]


def check_inspect(inspect, package, expected_json, expected_text):
    r = subprocess.run([inspect, package, "--json"], capture_output=True, text=True, check=True)
    got = json.loads(r.stdout)
    got.pop("file")
    want = json.load(open(expected_json))
    for key in sorted(want):
        assert got.get(key) == want.get(key), (key, got.get(key), want.get(key))
    for key in sorted(set(got) - set(want)):  # figures added since, none of which a v1 package holds
        assert got[key] is None, (key, got[key])
    text = subprocess.run([inspect, package], capture_output=True, text=True, check=True).stdout
    assert text.split("\n", 1)[1] == open(expected_text).read(), text
    return got["held_out"]


def check_by_position(package, held_out):
    with h5py.File(package, "r") as f:
        assert int(f.attrs["format_version"]) == 1
        a = f["appearance"]
        figures = a["held_out_error"][:]
        assert len(figures) == 11, len(figures)
        for name, value in zip(V1_ORDER, figures):
            assert held_out[name] == float(value), (name, held_out[name], float(value))
        assert held_out["l2_spread"] == [float(v) for v in a["held_out_spread"][:]]
        assert held_out["l2_truncation_curve"] == [float(v) for v in a["held_out_truncation_curve"][:]]
        assert held_out["nodes"] == len(a["held_out_nodes"])
    assert len(set(held_out[n] for n in V1_ORDER)) == 11, "not vacuous: every figure differs"


def check_serves(server_bin, package):
    server = subprocess.Popen([server_bin, package, "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"],
                              stdout=subprocess.PIPE, text=True)
    try:
        m = None
        while m is None:
            line = server.stdout.readline()
            assert line, "server exited before listening"
            m = re.search(r"listening cmd=(\S+) pub=(\S+)", line)
        ctx = zmq.Context()
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.SUBSCRIBE, b"inst/1/")
        sub.connect(m.group(2))
        assert sub.poll(10000), "no frame within 10 s"
        topic, payload = sub.recv_multipart()
        assert topic == b"inst/1/" and payload, topic
        sub.close(0)
        ctx.term()
    finally:
        server.send_signal(signal.SIGINT)
        server.communicate(timeout=20)
    assert server.returncode == 0, server.returncode


def main(inspect, server_bin, folder):
    package = os.path.join(folder, "cloth_door.h5")
    held_out = check_inspect(inspect, package, os.path.join(folder, "cloth_door.inspect.json"),
                             os.path.join(folder, "cloth_door.inspect.txt"))
    check_by_position(package, held_out)
    check_serves(server_bin, package)
    print("ok: the version 1 package inspects as before, its figures read by name, and it serves")


if __name__ == "__main__":
    main(*sys.argv[1:4])
