//! Arbitrary bytes as an MCAP file, through the whole read path from memory (no file is
//! written): `read_records_from`, `track_input` (default options and preset, into an MCAP in
//! memory) and `file_info_from` (see `probmot_fuzz::read_path`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::read_path::read_path(data);
});
