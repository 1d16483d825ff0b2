//! Reading the messages of one topic as bytes, for the channels that are not boxes (e.g. the
//! ego poses); box channels are read through [`super::recording`].

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;
use mcap::records::{Channel, MessageHeader, Record};

use super::reader::read_records;

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
