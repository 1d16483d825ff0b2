#!/usr/bin/env python3
"""Writes the small deterministic MCAP fixtures for `probmot eval` (tests/fixtures/eval/).

Each fixture is one nuScenes-style scene at 2 Hz (stamps 0.5 s apart from 1_767_225_600_000_000_000 ns)
with ground truth on /ground_truth and predicted tracks on /tracks, both `probmot.Tracks3D`. The schema
record (name `probmot.Tracks3D`, encoding `protobuf`) holds the FileDescriptorSet of
schemas/probmot/{geometry,detections,tracks}.proto compiled by grpcio-tools' protoc (with imports and
source info, like build.rs). Scenarios are scripted by hand; noise comes from numpy's default_rng with a
fixed seed per fixture, so the same package versions give the same bytes.

Usage:
    pip install -r scripts/requirements-devkit.txt
    python3 scripts/make_eval_fixtures.py tests/fixtures/eval
The golden numbers are then made with scripts/devkit_crosscheck.py (see tests/fixtures/eval/README.md).
"""

import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

T0_NS = 1_767_225_600_000_000_000
DT_NS = 500_000_000
DT = 0.5
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROTO_FILES = ["probmot/geometry.proto", "probmot/detections.proto", "probmot/tracks.proto"]

# Box size per class: (length, width, height).
SIZES = {
    "car": (4.6, 1.9, 1.7), "pedestrian": (0.7, 0.7, 1.75), "bicycle": (1.8, 0.6, 1.3),
    "motorcycle": (2.1, 0.8, 1.5), "truck": (7.0, 2.5, 3.0), "bus": (11.0, 2.9, 3.5),
    "trailer": (10.0, 2.5, 3.8),
}

EGO_POSE_JSON_SCHEMA = (
    '{"title":"probmot.EgoPose","type":"object","properties":{"stamp":{"type":"integer"},'
    '"translation":{"type":"array","items":{"type":"number"}},'
    '"rotation":{"type":"array","items":{"type":"number"}}},'
    '"required":["stamp","translation","rotation"]}')


def descriptor_set_bytes():
    """FileDescriptorSet of our three schema files, compiled by grpcio-tools' bundled protoc."""
    from grpc_tools import protoc
    import grpc_tools
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "probmot.fds")
        well_known = os.path.join(os.path.dirname(grpc_tools.__file__), "_proto")
        args = ["protoc", f"-I{os.path.join(REPO, 'schemas')}", f"-I{well_known}", "--include_imports",
                "--include_source_info", f"--descriptor_set_out={out}"] + PROTO_FILES
        if protoc.main(args) != 0:
            raise SystemExit("protoc failed on " + " ".join(PROTO_FILES))
        with open(out, "rb") as f:
            return f.read()


def message_classes(fds_bytes):
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    fds = descriptor_pb2.FileDescriptorSet.FromString(fds_bytes)
    assert [f.name for f in fds.file] == PROTO_FILES, [f.name for f in fds.file]
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    classes = message_factory.GetMessageClassesForFiles(PROTO_FILES, pool)
    return classes["probmot.Tracks3D"], classes["probmot.Track3D"]


