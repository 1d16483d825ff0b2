#!/usr/bin/env python3
"""Convert a tracked MCAP file to a Rerun recording (.rrd) for scrubbing through the drive.

The file is read with the `mcap` package and decoded from the schemas embedded in it (no
generated code from this repository), like check_tracks.py: protobuf with `mcap_protobuf`, ROS 2
CDR with `mcap_ros2`, JSON with the standard library. Each topic may hold any box message
`probmot track` reads or writes:
  probmot.Detections3D               protobuf or json
  probmot.Tracks3D                   protobuf (tracks, ground truth)
  vision_msgs/msg/Detection3DArray   ROS 2 CDR, vision_msgs 4.x or 2.x layout (detections, and
                                     the tracks of `track --tracks-format ros2`: id = the
                                     Detection3D id; no velocity)
  foxglove.SceneUpdate               protobuf; one box per cube; label, score and id from the
                                     entity metadata `label` (else `class`, `class_id`),
                                     `score`, `track_id`; each message is a whole frame

Entities (all under `world`, z up, metres):
  world/detections    thin grey boxes, labelled with class and score (shown on hover)
  world/tracks        boxes in a stable colour per track id (the colour `probmot plot` gives
                      the id), labelled "car 12"
  world/ground_truth  thin green boxes labelled "gt 3" (shown on hover), when the file has
                      ground truth
  world/trails        a line strip per track through its last N centres
  world/velocity      an arrow per track: its velocity over one second
  world/events        when the file has the /eval/events channel (`probmot eval --events`):
                      the evaluation's errors of each frame as boxes coloured by kind, and
  events              a text log entry per identity switch and fragmentation: the list of
                      moments to jump to (clicking an entry moves the timelines there)

Timelines: `log_time` (the MCAP messages' log time) and `frame` (index of the frame among all
distinct log times of the topics read, from 0). Every entity gets one row per frame in which its
topic has a message, empty frames included, so nothing stale stays on screen. The recording
carries a blueprint with a top-down 3D view, made active on load.

    python3 scripts/to_rerun.py drive.tracked.mcap -o drive.rrd
    rerun drive.rrd

Exit status: 0 on success, 2 on a usage error, an unreadable file or a missing topic.
Needs `python3 -m pip install -r scripts/requirements-view.txt` (the viewer only, about 770 MB).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from dataclasses import dataclass, field
from typing import Any, NoReturn, Sequence

try:
    import numpy as np
    import rerun as rr
    import rerun.blueprint as rrb
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory
except ImportError as e:  # pragma: no cover - depends on the environment
    sys.stderr.write(
        f"{os.path.basename(sys.argv[0])}: error: {e}; install the packages with "
        "`python3 -m pip install -r scripts/requirements-view.txt` (the viewer only, about 770 MB)\n"
    )
    sys.exit(2)

DETECTIONS_SCHEMA = "probmot.Detections3D"
TRACKS_SCHEMA = "probmot.Tracks3D"
ROS2_SCHEMA = "vision_msgs/msg/Detection3DArray"
SCENE_SCHEMA = "foxglove.SceneUpdate"
SCHEMAS = (DETECTIONS_SCHEMA, TRACKS_SCHEMA, ROS2_SCHEMA, SCENE_SCHEMA)
APPLICATION_ID = "probmot"

# Same table and hash as src/viz/plot.rs (PALETTE, mix64, id_color): an id has one colour in
# `probmot plot` pictures and in Rerun.
PALETTE = [
    (0x1F, 0x77, 0xB4),
    (0xFF, 0x7F, 0x0E),
    (0x2C, 0xA0, 0x2C),
    (0xD6, 0x27, 0x28),
    (0x94, 0x67, 0xBD),
    (0x8C, 0x56, 0x4B),
    (0xE3, 0x77, 0xC2),
    (0xBC, 0xBD, 0x22),
    (0x17, 0xBE, 0xCF),
    (0x1A, 0x1A, 0x80),
    (0x00, 0x80, 0x80),
    (0x7F, 0x00, 0x00),
    (0x99, 0x00, 0x66),
]
DETECTION_GREY = (0x8C, 0x8C, 0x8C)
TRUTH_GREEN = (0x2E, 0xCC, 0x40)
_M64 = (1 << 64) - 1


class UsageError(Exception):
    """A problem with the input or arguments, reported as `error: ...` with exit status 2."""


def fail(prog: str, message: str) -> NoReturn:
    """Print an error to stderr and exit with status 2."""
    sys.stderr.write(f"{prog}: error: {message}\n")
    sys.exit(2)


def mix64(x: int) -> int:
    """SplitMix64 finaliser, as `probmot::viz::plot::mix64`."""
    z = (x + 0x9E3779B97F4A7C15) & _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def id_color(track_id: int) -> tuple[int, int, int]:
    """The colour of an id: a stable hash of it into PALETTE."""
    return PALETTE[mix64(track_id) % len(PALETTE)]


@dataclass
class Box:
    """One box of a frame, as plain values."""

    id: int
    label: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float
    score: float
    # None: the message has no velocity (ROS 2 and SceneUpdate boxes).
    velocity: tuple[float, float, float] | None = (0.0, 0.0, 0.0)


@dataclass
class Run:
    """The frames of one file: per topic role, `log_time -> boxes` (one message per log time)."""

    path: str
    detections: dict[int, list[Box]] | None = None
    tracks: dict[int, list[Box]] | None = None
    ground_truth: dict[int, list[Box]] | None = None
    topics: list[str] = field(default_factory=list)

    def log_times(self) -> set[int]:
        """Every log time of the topics read."""
        out: set[int] = set()
        for frames in (self.detections, self.tracks, self.ground_truth):
            if frames is not None:
                out.update(frames)
        return out

    def all_boxes(self) -> list[Box]:
        """Every box of every topic read."""
        return [
            b
            for frames in (self.detections, self.tracks, self.ground_truth)
            if frames is not None
            for boxes in frames.values()
            for b in boxes
        ]


def _get(o: Any, name: str, default: Any = None) -> Any:
    """Field `name` of a decoded protobuf or ROS 2 message, or of a JSON object."""
    if isinstance(o, dict):
        return o.get(name, default)
    return getattr(o, name, default)


def _num(o: Any, name: str) -> float:
    v = _get(o, name)
    return 0.0 if v is None else float(v)


def _vec(v: Any) -> tuple[float, float, float]:
    return (_num(v, "x"), _num(v, "y"), _num(v, "z")) if v is not None else (0.0, 0.0, 0.0)


def _probmot_box(m: Any, with_id: bool) -> Box:
    """A probmot Detection3D or Track3D (protobuf or JSON)."""
    size = _get(m, "size")
    return Box(
        id=int(_get(m, "id", 0) or 0) if with_id else 0,
        label=_get(m, "label", "") or "",
        center=_vec(_get(m, "center")),
        size=(_num(size, "length"), _num(size, "width"), _num(size, "height"))
        if size is not None
        else (0.0, 0.0, 0.0),
        yaw=_num(m, "yaw"),
        score=_num(m, "score"),
        velocity=_vec(_get(m, "velocity")),
    )


def _yaw(q: Any) -> float:
    """The rotation about +z of a quaternion (x, y, z, w)."""
    x, y, z, w = (float(q.x), float(q.y), float(q.z), float(q.w))
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _int_or_zero(text: Any) -> int:
    try:
        return int(str(text))
    except ValueError:
        return 0


def _ros2_box(d: Any) -> Box:
    """A vision_msgs Detection3D (4.x: hypothesis.class_id; 2.x: id), best hypothesis."""
    best: tuple[str, float] | None = None
    for r in d.results:
        h = getattr(r, "hypothesis", r)
        label = h.class_id if hasattr(h, "class_id") else h.id
        if best is None or float(h.score) > best[1]:
            best = (label, float(h.score))
    if best is None:
        best = ("", 0.0)
    if hasattr(d, "id"):
        track_id = _int_or_zero(d.id)
    else:
        track_id = _int_or_zero(d.tracking_id) if d.is_tracking else 0
    c = d.bbox.center
    return Box(
        id=track_id,
        label=best[0],
        center=_vec(c.position),
        size=_vec(d.bbox.size),
        yaw=_yaw(c.orientation),
        score=best[1],
        velocity=None,
    )


def _scene_boxes(u: Any) -> list[Box]:
    """The cubes of a foxglove.SceneUpdate, labelled by their entity's metadata."""
    out = []
    for e in u.entities:
        meta = {kv.key: kv.value for kv in e.metadata}
        label = meta.get("label", meta.get("class", meta.get("class_id", "")))
        try:
            score = float(meta.get("score", "1"))
        except ValueError:
            score = 1.0
        for c in e.cubes:
            out.append(
                Box(
                    id=_int_or_zero(meta.get("track_id", "0")),
                    label=label,
                    center=_vec(c.pose.position),
                    size=_vec(c.size),
                    yaw=_yaw(c.pose.orientation),
                    score=score,
                    velocity=None,
                )
            )
    return out


