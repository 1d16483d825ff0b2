//! The per-class search space: dimensions with a handful of candidate values each. Candidate 0
//! of every dimension keeps the base config's value, so the search starts at the base config.

use crate::tracker::levers::{Coast, Motion, ScoreMode};
use crate::tracker::{ClassConfig, DistanceKind, MatcherKind};

/// One candidate value of a dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
// The noise variant is large, but a search holds only about a hundred values, built once.
#[allow(clippy::large_enum_variant)]
pub enum Value {
    /// Keep the base config's value.
    Keep,
    /// Distance and gate.
    Gate(DistanceKind, f64),
    /// Matcher.
    Matcher(MatcherKind),
    /// `min_hits`.
    MinHits(u32),
    /// `max_age`.
    MaxAge(u32),
    /// Which coasted frames are reported (offline).
    Coast(Coast),
    /// Report a confirmed track's frames from its birth (offline).
    Backfill(bool),
    /// Constant yaw rate in the state.
    AngularVelocity(bool),
    /// Motion model; the coordinated turn also turns the yaw rate on (it needs it).
    Motion(Motion),
    /// The base config's own noise (`q`, `r`, `p0`) instead of the fitted one.
    Noise([f64; 11], [f64; 7], [f64; 11]),
    /// Factor on the process noise `Q` (fitted, or the base's after [`Value::Noise`]).
    QFactor(f64),
    /// Factor on the measurement noise `R`.
    RFactor(f64),
    /// Score floor (a quantile of the training detections' scores).
    ScoreFloor(Option<f64>),
    /// Birth score of the two-stage association.
    BirthScore(Option<f64>),
    /// NMS IoU.
    Nms(Option<f64>),
    /// Reported score.
    Score(ScoreMode),
    /// Refinement blend.
    Blend(f64),
    /// Refinement boost.
    Boost(f64),
    /// Refinement decay while coasting.
    Decay(f64),
    /// Two-point initialization speed, m/s.
    TwoPoint(Option<f64>),
    /// Life cycle by confidence: keep score, and the decay it brings when the class has none
    /// (the life cycle needs one; without it the candidate could never be valid on its own).
    KeepScore(Option<f64>, f64),
}

/// A dimension: its name and candidates (the first is [`Value::Keep`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Dim {
    /// Name for reports.
    pub name: &'static str,
    /// Candidate values.
    pub values: Vec<Value>,
}

/// Score statistics of one class's training detections, which place the score thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoreStats {
    /// Quantiles 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9.
    pub q: [f64; 7],
    /// Standard deviation.
    pub std: f64,
}

impl ScoreStats {
    /// Statistics of `scores` (`None` without any).
    pub fn of(mut scores: Vec<f64>) -> Option<ScoreStats> {
        if scores.is_empty() {
            return None;
        }
        scores.sort_by(f64::total_cmp);
        let n = scores.len();
        let at = |p: f64| scores[((p * (n - 1) as f64).round() as usize).min(n - 1)];
        let mean = scores.iter().sum::<f64>() / n as f64;
        let var = scores.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / n as f64;
        Some(ScoreStats {
            q: [0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9].map(at),
            std: var.sqrt().max(1e-6),
        })
    }
}

/// Names of every search dimension, in search order (what `probmot tune --search` accepts).
pub const DIM_NAMES: [&str; 20] = [
    "noise",
    "gate",
    "matcher",
    "min_hits",
    "max_age",
    "coast",
    "backfill",
    "angular_velocity",
    "motion",
    "q_factor",
    "r_factor",
    "nms_iou",
    "score",
    "blend",
    "score_floor",
    "birth_score",
    "boost",
    "decay",
    "keep_score",
    TWO_POINT_NAME,
];

/// Name of the two-point initialization dimension: searched only when `--search` names it
/// ([`searches_two_point`]).
pub const TWO_POINT_NAME: &str = "two_point_speed";

/// Whether the class search includes [`TWO_POINT_NAME`]: only when `only` names it. On simulated
/// 2 Hz drives the default search reached the same held-out scores without it (the fitted or
/// own noise and the gate already follow fast objects there, docs/tune.md), so it costs the
/// default search evaluations for nothing; on its own it is the smallest change that keeps a
/// fast object in one track.
pub fn searches_two_point(only: &[String]) -> bool {
    only.iter().any(|n| n == TWO_POINT_NAME)
}

