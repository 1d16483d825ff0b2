//! `probmot import kitti` and `probmot export kitti`.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::formats::kitti::{
    box_to_camera, camera_to_box, format_row, parse_detection_line, parse_label_line, KittiRow,
};
use crate::mcapio::reader::{has_metadata, read_records};
use crate::mcapio::recording::for_each_tracks_frame;
use crate::mcapio::writer::{
    check_output_path, write_file_atomic_with, AtomicOutput, OutputOptions,
};
use crate::mcapio::LabelledBox;
use crate::msgs::size3;
use crate::msgs::track_encode::encode_tracks_into;
use crate::msgs::{self, v3, Detection3D, Detections3D, ImageBox, Track3D, Tracks3D};
use crate::tracker::Box3;

/// KITTI has no absolute times: an imported log starts at 2026-01-01T00:00:00Z, as simulated
/// logs do (`sim::write::START_NS`).
const START_NS: u64 = 1_767_225_600_000_000_000;

/// Coordinate frame of the imported boxes: KITTI's camera frame turned z-up
/// ([`camera_to_box`]).
const FRAME_ID: &str = "kitti_camera_z_up";

/// KITTI tracking runs at 10 Hz.
pub const KITTI_PERIOD_NS: u64 = 100_000_000;
/// Name of the metadata record that remembers the KITTI sequence and time base.
pub const KITTI_METADATA: &str = "probmot.kitti";

/// Attributes that carry the KITTI fields the 3D box does not hold.
pub mod attr {
    /// Original type, e.g. `Car`.
    pub const TYPE: &str = "kitti_type";
    /// Truncation.
    pub const TRUNCATED: &str = "kitti_truncated";
    /// Occlusion level.
    pub const OCCLUDED: &str = "kitti_occluded";
    /// Observation angle.
    pub const ALPHA: &str = "kitti_alpha";
    /// Original track id (ground truth).
    pub const TRACK_ID: &str = "kitti_track_id";
}

/// KITTI's track id of a ground-truth box, as the KITTI evaluation's loader reads it: the label
/// file's id (attribute [`attr::TRACK_ID`]), else the box id minus one (`import kitti` stores
/// id + 1, ids being non-zero).
pub fn truth_track_id(b: &LabelledBox) -> i64 {
    number_attr(&b.attributes, attr::TRACK_ID).map_or(b.id as i64 - 1, |v| v.trunc() as i64)
}

/// A numeric KITTI attribute as Python's `float(s)` reads the text field (surrounding
/// whitespace allowed); `None` when absent or not a number. The one reader of these attributes
/// for the evaluation and the export.
pub fn number_attr(attributes: &BTreeMap<String, String>, key: &str) -> Option<f64> {
    attributes.get(key).and_then(|v| v.trim().parse().ok())
}

/// Counts of an import.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ImportSummary {
    /// Frames written.
    pub frames: u32,
    /// Detections written.
    pub detections: u64,
    /// Ground-truth rows written (DontCare included).
    pub truth_rows: u64,
    /// Rows of another tracker's results written as tracks.
    pub track_rows: u64,
    /// Detection files read.
    pub detection_files: Vec<String>,
}

fn read_lines(path: &Path) -> Result<Vec<(usize, String)>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| (i + 1, l.to_string()))
        .collect())
}

