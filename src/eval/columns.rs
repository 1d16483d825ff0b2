//! The compact store of one log's boxes that the nuScenes metrics and the centre-distance HOTA
//! read: per side (truth, tracks) one column per field they use (id, class, ground-plane centre,
//! score) and per frame an offset range into the columns; about 34 bytes per box, no per-box
//! strings or maps. It is built while the log streams ([`load_columns`]): each message's boxes
//! are filtered (the nuScenes filters) and appended, and nothing else of them is kept.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;

use super::kitti_box::KittiFields;
use super::scene::{check, check_finite, check_ids, Reads, Scene};
use crate::mcapio::recording::{self, Boxes, FrameEvent, TopicKind, TopicRequest};
use crate::mcapio::LabelledBox;
use crate::tracker::Box3;

/// The boxes of one channel, frame by frame: frame `f`'s boxes are `at[f]..at[f + 1]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Side {
    /// Offsets into the columns, one more than there are frames.
    pub at: Vec<usize>,
    /// Track or instance id.
    pub id: Vec<u64>,
    /// Class, an index into [`ColumnScene::labels`].
    pub label: Vec<u16>,
    /// Centre on the ground plane (x, y).
    pub xy: Vec<[f64; 2]>,
    /// Score (tracks) or what the truth message says (1).
    pub score: Vec<f64>,
    /// Height of the centre, length, width, height and yaw, for `eval --events` (empty unless
    /// loaded with `geometry`).
    pub geometry: Vec<[f64; 5]>,
}

impl Side {
    /// A side with no frame yet, to fill frame by frame with [`Side::push_box`] and
    /// [`Side::end_frame`] (what an in-process tracker run writes, e.g. `probmot tune`).
    pub fn new() -> Side {
        Side {
            at: vec![0],
            ..Side::default()
        }
    }

    /// Appends a box (id, class index, ground-plane centre, score) to the frame being filled.
    pub fn push_box(&mut self, id: u64, label: u16, xy: [f64; 2], score: f64) {
        self.id.push(id);
        self.label.push(label);
        self.xy.push(xy);
        self.score.push(score);
    }

    /// Closes the frame being filled: its boxes are those pushed since the last close.
    pub fn end_frame(&mut self) {
        self.at.push(self.id.len());
    }

    /// The column range of frame `f`.
    pub fn frame(&self, f: usize) -> std::ops::Range<usize> {
        self.at[f]..self.at[f + 1]
    }

    /// Number of boxes.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// Whether there is no box.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    fn push<B: KittiFields>(&mut self, b: &B, label: u16, geometry: bool) {
        let Box3 { center, size, yaw } = b.box3();
        self.push_box(b.id(), label, [center[0], center[1]], b.score());
        if geometry {
            let [l, w, h] = size;
            self.geometry.push([center[2], l, w, h, yaw]);
        }
    }

    /// The boxes at `rows`, in that order (offsets left empty).
    fn gather(&self, rows: impl Iterator<Item = usize>) -> Side {
        let mut out = Side::default();
        for i in rows {
            out.id.push(self.id[i]);
            out.label.push(self.label[i]);
            out.xy.push(self.xy[i]);
            out.score.push(self.score[i]);
            if let Some(g) = self.geometry.get(i) {
                out.geometry.push(*g);
            }
        }
        out
    }
}

/// Ground truth and tracks of one log (one scene), columnar. Every stamp of either channel is a
/// frame, in stamp order; a frame may hold no box of one or both.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnScene {
    /// Name (the tracks file's name), used in reports.
    pub name: String,
    /// The class names the label columns index.
    pub labels: Vec<String>,
    /// Frame stamps (ns), increasing.
    pub stamps: Vec<u64>,
    /// Ground truth.
    pub truth: Side,
    /// Tracks.
    pub tracks: Side,
}

