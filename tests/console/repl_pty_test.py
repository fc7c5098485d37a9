#!/usr/bin/python3
"""REPL smoke test under a pseudo-terminal: expressions are shown, help()
prints, Ctrl-C cancels a running wait() without ending the console, and
Ctrl-D quits with status 0. Needs no server: nothing here talks to one."""
import os
import pty
import select
import sys
import time


class Terminal:
    """Reads a pty, keeping what follows each awaited text for the next wait."""

    def __init__(self, fd):
        self.fd, self.pending = fd, b""

    def expect(self, needle, timeout=10.0):
        data = self.pending
        end = time.time() + timeout
        while needle.encode() not in data:
            left = end - time.time()
            if left <= 0:
                raise AssertionError(f"timed out waiting for {needle!r}; got {data.decode(errors='replace')!r}")
            ready, _, _ = select.select([self.fd], [], [], left)
            if ready:
                try:
                    chunk = os.read(self.fd, 4096)
                except OSError:
                    break
                if not chunk:
                    break
                data += chunk
        at = data.find(needle.encode())
        if at < 0:
            raise AssertionError(f"output ended before {needle!r}; got {data.decode(errors='replace')!r}")
        self.pending = data[at + len(needle):]


def main(console):
    pid, fd = pty.fork()
    if pid == 0:
        os.environ["HOME"] = "/tmp"
        os.execv(console, [console, "--connect", "tcp://127.0.0.1:9", "--timeout", "100", "--attempts", "1"])
    term = Terminal(fd)
    term.expect("phasecast> ")
    os.write(fd, b"1 + 2\n")
    term.expect("3")
    term.expect("phasecast> ")
    os.write(fd, b"help()\n")
    term.expect("wait_frames")
    term.expect("phasecast> ")
    os.write(fd, b"wait(30)\n")
    time.sleep(0.5)
    os.write(fd, b"\x03")  # Ctrl-C cancels the wait
    term.expect("interrupted")
    os.write(fd, b"print('still' .. 'here')\n")
    term.expect("stillhere")
    term.expect("phasecast> ")
    os.write(fd, b"\x04")  # Ctrl-D
    _, status = os.waitpid(pid, 0)
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, f"status {status}"
    print("repl ok")


if __name__ == "__main__":
    main(sys.argv[1])
