#!/usr/bin/env python3
"""Writes tests/fixtures/ros2_tf/tf.mcap with a third-party ROS 2 writer (PyPI
`mcap-ros2-support`, which serialises CDR from the message definitions below) and
tests/fixtures/ros2_tf/expected.json with the values written, for tests/it/ros2_tf_fixture.rs.

Channels:
  /tf_static  tf2_msgs/msg/TFMessage  base_link -> lidar_top (static)
  /tf         tf2_msgs/msg/TFMessage  map -> odom and odom -> base_link at three stamps
  /odom       nav_msgs/msg/Odometry   odom -> base_footprint at two stamps

The message definitions are the upstream .msg files (ROS 2 Humble .. Rolling; comments left
out, fields, types, order and constants as upstream), concatenated the way rosbag2 stores them
in an MCAP schema record (`ros2msg` encoding):
  tf2_msgs/msg/TFMessage.msg              https://github.com/ros2/geometry2/blob/rolling/tf2_msgs/msg/TFMessage.msg
  nav_msgs/msg/Odometry.msg               https://github.com/ros2/common_interfaces/blob/rolling/nav_msgs/msg/Odometry.msg
  geometry_msgs/msg/TransformStamped.msg  https://github.com/ros2/common_interfaces/blob/rolling/geometry_msgs/msg/TransformStamped.msg
  geometry_msgs/msg/Transform.msg, Vector3.msg, Quaternion.msg, Pose.msg, Point.msg,
  PoseWithCovariance.msg, Twist.msg, TwistWithCovariance.msg   (ros2/common_interfaces, geometry_msgs/msg/)
  std_msgs/msg/Header.msg                 https://github.com/ros2/common_interfaces/blob/rolling/std_msgs/msg/Header.msg
  builtin_interfaces/msg/Time.msg         https://github.com/ros2/rcl_interfaces/blob/rolling/builtin_interfaces/msg/Time.msg

Regenerate (from the repository root):
  python3 -m pip install -r scripts/requirements.txt
  python3 scripts/make_ros2_tf_fixture.py
"""

import json
import math
from pathlib import Path

from mcap_ros2.writer import Writer

SEP = "=" * 80

TIME = "int32 sec\nuint32 nanosec\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
VECTOR3 = "float64 x\nfloat64 y\nfloat64 z\n"
POINT = "float64 x\nfloat64 y\nfloat64 z\n"
QUATERNION = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
TRANSFORM = "Vector3 translation\nQuaternion rotation\n"
TRANSFORM_STAMPED = "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms\n"
POSE = "Point position\nQuaternion orientation\n"
POSE_WITH_COVARIANCE = "Pose pose\nfloat64[36] covariance\n"
TWIST = "Vector3  linear\nVector3  angular\n"
TWIST_WITH_COVARIANCE = "Twist twist\nfloat64[36] covariance\n"
ODOMETRY = (
    "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n"
)


def msgdef(main, deps):
    parts = [main]
    for name, text in deps:
        parts.append(f"{SEP}\nMSG: {name}\n{text}")
    return "\n".join(parts)


TF_DEF = msgdef(
    TF_MESSAGE,
    [
        ("geometry_msgs/TransformStamped", TRANSFORM_STAMPED),
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
        ("geometry_msgs/Transform", TRANSFORM),
        ("geometry_msgs/Vector3", VECTOR3),
        ("geometry_msgs/Quaternion", QUATERNION),
    ],
)
ODOM_DEF = msgdef(
    ODOMETRY,
    [
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
        ("geometry_msgs/PoseWithCovariance", POSE_WITH_COVARIANCE),
        ("geometry_msgs/Pose", POSE),
        ("geometry_msgs/Point", POINT),
        ("geometry_msgs/Quaternion", QUATERNION),
        ("geometry_msgs/TwistWithCovariance", TWIST_WITH_COVARIANCE),
        ("geometry_msgs/Twist", TWIST),
        ("geometry_msgs/Vector3", VECTOR3),
    ],
)

