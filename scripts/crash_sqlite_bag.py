#!/usr/bin/env python3
"""Write a rosbag2-like sqlite3 bag until killed, as a recorder that crashes leaves one.

Writes OUT_BAG/OUT_BAG_0.db3 (no metadata.yaml, as ROS 2 Humble leaves a recording that did not
stop) with the tables rosbag2's sqlite3 plugin makes (`topics`, `messages`, the index
`timestamp_idx`) and its default pragmas (`journal_mode = MEMORY`, `synchronous = OFF`: fast,
and documented by rosbag2 to risk corrupting the file on a crash), one topic of 3000-byte
messages in transactions of 100, until the process is killed. For measuring what probmot reads
of such a file (docs/ros2.md):

    python3 scripts/crash_sqlite_bag.py crash & sleep 0.5; kill -9 $!
    probmot info crash

Needs only the Python standard library.
"""

from __future__ import annotations

import argparse
import os
import sqlite3
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out_bag", type=Path, help="bag directory to create")
    args = parser.parse_args()
    args.out_bag.mkdir()
    db = sqlite3.connect(args.out_bag / f"{args.out_bag.name}_0.db3", isolation_level=None)
    db.execute("PRAGMA journal_mode = MEMORY")
    db.execute("PRAGMA synchronous = OFF")
    db.execute(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
        "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL)"
    )
    db.execute(
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL)"
    )
    db.execute("CREATE INDEX timestamp_idx ON messages (timestamp ASC)")
    db.execute("INSERT INTO topics VALUES (1, '/points', 'pkg/msg/Blob', 'cdr', '')")
    data = os.urandom(3000)
    row = 0
    while True:
        db.execute("BEGIN")
        for _ in range(100):
            row += 1
            db.execute("INSERT INTO messages VALUES (?, 1, ?, ?)", (row, 1000 + row, data))
        db.execute("COMMIT")


if __name__ == "__main__":
    main()
