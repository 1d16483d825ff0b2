#!/usr/bin/env python3
"""Check a nuScenes tracking submission (e.g. from `probmot export nuscenes`) with the devkit.

Loads RESULTS.json with nuscenes-devkit's own loader, after loading the `tracking_nips_2019` config
as the devkit's evaluation does
(`nuscenes.eval.common.loaders.load_prediction(..., max_boxes_per_sample=500, box_cls=TrackingBox)`,
which asserts the box fields, the seven tracking classes, non-NaN float scores and at most 500 boxes
per sample), then checks the sample tokens against the tables in --meta DIR (sample.json,
scene.json): every token is a sample of the dataset, and every scene that has a token in the file
has all of its samples (the tracking evaluation requires the submission's samples to equal those
of the evaluated scenes). With --all-scenes, every scene of scene.json must be present. Also
checks that each box's sample_token equals its key and that a tracking_id keeps one
tracking_name within a scene.

Needs nuscenes-devkit (scripts/requirements-devkit.txt); does not need the sensor data.

Usage: python3 scripts/check_nuscenes_export.py RESULTS.json --meta DIR [--all-scenes]
Exit status: 0 valid, 1 invalid (the reasons are printed), 2 usage error.
"""

import argparse
import json
import math
import os
import sys
from collections import Counter, defaultdict


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", help="tracking submission JSON")
    ap.add_argument("--meta", required=True, help="directory holding sample.json and scene.json")
    ap.add_argument("--all-scenes", action="store_true", help="require every scene of scene.json")
    ap.add_argument("--max-boxes", type=int, default=None,
                    help="boxes allowed per sample (default: the config's, 500)")
    args = ap.parse_args()

    try:
        from nuscenes.eval.common.config import config_factory
        from nuscenes.eval.common.loaders import load_prediction
        from nuscenes.eval.tracking.data_classes import TrackingBox
    except ImportError as e:
        print(f"nuscenes-devkit is not installed ({e}); "
              "pip install -r scripts/requirements-devkit.txt", file=sys.stderr)
        return 2
    # Loading the config is what sets the devkit's list of tracking names (a module global that
    # TrackingBox checks against), as its evaluate.py does.
    cfg = config_factory("tracking_nips_2019")
    if args.max_boxes is None:
        args.max_boxes = int(cfg.max_boxes_per_sample)

    # The devkit's own loader: raises AssertionError on any malformed box or too many boxes.
    try:
        boxes, meta = load_prediction(args.results, args.max_boxes, TrackingBox, verbose=True)
    except (AssertionError, KeyError, TypeError, ValueError) as e:
        print(f"FAIL: the devkit's load_prediction refused {args.results}: {type(e).__name__}: {e}")
        return 1

    with open(os.path.join(args.meta, "sample.json")) as f:
        samples = {s["token"]: s for s in json.load(f)}
    with open(os.path.join(args.meta, "scene.json")) as f:
        scenes = {s["token"]: s for s in json.load(f)}

    problems = []
    for key in ("use_camera", "use_lidar", "use_radar", "use_map", "use_external"):
        if not isinstance(meta.get(key), bool):
            problems.append(f"meta.{key} is missing or not a boolean: {meta.get(key)!r}")

    tokens = set(boxes.sample_tokens)
    unknown = sorted(t for t in tokens if t not in samples)
    if unknown:
        problems.append(f"{len(unknown)} sample tokens are not in sample.json, e.g. {unknown[:3]}")

    covered = {samples[t]["scene_token"] for t in tokens if t in samples}
    wanted_scenes = set(scenes) if args.all_scenes else covered
    for st in sorted(wanted_scenes):
        scene = scenes.get(st)
        if scene is None:
            problems.append(f"scene token {st} (of a sample) is not in scene.json")
            continue
        chain, tok = [], scene["first_sample_token"]
        while tok and len(chain) <= len(samples):
            chain.append(tok)
            tok = samples[tok]["next"] if tok in samples else ""
        missing = [t for t in chain if t not in tokens]
        if missing:
            problems.append(f"scene {scene['name']} ({st}): {len(missing)} of its {len(chain)} "
                            f"sample tokens are missing, e.g. {missing[:3]}")

    names = defaultdict(set)
    per_class = Counter()
    n_boxes = 0
    for tok in boxes.sample_tokens:
        scene_tok = samples.get(tok, {}).get("scene_token", "?")
        for b in boxes[tok]:
            n_boxes += 1
            per_class[b.tracking_name] += 1
            if b.sample_token != tok:
                problems.append(f"results[{tok}] holds a box with sample_token {b.sample_token}")
            if not isinstance(b.tracking_id, str):
                problems.append(f"sample {tok}: tracking_id {b.tracking_id!r} is not a string")
            numbers = list(b.translation) + list(b.size) + list(b.rotation) + list(b.velocity)
            if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in numbers):
                problems.append(f"sample {tok}, track {b.tracking_id}: non-finite number")
            if len(b.translation) != 3 or len(b.size) != 3 or len(b.rotation) != 4 \
                    or len(b.velocity) != 2:
                problems.append(f"sample {tok}, track {b.tracking_id}: wrong field lengths")
            names[(scene_tok, b.tracking_id)].add(b.tracking_name)
    for (st, tid), ns in sorted(names.items()):
        if len(ns) > 1:
            problems.append(f"scene {st}: tracking_id {tid} has several tracking_names {sorted(ns)}")

    print(f"{args.results}: {len(tokens)} samples in {len(covered)} scenes, {n_boxes} boxes "
          f"({', '.join(f'{k} {v}' for k, v in sorted(per_class.items())) or 'none'}), "
          f"max {max((len(boxes[t]) for t in tokens), default=0)} per sample, meta {meta}")
    if problems:
        for p in problems[:50]:
            print(f"FAIL: {p}")
        if len(problems) > 50:
            print(f"FAIL: ... and {len(problems) - 50} more")
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