# ----------------------------------------------------------------------------------------------
# Scene building
# ----------------------------------------------------------------------------------------------
class Scene:
    def __init__(self, name, n_frames, seed, description):
        self.name = name
        self.n = n_frames
        self.rng = np.random.default_rng(seed)
        self.description = description
        self.gt = [[] for _ in range(n_frames)]
        self.pred = [[] for _ in range(n_frames)]
        # Frames that have a message on each topic (default: all).
        self.gt_frames = set(range(n_frames))
        self.pred_frames = set(range(n_frames))
        # Ego vehicle position per frame (global x, y, z), written to /ego_pose when set.
        self.ego = None

    @staticmethod
    def _box(track_id, label, pos, vel, yaw, score):
        return {"id": int(track_id), "label": label, "x": float(pos[0]), "y": float(pos[1]),
                "z": SIZES[label][2] / 2.0, "yaw": float(yaw), "vx": float(vel[0]),
                "vy": float(vel[1]), "score": float(score)}

    def path(self, start, vel, accel=(0.0, 0.0)):
        """Positions and velocities for every frame of the scene (frame 0 at `start`)."""
        t = np.arange(self.n) * DT
        start, vel, accel = np.array(start, float), np.array(vel, float), np.array(accel, float)
        pos = start[None, :] + vel[None, :] * t[:, None] + 0.5 * accel[None, :] * t[:, None] ** 2
        v = vel[None, :] + accel[None, :] * t[:, None]
        return pos, v

    def add_gt(self, gid, label, path, frames):
        pos, vel = path
        for f in frames:
            yaw = math.atan2(vel[f][1], vel[f][0]) if np.hypot(*vel[f]) > 0.05 else 0.3
            self.gt[f].append(self._box(gid, label, pos[f], vel[f], yaw, 0.0))

    def add_track(self, tid, label, path, frames, score, noise=0.2, score_noise=0.04, exact_score=False):
        """A predicted track following `path` (optionally a different one per frame: pass a callable)."""
        for f in frames:
            pos, vel = path(f) if callable(path) else (path[0][f], path[1][f])
            p = np.array(pos) + self.rng.normal(0.0, noise, 2)
            v = np.array(vel) + self.rng.normal(0.0, 0.3, 2)
            yaw = math.atan2(v[1], v[0]) if np.hypot(*v) > 0.05 else 0.3
            s = score if exact_score else float(np.clip(score + self.rng.normal(0.0, score_noise), 0.01, 0.99))
            lab = label(f) if callable(label) else label
            self.pred[f].append(self._box(tid, lab, p, v, yaw, s))

    def stamp(self, f):
        return T0_NS + f * DT_NS

    def write(self, path, tracks_cls, track_cls, fds_bytes):
        from mcap.writer import CompressionType, Writer
        with open(path, "wb") as f:
            # No summary offsets: mcap 1.6.0 would write offsets to empty attachment/metadata-index
            # groups, which `pymcap-cli doctor` reports as SUMMARY_OFFSET_WITHOUT_GROUP errors.
            w = Writer(f, compression=CompressionType.ZSTD, use_summary_offsets=False)
            w.start(profile="", library="probmot make_eval_fixtures.py")
            w.add_metadata("probmot.eval_fixture", {"name": self.name, "description": self.description})
            schema_id = w.register_schema(name="probmot.Tracks3D", encoding="protobuf", data=fds_bytes)
            channels = {
                "/ground_truth": w.register_channel(topic="/ground_truth", message_encoding="protobuf",
                                                    schema_id=schema_id,
                                                    metadata={"probmot.fixture": self.name}),
                "/tracks": w.register_channel(topic="/tracks", message_encoding="protobuf",
                                              schema_id=schema_id,
                                              metadata={"probmot.fixture": self.name}),
            }
            seq = {"/ground_truth": 0, "/tracks": 0}
            if self.ego is not None:
                # The channel `probmot import nuscenes` writes: JSON {stamp, translation, rotation}.
                ego_schema = w.register_schema(name="probmot.EgoPose", encoding="jsonschema",
                                               data=EGO_POSE_JSON_SCHEMA.encode())
                ego_channel = w.register_channel(topic="/ego_pose", message_encoding="json",
                                                 schema_id=ego_schema,
                                                 metadata={"probmot.fixture": self.name})
                for fr in range(self.n):
                    pose = {"stamp": self.stamp(fr),
                            "translation": [float(v) for v in self.ego[fr]],
                            "rotation": [1.0, 0.0, 0.0, 0.0]}
                    w.add_message(channel_id=ego_channel, log_time=self.stamp(fr),
                                  publish_time=self.stamp(fr), sequence=fr,
                                  data=json.dumps(pose, separators=(",", ":")).encode())
            for fr in range(self.n):
                for topic, boxes, present in (("/ground_truth", self.gt[fr], self.gt_frames),
                                              ("/tracks", self.pred[fr], self.pred_frames)):
                    if fr not in present:
                        assert not boxes, (self.name, topic, fr)
                        continue
                    msg = tracks_cls(stamp=self.stamp(fr), frame_id="map")
                    for b in boxes:
                        l, wd, h = SIZES[b["label"]]
                        t = msg.tracks.add()
                        t.id = b["id"]
                        t.label = b["label"]
                        t.center.x, t.center.y, t.center.z = b["x"], b["y"], b["z"]
                        t.size.length, t.size.width, t.size.height = l, wd, h
                        t.yaw = b["yaw"]
                        t.velocity.x, t.velocity.y = b["vx"], b["vy"]
                        t.score = b["score"]
                    w.add_message(channel_id=channels[topic], log_time=self.stamp(fr),
                                  publish_time=self.stamp(fr), sequence=seq[topic],
                                  data=msg.SerializeToString(deterministic=True))
                    seq[topic] += 1
            w.finish()


def rng_far_point(scene, frame_positions, lo, hi, min_dist):
    """A random point in the box [lo, hi] at least `min_dist` from all `frame_positions`."""
    for _ in range(1000):
        p = scene.rng.uniform(lo, hi)
        if all(np.hypot(*(p - q)) >= min_dist for q in frame_positions):
            return p
    raise RuntimeError("no free point")


# ----------------------------------------------------------------------------------------------
# Fixtures
# ----------------------------------------------------------------------------------------------
def perfect():
    s = Scene("perfect", 20, 1001, "tracks identical to GT (car, pedestrian); scores vary per track")
    specs = [  # gid, label, start, vel, accel, frames, track score
        (1, "car", (-20.0, -5.0), (8.0, 0.0), (0.0, 0.3), range(0, 20), 0.92),
        (2, "car", (30.0, 4.0), (-6.0, 0.5), (0.2, 0.0), range(0, 20), 0.71),
        (3, "car", (5.0, -25.0), (0.0, 5.0), (0.0, 0.0), range(3, 17), 0.55),
        (4, "pedestrian", (2.0, 8.0), (1.2, -0.3), (0.0, 0.0), range(0, 20), 0.83),
        (5, "pedestrian", (-6.0, 10.0), (0.5, 1.0), (0.0, 0.0), range(2, 20), 0.47),
        (6, "pedestrian", (12.0, -3.0), (0.0, 0.0), (0.0, 0.0), range(0, 13), 0.64),
    ]
    for gid, label, start, vel, acc, frames, score in specs:
        path = s.path(start, vel, acc)
        s.add_gt(gid, label, path, frames)
        # Identical boxes (only the ids and the scores differ from GT).
        for f in frames:
            b = dict(next(x for x in s.gt[f] if x["id"] == gid))
            b["id"] = 100 + gid
            b["score"] = float(np.clip(score + s.rng.normal(0.0, 0.04), 0.01, 0.99))
            s.pred[f].append(b)
    return s


