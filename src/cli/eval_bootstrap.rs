//! `eval --bootstrap`: the intervals of the metrics (or of their change from `--baseline`)
//! from the protocols' per-unit curves ([`probmot::eval::bootstrap`]), their report and the
//! interval rule of the regression gate.

use std::fmt::Write;

use probmot::eval::bootstrap::{changes, estimates, Change, Estimate, Options, Units};
use serde_json::{json, Value};

use super::eval_args::{gate_failures, EvalArgs, Gate};

/// The bootstrap's options: `--bootstrap N`, or 1000 resamples for the interval gate.
pub(super) fn options(a: &EvalArgs) -> Option<Options> {
    let gate = a.max_drop.is_some() && a.gate == Gate::Interval && !a.baseline.is_empty();
    let resamples = a.bootstrap.or(gate.then_some(1000))?;
    Some(Options {
        resamples: resamples as usize,
        seed: a.seed,
    })
}

/// What the bootstrap found: per row (the classes, then `overall`), per metric.
pub(super) enum Found {
    /// Each metric with its interval (no baseline).
    Estimates(Vec<Vec<Estimate>>),
    /// Each metric's change from the baseline with its paired interval.
    Changes(Vec<Vec<Change>>),
}

/// The bootstrap of one evaluation, for the report and the gate.
pub(super) struct Bootstrap {
    pub names: &'static [&'static str],
    pub rows: Vec<String>,
    pub found: Found,
    pub units: (usize, Option<f64>),
    pub options: Options,
}

/// Runs the bootstrap: `metrics(curves, weights)` gives per row (`rows`, then `overall`) the
/// `names.len()` metrics; `this` and `base` are each run's curves, aligned by row.
pub(super) fn run<C: Sync>(
    (names, rows): (&'static [&'static str], Vec<String>),
    (this, base): (&[C], Option<&[C]>),
    metrics: fn(&[C], &[u32]) -> Vec<f64>,
    units: &Units,
    options: Options,
) -> Bootstrap {
    let n = units.count;
    let found = match base {
        None => Found::Estimates(regroup(
            estimates(n, options, |w| metrics(this, w)),
            names.len(),
        )),
        Some(base) => Found::Changes(regroup(
            changes(n, options, |w| metrics(this, w), |w| metrics(base, w)),
            names.len(),
        )),
    };
    let mut rows = rows;
    rows.push("overall".into());
    Bootstrap {
        names,
        rows,
        found,
        units: (n, units.block_s),
        options,
    }
}

fn regroup<T: Clone>(v: Vec<T>, k: usize) -> Vec<Vec<T>> {
    v.chunks(k).map(<[T]>::to_vec).collect()
}

impl Bootstrap {
    /// The JSON object: per row, per metric, the estimate or change with `ci95`.
    pub(super) fn json(&self) -> Value {
        let mut classes = serde_json::Map::new();
        let mut overall = Value::Null;
        for (i, row) in self.rows.iter().enumerate() {
            let mut m = serde_json::Map::new();
            for (k, name) in self.names.iter().enumerate() {
                let v = match &self.found {
                    Found::Estimates(e) => serde_json::to_value(e[i][k]),
                    Found::Changes(c) => serde_json::to_value(c[i][k]),
                };
                m.insert(name.to_string(), v.unwrap_or(Value::Null));
            }
            if i + 1 == self.rows.len() {
                overall = Value::Object(m);
            } else if !self.empty(i) {
                classes.insert(row.clone(), Value::Object(m));
            }
        }
        json!({
            "resamples": self.options.resamples, "seed": self.options.seed,
            "units": if self.units.1.is_some() { "blocks" } else { "logs" },
            "block_s": self.units.1, "n_units": self.units.0,
            "classes": classes, "overall": overall,
        })
    }

    /// Whether row `i` has no value at all (a class without ground truth).
    fn empty(&self, i: usize) -> bool {
        match &self.found {
            Found::Estimates(e) => e[i].iter().all(|e| e.value.is_nan()),
            Found::Changes(c) => c[i].iter().all(|c| c.this.is_nan() && c.baseline.is_nan()),
        }
    }

