//! Tracking many files in one run (`probmot track --out-dir`): each input's output in the
//! output directory, checked before any work, and the files processed in parallel with one
//! result per file (a failed file does not stop the others).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{bail, Context, Result};
use rayon::prelude::*;

use super::bag_track::track_path;
use super::progress::no_progress;
use super::rosbag_dir::{check_output_dir, open_bag};
use super::track::{TrackOptions, TrackSummary};
use crate::mcapio::destination::resolved_file;
use crate::mcapio::writer::{check_output_path, refuse_outputs_onto_inputs};

/// The output of `input` in `dir`: the same file name (`NAME.mcap` for a sqlite3 file
/// `NAME.db3`, whose output is MCAP).
pub fn output_in(dir: &Path, input: &Path) -> Result<PathBuf> {
    let name = input
        .file_name()
        .with_context(|| format!("{} has no file name", input.display()))?;
    if let Some(stem) = name.to_str().and_then(|n| n.strip_suffix(".db3")) {
        if input.is_file() {
            return Ok(dir.join(format!("{stem}.mcap")));
        }
    }
    Ok(dir.join(name))
}

/// The outputs of `inputs` in `dir` (created when missing), each checked with
/// [`check_output_path`] (a rosbag2 bag directory is one input, its output a new bag directory
/// of the same name); refuses two inputs of the same name, and folders that are no bag.
pub fn out_dir_outputs(dir: &Path, inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    for i in inputs.iter().filter(|i| i.is_dir()) {
        // A folder that is no bag gets the bag reader's words (name its files instead).
        open_bag(i)?;
        check_output_dir(&output_in(dir, i)?)?;
    }
    if dir.exists() && !dir.is_dir() {
        bail!("--out-dir {} exists and is not a directory", dir.display());
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output directory {}", dir.display()))?;
    let mut outputs = Vec::new();
    let mut files = std::collections::HashSet::new();
    for i in inputs {
        let o = output_in(dir, i)?;
        // By the file the bytes go to: a link in the folder may lead to another output.
        let file = resolved_file(&o)?.unwrap_or_else(|| o.clone());
        if outputs.contains(&o) || !files.insert(file) {
            bail!("two inputs would both be written to {}", o.display());
        }
        if !i.is_dir() {
            check_output_path(Some(i), &o)?;
        }
        outputs.push(o);
    }
    let files = |v: &[PathBuf]| -> Vec<PathBuf> {
        let pairs = inputs.iter().zip(v).filter(|(i, _)| !i.is_dir());
        pairs.map(|(_, p)| p.clone()).collect()
    };
    refuse_outputs_onto_inputs(&files(&outputs), &files(inputs))?;
    Ok(outputs)
}

/// Runs `job(input, output)` for every pair on `jobs` threads: one result per input, in input
/// order. `on_done(failed)` is called after each file with the number of failures so far.
pub fn run_many<T: Send>(
    inputs: &[PathBuf],
    outputs: &[PathBuf],
    jobs: usize,
    job: &(dyn Fn(&Path, &Path) -> Result<T> + Sync),
    on_done: &(dyn Fn(usize) + Sync),
) -> Result<Vec<Result<T>>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .context("starting the worker threads")?;
    let failed = AtomicUsize::new(0);
    Ok(pool.install(|| {
        inputs
            .par_iter()
            .zip(outputs)
            .map(|(input, output)| {
                let r = job(input, output);
                if r.is_err() {
                    failed.fetch_add(1, Ordering::Relaxed);
                }
                on_done(failed.load(Ordering::Relaxed));
                r
            })
            .collect()
    }))
}

/// Checks every output path of `track` before any work (`-o OUT` for one input, or `--out-dir
/// DIR`, created when missing); returns the `--out-dir` outputs (empty with `-o`).
pub fn check_track_outputs(
    inputs: &[PathBuf],
    output: Option<&Path>,
    out_dir: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    match (output, out_dir) {
        (None, Some(dir)) => out_dir_outputs(dir, inputs),
        (Some(out), None) => {
            if inputs.len() != 1 {
                bail!("-o takes one input; use --out-dir DIR for several inputs");
            }
            // A bag directory's output is a new bag directory, checked by track_bag.
            if !inputs[0].is_dir() {
                check_output_path(Some(&inputs[0]), out)?;
            }
            Ok(Vec::new())
        }
        _ => bail!("give an output: -o OUT.mcap (one input) or --out-dir DIR"),
    }
}

/// The outcome of [`track_many`] per input, as `track --out-dir` reports it.
pub struct ManyReport<'a> {
    /// The inputs, in the order of `results`.
    pub inputs: &'a [PathBuf],
    /// One result per input.
    pub results: &'a [Result<TrackSummary>],
}

impl ManyReport<'_> {
    /// Number of inputs that failed.
    pub fn failed(&self) -> usize {
        self.results.iter().filter(|r| r.is_err()).count()
    }

    /// One JSON object per input: `{input, ok: true, summary}` or `{input, ok: false, error}`.
    pub fn json(&self) -> serde_json::Value {
        let one = |(input, r): (&PathBuf, &Result<TrackSummary>)| match r {
            Ok(s) => serde_json::json!({"input": input, "ok": true, "summary": s}),
            Err(e) => serde_json::json!({"input": input, "ok": false, "error": format!("{e:#}")}),
        };
        serde_json::Value::Array(self.inputs.iter().zip(self.results).map(one).collect())
    }

    /// The closing line: `N files: a tracked, b failed`.
    pub fn totals_line(&self) -> String {
        let n = self.inputs.len();
        let failed = self.failed();
        format!("{n} files: {} tracked, {failed} failed", n - failed)
    }
}

