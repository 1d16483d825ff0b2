//! `probmot fit` on simulated logs with known noise: it recovers each R diagonal within 10% and
//! Q within 20% of the simulator's truth.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use crate::common::*;
use probmot::sim::scenario::{class_profile, objects, Scenario, SimOptions};
use probmot::sim::sensor::sensor_model;
use probmot::tracker::TrackerConfig;
use serde_json::Value;

/// Two city logs (pooled by the fit), sized so that the rarest classes still get several
/// thousand matched pairs: the relative standard error of a variance from `n` Gaussian samples
/// is `sqrt(2 / n)`, about 2.5% at 3000 pairs, so the 10% tolerance is about 4 standard errors.
const SEEDS: [u64; 2] = [1, 2];
const FRAMES: u32 = 300;
const OBJECTS: u32 = 200;
/// `probmot simulate`'s default rate is 2 Hz: the data period equals the preset's dt_nominal
/// (0.5 s), so no time rescaling is involved here.
const RATE_HZ: f64 = 2.0;
/// Classes with fewer pairs are not checked.
const MIN_PAIRS: u64 = 1000;

fn sim_options(seed: u64) -> SimOptions {
    SimOptions {
        scenario: Scenario::City,
        seed,
        frames: FRAMES,
        objects: Some(OBJECTS),
        rate_hz: RATE_HZ,
        ego_frame: false,
    }
}

