//! What a bootstrap of an evaluation found, as `--json` and as text, and the interval rule of
//! the regression gate.

use std::fmt::Write;

use serde_json::{json, Value};

use super::{Change, Estimate, Options};

/// What the bootstrap found: per row (the classes, then `overall`), per metric.
#[derive(Debug, Clone)]
pub enum Found {
    /// Each metric with its interval (no baseline).
    Estimates(Vec<Vec<Estimate>>),
    /// Each metric's change from the baseline with its paired interval.
    Changes(Vec<Vec<Change>>),
}

/// The bootstrap of one evaluation, for the report and the gate.
#[derive(Debug, Clone)]
pub struct Bootstrap {
    /// The metrics' names: the protocol's, then each HOTA group's.
    pub names: Vec<&'static str>,
    /// How many of `names` each table takes (the protocol's first).
    pub groups: Vec<usize>,
    /// The rows: the classes, then `overall`.
    pub rows: Vec<String>,
    /// Per row, per metric.
    pub found: Found,
    /// The number of units and the block length (`None`: whole logs).
    pub units: (usize, Option<f64>),
    /// Resamples and seed.
    pub options: Options,
}

impl Bootstrap {
    /// Value (or change), interval and whether it is undefined (no value in either run) of
    /// metric `k` of row `i`.
    fn cell(&self, i: usize, k: usize) -> (f64, [f64; 2], bool) {
        match &self.found {
            Found::Estimates(e) => (e[i][k].value, e[i][k].ci95, e[i][k].value.is_nan()),
            Found::Changes(c) => {
                let c = &c[i][k];
                (c.delta, c.ci95, c.this.is_nan() && c.baseline.is_nan())
            }
        }
    }

    /// The JSON object: per row, per metric, the estimate or change with `ci95` (a HOTA metric
    /// of a class HOTA does not evaluate is left out).
    pub fn json(&self) -> Value {
        let mut classes = serde_json::Map::new();
        let mut overall = Value::Null;
        let protocol = self.groups.first().copied().unwrap_or(0);
        for (i, row) in self.rows.iter().enumerate() {
            let mut m = serde_json::Map::new();
            for (k, name) in self.names.iter().enumerate() {
                if k >= protocol && self.cell(i, k).2 {
                    continue;
                }
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
        (0..self.names.len()).all(|k| self.cell(i, k).2)
    }

    /// The text tables (the protocol's metrics, then each HOTA group's): per row, each metric
    /// as `value [low, high]`.
    pub fn text(&self) -> String {
        let what = match self.units.1 {
            Some(b) => format!("{} blocks of {b} s", self.units.0),
            None => format!("{} logs", self.units.0),
        };
        let (resamples, seed) = (self.options.resamples, self.options.seed);
        let mut s = match self.found {
            Found::Estimates(_) => format!("\n95 % bootstrap intervals ({resamples} resamples of {what}, seed {seed}):\n"),
            Found::Changes(_) => format!("\nchange (this - baseline) with its paired 95 % interval ({resamples} resamples of {what}, seed {seed}):\n"),
        };
        let mut start = 0;
        for (g, &len) in self.groups.iter().enumerate() {
            if g > 0 {
                s.push('\n');
            }
            self.table(&mut s, start..start + len);
            start += len;
        }
        s
    }

    /// One table of the metrics `cols`: the rows with a value among them.
    fn table(&self, s: &mut String, cols: std::ops::Range<usize>) {
        let _ = write!(s, "{:<12}", "class");
        for n in &self.names[cols.clone()] {
            let _ = write!(s, "  {:>30}", n.to_uppercase());
        }
        s.push('\n');
        for (i, row) in self.rows.iter().enumerate() {
            if cols.clone().all(|k| self.cell(i, k).2) {
                continue;
            }
            let _ = write!(s, "{row:<12}");
            for k in cols.clone() {
                let (v, ci, _) = self.cell(i, k);
                let cell = format!("{} [{}, {}]", num(v), num(ci[0]), num(ci[1]));
                let _ = write!(s, "  {cell:>30}");
            }
            s.push('\n');
        }
    }

    /// The gate's failures on the first (main) metric by the interval rule: a fall larger than
    /// `max_drop` points whose interval lies below 0 (overall, and per class with `per_class`).
    pub fn gate(&self, metric: &str, max_drop: f64, per_class: bool) -> Vec<String> {
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
