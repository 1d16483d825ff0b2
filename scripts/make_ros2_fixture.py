#!/usr/bin/env python3
"""Convert the detections of a probmot log into a ROS 2 MCAP of vision_msgs/msg/Detection3DArray.

The output is written by PyPI `mcap-ros2-support` (its own CDR serializer, driven by the message
definition text below), not by probmot, so `tests/it/ros2_foxglove_input/fixtures.rs` checks probmot's
decoder against a third-party writer. One Detection3DArray per `probmot.Detections3D` message:

- header.stamp = the message's `stamp` (or its log_time when unset), header.frame_id = frame_id;
- per box one Detection3D: bbox.center.position = centre, bbox.center.orientation = the rotation
  by `yaw` about +z, bbox.size = (length, width, height), one hypothesis (class_id = label,
  score = score, pose = the bbox centre pose), id = the box's `sim_truth_id` attribute if any;
- log_time and publish_time as in the input.

With `--layout 2` the messages follow vision_msgs 2.x (ROS 2 Foxy): the hypothesis is
(id = label, score, pose), and each Detection3D carries a one-point `source_cloud`,
`is_tracking` = false and `tracking_id` = the `sim_truth_id`.

    python3 scripts/make_ros2_fixture.py sample_logs/city.mcap -o tests/fixtures/ros2/city.mcap
    python3 scripts/make_ros2_fixture.py sample_logs/turning-car.mcap --layout 2 \
        -o tests/fixtures/ros2/turning-car-vision_msgs2.mcap

Needs `python3 -m pip install -r scripts/requirements.txt` (mcap, mcap-protobuf-support,
mcap-ros2-support).
"""

from __future__ import annotations

import argparse
import math
import struct
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

# vision_msgs 2.0 (ROS 2 Foxy; github.com/ros-perception/vision_msgs, branch foxy, msg/*.msg)
# and sensor_msgs (github.com/ros2/common_interfaces, sensor_msgs/msg/PointCloud2.msg and
# PointField.msg): the types that differ from 4.x, replacing theirs.
V2_REPLACEMENTS = {
    "vision_msgs/Detection3D": (
        "std_msgs/Header header\n\nObjectHypothesisWithPose[] results\n\n"
        "BoundingBox3D bbox\n\nsensor_msgs/PointCloud2 source_cloud\n\n"
        "bool is_tracking\n\nstring tracking_id\n"
    ),
    "vision_msgs/ObjectHypothesisWithPose": (
        "string id\n\nfloat64 score\n\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
}
V2_EXTRA = [
    (
        "sensor_msgs/PointCloud2",
        "std_msgs/Header header\n\nuint32 height\nuint32 width\n\n"
        "PointField[] fields\n\nbool    is_bigendian\nuint32  point_step\n"
        "uint32  row_step\nuint8[] data\n\nbool is_dense\n",
    ),
    (
        "sensor_msgs/PointField",
        "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\nuint8 UINT16  = 4\n"
        "uint8 INT32   = 5\nuint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n\n"
        "string name\nuint32 offset\nuint8  datatype\nuint32 count\n",
    ),
]


def definition_text(layout: int = 4) -> str:
    """The full ros2msg schema text: top-level definition plus every dependency."""
    deps = list(DEPENDENCIES)
    if layout == 2:
        deps = [
            (name, V2_REPLACEMENTS.get(name, text))
            for name, text in deps
            if name != "vision_msgs/ObjectHypothesis"
        ] + V2_EXTRA
    parts = [DETECTION3D_ARRAY]
    for name, text in deps:
        parts.append(f"{SEPARATOR}\nMSG: {name}\n{text}")
    return "\n".join(parts)


def yaw_quaternion(yaw: float) -> dict[str, float]:
    """The rotation by `yaw` radians about +z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}


def one_point_cloud(header: dict, value: float) -> dict:
    """A 1 x 1 sensor_msgs/PointCloud2 with one float32 field (4 data bytes, so the fields
    after it need alignment padding)."""
    return {
        "header": header,
        "height": 1,
        "width": 1,
        "fields": [{"name": "x", "offset": 0, "datatype": 7, "count": 1}],
        "is_bigendian": False,
        "point_step": 4,
        "row_step": 4,
        "data": struct.pack("<f", value),
        "is_dense": True,
    }


def convert(inp: str, out: str, topic: str, layout: int = 4) -> int:
    """Write `out`; returns the number of messages converted."""
    n = 0
    with open(inp, "rb") as f, open(out, "wb") as g:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        writer = Writer(g)
        schema = writer.register_msgdef(DATATYPE, definition_text(layout))
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
                bbox = {
                    "center": pose,
                    "size": {"x": d.size.length, "y": d.size.width, "z": d.size.height},
                }
                hyp_pose = {"pose": pose, "covariance": [0.0] * 36}
                truth_id = d.attributes.get("sim_truth_id", "")
                if layout == 2:
                    detections.append(
                        {
                            "header": header,
                            "results": [{"id": d.label, "score": d.score, "pose": hyp_pose}],
                            "bbox": bbox,
                            "source_cloud": one_point_cloud(header, d.center.x),
                            "is_tracking": False,
                            "tracking_id": truth_id,
                        }
                    )
                else:
                    detections.append(
                        {
                            "header": header,
                            "results": [
                                {
                                    "hypothesis": {"class_id": d.label, "score": d.score},
                                    "pose": hyp_pose,
                                }
                            ],
                            "bbox": bbox,
                            "id": truth_id,
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
    p.add_argument(
        "--layout",
        type=int,
        choices=[4, 2],
        default=4,
        help="vision_msgs layout: 4 (Humble and later, default) or 2 (Foxy)",
    )
    a = p.parse_args()
    n = convert(a.input, a.output, a.topic, a.layout)
    if n == 0:
        sys.stderr.write(f"make_ros2_fixture.py: error: no messages on {a.topic}\n")
        sys.exit(2)
    print(f"{a.output}: {n} Detection3DArray messages")


if __name__ == "__main__":
    main()
