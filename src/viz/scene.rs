//! What a Rerun recording of a run shows, prepared without the Rerun SDK: the frames of the
//! detections, tracks and ground-truth layers keyed by the MCAP log time, each track's trail of
//! recent centres, and a camera looking straight down at the boxes.
//!
//! Same semantics as `scripts/to_rerun.py`: a frame is a distinct log time of the topics read
//! (messages of one topic at the same log time are merged), a layer has a row in a frame only when
//! its topic has a message at that log time, boxes with a non-finite centre, size or yaw are left
//! out, and a track's trail holds its last `trail` centres up to and including this frame.

use std::collections::{BTreeMap, BTreeSet};

use super::{FileLayers, Layer};
use crate::mcapio::LabelledBox;
use crate::msgs::EvalEvents;

/// One frame of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFrame {
    /// MCAP log time of the frame's messages, ns.
    pub log_time: u64,
    /// Index of the frame among all frames, from 0.
    pub index: u64,
    /// Detection boxes, when the detections topic has a message at this log time.
    pub detections: Option<Vec<LabelledBox>>,
    /// Track boxes, when the tracks topic has a message at this log time.
    pub tracks: Option<Vec<LabelledBox>>,
    /// Ground-truth boxes, when the ground-truth topic has a message at this log time.
    pub ground_truth: Option<Vec<LabelledBox>>,
    /// For each box of `tracks` (same order): its id's last centres, oldest first, this
    /// frame's centre last. Empty when `tracks` is `None`.
    pub trails: Vec<Vec<[f64; 3]>>,
}

/// A camera above the scene looking straight down, +y up on screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TopDownCamera {
    /// Eye position, metres.
    pub eye: [f64; 3],
    /// The point looked at, on the ground (z = 0).
    pub look_target: [f64; 3],
    /// Screen up direction.
    pub up: [f64; 3],
}

/// The frames of one file, ready to be logged.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Frames in log-time order.
    pub frames: Vec<SceneFrame>,
    /// Which layers the file has (a topic with at least one message).
    pub layers: BTreeSet<Layer>,
    /// The evaluation's decisions per frame with their log times, when the file has them
    /// (`eval --events`); empty otherwise.
    pub events: Vec<(u64, EvalEvents)>,
}

/// Whether a box can be drawn: finite centre, size and yaw.
pub fn drawable(b: &LabelledBox) -> bool {
    b.center.iter().chain(&b.size).all(|v| v.is_finite()) && b.yaw.is_finite()
}

impl Scene {
    /// Builds the scene from the layers read by [`super::read_layers`]. Only boxes of `classes`
    /// are kept (all when empty); `trail` (at least 1) is the number of centres per trail.
    pub fn build(read: &FileLayers, classes: &[String], trail: usize) -> Scene {
        let trail = trail.max(1);
        let keep =
            |b: &LabelledBox| drawable(b) && (classes.is_empty() || classes.contains(&b.label));
        // Per layer: log time -> boxes of every message at that log time, in file order.
        let mut by_time: BTreeMap<Layer, BTreeMap<u64, Vec<LabelledBox>>> = BTreeMap::new();
        for lf in &read.layers {
            let frames = by_time.entry(lf.layer).or_default();
            for ((_, boxes), &t) in lf.frames.iter().zip(&lf.log_times) {
                frames
                    .entry(t)
                    .or_default()
                    .extend(boxes.iter().filter(|b| keep(b)).cloned());
            }
        }
        by_time.retain(|_, frames| !frames.is_empty());
        let times: BTreeSet<u64> = by_time.values().flat_map(|f| f.keys().copied()).collect();
        let mut take = |layer: Layer, t: u64| by_time.get_mut(&layer).and_then(|f| f.remove(&t));

        let mut history: BTreeMap<u64, Vec<[f64; 3]>> = BTreeMap::new();
        let mut frames = Vec::with_capacity(times.len());
        let layers: BTreeSet<Layer> = read
            .layers
            .iter()
            .filter(|l| !l.frames.is_empty())
            .map(|l| l.layer)
            .collect();
        for (index, &t) in times.iter().enumerate() {
            let tracks = take(Layer::Tracks, t);
            let trails = tracks
                .iter()
                .flatten()
                .map(|b| {
                    let h = history.entry(b.id).or_default();
                    h.push(b.center);
                    if h.len() > trail {
                        h.drain(..h.len() - trail);
                    }
                    h.clone()
                })
                .collect();
            frames.push(SceneFrame {
                log_time: t,
                index: index as u64,
                detections: take(Layer::Detections, t),
                tracks,
                ground_truth: take(Layer::GroundTruth, t),
                trails,
            });
        }
        Scene {
            frames,
            layers,
            events: Vec::new(),
        }
    }

    /// Every box of every frame and layer.
    pub fn boxes(&self) -> impl Iterator<Item = &LabelledBox> {
        self.frames.iter().flat_map(|f| {
            [&f.detections, &f.tracks, &f.ground_truth]
                .into_iter()
                .flatten()
                .flatten()
        })
    }

    /// Number of distinct track ids.
    pub fn track_ids(&self) -> usize {
        let ids: BTreeSet<u64> = self
            .frames
            .iter()
            .flat_map(|f| f.tracks.iter().flatten().map(|b| b.id))
            .collect();
        ids.len()
    }