def idswitch_frag():
    s = Scene("idswitch_frag", 30, 1002,
              "id switches (swap of two car tracks; crossing pedestrians), fragmentation (3-frame loss "
              "with the same id, fast and slow; resumed with a new id), late start / early end, a GT "
              "car never tracked")
    A = s.path((-45.0, 0.0), (6.0, 0.0))
    B = s.path((-43.0, 3.5), (6.0, 0.0))
    C = s.path((-60.0, -8.0), (10.0, 0.0))
    D = s.path((-20.0, -15.0), (4.0, 1.0))
    E = s.path((10.0, 12.0), (0.6, 0.0))
    F = s.path((40.0, 20.0), (-3.0, 0.0))
    G = s.path((-10.0, -30.0), (2.0, 2.0))
    P1 = s.path((-7.0, 30.0), (1.4, 0.0))
    P2 = s.path((7.0, 30.8), (-1.4, 0.0))
    P3 = s.path((15.0, 28.0), (0.0, 0.0))
    for gid, path, frames in ((1, A, range(30)), (2, B, range(30)), (3, C, range(30)), (4, D, range(30)),
                              (5, E, range(30)), (6, F, range(5, 26)), (7, G, range(20))):
        s.add_gt(gid, "car", path, frames)
    for gid, path in ((21, P1), (22, P2), (23, P3)):
        s.add_gt(gid, "pedestrian", path, range(30))

    def follow(first, second, switch):
        return lambda f: (first[0][f], first[1][f]) if f < switch else (second[0][f], second[1][f])

    # Car tracks 11/12 swap their objects at frame 15 (lanes 3.5 m apart: a clean double switch).
    s.add_track(11, "car", follow(A, B, 15), range(30), 0.81)
    s.add_track(12, "car", follow(B, A, 15), range(30), 0.77)
    # Fast car lost for 3 frames, same id: the devkit's (mirrored) interpolation misplaces 2 of 3 boxes.
    s.add_track(13, "car", C, [f for f in range(30) if f not in (10, 11, 12)], 0.90)
    # Slow car lost for 3 frames, same id: interpolation fills the hole within 2 m.
    s.add_track(15, "car", E, [f for f in range(30) if f not in (12, 13, 14)], 0.58)
    # Car lost for 3 frames and resumed under a new id.
    s.add_track(14, "car", D, range(0, 12), 0.66)
    s.add_track(16, "car", D, range(15, 30), 0.62)
    # Late start, early end.
    s.add_track(17, "car", F, range(8, 21), 0.45)
    # Crossing pedestrians: the tracks swap at the crossing (frame 10 -> 11).
    s.add_track(31, "pedestrian", follow(P1, P2, 11), range(30), 0.72, noise=0.1)
    s.add_track(32, "pedestrian", follow(P2, P1, 11), range(30), 0.69, noise=0.1)
    # Standing pedestrian, tracked from frame 3 on.
    s.add_track(33, "pedestrian", P3, range(3, 30), 0.50, noise=0.1)
    # A short false pedestrian track far away.
    s.add_track(34, "pedestrian", s.path((-30.0, 40.0), (0.5, 0.0)), range(12, 18), 0.30)
    return s


def false_positives():
    s = Scene("false_positives", 25, 1003,
              "good high-score tracks, low-score true tracks, a low-score shadow track next to a "
              "tracked car, many low-score false tracks far from GT, a truck with only far-off "
              "predictions")
    cars = {
        1: s.path((-30.0, -2.0), (7.0, 0.0)), 2: s.path((25.0, 2.0), (-7.0, 0.2)),
        3: s.path((0.0, -30.0), (0.5, 4.0)), 4: s.path((-15.0, 15.0), (3.0, -0.5)),
        5: s.path((10.0, -10.0), (0.0, 0.0)), 6: s.path((-5.0, 25.0), (5.0, 0.0)),
    }
    peds = {
        11: s.path((3.0, 5.0), (1.0, 0.5)), 12: s.path((-8.0, -6.0), (0.0, 1.3)),
        13: s.path((15.0, 10.0), (-0.8, 0.0)), 14: s.path((-20.0, 0.0), (1.1, -0.4)),
    }
    truck = s.path((40.0, -20.0), (-4.0, 1.0))
    for gid, p in cars.items():
        s.add_gt(gid, "car", p, range(25))
    for gid, p in peds.items():
        s.add_gt(gid, "pedestrian", p, range(25))
    s.add_gt(21, "truck", truck, range(25))

    for gid, score in ((1, 0.93), (2, 0.88), (3, 0.85), (4, 0.90)):
        s.add_track(100 + gid, "car", cars[gid], range(25), score, noise=0.25)
    s.add_track(105, "car", cars[5], range(25), 0.22, noise=0.25)      # low-score true tracks
    s.add_track(106, "car", cars[6], range(3, 25), 0.31, noise=0.25)
    shadow = (lambda f: (cars[1][0][f] + np.array([0.0, 0.8]), cars[1][1][f]))
    s.add_track(107, "car", shadow, range(5, 13), 0.35, noise=0.05)   # duplicate of car 1
    s.add_track(111, "pedestrian", peds[11], range(25), 0.80, noise=0.12)
    s.add_track(112, "pedestrian", peds[12], range(25), 0.75, noise=0.12)
    s.add_track(113, "pedestrian", peds[13], range(25), 0.25, noise=0.12)  # low-score true track
    s.add_track(114, "pedestrian", peds[14], range(6, 19), 0.60, noise=0.12)

    # False tracks: short, low score, at least 6 m from every GT box of their frames.
    next_id = 500
    for k in range(30):
        label = ("car", "pedestrian", "truck")[k % 3] if k < 27 else "car"
        length = int(s.rng.integers(2, 7))
        first = int(s.rng.integers(0, 25 - length + 1))
        frames = range(first, first + length)
        occupied = [b for f in frames for b in s.gt[f]]
        start = rng_far_point(s, [np.array([b["x"], b["y"]]) for b in occupied], np.array([-60.0, -50.0]),
                              np.array([60.0, 50.0]), 9.0)
        vel = s.rng.normal(0.0, 0.5, 2)
        t0 = first * DT
        path = s.path(start - vel * t0, vel)
        score = float(s.rng.uniform(0.05, 0.40))
        s.add_track(next_id, label, path, frames, score, noise=0.05, score_noise=0.02)
        next_id += 1
    # Sanity: every false box is far from all GT boxes of its frame.
    for f in range(25):
        for b in s.pred[f]:
            if b["id"] >= 500:
                assert all(np.hypot(b["x"] - g["x"], b["y"] - g["y"]) > 5.0 for g in s.gt[f])
    return s


