#!/usr/bin/env python3
"""Write a ROS 2 bag directory (rosbag2, MCAP storage) of detections with the `rosbags` library.

The scenario of issue #20, written by an independent ROS 2 implementation (PyPI `rosbags`, its own
CDR serializer and rosbag2 writer), not by probmot: `vision_msgs/msg/Detection3DArray` on
/perception/detections, three objects moving on straight lines over 60 frames at 10 Hz, frame
`map`, one hypothesis per box (class_id, score), no per-detection ids.

    python3 scripts/make_rosbag_fixture.py OUT_BAG_DIR [--frames 60]

OUT_BAG_DIR must not exist; it is created as `ros2 bag record` does (metadata.yaml + OUT.mcap).
The true positions are printed as JSON on stdout (one line per object: label and per-frame
centre), for checks that want them.

Needs `rosbags` (scripts/requirements.txt).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

try:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(f"make_rosbag_fixture.py: error: {e}; install `rosbags` (scripts/requirements.txt)\n")
    sys.exit(2)

# vision_msgs 4.x (ROS 2 Humble), field lines of github.com/ros-perception/vision_msgs (branch
# ros2, msg/*.msg); std_msgs, geometry_msgs and builtin_interfaces come with rosbags' Humble store.
VISION_MSGS = {
    "vision_msgs/msg/Detection3DArray": "std_msgs/Header header\nDetection3D[] detections\n",
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nObjectHypothesisWithPose[] results\nBoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
}

TOPIC = "/perception/detections"
FRAME = "map"
START_NS = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000

# (label, start x, start y, velocity x, velocity y, size l w h, score): three objects far apart.
OBJECTS = [
    ("car", 0.0, 0.0, 8.0, 0.0, (4.5, 1.9, 1.6), 0.92),
    ("pedestrian", 5.0, 20.0, 0.0, -1.2, (0.7, 0.7, 1.8), 0.81),
    ("bicycle", -20.0, -15.0, 3.0, 2.0, (1.8, 0.6, 1.5), 0.77),
]


def typestore():
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for name, text in VISION_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="bag directory to create")
    ap.add_argument("--frames", type=int, default=60)
    args = ap.parse_args()
    store = typestore()
    T = store.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    Pose, Point, Quat = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    Vector3, PwC = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/PoseWithCovariance"]
    Array, Det = T["vision_msgs/msg/Detection3DArray"], T["vision_msgs/msg/Detection3D"]
    Hyp, HypWP = T["vision_msgs/msg/ObjectHypothesis"], T["vision_msgs/msg/ObjectHypothesisWithPose"]
    Box = T["vision_msgs/msg/BoundingBox3D"]
    import numpy as np

    truth = {label: [] for label, *_ in OBJECTS}
    with Writer(args.out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection(TOPIC, "vision_msgs/msg/Detection3DArray", typestore=store)
        for k in range(args.frames):
            t = START_NS + k * PERIOD_NS
            header = Header(stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id=FRAME)
            dets = []
            for label, x0, y0, vx, vy, (l, wd, h), score in OBJECTS:
                x, y = x0 + vx * k * 0.1, y0 + vy * k * 0.1
                yaw = math.atan2(vy, vx)
                truth[label].append([x, y, h / 2])
                pose = Pose(
                    position=Point(x=x, y=y, z=h / 2),
                    orientation=Quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
                )
                dets.append(
                    Det(
                        header=header,
                        results=[HypWP(hypothesis=Hyp(class_id=label, score=score),
                                       pose=PwC(pose=pose, covariance=np.zeros(36)))],
                        bbox=Box(center=pose, size=Vector3(x=l, y=wd, z=h)),
                        id="",
                    )
                )
            raw = store.serialize_cdr(Array(header=header, detections=dets), "vision_msgs/msg/Detection3DArray")
            w.write(conn, t, raw)
    for label, centres in truth.items():
        print(json.dumps({"label": label, "centres": centres}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