/// Boxes of `scenes` whose label is none of `classes`, per label: `[truth boxes, track boxes]`
/// (what an evaluation of those classes leaves out, e.g. KITTI's `cyclist` under the nuScenes
/// classes, which call it `bicycle`).
pub fn boxes_outside(scenes: &[ColumnScene], classes: &[String]) -> BTreeMap<String, [u64; 2]> {
    let mut out: BTreeMap<String, [u64; 2]> = BTreeMap::new();
    for s in scenes {
        for (k, side) in [&s.truth, &s.tracks].into_iter().enumerate() {
            for &l in &side.label {
                let name = &s.labels[l as usize];
                if !classes.contains(name) {
                    out.entry(name.clone()).or_default()[k] += 1;
                }
            }
        }
    }
    out
}

impl ColumnScene {
    /// The index of class `name` in [`ColumnScene::labels`], if any box has it.
    pub fn label_index(&self, name: &str) -> Option<u16> {
        self.labels.iter().position(|l| l == name).map(|i| i as u16)
    }

    /// The index of class `name`, added to [`ColumnScene::labels`] when no box had it yet.
    pub fn label_or_add(&mut self, name: &str) -> u16 {
        label_or_add(&mut self.labels, name)
    }

    /// The columns of a [`Scene`] (the same frames and boxes, in the same order), of whole
    /// boxes or of what the evaluations read of them ([`KittiBox`](super::kitti_box::KittiBox)).
    pub fn from_scene<B: KittiFields>(scene: &Scene<B>) -> ColumnScene {
        Self::of_scene(scene, false)
    }

    /// [`ColumnScene::from_scene`] with the boxes' geometry ([`Side::geometry`]).
    pub fn from_scene_with_geometry<B: KittiFields>(scene: &Scene<B>) -> ColumnScene {
        Self::of_scene(scene, true)
    }

    fn of_scene<B: KittiFields>(scene: &Scene<B>, geometry: bool) -> ColumnScene {
        let mut b = Builder {
            geometry,
            ..Builder::default()
        };
        for (stamp, truth, tracks) in &scene.frames {
            b.push(0, *stamp, truth);
            b.push(1, *stamp, tracks);
        }
        b.finish(scene.name.clone(), None)
            .expect("no checks without paths")
    }
}

/// The index of `name` in `labels`, appended when missing.
fn label_or_add(labels: &mut Vec<String>, name: &str) -> u16 {
    match labels.iter().position(|l| l == name) {
        Some(i) => i as u16,
        None => {
            labels.push(name.to_string());
            (labels.len() - 1) as u16
        }
    }
}

/// One channel while it streams: its messages' stamps and where their boxes start.
#[derive(Default)]
struct Stream {
    messages: Vec<(u64, usize)>,
    cols: Side,
}

impl Stream {
    /// The columns in stamp order (messages of one stamp in reading order) and the distinct
    /// stamps with their offsets.
    fn into_frames(mut self) -> (Vec<u64>, Side) {
        let total = self.cols.len();
        let sorted = self.messages.windows(2).all(|w| w[0].0 <= w[1].0);
        if !sorted {
            let end = |k: usize, m: &[(u64, usize)]| m.get(k + 1).map_or(total, |n| n.1);
            let mut order: Vec<usize> = (0..self.messages.len()).collect();
            order.sort_by_key(|&k| self.messages[k].0);
            let rows = order
                .iter()
                .flat_map(|&k| self.messages[k].1..end(k, &self.messages));
            let cols = self.cols.gather(rows);
            let mut start = 0;
            self.messages = order
                .iter()
                .map(|&k| {
                    let s = (self.messages[k].0, start);
                    start += end(k, &self.messages) - self.messages[k].1;
                    s
                })
                .collect();
            self.cols = cols;
        }
        let mut stamps = Vec::new();
        self.cols.at.clear();
        for &(stamp, start) in &self.messages {
            if stamps.last() != Some(&stamp) {
                stamps.push(stamp);
                self.cols.at.push(start);
            }
        }
        self.cols.at.push(total);
        (stamps, self.cols)
    }
}

