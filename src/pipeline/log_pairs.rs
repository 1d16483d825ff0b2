//! Which files make up a run over many logs: file, directory and glob arguments expanded to
//! files, and the truth and tracks files of each log paired (`probmot eval`).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use super::rosbag_dir::bag_mcap;

/// Expands files, directories (their `*.mcap`, sorted) and glob patterns (matches sorted; a
/// path that exists is taken as given even when it holds pattern characters).
pub fn expand(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for a in args {
        let text = a.to_string_lossy();
        if a.is_dir() {
            let mut files: Vec<PathBuf> = std::fs::read_dir(a)
                .with_context(|| format!("cannot list {}", a.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
                .collect();
            if files.is_empty() {
                // A bag directory says what it is (a sqlite3 bag: track it first).
                if a.join("metadata.yaml").is_file() {
                    bag_mcap(a)?;
                }
                bail!("{}: no .mcap file in this directory", a.display());
            }
            files.sort();
            out.extend(files);
        } else if !a.exists() && text.contains(['*', '?', '[']) {
            let mut files: Vec<PathBuf> = glob::glob(&text)
                .with_context(|| format!("bad pattern {text}"))?
                .filter_map(|p| p.ok())
                .collect();
            if files.is_empty() {
                bail!("{text}: the pattern matches no file");
            }
            files.sort();
            out.extend(files);
        } else {
            out.push(a.clone());
        }
    }
    Ok(out)
}

/// Refuses a list of logs that names one file twice (also through another path to it, e.g.
/// `a.mcap` and `./a.mcap`, or overlapping patterns): the log would count twice in the metrics
/// or statistics, and in a cross-validation could sit in a training and a held-out fold at
/// once. Paths that cannot be resolved are left to the read that fails on them.
pub fn refuse_repeats(files: &[PathBuf]) -> Result<()> {
    let mut seen: BTreeMap<PathBuf, &PathBuf> = BTreeMap::new();
    for f in files {
        let Ok(real) = std::fs::canonicalize(f) else {
            continue;
        };
        if let Some(first) = seen.insert(real, f) {
            bail!(
                "{} is the same file as {}, given before it: give each log once (it would \
                 count twice)",
                f.display(),
                first.display()
            );
        }
    }
    Ok(())
}

/// Expands the truth and tracks arguments ([`expand`]), refuses a file named twice in either
/// list ([`refuse_repeats`]) and pairs them ([`pair_logs`]).
pub fn log_pairs(truth: &[PathBuf], tracks: &[PathBuf]) -> Result<Vec<(PathBuf, PathBuf)>> {
    let truth = expand(truth)?;
    refuse_repeats(&truth)?;
    let tracks = if tracks.is_empty() {
        Vec::new()
    } else {
        expand(tracks)?
    };
    refuse_repeats(&tracks)?;
    pair_logs(&truth, &tracks)
}

/// Pairs truth and tracks files: each file with itself when `tracks` is empty, as given when
/// both are one file, else by file name (every file in exactly one pair), in truth order.
pub fn pair_logs(truth: &[PathBuf], tracks: &[PathBuf]) -> Result<Vec<(PathBuf, PathBuf)>> {
    if tracks.is_empty() {
        return Ok(truth.iter().map(|t| (t.clone(), t.clone())).collect());
    }
    if truth.len() == 1 && tracks.len() == 1 {
        return Ok(vec![(truth[0].clone(), tracks[0].clone())]);
    }
    let name_of = |p: &PathBuf| {
        p.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let mut by_name: BTreeMap<String, PathBuf> = BTreeMap::new();
    for t in tracks {
        let name = name_of(t);
        if by_name.insert(name.clone(), t.clone()).is_some() {
            bail!("two tracks files are named {name}; they cannot be paired by name");
        }
    }
    let mut pairs = Vec::new();
    for t in truth {
        let name = name_of(t);
        match by_name.remove(&name) {
            Some(tr) => pairs.push((t.clone(), tr)),
            None => bail!(
                "no tracks file named {name} for the truth file {}",
                t.display()
            ),
        }
    }
    if let Some(name) = by_name.keys().next() {
        bail!("tracks file {name} has no truth file of the same name");
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(v: &[&str]) -> Vec<PathBuf> {
        v.iter().map(PathBuf::from).collect()
    }

    #[test]
    fn no_tracks_pairs_each_file_with_itself() {
        let p = pair_logs(&paths(&["a/x.mcap", "a/y.mcap"]), &[]).unwrap();
        assert_eq!(
            p,
            [("a/x.mcap", "a/x.mcap"), ("a/y.mcap", "a/y.mcap")].map(|(a, b)| (a.into(), b.into()))
        );
    }

    #[test]
    fn one_and_one_pair_whatever_their_names() {
        let p = pair_logs(&paths(&["gt/x.mcap"]), &paths(&["out/other.mcap"])).unwrap();
        assert_eq!(p, vec![("gt/x.mcap".into(), "out/other.mcap".into())]);
    }

    #[test]
    fn many_pair_by_file_name_in_truth_order() {
        let truth = paths(&["gt/b.mcap", "gt/a.mcap"]);
        let tracks = paths(&["out/a.mcap", "out/b.mcap"]);
        let p = pair_logs(&truth, &tracks).unwrap();
        let want: Vec<(PathBuf, PathBuf)> = vec![
            ("gt/b.mcap".into(), "out/b.mcap".into()),
            ("gt/a.mcap".into(), "out/a.mcap".into()),
        ];
        assert_eq!(p, want);
    }

    #[test]
    fn unpaired_or_ambiguous_names_are_refused() {
        let err = |t: &[&str], r: &[&str]| pair_logs(&paths(t), &paths(r)).unwrap_err().to_string();
        let e = err(&["gt/a.mcap", "gt/b.mcap"], &["out/a.mcap", "out/c.mcap"]);
        assert_eq!(
            e,
            "no tracks file named b.mcap for the truth file gt/b.mcap"
        );
        let e = err(&["gt/a.mcap", "gt/b.mcap"], &["x/a.mcap", "y/a.mcap"]);
        assert_eq!(
            e,
            "two tracks files are named a.mcap; they cannot be paired by name"
        );
        let e = err(&["gt/a.mcap"], &["out/a.mcap", "out/z.mcap"]);
        assert_eq!(e, "tracks file z.mcap has no truth file of the same name");
    }

    #[test]
    fn expand_lists_directories_and_globs_sorted() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["b.mcap", "a.mcap", "notes.txt"] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        let d = dir.path().to_path_buf();
        let want = vec![d.join("a.mcap"), d.join("b.mcap")];
        assert_eq!(expand(std::slice::from_ref(&d)).unwrap(), want);
        assert_eq!(expand(&[d.join("*.mcap")]).unwrap(), want);
        // A missing plain file is kept (its reader reports it); an empty match is an error.
        assert_eq!(expand(&[d.join("c.mcap")]).unwrap(), vec![d.join("c.mcap")]);
        let e = expand(&[d.join("*.bag")]).unwrap_err().to_string();
        assert!(e.ends_with("the pattern matches no file"), "{e}");
    }
}
