//! `probmot plot`: a bird's-eye-view PNG of a tracked sample log, checked pixel by pixel (size,
//! colours per id in the tracks panel, grey detections, rendered text), and its errors.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::common::{probmot, probmot_ok, repo};
use probmot::viz::plot::{id_color, BACKGROUND, DETECTION_GREY, PALETTE};

/// A decoded RGB picture.
struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Picture {
    fn read(path: &Path) -> Picture {
        let file = std::fs::File::open(path).expect("open png");
        let mut dec = png::Decoder::new(std::io::BufReader::new(file));
        dec.set_transformations(png::Transformations::EXPAND);
        let mut reader = dec.read_info().expect("png header");
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).expect("png data");
        assert_eq!(info.color_type, png::ColorType::Rgb, "probmot writes RGB");
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        Picture {
            width: info.width as usize,
            height: info.height as usize,
            rgb: buf,
        }
    }

    fn at(&self, x: usize, y: usize) -> (u8, u8, u8) {
        let i = 3 * (y * self.width + x);
        (self.rgb[i], self.rgb[i + 1], self.rgb[i + 2])
    }

    /// Every colour in columns `x0..x1` and rows `y0..y1`.
    fn colours(&self, x0: usize, x1: usize, y0: usize, y1: usize) -> BTreeSet<(u8, u8, u8)> {
        let mut s = BTreeSet::new();
        for y in y0..y1 {
            for x in x0..x1 {
                s.insert(self.at(x, y));
            }
        }
        s
    }

    /// Pixels darker than mid-grey (text and axes) in the region.
    fn dark_pixels(&self, x0: usize, x1: usize, y0: usize, y1: usize) -> usize {
        let mut n = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                let (r, g, b) = self.at(x, y);
                if u32::from(r) + u32::from(g) + u32::from(b) < 3 * 100 {
                    n += 1;
                }
            }
        }
        n
    }
}

