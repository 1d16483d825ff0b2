//! `probmot plot`.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Args;
use probmot::mcapio::reader::read_summary_records;
use probmot::mcapio::writer::{check_output_path, write_file_atomic};
use probmot::msgs::eval_events::EVENTS_TOPIC;
use probmot::pipeline::rosbag_dir::resolve_input;
use probmot::viz::plot::{
    bev_drawable, render_png_with_layout, EventMark, Extent, Panel, PlotOptions,
};
use probmot::viz::truth_colors::{marks, match_by_distance, match_from_events};
use probmot::viz::window::{read_events, read_window};
use probmot::viz::{FileLayers, Layer, Selection};

use super::layer_topics::LayerTopics;

/// Draw a bird's-eye-view PNG of a recording, one panel per layer, with a legend.
///
/// The panels (detections, tracks, ground truth) stand side by side, every box of the time
/// window in place, axes in metres with equal scale on x and y, each panel's coordinate frame in
/// its title. The legend under the panels says what the colours and marks mean: detections
/// grey; ground truth a colour per object id; each track box in the colour of the ground-truth
/// object it matches (dark grey: it matches none; --own-colors: a colour per track id), so an
/// identity switch shows as a change of colour; the last box of each id bold, its path a thin
/// line, the heading a tick; with --events, identity switches (magenta rings), fragmentations
/// (orange rings), false positives (red crosses) and misses (small blue rings).
///
/// Labels (each id at its last box, each switch and fragmentation at its ring) keep off the
/// boxes and each other; one set apart has a line to what it names; a panel's title says how
/// many labels found no room.
///
/// The region shown: --extent when given; else, with --events and a window (--from/--to), that
/// of the window's identity switches and fragmentations with 6 m around them (at least 20 m
/// across: what `eval --events` prints as --extent beside each worst moment); else that of the
/// window's tracks and ground truth (far detections do not zoom out). Only the chunks of the
/// window are read (files with chunk indexes, as probmot writes them).
///
/// Examples:
///   probmot plot city.tracked.mcap -o city.png --class car
///   probmot plot city.tracked.mcap -o first5s.png --from 0 --to 5 --layers tracks,ground_truth
///   probmot plot ped.tracked.mcap -o sw.png --from 9.5 --to 13.5 --events ped.events.mcap
///   probmot plot ped.tracked.mcap -o sw.png --from 9.5 --to 13.5 --extent -13,13,-8,13 \
///       --events ped.events.mcap --layout sw.layout.json
///   probmot plot city.tracked.mcap -o near.png --extent -30,30,-20,20
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
    /// Window start, seconds after the file's first frame (inclusive). With --events, the
    /// region shown is that of the window's identity switches and fragmentations.
    #[arg(long, value_name = "SECONDS")]
    from: Option<f64>,
    /// Window end, seconds after the file's first frame (inclusive).
    #[arg(long, value_name = "SECONDS")]
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
    /// Region shown, metres: X0,X1,Y0,Y1 (default: that of the window's identity switches and
    /// fragmentations with --events and --from/--to, else that of the tracks and ground truth of
    /// the window). `eval --events` prints one per worst moment. Example: --extent -30,30,-20,20
    #[arg(
        long,
        value_name = "X0,X1,Y0,Y1",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    extent: Vec<f64>,
    /// Mark the evaluation's errors of the window (identity switches, fragmentations, false
    /// positives, misses) from the /eval/events channel of this file (`probmot eval --events`),
    /// and colour tracks by the ground truth the evaluation matched them with.
    /// Example: --events drive.events.mcap
    #[arg(long, value_name = "EVENTS.mcap")]
    events: Option<PathBuf>,
    /// With ground truth and no --events: how far (m, centre to centre) a track may be from the
    /// ground truth whose colour it takes.
    #[arg(long, value_name = "M", default_value_t = 2.0)]
    match_distance: f64,
    /// Give each track its own colour (by track id) instead of that of its ground truth.
    /// Example: --own-colors
    #[arg(long)]
    own_colors: bool,
    /// Also write where everything went in the picture (each panel's region and plotting area,
    /// label boxes and leader lines, event marks, legend entries; pixels) as JSON, for checking
    /// a picture without looking at it. Example: --layout city.layout.json
    #[arg(long, value_name = "OUT.json")]
    layout: Option<PathBuf>,
    #[command(flatten)]
    topics: LayerTopics,
    /// Print nothing on success (and no spinner while a long log is read).
    #[arg(short, long)]
    quiet: bool,
}

