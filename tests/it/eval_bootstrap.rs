//! `eval --bootstrap`: the resampled metrics are the protocol's own on all the data, identical
//! runs change by exactly 0 with the interval [0, 0], a clearly worse run fails the interval
//! gate, and the intervals do not depend on the number of threads.

use std::path::Path;

use serde_json::Value;

use crate::common::{self, bin, probmot, probmot_ok, repo, skip};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json(args: &[&str]) -> Value {
    serde_json::from_slice(&probmot_ok(args).stdout).unwrap()
}

/// Checks that every metric's `this` (and `baseline`) of the bootstrap is the protocol's own
/// value on all the data, per class and overall.
fn check_values(v: &Value, names: &[(&str, &str)], base: bool) {
    let b = &v["bootstrap"];
    let rows = (b["classes"].as_object().unwrap().iter())
        .map(|(c, m)| {
            (
                m,
                &v["result"]["classes"][c],
                &v["baseline"]["result"]["classes"][c],
            )
        })
        .chain([(
            &b["overall"],
            &v["result"]["overall"],
            &v["baseline"]["result"]["overall"],
        )]);
    let mut n = 0;
    for (m, this, old) in rows {
        for (ours, theirs) in names {
            let close = |a: &Value, b: &Value| match (a.as_f64(), b.as_f64()) {
                (Some(a), Some(b)) => (a - b).abs() < 1e-9,
                (a, b) => a == b,
            };
            assert!(
                close(&m[ours]["this"], &this[theirs]),
                "{ours}: {m} vs {this}"
            );
            if base {
                assert!(
                    close(&m[ours]["baseline"], &old[theirs]),
                    "{ours}: {m} vs {old}"
                );
            }
            n += 1;
        }
    }
    assert!(n >= 8, "too few metrics compared: {n}");
}

/// Checks that the bootstrap's HOTA, DetA and AssA (`names`) of this run and the baseline are
/// exactly the HOTA tables' values (`hota`: the `hota` member of this run's and the baseline's
/// own evaluation; `group`: its member holding the classes), per class and overall (the mean
/// over the classes).
fn check_hota(v: &Value, hota: [&Value; 2], group: &str, names: [&str; 3]) {
    let b = &v["bootstrap"];
    for (run, side) in ["this", "baseline"].into_iter().zip(hota) {
        let table = side[group].as_object().unwrap();
        assert!(!table.is_empty(), "no HOTA class in {side}");
        for (k, field) in ["hota", "deta", "assa"].iter().enumerate() {
            let mut sum = 0.0;
            for (class, h) in table {
                let want = h[field].as_f64().unwrap();
                sum += want;
                let got = &b["classes"][class][names[k]][run];
                assert_eq!(got.as_f64(), Some(want), "{class} {field} {run}");
            }
            let overall = b["overall"][names[k]][run].as_f64().unwrap();
            assert_eq!(overall, sum / table.len() as f64, "overall {field} {run}");
        }
    }
}

/// Every interval of the bootstrap is [0, 0] and every change 0.
fn all_zero(b: &Value) {
    let rows = b["classes"]
        .as_object()
        .unwrap()
        .values()
        .chain([&b["overall"]]);
    for m in rows {
        for (name, c) in m.as_object().unwrap() {
            assert_eq!(c["delta"], 0.0, "{name}: {c}");
            assert_eq!(c["ci95"], serde_json::json!([0.0, 0.0]), "{name}: {c}");
        }
    }
}

