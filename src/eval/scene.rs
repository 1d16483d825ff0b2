//! Loading ground truth and tracks from MCAP into per-frame box lists (one log = one scene).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Result};

use crate::mcapio::recording::{self, Boxes, FrameEvent, TopicKind, TopicRequest};
use crate::mcapio::LabelledBox;

/// Ground truth and tracks of one log, by frame stamp (ns). Every stamp of either channel is a
/// frame; a frame may hold no box of one or both.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// Name (the file name), used in reports.
    pub name: String,
    /// Frames in stamp order: `(stamp_ns, truth boxes, track boxes)`.
    pub frames: Vec<(u64, Vec<LabelledBox>, Vec<LabelledBox>)>,
}

/// Reads the tracks messages of one topic (`probmot.Tracks3D`, or ROS 2
/// `vision_msgs/msg/Detection3DArray` tracks: [`recording::frames`]): `(stamp, boxes)` per
/// message (the stamp is the message's, or its `log_time` when that is 0).
pub fn read_tracks_topic(path: &Path, topic: &str) -> Result<Vec<(u64, Vec<LabelledBox>)>> {
    read_boxes(path, topic, &|_| {}, false)
}

/// Whether the evaluation reads an attribute: the KITTI fields (`kitti_*`) and the nuScenes
/// ones (`nuscenes_*`: point counts, rack rotations). Others (e.g. `sim_truth_id`, which
/// `track` copies from each detection to its track) are dropped by [`load_scene_progress`]: a
/// map per box would be most of a long log's memory.
pub fn is_evaluated_attribute(key: &str) -> bool {
    key.starts_with("kitti_") || key.starts_with("nuscenes_")
}

/// The boxes of a tracks topic, message by message; `evaluated_only` keeps only the
/// attributes [`is_evaluated_attribute`] names.
fn read_boxes(
    path: &Path,
    topic: &str,
    progress: &dyn Fn(u64),
    evaluated_only: bool,
) -> Result<Vec<(u64, Vec<LabelledBox>)>> {
    let req = TopicRequest {
        topic: topic.to_string(),
        kind: TopicKind::Tracks,
        role: "tracks or ground truth".to_string(),
    };
    let mut out = Vec::new();
    let mut found = false;
    let mut reported = 0u64;
    recording::for_each_frame(path, std::slice::from_ref(&req), |event, stats| {
        progress(stats.bytes_read.saturating_sub(reported));
        reported = reported.max(stats.bytes_read);
        match event {
            FrameEvent::Channel(_) => found = true,
            FrameEvent::Frame(_, f) => {
                let boxes: Vec<LabelledBox> = match f.boxes {
                    Boxes::Tracks(t) => t
                        .into_iter()
                        .map(LabelledBox::from_track)
                        .map(|b| match evaluated_only {
                            true => b.keep_attributes(is_evaluated_attribute),
                            false => b,
                        })
                        .collect(),
                    Boxes::Detections(_) => unreachable!("a tracks request gives tracks"),
                };
                out.push((f.stamp, boxes));
            }
        }
        Ok(())
    })?;
    if !found {
        bail!("{}: no channel with topic {topic}", path.display());
    }
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
/// `probmot import kitti` stores with id 0 and label `dontcare`).
pub fn load_scene_with(
    truth: &Path,
    truth_topic: &str,
    tracks: &Path,
    tracks_topic: &str,
    allow_unlabelled: bool,
) -> Result<Scene> {
    load_scene_progress(
        (truth, truth_topic),
        (tracks, tracks_topic),
        allow_unlabelled,
        &|_| {},
    )
}

/// [`load_scene_with`], telling `progress` the bytes read (both files, the shared file twice),
/// keeping only the attributes the evaluation reads ([`is_evaluated_attribute`]).
pub fn load_scene_progress(
    (truth, truth_topic): (&Path, &str),
    (tracks, tracks_topic): (&Path, &str),
    allow_unlabelled: bool,
    progress: &dyn Fn(u64),
) -> Result<Scene> {
    let gt = read_boxes(truth, truth_topic, progress, true)?;
    let tr = read_boxes(tracks, tracks_topic, progress, true)?;
    for (stamp, boxes) in gt.iter().filter(|_| !allow_unlabelled) {
        check_ids(truth, truth_topic, *stamp, boxes)?;
    }
    // Frames are the union of both channels' stamps.
    let stamps = |v: &[(u64, Vec<LabelledBox>)]| v.iter().map(|m| m.0).collect::<Vec<_>>();
    check(
        &stamps(&gt),
        &stamps(&tr),
        (truth, truth_topic),
        (tracks, tracks_topic),
    )?;
    let mut frames: BTreeMap<u64, (Vec<LabelledBox>, Vec<LabelledBox>)> = BTreeMap::new();
    for (s, b) in gt {
        frames.entry(s).or_default().0.extend(b);
    }
    for (s, b) in tr {
        frames.entry(s).or_default().1.extend(b);
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
