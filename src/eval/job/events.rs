//! `probmot eval --events OUT.mcap`: the decisions behind the numbers, written as channels of a
//! copy of the truth log, with the worst moments (identity switches, then fragmentations) listed
//! in the report, each with a `--from/--to` window for `probmot plot`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::eval::event_view::frame_window;
use crate::eval::events::{resolve, ClassEvents, Collector, Counts, EventBoxes, Located, Protocol};
use crate::eval::events_log::{write_events_log, EventLabels, LogEvents};
use crate::mcapio::writer::{check_output_path, refuse_outputs_onto_inputs};
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::{event_text, EVENTS_SCENE_TOPIC, EVENTS_TOPIC};
use anyhow::{bail, Context, Result};

/// Worst moments listed in the report.
const WORST: usize = 10;

/// Seconds of context on each side of a moment in the suggested plot window.
const CONTEXT_S: f64 = 2.0;

/// One listed moment.
#[derive(Debug, Clone, serde::Serialize)]
struct Moment {
    log: String,
    time_s: f64,
    stamp_ns: u64,
    class: String,
    event: String,
    truth_id: u64,
    track_id: u64,
    previous_track_id: u64,
    from_s: f64,
    to_s: f64,
    /// The region framing the log's identity switches and fragmentations of the window, metres
    /// `[x0, x1, y0, y1]` (`plot --extent`).
    extent: Option<[f64; 4]>,
}

/// What `--events` wrote and found, for the report.
pub struct EventsReport {
    outputs: Vec<PathBuf>,
    counts: BTreeMap<String, Counts>,
    worst: Vec<Moment>,
    total_switches: u64,
    total_frags: u64,
}

impl EventsReport {
    /// The `events` member of `--json`.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "outputs": self.outputs, "topics": [EVENTS_TOPIC, EVENTS_SCENE_TOPIC],
            "counts": self.counts, "worst_moments": self.worst,
        })
    }

    /// The lines of the terminal report.
    pub fn text(&self) -> String {
        let mut s = format!(
            "\nevents ({} identity switches, {} fragmentations) written to {}",
            self.total_switches,
            self.total_frags,
            self.outputs
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        s.push_str(&format!(" ({EVENTS_TOPIC}, {EVENTS_SCENE_TOPIC})\n"));
        if !self.worst.is_empty() {
            s.push_str(
                "worst moments (time after the log's first frame; plot window and region):\n",
            );
        }
        let width = self.worst.iter().map(|m| m.event.len()).max().unwrap_or(0);
        for m in &self.worst {
            let extent = m.extent.map_or(String::new(), |e| {
                format!(" --extent {:.0},{:.0},{:.0},{:.0}", e[0], e[1], e[2], e[3])
            });
            s.push_str(&format!(
                "  {:>8.2} s  {:<10}  {:<width$}  {}  --from {:.1} --to {:.1}{extent}\n",
                m.time_s, m.class, m.event, m.log, m.from_s, m.to_s
            ));
        }
        s
    }
}

/// Where each log's events go: `out` itself for one log, `out/<truth file name>` for several
/// (`out` is then a directory, created if missing).
fn output_paths(out: &Path, pairs: &[(PathBuf, PathBuf)]) -> Result<Vec<PathBuf>> {
    let outputs = events_outputs(out, pairs)?;
    let inputs: Vec<PathBuf> = pairs
        .iter()
        .flat_map(|(truth, tracks)| [truth.clone(), tracks.clone()])
        .collect();
    refuse_outputs_onto_inputs(&outputs, &inputs)?;
    Ok(outputs)
}

/// [`output_paths`] before the check against every input.
fn events_outputs(out: &Path, pairs: &[(PathBuf, PathBuf)]) -> Result<Vec<PathBuf>> {
    if let [(truth, _)] = pairs {
        check_output_path(Some(truth), out)?;
        return Ok(vec![out.to_path_buf()]);
    }
    if out.exists() && !out.is_dir() {
        bail!(
            "--events {}: several logs are evaluated, so --events names a directory (one copy \
             per log, named as the truth file)",
            out.display()
        );
    }
    std::fs::create_dir_all(out)?;
    pairs
        .iter()
        .map(|(truth, _)| {
            let dest = out.join(truth.file_name().unwrap_or_default());
            check_output_path(Some(truth), &dest)?;
            Ok(dest)
        })
        .collect()
}

