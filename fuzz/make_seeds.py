#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets into fuzz/corpus/ (not committed).

read_path:        the sample logs of at most 64 KiB, plus small MCAP files made here (unchunked, lz4 chunks, a JSON
                  detections channel, stamps out of order, attachments and metadata) and by
                  scripts/make_autoware_bag.py (Autoware detections and /tf).
decode_protobuf:  /detections payloads of the sample logs, and a few hand-made messages (with the
                  absurd values of issue #36: huge centres and sizes, NaN velocities, a label
                  that is not UTF-8; read_path gets a log with a u64::MAX stamp and a shared one).
decode_json:      the same messages in probmot's JSON form (serde, proto field names).
decode_sources:   a selector byte (0: vision_msgs 4.x, 1: vision_msgs 2.x, 2: foxglove.SceneUpdate,
                  3: Autoware autoware_perception_msgs DetectedObjects, 4: the same of
                  autoware_auto_perception_msgs) and a message of the ROS 2 and Foxglove test
                  fixtures, or of a bag made by scripts/make_autoware_bag.py (both packages).
bag_metadata:     metadata.yaml files of bags of scripts/make_autoware_bag.py and hand-made ones.
frame_reader:     runs of the decode_protobuf messages, each a little-endian u16 length and the
                  message, in the framing of probmot_fuzz::frame_reader::read_frames.
transforms:       the transform messages of tests/fixtures/ros2_tf/tf.mcap and two Foxglove frame
                  transform messages made here, in the framing of probmot_fuzz::read_transforms.

Needs the Python packages of scripts/requirements.txt (mcap, protobuf, foxglove-schemas-protobuf,
lz4, zstandard, rosbags, numpy).
Run from anywhere: python3 fuzz/make_seeds.py
"""

import hashlib
import io
import json
import pathlib
import shutil
import subprocess
import sys
import tempfile

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

ROOT = pathlib.Path(__file__).resolve().parent.parent
CORPUS = ROOT / "fuzz" / "corpus"
SAMPLES = sorted((ROOT / "sample_logs").glob("*.mcap"))
FIXTURES = ROOT / "tests" / "fixtures"
TARGETS = ("read_path", "decode_protobuf", "decode_json", "decode_sources", "transforms",
           "frame_reader", "bag_metadata")
# Channel numbers of probmot_fuzz::read_transforms (TRANSFORM_CHANNELS), by topic.
TRANSFORM_CHANNEL = {"/tf": 0, "/tf_static": 1, "/odom": 2, "/frame": 3, "/frames": 4}


def put(target: str, data: bytes) -> None:
    d = CORPUS / target
    d.mkdir(parents=True, exist_ok=True)
    (d / hashlib.sha1(data).hexdigest()).write_bytes(data)


def load_types():
    """Detections3D class from the FileDescriptorSet in a sample log's schema record."""
    with open(SAMPLES[0], "rb") as f:
        summary = make_reader(f).get_summary()
    schema = next(s for s in summary.schemas.values() if s.name == "probmot.Detections3D")
    fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName("probmot.Detections3D"))
    return schema.data, cls


def to_json(msg) -> bytes:
    """probmot's JSON form (serde of the prost types: proto field names, numbers as numbers)."""
    def v(m, names):
        return {n: getattr(m, n) for n in names}

    out = {"frame_id": msg.frame_id, "detections": []}
    if msg.HasField("stamp"):
        out["stamp"] = msg.stamp
    for d in msg.detections:
        j = {"yaw": d.yaw, "label": d.label, "score": d.score, "attributes": dict(d.attributes)}
        if d.HasField("center"):
            j["center"] = v(d.center, "xyz")
        if d.HasField("size"):
            j["size"] = v(d.size, ["length", "width", "height"])
        if d.HasField("velocity"):
            j["velocity"] = v(d.velocity, "xyz")
        if d.HasField("image_box"):
            j["image_box"] = v(d.image_box, ["x1", "y1", "x2", "y2"])
        out["detections"].append(j)
    return json.dumps(out).encode()


