//! Compiles `schemas/probmot/*.proto` with the pure-Rust `protox` compiler (no `protoc` needed)
//! and generates the Rust types with `prost-build`. The serialized `FileDescriptorSet`s are kept
//! for the MCAP schema records: one of the tracking messages, one of the evaluation events (kept
//! apart so that adding the events leaves the schema records of tracked logs byte-identical).

use std::path::PathBuf;

fn main() {
    let files = [
        "schemas/probmot/geometry.proto",
        "schemas/probmot/detections.proto",
        "schemas/probmot/tracks.proto",
    ];
    let eval_files = ["schemas/probmot/eval_events.proto"];
    for f in files.iter().chain(&eval_files) {
        println!("cargo:rerun-if-changed={f}");
    }
    let fds = protox::compile(files, ["schemas"]).expect("compile .proto schemas");
    let eval_fds = protox::compile(eval_files, ["schemas"]).expect("compile eval_events.proto");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    std::fs::write(
        out.join("probmot_descriptor.bin"),
        prost::Message::encode_to_vec(&fds),
    )
    .unwrap();
    std::fs::write(
        out.join("probmot_eval_descriptor.bin"),
        prost::Message::encode_to_vec(&eval_fds),
    )
    .unwrap();
    let all = protox::compile(files.iter().chain(&eval_files), ["schemas"])
        .expect("compile .proto schemas");
    prost_build::Config::new()
        .type_attribute(".", "#[derive(serde::Serialize, serde::Deserialize)]")
        .message_attribute(".", "#[serde(default)]")
        .btree_map(["."])
        .compile_fds(all)
        .expect("generate Rust types");
}
