//! Reading the decoded messages of one topic of a probmot schema.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::{Channel, MessageHeader, Record};

use super::reader::read_records;
use super::recording::no_channel;
use crate::msgs::{self, Encoding};

/// Calls `on_channel` for every channel of `topic` with its schema's name (it checks the
/// channel and returns how its messages are to be read), `on_message` for every message of
/// those channels with its bytes, and `on_other` for every other record, in file order.
/// Returns whether the file has a channel of `topic`.
pub fn for_each_payload<E: Copy>(
    path: &Path,
    topic: &str,
    mut on_channel: impl FnMut(&Channel, &str) -> Result<E>,
    mut on_message: impl FnMut(&MessageHeader, &[u8], E) -> Result<()>,
    mut on_other: impl FnMut(Record<'_>) -> Result<()>,
) -> Result<bool> {
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut channels: BTreeMap<u16, E> = BTreeMap::new();
    let mut found = false;
    read_records(path, |rec, _| {
        match rec {
            Record::Schema { header, data } => {
                schemas.insert(header.id, header.name.clone());
                on_other(Record::Schema { header, data })?;
            }
            Record::Channel(c) if c.topic == topic => {
                found = true;
                let name = schemas.get(&c.schema_id).map_or("", String::as_str);
                let how = on_channel(&c, name)?;
                channels.insert(c.id, how);
            }
            Record::Message { header, data } if channels.contains_key(&header.channel_id) => {
                on_message(&header, &data, channels[&header.channel_id])?;
            }
            other => on_other(other)?,
        }
        Ok(())
    })?;
    Ok(found)
}

/// Calls `on_message` for every message of `topic` (schema `schema`, protobuf or JSON) in file
/// order, decoded as `M`, and `on_other` for every other record (e.g. metadata). Errors name the
/// file, the topic and the message; a missing topic, another schema or encoding is an error.
pub fn for_each_message<M>(
    path: &Path,
    topic: &str,
    schema: &str,
    mut on_message: impl FnMut(&MessageHeader, M) -> Result<()>,
    mut on_other: impl FnMut(Record<'_>) -> Result<()>,
) -> Result<()>
where
    M: prost::Message + Default + serde::de::DeserializeOwned,
{
    let file = path.display().to_string();
    // The other topics, for the error when `topic` is missing.
    let mut topics = BTreeSet::new();
    let found = for_each_payload(
        path,
        topic,
        |c, name| {
            if name != schema {
                bail!("{file}: topic {topic} has schema '{name}', expected {schema}");
            }
            Encoding::from_message_encoding(&c.message_encoding).with_context(|| {
                format!(
                    "{file}: topic {topic} has message encoding '{}'; expected protobuf or json",
                    c.message_encoding
                )
            })
        },
        |header, data, enc| {
            let m: M = msgs::decode(data, enc).with_context(|| {
                format!(
                    "{file}: topic {topic}, message at log_time {} (sequence {}): cannot decode \
                     {schema}",
                    header.log_time, header.sequence
                )
            })?;
            on_message(header, m)
        },
        |rec| {
            if let Record::Channel(c) = &rec {
                topics.insert(c.topic.clone());
            }
            on_other(rec)
        },
    )?;
    if !found {
        return Err(no_channel(&file, topic, &topics));
    }
    Ok(())
}