/// Resolves `--detections` arguments: files as given; for a directory, `SEQ.txt` in it or in its
/// immediate subdirectories (e.g. `pointrcnn/{Car,Pedestrian,Cyclist}/SEQ.txt`), other than the
/// `labels` file and files that are clearly other KITTI files (a dataset folder given one level
/// too high holds `label_02/SEQ.txt` and `calib/SEQ.txt`, which are skipped and named if nothing
/// is found). Any other file is read as detections, so a damaged one fails with its line.
pub fn resolve_detection_files(
    args: &[PathBuf],
    sequence: &str,
    labels: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    let (mut out, mut candidates) = (Vec::new(), Vec::new());
    let name = format!("{sequence}.txt");
    for a in args {
        if a.is_dir() {
            candidates.push(a.join(&name));
            let mut subs: Vec<PathBuf> = std::fs::read_dir(a)
                .with_context(|| format!("cannot list {}", a.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_dir())
                .collect();
            subs.sort();
            candidates.extend(subs.into_iter().map(|s| s.join(&name)));
        } else if a.is_file() {
            out.push(a.clone());
        } else {
            bail!("{}: no such file or directory", a.display());
        }
    }
    let labels = labels.and_then(|l| std::fs::canonicalize(l).ok());
    let mut skipped = Vec::new();
    for f in candidates.into_iter().filter(|f| f.is_file()) {
        let is_labels = labels.is_some() && std::fs::canonicalize(&f).ok() == labels;
        if is_labels || is_other_kitti_file(&f) {
            skipped.push(f.display().to_string());
        } else {
            out.push(f);
        }
    }
    if out.is_empty() {
        let dirs: Vec<String> = args.iter().map(|a| a.display().to_string()).collect();
        let skipped = match skipped.is_empty() {
            true => String::new(),
            false => format!(" (skipped, not detection files: {})", skipped.join(", ")),
        };
        bail!(
            "no detection file {name} in {} or the folders directly inside{skipped}; \
             --detections takes e.g. pointrcnn/ (which holds Car/{name}, ...)",
            dirs.join(", ")
        );
    }
    Ok(out)
}

/// Whether the first line of `path` that is not blank is a line of another KITTI file: a label
/// or tracking result line, a calibration line or an oxts (GPS/IMU) line. An empty or unreadable
/// file is not: it is read as detections (a sequence without any, or an error naming the file).
fn is_other_kitti_file(path: &Path) -> bool {
    use std::io::BufRead;
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    let mut lines = std::io::BufReader::new(file).lines();
    match lines.find(|l| l.as_ref().map_or(true, |l| !l.trim().is_empty())) {
        Some(Ok(line)) => is_other_kitti_line(&line),
        _ => false,
    }
}

/// A line of a KITTI label or tracking result file (17 or 18 fields), of a calibration file
/// (`P0: ...`, `R_rect ...`, `Tr_velo_cam ...`: a matrix name, then 9 or 12 numbers) or of an
/// oxts file (30 numbers separated by spaces). PointRCNN detection lines are comma-separated.
fn is_other_kitti_line(line: &str) -> bool {
    let numbers = |fields: &[&str]| fields.iter().all(|f| f.parse::<f64>().is_ok());
    let fields: Vec<&str> = line.split_whitespace().collect();
    let calib = fields.split_first().is_some_and(|(key, rest)| {
        let key = key.trim_end_matches(':');
        let named =
            ["P0", "P1", "P2", "P3", "R0_rect", "R_rect"].contains(&key) || key.starts_with("Tr_");
        named && [9, 12].contains(&rest.len()) && numbers(rest)
    });
    let oxts = fields.len() == 30 && numbers(&fields);
    parse_label_line(line).is_ok() || calib || oxts
}

fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

fn image_box(b: [f64; 4]) -> ImageBox {
    ImageBox {
        x1: b[0],
        y1: b[1],
        x2: b[2],
        y2: b[3],
    }
}

/// Another tracker's KITTI tracking result file to import as a tracks channel.
#[derive(Debug, Clone)]
pub struct TracksInput {
    /// Result file (`frame id type 0 0 alpha x1 y1 x2 y2 h w l x y z rotation_y score`).
    pub file: PathBuf,
    /// Topic of the tracks channel to write, e.g. `/tracks`.
    pub topic: String,
}

/// Rows of a KITTI text file by frame, parsed with `parse` (errors name the file and line).
fn rows_by_frame(
    path: &Path,
    parse: fn(&str) -> Result<KittiRow>,
    into: &mut BTreeMap<u32, Vec<KittiRow>>,
) -> Result<()> {
    for (n, line) in read_lines(path)? {
        let row = parse(&line).with_context(|| format!("{}:{n}", path.display()))?;
        into.entry(row.frame).or_default().push(row);
    }
    Ok(())
}

/// Reads a tracking result file: rows by frame, each with a score and a track id >= 0.
fn read_result_tracks(path: &Path) -> Result<BTreeMap<u32, Vec<KittiRow>>> {
    let mut rows = BTreeMap::new();
    rows_by_frame(path, parse_label_line, &mut rows)?;
    for r in rows.values().flatten() {
        if r.score.is_none() || r.track_id < 0 {
            bail!(
                "{}: frame {} ({}): a tracking result row needs a track id >= 0 and a score \
                 (18 fields), got id {} and {} fields",
                path.display(),
                r.frame,
                r.kind,
                r.track_id,
                if r.score.is_some() { 18 } else { 17 }
            );
        }
    }
    Ok(rows)
}

/// Writes one sequence as MCAP: `/detections` (when detection files are given) and
/// `/ground_truth` (when labels are) at 10 Hz, one message per frame on each (empty where
/// nothing was seen), plus a `probmot.kitti` metadata record. With
/// `tracks`, another tracker's results are written as a `probmot.Tracks3D` channel too (one
/// message per frame), which `probmot eval --tracks/--baseline` reads like probmot's own tracks.
pub fn import_kitti(
    labels: Option<&Path>,
    detection_files: &[PathBuf],
    tracks: Option<&TracksInput>,
    sequence: &str,
    output: &Path,
) -> Result<ImportSummary> {
    check_output_path(None, output)?;
    let mut dets: BTreeMap<u32, Vec<KittiRow>> = BTreeMap::new();
    let mut summary = ImportSummary::default();
    for f in detection_files {
        rows_by_frame(f, parse_detection_line, &mut dets)?;
        summary.detection_files.push(f.display().to_string());
    }
    let mut truth: BTreeMap<u32, Vec<KittiRow>> = BTreeMap::new();
    if let Some(l) = labels {
        rows_by_frame(l, parse_label_line, &mut truth)?;
    }
    let results = match tracks {
        Some(t) => read_result_tracks(&t.file)?,
        None => BTreeMap::new(),
    };
    let last = dets
        .keys()
        .chain(truth.keys())
        .chain(results.keys())
        .max()
        .copied()
        .context("no rows in the label, detection or tracks files")?;

    let mut out = AtomicOutput::create(output, &OutputOptions::default())?;
    let w = &mut out.writer;
    let s_det = w.add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
    let s_trk = w.add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
    let none = BTreeMap::new();
    // No detection files (truth or another tracker's results only): no /detections channel,
    // so that `track` on the log says so instead of tracking an empty channel.
    let c_det = if detection_files.is_empty() {
        None
    } else {
        Some(w.add_channel(s_det, "/detections", "protobuf", &none)?)
    };
    let c_gt = if labels.is_some() {
        Some(w.add_channel(s_trk, "/ground_truth", "protobuf", &none)?)
    } else {
        None
    };
    let c_trk = match tracks {
        Some(t) => Some(w.add_channel(s_trk, &t.topic, "protobuf", &none)?),
        None => None,
    };
    w.write_metadata(&mcap::records::Metadata {
        name: KITTI_METADATA.into(),
        metadata: attrs(&[
            ("sequence", sequence.to_string()),
            ("first_stamp_ns", START_NS.to_string()),
            ("frame_period_ns", KITTI_PERIOD_NS.to_string()),
        ]),
    })?;
    let mut buf = Vec::new();
    for frame in 0..=last {
        let stamp = START_NS + frame as u64 * KITTI_PERIOD_NS;
        let header = |ch| mcap::records::MessageHeader {
            channel_id: ch,
            sequence: frame,
            log_time: stamp,
            publish_time: stamp,
        };
        if let Some(c_det) = c_det {
            let rows = dets.get(&frame).map(Vec::as_slice).unwrap_or(&[]);
            let msg = detections_msg(stamp, rows);
            summary.detections += rows.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_det), &buf)?;
        }
        if let Some(c_gt) = c_gt {
            let rows = truth.get(&frame).map(Vec::as_slice).unwrap_or(&[]);
            let gt = tracks_msg(stamp, rows.iter().map(truth_track).collect());
            summary.truth_rows += rows.len() as u64;
            encode_tracks_into(&gt, &mut buf);
            w.write_to_known_channel(&header(c_gt), &buf)?;
        }
        if let Some(c_trk) = c_trk {
            let rows = results.get(&frame).map(Vec::as_slice).unwrap_or(&[]);
            let msg = tracks_msg(stamp, rows.iter().map(result_track).collect());
            summary.track_rows += rows.len() as u64;
            encode_tracks_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_trk), &buf)?;
        }
    }
    out.commit()?;
    summary.frames = last + 1;
    Ok(summary)
}

