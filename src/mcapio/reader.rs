//! Streams every record of an MCAP file in file order with bounded memory: the sans-I/O
//! `mcap::sans_io::LinearReader` fed from any byte source ([`McapInput`]: a file, bytes in
//! memory), decompressing one chunk at a time. The functions taking a path are thin adapters.
//!
//! A linear read is used for every file because it is the one read that is correct for all valid
//! files: files without chunks, without a summary, or whose summary omits schema and channel
//! records (see the MCAP conformance corpus).
//!
//! Malformed files are errors, never panics, and cost memory only for the bytes really in the
//! file (or really decompressed from it), whatever their length fields claim. Three things here
//! make it so (see the findings in `fuzz/README.md`):
//! * the file is read in blocks of `READ_BLOCK`, so a record header claiming gigabytes in a
//!   short file fails at end of file instead of first allocating what it claims;
//! * chunks are decompressed and split into records as a stream by [`super::chunk_stream`], not
//!   by the `LinearReader`, which does not check a record in an uncompressed chunk against the
//!   chunk's end (overflow panic); a chunk or record above
//!   [`size_limit`] is refused;
//! * `check_record` walks the length fields `mcap::parse_record` trusts.
//!
//! Every record is checked by the structural validation (`validate.rs`) before it is handed on.

