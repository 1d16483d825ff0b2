#!/usr/bin/env python3
"""Convert the detections of a probmot log into a ROS 2 MCAP of vision_msgs/msg/Detection3DArray.

The output is written by PyPI `mcap-ros2-support` (its own CDR serializer, driven by the message
definition text below), not by probmot, so `tests/ros2_foxglove_input.rs` checks probmot's
decoder against a third-party writer. One Detection3DArray per `probmot.Detections3D` message:

- header.stamp = the message's `stamp` (or its log_time when unset), header.frame_id = frame_id;
- per box one Detection3D: bbox.center.position = centre, bbox.center.orientation = the rotation
  by `yaw` about +z, bbox.size = (length, width, height), one hypothesis (class_id = label,
  score = score, pose = the bbox centre pose), id = the box's `sim_truth_id` attribute if any;
- log_time and publish_time as in the input.

    python3 scripts/make_ros2_fixture.py sample_logs/city.mcap -o tests/fixtures/ros2/city.mcap

Needs `python3 -m pip install -r scripts/requirements.txt` (mcap, mcap-protobuf-support,
mcap-ros2-support).
"""

from __future__ import annotations

import argparse
import math
import sys

try:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    from mcap_ros2.writer import Writer
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(
        f"make_ros2_fixture.py: error: {e}; install with "
        "`python3 -m pip install -r scripts/requirements.txt`\n"
    )
    sys.exit(2)

SEPARATOR = "=" * 80

# The field lines of the ROS 2 message definitions (comments left out), as published for
# vision_msgs 4.x (ROS 2 Humble, Jazzy, Kilted, Rolling: docs.ros.org/en/jazzy/p/vision_msgs/
# msg/{Detection3DArray,Detection3D,ObjectHypothesisWithPose,ObjectHypothesis,BoundingBox3D}.html),
# geometry_msgs and std_msgs (github.com/ros2/common_interfaces, msg/*.msg) and
# builtin_interfaces (github.com/ros2/rcl_interfaces, builtin_interfaces/msg/Time.msg).
# Sections follow the layout rosbag2 writes: the top-level type, then each dependency after a
# line of 80 '=' and a `MSG: package/Type` line.
DETECTION3D_ARRAY = "std_msgs/Header header\n\nDetection3D[] detections\n"
DEPENDENCIES = [
    (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\n\nstring frame_id\n",
    ),
    ("builtin_interfaces/Time", "int32 sec\n\nuint32 nanosec\n"),
    (
        "vision_msgs/Detection3D",
        "std_msgs/Header header\n\nObjectHypothesisWithPose[] results\n\n"
        "BoundingBox3D bbox\n\nstring id\n",
    ),
    (
        "vision_msgs/ObjectHypothesisWithPose",
        "ObjectHypothesis hypothesis\n\ngeometry_msgs/PoseWithCovariance pose\n",
    ),
    ("vision_msgs/ObjectHypothesis", "string class_id\n\nfloat64 score\n"),
    (
        "geometry_msgs/PoseWithCovariance",
        "Pose pose\n\nfloat64[36] covariance\n",
    ),
    ("geometry_msgs/Pose", "Point position\nQuaternion orientation\n"),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
    (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    ),
    (
        "vision_msgs/BoundingBox3D",
        "geometry_msgs/Pose center\n\ngeometry_msgs/Vector3 size\n",
    ),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
]
DATATYPE = "vision_msgs/msg/Detection3DArray"


def definition_text() -> str:
    """The full ros2msg schema text: top-level definition plus every dependency."""
    parts = [DETECTION3D_ARRAY]
    for name, text in DEPENDENCIES:
        parts.append(f"{SEPARATOR}\nMSG: {name}\n{text}")
    return "\n".join(parts)


def yaw_quaternion(yaw: float) -> dict[str, float]:
    """The rotation by `yaw` radians about +z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}


def convert(inp: str, out: str, topic: str) -> int:
    """Write `out`; returns the number of messages converted."""
    n = 0
    with open(inp, "rb") as f, open(out, "wb") as g:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        writer = Writer(g)
        schema = writer.register_msgdef(DATATYPE, definition_text())
        for _, channel, message, proto in reader.iter_decoded_messages(topics=[topic]):
            stamp = proto.stamp if proto.HasField("stamp") else message.log_time
            header = {
                "stamp": {"sec": stamp // 1_000_000_000, "nanosec": stamp % 1_000_000_000},
                "frame_id": proto.frame_id,
            }
            detections = []
            for d in proto.detections:
                pose = {
                    "position": {"x": d.center.x, "y": d.center.y, "z": d.center.z},
                    "orientation": yaw_quaternion(d.yaw),
                }
                detections.append(
                    {
                        "header": header,
                        "results": [
                            {
                                "hypothesis": {"class_id": d.label, "score": d.score},
                                "pose": {"pose": pose, "covariance": [0.0] * 36},
                            }
                        ],
                        "bbox": {
                            "center": pose,
                            "size": {
                                "x": d.size.length,
                                "y": d.size.width,
                                "z": d.size.height,
                            },
                        },
                        "id": d.attributes.get("sim_truth_id", ""),
                    }
                )
            writer.write_message(
                topic=channel.topic,
                schema=schema,
                message={"header": header, "detections": detections},
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
        sys.stderr.write(f"make_ros2_fixture.py: error: no messages on {a.topic}\n")
        sys.exit(2)
    print(f"{a.output}: {n} Detection3DArray messages")


if __name__ == "__main__":
    main()
