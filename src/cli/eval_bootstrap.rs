//! `eval --bootstrap`: its options from the arguments, and the regression gate by the rule
//! `--gate` chooses.

use probmot::eval::bootstrap::report::Bootstrap;
use probmot::eval::bootstrap::Options;

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
