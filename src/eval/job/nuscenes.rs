//! The nuScenes protocol's job: the logs loaded through the devkit's filters, the metrics and
//! HOTA (BEV centre distance), the baseline, the bootstrap and the gate, and the report.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use rayon::prelude::*;

use super::common::{
    bootstrap_options, change_table, describe, footer, gate, header, paths, LogPairs,
};
use super::events;
use super::logs::{filter_notes, filters_json, load_columns_logs};
use super::options::{EvalOptions, EvalReport};
use crate::eval::bootstrap::curve::{nuscenes_metrics, NUSCENES_METRICS};
use crate::eval::bootstrap::paired::{self, aligned, paired_units, HotaGroup, HOTA_METRICS};
use crate::eval::bootstrap::report::Bootstrap;
use crate::eval::bootstrap::Options;
use crate::eval::columns::{boxes_outside, ColumnScene};
use crate::eval::events::Protocol as EventsProtocol;
use crate::eval::filters::FilterCounts;
use crate::eval::hota::centre::{centre_hota, centre_hota_by, ZERO_DISTANCE};
use crate::eval::hota::units::ByUnit;
use crate::eval::hota::{hota_rows, Hota, HOTA_COLUMNS};
use crate::eval::legend;
use crate::eval::nuscenes::curve::unit_curves;
use crate::eval::nuscenes::{
    evaluate_columns, evaluate_columns_recording, NuscenesParams, NuscenesResult,
};
use crate::eval::report::table;
use crate::pipeline::kitti_io::is_kitti_import;
use crate::pipeline::log_pairs::log_pairs;
use crate::pipeline::progress::{Progress, ProgressFn};

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

/// The per-log breakdown when several logs were scored together (empty for one log).
fn per_log_json(
    scenes: &[ColumnScene],
    pairs: &[(PathBuf, PathBuf)],
    params: &NuscenesParams,
) -> Vec<serde_json::Value> {
    if scenes.len() < 2 {
        return Vec::new();
    }
    scenes
        .par_iter()
        .zip(pairs)
        .map(|(s, (t, r))| {
            serde_json::json!({"truth": t, "tracks": r,
                "result": evaluate_columns(std::slice::from_ref(s), params)})
        })
        .collect()
}

/// The classes of the ground truth of `scenes`, sorted, as the error without any box of the
/// evaluated classes gives them.
fn truth_classes(scenes: &[ColumnScene]) -> String {
    let names: std::collections::BTreeSet<&str> = (scenes.iter())
        .flat_map(|s| s.truth.label.iter().map(|&l| s.labels[l as usize].as_str()))
        .collect();
    let names: Vec<&str> = names.into_iter().collect();
    match names.is_empty() {
        true => "it has no box".to_string(),
        false => format!("its classes: {} (choose with --classes)", names.join(", ")),
    }
}

/// A note naming the labels no evaluated class reads, with their boxes, so that none is left
/// out unsaid: labels with ground truth first (with what to do), then those only the tracks
/// have (a detector's classes outside the benchmark, e.g. nuScenes' traffic cones).
fn unevaluated_labels(
    scenes: &[ColumnScene],
    classes: &[String],
    o: &EvalOptions,
    pairs: &LogPairs,
) -> Option<String> {
    let outside = boxes_outside(scenes, classes);
    let (with_truth, tracks_only): (Vec<_>, Vec<_>) =
        outside.iter().partition(|(_, [truth, _])| *truth > 0);
    let mut parts = Vec::new();
    if !with_truth.is_empty() {
        let each: Vec<String> = (with_truth.iter())
            .map(|(l, [truth, tracks])| format!("{l} ({truth} truth, {tracks} track boxes)"))
            .collect();
        let kitti = (pairs.iter()).any(|(t, _)| is_kitti_import(t).unwrap_or(false));
        let why = match (o.classes.is_empty(), kitti) {
            (false, _) => "not in --classes",
            (true, true) => {
                "not classes of the nuScenes protocol; --protocol kitti evaluates these KITTI \
                 logs by KITTI's classes, --classes chooses others"
            }
            (true, false) => "not classes of the nuScenes protocol; --classes chooses others",
        };
        parts.push(format!(
            "labels with ground truth not evaluated ({why}): {}",
            each.join(", ")
        ));
    }
    if !tracks_only.is_empty() {
        let each: Vec<String> = (tracks_only.iter())
            .map(|(l, [_, tracks])| format!("{l} ({tracks})"))
            .collect();
        parts.push(format!(
            "track boxes of labels without ground truth, not evaluated: {}",
            each.join(", ")
        ));
    }
    (!parts.is_empty()).then(|| parts.join("; "))
}

