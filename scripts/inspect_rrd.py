#!/usr/bin/env python3
"""Summarise a Rerun .rrd file as JSON, read back with the Rerun SDK's own reader.

Uses `rerun.experimental.RrdReader` (rerun-sdk 0.36): the stores of the file (recordings and
blueprints), then every chunk of the first recording, summed per entity path:

    {"file": ..., "recordings": [{"application_id", "recording_id"}], "blueprints": [...],
     "entities": {"/world/tracks": {"rows": 40, "static_rows": 0,
                                    "components": ["Boxes3D:centers", ...],
                                    "instances": 202,
                                    "timelines": {"frame": {"rows": 40, "distinct": 40,
                                                            "min": 0, "max": 39}, ...}}},
     "views": [{"class": "3D", "name": ..., "origin": "world", "eye_position": [x, y, z],
                "look_target": [x, y, z], "eye_up": [x, y, z]}]}

`rows` counts logged rows, `instances` the largest total length of one component over them (the
number of boxes, strips or arrows), and per timeline `distinct` the number of distinct times.
Times of timestamp timelines are nanoseconds since the epoch.

    python3 scripts/inspect_rrd.py drive.rrd

Used by tests/it/rerun_scripts.rs. Exit status 2 when the file cannot be read.
"""

from __future__ import annotations

import json
import sys
from typing import Any

try:
    import pyarrow as pa
    import rerun as rr
    from rerun.experimental import RrdReader
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(
        f"inspect_rrd.py: error: {e}; install with "
        "`python3 -m pip install -r scripts/requirements.txt`\n"
    )
    sys.exit(2)


def _index_values(col: Any) -> list[int]:
    if pa.types.is_timestamp(col.type) or pa.types.is_duration(col.type):
        col = col.cast(pa.int64())
    return [v for v in col.to_pylist() if v is not None]


def inspect(path: str) -> dict[str, Any]:
    """The JSON-ready summary of `path` described in the module docstring."""
    reader = RrdReader(path)
    out: dict[str, Any] = {
        "file": path,
        "sdk_version": rr.__version__,
        "recordings": [
            {"application_id": s.application_id, "recording_id": s.recording_id}
            for s in reader.recordings()
        ],
        "blueprints": [
            {"application_id": s.application_id, "recording_id": s.recording_id}
            for s in reader.blueprints()
        ],
        "entities": {},
    }
    entities: dict[str, Any] = out["entities"]
    times: dict[tuple[str, str], list[int]] = {}
    for chunk in reader.stream().to_chunks():
        e = entities.setdefault(
            chunk.entity_path,
            {"rows": 0, "static_rows": 0, "components": set(), "lengths": {}, "timelines": {}},
        )
        e["rows"] += chunk.num_rows
        if chunk.is_static:
            e["static_rows"] += chunk.num_rows
        batch = chunk.to_record_batch()
        for i, f in enumerate(batch.schema):
            meta = {k.decode(): v.decode() for k, v in (f.metadata or {}).items()}
            kind = meta.get("rerun:kind")
            col = batch.column(i)
            if kind == "index":
                name = meta.get("rerun:index_name", f.name)
                tl = e["timelines"].setdefault(name, {"rows": 0})
                tl["rows"] += chunk.num_rows
                times.setdefault((chunk.entity_path, name), []).extend(_index_values(col))
            elif kind == "data":
                comp = meta.get("rerun:component", f.name)
                e["components"].add(comp)
                if pa.types.is_list(col.type) or pa.types.is_large_list(col.type):
                    n = sum(len(v) for v in col.to_pylist() if v is not None)
                else:
                    n = len(col) - col.null_count
                e["lengths"][comp] = e["lengths"].get(comp, 0) + n
    for (entity, name), values in times.items():
        tl = entities[entity]["timelines"][name]
        tl["distinct"] = len(set(values))
        tl["min"] = min(values) if values else None
        tl["max"] = max(values) if values else None
    for e in entities.values():
        e["components"] = sorted(e["components"])
        e["instances"] = max(e.pop("lengths").values(), default=0)
    out["entities"] = dict(sorted(entities.items()))
    out["views"] = views(reader)
    return out


def views(reader: Any) -> list[dict[str, Any]]:
    """The views of the file's blueprints: class ("3D", "2D", ...), name, origin, and for 3D
    views the eye position and look target when the blueprint sets them."""
    found: dict[str, dict[str, Any]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store).to_chunks():
            path = chunk.entity_path
            if not path.startswith("/view/"):
                continue
            view_path = "/".join(path.split("/")[:3])
            v = found.setdefault(view_path, {})
            batch = chunk.to_record_batch()
            cols = {n: batch.column(n).to_pylist() for n in batch.column_names}

            def last(name: str) -> Any:
                rows = [r for r in cols.get(name, []) if r]
                return rows[-1][0] if rows else None

            for key, comp in [
                ("class", "ViewBlueprint:class_identifier"),
                ("name", "ViewBlueprint:display_name"),
                ("origin", "ViewBlueprint:space_origin"),
                ("eye_position", "EyeControls3D:position"),
                ("look_target", "EyeControls3D:look_target"),
                ("eye_up", "EyeControls3D:eye_up"),
            ]:
                value = last(comp)
                if value is not None:
                    v[key] = value
    return [found[k] for k in sorted(found)]


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or args[0] in ("-h", "--help"):
        sys.stderr.write("usage: inspect_rrd.py FILE.rrd\n")
        return 2
    try:
        summary = inspect(args[0])
    except Exception as e:  # the reader raises plain ValueError/OSError/Rust panics
        sys.stderr.write(f"inspect_rrd.py: error: cannot read {args[0]}: {e}\n")
        return 2
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
