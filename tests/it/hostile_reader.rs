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
    out.extend(rec(0x02, &[0u64.to_le_bytes().to_vec(), vec![0; 12]].concat()));
    out.extend(MAGIC);
    out
}

/// A zstd chunk of `frames` copies of one zstd frame, each 16 MiB of 64 KiB messages on channel
/// 1 (zstd decoders read concatenated frames as one stream; the file stays small). `noise` of each
/// message's 64 KiB is pseudo-random, so the chunk is as large in the file as real data.
fn zstd_chunk(frames: u64, noise: usize) -> Vec<u8> {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut block = Vec::with_capacity(16 << 20);
    let per_message = 64 << 10;
    while block.len() + per_message <= 16 << 20 {
        let mut data = vec![0u8; per_message - 9 - 22];
        for b in &mut data[..noise.min(per_message - 31)] {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            *b = state as u8;
        }
        block.extend(message(1, 1_000, &data));
    }
    let frame = zstd::bulk::compress(&block, 1).unwrap();
    let compressed = frame.repeat(frames as usize);
    chunk("zstd", block.len() as u64 * frames, &compressed)
}

/// `probmot ARGS` under an address-space limit of [`ADDRESS_SPACE_KIB`].
fn probmot_limited(args: &[&str]) -> Output {
    let bin = env!("CARGO_BIN_EXE_probmot");
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {ADDRESS_SPACE_KIB} && exec \"$0\" \"$@\""))
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
    let chunk = zstd_chunk(160, 0);
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
    assert_eq!(json["messages"], 160 * 256, "{json}");
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
    let bytes = file(&[channel(1, 0, "/blob"), chunk("lz4", 2_684_354_560, &compressed)]);
    let input = write(dir.path(), "lz4.mcap", &bytes);
    let out = probmot_limited(&["info", &input]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("declares 2684354560 bytes") && err.contains("--max-chunk-mib"), "{err}");
}

/// An ordinary 300 MB chunk (64 KiB messages, half of each pseudo-random, so ~150 MB in the file)
/// is read by `info` under an address-space limit of 1 GB.
#[test]
fn ordinary_300_mb_chunk_is_read_in_less_than_1_gb() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = file(&[channel(1, 0, "/blob"), zstd_chunk(18, 32 << 10)]);
    assert!(bytes.len() > 100_000_000, "{} bytes", bytes.len());
    let input = write(dir.path(), "big.mcap", &bytes);
    drop(bytes);
    let out = probmot_limited(&["info", "--json", &input]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["messages"], 18 * 256, "{json}");
}
