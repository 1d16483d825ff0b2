//! A bird's-eye-view picture of a recording's file, as `probmot plot` draws it: the options
//! checked, the window of the asked layers read, the panels built, the tracks coloured by their
//! ground truth, the evaluation's events marked, the PNG (and its layout) written.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

use super::plot::{bev_drawable, render_png_with_layout, EventMark, Extent, Panel, PlotOptions};
use super::truth_colors::{marks, match_by_distance, match_from_events};
use super::window::{read_events, read_window};
use super::{check_named_topics, FileLayers, Layer, Selection};
use crate::mcapio::reader::read_summary_records;
use crate::mcapio::recording::topic_list;
use crate::mcapio::writer::{check_output_path, is_device_or_fifo, write_file_atomic};
use crate::msgs::eval_events::EVENTS_TOPIC;
use crate::pipeline::progress::{Progress, ProgressFn};
use crate::pipeline::rosbag_dir::resolve_input;

/// Topics of the detections, tracks and ground-truth layers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LayerTopics {
    /// Topic of the detections.
    pub detections: String,
    /// Topic of the tracks.
    pub tracks: String,
    /// Topic of the ground truth.
    pub truth: String,
}

impl Default for LayerTopics {
    fn default() -> Self {
        LayerTopics {
            detections: "/detections".into(),
            tracks: "/tracks".into(),
            truth: "/ground_truth".into(),
        }
    }
}

impl LayerTopics {
    /// The topic of `layer`.
    pub fn of(&self, layer: Layer) -> &str {
        match layer {
            Layer::Detections => &self.detections,
            Layer::Tracks => &self.tracks,
            Layer::GroundTruth => &self.truth,
        }
    }
}

/// Settings of a picture of a file ([`plot_file`]); the defaults are `probmot plot`'s.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotFileOptions {
    /// Only boxes of these classes; empty: every class.
    pub classes: Vec<String>,
    /// Window start, seconds after the file's first frame (inclusive).
    pub from_s: Option<f64>,
    /// Window end, seconds after the file's first frame (inclusive).
    pub to_s: Option<f64>,
    /// Panels in order, without repeats (each must be in the file); empty: each layer whose
    /// topic the file has.
    pub layers: Vec<Layer>,
    /// Picture width, pixels (all panels together).
    pub width: u32,
    /// Picture height, pixels.
    pub height: u32,
    /// Title above the panels; `None`: file name, classes and time window.
    pub title: Option<String>,
    /// Region shown, metres; `None`: see [`PlotOptions::frame_events`], else the window's
    /// tracks and ground truth.
    pub extent: Option<Extent>,
    /// A file with the evaluation's events (`probmot eval --events`) to mark, and to colour the
    /// tracks by the ground truth the evaluation matched them with.
    pub events: Option<PathBuf>,
    /// Without `events`: how far (m) a track may be from the ground truth whose colour it takes.
    pub match_distance: f64,
    /// A colour per track id instead of that of its ground truth.
    pub own_colors: bool,
    /// Also write where everything went in the picture, as JSON, to this file.
    pub layout: Option<PathBuf>,
    /// The layers' topics.
    pub topics: LayerTopics,
}

impl Default for PlotFileOptions {
    fn default() -> Self {
        PlotFileOptions {
            classes: Vec::new(),
            from_s: None,
            to_s: None,
            layers: Vec::new(),
            width: 1800,
            height: 700,
            title: None,
            extent: None,
            events: None,
            match_distance: 2.0,
            own_colors: false,
            layout: None,
            topics: LayerTopics::default(),
        }
    }
}

/// What a picture shows.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSummary {
    /// The panels' layers, in order.
    pub layers: Vec<Layer>,
    /// Frames of the window.
    pub frames: usize,
    /// First and last frame of the window, seconds after the file's first frame.
    pub window_s: (f64, f64),
    /// Boxes drawn.
    pub boxes: usize,
    /// Evaluation events marked.
    pub marks: usize,
}

impl PlotSummary {
    /// The line `probmot plot` prints: the picture written to `output` with options `o`.
    pub fn line(&self, output: &Path, o: &PlotFileOptions) -> String {
        let layers: Vec<&str> = self.layers.iter().map(|l| l.name()).collect();
        let marks = match o.events {
            Some(_) => format!(", {} events marked", self.marks),
            None => String::new(),
        };
        format!(
            "{}: {}x{} px, {} panel(s) ({}), {} frames from {:.2} to {:.2} s, {} boxes{marks}",
            output.display(),
            o.width,
            o.height,
            self.layers.len(),
            layers.join(", "),
            self.frames,
            self.window_s.0,
            self.window_s.1,
            self.boxes,
        )
    }
}

