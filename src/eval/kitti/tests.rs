use super::munkres::munkres;
use super::*;
use crate::mcapio::LabelledBox;
use crate::pipeline::kitti_io::attr::TRACK_ID as ATTR_TRACK_ID;

/// A normal-sized 2D box (100 px high).
const IMG: [f64; 4] = [100.0, 100.0, 200.0, 200.0];
/// IoU of a track on its ground truth (see [`trk`]): overlap 3.5 x 1.75 m of 4 x 2 m boxes.
const IOU: f64 = 6.125 / 9.875;

fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// A ground-truth box as `probmot import kitti` writes it: a 4 x 2 x 1.5 m box at `(x, 0)`.
fn gt(kitti_id: i64, kind: &str, x: f64, truncated: u8, occluded: u8) -> LabelledBox {
    LabelledBox {
        id: (kitti_id + 1) as u64,
        label: kind.to_lowercase(),
        center: [x, 0.0, 0.0],
        size: [4.0, 2.0, 1.5],
        score: 1.0,
        attributes: attrs(&[
            (ATTR_TYPE, kind.to_string()),
            (ATTR_TRUNCATED, truncated.to_string()),
            (ATTR_OCCLUDED, occluded.to_string()),
            (ATTR_TRACK_ID, kitti_id.to_string()),
        ]),
        image_box: Some(IMG),
        ..Default::default()
    }
}

fn dontcare(image_box: [f64; 4]) -> LabelledBox {
    LabelledBox {
        id: 0,
        attributes: attrs(&[(ATTR_TYPE, "DontCare".into()), (ATTR_TRACK_ID, "-1".into())]),
        image_box: Some(image_box),
        ..gt(-1, "DontCare", -100.0, 0, 0)
    }
}

/// A track box of `kind` at `(x + 0.5, 0.25)`, the same size as [`gt`]'s: on a ground truth
/// at `x` its IoU is [`IOU`]. (Not exactly on it: the reference's polygon clipping fails on
/// collinear edges, and these scenes are also checked against the reference, see
/// `tests/fixtures/kitti/README.md`.)
fn trk(id: u64, kind: &str, x: f64, score: f64, image_box: [f64; 4]) -> LabelledBox {
    LabelledBox {
        id,
        label: kind.to_lowercase(),
        center: [x + 0.5, 0.25, 0.0],
        size: [4.0, 2.0, 1.5],
        score,
        attributes: attrs(&[(ATTR_TYPE, kind.to_string())]),
        image_box: Some(image_box),
        ..Default::default()
    }
}

fn scene(frames: Vec<(Vec<LabelledBox>, Vec<LabelledBox>)>) -> Scene {
    Scene {
        name: "test".into(),
        frames: frames
            .into_iter()
            .enumerate()
            .map(|(i, (g, t))| (i as u64 * 100_000_000, g, t))
            .collect(),
    }
}

