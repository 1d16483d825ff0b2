//! `track`'s output is in log-time order when its input is: each frame's tracks (and their
//! SceneUpdate) come before every later input message, at the latest log time of the frame's
//! detection messages; the input messages keep their order and bytes. And the SceneUpdate
//! channel is there by default, on `--scene-topic`, or not at all with `--no-scene` or ROS 2
//! tracks.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::*;
use probmot::msgs::{self, v3, Detection3D, Detections3D, Size3};

const MS: u64 = 1_000_000;

/// A car driving along x, detected every 100 ms; each detection message is logged 30 ms after
/// its stamp (the detector's latency), between camera messages logged every 25 ms, and the
/// messages are written in log-time order. Returns the detection stamps.
fn write_latency_log(path: &Path) -> Vec<u64> {
    let file = std::fs::File::create(path).unwrap();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(file)).unwrap();
    let s = w
        .add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)
        .unwrap();
    let det = w
        .add_channel(s, "/detections", "protobuf", &BTreeMap::new())
        .unwrap();
    let camera = w
        .add_channel(0, "/camera", "raw", &BTreeMap::new())
        .unwrap();
    let t0 = 1_000 * 1_000 * MS;
    let mut records: Vec<(u64, u16, Vec<u8>)> = Vec::new();
    let mut stamps = Vec::new();
    for k in 0..30u64 {
        let stamp = t0 + k * 100 * MS;
        stamps.push(stamp);
        let m = Detections3D {
            stamp: Some(stamp),
            frame_id: "map".into(),
            detections: vec![Detection3D {
                center: Some(v3([k as f64, 0.0, 0.0])),
                size: Some(Size3 {
                    length: 4.0,
                    width: 2.0,
                    height: 1.5,
                }),
                label: "car".into(),
                score: 0.9,
                ..Default::default()
            }],
        };
        records.push((stamp + 30 * MS, det, prost::Message::encode_to_vec(&m)));
    }
    for k in 0..130u64 {
        records.push((t0 + k * 25 * MS, camera, format!("image {k}").into_bytes()));
    }
    records.sort_by_key(|r| (r.0, r.1));
    for (i, (log_time, channel_id, data)) in records.iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: *channel_id,
            sequence: i as u32,
            log_time: *log_time,
            publish_time: *log_time,
        };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
    stamps
}

fn log_times(msgs: &[Msg]) -> Vec<u64> {
    msgs.iter().map(|m| m.log_time).collect()
}

/// The output's messages are in log-time order, the input's keep their order, and the tracks
/// and scene of each frame are at its detection message's log time.
fn assert_ordered(input: &Path, output: &Path, name: &str) {
    let before = messages(input);
    let after = messages(output);
    let times = log_times(&after);
    let back = times.windows(2).filter(|w| w[1] < w[0]).count();
    assert_eq!(back, 0, "{name}: {back} messages before an earlier one");
    let ours = |m: &&Msg| m.topic == "/tracks" || m.topic == "/tracks/scene";
    let copied: Vec<Msg> = after.iter().filter(|m| !ours(m)).cloned().collect();
    assert_eq!(
        copied, before,
        "{name}: input messages changed or reordered"
    );
    let det: Vec<u64> = before
        .iter()
        .filter(|m| m.topic == "/detections")
        .map(|m| m.log_time)
        .collect();
    for topic in ["/tracks", "/tracks/scene"] {
        let t: Vec<Msg> = after.iter().filter(|m| m.topic == topic).cloned().collect();
        assert_eq!(log_times(&t), det, "{name}: log times of {topic}");
    }
}

#[test]
fn tracks_come_before_every_later_message() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("latency.mcap");
    let stamps = write_latency_log(&input);
    let output = dir.path().join("latency.tracked.mcap");
    // Read once: the summary section plans the pass, and a frame is complete only when the
    // next detection message arrives, so the camera messages between them wait.
    let out = probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["passes"], 1);
    assert_ordered(&input, &output, "latency log");
    // The stamp in the message stays the detection stamp.
    let got: Vec<u64> = tracks(&output, "/tracks").iter().map(|f| f.stamp).collect();
    assert_eq!(got, stamps);

    // Two passes: an ego-frame simulation with /tf.
    let ego = dir.path().join("ego.mcap");
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "20",
        "--ego-frame",
        "-o",
        ego.to_str().unwrap(),
    ]);
    let ego_out = dir.path().join("ego.tracked.mcap");
    let out = probmot_ok(&[
        "track",
        ego.to_str().unwrap(),
        "-o",
        ego_out.to_str().unwrap(),
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["passes"], 2);
    assert_ordered(&ego, &ego_out, "ego-frame simulation");
}

fn topics(path: &Path) -> Vec<String> {
    let mut t: Vec<String> = messages(path).into_iter().map(|m| m.topic).collect();
    t.sort();
    t.dedup();
    t
}

