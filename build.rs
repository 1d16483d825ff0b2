//! Compiles `schemas/probmot/*.proto` with the pure-Rust `protox` compiler (no `protoc` needed)
//! and generates the Rust types with `prost-build`. The serialized `FileDescriptorSet` is kept
//! for the MCAP schema records.

use std::path::PathBuf;

fn main() {
    let files = [
        "schemas/probmot/geometry.proto",
        "schemas/probmot/detections.proto",
        "schemas/probmot/tracks.proto",
    ];
    for f in &files {
        println!("cargo:rerun-if-changed={f}");
    }
    let fds = protox::compile(files, ["schemas"]).expect("compile .proto schemas");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    std::fs::write(
        out.join("probmot_descriptor.bin"),
        prost::Message::encode_to_vec(&fds),
    )
    .unwrap();
    prost_build::Config::new()
        .type_attribute(".", "#[derive(serde::Serialize, serde::Deserialize)]")
        .type_attribute(".", "#[serde(default)]")
        .btree_map(["."])
        .compile_fds(fds)
        .expect("generate Rust types");
}
