//! `probmot eval`: the checks of the arguments, and the nuScenes protocol (the KITTI one is in
//! [`super::eval_kitti`]).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;

use probmot::eval::columns::{boxes_outside, load_columns, ColumnScene};
use probmot::eval::filters::{apply_bike_racks, apply_min_points, read_racks, FilterCounts, Rack};
use probmot::eval::hota::centre::{centre_hota, centre_hota_by, ZERO_DISTANCE};
use probmot::eval::hota::{hota_rows, HOTA_COLUMNS};

use probmot::eval::legend;
use probmot::eval::nuscenes::{
    evaluate_columns, evaluate_columns_recording, NuscenesParams, NuscenesResult,
};
use probmot::eval::range::{
    apply_range_filter, read_ego_positions, EgoPositions, RangeFilter, RangeRemoved,
};
use probmot::eval::report::table;
use probmot::eval::scene::Scene;
use probmot::mcapio::LabelledBox;
use probmot::pipeline::kitti_io::is_kitti_import;
use probmot::pipeline::log_pairs::log_pairs;
use rayon::prelude::*;

use super::eval_args::{
    change_table, describe, footer, gate_exit, header, paths, reading_bar, scoring_spinner,
    EvalArgs, LogPairs, Protocol,
};
use super::eval_bootstrap;
use super::eval_events;
use probmot::eval::bootstrap::curve::{nuscenes_metrics, NUSCENES_METRICS};
use probmot::eval::bootstrap::paired::{self, aligned, paired_units, HotaGroup, HOTA_METRICS};
use probmot::eval::bootstrap::report::Bootstrap;
use probmot::eval::bootstrap::Options;
use probmot::eval::events::Protocol as EventsProtocol;
use probmot::eval::hota::units::ByUnit;
use probmot::eval::nuscenes::curve::unit_curves;

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

/// The filters that are on for one log, with the ego poses and racks of its truth file.
struct LogFilters<'a> {
    args: &'a EvalArgs,
    truth: &'a Path,
    ego: Option<(&'a RangeFilter, EgoPositions)>,
    racks: Option<BTreeMap<u64, Vec<Rack>>>,
}

impl<'a> LogFilters<'a> {
    fn new(a: &'a EvalArgs, truth: &'a Path) -> Result<LogFilters<'a>> {
        let ego = match &a.max_range {
            Some(filter) => Some((filter, read_ego_positions(truth, &a.ego_topic)?)),
            None => None,
        };
        let racks = if a.bike_racks {
            Some(read_racks(truth, &a.racks_topic).with_context(|| {
                format!(
                    "--bike-racks needs the bicycle racks of each scene on {} (`probmot import \
                     nuscenes` writes them from sample_annotation.json)",
                    a.racks_topic
                )
            })?)
        } else {
            None
        };
        Ok(LogFilters {
            args: a,
            truth,
            ego,
            racks,
        })
    }

    /// Applies the filters to `scene`, in the devkit's order (range, points, racks).
    fn apply(&self, scene: &mut Scene) -> Result<FilterCounts> {
        let mut counts = FilterCounts::default();
        if let Some((filter, ego)) = &self.ego {
            counts.range = Some(apply_range_filter(scene, filter, ego).with_context(|| {
                format!("--max-range with the ego poses of {}", self.truth.display())
            })?);
        }
        if let Some(min) = self.args.min_points {
            counts.points = Some(apply_min_points(scene, min).with_context(|| {
                format!(
                    "--min-points: {} (topic {})",
                    self.truth.display(),
                    self.args.truth_topic
                )
            })?);
        }
        if let Some(racks) = &self.racks {
            counts.bike_racks = Some(apply_bike_racks(scene, racks));
        }
        Ok(counts)
    }

    /// [`LogFilters::apply`] to the boxes of one message (truth or tracks) of `scene_name` at
    /// `stamp`: every filter is a rule per frame, so filtering message by message while the log
    /// streams removes the same boxes.
    fn apply_message(
        &self,
        scene_name: &str,
        (stamp, boxes, truth): (u64, &mut Vec<LabelledBox>, bool),
        counts: &mut FilterCounts,
    ) -> Result<()> {
        if self.ego.is_none() && self.args.min_points.is_none() && self.racks.is_none() {
            return Ok(());
        }
        let mut one = Scene {
            name: scene_name.to_string(),
            frames: vec![(stamp, Vec::new(), Vec::new())],
        };
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        let c = self.apply(&mut one);
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        counts.add(&c?);
        Ok(())
    }
}

/// The scenes, and the filters' counts summed over them.
fn sum_counts<S>(loaded: Vec<(S, FilterCounts)>) -> (Vec<S>, FilterCounts) {
    let mut total = FilterCounts::default();
    let scenes = loaded
        .into_iter()
        .map(|(s, c)| {
            total.add(&c);
            s
        })
        .collect();
    (scenes, total)
}