def gaps_multiclass():
    s = Scene("gaps_multiclass", 24, 1004,
              "car/pedestrian/bicycle/truck/bus with 1-, 2- and 3-frame holes in GT and in tracks "
              "(filled by the devkit's interpolation, some misplaced by its mirrored weights); a track "
              "whose label changes from bicycle to motorcycle across a hole; motorcycle only predicted "
              "(NaN); trailer only in GT (worst values); frames 0-1 have no /tracks message, frame 23 no "
              "/ground_truth message")
    s.pred_frames = set(range(2, 24))
    s.gt_frames = set(range(0, 23))
    allf = range(0, 23)

    def minus(r, holes):
        return [f for f in r if f not in holes]

    # car
    c1 = s.path((-50.0, 0.0), (8.0, 0.0))
    c2 = s.path((5.0, 6.0), (1.0, 0.0))
    c3 = s.path((-20.0, -6.0), (5.0, 0.5))
    c4 = s.path((30.0, 12.0), (-6.0, 0.0))
    s.add_gt(1, "car", c1, minus(allf, (8, 9)))              # 2-frame GT hole, fast
    s.add_gt(2, "car", c2, minus(allf, (12, 13, 14)))        # 3-frame GT hole, slow
    s.add_gt(3, "car", c3, allf)
    s.add_gt(4, "car", c4, allf)
    s.add_track(101, "car", c1, range(2, 23), 0.82)
    s.add_track(102, "car", c2, range(2, 24), 0.74)
    s.add_track(103, "car", c3, minus(range(2, 23), (10,)), 0.66)       # 1-frame hole
    s.add_track(104, "car", c4, minus(range(2, 23), (15, 16)), 0.58)    # 2-frame hole, fast
    # pedestrian
    p1 = s.path((0.0, -15.0), (1.5, 0.0))
    p2 = s.path((-10.0, 20.0), (0.0, -3.0))
    s.add_gt(11, "pedestrian", p1, minus(allf, (6,)))        # 1-frame GT hole
    s.add_gt(12, "pedestrian", p2, minus(allf, (4, 5, 6)))   # 3-frame GT hole, running
    s.add_track(111, "pedestrian", p1, minus(range(2, 23), (12, 13, 14)), 0.71, noise=0.1)
    s.add_track(112, "pedestrian", p2, range(2, 23), 0.53, noise=0.1)
    # bicycle
    b1 = s.path((20.0, -20.0), (0.0, 4.0))
    b2 = s.path((-30.0, -25.0), (3.0, 1.0))
    b3 = s.path((-40.0, 30.0), (4.0, 0.0))
    s.add_gt(21, "bicycle", b1, allf)
    s.add_gt(22, "bicycle", b2, minus(allf, (9,)))           # 1-frame GT hole
    s.add_gt(23, "bicycle", b3, range(3, 21))
    s.add_track(121, "bicycle", b1, minus(range(2, 23), (7, 8)), 0.63, noise=0.15)   # 2-frame hole
    s.add_track(122, "bicycle", b2, range(4, 23), 0.41, noise=0.15)
    # Label flips bicycle -> motorcycle across a 2-frame hole (frames 10, 11).
    s.add_track(123, lambda f: "bicycle" if f < 10 else "motorcycle", b3, minus(range(3, 21), (10, 11)),
                0.57, noise=0.15)
    # truck
    t1 = s.path((-35.0, -40.0), (6.0, 1.0))
    s.add_gt(31, "truck", t1, minus(allf, (10, 15, 16, 17)))  # 1- and 3-frame GT holes
    s.add_track(131, "truck", t1, minus(range(2, 23), (5, 12, 13)), 0.69, noise=0.3)
    # bus
    u1 = s.path((45.0, -5.0), (-0.5, 0.0))
    u2 = s.path((-70.0, 45.0), (10.0, 0.0))
    s.add_gt(41, "bus", u1, minus(allf, (7, 8)))             # 2-frame GT hole
    s.add_gt(42, "bus", u2, allf)
    s.add_track(141, "bus", u1, minus(range(2, 23), (14, 15, 16)), 0.77, noise=0.3)
    s.add_track(142, "bus", u2, minus(range(2, 23), (11, 12, 13)), 0.61, noise=0.3)   # fast: misplaced
    # motorcycle: predictions only
    s.add_track(151, "motorcycle", s.path((10.0, 40.0), (3.0, -1.0)), range(4, 20), 0.49)
    # trailer: GT only
    s.add_gt(51, "trailer", s.path((-25.0, 45.0), (0.0, 0.0)), allf)
    s.add_gt(52, "trailer", s.path((55.0, 30.0), (-2.0, 0.0)), range(5, 18))
    return s


