//! Recordings that did not finish (a recorder killed, crashed or without power leaves its file
//! cut off mid-record): `track` and `info` read them up to the last whole record and say what
//! was lost; the commands that read `track`'s outputs refuse them, pointing at `track`.

use std::path::{Path, PathBuf};

use crate::common::split::split_mcap;
use crate::common::*;

/// The messages of `topic` in `path`, as bytes, in file order.
fn topic_data(path: &Path, topic: &str) -> Vec<Vec<u8>> {
    (messages(path).into_iter())
        .filter(|m| m.topic == topic)
        .map(|m| m.data)
        .collect()
}

/// `bytes[..len]` written to `dir/name`.
fn cut_copy(dir: &Path, name: &str, bytes: &[u8], len: usize) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, &bytes[..len]).unwrap();
    path
}

/// A simulated drive of several chunks (`sample_logs/city.mcap` is one chunk).
fn long_drive(dir: &Path) -> PathBuf {
    let path = dir.join("drive.mcap");
    let p = path.to_str().unwrap();
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "400",
        "-o",
        p,
        "--quiet",
    ]);
    path
}

/// The drive of [`long_drive`] (made in `dir` once) split in three files, as rosbag2 splits a
/// recording, in the bag directory `dir/name`.
fn three_file_bag(dir: &Path, name: &str) -> Vec<PathBuf> {
    let drive = dir.join("drive.mcap");
    if !drive.exists() {
        long_drive(dir);
    }
    let n = messages(&drive).len();
    split_mcap(&drive, &dir.join(name), &[n / 3, 2 * n / 3])
}

/// Keeps the first half of the file `path`: a recorder died while writing it.
fn cut_in_half(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    std::fs::write(path, &bytes[..bytes.len() / 2]).unwrap();
}

/// Tracks `input` into `out`, which must succeed; its stderr.
fn track_ok(input: &Path, out: &Path) -> String {
    let r = track(input, out, &["--quiet"]);
    assert_eq!(r.status.code(), Some(0), "{r:?}");
    String::from_utf8_lossy(&r.stderr).into_owned()
}

/// The `/tracks` messages of the output bag `dir`, file after file (fewer than 10 files).
fn bag_tracks(dir: &Path) -> Vec<Vec<u8>> {
    let mut files: Vec<PathBuf> = (std::fs::read_dir(dir).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    files.sort();
    assert!(!files.is_empty() && files.len() < 10, "{files:?}");
    files
        .iter()
        .flat_map(|f| topic_data(f, "/tracks"))
        .collect()
}

fn track(input: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    probmot(&args)
}

#[test]
fn a_file_cut_short_is_tracked_up_to_the_cut_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let sample = long_drive(dir.path());
    let good = std::fs::read(&sample).unwrap();
    let full = dir.path().join("full.mcap");
    probmot_ok(&[
        "track",
        sample.to_str().unwrap(),
        "-o",
        full.to_str().unwrap(),
    ]);
    let full_tracks = topic_data(&full, "/tracks");
    let full_scene = topic_data(&full, "/tracks/scene");

    // Cut in the middle of the data: the tracks are those of the full run, up to the cut.
    let half = cut_copy(dir.path(), "half.mcap", &good, good.len() / 2);
    let out = dir.path().join("half.out.mcap");
    let err = track_ok(&half, &out);
    assert!(
        err.contains(&format!(
            "warning: {}: the file is cut short",
            half.display()
        )) && err.contains("were read up to byte")
            && err.contains("were not"),
        "{err}"
    );
    let tracks = topic_data(&out, "/tracks");
    assert!(
        !tracks.is_empty() && tracks.len() < full_tracks.len(),
        "{} of {} tracks messages",
        tracks.len(),
        full_tracks.len()
    );
    assert_eq!(tracks[..], full_tracks[..tracks.len()]);
    let scene = topic_data(&out, "/tracks/scene");
    assert_eq!(scene[..], full_scene[..scene.len()]);
    // Every input message before the cut is in the output, in order.
    let kept: Vec<Msg> = (messages(&out).into_iter())
        .filter(|m| !m.topic.starts_with("/tracks"))
        .collect();
    let input: Vec<Msg> = (messages(&full).into_iter())
        .filter(|m| !m.topic.starts_with("/tracks"))
        .collect();
    assert!(!kept.is_empty() && kept.len() < input.len());
    for (a, b) in kept.iter().zip(&input) {
        assert_eq!(
            (&a.topic, a.log_time, &a.data),
            (&b.topic, b.log_time, &b.data)
        );
    }
    assert_eq!(
        std::fs::read(&half).unwrap(),
        good[..good.len() / 2],
        "input changed"
    );

    // Cut in the footer: every message is read, the tracks are the full run's.
    let tail = cut_copy(dir.path(), "tail.mcap", &good, good.len() - 9);
    let out = dir.path().join("tail.out.mcap");
    let err = track_ok(&tail, &out);
    assert!(err.contains("every message was read"), "{err}");
    assert_eq!(topic_data(&out, "/tracks"), full_tracks);

    // --strict refuses the file, and writes nothing.
    let out = dir.path().join("strict.out.mcap");
    let r = track(&half, &out, &["--strict"]);
    assert_eq!(r.status.code(), Some(2), "{r:?}");
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("cut short") && err.contains("--strict"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The messages of `input` rewritten in chunks of about `chunk` bytes.
fn rechunked(input: &Path, out: &Path, chunk: u64) {
    let bytes = std::fs::read(input).unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(out).unwrap());
    let mut w = mcap::WriteOptions::new()
        .chunk_size(Some(chunk))
        .create(file)
        .unwrap();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        w.write(&m.unwrap()).unwrap();
    }
    w.finish().unwrap();
}

