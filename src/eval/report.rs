//! Human-readable metric tables.

use std::fmt::Write;

/// Formats a value: integers without decimals, others with 3, NaN as "-".
pub fn fmt_value(name: &str, v: f64) -> String {
    if v.is_nan() {
        return "-".into();
    }
    match name {
        "mt" | "ml" | "tp" | "fp" | "fn" | "ids" | "frag" | "gt" => format!("{v:.0}"),
        _ => format!("{v:.3}"),
    }
}

/// A table with one row per class plus `overall`, columns = metric names.
pub fn table(columns: &[&str], rows: &[(String, Vec<f64>)]) -> String {
    let mut widths: Vec<usize> = columns.iter().map(|c| c.len().max(6)).collect();
    let label_w = rows.iter().map(|r| r.0.len()).max().unwrap_or(5).max(7);
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|(_, vals)| {
            vals.iter()
                .zip(columns)
                .map(|(v, c)| fmt_value(c, *v))
                .collect()
        })
        .collect();
    for row in &cells {
        for (i, c) in row.iter().enumerate() {
            widths[i] = widths[i].max(c.len());
        }
    }
    let mut s = String::new();
    let _ = write!(s, "{:<label_w$}", "class");
    for (c, w) in columns.iter().zip(&widths) {
        let _ = write!(s, "  {:>w$}", c.to_uppercase());
    }
    s.push('\n');
    for ((label, _), row) in rows.iter().zip(&cells) {
        let _ = write!(s, "{label:<label_w$}");
        for (c, w) in row.iter().zip(&widths) {
            let _ = write!(s, "  {c:>w$}");
        }
        s.push('\n');
    }
    s
}