/// [`load_logs`] for the nuScenes protocol: each log streamed into columns
/// ([`load_columns`]), filtered message by message.
fn load_columns_logs(
    a: &EvalArgs,
    pairs: &[(PathBuf, PathBuf)],
    geometry: bool,
) -> Result<(Vec<ColumnScene>, FilterCounts)> {
    let bar = reading_bar(a, pairs);
    let loaded: Vec<(ColumnScene, FilterCounts)> = pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let filters = LogFilters::new(a, truth)?;
            let name = tracks
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut counts = FilterCounts::default();
            let scene = load_columns(
                (truth, &a.truth_topic),
                (tracks, &a.tracks_topic),
                &|n| bar.inc(n),
                &mut |stamp, boxes, is_truth| {
                    filters.apply_message(&name, (stamp, boxes, is_truth), &mut counts)
                },
                geometry,
            )?;
            Ok((scene, counts))
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    Ok(sum_counts(loaded))
}

pub fn run(mut a: EvalArgs) -> Result<ExitCode> {
    super::eval_args::refuse_stray(&a)?;
    if a.explain && a.truth.is_empty() {
        print!("{}", legend::text(&legend::SECTIONS));
        return Ok(ExitCode::SUCCESS);
    }
    let nuscenes_filters = a.max_range.is_some() || a.min_points.is_some() || a.bike_racks;
    if a.devkit {
        a.max_range.get_or_insert_with(RangeFilter::nuscenes);
        a.min_points.get_or_insert(1);
        a.bike_racks = true;
    }
    if a.max_drop.is_some() && a.baseline.is_empty() {
        bail!("--max-drop needs --baseline");
    }
    if let Some(b) = a.block.filter(|b| !(*b > 0.0 && b.is_finite())) {
        bail!("--block must be a positive number of seconds, got {b}");
    }
    if let Some(d) = a.max_drop.filter(|d| !(*d >= 0.0 && d.is_finite())) {
        bail!("--max-drop must be a number of points >= 0, got {d}");
    }
    match a.protocol {
        Protocol::Nuscenes => {
            if a.iou.is_some() {
                bail!("--iou is a KITTI option (the nuScenes protocol matches by 2 m centre distance)");
            }
            if a.means.is_some() {
                bail!("--means is a KITTI option (the nuScenes devkit averages each track's score once)");
            }
            run_nuscenes(a)
        }
        Protocol::Kitti => {
            if a.devkit || nuscenes_filters {
                bail!(
                    "--devkit, --max-range, --min-points and --bike-racks are nuScenes options \
                     (the KITTI protocol has no range, points or bicycle-rack filter)"
                );
            }
            super::eval_kitti::run_kitti(a)
        }
    }
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
    a: &EvalArgs,
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
        let why = match (a.classes.is_empty(), kitti) {
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

/// The `--baseline` logs scored with the nuScenes protocol (none without `--baseline`), and
/// their scenes when `keep`.
fn nuscenes_baseline(
    a: &EvalArgs,
    params: &NuscenesParams,
    keep: bool,
) -> Result<(LogPairs, Option<NuscenesResult>, Option<Vec<ColumnScene>>)> {
    if a.baseline.is_empty() {
        return Ok((Vec::new(), None, None));
    }
    let pairs = log_pairs(&a.truth, &a.baseline)?;
    let (scenes, _) = load_columns_logs(a, &pairs, false)?;
    let result = evaluate_columns(&scenes, params);
    Ok((pairs, Some(result), keep.then_some(scenes)))
}

/// The bootstrap of the nuScenes metrics and HOTA over `scenes` (and the change from `base`).
fn nuscenes_bootstrap(
    scenes: &[ColumnScene],
    base: Option<&[ColumnScene]>,
    params: &NuscenesParams,
    a: &EvalArgs,
    o: Options,
) -> Bootstrap {
    let stamps =
        |s: &[ColumnScene]| -> Vec<Vec<u64>> { s.iter().map(|s| s.stamps.clone()).collect() };
    let runs: Vec<Vec<Vec<u64>>> = std::iter::once(scenes).chain(base).map(stamps).collect();
    let units = paired_units(&runs, a.block);
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
    paired::run((p, rows), (&this, base.as_deref()), &hota, &units[0], o)
}

/// The result, refused when no evaluated class had ground truth, with the note on the labels
/// left out.
fn with_truth_checked(
    mut result: NuscenesResult,
    scenes: &[ColumnScene],
    params: &NuscenesParams,
    a: &EvalArgs,
    pairs: &LogPairs,
) -> Result<NuscenesResult> {
    if result.classes.values().all(|m| m.gt.is_nan()) {
        bail!(
            "{}: topic {} has no ground-truth box of the evaluated classes ({}); {}",
            describe(pairs, false),
            a.truth_topic,
            params.classes.join(", "),
            truth_classes(scenes)
        );
    }
    result
        .notes
        .extend(unevaluated_labels(scenes, &params.classes, a, pairs));
    Ok(result)
}

fn run_nuscenes(a: EvalArgs) -> Result<ExitCode> {
    let mut params = NuscenesParams::default();
    if !a.classes.is_empty() {
        params.classes = a.classes.clone();
    }
    let pairs = log_pairs(&a.truth, &a.tracks)?;
    // With --events the columns keep the boxes' geometry too, to place the events.
    let (scenes, removed) = load_columns_logs(&a, &pairs, a.events.is_some())?;
    let spinner = scoring_spinner(&a, "nuScenes metrics and HOTA");
    let ((result, decisions), (hota, hota_notes)) = rayon::join(
        || evaluate_columns_recording(&scenes, &params, a.events.is_some()),
        || centre_hota(&scenes, &params.classes),
    );
    spinner.finish_and_clear();
    let result = with_truth_checked(result, &scenes, &params, &a, &pairs)?;
    let events = (a.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Nuscenes, decisions);
            eval_events::write(out, logs, &pairs, &scenes[..], &a.truth_topic)
        })
        .transpose()?;
    let boot_options = eval_bootstrap::options(&a);
    let (base_pairs, baseline, base_scenes) =
        nuscenes_baseline(&a, &params, boot_options.is_some())?;
    let boot =
        boot_options.map(|o| nuscenes_bootstrap(&scenes, base_scenes.as_deref(), &params, &a, o));

    // The gate, on AMOTA.
    let failures = match &baseline {
        Some(base) => eval_bootstrap::gate(
            &a,
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

    if a.json {
        let per_log = per_log_json(&scenes, &pairs, &params);
        let mut v = serde_json::json!({
            "logs": paths(&pairs), "result": result, "per_log": per_log,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"logs": paths(&base_pairs), "result": b})),
            "gate_failures": failures,
            "hota": {"similarity": "bev_centre_distance", "zero_distance_m": ZERO_DISTANCE,
                     "classes": hota, "notes": hota_notes},
            "range_filter": a.max_range.as_ref().map(|f| {
                let r = removed.range.unwrap_or_default();
                serde_json::json!({
                "ranges": f.per_class, "other": f.other, "ego_topic": a.ego_topic,
                "removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks})
            }),
            "filters": filters_json(&a, &removed),
        });
        if let Some(e) = &events {
            v["events"] = e.json();
        }
        if let Some(b) = &boot {
            v["bootstrap"] = b.json();
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{}", header("nuScenes tracking metrics", &pairs, &a));
        print!("{}", table(&COLUMNS, &rows(&result)));
        println!(
            "\nHOTA (TrackEval's definition; similarity max(0, 1 - BEV centre distance / 2 m)):"
        );
        print!("{}", table(&HOTA_COLUMNS, &hota_rows(&hota, "")));
        if let Some(base) = &baseline {
            println!("\nbaseline {}:", describe(&base_pairs, true));
            print!("{}", table(&COLUMNS, &rows(base)));
            let mut delta = Vec::new();
            for ((name, new), (_, old)) in rows(&result).into_iter().zip(rows(base)) {
                delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
            }
            print!("{}", change_table(&legend::NUSCENES, &COLUMNS, &delta));
        }
        print!("{}", boot.as_ref().map(Bootstrap::text).unwrap_or_default());
        for line in filter_notes(&removed, a.min_points) {
            println!("note: {line}");
        }
        for n in result.notes.iter().chain(&hota_notes) {
            println!("note: {n}");
        }
        print!("{}", events.as_ref().map(|e| e.text()).unwrap_or_default());
        print!("{}", footer(&a, &[legend::NUSCENES, legend::HOTA]));
    }
    Ok(gate_exit(&failures))
}

/// The filters that ran, in the devkit's order, with what each removed (JSON).
fn filters_json(a: &EvalArgs, c: &FilterCounts) -> serde_json::Value {
    let counts = |r: &RangeRemoved| serde_json::json!({"removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks});
    serde_json::json!({
        "devkit": a.devkit,
        "range": c.range.as_ref().map(counts),
        "min_points": c.points.as_ref().map(|r| serde_json::json!({
            "min": a.min_points, "removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks})),
        "bike_racks": c.bike_racks.as_ref().map(|r| serde_json::json!({
            "topic": a.racks_topic, "removed_truth_boxes": r.truth,
            "removed_track_boxes": r.tracks})),
    })
}

/// One line per filter that ran, in the devkit's order.
fn filter_notes(c: &FilterCounts, min_points: Option<u64>) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(r) = c.range {
        out.push(format!(
            "range filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    if let (Some(r), Some(n)) = (c.points, min_points) {
        out.push(format!(
            "points filter (fewer than {n} lidar + radar points) removed {} ground-truth boxes",
            r.truth
        ));
    }
    if let Some(r) = c.bike_racks {
        out.push(format!(
            "bicycle-rack filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    out
}
