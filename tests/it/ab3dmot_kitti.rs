//! The `ab3dmot-kitti` preset against AB3DMOT itself, on the ten KITTI tracking train sequences
//! of `../shared/data/kitti-tracking-train` (PointRCNN detections).
//!
//! AB3DMOT's own output on these sequences and its scores by its own evaluator are in
//! `../shared/data/ab3dmot-kitti-train/` (its README says how they were made). Checked here:
//! - `track --preset ab3dmot-kitti`, exported, writes the same rows as AB3DMOT (frame, class, box
//!   to 1e-3 m / 1e-3 rad, score to 1e-6) for at least 99.9 % of AB3DMOT's rows, with no more
//!   than 0.1 % rows of its own, and track ids equal up to a one-to-one renaming;
//! - AB3DMOT's results imported with `import kitti --tracks` and scored by
//!   `eval --protocol kitti` give the scores of that README (counts equal, ratios to 1e-4), and
//!   so do probmot's tracks; `eval --baseline` reads the imported channel.

use crate::common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::common::{probmot, probmot_ok, skip};
use serde_json::Value;

const SEQUENCES: [&str; 10] = [
    "0000", "0002", "0003", "0004", "0005", "0007", "0009", "0011", "0017", "0020",
];

/// AB3DMOT's scores on the ten sequences by its own evaluator (3D IoU 0.25), from the table of
/// `../shared/data/ab3dmot-kitti-train/README.md`, in percent:
/// `(class, sAMOTA, AMOTA, MOTA, MOTP, IDS, FRAG, FP, FN)`.
type ClassScores = (&'static str, f64, f64, f64, f64, u64, u64, u64, u64);
const AB3DMOT_SCORES: [ClassScores; 3] = [
    ("car", 87.75, 40.39, 78.33, 79.00, 0, 33, 747, 2654),
    ("pedestrian", 57.30, -18.43, 59.61, 56.46, 1, 6, 78, 455),
    ("cyclist", 53.10, 19.77, 34.83, 68.83, 0, 0, 17, 316),
];

fn shared(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(rel)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// One row of a KITTI tracking result: frame, id, type, `h w l x y z rotation_y`, score.
#[derive(Debug, Clone)]
struct Row {
    frame: u32,
    id: i64,
    kind: String,
    bx: [f64; 7],
    score: f64,
}

fn read_rows(path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            assert_eq!(f.len(), 18, "{}: {l}", path.display());
            let num = |i: usize| f[i].parse::<f64>().unwrap();
            Row {
                frame: f[0].parse().unwrap(),
                id: f[1].parse().unwrap(),
                kind: f[2].to_string(),
                bx: std::array::from_fn(|i| num(10 + i)),
                score: num(17),
            }
        })
        .collect()
}

/// The angle difference wrapped to `[-pi, pi)`: both files wrap rotation_y, but a value at the
/// seam may be written as `-pi + e` by one and `pi - e` by the other.
fn angle_diff(a: f64, b: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    (a - b + PI).rem_euclid(TAU) - PI
}

fn same_row(a: &Row, b: &Row) -> bool {
    a.bx[..6]
        .iter()
        .zip(&b.bx[..6])
        .all(|(x, y)| (x - y).abs() <= 1e-3)
        && angle_diff(a.bx[6], b.bx[6]).abs() <= 1e-3
        && (a.score - b.score).abs() <= 1e-6 + 1e-9
}

/// Counts of one sequence's comparison.
#[derive(Debug, Default)]
struct Compared {
    reference: usize,
    ours: usize,
    equal: usize,
    id_conflicts: Vec<String>,
}

/// Pairs each reference row with an equal row of ours (same frame and type), and checks that
/// the pairs' ids form a one-to-one renaming.
fn compare(reference: &[Row], ours: &[Row]) -> Compared {
    let mut by_frame: HashMap<(u32, &str), Vec<(usize, &Row)>> = HashMap::new();
    for (i, r) in ours.iter().enumerate() {
        by_frame
            .entry((r.frame, r.kind.as_str()))
            .or_default()
            .push((i, r));
    }
    let mut used = vec![false; ours.len()];
    let (mut fwd, mut bwd) = (HashMap::new(), HashMap::new());
    let mut c = Compared {
        reference: reference.len(),
        ours: ours.len(),
        ..Default::default()
    };
    for r in reference {
        let candidates = by_frame
            .get(&(r.frame, r.kind.as_str()))
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        let Some(&(i, o)) = candidates.iter().find(|(i, o)| !used[*i] && same_row(r, o)) else {
            continue;
        };
        used[i] = true;
        c.equal += 1;
        if *fwd.entry(r.id).or_insert(o.id) != o.id || *bwd.entry(o.id).or_insert(r.id) != r.id {
            c.id_conflicts.push(format!(
                "frame {} {}: AB3DMOT id {} is probmot id {}, but the renaming says {:?} / {:?}",
                r.frame,
                r.kind,
                r.id,
                o.id,
                fwd.get(&r.id),
                bwd.get(&o.id)
            ));
        }
    }
    c
}