/// Largest accepted side, pixels (a 16k x 16k RGB picture is 768 MiB in memory).
const MAX_SIDE: u32 = 16_384;

/// Logs longer than this (minutes) plotted whole get a warning.
const LONG_LOG_MIN: f64 = 10.0;

fn secs(ns: u64, t0: u64) -> f64 {
    (ns as f64 - t0 as f64) / 1e9
}

/// Draws the layers of `file` (a rosbag directory resolved) to the PNG `output`, written
/// atomically. Warnings (undrawable boxes, absent classes, a long log read whole) go to `warn`;
/// progress: a message while the file is read, then done.
pub fn plot_file(
    file: &Path,
    output: &Path,
    o: &PlotFileOptions,
    warn: &dyn Fn(&str),
    progress: ProgressFn<'_>,
) -> Result<PlotSummary> {
    let file = resolve_input(file)?;
    check(&file, output, o)?;
    let p = Plot {
        file: &file,
        o,
        warn,
    };
    p.draw(output, progress)
}

/// Checks the options that need no file.
fn check(file: &Path, output: &Path, o: &PlotFileOptions) -> Result<()> {
    let is_png = (output.extension()).is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png && !is_device_or_fifo(output) {
        bail!(
            "output {} must end in .png (probmot plot writes PNG pictures)",
            output.display()
        );
    }
    check_output_path(Some(file), output)?;
    if let Some(layout) = &o.layout {
        check_output_path(Some(file), layout)?;
    }
    for (name, v) in [("--width", o.width), ("--height", o.height)] {
        if !(100..=MAX_SIDE).contains(&v) {
            bail!("{name} {v} is out of range: give 100 to {MAX_SIDE} pixels");
        }
    }
    if let (Some(f), Some(t)) = (o.from_s, o.to_s) {
        if f > t {
            bail!("--from {f} is after --to {t}; the window is empty");
        }
    }
    for (name, v) in [("--from", o.from_s), ("--to", o.to_s)] {
        if v.is_some_and(|v| !v.is_finite()) {
            bail!("{name} must be a number of seconds");
        }
    }
    if !(o.match_distance > 0.0 && o.match_distance.is_finite()) {
        bail!("--match-distance must be a positive number of metres");
    }
    match o.extent {
        Some((x0, x1, y0, y1))
            if !(x0 < x1 && y0 < y1 && [x0, x1, y0, y1].iter().all(|v| v.is_finite())) =>
        {
            bail!("{EXTENT_ERROR}")
        }
        _ => Ok(()),
    }
}

/// The error of a region that is not one.
pub const EXTENT_ERROR: &str =
    "--extent X0,X1,Y0,Y1 needs X0 < X1 and Y0 < Y1 (metres), e.g. -30,30,-20,20";

/// One picture of a checked file.
struct Plot<'a> {
    file: &'a Path,
    o: &'a PlotFileOptions,
    warn: &'a dyn Fn(&str),
}

