#!/usr/bin/env python3
"""HOTA numbers computed by the TrackEval package (Luiten et al., IJCV 2020; PyPI `trackeval`,
pinned in scripts/requirements.txt), to check `probmot eval`'s HOTA against.

Only glue is written here; every metric and preprocessing step is TrackEval's own code.

Mode `kitti`: KITTI tracking label files (ground truth, `label_02/SEQ.txt`) and KITTI result
files (what `probmot export kitti` writes, `SEQ.txt`) are laid out as TrackEval's KITTI folders
in a temporary directory and scored by `trackeval.Evaluator` with the `Kitti2DBox` dataset and the
`HOTA` metric (classes car and pedestrian, split `training`). Two adaptations, both to the input
files only:
  * TrackEval's class table spells the sitting person `Person` (KITTI's labels write
    `Person_sitting`, which its loader cannot convert), so `Person_sitting` is renamed `Person` in
    the copied label files;
  * the seqmap (`evaluate_tracking.seqmap.training`) is written here: one line per sequence with
    the frame count max(frame) + 1 over its label and result files (the count only bounds the
    frame numbers; HOTA does not depend on it).

Mode `centre`: probmot MCAP files (probmot.Tracks3D on --truth-topic and --tracks-topic, decoded
with the schema embedded in the file); per class (the box's label), each file one sequence, each
distinct stamp one timestep; similarity = TrackEval's `_calculate_euclidean_similarity` of the
(x, y) centres with zero_distance 2.0; then `HOTA().eval_sequence` per sequence and
`HOTA().combine_sequences`, as `trackeval.Evaluator` calls them. Ids are relabelled 0..n per
sequence (as TrackEval's datasets do).

Output JSON: {"trackeval_version", "mode", "alphas", "classes": {CLASS: {"hota", "deta", "assa",
"loca", "detre", "detpr", "assre", "asspr" (means over alpha, as TrackEval's summary prints them),
"curves": {same names: per-alpha arrays, "tp", "fn", "fp"}}}}.

Examples (see docs/hota.md):
    python3 scripts/trackeval_crosscheck.py kitti --labels ../shared/data/kitti-tracking-train/label_02 \
        --results results/ --seqs 0000,0002 -o trackeval.json
    python3 scripts/trackeval_crosscheck.py centre --truth a.mcap b.mcap --classes car,pedestrian
"""

import argparse
import contextlib
import json
import os
import sys
import tempfile

FIELDS = ["HOTA", "DetA", "AssA", "LocA", "DetRe", "DetPr", "AssRe", "AssPr"]


def summarise(res):
    """TrackEval's per-class HOTA result dict -> our JSON layout."""
    import numpy as np

    out = {f.lower(): float(np.mean(res[f])) for f in FIELDS}
    curves = {f.lower(): [float(v) for v in res[f]] for f in FIELDS}
    for f in ["HOTA_TP", "HOTA_FN", "HOTA_FP"]:
        curves[f.split("_")[1].lower()] = [float(v) for v in res[f]]
    out["curves"] = curves
    return out


def frame_count(path):
    last = -1
    with open(path) as f:
        for line in f:
            if line.strip():
                last = max(last, int(float(line.split()[0])))
    return last + 1


def run_kitti(a):
    import trackeval

    seqs = [s for s in a.seqs.split(",") if s]
    classes = [c for c in a.classes.split(",") if c]
    with tempfile.TemporaryDirectory() as tmp:
        gt = os.path.join(tmp, "gt")
        trk = os.path.join(tmp, "trackers")
        os.makedirs(os.path.join(gt, "label_02"))
        os.makedirs(os.path.join(trk, "probmot", "data"))
        seqmap = []
        for s in seqs:
            label = os.path.join(a.labels, s + ".txt")
            result = os.path.join(a.results, s + ".txt")
            with open(label) as f:
                rows = [r.split(" ") for r in f.read().splitlines() if r.strip()]
            for r in rows:
                if r[2] == "Person_sitting":
                    r[2] = "Person"
            with open(os.path.join(gt, "label_02", s + ".txt"), "w") as f:
                f.write("".join(" ".join(r) + "\n" for r in rows))
            with open(result) as f, open(os.path.join(trk, "probmot", "data", s + ".txt"), "w") as g:
                g.write(f.read())
            n = max(frame_count(label), frame_count(result), 1)
            seqmap.append(f"{s} empty 000000 {n:06d}\n")
        with open(os.path.join(gt, "evaluate_tracking.seqmap.training"), "w") as f:
            f.write("".join(seqmap))
        evaluator = trackeval.Evaluator({
            "USE_PARALLEL": False, "BREAK_ON_ERROR": True, "LOG_ON_ERROR": None,
            "PRINT_RESULTS": False, "PRINT_CONFIG": False, "TIME_PROGRESS": False,
            "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False,
        })
        dataset = trackeval.datasets.Kitti2DBox({
            "GT_FOLDER": gt, "TRACKERS_FOLDER": trk, "TRACKERS_TO_EVAL": ["probmot"],
            "CLASSES_TO_EVAL": classes, "SPLIT_TO_EVAL": "training", "PRINT_CONFIG": False,
        })
        # TrackEval prints progress on stdout; keep stdout for the JSON.
        with contextlib.redirect_stdout(sys.stderr):
            res, msg = evaluator.evaluate([dataset], [trackeval.metrics.HOTA({"PRINT_CONFIG": False})])
        status = msg["Kitti2DBox"]["probmot"]
        if status != "Success":
            raise SystemExit(f"TrackEval failed: {status}")
        combined = res["Kitti2DBox"]["probmot"]["COMBINED_SEQ"]
        return {c: summarise(combined[c]["HOTA"]) for c in classes}


