//! A run of length-prefixed protobuf `probmot.Detections3D` messages read by one `FrameReader`
//! that recycles every frame, each compared with the prost path (see
//! `probmot_fuzz::frame_reader::read_frames`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::frame_reader::read_frames(data);
});
