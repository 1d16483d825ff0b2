//! Tracking frames made in code, without any MCAP file: two cars, one driving along x and one
//! crossing along y, seen every 0.5 s (the preset's frame rate) by a detector that misses the second car once and
//! reports a false box once. Prints each frame's confirmed tracks and the summary.
//!
//! Run with `cargo run --example track_in_code`.

use anyhow::{ensure, Result};
use probmot::msgs::detection_frame::{DetectionBox, DetectionFrame};
use probmot::pipeline::track_session::{SessionOptions, TrackSession};
use probmot::tracker::{Box3, TrackerConfig};

/// A car detection at `(x, y)` heading `yaw`.
fn car(index: u32, x: f64, y: f64, yaw: f64) -> DetectionBox {
    DetectionBox {
        index,
        bbox: Box3 {
            center: [x, y, 0.8],
            yaw,
            size: [4.5, 1.9, 1.6],
        },
        label: "car".into(),
        score: 0.8,
        velocity: None,
        image_box: None,
        attributes: Default::default(),
        needs_own_entry: false,
    }
}

/// Frame `i`: what the detector reports at `t = 0.5 i` s.
fn frame(i: u32) -> DetectionFrame {
    let t = 0.5 * f64::from(i);
    let mut boxes = vec![car(0, 6.0 * t, 0.0, 0.0)];
    if i != 7 {
        boxes.push(car(1, 20.0, -15.0 + 3.0 * t, std::f64::consts::FRAC_PI_2));
    }
    if i == 12 {
        boxes.push(car(2, -30.0, 30.0, 0.0));
    }
    DetectionFrame {
        stamp: 1_700_000_000_000_000_000 + u64::from(i) * 500_000_000,
        frame_id: "map".into(),
        boxes,
        rejected: vec![],
    }
}

fn main() -> Result<()> {
    let config = TrackerConfig::preset("nuscenes-chiu2019")?;
    let mut session = TrackSession::new(config, SessionOptions::default())?;
    let mut ids = std::collections::BTreeSet::new();
    for i in 0..30 {
        session.track(frame(i))?;
        while let Some(tracks) = session.next_frame() {
            let shown: Vec<String> = (tracks.tracks.iter())
                .map(|t| {
                    let (x, y) = t.center.as_ref().map_or((0.0, 0.0), |c| (c.x, c.y));
                    format!("{} {} at ({x:.1}, {y:.1})", t.label, t.id)
                })
                .collect();
            ids.extend(tracks.tracks.iter().map(|t| t.id));
            println!("{}: {}", tracks.stamp, shown.join(", "));
        }
    }
    session.end();
    while let Some(tracks) = session.next_frame() {
        println!("{}: {} tracks (held)", tracks.stamp, tracks.tracks.len());
    }
    let summary = session.finish();
    println!(
        "{} frames, {} tracks born, {} confirmed, ids shown: {ids:?}",
        summary.frames, summary.tracks_born, summary.tracks_confirmed
    );
    for w in &summary.warnings {
        println!("warning: {w}");
    }
    // Two cars, two tracks: the missed frame does not break the crossing car's track, and the
    // false box never becomes a confirmed track.
    ensure!(ids.len() == 2, "expected two track ids, got {ids:?}");
    Ok(())
}

/// `cargo test` builds the example as a test (`test = true` in Cargo.toml) and runs it here.
#[test]
fn the_example_runs_and_finds_two_tracks() {
    main().unwrap();
}
