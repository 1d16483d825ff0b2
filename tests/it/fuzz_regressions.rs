//! Inputs found by (or distilled from) the `fuzz/` targets, kept so the fixes stay fixed. Every
//! malformed file must give an error — no panic, no output file — and must not make the reader
//! allocate more than a few MiB, whatever its length fields claim. See `fuzz/README.md` and
//! `tests/fixtures/fuzz/README.md`.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::alloc::largest_allocation;
use crate::common::repo;
use probmot::mcapio::reader::{read_records, read_records_from, McapInput};
use probmot::msgs::{self, Detections3D, DetectionsEnvelope, Encoding};
use probmot::pipeline::info::file_info;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track::{track_file, SceneOutput, TrackOptions, DEFAULT_MAX_DETECTIONS};
use probmot::tracker::TrackerConfig;

/// More than the reader's 1 MiB read block and the writer's buffers, far less than the
/// gigabytes the fixed inputs used to cost.
const ALLOCATION_BOUND: usize = 64 << 20;

fn options() -> TrackOptions {
    TrackOptions {
        detection_topics: Vec::new(),
        tracks_topic: None,
        tracks_format: None,
        config: TrackerConfig::preset("nuscenes-chiu2019").unwrap(),
        no_track: false,
        strict: false,
        max_detections_per_message: DEFAULT_MAX_DETECTIONS,
        ego: Default::default(),
        scene: SceneOutput::Off,
        compression: Default::default(),
        background_writer: true,
    }
}

/// The whole read path on one malformed file: each reader fails with an error naming the file,
/// `track` leaves no output, and nothing allocates more than [`ALLOCATION_BOUND`].
fn assert_refused(name: &str, expect: &str) {
    let input = repo(&format!("tests/fixtures/fuzz/{name}"));
    let (res, peak) = largest_allocation(|| read_records(&input, |_, _| Ok(())));
    assert!(
        peak < ALLOCATION_BOUND,
        "{name}: read_records allocated {peak} bytes"
    );
    let err = format!("{:#}", res.expect_err(name));
    assert!(
        err.contains(name),
        "{name}: error does not name the file: {err}"
    );
    assert!(
        err.contains(expect),
        "{name}: expected '{expect}' in: {err}"
    );
    // The same bytes from memory: the same error, under the name given.
    let bytes = std::fs::read(&input).unwrap();
    let mut in_memory = McapInput::from_bytes(format!("memory:{name}"), &bytes);
    let from_bytes = read_records_from(&mut in_memory, |_, _| Ok(()));
    let from_bytes = format!("{:#}", from_bytes.expect_err(name));
    assert_eq!(
        from_bytes,
        err.replace(&input.display().to_string(), &format!("memory:{name}")),
        "{name}: the reader over bytes and over the file disagree"
    );

    let (res, peak) = largest_allocation(|| file_info(&input));
    assert!(res.is_err(), "{name}: file_info accepted it");
    assert!(
        peak < ALLOCATION_BOUND,
        "{name}: file_info allocated {peak} bytes"
    );

    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.mcap");
    let (res, peak) = largest_allocation(|| track_file(&input, &output, &options(), &no_progress));
    assert!(res.is_err(), "{name}: track_file accepted it");
    assert!(
        peak < ALLOCATION_BOUND,
        "{name}: track_file allocated {peak} bytes"
    );
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "{name}: track_file left {left:?}");
}

/// Found by `read_path`: a header record whose profile string claims ~4 GiB; the MCAP parser
/// reserved the claimed length before reading it (libFuzzer: out-of-memory).
#[test]
fn fuzz_read_path_oom_string_length() {
    assert_refused(
        "read_path-oom-768179b2.mcap",
        "a field runs past the end of the record",
    );
}

#[test]
fn string_length_past_the_record_is_an_error() {
    assert_refused(
        "string_length_4gib.mcap",
        "a field runs past the end of the record",
    );
}

/// A 33-byte file claiming a 4 GiB record: the reader used to zero-fill a 4 GiB buffer before
/// finding the end of the file.
#[test]
fn record_length_past_the_file_is_an_error() {
    assert_refused("record_length_4gib.mcap", "not a readable MCAP file");
}

/// A record in a zstd chunk claiming 1 GiB, in a 111-byte file: the MCAP reader zero-filled a
/// 1 GiB buffer before decompressing into it.
#[test]
fn compressed_chunk_record_length_past_the_chunk_is_an_error() {
    assert_refused(
        "chunk_record_length_1gib.mcap",
        "runs past the end of its chunk",
    );
}

/// Found by `read_path`: a record in an uncompressed chunk running past the chunk's end made the
/// MCAP reader's chunk bookkeeping underflow ("attempt to subtract with overflow" in
/// `mcap::sans_io::linear_reader`, a panic with overflow checks, a misread without). A chunk
/// whose CRC does not match is reported as such in place of the error its records give.
#[test]
fn fuzz_read_path_crash_uncompressed_chunk_overflow() {
    assert_refused("read_path-crash-76e4c3d0.mcap", "malformed chunk");
}

#[test]
fn uncompressed_chunk_record_past_the_chunk_is_an_error() {
    assert_refused(
        "uncompressed_chunk_record_past_end.mcap",
        "runs past the end of its chunk",
    );
}

/// Issue #36: a zstd chunk declaring 2.5 GB is refused by the size limit before it is read.
#[test]
fn chunk_declaring_gigabytes_is_refused_by_the_size_limit() {
    assert_refused(
        "chunk_declaring_2_5gb.mcap",
        "the chunk declares 2684354560 bytes of records uncompressed; the limit is",
    );
}

