//! The counts each resampling unit keeps per pass of a protocol's recall curve, and the
//! protocols' aggregate metrics recomputed from weighted sums of them.
//!
//! KITTI (AB3DMOT): sAMOTA and AMOTA are the sums of sMOTA and MOTA over the passes divided by
//! the number of recall points; MOTA is the best pass's (the pass keeping every track when
//! none is positive); `overall` is the mean over the classes with ground truth that counts.
//! nuScenes: AMOTA and AMOTP are the means of MOTAR (0 where undefined or unreached) and MOTP
//! (2 m where undefined or unreached) over the recall levels; MOTA and IDS are those of the
//! first level with the best MOTA; `overall` is the mean over classes with ground truth, IDS
//! their sum. With every weight 1 these are the protocols' own numbers.

/// Counts of one unit in one pass (f64: they are summed with weights).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UnitCounts {
    /// Ground truth that counts (KITTI: not ignored).
    pub gt: f64,
    /// True positives (KITTI: ignored ones included; nuScenes: matches without switches).
    pub tp: f64,
    /// False positives.
    pub fp: f64,
    /// False negatives.
    pub fn_: f64,
    /// Identity switches.
    pub ids: f64,
    /// Sum of the matches' similarity (KITTI: 3D IoU) or distance (nuScenes: metres).
    pub sim: f64,
}

impl UnitCounts {
    /// Adds `other` `w` times.
    fn add(&mut self, o: &UnitCounts, w: f64) {
        self.gt += w * o.gt;
        self.tp += w * o.tp;
        self.fp += w * o.fp;
        self.fn_ += w * o.fn_;
        self.ids += w * o.ids;
        self.sim += w * o.sim;
    }
}

/// The weighted sum of per-unit counts.
pub fn weighted(units: &[UnitCounts], w: &[u32]) -> UnitCounts {
    let mut s = UnitCounts::default();
    for (u, &k) in units.iter().zip(w) {
        if k > 0 {
            s.add(u, f64::from(k));
        }
    }
    s
}

/// One KITTI class: per pass, its recall point and per-unit counts.
#[derive(Debug, Clone, Default)]
pub struct KittiCurve {
    /// `(recall point, counts per unit)` of the passes at the curve's thresholds.
    pub passes: Vec<(f64, Vec<UnitCounts>)>,
    /// The pass keeping every track (the best pass when no MOTA is positive).
    pub all_tracks: Vec<UnitCounts>,
    /// The number of recall points the sums are divided by (40).
    pub recall_points: usize,
}

/// Names of the KITTI metrics [`kitti_class`] computes, in order.
pub const KITTI_METRICS: [&str; 3] = ["sAMOTA", "AMOTA", "MOTA"];

/// The recall of the pass keeping every track: the highest the curve can reach.
fn max_recall(s: &UnitCounts) -> f64 {
    s.tp / (s.tp + s.fn_)
}

/// sAMOTA, AMOTA and MOTA of one KITTI class under weights `w`; `None` without ground truth
/// that counts. The recall points a resample reaches move with its highest recall (one more or
/// fewer per 1/40 of recall than all the data reach; a point beyond them takes the last
/// pass's counts): how far the curve reaches is most of AMOTA's noise.
pub fn kitti_class(c: &KittiCurve, w: &[u32]) -> Option<[f64; 3]> {
    let all = weighted(&c.all_tracks, w);
    if all.gt <= 0.0 {
        return None;
    }
    let mota_of = |s: &UnitCounts| 1.0 - (s.fn_ + s.fp + s.ids) / s.gt;
    let (mut smota, mut mota, mut best) = (0.0, 0.0, 0.0f64);
    let mut any = false;
    let k = c.recall_points as f64;
    let ones = vec![1; w.len()];
    let full = weighted(&c.all_tracks, &ones);
    let shift = (max_recall(&all) - max_recall(&full)) * k;
    let reached = (c.passes.len() as f64 + shift.round()).clamp(0.0, k) as usize;
    for i in 0..reached {
        let Some(last) = c.passes.len().checked_sub(1) else {
            break;
        };
        let (r, units) = &c.passes[i.min(last)];
        let r = if i > last { (i + 1) as f64 / k } else { *r };
        let s = weighted(units, w);
        let m = mota_of(&s);
        let errors = s.fn_ + s.fp + s.ids;
        smota += (1.0 - (errors - (1.0 - r) * s.gt) / (r * s.gt)).clamp(0.0, 1.0);
        mota += m;
        if m > best {
            (best, any) = (m, true);
        }
    }
    Some([smota / k, mota / k, if any { best } else { mota_of(&all) }])
}

