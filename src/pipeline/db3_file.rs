//! One file of a rosbag2 bag with sqlite3 storage (`NAME_0.db3`, the default storage of ROS 2
//! Humble and older) read as the MCAP records a rosbag2 MCAP file of the same recording holds
//! ([`read_db3`]): a header (profile `ros2`), a schema per message type, a channel per topic,
//! every message in timestamp order, then the end of the data section. Everything after this
//! reader (the bag stream of [`super::bag_source`], tracking, the output bag) sees MCAP records
//! only, so a sqlite3 bag is tracked like an MCAP one and its output is an MCAP bag.
//!
//! The tables read are those rosbag2's sqlite3 plugin writes (its schema versions 1 to 4):
//! `topics(id, name, type, serialization_format[, offered_qos_profiles])`,
//! `messages(id, topic_id, timestamp, data)` and, from version 4 (ROS 2 Iron and later),
//! `message_definitions(topic_type, encoding, encoded_message_definition)`. A type with no
//! stored definition (any Humble bag) gets the definition probmot reads it with when it has one
//! (`vision_msgs/msg/Detection3DArray` 4.x, `tf2_msgs/msg/TFMessage`: [`assumed_definition`]),
//! and otherwise a schema record with no text, as rosbag2 leaves a definition it cannot find.
//!
//! The file is opened read-only and with SQLite's defensive settings, and only tables are read
//! (a `messages` view is refused, so a hostile file cannot make a query of it). A message longer
//! than the record size limit (`--max-chunk-mib`) is refused before its bytes are read, as an
//! MCAP record of that size is.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::{Channel, DataEnd, Header, Record, SchemaHeader};
use rusqlite::{Connection, OpenFlags};

use super::db3_messages::read_messages;
use super::scratch_file::ScratchFile;
use crate::mcapio::cut_short::{CutAt, CutShort};

use crate::mcapio::chunk_stream::size_limit;
use crate::msgs::{ros2_tf, ros2_tracks};

pub use super::db3_messages::OnDb3Record;

/// Whether `path` is a regular file that starts as a SQLite database does (a `.db3` file named
/// on its own, without its bag directory). Reads 16 bytes; anything but a regular file is not
/// read at all (a FIFO's bytes would be lost).
pub fn is_sqlite_file(path: &Path) -> bool {
    use std::io::Read;
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut magic = [0u8; 16];
    (std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)))
        .is_ok_and(|()| &magic == b"SQLite format 3\0")
}

/// One row of `topics`.
struct Topic {
    id: i64,
    name: String,
    msgtype: String,
    serialization: String,
    qos: String,
}

/// Opens `path` read-only, refusing what is not a rosbag2 sqlite3 file.
fn open(path: &Path) -> Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = Connection::open_with_flags(path, flags).context("cannot open it with SQLite")?;
    // A hostile file's schema cannot run SQL functions or make a corrupt page look valid.
    conn.set_db_config(rusqlite::config::DbConfig::SQLITE_DBCONFIG_DEFENSIVE, true)?;
    conn.execute_batch("PRAGMA trusted_schema = OFF; PRAGMA cell_size_check = ON;")?;
    for table in ["topics", "messages"] {
        if !has_table(&conn, table)? {
            bail!("not a rosbag2 sqlite3 file: it has no `{table}` table");
        }
    }
    Ok(conn)
}

/// Whether the file has a table (not a view) called `name`.
fn has_table(conn: &Connection, name: &str) -> Result<bool> {
    let n: i64 = conn
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
            [name],
            |r| r.get(0),
        )
        .context("not a readable SQLite file")?;
    Ok(n > 0)
}

/// The column names of `table`.
fn columns(conn: &Connection, table: &str) -> Result<Vec<String>> {
    let mut stmt = conn.prepare(&format!("PRAGMA table_info({table})"))?;
    let names = stmt.query_map([], |r| r.get::<_, String>(1))?;
    Ok(names.collect::<rusqlite::Result<_>>()?)
}

/// The most bytes the text fields of a `topics` row may hold (names, type, QoS profiles are a
/// few kilobytes at most): a hostile file cannot make the reader hold gigabytes of names.
const MAX_TOPIC_ROW: i64 = 1 << 20;