fn params(classes: &[&str]) -> KittiParams {
    KittiParams {
        classes: classes.iter().map(|s| s.to_string()).collect(),
        ..KittiParams::default()
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

/// Track boxes without a 2D box (a log not imported from KITTI) cannot be ignored by the 2D
/// rules: an unmatched one is a false positive, and a note says how many rows had none.
#[test]
fn tracks_without_image_boxes_are_not_ignored_by_the_2d_rules() {
    let truth = vec![gt(0, "Car", 10.0, 0, 0), dontcare(IMG)];
    let flat = |b: LabelledBox| LabelledBox {
        image_box: None,
        ..b
    };
    let tracks = vec![
        flat(trk(1, "Car", 10.0, 1.0, IMG)),
        flat(trk(2, "Car", 50.0, 1.0, IMG)),
        flat(trk(3, "Van", 70.0, 1.0, IMG)),
    ];
    let r = evaluate(&[scene(vec![(truth, tracks)])], &params(&["car"]));
    let m = &r.classes["car"];
    assert_eq!((m.tp, m.fp, m.ignored_tracker), (1, 1, 1), "{m:?}");
    let note = r.notes.iter().find(|n| n.contains("no 2D image box"));
    assert!(
        note.is_some_and(|n| n.starts_with("car: 3 of 3 track boxes")),
        "{:?}",
        r.notes
    );
    // With 2D boxes inside the DontCare region the same unmatched tracks are ignored.
    let truth = vec![gt(0, "Car", 10.0, 0, 0), dontcare(IMG)];
    let tracks = vec![trk(1, "Car", 10.0, 1.0, IMG), trk(2, "Car", 50.0, 1.0, IMG)];
    let r = evaluate(&[scene(vec![(truth, tracks)])], &params(&["car"]));
    assert_eq!(r.classes["car"].fp, 0);
    assert!(r.notes.iter().all(|n| !n.contains("no 2D image box")));
}

#[test]
fn ignore_rules_for_ground_truth_and_tracks() {
    // One frame, Car evaluation.
    let truth = vec![
        gt(0, "Car", 10.0, 0, 0),   // A: matched by 1 -> TP
        gt(1, "Car", 20.0, 1, 0),   // B: truncated, missed -> ignored FN
        gt(2, "Car", 30.0, 0, 3),   // C: occluded, matched by 2 -> ignored TP
        gt(3, "Van", 40.0, 0, 0),   // D: neighbouring class, missed -> ignored FN
        gt(4, "Car", 50.0, 0, 0),   // E: missed -> FN
        gt(5, "Truck", 60.0, 0, 0), // not loaded at all
        dontcare([500.0, 100.0, 700.0, 300.0]),
    ];
    let tracks = vec![
        trk(1, "Car", 10.0, 1.0, IMG),
        trk(2, "Car", 30.0, 1.0, IMG),
        // Van in a Car evaluation, unmatched: ignored.
        trk(3, "Van", 70.0, 1.0, IMG),
        // 2D box exactly 25 px high: ignored.
        trk(4, "Car", 80.0, 1.0, [100.0, 100.0, 200.0, 125.0]),
        // 2D box inside the DontCare region: ignored.
        trk(5, "Car", 90.0, 1.0, [550.0, 150.0, 650.0, 250.0]),
        // Exactly half inside the DontCare region: not ignored -> FP.
        trk(6, "Car", 100.0, 1.0, [600.0, 100.0, 800.0, 300.0]),
        // An ordinary false positive.
        trk(7, "Car", 110.0, 1.0, IMG),
        // A truck track is not loaded in the Car evaluation.
        trk(8, "Truck", 120.0, 1.0, IMG),
    ];
    let r = evaluate(&[scene(vec![(truth, tracks)])], &params(&["car"]));
    let m = &r.classes["car"];
    assert_eq!(m.gt_objects, 5);
    assert_eq!(m.ignored_gt, 3);
    assert_eq!(m.tp, 2, "TP includes the ignored match of C");
    assert_eq!(m.itp, 1);
    assert_eq!(m.fn_, 1);
    assert_eq!(m.ifn, 2);
    assert_eq!(m.fp, 2);
    assert_eq!(m.ignored_tracker, 3);
    assert_eq!(m.tracker_objects, 7);
    assert_eq!(m.tracker_trajectories, 7);
    assert_eq!(
        m.gt_trajectories, 5,
        "the van's trajectory is loaded (and ignored)"
    );
    assert_eq!((m.ids, m.frag), (0, 0));
    // MOTA over the two ground truths that count (A, E): 1 - (FN 1 + FP 2) / 2.
    assert!(close(m.mota, -0.5));
    assert!(close(m.motp, IOU));
    assert!(close(m.recall, 2.0 / 3.0));
    assert!(close(m.precision, 0.5));
    // FP per devkit frame (one frame + the devkit's extra one).
    assert!(close(m.far, 1.0));
    // MT: A; ML: E; B, C, D are wholly ignored.
    assert!(close(m.mt, 0.5) && close(m.ml, 0.5) && close(m.pt, 0.0));
    // One recall point (scores [1, 1], 3 positives): MOTA -0.5 there, sMOTA clipped to 0,
    // and no positive MOTA, so the "best" threshold stays at -10000.
    assert_eq!(m.curve.len(), 1);
    assert!(close(m.curve[0].recall_point, 0.025));
    assert!(close(m.samota, 0.0));
    assert!(close(m.amota, -0.5 / 40.0));
    assert!(close(m.amotp, IOU / 40.0));
    assert_eq!(m.best_threshold, -10000.0);
}

#[test]
fn pedestrian_neighbour_and_cyclist_rows() {
    let truth = vec![
        gt(0, "Pedestrian", 10.0, 0, 0),
        gt(1, "Person_sitting", 20.0, 0, 0),
        gt(2, "Cyclist", 30.0, 0, 0),
    ];
    let tracks = vec![
        trk(1, "Pedestrian", 10.0, 1.0, IMG),
        trk(2, "Person_sitting", 50.0, 1.0, IMG), // ignored in Pedestrian
        trk(3, "Cyclist", 30.0, 1.0, IMG),
        trk(4, "Van", 70.0, 1.0, IMG), // loaded by neither
    ];
    let r = evaluate(
        &[scene(vec![(truth, tracks)])],
        &params(&["pedestrian", "cyclist"]),
    );
    let p = &r.classes["pedestrian"];
    assert_eq!((p.tp, p.fp, p.fn_, p.ifn), (1, 0, 0, 1));
    assert_eq!((p.gt_objects, p.ignored_gt, p.ignored_tracker), (2, 1, 1));
    assert!(close(p.mota, 1.0));
    let c = &r.classes["cyclist"];
    assert_eq!(
        (c.tp, c.fp, c.fn_, c.gt_objects, c.tracker_objects),
        (1, 0, 0, 1, 1)
    );
    // Overall: mean of the ratios, sum of the counts.
    assert_eq!(r.overall.tp, 2);
    assert!(close(r.overall.mota, 1.0));
    assert!(close(r.overall.samota, (p.samota + c.samota) / 2.0));
}

#[test]
fn id_switches_and_fragmentations_along_trajectories() {
    let f = |g: Vec<LabelledBox>, t: Vec<LabelledBox>| (g, t);
    let frames = vec![
        f(
            vec![
                gt(0, "Car", 10.0, 0, 0),
                gt(1, "Car", 20.0, 0, 0),
                gt(2, "Car", 30.0, 0, 0),
                gt(3, "Car", 40.0, 0, 0),
            ],
            vec![
                trk(1, "Car", 10.0, 1.0, IMG),
                trk(3, "Car", 20.0, 1.0, IMG),
                trk(4, "Car", 30.0, 1.0, IMG),
                trk(6, "Car", 40.0, 1.0, IMG),
            ],
        ),
        f(
            vec![
                gt(0, "Car", 10.0, 0, 0),
                gt(1, "Car", 20.0, 0, 0),
                gt(2, "Car", 30.0, 0, 0),
                gt(3, "Car", 40.0, 0, 3), // occluded: an ignored frame
            ],
            vec![
                trk(1, "Car", 10.0, 1.0, IMG),
                trk(3, "Car", 20.0, 1.0, IMG),
                trk(6, "Car", 40.0, 1.0, IMG),
            ],
        ),
        f(
            vec![
                gt(0, "Car", 10.0, 0, 0),
                gt(1, "Car", 20.0, 0, 0),
                gt(2, "Car", 30.0, 0, 0),
                gt(3, "Car", 40.0, 0, 0),
            ],
            vec![
                trk(2, "Car", 10.0, 1.0, IMG),
                trk(5, "Car", 30.0, 1.0, IMG),
                trk(7, "Car", 40.0, 1.0, IMG),
            ],
        ),
        f(
            vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Car", 20.0, 0, 0)],
            vec![trk(2, "Car", 10.0, 1.0, IMG), trk(3, "Car", 20.0, 1.0, IMG)],
        ),
    ];
    let r = evaluate(&[scene(frames)], &params(&["car"]));
    let m = &r.classes["car"];
    // GT 0: tracks [1, 1, 2, 2] -> 1 switch, 1 fragmentation.
    // GT 1: [3, 3, -, 3] -> a gap: 1 fragmentation, no switch.
    // GT 2: [4, -, 5] -> a new id after a gap: a fragmentation but no switch.
    // GT 3: [6, 6 (ignored), 7] -> a new id after an ignored frame: a fragmentation only.
    assert_eq!(m.ids, 1);
    assert_eq!(m.frag, 4);
    assert_eq!((m.tp, m.itp, m.fn_, m.fp), (12, 1, 2, 0));
    // 13 ground truths count: MOTA = 1 - (FN 2 + FP 0 + IDS 1) / 13.
    assert!(close(m.mota, 10.0 / 13.0));
    // Coverage: GT 0 4/4 and GT 3 2/2 mostly tracked; GT 1 3/4 and GT 2 2/3 partly.
    assert!(close(m.mt, 0.5) && close(m.pt, 0.5) && close(m.ml, 0.0));
    assert_eq!(m.best_threshold, 1.0);
    // Twelve equal scores over 14 positives: every match is a recall point, the first
    // dropped, so 11 points with sMOTA 1 (MOTA 10/13 is above every point's recall).
    assert_eq!(m.curve.len(), 11);
    assert!(close(m.samota, 11.0 / 40.0));
    assert!(close(m.amota, 11.0 * (10.0 / 13.0) / 40.0));
}

#[test]
fn ids_repeated_in_another_log_are_other_objects() {
    // Two logs whose ids both start at 0: GT 0 and 1 in each, track 1 on GT 0 in the first
    // log (score 0.9) and on GT 1 in the second (score 0.1). Four trajectories, two mostly
    // tracked and two mostly lost; each track's mean score is its own log's.
    let frames = |tracked: i64, score: f64| -> Vec<(Vec<LabelledBox>, Vec<LabelledBox>)> {
        (0..4)
            .map(|_| {
                let x = if tracked == 0 { 10.0 } else { 20.0 };
                (
                    vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Car", 20.0, 0, 0)],
                    vec![trk(1, "Car", x, score, IMG)],
                )
            })
            .collect()
    };
    let r = evaluate(
        &[scene(frames(0, 0.9)), scene(frames(1, 0.1))],
        &params(&["car"]),
    );
    let m = &r.classes["car"];
    assert_eq!((m.tp, m.fn_, m.ids, m.frag), (8, 8, 0, 0));
    assert!(close(m.mt, 0.5) && close(m.ml, 0.5) && close(m.pt, 0.0));
    assert!(close(m.best_threshold, 0.1), "{}", m.best_threshold);
}

#[test]
fn the_reference_re_averaging_can_drop_a_track_at_its_own_mean() {
    // One ground truth in six frames, matched by track 1 scoring 0.1 five times and 0.35 once.
    // Its mean m = 0.14166666666666666 is every threshold; six copies of m add up to a sum
    // whose sixth is one ulp lower, so the reference (which re-averages at every threshold)
    // drops the track at all five points. Averaged once, it is kept: sMOTA 1 at each.
    let frames: Vec<_> = [0.1, 0.1, 0.1, 0.1, 0.1, 0.35]
        .iter()
        .map(|&s| {
            (
                vec![gt(0, "Car", 10.0, 0, 0)],
                vec![trk(1, "Car", 10.0, s, IMG)],
            )
        })
        .collect();
    let scenes = [scene(frames)];
    let reference = evaluate(&scenes, &params(&["car"]));
    let m = &reference.classes["car"];
    let mean = m.curve[0].threshold;
    assert_eq!(mean, (0.1 * 5.0 + 0.35) / 6.0);
    assert!((mean * 6.0) / 6.0 == mean && (0..6).map(|_| mean).sum::<f64>() / 6.0 < mean);
    assert_eq!(m.curve.len(), 5);
    assert!(m.curve.iter().all(|c| c.threshold == mean && c.tp == 0));
    assert!(
        m.samota < 1e-12 && m.drift_points == 5,
        "{} {}",
        m.samota,
        m.drift_points
    );
    assert!(close(m.samota_means_once, 5.0 / 40.0));
    let note = &reference.notes[0];
    assert!(
        note.contains("at 5 of 5 recall points") && note.contains("0.1250"),
        "{note}"
    );

    // Averaged once, or re-averaged with Python 3.12's compensated sum (six copies of m add
    // up to 6m there, whose sixth is m), the track is kept.
    for means in [MeanScores::Once, MeanScores::EveryPassCompensated] {
        let r = evaluate(
            &scenes,
            &KittiParams {
                means,
                ..params(&["car"])
            },
        );
        let m = &r.classes["car"];
        assert!(m.curve.iter().all(|c| c.tp == 6), "{means:?}");
        assert!(close(m.samota, 5.0 / 40.0), "{means:?}");
        assert_eq!(m.drift_points, 0, "{means:?}");
        assert!(r.notes.is_empty(), "{means:?}: {:?}", r.notes);
    }
}

/// `tests/fixtures/eval/python_sum_means.json`, written by `scripts/python_sum_means.py`
/// under real Python interpreters: score lists, and per Python version the means the
/// reference's re-averaging gives after each pass.
#[derive(serde::Deserialize)]
struct PythonSumFixture {
    passes: usize,
    inputs: Vec<FixtureScores>,
    /// Per version ("3.11"), per score list: runs of `[repr(mean), passes]`.
    means: BTreeMap<String, Vec<Vec<(String, usize)>>>,
}

/// Scores `k / d`, one correctly rounded division each, as the script makes them.
#[derive(serde::Deserialize)]
struct FixtureScores {
    d: i64,
    k: Vec<i64>,
}

/// The mean of each score list after each of `passes` re-averagings, as `average_scores`
/// computes them for one scene holding every list as a track (their rows interleaved frame
/// by frame, each track's in its own order).
fn reaveraged(inputs: &[FixtureScores], passes: usize, compensated: bool) -> Vec<Vec<f64>> {
    let mut rows = Vec::new();
    let longest = inputs.iter().map(|c| c.k.len()).max().unwrap_or(0);
    for i in 0..longest {
        for (slot, case) in inputs.iter().enumerate() {
            if let Some(&k) = case.k.get(i) {
                rows.push(tracks::TrObj {
                    id: slot as i64,
                    slot: slot as u32,
                    ignorable: false,
                    score: k as f64 / case.d as f64,
                    valid: false,
                    kept: false,
                });
            }
        }
    }
    let n_rows = rows.len() as u32;
    let mut seq = SeqTracks {
        rows,
        row_start: vec![0, n_rows],
        edges: Vec::new(),
        edge_start: vec![0, 0],
        n_tracks: inputs.len(),
    };
    let mut per_case = vec![Vec::with_capacity(passes); inputs.len()];
    let mut sums = Vec::new();
    for _ in 0..passes {
        pass::average_scores(&mut seq, &mut sums, compensated);
        let mut seen = vec![false; inputs.len()];
        for row in &seq.rows {
            let slot = row.slot as usize;
            if !std::mem::replace(&mut seen[slot], true) {
                per_case[slot].push(row.score);
            }
        }
    }
    per_case
}

#[test]
fn every_pass_means_equal_pythons_sum() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/eval/python_sum_means.json"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let fixture: PythonSumFixture = serde_json::from_str(&text).unwrap();
    let left_to_right = reaveraged(&fixture.inputs, fixture.passes, false);
    let compensated = reaveraged(&fixture.inputs, fixture.passes, true);
    // The two sums must differ on the fixture, or it could not tell them apart.
    assert!(left_to_right != compensated);
    let (mut old, mut new) = (0, 0);
    for (version, cases) in &fixture.means {
        let minor: u32 = version.strip_prefix("3.").unwrap().parse().unwrap();
        let ours = if minor >= 12 {
            &compensated
        } else {
            &left_to_right
        };
        *(if minor >= 12 { &mut new } else { &mut old }) += 1;
        assert_eq!(cases.len(), fixture.inputs.len(), "Python {version}");
        for (case, (runs, means)) in cases.iter().zip(ours).enumerate() {
            let expanded: Vec<f64> = runs
                .iter()
                .flat_map(|(mean, n)| std::iter::repeat_n(mean.parse::<f64>().unwrap(), *n))
                .collect();
            let same = expanded.len() == means.len()
                && expanded
                    .iter()
                    .zip(means)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "Python {version}, score list {case}: {runs:?} vs {means:?}"
            );
        }
    }
    assert!(
        old >= 1 && new >= 1,
        "the fixture needs Python <= 3.11 and >= 3.12"
    );
}

