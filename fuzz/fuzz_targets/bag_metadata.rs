//! Arbitrary bytes as a rosbag2 `metadata.yaml`: read as `track` reads a bag directory's (UTF-8
//! text, then `pipeline::bag_metadata::parse_metadata`). Errors are fine; a panic or a hang is
//! not.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::parse_bag_metadata(data);
});
