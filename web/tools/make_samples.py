#!/usr/bin/env python3
"""Writes PageEvent samples for test/protocol.test.mjs (development stand-in
for the lead's C++ sample writer; the contract is in that test's header).

  protoc --python_out=/tmp/pcproto -I proto proto/phasecast.proto
  PYTHONPATH=/tmp/pcproto /usr/bin/python3 web/tools/make_samples.py OUTDIR
"""
import json
import os
import sys

from google.protobuf import json_format

import phasecast_pb2 as pb


def expected(event):
    # snake_case names, uint64 as decimal strings, bytes as base64, enums as names
    return json_format.MessageToDict(event, preserving_proto_field_name=True)


def main(out):
    os.makedirs(out, exist_ok=True)
    hello = pb.PageEvent(hello=pb.GatewayHello(protocol_version=1, server="tcp://127.0.0.1:5555",
                                               max_message_bytes=65536, max_requests_in_flight=8, frame_queue=4))
    frame = pb.PageEvent(frame=pb.Frame(instance=3, seq=41, frame=12345678901, sim_time=246.91357802,
                                        q_u=[0.1, -2.5, 3.0e-7, 1.0e10], q_a=[0.25, -0.125],
                                        support=[1, 0, 0, 0.5, 0, 1, 0, -1.25, 0, 0, 1, 2], palette_index=2,
                                        irf=5, irf_t=17, scene="cloth_door"))
    chunk = pb.BasisChunk(scene="cloth_door", part=pb.U_U, offset=1048576, total_bytes=2000000,
                          data=bytes(range(256)) * 3, content_hash=0xA943D6CF7BFCDAE1,
                          info=pb.BasisPartInfo(part=pb.U_U, dtype="float32", shape=[3726, 11],
                                                total_bytes=163944))
    reply = pb.PageEvent(reply=pb.Reply(id=7, ok=True, basis=chunk))
    samples = {}
    for name, event in (("hello", hello), ("frame", frame), ("basis_reply", reply)):
        with open(os.path.join(out, name + ".bin"), "wb") as f:
            f.write(event.SerializeToString())
        samples[name] = expected(event)
    with open(os.path.join(out, "samples.json"), "w") as f:
        json.dump(samples, f, indent=2)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "samples")
