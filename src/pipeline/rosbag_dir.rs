//! rosbag2 bag directories (as `ros2 bag record -s mcap` writes them: a folder with
//! `metadata.yaml` and the `.mcap` file; a folder without `metadata.yaml` is refused): `track BAG_DIR -o OUT_DIR` tracks the bag's MCAP file
//! and writes OUT_DIR as a bag directory of its own, with a `metadata.yaml` that lists every
//! topic of the output, the tracks topic included.
//!
//! The new `metadata.yaml` is written from the output file's MCAP summary (channels, schemas,
//! statistics), in the layout of rosbag2 metadata version 5 (ROS 2 Humble; newer rosbag2
//! versions read it too): per topic its name, type (schema name), serialization_format (message
//! encoding), offered_qos_profiles (the channel's metadata value, as rosbag2 stores it) and
//! message count. Only single-file MCAP bags are read; a split bag or a sqlite3 (`.db3`) bag is
//! refused with what to do instead.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mcap::records::Record;

use crate::mcapio::reader::read_summary_records;

/// The MCAP file of a bag directory, or `None` when `path` is not a directory. A directory is a
/// bag only with rosbag2's `metadata.yaml`: a folder of logs is not one log, and taking it for a
/// bag would make `-o` a directory without a word.
pub fn bag_mcap(path: &Path) -> Result<Option<PathBuf>> {
    if !path.is_dir() {
        return Ok(None);
    }
    let mut mcaps = Vec::new();
    let (mut db3, mut metadata) = (false, false);
    for entry in
        std::fs::read_dir(path).with_context(|| format!("cannot read {}", path.display()))?
    {
        let p = entry?.path();
        match p.extension().and_then(|e| e.to_str()) {
            Some("mcap") => mcaps.push(p),
            Some("db3") => db3 = true,
            _ => metadata |= p.file_name().is_some_and(|n| n == "metadata.yaml"),
        }
    }
    mcaps.sort();
    let dir = path.display();
    match mcaps.len() {
        0 if db3 => bail!(
            "{dir}: a rosbag2 bag with sqlite3 storage (.db3); probmot reads MCAP storage: convert \
             it with `ros2 bag convert` to storage_id mcap, or record with `ros2 bag record -s mcap`"
        ),
        0 => bail!("{dir}: a directory without an .mcap file"),
        1 if !metadata => bail!(
            "{dir}: a directory with one .mcap file but no metadata.yaml, so not a rosbag2 bag: \
             name the file instead ({}); a bag whose recording was cut gets its metadata.yaml \
             back with `ros2 bag reindex`",
            mcaps[0].display()
        ),
        n if !metadata => bail!(
            "{dir}: a directory of {n} .mcap files without metadata.yaml, not a rosbag2 bag: \
             name the files instead (`probmot track {dir}/*.mcap --out-dir OUT` tracks them \
             all, `fit` and `tune` take them all as `{dir}/*.mcap`; `info`, `plot` and `viz` \
             read one file, `eval --truth {dir}` the folder)"
        ),
        1 => Ok(mcaps.pop()),
        n => bail!(
            "{dir}: a bag split into {n} .mcap files; probmot tracks one file at a time: run \
             `probmot track` on each .mcap file (tracks then restart at each split)"
        ),
    }
}

/// `path`, or for a bag directory its MCAP file: what the commands that read one file at a time
/// (`info`, `plot`, `viz`, `fit`, `tune`, `export`) open.
pub fn resolve_input(path: &Path) -> Result<PathBuf> {
    Ok(bag_mcap(path)?.unwrap_or_else(|| path.to_path_buf()))
}

