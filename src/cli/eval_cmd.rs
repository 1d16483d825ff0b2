//! `probmot eval`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use probmot::eval::nuscenes::{evaluate, Metrics, NuscenesParams, NuscenesResult};
use probmot::eval::report::{fmt_value, table};
use probmot::eval::scene::{load_scene, Scene};

/// Evaluation protocols.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Protocol {
    /// nuScenes tracking benchmark (AMOTA, AMOTP, MOTA, ...; 2 m centre distance).
    Nuscenes,
}

/// Score tracks against ground truth with the nuScenes tracking metrics, optionally against a
/// baseline run, as a regression gate.
///
/// Ground truth is a probmot.Tracks3D channel whose ids are the true instance ids (a simulated
/// log carries it as /ground_truth, so a tracked simulated log holds both channels).
///
/// Exit status: 0 ok, 2 error, 3 the gate (--max-drop) failed.
///
/// Examples:
///   probmot eval --truth drive.tracked.mcap
///   probmot eval --truth drive.mcap --tracks drive.tracked.mcap --json
///   probmot eval --truth gt.mcap --tracks new.mcap --baseline old.mcap --max-drop 1
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
    /// Classes to evaluate, comma separated (default: the seven nuScenes classes).
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// Another tracked version of the same log to compare with (same truth).
    #[arg(long, value_name = "OTHER.mcap")]
    baseline: Option<PathBuf>,
    /// With --baseline: exit 3 if the overall main metric (AMOTA) falls by more than this many
    /// percentage points.
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

fn scene(args: &EvalArgs, tracks: &PathBuf) -> Result<Scene> {
    load_scene(&args.truth, &args.truth_topic, tracks, &args.tracks_topic)
}

pub fn run(a: EvalArgs) -> Result<ExitCode> {
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
