//! `--means` (eval) and `--search-means` (tune): when the KITTI evaluation computes the tracks'
//! mean scores, on the command line.

use clap::ValueEnum;
use probmot::eval::kitti::MeanScores;

/// When the KITTI evaluation computes the tracks' mean scores, on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MeansArg {
    /// At every threshold, from the previous means (the reference; official numbers).
    EveryPass,
    /// Once per track.
    Once,
}

impl MeansArg {
    /// The library's value.
    pub fn means(self) -> MeanScores {
        match self {
            MeansArg::EveryPass => MeanScores::EveryPass,
            MeansArg::Once => MeanScores::Once,
        }
    }
}
