//! Every shell example of README.md and docs/*.md runs: each fenced ```sh block is run with bash
//! (`set -euo pipefail`) against the binary under test, in a temporary directory per document
//! (blocks of one document run in order there, so a later block may use an earlier one's
//! output). The directory holds links to `sample_logs/` and `scripts/` of the repository, as a
//! checkout's root does: the examples name real files, no placeholder. They write into `out/`
//! (ignored by git), and the test fails when a document's examples leave anything else there or
//! add a file to `sample_logs/` or `scripts/`, so running them from a checkout leaves no
//! untracked file.
//!
//! A block that cannot run here (a Ray cluster, the `rerun` feature build, dataset files) has the
//! line `<!-- not run in CI: REASON -->` right before its fence; the reason is required.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{self, repo};

const MARKER: &str = "<!-- not run in CI:";

/// One ```sh block: its first line number, its text, and the reason it is not run.
struct Block {
    line: usize,
    text: String,
    skip: Option<String>,
    /// Indentation of the fence (a block inside a list item); removed from each line, the rest of
    /// a line's indentation is kept (a here-document or `python3 -c` needs it).
    indent: usize,
}

/// The ```sh blocks of a Markdown text. Panics on a shell block in another fence language, so
/// none escapes the test.
fn blocks(doc: &str, name: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut current: Option<Block> = None;
    let mut previous = "";
    for (i, line) in doc.lines().enumerate() {
        let t = line.trim();
        if let Some(b) = current.as_mut() {
            if t == "```" {
                out.push(current.take().unwrap());
            } else {
                let lead = line.len() - line.trim_start().len();
                b.text.push_str(&line[lead.min(b.indent)..]);
                b.text.push('\n');
            }
            continue;
        }
        if let Some(lang) = t.strip_prefix("```") {
            assert!(
                !["bash", "shell", "console", "zsh"].contains(&lang),
                "{name}:{}: use ```sh for shell examples",
                i + 1
            );
            if lang == "sh" {
                let skip = previous.strip_prefix(MARKER).map(|r| {
                    let reason = r.trim_end_matches("-->").trim().to_string();
                    assert!(
                        !reason.is_empty(),
                        "{name}:{}: marker without reason",
                        i + 1
                    );
                    reason
                });
                current = Some(Block {
                    line: i + 1,
                    text: String::new(),
                    skip,
                    indent: line.len() - line.trim_start().len(),
                });
            }
        }
        if !t.is_empty() {
            previous = t;
        }
    }
    assert!(current.is_none(), "{name}: unclosed ```sh block");
    out
}

/// README.md and docs/*.md.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![repo("README.md")];
    let mut pages: Vec<PathBuf> = std::fs::read_dir(repo("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    pages.sort();
    docs.extend(pages);
    docs
}

/// The repository's folders the examples read, linked into their directory.
const LINKED: [&str; 2] = ["sample_logs", "scripts"];

/// The folder the examples write into (`/out/` in `.gitignore`).
const OUT: &str = "out";

/// A working directory like a checkout's root, for what the examples read.
fn workdir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for l in LINKED {
        std::os::unix::fs::symlink(repo(l), dir.path().join(l)).unwrap();
    }
    dir
}

/// The names in a directory, sorted; Python's `__pycache__` (ignored by git) left out.
fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "__pycache__")
        .collect();
    n.sort();
    n
}

/// The linked folders' listings, to see that no example wrote into the repository.
fn linked_listings() -> Vec<Vec<String>> {
    LINKED.iter().map(|l| names(&repo(l))).collect()
}

/// Panics when a document's examples left something outside `out/` (a file a user running them
/// from the checkout would find untracked).
fn assert_only_out(dir: &Path, name: &str, before: &[Vec<String>]) {
    let stray: Vec<String> = names(dir)
        .into_iter()
        .filter(|n| n != OUT && !LINKED.contains(&n.as_str()))
        .collect();
    assert!(
        stray.is_empty(),
        "{name}: the examples wrote {stray:?} outside {OUT}/ (write into {OUT}/, which git ignores)"
    );
    assert_eq!(
        linked_listings(),
        before,
        "{name}: the examples added or removed a file in {LINKED:?} of the repository"
    );
}

/// Runs one example; `false` when it could not run because a Python package is missing (a skip:
/// outside CI it says so, under CI it fails).
fn run_block(dir: &Path, name: &str, b: &Block) -> bool {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_probmot")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = Command::new("bash")
        .args(["-c", &format!("set -euo pipefail\n{}", b.text)])
        .current_dir(dir)
        .env("PATH", path)
        .output()
        .expect("run bash");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        if let Some(missing) = stderr.lines().find(|l| l.contains("No module named")) {
            common::skip(
                &format!("doc example {name}:{}", b.line),
                &format!("a Python package is missing: {missing}"),
            );
            return false;
        }
    }
    assert!(
        out.status.success(),
        "{name}:{}: the example failed ({}):\n{}\nstdout:\n{}\nstderr:\n{}",
        b.line,
        out.status,
        b.text,
        String::from_utf8_lossy(&out.stdout),
        stderr
    );
    true
}

#[test]
fn every_shell_example_of_the_docs_runs() {
    use std::io::Write as _;
    let (mut ran, mut not_run) = (0, Vec::new());
    for doc in documents() {
        let name = doc.strip_prefix(repo("")).unwrap().display().to_string();
        let text = std::fs::read_to_string(&doc).unwrap();
        let dir = workdir();
        let before = linked_listings();
        for b in blocks(&text, &name) {
            match &b.skip {
                Some(reason) => not_run.push(format!("{name}:{}: {reason}", b.line)),
                None => {
                    if !run_block(dir.path(), &name, &b) {
                        // Later examples of the page may use what this one makes.
                        break;
                    }
                    ran += 1;
                }
            }
        }
        assert_only_out(dir.path(), &name, &before);
    }
    assert!(ran >= 8, "only {ran} examples ran");
    // Straight to stderr, past libtest's capture: which examples are documented as not run.
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "doc examples: {ran} ran, {} marked not run:",
        not_run.len()
    );
    for n in &not_run {
        let _ = writeln!(err, "  {n}");
    }
}

#[test]
fn markers_and_blocks_are_parsed() {
    let doc = "text\n\n<!-- not run in CI: needs a cluster -->\n```sh\na \\\n  b\n```\n\n```sh\nc\n```\n```rust\nx\n```\n";
    let b = blocks(doc, "t");
    assert_eq!(b.len(), 2);
    assert_eq!(b[0].skip.as_deref(), Some("needs a cluster"));
    // Indentation inside the block is kept.
    assert_eq!(b[0].text, "a \\\n  b\n");
    assert_eq!(
        (b[1].skip.as_deref(), b[1].text.as_str(), b[1].line),
        (None, "c\n", 9)
    );
    // The fence's own indentation (a block inside a list item) is removed.
    let listed = blocks("- item\n\n  ```sh\n  a\n    b\n  ```\n", "t");
    assert_eq!(listed[0].text, "a\n  b\n");
}

#[test]
fn a_file_outside_out_is_caught() {
    let dir = workdir();
    let before = linked_listings();
    std::fs::create_dir(dir.path().join(OUT)).unwrap();
    std::fs::write(dir.path().join(OUT).join("a.mcap"), b"").unwrap();
    assert_only_out(dir.path(), "t", &before);
    std::fs::write(dir.path().join("stray.png"), b"").unwrap();
    let caught = std::panic::catch_unwind(|| assert_only_out(dir.path(), "t", &before));
    assert!(caught.is_err(), "a file beside out/ passed");
}
