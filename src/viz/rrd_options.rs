//! What a Rerun recording of a file reads ([`VizOptions`]) and what it wrote ([`RrdSummary`]),
//! with or without the `rerun` feature.

use super::Layer;

/// What was written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RrdSummary {
    /// Frames logged.
    pub frames: usize,
    /// Distinct track ids.
    pub track_ids: usize,
    /// Size of the file, bytes.
    pub bytes: usize,
    /// Per topic, the boxes (of the chosen classes) left out because they cannot be drawn
    /// ([`super::scene::drawable`]); only topics with any.
    pub undrawable: Vec<(String, u64)>,
}

impl RrdSummary {
    /// The line `probmot viz` prints: the recording written to `output`.
    pub fn line(&self, output: &std::path::Path) -> String {
        let (frames, ids, bytes) = (self.frames, self.track_ids, self.bytes);
        format!(
            "{}: {frames} frames, {ids} track ids, {bytes} bytes",
            output.display()
        )
    }
}

/// What to read from an MCAP file for a recording ([`super::rrd_file::rrd_file`]); the
/// defaults are `probmot viz`'s.
#[derive(Debug, Clone)]
pub struct VizOptions {
    /// Topic of the detections (`probmot.Detections3D`).
    pub detections_topic: String,
    /// Topic of the tracks (`probmot.Tracks3D`).
    pub tracks_topic: String,
    /// Topic of the ground truth (`probmot.Tracks3D`).
    pub truth_topic: String,
    /// Only boxes of these classes; all when empty.
    pub classes: Vec<String>,
    /// Centres per track in `world/trails` (at least 1).
    pub trail: usize,
    /// Rerun recording id; `None` for a random one.
    pub recording_id: Option<String>,
    /// Window start, seconds after the first frame (inclusive); `None` from the start. With a
    /// window only the chunks that overlap it are read.
    pub from_s: Option<f64>,
    /// Window end, seconds after the first frame (inclusive); `None` to the end.
    pub to_s: Option<f64>,
}

impl Default for VizOptions {
    fn default() -> Self {
        VizOptions {
            detections_topic: Layer::Detections.default_topic().into(),
            tracks_topic: Layer::Tracks.default_topic().into(),
            truth_topic: Layer::GroundTruth.default_topic().into(),
            classes: Vec::new(),
            trail: 20,
            recording_id: None,
            from_s: None,
            to_s: None,
        }
    }
}
