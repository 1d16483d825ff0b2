//! The text report of `probmot eval` as a reader meets it: the files and topics on labelled
//! lines, an overall HOTA row, the change table's row `better`, and the legend (`--explain`,
//! `--help`).

use crate::common::{probmot, probmot_ok, repo};

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

fn stdout(args: &[&str]) -> String {
    String::from_utf8(probmot_ok(args).stdout).unwrap()
}

/// The columns of `line` that hold `+` or `-` alone, by the header's column names.
fn signs(header: &str, row: &str) -> Vec<(String, String)> {
    let names: Vec<&str> = header.split_whitespace().skip(1).collect();
    let cells: Vec<&str> = row.split_whitespace().skip(1).collect();
    assert_eq!(names.len(), cells.len(), "{header}\n{row}");
    (names.into_iter().zip(cells))
        .map(|(n, c)| (n.to_string(), c.to_string()))
        .collect()
}

#[test]
fn the_report_labels_its_files_rows_and_directions() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = dir.path().join("turning-car.tracked.mcap");
    let log = repo("sample_logs/turning-car.mcap");
    probmot_ok(&["track", s(&log), "-o", s(&tracked), "--quiet"]);
    for protocol in ["nuscenes", "kitti"] {
        let t = s(&tracked);
        let out = stdout(&[
            "eval",
            "--protocol",
            protocol,
            "--truth",
            t,
            "--baseline",
            t,
            "-q",
        ]);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines[1], format!("  tracks: {t} (topic /tracks)"), "{out}");
        assert_eq!(
            lines[2],
            format!("  truth:  {t} (topic /ground_truth)"),
            "{out}"
        );
        assert!(!out.contains(" vs "), "{out}");
        let change = lines
            .iter()
            .position(|l| l.starts_with("change (this - baseline"))
            .unwrap();
        assert!(
            lines[change].contains("+ higher is better, - lower is better"),
            "{out}"
        );
        assert!(lines[change + 2].starts_with("better "), "{out}");
        let signs = signs(lines[change + 1], lines[change + 2]);
        let sign = |c: &str| signs.iter().find(|(n, _)| n == c).unwrap().1.clone();
        assert_eq!(sign("AMOTA"), "+");
        assert_eq!(sign("IDS"), "-");
        assert_eq!(sign("FP"), "-");
        // nuScenes' MOTP is a distance, KITTI's an IoU.
        assert_eq!(sign("MOTP"), if protocol == "kitti" { "+" } else { "-" });
        assert!(signs.iter().all(|(_, c)| c == "+" || c == "-"), "{signs:?}");
        assert!(out.contains("`probmot eval --explain`"), "{out}");
    }
    // With --explain the report ends with the legend of its tables.
    let out = stdout(&["eval", "--truth", s(&tracked), "-q", "--explain"]);
    let legend = out
        .find("What the columns of `probmot eval` mean")
        .expect(&out);
    assert!(out[legend..].contains("nuScenes table") && !out[legend..].contains("KITTI table"));
    // The HOTA table ends with the class mean of its rows.
    let out = stdout(&["eval", "--truth", s(&tracked), "-q"]);
    let hota: Vec<&str> = (out.lines())
        .skip_while(|l| !l.starts_with("HOTA"))
        .skip(2)
        .take_while(|l| !l.is_empty())
        .collect();
    let value = |l: &str| l.split_whitespace().nth(1).unwrap().parse::<f64>().unwrap();
    let (overall, classes) = hota.split_last().unwrap();
    assert!(
        overall.starts_with("overall") && !classes.is_empty(),
        "{out}"
    );
    let mean = classes.iter().map(|l| value(l)).sum::<f64>() / classes.len() as f64;
    assert!((value(overall) - mean).abs() <= 0.0015, "{out}");
}

#[test]
fn explain_and_help_give_each_column_its_unit_and_direction() {
    let legend = stdout(&["eval", "--explain"]);
    for needle in [
        "AMOTP   m ",
        "FAF     per 100 frames  - better",
        "TID     s ",
        "LGD",
        "sAMOTA",
    ] {
        let found = legend.contains(needle) || legend.contains(&needle.to_uppercase());
        assert!(found, "{needle}: {legend}");
    }
    for column in ["MT", "ML", "HOTA", "DETA", "ASSA", "LOCA"] {
        let entry = (legend.lines())
            .find(|l| l.trim_start().starts_with(&format!("{column} ")) && l.contains(" better "));
        assert!(entry.is_some(), "{column}: {legend}");
    }
    let help = stdout(&["eval", "--help"]);
    assert!(
        help.contains("FAF") && help.contains("per 100 frames"),
        "{help}"
    );
    // Without --explain or --truth, --truth is still required.
    let run = probmot(&["eval"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("--truth"));
}

#[test]
fn docs_list_every_column_of_the_legend() {
    let doc = std::fs::read_to_string(repo("docs/eval.md")).unwrap();
    for sec in probmot::eval::legend::SECTIONS {
        for e in sec.entries {
            let better = match e.better {
                probmot::eval::legend::Better::Higher => "higher",
                probmot::eval::legend::Better::Lower => "lower",
            };
            let row = format!("| {} | {} | {better} | {} |", e.column, e.unit, e.meaning);
            assert!(doc.contains(&row), "docs/eval.md lacks the row {row}");
        }
    }
}

/// The library's `eval::job::evaluate` is the command: the same JSON document and text report,
/// and the same gate failures, for the same options; contradicting options are refused.
#[test]
fn the_library_call_gives_the_commands_report() {
    use probmot::eval::job::{evaluate, EvalOptions};
    use probmot::pipeline::progress::no_progress;
    let dir = tempfile::tempdir().unwrap();
    let (new, old) = (dir.path().join("new.mcap"), dir.path().join("old.mcap"));
    let log = repo("sample_logs/turning-car.mcap");
    probmot_ok(&["track", s(&log), "-o", s(&new), "--quiet"]);
    let worse = ["--preset", "ab3dmot-2019"];
    probmot_ok(&[&["track", s(&log), "-o", s(&old), "--quiet"][..], &worse].concat());
    let o = EvalOptions {
        truth: vec![old.clone()],
        baseline: vec![new.clone()],
        max_drop: Some(0.0),
        bootstrap: Some(50),
        ..EvalOptions::default()
    };
    let args = [
        "eval",
        "--truth",
        s(&old),
        "--baseline",
        s(&new),
        "--max-drop",
        "0",
    ];
    let args = [&args[..], &["--bootstrap", "50"]].concat();
    let text = evaluate(&o, &no_progress).unwrap();
    let cli = probmot(&args);
    assert_eq!(text.text, String::from_utf8(cli.stdout).unwrap());
    assert_eq!(cli.status.code(), Some(3), "the worse run fails the gate");
    let stderr = String::from_utf8(cli.stderr).unwrap();
    for f in &text.gate_failures {
        assert!(stderr.contains(&format!("gate failed: {f}")), "{stderr}");
    }
    assert!(!text.gate_failures.is_empty());
    let json = evaluate(
        &EvalOptions {
            json: true,
            ..o.clone()
        },
        &no_progress,
    )
    .unwrap();
    let cli: serde_json::Value =
        serde_json::from_slice(&probmot(&[&args[..], &["--json"]].concat()).stdout).unwrap();
    assert_eq!(json.json.unwrap(), cli);
    let bad = EvalOptions {
        iou: Some(0.5),
        ..o
    };
    let e = evaluate(&bad, &no_progress).unwrap_err().to_string();
    assert!(e.starts_with("--iou is a KITTI option"), "{e}");
}
