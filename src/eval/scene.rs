//! Loading ground truth and tracks from MCAP into per-frame box lists (one log = one scene).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Result};

use super::kitti_box::{KittiBox, KittiBoxes};
use crate::mcapio::recording;
use crate::mcapio::LabelledBox;

/// Ground truth and tracks of one log, by frame stamp (ns). Every stamp of either channel is a
/// frame; a frame may hold no box of one or both. The boxes are whole boxes, or what one
/// protocol reads of them (`Scene<KittiBox>`, [`load_kitti_scene`]).
#[derive(Debug, Clone)]
pub struct Scene<B = LabelledBox> {
    /// Name (the file name), used in reports.
    pub name: String,
    /// Frames in stamp order: `(stamp_ns, truth boxes, track boxes)`.
    pub frames: Vec<(u64, Vec<B>, Vec<B>)>,
}

impl<B> Default for Scene<B> {
    fn default() -> Self {
        Scene {
            name: String::new(),
            frames: Vec::new(),
        }
    }
}

/// Reads the tracks messages of one topic (`probmot.Tracks3D`, or ROS 2
/// `vision_msgs/msg/Detection3DArray` tracks: [`recording::frames`]): `(stamp, boxes)` per
/// message (the stamp is the message's, or its `log_time` when that is 0). A box with a
/// non-finite centre, size, yaw or score is an error.
pub fn read_tracks_topic(path: &Path, topic: &str) -> Result<Vec<(u64, Vec<LabelledBox>)>> {
    read_boxes(path, topic, &|_| {}, false, &mut |b| b)
}

/// [`read_tracks_topic`], each box kept as what the evaluations read of it ([`KittiBox`]: the
/// nuScenes protocol reads its id, label, centre and score), its strings shared through
/// `boxes`: a few times smaller than a whole box with its attribute map.
pub fn read_kitti_topic(
    path: &Path,
    topic: &str,
    boxes: &mut KittiBoxes,
) -> Result<Vec<(u64, Vec<KittiBox>)>> {
    read_boxes(path, topic, &|_| {}, false, &mut |b| boxes.read(&b))
}

/// Whether the evaluation reads an attribute: the KITTI fields (`kitti_*`) and the nuScenes
/// ones (`nuscenes_*`: point counts, rack rotations). Others (e.g. `sim_truth_id`, which
/// `track` copies from each detection to its track) are dropped by [`load_scene_with`]: a
/// map per box would be most of a long log's memory.
pub fn is_evaluated_attribute(key: &str) -> bool {
    key.starts_with("kitti_") || key.starts_with("nuscenes_")
}

/// Messages' boxes in read order: `(stamp, boxes)`.
type Messages<B> = Vec<(u64, Vec<B>)>;

/// The boxes of a tracks topic, message by message, each made into what the caller keeps of it
/// by `keep`. The first message with a box the evaluation cannot score ([`check_finite`]) or,
/// with `truth_ids`, a truth box without id ([`check_ids`]) stops the reading with its error:
/// the rest of a long log is not read for nothing.
fn read_boxes<B>(
    path: &Path,
    topic: &str,
    progress: &dyn Fn(u64),
    truth_ids: bool,
    keep: &mut dyn FnMut(LabelledBox) -> B,
) -> Result<Messages<B>> {
    let mut out = Vec::new();
    let mut reported = 0u64;
    recording::for_each_tracks_frame(path, topic, |stamp, tracks, stats| {
        progress(stats.bytes_read.saturating_sub(reported));
        reported = reported.max(stats.bytes_read);
        let boxes: Vec<LabelledBox> = tracks.into_iter().map(LabelledBox::from_track).collect();
        check_finite(path, (topic, stamp), &boxes, Reads::Box3d)?;
        if truth_ids {
            check_ids(path, topic, stamp, &boxes)?;
        }
        // A new allocation of the kept size: `collect` would reuse the decoded boxes' larger
        // one in place, and a long log holds millions of them.
        let mut kept = Vec::with_capacity(boxes.len());
        kept.extend(boxes.into_iter().map(&mut *keep));
        out.push((stamp, kept));
        Ok(())
    })?;
    let size = std::fs::metadata(path).map_or(reported, |m| m.len());
    progress(size.saturating_sub(reported));
    Ok(out)
}