/// A file and a topic in it.
type Topic<'a> = (&'a Path, &'a str);

/// Builds a [`ColumnScene`] from messages of both channels.
#[derive(Default)]
struct Builder {
    labels: Vec<String>,
    sides: [Stream; 2],
    /// Whether to keep the boxes' geometry ([`Side::geometry`]).
    geometry: bool,
}

impl Builder {
    fn label(&mut self, name: &str) -> u16 {
        label_or_add(&mut self.labels, name)
    }

    /// Appends one message of side `s` (0 truth, 1 tracks).
    fn push<B: KittiFields>(&mut self, s: usize, stamp: u64, boxes: &[B]) {
        let start = self.sides[s].cols.len();
        self.sides[s].messages.push((stamp, start));
        for b in boxes {
            let l = self.label(b.label());
            self.sides[s].cols.push(b, l, self.geometry);
        }
    }

    /// The scene; with the files' paths and topics, checked ([`check`]).
    fn finish(self, name: String, files: Option<(Topic<'_>, Topic<'_>)>) -> Result<ColumnScene> {
        let [truth, tracks] = self.sides;
        let (ts, mut truth) = truth.into_frames();
        let (rs, mut tracks) = tracks.into_frames();
        if let Some((t, r)) = files {
            check(&ts, &rs, t, r)?;
        }
        let mut stamps: Vec<u64> = ts.iter().chain(&rs).copied().collect();
        stamps.sort_unstable();
        stamps.dedup();
        truth.at = union_offsets(&stamps, &ts, &truth.at);
        tracks.at = union_offsets(&stamps, &rs, &tracks.at);
        Ok(ColumnScene {
            name,
            labels: self.labels,
            stamps,
            truth,
            tracks,
        })
    }
}

/// The offsets of a side's frames (`own` stamps, `at` offsets) over the frames `all` (a sorted
/// superset): a frame of `all` the side has no message at is empty.
fn union_offsets(all: &[u64], own: &[u64], at: &[usize]) -> Vec<usize> {
    let mut out = Vec::with_capacity(all.len() + 1);
    let mut k = 0;
    for &s in all {
        out.push(at[k]);
        if own.get(k) == Some(&s) {
            k += 1;
        }
    }
    out.push(at[k]);
    out
}

/// Per message, what the caller removes from its boxes before they are stored (the nuScenes
/// filters): `(stamp, boxes, is_truth)`.
pub type MessageFilter<'a> = dyn FnMut(u64, &mut Vec<LabelledBox>, bool) -> Result<()> + 'a;

