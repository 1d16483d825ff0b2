//! What the two protocols' jobs share: the report's header, footer and change table, the log
//! pairs, the progress of reading, and the regression gate with the bootstrap it may need.

use std::path::{Path, PathBuf};

use super::options::{EvalOptions, Gate};
use crate::eval::bootstrap::report::Bootstrap;
use crate::eval::bootstrap::Options;
use crate::eval::legend::Section;
use crate::pipeline::progress::{Progress, ProgressFn};

/// `(truth, tracks)` file pairs, one per log.
pub type LogPairs = Vec<(PathBuf, PathBuf)>;

/// Starts reading `pairs`: the total of their bytes (a file holding both channels is read
/// twice) as the progress's length; each log then reports its bytes read as advances.
pub fn reading(progress: ProgressFn, pairs: &[(PathBuf, PathBuf)]) {
    let files: Vec<&Path> = (pairs.iter())
        .flat_map(|(t, r)| [t.as_path(), r.as_path()])
        .collect();
    let total = (files.iter())
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    progress(Progress::Length(total));
    progress(Progress::Position(0));
}

/// The regression gate: what fell by more than `max_drop` percentage points, as
/// `(baseline, this)` values of the main metric, overall and (with `per_class`) per class. An
/// overall value that has become undefined (no ground truth that counts) also fails.
pub fn gate_failures<'a>(
    metric: &str,
    (old, new): (f64, f64),
    classes: impl Iterator<Item = (&'a str, f64, f64)>,
    max_drop: f64,
    per_class: bool,
) -> Vec<String> {
    let mut failures = Vec::new();
    let d = (old - new) * 100.0;
    if d > max_drop || (d.is_nan() && old.is_finite()) {
        failures.push(format!(
            "overall {metric} fell by {d:.2} points ({old:.4} -> {new:.4}), more than --max-drop {max_drop}"
        ));
    }
    if per_class {
        for (c, old, new) in classes {
            let d = (old - new) * 100.0;
            if d > max_drop {
                failures.push(format!(
                    "{c}: {metric} fell by {d:.2} points ({old:.4} -> {new:.4})"
                ));
            }
        }
    }
    failures
}

/// The bootstrap's options: `bootstrap` resamples, or 1000 for the interval gate.
pub fn bootstrap_options(o: &EvalOptions) -> Option<Options> {
    let gate = o.max_drop.is_some() && o.gate == Gate::Interval && !o.baseline.is_empty();
    let resamples = o.bootstrap.or(gate.then_some(1000))?;
    Some(Options {
        resamples,
        seed: o.seed,
    })
}

/// The gate's failures by the rule `o.gate` says: the point rule on the protocol's values
/// (`point`: overall then per class as `(class, baseline, this)`), or the interval rule on the
/// bootstrap.
pub fn gate<'a>(
    o: &EvalOptions,
    metric: &str,
    point: ((f64, f64), impl Iterator<Item = (&'a str, f64, f64)>),
    boot: Option<&Bootstrap>,
) -> Vec<String> {
    let Some(max_drop) = o.max_drop.filter(|_| !o.baseline.is_empty()) else {
        return Vec::new();
    };
    match (o.gate, boot) {
        (Gate::Interval, Some(b)) => b.gate(metric, max_drop, o.per_class),
        _ => gate_failures(metric, point.0, point.1, max_drop, o.per_class),
    }
}

/// "file" or "N logs" for the report's header.
pub fn describe(pairs: &[(PathBuf, PathBuf)], tracks: bool) -> String {
    match pairs {
        [(t, r)] => if tracks { r } else { t }.display().to_string(),
        _ => format!("{} logs", pairs.len()),
    }
}

/// The report's header: its title, then the tracks and truth files with their topics, one
/// labelled line each.
pub fn header(title: &str, pairs: &[(PathBuf, PathBuf)], o: &EvalOptions) -> String {
    format!(
        "{title}\n  tracks: {} (topic {})\n  truth:  {} (topic {})",
        describe(pairs, true),
        o.tracks_topic,
        describe(pairs, false),
        o.truth_topic
    )
}

/// The end of a text report: with `explain` the legend of `tables`, else a line saying where
/// it is.
pub fn footer(o: &EvalOptions, tables: &[Section]) -> String {
    match o.explain {
        true => format!("\n{}", crate::eval::legend::text(tables)),
        false => "\n`probmot eval --explain` says what each column means, its unit and which way \
                  is better.\n"
            .to_string(),
    }
}

/// The change table (`this - baseline`) with its row `better`: the sign of an improvement per
/// column.
pub fn change_table(table: &Section, columns: &[&str], delta: &[(String, Vec<f64>)]) -> String {
    let signs = table.signs(columns);
    let t = crate::eval::report::table_with_row(columns, ("better", &signs), delta);
    format!("\nchange (this - baseline; row `better`: + higher is better, - lower is better):\n{t}")
}

/// The logs as JSON: `[{"truth": ..., "tracks": ...}]`.
pub fn paths(pairs: &[(PathBuf, PathBuf)]) -> serde_json::Value {
    serde_json::json!(pairs
        .iter()
        .map(|(t, r)| serde_json::json!({"truth": t, "tracks": r}))
        .collect::<Vec<_>>())
}
