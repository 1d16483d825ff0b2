//! `probmot eval --protocol kitti`: the KITTI logs loaded as the evaluation reads them, the
//! AB3DMOT evaluation and TrackEval's KITTI HOTA, the regression gate, and the report.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use probmot::eval::hota::kitti2d::{kitti_hota, kitti_hota_by, KittiSimilarity};
use probmot::eval::hota::{hota_rows, Hota, HOTA_COLUMNS};
use probmot::eval::kitti::{self, KittiBox, KittiMetrics, KittiParams, KittiResult, MeanScores};
use probmot::eval::legend;
use probmot::eval::report::table;
use probmot::eval::scene::{load_kitti_scene, Scene};
use probmot::pipeline::log_pairs::log_pairs;
use rayon::prelude::*;

use super::eval_args::{
    change_table, describe, footer, gate_exit, header, paths, reading_bar, scoring_spinner,
    EvalArgs, LogPairs,
};
use super::eval_bootstrap;
use super::eval_events::{self, EventsReport};
use super::means_arg::MeansArg;
use probmot::eval::bootstrap::curve::{kitti_metrics, KITTI_METRICS};
use probmot::eval::bootstrap::paired::{self, aligned, paired_units, HotaGroup};
use probmot::eval::bootstrap::report::Bootstrap;
use probmot::eval::bootstrap::Options;
use probmot::eval::events::Protocol as EventsProtocol;
use probmot::eval::hota::units::ByUnit;
use probmot::eval::kitti::curve::unit_curves;

/// Loads every log (in parallel) for the KITTI protocol, each box as the KITTI evaluation
/// reads it ([`load_kitti_scene`]): ground-truth boxes without id (DontCare) are allowed. The
/// protocol has no filters.
fn load_logs(a: &EvalArgs, pairs: &[(PathBuf, PathBuf)]) -> Result<Vec<Scene<KittiBox>>> {
    let bar = reading_bar(a, pairs);
    let scenes = pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let (truth, tracks) = ((&**truth, &*a.truth_topic), (&**tracks, &*a.tracks_topic));
            load_kitti_scene(truth, tracks, &|n| bar.inc(n))
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    Ok(scenes)
}

/// The `--baseline` logs of the KITTI protocol, paired with the truth like `--tracks`, loaded as
/// [`load_logs`] does; no pairs and `None` without `--baseline`.
fn load_baseline(a: &EvalArgs) -> Result<(LogPairs, Option<Vec<Scene<KittiBox>>>)> {
    if a.baseline.is_empty() {
        return Ok((Vec::new(), None));
    }
    let pairs = log_pairs(&a.truth, &a.baseline)?;
    let scenes = load_logs(a, &pairs)?;
    Ok((pairs, Some(scenes)))
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

/// The KITTI protocol's parameters from --classes and --iou.
fn kitti_params(a: &EvalArgs) -> Result<KittiParams> {
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
    params.means = a.means.map_or(MeanScores::EveryPass, MeansArg::means);
    Ok(params)
}

/// `probmot eval --protocol kitti` with its arguments checked by `eval_cmd::run`.
pub fn run_kitti(a: EvalArgs) -> Result<ExitCode> {
    let params = kitti_params(&a)?;
    let pairs = log_pairs(&a.truth, &a.tracks)?;
    let scenes = load_logs(&a, &pairs)?;
    let spinner = scoring_spinner(&a, "KITTI metrics and HOTA");
    // The metrics and the two HOTA similarities are independent: run side by side.
    let hota = |sim| kitti_hota(&scenes, &params.classes, sim);
    let ((result, decisions), ((hota_2d, mut hota_notes), (hota_3d, _))) = rayon::join(
        || kitti::evaluate_recording(&scenes, &params, a.events.is_some()),
        || {
            rayon::join(
                || hota(KittiSimilarity::Image),
                || hota(KittiSimilarity::Box3d),
            )
        },
    );
    spinner.finish_and_clear();
    hota_notes.dedup();
    if result.classes.is_empty() {
        let classes: std::collections::BTreeSet<&str> = (scenes.iter())
            .flat_map(|s| s.frames.iter().flat_map(|f| f.2.iter().map(|b| b.label())))
            .collect();
        let classes: Vec<&str> = classes.into_iter().collect();
        bail!(
            "{}: topic {} has no track box of the evaluated classes ({}); nothing to evaluate \
             (its classes: {}; choose them with --classes)",
            describe(&pairs, true),
            a.tracks_topic,
            params.classes.join(", "),
            if classes.is_empty() {
                "none".to_string()
            } else {
                classes.join(", ")
            }
        );
    }
    let events = (a.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Kitti, decisions);
            eval_events::write(out, logs, &pairs, &scenes[..], &a.truth_topic)
        })
        .transpose()?;
    let boot_options = eval_bootstrap::options(&a);
    // The logs are scored: without a bootstrap the baseline's need not be held beside them.
    let scenes = boot_options.map(|_| scenes);
    let (base_pairs, base_scenes) = load_baseline(&a)?;
    let baseline = (base_scenes.as_ref()).map(|scenes| kitti::evaluate(scenes, &params));
    let boot = match (boot_options, &scenes) {
        (Some(o), Some(s)) => Some(kitti_bootstrap(s, base_scenes.as_deref(), &params, &a, o)),
        _ => None,
    };

    // The gate, on sAMOTA.
    let failures = match &baseline {
        Some(base) => eval_bootstrap::gate(
            &a,
            "sAMOTA",
            (
                (base.overall.samota, result.overall.samota),
                result.classes.iter().filter_map(|(c, m)| {
                    (base.classes.get(c)).map(|o| (c.as_str(), o.samota, m.samota))
                }),
            ),
            boot.as_ref(),
        ),
        None => Vec::new(),
    };

    if a.json {
        let mut v = serde_json::json!({
            "logs": paths(&pairs), "result": result,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"logs": paths(&base_pairs), "result": b})),
            "gate_failures": failures,
            "hota": {"image_2d": hota_2d, "iou_3d": hota_3d, "notes": hota_notes},
        });
        if let Some(e) = &events {
            v["events"] = e.json();
        }
        if let Some(b) = &boot {
            v["bootstrap"] = b.json();
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let hota = (&hota_2d, &hota_3d, &hota_notes[..]);
        let base = baseline.as_ref().map(|b| (&base_pairs[..], b));
        print_kitti(
            &a,
            (&params, &pairs),
            (&result, hota),
            base,
            events.as_ref(),
        );
        print!("{}", boot.as_ref().map(Bootstrap::text).unwrap_or_default());
    }
    Ok(gate_exit(&failures))
}

