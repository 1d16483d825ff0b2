#!/usr/bin/env python3
"""Golden nuScenes tracking numbers for probmot MCAP files, computed by the OFFICIAL nuscenes-devkit.

Each --truth file is one nuScenes "scene". Ground truth is read from --truth-topic (default
/ground_truth) and predictions from --tracks-topic (default /tracks), both `probmot.Tracks3D`
protobuf messages decoded with the FileDescriptorSet embedded in the MCAP schema record. Give
--tracks once per --truth (paired in order) or not at all (then the predictions are read from the
truth file itself).

What is handed to the devkit (only glue is written here; all evaluation logic is the devkit's):
  * one sample per frame, sample_token = f"{scene}_{stamp_ns}", timestamp = stamp_ns // 1000 (us);
    the frames of a scene are the union of the stamps of both topics (the Track3D message's `stamp`);
  * one `TrackingBox` per Track3D whose label is a nuScenes tracking class (others are dropped,
    exactly as the devkit drops GT of other categories): translation = center (x, y, z),
    size = [width, length, height], rotation = quaternion of `yaw` about +z, velocity = (vx, vy),
    tracking_id = f"{scene}/{id}" (ids are per log, as probmot counts them; the devkit's instance
    tokens are unique across scenes, so repeated ids of different scenes must not meet in its
    count of ground-truth tracks), tracking_name = label, tracking_score = score (GT: -1.0, like load_gt);
    boxes keep their order inside a message. Predicted boxes go through the devkit's own
    `load_prediction` (submission JSON written to a temporary file, including the 500-box check);
  * no range, bike-rack or lidar-points filter by default; with --max-range, the devkit's own
    `add_center_dist` and `filter_eval_boxes` with the config's `class_range` (40/50 m), run on GT
    and predictions before `create_tracks` exactly where `TrackingEval.__init__` runs them. The ego
    pose of each sample comes from the truth file's /ego_pose channel (JSON {stamp, translation,
    rotation}, as `probmot import nuscenes` writes it), at the sample's stamp; no sample has
    annotations, so the bike-rack filter removes nothing, and boxes keep num_pts = -1 (no points
    filter);
  * `nuscenes.eval.tracking.loaders.create_tracks` itself (mean track score, `interpolate_tracks`,
    chronological order) with a minimal stand-in for the NuScenes table object and a temporary
    custom split file naming our scenes;
  * `TrackingEval.evaluate` itself (the per-class `TrackingEvaluation` and the aggregation) on a
    TrackingEval object whose loading step is replaced by the above; config
    `config_factory('tracking_nips_2019')`.

Hash seed: `create_tracks` iterates a `set` of scene tokens, so with several scenes the devkit's
scene order (and the float summation order of MOTP) depends on PYTHONHASHSEED. By default this script
re-orders the scenes afterwards into the order of the --truth arguments (one of the orders the
devkit can produce), which makes the output independent of the hash seed; --keep-devkit-scene-order
keeps the devkit's hash-dependent order instead. Run it with PYTHONHASHSEED=0 all the same.

Output JSON: {"protocol": "nuscenes", "devkit_version", "motmetrics_version",
  "classes": {CLASS: {amota, amotp, recall, motar, mota, motp, mt, ml, faf, tp, fp, fn, ids, frag,
  tid, lgd}}, "overall": {same keys}, "inputs": {...}, "metric_data": {CLASS: per-threshold arrays of
  the devkit's TrackingMetricData}, "distance_check": {...}}, NaN written as null. If the devkit
  raises, the JSON holds "devkit_error" (exception type, message and the devkit source line) instead
  of "classes"/"overall"/"metric_data".

Install (not needed by CI; CI only reads the committed JSON):
    pip install -r scripts/requirements-devkit.txt

Regenerate one file:
    PYTHONHASHSEED=0 python3 scripts/devkit_crosscheck.py \
        --truth tests/fixtures/eval/perfect.mcap -o tests/fixtures/eval/perfect.devkit.json
All fixtures: see tests/fixtures/eval/README.md.
"""

import argparse
import contextlib
import io
import json
import math
import os
import sys
import tempfile
import traceback
from collections import OrderedDict, defaultdict
from importlib.metadata import version as pkg_version

