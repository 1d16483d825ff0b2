//! Shared harness code of the fuzz targets (see `fuzz/README.md`).

use probmot::msgs::{self, Detections3D, DetectionsEnvelope, Encoding};
use probmot::pipeline::detections::{convert, InputCounters, Origin};
use probmot::tracker::{Tracker, TrackerConfig};

/// Preset used when `probmot track` is given no `--preset`/`--config`.
pub const DEFAULT_PRESET: &str = "nuscenes-chiu2019";

/// Frames the decoded message is replayed for (so that the second and third frames exercise
/// prediction, association and update of the tracks born in the first).
const FRAMES: u64 = 3;

/// Decodes `data` as `Detections3D` and as `DetectionsEnvelope` (the two decodes `track` does
/// of every detection message, in its two passes), and runs the boxes of a decoded message
/// through `convert` and `Tracker::step`. Errors are fine; panics and these invariants are not:
///
/// * a message that decodes fully also decodes as an envelope, with the same stamp and box count
///   (otherwise `track`'s two passes would disagree about the frames);
/// * `convert` with `strict` refuses exactly the boxes it skips without;
/// * `Tracker::step` accepts every box `convert` let through, at increasing stamps.
pub fn decode_and_track(data: &[u8], encoding: Encoding) {
    let envelope = msgs::decode::<DetectionsEnvelope>(data, encoding);
    let Ok(msg) = msgs::decode::<Detections3D>(data, encoding) else {
        return;
    };
    let envelope = envelope.expect("a message that decodes fully decodes as an envelope");
    assert_eq!(envelope.stamp, msg.stamp, "envelope stamp");
    assert_eq!(
        envelope.detections.len(),
        msg.detections.len(),
        "envelope count"
    );

    let config = TrackerConfig::preset(DEFAULT_PRESET).expect("default preset");
    let mut tracker = Tracker::new(config.clone()).expect("default preset validates");
    let mut strict_tracker = Tracker::new(config).expect("default preset validates");
    let mut counters = InputCounters::default();
    let mut strict_counters = InputCounters::default();
    let origin = Origin {
        file: "fuzz",
        topic: "/detections",
        log_time: 0,
    };
    let mut dets = Vec::with_capacity(msg.detections.len());
    for (i, d) in msg.detections.iter().enumerate() {
        let lenient = convert(d, i, &mut tracker, &mut counters, false, &origin)
            .expect("convert without --strict never fails");
        let strict = convert(
            d,
            i,
            &mut strict_tracker,
            &mut strict_counters,
            true,
            &origin,
        );
        match (&lenient, &strict) {
            (Some(a), Ok(Some(b))) => assert_eq!((a.bbox, a.score), (b.bbox, b.score)),
            (None, Err(_)) => {}
            _ => panic!("strict and lenient convert disagree on detection {i}: {d:?}"),
        }
        dets.extend(lenient);
    }
    assert_eq!(
        counters.total_skipped() as usize + dets.len(),
        msg.detections.len(),
        "every box is either converted or counted as skipped"
    );

    // Step spacing from the message's own stamp: 1 ns .. ~10 s.
    let dt = msg.stamp.unwrap_or(500_000_000) % 10_000_000_000 + 1;
    for k in 0..FRAMES {
        let stamp = 1 + k * dt;
        if let Err(e) = tracker.step(stamp, &dets) {
            panic!("step refused converted detections at stamp {stamp}: {e}");
        }
        // Touch every report (formats and reads all fields).
        for r in tracker.reports() {
            std::hint::black_box(format!("{r:?} {}", tracker.label(r.class)));
        }
    }
    std::hint::black_box(tracker.mean_confirmed_track_length());
}