/// Refuses `table` when the value of the aggregate `longest` (a `max(length(...))`) passes
/// `limit` bytes, before any of its rows is read.
fn refuse_long_rows(conn: &Connection, table: &str, longest: &str, limit: i64) -> Result<()> {
    let sql = format!("SELECT coalesce({longest}, 0) FROM {table}");
    let n: i64 = conn
        .query_row(&sql, [], |r| r.get(0))
        .with_context(|| format!("reading the {table} table"))?;
    if n > limit {
        bail!(
            "the {table} table has a row of {n} bytes of text, more than the {limit} probmot reads"
        );
    }
    Ok(())
}

/// The rows of `topics`, by id.
fn topics(conn: &Connection) -> Result<Vec<Topic>> {
    let has_qos = columns(conn, "topics")?
        .iter()
        .any(|c| c == "offered_qos_profiles");
    let qos = if has_qos {
        "offered_qos_profiles"
    } else {
        "''"
    };
    let longest = "max(length(name) + length(type) + length(serialization_format))";
    refuse_long_rows(conn, "topics", longest, MAX_TOPIC_ROW)?;
    if has_qos {
        refuse_long_rows(
            conn,
            "topics",
            "max(length(offered_qos_profiles))",
            MAX_TOPIC_ROW,
        )?;
    }
    let n: i64 = conn.query_row("SELECT count(*) FROM topics", [], |r| r.get(0))?;
    if n > i64::from(u16::MAX) {
        bail!("{n} topics; an MCAP file holds at most 65535 channels");
    }
    let sql = format!("SELECT id, name, type, serialization_format, {qos} FROM topics ORDER BY id");
    let mut stmt = conn.prepare(&sql).context("reading the topics table")?;
    let rows = stmt.query_map([], |r| {
        Ok(Topic {
            id: r.get(0)?,
            name: r.get(1)?,
            msgtype: r.get(2)?,
            serialization: r.get(3)?,
            qos: r.get(4)?,
        })
    })?;
    rows.collect::<rusqlite::Result<_>>()
        .context("reading the topics table")
}

/// The stored definition of each type (`message_definitions`, schema version 4): its schema
/// encoding (`ros2msg`, `ros2idl`) and text. Empty texts are left out.
fn definitions(conn: &Connection) -> Result<HashMap<String, (String, String)>> {
    let mut out = HashMap::new();
    if !has_table(conn, "message_definitions")? {
        return Ok(out);
    }
    let longest = "max(length(topic_type) + length(encoding) + length(encoded_message_definition))";
    let limit = i64::try_from(size_limit()).unwrap_or(i64::MAX);
    refuse_long_rows(conn, "message_definitions", longest, limit)?;
    let mut stmt = conn
        .prepare(
            "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions \
             ORDER BY id",
        )
        .context("reading the message_definitions table")?;
    let rows = stmt.query_map([], |r| {
        Ok((
            r.get::<_, String>(0)?,
            r.get::<_, String>(1)?,
            r.get::<_, String>(2)?,
        ))
    })?;
    for row in rows {
        let (msgtype, encoding, text) = row.context("reading the message_definitions table")?;
        if !text.is_empty() {
            out.entry(msgtype).or_insert((encoding, text));
        }
    }
    Ok(out)
}

/// The `ros2msg` definition probmot decodes `msgtype` with when a bag stores none: the layout of
/// ROS 2 Humble, written into the output so that it decodes by its schemas.
pub fn assumed_definition(msgtype: &str) -> Option<&'static str> {
    match msgtype {
        ros2_tracks::SCHEMA_NAME => Some(ros2_tracks::SCHEMA_TEXT),
        ros2_tf::TF_MESSAGE_SCHEMA => Some(ros2_tf::TF_MESSAGE_TEXT),
        _ => None,
    }
}

