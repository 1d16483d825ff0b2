//! The structural checks every read of an MCAP file makes (they run inside
//! [`read_records`](super::reader::read_records), so every command shares them): a schema or
//! channel id is defined once, or again with the same content; a channel's schema and a message's
//! channel are defined before they are used. The MCAP specification requires each; a file that
//! breaks one is refused with an error naming the record and its byte offset, instead of one
//! reader silently keeping the first definition and another the last.

use std::collections::{BTreeMap, HashMap};

use anyhow::{bail, Result};
use mcap::records::Record;

/// What the records of a file defined so far, and where.
#[derive(Default)]
pub(crate) struct Validator {
    schemas: HashMap<u16, Defined<SchemaContent>>,
    channels: HashMap<u16, Defined<ChannelContent>>,
}

/// A definition and where it was first seen.
struct Defined<T> {
    content: T,
    at: String,
}

#[derive(PartialEq)]
struct SchemaContent {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

#[derive(PartialEq)]
struct ChannelContent {
    topic: String,
    schema_id: u16,
    message_encoding: String,
    metadata: BTreeMap<String, String>,
}

impl Validator {
    /// Checks one record against those before it; `at` says where the record is (e.g. `byte 77`).
    /// The error says what is wrong, naming the record, its offset and the earlier definition.
    pub(crate) fn check(&mut self, record: &Record<'_>, at: impl Fn() -> String) -> Result<()> {
        match record {
            Record::Schema { header, data } => {
                let content = SchemaContent {
                    name: header.name.clone(),
                    encoding: header.encoding.clone(),
                    data: data.to_vec(),
                };
                self.on_schema(header.id, content, at)
            }
            Record::Channel(c) => {
                let content = ChannelContent {
                    topic: c.topic.clone(),
                    schema_id: c.schema_id,
                    message_encoding: c.message_encoding.clone(),
                    metadata: c.metadata.clone(),
                };
                self.on_channel(c.id, content, at)
            }
            Record::Message { header, .. } if !self.channels.contains_key(&header.channel_id) => {
                bail!(
                    "the message record at {} is on channel {}, which no channel record before \
                     it defines",
                    at(),
                    header.channel_id
                )
            }
            _ => Ok(()),
        }
    }

    fn on_schema(
        &mut self,
        id: u16,
        content: SchemaContent,
        at: impl Fn() -> String,
    ) -> Result<()> {
        let Some(first) = self.schemas.get(&id) else {
            self.schemas.insert(id, Defined { content, at: at() });
            return Ok(());
        };
        if first.content == content {
            return Ok(());
        }
        let old = &first.content;
        let what = if old.name != content.name {
            format!("name '{}' instead of '{}'", content.name, old.name)
        } else if old.encoding != content.encoding {
            format!(
                "encoding '{}' instead of '{}'",
                content.encoding, old.encoding
            )
        } else {
            format!(
                "{} bytes of data unlike the {} before",
                content.data.len(),
                old.data.len()
            )
        };
        bail!(
            "the schema record at {} redefines schema {id} (first defined at {}) with {what}",
            at(),
            first.at
        )
    }

    fn on_channel(
        &mut self,
        id: u16,
        content: ChannelContent,
        at: impl Fn() -> String,
    ) -> Result<()> {
        let schema = content.schema_id;
        if schema != 0 && !self.schemas.contains_key(&schema) {
            bail!(
                "the channel record at {} (channel {id}, topic '{}') refers to schema {schema}, \
                 which no schema record before it defines",
                at(),
                content.topic
            );
        }
        let Some(first) = self.channels.get(&id) else {
            self.channels.insert(id, Defined { content, at: at() });
            return Ok(());
        };
        if first.content == content {
            return Ok(());
        }
        let old = &first.content;
        let what = if old.topic != content.topic {
            format!("topic '{}' instead of '{}'", content.topic, old.topic)
        } else if old.schema_id != content.schema_id {
            format!("schema {} instead of {}", content.schema_id, old.schema_id)
        } else if old.message_encoding != content.message_encoding {
            format!(
                "message encoding '{}' instead of '{}'",
                content.message_encoding, old.message_encoding
            )
        } else {
            "different metadata".to_string()
        };
        bail!(
            "the channel record at {} redefines channel {id} (topic '{}', first defined at {}) \
             with {what}",
            at(),
            old.topic,
            first.at
        )
    }
}
