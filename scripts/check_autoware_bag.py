#!/usr/bin/env python3
"""Read a tracked Autoware bag with `rosbags` and check its TrackedObjects.

Reads every message of every topic with `rosbags.highlevel.AnyReader` (a bag directory with
metadata.yaml, or a single .mcap file). rosbags' own type store has no Autoware types, so the
TrackedObjects are decoded from the definitions the bag's schema record carries. Checks:

- the tracks topic has `--messages` messages of type autoware_perception_msgs/msg/TrackedObjects;
- their object ids hold `--ids` distinct UUIDs;
- with `--truth FILE` (the JSON lines of scripts/make_autoware_bag.py): every tracked object is
  within 1 m of the true centre of one object of its class, the same object for every frame of
  its UUID; every tracked true object has one UUID; in the last 10 frames the twist (in the
  object's frame) turned by the yaw is within 0.5 m/s of the true velocity and `is_stationary`
  is true for the parked car only; pose covariances are positive on the diagonal; existence probabilities in [0, 1];
- when `mcap-ros2-support` is installed, it decodes the tracks too (its own CDR decoder driven
  by the schema text): the same number of messages and UUIDs;
- for a bag directory: its metadata.yaml lists every topic with the number of messages read.

    python3 scripts/check_autoware_bag.py tracked_bag/ --messages 60 --ids 5 --truth truth.jsonl

Prints one summary line and exits 0, or prints what is wrong and exits 1.
Needs `rosbags` (scripts/requirements.txt).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

try:
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(f"check_autoware_bag.py: error: {e}; install `rosbags` (scripts/requirements.txt)\n")
    sys.exit(2)

TRACKS_TYPE = "autoware_perception_msgs/msg/TrackedObjects"
TOPIC = "/perception/object_recognition/tracking/objects"
CLASSES = ["unknown", "car", "truck", "bus", "trailer", "motorcycle", "bicycle", "pedestrian",
           "animal", "hazard", "over_drivable", "under_drivable"]


def mcap_ros2_check(bag: Path, topic: str, count: int, ids: set, errors: list) -> str:
    """Decodes the tracks with mcap-ros2-support when installed; returns a note for the summary."""
    try:
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
    except ImportError:
        return ""
    files = sorted(bag.glob("*.mcap")) if bag.is_dir() else [bag]
    n, seen = 0, set()
    for path in files:
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, _, _, msg in reader.iter_decoded_messages(topics=[topic]):
                n += 1
                seen |= {bytes(o.object_id.uuid) for o in msg.objects}
    if (n, seen) != (count, ids):
        errors.append(f"mcap-ros2-support decodes {n} messages with {len(seen)} ids")
    return f"; mcap-ros2-support: {n} messages, {len(seen)} ids"


def yaw_of(q) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def check_object(o, frame: int, frames: int, truth: list, owner: dict, errors: list) -> str:
    """Checks one TrackedObject of frame `frame`; returns its class name."""
    uid = bytes(o.object_id.uuid)
    label = CLASSES[o.classification[0].label] if o.classification else "none"
    k = o.kinematics
    p = k.pose_with_covariance.pose.position
    cov = k.pose_with_covariance.covariance
    if not 0.0 <= o.existence_probability <= 1.0:
        errors.append(f"frame {frame}: existence_probability {o.existence_probability}")
    if min(cov[0], cov[7], cov[14], cov[35]) <= 0.0:
        errors.append(f"frame {frame}: pose covariance diagonal {cov[[0, 7, 14, 35]]}")
    if not truth:
        return label
    near = [i for i, t in enumerate(truth) if math.dist((p.x, p.y), t["centres"][frame][:2]) < 1.0]
    if len(near) != 1 or truth[near[0]]["label"] != label:
        errors.append(f"frame {frame}: {uid.hex()} ({label}) at ({p.x:.2f}, {p.y:.2f}) is not at one "
                      "true object of its class")
        return label
    if owner.setdefault(uid, near[0]) != near[0]:
        errors.append(f"frame {frame}: {uid.hex()} switched objects")
    if frame >= frames - 10:
        t = k.twist_with_covariance.twist.linear
        yaw = yaw_of(k.pose_with_covariance.pose.orientation)
        vx = math.cos(yaw) * t.x - math.sin(yaw) * t.y
        vy = math.sin(yaw) * t.x + math.cos(yaw) * t.y
        true_v = truth[near[0]]["velocity"]
        if math.dist((vx, vy), true_v) > 0.5:
            errors.append(f"frame {frame}: {label} velocity ({vx:.2f}, {vy:.2f}), true {true_v}")
        if k.is_stationary != (math.hypot(*true_v) == 0.0):
            errors.append(f"frame {frame}: {label} at speed {math.hypot(*true_v)}: is_stationary "
                          f"{k.is_stationary}")
    return label


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("--tracks-topic", default=TOPIC)
    ap.add_argument("--messages", type=int, required=True)
    ap.add_argument("--ids", type=int, required=True)
    ap.add_argument("--truth", type=Path)
    args = ap.parse_args()
    truth = []
    if args.truth:
        lines = args.truth.read_text().splitlines()
        truth = [t for t in (json.loads(line) for line in lines if line.strip()) if t["tracked"]]
    errors: list[str] = []
    per_topic: dict[str, int] = {}
    ids: set[bytes] = set()
    classes: set[str] = set()
    owner: dict[bytes, int] = {}
    frame = 0
    if TRACKS_TYPE in get_typestore(Stores.LATEST).types:
        errors.append("rosbags' own type store has TrackedObjects: the bag's definitions go untested")
    with AnyReader([args.bag]) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            per_topic[conn.topic] = per_topic.get(conn.topic, 0) + 1
            if conn.topic != args.tracks_topic:
                continue
            if conn.msgtype != TRACKS_TYPE:
                errors.append(f"{conn.topic} has type {conn.msgtype}, expected {TRACKS_TYPE}")
                break
            for o in msg.objects:
                ids.add(bytes(o.object_id.uuid))
                classes.add(check_object(o, frame, args.messages, truth, owner, errors))
            frame += 1
    mcap_ros2 = "" if errors else mcap_ros2_check(args.bag, args.tracks_topic, frame, ids, errors)
    if args.bag.is_dir():
        with Reader(args.bag) as bag:
            listed = {c.topic: c.msgcount for c in bag.connections}
            if listed != per_topic:
                errors.append(f"metadata.yaml lists {listed}, the messages read are {per_topic}")
    if frame != args.messages:
        errors.append(f"{args.tracks_topic}: {frame} messages, expected {args.messages}")
    if len(ids) != args.ids:
        errors.append(f"{args.tracks_topic}: {len(ids)} UUIDs, expected {args.ids}")
    if truth:
        want = {t["label"] for t in truth}
        if classes != want:
            errors.append(f"classes {sorted(classes)}, expected {sorted(want)}")
        if sorted(owner.values()) != list(range(len(truth))):
            errors.append(f"true objects per UUID: {sorted(owner.values())}")
    summary = ", ".join(f"{t} {n}" for t, n in sorted(per_topic.items()))
    if errors:
        print("\n".join(errors[:20]))
        return 1
    print(f"ok: {summary}; {len(ids)} UUIDs, classes {', '.join(sorted(classes))}{mcap_ros2}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
