//! The topic options of the commands that draw a file's layers (`plot`, `viz`).

use clap::Args;

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
    /// The library's topic names.
    pub fn names(&self) -> probmot::viz::plot_file::LayerTopics {
        probmot::viz::plot_file::LayerTopics {
            detections: self.detections_topic.clone(),
            tracks: self.tracks_topic.clone(),
            truth: self.truth_topic.clone(),
        }
    }
}
