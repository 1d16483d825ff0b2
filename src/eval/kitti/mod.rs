//! The KITTI 3D multi-object tracking metrics as the AB3DMOT evaluation (Weng et al. 2020,
//! `scripts/KITTI/evaluate.py`, 3D mode) computes them: sAMOTA, AMOTA and AMOTP over 40 recall
//! points, and the CLEAR MOT metrics (MOTA, MOTP, IDS, FRAG, ...) at the threshold with the
//! highest MOTA. The rules are summarised in `../shared/reference/evaluation-protocols.md`
//! (beside the repository); this is our own implementation of them, checked against numbers of
//! the reference evaluation in `tests/it/kitti_eval.rs` (see `tests/fixtures/kitti/README.md`).
//!
//! In short, per class and over all scenes:
//! - Rows (ground truth and tracks alike) are kept when a class string is a substring of the
//!   lower-cased KITTI type (the `kitti_type` attribute, else the label): Car evaluation keeps
//!   `car`, `van`, `dontcare`; Pedestrian keeps `pedestrian`, `person_sitting`, `dontcare`;
//!   any other class keeps itself and `dontcare`. Ground-truth DontCare rows become 2D
//!   don't-care regions; other ground-truth rows with KITTI id -1 are dropped.
//! - Per frame, ground truth and tracks are matched by the Munkres algorithm on `1 - IoU3D`,
//!   pairs with `1 - IoU3D > 1 - min_overlap` being forbidden.
//! - Ground truth with truncation > 0, occlusion > 2 or of the neighbouring class (Van for Car,
//!   Person_sitting for Pedestrian) is ignored: neither FN nor, when matched, counted against
//!   the track. Unmatched track boxes of the neighbouring class, with a 2D box at most 25 px high,
//!   or with more than half of their 2D box inside a DontCare region are ignored (not FP).
//! - A track's boxes all get the mean score of the track; at a threshold, tracks with a lower
//!   mean are dropped whole. The thresholds come from the (mean) scores of the matched boxes at
//!   40 recall points; sMOTA, MOTA and MOTP are averaged over them (missing points count 0).
//! - IDS, FRAG and MT/PT/ML are counted along each ground-truth trajectory (its frames in
//!   order, ignored frames interrupting it).
//!
//! Quirks of the reference evaluation that change numbers, and that we therefore keep:
//! - `TP` includes the matches of ignored ground truth (reported separately as `ITP`), and so do
//!   `MOTP` (mean IoU over `TP`), `recall` and `precision`; `MOTA` divides by the non-ignored
//!   ground truth only.
//! - A track box once matched (at any earlier threshold of the same class) can no longer be
//!   ignored by the neighbouring-class, height or DontCare rules.
//! - The mean track score is recomputed at every threshold from the previous means, which can
//!   move it by an ulp (and drop a track whose mean equals the threshold). The reference sums
//!   with Python's `sum`, plain left-to-right summation up to Python 3.11 (the version the
//!   reference numbers were made with); Python 3.12's compensated `sum` drifts far less
//!   ([`MeanScores::EveryPassCompensated`]). `drift_points` counts the recall points where
//!   that changed which tracks were kept, `sAMOTA_means_once` shows what it cost, and
//!   [`MeanScores::Once`] evaluates without it.
//! - FAR and MODP divide by the devkit's frame count, which is one more than the number of
//!   frames (the KITTI seqmap's last column holds the frame count, read as the last index).
//! - `overall` is not printed by the reference script; AB3DMOT's published tables give, for
//!   the three classes, the mean of the ratios and the sum of the counts, which is what we
//!   report, over the classes with ground truth that counts (a class evaluated only because
//!   tracks claim it has MOTA -inf and is left out, as the nuScenes protocol leaves out classes
//!   without ground truth).

use std::collections::BTreeMap;

use rayon::prelude::*;
use serde::Serialize;

use super::events::Collector;
pub use super::kitti_box::{KittiBox, KittiBoxes, KittiFields};
use super::nan_as_null;
use super::scene::Scene;
#[cfg(test)]
use crate::pipeline::kitti_io::attr::{
    OCCLUDED as ATTR_OCCLUDED, TRUNCATED as ATTR_TRUNCATED, TYPE as ATTR_TYPE,
};
use pass::{ClassEval, Pass};
use prepare::loaded_types;
pub use prepare::ClassTruth;
use tracks::SeqTracks;
pub use tracks::{row_kind, scene_rows, RowKind, Skip, TrackRow};

