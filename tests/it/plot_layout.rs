//! `probmot plot --layout`: the picture's layout model (label boxes, leader lines, event marks,
//! legend, in pixels) checked for what a reader needs: every identity switch and fragmentation
//! of the window `eval --events` suggests in view and labelled, a legend, no two labels
//! overlapping, no label on an event ring or (an id's) on a bold box, leader lines from each
//! label to what it names; on the city sample and on a 200-object drive.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::common::{probmot_ok, repo};
use probmot::msgs::eval_event::Kind;
use probmot::viz::window::{read_timed_events, read_window};
use probmot::viz::Layer;

/// `(x0, x1, y0, y1)` of a layout rectangle.
type Rect = (f64, f64, f64, f64);

fn rect(v: &Value) -> Rect {
    let f = |k: &str| v[k].as_f64().unwrap();
    (f("x0"), f("x1"), f("y0"), f("y1"))
}

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.1 && b.0 < a.1 && a.2 < b.3 && b.2 < a.3
}

fn inside(r: Rect, bounds: Rect) -> bool {
    r.0 >= bounds.0 && r.1 <= bounds.1 && r.2 >= bounds.2 && r.3 <= bounds.3
}

fn on(r: Rect, p: &Value) -> bool {
    let (x, y) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
    x >= r.0 - 0.01 && x <= r.1 + 0.01 && y >= r.2 - 0.01 && y <= r.3 + 0.01
}

/// The ring of a switch or fragmentation mark in view, as a rectangle.
fn rings(panel: &Value) -> Vec<Rect> {
    (panel["marks"].as_array().unwrap().iter())
        .filter(|m| m["in_view"].as_bool().unwrap())
        .filter(|m| matches!(m["kind"].as_str().unwrap(), "switch" | "fragmentation"))
        .map(|m| {
            let (x, y, r) = (
                m["px"][0].as_f64().unwrap(),
                m["px"][1].as_f64().unwrap(),
                m["radius_px"].as_f64().unwrap(),
            );
            (x - r, x + r, y - r, y + r)
        })
        .collect()
}

/// Checks what every picture must hold: a legend under the panels, labels inside their panel,
/// apart, off the event rings (and, for ids, off the bold boxes), with leader lines from their
/// edge to what they name. Returns the number of labels placed.
fn check_layout(layout: &Value) -> usize {
    let (w, h) = (
        layout["width"].as_f64().unwrap(),
        layout["height"].as_f64().unwrap(),
    );
    let legend = rect(&layout["legend"]["rect"]);
    assert!(inside(legend, (0.0, w, 0.0, h)), "legend {legend:?}");
    let entries = layout["legend"]["entries"].as_array().unwrap();
    assert!(entries.len() >= 3, "{entries:?}");
    let entry_rects: Vec<Rect> = entries.iter().map(|e| rect(&e["rect"])).collect();
    for (i, r) in entry_rects.iter().enumerate() {
        assert!(
            inside(*r, legend),
            "legend entry {i} {r:?} outside {legend:?}"
        );
        assert!(entry_rects[..i].iter().all(|o| !overlaps(*o, *r)));
    }
    let mut all: Vec<Rect> = Vec::new();
    for panel in layout["panels"].as_array().unwrap() {
        let area = rect(&panel["view"]["area"]);
        assert!(
            area.3 <= legend.2,
            "panel {area:?} reaches the legend {legend:?}"
        );
        let rings = rings(panel);
        let last_boxes: Vec<Rect> = panel["last_boxes"]
            .as_array()
            .unwrap()
            .iter()
            .map(rect)
            .collect();
        for l in panel["labels"].as_array().unwrap() {
            let (r, target) = (rect(&l["rect"]), rect(&l["target"]));
            let what = l["text"].as_str().unwrap();
            assert!(inside(r, area), "{what}: {r:?} outside the panel {area:?}");
            if let Some(o) = all.iter().find(|o| overlaps(**o, r)) {
                panic!("{what}: {r:?} overlaps another label {o:?}");
            }
            all.push(r);
            assert!(
                rings.iter().all(|g| !overlaps(*g, r)),
                "{what} covers a ring"
            );
            if l["kind"] == "id" {
                assert!(last_boxes.contains(&target), "{what}: names no last box");
                assert!(
                    last_boxes.iter().all(|b| !overlaps(*b, r)),
                    "{what} covers a box"
                );
            } else {
                assert!(rings.contains(&target), "{what}: names no ring");
            }
            match &l["leader"] {
                Value::Null => {
                    // Touching: a couple of pixels from what it names.
                    let gap = (target.0 - r.1)
                        .max(r.0 - target.1)
                        .max(target.2 - r.3)
                        .max(r.2 - target.3);
                    assert!(gap <= 3.5, "{what}: {gap} px away without a leader line");
                }
                line => assert!(on(r, &line[0]) && on(target, &line[1]), "{what}: {line}"),
            }
        }
    }
    all.len()
}

