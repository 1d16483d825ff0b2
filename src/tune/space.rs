//! The per-class search space: dimensions with a handful of candidate values each. Candidate 0
//! of every dimension keeps the base config's value, so the search starts at the base config.

use crate::tracker::levers::ScoreMode;
use crate::tracker::{ClassConfig, DistanceKind, MatcherKind};

/// One candidate value of a dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
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
    /// Constant yaw rate in the state.
    AngularVelocity(bool),
    /// Factor on the fitted process noise `Q`.
    QFactor(f64),
    /// Factor on the fitted measurement noise `R`.
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
    /// Life cycle by confidence: keep score.
    KeepScore(Option<f64>),
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

/// The search space of one class.
pub fn dims(stats: Option<ScoreStats>) -> Vec<Dim> {
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
        Dim {
            name: "angular_velocity",
            values: vec![Keep, AngularVelocity(true), AngularVelocity(false)],
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
    ];
    if let Some(s) = stats {
        let q = |i: usize| Some(s.q[i]);
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
                KeepScore(None),
                KeepScore(q(4)),
                KeepScore(q(5)),
                KeepScore(q(6)),
            ],
        });
    }
    d
}

/// Applies a candidate to `cc`; `base` holds the fitted noise the factors apply to.
pub fn apply(cc: &mut ClassConfig, base: &ClassConfig, v: Value) {
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
        AngularVelocity(b) => cc.angular_velocity = b,
        QFactor(f) => cc.q = base.q.map(|x| x * f),
        RFactor(f) => cc.r = base.r.map(|x| x * f),
        ScoreFloor(f) => cc.score_floor = f,
        BirthScore(b) => l.birth_score = b,
        Nms(n) => l.nms_iou = n,
        Score(m) => l.score = m,
        Blend(b) => l.blend = b,
        Boost(b) => l.boost = b,
        Decay(d) => l.decay = d,
        KeepScore(k) => l.keep_score = k,
    }
}

/// The class config at a point of the space (one candidate index per dimension).
pub fn at(base: &ClassConfig, dims: &[Dim], point: &[usize]) -> ClassConfig {
    let mut cc = base.clone();
    for (d, &i) in dims.iter().zip(point) {
        apply(&mut cc, base, d.values[i]);
    }
    cc
}

/// Readable form of a value (for the search log).
pub fn describe(v: Value) -> String {
    match v {
        Value::Keep => "base".into(),
        other => format!("{other:?}"),
    }
}