pub mod curve;
mod munkres;
mod pass;
mod prepare;
#[cfg(test)]
mod tests;
mod tracks;

/// The classes evaluated by default.
pub const KITTI_CLASSES: [&str; 3] = ["car", "pedestrian", "cyclist"];

/// The cost the reference gives forbidden pairs.
const MAX_COST: f64 = 1e9;
/// Extra frames per scene in the devkit's frame count (see the module documentation).
const DEVKIT_EXTRA_FRAMES: usize = 1;

/// Parameters of the protocol.
#[derive(Debug, Clone)]
pub struct KittiParams {
    /// Classes to evaluate (lower case; `car`, `pedestrian`, `cyclist` in the benchmark).
    pub classes: Vec<String>,
    /// Minimum 3D IoU of a match (0.25 by default; 0.5 and 0.7 are also used).
    pub min_overlap: f64,
    /// Ground truth truncated more than this is ignored.
    pub max_truncation: i64,
    /// Ground truth occluded more than this is ignored.
    pub max_occlusion: i64,
    /// Unmatched track boxes whose 2D box is at most this high (pixels) are ignored.
    pub min_height: f64,
    /// Number of recall points (40).
    pub recall_points: usize,
    /// When each track's mean score is computed: at every threshold from the previous means,
    /// as the reference does (the default), or once.
    pub means: MeanScores,
}

/// When the evaluation computes each track's mean score, the score its boxes are kept or
/// dropped by at a threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MeanScores {
    /// At every threshold, from the means of the previous one, as the reference does (summed
    /// left to right, as Python's `sum` did up to 3.11). Adding up `n` copies of a mean and
    /// dividing by `n` can move it by an ulp, so a track can be dropped at a threshold equal
    /// to its own mean (the thresholds are the matched boxes' means): the official numbers,
    /// quirk included (AB3DMOT's published scores are these).
    #[default]
    EveryPass,
    /// At every threshold, from the means of the previous one, summed with Neumaier's
    /// compensation as Python's `sum` does from 3.12: the reference's script run on a current
    /// Python. Its means barely drift (checked against Python 3.11, 3.12 and 3.13 in
    /// `tests/fixtures/eval/python_sum_means.json`).
    #[serde(rename = "every-pass-py312")]
    EveryPassCompensated,
    /// Once, from the track's own scores (summed left to right): a track is kept exactly when
    /// its mean reaches the threshold. Not the reference's numbers where they differ.
    Once,
}

impl crate::tracker::choice::Choice for MeanScores {
    const VALUES: &'static [Self] = &[
        MeanScores::EveryPass,
        MeanScores::EveryPassCompensated,
        MeanScores::Once,
    ];

    fn name(self) -> &'static str {
        match self {
            MeanScores::EveryPass => "every-pass",
            MeanScores::EveryPassCompensated => "every-pass-py312",
            MeanScores::Once => "once",
        }
    }

    fn description(self) -> &'static str {
        match self {
            MeanScores::EveryPass => {
                "At every threshold, from the previous means, summed left to right (the \
                 reference as run on Python 3.11 or older: the official numbers)"
            }
            MeanScores::EveryPassCompensated => {
                "At every threshold, from the previous means, with Python 3.12's compensated \
                 sum (the reference run on a current Python)"
            }
            MeanScores::Once => "Once per track",
        }
    }
}

impl MeanScores {
    /// Whether the means are computed again at every threshold, as the reference does.
    pub fn every_pass(self) -> bool {
        self != MeanScores::Once
    }

    /// Whether the sums are compensated (Python 3.12's `sum`).
    pub fn compensated(self) -> bool {
        self == MeanScores::EveryPassCompensated
    }
}

impl Default for KittiParams {
    fn default() -> Self {
        KittiParams {
            classes: KITTI_CLASSES.iter().map(|s| s.to_string()).collect(),
            min_overlap: 0.25,
            max_truncation: 0,
            max_occlusion: 2,
            min_height: 25.0,
            recall_points: 40,
            means: MeanScores::EveryPass,
        }
    }
}

