//! The few fields of a rosbag2 `metadata.yaml` that say where a bag's data is: its storage, its
//! files in recording order (`relative_file_paths`) and their compression
//! (`compression_mode`, `compression_format`).
//!
//! Read by a narrow reader of the block YAML that rosbag2 (yaml-cpp) and rosbags (ruamel) write:
//! the keys directly under `rosbag2_bagfile_information`, plain or quoted scalars, and the list
//! of file names in block (`- name`) or flow (`[a, b]`) style. Other keys and deeper levels are
//! skipped unread. A file it cannot make sense of is an error naming the line.

use std::path::Path;

use anyhow::{bail, Context, Result};

/// How a bag's data is compressed (`ros2 bag record --compression-mode`, zstd being rosbag2's
/// only compressor).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BagCompression {
    /// Plain storage files (the MCAP files may compress their chunks themselves).
    #[default]
    None,
    /// Each file is one zstd stream (`NAME.mcap.zstd`; `--compression-mode file`).
    FileZstd,
    /// Each message's bytes are one zstd frame (`--compression-mode message`).
    MessageZstd,
}

/// What `metadata.yaml` says about the data of a bag.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BagMetadata {
    /// `storage_identifier` (`mcap`, `sqlite3`), empty when not given.
    pub storage: String,
    /// `relative_file_paths`, in recording order (empty when not given).
    pub files: Vec<String>,
    /// From `compression_mode` and `compression_format`.
    pub compression: BagCompression,
}

/// A scalar: plain, 'single-quoted' or "double-quoted".
fn scalar(v: &str) -> Result<String> {
    let v = v.trim();
    // A comment after a plain scalar.
    let v = match v.find(" #") {
        Some(i) if !v.starts_with(['"', '\'']) => v[..i].trim_end(),
        _ => v,
    };
    if let Some(inner) = v.strip_prefix('\'').and_then(|s| s.strip_suffix('\'')) {
        return Ok(inner.replace("''", "'"));
    }
    if v.starts_with('"') {
        return serde_json::from_str(v).with_context(|| format!("not a quoted string: {v}"));
    }
    Ok(v.to_string())
}

/// Parses the text of a `metadata.yaml`.
pub fn parse_metadata(text: &str) -> Result<BagMetadata> {
    let mut m = BagMetadata::default();
    let lines: Vec<&str> = text.lines().collect();
    let Some(start) = lines
        .iter()
        .position(|l| l.trim_end() == "rosbag2_bagfile_information:")
    else {
        // An empty file says nothing (a bag of one file is still found).
        if text.trim().is_empty() {
            return Ok(m);
        }
        bail!("no rosbag2_bagfile_information key");
    };
    let indent_of = |l: &str| l.len() - l.trim_start().len();
    let body = |l: &str| !l.trim().is_empty() && !l.trim_start().starts_with('#');
    let Some(first) = lines[start + 1..].iter().find(|l| body(l)) else {
        return Ok(m);
    };
    let key_indent = indent_of(first);
    let (mut mode, mut format) = (String::new(), String::new());
    let mut i = start + 1;
    while i < lines.len() {
        let (line, n) = (lines[i], i + 1);
        i += 1;
        if !body(line) || indent_of(line) > key_indent || line.trim_start().starts_with("- ") {
            continue;
        }
        if indent_of(line) < key_indent {
            break;
        }
        let Some((key, value)) = line.trim().split_once(':') else {
            bail!("line {n}: expected `key: value`, found {line:?}");
        };
        let value = value.trim();
        let read = |v: &str| scalar(v).with_context(|| format!("line {n}"));
        match key {
            "storage_identifier" => m.storage = read(value)?,
            "compression_mode" => mode = read(value)?,
            "compression_format" => format = read(value)?,
            "relative_file_paths" if value.starts_with('[') => {
                let inner = value.trim_start_matches('[').trim_end_matches(']');
                for item in inner.split(',').filter(|s| !s.trim().is_empty()) {
                    m.files.push(read(item)?);
                }
            }
            "relative_file_paths" if !value.is_empty() => {
                bail!("line {n}: relative_file_paths is not a list")
            }
            "relative_file_paths" => {
                // Block items, indented or at the key's indentation.
                while let Some(item) = lines.get(i).map(|l| l.trim_start()) {
                    let Some(name) = item.strip_prefix("- ") else {
                        break;
                    };
                    m.files
                        .push(scalar(name).with_context(|| format!("line {}", i + 1))?);
                    i += 1;
                }
            }
            _ => {}
        }
    }
    m.compression = match mode.to_ascii_lowercase().as_str() {
        "" | "none" => BagCompression::None,
        "file" if format == "zstd" => BagCompression::FileZstd,
        "message" if format == "zstd" => BagCompression::MessageZstd,
        "file" | "message" => bail!(
            "compression_format {format:?}: probmot reads zstd compression (the one rosbag2 \
             writes)"
        ),
        other => bail!("unknown compression_mode {other:?}"),
    };
    Ok(m)
}

