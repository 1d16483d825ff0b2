//! `--means` (eval) and `--search-means` (tune): when the KITTI evaluation computes the tracks'
//! mean scores, on the command line.

use clap::ValueEnum;
use probmot::eval::kitti::MeanScores;

/// When the KITTI evaluation computes the tracks' mean scores, on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MeansArg {
    /// At every threshold, from the previous means, summed left to right (the reference as run
    /// on Python 3.11 or older: the official numbers).
    EveryPass,
    /// At every threshold, from the previous means, with Python 3.12's compensated sum (the
    /// reference run on a current Python).
    #[value(name = "every-pass-py312")]
    EveryPassPy312,
    /// Once per track.
    Once,
}

impl MeansArg {
    /// The library's value.
    pub fn means(self) -> MeanScores {
        match self {
            MeansArg::EveryPass => MeanScores::EveryPass,
            MeansArg::EveryPassPy312 => MeanScores::EveryPassCompensated,
            MeansArg::Once => MeanScores::Once,
        }
    }
}
