//! A rosbag2 bag of several files read as one stream of records ([`BagSource`]): the files in
//! recording order, each file's header record first (it tells the sink that the next file
//! starts), then its data section; summary sections and footers are read (and checked) but not
//! handed on.
//!
//! Each file declares its own schemas and channels, and rosbag2 numbers them anew in every file
//! of a split: the same topic may have another id in the next file. The stream gives them one
//! numbering: a schema or channel seen before (same content) keeps its first id, a new one keeps
//! its own id when that is free and else gets the lowest free one.
//!
//! A zstd-compressed file (`compression_mode: file`) is decompressed as it is read, a stream
//! with a window of at most a few MiB: no temporary copy. Such a file has no readable summary
//! (that needs seeking), so its bag is tracked in two passes, each decompressing it again.
//! A compressed message (`compression_mode: message`) is decompressed as it is handed on, into
//! one buffer reused for every message, no larger than the record size limit.
//!
//! A sqlite3 file (`.db3`) is read as MCAP records by [`super::db3_file`]; it has no summary
//! either. Compressed whole (`.db3.zstd`), it is decompressed into a scratch file first
//! ([`super::scratch_file`]; SQLite needs random access), one file at a time, each pass again.

use std::cell::Cell;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::File;
use std::io::{BufReader, Read};
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::rc::Rc;

use anyhow::{bail, Context, Result};
use mcap::records::{Channel, Record, SchemaHeader, Statistics};

use super::bag_metadata::BagCompression;
use super::db3_file::read_db3_as;
use super::rosbag_dir::{compressed_whole, Bag, Storage};
use super::scratch_file::ScratchFile;
use crate::mcapio::chunk_stream::{limit_hint, size_limit};
use crate::mcapio::reader::{
    read_records_to_cut, read_summary_records, CutShort, McapInput, ReadStats,
};
use crate::mcapio::source::{OnRecord, RecordSource};

/// The files of a bag, read one after the other as one input.
pub struct BagSource {
    /// The bag directory, named in errors about the whole bag.
    pub name: String,
    /// Its files, in recording order.
    pub files: Vec<PathBuf>,
    /// What the files are.
    pub storage: Storage,
    /// How they, or their messages, are compressed.
    pub compression: BagCompression,
    /// Per file, where the first read ended, for later reads to stop there too, also in a file
    /// still being written: the byte where an MCAP file was cut short ([`McapInput::cut_at`]),
    /// the last row of a sqlite3 file's `messages`.
    read_to: Vec<ReadTo>,
}

impl BagSource {
    /// The source of the bag `bag`.
    pub fn of(bag: &Bag) -> Self {
        BagSource {
            name: bag.dir.display().to_string(),
            files: bag.files.clone(),
            storage: bag.storage,
            compression: bag.compression,
            read_to: vec![ReadTo::default(); bag.files.len()],
        }
    }

    /// The source of one sqlite3 storage file named on its own (no bag directory around it).
    pub fn sqlite_file(path: &std::path::Path) -> Self {
        BagSource {
            name: path.display().to_string(),
            files: vec![path.to_path_buf()],
            storage: Storage::Sqlite3,
            compression: BagCompression::None,
            read_to: vec![ReadTo::default()],
        }
    }
}

/// Where the first read of a file ended ([`BagSource`]'s `read_to`).
#[derive(Debug, Clone, Copy, Default)]
struct ReadTo {
    /// An MCAP file: the byte where it was found cut short.
    cut_at: Option<u64>,
    /// A sqlite3 file: the last row id of `messages` read.
    last_row: Option<i64>,
}

/// Decompresses the messages of a bag written with `compression_mode: message`.
#[derive(Default)]
struct MessageInflater {
    buf: Vec<u8>,
}