def boxes_of(schema: str, decoded: Any) -> list[Box]:
    """The boxes of one decoded message of a schema in SCHEMAS."""
    if schema == DETECTIONS_SCHEMA:
        return [_probmot_box(m, False) for m in _get(decoded, "detections", []) or []]
    if schema == TRACKS_SCHEMA:
        return [_probmot_box(m, True) for m in _get(decoded, "tracks", []) or []]
    if schema == ROS2_SCHEMA:
        return [_ros2_box(d) for d in decoded.detections]
    return _scene_boxes(decoded)


class _Decoders:
    """Per channel, a function from message bytes to the decoded message."""

    def __init__(self) -> None:
        self.factories = [DecoderFactory(), Ros2DecoderFactory()]
        self.by_channel: dict[int, Any] = {}

    def decode(self, schema: Any, channel: Any, data: bytes) -> Any:
        fn = self.by_channel.get(channel.id)
        if fn is None:
            if channel.message_encoding == "json":
                fn = json.loads
            else:
                for f in self.factories:
                    fn = f.decoder_for(channel.message_encoding, schema)
                    if fn is not None:
                        break
            if fn is None:
                raise UsageError(
                    f"topic {channel.topic!r}: no decoder for message encoding "
                    f"{channel.message_encoding!r}"
                )
            self.by_channel[channel.id] = fn
        return fn(data)


