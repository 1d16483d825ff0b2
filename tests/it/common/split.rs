//! Splitting a one-file MCAP recording into a rosbag2 bag directory of several files, as
//! `ros2 bag record --max-bag-size` does, for the property test of tests/it/split_bags.rs: each
//! part a complete MCAP file with the schemas and channels of the messages in it, numbered anew
//! in each part in the order they are first used there (so a topic may have another id in the
//! next file, as rosbag2 does), and a `metadata.yaml` listing the parts.

use std::collections::HashMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Writes the messages of `input` (in file order, with its profile) into the bag directory `out` (created), a new
/// file starting at each of the message indices `starts` (ascending, within 1..messages):
/// `out/NAME_0.mcap`, `out/NAME_1.mcap`, … where NAME is `out`'s name. Returns the files.
pub fn split_mcap(input: &Path, out: &Path, starts: &[usize]) -> Vec<PathBuf> {
    let bytes = std::fs::read(input).unwrap();
    let messages: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    assert!(
        starts.windows(2).all(|w| w[0] < w[1]),
        "ascending: {starts:?}"
    );
    assert!(starts.iter().all(|&s| 0 < s && s < messages.len()));
    let profile = match mcap::read::LinearReader::new(&bytes).unwrap().next() {
        Some(Ok(mcap::records::Record::Header(h))) => h.profile,
        _ => String::new(),
    };
    std::fs::create_dir(out).unwrap();
    let name = out.file_name().unwrap().to_str().unwrap().to_string();
    let bounds: Vec<usize> = (std::iter::once(0).chain(starts.iter().copied()))
        .chain(std::iter::once(messages.len()))
        .collect();
    let mut files = Vec::new();
    for (i, part) in bounds.windows(2).enumerate() {
        let path = out.join(format!("{name}_{i}.mcap"));
        write_part(&path, &profile, &messages[part[0]..part[1]]);
        files.push(path);
    }
    write_metadata(out, &files);
    files
}

/// One part (with the input's `profile`): its own schema and channel records, ids in the order
/// of first use.
fn write_part(path: &Path, profile: &str, messages: &[mcap::Message]) {
    let file = BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile(profile)
        .library("probmot tests/it/common/split.rs")
        .create(file)
        .unwrap();
    let mut schemas: HashMap<u16, u16> = HashMap::new();
    let mut channels: HashMap<u16, u16> = HashMap::new();
    for m in messages {
        let c = &m.channel;
        let channel = match channels.get(&c.id) {
            Some(&id) => id,
            None => {
                let schema = match &c.schema {
                    None => 0,
                    Some(s) => match schemas.get(&s.id) {
                        Some(&id) => id,
                        None => {
                            let id = w.add_schema(&s.name, &s.encoding, &s.data).unwrap();
                            schemas.insert(s.id, id);
                            id
                        }
                    },
                };
                let id =
                    (w.add_channel(schema, &c.topic, &c.message_encoding, &c.metadata)).unwrap();
                channels.insert(c.id, id);
                id
            }
        };
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
        };
        w.write_to_known_channel(&header, &m.data).unwrap();
    }
    w.finish().unwrap();
}

/// A `metadata.yaml` with the fields probmot and rosbags need to find the files.
fn write_metadata(dir: &Path, files: &[PathBuf]) {
    let mut yaml = String::from(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  \
         compression_format: ''\n  compression_mode: ''\n  relative_file_paths:\n",
    );
    for f in files {
        let name = f.file_name().unwrap().to_str().unwrap();
        yaml.push_str(&format!("    - {name}\n"));
    }
    std::fs::write(dir.join("metadata.yaml"), yaml).unwrap();
}
