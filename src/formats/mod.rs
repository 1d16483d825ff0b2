//! Dataset formats: parsing and writing the text formats of public benchmarks.

pub mod kitti;
pub mod nuscenes;
