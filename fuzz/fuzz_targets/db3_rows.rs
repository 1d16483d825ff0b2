//! A rosbag2 sqlite3 storage file whose rows the input's bytes choose (or, after a 0xFF byte,
//! the file's bytes themselves), read as `track` and `info` read a `.db3` file (see
//! `probmot_fuzz::db3_rows`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::db3_rows::db3_rows(data);
});
