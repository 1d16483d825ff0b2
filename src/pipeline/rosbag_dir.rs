//! rosbag2 bag directories (as `ros2 bag record` writes them: a folder with `metadata.yaml` and
//! the bag's storage files, `.mcap` or sqlite3 `.db3`, one or several when the recording was
//! split, MCAP files maybe compressed whole as `.mcap.zstd`, messages maybe compressed one by
//! one; a folder without `metadata.yaml` is a bag only when its files carry rosbag2's names,
//! as a recorder that died leaves them):
//! [`open_bag`] finds the files, [`write_metadata`] writes the `metadata.yaml` of an output
//! bag. `track BAG_DIR -o OUT_DIR` ([`super::bag_track`]) tracks the files as one drive.
//!
//! The new `metadata.yaml` is written from the output files' MCAP summaries (channels, schemas,
//! statistics), in the layout of rosbag2 metadata version 5 (ROS 2 Humble; newer rosbag2
//! versions read it too): per topic its name, type (schema name), serialization_format (message
//! encoding), offered_qos_profiles (the channel's metadata value, as rosbag2 stores it) and
//! message count; per file its name, starting time, duration and message count. The output of
//! a sqlite3 bag is an MCAP bag (its files named `NAME_0.mcap` for `NAME_0.db3`).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use mcap::records::Record;

use super::bag_metadata::{read_metadata, BagCompression};
use crate::mcapio::reader::read_summary_records;

/// The storage plugin a bag was written with (`storage_identifier`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// MCAP files (`ros2 bag record -s mcap`, the default from ROS 2 Iron).
    Mcap,
    /// SQLite databases (`.db3`, the default up to ROS 2 Humble), read by
    /// [`super::db3_file`].
    Sqlite3,
}

/// A rosbag2 bag: its directory, its files in recording order, their storage and compression.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bag {
    /// The bag directory.
    pub dir: PathBuf,
    /// Its storage files, in recording order.
    pub files: Vec<PathBuf>,
    /// What the files are.
    pub storage: Storage,
    /// Whether the files, or each message, are compressed.
    pub compression: BagCompression,
    /// Whether the directory has no `metadata.yaml`, its files found by rosbag2's names
    /// ([`open_bag`]): a recording that did not finish.
    pub without_metadata: bool,
}

impl Bag {
    /// The warning of a bag read without its `metadata.yaml`.
    pub fn warning(&self) -> Option<String> {
        let name = |f: &PathBuf| {
            f.file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into())
        };
        let files = match &self.files[..] {
            [one] => format!("its file {}", name(one)),
            [first, .., last] => {
                let n = self.files.len();
                format!(
                    "its {n} files, {} to {}, in that order",
                    name(first),
                    name(last)
                )
            }
            [] => "no file".into(),
        };
        self.without_metadata.then(|| {
            format!(
                "{}: no metadata.yaml (a recording that did not finish?); read as a rosbag2 bag \
                 by the names rosbag2 gives a bag's files: {files}",
                self.dir.display(),
            )
        })
    }

    /// The name of file `i` once decompressed (`drive_0.mcap.zstd` → `drive_0.mcap`): the name
    /// of its output file.
    pub fn output_name(&self, i: usize) -> Result<String> {
        let f = &self.files[i];
        let name = (f.file_name().and_then(|n| n.to_str()))
            .with_context(|| format!("{}: file name is not UTF-8", f.display()))?;
        let name = name.strip_suffix(".zstd").unwrap_or(name);
        Ok(match self.storage {
            Storage::Sqlite3 => format!("{}.mcap", name.strip_suffix(".db3").unwrap_or(name)),
            Storage::Mcap => name.to_string(),
        })
    }
}

