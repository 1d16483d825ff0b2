//! Rerun recordings (.rrd) of a run, written with the Rerun Rust SDK (cargo feature `rerun`).
//!
//! The recording mirrors `scripts/to_rerun.py`: the same entity paths, timelines, colours and
//! top-down view, so `scripts/inspect_rrd.py` checks both.
//!
//! Entities (z up, metres): `world` (static `ViewCoordinates` RIGHT_HAND_Z_UP),
//! `world/detections` (thin grey boxes labelled "car 0.87", labels shown on hover),
//! `world/tracks` (boxes in the id's colour, labelled "car 12"), `world/ground_truth` (thin green
//! boxes labelled "gt 3", when the file has ground truth), `world/trails` (a line strip per track
//! through its last centres) and `world/velocity` (an arrow per track: its velocity over one
//! second); with the evaluation's events in the file (`eval --events`), `world/events` (the errors
//! as boxes coloured by kind) and `events` (a text entry per identity switch and fragmentation).
//! Timelines: `log_time` (timestamp, the MCAP log time) and `frame` (sequence, the
//! frame index); the SDK's own `log_time`/`log_tick` injection is turned off.
//!
//! The recording carries a blueprint (made active and default on load) with one 3D view of `world` whose eye looks straight
//! down (+y up on screen) on a light background. The SDK's high-level blueprint API
//! (`rerun::blueprint`) cannot set a 3D view's eye or background in 0.36, so the blueprint store is
//! written here from the same blueprint archetypes the viewer reads (`ViewBlueprint`,
//! `ViewContents`, `EyeControls3D`, `Background`, `ContainerBlueprint`, `ViewportBlueprint`).

use std::path::Path;

use anyhow::{bail, Context, Result};
use rerun::blueprint::components::{
    BackgroundKind, ContainerKind, Eye3DKind, IncludedContent, QueryExpression, RootContainer,
    ViewClass,
};
use rerun::external::re_log_types::{BlueprintActivationCommand, LogMsg};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    Background, ContainerBlueprint, EyeControls3D, ViewBlueprint, ViewContents, ViewportBlueprint,
};
use rerun::external::uuid::Uuid;
use rerun::{
    Angle, Arrows3D, Boxes3D, Color, FillMode, LineStrips3D, Radius, RecordingStream,
    RecordingStreamBuilder, RotationAxisAngle, TextLog, TextLogLevel, TimeCell, ViewCoordinates,
};

use super::plot::{id_color, mix64, DETECTION_GREY};
pub use super::rrd_options::{RrdSummary, VizOptions};
use super::scene::{drawable, Scene};
use super::window::{read_timed_events, read_window};
use super::{read_layers, FileLayers, Layer, Selection};
use crate::mcapio::recording::topic_list;
use crate::mcapio::writer::write_file_atomic;
use crate::mcapio::LabelledBox;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::{kind_name, kind_rgb, EVENTS_TOPIC};
use crate::msgs::EvalEvent;

/// Application id of the recordings (as `scripts/to_rerun.py`).
pub const APPLICATION_ID: &str = "probmot";

/// Colour of ground-truth boxes (as `scripts/to_rerun.py`).
pub const TRUTH_GREEN: (u8, u8, u8) = (0x2e, 0xcc, 0x40);

/// Background of the 3D view: light, like `probmot plot` pictures (the id palette is chosen for a
/// light background).
pub const VIEW_BACKGROUND: (u8, u8, u8) = (0xf4, 0xf4, 0xf4);

/// How the recording is written.
#[derive(Debug, Clone)]
pub struct RrdOptions {
    /// Rerun recording id; `None` for a random one (as `scripts/to_rerun.py`: the viewer merges
    /// recordings with the same id, and two logs can share a file name).
    pub recording_id: Option<String>,
    /// Name of the view (and of the recording), e.g. the input's file name.
    pub name: String,
}

fn rgb((r, g, b): (u8, u8, u8)) -> Color {
    Color::from_rgb(r, g, b)
}