/// The `/detections` message of one frame's detection rows.
fn detections_msg(stamp: u64, rows: &[KittiRow]) -> Detections3D {
    Detections3D {
        stamp: Some(stamp),
        frame_id: FRAME_ID.into(),
        detections: rows
            .iter()
            .map(|r| {
                let b = camera_to_box(r.hwl, r.xyz, r.rotation_y);
                Detection3D {
                    center: Some(v3(b.center)),
                    size: Some(size3(b.size)),
                    yaw: b.yaw,
                    label: r.kind.to_lowercase(),
                    score: r.score.unwrap_or(0.0),
                    velocity: None,
                    image_box: Some(image_box(r.bbox)),
                    attributes: attrs(&[
                        (attr::TYPE, r.kind.clone()),
                        (attr::ALPHA, format!("{}", r.alpha)),
                    ]),
                }
            })
            .collect(),
    }
}

/// A `Tracks3D` message of one frame.
fn tracks_msg(stamp: u64, tracks: Vec<Track3D>) -> Tracks3D {
    Tracks3D {
        stamp,
        frame_id: FRAME_ID.into(),
        tracks,
    }
}

fn truth_track(r: &KittiRow) -> Track3D {
    let b = camera_to_box(r.hwl, r.xyz, r.rotation_y);
    Track3D {
        // Instance ids must be non-zero; DontCare regions (id -1) get id 0.
        id: if r.track_id >= 0 {
            r.track_id as u64 + 1
        } else {
            0
        },
        label: r.kind.to_lowercase(),
        center: Some(v3(b.center)),
        size: Some(size3(b.size)),
        yaw: b.yaw,
        velocity: Some(v3([0.0; 3])),
        score: 1.0,
        image_box: Some(image_box(r.bbox)),
        attributes: attrs(&[
            (attr::TYPE, r.kind.clone()),
            (attr::TRUNCATED, format!("{}", r.truncated)),
            (attr::OCCLUDED, format!("{}", r.occluded)),
            (attr::ALPHA, format!("{}", r.alpha)),
            (attr::TRACK_ID, format!("{}", r.track_id)),
        ]),
        ..Default::default()
    }
}

