//! The ego poses of an import: the `ego_pose` of each sample's LIDAR_TOP key frame.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use anyhow::{bail, Context, Result};

use super::plan::table;
use super::tables::{
    read_all, read_table, CalibratedSensorRow, EgoPoseRow, SampleDataRow, SensorRow,
};

/// Reads the ego pose of every sample in `wanted`, or `None` when `sample_data.json` and
/// `ego_pose.json` are not both present (a warning in `warnings` when only one is).
pub(crate) fn read_ego_poses(
    meta: &Path,
    wanted: &HashSet<&str>,
    warnings: &mut Vec<String>,
) -> Result<Option<HashMap<String, EgoPoseRow>>> {
    let sd_path = table(meta, "sample_data.json");
    let ep_path = table(meta, "ego_pose.json");
    match (sd_path.is_file(), ep_path.is_file()) {
        (true, true) => {}
        (true, false) => {
            warnings.push(missing_warning(&sd_path, &ep_path));
            return Ok(None);
        }
        (false, true) => {
            warnings.push(missing_warning(&ep_path, &sd_path));
            return Ok(None);
        }
        (false, false) => return Ok(None),
    }
    let lidar_of = lidar_key_frames(meta, &sd_path, wanted)?;
    let needed: HashSet<&str> = lidar_of
        .values()
        .map(|r| r.ego_pose_token.as_str())
        .collect();
    let poses: HashMap<String, EgoPoseRow> =
        read_table(&ep_path, |p: &EgoPoseRow| needed.contains(p.token.as_str()))?
            .into_iter()
            .map(|p| (p.token.clone(), p))
            .collect();
    let mut wanted_sorted: Vec<&str> = wanted.iter().copied().collect();
    wanted_sorted.sort();
    let mut ego: HashMap<String, EgoPoseRow> = HashMap::new();
    for tok in wanted_sorted {
        let sd = lidar_of.get(tok).with_context(|| {
            format!(
                "{}: no LIDAR_TOP key frame for sample {tok}",
                sd_path.display()
            )
        })?;
        let pose = poses.get(&sd.ego_pose_token).with_context(|| {
            format!(
                "{}: no ego pose {} (ego_pose_token of sample_data {})",
                ep_path.display(),
                sd.ego_pose_token,
                sd.token
            )
        })?;
        ego.insert(tok.to_string(), pose.clone());
    }
    Ok(Some(ego))
}

/// The warning when table `present` is there without table `missing`.
fn missing_warning(present: &Path, missing: &Path) -> String {
    format!(
        "{} needs {}; no /ego_pose channel written",
        present.display(),
        missing.display()
    )
}

/// The LIDAR_TOP key frame of each sample in `wanted`, by sample token. The channel of a
/// sample_data record comes from calibrated_sensor -> sensor when those tables exist, else from
/// the file name (`samples/LIDAR_TOP/...`).
fn lidar_key_frames(
    meta: &Path,
    sd_path: &Path,
    wanted: &HashSet<&str>,
) -> Result<HashMap<String, SampleDataRow>> {
    let cs_path = table(meta, "calibrated_sensor.json");
    let sensor_path = table(meta, "sensor.json");
    let lidar_cs: Option<HashSet<String>> = if cs_path.is_file() && sensor_path.is_file() {
        let lidar: HashSet<String> = read_all::<SensorRow>(&sensor_path)?
            .into_iter()
            .filter(|s| s.channel == "LIDAR_TOP")
            .map(|s| s.token)
            .collect();
        Some(
            read_all::<CalibratedSensorRow>(&cs_path)?
                .into_iter()
                .filter(|c| lidar.contains(&c.sensor_token))
                .map(|c| c.token)
                .collect(),
        )
    } else {
        None
    };
    let sd: Vec<SampleDataRow> = read_table(sd_path, |r: &SampleDataRow| {
        r.is_key_frame
            && wanted.contains(r.sample_token.as_str())
            && match &lidar_cs {
                Some(set) => set.contains(&r.calibrated_sensor_token),
                None => r.filename.starts_with("samples/LIDAR_TOP/"),
            }
    })?;
    let mut lidar_of: HashMap<String, SampleDataRow> = HashMap::new();
    for r in sd {
        if let Some(prev) = lidar_of.get(&r.sample_token) {
            bail!(
                "{}: sample {} has two LIDAR_TOP key frames ({} and {})",
                sd_path.display(),
                r.sample_token,
                prev.token,
                r.token
            );
        }
        lidar_of.insert(r.sample_token.clone(), r);
    }
    Ok(lidar_of)
}
