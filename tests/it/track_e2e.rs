//! End-to-end tests of `probmot track` on the sample logs.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::*;
use prost::Message as _;
use prost_reflect::{DescriptorPool, DynamicMessage, Value};

const SAMPLES: [&str; 3] = ["turning-car", "pedestrians", "city"];

/// The arguments each sample log was made with (also in sample_logs/README.md).
fn sample_args(name: &str) -> Vec<&'static str> {
    match name {
        "turning-car" => vec!["--scenario", "turning-car", "--seed", "1", "--frames", "40"],
        "pedestrians" => vec!["--scenario", "pedestrians", "--seed", "1", "--frames", "40"],
        "city" => vec![
            "--scenario",
            "city",
            "--seed",
            "1",
            "--frames",
            "40",
            "--objects",
            "40",
        ],
        _ => unreachable!(),
    }
}

fn track(input: &Path, output: &Path, extra: &[&str]) {
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    probmot_ok(&args);
}

#[test]
fn sample_logs_regenerate_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    for name in SAMPLES {
        let out = dir.path().join(format!("{name}.mcap"));
        let mut args = vec!["simulate"];
        args.extend(sample_args(name));
        args.extend(["-o", out.to_str().unwrap()]);
        probmot_ok(&args);
        let committed = std::fs::read(repo(&format!("sample_logs/{name}.mcap"))).unwrap();
        assert!(
            std::fs::read(&out).unwrap() == committed,
            "sample_logs/{name}.mcap differs from a fresh `probmot simulate`"
        );
    }
}

#[test]
fn every_input_message_survives_and_tracks_decode_with_the_embedded_descriptor() {
    let dir = tempfile::tempdir().unwrap();
    for name in SAMPLES {
        let input = repo(&format!("sample_logs/{name}.mcap"));
        let output = dir.path().join(format!("{name}.tracked.mcap"));
        track(&input, &output, &[]);
        let before = messages(&input);
        let after = messages(&output);
        let mut copied: Vec<Msg> = after
            .iter()
            .filter(|m| m.topic != "/tracks" && m.topic != "/tracks/scene")
            .cloned()
            .collect();
        let mut original = before.clone();
        copied.sort();
        original.sort();
        assert_eq!(copied, original, "{name}: input messages changed");

        // One tracks message per frame (distinct detection stamps), at the frame's log time
        // (here its stamp), and its SceneUpdate beside it.
        let det_times: Vec<u64> = before
            .iter()
            .filter(|m| m.topic == "/detections")
            .map(|m| m.log_time)
            .collect();
        let trk: Vec<&Msg> = after.iter().filter(|m| m.topic == "/tracks").collect();
        assert_eq!(trk.len(), det_times.len());
        assert_eq!(
            trk.iter().map(|m| m.log_time).collect::<Vec<_>>(),
            det_times
        );
        let scene: Vec<&Msg> = after
            .iter()
            .filter(|m| m.topic == "/tracks/scene")
            .collect();
        assert_eq!(
            scene.iter().map(|m| m.log_time).collect::<Vec<_>>(),
            det_times
        );
        assert!(scene.iter().all(|m| m.schema == "foxglove.SceneUpdate"));

        // Decode with the descriptor embedded in the file's schema record, not our types.
        let bytes = std::fs::read(&output).unwrap();
        let summary = mcap::Summary::read(&bytes)
            .unwrap()
            .expect("output has a summary");
        let ch = summary
            .channels
            .values()
            .find(|c| c.topic == "/tracks")
            .unwrap();
        let schema = ch.schema.as_ref().unwrap();
        assert_eq!(schema.name, "probmot.Tracks3D");
        assert_eq!(schema.encoding, "protobuf");
        let pool = DescriptorPool::decode(schema.data.as_ref()).unwrap();
        let desc = pool.get_message_by_name("probmot.Tracks3D").unwrap();
        for m in &trk {
            let dynamic = DynamicMessage::decode(desc.clone(), m.data.as_slice()).unwrap();
            let ours = probmot::msgs::Tracks3D::decode(m.data.as_slice()).unwrap();
            assert_finite(&ours);
            assert_eq!(
                dynamic.get_field_by_name("stamp").unwrap().as_u64(),
                Some(ours.stamp)
            );
            let list = dynamic.get_field_by_name("tracks").unwrap();
            let list = list.as_list().unwrap();
            assert_eq!(list.len(), ours.tracks.len());
            for (d, o) in list.iter().zip(&ours.tracks) {
                let d = d.as_message().unwrap();
                assert_eq!(d.get_field_by_name("id").unwrap().as_u64(), Some(o.id));
                assert_eq!(
                    d.get_field_by_name("label").unwrap().as_str(),
                    Some(o.label.as_str())
                );
                let c = d.get_field_by_name("center").unwrap();
                let c = c.as_message().unwrap();
                assert_eq!(
                    c.get_field_by_name("x").unwrap().as_ref(),
                    &Value::F64(o.center.unwrap().x)
                );
            }
        }
    }
}

