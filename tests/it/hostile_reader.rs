//! Hostile MCAP files made here from raw record bytes: a small file whose chunk really expands to
//! gigabytes is refused in bounded memory (and read in bounded memory when the limit is raised),
//! an ordinary 300 MB chunk is read in < 1 GB, and records that break the file's structure
//! (undefined or conflicting channels and schemas) are refused by every command, naming the
//! record and its byte offset. Memory is checked in a child process under `ulimit -v`.

use std::path::Path;
use std::process::Output;

use crate::common;

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Address-space limit of the child processes, KiB (< 1 GB).
const ADDRESS_SPACE_KIB: u64 = 1_000_000;

fn rec(op: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![op];
    out.extend((body.len() as u64).to_le_bytes());
    out.extend(body);
    out
}

fn s(x: &str) -> Vec<u8> {
    let mut out = (x.len() as u32).to_le_bytes().to_vec();
    out.extend(x.as_bytes());
    out
}

fn header() -> Vec<u8> {
    rec(0x01, &[s(""), s("hostile")].concat())
}

fn schema(id: u16, name: &str, data: &[u8]) -> Vec<u8> {
    let mut body = id.to_le_bytes().to_vec();
    body.extend(s(name));
    body.extend(s("jsonschema"));
    body.extend((data.len() as u32).to_le_bytes());
    body.extend(data);
    rec(0x03, &body)
}

fn channel(id: u16, schema_id: u16, topic: &str) -> Vec<u8> {
    let mut body = id.to_le_bytes().to_vec();
    body.extend(schema_id.to_le_bytes());
    body.extend(s(topic));
    body.extend(s("json"));
    body.extend(0u32.to_le_bytes()); // empty metadata map
    rec(0x04, &body)
}

fn message(channel_id: u16, log_time: u64, data: &[u8]) -> Vec<u8> {
    let mut body = channel_id.to_le_bytes().to_vec();
    body.extend(0u32.to_le_bytes()); // sequence
    body.extend(log_time.to_le_bytes());
    body.extend(log_time.to_le_bytes());
    body.extend(data);
    rec(0x05, &body)
}

/// A chunk record holding `compressed`, declared to expand to `size` bytes (no CRC).
fn chunk(compression: &str, size: u64, compressed: &[u8]) -> Vec<u8> {
    let mut body = [0u64.to_le_bytes(), 0u64.to_le_bytes(), size.to_le_bytes()].concat();
    body.extend(0u32.to_le_bytes());
    body.extend(s(compression));
    body.extend((compressed.len() as u64).to_le_bytes());
    body.extend(compressed);
    rec(0x06, &body)
}

/// A whole file: magic, header, `records`, data end, footer (no summary), magic.
fn file(records: &[Vec<u8>]) -> Vec<u8> {
    let mut out = MAGIC.to_vec();
    out.extend(header());
    for r in records {
        out.extend(r);
    }
    out.extend(rec(0x0F, &0u32.to_le_bytes()));
    out.extend(rec(
        0x02,
        &[0u64.to_le_bytes().to_vec(), vec![0; 12]].concat(),
    ));
    out.extend(MAGIC);
    out
}

/// A zstd chunk of `frames` copies of one zstd frame of 16 MiB (zstd decoders read concatenated
/// frames as one stream; the file stays small), and the number of messages in it. A frame is
/// `len`-byte messages on channel 1 with `noise` pseudo-random bytes each (so that the chunk is as
/// large in the file as real data), or for `len` < 31 (too short for a message) records of an
/// unknown opcode with one message at the end.
fn zstd_chunk(frames: u64, len: usize, noise: usize) -> (Vec<u8>, u64) {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut block = Vec::with_capacity(16 << 20);
    let mut count = 0;
    while block.len() + len.max(31) * 2 <= 16 << 20 {
        if len < 31 {
            block.extend(rec(0x80, &vec![0; len - 9]));
            continue;
        }
        let mut data = vec![0u8; len - 9 - 22];
        for b in &mut data[..noise] {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            *b = state as u8;
        }
        block.extend(message(1, 1_000, &data));
        count += 1;
    }
    block.extend(message(1, 1_000, &vec![0; len.max(31) - 31]));
    count += 1;
    let frame = zstd::bulk::compress(&block, 1).unwrap();
    let compressed = frame.repeat(frames as usize);
    let chunk = chunk("zstd", block.len() as u64 * frames, &compressed);
    (chunk, count * frames)
}