/// Largest accepted side, pixels (a 16k x 16k RGB picture is 768 MiB in memory).
const MAX_SIDE: u32 = 16_384;

fn secs(ns: u64, t0: u64) -> f64 {
    (ns as f64 - t0 as f64) / 1e9
}

/// Checks the options that need no file.
fn validate(a: &PlotArgs) -> Result<Option<Extent>> {
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
    if let Some(layout) = &a.layout {
        check_output_path(Some(&a.file), layout)?;
    }
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
    if !(a.match_distance > 0.0 && a.match_distance.is_finite()) {
        bail!("--match-distance must be a positive number of metres");
    }
    match a.extent[..] {
        [] => Ok(None),
        [x0, x1, y0, y1] if x0 < x1 && y0 < y1 && a.extent.iter().all(|v| v.is_finite()) => {
            Ok(Some((x0, x1, y0, y1)))
        }
        _ => bail!("--extent X0,X1,Y0,Y1 needs X0 < X1 and Y0 < Y1 (metres), e.g. -30,30,-20,20"),
    }
}

/// The panels asked for, in order, without repeats (default: all three); whether explicit.
fn asked_layers(a: &PlotArgs) -> Result<(Vec<Layer>, bool)> {
    let mut out: Vec<Layer> = Vec::new();
    for s in &a.layers {
        let Some(l) = Layer::parse(s) else {
            bail!("unknown layer '{s}'; layers are detections, tracks and ground_truth");
        };
        if !out.contains(&l) {
            out.push(l);
        }
    }
    if out.is_empty() {
        return Ok((Layer::ALL.to_vec(), false));
    }
    Ok((out, true))
}

/// Keeps the layers whose topic the file has (explicit layers must all be there).
fn present_layers(
    a: &PlotArgs,
    read: &FileLayers,
    mut wanted: Vec<Layer>,
    explicit: bool,
) -> Result<Vec<Layer>> {
    let file = a.file.display();
    let topics = || match read.topics.is_empty() {
        true => "none".to_string(),
        false => read.topics.iter().cloned().collect::<Vec<_>>().join(", "),
    };
    if explicit {
        if let Some(l) = wanted.iter().find(|l| read.get(**l).is_none()) {
            bail!(
                "{file} has no topic {} for the {l} layer (topics: {}); run `probmot track` \
                 first for tracks, or choose other --layers",
                a.topics.of(*l),
                topics()
            );
        }
        return Ok(wanted);
    }
    wanted.retain(|l| read.get(*l).is_some());
    if wanted.is_empty() {
        bail!(
            "{file} has none of the topics {}, {}, {} (topics: {})",
            a.topics.detections_topic,
            a.topics.tracks_topic,
            a.topics.truth_topic,
            topics()
        );
    }
    Ok(wanted)
}

/// The panels of the window: `(panels, stamps of the window, boxes drawn)`.
fn build_panels(
    a: &PlotArgs,
    read: &FileLayers,
    layers: &[Layer],
    sel: &Selection,
    (t0, t_end): (u64, u64),
) -> Result<(Vec<Panel>, BTreeSet<u64>, usize)> {
    let mut panels = Vec::new();
    let mut window_stamps = BTreeSet::new();
    let mut boxes_total = 0usize;
    for &l in layers {
        let lf = read.get(l).expect("checked above");
        let frames = sel.apply(&lf.frames, t0);
        if frames.is_empty() {
            bail!(
                "{}: topic {} has no frame in the window {} (the file's frames span {:.2} to \
                 {:.2} s after the first frame)",
                a.file.display(),
                lf.topic,
                window_text(sel, t_end, t0),
                0.0,
                secs(t_end, t0)
            );
        }
        window_stamps.extend(frames.iter().map(|f| f.0));
        let n_boxes: usize = frames.iter().map(|f| f.1.len()).sum();
        boxes_total += n_boxes;
        let undrawable = (frames.iter().flat_map(|f| f.1.iter()))
            .filter(|b| !bev_drawable(b))
            .count();
        if undrawable > 0 {
            eprintln!(
                "warning: {}: topic {}: {undrawable} box(es) with a non-finite centre, length, \
                 width or yaw are not drawn",
                a.file.display(),
                lf.topic
            );
        }
        let ids: BTreeSet<u64> = frames
            .iter()
            .flat_map(|f| f.1.iter().map(|b| b.id))
            .collect();
        let what = match l.has_ids() {
            true => format!("{} ids, {n_boxes} boxes", ids.len()),
            false => format!("{n_boxes} boxes"),
        };
        let frame = match lf
            .frame_ids
            .iter()
            .filter(|f| !f.is_empty())
            .collect::<Vec<_>>()[..]
        {
            [] => String::new(),
            ref f => format!(
                " in {}",
                f.iter().map(|s| s.as_str()).collect::<Vec<_>>().join("+")
            ),
        };
        panels.push(Panel {
            title: format!("{} ({}{frame}): {what}", l.title(), lf.topic),
            layer: l,
            frames,
            truth_of: None,
        });
    }
    Ok((panels, window_stamps, boxes_total))
}

