//! Seeing the tracks: bird's-eye-view (BEV) pictures of the boxes of a recording.
//!
//! This module reads the layers (detections, tracks, ground truth) of an MCAP file into plain
//! per-frame box lists and selects a class and a time window; [`plot`] draws them, with no I/O.

pub mod labels;
mod legend;
pub mod plot;
pub mod plot_file;
pub mod plot_layout;
mod plot_panel;
mod plot_scene;
pub mod plot_types;
#[cfg(feature = "rerun")]
pub mod rrd;
pub mod rrd_file;
pub mod rrd_options;
pub mod scene;
pub mod text;
pub mod truth_colors;
pub mod window;

use std::collections::BTreeSet;
use std::fmt;
use std::path::Path;

use anyhow::Result;

use crate::mcapio::recording::{self, Boxes, TopicKind, TopicRequest};
use crate::mcapio::LabelledBox;
use crate::msgs::{self, Detection3D, Track3D};

/// A track as drawn. Nothing draws attributes, so they are not kept.
fn drawn_track(t: Track3D) -> LabelledBox {
    LabelledBox::from_track(t).keep_attributes(|_| false)
}

/// A detection as drawn (a missing centre or size draws at zero, as the message says).
fn drawn_detection(d: Detection3D) -> LabelledBox {
    LabelledBox::from_detection(d).keep_attributes(|_| false)
}

/// The boxes of a decoded message as drawn.
pub(crate) fn drawn_boxes(boxes: Boxes) -> Vec<LabelledBox> {
    // Extended into a vector of exactly their number: `collect` would reuse the decoded
    // message's larger allocation, and a plot holds every frame's boxes to the end.
    let mut drawn = Vec::new();
    match boxes {
        Boxes::Detections(d) => {
            drawn.reserve_exact(d.len());
            drawn.extend(d.into_iter().map(drawn_detection));
        }
        Boxes::Tracks(t) => {
            drawn.reserve_exact(t.len());
            drawn.extend(t.into_iter().map(drawn_track));
        }
    }
    drawn
}

/// Boxes of one frame: `(stamp in ns, boxes)`.
pub type Frame = (u64, Vec<LabelledBox>);

/// What a channel holds, and so how it is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Layer {
    /// Detections (any input `track` reads: probmot, ROS 2 vision_msgs, Foxglove SceneUpdate):
    /// boxes without ids, drawn grey.
    Detections,
    /// `probmot.Tracks3D` written by the tracker: a colour per track id.
    Tracks,
    /// `probmot.Tracks3D` holding the true instances: a colour per instance id.
    GroundTruth,
}

impl Layer {
    /// Every layer, in panel order.
    pub const ALL: [Layer; 3] = [Layer::Detections, Layer::Tracks, Layer::GroundTruth];

    /// The name used on the command line (`detections`, `tracks`, `ground_truth`).
    pub fn name(self) -> &'static str {
        match self {
            Layer::Detections => "detections",
            Layer::Tracks => "tracks",
            Layer::GroundTruth => "ground_truth",
        }
    }

    /// Parses a command-line name (`-` may stand for `_`, and `gt`/`truth` for ground truth).
    pub fn parse(s: &str) -> Option<Layer> {
        match s.trim().to_ascii_lowercase().replace('-', "_").as_str() {
            "detections" | "dets" => Some(Layer::Detections),
            "tracks" => Some(Layer::Tracks),
            "ground_truth" | "groundtruth" | "gt" | "truth" => Some(Layer::GroundTruth),
            _ => None,
        }
    }

    /// The topic probmot writes this layer on.
    pub fn default_topic(self) -> &'static str {
        match self {
            Layer::Detections => "/detections",
            Layer::Tracks => "/tracks",
            Layer::GroundTruth => "/ground_truth",
        }
    }

    /// The option that names the layer's topic.
    pub fn topic_flag(self) -> &'static str {
        match self {
            Layer::Detections => "--detections-topic",
            Layer::Tracks => "--tracks-topic",
            Layer::GroundTruth => "--truth-topic",
        }
    }

    /// Schema the layer's channel must have.
    pub fn schema(self) -> &'static str {
        match self {
            Layer::Detections => msgs::DETECTIONS_SCHEMA,
            Layer::Tracks | Layer::GroundTruth => msgs::TRACKS_SCHEMA,
        }
    }

    /// The request that reads this layer from `topic` ([`recording::Decoder`]): detections
    /// of any input `track` reads (probmot, ROS 2, Foxglove), else tracks.
    pub fn request(self, topic: &str) -> TopicRequest {
        TopicRequest {
            topic: topic.to_string(),
            kind: match self {
                Layer::Detections => TopicKind::Detections,
                Layer::Tracks | Layer::GroundTruth => TopicKind::Tracks,
            },
            role: format!("{self} layer"),
        }
    }

    /// Whether boxes carry ids (and so get a colour each).
    pub fn has_ids(self) -> bool {
        !matches!(self, Layer::Detections)
    }

    /// Human title of the layer.
    pub fn title(self) -> &'static str {
        match self {
            Layer::Detections => "detections",
            Layer::Tracks => "tracks",
            Layer::GroundTruth => "ground truth",
        }
    }
}