#[test]
fn whole_trajectories_are_filtered_by_their_mean_score() {
    // GT 0 in four frames, matched by track 1 with scores averaging 0.5 (one box below);
    // GT 1 in the first two frames, matched by track 3 (mean 0.125); track 2 is a false
    // positive in every frame (mean 0.25).
    let s1 = [0.75, 0.5, 0.25, 0.5];
    let frames: Vec<_> = (0..4)
        .map(|i| {
            let mut g = vec![gt(0, "Car", 10.0, 0, 0)];
            let mut t = vec![
                trk(1, "Car", 10.0, s1[i], IMG),
                trk(2, "Car", 50.0, 0.25, IMG),
            ];
            if i < 2 {
                g.push(gt(1, "Car", 20.0, 0, 0));
                t.push(trk(3, "Car", 20.0, 0.125, IMG));
            }
            (g, t)
        })
        .collect();
    let r = evaluate(&[scene(frames)], &params(&["car"]));
    let m = &r.classes["car"];
    // Matched scores: 0.5 x4, 0.125 x2 over 6 positives -> the recall walk takes
    // [0.5, 0.5, 0.5, 0.5, 0.125, 0.125] and drops the first.
    let th: Vec<f64> = m.curve.iter().map(|c| c.threshold).collect();
    assert_eq!(th, vec![0.5, 0.5, 0.5, 0.125, 0.125]);
    let rec: Vec<f64> = m.curve.iter().map(|c| c.recall_point).collect();
    for (a, b) in rec.iter().zip([0.025, 0.05, 0.075, 0.1, 0.125]) {
        assert!(close(*a, b));
    }
    // At 0.5 track 1 is kept whole (4 TP; its 0.25 box too), tracks 2 and 3 dropped.
    let c = &m.curve[0];
    assert_eq!((c.tp, c.fp, c.fn_), (4, 0, 2));
    assert!(close(c.mota, 1.0 - 2.0 / 6.0));
    // At 0.125 everything is kept: 4 false positives.
    let c = &m.curve[3];
    assert_eq!((c.tp, c.fp, c.fn_), (6, 4, 0));
    assert!(close(c.mota, 1.0 - 4.0 / 6.0));
    // Means of 0.5, 0.25 and 0.125 survive the re-averaging exactly: no drift reported.
    assert_eq!((m.drift_points, m.samota_means_once), (0, m.samota));
    assert!(r.notes.is_empty(), "{:?}", r.notes);
    // Best MOTA at 0.5.
    assert_eq!(m.best_threshold, 0.5);
    assert_eq!((m.tp, m.fp, m.fn_, m.tracker_objects), (4, 0, 2, 4));
    assert!(close(m.mt, 0.5) && close(m.ml, 0.5));
    // sMOTA is 1 at the five low recall points; the 35 points never reached count 0.
    assert!(close(m.samota, 5.0 / 40.0));
    assert!(close(
        m.amota,
        (3.0 * (4.0 / 6.0) + 2.0 * (2.0 / 6.0)) / 40.0
    ));
}