/// The metrics at one score threshold (one recall point), as the reference prints them per
/// threshold.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CurvePoint {
    /// Score threshold (tracks with a lower mean score are dropped).
    pub threshold: f64,
    /// The recall point this threshold stands for.
    pub recall_point: f64,
    /// Scaled MOTA at this recall point.
    #[serde(rename = "sMOTA", serialize_with = "nan_as_null")]
    pub smota: f64,
    /// MOTA.
    #[serde(rename = "MOTA", serialize_with = "nan_as_null")]
    pub mota: f64,
    /// MOTP (mean IoU3D of the matches).
    #[serde(rename = "MOTP", serialize_with = "nan_as_null")]
    pub motp: f64,
    /// Fraction of mostly tracked trajectories.
    #[serde(rename = "MT", serialize_with = "nan_as_null")]
    pub mt: f64,
    /// Fraction of mostly lost trajectories.
    #[serde(rename = "ML", serialize_with = "nan_as_null")]
    pub ml: f64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: u64,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: u64,
    /// F1 score.
    #[serde(rename = "F1", serialize_with = "nan_as_null")]
    pub f1: f64,
    /// Precision.
    #[serde(serialize_with = "nan_as_null")]
    pub precision: f64,
    /// Recall achieved.
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    /// False alarms per frame.
    #[serde(rename = "FAR", serialize_with = "nan_as_null")]
    pub far: f64,
    /// True positives (ignored ones included).
    #[serde(rename = "TP")]
    pub tp: u64,
    /// False positives.
    #[serde(rename = "FP")]
    pub fp: u64,
    /// False negatives.
    #[serde(rename = "FN")]
    pub fn_: u64,
}

/// Every metric of one class (or of the overall aggregate). Names follow the reference's
/// output; non-finite values are JSON `null`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct KittiMetrics {
    /// Scaled AMOTA: mean sMOTA over the recall points.
    #[serde(rename = "sAMOTA", serialize_with = "nan_as_null")]
    pub samota: f64,
    /// Mean MOTA over the recall points.
    #[serde(rename = "AMOTA", serialize_with = "nan_as_null")]
    pub amota: f64,
    /// Mean MOTP over the recall points.
    #[serde(rename = "AMOTP", serialize_with = "nan_as_null")]
    pub amotp: f64,
    /// MOTA at the best threshold.
    #[serde(rename = "MOTA", serialize_with = "nan_as_null")]
    pub mota: f64,
    /// MOTP (mean IoU3D of the true positives) at the best threshold.
    #[serde(rename = "MOTP", serialize_with = "nan_as_null")]
    pub motp: f64,
    /// MOTA with `log10(IDS)` in place of IDS.
    #[serde(rename = "MOTAL", serialize_with = "nan_as_null")]
    pub motal: f64,
    /// MODA (MOTA without IDS).
    #[serde(rename = "MODA", serialize_with = "nan_as_null")]
    pub moda: f64,
    /// MODP (mean over frames of the mean IoU of non-ignored matches; 1 in frames without).
    #[serde(rename = "MODP", serialize_with = "nan_as_null")]
    pub modp: f64,
    /// Recall.
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    /// Precision.
    #[serde(serialize_with = "nan_as_null")]
    pub precision: f64,
    /// F1 score.
    #[serde(rename = "F1", serialize_with = "nan_as_null")]
    pub f1: f64,
    /// False alarms per frame.
    #[serde(rename = "FAR", serialize_with = "nan_as_null")]
    pub far: f64,
    /// Fraction of mostly tracked trajectories (> 80 % of their frames).
    #[serde(rename = "MT", serialize_with = "nan_as_null")]
    pub mt: f64,
    /// Fraction of partly tracked trajectories.
    #[serde(rename = "PT", serialize_with = "nan_as_null")]
    pub pt: f64,
    /// Fraction of mostly lost trajectories (< 20 %).
    #[serde(rename = "ML", serialize_with = "nan_as_null")]
    pub ml: f64,
    /// True positives, ignored ones included.
    #[serde(rename = "TP")]
    pub tp: u64,
    /// True positives on ignored ground truth.
    #[serde(rename = "ITP")]
    pub itp: u64,
    /// False positives.
    #[serde(rename = "FP")]
    pub fp: u64,
    /// False negatives.
    #[serde(rename = "FN")]
    pub fn_: u64,
    /// Ignored false negatives.
    #[serde(rename = "IFN")]
    pub ifn: u64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: u64,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: u64,
    /// Ground-truth boxes (ignored ones included).
    pub gt_objects: u64,
    /// Ignored ground-truth boxes.
    pub ignored_gt: u64,
    /// Ground-truth trajectories.
    pub gt_trajectories: u64,
    /// Track boxes kept at the best threshold.
    pub tracker_objects: u64,
    /// Ignored track boxes.
    pub ignored_tracker: u64,
    /// Track trajectories (all, before thresholding).
    pub tracker_trajectories: u64,
    /// The threshold of the best MOTA (the reference's "best results with single threshold").
    #[serde(serialize_with = "nan_as_null")]
    pub best_threshold: f64,
    /// Recall points at which a track was kept or dropped otherwise than its mean score says:
    /// the drift of the reference's re-averaging ([`MeanScores::EveryPass`]); summed in
    /// `overall`.
    pub drift_points: u64,
    /// sAMOTA with each track's mean score computed once ([`MeanScores::Once`]): `sAMOTA`
    /// itself when no point drifted. Not an official number; it shows what the drift cost.
    #[serde(rename = "sAMOTA_means_once", serialize_with = "nan_as_null")]
    pub samota_means_once: f64,
    /// The metrics at every recall point, in order (empty for `overall`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub curve: Vec<CurvePoint>,
}

