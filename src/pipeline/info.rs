//! `probmot info`: what a recording holds, per channel, and which channels probmot can use.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use anyhow::Result;
use mcap::records::Record;

use crate::mcapio::reader::read_records;
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
    /// The transform tree read from the transform channels (see [`crate::transforms`]).
    pub transform_tree: Vec<EdgeSummary>,
}

/// Reads the whole file and summarises it.
pub fn file_info(path: &Path) -> Result<FileSummary> {
    let mut out = FileSummary {
        path: path.display().to_string(),
        ..Default::default()
    };
    let mut schemas: HashMap<u16, (String, String, Vec<u8>)> = HashMap::new();
    let mut channels: BTreeMap<u16, ChannelSummary> = BTreeMap::new();
    let mut sources: HashMap<u16, DetectionSource> = HashMap::new();
    let mut transforms = TransformCollector::new();
    let file = path.display().to_string();
    read_records(path, |rec, _| {
        match rec {
            Record::Header(h) => {
                out.profile = h.profile;
                out.library = h.library;
            }
            Record::Schema { header, data } => {
                schemas.insert(header.id, (header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                let (schema, schema_encoding, schema_data) =
                    schemas.get(&c.schema_id).cloned().unwrap_or_default();
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
                let tracks = schema == msgs::TRACKS_SCHEMA
                    && Encoding::from_message_encoding(&c.message_encoding).is_some();
                let is_transform = transforms.on_channel(&c, &schema).is_some();
                let role = match source {
                    Ok(s) => {
                        sources.insert(c.id, s);
                        "detections"
                    }
                    Err(_) if tracks => "tracks",
                    Err(_) if is_transform => "transforms",
                    Err(_) => "",
                };
                let default_candidate = is_default_candidate(&schema, &c.metadata);
                channels.entry(c.id).or_insert(ChannelSummary {
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
            Record::Message { header, data } => {
                out.messages += 1;
                if let Some(ch) = channels.get_mut(&header.channel_id) {
                    ch.messages += 1;
                    let t = header.log_time;
                    ch.log_time_range = Some(match ch.log_time_range {
                        Some((a, b)) => (a.min(t), b.max(t)),
                        None => (t, t),
                    });
                    if transforms.on_message(&file, &header, &data) {
                        ch.undecodable = transforms
                            .per_topic
                            .get(&ch.topic)
                            .map_or(0, |c| c.undecodable);
                    }
                    let enc = Encoding::from_message_encoding(&ch.message_encoding);
                    let source = sources.get(&header.channel_id);
                    match (ch.role.as_str(), enc, source) {
                        ("detections", _, Some(source)) => match source.decode(&data) {
                            Ok(m) => {
                                for d in m.detections {
                                    *ch.per_label.entry(d.label).or_default() += 1;
                                }
                            }
                            Err(_) => ch.undecodable += 1,
                        },
                        ("tracks", Some(enc), _) => match msgs::decode::<Tracks3D>(&data, enc) {
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
            }
            Record::Attachment { .. } => out.attachments += 1,
            Record::Metadata(_) => out.metadata += 1,
            _ => {}
        }
        Ok(())
    })?;
    // `track`'s default selection: a SceneUpdate only when nothing else is there.
    let left_out = scenes_left_out(
        sources
            .iter()
            .filter(|(id, _)| channels.get(id).is_some_and(|c| c.default_detections))
            .map(|(id, s)| (*id, s)),
    );
    for id in left_out {
        if let Some(c) = channels.get_mut(&id) {
            c.default_detections = false;
        }
    }
    out.channels = channels.into_values().collect();
    transforms.finish();
    out.transform_tree = transforms.buffer.summary();
    Ok(out)
}