#[test]
fn a_class_without_tracks_is_not_evaluated() {
    let frames = vec![(
        vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Pedestrian", 20.0, 0, 0)],
        vec![trk(1, "Car", 10.0, 1.0, IMG)],
    )];
    let r = evaluate(&[scene(frames)], &KittiParams::default());
    assert_eq!(r.classes.keys().collect::<Vec<_>>(), vec!["car"]);
    assert_eq!(r.notes.len(), 2, "{:?}", r.notes);
    assert_eq!(r.overall.tp, 1);
}

#[test]
fn a_class_without_ground_truth_is_left_out_of_overall() {
    // A cyclist track but no cyclist: the class is evaluated (as the reference does), with
    // MOTA -inf, but the overall numbers are those of Car alone.
    let frames = vec![(
        vec![gt(0, "Car", 10.0, 0, 0)],
        vec![
            trk(1, "Car", 10.0, 1.0, IMG),
            trk(2, "Cyclist", 40.0, 1.0, IMG),
        ],
    )];
    let r = evaluate(&[scene(frames)], &params(&["car", "cyclist"]));
    let c = &r.classes["cyclist"];
    assert_eq!(c.mota, f64::NEG_INFINITY);
    assert_eq!((c.fp, c.samota), (1, 0.0));
    let car_alone = KittiMetrics::overall([&r.classes["car"]].into_iter());
    assert_eq!(
        serde_json::to_value(&r.overall).unwrap(),
        serde_json::to_value(&car_alone).unwrap()
    );
    assert!(r.notes[0].contains("left out of overall"), "{:?}", r.notes);
    let json = serde_json::to_value(&r).unwrap();
    assert!(json["classes"]["cyclist"]["MOTA"].is_null());
}