/// Two-point initialization speeds, m/s: walking, cycling, town and road speeds.
fn two_point_dim() -> Dim {
    use Value::{Keep, TwoPoint};
    Dim {
        name: TWO_POINT_NAME,
        values: vec![
            Keep,
            TwoPoint(None),
            TwoPoint(Some(5.0)),
            TwoPoint(Some(10.0)),
            TwoPoint(Some(20.0)),
            TwoPoint(Some(40.0)),
        ],
    }
}

/// Checks that every name of `only` is a dimension ([`DIM_NAMES`]).
pub fn check_names(only: &[String]) -> Result<(), String> {
    match only.iter().find(|n| !DIM_NAMES.contains(&n.as_str())) {
        Some(n) => Err(format!(
            "unknown search option '{n}' (options: {})",
            DIM_NAMES.join(", ")
        )),
        None => Ok(()),
    }
}

/// `dims` without the dimensions not named in `only` (empty `only`: all of them).
pub fn restrict(dims: Vec<Dim>, only: &[String]) -> Vec<Dim> {
    dims.into_iter()
        .filter(|d| only.is_empty() || only.iter().any(|n| n == d.name))
        .collect()
}

/// The search space of one class: the choice between the fitted noise and the base config's own
/// (`own`, when it differs), the class-agnostic dimensions, the score thresholds and
/// refinement steps placed by the class's detection scores (none without scores), then with
/// `two_point` the two-point initialization speeds ([`searches_two_point`]).
pub fn dims(
    stats: Option<ScoreStats>,
    fitted: &ClassConfig,
    own: Option<&ClassConfig>,
    two_point: bool,
) -> Vec<Dim> {
    let mut d = Vec::new();
    if let Some(o) = own.filter(|o| (o.q, o.r, o.p0) != (fitted.q, fitted.r, fitted.p0)) {
        d.push(Dim {
            name: "noise",
            values: vec![Value::Keep, Value::Noise(o.q, o.r, o.p0)],
        });
    }
    d.extend(shared_dims());
    if let Some(s) = stats {
        d.extend(score_dims(s));
    }
    if two_point {
        d.push(two_point_dim());
    }
    d
}

/// The dimensions whose candidates mean the same for every class (gates in units of the fitted
/// noise, factors on it, counts, modes), which the shared stage applies to all classes at once.
pub fn shared_dims() -> Vec<Dim> {
    use DistanceKind::*;
    use Value::*;
    let mut gate = vec![Keep];
    gate.extend([3.0, 5.0, 7.0, 9.0, 11.0, 13.0, 15.0, 20.0].map(|t| Gate(Mahalanobis, t)));
    gate.extend([-0.6, -0.4, -0.2, 0.0, 0.2].map(|t| Gate(Giou3d, t)));
    gate.extend([0.01, 0.1, 0.25].map(|t| Gate(Iou3d, t)));
    gate.extend([1.0, 2.0, 4.0].map(|t| Gate(Center, t)));
    let mut d = vec![
        Dim {
            name: "gate",
            values: gate,
        },
        Dim {
            name: "matcher",
            values: vec![
                Keep,
                Matcher(MatcherKind::Greedy),
                Matcher(MatcherKind::Hungarian),
            ],
        },
        Dim {
            name: "min_hits",
            values: vec![
                Keep,
                MinHits(1),
                MinHits(2),
                MinHits(3),
                MinHits(4),
                MinHits(5),
            ],
        },
        Dim {
            name: "max_age",
            values: [1, 2, 3, 4, 6, 8, 12, 16].map(MaxAge).into_iter().fold(
                vec![Keep],
                |mut v, x| {
                    v.push(x);
                    v
                },
            ),
        },
    ];
    d.extend(reporting_dims());
    d.extend([
        Dim {
            name: "angular_velocity",
            values: vec![Keep, AngularVelocity(true), AngularVelocity(false)],
        },
        // After angular_velocity: `ctrv` overrides a `false` there.
        Dim {
            name: "motion",
            values: vec![
                Keep,
                Value::Motion(crate::tracker::levers::Motion::Cv),
                Value::Motion(crate::tracker::levers::Motion::Ctrv),
            ],
        },
        Dim {
            name: "q_factor",
            values: vec![
                Keep,
                QFactor(0.1),
                QFactor(0.3),
                QFactor(3.0),
                QFactor(10.0),
                QFactor(30.0),
            ],
        },
        Dim {
            name: "r_factor",
            values: vec![Keep, RFactor(0.3), RFactor(3.0), RFactor(10.0)],
        },
        Dim {
            name: "nms_iou",
            values: vec![
                Keep,
                Nms(None),
                Nms(Some(0.05)),
                Nms(Some(0.1)),
                Nms(Some(0.3)),
                Nms(Some(0.5)),
            ],
        },
        Dim {
            name: "score",
            values: vec![
                Keep,
                Score(ScoreMode::Last),
                Score(ScoreMode::Mean),
                Score(ScoreMode::Refined),
            ],
        },
        Dim {
            name: "blend",
            values: vec![Keep, Blend(0.1), Blend(0.3), Blend(0.5), Blend(1.0)],
        },
    ]);
    d
}

