//! A sequence of transform messages (ROS 2 `/tf`, `/tf_static`, odometry, Foxglove frame
//! transforms) read into the transform buffer, then looked up and used to move detections into
//! the fixed frame (see `probmot_fuzz::read_transforms`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    probmot_fuzz::read_transforms(data);
});
