#!/usr/bin/python3
"""docs/your-first-scene.md cannot rot: its ```sh blocks, in order, run as
one bash script exactly as written, with three substitutions a machine needs:
the tools come from this build, HOME is a scratch folder, and the server's
ports are free ones. Then what the reader is promised must be there: the
contact sheets, a package inspect accepted, validate's figures, served frames
and a glTF file."""
import json
import os
import re
import signal
import socket
import subprocess
import sys
from pathlib import Path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(source_dir: str, bin_dir: str, workdir: str) -> None:
    source, work, bin_dir = Path(source_dir).resolve(), Path(workdir), str(Path(bin_dir).resolve())
    text = (source / "docs" / "your-first-scene.md").read_text()
    blocks = re.findall(r"```sh\n(.*?)```", text, re.S)
    assert len(blocks) >= 6, f"{len(blocks)} sh blocks"
    script = "\n".join(blocks)
    script = script.replace('"$PWD/build/bin:$PWD/scripts:$PATH"', f'"{bin_dir}:{source / "scripts"}:$PATH"')
    cmd, pub = free_port(), free_port()
    script = script.replace("127.0.0.1:5590", f"127.0.0.1:{cmd}").replace("127.0.0.1:5591", f"127.0.0.1:{pub}")
    home = work / "home"
    subprocess.run(["rm", "-rf", str(work)], check=True)
    home.mkdir(parents=True)
    env = dict(os.environ, HOME=str(home))
    (work / "tutorial.sh").write_text(script)
    log = work / "tutorial.log"
    # Output to a file, not a pipe, and in a session of its own: a server the
    # script leaves behind when it fails holds no pipe open and is killed here.
    with open(log, "w") as out:
        p = subprocess.Popen(["bash", "-euo", "pipefail", str(work / "tutorial.sh")], cwd=source, env=env,
                             stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
        try:
            code = p.wait(timeout=900)
        finally:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    output = log.read_text()
    assert code == 0, f"the tutorial failed (exit {code}); its output: {log}\n{output[-3000:]}"
    folder = home / "curtain"
    for name in ["curtain.obj", "curtain.toml", "sim.png", "curtain.h5", "validation.json", "validation.png",
                 "served.png", "curtain.glb"]:
        assert (folder / name).is_file() and (folder / name).stat().st_size > 0, f"missing {name}"
    assert len(list((folder / "sim").glob("frame_*.png"))) >= 100
    assert len(list((folder / "served").glob("frame_*.png"))) == 150
    assert "back within" in output and "neutral mode" not in output, "check found the curtain's rest"
    for line in ["in the package", "fidelity (2 random schedules", "wrote curtain.h5", "random schedules: median NRMSE"]:
        assert line in output, f"the tutorial's output lacks '{line}'"
    report = json.loads((folder / "validation.json").read_text())
    assert report["summary_random"]["moving_segments"] > 0, "validate measured moving segments"
    print(f"tutorial ran: {len(blocks)} blocks, files in {folder}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
