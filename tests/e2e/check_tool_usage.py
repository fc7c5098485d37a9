#!/usr/bin/env python3
"""Every tool answers --help, and a command-line error is one line naming the tool.

  check_tool_usage.py SOURCE_DIR BIN_DIR

For each phasecast-* tool (the benchmark drivers too): --help exits 0 with the options on
stdout; an unknown option, a value that does not convert and a missing file
each print exactly one line "<tool>: ... (see --help)" on stderr, nothing on
stdout, and exit 2 (bad usage), never CLI11's two lines and its own codes.
The scripts whose header comment is their usage (scripts/lib/help.sh) print
that comment for --help and exit 0 without installing or building anything.
"""
import os
import subprocess
import sys

source, bin_dir = sys.argv[1], sys.argv[2]
failures = []


def check(ok, what):
    if not ok:
        failures.append(what)


def run(argv):
    return subprocess.run(argv, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)


missing = "/no/such/file.h5"
# tool -> (arguments before the bad one, an option taking a number, an argument naming a file)
tools = {
    "phasecast-precompute": (["reduce"], "--rank", ["reduce", missing, "orbits.h5", "-o", "/tmp/x.h5"]),
    "phasecast-server": ([], "--rate", [missing]),
    "phasecast-render": ([], "--frames", ["--package", missing]),
    "phasecast-export": ([], "--instance", [missing, "-o", "/tmp/x.glb"]),
    "phasecast-console": ([], "--timeout", [missing]),
    "phasecast-gateway": ([], "--connect-timeout", ["--server-key", missing]),
    "phasecast-inspect": ([], "--rank", [missing]),
    "phasecast-keygen": ([], None, None),
    "phasecast-fuzz-requests": ([], "--iterations", ["--package", missing]),
    "phasecast-fuzz-package": ([], "--iterations", ["--package", missing]),
    "phasecast-make-fixture": ([], None, None),
    "phasecast-bench-svd": ([], None, None),
    "phasecast-bench-irf-cache": ([], None, None),
    "phasecast-bench-orbit-svd": ([], None, None),
    "phasecast-bench-reduce-memory": ([], None, None),
    "phasecast-bench-server-load": ([], None, None),
}
for tool, (prefix, number_option, missing_file) in tools.items():
    path = os.path.join(bin_dir, tool)
    r = run([path] + prefix + ["--help"])
    check(r.returncode == 0 and ("Usage" in r.stdout or "OPTIONS" in r.stdout),
          f"{tool} {' '.join(prefix)} --help: exit {r.returncode}, stdout {r.stdout[:200]!r}")
    cases = [prefix + ["--no-such-option"]]
    if number_option:
        cases.append(prefix + [number_option, "many"])
    for args in cases:
        r = run([path] + args)
        lines = r.stderr.splitlines()
        check(r.returncode == 2, f"{tool} {args}: exit {r.returncode}, expected 2 (stderr {r.stderr!r})")
        check(len(lines) == 1 and lines[0].startswith(tool + ": ") and lines[0].endswith("(see --help)"),
              f"{tool} {args}: stderr {r.stderr!r}, expected one line '{tool}: ... (see --help)'")
        check(r.stdout == "", f"{tool} {args}: stdout {r.stdout!r}, expected nothing")
    if missing_file:
        # Checked on the command line (2) or when the tool opens it (1): one line naming it either way.
        r = run([path] + missing_file)
        lines = r.stderr.splitlines()
        check(r.returncode in (1, 2), f"{tool} {missing_file}: exit {r.returncode} (stderr {r.stderr!r})")
        check(len(lines) == 1 and lines[0].startswith(tool + ": ") and missing in lines[0],
              f"{tool} {missing_file}: stderr {r.stderr!r}, expected one line '{tool}: ...' naming {missing}")

for script in ["install-deps", "build", "test", "test-sanitizers", "build-web"]:
    path = os.path.join(source, "scripts", script)
    with open(path) as f:
        header = f.read().splitlines()[1]
    r = run([path, "--help"])
    check(r.returncode == 0, f"scripts/{script} --help: exit {r.returncode}")
    check(r.stdout.splitlines()[:1] == [header[2:]], f"scripts/{script} --help: stdout {r.stdout[:200]!r}")
    check(r.stderr == "", f"scripts/{script} --help: stderr {r.stderr[:200]!r} (did it install or build?)")

for f in failures:
    print("FAIL:", f)
print(f"{len(failures)} failure(s)")
sys.exit(1 if failures else 0)
