//! The topic options of the commands that draw a file's layers (`plot`, `viz`).

use clap::Args;
use probmot::viz::Layer;

/// Topics of the detections, tracks and ground-truth layers.
#[derive(Debug, Clone, Args)]
pub struct LayerTopics {
    /// Topic of the detections.
    #[arg(long, default_value = "/detections", value_name = "TOPIC")]
    pub detections_topic: String,
    /// Topic of the tracks.
    #[arg(long, default_value = "/tracks", value_name = "TOPIC")]
    pub tracks_topic: String,
    /// Topic of the ground truth.
    #[arg(long, default_value = "/ground_truth", value_name = "TOPIC")]
    pub truth_topic: String,
}

impl LayerTopics {
    /// The topic of `layer`.
    pub fn of(&self, layer: Layer) -> &str {
        match layer {
            Layer::Detections => &self.detections_topic,
            Layer::Tracks => &self.tracks_topic,
            Layer::GroundTruth => &self.truth_topic,
        }
    }
}
