//! The nuScenes range filter: boxes farther from the ego vehicle than their class's range are
//! removed from ground truth and tracks before anything else (before the mean track score and the
//! interpolation over gaps), as the devkit's `filter_eval_boxes` does with `class_range` of the
//! `tracking_nips_2019` configuration.
//!
//! The distance is the devkit's `ego_dist`: the ground-plane (x, y) distance between the box
//! centre and the ego vehicle's position in the same frame; a box is kept when it is strictly
//! nearer than the range. The ego position comes from the log (the `/ego_pose` channel that
//! `probmot import nuscenes` writes), at each frame's stamp.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};

use super::scene::Scene;
use crate::mcapio::topic::for_each_payload;
use crate::mcapio::LabelledBox;
use crate::msgs::EGO_POSE_SCHEMA;
use crate::pipeline::per_class::PerClass;

/// Maximum ego distance per class, metres.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeFilter {
    /// Range of each named class.
    pub per_class: BTreeMap<String, f64>,
    /// Range of classes not named (`None`: not filtered).
    pub other: Option<f64>,
}

impl RangeFilter {
    /// The devkit's `class_range` of `tracking_nips_2019`: 40 m for bicycle, motorcycle and
    /// pedestrian, 50 m for bus, car, trailer and truck.
    pub fn nuscenes() -> RangeFilter {
        let per_class = [
            ("bicycle", 40.0),
            ("motorcycle", 40.0),
            ("pedestrian", 40.0),
            ("bus", 50.0),
            ("car", 50.0),
            ("trailer", 50.0),
            ("truck", 50.0),
        ]
        .into_iter()
        .map(|(c, r)| (c.to_string(), r))
        .collect();
        RangeFilter {
            per_class,
            other: None,
        }
    }

    /// Parses `nuscenes` (the devkit's table), a single number (every class), or
    /// `class=metres,...` with an optional `*=metres` for the classes not named.
    pub fn parse(spec: &str) -> Result<RangeFilter, String> {
        let spec = spec.trim();
        if spec == "nuscenes" {
            return Ok(RangeFilter::nuscenes());
        }
        let spec = PerClass::parse(spec, "metres")?;
        Ok(RangeFilter {
            per_class: spec.named,
            other: spec.other,
        })
    }

    /// The range of a class, if it is filtered.
    pub fn range_of(&self, class: &str) -> Option<f64> {
        self.per_class.get(class).copied().or(self.other)
    }

    /// Whether a box at ground-plane offset `(dx, dy)` from the ego vehicle is kept.
    pub fn keeps(&self, class: &str, dx: f64, dy: f64) -> bool {
        match self.range_of(class) {
            Some(r) => (dx * dx + dy * dy).sqrt() < r,
            None => true,
        }
    }
}

/// The ego vehicle's positions over a log, by stamp.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EgoPositions {
    /// `(stamp_ns, [x, y, z])`, sorted by stamp, stamps unique.
    pub samples: Vec<(u64, [f64; 3])>,
}

impl EgoPositions {
    /// The position at `stamp`: the sample at that stamp, or linearly interpolated between the
    /// neighbouring samples; `None` outside the sampled time range.
    pub fn at(&self, stamp: u64) -> Option<[f64; 3]> {
        let i = self.samples.partition_point(|(s, _)| *s < stamp);
        let (s1, p1) = *self.samples.get(i)?;
        if s1 == stamp {
            return Some(p1);
        }
        let (s0, p0) = *self.samples.get(i.checked_sub(1)?)?;
        let t = (stamp - s0) as f64 / (s1 - s0) as f64;
        Some([0, 1, 2].map(|k| p0[k] + t * (p1[k] - p0[k])))
    }
}

#[derive(serde::Deserialize)]
struct EgoPoseJson {
    stamp: u64,
    translation: [f64; 3],
}

/// Reads the ego positions of `topic` (schema `probmot.EgoPose`, JSON) from `path`.
pub fn read_ego_positions(path: &Path, topic: &str) -> Result<EgoPositions> {
    let file = path.display().to_string();
    let mut samples: BTreeMap<u64, [f64; 3]> = BTreeMap::new();
    let found = for_each_payload(
        path,
        topic,
        |c, name| {
            if name != EGO_POSE_SCHEMA || c.message_encoding != "json" {
                bail!(
                    "{file}: topic {topic} has schema '{name}' ({}); the range filter needs \
                     {EGO_POSE_SCHEMA} (json), as `probmot import nuscenes` writes",
                    c.message_encoding
                );
            }
            Ok(())
        },
        |header, data, ()| {
            let m: EgoPoseJson = serde_json::from_slice(data).with_context(|| {
                format!(
                    "{file}: topic {topic}, message at log_time {} (sequence {}): cannot \
                     decode {EGO_POSE_SCHEMA}",
                    header.log_time, header.sequence
                )
            })?;
            if m.translation.iter().any(|v| !v.is_finite()) {
                bail!(
                    "{file}: topic {topic}, message at log_time {}: non-finite translation",
                    header.log_time
                );
            }
            if let Some(old) = samples.insert(m.stamp, m.translation) {
                if old != m.translation {
                    bail!(
                        "{file}: topic {topic}: two different ego poses at stamp {}",
                        m.stamp
                    );
                }
            }
            Ok(())
        },
        |_| Ok(()),
    )?;
    if !found {
        bail!(
            "{file}: no channel with topic {topic}: the range filter (--max-range) needs the ego \
             vehicle's pose (`probmot import nuscenes` writes it when ego_pose.json is present)"
        );
    }
    if samples.is_empty() {
        bail!("{file}: topic {topic} has no messages");
    }
    Ok(EgoPositions {
        samples: samples.into_iter().collect(),
    })
}