/// A row of another tracker's result file as a track: id = the file's id + 1 (ids must be
/// non-zero; `export kitti` writes the original from the `kitti_track_id` attribute), the score,
/// type, alpha and 2D box kept.
fn result_track(r: &KittiRow) -> Track3D {
    let b = camera_to_box(r.hwl, r.xyz, r.rotation_y);
    Track3D {
        id: r.track_id as u64 + 1,
        label: r.kind.to_lowercase(),
        center: Some(v3(b.center)),
        size: Some(size3(b.size)),
        yaw: b.yaw,
        velocity: Some(v3([0.0; 3])),
        score: r.score.unwrap_or(0.0),
        image_box: Some(image_box(r.bbox)),
        attributes: attrs(&[
            (attr::TYPE, r.kind.clone()),
            (attr::ALPHA, format!("{}", r.alpha)),
            (attr::TRACK_ID, format!("{}", r.track_id)),
        ]),
        ..Default::default()
    }
}

/// The object types of KITTI's tracking labels (its devkit's readme); the evaluation scores
/// Car and Pedestrian (and Cyclist), with Van and Person_sitting as their neighbours.
pub const KITTI_TYPES: [&str; 9] = [
    "Car",
    "Van",
    "Truck",
    "Pedestrian",
    "Person_sitting",
    "Cyclist",
    "Tram",
    "Misc",
    "DontCare",
];

