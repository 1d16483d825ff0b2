#!/usr/bin/env python3
"""Write a ROS 2 bag directory of Autoware detections with the `rosbags` library.

An independent writer (PyPI `rosbags`: its own CDR serializer and rosbag2 writer, the message
types registered from the .msg field lists below), not probmot:
`autoware_perception_msgs/msg/DetectedObjects` on /perception/object_recognition/detection/objects,
60 frames at 10 Hz, six objects:

- a car driving along +x (BOUNDING_BOX, twist given in the object's frame);
- a car driving along -x whose classification lists TRUCK 0.3 before CAR 0.7 (twist given);
- a pedestrian walking along -y (CYLINDER, no twist);
- a truck driving at yaw 0.3 rad given as a POLYGON footprint whose middle is 0.5 m ahead of
  the pose (so the box centre is not the pose);
- a parked car (twist zero);
- a static UNKNOWN object (skipped by probmot unless the config has an `unknown` entry).

    python3 scripts/make_autoware_bag.py OUT_BAG_DIR [--frames 60] [--ego] [--auto]

--ego writes the detections in a moving `base_link` frame with the ego pose on /tf
(tf2_msgs/msg/TFMessage, map -> base_link); without it they are in `map`. --auto writes the
older package's type, `autoware_auto_perception_msgs/msg/DetectedObjects` (same fields).

OUT_BAG_DIR must not exist; it is created as `ros2 bag record` does (metadata.yaml + OUT.mcap).
The truth is printed as JSON lines on stdout, one per object: label, whether probmot tracks it
with its default config, the true box centre per frame in `map`, and the velocity.

Needs `rosbags` and numpy (scripts/requirements.txt).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

try:
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(f"make_autoware_bag.py: error: {e}; install `rosbags` (scripts/requirements.txt)\n")
    sys.exit(2)

# The field lists (and constants) of autoware_perception_msgs 1.x, as in
# github.com/autowarefoundation/autoware_msgs, autoware_perception_msgs/msg/*.msg (comments left
# out). autoware_auto_perception_msgs (tier4/autoware_auto_msgs, written there in IDL) has the
# same fields; its ObjectClassification has the constants up to PEDESTRIAN only.
PERCEPTION_MSGS = {
    "DetectedObjects": "std_msgs/Header header\nDetectedObject[] objects\n",
    "DetectedObject": (
        "float32 existence_probability\nObjectClassification[] classification\n"
        "DetectedObjectKinematics kinematics\nShape shape\n"
    ),
    "ObjectClassification": (
        "uint8 UNKNOWN = 0\nuint8 CAR = 1\nuint8 TRUCK = 2\nuint8 BUS = 3\nuint8 TRAILER = 4\n"
        "uint8 MOTORCYCLE = 5\nuint8 BICYCLE = 6\nuint8 PEDESTRIAN = 7\n{extra}"
        "uint8 label\nfloat32 probability\n"
    ),
    "DetectedObjectKinematics": (
        "uint8 UNAVAILABLE=0\nuint8 SIGN_UNKNOWN=1\nuint8 AVAILABLE=2\n"
        "geometry_msgs/PoseWithCovariance pose_with_covariance\nbool has_position_covariance\n"
        "uint8 orientation_availability\ngeometry_msgs/TwistWithCovariance twist_with_covariance\n"
        "bool has_twist\nbool has_twist_covariance\n"
    ),
    "Shape": (
        "uint8 BOUNDING_BOX=0\nuint8 CYLINDER=1\nuint8 POLYGON=2\nuint8 type\n"
        "geometry_msgs/Polygon footprint\ngeometry_msgs/Vector3 dimensions\n"
    ),
}
EXTRA_CLASSES = "uint8 ANIMAL = 8\nuint8 HAZARD = 9\nuint8 OVER_DRIVABLE = 10\nuint8 UNDER_DRIVABLE = 11\n"

TOPIC = "/perception/object_recognition/detection/objects"
START_NS = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000
CAR, TRUCK, PEDESTRIAN, UNKNOWN = 1, 2, 7, 0
BOUNDING_BOX, CYLINDER, POLYGON = 0, 1, 2
SIGN_UNKNOWN, AVAILABLE = 1, 2

# name, classes [(code, probability)], existence, start (x, y), velocity (x, y), yaw, shape,
# dimensions (x, y, z), footprint offset of the box middle ahead of the pose, has twist.
OBJECTS = [
    ("car", [(CAR, 1.0)], 0.9, (0.0, 0.0), (8.0, 0.0), 0.0, BOUNDING_BOX, (4.5, 1.9, 1.6), 0.0, True),
    ("car", [(TRUCK, 0.3), (CAR, 0.7)], 0.85, (50.0, 8.0), (-6.0, 0.0), math.pi, BOUNDING_BOX,
     (4.2, 1.8, 1.5), 0.0, True),
    ("pedestrian", [(PEDESTRIAN, 1.0)], 0.8, (5.0, 20.0), (0.0, -1.2), -math.pi / 2, CYLINDER,
     (0.7, 0.7, 1.8), 0.0, False),
    ("truck", [(TRUCK, 1.0)], 0.75, (-20.0, 30.0), (3 * math.cos(0.3), 3 * math.sin(0.3)), 0.3,
     POLYGON, (8.0, 2.5, 3.2), 0.5, True),
    ("car", [(CAR, 1.0)], 0.95, (20.0, -15.0), (0.0, 0.0), 0.5, BOUNDING_BOX, (4.6, 1.9, 1.5), 0.0, True),
    ("unknown", [(UNKNOWN, 1.0)], 0.5, (-10.0, -10.0), (0.0, 0.0), 0.0, BOUNDING_BOX,
     (1.0, 1.0, 1.0), 0.0, False),
]


def ego_pose(t: float) -> tuple[float, float, float]:
    """The ego's (x, y, yaw) in `map` at `t` seconds: driving and turning slowly."""
    return 4.0 * t, 0.2 * t, 0.1 * t


