//! `probmot plot`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Args;
use probmot::viz::plot_file::{plot_file, PlotFileOptions, EXTENT_ERROR};
use probmot::viz::Layer;

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
    #[arg(
        long,
        value_name = "CLASS",
        value_delimiter = ',',
        visible_alias = "classes"
    )]
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

impl PlotArgs {
    /// The library's options from the flags: the layers named, without repeats, and the region.
    fn options(&self) -> Result<PlotFileOptions> {
        let mut layers: Vec<Layer> = Vec::new();
        for s in &self.layers {
            let Some(l) = Layer::parse(s) else {
                bail!("unknown layer '{s}'; layers are detections, tracks and ground_truth");
            };
            if !layers.contains(&l) {
                layers.push(l);
            }
        }
        let extent = match self.extent[..] {
            [] => None,
            [x0, x1, y0, y1] => Some((x0, x1, y0, y1)),
            _ => bail!("{EXTENT_ERROR}"),
        };
        Ok(PlotFileOptions {
            classes: self.class.clone(),
            from_s: self.from,
            to_s: self.to,
            layers,
            width: self.width,
            height: self.height,
            title: self.title.clone(),
            extent,
            events: self.events.clone(),
            match_distance: self.match_distance,
            own_colors: self.own_colors,
            layout: self.layout.clone(),
            topics: self.topics.names(),
        })
    }
}

pub fn run(a: PlotArgs) -> Result<ExitCode> {
    let spinner = super::spinner(super::show_progress(a.quiet));
    let warn = |w: &str| spinner.suspend(|| eprintln!("warning: {w}"));
    let o = a.options()?;
    let s = plot_file(&a.file, &a.output, &o, &warn, &|e| {
        super::show_on_spinner(&spinner, e)
    });
    spinner.finish_and_clear();
    let s = s?;
    if !a.quiet {
        println!("{}", s.line(&a.output, &o));
    }
    Ok(ExitCode::SUCCESS)
}
