//! Three first-use errors that pointed the wrong way: `tune` on a misspelt log, `eval` with its
//! file as a positional argument, and `info`'s count of boxes without a class.

use crate::common::{probmot, probmot_ok, repo};

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

fn stderr_of_failure(args: &[&str]) -> String {
    let run = probmot(args);
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
    stderr
}

#[test]
fn tune_names_a_log_it_cannot_open() {
    let dir = tempfile::tempdir().unwrap();
    let missing = repo("sample_logs/cty.mcap");
    let out = dir.path().join("t.json");
    let err = stderr_of_failure(&["tune", s(&missing), "-o", s(&out)]);
    assert!(
        err.contains(&format!("cannot open {}", missing.display())),
        "{err}"
    );
    assert!(!err.contains("--folds"), "{err}");
    assert!(!out.exists());
}

#[test]
fn eval_with_a_positional_file_hints_truth() {
    let city = repo("sample_logs/city.mcap");
    let err = stderr_of_failure(&["eval", s(&city)]);
    assert!(
        err.contains(&format!("--truth {}", city.display())),
        "{err}"
    );
    assert!(err.contains("--tracks"), "{err}");
    // A second file after --truth is still one of its values, not a stray argument.
    let err = stderr_of_failure(&["eval", "--truth", s(&city), s(&city)]);
    assert!(!err.contains("unexpected argument"), "{err}");
}

#[test]
fn info_names_boxes_without_a_class() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = dir.path().join("turning-car.tracked.mcap");
    let log = repo("sample_logs/turning-car.mcap");
    probmot_ok(&["track", s(&log), "-o", s(&tracked), "--quiet"]);
    let events = dir.path().join("events.mcap");
    probmot_ok(&["eval", "--truth", s(&tracked), "--events", s(&events), "-q"]);
    let out = String::from_utf8(probmot_ok(&["info", s(&events)]).stdout).unwrap();
    let counts: Vec<&str> = out
        .lines()
        .filter(|l| l.contains("boxes per class:"))
        .collect();
    assert!(counts.iter().any(|l| l.contains("(no class) ")), "{out}");
    // Every count has a name before it.
    for l in counts {
        let list = l.split("boxes per class:").nth(1).unwrap();
        for part in list.split(", ") {
            assert!(!part.starts_with("  ") && part.trim().contains(' '), "{l}");
        }
    }
}