fn tracked_turning_car(dir: &Path) -> PathBuf {
    let out = dir.join("turning-car.tracked.mcap");
    let input = repo("sample_logs/turning-car.mcap");
    probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    out
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Checks the legend of the turning-car picture (its layout in `layout`, a `--layout` file): a
/// strip under the panels with the entries of the three layers, whose samples show colours of
/// ids and the grey of detections, and text. Returns its top row.
fn check_legend(pic: &Picture, layout: &Path) -> usize {
    let (w, h) = (pic.width, pic.height);
    let layout: serde_json::Value =
        serde_json::from_slice(&std::fs::read(layout).unwrap()).unwrap();
    let legend_top = layout["legend"]["rect"]["y0"].as_f64().unwrap() as usize;
    assert!(
        legend_top > h / 2 && legend_top < h - 20,
        "legend at {legend_top}"
    );
    let texts: Vec<&str> = (layout["legend"]["entries"].as_array().unwrap().iter())
        .map(|e| e["text"].as_str().unwrap())
        .collect();
    assert_eq!(
        texts,
        [
            "detection (no id)",
            "track: colour of the ground-truth object it matches",
            "track matching no ground truth",
            "ground truth: a colour per object id",
            "bold: last box of an id, line: its path, tick: heading"
        ]
    );
    let legend = pic.colours(0, w, legend_top, h);
    assert!(legend.contains(&DETECTION_GREY) && legend.contains(&id_color(1)));
    assert!(pic.dark_pixels(0, w, legend_top, h) > 200, "legend text");
    legend_top
}

#[test]
fn plot_draws_three_panels_with_colours_per_track_and_text() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = tracked_turning_car(dir.path());
    let png = dir.path().join("bev.png");
    let layout = dir.path().join("bev.json");
    let (w, h) = (1200usize, 500usize);
    let out = probmot_ok(&[
        "plot",
        tracked.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--layout",
        layout.to_str().unwrap(),
        "--class",
        "car",
        "--layers",
        "detections,tracks,ground_truth",
        "--width",
        &w.to_string(),
        "--height",
        &h.to_string(),
    ]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("3 panel(s)"), "{said}");
    // Atomic output: no temporary file is left beside it.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".probmot-")), "{names:?}");

    let pic = Picture::read(&png);
    assert_eq!((pic.width, pic.height), (w, h), "size as requested");

    // Panels split the width evenly: detections | tracks | ground truth; the legend under them.
    let legend_top = check_legend(&pic, &layout);
    let third = w / 3;
    let palette: BTreeSet<(u8, u8, u8)> = PALETTE.iter().copied().collect();
    let dets = pic.colours(0, third, 0, legend_top);
    let tracks = pic.colours(third, 2 * third, 0, legend_top);
    let truth = pic.colours(2 * third, w, 0, legend_top);

    let ids_in = |c: &BTreeSet<(u8, u8, u8)>| c.intersection(&palette).count();
    assert!(
        ids_in(&tracks) >= 3,
        "tracks panel has {} id colours: {:?}",
        ids_in(&tracks),
        tracks.intersection(&palette).collect::<Vec<_>>()
    );
    assert!(ids_in(&truth) >= 3, "ground-truth panel: one colour per id");
    assert_eq!(ids_in(&dets), 0, "detections have no ids and are grey");
    assert!(dets.contains(&DETECTION_GREY), "grey detection boxes");
    let non_background = tracks.iter().filter(|c| **c != BACKGROUND).count();
    assert!(
        non_background >= 5,
        "{non_background} colours in the tracks panel"
    );

    // The colour of every ground-truth instance id of the log appears in the truth panel.
    for id in 1..=5u64 {
        assert!(
            truth.contains(&id_color(id)),
            "ground-truth id {id}: colour {:?} missing",
            id_color(id)
        );
    }

    // Text: the title rows and each panel's caption rows hold dark (glyph) pixels; a renderer
    // without a font would have left them blank or failed.
    let title_rows = (h / 25).max(18);
    assert!(
        pic.dark_pixels(w / 4, 3 * w / 4, 0, title_rows) > 50,
        "title text"
    );
    for p in 0..3 {
        assert!(
            pic.dark_pixels(p * third, (p + 1) * third, title_rows, 2 * title_rows + 6) > 50,
            "caption of panel {p}"
        );
    }
    // Axis labels at the bottom of the panels ("x (m)" and tick numbers).
    assert!(
        pic.dark_pixels(third, 2 * third, legend_top - 40, legend_top) > 30,
        "x axis text"
    );
}

#[test]
fn plot_window_class_and_default_layers() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = tracked_turning_car(dir.path());
    let png = dir.path().join("window.png");
    // Default layers: the three topics the tracked file has; a window of 2 s (5 frames at 2 Hz).
    let out = probmot_ok(&[
        "plot",
        tracked.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--from",
        "5",
        "--to",
        "7",
        "--width",
        "900",
        "--height",
        "400",
    ]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("(detections, tracks, ground_truth)"),
        "{said}"
    );
    assert!(said.contains("5 frames from 5.00 to 7.00 s"), "{said}");
    let pic = Picture::read(&png);
    assert_eq!((pic.width, pic.height), (900, 400));
}

