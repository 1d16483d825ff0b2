//! The MCAP conformance corpus through the copy path of `probmot track`: every schema, channel,
//! message, attachment and metadata record listed in each file's `.json` must come out unchanged.
//! Reads `../shared/data/mcap-conformance/` beside the repository; skips when it is absent.

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mcap::records::Record;
use probmot::mcapio::reader::read_records;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track::{track_file, SceneOutput, TrackOptions};
use probmot::tracker::TrackerConfig;
use serde_json::Value;

#[derive(Debug, Default, PartialEq)]
struct Content {
    schemas: Vec<(String, String, Vec<u8>)>,
    channels: Vec<(String, String, BTreeMap<String, String>, String)>,
    messages: Vec<(String, u64, u64, u32, Vec<u8>)>,
    attachments: Vec<(String, String, u64, u64, Vec<u8>)>,
    metadata: Vec<(String, BTreeMap<String, String>)>,
}

impl Content {
    fn normalise(&mut self) {
        self.schemas.sort();
        self.schemas.dedup();
        self.channels.sort();
        self.channels.dedup();
        self.messages.sort();
        self.attachments.sort();
        self.metadata.sort();
    }
}

fn field<'a>(rec: &'a Value, name: &str) -> &'a Value {
    rec["fields"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f[0] == name)
        .map(|f| &f[1])
        .unwrap_or_else(|| panic!("no field {name} in {rec}"))
}

fn num(v: &Value) -> u64 {
    v.as_str().unwrap().parse().unwrap()
}

fn bytes(v: &Value) -> Vec<u8> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_str().unwrap().parse().unwrap())
        .collect()
}

fn text(v: &Value) -> String {
    v.as_str().unwrap().to_string()
}

fn map(v: &Value) -> BTreeMap<String, String> {
    v.as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), text(v)))
        .collect()
}

/// What the conformance `.json` says the file holds.
fn expected(json: &Path) -> Content {
    let v: Value = serde_json::from_slice(&std::fs::read(json).unwrap()).unwrap();
    let mut schemas: BTreeMap<u64, (String, String, Vec<u8>)> = BTreeMap::new();
    let mut channels: BTreeMap<u64, (String, String, BTreeMap<String, String>, String)> =
        BTreeMap::new();
    let mut c = Content::default();
    for r in v["records"].as_array().unwrap() {
        match r["type"].as_str().unwrap() {
            "Schema" => {
                let s = (
                    text(field(r, "name")),
                    text(field(r, "encoding")),
                    bytes(field(r, "data")),
                );
                schemas.insert(num(field(r, "id")), s.clone());
                c.schemas.push(s);
            }
            "Channel" => {
                let schema_id = num(field(r, "schema_id"));
                let schema_name = schemas
                    .get(&schema_id)
                    .map(|s| s.0.clone())
                    .unwrap_or_default();
                let ch = (
                    text(field(r, "topic")),
                    text(field(r, "message_encoding")),
                    map(field(r, "metadata")),
                    schema_name,
                );
                channels.insert(num(field(r, "id")), ch.clone());
                c.channels.push(ch);
            }
            "Message" => {
                let ch = &channels[&num(field(r, "channel_id"))];
                c.messages.push((
                    ch.0.clone(),
                    num(field(r, "log_time")),
                    num(field(r, "publish_time")),
                    num(field(r, "sequence")) as u32,
                    bytes(field(r, "data")),
                ));
            }
            "Attachment" => c.attachments.push((
                text(field(r, "name")),
                text(field(r, "media_type")),
                num(field(r, "log_time")),
                num(field(r, "create_time")),
                bytes(field(r, "data")),
            )),
            "Metadata" => c
                .metadata
                .push((text(field(r, "name")), map(field(r, "metadata")))),
            _ => {}
        }
    }
    c.normalise();
    c
}

/// What a file written by probmot holds, read back with our streaming reader.
fn actual(path: &Path) -> Content {
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    let mut c = Content::default();
    read_records(path, |rec, _| {
        match rec {
            Record::Schema { header, data } => {
                schemas.insert(header.id, header.name.clone());
                c.schemas
                    .push((header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(ch) => {
                topics.insert(ch.id, ch.topic.clone());
                c.channels.push((
                    ch.topic,
                    ch.message_encoding,
                    ch.metadata,
                    schemas.get(&ch.schema_id).cloned().unwrap_or_default(),
                ));
            }
            Record::Message { header, data } => c.messages.push((
                topics[&header.channel_id].clone(),
                header.log_time,
                header.publish_time,
                header.sequence,
                data.into_owned(),
            )),
            Record::Attachment { header, data, .. } => c.attachments.push((
                header.name,
                header.media_type,
                header.log_time,
                header.create_time,
                data.into_owned(),
            )),
            Record::Metadata(m) => c.metadata.push((m.name, m.metadata)),
            _ => {}
        }
        Ok(())
    })
    .unwrap();
    c.normalise();
    c
}

fn corpus() -> Option<Vec<PathBuf>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/mcap-conformance");
    if !dir.is_dir() {
        common::skip(
            "copy_path_keeps_every_record_of_the_conformance_corpus",
            &format!(
                "{} is absent; the conformance test needs the MCAP conformance corpus",
                dir.display()
            ),
        );
        return None;
    }
    let mut files = Vec::new();
    for sub in std::fs::read_dir(&dir).unwrap() {
        let sub = sub.unwrap().path();
        if sub.is_dir() {
            for f in std::fs::read_dir(&sub).unwrap() {
                let f = f.unwrap().path();
                if f.extension().is_some_and(|e| e == "mcap") {
                    files.push(f);
                }
            }
        }
    }
    files.sort();
    Some(files)
}

#[test]
fn copy_path_keeps_every_record_of_the_conformance_corpus() {
    let Some(files) = corpus() else { return };
    assert!(files.len() >= 400, "only {} files found", files.len());
    let dir = tempfile::tempdir().unwrap();
    let opts = TrackOptions {
        detection_topics: vec![],
        tracks_topic: None,
        tracks_format: None,
        config: TrackerConfig::preset("nuscenes-chiu2019").unwrap(),
        no_track: false,
        strict: false,
        max_detections_per_message: 100_000,
        ego: Default::default(),
        scene: SceneOutput::Off,
        compression: Default::default(),
        background_writer: true,
    };
    let mut failures = Vec::new();
    for (i, f) in files.iter().enumerate() {
        let out = dir.path().join(format!("{i}.mcap"));
        let summary = match track_file(f, &out, &opts, &no_progress) {
            Ok(s) => s,
            Err(e) => {
                failures.push(format!("{}: cannot be copied: {e:#}", f.display()));
                continue;
            }
        };
        // No detection channel: a warning, not an error.
        assert!(
            summary
                .warnings
                .iter()
                .any(|w| w.contains("no detection channel")),
            "{}: {:?}",
            f.display(),
            summary.warnings
        );
        let want = expected(&f.with_extension("json"));
        let got = actual(&out);
        if want != got {
            failures.push(format!(
                "{}: content differs\n  expected {want:?}\n  got      {got:?}",
                f.display()
            ));
        }
        // The output is a valid, seekable MCAP.
        let bytes = std::fs::read(&out).unwrap();
        if let Err(e) = mcap::Summary::read(&bytes) {
            failures.push(format!("{}: output summary unreadable: {e}", f.display()));
        }
        std::fs::remove_file(&out).unwrap();
    }
    eprintln!(
        "conformance: {} files copied, {} failures",
        files.len(),
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