/// The classes of the boxes read for `layers`.
fn present_classes<'a>(read: &'a FileLayers, layers: &[Layer]) -> BTreeSet<&'a str> {
    (layers.iter())
        .filter_map(|l| read.get(*l))
        .flat_map(|lf| lf.frames.iter().flat_map(|f| f.1.iter()))
        .map(|b| b.label.as_str())
        .collect()
}

/// A warning for each `--class` that no box read has (a typo among classes that are drawn
/// would otherwise go unnoticed).
fn warn_absent_classes(a: &PlotArgs, read: &FileLayers, layers: &[Layer]) {
    let present = present_classes(read, layers);
    for c in a.class.iter().filter(|c| !present.contains(c.as_str())) {
        let has: Vec<&str> = present.iter().copied().collect();
        eprintln!(
            "warning: {}: no box of class {c} on the plotted topics (classes: {})",
            a.file.display(),
            has.join(", ")
        );
    }
}

/// The error when the window holds no box of the classes asked for.
fn no_boxes(
    a: &PlotArgs,
    read: &FileLayers,
    layers: &[Layer],
    sel: &Selection,
    (t0, t_end): (u64, u64),
) -> anyhow::Error {
    let present = present_classes(read, layers);
    let join = |v: Vec<String>| v.join(", ");
    anyhow::anyhow!(
        "{}: no box{} in the window {} on {} (classes in the file: {})",
        a.file.display(),
        match sel.classes.is_empty() {
            true => String::new(),
            false => format!(" of class {}", sel.classes.join(", ")),
        },
        window_text(sel, t_end, t0),
        join(layers.iter().map(|l| a.topics.of(*l).to_string()).collect()),
        match present.is_empty() {
            true => "none".to_string(),
            false => join(present.into_iter().map(String::from).collect()),
        }
    )
}

/// Ties the tracks' colours to the ground truth (the evaluation's pairs with `--events`, else
/// nearest centres) and returns the event marks of the window.
fn colour_and_marks(
    a: &PlotArgs,
    read: &FileLayers,
    panels: &mut [Panel],
    sel: &Selection,
    stamps: &BTreeSet<u64>,
) -> Result<Vec<EventMark>> {
    let (Some(&w0), Some(&w1)) = (stamps.first(), stamps.last()) else {
        return Ok(Vec::new());
    };
    let events = match &a.events {
        Some(path) => Some(read_events(path, EVENTS_TOPIC, w0, w1)?),
        None => None,
    };
    let truth = read.get(Layer::GroundTruth).map(|lf| &lf.frames);
    for p in panels
        .iter_mut()
        .filter(|p| p.layer == Layer::Tracks && !a.own_colors)
    {
        p.truth_of = match (&events, truth) {
            (Some(ev), _) => Some(match_from_events(ev)),
            (None, Some(gt)) if !gt.is_empty() => {
                Some(match_by_distance(&p.frames, gt, a.match_distance))
            }
            _ => None,
        };
    }
    Ok(events.map_or_else(Vec::new, |ev| marks(&ev, |c| sel.keeps_class(c))))
}

/// Logs longer than this (minutes) plotted whole get a warning.
const LONG_LOG_MIN: f64 = 10.0;

/// A warning before a whole long log is read (its summary says how long): every box is held
/// and every track drawn on one picture, so --from/--to is what the user wants.
fn long_log_warning(a: &PlotArgs) -> Option<String> {
    if a.from.is_some() || a.to.is_some() {
        return None;
    }
    let (_, records) = read_summary_records(&a.file)?;
    let minutes = records.iter().find_map(|r| match r {
        mcap::records::Record::Statistics(s) if s.message_count > 0 => {
            Some(s.message_end_time.saturating_sub(s.message_start_time) as f64 / 60e9)
        }
        _ => None,
    })?;
    (minutes > LONG_LOG_MIN).then(|| {
        format!(
            "{} is {minutes:.0} minutes long: a plot of all of it holds every box in memory \
             (about 600 bytes each) and draws every track on one picture; --from/--to (seconds \
             from the first frame) draws a window, e.g. --from 0 --to 30",
            a.file.display()
        )
    })
}

