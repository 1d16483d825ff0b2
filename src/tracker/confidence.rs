//! Track confidence: the refined score (raised on a match, decayed while coasting), the score a
//! track reports, and the life cycle by confidence. See [`super::levers`].

use super::levers::{Levers, ScoreMode};

/// Confidence state of one track.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Confidence {
    /// Refined score.
    pub refined: f64,
    /// Sum of the matched detections' scores.
    pub sum: f64,
    /// Number of matched detections.
    pub n: u32,
}

impl Confidence {
    /// The state of a track born from a detection with score `s`.
    pub fn born(s: f64) -> Self {
        Confidence {
            refined: s,
            sum: s,
            n: 1,
        }
    }

    /// A match with a detection of score `s`.
    pub fn on_match(&mut self, s: f64, l: &Levers) {
        self.refined += l.blend * (s - self.refined) + l.boost;
        self.sum += s;
        self.n += 1;
    }

    /// A frame without a match.
    pub fn on_coast(&mut self, l: &Levers) {
        self.refined -= l.decay;
    }

    /// The score to report, given the last matched detection's score.
    pub fn reported(&self, last: f64, l: &Levers) -> f64 {
        match l.score {
            ScoreMode::Last => last,
            ScoreMode::Mean => self.sum / self.n.max(1) as f64,
            ScoreMode::Refined => self.refined,
        }
    }

    /// Whether a track that is past its `max_age` stays alive (life cycle by confidence).
    pub fn keeps_alive(&self, l: &Levers) -> bool {
        l.keep_score.is_some_and(|k| self.refined >= k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn levers(score: ScoreMode, blend: f64, boost: f64, decay: f64) -> Levers {
        Levers {
            score,
            blend,
            boost,
            decay,
            ..Levers::default()
        }
    }

    #[test]
    fn modes_report_what_they_say() {
        let l = levers(ScoreMode::Last, 0.5, 1.0, 0.25);
        let mut c = Confidence::born(2.0);
        c.on_match(4.0, &l);
        // refined: 2 + 0.5 * (4 - 2) + 1 = 4; mean 3.
        assert_eq!(c.reported(4.0, &l), 4.0);
        assert_eq!(
            c.reported(4.0, &levers(ScoreMode::Mean, 0.5, 1.0, 0.25)),
            3.0
        );
        assert_eq!(c.refined, 4.0);
        c.on_coast(&l);
        assert_eq!(c.refined, 3.75);
        assert_eq!(
            c.reported(4.0, &levers(ScoreMode::Refined, 0.5, 1.0, 0.25)),
            3.75
        );
    }

    #[test]
    fn keep_alive_only_with_a_threshold() {
        let mut l = levers(ScoreMode::Refined, 1.0, 0.0, 1.0);
        let mut c = Confidence::born(2.5);
        assert!(!c.keeps_alive(&l));
        l.keep_score = Some(1.0);
        assert!(c.keeps_alive(&l));
        c.on_coast(&l);
        assert!(c.keeps_alive(&l));
        c.on_coast(&l);
        assert!(!c.keeps_alive(&l));
    }

    proptest! {
        /// With the default levers the refined score follows the last detection exactly, so
        /// the paper's score is reproduced.
        #[test]
        fn default_refined_is_last(scores in prop::collection::vec(-10.0f64..10.0, 1..20)) {
            let l = Levers::default();
            let mut c = Confidence::born(scores[0]);
            for s in &scores[1..] {
                c.on_match(*s, &l);
            }
            prop_assert!((c.refined - scores[scores.len() - 1]).abs() < 1e-9);
        }

        /// A match never lowers the refined score below the blend of old and new, and coasting
        /// never raises it.
        #[test]
        fn match_raises_coast_lowers(r in -5.0f64..5.0, s in -5.0f64..5.0, blend in 0.0f64..1.0,
                                     boost in 0.0f64..2.0, decay in 0.0f64..2.0) {
            let l = levers(ScoreMode::Refined, blend, boost, decay);
            let mut c = Confidence::born(r);
            c.on_match(s, &l);
            prop_assert!(c.refined >= r.min(s) - 1e-12);
            let before = c.refined;
            c.on_coast(&l);
            prop_assert!(c.refined <= before);
        }
    }
}
