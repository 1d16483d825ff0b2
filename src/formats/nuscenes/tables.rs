//! The dataset's metadata tables (`sample.json`, `scene.json`, ...): rows and streaming readers.

use std::fmt;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use anyhow::{Context, Result};
use serde::de::{DeserializeOwned, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};

// ---------------------------------------------------------------------------------------------
// Tables

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct SampleRow {
    pub(crate) token: String,
    pub(crate) timestamp: u64,
    pub(crate) scene_token: String,
    #[serde(default)]
    pub(crate) next: String,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct SceneRow {
    pub(crate) token: String,
    pub(crate) name: String,
    #[serde(default)]
    pub(crate) description: String,
    pub(crate) nbr_samples: Option<u64>,
    pub(crate) first_sample_token: String,
    pub(crate) last_sample_token: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct AnnotationRow {
    pub(crate) token: String,
    pub(crate) sample_token: String,
    pub(crate) instance_token: String,
    pub(crate) translation: [f64; 3],
    pub(crate) size: [f64; 3],
    pub(crate) rotation: [f64; 4],
    #[serde(default)]
    pub(crate) prev: String,
    #[serde(default)]
    pub(crate) next: String,
    pub(crate) num_lidar_pts: Option<i64>,
    pub(crate) num_radar_pts: Option<i64>,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct InstanceRow {
    pub(crate) token: String,
    pub(crate) category_token: String,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct CategoryRow {
    pub(crate) token: String,
    pub(crate) name: String,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct SampleDataRow {
    pub(crate) token: String,
    pub(crate) sample_token: String,
    pub(crate) ego_pose_token: String,
    #[serde(default)]
    pub(crate) calibrated_sensor_token: String,
    #[serde(default)]
    pub(crate) filename: String,
    #[serde(default)]
    pub(crate) is_key_frame: bool,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct EgoPoseRow {
    pub(crate) token: String,
    pub(crate) translation: [f64; 3],
    pub(crate) rotation: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct CalibratedSensorRow {
    pub(crate) token: String,
    pub(crate) sensor_token: String,
}

#[derive(Debug, Clone, Deserialize)]
pub(crate) struct SensorRow {
    pub(crate) token: String,
    pub(crate) channel: String,
}

/// Visits a JSON array, keeping the records `keep` accepts (big tables are never held whole).
pub(crate) struct FilterSeq<'a, T, F> {
    pub(crate) keep: &'a mut F,
    pub(crate) out: &'a mut Vec<T>,
}

impl<'de, T, F> Visitor<'de> for FilterSeq<'_, T, F>
where
    T: Deserialize<'de>,
    F: FnMut(&T) -> bool,
{
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON array of records")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(row) = seq.next_element::<T>()? {
            if (self.keep)(&row) {
                self.out.push(row);
            }
        }
        Ok(())
    }
}

/// Reads a nuScenes table (a JSON array of records), keeping the records `keep` accepts.
pub(crate) fn read_table<T, F>(path: &Path, mut keep: F) -> Result<Vec<T>>
where
    T: DeserializeOwned,
    F: FnMut(&T) -> bool,
{
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut de = serde_json::Deserializer::from_reader(BufReader::with_capacity(1 << 20, file));
    let mut out = Vec::new();
    de.deserialize_seq(FilterSeq {
        keep: &mut keep,
        out: &mut out,
    })
    .and_then(|()| de.end())
    .with_context(|| format!("{}: not a readable nuScenes table", path.display()))?;
    Ok(out)
}

pub(crate) fn read_all<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    read_table(path, |_: &T| true)
}
