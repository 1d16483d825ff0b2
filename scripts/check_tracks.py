#!/usr/bin/env python3
"""Print the tracks of one frame of a tracked MCAP file, decoded by a third-party reader.

The file is read with the `mcap` package and decoded with `mcap_protobuf`'s DecoderFactory,
using only the protobuf schemas embedded in the file (no generated code from this repository),
so the output is an independent check of what `probmot track` wrote.

Frame N is the N-th message (0-based, in file order) on the topic. Exit status: 0 on success,
2 on a usage error, an unreadable file, a missing topic or an out-of-range frame.

    python3 scripts/check_tracks.py drive.tracked.mcap --frame 10
    python3 scripts/check_tracks.py drive.tracked.mcap --topic /ground_truth --json

Needs `python3 -m pip install -r scripts/requirements.txt`.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, NoReturn

try:
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(
        f"check_tracks.py: error: {e}; install the readers with "
        "`python3 -m pip install -r scripts/requirements.txt`\n"
    )
    sys.exit(2)

TRACKS_SCHEMA = "probmot.Tracks3D"
PROG = "check_tracks.py"


def fail(message: str) -> NoReturn:
    """Print an error to stderr and exit with status 2."""
    sys.stderr.write(f"{PROG}: error: {message}\n")
    sys.exit(2)


def track_to_dict(t: Any) -> dict[str, Any]:
    """One probmot.Track3D as plain Python values (unset sub-messages read as zeros)."""
    return {
        "id": int(t.id),
        "label": t.label,
        "center": [t.center.x, t.center.y, t.center.z],
        "size": [t.size.length, t.size.width, t.size.height],
        "yaw": t.yaw,
        "velocity": [t.velocity.x, t.velocity.y, t.velocity.z],
        "score": t.score,
        "frames_since_update": int(t.frames_since_update),
    }


def read_frame(path: str, topic: str, frame: int) -> dict[str, Any]:
    """Decode message number `frame` of `topic` and return it as a JSON-ready dict."""
    if frame < 0:
        fail(f"frame index {frame} is out of range (frames are numbered from 0)")
    try:
        f = open(path, "rb")
    except OSError as e:
        fail(f"cannot open {path}: {e.strerror}")
    with f:
        try:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            if summary is not None:
                topics = sorted({c.topic for c in summary.channels.values()})
                if topic not in topics:
                    fail(f"{path} has no topic {topic!r} (topics: {', '.join(topics) or 'none'})")
            count = 0
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=[topic], log_time_order=False
            ):
                name = schema.name if schema is not None else "(no schema)"
                if name != TRACKS_SCHEMA:
                    fail(f"topic {topic!r} has schema {name!r}, not {TRACKS_SCHEMA!r}")
                if count == frame:
                    return {
                        "stamp": int(decoded.stamp),
                        "tracks": [track_to_dict(t) for t in decoded.tracks],
                    }
                count += 1
        except McapError as e:
            fail(f"cannot read {path}: {type(e).__name__}: {e}")
    if count == 0:
        fail(f"{path} has no messages on topic {topic!r}")
    fail(f"frame index {frame} is out of range: topic {topic!r} has {count} messages (0..{count - 1})")


def print_text(path: str, topic: str, frame: int, data: dict[str, Any]) -> None:
    """Human-readable listing of one frame."""
    print(f"{path} {topic} frame {frame}: stamp {data['stamp']} ns, {len(data['tracks'])} tracks")
    if not data["tracks"]:
        return
    header = (
        f"{'id':>6} {'label':<12} {'center x, y, z (m)':>27} {'size l, w, h (m)':>20} "
        f"{'yaw':>7} {'velocity x, y, z (m/s)':>24} {'score':>6} {'fsu':>4}"
    )
    print(header)
    for t in data["tracks"]:
        center = ", ".join(f"{v:8.3f}" for v in t["center"])
        size = ", ".join(f"{v:5.2f}" for v in t["size"])
        vel = ", ".join(f"{v:6.2f}" for v in t["velocity"])
        print(
            f"{t['id']:>6} {t['label']:<12} {center:>27} {size:>20} {t['yaw']:7.3f} "
            f"{vel:>24} {t['score']:6.3f} {t['frames_since_update']:>4}"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Print the tracks of one frame of a tracked MCAP file, decoded with the "
        "third-party `mcap` + `mcap-protobuf-support` readers from the schemas embedded in "
        "the file.",
    )
    parser.add_argument("file", metavar="TRACKED.mcap", help="MCAP file written by `probmot track`")
    parser.add_argument(
        "--topic", default="/tracks", help="topic with probmot.Tracks3D messages (default: /tracks)"
    )
    parser.add_argument(
        "--frame",
        type=int,
        default=0,
        metavar="N",
        help="0-based index of the message on the topic, in file order (default: 0)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object {stamp, tracks: [{id, label, center, size, yaw, velocity, "
        "score, frames_since_update}]} with floats at full precision",
    )
    args = parser.parse_args(argv)
    data = read_frame(args.file, args.topic, args.frame)
    if args.json:
        # json.dumps writes floats with repr(), which round-trips every double exactly.
        print(json.dumps(data))
    else:
        print_text(args.file, args.topic, args.frame, data)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:  # e.g. piped into `head`
        sys.stderr.close()
        sys.exit(0)
