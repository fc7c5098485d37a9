#!/usr/bin/env python3
"""Sends a small built-in impulse sequence to one instance of phasecast-server.

Stands in for the Lua console script scenes/scripts/door_open_close.lua until
phasecast-console lands. Impulses are scheduled by frame (Impulse.at_frame),
so the same sequence lands in the same frames however loaded the machine is.

  drive_impulses.py CMD_ENDPOINT PROTO_DIR [--instance 1] [--sequence "open@0 stop@40 ..."]
                    [--stats-out stats.json]

Each step is ENTRY@OFFSET: palette entry ENTRY in frame start + OFFSET, where
start is a few frames after the instance's current frame. Each impulse is sent
about three frames ahead of its frame, so the server checks it against the
entry playing then. A step the palette
refuses is reported on stdout and counted; it does not end the run (the IRF
before it may already have ended into another entry). The script waits until
the last step's frame has passed, then writes the server's stats as JSON.
"""
import argparse
import json
import sys
import time

DEFAULT_SEQUENCE = "open@0 close@60 open@130 close@200"


def parse_sequence(text):
    steps = []
    for word in text.split():
        entry, sep, offset = word.partition("@")
        if not sep or not entry or not offset.isdigit():
            raise ValueError(f"--sequence: step '{word}' is not ENTRY@FRAME_OFFSET (e.g. open@0)")
        steps.append((entry, int(offset)))
    if not steps:
        raise ValueError("--sequence: no steps (expected e.g. 'open@0 stop@40')")
    return steps


class Commands:
    """A DEALER sending [""][Request] and waiting for [""][Reply] (docs/protocol.md)."""

    def __init__(self, zmq, pb, endpoint):
        self.zmq, self.pb = zmq, pb
        self.socket = zmq.Context.instance().socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.connect(endpoint)
        self.endpoint, self.next_id = endpoint, 1

    def call(self, fill):
        request = self.pb.Request(id=self.next_id)
        self.next_id += 1
        fill(request)
        self.socket.send_multipart([b"", request.SerializeToString()])
        if not self.socket.poll(10000):
            raise RuntimeError(f"{self.endpoint}: no reply within 10 s")
        parts = self.socket.recv_multipart()
        reply = self.pb.Reply()
        reply.ParseFromString(parts[-1])
        return reply


def instance_frame(commands, instance):
    reply = commands.call(lambda r: r.list_instances.SetInParent())
    for info in reply.instances.instances:
        if info.instance == instance:
            return info.frame
    raise RuntimeError(f"--instance {instance}: no such instance on the server")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("endpoint", help="command endpoint of phasecast-server")
    parser.add_argument("proto_dir", help="folder with phasecast_pb2.py (build/proto/python)")
    parser.add_argument("--instance", type=int, default=1)
    parser.add_argument("--sequence", default=DEFAULT_SEQUENCE)
    parser.add_argument("--stats-out")
    args = parser.parse_args()
    try:
        steps = parse_sequence(args.sequence)
        sys.path.insert(0, args.proto_dir)
        import zmq
        import phasecast_pb2 as pb

        commands = Commands(zmq, pb, args.endpoint)
        start = instance_frame(commands, args.instance) + 5
        applied = refused = 0
        for entry, offset in steps:
            # Sent just before its frame, so the server checks it against the entry
            # playing then (a queued impulse is checked against the one queued before it).
            target = start + offset
            while instance_frame(commands, args.instance) + 3 < target:
                time.sleep(0.02)
            def fill(r, entry=entry, target=target):
                r.impulse.instance = args.instance
                r.impulse.name = entry
                r.impulse.at_frame = target
            reply = commands.call(fill)
            if reply.ok:
                applied += 1
                print(f"drive: '{entry}' queued for frame {reply.impulse.at_frame}", flush=True)
            else:
                refused += 1
                print(f"drive: refused: {reply.error}", flush=True)
        last = start + max(offset for _, offset in steps)
        while instance_frame(commands, args.instance) <= last:
            time.sleep(0.1)
        stats = commands.call(lambda r: r.stats.SetInParent())
        if args.stats_out:
            from google.protobuf import json_format
            with open(args.stats_out, "w") as f:
                f.write(json_format.MessageToJson(stats.stats, preserving_proto_field_name=True))
        print(f"drive: {applied} impulses queued, {refused} refused at queue time", flush=True)
    except KeyboardInterrupt:
        print("drive_impulses: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # one line, the shell script reports it
        print(f"drive_impulses: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