def ties():
    s = Scene("ties", 20, 1005,
              "many identical scores: car tracks at exactly 0.1 or 0.7 (means of equal 0.1 scores are "
              "not exactly 0.1), pedestrian tracks all at exactly 0.5, bicycle tracks and false tracks "
              "at exactly 0.3")
    # car
    cars = {i: s.path((-40.0 + 12.0 * i, -10.0 + 4.0 * (i % 3)), (4.0 + i, 0.3 * i)) for i in range(1, 7)}
    for gid, p in cars.items():
        s.add_gt(gid, "car", p, range(20))
    s.add_track(101, "car", cars[1], range(20), 0.1, exact_score=True)
    s.add_track(102, "car", cars[2], range(0, 7), 0.1, exact_score=True)
    s.add_track(103, "car", cars[3], [f for f in range(20) if f not in (8, 9)], 0.1, exact_score=True)
    s.add_track(104, "car", cars[4], range(20), 0.7, exact_score=True)
    s.add_track(105, "car", cars[5], range(5, 20), 0.7, exact_score=True)
    s.add_track(106, "car", cars[6], range(0, 3), 0.1, exact_score=True)
    s.add_track(107, "car", s.path((0.0, 40.0), (1.0, 0.0)), range(4, 12), 0.1, exact_score=True)
    s.add_track(108, "car", s.path((-30.0, 45.0), (0.0, -1.0)), range(0, 20), 0.7, exact_score=True)
    # pedestrian: everything at 0.5
    peds = {10 + i: s.path((-10.0 + 5.0 * i, 20.0), (0.0, 1.0 - 0.3 * i)) for i in range(1, 5)}
    for gid, p in peds.items():
        s.add_gt(gid, "pedestrian", p, range(20))
    s.add_track(111, "pedestrian", peds[11], range(20), 0.5, exact_score=True, noise=0.1)
    s.add_track(112, "pedestrian", peds[12], range(3, 17), 0.5, exact_score=True, noise=0.1)
    s.add_track(113, "pedestrian", peds[13], range(0, 10), 0.5, exact_score=True, noise=0.1)
    s.add_track(114, "pedestrian", peds[13], range(10, 20), 0.5, exact_score=True, noise=0.1)
    s.add_track(115, "pedestrian", s.path((30.0, -30.0), (0.0, 0.0)), range(20), 0.5, exact_score=True)
    # bicycle: one true and one false track, both at 0.3
    b1 = s.path((20.0, 0.0), (3.0, 3.0))
    s.add_gt(21, "bicycle", b1, range(20))
    s.add_track(121, "bicycle", b1, range(2, 18), 0.3, exact_score=True, noise=0.1)
    s.add_track(122, "bicycle", s.path((-40.0, -40.0), (2.0, 0.0)), range(0, 10), 0.3, exact_score=True)
    return s


def range_filter():
    s = Scene("range_filter", 30, 1006,
              "ego drives along x at 8 m/s; objects enter and leave the 40/50 m class ranges; "
              "/ego_pose channel for the range filter")
    s.ego = [(8.0 * DT * f, 1.0, 0.0) for f in range(s.n)]
    ego_x = np.array([e[0] for e in s.ego])
    # Parked cars along the road: they come into the 50 m range and fall out of it behind.
    for i, x in enumerate((20.0, 55.0, 90.0, 125.0, 160.0)):
        p = s.path((x, 6.0 if i % 2 else -5.0), (0.0, 0.0))
        s.add_gt(1 + i, "car", p, range(s.n))
        s.add_track(101 + i, "car", p, range(s.n), 0.6 + 0.05 * i, noise=0.15)
    # A car ahead whose distance oscillates across 50 m: the devkit drops it in the frames where
    # it is out of range, then interpolation fills those frames again (GT and track alike).
    ahead = (np.stack([ego_x + 50.0 + 1.5 * np.sin(np.arange(s.n) * 0.9), np.full(s.n, 1.0)], 1),
             np.tile([8.0, 0.0], (s.n, 1)))
    s.add_gt(10, "car", ahead, range(s.n))
    s.add_track(110, "car", ahead, range(s.n), 0.7, noise=0.1)
    # A truck ahead at 47-53 m, tracked with a lag (2.5 m behind: FN + FP when both are in range).
    truck = (np.stack([ego_x + 50.0 + 3.0 * np.cos(np.arange(s.n) * 0.4), np.full(s.n, -3.0)], 1),
             np.tile([8.0, 0.0], (s.n, 1)))
    lagged = (truck[0] - np.array([2.5, 0.0]), truck[1])
    s.add_gt(20, "truck", truck, range(s.n))
    s.add_track(120, "truck", lagged, range(s.n), 0.5, noise=0.05)
    # Pedestrians standing at the roadside: in the 40 m range only while the ego passes.
    for i, x in enumerate((35.0, 70.0, 105.0)):
        p = s.path((x, 8.0), (0.0, 0.3))
        s.add_gt(30 + i, "pedestrian", p, range(s.n))
        s.add_track(130 + i, "pedestrian", p, range(4, s.n), 0.55, noise=0.1)
    # A bicycle riding ahead at 38-44 m (range 40 m).
    bike = (np.stack([ego_x + 41.0 + 3.0 * np.sin(np.arange(s.n) * 0.5), np.full(s.n, 3.0)], 1),
            np.tile([8.0, 0.0], (s.n, 1)))
    s.add_gt(40, "bicycle", bike, range(s.n))
    s.add_track(140, "bicycle", bike, range(s.n), 0.45, noise=0.1)
    # False tracks: far away (removed by the filter) and near (kept: FP).
    s.add_track(150, "car", s.path((60.0, 70.0), (0.0, 0.0)), range(s.n), 0.3, noise=0.05)
    s.add_track(151, "pedestrian", (np.stack([ego_x + 10.0, np.full(s.n, -12.0)], 1),
                                    np.tile([8.0, 0.0], (s.n, 1))), range(5, 15), 0.2, noise=0.05)
    return s