T0 = 1_700_000_000  # seconds


def yaw_quat(yaw, roll=0.0):
    # Rotation about z by yaw after a rotation about x by roll (ZYX with pitch 0).
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return {"x": cy * sr, "y": sy * sr, "z": sy * cr, "w": cy * cr}


def stamped(sec, nanosec, parent, child, t, q):
    return {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": parent},
        "child_frame_id": child,
        "transform": {"translation": {"x": t[0], "y": t[1], "z": t[2]}, "rotation": q},
    }


def main():
    out_dir = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "ros2_tf"
    out_dir.mkdir(parents=True, exist_ok=True)
    expected = []

    def record(topic, m, stamp_ns):
        tr = m["transform"]
        expected.append(
            {
                "topic": topic,
                "parent": m["header"]["frame_id"],
                "child": m["child_frame_id"],
                "stamp_ns": stamp_ns,
                "translation": [tr["translation"][k] for k in "xyz"],
                "rotation": [tr["rotation"][k] for k in "xyzw"],
            }
        )

    with open(out_dir / "tf.mcap", "wb") as f:
        w = Writer(f)
        tf_schema = w.register_msgdef("tf2_msgs/msg/TFMessage", TF_DEF)
        odom_schema = w.register_msgdef("nav_msgs/msg/Odometry", ODOM_DEF)

        static = stamped(T0, 0, "base_link", "lidar_top", (1.25, -0.5, 1.875), yaw_quat(0.1, 0.02))
        w.write_message("/tf_static", tf_schema, {"transforms": [static]}, log_time=T0 * 10**9)
        record("/tf_static", static, T0 * 10**9)

        for i, (x, yaw) in enumerate([(0.0, 0.0), (5.0, 0.4), (10.5, 0.9)]):
            sec, ns = T0 + i, 250_000_000
            stamp = sec * 10**9 + ns
            msgs = [
                stamped(sec, ns, "map", "odom", (100.0, -20.0, 0.0), yaw_quat(0.0)),
                stamped(sec, ns, "odom", "base_link", (x, 0.5 * x, 0.25), yaw_quat(yaw)),
            ]
            w.write_message("/tf", tf_schema, {"transforms": msgs}, log_time=stamp, sequence=i)
            for m in msgs:
                record("/tf", m, stamp)

        cov = [float(k) / 10.0 for k in range(36)]
        for i, (x, y, yaw) in enumerate([(1.0, 2.0, -0.3), (3.0, 4.5, 0.2)]):
            sec, ns = T0 + i, 500_000_000
            stamp = sec * 10**9 + ns
            q = yaw_quat(yaw)
            odom = {
                "header": {"stamp": {"sec": sec, "nanosec": ns}, "frame_id": "odom"},
                "child_frame_id": "base_footprint",
                "pose": {
                    "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": q},
                    "covariance": cov,
                },
                "twist": {
                    "twist": {
                        "linear": {"x": 2.0, "y": 0.0, "z": 0.0},
                        "angular": {"x": 0.0, "y": 0.0, "z": 0.1},
                    },
                    "covariance": cov,
                },
            }
            w.write_message("/odom", odom_schema, odom, log_time=stamp, sequence=i)
            expected.append(
                {
                    "topic": "/odom",
                    "parent": "odom",
                    "child": "base_footprint",
                    "stamp_ns": stamp,
                    "translation": [x, y, 0.0],
                    "rotation": [q[k] for k in "xyzw"],
                    "covariance": cov,
                    "twist_linear": [2.0, 0.0, 0.0],
                    "twist_angular": [0.0, 0.0, 0.1],
                }
            )
        w.finish()

    (out_dir / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")
    print(f"wrote {out_dir / 'tf.mcap'} and expected.json ({len(expected)} transforms)")


if __name__ == "__main__":
    main()