#[test]
fn turning_car_keeps_one_track_id() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/turning-car.mcap");
    let output = dir.path().join("out.mcap");
    track(&input, &output, &[]);
    // Frames in which the turning car (truth id 1) was detected.
    let dets = detections(&input, "/detections");
    let detected: Vec<usize> = dets
        .iter()
        .enumerate()
        .filter(|(_, d)| {
            d.detections
                .iter()
                .any(|x| x.attributes.get("sim_truth_id").map(String::as_str) == Some("1"))
        })
        .map(|(i, _)| i)
        .collect();
    let frames = tracks(&output, "/tracks");
    let seq = truth_to_track(&frames).remove(&1).unwrap_or_default();
    let mut count: BTreeMap<u64, usize> = BTreeMap::new();
    for (_, id) in &seq {
        *count.entry(*id).or_default() += 1;
    }
    let (best, n) = count
        .iter()
        .max_by_key(|(_, n)| **n)
        .map(|(a, b)| (*a, *b))
        .unwrap();
    eprintln!(
        "turning car: detected in {} frames, track {best} reported it in {n}; ids seen {count:?}",
        detected.len()
    );
    assert!(
        n as f64 >= 0.9 * detected.len() as f64,
        "the turning car kept track {best} in only {n} of {} frames",
        detected.len()
    );
}

#[test]
fn pedestrians_id_switches_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.mcap");
    track(&repo("sample_logs/pedestrians.mcap"), &output, &[]);
    let frames = tracks(&output, "/tracks");
    let per_truth = truth_to_track(&frames);
    let mut total = 0;
    for (truth, seq) in &per_truth {
        let s = id_switches(seq);
        eprintln!(
            "pedestrians: truth {truth}: {} matched frames, {s} id switches",
            seq.len()
        );
        total += s;
    }
    eprintln!("pedestrians: {total} id switches in all");
    // 8 objects over 40 frames with scripted occlusions: switches must stay rare.
    assert!(total <= 4, "{total} id switches");
    assert_eq!(per_truth.len(), 8);
}

/// Writes a copy of `input` with its messages in reverse file order (same times and bytes).
fn reverse_order_copy(input: &Path, output: &Path) {
    let bytes = std::fs::read(input).unwrap();
    let msgs: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(output).unwrap(),
    ))
    .unwrap();
    for m in msgs.iter().rev() {
        w.write(m).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn out_of_order_input_gives_the_same_tracks() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["turning-car", "city"] {
        let input = repo(&format!("sample_logs/{name}.mcap"));
        let reversed = dir.path().join(format!("{name}.reversed.mcap"));
        reverse_order_copy(&input, &reversed);
        let a = dir.path().join("a.mcap");
        let b = dir.path().join("b.mcap");
        track(&input, &a, &[]);
        track(&reversed, &b, &[]);
        let mut ta = tracks(&a, "/tracks");
        let mut tb = tracks(&b, "/tracks");
        assert!(!ta.is_empty());
        ta.sort_by_key(|t| t.stamp);
        tb.sort_by_key(|t| t.stamp);
        assert_eq!(
            ta, tb,
            "{name}: tracks differ when the file is written backwards"
        );
    }
}

#[test]
fn same_input_gives_byte_identical_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/city.mcap");
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    track(&input, &a, &[]);
    track(&input, &b, &[]);
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
}