/// The time base written by `import kitti`: `(first_stamp_ns, frame_period_ns)`, if the file
/// has one.
pub fn kitti_time_base(path: &Path) -> Result<Option<(u64, u64)>> {
    let mut base = None;
    read_records(path, |rec, _| {
        if let mcap::records::Record::Metadata(m) = rec {
            if m.name == KITTI_METADATA {
                let get = |k: &str| -> Result<u64> {
                    m.metadata
                        .get(k)
                        .with_context(|| format!("metadata {KITTI_METADATA} lacks {k}"))?
                        .parse()
                        .with_context(|| format!("metadata {KITTI_METADATA}: bad {k}"))
                };
                let period = get("frame_period_ns")?;
                if period == 0 {
                    bail!("metadata {KITTI_METADATA}: frame_period_ns is 0");
                }
                base = Some((get("first_stamp_ns")?, period));
            }
        }
        Ok(())
    })?;
    Ok(base)
}

/// Whether `import kitti` wrote `path` (it has the `probmot.kitti` metadata record): from the
/// summary's metadata index when the file has one, which reads only the file's ends, else by
/// reading the file.
pub fn is_kitti_import(path: &Path) -> Result<bool> {
    match has_metadata(path, KITTI_METADATA) {
        Some(known) => Ok(known),
        None => Ok(kitti_time_base(path)?.is_some()),
    }
}

/// Counts of an export.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ExportSummary {
    /// Rows written.
    pub rows: u64,
    /// Frames with at least one row.
    pub frames: u64,
    /// What the file may not say as the reader expects (frames numbered by order, types KITTI
    /// does not know).
    pub warnings: Vec<String>,
}

/// How an export numbers its frames: on `import kitti`'s time base, or by the order of the
/// topic's distinct stamps.
enum FrameNumbers {
    /// First stamp and period (not 0) of `import kitti`'s time base.
    TimeBase(u64, u64),
    /// The topic's distinct stamps, sorted: a frame's number is its stamp's index.
    Order(Vec<u64>),
}

impl FrameNumbers {
    /// The frame number of the message stamped `stamp`; a stamp off the time base (or, by
    /// order, one the checking pass did not see) is an error.
    fn number(&self, input: &Path, topic: &str, stamp: u64) -> Result<u32> {
        match self {
            FrameNumbers::TimeBase(first, period) => {
                if stamp < *first || !(stamp - first).is_multiple_of(*period) {
                    bail!(
                        "{}: topic {topic} has a frame at stamp {stamp} ns, not on the KITTI \
                         time base ({first} + k * {period} ns)",
                        input.display()
                    );
                }
                Ok(((stamp - first) / period) as u32)
            }
            FrameNumbers::Order(stamps) => match stamps.binary_search(&stamp) {
                Ok(i) => Ok(i as u32),
                Err(_) => bail!(
                    "{}: topic {topic}: stamp {stamp} was not there on the first read (did the \
                     file change while it was exported?)",
                    input.display()
                ),
            },
        }
    }
}

/// The first pass of an export: every row checked and counted before the output is opened, so
/// a row that cannot be written leaves nothing written, whatever the destination (stdout or a
/// pipe has no partial file to remove). Keeps 8 bytes a frame (the stamps).
fn check_rows(
    input: &Path,
    topic: &str,
    (base, truth): (Option<(u64, u64)>, bool),
    summary: &mut ExportSummary,
    progress: &dyn Fn(u64),
) -> Result<FrameNumbers> {
    let mut stamps = Vec::new();
    let mut unknown_types: BTreeMap<String, u64> = BTreeMap::new();
    let mut flat = 0u64;
    let on_base = base.map(|(first, period)| FrameNumbers::TimeBase(first, period));
    for_each_tracks_frame(input, topic, |stamp, boxes, stats| {
        progress(stats.bytes_read);
        match &on_base {
            Some(numbers) => _ = numbers.number(input, topic, stamp)?,
            None => stamps.push(stamp),
        }
        summary.frames += u64::from(!boxes.is_empty());
        for (i, b) in boxes.iter().enumerate() {
            let row = kitti_row(b, 0, truth);
            if !KITTI_TYPES
                .iter()
                .any(|t| t.eq_ignore_ascii_case(&row.kind))
            {
                *unknown_types.entry(row.kind.clone()).or_default() += 1;
            }
            if !row.is_finite() {
                bail!(
                    "{}: topic {topic}, stamp {stamp}: box {i} ({}, id {}) has a non-finite \
                     number; a KITTI result file cannot hold it",
                    input.display(),
                    b.label,
                    b.id
                );
            }
            flat += u64::from(b.image_box.is_none());
            summary.rows += 1;
        }
        Ok(())
    })?;
    let numbers = match on_base {
        Some(numbers) => numbers,
        None => {
            stamps.sort_unstable();
            stamps.dedup();
            summary.warnings.push(format!(
                "{}: not written by `probmot import kitti` (no KITTI time base): frames are \
                 numbered 0, 1, 2, ... in the order of the {} stamps of topic {topic}",
                input.display(),
                stamps.len()
            ));
            FrameNumbers::Order(stamps)
        }
    };
    summary
        .warnings
        .extend(row_warnings(input, flat, summary.rows, &unknown_types));
    Ok(numbers)
}

