//! `probmot plot`.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Args;
use probmot::mcapio::writer::{check_output_path, write_file_atomic};
use probmot::viz::plot::{render_png, Panel, PlotOptions};
use probmot::viz::{read_layers, Layer, Selection};

use super::layer_topics::LayerTopics;

/// Draw a bird's-eye-view PNG of a recording, one panel per layer, a colour per track id.
///
/// The panels (detections, tracks, ground truth) stand side by side, every box of the time
/// window in place, detections grey, axes in metres with equal scale on x and y.
///
/// Examples:
///   probmot plot city.tracked.mcap -o city.png --class car
///   probmot plot city.tracked.mcap -o first5s.png --from 0 --to 5 --layers tracks,ground_truth
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct PlotArgs {
    /// MCAP file, e.g. the output of `probmot track`.
    file: PathBuf,
    /// Output PNG file (written atomically).
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Only boxes of these classes (comma-separated or repeated); default: every class.
    #[arg(long, value_name = "CLASS", value_delimiter = ',')]
    class: Vec<String>,
    /// Window start, seconds after the file's first frame (inclusive).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    from: Option<f64>,
    /// Window end, seconds after the file's first frame (inclusive).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    to: Option<f64>,
    /// Panels, in order (comma-separated): detections, tracks, ground_truth. Default: each of the
    /// three whose topic the file has.
    #[arg(long, value_name = "LAYERS", value_delimiter = ',')]
    layers: Vec<String>,
    /// Picture width, pixels (all panels together).
    #[arg(long, value_name = "PX", default_value_t = 1800)]
    width: u32,
    /// Picture height, pixels.
    #[arg(long, value_name = "PX", default_value_t = 700)]
    height: u32,
    /// Title above the panels; default: file name, classes and time window.
    #[arg(long)]
    title: Option<String>,
    #[command(flatten)]
    topics: LayerTopics,
    /// Print nothing on success.
    #[arg(short, long)]
    quiet: bool,
}

/// Largest accepted side, pixels (a 16k x 16k RGB picture is 768 MiB in memory).
const MAX_SIDE: u32 = 16_384;

fn secs(ns: u64, t0: u64) -> f64 {
    (ns as f64 - t0 as f64) / 1e9
}