/// The `baseline` logs scored with the nuScenes protocol (none without a baseline), and
/// their scenes when `keep`.
fn nuscenes_baseline(
    o: &EvalOptions,
    params: &NuscenesParams,
    keep: bool,
    progress: ProgressFn,
) -> Result<(LogPairs, Option<NuscenesResult>, Option<Vec<ColumnScene>>)> {
    if o.baseline.is_empty() {
        return Ok((Vec::new(), None, None));
    }
    let pairs = log_pairs(&o.truth, &o.baseline)?;
    let (scenes, _) = load_columns_logs(o, &pairs, false, progress)?;
    let result = evaluate_columns(&scenes, params);
    Ok((pairs, Some(result), keep.then_some(scenes)))
}

/// The bootstrap of the nuScenes metrics and HOTA over `scenes` (and the change from `base`).
fn nuscenes_bootstrap(
    scenes: &[ColumnScene],
    base: Option<&[ColumnScene]>,
    params: &NuscenesParams,
    block: Option<f64>,
    boot: Options,
) -> Bootstrap {
    let stamps =
        |s: &[ColumnScene]| -> Vec<Vec<u64>> { s.iter().map(|s| s.stamps.clone()).collect() };
    let runs: Vec<Vec<Vec<u64>>> = std::iter::once(scenes).chain(base).map(stamps).collect();
    let units = paired_units(&runs, block);
    let last = &units[units.len() - 1];
    let this = unit_curves(scenes, params, &units[0]);
    let base_curves = base.map(|b| unit_curves(b, params, last));
    let hota = |s, u| centre_hota_by(s, &params.classes, &ByUnit(u)).0;
    let mut runs = vec![hota(scenes, &units[0])];
    runs.extend(base.map(|b| hota(b, last)));
    let (rows, this, base) = aligned(this, base_curves);
    let p = paired::Protocol {
        names: &NUSCENES_METRICS[..],
        metrics: nuscenes_metrics,
    };
    let hota = [HotaGroup {
        names: &HOTA_METRICS,
        runs,
    }];
    paired::run((p, rows), (&this, base.as_deref()), &hota, &units[0], boot)
}

/// The result, refused when no evaluated class had ground truth, with the note on the labels
/// left out.
fn with_truth_checked(
    mut result: NuscenesResult,
    scenes: &[ColumnScene],
    params: &NuscenesParams,
    o: &EvalOptions,
    pairs: &LogPairs,
) -> Result<NuscenesResult> {
    if result.classes.values().all(|m| m.gt.is_nan()) {
        bail!(
            "{}: topic {} has no ground-truth box of the evaluated classes ({}); {}",
            describe(pairs, false),
            o.truth_topic,
            params.classes.join(", "),
            truth_classes(scenes)
        );
    }
    result
        .notes
        .extend(unevaluated_labels(scenes, &params.classes, o, pairs));
    Ok(result)
}

/// `probmot eval` with the nuScenes protocol (the options checked by [`super::evaluate`]).
pub fn run(o: &EvalOptions, progress: ProgressFn) -> Result<EvalReport> {
    let mut params = NuscenesParams::default();
    if !o.classes.is_empty() {
        params.classes = o.classes.clone();
    }
    let pairs = log_pairs(&o.truth, &o.tracks)?;
    // With events the columns keep the boxes' geometry too, to place the events.
    let (scenes, removed) = load_columns_logs(o, &pairs, o.events.is_some(), progress)?;
    progress(Progress::Message("scoring (nuScenes metrics and HOTA)"));
    let ((result, decisions), (hota, hota_notes)) = rayon::join(
        || evaluate_columns_recording(&scenes, &params, o.events.is_some()),
        || centre_hota(&scenes, &params.classes),
    );
    progress(Progress::Done);
    let result = with_truth_checked(result, &scenes, &params, o, &pairs)?;
    let events = (o.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Nuscenes, decisions);
            events::write(out, logs, &pairs, &scenes[..], &o.truth_topic)
        })
        .transpose()?;
    let boot_options = bootstrap_options(o);
    let (base_pairs, baseline, base_scenes) =
        nuscenes_baseline(o, &params, boot_options.is_some(), progress)?;
    progress(Progress::Done);
    let boot = boot_options
        .map(|b| nuscenes_bootstrap(&scenes, base_scenes.as_deref(), &params, o.block, b));

    // The gate, on AMOTA.
    let gate_failures = match &baseline {
        Some(base) => gate(
            o,
            "AMOTA",
            (
                (base.overall.amota, result.overall.amota),
                (result.classes.iter()).filter_map(|(c, m)| {
                    base.classes.get(c).map(|o| (c.as_str(), o.amota, m.amota))
                }),
            ),
            boot.as_ref(),
        ),
        None => Vec::new(),
    };
    let found = Found {
        pairs: &pairs,
        result: &result,
        hota: (&hota, &hota_notes),
        baseline: baseline.as_ref().map(|b| (&base_pairs[..], b)),
        removed: &removed,
        events: events.as_ref(),
        boot: boot.as_ref(),
    };
    Ok(match o.json {
        true => EvalReport {
            json: Some(json(o, &scenes, &params, &found, &gate_failures)),
            text: String::new(),
            gate_failures,
        },
        false => EvalReport {
            json: None,
            text: text(o, &found),
            gate_failures,
        },
    })
}