#[test]
fn refuses_bad_paths_with_status_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    std::fs::copy(repo("sample_logs/turning-car.mcap"), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let inp = input.to_str().unwrap();

    let out = probmot(&["track", inp, "-o", inp]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is the input file"));

    let missing_dir = dir.path().join("nope/out.mcap");
    let out = probmot(&["track", inp, "-o", missing_dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));

    let out = probmot(&[
        "track",
        dir.path().join("absent.mcap").to_str().unwrap(),
        "-o",
        dir.path().join("o.mcap").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.mcap"));

    // A tracks topic that already exists is refused.
    let out = probmot(&[
        "track",
        inp,
        "-o",
        dir.path().join("o.mcap").to_str().unwrap(),
        "--tracks-topic",
        "/ground_truth",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/ground_truth"));

    // Nothing but the input is left in the directory, and the input is unchanged.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["in.mcap".to_string()]);
    assert!(std::fs::read(&input).unwrap() == before);
}

#[test]
fn many_files_in_parallel_report_failures_and_finish_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let good = repo("sample_logs/pedestrians.mcap");
    let bad = dir.path().join("corrupt.mcap");
    let mut bytes = std::fs::read(&good).unwrap();
    bytes[1] = b'X';
    std::fs::write(&bad, &bytes).unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = probmot(&[
        "track",
        good.to_str().unwrap(),
        bad.to_str().unwrap(),
        repo("sample_logs/turning-car.mcap").to_str().unwrap(),
        "--out-dir",
        out_dir.to_str().unwrap(),
        "--jobs",
        "2",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("corrupt.mcap"), "{err}");
    assert!(out_dir.join("pedestrians.mcap").exists());
    assert!(out_dir.join("turning-car.mcap").exists());
    assert!(!out_dir.join("corrupt.mcap").exists());
    assert_eq!(std::fs::read_dir(&out_dir).unwrap().count(), 2);
}

#[test]
fn compression_option_changes_only_the_chunk_compression() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/city.mcap");
    let mut runs = Vec::new();
    for algo in ["zstd", "lz4", "none"] {
        let out = dir.path().join(format!("{algo}.mcap"));
        track(&input, &out, &["--compression", algo]);
        let bytes = std::fs::read(&out).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let used: std::collections::BTreeSet<String> = summary
            .chunk_indexes
            .iter()
            .map(|c| c.compression.clone())
            .collect();
        let want = if algo == "none" { "" } else { algo };
        assert_eq!(used, [want.to_string()].into(), "{algo}");
        let msgs: Vec<(String, u64, Vec<u8>)> = messages(&out)
            .into_iter()
            .map(|m| (m.topic, m.log_time, m.data))
            .collect();
        runs.push((bytes.len(), msgs));
    }
    assert_eq!(runs[0].1, runs[1].1);
    assert_eq!(runs[0].1, runs[2].1);
    // Uncompressed is the largest, zstd the smallest.
    assert!(
        runs[2].0 > runs[1].0 && runs[1].0 > runs[0].0,
        "{:?}",
        runs.iter().map(|r| r.0).collect::<Vec<_>>()
    );
    let bad = probmot(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        dir.path().join("x.mcap").to_str().unwrap(),
        "--compression",
        "gzip",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("expected zstd, lz4 or none"));
}

/// Writes a copy of `input` (same messages in the same order) whose summary section has no
/// schemas, channels or statistics, so `track` cannot plan a single pass from it.
fn copy_without_summary(input: &Path, output: &Path) {
    let bytes = std::fs::read(input).unwrap();
    let mut w = mcap::WriteOptions::new()
        .emit_summary_records(false)
        .emit_statistics(false)
        .create(std::io::BufWriter::new(
            std::fs::File::create(output).unwrap(),
        ))
        .unwrap();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        w.write(&m.unwrap()).unwrap();
    }
    w.finish().unwrap();
}

/// Writes a copy of `input` with its first detections message moved to the end of the file.
fn late_first_detections_copy(input: &Path, output: &Path) {
    let bytes = std::fs::read(input).unwrap();
    let mut msgs: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    let first = msgs
        .iter()
        .position(|m| m.channel.topic == "/detections")
        .unwrap();
    let m = msgs.remove(first);
    msgs.push(m);
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(output).unwrap(),
    ))
    .unwrap();
    for m in &msgs {
        w.write(m).unwrap();
    }
    w.finish().unwrap();
}

/// A log with a summary section is tracked in one pass, also when its messages are in reverse
/// order (the frames wait until the end); without a summary, or when a detection stamp goes
/// back to a frame already tracked (the first frame's message moved to the end), in two. All
/// give the same tracks message for message, and the same counts.
#[test]
fn one_pass_and_two_passes_give_the_same_tracks() {
    let dir = tempfile::tempdir().unwrap();
    for name in SAMPLES {
        let input = repo(&format!("sample_logs/{name}.mcap"));
        let bare = dir.path().join(format!("{name}.bare.mcap"));
        let late = dir.path().join(format!("{name}.late.mcap"));
        let reversed = dir.path().join(format!("{name}.reversed.mcap"));
        copy_without_summary(&input, &bare);
        late_first_detections_copy(&input, &late);
        reverse_order_copy(&input, &reversed);
        let runs: Vec<(serde_json::Value, Vec<probmot::msgs::Tracks3D>)> =
            [&input, &bare, &late, &reversed]
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let out = dir.path().join(format!("{name}.{i}.out.mcap"));
                    let s = track_json(p, &out, &[]);
                    let mut t = tracks(&out, "/tracks");
                    // In stamp order in every output; sorted so that a failure shows the tracks.
                    t.sort_by_key(|m| m.stamp);
                    (s, t)
                })
                .collect();
        let passes: Vec<u64> = runs
            .iter()
            .map(|(s, _)| s["passes"].as_u64().unwrap())
            .collect();
        assert_eq!(passes, [1, 2, 2, 1], "{name}");
        assert!(!runs[0].1.is_empty());
        for (s, t) in &runs[1..] {
            assert!(t == &runs[0].1, "{name}: the tracks differ");
            for key in [
                "frames",
                "detection_messages",
                "merged_messages",
                "tracks_born",
                "tracks_confirmed",
                "tracks_messages",
                "detections",
            ] {
                assert_eq!(s[key], runs[0].0[key], "{name}: {key}");
            }
        }
    }
}