/// Issue #36: records that break the structure the MCAP specification requires.
#[test]
fn structurally_invalid_files_are_refused() {
    for (name, expect) in [
        (
            "message_on_undefined_channel.mcap",
            "is on channel 2, which no channel record",
        ),
        ("channel_redefined.mcap", "redefines channel 1"),
        (
            "channel_on_undefined_schema.mcap",
            "refers to schema 3, which no schema record",
        ),
        ("schema_redefined.mcap", "redefines schema 1"),
    ] {
        assert_refused(name, expect);
        assert_refused(name, "not a valid MCAP file");
    }
}

/// An attachment record too short for its CRC made `mcap::parse_record` panic (slice index).
#[test]
fn attachment_without_crc_is_an_error() {
    assert_refused(
        "attachment_without_crc.mcap",
        "attachment record too short for its CRC",
    );
}

/// Reading in 1 MiB blocks and checking string lengths must not refuse valid files: records
/// larger than a block (top-level, in an uncompressed chunk, in a zstd chunk), strings, maps and
/// attachments read back unchanged.
#[test]
fn records_larger_than_a_read_block_still_read() {
    let dir = tempfile::tempdir().unwrap();
    let big: Vec<u8> = (0..(3 << 20) + 17).map(|i| (i * 7 % 251) as u8).collect();
    for (name, compression) in [("plain", None), ("zstd", Some(mcap::Compression::Zstd))] {
        let path = dir.path().join(format!("{name}.mcap"));
        let mut w = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(Some(1 << 20))
            .create(std::io::BufWriter::new(
                std::fs::File::create(&path).unwrap(),
            ))
            .unwrap();
        let meta: BTreeMap<String, String> = [("k".to_string(), "v".repeat(100))].into();
        let s = w.add_schema("blob", "", b"").unwrap();
        let ch = w.add_channel(s, "/blob", "", &meta).unwrap();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: 0,
                log_time: 1,
                publish_time: 1,
            },
            &big,
        )
        .unwrap();
        w.attach(&mcap::Attachment {
            log_time: 2,
            create_time: 2,
            name: "big.bin".into(),
            media_type: "application/octet-stream".into(),
            data: big.clone().into(),
        })
        .unwrap();
        w.write_metadata(&mcap::records::Metadata {
            name: "m".into(),
            metadata: meta.clone(),
        })
        .unwrap();
        w.finish().unwrap();
        drop(w);

        let (mut message, mut attachment, mut metadata, mut channel) = (None, None, None, None);
        read_records(&path, |rec, _| {
            match rec {
                mcap::records::Record::Message { data, .. } => message = Some(data.into_owned()),
                mcap::records::Record::Attachment { data, header, .. } => {
                    attachment = Some((header.name, data.into_owned()))
                }
                mcap::records::Record::Metadata(m) => metadata = Some(m.metadata),
                mcap::records::Record::Channel(c) => channel = Some((c.topic, c.metadata)),
                _ => {}
            }
            Ok(())
        })
        .unwrap();
        assert!(message.as_deref() == Some(&big[..]), "{name}: message");
        assert!(
            attachment == Some(("big.bin".to_string(), big.clone())),
            "{name}: attachment"
        );
        assert_eq!(metadata.as_ref(), Some(&meta), "{name}: metadata");
        assert_eq!(channel, Some(("/blob".to_string(), meta.clone())), "{name}");
    }
}

/// The sample logs still track with the fixed reader.
#[test]
fn sample_log_still_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let s = track_file(
        &repo("sample_logs/turning-car.mcap"),
        &out,
        &options(),
        &no_progress,
    )
    .unwrap();
    assert_eq!(s.frames, 40);
    assert!(Path::new(&out).is_file());
}

/// What the decode targets check: a message that decodes fully decodes as the first pass's
/// envelope too, with the same stamp and box count.
fn assert_envelope_agrees(bytes: &[u8], enc: Encoding) -> Detections3D {
    let full: Detections3D = msgs::decode(bytes, enc).expect("decodes fully");
    let env: DetectionsEnvelope = msgs::decode(bytes, enc).unwrap_or_else(|e| {
        panic!(
            "{:?} decodes fully but not as the envelope: {e}",
            String::from_utf8_lossy(bytes)
        )
    });
    assert_eq!(
        (env.stamp, env.detections.len()),
        (full.stamp, full.detections.len())
    );
    full
}

#[test]
fn envelope_agrees_with_full_decode() {
    let msg = Detections3D {
        stamp: Some(5),
        frame_id: "map".into(),
        detections: vec![Default::default(); 4],
    };
    assert_envelope_agrees(&prost::Message::encode_to_vec(&msg), Encoding::Protobuf);
    assert_envelope_agrees(&serde_json::to_vec(&msg).unwrap(), Encoding::Json);
}

/// Found by `decode_json` (11 bytes): serde also reads a struct from a JSON array of its fields
/// by position, so this decoded as `Detections3D { stamp: 6, frame_id: "{" }` but not as the
/// envelope, whose second field was `detections`: `track` would refuse in its first pass a
/// message that `info` and its second pass read.
#[test]
fn fuzz_decode_json_positional_array() {
    let full = assert_envelope_agrees(b"[6\n,\n\n\n\"{\"]", Encoding::Json);
    assert_eq!((full.stamp, full.frame_id.as_str()), (Some(6), "{"));
    let full = assert_envelope_agrees(
        br#"[7, "map", [{"label": "car"}, [null, null, 0.5, "car"]]]"#,
        Encoding::Json,
    );
    assert_eq!(full.detections.len(), 2);
}
