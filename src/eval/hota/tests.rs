//! Hand-worked cases of the HOTA definitions (Luiten et al. 2020, eqs. 1-9).

use super::*;

fn frame(gt: &[u32], tr: &[u32], sim: &[f64]) -> HotaFrame {
    HotaFrame {
        gt: gt.to_vec(),
        tr: tr.to_vec(),
        sim: sparse(sim),
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

#[test]
fn perfect_tracking_scores_one() {
    let frames = vec![frame(&[0], &[0], &[1.0]); 3];
    let h = Hota::from_counts(&combine(&[eval_sequence(&frames, 1, 1)]));
    assert!(close(h.hota, 1.0) && close(h.deta, 1.0) && close(h.assa, 1.0));
    assert!(close(h.loca, 1.0));
}

/// One object seen in 4 frames, tracked by id A in two and by id B in the other two: every
/// frame is a true positive (DetA 1), each TPA's association IoU is 2 / (4 + 2 - 2) = 0.5.
#[test]
fn an_id_switch_halves_assa() {
    let frames = vec![
        frame(&[0], &[0], &[1.0]),
        frame(&[0], &[0], &[1.0]),
        frame(&[0], &[1], &[1.0]),
        frame(&[0], &[1], &[1.0]),
    ];
    let h = Hota::from_counts(&eval_sequence(&frames, 1, 2));
    assert!(close(h.deta, 1.0));
    assert!(close(h.assa, 0.5));
    assert!(close(h.hota, 0.5f64.sqrt()));
    assert!(close(h.assre, 0.5) && close(h.asspr, 1.0));
}

/// Similarity 0.5: a match for alpha 0.05 ... 0.50 (10 thresholds), a miss and a false positive
/// above. LocA is 0.5 where there are matches and 1 (TrackEval's 1e-10 / 1e-10) where not.
#[test]
fn similarity_decides_per_alpha() {
    let frames = vec![frame(&[0], &[0], &[0.5])];
    let c = eval_sequence(&frames, 1, 1);
    assert_eq!(c.tp.iter().filter(|&&t| t == 1.0).count(), 10);
    let h = Hota::from_counts(&c);
    assert!(close(h.hota, 10.0 / 19.0));
    assert!(close(h.loca, (10.0 * 0.5 + 9.0) / 19.0));
    assert!(close(h.detre, 10.0 / 19.0));
}

/// Two objects crossing: in the last frame the wrong pairing is slightly more similar, but
/// the alignment built over the earlier frames keeps the ids on their objects.
#[test]
fn alignment_beats_a_slightly_better_frame_iou() {
    let mut frames = vec![frame(&[0, 1], &[0, 1], &[0.9, 0.0, 0.0, 0.9]); 5];
    frames.push(frame(&[0, 1], &[0, 1], &[0.6, 0.65, 0.65, 0.6]));
    let c = eval_sequence(&frames, 2, 2);
    // At alpha 0.05 every frame matches both objects; on the right ids the association is perfect.
    assert_eq!(c.tp[0], 12.0);
    assert!(close(c.ass_a[0], 1.0), "AssA {}", c.ass_a[0]);
    // At alpha 0.7 the last frame matches nothing: each object's 5 matches of 6 + 6 detections.
    assert!(close(c.ass_a[13], 5.0 / 7.0), "AssA {}", c.ass_a[13]);
}

#[test]
fn empty_sides() {
    let only_gt = eval_sequence(&[frame(&[0], &[], &[])], 1, 0);
    assert_eq!(only_gt.fn_[0], 1.0);
    let only_tr = eval_sequence(&[frame(&[], &[0, 1], &[])], 0, 2);
    assert_eq!(only_tr.fp[18], 2.0);
    let h = Hota::from_counts(&combine(&[only_gt, only_tr]));
    assert_eq!(h.hota, 0.0);
    assert_eq!(h.loca, 1.0);
}

#[test]
fn sequences_combine_weighted_by_true_positives() {
    let a = eval_sequence(&vec![frame(&[0], &[0], &[1.0]); 3], 1, 1);
    let b = eval_sequence(
        &[frame(&[0], &[0], &[1.0]), frame(&[0], &[1], &[1.0])],
        1,
        2,
    );
    let c = combine(&[a, b]);
    // AssA: (3 x 1 + 2 x 0.5) / 5.
    assert!(close(c.ass_a[0], 4.0 / 5.0));
    assert_eq!(c.tp[0], 5.0);
}

#[test]
fn the_overall_row_is_the_class_mean_of_each_column() {
    let perfect = Hota::from_counts(&eval_sequence(&vec![frame(&[0], &[0], &[1.0]); 3], 1, 1));
    let missed = Hota::from_counts(&eval_sequence(&[frame(&[0], &[], &[])], 1, 0));
    let classes = std::collections::BTreeMap::from([
        ("car".to_string(), perfect.clone()),
        ("truck".to_string(), missed.clone()),
    ]);
    let rows = hota_rows(&classes, " 3d");
    let names: Vec<&str> = rows.iter().map(|r| r.0.as_str()).collect();
    assert_eq!(names, ["car 3d", "truck 3d", "overall 3d"]);
    assert!(close(rows[2].1[0], (perfect.hota + missed.hota) / 2.0));
    assert!(close(rows[2].1[3], (perfect.loca + missed.loca) / 2.0));
    assert!(hota_rows(&Default::default(), "").is_empty());
}