# OpenBLAS picks its kernel by CPU; FMA kernels change sklearn's euclidean_distances (the devkit's
# distance) in the last bits, which moves MOTP by up to 1e-9. The committed outputs were made with
# the generic x86-64 kernel: pin it (before numpy loads OpenBLAS) so that any machine reproduces
# them byte for byte.
os.environ.setdefault("OPENBLAS_CORETYPE", "Prescott")

import numpy as np  # noqa: E402

TRACKING_CLASSES = ("bicycle", "bus", "car", "motorcycle", "pedestrian", "trailer", "truck")
OUTPUT_METRICS = ("amota", "amotp", "recall", "motar", "mota", "motp", "mt", "ml", "faf",
                  "tp", "fp", "fn", "ids", "frag", "tid", "lgd")
CUSTOM_SPLIT = "probmot_crosscheck"


# ----------------------------------------------------------------------------------------------
# MCAP reading
# ----------------------------------------------------------------------------------------------
def read_frames(path, topic):
    """Returns ({stamp_ns: [Track3D, ...]}, number of messages) of one topic of an MCAP file."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    frames = OrderedDict()
    count = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages(topics=[topic]):
            if schema is None or schema.name != "probmot.Tracks3D":
                raise SystemExit(f"{path}: topic {topic} has schema "
                                 f"{schema.name if schema else None}, expected probmot.Tracks3D")
            count += 1
            frames.setdefault(int(msg.stamp), []).extend(msg.tracks)
    return frames, count


def quaternion_from_yaw(yaw):
    from pyquaternion import Quaternion
    return tuple(float(v) for v in Quaternion(axis=[0.0, 0.0, 1.0], angle=float(yaw)).elements)


def box_dict(scene, sample_token, trk, gt):
    return {
        "sample_token": sample_token,
        "translation": [float(trk.center.x), float(trk.center.y), float(trk.center.z)],
        "size": [float(trk.size.width), float(trk.size.length), float(trk.size.height)],
        "rotation": list(quaternion_from_yaw(trk.yaw)),
        "velocity": [float(trk.velocity.x), float(trk.velocity.y)],
        "tracking_id": f"{scene}/{trk.id}",
        "tracking_name": trk.label,
        "tracking_score": -1.0 if gt else float(trk.score),
    }


# ----------------------------------------------------------------------------------------------
# Minimal stand-in for nuscenes.NuScenes: only what create_tracks / get_scenes_of_split read.
# ----------------------------------------------------------------------------------------------
class SceneTables:
    def __init__(self, dataroot, version):
        self.dataroot = dataroot
        self.version = version
        self.tables = {"sample": {}, "scene": {}}

    def add_ego_poses(self, tokens, translations):
        """Ego pose per sample, reached as the devkit's add_center_dist does (sample -> LIDAR_TOP
        sample_data -> ego_pose)."""
        for tok, tr in zip(tokens, translations):
            self.tables["sample"][tok]["data"] = {"LIDAR_TOP": "sd_" + tok}
            self.tables.setdefault("sample_data", {})["sd_" + tok] = {"ego_pose_token": "ep_" + tok}
            self.tables.setdefault("ego_pose", {})["ep_" + tok] = {"translation": list(tr)}

    def add_scene(self, name, tokens, timestamps_us):
        self.tables["scene"][name] = {"token": name, "name": name,
                                      "first_sample_token": tokens[0], "last_sample_token": tokens[-1],
                                      "nbr_samples": len(tokens)}
        for i, (tok, t) in enumerate(zip(tokens, timestamps_us)):
            self.tables["sample"][tok] = {"token": tok, "timestamp": t, "scene_token": name,
                                          "anns": [],
                                          "prev": tokens[i - 1] if i > 0 else "",
                                          "next": tokens[i + 1] if i + 1 < len(tokens) else ""}

    def get(self, table_name, token):
        return self.tables[table_name][token]


def read_ego_poses(path, topic):
    """{stamp_ns: translation} of the JSON ego pose channel of an MCAP file."""
    from mcap.reader import make_reader

    poses = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=[topic]):
            if schema is None or schema.name != "probmot.EgoPose" or channel.message_encoding != "json":
                raise SystemExit(f"{path}: topic {topic} is not a probmot.EgoPose JSON channel")
            m = json.loads(message.data)
            poses[int(m["stamp"])] = [float(v) for v in m["translation"]]
    if not poses:
        raise SystemExit(f"{path}: no messages on {topic} (needed by --max-range)")
    return poses


def build_inputs(pairs, truth_topic, tracks_topic, ego_topic=None):
    """Reads all scenes. Returns (scene tables info, gt submission dict, pred submission dict, info)."""
    scenes = []
    used_names = set()
    for truth_path, tracks_path in pairs:
        name = os.path.splitext(os.path.basename(truth_path))[0]
        base, k = name, 2
        while name in used_names:
            name, k = f"{base}-{k}", k + 1
        used_names.add(name)

        gt_frames, gt_msgs = read_frames(truth_path, truth_topic)
        pred_frames, pred_msgs = read_frames(tracks_path, tracks_topic)
        for path, topic, n in ((truth_path, truth_topic, gt_msgs), (tracks_path, tracks_topic, pred_msgs)):
            if n == 0:
                print(f"warning: {path} has no messages on {topic}", file=sys.stderr)
        stamps_ns = sorted(set(gt_frames) | set(pred_frames))
        if not stamps_ns:
            raise SystemExit(f"{truth_path}: no messages on {truth_topic} or {tracks_topic}")

        # ns -> us; distinct ns stamps that fall into the same microsecond become one sample.
        by_us = OrderedDict()
        for s in stamps_ns:
            by_us.setdefault(s // 1000, []).append(s)

        gt_results, pred_results = OrderedDict(), OrderedDict()
        ignored = defaultdict(int)
        n_gt = defaultdict(int)
        n_pred = defaultdict(int)
        for t_us, ns_list in by_us.items():
            token = f"{name}_{ns_list[0]}"
            gt_results[token], pred_results[token] = [], []
            for s in ns_list:
                for trk in gt_frames.get(s, []):
                    if trk.label in TRACKING_CLASSES:
                        gt_results[token].append(box_dict(name, token, trk, gt=True))
                        n_gt[trk.label] += 1
                    else:
                        ignored["truth:" + trk.label] += 1
                for trk in pred_frames.get(s, []):
                    if trk.label in TRACKING_CLASSES:
                        pred_results[token].append(box_dict(name, token, trk, gt=False))
                        n_pred[trk.label] += 1
                    else:
                        ignored["tracks:" + trk.label] += 1
        ego = None
        if ego_topic is not None:
            poses = read_ego_poses(truth_path, ego_topic)
            missing = [ns_list[0] for ns_list in by_us.values() if ns_list[0] not in poses]
            if missing:
                raise SystemExit(f"{truth_path}: no ego pose at stamps {missing[:5]} ...")
            ego = [poses[ns_list[0]] for ns_list in by_us.values()]
        scenes.append({
            "name": name,
            "ego_translations": ego,
            "truth_file": os.path.basename(truth_path),
            "tracks_file": os.path.basename(tracks_path),
            "truth_messages": gt_msgs,
            "tracks_messages": pred_msgs,
            "frames": len(by_us),
            "first_stamp_ns": stamps_ns[0],
            "last_stamp_ns": stamps_ns[-1],
            "timestamps_us": list(by_us.keys()),
            "sample_tokens": [f"{name}_{ns_list[0]}" for ns_list in by_us.values()],
            "gt_boxes": dict(sorted(n_gt.items())),
            "pred_boxes": dict(sorted(n_pred.items())),
            "ignored_labels": dict(sorted(ignored.items())),
            "gt_results": gt_results,
            "pred_results": pred_results,
        })
    return scenes


# ----------------------------------------------------------------------------------------------
# Distance diagnostic: how far sklearn's euclidean_distances (what the devkit uses) is from
# math.hypot on these inputs, over every (GT, prediction) pair of the same frame and class.
# ----------------------------------------------------------------------------------------------
def distance_check(tracks_gt, tracks_pred):
    from sklearn.metrics.pairwise import euclidean_distances
    max_abs, max_rel, n, near, closest = 0.0, 0.0, 0, 0, math.inf
    for scene in tracks_gt:
        for t, gt_boxes in tracks_gt[scene].items():
            pred_boxes = tracks_pred[scene].get(t, [])
            for cls in TRACKING_CLASSES:
                g = [b.translation[:2] for b in gt_boxes if b.tracking_name == cls]
                p = [b.translation[:2] for b in pred_boxes if b.tracking_name == cls]
                if not g or not p:
                    continue
                d = euclidean_distances(np.array(g), np.array(p))
                for i, gg in enumerate(g):
                    for j, pp in enumerate(p):
                        exact = math.hypot(gg[0] - pp[0], gg[1] - pp[1])
                        err = abs(float(d[i, j]) - exact)
                        n += 1
                        max_abs = max(max_abs, err)
                        if exact > 0:
                            max_rel = max(max_rel, err / exact)
                        closest = min(closest, abs(exact - 2.0))
                        if abs(exact - 2.0) < 1e-6:
                            near += 1
    return {"pairs": n, "max_abs_error_vs_hypot": max_abs, "max_rel_error_vs_hypot": max_rel,
            "pairs_within_1e-6_of_2m": near,
            "min_abs_distance_minus_2m": closest if n else None}


# ----------------------------------------------------------------------------------------------
def nan_to_none(x):
    if isinstance(x, dict):
        return {k: nan_to_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [nan_to_none(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        x = x.item()
    if isinstance(x, float) and math.isnan(x):
        return None
    return x


def to_json(x, indent=0):
    """json.dumps with indentation, but lists of scalars on one line."""
    pad = " " * (indent + 1)
    if isinstance(x, dict):
        if not x:
            return "{}"
        items = [f"{pad}{json.dumps(k)}: {to_json(v, indent + 1)}" for k, v in x.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
    if isinstance(x, list) and any(isinstance(v, (dict, list)) for v in x):
        items = [pad + to_json(v, indent + 1) for v in x]
        return "[\n" + ",\n".join(items) + "\n" + " " * indent + "]"
    return json.dumps(x, allow_nan=False)


def evaluate(scenes, keep_devkit_scene_order, verbose, max_range=False):
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.common.loaders import load_prediction
    from nuscenes.eval.common.data_classes import EvalBoxes
    from nuscenes.eval.tracking.data_classes import TrackingBox
    from nuscenes.eval.tracking.evaluate import TrackingEval
    from nuscenes.eval.tracking.loaders import create_tracks

    cfg = config_factory("tracking_nips_2019")

    with tempfile.TemporaryDirectory(prefix="probmot-devkit-") as tmp:
        version = "v1.0-probmot"
        os.makedirs(os.path.join(tmp, version))
        with open(os.path.join(tmp, version, "splits.json"), "w") as f:
            json.dump({CUSTOM_SPLIT: [s["name"] for s in scenes]}, f)
        nusc = SceneTables(tmp, version)
        for s in scenes:
            nusc.add_scene(s["name"], s["sample_tokens"], s["timestamps_us"])

        # Predictions: a submission file read by the devkit's own loader.
        submission = {"meta": {"use_camera": False, "use_lidar": True, "use_radar": False,
                               "use_map": False, "use_external": False},
                      "results": OrderedDict()}
        for s in scenes:
            submission["results"].update(s["pred_results"])
        result_path = os.path.join(tmp, "results.json")
        with open(result_path, "w") as f:
            json.dump(submission, f)
        pred_boxes, _meta = load_prediction(result_path, cfg.max_boxes_per_sample, TrackingBox,
                                            verbose=verbose)

        # Ground truth: boxes built like load_gt does (tracking_score -1.0), every sample present.
        gt_boxes = EvalBoxes()
        for s in scenes:
            for token, boxes in s["gt_results"].items():
                gt_boxes.add_boxes(token, [TrackingBox(
                    sample_token=b["sample_token"], translation=tuple(b["translation"]),
                    size=tuple(b["size"]), rotation=tuple(b["rotation"]),
                    velocity=tuple(b["velocity"]), tracking_id=b["tracking_id"],
                    tracking_name=b["tracking_name"], tracking_score=-1.0) for b in boxes])
        assert set(pred_boxes.sample_tokens) == set(gt_boxes.sample_tokens), \
            "Samples in split don't match samples in predicted tracks."

        range_counts = None
        if max_range:
            # What TrackingEval.__init__ does after loading, with the devkit's own functions.
            from nuscenes.eval.common.loaders import add_center_dist, filter_eval_boxes
            for s in scenes:
                nusc.add_ego_poses(s["sample_tokens"], s["ego_translations"])
            before = (sum(len(b) for b in gt_boxes.boxes.values()),
                      sum(len(b) for b in pred_boxes.boxes.values()))
            gt_boxes = filter_eval_boxes(nusc, add_center_dist(nusc, gt_boxes), cfg.class_range)
            pred_boxes = filter_eval_boxes(nusc, add_center_dist(nusc, pred_boxes), cfg.class_range)
            range_counts = {
                "class_range": dict(sorted(cfg.class_range.items())),
                "removed_truth_boxes": before[0] - sum(len(b) for b in gt_boxes.boxes.values()),
                "removed_track_boxes": before[1] - sum(len(b) for b in pred_boxes.boxes.values()),
            }

        tracks_gt = create_tracks(gt_boxes, nusc, CUSTOM_SPLIT, gt=True)
        tracks_pred = create_tracks(pred_boxes, nusc, CUSTOM_SPLIT, gt=False)
        devkit_scene_order = list(tracks_gt.keys())
        if not keep_devkit_scene_order:
            order = [s["name"] for s in scenes]
            tracks_gt = defaultdict(lambda: defaultdict(list), [(k, tracks_gt[k]) for k in order])
            tracks_pred = defaultdict(lambda: defaultdict(list), [(k, tracks_pred[k]) for k in order])

        # TrackingEval without its dataset loading: evaluate() reads only these attributes.
        ev = TrackingEval.__new__(TrackingEval)
        ev.cfg = cfg
        ev.tracks_gt = tracks_gt
        ev.tracks_pred = tracks_pred
        ev.verbose = verbose
        ev.output_dir = tmp
        ev.render_classes = None
        ev.sample_tokens = gt_boxes.sample_tokens

        interp = {"gt_boxes_after_interpolation": defaultdict(int),
                  "pred_boxes_after_interpolation": defaultdict(int)}
        for key, tr in (("gt_boxes_after_interpolation", tracks_gt),
                        ("pred_boxes_after_interpolation", tracks_pred)):
            for sc in tr.values():
                for boxes in sc.values():
                    for b in boxes:
                        interp[key][b.tracking_name] += 1
        interp = {k: dict(sorted(v.items())) for k, v in interp.items()}

        out = {"scene_order_used": list(tracks_gt.keys()),
               "range_filter": range_counts,
               "devkit_scene_order": devkit_scene_order,
               "interpolation": interp,
               "distance_check": distance_check(tracks_gt, tracks_pred)}
        try:
            sink = io.StringIO()
            with contextlib.redirect_stdout(sink if not verbose else sys.stdout):
                metrics, md_list = ev.evaluate()
        except Exception as e:  # The devkit's own failure is a result too.
            tb = traceback.extract_tb(e.__traceback__)
            frame = next((fr for fr in reversed(tb) if "nuscenes" in fr.filename), tb[-1])
            rel = frame.filename[frame.filename.rfind("nuscenes"):]
            msg = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__
            out["devkit_error"] = f"{msg} (at {rel}:{frame.lineno}: {frame.line})"
            # Which classes make the devkit fail (evaluate() stops at the first one).
            from nuscenes.eval.tracking.algo import TrackingEvaluation
            from nuscenes.eval.tracking.data_classes import TrackingMetricData
            failing = []
            for c in cfg.class_names:
                try:
                    with contextlib.redirect_stdout(io.StringIO()):
                        TrackingEvaluation(tracks_gt, tracks_pred, c, cfg.dist_fcn_callable,
                                           cfg.dist_th_tp, cfg.min_recall,
                                           num_thresholds=TrackingMetricData.nelem,
                                           metric_worst=cfg.metric_worst, verbose=False,
                                           output_dir=tmp, render_classes=None).accumulate()
                except Exception:
                    failing.append(c)
            out["devkit_error_classes"] = failing
            return out

        summary = metrics.serialize()
        label_metrics = summary["label_metrics"]
        out["classes"] = {c: {m: label_metrics[m][c] for m in OUTPUT_METRICS}
                          for c in sorted(TRACKING_CLASSES)}
        out["overall"] = {m: summary[m] for m in OUTPUT_METRICS}
        # TrackingMetricData.serialize() orders its keys by iterating a set (hash-seed dependent):
        # write them in a fixed order instead.
        from nuscenes.eval.tracking.constants import TRACKING_METRICS
        md_keys = ["confidence", "recall_hypo"] + [m for m in TRACKING_METRICS
                                                   if m not in ("amota", "amotp")]
        out["metric_data"] = {}
        for c in sorted(TRACKING_CLASSES):
            ser = md_list[c].serialize()
            assert set(ser) == set(md_keys), sorted(ser)
            out["metric_data"][c] = {k: ser[k] for k in md_keys}
        return out


# ----------------------------------------------------------------------------------------------
# Whole pipeline on nuScenes tables: the devkit's own NuScenes, TrackingEval and every filter.
# ----------------------------------------------------------------------------------------------
def evaluate_tables(dataroot, version, split, submission, verbose):
    """Runs the devkit's TrackingEval as its own `evaluate.py` does, on tables under
    dataroot/version (custom split `split` from splits.json there) and a tracking submission:
    its loaders, add_center_dist, filter_eval_boxes (range, points, bicycle racks), create_tracks
    and evaluate. Returns (doc, filter counts parsed from the devkit's verbose output)."""
    import re
    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.tracking.constants import TRACKING_METRICS
    from nuscenes.eval.tracking.evaluate import TrackingEval

    cfg = config_factory("tracking_nips_2019")
    with tempfile.TemporaryDirectory(prefix="probmot-devkit-") as tmp:
        # The devkit's NuScenes checks that each map's mask file exists (it never reads it here).
        root = os.path.join(tmp, "data")
        os.makedirs(os.path.join(root, "maps"))
        os.symlink(os.path.abspath(os.path.join(dataroot, version)), os.path.join(root, version))
        with open(os.path.join(root, version, "map.json")) as f:
            for m in json.load(f):
                open(os.path.join(root, m["filename"]), "wb").close()
        sink = io.StringIO()
        with contextlib.redirect_stdout(sink):
            ev = TrackingEval(config=cfg, result_path=submission, eval_set=split,
                              output_dir=os.path.join(tmp, "out"), nusc_version=version,
                              nusc_dataroot=root, verbose=True)
        log = sink.getvalue()
        with contextlib.redirect_stdout(sink if not verbose else sys.stdout):
            metrics, md_list = ev.evaluate()
    # filter_eval_boxes prints four counts per call: predictions first, then ground truth.
    nums = [int(v) for v in re.findall(r"=> (?:Original number of boxes|After [^:]+): (\d+)", log)]
    assert len(nums) == 8, log
    counts = {}
    for who, (total, dist, pts, rack) in (("tracks", nums[:4]), ("truth", nums[4:])):
        counts[who] = {"total": total, "range": total - dist, "points": dist - pts,
                       "bike_racks": pts - rack}
    summary = metrics.serialize()
    label_metrics = summary["label_metrics"]
    out = {"classes": {c: {m: label_metrics[m][c] for m in OUTPUT_METRICS}
                       for c in sorted(TRACKING_CLASSES)},
           "overall": {m: summary[m] for m in OUTPUT_METRICS}}
    md_keys = ["confidence", "recall_hypo"] + [m for m in TRACKING_METRICS
                                               if m not in ("amota", "amotp")]
    out["metric_data"] = {c: {k: md_list[c].serialize()[k] for k in md_keys}
                          for c in sorted(TRACKING_CLASSES)}
    return out, counts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--truth", action="append", default=[],
                    help="MCAP file with ground truth (one scene); repeatable")
    ap.add_argument("--tables", metavar="DATAROOT",
                    help="instead of --truth: nuScenes tables under DATAROOT/VERSION, evaluated by "
                         "the devkit's own TrackingEval (every filter of filter_eval_boxes) with the "
                         "tracking submission --submission and the custom split --split")
    ap.add_argument("--version", default="v1.0-probmot")
    ap.add_argument("--split", default="probmot_filters")
    ap.add_argument("--submission", help="tracking submission JSON (with --tables)")
    ap.add_argument("--tracks", action="append", default=[],
                    help="MCAP file with the predicted tracks, paired with --truth in order; "
                         "default: the truth file itself")
    ap.add_argument("--truth-topic", default="/ground_truth")
    ap.add_argument("--tracks-topic", default="/tracks")
    ap.add_argument("--keep-devkit-scene-order", action="store_true",
                    help="keep create_tracks' hash-seed-dependent scene order")
    ap.add_argument("--max-range", action="store_true",
                    help="apply the devkit's range filter (class_range of tracking_nips_2019) with "
                         "the ego poses of --ego-topic in each truth file")
    ap.add_argument("--ego-topic", default="/ego_pose")
    ap.add_argument("-v", "--verbose", action="store_true", help="let the devkit print")
    ap.add_argument("-o", "--output", required=True, help="output JSON file ('-' for stdout)")
    args = ap.parse_args(argv)
    if args.tables:
        return main_tables(args)
    if not args.truth:
        ap.error("give --truth (MCAP files) or --tables")

    if args.tracks and len(args.tracks) != len(args.truth):
        ap.error("give --tracks once per --truth, or not at all")
    pairs = list(zip(args.truth, args.tracks or args.truth))

    scenes = build_inputs(pairs, args.truth_topic, args.tracks_topic,
                          args.ego_topic if args.max_range else None)
    result = evaluate(scenes, args.keep_devkit_scene_order, args.verbose, args.max_range)

    doc = OrderedDict()
    doc["protocol"] = "nuscenes"
    doc["devkit_version"] = pkg_version("nuscenes-devkit")
    doc["motmetrics_version"] = pkg_version("motmetrics")
    doc["config"] = "tracking_nips_2019"
    if "devkit_error" in result:
        doc["devkit_error"] = result["devkit_error"]
        doc["devkit_error_classes"] = result["devkit_error_classes"]
    else:
        doc["classes"] = result["classes"]
        doc["overall"] = result["overall"]
    doc["inputs"] = {
        "truth_topic": args.truth_topic,
        "tracks_topic": args.tracks_topic,
        "filters": ("range filter (devkit filter_eval_boxes with class_range; no annotations, so "
                    "no bike-rack filter; num_pts -1, so no points filter)" if args.max_range
                    else "none (no range / bike-rack / lidar-points filter)"),
        "scenes": [{k: v for k, v in s.items()
                    if k not in ("gt_results", "pred_results", "timestamps_us", "sample_tokens",
                                 "ego_translations")}
                   for s in scenes],
        "scene_order_used": result["scene_order_used"],
        "interpolation": result["interpolation"],
    }
    if args.max_range:
        doc["inputs"]["range_filter"] = result["range_filter"]
    doc["distance_check"] = result["distance_check"]
    doc["environment"] = {p: pkg_version(p) for p in ("numpy", "pandas", "scipy", "scikit-learn",
                                                      "pyquaternion")}
    if "metric_data" in result:
        doc["metric_data"] = result["metric_data"]

    text = to_json(nan_to_none(doc)) + "\n"
    if args.output == "-":
        sys.stdout.write(text)
    else:
        with open(args.output, "w") as f:
            f.write(text)
    if "devkit_error" in result:
        print(f"devkit error: {result['devkit_error']}", file=sys.stderr)
    else:
        o = result["overall"]
        print(f"{args.output}: AMOTA {o['amota']:.6f} AMOTP {o['amotp']:.6f} MOTA {o['mota']:.6f} "
              f"IDS {o['ids']:g} FRAG {o['frag']:g}", file=sys.stderr)
    return 0