def read_run(
    path: str,
    detections_topic: str = "/detections",
    tracks_topic: str = "/tracks",
    truth_topic: str = "/ground_truth",
    require_tracks: bool = True,
    classes: Sequence[str] = (),
) -> Run:
    """Decode the detections, tracks and ground-truth topics of `path` (each optional, except the
    tracks when `require_tracks`). Boxes of other classes than `classes` (if given) are dropped.
    Raises UsageError on an unreadable file, a wrong schema or a missing tracks topic."""
    roles = {
        detections_topic: "detections",
        tracks_topic: "tracks",
        truth_topic: "ground_truth",
    }
    run = Run(path=path)
    try:
        f = open(path, "rb")
    except OSError as e:
        raise UsageError(f"cannot open {path}: {e.strerror}") from e
    with f:
        try:
            reader = make_reader(f)
            decoders = _Decoders()
            summary = reader.get_summary()
            if summary is not None:
                run.topics = sorted({c.topic for c in summary.channels.values()})
            for schema, channel, message in reader.iter_messages(
                topics=list(roles), log_time_order=True
            ):
                role = roles[channel.topic]
                name = schema.name if schema is not None else "(no schema)"
                if name not in SCHEMAS:
                    raise UsageError(
                        f"{path}: topic {channel.topic!r} has schema {name!r}, not one of "
                        f"{', '.join(SCHEMAS)}"
                    )
                try:
                    decoded = decoders.decode(schema, channel, message.data)
                    boxes = boxes_of(name, decoded)
                except UsageError as e:
                    raise UsageError(f"{path}: {e}") from e
                except Exception as e:  # noqa: BLE001 - any decoder error names the message
                    raise UsageError(
                        f"{path}: topic {channel.topic!r}, message at log_time "
                        f"{message.log_time}: cannot decode {name}: {type(e).__name__}: {e}"
                    ) from e
                boxes = [b for b in boxes if not classes or b.label in classes]
                frames = getattr(run, role)
                if frames is None:
                    frames = {}
                    setattr(run, role, frames)
                frames.setdefault(int(message.log_time), []).extend(boxes)
        except McapError as e:
            raise UsageError(f"cannot read {path}: {type(e).__name__}: {e}") from e
    if require_tracks and run.tracks is None:
        raise UsageError(
            f"{path} has no messages on topic {tracks_topic!r} "
            f"(topics: {', '.join(run.topics) or 'none'}); run `probmot track` on it first"
        )
    if not run.log_times():
        raise UsageError(f"{path} has no messages on {', '.join(roles)}")
    return run


