//! `probmot eval`'s HOTA against the TrackEval package (`scripts/trackeval_crosscheck.py`):
//! - the nuScenes protocol (BEV centre-distance similarity) on the committed eval fixtures, whose
//!   `*.trackeval.json` files the script made (always runs; a second test regenerates them with
//!   TrackEval when it is installed and checks they are still what the script produces);
//! - the KITTI protocol (TrackEval's `Kitti2DBox`) on the KITTI train sequences of
//!   `../shared/data/kitti-tracking-train`, imported, tracked and exported by probmot, with
//!   TrackEval run live on the exported result files.
//!
//! HOTA, DetA, AssA, LocA (and the other means) and every per-alpha curve agree to 1e-6.

use crate::common;

use std::path::{Path, PathBuf};

use crate::common::{probmot_ok, python_has, repo, skip};
use serde_json::Value;

const NUSCENES_CLASSES: &str = "car,pedestrian,bicycle,bus,motorcycle,trailer,truck";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Compares TrackEval's classes with ours: the same classes, every mean and curve to 1e-6.
fn compare(what: &str, reference: &Value, ours: &Value, errors: &mut Vec<String>) {
    let (r, o) = (reference.as_object().unwrap(), ours.as_object().unwrap());
    let mut rk: Vec<_> = r.keys().collect();
    let mut ok: Vec<_> = o.keys().collect();
    rk.sort();
    ok.sort();
    if rk != ok {
        errors.push(format!(
            "{what}: classes {rk:?} (TrackEval) vs {ok:?} (ours)"
        ));
        return;
    }
    for (class, want) in r {
        let got = &o[class];
        for key in [
            "hota", "deta", "assa", "loca", "detre", "detpr", "assre", "asspr",
        ] {
            let (w, g) = (want[key].as_f64().unwrap(), got[key].as_f64().unwrap());
            if (w - g).abs() > 1e-6 {
                errors.push(format!("{what} {class} {key}: TrackEval {w}, ours {g}"));
            }
            let (wc, gc) = (
                want["curves"][key].as_array().unwrap(),
                got["curves"][key].as_array().unwrap(),
            );
            assert_eq!(wc.len(), 19, "{what}: TrackEval's alphas");
            assert_eq!(gc.len(), 19, "{what}: our alphas");
            for (i, (w, g)) in wc.iter().zip(gc).enumerate() {
                let (w, g) = (w.as_f64().unwrap(), g.as_f64().unwrap());
                if (w - g).abs() > 1e-6 {
                    errors.push(format!(
                        "{what} {class} {key}[alpha {i}]: TrackEval {w}, ours {g}"
                    ));
                }
            }
        }
        for key in ["tp", "fn", "fp"] {
            if want["curves"][key] != got["curves"][key] {
                errors.push(format!("{what} {class} {key} counts differ"));
            }
        }
    }
}