/// `eval --protocol kitti --json` of a directory of logs: the per-class results.
fn kitti_scores(truth: &Path, tracks: Option<&Path>) -> Value {
    let mut args = vec!["eval", "--protocol", "kitti", "--truth", s(truth), "--json"];
    if let Some(t) = tracks {
        args.extend(["--tracks", s(t)]);
    }
    let out = probmot_ok(&args);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v["result"]["classes"].clone()
}

/// Checks per-class scores against AB3DMOT's table: counts equal, ratios to the table's 1e-4
/// (the table gives percent with two decimals).
fn check_scores(what: &str, classes: &Value, errors: &mut Vec<String>) {
    for (class, samota, amota, mota, motp, ids, frag, fp, fn_) in AB3DMOT_SCORES {
        let m = &classes[class];
        for (key, want) in [
            ("sAMOTA", samota),
            ("AMOTA", amota),
            ("MOTA", mota),
            ("MOTP", motp),
        ] {
            let got = m[key].as_f64().unwrap_or(f64::NAN);
            let within = (got - want / 100.0).abs() <= 0.5e-4 + 1e-12;
            if !within {
                errors.push(format!("{what} {class} {key}: {got:.6}, AB3DMOT {want}"));
            }
        }
        for (key, want) in [("IDS", ids), ("FRAG", frag), ("FP", fp), ("FN", fn_)] {
            let got = m[key].as_f64().map(|v| v as u64);
            if got != Some(want) {
                errors.push(format!("{what} {class} {key}: {got:?}, AB3DMOT {want}"));
            }
        }
    }
}

#[test]
fn ab3dmot_kitti_preset_gives_ab3dmots_tracks_and_scores() {
    let data = shared("kitti-tracking-train");
    let results = shared("ab3dmot-kitti-train/results");
    if !data.join("label_02").is_dir() || !results.is_dir() {
        skip(
            "ab3dmot_kitti_preset_gives_ab3dmots_tracks_and_scores",
            "no KITTI data at ../shared/data/kitti-tracking-train or no AB3DMOT results at \
             ../shared/data/ab3dmot-kitti-train/results beside the repository",
        );
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let ours_dir = tmp.path().join("probmot");
    let theirs_dir = tmp.path().join("ab3dmot");
    std::fs::create_dir_all(&ours_dir).unwrap();
    std::fs::create_dir_all(&theirs_dir).unwrap();

    // Each sequence: import, track, export; import AB3DMOT's results as a tracks channel.
    let compared: Vec<(&str, Compared)> = std::thread::scope(|scope| {
        let jobs: Vec<_> = SEQUENCES
            .iter()
            .map(|&seq| {
                let (data, results) = (&data, &results);
                let (ours_dir, theirs_dir) = (&ours_dir, &theirs_dir);
                scope.spawn(move || {
                    let label = data.join(format!("label_02/{seq}.txt"));
                    let theirs = results.join(format!("{seq}.txt"));
                    let input = tmp_path(ours_dir, seq, "input.mcap");
                    let tracked = ours_dir.join(format!("{seq}.mcap"));
                    let exported = tmp_path(ours_dir, seq, "txt");
                    common::import_kitti_sequence(data, seq, &input);
                    probmot_ok(&[
                        "track",
                        s(&input),
                        "-o",
                        s(&tracked),
                        "--quiet",
                        "--preset",
                        "ab3dmot-kitti",
                    ]);
                    probmot_ok(&["export", "kitti", s(&tracked), "-o", s(&exported)]);
                    probmot_ok(&[
                        "import",
                        "kitti",
                        "--labels",
                        s(&label),
                        "--tracks",
                        s(&theirs),
                        "-o",
                        s(&theirs_dir.join(format!("{seq}.mcap"))),
                    ]);
                    (seq, compare(&read_rows(&theirs), &read_rows(&exported)))
                })
            })
            .collect();
        jobs.into_iter().map(|j| j.join().unwrap()).collect()
    });
    std::fs::remove_dir_all(ours_dir.join("work")).unwrap();

    let (mut reference, mut ours, mut equal) = (0, 0, 0);
    let mut conflicts = Vec::new();
    for (seq, c) in &compared {
        eprintln!(
            "{seq}: AB3DMOT {} rows, probmot {} rows, {} equal",
            c.reference, c.ours, c.equal
        );
        reference += c.reference;
        ours += c.ours;
        equal += c.equal;
        conflicts.extend(c.id_conflicts.iter().map(|e| format!("{seq}: {e}")));
    }
    let share = equal as f64 / reference as f64;
    eprintln!(
        "all: AB3DMOT {reference} rows, probmot {ours}, equal {equal} ({:.3} %)",
        100.0 * share
    );
    assert!(
        reference > 40_000,
        "AB3DMOT's results hold {reference} rows"
    );
    assert!(share >= 0.999, "only {equal} of {reference} rows are equal");
    assert!(
        (ours - equal) as f64 <= 0.001 * reference as f64,
        "{} rows of probmot are not AB3DMOT's",
        ours - equal
    );
    assert!(
        conflicts.is_empty(),
        "ids differ:\n{}",
        conflicts.join("\n")
    );

    // Scores: AB3DMOT's imported results, and probmot's tracks, by probmot's KITTI evaluation.
    let mut errors = Vec::new();
    check_scores(
        "AB3DMOT imported",
        &kitti_scores(&theirs_dir, None),
        &mut errors,
    );
    check_scores(
        "probmot ab3dmot-kitti",
        &kitti_scores(&ours_dir, None),
        &mut errors,
    );
    assert!(errors.is_empty(), "{}", errors.join("\n"));

    // The imported channel works as a baseline: probmot's tracks are not worse than AB3DMOT's.
    let gate = probmot(&[
        "eval",
        "--protocol",
        "kitti",
        "--truth",
        s(&ours_dir.join("0000.mcap")),
        "--baseline",
        s(&theirs_dir.join("0000.mcap")),
        "--max-drop",
        "0",
        "--gate",
        "point",
    ]);
    assert_eq!(
        gate.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&gate.stdout)
    );
}

