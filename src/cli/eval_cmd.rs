//! `probmot eval`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use probmot::eval::kitti::{self, KittiMetrics, KittiParams, KittiResult};
use probmot::eval::nuscenes::{evaluate, Metrics, NuscenesParams, NuscenesResult};
use probmot::eval::report::{fmt_value, table};
use probmot::eval::scene::{load_scene, read_tracks_topic, EvalBox, Scene};

/// Evaluation protocols.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Protocol {
    /// nuScenes tracking benchmark (AMOTA, AMOTP, MOTA, ...; 2 m centre distance).
    Nuscenes,
    /// KITTI 3D MOT as evaluated by AB3DMOT (sAMOTA, AMOTA, AMOTP, MOTA, ...; 3D IoU matching,
    /// KITTI's ignore rules for truncated/occluded ground truth, DontCare regions, small boxes
    /// and the neighbouring classes Van and Person_sitting).
    Kitti,
}

/// Score tracks against ground truth with the nuScenes tracking metrics or the KITTI 3D MOT
/// metrics (AB3DMOT's evaluation), optionally against a baseline run, as a regression gate.
///
/// Ground truth is a probmot.Tracks3D channel whose ids are the true instance ids (a simulated
/// log carries it as /ground_truth, so a tracked simulated log holds both channels; so does a
/// KITTI sequence written by `probmot import kitti` with --labels, once tracked).
///
/// Exit status: 0 ok, 2 error, 3 the gate (--max-drop) failed.
///
/// Examples:
///   probmot eval --truth drive.tracked.mcap
///   probmot eval --truth drive.mcap --tracks drive.tracked.mcap --json
///   probmot eval --truth gt.mcap --tracks new.mcap --baseline old.mcap --max-drop 1
///   probmot eval --protocol kitti --truth 0000.tracked.mcap
///   probmot eval --protocol kitti --iou 0.5 --classes car --truth 0000.tracked.mcap
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct EvalArgs {
    /// File with the ground-truth channel.
    #[arg(long, value_name = "GT.mcap")]
    truth: PathBuf,
    /// File with the tracks channel (default: the truth file).
    #[arg(long, value_name = "TRACKED.mcap")]
    tracks: Option<PathBuf>,
    /// Ground-truth topic.
    #[arg(long, default_value = "/ground_truth")]
    truth_topic: String,
    /// Tracks topic.
    #[arg(long, default_value = "/tracks")]
    tracks_topic: String,
    /// Protocol.
    #[arg(long, value_enum, default_value_t = Protocol::Nuscenes)]
    protocol: Protocol,
    /// Classes to evaluate, comma separated (default: the seven nuScenes classes; for kitti:
    /// car, pedestrian, cyclist).
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// KITTI only: minimum 3D IoU of a match [default: 0.25; 0.5 and 0.7 are also used].
    #[arg(long, value_name = "IOU")]
    iou: Option<f64>,
    /// Another tracked version of the same log to compare with (same truth).
    #[arg(long, value_name = "OTHER.mcap")]
    baseline: Option<PathBuf>,
    /// With --baseline: exit 3 if the overall main metric (AMOTA for nuscenes, sAMOTA for kitti)
    /// falls by more than this many percentage points.
    #[arg(long, value_name = "POINTS", requires = "baseline")]
    max_drop: Option<f64>,
    /// With --max-drop: also fail when any single class falls by more than that.
    #[arg(long, requires = "max_drop")]
    per_class: bool,
    /// Print every number as JSON.
    #[arg(long)]
    json: bool,
}

const COLUMNS: [&str; 14] = [
    "amota", "amotp", "recall", "mota", "motp", "ids", "frag", "fp", "fn", "mt", "ml", "faf",
    "tid", "lgd",
];

fn rows(r: &NuscenesResult) -> Vec<(String, Vec<f64>)> {
    let mut out: Vec<(String, Vec<f64>)> = r
        .classes
        .iter()
        .filter(|(_, m)| !m.gt.is_nan())
        .map(|(c, m)| (c.clone(), COLUMNS.iter().map(|k| m.get(k)).collect()))
        .collect();
    out.push((
        "overall".into(),
        COLUMNS.iter().map(|k| r.overall.get(k)).collect(),
    ));
    out
}

fn scene(args: &EvalArgs, tracks: &Path) -> Result<Scene> {
    load_scene(&args.truth, &args.truth_topic, tracks, &args.tracks_topic)
}