fn eval_json(args: &[&str]) -> Value {
    let out = probmot_ok(args);
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The eval fixtures with their TrackEval files: each alone, and all together.
fn fixture_runs() -> Vec<(String, Vec<PathBuf>, PathBuf)> {
    let dir = repo("tests/fixtures/eval");
    let mut runs = Vec::new();
    let mut all = Vec::new();
    for name in [
        "perfect",
        "false_positives",
        "gaps_multiclass",
        "idswitch_frag",
        "range_filter",
        "ties",
    ] {
        let mcap = dir.join(format!("{name}.mcap"));
        all.push(mcap.clone());
        runs.push((
            name.to_string(),
            vec![mcap],
            dir.join(format!("{name}.trackeval.json")),
        ));
    }
    runs.push((
        "all_fixtures".into(),
        all,
        dir.join("all_fixtures.trackeval.json"),
    ));
    runs
}

#[test]
fn nuscenes_hota_equals_trackeval_on_the_fixtures() {
    let mut errors = Vec::new();
    for (name, files, reference) in fixture_runs() {
        let reference: Value =
            serde_json::from_str(&std::fs::read_to_string(&reference).unwrap()).unwrap();
        let mut args = vec!["eval", "--json", "--truth"];
        args.extend(files.iter().map(|f| s(f)));
        let ours = eval_json(&args);
        assert_eq!(ours["hota"]["similarity"], "bev_centre_distance");
        compare(
            &name,
            &reference["classes"],
            &ours["hota"]["classes"],
            &mut errors,
        );
    }
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

#[test]
fn trackeval_fixtures_are_what_the_script_makes() {
    let test = "trackeval_fixtures_are_what_the_script_makes";
    if !python_has("trackeval, mcap_protobuf, numpy") {
        return skip(
            test,
            "python3 cannot import trackeval, mcap_protobuf and numpy",
        );
    }
    for (name, files, reference) in fixture_runs() {
        let mut cmd = std::process::Command::new("python3");
        cmd.arg(repo("scripts/trackeval_crosscheck.py"))
            .args(["centre", "--classes", NUSCENES_CLASSES, "--truth"])
            .args(&files);
        let out = cmd.output().unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let fresh: Value = serde_json::from_slice(&out.stdout).unwrap();
        let committed: Value =
            serde_json::from_str(&std::fs::read_to_string(&reference).unwrap()).unwrap();
        let mut errors = Vec::new();
        compare(&name, &fresh["classes"], &committed["classes"], &mut errors);
        assert!(errors.is_empty(), "{}", errors.join("\n"));
    }
}

fn kitti_data() -> Option<PathBuf> {
    let d = repo("../shared/data/kitti-tracking-train");
    d.join("label_02").is_dir().then_some(d)
}

#[test]
fn kitti_hota_equals_trackeval_on_the_train_sequences() {
    let test = "kitti_hota_equals_trackeval_on_the_train_sequences";
    let Some(data) = kitti_data() else {
        return skip(test, "no KITTI data at ../shared/data/kitti-tracking-train");
    };
    if !python_has("trackeval, numpy") {
        return skip(test, "python3 cannot import trackeval and numpy");
    }
    let mut seqs: Vec<String> = std::fs::read_dir(data.join("label_02"))
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "txt").then(|| p.file_stem().unwrap().to_string_lossy().into())
        })
        .collect();
    seqs.sort();
    assert!(!seqs.is_empty());
    let tmp = tempfile::tempdir().unwrap();
    let (tracked, results) = (tmp.path().join("tracked"), tmp.path().join("results"));
    std::fs::create_dir_all(&tracked).unwrap();
    std::fs::create_dir_all(&results).unwrap();
    for seq in &seqs {
        let input = tmp.path().join(format!("{seq}.mcap"));
        let out = tracked.join(format!("{seq}.mcap"));
        common::import_kitti_sequence(&data, seq, &input);
        probmot_ok(&["track", s(&input), "-o", s(&out), "--quiet"]);
        let result = results.join(format!("{seq}.txt"));
        probmot_ok(&["export", "kitti", s(&out), "-o", s(&result)]);
    }
    let out = std::process::Command::new("python3")
        .arg(repo("scripts/trackeval_crosscheck.py"))
        .args(["kitti", "--labels", s(&data.join("label_02"))])
        .args(["--results", s(&results), "--seqs", &seqs.join(",")])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "trackeval_crosscheck.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reference: Value = serde_json::from_slice(&out.stdout).unwrap();
    let ours = eval_json(&[
        "eval",
        "--protocol",
        "kitti",
        "--json",
        "--truth",
        s(&tracked),
    ]);
    let mut errors = Vec::new();
    compare(
        &format!("KITTI {} sequences", seqs.len()),
        &reference["classes"],
        &ours["hota"]["image_2d"],
        &mut errors,
    );
    assert!(errors.is_empty(), "{}", errors.join("\n"));
    // Not a vacuous comparison: the tracker finds most cars.
    let car = ours["hota"]["image_2d"]["car"]["hota"].as_f64().unwrap();
    assert!(car > 0.5, "car HOTA {car}");
}