/// What an export's rows may not say as a KITTI reader expects: rows without a 2D image box
/// (`flat` of `rows`) and types KITTI's labels do not have.
fn row_warnings(
    input: &Path,
    flat: u64,
    rows: u64,
    unknown_types: &BTreeMap<String, u64>,
) -> Vec<String> {
    let mut warnings = Vec::new();
    if flat > 0 {
        warnings.push(format!(
            "{}: {flat} of {rows} rows have no 2D image box (the log was not imported from KITTI) \
             and are written with 0 0 0 0: KITTI's evaluation reads their height as 0 px and \
             ignores every such track it does not match (`probmot eval --protocol kitti` on the \
             MCAP counts them)",
            input.display(),
        ));
    }
    if !unknown_types.is_empty() {
        let each: Vec<String> = (unknown_types.iter())
            .map(|(t, n)| format!("{t} {n}"))
            .collect();
        warnings.push(format!(
            "{}: rows of types KITTI's labels do not have, written as they are (its evaluation \
             scores Car, Pedestrian and Cyclist): {}",
            input.display(),
            each.join(", ")
        ));
    }
    warnings
}

/// One box as a KITTI row of frame `frame`: a label row for ground truth (`truth`: original
/// id, truncation and occlusion, no score), else a result row.
fn kitti_row(b: &Track3D, frame: u32, truth: bool) -> KittiRow {
    let (c, s) = (b.center.unwrap_or_default(), b.size.unwrap_or_default());
    let bx = Box3 {
        center: [c.x, c.y, c.z],
        yaw: b.yaw,
        size: [s.length, s.width, s.height],
    };
    let (hwl, xyz, ry) = box_to_camera(&bx);
    let a = &b.attributes;
    let parse = |k: &str, d: f64| number_attr(a, k).unwrap_or(d);
    // Imported results (and ground truth) keep their original id in an attribute.
    let own_id = if truth {
        b.id as f64 - 1.0
    } else {
        b.id as f64
    };
    KittiRow {
        frame,
        track_id: parse(attr::TRACK_ID, own_id) as i64,
        kind: (a.get(attr::TYPE).cloned()).unwrap_or_else(|| capitalize(&b.label)),
        truncated: if truth {
            parse(attr::TRUNCATED, 0.0)
        } else {
            0.0
        },
        occluded: if truth {
            parse(attr::OCCLUDED, 0.0) as i64
        } else {
            0
        },
        alpha: parse(attr::ALPHA, -10.0),
        bbox: b.image_box.map_or([0.0; 4], |i| [i.x1, i.y1, i.x2, i.y2]),
        hwl,
        xyz,
        rotation_y: ry,
        score: if truth { None } else { Some(b.score) },
    }
}

