#!/usr/bin/env python3
"""Rejection paths of scripts/demo and scripts/lib/drive_impulses.py, and one
driven sequence against the real phasecast-server.

  check_demo_scripts.py SOURCE_DIR BIN_DIR PROTO_DIR WORK_DIR
"""
import os
import shutil
import subprocess
import sys
import time

source, bin_dir, proto_dir, work = sys.argv[1:5]
demo = os.path.join(source, "scripts", "demo")
driver = os.path.join(source, "scripts", "lib", "drive_impulses.py")
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what)


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=60, **kw)


# scripts/demo checks its arguments before installing or building anything.
for args, message in [
    (["--bogus"], "demo: unknown argument '--bogus' (expected --scene, --tiny, --frames, --size, --full-sampling, --help)"),
    (["--frames", "x"], "demo: --frames 'x' is not a positive whole number"),
    (["--size", "big"], "demo: --size 'big' is not WxH (e.g. 320x240)"),
    (["--scene", "nope"], "demo: scene 'nope' has no file " + os.path.join(source, "scenes", "nope.toml")),
]:
    r = run([demo] + args)
    lines = r.stderr.strip().splitlines()
    check(r.returncode == 2, f"scripts/demo {args}: exit {r.returncode}, expected 2")
    check(len(lines) == 1 and lines[0].startswith(message), f"scripts/demo {args}: stderr {r.stderr!r}")
r = run([demo, "--help"])
check(r.returncode == 0 and "--tiny" in r.stdout, f"scripts/demo --help: {r.returncode} {r.stdout!r}")

# The driver refuses a malformed sequence without contacting anyone.
r = run([sys.executable, driver, "tcp://127.0.0.1:1", proto_dir, "--sequence", "open"])
check(r.returncode == 1 and r.stderr.strip() ==
      "drive_impulses: --sequence: step 'open' is not ENTRY@FRAME_OFFSET (e.g. open@0)", f"bad sequence: {r.stderr!r}")

# Against the real server: an unknown instance, an unknown entry, then a sequence.
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
package = os.path.join(work, "plate.h5")
subprocess.run([os.path.join(bin_dir, "phasecast-make-fixture"), "-o", package], check=True, capture_output=True)
server = subprocess.Popen([os.path.join(bin_dir, "phasecast-server"), package, "--instances", "1", "--rate", "60",
                           "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
try:
    cmd = None
    deadline = time.time() + 30
    while cmd is None and time.time() < deadline:
        line = server.stdout.readline()
        if "listening cmd=" in line:
            cmd = line.split("cmd=")[1].split()[0]
    check(cmd is not None, "server did not announce its endpoints")

    r = run([sys.executable, driver, cmd, proto_dir, "--instance", "9"])
    check(r.returncode == 1 and r.stderr.strip() == "drive_impulses: --instance 9: no such instance on the server",
          f"unknown instance: {r.stderr!r}")

    r = run([sys.executable, driver, cmd, proto_dir, "--sequence", "opn@0"])
    check(r.returncode == 0 and "drive: refused: impulse: instance 1 (plate): unknown palette entry 'opn'" in r.stdout,
          f"unknown entry: {r.returncode} {r.stdout!r} {r.stderr!r}")

    stats = os.path.join(work, "stats.json")
    r = run([sys.executable, driver, cmd, proto_dir, "--sequence", "open@0 stop@10", "--stats-out", stats])
    check(r.returncode == 0 and "drive: 2 impulses queued, 0 refused at queue time" in r.stdout,
          f"sequence: {r.returncode} {r.stdout!r} {r.stderr!r}")
    import json
    s = json.load(open(stats)) if os.path.exists(stats) else {}
    check(int(s.get("impulses_applied", 0)) == 2, f"stats after the sequence: {s}")
finally:
    server.terminate()
    server.wait(timeout=30)

if failures:
    sys.exit(f"{len(failures)} check(s) failed")
print("demo scripts: all checks passed")
