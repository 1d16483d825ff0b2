//! A tune's report as text (the held-out table, the gains, the per-class summary) and as JSON,
//! as `probmot tune` prints them.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use super::files::{protocol_name, TuneFilesReport};
use super::{overall, ClassTune, CvReport, HeldOutLoss, TuneOptions};

/// A score x 100 with two decimals, `-` when there is none.
fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2}", 100.0 * v)
    } else {
        "-".into()
    }
}

/// What a class that was not searched got: the same words in the table and the summary.
/// `kept_on_loss`: the final tune kept it for its held-out loss (the folds never do).
fn not_searched(o: &TuneOptions, kept_on_loss: bool) -> &'static str {
    if kept_on_loss {
        "lost held-out (--keep-base-on-loss): the base's own settings and noise"
    } else if o.limits.shared {
        "too few trajectories: shared settings"
    } else {
        "too few trajectories: the base's own settings and noise"
    }
}

impl TuneFilesReport {
    /// The report as JSON, with the config's path `output`.
    pub fn json(&self, output: &Path) -> serde_json::Value {
        let t = &self.tuned;
        serde_json::json!({
            "output": output.display().to_string(),
            "options": self.options,
            "warnings": self.warnings,
            "cross_validation": self.cv,
            "held_out_losses": self.losses,
            "final": { "shared": t.shared, "classes": t.classes, "scored": t.scored },
        })
    }

    /// The report as text: the classes scored, the cross-validation table, the final tune's
    /// line per class and the config's path `output`.
    pub fn text(&self, output: &Path) -> String {
        let o = &self.options;
        let t = &self.tuned;
        let mut s = String::new();
        let scored: Vec<&str> = t.classes.iter().map(|c| c.label.as_str()).collect();
        let _ = writeln!(
            s,
            "scored with the {} protocol: {} (its classes with detections in the logs); other \
             classes keep the base's settings with the fitted noise{}",
            protocol_name(o.scoring.protocol),
            scored.join(", "),
            match o.limits.pool_reporting {
                true => " and the pooled reporting options",
                false => "",
            }
        );
        if let Some(cv) = &self.cv {
            s.push_str(&table(cv, o));
        }
        for c in &t.classes {
            let _ = writeln!(
                s,
                "{}: {} trajector{}, training {} base {} -> shared {} -> {} ({})",
                c.label,
                c.trajectories,
                if c.trajectories == 1 { "y" } else { "ies" },
                o.scoring.search_metric(),
                pct(c.base_score),
                pct(c.shared_score),
                pct(c.score),
                if c.refined {
                    "searched"
                } else {
                    not_searched(o, o.keep_base.contains(&c.label))
                }
            );
        }
        let _ = writeln!(s, "wrote {}", output.display());
        s
    }
}

/// The warning for a class that lost held-out on a fold.
pub fn loss_warning(l: &HeldOutLoss) -> String {
    format!(
        "{} on fold {}: the settings tuned on its {} training trajectories scored {} held-out \
         against the base's {}; too few to tune it? (--min-tracks above {}, or \
         --keep-base-on-loss, keeps the base's settings)",
        l.label,
        l.fold,
        l.trajectories,
        pct(l.tuned),
        pct(l.base),
        l.trajectories
    )
}

/// The held-out table of a cross-validation: per fold and class, base against tuned.
pub fn table(cv: &CvReport, o: &TuneOptions) -> String {
    let metric = o.scoring.metric();
    let mut s = String::new();
    let _ = writeln!(s, "held-out {metric} (x100): base (fitted noise) vs tuned");
    let _ = writeln!(
        s,
        "{:<28} {:<12} {:>8} {:>8}  training trajectories",
        "held-out logs", "class", "base", "tuned"
    );
    for (i, f) in cv.folds.iter().enumerate() {
        let n = f.held_out.len();
        let name = format!("fold {} ({n} log{})", i + 1, if n == 1 { "" } else { "s" });
        rows(&mut s, o, &name, (&f.base, &f.tuned), &f.search);
    }
    let all = (&cv.base, &cv.tuned);
    rows(&mut s, o, "all held-out together", all, &[]);
    if !cv.tuned_means_once.is_empty() {
        let once = (&cv.base_means_once, &cv.tuned_means_once);
        rows(&mut s, o, "all, means once *", once, &[]);
        let _ = writeln!(
            s,
            "* each track's mean score computed once, not re-averaged at every threshold as the\n  \
             reference does: not the official number (see `probmot eval --means`)"
        );
    }
    s.push_str(&gains_table(cv, metric));
    s
}

/// The rows of one part of the held-out table, and its overall row.
fn rows(
    s: &mut String,
    o: &TuneOptions,
    name: &str,
    (base, tuned): (&BTreeMap<String, f64>, &BTreeMap<String, f64>),
    search: &[ClassTune],
) {
    for (c, b) in base {
        let t = tuned.get(c).copied().unwrap_or(f64::NAN);
        let note = match search.iter().find(|x| &x.label == c) {
            Some(x) if x.refined => format!("{} (searched)", x.trajectories),
            Some(x) => format!("{} ({})", x.trajectories, not_searched(o, false)),
            None if search.is_empty() => String::new(),
            None => "none (no detections in the training folds: folds are the logs in the order \
                     given)"
                .into(),
        };
        let line = format!("{name:<28} {c:<12} {:>8} {:>8}  {note}", pct(*b), pct(t));
        let _ = writeln!(s, "{}", line.trim_end());
    }
    let _ = writeln!(
        s,
        "{name:<28} {:<12} {:>8} {:>8}",
        "overall",
        pct(overall(base)),
        pct(overall(tuned))
    );
}

/// The held-out gains with their paired intervals; a gain whose interval holds 0 is within the
/// noise, and said so.
fn gains_table(cv: &CvReport, metric: &str) -> String {
    let mut s = format!(
        "held-out gain of {metric} (tuned - base, x100), all held-out logs together, with its \
         paired 95 % bootstrap interval ({} resamples):\n",
        super::gains::RESAMPLES
    );
    for (c, g) in &cv.gains {
        let (lo, hi) = (g.ci95[0] * 100.0, g.ci95[1] * 100.0);
        let verdict = if g.ci95[0] > 0.0 {
            "a gain beyond the noise"
        } else if g.ci95[1] < 0.0 {
            "a loss beyond the noise"
        } else {
            "within the noise"
        };
        let d = g.delta * 100.0;
        let _ = writeln!(s, "  {c:<12} {d:>+7.2} [{lo:+.2}, {hi:+.2}]  {verdict}");
    }
    s
}