#[test]
fn the_scene_channel_is_on_by_default_and_can_be_moved_or_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/turning-car.mcap");
    let out = dir.path().join("out.mcap");
    let run = |extra: &[&str]| {
        let mut args = vec!["track", "-q", input.to_str().unwrap()];
        args.extend(["-o", out.to_str().unwrap()]);
        args.extend(extra);
        probmot_ok(&args);
        topics(&out)
    };
    let base = ["/detections", "/ground_truth", "/tracks"];
    assert_eq!(run(&[]), [&base[..], &["/tracks/scene"]].concat());
    assert_eq!(run(&["--no-scene"]), base);
    assert_eq!(
        run(&["--scene-topic", "/viz"]),
        [&base[..], &["/viz"]].concat()
    );
    // The default follows --tracks-topic.
    assert_eq!(
        run(&["--tracks-topic", "/t"]),
        ["/detections", "/ground_truth", "/t", "/t/scene"]
    );
    let both = probmot(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--no-scene",
        "--scene-topic",
        "/viz",
    ]);
    assert_eq!(both.status.code(), Some(2), "--no-scene with --scene-topic");
}

#[test]
fn ros2_tracks_get_no_scene_unless_asked_and_asking_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("tests/fixtures/ros2/city.mcap");
    let out = dir.path().join("out.mcap");
    let args = ["track", "-q", input.to_str().unwrap(), "-o"];
    probmot_ok(&[&args[..], &[out.to_str().unwrap()]].concat());
    assert_eq!(topics(&out), ["/detections", "/tracks"]);
    let refused = probmot(&[&args[..], &[out.to_str().unwrap(), "--scene-topic", "/s"]].concat());
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("--scene-topic"), "{err}");
    // Protobuf tracks asked for: the scene comes with them.
    probmot_ok(
        &[
            &args[..],
            &[out.to_str().unwrap(), "--tracks-format", "probmot"],
        ]
        .concat(),
    );
    assert_eq!(topics(&out), ["/detections", "/tracks", "/tracks/scene"]);
}

/// A frame's stamp and its tracks' ids and positions (micrometres).
type ShownFrame = (u64, Vec<(u64, [i64; 2])>);

/// The offline options (`--coast gaps --backfill`) hold frames back: the output keeps its
/// order and every input message, has one tracks message per frame, and shows exactly what
/// the library's tracker and lookback show (which differs from the online output here).
#[test]
fn offline_reporting_keeps_the_order_and_shows_what_the_library_shows() {
    use probmot::tracker::TrackerConfig;
    use probmot::tune::score::track_log;
    use probmot::tune::TuneLog;

    let dir = tempfile::tempdir().unwrap();
    let city = dir.path().join("city.mcap");
    let city = city.to_str().unwrap();
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "40",
        "-o",
        city,
    ]);
    let run = |name: &str, offline: bool| {
        let out = dir.path().join(name);
        let mut args = vec!["track", city, "-o", out.to_str().unwrap(), "--quiet"];
        if offline {
            args.extend(["--coast", "gaps", "--backfill"]);
        }
        probmot_ok(&args);
        out
    };
    let online = run("online.mcap", false);
    let offline = run("offline.mcap", true);
    assert_ordered(Path::new(city), &offline, "offline city");
    let shown = |frames: Vec<msgs::Tracks3D>| -> Vec<ShownFrame> {
        let at = |v: Option<msgs::Vector3>| {
            let v = v.unwrap();
            [(v.x * 1e6).round() as i64, (v.y * 1e6).round() as i64]
        };
        frames
            .into_iter()
            .map(|f| {
                (
                    f.stamp,
                    f.tracks.into_iter().map(|t| (t.id, at(t.center))).collect(),
                )
            })
            .collect()
    };
    let got = shown(tracks(&offline, "/tracks"));
    assert_eq!(got.len(), 40);
    assert_ne!(
        got,
        shown(tracks(&online, "/tracks")),
        "the options change this log"
    );

    let mut cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    cfg.for_each_class(|c| {
        c.levers.coast = probmot::tracker::levers::Coast::Gaps;
        c.levers.backfill = true;
    });
    let log = TuneLog::load(Path::new(city), "/ground_truth", "/detections").unwrap();
    let scene = track_log(&log, &cfg).unwrap();
    let want: Vec<ShownFrame> = scene
        .frames
        .iter()
        .map(|(stamp, _, tracks)| {
            let boxes = tracks.iter().map(|t| {
                let c = t.box3.center;
                (
                    t.id,
                    [(c[0] * 1e6).round() as i64, (c[1] * 1e6).round() as i64],
                )
            });
            (*stamp, boxes.collect())
        })
        .collect();
    assert_eq!(got, want);

    // The summary's mean track length is that of the written tracks (the tracker alone would
    // count coasted frames the lookback leaves out).
    let out = dir.path().join("json.mcap");
    let r = probmot_ok(&[
        "track",
        city,
        "-o",
        out.to_str().unwrap(),
        "--quiet",
        "--json",
        "--coast",
        "gaps",
        "--backfill",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let boxes: usize = got.iter().map(|(_, t)| t.len()).sum();
    let ids: std::collections::BTreeSet<u64> = got
        .iter()
        .flat_map(|(_, t)| t.iter().map(|x| x.0))
        .collect();
    let mean = v["mean_track_length"].as_f64().unwrap();
    assert!(
        (mean - boxes as f64 / ids.len() as f64).abs() < 1e-12,
        "{mean} {v}"
    );
}