/// The bag at `path`, or `None` when `path` is not a directory. A directory is a bag with
/// rosbag2's `metadata.yaml`, or without one when its storage files are named as rosbag2 names
/// them (`DIR_0.mcap`, `DIR_1.mcap`, ...: a recorder that died before writing it); a folder of logs
/// is not one log, and taking it for a bag would make `-o` a directory without a word. Its
/// files are those `metadata.yaml` lists (`relative_file_paths`), or with a `metadata.yaml` that
/// lists none, its one storage file.
pub fn open_bag(path: &Path) -> Result<Option<Bag>> {
    if !path.is_dir() {
        return Ok(None);
    }
    let (mut mcaps, mut db3s, mut metadata) = (Vec::new(), Vec::new(), false);
    for entry in
        std::fs::read_dir(path).with_context(|| format!("cannot read {}", path.display()))?
    {
        let p = entry?.path();
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.ends_with(".mcap") || name.ends_with(".mcap.zstd") {
            mcaps.push(p);
        } else if name.ends_with(".db3") || name.ends_with(".db3.zstd") {
            db3s.push(p);
        } else {
            metadata |= name == "metadata.yaml";
        }
    }
    mcaps.sort();
    db3s.sort();
    if !metadata {
        let Some((files, storage)) = files_by_rosbag2_names(path, &mcaps, &db3s) else {
            return Err(no_metadata(path, &mcaps, &db3s));
        };
        let (dir, compression) = (path.to_path_buf(), BagCompression::None);
        let without_metadata = true;
        return Ok(Some(Bag {
            dir,
            files,
            storage,
            compression,
            without_metadata,
        }));
    }
    let md = read_metadata(path)?;
    let dir = path.display();
    let storage = match md.storage.as_str() {
        "mcap" => Storage::Mcap,
        "sqlite3" => Storage::Sqlite3,
        "" if mcaps.is_empty() && !db3s.is_empty() => Storage::Sqlite3,
        "" => Storage::Mcap,
        other => {
            bail!("{dir}: storage_identifier {other:?}; probmot reads mcap and sqlite3 storage")
        }
    };
    let (found, kind) = match storage {
        Storage::Mcap => (mcaps, ".mcap"),
        Storage::Sqlite3 => (db3s, ".db3"),
    };
    let files = if md.files.is_empty() {
        match found.len() {
            0 => bail!("{dir}: a directory without an {kind} file"),
            1 => found,
            n => bail!(
                "{dir}: metadata.yaml lists no files (relative_file_paths) and the directory \
                 has {n} {kind} files; `ros2 bag reindex {dir}` writes the list"
            ),
        }
    } else {
        let mut files = Vec::new();
        for f in &md.files {
            // As rosbag2 does: the file name, in the bag directory.
            let name = Path::new(f).file_name().unwrap_or(f.as_ref());
            let p = path.join(name);
            if !p.is_file() {
                bail!("{dir}: metadata.yaml lists {f}, which is not in the directory");
            }
            files.push(p);
        }
        files
    };
    let bag = Bag {
        dir: path.to_path_buf(),
        files,
        storage,
        compression: md.compression,
        without_metadata: false,
    };
    Ok(Some(bag))
}

/// Whether the storage file `file` is compressed whole (`NAME.mcap.zstd`, `NAME.db3.zstd`), as
/// rosbag2 names the files of a bag recorded with `--compression-mode file`. By its name, file
/// by file: a recording that did not finish has its last file uncompressed.
pub fn compressed_whole(file: &Path) -> bool {
    file.extension().is_some_and(|e| e == "zstd")
}

/// The storage files of the directory `path` (without `metadata.yaml`) in recording order, when
/// they are named as `ros2 bag record` names them: `DIR_0.EXT`, `DIR_1.EXT`, … with DIR the
/// directory's name, every index from 0 up, all `.mcap` or all `.db3`, each maybe compressed
/// whole (`.zstd`). That is what a recorder leaves that died before writing `metadata.yaml`
/// (ROS 2 Humble writes it only when recording stops); a folder of logs is not named so. A
/// file there both as `NAME` and `NAME.zstd` is read as `NAME`: the recorder died compressing
/// it, after closing it whole.
fn files_by_rosbag2_names(
    path: &Path,
    mcaps: &[PathBuf],
    db3s: &[PathBuf],
) -> Option<(Vec<PathBuf>, Storage)> {
    let base = path.file_name()?.to_str()?;
    let (files, storage, ext) = match (mcaps.is_empty(), db3s.is_empty()) {
        (false, true) => (mcaps, Storage::Mcap, ".mcap"),
        (true, false) => (db3s, Storage::Sqlite3, ".db3"),
        _ => return None,
    };
    let mut numbered: BTreeMap<usize, PathBuf> = BTreeMap::new();
    for f in files {
        let name = f.file_name()?.to_str()?;
        let name = name.strip_suffix(".zstd").unwrap_or(name);
        let index = name
            .strip_prefix(base)?
            .strip_prefix('_')?
            .strip_suffix(ext)?;
        if !index.bytes().all(|b| b.is_ascii_digit()) || index.len() > 1 && index.starts_with('0') {
            return None;
        }
        let slot = numbered
            .entry(index.parse().ok()?)
            .or_insert_with(|| f.clone());
        if compressed_whole(slot) {
            slot.clone_from(f);
        }
    }
    (numbered.keys().enumerate())
        .all(|(i, n)| i == *n)
        .then(|| (numbered.into_values().collect(), storage))
}