/// Writes a `Tracks3D` topic as a KITTI tracking result (or label) file. Type, 2D box, alpha,
/// truncation and occlusion come from the box's `kitti_*` attributes and image box (a track
/// carries those of its last matched detection); missing ones are written as the label with a
/// capital, a zero box, -10 and 0.
///
/// Reads the input twice (checking every row, then writing): `progress` gets the bytes read so
/// far over both passes, out of twice the file's size.
pub fn export_kitti(
    input: &Path,
    topic: &str,
    output: &Path,
    scores: bool,
    progress: &dyn Fn(u64),
) -> Result<ExportSummary> {
    check_output_path(Some(input), output)?;
    let base = kitti_time_base(input)?;
    let mut summary = ExportSummary::default();
    let truth = topic != "/tracks" && !scores;
    let size = std::fs::metadata(input).map_or(0, |m| m.len());
    let numbers = check_rows(input, topic, (base, truth), &mut summary, progress)?;
    // The rows go straight to the output, a message at a time (an hour-long log's text is
    // hundreds of megabytes).
    write_file_atomic_with(output, |w| {
        for_each_tracks_frame(input, topic, |stamp, boxes, stats| {
            progress(size + stats.bytes_read);
            let frame = numbers.number(input, topic, stamp)?;
            for b in &boxes {
                writeln!(w, "{}", format_row(&kitti_row(b, frame, truth)))
                    .with_context(|| format!("writing {}", output.display()))?;
            }
            Ok(())
        })
    })?;
    Ok(summary)
}

fn capitalize(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_uppercase().collect::<String>() + c.as_str(),
        None => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first lines of the files a KITTI tracking folder holds: labels, calibration and
    /// oxts are other files; PointRCNN detections (and anything else) are not.
    #[test]
    fn other_kitti_files_are_told_from_detections_by_their_first_line() {
        let others = [
            "0 -1 DontCare -1 -1 -10.000000 219.310000 188.490000 245.500000 218.560000 \
             -1000.000000 -1000.000000 -1000.000000 -10.000000 -1.000000 -1.000000 -1.000000",
            "P0: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 \
             7.215377e+02 1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 \
             0.000000e+00",
            "R_rect 9.999239e-01 9.837760e-03 -7.445048e-03 -9.869795e-03 9.999421e-01 \
             -4.278459e-03 7.402527e-03 4.351614e-03 9.999631e-01",
            "Tr_velo_cam 7.533745e-03 -9.999714e-01 -6.166020e-04 -4.069766e-03 1.480249e-02 \
             7.280733e-04 -9.998902e-01 -7.631618e-02 9.998621e-01 7.523790e-03 1.480755e-02 \
             -2.717806e-01",
            "49.015003823272 8.4342971002335 113.87133789062 0.022100000000000 \
             -0.0093 -1.3946 0.79 -5.4 0.56 0.77 0.37 -0.21 -0.79 -0.05 -0.43 0.01 -0.05 \
             0.08 1.3 0.3 0.46 0.4 0.3 4 10 4 4 1 1 0",
        ];
        for line in others {
            assert!(is_other_kitti_line(line), "{line}");
        }
        let not = [
            "0,2,296.7,161.8,455.2,292.2,8.8,2.0,1.8,4.4,-3.7,1.8,13.2,-1.7,-1.5",
            "\u{feff}0,2,296.7,161.8,455.2,292.2,8.8,2.0,1.8,4.4,-3.7,1.8,13.2,-1.7,-1.5",
            "Error: 1 2 3 4 5 6 7 8 9",
            "frame: 0",
            "P0: not numbers",
        ];
        for line in not {
            assert!(!is_other_kitti_line(line), "{line}");
        }
    }

    #[test]
    fn numeric_attributes_read_as_python_floats() {
        let attrs: BTreeMap<String, String> = [("a", " 7 "), ("b", "2.9"), ("c", "x"), ("d", "-1")]
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        assert_eq!(number_attr(&attrs, "a"), Some(7.0));
        assert_eq!(number_attr(&attrs, "b"), Some(2.9));
        assert_eq!(number_attr(&attrs, "c"), None);
        assert_eq!(number_attr(&attrs, "d"), Some(-1.0));
        assert_eq!(number_attr(&attrs, "e"), None);
        let b = LabelledBox {
            id: 5,
            attributes: attrs,
            ..Default::default()
        };
        assert_eq!(truth_track_id(&b), 4, "no kitti_track_id: id - 1");
    }
}