/// Simulates the logs in parallel (the binary, as a user would).
fn simulate_logs(dir: &Path) -> Vec<PathBuf> {
    let paths: Vec<PathBuf> = SEEDS
        .iter()
        .map(|s| dir.join(format!("city-{s}.mcap")))
        .collect();
    let children: Vec<_> = SEEDS
        .iter()
        .zip(&paths)
        .map(|(seed, path)| {
            bin()
                .args(["simulate", "--scenario", "city"])
                .args(["--seed", &seed.to_string()])
                .args(["--frames", &FRAMES.to_string()])
                .args(["--objects", &OBJECTS.to_string()])
                .args(["--rate", &RATE_HZ.to_string()])
                .arg("-o")
                .arg(path)
                .output()
        })
        .collect();
    for c in children {
        let out = c.expect("run probmot simulate");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    paths
}

/// The process-noise truth per class, from the scenario's own objects: `(number of triples of
/// consecutive frames, expected variance of the x (and y) second difference)`.
///
/// The city scenario (`scenario.rs`, fn `city`) integrates `pos += vel * dt` and then, for a
/// moving object, `vel += N(0, q_std)` per axis and frame (`q_std = class_profile(label).2`).
/// So `pos[k+1] - 2 pos[k] + pos[k-1] = (vel[k] - vel[k-1]) dt = w dt` with variance
/// `(q_std dt)^2`; parked objects (20%) never move, their second differences are 0. The pooled
/// (population) variance is therefore `(q_std dt)^2` times the fraction of triples from moving
/// objects (the mean is 0). z never changes: its Q is 0.
fn q_truth() -> BTreeMap<String, (u64, f64)> {
    let dt = 1.0 / RATE_HZ;
    let mut acc: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    for seed in SEEDS {
        for o in objects(&sim_options(seed)) {
            let parked = o
                .states
                .iter()
                .flatten()
                .all(|s| s.velocity == [0.0, 0.0, 0.0]);
            let triples = o
                .states
                .windows(3)
                .filter(|w| w.iter().all(Option::is_some))
                .count() as u64;
            let e = acc.entry(o.label.to_string()).or_default();
            e.0 += triples;
            if !parked {
                e.1 += triples;
            }
        }
    }
    acc.into_iter()
        .map(|(label, (all, moving))| {
            let q_std = class_profile(&label).2;
            let v = (q_std * dt).powi(2) * moving as f64 / all.max(1) as f64;
            (label, (all, v))
        })
        .collect()
}

/// Expected variance of the wrapped yaw residual with flips: with probability `p` the residual
/// is `wrap(e + pi)`, whose second moment is `pi^2 - 2 pi E|e| + sigma^2` for a small Gaussian
/// `e`.
fn wrapped_yaw_truth(sigma: f64, p: f64) -> f64 {
    let flipped = PI * PI - 2.0 * PI * sigma * (2.0 / PI).sqrt() + sigma * sigma;
    p * flipped + (1.0 - p) * sigma * sigma
}

fn arr(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn rel(fitted: f64, truth: f64) -> f64 {
    (fitted - truth) / truth
}

#[test]
fn fit_on_simulated_logs_recovers_the_simulator_noise() {
    let dir = tempfile::tempdir().unwrap();
    let logs = simulate_logs(dir.path());
    let out = dir.path().join("noise.json");
    // --fold-yaw: the simulated detector flips 3% of the headings by 180 degrees; the wrapped
    // yaw variance is dominated by those flips (checked separately below), so the yaw entry of
    // R is compared with the sensor's std^2 only when folded.
    let mut args = vec!["fit"];
    args.extend(logs.iter().map(|p| p.to_str().unwrap()));
    args.extend(["-o", out.to_str().unwrap(), "--fold-yaw", "--json"]);
    let res = probmot_ok(&args);
    let report: Value = serde_json::from_slice(&res.stdout).unwrap();
    assert_eq!(report["yaw_mode"], "folded");
    assert_eq!(report["variance"], "population (ddof=0)");
    assert_eq!(report["q_scale"].as_f64(), Some(1.0));
    assert_eq!(report["period"]["median_s"].as_f64(), Some(0.5));

    let cfg = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(cfg.dt_nominal, 0.5);
    let q_truth = q_truth();
    let fields = ["x", "y", "z", "yaw", "l", "w", "h"];
    let mut checked = 0;
    let mut lines = Vec::new();
    for c in report["classes"].as_array().unwrap() {
        let label = c["label"].as_str().unwrap();
        let n_pairs = c["n_pairs"].as_u64().unwrap();
        let (triples, q_xy) = q_truth[label];
        // Gaps break sequences: exactly the triples of consecutive frames of each instance.
        assert_eq!(c["n_q_samples"].as_u64(), Some(triples), "{label}");
        if n_pairs < MIN_PAIRS {
            continue;
        }
        checked += 1;
        let sensor = sensor_model(Scenario::City, label);
        let r = arr(&c["r"]);
        for i in 0..7 {
            let truth = sensor.std[i].powi(2);
            lines.push(format!(
                "{label:<10} R_{:<4} fitted {:.5} truth {:.5} ({:+.1}%)",
                fields[i],
                r[i],
                truth,
                100.0 * rel(r[i], truth)
            ));
            assert!(
                rel(r[i], truth).abs() < 0.10,
                "{label}: R[{}] = {} vs truth {truth}",
                fields[i],
                r[i]
            );
        }
        // Both yaw statistics are reported; R got the folded one.
        let folded = c["r_yaw_folded"].as_f64().unwrap();
        let wrapped = c["r_yaw_wrapped"].as_f64().unwrap();
        assert_eq!(folded, r[3]);
        // The flips add about p_flip * pi^2 to the wrapped variance.
        assert!(
            wrapped > folded + 0.5 * sensor.p_flip * PI * PI,
            "{label}: {wrapped} vs {folded}"
        );
        let w_truth = wrapped_yaw_truth(sensor.std[3], sensor.p_flip);
        lines.push(format!(
            "{label:<10} R_yaw wrapped {wrapped:.4} (flip model {w_truth:.4}), folded {folded:.5}"
        ));
        if label == "car" {
            // Enough flips (about 1000) for a check of the mixture.
            assert!(rel(wrapped, w_truth).abs() < 0.15, "{wrapped} vs {w_truth}");
        }

        let q = arr(&c["q"]);
        for i in 0..2 {
            lines.push(format!(
                "{label:<10} Q_{}    fitted {:.5} truth {:.5} ({:+.1}%)",
                fields[i],
                q[i],
                q_xy,
                100.0 * rel(q[i], q_xy)
            ));
            assert!(
                rel(q[i], q_xy).abs() < 0.20,
                "{label}: Q[{}] = {} vs truth {q_xy}",
                fields[i],
                q[i]
            );
        }
        assert!(q[2].abs() < 1e-12, "{label}: Q_z = {}", q[2]);
        assert!(q[3].is_finite() && q[3] >= 0.0, "{label}: Q_yaw = {}", q[3]);

        // P0 velocity entries: the detector's errors are independent between frames, so their
        // change has twice the variance.
        let p0v = arr(&c["p0_velocity"]);
        for i in 0..2 {
            let truth = 2.0 * sensor.std[i].powi(2);
            assert!(
                rel(p0v[i], truth).abs() < 0.15,
                "{label}: P0 d{} = {} vs {truth}",
                fields[i],
                p0v[i]
            );
        }

        // The config carries the fitted values.
        let cc = &cfg.classes[label];
        assert_eq!(cc.r.to_vec(), r, "{label}");
        assert_eq!(cc.p0[..7], cc.r[..]);
        assert_eq!(cc.q[0], q[0]);
        assert_eq!(cc.q[7], q[0]);
        assert_eq!(cc.q[2], 1e-6, "{label}: Q_z is raised to the floor");
        assert_eq!(cc.samples, Some(n_pairs));
    }
    eprintln!("{}", lines.join("\n"));
    assert_eq!(checked, 7, "every class should have {MIN_PAIRS} pairs");
    // The written config is accepted by the commands that take --config.
    probmot_ok(&["config", "--config", out.to_str().unwrap()]);
}

#[test]
fn fit_errors_few_samples_and_rescaling() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("small.mcap");
    let l = log.to_str().unwrap();
    // 10 Hz: the data period (0.1 s) differs from the preset's dt_nominal (0.5 s).
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "20",
        "--objects",
        "8",
        "--rate",
        "10",
        "-o",
        l,
    ]);
    let out = dir.path().join("noise.json");
    let o = out.to_str().unwrap();

    // A missing channel: exit status 2, the message names the file and the topic, no output.
    let res = probmot(&["fit", l, "-o", o, "--truth-topic", "/nope"]);
    assert_eq!(res.status.code(), Some(2));
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(err.contains("small.mcap") && err.contains("/nope"), "{err}");
    // A channel of the wrong schema.
    let res = probmot(&["fit", l, "-o", o, "--detections-topic", "/ground_truth"]);
    assert_eq!(res.status.code(), Some(2));
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(
        err.contains("/ground_truth") && err.contains("probmot.Detections3D"),
        "{err}"
    );
    assert!(!out.exists());

    // Too few samples everywhere: the base values are kept, with warnings.
    let res = probmot_ok(&["fit", l, "-o", o, "--min-samples", "100000", "--json"]);
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(err.contains("keeping the base config's values"), "{err}");
    let report: Value = serde_json::from_slice(&res.stdout).unwrap();
    // Q per nominal frame: the per-0.1 s statistics times (0.5 / 0.1)^3.
    assert!((report["q_scale"].as_f64().unwrap() - 125.0).abs() < 1e-9);
    assert!((report["period"]["median_s"].as_f64().unwrap() - 0.1).abs() < 1e-12);
    let cfg = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    assert_eq!(cfg.classes, base.classes);

    // A new base and nominal period.
    probmot_ok(&[
        "fit",
        l,
        "-o",
        o,
        "--min-samples",
        "5",
        "--base-preset",
        "ab3dmot-2019",
        "--dt-nominal",
        "0.1",
    ]);
    let cfg = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(cfg.dt_nominal, 0.1);
    assert!(cfg.classes.values().all(|c| c.samples.is_some()));
    assert!(!cfg.classes.is_empty());
}