def typestore(package: str):
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    extra = "" if package == "autoware_auto_perception_msgs" else EXTRA_CLASSES
    for name, text in PERCEPTION_MSGS.items():
        types.update(get_types_from_msg(text.replace("{extra}", extra), f"{package}/msg/{name}"))
    store.register(types)
    return store


def quat(yaw: float):
    return dict(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


class Messages:
    """Builds the messages with the typestore's classes."""

    def __init__(self, store, package: str):
        self.T = store.types
        self.p = package

    def t(self, name: str):
        return self.T[name if "/" in name else f"{self.p}/msg/{name}"]

    def header(self, t_ns: int, frame: str):
        Time = self.t("builtin_interfaces/msg/Time")
        return self.t("std_msgs/msg/Header")(stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame)

    def pose(self, x, y, z, yaw):
        g = lambda n: self.t(f"geometry_msgs/msg/{n}")
        return g("Pose")(position=g("Point")(x=x, y=y, z=z), orientation=g("Quaternion")(**quat(yaw)))

    def obj(self, o, k: int, to_frame):
        """The DetectedObject of object `o` in frame `k`; `to_frame` maps (x, y, yaw) from map."""
        _, classes, existence, (x0, y0), (vx, vy), yaw, shape, dims, ahead, has_twist = o
        g = lambda n: self.t(f"geometry_msgs/msg/{n}")
        x, y = x0 + vx * k * 0.1, y0 + vy * k * 0.1
        fx, fy, fyaw = to_frame(x, y, yaw)
        speed = math.hypot(vx, vy)
        vec = lambda a, b, c: g("Vector3")(x=a, y=b, z=c)
        twist = g("Twist")(linear=vec(speed if has_twist else 0.0, 0.0, 0.0), angular=vec(0.0, 0.0, 0.0))
        kin = self.t("DetectedObjectKinematics")(
            pose_with_covariance=g("PoseWithCovariance")(pose=self.pose(fx, fy, dims[2] / 2, fyaw), covariance=np.zeros(36)),
            has_position_covariance=False,
            orientation_availability=SIGN_UNKNOWN if shape == BOUNDING_BOX else AVAILABLE,
            twist_with_covariance=g("TwistWithCovariance")(twist=twist, covariance=np.zeros(36)),
            has_twist=has_twist,
            has_twist_covariance=False,
        )
        points = []
        if shape == POLYGON:
            half_l, half_w = dims[0] / 2, dims[1] / 2
            P32 = g("Point32")
            points = [P32(x=ahead + sx * half_l, y=sy * half_w, z=0.0)
                      for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        shp = self.t("Shape")(type=shape, footprint=g("Polygon")(points=points),
                              dimensions=vec(*(dims if shape != POLYGON else (0.0, 0.0, dims[2]))))
        Cls = self.t("ObjectClassification")
        return self.t("DetectedObject")(
            existence_probability=existence,
            classification=[Cls(label=c, probability=p) for c, p in classes],
            kinematics=kin,
            shape=shp,
        )

    def tf(self, t_ns: int, x, y, yaw):
        g = lambda n: self.t(f"geometry_msgs/msg/{n}")
        ts = g("TransformStamped")(
            header=self.header(t_ns, "map"),
            child_frame_id="base_link",
            transform=g("Transform")(translation=g("Vector3")(x=x, y=y, z=0.0), rotation=g("Quaternion")(**quat(yaw))),
        )
        return self.t("tf2_msgs/msg/TFMessage")(transforms=[ts])


def truth(frames: int) -> list[dict]:
    out = []
    for name, _, _, (x0, y0), (vx, vy), yaw, _, dims, ahead, _ in OBJECTS:
        centres = []
        for k in range(frames):
            x, y = x0 + vx * k * 0.1, y0 + vy * k * 0.1
            centres.append([x + ahead * math.cos(yaw), y + ahead * math.sin(yaw), dims[2] / 2])
        out.append({"label": name, "tracked": name != "unknown", "centres": centres, "velocity": [vx, vy]})
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="bag directory to create")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--ego", action="store_true", help="detections in a moving base_link, ego pose on /tf")
    ap.add_argument("--auto", action="store_true", help="autoware_auto_perception_msgs instead")
    args = ap.parse_args()
    package = "autoware_auto_perception_msgs" if args.auto else "autoware_perception_msgs"
    store = typestore(package)
    m = Messages(store, package)
    msgtype = f"{package}/msg/DetectedObjects"
    with Writer(args.out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection(TOPIC, msgtype, typestore=store)
        tf_conn = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store) if args.ego else None
        for k in range(args.frames):
            t_ns = START_NS + k * PERIOD_NS
            frame = "map"

            def to_frame(x, y, yaw):
                return x, y, yaw

            if args.ego:
                ex, ey, eyaw = ego_pose(k * 0.1)
                c, s = math.cos(eyaw), math.sin(eyaw)
                w.write(tf_conn, t_ns, store.serialize_cdr(m.tf(t_ns, ex, ey, eyaw), "tf2_msgs/msg/TFMessage"))
                frame = "base_link"

                def to_frame(x, y, yaw, ex=ex, ey=ey, eyaw=eyaw, c=c, s=s):
                    dx, dy = x - ex, y - ey
                    return c * dx + s * dy, -s * dx + c * dy, yaw - eyaw

            objects = [m.obj(o, k, to_frame) for o in OBJECTS]
            msg = m.t("DetectedObjects")(header=m.header(t_ns, frame), objects=objects)
            w.write(conn, t_ns, store.serialize_cdr(msg, msgtype))
    for line in truth(args.frames):
        print(json.dumps(line))
    return 0


if __name__ == "__main__":
    sys.exit(main())
