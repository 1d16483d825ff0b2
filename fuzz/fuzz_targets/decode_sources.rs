//! A selector byte and one message of a detection input other than probmot's own (ROS 2
//! `vision_msgs` in either layout, `foxglove.SceneUpdate`, Autoware `DetectedObjects`): decoded
//! as `track` decodes it in its two passes, then converted and tracked (see
//! `probmot_fuzz::decode_source_and_track`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::decode_source_and_track(data);
});
