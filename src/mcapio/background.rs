//! An atomic MCAP output whose writing and chunk compression run on a thread of their own, so
//! that compressing the output overlaps with reading, decoding and tracking on the caller's
//! thread.
//!
//! The caller's calls are recorded into batches (the payloads of a batch's messages in one reused
//! byte buffer, so steady-state writing allocates nothing per message) and handed to the writer
//! thread through a bounded channel; used batches come back for reuse. At most [`BATCHES`]
//! batches of about [`BATCH_BYTES`] exist, so memory stays bounded whatever the length of the
//! log. Records that refer to an unknown schema or channel are refused at the call, as
//! `mcap::Writer` refuses them; errors of the writer thread itself (a full disk, a conflicting
//! record) are returned by the next call or by [`BackgroundOutput::commit`].

use std::collections::{BTreeMap, HashSet};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::thread::JoinHandle;

use anyhow::{anyhow, Context, Result};
use mcap::records::{MessageHeader, Metadata};
use mcap::McapError;

use super::writer::{AtomicOutput, OutputOptions};

/// Bytes of message payloads after which a batch is handed to the writer thread.
pub const BATCH_BYTES: usize = 1 << 19;

/// Calls after which a batch is handed over even if its payloads are small.
const BATCH_OPS: usize = 4096;

/// Batches in circulation (filled by the caller, queued, or being written).
pub const BATCHES: usize = 4;

/// Capacity a batch's buffer keeps once written: a batch that held one huge payload (an
/// attachment, a point cloud) gives that memory back instead of holding it for the rest of the
/// run, while ordinary batches (up to [`BATCH_BYTES`] and one payload more) keep theirs.
const KEPT_BATCH_BYTES: usize = 4 * BATCH_BYTES;

/// One recorded call; payloads are ranges into the batch's byte buffer.
enum Op {
    Schema {
        id: u16,
        name: String,
        encoding: String,
        data: Range<usize>,
    },
    Channel {
        id: u16,
        schema_id: u16,
        topic: String,
        encoding: String,
        metadata: BTreeMap<String, String>,
    },
    Message {
        header: MessageHeader,
        data: Range<usize>,
    },
    Attachment {
        log_time: u64,
        create_time: u64,
        name: String,
        media_type: String,
        data: Range<usize>,
    },
    Metadata(Metadata),
    /// Commit this file and go on writing into a new one, `dest`.
    NextFile(PathBuf),
}

#[derive(Default)]
struct Batch {
    ops: Vec<Op>,
    bytes: Vec<u8>,
}

impl Batch {
    /// Empties a written batch for reuse, keeping at most [`KEPT_BATCH_BYTES`] of its buffer.
    fn empty(&mut self) {
        self.ops.clear();
        self.bytes.clear();
        self.bytes.shrink_to(KEPT_BATCH_BYTES);
    }

    fn push_bytes(&mut self, data: &[u8]) -> Range<usize> {
        let start = self.bytes.len();
        self.bytes.extend_from_slice(data);
        start..self.bytes.len()
    }
}

/// An MCAP output on a temporary file, written by a background thread (or, made with
/// [`BackgroundOutput::create_inline`], on the caller's), that becomes its destination on
/// [`BackgroundOutput::commit`]. Dropped without a commit, it leaves no file.
pub struct BackgroundOutput {
    mode: Mode,
    /// What it was made with, to start again ([`BackgroundOutput::restart`]): the destination,
    /// the options and whether it has a writer thread.
    made_with: (PathBuf, OutputOptions, bool),
    /// The batch being filled (unused inline).
    batch: Batch,
    /// Ids added so far, to refuse unknown ones at the call.
    schemas: HashSet<u16>,
    channels: HashSet<u16>,
}

enum Mode {
    /// Every call is written at once on the caller's thread.
    Inline {
        out: Box<AtomicOutput>,
        dest: PathBuf,
    },
    /// Calls are batched to the writer thread.
    Thread {
        /// Batches to write; `None` asks for the commit.
        tx: Option<SyncSender<Option<Batch>>>,
        /// Batches given back by the writer thread.
        free: Receiver<Batch>,
        /// Batches in circulation.
        batches: usize,
        thread: Option<JoinHandle<Result<()>>>,
    },
    /// Committed, failed or dropped.
    Done,
}