impl Plot<'_> {
    fn draw(&self, output: &Path, progress: ProgressFn<'_>) -> Result<PlotSummary> {
        let o = self.o;
        let explicit = !o.layers.is_empty();
        let asked = match explicit {
            true => o.layers.clone(),
            false => Layer::ALL.to_vec(),
        };
        // Every layer's topic is looked at, so that "the first frame" does not depend on the
        // layers; the ground truth is read with the tracks, whose colours follow it.
        let all: Vec<(Layer, String)> = (Layer::ALL.iter())
            .map(|&l| (l, o.topics.of(l).to_string()))
            .collect();
        let mut drawn = asked.clone();
        if drawn.contains(&Layer::Tracks) {
            drawn.push(Layer::GroundTruth);
        }
        if let Some(w) = self.long_log_warning() {
            (self.warn)(&w);
        }
        progress(Progress::Message(&format!(
            "reading {}",
            self.file.display()
        )));
        let read = read_window(self.file, &all, &drawn, o.from_s, o.to_s);
        progress(Progress::Done);
        let mut read = read?;
        let layers = self.present_layers(&read, asked, explicit)?;
        let (Some(t0), Some(t_end)) = (read.first_stamp(), read.last_stamp()) else {
            bail!(
                "{}: the topics of the layers ({}) have no messages",
                self.file.display(),
                (layers.iter().map(|l| o.topics.of(*l)))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        };
        let sel = Selection {
            classes: o.classes.clone(),
            from_s: o.from_s,
            to_s: o.to_s,
        };
        let span = (t0, t_end);
        // The panels take the boxes they draw out of `read`, so what else is asked of the
        // boxes read is gathered first.
        let present = present_classes(&read, &layers);
        let (mut panels, stamps, boxes) = self.build_panels(&mut read, &layers, &sel, span)?;
        if boxes == 0 {
            return Err(self.no_boxes(&present, &layers, &sel, span));
        }
        self.warn_absent_classes(&present);
        let marks = self.colour_and_marks(&read, &mut panels, &sel, &stamps)?;
        let (w0, w1) = (
            *stamps.first().expect("non-empty"),
            *stamps.last().expect("non-empty"),
        );
        let title = (o.title.clone())
            .unwrap_or_else(|| self.default_title(&sel, (w0, w1), t0, stamps.len()));
        let opts = PlotOptions {
            width: o.width,
            height: o.height,
            title: Some(title),
            extent: o.extent,
            marks,
            frame_events: o.from_s.is_some() || o.to_s.is_some(),
        };
        let (png, layout) = render_png_with_layout(&panels, &opts)?;
        write_file_atomic(output, &png)?;
        if let Some(path) = &o.layout {
            write_file_atomic(path, &serde_json::to_vec_pretty(&layout)?)?;
        }
        Ok(PlotSummary {
            layers,
            frames: stamps.len(),
            window_s: (secs(w0, t0), secs(w1, t0)),
            boxes,
            marks: opts.marks.len(),
        })
    }

    /// Keeps the layers whose topic the file has (explicit layers must all be there).
    fn present_layers(
        &self,
        read: &FileLayers,
        mut wanted: Vec<Layer>,
        explicit: bool,
    ) -> Result<Vec<Layer>> {
        let file = self.file.display();
        let topics = || topic_list(&read.topics);
        if explicit {
            if let Some(l) = wanted.iter().find(|l| read.get(**l).is_none()) {
                bail!(
                    "{file} has no topic {} for the {l} layer ({}); run `probmot track` first \
                     for tracks, or choose other --layers",
                    self.o.topics.of(*l),
                    topics()
                );
            }
            return Ok(wanted);
        }
        let named = wanted.iter().map(|l| (*l, self.o.topics.of(*l)));
        check_named_topics(&file, named, &read.topics)?;
        wanted.retain(|l| read.get(*l).is_some());
        if wanted.is_empty() {
            let t = &self.o.topics;
            bail!(
                "{file} has none of the topics {}, {}, {} ({})",
                t.detections,
                t.tracks,
                t.truth,
                topics()
            );
        }
        Ok(wanted)
    }

    /// The panels of the window: `(panels, stamps of the window, boxes drawn)`. The boxes of
    /// each layer but the ground truth are moved out of `read` (a plot of a long log holds
    /// each box once); the ground truth, which the tracks' colours follow, stays whole.
    fn build_panels(
        &self,
        read: &mut FileLayers,
        layers: &[Layer],
        sel: &Selection,
        (t0, t_end): (u64, u64),
    ) -> Result<(Vec<Panel>, BTreeSet<u64>, usize)> {
        let mut panels = Vec::new();
        let mut window_stamps = BTreeSet::new();
        let mut boxes_total = 0usize;
        for &l in layers {
            let lf = read.get_mut(l).expect("checked above");
            let frames = match l {
                Layer::GroundTruth => sel.apply(&lf.frames, t0),
                _ => sel.take(&mut lf.frames, t0),
            };
            if frames.is_empty() {
                bail!(
                    "{}: topic {} has no frame in the window {} (the file's frames span {:.2} to \
                     {:.2} s after the first frame)",
                    self.file.display(),
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
                (self.warn)(&format!(
                    "{}: topic {}: {undrawable} box(es) with a non-finite centre, length, \
                     width or yaw are not drawn",
                    self.file.display(),
                    lf.topic
                ));
            }
            let ids: BTreeSet<u64> = (frames.iter())
                .flat_map(|f| f.1.iter().map(|b| b.id))
                .collect();
            let what = match l.has_ids() {
                true => format!("{} ids, {n_boxes} boxes", ids.len()),
                false => format!("{n_boxes} boxes"),
            };
            let ids: Vec<&str> = (lf.frame_ids.iter())
                .filter(|f| !f.is_empty())
                .map(String::as_str)
                .collect();
            let frame = match ids.is_empty() {
                true => String::new(),
                false => format!(" in {}", ids.join("+")),
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

    /// A warning for each asked class that no box read has (a typo among classes that are
    /// drawn would otherwise go unnoticed).
    fn warn_absent_classes(&self, present: &BTreeSet<String>) {
        for c in (self.o.classes.iter()).filter(|c| !present.contains(c.as_str())) {
            let has: Vec<&str> = present.iter().map(String::as_str).collect();
            (self.warn)(&format!(
                "{}: no box of class {c} on the plotted topics (classes: {})",
                self.file.display(),
                has.join(", ")
            ));
        }
    }

    /// The error when the window holds no box of the classes asked for.
    fn no_boxes(
        &self,
        present: &BTreeSet<String>,
        layers: &[Layer],
        sel: &Selection,
        (t0, t_end): (u64, u64),
    ) -> anyhow::Error {
        let join = |v: Vec<String>| v.join(", ");
        anyhow::anyhow!(
            "{}: no box{} in the window {} on {} (classes in the file: {})",
            self.file.display(),
            match sel.classes.is_empty() {
                true => String::new(),
                false => format!(" of class {}", sel.classes.join(", ")),
            },
            window_text(sel, t_end, t0),
            join(
                layers
                    .iter()
                    .map(|l| self.o.topics.of(*l).to_string())
                    .collect()
            ),
            match present.is_empty() {
                true => "none".to_string(),
                false => join(present.iter().cloned().collect()),
            }
        )
    }

    /// Ties the tracks' colours to the ground truth (the evaluation's pairs with `events`, else
    /// nearest centres) and returns the event marks of the window.
    fn colour_and_marks(
        &self,
        read: &FileLayers,
        panels: &mut [Panel],
        sel: &Selection,
        stamps: &BTreeSet<u64>,
    ) -> Result<Vec<EventMark>> {
        let (Some(&w0), Some(&w1)) = (stamps.first(), stamps.last()) else {
            return Ok(Vec::new());
        };
        let events = match &self.o.events {
            Some(path) => Some(read_events(path, EVENTS_TOPIC, w0, w1)?),
            None => None,
        };
        let truth = read.get(Layer::GroundTruth).map(|lf| &lf.frames);
        let own = self.o.own_colors;
        for p in (panels.iter_mut()).filter(|p| p.layer == Layer::Tracks && !own) {
            p.truth_of = match (&events, truth) {
                (Some(ev), _) => Some(match_from_events(ev)),
                (None, Some(gt)) if !gt.is_empty() => {
                    Some(match_by_distance(&p.frames, gt, self.o.match_distance))
                }
                _ => None,
            };
        }
        Ok(events.map_or_else(Vec::new, |ev| marks(&ev, |c| sel.keeps_class(c))))
    }

    /// A warning before a whole long log is read (its summary says how long): every box is held
    /// and every track drawn on one picture, so a window is what the user wants.
    fn long_log_warning(&self) -> Option<String> {
        if self.o.from_s.is_some() || self.o.to_s.is_some() {
            return None;
        }
        let (_, records) = read_summary_records(self.file)?;
        let minutes = records.iter().find_map(|r| match r {
            mcap::records::Record::Statistics(s) if s.message_count > 0 => {
                Some(s.message_end_time.saturating_sub(s.message_start_time) as f64 / 60e9)
            }
            _ => None,
        })?;
        (minutes > LONG_LOG_MIN).then(|| {
            format!(
                "{} is {minutes:.0} minutes long: a plot of all of it holds every box in memory \
                 (about 330 bytes each) and draws every track on one picture; --from/--to \
                 (seconds from the first frame) draws a window, e.g. --from 0 --to 30",
                self.file.display()
            )
        })
    }

    /// File name, classes and window.
    fn default_title(&self, sel: &Selection, (w0, w1): (u64, u64), t0: u64, n: usize) -> String {
        let name = (self.file.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.file.display().to_string());
        let classes = match sel.classes.is_empty() {
            true => "all classes".to_string(),
            false => sel.classes.join(", "),
        };
        format!(
            "{name}  |  {classes}  |  {:.2} to {:.2} s, {n} frames",
            secs(w0, t0),
            secs(w1, t0),
        )
    }
}

/// The classes of the boxes read for `layers`.
fn present_classes(read: &FileLayers, layers: &[Layer]) -> BTreeSet<String> {
    let labels: BTreeSet<&str> = (layers.iter())
        .filter_map(|l| read.get(*l))
        .flat_map(|lf| lf.frames.iter().flat_map(|f| f.1.iter()))
        .map(|b| b.label.as_str())
        .collect();
    labels.into_iter().map(String::from).collect()
}

fn window_text(sel: &Selection, t_end: u64, t0: u64) -> String {
    format!(
        "{:.2} to {:.2} s",
        sel.from_s.unwrap_or(0.0),
        sel.to_s.unwrap_or(secs(t_end, t0))
    )
}