    /// The text table: per row, each metric as `value [low, high]`.
    pub(super) fn text(&self) -> String {
        let what = match self.units.1 {
            Some(b) => format!("{} blocks of {b} s", self.units.0),
            None => format!("{} logs", self.units.0),
        };
        let mut s = match self.found {
            Found::Estimates(_) => format!("\n95 % bootstrap intervals ({} resamples of {what}, seed {}):\n", self.options.resamples, self.options.seed),
            Found::Changes(_) => format!("\nchange (this - baseline) with its paired 95 % interval ({} resamples of {what}, seed {}):\n", self.options.resamples, self.options.seed),
        };
        let _ = write!(s, "{:<12}", "class");
        for n in self.names {
            let _ = write!(s, "  {:>30}", n.to_uppercase());
        }
        s.push('\n');
        for (i, row) in self.rows.iter().enumerate() {
            if self.empty(i) {
                continue;
            }
            let _ = write!(s, "{row:<12}");
            for k in 0..self.names.len() {
                let (v, ci) = match &self.found {
                    Found::Estimates(e) => (e[i][k].value, e[i][k].ci95),
                    Found::Changes(c) => (c[i][k].delta, c[i][k].ci95),
                };
                let cell = format!("{} [{}, {}]", num(v), num(ci[0]), num(ci[1]));
                let _ = write!(s, "  {cell:>30}");
            }
            s.push('\n');
        }
        s
    }

    /// The gate's failures on the first (main) metric: by `--gate point` the fall alone, by
    /// `--gate interval` a fall larger than `max_drop` points whose interval lies below 0.
    pub(super) fn gate(&self, metric: &str, max_drop: f64, per_class: bool) -> Vec<String> {
        let Found::Changes(c) = &self.found else {
            return Vec::new();
        };
        let last = self.rows.len() - 1;
        let mut out = Vec::new();
        for (i, row) in self.rows.iter().enumerate() {
            let ch = &c[i][0];
            if (i != last && !per_class) || self.empty(i) {
                continue;
            }
            let drop = -ch.delta * 100.0;
            let undefined = i == last && ch.delta.is_nan() && ch.baseline.is_finite();
            if undefined || (drop > max_drop && ch.below_zero()) {
                out.push(format!(
                    "{row}: {metric} fell by {drop:.2} points ({:.4} -> {:.4}), more than \
                     --max-drop {max_drop}, and its 95 % interval [{:+.4}, {:+.4}] lies below 0",
                    ch.baseline, ch.this, ch.ci95[0], ch.ci95[1]
                ));
            }
        }
        out
    }
}

fn num(v: f64) -> String {
    if v.is_nan() {
        "-".into()
    } else {
        format!("{v:+.4}")
    }
}

/// The gate's failures by the rule `a.gate` says: the point rule on the protocol's values
/// (`point`: overall then per class as `(class, baseline, this)`), or the interval rule on the
/// bootstrap.
pub(super) fn gate<'a>(
    a: &EvalArgs,
    metric: &str,
    point: ((f64, f64), impl Iterator<Item = (&'a str, f64, f64)>),
    boot: Option<&Bootstrap>,
) -> Vec<String> {
    let Some(max_drop) = a.max_drop.filter(|_| !a.baseline.is_empty()) else {
        return Vec::new();
    };
    match (a.gate, boot) {
        (Gate::Interval, Some(b)) => b.gate(metric, max_drop, a.per_class),
        _ => gate_failures(metric, point.0, point.1, max_drop, a.per_class),
    }
}

/// The stamps of each run's logs, and the units numbered alike over them (the first run's,
/// then the baseline's).
pub(super) fn paired_units(runs: &[Vec<Vec<u64>>], block: Option<f64>) -> Vec<Units> {
    let runs: Vec<Vec<&[u64]>> = (runs.iter())
        .map(|r| r.iter().map(Vec::as_slice).collect())
        .collect();
    Units::choose_paired(&runs, block)
}

/// The rows both runs have (the first run's order), and each run's curves in that order.
pub(super) fn aligned<C: Clone>(
    this: Vec<(String, C)>,
    base: Option<Vec<(String, C)>>,
) -> (Vec<String>, Vec<C>, Option<Vec<C>>) {
    let rows: Vec<String> = (this.iter())
        .map(|c| c.0.clone())
        .filter(|c| base.as_ref().is_none_or(|b| b.iter().any(|x| x.0 == *c)))
        .collect();
    let pick = |v: &[(String, C)]| -> Vec<C> {
        (rows.iter())
            .filter_map(|r| v.iter().find(|x| &x.0 == r).map(|x| x.1.clone()))
            .collect()
    };
    let (t, b) = (pick(&this), base.as_deref().map(pick));
    (rows, t, b)
}