/// Names accepted by [`KittiMetrics::get`], in report order (the main one first).
pub const METRIC_NAMES: [&str; 27] = [
    "sAMOTA",
    "AMOTA",
    "AMOTP",
    "MOTA",
    "MOTP",
    "MOTAL",
    "MODA",
    "MODP",
    "recall",
    "precision",
    "F1",
    "FAR",
    "MT",
    "PT",
    "ML",
    "TP",
    "ITP",
    "FP",
    "FN",
    "IFN",
    "IDS",
    "FRAG",
    "gt_objects",
    "ignored_gt",
    "gt_trajectories",
    "tracker_objects",
    "ignored_tracker",
];

impl KittiMetrics {
    /// A metric by its reference name (see [`METRIC_NAMES`]; also `tracker_trajectories` and
    /// `best_threshold`); NaN for an unknown name.
    pub fn get(&self, name: &str) -> f64 {
        match name {
            "sAMOTA" => self.samota,
            "AMOTA" => self.amota,
            "AMOTP" => self.amotp,
            "MOTA" => self.mota,
            "MOTP" => self.motp,
            "MOTAL" => self.motal,
            "MODA" => self.moda,
            "MODP" => self.modp,
            "recall" => self.recall,
            "precision" => self.precision,
            "F1" => self.f1,
            "FAR" => self.far,
            "MT" => self.mt,
            "PT" => self.pt,
            "ML" => self.ml,
            "TP" => self.tp as f64,
            "ITP" => self.itp as f64,
            "FP" => self.fp as f64,
            "FN" => self.fn_ as f64,
            "IFN" => self.ifn as f64,
            "IDS" => self.ids as f64,
            "FRAG" => self.frag as f64,
            "gt_objects" => self.gt_objects as f64,
            "ignored_gt" => self.ignored_gt as f64,
            "gt_trajectories" => self.gt_trajectories as f64,
            "tracker_objects" => self.tracker_objects as f64,
            "ignored_tracker" => self.ignored_tracker as f64,
            "tracker_trajectories" => self.tracker_trajectories as f64,
            "best_threshold" => self.best_threshold,
            _ => f64::NAN,
        }
    }

    /// The aggregate of several classes: mean of the ratios, sum of the counts.
    fn overall<'a>(classes: impl Iterator<Item = &'a KittiMetrics>) -> KittiMetrics {
        let all: Vec<&KittiMetrics> = classes.collect();
        let mean = |f: fn(&KittiMetrics) -> f64| {
            if all.is_empty() {
                f64::NAN
            } else {
                all.iter().map(|m| f(m)).sum::<f64>() / all.len() as f64
            }
        };
        let sum = |f: fn(&KittiMetrics) -> u64| all.iter().map(|m| f(m)).sum::<u64>();
        KittiMetrics {
            samota: mean(|m| m.samota),
            amota: mean(|m| m.amota),
            amotp: mean(|m| m.amotp),
            mota: mean(|m| m.mota),
            motp: mean(|m| m.motp),
            motal: mean(|m| m.motal),
            moda: mean(|m| m.moda),
            modp: mean(|m| m.modp),
            recall: mean(|m| m.recall),
            precision: mean(|m| m.precision),
            f1: mean(|m| m.f1),
            far: mean(|m| m.far),
            mt: mean(|m| m.mt),
            pt: mean(|m| m.pt),
            ml: mean(|m| m.ml),
            tp: sum(|m| m.tp),
            itp: sum(|m| m.itp),
            fp: sum(|m| m.fp),
            fn_: sum(|m| m.fn_),
            ifn: sum(|m| m.ifn),
            ids: sum(|m| m.ids),
            frag: sum(|m| m.frag),
            gt_objects: sum(|m| m.gt_objects),
            ignored_gt: sum(|m| m.ignored_gt),
            gt_trajectories: sum(|m| m.gt_trajectories),
            tracker_objects: sum(|m| m.tracker_objects),
            ignored_tracker: sum(|m| m.ignored_tracker),
            tracker_trajectories: sum(|m| m.tracker_trajectories),
            best_threshold: f64::NAN,
            drift_points: sum(|m| m.drift_points),
            samota_means_once: mean(|m| m.samota_means_once),
            curve: Vec::new(),
        }
    }
}