#[test]
fn plot_errors_are_clear_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let untracked = repo("sample_logs/turning-car.mcap");
    let png = dir.path().join("x.png");
    let p = png.to_str().unwrap();

    // A layer whose topic the file lacks.
    let out = probmot(&[
        "plot",
        untracked.to_str().unwrap(),
        "-o",
        p,
        "--layers",
        "tracks",
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("no topic /tracks"), "{e}");
    assert!(e.contains("/ground_truth"), "lists the topics: {e}");

    // A window after the end of the log.
    let out = probmot(&[
        "plot",
        untracked.to_str().unwrap(),
        "-o",
        p,
        "--from",
        "100",
        "--to",
        "200",
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("no frame in the window 100.00 to 200.00 s"),
        "{e}"
    );
    assert!(e.contains("19.50 s"), "says how long the log is: {e}");

    // A class the log does not have.
    let out = probmot(&[
        "plot",
        untracked.to_str().unwrap(),
        "-o",
        p,
        "--class",
        "bus",
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("no box of class bus"), "{e}");
    assert!(e.contains("classes in the file: car"), "{e}");
    // Beside a class it has, the missing one is drawn without, with a warning naming it.
    let out = probmot(&[
        "plot",
        untracked.to_str().unwrap(),
        "-o",
        p,
        "--class",
        "car,bus",
    ]);
    assert!(out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("warning: ")
            && e.contains("no box of class bus on the plotted topics (classes: car)"),
        "{e}"
    );
    std::fs::remove_file(p).unwrap(); // the errors below must write nothing

    // Unknown layer, reversed window, not a PNG name.
    for (args, needle) in [
        (vec!["--layers", "lidar"], "unknown layer 'lidar'"),
        (vec!["--from", "3", "--to", "1"], "the window is empty"),
        (vec!["--width", "20"], "--width 20 is out of range"),
    ] {
        let mut all = vec!["plot", untracked.to_str().unwrap(), "-o", p];
        all.extend(args);
        let out = probmot(&all);
        assert!(!out.status.success(), "{all:?}");
        assert!(stderr(&out).contains(needle), "{all:?}: {}", stderr(&out));
    }
    let jpg = dir.path().join("x.jpg");
    let out = probmot(&[
        "plot",
        untracked.to_str().unwrap(),
        "-o",
        jpg.to_str().unwrap(),
    ]);
    assert!(
        stderr(&out).contains("must end in .png"),
        "{}",
        stderr(&out)
    );

    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "no output on error"
    );
}

#[test]
fn plot_draws_ros2_and_foxglove_detections_like_probmot_ones() {
    // The ROS 2 and Foxglove fixtures carry the detections of sample_logs/city.mcap; tracked,
    // they give the same boxes (tests/it/ros2_foxglove_input/fixtures.rs), so their pictures are the same
    // pixels as the probmot log's.
    let dir = tempfile::tempdir().unwrap();
    let mut pictures = Vec::new();
    for (name, input) in [
        ("probmot", "sample_logs/city.mcap"),
        ("ros2", "tests/fixtures/ros2/city.mcap"),
        ("foxglove", "tests/fixtures/foxglove/city.mcap"),
    ] {
        let tracked = dir.path().join(format!("{name}.mcap"));
        probmot_ok(&[
            "track",
            repo(input).to_str().unwrap(),
            "-o",
            tracked.to_str().unwrap(),
            "--quiet",
            // plot reads probmot.Tracks3D tracks (a ROS 2 input's default is ROS 2 tracks).
            "--tracks-format",
            "probmot",
        ]);
        let png = dir.path().join(format!("{name}.png"));
        probmot_ok(&[
            "plot",
            tracked.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--layers",
            "detections,tracks",
            "--title",
            "city",
            // The fixtures have no ground truth to take the tracks' colours from.
            "--own-colors",
        ]);
        pictures.push(Picture::read(&png));
    }
    let grey = pictures[0]
        .rgb
        .chunks(3)
        .filter(|p| (p[0], p[1], p[2]) == DETECTION_GREY)
        .count();
    assert!(grey > 100, "the detections panel has grey boxes");
    for p in &pictures[1..] {
        assert_eq!((p.width, p.height), (pictures[0].width, pictures[0].height));
        assert!(
            p.rgb == pictures[0].rgb,
            "same picture as the probmot log's"
        );
    }
}

/// The pedestrians sample tracked and evaluated with `--events`: `(tracked, events)`.
fn pedestrians_with_events(dir: &Path) -> (PathBuf, PathBuf) {
    let tracked = dir.join("ped.tracked.mcap");
    let events = dir.join("ped.events.mcap");
    let input = repo("sample_logs/pedestrians.mcap");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    probmot_ok(&["track", &s(&input), "-o", &s(&tracked), "--quiet"]);
    probmot_ok(&["eval", "--truth", &s(&tracked), "--events", &s(&events)]);
    (tracked, events)
}

#[test]
fn plot_marks_events_and_gives_tracks_the_colour_of_their_ground_truth() {
    use probmot::msgs::eval_event::Kind;
    use probmot::msgs::eval_events::kind_rgb;
    let dir = tempfile::tempdir().unwrap();
    let (tracked, events) = pedestrians_with_events(dir.path());
    // 10.5 to 12.5 s: two pairs of pedestrians cross; the tracker swaps ids (eval reports the
    // switches at 11.5 and 12 s, tests/it/eval_events.rs).
    let plot = |name: &str, extra: &[&str]| {
        let png = dir.path().join(name);
        let mut args = vec![
            "plot",
            tracked.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--class",
            "pedestrian",
            "--from",
            "10.5",
            "--to",
            "12.5",
            "--layers",
            "tracks",
            "--width",
            "800",
            "--height",
            "600",
        ];
        args.extend(extra);
        let out = probmot_ok(&args);
        (
            Picture::read(&png),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    let (with, said) = plot("with.png", &["--events", events.to_str().unwrap()]);
    let (without, _) = plot("without.png", &[]);
    assert!(said.contains("events marked"), "{said}");
    // Above the legend (which shows the marks' colours when there are marks).
    let all_with = with.colours(0, 800, 0, 500);
    let all_without = without.colours(0, 800, 0, 500);
    let switch = kind_rgb(Kind::Switch);
    assert!(all_with.contains(&switch), "switches are marked");
    assert!(!all_without.contains(&switch), "no marks without --events");
    // Track boxes take the colours of the ground-truth ids (1..=7 in the window) they follow,
    // with or without the evaluation's pairs.
    for pic in [&with, &without] {
        let c = pic.colours(0, 800, 0, 500);
        let gt_colours = (1..=7u64).filter(|id| c.contains(&id_color(*id))).count();
        assert!(
            gt_colours >= 5,
            "{gt_colours} ground-truth colours in the tracks panel"
        );
    }
    // An events file without the channel is a clear error.
    let out = probmot(&[
        "plot",
        tracked.to_str().unwrap(),
        "-o",
        dir.path().join("x.png").to_str().unwrap(),
        "--events",
        tracked.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("no topic /eval/events"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn plot_extent_sets_the_region() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = tracked_turning_car(dir.path());
    let t = tracked.to_str().unwrap();
    let png = dir.path().join("e.png");
    let p = png.to_str().unwrap();
    probmot_ok(&[
        "plot",
        t,
        "-o",
        p,
        "--extent",
        "-1000,1000,-1000,1000",
        "--layers",
        "tracks",
    ]);
    // Zoomed out 40x: the boxes shrink to a few pixels near the centre, the rest is blank.
    let pic = Picture::read(&png);
    let (w, h) = (pic.width, pic.height);
    let coloured = |x0, x1, y0, y1| {
        pic.colours(x0, x1, y0, y1)
            .iter()
            .filter(|c| PALETTE.contains(c))
            .count()
    };
    assert!(coloured(w / 2 - 60, w / 2 + 60, h / 2 - 60, h / 2 + 60) > 0);
    assert_eq!(coloured(w * 3 / 4, w - 10, 60, h / 3), 0);
    for bad in ["1,0,0,1", "0,1,0", "0,1,a,1"] {
        let out = probmot(&["plot", t, "-o", p, "--extent", bad]);
        assert!(!out.status.success(), "{bad}");
    }
}

#[test]
fn windowed_read_gives_the_frames_of_a_full_read() {
    use probmot::viz::window::read_window;
    use probmot::viz::{read_layers, Layer, Selection};
    // 1200 frames of 30 objects: several 1 MiB chunks.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("city.mcap");
    let s = log.to_str().unwrap();
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "1200",
        "--objects",
        "30",
        "-o",
        s,
    ]);
    let wanted: Vec<(Layer, String)> = Layer::ALL
        .iter()
        .map(|l| (*l, l.default_topic().to_string()))
        .collect();
    let full = read_layers(&log, &wanted).unwrap();
    let (from, to) = (300.0, 310.0);
    let window = read_window(&log, &wanted, &[Layer::GroundTruth], Some(from), Some(to)).unwrap();
    assert_eq!(window.first_stamp(), full.first_stamp());
    assert_eq!(window.last_stamp(), full.last_stamp());
    let t0 = full.first_stamp().unwrap();
    let sel = Selection {
        classes: vec![],
        from_s: Some(from),
        to_s: Some(to),
    };
    let a = sel.apply(&full.get(Layer::GroundTruth).unwrap().frames, t0);
    let b = sel.apply(&window.get(Layer::GroundTruth).unwrap().frames, t0);
    assert_eq!(a.len(), 21, "10 s at 2 Hz");
    assert_eq!(a, b);
    // Only the window (and its slack) was decoded, and only the layer drawn.
    let read = window.get(Layer::GroundTruth).unwrap().frames.len();
    assert!(read < 100, "{read} frames decoded");
    assert!(window.get(Layer::Detections).unwrap().frames.is_empty());
    assert_eq!(
        window
            .get(Layer::GroundTruth)
            .unwrap()
            .frame_ids
            .iter()
            .collect::<Vec<_>>(),
        vec!["map"]
    );
}

/// A box that cannot be drawn from above (a NaN centre) is left out of the picture and named in
/// a warning, not dropped unsaid.
#[test]
fn undrawable_boxes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan.mcap");
    crate::common::city_with_nan_truth(&nan);
    let png = dir.path().join("nan.png");
    let out = probmot_ok(&["plot", nan.to_str().unwrap(), "-o", png.to_str().unwrap()]);
    let want = format!(
        "warning: {}: topic /ground_truth: 1 box(es) with a non-finite centre",
        nan.display()
    );
    assert!(stderr(&out).contains(&want), "{}", stderr(&out));
    let city = repo("sample_logs/city.mcap");
    let good = probmot_ok(&["plot", city.to_str().unwrap(), "-o", png.to_str().unwrap()]);
    assert!(!stderr(&good).contains("warning"), "{}", stderr(&good));
}

/// A whole log of more than ten minutes gets a warning that names --from/--to before it is
/// read; a window, or a short log, does not.
#[test]
fn plot_of_a_long_log_suggests_a_window() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("long.mcap");
    let l = log.to_str().unwrap();
    probmot_ok(&[
        "simulate",
        "--scenario",
        "turning-car",
        "--frames",
        "1300",
        "-o",
        l,
        "-q",
    ]);
    let png = dir.path().join("p.png");
    let p = png.to_str().unwrap();
    let whole = probmot_ok(&["plot", l, "-o", p, "--quiet"]);
    assert!(
        stderr(&whole).contains("is 11 minutes long")
            && stderr(&whole).contains("--from 0 --to 30"),
        "{}",
        stderr(&whole)
    );
    let window = probmot_ok(&["plot", l, "-o", p, "--quiet", "--from", "0", "--to", "30"]);
    assert!(!stderr(&window).contains("warning"), "{}", stderr(&window));
    let city = repo("sample_logs/city.mcap");
    let short = probmot_ok(&["plot", city.to_str().unwrap(), "-o", p, "--quiet"]);
    assert!(!stderr(&short).contains("warning"), "{}", stderr(&short));
}