pub fn run(mut a: PlotArgs) -> Result<ExitCode> {
    a.file = resolve_input(&a.file)?;
    let extent = validate(&a)?;
    let (asked, explicit) = asked_layers(&a)?;
    // Every layer's topic is looked at, so that "the first frame" does not depend on --layers;
    // the ground truth is read with the tracks, whose colours follow it.
    let all: Vec<(Layer, String)> = Layer::ALL
        .iter()
        .map(|&l| (l, a.topics.of(l).to_string()))
        .collect();
    let mut drawn = asked.clone();
    if drawn.contains(&Layer::Tracks) {
        drawn.push(Layer::GroundTruth);
    }
    if let Some(w) = long_log_warning(&a) {
        eprintln!("warning: {w}");
    }
    // A whole long log takes a while to read; a window takes a fraction of a second.
    let spinner = super::spinner(
        super::show_progress(a.quiet),
        &format!("reading {}", a.file.display()),
    );
    let read = read_window(&a.file, &all, &drawn, a.from, a.to);
    spinner.finish_and_clear();
    let read = read?;
    let layers = present_layers(&a, &read, asked, explicit)?;
    let (Some(t0), Some(t_end)) = (read.first_stamp(), read.last_stamp()) else {
        bail!(
            "{}: the topics of the layers ({}) have no messages",
            a.file.display(),
            layers
                .iter()
                .map(|l| a.topics.of(*l))
                .collect::<Vec<_>>()
                .join(", ")
        );
    };
    let sel = Selection {
        classes: a.class.clone(),
        from_s: a.from,
        to_s: a.to,
    };
    let (mut panels, stamps, boxes_total) = build_panels(&a, &read, &layers, &sel, (t0, t_end))?;
    if boxes_total == 0 {
        return Err(no_boxes(&a, &read, &layers, &sel, (t0, t_end)));
    }
    warn_absent_classes(&a, &read, &layers);
    let marks = colour_and_marks(&a, &read, &mut panels, &sel, &stamps)?;
    let (w0, w1) = (
        *stamps.first().expect("non-empty"),
        *stamps.last().expect("non-empty"),
    );
    let title = a
        .title
        .clone()
        .unwrap_or_else(|| default_title(&a, &sel, (w0, w1), t0, stamps.len()));
    let opts = PlotOptions {
        width: a.width,
        height: a.height,
        title: Some(title),
        extent,
        marks,
        frame_events: a.from.is_some() || a.to.is_some(),
    };
    let (png, layout) = render_png_with_layout(&panels, &opts)?;
    write_file_atomic(&a.output, &png)?;
    if let Some(path) = &a.layout {
        write_file_atomic(path, &serde_json::to_vec_pretty(&layout)?)?;
    }
    if !a.quiet {
        println!(
            "{}: {}x{} px, {} panel(s) ({}), {} frames from {:.2} to {:.2} s, {boxes_total} boxes{}",
            a.output.display(),
            a.width,
            a.height,
            panels.len(),
            layers.iter().map(|l| l.name()).collect::<Vec<_>>().join(", "),
            stamps.len(),
            secs(w0, t0),
            secs(w1, t0),
            match a.events {
                Some(_) => format!(", {} events marked", opts.marks.len()),
                None => String::new(),
            }
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// File name, classes and window.
fn default_title(
    a: &PlotArgs,
    sel: &Selection,
    (w0, w1): (u64, u64),
    t0: u64,
    frames: usize,
) -> String {
    let name = a
        .file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| a.file.display().to_string());
    let classes = match sel.classes.is_empty() {
        true => "all classes".to_string(),
        false => sel.classes.join(", "),
    };
    format!(
        "{name}  |  {classes}  |  {:.2} to {:.2} s, {frames} frames",
        secs(w0, t0),
        secs(w1, t0),
    )
}

fn window_text(sel: &Selection, t_end: u64, t0: u64) -> String {
    format!(
        "{:.2} to {:.2} s",
        sel.from_s.unwrap_or(0.0),
        sel.to_s.unwrap_or(secs(t_end, t0))
    )
}