/// The error for a directory without `metadata.yaml`, by the storage files it holds.
fn no_metadata(path: &Path, mcaps: &[PathBuf], db3s: &[PathBuf]) -> anyhow::Error {
    let dir = path.display();
    let (files, kind) = if mcaps.is_empty() {
        (db3s, ".db3")
    } else {
        (mcaps, ".mcap")
    };
    let base = path
        .file_name()
        .map_or("DIR".into(), |n| n.to_string_lossy());
    let unnamed =
        format!("not named as rosbag2 names a bag's files ({base}_0{kind}, {base}_1{kind}, ...)");
    match files.len() {
        0 => anyhow!("{dir}: a directory without an .mcap file"),
        1 => anyhow!(
            "{dir}: a directory with one {kind} file but no metadata.yaml, {unnamed}, so not a \
             rosbag2 bag: name the file instead ({}); a bag whose recording was cut gets its \
             metadata.yaml back with `ros2 bag reindex`",
            files[0].display()
        ),
        _ if kind == ".db3" => anyhow!(
            "{dir}: a directory of .db3 files without metadata.yaml, {unnamed}, so not a \
             rosbag2 bag; `ros2 bag reindex {dir}` writes it back"
        ),
        n => anyhow!(
            "{dir}: a directory of {n} .mcap files without metadata.yaml, {unnamed}, so not a \
             rosbag2 bag: name the files instead (`probmot track {dir}/*.mcap --out-dir OUT` \
             tracks them all, `fit` and `tune` take them all as `{dir}/*.mcap`; `info`, \
             `plot` and `viz` read one file, `eval --truth {dir}` the folder)"
        ),
    }
}

/// The MCAP file of a one-file bag, or `None` when `path` is not a directory: what the commands
/// that read one file (`plot`, `viz`, `fit`, `tune`, `export`) open. A split or compressed bag
/// is refused with what to do.
pub fn bag_mcap(path: &Path) -> Result<Option<PathBuf>> {
    let Some(mut bag) = open_bag(path)? else {
        return Ok(None);
    };
    let dir = path.display();
    let what = match (bag.storage, bag.compression) {
        (Storage::Sqlite3, _) => Some("a bag with sqlite3 storage (.db3)"),
        _ if bag.files.iter().any(|f| compressed_whole(f)) => {
            Some("a bag of compressed files (compression_mode file)")
        }
        (_, BagCompression::MessageZstd) => {
            Some("a bag of compressed messages (compression_mode message)")
        }
        // Files compressed whole are told by their names (`compressed_whole`), as they are read.
        (Storage::Mcap, BagCompression::None | BagCompression::FileZstd) => None,
    };
    if let Some(what) = what {
        bail!(
            "{dir}: {what}; this command reads an MCAP file: `probmot track {dir} -o OUT_BAG` \
             writes a plain MCAP bag"
        );
    }
    if bag.files.len() > 1 {
        bail!(
            "{dir}: a bag split into {} files; this command reads one file: name one of them \
             ({}), or track the whole drive with `probmot track {dir} -o OUT_BAG`",
            bag.files.len(),
            bag.files[0].display()
        );
    }
    Ok(bag.files.pop())
}

/// `path`, or for a bag directory its MCAP file: what the commands that read one file at a time
/// (`plot`, `viz`, `fit`, `tune`, `export`) open.
pub fn resolve_input(path: &Path) -> Result<PathBuf> {
    Ok(bag_mcap(path)?.unwrap_or_else(|| path.to_path_buf()))
}

/// The files a read of `path` goes through: a bag directory's files, or `path` itself.
pub fn input_files(path: &Path) -> Result<Vec<PathBuf>> {
    Ok(match open_bag(path)? {
        Some(bag) => bag.files,
        None => vec![path.to_path_buf()],
    })
}