/// Result of an evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct KittiResult {
    /// Protocol name.
    pub protocol: &'static str,
    /// Minimum 3D IoU of a match.
    pub min_overlap: f64,
    /// When the tracks' mean scores were computed (`every-pass`: the official numbers).
    pub means: MeanScores,
    /// Per evaluated class. A class without any track box of its types is not evaluated (as in
    /// the reference) and is absent here; see `notes`.
    pub classes: BTreeMap<String, KittiMetrics>,
    /// Aggregate over the evaluated classes with ground truth that counts: mean of the ratios,
    /// sum of the counts (NaN / 0 when there is none).
    pub overall: KittiMetrics,
    /// Things the user should know (skipped classes, classes without ground truth).
    pub notes: Vec<String>,
}

/// The score thresholds and their recall points: walking the matched boxes' scores from the
/// highest, a threshold is taken whenever the recall reached is the closest to the next of the
/// `recall_points` evenly spaced points (the first, at recall 0, is dropped).
fn thresholds(scores: &[f64], num_gt: u64, recall_points: usize) -> (Vec<f64>, Vec<f64>) {
    let mut s = scores.to_vec();
    s.sort_by(|a, b| b.total_cmp(a));
    let (mut th, mut rec) = (Vec::new(), Vec::new());
    let mut current = 0.0f64;
    let n = s.len();
    for (i, &score) in s.iter().enumerate() {
        let l_recall = (i + 1) as f64 / num_gt as f64;
        let r_recall = if i + 1 < n {
            (i + 2) as f64 / num_gt as f64
        } else {
            l_recall
        };
        if (r_recall - current) < (current - l_recall) && i + 1 < n {
            continue;
        }
        th.push(score);
        rec.push(current);
        current += 1.0 / recall_points as f64;
    }
    if !th.is_empty() {
        th.remove(0);
        rec.remove(0);
    }
    (th, rec)
}

/// Evaluates one class; `None` (and a note) when it cannot be evaluated.
fn evaluate_class<B: KittiFields>(
    scenes: &[Scene<B>],
    cls: &str,
    p: &KittiParams,
    notes: &mut Vec<String>,
    log: Option<&mut Collector>,
) -> Option<KittiMetrics> {
    let truth = ClassTruth::of_scenes(scenes, cls, p);
    let tracks: Vec<Vec<TrackRow>> = scenes.iter().map(|s| scene_rows(s, cls)).collect();
    let rows = tracks.iter().map(Vec::len).sum::<usize>();
    let flat = (tracks.iter().flatten())
        .filter(|r| r.image_box.is_none())
        .count();
    if flat > 0 {
        notes.push(format!(
            "{cls}: {flat} of {rows} track boxes have no 2D image box (the log was not imported \
             from KITTI): the reference's 2D rules (boxes {} px high or lower, DontCare regions) \
             cannot ignore them, so unmatched ones count as false positives; the scores are not \
             the official evaluation's",
            p.min_height
        ));
    }
    match truth.evaluate_recording(&tracks, log) {
        Ok(m) => {
            if m.drift_points > 0 {
                let python = if p.means.compensated() {
                    "3.12 or newer"
                } else {
                    "3.11 or older"
                };
                notes.push(format!(
                    "{cls}: the reference's re-averaging of the track scores (an ulp of drift \
                     at each threshold, whose values are the tracks' own means) changed which \
                     tracks were kept at {} of {} recall points: sAMOTA {:.4} as the reference \
                     computes it on Python {python}, {:.4} with each track's mean computed once \
                     (`--means once`; not the official number)",
                    m.drift_points,
                    m.curve.len(),
                    m.samota,
                    m.samota_means_once
                ));
            }
            if m.gt_objects == m.ignored_gt {
                notes.push(format!(
                    "{cls}: no ground truth that counts (all ignored or none): MOTA is -inf \
                     (null), as in the reference; left out of overall"
                ));
            }
            Some(m)
        }
        Err(Skip::NoTracks) => {
            notes.push(format!(
                "{cls}: no track box of the types {} evaluated; class not evaluated (as the \
                 reference does)",
                loaded_types(cls)[..loaded_types(cls).len() - 1].join("/")
            ));
            None
        }
        Err(Skip::DuplicateId { scene, frame, id }) => {
            notes.push(format!(
                "{cls}: {scene}: track id {id} appears twice in frame {frame}; class not \
                 evaluated (the reference rejects such results)"
            ));
            None
        }
        Err(Skip::Mismatch(m)) => {
            notes.push(format!("{cls}: {m}; class not evaluated"));
            None
        }
    }
}