fn point(p: [f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

/// Line radii in UI points, so lines stay visible at any zoom (the script's negative radii).
fn ui_points(r: f32) -> Radius {
    Radius::new_ui_points(r)
}

fn boxes3d(
    boxes: &[LabelledBox],
    color: impl Fn(&LabelledBox) -> Color,
    label: impl Fn(&LabelledBox) -> String,
    radius: f32,
    show_labels: bool,
) -> Boxes3D {
    Boxes3D::from_centers_and_half_sizes(
        boxes.iter().map(|b| point(b.center)),
        boxes.iter().map(|b| {
            [
                b.size[0] as f32 / 2.0,
                b.size[1] as f32 / 2.0,
                b.size[2] as f32 / 2.0,
            ]
        }),
    )
    .with_rotation_axis_angles(
        boxes
            .iter()
            .map(|b| RotationAxisAngle::new([0.0, 0.0, 1.0], Angle::from_radians(b.yaw as f32))),
    )
    .with_colors(boxes.iter().map(color))
    .with_labels(boxes.iter().map(label))
    .with_show_labels(show_labels)
    .with_radii([ui_points(radius)])
    .with_fill_mode(FillMode::MajorWireframe)
}

/// Logs the scene's entities under `world` on the `frame` and `log_time` timelines.
fn log_scene(rec: &RecordingStream, scene: &Scene) -> rerun::RecordingStreamResult<()> {
    rec.log_static("world", &ViewCoordinates::RIGHT_HAND_Z_UP())?;
    for f in &scene.frames {
        rec.set_time("frame", TimeCell::from_sequence(f.index as i64));
        rec.set_time(
            "log_time",
            TimeCell::from_timestamp_nanos_since_epoch(f.log_time as i64),
        );
        if let Some(dets) = &f.detections {
            rec.log(
                "world/detections",
                &boxes3d(
                    dets,
                    |_| rgb(DETECTION_GREY),
                    |b| format!("{} {:.2}", b.label, b.score),
                    0.5,
                    false,
                ),
            )?;
        }
        if let Some(gt) = &f.ground_truth {
            rec.log(
                "world/ground_truth",
                &boxes3d(
                    gt,
                    |_| rgb(TRUTH_GREEN),
                    |b| format!("gt {}", b.id),
                    0.75,
                    false,
                ),
            )?;
        }
        if let Some(tracks) = &f.tracks {
            let color = |b: &LabelledBox| rgb(id_color(b.id));
            rec.log(
                "world/tracks",
                &boxes3d(
                    tracks,
                    color,
                    |b| format!("{} {}", b.label, b.id),
                    1.5,
                    true,
                ),
            )?;
            rec.log(
                "world/trails",
                &LineStrips3D::new(
                    f.trails
                        .iter()
                        .map(|t| t.iter().map(|p| point(*p)).collect::<Vec<_>>()),
                )
                .with_colors(tracks.iter().map(color))
                .with_radii([ui_points(1.0)]),
            )?;
            rec.log(
                "world/velocity",
                &Arrows3D::from_vectors(tracks.iter().map(|b| point(b.velocity)))
                    .with_origins(tracks.iter().map(|b| point(b.center)))
                    .with_colors(tracks.iter().map(color))
                    .with_radii([ui_points(1.0)]),
            )?;
        }
    }
    log_events(rec, scene)
}

/// Logs the evaluation's errors (`eval --events`) as `scripts/to_rerun.py` does: per frame, the
/// `world/events` boxes (a little larger than the object, in the kind's colour) and, per identity
/// switch and fragmentation, an `events` text entry (level WARN): the moments to jump to on the
/// timeline.
fn log_events(rec: &RecordingStream, scene: &Scene) -> rerun::RecordingStreamResult<()> {
    for (log_time, ev) in &scene.events {
        if let Ok(i) = scene.frames.binary_search_by_key(log_time, |f| f.log_time) {
            rec.set_time(
                "frame",
                TimeCell::from_sequence(scene.frames[i].index as i64),
            );
        }
        rec.set_time(
            "log_time",
            TimeCell::from_timestamp_nanos_since_epoch(*log_time as i64),
        );
        let errors: Vec<&EvalEvent> = ev
            .events
            .iter()
            .filter(|e| e.kind() != Kind::Match)
            .collect();
        let center = |e: &EvalEvent| e.center.unwrap_or_default();
        let size = |e: &EvalEvent| e.size.unwrap_or_default();
        let boxes =
            Boxes3D::from_centers_and_half_sizes(
                errors.iter().map(|e| {
                    let c = center(e);
                    [c.x as f32, c.y as f32, c.z as f32]
                }),
                errors.iter().map(|e| {
                    let s = size(e);
                    [
                        (s.length / 2.0 + 0.2) as f32,
                        (s.width / 2.0 + 0.2) as f32,
                        (s.height / 2.0 + 0.2) as f32,
                    ]
                }),
            )
            .with_rotation_axis_angles(errors.iter().map(|e| {
                RotationAxisAngle::new([0.0, 0.0, 1.0], Angle::from_radians(e.yaw as f32))
            }))
            .with_colors(errors.iter().map(|e| rgb(kind_rgb(e.kind()))))
            .with_labels(
                errors
                    .iter()
                    .map(|e| format!("{} gt {}", kind_name(e.kind()), e.truth_id)),
            )
            .with_radii([ui_points(2.0)]);
        rec.log("world/events", &boxes)?;
        for e in errors {
            let what = match e.kind() {
                Kind::Switch => format!("trk {}->{}", e.previous_track_id, e.track_id),
                Kind::Fragmentation => format!("lost trk {}", e.previous_track_id),
                _ => continue,
            };
            let text = format!(
                "{} {} gt {} {what}",
                kind_name(e.kind()),
                e.label,
                e.truth_id
            );
            rec.log("events", &TextLog::new(text).with_level(TextLogLevel::WARN))?;
        }
    }
    Ok(())
}

/// A UUID derived from `name` and `salt`: the blueprint's ids are the same for the same input.
fn stable_uuid(name: &str, salt: u64) -> Uuid {
    let mut h = salt;
    for b in name.bytes() {
        h = mix64(h ^ u64::from(b));
    }
    let hi = mix64(h);
    let lo = mix64(hi ^ salt);
    Uuid::from_u128((u128::from(hi) << 64) | u128::from(lo))
}

/// The blueprint store: one top-down 3D view of `world` in a tab container.
fn blueprint(scene: &Scene, name: &str) -> rerun::RecordingStreamResult<Vec<LogMsg>> {
    let (bp, storage) = RecordingStreamBuilder::new(APPLICATION_ID)
        .recording_id(stable_uuid(name, 3).to_string())
        .blueprint()
        .memory()?;
    // The viewer reads blueprint data at time 0 of the `blueprint` timeline.
    bp.set_time_sequence("blueprint", 0);
    let view = format!("view/{}", stable_uuid(name, 1));
    let container_id = stable_uuid(name, 2);
    let camera = scene.top_down_camera(0.55);
    bp.log(
        format!("{view}/ViewContents"),
        &ViewContents::new([QueryExpression("$origin/**".into())]),
    )?;
    bp.log(
        view.as_str(),
        &ViewBlueprint::new(ViewClass("3D".into()))
            .with_display_name(format!("{name} (top-down)"))
            .with_space_origin("world"),
    )?;
    bp.log(
        format!("{view}/EyeControls3D"),
        &EyeControls3D::new()
            .with_kind(Eye3DKind::Orbital)
            .with_position(point(camera.eye))
            .with_look_target(point(camera.look_target))
            .with_eye_up(point(camera.up)),
    )?;
    bp.log(
        format!("{view}/Background"),
        &Background::new(BackgroundKind::SolidColor).with_color(rgb(VIEW_BACKGROUND)),
    )?;
    bp.log(
        format!("container/{container_id}"),
        &ContainerBlueprint::new(ContainerKind::Tabs)
            .with_contents([IncludedContent(view.as_str().into())]),
    )?;
    bp.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(container_id.into()))
            .with_auto_layout(false)
            .with_auto_views(false),
    )?;
    // `take` flushes the stream first.
    Ok(storage.take())
}