def _boxes3d(
    boxes: list[Box], colors: Any, labels: list[str], radius: float, show_labels: bool
) -> rr.Boxes3D:
    n = len(boxes)
    return rr.Boxes3D(
        centers=np.array([b.center for b in boxes], dtype=np.float32).reshape(n, 3),
        half_sizes=np.array([b.size for b in boxes], dtype=np.float32).reshape(n, 3) / 2.0,
        rotation_axis_angles=[
            rr.RotationAxisAngle(axis=(0.0, 0.0, 1.0), radians=b.yaw) for b in boxes
        ],
        colors=colors,
        labels=labels,
        show_labels=show_labels,
        radii=radius,
        fill_mode="majorwireframe",
    )


def _finite(b: Box) -> bool:
    return all(math.isfinite(v) for v in (*b.center, *b.size, b.yaw))


# Line radii are negative: Rerun reads them as UI points, so lines stay visible at any zoom.
def log_run(
    rec: rr.RecordingStream,
    run: Run,
    frame_of: dict[int, int],
    prefix: str = "world",
    trail: int = 20,
) -> None:
    """Log one run's entities under `prefix`, a row per frame on the `log_time` and `frame`
    timelines (frame indices from `frame_of`, log time -> index)."""
    # Track positions so far, per id, for the trails.
    history: dict[int, list[tuple[float, float, float]]] = {}
    for t in sorted(run.log_times()):
        rec.set_time("frame", sequence=frame_of[t])
        rec.set_time("log_time", timestamp=np.datetime64(t, "ns"))
        if run.detections is not None and t in run.detections:
            dets = [b for b in run.detections[t] if _finite(b)]
            rec.log(
                f"{prefix}/detections",
                _boxes3d(
                    dets,
                    [DETECTION_GREY] * len(dets),
                    [f"{b.label} {b.score:.2f}" for b in dets],
                    -0.5,
                    False,
                ),
            )
        if run.ground_truth is not None and t in run.ground_truth:
            gt = [b for b in run.ground_truth[t] if _finite(b)]
            rec.log(
                f"{prefix}/ground_truth",
                _boxes3d(
                    gt, [TRUTH_GREEN] * len(gt), [f"gt {b.id}" for b in gt], -0.75, False
                ),
            )
        if run.tracks is not None and t in run.tracks:
            tracks = [b for b in run.tracks[t] if _finite(b)]
            colors = [id_color(b.id) for b in tracks]
            rec.log(
                f"{prefix}/tracks",
                _boxes3d(tracks, colors, [f"{b.label} {b.id}" for b in tracks], -1.5, True),
            )
            strips = []
            strip_colors = []
            for b in tracks:
                h = history.setdefault(b.id, [])
                h.append(b.center)
                del h[:-trail]
                strips.append(np.array(h, dtype=np.float32).reshape(len(h), 3))
                strip_colors.append(id_color(b.id))
            rec.log(
                f"{prefix}/trails", rr.LineStrips3D(strips, colors=strip_colors, radii=-1.0)
            )
            moving = [b for b in tracks if b.velocity is not None]
            n = len(moving)
            rec.log(
                f"{prefix}/velocity",
                rr.Arrows3D(
                    origins=np.array([b.center for b in moving], dtype=np.float32).reshape(n, 3),
                    vectors=np.array([b.velocity for b in moving], dtype=np.float32).reshape(
                        n, 3
                    ),
                    colors=[id_color(b.id) for b in moving],
                    radii=-1.0,
                ),
            )


