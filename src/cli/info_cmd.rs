//! `probmot info`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::pipeline::info::recording_info;

use super::show_progress;

/// Show what an MCAP file holds: channels, schemas, message counts, times, boxes per class.
///
/// Per channel: schema, encodings, message count, time range, whether probmot can use it (as
/// detections, tracks or transforms), and for detection and track channels the boxes per class;
/// then the transform tree. Times: the file's start and end as ISO 8601 UTC (and seconds since
/// the epoch), its duration, and each channel's range relative to the start.
///
/// Examples:
///   probmot info sample_logs/city.mcap
///   probmot info sample_logs/city.mcap --json | head
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct InfoArgs {
    /// MCAP file, rosbag2 bag directory (MCAP or sqlite3 storage, split or compressed: one
    /// drive) or sqlite3 .db3 file.
    file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    json: bool,
    /// No progress bar (it is shown on a terminal only, on stderr). Example: --quiet
    #[arg(long, short)]
    quiet: bool,
}

pub fn run(a: InfoArgs) -> Result<ExitCode> {
    let bar = super::bar(
        show_progress(a.quiet || a.json),
        super::style(super::READING),
    );
    let info = recording_info(&a.file, &|e| super::show_on_bar(&bar, e));
    bar.finish_and_clear();
    let info = info?;
    for w in &info.warnings {
        eprintln!("warning: {w}");
    }
    match a.json {
        true => println!("{}", serde_json::to_string_pretty(&info)?),
        false => print!("{}", info.text()),
    }
    Ok(ExitCode::SUCCESS)
}
