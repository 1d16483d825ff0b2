//! The ground truth of an import: the annotations of the imported samples, each with its
//! tracking class, instance id and devkit velocity; bicycle racks apart.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use anyhow::{bail, Context, Result};

use super::plan::table;
use super::tables::{read_all, read_table, AnnotationRow, CategoryRow, InstanceRow};
use super::tracks::RackAnn;
use super::{tracking_name, BIKE_RACK_CATEGORY};

/// Ground-truth box of one sample.
pub(crate) struct TruthBox {
    pub(crate) id: u64,
    pub(crate) label: &'static str,
    pub(crate) ann: AnnotationRow,
    pub(crate) category: String,
    pub(crate) velocity: [f64; 3],
}

/// The ground truth of the imported samples, by sample token.
#[derive(Default)]
pub(crate) struct GroundTruth {
    /// Boxes of the seven tracking classes.
    pub(crate) boxes: HashMap<String, Vec<TruthBox>>,
    /// Bicycle racks.
    pub(crate) racks: HashMap<String, Vec<RackAnn>>,
    /// Boxes of other categories (skipped), per category.
    pub(crate) skipped: BTreeMap<String, u64>,
}

/// Reads the ground truth of the samples in `wanted` (`time_us`: their timestamps), or `None`
/// when the tables have no `sample_annotation.json`.
pub(crate) fn read_truth(
    meta: &Path,
    wanted: &HashSet<&str>,
    time_us: &HashMap<String, u64>,
) -> Result<Option<GroundTruth>> {
    let ann_path = table(meta, "sample_annotation.json");
    if !ann_path.is_file() {
        return Ok(None);
    }
    let classes = Classes::read(meta, &ann_path)?;
    let anns: Vec<AnnotationRow> = read_table(&ann_path, |a: &AnnotationRow| {
        wanted.contains(a.sample_token.as_str())
    })?;
    let by_token: HashMap<String, AnnotationRow> =
        anns.iter().map(|a| (a.token.clone(), a.clone())).collect();
    let mut truth = GroundTruth::default();
    for a in anns {
        let (id, category) = classes.of(meta, &a)?;
        if category == BIKE_RACK_CATEGORY {
            let rack = RackAnn {
                id,
                token: a.token,
                translation: a.translation,
                size: a.size,
                rotation: a.rotation,
            };
            truth.racks.entry(a.sample_token).or_default().push(rack);
            continue;
        }
        let Some(label) = tracking_name(category) else {
            *truth.skipped.entry(category.to_string()).or_default() += 1;
            continue;
        };
        let velocity = truth_velocity(&a, &by_token, time_us);
        let sample = a.sample_token.clone();
        truth.boxes.entry(sample).or_default().push(TruthBox {
            id,
            label,
            category: category.to_string(),
            velocity,
            ann: a,
        });
    }
    Ok(Some(truth))
}

/// The class tables: instance token -> (index in `instance.json`, category token), and category
/// token -> name.
struct Classes {
    instances: HashMap<String, (usize, String)>,
    categories: HashMap<String, String>,
}

impl Classes {
    /// Reads `instance.json` and `category.json`, both needed with `ann_path`.
    fn read(meta: &Path, ann_path: &Path) -> Result<Classes> {
        for need in ["instance.json", "category.json"] {
            if !table(meta, need).is_file() {
                bail!(
                    "{} is present but {} is missing (needed to name the classes of the ground \
                     truth)",
                    ann_path.display(),
                    table(meta, need).display()
                );
            }
        }
        let instances: Vec<InstanceRow> = read_all(&table(meta, "instance.json"))?;
        let categories: HashMap<String, String> =
            read_all::<CategoryRow>(&table(meta, "category.json"))?
                .into_iter()
                .map(|c| (c.token, c.name))
                .collect();
        let instances = instances
            .into_iter()
            .enumerate()
            .map(|(i, r)| (r.token, (i, r.category_token)))
            .collect();
        Ok(Classes {
            instances,
            categories,
        })
    }

    /// The instance id (index + 1) and category name of an annotation.
    fn of(&self, meta: &Path, a: &AnnotationRow) -> Result<(u64, &str)> {
        let (idx, cat_tok) = self.instances.get(&a.instance_token).with_context(|| {
            format!(
                "{}: no instance {} (instance_token of sample_annotation {})",
                table(meta, "instance.json").display(),
                a.instance_token,
                a.token
            )
        })?;
        let category = self.categories.get(cat_tok).with_context(|| {
            format!(
                "{}: no category {cat_tok} (category_token of instance {})",
                table(meta, "category.json").display(),
                a.instance_token
            )
        })?;
        Ok((*idx as u64 + 1, category))
    }
}

/// Velocity of an annotation the way the devkit's `box_velocity` computes it (centre difference
/// of the previous and next annotations over their time difference, at most 1.5 s per side);
/// zero where it is undefined.
pub(crate) fn truth_velocity(
    ann: &AnnotationRow,
    anns: &HashMap<String, AnnotationRow>,
    time_us: &HashMap<String, u64>,
) -> [f64; 3] {
    let prev = anns.get(&ann.prev);
    let next = anns.get(&ann.next);
    if prev.is_none() && next.is_none() {
        return [0.0; 3];
    }
    let first = prev.unwrap_or(ann);
    let last = next.unwrap_or(ann);
    let (Some(&t0), Some(&t1)) = (
        time_us.get(&first.sample_token),
        time_us.get(&last.sample_token),
    ) else {
        return [0.0; 3];
    };
    let dt = (t1 as f64 - t0 as f64) * 1e-6;
    let max_dt = if prev.is_some() && next.is_some() {
        3.0
    } else {
        1.5
    };
    if dt <= 0.0 || dt > max_dt {
        return [0.0; 3];
    }
    let d = |i: usize| (last.translation[i] - first.translation[i]) / dt;
    [d(0), d(1), d(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn velocity_like_the_devkit() {
        let row = |tok: &str, s: &str, x: f64, prev: &str, next: &str| AnnotationRow {
            token: tok.into(),
            sample_token: s.into(),
            instance_token: "i".into(),
            translation: [x, 0.0, 0.0],
            size: [1.0; 3],
            rotation: [1.0, 0.0, 0.0, 0.0],
            prev: prev.into(),
            next: next.into(),
            num_lidar_pts: None,
            num_radar_pts: None,
        };
        let anns: HashMap<String, AnnotationRow> = [
            row("a", "s1", 0.0, "", "b"),
            row("b", "s2", 1.0, "a", "c"),
            row("c", "s3", 3.0, "b", ""),
            row("d", "s4", 9.0, "", ""),
        ]
        .into_iter()
        .map(|r| (r.token.clone(), r))
        .collect();
        let t: HashMap<String, u64> = [("s1", 0), ("s2", 500_000), ("s3", 1_000_000)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        assert_eq!(truth_velocity(&anns["a"], &anns, &t), [2.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["b"], &anns, &t), [3.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["c"], &anns, &t), [4.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["d"], &anns, &t), [0.0; 3]);
    }
}
