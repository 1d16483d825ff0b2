//! The harness of the `read_path` target: arbitrary bytes as an MCAP file, read from memory
//! (no file anywhere) by the record reader, `track` (into an MCAP written in memory) and `info`.

use std::collections::BTreeMap;
use std::io::Cursor;

use anyhow::Result;
use mcap::records::{MessageHeader, Metadata};
use probmot::mcapio::reader::{read_records_from, McapInput};
use probmot::mcapio::sink::RecordSink;
use probmot::mcapio::source::RecordSource;
use probmot::pipeline::info::file_info_from;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track::{track_input, TrackOptions};
use probmot::tracker::TrackerConfig;

use crate::DEFAULT_PRESET;

/// An MCAP file written into memory, started again on [`RecordSink::restart`].
pub struct McapInMemory {
    writer: mcap::Writer<Cursor<Vec<u8>>>,
}

impl McapInMemory {
    /// An empty MCAP file with the header profile `profile`.
    pub fn new(profile: &str) -> Result<Self> {
        let writer = mcap::WriteOptions::new()
            .profile(profile)
            .create(Cursor::new(Vec::new()))?;
        Ok(McapInMemory { writer })
    }

    /// The finished file's bytes.
    pub fn finish(mut self) -> Result<Vec<u8>> {
        self.writer.finish()?;
        Ok(self.writer.into_inner().into_inner())
    }
}

impl RecordSink for McapInMemory {
    fn add_schema_with_id(&mut self, id: u16, name: &str, enc: &str, data: &[u8]) -> Result<()> {
        self.writer.add_schema_with_id(id, name, enc, data)?;
        Ok(())
    }

    fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<()> {
        (self.writer).add_channel_with_id(id, schema_id, topic, encoding, metadata)?;
        Ok(())
    }

    fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()> {
        Ok(self.writer.write_to_known_channel(header, data)?)
    }

    fn attach(&mut self, a: &mcap::Attachment) -> Result<()> {
        Ok(self.writer.attach(a)?)
    }

    fn write_metadata(&mut self, m: &Metadata) -> Result<()> {
        Ok(self.writer.write_metadata(m)?)
    }

    fn restart(&mut self) -> Result<()> {
        *self = McapInMemory::new("")?;
        Ok(())
    }
}

/// `input` through `track_input` (default options and preset) into an MCAP in memory. Errors
/// are fine; when it succeeds, its output must be readable again.
pub fn track_and_read_back(input: &mut impl RecordSource) {
    let opts = TrackOptions::new(TrackerConfig::preset(DEFAULT_PRESET).expect("default preset"));
    let open = |profile: String| McapInMemory::new(&profile);
    match track_input(input, &opts, &no_progress, open) {
        Ok((out, summary)) => {
            std::hint::black_box(serde_json::to_string(&summary).expect("summary serializes"));
            let bytes = out.finish().expect("track's output finishes");
            let mut output = McapInput::from_bytes("output.mcap", &bytes);
            if let Err(e) = read_records_from(&mut output, |_, _| Ok(())) {
                panic!("track wrote an output read_records cannot read: {e:#}");
            }
        }
        Err(e) => {
            std::hint::black_box(format!("{e:#}"));
        }
    }
}

/// `data` through the whole read path. Errors are fine; panics are not, and when `track`
/// succeeds its output must be readable again.
pub fn read_path(data: &[u8]) {
    let mut records = 0u64;
    let mut input = McapInput::from_bytes("input.mcap", data);
    let _ = read_records_from(&mut input, |rec, stats| {
        records += 1;
        std::hint::black_box((&rec, stats.bytes_read));
        Ok(())
    });
    std::hint::black_box(records);

    track_and_read_back(&mut McapInput::from_bytes("input.mcap", data));

    let mut input = McapInput::from_bytes("input.mcap", data);
    if let Ok(info) = file_info_from(&mut input, &|_| {}) {
        std::hint::black_box(serde_json::to_string(&info).expect("info serializes"));
    }
}
