#!/usr/bin/env python3
"""Reads the events channel that `probmot eval --events` writes (probmot.EvalEvents, protobuf)
with the Python `mcap` reader, decoding each message with the FileDescriptorSet embedded in its
schema record (`mcap-protobuf-support`), as any MCAP program would. Prints JSON:
{"frames": N, "counts": {class: {kind: n}}, "switches": [[stamp_ns, class, truth, prev, track]]}.

Usage: python3 scripts/read_eval_events.py EVENTS.mcap [--topic /eval/events]
"""

import argparse
import json
import os
import sys
from collections import defaultdict

try:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
except ImportError as e:  # depends on the environment
    sys.exit(
        f"{os.path.basename(sys.argv[0])}: error: {e}; install the packages with "
        "`python3 -m pip install -r scripts/requirements-view.txt` (the viewer only, about 770 MB)"
    )

KINDS = {0: "tp", 1: "ids", 2: "frag", 3: "fp", 4: "fn"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--topic", default="/eval/events")
    a = ap.parse_args()
    counts = defaultdict(lambda: {k: 0 for k in KINDS.values()})
    switches = []
    frames = 0
    with open(a.file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, _, msg, ev in reader.iter_decoded_messages(topics=[a.topic]):
            assert schema.name == "probmot.EvalEvents", schema.name
            assert ev.stamp == msg.log_time, (ev.stamp, msg.log_time)
            frames += 1
            for e in ev.events:
                counts[e.label][KINDS[e.kind]] += 1
                if e.kind == 1:
                    switches.append(
                        [ev.stamp, e.label, e.truth_id, e.previous_track_id, e.track_id]
                    )
    print(json.dumps({"frames": frames, "counts": counts, "switches": switches}))


if __name__ == "__main__":
    main()