/// Hands on the header, schema and channel records of `topics`; returns the channel id of each
/// topic id, or `None` when `f` stopped the read.
fn declare(
    topics: &[Topic],
    defs: &HashMap<String, (String, String)>,
    f: &mut OnDb3Record<'_>,
) -> Result<Option<HashMap<i64, u16>>> {
    let header = Header {
        profile: "ros2".into(),
        library: "rosbag2 sqlite3 storage".into(),
    };
    if f(Record::Header(header), 0)?.is_break() {
        return Ok(None);
    }
    let mut schema_ids: HashMap<&str, u16> = HashMap::new();
    let mut channel_ids = HashMap::new();
    for (i, t) in topics.iter().enumerate() {
        let next = schema_ids.len() + 1;
        let schema_id = match schema_ids.get(t.msgtype.as_str()) {
            Some(&id) => id,
            None => {
                let id = u16::try_from(next).context("more than 65535 message types")?;
                schema_ids.insert(&t.msgtype, id);
                let assumed = assumed_definition(&t.msgtype).unwrap_or("");
                let (encoding, text) = (defs.get(&t.msgtype))
                    .map_or(("ros2msg", assumed), |(e, t)| (e.as_str(), t.as_str()));
                let header = SchemaHeader {
                    id,
                    name: t.msgtype.clone(),
                    encoding: encoding.into(),
                };
                let data = Cow::Borrowed(text.as_bytes());
                if f(Record::Schema { header, data }, 0)?.is_break() {
                    return Ok(None);
                }
                id
            }
        };
        let id = u16::try_from(i + 1).context("more than 65535 topics")?;
        let metadata = BTreeMap::from([("offered_qos_profiles".to_string(), t.qos.clone())]);
        let channel = Channel {
            id,
            topic: t.name.clone(),
            schema_id,
            message_encoding: t.serialization.clone(),
            metadata,
        };
        if f(Record::Channel(channel), 0)?.is_break() {
            return Ok(None);
        }
        channel_ids.insert(t.id, id);
    }
    Ok(Some(channel_ids))
}

/// Reads the sqlite3 storage file `path` as MCAP records, handing each to `f` until it says
/// [`std::ops::ControlFlow::Break`]; returns whether it did. Messages come in timestamp order (ties in
/// the order they were written), each with its log and publish time set to the timestamp.
pub fn read_db3(path: &Path, f: &mut OnDb3Record<'_>) -> Result<bool> {
    Ok(read_db3_as(path, path, &mut None, f)?.0)
}

/// [`read_db3`] of a copy of the file `name` at `path` (a decompressed scratch copy): errors
/// and progress are of `name`. Reads the rows of `messages` up to the id `last_row`; `None`
/// sets it to the file's last row now, so that a later read given it reads the same rows,
/// also of a file still being written (`track`'s two passes). Also returns where the file was
/// found cut short: a crash left it damaged, and its messages were read as far as they could
/// be (`super::db3_messages`).
pub fn read_db3_as(
    path: &Path,
    name: &Path,
    last_row: &mut Option<i64>,
    f: &mut OnDb3Record<'_>,
) -> Result<(bool, Option<CutShort>)> {
    // A file in WAL mode (rosbag2's `resilient` storage preset), with the write-ahead log a
    // recorder that crashed or is still recording leaves beside it (its newest messages):
    // SQLite would write its log and index files beside the input, so a copy of both is read.
    let mut wal = path.as_os_str().to_owned();
    wal.push("-wal");
    let wal = std::path::PathBuf::from(wal);
    let has_log = std::fs::metadata(&wal).is_ok_and(|m| m.is_file() && m.len() > 0);
    let scratch = match has_log || in_wal_mode(path) {
        true => Some(ScratchFile::sqlite_with_wal(path, &wal)?),
        false => None,
    };
    let path = scratch.as_ref().map_or(path, |s| s.path());
    // A header that counts more pages than the file holds (a writer killed while committing):
    // SQLite refuses the file at once, and reads a copy whose header counts the file's pages.
    // (With a write-ahead log SQLite takes the size from the log.)
    let pages = page_counts(path);
    let over = (pages.filter(|_| !has_log))
        .and_then(|(counted, held)| counted.filter(|&c| c > held).map(|c| (c, held)));
    let patched = match over {
        Some((_, held)) => Some(ScratchFile::sqlite_with_page_count(path, held)?),
        None => None,
    };
    let path = patched.as_ref().map_or(path, |s| s.path());
    let shown = name.display();
    let conn = open(path).with_context(|| format!("{shown}"))?;
    let topics = topics(&conn).with_context(|| format!("{shown}"))?;
    let defs = definitions(&conn).with_context(|| format!("{shown}"))?;
    let Some(channels) = declare(&topics, &defs, f)? else {
        return Ok((true, None));
    };
    let file_len = std::fs::metadata(name).map_or(0, |m| m.len());
    let read = read_messages(&conn, &channels, last_row, file_len, f)
        .with_context(|| format!("{shown}"))?;
    let cut = (read.damaged || over.is_some()).then(|| CutShort {
        file: shown.to_string(),
        at: CutAt::Sqlite3 {
            table_whole: !read.damaged,
            rows_read: read.rows,
            last_row: (read.rows > 0).then_some(read.last_row),
            header_pages: over.map(|o| o.0),
            file_pages: pages.map_or(0, |p| p.1),
        },
    });
    if read.stopped {
        return Ok((true, cut));
    }
    let end = Record::DataEnd(DataEnd {
        data_section_crc: 0,
    });
    Ok((f(end, file_len)?.is_break(), cut))
}