fn layout_of(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// The `--from A --to B --extent X0,X1,Y0,Y1` of each worst moment `eval` printed.
fn suggestions(eval_stdout: &str) -> Vec<(f64, f64, String)> {
    let mut out = Vec::new();
    for line in eval_stdout.lines() {
        let Some(at) = line.find("--from ") else {
            continue;
        };
        let words: Vec<&str> = line[at..].split_whitespace().collect();
        assert_eq!(
            (words[0], words[2], words[4]),
            ("--from", "--to", "--extent"),
            "{line}"
        );
        let s = (
            words[1].parse().unwrap(),
            words[3].parse().unwrap(),
            words[5].to_string(),
        );
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out
}

/// Tracks `input` and evaluates it with `--events`: `(tracked, events, eval's stdout)`.
fn tracked_with_events(dir: &Path, input: &Path) -> (PathBuf, PathBuf, String) {
    let tracked = dir.join("drive.tracked.mcap");
    let events = dir.join("drive.events.mcap");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    probmot_ok(&["track", &s(input), "-o", &s(&tracked), "--quiet"]);
    let out = probmot_ok(&["eval", "--truth", &s(&tracked), "--events", &s(&events)]);
    (
        tracked,
        events,
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

/// The identity switches and fragmentations in `events` between `from_s` and `to_s` seconds
/// after the first frame of `tracked`, read apart from the plot.
fn window_events(tracked: &Path, events: &Path, from_s: f64, to_s: f64) -> usize {
    let topics: Vec<(Layer, String)> = Layer::ALL
        .iter()
        .map(|l| (*l, l.default_topic().to_string()))
        .collect();
    // (Only the first stamp is used here; the tracks layer is read with it.)
    let read = read_window(tracked, &topics, &[Layer::Tracks], None, None).unwrap();
    let t0 = read.first_stamp().unwrap();
    let at = |s: f64| (t0 as f64 + s * 1e9) as u64;
    let timed = read_timed_events(events, "/eval/events", 0, u64::MAX).unwrap();
    (timed.iter().map(|t| &t.1))
        .filter(|ev| ev.stamp + 500 >= at(from_s) && ev.stamp <= at(to_s) + 500)
        .flat_map(|ev| ev.events.iter())
        .filter(|e| matches!(e.kind(), Kind::Switch | Kind::Fragmentation))
        .count()
}

/// Plots every window `eval --events` suggested, as printed and without its `--extent`, and
/// checks the layouts.
fn check_suggested_windows(dir: &Path, input: &Path, most: usize) {
    let (tracked, events, said) = tracked_with_events(dir, input);
    let windows = suggestions(&said);
    assert!(!windows.is_empty(), "eval suggested no window:\n{said}");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    for (from, to, extent) in windows.into_iter().take(most) {
        let (png, json) = (dir.join("w.png"), dir.join("w.json"));
        let (f, t) = (from.to_string(), to.to_string());
        let mut args = vec!["plot".to_string(), s(&tracked), "-o".into(), s(&png)];
        args.extend(["--from", &f, "--to", &t, "--events"].map(String::from));
        args.extend([s(&events), "--layout".into(), s(&json), "--quiet".into()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        probmot_ok(&args);
        let own = layout_of(&json);
        probmot_ok(&[&args[..], &["--extent", &extent]].concat());
        let printed = layout_of(&json);
        assert_eq!(own["view_rule"], "events");
        assert_eq!(printed["view_rule"], "extent");
        // The region plot chooses for the window is the one eval printed.
        let region = |l: &Value| l["panels"][0]["view"]["extent"].clone();
        assert_eq!(
            region(&own),
            region(&printed),
            "{from}..{to}: --extent {extent}"
        );
        let n = window_events(&tracked, &events, from, to);
        assert!(n > 0, "the window {from}..{to} holds the moment listed");
        for layout in [&own, &printed] {
            check_layout(layout);
            let tracks = (layout["panels"].as_array().unwrap().iter())
                .find(|p| p["title"].as_str().unwrap().starts_with("tracks"))
                .unwrap();
            let marks: Vec<&Value> = (tracks["marks"].as_array().unwrap().iter())
                .filter(|m| matches!(m["kind"].as_str().unwrap(), "switch" | "fragmentation"))
                .collect();
            assert_eq!(
                marks.len(),
                n,
                "{from}..{to}: the window's events are marked"
            );
            assert!(
                marks.iter().all(|m| m["in_view"] == true),
                "{from}..{to}: {marks:?}"
            );
            let event_labels = (tracks["labels"].as_array().unwrap().iter())
                .filter(|l| l["kind"] == "event")
                .count();
            assert_eq!(event_labels, n, "{from}..{to}: each event labelled");
            let legend: Vec<&str> = (layout["legend"]["entries"].as_array().unwrap().iter())
                .map(|e| e["text"].as_str().unwrap())
                .collect();
            for want in [
                "identity switch",
                "fragmentation",
                "track matching no ground truth",
            ] {
                assert!(legend.contains(&want), "{want} missing from {legend:?}");
            }
        }
    }
}

#[test]
fn city_plots_of_the_suggested_windows_frame_every_event_with_labels_apart() {
    let dir = tempfile::tempdir().unwrap();
    // The first four moments: 5.5 to 9.5 s, 8.5 to 12.5, 9.5 to 13.5 (the window of the issue
    // that asked for this) and 10.5 to 14.5.
    check_suggested_windows(dir.path(), &repo("sample_logs/city.mcap"), 4);
}

#[test]
fn a_200_object_drive_plots_with_labels_apart() {
    let dir = tempfile::tempdir().unwrap();
    let drive = dir.path().join("city200.mcap");
    let d = drive.to_str().unwrap();
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--objects",
        "200",
        "-o",
        d,
        "--quiet",
    ]);
    check_suggested_windows(dir.path(), &drive, 2);
    // The whole drive at the default size: hundreds of ids; every label placed is apart from
    // the others and off the boxes, and most ids in view are labelled in the ground truth.
    let (png, json) = (dir.path().join("all.png"), dir.path().join("all.json"));
    let tracked = dir.path().join("drive.tracked.mcap");
    let (p, j) = (png.to_str().unwrap(), json.to_str().unwrap());
    probmot_ok(&[
        "plot",
        tracked.to_str().unwrap(),
        "-o",
        p,
        "--layout",
        j,
        "--quiet",
    ]);
    let layout = layout_of(&json);
    let placed = check_layout(&layout);
    let truth = &layout["panels"][2];
    let ids = truth["last_boxes"].as_array().unwrap().len();
    let labelled = truth["labels"].as_array().unwrap().len();
    assert!(
        ids >= 150 && labelled >= 60,
        "{labelled} of {ids} ids labelled"
    );
    assert_eq!(
        labelled + truth["labels_left_out"].as_u64().unwrap() as usize,
        ids
    );
    assert!(placed >= 120, "{placed} labels");
}

#[test]
fn docs_pictures_are_those_the_script_makes() {
    // scripts/make_docs_images.sh is the one writer of the docs' plot pictures; made again with
    // the binary under test, they are byte for byte the committed ones (else run the script).
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new("bash")
        .arg(repo("scripts/make_docs_images.sh"))
        .arg(dir.path())
        .env("PROBMOT", env!("CARGO_BIN_EXE_probmot"))
        .output()
        .expect("run bash");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in ["turning-car-bev.png", "pedestrian-switch.png"] {
        let made = std::fs::read(dir.path().join(name)).unwrap();
        let committed = std::fs::read(repo(&format!("docs/{name}"))).unwrap();
        assert!(
            made == committed,
            "docs/{name} is stale: run scripts/make_docs_images.sh"
        );
    }
}
