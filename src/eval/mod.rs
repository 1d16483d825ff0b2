//! Evaluation: the nuScenes tracking metrics (as the official devkit computes them) and the
//! KITTI-style 3D MOT metrics, on probmot's `Tracks3D` channels.

pub mod bootstrap;
pub mod columns;
pub mod event_boxes;
pub mod event_view;
pub mod events;
pub mod events_log;
pub mod filters;
pub mod hota;
pub mod job;
pub mod kitti;
pub mod kitti_box;
pub mod legend;
pub mod mot_accumulator;
pub mod numpy_compat;
pub mod nuscenes;
pub mod range;
pub mod report;
pub mod scene;

/// Serializes NaN as JSON `null`.
pub(crate) fn nan_as_null<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}