#[test]
fn duplicate_track_ids_in_a_frame_skip_the_class() {
    let frames = vec![(
        vec![gt(0, "Car", 10.0, 0, 0)],
        vec![trk(1, "Car", 10.0, 1.0, IMG), trk(1, "Car", 30.0, 1.0, IMG)],
    )];
    let r = evaluate(&[scene(frames)], &params(&["car"]));
    assert!(r.classes.is_empty());
    assert!(r.notes[0].contains("twice"), "{:?}", r.notes);
}

#[test]
fn iou_threshold_gates_matches() {
    // Shifted by 2 m along the 4 m length and 0.25 m across: IoU = 3.5 / (16 - 3.5).
    let frames = vec![(
        vec![gt(0, "Car", 10.0, 0, 0)],
        vec![trk(1, "Car", 11.5, 1.0, IMG)],
    )];
    let s = [scene(frames)];
    let m = &evaluate(&s, &params(&["car"])).classes["car"];
    assert_eq!((m.tp, m.fp, m.fn_), (1, 0, 0));
    assert!((m.motp - 0.28).abs() < 1e-12);
    let strict = KittiParams {
        min_overlap: 0.5,
        ..params(&["car"])
    };
    let m = &evaluate(&s, &strict).classes["car"];
    assert_eq!((m.tp, m.fp, m.fn_), (0, 1, 1));
}

