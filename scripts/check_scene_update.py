#!/usr/bin/env python3
"""Decodes the foxglove.SceneUpdate channel of a tracked MCAP with the official Foxglove
Python schemas (PyPI `foxglove-schemas-protobuf`, generated from the same .proto files as the
Foxglove app uses) and prints one JSON line per message, for tests/it/scene_update.rs.

The messages are parsed with `foxglove_schemas_protobuf.SceneUpdate_pb2.SceneUpdate`, not with
the descriptor embedded in the file, so a wrong field number or type in probmot's output fails
here. The script also checks that the schema record names foxglove.SceneUpdate (protobuf) and
that its embedded descriptor declares the same message as the official one.

Usage: python3 scripts/check_scene_update.py FILE.mcap [--topic /tracks/scene]
"""

import argparse
import json
import os
import sys

try:
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from google.protobuf import descriptor_pb2, descriptor_pool
    from mcap.reader import make_reader
except ImportError as e:  # depends on the environment
    sys.exit(
        f"{os.path.basename(sys.argv[0])}: error: {e}; install the packages with "
        "`python3 -m pip install -r scripts/requirements.txt`"
    )


def ns(ts):
    return ts.seconds * 1_000_000_000 + ts.nanos


def vec(v):
    return [v.x, v.y, v.z]


def fields(d):
    """(name, number, label, type, type name) of each field of a DescriptorProto."""
    return sorted((f.name, f.number, f.label, f.type, f.type_name) for f in d.field)


def check_embedded_descriptor(data):
    """Every foxglove message of the embedded FileDescriptorSet has the fields of the official
    one (json_name and comments aside)."""
    pool = descriptor_pool.Default()
    fds = descriptor_pb2.FileDescriptorSet.FromString(data)
    names = []
    for fd in fds.file:
        for m in fd.message_type:
            full = f"{fd.package}.{m.name}"
            official = descriptor_pb2.DescriptorProto()
            pool.FindMessageTypeByName(full).CopyToProto(official)
            if fields(m) != fields(official):
                sys.exit(f"embedded descriptor of {full} differs from the official one")
            names.append(full)
    if "foxglove.SceneUpdate" not in names:
        sys.exit("the schema record does not hold foxglove.SceneUpdate")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--topic", default="/tracks/scene")
    a = ap.parse_args()
    n = 0
    with open(a.file, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=[a.topic]):
            if schema.name != "foxglove.SceneUpdate" or schema.encoding != "protobuf":
                sys.exit(f"{a.topic}: schema {schema.name} ({schema.encoding})")
            if channel.message_encoding != "protobuf":
                sys.exit(f"{a.topic}: message encoding {channel.message_encoding}")
            if n == 0:
                check_embedded_descriptor(schema.data)
            u = SceneUpdate.FromString(message.data)
            out = {
                "log_time": message.log_time,
                "deletions": [
                    {"id": d.id, "type": d.type, "stamp_ns": ns(d.timestamp)} for d in u.deletions
                ],
                "entities": [
                    {
                        "id": e.id,
                        "frame_id": e.frame_id,
                        "stamp_ns": ns(e.timestamp),
                        "lifetime_ns": ns(e.lifetime),
                        "cubes": [
                            {
                                "position": vec(c.pose.position),
                                "orientation": [c.pose.orientation.x, c.pose.orientation.y,
                                                c.pose.orientation.z, c.pose.orientation.w],
                                "size": vec(c.size),
                                "color": [c.color.r, c.color.g, c.color.b, c.color.a],
                            }
                            for c in e.cubes
                        ],
                        "texts": [t.text for t in e.texts],
                        "arrows": [
                            {"position": vec(r.pose.position),
                             "length": r.shaft_length + r.head_length}
                            for r in e.arrows
                        ],
                    }
                    for e in u.entities
                ],
            }
            print(json.dumps(out))
            n += 1
    if n == 0:
        sys.exit(f"no message on {a.topic}")


if __name__ == "__main__":
    main()