def read_frames(path, topic):
    """{stamp_ns: [Track3D, ...]} of one probmot.Tracks3D topic of an MCAP file."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    frames = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, _channel, message, msg in reader.iter_decoded_messages(topics=[topic]):
            if schema is None or schema.name != "probmot.Tracks3D":
                raise SystemExit(f"{path}: topic {topic} is not probmot.Tracks3D")
            stamp = int(msg.stamp) or int(message.log_time)
            frames.setdefault(stamp, []).extend(msg.tracks)
    return frames


def centre_sequence(gt_frames, tr_frames, cls):
    """TrackEval's input dict for one sequence and class."""
    import numpy as np
    from trackeval.datasets._base_dataset import _BaseDataset

    stamps = sorted(set(gt_frames) | set(tr_frames))
    gt_map, tr_map = {}, {}
    data = {"gt_ids": [], "tracker_ids": [], "similarity_scores": []}
    n_gt = n_tr = 0
    for s in stamps:
        g = [b for b in gt_frames.get(s, []) if b.label == cls]
        t = [b for b in tr_frames.get(s, []) if b.label == cls]
        g_ids = np.array([gt_map.setdefault(b.id, len(gt_map)) for b in g], dtype=int)
        t_ids = np.array([tr_map.setdefault(b.id, len(tr_map)) for b in t], dtype=int)
        g_xy = np.array([[b.center.x, b.center.y] for b in g], dtype=float).reshape(-1, 2)
        t_xy = np.array([[b.center.x, b.center.y] for b in t], dtype=float).reshape(-1, 2)
        data["gt_ids"].append(g_ids)
        data["tracker_ids"].append(t_ids)
        data["similarity_scores"].append(
            _BaseDataset._calculate_euclidean_similarity(g_xy, t_xy, zero_distance=2.0))
        n_gt += len(g)
        n_tr += len(t)
    data.update(num_gt_ids=len(gt_map), num_tracker_ids=len(tr_map), num_gt_dets=n_gt,
                num_tracker_dets=n_tr, num_timesteps=len(stamps))
    return data


def run_centre(a):
    import trackeval

    tracks = a.tracks or a.truth
    if len(tracks) != len(a.truth):
        raise SystemExit("give --tracks once per --truth, or not at all")
    logs = [(read_frames(t, a.truth_topic), read_frames(r, a.tracks_topic))
            for t, r in zip(a.truth, tracks)]
    metric = trackeval.metrics.HOTA({"PRINT_CONFIG": False})
    out = {}
    for cls in [c for c in a.classes.split(",") if c]:
        per_seq = {}
        for i, (g, t) in enumerate(logs):
            per_seq[f"seq{i}"] = metric.eval_sequence(centre_sequence(g, t, cls))
        if any(r["HOTA_TP"][0] + r["HOTA_FN"][0] + r["HOTA_FP"][0] > 0 for r in per_seq.values()):
            out[cls] = summarise(metric.combine_sequences(per_seq))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="mode", required=True)
    k = sub.add_parser("kitti", help="KITTI label and result files, TrackEval's Kitti2DBox")
    k.add_argument("--labels", required=True, help="directory of ground-truth SEQ.txt files")
    k.add_argument("--results", required=True, help="directory of result SEQ.txt files")
    k.add_argument("--seqs", required=True, help="comma-separated sequence names, e.g. 0000,0002")
    k.add_argument("--classes", default="car,pedestrian")
    c = sub.add_parser("centre", help="probmot MCAP files, BEV centre-distance similarity")
    c.add_argument("--truth", nargs="+", required=True)
    c.add_argument("--tracks", nargs="+")
    c.add_argument("--truth-topic", default="/ground_truth")
    c.add_argument("--tracks-topic", default="/tracks")
    c.add_argument("--classes", required=True, help="comma-separated labels")
    for s in (k, c):
        s.add_argument("-o", "--output", help="JSON output file (default: stdout)")
    a = p.parse_args()

    import numpy as np
    import trackeval  # noqa: F401  (fail early with a clear import error)
    from importlib.metadata import version

    classes = run_kitti(a) if a.mode == "kitti" else run_centre(a)
    out = {
        "trackeval_version": version("trackeval"),
        "mode": a.mode,
        "alphas": [float(v) for v in np.arange(0.05, 0.99, 0.05)],
        "classes": classes,
    }
    text = json.dumps(out, indent=1) + "\n"
    if a.output:
        tmp = a.output + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, a.output)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
