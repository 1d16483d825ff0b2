//! The KITTI protocol's job: the logs loaded as the evaluation reads them, the AB3DMOT
//! evaluation and TrackEval's KITTI HOTA, the baseline, the bootstrap and the gate, and the
//! report.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};

use super::common::{bootstrap_options, change_table, describe, footer, gate, header, paths};
use super::events::{self, EventsReport};
use super::logs::{load_kitti_baseline, load_kitti_logs};
use super::options::{EvalOptions, EvalReport};
use crate::eval::bootstrap::curve::{kitti_metrics, KITTI_METRICS};
use crate::eval::bootstrap::paired::{self, aligned, paired_units, HotaGroup};
use crate::eval::bootstrap::report::Bootstrap;
use crate::eval::bootstrap::Options;
use crate::eval::events::Protocol as EventsProtocol;
use crate::eval::hota::kitti2d::{kitti_hota, kitti_hota_by, KittiSimilarity};
use crate::eval::hota::units::ByUnit;
use crate::eval::hota::{hota_rows, Hota, HOTA_COLUMNS};
use crate::eval::kitti::curve::unit_curves;
use crate::eval::kitti::{self, KittiBox, KittiMetrics, KittiParams, KittiResult, MeanScores};
use crate::eval::legend;
use crate::eval::report::table;
use crate::eval::scene::Scene;
use crate::pipeline::log_pairs::log_pairs;
use crate::pipeline::progress::{Progress, ProgressFn};

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

/// The KITTI protocol's parameters from the classes, the IoU and the means.
fn kitti_params(o: &EvalOptions) -> Result<KittiParams> {
    let mut params = KittiParams::default();
    if !o.classes.is_empty() {
        params.classes = o.classes.iter().map(|c| c.to_lowercase()).collect();
    }
    if let Some(iou) = o.iou {
        if !(iou > 0.0 && iou <= 1.0) {
            bail!("--iou {iou}: the minimum 3D IoU must lie in (0, 1]");
        }
        params.min_overlap = iou;
    }
    params.means = o.means.unwrap_or_default();
    Ok(params)
}

/// The error when no track box is of an evaluated class, with the classes the tracks have.
fn no_tracks(
    o: &EvalOptions,
    pairs: &[(PathBuf, PathBuf)],
    scenes: &[Scene<KittiBox>],
    params: &KittiParams,
) -> anyhow::Error {
    let classes: std::collections::BTreeSet<&str> = (scenes.iter())
        .flat_map(|s| s.frames.iter().flat_map(|f| f.2.iter().map(|b| b.label())))
        .collect();
    let classes: Vec<&str> = classes.into_iter().collect();
    anyhow::anyhow!(
        "{}: topic {} has no track box of the evaluated classes ({}); nothing to evaluate \
         (its classes: {}; choose them with --classes)",
        describe(pairs, true),
        o.tracks_topic,
        params.classes.join(", "),
        if classes.is_empty() {
            "none".to_string()
        } else {
            classes.join(", ")
        }
    )
}

/// `probmot eval --protocol kitti` (the options checked by [`super::evaluate`]).
pub fn run(o: &EvalOptions, progress: ProgressFn) -> Result<EvalReport> {
    let params = kitti_params(o)?;
    let pairs = log_pairs(&o.truth, &o.tracks)?;
    let scenes = load_kitti_logs(o, &pairs, progress)?;
    progress(Progress::Message("scoring (KITTI metrics and HOTA)"));
    // The metrics and the two HOTA similarities are independent: run side by side.
    let hota = |sim| kitti_hota(&scenes, &params.classes, sim);
    let ((result, decisions), ((hota_2d, mut hota_notes), (hota_3d, _))) = rayon::join(
        || kitti::evaluate_recording(&scenes, &params, o.events.is_some()),
        || {
            rayon::join(
                || hota(KittiSimilarity::Image),
                || hota(KittiSimilarity::Box3d),
            )
        },
    );
    progress(Progress::Done);
    hota_notes.dedup();
    if result.classes.is_empty() {
        return Err(no_tracks(o, &pairs, &scenes, &params));
    }
    let events = (o.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Kitti, decisions);
            events::write(out, logs, &pairs, &scenes[..], &o.truth_topic)
        })
        .transpose()?;
    let boot_options = bootstrap_options(o);
    // The logs are scored: without a bootstrap the baseline's need not be held beside them.
    let scenes = boot_options.map(|_| scenes);
    let (base_pairs, base_scenes) = load_kitti_baseline(o, progress)?;
    progress(Progress::Done);
    let baseline = (base_scenes.as_ref()).map(|scenes| kitti::evaluate(scenes, &params));
    let boot = match (boot_options, &scenes) {
        (Some(b), Some(s)) => Some(kitti_bootstrap(
            s,
            base_scenes.as_deref(),
            &params,
            o.block,
            b,
        )),
        _ => None,
    };

    // The gate, on sAMOTA.
    let gate_failures = match &baseline {
        Some(base) => gate(
            o,
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
    let found = Found {
        pairs: &pairs,
        result: &result,
        hota: (&hota_2d, &hota_3d, &hota_notes),
        baseline: baseline.as_ref().map(|b| (&base_pairs[..], b)),
        events: events.as_ref(),
        boot: boot.as_ref(),
    };
    Ok(match o.json {
        true => EvalReport {
            json: Some(json(&found, &gate_failures)),
            text: String::new(),
            gate_failures,
        },
        false => EvalReport {
            json: None,
            text: text(o, &params, &found),
            gate_failures,
        },
    })
}

/// HOTA per class of both similarities, and their notes.
type KittiHota<'a> = (
    &'a BTreeMap<String, Hota>,
    &'a BTreeMap<String, Hota>,
    &'a [String],
);

