//! One output file per input file: the [`RecordSink`] of a split rosbag2 bag. Each part is a
//! complete MCAP file of its own (one [`BackgroundOutput`] that moves on to the next file when
//! the next part starts, so that one writer thread writes them all without the run waiting),
//! with the schema and channel records of what is written into it: a channel first met in an
//! earlier part is declared again in the part that writes a message on it.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use mcap::records::{MessageHeader, Metadata};

use super::background::BackgroundOutput;
use super::sink::RecordSink;
use super::writer::OutputOptions;

/// A channel as added: schema id, topic, message encoding, metadata.
type ChannelDef = (u16, String, String, BTreeMap<String, String>);

/// Writes part `i` of a run to `paths[i]`; [`RecordSink::next_part`] moves to the next path.
pub struct SplitSink {
    paths: Vec<PathBuf>,
    opts: OutputOptions,
    background: bool,
    /// The part being written, and its index.
    current: Option<BackgroundOutput>,
    index: usize,
    /// Every schema and channel added so far, and those declared in the current part.
    schemas: BTreeMap<u16, (String, String, Vec<u8>)>,
    channels: BTreeMap<u16, ChannelDef>,
    declared_schemas: HashSet<u16>,
    declared_channels: HashSet<u16>,
}

impl SplitSink {
    /// Starts writing the first of `paths` (at least one), each written with `opts`, on a
    /// thread of its own when `background`.
    pub fn create(paths: Vec<PathBuf>, opts: OutputOptions, background: bool) -> Result<Self> {
        if paths.is_empty() {
            bail!("a split output needs at least one file");
        }
        let mut s = SplitSink {
            paths,
            opts,
            background,
            current: None,
            index: 0,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            declared_schemas: HashSet::new(),
            declared_channels: HashSet::new(),
        };
        s.current = Some(s.open(0)?);
        Ok(s)
    }

    fn open(&self, i: usize) -> Result<BackgroundOutput> {
        let path: &Path = &self.paths[i];
        if self.background {
            BackgroundOutput::create(path, &self.opts)
        } else {
            BackgroundOutput::create_inline(path, &self.opts)
        }
    }

    fn out(&mut self) -> &mut BackgroundOutput {
        self.current.as_mut().expect("an open part")
    }

    /// Declares channel `id` (and its schema) in the current part if it is not yet.
    fn declare(&mut self, id: u16) -> Result<()> {
        if self.declared_channels.contains(&id) {
            return Ok(());
        }
        let Some((schema_id, topic, encoding, metadata)) = self.channels.get(&id).cloned() else {
            // Unknown: the output refuses it with its own error.
            return Ok(());
        };
        self.declare_schema_of(schema_id)?;
        self.out()
            .add_channel_with_id(id, schema_id, &topic, &encoding, &metadata)?;
        self.declared_channels.insert(id);
        Ok(())
    }

    /// Commits the last part; an error if the input had fewer files than `paths`.
    pub fn commit(mut self) -> Result<()> {
        if self.index + 1 != self.paths.len() {
            bail!(
                "the input ended at file {} of {}",
                self.index + 1,
                self.paths.len()
            );
        }
        self.current.take().expect("an open part").commit()
    }
}

impl RecordSink for SplitSink {
    fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<()> {
        self.schemas
            .insert(id, (name.into(), encoding.into(), data.to_vec()));
        self.declared_schemas.insert(id);
        self.out().add_schema_with_id(id, name, encoding, data)
    }

    fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<()> {
        let def = (schema_id, topic.into(), encoding.into(), metadata.clone());
        self.channels.insert(id, def);
        self.declare_schema_of(schema_id)?;
        self.declared_channels.insert(id);
        self.out()
            .add_channel_with_id(id, schema_id, topic, encoding, metadata)
    }

    fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()> {
        self.declare(header.channel_id)?;
        self.out().write_to_known_channel(header, data)
    }

    fn write_encoded(
        &mut self,
        header: &MessageHeader,
        _: &mut Vec<u8>,
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> Result<()> {
        self.declare(header.channel_id)?;
        self.out().write_encoded_to_known_channel(header, encode)
    }

    fn attach(&mut self, a: &mcap::Attachment) -> Result<()> {
        self.out().attach(a)
    }

    fn write_metadata(&mut self, m: &Metadata) -> Result<()> {
        self.out().write_metadata(m)
    }

    fn next_part(&mut self) -> Result<()> {
        if self.index + 1 >= self.paths.len() {
            bail!("more input files than the {} planned", self.paths.len());
        }
        let next = self.paths[self.index + 1].clone();
        self.out().next_file(&next)?;
        self.index += 1;
        self.declared_schemas.clear();
        self.declared_channels.clear();
        Ok(())
    }

    fn restart(&mut self) -> Result<()> {
        // Parts already committed go; the first starts again, empty.
        drop(self.current.take());
        for p in &self.paths[..self.index] {
            let _ = std::fs::remove_file(p);
        }
        self.index = 0;
        self.schemas.clear();
        self.channels.clear();
        self.declared_schemas.clear();
        self.declared_channels.clear();
        self.current = Some(self.open(0)?);
        Ok(())
    }
}

impl SplitSink {
    /// Declares schema `id` in the current part if it is known and not yet declared.
    fn declare_schema_of(&mut self, id: u16) -> Result<()> {
        if id == 0 || self.declared_schemas.contains(&id) {
            return Ok(());
        }
        if let Some((name, enc, data)) = self.schemas.get(&id).cloned() {
            self.out().add_schema_with_id(id, &name, &enc, &data)?;
            self.declared_schemas.insert(id);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::reader::read_records;
    use mcap::records::Record;

    /// Records of `path`: `(topic of each channel record, channel id of each message)`.
    fn contents(path: &Path) -> (Vec<String>, Vec<u16>) {
        let (mut topics, mut msgs) = (Vec::new(), Vec::new());
        read_records(path, |r, _| {
            match r {
                Record::Channel(c) => topics.push(c.topic),
                Record::Message { header, .. } => msgs.push(header.channel_id),
                _ => {}
            }
            Ok(())
        })
        .unwrap();
        topics.sort();
        topics.dedup();
        (topics, msgs)
    }

    /// A channel added in the first part and written in the second is declared there too;
    /// each part is a complete file with its own messages.
    #[test]
    fn each_part_is_a_file_with_the_channels_it_writes() {
        let d = tempfile::tempdir().unwrap();
        let paths = vec![d.path().join("a.mcap"), d.path().join("b.mcap")];
        let mut s = SplitSink::create(paths.clone(), OutputOptions::default(), false).unwrap();
        s.add_schema_with_id(1, "S", "jsonschema", b"{}").unwrap();
        s.add_channel_with_id(1, 1, "/t", "json", &BTreeMap::new())
            .unwrap();
        s.add_channel_with_id(2, 1, "/u", "json", &BTreeMap::new())
            .unwrap();
        let h = |channel_id, log_time| MessageHeader {
            channel_id,
            sequence: 0,
            log_time,
            publish_time: log_time,
        };
        s.write_to_known_channel(&h(1, 1), b"{}").unwrap();
        s.next_part().unwrap();
        s.write_to_known_channel(&h(2, 2), b"{}").unwrap();
        assert!(s.next_part().is_err(), "only two parts planned");
        s.commit().unwrap();
        let (topics, msgs) = contents(&paths[0]);
        assert_eq!((topics, msgs), (vec!["/t".into(), "/u".into()], vec![1]));
        let (topics, msgs) = contents(&paths[1]);
        assert_eq!((topics, msgs), (vec!["/u".to_string()], vec![2]));
    }
}