impl MessageInflater {
    /// The bytes of the zstd frame `data`, refused when they would pass the record size limit.
    fn inflate(&mut self, data: &[u8]) -> Result<&[u8]> {
        let limit = size_limit();
        self.buf.clear();
        let decoder = zstd::stream::read::Decoder::with_buffer(data)
            .context("cannot start zstd on a compressed message")?;
        let mut capped = decoder.take(limit.saturating_add(1));
        std::io::copy(&mut capped, &mut self.buf)
            .context("not a zstd frame (the bag says its messages are compressed)")?;
        if self.buf.len() as u64 > limit {
            bail!(
                "a compressed message decompresses beyond {}",
                limit_hint(limit + 1)
            );
        }
        Ok(&self.buf)
    }

    /// `rec`, its message data decompressed.
    fn message<'a>(&'a mut self, rec: Record<'a>) -> Result<Record<'a>> {
        Ok(match rec {
            Record::Message { header, data } => {
                let bytes = self.inflate(&data).with_context(|| {
                    format!(
                        "message at log_time {} on channel {}",
                        header.log_time, header.channel_id
                    )
                })?;
                Record::Message {
                    header,
                    data: std::borrow::Cow::Borrowed(bytes),
                }
            }
            other => other,
        })
    }
}

/// Schema and channel ids of the stream, from each file's own.
#[derive(Default)]
struct IdMap {
    schemas: HashMap<(String, String, Vec<u8>), u16>,
    schema_ids: HashSet<u16>,
    channels: HashMap<(String, u16, String, BTreeMap<String, String>), u16>,
    channel_ids: HashSet<u16>,
    /// The current file's ids → the stream's.
    file_schemas: HashMap<u16, u16>,
    file_channels: HashMap<u16, u16>,
}

/// `own` when it is free, else the lowest free id.
fn free_id(own: u16, used: &HashSet<u16>) -> Option<u16> {
    if !used.contains(&own) {
        return Some(own);
    }
    (1..=u16::MAX).find(|i| !used.contains(i))
}

impl IdMap {
    fn next_file(&mut self) {
        self.file_schemas.clear();
        self.file_channels.clear();
    }

    fn schema(&mut self, h: &SchemaHeader, data: &[u8]) -> Result<u16> {
        if h.id == 0 {
            return Ok(0);
        }
        let key = (h.name.clone(), h.encoding.clone(), data.to_vec());
        let id = match self.schemas.get(&key) {
            Some(&id) => id,
            None => {
                let id = free_id(h.id, &self.schema_ids).context("no free schema id left")?;
                self.schema_ids.insert(id);
                self.schemas.insert(key, id);
                id
            }
        };
        self.file_schemas.insert(h.id, id);
        Ok(id)
    }

    fn channel(&mut self, c: &Channel) -> Result<(u16, u16)> {
        let schema_id = match c.schema_id {
            0 => 0,
            s => *self.file_schemas.get(&s).with_context(|| {
                format!(
                    "channel {} (topic {}) refers to schema {s}, not declared before it",
                    c.id, c.topic
                )
            })?,
        };
        let key = (
            c.topic.clone(),
            schema_id,
            c.message_encoding.clone(),
            c.metadata.clone(),
        );
        let id = match self.channels.get(&key) {
            Some(&id) => id,
            None => {
                let id = free_id(c.id, &self.channel_ids).context("no free channel id left")?;
                self.channel_ids.insert(id);
                self.channels.insert(key, id);
                id
            }
        };
        self.file_channels.insert(c.id, id);
        Ok((id, schema_id))
    }

    /// The record with the stream's ids (`None`: a message on a channel never declared, which
    /// the caller reports).
    fn map<'a>(&mut self, rec: Record<'a>) -> Result<Record<'a>> {
        Ok(match rec {
            Record::Schema { mut header, data } => {
                header.id = self.schema(&header, &data)?;
                Record::Schema { header, data }
            }
            Record::Channel(mut c) => {
                (c.id, c.schema_id) = self.channel(&c)?;
                Record::Channel(c)
            }
            Record::Message { mut header, data } => {
                header.channel_id =
                    *self
                        .file_channels
                        .get(&header.channel_id)
                        .with_context(|| {
                            format!(
                                "message at log_time {} (sequence {}) on channel {}, not declared \
                             before it",
                                header.log_time, header.sequence, header.channel_id
                            )
                        })?;
                Record::Message { header, data }
            }
            other => other,
        })
    }
}