/// Tracks every input into its output ([`track_path`]: a file, or a bag directory as one
/// drive; without per-file progress) on `jobs`
/// threads; see [`run_many`].
pub fn track_many(
    inputs: &[PathBuf],
    outputs: &[PathBuf],
    opts: &TrackOptions,
    jobs: usize,
    on_done: &(dyn Fn(usize) + Sync),
) -> Result<Vec<Result<TrackSummary>>> {
    let job = |input: &Path, output: &Path| track_path(input, output, opts, &no_progress);
    run_many(inputs, outputs, jobs, &job, on_done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn every_file_gets_its_result_in_input_order_and_failures_are_counted() {
        let inputs: Vec<PathBuf> = (0..7)
            .map(|i| PathBuf::from(format!("in/{i}.mcap")))
            .collect();
        let outputs: Vec<PathBuf> = (0..7)
            .map(|i| PathBuf::from(format!("out/{i}.mcap")))
            .collect();
        let job = |i: &Path, o: &Path| -> Result<String> {
            let n: u32 = i.file_stem().unwrap().to_str().unwrap().parse()?;
            if n % 3 == 1 {
                bail!("file {n} fails");
            }
            Ok(format!("{} -> {}", i.display(), o.display()))
        };
        let seen = Mutex::new(Vec::new());
        let r = run_many(&inputs, &outputs, 3, &job, &|f| {
            seen.lock().unwrap().push(f)
        })
        .unwrap();
        assert_eq!(r.len(), 7);
        for (k, r) in r.iter().enumerate() {
            match r {
                Ok(s) => assert_eq!(*s, format!("in/{k}.mcap -> out/{k}.mcap")),
                Err(e) => {
                    assert_eq!(k % 3, 1);
                    assert_eq!(e.to_string(), format!("file {k} fails"));
                }
            }
        }
        let mut seen = seen.into_inner().unwrap();
        seen.sort();
        // One call per file; the failure count never falls and ends at the 2 failures.
        assert_eq!(seen.len(), 7);
        assert_eq!(seen.last(), Some(&2));
    }

    #[test]
    fn out_dir_outputs_keep_names_and_refuse_clashes() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/sub");
        let inputs = vec![PathBuf::from("a/x.mcap"), PathBuf::from("b/y.mcap")];
        let o = out_dir_outputs(&out, &inputs).unwrap();
        assert_eq!(o, vec![out.join("x.mcap"), out.join("y.mcap")]);
        assert!(out.is_dir(), "created");
        let clash = vec![PathBuf::from("a/x.mcap"), PathBuf::from("b/x.mcap")];
        let e = out_dir_outputs(&out, &clash).unwrap_err().to_string();
        assert!(e.starts_with("two inputs would both be written to"), "{e}");
        assert!(e.ends_with("x.mcap"), "{e}");
        let folder = dir.path().join("logs");
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("a.mcap"), b"").unwrap();
        let e = out_dir_outputs(&out, std::slice::from_ref(&folder))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("but no metadata.yaml, not named as rosbag2 names a bag's files"),
            "{e}"
        );
        std::fs::write(folder.join("metadata.yaml"), b"").unwrap();
        let bag_out = out_dir_outputs(&out, std::slice::from_ref(&folder)).unwrap();
        assert_eq!(bag_out, [out.join("logs")], "a bag is one input");
        std::fs::create_dir(out.join("logs")).unwrap();
        std::fs::write(out.join("logs/x"), b"").unwrap();
        let e = out_dir_outputs(&out, &[folder]).unwrap_err().to_string();
        assert!(e.contains("exists"), "{e}");
        let file = dir.path().join("file");
        std::fs::write(&file, b"").unwrap();
        let e = out_dir_outputs(&file, &inputs).unwrap_err().to_string();
        assert!(e.contains("exists and is not a directory"), "{e}");
    }

    /// An output that is a link to another input is refused: writing through the link would
    /// replace that input.
    #[cfg(unix)]
    #[test]
    fn out_dir_outputs_refuse_a_link_to_another_input() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("in")).unwrap();
        std::fs::create_dir_all(d.join("out")).unwrap();
        for n in ["x.mcap", "y.mcap"] {
            std::fs::write(d.join("in").join(n), b"input").unwrap();
        }
        std::os::unix::fs::symlink(d.join("in/y.mcap"), d.join("out/x.mcap")).unwrap();
        let inputs = vec![d.join("in/x.mcap"), d.join("in/y.mcap")];
        let e = out_dir_outputs(&d.join("out"), &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("is the input") && e.contains("y.mcap"), "{e}");
        // A link in the folder leading to another output: both would write one file.
        std::fs::remove_file(d.join("out/x.mcap")).unwrap();
        std::os::unix::fs::symlink("y.mcap", d.join("out/x.mcap")).unwrap();
        let e = out_dir_outputs(&d.join("out"), &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("two inputs would both be written to"), "{e}");
    }
}