impl ClassTruth {
    /// The class's metrics for one set of tracks of the truth's scenes: per scene, its track
    /// rows of the class in frame order (as [`scene_rows`] selects them). The truth is not
    /// changed, so one `ClassTruth` scores any number of track sets.
    pub fn evaluate(&self, tracks: &[Vec<TrackRow>]) -> Result<KittiMetrics, Skip> {
        self.evaluate_recording(tracks, None)
    }

    /// [`ClassTruth::evaluate`]; with `log`, also the decisions of the pass at the best-MOTA
    /// threshold (the pass the counts come from).
    pub fn evaluate_recording(
        &self,
        tracks: &[Vec<TrackRow>],
        log: Option<&mut Collector>,
    ) -> Result<KittiMetrics, Skip> {
        let (seqs, n_tr_trajectories) = tracks::prepare_tracks(&self.seqs, tracks, &self.p)?;
        // The passes change the rows' scores and flags: a drift needs the rows' own scores to
        // evaluate them again.
        let scores: Option<Vec<Vec<f64>>> =
            (self.p.means.every_pass()).then(|| seqs.iter().map(SeqTracks::scores).collect());
        let (mut m, mut seqs) = self.evaluate_means((seqs, n_tr_trajectories), log, self.p.means);
        m.samota_means_once = match scores {
            Some(scores) if m.drift_points > 0 => {
                for (seq, scores) in seqs.iter_mut().zip(&scores) {
                    seq.restart(scores);
                }
                let once = self.evaluate_means((seqs, n_tr_trajectories), None, MeanScores::Once);
                once.0.samota
            }
            _ => m.samota,
        };
        Ok(m)
    }

    /// The evaluation of prepared tracks (and their number of trajectories) with the mean
    /// scores computed as `means` says; the tracks given back as the passes left them.
    fn evaluate_means(
        &self,
        (seqs, n_tr_trajectories): (Vec<SeqTracks>, u64),
        log: Option<&mut Collector>,
        means: MeanScores,
    ) -> (KittiMetrics, Vec<SeqTracks>) {
        let p = &self.p;
        let mut e = ClassEval::new(self, seqs, means);
        let first = e.pass(-10000.0, 1.0, true);
        let num_gt = first.tp + first.fn_;
        let (ths, recs) = thresholds(&first.scores, num_gt, p.recall_points);
        let mut curve = Vec::with_capacity(ths.len());
        let (mut sum_smota, mut sum_mota, mut sum_motp) = (0.0f64, 0.0f64, 0.0f64);
        let (mut best_mota, mut best_threshold) = (0.0f64, -10000.0f64);
        let mut drift_points = 0;
        for (&th, &rec) in ths.iter().zip(&recs) {
            let r = e.pass(th, rec, false);
            drift_points += u64::from(r.drifted);
            sum_smota += r.smota;
            sum_mota += r.mota;
            sum_motp += r.motp;
            if r.mota > best_mota {
                best_threshold = th;
                best_mota = r.mota;
            }
            curve.push(curve_point(th, rec, &r));
        }
        e.log = log.is_some().then(Collector::default);
        let best = e.pass(best_threshold, 1.0, false);
        if let (Some(out), Some(recorded)) = (log, e.log.take()) {
            *out = recorded;
        }
        let k = p.recall_points as f64;
        let n_gt_trajectories = self.n_gt_trajectories;
        let mut m = metrics_at(&best, (n_gt_trajectories, n_tr_trajectories));
        (m.samota, m.amota, m.amotp) = (sum_smota / k, sum_mota / k, sum_motp / k);
        m.best_threshold = best_threshold;
        m.drift_points = drift_points;
        m.curve = curve;
        (m, e.into_seqs())
    }
}