/// Per class (in order) then overall: [`KITTI_METRICS`] under weights `w`, NaN for a class
/// without ground truth that counts in this resample.
pub fn kitti_metrics(classes: &[KittiCurve], w: &[u32]) -> Vec<f64> {
    let per: Vec<Option<[f64; 3]>> = classes.iter().map(|c| kitti_class(c, w)).collect();
    mean_overall(&per, &[false; 3])
}

/// The values of each class (NaN when `None`), then over the classes with a value: the mean,
/// or the sum for the metrics `summed` marks.
fn mean_overall<const N: usize>(per: &[Option<[f64; N]>], summed: &[bool; N]) -> Vec<f64> {
    let mut out = Vec::with_capacity((per.len() + 1) * N);
    for p in per {
        out.extend(p.unwrap_or([f64::NAN; N]));
    }
    let with: Vec<&[f64; N]> = per.iter().flatten().collect();
    for k in 0..N {
        let finite: Vec<f64> = with.iter().map(|v| v[k]).filter(|v| !v.is_nan()).collect();
        out.push(match (finite.is_empty(), summed[k]) {
            (true, _) => f64::NAN,
            (false, true) => finite.iter().sum(),
            (false, false) => finite.iter().sum::<f64>() / finite.len() as f64,
        });
    }
    out
}

/// One nuScenes class: per recall level, per-unit counts (`None`: the level is not reached).
#[derive(Debug, Clone, Default)]
pub struct NuscenesCurve {
    /// Per recall level, in the devkit's order.
    pub levels: Vec<Option<Vec<UnitCounts>>>,
    /// Ground-truth boxes per unit.
    pub gt: Vec<f64>,
    /// Matched boxes per unit when every track is kept (what the highest recall counts).
    pub matched: Vec<f64>,
    /// The lowest recall level (0.1).
    pub min_recall: f64,
}

/// Names of the nuScenes metrics [`nuscenes_class`] computes, in order.
pub const NUSCENES_METRICS: [&str; 4] = ["amota", "amotp", "mota", "ids"];

/// `Σ w·v`.
fn dot(v: &[f64], w: &[u32]) -> f64 {
    v.iter().zip(w).map(|(v, &k)| v * f64::from(k)).sum()
}

/// AMOTA, AMOTP, MOTA and IDS of one nuScenes class under weights `w`; `None` without ground
/// truth. The recall levels a resample reaches move with its highest recall (one more or fewer
/// per level step than all the data reach; a level beyond them takes the counts of the
/// highest level all the data reach): how far the curve reaches is most of AMOTA's noise.
pub fn nuscenes_class(c: &NuscenesCurve, w: &[u32]) -> Option<[f64; 4]> {
    let gt = dot(&c.gt, w);
    if gt <= 0.0 {
        return None;
    }
    let n = c.levels.len();
    let ones = vec![1; w.len()];
    let full_reached = c.levels.iter().filter(|l| l.is_some()).count();
    let step = (1.0 - c.min_recall) / (n.max(2) - 1) as f64;
    let shift = (dot(&c.matched, w) / gt - dot(&c.matched, &ones) / dot(&c.gt, &ones)) / step;
    let reached = match full_reached {
        0 => 0,
        r => (r as f64 + shift.round()).clamp(0.0, n as f64) as usize,
    };
    let (mut motar_sum, mut motp_sum) = (0.0, 0.0);
    let mut best: Option<(f64, f64)> = None;
    for j in 0..n {
        // Devkit order: the highest recall level first.
        let level = (j >= n - reached).then(|| &c.levels[j.max(n - full_reached)]);
        let Some(Some(units)) = level else {
            motp_sum += 2.0;
            continue;
        };
        let s = weighted(units, w);
        let objects = s.tp + s.ids + s.fn_;
        let errors = s.fn_ + s.ids + s.fp;
        let recall = s.tp / objects;
        let denominator = recall * objects;
        if denominator != 0.0 {
            let motar = 1.0 - (errors - (1.0 - recall) * objects) / denominator;
            motar_sum += motar.max(0.0);
        }
        let detections = s.tp + s.ids;
        motp_sum += if detections == 0.0 {
            2.0
        } else {
            s.sim / detections
        };
        let mota = (1.0 - errors / objects).max(0.0);
        if best.is_none_or(|(b, _)| mota > b) {
            best = Some((mota, s.ids));
        }
    }
    let n = c.levels.len() as f64;
    let (mota, ids) = best.unwrap_or((0.0, f64::NAN));
    Some([motar_sum / n, motp_sum / n, mota, ids])
}

/// Per class (in order) then overall: [`NUSCENES_METRICS`] under weights `w` (NaN for a class
/// without ground truth in this resample; IDS summed over the classes).
pub fn nuscenes_metrics(classes: &[NuscenesCurve], w: &[u32]) -> Vec<f64> {
    let per: Vec<Option<[f64; 4]>> = classes.iter().map(|c| nuscenes_class(c, w)).collect();
    mean_overall(&per, &[false, false, false, true])
}
