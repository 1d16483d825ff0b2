//! Coordinate frames: the transform tree read from a recording ([`sources`]), kept and
//! queried at any stamp ([`buffer`]), and applied to boxes ([`boxes`]).

pub mod boxes;
pub mod buffer;
pub mod sources;

pub use buffer::{LookupError, TransformBuffer};
pub use sources::TransformCollector;
