//! `track` on a rosbag2 bag directory: the bag's files are one drive, tracked as one session in
//! recording order (tracks go on across the splits), and the output is a bag directory split
//! the same way: one MCAP file per input file with every record of that file, the tracks of the
//! frames completed while that file was read, and its own summary; and a `metadata.yaml`
//! listing them ([`super::rosbag_dir::write_metadata`]).
//!
//! The output directory is written beside it as `.NAME.probmot-partial` and renamed at the end
//! ([`PartialDir`]): an error or an interrupt leaves no half-written bag. Its files are synced
//! together just before the rename, not each as it ends, which would stall the writing at every
//! file. Compressed input files (`.mcap.zstd`) are read as a stream ([`super::bag_source`]); the
//! output files are plain MCAP files with zstd-compressed chunks (see docs/ros2.md).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use super::bag_source::BagSource;
use super::progress::Progress;
use super::rosbag_dir::{check_output_dir, open_bag, write_metadata, Bag};
use super::track::{track_file, track_input};
use super::track_options::{TrackOptions, TrackSummary};
use crate::mcapio::partial_dir::PartialDir;
use crate::mcapio::split_sink::SplitSink;
use crate::mcapio::writer::OutputOptions;

/// Tracks `input` into `output`: a bag directory into a new bag directory ([`track_bag`]), a
/// file into a file ([`track_file`]).
pub fn track_path(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<TrackSummary> {
    match open_bag(input)? {
        Some(bag) => track_bag(&bag, output, opts, progress),
        None => track_file(input, output, opts, progress),
    }
}

/// Tracks the bag `bag` as one drive into the new bag directory `out` (it must not exist, or
/// be empty). The output appears only when everything succeeded.
pub fn track_bag(
    bag: &Bag,
    out: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<TrackSummary> {
    let started = Instant::now();
    check_output_dir(out)?;
    let partial = PartialDir::create(out)?;
    let mut summary = write_bag(bag, partial.path(), opts, progress)?;
    summary.warnings.splice(0..0, bag.warning());
    partial.persist()?;
    summary.output = out.display().to_string();
    summary.wall_time_s = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// Syncs the files `paths` to the disk, before their directory is renamed into place.
fn sync_files(paths: &[PathBuf]) -> Result<()> {
    for p in paths {
        (std::fs::File::open(p).and_then(|f| f.sync_all()))
            .with_context(|| format!("syncing {}", p.display()))?;
    }
    Ok(())
}

/// Writes the output files and the metadata of `bag` into the directory `dir`.
fn write_bag(
    bag: &Bag,
    dir: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<TrackSummary> {
    let paths: Vec<PathBuf> = (0..bag.files.len())
        .map(|i| Ok(dir.join(bag.output_name(i)?)))
        .collect::<Result<_>>()?;
    let mut source = BagSource::of(bag);
    let open = |profile| {
        let out_opts = OutputOptions {
            profile,
            compression: opts.compression,
            // Synced all together at the end (sync_files).
            sync: false,
            ..Default::default()
        };
        SplitSink::create(paths.clone(), out_opts, opts.background_writer)
    };
    let (sink, summary) = track_input(&mut source, opts, progress, open)?;
    sink.commit()
        .with_context(|| format!("{}: writing the output bag", bag.dir.display()))?;
    write_metadata(dir, &paths)?;
    sync_files(&paths)?;
    progress(Progress::Done);
    Ok(summary)
}
