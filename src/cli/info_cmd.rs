//! `probmot info`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::msgs::detection_source::{is_detection_schema, SUPPORTED};
use probmot::pipeline::info::file_info;
use probmot::transforms::buffer::EdgeSummary;

/// Show the channels of an MCAP file: schema, encodings, message counts, time range, and for
/// detection and track channels the boxes per class.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// MCAP file.
    file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    json: bool,
}

fn secs(ns: u64) -> String {
    format!("{}.{:09}", ns / 1_000_000_000, ns % 1_000_000_000)
}

pub fn run(a: InfoArgs) -> Result<ExitCode> {
    let info = file_info(&a.file)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("file:        {}", info.path);
    println!("library:     {}", info.library);
    println!("profile:     {}", info.profile);
    println!(
        "messages:    {}   attachments: {}   metadata: {}",
        info.messages, info.attachments, info.metadata
    );
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
            .map(|(a, b)| format!("{} .. {}", secs(a), secs(b)))
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
            if c.role.is_empty() {
                String::new()
            } else {
                format!("  <- usable as {}", c.role)
            },
        );
        if !c.per_label.is_empty() {
            let parts: Vec<String> = c
                .per_label
                .iter()
                .map(|(l, n)| format!("{l} {n}"))
                .collect();
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
    print_transform_tree(&info.transform_tree);
    Ok(ExitCode::SUCCESS)
}

/// Prints the frame tree, each child indented under its parent, roots first.
fn print_transform_tree(edges: &[EdgeSummary]) {
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
    fn walk<'a>(e: &'a EdgeSummary, depth: usize, children: &dyn Fn(&str) -> Vec<&'a EdgeSummary>) {
        let what = if e.is_static {
            "static".to_string()
        } else {
            let (a, b) = e.stamp_range.unwrap_or_default();
            format!("{} transforms, {} .. {}", e.transforms, secs(a), secs(b))
        };
        println!("  {}{}  ({what})", "  ".repeat(depth), e.child);
        for c in children(&e.child) {
            walk(c, depth + 1, children);
        }
    }
    for r in roots {
        println!("  {r}");
        for e in children(r) {
            walk(e, 1, &children);
        }
    }
}