def small_mcap(descriptor: bytes, payloads, encoding="protobuf", compression=None,
               chunked=True, extras=False) -> bytes:
    buf = io.BytesIO()
    w = Writer(buf, compression=compression or CompressionType.NONE, use_chunking=chunked,
               chunk_size=512)
    w.start(profile="", library="probmot-fuzz-seeds")
    if encoding == "json":
        sid = w.register_schema("probmot.Detections3D", "jsonschema", b"{}")
    else:
        sid = w.register_schema("probmot.Detections3D", "protobuf", descriptor)
    ch = w.register_channel("/detections", encoding, sid)
    for seq, (log_time, data) in enumerate(payloads):
        w.add_message(ch, log_time=log_time, data=data, publish_time=log_time, sequence=seq)
    if extras:
        w.add_attachment(create_time=1, log_time=1, name="a.txt", media_type="text/plain",
                         data=b"hello")
        w.add_metadata("meta", {"k": "v"})
    w.finish()
    return buf.getvalue()


def framed(channel: str, log_time_tenths: int, data: bytes) -> bytes:
    """One message in the framing of probmot_fuzz::read_transforms."""
    return (bytes([TRANSFORM_CHANNEL[channel], log_time_tenths % 256])
            + len(data).to_bytes(2, "little") + data)


def merged_mcap(sources) -> bytes:
    """An MCAP with the first messages of each (path, count) in `sources`, schemas and channels
    copied, zstd chunks."""
    buf = io.BytesIO()
    w = Writer(buf, compression=CompressionType.ZSTD, chunk_size=4096)
    w.start(profile="", library="probmot-fuzz-seeds")
    for path, count in sources:
        with open(path, "rb") as f:
            ids = {}
            for i, (schema, channel, message) in enumerate(make_reader(f).iter_messages()):
                if i >= count:
                    break
                if channel.id not in ids:
                    sid = w.register_schema(schema.name, schema.encoding, schema.data)
                    ids[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                         sid)
                w.add_message(ids[channel.id], log_time=message.log_time, data=message.data,
                              publish_time=message.publish_time, sequence=message.sequence)
    w.finish()
    return buf.getvalue()