/// A scratch file of a sequence, outside the directory of tracked logs that `eval` reads.
fn tmp_path(ours_dir: &Path, seq: &str, ext: &str) -> PathBuf {
    let dir = ours_dir.join("work");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{seq}.{ext}"))
}

/// `import kitti --tracks` keeps a result file's rows: exporting the imported channel (here on a
/// topic of its own) writes the same ids, types, boxes and scores; rows without a score are
/// refused with the file and line.
#[test]
fn imported_results_export_unchanged() {
    let tmp = tempfile::tempdir().unwrap();
    let results = tmp.path().join("0001.txt");
    std::fs::write(
        &results,
        "0 0 Car 0 0 -1.5 100 120 200 220 1.5 1.6 3.9 -4.5 1.8 13.4 -2.1 0.95\n\
         0 7 Pedestrian 0 0 0.3 300 100 340 200 1.7 0.6 0.8 2.0 1.7 8.0 0.5 3.25\n\
         2 0 Car 0 0 -1.4 101 121 201 221 1.5 1.6 3.9 -4.4 1.8 12.9 -2.0 0.5\n",
    )
    .unwrap();
    let log = tmp.path().join("0001.mcap");
    probmot_ok(&[
        "import",
        "kitti",
        "--sequence",
        "0001",
        "--tracks",
        s(&results),
        "--tracks-topic",
        "/other",
        "-o",
        s(&log),
    ]);
    let out = tmp.path().join("out.txt");
    probmot_ok(&[
        "export",
        "kitti",
        s(&log),
        "--topic",
        "/other",
        "-o",
        s(&out),
    ]);
    let (a, b) = (read_rows(&results), read_rows(&out));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!((x.frame, x.id, &x.kind), (y.frame, y.id, &y.kind));
        assert!(
            x.bx.iter().zip(&y.bx).all(|(p, q)| (p - q).abs() < 1e-9),
            "{x:?} {y:?}"
        );
        assert_eq!(x.score, y.score);
    }

    let bad = tmp.path().join("bad.txt");
    std::fs::write(
        &bad,
        "0 0 Car 0 0 -1.5 100 120 200 220 1.5 1.6 3.9 -4.5 1.8 13.4 -2.1\n",
    )
    .unwrap();
    let r = probmot(&[
        "import",
        "kitti",
        "--sequence",
        "0001",
        "--tracks",
        s(&bad),
        "-o",
        s(&tmp.path().join("bad.mcap")),
    ]);
    assert_eq!(
        r.status.code(),
        Some(2),
        "a row without score must fail (status 2, errors)"
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("bad.txt") && err.contains("score"),
        "error names the file and the score: {err}"
    );
}