def frame_index(runs: Sequence[Run]) -> dict[int, int]:
    """Index of every distinct log time of the runs, in time order."""
    times: set[int] = set()
    for r in runs:
        times |= r.log_times()
    return {t: i for i, t in enumerate(sorted(times))}


def top_down_view(
    runs: Sequence[Run], origin: str, name: str, height_factor: float = 0.55
) -> rrb.Spatial3DView:
    """A 3D view of `origin` looking straight down (+y up on screen) at the runs' boxes, from
    `height_factor` times the boxes' extent above them (larger for narrower views)."""
    pts = [b.center for r in runs for b in r.all_boxes() if _finite(b)]
    if pts:
        xs = [p[0] for p in pts]
        ys = [p[1] for p in pts]
        cx, cy = (min(xs) + max(xs)) / 2.0, (min(ys) + max(ys)) / 2.0
        extent = max(max(xs) - min(xs), max(ys) - min(ys), 20.0)
    else:
        cx, cy, extent = 0.0, 0.0, 50.0
    height = height_factor * extent
    return rrb.Spatial3DView(
        origin=origin,
        name=name,
        # Light, like `probmot plot` pictures: the id palette is chosen for a light background.
        background=rrb.Background(kind=rrb.BackgroundKind.SolidColor, color=(0xF4, 0xF4, 0xF4)),
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(cx, cy - 0.001 * extent, height),
            look_target=(cx, cy, 0.0),
            eye_up=(0.0, 1.0, 0.0),
        ),
    )


