//! Streams every record of an MCAP file in file order with bounded memory: the sans-I/O
//! `mcap::sans_io::LinearReader` fed from a plain `File`, decompressing one chunk at a time.
//!
//! A linear read is used for every file because it is the one read that is correct for all valid
//! files: files without chunks, without a summary, or whose summary omits schema and channel
//! records (see the MCAP conformance corpus).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use anyhow::{Context, Result};
use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// Largest non-chunk record accepted (protects against corrupted length fields).
const RECORD_LENGTH_LIMIT: usize = 1 << 32;

/// Bytes consumed so far, for progress reporting.
#[derive(Debug, Default, Clone, Copy)]
pub struct ReadStats {
    /// Bytes read from the file.
    pub bytes_read: u64,
}

/// Calls `f` for each record of `path` in file order (records inside chunks are yielded
/// individually). Chunk CRCs are checked. Errors name the file and the byte offset reached.
pub fn read_records(
    path: &Path,
    mut f: impl FnMut(Record<'_>, ReadStats) -> Result<()>,
) -> Result<()> {
    let mut file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let options = LinearReaderOptions::default()
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(RECORD_LENGTH_LIMIT);
    let mut reader = LinearReader::new_with_options(options);
    let mut stats = ReadStats::default();
    while let Some(event) = reader.next_event() {
        let event = event.with_context(|| {
            format!(
                "{}: not a readable MCAP file (failed near byte {})",
                path.display(),
                stats.bytes_read
            )
        })?;
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = loop {
                    match file.read(reader.insert(need)) {
                        Ok(n) => break n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(e) => {
                            return Err(e).with_context(|| format!("reading {}", path.display()))
                        }
                    }
                };
                reader.notify_read(n);
                stats.bytes_read += n as u64;
            }
            LinearReadEvent::Record { opcode, data } => {
                let record = mcap::parse_record(opcode, data).with_context(|| {
                    format!(
                        "{}: malformed record (opcode {opcode:#04x}) near byte {}",
                        path.display(),
                        stats.bytes_read
                    )
                })?;
                f(record, stats)?;
            }
        }
    }
    Ok(())
}
