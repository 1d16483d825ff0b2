//! Where a track session's records go: the output file ([`BackgroundOutput`]) or, in tests, a
//! list in memory. The session itself does no I/O.

use std::collections::BTreeMap;

use anyhow::Result;
use mcap::records::{MessageHeader, Metadata};

use super::background::BackgroundOutput;

/// A writer of MCAP records with caller-chosen schema and channel ids.
pub trait RecordSink {
    /// Adds a schema record with the given id.
    fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<()>;
    /// Adds a channel record with the given id.
    fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<()>;
    /// Writes a message on a channel added before.
    fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()>;
    /// Writes a message on a channel added before, its bytes appended by `encode` to the buffer
    /// it is given. `encode` must only append (the buffer may hold other bytes before it): a
    /// batching sink has it write straight into its batch; by default the bytes are written
    /// into `scratch` (cleared first) and then as [`RecordSink::write_to_known_channel`].
    fn write_encoded(
        &mut self,
        header: &MessageHeader,
        scratch: &mut Vec<u8>,
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> Result<()> {
        scratch.clear();
        encode(scratch);
        self.write_to_known_channel(header, scratch)
    }
    /// Writes an attachment.
    fn attach(&mut self, a: &mcap::Attachment) -> Result<()>;
    /// Writes a metadata record.
    fn write_metadata(&mut self, m: &Metadata) -> Result<()>;
    /// The input moves on to its next file (a split rosbag2 bag): the records that follow go to
    /// the next output file, if the sink writes one per input file; by default one output
    /// takes them all.
    fn next_part(&mut self) -> Result<()> {
        Ok(())
    }
    /// Forgets everything written so far: the output starts again, empty (when a single pass
    /// over the input turns out to need two).
    fn restart(&mut self) -> Result<()>;
}

impl RecordSink for BackgroundOutput {
    fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<()> {
        BackgroundOutput::add_schema_with_id(self, id, name, encoding, data)
    }

    fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<()> {
        BackgroundOutput::add_channel_with_id(self, id, schema_id, topic, encoding, metadata)
    }

    fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()> {
        BackgroundOutput::write_to_known_channel(self, header, data)
    }

    fn write_encoded(
        &mut self,
        header: &MessageHeader,
        _: &mut Vec<u8>,
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> Result<()> {
        self.write_encoded_to_known_channel(header, encode)
    }

    fn attach(&mut self, a: &mcap::Attachment) -> Result<()> {
        BackgroundOutput::attach(self, a)
    }

    fn write_metadata(&mut self, m: &Metadata) -> Result<()> {
        BackgroundOutput::write_metadata(self, m)
    }

    fn restart(&mut self) -> Result<()> {
        BackgroundOutput::restart(self)
    }
}

/// One record written to a [`MemorySink`].
#[derive(Debug, Clone, PartialEq)]
pub enum SinkRecord {
    /// `(id, name, encoding)` of a schema.
    Schema(u16, String, String),
    /// `(id, schema id, topic)` of a channel.
    Channel(u16, u16, String),
    /// A message: header and bytes.
    Message(MessageHeader, Vec<u8>),
    /// An attachment's name.
    Attachment(String),
    /// A metadata record's name.
    Metadata(String),
}

/// A sink that keeps what it is given, in order (for tests of a session without files).
#[derive(Debug, Default)]
pub struct MemorySink {
    /// The records written, in order.
    pub records: Vec<SinkRecord>,
}

impl RecordSink for MemorySink {
    fn add_schema_with_id(&mut self, id: u16, name: &str, encoding: &str, _: &[u8]) -> Result<()> {
        let r = SinkRecord::Schema(id, name.into(), encoding.into());
        self.records.push(r);
        Ok(())
    }

    fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        _: &str,
        _: &BTreeMap<String, String>,
    ) -> Result<()> {
        self.records
            .push(SinkRecord::Channel(id, schema_id, topic.into()));
        Ok(())
    }

    fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()> {
        self.records
            .push(SinkRecord::Message(*header, data.to_vec()));
        Ok(())
    }

    fn attach(&mut self, a: &mcap::Attachment) -> Result<()> {
        self.records.push(SinkRecord::Attachment(a.name.clone()));
        Ok(())
    }

    fn write_metadata(&mut self, m: &Metadata) -> Result<()> {
        self.records.push(SinkRecord::Metadata(m.name.clone()));
        Ok(())
    }

    fn restart(&mut self) -> Result<()> {
        self.records.clear();
        Ok(())
    }
}