/// Cut anywhere after its header record, a file tracks: its tracks are the whole file's up to
/// the cut, more of them the later the cut.
#[test]
fn a_file_cut_anywhere_tracks_the_whole_files_tracks_up_to_the_cut() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("small.mcap");
    rechunked(&repo("sample_logs/city.mcap"), &input, 8 << 10);
    let good = std::fs::read(&input).unwrap();
    let full = dir.path().join("full.mcap");
    assert_eq!(track(&input, &full, &["--quiet"]).status.code(), Some(0));
    let all = topic_data(&full, "/tracks");
    let mut before = 0;
    for k in 1..40 {
        let len = 64 + k * (good.len() - 64) / 40;
        let cut = cut_copy(dir.path(), "cut.mcap", &good, len);
        let out = dir.path().join(format!("cut{k}.mcap"));
        let r = track(&cut, &out, &["--quiet"]);
        assert_eq!(r.status.code(), Some(0), "cut at {len}: {r:?}");
        let tracks = topic_data(&out, "/tracks");
        assert!(
            tracks.len() >= before && tracks.len() <= all.len(),
            "cut at {len}"
        );
        assert_eq!(tracks[..], all[..tracks.len()], "cut at {len}");
        before = tracks.len();
    }
    assert!(before > all.len() * 9 / 10, "{before} of {}", all.len());
}

