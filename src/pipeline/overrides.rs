//! The tracker configuration a run uses: a config file or a preset, then the ablation overrides
//! (the rows of the paper's Table 1) and the tracker-wide overrides applied to every class.
//! `probmot track` and `probmot config` take these from flags; the rules live here.

use std::path::Path;

use anyhow::{Context, Result};

use super::per_class::PerClass;
use crate::tracker::config::ab3dmot_covariances;
use crate::tracker::ctrv::Motion;
use crate::tracker::levers::Coast;
use crate::tracker::{ClassConfig, DistanceKind, MatcherKind, Preset, TrackerConfig};

/// Overrides applied to every class of a configuration; `None`/`false` leaves a setting as it
/// is.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// Distance of every class. A class whose distance changes gets that distance's usual gate
    /// ([`default_threshold`]) unless `threshold` is given too.
    pub distance: Option<DistanceKind>,
    /// Gate of every class (max distance, or min IoU for IoU kinds).
    pub threshold: Option<f64>,
    /// Matcher of every class.
    pub matcher: Option<MatcherKind>,
    /// Turn off the angular velocity in the motion model.
    pub no_angular_velocity: bool,
    /// Use AB3DMOT's hand-set covariances (the paper's "default covariance" ablation).
    pub default_covariance: bool,
    /// Nominal frame period, seconds.
    pub dt_nominal: Option<f64>,
    /// min_hits of every class.
    pub min_hits: Option<u32>,
    /// max_age of every class.
    pub max_age: Option<u32>,
    /// Score floor of every class.
    pub score_floor: Option<f64>,
    /// Motion model of every class (`levers.motion`); `Ctrv` also turns the yaw rate on, which
    /// the coordinated turn needs.
    pub motion: Option<Motion>,
    /// Non-maximum suppression IoU of every class (`levers.nms_iou`): duplicates are a property
    /// of the detector, so one value for all classes is a sensible first try.
    pub nms_iou: Option<f64>,
    /// Two-stage birth score of every class (`levers.birth_score`), on the detector's scale.
    pub birth_score: Option<f64>,
    /// Coasted frames every class reports (`levers.coast`).
    pub coast: Option<Coast>,
    /// Backfill of every class (`levers.backfill`: report a confirmed track from its birth).
    pub backfill: Option<bool>,
    /// Two-point initialization speed (`levers.two_point_speed`, m/s): one for every class, or
    /// per class (fast cars, not pedestrians).
    pub two_point_speed: Option<PerClass>,
}

impl Overrides {
    /// Applies the overrides to `cfg` and validates the result.
    pub fn apply(&self, cfg: &mut TrackerConfig) -> Result<()> {
        if self.no_angular_velocity && self.motion == Some(Motion::Ctrv) {
            anyhow::bail!("the ctrv motion model needs the yaw rate: drop --no-angular-velocity");
        }
        if let Some(d) = self.dt_nominal {
            cfg.dt_nominal = d;
        }
        let (p0, q, r) = ab3dmot_covariances();
        cfg.for_each_class(|c| {
            if let Some(d) = self.distance {
                if d != c.distance && self.threshold.is_none() {
                    // A gate of another distance means nothing: use that distance's usual gate.
                    c.threshold = default_threshold(d);
                }
                c.distance = d;
            }
            if let Some(t) = self.threshold {
                c.threshold = t;
            }
            if let Some(m) = self.matcher {
                c.matcher = m;
            }
            if self.no_angular_velocity {
                c.angular_velocity = false;
            }
            if self.default_covariance {
                c.p0 = p0;
                c.q = q;
                c.r = r;
            }
            if let Some(h) = self.min_hits {
                c.min_hits = h;
            }
            if let Some(a) = self.max_age {
                c.max_age = a;
            }
            if let Some(f) = self.score_floor {
                c.score_floor = Some(f);
            }
            if let Some(m) = self.motion {
                c.levers.motion = m;
                if m == Motion::Ctrv {
                    c.angular_velocity = true;
                }
            }
            if let Some(v) = self.nms_iou {
                c.levers.nms_iou = Some(v);
            }
            if let Some(v) = self.birth_score {
                c.levers.birth_score = Some(v);
            }
            if let Some(v) = self.coast {
                c.levers.coast = v;
            }
            if let Some(b) = self.backfill {
                c.levers.backfill = b;
            }
        });
        if let Some(speeds) = &self.two_point_speed {
            set_per_class(cfg, speeds, "--two-point-speed", |c, v| {
                c.levers.two_point_speed = Some(v)
            })?;
        }
        cfg.validate()?;
        Ok(())
    }
}