/// Loads one scene: truth and tracks topics (possibly of the same file), checked: truth boxes
/// need ids, and tracks must share time with the truth.
pub fn load_scene(
    truth: &Path,
    truth_topic: &str,
    tracks: &Path,
    tracks_topic: &str,
) -> Result<Scene> {
    load_scene_with(truth, truth_topic, tracks, tracks_topic, false)
}

/// [`load_scene`], optionally allowing truth boxes without id (KITTI's DontCare regions, which
/// `probmot import kitti` stores with id 0 and label `dontcare`). Only the attributes the
/// evaluation reads are kept ([`is_evaluated_attribute`]).
pub fn load_scene_with(
    truth: &Path,
    truth_topic: &str,
    tracks: &Path,
    tracks_topic: &str,
    allow_unlabelled: bool,
) -> Result<Scene> {
    let mut keep = |b: LabelledBox| b.keep_attributes(is_evaluated_attribute);
    let (truth, tracks) = ((truth, truth_topic), (tracks, tracks_topic));
    load_scene_as(truth, tracks, allow_unlabelled, &|_| {}, &mut keep)
}

/// [`load_scene_with`] for the KITTI protocol: truth boxes without id (DontCare) allowed,
/// and of each box only what the KITTI evaluation reads ([`KittiBox`]), made while the log
/// streams.
pub fn load_kitti_scene(
    truth: (&Path, &str),
    tracks: (&Path, &str),
    progress: &dyn Fn(u64),
) -> Result<Scene<KittiBox>> {
    let mut boxes = KittiBoxes::default();
    let mut keep = |b: LabelledBox| boxes.read(&b);
    load_scene_as(truth, tracks, true, progress, &mut keep)
}

/// The loading of [`load_scene_with`], telling `progress` the bytes read (both files, the
/// shared file twice), each box made into what the caller keeps by `keep`.
fn load_scene_as<B>(
    (truth, truth_topic): (&Path, &str),
    (tracks, tracks_topic): (&Path, &str),
    allow_unlabelled: bool,
    progress: &dyn Fn(u64),
    keep: &mut dyn FnMut(LabelledBox) -> B,
) -> Result<Scene<B>> {
    let gt = read_boxes(truth, truth_topic, progress, !allow_unlabelled, keep)?;
    let tr = read_boxes(tracks, tracks_topic, progress, false, keep)?;
    // Frames are the union of both channels' stamps.
    let stamps = |v: &[(u64, Vec<B>)]| v.iter().map(|m| m.0).collect::<Vec<_>>();
    check(
        &stamps(&gt),
        &stamps(&tr),
        (truth, truth_topic),
        (tracks, tracks_topic),
    )?;
    // Each message's boxes move into their frame (copied only when a stamp repeats), so the
    // boxes are not held twice while the frames are made.
    let mut frames: BTreeMap<u64, (Vec<B>, Vec<B>)> = BTreeMap::new();
    let join = |into: &mut Vec<B>, b: Vec<B>| match into.is_empty() {
        true => *into = b,
        false => into.extend(b),
    };
    for (s, b) in gt {
        join(
            &mut frames
                .entry(s)
                .or_insert_with(|| (Vec::new(), Vec::new()))
                .0,
            b,
        );
    }
    for (s, b) in tr {
        join(
            &mut frames
                .entry(s)
                .or_insert_with(|| (Vec::new(), Vec::new()))
                .1,
            b,
        );
    }
    Ok(Scene {
        name: tracks
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        frames: frames.into_iter().map(|(s, (g, t))| (s, g, t)).collect(),
    })
}

