//! Detection results files (the nuScenes detection submission format), read compactly.

use std::collections::HashMap;
use std::fmt;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::de::{DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};

// ---------------------------------------------------------------------------------------------
// Detection results

/// One detection box of the results file, compact (tokens and names interned).
#[derive(Debug, Clone)]
pub(crate) struct DetBox {
    pub(crate) translation: [f64; 3],
    pub(crate) size: [f64; 3],
    pub(crate) rotation: [f64; 4],
    pub(crate) velocity: [f64; 2],
    pub(crate) score: f64,
    pub(crate) name: u32,
    pub(crate) attribute: u32,
}

#[derive(Debug, Deserialize)]
pub(crate) struct RawDetBox {
    pub(crate) sample_token: String,
    pub(crate) translation: [f64; 3],
    pub(crate) size: [f64; 3],
    pub(crate) rotation: [f64; 4],
    pub(crate) velocity: Option<[f64; 2]>,
    pub(crate) detection_name: String,
    pub(crate) detection_score: f64,
    #[serde(default)]
    pub(crate) attribute_name: String,
}

#[derive(Debug, Default)]
pub(crate) struct Interner {
    pub(crate) names: Vec<String>,
    pub(crate) index: HashMap<String, u32>,
}

impl Interner {
    fn get(&mut self, s: String) -> u32 {
        if let Some(&i) = self.index.get(&s) {
            return i;
        }
        let i = self.names.len() as u32;
        self.names.push(s.clone());
        self.index.insert(s, i);
        i
    }
}

/// The results file: boxes per sample token (a key with an empty list is kept).
#[derive(Debug, Default)]
pub(crate) struct DetectionResults {
    pub(crate) meta: Option<serde_json::Value>,
    pub(crate) boxes: HashMap<String, Vec<DetBox>>,
    pub(crate) strings: Interner,
    /// A box whose `sample_token` differs from its key: `(key, box token)`.
    pub(crate) mismatch: Option<(String, String)>,
}

pub(crate) struct ResultsVisitor<'a>(&'a mut DetectionResults);

impl<'de> Visitor<'de> for ResultsVisitor<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(r#"an object {"meta": {...}, "results": {sample_token: [box, ...]}}"#)
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen_results = false;
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "meta" => self.0.meta = Some(map.next_value()?),
                "results" => {
                    map.next_value_seed(SamplesSeed(&mut *self.0))?;
                    seen_results = true;
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        if !seen_results {
            return Err(serde::de::Error::missing_field("results"));
        }
        Ok(())
    }
}

pub(crate) struct SamplesSeed<'a>(&'a mut DetectionResults);

impl<'de> DeserializeSeed<'de> for SamplesSeed<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for SamplesSeed<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an object {sample_token: [box, ...]}")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(token) = map.next_key::<String>()? {
            let mut boxes = Vec::new();
            map.next_value_seed(BoxesSeed {
                key: &token,
                res: &mut *self.0,
                out: &mut boxes,
            })?;
            self.0.boxes.entry(token).or_default().extend(boxes);
        }
        Ok(())
    }
}

pub(crate) struct BoxesSeed<'a> {
    pub(crate) key: &'a str,
    pub(crate) res: &'a mut DetectionResults,
    pub(crate) out: &'a mut Vec<DetBox>,
}

impl<'de> DeserializeSeed<'de> for BoxesSeed<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for BoxesSeed<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a list of detection boxes")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(b) = seq.next_element::<RawDetBox>()? {
            if b.sample_token != self.key && self.res.mismatch.is_none() {
                self.res.mismatch = Some((self.key.to_string(), b.sample_token.clone()));
            }
            let name = self.res.strings.get(b.detection_name);
            let attribute = self.res.strings.get(b.attribute_name);
            self.out.push(DetBox {
                translation: b.translation,
                size: b.size,
                rotation: b.rotation,
                velocity: b.velocity.unwrap_or([0.0, 0.0]),
                score: b.detection_score,
                name,
                attribute,
            });
        }
        Ok(())
    }
}

pub(crate) fn read_results(path: &Path) -> Result<DetectionResults> {
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut de = serde_json::Deserializer::from_reader(BufReader::with_capacity(1 << 20, file));
    let mut res = DetectionResults::default();
    de.deserialize_map(ResultsVisitor(&mut res))
        .and_then(|()| de.end())
        .with_context(|| {
            format!(
                "{}: not a nuScenes detection results file (JSON {{\"meta\": ..., \"results\": \
                 {{sample_token: [box, ...]}}}}; NaN and Infinity are not JSON)",
                path.display()
            )
        })?;
    if let Some((key, tok)) = &res.mismatch {
        bail!(
            "{}: results[{key}] holds a box whose sample_token is {tok}",
            path.display()
        );
    }
    Ok(res)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_results_and_refuses_a_wrong_sample_token() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.json");
        std::fs::write(
            &p,
            r#"{"results": {"s1": [{"sample_token": "s1", "translation": [1, 2, 3],
                "size": [1, 2, 3], "rotation": [1, 0, 0, 0], "velocity": [0, 0],
                "detection_name": "car", "detection_score": 0.5, "attribute_name": ""}],
                "s2": []}, "meta": {"use_lidar": true}, "extra": [1]}"#,
        )
        .unwrap();
        let r = read_results(&p).unwrap();
        assert_eq!(r.boxes.len(), 2);
        assert_eq!(r.boxes["s1"].len(), 1);
        assert!(r.boxes["s2"].is_empty());
        assert_eq!(r.strings.names[r.boxes["s1"][0].name as usize], "car");
        std::fs::write(
            &p,
            r#"{"results": {"s1": [{"sample_token": "s9", "translation": [1, 2, 3],
                "size": [1, 2, 3], "rotation": [1, 0, 0, 0], "velocity": [0, 0],
                "detection_name": "car", "detection_score": 0.5}]}}"#,
        )
        .unwrap();
        let e = format!("{:#}", read_results(&p).unwrap_err());
        assert!(e.contains("results[s1]") && e.contains("s9"), "{e}");
        std::fs::write(&p, r#"{"meta": {}}"#).unwrap();
        let e = format!("{:#}", read_results(&p).unwrap_err());
        assert!(e.contains("results"), "{e}");
    }
}