#[test]
fn thresholds_walk_the_recall_points() {
    let (th, rec) = thresholds(&[1.0, 1.0], 3, 40);
    assert_eq!(th, vec![1.0]);
    assert_eq!(rec, vec![0.025]);
    // Forty matches of 400 positives: a point (every 10 matches) is taken at the score
    // whose recall is the closest to it, the 10th, 20th, 30th and 40th highest.
    let scores: Vec<f64> = (0..40).map(|i| i as f64).collect();
    let (th, rec) = thresholds(&scores, 400, 40);
    assert_eq!(th, vec![30.0, 20.0, 10.0, 0.0]);
    assert!(close(rec[3], 0.1));
    assert!(thresholds(&[], 0, 40).0.is_empty());
}

fn brute_force(cost: &[f64], n: usize) -> f64 {
    fn go(cost: &[f64], n: usize, row: usize, used: &mut Vec<bool>) -> f64 {
        if row == n {
            return 0.0;
        }
        let mut best = f64::INFINITY;
        for j in 0..n {
            if !used[j] {
                used[j] = true;
                best = best.min(cost[row * n + j] + go(cost, n, row + 1, used));
                used[j] = false;
            }
        }
        best
    }
    go(cost, n, 0, &mut vec![false; n])
}

#[test]
fn munkres_finds_minimum_cost_assignments() {
    // Deterministic pseudo-random square matrices with ties and forbidden pairs.
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as f64 / (1u64 << 31) as f64
    };
    for n in 1..=5 {
        for _ in 0..50 {
            let cost: Vec<f64> = (0..n * n)
                .map(|_| {
                    let v = next();
                    if v > 0.8 {
                        MAX_COST
                    } else {
                        (v * 8.0).floor() / 8.0
                    }
                })
                .collect();
            let pairs = munkres(&cost, n, n);
            assert_eq!(pairs.len(), n);
            let total: f64 = pairs.iter().map(|&(i, j)| cost[i * n + j]).sum();
            assert_eq!(total, brute_force(&cost, n), "{cost:?}");
        }
    }
    // Rectangular: the classic example, padded with zeros.
    let c = [
        400.0, 150.0, 400.0, 1.0, 400.0, 450.0, 600.0, 2.0, 300.0, 225.0, 300.0, 3.0,
    ];
    let pairs = munkres(&c, 3, 4);
    assert_eq!(pairs, vec![(0, 1), (1, 3), (2, 2)]);
    assert!(munkres(&[], 0, 3).is_empty());
}