/// Refuses a layer topic named on purpose (not the layer's default) that `file` lacks, as plot
/// and viz do: a misspelt topic would otherwise only drop its layer. `named` gives each drawn
/// layer's topic, `topics` every topic of the file; the error names them
/// ([`recording::topic_list`]) and the option to check.
pub fn check_named_topics<'a>(
    file: impl fmt::Display,
    named: impl IntoIterator<Item = (Layer, &'a str)>,
    topics: &BTreeSet<String>,
) -> Result<()> {
    let mut named = named.into_iter();
    let missing = named.find(|(l, t)| *t != l.default_topic() && !topics.contains(*t));
    match missing {
        Some((l, t)) => anyhow::bail!(
            "{file} has no topic {t} for the {l} layer ({}); check {}",
            recording::topic_list(topics),
            l.topic_flag()
        ),
        None => Ok(()),
    }
}

impl fmt::Display for Layer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The frames of one layer as read from its topic, in file order.
#[derive(Debug, Clone)]
pub struct LayerFrames {
    /// Which layer.
    pub layer: Layer,
    /// The topic it was read from.
    pub topic: String,
    /// Frames in file order (one per message).
    pub frames: Vec<Frame>,
    /// The MCAP log time of each frame's message, ns (`log_times[i]` belongs to `frames[i]`).
    pub log_times: Vec<u64>,
    /// The `frame_id`s of the messages read (empty when the reader does not keep them).
    pub frame_ids: BTreeSet<String>,
}

/// The layers of one file, read in a single pass.
#[derive(Debug, Clone)]
pub struct FileLayers {
    /// The layers found, in the order asked for. A layer whose topic the file lacks is absent.
    pub layers: Vec<LayerFrames>,
    /// Every topic of the file (for error messages).
    pub topics: BTreeSet<String>,
    /// First and last frame stamp over the layers' topics, when known without the frames (a
    /// windowed read holds only the window's frames).
    pub span: Option<(u64, u64)>,
}

impl FileLayers {
    /// The layer, if its topic was found.
    pub fn get(&self, layer: Layer) -> Option<&LayerFrames> {
        self.layers.iter().find(|l| l.layer == layer)
    }

    /// The frames read for one layer, to take boxes out of.
    pub fn get_mut(&mut self, layer: Layer) -> Option<&mut LayerFrames> {
        self.layers.iter_mut().find(|l| l.layer == layer)
    }

    /// Earliest frame stamp over all layers read, ns.
    pub fn first_stamp(&self) -> Option<u64> {
        if let Some((first, _)) = self.span {
            return Some(first);
        }
        self.layers
            .iter()
            .flat_map(|l| l.frames.iter().map(|f| f.0))
            .min()
    }

    /// Latest frame stamp over all layers read, ns.
    pub fn last_stamp(&self) -> Option<u64> {
        if let Some((_, last)) = self.span {
            return Some(last);
        }
        self.layers
            .iter()
            .flat_map(|l| l.frames.iter().map(|f| f.0))
            .max()
    }
}

/// Reads the given `(layer, topic)` channels of `path` in one pass (through
/// [`crate::mcapio::recording::frames`]). Topics the file lacks are left out of the result (see
/// [`FileLayers::topics`]); a topic with the wrong schema or an undecodable message is an error
/// naming the file, topic and log time.
pub fn read_layers(path: &Path, wanted: &[(Layer, String)]) -> Result<FileLayers> {
    let requests: Vec<TopicRequest> = wanted.iter().map(|(l, t)| l.request(t)).collect();
    let read = recording::frames(path, &requests)?;
    let layers = wanted
        .iter()
        .zip(read.frames)
        .filter_map(|((layer, topic), f)| {
            let f = f?;
            let log_times = f.iter().map(|fr| fr.log_time).collect();
            let frames = f
                .into_iter()
                .map(|fr| (fr.stamp, drawn_boxes(fr.boxes)))
                .collect();
            Some(LayerFrames {
                layer: *layer,
                topic: topic.clone(),
                frames,
                log_times,
                frame_ids: BTreeSet::new(),
            })
        })
        .collect();
    Ok(FileLayers {
        layers,
        topics: read.topics,
        span: None,
    })
}