/// Encodes the scene as an .rrd file in memory: the blueprint first, then the data.
pub fn encode_rrd(scene: &Scene, opts: &RrdOptions) -> Result<Vec<u8>> {
    let mut builder = RecordingStreamBuilder::new(APPLICATION_ID);
    if let Some(id) = &opts.recording_id {
        builder = builder.recording_id(id.clone());
    }
    let rec = builder.buffered().context("starting the Rerun recording")?;
    rec.set_log_time_enabled(false);
    rec.set_log_tick_enabled(false);
    let storage = rec.binary_stream();
    // Named here, once the sink is in place: a name given to the builder (with SDK 0.36.3) did not
    // reach the file, and the viewer listed the recording as "<unknown>".
    rec.send_recording_name(opts.name.clone())
        .context("naming the Rerun recording")?;

    let bp = blueprint(scene, &opts.name).context("building the Rerun blueprint")?;
    if let Some(LogMsg::SetStoreInfo(info)) = bp.first() {
        let blueprint_id = info.info.store_id.clone();
        rec.send_blueprint(
            bp,
            BlueprintActivationCommand {
                blueprint_id,
                // Active at once: the eye is placed for this file's boxes, so a layout the viewer
                // kept from another recording of the same application would look elsewhere.
                make_active: true,
                make_default: true,
            },
        );
    }
    log_scene(&rec, scene).context("logging to the Rerun recording")?;
    storage
        .flush(std::time::Duration::MAX)
        .context("flushing the Rerun recording")?;
    storage
        .read()
        .context("the Rerun recording is empty (nothing was logged)")
}