/// Whether the SQLite file `path` is in WAL mode (its header's read and write versions are 2).
fn in_wal_mode(path: &Path) -> bool {
    use std::io::Read;
    let mut h = [0u8; 20];
    (std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut h))).is_ok()
        && (h[18] == 2 || h[19] == 2)
}

/// The pages the header of the SQLite file `path` counts (when SQLite trusts that count: it
/// was written by the last writer to change the file) and the pages the file holds.
fn page_counts(path: &Path) -> Option<(Option<u64>, u64)> {
    use std::io::Read;
    let mut h = [0u8; 100];
    std::fs::File::open(path).ok()?.read_exact(&mut h).ok()?;
    let page_size = match u16::from_be_bytes([h[16], h[17]]) {
        1 => 65536,
        n => u64::from(n),
    };
    if page_size < 512 {
        return None;
    }
    let counted = u64::from(u32::from_be_bytes(h[28..32].try_into().ok()?));
    let trusted = h[24..28] == h[92..96];
    let held = std::fs::metadata(path).ok()?.len() / page_size;
    Some((trusted.then_some(counted), held))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ops::ControlFlow;

    /// A sqlite3 storage file made by `sql` (after the tables of schema version 3, which has
    /// no `message_definitions`).
    fn db3(sql: &str) -> tempfile::TempPath {
        let path = tempfile::Builder::new()
            .suffix(".db3")
            .tempfile()
            .unwrap()
            .into_temp_path();
        let conn = Connection::open(&path).unwrap();
        conn.execute_batch(TABLES).unwrap();
        conn.execute_batch(sql).unwrap();
        path
    }

    /// What `read_db3` hands on, one line per record, and its result.
    fn records(path: &Path, stop_after: usize) -> (Vec<String>, Result<bool>) {
        let mut seen = Vec::new();
        let result = read_db3(path, &mut |rec, _| {
            seen.push(match rec {
                Record::Header(h) => format!("header {}", h.profile),
                Record::Schema { header, data } => format!(
                    "schema {} {} {} {:?}",
                    header.id,
                    header.name,
                    header.encoding,
                    String::from_utf8_lossy(&data)
                ),
                Record::Channel(c) => format!(
                    "channel {} {} {} {} {:?}",
                    c.id, c.topic, c.schema_id, c.message_encoding, c.metadata
                ),
                Record::Message { header, data } => {
                    format!(
                        "message {} {} {:?}",
                        header.channel_id, header.log_time, data
                    )
                }
                Record::DataEnd(_) => "end".into(),
                other => format!("{other:?}"),
            });
            Ok(match seen.len() >= stop_after {
                true => ControlFlow::Break(()),
                false => ControlFlow::Continue(()),
            })
        });
        (seen, result)
    }

    /// The tables of rosbag2's sqlite3 schema version 3 (no `message_definitions`).
    const TABLES: &str =
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
               serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
               timestamp INTEGER NOT NULL, data BLOB NOT NULL);";

    const TWO_TOPICS: &str = "
        INSERT INTO topics VALUES (7, '/b', 'pkg/msg/B', 'cdr', 'qos b');
        INSERT INTO topics VALUES (3, '/a', 'pkg/msg/A', 'cdr', 'qos a');
        INSERT INTO topics VALUES (9, '/a2', 'pkg/msg/A', 'cdr', '');
        INSERT INTO messages VALUES (1, 7, 20, x'0102');
        INSERT INTO messages VALUES (2, 3, 10, x'03');
        INSERT INTO messages VALUES (3, 9, 20, x'04');";

    /// A file left in WAL mode with its write-ahead log (a recorder that died): the log's
    /// messages are read, from a scratch copy, and nothing is written beside the input.
    #[test]
    fn a_write_ahead_log_is_read_from_a_copy_and_the_input_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b_0.db3");
        // Written by another process that dies without closing the file (closing would fold
        // the log into it): Python's sqlite3 module and `os._exit`.
        let sql = format!(
            "PRAGMA journal_mode = WAL;
             {TABLES}
             {TWO_TOPICS}
             PRAGMA wal_checkpoint(TRUNCATE);
             INSERT INTO messages VALUES (4, 3, 30, x'05');"
        );
        let script = "import os, sqlite3, sys\n\
                      c = sqlite3.connect(sys.argv[1], isolation_level=None)\n\
                      c.executescript(sys.argv[2])\n\
                      os._exit(0)\n";
        let run = std::process::Command::new("python3")
            .args(["-c", script, path.to_str().unwrap(), &sql])
            .output()
            .expect("python3 runs");
        assert!(run.status.success(), "{run:?}");
        let shm = dir.path().join("b_0.db3-shm");
        let _ = std::fs::remove_file(&shm);
        let snapshot = || -> Vec<(std::path::PathBuf, Vec<u8>)> {
            let mut files: Vec<_> = (std::fs::read_dir(dir.path()).unwrap())
                .map(|e| e.unwrap().path())
                .map(|p| (p.clone(), std::fs::read(p).unwrap()))
                .collect();
            files.sort();
            files
        };
        let before = snapshot();
        assert_eq!(before.len(), 2, "the file and its log");
        let (seen, result) = records(&path, usize::MAX);
        assert!(!result.unwrap());
        assert!(seen.contains(&"message 1 30 [5]".to_string()), "{seen:?}");
        assert_eq!(seen.iter().filter(|l| l.starts_with("message")).count(), 4);
        assert!(snapshot() == before, "the input's directory changed");
        let tmp = std::fs::read_dir(std::env::temp_dir()).unwrap();
        let pid = format!(".probmot-{}-", std::process::id());
        let left = tmp.filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            name.to_string_lossy().starts_with(&pid) && name.to_string_lossy().contains("b_0.db3")
        });
        assert_eq!(left.count(), 0, "a scratch file was left behind");
    }

    /// A file still being written: a second read given the first read's last row reads the
    /// same rows, though rows were added in between.
    #[test]
    fn a_later_read_stops_at_the_first_reads_last_row() {
        let path = db3(TWO_TOPICS);
        let read = |last_row: &mut Option<i64>| {
            let mut messages = Vec::new();
            let stopped = read_db3_as(&path, &path, last_row, &mut |rec, _| {
                if let Record::Message { header, .. } = rec {
                    messages.push(header.log_time);
                }
                Ok(ControlFlow::Continue(()))
            });
            assert_eq!(stopped.unwrap(), (false, None));
            messages
        };
        let mut last_row = None;
        assert_eq!(read(&mut last_row), [10, 20, 20]);
        assert_eq!(last_row, Some(3));
        let conn = Connection::open(&path).unwrap();
        conn.execute_batch("INSERT INTO messages VALUES (4, 3, 5, x'06');")
            .unwrap();
        assert_eq!(read(&mut last_row), [10, 20, 20], "the same rows");
        assert_eq!(
            read(&mut None),
            [5, 10, 20, 20],
            "a new read reads them all"
        );
    }

    /// The log times of the messages a whole read of `path` hands on, and the cut it reports.
    fn stamps_and_cut(path: &Path) -> (Vec<u64>, Option<CutShort>) {
        let mut stamps = Vec::new();
        let (stopped, cut) = read_db3_as(path, path, &mut None, &mut |rec, _| {
            if let Record::Message { header, .. } = rec {
                stamps.push(header.log_time);
            }
            Ok(ControlFlow::Continue(()))
        })
        .unwrap();
        assert!(!stopped);
        (stamps, cut)
    }

    /// What a recorder killed while committing leaves (rosbag2's default pragmas: journal in
    /// memory, no sync): a header counting pages the file does not hold. SQLite refuses such a
    /// file at once; its messages are read in row order as far as the pages go, handed on in
    /// timestamp order, and the cut is reported.
    #[test]
    fn a_file_whose_last_pages_are_missing_is_read_as_far_as_it_goes() {
        // 400 messages of 3000 bytes (about a page each), timestamps not in row order.
        let rows: String = (1..=400)
            .map(|i| {
                format!(
                    "INSERT INTO messages VALUES ({i}, 3, {}, randomblob(3000));",
                    (i * 7919) % 400
                )
            })
            .collect();
        let path = db3(&format!(
            "PRAGMA page_size = 4096; CREATE INDEX timestamp_idx ON messages (timestamp ASC);
             INSERT INTO topics VALUES (3, '/a', 'pkg/msg/A', 'cdr', '');
             {rows}"
        ));
        let whole = std::fs::read(&path).unwrap();
        let read = |bytes: &[u8]| {
            std::fs::write(&path, bytes).unwrap();
            stamps_and_cut(&path)
        };
        let (all, cut) = read(&whole);
        assert_eq!((all.len(), cut), (400, None));
        // A header counting 10 pages more than the file holds, and nothing else amiss.
        let mut over = whole.clone();
        let pages = u32::from_be_bytes(over[28..32].try_into().unwrap());
        over[28..32].copy_from_slice(&(pages + 10).to_be_bytes());
        let (stamps, cut) = read(&over);
        assert_eq!(stamps.len(), 400);
        let w = cut.expect("the header's count is reported").warning();
        assert!(
            w.contains(&format!(
                "counts {} pages and the file holds {pages}; its 400 messages were all read",
                pages + 10
            )),
            "{w}"
        );
        // The last 40 pages never reached the file.
        let (stamps, cut) = read(&whole[..whole.len() - 40 * 4096]);
        let n = stamps.len();
        assert!((300..400).contains(&n), "{n} messages read");
        assert!(
            stamps.windows(2).all(|w| w[0] <= w[1]),
            "in timestamp order"
        );
        let expected: Vec<u64> = {
            let mut e: Vec<u64> = (1..=n as u64).map(|i| (i * 7919) % 400).collect();
            e.sort_unstable();
            e
        };
        assert_eq!(
            stamps, expected,
            "the rows 1 to {n}, in row order up to the cut"
        );
        let Some(CutShort {
            at:
                CutAt::Sqlite3 {
                    table_whole: false,
                    rows_read,
                    last_row,
                    header_pages,
                    file_pages,
                },
            ..
        }) = cut
        else {
            panic!("no cut reported: {cut:?}");
        };
        assert_eq!((rows_read, last_row), (n as u64, Some(n as i64)));
        let pages = (whole.len() / 4096) as u64;
        assert_eq!((header_pages, file_pages), (Some(pages), pages - 40));
        // Nothing is left in the temporary directory.
        let pid = format!(".probmot-{}-", std::process::id());
        let left = (std::fs::read_dir(std::env::temp_dir()).unwrap())
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with(&pid)
            })
            .count();
        assert_eq!(left, 0, "a scratch file was left behind");
    }

    /// The data of a row in the middle of the table spoiled (a pointer of its overflow pages):
    /// each message that can be read is handed on once, in timestamp order, and the read says
    /// where it stopped. SQLite reads the table by the timestamp index (as this build plans
    /// it): the messages of stamps before the spoiled row's, then the rows before it in row
    /// order that come later in time; sorting the table instead, the rows before it in row
    /// order.
    #[test]
    fn a_table_spoiled_midway_is_read_on_in_row_order() {
        let stamp = |i: u64| (i * 7919) % 400;
        let rows: String = (1..=400)
            .map(|i| {
                format!(
                    "INSERT INTO messages VALUES ({i}, 3, {}, randomblob(5000) || \
                     CAST('MARKER-{i}-' AS BLOB) || randomblob(5000));",
                    stamp(i)
                )
            })
            .collect();
        let path = db3(&format!(
            "CREATE INDEX timestamp_idx ON messages (timestamp ASC);
             INSERT INTO topics VALUES (3, '/a', 'pkg/msg/A', 'cdr', '');
             {rows}"
        ));
        let by_index = {
            let conn = Connection::open(&path).unwrap();
            let mut stmt = (conn.prepare(
                "EXPLAIN QUERY PLAN SELECT id, topic_id, timestamp, length(data), data FROM \
                 messages WHERE id <= 1 ORDER BY timestamp, id",
            ))
            .unwrap();
            let details = stmt.query_map([], |r| r.get::<_, String>(3)).unwrap();
            let plan: String = details.map(|d| d.unwrap()).collect();
            plan.contains("timestamp_idx")
        };
        let mut bytes = std::fs::read(&path).unwrap();
        let marker = b"MARKER-200-";
        let at = (bytes.windows(marker.len()))
            .position(|w| w == marker)
            .unwrap();
        // The marker is in the first of the row's two overflow pages, which starts with the
        // number of the next: now a page the file does not have.
        let page = at / 4096 * 4096;
        bytes[page..page + 4].copy_from_slice(&[0xff; 4]);
        std::fs::write(&path, &bytes).unwrap();
        let (stamps, cut) = stamps_and_cut(&path);
        let mut expected: Vec<u64> = (1..=400u64)
            .filter(|&i| i < 200 || by_index && stamp(i) < stamp(200))
            .map(stamp)
            .collect();
        expected.sort_unstable();
        assert_eq!(stamps, expected, "read by the index: {by_index}");
        let Some(CutShort {
            at:
                CutAt::Sqlite3 {
                    table_whole: false,
                    rows_read,
                    last_row,
                    header_pages,
                    ..
                },
            ..
        }) = cut
        else {
            panic!("no cut reported: {cut:?}");
        };
        assert_eq!((rows_read, last_row, header_pages), (199, Some(199), None));
    }

    /// A file left in WAL mode by a recorder that closed it (no log beside it): read from a
    /// copy too, since SQLite would make its log and index files beside the input.
    #[test]
    fn a_file_in_wal_mode_without_its_log_leaves_the_input_alone() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b_0.db3");
        let conn = Connection::open(&path).unwrap();
        conn.execute_batch(&format!(
            "PRAGMA journal_mode = WAL;
             {TABLES}
             {TWO_TOPICS}"
        ))
        .unwrap();
        drop(conn);
        assert!(in_wal_mode(&path));
        let names = || -> Vec<std::ffi::OsString> {
            let mut n: Vec<_> = (std::fs::read_dir(dir.path()).unwrap())
                .map(|e| e.unwrap().file_name())
                .collect();
            n.sort();
            n
        };
        assert_eq!(names(), ["b_0.db3"]);
        let (stamps, cut) = stamps_and_cut(&path);
        assert_eq!((stamps, cut), (vec![10, 20, 20], None));
        assert_eq!(names(), ["b_0.db3"], "files were made beside the input");
    }

    /// Topics become channels in id order, one schema per type (its stored definition, or no
    /// text), messages come in timestamp order (ties by row id), then the end of the data.
    #[test]
    fn a_file_reads_as_the_records_of_an_mcap_file() {
        let path = db3(&format!(
            "{TWO_TOPICS}
             CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
               encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL,
               type_description_hash TEXT NOT NULL);
             INSERT INTO message_definitions VALUES (1, 'pkg/msg/B', 'ros2msg', 'int8 x', '');"
        ));
        let (seen, result) = records(&path, usize::MAX);
        assert!(!result.unwrap());
        assert_eq!(
            seen,
            [
                "header ros2",
                "schema 1 pkg/msg/A ros2msg \"\"",
                "channel 1 /a 1 cdr {\"offered_qos_profiles\": \"qos a\"}",
                "schema 2 pkg/msg/B ros2msg \"int8 x\"",
                "channel 2 /b 2 cdr {\"offered_qos_profiles\": \"qos b\"}",
                "channel 3 /a2 1 cdr {\"offered_qos_profiles\": \"\"}",
                "message 1 10 [3]",
                "message 2 20 [1, 2]",
                "message 3 20 [4]",
                "end",
            ]
        );
        let (seen, result) = records(&path, 7);
        assert!(result.unwrap(), "stopped");
        assert_eq!(seen.len(), 7);
    }

    /// A Humble bag's vision_msgs and tf2_msgs topics get the definitions probmot reads them
    /// with; a stored definition wins.
    #[test]
    fn known_types_without_a_stored_definition_get_probmot_s() {
        let path = db3(
            "INSERT INTO topics VALUES (1, '/d', 'vision_msgs/msg/Detection3DArray', 'cdr', '');
             INSERT INTO topics VALUES (2, '/tf', 'tf2_msgs/msg/TFMessage', 'cdr', '');",
        );
        let (seen, _) = records(&path, usize::MAX);
        assert_eq!(
            seen[1],
            format!(
                "schema 1 vision_msgs/msg/Detection3DArray ros2msg {:?}",
                ros2_tracks::SCHEMA_TEXT
            )
        );
        assert_eq!(
            seen[3],
            format!(
                "schema 2 tf2_msgs/msg/TFMessage ros2msg {:?}",
                ros2_tf::TF_MESSAGE_TEXT
            )
        );
        let sections = crate::msgs::ros2_schema::parse_msg(ros2_tf::TF_MESSAGE_TEXT, "TFMessage");
        assert_eq!(sections.len(), 7, "TFMessage and its six dependencies");
    }

    /// Files and rows that are not what rosbag2 writes are refused, naming the file and the
    /// message; none panics.
    #[test]
    fn bad_files_and_rows_are_named() {
        let error = |path: &Path| format!("{:#}", records(path, usize::MAX).1.unwrap_err());
        let garbage = tempfile::NamedTempFile::new().unwrap();
        std::fs::write(
            garbage.path(),
            b"not a database, not at all; just some bytes",
        )
        .unwrap();
        let e = error(garbage.path());
        assert!(
            e.contains(&garbage.path().display().to_string()) && e.contains("SQLite"),
            "{e}"
        );
        let cases = [
            ("DROP TABLE topics;", "no `topics` table"),
            (
                "DROP TABLE messages; CREATE VIEW messages AS SELECT 1 AS id;",
                "no `messages` table",
            ),
            (
                "UPDATE messages SET topic_id = 5 WHERE id = 2;",
                "message 2 of the messages table: topic_id 5",
            ),
            (
                "UPDATE messages SET timestamp = -1 WHERE id = 3;",
                "message 3 of the messages table: negative timestamp",
            ),
            (
                "UPDATE messages SET data = 4.5 WHERE id = 1;",
                "message 1 of the messages table: its data is Real",
            ),
            (
                "UPDATE topics SET name = printf('%.*c', 2000000, 'x') WHERE id = 3;",
                "the topics table has a row of 2000012 bytes",
            ),
            (
                "WITH RECURSIVE k(v) AS (SELECT 1 UNION ALL SELECT v + 1 FROM k WHERE v < 65535) \
                 INSERT INTO topics SELECT v + 100, 'n', 't', 'cdr', '' FROM k;",
                "65538 topics",
            ),
        ];
        for (sql, expected) in cases {
            let path = db3(&format!("{TWO_TOPICS}\n{sql}"));
            let e = error(&path);
            assert!(e.contains(expected), "{sql}: {e}");
            assert!(e.contains(&path.display().to_string()), "{e}");
        }
    }
}
