//! The lines `probmot import nuscenes` and `probmot export nuscenes` print.

use std::path::Path;

use super::{ExportSummary, ImportSummary};

impl ImportSummary {
    /// A line per scene written, then one over all of them (`out_dir`: where they went).
    pub fn lines(&self, out_dir: &Path) -> Vec<String> {
        let mut out: Vec<String> = (self.scenes.iter())
            .map(|sc| {
                format!(
                    "{}: {} frames, {} detections, {} track boxes, {} ground-truth boxes, {} \
                     bicycle racks, {} ego poses",
                    sc.output,
                    sc.frames,
                    sc.detections,
                    sc.tracks,
                    sc.truth_boxes,
                    sc.bike_racks,
                    sc.ego_poses
                )
            })
            .collect();
        let truth = match self.ground_truth {
            true => format!(
                "{} ground-truth boxes ({} outside the tracking classes skipped)",
                self.truth_boxes,
                self.truth_skipped.values().sum::<u64>()
            ),
            false => "no ground truth (no sample_annotation.json)".to_string(),
        };
        let ego = match self.ego_pose {
            true => format!("{} ego poses", self.ego_poses),
            false => "no ego poses".to_string(),
        };
        out.push(format!(
            "{}: {} scenes, {} frames, {} detections, {} track boxes, {} bicycle racks, {truth}, \
             {ego}",
            out_dir.display(),
            self.scenes.len(),
            self.frames,
            self.detections,
            self.tracks,
            self.bike_racks,
        ));
        out
    }
}

impl ExportSummary {
    /// The line of a submission written to `output`.
    pub fn line(&self, output: &Path) -> String {
        format!(
            "{}: {} scenes, {} samples, {} boxes ({} dropped over the 500-per-sample cap, {} \
             with a non-tracking label skipped)",
            output.display(),
            self.scenes,
            self.samples,
            self.boxes,
            self.dropped_over_cap,
            self.skipped_labels.values().sum::<u64>()
        )
    }
}
