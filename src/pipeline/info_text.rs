//! A recording's summary as text, as `probmot info` prints it.

use std::fmt::Write as _;

use super::info::{duration, iso8601, FileSummary};
use crate::msgs::detection_source::{is_detection_schema, SUPPORTED};
use crate::transforms::buffer::EdgeSummary;

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

impl FileSummary {
    /// The summary as text: the file, its times, each channel (with what probmot can use it
    /// for and its boxes per class), the detection channels and the transform tree.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "file:        {}", self.path);
        let _ = writeln!(s, "library:     {}", self.library);
        if !self.profile.is_empty() {
            let _ = writeln!(s, "profile:     {}", self.profile);
        }
        self.counts(&mut s);
        let start = self.log_time_range.map_or(0, |(a, _)| a);
        if let Some((a, b)) = self.log_time_range {
            let _ = writeln!(s, "duration:    {}", duration(b - a));
            let _ = writeln!(s, "start:       {}", time(a));
            let _ = writeln!(s, "end:         {}", time(b));
        }
        let _ = writeln!(s, "channels:");
        let w = self
            .channels
            .iter()
            .map(|c| c.topic.len())
            .max()
            .unwrap_or(5)
            .max(5);
        for c in &self.channels {
            let range = c
                .log_time_range
                .map(|(a, b)| format!("{} .. {}", rel(a, start), rel(b, start)))
                .unwrap_or_else(|| "-".into());
            let schema = if c.schema.is_empty() {
                "(no schema)"
            } else {
                &c.schema
            };
            let _ = writeln!(
                s,
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
                let _ = writeln!(s, "        boxes per class: {}", parts.join(", "));
            }
            if c.role == "detections" {
                let how = if c.default_detections {
                    ""
                } else {
                    " (read only when named with --detections-topic)"
                };
                let _ = writeln!(s, "        detections: {}{how}", c.detections_note);
            } else if is_detection_schema(&c.schema) {
                let _ = writeln!(s, "        not usable as detections: {}", c.detections_note);
            }
            if c.undecodable > 0 {
                let _ = writeln!(s, "        {} messages could not be decoded", c.undecodable);
            }
            if c.boxes_not_utf8 > 0 {
                let n = c.boxes_not_utf8;
                let _ = writeln!(
                    s,
                    "        {n} boxes have a label or id that is not UTF-8 (track skips them)"
                );
            }
        }
        let det: Vec<&str> = self
            .channels
            .iter()
            .filter(|c| c.default_detections)
            .map(|c| c.topic.as_str())
            .collect();
        if det.is_empty() {
            let _ = writeln!(s, "detection channels: none (supported: {SUPPORTED})");
        } else {
            let _ = writeln!(
                s,
                "detection channels (read by `track` by default): {}",
                det.join(", ")
            );
        }
        transform_tree(&mut s, &self.transform_tree, start);
        s
    }
}

impl FileSummary {
    /// The message, attachment and metadata counts, and where a file was cut short.
    fn counts(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "messages:    {}   attachments: {}   metadata: {}",
            self.messages, self.attachments, self.metadata
        );
        for cut in &self.cut_short {
            let _ = writeln!(s, "cut short:   {}: {}", cut.file, cut.what_was_read());
        }
    }
}

/// Writes the frame tree, each child indented under its parent, roots first.
fn transform_tree(s: &mut String, edges: &[EdgeSummary], start: u64) {
    if edges.is_empty() {
        return;
    }
    let _ = writeln!(s, "transform tree:");
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
        s: &mut String,
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
        let _ = writeln!(s, "  {}{}  ({what})", "  ".repeat(depth), e.child);
        for c in children(&e.child) {
            walk(s, c, depth + 1, start, children);
        }
    }
    for r in roots {
        let _ = writeln!(s, "  {r}");
        for e in children(r) {
            walk(s, e, 1, start, &children);
        }
    }
}
