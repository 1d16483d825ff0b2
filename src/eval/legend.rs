//! What each column of `probmot eval`'s tables means: its unit and which way is better, for
//! `eval --explain`, `eval --help` and the direction row of the change table.

/// Which way a metric improves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Better {
    /// A larger value is better (`+` in the change table).
    Higher,
    /// A smaller value is better (`-` in the change table).
    Lower,
}

impl Better {
    /// The sign of an improvement: `+` or `-`.
    pub fn sign(self) -> &'static str {
        match self {
            Better::Higher => "+",
            Better::Lower => "-",
        }
    }
}

/// One column of a table.
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    /// The column's name as the table prints it (upper case).
    pub column: &'static str,
    /// Its unit or range.
    pub unit: &'static str,
    /// Which way is better.
    pub better: Better,
    /// What it measures.
    pub meaning: &'static str,
}

const fn e(
    column: &'static str,
    unit: &'static str,
    better: Better,
    meaning: &'static str,
) -> Entry {
    Entry {
        column,
        unit,
        better,
        meaning,
    }
}

use Better::{Higher as H, Lower as L};

/// One table of the report: its title and its columns.
#[derive(Debug, Clone, Copy)]
pub struct Section {
    /// Which table, and how its rows are made.
    pub title: &'static str,
    /// Its columns, in the table's order.
    pub entries: &'static [Entry],
}

/// The nuScenes table (`--protocol nuscenes`, the default).
pub const NUSCENES: Section = Section {
    title: "nuScenes table (the default protocol; matches: ground-plane centre distance <= 2 m; \
            the CLEAR MOT columns are at the score threshold of the best MOTA; overall: mean \
            over the classes with ground truth, counts summed)",
    entries: &[
        e("AMOTA", "0..1", H, "average multi-object tracking accuracy: recall-normalised MOTA averaged over 40 recall thresholds (the devkit's headline metric)"),
        e("AMOTP", "m", L, "average multi-object tracking precision: MOTP averaged over the recall thresholds (2 m where a recall is not reached)"),
        e("RECALL", "0..1", H, "share of ground-truth boxes matched"),
        e("MOTA", "0..1", H, "multi-object tracking accuracy: 1 - (FN + FP + IDS) / ground-truth boxes, at least 0"),
        e("MOTP", "m", L, "multi-object tracking precision: mean centre distance of the matches"),
        e("IDS", "count", L, "identity switches: a ground-truth object matched by another track than before"),
        e("FRAG", "count", L, "fragmentations: a tracked ground-truth object lost, then tracked again"),
        e("FP", "count", L, "false positives: track boxes that match no ground truth"),
        e("FN", "count", L, "false negatives: ground-truth boxes no track box matches"),
        e("MT", "count", H, "mostly tracked: ground-truth objects matched in at least 80 % of their frames"),
        e("ML", "count", L, "mostly lost: ground-truth objects matched in under 20 % of their frames"),
        e("FAF", "per 100 frames", L, "false alarms per frame, x 100 (as the devkit reports it)"),
        e("TID", "s", L, "track initialisation duration: mean time from an object's first frame to its first match"),
        e("LGD", "s", L, "longest gap duration: mean over objects of the longest time an object is not matched"),
    ],
};

/// The KITTI table (`--protocol kitti`, AB3DMOT's evaluation).
pub const KITTI: Section = Section {
    title: "KITTI table (--protocol kitti; matches: 3D IoU >= --iou; the CLEAR MOT columns are \
            at the score threshold of the best MOTA; overall: mean over the classes, counts summed)",
    entries: &[
        e("SAMOTA", "0..1", H, "scaled AMOTA (AB3DMOT's headline metric): MOTA scaled by the recall reached, averaged over 40 recall points"),
        e("AMOTA", "<= 1", H, "MOTA averaged over the 40 recall points"),
        e("AMOTP", "IoU 0..1", H, "MOTP averaged over the 40 recall points"),
        e("MOTA", "<= 1", H, "multi-object tracking accuracy: 1 - (FN + FP + IDS) / ground-truth boxes"),
        e("MOTP", "IoU 0..1", H, "multi-object tracking precision: mean 3D IoU of the matches"),
        e("IDS", "count", L, "identity switches"),
        e("FRAG", "count", L, "fragmentations: a tracked ground-truth object lost, then tracked again"),
        e("FP", "count", L, "false positives"),
        e("FN", "count", L, "false negatives"),
        e("TP", "count", H, "true positives (matches, those of ignored ground truth included)"),
        e("RECALL", "0..1", H, "TP / (TP + FN)"),
        e("PRECISION", "0..1", H, "TP / (TP + FP)"),
        e("MT", "0..1", H, "mostly tracked: share of ground-truth objects matched in over 80 % of their frames"),
        e("ML", "0..1", L, "mostly lost: share of ground-truth objects matched in under 20 % of their frames"),
    ],
};