def main_tables(args):
    """--tables: the devkit's whole tracking evaluation on nuScenes tables."""
    result, counts = evaluate_tables(args.tables, args.version, args.split, args.submission,
                                     args.verbose)
    doc = OrderedDict()
    doc["protocol"] = "nuscenes"
    doc["devkit_version"] = pkg_version("nuscenes-devkit")
    doc["motmetrics_version"] = pkg_version("motmetrics")
    doc["config"] = "tracking_nips_2019"
    doc["classes"] = result["classes"]
    doc["overall"] = result["overall"]
    doc["inputs"] = {"tables": f"{os.path.basename(os.path.normpath(args.tables))}/{args.version}",
                     "split": args.split, "submission": os.path.basename(args.submission),
                     "filters": "the devkit's TrackingEval: add_center_dist + filter_eval_boxes "
                                "(class_range, num_pts == 0, bicycle racks) on GT and predictions",
                     "removed_boxes": counts}
    doc["environment"] = {p: pkg_version(p) for p in ("numpy", "pandas", "scipy", "scikit-learn",
                                                      "pyquaternion")}
    doc["metric_data"] = result["metric_data"]
    text = to_json(nan_to_none(doc)) + "\n"
    if args.output == "-":
        sys.stdout.write(text)
    else:
        with open(args.output, "w") as f:
            f.write(text)
    o = result["overall"]
    print(f"{args.output}: AMOTA {o['amota']:.6f} AMOTP {o['amotp']:.6f} MOTA {o['mota']:.6f} "
          f"removed {counts}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