def new_recording(recording_id: str | None) -> rr.RecordingStream:
    """A recording stream with only our two timelines (no wall-clock log time, no log tick)."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    return rec


def save_atomically(
    out: str, blueprint: rrb.Blueprint, recording_id: str | None, log: Any
) -> None:
    """Log everything with `log(rec)` into a temporary .rrd beside `out`, then rename it over
    `out`: a failure leaves no partial output."""
    out_dir = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(out_dir):
        raise UsageError(f"output directory {out_dir} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=".probmot-", suffix=".rrd", dir=out_dir)
    os.close(fd)
    try:
        rec = new_recording(recording_id)
        rec.save(tmp)
        # Active on load, not only the default: the eye is placed for this file's boxes, so a
        # layout the viewer kept from another recording of the application would look elsewhere.
        rec.send_blueprint(blueprint, make_active=True, make_default=True)
        log(rec)
        rec.flush()
        rec.disconnect()
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# Same as src/msgs/eval_events.rs (kind_rgb, kind_name), indexed by EvalEvent.Kind.
EVENT_KINDS = {
    0: ("match", (40, 170, 70)),
    1: ("id switch", (220, 0, 220)),
    2: ("fragmentation", (255, 140, 0)),
    3: ("false positive", (220, 30, 30)),
    4: ("miss", (30, 90, 230)),
}


def log_events(
    rec: rr.RecordingStream,
    path: str,
    frame_of: dict[int, int],
    topic: str = "/eval/events",
    prefix: str = "world",
) -> int:
    """Log the evaluation's errors of `topic` (probmot.EvalEvents, written by `probmot eval
    --events`) when the file has it: `{prefix}/events` boxes per frame, and a `events` text log
    entry (level WARN) per identity switch and fragmentation. Returns the number of entries."""
    entries = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, _, message, ev in reader.iter_decoded_messages(topics=[topic]):
            t = message.log_time
            if t in frame_of:
                rec.set_time("frame", sequence=frame_of[t])
            rec.set_time("log_time", timestamp=np.datetime64(t, "ns"))
            errors = [e for e in ev.events if e.kind != 0]
            rec.log(
                f"{prefix}/events",
                rr.Boxes3D(
                    centers=[(e.center.x, e.center.y, e.center.z) for e in errors],
                    half_sizes=[
                        (e.size.length / 2 + 0.2, e.size.width / 2 + 0.2, e.size.height / 2 + 0.2)
                        for e in errors
                    ],
                    rotation_axis_angles=[
                        rr.RotationAxisAngle(axis=(0.0, 0.0, 1.0), radians=e.yaw) for e in errors
                    ],
                    colors=[EVENT_KINDS[e.kind][1] for e in errors],
                    labels=[f"{EVENT_KINDS[e.kind][0]} gt {e.truth_id}" for e in errors],
                    radii=-2.0,
                ),
            )
            for e in errors:
                if e.kind in (1, 2):
                    what = "trk {}->{}".format(e.previous_track_id, e.track_id)
                    if e.kind == 2:
                        what = f"lost trk {e.previous_track_id}"
                    text = f"{EVENT_KINDS[e.kind][0]} {e.label} gt {e.truth_id} {what}"
                    rec.log("events", rr.TextLog(text, level="WARN"))
                    entries += 1
    return entries


def add_common_args(parser: argparse.ArgumentParser) -> None:
    """Options shared with compare_runs.py."""
    parser.add_argument("-o", "--output", required=True, metavar="OUT.rrd", help="output file")
    parser.add_argument(
        "--trail",
        type=int,
        default=20,
        metavar="N",
        help="positions per track in world/trails (default: 20)",
    )
    parser.add_argument(
        "--class",
        dest="classes",
        action="append",
        default=[],
        metavar="CLASS",
        help="only boxes of this class (repeatable; default: every class)",
    )
    parser.add_argument("--detections-topic", default="/detections", metavar="TOPIC")
    parser.add_argument("--tracks-topic", default="/tracks", metavar="TOPIC")
    parser.add_argument("--truth-topic", default="/ground_truth", metavar="TOPIC")
    parser.add_argument(
        "--recording-id", default=None, help="Rerun recording id (default: a random one)"
    )


def main(argv: list[str] | None = None) -> int:
    prog = "to_rerun.py"
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Convert a tracked MCAP file (probmot track output) to a Rerun .rrd "
        "recording: detections, tracks, ground truth, trails and velocity arrows on `log_time` "
        "and `frame` timelines, with a top-down view.",
    )
    parser.add_argument("file", metavar="TRACKED.mcap", help="MCAP file written by `probmot track`")
    add_common_args(parser)
    args = parser.parse_args(argv)
    if args.trail < 1:
        fail(prog, "--trail must be at least 1")
    try:
        run = read_run(
            args.file,
            args.detections_topic,
            args.tracks_topic,
            args.truth_topic,
            classes=args.classes,
        )
        frame_of = frame_index([run])
        name = os.path.basename(args.file)
        blueprint = rrb.Blueprint(top_down_view([run], "world", f"{name} (top-down)"))

        def log(rec: rr.RecordingStream) -> None:
            rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            log_run(rec, run, frame_of, "world", args.trail)
            log_events(rec, args.file, frame_of)

        save_atomically(args.output, blueprint, args.recording_id, log)
    except UsageError as e:
        fail(prog, str(e))
    n_tracks = len({b.id for boxes in (run.tracks or {}).values() for b in boxes})
    print(
        f"{args.output}: {len(frame_of)} frames, {n_tracks} track ids"
        + ("" if run.ground_truth is None else ", ground truth")
        + ("" if run.detections is None else ", detections")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