/// Writes the scene to `out` as an .rrd file, atomically (temporary file, then rename).
pub fn write_rrd(scene: &Scene, out: &Path, opts: &RrdOptions) -> Result<RrdSummary> {
    let bytes = encode_rrd(scene, opts)?;
    write_file_atomic(out, &bytes)?;
    Ok(RrdSummary {
        frames: scene.frames.len(),
        track_ids: scene.track_ids(),
        bytes: bytes.len(),
        undrawable: Vec::new(),
    })
}

/// Reads the detections, tracks and ground truth of the MCAP file `input` (each optional, but at
/// least one must have messages) and writes them to `out` as a Rerun recording, atomically.
pub fn mcap_to_rrd(input: &Path, out: &Path, o: &VizOptions) -> Result<RrdSummary> {
    let file = input.display().to_string();
    let wanted = [
        (Layer::Detections, o.detections_topic.clone()),
        (Layer::Tracks, o.tracks_topic.clone()),
        (Layer::GroundTruth, o.truth_topic.clone()),
    ];
    let read = read_drawn(input, &wanted, o)?;
    let undrawable = undrawable(&read, &o.classes);
    let mut scene = Scene::build(&read, &o.classes, o.trail);
    let log_times = read.layers.iter().flat_map(|l| l.log_times.iter().copied());
    let (first, last) = log_times.fold((u64::MAX, 0), |(a, b), t| (a.min(t), b.max(t)));
    if read.topics.contains(EVENTS_TOPIC) && first <= last {
        let whole = o.from_s.is_none() && o.to_s.is_none();
        let (from, to) = if whole { (0, u64::MAX) } else { (first, last) };
        scene.events = read_timed_events(input, EVENTS_TOPIC, from, to)?;
    }
    if scene.frames.is_empty() && (o.from_s.is_some() || o.to_s.is_some()) {
        bail!(
            "{file}: no frame of {}, {} or {} in the window {} to {} s after the first frame",
            o.detections_topic,
            o.tracks_topic,
            o.truth_topic,
            o.from_s.map_or("the start".to_string(), |s| s.to_string()),
            o.to_s.map_or("the end".to_string(), |s| s.to_string()),
        );
    }
    if scene.frames.is_empty() {
        bail!(
            "{file} has no messages on {}, {} or {} ({})",
            o.detections_topic,
            o.tracks_topic,
            o.truth_topic,
            topic_list(&read.topics)
        );
    }
    let name = input
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| file.clone());
    let opts = RrdOptions {
        recording_id: o.recording_id.clone(),
        name,
    };
    let mut summary =
        write_rrd(&scene, out, &opts).with_context(|| format!("writing {}", out.display()))?;
    summary.undrawable = undrawable;
    Ok(summary)
}

/// Per topic, the boxes of `classes` (all when empty) that [`Scene::build`] leaves out because
/// they cannot be drawn.
fn undrawable(read: &FileLayers, classes: &[String]) -> Vec<(String, u64)> {
    let counted =
        |b: &&LabelledBox| !drawable(b) && (classes.is_empty() || classes.contains(&b.label));
    (read.layers.iter())
        .map(|lf| {
            let boxes = lf.frames.iter().flat_map(|f| &f.1);
            (lf.topic.clone(), boxes.filter(counted).count() as u64)
        })
        .filter(|(_, n)| *n > 0)
        .collect()
}

/// The layers the recording draws: the whole file, or with a window ([`VizOptions::from_s`],
/// [`VizOptions::to_s`]) only the chunks that overlap it ([`read_window`]), trimmed to the
/// frames whose stamp lies in it.
fn read_drawn(input: &Path, wanted: &[(Layer, String)], o: &VizOptions) -> Result<FileLayers> {
    if o.from_s.is_none() && o.to_s.is_none() {
        return read_layers(input, wanted);
    }
    let mut read = read_window(input, wanted, &Layer::ALL, o.from_s, o.to_s)?;
    let stamps = read
        .layers
        .iter()
        .flat_map(|l| l.frames.iter().map(|f| f.0));
    let Some(t0) = read.span.map(|s| s.0).or_else(|| stamps.min()) else {
        return Ok(read);
    };
    let window = Selection {
        classes: Vec::new(),
        from_s: o.from_s,
        to_s: o.to_s,
    };
    for lf in &mut read.layers {
        let keep: Vec<bool> = lf
            .frames
            .iter()
            .map(|f| window.in_window(f.0, t0))
            .collect();
        let mut k = keep.iter();
        lf.frames.retain(|_| *k.next().expect("one flag per frame"));
        let mut k = keep.iter();
        lf.log_times
            .retain(|_| *k.next().expect("one flag per log time"));
    }
    Ok(read)
}