/// Names of the reporting dimensions (`coast`, `backfill`).
pub const REPORTING_NAMES: [&str; 2] = ["coast", "backfill"];

/// Which frames a track reports (offline options, see [`crate::tracker::lookback`]).
fn reporting_dims() -> [Dim; 2] {
    use crate::tracker::levers::Coast;
    use Value::{Backfill, Keep};
    [
        Dim {
            name: REPORTING_NAMES[0],
            values: vec![
                Keep,
                Value::Coast(Coast::All),
                Value::Coast(Coast::Gaps),
                Value::Coast(Coast::None),
            ],
        },
        Dim {
            name: REPORTING_NAMES[1],
            values: vec![Keep, Backfill(false), Backfill(true)],
        },
    ]
}

/// The dimensions placed by one class's detection scores: thresholds at quantiles, refinement
/// steps in units of the scores' standard deviation.
fn score_dims(s: ScoreStats) -> Vec<Dim> {
    use Value::*;
    let q = |i: usize| Some(s.q[i]);
    let mut d = Vec::new();
    d.push(Dim {
        name: "score_floor",
        values: vec![
            Keep,
            ScoreFloor(None),
            ScoreFloor(q(0)),
            ScoreFloor(q(1)),
            ScoreFloor(q(2)),
            ScoreFloor(q(3)),
        ],
    });
    d.push(Dim {
        name: "birth_score",
        values: vec![
            Keep,
            BirthScore(None),
            BirthScore(q(1)),
            BirthScore(q(2)),
            BirthScore(q(3)),
            BirthScore(q(4)),
        ],
    });
    let sd = s.std;
    d.push(Dim {
        name: "boost",
        values: vec![
            Keep,
            Boost(0.0),
            Boost(0.02 * sd),
            Boost(0.1 * sd),
            Boost(0.3 * sd),
            Boost(1.0 * sd),
        ],
    });
    d.push(Dim {
        name: "decay",
        values: vec![
            Keep,
            Decay(0.0),
            Decay(0.05 * sd),
            Decay(0.2 * sd),
            Decay(0.5 * sd),
            Decay(1.0 * sd),
        ],
    });
    d.push(Dim {
        name: "keep_score",
        values: vec![
            Keep,
            KeepScore(None, 0.0),
            KeepScore(q(4), 0.2 * sd),
            KeepScore(q(5), 0.2 * sd),
            KeepScore(q(6), 0.2 * sd),
        ],
    });
    d
}

