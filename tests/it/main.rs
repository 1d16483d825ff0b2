//! The integration tests, one binary (as ripgrep's tests/): one module per area, shared
//! helpers in `common`. `cargo test --test it AREA::` runs one area.

mod common;

mod ab3dmot_kitti;
mod autoware;
mod cli_papercuts;
mod conformance;
mod cut_short;
mod doc_examples;
mod ego_motion;
mod error_hints;
mod eval_bootstrap;
mod eval_devkit;
mod eval_events;
mod eval_report;
mod fit;
mod foxglove_js_reader;
mod fuzz_regressions;
mod hostile;
mod hostile_reader;
mod hota;
mod interrupts;
mod kitti_eval;
mod levers;
mod library_calls;
mod nuscenes_io;
mod plot;
mod plot_layout;
mod ray_track;
mod rerun_scripts;
mod robustness;
mod ros2_bag_output;
mod ros2_foxglove_input;
mod ros2_tf_fixture;
mod ros2_tracks_read;
mod scene_update;
mod special_outputs;
mod split_bags;
mod third_party_reader;
mod track_e2e;
mod track_log_order;
mod tracker_core;
mod tune;
mod tune_cli;
mod viewer_install;
