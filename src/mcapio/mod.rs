//! MCAP input and output: a streaming record reader over any file, and an atomic writer (also
//! one that writes and compresses on a thread of its own), the one reader of box channels
//! ([`recording`]) and the one box type its readers hand on ([`LabelledBox`]).

pub mod background;
pub mod chunk_stream;
pub mod cut_short;
pub mod destination;
pub mod labelled_box;
pub mod partial_dir;
pub mod reader;
pub mod recording;
pub mod sink;
pub mod source;
pub mod split_sink;
pub mod topic;
mod validate;
pub mod writer;

pub use labelled_box::LabelledBox;
pub use reader::{read_records, read_records_from, McapInput, ReadStats};
pub use writer::{AtomicOutput, OutputOptions};