pub fn run(a: EvalArgs) -> Result<ExitCode> {
    match a.protocol {
        Protocol::Nuscenes => {
            if a.iou.is_some() {
                bail!("--iou is a KITTI option (the nuScenes protocol matches by 2 m centre distance)");
            }
            run_nuscenes(a)
        }
        Protocol::Kitti => run_kitti(a),
    }
}

fn run_nuscenes(a: EvalArgs) -> Result<ExitCode> {
    let mut params = NuscenesParams::default();
    if !a.classes.is_empty() {
        params.classes = a.classes.clone();
    }
    let tracks = a.tracks.clone().unwrap_or_else(|| a.truth.clone());
    let result = evaluate(&[scene(&a, &tracks)?], &params);
    if result.classes.values().all(|m| m.gt.is_nan()) {
        bail!(
            "{}: topic {} has no ground-truth box of the evaluated classes ({})",
            a.truth.display(),
            a.truth_topic,
            params.classes.join(", ")
        );
    }
    let baseline = match &a.baseline {
        Some(b) => Some(evaluate(&[scene(&a, b)?], &params)),
        None => None,
    };

    // The gate.
    let mut failures = Vec::new();
    if let (Some(base), Some(max_drop)) = (&baseline, a.max_drop) {
        let drop = |new: &Metrics, old: &Metrics| (old.amota - new.amota) * 100.0;
        let d = drop(&result.overall, &base.overall);
        if d > max_drop {
            failures.push(format!(
                "overall AMOTA fell by {d:.2} points ({:.4} -> {:.4}), more than --max-drop {max_drop}",
                base.overall.amota, result.overall.amota
            ));
        }
        if a.per_class {
            for (c, m) in &result.classes {
                if let Some(o) = base.classes.get(c) {
                    let d = drop(m, o);
                    if d > max_drop {
                        failures.push(format!(
                            "{c}: AMOTA fell by {d:.2} points ({:.4} -> {:.4})",
                            o.amota, m.amota
                        ));
                    }
                }
            }
        }
    }

    if a.json {
        let v = serde_json::json!({
            "truth": a.truth, "tracks": tracks, "result": result,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"tracks": a.baseline, "result": b})),
            "gate_failures": failures,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "nuScenes tracking metrics: {} vs {} ({} / {})",
            tracks.display(),
            a.truth.display(),
            a.tracks_topic,
            a.truth_topic
        );
        print!("{}", table(&COLUMNS, &rows(&result)));
        if let Some(base) = &baseline {
            println!("\nbaseline {}:", a.baseline.as_ref().unwrap().display());
            print!("{}", table(&COLUMNS, &rows(base)));
            println!("\nchange (this - baseline):");
            let mut delta = Vec::new();
            for ((name, new), (_, old)) in rows(&result).into_iter().zip(rows(base)) {
                delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
            }
            print!("{}", table(&COLUMNS, &delta));
        }
        for n in &result.notes {
            println!("note: {n}");
        }
        let _ = fmt_value;
    }
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("gate failed: {f}");
        }
        return Ok(ExitCode::from(3));
    }
    Ok(ExitCode::SUCCESS)
}

/// Table columns of the KITTI report; lower-case names are counts (printed without decimals).
const KITTI_COLUMNS: [&str; 14] = [
    "sAMOTA",
    "AMOTA",
    "AMOTP",
    "MOTA",
    "MOTP",
    "ids",
    "frag",
    "fp",
    "fn",
    "tp",
    "recall",
    "precision",
    "MT",
    "ML",
];

fn kitti_value(m: &KittiMetrics, column: &str) -> f64 {
    match column {
        "ids" | "frag" | "fp" | "fn" | "tp" => m.get(&column.to_uppercase()),
        _ => m.get(column),
    }
}

fn kitti_rows(r: &KittiResult, classes: &[String]) -> Vec<(String, Vec<f64>)> {
    let row = |m: &KittiMetrics| KITTI_COLUMNS.iter().map(|c| kitti_value(m, c)).collect();
    let mut out: Vec<(String, Vec<f64>)> = classes
        .iter()
        .filter_map(|c| r.classes.get(c).map(|m| (c.clone(), row(m))))
        .collect();
    out.push(("overall".into(), row(&r.overall)));
    out
}