def repeated_ids(part):
    """One of three logs whose ids all start at 1 (as KITTI label files and `simulate` number
    them): evaluated together they check that every per-id count takes (log, id) as the object."""
    seed = {"a": 1007, "b": 1008, "c": 1009}[part]
    s = Scene(f"repeated_ids_{part}", 20, seed,
              "ids 1.. in every log: cars 1-2 tracked by tracks 1-2 (log b: a switch of track 1 to "
              "track 2 on car 1), bicycles 5-6 never matched (no recall threshold reached), "
              "motorcycle 7 tracked by track 7 at a score that differs per log")
    off = {"a": 0.0, "b": 7.0, "c": -6.0}[part]
    car1 = s.path((-20.0 + off, -4.0), (6.0, 0.2))
    car2 = s.path((10.0, 6.0 + off), (-4.0, 0.5))
    s.add_gt(1, "car", car1, range(20))
    s.add_gt(2, "car", car2, range(2, 20))
    if part == "b":
        s.add_track(1, "car", car1, range(0, 10), 0.8)
        s.add_track(2, "car", car1, range(10, 20), 0.8)
        s.add_track(3, "car", car2, range(4, 20), 0.6)
    else:
        s.add_track(1, "car", car1, range(1, 20), 0.8)
        s.add_track(2, "car", car2, range(2, 16), 0.6)
    # Bicycles that nothing matches; a false bicycle track far away in log a only.
    s.add_gt(5, "bicycle", s.path((30.0, -30.0 + off), (1.0, 1.0)), range(20))
    s.add_gt(6, "bicycle", s.path((-35.0, 25.0), (0.0, -1.5)), range(5, 20))
    if part == "a":
        s.add_track(5, "bicycle", s.path((60.0, 60.0), (0.0, 0.0)), range(3, 12), 0.4)
    # Motorcycle 7 in logs a and c, tracked by track 7 (0.9 in a, 0.2 in c) and, in c, a false
    # track 8 at 0.5: with per-log mean scores the false track ranks between the true ones.
    if part in ("a", "c"):
        moto = s.path((0.0, -15.0), (5.0, 2.0))
        s.add_gt(7, "motorcycle", moto, range(20))
        s.add_track(7, "motorcycle", moto, range(20), 0.9 if part == "a" else 0.2)
        if part == "c":
            s.add_track(8, "motorcycle", s.path((-40.0, -40.0), (0.0, 1.0)), range(6, 14), 0.5)
    return s


FIXTURES = [perfect, idswitch_frag, false_positives, gaps_multiclass, ties, range_filter,
            lambda: repeated_ids("a"), lambda: repeated_ids("b"), lambda: repeated_ids("c")]


# ----------------------------------------------------------------------------------------------
# nuScenes tables: the devkit's filters end to end (import nuscenes --tracks, eval --devkit)
# ----------------------------------------------------------------------------------------------
CATEGORIES = {"car": "vehicle.car", "pedestrian": "human.pedestrian.adult",
              "bicycle": "vehicle.bicycle", "motorcycle": "vehicle.motorcycle",
              "truck": "vehicle.truck", "bus": "vehicle.bus.rigid", "trailer": "vehicle.trailer",
              "rack": "static_object.bicycle_rack"}
RACK_SIZE = (6.0, 2.0, 1.5)  # length, width, height


def quat_yaw(yaw, pitch=0.0):
    """Quaternion [w, x, y, z] of a yaw about z followed by a small pitch about the box's y axis."""
    cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
    return [cy * cp, -sy * sp, cy * sp, sy * cp]


class TablesScene:
    """One scene of nuScenes tables: samples, ego poses, annotated objects and submitted tracks."""

    def __init__(self, name, n, t0_us, ego, seed):
        self.name, self.n, self.rng = name, n, np.random.default_rng(seed)
        self.samples = [f"{name}-s{i:02d}" for i in range(n)]
        self.times = [t0_us + 500_000 * i for i in range(n)]
        self.ego = ego  # (x, y) per sample
        self.objects = []  # (key, class, positions per sample or None, yaw, pitch, points per sample)
        self.tracks = []  # (tracking_id, class, positions per sample or None, score)

    def obj(self, key, cls, pos, yaw=0.0, pitch=0.0, points=None, z=None):
        size = RACK_SIZE if cls == "rack" else SIZES[cls]
        z = size[2] / 2 if z is None else z
        pos = [None if p is None else (float(p[0]), float(p[1]), z) for p in pos]
        pts = points or [(12, 1)] * self.n
        self.objects.append((f"{self.name}-{key}", cls, pos, yaw, pitch, pts))

    def track(self, tid, cls, pos, score, noise=0.15, z=None):
        z = SIZES[cls][2] / 2 if z is None else z
        out = []
        for p in pos:
            if p is None:
                out.append(None)
                continue
            d = self.rng.normal(0.0, noise, 2)
            out.append((float(p[0] + d[0]), float(p[1] + d[1]), z))
        self.tracks.append((f"{self.name}-{tid}", cls, out, score))


