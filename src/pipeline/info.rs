//! `probmot info`: what a recording holds, per channel, and which channels probmot can use.

use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::Path;

use anyhow::Result;
use mcap::records::Record;

use std::ops::ControlFlow;

use super::bag_source::BagSource;
use super::db3_file::is_sqlite_file;
use super::progress::{Progress, ProgressFn};
use super::rosbag_dir::open_bag;
use crate::mcapio::reader::{read_records_to_cut, CutShort, McapInput};
use crate::mcapio::source::{OnRecord, RecordSource};
use crate::msgs::autoware_tracks::{self, KinematicsOrder};
use crate::msgs::detection_source::{
    is_default_candidate, is_detection_schema, scenes_left_out, DetectionSource,
};
use crate::msgs::{self, Encoding, Tracks3D};
use crate::transforms::buffer::EdgeSummary;
use crate::transforms::TransformCollector;

/// One channel of a recording.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ChannelSummary {
    /// Channel id.
    pub id: u16,
    /// Topic.
    pub topic: String,
    /// Schema name (empty for schemaless channels).
    pub schema: String,
    /// Schema encoding.
    pub schema_encoding: String,
    /// Message encoding.
    pub message_encoding: String,
    /// Messages on the channel.
    pub messages: u64,
    /// Earliest and latest log_time, ns.
    pub log_time_range: Option<(u64, u64)>,
    /// What probmot can do with it: "detections", "tracks", or empty.
    pub role: String,
    /// Detection channels: how they are read (e.g. `vision_msgs/msg/Detection3DArray (cdr,
    /// vision_msgs 4.x layout)`); other channels: why they are not read as detections.
    pub detections_note: String,
    /// Detection channels: whether `track` reads it without `--detections-topic` (not for
    /// probmot's own outputs, nor for a SceneUpdate beside other detection channels).
    pub default_detections: bool,
    /// For detection and track channels: boxes per label.
    pub per_label: BTreeMap<String, u64>,
    /// Messages of a detections/tracks channel that failed to decode.
    pub undecodable: u64,
    /// Boxes of a detections channel that `track` skips because their label or id is not
    /// UTF-8 (the rest of their message is read; not in `per_label`).
    pub boxes_not_utf8: u64,
}

/// The whole file.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct FileSummary {
    /// Path.
    pub path: String,
    /// Header profile.
    pub profile: String,
    /// Header library.
    pub library: String,
    /// Channels by id.
    pub channels: Vec<ChannelSummary>,
    /// Attachments.
    pub attachments: u64,
    /// Metadata records.
    pub metadata: u64,
    /// All messages.
    pub messages: u64,
    /// Earliest and latest message log_time of the file, ns.
    pub log_time_range: Option<(u64, u64)>,
    /// The transform tree read from the transform channels (see [`crate::transforms`]).
    pub transform_tree: Vec<EdgeSummary>,
    /// Files cut short (recordings that did not finish): what is summarised here is what they
    /// hold up to the cut. (Left out of the JSON when empty.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub cut_short: Vec<CutShort>,
    /// What the reader of the recording warns of (e.g. a bag read without its
    /// `metadata.yaml`). (Left out of the JSON when empty.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Reads the whole file and summarises it.
pub fn file_info(path: &Path) -> Result<FileSummary> {
    file_info_progress(path, &|_| {})
}

/// [`file_info`], telling `progress` the bytes read at each step. Memory stays bounded by the
/// number of channels and labels, whatever the file's length.
pub fn file_info_progress(path: &Path, progress: &dyn Fn(u64)) -> Result<FileSummary> {
    file_info_from(&mut McapInput::open(path)?, progress)
}

/// [`file_info_progress`] of a file or of a rosbag2 bag directory: a bag's files (split or
/// compressed) are read as one drive, its schema and channel ids as one numbering
/// ([`super::bag_source`]).
pub fn path_info(path: &Path, progress: &dyn Fn(u64)) -> Result<FileSummary> {
    let (mut source, warning) = if is_sqlite_file(path) {
        (BagSource::sqlite_file(path), None)
    } else {
        match open_bag(path)? {
            Some(bag) => (BagSource::of(&bag), bag.warning()),
            None => return file_info_progress(path, progress),
        }
    };
    let name = source.name.clone();
    let mut info = info_of(name, |f| source.read_while(f), progress)?;
    info.warnings.extend(warning);
    Ok(info)
}