    /// A camera looking straight down at the middle of the boxes, from `height_factor` times
    /// their extent (at least 20 m) above the ground, like `scripts/to_rerun.py`'s view (0.55).
    pub fn top_down_camera(&self, height_factor: f64) -> TopDownCamera {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for b in self.boxes() {
            for k in 0..2 {
                lo[k] = lo[k].min(b.center[k]);
                hi[k] = hi[k].max(b.center[k]);
            }
        }
        let (cx, cy, extent) = if lo[0].is_finite() {
            (
                (lo[0] + hi[0]) / 2.0,
                (lo[1] + hi[1]) / 2.0,
                (hi[0] - lo[0]).max(hi[1] - lo[1]).max(20.0),
            )
        } else {
            (0.0, 0.0, 50.0)
        };
        TopDownCamera {
            // A hair south of the target: a camera exactly above it has no defined "up".
            eye: [cx, cy - 0.001 * extent, height_factor * extent],
            look_target: [cx, cy, 0.0],
            up: [0.0, 1.0, 0.0],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::LayerFrames;
    use super::*;

    fn bx(id: u64, label: &str, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: label.into(),
            center: [x, 0.0, 0.5],
            size: [4.0, 2.0, 1.5],
            score: 0.9,
            velocity: [1.0, 0.0, 0.0],
            ..Default::default()
        }
    }

    fn layer(layer: Layer, msgs: Vec<(u64, Vec<LabelledBox>)>) -> LayerFrames {
        LayerFrames {
            layer,
            topic: layer.default_topic().into(),
            log_times: msgs.iter().map(|m| m.0).collect(),
            // The message stamps differ from the log times: frames follow the log time.
            frames: msgs.into_iter().map(|(t, b)| (t + 7, b)).collect(),
            frame_ids: BTreeSet::new(),
        }
    }

    fn read(layers: Vec<LayerFrames>) -> FileLayers {
        FileLayers {
            layers,
            topics: BTreeSet::new(),
            span: None,
        }
    }

    #[test]
    fn frames_follow_log_times_and_merge_messages() {
        let r = read(vec![
            layer(
                Layer::Detections,
                vec![(10, vec![bx(0, "car", 0.0)]), (30, vec![bx(0, "car", 1.0)])],
            ),
            layer(
                Layer::Tracks,
                vec![
                    (20, vec![bx(1, "car", 0.0)]),
                    (20, vec![bx(2, "pedestrian", 5.0)]),
                    (30, vec![]),
                ],
            ),
        ]);
        let s = Scene::build(&r, &[], 20);
        let times: Vec<u64> = s.frames.iter().map(|f| f.log_time).collect();
        assert_eq!(times, [10, 20, 30]);
        assert_eq!(
            s.frames.iter().map(|f| f.index).collect::<Vec<_>>(),
            [0, 1, 2]
        );
        assert!(s.frames[0].tracks.is_none() && s.frames[1].detections.is_none());
        assert_eq!(s.frames[1].tracks.as_ref().unwrap().len(), 2, "merged");
        assert_eq!(
            s.frames[2].tracks.as_deref(),
            Some(&[][..]),
            "empty frame kept"
        );
        assert!(s.frames.iter().all(|f| f.ground_truth.is_none()));
        assert_eq!(s.layers, BTreeSet::from([Layer::Detections, Layer::Tracks]));
        assert_eq!(s.track_ids(), 2);

        let cars = Scene::build(&r, &["car".to_string()], 20);
        assert_eq!(cars.frames[1].tracks.as_ref().unwrap().len(), 1);
        assert_eq!(cars.track_ids(), 1);
    }

    #[test]
    fn trails_keep_the_last_centres_of_each_id() {
        let msgs = (0..5u64)
            .map(|i| {
                (
                    i * 100,
                    vec![bx(3, "car", i as f64), bx(4, "car", -(i as f64))],
                )
            })
            .collect();
        let s = Scene::build(&read(vec![layer(Layer::Tracks, msgs)]), &[], 3);
        assert_eq!(s.frames[0].trails, vec![vec![[0.0, 0.0, 0.5]]; 2]);
        let last = &s.frames[4].trails;
        let xs: Vec<f64> = last[0].iter().map(|p| p[0]).collect();
        assert_eq!(xs, [2.0, 3.0, 4.0], "id 3, oldest first");
        let xs: Vec<f64> = last[1].iter().map(|p| p[0]).collect();
        assert_eq!(xs, [-2.0, -3.0, -4.0], "id 4");
    }

    #[test]
    fn non_finite_boxes_are_dropped() {
        let mut bad = bx(5, "car", 0.0);
        bad.yaw = f64::NAN;
        let s = Scene::build(
            &read(vec![layer(
                Layer::Tracks,
                vec![(1, vec![bad, bx(6, "car", 2.0)])],
            )]),
            &[],
            20,
        );
        let t = s.frames[0].tracks.as_ref().unwrap();
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].id, 6);
        assert_eq!(s.frames[0].trails.len(), 1);
    }

    #[test]
    fn camera_looks_down_at_the_middle() {
        let msgs = vec![(1, vec![bx(1, "car", -10.0), bx(2, "car", 90.0)])];
        let s = Scene::build(&read(vec![layer(Layer::Tracks, msgs)]), &[], 20);
        let c = s.top_down_camera(0.55);
        assert_eq!(c.look_target, [40.0, 0.0, 0.0]);
        assert!((c.eye[2] - 55.0).abs() < 1e-9);
        assert!((c.eye[0] - 40.0).abs() < 1e-12 && c.eye[1] < 0.0 && c.eye[1] > -0.2);
        let empty = Scene::build(&read(vec![]), &[], 20);
        assert!(empty.frames.is_empty());
        assert_eq!(empty.top_down_camera(0.55).look_target, [0.0; 3]);
    }
}
