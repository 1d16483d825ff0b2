//! probmot: probabilistic 3D multi-object tracking (Chiu et al. 2019) for MCAP recordings.
//!
//! [`tracker`] is the pure tracker core; the other modules read and write MCAP, simulate drives,
//! and drive the command-line tool.

pub mod eval;
pub mod fit;
pub mod formats;
pub mod mcapio;
pub mod msgs;
pub mod pipeline;
pub mod sim;
pub mod tracker;
pub mod transforms;
pub mod tune;
pub mod viz;