/// A copy of the MCAP file `src` with its messages in the order `order` gives them.
fn reordered<F>(src: &Path, dst: &Path, order: F)
where
    F: for<'a> Fn(Vec<mcap::Message<'a>>) -> Vec<mcap::Message<'a>>,
{
    let bytes = std::fs::read(src).unwrap();
    let msgs: Vec<mcap::Message<'_>> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    let file = std::fs::File::create(dst).unwrap();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(file)).unwrap();
    for m in order(msgs) {
        w.write(&m).unwrap();
    }
    w.finish().unwrap();
}

/// The fit streams a log frame by frame when each channel's stamps are in order and reads it
/// whole when they go back: the same statistics either way, whatever the interleaving of the
/// channels (all truth first, or every message in reverse).
#[test]
fn streamed_and_whole_reads_give_the_same_fit() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("log.mcap");
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "60",
        "--objects",
        "30",
        "-o",
        log.to_str().unwrap(),
    ]);
    let truth_first = dir.path().join("truth_first.mcap");
    reordered(&log, &truth_first, |mut m| {
        m.sort_by_key(|m| m.channel.topic != "/ground_truth");
        m
    });
    let reversed = dir.path().join("reversed.mcap");
    reordered(&log, &reversed, |mut m| {
        m.reverse();
        m
    });
    let fit = |p: &Path| {
        let out = dir.path().join("cfg.json");
        let r = probmot_ok(&[
            "fit",
            p.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        let mut v: Value = serde_json::from_slice(&r.stdout).unwrap();
        for k in ["logs", "output"] {
            v.as_object_mut().unwrap().remove(k);
        }
        v
    };
    let streamed = fit(&log);
    assert!(streamed["frames"].as_u64().unwrap() == 60, "{streamed}");
    assert!(streamed["classes"].as_array().unwrap().len() >= 3);
    assert_eq!(fit(&truth_first), streamed);
    assert_eq!(fit(&reversed), streamed);
}

/// Detection boxes `track` would skip are left out of the fit too, counted and named in a
/// warning, whether the log streams or is read whole.
#[test]
fn skipped_detections_are_left_out_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.mcap");
    city_with_bad_boxes(&bad);
    let reversed = dir.path().join("reversed.mcap");
    reordered(&bad, &reversed, |mut m| {
        m.reverse();
        m
    });
    let fit = |p: &Path| {
        let out = dir.path().join("cfg.json");
        let (p, o) = (p.to_str().unwrap(), out.to_str().unwrap());
        let r = probmot_ok(&["fit", p, "-o", o, "--json"]);
        let v: Value = serde_json::from_slice(&r.stdout).unwrap();
        let warning = v["warnings"][0].as_str().unwrap().to_string();
        assert_eq!(
            warning,
            format!(
                "{p}: skipped 2 detection boxes: 1 (non-positive size), 1 (missing centre or \
                 size), as `probmot track` skips them"
            )
        );
        v
    };
    let (streamed, whole) = (fit(&bad), fit(&reversed));
    assert_eq!(streamed["classes"], whole["classes"]);
    let good = fit_detections(&repo("sample_logs/city.mcap"), dir.path());
    assert_eq!(streamed["detections"].as_u64().unwrap() + 2, good);
}