/// `probmot ARGS` under an address-space limit of [`ADDRESS_SPACE_KIB`].
fn probmot_limited(args: &[&str]) -> Output {
    let bin = env!("CARGO_BIN_EXE_probmot");
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {ADDRESS_SPACE_KIB} && exec \"$0\" \"$@\""
        ))
        .arg(bin)
        .args(args)
        .output()
        .unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path.display().to_string()
}

/// 2.5 GB of messages in a file of ~250 KB: refused by `info` and `track` (exit 2, the chunk's
/// offset and the limit named) under an address-space limit of 1 GB; with the limit raised, `info`
/// reads all of it within the same address space (the chunk is streamed, not held).
#[test]
fn chunk_expanding_to_gigabytes_is_refused_then_streamed() {
    let dir = tempfile::tempdir().unwrap();
    let (chunk, count) = zstd_chunk(160, 64 << 10, 0);
    let bytes = file(&[channel(1, 0, "/blob"), chunk]);
    assert!(bytes.len() < 1_000_000, "{} bytes", bytes.len());
    let input = write(dir.path(), "bomb.mcap", &bytes);
    let chunk_at = MAGIC.len() + header().len() + channel(1, 0, "/blob").len();
    let out_path = dir.path().join("out.mcap").display().to_string();
    for args in [vec!["info", &input], vec!["track", &input, "-o", &out_path]] {
        let out = probmot_limited(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        for needle in [
            input.as_str(),
            &format!("chunk at byte {chunk_at}"),
            "2684354560 bytes",
            "536870912 bytes (512 MiB)",
            "--max-chunk-mib 2560",
        ] {
            assert!(err.contains(needle), "{args:?}: no '{needle}' in: {err}");
        }
    }
    assert!(!Path::new(&out_path).exists());
    let out = probmot_limited(&["info", "--json", &input, "--max-chunk-mib", "2560"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["messages"], count, "{json}");
}

/// An lz4 chunk declaring 2.5 GB is refused before it is decompressed.
#[test]
fn lz4_chunk_declaring_gigabytes_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let records = message(1, 1_000, &[0; 1 << 20]).repeat(16);
    let mut enc = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
    std::io::Write::write_all(&mut enc, &records).unwrap();
    let (compressed, res) = enc.finish();
    res.unwrap();
    let bytes = file(&[
        channel(1, 0, "/blob"),
        chunk("lz4", 2_684_354_560, &compressed),
    ]);
    let input = write(dir.path(), "lz4.mcap", &bytes);
    let out = probmot_limited(&["info", &input]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("declares 2684354560 bytes") && err.contains("--max-chunk-mib"),
        "{err}"
    );
}

/// Ordinary 300 MB chunks are read by `info` under an address-space limit of 1 GB: 64 KiB
/// messages, half of each pseudo-random (so ~150 MB in the file), and the smallest records there
/// are (9 bytes: 35 million records in the chunk; they used to cost 24 bytes each in an index).
#[test]
fn ordinary_300_mb_chunks_are_read_in_less_than_1_gb() {
    for (len, noise) in [(64 << 10, 32 << 10), (9, 0)] {
        let dir = tempfile::tempdir().unwrap();
        let (chunk, count) = zstd_chunk(18, len, noise);
        let bytes = file(&[channel(1, 0, "/blob"), chunk]);
        let input = write(dir.path(), "big.mcap", &bytes);
        drop(bytes);
        let out = probmot_limited(&["info", "--json", &input]);
        assert!(
            out.status.success(),
            "{len}-byte messages: {}",
            stderr(&out)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["messages"], count, "{json}");
    }
}

/// Offset of the record at index `i` of `records` in [`file`]`(records)`.
fn offset(records: &[Vec<u8>], i: usize) -> usize {
    MAGIC.len() + header().len() + records[..i].iter().map(Vec::len).sum::<usize>()
}

/// Every command that reads the file refuses it (exit 2): the file named as invalid, and each of
/// `needles` in the error. `track` leaves no output.
fn assert_invalid(records: &[Vec<u8>], needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.mcap", &file(records));
    let out_path = dir.path().join("out.mcap").display().to_string();
    let png = dir.path().join("out.png").display().to_string();
    let commands: [Vec<&str>; 5] = [
        vec!["info", &input],
        vec!["info", "--json", &input],
        vec!["track", &input, "-o", &out_path],
        vec!["eval", "--truth", &input],
        vec!["plot", &input, "-o", &png],
    ];
    for args in commands {
        let out = common::probmot(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let invalid = format!("{input}: not a valid MCAP file");
        for needle in [invalid.as_str()].iter().chain(needles) {
            assert!(err.contains(needle), "{args:?}: no '{needle}' in: {err}");
        }
        assert!(
            !err.contains("writing"),
            "{args:?} blames the output: {err}"
        );
    }
    assert!(!Path::new(&out_path).exists() && !Path::new(&png).exists());
}

#[test]
fn message_on_an_undefined_channel_is_refused_by_every_command() {
    let records = [
        channel(1, 0, "/a"),
        message(1, 1, b"{}"),
        message(7, 2, b"{}"),
    ];
    let at = format!(
        "message record at byte {} is on channel 7",
        offset(&records, 2)
    );
    assert_invalid(&records, &[&at]);
}

#[test]
fn channel_redefined_with_another_topic_is_refused_by_every_command() {
    let records = [
        channel(1, 0, "/a"),
        message(1, 1, b"{}"),
        channel(1, 0, "/b"),
    ];
    let at = format!(
        "channel record at byte {} redefines channel 1 (topic '/a', first defined at byte {}) \
         with topic '/b' instead of '/a'",
        offset(&records, 2),
        offset(&records, 0)
    );
    assert_invalid(&records, &[&at]);
}

#[test]
fn channel_on_an_undefined_schema_is_refused_by_every_command() {
    let records = [
        schema(1, "a", b"{}"),
        channel(1, 2, "/a"),
        message(1, 1, b"{}"),
    ];
    let at = format!(
        "channel record at byte {} (channel 1, topic '/a') refers to schema 2",
        offset(&records, 1)
    );
    assert_invalid(&records, &[&at]);
}

#[test]
fn schema_redefined_with_other_data_is_refused_by_every_command() {
    let records = [
        schema(1, "a", b"{}"),
        channel(1, 1, "/a"),
        schema(1, "a", b"{\"x\":1}"),
    ];
    let at = format!(
        "schema record at byte {} redefines schema 1 (first defined at byte {})",
        offset(&records, 2),
        offset(&records, 0)
    );
    assert_invalid(&records, &[&at]);
}

/// Inside a chunk the offset is the record's in the chunk's records, and the chunk's.
#[test]
fn conflicting_channel_inside_a_chunk_names_the_chunk() {
    let inner = [channel(1, 0, "/a"), channel(1, 0, "/b")];
    let records = inner.concat();
    let compressed = zstd::bulk::compress(&records, 1).unwrap();
    let all = [chunk("zstd", records.len() as u64, &compressed)];
    let at = format!(
        "channel record at byte {} of the records of the chunk at byte {} redefines channel 1 \
         (topic '/a', first defined at byte 0 of the records of the chunk at byte {})",
        inner[0].len(),
        offset(&all, 0),
        offset(&all, 0)
    );
    assert_invalid(&all, &[&at]);
}

/// Records repeated with the same content (as chunked files and summaries do) are valid.
#[test]
fn identical_repeated_records_are_valid() {
    let dir = tempfile::tempdir().unwrap();
    let defs = [schema(1, "a", b"{}"), channel(1, 1, "/a")].concat();
    let records = [
        defs.clone(),
        message(1, 1, b"{}"),
        defs,
        message(1, 2, b"{}"),
    ];
    let input = write(dir.path(), "ok.mcap", &file(&records));
    let out = common::probmot(&["info", "--json", &input]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["messages"], 2, "{json}");
}

/// Issue #36 item 10: `track` of a recording with conflicting channel records (sample log plus
/// one record) blames its input, not its output.
#[test]
fn track_blames_the_input_for_conflicting_records() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(common::repo("sample_logs/city.mcap")).unwrap();
    // Before the data end record: a second channel 1 that no summary mentions.
    let data_end = find_data_end(&bytes);
    let extra = channel(1, 0, "/hijacked");
    bytes.splice(data_end..data_end, extra);
    let input = write(dir.path(), "city.mcap", &bytes);
    let out_path = dir.path().join("out.mcap").display().to_string();
    let out = common::probmot(&["track", &input, "-o", &out_path]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let expect = format!("{input}: not a valid MCAP file: the channel record at byte {data_end}");
    assert!(err.contains(&expect), "no '{expect}' in: {err}");
    assert!(
        err.contains("redefines channel 1") && !err.contains("writing"),
        "{err}"
    );
    assert!(!Path::new(&out_path).exists());
}

/// Offset of the data end record of an MCAP file written by the `mcap` crate, found by walking
/// its top-level records.
fn find_data_end(bytes: &[u8]) -> usize {
    let mut at = MAGIC.len();
    while bytes[at] != 0x0F {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap());
        at += 9 + len as usize;
    }
    at
}