/// Reads `dir/metadata.yaml`; errors name it.
pub fn read_metadata(dir: &Path) -> Result<BagMetadata> {
    let path = dir.join("metadata.yaml");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    parse_metadata(&text).with_context(|| format!("{}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As rosbag2 (yaml-cpp) writes it: indented block list, plain scalars.
    const ROSBAG2: &str = "rosbag2_bagfile_information:
  version: 5
  storage_identifier: mcap
  duration:
    nanoseconds: 10
  relative_file_paths:
    - drive_0.mcap.zstd
    - drive_1.mcap.zstd
  topics_with_message_count:
    - topic_metadata:
        name: /x
      message_count: 1
  compression_format: zstd
  compression_mode: FILE
  files:
    - path: drive_0.mcap.zstd
";

    /// As rosbags (ruamel) writes it: block list at the key's indentation, quoted empties.
    const ROSBAGS: &str = "rosbag2_bagfile_information:
  compression_format: ''
  compression_mode: ''
  relative_file_paths:
  - b_0.mcap
  storage_identifier: mcap
  version: 8
";

    #[test]
    fn reads_files_and_compression_as_both_writers_write_them() {
        let m = parse_metadata(ROSBAG2).unwrap();
        assert_eq!(m.files, ["drive_0.mcap.zstd", "drive_1.mcap.zstd"]);
        assert_eq!(
            (m.storage.as_str(), m.compression),
            ("mcap", BagCompression::FileZstd)
        );
        let m = parse_metadata(ROSBAGS).unwrap();
        assert_eq!(m.files, ["b_0.mcap"]);
        assert_eq!(m.compression, BagCompression::None);
        let flow = "rosbag2_bagfile_information:\n  relative_file_paths: [\"a.mcap\", 'b.mcap']\n";
        assert_eq!(parse_metadata(flow).unwrap().files, ["a.mcap", "b.mcap"]);
    }

    #[test]
    fn refuses_what_it_cannot_read() {
        let lz4 = ROSBAG2.replace("compression_format: zstd", "compression_format: lz4");
        let e = format!("{:#}", parse_metadata(&lz4).unwrap_err());
        assert!(e.contains("lz4"), "{e}");
        let msg = ROSBAG2.replace("mode: FILE", "mode: MESSAGE");
        assert_eq!(
            parse_metadata(&msg).unwrap().compression,
            BagCompression::MessageZstd
        );
        let msg_lz4 = lz4.replace("mode: FILE", "mode: MESSAGE");
        assert!(format!("{:#}", parse_metadata(&msg_lz4).unwrap_err()).contains("lz4"));
        assert!(parse_metadata("other: 1\n").is_err());
        let bad = "rosbag2_bagfile_information:\n  relative_file_paths: \"a\n";
        assert!(format!("{:#}", parse_metadata(bad).unwrap_err()).contains("line 2"));
        let bad = "rosbag2_bagfile_information:\n  compression_mode: \"file\n";
        assert!(format!("{:#}", parse_metadata(bad).unwrap_err()).contains("line 2"));
        assert_eq!(parse_metadata("\n").unwrap(), BagMetadata::default());
    }
}
