#!/usr/bin/env python3
"""Writes the hand-made inputs of tests/fixtures/fuzz/ (see its README.md); same bytes every run.

Usage: python3 fuzz/make_regressions.py [OUT_DIR]   (default: tests/fixtures/fuzz)
Needs the Python package zstandard (pulled in by scripts/requirements.txt).
"""

import os
import struct
import sys

import zstandard

MAGIC = b"\x89MCAP0\r\n"


def rec(op: int, body: bytes) -> bytes:
    return bytes([op]) + struct.pack("<Q", len(body)) + body


def s(x: bytes) -> bytes:
    return struct.pack("<I", len(x)) + x


def main() -> None:
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "tests", "fixtures", "fuzz")
    os.makedirs(out, exist_ok=True)
    header = rec(0x01, s(b"") + s(b"fuzz"))
    files = {}
    # A top-level record whose length field claims ~4 GiB, in a 33-byte file.
    files["record_length_4gib.mcap"] = (
        MAGIC + b"\x01" + struct.pack("<Q", 0xFFFF_FF00) + b"\0" * 16
    )
    # A header record whose profile string claims ~4 GiB.
    files["string_length_4gib.mcap"] = (
        MAGIC + rec(0x01, struct.pack("<I", 0xFFFF_FF00) + b"\0" * 8) + MAGIC
    )
    # An attachment whose record ends right after its data length (no room for the CRC).
    att = struct.pack("<QQ", 1, 1) + s(b"") + s(b"") + struct.pack("<Q", 0)
    files["attachment_without_crc.mcap"] = MAGIC + header + rec(0x09, att) + MAGIC
    # A zstd chunk whose first record claims 1 GiB.
    inner = b"\x05" + struct.pack("<Q", 1 << 30) + b"\0" * 32
    comp = zstandard.ZstdCompressor().compress(inner)
    chunk = (
        struct.pack("<QQQI", 0, 0, len(inner), 0)
        + s(b"zstd")
        + struct.pack("<Q", len(comp))
        + comp
    )
    files["chunk_record_length_1gib.mcap"] = MAGIC + header + rec(0x06, chunk) + MAGIC
    # An uncompressed chunk whose record runs past the chunk's end (into the next record).
    inner = b"\x05" + struct.pack("<Q", 100) + b"\0" * 10
    chunk = (
        struct.pack("<QQQI", 0, 0, len(inner), 0)
        + s(b"")
        + struct.pack("<Q", len(inner))
        + inner
    )
    files["uncompressed_chunk_record_past_end.mcap"] = (
        MAGIC + header + rec(0x06, chunk) + rec(0x0C, s(b"m") + s(b"")) + b"\0" * 100 + MAGIC
    )
    # Issue #36: a zstd chunk declaring 2.5 GB of records (refused by the size limit before it
    # is decompressed), and records that break the structure the MCAP specification requires.
    end = rec(0x0F, struct.pack("<I", 0)) + rec(0x02, struct.pack("<QQI", 0, 0, 0)) + MAGIC

    def channel(cid: int, schema_id: int, topic: bytes) -> bytes:
        return rec(0x04, struct.pack("<HH", cid, schema_id) + s(topic) + s(b"json") + s(b""))

    def schema(sid: int, data: bytes) -> bytes:
        return rec(0x03, struct.pack("<H", sid) + s(b"a") + s(b"jsonschema") + s(data))

    def message(cid: int) -> bytes:
        return rec(0x05, struct.pack("<HIQQ", cid, 0, 1, 1) + b"{}")

    inner = channel(1, 0, b"/a") + message(1)
    comp = zstandard.ZstdCompressor().compress(inner)
    chunk = (
        struct.pack("<QQQI", 0, 0, 2_684_354_560, 0)
        + s(b"zstd")
        + struct.pack("<Q", len(comp))
        + comp
    )
    files["chunk_declaring_2_5gb.mcap"] = MAGIC + header + rec(0x06, chunk) + end
    files["message_on_undefined_channel.mcap"] = (
        MAGIC + header + channel(1, 0, b"/a") + message(2) + end
    )
    files["channel_redefined.mcap"] = (
        MAGIC + header + channel(1, 0, b"/a") + message(1) + channel(1, 0, b"/b") + end
    )
    files["channel_on_undefined_schema.mcap"] = MAGIC + header + channel(1, 3, b"/a") + end
    files["schema_redefined.mcap"] = (
        MAGIC + header + schema(1, b"{}") + schema(1, b'{"x":1}') + end
    )
    for name, data in files.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)
        print(name, len(data))


if __name__ == "__main__":
    main()