def filters_scene_1():
    n = 20
    ego = [(500.0 + 5.0 * i, 1000.0) for i in range(n)]
    s = TablesScene("scene-f001", n, 1_767_225_600_000_000, ego, 2001)
    ex = np.array([e[0] for e in ego])
    # A parked car that comes into the 50 m range at frame 6 (58 m ahead at the start).
    car_a = [(ego[0][0] + 58.0, 1004.0)] * n
    s.obj("car-a", "car", car_a)
    s.track("car-a", "car", car_a, 0.8)
    # A car always 60-70 m away: removed by the range filter (GT and track).
    car_b = [(x + 60.0 + 0.5 * i, 990.0) for i, x in enumerate(ex)]
    s.obj("car-b", "car", car_b)
    s.track("car-b", "car", car_b, 0.6)
    # A car beside the road whose annotations in frames 7-9 have no lidar or radar point.
    car_c = [(520.0 + 2.0 * i, 1007.0) for i in range(n)]
    s.obj("car-c", "car", car_c, points=[(0, 0) if 7 <= i <= 9 else (30, 2) for i in range(n)])
    s.track("car-c", "car", car_c, 0.7)
    # A pedestrian without points in its first four annotations, tracked throughout.
    ped = [(530.0, 1012.0 - 0.6 * i) for i in range(n)]
    s.obj("ped-a", "pedestrian", ped, points=[(0, 0) if i < 4 else (8, 0) for i in range(n)])
    s.track("ped-a", "pedestrian", ped, 0.55)
    # A pedestrian with radar points only (kept).
    ped_b = [(540.0 - 0.5 * i, 995.0) for i in range(n)]
    s.obj("ped-b", "pedestrian", ped_b, points=[(0, 1)] * n)
    s.track("ped-b", "pedestrian", ped_b, 0.5)
    # A bicycle rack at (545, 1003), turned by 0.3 rad and pitched by 0.05 rad.
    rack = [(545.0, 1003.0)] * n
    s.obj("rack", "rack", rack, yaw=0.3, pitch=0.05, z=0.75)
    # Bicycles parked in the rack (GT and tracks removed), a motorcycle in it (removed), a
    # pedestrian standing in it (kept), a bicycle ridden past it (kept), a false bicycle track
    # just outside it (kept: FP).
    c, sn = math.cos(0.3), math.sin(0.3)
    in_rack = lambda u, v: (545.0 + c * u - sn * v, 1003.0 + sn * u + c * v)
    for k, u in enumerate((-2.0, 0.0, 2.0)):
        p = [in_rack(u, 0.2)] * n
        s.obj(f"bike-rack-{k}", "bicycle", p, yaw=0.3 + math.pi / 2, z=0.6)
        s.track(f"bike-rack-{k}", "bicycle", p, 0.4 + 0.1 * k, noise=0.05, z=0.6)
    moto = [in_rack(1.0, -0.4)] * n
    s.obj("moto-rack", "motorcycle", moto, z=0.7)
    s.track("moto-rack", "motorcycle", moto, 0.45, noise=0.05, z=0.7)
    ped_r = [in_rack(-1.0, -0.3)] * n
    s.obj("ped-rack", "pedestrian", ped_r, z=0.9)
    s.track("ped-rack", "pedestrian", ped_r, 0.6, noise=0.05, z=0.9)
    bike = [(535.0 + 1.5 * i, 1001.0 - 0.3 * i) for i in range(n)]
    s.obj("bike-ride", "bicycle", bike)
    s.track("bike-ride", "bicycle", bike, 0.65)
    s.track("bike-false", "bicycle", [in_rack(0.0, 1.6)] * n, 0.3, noise=0.02, z=0.6)
    # A motorcycle on the road, tracked from frame 3, beyond 40 m from frame 14 on.
    moto_r = [(530.0 + 0.5 * i, 998.0) for i in range(n)]
    s.obj("moto-road", "motorcycle", moto_r)
    s.track("moto-road", "motorcycle", [None] * 3 + moto_r[3:], 0.5)
    return s


def filters_scene_2():
    n = 16
    ego = [(2000.0, 3000.0 + 1.0 * i) for i in range(n)]
    s = TablesScene("scene-f002", n, 1_767_226_000_000_000, ego, 2002)
    # A truck at 45-55 m from the ego (range 50 m), tracked.
    truck = [(2000.0 + 50.0 + 5.0 * math.sin(0.7 * i), 3000.0 + i) for i in range(n)]
    s.obj("truck", "truck", truck)
    s.track("truck", "truck", truck, 0.7)
    # A bus tracked with a lag, and a trailer whose annotations all lack points (no GT left).
    bus = [(2010.0 + 2.0 * i, 3020.0) for i in range(n)]
    s.obj("bus", "bus", bus)
    s.track("bus", "bus", [(x - 1.2, y) for x, y in bus], 0.6)
    trailer = [(1985.0, 3010.0)] * n
    s.obj("trailer", "trailer", trailer, points=[(0, 0)] * n)
    s.track("trailer", "trailer", trailer, 0.5)
    # A rack without yaw: a bicycle in it for the first half only (it then rides away).
    s.obj("rack", "rack", [(1995.0, 2990.0)] * n, z=0.75)
    bike = [(1995.0 + (0.0 if i < 8 else 1.5 * (i - 7)), 2990.0 + (0.0 if i < 8 else 2.0)) for i in range(n)]
    s.obj("bike", "bicycle", bike, z=0.6)
    s.track("bike", "bicycle", bike, 0.5, noise=0.05, z=0.6)
    # Cars: one tracked, one missed.
    car = [(2005.0, 2995.0 + 0.8 * i) for i in range(n)]
    s.obj("car", "car", car)
    s.track("car", "car", car, 0.9)
    s.obj("car-missed", "car", [(1990.0 - 0.5 * i, 3005.0) for i in range(n)])
    return s