impl BackgroundOutput {
    /// Creates the temporary file beside `dest` (see [`AtomicOutput::create`]) and starts the
    /// writer thread, which also compresses the chunks.
    pub fn create(dest: &Path, opts: &OutputOptions) -> Result<Self> {
        let out = AtomicOutput::create(dest, opts)?;
        let made_with = (dest.to_path_buf(), opts.clone(), true);
        let dest: PathBuf = dest.to_path_buf();
        let (tx, rx) = mpsc::sync_channel::<Option<Batch>>(BATCHES);
        let (free_tx, free) = mpsc::sync_channel::<Batch>(BATCHES);
        let thread_opts = opts.clone();
        let thread = std::thread::Builder::new()
            .name("probmot-writer".into())
            .spawn(move || write_batches(out, rx, free_tx, dest, &thread_opts))
            .context("cannot start the output writer thread")?;
        let mode = Mode::Thread {
            tx: Some(tx),
            free,
            batches: 1,
            thread: Some(thread),
        };
        Ok(Self::with_mode(mode, made_with))
    }

    /// The same interface without the thread: every call is written on the caller's thread, as
    /// [`AtomicOutput`] writes (chunks compressed on the caller's thread too), for runs where
    /// each core already has a file of its own.
    pub fn create_inline(dest: &Path, opts: &OutputOptions) -> Result<Self> {
        let out = AtomicOutput::create(dest, opts)?;
        let mode = Mode::Inline {
            out: Box::new(out),
            dest: dest.to_path_buf(),
        };
        Ok(Self::with_mode(
            mode,
            (dest.to_path_buf(), opts.clone(), false),
        ))
    }

    fn with_mode(mode: Mode, made_with: (PathBuf, OutputOptions, bool)) -> Self {
        BackgroundOutput {
            mode,
            made_with,
            batch: Batch::default(),
            schemas: HashSet::new(),
            channels: HashSet::new(),
        }
    }

    /// Like `mcap::Writer::add_schema_with_id`.
    pub fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<()> {
        if id == 0 {
            return Err(McapError::InvalidSchemaId.into());
        }
        self.schemas.insert(id);
        self.push(data, |data| Op::Schema {
            id,
            name: name.to_string(),
            encoding: encoding.to_string(),
            data,
        })
    }

