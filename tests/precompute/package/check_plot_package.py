#!/usr/bin/python3
"""scripts/plot-package on the synthetic plate package: both PNGs are written
and are real PNG images; a file that is not a package gets one error line."""
import os
import subprocess
import sys

fixture_tool, plot_script, work = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(work, exist_ok=True)
package = os.path.join(work, "plate.h5")
subprocess.run([fixture_tool, "-o", package], check=True, capture_output=True)
done = subprocess.run([plot_script, package], capture_output=True, text=True)
assert done.returncode == 0, done.stderr
for suffix in ("-spectrum.png", "-portrait.png"):
    path = package[:-3] + suffix
    with open(path, "rb") as f:
        head = f.read(8)
    assert head == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    assert os.path.getsize(path) > 5000, f"{path} is suspiciously small"

not_package = os.path.join(work, "not-a-package.h5")
with open(not_package, "w") as f:
    f.write("hello")
bad = subprocess.run([plot_script, not_package], capture_output=True, text=True)
assert bad.returncode == 1, bad.returncode
assert bad.stderr.count("\n") == 1 and "cannot open as HDF5" in bad.stderr, bad.stderr
print("plot-package ok")
