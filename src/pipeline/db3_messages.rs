//! The `messages` table of a rosbag2 sqlite3 file, handed on as MCAP message records in
//! timestamp order (ties by row id), as far as the file can be read.
//!
//! rosbag2 writes sqlite3 files, by its default storage preset, with the journal in memory and
//! without syncing; its documentation warns that a crash may then corrupt the file being
//! written. A recorder killed while committing leaves a header that counts pages the file does
//! not hold (the header's count is set right in a scratch copy, `super::db3_file`), or pages
//! half written: SQLite reports "database disk image is malformed" when its read meets them,
//! before `ORDER BY timestamp` gives its first row if it sorts the table, later if it reads it
//! by rosbag2's timestamp index. The table is then read on in row order, as far as its pages
//! can be read ([`read_in_row_order`]). What this reads of killed recordings: docs/ros2.md.

use std::borrow::Cow;
use std::collections::HashMap;
use std::ops::ControlFlow;

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Record};
use rusqlite::types::ValueRef;
use rusqlite::{Connection, ErrorCode, Row};

use crate::mcapio::chunk_stream::{limit_hint, size_limit};

/// The callback of [`super::db3_file::read_db3`]: each record, and the bytes of the file read so
/// far (an estimate from the messages read, for progress).
pub type OnDb3Record<'f> = dyn FnMut(Record<'_>, u64) -> Result<ControlFlow<()>> + 'f;

/// How a read of the messages ended.
pub(super) struct MessagesRead {
    /// Whether the callback stopped the read.
    pub stopped: bool,
    /// Whether the table was damaged, and read in row order as far as it could be.
    pub damaged: bool,
    /// The rows to hand on (up to `last_row`).
    pub rows: u64,
    /// The id of the last of them.
    pub last_row: i64,
}

/// Hands on the rows of `messages` up to the id `last_row` in timestamp order; `last_row`
/// `None` is set to the last row there is (or that could be read), for a later read of the
/// same file to read the same rows.
pub(super) fn read_messages(
    conn: &Connection,
    channels: &HashMap<i64, u16>,
    last_row: &mut Option<i64>,
    file_len: u64,
    f: &mut OnDb3Record<'_>,
) -> Result<MessagesRead> {
    match read_in_timestamp_order(conn, channels, last_row, file_len, f)? {
        Ordered::Read(read) => Ok(read),
        Ordered::Damaged { after } => {
            read_in_row_order(conn, channels, last_row, after, file_len, f)
        }
    }
}

/// How the read by `ORDER BY` ended.
enum Ordered {
    /// Every row was read (or the callback stopped the read).
    Read(MessagesRead),
    /// SQLite found the table corrupt, after handing on the rows up to the key
    /// `(timestamp, id)` `after` (`None`: none).
    Damaged { after: Option<(u64, i64)> },
}

/// Whether `e` is SQLite finding the file corrupt.
fn is_corrupt(e: &rusqlite::Error) -> bool {
    e.sqlite_error_code() == Some(ErrorCode::DatabaseCorrupt)
}

/// The rows of `messages` up to `last_row` by `ORDER BY timestamp, id`, until SQLite finds
/// the table corrupt (before the first row, when it sorts the table; later, when it reads it
/// by the timestamp index rosbag2 makes).
fn read_in_timestamp_order(
    conn: &Connection,
    channels: &HashMap<i64, u16>,
    last_row: &mut Option<i64>,
    file_len: u64,
    f: &mut OnDb3Record<'_>,
) -> Result<Ordered> {
    let bound = last_row.unwrap_or(i64::MAX);
    let counted = conn.query_row(
        "SELECT count(*), max(id) FROM messages WHERE id <= ?1",
        [bound],
        |r| Ok((r.get::<_, i64>(0)?, r.get::<_, Option<i64>>(1)?)),
    );
    let (count, max) = match counted {
        Err(e) if is_corrupt(&e) => return Ok(Ordered::Damaged { after: None }),
        other => other.context("reading the messages table")?,
    };
    // An empty table: no row to read, now or later.
    let last = *last_row.get_or_insert(max.unwrap_or(i64::MIN));
    let ended = |stopped| {
        let (damaged, rows, last_row) = (false, count as u64, last);
        Ordered::Read(MessagesRead {
            stopped,
            damaged,
            rows,
            last_row,
        })
    };
    let mut stmt = conn.prepare(
        "SELECT id, topic_id, timestamp, length(data), data FROM messages WHERE id <= ?1 \
         ORDER BY timestamp, id",
    )?;
    let mut rows = stmt.query([bound])?;
    let (mut read, mut after) = (0u64, None);
    loop {
        let row = match rows.next() {
            Err(e) if is_corrupt(&e) => return Ok(Ordered::Damaged { after }),
            other => other.context("reading the messages table")?,
        };
        let Some(row) = row else {
            return Ok(ended(false));
        };
        read += 1;
        let bytes = file_len.saturating_mul(read) / count.max(1) as u64;
        let record = message(row, channels)?;
        if let Record::Message { header, .. } = &record {
            after = Some((header.log_time, row.get(0)?));
        }
        if f(record, bytes)?.is_break() {
            return Ok(ended(true));
        }
    }
}