def write_tables(out_dir, scenes, version="v1.0-probmot"):
    """Writes the scenes as nuScenes tables under out_dir/version and the tracking submission."""
    tdir = os.path.join(out_dir, version)
    os.makedirs(tdir, exist_ok=True)
    t = {k: [] for k in ("category", "attribute", "visibility", "instance", "sensor",
                         "calibrated_sensor", "ego_pose", "log", "scene", "sample", "sample_data",
                         "sample_annotation", "map")}
    for cls, cat in CATEGORIES.items():
        t["category"].append({"token": f"cat-{cls}", "name": cat, "description": ""})
    t["visibility"].append({"token": "4", "level": "v80-100", "description": ""})
    t["sensor"].append({"token": "sensor-lidar", "channel": "LIDAR_TOP", "modality": "lidar"})
    t["calibrated_sensor"].append({"token": "cs-lidar", "sensor_token": "sensor-lidar",
                                   "translation": [0.9, 0.0, 1.8], "rotation": [1.0, 0.0, 0.0, 0.0],
                                   "camera_intrinsic": []})
    results = {}
    for sc in scenes:
        log = f"log-{sc.name}"
        t["log"].append({"token": log, "logfile": sc.name, "vehicle": "probmot",
                         "date_captured": "2026-01-01", "location": "singapore-onenorth"})
        t["scene"].append({"token": f"tok-{sc.name}", "name": sc.name, "description": "",
                           "log_token": log, "nbr_samples": sc.n,
                           "first_sample_token": sc.samples[0], "last_sample_token": sc.samples[-1]})
        for i, (tok, ts) in enumerate(zip(sc.samples, sc.times)):
            t["sample"].append({"token": tok, "timestamp": ts, "scene_token": f"tok-{sc.name}",
                                "prev": sc.samples[i - 1] if i else "",
                                "next": sc.samples[i + 1] if i + 1 < sc.n else ""})
            t["ego_pose"].append({"token": f"ep-{tok}", "timestamp": ts,
                                  "translation": [sc.ego[i][0], sc.ego[i][1], 0.0],
                                  "rotation": [1.0, 0.0, 0.0, 0.0]})
            t["sample_data"].append({"token": f"sd-{tok}", "sample_token": tok,
                                     "ego_pose_token": f"ep-{tok}", "calibrated_sensor_token": "cs-lidar",
                                     "timestamp": ts, "fileformat": "pcd", "is_key_frame": True,
                                     "height": 0, "width": 0,
                                     "filename": f"samples/LIDAR_TOP/{tok}.pcd.bin",
                                     "prev": "", "next": ""})
        for key, cls, pos, yaw, pitch, pts in sc.objects:
            frames = [i for i, p in enumerate(pos) if p is not None]
            anns = [f"ann-{key}-{i:02d}" for i in frames]
            size = RACK_SIZE if cls == "rack" else SIZES[cls]
            t["instance"].append({"token": f"inst-{key}", "category_token": f"cat-{cls}",
                                  "nbr_annotations": len(anns), "first_annotation_token": anns[0],
                                  "last_annotation_token": anns[-1]})
            for k, i in enumerate(frames):
                t["sample_annotation"].append({
                    "token": anns[k], "sample_token": sc.samples[i], "instance_token": f"inst-{key}",
                    "visibility_token": "4", "attribute_tokens": [],
                    "translation": list(pos[i]), "size": [size[1], size[0], size[2]],
                    "rotation": quat_yaw(yaw, pitch), "prev": anns[k - 1] if k else "",
                    "next": anns[k + 1] if k + 1 < len(anns) else "",
                    "num_lidar_pts": pts[i][0], "num_radar_pts": pts[i][1]})
        for tok in sc.samples:
            results[tok] = []
        for tid, cls, pos, score in sc.tracks:
            for i, p in enumerate(pos):
                if p is None:
                    continue
                sz = SIZES[cls]
                results[sc.samples[i]].append({
                    "sample_token": sc.samples[i], "translation": list(p),
                    "size": [sz[1], sz[0], sz[2]], "rotation": quat_yaw(0.2),
                    "velocity": [0.0, 0.0], "tracking_id": tid, "tracking_name": cls,
                    "tracking_score": float(np.clip(score + sc.rng.normal(0.0, 0.05), 0.01, 0.99))})
    t["map"].append({"token": "map-probmot", "log_tokens": [lg["token"] for lg in t["log"]],
                     "category": "semantic_prior", "filename": "maps/probmot.png"})
    for name, rows in t.items():
        with open(os.path.join(tdir, name + ".json"), "w") as f:
            json.dump(rows, f, indent=0)
    with open(os.path.join(tdir, "splits.json"), "w") as f:
        json.dump({"probmot_filters": [sc.name for sc in scenes]}, f)
    sub = {"meta": {"use_camera": False, "use_lidar": True, "use_radar": False, "use_map": False,
                    "use_external": False}, "results": results}
    path = os.path.join(out_dir, "tracking_results.json")
    with open(path, "w") as f:
        json.dump(sub, f)
    n_ann = len(t["sample_annotation"])
    n_trk = sum(len(v) for v in results.values())
    print(f"{tdir}: {len(scenes)} scenes, {len(t['sample'])} samples, {n_ann} annotations; "
          f"{path}: {n_trk} track boxes")


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    out_dir = argv[1]
    os.makedirs(out_dir, exist_ok=True)
    fds = descriptor_set_bytes()
    tracks_cls, track_cls = message_classes(fds)
    for make in FIXTURES:
        scene = make()
        path = os.path.join(out_dir, scene.name + ".mcap")
        scene.write(path, tracks_cls, track_cls, fds)
        n_gt = sum(len(b) for b in scene.gt)
        n_pred = sum(len(b) for b in scene.pred)
        print(f"{path}: {scene.n} frames, {n_gt} GT boxes, {n_pred} track boxes, "
              f"{os.path.getsize(path)} bytes")
    write_tables(os.path.join(out_dir, "nuscenes_filters"), [filters_scene_1(), filters_scene_2()])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