/// Sets a per-class value: each named class's entry (which must exist) and, with a value for
/// the classes not named, every other entry and the default one.
fn set_per_class(
    cfg: &mut TrackerConfig,
    values: &PerClass,
    flag: &str,
    set: impl Fn(&mut ClassConfig, f64),
) -> Result<()> {
    if let Some(missing) = values.named.keys().find(|c| !cfg.classes.contains_key(*c)) {
        let have: Vec<&str> = cfg.classes.keys().map(String::as_str).collect();
        if have.is_empty() {
            anyhow::bail!(
                "{flag}: the config has one entry for every class and none for {missing}: give \
                 one value, or write per-class entries in a config file (`probmot config`)"
            );
        }
        anyhow::bail!(
            "{flag}: the config has no entry for class {missing} (its classes: {}; `*=` sets \
             the others and the default entry)",
            have.join(", ")
        );
    }
    for (label, c) in cfg.classes.iter_mut() {
        if let Some(v) = values.of(label) {
            set(c, v);
        }
    }
    if let (Some(d), Some(v)) = (cfg.default.as_mut(), values.other) {
        set(d, v);
    }
    Ok(())
}

/// The base configuration: the config file (JSON, as `probmot config` prints it) when given,
/// else the preset (default [`Preset::NuscenesChiu2019`]).
pub fn base_config(config: Option<&Path>, preset: Option<Preset>) -> Result<TrackerConfig> {
    match config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read config {}", path.display()))?;
            TrackerConfig::from_json(&text).with_context(|| format!("config {}", path.display()))
        }
        None => Ok(preset.unwrap_or(Preset::NuscenesChiu2019).config()?),
    }
}