/// What the nuScenes job found, for its report.
struct Found<'a> {
    pairs: &'a [(PathBuf, PathBuf)],
    result: &'a NuscenesResult,
    hota: (&'a BTreeMap<String, Hota>, &'a [String]),
    baseline: Option<(&'a [(PathBuf, PathBuf)], &'a NuscenesResult)>,
    removed: &'a FilterCounts,
    events: Option<&'a events::EventsReport>,
    boot: Option<&'a Bootstrap>,
}

/// The `--json` document.
fn json(
    o: &EvalOptions,
    scenes: &[ColumnScene],
    params: &NuscenesParams,
    f: &Found,
    failures: &[String],
) -> serde_json::Value {
    let per_log = per_log_json(scenes, f.pairs, params);
    let mut v = serde_json::json!({
        "logs": paths(f.pairs), "result": f.result, "per_log": per_log,
        "baseline": f.baseline.map(|(p, b)| serde_json::json!({"logs": paths(p), "result": b})),
        "gate_failures": failures,
        "hota": {"similarity": "bev_centre_distance", "zero_distance_m": ZERO_DISTANCE,
                 "classes": f.hota.0, "notes": f.hota.1},
        "range_filter": o.max_range.as_ref().map(|r| {
            let c = f.removed.range.unwrap_or_default();
            serde_json::json!({
            "ranges": r.per_class, "other": r.other, "ego_topic": o.ego_topic,
            "removed_truth_boxes": c.truth, "removed_track_boxes": c.tracks})
        }),
        "filters": filters_json(o, f.removed),
    });
    if let Some(e) = f.events {
        v["events"] = e.json();
    }
    if let Some(b) = f.boot {
        v["bootstrap"] = b.json();
    }
    v
}

/// The text report.
fn text(o: &EvalOptions, f: &Found) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{}", header("nuScenes tracking metrics", f.pairs, o));
    s.push_str(&table(&COLUMNS, &rows(f.result)));
    s.push_str(
        "\nHOTA (TrackEval's definition; similarity max(0, 1 - BEV centre distance / 2 m)):\n",
    );
    s.push_str(&table(&HOTA_COLUMNS, &hota_rows(f.hota.0, "")));
    if let Some((base_pairs, base)) = f.baseline {
        let _ = writeln!(s, "\nbaseline {}:", describe(base_pairs, true));
        s.push_str(&table(&COLUMNS, &rows(base)));
        let mut delta = Vec::new();
        for ((name, new), (_, old)) in rows(f.result).into_iter().zip(rows(base)) {
            delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
        }
        s.push_str(&change_table(&legend::NUSCENES, &COLUMNS, &delta));
    }
    s.push_str(&f.boot.map(Bootstrap::text).unwrap_or_default());
    for line in filter_notes(f.removed, o.min_points) {
        let _ = writeln!(s, "note: {line}");
    }
    for n in f.result.notes.iter().chain(f.hota.1) {
        let _ = writeln!(s, "note: {n}");
    }
    s.push_str(&f.events.map(|e| e.text()).unwrap_or_default());
    s.push_str(&footer(o, &[legend::NUSCENES, legend::HOTA]));
    s
}