    /// Like `mcap::Writer::add_channel_with_id`.
    pub fn add_channel_with_id(
        &mut self,
        id: u16,
        schema_id: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<()> {
        if schema_id != 0 && !self.schemas.contains(&schema_id) {
            return Err(McapError::UnknownSchema(topic.into(), schema_id).into());
        }
        self.channels.insert(id);
        self.push(&[], |_| Op::Channel {
            id,
            schema_id,
            topic: topic.to_string(),
            encoding: encoding.to_string(),
            metadata: metadata.clone(),
        })
    }

    /// Like `mcap::Writer::write_to_known_channel`: the payload is copied into the batch (written
    /// at once inline), nothing is allocated in steady state.
    pub fn write_to_known_channel(&mut self, header: &MessageHeader, data: &[u8]) -> Result<()> {
        if !self.channels.contains(&header.channel_id) {
            return Err(McapError::UnknownChannel(header.sequence, header.channel_id).into());
        }
        self.push(data, |data| Op::Message {
            header: *header,
            data,
        })
    }

    /// Like [`BackgroundOutput::write_to_known_channel`], but `encode` appends the payload
    /// straight to the batch's buffer (no copy). It must only append: the buffer may hold other
    /// payloads before it.
    pub fn write_encoded_to_known_channel(
        &mut self,
        header: &MessageHeader,
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> Result<()> {
        if !self.channels.contains(&header.channel_id) {
            return Err(McapError::UnknownChannel(header.sequence, header.channel_id).into());
        }
        self.refuse_if_stopped()?;
        let bytes = &mut self.batch.bytes;
        let start = bytes.len();
        encode(bytes);
        let data = start..bytes.len();
        let op = Op::Message {
            header: *header,
            data,
        };
        if let Mode::Inline { out, dest } = &mut self.mode {
            // Inline, the batch is unused but as this payload's buffer (empty before it).
            let r = apply(out, op, bytes, dest);
            self.batch.empty();
            return r;
        }
        self.batch.ops.push(op);
        self.send_if_full()
    }

    /// Like `mcap::Writer::attach`.
    pub fn attach(&mut self, a: &mcap::Attachment) -> Result<()> {
        self.push(&a.data, |data| Op::Attachment {
            log_time: a.log_time,
            create_time: a.create_time,
            name: a.name.clone(),
            media_type: a.media_type.clone(),
            data,
        })
    }

    /// Like `mcap::Writer::write_metadata`.
    pub fn write_metadata(&mut self, m: &Metadata) -> Result<()> {
        self.push(&[], |_| Op::Metadata(m.clone()))
    }

    /// Commits the file written so far (as [`BackgroundOutput::commit`]) and goes on writing
    /// into a new file `dest`, with the same options and no schema or channel yet. On the writer
    /// thread, the commit and the new file are that thread's work: the caller does not wait for
    /// them (their errors come with a later call), and one thread writes every file.
    pub fn next_file(&mut self, dest: &Path) -> Result<()> {
        self.schemas.clear();
        self.channels.clear();
        self.made_with.0 = dest.to_path_buf();
        if matches!(self.mode, Mode::Inline { .. }) {
            if let Mode::Inline { out, .. } = std::mem::replace(&mut self.mode, Mode::Done) {
                out.commit()?;
            }
            self.mode = Mode::Inline {
                out: Box::new(AtomicOutput::create(dest, &self.made_with.1)?),
                dest: dest.to_path_buf(),
            };
            return Ok(());
        }
        self.batch.ops.push(Op::NextFile(dest.to_path_buf()));
        self.send()
    }

    /// Drops what was written (the partial file goes, as on a drop) and starts the output again,
    /// empty, with the same destination and options.
    pub fn restart(&mut self) -> Result<()> {
        self.abandon();
        let (dest, opts, threaded) = self.made_with.clone();
        *self = if threaded {
            Self::create(&dest, &opts)?
        } else {
            Self::create_inline(&dest, &opts)?
        };
        Ok(())
    }

    /// Stops writing without a commit: hangs up and waits for the writer thread; the partial
    /// file is deleted with the writer.
    fn abandon(&mut self) {
        if let Mode::Thread { tx, thread, .. } = std::mem::replace(&mut self.mode, Mode::Done) {
            drop(tx);
            let _ = join(thread);
        }
    }

    /// Writes what is left, finishes the MCAP (summary, footer), syncs it and renames it over
    /// the destination.
    pub fn commit(mut self) -> Result<()> {
        if matches!(self.mode, Mode::Thread { .. }) && !self.batch.ops.is_empty() {
            self.send()?;
        }
        match std::mem::replace(&mut self.mode, Mode::Done) {
            Mode::Inline { out, .. } => out.commit(),
            Mode::Thread { tx, thread, .. } => {
                let asked = tx.is_some_and(|tx| tx.send(None).is_ok());
                match join(thread) {
                    Ok(()) if !asked => Err(anyhow!("the output writer thread stopped early")),
                    r => r,
                }
            }
            Mode::Done => Err(anyhow!("the output is already committed")),
        }
    }

    /// Records the call `op` with its `payload` (given to `op` as a range of the bytes it is
    /// written from); inline, writes it at once from `payload` itself.
    fn push(&mut self, payload: &[u8], op: impl FnOnce(Range<usize>) -> Op) -> Result<()> {
        self.refuse_if_stopped()?;
        if let Mode::Inline { out, dest } = &mut self.mode {
            return apply(out, op(0..payload.len()), payload, dest);
        }
        let range = self.batch.push_bytes(payload);
        self.batch.ops.push(op(range));
        self.send_if_full()
    }

    /// Refuses a call once the output has stopped (its writer failed): the batch could never
    /// be written.
    fn refuse_if_stopped(&self) -> Result<()> {
        match self.mode {
            Mode::Done => Err(stopped()),
            _ => Ok(()),
        }
    }

    /// Hands the current batch over when it is full.
    fn send_if_full(&mut self) -> Result<()> {
        if self.batch.bytes.len() >= BATCH_BYTES || self.batch.ops.len() >= BATCH_OPS {
            self.send()?;
        }
        Ok(())
    }

    /// Hands the current batch to the writer thread and takes an empty one: a returned batch,
    /// a new one while fewer than [`BATCHES`] exist, or else waits for one to come back.
    fn send(&mut self) -> Result<()> {
        let Mode::Thread {
            tx, free, batches, ..
        } = &mut self.mode
        else {
            return Err(stopped());
        };
        let next = match free.try_recv() {
            Ok(b) => Some(b),
            Err(_) if *batches < BATCHES => {
                *batches += 1;
                Some(Batch::default())
            }
            Err(_) => free.recv().ok(),
        };
        let sent = match (next, tx.as_ref()) {
            (Some(next), Some(tx)) => tx
                .send(Some(std::mem::replace(&mut self.batch, next)))
                .is_ok(),
            _ => false,
        };
        if !sent {
            return Err(self.writer_failed());
        }
        Ok(())
    }

    /// The error of a writer thread that stopped early.
    fn writer_failed(&mut self) -> anyhow::Error {
        match std::mem::replace(&mut self.mode, Mode::Done) {
            Mode::Thread { thread, .. } => match join(thread) {
                Err(e) => e,
                Ok(()) => anyhow!("the output writer thread stopped early"),
            },
            _ => anyhow!("the output writer thread has already stopped"),
        }
    }
}

/// The error of a call made after the output stopped (its writer failed, or it was given up).
fn stopped() -> anyhow::Error {
    anyhow!("the output has stopped after an earlier error")
}

/// Waits for the writer thread and returns its result.
fn join(thread: Option<JoinHandle<Result<()>>>) -> Result<()> {
    match thread.map(JoinHandle::join) {
        Some(Ok(r)) => r,
        Some(Err(_)) => Err(anyhow!("the output writer thread panicked")),
        None => Err(anyhow!("the output writer thread has already stopped")),
    }
}

impl Drop for BackgroundOutput {
    fn drop(&mut self) {
        self.abandon();
    }
}

/// The writer thread: applies every batch in order, returns each for reuse, and commits the
/// output on the caller's `None` (sent by [`BackgroundOutput::commit`]); a
/// [`BackgroundOutput::next_file`] commits the file and starts the next with `opts`. A caller
/// that hangs up without a commit (an error, a drop) leaves no output: the temporary file is
/// deleted.
fn write_batches(
    mut out: AtomicOutput,
    rx: Receiver<Option<Batch>>,
    free: SyncSender<Batch>,
    mut dest: PathBuf,
    opts: &OutputOptions,
) -> Result<()> {
    loop {
        let mut batch = match rx.recv() {
            Ok(Some(batch)) => batch,
            Ok(None) => return out.commit(),
            // Hung up without a commit: the temporary file goes with `out`.
            Err(_) => return Ok(()),
        };
        for op in batch.ops.drain(..) {
            if let Op::NextFile(next) = op {
                // Committed first: the two files' buffers are not held at once.
                out.commit()?;
                out = AtomicOutput::create(&next, opts)?;
                dest = next;
                continue;
            }
            apply(&mut out, op, &batch.bytes, &dest)?;
        }
        batch.empty();
        // The caller may have stopped taking batches back; that is fine.
        let _ = free.try_send(batch);
    }
}

/// Writes one recorded call; `bytes` holds its payload. Errors name the output.
fn apply(out: &mut AtomicOutput, op: Op, bytes: &[u8], dest: &Path) -> Result<()> {
    let d = dest.display();
    let w = &mut out.writer;
    match op {
        Op::Schema {
            id,
            name,
            encoding,
            data,
        } => {
            w.add_schema_with_id(id, &name, &encoding, &bytes[data])
                .with_context(|| format!("writing {d}: schema {id} ({name})"))?;
        }
        Op::Channel {
            id,
            schema_id,
            topic,
            encoding,
            metadata,
        } => {
            w.add_channel_with_id(id, schema_id, &topic, &encoding, &metadata)
                .with_context(|| format!("writing {d}: channel {id} ({topic})"))?;
        }
        Op::Message { header, data } => {
            w.write_to_known_channel(&header, &bytes[data])
                .with_context(|| {
                    format!(
                        "writing {d}: message at log_time {} on channel {}",
                        header.log_time, header.channel_id
                    )
                })?;
        }
        Op::Attachment {
            log_time,
            create_time,
            name,
            media_type,
            data,
        } => {
            w.attach(&mcap::Attachment {
                log_time,
                create_time,
                name,
                media_type,
                data: std::borrow::Cow::Borrowed(&bytes[data]),
            })
            .with_context(|| format!("writing {d}: an attachment"))?;
        }
        Op::Metadata(m) => {
            w.write_metadata(&m)
                .with_context(|| format!("writing {d}: metadata {}", m.name))?;
        }
        Op::NextFile(_) => unreachable!("the writer thread starts the next file itself"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::read_records;
    use mcap::records::Record;

    fn header(channel_id: u16, i: u64) -> MessageHeader {
        MessageHeader {
            channel_id,
            sequence: i as u32,
            log_time: 1_000 + i,
            publish_time: 2_000 + i,
        }
    }

    /// A written batch that held a huge payload gives its memory back; an ordinary one keeps
    /// its buffer (no reallocation in steady state).
    #[test]
    fn an_emptied_batch_keeps_only_an_ordinary_buffer() {
        let mut huge = Batch::default();
        huge.push_bytes(&vec![7; 64 << 20]);
        huge.empty();
        assert!(huge.bytes.is_empty());
        assert!(
            huge.bytes.capacity() <= KEPT_BATCH_BYTES,
            "{}",
            huge.bytes.capacity()
        );
        let mut ordinary = Batch::default();
        ordinary.push_bytes(&vec![7; BATCH_BYTES + 1000]);
        let capacity = ordinary.bytes.capacity();
        ordinary.empty();
        assert_eq!(ordinary.bytes.capacity(), capacity);
    }

    /// `next_file` commits the first file and goes on in the second, which declares its own
    /// channel (the first file's ids are unknown to it); on the thread and inline.
    #[test]
    fn next_file_commits_one_file_and_starts_the_next() {
        for inline in [false, true] {
            let dir = tempfile::tempdir().unwrap();
            let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
            let opts = OutputOptions::default();
            let mut out = match inline {
                true => BackgroundOutput::create_inline(&a, &opts).unwrap(),
                false => BackgroundOutput::create(&a, &opts).unwrap(),
            };
            out.add_channel_with_id(1, 0, "/a", "raw", &BTreeMap::new())
                .unwrap();
            out.write_to_known_channel(&header(1, 0), b"first").unwrap();
            out.next_file(&b).unwrap();
            assert!(out.write_to_known_channel(&header(1, 1), b"x").is_err());
            out.add_channel_with_id(2, 0, "/b", "raw", &BTreeMap::new())
                .unwrap();
            out.write_to_known_channel(&header(2, 1), b"second")
                .unwrap();
            out.commit().unwrap();
            for (path, topic, data) in [(&a, "/a", &b"first"[..]), (&b, "/b", b"second")] {
                let bytes = std::fs::read(path).unwrap();
                let msgs: Vec<_> = mcap::MessageStream::new(&bytes)
                    .unwrap()
                    .map(|m| m.unwrap())
                    .collect();
                assert_eq!(msgs.len(), 1, "inline {inline}");
                assert_eq!(
                    (msgs[0].channel.topic.as_str(), &*msgs[0].data),
                    (topic, data)
                );
            }
            let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
            assert_eq!(names.len(), 2, "no partial file left");
        }
    }

    /// Every record kind goes through in order, over many batches (payloads of 3 x BATCH_BYTES
    /// in all, so batches are reused), and reads back unchanged, payloads copied or encoded in
    /// place alike; also written inline.
    #[test]
    fn writes_every_record_in_order() {
        for inline in [false, true] {
            writes_every_record_in_order_with(inline);
        }
    }

    fn writes_every_record_in_order_with(inline: bool) {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("out.mcap");
        let opts = OutputOptions::default();
        let mut out = if inline {
            BackgroundOutput::create_inline(&dest, &opts).unwrap()
        } else {
            BackgroundOutput::create(&dest, &opts).unwrap()
        };
        out.add_schema_with_id(3, "s", "raw", b"schema bytes")
            .unwrap();
        let meta = BTreeMap::from([("k".to_string(), "v".to_string())]);
        out.add_channel_with_id(7, 3, "/a", "raw", &meta).unwrap();
        out.add_channel_with_id(9, 0, "/b", "raw", &BTreeMap::new())
            .unwrap();
        let n = 3 * BATCH_BYTES / 1000;
        let payload =
            |i: u64| -> Vec<u8> { (0..1000).map(|k| ((i * 31 + k) % 251) as u8).collect() };
        // Channel /b's payloads are encoded in place: appended to the batch, not copied.
        for i in 0..n as u64 {
            if i.is_multiple_of(2) {
                out.write_to_known_channel(&header(7, i), &payload(i))
                    .unwrap();
            } else {
                out.write_encoded_to_known_channel(&header(9, i), |b| b.extend(payload(i)))
                    .unwrap();
            }
        }
        out.attach(&mcap::Attachment {
            log_time: 5,
            create_time: 6,
            name: "a.txt".into(),
            media_type: "text/plain".into(),
            data: std::borrow::Cow::Borrowed(b"attached"),
        })
        .unwrap();
        out.write_metadata(&Metadata {
            name: "m".into(),
            metadata: meta.clone(),
        })
        .unwrap();
        out.commit().unwrap();

        let mut messages = 0u64;
        let (mut attachments, mut metadata, mut channels) = (0, 0, Vec::new());
        read_records(&dest, |rec, _| {
            match rec {
                // The summary section repeats the channels.
                Record::Channel(c) if channels.len() < 2 => {
                    channels.push((c.id, c.schema_id, c.topic, c.metadata))
                }
                Record::Message { header: h, data } => {
                    let i = messages;
                    assert_eq!(h, header(if i.is_multiple_of(2) { 7 } else { 9 }, i));
                    assert_eq!(&data[..], &payload(i)[..]);
                    messages += 1;
                }
                Record::Attachment { header, data, .. } => {
                    assert_eq!(
                        (header.name.as_str(), &data[..]),
                        ("a.txt", &b"attached"[..])
                    );
                    attachments += 1;
                }
                Record::Metadata(m) => {
                    assert_eq!((m.name.as_str(), &m.metadata), ("m", &meta));
                    metadata += 1;
                }
                _ => {}
            }
            Ok(())
        })
        .unwrap();
        assert_eq!(messages, n as u64);
        assert_eq!((attachments, metadata), (1, 1));
        assert_eq!(
            channels,
            vec![
                (7, 3, "/a".to_string(), meta.clone()),
                (9, 0, "/b".to_string(), BTreeMap::new())
            ]
        );
    }

    /// Unknown schemas and channels are refused at the call, as `mcap::Writer` refuses them.
    #[test]
    fn refuses_unknown_ids_at_the_call() {
        let dir = tempfile::tempdir().unwrap();
        let mut out =
            BackgroundOutput::create(&dir.path().join("o.mcap"), &OutputOptions::default())
                .unwrap();
        let e = out
            .add_channel_with_id(1, 4, "/x", "raw", &BTreeMap::new())
            .unwrap_err();
        assert!(e.to_string().contains("schema"), "{e}");
        let e = out.write_to_known_channel(&header(2, 0), b"x").unwrap_err();
        assert!(e.to_string().contains("channel"), "{e}");
        let e = (out.write_encoded_to_known_channel(&header(2, 0), |b| b.push(1))).unwrap_err();
        assert!(e.to_string().contains("channel"), "{e}");
        assert!(out.add_schema_with_id(0, "s", "raw", b"").is_err());
    }

    /// An output in `dir` whose writer thread fails on its first batch: channel 1 is declared
    /// twice, for two topics (the call side cannot tell; the MCAP writer refuses it).
    fn failing_output(dir: &Path) -> BackgroundOutput {
        let dest = dir.join("o.mcap");
        let mut out = BackgroundOutput::create(&dest, &OutputOptions::default()).unwrap();
        out.add_channel_with_id(1, 0, "/x", "raw", &BTreeMap::new())
            .unwrap();
        out.add_channel_with_id(1, 0, "/y", "raw", &BTreeMap::new())
            .unwrap();
        out
    }

    /// An error of the writer thread (here a channel id reused for another topic) comes back
    /// from `commit`, and no output (nor temporary file) is left.
    #[test]
    fn writer_errors_reach_the_caller_and_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = failing_output(dir.path());
        let e = format!("{:#}", out.commit().unwrap_err());
        assert!(e.contains("channel 1 (/y)") && e.contains("o.mcap"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// Writes after the writer thread failed are refused, every one (the copying and the
    /// encoding calls alike), instead of filling batches that can no longer be sent.
    #[test]
    fn writes_after_a_writer_error_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut out = failing_output(dir.path());
        let mut first_error = None;
        for i in 0..4000 {
            let r = if i % 2 == 0 {
                out.write_to_known_channel(&header(1, i), &[0u8; 1000])
            } else {
                out.write_encoded_to_known_channel(&header(1, i), |b| b.extend([0u8; 1000]))
            };
            match (r, first_error) {
                (Err(_), None) => first_error = Some(i),
                (Ok(()), Some(at)) => panic!("write {i} accepted after the error at {at}"),
                _ => {}
            }
        }
        assert!(first_error.is_some(), "the writer's error never came back");
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// Dropped without a commit (the caller failed): no output, no temporary file.
    #[test]
    fn drop_without_commit_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("o.mcap");
        let mut out = BackgroundOutput::create(&dest, &OutputOptions::default()).unwrap();
        out.add_channel_with_id(1, 0, "/x", "raw", &BTreeMap::new())
            .unwrap();
        for i in 0..2000 {
            out.write_to_known_channel(&header(1, i), &[0u8; 1000])
                .unwrap();
        }
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