/// Creates the output bag directory (it must not exist, or be empty, as for `ros2 bag record`)
/// and returns the path of its MCAP file (named after the input's).
pub fn prepare_output(dir: &Path, input_mcap: &Path) -> Result<PathBuf> {
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
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let name = input_mcap
        .file_name()
        .with_context(|| format!("{} has no file name", input_mcap.display()))?;
    Ok(dir.join(name))
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

/// Writes `dir/metadata.yaml` for the bag's MCAP file `mcap` (inside `dir`), from its summary.
pub fn write_metadata(dir: &Path, mcap: &Path) -> Result<()> {
    let file = mcap.display();
    let Some((_, records)) = read_summary_records(mcap) else {
        bail!("{file}: no readable summary section to write metadata.yaml from");
    };
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut topics: BTreeMap<u16, Topic> = BTreeMap::new();
    let mut stats = None;
    for rec in records {
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                let topic = Topic {
                    name: c.topic,
                    msgtype: schemas.get(&c.schema_id).cloned().unwrap_or_default(),
                    serialization: c.message_encoding,
                    qos: c
                        .metadata
                        .get("offered_qos_profiles")
                        .cloned()
                        .unwrap_or_default(),
                    count: 0,
                };
                topics.insert(c.id, topic);
            }
            Record::Statistics(s) => stats = Some(s),
            _ => {}
        }
    }
    let stats = stats.with_context(|| format!("{file}: no statistics record"))?;
    for (id, n) in &stats.channel_message_counts {
        if let Some(t) = topics.get_mut(id) {
            t.count = *n;
        }
    }
    let (start, duration) = if stats.message_count == 0 {
        (0, 0)
    } else {
        let d = stats.message_end_time - stats.message_start_time;
        (stats.message_start_time, d)
    };
    let name = mcap
        .file_name()
        .and_then(|n| n.to_str())
        .with_context(|| format!("{file}: file name is not UTF-8"))?;
    let mut y = String::from("rosbag2_bagfile_information:\n  version: 5\n");
    y.push_str("  storage_identifier: mcap\n");
    let _ = writeln!(y, "  duration:\n    nanoseconds: {duration}");
    let _ = writeln!(y, "  starting_time:\n    nanoseconds_since_epoch: {start}");
    let _ = writeln!(y, "  message_count: {}", stats.message_count);
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
    let _ = writeln!(y, "  relative_file_paths:\n    - {}", quoted(name));
    let _ = writeln!(y, "  files:\n    - path: {}", quoted(name));
    let _ = writeln!(
        y,
        "      starting_time:\n        nanoseconds_since_epoch: {start}"
    );
    let _ = writeln!(y, "      duration:\n        nanoseconds: {duration}");
    let _ = writeln!(y, "      message_count: {}", stats.message_count);
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
    fn bag_mcap_finds_the_one_file_and_refuses_others() {
        let d = tempfile::tempdir().unwrap();
        assert!(bag_mcap(&d.path().join("x.mcap")).unwrap().is_none());
        let e = bag_mcap(d.path()).unwrap_err().to_string();
        assert!(e.contains("without an .mcap"), "{e}");
        std::fs::write(d.path().join("b_0.db3"), b"").unwrap();
        let e = bag_mcap(d.path()).unwrap_err().to_string();
        assert!(e.contains("ros2 bag convert"), "{e}");
        std::fs::write(d.path().join("b_0.mcap"), b"").unwrap();
        std::fs::write(d.path().join("metadata.yaml"), b"").unwrap();
        assert_eq!(bag_mcap(d.path()).unwrap(), Some(d.path().join("b_0.mcap")));
        std::fs::write(d.path().join("b_1.mcap"), b"").unwrap();
        let e = bag_mcap(d.path()).unwrap_err().to_string();
        assert!(e.contains("split into 2"), "{e}");
    }

    #[test]
    fn output_directory_must_be_new_or_empty() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let m = prepare_output(&out, Path::new("/x/in_0.mcap")).unwrap();
        assert_eq!(m, out.join("in_0.mcap"));
        std::fs::write(&m, b"").unwrap();
        assert!(prepare_output(&out, Path::new("/x/in_0.mcap")).is_err());
    }

    #[test]
    fn quoted_strings_are_yaml_scalars() {
        assert_eq!(quoted("/tracks"), "\"/tracks\"");
        assert_eq!(quoted("a\"b\n"), "\"a\\\"b\\n\"");
    }
}