/// Loads one KITTI scene. Unlike [`load_scene`], ground-truth boxes without an id are allowed:
/// `probmot import kitti` stores DontCare regions that way.
fn kitti_scene(a: &EvalArgs, tracks: &Path) -> Result<Scene> {
    let gt = read_tracks_topic(&a.truth, &a.truth_topic)?;
    let tr = read_tracks_topic(tracks, &a.tracks_topic)?;
    let (Some(first), Some(last)) = (gt.iter().map(|g| g.0).min(), gt.iter().map(|g| g.0).max())
    else {
        bail!(
            "{}: topic {} has no messages",
            a.truth.display(),
            a.truth_topic
        );
    };
    if let Some((s, _)) = tr.iter().find(|(s, _)| *s < first || *s > last) {
        bail!(
            "{}: topic {} has a frame at stamp {s} ns, outside the ground truth's time range \
             {first}..{last} ns in {}; are these the tracks of another log?",
            tracks.display(),
            a.tracks_topic,
            a.truth.display()
        );
    }
    let mut frames: BTreeMap<u64, (Vec<EvalBox>, Vec<EvalBox>)> = BTreeMap::new();
    for (s, b) in gt {
        frames.entry(s).or_default().0.extend(b);
    }
    for (s, b) in tr {
        frames.entry(s).or_default().1.extend(b);
    }
    Ok(Scene {
        name: tracks
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        frames: frames.into_iter().map(|(s, (g, t))| (s, g, t)).collect(),
    })
}

fn run_kitti(a: EvalArgs) -> Result<ExitCode> {
    let mut params = KittiParams::default();
    if !a.classes.is_empty() {
        params.classes = a.classes.iter().map(|c| c.to_lowercase()).collect();
    }
    if let Some(iou) = a.iou {
        if !(iou > 0.0 && iou <= 1.0) {
            bail!("--iou {iou}: the minimum 3D IoU must lie in (0, 1]");
        }
        params.min_overlap = iou;
    }
    let tracks = a.tracks.clone().unwrap_or_else(|| a.truth.clone());
    let result = kitti::evaluate(&[kitti_scene(&a, &tracks)?], &params);
    if result.classes.is_empty() {
        bail!(
            "{}: topic {} has no track box of the evaluated classes ({}); nothing to evaluate",
            tracks.display(),
            a.tracks_topic,
            params.classes.join(", ")
        );
    }
    let baseline = match &a.baseline {
        Some(b) => Some(kitti::evaluate(&[kitti_scene(&a, b)?], &params)),
        None => None,
    };

    // The gate, on sAMOTA.
    let mut failures = Vec::new();
    if let (Some(base), Some(max_drop)) = (&baseline, a.max_drop) {
        let drop = |new: &KittiMetrics, old: &KittiMetrics| (old.samota - new.samota) * 100.0;
        let d = drop(&result.overall, &base.overall);
        // A result that has become undefined (no ground truth that counts) also fails.
        if d > max_drop || (d.is_nan() && base.overall.samota.is_finite()) {
            failures.push(format!(
                "overall sAMOTA fell by {d:.2} points ({:.4} -> {:.4}), more than --max-drop {max_drop}",
                base.overall.samota, result.overall.samota
            ));
        }
        if a.per_class {
            for (c, m) in &result.classes {
                if let Some(o) = base.classes.get(c) {
                    let d = drop(m, o);
                    if d > max_drop {
                        failures.push(format!(
                            "{c}: sAMOTA fell by {d:.2} points ({:.4} -> {:.4})",
                            o.samota, m.samota
                        ));
                    }
                }
            }
        }
    }

    if a.json {
        let v = serde_json::json!({
            "truth": a.truth, "tracks": tracks, "result": result,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"tracks": a.baseline, "result": b})),
            "gate_failures": failures,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "KITTI 3D MOT metrics (AB3DMOT evaluation, 3D IoU >= {}): {} vs {} ({} / {})",
            params.min_overlap,
            tracks.display(),
            a.truth.display(),
            a.tracks_topic,
            a.truth_topic
        );
        print!(
            "{}",
            table(&KITTI_COLUMNS, &kitti_rows(&result, &params.classes))
        );
        if let Some(base) = &baseline {
            println!("\nbaseline {}:", a.baseline.as_ref().unwrap().display());
            print!(
                "{}",
                table(&KITTI_COLUMNS, &kitti_rows(base, &params.classes))
            );
            println!("\nchange (this - baseline):");
            let mut delta = Vec::new();
            for (name, new) in kitti_rows(&result, &params.classes) {
                if let Some((_, old)) = kitti_rows(base, &params.classes)
                    .into_iter()
                    .find(|(n, _)| *n == name)
                {
                    delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
                }
            }
            print!("{}", table(&KITTI_COLUMNS, &delta));
        }
        for n in &result.notes {
            println!("note: {n}");
        }
    }
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("gate failed: {f}");
        }
        return Ok(ExitCode::from(3));
    }
    Ok(ExitCode::SUCCESS)
}