/// Refuses an output bag directory that exists and is not empty (as `ros2 bag record` does).
pub fn check_output_dir(dir: &Path) -> Result<()> {
    if dir.exists() {
        let empty = dir.is_dir()
            && std::fs::read_dir(dir)
                .with_context(|| format!("cannot read {}", dir.display()))?
                .next()
                .is_none();
        if !empty {
            bail!(
                "{}: exists; the output of a bag directory is a new bag directory (give a path \
                 that does not exist)",
                dir.display()
            );
        }
    }
    Ok(())
}

/// One topic of the metadata.
struct Topic {
    name: String,
    msgtype: String,
    serialization: String,
    qos: String,
    count: u64,
}

/// A YAML double-quoted scalar (JSON string syntax is valid YAML).
fn quoted(s: &str) -> String {
    serde_json::to_string(s).expect("a string serializes")
}

/// One file of the metadata: name, starting time, duration, message count.
struct FileEntry {
    name: String,
    start: u64,
    duration: u64,
    count: u64,
}

/// Adds the topics and counts of the MCAP file `mcap`'s summary to `topics`; returns its entry.
fn add_file(mcap: &Path, topics: &mut BTreeMap<u16, Topic>) -> Result<FileEntry> {
    let file = mcap.display();
    let Some((_, records)) = read_summary_records(mcap) else {
        bail!("{file}: no readable summary section to write metadata.yaml from");
    };
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut stats = None;
    for rec in records {
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                topics.entry(c.id).or_insert_with(|| Topic {
                    name: c.topic,
                    msgtype: schemas.get(&c.schema_id).cloned().unwrap_or_default(),
                    serialization: c.message_encoding,
                    qos: (c.metadata.get("offered_qos_profiles").cloned()).unwrap_or_default(),
                    count: 0,
                });
            }
            Record::Statistics(s) => stats = Some(s),
            _ => {}
        }
    }
    let stats = stats.with_context(|| format!("{file}: no statistics record"))?;
    for (id, n) in &stats.channel_message_counts {
        if let Some(t) = topics.get_mut(id) {
            t.count += *n;
        }
    }
    let (start, duration) = match stats.message_count {
        0 => (0, 0),
        _ => (
            stats.message_start_time,
            stats.message_end_time - stats.message_start_time,
        ),
    };
    let name = (mcap.file_name().and_then(|n| n.to_str()))
        .with_context(|| format!("{file}: file name is not UTF-8"))?;
    Ok(FileEntry {
        name: name.to_string(),
        start,
        duration,
        count: stats.message_count,
    })
}

