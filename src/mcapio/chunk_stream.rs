//! The records of one MCAP chunk, decompressed and split as a stream: memory is the compressed
//! chunk (bytes really in the file), the decompressor's window and one record, whatever the size
//! the chunk declares or really expands to. No index of the chunk's records is built.
//!
//! A chunk whose declared uncompressed size is above the size limit ([`size_limit`], 512 MiB
//! unless raised with [`set_size_limit`], the `--max-chunk-mib` option of the command line) is
//! refused before anything is decompressed: a file of a few KB can declare and really hold
//! gigabytes of zstd-compressed records, which would take time, not memory, to read. The same
//! limit bounds every single record, inside a chunk or not.

use std::io::{BufReader, Read};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{bail, Context, Result};
use mcap::records::ChunkHeader;

/// The default of [`size_limit`]: 512 MiB.
pub const DEFAULT_SIZE_LIMIT: u64 = 512 << 20;

static SIZE_LIMIT: AtomicU64 = AtomicU64::new(DEFAULT_SIZE_LIMIT);

/// The largest chunk (uncompressed) and the largest record read from an MCAP file, in bytes.
pub fn size_limit() -> u64 {
    SIZE_LIMIT.load(Ordering::Relaxed)
}

/// Sets [`size_limit`] for every read that starts afterwards (the command line's
/// `--max-chunk-mib`). Memory grows with the largest record read, not with this limit.
pub fn set_size_limit(bytes: u64) {
    SIZE_LIMIT.store(bytes.max(1), Ordering::Relaxed);
}

/// How to raise the limit, for error messages.
pub(crate) fn limit_hint(needed: u64) -> String {
    format!(
        "the limit is {} bytes ({} MiB); `--max-chunk-mib {}` raises it",
        size_limit(),
        size_limit() >> 20,
        needed.div_ceil(1 << 20)
    )
}

/// Calls `f(opcode, body, at)` for each record of a chunk, in order; `at` is the record's offset
/// in the chunk's uncompressed records. Errors say what is wrong with the chunk; the caller names
/// the file and the chunk's offset. A chunk whose CRC does not match its records is reported as
/// such, even when a record before the mismatch is found malformed first.
pub(crate) fn for_each_record(
    header: &ChunkHeader,
    data: &[u8],
    buf: &mut Vec<u8>,
    mut f: impl FnMut(u8, &[u8], u64) -> Result<()>,
) -> Result<()> {
    // An uncompressed chunk is its records (already in memory), whatever size it declares.
    let size = match header.compression.as_str() {
        "" => data.len() as u64,
        _ => header.uncompressed_size,
    };
    if size > size_limit() {
        bail!(
            "the chunk declares {size} bytes of records uncompressed; {}",
            limit_hint(size)
        );
    }
    let crc = header.uncompressed_crc;
    let mut source = Source::new(&header.compression, data, size, crc != 0)?;
    let result = split(&mut source, size, buf, &mut f);
    if crc == 0 {
        return result;
    }
    // After an error part of the chunk is unread: hash the rest to tell corruption apart.
    let complete = result.is_ok();
    if !complete && std::io::copy(&mut source, &mut std::io::sink()).is_err() {
        return result;
    }
    let found = source.crc();
    if found != crc {
        return Err(CrcMismatch { saved: crc, found }.into());
    }
    result
}

/// A chunk whose records do not match its CRC (reported in place of any other error found in
/// the chunk, which may be a consequence).
#[derive(Debug, thiserror::Error)]
#[error("chunk CRC mismatch: header {saved:#010x}, data {found:#010x}")]
pub(crate) struct CrcMismatch {
    saved: u32,
    found: u32,
}

/// Splits the records out of `source` (which holds at most `size` bytes) into `buf`, one at a
/// time; every record must end inside the chunk, and the chunk must hold its declared size.
fn split(
    source: &mut Source<'_>,
    size: u64,
    buf: &mut Vec<u8>,
    f: &mut impl FnMut(u8, &[u8], u64) -> Result<()>,
) -> Result<()> {
    let mut at = 0u64;
    let mut head = [0u8; 9];
    loop {
        let got = read_full(source, &mut head)?;
        if got == 0 {
            break;
        }
        if got < head.len() {
            if at + (got as u64) < size {
                at += got as u64;
                break;
            }
            bail!("the chunk ends inside a record header (at byte {at} of its records)");
        }
        let opcode = head[0];
        let len = u64::from_le_bytes(head[1..].try_into().expect("8 bytes"));
        let left = size - at - 9;
        if len > left {
            bail!(
                "a record (opcode {opcode:#04x}) at byte {at} of the chunk's records claims \
                 {len} bytes and runs past the end of its chunk ({left} bytes left)"
            );
        }
        if len > size_limit() {
            bail!(
                "a record (opcode {opcode:#04x}) at byte {at} of the chunk's records has {len} \
                 bytes; {}",
                limit_hint(len)
            );
        }
        buf.clear();
        if len <= DECODED_BLOCK as u64 {
            buf.resize(len as usize, 0);
            let got = read_full(source, buf)?;
            buf.truncate(got);
        } else {
            // Grows with the bytes really decompressed, not with the length claimed.
            source.take(len).read_to_end(buf)?;
        }
        if (buf.len() as u64) < len {
            at += 9 + buf.len() as u64;
            break;
        }
        f(opcode, buf, at)?;
        at += 9 + len;
    }
    if at < size {
        bail!("chunk decompresses to {at} bytes, its header says {size}");
    }
    Ok(())
}

/// Reads until `out` is full or the source ends; the bytes read.
fn read_full(source: &mut impl Read, out: &mut [u8]) -> Result<usize> {
    let mut n = 0;
    while n < out.len() {
        match source.read(&mut out[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    Ok(n)
}

/// Decompressed bytes buffered for the reads of record headers and small records.
const DECODED_BLOCK: usize = 64 << 10;

/// A chunk's records as a byte stream, cut at the declared size and hashed as read (when the
/// chunk has a CRC).
struct Source<'a> {
    inner: std::io::Take<Box<dyn Read + 'a>>,
    hasher: Option<crc32fast::Hasher>,
}

impl<'a> Source<'a> {
    fn new(compression: &str, data: &'a [u8], size: u64, hash: bool) -> Result<Self> {
        let inner: Box<dyn Read + 'a> = match compression {
            "" => Box::new(data),
            // Buffered: records are read a few bytes at a time.
            "zstd" => Box::new(BufReader::with_capacity(
                DECODED_BLOCK,
                zstd::stream::read::Decoder::with_buffer(data).context("zstd")?,
            )),
            "lz4" => Box::new(BufReader::with_capacity(
                DECODED_BLOCK,
                lz4::Decoder::new(data).context("lz4")?,
            )),
            other => {
                bail!("unsupported chunk compression '{other}' (supported: zstd, lz4, none)")
            }
        };
        Ok(Source {
            inner: inner.take(size),
            hasher: hash.then(crc32fast::Hasher::new),
        })
    }

    /// The CRC-32 of the bytes read so far.
    fn crc(&self) -> u32 {
        self.hasher.clone().map_or(0, |h| h.finalize())
    }
}

impl Read for Source<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(out)?;
        if let Some(h) = &mut self.hasher {
            h.update(&out[..n]);
        }
        Ok(n)
    }
}
