//! The bootstrap of one evaluation: a protocol's metrics and HOTA's, per class and overall,
//! each with its interval (or, against a baseline, its change with a paired interval).

use std::collections::BTreeMap;

use super::report::{Bootstrap, Found};
use super::{changes, estimates, Options, Units};
use crate::eval::hota::units::{hota_class, HotaCurve};

/// Names of the HOTA metrics [`hota_class`] gives, in order.
pub const HOTA_METRICS: [&str; 3] = ["hota", "deta", "assa"];

/// A protocol's side of the bootstrap: its metric names and, per unit weights, its metrics per
/// row (in order) then overall.
pub struct Protocol<C> {
    /// Names of the metrics.
    pub names: &'static [&'static str],
    /// `metrics(rows' curves, weights)`: the rows' metrics then the overall ones.
    pub metrics: fn(&[C], &[u32]) -> Vec<f64>,
}

/// One HOTA similarity's side: its metric names (in the order of [`HOTA_METRICS`]) and, per
/// run, each class's curve.
pub struct HotaGroup {
    /// Names of HOTA, DetA and AssA.
    pub names: &'static [&'static str],
    /// Per run (this, then the baseline): the classes' curves.
    pub runs: Vec<BTreeMap<String, HotaCurve>>,
}

/// One run's curves.
struct Run<'a, C> {
    protocol: &'a [C],
    hota: Vec<&'a BTreeMap<String, HotaCurve>>,
}

/// Per row (`rows`, then overall): the protocol's metrics, then each HOTA group's. A row's HOTA
/// is its class's (NaN without one); overall HOTA is the mean over the classes with a value,
/// as the HOTA table's `overall` row.
fn metrics<C>(p: &Protocol<C>, rows: &[String], run: &Run<C>, w: &[u32]) -> Vec<f64> {
    let n = p.names.len();
    let proto = (p.metrics)(run.protocol, w);
    let per_group: Vec<BTreeMap<&str, [f64; 3]>> = (run.hota.iter())
        .map(|classes| {
            (classes.iter())
                .filter_map(|(c, curve)| hota_class(curve, w).map(|v| (c.as_str(), v)))
                .collect()
        })
        .collect();
    let mut out = Vec::with_capacity((rows.len() + 1) * (n + 3 * per_group.len()));
    for (i, row) in rows.iter().enumerate() {
        out.extend_from_slice(&proto[i * n..(i + 1) * n]);
        for g in &per_group {
            out.extend(g.get(row.as_str()).copied().unwrap_or([f64::NAN; 3]));
        }
    }
    out.extend_from_slice(&proto[rows.len() * n..]);
    for g in &per_group {
        let k = g.len() as f64;
        let mean = |m: usize| match g.is_empty() {
            true => f64::NAN,
            false => g.values().map(|v| v[m]).sum::<f64>() / k,
        };
        out.extend([mean(0), mean(1), mean(2)]);
    }
    out
}

/// Runs the bootstrap over `units`: `this` and (with a baseline) `base` are each run's protocol
/// curves, aligned by `rows`; `hota` the HOTA groups (their runs in the same order).
pub fn run<C: Sync>(
    (p, rows): (Protocol<C>, Vec<String>),
    (this, base): (&[C], Option<&[C]>),
    hota: &[HotaGroup],
    units: &Units,
    options: Options,
) -> Bootstrap {
    let n = units.count;
    let run_of = |k: usize, protocol| Run {
        protocol,
        hota: hota.iter().map(|g| &g.runs[k]).collect(),
    };
    let mut names: Vec<&'static str> = p.names.to_vec();
    let mut groups = vec![p.names.len()];
    for g in hota {
        names.extend(g.names);
        groups.push(g.names.len());
    }
    let k = names.len();
    let this_run = run_of(0, this);
    let f = |w: &[u32]| metrics(&p, &rows, &this_run, w);
    let found = match base {
        None => Found::Estimates(regroup(estimates(n, options, f), k)),
        Some(base) => {
            let base_run = run_of(1, base);
            let g = |w: &[u32]| metrics(&p, &rows, &base_run, w);
            Found::Changes(regroup(changes(n, options, f, g), k))
        }
    };
    let mut rows = rows;
    rows.push("overall".into());
    Bootstrap {
        names,
        groups,
        rows,
        found,
        units: (n, units.block_s),
        options,
    }
}

fn regroup<T: Clone>(v: Vec<T>, k: usize) -> Vec<Vec<T>> {
    v.chunks(k).map(<[T]>::to_vec).collect()
}

/// The units numbered alike over each run's logs (given by their frame stamps): the first
/// run's, then the baseline's.
pub fn paired_units(runs: &[Vec<Vec<u64>>], block: Option<f64>) -> Vec<Units> {
    let runs: Vec<Vec<&[u64]>> = (runs.iter())
        .map(|r| r.iter().map(Vec::as_slice).collect())
        .collect();
    Units::choose_paired(&runs, block)
}

/// The rows both runs have (the first run's order), and each run's curves in that order.
pub fn aligned<C: Clone>(
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