/// The bytes of one file, and the shared count of bytes read from the disk.
type Opened = (Box<dyn Read>, Rc<Cell<u64>>);

/// A reader that counts the bytes it reads (the compressed bytes, under a decompressor).
struct Counting<R> {
    inner: R,
    count: Rc<Cell<u64>>,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count.set(self.count.get() + n as u64);
        Ok(n)
    }
}

impl BagSource {
    /// The bytes of file `i`, decompressed when the bag is, and the counter of bytes read.
    fn open(&self, i: usize) -> Result<Opened> {
        let path = &self.files[i];
        let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        let count = Rc::new(Cell::new(0));
        let raw = Counting {
            inner: file,
            count: count.clone(),
        };
        let bytes: Box<dyn Read> = match compressed_whole(path) {
            false => Box::new(raw),
            true => Box::new(
                zstd::stream::read::Decoder::with_buffer(BufReader::new(raw))
                    .with_context(|| format!("{}: cannot start zstd", path.display()))?,
            ),
        };
        Ok((bytes, count))
    }

    /// Reads file `i` with `ids`, handing its header and data-section records to `f`; returns
    /// whether `f` stopped the read. A file cut short is read up to the cut, added to `cuts`.
    fn read_file(
        &self,
        i: usize,
        ids: &mut IdMap,
        base: u64,
        f: &mut OnRecord<'_>,
        cuts: &mut Vec<CutShort>,
        read_to: &mut ReadTo,
    ) -> Result<bool> {
        let name = self.files[i].display().to_string();
        let mut inflater = MessageInflater::default();
        let inflate = self.compression == BagCompression::MessageZstd;
        ids.next_file();
        let mut hand_on = |rec: Record<'_>, bytes: u64| -> Result<ControlFlow<()>> {
            let rec = ids.map(rec).with_context(|| name.clone())?;
            let rec = match inflate {
                true => inflater.message(rec).with_context(|| name.clone())?,
                false => rec,
            };
            f(
                rec,
                ReadStats {
                    bytes_read: base + bytes,
                },
            )
        };
        if self.storage == Storage::Sqlite3 {
            let file = &self.files[i];
            // SQLite reads a file, not a stream: a compressed one is read from a scratch copy.
            let scratch = match compressed_whole(file) {
                true => Some(ScratchFile::unzstd(file)?),
                false => None,
            };
            let path = scratch.as_ref().map_or(file.as_path(), |s| s.path());
            let (stopped, cut) = read_db3_as(path, file, &mut read_to.last_row, &mut hand_on)?;
            cuts.extend(cut);
            return Ok(stopped);
        }
        let (bytes, count) = self.open(i)?;
        let mut input = McapInput::new(name.clone(), bytes);
        input.stop_at(read_to.cut_at);
        let (mut in_data, mut stopped) = (true, false);
        let cut = read_records_to_cut(&mut input, |rec, _| {
            if !in_data {
                return Ok(ControlFlow::Continue(()));
            }
            if matches!(rec, Record::DataEnd(_)) {
                in_data = false;
            }
            let flow = hand_on(rec, count.get())?;
            stopped = flow.is_break();
            Ok(flow)
        })?;
        read_to.cut_at = input.cut_at();
        // The bytes of a cut in a file compressed whole count in the decompressed MCAP file.
        cuts.extend(cut.map(|c| match compressed_whole(&self.files[i]) {
            true => CutShort {
                file: format!("{} (decompressed)", c.file),
                ..c
            },
            false => c,
        }));
        Ok(stopped)
    }
}