#[test]
fn munkres_takes_every_feasible_pair_that_competes_with_none() {
    // The shortcut of `pass::select_pairs`: when no row and no column has two feasible pairs,
    // the reference's Munkres matches exactly the feasible pairs (the others at MAX_COST).
    let mut state = 987654321u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as f64 / (1u64 << 31) as f64
    };
    for (rows, cols) in [(1, 1), (3, 3), (4, 7), (7, 4), (12, 20), (20, 12), (30, 30)] {
        for _ in 0..40 {
            let mut cost = vec![MAX_COST; rows * cols];
            let mut feasible = Vec::new();
            let mut used_col = vec![false; cols];
            for r in 0..rows {
                let c = (next() * cols as f64) as usize % cols;
                if next() < 0.7 && !used_col[c] {
                    used_col[c] = true;
                    // Costs as the evaluation has them: 1 - IoU, at most 1 - 0.25.
                    cost[r * cols + c] = 0.75 * next();
                    feasible.push((r, c));
                }
            }
            let got: Vec<(usize, usize)> = munkres(&cost, rows, cols)
                .into_iter()
                .filter(|&(r, c)| cost[r * cols + c] < MAX_COST)
                .collect();
            assert_eq!(got, feasible, "{rows}x{cols}");
        }
    }
}
