#!/usr/bin/env python3
"""Read a tracked ROS 2 bag with `rosbags` (an independent ROS 2 implementation) and check it.

Reads every message of every topic with `rosbags.highlevel.AnyReader` (a bag directory with
metadata.yaml, or a single .mcap file), decodes each one, and checks the tracks topic:

- it has `--messages` messages of type vision_msgs/msg/Detection3DArray,
- their Detection3D.id values hold `--ids` distinct track ids,
- with `--truth FILE` (the JSON lines printed by scripts/make_rosbag_fixture.py): every track's
  box centre is within 0.5 m of the true centre of one object, the same object for all of that
  track's frames, with the object's label;
- when `mcap-ros2-support` is installed, it decodes the tracks topic too (its own CDR decoder,
  driven by the schema text): the same number of messages and the same ids;
- for a bag directory: its metadata.yaml (read by rosbags' rosbag2 Reader, as `ros2 bag info`
  shows it) lists every topic with the number of messages actually read, and its total.

    python3 scripts/check_ros2_bag.py tracked_bag/ --tracks-topic /tracks --messages 60 --ids 3 \
        --truth truth.jsonl

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
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(f"check_ros2_bag.py: error: {e}; install `rosbags` (scripts/requirements.txt)\n")
    sys.exit(2)

TRACKS_TYPE = "vision_msgs/msg/Detection3DArray"


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
                seen |= {d.id for d in msg.detections}
    if (n, seen) != (count, ids):
        errors.append(f"mcap-ros2-support decodes {n} messages with ids {sorted(seen)}")
    return f"; mcap-ros2-support: {n} messages, {len(seen)} ids"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("--tracks-topic", default="/tracks")
    ap.add_argument("--messages", type=int, required=True)
    ap.add_argument("--ids", type=int, required=True)
    ap.add_argument("--truth", type=Path)
    args = ap.parse_args()
    truth = []
    if args.truth:
        truth = [json.loads(line) for line in args.truth.read_text().splitlines() if line.strip()]
    errors = []
    per_topic: dict[str, int] = {}
    ids: set[str] = set()
    tracks_messages = 0
    track_object: dict[str, str] = {}
    with AnyReader([args.bag]) as reader:
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            per_topic[conn.topic] = per_topic.get(conn.topic, 0) + 1
            if conn.topic != args.tracks_topic:
                continue
            if conn.msgtype != TRACKS_TYPE:
                errors.append(f"{conn.topic} has type {conn.msgtype}, expected {TRACKS_TYPE}")
                break
            frame = tracks_messages
            tracks_messages += 1
            for det in msg.detections:
                ids.add(det.id)
                if not truth:
                    continue
                p = det.bbox.center.position
                label = det.results[0].hypothesis.class_id if det.results else ""
                near = [
                    o for o in truth
                    if frame < len(o["centres"])
                    and math.dist((p.x, p.y, p.z), o["centres"][frame]) < 2.0
                ]
                if len(near) != 1 or near[0]["label"] != label:
                    errors.append(f"frame {frame}: track {det.id} ({label}) at ({p.x:.2f}, {p.y:.2f}) "
                                  "is not at one true object of its label")
                elif track_object.setdefault(det.id, near[0]["label"]) != near[0]["label"]:
                    errors.append(f"frame {frame}: track {det.id} switched objects")
    mcap_ros2 = mcap_ros2_check(args.bag, args.tracks_topic, tracks_messages, ids, errors)
    if args.bag.is_dir():
        with Reader(args.bag) as bag:
            listed = {c.topic: c.msgcount for c in bag.connections}
            if listed != per_topic:
                errors.append(f"metadata.yaml lists {listed}, the messages read are {per_topic}")
            if bag.message_count != sum(per_topic.values()):
                errors.append(f"metadata.yaml message_count {bag.message_count}")
    if tracks_messages != args.messages:
        errors.append(f"{args.tracks_topic}: {tracks_messages} messages, expected {args.messages}")
    if len(ids) != args.ids:
        errors.append(f"{args.tracks_topic}: ids {sorted(ids)}, expected {args.ids} distinct ids")
    summary = ", ".join(f"{t} {n}" for t, n in sorted(per_topic.items()))
    if errors:
        print("\n".join(errors[:20]))
        return 1
    print(f"ok: {summary}; {len(ids)} track ids{mcap_ros2}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