/// The HOTA table (both protocols; TrackEval's definitions, means over 19 localisation
/// thresholds alpha).
pub const HOTA: Section = Section {
    title: "HOTA table (TrackEval's definitions, each the mean over the localisation thresholds \
            alpha = 0.05 .. 0.95; overall: mean over the classes shown, TrackEval's class average)",
    entries: &[
        e("HOTA", "0..1", H, "higher order tracking accuracy: sqrt(DetA x AssA)"),
        e("DETA", "0..1", H, "detection accuracy: TP / (TP + FN + FP)"),
        e("ASSA", "0..1", H, "association accuracy: how well the matches of each object keep one track, and each track one object"),
        e("LOCA", "0..1", H, "localisation accuracy: mean similarity of the matches"),
        e("DETRE", "0..1", H, "detection recall: TP / (TP + FN)"),
        e("DETPR", "0..1", H, "detection precision: TP / (TP + FP)"),
        e("ASSRE", "0..1", H, "association recall: how much of each object's life its track covers"),
        e("ASSPR", "0..1", H, "association precision: how much of each track's life is one object"),
    ],
};

/// Every table, in the report's order.
pub const SECTIONS: [Section; 3] = [NUSCENES, KITTI, HOTA];

impl Section {
    /// The entry of `column` (any case), if the table has it.
    pub fn entry(&self, column: &str) -> Option<&Entry> {
        (self.entries.iter()).find(|e| e.column.eq_ignore_ascii_case(column))
    }

    /// The sign of an improvement per column of `columns` (`+`, `-`, or empty when the column
    /// is not in the table), for the change table's direction row.
    pub fn signs(&self, columns: &[&str]) -> Vec<String> {
        (columns.iter())
            .map(|c| self.entry(c).map_or("", |e| e.better.sign()).to_string())
            .collect()
    }

    /// The legend of this table, one entry per column, wrapped to [`WIDTH`].
    pub fn text(&self) -> String {
        let name_w = self
            .entries
            .iter()
            .map(|e| e.column.len())
            .max()
            .unwrap_or(0);
        let unit_w = self.entries.iter().map(|e| e.unit.len()).max().unwrap_or(0);
        let mut s = wrap(&format!("{}:", self.title), "", "");
        for en in self.entries {
            let head = format!(
                "  {:<name_w$}  {:<unit_w$}  {} better  ",
                en.column,
                en.unit,
                en.better.sign()
            );
            let indent = " ".repeat(head.len());
            s.push_str(&wrap(en.meaning, &head, &indent));
        }
        s
    }
}

/// The width the legend is wrapped to (what `--help` shows unwrapped on a 100-column terminal).
pub const WIDTH: usize = 98;

/// `text` as lines of at most [`WIDTH`] characters (a longer word stays whole): the first
/// starts with `first`, the others with `indent`.
fn wrap(text: &str, first: &str, indent: &str) -> String {
    let mut out = String::new();
    let mut line = first.to_string();
    let mut empty = true;
    for word in text.split_whitespace() {
        if !empty && line.len() + 1 + word.len() > WIDTH {
            out.push_str(line.trim_end());
            out.push('\n');
            line = indent.to_string();
            empty = true;
        }
        if !empty {
            line.push(' ');
        }
        line.push_str(word);
        empty = false;
    }
    out.push_str(line.trim_end());
    out.push('\n');
    out
}

/// The legend of `sections`, with the key to the signs.
pub fn text(sections: &[Section]) -> String {
    let mut s = wrap(
        "What the columns of `probmot eval` mean (unit; + better: higher is better, - better: \
         lower is better; the change table's row `better` gives the same signs)",
        "",
        "",
    );
    for sec in sections {
        s.push('\n');
        s.push_str(&sec.text());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_column_of_every_table_has_one_entry() {
        for sec in SECTIONS {
            let mut names: Vec<&str> = sec.entries.iter().map(|e| e.column).collect();
            names.sort_unstable();
            names.dedup();
            assert_eq!(names.len(), sec.entries.len(), "{}", sec.title);
            assert!(sec
                .entries
                .iter()
                .all(|e| e.column == e.column.to_uppercase()));
        }
    }

    #[test]
    fn signs_follow_the_direction_and_leave_unknown_columns_blank() {
        let s = NUSCENES.signs(&["amota", "AMOTP", "ids", "mt", "unknown"]);
        assert_eq!(s, ["+", "-", "-", "+", ""]);
        // KITTI's MOTP is an IoU (higher is better), nuScenes' a distance.
        assert_eq!(KITTI.signs(&["MOTP"]), ["+"]);
        assert_eq!(NUSCENES.signs(&["motp"]), ["-"]);
    }

    #[test]
    fn the_text_has_a_line_per_column_with_unit_and_sign() {
        let t = text(&SECTIONS);
        let line = t
            .lines()
            .find(|l| l.trim_start().starts_with("AMOTP"))
            .unwrap();
        assert!(line.contains(" m ") && line.contains("- better"), "{line}");
        let n = SECTIONS.iter().map(|s| s.entries.len()).sum::<usize>();
        assert_eq!(t.lines().filter(|l| l.contains(" better  ")).count(), n);
        assert!(t.lines().all(|l| l.len() <= WIDTH), "{t}");
        // A wrapped meaning continues under its first line, not at the margin.
        let i = t
            .lines()
            .position(|l| l.trim_start().starts_with("SAMOTA"))
            .unwrap();
        let next = t.lines().nth(i + 1).unwrap();
        let col = line_start_of_meaning(t.lines().nth(i).unwrap());
        assert!(next.len() > col && next[..col].trim().is_empty(), "{next}");
    }

    fn line_start_of_meaning(line: &str) -> usize {
        line.find(" better  ").unwrap() + " better  ".len()
    }
}