/// Which boxes to keep: classes and a time window relative to a reference stamp.
#[derive(Debug, Clone, Default)]
pub struct Selection {
    /// Classes to keep (exact label match); empty keeps all.
    pub classes: Vec<String>,
    /// Window start, seconds after the reference stamp (inclusive).
    pub from_s: Option<f64>,
    /// Window end, seconds after the reference stamp (inclusive).
    pub to_s: Option<f64>,
}

impl Selection {
    /// Whether a frame at `stamp` lies in the window, `t0` being the reference (first) stamp.
    pub fn in_window(&self, stamp: u64, t0: u64) -> bool {
        let t = (stamp as f64 - t0 as f64) / 1e9;
        // Half a microsecond of slack so that `--to 9.5` keeps a frame stamped at 9.5 s.
        const EPS: f64 = 5e-7;
        self.from_s.is_none_or(|f| t >= f - EPS) && self.to_s.is_none_or(|e| t <= e + EPS)
    }

    /// Whether a box's class is kept.
    pub fn keeps_class(&self, label: &str) -> bool {
        self.classes.is_empty() || self.classes.iter().any(|c| c == label)
    }

    /// The frames of `frames` in the window with only the kept classes (frames left empty by the
    /// class filter are kept, so the frame count still tells the window's length).
    pub fn apply(&self, frames: &[Frame], t0: u64) -> Vec<Frame> {
        frames
            .iter()
            .filter(|(s, _)| self.in_window(*s, t0))
            .map(|(s, boxes)| {
                (
                    *s,
                    boxes
                        .iter()
                        .filter(|b| self.keeps_class(&b.label))
                        .cloned()
                        .collect(),
                )
            })
            .collect()
    }

    /// [`Self::apply`], moving the frames out of `frames` (left empty) instead of copying them.
    pub fn take(&self, frames: &mut Vec<Frame>, t0: u64) -> Vec<Frame> {
        let mut kept = std::mem::take(frames);
        kept.retain(|(s, _)| self.in_window(*s, t0));
        for (_, boxes) in &mut kept {
            boxes.retain(|b| self.keeps_class(&b.label));
        }
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bx(id: u64, label: &str) -> LabelledBox {
        LabelledBox {
            id,
            label: label.into(),
            center: [1.0, 2.0, 0.5],
            size: [4.0, 2.0, 1.5],
            score: 1.0,
            ..Default::default()
        }
    }

    #[test]
    fn corners_follow_the_heading() {
        let mut b = bx(1, "car");
        let c = b.bev_corners();
        assert_eq!(c[0], (3.0, 3.0));
        assert_eq!(c[2], (-1.0, 1.0));
        b.yaw = std::f64::consts::FRAC_PI_2;
        let c = b.bev_corners();
        // Front-left of a box heading +y lies at +y (front) and -x (left).
        assert!((c[0].0 - 0.0).abs() < 1e-12 && (c[0].1 - 4.0).abs() < 1e-12);
    }

    #[test]
    fn layer_names_round_trip() {
        for l in Layer::ALL {
            assert_eq!(Layer::parse(l.name()), Some(l));
        }
        assert_eq!(Layer::parse("ground-truth"), Some(Layer::GroundTruth));
        assert_eq!(Layer::parse("gt"), Some(Layer::GroundTruth));
        assert_eq!(Layer::parse("lidar"), None);
    }

    #[test]
    fn selection_filters_window_and_class() {
        let t0 = 1_000_000_000_000;
        let frames: Vec<Frame> = (0..10u64)
            .map(|i| {
                (
                    t0 + i * 500_000_000,
                    vec![bx(1, "car"), bx(2, "pedestrian")],
                )
            })
            .collect();
        let sel = Selection {
            classes: vec!["car".into()],
            from_s: Some(1.0),
            to_s: Some(2.0),
        };
        let out = sel.apply(&frames, t0);
        assert_eq!(out.len(), 3, "1.0, 1.5 and 2.0 s");
        assert!(out.iter().all(|(_, b)| b.len() == 1 && b[0].label == "car"));
        let all = Selection::default().apply(&frames, t0);
        assert_eq!(all.len(), 10);
        assert_eq!(all[0].1.len(), 2);
        let mut read = frames.clone();
        assert_eq!(sel.take(&mut read, t0), out);
        assert!(read.is_empty());
    }
}
