//! Arbitrary bytes as a json `probmot.Detections3D` message: decoded fully and as the
//! envelope `track` reads in its first pass, then converted and tracked (see
//! `probmot_fuzz::decode_and_track`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use probmot::msgs::Encoding;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::decode_and_track(data, Encoding::Json);
});
