//! Reading a [`FitLog`] from an MCAP file: a ground-truth channel (`probmot.Tracks3D` with the
//! true instance ids) and a detections channel (`probmot.Detections3D`).

use std::collections::{BTreeMap, HashSet};
use std::path::Path;

use anyhow::{bail, Result};

use super::accumulate::FitAccumulator;
use super::data::{assemble_frames, FitFrame, FitLog};
use crate::mcapio::recording::{self, Boxes, FrameEvent, TopicKind, TopicRequest};
use crate::mcapio::LabelledBox;
use crate::msgs::detection_frame::{check_box, count_skips, SkipReason};
use crate::msgs::{Detection3D, Track3D};

/// `(stamp, boxes)` per message of one topic.
type TopicBoxes = Vec<(u64, Vec<LabelledBox>)>;

/// Detection boxes left out, by reason.
type Skipped = BTreeMap<SkipReason, u64>;

/// Reads topics of `path` in one pass ([`recording::for_each_frame`]), each message turned into
/// fit boxes as soon as it is decoded: `(stamp, boxes)` per message and request, the stamp being
/// the message's own else its MCAP `log_time` (as `probmot track` does). A missing topic,
/// another schema or an undecodable message is an error naming them. `progress` gets the bytes
/// read at each step. Detection boxes `track` would skip are left out and counted (an Autoware
/// class that is none of probmot's without a config entry of its name: `has_entry`).
fn read_topics(
    path: &Path,
    wanted: &[TopicRequest],
    has_entry: &dyn Fn(&str) -> bool,
    progress: &dyn Fn(u64),
) -> Result<(Vec<TopicBoxes>, Skipped)> {
    let mut out: Vec<Option<TopicBoxes>> = vec![None; wanted.len()];
    let mut skipped = Skipped::new();
    let mut reported = 0u64;
    let topics = recording::for_each_frame(path, wanted, |event, stats| {
        progress(stats.bytes_read.saturating_sub(reported));
        reported = reported.max(stats.bytes_read);
        match event {
            FrameEvent::Channel(i) => {
                out[i].get_or_insert_with(Vec::new);
            }
            FrameEvent::Frame(i, mut f) => {
                f.skip_classes_without_entry(has_entry);
                count_skips(&mut skipped, &f.skipped);
                // Extended into a new vector: `collect` would keep the decoded messages'
                // larger allocation in place for as long as the log is held.
                let mut boxes = Vec::new();
                match f.boxes {
                    Boxes::Detections(d) => {
                        boxes.reserve_exact(d.len());
                        let kept = d.into_iter().filter_map(|d| detection_box(d, &mut skipped));
                        boxes.extend(kept);
                    }
                    Boxes::Tracks(t) => {
                        boxes.reserve_exact(t.len());
                        boxes.extend(t.into_iter().map(truth_box));
                    }
                }
                out[i].get_or_insert_with(Vec::new).push((f.stamp, boxes));
            }
        }
        Ok(())
    })?;
    let read = out
        .into_iter()
        .zip(wanted)
        .map(|(o, r)| o.ok_or_else(|| recording::no_channel(path.display(), &r.topic, &topics)));
    Ok((read.collect::<Result<_>>()?, skipped))
}

fn request(topic: &str, kind: TopicKind, role: &str) -> TopicRequest {
    TopicRequest {
        topic: topic.to_string(),
        kind,
        role: role.to_string(),
    }
}

/// A ground-truth track as a fit box (missing centre or size read as zeros, as eval does); the
/// fit reads no attribute, so none is kept.
fn truth_box(t: Track3D) -> LabelledBox {
    LabelledBox::from_track(t).keep_attributes(|_| false)
}

/// A detection as a fit box, if `track` would track it (else counted in `skipped`: it measures
/// nothing the tracker sees).
fn detection_box(d: Detection3D, skipped: &mut Skipped) -> Option<LabelledBox> {
    match check_box(&d) {
        Ok(_) => Some(LabelledBox::from_detection(d).keep_attributes(|_| false)),
        Err(reason) => {
            *skipped.entry(reason).or_default() += 1;
            None
        }
    }
}

