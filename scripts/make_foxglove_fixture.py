#!/usr/bin/env python3
"""Convert the detections of a probmot log into a Foxglove MCAP of foxglove.SceneUpdate.

The output is written by PyPI `mcap-protobuf-support` with the message classes and descriptors
of PyPI `foxglove-schemas-protobuf` (Foxglove's published .proto files), not by probmot, so
`tests/it/ros2_foxglove_input/fixtures.rs` checks probmot's decoder against a third-party writer. One
SceneUpdate per `probmot.Detections3D` message, one entity per box, following probmot's
metadata convention (README, "Detection inputs"):

- entity.timestamp = the message's `stamp` (or its log_time when unset), frame_id = frame_id,
  id = "det-N" (N = index of the box in the message);
- one cube: pose.position = centre, pose.orientation = the rotation by `yaw` about +z,
  size = (length, width, height);
- metadata: `label` = label, `score` = the score written with Python's `repr` (the shortest
  text that reads back as the same double), and every attribute of the box (`sim_truth_id`);
- log_time and publish_time as in the input.

    python3 scripts/make_foxglove_fixture.py sample_logs/city.mcap -o tests/fixtures/foxglove/city.mcap

Needs `python3 -m pip install -r scripts/requirements.txt` (mcap, mcap-protobuf-support,
foxglove-schemas-protobuf).
"""

from __future__ import annotations

import argparse
import math
import sys

try:
    from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
    from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
    from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    from mcap_protobuf.writer import Writer
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(
        f"make_foxglove_fixture.py: error: {e}; install with "
        "`python3 -m pip install -r scripts/requirements.txt`\n"
    )
    sys.exit(2)


def convert(inp: str, out: str, topic: str) -> int:
    """Write `out`; returns the number of messages converted."""
    n = 0
    with open(inp, "rb") as f, open(out, "wb") as g:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        writer = Writer(g)
        for _, channel, message, proto in reader.iter_decoded_messages(topics=[topic]):
            stamp = proto.stamp if proto.HasField("stamp") else message.log_time
            update = SceneUpdate()
            for i, d in enumerate(proto.detections):
                e = SceneEntity(id=f"det-{i}", frame_id=proto.frame_id)
                e.timestamp.seconds = stamp // 1_000_000_000
                e.timestamp.nanos = stamp % 1_000_000_000
                cube = CubePrimitive()
                cube.pose.position.x = d.center.x
                cube.pose.position.y = d.center.y
                cube.pose.position.z = d.center.z
                cube.pose.orientation.x = 0.0
                cube.pose.orientation.y = 0.0
                cube.pose.orientation.z = math.sin(d.yaw / 2.0)
                cube.pose.orientation.w = math.cos(d.yaw / 2.0)
                cube.size.x = d.size.length
                cube.size.y = d.size.width
                cube.size.z = d.size.height
                e.cubes.append(cube)
                e.metadata.append(KeyValuePair(key="label", value=d.label))
                e.metadata.append(KeyValuePair(key="score", value=repr(d.score)))
                for k in sorted(d.attributes):
                    e.metadata.append(KeyValuePair(key=k, value=d.attributes[k]))
                update.entities.append(e)
            writer.write_message(
                topic=channel.topic,
                message=update,
                log_time=message.log_time,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )
            n += 1
        writer.finish()
    return n


def main() -> None:
    """Command line."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("input", help="a probmot log with a probmot.Detections3D topic")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--topic", default="/detections")
    a = p.parse_args()
    n = convert(a.input, a.output, a.topic)
    if n == 0:
        sys.stderr.write(f"make_foxglove_fixture.py: error: no messages on {a.topic}\n")
        sys.exit(2)
    print(f"{a.output}: {n} SceneUpdate messages")


if __name__ == "__main__":
    main()
