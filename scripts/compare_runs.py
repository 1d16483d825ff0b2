#!/usr/bin/env python3
"""Put two tracked runs of the same drive side by side in one Rerun recording (.rrd).

Run A is logged under `a/world/...` and run B under `b/world/...`, with the entities of
to_rerun.py (detections, tracks, ground_truth, trails, velocity), on shared `log_time` and
`frame` timelines: the frame index counts the distinct log times of both files, so the same
index is the same moment in both. The blueprint holds two top-down 3D views, A left and B right,
looking at the same region.

    probmot track drive.mcap -o a.mcap
    probmot track drive.mcap -o b.mcap --max-age 5
    python3 scripts/compare_runs.py a.mcap b.mcap -o compare.rrd
    rerun compare.rrd

Exit status: 0 on success, 2 on a usage error, an unreadable file or a missing topic.
Needs `python3 -m pip install -r scripts/requirements-view.txt` (the viewer only, about 770 MB).
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import to_rerun  # noqa: E402  (same directory; exits with a clear message without rerun-sdk)
from to_rerun import rr, rrb  # noqa: E402

PROG = "compare_runs.py"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Two tracked MCAP files of the same drive side by side in one Rerun .rrd "
        "recording: run A under a/world, run B under b/world, two top-down views.",
    )
    parser.add_argument("a", metavar="A.mcap", help="first tracked MCAP file (left view)")
    parser.add_argument("b", metavar="B.mcap", help="second tracked MCAP file (right view)")
    to_rerun.add_common_args(parser)
    parser.add_argument("--name-a", default=None, help="title of view A (default: file name)")
    parser.add_argument("--name-b", default=None, help="title of view B (default: file name)")
    args = parser.parse_args(argv)
    if args.trail < 1:
        to_rerun.fail(PROG, "--trail must be at least 1")
    try:
        runs = [
            to_rerun.read_run(
                path,
                args.detections_topic,
                args.tracks_topic,
                args.truth_topic,
                classes=args.classes,
            )
            for path in (args.a, args.b)
        ]
        frame_of = to_rerun.frame_index(runs)
        names = [
            args.name_a or f"A: {os.path.basename(args.a)}",
            args.name_b or f"B: {os.path.basename(args.b)}",
        ]
        if names[0] == names[1]:
            names = [f"{names[0]} (A)", f"{names[1]} (B)"]
        # Both views are framed on the union of the runs, so they show the same region; each is
        # half as wide as a single view, hence the higher eye.
        blueprint = rrb.Blueprint(
            rrb.Horizontal(
                to_rerun.top_down_view(runs, "a/world", names[0], height_factor=1.0),
                to_rerun.top_down_view(runs, "b/world", names[1], height_factor=1.0),
            )
        )

        def log(rec: rr.RecordingStream) -> None:
            for prefix, run in zip(("a/world", "b/world"), runs):
                rec.log(prefix, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
                to_rerun.log_run(rec, run, frame_of, prefix, args.trail)

        to_rerun.save_atomically(args.output, blueprint, args.recording_id, log)
    except to_rerun.UsageError as e:
        to_rerun.fail(PROG, str(e))
    ids = [len({b.id for boxes in (r.tracks or {}).values() for b in boxes}) for r in runs]
    print(
        f"{args.output}: {len(frame_of)} frames; A {ids[0]} track ids, B {ids[1]} track ids"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