/// A footer whose summary offset points at garbage: `track` does not trust it, reads the log
/// twice and gives the same tracks.
#[test]
fn a_bad_summary_offset_falls_back_to_two_passes() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/city.mcap");
    let mut bytes = std::fs::read(&input).unwrap();
    // Footer: opcode, length, summary start, summary offset start, CRC; then the magic.
    let footer = bytes.len() - (1 + 8 + 20 + 8);
    assert_eq!(bytes[footer], 0x02);
    let bad = (footer as u64 - 5).to_le_bytes();
    bytes[footer + 9..footer + 17].copy_from_slice(&bad);
    let broken = dir.path().join("broken-summary.mcap");
    std::fs::write(&broken, &bytes).unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    let sa = track_json(&input, &a, &[]);
    let sb = track_json(&broken, &b, &[]);
    assert_eq!(
        (sa["passes"].as_u64(), sb["passes"].as_u64()),
        (Some(1), Some(2))
    );
    assert!(tracks(&a, "/tracks") == tracks(&b, "/tracks"));
}

/// `track` over bytes in memory into a sink in memory (no file): the same tracks as the file
/// run; and when the single pass finds a stamp going back to a tracked frame, the sink is
/// restarted, so it holds every input message once, not the first attempt's too.
#[test]
fn tracking_bytes_into_memory_restarts_the_sink_for_a_second_pass() {
    use probmot::mcapio::reader::McapInput;
    use probmot::mcapio::sink::{MemorySink, SinkRecord};
    use probmot::pipeline::progress::no_progress;
    use probmot::pipeline::track::{track_input, TrackOptions};

    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/turning-car.mcap");
    let late = dir.path().join("late.mcap");
    late_first_detections_copy(&input, &late);
    let file_out = dir.path().join("late.out.mcap");
    let file_summary = track_json(&late, &file_out, &[]);
    let expected: Vec<probmot::msgs::Tracks3D> = tracks(&file_out, "/tracks");

    let bytes = std::fs::read(&late).unwrap();
    let mut source = McapInput::from_bytes("late in memory", &bytes);
    let config = probmot::tracker::TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let opts = TrackOptions::new(config);
    let open = |_profile: String| Ok(MemorySink::default());
    let (sink, summary) = track_input(&mut source, &opts, &no_progress, open).unwrap();
    assert_eq!(summary.passes, 2, "the single pass met a stamp going back");
    assert_eq!(summary.input, "late in memory");
    assert_eq!(
        file_summary["messages_copied"].as_u64(),
        Some(summary.messages_copied)
    );
    let mut input_channels = std::collections::BTreeSet::new();
    let mut input_messages = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        input_channels.insert(m.unwrap().channel.id);
        input_messages += 1;
    }
    let tracks_channel =
        |r: &&SinkRecord| matches!(r, SinkRecord::Channel(_, _, t) if t == "/tracks");
    let Some(SinkRecord::Channel(tracks_id, _, _)) = sink.records.iter().find(tracks_channel)
    else {
        panic!("no tracks channel in the sink");
    };
    let (mut copied, mut got) = (0, Vec::new());
    for r in &sink.records {
        match r {
            SinkRecord::Message(h, d) if h.channel_id == *tracks_id => {
                got.push(probmot::msgs::Tracks3D::decode(d.as_slice()).unwrap())
            }
            SinkRecord::Message(h, _) if input_channels.contains(&h.channel_id) => copied += 1,
            _ => {}
        }
    }
    assert_eq!(copied, input_messages, "every input message once");
    assert!(got == expected, "the tracks differ from the file run's");
}
