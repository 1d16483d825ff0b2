//! `probmot info`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::msgs::detection_source::{is_detection_schema, SUPPORTED};
use probmot::pipeline::info::{duration, iso8601, path_info};
use probmot::pipeline::rosbag_dir::input_files;

use super::eval_args::bytes_bar;
use super::show_progress;
use probmot::transforms::buffer::EdgeSummary;

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
    /// MCAP file.
    file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    json: bool,
    /// No progress bar (it is shown on a terminal only, on stderr). Example: --quiet
    #[arg(long, short)]
    quiet: bool,
}

/// `class count` for the boxes-per-class line; boxes without a class as `(no class) count`.
fn class_count((label, n): (&String, &u64)) -> String {
    match label.is_empty() {
        true => format!("(no class) {n}"),
        false => format!("{label} {n}"),
    }
}

/// A time as ISO 8601 UTC and, in parentheses, seconds since the epoch (as `mcap info`).
fn time(ns: u64) -> String {
    format!(
        "{} ({}.{:09})",
        iso8601(ns),
        ns / 1_000_000_000,
        ns % 1_000_000_000
    )
}

/// A time relative to the file's start, for the per-channel ranges: `+1.500s`.
fn rel(ns: u64, start: u64) -> String {
    format!("+{}", duration(ns.saturating_sub(start)))
}

pub fn run(a: InfoArgs) -> Result<ExitCode> {
    // A bag directory is one drive: all its files.
    let files = input_files(&a.file)?;
    let files: Vec<&std::path::Path> = files.iter().map(|p| p.as_path()).collect();
    let bar = bytes_bar(&files, show_progress(a.quiet || a.json));
    let info = path_info(&a.file, &|n| bar.inc(n))?;
    bar.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("file:        {}", info.path);
    println!("library:     {}", info.library);
    if !info.profile.is_empty() {
        println!("profile:     {}", info.profile);
    }
    println!(
        "messages:    {}   attachments: {}   metadata: {}",
        info.messages, info.attachments, info.metadata
    );
    let start = info.log_time_range.map_or(0, |(a, _)| a);
    if let Some((a, b)) = info.log_time_range {
        println!("duration:    {}", duration(b - a));
        println!("start:       {}", time(a));
        println!("end:         {}", time(b));
    }
    println!("channels:");
    let w = info
        .channels
        .iter()
        .map(|c| c.topic.len())
        .max()
        .unwrap_or(5)
        .max(5);
    for c in &info.channels {
        let range = c
            .log_time_range
            .map(|(a, b)| format!("{} .. {}", rel(a, start), rel(b, start)))
            .unwrap_or_else(|| "-".into());
        let schema = if c.schema.is_empty() {
            "(no schema)"
        } else {
            &c.schema
        };
        println!(
            "  ({:>3}) {:<w$}  {:>7} msgs  {} [{}/{}]  {}{}",
            c.id,
            c.topic,
            c.messages,
            schema,
            c.schema_encoding,
            c.message_encoding,
            range,
            match c.role.as_str() {
                "" => String::new(),
                // A detection schema track does not read by default: one of probmot's outputs.
                "detections" if !c.default_detections => {
                    "  <- probmot's own output (read as detections only when named)".to_string()
                }
                role => format!("  <- usable as {role}"),
            },
        );
        if !c.per_label.is_empty() {
            let parts: Vec<String> = c.per_label.iter().map(class_count).collect();
            println!("        boxes per class: {}", parts.join(", "));
        }
        if c.role == "detections" {
            let how = if c.default_detections {
                ""
            } else {
                " (read only when named with --detections-topic)"
            };
            println!("        detections: {}{how}", c.detections_note);
        } else if is_detection_schema(&c.schema) {
            println!("        not usable as detections: {}", c.detections_note);
        }
        if c.undecodable > 0 {
            println!("        {} messages could not be decoded", c.undecodable);
        }
    }
    let det: Vec<&str> = info
        .channels
        .iter()
        .filter(|c| c.default_detections)
        .map(|c| c.topic.as_str())
        .collect();
    if det.is_empty() {
        println!("detection channels: none (supported: {SUPPORTED})");
    } else {
        println!(
            "detection channels (read by `track` by default): {}",
            det.join(", ")
        );
    }
    print_transform_tree(&info.transform_tree, start);
    Ok(ExitCode::SUCCESS)
}

/// Prints the frame tree, each child indented under its parent, roots first.
fn print_transform_tree(edges: &[EdgeSummary], start: u64) {
    if edges.is_empty() {
        return;
    }
    println!("transform tree:");
    let children = |parent: &str| -> Vec<&EdgeSummary> {
        edges.iter().filter(|e| e.parent == parent).collect()
    };
    let mut roots: Vec<&str> = edges
        .iter()
        .map(|e| e.parent.as_str())
        .filter(|p| !edges.iter().any(|e| e.child == *p))
        .collect();
    roots.sort_unstable();
    roots.dedup();
    fn walk<'a>(
        e: &'a EdgeSummary,
        depth: usize,
        start: u64,
        children: &dyn Fn(&str) -> Vec<&'a EdgeSummary>,
    ) {
        let what = if e.is_static {
            "static".to_string()
        } else {
            let (a, b) = e.stamp_range.unwrap_or_default();
            format!(
                "{} transforms, stamps {} .. {}",
                e.transforms,
                rel(a, start),
                rel(b, start)
            )
        };
        println!("  {}{}  ({what})", "  ".repeat(depth), e.child);
        for c in children(&e.child) {
            walk(c, depth + 1, start, children);
        }
    }
    for r in roots {
        println!("  {r}");
        for e in children(r) {
            walk(e, 1, start, &children);
        }
    }
}
