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
    render(columns, None, rows)
}

/// [`table`] with a row of text under the header, `(label, one cell per column)`: the change
/// table's row `better` (the sign of an improvement per column).
pub fn table_with_row(
    columns: &[&str],
    (label, marks): (&str, &[String]),
    rows: &[(String, Vec<f64>)],
) -> String {
    render(columns, Some((label, marks)), rows)
}

fn render(
    columns: &[&str],
    extra: Option<(&str, &[String])>,
    rows: &[(String, Vec<f64>)],
) -> String {
    let mut widths: Vec<usize> = columns.iter().map(|c| c.len().max(6)).collect();
    let extra_label = extra.map_or(0, |(l, _)| l.len());
    let label_w = rows
        .iter()
        .map(|r| r.0.len())
        .max()
        .unwrap_or(5)
        .max(7)
        .max(extra_label);
    let mut cells: Vec<Vec<String>> = extra.iter().map(|(_, m)| m.to_vec()).collect();
    cells.extend(rows.iter().map(|(_, vals)| {
        vals.iter()
            .zip(columns)
            .map(|(v, c)| fmt_value(c, *v))
            .collect()
    }));
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
    let labels = extra.map(|(l, _)| l).into_iter();
    for (label, row) in labels.chain(rows.iter().map(|r| r.0.as_str())).zip(&cells) {
        let _ = write!(s, "{label:<label_w$}");
        for (c, w) in row.iter().zip(&widths) {
            let _ = write!(s, "  {c:>w$}");
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_extra_row_sits_under_the_header_aligned_with_the_columns() {
        let rows = vec![("car".to_string(), vec![0.5, 3.0])];
        let marks = ["+".to_string(), "-".to_string()];
        let t = table_with_row(&["amota", "ids"], ("better", &marks), &rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 3, "{t}");
        assert!(
            lines[1].starts_with("better") && lines[2].starts_with("car"),
            "{t}"
        );
        // Each mark ends where its column's header and values end.
        for (name, mark) in [("AMOTA", "+"), ("IDS", "-")] {
            let end = lines[0].find(name).unwrap() + name.len();
            assert_eq!(&lines[1][end - 1..end], mark, "{t}");
        }
        assert_eq!(
            lines[2].find("0.500").unwrap() + 5,
            lines[0].find("AMOTA").unwrap() + 5
        );
        assert_eq!(table(&["amota", "ids"], &rows).lines().count(), 2);
    }
}
