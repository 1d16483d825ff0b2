//! The jobs behind the subcommands, built on the tracker core and the MCAP adapters.

pub mod bag_metadata;
pub mod bag_source;
pub mod bag_track;
pub mod detections;
pub mod ego;
pub mod frame_schedule;
pub mod info;
pub mod info_text;
pub mod kitti_files;
pub mod kitti_io;
pub mod log_pairs;
pub mod many;
pub mod overrides;
pub mod per_class;
pub mod progress;
pub mod rosbag_dir;
pub mod stamp_check;
pub mod track;
mod track_frames;
pub mod track_options;
mod track_order;
pub mod track_outputs;
mod track_plan;
mod track_records;
pub mod track_session;
mod track_warnings;
pub mod tracks_format;
