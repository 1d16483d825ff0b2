//! The harness of the `db3_rows` target: a rosbag2 sqlite3 storage file built from the input's
//! bytes, read the way `track` and `info` read a `.db3` file. The bytes choose the rows of the
//! `topics`, `messages` and (optionally) `message_definitions` tables: topic types probmot
//! decodes and others, topic ids that exist and that do not, any timestamp, any message bytes.
//! An input starting with 0xFF is the file's bytes themselves (a damaged or hostile database).
//! Errors are fine; panics are not, and when `track` succeeds its output must be readable again.

use std::path::{Path, PathBuf};

use probmot::mcapio::source::RecordSource;
use probmot::pipeline::bag_source::BagSource;
use probmot::pipeline::db3_file::read_db3;
use probmot::pipeline::info::path_info;
use rusqlite::Connection;

use crate::read_path::track_and_read_back;

/// Topic types the rows choose from: the detection and transform types probmot decodes, and
/// one it does not.
const TYPES: [&str; 5] = [
    "vision_msgs/msg/Detection3DArray",
    "tf2_msgs/msg/TFMessage",
    "autoware_perception_msgs/msg/DetectedObjects",
    "autoware_auto_perception_msgs/msg/DetectedObjects",
    "std_msgs/msg/String",
];

/// Reads the input's bytes in order; past the end, zeros.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }

    fn take(&mut self, n: usize) -> &[u8] {
        let (a, b) = self.0.split_at(n.min(self.0.len()));
        self.0 = b;
        a
    }

    fn i64(&mut self) -> i64 {
        let mut b = [0u8; 8];
        let t = self.take(8);
        b[..t.len()].copy_from_slice(t);
        i64::from_le_bytes(b)
    }
}

/// The scratch file of this process (libFuzzer runs one input at a time).
fn scratch() -> PathBuf {
    let dir = Path::new("/dev/shm");
    let dir = if dir.is_dir() {
        dir.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("probmot-fuzz-{}.db3", std::process::id()))
}

/// Writes the tables the bytes describe into a new database at `path`.
fn build(path: &Path, data: &[u8]) -> rusqlite::Result<()> {
    let conn = Connection::open(path)?;
    conn.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
           serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
           timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);",
    )?;
    let mut b = Bytes(data);
    let head = b.u8();
    let topics = i64::from(head % 4) + 1;
    for id in 1..=topics {
        let kind = b.u8();
        let msgtype = TYPES[usize::from(kind) % TYPES.len()];
        let encoding = if kind & 0x80 == 0 { "cdr" } else { "json" };
        conn.execute(
            "INSERT INTO topics VALUES (?1, ?2, ?3, ?4, '')",
            rusqlite::params![id, format!("/t{id}"), msgtype, encoding],
        )?;
    }
    if head & 0x40 != 0 {
        let len = usize::from(b.u8()) * 4;
        let text = String::from_utf8_lossy(b.take(len)).into_owned();
        conn.execute_batch(
            "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
               encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL,
               type_description_hash TEXT NOT NULL);",
        )?;
        conn.execute(
            "INSERT INTO message_definitions VALUES (1, ?1, 'ros2msg', ?2, '')",
            rusqlite::params![TYPES[usize::from(head >> 4) % TYPES.len()], text],
        )?;
    }
    while !b.0.is_empty() {
        let topic = i64::from(b.u8()) % (topics + 2);
        let stamp = match b.u8() {
            0..=15 => b.i64(),
            k => 1_700_000_000_000_000_000 + i64::from(k) * 100_000_000,
        };
        let len = usize::from(b.u8()) * 8;
        let bytes = b.take(len).to_vec();
        conn.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
            rusqlite::params![topic, stamp, bytes],
        )?;
    }
    Ok(())
}

/// `data` as a `.db3` file through `read_db3`, `track` (into an MCAP in memory) and `info`.
pub fn db3_rows(data: &[u8]) {
    let path = scratch();
    let _ = std::fs::remove_file(&path);
    match data.split_first() {
        Some((0xFF, raw)) => std::fs::write(&path, raw).expect("write the scratch file"),
        _ => build(&path, data).expect("build the scratch database"),
    }
    let mut records = 0u64;
    let _ = read_db3(&path, &mut |rec, bytes| {
        records += 1;
        std::hint::black_box((&rec, bytes));
        Ok(std::ops::ControlFlow::Continue(()))
    });
    std::hint::black_box(records);

    let mut source = BagSource::sqlite_file(&path);
    std::hint::black_box(source.byte_len());
    track_and_read_back(&mut source);
    if let Ok(info) = path_info(&path, &|_| {}) {
        std::hint::black_box(serde_json::to_string(&info).expect("info serializes"));
    }
    let _ = std::fs::remove_file(&path);
}