/// One point of the curve: the pass at threshold `th` (recall point `rec`).
fn curve_point(th: f64, rec: f64, r: &Pass) -> CurvePoint {
    CurvePoint {
        threshold: th,
        recall_point: rec,
        smota: r.smota,
        mota: r.mota,
        motp: r.motp,
        mt: r.mt,
        ml: r.ml,
        ids: r.ids,
        frag: r.frag,
        f1: r.f1,
        precision: r.precision,
        recall: r.recall,
        far: r.far,
        tp: r.tp,
        fp: r.fp,
        fn_: r.fn_,
    }
}

/// The metrics of the best pass; the averages over the curve, the threshold and the curve are
/// left for the caller to fill in.
fn metrics_at(best: &Pass, (gt_trajectories, tracker_trajectories): (u64, u64)) -> KittiMetrics {
    KittiMetrics {
        samota: f64::NAN,
        amota: f64::NAN,
        amotp: f64::NAN,
        mota: best.mota,
        motp: best.motp,
        motal: best.motal,
        moda: best.moda,
        modp: best.modp,
        recall: best.recall,
        precision: best.precision,
        f1: best.f1,
        far: best.far,
        mt: best.mt,
        pt: best.pt,
        ml: best.ml,
        tp: best.tp,
        itp: best.itp,
        fp: best.fp,
        fn_: best.fn_,
        ifn: best.ifn,
        ids: best.ids,
        frag: best.frag,
        gt_objects: best.n_gt + best.n_igt,
        ignored_gt: best.n_igt,
        gt_trajectories,
        tracker_objects: best.n_tr,
        ignored_tracker: best.n_itr,
        tracker_trajectories,
        best_threshold: f64::NAN,
        drift_points: 0,
        samota_means_once: f64::NAN,
        curve: Vec::new(),
    }
}

/// Evaluates scenes (one KITTI sequence each) with the KITTI 3D MOT protocol of AB3DMOT.
///
/// Truth boxes carry the KITTI fields as attributes (`kitti_type`, `kitti_truncated`,
/// `kitti_occluded`, `kitti_track_id`) and DontCare regions as boxes of type DontCare with an
/// `image_box`; track boxes need `image_box` (the 2D box of their last matched detection) for
/// the ignore rules and take their type from `kitti_type` (else the label).
pub fn evaluate<B: KittiFields + Sync>(scenes: &[Scene<B>], p: &KittiParams) -> KittiResult {
    evaluate_recording(scenes, p, false).0
}

/// [`evaluate`]; with `record`, also the decisions of each evaluated class's pass at its best-MOTA
/// threshold (the pass its counts come from), for `eval --events`.
pub fn evaluate_recording<B: KittiFields + Sync>(
    scenes: &[Scene<B>],
    p: &KittiParams,
    record: bool,
) -> (KittiResult, Vec<(String, Collector)>) {
    // Classes are independent: evaluated in parallel, notes kept in class order.
    type ClassOutcome = (String, Option<KittiMetrics>, Vec<String>, Option<Collector>);
    let per_class: Vec<ClassOutcome> = p
        .classes
        .par_iter()
        .map(|c| {
            let c = c.to_lowercase();
            let mut notes = Vec::new();
            let mut log = record.then(Collector::default);
            let m = evaluate_class(scenes, &c, p, &mut notes, log.as_mut());
            (c, m, notes, log)
        })
        .collect();
    let mut notes = Vec::new();
    let mut classes = BTreeMap::new();
    let mut decisions = Vec::new();
    for (c, m, n, log) in per_class {
        notes.extend(n);
        if let Some(m) = m {
            if let Some(log) = log {
                decisions.push((c.clone(), log));
            }
            classes.insert(c, m);
        }
    }
    let overall = KittiMetrics::overall(classes.values().filter(|m| m.gt_objects > m.ignored_gt));
    let result = KittiResult {
        protocol: "kitti",
        min_overlap: p.min_overlap,
        means: p.means,
        classes,
        overall,
        notes,
    };
    (result, decisions)
}