/// What the KITTI job found, for its report.
struct Found<'a> {
    pairs: &'a [(PathBuf, PathBuf)],
    result: &'a KittiResult,
    hota: KittiHota<'a>,
    baseline: Option<(&'a [(PathBuf, PathBuf)], &'a KittiResult)>,
    events: Option<&'a EventsReport>,
    boot: Option<&'a Bootstrap>,
}

/// The `--json` document.
fn json(f: &Found, failures: &[String]) -> serde_json::Value {
    let (hota_2d, hota_3d, hota_notes) = f.hota;
    let mut v = serde_json::json!({
        "logs": paths(f.pairs), "result": f.result,
        "baseline": f.baseline.map(|(p, b)| serde_json::json!({"logs": paths(p), "result": b})),
        "gate_failures": failures,
        "hota": {"image_2d": hota_2d, "iou_3d": hota_3d, "notes": hota_notes},
    });
    if let Some(e) = f.events {
        v["events"] = e.json();
    }
    if let Some(b) = f.boot {
        v["bootstrap"] = b.json();
    }
    v
}

/// The text report: the metrics, HOTA, the baseline and the change, the notes, the events
/// written and the bootstrap.
fn text(o: &EvalOptions, params: &KittiParams, f: &Found) -> String {
    let (hota_2d, hota_3d, hota_notes) = f.hota;
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
    let mut s = String::new();
    let _ = writeln!(s, "{}", header(&title, f.pairs, o));
    s.push_str(&table(
        &KITTI_COLUMNS,
        &kitti_rows(f.result, &params.classes),
    ));
    let mut h = hota_rows(hota_2d, "");
    h.extend(hota_rows(hota_3d, " 3d"));
    // Without any evaluated class the notes say why; an empty table would say nothing.
    if !h.is_empty() {
        s.push_str(
            "\nHOTA (TrackEval's Kitti2DBox: 2D image-box IoU; 3d: the same boxes by 3D IoU):\n",
        );
        s.push_str(&table(&HOTA_COLUMNS, &h));
    }
    if let Some((base_pairs, base)) = f.baseline {
        let _ = writeln!(s, "\nbaseline {}:", describe(base_pairs, true));
        s.push_str(&table(&KITTI_COLUMNS, &kitti_rows(base, &params.classes)));
        let mut delta = Vec::new();
        for (name, new) in kitti_rows(f.result, &params.classes) {
            if let Some((_, old)) = kitti_rows(base, &params.classes)
                .into_iter()
                .find(|(n, _)| *n == name)
            {
                delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
            }
        }
        s.push_str(&change_table(&legend::KITTI, &KITTI_COLUMNS, &delta));
    }
    for n in f.result.notes.iter().chain(hota_notes) {
        let _ = writeln!(s, "note: {n}");
    }
    s.push_str(&f.events.map(|e| e.text()).unwrap_or_default());
    s.push_str(&footer(o, &[legend::KITTI, legend::HOTA]));
    s.push_str(&f.boot.map(Bootstrap::text).unwrap_or_default());
    s
}

/// The bootstrap of the KITTI metrics and both HOTAs over `scenes` (and the change from `base`).
fn kitti_bootstrap(
    scenes: &[Scene<KittiBox>],
    base: Option<&[Scene<KittiBox>]>,
    params: &KittiParams,
    block: Option<f64>,
    boot: Options,
) -> Bootstrap {
    let stamps = |s: &[Scene<KittiBox>]| -> Vec<Vec<u64>> {
        (s.iter())
            .map(|s| s.frames.iter().map(|f| f.0).collect())
            .collect()
    };
    let runs: Vec<Vec<Vec<u64>>> = std::iter::once(scenes).chain(base).map(stamps).collect();
    let units = paired_units(&runs, block);
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
    paired::run((p, rows), (&this, base.as_deref()), &hota, &units[0], boot)
}

/// The HOTA metrics of the KITTI bootstrap: image-box HOTA, DetA, AssA, then the 3D-IoU ones.
const KITTI_HOTA_METRICS: [&str; 6] = ["HOTA", "DetA", "AssA", "HOTA_3d", "DetA_3d", "AssA_3d"];