/// The checks of [`load_scene`] on the message stamps of truth (`ts`) and tracks (`rs`, any
/// order): the truth has messages, and tracks that share no time with the truth belong to
/// another log.
pub(super) fn check(
    ts: &[u64],
    rs: &[u64],
    truth: (&Path, &str),
    tracks: (&Path, &str),
) -> Result<()> {
    let (Some(&first), Some(&last)) = (ts.iter().min(), ts.iter().max()) else {
        bail!("{}: topic {} has no messages", truth.0.display(), truth.1);
    };
    if !rs.is_empty() && rs.iter().all(|s| *s < first || *s > last) {
        bail!(
            "{}: every frame of topic {} lies outside the ground truth's time range \
             {first}..{last} ns in {}; are these the tracks of another log?",
            tracks.0.display(),
            tracks.1,
            truth.0.display()
        );
    }
    Ok(())
}

/// The numbers of a box an evaluation reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Reads {
    /// The 3D box and the score (KITTI's 3D IoU).
    Box3d,
    /// The ground-plane centre and the score (the nuScenes centre distance).
    GroundCentre,
}

/// The first box with a non-finite number the evaluation reads (`reads`), as an error: the
/// metrics can neither place nor rank it, and leaving it out would change the counts unsaid.
pub(super) fn check_finite(
    path: &Path,
    (topic, stamp): (&str, u64),
    boxes: &[LabelledBox],
    reads: Reads,
) -> Result<()> {
    let (ok, what): (fn(&LabelledBox) -> bool, _) = match reads {
        Reads::Box3d => (|b| b.is_finite(), "centre, size, yaw or score"),
        Reads::GroundCentre => (
            |b| b.center[0].is_finite() && b.center[1].is_finite(),
            "ground-plane centre or score",
        ),
    };
    let bad = (boxes.iter().enumerate()).find(|(_, b)| !(ok(b) && b.score.is_finite()));
    if let Some((i, b)) = bad {
        bail!(
            "{}: topic {topic}, stamp {stamp}: box {i} ({}, id {}) has a non-finite {what}; \
             the evaluation cannot score it",
            path.display(),
            b.label,
            b.id
        );
    }
    check_bounds(path, (topic, stamp), boxes, reads)
}

/// The first box beyond the physical bounds ([`crate::tracker::bounds`]: a centre coordinate
/// over 1e7 m, a size over 1e4 m), as an error: no tracker output holds one, and scoring it
/// would only hide that the input is broken.
fn check_bounds(
    path: &Path,
    (topic, stamp): (&str, u64),
    boxes: &[LabelledBox],
    reads: Reads,
) -> Result<()> {
    use crate::tracker::bounds::{MAX_COORDINATE, MAX_SIZE};
    let within = |b: &LabelledBox| match reads {
        Reads::Box3d => {
            b.center.iter().all(|v| v.abs() <= MAX_COORDINATE)
                && b.size.iter().all(|v| v.abs() <= MAX_SIZE)
        }
        Reads::GroundCentre => b.center[..2].iter().all(|v| v.abs() <= MAX_COORDINATE),
    };
    if let Some((i, b)) = (boxes.iter().enumerate()).find(|(_, b)| !within(b)) {
        bail!(
            "{}: topic {topic}, stamp {stamp}: box {i} ({}, id {}) lies beyond the physical \
             bounds (centre coordinates 1e7 m, sizes 1e4 m); the evaluation cannot score it",
            path.display(),
            b.label,
            b.id
        );
    }
    Ok(())
}

/// The first truth box without id (id 0; KITTI's `dontcare` regions excepted), as an error.
pub(super) fn check_ids(path: &Path, topic: &str, stamp: u64, boxes: &[LabelledBox]) -> Result<()> {
    if let Some(b) = boxes.iter().find(|b| b.id == 0 && b.label != "dontcare") {
        bail!(
            "{}: topic {topic}, stamp {stamp}: ground-truth box ({}) has no id (id 0); \
             ground truth needs the true instance ids",
            path.display(),
            b.label
        );
    }
    Ok(())
}