/// [`path_info`] as `probmot info` reads it: a file, or a rosbag2 bag directory as one drive.
/// Progress: bytes read of the total size of its files.
pub fn recording_info(path: &Path, progress: ProgressFn<'_>) -> Result<FileSummary> {
    let size = super::rosbag_dir::input_files(path)?
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    progress(Progress::Length(size));
    let info = path_info(path, &|n| progress(Progress::Advance(n)))?;
    progress(Progress::Done);
    Ok(info)
}

/// [`file_info_progress`] of any input (a file, bytes in memory), named by its name.
pub fn file_info_from<R: Read>(
    input: &mut McapInput<R>,
    progress: &dyn Fn(u64),
) -> Result<FileSummary> {
    let name = input.name.clone();
    info_of(
        name,
        |f| Ok(read_records_to_cut(input, f)?.into_iter().collect()),
        progress,
    )
}

/// The summary of the records `read` hands to its callback, from an input named `name`.
fn info_of(
    name: String,
    read: impl FnOnce(&mut OnRecord<'_>) -> Result<Vec<CutShort>>,
    progress: &dyn Fn(u64),
) -> Result<FileSummary> {
    let mut st = InfoState {
        out: FileSummary {
            path: name.clone(),
            ..Default::default()
        },
        file: name,
        schemas: HashMap::new(),
        channels: BTreeMap::new(),
        sources: HashMap::new(),
        autoware_tracks: HashMap::new(),
        transforms: TransformCollector::new(),
    };
    let mut reported = 0u64;
    let cuts = read(&mut |rec, stats| {
        progress(stats.bytes_read.saturating_sub(reported));
        reported = reported.max(stats.bytes_read);
        match rec {
            Record::Header(h) => {
                st.out.profile = h.profile;
                st.out.library = h.library;
            }
            Record::Schema { header, data } => {
                let schema = (header.name, header.encoding, data.into_owned());
                st.schemas.insert(header.id, schema);
            }
            Record::Channel(c) => st.on_channel(c),
            Record::Message { header, data } => st.on_message(&header, &data),
            Record::Attachment { .. } => st.out.attachments += 1,
            Record::Metadata(_) => st.out.metadata += 1,
            _ => {}
        }
        Ok(ControlFlow::Continue(()))
    })?;
    st.out.cut_short = cuts;
    Ok(st.finish())
}

/// What [`file_info_progress`] keeps while reading.
struct InfoState {
    out: FileSummary,
    file: String,
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channels: BTreeMap<u16, ChannelSummary>,
    sources: HashMap<u16, DetectionSource>,
    /// Channels of Autoware `TrackedObjects` tracks, with their kinematics field order.
    autoware_tracks: HashMap<u16, KinematicsOrder>,
    transforms: TransformCollector,
}

impl InfoState {
    /// A channel record: its role (detections, tracks, transforms) and summary.
    fn on_channel(&mut self, c: mcap::records::Channel) {
        let (schema, schema_encoding, schema_data) =
            self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
        let source = DetectionSource::for_channel(
            &schema,
            &schema_encoding,
            &schema_data,
            &c.message_encoding,
        );
        let detections_note = match &source {
            Ok(s) => s.describe(),
            Err(_) if !is_detection_schema(&schema) => "not a detection schema".to_string(),
            Err(why) => why.clone(),
        };
        let autoware_tracks = autoware_tracks::layout_for_channel(
            &schema,
            &schema_encoding,
            &schema_data,
            &c.message_encoding,
        );
        if let Some(Ok(order)) = autoware_tracks {
            self.autoware_tracks.insert(c.id, order);
        }
        let tracks = schema == msgs::TRACKS_SCHEMA
            && Encoding::from_message_encoding(&c.message_encoding).is_some()
            || matches!(autoware_tracks, Some(Ok(_)));
        let is_transform = self.transforms.on_channel(&c, &schema).is_some();
        let role = match source {
            Ok(s) => {
                self.sources.insert(c.id, s);
                "detections"
            }
            Err(_) if tracks => "tracks",
            Err(_) if is_transform => "transforms",
            Err(_) => "",
        };
        let default_candidate = is_default_candidate(&schema, &c.metadata);
        self.channels.entry(c.id).or_insert(ChannelSummary {
            default_detections: role == "detections" && default_candidate,
            id: c.id,
            topic: c.topic,
            schema,
            schema_encoding,
            message_encoding: c.message_encoding,
            role: role.into(),
            detections_note,
            ..Default::default()
        });
    }

    /// A message: counts, time range, transforms and boxes per label.
    fn on_message(&mut self, header: &mcap::records::MessageHeader, data: &[u8]) {
        self.out.messages += 1;
        let Some(ch) = self.channels.get_mut(&header.channel_id) else {
            return;
        };
        ch.messages += 1;
        let t = header.log_time;
        ch.log_time_range = Some(match ch.log_time_range {
            Some((a, b)) => (a.min(t), b.max(t)),
            None => (t, t),
        });
        if self.transforms.on_message(&self.file, header, data) {
            ch.undecodable = self
                .transforms
                .per_topic
                .get(&ch.topic)
                .map_or(0, |c| c.undecodable);
        }
        let enc = Encoding::from_message_encoding(&ch.message_encoding);
        let source = self.sources.get(&header.channel_id);
        match (ch.role.as_str(), enc, source) {
            ("detections", _, Some(source)) => match source.decode_kept(data) {
                Ok((m, skipped)) => {
                    ch.boxes_not_utf8 += skipped.len() as u64;
                    for d in m.detections {
                        *ch.per_label.entry(d.label).or_default() += 1;
                    }
                }
                Err(_) => ch.undecodable += 1,
            },
            ("tracks", _, _) if self.autoware_tracks.contains_key(&header.channel_id) => {
                let order = self.autoware_tracks[&header.channel_id];
                match autoware_tracks::decode_tracks(data, order) {
                    Ok(m) => {
                        for t in m.tracks {
                            *ch.per_label.entry(t.label).or_default() += 1;
                        }
                    }
                    Err(_) => ch.undecodable += 1,
                }
            }
            ("tracks", Some(enc), _) => match msgs::decode::<Tracks3D>(data, enc) {
                Ok(m) => {
                    for t in m.tracks {
                        *ch.per_label.entry(t.label).or_default() += 1;
                    }
                }
                Err(_) => ch.undecodable += 1,
            },
            _ => {}
        }
    }

    /// The summary: `track`'s default selection, the time range and the transform tree.
    fn finish(mut self) -> FileSummary {
        // `track`'s default selection: a SceneUpdate only when nothing else is there.
        let left_out = scenes_left_out(
            self.sources
                .iter()
                .filter(|(id, _)| self.channels.get(id).is_some_and(|c| c.default_detections))
                .map(|(id, s)| (*id, s)),
        );
        for id in left_out {
            if let Some(c) = self.channels.get_mut(&id) {
                c.default_detections = false;
            }
        }
        let mut out = self.out;
        out.channels = self.channels.into_values().collect();
        out.log_time_range = out
            .channels
            .iter()
            .filter_map(|c| c.log_time_range)
            .reduce(|(a0, a1), (b0, b1)| (a0.min(b0), a1.max(b1)));
        self.transforms.finish();
        out.transform_tree = self.transforms.buffer.summary();
        out
    }
}

/// A time in ns since the Unix epoch as ISO 8601 UTC with nanoseconds, as `mcap info` prints
/// it: `2023-11-14T22:13:20.000000000Z`.
pub fn iso8601(ns: u64) -> String {
    let secs = ns / 1_000_000_000;
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:09}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60,
        ns % 1_000_000_000
    )
}