/// Writes `dir/metadata.yaml` for the bag's MCAP files `mcaps` (inside `dir`, in recording
/// order), from their summaries. The files are plain MCAP files (`compression_mode` empty).
pub fn write_metadata(dir: &Path, mcaps: &[PathBuf]) -> Result<()> {
    let mut topics: BTreeMap<u16, Topic> = BTreeMap::new();
    let files: Vec<FileEntry> = (mcaps.iter())
        .map(|m| add_file(m, &mut topics))
        .collect::<Result<_>>()?;
    let counted = files.iter().filter(|f| f.count > 0);
    let start = counted.clone().map(|f| f.start).min().unwrap_or(0);
    let end = counted.map(|f| f.start + f.duration).max().unwrap_or(0);
    let count: u64 = files.iter().map(|f| f.count).sum();
    let mut y = String::from("rosbag2_bagfile_information:\n  version: 5\n");
    y.push_str("  storage_identifier: mcap\n");
    let _ = writeln!(y, "  duration:\n    nanoseconds: {}", end - start);
    let _ = writeln!(y, "  starting_time:\n    nanoseconds_since_epoch: {start}");
    let _ = writeln!(y, "  message_count: {count}");
    y.push_str("  topics_with_message_count:\n");
    for t in topics.values() {
        let _ = writeln!(y, "    - topic_metadata:");
        let _ = writeln!(y, "        name: {}", quoted(&t.name));
        let _ = writeln!(y, "        type: {}", quoted(&t.msgtype));
        let _ = writeln!(
            y,
            "        serialization_format: {}",
            quoted(&t.serialization)
        );
        let _ = writeln!(y, "        offered_qos_profiles: {}", quoted(&t.qos));
        let _ = writeln!(y, "      message_count: {}", t.count);
    }
    y.push_str("  compression_format: \"\"\n  compression_mode: \"\"\n");
    y.push_str("  relative_file_paths:\n");
    for f in &files {
        let _ = writeln!(y, "    - {}", quoted(&f.name));
    }
    y.push_str("  files:\n");
    for f in &files {
        let _ = writeln!(y, "    - path: {}", quoted(&f.name));
        let _ = writeln!(
            y,
            "      starting_time:\n        nanoseconds_since_epoch: {}",
            f.start
        );
        let _ = writeln!(y, "      duration:\n        nanoseconds: {}", f.duration);
        let _ = writeln!(y, "      message_count: {}", f.count);
    }
    let path = dir.join("metadata.yaml");
    let tmp = dir.join(".metadata.yaml.tmp");
    std::fs::write(&tmp, y).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bag_without_metadata_is_read_only_by_rosbag2_names() {
        let d = tempfile::tempdir().unwrap();
        let bag = d.path().join("rec");
        std::fs::create_dir(&bag).unwrap();
        let touch = |name: &str| std::fs::write(bag.join(name), b"").unwrap();
        let rm = |name: &str| std::fs::remove_file(bag.join(name)).unwrap();
        let files = |names: &[&str]| names.iter().map(|n| bag.join(n)).collect::<Vec<_>>();
        for n in ["rec_0.mcap", "rec_1.mcap", "rec_10.mcap"] {
            touch(n);
        }
        // A gap in the indices (rec_2 .. rec_9 missing): not a whole recording.
        let e = open_bag(&bag).unwrap_err().to_string();
        assert!(
            e.contains("not named as rosbag2 names a bag's files (rec_0.mcap"),
            "{e}"
        );
        rm("rec_10.mcap");
        touch("rec_2.mcap");
        let b = open_bag(&bag).unwrap().unwrap();
        assert_eq!(b.files, files(&["rec_0.mcap", "rec_1.mcap", "rec_2.mcap"]));
        assert_eq!(
            (b.storage, b.compression),
            (Storage::Mcap, BagCompression::None)
        );
        let w = b.warning().unwrap();
        assert!(
            w.contains("no metadata.yaml")
                && w.contains("3 files")
                && w.contains("rec_0.mcap to rec_2.mcap"),
            "{w}"
        );
        // Compressed whole, file by file; both `NAME` and `NAME.zstd`: `NAME`, the whole one.
        touch("rec_0.mcap.zstd");
        touch("rec_3.mcap.zstd");
        let b = open_bag(&bag).unwrap().unwrap();
        let names = ["rec_0.mcap", "rec_1.mcap", "rec_2.mcap", "rec_3.mcap.zstd"];
        assert_eq!(b.files, files(&names));
        rm("rec_0.mcap.zstd");
        rm("rec_3.mcap.zstd");
        // Another name, a leading zero, a gap or two storage kinds: refused.
        for odd in [
            "other_3.mcap",
            "rec_03.mcap",
            "rec_4.mcap.zstd",
            "rec_3.db3",
        ] {
            touch(odd);
            let e = open_bag(&bag).unwrap_err().to_string();
            assert!(e.contains("without metadata.yaml"), "{odd}: {e}");
            rm(odd);
        }
        for n in ["rec_0.mcap", "rec_1.mcap", "rec_2.mcap"] {
            rm(n);
        }
        touch("rec_0.db3");
        touch("rec_0.db3-wal");
        let b = open_bag(&bag).unwrap().unwrap();
        assert_eq!(
            (b.files, b.storage),
            (files(&["rec_0.db3"]), Storage::Sqlite3)
        );
        // With its metadata.yaml, a bag gives no warning.
        std::fs::write(bag.join("metadata.yaml"), "rosbag2_bagfile_information:\n").unwrap();
        assert_eq!(open_bag(&bag).unwrap().unwrap().warning(), None);
    }

    #[test]
    fn open_bag_finds_the_listed_files_and_refuses_others() {
        let d = tempfile::tempdir().unwrap();
        assert!(open_bag(&d.path().join("x.mcap")).unwrap().is_none());
        let e = open_bag(d.path()).unwrap_err().to_string();
        assert!(e.contains("without an .mcap"), "{e}");
        std::fs::write(d.path().join("b_0.db3"), b"").unwrap();
        let e = open_bag(d.path()).unwrap_err().to_string();
        assert!(e.contains("one .db3 file but no metadata.yaml"), "{e}");
        std::fs::write(d.path().join("b_0.mcap"), b"").unwrap();
        std::fs::write(d.path().join("metadata.yaml"), b"x: 1").unwrap();
        let e = format!("{:#}", open_bag(d.path()).unwrap_err());
        assert!(
            e.contains("metadata.yaml") && e.contains("rosbag2_bagfile"),
            "{e}"
        );
        let minimal = "rosbag2_bagfile_information:\n";
        std::fs::write(d.path().join("metadata.yaml"), minimal).unwrap();
        assert_eq!(bag_mcap(d.path()).unwrap(), Some(d.path().join("b_0.mcap")));
        std::fs::write(d.path().join("b_1.mcap"), b"").unwrap();
        let e = open_bag(d.path()).unwrap_err().to_string();
        assert!(e.contains("lists no files"), "{e}");
        let listed = "rosbag2_bagfile_information:\n  relative_file_paths:\n  - b_1.mcap\n  - \
                      b_0.mcap\n  - b_2.mcap\n";
        std::fs::write(d.path().join("metadata.yaml"), listed).unwrap();
        let e = open_bag(d.path()).unwrap_err().to_string();
        assert!(e.contains("lists b_2.mcap"), "{e}");
        std::fs::write(d.path().join("metadata.yaml"), &listed[..listed.len() - 13]).unwrap();
        let bag = open_bag(d.path()).unwrap().unwrap();
        let order = [d.path().join("b_1.mcap"), d.path().join("b_0.mcap")];
        assert_eq!(bag.files, order, "in the order metadata.yaml lists them");
        let e = bag_mcap(d.path()).unwrap_err().to_string();
        assert!(e.contains("split into 2"), "{e}");
    }

    /// A sqlite3 bag is found by its `storage_identifier` (or, without one, by holding only
    /// `.db3` files), compressed whole or not; its output files are MCAP files; the commands
    /// that read one MCAP file send it to `track`.
    #[test]
    fn a_sqlite3_bag_is_opened_and_its_output_is_mcap() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("b_0.db3"), b"").unwrap();
        std::fs::write(d.path().join("b_1.db3"), b"").unwrap();
        let listed = "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  \
                      relative_file_paths:\n  - b_0.db3\n  - b_1.db3\n";
        std::fs::write(d.path().join("metadata.yaml"), listed).unwrap();
        let bag = open_bag(d.path()).unwrap().unwrap();
        assert_eq!(bag.storage, Storage::Sqlite3);
        assert_eq!(bag.output_name(1).unwrap(), "b_1.mcap");
        let e = bag_mcap(d.path()).unwrap_err().to_string();
        assert!(e.contains("sqlite3") && e.contains("probmot track"), "{e}");
        let unnamed = listed.replace("  storage_identifier: sqlite3\n", "");
        std::fs::write(d.path().join("metadata.yaml"), unnamed).unwrap();
        assert_eq!(
            open_bag(d.path()).unwrap().unwrap().storage,
            Storage::Sqlite3
        );
        let zstd = listed.replace(".db3\n", ".db3.zstd\n")
            + "  compression_mode: file\n  compression_format: zstd\n";
        std::fs::write(d.path().join("metadata.yaml"), zstd).unwrap();
        std::fs::write(d.path().join("b_0.db3.zstd"), b"").unwrap();
        std::fs::write(d.path().join("b_1.db3.zstd"), b"").unwrap();
        let bag = open_bag(d.path()).unwrap().unwrap();
        assert_eq!(bag.compression, BagCompression::FileZstd);
        assert_eq!(bag.output_name(0).unwrap(), "b_0.mcap");
    }

    #[test]
    fn output_directory_must_be_new_or_empty() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        check_output_dir(&out).unwrap();
        std::fs::create_dir(&out).unwrap();
        check_output_dir(&out).unwrap();
        std::fs::write(out.join("x"), b"").unwrap();
        assert!(check_output_dir(&out).is_err());
    }

    #[test]
    fn quoted_strings_are_yaml_scalars() {
        assert_eq!(quoted("/tracks"), "\"/tracks\"");
        assert_eq!(quoted("a\"b\n"), "\"a\\\"b\\n\"");
    }
}