#[test]
fn info_reads_a_file_cut_short_and_the_readers_of_outputs_refuse_it() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read(long_drive(dir.path())).unwrap();
    let half = cut_copy(dir.path(), "half.mcap", &good, good.len() / 2);
    let h = half.to_str().unwrap();
    let r = probmot_ok(&["info", h]);
    let text = String::from_utf8_lossy(&r.stdout);
    let line = text.lines().find(|l| l.starts_with("cut short:"));
    assert!(
        line.is_some_and(|l| l.contains("half.mcap") && l.contains("up to byte")),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&probmot_ok(&["info", h, "--json"]).stdout).unwrap();
    let cut = &json["cut_short"][0];
    assert_eq!(cut["file_bytes"].as_u64(), Some(good.len() as u64 / 2));
    assert!(cut["complete_bytes"].as_u64().unwrap() < good.len() as u64 / 2);
    // A whole file has no such line.
    let whole = probmot_ok(&["info", repo("sample_logs/city.mcap").to_str().unwrap()]);
    assert!(!String::from_utf8_lossy(&whole.stdout).contains("cut short"));

    let (png, json) = (dir.path().join("x.png"), dir.path().join("x.json"));
    for args in [
        vec!["eval", "--truth", h],
        vec!["plot", h, "-o", png.to_str().unwrap()],
        vec!["fit", h, "-o", json.to_str().unwrap()],
    ] {
        let r = probmot(&args);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {r:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            err.contains("half.mcap")
                && err.contains("cut short at byte")
                && err.contains("`probmot track`"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn a_split_bag_whose_last_file_is_cut_short_is_tracked_up_to_the_cut() {
    let dir = tempfile::tempdir().unwrap();
    let (bag, files) = (
        dir.path().join("drive"),
        three_file_bag(dir.path(), "drive"),
    );
    let whole = dir.path().join("whole");
    track_ok(&bag, &whole);
    // The recorder died while writing the last file: cut it in its middle.
    cut_in_half(&files[2]);
    let out = dir.path().join("out");
    let err = track_ok(&bag, &out);
    assert!(
        err.contains(&format!("{}: the file is cut short", files[2].display())),
        "{err}"
    );
    // The tracks, file after file, are the whole bag's up to the cut. (Which output file a
    // tracks message lands in may differ: the cut bag has no summary to plan one pass with.)
    let (cut, all) = (bag_tracks(&out), bag_tracks(&whole));
    assert!(
        2 * all.len() / 3 < cut.len() && cut.len() < all.len(),
        "{} of {}",
        cut.len(),
        all.len()
    );
    assert_eq!(cut[..], all[..cut.len()]);
    // The output bag is whole: info reads it without a word of a cut.
    let info = probmot_ok(&["info", out.to_str().unwrap()]);
    assert!(!String::from_utf8_lossy(&info.stdout).contains("cut short"));

    // The same bag with its files compressed whole (`--compression-mode file`), the last one
    // cut short in its compressed bytes.
    let (zbag, zfiles) = (
        dir.path().join("zdrive"),
        three_file_bag(dir.path(), "zdrive"),
    );
    let mut yaml = std::fs::read_to_string(zbag.join("metadata.yaml")).unwrap();
    yaml = yaml.replace("compression_format: ''", "compression_format: zstd");
    yaml = yaml.replace("compression_mode: ''", "compression_mode: FILE");
    for (i, f) in zfiles.iter().enumerate() {
        let z = zstd::encode_all(std::fs::read(f).unwrap().as_slice(), 3).unwrap();
        let z = if i == 2 { &z[..z.len() / 2] } else { &z[..] };
        std::fs::write(f.with_extension("mcap.zstd"), z).unwrap();
        std::fs::remove_file(f).unwrap();
        yaml = yaml.replace(
            &format!("zdrive_{i}.mcap"),
            &format!("zdrive_{i}.mcap.zstd"),
        );
    }
    std::fs::write(zbag.join("metadata.yaml"), yaml).unwrap();
    let zout = dir.path().join("zout");
    let err = track_ok(&zbag, &zout);
    assert!(
        err.contains("zdrive_2.mcap.zstd (decompressed): the file is cut short"),
        "{err}"
    );
    let ztracks = bag_tracks(&zout);
    assert!(
        2 * all.len() / 3 < ztracks.len() && ztracks.len() < all.len(),
        "{} of {}",
        ztracks.len(),
        all.len()
    );
    assert_eq!(ztracks[..], all[..ztracks.len()]);
}

/// What a recorder leaves that lost power (ROS 2 Humble writes `metadata.yaml` only when
/// recording stops): the bag's files, the last one cut short, and no `metadata.yaml`. `track`
/// and `info` read it by rosbag2's file names, with a warning; the output is a whole bag.
#[test]
fn a_recording_that_lost_power_is_tracked_without_its_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let (bag, files) = (
        dir.path().join("drive"),
        three_file_bag(dir.path(), "drive"),
    );
    let whole = dir.path().join("whole");
    track_ok(&bag, &whole);
    std::fs::remove_file(bag.join("metadata.yaml")).unwrap();
    cut_in_half(&files[2]);

    let out = dir.path().join("out");
    let err = track_ok(&bag, &out);
    let no_metadata = format!(
        "warning: {}: no metadata.yaml (a recording that did not finish?); read as a rosbag2 \
         bag by the names rosbag2 gives a bag's files: its 3 files, drive_0.mcap to \
         drive_2.mcap, in that order",
        bag.display()
    );
    assert!(err.contains(&no_metadata), "{err}");
    assert!(err.contains("drive_2.mcap: the file is cut short"), "{err}");
    let (cut, all) = (bag_tracks(&out), bag_tracks(&whole));
    assert!(2 * all.len() / 3 < cut.len() && cut.len() < all.len());
    assert_eq!(cut[..], all[..cut.len()]);
    // The output is a whole bag, with its metadata.yaml.
    assert!(out.join("metadata.yaml").is_file());
    let info = probmot_ok(&["info", out.to_str().unwrap()]);
    assert!(info.stderr.is_empty(), "{info:?}");

    let info = probmot_ok(&["info", bag.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&info.stderr);
    assert!(err.contains(&no_metadata), "{err}");
    assert!(String::from_utf8_lossy(&info.stdout).contains("cut short:"));

    // Recorded with `--compression-mode file`: rosbag2 compresses each file once it is closed,
    // so the power went while file 1 was being compressed (`drive_1.mcap` whole beside a part
    // of `drive_1.mcap.zstd`) and file 2 was being written.
    let (zbag, zfiles) = (
        dir.path().join("zdrive"),
        three_file_bag(dir.path(), "zdrive"),
    );
    std::fs::remove_file(zbag.join("metadata.yaml")).unwrap();
    let compress = |f: &Path| zstd::encode_all(std::fs::read(f).unwrap().as_slice(), 3).unwrap();
    std::fs::write(zfiles[0].with_extension("mcap.zstd"), compress(&zfiles[0])).unwrap();
    std::fs::remove_file(&zfiles[0]).unwrap();
    let z1 = compress(&zfiles[1]);
    std::fs::write(zfiles[1].with_extension("mcap.zstd"), &z1[..z1.len() / 3]).unwrap();
    cut_in_half(&zfiles[2]);
    let zout = dir.path().join("zout");
    let err = track_ok(&zbag, &zout);
    assert!(
        err.contains("its 3 files, zdrive_0.mcap.zstd to zdrive_2.mcap, in that order"),
        "{err}"
    );
    let ztracks = bag_tracks(&zout);
    assert_eq!(
        ztracks, cut,
        "the same drive, read from the same whole records"
    );
}

/// A file still being written: each time it is read from its start again, it has grown by
/// `step` bytes (until whole).
struct Growing {
    bytes: Vec<u8>,
    visible: usize,
    step: usize,
    pos: u64,
}

impl std::io::Read for Growing {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let end = self.visible.min(self.bytes.len());
        let pos = (self.pos as usize).min(end);
        let n = buf.len().min(end - pos);
        buf[..n].copy_from_slice(&self.bytes[pos..pos + n]);
        self.pos += n as u64;
        Ok(n)
    }
}

impl std::io::Seek for Growing {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        use std::io::SeekFrom;
        let end = self.visible.min(self.bytes.len()) as i64;
        self.pos = match to {
            SeekFrom::Start(0) => {
                self.visible += self.step;
                0
            }
            SeekFrom::Start(n) => n,
            SeekFrom::End(d) => (end + d).max(0) as u64,
            SeekFrom::Current(d) => (self.pos as i64 + d).max(0) as u64,
        };
        Ok(self.pos)
    }
}

/// `track` on a recording in progress (it grows between the two passes): the second pass reads
/// what the first read, so every detection message copied is tracked, and none is left out.
#[test]
fn a_recording_still_being_written_is_read_alike_by_both_passes() {
    use probmot::mcapio::reader::McapInput;
    use probmot::mcapio::sink::{MemorySink, SinkRecord};
    use probmot::pipeline::progress::no_progress;
    use probmot::pipeline::track::{track_input, TrackOptions};

    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("small.mcap");
    rechunked(&repo("sample_logs/city.mcap"), &file, 8 << 10);
    let bytes = std::fs::read(&file).unwrap();
    let step = bytes.len() / 10;
    let growing = Growing {
        bytes: bytes.clone(),
        visible: 4 * step,
        step,
        pos: 0,
    };
    let mut source = McapInput::new("live.mcap", growing);
    let config = probmot::tracker::TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let open = |_profile: String| Ok(MemorySink::default());
    let (sink, summary) =
        track_input(&mut source, &TrackOptions::new(config), &no_progress, open).unwrap();
    assert_eq!(summary.passes, 2);
    let cut = (summary.warnings.iter()).find(|w| w.starts_with("live.mcap: the file is cut short"));
    assert!(cut.is_some(), "{:?}", summary.warnings);
    let topics: std::collections::HashMap<u16, String> = (sink.records.iter())
        .filter_map(|r| match r {
            SinkRecord::Channel(id, _, topic) => Some((*id, topic.clone())),
            _ => None,
        })
        .collect();
    let on = |topic: &str| -> Vec<u64> {
        (sink.records.iter())
            .filter_map(|r| match r {
                SinkRecord::Message(h, _) if topics[&h.channel_id] == topic => Some(h.log_time),
                _ => None,
            })
            .collect()
    };
    let (detections, tracks) = (on("/detections"), on("/tracks"));
    let all = detections_in(&bytes);
    assert!(
        !detections.is_empty() && detections.len() < all,
        "{} of {all}",
        detections.len()
    );
    assert_eq!(
        tracks.len(),
        detections.len(),
        "a tracks message per detection message"
    );
}

/// The number of `/detections` messages of the MCAP file `bytes`.
fn detections_in(bytes: &[u8]) -> usize {
    (mcap::MessageStream::new(bytes).unwrap())
        .filter(|m| m.as_ref().unwrap().channel.topic == "/detections")
        .count()
}
