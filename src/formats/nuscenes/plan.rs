//! The scenes an import writes: which scenes, each scene's sample chain (checked against the
//! tables) and its output file. Export uses the same sample chains.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::mcapio::writer::check_output_path;

use super::tables::{SampleRow, SceneRow};

/// One scene to write.
pub(crate) struct ScenePlan {
    pub(crate) scene: SceneRow,
    /// `(sample token, timestamp µs)` in time order.
    pub(crate) samples: Vec<(String, u64)>,
    pub(crate) output: PathBuf,
}

/// The output file name of a scene: characters outside `[A-Za-z0-9._-]` become `_`.
pub(crate) fn file_name_of(scene: &str) -> String {
    let s: String = scene
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{s}.mcap")
}

/// The path of table `name` (e.g. `sample.json`) in the tables directory.
pub(crate) fn table(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

/// Walks a scene's sample chain, checking it against the tables.
pub(crate) fn scene_samples(
    meta: &Path,
    scene: &SceneRow,
    samples: &HashMap<String, SampleRow>,
) -> Result<Vec<(String, u64)>> {
    let sample_json = table(meta, "sample.json");
    let mut out: Vec<(String, u64)> = Vec::new();
    let mut token = scene.first_sample_token.clone();
    let mut prev_token = String::new();
    while !token.is_empty() {
        let s = samples.get(&token).with_context(|| {
            if prev_token.is_empty() {
                format!(
                    "{}: no sample {token} (first_sample_token of scene {} {})",
                    sample_json.display(),
                    scene.name,
                    scene.token
                )
            } else {
                format!(
                    "{}: no sample {token} (next of sample {prev_token} in scene {})",
                    sample_json.display(),
                    scene.name
                )
            }
        })?;
        if s.scene_token != scene.token {
            bail!(
                "{}: sample {token} is in the chain of scene {} ({}) but has scene_token {}",
                sample_json.display(),
                scene.name,
                scene.token,
                s.scene_token
            );
        }
        if let Some(&(_, t_prev)) = out.last() {
            if s.timestamp <= t_prev {
                bail!(
                    "{}: sample {token} (timestamp {}) does not come after sample {prev_token} \
                     (timestamp {t_prev}) in scene {}",
                    sample_json.display(),
                    s.timestamp,
                    scene.name
                );
            }
        }
        if out.len() > samples.len() {
            bail!(
                "{}: the sample chain of scene {} loops",
                sample_json.display(),
                scene.name
            );
        }
        out.push((token.clone(), s.timestamp));
        prev_token = std::mem::replace(&mut token, s.next.clone());
    }
    check_chain_end(meta, scene, &prev_token, out.len())?;
    Ok(out)
}

/// The scene's `last_sample_token` and `nbr_samples`, when given, match its sample chain.
fn check_chain_end(
    meta: &Path,
    scene: &SceneRow,
    last_token: &str,
    n_samples: usize,
) -> Result<()> {
    if let Some(last) = &scene.last_sample_token {
        if *last != last_token {
            bail!(
                "{}: scene {} ({}) has last_sample_token {last}, but its sample chain ends at {}",
                table(meta, "scene.json").display(),
                scene.name,
                scene.token,
                last_token
            );
        }
    }
    if let Some(n) = scene.nbr_samples {
        if n != n_samples as u64 {
            bail!(
                "{}: scene {} ({}) has nbr_samples {n}, but its sample chain holds {} samples",
                table(meta, "scene.json").display(),
                scene.name,
                scene.token,
                n_samples
            );
        }
    }
    Ok(())
}

/// The scenes to write: the named ones (each once, in the order given), or when none is named
/// every scene holding a sample of the results, in `scene.json` order. `results_file` names the
/// results in the error when they hold no sample.
pub(crate) fn choose_scenes<'a>(
    meta: &Path,
    scenes: &'a [SceneRow],
    names: &[String],
    with_results: &HashSet<&str>,
    results_file: &str,
) -> Result<Vec<&'a SceneRow>> {
    if names.is_empty() {
        let v: Vec<&SceneRow> = scenes
            .iter()
            .filter(|s| with_results.contains(s.token.as_str()))
            .collect();
        if v.is_empty() {
            bail!("{results_file}: the results hold no sample");
        }
        return Ok(v);
    }
    let mut v: Vec<&SceneRow> = Vec::new();
    for name in names {
        let s = scenes.iter().find(|s| s.name == *name).with_context(|| {
            format!(
                "no scene named {name} in {}",
                table(meta, "scene.json").display()
            )
        })?;
        if !v.iter().any(|x| x.token == s.token) {
            v.push(s);
        }
    }
    Ok(v)
}

/// The plan of each chosen scene: its checked sample chain and its output file in `out_dir`
/// (two scenes may not share one; an existing file is checked by `check_output_path`).
pub(crate) fn plan_scenes(
    meta: &Path,
    chosen: &[&SceneRow],
    samples: &HashMap<String, SampleRow>,
    out_dir: &Path,
) -> Result<Vec<ScenePlan>> {
    let mut plans: Vec<ScenePlan> = Vec::new();
    let mut outputs: HashSet<PathBuf> = HashSet::new();
    for scene in chosen {
        let list = scene_samples(meta, scene, samples)?;
        let output = out_dir.join(file_name_of(&scene.name));
        if !outputs.insert(output.clone()) {
            bail!(
                "two scenes would both be written to {} (scene names must be unique)",
                output.display()
            );
        }
        check_output_path(None, &output)?;
        plans.push(ScenePlan {
            scene: (*scene).clone(),
            samples: list,
            output,
        });
    }
    Ok(plans)
}