/// HOTA per class of both similarities, and their notes.
type KittiHota<'a> = (
    &'a BTreeMap<String, Hota>,
    &'a BTreeMap<String, Hota>,
    &'a [String],
);

/// The text report of `eval --protocol kitti`: the metrics, HOTA, the baseline and the change,
/// the notes and the events written.
fn print_kitti(
    a: &EvalArgs,
    (params, pairs): (&KittiParams, &[(PathBuf, PathBuf)]),
    (result, (hota_2d, hota_3d, hota_notes)): (&KittiResult, KittiHota),
    baseline: Option<(&[(PathBuf, PathBuf)], &KittiResult)>,
    events: Option<&EventsReport>,
) {
    let title = format!(
        "KITTI 3D MOT metrics (AB3DMOT evaluation{}, 3D IoU >= {})",
        match params.means {
            MeanScores::EveryPass => "",
            MeanScores::EveryPassCompensated =>
                " as run on Python 3.12+, not the published numbers",
            MeanScores::Once => " with each track's mean computed once, not official",
        },
        params.min_overlap,
    );
    println!("{}", header(&title, pairs, a));
    print!(
        "{}",
        table(&KITTI_COLUMNS, &kitti_rows(result, &params.classes))
    );
    let mut h = hota_rows(hota_2d, "");
    h.extend(hota_rows(hota_3d, " 3d"));
    // Without any evaluated class the notes say why; an empty table would say nothing.
    if !h.is_empty() {
        println!(
            "\nHOTA (TrackEval's Kitti2DBox: 2D image-box IoU; 3d: the same boxes by 3D IoU):"
        );
        print!("{}", table(&HOTA_COLUMNS, &h));
    }
    if let Some((base_pairs, base)) = baseline {
        println!("\nbaseline {}:", describe(base_pairs, true));
        print!(
            "{}",
            table(&KITTI_COLUMNS, &kitti_rows(base, &params.classes))
        );
        let mut delta = Vec::new();
        for (name, new) in kitti_rows(result, &params.classes) {
            if let Some((_, old)) = kitti_rows(base, &params.classes)
                .into_iter()
                .find(|(n, _)| *n == name)
            {
                delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
            }
        }
        print!("{}", change_table(&legend::KITTI, &KITTI_COLUMNS, &delta));
    }
    for n in result.notes.iter().chain(hota_notes) {
        println!("note: {n}");
    }
    print!("{}", events.map(|e| e.text()).unwrap_or_default());
    print!("{}", footer(a, &[legend::KITTI, legend::HOTA]));
}

/// The bootstrap of the KITTI metrics and both HOTAs over `scenes` (and the change from `base`).
fn kitti_bootstrap(
    scenes: &[Scene<KittiBox>],
    base: Option<&[Scene<KittiBox>]>,
    params: &KittiParams,
    a: &EvalArgs,
    o: Options,
) -> Bootstrap {
    let stamps = |s: &[Scene<KittiBox>]| -> Vec<Vec<u64>> {
        (s.iter())
            .map(|s| s.frames.iter().map(|f| f.0).collect())
            .collect()
    };
    let runs: Vec<Vec<Vec<u64>>> = std::iter::once(scenes).chain(base).map(stamps).collect();
    let units = paired_units(&runs, a.block);
    let last = &units[units.len() - 1];
    let this = unit_curves(scenes, params, &units[0]);
    let base_curves = base.map(|b| unit_curves(b, params, last));
    let group = |names, sim| {
        let hota = |s, u| kitti_hota_by(s, &params.classes, sim, &ByUnit(u)).0;
        let mut runs = vec![hota(scenes, &units[0])];
        runs.extend(base.map(|b| hota(b, last)));
        HotaGroup { names, runs }
    };
    let hota = [
        group(&KITTI_HOTA_METRICS[..3], KittiSimilarity::Image),
        group(&KITTI_HOTA_METRICS[3..], KittiSimilarity::Box3d),
    ];
    let (rows, this, base) = aligned(this, base_curves);
    let p = paired::Protocol {
        names: &KITTI_METRICS[..],
        metrics: kitti_metrics,
    };
    paired::run((p, rows), (&this, base.as_deref()), &hota, &units[0], o)
}

/// The HOTA metrics of the KITTI bootstrap: image-box HOTA, DetA, AssA, then the 3D-IoU ones.
const KITTI_HOTA_METRICS: [&str; 6] = ["HOTA", "DetA", "AssA", "HOTA_3d", "DetA_3d", "AssA_3d"];