/// Loads one scene into columns while streaming: truth and tracks topics (one pass when both
/// are in the same file), each message filtered by `filter`, checked as
/// [`super::scene::load_scene`] checks (truth boxes need ids, tracks must share time with the
/// truth). `progress` is told the bytes read (a shared file counts twice, as two reads would).
/// With `geometry` the boxes' geometry is kept too ([`Side::geometry`], for `eval --events`).
pub fn load_columns(
    (truth, truth_topic): (&Path, &str),
    (tracks, tracks_topic): (&Path, &str),
    progress: &dyn Fn(u64),
    filter: &mut MessageFilter<'_>,
    geometry: bool,
) -> Result<ColumnScene> {
    let mut b = Builder {
        geometry,
        ..Builder::default()
    };
    let request = |topic: &str| TopicRequest {
        topic: topic.to_string(),
        kind: TopicKind::Tracks,
        role: "tracks or ground truth".to_string(),
    };
    let one_pass = truth == tracks;
    let mut files: Vec<(&Path, Vec<(usize, &str)>)> = vec![(truth, vec![(0, truth_topic)])];
    if one_pass {
        files[0].1.push((1, tracks_topic));
    } else {
        files.push((tracks, vec![(1, tracks_topic)]));
    }
    let weight = if one_pass { 2 } else { 1 };
    let mut boxes: Vec<LabelledBox> = Vec::new();
    for (path, sides) in files {
        let reqs: Vec<TopicRequest> = sides.iter().map(|s| request(s.1)).collect();
        let mut found = vec![false; reqs.len()];
        let mut reported = 0u64;
        let topics = recording::for_each_frame(path, &reqs, |event, stats| {
            progress(weight * stats.bytes_read.saturating_sub(reported));
            reported = reported.max(stats.bytes_read);
            match event {
                FrameEvent::Channel(i) => found[i] = true,
                FrameEvent::Frame(i, f) => {
                    let side = sides[i].0;
                    boxes.clear();
                    match f.boxes {
                        Boxes::Tracks(t) => {
                            boxes.extend(t.into_iter().map(LabelledBox::from_track))
                        }
                        Boxes::Detections(_) => unreachable!("a tracks request gives tracks"),
                    }
                    if side == 0 {
                        check_ids(path, sides[i].1, f.stamp, &boxes)?;
                    }
                    filter(f.stamp, &mut boxes, side == 0)?;
                    // After the filters: what they remove is not scored.
                    let at = (sides[i].1, f.stamp);
                    check_finite(path, at, &boxes, Reads::GroundCentre)?;
                    b.push(side, f.stamp, &boxes);
                }
            }
            Ok(())
        })?;
        if let Some(k) = found.iter().position(|f| !f) {
            return Err(recording::no_channel(path.display(), sides[k].1, &topics));
        }
        let size = std::fs::metadata(path).map_or(reported, |m| m.len());
        progress(weight * size.saturating_sub(reported));
    }
    let name = tracks
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    b.finish(name, Some(((truth, truth_topic), (tracks, tracks_topic))))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(id: u64, label: &str, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: label.into(),
            center: [x, -x, 7.0],
            score: 0.5,
            ..Default::default()
        }
    }

    #[test]
    fn frames_are_the_stamps_of_both_channels_in_order_messages_of_a_stamp_in_reading_order() {
        let mut s = Builder::default();
        s.push(0, 20, &[b(1, "car", 1.0)]);
        s.push(0, 10, &[b(2, "bus", 2.0), b(3, "car", 3.0)]);
        s.push(0, 20, &[b(4, "car", 4.0)]);
        s.push(1, 30, &[b(9, "pedestrian", 9.0)]);
        s.push::<LabelledBox>(1, 10, &[]);
        let c = s.finish("x".into(), None).unwrap();
        assert_eq!(c.stamps, vec![10, 20, 30]);
        assert_eq!(c.labels, vec!["car", "bus", "pedestrian"]);
        assert_eq!(c.truth.at, vec![0, 2, 4, 4]);
        assert_eq!(c.truth.id, vec![2, 3, 1, 4]);
        assert_eq!(c.truth.label, vec![1, 0, 0, 0]);
        assert_eq!(c.truth.xy[1], [3.0, -3.0]);
        assert_eq!(c.tracks.at, vec![0, 0, 0, 1]);
        assert_eq!((c.tracks.id[0], c.tracks.score[0]), (9, 0.5));
        assert_eq!(c.label_index("pedestrian"), Some(2));
        assert_eq!(c.label_index("truck"), None);
    }

    #[test]
    fn from_scene_keeps_frames_without_boxes() {
        let scene = Scene {
            name: "s".into(),
            frames: vec![(5, vec![], vec![]), (6, vec![b(1, "car", 0.0)], vec![])],
        };
        let c = ColumnScene::from_scene(&scene);
        assert_eq!(
            (c.stamps.clone(), c.truth.at.clone()),
            (vec![5, 6], vec![0, 0, 1])
        );
        assert_eq!(c.tracks.at, vec![0, 0, 0]);
    }
}