pub fn run(a: PlotArgs) -> Result<ExitCode> {
    let file = a.file.display().to_string();
    let is_png = a
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        bail!(
            "output {} must end in .png (probmot plot writes PNG pictures)",
            a.output.display()
        );
    }
    check_output_path(Some(&a.file), &a.output)?;
    for (name, v) in [("--width", a.width), ("--height", a.height)] {
        if !(100..=MAX_SIDE).contains(&v) {
            bail!("{name} {v} is out of range: give 100 to {MAX_SIDE} pixels");
        }
    }
    if let (Some(f), Some(t)) = (a.from, a.to) {
        if f > t {
            bail!("--from {f} is after --to {t}; the window is empty");
        }
    }
    for (name, v) in [("--from", a.from), ("--to", a.to)] {
        if v.is_some_and(|v| !v.is_finite()) {
            bail!("{name} must be a number of seconds");
        }
    }

    // Panels asked for, in order, without repeats.
    let explicit = !a.layers.is_empty();
    let mut wanted_layers: Vec<Layer> = Vec::new();
    for s in &a.layers {
        let Some(l) = Layer::parse(s) else {
            bail!("unknown layer '{s}'; layers are detections, tracks and ground_truth");
        };
        if !wanted_layers.contains(&l) {
            wanted_layers.push(l);
        }
    }
    if !explicit {
        wanted_layers = Layer::ALL.to_vec();
    }
    let topic_of = |l: Layer| a.topics.of(l).to_string();

    // Every layer's topic is read, so that "the first frame" does not depend on --layers.
    let all: Vec<(Layer, String)> = Layer::ALL.iter().map(|&l| (l, topic_of(l))).collect();
    let read = read_layers(&a.file, &all)?;
    let topics = || {
        if read.topics.is_empty() {
            "none".to_string()
        } else {
            read.topics.iter().cloned().collect::<Vec<_>>().join(", ")
        }
    };
    if explicit {
        if let Some(l) = wanted_layers.iter().find(|l| read.get(**l).is_none()) {
            bail!(
                "{file} has no topic {} for the {l} layer (topics: {}); run `probmot track` \
                 first for tracks, or choose other --layers",
                topic_of(*l),
                topics()
            );
        }
    } else {
        wanted_layers.retain(|l| read.get(*l).is_some());
        if wanted_layers.is_empty() {
            bail!(
                "{file} has none of the topics {}, {}, {} (topics: {})",
                a.topics.detections_topic,
                a.topics.tracks_topic,
                a.topics.truth_topic,
                topics()
            );
        }
    }
    let (Some(t0), Some(t_end)) = (read.first_stamp(), read.last_stamp()) else {
        bail!(
            "{file}: the topics of the layers ({}) have no messages",
            wanted_layers
                .iter()
                .map(|l| topic_of(*l))
                .collect::<Vec<_>>()
                .join(", ")
        );
    };
    let span = format!("{:.2} to {:.2} s", 0.0, secs(t_end, t0));

    let sel = Selection {
        classes: a.class.clone(),
        from_s: a.from,
        to_s: a.to,
    };
    let mut panels = Vec::new();
    let mut window_stamps = BTreeSet::new();
    let mut boxes_total = 0usize;
    for &l in &wanted_layers {
        let lf = read.get(l).expect("checked above");
        let frames = sel.apply(&lf.frames, t0);
        if frames.is_empty() {
            bail!(
                "{file}: topic {} has no frame in the window {} (the file's frames span {span} \
                 after the first frame)",
                lf.topic,
                window_text(&sel, t_end, t0)
            );
        }
        window_stamps.extend(frames.iter().map(|f| f.0));
        let n_boxes: usize = frames.iter().map(|f| f.1.len()).sum();
        boxes_total += n_boxes;
        let ids: BTreeSet<u64> = frames
            .iter()
            .flat_map(|f| f.1.iter().map(|b| b.id))
            .collect();
        let what = if l.has_ids() {
            format!("{} ids, {n_boxes} boxes", ids.len())
        } else {
            format!("{n_boxes} boxes")
        };
        panels.push(Panel {
            title: format!("{} ({}): {what}", l.title(), lf.topic),
            layer: l,
            frames,
        });
    }
    if boxes_total == 0 {
        let present: BTreeSet<&str> = wanted_layers
            .iter()
            .filter_map(|l| read.get(*l))
            .flat_map(|lf| lf.frames.iter().flat_map(|f| f.1.iter()))
            .map(|b| b.label.as_str())
            .collect();
        bail!(
            "{file}: no box{} in the window {} on {} (classes in the file: {})",
            if sel.classes.is_empty() {
                String::new()
            } else {
                format!(" of class {}", sel.classes.join(", "))
            },
            window_text(&sel, t_end, t0),
            wanted_layers
                .iter()
                .map(|l| topic_of(*l))
                .collect::<Vec<_>>()
                .join(", "),
            if present.is_empty() {
                "none".to_string()
            } else {
                present.into_iter().collect::<Vec<_>>().join(", ")
            }
        );
    }

    let w0 = *window_stamps.first().expect("non-empty");
    let w1 = *window_stamps.last().expect("non-empty");
    let title = a.title.clone().unwrap_or_else(|| {
        let name = a
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| file.clone());
        let classes = if sel.classes.is_empty() {
            "all classes".to_string()
        } else {
            sel.classes.join(", ")
        };
        format!(
            "{name}  |  {classes}  |  {:.2} to {:.2} s, {} frames",
            secs(w0, t0),
            secs(w1, t0),
            window_stamps.len()
        )
    });
    let opts = PlotOptions {
        width: a.width,
        height: a.height,
        title: Some(title),
    };
    let png = render_png(&panels, &opts)?;
    write_file_atomic(&a.output, &png)?;
    if !a.quiet {
        println!(
            "{}: {}x{} px, {} panel(s) ({}), {} frames from {:.2} to {:.2} s, {boxes_total} boxes",
            a.output.display(),
            a.width,
            a.height,
            panels.len(),
            wanted_layers
                .iter()
                .map(|l| l.name())
                .collect::<Vec<_>>()
                .join(", "),
            window_stamps.len(),
            secs(w0, t0),
            secs(w1, t0),
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn window_text(sel: &Selection, t_end: u64, t0: u64) -> String {
    format!(
        "{:.2} to {:.2} s",
        sel.from_s.unwrap_or(0.0),
        sel.to_s.unwrap_or(secs(t_end, t0))
    )
}