/// The detections a fit of `log` counted.
fn fit_detections(log: &Path, dir: &Path) -> u64 {
    let out = dir.join("good.json");
    let (p, o) = (log.to_str().unwrap(), out.to_str().unwrap());
    let r = probmot_ok(&["fit", p, "-o", o, "--json"]);
    let v: Value = serde_json::from_slice(&r.stdout).unwrap();
    v["detections"].as_u64().unwrap()
}

/// Logs of different frame rates pool at a period that is neither: `fit` and `tune` say so,
/// naming each log's period; two logs of one rate give no such warning. A log whose detection
/// messages hold no box leaves nothing to fit: an error, and no config written.
#[test]
fn mixed_frame_rates_are_named_and_no_detections_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (slow, fast) = (dir.path().join("slow.mcap"), dir.path().join("fast.mcap"));
    let sim = |out: &Path, rate: &str| {
        let o = out.to_str().unwrap();
        probmot_ok(&[
            "simulate",
            "--scenario",
            "city",
            "--rate",
            rate,
            "-o",
            o,
            "--quiet",
        ]);
    };
    sim(&slow, "2");
    sim(&fast, "10");
    let (s, f) = (slow.to_str().unwrap(), fast.to_str().unwrap());
    let out = dir.path().join("noise.json");
    let o = out.to_str().unwrap();
    let warned = |args: &[&str]| {
        let r = probmot_ok(args);
        let err = String::from_utf8_lossy(&r.stderr).to_string();
        err.contains("the logs have different frame periods")
            && err.contains("slow.mcap 0.5000 s")
            && err.contains("fast.mcap 0.1000 s")
    };
    assert!(warned(&["fit", s, f, "-o", o]));
    assert!(warned(&[
        "tune",
        s,
        f,
        "-o",
        o,
        "--protocol",
        "nuscenes",
        "--budget",
        "2",
        "--quiet"
    ]));
    // Two logs of one rate (a copy: the same file twice is refused).
    let slow2 = dir.path().join("slow2.mcap");
    std::fs::copy(&slow, &slow2).unwrap();
    assert!(!warned(&["fit", s, slow2.to_str().unwrap(), "-o", o]));

    let empty = dir.path().join("empty.mcap");
    city_with_messages(&empty, "/detections", |_, data| {
        use prost::Message as _;
        let mut d = probmot::msgs::Detections3D::decode(data).unwrap();
        d.detections.clear();
        d.encode_to_vec()
    });
    std::fs::remove_file(&out).unwrap();
    let r = probmot(&["fit", empty.to_str().unwrap(), "-o", o]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no detection box on topic /detections in"),
        "{err}"
    );
    assert!(!out.exists());
}