/// Applies a candidate to `cc` (the factors apply to the noise `cc` holds, so the noise dimension
/// comes first).
pub fn apply(cc: &mut ClassConfig, v: Value) {
    use Value::*;
    let l = &mut cc.levers;
    match v {
        Keep => {}
        Gate(d, t) => {
            cc.distance = d;
            cc.threshold = t;
        }
        Matcher(m) => cc.matcher = m,
        MinHits(n) => cc.min_hits = n,
        MaxAge(n) => cc.max_age = n,
        Value::Coast(c) => l.coast = c,
        Backfill(b) => l.backfill = b,
        AngularVelocity(b) => cc.angular_velocity = b,
        Motion(m) => {
            l.motion = m;
            cc.angular_velocity |= m == crate::tracker::levers::Motion::Ctrv;
        }
        Noise(q, r, p0) => (cc.q, cc.r, cc.p0) = (q, r, p0),
        QFactor(f) => cc.q = cc.q.map(|x| x * f),
        RFactor(f) => cc.r = cc.r.map(|x| x * f),
        ScoreFloor(f) => cc.score_floor = f,
        BirthScore(b) => l.birth_score = b,
        Nms(n) => l.nms_iou = n,
        TwoPoint(v) => l.two_point_speed = v,
        Score(m) => l.score = m,
        Blend(b) => l.blend = b,
        Boost(b) => l.boost = b,
        Decay(d) => l.decay = d,
        KeepScore(k, decay) => {
            l.keep_score = k;
            if k.is_some() && l.decay == 0.0 {
                l.decay = decay;
            }
        }
    }
}

/// The class config at a point of the space (one candidate index per dimension).
pub fn at(base: &ClassConfig, dims: &[Dim], point: &[usize]) -> ClassConfig {
    let mut cc = base.clone();
    for (d, &i) in dims.iter().zip(point) {
        apply(&mut cc, d.values[i]);
    }
    cc
}

/// A key of what a class config tracks like: the refinement steps are dropped when nothing reads
/// the refined score (reported score not `refined`, no `keep_score`), so candidates that cannot
/// change the tracks share one key and are scored once.
pub fn key(cc: &ClassConfig) -> String {
    let mut c = cc.clone();
    let l = &mut c.levers;
    if l.score != ScoreMode::Refined && l.keep_score.is_none() {
        let off = crate::tracker::levers::Levers::default();
        (l.blend, l.boost, l.decay) = (off.blend, off.boost, off.decay);
    }
    serde_json::to_string(&c).expect("config serializes")
}