/// The usual gate of a distance: 11 for Mahalanobis (the paper), 0.1 IoU and -0.5 GIoU
/// (AB3DMOT), 2 m for centre distances (the nuScenes matching radius; AB3DMOT's cyclist gate).
pub fn default_threshold(d: DistanceKind) -> f64 {
    match d {
        DistanceKind::Mahalanobis => 11.0,
        DistanceKind::Iou3d => 0.1,
        DistanceKind::Giou3d => -0.5,
        DistanceKind::Center | DistanceKind::Dist3d => 2.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn preset() -> TrackerConfig {
        base_config(None, None).unwrap()
    }

    fn classes(cfg: &mut TrackerConfig) -> Vec<crate::tracker::ClassConfig> {
        let mut v = Vec::new();
        cfg.for_each_class(|c| v.push(c.clone()));
        v
    }

    #[test]
    fn no_overrides_leave_the_preset_as_it_is() {
        let mut cfg = preset();
        Overrides::default().apply(&mut cfg).unwrap();
        assert_eq!(cfg.to_json(), preset().to_json());
    }

    #[test]
    fn a_new_distance_brings_its_usual_gate_unless_a_threshold_is_given() {
        let mut cfg = preset();
        let o = Overrides {
            distance: Some(DistanceKind::Iou3d),
            ..Default::default()
        };
        o.apply(&mut cfg).unwrap();
        for c in classes(&mut cfg) {
            assert_eq!(c.distance, DistanceKind::Iou3d);
            assert_eq!(c.threshold, 0.1);
        }
        let mut cfg = preset();
        let o = Overrides {
            distance: Some(DistanceKind::Center),
            threshold: Some(3.5),
            ..Default::default()
        };
        o.apply(&mut cfg).unwrap();
        assert!(classes(&mut cfg).iter().all(|c| c.threshold == 3.5));
    }

    #[test]
    fn the_same_distance_keeps_each_class_gate() {
        let mut cfg = preset();
        let before: Vec<f64> = classes(&mut cfg).iter().map(|c| c.threshold).collect();
        let o = Overrides {
            distance: Some(DistanceKind::Mahalanobis),
            ..Default::default()
        };
        o.apply(&mut cfg).unwrap();
        let after: Vec<f64> = classes(&mut cfg).iter().map(|c| c.threshold).collect();
        assert_eq!(before, after);
    }

    #[test]
    fn every_class_gets_the_tracker_wide_overrides() {
        let mut cfg = preset();
        let o = Overrides {
            matcher: Some(MatcherKind::Hungarian),
            no_angular_velocity: true,
            default_covariance: true,
            dt_nominal: Some(0.1),
            min_hits: Some(3),
            max_age: Some(7),
            score_floor: Some(0.25),
            ..Default::default()
        };
        o.apply(&mut cfg).unwrap();
        assert_eq!(cfg.dt_nominal, 0.1);
        let (p0, q, r) = ab3dmot_covariances();
        for c in classes(&mut cfg) {
            assert_eq!(c.matcher, MatcherKind::Hungarian);
            assert!(!c.angular_velocity);
            assert_eq!((c.p0, c.q, c.r), (p0, q, r));
            assert_eq!((c.min_hits, c.max_age), (3, 7));
            assert_eq!(c.score_floor, Some(0.25));
        }
    }

    #[test]
    fn the_lever_overrides_reach_every_class_and_ctrv_brings_the_yaw_rate() {
        let mut cfg = base_config(None, Some(Preset::Ab3dmotKitti)).unwrap();
        assert!(classes(&mut cfg).iter().any(|c| !c.angular_velocity));
        let o = Overrides {
            motion: Some(Motion::Ctrv),
            nms_iou: Some(0.1),
            birth_score: Some(0.5),
            coast: Some(Coast::Gaps),
            backfill: Some(true),
            two_point_speed: PerClass::parse("40", "m/s").ok(),
            ..Default::default()
        };
        o.apply(&mut cfg).unwrap();
        for c in classes(&mut cfg) {
            assert_eq!(c.levers.motion, Motion::Ctrv);
            assert!(c.angular_velocity);
            assert_eq!(c.levers.nms_iou, Some(0.1));
            assert_eq!(c.levers.birth_score, Some(0.5));
            assert_eq!(c.levers.coast, Coast::Gaps);
            assert!(c.levers.backfill);
            assert_eq!(c.levers.two_point_speed, Some(40.0));
        }
        let clash = Overrides {
            motion: Some(Motion::Ctrv),
            no_angular_velocity: true,
            ..Default::default()
        };
        let err = clash.apply(&mut preset()).unwrap_err();
        assert!(err.to_string().contains("--no-angular-velocity"), "{err}");
        let bad = Overrides {
            nms_iou: Some(1.5),
            ..Default::default()
        };
        assert!(bad.apply(&mut preset()).is_err());
    }

    /// `car=40,*=20` sets cars to 40 and every other entry (the default too) to 20; named
    /// classes alone leave the others as they are; a class the config has no entry for is
    /// refused with the classes it has.
    #[test]
    fn two_point_speed_per_class() {
        let speeds = |spec: &str| Overrides {
            two_point_speed: Some(PerClass::parse(spec, "m/s").unwrap()),
            ..Default::default()
        };
        let mut cfg = preset();
        speeds("car=40,*=20").apply(&mut cfg).unwrap();
        assert_eq!(cfg.classes["car"].levers.two_point_speed, Some(40.0));
        assert_eq!(cfg.classes["pedestrian"].levers.two_point_speed, Some(20.0));
        if let Some(d) = &cfg.default {
            assert_eq!(d.levers.two_point_speed, Some(20.0));
        }
        let mut cfg = preset();
        speeds("car=40,motorcycle=35").apply(&mut cfg).unwrap();
        assert_eq!(cfg.classes["motorcycle"].levers.two_point_speed, Some(35.0));
        assert_eq!(cfg.classes["pedestrian"].levers.two_point_speed, None);
        let mut one = base_config(None, Some(Preset::Ab3dmot2019)).unwrap();
        let err = speeds("car=40").apply(&mut one).unwrap_err().to_string();
        assert!(
            err.contains("one entry for every class and none for car"),
            "{err}"
        );
        let err = speeds("cars=40").apply(&mut preset()).unwrap_err();
        assert!(
            err.to_string().contains("no entry for class cars") && err.to_string().contains("car,"),
            "{err}"
        );
    }

    #[test]
    fn an_invalid_result_is_refused_and_a_missing_file_named() {
        let mut cfg = preset();
        let o = Overrides {
            dt_nominal: Some(-1.0),
            ..Default::default()
        };
        assert!(o.apply(&mut cfg).is_err());
        let err = base_config(Some(Path::new("/nonexistent/cfg.json")), None).unwrap_err();
        assert!(err.to_string().contains("/nonexistent/cfg.json"), "{err}");
    }
}