/// Turns the decisions each class's evaluation recorded at its best-MOTA threshold (`logs`,
/// from `evaluate_recording` of `protocol`) into events, writes one copy of each truth log with
/// the events channels and returns the report. Each class's record is dropped once resolved
/// and its events moved to their logs, keeping only what the report lists (a long log has
/// millions of events; no second copy).
pub fn write<B: EventBoxes + ?Sized>(
    out: &Path,
    (protocol, logs): (Protocol, Vec<(String, Collector)>),
    pairs: &[(PathBuf, PathBuf)],
    scenes: &B,
    truth_topic: &str,
) -> Result<EventsReport> {
    let dests = output_paths(out, pairs)?;
    let name = match protocol {
        Protocol::Nuscenes => "nuscenes",
        Protocol::Kitti => "kitti",
    };
    let mut per_log: Vec<LogEvents> = vec![LogEvents::new(); scenes.logs()];
    let mut summaries = Vec::with_capacity(logs.len());
    for (class, (label, log)) in logs.into_iter().enumerate() {
        let class = u16::try_from(class).context("more than 65,536 classes")?;
        let ClassEvents {
            class: label,
            counts,
            events,
        } = resolve(scenes, &label, &log, protocol);
        drop(log);
        let listed = (events.iter())
            .filter(|e| matches!(e.event.kind, Kind::Switch | Kind::Fragmentation))
            .copied()
            .collect();
        for e in events {
            let stamp = scenes.stamp(e.scene, e.frame);
            per_log[e.scene]
                .entry(stamp)
                .or_default()
                .push((class, e.event));
        }
        summaries.push(ClassSummary {
            class: label,
            counts,
            listed,
        });
    }
    let names: Vec<String> = summaries.iter().map(|c| c.class.clone()).collect();
    let labels = EventLabels {
        protocol: name,
        classes: &names,
    };
    for (((truth, _), dest), events) in pairs.iter().zip(&dests).zip(&per_log) {
        write_events_log(truth, dest, truth_topic, (events, labels), false)?;
    }
    Ok(report(dests, &summaries, scenes))
}

/// What the report keeps of one class's events: the counts, and the identity switches and
/// fragmentations it may list.
struct ClassSummary {
    class: String,
    counts: Counts,
    listed: Vec<Located>,
}

/// The region of the identity switches and fragmentations of `m`'s log in its plot window
/// (every class: `plot` draws them all by default).
fn frame_listed<B: EventBoxes + ?Sized>(
    classes: &[ClassSummary],
    scenes: &B,
    m: &Moment,
) -> Option<(f64, f64, f64, f64)> {
    let same_log = |e: &&Located| scenes.name(e.scene) == m.log;
    let timed = (classes
        .iter()
        .flat_map(|c| c.listed.iter().filter(same_log)))
    .map(|e| {
        let t = (scenes.stamp(e.scene, e.frame) - scenes.stamp(e.scene, 0)) as f64 / 1e9;
        (t, (e.event.center[0], e.event.center[1]))
    });
    frame_window(timed, m.from_s, m.to_s)
}

fn report<B: EventBoxes + ?Sized>(
    outputs: Vec<PathBuf>,
    classes: &[ClassSummary],
    scenes: &B,
) -> EventsReport {
    let mut worst = Vec::new();
    for kind in [Kind::Switch, Kind::Fragmentation] {
        let start = worst.len();
        for ce in classes {
            for e in ce.listed.iter().filter(|e| e.event.kind == kind) {
                let stamp = scenes.stamp(e.scene, e.frame);
                let time_s = (stamp - scenes.stamp(e.scene, 0)) as f64 / 1e9;
                worst.push(Moment {
                    log: scenes.name(e.scene).to_string(),
                    time_s,
                    stamp_ns: stamp,
                    class: ce.class.clone(),
                    event: event_text(&e.event.message("")),
                    truth_id: e.event.truth_id,
                    track_id: e.event.track_id,
                    previous_track_id: e.event.previous_track_id,
                    from_s: (time_s - CONTEXT_S).max(0.0),
                    to_s: time_s + CONTEXT_S,
                    extent: None,
                });
            }
        }
        // Switches first, then fragmentations, each in time order (log, time, class).
        worst[start..].sort_by(|a: &Moment, b: &Moment| {
            (&a.log, a.stamp_ns, &a.class).cmp(&(&b.log, b.stamp_ns, &b.class))
        });
    }
    worst.truncate(WORST);
    for m in &mut worst {
        m.extent = frame_listed(classes, scenes, m).map(|e| [e.0, e.1, e.2, e.3]);
    }
    EventsReport {
        outputs,
        counts: classes
            .iter()
            .map(|c| (c.class.clone(), c.counts))
            .collect(),
        total_switches: classes.iter().map(|c| c.counts.ids).sum(),
        total_frags: classes.iter().map(|c| c.counts.frag).sum(),
        worst,
    }
}