use std::fs::File;
use std::io::{Cursor, Read, Seek, SeekFrom};
use std::ops::ControlFlow;
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::{op, ChunkHeader, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::chunk_stream::{for_each_record, limit_hint, size_limit, CrcMismatch};
pub use super::cut_short::{CutAt, CutShort};
use super::validate::Validator;

/// Largest buffer given to the reader for one `read`. The reader asks for a whole record at once;
/// reading in blocks makes its buffer grow only with bytes that are really in the file.
const READ_BLOCK: usize = 1 << 20;

/// Bytes consumed so far, for progress reporting.
#[derive(Debug, Default, Clone, Copy)]
pub struct ReadStats {
    /// Bytes read from the file.
    pub bytes_read: u64,
}

/// An MCAP input: any byte source (a file, bytes in memory, a socket buffered into a cursor)
/// with the name its errors give it.
pub struct McapInput<R> {
    /// Named in errors, e.g. the path of the file.
    pub name: String,
    /// The bytes of the MCAP file.
    pub source: R,
    /// Where a read ([`read_records_to_cut`]) found the file cut short: later reads stop there
    /// too, so that every read gives the same records, also of a file still being written (a
    /// recording in progress grows between `track`'s two passes).
    cut_at: Option<u64>,
}

impl<R> McapInput<R> {
    /// The input of the bytes of `source`, named `name` in errors.
    pub fn new(name: impl Into<String>, source: R) -> Self {
        let name = name.into();
        McapInput {
            name,
            source,
            cut_at: None,
        }
    }

    /// Where a read of this input found it cut short (the end of its last whole record), and
    /// every later read stops; `None` while no read found a cut.
    pub fn cut_at(&self) -> Option<u64> {
        self.cut_at
    }

    /// Makes every read stop at byte `at`, as if a read had found the file cut short there
    /// (for an input made anew for each read, e.g. one file of a bag).
    pub fn stop_at(&mut self, at: Option<u64>) {
        self.cut_at = at;
    }
}

impl McapInput<File> {
    /// Opens the file at `path`, named by its path.
    pub fn open(path: &Path) -> Result<Self> {
        let source = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        Ok(McapInput::new(path.display().to_string(), source))
    }

    /// [`McapInput::open`] for a reader that seeks and reads its input more than once
    /// (`track`: to the summary section, and back to the start for a second pass). A
    /// directory, FIFO, pipe or device is refused by name before it is opened: a FIFO would
    /// otherwise block the open, and a pipe on `/dev/stdin` fail with a puzzling "Bad magic
    /// number" once its first bytes were consumed.
    pub fn open_regular(path: &Path) -> Result<Self> {
        let m =
            std::fs::metadata(path).with_context(|| format!("cannot open {}", path.display()))?;
        if !m.is_file() {
            let what = match () {
                _ if m.is_dir() => "a directory",
                _ => "not seekable (a pipe, FIFO or device)",
            };
            bail!(
                "{}: {what}: track reads its input more than once; give a regular file (e.g. \
                 save the stream to a file first)",
                path.display()
            );
        }
        Self::open(path)
    }
}

impl<'a> McapInput<Cursor<&'a [u8]>> {
    /// The MCAP file held in `bytes`, named `name` in errors.
    pub fn from_bytes(name: impl Into<String>, bytes: &'a [u8]) -> Self {
        McapInput::new(name, Cursor::new(bytes))
    }
}

impl<R: Read + Seek> McapInput<R> {
    /// Goes back to the start of the input, for another pass.
    pub fn rewind(&mut self) -> Result<()> {
        (self.source.rewind())
            .with_context(|| format!("cannot go back to the start of {}", self.name))
    }
}

/// Calls `f` for each record of `path` in file order (records inside chunks are yielded
/// individually). Chunk CRCs are checked. Errors name the file and the byte offset reached.
pub fn read_records(path: &Path, f: impl FnMut(Record<'_>, ReadStats) -> Result<()>) -> Result<()> {
    read_records_from(&mut McapInput::open(path)?, f)
}

/// [`read_records`] over any input, from where its source is (its start, when new).
pub fn read_records_from<R: Read>(
    input: &mut McapInput<R>,
    mut f: impl FnMut(Record<'_>, ReadStats) -> Result<()>,
) -> Result<()> {
    read_records_while(input, |rec, stats| f(rec, stats).map(ControlFlow::Continue))
}

/// [`read_records_from`], stopping early (without an error) when `f` says
/// [`ControlFlow::Break`]. A file cut short is an error ([`CutShort::error`]).
pub fn read_records_while<R: Read>(
    input: &mut McapInput<R>,
    f: impl FnMut(Record<'_>, ReadStats) -> Result<ControlFlow<()>>,
) -> Result<()> {
    match read_records_to_cut(input, f)? {
        None => Ok(()),
        Some(cut) => bail!(cut.error()),
    }
}

/// [`read_records_while`], except that a file cut short (it ends in the middle of a record,
/// after at least its header record) is read up to its last whole record, and where it was cut
/// is returned instead of an error. For the commands that read recordings as recorders leave
/// them (see [`super::cut_short`]).
pub fn read_records_to_cut<R: Read>(
    input: &mut McapInput<R>,
    mut f: impl FnMut(Record<'_>, ReadStats) -> Result<ControlFlow<()>>,
) -> Result<Option<CutShort>> {
    let stop_at = input.cut_at;
    // Errors show the input's name like a path.
    let path = Path::new(input.name.as_str());
    let file = &mut input.source;
    let options = LinearReaderOptions::default()
        .with_emit_chunks(true)
        .with_record_length_limit(usize::try_from(size_limit()).unwrap_or(usize::MAX));
    let mut reader = LinearReader::new_with_options(options);
    let mut stats = ReadStats::default();
    let mut chunk_buf = Vec::new();
    let mut validator = Validator::default();
    // Where the next record starts: after the magic.
    let mut offset = mcap::MAGIC.len() as u64;
    let mut in_summary = false;
    while let Some(event) = reader.next_event() {
        let cut = |complete_bytes, stats: ReadStats| CutShort {
            file: path.display().to_string(),
            at: CutAt::Mcap {
                complete_bytes,
                file_bytes: stats.bytes_read,
                in_summary,
            },
        };
        if let Err(mcap::McapError::UnexpectedEof) = event {
            // After a whole header record, the records before the cut are a recording.
            if offset > mcap::MAGIC.len() as u64 {
                let cut = cut(offset, stats);
                input.cut_at = Some(offset);
                return Ok(Some(cut));
            }
        }
        let event = event.map_err(|e| unreadable(path, e, stats.bytes_read))?;
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = loop {
                    match file.read(reader.insert(need.min(READ_BLOCK))) {
                        Ok(n) => break n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        // A decompressing source (a `.mcap.zstd` file of a bag) whose
                        // compressed file is cut short: its end, so the MCAP file is cut short.
                        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => break 0,
                        Err(e) => {
                            return Err(e).with_context(|| format!("reading {}", path.display()))
                        }
                    }
                };
                reader.notify_read(n);
                stats.bytes_read += n as u64;
            }
            LinearReadEvent::Record { opcode, data } => {
                let malformed = || {
                    format!(
                        "{}: malformed record (opcode {opcode:#04x}) near byte {}",
                        path.display(),
                        stats.bytes_read
                    )
                };
                let at = offset;
                offset += 9 + data.len() as u64;
                // Where an earlier read found the file cut short: what follows is not read, for
                // every read to give the same records.
                if stop_at.is_some_and(|end| offset > end) {
                    return Ok(Some(cut(at, stats)));
                }
                let record = parse_record(opcode, data).with_context(malformed)?;
                let Record::Chunk { header, data } = record else {
                    in_summary |= matches!(record, Record::DataEnd(_));
                    let here = || format!("byte {at}");
                    validator
                        .check(&record, here)
                        .map_err(|e| invalid(path, e))?;
                    if f(record, stats)?.is_break() {
                        return Ok(None);
                    }
                    continue;
                };
                let (buf, v) = (&mut chunk_buf, &mut validator);
                if read_chunk(path, at, &header, &data, buf, v, stats, &mut f)?.is_break() {
                    return Ok(None);
                }
            }
        }
    }
    Ok(None)
}

/// The error of a file the reader cannot go on with, `bytes_read` into it, with a hint where
/// the likely cause is known.
fn unreadable(path: &Path, e: mcap::McapError, bytes_read: u64) -> anyhow::Error {
    let hint = match e {
        mcap::McapError::UnexpectedEof if bytes_read == 0 => "; the file is empty",
        // Not even the 8-byte magic: nothing a recorder wrote.
        mcap::McapError::UnexpectedEof if bytes_read < 8 => {
            "; the file is too short to be an MCAP file"
        }
        // (A file cut short after its header record is read up to the cut.)
        mcap::McapError::UnexpectedEof => {
            "; the file is cut short inside its header record, so it holds nothing"
        }
        mcap::McapError::RecordTooLarge { len, .. } => &format!("; {}", limit_hint(len)),
        // Some other file named .mcap: a ROS 1 bag or a sqlite3 rosbag2 file is the likely one.
        mcap::McapError::BadMagic => {
            "; it does not start with MCAP's magic bytes, so it is not an MCAP file (a ROS 2 .db3 \
             file: `probmot track` reads it, or its bag directory, and writes MCAP; a ROS 1 .bag \
             converts with `mcap convert IN OUT.mcap`, the mcap CLI, https://mcap.dev)"
        }
        _ => "",
    };
    anyhow::Error::new(e).context(format!(
        "{}: not a readable MCAP file (failed near byte {bytes_read}){hint}",
        path.display(),
    ))
}

/// Hands each record of the chunk at byte `at` of `path` to `f`, checked by `validator` first.
/// An error of `f` or of the validation is returned as is (a CRC mismatch of the chunk takes
/// its place); anything else wrong is reported as a malformed chunk at `at`.
#[allow(clippy::too_many_arguments)]
fn read_chunk(
    path: &Path,
    at: u64,
    header: &ChunkHeader,
    data: &[u8],
    buf: &mut Vec<u8>,
    validator: &mut Validator,
    stats: ReadStats,
    f: &mut impl FnMut(Record<'_>, ReadStats) -> Result<ControlFlow<()>>,
) -> Result<ControlFlow<()>> {
    let mut stopped = None;
    let mut broke = false;
    let res = for_each_record(header, data, buf, |opcode, body, inner| {
        let record = parse_record(opcode, body).with_context(|| {
            format!("malformed record (opcode {opcode:#04x}) at byte {inner} of its records")
        })?;
        let step = (validator)
            .check(&record, || {
                format!("byte {inner} of the records of the chunk at byte {at}")
            })
            .map_err(|e| invalid(path, e))
            .and_then(|()| f(record, stats));
        match step {
            Ok(ControlFlow::Continue(())) => Ok(()),
            Ok(ControlFlow::Break(())) => {
                broke = true;
                Err(anyhow::anyhow!(
                    "stopped early by the reader of the records"
                ))
            }
            Err(e) => {
                stopped = Some(e);
                Err(anyhow::anyhow!("stopped by the reader of the records"))
            }
        }
    });
    match (res, stopped) {
        (Ok(()), _) => Ok(ControlFlow::Continue(())),
        (Err(e), None) if broke && !e.is::<CrcMismatch>() => Ok(ControlFlow::Break(())),
        (Err(e), Some(caller)) if !e.is::<CrcMismatch>() => Err(caller),
        (Err(e), _) => Err(e.context(format!("{}: malformed chunk at byte {at}", path.display()))),
    }
}

/// A validation error of the file at `path`.
fn invalid(path: &Path, e: anyhow::Error) -> anyhow::Error {
    e.context(format!("{}: not a valid MCAP file", path.display()))
}

/// Largest summary section read by [`read_summary_records`].
const SUMMARY_LIMIT: u64 = 64 << 20;

/// Whether the file has a metadata record named `name`, from its summary alone (the metadata
/// index, or statistics counting no metadata); `None` when the summary cannot say (no summary,
/// or metadata without an index), and the file has to be read.
pub fn has_metadata(path: &Path, name: &str) -> Option<bool> {
    let (_, records) = read_summary_records(path)?;
    let indexed = (records.iter()).any(|r| matches!(r, Record::MetadataIndex(_)));
    let none =
        (records.iter()).any(|r| matches!(r, Record::Statistics(s) if s.metadata_count == 0));
    (indexed || none)
        .then(|| (records.iter()).any(|r| matches!(r, Record::MetadataIndex(m) if m.name == name)))
}

/// The records of the summary section the footer points to, each checked like every record
/// read here; `None` when the file has no summary section, or it is not readable (a file the
/// linear read then reports on), or larger than 64 MiB. Also the header record at the start of
/// the file. Reads only the start and the end of the file.
pub fn read_summary_records(path: &Path) -> Option<(Record<'static>, Vec<Record<'static>>)> {
    read_summary_records_from(&mut File::open(path).ok()?)
}

/// [`read_summary_records`] of any seekable source (left at an unspecified position).
pub fn read_summary_records_from<R: Read + Seek>(
    file: &mut R,
) -> Option<(Record<'static>, Vec<Record<'static>>)> {
    let size = file.seek(SeekFrom::End(0)).ok()?;
    file.seek(SeekFrom::Start(0)).ok()?;
    // The header: magic, opcode, length, body.
    let mut start = [0u8; 17];
    file.read_exact(&mut start).ok()?;
    if start[..8] != mcap::MAGIC[..] || start[8] != op::HEADER {
        return None;
    }
    let len = u64::from_le_bytes(start[9..17].try_into().ok()?);
    if len > size.saturating_sub(17) || len > SUMMARY_LIMIT {
        return None;
    }
    let mut body = vec![0u8; len as usize];
    file.read_exact(&mut body).ok()?;
    let header = parse_record(op::HEADER, &body).ok()?.into_owned();
    // The footer: opcode, length (20), summary start, summary offset start, CRC; then magic.
    const TAIL: u64 = 1 + 8 + 20 + 8;
    if size < 8 + TAIL {
        return None;
    }
    let mut tail = [0u8; TAIL as usize];
    file.seek(SeekFrom::End(-(TAIL as i64))).ok()?;
    file.read_exact(&mut tail).ok()?;
    if tail[0] != op::FOOTER || tail[29..] != mcap::MAGIC[..] {
        return None;
    }
    let summary_start = u64::from_le_bytes(tail[9..17].try_into().ok()?);
    let offsets_start = u64::from_le_bytes(tail[17..25].try_into().ok()?);
    let footer_at = size - TAIL;
    let end = if offsets_start == 0 {
        footer_at
    } else {
        offsets_start
    };
    if summary_start == 0 || summary_start > end || end > footer_at {
        return None;
    }
    if end - summary_start > SUMMARY_LIMIT {
        return None;
    }
    let mut section = vec![0u8; (end - summary_start) as usize];
    file.seek(SeekFrom::Start(summary_start)).ok()?;
    file.read_exact(&mut section).ok()?;
    let mut records = Vec::new();
    let mut rest = &section[..];
    while !rest.is_empty() {
        if rest.len() < 9 {
            return None;
        }
        let opcode = rest[0];
        let len = u64::from_le_bytes(rest[1..9].try_into().ok()?);
        if len > (rest.len() - 9) as u64 {
            return None;
        }
        let (body, next) = rest[9..].split_at(len as usize);
        records.push(parse_record(opcode, body).ok()?.into_owned());
        rest = next;
    }
    Some((header, records))
}

/// [`check_record`], then `mcap::parse_record`.
fn parse_record(opcode: u8, body: &[u8]) -> Result<Record<'_>> {
    check_record(opcode, body).map_err(anyhow::Error::msg)?;
    Ok(mcap::parse_record(opcode, body)?)
}

/// Checks what `mcap::parse_record` takes on trust, so that a malformed record is an error rather
/// than a panic or a huge allocation:
/// * every length-prefixed string fits in the rest of the record (the parser reserves the length
///   a string claims, up to 4 GiB, before reading it);
/// * an attachment has room for its CRC after its data length (the parser slices the data up to
///   4 bytes before the record's end, and panics when that is before the data's start).
///
/// It refuses only records that `parse_record` cannot parse either.
fn check_record(opcode: u8, body: &[u8]) -> Result<(), &'static str> {
    let mut f = Fields(body);
    let ok = match opcode {
        op::HEADER => f.string() && f.string(),
        op::SCHEMA => f.skip(2) && f.string() && f.string(),
        op::CHANNEL => f.skip(4) && f.string() && f.string() && f.string_map(),
        op::CHUNK => f.skip(28) && f.string(),
        op::CHUNK_INDEX => f.skip(32) && f.int_map(2 + 8) && f.skip(8) && f.string(),
        op::ATTACHMENT => {
            if !(f.skip(16) && f.string() && f.string() && f.skip(8)) {
                false
            } else if f.0.len() < 4 {
                return Err("attachment record too short for its CRC");
            } else {
                true
            }
        }
        op::ATTACHMENT_INDEX => f.skip(40) && f.string() && f.string(),
        op::METADATA => f.string() && f.string_map(),
        op::METADATA_INDEX => f.skip(16) && f.string(),
        // Message, schema, channel, attachment, metadata and chunk counts, time range.
        op::STATISTICS => f.skip(42) && f.int_map(2 + 8),
        _ => true,
    };
    if ok {
        Ok(())
    } else {
        Err("a field runs past the end of the record")
    }
}

/// The unread rest of a record, walked field by field the way `mcap::parse_record` reads it.
struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn skip(&mut self, n: usize) -> bool {
        match self.0.get(n..) {
            Some(rest) => {
                self.0 = rest;
                true
            }
            None => false,
        }
    }

    fn u32(&mut self) -> Option<u32> {
        let (head, rest) = self.0.split_first_chunk::<4>()?;
        self.0 = rest;
        Some(u32::from_le_bytes(*head))
    }

    /// A string: `u32` byte length, then the bytes.
    fn string(&mut self) -> bool {
        match self.u32() {
            Some(n) => self.skip(n as usize),
            None => false,
        }
    }

    /// A map: `u32` byte length, then entries until at least that many bytes were read.
    fn map_entries(&mut self, mut entry: impl FnMut(&mut Self) -> bool) -> bool {
        let Some(len) = self.u32() else {
            return false;
        };
        let start = self.0.len();
        while start - self.0.len() < len as usize {
            if !entry(self) {
                return false;
            }
        }
        true
    }

    fn string_map(&mut self) -> bool {
        self.map_entries(|f| f.string() && f.string())
    }

    fn int_map(&mut self, entry_len: usize) -> bool {
        self.map_entries(|f| f.skip(entry_len))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (A FIFO and a pipe on /dev/stdin: `tests/it/hostile.rs`.)
    #[test]
    fn open_regular_refuses_a_directory_by_name_and_opens_a_file() {
        let dir = tempfile::tempdir().unwrap();
        let err = McapInput::open_regular(dir.path())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.starts_with(&format!("{}: a directory", dir.path().display()))
                && err.contains("give a regular file"),
            "{err}"
        );
        let file = dir.path().join("f.mcap");
        std::fs::write(&file, b"12345").unwrap();
        let mut input = McapInput::open_regular(&file).unwrap();
        assert_eq!(input.name, file.display().to_string());
        let mut bytes = Vec::new();
        input.source.read_to_end(&mut bytes).unwrap();
        assert_eq!(bytes, b"12345");
        let missing = dir.path().join("missing.mcap");
        let err = McapInput::open_regular(&missing).err().unwrap().to_string();
        assert_eq!(err, format!("cannot open {}", missing.display()));
    }
}