/// Readable form of a value (for the search log).
pub fn describe(v: Value) -> String {
    match v {
        Value::Keep => "base".into(),
        Value::Noise(..) => "the base config's own noise".into(),
        other => format!("{other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::TrackerConfig;

    #[test]
    fn key_ignores_refinement_only_when_nothing_reads_it() {
        let cc = TrackerConfig::preset("nuscenes-chiu2019").unwrap().classes["car"].clone();
        let mut b = cc.clone();
        b.levers.blend = 0.3;
        b.levers.decay = 0.1;
        assert_eq!(key(&cc), key(&b));
        let (mut r1, mut r2) = (cc.clone(), b.clone());
        r1.levers.score = ScoreMode::Refined;
        r2.levers.score = ScoreMode::Refined;
        assert_ne!(key(&r1), key(&r2));
        let mut k = b.clone();
        k.levers.keep_score = Some(0.5);
        let mut k0 = cc.clone();
        k0.levers.keep_score = Some(0.5);
        assert_ne!(key(&k), key(&k0));
        let mut g = cc.clone();
        g.threshold += 1.0;
        assert_ne!(key(&cc), key(&g));
    }

    /// The coordinated turn is a per-class candidate and always yields a valid config, also
    /// where the point turns the yaw rate off.
    #[test]
    fn ctrv_candidate_turns_the_yaw_rate_on() {
        let cc = TrackerConfig::preset("ab3dmot-kitti").unwrap().classes["car"].clone();
        let d = dims(None, &cc, None, false);
        let mi = d.iter().position(|d| d.name == "motion").unwrap();
        let ai = d.iter().position(|d| d.name == "angular_velocity").unwrap();
        assert!(ai < mi);
        let ct = d[mi]
            .values
            .iter()
            .position(|v| *v == Value::Motion(Motion::Ctrv))
            .unwrap();
        let off = d[ai]
            .values
            .iter()
            .position(|v| *v == Value::AngularVelocity(false))
            .unwrap();
        let mut p = vec![0; d.len()];
        p[ai] = off;
        p[mi] = ct;
        let c = at(&cc, &d, &p);
        assert_eq!(c.levers.motion, Motion::Ctrv);
        assert!(c.angular_velocity);
        c.validate().unwrap();
    }

    /// A keep-score candidate is valid from a class without decay (it brings one) and keeps
    /// a decay the search chose before.
    #[test]
    fn keep_score_candidates_bring_their_decay() {
        let cc = TrackerConfig::preset("ab3dmot-kitti").unwrap().classes["car"].clone();
        let stats = ScoreStats::of((0..100).map(|i| i as f64 / 100.0).collect());
        let d = dims(stats, &cc, None, false);
        let ki = d.iter().position(|d| d.name == "keep_score").unwrap();
        let di = d.iter().position(|d| d.name == "decay").unwrap();
        let mut p = vec![0; d.len()];
        p[ki] = 2;
        let c = at(&cc, &d, &p);
        assert!(c.levers.keep_score.is_some() && c.levers.decay > 0.0);
        c.validate().unwrap();
        p[di] = d[di].values.len() - 1;
        let chosen = at(&cc, &d, &p);
        let Value::Decay(want) = d[di].values[p[di]] else {
            panic!("decay candidates are Decay values")
        };
        assert_eq!(chosen.levers.decay, want);
    }

    /// The names list is the space, in order, and a restriction keeps only the named ones.
    #[test]
    fn dimension_names_are_the_space_and_restrict_filters() {
        let own = TrackerConfig::preset("nuscenes-chiu2019").unwrap().classes["car"].clone();
        let mut fitted = own.clone();
        fitted.q = own.q.map(|x| 2.0 * x);
        let stats = ScoreStats::of(vec![0.1, 0.5, 0.9]);
        let d = dims(stats, &fitted, Some(&own), true);
        let names: Vec<&str> = d.iter().map(|d| d.name).collect();
        assert_eq!(names, DIM_NAMES);
        let only = vec!["nms_iou".to_string(), "gate".to_string()];
        let r: Vec<&str> = restrict(d, &only).iter().map(|d| d.name).collect();
        assert_eq!(r, ["gate", "nms_iou"]);
        assert!(check_names(&only).is_ok());
        let err = check_names(&["nsm".to_string()]).unwrap_err();
        assert!(err.contains("'nsm'") && err.contains("keep_score"), "{err}");
    }

    /// Two-point initialization is searched only when named, and its candidates set the lever.
    #[test]
    fn two_point_is_searched_on_request() {
        let named = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert!(!searches_two_point(&[]));
        assert!(!searches_two_point(&named(&["gate", "nms_iou"])));
        assert!(searches_two_point(&named(&["gate", "two_point_speed"])));
        let cc = TrackerConfig::preset("nuscenes-chiu2019").unwrap().classes["car"].clone();
        assert!(dims(None, &cc, None, false)
            .iter()
            .all(|d| d.name != TWO_POINT_NAME));
        let d = dims(None, &cc, None, true);
        let last = d.last().unwrap();
        assert_eq!(last.name, TWO_POINT_NAME);
        let mut p = vec![0; d.len()];
        assert_eq!(at(&cc, &d, &p).levers.two_point_speed, None);
        p[d.len() - 1] = last.values.len() - 1;
        let fast = at(&cc, &d, &p);
        assert_eq!(fast.levers.two_point_speed, Some(40.0));
        fast.validate().unwrap();
    }

    #[test]
    fn noise_dimension_comes_first_and_factors_scale_the_chosen_noise() {
        let own = TrackerConfig::preset("nuscenes-chiu2019").unwrap().classes["car"].clone();
        let mut fitted = own.clone();
        fitted.q = own.q.map(|x| 2.0 * x);
        let d = dims(None, &fitted, Some(&own), false);
        assert_eq!(d[0].name, "noise");
        assert!(dims(None, &own, Some(&own), false)
            .iter()
            .all(|d| d.name != "noise"));
        let qi = d.iter().position(|d| d.name == "q_factor").unwrap();
        let fi = d[qi]
            .values
            .iter()
            .position(|v| *v == Value::QFactor(3.0))
            .unwrap();
        let mut p = vec![0; d.len()];
        p[0] = 1;
        p[qi] = fi;
        assert_eq!(at(&fitted, &d, &p).q, own.q.map(|x| 3.0 * x));
        p[0] = 0;
        assert_eq!(at(&fitted, &d, &p).q, fitted.q.map(|x| 3.0 * x));
    }
}
