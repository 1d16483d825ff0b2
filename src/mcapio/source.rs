//! What `track` reads: a source of MCAP records that can be read again from its start, and may
//! have a summary section. One MCAP file ([`McapInput`]) is one; a rosbag2 bag split into several
//! files (`crate::pipeline::bag_source`) is another, read as one stream of records.

use std::io::{Read, Seek};
use std::ops::ControlFlow;

use anyhow::Result;
use mcap::records::Record;

use super::reader::{
    read_records_to_cut, read_summary_records_from, CutShort, McapInput, ReadStats,
};

/// The callback of [`RecordSource::read_while`]: each record in order, and how far the read is.
pub type OnRecord<'f> = dyn FnMut(Record<'_>, ReadStats) -> Result<ControlFlow<()>> + 'f;

/// Records that can be read in order, from the start, as often as needed.
pub trait RecordSource {
    /// Named in errors (e.g. the path of the file).
    fn name(&self) -> &str;
    /// Bytes a whole read goes through, for progress (0 when unknown).
    fn byte_len(&mut self) -> u64;
    /// The header record and the records of the summary section, when the source has a
    /// readable one (see [`read_summary_records_from`]); `None` otherwise.
    fn summary(&mut self) -> Option<(Record<'static>, Vec<Record<'static>>)>;
    /// Reads every record from the start, in order, until `f` says [`ControlFlow::Break`].
    /// A source of several files gives each file's header record before its records. A file
    /// cut short (a recording that did not finish) is read up to its last whole record, and
    /// returned among the cuts met, for the caller to warn of.
    fn read_while(&mut self, f: &mut OnRecord<'_>) -> Result<Vec<CutShort>>;
}

impl<R: Read + Seek> RecordSource for McapInput<R> {
    fn name(&self) -> &str {
        &self.name
    }

    fn byte_len(&mut self) -> u64 {
        self.source.seek(std::io::SeekFrom::End(0)).unwrap_or(0)
    }

    fn summary(&mut self) -> Option<(Record<'static>, Vec<Record<'static>>)> {
        read_summary_records_from(&mut self.source)
    }

    fn read_while(&mut self, f: &mut OnRecord<'_>) -> Result<Vec<CutShort>> {
        self.rewind()?;
        Ok(read_records_to_cut(self, f)?.into_iter().collect())
    }
}