/// Reads one log: truth from `truth_topic`, detections from `detections_topic`. The truth must
/// carry instance ids: a box with id 0 (except `dontcare` regions, which are skipped), or two
/// boxes with the same label and id at one stamp, is an error. Autoware classes that are none
/// of probmot's are skipped as `track` skips them with a config without entries of their names
/// (every preset); [`load_log_progress`] takes the config's entries.
pub fn load_log(path: &Path, truth_topic: &str, detections_topic: &str) -> Result<FitLog> {
    load_log_progress(path, (truth_topic, detections_topic), &|_| false, &|_| {})
}

/// Feeds one log to `acc` frame by frame while the file streams (one pass), holding only the
/// frames whose stamp either channel may still reach: a frame is complete once both channels
/// have moved past its stamp. That needs each channel's stamps in order; a log whose stamps go
/// back is read whole instead ([`load_log_progress`]), with the same result. Errors as
/// [`load_log`]; `has_entry` as in [`load_log_progress`].
pub fn stream_log(
    acc: &mut FitAccumulator,
    path: &Path,
    topics: (&str, &str),
    has_entry: &dyn Fn(&str) -> bool,
    progress: &dyn Fn(u64),
) -> Result<()> {
    let before = acc.clone();
    match stream_ordered(acc, path, topics, has_entry, progress)? {
        true => Ok(()),
        false => {
            *acc = before;
            let log = load_log_progress(path, topics, has_entry, &|_| {})?;
            acc.add_log(&log);
            Ok(())
        }
    }
}

/// The instances `(label, id)` of one stamp's truth so far.
type SeenInstances = HashSet<(String, u64)>;

/// Frames not yet complete in [`stream_log`]: per stamp, the truth (if any message) with the
/// instance keys seen, the detections, and the detection messages.
#[derive(Default)]
struct Pending {
    truth: Option<(Vec<LabelledBox>, SeenInstances)>,
    detections: Vec<LabelledBox>,
    detection_messages: u64,
}

/// [`stream_log`] while both channels' stamps are in order; `false` (and a partial feed) as
/// soon as one goes back.
fn stream_ordered(
    acc: &mut FitAccumulator,
    path: &Path,
    (truth_topic, detections_topic): (&str, &str),
    has_entry: &dyn Fn(&str) -> bool,
    progress: &dyn Fn(u64),
) -> Result<bool> {
    let file = path.display().to_string();
    let wanted = [
        request(truth_topic, TopicKind::Tracks, "ground truth"),
        request(detections_topic, TopicKind::Detections, "detections"),
    ];
    let mut log = acc.begin_log(&file);
    let (mut skipped, mut skipped_truth) = (Skipped::new(), 0u64);
    let mut pending: BTreeMap<u64, Pending> = BTreeMap::new();
    let mut newest: [Option<u64>; 2] = [None, None];
    let mut found = [false; 2];
    let mut ordered = true;
    let mut reported = 0u64;
    let mut flush =
        |acc: &mut FitAccumulator, pending: &mut BTreeMap<u64, Pending>, below: Option<u64>| {
            while let Some(entry) = pending
                .first_entry()
                .filter(|e| below.is_none_or(|b| *e.key() < b))
            {
                let (stamp, p) = entry.remove_entry();
                match p.truth {
                    Some((truth, _)) => {
                        let detections = p.detections;
                        acc.push_frame(
                            &mut log,
                            FitFrame {
                                stamp,
                                truth,
                                detections,
                            },
                        );
                    }
                    None => acc.add_unmatched(p.detection_messages),
                }
            }
        };
    let topics = recording::for_each_frame(path, &wanted, |event, stats| {
        progress(stats.bytes_read.saturating_sub(reported));
        reported = reported.max(stats.bytes_read);
        let (i, f) = match event {
            FrameEvent::Channel(i) => {
                found[i] = true;
                return Ok(());
            }
            FrameEvent::Frame(_, _) if !ordered => return Ok(()),
            FrameEvent::Frame(i, f) => (i, f),
        };
        let mut f = f;
        f.skip_classes_without_entry(has_entry);
        if newest[i].is_some_and(|n| f.stamp < n) {
            ordered = false;
            return Ok(());
        }
        newest[i] = Some(f.stamp);
        let p = pending.entry(f.stamp).or_default();
        match f.boxes {
            Boxes::Tracks(t) => {
                let (boxes, seen) = p.truth.get_or_insert_with(Default::default);
                for b in t.into_iter().map(truth_box) {
                    let at = (file.as_str(), truth_topic, f.stamp);
                    if check_truth_box(&b, seen, &mut skipped_truth, at)? {
                        boxes.push(b);
                    }
                }
            }
            Boxes::Detections(d) => {
                count_skips(&mut skipped, &f.skipped);
                let kept = d.into_iter().filter_map(|d| detection_box(d, &mut skipped));
                p.detections.extend(kept);
                p.detection_messages += 1;
            }
        }
        if let [Some(a), Some(b)] = newest {
            flush(acc, &mut pending, Some(a.min(b)));
        }
        Ok(())
    })?;
    if !ordered {
        return Ok(false);
    }
    if let Some(k) = found.iter().position(|f| !f) {
        return Err(recording::no_channel(&file, &wanted[k].topic, &topics));
    }
    if newest[0].is_none() {
        bail!("{file}: topic {truth_topic} (ground truth) has no messages");
    }
    flush(acc, &mut pending, None);
    acc.add_skipped(&skipped);
    acc.add_skipped_truth(skipped_truth);
    Ok(true)
}

