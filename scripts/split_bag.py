#!/usr/bin/env python3
"""Split a rosbag2 bag directory into several files, as `ros2 bag record --max-bag-size` does,
with the `rosbags` library (an independent rosbag2 writer, not probmot).

Reads every message of SRC_BAG in log-time order and writes them, unchanged, into OUT_BAG as
`--parts` files of about equal message counts (or split before the message indexes given with
`--at`), each a complete rosbag2 MCAP file written by rosbags' Writer, then one metadata.yaml
listing the files in order, as rosbag2 writes it for a split bag. As rosbag2 does when it
splits, every file declares every topic, and the files after the first declare them in reverse
order (so the same topic has other channel and schema ids in each file).

    python3 scripts/split_bag.py SRC_BAG OUT_BAG [--parts 2 | --at 10 --at 20] [--compress]
        [--compress-messages] [--storage sqlite3 [--no-definitions]]

--compress writes each file compressed whole with zstd (`compression_mode: file`, files named
NAME.mcap.zstd), as `ros2 bag record --compression-mode file` does; --compress-messages
compresses each message on its own (`compression_mode: message`). With --parts 1 it is the
whole bag in one file. --storage sqlite3 writes `.db3` files (rosbag2's sqlite3 storage, the
default up to ROS 2 Humble); --no-definitions then removes the message_definitions table and
sets the schema version to 3, as a Humble bag is (it stores no message definitions).

Needs `rosbags` (scripts/requirements.txt).
"""

from __future__ import annotations

import argparse
import shutil
import sqlite3
import sys
import tempfile
from pathlib import Path

try:
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from ruamel.yaml import YAML
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(f"split_bag.py: error: {e}; install `rosbags` (scripts/requirements.txt)\n")
    sys.exit(2)


def write_part(path: Path, conns, msgs, reverse: bool, args) -> dict:
    """Writes `msgs` ([(conn, t, raw)]) as the one-file bag `path`; returns its metadata."""
    storage = StoragePlugin.SQLITE3 if args.storage == "sqlite3" else StoragePlugin.MCAP
    w = Writer(path, version=8, storage_plugin=storage)
    if args.compress:
        w.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    if args.compress_messages:
        w.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with w:
        out = {}
        for c in reversed(conns) if reverse else conns:
            out[c.id] = w.add_connection(
                c.topic,
                c.msgtype,
                msgdef=c.msgdef.data,
                rihs01=c.digest or "RIHS01_" + "0" * 64,
                serialization_format=c.ext.serialization_format,
                offered_qos_profiles=c.ext.offered_qos_profiles,
            )
        for c, t, raw in msgs:
            w.write(out[c.id], t, raw)
    if args.no_definitions:
        for db in path.glob("*.db3"):
            con = sqlite3.connect(db)
            con.executescript(
                "DROP TABLE message_definitions; UPDATE schema SET schema_version = 3;"
            )
            con.commit()
            con.close()
    yaml = YAML(typ="safe")
    return yaml.load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("out", type=Path, help="bag directory to create")
    ap.add_argument("--parts", type=int, default=2)
    ap.add_argument("--at", type=int, action="append", default=[], help="message index a file starts at")
    ap.add_argument("--compress", action="store_true", help="zstd file compression")
    ap.add_argument("--compress-messages", action="store_true", help="zstd message compression")
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    ap.add_argument("--no-definitions", action="store_true", help="sqlite3: as ROS 2 Humble")
    args = ap.parse_args()
    with Reader(args.src) as r:
        conns = list(r.connections)
        msgs = list(r.messages())
    n = len(msgs)
    cuts = sorted(set(args.at)) if args.at else [n * k // args.parts for k in range(1, args.parts)]
    bounds = [0, *cuts, n]
    name = args.out.name
    args.out.mkdir()
    metas, files = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(len(bounds) - 1):
            part = Path(tmp) / f"{name}_{k}"
            meta = write_part(part, conns, msgs[bounds[k]:bounds[k + 1]], k > 0, args)
            (src,) = meta["relative_file_paths"]
            dst = f"{name}_{k}" + src[len(part.name):]
            shutil.move(str(part / src), str(args.out / dst))
            metas.append(meta)
            files.append({**meta["files"][0], "path": dst})
    counted = [m for m in metas if m["message_count"]]
    start = min(m["starting_time"]["nanoseconds_since_epoch"] for m in counted)
    end = max(m["starting_time"]["nanoseconds_since_epoch"] + m["duration"]["nanoseconds"] for m in counted)
    topics = {}
    for m in metas:
        for t in m["topics_with_message_count"]:
            key = t["topic_metadata"]["name"]
            if key in topics:
                topics[key]["message_count"] += t["message_count"]
            else:
                topics[key] = dict(t)
    merged = {
        **metas[0],
        "relative_file_paths": [f["path"] for f in files],
        "files": files,
        "starting_time": {"nanoseconds_since_epoch": start},
        "duration": {"nanoseconds": end - start},
        "message_count": sum(m["message_count"] for m in metas),
        "topics_with_message_count": list(topics.values()),
    }
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    with (args.out / "metadata.yaml").open("w") as f:
        yaml.dump({"rosbag2_bagfile_information": merged}, f)
    print(f"{args.out}: {len(files)} files, {n} messages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