/// Year, month, day of a count of days since 1970-01-01 in the proleptic Gregorian calendar
/// (the era arithmetic of H. Hinnant, "chrono-Compatible Low-Level Date Algorithms").
fn civil_from_days(days: u64) -> (u64, u64, u64) {
    let z = days + 719_468; // days since 0000-03-01
    let era = z / 146_097;
    let doe = z % 146_097; // day of the 400-year era
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of the year starting 1 March
    let mp = (5 * doy + 2) / 153; // month, March = 0
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + u64::from(m <= 2);
    (y, m, d)
}

/// A duration in ns as seconds with millisecond precision (`19.500s`), as `mcap info` prints it.
pub fn duration(ns: u64) -> String {
    format!(
        "{}.{:03}s",
        ns / 1_000_000_000,
        ns % 1_000_000_000 / 1_000_000
    )
}

#[cfg(test)]
mod time_tests {
    use super::*;

    /// Expected values from Python's `datetime.fromtimestamp(s, timezone.utc)`.
    #[test]
    fn iso8601_matches_python_datetime() {
        for (s, want) in [
            (0, "1970-01-01T00:00:00"),
            (951_782_400, "2000-02-29T00:00:00"),
            (1_672_531_200, "2023-01-01T00:00:00"),
            (1_700_000_000, "2023-11-14T22:13:20"),
            (4_102_444_799, "2099-12-31T23:59:59"),
        ] {
            assert_eq!(iso8601(s * 1_000_000_000 + 5), format!("{want}.000000005Z"));
        }
    }

    #[test]
    fn duration_in_seconds_with_milliseconds() {
        assert_eq!(duration(19_500_000_000), "19.500s");
        assert_eq!(duration(999_999), "0.000s");
    }
}