/// Boxes removed by the range filter.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RangeRemoved {
    /// Ground-truth boxes removed.
    pub truth: u64,
    /// Track boxes removed.
    pub tracks: u64,
}

/// Removes the boxes of `scene` that lie out of range of the ego position at their frame's
/// stamp. A frame with boxes but no ego position (outside the pose channel's time range) is an
/// error naming the log.
pub fn apply_range_filter(
    scene: &mut Scene,
    filter: &RangeFilter,
    ego: &EgoPositions,
) -> Result<RangeRemoved> {
    let mut removed = RangeRemoved::default();
    for (stamp, truth, tracks) in &mut scene.frames {
        if truth.is_empty() && tracks.is_empty() {
            continue;
        }
        let Some(p) = ego.at(*stamp) else {
            bail!(
                "{}: no ego pose at stamp {stamp} ns (the pose channel covers {}..{} ns)",
                scene.name,
                ego.samples.first().map_or(0, |s| s.0),
                ego.samples.last().map_or(0, |s| s.0)
            );
        };
        let keep = |b: &LabelledBox| filter.keeps(&b.label, b.center[0] - p[0], b.center[1] - p[1]);
        let (n_truth, n_tracks) = (truth.len(), tracks.len());
        truth.retain(keep);
        tracks.retain(keep);
        removed.truth += (n_truth - truth.len()) as u64;
        removed.tracks += (n_tracks - tracks.len()) as u64;
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(label: &str, x: f64, y: f64) -> LabelledBox {
        LabelledBox {
            id: 1,
            label: label.into(),
            center: [x, y, 0.0],
            size: [4.0, 2.0, 1.5],
            score: 0.5,
            ..Default::default()
        }
    }

    #[test]
    fn parses_the_three_forms_and_refuses_bad_ones() {
        let n = RangeFilter::parse("nuscenes").unwrap();
        assert_eq!(n.range_of("pedestrian"), Some(40.0));
        assert_eq!(n.range_of("car"), Some(50.0));
        assert_eq!(n.range_of("dog"), None);
        assert_eq!(
            RangeFilter::parse("30").unwrap().range_of("dog"),
            Some(30.0)
        );
        let c = RangeFilter::parse("car=60, *=20").unwrap();
        assert_eq!(
            (c.range_of("car"), c.range_of("bus")),
            (Some(60.0), Some(20.0))
        );
        assert_eq!(RangeFilter::parse("car=60").unwrap().range_of("bus"), None);
        for bad in ["-3", "car=", "car=x", "=5", "car=1,car=2", "car=inf", "abc"] {
            assert!(RangeFilter::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn keeps_strictly_inside_on_the_ground_plane() {
        let f = RangeFilter::nuscenes();
        assert!(f.keeps("car", 30.0, 39.9));
        assert!(!f.keeps("car", 30.0, 40.0)); // exactly 50 m: removed, as `ego_dist < max_dist`
        assert!(!f.keeps("pedestrian", 40.0, 0.0));
        assert!(f.keeps("pedestrian", 0.0, -39.99));
    }

    #[test]
    fn ego_position_is_exact_or_interpolated_and_none_outside() {
        let e = EgoPositions {
            samples: vec![(10, [0.0, 0.0, 0.0]), (20, [10.0, -2.0, 1.0])],
        };
        assert_eq!(e.at(10), Some([0.0, 0.0, 0.0]));
        assert_eq!(e.at(20), Some([10.0, -2.0, 1.0]));
        assert_eq!(e.at(15), Some([5.0, -1.0, 0.5]));
        assert_eq!(e.at(9), None);
        assert_eq!(e.at(21), None);
    }

    #[test]
    fn filter_uses_the_pose_of_each_frame() {
        let mut scene = Scene {
            name: "log.mcap".into(),
            frames: vec![
                (10, vec![b("car", 45.0, 0.0)], vec![b("car", 55.0, 0.0)]),
                (
                    20,
                    vec![b("car", 45.0, 0.0)],
                    vec![b("pedestrian", 100.0, 0.0)],
                ),
            ],
        };
        let ego = EgoPositions {
            samples: vec![(10, [0.0, 0.0, 0.0]), (20, [70.0, 0.0, 0.0])],
        };
        let removed = apply_range_filter(&mut scene, &RangeFilter::nuscenes(), &ego).unwrap();
        // Frame 10: GT at 45 m kept, track at 55 m removed. Frame 20 (ego at x = 70): GT at
        // 25 m kept, pedestrian at 30 m kept.
        assert_eq!(
            removed,
            RangeRemoved {
                truth: 0,
                tracks: 1
            }
        );
        assert_eq!(scene.frames[0].2.len(), 0);
        assert_eq!(scene.frames[1].2.len(), 1);
        let late = EgoPositions {
            samples: vec![(15, [0.0; 3]), (20, [0.0; 3])],
        };
        let err = apply_range_filter(&mut scene, &RangeFilter::nuscenes(), &late).unwrap_err();
        assert!(
            err.to_string()
                .contains("log.mcap: no ego pose at stamp 10"),
            "{err}"
        );
    }
}