impl RecordSource for BagSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn byte_len(&mut self) -> u64 {
        (self.files.iter())
            .map(|f| std::fs::metadata(f).map_or(0, |m| m.len()))
            .sum()
    }

    /// The files' summaries as one: their schemas and channels in the stream's ids, and the
    /// message counts added up; `None` when a file has no readable summary (or is compressed).
    fn summary(&mut self) -> Option<(Record<'static>, Vec<Record<'static>>)> {
        if self.files.iter().any(|f| compressed_whole(f)) || self.storage == Storage::Sqlite3 {
            return None;
        }
        let mut ids = IdMap::default();
        let mut header = None;
        let mut out = Vec::new();
        let mut stats = Statistics {
            message_start_time: u64::MAX,
            ..Default::default()
        };
        for path in &self.files {
            let (h, records) = read_summary_records(path)?;
            header.get_or_insert(h);
            ids.next_file();
            for rec in records {
                match rec {
                    Record::Statistics(s) => add_statistics(&mut stats, &s, &ids)?,
                    r @ (Record::Schema { .. } | Record::Channel(_)) => {
                        out.push(ids.map(r).ok()?);
                    }
                    _ => {}
                }
            }
        }
        if stats.message_count == 0 {
            stats.message_start_time = 0;
        }
        out.push(Record::Statistics(stats));
        Some((header?, out))
    }

    fn read_while(&mut self, f: &mut OnRecord<'_>) -> Result<Vec<CutShort>> {
        let (mut ids, mut base, mut cuts) = (IdMap::default(), 0, Vec::new());
        let mut read_to = std::mem::take(&mut self.read_to);
        read_to.resize(self.files.len(), ReadTo::default());
        let mut stopped = false;
        for (i, file_end) in read_to.iter_mut().enumerate() {
            stopped = self.read_file(i, &mut ids, base, f, &mut cuts, file_end)?;
            if stopped {
                break;
            }
            base += std::fs::metadata(&self.files[i]).map_or(0, |m| m.len());
        }
        self.read_to = read_to;
        if stopped {
            return Ok(cuts);
        }
        if self.files.is_empty() {
            bail!("{}: a bag without files", self.name);
        }
        Ok(cuts)
    }
}

/// Adds a file's statistics (its channel ids mapped by `ids`) to the bag's.
fn add_statistics(total: &mut Statistics, s: &Statistics, ids: &IdMap) -> Option<()> {
    total.message_count += s.message_count;
    if s.message_count > 0 {
        total.message_start_time = total.message_start_time.min(s.message_start_time);
        total.message_end_time = total.message_end_time.max(s.message_end_time);
    }
    for (id, n) in &s.channel_message_counts {
        *total
            .channel_message_counts
            .entry(*ids.file_channels.get(id)?)
            .or_default() += n;
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(id: u16, schema_id: u16, topic: &str) -> Channel {
        Channel {
            id,
            schema_id,
            topic: topic.into(),
            message_encoding: "cdr".into(),
            metadata: BTreeMap::new(),
        }
    }

    fn schema(ids: &mut IdMap, id: u16, name: &str) -> u16 {
        let h = SchemaHeader {
            id,
            name: name.into(),
            encoding: "ros2msg".into(),
        };
        ids.schema(&h, b"").unwrap()
    }

    /// The second file numbers the same topics the other way round: they keep the first file's
    /// ids; a new topic whose id is taken gets a free one.
    #[test]
    fn the_same_topic_keeps_its_id_across_files() {
        let mut ids = IdMap::default();
        assert_eq!(schema(&mut ids, 1, "A"), 1);
        assert_eq!(schema(&mut ids, 2, "B"), 2);
        assert_eq!(ids.channel(&channel(1, 1, "/a")).unwrap(), (1, 1));
        assert_eq!(ids.channel(&channel(2, 2, "/b")).unwrap(), (2, 2));
        ids.next_file();
        assert_eq!(schema(&mut ids, 1, "B"), 2);
        assert_eq!(schema(&mut ids, 2, "A"), 1);
        assert_eq!(ids.channel(&channel(1, 1, "/b")).unwrap(), (2, 2));
        assert_eq!(ids.channel(&channel(2, 2, "/a")).unwrap(), (1, 1));
        assert_eq!(ids.channel(&channel(3, 2, "/c")).unwrap(), (3, 1));
        assert_eq!(ids.channel(&channel(1, 2, "/d")).unwrap(), (4, 1));
        assert!(
            ids.channel(&channel(9, 7, "/e")).is_err(),
            "undeclared schema"
        );
    }
}