/// Whether a truth box counts (KITTI's `dontcare` regions, id 0, hold no box; one with a
/// non-finite centre, size or yaw is left out and counted in `non_finite`); an error for a box
/// without id or an instance given twice at one stamp.
fn check_truth_box(
    b: &LabelledBox,
    seen: &mut HashSet<(String, u64)>,
    non_finite: &mut u64,
    (file, topic, stamp): (&str, &str, u64),
) -> Result<bool> {
    if b.id == 0 && b.label == "dontcare" {
        return Ok(false);
    }
    if b.id == 0 {
        bail!(
            "{file}: topic {topic}, stamp {stamp}: ground-truth box ({}) has no id (id 0); the \
             fit needs the true instance ids",
            b.label
        );
    }
    if !b.is_finite() {
        *non_finite += 1;
        return Ok(false);
    }
    if !seen.insert((b.label.clone(), b.id)) {
        bail!(
            "{file}: topic {topic}, stamp {stamp}: two ground-truth boxes with label {} and id {}",
            b.label,
            b.id
        );
    }
    Ok(true)
}

/// [`load_log`] in one pass over the file, telling `progress` the bytes read at each step; an
/// Autoware class that is none of probmot's is read only when `has_entry` (the config has an
/// entry of its name), as `track` tracks it only then.
pub fn load_log_progress(
    path: &Path,
    (truth_topic, detections_topic): (&str, &str),
    has_entry: &dyn Fn(&str) -> bool,
    progress: &dyn Fn(u64),
) -> Result<FitLog> {
    let file = path.display().to_string();
    let wanted = [
        request(truth_topic, TopicKind::Tracks, "ground truth"),
        request(detections_topic, TopicKind::Detections, "detections"),
    ];
    let (mut read, skipped) = read_topics(path, &wanted, has_entry, progress)?;
    let detections = read.pop().expect("two requests");
    let truth = read.pop().expect("two requests");
    if truth.is_empty() {
        bail!("{file}: topic {truth_topic} (ground truth) has no messages");
    }
    let mut by_stamp: BTreeMap<u64, HashSet<(String, u64)>> = BTreeMap::new();
    let mut truth_boxes = Vec::with_capacity(truth.len());
    let mut skipped_truth = 0;
    for (stamp, boxes) in truth {
        let seen = by_stamp.entry(stamp).or_default();
        let mut fb = Vec::with_capacity(boxes.len());
        for b in boxes {
            // Regions without an object (KITTI's DontCare, imported with id 0) hold no box.
            if check_truth_box(&b, seen, &mut skipped_truth, (&file, truth_topic, stamp))? {
                fb.push(b);
            }
        }
        truth_boxes.push((stamp, fb));
    }
    let mut log = assemble_frames(&file, truth_boxes, detections);
    log.skipped_detections = skipped;
    log.skipped_truth = skipped_truth;
    Ok(log)
}