def source_and_transform_seeds() -> None:
    # Whole-pipeline seeds of the other input kinds: ROS 2 detections with ROS 2 transforms,
    # Foxglove detections.
    put("read_path", merged_mcap([(FIXTURES / "ros2" / "turning-car-vision_msgs2.mcap", 8),
                                  (FIXTURES / "ros2_tf" / "tf.mcap", 6)]))
    put("read_path", merged_mcap([(FIXTURES / "foxglove" / "city.mcap", 3)]))

    for selector, path in ((0, "ros2/city.mcap"), (1, "ros2/turning-car-vision_msgs2.mcap"),
                           (2, "foxglove/city.mcap")):
        with open(FIXTURES / path, "rb") as f:
            for i, (_, _, message) in enumerate(make_reader(f).iter_messages()):
                if i in (0, 1, 20):
                    put("decode_sources", bytes([selector]) + message.data)

    autoware_seeds()

    tf = b""
    with open(FIXTURES / "ros2_tf" / "tf.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            tf += framed(channel.topic, message.log_time // 100_000_000, message.data)
    put("transforms", tf)

    def frame_transform(sec: int, parent: str, child: str, x: float, yaw_w: float):
        t = FrameTransform(parent_frame_id=parent, child_frame_id=child)
        t.timestamp.seconds = sec
        t.translation.x, t.translation.y = x, 1.0
        t.rotation.z, t.rotation.w = (1 - yaw_w * yaw_w) ** 0.5, yaw_w
        return t

    one = frame_transform(1, "map", "base_link", 2.0, 1.0)
    many = FrameTransforms(transforms=[frame_transform(2, "map", "base_link", 3.0, 0.8),
                                       frame_transform(0, "base_link", "lidar", 1.2, 1.0)])
    put("transforms", tf + framed("/frame", 10, one.SerializeToString())
        + framed("/frames", 20, many.SerializeToString()))


def autoware_seeds() -> None:
    """decode_sources seeds of selectors 3 and 4: messages 0, 1 and 20 of a 30-frame bag of
    scripts/make_autoware_bag.py (six objects, the UNKNOWN one among them) in each package;
    read_path: an 8-frame bag of it; bag_metadata seeds: the metadata.yaml of those bags
    (rosbags' writer) and hand-made ones (a split bag in flow and block style, quoted names,
    zstd and message compression)."""
    for text in (
        "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n"
        "  relative_file_paths: [drive_0.mcap, 'drive_1.mcap', \"drive_2.mcap\"]\n"
        "  compression_format: ''\n  compression_mode: ''\n",
        "rosbag2_bagfile_information:\n    storage_identifier: mcap  # comment\n"
        "    relative_file_paths:\n    - d_0.mcap.zstd\n    - \"d_\\u0031.mcap.zstd\"\n"
        "    compression_format: zstd\n    compression_mode: FILE\n"
        "    topics_with_message_count:\n      - topic_metadata:\n          name: /tf\n",
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n"
        "  relative_file_paths:\n  - 'it''s.db3'\n  compression_mode: message\n",
    ):
        put("bag_metadata", text.encode())
    for selector, flags in ((3, []), (4, ["--auto", "--ego"])):
        with tempfile.TemporaryDirectory() as d:
            bag = pathlib.Path(d) / "bag"
            subprocess.run([sys.executable, str(ROOT / "scripts" / "make_autoware_bag.py"),
                            str(bag), "--frames", "30", *flags], check=True,
                           stdout=subprocess.DEVNULL)
            put("bag_metadata", (bag / "metadata.yaml").read_bytes())
            for path in bag.glob("*.mcap"):
                with open(path, "rb") as f:
                    messages = make_reader(f).iter_messages(
                        topics=["/perception/object_recognition/detection/objects"])
                    for i, (_, _, message) in enumerate(messages):
                        if i in (0, 1, 20):
                            put("decode_sources", bytes([selector]) + message.data)
    # read_path: an 8-frame Autoware bag's MCAP file with the ego pose on /tf (~40 KB).
    with tempfile.TemporaryDirectory() as d:
        bag = pathlib.Path(d) / "bag"
        subprocess.run([sys.executable, str(ROOT / "scripts" / "make_autoware_bag.py"), str(bag),
                        "--frames", "8", "--ego"], check=True, stdout=subprocess.DEVNULL)
        for path in bag.glob("*.mcap"):
            put("read_path", path.read_bytes())


def frame_reader_seeds(Detections3D, messages) -> None:
    """Runs of `messages` (protobuf payloads) for one FrameReader, and a run whose boxes keep,
    change, add and drop attributes and labels from one message to the next."""
    def run(payloads) -> bytes:
        return b"".join(len(p).to_bytes(2, "little") + p for p in payloads)

    for i in range(0, len(messages), 3):
        put("frame_reader", run(messages[i:i + 4]))
    put("frame_reader", run(list(reversed(messages))[:8]))
    runs = []
    for attrs, label in (({"id": "7"}, "car"), ({"id": "8"}, "truck"),
                         ({"id": "9", "sim_truth_id": "3"}, "car"), ({}, "pedestrian")):
        m = Detections3D(stamp=len(runs) + 1, frame_id="lidar" if attrs else "")
        for k in range(2):
            d = m.detections.add(label=label, score=0.5)
            d.center.x, d.size.length, d.size.width, d.size.height = k, 4.5, 1.9, 1.6
            d.attributes.update(attrs)
        runs.append(m.SerializeToString())
    put("frame_reader", run(runs))


def hostile_value_seeds(Detections3D, hand) -> list:
    """The values of issue #36: a centre at 1e308 m, a 20 km box, NaN and 1e6 m/s velocities
    (appended to `hand`), a label that is not UTF-8 (a protobuf payload, put here), and the
    `(log_time, payload)` list of a log with a stamp of u64::MAX and two messages sharing a stamp."""
    m = Detections3D(stamp=2_000_000_000, frame_id="map")
    for x, length, vel in [(1e308, 4.5, None), (1.0, 2e4, None), (2.0, 4.5, float("nan")),
                           (3.0, 4.5, 1e6)]:
        d = m.detections.add(label="car", score=0.9)
        d.center.x, d.size.length, d.size.width, d.size.height = x, length, 1.9, 1.6
        if vel is not None:
            d.velocity.x = vel
    hand.append(m)
    m = Detections3D(stamp=2_500_000_000, frame_id="map")
    for label in ("car", "QQQQ"):
        d = m.detections.add(label=label, score=0.9)
        d.center.x = 1.0
        d.size.length, d.size.width, d.size.height = 4.5, 1.9, 1.6
    bad = m.SerializeToString().replace(b"QQQQ", b"\xc3\x28\xff\x72")
    put("decode_protobuf", bad)
    log = []
    for i, stamp in enumerate([3, 4, 2**64 - 1, 5, 5, 6]):
        msg = Detections3D(stamp=stamp * 500_000_000 if stamp < 2**63 else stamp)
        d = msg.detections.add(label="car", score=0.9)
        d.center.x, d.size.length, d.size.width, d.size.height = float(i), 4.5, 1.9, 1.6
        log.append(((3 + i) * 500_000_000, msg.SerializeToString()))
    log.append((9 * 500_000_000, bad))
    return log


def main() -> None:
    if CORPUS.exists():
        for t in TARGETS:
            shutil.rmtree(CORPUS / t, ignore_errors=True)
    descriptor, Detections3D = load_types()

    samples = []
    for path in SAMPLES:
        if path.stat().st_size <= 64 * 1024:  # small logs only: big inputs slow every run
            put("read_path", path.read_bytes())
        with open(path, "rb") as f:
            for _, channel, message in make_reader(f).iter_messages(topics=["/detections"]):
                samples.append((message.log_time, message.data))

    # A few payloads from each log: first, middle, last.
    picked = []
    per_log = len(samples) // len(SAMPLES)
    for i in range(len(SAMPLES)):
        for j in (0, per_log // 2, per_log - 1):
            picked.append(samples[i * per_log + j])

    hand = []
    m = Detections3D()
    hand.append(m)  # empty message
    m = Detections3D(stamp=1_000_000_000, frame_id="map")
    d = m.detections.add(label="car", score=0.9, yaw=0.3)
    d.center.x, d.center.y, d.center.z = 1.0, 2.0, 0.5
    d.size.length, d.size.width, d.size.height = 4.5, 1.9, 1.6
    d.attributes["id"] = "7"
    d = m.detections.add(label="pedestrian", score=1.5, yaw=-3.0)  # score outside [0, 1]
    d.center.x, d.center.y = -3.0, 4.0
    d.size.length, d.size.width, d.size.height = 0.7, 0.7, 1.8
    d.image_box.x1, d.image_box.y1, d.image_box.x2, d.image_box.y2 = 1, 2, 30, 40
    d = m.detections.add(label="truck")  # missing size
    d.center.x = 5.0
    d = m.detections.add(label="unknown-label", score=0.2)
    d.center.x = 9.0
    d.size.length, d.size.width, d.size.height = 1.0, 0.0, 1.0  # non-positive size
    hand.append(m)

    hostile = hostile_value_seeds(Detections3D, hand)

    for _, data in picked:
        put("decode_protobuf", data)
        put("decode_json", to_json(Detections3D.FromString(data)))
    for msg in hand:
        put("decode_protobuf", msg.SerializeToString())
        put("decode_json", to_json(msg))

    pb = [(i * 500_000_000, msg.SerializeToString()) for i, msg in enumerate(hand)]
    pb += picked[:1]
    js = [(t, to_json(Detections3D.FromString(d))) for t, d in picked[:2]]
    put("read_path", small_mcap(descriptor, pb, chunked=False))
    put("read_path", small_mcap(descriptor, pb, compression=CompressionType.LZ4, extras=True))
    put("read_path", small_mcap(descriptor, list(reversed(pb)), compression=CompressionType.ZSTD))
    put("read_path", small_mcap(descriptor, js, encoding="json"))
    put("read_path", small_mcap(descriptor, hostile, chunked=False))
    source_and_transform_seeds()
    frame_reader_seeds(Detections3D, [d for _, d in picked]
                       + [m.SerializeToString() for m in hand] + [hostile[-1][1]])
    for t in TARGETS:
        files = list((CORPUS / t).iterdir())
        print(f"{t}: {len(files)} seeds, {sum(f.stat().st_size for f in files)} bytes")


if __name__ == "__main__":
    main()