#[test]
fn nuscenes_bootstrap_reuses_the_protocols_numbers_and_gates_on_the_interval() {
    let dir = tempfile::tempdir().unwrap();
    let (good, bad) = (dir.path().join("good.mcap"), dir.path().join("bad.mcap"));
    let city = repo("sample_logs/city.mcap");
    probmot_ok(&["track", s(&city), "-o", s(&good), "--quiet"]);
    let worse = ["--preset", "ab3dmot-2019"];
    probmot_ok(&[&["track", s(&city), "-o", s(&bad), "--quiet"][..], &worse].concat());
    let eval = [
        "eval",
        "--truth",
        s(&good),
        "--baseline",
        s(&bad),
        "--bootstrap",
        "200",
    ];
    let names = [
        ("amota", "amota"),
        ("amotp", "amotp"),
        ("mota", "mota"),
        ("ids", "ids"),
    ];
    let v = json(&[&eval[..], &["--block", "5", "--json"]].concat());
    check_values(&v, &names, true);
    assert_eq!(v["bootstrap"]["n_units"], 4, "20 s of frames in 5-s blocks");
    let base = json(&["eval", "--truth", s(&bad), "--json"]);
    check_hota(
        &v,
        [&v["hota"], &base["hota"]],
        "classes",
        ["hota", "deta", "assa"],
    );

    // Identical runs: no change, [0, 0], and the gate passes even at --max-drop 0.
    let same = [
        "eval",
        "--truth",
        s(&good),
        "--baseline",
        s(&good),
        "--max-drop",
        "0",
    ];
    let out = probmot(&[&same[..], &["--bootstrap", "100", "--json"]].concat());
    assert_eq!(out.status.code(), Some(0));
    all_zero(&serde_json::from_slice::<Value>(&out.stdout).unwrap()["bootstrap"]);

    // The worse run against the good one: a fall whose interval lies below 0 fails the gate
    // (with 1000 resamples when --bootstrap is not given).
    let gate = [
        "eval",
        "--truth",
        s(&bad),
        "--baseline",
        s(&good),
        "--max-drop",
        "1",
    ];
    let out = probmot(&[&gate[..], &["--block", "5", "--json"]].concat());
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["bootstrap"]["resamples"], 1000);
    assert!(
        v["bootstrap"]["overall"]["amota"]["ci95"][1]
            .as_f64()
            .unwrap()
            < 0.0
    );
    // The point rule fails it too.
    let point = probmot(&[&gate[..], &["--gate", "point"]].concat());
    assert_eq!(point.status.code(), Some(3));
}

#[test]
fn bootstrap_intervals_do_not_depend_on_the_threads() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.mcap");
    probmot_ok(&[
        "track",
        s(&repo("sample_logs/city.mcap")),
        "-o",
        s(&out),
        "--quiet",
    ]);
    let run = |threads: &str, seed: &str| {
        let args = [
            "eval",
            "--truth",
            s(&out),
            "--bootstrap",
            "300",
            "--seed",
            seed,
            "--json",
        ];
        let o = bin()
            .args(args)
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(o.status.success());
        serde_json::from_slice::<Value>(&o.stdout).unwrap()["bootstrap"].clone()
    };
    let one = run("1", "7");
    assert_eq!(one, run("2", "7"));
    assert_ne!(one, run("2", "8"), "another seed draws other resamples");
    let car = &one["classes"]["car"]["amota"];
    let (lo, hi) = (
        car["ci95"][0].as_f64().unwrap(),
        car["ci95"][1].as_f64().unwrap(),
    );
    assert!(lo < hi, "{car}");
    // HOTA has its interval too, around its value on all the data.
    let hota = &one["overall"]["hota"];
    let (v, lo, hi) = (
        hota["value"].as_f64().unwrap(),
        hota["ci95"][0].as_f64().unwrap(),
        hota["ci95"][1].as_f64().unwrap(),
    );
    assert!(lo < v && v < hi, "{hota}");
}

#[test]
fn kitti_bootstrap_reuses_the_protocols_numbers() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti-tracking-train");
    if !data.join("label_02").is_dir() {
        let why = "no KITTI data at ../shared/data/kitti-tracking-train beside the repository";
        skip("kitti_bootstrap_reuses_the_protocols_numbers", why);
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("0000.mcap");
    common::import_kitti_sequence(&data, "0000", &input);
    let (a, b) = (
        dir.path().join("a/0000.mcap"),
        dir.path().join("b/0000.mcap"),
    );
    for (out, preset) in [(&a, "kitti-pointrcnn"), (&b, "ab3dmot-kitti")] {
        std::fs::create_dir_all(out.parent().unwrap()).unwrap();
        probmot_ok(&[
            "track",
            s(&input),
            "-o",
            s(out),
            "--quiet",
            "--preset",
            preset,
        ]);
    }
    let eval = [
        "eval",
        "--protocol",
        "kitti",
        "--truth",
        s(&a),
        "--bootstrap",
        "100",
    ];
    let v = json(&[&eval[..], &["--baseline", s(&b), "--json"]].concat());
    let names = [("sAMOTA", "sAMOTA"), ("AMOTA", "AMOTA"), ("MOTA", "MOTA")];
    check_values(&v, &names, true);
    let base = json(&["eval", "--protocol", "kitti", "--truth", s(&b), "--json"]);
    let hota = [&v["hota"], &base["hota"]];
    check_hota(&v, hota, "image_2d", ["HOTA", "DetA", "AssA"]);
    check_hota(&v, hota, "iou_3d", ["HOTA_3d", "DetA_3d", "AssA_3d"]);
    let same = json(&[&eval[..], &["--baseline", s(&a), "--json"]].concat());
    all_zero(&same["bootstrap"]);
}