/// The rows of `messages` up to `last_row` that can be read in row order, up to the first that
/// cannot (its page, or one of its data's overflow pages, spoiled: the data is selected so that
/// SQLite reads it), then handed on in timestamp order after the key `after` (the rows up to it
/// were handed on already): 16 bytes kept per row, and each row read again by its id.
fn read_in_row_order(
    conn: &Connection,
    channels: &HashMap<i64, u16>,
    last_row: &mut Option<i64>,
    after: Option<(u64, i64)>,
    file_len: u64,
    f: &mut OnDb3Record<'_>,
) -> Result<MessagesRead> {
    let bound = last_row.unwrap_or(i64::MAX);
    let mut stmt = conn.prepare(
        "SELECT id, timestamp, length(data), data FROM messages WHERE id <= ?1 ORDER BY id",
    )?;
    let mut rows = stmt.query([bound])?;
    let mut order: Vec<(u64, i64)> = Vec::new();
    loop {
        let row = match rows.next() {
            Err(e) if is_corrupt(&e) => break,
            other => other.context("reading the messages table in row order")?,
        };
        let Some(row) = row else { break };
        let id: i64 = row.get(0)?;
        let (timestamp, _) = checked(row, id, 1)?;
        order.push((timestamp, id));
    }
    drop(rows);
    let count = order.len() as u64;
    // The last row read; later reads stop at the bound this read had, or at this row.
    let last = order.last().map_or(i64::MIN, |o| o.1);
    last_row.get_or_insert(last);
    order.retain(|&key| after.is_none_or(|a| key > a));
    let ended = |stopped| MessagesRead {
        stopped,
        damaged: true,
        rows: count,
        last_row: last,
    };
    order.sort_unstable();
    let mut by_id = conn.prepare(
        "SELECT id, topic_id, timestamp, length(data), data FROM messages WHERE id = ?1",
    )?;
    let done = count - order.len() as u64;
    for (i, &(_, id)) in order.iter().enumerate() {
        let mut rows = by_id.query([id])?;
        let row = (rows.next())
            .with_context(|| format!("message {id} of the messages table"))?
            .with_context(|| format!("message {id} of the messages table is gone"))?;
        let bytes = file_len.saturating_mul(done + i as u64 + 1) / count.max(1);
        if f(message(row, channels)?, bytes)?.is_break() {
            return Ok(ended(true));
        }
    }
    Ok(ended(false))
}

/// The timestamp (column `at`) and data length (column `at + 1`) of the row `id`, checked: a
/// negative timestamp, and data over the record size limit, are refused (the data unread).
fn checked(row: &Row<'_>, id: i64, at: usize) -> Result<(u64, i64)> {
    let here = || format!("message {id} of the messages table");
    let timestamp: i64 = row.get(at).with_context(here)?;
    let log_time = u64::try_from(timestamp)
        .map_err(|_| anyhow::anyhow!("{}: negative timestamp {timestamp}", here()))?;
    let len: i64 = row.get(at + 1).with_context(here)?;
    if u64::try_from(len).unwrap_or(0) > size_limit() {
        bail!("{}: {len} bytes long; {}", here(), limit_hint(len as u64));
    }
    Ok((log_time, len))
}

/// The message record of a row `(id, topic_id, timestamp, length(data), data)`.
fn message<'r>(row: &'r Row<'_>, channels: &HashMap<i64, u16>) -> Result<Record<'r>> {
    let id: i64 = row.get(0)?;
    let here = || format!("message {id} of the messages table");
    let topic_id: i64 = row.get(1)?;
    let channel_id = *channels
        .get(&topic_id)
        .with_context(|| format!("{}: topic_id {topic_id} is not in the topics table", here()))?;
    let (log_time, _) = checked(row, id, 2)?;
    let data = match row.get_ref(4).with_context(here)? {
        ValueRef::Blob(b) | ValueRef::Text(b) => b,
        other => bail!("{}: its data is {:?}, not bytes", here(), other.data_type()),
    };
    let header = MessageHeader {
        channel_id,
        sequence: 0,
        log_time,
        publish_time: log_time,
    };
    Ok(Record::Message {
        header,
        data: Cow::Borrowed(data),
    })
}
